//! The certified safety filter (docs/model.md §5).

use softcbf::control::SafetyMode;
use softcbf::model::Model;
use softcbf::scenario::{Overrides, ScenarioFile};
use softcbf::settings::GainOptions;
use softcbf::sim::simulate;
use softcbf_description::Robot;

#[test]
#[ignore]
fn explore_paper_33hz() {
    let model = Model::new(Robot::paper_sim()).unwrap();
    for safety in [SafetyMode::Certified, SafetyMode::Predicted] {
        let overrides = Overrides {
            gains: GainOptions {
                p1: Some(10.0),
                p2: Some(10.0),
                ..GainOptions::default()
            },
            duration: Some(4.0),
            control_period: Some(1.0 / 33.0),
            safety: Some(safety),
            compare: Some(false),
            record_period: Some(1e-4),
            ..Overrides::default()
        };
        let scenario = ScenarioFile::paper_sim()
            .resolve_with(&model, &overrides)
            .unwrap();
        let start = std::time::Instant::now();
        let run = simulate(&model, &scenario, true, &mut |_| {}).unwrap();
        let s = &run.summary;
        eprintln!(
            "{safety}: lowest {:e} ({}) counts {:?} error {:.4} in {:?}",
            s.min_barrier.value,
            s.min_barrier.label,
            s.counts,
            s.set_point_error,
            start.elapsed()
        );
    }
}

#[test]
#[ignore]
fn explore_regimes() {
    use softcbf::control::{Controller, Reference, tick};
    let model = Model::new(Robot::paper_sim()).unwrap();
    let zero = [0.0; 6];
    let cases: [(&str, f64, [f64; 6], [f64; 6], [f64; 6]); 5] = [
        (
            "1 kHz fast start",
            1e-3,
            [0.01, 0.0, -0.01, 0.0, 0.01, -0.01],
            [0.01, 0.0, 0.0, 0.0, 0.0, 0.0],
            [0.08, 0.0, -0.05, 0.0, -0.06, -0.07],
        ),
        (
            "33 Hz at rest",
            1.0 / 33.0,
            [0.01, 0.0, -0.01, 0.0, 0.01, -0.01],
            zero,
            [0.01, 0.0, -0.01, 0.0, 0.01, -0.01],
        ),
        (
            "33 Hz small step",
            1.0 / 33.0,
            [0.01, 0.0, -0.01, 0.0, 0.01, -0.01],
            zero,
            [0.012, 0.0, -0.01, 0.0, 0.01, -0.012],
        ),
        (
            "33 Hz slow approach",
            1.0 / 33.0,
            [0.05, 0.0, -0.04, 0.0, -0.04, -0.05],
            [0.005, 0.0, -0.002, 0.0, -0.004, -0.002],
            [0.08, 0.0, -0.05, 0.0, -0.06, -0.07],
        ),
        (
            "33 Hz fast start",
            1.0 / 33.0,
            [0.01, 0.0, -0.01, 0.0, 0.01, -0.01],
            [0.01, 0.0, 0.0, 0.0, 0.0, 0.0],
            [0.08, 0.0, -0.05, 0.0, -0.06, -0.07],
        ),
    ];
    for (name, hold, q, qd, set) in cases {
        let mut settings = softcbf::control::ControllerSettings::paper(&model);
        settings.safety = SafetyMode::Certified;
        settings.hold = hold;
        let mut controller = Controller::new(&model, settings).unwrap();
        let mut statuses = Vec::new();
        let start = std::time::Instant::now();
        for _ in 0..5 {
            statuses.push(tick(
                &model,
                &mut controller,
                &q,
                &qd,
                Reference {
                    q: &set,
                    qd: &zero,
                    qdd: &zero,
                },
            ));
        }
        eprintln!(
            "{name}: {:?} in {:?} per tick; τ {:?} τ_nom {:?}",
            statuses,
            start.elapsed() / 5,
            controller
                .tau()
                .iter()
                .map(|x| format!("{x:.2}"))
                .collect::<Vec<_>>(),
            controller
                .tau_nom()
                .iter()
                .map(|x| format!("{x:.2}"))
                .collect::<Vec<_>>()
        );
    }
}

#[test]
#[ignore]
fn explore_one_tick() {
    use softcbf::control::{Controller, Reference, tick};
    let model = Model::new(Robot::paper_sim()).unwrap();
    let mut settings = softcbf::control::ControllerSettings::paper(&model);
    settings.safety = SafetyMode::Certified;
    settings.hold = 1.0 / 33.0;
    let mut controller = Controller::new(&model, settings).unwrap();
    let q = [0.01, 0.0, -0.01, 0.0, 0.01, -0.01];
    let qd = [0.01, 0.0, 0.0, 0.0, 0.0, 0.0];
    let set = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];
    let zero = [0.0; 6];
    for _ in 0..3 {
        let status = tick(
            &model,
            &mut controller,
            &q,
            &qd,
            Reference {
                q: &set,
                qd: &zero,
                qdd: &zero,
            },
        );
        eprintln!("{status:?} tau {:?}", controller.tau());
    }
}

/// How far the true motion drifts from the frozen linear model over one hold.
#[test]
#[ignore]
fn explore_linear_error() {
    use softcbf::control::{Controller, Reference, tick};
    use softcbf::hold::HoldPrediction;
    use softcbf::integrator::Tolerances;
    use softcbf::plant::Plant;
    let model = Model::new(Robot::paper_sim()).unwrap();
    let mut settings = softcbf::control::ControllerSettings::paper(&model);
    settings.safety = SafetyMode::Paper;
    let mut controller = Controller::new(&model, settings).unwrap();
    let q = [0.01, 0.0, -0.01, 0.0, 0.01, -0.01];
    let qd = [0.01, 0.0, 0.0, 0.0, 0.0, 0.0];
    let set = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];
    let zero = [0.0; 6];
    tick(
        &model,
        &mut controller,
        &q,
        &qd,
        Reference {
            q: &set,
            qd: &zero,
            qdd: &zero,
        },
    );
    let tau = controller.tau_nom().to_vec();
    let hold = 1.0 / 33.0;
    let tol = Tolerances {
        rtol: 1e-11,
        atol: 1e-14,
        ..Tolerances::default()
    };
    let mut plant = Plant::new(&model, tol).unwrap();
    plant.reset(&q, &qd, 0.0);
    plant.tau_mut().copy_from_slice(&tau);
    // Linear model with K only.
    let ws = controller.dynamics();
    let nq = 6;
    let mut inverse = vec![0.0; 36];
    let mut work = vec![0.0; 36];
    softcbf::linalg::cholesky_inverse(&ws.cholesky, nq, &mut inverse, &mut work);
    let mut k = vec![0.0; 36];
    for i in 0..nq {
        k[i * nq + i] = model.stiffness[i];
    }
    let mut p = HoldPrediction::new(nq, 8, 6);
    assert!(p.predict(&inverse, &k, &model.damping, &qd, hold));
    let u: Vec<f64> = (0..nq)
        .map(|i| tau[i] - ws.nonlinear[i] - model.stiffness[i] * q[i])
        .collect();
    let mut t = 0.0;
    for j in 0..p.samples() {
        let tj = p.time(j);
        plant.advance(tj - t).unwrap();
        t = tj;
        let mut e = vec![0.0; nq];
        p.excursion(j, &u, &mut e);
        let err: Vec<String> = (0..nq)
            .map(|i| format!("{:+.2e}", plant.q()[i] - q[i] - e[i]))
            .collect();
        eprintln!(
            "t {tj:.5}: error {err:?}  e {:?}",
            e.iter().map(|x| format!("{x:.2e}")).collect::<Vec<_>>()
        );
        // The true forcing of the error: (M0 − M(q)) ë_L + f0 − h(q, ė_L) − G(q).
        let mut ev = vec![0.0; nq];
        let (fv, gv) = (p.free_velocity(j), p.forced_velocity(j));
        for i in 0..nq {
            ev[i] = fv[i] + (0..nq).map(|c| gv[i * nq + c] * u[c]).sum::<f64>();
        }
        let mut acc = vec![0.0; nq];
        for i in 0..nq {
            acc[i] = u[i] - model.damping[i] * ev[i] - model.stiffness[i] * e[i];
        }
        let acc2 = acc.clone();
        for i in 0..nq {
            acc[i] = (0..nq).map(|c| inverse[i * nq + c] * acc2[c]).sum();
        }
        let qt: Vec<f64> = (0..nq).map(|i| plant.q()[i]).collect();
        let mut w2 = softcbf::dynamics::DynamicsWorkspace::new(&model);
        softcbf::dynamics::update_joints(&model, &mut w2, &qt, &ev).unwrap();
        softcbf::dynamics::mass_matrix(&model, &mut w2).unwrap();
        softcbf::dynamics::bias_and_gravity(&model, &mut w2, &ev).unwrap();
        let force: Vec<String> = (0..nq)
            .map(|i| {
                let inertial: f64 = (0..nq)
                    .map(|c| (ws.mass_matrix[i * nq + c] - w2.mass_matrix[i * nq + c]) * acc[c])
                    .sum();
                format!("{:+.2e}", inertial + ws.nonlinear[i] - w2.nonlinear[i])
            })
            .collect();
        eprintln!(
            "    true F {force:?} |acc| {:?}",
            acc.iter().map(|x| format!("{x:.1e}")).collect::<Vec<_>>()
        );
    }
}

#[test]
#[ignore]
fn explore_bias_enclosure() {
    use rand::RngExt;
    use softcbf::dynamics::{DynamicsWorkspace, bias_and_gravity, update_joints};
    use softcbf::enclosure::{EnclosureWorkspace, enclose_bias};
    use softcbf_generated::Interval;
    let model = Model::new(Robot::paper_sim()).unwrap();
    let q0 = [0.01, 0.0, -0.01, 0.0, 0.01, -0.01];
    let v_lo = [0.01, 0.0, -0.001, 0.0, -0.01, -0.001];
    let v_hi = [0.13, 0.01, 0.01, 0.01, 0.0, 0.01];
    for qw in [1e-6, 1e-4] {
        let qbox: Vec<Interval> = q0.iter().map(|&x| Interval::around(x, qw)).collect();
        let vbox: Vec<Interval> = (0..6).map(|i| Interval::new(v_lo[i], v_hi[i])).collect();
        let mut ws = EnclosureWorkspace::new(&model);
        let center: Vec<f64> = vbox.iter().map(|v| v.mid()).collect();
        let delta: Vec<Interval> = vbox.iter().map(|v| *v - v.mid()).collect();
        assert!(enclose_bias(&model, &mut ws, &qbox, &center, &delta));
        let mut d = DynamicsWorkspace::new(&model);
        let mut rng = softcbf_tests::rng(3);
        let mut lo = [f64::INFINITY; 6];
        let mut hi = [f64::NEG_INFINITY; 6];
        for _ in 0..3000 {
            let q: Vec<f64> = q0.iter().map(|&x| x + rng.random_range(-qw..qw)).collect();
            let v: Vec<f64> = (0..6)
                .map(|i| rng.random_range(v_lo[i]..=v_hi[i]))
                .collect();
            update_joints(&model, &mut d, &q, &v).unwrap();
            bias_and_gravity(&model, &mut d, &v).unwrap();
            for i in 0..6 {
                lo[i] = lo[i].min(d.nonlinear[i]);
                hi[i] = hi[i].max(d.nonlinear[i]);
                assert!(ws.nonlinear[i].contains(d.nonlinear[i]));
            }
        }
        for i in 0..6 {
            eprintln!(
                "qw {qw:e} coord {i}: sampled [{:.4}, {:.4}] width {:.2e}; interval [{:.4}, {:.4}] width {:.2e}; per_body {:.3}",
                lo[i],
                hi[i],
                hi[i] - lo[i],
                ws.nonlinear[i].lo(),
                ws.nonlinear[i].hi(),
                ws.nonlinear[i].width(),
                ws.per_body[i]
            );
        }
    }
}

#[test]
#[ignore]
fn explore_bias_pieces() {
    use softcbf::enclosure::{EnclosureWorkspace, enclose_bias};
    use softcbf_generated::Interval;
    let model = Model::new(Robot::paper_sim()).unwrap();
    let q0 = [0.01, 0.0, -0.01, 0.0, 0.01, -0.01];
    let qbox: Vec<Interval> = q0.iter().map(|&x| Interval::point(x)).collect();
    let mut ws = EnclosureWorkspace::new(&model);
    let center = [0.07, 0.005, 0.0045, 0.005, -0.005, 0.0045];
    for r in [0.0, 1e-4, 1e-3, 1e-2, 6e-2] {
        let delta: Vec<Interval> = (0..6).map(|_| Interval::around(0.0, r)).collect();
        assert!(enclose_bias(&model, &mut ws, &qbox, &center, &delta));
        eprintln!(
            "r {r:e}: widths {:?}",
            ws.nonlinear
                .iter()
                .map(|x| format!("{:.2e}", x.width()))
                .collect::<Vec<_>>()
        );
    }
    let center0 = [0.0; 6];
    let delta: Vec<Interval> = (0..6).map(|_| Interval::around(0.0, 0.0)).collect();
    assert!(enclose_bias(&model, &mut ws, &qbox, &center0, &delta));
    eprintln!(
        "gravity only widths {:?}",
        ws.nonlinear
            .iter()
            .map(|x| format!("{:.2e}", x.width()))
            .collect::<Vec<_>>()
    );
}

#[test]
#[ignore]
fn explore_closed_loop_statuses() {
    use softcbf::control::{Controller, Reference, tick};
    use softcbf::integrator::Tolerances;
    use softcbf::plant::Plant;
    let model = Model::new(Robot::paper_sim()).unwrap();
    let mut settings = softcbf::control::ControllerSettings::paper(&model);
    settings.safety = std::env::var("MODE")
        .ok()
        .and_then(|m| SafetyMode::parse(&m).ok())
        .unwrap_or(SafetyMode::Certified);
    settings.filter = std::env::var("NOFILTER").is_err();
    let hold = 1.0 / 33.0;
    settings.hold = hold;
    let mut controller = Controller::new(&model, settings).unwrap();
    let mut plant = Plant::new(
        &model,
        Tolerances {
            rtol: 1e-8,
            atol: 1e-11,
            ..Tolerances::default()
        },
    )
    .unwrap();
    plant.reset(&[0.0; 6], &[0.0; 6], 0.0);
    let set = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];
    let zero = [0.0; 6];
    for k in 0..40 {
        let (q, qd) = (plant.q().to_vec(), plant.qd().to_vec());
        let start = std::time::Instant::now();
        let status = tick(
            &model,
            &mut controller,
            &q,
            &qd,
            Reference {
                q: &set,
                qd: &zero,
                qdd: &zero,
            },
        );
        let elapsed = start.elapsed();
        let b = controller
            .barriers()
            .iter()
            .cloned()
            .fold(f64::INFINITY, f64::min);
        eprintln!(
            "tick {k}: {status:?} {elapsed:?} min b {b:.4e} |qd| {:.3}",
            qd.iter().map(|x| x.abs()).fold(0.0, f64::max)
        );
        plant.tau_mut().copy_from_slice(controller.tau());
        plant.advance(hold).unwrap();
    }
}
