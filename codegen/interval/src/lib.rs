//! Closed intervals `[lo, hi]` of `f64` with outward rounding: every operation returns an
//! interval that contains the exact result of the operation applied to any points of its
//! operands (docs/model.md §5, the certified filter's enclosures).
//!
//! Rounding: each bound is computed in round-to-nearest and then moved outward by
//! `|x|·2⁻⁵¹ + 2⁻¹⁰⁷³` (two units in the last place of a normal number, two of the smallest
//! subnormal). Round-to-nearest is within half a unit of the exact value, and the move, itself
//! rounded to nearest, lands at least one and a half units further out, so the moved bound is
//! on the safe side whatever the operation; this costs a few ulps of width per operation,
//! needs no change of the rounding mode and no branch (measured: a quarter of the cost of
//! `next_down`/`next_up`).
//!
//! Infinite bounds are allowed (a division by an interval holding zero gives
//! [`Interval::ENTIRE`]); a NaN bound marks an invalid interval ([`Interval::is_valid`]), and
//! callers check their results once at the end, as the generated code does for `f64`.
//!
//! Operators take intervals and `f64` on either side, so that code written for `f64`
//! (the emitted model functions) compiles for intervals with state inputs made intervals
//! and parameters left as `f64`.

use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// A closed interval `[lo, hi]` of real numbers, `lo ≤ hi` (either may be infinite).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    lo: f64,
    hi: f64,
}

impl Default for Interval {
    fn default() -> Interval {
        Interval::ZERO
    }
}

/// `2⁻⁵¹`: two units in the last place relative to the magnitude.
const RELATIVE: f64 = 4.440_892_098_500_626e-16;
/// `2⁻¹⁰⁷³`: two units of the smallest subnormal (covers results that underflow).
const ABSOLUTE: f64 = 1e-323;

#[inline(always)]
fn down(x: f64) -> f64 {
    x - (x.abs() * RELATIVE + ABSOLUTE)
}

#[inline(always)]
fn up(x: f64) -> f64 {
    x + (x.abs() * RELATIVE + ABSOLUTE)
}

impl Interval {
    /// `[0, 0]`.
    pub const ZERO: Interval = Interval { lo: 0.0, hi: 0.0 };
    /// The whole real line.
    pub const ENTIRE: Interval = Interval {
        lo: f64::NEG_INFINITY,
        hi: f64::INFINITY,
    };
    /// An invalid interval (both bounds NaN).
    pub const NAN: Interval = Interval {
        lo: f64::NAN,
        hi: f64::NAN,
    };

    /// `[lo, hi]`; invalid ([`Interval::NAN`]) if either is NaN or `lo > hi`.
    #[inline]
    pub fn new(lo: f64, hi: f64) -> Interval {
        if lo <= hi {
            Interval { lo, hi }
        } else {
            Interval::NAN
        }
    }

    /// The point `[x, x]` (exact: `x` is a number).
    #[inline]
    pub const fn point(x: f64) -> Interval {
        Interval { lo: x, hi: x }
    }

    /// `[c − r, c + r]` rounded outward, for `r ≥ 0`.
    #[inline]
    pub fn around(center: f64, radius: f64) -> Interval {
        let r = radius.abs();
        Interval::new(down(center - r), up(center + r))
    }

    /// The smallest interval holding both.
    #[inline]
    pub fn hull(self, other: Interval) -> Interval {
        if !(self.is_valid() && other.is_valid()) {
            return Interval::NAN;
        }
        Interval {
            lo: self.lo.min(other.lo),
            hi: self.hi.max(other.hi),
        }
    }

    /// The smallest interval holding `self` and the number `x`.
    #[inline]
    pub fn hull_point(self, x: f64) -> Interval {
        self.hull(Interval::point(x))
    }

    /// This interval widened by `r ≥ 0` on both sides (rounded outward).
    #[inline]
    pub fn widened(self, r: f64) -> Interval {
        let r = r.abs();
        Interval::new(down(self.lo - r), up(self.hi + r))
    }

    /// Lower bound.
    #[inline]
    pub fn lo(self) -> f64 {
        self.lo
    }

    /// Upper bound.
    #[inline]
    pub fn hi(self) -> f64 {
        self.hi
    }

    /// The midpoint (a number inside the interval for finite bounds).
    #[inline]
    pub fn mid(self) -> f64 {
        let m = 0.5 * self.lo + 0.5 * self.hi;
        m.clamp(self.lo, self.hi)
    }

    /// A radius `r` with `[mid − r, mid + r] ⊇ self` (rounded up).
    #[inline]
    pub fn rad(self) -> f64 {
        let m = self.mid();
        up((self.hi - m).max(m - self.lo))
    }

    /// `max |x|` over the interval (the magnitude).
    #[inline]
    pub fn mag(self) -> f64 {
        self.lo.abs().max(self.hi.abs())
    }

    /// `hi − lo`, rounded up.
    #[inline]
    pub fn width(self) -> f64 {
        up(self.hi - self.lo)
    }

    /// Both bounds are numbers and `lo ≤ hi`.
    #[inline]
    pub fn is_valid(self) -> bool {
        self.lo <= self.hi
    }

    /// Valid with finite bounds.
    #[inline]
    pub fn is_finite(self) -> bool {
        self.is_valid() && self.lo.is_finite() && self.hi.is_finite()
    }

    /// Whether `x` lies in the interval.
    #[inline]
    pub fn contains(self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }

    /// Whether `self ⊆ other`.
    #[inline]
    pub fn subset_of(self, other: Interval) -> bool {
        other.lo <= self.lo && self.hi <= other.hi
    }

    /// `[x², …]`: the square, tighter than `x * x` when the interval holds zero.
    #[inline]
    pub fn square(self) -> Interval {
        if !self.is_valid() {
            return Interval::NAN;
        }
        let (a, b) = (self.lo * self.lo, self.hi * self.hi);
        if self.lo >= 0.0 {
            Interval::new(down(a), up(b))
        } else if self.hi <= 0.0 {
            Interval::new(down(b), up(a))
        } else {
            Interval::new(0.0, up(a.max(b)))
        }
    }

    /// `√x` over the part of the interval at or above zero (the callers take roots of sums
    /// of squares, which are never negative: a lower bound below zero is widening only).
    /// Invalid if the whole interval is below zero.
    #[inline]
    pub fn sqrt(self) -> Interval {
        // `hi` below zero or NaN: nothing to take a root of.
        if self.hi.is_nan() || self.hi < 0.0 {
            return Interval::NAN;
        }
        let lo = self.lo.max(0.0);
        Interval::new(down(lo.sqrt()).max(0.0), up(self.hi.sqrt()))
    }

    /// `sin` by the mean-value form `sin(m) ± r` (|sin′| ≤ 1), within `[−1, 1]`. The `f64`
    /// `sin` of the midpoint is taken as correct to 1e-15 absolute.
    #[inline]
    pub fn sin(self) -> Interval {
        self.lipschitz_unit(f64::sin)
    }

    /// `cos` as [`Interval::sin`].
    #[inline]
    pub fn cos(self) -> Interval {
        self.lipschitz_unit(f64::cos)
    }

    fn lipschitz_unit(self, f: fn(f64) -> f64) -> Interval {
        if !self.is_finite() {
            return if self.is_valid() {
                Interval::new(-1.0, 1.0)
            } else {
                Interval::NAN
            };
        }
        let r = self.rad() + 1e-15;
        let c = f(self.mid());
        Interval::new(down(c - r).max(-1.0), up(c + r).min(1.0))
    }

    /// `1 / x`; [`Interval::ENTIRE`] when the interval holds zero.
    #[inline]
    pub fn recip(self) -> Interval {
        if !self.is_valid() {
            return Interval::NAN;
        }
        if self.lo > 0.0 || self.hi < 0.0 {
            Interval::new(down(1.0 / self.hi), up(1.0 / self.lo))
        } else {
            Interval::ENTIRE
        }
    }

    /// `x^n` for small integer `n` (by repeated products; negative `n` through
    /// [`Interval::recip`]).
    pub fn powi(self, n: i32) -> Interval {
        match n {
            0 => Interval::point(1.0),
            1 => self,
            2 => self.square(),
            n if n < 0 => self.powi(-n).recip(),
            n => {
                let mut out = self;
                for _ in 1..n {
                    out *= self;
                }
                out
            }
        }
    }
}

impl From<f64> for Interval {
    #[inline]
    fn from(x: f64) -> Interval {
        Interval::point(x)
    }
}

impl Neg for Interval {
    type Output = Interval;
    #[inline]
    fn neg(self) -> Interval {
        Interval {
            lo: -self.hi,
            hi: -self.lo,
        }
    }
}

impl Add for Interval {
    type Output = Interval;
    #[inline]
    fn add(self, other: Interval) -> Interval {
        Interval {
            lo: down(self.lo + other.lo),
            hi: up(self.hi + other.hi),
        }
    }
}

impl Sub for Interval {
    type Output = Interval;
    #[inline]
    fn sub(self, other: Interval) -> Interval {
        Interval {
            lo: down(self.lo - other.hi),
            hi: up(self.hi - other.lo),
        }
    }
}

impl Mul for Interval {
    type Output = Interval;
    #[inline]
    fn mul(self, other: Interval) -> Interval {
        let (a, b) = (self.lo * other.lo, self.lo * other.hi);
        let (c, d) = (self.hi * other.lo, self.hi * other.hi);
        if a.is_nan() && b.is_nan() && c.is_nan() && d.is_nan() {
            return Interval::NAN;
        }
        Interval {
            lo: down(a.min(b).min(c.min(d))),
            hi: up(a.max(b).max(c.max(d))),
        }
    }
}

impl Div for Interval {
    type Output = Interval;
    #[inline]
    // Division is multiplication by the enclosure of the reciprocal (outward rounded both
    // times, so the quotient's enclosure holds).
    #[allow(clippy::suspicious_arithmetic_impl)]
    fn div(self, other: Interval) -> Interval {
        self * other.recip()
    }
}

impl Add<f64> for Interval {
    type Output = Interval;
    #[inline]
    fn add(self, x: f64) -> Interval {
        Interval {
            lo: down(self.lo + x),
            hi: up(self.hi + x),
        }
    }
}

impl Add<Interval> for f64 {
    type Output = Interval;
    #[inline]
    fn add(self, x: Interval) -> Interval {
        x + self
    }
}

impl Sub<f64> for Interval {
    type Output = Interval;
    #[inline]
    fn sub(self, x: f64) -> Interval {
        Interval {
            lo: down(self.lo - x),
            hi: up(self.hi - x),
        }
    }
}

impl Sub<Interval> for f64 {
    type Output = Interval;
    #[inline]
    fn sub(self, x: Interval) -> Interval {
        Interval {
            lo: down(self - x.hi),
            hi: up(self - x.lo),
        }
    }
}

impl Mul<f64> for Interval {
    type Output = Interval;
    #[inline]
    fn mul(self, x: f64) -> Interval {
        let (a, b) = (self.lo * x, self.hi * x);
        if x >= 0.0 {
            Interval {
                lo: down(a),
                hi: up(b),
            }
        } else if x < 0.0 {
            Interval {
                lo: down(b),
                hi: up(a),
            }
        } else {
            Interval::NAN
        }
    }
}

impl Mul<Interval> for f64 {
    type Output = Interval;
    #[inline]
    fn mul(self, x: Interval) -> Interval {
        x * self
    }
}

impl Div<f64> for Interval {
    type Output = Interval;
    #[inline]
    fn div(self, x: f64) -> Interval {
        if x == 0.0 || x.is_nan() {
            return if x == 0.0 {
                Interval::ENTIRE
            } else {
                Interval::NAN
            };
        }
        let (a, b) = (self.lo / x, self.hi / x);
        if x > 0.0 {
            Interval {
                lo: down(a),
                hi: up(b),
            }
        } else {
            Interval {
                lo: down(b),
                hi: up(a),
            }
        }
    }
}

impl Div<Interval> for f64 {
    type Output = Interval;
    #[inline]
    // As for `Interval / Interval`: times the reciprocal's enclosure.
    #[allow(clippy::suspicious_arithmetic_impl)]
    fn div(self, x: Interval) -> Interval {
        x.recip() * self
    }
}

impl AddAssign for Interval {
    #[inline]
    fn add_assign(&mut self, other: Interval) {
        *self = *self + other;
    }
}

impl SubAssign for Interval {
    #[inline]
    fn sub_assign(&mut self, other: Interval) {
        *self = *self - other;
    }
}

impl MulAssign for Interval {
    #[inline]
    fn mul_assign(&mut self, other: Interval) {
        *self = *self * other;
    }
}

impl AddAssign<f64> for Interval {
    #[inline]
    fn add_assign(&mut self, x: f64) {
        *self = *self + x;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (SplitMix64) for the property checks.
    struct Draws(u64);

    impl Draws {
        fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 53) as f64
        }

        fn interval(&mut self) -> (Interval, [f64; 5]) {
            let center = 4.0 * self.next() - 2.0;
            let width = if self.next() < 0.2 { 0.0 } else { self.next() };
            let x = Interval::new(center - width, center + width);
            let points = [
                x.lo(),
                x.hi(),
                x.lo() + (x.hi() - x.lo()) * self.next(),
                x.lo() + (x.hi() - x.lo()) * self.next(),
                x.mid(),
            ];
            (x, points)
        }
    }

    /// Every operation's result holds the operation at points of its operands (the points
    /// computed in f64, the interval outward-rounded).
    #[test]
    fn operations_enclose_their_point_values() {
        let mut draws = Draws(7);
        for _ in 0..20_000 {
            let (x, xs) = draws.interval();
            let (y, ys) = draws.interval();
            let k = 6.0 * draws.next() - 3.0;
            for &a in &xs {
                assert!((-x).contains(-a));
                assert!(x.square().contains(a * a), "{x:?}² ∌ {}", a * a);
                assert!((x * k).contains(a * k));
                assert!((k * x).contains(k * a));
                assert!((x + k).contains(a + k));
                assert!((k - x).contains(k - a));
                if a >= 0.0 {
                    assert!(x.sqrt().contains(a.sqrt()));
                }
                assert!(x.sin().contains(a.sin()));
                assert!(x.cos().contains(a.cos()));
                if !x.contains(0.0) {
                    assert!(x.recip().contains(1.0 / a));
                    assert!((k / x).contains(k / a));
                }
                for &b in &ys {
                    assert!((x + y).contains(a + b));
                    assert!((x - y).contains(a - b));
                    assert!((x * y).contains(a * b), "{x:?}·{y:?} ∌ {}", a * b);
                    if !y.contains(0.0) {
                        assert!((x / y).contains(a / b));
                    }
                }
            }
        }
    }

    #[test]
    fn outward_rounding_contains_exact_sums() {
        // 0.1 + 0.2 is not 0.3 in f64; the interval sum of the points holds both the
        // rounded sum and its neighbours on either side.
        let s = Interval::point(0.1) + Interval::point(0.2);
        assert!(s.contains(0.1 + 0.2));
        assert!(s.lo() < 0.1 + 0.2 && s.hi() > 0.1 + 0.2);
        assert!(s.width() < 1e-15);
    }

    #[test]
    fn special_cases() {
        assert_eq!(Interval::new(-1.0, 2.0).recip(), Interval::ENTIRE);
        assert!(!Interval::new(2.0, 1.0).is_valid());
        assert!(!Interval::new(f64::NAN, 1.0).is_valid());
        assert!(!(Interval::NAN * Interval::NAN).is_valid());
        assert!(!Interval::new(-2.0, -1.0).sqrt().is_valid());
        assert_eq!(Interval::new(-1e-18, 4.0).sqrt().lo(), 0.0);
        assert_eq!(Interval::new(-3.0, 2.0).square().lo(), 0.0);
        assert!(Interval::new(-3.0, 2.0).square().contains(9.0));
        assert_eq!(Interval::new(-1.0, 2.0).mag(), 2.0);
        let x = Interval::new(1.0, 3.0);
        assert!(Interval::around(x.mid(), x.rad()).subset_of(x.widened(1e-15)));
        assert!(x.subset_of(Interval::around(x.mid(), x.rad())));
        assert!(x.powi(3).contains(27.0) && x.powi(-1).contains(1.0 / 3.0));
        assert!((Interval::new(0.0, 1.0) * Interval::ENTIRE).lo() == f64::NEG_INFINITY);
    }
}

/// A first-order jet of intervals: `value` encloses a quantity over a box and `slope` its
/// derivative along a direction (also an enclosure over the box). The product rule and the
/// chain rule hold for the enclosures because each operation's slope is formed from
/// enclosures of the exact partial derivatives.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Dual {
    /// The value's enclosure.
    pub value: Interval,
    /// The derivative's enclosure.
    pub slope: Interval,
}

impl Dual {
    /// A constant (zero slope).
    #[inline]
    pub const fn constant(x: Interval) -> Dual {
        Dual {
            value: x,
            slope: Interval::ZERO,
        }
    }

    /// A variable with the given slope.
    #[inline]
    pub const fn new(value: Interval, slope: Interval) -> Dual {
        Dual { value, slope }
    }

    /// `√x` (slope `x′/(2√x)`; infinite when the value's enclosure reaches zero).
    #[inline]
    pub fn sqrt(self) -> Dual {
        let root = self.value.sqrt();
        Dual {
            value: root,
            slope: self.slope / (root * 2.0),
        }
    }

    /// `sin x`.
    #[inline]
    pub fn sin(self) -> Dual {
        Dual {
            value: self.value.sin(),
            slope: self.slope * self.value.cos(),
        }
    }

    /// `cos x`.
    #[inline]
    pub fn cos(self) -> Dual {
        Dual {
            value: self.value.cos(),
            slope: -(self.slope * self.value.sin()),
        }
    }

    /// `x^n` by repeated products.
    pub fn powi(self, n: i32) -> Dual {
        match n {
            0 => Dual::constant(Interval::point(1.0)),
            1 => self,
            n if n < 0 => Dual::constant(Interval::point(1.0)) / self.powi(-n),
            n => {
                let mut out = self;
                for _ in 1..n {
                    out *= self;
                }
                out
            }
        }
    }

    /// Both enclosures are finite.
    #[inline]
    pub fn is_finite(self) -> bool {
        self.value.is_finite() && self.slope.is_finite()
    }
}

impl From<f64> for Dual {
    #[inline]
    fn from(x: f64) -> Dual {
        Dual::constant(Interval::point(x))
    }
}

impl From<Interval> for Dual {
    #[inline]
    fn from(x: Interval) -> Dual {
        Dual::constant(x)
    }
}

impl Neg for Dual {
    type Output = Dual;
    #[inline]
    fn neg(self) -> Dual {
        Dual {
            value: -self.value,
            slope: -self.slope,
        }
    }
}

impl Add for Dual {
    type Output = Dual;
    #[inline]
    fn add(self, o: Dual) -> Dual {
        Dual {
            value: self.value + o.value,
            slope: self.slope + o.slope,
        }
    }
}

impl Sub for Dual {
    type Output = Dual;
    #[inline]
    fn sub(self, o: Dual) -> Dual {
        Dual {
            value: self.value - o.value,
            slope: self.slope - o.slope,
        }
    }
}

impl Mul for Dual {
    type Output = Dual;
    #[inline]
    fn mul(self, o: Dual) -> Dual {
        Dual {
            value: self.value * o.value,
            slope: self.value * o.slope + self.slope * o.value,
        }
    }
}

impl Div for Dual {
    type Output = Dual;
    #[inline]
    fn div(self, o: Dual) -> Dual {
        let inverse = o.value.recip();
        let value = self.value * inverse;
        Dual {
            value,
            slope: (self.slope - value * o.slope) * inverse,
        }
    }
}

impl Add<f64> for Dual {
    type Output = Dual;
    #[inline]
    fn add(self, x: f64) -> Dual {
        Dual {
            value: self.value + x,
            slope: self.slope,
        }
    }
}

impl Add<Dual> for f64 {
    type Output = Dual;
    #[inline]
    fn add(self, x: Dual) -> Dual {
        x + self
    }
}

impl Sub<f64> for Dual {
    type Output = Dual;
    #[inline]
    fn sub(self, x: f64) -> Dual {
        Dual {
            value: self.value - x,
            slope: self.slope,
        }
    }
}

impl Sub<Dual> for f64 {
    type Output = Dual;
    #[inline]
    fn sub(self, x: Dual) -> Dual {
        Dual {
            value: self - x.value,
            slope: -x.slope,
        }
    }
}

impl Mul<f64> for Dual {
    type Output = Dual;
    #[inline]
    fn mul(self, x: f64) -> Dual {
        Dual {
            value: self.value * x,
            slope: self.slope * x,
        }
    }
}

impl Mul<Dual> for f64 {
    type Output = Dual;
    #[inline]
    fn mul(self, x: Dual) -> Dual {
        x * self
    }
}

impl Div<f64> for Dual {
    type Output = Dual;
    #[inline]
    fn div(self, x: f64) -> Dual {
        Dual {
            value: self.value / x,
            slope: self.slope / x,
        }
    }
}

impl Div<Dual> for f64 {
    type Output = Dual;
    #[inline]
    fn div(self, x: Dual) -> Dual {
        Dual::from(self) / x
    }
}

impl AddAssign for Dual {
    #[inline]
    fn add_assign(&mut self, o: Dual) {
        *self = *self + o;
    }
}

impl SubAssign for Dual {
    #[inline]
    fn sub_assign(&mut self, o: Dual) {
        *self = *self - o;
    }
}

impl MulAssign for Dual {
    #[inline]
    fn mul_assign(&mut self, o: Dual) {
        *self = *self * o;
    }
}

#[cfg(test)]
mod dual_tests {
    use super::*;

    /// The slope of a composite function encloses its derivative (by central differences
    /// at points of the box, well inside the enclosure's width).
    #[test]
    fn slopes_enclose_derivatives() {
        let f = |x: Dual| (x * x + 1.0).sqrt() * x.sin() / (x + 3.0) - 2.0 * x.cos();
        let g = |x: f64| (x * x + 1.0).sqrt() * x.sin() / (x + 3.0) - 2.0 * x.cos();
        for k in 0..200 {
            let center = -1.0 + 0.01 * k as f64;
            let x = Dual::new(Interval::around(center, 0.05), Interval::point(1.0));
            let y = f(x);
            for t in [-0.05, -0.02, 0.0, 0.03, 0.05] {
                let p = center + t;
                assert!(y.value.contains(g(p)));
                let h = 1e-6;
                let derivative = (g(p + h) - g(p - h)) / (2.0 * h);
                assert!(
                    y.slope.widened(1e-7).contains(derivative),
                    "{y:?} ∌ {derivative}"
                );
            }
        }
    }
}
