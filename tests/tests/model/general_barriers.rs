//! The general barriers of issue 12 in closed loop: the paper's scenario with elongation
//! limits, a sphere in the way, and the relaxed problem when limits, cable tensions and a
//! fast approach leave no common point.

use std::path::{Path, PathBuf};

use softcbf::control::{Controller, ControllerSettings, Reference, TickStatus, tick};
use softcbf::hardware::mapping::TendonMap;
use softcbf::model::Model;
use softcbf::scenario::{Scenario, ScenarioFile};
use softcbf::sim::{Run, simulate};
use softcbf_description::Robot;
use softcbf_description::barriers::{BarrierKind, Shape};

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

fn scenario(path: &str) -> (Model, Scenario) {
    let file = ScenarioFile::load(&repo(path)).expect("shipped scenario reads");
    let robot = file
        .load_robot()
        .expect("its robot reads")
        .expect("it names a robot");
    let model = Model::new(robot).expect("its model is generated");
    let scenario = file.resolve(&model).expect("it resolves");
    (model, scenario)
}

fn run(model: &Model, scenario: &Scenario, filter: bool) -> Run {
    let run = simulate(model, scenario, filter, &mut |_| {}).expect("simulation starts");
    assert_eq!(run.summary.stopped, None, "the run stopped early");
    run
}

/// The lowest value of every barrier over the run, in barrier order.
fn lowest_per_barrier(run: &Run) -> Vec<f64> {
    (0..run.record.columns().m())
        .map(|j| run.record.b(j).fold(f64::INFINITY, f64::min))
        .collect()
}

/// `δL_i` over the run, from its CSV column (not from a barrier).
fn elongation(run: &Run, module: usize) -> Vec<f64> {
    let columns = run.record.columns();
    let name = format!("dL{module} [m]");
    let index = columns.index_of(&name).expect("a δL column");
    run.record.column(index).collect()
}

/// `paper-sim-limits`: every corner and limit barrier stays ≥ −1e-6 at 1 kHz, and `δL`
/// itself (read from the coordinates, not the barriers) stays inside [−0.05, 0.03] m for
/// the whole run, where the unlimited run stretches `δL₂` to 0.24 m. Plain PD+ ignores
/// the limits and ends at the set point's `δL₂ = −0.07 m`.
#[test]
fn paper_scenario_with_elongation_limits_keeps_them() {
    let (model, scenario) = scenario("scenarios/paper-sim-limits.toml");
    assert_eq!(scenario.control_period, 0.001);
    let table = model.generated.barrier_table();
    let kinds: Vec<BarrierKind> = table.iter().map(|b| b.kind).collect();
    assert_eq!(
        kinds
            .iter()
            .filter(|&&k| k == BarrierKind::PlateCorner)
            .count(),
        12
    );
    assert_eq!(
        kinds
            .iter()
            .filter(|&&k| matches!(k, BarrierKind::ElongationMin | BarrierKind::ElongationMax))
            .count(),
        4
    );
    let filtered = run(&model, &scenario, true);
    for (k, lowest) in lowest_per_barrier(&filtered).into_iter().enumerate() {
        assert!(lowest >= -1e-6, "{}: lowest {lowest}", table[k].label);
    }
    assert_eq!(filtered.summary.counts.failed, 0);
    for module in 1..=2 {
        let dl = elongation(&filtered, module);
        let (low, high) = dl
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        assert!(
            low >= -0.05 - 1e-6 && high <= 0.03 + 1e-6,
            "module {module}: δL in [{low}, {high}]"
        );
    }
    let plain = run(&model, &scenario, false);
    let dl2 = elongation(&plain, 2);
    let last = *dl2.last().expect("rows");
    assert!(
        (last + 0.07).abs() < 1e-3,
        "PD+ should reach δL₂ = −0.07 m, got {last}"
    );
}

/// `obstacle`: with the filter no watched point comes within the sphere's radius plus
/// margin (every barrier ≥ −1e-6 at 1 kHz); plain PD+ drives module 2's plate centre
/// into the sphere itself. The distance is measured from the plate poses, independently
/// of the barrier's generated expression.
#[test]
fn the_filter_keeps_watched_points_out_of_the_sphere() {
    let (model, scenario) = scenario("scenarios/obstacle.toml");
    let Shape::Sphere { center, radius } = model.robot.obstacles[0].shape else {
        panic!("the obstacle is a sphere")
    };
    let margin = model.robot.obstacles[0].margin;
    let table = model.generated.barrier_table();
    let filtered = run(&model, &scenario, true);
    for (k, lowest) in lowest_per_barrier(&filtered).into_iter().enumerate() {
        assert!(lowest >= -1e-6, "{}: lowest {lowest}", table[k].label);
    }
    let nq = model.nq();
    let centre_distance = |run: &Run| {
        let mut poses = vec![[[0.0; 4]; 4]; model.n_modules()];
        run.record
            .rows()
            .map(|row| {
                model
                    .generated
                    .plate_poses(&model.params, &row.q[..nq], &mut poses);
                let p = [poses[1][0][3], poses[1][1][3], poses[1][2][3]];
                ((p[0] - center[0]).powi(2)
                    + (p[1] - center[1]).powi(2)
                    + (p[2] - center[2]).powi(2))
                .sqrt()
            })
            .fold(f64::INFINITY, f64::min)
    };
    let closest = centre_distance(&filtered);
    assert!(
        closest >= radius + margin - 1e-6,
        "filter: plate centre {closest} m from the sphere's centre"
    );
    let plain = run(&model, &scenario, false);
    let closest_pd = centre_distance(&plain);
    assert!(
        closest_pd < radius,
        "PD+ should pass through the sphere, closest {closest_pd} m"
    );
    assert!(plain.summary.min_barrier.value < -margin);
}

/// When the rows have no common point the tick solves the slack-relaxed problem and says
/// which rows it relaxed: module 1 of the example robot, 1 mm above its elongation
/// barrier's zero and compressing at 0.5 m/s, cannot be stopped by cable tensions of at
/// most 40 N within the class-K bound.
#[test]
fn an_infeasible_elongation_limit_is_relaxed_and_reported() {
    let robot = Robot::load(&repo("robots/hardware-example.toml")).expect("example robot");
    let map = TendonMap::new(&robot).expect("its [hardware] table");
    let model = Model::new(robot).expect("its model");
    let table = model.generated.barrier_table();
    let limit = table
        .iter()
        .position(|b| b.kind == BarrierKind::ElongationMin && b.module == 0)
        .expect("module 1 has a lower elongation limit");
    let mut settings = ControllerSettings::paper(&model);
    settings.input_limits = map.tension_limit_rows();
    let mut controller = Controller::new(&model, settings).expect("controller");
    let [min, _] = model.robot.limits[0].elongation;
    let dl = min + model.robot.limits[0].elongation_margin + 0.001;
    let q = [0.0, 0.0, dl, 0.0, 0.0, 0.0];
    let qd = [0.0, 0.0, -0.5, 0.0, 0.0, 0.0];
    let zero = [0.0; 6];
    let reference = Reference {
        q: &[0.0, 0.0, -0.04, 0.0, 0.0, 0.0],
        qd: &zero,
        qdd: &zero,
    };
    let status = tick(&model, &mut controller, &q, &qd, reference);
    assert_eq!(status, TickStatus::Relaxed);
    let report = controller.qp_report();
    assert!(
        report.relaxed_rows.contains(&limit),
        "relaxed rows {:?}, the limit is row {limit}",
        report.relaxed_rows
    );
    assert!(controller.tau().iter().all(|t| t.is_finite()));
    // At rest where the springs carry the plates' weight and the cables' least tension, far
    // from the limit, the same controller filters without relaxing. (Straight and unloaded,
    // q = 0, is no such state: the cables only pull down, at f_min at least, so nothing
    // could stop the light upper plate's fall toward its limit at once.)
    let hardware = map.hardware();
    let at_rest = |i: usize| {
        let weight: f64 = model.robot.modules[i..].iter().map(|m| m.mass * 9.81).sum();
        let pull = 3.0 * hardware.modules[i].tension_limits[0];
        -(weight + pull) / model.robot.modules[i].axial_stiffness
    };
    let q = [0.0, 0.0, at_rest(0), 0.0, 0.0, at_rest(1)];
    let reference = Reference {
        q: &q,
        qd: &zero,
        qdd: &zero,
    };
    let status = tick(&model, &mut controller, &q, &zero, reference);
    assert_eq!(
        status,
        TickStatus::Filtered,
        "{:?} {:?}",
        controller.qp_report(),
        controller.constraints().1
    );
}

/// A state whose backbone has no length is an invalid state for the tick: the zero
/// command and a status, never a number computed from it.
#[test]
fn a_backbone_of_no_length_is_an_invalid_state() {
    let model = Model::new(Robot::paper_sim()).expect("paper model");
    let mut controller =
        Controller::new(&model, ControllerSettings::paper(&model)).expect("controller");
    let zero = [0.0; 6];
    let reference = Reference {
        q: &zero,
        qd: &zero,
        qdd: &zero,
    };
    for dl in [-0.1, -0.2] {
        let q = [0.0, 0.0, 0.0, 0.0, 0.0, dl];
        let status = tick(&model, &mut controller, &q, &zero, reference);
        assert_eq!(
            status,
            TickStatus::InvalidState(softcbf::control::InvalidState::OutOfDomain)
        );
        assert!(controller.tau().iter().all(|&t| t == 0.0));
    }
}

/// The predicted rows give way in the order of what each is for: on the example robot
/// (±10 % declared, cables that only pull), module 1 compressing toward its lower limit at
/// 58 mm/s (the second tick of the hardware walk-through against the emulator), the robust
/// margin of the end-of-hold rows asks for more than the cables can give; without it every
/// row is met, the samples' rows with their margins included. Before the rows gave way in
/// order this tick was relaxed.
#[test]
fn end_of_hold_margins_give_way_before_any_row_is_relaxed() {
    use softcbf::control::{GaveWay, SafetyMode};
    let robot = Robot::load(&repo("robots/hardware-example.toml")).expect("example robot");
    assert!(robot.uncertainty.stiffness > 0.0, "the file declares a box");
    let map = TendonMap::new(&robot).expect("its [hardware] table");
    let model = Model::new(robot).expect("its model");
    let mut settings = ControllerSettings::paper(&model);
    settings.input_limits = map.tension_limit_rows();
    settings.safety = SafetyMode::Predicted;
    settings.hold = 1.0 / 33.0;
    settings.barrier_gains = [20.0, 20.0];
    let mut controller = Controller::new(&model, settings).expect("controller");
    let q = [0.0, 3.22e-4, -0.015347, 0.0, -1.4726e-3, -7.064e-3];
    let qd = [-6.23e-4, 3.957e-3, -0.057554, 0.0, -0.036691, -0.16295];
    // The walk-through's set point (the file's [hardware] table).
    let set_point = [0.0, 0.0, -0.04, 0.0, -0.065, 0.0];
    let zero = [0.0; 6];
    let reference = Reference {
        q: &set_point,
        qd: &zero,
        qdd: &zero,
    };
    let status = tick(&model, &mut controller, &q, &qd, reference);
    assert_eq!(status, TickStatus::Filtered, "{:?}", controller.qp_report());
    assert_eq!(controller.gave_way(), GaveWay::EndMargins);
    // Every row the command was given is met (the end rows without their margins).
    let (rows, rhs) = controller.constraints();
    let nq = 6;
    for (r, want) in rhs.iter().enumerate() {
        let have: f64 = (0..nq)
            .map(|i| rows[r * nq + i] * controller.tau()[i])
            .sum();
        assert!(
            have >= want - 1e-7 * (1.0 + want.abs()),
            "row {r}: {have} < {want}"
        );
    }
}

/// A loop with a deadline limits the time a certified tick spends on its attempts: on the
/// ±20 % robot at the start of the paper's scenario the first attempt's bound does not
/// close (the later attempts prove a command closer to holding the state); with a budget
/// smaller than any attempt no second attempt starts, and the tick says why it is not
/// proven. Without a budget the tick is unchanged.
#[test]
fn a_compute_budget_stops_the_certified_attempts() {
    use softcbf::control::{SafetyMode, Uncertified};
    let robot = Robot::load(&repo("robots/paper-sim-uncertain.toml")).expect("±20 % robot");
    let model = Model::new(robot).expect("its model");
    let mut settings = ControllerSettings::paper(&model);
    settings.safety = SafetyMode::Certified;
    settings.hold = 0.0303;
    let set_point = model.robot.set_point.clone().expect("the file's set point");
    let zero = [0.0; 6];
    let reference = Reference {
        q: &set_point,
        qd: &zero,
        qdd: &zero,
    };
    let (q, qd) = (
        [0.02, 0.0, -0.01, 0.0, -0.02, -0.02],
        [0.05, 0.0, -0.05, 0.0, -0.05, -0.05],
    );
    let mut free = Controller::new(&model, settings.clone()).expect("controller");
    let unlimited = tick(&model, &mut free, &q, &qd, reference);
    let mut limited = Controller::new(&model, settings).expect("controller");
    assert!(limited.set_compute_budget(1e-9));
    assert!(!limited.set_compute_budget(0.0) && !limited.set_compute_budget(f64::NAN));
    let status = tick(&model, &mut limited, &q, &qd, reference);
    assert_eq!(
        status,
        TickStatus::Uncertified(Uncertified::Budget),
        "{unlimited:?}"
    );
    assert_ne!(unlimited, status);
    assert!(limited.tau().iter().all(|t| t.is_finite()));
}
