//! `softcbf verify --search`: runs a search (or some islands of it), writes `search.csv`,
//! `search-shard.json`, `report.json`, a scenario file per group's worst case and the
//! figure of the search's progress; `softcbf verify merge` of search shards joins them.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use crate::draw::Draw;
use crate::exit;
use crate::figures::write_search_figure;
use crate::model::Model;
use crate::output::Console;
use crate::output::output_directory;
use crate::scenario::ScenarioFile;
use crate::search::replay::scenario_text;
use crate::search::report::{
    SearchBatch, SearchManifest, SearchReport, in_spending_order, report, report_json, search_csv,
    worst_file,
};
use crate::search::space::Space;
use crate::search::{Candidate, Event, Plan, run_search, score};
use crate::spec::VerifySpec;
use crate::table::{self, write};

/// Most islands a search may be split into.
pub const MAX_ISLANDS: usize = 100_000;
/// Most candidates per generation.
pub const MAX_POPULATION: usize = 10_000;

/// What `softcbf verify --search` was asked.
pub struct SearchCommand {
    /// The scenario file, read and checked, its model and table.
    pub file: ScenarioFile,
    pub model: Model,
    pub spec: VerifySpec,
    /// `--islands` (default: the shards' count, or 1).
    pub islands: Option<i64>,
    /// `--shard K/M` parsed.
    pub shard: Option<(usize, usize)>,
    /// `--population`.
    pub population: Option<i64>,
    /// `--threads`.
    pub threads: usize,
    /// `--duration`, if given \[s\].
    pub duration: Option<f64>,
    /// `--out`.
    pub out: PathBuf,
}

/// Progress on standard error: a bar with the lowest barrier so far on a terminal, a line
/// every tenth otherwise.
struct SearchProgress {
    start: Instant,
    terminal: bool,
    total: usize,
    state: Mutex<(usize, usize, f64)>,
}

impl SearchProgress {
    fn update(&self, event: Event) {
        let Ok(mut state) = self.state.lock() else {
            return;
        };
        let (done, shown, lowest) = &mut *state;
        match event {
            Event::Run => *done += 1,
            Event::Generation { lowest: l } => *lowest = l,
        }
        let steps = if self.terminal { 200 } else { 10 };
        let step = *done * steps / self.total.max(1);
        let last = *done == self.total && matches!(event, Event::Generation { .. });
        // The last run's line waits for its generation's lowest barrier.
        if (step <= *shown || *done == self.total) && !last {
            return;
        }
        *shown = step.max(*shown + usize::from(last));
        let elapsed = self.start.elapsed().as_secs_f64();
        let left = elapsed / (*done).max(1) as f64 * (self.total - *done) as f64;
        let width = 30;
        let filled = *done * width / self.total.max(1);
        let bar: String = (0..width)
            .map(|k| if k < filled { '#' } else { '.' })
            .collect();
        let lowest = if lowest.is_finite() {
            format!("{lowest:.3e}")
        } else if *lowest < 0.0 {
            "-inf (left the model's domain)".into()
        } else {
            "none yet".into()
        };
        let text = format!(
            "search [{bar}] {done}/{} runs, lowest barrier so far {lowest}, {elapsed:.0} s, \
             about {left:.0} s left",
            self.total
        );
        let mut stderr = std::io::stderr().lock();
        if self.terminal {
            let _ = write!(stderr, "\r{text}\x1b[K");
            if last {
                let _ = writeln!(stderr);
            }
        } else {
            let _ = writeln!(stderr, "{text}");
        }
        let _ = stderr.flush();
    }
}

/// The settings of a search, checked: islands, the islands this process runs, the method.
fn plan(command: &SearchCommand, space: &Space) -> Result<Plan, String> {
    let islands = match command.islands {
        Some(n) if !(1..=MAX_ISLANDS as i64).contains(&n) => {
            return Err(format!(
                "--islands: must be a whole number in 1..={MAX_ISLANDS}, got {n}"
            ));
        }
        Some(n) => n as usize,
        None => command.shard.map_or(1, |(_, m)| m),
    };
    let run_islands = match command.shard {
        None => 0..islands,
        Some((k, m)) => {
            if islands < m {
                return Err(format!(
                    "--shard {k}/{m}: the search has {islands} islands (--islands), fewer \
                     than {m} shards; give at least as many islands as shards"
                ));
            }
            table::shard_range(islands, k, m)
        }
    };
    let population = match command.population {
        Some(n) if !(2..=MAX_POPULATION as i64).contains(&n) => {
            return Err(format!(
                "--population: must be a whole number in 2..={MAX_POPULATION}, got {n}"
            ));
        }
        other => other.map(|n| n as usize),
    };
    let groups = command.spec.groups.len();
    if command.spec.runs < groups * islands {
        return Err(format!(
            "--runs (or the table's `runs`): a budget of {} runs cannot give each of the \
             {groups} groups on each of the {islands} islands one run; give at least {}",
            command.spec.runs,
            groups * islands
        ));
    }
    Ok(Plan {
        islands,
        run_islands,
        settings: Plan::settings(space, population),
    })
}

/// The search's identity as its manifests and report record it.
fn batch_of(command: &SearchCommand, plan: &Plan, space: &Space) -> SearchBatch {
    let spec = &command.spec;
    SearchBatch {
        scenario: spec.file.clone(),
        fingerprint: spec.fingerprint.clone(),
        seed: spec.seed,
        runs: spec.runs,
        islands: plan.islands,
        duration: command.duration,
        threshold: spec.threshold,
        groups: spec.groups.iter().map(|g| g.name()).collect(),
        coordinates: command.model.nq(),
        method: plan.settings,
        variables: space.variables.iter().map(|v| v.name.clone()).collect(),
    }
}

/// Runs `softcbf verify --search`; returns the exit status (3 if any run found is
/// unsafe).
pub fn search_command(command: SearchCommand, console: &mut Console) -> Result<u8, String> {
    let space = Space::new(&command.model, &command.spec);
    let plan = plan(&command, &space)?;
    output_directory(&command.out, "--out")?;
    let batch = batch_of(&command, &plan, &space);
    let spec = &command.spec;
    let total: usize = plan
        .run_islands
        .clone()
        .map(|island| {
            (0..spec.groups.len())
                .map(|g| super::budget(spec.runs, spec.groups.len(), g, plan.islands, island))
                .sum::<usize>()
        })
        .sum();
    console.say(&format!(
        "search {}: {total} of {} runs (islands {}..{} of {}), seed {}, {} variables, {} \
         candidates per generation, groups: {}",
        spec.file,
        spec.runs,
        plan.run_islands.start,
        plan.run_islands.end,
        plan.islands,
        spec.seed,
        space.dimension(),
        plan.settings.population,
        batch.groups.join(", ")
    ));
    let progress = SearchProgress {
        start: Instant::now(),
        terminal: std::io::stderr().is_terminal(),
        total,
        state: Mutex::new((0, 0, f64::INFINITY)),
    };
    let start = Instant::now();
    let candidates = run_search(&command.model, spec, &plan, command.threads, &|event| {
        progress.update(event)
    })
    .map_err(|e| e.to_string())?;
    let wall = start.elapsed().as_secs_f64();
    let manifest = SearchManifest {
        search: batch.clone(),
        first: plan.run_islands.start,
        end: plan.run_islands.end,
        software: env!("CARGO_PKG_VERSION").to_string(),
    };
    let out = &command.out;
    let mut written = Vec::new();
    put(
        out,
        "search-shard.json",
        &serde_json::to_string_pretty(&manifest).map_err(|e| e.to_string())?,
        &mut written,
    )?;
    // The worst case of each group among these islands, as a scenario file.
    let mut worst_files = Vec::new();
    for (g, name) in batch.groups.iter().enumerate() {
        let Some(worst) = in_spending_order(&candidates, g)
            .into_iter()
            .min_by(|a, b| {
                score(&a.row)
                    .total_cmp(&score(&b.row))
                    .then((a.island, a.row.run).cmp(&(b.island, b.row.run)))
            })
        else {
            continue;
        };
        let text = worst_text(&command, &batch, name, worst)?;
        put(out, &worst_file(name), &text, &mut written)?;
        worst_files.push(out.join(worst_file(name)));
    }
    let code = summarize(out, &batch, &candidates, console, &mut written)?;
    console.say(&format!("wrote {}", written.join(", ")));
    console.say(&format!(
        "{} runs in {wall:.1} s wall ({} threads)",
        candidates.len(),
        rayon_threads(command.threads)
    ));
    if let Some(error) = console.error() {
        return Err(error.to_string());
    }
    Ok(code)
}

fn rayon_threads(threads: usize) -> usize {
    if threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        threads
    }
}

/// Writes `text` to `out/name` and notes it in `written`.
fn put(out: &Path, name: &str, text: &str, written: &mut Vec<String>) -> Result<(), String> {
    let path = out.join(name);
    write(&path, text).map_err(|e| e.to_string())?;
    written.push(path.display().to_string());
    Ok(())
}

/// The worst-case scenario file of group `name`, found as `worst`.
fn worst_text(
    command: &SearchCommand,
    batch: &SearchBatch,
    name: &str,
    worst: &Candidate,
) -> Result<String, String> {
    let row = &worst.row;
    let lowest = score(row);
    let found = if lowest.is_finite() {
        format!(
            "lowest barrier {lowest:e} ({} at t = {} s)",
            row.lowest_label, row.lowest_t
        )
    } else if row.counts.invalid_state > 0 {
        format!(
            "the state left the model's domain ({} ticks with an invalid state)",
            row.counts.invalid_state
        )
    } else {
        format!("the run stopped early: {}", row.stopped)
    };
    let header = vec![
        format!("The worst case `softcbf verify --search` found for `{name}`: {found}."),
        format!(
            "Search of {} (seed {}, {} runs, {} island{}): island {}, generation {}, \
             candidate {}.",
            batch.scenario,
            batch.seed,
            batch.runs,
            batch.islands,
            if batch.islands == 1 { "" } else { "s" },
            worst.island,
            worst.generation,
            worst.candidate
        ),
        "Run it again: softcbf simulate --scenario <this file> --out <directory>".to_string(),
    ];
    let draw: &Draw = &row.draw;
    scenario_text(
        &command.file,
        &command.spec,
        draw,
        &format!("worst {name}"),
        &header,
    )
}

/// Writes `search.csv`, `report.json` and the figure of `candidates` (every run of
/// `batch`) into `out`, prints one line per group, and returns the exit status.
fn summarize(
    out: &Path,
    batch: &SearchBatch,
    candidates: &[Candidate],
    console: &mut Console,
    written: &mut Vec<String>,
) -> Result<u8, String> {
    put(
        out,
        "search.csv",
        &search_csv(candidates, batch.coordinates),
        written,
    )?;
    let report: SearchReport = report(batch, candidates, out);
    put(out, "report.json", &report_json(&report), written)?;
    let curves: Vec<Vec<f64>> = (0..batch.groups.len())
        .map(|g| {
            in_spending_order(candidates, g)
                .iter()
                .map(|c| score(&c.row))
                .collect()
        })
        .collect();
    let figures = write_search_figure(out, &curves, &batch.groups, batch.threshold)
        .map_err(|e| e.to_string())?;
    written.extend(figures.iter().map(|p| p.display().to_string()));
    for group in &report.groups {
        let worst = match &group.worst {
            Some(w) => match w.lowest_barrier {
                Some(v) => format!("worst {v:.3e} ({}, t = {:.3} s)", w.barrier, w.t),
                None if w.invalid_state > 0 => format!(
                    "worst -inf: the state left the model's domain ({} ticks)",
                    w.invalid_state
                ),
                None => format!("worst: stopped early ({})", w.stopped),
            },
            None => "no runs".into(),
        };
        let first = group.first_unsafe.map_or_else(
            || "none unsafe".to_string(),
            |k| {
                format!(
                    "first unsafe after {k} run{}",
                    if k == 1 { "" } else { "s" }
                )
            },
        );
        console.say(&format!(
            "{}: {} of {} runs unsafe (below {:e}, invalid state or stopped), {first}, {worst}",
            group.name, group.unsafe_runs, group.runs, batch.threshold
        ));
        if let Some(w) = &group.worst {
            console.say(&format!("  replay: {}", w.replay));
        }
    }
    Ok(if report.unsafe_runs > 0 {
        exit::UNSAFE
    } else {
        exit::OK
    })
}

/// `softcbf verify merge` of the directories of a search's shards.
pub fn merge_command(dirs: &[PathBuf], out: &Path, console: &mut Console) -> Result<u8, String> {
    output_directory(out, "--out")?;
    let (batch, candidates, holders) = super::report::merge(dirs).map_err(|e| e.to_string())?;
    let mut written = Vec::new();
    let manifest = SearchManifest {
        search: batch.clone(),
        first: 0,
        end: batch.islands,
        software: env!("CARGO_PKG_VERSION").to_string(),
    };
    put(
        out,
        "search-shard.json",
        &serde_json::to_string_pretty(&manifest).map_err(|e| e.to_string())?,
        &mut written,
    )?;
    // Each group's worst case: the scenario file of the shard whose island found it.
    let report = report(&batch, &candidates, out);
    for group in &report.groups {
        let Some(worst) = &group.worst else { continue };
        let from = holders[worst.island].join(&worst.scenario_file);
        let text = table::read(&from).map_err(|e| e.to_string())?;
        put(out, &worst.scenario_file, &text, &mut written)?;
    }
    let code = summarize(out, &batch, &candidates, console, &mut written)?;
    console.say(&format!("wrote {}", written.join(", ")));
    if let Some(error) = console.error() {
        return Err(error.to_string());
    }
    Ok(code)
}

/// Whether `dir` holds a search's shard (its `search-shard.json`).
pub fn is_search_shard(dir: &Path) -> bool {
    dir.join("search-shard.json").is_file()
}
