//! The `softcbf verify` command: a batch (or one shard of it), `verify merge` of shard
//! directories, and `verify replay` of one run with the figures `softcbf simulate` draws.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use clap::{Args, Subcommand};

use crate::directory::{self, Found};
use crate::draw::draw;
use crate::exit;
use crate::model::Model;
use crate::noise::SEED;
use crate::output::output_directory;
use crate::output::{Console, one_line, write_outputs};
use crate::report::is_unsafe;
use crate::report::{report, report_json};
use crate::robot_file::load_robot;
use crate::scenario::ScenarioFile;
use crate::search::cli::{SearchCommand, is_search_shard, search_command};
use crate::settings::check_number;
use crate::signal;
use crate::sim::simulate;
use crate::spec::{RUNS, VerifyOverrides, VerifySpec};
use crate::table::{self, Batch, Manifest, read, runs_csv, shard_range, write};
use crate::verdict::{Limits, Verdict, judge};
use crate::{RunRow, figures, run_batch};
use softcbf_description::limits::Limit;
use softcbf_description::toml_file::shell_word;

/// Options of `softcbf verify`.
#[derive(Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct VerifyArgs {
    #[command(subcommand)]
    command: Option<VerifyCommand>,
    #[command(flatten)]
    batch: BatchArgs,
}

#[derive(Subcommand)]
enum VerifyCommand {
    /// Merge shard directories into the runs.csv, report.json and figures one process
    /// would have written.
    Merge(MergeArgs),
    /// Run one run of a batch again alone, with the figures and 3-D view of `simulate`.
    Replay(ReplayArgs),
}

/// The batch: which scenario, how many runs, which slice.
#[derive(Args)]
struct BatchArgs {
    /// Scenario file with a `[verify]` table (scenarios/README.md).
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Runs in the batch (default: the table's `runs`).
    #[arg(long)]
    runs: Option<i64>,
    /// The batch's seed (default: the table's `seed`).
    #[arg(long)]
    seed: Option<i64>,
    /// Run only the K-th (from 0) of M disjoint slices of the batch, e.g. `--shard 3/100`;
    /// `softcbf verify merge` joins the slices' directories.
    #[arg(long, value_name = "K/M")]
    shard: Option<String>,
    /// Worker threads, 0 to 1024 (default 0: one per core); never more than the runs left.
    #[arg(long, allow_negative_numbers = true)]
    threads: Option<i64>,
    /// Simulated time of each run (s), replacing the scenario's.
    #[arg(long, allow_negative_numbers = true)]
    duration: Option<f64>,
    /// Output directory.
    #[arg(long, default_value = "verify")]
    out: PathBuf,
    /// Search for the worst case instead of drawing uniformly: `--runs` is the budget
    /// (docs/verify.md, "Searching for the worst case").
    #[arg(long)]
    search: bool,
    /// With --search: split the budget into this many independent searches (default: the
    /// shards' count, or 1); `--shard K/M` runs a slice of them.
    #[arg(long, requires = "search")]
    islands: Option<i64>,
    /// With --search: candidates per generation (default: twice the variables, 12 to 40).
    #[arg(long, requires = "search")]
    population: Option<i64>,
    /// Continue the batch (or shard) that an interrupted command left in --out, with the
    /// same settings; start it if the directory holds none.
    #[arg(long)]
    resume: bool,
}

#[derive(Args)]
struct MergeArgs {
    /// The shards' output directories.
    #[arg(required = true, value_name = "DIR")]
    dirs: Vec<PathBuf>,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
}

#[derive(Args)]
struct ReplayArgs {
    /// The batch's scenario file.
    #[arg(long)]
    scenario: PathBuf,
    /// The batch's seed (default: the table's `seed`).
    #[arg(long)]
    seed: Option<i64>,
    /// The run's index in the batch.
    #[arg(long)]
    run: usize,
    /// The batch's `--duration`, if it gave one (s).
    #[arg(long, allow_negative_numbers = true)]
    duration: Option<f64>,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// Also write an animation of the run, `robot.gif`.
    #[arg(long)]
    animate: bool,
    /// Also write the run as an MCAP log, `run.mcap` (as `softcbf simulate --mcap`).
    #[arg(long)]
    mcap: bool,
}

/// Runs `softcbf verify`; returns the exit status. A batch runs to its end (for callers
/// that keep the process's signals, such as the Python package).
pub fn verify(args: VerifyArgs, console: &mut Console) -> Result<u8, String> {
    verify_command(args, console, false)
}

/// [`verify`] as the `softcbf` command runs it: a terminating signal (Ctrl-C, `kill`, a
/// closed terminal) interrupts a batch, whose runs under way finish and are written (a
/// second signal ends it at once), and it exits [`exit::ERROR`] saying how far it got and
/// how to resume.
pub fn verify_interruptible(args: VerifyArgs, console: &mut Console) -> Result<u8, String> {
    verify_command(args, console, true)
}

fn verify_command(args: VerifyArgs, console: &mut Console, signals: bool) -> Result<u8, String> {
    match args.command {
        Some(VerifyCommand::Merge(merge)) => merge_command(merge, console),
        Some(VerifyCommand::Replay(replay)) => replay_command(replay, console),
        None => batch_command(args.batch, console, signals),
    }
}

/// Worker threads of a batch (0: one per core).
pub const THREADS: Limit = Limit::integer(0, 1024);

/// Never set: a batch without signal handling.
static NEVER: AtomicBool = AtomicBool::new(false);

/// The model and checked spec of a scenario file, with the command line's overrides.
fn load(
    path: &Path,
    runs: Option<i64>,
    seed: Option<i64>,
    duration: Option<f64>,
) -> Result<(Model, VerifySpec), String> {
    load_file(path, runs, seed, duration).map(|(_, model, spec)| (model, spec))
}

/// The scenario file, its model and its checked spec, with the command line's overrides.
fn load_file(
    path: &Path,
    runs: Option<i64>,
    seed: Option<i64>,
    duration: Option<f64>,
) -> Result<(ScenarioFile, Model, VerifySpec), String> {
    let runs = runs
        .map(|n| RUNS.check_integer(n).map_err(|m| format!("--runs: {m}")))
        .transpose()?;
    let seed = seed
        .map(|n| SEED.check_integer(n).map_err(|m| format!("--seed: {m}")))
        .transpose()?;
    let duration = duration
        .map(|d| check_number("--duration", d, &softcbf_description::limits::DURATION_S))
        .transpose()?;
    let file = ScenarioFile::load(path).map_err(|e| e.to_string())?;
    let robot = file
        .load_robot()
        .and_then(|robot| robot.map_or_else(|| load_robot(None), Ok))
        .map_err(|e| e.to_string())?;
    let robot_text = std::fs::read_to_string(&robot.source)
        .unwrap_or_else(|_| crate::robot_file::PAPER_SIM_ROBOT.to_string());
    let model = Model::new(robot).map_err(|e| e.to_string())?;
    let overrides = VerifyOverrides {
        runs: runs.map(|n| n as usize),
        seed: seed.map(|n| n as u64),
        duration,
    };
    let spec =
        VerifySpec::from_file(&file, &model, &overrides, &robot_text).map_err(|e| e.to_string())?;
    Ok((file, model, spec))
}

/// `K/M` with `0 ≤ K < M`.
fn parse_shard(text: &str) -> Result<(usize, usize), String> {
    let bad = || {
        format!(
            "--shard: expected K/M with 0 ≤ K < M (the K-th of M slices, from 0, e.g. \
             `--shard 0/4`), got `{text}`"
        )
    };
    let (k, m) = text.split_once('/').ok_or_else(bad)?;
    let k: usize = k.trim().parse().map_err(|_| bad())?;
    let m: usize = m.trim().parse().map_err(|_| bad())?;
    if m == 0 || k >= m {
        return Err(bad());
    }
    Ok((k, m))
}

/// The batch's identity as shard manifests and the report record it.
fn batch_of(spec: &VerifySpec, model: &Model, duration: Option<f64>) -> Batch {
    Batch {
        scenario: spec.file.clone(),
        fingerprint: spec.fingerprint.clone(),
        seed: spec.seed,
        runs: spec.runs,
        duration,
        threshold: spec.threshold,
        groups: spec.groups.iter().map(|g| g.name()).collect(),
        coordinates: model.nq(),
    }
}

/// Progress on standard error: a bar on a terminal, a line every tenth otherwise.
struct BatchProgress {
    start: Instant,
    terminal: bool,
    shown: Mutex<usize>,
}

impl BatchProgress {
    fn new() -> BatchProgress {
        BatchProgress {
            start: Instant::now(),
            terminal: std::io::stderr().is_terminal(),
            shown: Mutex::new(0),
        }
    }

    /// `done` of `total` runs written, `before` of them before this command started.
    fn update(&self, done: usize, total: usize, before: usize) {
        let Ok(mut shown) = self.shown.lock() else {
            return;
        };
        let steps = if self.terminal { 200 } else { 10 };
        let step = done * steps / total.max(1);
        if step <= *shown && done != total {
            return;
        }
        *shown = step;
        let elapsed = self.start.elapsed().as_secs_f64();
        let left = elapsed / (done - before).max(1) as f64 * (total - done) as f64;
        let width = 30;
        let filled = done * width / total.max(1);
        let bar: String = (0..width)
            .map(|k| if k < filled { '#' } else { '.' })
            .collect();
        let text =
            format!("verify [{bar}] {done}/{total} runs, {elapsed:.0} s, about {left:.0} s left");
        let mut stderr = std::io::stderr().lock();
        if self.terminal {
            let _ = write!(stderr, "\r{text}");
            if done == total {
                let _ = writeln!(stderr);
            }
        } else {
            let _ = writeln!(stderr, "{text}");
        }
        let _ = stderr.flush();
    }
}

fn batch_command(args: BatchArgs, console: &mut Console, signals: bool) -> Result<u8, String> {
    let Some(path) = &args.scenario else {
        return Err(
            "--scenario: give the scenario file whose [verify] table declares the ranges \
             (e.g. --scenario scenarios/verify-paper.toml)"
                .into(),
        );
    };
    let (shard, slices) = args.shard.as_deref().map_or(Ok((0, 1)), parse_shard)?;
    let threads = args
        .threads
        .map(|n| {
            THREADS
                .check_integer(n)
                .map_err(|m| format!("--threads: {m}"))
        })
        .transpose()?
        .unwrap_or(0) as usize;
    if args.search {
        let (file, model, spec) = load_file(path, args.runs, args.seed, args.duration)?;
        let command = SearchCommand {
            file,
            model,
            spec,
            islands: args.islands,
            shard: args.shard.is_some().then_some((shard, slices)),
            population: args.population,
            threads,
            duration: args.duration,
            out: args.out,
        };
        return search_command(command, console);
    }
    let (model, spec) = load(path, args.runs, args.seed, args.duration)?;
    output_directory(&args.out, "--out")?;
    let range = shard_range(spec.runs, shard, slices);
    let batch = batch_of(&spec, &model, args.duration);
    let manifest = Manifest {
        batch: batch.clone(),
        shard: [shard, slices],
        first: range.start,
        end: range.end,
        software: env!("CARGO_PKG_VERSION").to_string(),
    };
    let out = &args.out;
    let opened = directory::open(out, &manifest, args.resume).map_err(|e| e.to_string())?;
    let (mut rows, mut timing, mut files) = (opened.rows, opened.timing, opened.files);
    let stop: &AtomicBool = if signals {
        signal::exit_on_second_signal(i32::from(exit::ERROR));
        signal::stop_flag()
    } else {
        &NEVER
    };
    let groups: Vec<String> = spec.groups.iter().map(|g| g.name()).collect();
    console.say(&format!(
        "verify {}: {} of {} runs (shard {shard}/{slices}), seed {}, groups: {}",
        spec.file,
        range.len(),
        spec.runs,
        spec.seed,
        groups.join(", ")
    ));
    let left = range.start + rows.len()..range.end;
    match opened.found {
        Found::Resumed => console.say(&format!(
            "resuming {}: {} of the {} runs written, {} to run",
            out.display(),
            rows.len(),
            range.len(),
            left.len()
        )),
        Found::Finished => console.say(&format!(
            "{} held a finished batch: replaced",
            out.display()
        )),
        Found::Nothing if args.resume => console.say(&format!(
            "--resume: {} holds no batch yet: starting it",
            out.display()
        )),
        Found::Nothing => {}
    }
    let workers = if threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        threads
    }
    .clamp(1, left.len().max(1));
    let progress = BatchProgress::new();
    let start = Instant::now();
    let (before, total) = (rows.len(), range.len());
    let mut write_error = None;
    let ended = run_batch(&model, &spec, left.clone(), workers, stop, &mut |f| {
        if let Err(e) = files.push(&f.row, f.wall_time) {
            let message = e.to_string();
            write_error = Some(message.clone());
            return Err(message);
        }
        timing.push((f.row.run, f.wall_time));
        rows.push(f.row);
        progress.update(rows.len(), total, before);
        Ok(())
    });
    let wall = start.elapsed().as_secs_f64();
    let written = || {
        format!(
            "runs {}..{} are in {}",
            range.start,
            range.start + rows.len(),
            out.join("runs.csv").display()
        )
    };
    let ended = match ended {
        Ok(ended) => ended,
        Err(e) => {
            let why = write_error.unwrap_or_else(|| e.to_string());
            return Err(format!("{why} ({})", written()));
        }
    };
    let new = rows.len() - before;
    let per_run: f64 = timing.iter().rev().take(new).map(|t| t.1).sum();
    let speed = format!(
        "{new} runs in {wall:.1} s wall ({:.1} ms per run on one core, {workers} threads)",
        1e3 * per_run / new.max(1) as f64
    );
    if ended.interrupted {
        let signal = signal::received().map_or("a stop request", signal::name);
        let unsafe_runs = rows.iter().filter(|r| is_unsafe(r, spec.threshold)).count();
        let message = format!(
            "verify interrupted by {signal} after {} of the {total} runs (shard {shard}/\
             {slices}; {unsafe_runs} of them unsafe): {}; continue with: {}",
            rows.len(),
            written(),
            resume_command(&args)
        );
        console.say(&speed);
        eprintln!("error: {message}");
        return Ok(exit::ERROR);
    }

    let mut written = vec![
        out.join("shard.json").display().to_string(),
        out.join("runs.csv").display().to_string(),
        out.join("timing.csv").display().to_string(),
    ];
    let code = if slices == 1 {
        let code = summarize(out, &batch, &rows, console, &mut written)?;
        console.say(&format!("wrote {}", written.join(", ")));
        code
    } else {
        // A shard's verdict is its runs' (the report needs every shard: merge them).
        let unsafe_runs = rows.iter().filter(|r| is_unsafe(r, spec.threshold)).count();
        console.say(&format!(
            "shard {shard}/{slices}: {unsafe_runs} of {} runs unsafe (below {:e}, invalid \
             state, failed QP or stopped)",
            rows.len(),
            spec.threshold
        ));
        console.say(&format!(
            "wrote {}; join the shards with `softcbf verify merge DIR… --out DIR`",
            written.join(", ")
        ));
        if unsafe_runs > 0 {
            exit::UNSAFE
        } else {
            exit::OK
        }
    };
    console.say(&speed);
    if let Some(error) = console.error() {
        return Err(error.to_string());
    }
    Ok(code)
}

/// The command that resumes the batch `args` describe.
fn resume_command(args: &BatchArgs) -> String {
    let mut words = vec!["softcbf verify".to_string()];
    if let Some(path) = &args.scenario {
        words.push(format!("--scenario {}", shell_word(path)));
    }
    if let Some(runs) = args.runs {
        words.push(format!("--runs {runs}"));
    }
    if let Some(seed) = args.seed {
        words.push(format!("--seed {seed}"));
    }
    if let Some(shard) = &args.shard {
        words.push(format!("--shard {}", shard.trim()));
    }
    if let Some(duration) = args.duration {
        words.push(format!("--duration {duration}"));
    }
    if let Some(threads) = args.threads {
        words.push(format!("--threads {threads}"));
    }
    words.push(format!("--out {} --resume", shell_word(&args.out)));
    words.join(" ")
}

/// Writes report.json and the figures of a whole batch into `out`, prints one line per
/// group, and returns the exit status: unsafe (3) if any run went below the threshold.
fn summarize(
    out: &Path,
    batch: &Batch,
    rows: &[RunRow],
    console: &mut Console,
    written: &mut Vec<String>,
) -> Result<u8, String> {
    let report = report(batch, rows);
    let path = out.join("report.json");
    write(&path, &report_json(&report)).map_err(|e| e.to_string())?;
    written.push(path.display().to_string());
    let figures = figures::write_figures(out, rows, &batch.groups, batch.threshold)
        .map_err(|e| e.to_string())?;
    written.extend(figures.iter().map(|p| p.display().to_string()));
    for group in &report.groups {
        let lowest = group.lowest_barrier.as_ref().map_or(f64::NAN, |q| q.min);
        console.say(&format!(
            "{}: {} of {} runs unsafe ({:.2} %; below {:e}, invalid state, relaxed or stopped; {} \
             with the set point inside the safe set), lowest {lowest:.3e}, {} with an \
             invalid state, {} relaxed, {} failed QP, {} stopped",
            group.name,
            group.unsafe_runs,
            group.runs,
            100.0 * group.unsafe_fraction,
            batch.threshold,
            group.unsafe_with_set_point_inside,
            group.with_invalid_state,
            group.with_relaxed,
            group.with_failed_qp,
            group.stopped,
        ));
    }
    if let Some(first) = report
        .worst
        .iter()
        .min_by(|a, b| a.lowest_barrier.total_cmp(&b.lowest_barrier))
    {
        console.say(&format!("worst run: {}", first.replay));
    }
    let code = if report.all.unsafe_runs > 0 {
        exit::UNSAFE
    } else {
        exit::OK
    };
    Ok(code)
}

fn merge_command(args: MergeArgs, console: &mut Console) -> Result<u8, String> {
    // The output would overwrite the shard it is read from.
    if let Ok(out) = std::fs::canonicalize(&args.out) {
        for dir in &args.dirs {
            if std::fs::canonicalize(dir).is_ok_and(|d| d == out) {
                return Err(format!(
                    "--out {}: is one of the shard directories merged ({}); give a \
                     directory of its own for the merged batch",
                    args.out.display(),
                    dir.display()
                ));
            }
        }
    }
    if args.dirs.first().is_some_and(|dir| is_search_shard(dir)) {
        return crate::search::cli::merge_command(&args.dirs, &args.out, console);
    }
    output_directory(&args.out, "--out")?;
    let (batch, rows) = table::merge(&args.dirs).map_err(|e| e.to_string())?;
    let mut written = Vec::new();
    let path = args.out.join("runs.csv");
    write(&path, &runs_csv(&rows, batch.coordinates)).map_err(|e| e.to_string())?;
    written.push(path.display().to_string());
    let manifest = Manifest {
        batch: batch.clone(),
        shard: [0, 1],
        first: 0,
        end: batch.runs,
        software: env!("CARGO_PKG_VERSION").to_string(),
    };
    let path = args.out.join("shard.json");
    write(
        &path,
        &serde_json::to_string_pretty(&manifest).map_err(|e| e.to_string())?,
    )
    .map_err(|e| e.to_string())?;
    written.push(path.display().to_string());
    let mut timing = String::from("run,wall_time [s]\n");
    for dir in &args.dirs {
        if let Ok(text) = read(&dir.join("timing.csv")) {
            timing.extend(text.lines().skip(1).map(|l| format!("{l}\n")));
        }
    }
    let path = args.out.join("timing.csv");
    write(&path, &timing).map_err(|e| e.to_string())?;
    written.push(path.display().to_string());
    let code = summarize(&args.out, &batch, &rows, console, &mut written)?;
    console.say(&format!("wrote {}", written.join(", ")));
    if let Some(error) = console.error() {
        return Err(error.to_string());
    }
    Ok(code)
}

fn replay_command(args: ReplayArgs, console: &mut Console) -> Result<u8, String> {
    let (model, spec) = load(&args.scenario, None, args.seed, args.duration)?;
    output_directory(&args.out, "--out")?;
    let drawn = draw(&model, &spec, args.run)?;
    let scenario = drawn.scenario(&spec, &model)?;
    let group = &spec.groups[drawn.group];
    console.say(&format!(
        "run {} of seed {} ({}): set point {:?}",
        args.run,
        spec.seed,
        group.name(),
        drawn.set_point
    ));
    let mut progress = crate::output::Progress::new("replay");
    let run = simulate(&model, &scenario, true, &mut |f| progress.update(f))
        .map_err(|e| e.to_string())?;
    let mut written =
        write_outputs(&args.out, &run, None, &model, args.animate).map_err(|e| e.to_string())?;
    if args.mcap {
        let path = args.out.join(crate::mcap_log::FILE_NAME);
        let log = crate::mcap_log::write_simulation(&path, &run, None, &model)
            .map_err(|e| e.to_string())?;
        console.say(&log.line());
        written.push(log.path);
    }
    console.say(&one_line(&run.summary));
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    console.say(&format!("wrote {}", names.join(", ")));
    // The verdict `verify` gives this run's row (the same function, the same outcome).
    let verdict = judge(&run.summary.outcome(), &Limits::new(spec.threshold));
    let counts = &run.summary.counts;
    console.say(&format!(
        "verdict: {}",
        verdict.line_with_unproven(counts.uncertified, counts.ticks)
    ));
    if let Verdict::Unsafe(why) = &verdict {
        eprintln!("error: unsafe run: {why}");
    }
    if let Some(error) = console.error() {
        return Err(error.to_string());
    }
    Ok(verdict.status())
}
