//! `softcbf verify --search` end to end: the same files whatever the thread count, and
//! from one process running two islands or two shards merged; a search that finds a
//! violation uniform draws of the same budget miss; each worst case replayed with
//! `softcbf simulate` gives its lowest barrier bit for bit (also with a plant inside the
//! declared box and sensor noise); bad options and mixed shards refused, naming what is
//! wrong.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common::{BIN, temp_dir};

fn softcbf(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&read(path)).unwrap()
}

/// The repository's `scenario` with `replacements` made (each must apply) and `extra`
/// appended, written into `dir` as `name`.
fn scenario(
    dir: &Path,
    name: &str,
    original: &str,
    replacements: &[(&str, &str)],
    extra: &str,
) -> PathBuf {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios")
        .join(original);
    let mut text = std::fs::read_to_string(path).unwrap();
    for (from, to) in replacements {
        assert!(text.contains(from), "{original} has no `{from}`");
        text = text.replace(from, to);
    }
    // A relative robot path stays valid from the temporary folder.
    let robots = Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots");
    text = text.replace("\"../robots/", &format!("\"{}/", robots.display()));
    text.push_str(extra);
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// The paper's robot with the paper's rows at 1 kHz, set points in a box whose deepest
/// violations lie in one corner (both modules bent toward +x, shortened).
fn corner_scenario(dir: &Path) -> PathBuf {
    scenario(
        dir,
        "corner.toml",
        "verify-paper.toml",
        &[
            (
                "safety = [\"paper\", \"certified\"]",
                "safety = [\"paper\"]",
            ),
            (
                "control_periods = [0.001, 0.0303]",
                "control_periods = [0.001]",
            ),
            ("threshold = -1e-6 ", "threshold = -2e-3 "),
            (
                "set_point_min = [-0.08, -0.08, -0.07, -0.08, -0.08, -0.07]",
                "set_point_min = [0.0, 0.0, -0.07, 0.0, 0.0, -0.07]",
            ),
            (
                "set_point_max = [0.08, 0.08, 0.0, 0.08, 0.08, 0.0]",
                "set_point_max = [0.08, 0.0, 0.0, 0.08, 0.0, 0.0]",
            ),
        ],
        "",
    )
}

/// Runs `softcbf verify` with `args` and returns its output, checking its exit status.
fn verify(args: &[&str], status: i32) -> Output {
    let out = softcbf(&[&["verify"], args].concat());
    assert_eq!(
        out.status.code(),
        Some(status),
        "{args:?}\n{}\n{}",
        text(&out.stdout),
        text(&out.stderr)
    );
    out
}

/// The lowest barrier of a group's worst case in a search's report (`-∞` for `null`).
fn worst_of(report: &serde_json::Value, group: usize) -> f64 {
    report["groups"][group]["worst"]["lowest_barrier"]
        .as_f64()
        .unwrap_or(f64::NEG_INFINITY)
}

/// Replays the worst case of every group of the search in `dir` with `softcbf simulate`
/// and checks that it gives the report's lowest barrier (or invalid states) bit for bit.
fn replays_bit_for_bit(dir: &Path) {
    let report = json(&dir.join("report.json"));
    for (g, group) in report["groups"].as_array().unwrap().iter().enumerate() {
        let worst = &group["worst"];
        let file = dir.join(worst["scenario_file"].as_str().unwrap());
        let out = dir.join(format!("replay-{g}"));
        let o = softcbf(&[
            "simulate",
            "--scenario",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(
            matches!(o.status.code(), Some(0 | 3)),
            "{}",
            text(&o.stderr)
        );
        let summary = json(&out.join("summary.json"));
        let invalid = summary["counts"]["invalid_state"].as_u64().unwrap();
        assert_eq!(invalid, worst["invalid_state"].as_u64().unwrap());
        if let Some(expected) = worst["lowest_barrier"].as_f64() {
            let lowest = summary["min_barrier"]["value"].as_f64().unwrap();
            assert_eq!(
                lowest.to_bits(),
                expected.to_bits(),
                "{}: replayed {lowest}, search {expected}",
                file.display()
            );
            assert_eq!(
                summary["min_barrier"]["label"].as_str(),
                worst["barrier"].as_str()
            );
        } else {
            assert!(invalid > 0 || worst["stopped"].as_str() != Some(""));
        }
    }
}

#[test]
fn the_search_finds_what_uniform_draws_of_its_budget_miss() {
    let dir = temp_dir("search-corner");
    let scenario = corner_scenario(&dir);
    let scenario = scenario.to_str().unwrap();
    let uniform = dir.join("uniform");
    let search = dir.join("search");
    // 24 uniform draws: none below −2 mm (exit 0).
    verify(
        &[
            "--scenario",
            scenario,
            "--runs",
            "24",
            "--out",
            uniform.to_str().unwrap(),
        ],
        0,
    );
    // A search of 24 runs (two generations): below −2 mm (exit 3).
    let out = verify(
        &[
            "--search",
            "--scenario",
            scenario,
            "--runs",
            "24",
            "--out",
            search.to_str().unwrap(),
        ],
        3,
    );
    let stdout = text(&out.stdout);
    assert!(
        stdout.contains("replay: softcbf simulate --scenario"),
        "{stdout}"
    );
    let report = json(&search.join("report.json"));
    let uniform_lowest = json(&uniform.join("report.json"))["all"]["lowest_barrier"]["min"]
        .as_f64()
        .unwrap();
    let found = worst_of(&report, 0);
    assert!(
        found < -2e-3 && uniform_lowest > -2e-3,
        "search {found}, uniform {uniform_lowest}"
    );
    assert_eq!(report["groups"][0]["runs"], 24);
    assert!(report["groups"][0]["unsafe_runs"].as_u64().unwrap() >= 1);
    // search.csv holds every run: a header and 24 rows, two generations of 12.
    let csv = text(&read(&search.join("search.csv")));
    assert_eq!(csv.lines().count(), 25);
    assert!(csv.starts_with("island,generation,candidate,run,"));
    assert!(search.join("search.png").exists() && search.join("search.svg").exists());
    replays_bit_for_bit(&search);
}

#[test]
fn threads_islands_and_merged_shards_give_the_same_search() {
    let dir = temp_dir("search-shards");
    let scenario = scenario(
        &dir,
        "small.toml",
        "verify-paper.toml",
        &[("duration = 3.0", "duration = 0.3")],
        "",
    );
    let scenario = scenario.to_str().unwrap();
    let run = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut args = vec![
            "--search",
            "--scenario",
            scenario,
            "--runs",
            "32",
            "--islands",
            "2",
            "--population",
            "3",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = softcbf(&[&["verify"], &args[..]].concat());
        assert!(
            matches!(o.status.code(), Some(0 | 3)),
            "{}",
            text(&o.stderr)
        );
        out
    };
    let one = run("one", &["--threads", "1"]);
    let two = run("two", &["--threads", "2"]);
    let shard0 = run("shard0", &["--threads", "1", "--shard", "0/2"]);
    let shard1 = run("shard1", &["--threads", "2", "--shard", "1/2"]);
    let merged = dir.join("merged");
    let o = softcbf(&[
        "verify",
        "merge",
        shard1.to_str().unwrap(),
        shard0.to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
    ]);
    assert!(
        matches!(o.status.code(), Some(0 | 3)),
        "{}",
        text(&o.stderr)
    );
    let report = json(&one.join("report.json"));
    let groups = report["groups"].as_array().unwrap();
    assert_eq!(groups.len(), 4);
    let mut files = vec!["search.csv".to_string(), "search-shard.json".to_string()];
    for g in groups {
        assert_eq!(g["runs"], 8);
        files.push(g["worst"]["scenario_file"].as_str().unwrap().to_string());
    }
    for name in &files {
        let reference = read(&one.join(name));
        assert_eq!(reference, read(&two.join(name)), "{name}: 1 vs 2 threads");
        assert_eq!(reference, read(&merged.join(name)), "{name}: one vs merged");
    }
    // report.json: the same but for the output directory its replay commands name.
    let normalized =
        |dir: &Path| text(&read(&dir.join("report.json"))).replace(dir.to_str().unwrap(), "DIR");
    assert_eq!(normalized(&one), normalized(&two));
    assert_eq!(normalized(&one), normalized(&merged));
    // Both islands searched: the 16 rows of island 0, then the 16 of island 1.
    let csv = text(&read(&one.join("search.csv")));
    let islands: Vec<&str> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(islands.len(), 32);
    assert!(islands[..16].iter().all(|&i| i == "0") && islands[16..].iter().all(|&i| i == "1"));
    // A shard alone does not merge; nor do shards of another search.
    let lonely = softcbf(&[
        "verify",
        "merge",
        shard0.to_str().unwrap(),
        "--out",
        dir.join("lonely").to_str().unwrap(),
    ]);
    assert_eq!(lonely.status.code(), Some(1));
    assert!(
        text(&lonely.stderr).contains("islands 1..2 of the search's 2 are in none"),
        "{}",
        text(&lonely.stderr)
    );
    let other = run("other", &["--seed", "2", "--shard", "1/2"]);
    let mixed = softcbf(&[
        "verify",
        "merge",
        shard0.to_str().unwrap(),
        other.to_str().unwrap(),
        "--out",
        dir.join("mixed").to_str().unwrap(),
    ]);
    assert_eq!(mixed.status.code(), Some(1));
    assert!(
        text(&mixed.stderr).contains("belong to different searches"),
        "{}",
        text(&mixed.stderr)
    );
}

#[test]
fn a_worst_case_inside_the_declared_box_with_noise_replays_bit_for_bit() {
    let dir = temp_dir("search-uncertain");
    let scenario = scenario(
        &dir,
        "uncertain.toml",
        "verify-uncertain.toml",
        &[("duration = 3.0", "duration = 0.3")],
        "sensor_noise_q = 1e-4\nsensor_noise_qd = 1e-3\n",
    );
    let out = dir.join("search");
    let o = softcbf(&[
        "verify",
        "--search",
        "--scenario",
        scenario.to_str().unwrap(),
        "--runs",
        "6",
        "--population",
        "3",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        matches!(o.status.code(), Some(0 | 3)),
        "{}",
        text(&o.stderr)
    );
    let report = json(&out.join("report.json"));
    let worst = &report["groups"][0]["worst"];
    // Five factors per module, each inside ±20 %.
    let factors = worst["factors"].as_array().unwrap();
    assert_eq!(factors.len(), 2);
    for f in factors.iter().flat_map(|m| m.as_array().unwrap()) {
        let f = f.as_f64().unwrap();
        assert!((0.8..=1.2).contains(&f), "{f}");
    }
    let file = text(&read(&out.join(worst["scenario_file"].as_str().unwrap())));
    assert!(
        file.contains("[[plant_factors]]") && file.contains("[sensor_noise]"),
        "{file}"
    );
    replays_bit_for_bit(&out);
}

#[test]
fn bad_options_are_refused_naming_the_option() {
    let dir = temp_dir("search-options");
    let scenario = corner_scenario(&dir);
    let scenario = scenario.to_str().unwrap();
    let out = dir.join("out");
    let out = out.to_str().unwrap();
    let refused = |args: &[&str], fragment: &str| {
        let o = softcbf(&[&["verify", "--scenario", scenario, "--out", out], args].concat());
        assert!(
            matches!(o.status.code(), Some(1 | 2)),
            "{args:?}: exit {:?}",
            o.status.code()
        );
        let stderr = text(&o.stderr);
        assert!(stderr.contains(fragment), "{args:?}: {stderr}");
    };
    refused(
        &["--search", "--islands", "0"],
        "--islands: must be a whole number in 1..=",
    );
    refused(
        &["--search", "--population", "1"],
        "--population: must be a whole number in 2..=",
    );
    refused(&["--islands", "2"], "--search");
    refused(&["--population", "4"], "--search");
    refused(&["--search", "--runs", "0"], "--runs");
    refused(
        &["--search", "--runs", "3", "--islands", "4"],
        "a budget of 3 runs cannot give",
    );
    refused(&["--search", "--shard", "1/1"], "--shard: expected K/M");
    refused(
        &["--search", "--shard", "0/4", "--islands", "2"],
        "fewer than 4 shards",
    );
    refused(&["--search", "--threads", "x"], "--threads");
}

#[test]
fn plant_factors_and_sensor_noise_of_a_scenario_are_checked_at_the_field() {
    let dir = temp_dir("search-fields");
    let base = "duration = 0.01\n[reference]\nset_point = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\n";
    let refused = |extra: &str, fragment: &str| {
        let path = dir.join("bad.toml");
        std::fs::write(&path, format!("{base}{extra}")).unwrap();
        let o = softcbf(&[
            "simulate",
            "--scenario",
            path.to_str().unwrap(),
            "--out",
            dir.join("out").to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "{extra}");
        let stderr = text(&o.stderr);
        assert!(stderr.contains(fragment), "{extra}: {stderr}");
    };
    let module = "[[plant_factors]]\nstiffness = [1.0, 1.0]\ndamping = [1.0, 1.0]\nmass = 1.0\n";
    refused(
        module,
        "field `plant_factors`: has 1 tables, the robot has 2 modules",
    );
    refused(
        &format!("{module}{}", module.replace("mass = 1.0", "mass = -1.0")),
        "field `plant_factors`: module 2: the factor of mass must be a finite number > 0",
    );
    refused(
        "[sensor_noise]\nq = 1.0\nseed = 3\n",
        "field `sensor_noise.q`",
    );
    refused("[sensor_noise]\nseed = -3\n", "field `sensor_noise.seed`");
    // Accepted: a plant 20 % stiffer everywhere, noise on q̇ only.
    let path = dir.join("good.toml");
    std::fs::write(
        &path,
        format!(
            "{base}{}{}[sensor_noise]\nqd = 1e-3\nseed = 7\n",
            module.replace("stiffness = [1.0, 1.0]", "stiffness = [1.2, 1.2]"),
            module
        ),
    )
    .unwrap();
    let o = softcbf(&[
        "simulate",
        "--scenario",
        path.to_str().unwrap(),
        "--out",
        dir.join("good").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let summary = json(&dir.join("good/summary.json"));
    assert!(
        summary["settings"]["plant"]["value"]["name"]
            .as_str()
            .unwrap()
            .ends_with("× plant_factors"),
        "{summary}"
    );
    assert_eq!(summary["settings"]["sensor_noise"]["seed"], 7);
    assert_eq!(summary["settings"]["sensor_noise"]["qd"], 1e-3);
}

#[test]
fn batches_and_searches_start_only_where_the_guarantee_holds() {
    let dir = temp_dir("search-starts");
    // Every start of this box moves at 20 m/s: some plate corner approaches faster than
    // ḃ + p1·b ≥ 0 allows, so no start is one the guarantee covers.
    let fast = "initial_qd_min = [20.0, 20.0, 0.0, 20.0, 20.0, 0.0]\n\
                initial_qd_max = [20.5, 20.5, 0.0, 20.5, 20.5, 0.0]\n";
    let scenario = scenario(&dir, "fast.toml", "verify-paper.toml", &[], fast);
    let scenario = scenario.to_str().unwrap();
    let out = dir.join("out");
    let batch = verify(
        &[
            "--scenario",
            scenario,
            "--runs",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        1,
    );
    let stderr = text(&batch.stderr);
    assert!(
        stderr.contains("no initial state the guarantee covers") && stderr.contains("ḃ + p1·b"),
        "{stderr}"
    );
    let search = verify(
        &[
            "--search",
            "--scenario",
            scenario,
            "--runs",
            "4",
            "--out",
            out.to_str().unwrap(),
        ],
        1,
    );
    let stderr = text(&search.stderr);
    assert!(
        stderr.contains("no candidate whose start the guarantee covers"),
        "{stderr}"
    );
}
