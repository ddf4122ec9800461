//! `softcbf verify`: many closed-loop runs drawn from the ranges a scenario's `[verify]`
//! table declares, across every core, summarised as `runs.csv`, `report.json` and figures.
//!
//! A run is a pure function of the scenario, the batch's seed and the run's index
//! ([`draw::draw`]): its safety mode and control period come from the index (the groups
//! of [`spec::VerifySpec`] in turn), its set point, initial state, plant numbers and sensor
//! noise from a generator seeded with [`draw::run_seed`]. So a batch can be cut into
//! disjoint slices (`--shard K/M`) that run anywhere, and [`table`] merges their rows into
//! the files one process would have written, byte for byte, whatever the thread count:
//! nothing in `runs.csv` or `report.json` depends on the machine or the clock (wall times
//! go to `timing.csv`).

pub mod cli;
pub mod draw;
pub mod figures;
pub mod report;
pub mod search;
pub mod spec;
pub mod start;
pub mod table;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use crate::model::Model;
use crate::sim::{TickCounts, simulate};
use crate::verify::draw::{Draw, draw};
use crate::verify::spec::VerifySpec;

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
    /// The thread pool could not be built.
    #[error("threads: {0}")]
    Threads(String),
}

/// Runs `runs` (indices of `spec`'s batch) on `model` with `threads` worker threads (0:
/// one per core), calling `progress(done, total)` from the workers as runs finish. Rows
/// come back in index order, whatever the thread count.
pub fn run_batch(
    model: &Model,
    spec: &VerifySpec,
    runs: std::ops::Range<usize>,
    threads: usize,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Vec<Finished>, VerifyError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| VerifyError::Threads(e.to_string()))?;
    let total = runs.len();
    let done = AtomicUsize::new(0);
    pool.install(|| {
        runs.into_par_iter()
            .map(|run| {
                let finished = run_one(model, spec, run);
                let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                progress(n, total);
                finished
            })
            .collect()
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
    let scenario = spec
        .scenario_for(model, &draw)
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
            let (lowest_barrier, lowest_label) = if s.counts.invalid_state > 0 {
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
