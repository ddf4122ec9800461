//! `softcbf verify` end to end: a small batch run in one process with one and with two
//! threads, and as three shards in separate processes merged, gives the same `runs.csv` and
//! `report.json` byte for byte; a replayed run reproduces its row; bad shards and bad
//! tables are refused naming what is wrong.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use crate::common::{BIN, lines_of, temp_dir, wait_for};
use softcbf::verify::report::{read_report, report_json};

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

/// Runs of `runs.csv` text that are unsafe by the documented rule (docs/verify.md): the
/// lowest barrier below −1e-6 m or not finite, a tick with an invalid state or a failed
/// QP, or stopped early; counted here from the columns, independently of the code.
fn unsafe_rows(runs: &str) -> usize {
    let mut lines = runs.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (lowest, failed, invalid, stopped) = (
        column("lowest_barrier [m]"),
        column("failed"),
        column("invalid_state"),
        column("stopped"),
    );
    lines
        .filter(|line| {
            let f: Vec<&str> = line.split(',').collect();
            let b: f64 = f[lowest].parse().unwrap();
            b.is_nan()
                || b < -1e-6
                || f[failed] != "0"
                || f[invalid] != "0"
                || !f[stopped].is_empty()
        })
        .count()
}

/// A shard exits 3 when one of its runs is unsafe, 0 when none is (docs/verify.md).
fn assert_shard_status(out: &Output, dir: &Path) {
    let runs = text(&read(&dir.join("runs.csv")));
    let expected = if unsafe_rows(&runs) > 0 { 3 } else { 0 };
    assert_eq!(
        out.status.code(),
        Some(expected),
        "{}: {} unsafe runs\n{}\n{}",
        dir.display(),
        unsafe_rows(&runs),
        text(&out.stdout),
        text(&out.stderr)
    );
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
    for (child, out_dir) in children.into_iter().zip(&shards) {
        let out = child.unwrap();
        assert_shard_status(&out, out_dir);
    }
    // Paper's rows among them go below the threshold: a shard holding one says so.
    let unsafe_in_shards: usize = shards
        .iter()
        .map(|d| unsafe_rows(&text(&read(&d.join("runs.csv")))))
        .sum();
    assert!(
        unsafe_in_shards > 0,
        "the batch has no unsafe run to report"
    );
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
            ("certified", "0.001"),
            ("paper", "0.0303"),
            ("certified", "0.0303"),
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
    // With --mcap, the run as an MCAP log too: the CSV's rows, summary.json's metadata.
    let logged = dir.join("replay-mcap");
    let o = softcbf(&[
        "verify",
        "replay",
        "--scenario",
        scenario,
        "--run",
        "5",
        "--mcap",
        "--out",
        logged.to_str().unwrap(),
    ]);
    assert!(
        matches!(o.status.code(), Some(0 | 3)),
        "{}",
        text(&o.stderr)
    );
    assert!(text(&o.stdout).contains("run.mcap"), "{}", text(&o.stdout));
    crate::common::assert_log_is_the_csvs(&logged, "filter");
    // The report, read back through the type that wrote it, writes the same bytes again;
    // it names that command for its worst runs.
    let report = read_report(&one.join("report.json")).unwrap();
    assert_eq!(
        report_json(&report),
        text(&read(&one.join("report.json"))),
        "report.json read back and written again"
    );
    assert_eq!((report.runs, report.groups.len()), (22, 4));
    let worst = &report.worst;
    assert!(!worst.is_empty());
    let command = &worst[0].replay;
    assert!(
        command.starts_with("softcbf verify replay --scenario "),
        "{command}"
    );
    assert!(
        command.contains(&format!("--run {}", worst[0].run)),
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
        assert_shard_status(&o, &out);
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
            "safety = [\"paper\", \"certified\"]",
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

/// Starts `softcbf verify ARGS…` in the background, its output read line by line.
fn start_verify(args: &[&str]) -> (std::process::Child, std::sync::mpsc::Receiver<String>) {
    let mut child = Command::new(BIN)
        .arg("verify")
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let lines = lines_of(child.stdout.take().unwrap());
    (child, lines)
}

/// Rows in a runs.csv (whole lines after the header).
fn rows_in(path: &Path) -> usize {
    std::fs::read_to_string(path)
        .map(|t| t.matches('\n').count().saturating_sub(1))
        .unwrap_or(0)
}

/// Sends `signal` to `child` once `runs.csv` in `out` holds more than `rows` rows.
fn interrupt_after(child: &std::process::Child, out: &Path, rows: usize, signal: &str) {
    let start = Instant::now();
    while rows_in(&out.join("runs.csv")) <= rows {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no row written after {rows} within 2 minutes"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    let status = Command::new("kill")
        .arg(format!("-{signal}"))
        .arg(child.id().to_string())
        .status()
        .unwrap();
    assert!(status.success());
}

#[test]
fn an_interrupted_batch_keeps_its_runs_and_resumes_to_the_same_bytes() {
    let dir = temp_dir("resume");
    // Enough that each interrupted batch is still running when its signal comes (a signal
    // follows its third new row within milliseconds; a run takes tens of them).
    let runs = 200;
    let scenario = small_scenario(&dir, runs, "");
    let scenario = scenario.to_str().unwrap();
    let reference = dir.join("reference");
    verify(&[
        "--scenario",
        scenario,
        "--threads",
        "2",
        "--out",
        reference.to_str().unwrap(),
    ]);
    let whole = read(&reference.join("runs.csv"));
    let out = dir.join("interrupted");
    let out_arg = out.to_str().unwrap();
    let mut written = 0;
    // Interrupted three times, by each signal that ends a batch, then finished.
    for (k, signal) in ["INT", "TERM", "HUP"].into_iter().enumerate() {
        let mut args = vec!["--scenario", scenario, "--threads", "2", "--out", out_arg];
        if k > 0 {
            args.push("--resume");
        }
        let (mut child, lines) = start_verify(&args);
        interrupt_after(&child, &out, written + 3, signal);
        let status = wait_for(&mut child, Duration::from_secs(120), "verify");
        let stdout: Vec<String> = lines.iter().collect();
        let mut stderr = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
        let stdout = stdout.join("\n");
        if k > 0 {
            assert!(
                stdout.contains(&format!("resuming {out_arg}: {written} of the {runs} runs")),
                "{stdout}"
            );
        }
        assert_eq!(status.code(), Some(1), "SIG{signal}:\n{stdout}\n{stderr}");
        // How far it got, and how to go on.
        let now = rows_in(&out.join("runs.csv"));
        assert!(now > written, "SIG{signal}: {now} rows after {written}");
        written = now;
        assert!(
            stderr.contains(&format!("verify interrupted by SIG{signal}"))
                && stderr.contains(&format!("after {written} of the {runs} runs")),
            "SIG{signal}: {stderr}"
        );
        assert!(
            stderr.contains(&format!("runs 0..{written} are in")),
            "{stderr}"
        );
        assert!(
            stderr.contains(&format!("--out {out_arg} --resume")),
            "{stderr}"
        );
        // What is written is the uninterrupted batch's beginning, byte for byte.
        let partial = read(&out.join("runs.csv"));
        assert!(
            whole.starts_with(&partial) && whole.len() > partial.len(),
            "SIG{signal}: runs.csv is not a prefix of the uninterrupted batch's"
        );
        assert_eq!(rows_in(&out.join("timing.csv")), written);
        assert!(
            !out.join("report.json").exists(),
            "a report of part of a batch"
        );
    }
    // Another batch's settings are refused, naming what differs; so is starting over.
    for (extra, fragment) in [
        (&["--seed", "2"][..], "seed 1 vs 2"),
        (&["--runs", "150"][..], "200 vs 150 runs"),
        (&["--shard", "0/2"][..], "shard 0/1 vs 0/2"),
    ] {
        let mut args = vec![
            "verify",
            "--scenario",
            scenario,
            "--out",
            out_arg,
            "--resume",
        ];
        args.extend_from_slice(extra);
        let o = softcbf(&args);
        assert_eq!(o.status.code(), Some(1), "{extra:?}");
        let err = text(&o.stderr);
        assert!(
            err.contains("holds another batch") && err.contains(fragment),
            "{extra:?}: {err}"
        );
    }
    let o = softcbf(&["verify", "--scenario", scenario, "--out", out_arg]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        text(&o.stderr).contains(&format!(
            "({written} of its {runs} runs written): give --resume"
        )),
        "{}",
        text(&o.stderr)
    );
    assert_eq!(
        rows_in(&out.join("runs.csv")),
        written,
        "a refusal keeps the rows"
    );
    // A row cut by a killed process is dropped, and the batch finishes with other threads.
    let mut cut = read(&out.join("runs.csv"));
    cut.extend_from_slice(b"99999,123,pap");
    std::fs::write(out.join("runs.csv"), cut).unwrap();
    verify(&[
        "--scenario",
        scenario,
        "--threads",
        "1",
        "--out",
        out_arg,
        "--resume",
    ]);
    for name in ["runs.csv", "report.json"] {
        assert_eq!(
            read(&reference.join(name)),
            read(&out.join(name)),
            "{name}: interrupted and resumed vs uninterrupted"
        );
    }
    assert_eq!(rows_in(&out.join("timing.csv")), runs);
    // Resuming a finished batch runs nothing and gives the same files.
    let o = verify(&["--scenario", scenario, "--out", out_arg, "--resume"]);
    assert!(
        text(&o.stdout).contains(&format!("{runs} of the {runs} runs written, 0 to run")),
        "{}",
        text(&o.stdout)
    );
    assert_eq!(
        read(&reference.join("report.json")),
        read(&out.join("report.json"))
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn thread_counts_are_checked_and_never_exceed_the_runs() {
    let dir = temp_dir("threads");
    let scenario = small_scenario(&dir, 4, "");
    let scenario = scenario.to_str().unwrap();
    let out = dir.join("o");
    let start = Instant::now();
    let o = softcbf(&[
        "verify",
        "--scenario",
        scenario,
        "--runs",
        "2",
        "--threads",
        "100000",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        text(&o.stderr).contains("--threads: must be an integer in 0..=1024, got 100000"),
        "{}",
        text(&o.stderr)
    );
    let o = softcbf(&[
        "verify",
        "--scenario",
        scenario,
        "--threads",
        "-1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        text(&o.stderr).contains("--threads: must be an integer in 0..=1024, got -1"),
        "{}",
        text(&o.stderr)
    );
    let o = verify(&[
        "--scenario",
        scenario,
        "--runs",
        "2",
        "--threads",
        "1000",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        text(&o.stdout).contains("2 runs in "),
        "{}",
        text(&o.stdout)
    );
    assert!(
        text(&o.stdout).contains(", 2 threads)"),
        "{}",
        text(&o.stdout)
    );
    // All of it in the time of two short runs, not of a thousand threads' start.
    assert!(
        start.elapsed() < Duration::from_secs(60),
        "{:?}",
        start.elapsed()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn merge_refuses_to_write_over_one_of_its_shards() {
    let dir = temp_dir("merge-over");
    let scenario = small_scenario(&dir, 4, "");
    let scenario = scenario.to_str().unwrap();
    let shards: Vec<PathBuf> = (0..2).map(|k| dir.join(format!("s{k}"))).collect();
    for (k, out) in shards.iter().enumerate() {
        let o = softcbf(&[
            "verify",
            "--scenario",
            scenario,
            "--duration",
            "0.05",
            "--shard",
            &format!("{k}/2"),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_shard_status(&o, out);
    }
    let before = read(&shards[0].join("runs.csv"));
    // The same directory, also spelled another way.
    let other_spelling = dir.join("s1/../s0");
    for out in [&shards[0], &other_spelling] {
        let o = softcbf(&[
            "verify",
            "merge",
            shards[0].to_str().unwrap(),
            shards[1].to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o.stdout));
        assert!(
            text(&o.stderr).contains("is one of the shard directories merged"),
            "{}",
            text(&o.stderr)
        );
    }
    assert_eq!(
        before,
        read(&shards[0].join("runs.csv")),
        "the shard is untouched"
    );
    assert!(!shards[0].join("report.json").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn file_values_are_checked_when_the_command_line_replaces_them() {
    let dir = temp_dir("overridden");
    // The last one is the [verify] table's own duration, appended to it.
    for (from, to, option, field) in [
        ("runs = 4", "runs = 0", ["--runs", "2"], "verify.runs"),
        ("seed = 1", "seed = -5", ["--seed", "3"], "verify.seed"),
        (
            "\nduration = 7.0\n",
            "duration = -1.0",
            ["--duration", "0.1"],
            "verify.duration",
        ),
    ] {
        let scenario = small_scenario(&dir, 4, "\nduration = 7.0\n");
        let original = std::fs::read_to_string(&scenario).unwrap();
        assert!(original.contains(from), "{from}");
        let edited = original.replacen(from, &format!("\n{to}\n"), 1);
        std::fs::write(&scenario, &edited).unwrap();
        let line = edited.lines().position(|l| l.starts_with(to)).unwrap() + 1;
        let o = softcbf(&[
            "verify",
            "--scenario",
            scenario.to_str().unwrap(),
            option[0],
            option[1],
            "--out",
            dir.join("o").to_str().unwrap(),
        ]);
        let err = text(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{to} with {option:?}: {err}");
        assert!(
            err.contains(&format!("small.toml:{line}: field `{field}`")),
            "{to} with {option:?}: {err}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_run_with_invalid_states_has_one_verdict_in_verify_and_in_replay() {
    let dir = temp_dir("invalid");
    // The paper's rows at 33 Hz drive most runs out of the model's domain within 3 s.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/verify-paper.toml");
    let scenario = std::fs::read_to_string(path)
        .unwrap()
        .replace("runs = 10000", "runs = 12")
        .replace(
            "safety = [\"paper\", \"certified\"]",
            "safety = [\"paper\"]",
        )
        .replace(
            "control_periods = [0.001, 0.0303]",
            "control_periods = [0.0303]",
        );
    assert!(scenario.contains("control_periods = [0.0303]") && scenario.contains("runs = 12"));
    let file = dir.join("paper-33.toml");
    std::fs::write(&file, scenario).unwrap();
    let file = file.to_str().unwrap();
    let batch = dir.join("batch");
    let o = verify(&["--scenario", file, "--out", batch.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(3));
    let runs = text(&read(&batch.join("runs.csv")));
    let header: Vec<&str> = runs.lines().next().unwrap().split(',').collect();
    let invalid = header.iter().position(|h| *h == "invalid_state").unwrap();
    let run = runs
        .lines()
        .skip(1)
        .position(|l| l.split(',').nth(invalid) != Some("0"))
        .expect("a run with invalid states");
    // verify counts it unsafe (its row); its replay, what `simulate` writes, says so too.
    assert!(
        unsafe_rows(
            &runs
                .lines()
                .take(1)
                .chain(runs.lines().nth(run + 1))
                .collect::<Vec<_>>()
                .join("\n")
        ) == 1
    );
    let replay = dir.join("replay");
    let o = softcbf(&[
        "verify",
        "replay",
        "--scenario",
        file,
        "--run",
        &run.to_string(),
        "--out",
        replay.to_str().unwrap(),
    ]);
    let stdout = text(&o.stdout);
    assert_eq!(o.status.code(), Some(3), "{stdout}\n{}", text(&o.stderr));
    assert!(stdout.contains("verdict: UNSAFE"), "{stdout}");
    // Its lowest barrier is not a number over the valid rows alone: the invalid rows are
    // counted in the line.
    let summary: serde_json::Value =
        serde_json::from_slice(&read(&replay.join("summary.json"))).unwrap();
    let bad = summary["invalid_rows"].as_u64().unwrap();
    let rows = summary["rows"].as_u64().unwrap();
    assert!(bad > 0 && rows > bad, "{bad} of {rows}");
    // Over its valid rows alone the lowest barrier is a number; the invalid rows must not
    // hide behind it.
    let valid_lowest = summary["min_barrier"]["value"].as_f64().unwrap();
    assert!(valid_lowest.is_finite(), "run {run}: {valid_lowest} m");
    assert!(
        stdout.contains(&format!(
            "none at {bad} of {rows} recorded rows (an invalid state"
        )),
        "{stdout}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
