//! The smooth kernel both sides of the equation of motion are filtered with, and the
//! filtered readings, velocities, accelerations and tensions of one log at one instant.
//!
//! `F[x](t) = ∫ k(s) x(t − s) ds` with `k(s) ∝ (1 − (s/T)²)⁶` on `[−T, T]` (zero outside,
//! five times continuously differentiable at its ends, `∫ k = 1`). Derivatives move onto
//! the kernel by integration by parts, exactly: `F[q̇] = ∫ k′(s) q(t − s) ds`,
//! `F[q̈] = ∫ k″(s) q(t − s) ds`. These integrals of sampled `q` are taken by the trapezoid
//! rule over the readings' own (non-uniform) times; the integrand vanishes with five
//! derivatives at both ends, so the rule is far more accurate than its `O(h²)` suggests
//! on a regular grid. Tensions are piecewise constant between command landings, and their
//! filtered value is exact: `∫ₐᵇ k(t − τ) dτ = K(t − a) − K(t − b)` with `K` the kernel's
//! antiderivative.

/// Coefficients of `(1 − x²)⁶ = Σ_j c_j x^{2j}`.
const POWERS: [f64; 7] = [1.0, -6.0, 15.0, -20.0, 15.0, -6.0, 1.0];

/// `P(x) = ∫₀ˣ (1 − y²)⁶ dy`, an odd polynomial of degree 13.
fn primitive(x: f64) -> f64 {
    let x2 = x * x;
    let mut sum = 0.0;
    for (j, c) in POWERS.iter().enumerate().rev() {
        sum = sum * x2 + c / (2 * j + 1) as f64;
    }
    sum * x
}

/// The filter kernel of half-width `T`: values, derivatives and antiderivative.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kernel {
    half_width: f64,
    /// `1 / T` \[1/s\]: the kernel is evaluated hundreds of millions of times in an hour of
    /// logs, and a product is several times cheaper than a quotient.
    inverse: f64,
    /// `1 / ∫₋₁¹ (1 − x²)⁶ dx`.
    scale: f64,
    /// The factors of `k`, `k′`, `k″`: `scale/T`, `scale/T²`, `scale/T³`.
    factors: [f64; 3],
}

impl Kernel {
    /// The kernel of half-width `half_width` \[s\] (positive and finite).
    pub fn new(half_width: f64) -> Kernel {
        let t = half_width;
        let scale = 0.5 / primitive(1.0);
        let c = scale / t;
        Kernel {
            half_width,
            inverse: 1.0 / t,
            scale,
            factors: [c, c / t, c / (t * t)],
        }
    }

    /// `T` \[s\].
    pub fn half_width(&self) -> f64 {
        self.half_width
    }

    /// `k(s)`, `k′(s)`, `k″(s)` \[1/s, 1/s², 1/s³\]; zero outside `(−T, T)`.
    pub fn values(&self, s: f64) -> [f64; 3] {
        let x = s * self.inverse;
        if x.is_nan() || x.abs() >= 1.0 {
            return [0.0; 3];
        }
        let x2 = x * x;
        let u = 1.0 - x2;
        let u2 = u * u;
        let u4 = u2 * u2;
        let [c0, c1, c2] = self.factors;
        [
            c0 * u4 * u2,
            c1 * (-12.0 * x) * u4 * u,
            c2 * u4 * (132.0 * x2 - 12.0),
        ]
    }

    /// `K(s) = ∫₋T^s k`: 0 below `−T`, 1 above `T`.
    pub fn cumulative(&self, s: f64) -> f64 {
        let x = s * self.inverse;
        if x <= -1.0 {
            0.0
        } else if x >= 1.0 {
            1.0
        } else {
            0.5 + self.scale * primitive(x)
        }
    }

    /// `∫ₐᵇ k(t − τ) dτ`: the weight of a constant held over `[a, b)` in `F[·](t)`.
    pub fn hold_weight(&self, t: f64, a: f64, b: f64) -> f64 {
        self.cumulative(t - a) - self.cumulative(t - b)
    }
}

/// The half-width the identification uses for readings `period` \[s\] apart: 0.08 s, or
/// five periods at slow rates (below 62.5 Hz), so that a window always holds about ten
/// readings or more.
pub fn default_half_width(period: f64) -> f64 {
    (5.0 * period).max(0.08)
}

/// Trapezoid weights `w_j` of samples at `times` (non-decreasing): `∫ f ≈ Σ w_j f(τ_j)`
/// for an `f` that vanishes at and beyond the first and last sample.
pub fn trapezoid_weight(times: &[f64], j: usize) -> f64 {
    let before = if j > 0 { times[j - 1] } else { times[j] };
    let after = times.get(j + 1).copied().unwrap_or(times[j]);
    0.5 * (after - before)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Composite Simpson on `[a, b]` with `n` (even) intervals.
    fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
        let h = (b - a) / n as f64;
        let mut sum = f(a) + f(b);
        for i in 1..n {
            let w = if i % 2 == 1 { 4.0 } else { 2.0 };
            sum += w * f(a + i as f64 * h);
        }
        sum * h / 3.0
    }

    #[test]
    fn kernel_integrates_to_one_and_its_derivatives_are_its_slopes() {
        let kernel = Kernel::new(0.08);
        let area = simpson(|s| kernel.values(s)[0], -0.08, 0.08, 2000);
        assert!((area - 1.0).abs() < 1e-12, "{area}");
        // (1 − x²)⁶ integrates to 2·(2¹²·6!²/13!) = 2048/3003 over [−1, 1].
        assert!((primitive(1.0) - 1024.0 / 3003.0).abs() < 1e-15);
        for s in [-0.07, -0.031, 0.0, 0.012, 0.05, 0.079] {
            let h = 1e-6;
            let [k, k1, k2] = kernel.values(s);
            let slope = (kernel.values(s + h)[0] - kernel.values(s - h)[0]) / (2.0 * h);
            let curvature = (kernel.values(s + h)[1] - kernel.values(s - h)[1]) / (2.0 * h);
            assert!(
                (k1 - slope).abs() < 1e-6 * k1.abs().max(1.0),
                "{s}: {k1} {slope}"
            );
            assert!((k2 - curvature).abs() < 1e-5 * k2.abs().max(1.0), "{s}");
            let antiderivative = (kernel.cumulative(s + h) - kernel.cumulative(s - h)) / (2.0 * h);
            assert!((k - antiderivative).abs() < 1e-6 * k.max(1.0));
        }
        assert_eq!(kernel.cumulative(-0.09), 0.0);
        assert_eq!(kernel.cumulative(0.09), 1.0);
        assert!((kernel.cumulative(0.0) - 0.5).abs() < 1e-15);
        assert_eq!(kernel.values(0.08), [0.0; 3]);
    }

    #[test]
    fn filtered_derivatives_of_a_polynomial_are_exact_on_a_jittered_grid() {
        // q(t) = 1 + 2t + 3t², q̇ = 2 + 6t, q̈ = 6: the kernel is symmetric, so F[q](t)
        // = q(t) + 3·∫s²k, F[q̇](t) = q̇(t), F[q̈] = 6.
        let kernel = Kernel::new(0.08);
        let times: Vec<f64> = (0..60)
            .map(|j| j as f64 * 0.005 + 0.0007 * ((j * 7 % 5) as f64 - 2.0))
            .collect();
        let q = |t: f64| 1.0 + 2.0 * t + 3.0 * t * t;
        let t = times[30];
        let (mut fq, mut fqd, mut fqdd) = (0.0, 0.0, 0.0);
        for j in 0..times.len() {
            let w = trapezoid_weight(&times, j);
            let [k, k1, k2] = kernel.values(t - times[j]);
            fq += w * k * q(times[j]);
            fqd += w * k1 * q(times[j]);
            fqdd += w * k2 * q(times[j]);
        }
        let second_moment = simpson(|s| s * s * kernel.values(s)[0], -0.08, 0.08, 2000);
        assert!((fq - (q(t) + 3.0 * second_moment)).abs() < 1e-5, "{fq}");
        assert!((fqd - (2.0 + 6.0 * t)).abs() < 1e-3, "{fqd}");
        assert!((fqdd - 6.0).abs() < 0.05, "{fqdd}");
    }
}
