//! Small-θ series expansion: emits `pcc_fs_fc_<order>(u)`, which evaluates
//! f_s(u) = sin√u/√u, f_c(u) = (1 − cos√u)/u and their u-derivatives (docs/model.md §2, §8).
//!
//! # Method
//!
//! With θ = √u, `s = sin θ`, `c = cos θ`, the closed forms are `f_s = s/θ`,
//! `f_c = (1 − c)/u`, and differentiating `2u f_s' = c − f_s`, `(cos√u)' = −f_s/2` and
//! `u f_c' = f_s/2 − f_c` k times gives the upward recurrences (k ≥ 1)
//!
//! ```text
//! f_s'      = (c − f_s)/(2u)
//! f_s^(k+1) = (−f_s^(k−1)/2 − (2k+1) f_s^(k))/(2u)
//! f_c^(k+1) = (f_s^(k)/2 − (k+1) f_c^(k))/u
//! ```
//!
//! They cancel near u = 0 (error ≈ eps·C_k/u^k relative to `|f^(k)(0)|`), so each order k
//! has its own switch point `U_k`: below it a truncated Taylor series in u,
//! `f_s^(k) = Σ_n (−1)^(n+k) (n+k)!/n! · u^n/(2n+2k+1)!` (and `(2n+2k+2)!` for f_c),
//! evaluated by second-order Horner in `w = u·2^−m` (an exact scaling that keeps the
//! coefficient literals short; `w` and `w²` are shared by f_s and f_c). Below `U_0` every
//! order uses its series (with the fewer terms that `[0, U_0]` needs) and no sin/cos is
//! computed. The number of terms is the least `N` with decreasing terms beyond `N` and
//! `|a_N| U_k^N ≤ 2^−60 |a_0|` (alternating series: the tail is below the first omitted
//! term). Coefficients are computed in double-double and rounded once to f64.
//!
//! # Switch points (measured)
//!
//! Errors are measured against a double-double reference (`softcbf-tests`, `highprec.rs`)
//! in units of the acceptance bound `1e−14·|x| + 1e−15·|f^(k)(0)|` (≤ 1 passes; worst of
//! f_s and f_c), on a 4001-point log grid over `[1e−12, 100]` plus 20000 uniform points.
//! For each order the candidates `U ∈ {2^j, 1.5·2^j} ≤ 96` were scanned (series error on
//! `[0, U)`, closed-form error on `[U, 100]`); `U_k` is the smallest candidate whose larger
//! error is within 1.2× of the best one. The closed forms' error falls like `1/u^k`
//! (order 5 at U = 4: 4106×, at 32: 0.29×); the series' grows with u (order 6 at U = 96:
//! 2.5×). Figures below are for the emitted `pcc_fs_fc_6` (test `error_table`):
//!
//! | order k | U_k     | terms f_s/f_c on [0, U_k) | terms for u < U_0 | max error below U_k | max error above U_k | max abs error / `\|f^(k)(0)\|` |
//! |---------|---------|-------|-----|-------|-------|---------|
//! | 0       | 0.09375 | 7/7   | 7/7 | 0.015 | 0.100 | 1.1e−15 |
//! | 1       | 6       | 13/13 | 7/7 | 0.033 | 0.061 | 4.2e−16 |
//! | 2       | 12      | 15/14 | 7/7 | 0.050 | 0.067 | 3.9e−16 |
//! | 3       | 24      | 17/16 | 7/7 | 0.146 | 0.084 | 4.7e−16 |
//! | 4       | 32      | 18/17 | 7/6 | 0.181 | 0.088 | 5.4e−16 |
//! | 5       | 32      | 17/17 | 6/6 | 0.126 | 0.267 | 1.1e−15 |
//! | 6       | 48      | 19/18 | 6/6 | 0.198 | 0.218 | 6.8e−16 |
//!
//! Values at u = 0 are the exact limits (the leading coefficients). NaN gives NaN (it
//! fails every `u < U_k` test and reaches the closed forms); +∞ gives NaN; no panics.
//! Negative u (outside the domain) takes the series branch: the analytic continuation.

use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};
use softcbf_interval::{Dual, Interval};

/// Switch points `U_k` for derivative orders `k = 0..=MAX_ORDER` (non-decreasing, so a
/// closed form at order k only ever uses closed forms of lower orders).
pub const SWITCH_POINTS: [f64; MAX_ORDER + 1] = [0.09375, 6.0, 12.0, 24.0, 32.0, 32.0, 48.0];

/// Cap on the series length (the measured switch points need at most 19 terms).
pub const MAX_TERMS: usize = 64;

/// Highest derivative order [`emit`] supports (its switch point was measured).
pub const MAX_ORDER: usize = 6;

/// Identifier of the emitted function for derivative orders 0..=order, e.g. `pcc_fs_fc_3`.
pub fn function_ident(order: usize) -> Ident {
    format_ident!("pcc_fs_fc_{}", order)
}

/// Identifier of the emitted enclosure for derivative orders 0..=order, e.g.
/// `pcc_fs_fc_3_interval`.
pub fn interval_function_ident(order: usize) -> Ident {
    format_ident!("pcc_fs_fc_{}_interval", order)
}

/// Identifier of the emitted jet version for derivative orders 0..=order, e.g.
/// `pcc_fs_fc_2_dual`.
pub fn dual_function_ident(order: usize) -> Ident {
    format_ident!("pcc_fs_fc_{}_dual", order)
}

/// Emits `pub fn pcc_fs_fc_<order>_dual(u: Dual) -> ([Dual; order+1], [Dual; order+1])`:
/// values from the enclosures of `pcc_fs_fc_<order+1>_interval`, slopes by the chain rule
/// (`f^(j)′ = f^(j+1) u′`). Needs the enclosure of order `order + 1`.
pub fn emit_dual(order: usize) -> TokenStream {
    let name = dual_function_ident(order);
    let enclosure = interval_function_ident(order + 1);
    let len = Literal::usize_unsuffixed(order + 1);
    let doc = format!(
        " Jets of `[f_s, …, f_s^({order})]`, `[f_c, …, f_c^({order})]` at `u`: values and the \
         chain rule's slopes from the enclosures of order {}.",
        order + 1
    );
    quote! {
        #[doc = #doc]
        pub fn #name(u: Dual) -> ([Dual; #len], [Dual; #len]) {
            let (s, c) = #enclosure(u.value);
            (
                std::array::from_fn(|j| Dual::new(s[j], s[j + 1] * u.slope)),
                std::array::from_fn(|j| Dual::new(c[j], c[j + 1] * u.slope)),
            )
        }
    }
}

/// `|f_s^(j)(0)| = j!/(2j+1)!` (`fc = false`) or `|f_c^(j)(0)| = j!/(2j+2)!` (`fc = true`).
///
/// These bound the derivatives on the whole domain: `f_s(u) = ∫₀¹ c(s²u) ds` and
/// `f_c(u) = ∫₀¹ (1 − s) c(s²u) ds` with `c(w) = cos √w`, so
/// `f^(j)(u) = ∫ s^{2j} c^(j)(s²u) (…) ds`, and `c^(j)(w)` is a constant times
/// `J_{j−1/2}(√w)/√w^{j−1/2}`, whose magnitude on `w ≥ 0` is largest at `w = 0`
/// (`|J_ν(x)| ≤ |x/2|^ν/Γ(ν+1)` for `ν ≥ −1/2`). Hence `|f^(j)(u)| ≤ |f^(j)(0)|` for all
/// `u ≥ 0` (docs/model.md §5).
pub fn derivative_bound(j: usize, fc: bool) -> f64 {
    let mut value = 1.0;
    for n in 1..=j {
        value *= n as f64;
    }
    let top = 2 * j + 1 + usize::from(fc);
    for n in 1..=top {
        value /= n as f64;
    }
    value
}

/// Relative and absolute accuracy of the `f64` functions `pcc_fs_fc_<k>` (docs/model.md
/// §8: measured within 0.27 of `1e-14 |f| + 1e-15 |f^(k)(0)|`; taken at twice the bound).
pub const ACCURACY_RELATIVE: f64 = 2e-14;
/// See [`ACCURACY_RELATIVE`]: the part in units of `|f^(k)(0)|`.
pub const ACCURACY_ABSOLUTE: f64 = 2e-15;

/// Emits `pub fn pcc_fs_fc_<order>_interval(u: Interval) -> ([Interval; order+1],
/// [Interval; order+1])`: enclosures of `f_s^(k)`, `f_c^(k)` over the part of `u` at or
/// above zero (the argument is `θ² ≥ 0`, so a lower bound below zero is widening only).
/// Mean-value form around the midpoint `m`: `f^(k)(m) ± (|f^(k+1)(0)| r + e_k)` with `r`
/// the radius, [`derivative_bound`] for the slope and `e_k` the `f64` evaluation's accuracy
/// ([`ACCURACY_RELATIVE`]), and within `±|f^(k)(0)|`. An unbounded or invalid `u` gives
/// [`Interval::ENTIRE`]-wide or invalid entries.
pub fn emit_interval(order: usize) -> TokenStream {
    let name = interval_function_ident(order);
    let point = function_ident(order);
    let len = Literal::usize_unsuffixed(order + 1);
    let bounds = |fc: bool| -> Vec<Literal> {
        (0..=order + 1)
            .map(|j| float(derivative_bound(j, fc)))
            .collect()
    };
    let (s0, c0) = (bounds(false), bounds(true));
    let bound_len = Literal::usize_unsuffixed(order + 2);
    let (rel, abs) = (float(ACCURACY_RELATIVE), float(ACCURACY_ABSOLUTE));
    let doc = format!(
        " Enclosures of `[f_s, …, f_s^({order})]`, `[f_c, …, f_c^({order})]` over `u ≥ 0` in \
         the interval `u` (mean-value form around the midpoint with the global derivative \
         bounds `|f^(j)(u)| ≤ |f^(j)(0)|`)."
    );
    quote! {
        #[doc = #doc]
        pub fn #name(u: Interval) -> ([Interval; #len], [Interval; #len]) {
            const S0: [f64; #bound_len] = [#(#s0),*];
            const C0: [f64; #bound_len] = [#(#c0),*];
            if !u.is_valid() || u.hi() < 0.0 {
                return ([Interval::NAN; #len], [Interval::NAN; #len]);
            }
            if !u.hi().is_finite() {
                let whole = |j: usize, b: &[f64]| Interval::new(-b[j], b[j]);
                return (
                    std::array::from_fn(|j| whole(j, &S0)),
                    std::array::from_fn(|j| whole(j, &C0)),
                );
            }
            let range = Interval::new(u.lo().max(0.0), u.hi());
            let (m, r) = (range.mid(), range.rad());
            let (fs, fc) = #point(m);
            let enclose = |value: f64, j: usize, b: &[f64]| {
                let slack = b[j + 1] * r + #rel * value.abs() + #abs * b[j];
                let around = Interval::around(value, slack);
                Interval::new(around.lo().max(-b[j]), around.hi().min(b[j]))
            };
            (
                std::array::from_fn(|j| enclose(fs[j], j, &S0)),
                std::array::from_fn(|j| enclose(fc[j], j, &C0)),
            )
        }
    }
}

/// Emits `#[inline] pub fn pcc_fs_fc_<order>(u: f64) -> ([f64; order+1], [f64; order+1])`
/// returning `([f_s, f_s', …, f_s^(order)], [f_c, f_c', …, f_c^(order)])` at `u`
/// (derivatives in u). For `order > MAX_ORDER` it emits a `compile_error!` instead.
pub fn emit(order: usize) -> TokenStream {
    if order > MAX_ORDER {
        let msg = format!(
            "softcbf-codegen: pcc_fs_fc_{order} requested, series switch points are measured up to order {MAX_ORDER}"
        );
        return quote! { compile_error!(#msg); };
    }
    let name = function_ident(order);
    let len = Literal::usize_unsuffixed(order + 1);
    let doc = format!(
        " `([f_s, f_s', …], [f_c, f_c', …])` at `u = θ²` up to derivative order {order}: \
         series below the switch points {:?}, closed forms above.",
        &SWITCH_POINTS[..=order]
    );

    // u < U_0: every order from its series on [0, U_0].
    let u0 = float(SWITCH_POINTS[0]);
    let (small_prelude, small_s, small_c) = series_block(0..=order, SWITCH_POINTS[0]);

    // u ≥ U_0: closed forms, and per order k ≥ 1 its series below U_k.
    let mut steps = Vec::new();
    for (k, &u_k) in SWITCH_POINTS.iter().enumerate().take(order + 1).skip(1) {
        let (fs_k, fc_k) = (format_ident!("fs{}", k), format_ident!("fc{}", k));
        let uk = float(u_k);
        let (prelude, s, c) = series_block(k..=k, u_k);
        let (ser_s, ser_c) = (&s[0], &c[0]);
        let (closed_s, closed_c) = closed_step(k);
        steps.push(quote! {
            let (#fs_k, #fc_k) = if u < #uk {
                #prelude
                (#ser_s, #ser_c)
            } else {
                (#closed_s, #closed_c)
            };
        });
    }
    let fs_all: Vec<Ident> = (0..=order).map(|k| format_ident!("fs{}", k)).collect();
    let fc_all: Vec<Ident> = (0..=order).map(|k| format_ident!("fc{}", k)).collect();
    let one = float(1.0);

    quote! {
        #[doc = #doc]
        #[inline]
        pub fn #name(u: f64) -> ([f64; #len], [f64; #len]) {
            if u < #u0 {
                #small_prelude
                ([#(#small_s),*], [#(#small_c),*])
            } else {
                let t = u.sqrt();
                let (sn, cs) = t.sin_cos();
                let inv = #one / u;
                let fs0 = sn / t;
                let fc0 = (#one - cs) * inv;
                #(#steps)*
                ([#(#fs_all),*], [#(#fc_all),*])
            }
        }
    }
}

/// `f_s`, `f_c` and their u-derivatives up to `order` (≤ [`MAX_ORDER`]) at `u`, computed
/// at run time exactly as the emitted `pcc_fs_fc_<order>` computes them: the same
/// coefficients, switch points, scaling and operation order, so the same bits. Returns
/// `([f_s, f_s', …], [f_c, f_c', …])` with entries past `order` zero. For the interpreter
/// of the generated model (`softcbf-generated`'s `interpreted`).
///
/// # Panics
///
/// If `order > MAX_ORDER` (the emitter refuses it too).
pub fn evaluate(order: usize, u: f64) -> ([f64; MAX_ORDER + 1], [f64; MAX_ORDER + 1]) {
    assert!(
        order <= MAX_ORDER,
        "pcc_fs_fc_{order}: switch points are measured up to order {MAX_ORDER}"
    );
    let tables = SeriesTables::get();
    let (mut fs, mut fc) = ([0.0; MAX_ORDER + 1], [0.0; MAX_ORDER + 1]);
    if u < SWITCH_POINTS[0] {
        let w = tables.small.scaled(u);
        let w2 = w * w;
        for k in 0..=order {
            let (s, c) = &tables.small.orders[k];
            fs[k] = horner2_value(s, k, w, w2);
            fc[k] = horner2_value(c, k, w, w2);
        }
        return (fs, fc);
    }
    let t = u.sqrt();
    let (sn, cs) = t.sin_cos();
    let inv = 1.0 / u;
    fs[0] = sn / t;
    fc[0] = (1.0 - cs) * inv;
    for k in 1..=order {
        if u < SWITCH_POINTS[k] {
            let series = &tables.per_order[k];
            let w = series.scaled(u);
            let w2 = w * w;
            let (s, c) = &series.orders[0];
            fs[k] = horner2_value(s, k, w, w2);
            fc[k] = horner2_value(c, k, w, w2);
        } else if k == 1 {
            fs[1] = (cs - fs[0]) * (0.5 * inv);
            fc[1] = (0.5 * fs[0] - fc[0]) * inv;
        } else {
            let odd = (2 * k - 1) as f64;
            fs[k] = (-(0.5 * fs[k - 2]) - odd * fs[k - 1]) * (0.5 * inv);
            fc[k] = (0.5 * fs[k - 1] - k as f64 * fc[k - 1]) * inv;
        }
    }
    (fs, fc)
}

/// The enclosures of the emitted `pcc_fs_fc_<order>_interval` ([`emit_interval`]) computed
/// at run time the same way, from [`evaluate`] at the midpoint: `([f_s, …], [f_c, …])` with
/// entries past `order` zero. For the interpreter's interval functions.
pub fn evaluate_interval(
    order: usize,
    u: Interval,
) -> ([Interval; MAX_ORDER + 1], [Interval; MAX_ORDER + 1]) {
    let (mut fs, mut fc) = (
        [Interval::ZERO; MAX_ORDER + 1],
        [Interval::ZERO; MAX_ORDER + 1],
    );
    if !u.is_valid() || u.hi() < 0.0 {
        fs[..=order].fill(Interval::NAN);
        fc[..=order].fill(Interval::NAN);
        return (fs, fc);
    }
    if !u.hi().is_finite() {
        for j in 0..=order {
            let (s, c) = (derivative_bound(j, false), derivative_bound(j, true));
            fs[j] = Interval::new(-s, s);
            fc[j] = Interval::new(-c, c);
        }
        return (fs, fc);
    }
    let range = Interval::new(u.lo().max(0.0), u.hi());
    let (m, r) = (range.mid(), range.rad());
    let (point_s, point_c) = evaluate(order, m);
    let enclose = |value: f64, j: usize, fc: bool| {
        let (b, slope) = (derivative_bound(j, fc), derivative_bound(j + 1, fc));
        let slack = slope * r + ACCURACY_RELATIVE * value.abs() + ACCURACY_ABSOLUTE * b;
        let around = Interval::around(value, slack);
        Interval::new(around.lo().max(-b), around.hi().min(b))
    };
    for j in 0..=order {
        fs[j] = enclose(point_s[j], j, false);
        fc[j] = enclose(point_c[j], j, true);
    }
    (fs, fc)
}

/// The jets of the emitted `pcc_fs_fc_<order>_dual` ([`emit_dual`]) computed at run time:
/// values and slopes from [`evaluate_interval`] of order `order + 1`.
pub fn evaluate_dual(order: usize, u: Dual) -> ([Dual; MAX_ORDER + 1], [Dual; MAX_ORDER + 1]) {
    let (mut fs, mut fc) = (
        [Dual::default(); MAX_ORDER + 1],
        [Dual::default(); MAX_ORDER + 1],
    );
    let (s, c) = evaluate_interval((order + 1).min(MAX_ORDER), u.value);
    for j in 0..=order {
        // Past the measured orders the slope's bound is the global one.
        let (next_s, next_c) = if j < MAX_ORDER {
            (s[j + 1], c[j + 1])
        } else {
            let (bs, bc) = (
                derivative_bound(j + 1, false),
                derivative_bound(j + 1, true),
            );
            (Interval::new(-bs, bs), Interval::new(-bc, bc))
        };
        fs[j] = Dual::new(s[j], next_s * u.slope);
        fc[j] = Dual::new(c[j], next_c * u.slope);
    }
    (fs, fc)
}

/// The coefficients [`evaluate`] reads, computed once by the emitter's own
/// [`series_coefficients`].
struct SeriesTables {
    /// Every order's series on `[0, U_0)`.
    small: Series,
    /// Order k's series on `[U_0, U_k)` (entry 0 unused).
    per_order: Vec<Series>,
}

/// Series valid on `[0, u_max]`: the scaling of `w` and the f_s, f_c magnitudes per order.
struct Series {
    /// `2^−m` of `w = u·2^−m`, `None` when `m = 0` (the emitted code writes `w = u`).
    factor: Option<f64>,
    /// `(f_s, f_c)` coefficient magnitudes, one pair per order held.
    orders: Vec<(Vec<f64>, Vec<f64>)>,
}

impl Series {
    fn new(orders: std::ops::RangeInclusive<usize>, u_max: f64) -> Series {
        let m = scale_log2(u_max);
        Series {
            factor: (m != 0).then(|| 2f64.powi(-m)),
            orders: orders
                .map(|k| {
                    (
                        series_coefficients(k, false, u_max),
                        series_coefficients(k, true, u_max),
                    )
                })
                .collect(),
        }
    }

    fn scaled(&self, u: f64) -> f64 {
        match self.factor {
            Some(factor) => u * factor,
            None => u,
        }
    }
}

impl SeriesTables {
    fn get() -> &'static SeriesTables {
        static TABLES: std::sync::OnceLock<SeriesTables> = std::sync::OnceLock::new();
        TABLES.get_or_init(|| SeriesTables {
            small: Series::new(0..=MAX_ORDER, SWITCH_POINTS[0]),
            per_order: (0..=MAX_ORDER)
                .map(|k| Series::new(k..=k, SWITCH_POINTS[k]))
                .collect(),
        })
    }
}

/// The value of [`horner2`]'s expression: `±(E(w²) − w·O(w²))` with the same nesting.
fn horner2_value(b: &[f64], k: usize, w: f64, w2: f64) -> f64 {
    let nest = |start: usize| -> Option<f64> {
        let mut coeffs = b.iter().skip(start).step_by(2).rev();
        let last = *coeffs.next()?;
        Some(coeffs.fold(last, |acc, &coef| coef + w2 * acc))
    };
    let e = nest(0).expect("a series has its leading coefficient");
    match nest(1) {
        None if k.is_multiple_of(2) => e,
        None => -e,
        Some(o) if k.is_multiple_of(2) => e - w * o,
        Some(o) => w * o - e,
    }
}

/// Closed-form recurrence for order `k ≥ 1` in terms of `fs{k−1}`, `fs{k−2}`, `fc{k−1}`,
/// `cs` and `inv = 1/u`.
fn closed_step(k: usize) -> (TokenStream, TokenStream) {
    let fs_prev = format_ident!("fs{}", k - 1);
    let fc_prev = format_ident!("fc{}", k - 1);
    let half = float(0.5);
    let fs = if k == 1 {
        quote! { (cs - fs0) * (#half * inv) }
    } else {
        let fs_prev2 = format_ident!("fs{}", k - 2);
        let odd = float((2 * k - 1) as f64);
        quote! { (-(#half * #fs_prev2) - #odd * #fs_prev) * (#half * inv) }
    };
    let fc = if k == 1 {
        quote! { (#half * fs0 - fc0) * inv }
    } else {
        let kf = float(k as f64);
        quote! { (#half * #fs_prev - #kf * #fc_prev) * inv }
    };
    (fs, fc)
}

/// Series of f_s and f_c for the given orders, valid on `[0, u_max]`: the prelude
/// (`w`, `w2`) and one expression per order for each function.
fn series_block(
    orders: std::ops::RangeInclusive<usize>,
    u_max: f64,
) -> (TokenStream, Vec<TokenStream>, Vec<TokenStream>) {
    let scale_log2 = scale_log2(u_max);
    let w_expr = if scale_log2 == 0 {
        quote! { u }
    } else {
        let factor = float(2f64.powi(-scale_log2));
        quote! { u * #factor }
    };
    let (mut s, mut c) = (Vec::new(), Vec::new());
    let mut max_terms = 0;
    for k in orders {
        let cs = series_coefficients(k, false, u_max);
        let cc = series_coefficients(k, true, u_max);
        max_terms = max_terms.max(cs.len()).max(cc.len());
        s.push(horner2(&cs, k));
        c.push(horner2(&cc, k));
    }
    let prelude = match max_terms {
        0 | 1 => quote! {},
        2 => quote! { let w = #w_expr; },
        _ => quote! { let w = #w_expr; let w2 = w * w; },
    };
    (prelude, s, c)
}

/// `m` with `2^m` nearest to `u_max` (the series runs in `w = u·2^−m`, `w ≤ ~1.4`).
fn scale_log2(u_max: f64) -> i32 {
    u_max.log2().round() as i32
}

/// Second-order Horner for `Σ b_n w^n` with alternating signs `(−1)^(n+k)` and `b` the
/// magnitudes: `±(E(w²) − w·O(w²))`, every literal positive.
fn horner2(b: &[f64], k: usize) -> TokenStream {
    // b_0 + w2·(b_2 + w2·(…)) over the given coefficients (never empty here: b_0 exists).
    let nest = |coeffs: Vec<f64>| -> TokenStream {
        coeffs.iter().rev().fold(TokenStream::new(), |acc, &coef| {
            let lit = float(coef);
            if acc.is_empty() {
                quote! { #lit }
            } else {
                quote! { #lit + w2 * (#acc) }
            }
        })
    };
    let even: Vec<f64> = b.iter().step_by(2).copied().collect();
    let odd: Vec<f64> = b.iter().skip(1).step_by(2).copied().collect();
    let e = nest(even);
    if odd.is_empty() {
        return if k.is_multiple_of(2) {
            e
        } else {
            quote! { -(#e) }
        };
    }
    let o = nest(odd);
    if k.is_multiple_of(2) {
        quote! { (#e) - w * (#o) }
    } else {
        quote! { w * (#o) - (#e) }
    }
}

/// Magnitudes `|a_n|·2^(m n)` of the Taylor coefficients of f_s^(k) (`cosine = false`) or
/// f_c^(k) (`cosine = true`) in `w = u·2^−m` (`m` from `u_max`), as many as needed on
/// `[0, u_max]`: `|a_n| = (n+k)!/(n!·(2n+2k+first)!)`, `first` = 1 for f_s, 2 for f_c.
/// Meant for `0 < u_max ≤ ~1000`; at most [`MAX_TERMS`] coefficients.
pub fn series_coefficients(k: usize, cosine: bool, u_max: f64) -> Vec<f64> {
    let first = if cosine { 2 } else { 1 };
    let scale = 2f64.powi(scale_log2(u_max));
    // Leading coefficient k!/(2k+first)! in double-double.
    let mut a = Dd::ONE;
    for j in (k + 1)..=(2 * k + first) {
        a = a.div_int(j as f64);
    }
    let tol = a.hi * 2f64.powi(-60);
    let mut out = Vec::new();
    let mut power = 1.0; // scale^n, exact
    let mut bound = a.hi; // |a_n| u_max^n
    for n in 0..MAX_TERMS {
        let (nf, kf, ff) = (n as f64, k as f64, first as f64);
        let den = (nf + 1.0) * (2.0 * nf + 2.0 * kf + ff + 1.0) * (2.0 * nf + 2.0 * kf + ff + 2.0);
        let ratio = u_max * (nf + kf + 1.0) / den;
        if bound <= tol && ratio < 1.0 {
            break;
        }
        out.push(a.hi * power + a.lo * power);
        a = a.mul_int(nf + kf + 1.0).div_int(den);
        power *= scale;
        bound *= ratio;
    }
    out
}

/// A minimal double-double (≈106 bits) for the coefficients: enough that rounding the
/// exact rational to f64 is correct except within 1e−30 of a tie.
#[derive(Clone, Copy)]
struct Dd {
    hi: f64,
    lo: f64,
}

impl Dd {
    const ONE: Dd = Dd { hi: 1.0, lo: 0.0 };

    fn normalize(hi: f64, lo: f64) -> Dd {
        let s = hi + lo;
        Dd {
            hi: s,
            lo: lo - (s - hi),
        }
    }

    /// Times an integer-valued f64 (exact product via fused multiply-add).
    fn mul_int(self, m: f64) -> Dd {
        let p = self.hi * m;
        let e = self.hi.mul_add(m, -p);
        Dd::normalize(p, e + self.lo * m)
    }

    /// Divided by an integer-valued f64 (two correction steps).
    fn div_int(self, d: f64) -> Dd {
        let q1 = self.hi / d;
        let p = q1 * d;
        let e = q1.mul_add(d, -p);
        let r = (self.hi - p) - e + self.lo;
        let q2 = r / d;
        Dd::normalize(q1, q2)
    }
}

/// An unsuffixed float literal (shortest round-trip digits).
fn float(x: f64) -> Literal {
    Literal::f64_unsuffixed(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn literals(tokens: TokenStream, out: &mut Vec<String>) {
        for tt in tokens {
            match tt {
                proc_macro2::TokenTree::Literal(l) => out.push(l.to_string()),
                proc_macro2::TokenTree::Group(g) => literals(g.stream(), out),
                _ => {}
            }
        }
    }

    #[test]
    fn emitted_code_parses_and_is_stable() {
        for order in 0..=MAX_ORDER {
            let a = emit(order).to_string();
            let b = emit(order).to_string();
            assert_eq!(a, b);
            let file: syn::File = syn::parse2(emit(order)).expect("parses");
            let text = prettyplease::unparse(&file);
            assert!(text.contains(&format!("pub fn pcc_fs_fc_{order}(u: f64)")));
        }
    }

    #[test]
    fn float_literals_round_trip() {
        let mut lits = Vec::new();
        literals(emit(MAX_ORDER), &mut lits);
        let floats: Vec<&String> = lits
            .iter()
            .filter(|l| !l.starts_with('"') && l.contains('.'))
            .collect();
        assert!(floats.len() > 50);
        for l in floats {
            let x: f64 = l.parse().expect("float literal");
            assert_eq!(Literal::f64_unsuffixed(x).to_string(), *l);
            assert!(x > 0.0 && x.is_finite(), "{l}");
        }
    }

    /// For coefficients whose exact denominator fits in 2^53, `1/D` in f64 is the
    /// correctly rounded value: the double-double path must give the same bits.
    #[test]
    fn coefficients_are_correctly_rounded() {
        fn fact(n: u64) -> u128 {
            (1..=n as u128).product()
        }
        for k in 0..=3_u64 {
            for cosine in [false, true] {
                let first = if cosine { 2 } else { 1 };
                let c = series_coefficients(k as usize, cosine, 1.0);
                for (n, &got) in c.iter().enumerate() {
                    let n = n as u64;
                    if 2 * n + 2 * k + first > 30 {
                        break;
                    }
                    let num = fact(n + k);
                    let den = fact(n) * fact(2 * n + 2 * k + first);
                    if den.is_multiple_of(num) && den / num < (1 << 53) {
                        assert_eq!(got, 1.0 / (den / num) as f64, "k={k} n={n}");
                    }
                }
            }
        }
    }

    #[test]
    fn switch_points_increase() {
        assert!(SWITCH_POINTS.windows(2).all(|w| w[0] <= w[1]));
        assert!(SWITCH_POINTS.iter().all(|&u| u > 0.0));
    }

    #[test]
    fn too_high_order_is_a_compile_error() {
        assert!(emit(MAX_ORDER + 1).to_string().contains("compile_error"));
    }
}
