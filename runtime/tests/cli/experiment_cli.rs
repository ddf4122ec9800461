//! End-to-end tests of `softcbf run --experiment` against the emulator: a static run logs
//! rest rows and says so in `summary.json`, a dynamic run keeps its tensions in their
//! limits, experiments on robots far from their file (tests/data/plants/) grow their
//! levels only as far as the barriers allow and stop before them, and bad options are
//! refused before the port is opened.

use std::path::Path;
use std::process::Command;
use std::sync::Mutex;
use std::time::Duration;

use crate::common::{
    BIN, Emulator, LOAD_FAULTS, finish_run, finish_run_within, robot, start_run, temp_dir,
};

/// One emulator run at a time: their timing is part of what they check.
static SERIAL: Mutex<()> = Mutex::new(());

/// A CSV log: its header and its rows (NaN where empty or not a number).
fn read_log(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| {
            l.split(',')
                .map(|v| v.trim().parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    (header, rows)
}

fn column(header: &[String], name: &str) -> usize {
    header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column `{name}` in {header:?}"))
}

fn summary(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("summary.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// Every one of the six servos confirmed its torque off at the end (the safe stop).
fn assert_torque_off(s: &serde_json::Value) {
    let servos = s["torque_off"].as_array().expect("torque_off");
    assert_eq!(servos.len(), 6, "{servos:?}");
    assert!(
        servos.iter().all(|servo| servo["confirmed"] == true),
        "{servos:?}"
    );
}

const TENSIONS: [&str; 6] = [
    "f module 1 tendon 1 [N]",
    "f module 1 tendon 2 [N]",
    "f module 1 tendon 3 [N]",
    "f module 2 tendon 1 [N]",
    "f module 2 tendon 2 [N]",
    "f module 2 tendon 3 [N]",
];
const COORDINATES: [&str; 6] = [
    "dx1 [m]", "dy1 [m]", "dL1 [m]", "dx2 [m]", "dy2 [m]", "dL2 [m]",
];

/// Whether the run could not keep its 33 Hz on this machine (loaded by other work), as
/// it measured itself: the rate refused before torque on, a stop on one of the
/// [`LOAD_FAULTS`], or more than one deadline in twenty missed. The experiments' rest states and tensions depend on
/// the loop's period, so the test then says it skipped rather than judge them.
fn skipped_for_load(code: i32, stdout: &str, stderr: &str, out: &Path) -> bool {
    let refused = code == 1 && stderr.contains("the bus cannot hold it");
    let slow = code == 4 && LOAD_FAULTS.iter().any(|w| stdout.contains(w));
    let summary = std::fs::read_to_string(out.join("summary.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok());
    let missed = summary
        .as_ref()
        .and_then(|s| Some((s["deadline_overruns"].as_u64()?, s["ticks"].as_u64()?)))
        .filter(|(missed, ticks)| missed * 20 > *ticks);
    // The guard stopping an experiment after a command stayed in force past its hold (a
    // tick the machine's load delayed moved the robot further than the filter planned):
    // the stop is right, and the experiment's own question cannot be asked (seen beside a
    // second 2-core job: computing a command took 10 ms, one command overran by 10 ms).
    let late_guard = code == 1
        && stdout.contains("experiment stopped by its guard")
        && summary
            .as_ref()
            .and_then(|s| s["hold_overruns"].as_u64())
            .is_some_and(|late| late > 0);
    if refused || slow || missed.is_some() || late_guard {
        println!(
            "skipped: this machine (under its load) did not keep 33 Hz (deadlines missed: \
             {missed:?}):\n{stdout}\n{stderr}"
        );
        return true;
    }
    false
}

/// Whether an exit 3 is the load's doing and nothing else: the run's only fault is relaxed
/// ticks (every barrier kept above the threshold), and at least one command was in force
/// longer than the hold it was computed for (the machine's load delayed the next one). The
/// filter predicts over one hold; a longer one moves the state past what it proved, and
/// the next rows may have no common point. The verdict then says so and exits 3, which is
/// right. The test goes on to check everything else the run promises.
fn relaxed_by_load(code: i32, stdout: &str, out: &Path) -> bool {
    if code != 3 || !stdout.contains("ticks relaxed barrier rows") {
        return false;
    }
    let Some(s) = std::fs::read_to_string(out.join("summary.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
    else {
        return false;
    };
    let late = s["hold_overruns"].as_u64().unwrap_or(0) > 0;
    let kept = s["min_barrier"]["value"].as_f64().is_some_and(|b| b > 0.0);
    if late && kept {
        println!("loaded machine: a command overran its hold and a later tick relaxed:\n{stdout}");
    }
    late && kept
}

#[test]
fn a_static_run_logs_its_rest_states_and_reports_them() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let emulator = Emulator::start(&[]);
    let out = temp_dir("experiment-static");
    // Three or four of the sixteen sets (each at least 2 s), cut by --duration.
    let run = start_run(
        &emulator.port,
        &out,
        &["--experiment", "static", "--duration", "7", "--quiet"],
    );
    let (code, stdout, stderr) = finish_run(run, "static experiment");
    if skipped_for_load(code, &stdout, &stderr, &out) {
        return;
    }
    if !relaxed_by_load(code, &stdout, &out) {
        assert_eq!(code, 0, "{stdout}\n{stderr}");
    }
    assert!(
        stdout.contains("experiment: step 1 of 25: at rest"),
        "{stdout}"
    );
    assert!(
        stdout.contains("stopped: experiment ended by --duration with"),
        "{stdout}"
    );
    assert!(
        stdout.contains("next: softcbf identify --robot"),
        "{stdout}"
    );

    let s = summary(&out);
    assert_torque_off(&s);
    let e = &s["experiment"];
    assert_eq!(e["kind"], "static");
    // The base, four rounds of single tendons (levels 1/8 to 1, the example's own robot
    // leaving room), the twelve other sets.
    assert_eq!(e["steps"], 25);
    let start = e["start_scale"].as_f64().unwrap();
    assert_eq!(start, 0.125);
    assert_eq!(e["complete"], false);
    assert_eq!(s["set_point"], serde_json::Value::Null);
    let at_rest = e["steps_at_rest"].as_u64().unwrap();
    assert!(at_rest >= 2, "{e}");
    let threshold = e["rest_threshold"].as_f64().unwrap();
    let base: Vec<f64> = serde_json::from_value(e["base_tension"].clone()).unwrap();
    let amplitude: Vec<f64> = serde_json::from_value(e["amplitude"].clone()).unwrap();

    let (header, rows) = read_log(&out.join("trajectory.csv"));
    let (step, rest) = (column(&header, "step"), column(&header, "rest"));
    let rest_rows: Vec<&Vec<f64>> = rows.iter().filter(|r| r[rest] == 1.0).collect();
    assert_eq!(rest_rows.len() as u64, e["rest_rows"].as_u64().unwrap());
    assert!(rows.iter().all(|r| r[step].is_finite()));
    for k in 0..at_rest as usize {
        let rows: Vec<&&Vec<f64>> = rest_rows.iter().filter(|r| r[step] == k as f64).collect();
        // A second of rest rows: at 33 Hz about 33 (at most 36); a loaded machine's loop
        // may tick less often in that second, never more.
        assert!((2..=36).contains(&rows.len()), "step {k}: {}", rows.len());
        let t = column(&header, "t [s]");
        let span = rows[rows.len() - 1][t] - rows[0][t];
        assert!(
            (0.5..=1.1).contains(&span),
            "step {k}: rest rows over {span} s"
        );
        // At rest: every coordinate within the threshold over the rest rows (the quiet
        // window before them was, and nothing moves the robot while the set is held).
        for name in COORDINATES {
            let c = column(&header, name);
            let values = rows.iter().map(|r| r[c]);
            let span = values.clone().fold(f64::MIN, f64::max) - values.fold(f64::MAX, f64::min);
            assert!(span < threshold, "step {k}, {name}: {span} m");
        }
        // The set held: step 0 the base on every tendon; step 1 the first level of the
        // amplitude added to each module's first tendon (the robot's own physics, in the
        // file's limits: the filter has no reason to change them at rest).
        for (j, name) in TENSIONS.iter().enumerate().filter(|_| k <= 1) {
            let c = column(&header, name);
            let expected = base[j / 3]
                + if k == 1 && j % 3 == 0 {
                    start * amplitude[j / 3]
                } else {
                    0.0
                };
            for r in &rows {
                assert!(
                    (r[c] - expected).abs() < 1e-9,
                    "step {k}, {name}: {} N",
                    r[c]
                );
            }
        }
    }
}

#[test]
fn a_dynamic_run_keeps_its_tensions_in_their_limits_and_ends_by_itself() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let emulator = Emulator::start(&[]);
    let out = temp_dir("experiment-dynamic");
    let run = start_run(
        &emulator.port,
        &out,
        &["--experiment", "dynamic", "--duration", "4.5", "--quiet"],
    );
    let (code, stdout, stderr) = finish_run(run, "dynamic experiment");
    if skipped_for_load(code, &stdout, &stderr, &out) {
        return;
    }
    if !relaxed_by_load(code, &stdout, &out) {
        assert_eq!(code, 0, "{stdout}\n{stderr}");
    }
    assert!(stdout.contains("stopped: experiment complete"), "{stdout}");
    assert!(
        stdout.contains("experiment: operating point 3 of 3 done"),
        "{stdout}"
    );
    let s = summary(&out);
    assert_torque_off(&s);
    let e = &s["experiment"];
    assert_eq!(e["kind"], "dynamic");
    assert_eq!(e["complete"], true);
    assert_eq!(e["steps_run"], 3);
    assert_eq!(e["duration"], 4.5);
    // Its length after a second's hold at f_min (the reference state of its levels).
    let elapsed = s["elapsed"].as_f64().unwrap();
    assert!((5.4..6.0).contains(&elapsed), "{elapsed} s");

    // The hardware example's tension limits, [0.2, 40] N on every tendon.
    let (header, rows) = read_log(&out.join("trajectory.csv"));
    let (step, rest) = (column(&header, "step"), column(&header, "rest"));
    let fresh = column(&header, "fresh");
    let mut steps = Vec::new();
    for r in &rows {
        assert_eq!(r[rest], 0.0);
        if r[fresh] != 1.0 {
            // A tick without a reading (a loaded machine) sent nothing: no tensions.
            continue;
        }
        if steps.last() != Some(&r[step]) {
            steps.push(r[step]);
        }
        for name in TENSIONS {
            let f = r[column(&header, name)];
            assert!((0.2 - 1e-9..=40.0).contains(&f), "{name}: {f} N");
        }
    }
    assert_eq!(steps, [0.0, 1.0, 2.0]);
    // The tensions move: a multisine, not a constant.
    let c = column(&header, TENSIONS[4]);
    let values = rows.iter().map(|r| r[c]);
    let span = values.clone().fold(f64::MIN, f64::max) - values.fold(f64::MAX, f64::min);
    assert!(span > 0.1, "{span} N");
}

/// A true plant of tests/data/plants/.
fn plant(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(format!("../tests/data/plants/{name}.toml"))
        .display()
        .to_string()
}

/// The barrier values of the log's fresh rows (one vector per row).
fn barriers(header: &[String], rows: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let fresh = column(header, "fresh");
    let columns: Vec<usize> = (0..header.len())
        .filter(|&c| header[c].starts_with("b "))
        .collect();
    assert!(!columns.is_empty(), "{header:?}");
    rows.iter()
        .filter(|r| r[fresh] == 1.0)
        .map(|r| columns.iter().map(|&c| r[c]).collect())
        .collect()
}

/// A robot whose masses are 50 % above its file's (module 1 then hangs 4 mm above its
/// elongation barrier at f_min, not 11 mm): the static experiment starts at the level its
/// ±50 % allows, grows it only while the barriers keep their 3 mm, and no barrier at a
/// state read goes below it. Before the levels, the sets went on at the full amplitude
/// whatever the barriers did (and `summary.json` had no `levels`).
#[test]
fn on_a_heavy_robot_the_levels_stop_growing_where_the_barriers_would_come_too_near() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let emulator = Emulator::start(&["--plant", &plant("heavy")]);
    let out = temp_dir("experiment-heavy");
    let run = start_run(
        &emulator.port,
        &out,
        &["--experiment", "static", "--duration", "25", "--quiet"],
    );
    let (code, stdout, stderr) = finish_run_within(run, Duration::from_secs(90), "heavy");
    if skipped_for_load(code, &stdout, &stderr, &out) {
        return;
    }
    assert_eq!(code, 0, "{stdout}\n{stderr}");
    let s = summary(&out);
    assert_torque_off(&s);
    let e = &s["experiment"];
    assert_eq!(e["stopped_by_guard"], false, "{e}");
    assert_eq!(e["uncertainty"], 0.5);
    let levels = e["levels"].as_array().expect("levels");
    assert!(levels.len() >= 2, "{e}");
    let scale = |l: &serde_json::Value| l["scale"].as_f64().unwrap();
    // From 1/8, doubling while the prediction allows, and not to the full level here.
    assert_eq!(scale(&levels[0]), 0.125);
    assert!(
        levels
            .windows(2)
            .all(|w| scale(&w[1]) <= 2.0 * scale(&w[0]) + 1e-12),
        "{e}"
    );
    let last = &levels[levels.len() - 1];
    assert!(last["next"].as_f64().unwrap() < 1.0, "{e}");
    assert!(last["predicted"].as_f64().unwrap() >= 3e-3 - 1e-9, "{e}");
    // Every barrier at every state read, brute force over the log: above zero (and in
    // fact above the stop distance, or the guard would have stopped the run).
    let (header, rows) = read_log(&out.join("trajectory.csv"));
    let lowest = barriers(&header, &rows)
        .iter()
        .flatten()
        .copied()
        .fold(f64::INFINITY, f64::min);
    assert!(lowest >= 1e-3, "{lowest} m");
    assert!(e["steps_at_rest"].as_u64().unwrap() >= 5, "{e}");
}

/// A robot 50 % softer than its file with 50 % stronger actuators: module 1 hangs 1.4 mm
/// past its elongation barrier before the experiment begins (its weight on half the
/// stiffness). The guard stops the experiment at its first readings, the cables back to
/// f_min and then slack, and says why; no barrier goes further than where the robot
/// started. Before the guard, the static experiment drove the same robot 99 mm past its
/// limits (exit 3).
#[test]
fn on_a_robot_past_its_barriers_the_guard_stops_the_experiment_at_once() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let emulator = Emulator::start(&["--plant", &plant("soft-strong")]);
    let out = temp_dir("experiment-soft-strong");
    let run = start_run(
        &emulator.port,
        &out,
        &["--experiment", "static", "--duration", "20", "--quiet"],
    );
    let (code, stdout, stderr) = finish_run_within(run, Duration::from_secs(60), "soft-strong");
    if skipped_for_load(code, &stdout, &stderr, &out) {
        return;
    }
    // Below the verdict's threshold (−1 mm) from the start: unsafe, and not all done.
    assert_eq!(code, 3, "{stdout}\n{stderr}");
    assert!(
        stdout.contains("stopped: experiment stopped by its guard"),
        "{stdout}"
    );
    assert!(stdout.contains("module 1 elongation min at"), "{stdout}");
    assert!(!stdout.contains("next: "), "{stdout}");
    let s = summary(&out);
    assert_torque_off(&s);
    assert_eq!(s["experiment"]["stopped_by_guard"], true);
    assert_eq!(s["experiment"]["complete"], false);
    let (header, rows) = read_log(&out.join("trajectory.csv"));
    let seen = barriers(&header, &rows);
    assert!(seen.len() <= 5, "{} fresh rows", seen.len());
    let first = seen[0].iter().copied().fold(f64::INFINITY, f64::min);
    let lowest = seen.iter().flatten().copied().fold(f64::INFINITY, f64::min);
    assert!(first < 0.0, "{first}");
    assert!(lowest >= first - 1e-3, "{lowest} m from {first} m");
}

/// `softcbf run` with `options` on the hardware example, with a port that is never
/// opened: its exit code and standard error.
fn refused(options: &[&str]) -> (i32, String) {
    let output = Command::new(BIN)
        .arg("run")
        .arg("--robot")
        .arg(robot())
        .args(["--port", "/dev/null", "--out"])
        .arg(temp_dir("experiment-refused").join("out"))
        .args(options)
        .output()
        .unwrap();
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stderr).to_string(),
    )
}

#[test]
fn bad_experiment_options_are_refused_naming_the_option() {
    for (options, code, message) in [
        (
            &["--experiment", "wobble"][..],
            2,
            "`wobble` is not an experiment",
        ),
        (
            &["--amplitude", "1"],
            1,
            "--amplitude: an option of --experiment",
        ),
        (
            &[
                "--experiment",
                "static",
                "--set-point",
                "0,0,-0.02,0,0,-0.01",
            ],
            1,
            "--set-point: not with --experiment",
        ),
        (
            &["--experiment", "static", "--no-filter"],
            1,
            "--no-filter: not with --experiment",
        ),
        (
            &["--experiment", "static", "--amplitude", "100"],
            1,
            "--amplitude: module 1's tensions would span",
        ),
        (
            &["--experiment", "static", "--amplitude", "0.5,0.5,0.5"],
            1,
            "--amplitude: give one value or one per module (2), got 3",
        ),
        (
            &["--experiment", "static", "--amplitude", "nan"],
            1,
            "--amplitude: must be a finite number",
        ),
        (
            &["--experiment", "static", "--step-time", "-1"],
            1,
            "--step-time: must be > 0",
        ),
        (
            &["--experiment", "static", "--step-time", "0.5"],
            1,
            "--step-time: 0.5 s leaves no time",
        ),
        (
            &["--experiment", "dynamic", "--rest-threshold", "1e-3"],
            1,
            "--rest-threshold: an option of --experiment static",
        ),
        (
            &["--experiment", "dynamic", "--duration", "2"],
            1,
            "--duration: 2 s gives each of the 3 operating points",
        ),
        (
            &["--experiment", "dynamic", "--base-tension", "0.1"],
            1,
            "--base-tension: module 1's tensions would span",
        ),
        (
            &["--stop-distance", "1e-3"],
            1,
            "--stop-distance: an option of --experiment",
        ),
        (
            &["--experiment", "static", "--experiment-uncertainty", "1.5"],
            1,
            "--experiment-uncertainty: must be",
        ),
        (
            &["--experiment", "dynamic", "--stop-distance", "nan"],
            1,
            "--stop-distance: must be a finite number",
        ),
        (
            &["--experiment", "static", "--growth-distance", "5e-4"],
            1,
            "--growth-distance: 0.0005 must be at least the stop distance 0.001",
        ),
    ] {
        let (got, stderr) = refused(options);
        assert_eq!(got, code, "{options:?}: {stderr}");
        assert!(stderr.contains(message), "{options:?}: {stderr}");
    }
}
