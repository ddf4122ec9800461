//! Double-double (≈32 significant digits) arithmetic and the high-precision reference for
//! the small-θ functions f_s(u) = sin√u/√u, f_c(u) = (1 − cos√u)/u and their u-derivatives.

use std::cmp::Ordering;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// An unevaluated sum `hi + lo` with `|lo| ≤ ulp(hi)/2`: about 106 significant bits.
///
/// Products use Dekker's splitting (no fused multiply-add needed), which is exact for
/// operands below about 1e300 in magnitude; that is ample for the series evaluated here.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DD {
    /// Leading part (the value rounded to f64).
    pub hi: f64,
    /// Trailing part.
    pub lo: f64,
}

/// `a + b` exactly as `s + e`.
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// `a + b` exactly as `s + e`, given `|a| ≥ |b|`.
fn quick_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

/// Dekker's split of `a` into two halves of 26 significant bits.
fn split(a: f64) -> (f64, f64) {
    let t = 134_217_729.0 * a; // 2^27 + 1
    let hi = t - (t - a);
    (hi, a - hi)
}

/// `a · b` exactly as `p + e`.
fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    let e = ((ah * bh - p) + ah * bl + al * bh) + al * bl;
    (p, e)
}

impl DD {
    /// Zero.
    pub const ZERO: DD = DD { hi: 0.0, lo: 0.0 };
    /// One.
    pub const ONE: DD = DD { hi: 1.0, lo: 0.0 };
    /// π rounded to double-double (checked against Machin's formula in the unit tests).
    pub const PI: DD = DD {
        hi: std::f64::consts::PI,
        lo: 1.224_646_799_147_353_2e-16,
    };

    /// The exact value of `x`.
    pub const fn from_f64(x: f64) -> DD {
        DD { hi: x, lo: 0.0 }
    }

    /// Nearest f64 (the leading part of a normalized pair).
    pub fn to_f64(self) -> f64 {
        self.hi + self.lo
    }

    /// Absolute value.
    pub fn abs(self) -> DD {
        if self.hi < 0.0 { -self } else { self }
    }

    /// Square root (Newton step from the f64 root); `sqrt(0) = 0`.
    pub fn sqrt(self) -> DD {
        if self.hi <= 0.0 {
            return DD::from_f64(self.hi.sqrt());
        }
        let x = self.hi.sqrt();
        let (p, e) = two_prod(x, x);
        let residual = (self - DD { hi: p, lo: e }).hi;
        let (s, t) = quick_two_sum(x, residual / (2.0 * x));
        DD { hi: s, lo: t }
    }

    /// `x` times a power of two or a small integer held exactly in f64.
    pub fn mul_f64(self, b: f64) -> DD {
        let (p, e) = two_prod(self.hi, b);
        let (hi, lo) = quick_two_sum(p, e + self.lo * b);
        DD { hi, lo }
    }

    /// Sine and cosine, with the argument reduced by multiples of π/2 in double-double.
    ///
    /// Accurate to ~1e-31 absolute for `|x|` up to a few hundred.
    pub fn sin_cos(self) -> (DD, DD) {
        let half_pi = DD::PI.mul_f64(0.5);
        let k = (self / half_pi).to_f64().round();
        let r = self - half_pi.mul_f64(k);
        let (s, c) = sin_cos_taylor(r);
        match (k.rem_euclid(4.0)) as i64 {
            0 => (s, c),
            1 => (c, -s),
            2 => (-s, -c),
            _ => (-c, s),
        }
    }
}

/// Taylor series of sin and cos for `|r| ≤ π/4`, summed to below 1e-34.
fn sin_cos_taylor(r: DD) -> (DD, DD) {
    let r2 = r * r;
    let mut sin = DD::ZERO;
    let mut cos = DD::ZERO;
    let mut term = DD::ONE; // r^n / n!
    let mut n = 0.0_f64;
    while n < 60.0 {
        if term.hi.abs() < 1e-36 {
            break;
        }
        // even n: cos term; the sine term is term·r/(n+1).
        let sign = if (n / 2.0).rem_euclid(2.0) == 0.0 {
            1.0
        } else {
            -1.0
        };
        cos = cos + term.mul_f64(sign);
        let odd = (term * r) / DD::from_f64(n + 1.0);
        sin = sin + odd.mul_f64(sign);
        term = (term * r2) / DD::from_f64((n + 1.0) * (n + 2.0));
        n += 2.0;
    }
    (sin, cos)
}

impl From<f64> for DD {
    fn from(x: f64) -> DD {
        DD::from_f64(x)
    }
}

impl Neg for DD {
    type Output = DD;
    fn neg(self) -> DD {
        DD {
            hi: -self.hi,
            lo: -self.lo,
        }
    }
}

impl Add for DD {
    type Output = DD;
    fn add(self, b: DD) -> DD {
        let (s, e) = two_sum(self.hi, b.hi);
        let (t, f) = two_sum(self.lo, b.lo);
        let (s, e) = quick_two_sum(s, e + t);
        let (hi, lo) = quick_two_sum(s, e + f);
        DD { hi, lo }
    }
}

impl Sub for DD {
    type Output = DD;
    fn sub(self, b: DD) -> DD {
        self + (-b)
    }
}

impl Mul for DD {
    type Output = DD;
    fn mul(self, b: DD) -> DD {
        let (p, e) = two_prod(self.hi, b.hi);
        let (hi, lo) = quick_two_sum(p, e + (self.hi * b.lo + self.lo * b.hi));
        DD { hi, lo }
    }
}

impl Div for DD {
    type Output = DD;
    fn div(self, b: DD) -> DD {
        let q1 = self.hi / b.hi;
        let r = self - b.mul_f64(q1);
        let q2 = r.hi / b.hi;
        let r = r - b.mul_f64(q2);
        let q3 = r.hi / b.hi;
        let (hi, lo) = quick_two_sum(q1, q2);
        DD { hi, lo } + DD::from_f64(q3)
    }
}

impl PartialOrd for DD {
    fn partial_cmp(&self, other: &DD) -> Option<Ordering> {
        match self.hi.partial_cmp(&other.hi) {
            Some(Ordering::Equal) => self.lo.partial_cmp(&other.lo),
            ord => ord,
        }
    }
}

/// `u` above which [`fs_fc_reference`] switches from the power series to the recurrences
/// on double-double sin/cos (θ = 12, where the series has lost ~5 of its 32 digits).
pub const SERIES_LIMIT: f64 = 144.0;

/// `f_s^(k)(u)` and `f_c^(k)(u)` for `k = 0..=order` in double-double, for `u ≥ 0`.
///
/// For `u ≤` [`SERIES_LIMIT`] straight from the definitions' power series
/// `f_s = Σ (−u)^n/(2n+1)!`, `f_c = Σ (−u)^n/(2n+2)!` differentiated term by term;
/// above it from the upward recurrences on double-double `sin√u`, `cos√u` (stable there
/// for `order ≤ 8`; cross-checked against the series in the unit tests). Relative error
/// ≈1e-27 away from the functions' zeros for `u ≤ 144`, ≈1e-28 absolute in units of
/// `|f^(k)(0)|` elsewhere.
pub fn fs_fc_reference(u: f64, order: usize) -> (Vec<DD>, Vec<DD>) {
    if u <= SERIES_LIMIT {
        fs_fc_series(u, order)
    } else {
        fs_fc_recurrence(u, order)
    }
}

/// The power series of `f_s^(k)` (`first = 1`) or `f_c^(k)` (`first = 2`) at `u`:
/// `Σ_n (−1)^(n+k) (n+k)!/n! · u^n/(2n+2k+first)!`.
fn series(u: DD, k: usize, first: usize) -> DD {
    // Leading coefficient (−1)^k k!/(2k+first)!.
    let mut term = DD::ONE;
    for j in (k + 1)..=(2 * k + first) {
        term = term / DD::from_f64(j as f64);
    }
    if !k.is_multiple_of(2) {
        term = -term;
    }
    let mut sum = DD::ZERO;
    let mut largest = 0.0_f64;
    for n in 0..400_usize {
        sum = sum + term;
        largest = largest.max(term.hi.abs());
        let (nf, kf, ff) = (n as f64, k as f64, first as f64);
        let den = (nf + 1.0) * (2.0 * nf + 2.0 * kf + ff + 1.0) * (2.0 * nf + 2.0 * kf + ff + 2.0);
        let ratio = (nf + kf + 1.0) / den; // exact enough: ratio of two exact integers
        let next = -(term * u) * DD::from_f64(nf + kf + 1.0) / DD::from_f64(den);
        // Stop once the terms decrease fast and are negligible (alternating: the tail
        // is bounded by the first omitted term).
        if u.hi * ratio < 0.5 && next.hi.abs() <= 1e-36 * largest {
            break;
        }
        term = next;
    }
    sum
}

/// Series evaluation of all orders.
fn fs_fc_series(u: f64, order: usize) -> (Vec<DD>, Vec<DD>) {
    let ud = DD::from_f64(u);
    let fs = (0..=order).map(|k| series(ud, k, 1)).collect();
    let fc = (0..=order).map(|k| series(ud, k, 2)).collect();
    (fs, fc)
}

/// Closed forms and the upward recurrences, in double-double (for large `u`):
/// `f_s' = (cos√u − f_s)/(2u)`, `f_s^(k+1) = (−f_s^(k−1)/2 − (2k+1) f_s^(k))/(2u)`,
/// `f_c^(k+1) = (f_s^(k)/2 − (k+1) f_c^(k))/u`.
pub fn fs_fc_recurrence(u: f64, order: usize) -> (Vec<DD>, Vec<DD>) {
    let ud = DD::from_f64(u);
    let theta = ud.sqrt();
    let (s, c) = theta.sin_cos();
    let mut fs = vec![s / theta];
    let mut fc = vec![(DD::ONE - c) / ud];
    for k in 0..order {
        let kf = k as f64;
        let prev = if k == 0 { c } else { -fs[k - 1].mul_f64(0.5) };
        let next_s = (prev - fs[k].mul_f64(2.0 * kf + 1.0)) / ud.mul_f64(2.0);
        let next_c = (fs[k].mul_f64(0.5) - fc[k].mul_f64(kf + 1.0)) / ud;
        fs.push(next_s);
        fc.push(next_c);
    }
    (fs, fc)
}

/// Exact limits at `u = 0`: `f_s^(k)(0) = (−1)^k k!/(2k+1)!`, `f_c^(k)(0) = (−1)^k k!/(2k+2)!`,
/// as double-double (from the factorial products, not from the series code).
pub fn limits_at_zero(k: usize) -> (DD, DD) {
    let mut fs = DD::ONE;
    for j in (k + 1)..=(2 * k + 1) {
        fs = fs / DD::from_f64(j as f64);
    }
    let mut fc = fs / DD::from_f64((2 * k + 2) as f64);
    if !k.is_multiple_of(2) {
        fs = -fs;
        fc = -fc;
    }
    (fs, fc)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rel(a: DD, b: DD) -> f64 {
        ((a - b).abs().to_f64()) / b.abs().to_f64()
    }

    #[test]
    fn arithmetic_identities() {
        let two = DD::from_f64(2.0);
        let r = two.sqrt();
        assert!(rel(r * r, two) < 1e-31);
        let third = DD::ONE / DD::from_f64(3.0);
        assert!(rel(third.mul_f64(3.0), DD::ONE) < 1e-31);
        // 1/3 is not an f64: the low part must carry the rest.
        assert!(third.lo != 0.0);
        let x = DD::from_f64(0.1) + DD::from_f64(1e-20);
        assert!(rel((x * x).sqrt(), x) < 1e-31);
        assert!(rel((x * third) / third, x) < 1e-31);
    }

    /// π from Machin's formula π = 16 atan(1/5) − 4 atan(1/239).
    #[test]
    fn pi_matches_machin() {
        let atan_inv = |m: f64| {
            let x = DD::ONE / DD::from_f64(m);
            let x2 = x * x;
            let mut pow = x;
            let mut sum = DD::ZERO;
            for n in 0..60 {
                let t = pow / DD::from_f64((2 * n + 1) as f64);
                sum = if n % 2 == 0 { sum + t } else { sum - t };
                pow = pow * x2;
            }
            sum
        };
        let pi = atan_inv(5.0).mul_f64(16.0) - atan_inv(239.0).mul_f64(4.0);
        assert!((pi - DD::PI).abs().to_f64() < 1e-31, "{pi:?}");
    }

    #[test]
    fn sin_cos_known_values() {
        for &x in &[0.3, 1.0, 2.5, 7.0, 20.0, 100.0] {
            let (s, c) = DD::from_f64(x).sin_cos();
            assert!(((s * s + c * c) - DD::ONE).abs().to_f64() < 1e-30);
            assert!((s.to_f64() - x.sin()).abs() < 1e-15);
            assert!((c.to_f64() - x.cos()).abs() < 1e-15);
        }
        let (s, c) = (DD::PI / DD::from_f64(6.0)).sin_cos();
        assert!((s - DD::from_f64(0.5)).abs().to_f64() < 1e-31);
        assert!((c * c - DD::from_f64(0.75)).abs().to_f64() < 1e-31);
    }

    /// The series of f_s and f_c agree with sin√u/√u and (1 − cos√u)/u in double-double.
    #[test]
    fn series_match_definitions() {
        for &u in &[1e-3, 0.5, 2.0, 9.0, 30.0, 100.0] {
            let (fs, fc) = fs_fc_series(u, 0);
            let ud = DD::from_f64(u);
            let t = ud.sqrt();
            let (s, c) = t.sin_cos();
            assert!(rel(fs[0], s / t) < 1e-27, "u={u}");
            assert!(rel(fc[0], (DD::ONE - c) / ud) < 1e-27, "u={u}");
        }
    }

    /// Series (from the definition) and recurrences (derived by hand) agree where both are
    /// accurate, which checks the recurrences used above SERIES_LIMIT and in the generator.
    #[test]
    fn series_match_recurrences() {
        for &u in &[40.0, 80.0, 120.0, 144.0] {
            let (ss, sc) = fs_fc_series(u, 8);
            let (rs, rc) = fs_fc_recurrence(u, 8);
            for k in 0..=8 {
                let (s0, c0) = limits_at_zero(k);
                let es = (ss[k] - rs[k]).abs().to_f64() / s0.abs().to_f64();
                let ec = (sc[k] - rc[k]).abs().to_f64() / c0.abs().to_f64();
                assert!(es < 1e-25 && ec < 1e-25, "u={u} k={k} {es:e} {ec:e}");
            }
        }
    }

    /// Term-by-term derivatives agree with central differences of the series itself.
    #[test]
    fn series_derivatives_match_differences() {
        let h = 1e-10;
        for &u in &[0.7, 5.0, 50.0] {
            let (fs, fc) = fs_fc_series(u, 3);
            let (up, um) = (u + h, u - h);
            let (ps, pc) = fs_fc_series(up, 3);
            let (ms, mc) = fs_fc_series(um, 3);
            for k in 0..3 {
                let ds = (ps[k] - ms[k]).to_f64() / (up - um);
                let dc = (pc[k] - mc[k]).to_f64() / (up - um);
                assert!((ds - fs[k + 1].to_f64()).abs() < 1e-12, "u={u} k={k}");
                assert!((dc - fc[k + 1].to_f64()).abs() < 1e-12, "u={u} k={k}");
            }
        }
    }

    #[test]
    fn limits_at_zero_match_series() {
        let (fs, fc) = fs_fc_series(0.0, 6);
        for k in 0..=6 {
            let (s0, c0) = limits_at_zero(k);
            assert_eq!(fs[k], s0);
            assert_eq!(fc[k], c0);
        }
        assert_eq!(limits_at_zero(0).1.to_f64(), 0.5);
        assert_eq!(limits_at_zero(1).0.to_f64(), -1.0 / 6.0);
    }
}
