//! The simulated robot: the generated dynamics as a first-order system with the generalized
//! force held constant (zero-order hold), advanced by the exponential integrator.
//!
//! The state is `x = (q, q̇)`. The integrator ([`crate::integrator::Exponential`]) treats the
//! linear part `A = [[0, I], [−M⁻¹K, −M⁻¹D]]` exactly, with `M` frozen where `A` was built
//! and rebuilt when `M` has drifted ([`LinearPart::drift`] is `‖M_A⁻¹(M(x) − M_A)‖∞`): the
//! stiff part of this plant is exactly its linear `K`, `D` (docs/model.md §7), and
//! Coriolis, gravity and the change of `M`, left to the explicit part, are not stiff
//! (measurements in [`crate::integrator`]'s module docs). [`PlantSystem`] also provides the
//! mechanical `W` of the Rosenbrock-W method, which the controller's predictions use.
//! Nothing allocates after [`Plant::new`].
//!
//! On the paper's scenario (10 s at 1 kHz, filter on) the default `rtol = 1e-6`,
//! `atol = 1e-9` take 1.09 steps and 3.4 right-hand sides per tick, rebuild `A`
//! at one tick in 20, and stay within 1.4e-7 m of a run at `rtol = 1e-10` over the whole
//! 10 s (the test `closed_loop_agrees_with_a_tight_tolerance_run`).
//!
//! The first right-hand side of a tick is at the state the controller has just evaluated
//! the model at: [`Plant::use_evaluation`] takes that evaluation (`M`, its factor, `h + G`),
//! only from the plant's own model object and at its state bit for bit, so the first
//! right-hand side is a solve instead of a model evaluation (2.4 of the 3.4 per tick are
//! evaluations; measured 3.92 → 3.35 µs of integration per tick together with the faster
//! `φ` products of [`crate::integrator`]). A plant of another model, or a noisy sample,
//! falls back to the plant's own evaluation.

use crate::dynamics::{
    DynamicsError, DynamicsWorkspace, forward_dynamics, mass_matrix, update_joints,
};
use crate::integrator::{
    Exponential, IntegratorError, LinearPart, MechanicalW, OdeSystem, Stats, Tolerances, WSolve,
};
use crate::linalg::{cholesky_in_place, cholesky_inverse, cholesky_solve, with_const_size};
use crate::model::Model;

/// The workspace of the plant's equations for one model: the held `τ` and what the
/// right-hand side and `W` write. [`PlantSystem`] joins it to its model for a computation.
pub struct PlantWorkspace {
    dynamics: DynamicsWorkspace,
    tau: Vec<f64>,
    qdd: Vec<f64>,
    w: MechanicalW,
    last_error: Option<DynamicsError>,
    /// The state at which `dynamics` holds `M` (the last successful right-hand side).
    evaluated_at: Vec<f64>,
    /// Whether `dynamics` also holds `M`'s Cholesky factor and `h + G` at `evaluated_at`
    /// (after a right-hand side there, or handed over by [`Plant::use_evaluation`]).
    terms_valid: bool,
    /// `M⁻¹` at the state of the last linear part, and scratch (`nq × nq` each).
    reference_inverse: Vec<f64>,
    reference_mass: Vec<f64>,
    scratch: Vec<f64>,
    scratch2: Vec<f64>,
}

impl PlantWorkspace {
    /// Storage for `model`'s equations with `τ = 0`.
    pub fn new(model: &Model) -> PlantWorkspace {
        let nq = model.nq();
        let mut w = MechanicalW::new(nq);
        for (i, (k, d)) in model.stiffness.iter().zip(&model.damping).enumerate() {
            w.stiffness_mut()[i * nq + i] = *k;
            w.damping_mut()[i * nq + i] = *d;
        }
        PlantWorkspace {
            dynamics: DynamicsWorkspace::new(model),
            tau: vec![0.0; nq],
            qdd: vec![0.0; nq],
            w,
            last_error: None,
            evaluated_at: vec![f64::NAN; 2 * nq],
            terms_valid: false,
            reference_inverse: vec![0.0; nq * nq],
            reference_mass: vec![0.0; nq * nq],
            scratch: vec![0.0; nq * nq],
            scratch2: vec![0.0; nq * nq],
        }
    }

    /// The held generalized force \[N\], length `nq`.
    pub fn tau_mut(&mut self) -> &mut [f64] {
        &mut self.tau
    }

    /// Why the last right-hand side failed, if it did.
    pub fn last_error(&self) -> Option<DynamicsError> {
        self.last_error
    }
}

/// The plant's equations `ẋ = (q̇, M⁻¹(τ − h − G − K q − D q̇))` for a held `τ`: a model
/// and a [`PlantWorkspace`] built for it, as the integrator sees them.
pub struct PlantSystem<'a> {
    /// The model whose dynamics are integrated.
    pub model: &'a Model,
    /// Its workspace.
    pub workspace: &'a mut PlantWorkspace,
}

impl OdeSystem for PlantSystem<'_> {
    fn dim(&self) -> usize {
        2 * self.model.nq()
    }

    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        let nq = self.model.nq();
        let (q, qd) = x.split_at(nq);
        let ws = &mut *self.workspace;
        if ws.terms_valid && same_bits(&ws.evaluated_at, x) {
            // M's factor and h + G at exactly this state are at hand: only the solve.
            let model = self.model;
            for k in 0..nq {
                ws.qdd[k] = ws.tau[k]
                    - ws.dynamics.nonlinear[k]
                    - model.stiffness[k] * q[k]
                    - model.damping[k] * qd[k];
            }
            cholesky_solve(&ws.dynamics.cholesky, nq, &mut ws.qdd);
            dx[..nq].copy_from_slice(qd);
            dx[nq..].copy_from_slice(&ws.qdd);
            let finite = ws.qdd.iter().all(|v| v.is_finite());
            ws.last_error = (!finite).then_some(DynamicsError::NonFinite);
            return finite;
        }
        match forward_dynamics(self.model, &mut ws.dynamics, q, qd, &ws.tau, &mut ws.qdd) {
            Ok(()) => {
                dx[..nq].copy_from_slice(qd);
                dx[nq..].copy_from_slice(&ws.qdd);
                ws.last_error = None;
                ws.evaluated_at.copy_from_slice(x);
                ws.terms_valid = true;
                true
            }
            Err(error) => {
                ws.last_error = Some(error);
                ws.evaluated_at.fill(f64::NAN);
                ws.terms_valid = false;
                false
            }
        }
    }
}

impl WSolve for PlantSystem<'_> {
    fn prepare_w(&mut self, _t: f64, x: &[f64], gamma_h: f64) -> bool {
        let ws = &mut *self.workspace;
        // The integrator evaluates f at a step's start just before preparing W there, so
        // M is usually in the workspace already.
        if ws.evaluated_at != x {
            let nq = self.model.nq();
            let (q, qd) = x.split_at(nq);
            let evaluated = update_joints(self.model, &mut ws.dynamics, q, qd)
                .and_then(|()| mass_matrix(self.model, &mut ws.dynamics));
            ws.evaluated_at.fill(f64::NAN);
            ws.terms_valid = false;
            if evaluated.is_err() {
                return false;
            }
        }
        ws.w.mass_matrix_mut()
            .copy_from_slice(&ws.dynamics.mass_matrix);
        ws.w.factor(gamma_h)
    }

    fn solve_w(&mut self, r: &mut [f64]) -> bool {
        self.workspace.w.solve(r)
    }
}

impl PlantSystem<'_> {
    /// Makes `ws.dynamics.mass_matrix` hold `M` at `x`.
    fn mass_matrix_at(&mut self, x: &[f64]) -> bool {
        let ws = &mut *self.workspace;
        if ws.evaluated_at != x {
            let nq = self.model.nq();
            let (q, qd) = x.split_at(nq);
            let evaluated = update_joints(self.model, &mut ws.dynamics, q, qd)
                .and_then(|()| mass_matrix(self.model, &mut ws.dynamics));
            ws.evaluated_at.fill(f64::NAN);
            ws.terms_valid = false;
            if evaluated.is_err() {
                return false;
            }
        }
        true
    }
}

impl LinearPart for PlantSystem<'_> {
    fn linear_part(&mut self, _t: f64, x: &[f64], a: &mut [f64]) -> bool {
        if !self.mass_matrix_at(x) {
            return false;
        }
        let nq = self.model.nq();
        let ws = &mut *self.workspace;
        ws.reference_mass.copy_from_slice(&ws.dynamics.mass_matrix);
        ws.scratch.copy_from_slice(&ws.dynamics.mass_matrix);
        if !cholesky_in_place(&mut ws.scratch, nq) {
            return false;
        }
        cholesky_inverse(&ws.scratch, nq, &mut ws.reference_inverse, &mut ws.scratch2);
        let m = 2 * nq;
        a.fill(0.0);
        for i in 0..nq {
            a[i * m + nq + i] = 1.0;
            for j in 0..nq {
                let inv = ws.reference_inverse[i * nq + j];
                a[(nq + i) * m + j] = -inv * self.model.stiffness[j];
                a[(nq + i) * m + nq + j] = -inv * self.model.damping[j];
            }
        }
        true
    }

    fn drift(&mut self, x: &[f64]) -> f64 {
        if !self.mass_matrix_at(x) {
            return f64::INFINITY;
        }
        // ‖M_ref⁻¹ (M(x) − M_ref)‖∞: the relative error of the frozen M⁻¹ on the stiff forces.
        let nq = self.model.nq();
        if nq == 0 {
            return 0.0;
        }
        let ws = &mut *self.workspace;
        with_const_size!(nq, [3, 6, 9, 12], |nq| {
            drift_sized(
                &ws.dynamics.mass_matrix,
                &ws.reference_mass,
                &ws.reference_inverse,
                &mut ws.scratch,
                &mut ws.scratch2,
                nq,
            )
        })
    }
}

/// `‖M_ref⁻¹ (M − M_ref)‖∞` for `nq × nq` matrices, `scratch` and `row_out` of that size
/// and more.
#[inline(always)]
fn drift_sized(
    mass: &[f64],
    reference_mass: &[f64],
    reference_inverse: &[f64],
    scratch: &mut [f64],
    row_out: &mut [f64],
    nq: usize,
) -> f64 {
    let change = &mut scratch[..nq * nq];
    for ((c, m), r) in change
        .iter_mut()
        .zip(&mass[..nq * nq])
        .zip(&reference_mass[..nq * nq])
    {
        *c = m - r;
    }
    let row_out = &mut row_out[..nq];
    let mut worst = 0.0_f64;
    for row in reference_inverse[..nq * nq].chunks_exact(nq) {
        row_out.fill(0.0);
        for (r, change_row) in row.iter().zip(change.chunks_exact(nq)) {
            for (o, c) in row_out.iter_mut().zip(change_row) {
                *o += r * c;
            }
        }
        worst = worst.max(row_out.iter().map(|v| v.abs()).sum());
    }
    worst
}

/// Whether `a` and `b` hold the same numbers bit for bit.
fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// The simulated robot: its state, time and integrator.
pub struct Plant<'m> {
    model: &'m Model,
    system: PlantWorkspace,
    integrator: Exponential,
    state: Vec<f64>,
    time: f64,
    stats: Stats,
}

impl<'m> Plant<'m> {
    /// A plant at rest at `q = 0`, `t = 0`, integrating with `tolerances` (validated).
    pub fn new(model: &'m Model, tolerances: Tolerances) -> Result<Plant<'m>, IntegratorError> {
        let nq = model.nq();
        Ok(Plant {
            model,
            system: PlantWorkspace::new(model),
            integrator: Exponential::new(2 * nq, tolerances)?,
            state: vec![0.0; 2 * nq],
            time: 0.0,
            stats: Stats::default(),
        })
    }

    /// Number of generalized coordinates.
    pub fn nq(&self) -> usize {
        self.state.len() / 2
    }

    /// Sets the state `(q, q̇)` and the time \[s\], and restarts the step-size control.
    pub fn reset(&mut self, q: &[f64], qd: &[f64], time: f64) {
        let nq = self.nq();
        self.state[..nq].copy_from_slice(q);
        self.state[nq..].copy_from_slice(qd);
        self.time = time;
        self.integrator.reset();
    }

    /// Generalized coordinates `q`.
    pub fn q(&self) -> &[f64] {
        &self.state[..self.nq()]
    }

    /// Generalized velocities `q̇`.
    pub fn qd(&self) -> &[f64] {
        &self.state[self.nq()..]
    }

    /// Simulated time \[s\].
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Integrator work since construction.
    pub fn stats(&self) -> Stats {
        self.stats
    }

    /// The held generalized force \[N\].
    pub fn tau_mut(&mut self) -> &mut [f64] {
        self.system.tau_mut()
    }

    /// Why the dynamics failed in the last failed step, if they did.
    pub fn last_dynamics_error(&self) -> Option<DynamicsError> {
        self.system.last_error()
    }

    /// Hands the plant an evaluation of its model at its current state, which its next
    /// [`Plant::advance`] then need not repeat: `dynamics` holding `M`, its Cholesky factor
    /// and `h + G` at the state `(q, q̇)` given as `state` (as [`crate::control::tick`]
    /// leaves them in [`crate::control::Controller::dynamics`] at
    /// [`crate::control::Controller::dynamics_state`]). Taken only if `model` is the plant's
    /// own model (the same object) and `state` is bit for bit the plant's state; returns
    /// whether it was taken. Anything else (another model, a noisy or stale state) is
    /// ignored and the plant evaluates its dynamics itself.
    pub fn use_evaluation(
        &mut self,
        model: &Model,
        state: &[f64],
        dynamics: &DynamicsWorkspace,
    ) -> bool {
        let nq = self.nq();
        let ws = &mut self.system;
        let fits = std::ptr::eq(model, self.model)
            && same_bits(state, &self.state)
            && dynamics.mass_matrix.len() == nq * nq
            && dynamics.cholesky.len() == nq * nq
            && dynamics.nonlinear.len() == nq;
        if !fits {
            return false;
        }
        ws.dynamics
            .mass_matrix
            .copy_from_slice(&dynamics.mass_matrix);
        ws.dynamics.cholesky.copy_from_slice(&dynamics.cholesky);
        ws.dynamics.nonlinear.copy_from_slice(&dynamics.nonlinear);
        ws.evaluated_at.copy_from_slice(state);
        ws.terms_valid = true;
        true
    }

    /// Advances the state by `dt ≥ 0` seconds with the held `τ`. On error the state is the
    /// last accepted one, at [`Plant::time`].
    pub fn advance(&mut self, dt: f64) -> Result<(), IntegratorError> {
        let (t0, t1) = (self.time, self.time + dt);
        let mut system = PlantSystem {
            model: self.model,
            workspace: &mut self.system,
        };
        let result = self
            .integrator
            .integrate(&mut system, t0, t1, &mut self.state);
        match result {
            Ok(stats) => {
                self.stats.accumulate(&stats);
                self.time = t1;
                Ok(())
            }
            Err(error) => {
                if let IntegratorError::NonFinite { t }
                | IntegratorError::StepTooSmall { t, .. }
                | IntegratorError::TooManySteps { t }
                | IntegratorError::WFailed { t } = error
                {
                    self.time = t;
                }
                Err(error)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot_file::load_robot;

    /// The plant takes an evaluation only of its own model object at its exact state, and
    /// then advances as it would have with its own evaluation (to rounding).
    #[test]
    fn an_evaluation_is_taken_only_at_the_plants_state_of_its_model() {
        let model = Model::new(load_robot(None).unwrap()).unwrap();
        let other = Model::new(load_robot(None).unwrap()).unwrap();
        let nq = model.nq();
        let q: Vec<f64> = (0..nq).map(|i| 1e-3 * (i as f64 + 1.0)).collect();
        let qd: Vec<f64> = (0..nq).map(|i| -2e-3 * i as f64).collect();
        let state: Vec<f64> = q.iter().chain(&qd).copied().collect();
        let mut dynamics = DynamicsWorkspace::new(&model);
        let mut qdd = vec![0.0; nq];
        forward_dynamics(&model, &mut dynamics, &q, &qd, &vec![0.0; nq], &mut qdd).unwrap();
        let mut plain = Plant::new(&model, Tolerances::default()).unwrap();
        let mut given = Plant::new(&model, Tolerances::default()).unwrap();
        for plant in [&mut plain, &mut given] {
            plant.reset(&q, &qd, 0.0);
            plant.tau_mut().fill(0.5);
        }
        assert!(!given.use_evaluation(&other, &state, &dynamics));
        let mut moved = state.clone();
        moved[0] = f64::from_bits(moved[0].to_bits() + 1);
        assert!(!given.use_evaluation(&model, &moved, &dynamics));
        assert!(given.use_evaluation(&model, &state, &dynamics));
        plain.advance(1e-3).unwrap();
        given.advance(1e-3).unwrap();
        for (a, b) in plain.q().iter().zip(given.q()) {
            assert!((a - b).abs() <= 1e-15, "{a} {b}");
        }
        // The state has moved on: the old evaluation no longer applies.
        assert!(!given.use_evaluation(&model, &state, &dynamics));
    }
}
