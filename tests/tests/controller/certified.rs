//! The certified safety filter (docs/model.md §5, "The certified guarantee") against an
//! independent check: for random states, set points, holds and plants inside the declared
//! box, every command the filter reports proven is held for the whole hold on a plant
//! integrated with the tests' own reference dynamics (`softcbf_tests::reference`, a jet
//! implementation of the Lagrangian, not the generated code) and the tests' Dormand–Prince
//! at tight tolerance, and every barrier, evaluated in closed form at 400 instants of the
//! hold, must stay at or above the bound the filter proved for it. A bound is a statement
//! about every instant, so a sampled minimum above it is necessary: any dip below it fails
//! the test.
//!
//! Episodes of three ticks follow the plant, so the filter's warm start (the margins the
//! last tick proved) is exercised too; some start with speeds of 1 m/s (stiff transients of
//! the axial mode).

use nalgebra::{DMatrix, DVector};
use rand::RngExt;
use softcbf::control::{Controller, ControllerSettings, Reference, SafetyMode, TickStatus, tick};
use softcbf::integrator::{OdeSystem, Tolerances};
use softcbf::model::Model;
use softcbf_description::Robot;
use softcbf_tests::integrators::DormandPrince;
use softcbf_tests::reference::{all_barrier_values_closed_form, dynamics, stiffness_and_damping};

/// Instants of the hold at which the true barriers are evaluated (besides its ends).
const POINTS: usize = 400;
/// The reference integration's own error allowance \[m\] (rtol 1e-11 on states of 0.1 m).
const INTEGRATION: f64 = 1e-10;

/// The plant `M(q) q̈ = τ + w − h(q, q̇) − G(q) − K q − D q̇` of `robot` from the reference
/// dynamics, with a constant unmodelled force `w`.
struct ReferencePlant<'a, const N: usize> {
    robot: &'a Robot,
    stiffness: Vec<f64>,
    damping: Vec<f64>,
    tau: [f64; N],
}

impl<const N: usize> OdeSystem for ReferencePlant<'_, N> {
    fn dim(&self) -> usize {
        2 * N
    }

    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        let q: [f64; N] = std::array::from_fn(|i| x[i]);
        let qd: [f64; N] = std::array::from_fn(|i| x[N + i]);
        let d = dynamics::<N>(self.robot, &q, &qd);
        let mass = DMatrix::from_fn(N, N, |r, c| d.mass_matrix[r][c]);
        let force = DVector::from_fn(N, |i, _| {
            self.tau[i]
                - d.bias[i]
                - d.gravity[i]
                - self.stiffness[i] * q[i]
                - self.damping[i] * qd[i]
        });
        let Some(acceleration) = mass.cholesky().map(|c| c.solve(&force)) else {
            return false;
        };
        dx[..N].copy_from_slice(&qd);
        for i in 0..N {
            dx[N + i] = acceleration[i];
        }
        dx.iter().all(|v| v.is_finite())
    }
}

/// The lowest closed-form value of every barrier of `plant` over `[0, hold]` under `τ`
/// from `(q, q̇)`, and the state at the hold's end.
fn true_lowest<const N: usize>(
    plant: &Robot,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
    hold: f64,
) -> Option<(Vec<f64>, Vec<f64>)> {
    let (stiffness, damping) = stiffness_and_damping(plant);
    let mut system = ReferencePlant::<N> {
        robot: plant,
        stiffness,
        damping,
        tau: std::array::from_fn(|i| tau[i]),
    };
    let tolerances = Tolerances {
        rtol: 1e-11,
        atol: 1e-13,
        h_initial: 1e-6,
        max_steps: 1_000_000,
        ..Tolerances::default()
    };
    let mut integrator = DormandPrince::new(2 * N, tolerances).ok()?;
    let mut x: Vec<f64> = q.iter().chain(qd).copied().collect();
    let mut lowest = all_barrier_values_closed_form(plant, q);
    for step in 1..=POINTS + 1 {
        let (t0, t1) = (
            hold * (step - 1) as f64 / (POINTS + 1) as f64,
            hold * step as f64 / (POINTS + 1) as f64,
        );
        integrator.integrate(&mut system, t0, t1, &mut x).ok()?;
        for (low, value) in lowest
            .iter_mut()
            .zip(all_barrier_values_closed_form(plant, &x[..N]))
        {
            *low = low.min(value);
        }
    }
    Some((lowest, x))
}

/// What the episodes of one robot found.
#[derive(Debug, Default)]
struct Tally {
    ticks: usize,
    proven: usize,
    /// Proven ticks whose command is not the QP's but a point on the line from the
    /// predicted rows' command to holding the state (the backup, docs/model.md §5): every
    /// proven tick is checked alike, so these are too.
    backups: u64,
    /// Over proven ticks: the smallest gap `true lowest − bound` over barriers, and for the
    /// barrier closest to zero the bound and the true lowest value.
    closest: Vec<(f64, f64)>,
    /// Every status seen, with its count.
    statuses: std::collections::BTreeMap<String, usize>,
}

/// `episodes` episodes of three ticks on `model`'s robot (the controller) against `plant`,
/// from random states at least 2 mm inside every barrier, toward random set points, at each
/// hold of `holds`; `fast`: speeds up to 1 m/s instead of 0.2 m/s.
fn episodes<const N: usize>(
    model: &Model,
    plant: &Robot,
    seed: u64,
    episodes: usize,
    holds: &[f64],
    fast: bool,
) -> Tally {
    assert_eq!(model.nq(), N);
    let robot = &model.robot;
    let modules = robot.modules.len();
    let mut rng = softcbf_tests::rng(seed);
    let mut tally = Tally::default();
    let speed = if fast { 1.0 } else { 0.2 };
    for &hold in holds {
        for _ in 0..episodes {
            // A state inside every barrier, with clearance, and inside the domain.
            let (q, qd) = loop {
                let q: Vec<f64> = (0..modules)
                    .flat_map(|_| {
                        [
                            rng.random_range(-0.06..0.06),
                            rng.random_range(-0.06..0.06),
                            rng.random_range(-0.04..0.03),
                        ]
                    })
                    .collect();
                let qd: Vec<f64> = (0..N).map(|_| rng.random_range(-speed..speed)).collect();
                let clear = all_barrier_values_closed_form(plant, &q)
                    .iter()
                    .all(|b| *b >= 2e-3);
                if clear && softcbf_description::domain::state_problem(robot, &q, &qd).is_none() {
                    break (q, qd);
                }
            };
            let set_point: Vec<f64> = (0..modules)
                .flat_map(|_| {
                    [
                        rng.random_range(-0.1..0.1),
                        rng.random_range(-0.1..0.1),
                        rng.random_range(-0.07..0.05),
                    ]
                })
                .collect();
            let mut settings = ControllerSettings::paper(model);
            settings.safety = SafetyMode::Certified;
            settings.hold = hold;
            let mut controller = Controller::new(model, settings).expect("controller");
            let zero = vec![0.0; N];
            let (mut q, mut qd) = (q, qd);
            for _ in 0..3 {
                let backups_before = controller.certified_split().map_or(0, |s| s.backups);
                let reference = Reference {
                    q: &set_point,
                    qd: &zero,
                    qdd: &zero,
                };
                let status = tick(model, &mut controller, &q, &qd, reference);
                tally.ticks += 1;
                *tally
                    .statuses
                    .entry(format!("{hold:.4} {status:?}"))
                    .or_default() += 1;
                // The controller's barriers are the closed forms' (same order and values).
                let closed = all_barrier_values_closed_form(robot, &q);
                assert_eq!(closed.len(), controller.barriers().len());
                for (a, b) in closed.iter().zip(controller.barriers()) {
                    assert!((a - b).abs() <= 1e-9, "{a} against {b}");
                }
                let bound = controller.certified_bound().map(<[f64]>::to_vec);
                assert_eq!(
                    bound.is_some(),
                    status == TickStatus::Filtered,
                    "{status:?}"
                );
                let Some((lowest, end)) = true_lowest::<N>(plant, &q, &qd, controller.tau(), hold)
                else {
                    // The plant failed (left the domain): only an unproven command may do that.
                    assert!(
                        bound.is_none(),
                        "a proven command broke the plant at {q:?} {qd:?}"
                    );
                    break;
                };
                if let Some(bound) = bound {
                    tally.proven += 1;
                    tally.backups +=
                        controller.certified_split().map_or(0, |s| s.backups) - backups_before;
                    let mut gap = f64::INFINITY;
                    for (k, (b, t)) in bound.iter().zip(&lowest).enumerate() {
                        assert!(
                            *t >= *b - INTEGRATION,
                            "{}: barrier {k} reached {t:e} m, below its proven bound {b:e} m \
                             (hold {hold} s, q {q:?}, q̇ {qd:?}, set point {set_point:?})",
                            robot.name
                        );
                        if closed[k] >= 0.0 {
                            assert!(*b >= 0.0, "a proven bound below zero: {b:e}");
                        }
                        gap = gap.min(t - b);
                    }
                    let k = (0..lowest.len())
                        .min_by(|&a, &b| lowest[a].total_cmp(&lowest[b]))
                        .unwrap_or(0);
                    tally.closest.push((bound[k], lowest[k]));
                    let _ = gap;
                }
                q = end[..N].to_vec();
                qd = end[N..].to_vec();
                if softcbf_description::domain::state_problem(robot, &q, &qd).is_some() {
                    break;
                }
            }
        }
    }
    eprintln!(
        "{} against {}: {} of {} ticks proven ({} by the backup); {:?}",
        robot.name, plant.name, tally.proven, tally.ticks, tally.backups, tally.statuses
    );
    tally
}

fn repo_robot(name: &str) -> Robot {
    Robot::load(&softcbf_tests::robots::path(name)).expect("shipped robot file")
}

/// Asserts that at least `fraction` of the ticks were proven (the test is not vacuous). The
/// fractions below are what the bound proves on these adversarial draws (random states near
/// the barriers, speeds up to 1 m/s), with some room: measured 32/72, 10/36, 8/30 and 1/72
/// (the ±20 % box); in the closed-loop scenarios far more ticks are proven (docs/model.md §5).
fn mostly_proven(tally: &Tally, fraction: f64) {
    assert!(
        tally.proven as f64 >= fraction * tally.ticks as f64,
        "only {} of {} ticks proven",
        tally.proven,
        tally.ticks
    );
}

/// The paper's robot at the paper's 1 kHz, a 10 ms hold, the hardware's 33 Hz and a slow
/// 20 Hz, from moderate and from fast states.
#[test]
fn the_bound_holds_on_the_paper_robot() {
    let model = Model::new(Robot::paper_sim()).unwrap();
    let holds = [1e-3, 1e-2, 1.0 / 33.0, 0.05];
    let calm = episodes::<6>(&model, &model.robot, 27, 6, &holds, false);
    mostly_proven(&calm, 0.35);
    let fast = episodes::<6>(&model, &model.robot, 28, 3, &holds, true);
    mostly_proven(&fast, 0.2);
}

/// Three modules with square plates (nine coordinates), at 1 kHz and 33 Hz.
#[test]
fn the_bound_holds_on_three_square_modules() {
    let model = Model::new(repo_robot("three-square.toml")).unwrap();
    let tally = episodes::<9>(&model, &model.robot, 29, 5, &[1e-3, 1.0 / 33.0], false);
    mostly_proven(&tally, 0.2);
}

/// The paper's robot declaring ±20 % on stiffness, damping and mass: plants drawn inside the
/// box, and plants at its corners.
#[test]
fn the_bound_holds_for_plants_inside_the_declared_box() {
    let declared = softcbf_tests::robots::paper_sim_uncertain();
    let model = Model::new(declared.clone()).unwrap();
    let mut tally = Tally::default();
    for draw in 0..4u64 {
        let plant = if draw < 2 {
            softcbf_tests::robots::draw_within(&declared, 500 + draw)
        } else {
            // Corners: everything soft, light and weakly damped, or the opposite.
            let f = if draw == 2 { 0.8 } else { 1.2 };
            let g = 2.0 - f;
            let factors: Vec<_> = declared
                .modules
                .iter()
                .map(|_| softcbf_description::uncertainty::ModuleFactors {
                    stiffness: [f, f],
                    damping: [f, f],
                    mass: g,
                })
                .collect();
            softcbf_description::uncertainty::scaled(&declared, &factors).unwrap()
        };
        assert!(softcbf_description::uncertainty::contains(
            &declared, &plant
        ));
        let t = episodes::<6>(&model, &plant, 600 + draw, 3, &[1e-3, 1.0 / 33.0], false);
        tally.ticks += t.ticks;
        tally.proven += t.proven;
    }
    mostly_proven(&tally, 0.01);
}

/// The backup (docs/model.md §5): where no attempt proves the QP's command, a point on the
/// line from the predicted rows' command to holding the state may be proven instead. A
/// closed loop that needs it, `scenarios/verify-paper.toml`'s run 35 (seed 1: from rest
/// toward the set point below, at 33 Hz): 100 ticks, each held on the tests' reference
/// plant, and every proven tick's bound checked against the true barriers over its hold,
/// those proven by the backup among them. It must meet at least one such tick (the test
/// is not vacuous).
#[test]
fn ticks_proven_by_the_backup_hold_their_bound() {
    const N: usize = 6;
    let model = Model::new(Robot::paper_sim()).unwrap();
    let robot = &model.robot;
    let set_point = [
        0.07320929733462704,
        -0.06399910750656182,
        -0.06730955064498843,
        0.04289200938565489,
        0.07155517465083204,
        -0.03594174139327748,
    ];
    let hold = 0.0303;
    let mut settings = ControllerSettings::paper(&model);
    settings.safety = SafetyMode::Certified;
    settings.hold = hold;
    let mut controller = Controller::new(&model, settings).expect("controller");
    let zero = [0.0; N];
    let (mut q, mut qd) = (vec![0.0; N], vec![0.0; N]);
    let (mut proven, mut backups) = (0, 0);
    for tick_index in 0..100 {
        let before = controller.certified_split().map_or(0, |s| s.backups);
        let reference = Reference {
            q: &set_point,
            qd: &zero,
            qdd: &zero,
        };
        let status = tick(&model, &mut controller, &q, &qd, reference);
        let by_backup = controller.certified_split().map_or(0, |s| s.backups) > before;
        let bound = controller.certified_bound().map(<[f64]>::to_vec);
        assert_eq!(
            bound.is_some(),
            status == TickStatus::Filtered,
            "{status:?}"
        );
        assert!(
            !by_backup || bound.is_some(),
            "a backup tick is a proven one"
        );
        let (lowest, end) = true_lowest::<N>(robot, &q, &qd, controller.tau(), hold)
            .expect("the reference plant integrates the hold");
        if let Some(bound) = bound {
            proven += 1;
            backups += usize::from(by_backup);
            for (k, (b, t)) in bound.iter().zip(&lowest).enumerate() {
                assert!(
                    *t >= *b - INTEGRATION,
                    "tick {tick_index} (backup: {by_backup}): barrier {k} reached {t:e} m, \
                     below its proven bound {b:e} m"
                );
            }
        }
        q = end[..N].to_vec();
        qd = end[N..].to_vec();
    }
    eprintln!("verify-paper run 35: {proven} of 100 ticks proven, {backups} by the backup");
    assert!(backups >= 1, "no tick needed the backup ({proven} proven)");
    assert!(proven >= 90, "{proven} of 100 ticks proven");
}
