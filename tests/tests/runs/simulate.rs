//! The closed loop: the paper's scenario with and without the safety filter, a reachable
//! set point, agreement with a tight-tolerance run, and scenario-file errors.

use std::path::Path;

use softcbf::control::SafetyMode;
use softcbf::model::Model;
use softcbf::reference::ReferenceSpec;
use softcbf::robot_file::load_robot;
use softcbf::scenario::{Scenario, ScenarioFile};
use softcbf::settings::Source;
use softcbf::sim::{Run, simulate};

fn paper() -> (Model, Scenario) {
    let model = Model::new(load_robot(None).expect("embedded robot")).expect("paper model");
    let scenario = ScenarioFile::paper_sim()
        .resolve(&model)
        .expect("paper scenario");
    (model, scenario)
}

fn run(model: &Model, scenario: &Scenario, filter: bool) -> Run {
    let run = simulate(model, scenario, filter, &mut |_| {}).expect("simulation starts");
    assert_eq!(run.summary.stopped, None, "the run stopped early");
    run
}

fn min_barrier(run: &Run) -> f64 {
    let nb = run.record.columns().m();
    (0..nb)
        .flat_map(|j| run.record.b(j))
        .fold(f64::INFINITY, f64::min)
}

/// The paper's result (§IV, Fig. 4): with the filter every barrier stays non-negative for
/// the whole run and the unsafe set point is not reached; plain PD+ drives some below 0.
#[test]
fn paper_scenario_filter_keeps_barriers_and_pd_violates_them() {
    let (model, scenario) = paper();
    assert_eq!(scenario.duration, 10.0);
    let filtered = run(&model, &scenario, true);
    assert_eq!(filtered.record.len(), 10_001);
    let lowest = min_barrier(&filtered);
    assert!(lowest >= -1e-6, "filtered run: lowest barrier {lowest}");
    assert_eq!(lowest, filtered.summary.min_barrier.value);
    assert!(
        filtered.summary.set_point_error > 0.01,
        "the set point lies outside the safe set, yet the error is {}",
        filtered.summary.set_point_error
    );
    assert_eq!(filtered.summary.counts.failed, 0);
    assert_eq!(filtered.summary.counts.invalid_state, 0);
    assert!(filtered.summary.counts.active > 0);

    let plain = run(&model, &scenario, false);
    let lowest_pd = min_barrier(&plain);
    assert!(
        lowest_pd < 0.0,
        "plain PD+ should violate a barrier, lowest {lowest_pd}"
    );
    assert_eq!(plain.summary.counts.qp_solves, 0);
}

/// A set point inside the safe set is reached to 1e-4 with the filter on.
#[test]
fn safe_set_point_is_reached_with_the_filter_on() {
    let (model, mut scenario) = paper();
    scenario.reference = ReferenceSpec::SetPoint(vec![0.02, 0.0, 0.0, 0.0, 0.01, 0.0]);
    let filtered = run(&model, &scenario, true);
    assert!(
        filtered.summary.set_point_error < 1e-4,
        "error {} at the end",
        filtered.summary.set_point_error
    );
    assert!(min_barrier(&filtered) > 0.0);
    // Near the end no row is active, so the command is the nominal one.
    let last = filtered.record.row(filtered.record.len() - 1).unwrap();
    assert_eq!(last.tau, last.tau_nom);
}

/// The default tolerances against a run at rtol 1e-10, atol 1e-13, over the whole 10 s:
/// `q` at every tick within 1e-6 m (measured 1.4e-7 m; the closed loop is not chaotic, so
/// the difference is the integrator's, summed over the run). The plant's steps span a whole
/// tick, so this is what checks that its error estimate is honest: an estimate that let
/// through errors of 1e-7 per tick would add up to far more.
#[test]
fn closed_loop_agrees_with_a_tight_tolerance_run() {
    let (model, mut scenario) = paper();
    let coarse = run(&model, &scenario, true);
    scenario.tolerances.rtol = 1e-10;
    scenario.tolerances.atol = 1e-13;
    let fine = run(&model, &scenario, true);
    let nq = model.nq();
    assert_eq!(coarse.record.len(), 10_001);
    assert_eq!(fine.record.len(), 10_001);
    let mut worst = 0.0_f64;
    for i in 0..nq {
        for (a, b) in coarse.record.q(i).zip(fine.record.q(i)) {
            worst = worst.max((a - b).abs());
        }
    }
    eprintln!("largest |Δq| between rtol 1e-6 and 1e-10 over 10 s: {worst:.2e} m");
    assert!(worst < 1e-6, "trajectories differ by {worst} m");
    assert!(fine.summary.integrator_rhs_evals > coarse.summary.integrator_rhs_evals);
}

/// A trajectory reference is followed: PD+ without the filter tracks a minimum-jerk move
/// inside the safe set closely at its end.
#[test]
fn waypoint_reference_is_tracked() {
    let (model, mut scenario) = paper();
    scenario.duration = 6.0;
    scenario.reference = ReferenceSpec::Waypoints(vec![
        (0.0, vec![0.0; 6]),
        (2.0, vec![0.01, 0.0, -0.01, 0.0, 0.01, 0.0]),
        (3.0, vec![0.01, 0.01, -0.01, 0.0, 0.01, 0.0]),
    ]);
    let plain = run(&model, &scenario, false);
    assert!(
        plain.summary.set_point_error < 1e-4,
        "{}",
        plain.summary.set_point_error
    );
}

/// The three-module square-plate robot at 1 kHz: with the paper's rows a barrier dips below
/// zero between ticks (the zero-order hold on a stiff plant); with the default sampled-data
/// rows every barrier stays non-negative, and the scenario file is loaded with its relative
/// robot path.
#[test]
fn sampled_rows_keep_three_square_barriers() {
    let file = ScenarioFile::load(Path::new("../scenarios/three-square.toml")).unwrap();
    let robot = load_robot(file.robot_path().as_deref()).unwrap();
    let model = Model::new(robot).unwrap();
    assert_eq!(model.nq(), 9);
    let mut scenario = file.resolve(&model).unwrap();
    assert_eq!(scenario.controller.safety, SafetyMode::Certified);
    assert_eq!(scenario.controller.hold, scenario.control_period);
    scenario.duration = 3.0;
    let sampled = run(&model, &scenario, true);
    let lowest = min_barrier(&sampled);
    assert!(
        lowest >= -1e-6,
        "with the sampled rows: lowest barrier {lowest}"
    );
    scenario.controller.safety = SafetyMode::Paper;
    let paper_rows = run(&model, &scenario, true);
    let lowest = min_barrier(&paper_rows);
    eprintln!("three-square at 1 kHz, paper's rows: lowest barrier {lowest:.3e} m");
    assert!(
        lowest < -1e-4,
        "the paper's rows were expected to dip here, lowest {lowest}"
    );
}

fn scenario_error(text: &str) -> String {
    let model = Model::new(load_robot(None).unwrap()).unwrap();
    let path = Path::new("scenarios/bad.toml");
    match ScenarioFile::parse(text, path).and_then(|file| file.resolve(&model)) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(error) => error.to_string(),
    }
}

#[test]
fn malformed_scenarios_name_file_line_and_field() {
    let reference = "[reference]\nset_point = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\n";
    let cases: &[(String, &str)] = &[
        (
            format!("duration = \"ten\"\n{reference}"),
            "scenarios/bad.toml:1:12: field `duration`",
        ),
        (
            format!("duration = -1.0\n{reference}"),
            "scenarios/bad.toml:1: field `duration`: must be > 0 and ≤ 1000000 s, got -1",
        ),
        (
            "[reference]\nset_point = [0.1, 0.2]\n".to_string(),
            "scenarios/bad.toml:2: field `reference.set_point`: has 2 entries, the robot has 6",
        ),
        (
            format!("gain = 3\n{reference}"),
            "scenarios/bad.toml:1:1: field `gain`: unknown field `gain`, expected one of `name`",
        ),
        (
            format!("{reference}[gains]\nkp = [1.0, 2.0]\n"),
            "scenarios/bad.toml:4: field `gains.kp`: has 2 entries",
        ),
        (
            format!("{reference}[gains]\np1 = 0.0\n"),
            "scenarios/bad.toml:4: field `gains.p1`: must be > 0",
        ),
        (
            "[reference]\nwaypoints = [{ t = 1.0, q = [0,0,0,0,0,0] }, { t = 0.5, q = [0,0,0,0,0,0] }]\n"
                .to_string(),
            "field `reference.waypoints[2].t`: times must increase",
        ),
        (
            format!("{reference}[initial]\nq = [0.0, 0.0, nan, 0.0, 0.0, 0.0]\n"),
            "scenarios/bad.toml:4: field `initial.q`: entry 3 must be a finite number",
        ),
        (
            format!("control_period = 1e-6\nduration = 1000.0\n{reference}"),
            "field `duration`: 1000 s at a period of 0.000001 s is 1.0e9 ticks",
        ),
    ];
    for (text, expected) in cases {
        let message = scenario_error(text);
        assert!(
            message.contains(expected),
            "for\n{text}\nexpected `{expected}` in\n{message}"
        );
    }
    // No [reference]: the robot file's set point (the paper robot's gives the paper's).
    let model = Model::new(load_robot(None).unwrap()).unwrap();
    let scenario = ScenarioFile::parse("duration = 1.0\n", Path::new("scenarios/x.toml"))
        .and_then(|file| file.resolve(&model))
        .unwrap();
    assert_eq!(
        scenario.reference,
        ReferenceSpec::SetPoint(vec![0.08, 0.0, -0.05, 0.0, -0.06, -0.07])
    );
    assert_eq!(scenario.sources.reference, Source::RobotFile);
    let missing = ScenarioFile::load(Path::new("/nonexistent/scenario.toml")).unwrap_err();
    assert!(
        missing
            .to_string()
            .contains("/nonexistent/scenario.toml: cannot read scenario file")
    );
}

/// Every row of a run carries its tick's status and reason (`record::status`): counted
/// over the rows of a run with one row per tick, they are the summary's counts, reasons
/// included; a row between ticks carries the status of the tick before it.
#[test]
fn each_row_carries_its_ticks_status_and_reason() {
    use softcbf::record::status::{REASON, STATUS, reason_name, status_name};
    let (model, mut scenario) = paper();
    scenario.duration = 3.0;
    let mut seen = std::collections::BTreeSet::new();
    for (safety, period) in [
        (SafetyMode::Certified, 0.002),
        (SafetyMode::Paper, 1.0 / 33.0),
        (SafetyMode::Certified, 1.0 / 33.0),
    ] {
        scenario.controller.safety = safety;
        scenario.control_period = period;
        for (filter, record_period) in [(true, None), (false, None), (true, Some(period / 4.0))] {
            scenario.record_period = record_period;
            let run = simulate(&model, &scenario, filter, &mut |_| {}).expect("simulation starts");
            let columns = run.record.columns();
            let status = columns.index_of(STATUS).expect("a status column");
            let reason = columns.index_of(REASON).expect("a reason column");
            let statuses: Vec<f64> = run.record.column(status).collect();
            let reasons: Vec<f64> = run.record.column(reason).collect();
            let times: Vec<f64> = run.record.times().collect();
            if let Some(r) = record_period {
                // Rows between ticks hold the status of the tick before them.
                let per_tick = (period / r).round() as usize;
                for (k, (s, why)) in statuses.iter().zip(&reasons).enumerate() {
                    let tick = k - k % per_tick;
                    assert_eq!((*s, *why), (statuses[tick], reasons[tick]), "row {k}");
                }
                continue;
            }
            let c = &run.summary.counts;
            assert_eq!(statuses.len(), c.ticks, "{safety:?}");
            let count = |name: &str| {
                statuses
                    .iter()
                    .filter(|&&s| status_name(s) == Some(name))
                    .count()
            };
            let why = |name: &str| {
                reasons
                    .iter()
                    .filter(|&&r| reason_name(r) == Some(name))
                    .count()
            };
            let context = format!("{safety:?} at {period} s, filter {filter}");
            assert_eq!(count("unfiltered"), c.unfiltered, "{context}");
            assert_eq!(count("relaxed"), c.relaxed, "{context}");
            assert_eq!(count("qp-failed"), c.failed, "{context}");
            assert_eq!(count("invalid"), c.invalid_state, "{context}");
            assert_eq!(count("uncertified"), c.uncertified, "{context}");
            let r = &c.uncertified_reasons;
            for (name, n) in [
                ("tube", r.tube),
                ("domain", r.domain),
                ("start", r.start),
                ("bound", r.bound),
                ("budget", r.budget),
            ] {
                assert_eq!(why(name), n, "{context}: {name}");
            }
            assert_eq!(
                count("filtered") + c.relaxed + c.failed + c.uncertified,
                c.qp_solves,
                "{context}"
            );
            assert!(times.windows(2).all(|w| w[0] < w[1]));
            for (&s, &r) in statuses.iter().zip(&reasons) {
                seen.insert((status_name(s), reason_name(r)));
            }
        }
    }
    println!("statuses seen: {seen:?}");
    assert!(seen.len() >= 3, "the runs show too few statuses: {seen:?}");
}
