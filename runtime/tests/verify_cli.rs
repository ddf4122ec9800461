//! `softcbf verify` end to end: a small batch run in one process with one and with two
//! threads, and as three shards in separate processes merged, gives the same `runs.csv` and
//! `report.json` byte for byte; a replayed run reproduces its row; bad shards and bad
//! tables are refused naming what is wrong.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::{BIN, temp_dir};

fn softcbf(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The repository's verify scenario with 0.2 s runs and `runs` runs, written into `dir`.
fn small_scenario(dir: &Path, runs: usize, extra: &str) -> PathBuf {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/verify-paper.toml");
    let original = std::fs::read_to_string(path).unwrap();
    let scenario = original
        .replace("duration = 3.0", "duration = 0.2")
        .replace("runs = 10000", &format!("runs = {runs}"))
        + extra;
    assert!(scenario.contains("duration = 0.2") && scenario.contains(&format!("runs = {runs}")));
    let path = dir.join("small.toml");
    std::fs::write(&path, scenario).unwrap();
    path
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Runs `softcbf verify` and returns its output (exit 0: all safe, 3: some unsafe).
fn verify(args: &[&str]) -> Output {
    let out = softcbf(&[&["verify"], args].concat());
    let code = out.status.code();
    assert!(
        code == Some(0) || code == Some(3),
        "exit {code:?}\n{}\n{}",
        text(&out.stdout),
        text(&out.stderr)
    );
    out
}

/// Replays run `run` of the batch of `scenario` (default seed) into `out`, checks that its
/// lowest barrier is the one in the batch's `runs` (the text of runs.csv) bit for bit, and
/// returns its summary.json.
fn replayed(scenario: &str, runs: &str, run: usize, out: &Path) -> serde_json::Value {
    let o = softcbf(&[
        "verify",
        "replay",
        "--scenario",
        scenario,
        "--run",
        &run.to_string(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        matches!(o.status.code(), Some(0 | 3)),
        "{}",
        text(&o.stderr)
    );
    let header: Vec<&str> = runs.lines().next().unwrap().split(',').collect();
    let column = header
        .iter()
        .position(|h| *h == "lowest_barrier [m]")
        .unwrap();
    let row: Vec<&str> = runs.lines().nth(run + 1).unwrap().split(',').collect();
    let expected: f64 = row[column].parse().unwrap();
    let summary: serde_json::Value =
        serde_json::from_slice(&read(&out.join("summary.json"))).unwrap();
    let lowest = summary["min_barrier"]["value"].as_f64().unwrap();
    assert_eq!(
        lowest.to_bits(),
        expected.to_bits(),
        "run {run}: replayed {lowest}, batch {expected}"
    );
    summary
}

#[test]
fn shards_merged_and_thread_counts_give_the_same_files() {
    let dir = temp_dir("shards");
    let scenario = small_scenario(&dir, 22, "");
    let scenario = scenario.to_str().unwrap();
    let one = dir.join("one");
    let two = dir.join("two");
    verify(&[
        "--scenario",
        scenario,
        "--threads",
        "1",
        "--out",
        one.to_str().unwrap(),
    ]);
    verify(&[
        "--scenario",
        scenario,
        "--threads",
        "2",
        "--out",
        two.to_str().unwrap(),
    ]);
    // Three shards as separate processes, at once.
    let shards: Vec<PathBuf> = (0..3).map(|k| dir.join(format!("shard{k}"))).collect();
    let children: Vec<_> = shards
        .iter()
        .enumerate()
        .map(|(k, out)| {
            Command::new(BIN)
                .args([
                    "verify",
                    "--scenario",
                    scenario,
                    "--threads",
                    "1",
                    "--shard",
                ])
                .arg(format!("{k}/3"))
                .arg("--out")
                .arg(out)
                .output()
        })
        .collect();
    for child in children {
        let out = child.unwrap();
        assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    }
    let merged = dir.join("merged");
    // Shards given out of order.
    let out = verify(&[
        "merge",
        shards[2].to_str().unwrap(),
        shards[0].to_str().unwrap(),
        shards[1].to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
    ]);
    assert!(
        text(&out.stdout).contains("report.json"),
        "{}",
        text(&out.stdout)
    );
    for name in ["runs.csv", "report.json"] {
        let reference = read(&one.join(name));
        assert_eq!(reference, read(&two.join(name)), "{name}: 1 vs 2 threads");
        assert_eq!(
            reference,
            read(&merged.join(name)),
            "{name}: one process vs merged shards"
        );
    }
    let runs = text(&read(&one.join("runs.csv")));
    assert_eq!(runs.lines().count(), 23, "header and 22 runs");
    // Every group of the table is there, in turn.
    for (k, line) in runs.lines().skip(1).enumerate() {
        let fields: Vec<&str> = line.split(',').collect();
        assert_eq!(fields[0], k.to_string());
        let (safety, period) = [
            ("paper", "0.001"),
            ("sampled", "0.001"),
            ("paper", "0.0303"),
            ("sampled", "0.0303"),
        ][k % 4];
        assert_eq!((fields[2], fields[3]), (safety, period), "run {k}");
    }
    // The shards differ from one another (they hold different runs) and cover the batch.
    let sizes: Vec<usize> = shards
        .iter()
        .map(|s| text(&read(&s.join("runs.csv"))).lines().count() - 1)
        .collect();
    assert_eq!(sizes, vec![7, 7, 8]);

    // A run replayed alone gives its row's lowest barrier, bit for bit.
    let replay = dir.join("replay");
    replayed(scenario, &runs, 5, &replay);
    assert!(replay.join("figure.png").exists() && replay.join("robot.png").exists());
    // The report names that command for its worst runs.
    let report: serde_json::Value =
        serde_json::from_slice(&read(&one.join("report.json"))).unwrap();
    let worst = report["worst"].as_array().unwrap();
    assert!(!worst.is_empty());
    let command = worst[0]["replay"].as_str().unwrap();
    assert!(
        command.starts_with("softcbf verify replay --scenario "),
        "{command}"
    );
    assert!(
        command.contains(&format!("--run {}", worst[0]["run"])),
        "{command}"
    );
}

#[test]
fn merge_refuses_incomplete_duplicate_and_foreign_shards() {
    let dir = temp_dir("merge");
    let scenario = small_scenario(&dir, 6, "");
    let scenario = scenario.to_str().unwrap();
    let shard = |k: usize, m: usize, seed: &str| {
        let out = dir.join(format!("s{k}of{m}seed{seed}"));
        let o = softcbf(&[
            "verify",
            "--scenario",
            scenario,
            "--runs",
            "6",
            "--seed",
            seed,
            "--duration",
            "0.05",
            "--shard",
            &format!("{k}/{m}"),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
        out
    };
    let a = shard(0, 2, "1");
    let b = shard(1, 2, "1");
    let c = shard(1, 2, "2");
    let merged = dir.join("merged");
    let merge = |dirs: &[&PathBuf]| {
        let mut args: Vec<&str> = vec!["verify", "merge"];
        args.extend(dirs.iter().map(|d| d.to_str().unwrap()));
        args.extend(["--out", merged.to_str().unwrap()]);
        softcbf(&args)
    };
    let refused = |out: Output, fragment: &str| {
        assert_eq!(out.status.code(), Some(1), "{}", text(&out.stdout));
        let err = text(&out.stderr);
        assert!(err.contains(fragment), "`{err}` lacks `{fragment}`");
    };
    refused(
        merge(&[&a]),
        "runs 3..6 of the batch's 6 are in none of the shards",
    );
    refused(merge(&[&a, &b, &a]), "is in two shards");
    refused(merge(&[&a, &c]), "seed 1 vs 2");
    let out = merge(&[&a, &b]);
    assert!(
        matches!(out.status.code(), Some(0 | 3)),
        "{}",
        text(&out.stderr)
    );
    refused(
        softcbf(&[
            "verify",
            "--scenario",
            scenario,
            "--shard",
            "2/2",
            "--out",
            "x",
        ]),
        "--shard: expected K/M with 0 ≤ K < M",
    );
    refused(
        softcbf(&[
            "verify",
            "--scenario",
            scenario,
            "--runs",
            "0",
            "--out",
            "x",
        ]),
        "--runs",
    );
}

#[test]
fn bad_tables_are_refused_at_the_field() {
    let dir = temp_dir("tables");
    let cases = [
        (
            "set_point_min = [0.0]\n",
            "small.toml:",
            "field `verify.set_point_min`",
        ),
        (
            "initial_qd_min = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\n",
            "field `verify.initial_qd_min`",
            "has no `initial_qd_max`",
        ),
        (
            "parameter_errors = true\n",
            "field `verify.parameter_errors`",
            "declares no [uncertainty]",
        ),
        (
            "sensor_noise_q = 1.0\n",
            "field `verify.sensor_noise_q`",
            "≤ 0.01 m",
        ),
        ("color = 3\n", "verify", "unknown field `color`"),
    ];
    for (line, a, b) in cases {
        let scenario = small_scenario(&dir, 4, line);
        let out = softcbf(&[
            "verify",
            "--scenario",
            scenario.to_str().unwrap(),
            "--out",
            dir.join("o").to_str().unwrap(),
        ]);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{line}: {err}");
        assert!(
            err.contains(a) && err.contains(b),
            "{line}: `{err}` lacks `{a}` or `{b}`"
        );
    }
    // A box whose upper corner lies below the lower one, and a wrong mode, name their line.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/verify-paper.toml");
    let original = std::fs::read_to_string(path).unwrap();
    // Each corner of the last box is in the domain, (−0.18, 0.18) is not.
    let corners =
        "set_point_min = [-0.18, 0.0, -0.07, -0.08, -0.08, -0.07]\nset_point_max = [0.0, 0.18,";
    for (from, to, fragment) in [
        (
            "set_point_max = [0.08, 0.08, 0.0,",
            "set_point_max = [0.08, -0.09, 0.0,",
            "entry 2 is -0.09, below `set_point_min`'s -0.08",
        ),
        (
            "safety = [\"paper\", \"sampled\"]",
            "safety = [\"paper\", \"safe\"]",
            "field `verify.safety`: entry 2",
        ),
        (
            "control_periods = [0.001, 0.0303]",
            "control_periods = [0.001, 0.001]",
            "entry 2 repeats",
        ),
        (
            "set_point_min = [-0.08, -0.08, -0.07, -0.08, -0.08, -0.07]\nset_point_max = [0.08, 0.08,",
            corners,
            "box's corner [-0.18, 0.18, -0.07] of module 1 lies outside the robot's state domain",
        ),
    ] {
        assert!(original.contains(from), "{from}");
        let scenario = dir.join("edited.toml");
        std::fs::write(&scenario, original.replace(from, to)).unwrap();
        let out = softcbf(&[
            "verify",
            "--scenario",
            scenario.to_str().unwrap(),
            "--out",
            dir.join("o").to_str().unwrap(),
        ]);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{to}: {err}");
        let last = from.lines().last().unwrap();
        let line = original.lines().position(|l| l.starts_with(last)).unwrap() + 1;
        assert!(
            err.contains(&format!("edited.toml:{line}:"))
                || err.contains(&format!("edited.toml:{line} ")),
            "{to}: `{err}` lacks line {line}"
        );
        assert!(err.contains(fragment), "{to}: `{err}` lacks `{fragment}`");
    }
}

#[test]
fn parameter_errors_noise_and_initial_states_are_drawn_and_replayed() {
    let dir = temp_dir("uncertain");
    let robot = Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/paper-sim-uncertain.toml");
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/verify-paper.toml");
    let scenario = std::fs::read_to_string(path)
        .unwrap()
        .replace(
            "# robot = \"../robots/paper-sim.toml\"",
            &format!("robot = \"{}\"", robot.display()),
        )
        .replace("duration = 3.0", "duration = 0.1")
        + "parameter_errors = true\nsensor_noise_q = 1e-5\nsensor_noise_qd = 1e-3\n\
           initial_q_min = [-0.01, -0.01, -0.01, -0.01, -0.01, -0.01]\n\
           initial_q_max = [0.01, 0.01, 0.0, 0.01, 0.01, 0.0]\n";
    assert!(scenario.contains("robot = \"/"));
    let file = dir.join("uncertain.toml");
    std::fs::write(&file, scenario).unwrap();
    let file = file.to_str().unwrap();
    let out = dir.join("batch");
    verify(&[
        "--scenario",
        file,
        "--runs",
        "8",
        "--out",
        out.to_str().unwrap(),
    ]);
    let runs = text(&read(&out.join("runs.csv")));
    let header: Vec<&str> = runs.lines().next().unwrap().split(',').collect();
    let rows: Vec<Vec<&str>> = runs
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 8);
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    // The robot file declares ±20 % on stiffness, damping and mass: every factor lies
    // inside, and they differ from run to run.
    let mut factors = Vec::new();
    for row in &rows {
        for module in 1..=2 {
            for what in [
                "bend stiffness",
                "axial stiffness",
                "bend damping",
                "axial damping",
                "mass",
            ] {
                let f: f64 = row[column(&format!("module {module} {what} factor"))]
                    .parse()
                    .unwrap();
                assert!((0.8..=1.2).contains(&f), "{what} factor {f}");
                factors.push(f);
            }
        }
        let q: f64 = row[column("initial dx1 [m]")].parse().unwrap();
        assert!((-0.01..=0.01).contains(&q) && q != 0.0, "initial dx1 {q}");
    }
    factors.sort_by(f64::total_cmp);
    factors.dedup();
    assert_eq!(factors.len(), 80, "every factor drawn anew");
    // A run with noise replays to the bit (the noise is seeded by the run).
    let summary = replayed(file, &runs, 3, &dir.join("replay"));
    assert!(
        summary["settings"]["plant"].is_object(),
        "the replay's plant is the drawn robot"
    );
}
