//! The safe controller: HOCBF rows against the barrier's acceleration along the true
//! dynamics, the PD+ law against its defining property, the filter's pass-through, and the
//! fallbacks for non-finite states and infeasible rows.

use rand::RngExt;
use softcbf::control::{
    Controller, ControllerSettings, InvalidState, Reference, SafetyMode, TickStatus, tick,
};
use softcbf::dynamics::{DynamicsWorkspace, forward_dynamics};
use softcbf::model::Model;
use softcbf::qp::{QpSettings, QpStatus, SafetyQp};
use softcbf::robot_file::load_robot;
use softcbf_tests::TestRng;
use softcbf_tests::alloc::allocations;
use softcbf_tests::reference::stiffness_and_damping;

fn paper_model() -> Model {
    Model::new(load_robot(None).expect("embedded robot")).expect("paper model")
}

/// A random state with bend angles up to about 2 rad and moderate velocities.
fn random_state(rng: &mut TestRng, nq: usize) -> (Vec<f64>, Vec<f64>) {
    let q: Vec<f64> = (0..nq)
        .map(|i| match i % 3 {
            2 => rng.random_range(-0.04..0.04),
            _ => rng.random_range(-0.06..0.06),
        })
        .collect();
    let qd: Vec<f64> = (0..nq).map(|_| rng.random_range(-0.3..0.3)).collect();
    (q, qd)
}

fn barriers_at(model: &Model, q: &[f64]) -> Vec<f64> {
    let mut b = vec![0.0; model.nb()];
    model.generated.barriers(&model.params, q, &mut b);
    b
}

fn zeros(n: usize) -> Vec<f64> {
    vec![0.0; n]
}

/// The class-K gains `[p1, p2]` of barrier `k`: its own (a limit at the domain's default,
/// a limits table's or an obstacle's), else the run's.
fn gains(model: &Model, controller: &Controller, k: usize) -> (f64, f64) {
    let [p1, p2] = controller.settings().barrier_gains;
    let [own1, own2] = model.own_barrier_gains[k];
    (own1.unwrap_or(p1), own2.unwrap_or(p2))
}

/// Regulation toward `set_point`: `q̄̇ = q̄̈ = 0` (`zero` of the same length).
fn regulation<'a>(set_point: &'a [f64], zero: &'a [f64]) -> Reference<'a> {
    Reference {
        q: set_point,
        qd: zero,
        qdd: zero,
    }
}

/// `A τ − b` of every HOCBF row must equal `b̈ + (p1 + p2) ḃ + p1 p2 b` of the barrier along
/// the motion that `τ` causes, here measured by differences of the plain barrier values
/// along `q(t) = q + t q̇ + ½ t² q̈` (no Jacobian or `J̇q̇` of the generated code involved).
#[test]
fn hocbf_rows_predict_the_barrier_acceleration() {
    let model = paper_model();
    let (nq, nb) = (model.nq(), model.nb());
    let mut controller = Controller::new(&model, ControllerSettings::paper(&model)).unwrap();
    let mut ws = DynamicsWorkspace::new(&model);
    let mut rng = softcbf_tests::rng(11);
    let (zero, h) = (zeros(nq), 2e-5);
    let mut worst = 0.0_f64;
    for _ in 0..300 {
        let (q, qd) = random_state(&mut rng, nq);
        let reference = regulation(&zero, &zero);
        tick(&model, &mut controller, &q, &qd, reference);
        let tau: Vec<f64> = (0..nq).map(|_| rng.random_range(-3.0..3.0)).collect();
        let mut qdd = zeros(nq);
        forward_dynamics(&model, &mut ws, &q, &qd, &tau, &mut qdd).unwrap();
        let along = |t: f64| -> Vec<f64> {
            let point: Vec<f64> = (0..nq)
                .map(|i| q[i] + t * qd[i] + 0.5 * t * t * qdd[i])
                .collect();
            barriers_at(&model, &point)
        };
        // Central differences at h and h/2, combined by Richardson extrapolation: the
        // accelerations reach thousands of m/s², so the O(h²) term matters.
        let centre = along(0.0);
        let (minus, plus) = (along(-h), along(h));
        let (minus_half, plus_half) = (along(-h / 2.0), along(h / 2.0));
        let (rows, rhs) = controller.constraints();
        for k in 0..nb {
            let (p1, p2) = gains(&model, &controller, k);
            let rate_h = (plus[k] - minus[k]) / (2.0 * h);
            let rate_half = (plus_half[k] - minus_half[k]) / h;
            let rate = (4.0 * rate_half - rate_h) / 3.0;
            let second = |p: f64, m: f64, step: f64| (p - 2.0 * centre[k] + m) / (step * step);
            let acceleration = (4.0 * second(plus_half[k], minus_half[k], h / 2.0)
                - second(plus[k], minus[k], h))
                / 3.0;
            let expected = acceleration + (p1 + p2) * rate + p1 * p2 * centre[k];
            let predicted: f64 = rows[k * nq..(k + 1) * nq]
                .iter()
                .zip(&tau)
                .map(|(a, t)| a * t)
                .sum::<f64>()
                - rhs[k];
            let scale = 1.0 + acceleration.abs() + p1 * p2 * centre[k].abs();
            let error = (predicted - expected).abs() / scale;
            worst = worst.max(error);
            assert!(
                error < 1e-5,
                "barrier {k}: predicted {predicted}, from differences {expected} (q {q:?})"
            );
        }
    }
    eprintln!("worst relative error of the HOCBF rows: {worst:.2e}");
}

/// With the hold correction the rows predict the tick-averaged acceleration of a linearly
/// implicit Euler step, `(M + ΔD + Δ²K) q̇⁺ = M q̇ + Δ (τ − h − G − K q)`, solved here by
/// Gaussian elimination from `M`, `h + G` and the diagonals of docs/model.md §4.
#[test]
fn hold_corrected_rows_predict_the_implicit_euler_step() {
    let model = paper_model();
    let (nq, nb) = (model.nq(), model.nb());
    let mut settings = ControllerSettings::paper(&model);
    let hold = 1e-3;
    settings.safety = SafetyMode::HoldCorrection;
    settings.hold = hold;
    let mut controller = Controller::new(&model, settings).unwrap();
    let (stiffness, damping) = stiffness_and_damping(&model.robot);
    let mut rng = softcbf_tests::rng(14);
    let zero = zeros(nq);
    for _ in 0..100 {
        let (q, qd) = random_state(&mut rng, nq);
        let reference = regulation(&zero, &zero);
        tick(&model, &mut controller, &q, &qd, reference);
        let tau: Vec<f64> = (0..nq).map(|_| rng.random_range(-3.0..3.0)).collect();
        let ws = controller.dynamics();
        // Augmented system [S | M q̇ + Δ(τ − h − G − K q)].
        let mut system: Vec<Vec<f64>> = (0..nq)
            .map(|i| {
                let mut row: Vec<f64> = ws.mass_matrix[i * nq..(i + 1) * nq].to_vec();
                row[i] += hold * damping[i] + hold * hold * stiffness[i];
                let momentum: f64 = (0..nq).map(|j| ws.mass_matrix[i * nq + j] * qd[j]).sum();
                row.push(momentum + hold * (tau[i] - ws.nonlinear[i] - stiffness[i] * q[i]));
                row
            })
            .collect();
        for c in 0..nq {
            let pivot = (c..nq)
                .max_by(|&a, &b| system[a][c].abs().total_cmp(&system[b][c].abs()))
                .unwrap();
            system.swap(c, pivot);
            let pivot_row = system[c].clone();
            for (r, row) in system.iter_mut().enumerate() {
                if r != c {
                    let f = row[c] / pivot_row[c];
                    for (x, p) in row[c..].iter_mut().zip(&pivot_row[c..]) {
                        *x -= f * p;
                    }
                }
            }
        }
        let qd_next: Vec<f64> = (0..nq).map(|i| system[i][nq] / system[i][i]).collect();
        let jacobian = controller.barrier_jacobian();
        let mut jdot_qd = zeros(nb);
        let mut b = zeros(nb);
        let mut j_unused = zeros(nb * nq);
        model
            .generated
            .barrier_terms(&model.params, &q, &qd, &mut b, &mut j_unused, &mut jdot_qd);
        let (rows, rhs) = controller.constraints();
        for k in 0..nb {
            let (p1, p2) = gains(&model, &controller, k);
            let row = &jacobian[k * nq..(k + 1) * nq];
            let average: f64 = (0..nq).map(|i| row[i] * (qd_next[i] - qd[i]) / hold).sum();
            let rate: f64 = (0..nq).map(|i| row[i] * qd[i]).sum();
            let expected = average + jdot_qd[k] + (p1 + p2) * rate + p1 * p2 * b[k];
            let predicted: f64 = rows[k * nq..(k + 1) * nq]
                .iter()
                .zip(&tau)
                .map(|(a, t)| a * t)
                .sum::<f64>()
                - rhs[k];
            assert!(
                (predicted - expected).abs() < 1e-9 * (1.0 + expected.abs()),
                "barrier {k}: {predicted} vs {expected}"
            );
        }
    }
}

/// With `q = q̄(t)` and `q̇ = q̄̇(t)` the PD+ torque produces exactly `q̈ = q̄̈`, and at a
/// resting set point it is the static torque `G + K q̄`, so the robot stays.
#[test]
fn pd_plus_torque_reproduces_the_reference_acceleration() {
    let model = paper_model();
    let nq = model.nq();
    let mut settings = ControllerSettings::paper(&model);
    settings.filter = false;
    let mut controller = Controller::new(&model, settings).unwrap();
    let mut ws = DynamicsWorkspace::new(&model);
    let mut rng = softcbf_tests::rng(12);
    for trial in 0..200 {
        let (q, mut qd) = random_state(&mut rng, nq);
        let mut qdd_ref: Vec<f64> = (0..nq).map(|_| rng.random_range(-2.0..2.0)).collect();
        if trial % 2 == 0 {
            qd.fill(0.0);
            qdd_ref.fill(0.0);
        }
        let status = tick(
            &model,
            &mut controller,
            &q,
            &qd,
            Reference {
                q: &q,
                qd: &qd,
                qdd: &qdd_ref,
            },
        );
        assert_eq!(status, TickStatus::Unfiltered);
        assert_eq!(controller.tau(), controller.tau_nom());
        let mut qdd = zeros(nq);
        forward_dynamics(&model, &mut ws, &q, &qd, controller.tau(), &mut qdd).unwrap();
        for i in 0..nq {
            let scale = 1.0 + qdd_ref[i].abs();
            assert!(
                (qdd[i] - qdd_ref[i]).abs() < 1e-9 * scale,
                "coordinate {i}: q̈ {} instead of {}",
                qdd[i],
                qdd_ref[i]
            );
        }
    }
}

/// Whenever no HOCBF row is active the filter returns `τ_nom` bit for bit. With this stiff
/// plant the rows are active well away from contact: an offset of 1 mm from the set point
/// (`(K + K_P)·1 mm ≈ 6 N`) or a velocity of 1 mm/s (`D·1 mm/s ≈ 3 N`) accelerates a plate
/// by tens of m/s², more than `p1 p2 b ≈ 10 m/s²` allows; so the states are drawn within
/// 0.05 mm and 0.1 mm/s of rest on the set point, where the rows are inactive.
#[test]
fn filter_passes_nominal_torque_when_no_row_is_active() {
    let model = paper_model();
    let nq = model.nq();
    let mut controller = Controller::new(&model, ControllerSettings::paper(&model)).unwrap();
    let set_point = [0.02, 0.0, 0.0, 0.0, 0.01, 0.0];
    let zero = zeros(nq);
    let reference = regulation(&set_point, &zero);
    let status = tick(&model, &mut controller, &set_point, &zero, reference);
    assert_eq!(status, TickStatus::Filtered);
    assert_eq!(controller.qp_report().active, 0);
    assert_eq!(controller.tau(), controller.tau_nom());
    let mut rng = softcbf_tests::rng(13);
    let (mut inactive, mut active) = (0, 0);
    while inactive < 100 {
        let q: Vec<f64> = set_point
            .iter()
            .map(|s| s + rng.random_range(-5e-5..5e-5))
            .collect();
        let qd: Vec<f64> = (0..nq).map(|_| rng.random_range(-1e-4..1e-4)).collect();
        let status = tick(&model, &mut controller, &q, &qd, reference);
        assert_eq!(status, TickStatus::Filtered);
        if controller.qp_report().active == 0 {
            inactive += 1;
            assert_eq!(controller.tau(), controller.tau_nom());
        } else {
            active += 1;
            assert_ne!(controller.tau(), controller.tau_nom());
        }
        assert!(active < 10_000, "no inactive state found");
    }
}

/// Close to contact and moving toward it, the filtered command satisfies every row and
/// differs from the nominal one only along active rows (KKT: `τ − τ_nom = Aᵀ λ`, `λ ≥ 0`).
#[test]
fn filtered_torque_satisfies_rows_near_contact() {
    let model = paper_model();
    let (nq, nb) = (model.nq(), model.nb());
    let mut controller = Controller::new(&model, ControllerSettings::paper(&model)).unwrap();
    // Module 1 bent about 2 rad toward +x and compressed: its corner at φ = 0 is close to
    // its bottom plate; velocities push further.
    let q = [0.075, 0.0, -0.04, 0.0, -0.05, -0.05];
    let qd = [0.2, 0.0, -0.1, 0.0, -0.2, -0.1];
    let set_point = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];
    let zero = zeros(nq);
    let reference = regulation(&set_point, &zero);
    let status = tick(&model, &mut controller, &q, &qd, reference);
    assert_eq!(status, TickStatus::Filtered);
    assert!(
        controller.qp_report().active > 0,
        "some row should be active here"
    );
    let (rows, rhs) = controller.constraints();
    let tau = controller.tau();
    for k in 0..nb {
        let lhs: f64 = rows[k * nq..(k + 1) * nq]
            .iter()
            .zip(tau)
            .map(|(a, t)| a * t)
            .sum();
        assert!(
            lhs >= rhs[k] - 1e-7 * (1.0 + rhs[k].abs()),
            "row {k}: {lhs} < {}",
            rhs[k]
        );
    }
    assert_ne!(controller.tau(), controller.tau_nom());
}

#[test]
fn non_finite_state_gives_the_safe_command() {
    let model = paper_model();
    let nq = model.nq();
    let mut controller = Controller::new(&model, ControllerSettings::paper(&model)).unwrap();
    let zero = zeros(nq);
    let reference = regulation(&zero, &zero);
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut q = zeros(nq);
        q[4] = bad;
        let status = tick(&model, &mut controller, &q, &zero, reference);
        assert_eq!(status, TickStatus::InvalidState(InvalidState::NonFinite));
        assert!(status.is_fallback());
        assert!(controller.tau().iter().all(|&t| t == 0.0));
        let status = tick(&model, &mut controller, &zero, &q, reference);
        assert_eq!(status, TickStatus::InvalidState(InvalidState::NonFinite));
    }
    // A wrong length is refused as a size error (not NonFinite), never a panic.
    let status = tick(&model, &mut controller, &zero[..3], &zero, reference);
    assert!(matches!(
        status,
        TickStatus::InvalidState(InvalidState::Size { .. })
    ));
    // A valid state afterwards is served normally.
    assert_eq!(
        tick(&model, &mut controller, &zero, &zero, reference),
        TickStatus::Filtered
    );
}

#[test]
fn a_state_outside_the_model_gives_the_safe_command() {
    // Finite, but no robot: a bend of 0.3 turns past three quarters, δL of 1e3 rest
    // lengths, a speed of 1 km/s. The model would still produce numbers (or NaN, as
    // `softcbf model --q 1e308,…` once printed); the tick refuses them.
    let model = paper_model();
    let nq = model.nq();
    let d = model.robot.modules[1].tendon_radius;
    let mut controller = Controller::new(&model, ControllerSettings::paper(&model)).unwrap();
    let zero = zeros(nq);
    let reference = regulation(&zero, &zero);
    let mut bent = zeros(nq);
    bent[3] = 1.8 * std::f64::consts::PI * d;
    let mut stretched = zeros(nq);
    stretched[2] = 1e3 * model.robot.modules[0].rest_length;
    let mut fast = zeros(nq);
    fast[1] = 1e3;
    for (q, qd) in [(&bent, &zero), (&stretched, &zero), (&zero, &fast)] {
        let status = tick(&model, &mut controller, q, qd, reference);
        assert_eq!(status, TickStatus::InvalidState(InvalidState::OutOfDomain));
        assert!(status.is_fallback());
        assert!(controller.tau().iter().all(|&t| t == 0.0));
    }
    // Just inside the domain the tick computes a command.
    bent[3] = 1.4 * std::f64::consts::PI * d;
    let status = tick(&model, &mut controller, &bent, &zero, reference);
    assert!(!status.is_fallback(), "{status:?}");
}

/// The corner barriers of a module always leave room (extending the module raises all its
/// corners), so an infeasible set is constructed from the controller's own rows: every row
/// together with its negation shifted by one, `a τ ≥ b` and `−a τ ≥ −b + 1`.
#[test]
fn contradictory_rows_are_relaxed_and_reported() {
    let model = paper_model();
    let (nq, nb) = (model.nq(), model.nb());
    let mut controller = Controller::new(&model, ControllerSettings::paper(&model)).unwrap();
    let q = [0.05, 0.01, -0.02, -0.01, 0.04, -0.03];
    let qd = [0.1, 0.0, -0.1, 0.0, 0.1, 0.0];
    let zero = zeros(nq);
    let reference = regulation(&zero, &zero);
    tick(&model, &mut controller, &q, &qd, reference);
    let (rows, rhs) = controller.constraints();
    let mut a = rows.to_vec();
    let mut b = rhs.to_vec();
    a.extend(rows.iter().map(|v| -v));
    b.extend(rhs.iter().map(|v| -v + 1.0));
    let mut qp = SafetyQp::new(nq, 2 * nb, QpSettings::default()).unwrap();
    let mut tau = zeros(nq);
    let report = qp.solve(controller.tau_nom(), &a, &b, &mut tau);
    assert_eq!(report.status, QpStatus::Relaxed);
    assert!(!report.relaxed_rows.is_empty());
    assert!(tau.iter().all(|t| t.is_finite()));
}

/// Limits on the command are rows of the same QP: the filtered command satisfies them and
/// the barrier rows together; loose limits change nothing.
#[test]
fn input_limits_are_solved_with_the_barrier_rows() {
    let model = paper_model();
    let nq = model.nq();
    let q = [0.075, 0.0, -0.04, 0.0, -0.05, -0.05];
    let qd = [0.2, 0.0, -0.1, 0.0, -0.2, -0.1];
    let set_point = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];
    let zero = zeros(nq);
    let reference = regulation(&set_point, &zero);
    // |τ_i| ≤ limit as rows τ_i ≥ −limit and −τ_i ≥ −limit.
    let boxed = |limit: f64| {
        let mut rows = vec![0.0; 2 * nq * nq];
        let mut rhs = vec![0.0; 2 * nq];
        for i in 0..nq {
            rows[(2 * i) * nq + i] = 1.0;
            rows[(2 * i + 1) * nq + i] = -1.0;
            rhs[2 * i] = -limit;
            rhs[2 * i + 1] = -limit;
        }
        (rows, rhs)
    };
    let mut free = Controller::new(&model, ControllerSettings::paper(&model)).unwrap();
    assert_eq!(
        tick(&model, &mut free, &q, &qd, reference),
        TickStatus::Filtered
    );
    let mut settings = ControllerSettings::paper(&model);
    settings.input_limits = boxed(1e6);
    let mut loose = Controller::new(&model, settings).unwrap();
    assert_eq!(
        tick(&model, &mut loose, &q, &qd, reference),
        TickStatus::Filtered
    );
    for (a, b) in loose.tau().iter().zip(free.tau()) {
        assert!((a - b).abs() <= 1e-9 * (1.0 + b.abs()), "{a} vs {b}");
    }
    let limit = 0.5 * free.tau().iter().fold(0.0_f64, |m, t| m.max(t.abs()));
    let mut settings = ControllerSettings::paper(&model);
    settings.input_limits = boxed(limit);
    let mut tight = Controller::new(&model, settings).unwrap();
    let status = tick(&model, &mut tight, &q, &qd, reference);
    assert!(
        matches!(status, TickStatus::Filtered | TickStatus::Relaxed),
        "{status:?}"
    );
    let (rows, rhs) = tight.constraints();
    assert_eq!(rhs.len(), model.nb() + 2 * nq);
    if status == TickStatus::Filtered {
        for (k, b) in rhs.iter().enumerate() {
            let lhs: f64 = rows[k * nq..(k + 1) * nq]
                .iter()
                .zip(tight.tau())
                .map(|(a, t)| a * t)
                .sum();
            assert!(lhs >= b - 1e-7 * (1.0 + b.abs()), "row {k}: {lhs} < {b}");
        }
    }
    // Wrong sizes are refused when the controller is built.
    let mut settings = ControllerSettings::paper(&model);
    settings.input_limits = (vec![1.0; nq + 1], vec![0.0]);
    assert!(Controller::new(&model, settings).is_err());
}

/// The control path allocates nothing per tick: a tick (filter on, with active rows; the
/// paper's rows, the sampled-data rows, and those with a robust margin) and a plant step
/// between ticks, after the first of each has run.
#[test]
fn control_tick_and_plant_step_allocate_nothing() {
    use softcbf::integrator::Tolerances;
    use softcbf::plant::Plant;
    let model = paper_model();
    // The robust margin's path too: ±20 % declared on every number, and a force bound.
    let mut declared = model.robot.clone();
    declared.uncertainty = softcbf_description::uncertainty::Uncertainty {
        stiffness: 0.2,
        damping: 0.2,
        mass: 0.2,
        force: 0.05,
    };
    let uncertain = Model::new(declared).unwrap();
    for (model, safety) in [
        (&model, SafetyMode::Paper),
        (&model, SafetyMode::Predicted),
        (&uncertain, SafetyMode::Predicted),
        (&model, SafetyMode::Certified),
        (&uncertain, SafetyMode::Certified),
    ] {
        let nq = model.nq();
        let mut settings = ControllerSettings::paper(model);
        settings.safety = safety;
        settings.hold = 1e-3;
        let mut controller = Controller::new(model, settings).unwrap();
        let mut plant = Plant::new(model, Tolerances::default()).unwrap();
        let set_point = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];
        let zero = zeros(nq);
        let reference = regulation(&set_point, &zero);
        let (mut active, mut before) = (0, 0);
        for k in 0..400 {
            if k == 1 {
                before = allocations();
            }
            tick(model, &mut controller, plant.q(), plant.qd(), reference);
            active += usize::from(controller.qp_report().active > 0);
            plant.tau_mut().copy_from_slice(controller.tau());
            plant.advance(1e-3).unwrap();
        }
        assert_eq!(
            allocations() - before,
            0,
            "{safety}, uncertainty declared: {}: allocations in 399 ticks and steps",
            model.robot.uncertainty.is_declared()
        );
        assert!(active > 0, "{safety}: no tick exercised an active row");
    }
}

/// Every argument of a wrong length gives the size error naming it (a setup error, not
/// `NonFinite`), the safe command, no panic and no allocation; so does a controller built
/// for another model.
#[test]
fn wrong_lengths_give_the_size_error() {
    let model = paper_model();
    let nq = model.nq();
    let mut controller = Controller::new(&model, ControllerSettings::paper(&model)).unwrap();
    let (zero, long) = (zeros(nq), zeros(nq + 1));
    let size = |what: &'static str, got: usize| {
        TickStatus::InvalidState(InvalidState::Size {
            what,
            expected: nq,
            got,
        })
    };
    let good = regulation(&zero, &zero);
    let before = allocations();
    let statuses = [
        tick(&model, &mut controller, &long, &zero, good),
        tick(&model, &mut controller, &zero, &long[..2], good),
        tick(
            &model,
            &mut controller,
            &zero,
            &zero,
            Reference {
                q: &long,
                qd: &zero,
                qdd: &zero,
            },
        ),
        tick(
            &model,
            &mut controller,
            &zero,
            &zero,
            Reference {
                q: &zero,
                qd: &[],
                qdd: &zero,
            },
        ),
        tick(
            &model,
            &mut controller,
            &zero,
            &zero,
            Reference {
                q: &zero,
                qd: &zero,
                qdd: &long,
            },
        ),
    ];
    assert_eq!(allocations(), before, "a refused tick allocates nothing");
    assert_eq!(
        statuses,
        [
            size("q", nq + 1),
            size("q̇", 2),
            size("reference q̄", nq + 1),
            size("reference q̄̇", 0),
            size("reference q̄̈", nq + 1),
        ]
    );
    assert!(statuses.iter().all(|s| s.is_fallback()));
    assert!(controller.tau().iter().all(|&t| t == 0.0));

    // A controller of the one-module robot used with the paper's model.
    let one = Model::new(
        softcbf_description::robot::Robot::parse(
            "name = \"one\"\nmodules = 1\n",
            std::path::Path::new("<test>"),
        )
        .expect("one module"),
    )
    .expect("one-module model");
    let mut small = Controller::new(&one, ControllerSettings::paper(&one)).unwrap();
    let status = tick(&model, &mut small, &zero, &zero, good);
    assert!(
        matches!(
            status,
            TickStatus::InvalidState(InvalidState::Size { expected, got: 3, .. }) if expected == nq
        ),
        "{status:?}"
    );
    assert!(small.tau().iter().all(|&t| t == 0.0));
    assert_eq!(
        tick(&model, &mut controller, &zero, &zero, good),
        TickStatus::Filtered
    );
}
