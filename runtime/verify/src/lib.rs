//! `softcbf verify`: many closed-loop runs drawn from the ranges a scenario's `[verify]`
//! table declares, across every core, summarised as `runs.csv`, `report.json` and figures;
//! rows are written as runs finish, in index order ([`directory`]), so an interrupted batch
//! keeps them and `--resume` continues it.
//!
//! A run is a pure function of the scenario, the batch's seed and the run's index
//! ([`draw::draw`]): its safety mode and control period come from the index (the groups
//! of [`spec::VerifySpec`] in turn), its set point, initial state, plant numbers and sensor
//! noise from a generator seeded with [`draw::run_seed`]. So a batch can be cut into
//! disjoint slices (`--shard K/M`) that run anywhere, and [`table`] merges their rows into
//! the files one process would have written, byte for byte, whatever the thread count:
//! nothing in `runs.csv` or `report.json` depends on the machine or the clock (wall times
//! go to `timing.csv`).

// The lower crates' modules at the root, so that the paths the files had in `softcbf`
// (`crate::model`, `crate::output`, …) keep resolving.
use softcbf_core::{
    control, exit, model, noise, record, reference, robot_file, scenario, settings, sim, verdict,
};
use softcbf_figures::plot;
use softcbf_outputs::{mcap_log, output, signal};

pub mod cli;
pub mod directory;
pub mod draw;
pub mod figures;
pub mod report;
pub mod search;
pub mod spec;
pub mod start;
pub mod table;

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Instant;

use crate::draw::{Draw, draw};
use crate::model::Model;
use crate::sim::{TickCounts, simulate};
use crate::spec::VerifySpec;
use crate::verdict::{Lowest, Outcome};

/// The outcome of one run: what it was given and what it did. One row of `runs.csv`.
#[derive(Clone, Debug, PartialEq)]
pub struct RunRow {
    /// Index of the run in the batch (0-based).
    pub run: usize,
    /// What was drawn for it.
    pub draw: Draw,
    /// The lowest barrier at the set point (m, or rad for a bend limit): how far inside the
    /// safe set the set point lies (negative: outside it, the filter must stop short).
    pub set_point_barrier: f64,
    /// The lowest barrier over the run's dense record, its barrier's label and when \[s\]
    /// (`-∞` and [`INVALID_STATE`] if the sampled state left the model's domain).
    pub lowest_barrier: f64,
    pub lowest_label: String,
    pub lowest_t: f64,
    /// `‖q − q̄‖₂` at the end \[m\].
    pub set_point_error: f64,
    /// Largest `|τ_i|` applied \[N\].
    pub max_abs_tau: f64,
    /// The controller's outcomes (ticks, QP solves, active, relaxed and failed solves,
    /// ticks with an invalid state).
    pub counts: TickCounts,
    /// Accepted integrator steps.
    pub integrator_steps: usize,
    /// Why the run stopped early (empty: it reached its duration).
    pub stopped: String,
}

impl RunRow {
    /// What the run did, for its verdict ([`crate::verdict::judge`]): the verdict of the
    /// run's own simulation (`softcbf verify replay`), since a state outside the model's
    /// domain is its lowest barrier `-∞` here.
    pub fn outcome(&self) -> Outcome<'_> {
        let c = &self.counts;
        Outcome {
            ticks: c.ticks as u64,
            lowest: Lowest {
                value: self.lowest_barrier,
                label: &self.lowest_label,
                unit: "",
                t: self.lowest_t,
            },
            invalid_rows: 0,
            rows: 0,
            invalid_ticks: c.invalid_state as u64,
            failed_ticks: c.failed as u64,
            unfiltered_ticks: c.unfiltered as u64,
            relaxed_ticks: c.relaxed as u64,
            stopped: (!self.stopped.is_empty()).then_some(self.stopped.as_str()),
            overruns: None,
        }
    }
}

/// The label of a run's lowest barrier when its state left the model's domain (its lowest
/// barrier is then `-∞`).
pub const INVALID_STATE: &str = "invalid state (outside the model's domain)";

/// A finished run and its wall time \[s\] (kept apart: it is the one thing that differs
/// from machine to machine).
pub struct Finished {
    /// The run's row.
    pub row: RunRow,
    /// Wall time of the run \[s\].
    pub wall_time: f64,
}

/// Why a run could not be made at all (not a run that went badly: that is a row).
#[derive(Debug, thiserror::Error)]
pub enum VerifyError {
    /// The run's draws could not be turned into a scenario.
    #[error("run {run}: {message}")]
    Run { run: usize, message: String },
    /// A worker thread could not be started.
    #[error("threads: {0}")]
    Threads(String),
    /// A finished run could not be written.
    #[error("{0}")]
    Output(String),
}

/// How a batch's slice ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BatchEnd {
    /// Runs finished and given to the sink, from the slice's first on.
    pub finished: usize,
    /// Whether `stop` ended it before its last run.
    pub interrupted: bool,
}

/// Runs `runs` (indices of `spec`'s batch) on `model` with `threads` worker threads (at
/// least one, at most one per run), each taking the next index in order, and gives every
/// finished run to `sink` on the calling thread in index order, as soon as the runs before
/// it have finished. Once `stop` is set no run starts, the runs under way finish and are
/// given to `sink`, so the runs given are always the first of the slice. A run that cannot
/// be made, or a `sink` that fails, ends the batch the same way with its error.
pub fn run_batch(
    model: &Model,
    spec: &VerifySpec,
    runs: std::ops::Range<usize>,
    threads: usize,
    stop: &AtomicBool,
    sink: &mut dyn FnMut(Finished) -> Result<(), String>,
) -> Result<BatchEnd, VerifyError> {
    let threads = threads.clamp(1, runs.len().max(1));
    let next = AtomicUsize::new(runs.start);
    let failed = AtomicBool::new(false);
    let (tx, rx) = mpsc::channel::<Result<Finished, VerifyError>>();
    let mut error = None;
    let mut given = 0;
    std::thread::scope(|scope| -> Result<(), VerifyError> {
        for k in 0..threads {
            let tx = tx.clone();
            let (next, failed, end) = (&next, &failed, runs.end);
            std::thread::Builder::new()
                .name(format!("verify-{k}"))
                .spawn_scoped(scope, move || {
                    while !stop.load(Ordering::SeqCst) && !failed.load(Ordering::SeqCst) {
                        let run = next.fetch_add(1, Ordering::SeqCst);
                        if run >= end {
                            break;
                        }
                        if tx.send(run_one(model, spec, run)).is_err() {
                            break;
                        }
                    }
                })
                .map_err(|e| VerifyError::Threads(e.to_string()))?;
        }
        drop(tx);
        // Runs that finished before an earlier one, held until it has.
        let mut waiting = BTreeMap::new();
        let mut expected = runs.start;
        for finished in rx {
            match finished {
                Ok(finished) => {
                    waiting.insert(finished.row.run, finished);
                }
                Err(e) => {
                    failed.store(true, Ordering::SeqCst);
                    error.get_or_insert(e);
                }
            }
            while error.is_none()
                && let Some(finished) = waiting.remove(&expected)
            {
                if let Err(message) = sink(finished) {
                    failed.store(true, Ordering::SeqCst);
                    error = Some(VerifyError::Output(message));
                    break;
                }
                expected += 1;
                given += 1;
            }
        }
        Ok(())
    })?;
    if let Some(error) = error {
        return Err(error);
    }
    Ok(BatchEnd {
        finished: given,
        interrupted: given < runs.len(),
    })
}

/// Makes run `run` of `spec`'s batch on `model`.
pub fn run_one(model: &Model, spec: &VerifySpec, run: usize) -> Result<Finished, VerifyError> {
    let start = Instant::now();
    let draw = draw(model, spec, run).map_err(|message| VerifyError::Run { run, message })?;
    let mut finished = evaluate(model, spec, run, draw)?;
    finished.wall_time = start.elapsed().as_secs_f64();
    Ok(finished)
}

/// Runs the closed loop `draw` describes (its group's scenario with its set point, start,
/// plant and noise) on `model` and returns its row, numbered `run`. The same function for
/// a batch's draws and a search's candidates, so that both measure the lowest barrier
/// alike.
pub fn evaluate(
    model: &Model,
    spec: &VerifySpec,
    run: usize,
    draw: Draw,
) -> Result<Finished, VerifyError> {
    let start = Instant::now();
    let scenario = draw
        .scenario(spec, model)
        .map_err(|message| VerifyError::Run { run, message })?;
    let mut set_point_barriers = vec![0.0; model.nb()];
    model
        .generated
        .barriers(&model.params, &draw.set_point, &mut set_point_barriers);
    let set_point_barrier = set_point_barriers
        .iter()
        .fold(f64::INFINITY, |m, &b| if b.is_nan() { m } else { m.min(b) });
    let outcome = simulate(model, &scenario, true, &mut |_| {});
    let row = match outcome {
        Ok(result) => {
            let s = &result.summary;
            // A state outside the model's domain has no barrier values (the record holds
            // NaN there, which the lowest skips): the run is counted as the lowest of all.
            let (lowest_barrier, lowest_label) = if s.counts.invalid_state + s.invalid_rows > 0 {
                (f64::NEG_INFINITY, INVALID_STATE.to_string())
            } else {
                (s.min_barrier.value, s.min_barrier.label.to_string())
            };
            RunRow {
                run,
                set_point_barrier,
                lowest_barrier,
                lowest_label,
                lowest_t: s.min_barrier.t,
                set_point_error: s.set_point_error,
                max_abs_tau: s.max_abs_tau,
                counts: s.counts.clone(),
                integrator_steps: s.integrator_steps,
                stopped: s.stopped.clone().unwrap_or_default(),
                draw,
            }
        }
        Err(error) => {
            return Err(VerifyError::Run {
                run,
                message: error.to_string(),
            });
        }
    };
    Ok(Finished {
        row,
        wall_time: start.elapsed().as_secs_f64(),
    })
}
