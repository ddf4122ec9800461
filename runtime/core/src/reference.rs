//! What the nominal controller tracks over time: a set point, or waypoints joined by
//! minimum-jerk blends, sampled as `(q̄, q̄̇, q̄̈)` into preallocated buffers.
//!
//! Between waypoints `(t_a, q_a)` and `(t_b, q_b)` the reference is
//! `q̄ = q_a + (q_b − q_a) s(σ)`, `σ = (t − t_a)/(t_b − t_a)`, `s = 10σ³ − 15σ⁴ + 6σ⁵`, so
//! position, velocity and acceleration are continuous and velocity and acceleration vanish
//! at every waypoint. Before the first waypoint and after the last the reference holds.

use crate::control::Reference;

/// A reference as a scenario describes it.
#[derive(Clone, Debug, PartialEq)]
pub enum ReferenceSpec {
    /// A constant `q̄` with `q̄̇ = q̄̈ = 0`.
    SetPoint(Vec<f64>),
    /// Waypoints `(t [s], q̄)`, times strictly increasing, at least one.
    Waypoints(Vec<(f64, Vec<f64>)>),
}

impl ReferenceSpec {
    /// The final (or only) target `q̄`.
    pub fn final_target(&self) -> &[f64] {
        match self {
            ReferenceSpec::SetPoint(q) => q,
            ReferenceSpec::Waypoints(points) => points.last().map_or(&[], |(_, q)| q.as_slice()),
        }
    }

    /// Length of every `q̄` it holds (`None` if they differ or there are none).
    pub fn dimension(&self) -> Option<usize> {
        match self {
            ReferenceSpec::SetPoint(q) => Some(q.len()),
            ReferenceSpec::Waypoints(points) => {
                let n = points.first()?.1.len();
                points.iter().all(|(_, q)| q.len() == n).then_some(n)
            }
        }
    }
}

/// A reference with its sample buffers.
#[derive(Clone, Debug)]
pub struct ReferenceSignal {
    spec: ReferenceSpec,
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
}

impl ReferenceSignal {
    /// Buffers for `spec` (whose `q̄` all have the same length).
    pub fn new(spec: ReferenceSpec) -> ReferenceSignal {
        let n = spec.dimension().unwrap_or(0);
        ReferenceSignal {
            spec,
            q: vec![0.0; n],
            qd: vec![0.0; n],
            qdd: vec![0.0; n],
        }
    }

    /// The description.
    pub fn spec(&self) -> &ReferenceSpec {
        &self.spec
    }

    /// `(q̄, q̄̇, q̄̈)` at time `t` \[s\]. Allocates nothing.
    pub fn sample(&mut self, t: f64) -> Reference<'_> {
        match &self.spec {
            ReferenceSpec::SetPoint(q) => {
                self.q.copy_from_slice(q);
                self.qd.fill(0.0);
                self.qdd.fill(0.0);
            }
            ReferenceSpec::Waypoints(points) => {
                let next = points.partition_point(|(time, _)| *time <= t);
                if next == 0 || next == points.len() {
                    let (_, q) = &points[next.saturating_sub(1)];
                    self.q.copy_from_slice(q);
                    self.qd.fill(0.0);
                    self.qdd.fill(0.0);
                } else {
                    let (ta, qa) = &points[next - 1];
                    let (tb, qb) = &points[next];
                    let span = tb - ta;
                    let sigma = (t - ta) / span;
                    let (s, ds, dds) = minimum_jerk(sigma);
                    for i in 0..self.q.len() {
                        let delta = qb[i] - qa[i];
                        self.q[i] = qa[i] + delta * s;
                        self.qd[i] = delta * ds / span;
                        self.qdd[i] = delta * dds / (span * span);
                    }
                }
            }
        }
        Reference {
            q: &self.q,
            qd: &self.qd,
            qdd: &self.qdd,
        }
    }
}

/// `s(σ) = 10σ³ − 15σ⁴ + 6σ⁵` and its first two derivatives in `σ ∈ [0, 1]`.
pub fn minimum_jerk(sigma: f64) -> (f64, f64, f64) {
    let x = sigma.clamp(0.0, 1.0);
    let (x2, x3) = (x * x, x * x * x);
    (
        x3 * (10.0 - 15.0 * x + 6.0 * x2),
        30.0 * x2 * (1.0 - 2.0 * x + x2),
        60.0 * x * (1.0 - 3.0 * x + 2.0 * x2),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minimum_jerk_has_zero_rates_at_ends_and_matches_differences() {
        assert_eq!(minimum_jerk(0.0), (0.0, 0.0, 0.0));
        let (s, ds, dds) = minimum_jerk(1.0);
        assert!((s - 1.0).abs() < 1e-15 && ds.abs() < 1e-15 && dds.abs() < 1e-13);
        let h = 1e-6;
        for k in 1..10 {
            let x = f64::from(k) / 10.0;
            let (_, ds, dds) = minimum_jerk(x);
            let fd1 = (minimum_jerk(x + h).0 - minimum_jerk(x - h).0) / (2.0 * h);
            let fd2 = (minimum_jerk(x + h).1 - minimum_jerk(x - h).1) / (2.0 * h);
            assert!((ds - fd1).abs() < 1e-8, "{x}: {ds} vs {fd1}");
            assert!((dds - fd2).abs() < 1e-7, "{x}: {dds} vs {fd2}");
        }
    }

    #[test]
    fn waypoints_hold_outside_and_blend_inside() {
        let spec = ReferenceSpec::Waypoints(vec![(1.0, vec![0.0, 1.0]), (3.0, vec![2.0, 1.0])]);
        let mut signal = ReferenceSignal::new(spec);
        let r = signal.sample(0.0);
        assert_eq!((r.q, r.qd), (&[0.0, 1.0][..], &[0.0, 0.0][..]));
        let r = signal.sample(2.0);
        assert!((r.q[0] - 1.0).abs() < 1e-15 && r.q[1] == 1.0);
        // Peak velocity of a minimum-jerk blend: 15/8 · Δq / T.
        assert!((r.qd[0] - 15.0 / 8.0 * 2.0 / 2.0).abs() < 1e-12);
        let r = signal.sample(5.0);
        assert_eq!(r.q, &[2.0, 1.0][..]);
    }
}
