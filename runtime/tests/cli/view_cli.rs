//! `softcbf view` and `simulate --view` end to end: the page of a short run is one file
//! that fetches nothing, its embedded data reads back (through the one type that writes
//! it) with a frame per 1/30 s for both runs, every corner, and the CSV's barriers at the
//! rows it says it drew; bad directories and files are refused naming the file.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use softcbf::view::data::ViewData;

use crate::common::{BIN, temp_dir};

fn softcbf(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The paper's scenario (filter and PD+ comparison), shortened to `seconds`.
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

/// Simulates the shortened paper scenario into `dir/out` (with `extra` options).
fn simulate(dir: &Path, seconds: f64, extra: &[&str]) -> (PathBuf, Output) {
    let scenario = short_scenario(dir, seconds);
    let out = dir.join("out");
    let mut args = vec![
        "simulate",
        "--scenario",
        scenario.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let run = softcbf(&args);
    assert!(run.status.success(), "{}", text(&run.stderr));
    (out, run)
}

/// The CSV's rows: time and barrier values (columns `b …`).
fn csv_rows(file: &Path) -> (Vec<String>, Vec<(f64, Vec<f64>)>) {
    let content = std::fs::read_to_string(file).unwrap();
    let mut lines = content.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let barriers: Vec<usize> = (0..header.len())
        .filter(|&k| header[k].starts_with("b "))
        .collect();
    let rows = lines
        .map(|line| {
            let cells: Vec<f64> = line.split(',').map(|c| c.parse().unwrap()).collect();
            (cells[0], barriers.iter().map(|&k| cells[k]).collect())
        })
        .collect();
    let labels = barriers.iter().map(|&k| header[k].clone()).collect();
    (labels, rows)
}

#[test]
fn the_page_is_self_contained_and_holds_every_frame_of_both_runs() {
    let dir = temp_dir("view-page");
    let (out, _) = simulate(&dir, 0.4, &[]);
    let view = softcbf(&["view", out.to_str().unwrap()]);
    assert!(view.status.success(), "{}", text(&view.stderr));
    let page = out.join("view.html");
    let stdout = text(&view.stdout);
    assert!(
        stdout.starts_with(&format!(
            "wrote {}: 13 frames, 30 per second of robot time, ",
            page.display()
        )),
        "{stdout}"
    );
    let html = std::fs::read_to_string(&page).unwrap();

    // Nothing outside the file: no address of any network, no element that loads one.
    for needle in [
        "http://", "https://", "src=", "<link", "@import", "url(", "<iframe",
    ] {
        assert!(!html.contains(needle), "the page contains `{needle}`");
    }
    assert_eq!(html.matches("<script").count(), 2);

    let data = ViewData::from_page(&html).unwrap();
    assert_eq!(data.format, softcbf::view::data::FORMAT);
    assert_eq!(data.robot, "paper-sim");
    assert_eq!(data.fps, 30.0);
    // 0, 1/30, …, 12/30 = 0.4 s.
    assert_eq!(data.times.len(), 13);
    for (k, t) in data.times.iter().enumerate() {
        assert!((t - k as f64 / 30.0).abs() < 1e-12, "{k}: {t}");
    }
    let titles: Vec<&str> = data.runs.iter().map(|r| r.title.as_str()).collect();
    assert_eq!(titles.len(), 2);
    assert!(
        titles[0].contains("filter") && titles[1].contains("PD+"),
        "{titles:?}"
    );

    // Twelve corners, six to a plate, and the CSV's barriers in the CSV's order.
    assert_eq!(data.corners.len(), 12);
    assert!(data.watched.is_empty() && data.obstacles.is_empty());
    for (run, file) in data
        .runs
        .iter()
        .zip(["trajectory.csv", "trajectory_pd.csv"])
    {
        let (labels, rows) = csv_rows(&out.join(file));
        assert_eq!(run.file, out.join(file).display().to_string());
        let names: Vec<String> = data
            .barriers
            .iter()
            .map(|b| format!("b {} [{}]", b.label, b.unit))
            .collect();
        assert_eq!(names, labels);
        assert_eq!(run.frames.len(), data.times.len());
        for (frame, &asked) in run.frames.iter().zip(&data.times) {
            // The frame is the CSV's row nearest to its time, with that row's barriers.
            let nearest = rows
                .iter()
                .min_by(|a, b| (a.0 - asked).abs().total_cmp(&(b.0 - asked).abs()))
                .unwrap();
            assert_eq!(frame.t, Some(nearest.0));
            assert_eq!(frame.b.len(), labels.len());
            for (embedded, csv) in frame.b.iter().zip(&nearest.1) {
                let embedded = embedded.unwrap();
                assert!(
                    (embedded - csv).abs() <= 5e-4 * csv.abs(),
                    "{embedded} vs {csv}"
                );
            }
            assert!(frame.invalid.is_none());
            let robot = frame.robot.as_ref().unwrap();
            assert_eq!(robot.backbones.len(), 2);
            assert!(robot.backbones.iter().all(|b| b.len() == 3 * 17));
            assert_eq!(robot.plates.len(), 3);
            assert!(robot.plates.iter().all(|p| p.len() == 3 * 6));
            assert_eq!(robot.corners.len(), 6 * 12);
            // The base plate lies in z = 0 and the backbone starts at the origin.
            assert!(robot.plates[0].chunks(3).all(|p| p[2] == 0.0));
            assert!(robot.backbones[0][..3].iter().all(|&x| x == 0.0));
            for (k, corner) in data.corners.iter().enumerate() {
                let at = &robot.corners[6 * k..6 * k + 3];
                let foot = &robot.corners[6 * k + 3..6 * k + 6];
                // The corner is a corner of its module's top plate …
                let plate = &robot.plates[corner.module + 1];
                assert!(
                    plate
                        .chunks(3)
                        .any(|p| (0..3).all(|i| (p[i] - at[i]).abs() < 2e-5)),
                    "corner {k} is on no corner of plate {}",
                    corner.module + 1
                );
                // … and stands above its foot by its barrier plus the margin ε = 5 mm of
                // robots/paper-sim.toml (the corners stay above the plate below in this
                // short run), to the rounding of the page: 10 µm a coordinate, four
                // significant digits a barrier.
                let height = (0..3)
                    .map(|i| (at[i] - foot[i]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let b = frame.b[corner.barrier].unwrap();
                let tolerance = 2e-5 + 5e-4 * b.abs();
                assert!(
                    (height - b - 0.005).abs() <= tolerance,
                    "corner {k} at t = {asked}: height {height} m, b = {b} m"
                );
            }
        }
    }
}

#[test]
fn simulate_view_writes_the_page_with_the_run() {
    let dir = temp_dir("view-simulate");
    let (out, run) = simulate(&dir, 0.2, &["--view"]);
    let page = out.join("view.html");
    assert!(
        text(&run.stdout).contains(&page.display().to_string()),
        "{}",
        text(&run.stdout)
    );
    let data = ViewData::from_page(&std::fs::read_to_string(&page).unwrap()).unwrap();
    assert_eq!(data.runs.len(), 2);
    assert_eq!(data.times.len(), 7);
}

#[test]
fn bad_directories_and_files_are_refused_naming_them() {
    let dir = temp_dir("view-bad");
    let refused = |args: &[&str], words: &[&str]| {
        let view = softcbf(args);
        let stderr = text(&view.stderr);
        assert_eq!(view.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        for word in words {
            assert!(stderr.contains(word), "{args:?}: `{word}` not in {stderr}");
        }
    };
    let missing = dir.join("missing");
    refused(
        &["view", missing.to_str().unwrap()],
        &[missing.to_str().unwrap(), "no such directory"],
    );
    let file = dir.join("file.txt");
    std::fs::write(&file, "x").unwrap();
    refused(&["view", file.to_str().unwrap()], &["not a directory"]);
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    refused(
        &["view", empty.to_str().unwrap()],
        &[
            &empty.join("trajectory.csv").display().to_string(),
            "not found",
        ],
    );

    let (out, _) = simulate(&dir, 0.1, &[]);
    let out_text = out.to_str().unwrap();
    refused(&["view", out_text, "--fps", "0"], &["--fps"]);
    refused(&["view", out_text, "--fps", "nan"], &["--fps"]);
    let summary = out.join("summary.json");
    let good_summary = std::fs::read_to_string(&summary).unwrap();
    std::fs::write(&summary, "{\n  \"robot\": ").unwrap();
    refused(&["view", out_text], &[&format!("{}:", summary.display())]);
    // Without a summary the robot is not known, unless given.
    std::fs::remove_file(&summary).unwrap();
    refused(&["view", out_text], &["--robot FILE"]);
    let robot = Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/paper-sim.toml");
    let page = dir.join("elsewhere/page.html");
    let view = softcbf(&[
        "view",
        out_text,
        "--robot",
        robot.to_str().unwrap(),
        "--out",
        page.to_str().unwrap(),
    ]);
    assert!(view.status.success(), "{}", text(&view.stderr));
    assert!(page.is_file());
    // A robot of another structure does not fit the files.
    let three = Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/three-square.toml");
    refused(
        &["view", out_text, "--robot", three.to_str().unwrap()],
        &["trajectory.csv", "coordinates"],
    );
    std::fs::write(&summary, good_summary).unwrap();
    // A trajectory cut short, and one with a header only.
    let csv = out.join("trajectory.csv");
    let content = std::fs::read_to_string(&csv).unwrap();
    let mut lines = content.lines();
    let header = lines.next().unwrap().to_string();
    let row = lines.next().unwrap();
    std::fs::write(&csv, format!("{header}\n{}\n", &row[..row.len() / 2])).unwrap();
    refused(&["view", out_text], &[&csv.display().to_string()]);
    std::fs::write(&csv, format!("{header}\n")).unwrap();
    refused(&["view", out_text], &[&csv.display().to_string(), "no row"]);
}
