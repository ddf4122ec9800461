//! `softcbf verify --search`: a falsifier. Instead of drawing a batch's runs uniformly,
//! it looks for the run with the lowest barrier: a cross-entropy method ([`cem`]) over
//! the variables of the scenario's `[verify]` table ([`space`]) — set point, initial
//! state, plant factors inside the declared uncertainty — whose score is the lowest
//! barrier over the run's dense record, as `softcbf verify` measures it
//! ([`crate::evaluate`]); a run whose state leaves the model's domain, or that
//! stops early, scores `-∞`.
//!
//! One search per group (safety mode × control period): each group gets its share of the
//! budget and its own worst case, so a mode that fails everywhere does not starve the
//! search of a mode that fails rarely. A search may also be split into independent
//! *islands* (`--islands M`, or `--shard K/M`: island K of M), each with its own seed and
//! share of the budget; their rows are joined island by island, so one process running M
//! islands and M shards merged give the same `search.csv`.
//!
//! A search is a function of the scenario, the robot, the seed, the budget, the islands
//! and the method's settings: candidates are drawn one generation at a time from each
//! island's and group's own generator, in a fixed order, and only their evaluation runs on
//! several threads.

pub mod cem;
pub mod cli;
pub mod replay;
pub mod report;
pub mod space;

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};

use crate::draw::{Draw, run_seed};
use crate::model::Model;
use crate::spec::{INITIAL_STATE_TRIES, VerifySpec};
use crate::table::shard_range;
use crate::{RunRow, VerifyError, evaluate};
use cem::{Cem, Scored, Settings};
use space::Space;

/// Draws from the search's Gaussian before a candidate whose start the guarantee does not
/// cover is drawn uniformly instead.
pub const START_TRIES: usize = 100;

/// One evaluated candidate: where in the search it came from and its run.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    /// Its island (from 0).
    pub island: usize,
    /// Its generation (0: the uniform one) and its place in it.
    pub generation: usize,
    pub candidate: usize,
    /// The run: `row.run` counts the runs of its island's search of its group, from 0;
    /// `row.draw.group` is the group.
    pub row: RunRow,
}

/// What a search reports while it runs.
#[derive(Clone, Copy, Debug)]
pub enum Event {
    /// A run finished.
    Run,
    /// A generation of every search finished; the lowest score so far.
    Generation { lowest: f64 },
}

/// The score of a run: its lowest barrier, `-∞` if its state left the model's domain, it
/// stopped early or the value is not a number.
pub fn score(row: &RunRow) -> f64 {
    if !row.stopped.is_empty() || row.lowest_barrier.is_nan() || row.counts.invalid_state > 0 {
        f64::NEG_INFINITY
    } else {
        row.lowest_barrier
    }
}

/// The runs of group `group` (of `groups`) on island `island` (of `islands`) in a search of
/// `runs` runs: the budget split evenly over the groups, each group's over the islands.
pub fn budget(runs: usize, groups: usize, group: usize, islands: usize, island: usize) -> usize {
    let per_group = shard_range(runs, group, groups).len();
    shard_range(per_group, island, islands).len()
}

/// The seed of the search of group `group` on island `island` of a search seeded `seed`.
pub fn search_seed(seed: u64, island: usize, group: usize) -> u64 {
    run_seed(run_seed(seed, island), group)
}

/// The search of one group on one island.
struct Search {
    island: usize,
    group: usize,
    budget: usize,
    spent: usize,
    seed: u64,
    cem: Cem,
    draws: Xoshiro256PlusPlus,
}

/// How a search is cut and tuned.
#[derive(Clone, Debug)]
pub struct Plan {
    /// Islands in the whole search.
    pub islands: usize,
    /// The islands this process runs.
    pub run_islands: std::ops::Range<usize>,
    /// The method's settings.
    pub settings: Settings,
}

impl Plan {
    /// The default settings for `space`, or with `population` candidates per generation.
    pub fn settings(space: &Space, population: Option<usize>) -> Settings {
        population.map_or_else(
            || Settings::for_dimension(space.dimension()),
            Settings::with_population,
        )
    }
}

/// Draws candidate `k` of `search`'s current generation: a point of the unit box whose
/// start the guarantee covers (drawn from the Gaussian up to [`START_TRIES`] times, then
/// uniformly up to [`INITIAL_STATE_TRIES`] times), decoded into a draw.
fn draw_candidate(
    model: &Model,
    spec: &VerifySpec,
    space: &Space,
    search: &mut Search,
    k: usize,
) -> Result<(Vec<f64>, Draw), String> {
    let d = space.dimension();
    let mut last = String::new();
    for attempt in 0..START_TRIES + INITIAL_STATE_TRIES {
        let x = if attempt < START_TRIES {
            search.cem.sample(&mut search.draws, k)
        } else {
            (0..d).map(|_| search.draws.random::<f64>()).collect()
        };
        // Seeds a scenario file can hold (a TOML integer is at most 2⁶³ − 1).
        let noise_seed = search.draws.random::<u64>() >> 1;
        let draw = space.decode(model, spec, search.group, &x, noise_seed, search.seed);
        match spec.start.problem(model, &draw.initial_q, &draw.initial_qd) {
            None => return Ok((x, draw)),
            Some(problem) => last = problem,
        }
    }
    Err(format!(
        "no candidate whose start the guarantee covers in {} draws (the last: {last}): move \
         the boxes `initial_q_min`..`initial_q_max`, `initial_qd_min`..`initial_qd_max` into \
         the safe set, slow the starts down",
        START_TRIES + INITIAL_STATE_TRIES
    ))
}

/// Runs the islands `plan.run_islands` of the search of `spec` on `model` with `threads`
/// worker threads (0: one per core), reporting `progress`. Returns every evaluated
/// candidate, island by island, group by group, in the order drawn.
pub fn run_search(
    model: &Model,
    spec: &VerifySpec,
    plan: &Plan,
    threads: usize,
    progress: &(dyn Fn(Event) + Sync),
) -> Result<Vec<Candidate>, VerifyError> {
    let threads = match threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    };
    let space = Space::new(model, spec);
    let groups = spec.groups.len();
    let mut searches: Vec<Search> = Vec::new();
    for island in plan.run_islands.clone() {
        for group in 0..groups {
            let seed = search_seed(spec.seed, island, group);
            searches.push(Search {
                island,
                group,
                budget: budget(spec.runs, groups, group, plan.islands, island),
                spent: 0,
                seed,
                cem: Cem::new(space.dimension(), plan.settings),
                draws: Xoshiro256PlusPlus::seed_from_u64(seed),
            });
        }
    }
    let mut found: Vec<Vec<Candidate>> = vec![Vec::new(); searches.len()];
    let mut lowest = f64::INFINITY;
    loop {
        // Draw every search's next generation, in order, on this thread.
        let mut jobs: Vec<(usize, usize, Vec<f64>, Draw)> = Vec::new();
        for (s, search) in searches.iter_mut().enumerate() {
            let n = plan.settings.population.min(search.budget - search.spent);
            for k in 0..n {
                let (x, draw) =
                    draw_candidate(model, spec, &space, search, k).map_err(|message| {
                        VerifyError::Run {
                            run: search.spent + k,
                            message,
                        }
                    })?;
                jobs.push((s, k, x, draw));
            }
        }
        if jobs.is_empty() {
            break;
        }
        // The generation on worker threads, each taking the next candidate in turn.
        let next = AtomicUsize::new(0);
        let slots: Vec<Mutex<Option<Result<RunRow, VerifyError>>>> =
            jobs.iter().map(|_| Mutex::new(None)).collect();
        std::thread::scope(|scope| {
            for _ in 0..threads.min(jobs.len()).max(1) {
                scope.spawn(|| {
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let Some((s, k, _, draw)) = jobs.get(i) else {
                            break;
                        };
                        let run = searches[*s].spent + k;
                        let row = evaluate(model, spec, run, draw.clone()).map(|f| f.row);
                        progress(Event::Run);
                        *slots[i].lock().unwrap_or_else(|e| e.into_inner()) = Some(row);
                    }
                });
            }
        });
        let rows: Vec<Result<RunRow, VerifyError>> = slots
            .into_iter()
            .map(|slot| {
                slot.into_inner()
                    .unwrap_or_else(|e| e.into_inner())
                    .unwrap_or_else(|| Err(VerifyError::Threads("a worker thread stopped".into())))
            })
            .collect();
        let mut scored: Vec<Vec<Scored>> = vec![Vec::new(); searches.len()];
        for ((s, k, x, _), row) in jobs.into_iter().zip(rows) {
            let row = row?;
            let search = &searches[s];
            let value = score(&row);
            lowest = lowest.min(value);
            scored[s].push(Scored {
                x,
                score: value,
                order: search.spent + k,
            });
            found[s].push(Candidate {
                island: search.island,
                generation: search.cem.generation(),
                candidate: k,
                row,
            });
        }
        for (search, scored) in searches.iter_mut().zip(scored) {
            if scored.is_empty() {
                continue;
            }
            search.spent += scored.len();
            search.cem.tell(scored);
        }
        progress(Event::Generation { lowest });
    }
    Ok(found.into_iter().flatten().collect())
}
