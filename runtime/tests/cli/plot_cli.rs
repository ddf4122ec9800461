//! `softcbf plot` end to end: the figures of a `softcbf simulate` run are deleted and come
//! back from its CSVs, byte for byte; a time window and a split are taken; bad command
//! lines and bad files are refused with an error naming the option or the file.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_softcbf");

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("softcbf-plot-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn softcbf(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The paper's scenario, shortened to `seconds` (the embedded robot).
fn short_scenario(dir: &Path, seconds: f64) -> PathBuf {
    let paper = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/paper-sim.toml");
    let scenario = std::fs::read_to_string(paper)
        .unwrap()
        .replace("duration = 10.0", &format!("duration = {seconds}"));
    assert!(scenario.contains(&format!("duration = {seconds}")));
    let path = dir.join("short.toml");
    std::fs::write(&path, scenario).unwrap();
    path
}

/// `softcbf plot out/run.mcap` draws what `softcbf plot` of the two CSVs beside it draws,
/// byte for byte (every figure's data and titles the same), and the 3-D view from the
/// robot the log's own summary names; a file that is no MCAP log, or a cut one, is refused
/// naming it.
#[test]
fn figures_from_the_mcap_log_are_the_figures_from_the_csvs() {
    let dir = temp_dir("mcap");
    let scenario = short_scenario(&dir, 0.3);
    let out = dir.join("out");
    let run = softcbf(&[
        "simulate",
        "--scenario",
        scenario.to_str().unwrap(),
        "--compare",
        "--mcap",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    let log = out.join("run.mcap");
    // The log's runs are the CSVs' records, value for value, with the summary beside them.
    let read = softcbf::mcap_log::read_mcap(&log).unwrap();
    for (name, csv) in [("filter", "trajectory.csv"), ("pd", "trajectory_pd.csv")] {
        let record = softcbf::record::Record::read_csv(&out.join(csv)).unwrap();
        assert_eq!(record.columns().extra_names(), ["status", "reason"]);
        assert_eq!(read.run(name), Some(&record), "{name}");
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(read.summary.as_ref(), Some(&summary));
    let from_csv = dir.join("csv");
    let from_mcap = dir.join("mcap");
    let plot = softcbf(&[
        "plot",
        out.join("trajectory.csv").to_str().unwrap(),
        out.join("trajectory_pd.csv").to_str().unwrap(),
        "--out",
        from_csv.to_str().unwrap(),
    ]);
    assert!(plot.status.success(), "{}", text(&plot.stderr));
    // The log alone: summary.json moved away, so the titles and the robot come from it.
    std::fs::rename(out.join("summary.json"), dir.join("summary.json")).unwrap();
    let plot = softcbf(&[
        "plot",
        log.to_str().unwrap(),
        "--out",
        from_mcap.to_str().unwrap(),
    ]);
    assert!(plot.status.success(), "{}", text(&plot.stderr));
    for figure in ["figure.png", "figure.svg", "robot.png", "robot.svg"] {
        let a = std::fs::read(from_csv.join(figure)).unwrap();
        let b = std::fs::read(from_mcap.join(figure)).unwrap();
        assert!(a == b, "{figure} from run.mcap differs from the CSVs'");
    }
    // Not an MCAP log by its bytes: read as a CSV, refused naming it.
    let fake = dir.join("fake.mcap");
    std::fs::write(&fake, "hello\n").unwrap();
    let plot = softcbf(&["plot", fake.to_str().unwrap()]);
    assert!(!plot.status.success());
    assert!(
        text(&plot.stderr).contains("fake.mcap"),
        "{}",
        text(&plot.stderr)
    );
    // A log cut short (a disk that filled): refused naming it, no panic.
    let bytes = std::fs::read(&log).unwrap();
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let plot = softcbf(&["plot", cut.to_str().unwrap()]);
    assert_eq!(plot.status.code(), Some(1), "{}", text(&plot.stderr));
    assert!(
        text(&plot.stderr).contains("cut.mcap"),
        "{}",
        text(&plot.stderr)
    );
}

#[test]
fn figures_come_back_from_the_csvs() {
    let dir = temp_dir("again");
    let scenario = short_scenario(&dir, 0.4);
    let out = dir.join("out");
    let run = softcbf(&[
        "simulate",
        "--scenario",
        scenario.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    // The figures and the 3-D view, whose robot `plot` finds in summary.json.
    let figures = ["figure.png", "figure.svg", "robot.png", "robot.svg"].map(|f| out.join(f));
    let drawn: Vec<Vec<u8>> = figures.iter().map(|f| std::fs::read(f).unwrap()).collect();
    for figure in &figures {
        std::fs::remove_file(figure).unwrap();
    }
    let csv = out.join("trajectory.csv");
    let csv_pd = out.join("trajectory_pd.csv");
    let plot = softcbf(&["plot", csv.to_str().unwrap(), csv_pd.to_str().unwrap()]);
    assert!(plot.status.success(), "{}", text(&plot.stderr));
    let names: Vec<String> = figures.iter().map(|f| f.display().to_string()).collect();
    assert_eq!(
        text(&plot.stdout).trim(),
        format!("wrote {}", names.join(", "))
    );
    for (figure, bytes) in figures.iter().zip(&drawn) {
        assert!(
            std::fs::read(figure).unwrap() == *bytes,
            "{} differs",
            figure.display()
        );
    }

    // A window and a split, into another directory.
    let zoom = dir.join("zoom");
    let plot = softcbf(&[
        "plot",
        csv.to_str().unwrap(),
        "--out",
        zoom.to_str().unwrap(),
        "--t-range",
        "0,0.2",
        "--split",
        "0.05",
    ]);
    assert!(plot.status.success(), "{}", text(&plot.stderr));
    let zoomed = std::fs::read(zoom.join("figure.png")).unwrap();
    assert!(zoomed.len() > 10_000 && zoomed != drawn[0]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_command_lines_and_files_are_refused() {
    let dir = temp_dir("bad");
    let missing = dir.join("missing.csv");
    let cases: [(Vec<&str>, &str); 5] = [
        (
            vec!["--t-range", "2,1"],
            "error: --t-range: the start 2 s must be below the end 1 s",
        ),
        (
            vec!["--t-range", "0"],
            "error: --t-range: `0`: give two times in seconds, START,END (e.g. 0,2)",
        ),
        (
            vec!["--t-range", "0,inf"],
            "error: --t-range: `inf` is not a finite number of seconds",
        ),
        (
            vec!["--split", "soon"],
            "error: --split: `soon`: give `auto`, `off` or a time in seconds",
        ),
        (vec![], ""),
    ];
    for (options, expected) in cases {
        let mut args = vec!["plot", missing.to_str().unwrap()];
        args.extend(options);
        let output = softcbf(&args);
        assert_eq!(output.status.code(), Some(1), "{args:?}");
        let stderr = text(&output.stderr);
        if expected.is_empty() {
            // The options are fine: the missing file is named.
            assert!(
                stderr.starts_with(&format!("error: {}: ", missing.display())),
                "{stderr}"
            );
        } else {
            assert_eq!(stderr.trim(), expected);
        }
    }
    // No file at all: a usage error.
    assert_eq!(softcbf(&["plot"]).status.code(), Some(2));
    // A file that is not a trajectory: its line and column are named.
    let notes = dir.join("notes.csv");
    std::fs::write(&notes, "time,value\n0,1\n").unwrap();
    let output = softcbf(&["plot", notes.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(1));
    assert!(
        text(&output.stderr).starts_with(&format!(
            "error: {}:1: column 1 is `time`, expected `t [s]`",
            notes.display()
        )),
        "{}",
        text(&output.stderr)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
