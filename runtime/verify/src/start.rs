//! The initial states the safety guarantee covers, as one predicate: what `softcbf verify`
//! draws (and redraws) its runs' initial states from, and what `verify --search` keeps
//! its candidates in.
//!
//! A start is covered when the state lies in the model's domain
//! ([`softcbf_description::domain::state_problem`]) and, for every barrier `k`, `b_k ≥ 0`
//! and `ḃ_k + p1_k·b_k ≥ 0`, with `ḃ_k = J_k q̇` and `p1_k` the first class-K gain the
//! controller uses for that barrier (its own table's, else the run's): the first level set
//! of the HOCBF, whose forward invariance the filter's guarantee is about (docs/model.md
//! §5). A start at rest inside the safe set is covered; a start moving fast toward a
//! barrier is not. The definition lives here alone, so that a change of the guarantee
//! changes what every batch and search start from.

use crate::control::{Controller, ControllerSettings};
use crate::model::Model;

/// The predicate of covered starts for one robot and one set of barrier gains.
#[derive(Clone, Debug, PartialEq)]
pub struct StartSet {
    /// `p1` of every barrier as the controller uses it \[1/s\].
    p1: Vec<f64>,
}

impl StartSet {
    /// The covered starts of `model` under a controller with `settings` (the barrier gains
    /// are taken from a controller built with them, so they are the ones the filter uses).
    pub fn new(model: &Model, settings: &ControllerSettings) -> Result<StartSet, String> {
        let controller = Controller::new(model, settings.clone()).map_err(|e| e.to_string())?;
        let p1 = (0..model.nb())
            .map(|k| controller.barrier_gains(k).map_or(f64::NAN, |[p1, _]| p1))
            .collect();
        Ok(StartSet { p1 })
    }

    /// Why the state `(q, q̇)` is not a covered start, in words; `None` when it is.
    pub fn problem(&self, model: &Model, q: &[f64], qd: &[f64]) -> Option<String> {
        if let Some(problem) = softcbf_description::domain::state_problem(&model.robot, q, qd) {
            return Some(format!("outside the model's domain: {problem}"));
        }
        let (nb, nq) = (model.nb(), model.nq());
        let mut b = vec![0.0; nb];
        let mut jacobian = vec![0.0; nb * nq];
        let mut jdot_qd = vec![0.0; nb];
        model
            .generated
            .barrier_terms(&model.params, q, qd, &mut b, &mut jacobian, &mut jdot_qd);
        let labels = model.generated.barrier_table();
        for k in 0..nb {
            let label = labels.get(k).map_or("?", |info| info.label);
            if b[k].is_nan() || b[k] < 0.0 {
                return Some(format!("barrier {label} is {:e} < 0", b[k]));
            }
            let rate: f64 = jacobian[k * nq..(k + 1) * nq]
                .iter()
                .zip(qd)
                .map(|(j, v)| j * v)
                .sum();
            let level = rate + self.p1[k] * b[k];
            if level.is_nan() || level < 0.0 {
                return Some(format!(
                    "barrier {label}: ḃ + p1·b = {rate:e} + {}·{:e} = {level:e} < 0 (it \
                     approaches faster than the guarantee allows)",
                    self.p1[k], b[k]
                ));
            }
        }
        None
    }

    /// Whether `(q, q̇)` is a covered start.
    pub fn covers(&self, model: &Model, q: &[f64], qd: &[f64]) -> bool {
        self.problem(model, q, qd).is_none()
    }
}

#[cfg(test)]
mod tests {
    use softcbf_description::robot::Robot;

    use super::*;

    #[test]
    fn rest_inside_is_covered_a_fast_approach_and_the_domain_edge_are_not() {
        let model = Model::new(Robot::paper_sim()).unwrap();
        let settings = ControllerSettings::paper(&model);
        let set = StartSet::new(&model, &settings).unwrap();
        let rest = vec![0.0; 6];
        assert!(set.covers(&model, &rest, &rest));
        // Moving fast in one coordinate: some corner approaches faster than p1·b allows
        // (b ≈ 5 cm, p1 = 10/s: 0.5 m/s of approach is the limit).
        let mut fast = rest.clone();
        fast[0] = 20.0;
        let problem = set.problem(&model, &rest, &fast).expect("not covered");
        assert!(problem.contains("ḃ + p1·b"), "{problem}");
        // Slowly, the same direction is covered.
        fast[0] = 1e-3;
        assert!(set.covers(&model, &rest, &fast));
        // Outside the safe set, and outside the model's domain.
        let bent = vec![0.08, 0.0, -0.07, 0.0, 0.0, 0.0];
        let problem = set.problem(&model, &bent, &rest).expect("outside");
        assert!(problem.contains("< 0"), "{problem}");
        let crushed = vec![0.0, 0.0, -1.0, 0.0, 0.0, 0.0];
        let problem = set.problem(&model, &crushed, &rest).expect("outside");
        assert!(
            problem.starts_with("outside the model's domain"),
            "{problem}"
        );
    }
}
