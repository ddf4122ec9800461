//! What the figures say about a run, read back from the SVG files that `softcbf simulate`
//! and `softcbf plot` write: a barrier held at zero to rounding is on its margin, not past
//! it (the verdict's tolerance); a run whose state left the model's domain says so; the
//! barrier panel has a zoomed row near zero, barrier colours of their own, labels clear of
//! the zero line and time labels that do not run together at a split.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_softcbf");

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("softcbf-figures-{}-{name}", std::process::id()));
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

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The value of attribute `name` in an SVG element's text.
fn attribute<'a>(element: &'a str, name: &str) -> Option<&'a str> {
    let start = element.find(&format!(" {name}=\""))? + name.len() + 3;
    let end = start + element[start..].find('"')?;
    Some(&element[start..end])
}

fn number(element: &str, name: &str) -> f64 {
    attribute(element, name)
        .and_then(|v| v.parse().ok())
        .unwrap_or(f64::NAN)
}

/// Every `<text>` of an SVG: `(x, y, content)`.
fn texts(svg: &str) -> Vec<(f64, f64, String)> {
    let mut out = Vec::new();
    let mut rest = svg;
    while let Some(start) = rest.find("<text ") {
        let tail = &rest[start..];
        let Some(open_end) = tail.find('>') else {
            break;
        };
        let Some(close) = tail.find("</text>") else {
            break;
        };
        let element = &tail[..open_end];
        let content = tail[open_end + 1..close].trim().to_string();
        out.push((number(element, "x"), number(element, "y"), content));
        rest = &tail[close..];
    }
    out
}

/// Every `<polyline>` of an SVG: its stroke colour and points.
fn polylines(svg: &str) -> Vec<(String, Vec<(f64, f64)>)> {
    svg.split("<polyline ")
        .skip(1)
        .map(|element| {
            let element = &element[..element.find("/>").unwrap_or(element.len())];
            let stroke = attribute(element, "stroke").unwrap_or("").to_string();
            let points = attribute(element, "points")
                .unwrap_or("")
                .split_whitespace()
                .filter_map(|p| {
                    let (x, y) = p.split_once(',')?;
                    Some((x.parse().ok()?, y.parse().ok()?))
                })
                .collect();
            (stroke, points)
        })
        .collect()
}

/// Runs `softcbf simulate` with `args` into `out`; returns its exit status.
fn simulate(out: &Path, args: &[&str]) -> i32 {
    let mut all = vec!["simulate", "--out", out.to_str().unwrap()];
    all.extend_from_slice(args);
    let run = softcbf(&all);
    assert!(
        matches!(run.status.code(), Some(0 | 3)),
        "simulate {args:?}: {}",
        text(&run.stderr)
    );
    run.status.code().unwrap()
}

/// Sets column `name` of the last row of the CSV `path` to `value`.
fn set_last(path: &Path, name: &str, value: &str) {
    let csv = read(path);
    let mut lines: Vec<String> = csv.lines().map(str::to_string).collect();
    let column = lines[0]
        .split(',')
        .position(|c| c == name)
        .unwrap_or_else(|| panic!("no column {name}"));
    let last = lines.last_mut().unwrap();
    let mut values: Vec<String> = last.split(',').map(str::to_string).collect();
    values[column] = value.to_string();
    *last = values.join(",");
    std::fs::write(path, lines.join("\n") + "\n").unwrap();
}

/// The paper's filtered run holds module 1's corner 1 on its margin; ending it at
/// −1.6e-12 m (rounding, as a run did) still draws it on its margin, orange, as the
/// verdict counts it; the PD+ run, 28 mm past its margin, is drawn as past it.
#[test]
fn a_barrier_held_at_zero_to_rounding_is_on_its_margin() {
    let dir = temp_dir("zero");
    let out = dir.join("run");
    assert_eq!(simulate(&out, &[]), 0);
    let csv = out.join("trajectory.csv");
    set_last(&csv, "b module 1 corner 1 [m]", "-1.6e-12");
    let pd = out.join("trajectory_pd.csv");
    let redrawn = dir.join("redrawn");
    let plot = softcbf(&[
        "plot",
        csv.to_str().unwrap(),
        pd.to_str().unwrap(),
        "--out",
        redrawn.to_str().unwrap(),
    ]);
    assert!(plot.status.success(), "{}", text(&plot.stderr));
    let svg = read(&redrawn.join("robot.svg"));
    let notes: Vec<String> = texts(&svg)
        .into_iter()
        .map(|(_, _, t)| t)
        .filter(|t| t.starts_with("lowest: "))
        .collect();
    assert_eq!(
        notes,
        [
            "lowest: module 1 corner 1, on its margin",
            "lowest: module 2 corner 6, below its margin"
        ],
        "{notes:?}"
    );
    // The legend says where red begins.
    assert!(svg.contains("corner with b &lt; −1 µm") || svg.contains("corner with b < −1 µm"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The paper's rows at 33 Hz toward a set point far past contact leave the model's domain
/// (δL₁ past ten rest lengths, the domain's limits notwithstanding: nothing bounds the
/// hold): the figure says so under the column's title and the 3-D view names the state
/// invalid instead of a gap of hundreds of millimetres "clear".
#[test]
fn a_run_with_invalid_states_says_so_in_its_figures() {
    let dir = temp_dir("invalid");
    let status = simulate(
        &dir,
        &[
            "--safety",
            "paper",
            "--control-period",
            "0.0303",
            "--duration",
            "1",
            "--set-point=0.15,0,-0.09,0,-0.15,-0.09",
        ],
    );
    assert_eq!(status, 3);
    let figure = read(&dir.join("figure.svg"));
    let lines: Vec<String> = texts(&figure).into_iter().map(|(_, _, t)| t).collect();
    let note = lines
        .iter()
        .find(|t| t.starts_with("invalid state from t = "))
        .unwrap_or_else(|| panic!("no note of the invalid states in {lines:?}"));
    assert!(note.contains("values there mean nothing"), "{note}");
    assert!(
        lines
            .iter()
            .any(|t| t.starts_with("first: module 1: δL = ")),
        "{lines:?}"
    );
    // Only the filtered column has them.
    assert_eq!(
        lines
            .iter()
            .filter(|t| t.starts_with("invalid state from"))
            .count(),
        1
    );
    let view = read(&dir.join("robot.svg"));
    let view_texts: Vec<String> = texts(&view).into_iter().map(|(_, _, t)| t).collect();
    assert!(
        view_texts.iter().any(|t| t == "invalid state:"),
        "{view_texts:?}"
    );
    assert!(
        !view_texts.iter().any(|t| t.ends_with(", clear")),
        "an invalid state is drawn as clear: {view_texts:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The barrier row of the paper's run: a zoomed row near zero in millimetres, barrier
/// colours that are none of the coordinates', the labels of the barriers that reach zero
/// clear of the zero line, and, with the time axis split at 2 s, no time label running
/// into the split's own.
#[test]
fn the_barrier_panel_shows_what_the_paper_shows() {
    let dir = temp_dir("panel");
    let out = dir.join("run");
    assert_eq!(simulate(&out, &[]), 0);
    let svg = read(&out.join("figure.svg"));
    let all = texts(&svg);
    let zoomed: Vec<&(f64, f64, String)> = all
        .iter()
        .filter(|(_, _, t)| t.contains("near b = 0, zoomed (in mm)"))
        .collect();
    assert_eq!(zoomed.len(), 2, "a zoomed row in each column");
    assert!(all.iter().any(|(_, _, t)| t == "b [mm]"));

    // Colours: the coordinates' lines (rows a–c) and the barriers' (rows d, e).
    let lines = polylines(&svg);
    let zoom_top = zoomed[0].1;
    let barrier_top = all
        .iter()
        .find(|(_, _, t)| t.contains("barrier values b"))
        .unwrap()
        .1;
    let colours = |from: f64, to: f64| -> std::collections::BTreeSet<String> {
        lines
            .iter()
            .filter(|(stroke, points)| {
                points.len() > 2
                    && !matches!(stroke.as_str(), "#000000" | "#787878")
                    && points.iter().all(|&(_, y)| y > from && y < to)
            })
            .map(|(stroke, _)| stroke.clone())
            .collect()
    };
    let coordinates = colours(0.0, barrier_top);
    let barriers = colours(barrier_top, f64::INFINITY);
    assert!(
        coordinates.len() >= 6 && barriers.len() >= 6,
        "{coordinates:?} {barriers:?}"
    );
    let shared: Vec<&String> = coordinates.intersection(&barriers).collect();
    assert!(
        shared.is_empty(),
        "barriers drawn in coordinate colours {shared:?}"
    );
    assert!(zoom_top > barrier_top);

    // The labels' block: below the zero line of its panel by a clear gap.
    let blocks: Vec<(f64, f64, f64)> = svg
        .split("<rect ")
        .skip(1)
        .filter(|r| r.contains("opacity=\"0.85\""))
        .map(|r| (number(r, "x"), number(r, "y"), number(r, "width")))
        .collect();
    assert_eq!(blocks.len(), 2, "a block of labels in each column");
    for (x, y, _) in blocks {
        // The zero line of its panel: where the value axis left of the block labels 0 (the
        // lowest such label above the block's top: the zoomed row's is below it).
        let zero = all
            .iter()
            .filter(|(tx, ty, t)| *tx < x && *ty <= y && t.parse::<f64>() == Ok(0.0))
            .map(|&(_, ty, _)| ty)
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(
            zero.is_finite(),
            "no 0 on the value axis left of the block at {x}, {y}"
        );
        assert!(
            y - zero >= 8.0,
            "the labels' block at y = {y} is {} px under the zero line at {zero}",
            y - zero
        );
    }

    // The first 4 s split at 2 s: "2.0" ends the first part; the second does not start
    // with a "2" of its own.
    let csv = out.join("trajectory.csv");
    let split = dir.join("split");
    let plot = softcbf(&[
        "plot",
        csv.to_str().unwrap(),
        "--t-range",
        "0,4",
        "--split",
        "2",
        "--out",
        split.to_str().unwrap(),
    ]);
    assert!(plot.status.success(), "{}", text(&plot.stderr));
    let labels: Vec<(f64, f64, String)> = texts(&read(&split.join("figure.svg")))
        .into_iter()
        .filter(|(_, _, t)| !t.is_empty() && t.parse::<f64>().is_ok())
        .collect();
    assert!(labels.iter().any(|(_, _, t)| t == "2.0"));
    for (k, (x, y, a)) in labels.iter().enumerate() {
        for (x2, y2, b) in &labels[k + 1..] {
            if y != y2 {
                continue;
            }
            // About 8 px per character at the labels' size, and a space between.
            let apart = (a.len() + b.len()) as f64 * 4.0 + 6.0;
            assert!(
                (x - x2).abs() >= apart,
                "time labels `{a}` and `{b}` at y = {y} are {} px apart",
                (x - x2).abs()
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
