//! Energy conservation of the runtime dynamics (issue 3): with `τ = 0` and `D = 0` the paper
//! robot's kinetic + gravitational + elastic energy stays constant along a 2 s trajectory.
//!
//! The plant `q̈ = M⁻¹(−h − G − K q)` is integrated by Dormand–Prince 5(4) at rtol 1e-12.
//! Conservation holds only if `h = C q̇` has `q̇ᵀ h = ½ q̇ᵀ Ṁ q̇`, `G = ∇U_g`, `K q = ∇U_e`
//! and the energies match `M`; a 1 % error of `h` (the control run) breaks it by orders of
//! magnitude more than the tolerance.

use softcbf::dynamics::{
    DynamicsWorkspace, bias_and_gravity, elastic_energy, forward_dynamics, gravity_energy,
    kinetic_energy, solve_mass_matrix, update_joints,
};
use softcbf::integrator::{OdeSystem, Tolerances};
use softcbf::model::Model;
use softcbf_description::robot::Robot;
use softcbf_tests::integrators::DormandPrince;

/// The undamped, unactuated plant `x = (q, q̇)`, optionally with `h` scaled by
/// `1 + bias_error` (the control run that must not conserve energy).
struct Plant {
    model: Model,
    ws: DynamicsWorkspace,
    tau: Vec<f64>,
    correction: Vec<f64>,
    bias_error: f64,
}

impl Plant {
    fn new(bias_error: f64) -> Plant {
        let mut model = Model::new(Robot::paper_sim()).unwrap_or_else(|e| panic!("{e}"));
        model.damping.fill(0.0);
        let ws = DynamicsWorkspace::new(&model);
        let nq = model.nq();
        Plant {
            model,
            ws,
            tau: vec![0.0; nq],
            correction: vec![0.0; nq],
            bias_error,
        }
    }

    /// Kinetic, gravitational and elastic energy at `x`.
    fn energy(&mut self, x: &[f64]) -> [f64; 3] {
        let nq = self.model.nq();
        let (q, qd) = x.split_at(nq);
        update_joints(&self.model, &mut self.ws, q, qd).unwrap();
        bias_and_gravity(&self.model, &mut self.ws, qd).unwrap();
        [
            kinetic_energy(&self.model, &self.ws).unwrap(),
            gravity_energy(&self.model, &self.ws).unwrap(),
            elastic_energy(&self.model, q).unwrap(),
        ]
    }
}

impl OdeSystem for Plant {
    fn dim(&self) -> usize {
        2 * self.model.nq()
    }

    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        let nq = self.model.nq();
        let (q, qd) = x.split_at(nq);
        let (dq, qdd) = dx.split_at_mut(nq);
        dq.copy_from_slice(qd);
        if forward_dynamics(&self.model, &mut self.ws, q, qd, &self.tau, qdd).is_err() {
            return false;
        }
        if self.bias_error != 0.0 {
            // q̈ −= M⁻¹ (ε h), with the factor forward_dynamics left in the workspace.
            for (c, h) in self.correction.iter_mut().zip(&self.ws.bias) {
                *c = self.bias_error * h;
            }
            solve_mass_matrix(&self.ws, &mut self.correction).unwrap();
            for (a, c) in qdd.iter_mut().zip(&self.correction) {
                *a -= c;
            }
        }
        true
    }
}

/// A bent, moving start: module 1 bent 0.9 rad towards 30°, module 2 bent 1.3 rad towards
/// 200° (so the plates swing through different directions), both stretched or compressed,
/// every coordinate moving.
fn initial_state(model: &Model) -> Vec<f64> {
    let mut x = Vec::new();
    for (module, (theta, direction_deg, stretch)) in model
        .robot
        .modules
        .iter()
        .zip([(0.9_f64, 30.0_f64, 0.01), (1.3, 200.0, -0.015)])
    {
        let r = theta * module.tendon_radius;
        let alpha = direction_deg.to_radians();
        x.extend([r * alpha.cos(), r * alpha.sin(), stretch]);
    }
    x.extend([0.03, -0.02, 0.05, -0.04, 0.01, -0.03]);
    x
}

/// Integrates 2 s in 200 pieces; returns the largest `|E(t) − E(0)| / E(0)`, and the
/// largest kinetic energy reached (to show the motion is real).
fn relative_drift(bias_error: f64) -> (f64, f64) {
    let mut plant = Plant::new(bias_error);
    let mut x = initial_state(&plant.model);
    let tol = Tolerances {
        rtol: 1e-12,
        atol: 1e-14,
        h_initial: 1e-5,
        ..Tolerances::default()
    };
    let mut integrator = DormandPrince::new(x.len(), tol).expect("valid tolerances");
    let e0: f64 = plant.energy(&x).iter().sum();
    assert!(e0 > 0.0, "E(0) = {e0}");
    let (mut drift, mut kinetic_max) = (0.0_f64, 0.0_f64);
    let pieces = 200;
    for k in 0..pieces {
        let (t0, t1) = (
            2.0 * k as f64 / pieces as f64,
            2.0 * (k + 1) as f64 / pieces as f64,
        );
        if let Err(error) = integrator.integrate(&mut plant, t0, t1, &mut x) {
            panic!("integration failed: {error}");
        }
        let [kinetic, gravity, elastic] = plant.energy(&x);
        kinetic_max = kinetic_max.max(kinetic);
        drift = drift.max(((kinetic + gravity + elastic) - e0).abs() / e0);
    }
    (drift, kinetic_max)
}

#[test]
fn total_energy_is_conserved_without_damping_and_torque() {
    let (drift, kinetic_max) = relative_drift(0.0);
    eprintln!(
        "relative energy drift over 2 s: {drift:.2e} (largest kinetic energy {kinetic_max:.3} J)"
    );
    // The trajectory really exchanges energy: its kinetic energy grows well above the start's.
    let mut start = Plant::new(0.0);
    let x0 = initial_state(&start.model);
    let kinetic_start = start.energy(&x0)[0];
    assert!(
        kinetic_max > 100.0 * kinetic_start,
        "kinetic energy only reached {kinetic_max:e} J from {kinetic_start:e} J"
    );
    assert!(drift <= 1e-8, "relative energy drift {drift:e} > 1e-8");
}

/// The check is sensitive: with `h` wrong by 1 % the energy drifts far beyond 1e-8.
#[test]
fn wrong_bias_breaks_conservation() {
    let (drift, _) = relative_drift(0.01);
    eprintln!("relative energy drift with h off by 1 %: {drift:.2e}");
    assert!(drift > 1e-6, "a 1 % error of h drifted only {drift:e}");
}
