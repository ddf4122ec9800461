//! `softcbf run` measures its bus before torque on, against `softcbf emulate` over a
//! pseudo-terminal: it reports the round trip of one read-and-write cycle, refuses a rate
//! the bus cannot hold (exit status 1, torque never on), runs at what the bus allows with
//! `--rate auto`, and records its deadlines in the summary and the log.
//!
//! The emulator steps its plant in real time: run optimized (`cargo test --release`).

use std::path::Path;
use std::process::Command;
use std::sync::Mutex;

use crate::common::*;

/// One emulator and its runs at a time: the bus check measures the machine's timing.
static SERIAL: Mutex<()> = Mutex::new(());

/// `--rate auto` runs at this fraction of the rate the bus allows (the documented margin).
const AUTO_MARGIN: f64 = 0.8;

/// Runs `softcbf run` against `port` to its end (at most 60 s), quietly toward a set point
/// inside the safe set: exit code, stdout, stderr.
fn run(port: &str, out: &Path, extra: &[&str]) -> (i32, String, String) {
    let mut options = vec!["--quiet", "--set-point", INSIDE];
    options.extend_from_slice(extra);
    finish_run(
        start_run(port, out, &options),
        &format!("softcbf run {extra:?}"),
    )
}

/// The number after `prefix` in the first line of `text` that has it.
fn number_after(text: &str, prefix: &str) -> f64 {
    text.lines()
        .find_map(|l| l.split_once(prefix).map(|(_, rest)| rest))
        .and_then(|rest| rest.split([' ', ',']).next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no number after `{prefix}` in:\n{text}"))
}

fn assert_torque_never_on(emulator: &Emulator, what: &str) {
    for id in 1..=6 {
        assert_eq!(
            read_register(&emulator.port, id, TORQUE_ENABLE, 1)[0],
            0,
            "{what}: servo {id} has torque on"
        );
    }
}

#[test]
fn a_rate_the_bus_cannot_hold_is_refused_before_torque_on() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let root = temp_dir("refused");

    // Six servos at 1 Mbit/s: about 1.9 ms of wire per cycle, so 5000 Hz cannot be held.
    let emulator = Emulator::start(&[]);
    let out = root.join("fast");
    let (code, stdout, stderr) = run(&emulator.port, &out, &["--rate", "5000", "--duration", "1"]);
    println!("--rate 5000:\n{stdout}\n{stderr}");
    assert_eq!(code, 1, "{stdout}\n{stderr}");
    assert!(
        stdout.contains("bus: one read+write cycle takes "),
        "{stdout}"
    );
    // A pseudo-terminal is not a USB serial adapter.
    assert!(
        stdout.contains("bus: no latency timer (not a USB serial adapter)"),
        "{stdout}"
    );
    assert!(
        stderr.contains("--rate 5000 Hz: the bus cannot hold it"),
        "{stderr}"
    );
    assert!(stderr.contains("--rate auto to run at"), "{stderr}");
    let limit = number_after(&stdout, "→ at most ");
    assert!(limit < 5000.0, "the bus allows {limit} Hz");
    assert!(
        !out.join("summary.json").exists(),
        "a refused run has no summary"
    );
    assert_torque_never_on(&emulator, "--rate 5000");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn on_a_slow_bus_33_hz_is_refused_and_rate_auto_runs_slower() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    // Every reply 6 ms late (within the 10 ms reply timeout): a read of six servos takes at
    // least 36 ms, so the paper's 33 Hz (30.3 ms) cannot be held. A slow loop also leaves a
    // loaded machine's stalls far below a period.
    let emulator = Emulator::start(&["--delay-ms", "6"]);
    let root = temp_dir("slow");
    let (code, stdout, stderr) = run(&emulator.port, &root.join("33"), &["--duration", "1"]);
    println!("--delay-ms 6:\n{stdout}\n{stderr}");
    assert_eq!(code, 1, "{stdout}\n{stderr}");
    assert!(
        stderr.contains("--rate 33 Hz: the bus cannot hold it"),
        "{stderr}"
    );
    let median_ms = number_after(&stdout, "cycle takes ");
    assert!(
        median_ms >= 36.0,
        "a cycle of {median_ms} ms with 6 × 6 ms late replies"
    );
    assert!(
        !root.join("33/summary.json").exists(),
        "a refused run has no summary"
    );
    assert_torque_never_on(&emulator, "--delay-ms 6");

    let out = root.join("auto");
    let (code, stdout, stderr) = run(&emulator.port, &out, &["--rate", "auto", "--duration", "2"]);
    println!("--delay-ms 6, --rate auto:\n{stdout}\n{stderr}");
    if !status_is(code, 0, &format!("{stdout}\n{stderr}"), "--rate auto") {
        return;
    }
    assert!(stdout.contains("chosen by --rate auto"), "{stdout}");
    let chosen = number_after(&stdout, "loop: ");
    assert!(
        (1.0..1000.0 / 36.0).contains(&chosen),
        "--rate auto chose {chosen} Hz"
    );
    assert!(stdout.contains("deadlines: "), "{stdout}");

    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let number = |key: &str| {
        summary[key]
            .as_f64()
            .unwrap_or_else(|| panic!("summary.json: no number `{key}`:\n{summary:#}"))
    };
    // The rate run at is the whole number of Hz below the margin of the bus's own rate.
    let limit = summary["bus_check"]["rate_limit"].as_f64().unwrap();
    let p90 = summary["bus_check"]["p90"].as_f64().unwrap();
    // The computation of a command counts too (a sampled tick: tenths of a millisecond
    // to a few), not the bus alone.
    let compute = summary["bus_check"]["compute"].as_f64().unwrap();
    assert!(compute > 0.0 && compute < 1.0, "compute {compute} s");
    assert!(
        (limit * (p90 + compute) - 1.0).abs() < 1e-9,
        "rate_limit = 1 / (p90 + compute)"
    );
    assert!(stdout.contains("; computing a command "), "{stdout}");
    let median = summary["bus_check"]["median"].as_f64().unwrap();
    let max = summary["bus_check"]["max"].as_f64().unwrap();
    assert!(0.0 < median && median <= p90 && p90 <= max, "{summary:#}");
    assert_eq!(number("loop_rate"), (AUTO_MARGIN * limit).floor());
    assert_eq!(summary["rate_from_bus"], true);
    assert_eq!(number("loop_rate"), number_after(&stdout, "loop: "));
    let period = 1.0 / number("loop_rate");
    let control_period = summary["settings"]["control_period"]["value"]
        .as_f64()
        .unwrap();
    assert!((control_period - period).abs() < 1e-12, "{summary:#}");
    // Deadlines: counts of ticks and commands, and the longest time a command was in force.
    let ticks = number("ticks");
    assert!(number("deadline_overruns") <= ticks);
    assert!(number("hold_overruns") <= ticks);
    assert!(number("longest_period") > 0.0);
    let excess = number("longest_hold_excess");
    assert_eq!(excess > 0.0, number("hold_overruns") > 0.0, "{summary:#}");
    assert_eq!(summary["latency_timer_ms"], serde_json::Value::Null);

    // The log has the hold excess per tick; the summary's count is the log's.
    let text = std::fs::read_to_string(out.join("trajectory.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (excess_column, overrun_column) = (column("hold_excess [us]"), column("overrun"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len() as f64, ticks);
    let logged_holds = rows.iter().filter(|r| r[excess_column] > 0.0).count() as f64;
    let logged_deadlines = rows.iter().filter(|r| r[overrun_column] == 1.0).count() as f64;
    assert_eq!(logged_deadlines, number("deadline_overruns"));
    // The summary also counts the last command, in force until the safe stop.
    let final_hold = number("hold_overruns") - logged_holds;
    assert!(final_hold == 0.0 || final_hold == 1.0, "{summary:#}");

    // `softcbf plot` reads the log, and a log written before the column existed.
    let (plotted, _, plot_err) = plot(&out.join("trajectory.csv"), &root.join("plot"));
    assert_eq!(plotted, 0, "{plot_err}");
    let old = root.join("old");
    std::fs::create_dir_all(&old).unwrap();
    let without: String = text
        .lines()
        .map(|l| {
            let mut fields: Vec<&str> = l.split(',').collect();
            fields.remove(excess_column);
            fields.join(",") + "\n"
        })
        .collect();
    std::fs::write(old.join("trajectory.csv"), without).unwrap();
    let (plotted, _, plot_err) = plot(&old.join("trajectory.csv"), &old);
    assert_eq!(plotted, 0, "{plot_err}");
    assert!(old.join("figure.png").exists());
    std::fs::remove_dir_all(&root).unwrap();
}

/// `softcbf plot FILE --out DIR`: exit code, stdout, stderr.
fn plot(file: &Path, out: &Path) -> (i32, String, String) {
    let output = Command::new(BIN)
        .arg("plot")
        .arg(file)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}
