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
