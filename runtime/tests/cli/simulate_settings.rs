//! `softcbf simulate` settings end to end: one precedence (command line > scenario > robot
//! file > built-in) that the run actually uses, a summary that records every setting with
//! its source, the common flags, and the messages for settings that cannot work together.
//!
//! Runs are short (50–100 ms of robot time) so that each takes a few milliseconds.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_softcbf");

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("softcbf-settings-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn simulate(args: &[&str]) -> Output {
    Command::new(BIN)
        .arg("simulate")
        .args(args)
        .output()
        .expect("the softcbf binary runs")
}

/// Asserts that `output` is of a run that went as asked: safe (0), or with `--no-filter`
/// plain PD+, which nothing keeps safe (3, saying so).
fn assert_ran(output: &Output, args: &[&str]) {
    let stderr = String::from_utf8_lossy(&output.stderr);
    if args.contains(&"--no-filter") {
        assert_eq!(output.status.code(), Some(3), "simulate {args:?}: {stderr}");
        assert!(
            stderr.contains("ticks ran without the safety filter"),
            "simulate {args:?}: {stderr}"
        );
    } else {
        assert!(
            output.status.success(),
            "simulate {args:?} failed: {stderr}"
        );
    }
}

/// Runs `simulate` with `args` into `out` and returns its summary.json.
fn summary(out: &Path, args: &[&str]) -> Value {
    let mut all = vec!["--out", out.to_str().unwrap()];
    all.extend_from_slice(args);
    let output = simulate(&all);
    assert_ran(&output, args);
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// The paper robot with `[barrier] p1 = p2 = p`, written into `dir`.
fn robot_with_p(dir: &Path, p: f64, name: &str) -> PathBuf {
    let text = std::fs::read_to_string(repo("robots/paper-sim.toml")).unwrap();
    let text = text
        .replace("p1 = 10.0", &format!("p1 = {p:?}"))
        .replace("p2 = 10.0", &format!("p2 = {p:?}"))
        .replace("name = \"paper-sim\"", &format!("name = \"{name}\""));
    assert!(text.contains(&format!("p1 = {p:?}")));
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

fn setting<'a>(summary: &'a Value, name: &str) -> (&'a Value, &'a str) {
    let entry = &summary["settings"][name];
    (&entry["value"], entry["source"].as_str().unwrap_or("?"))
}

#[test]
fn the_robot_files_gains_are_used_unless_the_scenario_or_the_command_line_say_otherwise() {
    let dir = temp_dir("precedence");
    let robot = robot_with_p(&dir, 3.0, "soft-three");
    let robot = robot.to_str().unwrap();
    let short = ["--duration", "0.1"];

    // The embedded scenario gives no gains: the robot file's p = 3 wins over the built-in 10.
    let from_robot = summary(&dir.join("a"), &[&["--robot", robot][..], &short].concat());
    assert_eq!(
        setting(&from_robot, "p1"),
        (&Value::from(3.0), "robot_file")
    );
    assert_eq!(
        setting(&from_robot, "p2"),
        (&Value::from(3.0), "robot_file")
    );
    assert_eq!(
        setting(&from_robot, "kp"),
        (&Value::from(5.0), "robot_file")
    );
    assert_eq!(from_robot["robot"], "soft-three");
    assert_eq!(from_robot["settings"]["robot"]["file"], robot);
    // The PD+ comparison runs without the filter because the scenario's `compare` asks.
    let comparison = &from_robot["comparison"];
    assert_eq!(
        setting(comparison, "filter"),
        (&Value::from(false), "scenario")
    );
    assert_eq!(setting(comparison, "p1"), (&Value::from(3.0), "robot_file"));

    // The paper robot with --p 3 on the command line runs the same controller: the same
    // trajectory to the last digit, so the robot file's gains were used, not just recorded.
    let from_option = summary(&dir.join("b"), &[&["--p", "3"][..], &short].concat());
    assert_eq!(
        setting(&from_option, "p1"),
        (&Value::from(3.0), "command_line")
    );
    let csv = |run: &str| std::fs::read_to_string(dir.join(run).join("trajectory.csv")).unwrap();
    assert_eq!(csv("a"), csv("b"));
    // And the paper's p = 10 runs differently.
    let paper = summary(&dir.join("c"), &short);
    assert_eq!(setting(&paper, "p1"), (&Value::from(10.0), "robot_file"));
    assert_ne!(csv("a"), csv("c"));

    // A scenario's [gains] wins over the robot file's; the command line wins over both.
    let scenario = dir.join("scenario.toml");
    std::fs::write(
        &scenario,
        format!(
            "robot = \"{robot}\"\nduration = 0.1\n[reference]\nset_point = [0.08, 0.0, -0.05, \
             0.0, -0.06, -0.07]\n[gains]\np1 = 4.0\nkd = 2.0\n"
        ),
    )
    .unwrap();
    let scenario = scenario.to_str().unwrap();
    let from_scenario = summary(&dir.join("d"), &["--scenario", scenario]);
    assert_eq!(
        setting(&from_scenario, "p1"),
        (&Value::from(4.0), "scenario")
    );
    assert_eq!(
        setting(&from_scenario, "p2"),
        (&Value::from(3.0), "robot_file")
    );
    assert_eq!(
        setting(&from_scenario, "kd"),
        (&Value::from(2.0), "scenario")
    );
    let overridden = summary(
        &dir.join("e"),
        &["--scenario", scenario, "--p1", "7", "--kd", "0.5"],
    );
    assert_eq!(
        setting(&overridden, "p1"),
        (&Value::from(7.0), "command_line")
    );
    assert_eq!(
        setting(&overridden, "p2"),
        (&Value::from(3.0), "robot_file")
    );
    assert_eq!(
        setting(&overridden, "kd"),
        (&Value::from(0.5), "command_line")
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_summary_records_every_setting_and_the_flags_change_them() {
    let dir = temp_dir("flags");
    let out = dir.join("run");
    let output = simulate(&[
        "--out",
        out.to_str().unwrap(),
        "--duration",
        "0.06",
        "--control-period",
        "0.002",
        "--set-point",
        "0.01,0,0,0,0.01,-0.01",
        "--safety",
        "hold-correction",
    ]);
    assert!(output.status.success(), "{output:?}");
    let stdout = String::from_utf8_lossy(&output.stdout);
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let settings = &summary["settings"];
    for key in [
        "software",
        "robot",
        "scenario",
        "filter",
        "kp",
        "kd",
        "p1",
        "p2",
        "safety",
        "control_period",
        "duration",
        "reference",
        "integrator",
    ] {
        assert!(
            !settings[key].is_null(),
            "settings.{key} missing: {settings}"
        );
    }
    assert_eq!(
        settings["software"],
        format!("softcbf {}", env!("CARGO_PKG_VERSION"))
    );
    assert_eq!(
        setting(&summary, "control_period"),
        (&Value::from(0.002), "command_line")
    );
    assert_eq!(
        setting(&summary, "duration"),
        (&Value::from(0.06), "command_line")
    );
    assert_eq!(
        setting(&summary, "safety"),
        (&Value::from("hold-correction"), "command_line")
    );
    assert_eq!(
        setting(&summary, "filter"),
        (&Value::from(true), "scenario")
    );
    assert_eq!(settings["reference"]["source"], "command_line");
    assert_eq!(settings["integrator"]["rtol"], 1e-6);
    assert_eq!(
        summary["set_point"],
        serde_json::json!([0.01, 0.0, 0.0, 0.0, 0.01, -0.01])
    );
    assert_eq!(summary["control_period"], 0.002);
    // 0.06 s at 2 ms: 30 ticks and the final row.
    assert_eq!(summary["counts"]["ticks"], 31);
    // The lines on standard output say what ran: the settings, and the robot's name.
    assert!(stdout.starts_with("settings: softcbf "), "{stdout}");
    assert!(stdout.contains("p1 = 10 (robot file)"), "{stdout}");
    assert!(
        stdout.contains("paper-sim-certified on paper-sim [filter]"),
        "{stdout}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn another_robot_is_named_in_the_one_line_summary() {
    let dir = temp_dir("name");
    // The paper's set point would compress this robot's 0.06 m modules to a negative length
    // (δL₂ = −0.07 m): a set point of its own.
    let output = simulate(&[
        "--robot",
        repo("robots/hardware-example.toml").to_str().unwrap(),
        "--set-point",
        "0,0,-0.02,0,-0.03,-0.01",
        "--duration",
        "0.05",
        "--no-filter",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert_ran(&output, &["--no-filter"]);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        stdout.contains("paper-sim-certified on hardware-example [pd]"),
        "{stdout}"
    );
    assert!(stdout.contains("p1 = 20 (robot file)"), "{stdout}");
    // The embedded scenario asks for a comparison; a plain PD+ run says why there is none.
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("no PD+ comparison"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs `simulate` expecting a refusal (exit status `code`); returns standard error.
fn refused(args: &[&str], code: i32) -> String {
    let output = simulate(args);
    assert_eq!(output.status.code(), Some(code), "{output:?}");
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn settings_that_cannot_work_are_refused_with_the_option_or_field_named() {
    let dir = temp_dir("refused");
    let out = dir.join("out");
    let out = out.to_str().unwrap();
    // clap refuses the pair itself (usage error, status 2).
    let stderr = refused(&["--no-filter", "--compare", "--out", out], 2);
    assert!(
        stderr.contains("--no-filter") && stderr.contains("--compare"),
        "{stderr}"
    );
    let stderr = refused(&["--p", "-1", "--out", out], 1);
    assert!(stderr.contains("--p: must be"), "{stderr}");
    let stderr = refused(&["--p", "5", "--p1", "4", "--out", out], 1);
    assert!(stderr.contains("either --p or --p1/--p2"), "{stderr}");
    let stderr = refused(&["--duration", "0.0005", "--out", out], 1);
    assert!(
        stderr.contains("--duration: 0.0005 s is shorter than the control period"),
        "{stderr}"
    );
    let stderr = refused(&["--control-period", "0", "--out", out], 1);
    assert!(stderr.contains("--control-period: must be"), "{stderr}");
    let stderr = refused(&["--set-point", "0,0,0", "--out", out], 1);
    assert!(stderr.contains("--set-point: 3 values given"), "{stderr}");
    let stderr = refused(&["--safety", "yes", "--out", out], 2);
    assert!(
        stderr.contains("`yes` is not a safety mode; give one of \"certified\""),
        "{stderr}"
    );

    // A scenario without the filter cannot be compared with plain PD+.
    let plain = dir.join("plain.toml");
    std::fs::write(
        &plain,
        "filter = false\nduration = 0.05\n[reference]\nset_point = [0, 0, 0, 0, 0, 0]\n",
    )
    .unwrap();
    let stderr = refused(
        &[
            "--scenario",
            plain.to_str().unwrap(),
            "--compare",
            "--out",
            out,
        ],
        1,
    );
    assert!(
        stderr.contains("--compare: the scenario runs without the safety filter"),
        "{stderr}"
    );

    // A scenario's robot that cannot be read: the scenario file, its line, the resolved path.
    let nope = dir.join("nope-robot.toml");
    std::fs::write(
        &nope,
        "duration = 0.05\nrobot = \"nope.toml\"\n[reference]\nset_point = [0, 0, 0, 0, 0, 0]\n",
    )
    .unwrap();
    let stderr = refused(&["--scenario", nope.to_str().unwrap(), "--out", out], 1);
    let resolved = dir.join("nope.toml");
    assert!(
        stderr.contains(&format!(
            "{}:2: field `robot`: cannot read the robot file {}",
            nope.display(),
            resolved.display()
        )),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--record-period` records rows between ticks and says so: in summary.json, on the
/// `settings:` line and in the one-line summary; `--plant` integrates another robot of the
/// same structure, recorded with its file.
#[test]
fn record_period_and_plant_from_the_command_line() {
    let dir = temp_dir("dense");
    let out = dir.join("dense");
    let output = simulate(&[
        "--out",
        out.to_str().unwrap(),
        "--duration",
        "0.05",
        "--control-period",
        "0.002",
        "--record-period",
        "0.0005",
        "--no-filter",
    ]);
    assert_ran(&output, &["--no-filter"]);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        stdout.contains("; recorded every 500 µs (command line);"),
        "{stdout}"
    );
    assert!(
        stdout.contains("lowest barrier (dense, every 500 µs) "),
        "{stdout}"
    );
    let dense: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(dense["dense"], true);
    assert_eq!(dense["record_period"], 0.0005);
    assert_eq!(
        setting(&dense, "record_period"),
        (&Value::from(0.0005), "command_line")
    );
    assert_eq!(dense["settings"]["plant"], Value::Null);
    // 25 ticks of 2 ms, 3 rows between each two, the final tick: 101 rows and the header.
    let csv = std::fs::read_to_string(out.join("trajectory.csv")).unwrap();
    assert_eq!(csv.lines().count(), 102);
    assert_eq!(dense["counts"]["ticks"], 26);

    // A plant robot whose axial stiffness is half the controller's.
    let text = std::fs::read_to_string(repo("robots/paper-sim.toml")).unwrap();
    let soft = text.replace("axial_stiffness = 10.0", "axial_stiffness = 5.0");
    assert_ne!(soft, text);
    let plant = dir.join("soft-plant.toml");
    std::fs::write(&plant, soft).unwrap();
    let run = |out: &Path, plant: Option<&Path>| {
        let mut args = vec!["--duration", "0.05", "--no-filter"];
        if let Some(plant) = plant {
            args.extend(["--plant", plant.to_str().unwrap()]);
        }
        summary(out, &args)
    };
    let with_plant = run(&dir.join("plant"), Some(&plant));
    let without = run(&dir.join("model"), None);
    let plant_setting = &with_plant["settings"]["plant"];
    assert_eq!(plant_setting["source"], "command_line");
    assert_eq!(plant_setting["value"]["file"], plant.to_str().unwrap());
    assert_eq!(without["settings"]["plant"], Value::Null);
    let trajectory =
        |run: &str| std::fs::read_to_string(dir.join(run).join("trajectory.csv")).unwrap();
    assert_ne!(trajectory("plant"), trajectory("model"));

    // Refusals name the option.
    let out = dir.join("refused");
    let out = out.to_str().unwrap();
    let stderr = refused(&["--record-period", "0", "--out", out], 1);
    assert!(
        stderr.contains("--record-period: must be ≥ 1e-6"),
        "{stderr}"
    );
    let stderr = refused(&["--record-period", "0.002", "--out", out], 1);
    assert!(
        stderr.contains("--record-period: 0.002 s is longer than the control period (0.001 s)"),
        "{stderr}"
    );
    let three = repo("robots/three-square.toml");
    let stderr = refused(&["--plant", three.to_str().unwrap(), "--out", out], 1);
    assert!(
        stderr.contains("error: --plant: the plant robot ")
            && stderr.contains("it has 3 modules, the controller's robot 2"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A value in the scenario file is checked also when an option replaces it: the file may
/// be run without the option another time, and a bad value should not wait for it.
#[test]
fn file_values_are_checked_when_the_command_line_replaces_them() {
    let dir = temp_dir("overridden");
    let out = dir.join("out");
    let out = out.to_str().unwrap();
    let paper = repo("robots/paper-sim.toml");
    let paper = paper.to_str().unwrap();
    for (text, option, field) in [
        (
            "duration = 0.05\n[reference]\nset_point = [0, 0, 0]\n",
            vec!["--set-point", "0,0,0,0,0,0"],
            "3: field `reference.set_point`",
        ),
        (
            "duration = 0.05\nrobot = \"nope.toml\"\n[reference]\nset_point = [0, 0, 0, 0, 0, 0]\n",
            vec!["--robot", paper],
            "2: field `robot`",
        ),
        (
            "duration = 0.05\nplant = \"nope.toml\"\n[reference]\nset_point = [0, 0, 0, 0, 0, 0]\n",
            vec!["--plant", paper],
            "2: field `plant`",
        ),
        (
            "duration = -1.0\n[reference]\nset_point = [0, 0, 0, 0, 0, 0]\n",
            vec!["--duration", "0.05"],
            "1: field `duration`",
        ),
    ] {
        let file = dir.join("scenario.toml");
        std::fs::write(&file, text).unwrap();
        let mut args = vec!["--scenario", file.to_str().unwrap(), "--out", out];
        args.extend(option.iter().copied());
        let stderr = refused(&args, 1);
        assert!(
            stderr.contains(&format!("{}:{field}", file.display())),
            "{option:?}: {stderr}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The embedded scenario fits a robot of any structure: it starts the robot at rest and
/// takes the set point from the command line, else from the robot file's `set_point`; with
/// neither, the message says what is missing and every way to give it.
#[test]
fn a_robot_of_any_structure_runs_without_a_scenario_file() {
    let dir = temp_dir("any-structure");
    // Three modules with square plates: 9 coordinates, a set point in its robot file.
    let three = repo("robots/three-square.toml");
    let run = summary(
        &dir.join("three"),
        &["--robot", three.to_str().unwrap(), "--duration", "0.05"],
    );
    assert_eq!(run["robot"], "three-square");
    assert_eq!(
        setting(&run, "reference").1,
        "robot_file",
        "{}",
        run["settings"]
    );
    assert_eq!(
        run["set_point"],
        serde_json::json!([0.08, 0.0, -0.03, 0.0, 0.07, -0.02, -0.07, 0.0, -0.03])
    );
    let rows = std::fs::read_to_string(dir.join("three/trajectory.csv")).unwrap();
    let first: Vec<f64> = rows
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    // t, then q (9) and q̇ (9): at rest, straight.
    assert_eq!(first[..19], [0.0; 19]);

    // Four paper modules and no set point anywhere: refused, naming the ways to give one.
    let four = dir.join("four modules.toml");
    std::fs::write(&four, "name = \"four\"\nmodules = 4\n").unwrap();
    let four = four.to_str().unwrap();
    let message = refused(
        &["--robot", four, "--out", dir.join("x").to_str().unwrap()],
        1,
    );
    for fragment in [
        "no set point for the robot four",
        "four modules.toml",
        "`--set-point Δx1,Δy1,δL1, …, δL4` (12 numbers [m], 3 per module",
        "`set_point = [...]` with 12 numbers in the robot file (robots/README.md)",
        "[reference] table",
    ] {
        assert!(
            message.contains(fragment),
            "`{fragment}` missing from: {message}"
        );
    }
    assert!(!message.contains("initial.q"), "{message}");
    // The command line gives it.
    let set_point = "0.02,0,-0.01,0,0.02,-0.01,-0.02,0,-0.01,0,-0.02,-0.01";
    let run = summary(
        &dir.join("four"),
        &[
            "--robot",
            four,
            "--set-point",
            set_point,
            "--duration",
            "0.05",
        ],
    );
    assert_eq!(setting(&run, "reference").1, "command_line");
    assert_eq!(run["set_point"].as_array().unwrap().len(), 12);
    // And so does the robot file; a wrong length there is an error at its line.
    let with_point = dir.join("four-with-point.toml");
    std::fs::write(
        &with_point,
        format!("modules = 4\nset_point = [{set_point}]\n"),
    )
    .unwrap();
    let run = summary(
        &dir.join("four-file"),
        &[
            "--robot",
            with_point.to_str().unwrap(),
            "--duration",
            "0.05",
        ],
    );
    assert_eq!(setting(&run, "reference").1, "robot_file");
    std::fs::write(&with_point, "modules = 4\nset_point = [0, 0, 0]\n").unwrap();
    let message = refused(&["--robot", with_point.to_str().unwrap()], 1);
    assert!(
        message.contains(
            "four-with-point.toml:2: field `set_point`: has 3 entries, the robot has 12 coordinates"
        ),
        "{message}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A certified run says why the ticks it could not prove were not: the summary line and
/// `summary.json` count them per reason, and the reasons add up to the ticks not proven
/// (the ±20 % robot's first 4 s: 29 of 133 ticks, about 0.4 s here).
#[test]
fn unproven_ticks_are_counted_per_reason() {
    let out = temp_dir("reasons");
    let robot = repo("robots/paper-sim-uncertain.toml");
    let args = [
        "--robot",
        robot.to_str().unwrap(),
        "--control-period",
        "0.0303",
        "--duration",
        "4",
        "--out",
        out.to_str().unwrap(),
    ];
    let output = simulate(&args);
    let stdout = String::from_utf8_lossy(&output.stdout);
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let counts = &summary["counts"];
    let unproven = counts["uncertified"].as_u64().unwrap();
    assert!(
        unproven > 0,
        "the ±20 % box leaves ticks unproven: {counts}"
    );
    let reasons = counts["uncertified_reasons"].as_object().unwrap();
    let names: Vec<&str> = reasons.keys().map(|k| k.as_str()).collect();
    assert_eq!(names, ["bound", "budget", "domain", "start", "tube"]);
    let total: u64 = reasons.values().map(|v| v.as_u64().unwrap()).sum();
    assert_eq!(total, unproven, "{counts}");
    // A simulation has no compute budget: its results do not depend on the machine.
    assert_eq!(reasons["budget"], 0);
    let (top, count) = reasons
        .iter()
        .max_by_key(|(_, v)| v.as_u64().unwrap())
        .unwrap();
    assert!(
        stdout.contains(&format!(
            "ticks not proven over their hold (the prediction's rows alone; {top} {count}"
        )),
        "{stdout}"
    );
    // The verdict is what was measured (exit 0), and says the proof left those ticks out.
    assert_eq!(output.status.code(), Some(0), "{stdout}");
    let verdict = format!(
        "verdict: safe (measured: {unproven} of {} ticks were not proven over their hold, and \
         the guarantee does not cover those; docs/model.md §5)",
        counts["ticks"]
    );
    assert!(stdout.contains(&verdict), "{stdout}");
    let _ = std::fs::remove_dir_all(&out);
}
