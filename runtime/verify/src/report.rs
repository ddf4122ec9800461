//! `report.json`: what a batch found, per group and overall (counts of unsafe, stopped,
//! relaxed and failed runs, quantiles of the lowest barrier and the set-point error) and
//! its worst runs with the command that replays each. A function of the rows alone,
//! written ([`report_json`]) and read back ([`read_report`]) through [`Report`].

use std::path::Path;

use serde::{Deserialize, Deserializer, Serialize};

use crate::RunRow;
use crate::table::{Batch, TableError, read};
use crate::verdict::{Limits, judge};

/// Worst runs listed per group.
pub const WORST_PER_GROUP: usize = 5;

/// Quantiles of one number over runs (nearest rank; `null` in JSON without runs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quantiles {
    #[serde(deserialize_with = "number_or_null")]
    pub min: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub q01: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub q05: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub median: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub q95: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub q99: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub max: f64,
}

/// A number of `report.json`, where JSON's `null` stands for a number that was not finite
/// (serde_json writes NaN and ±∞ as `null`): read back as NaN.
fn number_or_null<'de, D: Deserializer<'de>>(deserializer: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(deserializer)?.unwrap_or(f64::NAN))
}

/// What the runs of one group (or of all) did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroupReport {
    /// `sampled @ 33.3 Hz`, or `all`.
    pub name: String,
    /// Runs in the group.
    pub runs: usize,
    /// Unsafe runs ([`is_unsafe`]: lowest barrier below the threshold, state outside the
    /// model's domain, a failed QP, or stopped early), and their fraction.
    pub unsafe_runs: usize,
    pub unsafe_fraction: f64,
    /// Of those, runs whose set point lay inside the safe set (the filter had a safe
    /// target and still let a barrier go below the threshold).
    pub unsafe_with_set_point_inside: usize,
    /// Runs that stopped early (the plant integration failed).
    pub stopped: usize,
    /// Runs with at least one relaxed, failed or invalid-state tick.
    pub with_relaxed: usize,
    pub with_failed_qp: usize,
    pub with_invalid_state: usize,
    /// The lowest barrier over each run (m or rad).
    pub lowest_barrier: Option<Quantiles>,
    /// `‖q − q̄‖` at each run's end \[m\].
    pub set_point_error: Option<Quantiles>,
}

/// One of the worst runs of a group.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WorstRun {
    pub run: usize,
    pub seed: u64,
    pub group: String,
    /// Its lowest barrier, which barrier, and when \[s\].
    #[serde(deserialize_with = "number_or_null")]
    pub lowest_barrier: f64,
    pub barrier: String,
    #[serde(deserialize_with = "number_or_null")]
    pub t: f64,
    /// Its set point \[m\] and the lowest barrier there.
    pub set_point: Vec<f64>,
    #[serde(deserialize_with = "number_or_null")]
    pub set_point_barrier: f64,
    /// The command that runs it again alone, with figures and the 3-D view.
    pub replay: String,
}

/// `report.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Report {
    pub scenario: String,
    pub seed: u64,
    pub runs: usize,
    pub threshold: f64,
    /// Every run together, then each group.
    pub all: GroupReport,
    pub groups: Vec<GroupReport>,
    /// The lowest runs of each group, lowest first.
    pub worst: Vec<WorstRun>,
}

/// Nearest-rank quantiles of the finite `values` (`None` if there are none).
pub fn quantiles(values: impl Iterator<Item = f64>) -> Option<Quantiles> {
    let mut v: Vec<f64> = values.filter(|x| !x.is_nan()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let at = |p: f64| v[((p * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1];
    Some(Quantiles {
        min: v[0],
        q01: at(0.01),
        q05: at(0.05),
        median: at(0.5),
        q95: at(0.95),
        q99: at(0.99),
        max: v[v.len() - 1],
    })
}

/// Whether a run is unsafe: the verdict on its row ([`crate::verdict::judge`]) is not
/// safe: its lowest barrier below `threshold` (or not a number, or its state left the
/// model's domain), ticks without a verified command, or the run stopped early.
pub fn is_unsafe(row: &RunRow, threshold: f64) -> bool {
    !judge(&row.outcome(), &Limits::new(threshold)).is_safe()
}

fn group_report(name: String, rows: &[&RunRow], threshold: f64) -> GroupReport {
    let count = |f: &dyn Fn(&RunRow) -> bool| rows.iter().filter(|r| f(r)).count();
    let is_unsafe = |r: &RunRow| is_unsafe(r, threshold);
    let unsafe_runs = count(&is_unsafe);
    GroupReport {
        name,
        runs: rows.len(),
        unsafe_runs,
        unsafe_fraction: unsafe_runs as f64 / rows.len().max(1) as f64,
        unsafe_with_set_point_inside: count(&|r| is_unsafe(r) && r.set_point_barrier >= 0.0),
        stopped: count(&|r| !r.stopped.is_empty()),
        with_relaxed: count(&|r| r.counts.relaxed > 0),
        with_failed_qp: count(&|r| r.counts.failed > 0),
        with_invalid_state: count(&|r| r.counts.invalid_state > 0),
        lowest_barrier: quantiles(rows.iter().map(|r| r.lowest_barrier)),
        set_point_error: quantiles(rows.iter().map(|r| r.set_point_error)),
    }
}

/// The command that replays run `run` of `batch` into `verify-run-<run>/`.
pub fn replay_command(batch: &Batch, run: usize) -> String {
    let scenario =
        softcbf_description::toml_file::shell_word(std::path::Path::new(&batch.scenario));
    let duration = batch
        .duration
        .map_or(String::new(), |d| format!(" --duration {d}"));
    format!(
        "softcbf verify replay --scenario {scenario} --seed {}{duration} --run {run} --out \
         verify-run-{run}",
        batch.seed
    )
}

/// The report of `rows` (every run of `batch`, in index order).
pub fn report(batch: &Batch, rows: &[RunRow]) -> Report {
    let all: Vec<&RunRow> = rows.iter().collect();
    let groups = batch
        .groups
        .iter()
        .enumerate()
        .map(|(g, name)| {
            let members: Vec<&RunRow> = rows.iter().filter(|r| r.draw.group == g).collect();
            group_report(name.clone(), &members, batch.threshold)
        })
        .collect();
    let mut worst = Vec::new();
    for (g, name) in batch.groups.iter().enumerate() {
        let mut members: Vec<&RunRow> = rows.iter().filter(|r| r.draw.group == g).collect();
        // Lowest first (NaN counts as lowest), ties by index.
        members.sort_by(|a, b| {
            let key = |r: &RunRow| {
                if r.lowest_barrier.is_nan() {
                    f64::NEG_INFINITY
                } else {
                    r.lowest_barrier
                }
            };
            key(a).total_cmp(&key(b)).then(a.run.cmp(&b.run))
        });
        worst.extend(members.iter().take(WORST_PER_GROUP).map(|r| WorstRun {
            run: r.run,
            seed: r.draw.seed,
            group: name.clone(),
            lowest_barrier: r.lowest_barrier,
            barrier: r.lowest_label.clone(),
            t: r.lowest_t,
            set_point: r.draw.set_point.clone(),
            set_point_barrier: r.set_point_barrier,
            replay: replay_command(batch, r.run),
        }));
    }
    Report {
        scenario: batch.scenario.clone(),
        seed: batch.seed,
        runs: rows.len(),
        threshold: batch.threshold,
        all: group_report("all".into(), &all, batch.threshold),
        groups,
        worst,
    }
}

/// `report.json`'s text (pretty, ending in a line end).
pub fn report_json(report: &Report) -> String {
    let mut text = serde_json::to_string_pretty(report).unwrap_or_default();
    text.push('\n');
    text
}

/// Reads `report.json` written by [`report_json`] (a number written as `null`, not finite
/// when written, reads as NaN).
pub fn read_report(path: &Path) -> Result<Report, TableError> {
    let text = read(path)?;
    serde_json::from_str(&text).map_err(|e| TableError::Format {
        path: path.to_path_buf(),
        line: e.line(),
        message: format!("not the report.json of a `softcbf verify` batch: {e}"),
    })
}
