//! The simulated robot: the generated dynamics as a first-order system with the generalized
//! force held constant (zero-order hold), advanced by the Rosenbrock-W integrator.
//!
//! The state is `x = (q, q̇)`. The integrator's `W = I − γh J̃` uses the mechanical
//! approximation `J̃ = [[0, I], [−M⁻¹K, −M⁻¹D]]` with `M` evaluated at each step's start: the
//! stiff part of this plant is exactly its linear `K`, `D` (docs/model.md §7), and Coriolis,
//! gravity and `∂M/∂q` terms, which `J̃` omits, are not stiff (measurements in
//! [`crate::integrator`]'s module docs). Nothing allocates after [`Plant::new`].
//!
//! On the paper's scenario (10 s at 1 kHz, filter on) the default `rtol = 1e-6`,
//! `atol = 1e-9` take 3.3 steps and 13.2 evaluations of the dynamics per tick, and the
//! first 3 s stay within 1.4e-7 m of a run at `rtol = 1e-10` (1e-5: 4.0e-7 m with half the
//! evaluations; 1e-4: 6e-6 m; 1e-3: 6.5e-5 m).

use crate::dynamics::{
    DynamicsError, DynamicsWorkspace, forward_dynamics, mass_matrix, update_joints,
};
use crate::integrator::{
    IntegratorError, MechanicalW, OdeSystem, Rosenbrock, Stats, Tolerances, WSolve,
};
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
        match forward_dynamics(self.model, &mut ws.dynamics, q, qd, &ws.tau, &mut ws.qdd) {
            Ok(()) => {
                dx[..nq].copy_from_slice(qd);
                dx[nq..].copy_from_slice(&ws.qdd);
                ws.last_error = None;
                ws.evaluated_at.copy_from_slice(x);
                true
            }
            Err(error) => {
                ws.last_error = Some(error);
                ws.evaluated_at.fill(f64::NAN);
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

/// The simulated robot: its state, time and integrator.
pub struct Plant<'m> {
    model: &'m Model,
    system: PlantWorkspace,
    integrator: Rosenbrock,
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
            integrator: Rosenbrock::new(2 * nq, tolerances)?,
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
