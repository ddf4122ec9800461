//! `runs.csv` (one row per run), `timing.csv` (wall times) and `shard.json` (which batch
//! and which slice of it a directory holds): written, read back exactly, and merged.
//!
//! Numbers are written in Rust's shortest round-trip form, so reading `runs.csv` back gives
//! the very rows that were written, and a merge rewrites them byte for byte.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use softcbf_description::uncertainty::ModuleFactors;

use crate::RunRow;
use crate::control::SafetyMode;
use crate::draw::Draw;
use crate::record::coordinate_names;
use crate::sim::TickCounts;

/// What identifies a batch: shards of one batch agree on all of it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Batch {
    /// The scenario file as given on the command line.
    pub scenario: String,
    /// Fingerprint of the scenario and robot files.
    pub fingerprint: String,
    /// The batch's seed.
    pub seed: u64,
    /// Runs in the whole batch.
    pub runs: usize,
    /// `--duration`, when the command line replaced the scenario's \[s\].
    pub duration: Option<f64>,
    /// A run whose lowest barrier falls below this is unsafe (m or rad).
    pub threshold: f64,
    /// The groups' names (safety mode @ rate), in order.
    pub groups: Vec<String>,
    /// Generalized coordinates of the robot.
    pub coordinates: usize,
}

/// `shard.json`: the batch and the slice of its runs a directory holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// The batch.
    pub batch: Batch,
    /// `[K, M]`: the K-th (from 0) of M slices.
    pub shard: [usize; 2],
    /// The runs held: `first..end`.
    pub first: usize,
    pub end: usize,
    /// The softcbf version that wrote it.
    pub software: String,
}

/// Why a table could not be written, read or merged.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    /// A file could not be read or written.
    #[error("{path}: {source}", path = path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A file's content is not what `softcbf verify` writes.
    #[error("{path}:{line}: {message}", path = path.display())]
    Format {
        path: PathBuf,
        line: usize,
        message: String,
    },
    /// Shards that do not add up to one batch.
    #[error("{0}")]
    Merge(String),
}

/// The runs of slice `shard` (0-based) of `slices` in a batch of `runs`: contiguous and
/// disjoint, together every run once, sizes differing by at most one.
pub fn shard_range(runs: usize, shard: usize, slices: usize) -> std::ops::Range<usize> {
    let at = |k: usize| (k as u128 * runs as u128 / slices.max(1) as u128) as usize;
    at(shard)..at(shard + 1)
}

/// The header of `runs.csv` for `coordinates` generalized coordinates.
pub fn header(coordinates: usize) -> Vec<String> {
    let names = coordinate_names(coordinates);
    let mut columns: Vec<String> = ["run", "seed", "safety", "control_period [s]"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    columns.extend(names.iter().map(|c| format!("set_point {c} [m]")));
    columns.extend(names.iter().map(|c| format!("initial {c} [m]")));
    columns.extend(names.iter().map(|c| format!("initial {c}/dt [m/s]")));
    for module in 1..=coordinates / 3 {
        for factor in [
            "bend stiffness",
            "axial stiffness",
            "bend damping",
            "axial damping",
            "mass",
        ] {
            columns.push(format!("module {module} {factor} factor"));
        }
    }
    columns.extend(
        [
            "noise_seed",
            "set_point_barrier [m]",
            "lowest_barrier [m]",
            "lowest_barrier_label",
            "lowest_barrier_t [s]",
            "set_point_error [m]",
            "max_abs_tau [N]",
            "ticks",
            "qp_solves",
            "active",
            "relaxed",
            "failed",
            "invalid_state",
            "uncertified",
            "integrator_steps",
            "stopped",
        ]
        .iter()
        .map(|s| s.to_string()),
    );
    columns
}

/// Text without the CSV's separators (commas, quotes, line ends become `;` or spaces).
fn plain(text: &str) -> String {
    text.chars()
        .map(|c| match c {
            ',' | '"' => ';',
            '\n' | '\r' => ' ',
            c => c,
        })
        .collect()
}

/// `runs.csv` for `rows` (in the order given) of a robot with `coordinates` coordinates:
/// [`runs_header`], then a [`run_line`] per row.
pub fn runs_csv(rows: &[RunRow], coordinates: usize) -> String {
    let mut text = runs_header(coordinates);
    for row in rows {
        text.push_str(&run_line(row));
    }
    text
}

/// The first line of `runs.csv` for `coordinates` coordinates, with its line end.
pub fn runs_header(coordinates: usize) -> String {
    header(coordinates).join(",") + "\n"
}

/// The line of `runs.csv` for `row`, with its line end: a batch appends its rows one by
/// one as they finish, the same bytes [`runs_csv`] writes.
pub fn run_line(row: &RunRow) -> String {
    let mut text = String::new();
    let d = &row.draw;
    let _ = write!(
        text,
        "{},{},{},{:?}",
        row.run,
        d.seed,
        d.safety.name(),
        d.control_period
    );
    for v in d.set_point.iter().chain(&d.initial_q).chain(&d.initial_qd) {
        let _ = write!(text, ",{v:?}");
    }
    for f in &d.factors {
        for v in [
            f.stiffness[0],
            f.stiffness[1],
            f.damping[0],
            f.damping[1],
            f.mass,
        ] {
            let _ = write!(text, ",{v:?}");
        }
    }
    let _ = writeln!(
        text,
        ",{},{:?},{:?},{},{:?},{:?},{:?},{},{},{},{},{},{},{},{},{}",
        d.noise_seed,
        row.set_point_barrier,
        row.lowest_barrier,
        plain(&row.lowest_label),
        row.lowest_t,
        row.set_point_error,
        row.max_abs_tau,
        row.counts.ticks,
        row.counts.qp_solves,
        row.counts.active,
        row.counts.relaxed,
        row.counts.failed,
        row.counts.invalid_state,
        row.counts.uncertified,
        row.integrator_steps,
        plain(&row.stopped),
    );
    text
}

/// Reads `runs.csv` text written by [`runs_csv`] for `coordinates` coordinates and
/// `groups` (names of the batch's groups, to find each row's group); `path` names the
/// file in errors.
pub fn read_runs(
    text: &str,
    path: &Path,
    coordinates: usize,
    groups: &[String],
) -> Result<Vec<RunRow>, TableError> {
    let format = |line: usize, message: String| TableError::Format {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut lines = text.lines();
    let expected = header(coordinates);
    let given = lines.next().unwrap_or("");
    if given != expected.join(",") {
        return Err(format(
            1,
            format!(
                "the header is not that of `softcbf verify`'s runs.csv for {coordinates} \
                 coordinates"
            ),
        ));
    }
    let modules = coordinates / 3;
    let mut rows = Vec::new();
    for (k, line) in lines.enumerate() {
        let number = k + 2;
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != expected.len() {
            return Err(format(
                number,
                format!("has {} fields, the header {}", fields.len(), expected.len()),
            ));
        }
        let mut at = 0;
        let mut next = || {
            let field = fields[at];
            let name = &expected[at];
            at += 1;
            (field, name)
        };
        let float = |(field, name): (&str, &String)| {
            field
                .parse::<f64>()
                .map_err(|_| format(number, format!("`{name}` is not a number: `{field}`")))
        };
        let whole = |(field, name): (&str, &String)| {
            field
                .parse::<u64>()
                .map_err(|_| format(number, format!("`{name}` is not a whole number: `{field}`")))
        };
        let run = whole(next())? as usize;
        let seed = whole(next())?;
        let (safety_text, _) = next();
        let safety = SafetyMode::parse(safety_text).map_err(|m| format(number, m))?;
        let control_period = float(next())?;
        let mut vector =
            |n: usize| -> Result<Vec<f64>, TableError> { (0..n).map(|_| float(next())).collect() };
        let set_point = vector(coordinates)?;
        let initial_q = vector(coordinates)?;
        let initial_qd = vector(coordinates)?;
        let mut factors = Vec::with_capacity(modules);
        for _ in 0..modules {
            let v = vector(5)?;
            factors.push(ModuleFactors {
                stiffness: [v[0], v[1]],
                damping: [v[2], v[3]],
                mass: v[4],
            });
        }
        let noise_seed = whole(next())?;
        let set_point_barrier = float(next())?;
        let lowest_barrier = float(next())?;
        let lowest_label = next().0.to_string();
        let lowest_t = float(next())?;
        let set_point_error = float(next())?;
        let max_abs_tau = float(next())?;
        let mut counts = [0usize; 8];
        for count in &mut counts {
            *count = whole(next())? as usize;
        }
        let stopped = next().0.to_string();
        let name = crate::spec::group_name(safety.name(), control_period);
        let group = groups.iter().position(|g| *g == name).ok_or_else(|| {
            format(
                number,
                format!(
                    "the group `{name}` is not one of the batch's ({})",
                    groups.join("; ")
                ),
            )
        })?;
        let [
            ticks,
            qp_solves,
            active,
            relaxed,
            failed,
            invalid_state,
            uncertified,
            integrator_steps,
        ] = counts;
        rows.push(RunRow {
            run,
            draw: Draw {
                seed,
                group,
                safety,
                control_period,
                set_point,
                initial_q,
                initial_qd,
                factors,
                noise_seed,
            },
            set_point_barrier,
            lowest_barrier,
            lowest_label,
            lowest_t,
            set_point_error,
            max_abs_tau,
            counts: TickCounts {
                ticks,
                qp_solves,
                active,
                relaxed,
                failed,
                invalid_state,
                uncertified,
                // runs.csv has no column per reason.
                uncertified_reasons: Default::default(),
                unfiltered: 0,
            },
            integrator_steps,
            stopped,
        });
    }
    Ok(rows)
}

/// The first line of `timing.csv`, with its line end.
pub const TIMING_HEADER: &str = "run,wall_time [s]\n";

/// `timing.csv`: each run's wall time \[s\] (differs from machine to machine, so it is kept
/// out of `runs.csv`).
pub fn timing_csv(runs: &[(usize, f64)]) -> String {
    let mut text = String::from(TIMING_HEADER);
    for &(run, wall) in runs {
        text.push_str(&timing_line(run, wall));
    }
    text
}

/// The line of `timing.csv` for run `run`, `wall` seconds, with its line end.
pub fn timing_line(run: usize, wall: f64) -> String {
    format!("{run},{wall:.6}\n")
}

/// Writes `text` to `path`.
pub fn write(path: &Path, text: &str) -> Result<(), TableError> {
    std::fs::write(path, text).map_err(|source| TableError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads `path` as text.
pub fn read(path: &Path) -> Result<String, TableError> {
    std::fs::read_to_string(path).map_err(|source| TableError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads the shard directories `dirs` and returns their batch and every run, in index
/// order, after checking that they belong to one batch and hold each of its runs once.
pub fn merge(dirs: &[PathBuf]) -> Result<(Batch, Vec<RunRow>), TableError> {
    let mut batch: Option<(Batch, PathBuf)> = None;
    let mut rows = Vec::new();
    for dir in dirs {
        let path = dir.join("shard.json");
        let text = read(&path)?;
        let manifest: Manifest = serde_json::from_str(&text).map_err(|e| TableError::Format {
            path: path.clone(),
            line: e.line(),
            message: format!("not a shard manifest of `softcbf verify`: {e}"),
        })?;
        match &batch {
            None => batch = Some((manifest.batch.clone(), path.clone())),
            Some((first, first_path)) if *first != manifest.batch => {
                return Err(TableError::Merge(format!(
                    "{} and {} belong to different batches ({}): merge only shards of one \
                     `softcbf verify` command",
                    first_path.display(),
                    path.display(),
                    difference(first, &manifest.batch)
                )));
            }
            Some(_) => {}
        }
        let csv = dir.join("runs.csv");
        let b = &manifest.batch;
        let shard_rows = read_runs(&read(&csv)?, &csv, b.coordinates, &b.groups)?;
        let expected = manifest.first..manifest.end;
        if shard_rows.len() != expected.len()
            || shard_rows
                .iter()
                .zip(expected.clone())
                .any(|(r, k)| r.run != k)
        {
            return Err(TableError::Merge(format!(
                "{} should hold runs {}..{} in order (shard.json), it holds {} rows: the \
                 shard did not finish; run its command again with --resume to finish it",
                csv.display(),
                expected.start,
                expected.end,
                shard_rows.len()
            )));
        }
        rows.extend(shard_rows);
    }
    let Some((batch, _)) = batch else {
        return Err(TableError::Merge("no shard directories given".into()));
    };
    rows.sort_by_key(|r| r.run);
    let mut missing = Vec::new();
    let mut next = 0;
    for row in &rows {
        if row.run < next {
            return Err(TableError::Merge(format!(
                "run {} is in two shards: give each shard once",
                row.run
            )));
        }
        if row.run > next {
            missing.push(format!("{}..{}", next, row.run));
        }
        next = row.run + 1;
    }
    if next < batch.runs {
        missing.push(format!("{}..{}", next, batch.runs));
    }
    if !missing.is_empty() {
        return Err(TableError::Merge(format!(
            "runs {} of the batch's {} are in none of the shards given",
            missing.join(", "),
            batch.runs
        )));
    }
    Ok((batch, rows))
}

/// The fields in which two batches differ, in words (`seed 1 vs 2; 100 vs 200 runs`).
pub fn difference(a: &Batch, b: &Batch) -> String {
    let mut parts = Vec::new();
    if a.scenario != b.scenario {
        parts.push(format!("scenario {} vs {}", a.scenario, b.scenario));
    }
    if a.fingerprint != b.fingerprint {
        parts.push(format!(
            "the scenario or robot files differ (fingerprint {} vs {})",
            a.fingerprint, b.fingerprint
        ));
    }
    if a.seed != b.seed {
        parts.push(format!("seed {} vs {}", a.seed, b.seed));
    }
    if a.runs != b.runs {
        parts.push(format!("{} vs {} runs", a.runs, b.runs));
    }
    if a.duration != b.duration {
        let text = |d: Option<f64>| d.map_or("the scenario's".to_string(), |d| format!("{d} s"));
        parts.push(format!(
            "duration {} vs {}",
            text(a.duration),
            text(b.duration)
        ));
    }
    if a.threshold != b.threshold {
        parts.push(format!("threshold {} vs {}", a.threshold, b.threshold));
    }
    if a.groups != b.groups {
        parts.push(format!(
            "groups {} vs {}",
            a.groups.join("; "),
            b.groups.join("; ")
        ));
    }
    if a.coordinates != b.coordinates {
        parts.push(format!(
            "{} vs {} coordinates",
            a.coordinates, b.coordinates
        ));
    }
    if parts.is_empty() {
        "settings differ".into()
    } else {
        parts.join("; ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_cover_the_batch_once_in_order() {
        for runs in [0, 1, 7, 100, 10_001] {
            for slices in [1, 2, 3, 16, 100] {
                let mut next = 0;
                for shard in 0..slices {
                    let range = shard_range(runs, shard, slices);
                    assert_eq!(range.start, next, "{runs} runs, shard {shard}/{slices}");
                    assert!(range.len() <= runs / slices + 1);
                    next = range.end;
                }
                assert_eq!(next, runs);
            }
        }
        // No overflow for the largest batches.
        assert_eq!(shard_range(usize::MAX, 1, 2).end, usize::MAX);
    }

    fn row(run: usize, lowest: f64) -> RunRow {
        RunRow {
            run,
            draw: Draw {
                seed: u64::MAX - run as u64,
                group: 1,
                safety: SafetyMode::Certified,
                control_period: 0.0303,
                set_point: vec![0.1 / 3.0, -1e-300, 0.0, 2.5e-7, -0.07, 1.0 / 7.0],
                initial_q: vec![0.0; 6],
                initial_qd: vec![-1.5, 0.0, 0.0, 0.0, 0.0, 3.0],
                factors: vec![
                    ModuleFactors {
                        stiffness: [0.9, 1.1],
                        damping: [1.0 + f64::EPSILON, 0.8],
                        mass: 1.2,
                    },
                    ModuleFactors::NOMINAL,
                ],
                noise_seed: 12345,
            },
            set_point_barrier: -0.0123,
            lowest_barrier: lowest,
            lowest_label: "module 1 corner 3".into(),
            lowest_t: 0.25,
            set_point_error: 1e-9,
            max_abs_tau: 500.4,
            counts: TickCounts {
                ticks: 100,
                qp_solves: 99,
                active: 50,
                relaxed: 1,
                failed: 0,
                invalid_state: 0,
                uncertified: 0,
                uncertified_reasons: Default::default(),
                unfiltered: 0,
            },
            integrator_steps: 300,
            stopped: String::new(),
        }
    }

    #[test]
    fn runs_read_back_bit_for_bit() {
        let rows = vec![row(0, -1e-7), row(1, f64::INFINITY), row(2, 3.0e-14)];
        let groups = vec![
            "paper @ 1000 Hz".to_string(),
            "certified @ 33.0 Hz".to_string(),
        ];
        let text = runs_csv(&rows, 6);
        let back = read_runs(&text, Path::new("runs.csv"), 6, &groups).expect("reads");
        assert_eq!(back, rows);
        assert_eq!(runs_csv(&back, 6), text);
        // A damaged file names its line and column.
        let damaged = text.replacen("0.25", "0.2x5", 1);
        let error = read_runs(&damaged, Path::new("runs.csv"), 6, &groups).unwrap_err();
        assert!(
            error
                .to_string()
                .starts_with("runs.csv:2: `lowest_barrier_t [s]`"),
            "{error}"
        );
        let short = text.replace(",300,", ",");
        let error = read_runs(&short, Path::new("runs.csv"), 6, &groups).unwrap_err();
        assert!(error.to_string().contains("fields, the header"), "{error}");
    }

    #[test]
    fn labels_and_reasons_keep_the_columns() {
        let mut r = row(0, 0.0);
        r.stopped = "plant integration failed: step, \"too small\"\nat t = 1".into();
        let text = runs_csv(&[r], 6);
        let groups = vec!["x".to_string(), "certified @ 33.0 Hz".to_string()];
        let back = read_runs(&text, Path::new("r.csv"), 6, &groups).expect("reads");
        assert_eq!(
            back[0].stopped,
            "plant integration failed: step; ;too small; at t = 1"
        );
    }
}
