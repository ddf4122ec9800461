//! Adaptive exponential Runge–Kutta integrator (ETD3RK of Cox & Matthews with an embedded
//! order-2 solution) for `x' = A x + N(x)` with a linear part `A` the system provides and
//! the integrator rebuilds only when it has drifted; see the module docs of
//! [`crate::integrator`] for why and what it costs.

use crate::linalg::with_const_size;

use super::{
    IntegratorError, OdeSystem, Stats, Tolerances, check_call, error_norm, shrink_after_rejection,
};

/// What the exponential integrator needs besides `f`: a linear part `A ≈ ∂f/∂x` holding the
/// stiff dynamics, treated exactly (the rest, `N(x) = f(x) − A x`, explicitly).
pub trait LinearPart: OdeSystem {
    /// Writes the linear part `A` at the state `x` (row-major `dim × dim`) and keeps it as
    /// the reference of [`LinearPart::drift`]. Returns `false` if it could not be built.
    fn linear_part(&mut self, t: f64, x: &[f64], a: &mut [f64]) -> bool;

    /// How far the linear part at `x` has moved from the one of the last
    /// [`LinearPart::linear_part`] call, relative (for example `‖M(x) − M_ref‖ / ‖M_ref‖`
    /// for a mechanical system whose `A` depends on `x` only through a mass matrix): the
    /// part of the stiff dynamics that the frozen `A` misses is about `drift · ‖A‖`.
    /// Called right after [`OdeSystem::rhs`] at the same `x`. The default, `0`, is right for
    /// a constant `A`.
    fn drift(&mut self, _x: &[f64]) -> f64 {
        0.0
    }
}

/// The matrices of one step size `h` and the current `A` (row-major `dim × dim`), with
/// `φ₁(z) = (eᶻ − 1)/z`, `φ₂(z) = (eᶻ − 1 − z)/z²`, `φ₃(z) = (eᶻ − 1 − z − z²/2)/z³`:
/// `half = (h/2) φ₁(hA/2)`, `full = h φ₁(hA)`, `second = h (4φ₂ − 8φ₃)(hA)`,
/// `third = h (4φ₃ − φ₂)(hA)`.
#[derive(Clone, Debug)]
struct PhiSet {
    h: f64,
    valid: bool,
    half: Vec<f64>,
    full: Vec<f64>,
    second: Vec<f64>,
    third: Vec<f64>,
}

/// Taylor coefficients `1/(k+3)!` of `φ₃`, `k = 0 … 12`: at `‖X‖₁ ≤ ½` the first term left
/// out, `‖X‖¹³/16!`, is below 1e-17 relative to `φ₃(0) = 1/6`.
const PHI3_TAYLOR: [f64; 13] = [
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5040.0,
    1.0 / 40320.0,
    1.0 / 362880.0,
    1.0 / 3628800.0,
    1.0 / 39916800.0,
    1.0 / 479001600.0,
    1.0 / 6227020800.0,
    1.0 / 87178291200.0,
    1.0 / 1307674368000.0,
];

/// Scratch of the `φ` computation, row-major `m × m` each.
#[derive(Clone, Debug)]
struct PhiWork {
    x: Vec<f64>,
    e: Vec<f64>,
    p1: Vec<f64>,
    p2: Vec<f64>,
    p3: Vec<f64>,
    t1: Vec<f64>,
    t2: Vec<f64>,
    t3: Vec<f64>,
}

impl PhiWork {
    fn new(m: usize) -> Self {
        let v = || vec![0.0; m * m];
        Self {
            x: v(),
            e: v(),
            p1: v(),
            p2: v(),
            p3: v(),
            t1: v(),
            t2: v(),
            t3: v(),
        }
    }

    /// Fills `out[j]` for the steps `h_j = span/2ʲ`: scaling `X = span·A/2ˢ` to `‖X‖₁ ≤ ½`
    /// with `s ≥ out.len()`, Taylor series of `φ₃(X)` (Horner), `φ₂ = I/2 + X φ₃`,
    /// `φ₁ = I + X φ₂`, `e^X = I + X φ₁`, then `s` doublings
    /// `φ_k(2X) = 2⁻ᵏ (e^X φ_k + Σ_{j=1..k} φ_j/(k−j)!)` (Skaflestad & Wright; all functions
    /// of `X` commute), whose last ones pass through `h_j A` and `h_j A/2`. Returns `false`
    /// on a non-finite result.
    fn compute(&mut self, a: &[f64], span: f64, m: usize, out: &mut [PhiSet]) -> bool {
        // The linear part of a mechanical system, [[0, I], [·, ·]] (checked exactly).
        let mechanical = m.is_multiple_of(2) && is_mechanical(a, m);
        self.compute_with(a, span, m, out, mechanical)
    }

    /// [`PhiWork::compute`], using the structure `[[0, I], [·, ·]]` of `a` if `mechanical`
    /// (then `a` must have it): only the lower half rows of the products by `e^X` of the
    /// doublings are computed for `φ₁`, `φ₂` and `e^X`, their upper half rows following
    /// from `φ_k = I/k! + X φ_{k+1}`, whose upper half rows are `e_i/k! + s φ_{k+1}[n + i]`
    /// for `X = [[0, sI], [·, ·]]` (and `e^X = I + X φ₁`): 2.5 products per doubling
    /// instead of 4 (measured on the paper scenario: the `φ` families 112M → 95M
    /// instructions over the run).
    fn compute_with(
        &mut self,
        a: &[f64],
        span: f64,
        m: usize,
        out: &mut [PhiSet],
        mechanical: bool,
    ) -> bool {
        let norm = (0..m)
            .map(|c| (0..m).map(|r| a[r * m + c].abs()).sum::<f64>())
            .fold(0.0, f64::max)
            * span;
        if !norm.is_finite() {
            return false;
        }
        let levels = out.len() as i32;
        let squarings = if norm > 0.5 {
            ((norm / 0.5).log2().ceil() as i32).max(levels)
        } else {
            levels
        };
        let scale = span * 0.5_f64.powi(squarings);
        for (x, v) in self.x.iter_mut().zip(a) {
            *x = v * scale;
        }
        let identity = |mat: &mut [f64], c: f64| {
            for i in 0..m {
                mat[i * m + i] += c;
            }
        };
        // φ₃ = Σ c_k X^k by Horner, starting from c_K X + c_{K−1} I.
        let n_terms = PHI3_TAYLOR.len();
        for (p, x) in self.p3.iter_mut().zip(&self.x) {
            *p = PHI3_TAYLOR[n_terms - 1] * x;
        }
        identity(&mut self.p3, PHI3_TAYLOR[n_terms - 2]);
        for &c in PHI3_TAYLOR.iter().rev().skip(2) {
            multiply_sparse_left(&self.x, &self.p3, &mut self.t1, m);
            identity(&mut self.t1, c);
            std::mem::swap(&mut self.p3, &mut self.t1);
        }
        multiply_sparse_left(&self.x, &self.p3, &mut self.p2, m);
        identity(&mut self.p2, 0.5);
        multiply_sparse_left(&self.x, &self.p2, &mut self.p1, m);
        identity(&mut self.p1, 1.0);
        multiply_sparse_left(&self.x, &self.p1, &mut self.e, m);
        identity(&mut self.e, 1.0);
        for k in 0..=squarings {
            // Here the functions are of X·2ᵏ = h_j A with j = s − k.
            let j = squarings - k;
            if j < levels {
                let set = &mut out[j as usize];
                let h = span * 0.5_f64.powi(j);
                let outs = set.full.iter_mut().zip(&mut set.second).zip(&mut set.third);
                let ins = self.p1.iter().zip(&self.p2).zip(&self.p3);
                for (((full, second), third), ((p1, p2), p3)) in outs.zip(ins) {
                    *full = h * p1;
                    *second = h * (4.0 * p2 - 8.0 * p3);
                    *third = h * (4.0 * p3 - p2);
                }
                set.h = h;
            }
            if j >= 1 && j - 1 < levels {
                let set = &mut out[(j - 1) as usize];
                let half = 0.5 * span * 0.5_f64.powi(j - 1);
                for (o, p) in set.half.iter_mut().zip(&self.p1) {
                    *o = half * p;
                }
            }
            if k == squarings {
                break;
            }
            // With the structure, only the lower half rows of the products by e are
            // needed for φ₁, φ₂ and e itself (their upper half rows follow from φ₂, φ₃).
            let first = if mechanical { m / 2 } else { 0 };
            multiply_dense(&self.e, &self.p3, &mut self.t3, m);
            multiply_rows(&self.e, &self.p2, &mut self.t2, m, first);
            multiply_rows(&self.e, &self.p1, &mut self.t1, m, first);
            // φ₃ in full, φ₂ and φ₁ from row `first` on.
            let (p1_top, p2_top, p3_top) = (
                &self.p1[..first * m],
                &self.p2[..first * m],
                &mut self.p3[..first * m],
            );
            for (((p3, t3), v1), v2) in p3_top.iter_mut().zip(&self.t3).zip(p1_top).zip(p2_top) {
                *p3 = 0.125 * (t3 + 0.5 * v1 + v2 + *p3);
            }
            let r = first * m..m * m;
            let ps = self.p1[r.clone()]
                .iter_mut()
                .zip(&mut self.p2[r.clone()])
                .zip(&mut self.p3[r.clone()]);
            let ts = self.t1[r.clone()]
                .iter()
                .zip(&self.t2[r.clone()])
                .zip(&self.t3[r]);
            for (((p1, p2), p3), ((t1, t2), t3)) in ps.zip(ts) {
                let (v1, v2, v3) = (*p1, *p2, *p3);
                *p3 = 0.125 * (t3 + 0.5 * v1 + v2 + v3);
                *p2 = 0.25 * (t2 + v1 + v2);
                *p1 = 0.5 * (t1 + v1);
            }
            if mechanical {
                // The upper half of X·2ᵏ⁺¹ is [0, s I]: φ_k = I/k! + X φ_{k+1} there reads
                // φ_k[i] = e_i/k! + s φ_{k+1}[n + i] (rows), and e^X = I + X φ₁.
                let n = m / 2;
                let s = scale * 2.0_f64.powi(k + 1);
                for (i, p3_low) in self.p3[..].chunks_exact(m).skip(n).enumerate() {
                    let row = &mut self.p2[i * m..(i + 1) * m];
                    for (p, low) in row.iter_mut().zip(p3_low) {
                        *p = s * low;
                    }
                    row[i] += 0.5;
                }
                for (i, p2_low) in self.p2[..].chunks_exact(m).skip(n).enumerate() {
                    let row = &mut self.p1[i * m..(i + 1) * m];
                    for (p, low) in row.iter_mut().zip(p2_low) {
                        *p = s * low;
                    }
                    row[i] += 1.0;
                }
            }
            if k + 1 < squarings {
                multiply_rows(&self.e, &self.e, &mut self.t1, m, first);
                std::mem::swap(&mut self.e, &mut self.t1);
                if mechanical {
                    let n = m / 2;
                    let s = scale * 2.0_f64.powi(k + 1);
                    for (i, p1_low) in self.p1[..].chunks_exact(m).skip(n).enumerate() {
                        let row = &mut self.e[i * m..(i + 1) * m];
                        for (e, low) in row.iter_mut().zip(p1_low) {
                            *e = s * low;
                        }
                        row[i] += 1.0;
                    }
                }
            }
        }
        let mut valid = true;
        for set in out.iter_mut() {
            set.valid = [&set.half, &set.full, &set.second, &set.third]
                .iter()
                .all(|v| v.iter().all(|x| x.is_finite()));
            valid &= set.valid;
        }
        valid
    }
}

/// Whether the row-major `m × m` `a` (`m` even) is `[[0, I], [·, ·]]` exactly.
fn is_mechanical(a: &[f64], m: usize) -> bool {
    let n = m / 2;
    a[..n * m].chunks_exact(m).enumerate().all(|(i, row)| {
        row.iter()
            .enumerate()
            .all(|(j, &v)| v == if j == n + i { 1.0 } else { 0.0 })
    })
}

/// Rows `first..m` of `c = a b` for row-major `m × m` (dense); rows above `first` of `c`
/// are left as they were.
fn multiply_rows(a: &[f64], b: &[f64], c: &mut [f64], m: usize, first: usize) {
    with_const_size!(m, [6, 12, 18, 24], |m| {
        multiply_rows_sized(a, b, c, first, m)
    })
}

#[inline(always)]
fn multiply_rows_sized(a: &[f64], b: &[f64], c: &mut [f64], first: usize, m: usize) {
    let (a, b, c) = (&a[first * m..m * m], &b[..m * m], &mut c[first * m..m * m]);
    for (row_a, row_c) in a.chunks_exact(m).zip(c.chunks_exact_mut(m)) {
        row_times(row_a, b, row_c, m);
    }
}

/// `c = a b` for row-major `m × m` (dense: no test for zeros). The kernels below run with
/// `m` a compile-time constant for the usual sizes ([`with_const_size`]; measured on the
/// paper scenario, `m = 12`: the dense product 7.4k → 3.6k instructions).
fn multiply_dense(a: &[f64], b: &[f64], c: &mut [f64], m: usize) {
    with_const_size!(m, [6, 12, 18, 24], |m| multiply_dense_sized(a, b, c, m))
}

#[inline(always)]
fn multiply_dense_sized(a: &[f64], b: &[f64], c: &mut [f64], m: usize) {
    let (a, b, c) = (&a[..m * m], &b[..m * m], &mut c[..m * m]);
    for (row_a, row_c) in a.chunks_exact(m).zip(c.chunks_exact_mut(m)) {
        row_times(row_a, b, row_c, m);
    }
}

/// `row_c = row_a b` for a row-major `m × m` `b`: four columns of `row_c` at a time, held in
/// registers over the whole sum, which takes four rows of `b` per addition
/// (`c += ((a₀b₀ + a₁b₁) + a₂b₂) + a₃b₃`, then the last `m mod 4` one by one).
#[inline(always)]
fn row_times(row_a: &[f64], b: &[f64], row_c: &mut [f64], m: usize) {
    let row_a = &row_a[..m];
    let b = &b[..m * m];
    let blocks = m / 4;
    let mut j = 0;
    while j < m {
        let width = (m - j).min(4);
        let mut acc = [0.0; 4];
        for kb in 0..blocks {
            let k = 4 * kb;
            let (a0, a1, a2, a3) = (row_a[k], row_a[k + 1], row_a[k + 2], row_a[k + 3]);
            let b0 = &b[k * m + j..k * m + j + width];
            let b1 = &b[(k + 1) * m + j..(k + 1) * m + j + width];
            let b2 = &b[(k + 2) * m + j..(k + 2) * m + j + width];
            let b3 = &b[(k + 3) * m + j..(k + 3) * m + j + width];
            for l in 0..width {
                acc[l] += a0 * b0[l] + a1 * b1[l] + a2 * b2[l] + a3 * b3[l];
            }
        }
        for k in 4 * blocks..m {
            let a0 = row_a[k];
            let b0 = &b[k * m + j..k * m + j + width];
            for l in 0..width {
                acc[l] += a0 * b0[l];
            }
        }
        row_c[j..j + width].copy_from_slice(&acc[..width]);
        j += width;
    }
}

/// `c = a b` for row-major `m × m`, rows of `a` with at most two nonzero entries as sparse:
/// for the scaled linear part of a mechanical system, `[[0, I], [·, ·]]`, the upper half
/// rows hold one entry each, which makes the 14 products by `X` of the Taylor series about
/// half as dear.
fn multiply_sparse_left(a: &[f64], b: &[f64], c: &mut [f64], m: usize) {
    with_const_size!(m, [6, 12, 18, 24], |m| {
        multiply_sparse_left_sized(a, b, c, m)
    })
}

#[inline(always)]
fn multiply_sparse_left_sized(a: &[f64], b: &[f64], c: &mut [f64], m: usize) {
    let (a, b, c) = (&a[..m * m], &b[..m * m], &mut c[..m * m]);
    for (row_a, row_c) in a.chunks_exact(m).zip(c.chunks_exact_mut(m)) {
        if row_a.iter().filter(|v| **v != 0.0).count() > 2 {
            row_times(row_a, b, row_c, m);
            continue;
        }
        row_c.fill(0.0);
        for (k, &a_k) in row_a.iter().enumerate() {
            if a_k != 0.0 {
                for (c, x) in row_c.iter_mut().zip(&b[k * m..(k + 1) * m]) {
                    *c += a_k * x;
                }
            }
        }
    }
}

/// `y = M x` for row-major `m × m` (each row's sum in four interleaved parts, which keeps
/// the additions from waiting on each other).
#[inline]
fn mat_vec(mat: &[f64], x: &[f64], y: &mut [f64]) {
    with_const_size!(x.len(), [6, 12, 18, 24], |m| mat_vec_sized(mat, x, y, m))
}

#[inline(always)]
fn mat_vec_sized(mat: &[f64], x: &[f64], y: &mut [f64], m: usize) {
    let (mat, x, y) = (&mat[..m * m], &x[..m], &mut y[..m]);
    for (yi, row) in y.iter_mut().zip(mat.chunks_exact(m)) {
        let mut parts = [0.0; 4];
        let (row4, x4) = (row.chunks_exact(4), x.chunks_exact(4));
        let tail: f64 = row4
            .remainder()
            .iter()
            .zip(x4.remainder())
            .map(|(a, b)| a * b)
            .sum();
        for (r, v) in row4.zip(x4) {
            for ((p, a), b) in parts.iter_mut().zip(r).zip(v) {
                *p += a * b;
            }
        }
        *yi = (parts[0] + parts[1]) + (parts[2] + parts[3]) + tail;
    }
}

/// Step sizes of one family of cached `φ` sets: `span/2ʲ`, `j < LEVELS`.
const LEVELS: usize = 6;

/// The `φ` sets of the steps `span/2ʲ`, `j < LEVELS`, for the current `A`.
#[derive(Clone, Debug)]
struct Family {
    span: f64,
    valid: bool,
    sets: Vec<PhiSet>,
}

/// Adaptive exponential integrator (ETD3RK with an embedded order-2 estimate) with a lazily
/// refreshed linear part; see the module docs of [`crate::integrator`].
#[derive(Clone, Debug)]
pub struct Exponential {
    dim: usize,
    tol: Tolerances,
    /// Step size wanted next (kept across calls).
    h: f64,
    /// The linear part in use, and whether it is set.
    a: Vec<f64>,
    a_valid: bool,
    /// `‖A‖₁`.
    a_norm: f64,
    /// `φ` sets of the two most recently used spans with this `A`, most recent first.
    families: [Family; 2],
    work: PhiWork,
    f0: Vec<f64>,
    fa: Vec<f64>,
    fb: Vec<f64>,
    xa: Vec<f64>,
    xb: Vec<f64>,
    d: Vec<f64>,
    db: Vec<f64>,
    err: Vec<f64>,
    x_new: Vec<f64>,
    /// Largest `drift · h‖A‖₁` at a step's start before the linear part is rebuilt there.
    refresh: f64,
    /// Same after a rejected step (rebuild and retry before reducing the step).
    refresh_on_reject: f64,
    /// Linear parts built and `φ` families computed since construction.
    refreshes: usize,
    phi_computes: usize,
}

/// Largest `drift · h‖A‖₁` at a step's start before the linear part is rebuilt there: the
/// stiff dynamics the frozen `A` misses, times the step. Measured on the paper scenario
/// (module docs of [`crate::integrator`]): 1 rebuilds 2.8× as often for no fewer steps.
const REFRESH: f64 = 10.0;

/// The same after a rejected step: below it the rejection is not the linear part's doing.
const REFRESH_ON_REJECT: f64 = 0.1;

/// Finest subdivision of a call's span: steps are `span/2ᵏ`, `k ≤ MAX_HALVINGS`, and the
/// position in the span is counted in units of `span/2^MAX_HALVINGS`.
const MAX_HALVINGS: u32 = 60;

impl Exponential {
    /// Integrator for systems of dimension `dim` with the given tolerances (validated).
    pub fn new(dim: usize, tol: Tolerances) -> Result<Self, IntegratorError> {
        tol.validate()?;
        let v = || vec![0.0; dim];
        let set = || PhiSet {
            h: 0.0,
            valid: false,
            half: vec![0.0; dim * dim],
            full: vec![0.0; dim * dim],
            second: vec![0.0; dim * dim],
            third: vec![0.0; dim * dim],
        };
        let family = || Family {
            span: 0.0,
            valid: false,
            sets: (0..LEVELS).map(|_| set()).collect(),
        };
        Ok(Self {
            dim,
            tol,
            h: tol.h_initial,
            a: vec![0.0; dim * dim],
            a_valid: false,
            a_norm: 0.0,
            families: [family(), family()],
            work: PhiWork::new(dim),
            f0: v(),
            fa: v(),
            fb: v(),
            xa: v(),
            xb: v(),
            d: v(),
            db: v(),
            err: v(),
            x_new: v(),
            refresh: REFRESH,
            refresh_on_reject: REFRESH_ON_REJECT,
            refreshes: 0,
            phi_computes: 0,
        })
    }

    /// The tolerances in use.
    pub fn tolerances(&self) -> &Tolerances {
        &self.tol
    }

    /// Step size the next call will try first, in s.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// Linear parts built since construction.
    pub fn refreshes(&self) -> usize {
        self.refreshes
    }

    /// Families of `φ` matrices computed since construction.
    pub fn phi_computations(&self) -> usize {
        self.phi_computes
    }

    /// Forgets the warm-start step size and the linear part.
    pub fn reset(&mut self) {
        self.h = self.tol.h_initial;
        self.a_valid = false;
        for f in &mut self.families {
            f.valid = false;
        }
    }

    /// Rebuilds the linear part at `x`.
    fn refresh_linear_part<S: LinearPart + ?Sized>(
        &mut self,
        sys: &mut S,
        t: f64,
        x: &[f64],
    ) -> bool {
        self.refreshes += 1;
        for f in &mut self.families {
            f.valid = false;
        }
        self.a_valid = sys.linear_part(t, x, &mut self.a) && self.a.iter().all(|v| v.is_finite());
        let m = self.dim;
        self.a_norm = (0..m)
            .map(|c| (0..m).map(|r| self.a[r * m + c].abs()).sum::<f64>())
            .fold(0.0, f64::max);
        self.a_valid
    }

    /// `(family, level)` of the cached `φ` set of the step `span/2ᵏ`, computing the family
    /// of `span` (or, beyond its levels, of the step itself) if missing; `None` if that
    /// failed.
    fn phi_for(&mut self, span: f64, k: u32) -> Option<(usize, usize)> {
        let h = span * 0.5_f64.powi(k as i32);
        for (i, f) in self.families.iter().enumerate() {
            if !f.valid {
                continue;
            }
            let ratio = f.span / h;
            let level = ratio.log2().round();
            if (0.0..LEVELS as f64).contains(&level) {
                let level = level as usize;
                if (f.sets[level].h - h).abs() <= 1e-12 * h {
                    return Some((i, level));
                }
            }
        }
        let base = if (k as usize) < LEVELS { span } else { h };
        // Replace the older family, keeping the most recent first.
        self.families.swap(0, 1);
        self.phi_computes += 1;
        let family = &mut self.families[0];
        family.valid = self.work.compute(&self.a, base, self.dim, &mut family.sets);
        family.span = base;
        let level = if (k as usize) < LEVELS { k as usize } else { 0 };
        family.valid.then_some((0, level))
    }

    /// Integrates `x` from `t0` to `t1 ≥ t0` with error control; `x` holds `x(t0)` on entry
    /// and `x(t1)` on success (on error: the last accepted state, at the reported `t`).
    /// Steps are `(t1 − t0)/2ᵏ`, the largest that fits the rest and the step size the error
    /// control wants: calls of the same length reuse the same `φ` matrices.
    pub fn integrate<S: LinearPart + ?Sized>(
        &mut self,
        sys: &mut S,
        t0: f64,
        t1: f64,
        x: &mut [f64],
    ) -> Result<Stats, IntegratorError> {
        check_call(self.dim, sys.dim(), x, t0, t1)?;
        if t1 < t0 {
            return Err(IntegratorError::InvalidTolerances { field: "t1 < t0" });
        }
        let mut stats = Stats::default();
        if t1 == t0 {
            return Ok(stats);
        }
        let tol = self.tol;
        let span = t1 - t0;
        let unit = span * 0.5_f64.powi(MAX_HALVINGS as i32);
        let total: u64 = 1 << MAX_HALVINGS;
        let mut pos: u64 = 0;
        let mut t = t0;
        let mut need_f0 = true;
        let mut attempts = 0usize;
        let mut last_rejected = false;
        let mut fresh = false;
        while pos < total {
            if attempts >= tol.max_steps {
                return Err(IntegratorError::TooManySteps { t });
            }
            attempts += 1;
            let h_wanted = self.h.clamp(tol.h_min, tol.h_max);
            // The largest span/2ᵏ within 1 % of the wanted step that fits the rest.
            let remaining = total - pos;
            let mut k = 0u32;
            while k < MAX_HALVINGS
                && ((1u64 << (MAX_HALVINGS - k)) > remaining
                    || span * 0.5_f64.powi(k as i32) > h_wanted * 1.01)
            {
                k += 1;
            }
            let h = span * 0.5_f64.powi(k as i32);
            if h < tol.h_min {
                return Err(IntegratorError::StepTooSmall { t, h });
            }
            if need_f0 {
                stats.rhs_evals += 1;
                if !sys.rhs(t, x, &mut self.f0) || self.f0.iter().any(|v| !v.is_finite()) {
                    return Err(IntegratorError::NonFinite { t });
                }
                need_f0 = false;
                fresh = false;
                if !self.a_valid || sys.drift(x) * h * self.a_norm > self.refresh {
                    stats.w_factorizations += 1;
                    if !self.refresh_linear_part(sys, t, x) {
                        return Err(IntegratorError::WFailed { t });
                    }
                    fresh = true;
                }
            }
            let Some((fam, level)) = self.phi_for(span, k) else {
                return Err(IntegratorError::WFailed { t });
            };
            let phi = &self.families[fam].sets[level];
            // ETD3RK (Cox & Matthews) in the form x + hφ₁(hA) f(x) = e^{hA} x + hφ₁ N(x):
            // a = x + (h/2)φ₁(hA/2) f(x); b = x + hφ₁ (f(x) + 2 (N(a) − N(x)));
            // x₁ = x + hφ₁ f(x) + h(4φ₂ − 8φ₃)(N(a) − N(x)) + h(4φ₃ − φ₂)(N(b) − N(x));
            // the embedded order-2 solution (c₂ = ½) x̂₁ = x + hφ₁ f(x) + 2hφ₂ (N(a) − N(x)),
            // so x₁ − x̂₁ = h(4φ₃ − φ₂)(N(b) − 2N(a) + N(x)). N(y) − N(x) = f(y) − f(x) − A (y − x).
            mat_vec(&phi.half, &self.f0, &mut self.d);
            for ((xa, x), d) in self.xa.iter_mut().zip(x.iter()).zip(&self.d) {
                *xa = x + d;
            }
            stats.rhs_evals += 1;
            let mut ok = sys.rhs(t + 0.5 * h, &self.xa, &mut self.fa)
                && self.fa.iter().all(|v| v.is_finite());
            let mut en = f64::INFINITY;
            if ok {
                // d = N(a) − N(x), using xb as scratch.
                mat_vec(&self.a, &self.d, &mut self.xb);
                for ((d, fa), (f0, ad)) in self
                    .d
                    .iter_mut()
                    .zip(&self.fa)
                    .zip(self.f0.iter().zip(&self.xb))
                {
                    *d = fa - f0 - ad;
                }
                for ((e, f0), d) in self.err.iter_mut().zip(&self.f0).zip(&self.d) {
                    *e = f0 + 2.0 * d;
                }
                mat_vec(&phi.full, &self.err, &mut self.db);
                for ((xb, x), db) in self.xb.iter_mut().zip(x.iter()).zip(&self.db) {
                    *xb = x + db;
                }
                stats.rhs_evals += 1;
                ok =
                    sys.rhs(t + h, &self.xb, &mut self.fb) && self.fb.iter().all(|v| v.is_finite());
                if ok {
                    // db = N(b) − N(x) (b − x is in db).
                    mat_vec(&self.a, &self.db, &mut self.err);
                    for ((db, fb), (f0, ad)) in self
                        .db
                        .iter_mut()
                        .zip(&self.fb)
                        .zip(self.f0.iter().zip(&self.err))
                    {
                        *db = fb - f0 - ad;
                    }
                    // x₁ = x + hφ₁ f0 + second·d + third·db; err = third·(db − 2d).
                    mat_vec(&phi.full, &self.f0, &mut self.x_new);
                    mat_vec(&phi.second, &self.d, &mut self.fa);
                    mat_vec(&phi.third, &self.db, &mut self.fb);
                    for (((xn, x), sa), sb) in self
                        .x_new
                        .iter_mut()
                        .zip(x.iter())
                        .zip(&self.fa)
                        .zip(&self.fb)
                    {
                        *xn += x + sa + sb;
                    }
                    for (db, d) in self.db.iter_mut().zip(&self.d) {
                        *db -= 2.0 * d;
                    }
                    mat_vec(&phi.third, &self.db, &mut self.err);
                    en = error_norm(&tol, x, &self.x_new, &self.err);
                }
            }
            if en <= 1.0 {
                stats.steps += 1;
                pos += 1u64 << (MAX_HALVINGS - k);
                t = if pos == total {
                    t1
                } else {
                    t0 + pos as f64 * unit
                };
                x.copy_from_slice(&self.x_new);
                need_f0 = true;
                let mut fac = (0.9 * en.max(1e-10).powf(-1.0 / 3.0)).clamp(0.2, 4.0);
                if last_rejected {
                    fac = fac.min(1.0);
                }
                // A step cut to fit the rest says little about the step size wanted.
                let cut = h < h_wanted * 0.99;
                self.h = (h * fac)
                    .max(if cut { h_wanted } else { 0.0 })
                    .min(tol.h_max);
                last_rejected = false;
            } else {
                stats.rejected += 1;
                last_rejected = true;
                if !fresh && sys.drift(x) * h * self.a_norm > self.refresh_on_reject {
                    // The frozen linear part may be what failed: rebuild it here and retry
                    // the same step (f(x) is still in f0).
                    stats.w_factorizations += 1;
                    if !self.refresh_linear_part(sys, t, x) {
                        return Err(IntegratorError::WFailed { t });
                    }
                    fresh = true;
                    continue;
                }
                self.h = shrink_after_rejection(h, en, 3.0, 0.1, &tol, t)?;
            }
        }
        Ok(stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `φ` sets of a mechanical linear part computed with its structure agree with
    /// the general computation to rounding, at every level.
    #[test]
    fn structured_phi_sets_agree_with_the_general_ones() {
        let n = 6;
        let m = 2 * n;
        // [[0, I], [−M⁻¹K, −M⁻¹D]] for an SPD M with entries from 0.05 to 2.7 and stiff
        // K, D, as the paper robot's.
        let mut minv = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                minv[i * n + j] = if i == j {
                    20.0 / (1.0 + i as f64)
                } else {
                    0.3 * ((i + 2 * j) as f64).sin()
                };
            }
        }
        let stiffness = [6250.0, 6250.0, 10.0, 6250.0, 6250.0, 10.0];
        let damping = [3125.0, 3125.0, 5.0, 3125.0, 3125.0, 5.0];
        let mut a = vec![0.0; m * m];
        for i in 0..n {
            a[i * m + n + i] = 1.0;
            for j in 0..n {
                let v = 0.5 * (minv[i * n + j] + minv[j * n + i]);
                a[(n + i) * m + j] = -v * stiffness[j];
                a[(n + i) * m + n + j] = -v * damping[j];
            }
        }
        assert!(is_mechanical(&a, m));
        let set = || PhiSet {
            h: 0.0,
            valid: false,
            half: vec![0.0; m * m],
            full: vec![0.0; m * m],
            second: vec![0.0; m * m],
            third: vec![0.0; m * m],
        };
        let mut worst = 0.0_f64;
        for span in [1e-3, 1e-5] {
            let mut general: Vec<PhiSet> = (0..LEVELS).map(|_| set()).collect();
            let mut structured: Vec<PhiSet> = (0..LEVELS).map(|_| set()).collect();
            let mut work = PhiWork::new(m);
            assert!(work.compute_with(&a, span, m, &mut general, false));
            assert!(work.compute_with(&a, span, m, &mut structured, true));
            for (g, s) in general.iter().zip(&structured) {
                assert_eq!(g.h, s.h);
                for (gm, sm) in [(&g.half, &s.half), (&g.full, &s.full)]
                    .into_iter()
                    .chain([(&g.second, &s.second), (&g.third, &s.third)])
                {
                    // Relative to each row's largest entry: the rows of q and of q̇ differ
                    // in scale by about ‖A‖.
                    for (gr, sr) in gm.chunks_exact(m).zip(sm.chunks_exact(m)) {
                        let size = gr.iter().fold(0.0_f64, |acc, v| acc.max(v.abs()));
                        for (x, y) in gr.iter().zip(sr) {
                            worst = worst.max((x - y).abs() / size);
                        }
                    }
                }
            }
        }
        println!("largest difference relative to the row: {worst:e}");
        assert!(worst < 1e-12, "{worst:e}");
        // Not mechanical: a perturbed upper half.
        a[1] = 1e-3;
        assert!(!is_mechanical(&a, m));
    }
}
