//! The closed-loop simulator: the controller ticks at a fixed period on the sampled state,
//! its command is held (zero-order hold) while the plant is integrated to the next tick.
//!
//! One run fills a [`Record`] (one row per tick, the last at `t = duration`, whose command is
//! computed and logged but not applied; each row ends with the tick's `status` and `reason`,
//! [`crate::record::status`]) and a [`RunSummary`]. With a record period
//! ([`Scenario::record_period`]) the plant is integrated from one recorded instant to the
//! next and rows between ticks hold the plant's state, the barriers the controller's model
//! gives there, and the held `τ` and the tick's `τ_nom`; the lowest barrier is taken over
//! every row. The plant may integrate another robot of the same structure
//! ([`Scenario::plant`]) than the one the controller uses. A failure of the plant
//! integration ends the run early; the record and summary keep what happened up to it and
//! [`RunSummary::stopped`] says why. With [`Scenario::sensor_noise`] the controller is given
//! a noisy sample of the state; the record and the lowest barrier keep the plant's own.
//! Nothing allocates inside the loop.

use std::path::Path;
use std::time::{Duration, Instant};

use serde::Serialize;
use softcbf_description::barriers::KIND_GROUPS;
use softcbf_generated::{BarrierInfo, BarrierKind, KindGroup};

use rand::SeedableRng;
use rand::rngs::Xoshiro256PlusPlus;

use crate::control::{self, Controller, ControllerError, TickStatus};
use crate::integrator::IntegratorError;
use crate::model::{Model, ModelError};
use crate::noise::{SensorNoise, standard_normal};
use crate::plant::Plant;
use crate::record::{Columns, Record, RecordError, Row, status};
use crate::reference::ReferenceSignal;
use crate::reference::ReferenceSpec;
use crate::scenario::{Scenario, between_ticks, structure_difference};
use crate::settings::{
    Described, IntegratorReport, SettingsReport, Sourced, file_name, software, vector_text,
};
use crate::verdict::{Lowest, Outcome};

/// Why a run could not start.
#[derive(Debug, thiserror::Error)]
pub enum SimulationError {
    /// The controller could not be built from the scenario's settings.
    #[error(transparent)]
    Controller(#[from] ControllerError),
    /// The integrator settings were refused.
    #[error("integrator: {0}")]
    Integrator(#[from] IntegratorError),
    /// The record could not be laid out.
    #[error("record: {0}")]
    Record(#[from] RecordError),
    /// The scenario's vectors do not fit the model.
    #[error("scenario has vectors of length {got}, the robot has {expected} coordinates")]
    Size { expected: usize, got: usize },
    /// The plant robot has no generated model.
    #[error("plant: {0}")]
    PlantModel(#[from] ModelError),
    /// The plant robot's structure is not the controller's robot's.
    #[error("plant {file}: {difference}")]
    PlantStructure {
        /// The plant robot's file.
        file: String,
        /// What differs.
        difference: String,
    },
}

/// The lowest barrier value seen in a recorded row (at a tick, or between ticks in a dense
/// record).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BarrierMinimum {
    /// `min_k b_k(t)` over the recorded rows, in [`BarrierMinimum::unit`].
    pub value: f64,
    /// Index of that barrier in the model's barrier table (0-based).
    pub barrier: usize,
    /// Its module (1-based, base first; 0 before any barrier was seen).
    pub module: usize,
    /// Its point on the module, for a plate corner the corner (1-based; 0 before any and
    /// for a barrier of another kind).
    pub corner: usize,
    /// Its name in the barrier table, e.g. `module 1 corner 3` (empty before any).
    pub label: &'static str,
    /// Its kind, as `softcbf model` names it (`plate_corner`, `bend`, `sphere`, …; empty
    /// before any).
    pub kind: &'static str,
    /// The unit of `value`: `m`, or `rad` for a bend limit.
    pub unit: &'static str,
    /// When \[s\].
    pub t: f64,
}

impl BarrierMinimum {
    /// Nothing seen yet: an infinite value owned by no barrier.
    pub fn none() -> BarrierMinimum {
        BarrierMinimum {
            value: f64::INFINITY,
            barrier: 0,
            module: 0,
            corner: 0,
            label: "",
            kind: "",
            unit: "m",
            t: 0.0,
        }
    }

    /// Barrier `k` of `table` at `value`, time `t`.
    pub fn of(table: &[BarrierInfo], k: usize, value: f64, t: f64) -> BarrierMinimum {
        let (module, corner, label) = owner(table, k);
        let kind = table.get(k).map(|b| b.kind);
        BarrierMinimum {
            value,
            barrier: k,
            module,
            corner,
            label,
            kind: kind.map_or("", BarrierKind::key),
            unit: kind.map_or("m", BarrierKind::unit),
            t,
        }
    }
}

/// The lowest barrier of each kind group a model has ([`KindGroup`]: plate corners,
/// elongation limits, bend limits, obstacles), kept in place over a run (no allocation per
/// tick). In `summary.json` it is an object keyed by [`KindGroup::key`] holding only the
/// groups the model has: `"lowest_by_kind": {"bend": {…}, "plate_corner": {…}}`, each a
/// [`BarrierMinimum`].
#[derive(Clone, Debug, PartialEq)]
pub struct LowestByKind {
    /// Per entry of [`KIND_GROUPS`]: `None` if the model has no barrier of that group.
    groups: [Option<BarrierMinimum>; KIND_GROUPS.len()],
}

/// The position of `group` in [`KIND_GROUPS`].
fn group_index(group: KindGroup) -> usize {
    KIND_GROUPS
        .iter()
        .position(|&g| g == group)
        .unwrap_or_default()
}

impl LowestByKind {
    /// Nothing seen yet, for the groups the barriers of `table` fall in.
    pub fn new(table: &[BarrierInfo]) -> LowestByKind {
        let mut groups: [Option<BarrierMinimum>; KIND_GROUPS.len()] = Default::default();
        for info in table {
            groups[group_index(info.kind.group())].get_or_insert_with(|| BarrierMinimum {
                unit: info.kind.unit(),
                ..BarrierMinimum::none()
            });
        }
        LowestByKind { groups }
    }

    /// Barrier `k` of `table` at `value`, time `t`: kept if below its group's lowest so far
    /// (a NaN never is; a caller that counts it as the lowest passes `-∞`).
    pub fn observe(&mut self, table: &[BarrierInfo], k: usize, value: f64, t: f64) {
        let Some(info) = table.get(k) else {
            return;
        };
        if let Some(lowest) = &mut self.groups[group_index(info.kind.group())]
            && value < lowest.value
        {
            *lowest = BarrierMinimum::of(table, k, value, t);
        }
    }

    /// Every barrier of `values` (one per row of `table`) at time `t`.
    pub fn observe_all(&mut self, table: &[BarrierInfo], values: &[f64], t: f64) {
        for (k, &value) in values.iter().enumerate() {
            self.observe(table, k, value, t);
        }
    }

    /// The lowest barrier of `group`, if the model has that group.
    pub fn get(&self, group: KindGroup) -> Option<&BarrierMinimum> {
        self.groups[group_index(group)].as_ref()
    }

    /// The groups the model has with their lowest barriers, in the order of [`KIND_GROUPS`].
    pub fn iter(&self) -> impl Iterator<Item = (KindGroup, &BarrierMinimum)> + '_ {
        KIND_GROUPS
            .iter()
            .zip(&self.groups)
            .filter_map(|(&group, lowest)| Some((group, lowest.as_ref()?)))
    }

    /// Number of groups the model has.
    pub fn len(&self) -> usize {
        self.groups.iter().flatten().count()
    }

    /// Whether the model has no barrier at all.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The per-group part of a printed summary, when the model has more groups than one:
    /// `lowest per kind: plate corners 1.000e-3 m (module 1 corner 3, t = 0.120 s), bend
    /// limits …`; `None` for a model with plate corners only.
    pub fn line(&self) -> Option<String> {
        if self.len() < 2 {
            return None;
        }
        let parts: Vec<String> = self
            .iter()
            .map(|(group, b)| {
                if b.value.is_finite() || b.value == f64::NEG_INFINITY {
                    format!(
                        "{} {:.3e} {} ({}, t = {:.3} s)",
                        group.title(),
                        b.value,
                        b.unit,
                        b.label,
                        b.t
                    )
                } else {
                    format!("{} not seen", group.title())
                }
            })
            .collect();
        Some(format!("lowest per kind: {}", parts.join(", ")))
    }
}

impl Serialize for LowestByKind {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = serializer.serialize_map(Some(self.len()))?;
        for (group, lowest) in self.iter() {
            map.serialize_entry(group.key(), lowest)?;
        }
        map.end()
    }
}

/// How often one barrier's row was relaxed.
#[derive(Clone, Debug, Serialize)]
pub struct RelaxedBarrier {
    /// Index in the model's barrier table (0-based).
    pub barrier: usize,
    /// Module (1-based) and point on it, for a plate corner the corner (1-based).
    pub module: usize,
    pub corner: usize,
    /// Its name in the barrier table.
    pub label: &'static str,
    /// Ticks in which its row was relaxed.
    pub ticks: usize,
}

/// Module and point (both 1-based) and label of barrier `k` of `table`.
fn owner(table: &[BarrierInfo], k: usize) -> (usize, usize, &'static str) {
    table.get(k).map_or((0, 0, ""), |b| {
        (b.module + 1, b.corner().map_or(0, |j| j + 1), b.label)
    })
}

/// How many barriers each of `modules` modules owns, in module order (the split the
/// figures draw barriers by).
pub fn barriers_per_module(table: &[BarrierInfo], modules: usize) -> Vec<usize> {
    let mut counts = vec![0; modules];
    for b in table {
        if let Some(count) = counts.get_mut(b.module) {
            *count += 1;
        }
    }
    counts
}

/// Counts of the controller's outcomes over a run.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct TickCounts {
    /// Ticks run.
    pub ticks: usize,
    /// QP solves (ticks with the filter on and a valid state).
    pub qp_solves: usize,
    /// Solves with at least one active barrier row.
    pub active: usize,
    /// Solves that had to relax some barrier rows (infeasible rows).
    pub relaxed: usize,
    /// Solves without a verified solution (safe command applied).
    pub failed: usize,
    /// Ticks whose state or model was not finite (safe command applied).
    pub invalid_state: usize,
    /// Ticks whose command could not be certified over its hold (the certified mode's
    /// [`TickStatus::Uncertified`]).
    pub uncertified: usize,
    /// Those ticks per reason.
    pub uncertified_reasons: crate::control::UncertifiedCounts,
    /// Ticks run without the safety filter (plain PD+; not in `runs.csv`, whose runs are
    /// all filtered).
    pub unfiltered: usize,
}

/// What `summary.json` holds for one run.
#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    /// `"filter"` (HOCBF-QP) or `"pd"` (plain PD+).
    pub controller: &'static str,
    /// Scenario name.
    pub scenario: String,
    /// Robot name.
    pub robot: String,
    /// Simulated time reached \[s\].
    pub duration: f64,
    /// Control period \[s\].
    pub control_period: f64,
    /// Time between recorded rows \[s\] (`None`: one row per tick).
    pub record_period: Option<f64>,
    /// Whether rows were recorded between ticks (a record period shorter than the control
    /// period): then the lowest barriers below are over those rows too.
    pub dense: bool,
    /// Lowest barrier value in a recorded row whose barriers are all numbers, and which
    /// barrier (rows with an invalid state are counted in `invalid_rows` instead).
    pub min_barrier: BarrierMinimum,
    /// Recorded rows whose barriers were not all numbers (a state outside the model's
    /// domain), and the rows recorded.
    pub invalid_rows: usize,
    pub rows: usize,
    /// Lowest barrier value in a recorded row of each kind group the model has.
    pub lowest_by_kind: LowestByKind,
    /// Final `q` \[m\].
    pub final_q: Vec<f64>,
    /// Final reference `q̄` \[m\].
    pub set_point: Vec<f64>,
    /// `‖q − q̄‖₂` at the end \[m\].
    pub set_point_error: f64,
    /// Largest `|τ_i|` applied \[N\].
    pub max_abs_tau: f64,
    /// Controller outcomes.
    pub counts: TickCounts,
    /// Barriers whose rows were relaxed, with how often.
    pub relaxed_barriers: Vec<RelaxedBarrier>,
    /// Accepted integrator steps, rejected attempts, right-hand sides and `W` factorizations.
    pub integrator_steps: usize,
    pub integrator_rejected: usize,
    pub integrator_rhs_evals: usize,
    pub integrator_w_factorizations: usize,
    /// Wall time of the whole run \[s\], of the control ticks and of the integration.
    pub wall_time: f64,
    pub control_time: f64,
    pub integration_time: f64,
    /// Simulated seconds per wall-clock second.
    pub real_time_factor: f64,
    /// Why the run ended early (`None`: it reached the duration).
    pub stopped: Option<String>,
    /// Every setting the run used, with where it came from.
    pub settings: SettingsReport,
}

impl RunSummary {
    /// What the run did, for its verdict ([`crate::verdict::judge`]).
    pub fn outcome(&self) -> Outcome<'_> {
        let b = &self.min_barrier;
        let c = &self.counts;
        let computed = c.ticks.saturating_sub(c.invalid_state);
        Outcome {
            ticks: c.ticks as u64,
            lowest: Lowest {
                value: b.value,
                label: b.label,
                unit: b.unit,
                t: b.t,
            },
            invalid_rows: self.invalid_rows as u64,
            rows: self.rows as u64,
            invalid_ticks: c.invalid_state as u64,
            failed_ticks: c.failed as u64,
            unfiltered_ticks: c.unfiltered.min(computed) as u64,
            relaxed_ticks: c.relaxed as u64,
            stopped: self.stopped.as_deref(),
            overruns: None,
        }
    }
}

/// Every setting a run of `scenario` on `model` uses, with the filter on or off, and where
/// each came from.
pub fn settings_report(model: &Model, scenario: &Scenario, filter: bool) -> SettingsReport {
    let sources = &scenario.sources;
    let robot = &model.robot;
    let reference = match &scenario.reference {
        ReferenceSpec::SetPoint(q) => format!("set point {}", vector_text(q)),
        ReferenceSpec::Waypoints(points) => format!(
            "{} waypoints from t = {} s to {} s",
            points.len(),
            points.first().map_or(0.0, |p| p.0),
            points.last().map_or(0.0, |p| p.0)
        ),
    };
    // A run whose filter differs from the scenario's is the PD+ comparison, which the
    // `compare` setting asked for.
    let filter_source = if filter == scenario.controller.filter {
        sources.filter
    } else {
        sources.compare
    };
    let tolerances = &scenario.tolerances;
    SettingsReport {
        software: software(),
        robot: Described {
            name: robot.name.clone(),
            file: file_name(&robot.source),
        },
        scenario: Some(Described {
            name: scenario.name.clone(),
            file: file_name(Path::new(&scenario.file)),
        }),
        filter: Sourced::new(filter, filter_source),
        gains: sources.gains.report(model.nq()),
        safety: Sourced::new(scenario.controller.safety, sources.safety),
        control_period: Sourced::new(scenario.control_period, sources.control_period),
        duration: Some(Sourced::new(scenario.duration, sources.duration)),
        reference: Sourced::new(reference, sources.reference),
        integrator: Some(IntegratorReport {
            rtol: tolerances.rtol,
            atol: tolerances.atol,
            h_initial: tolerances.h_initial,
            max_steps: tolerances.max_steps,
        }),
        record_period: scenario
            .record_period
            .map(|period| Sourced::new(period, sources.record_period)),
        plant: scenario.plant.as_ref().map(|plant| {
            Sourced::new(
                Described {
                    name: plant.name.clone(),
                    file: file_name(&plant.source),
                },
                sources.plant,
            )
        }),
        sensor_noise: scenario.sensor_noise.map(|n| crate::settings::NoiseReport {
            q: n.position,
            qd: n.velocity,
            seed: n.seed,
        }),
    }
}

/// Keeps barrier `values` (one per row of `table`) at time `t` in `minimum` and `by_kind`
/// if they are lower; a row with a value that is not a number counts in `invalid_rows` and
/// is kept out of both, and `rows` counts every row.
fn observe(
    minimum: &mut BarrierMinimum,
    by_kind: &mut LowestByKind,
    (invalid_rows, rows): (&mut usize, &mut usize),
    table: &[BarrierInfo],
    values: &[f64],
    t: f64,
) {
    *rows += 1;
    if values.iter().any(|b| b.is_nan()) {
        *invalid_rows += 1;
        return;
    }
    for (j, &b) in values.iter().enumerate() {
        if b < minimum.value {
            *minimum = BarrierMinimum::of(table, j, b, t);
        }
    }
    by_kind.observe_all(table, values, t);
}

/// A finished run: its trajectory and summary.
pub struct Run {
    /// One row per tick, and with a record period the rows between ticks.
    pub record: Record,
    /// Figures of the run.
    pub summary: RunSummary,
}

/// Simulates `scenario` on `model` with the safety filter on (`filter`) or off, calling
/// `progress` with the fraction done (about a hundred times per run).
///
/// The steps: the plant's model (`plant_model`), the controller, plant, reference and
/// record laid out for the scenario, then per tick the sensor's sample (`NoisySensor`),
/// the controller's tick, its tally and row (`Tally`), and the plant over the hold
/// (`integrate_hold`); last the summary (`summarize`).
pub fn simulate(
    model: &Model,
    scenario: &Scenario,
    filter: bool,
    progress: &mut dyn FnMut(f64),
) -> Result<Run, SimulationError> {
    let (nq, nb) = (model.nq(), model.nb());
    let plant_model = plant_model(model, scenario)?;
    let mut settings = scenario.controller.clone();
    settings.filter = filter;
    let mut controller = Controller::new(model, settings)?;
    let mut plant = Plant::new(plant_model.as_ref().unwrap_or(model), scenario.tolerances)?;
    plant.reset(&scenario.initial_q, &scenario.initial_qd, 0.0);
    let mut reference = ReferenceSignal::new(scenario.reference.clone());
    if reference.spec().dimension() != Some(nq) {
        return Err(SimulationError::Size {
            expected: nq,
            got: reference.spec().dimension().unwrap_or(0),
        });
    }
    let hold = Hold::of(scenario);
    let ticks = (scenario.duration / hold.period).round() as usize;
    let rows = ticks.saturating_mul(hold.between + 1).saturating_add(1);
    // The tick's status and its reason (`record::status`), held by the rows after it.
    let mut record = Record::for_columns(
        Columns::for_model(model, &[status::STATUS, status::REASON])?,
        rows,
    );
    let mut tally = Tally::new(model.generated.barrier_table());
    let mut between_barriers = vec![0.0; nb];
    let mut times = Times::default();
    let mut stopped = None;
    let report_every = (ticks / 100).max(1);
    // With sensor noise the controller samples a noisy state; the record and the lowest
    // barrier keep the plant's own.
    let mut sensor = scenario
        .sensor_noise
        .map(|noise| NoisySensor::new(noise, nq, nb));
    let start = Instant::now();
    let mut t = 0.0;
    for k in 0..=ticks {
        t = k as f64 * hold.period;
        let tick_start = Instant::now();
        let set_point = reference.sample(t);
        let status = match &mut sensor {
            Some(sensor) => {
                let (q, qd) = sensor.sample(&plant);
                control::tick(model, &mut controller, q, qd, set_point)
            }
            None => control::tick(model, &mut controller, plant.q(), plant.qd(), set_point),
        };
        times.control += tick_start.elapsed();
        let barriers = match &mut sensor {
            Some(sensor) => sensor.true_barriers(model, &plant),
            None => controller.barriers(),
        };
        tally.count(status, &controller);
        tally.observe(barriers, t);
        let (status_code, reason_code) = status::codes(status);
        let status_columns = [status_code, reason_code];
        let applied = if k < ticks { controller.tau() } else { &[][..] };
        tally.max_abs_tau = applied
            .iter()
            .fold(tally.max_abs_tau, |m, v| m.max(v.abs()));
        record.push_row(&Row {
            t,
            q: plant.q(),
            qd: plant.qd(),
            tau: controller.tau(),
            tau_nom: controller.tau_nom(),
            b: barriers,
            extra: &status_columns,
        })?;
        if k == ticks {
            break;
        }
        plant.tau_mut().copy_from_slice(controller.tau());
        // The controller evaluated the model at the plant's state (no noise, the plant's
        // model is the controller's): the plant takes that evaluation (it checks both)
        // instead of repeating it at the start of its first step.
        if let Some(state) = controller.dynamics_state() {
            plant.use_evaluation(model, state, controller.dynamics());
        }
        let mut rows = HoldRows {
            model,
            controller: &controller,
            record: &mut record,
            tally: &mut tally,
            barriers: &mut between_barriers,
            status_columns,
        };
        if let Some(why) = integrate_hold(&mut plant, &hold, t, &mut rows, &mut times)? {
            stopped = Some(why);
            t = plant.time();
            break;
        }
        if k % report_every == 0 {
            progress((k + 1) as f64 / ticks.max(1) as f64);
        }
    }
    times.wall = start.elapsed().as_secs_f64();
    progress(1.0);
    let set_point = reference.sample(t).q.to_vec();
    let ended = Ended {
        t,
        set_point,
        stopped,
    };
    let summary = summarize(model, scenario, filter, &plant, &hold, tally, &times, ended);
    Ok(Run { record, summary })
}

/// The plant's own model when the scenario gives a plant robot (of the controller robot's
/// structure: it takes the main model's functions, compiled or interpreted), `None` for the
/// controller's; the scenario's start checked against the model's size first.
fn plant_model(model: &Model, scenario: &Scenario) -> Result<Option<Model>, SimulationError> {
    let nq = model.nq();
    for len in [scenario.initial_q.len(), scenario.initial_qd.len()] {
        if len != nq {
            return Err(SimulationError::Size {
                expected: nq,
                got: len,
            });
        }
    }
    let Some(robot) = &scenario.plant else {
        return Ok(None);
    };
    if let Some(difference) = structure_difference(&model.robot, robot) {
        return Err(SimulationError::PlantStructure {
            file: file_name(&robot.source),
            difference,
        });
    }
    Ok(Some(Model::with_generated(robot.clone(), model.generated)?))
}

/// The timing of one hold: the control period \[s\] and the rows recorded between two
/// ticks (`between`, at multiples of the record period \[s\] after the earlier tick).
struct Hold {
    period: f64,
    record_period: Option<f64>,
    between: usize,
}

impl Hold {
    fn of(scenario: &Scenario) -> Hold {
        let period = scenario.control_period;
        let record_period = scenario.record_period;
        Hold {
            period,
            record_period,
            between: record_period.map_or(0, |r| between_ticks(period, r)),
        }
    }

    /// The offset \[s\] of the `j`-th row after a tick.
    fn offset(&self, j: usize) -> f64 {
        j as f64 * self.record_period.unwrap_or(self.period)
    }

    /// The `j`-th piece (from 1) of the hold: to the `j`-th recorded instant, the last
    /// (`j = between + 1`) to the next tick \[s\].
    fn piece(&self, j: usize) -> f64 {
        if j > self.between {
            self.period - self.offset(self.between)
        } else {
            self.offset(j) - self.offset(j - 1)
        }
    }
}

/// Where the times a run spends go \[s\]: the controller's ticks, the plant's integration,
/// the whole run.
#[derive(Default)]
struct Times {
    control: Duration,
    integration: Duration,
    wall: f64,
}

/// The sensor of a run with [`Scenario::sensor_noise`]: the plant's state with Gaussian
/// noise drawn from the scenario's seed, and the plant's true barriers for the record.
struct NoisySensor {
    spread: SensorNoise,
    draws: Xoshiro256PlusPlus,
    q: Vec<f64>,
    qd: Vec<f64>,
    barriers: Vec<f64>,
}

impl NoisySensor {
    fn new(spread: SensorNoise, nq: usize, nb: usize) -> NoisySensor {
        NoisySensor {
            spread,
            draws: Xoshiro256PlusPlus::seed_from_u64(spread.seed),
            q: vec![0.0; nq],
            qd: vec![0.0; nq],
            barriers: vec![0.0; nb],
        }
    }

    /// A noisy reading `(q, q̇)` of the plant's state.
    fn sample(&mut self, plant: &Plant) -> (&[f64], &[f64]) {
        for (sample, &x) in self.q.iter_mut().zip(plant.q()) {
            *sample = x + self.spread.position * standard_normal(&mut self.draws);
        }
        for (sample, &x) in self.qd.iter_mut().zip(plant.qd()) {
            *sample = x + self.spread.velocity * standard_normal(&mut self.draws);
        }
        (&self.q, &self.qd)
    }

    /// The barriers at the plant's true state.
    fn true_barriers(&mut self, model: &Model, plant: &Plant) -> &[f64] {
        model
            .generated
            .barriers(&model.params, plant.q(), &mut self.barriers);
        &self.barriers
    }
}

/// What a run counts tick by tick and row by row, for its [`RunSummary`].
struct Tally<'a> {
    table: &'a [BarrierInfo],
    counts: TickCounts,
    /// Per barrier, the ticks on which at least one of its rows was relaxed.
    relaxed_ticks: Vec<usize>,
    relaxed_now: Vec<bool>,
    minimum: BarrierMinimum,
    lowest_by_kind: LowestByKind,
    invalid_rows: usize,
    rows: usize,
    /// The largest `|τ|` entry applied \[N\].
    max_abs_tau: f64,
}

impl<'a> Tally<'a> {
    fn new(table: &'a [BarrierInfo]) -> Tally<'a> {
        Tally {
            table,
            counts: TickCounts::default(),
            relaxed_ticks: vec![0; table.len()],
            relaxed_now: vec![false; table.len()],
            minimum: BarrierMinimum::none(),
            lowest_by_kind: LowestByKind::new(table),
            invalid_rows: 0,
            rows: 0,
            max_abs_tau: 0.0,
        }
    }

    /// Counts one tick of `status`, with the QP's report from `controller`.
    fn count(&mut self, status: TickStatus, controller: &Controller) {
        let counts = &mut self.counts;
        counts.ticks += 1;
        match status {
            TickStatus::Unfiltered => counts.unfiltered += 1,
            TickStatus::Filtered | TickStatus::Relaxed | TickStatus::QpFailed => {
                counts.qp_solves += 1;
                let report = controller.qp_report();
                if report.active > 0 {
                    counts.active += 1;
                }
                if status == TickStatus::Relaxed {
                    counts.relaxed += 1;
                    // A barrier with several relaxed rows (one per sample of the hold)
                    // counts once per tick; rows past the barriers are input limits.
                    self.relaxed_now.fill(false);
                    for &row in &report.relaxed_rows {
                        if let Some(k) = controller.barrier_of_row(row) {
                            self.relaxed_now[k] = true;
                        }
                    }
                    for (ticks, _) in self
                        .relaxed_ticks
                        .iter_mut()
                        .zip(&self.relaxed_now)
                        .filter(|p| *p.1)
                    {
                        *ticks += 1;
                    }
                }
                if status == TickStatus::QpFailed {
                    counts.failed += 1;
                }
            }
            TickStatus::InvalidState(_) => counts.invalid_state += 1,
            TickStatus::Uncertified(why) => {
                counts.qp_solves += 1;
                counts.uncertified += 1;
                counts.uncertified_reasons.add(why);
            }
        }
    }

    /// Keeps a row's barrier `values` at time `t` ([`observe`]).
    fn observe(&mut self, values: &[f64], t: f64) {
        observe(
            &mut self.minimum,
            &mut self.lowest_by_kind,
            (&mut self.invalid_rows, &mut self.rows),
            self.table,
            values,
            t,
        );
    }

    /// The barriers some of whose rows were relaxed, with their tick counts.
    fn relaxed_barriers(&self) -> Vec<RelaxedBarrier> {
        self.relaxed_ticks
            .iter()
            .enumerate()
            .filter(|(_, n)| **n > 0)
            .map(|(barrier, &ticks)| {
                let (module, corner, label) = owner(self.table, barrier);
                RelaxedBarrier {
                    barrier,
                    module,
                    corner,
                    label,
                    ticks,
                }
            })
            .collect()
    }
}

/// What the rows recorded between two ticks write to and read from.
struct HoldRows<'r, 'a> {
    model: &'r Model,
    controller: &'r Controller,
    record: &'r mut Record,
    tally: &'r mut Tally<'a>,
    /// The barriers at a row's state (`nb`).
    barriers: &'r mut [f64],
    /// The tick's status and reason codes, held by the rows after it.
    status_columns: [f64; 2],
}

/// Integrates `plant` over one hold from the tick at `tick_time` \[s\]: one piece per
/// recorded instant, the last ending at the next tick (without rows between ticks, one
/// piece of a whole period). The integrator lands a step on each instant and carries its
/// step size on, so every piece is under error control. At each instant between ticks the
/// barriers of the controller's model are recorded and tallied with the held `τ`.
/// `Ok(Some(why))` when the plant's integration failed (the run ends there).
fn integrate_hold(
    plant: &mut Plant,
    hold: &Hold,
    tick_time: f64,
    rows: &mut HoldRows,
    times: &mut Times,
) -> Result<Option<String>, SimulationError> {
    for j in 1..=hold.between + 1 {
        let step_start = Instant::now();
        let advanced = plant.advance(hold.piece(j));
        times.integration += step_start.elapsed();
        if let Err(error) = advanced {
            let cause = plant
                .last_dynamics_error()
                .map_or(String::new(), |e| format!(" ({e})"));
            return Ok(Some(format!("plant integration failed: {error}{cause}")));
        }
        if j > hold.between {
            break;
        }
        let at = tick_time + hold.offset(j);
        let model = rows.model;
        model
            .generated
            .barriers(&model.params, plant.q(), rows.barriers);
        rows.tally.observe(rows.barriers, at);
        rows.record.push_row(&Row {
            t: at,
            q: plant.q(),
            qd: plant.qd(),
            tau: rows.controller.tau(),
            tau_nom: rows.controller.tau_nom(),
            b: rows.barriers,
            extra: &rows.status_columns,
        })?;
    }
    Ok(None)
}

/// How a run ended: the time reached \[s\], the set point then \[m\], and why it stopped
/// early (if it did).
struct Ended {
    t: f64,
    set_point: Vec<f64>,
    stopped: Option<String>,
}

/// The run's [`RunSummary`] from its tally, times and end.
#[allow(clippy::too_many_arguments)]
fn summarize(
    model: &Model,
    scenario: &Scenario,
    filter: bool,
    plant: &Plant,
    hold: &Hold,
    tally: Tally,
    times: &Times,
    ended: Ended,
) -> RunSummary {
    let final_q = plant.q().to_vec();
    let set_point_error = final_q
        .iter()
        .zip(&ended.set_point)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        .sqrt();
    let relaxed_barriers = tally.relaxed_barriers();
    let stats = plant.stats();
    RunSummary {
        controller: if filter { "filter" } else { "pd" },
        scenario: scenario.name.clone(),
        robot: model.robot.name.clone(),
        duration: ended.t,
        control_period: hold.period,
        record_period: hold.record_period,
        dense: hold.between > 0,
        min_barrier: tally.minimum,
        invalid_rows: tally.invalid_rows,
        rows: tally.rows,
        lowest_by_kind: tally.lowest_by_kind,
        final_q,
        set_point: ended.set_point,
        set_point_error,
        max_abs_tau: tally.max_abs_tau,
        counts: tally.counts,
        relaxed_barriers,
        integrator_steps: stats.steps,
        integrator_rejected: stats.rejected,
        integrator_rhs_evals: stats.rhs_evals,
        integrator_w_factorizations: stats.w_factorizations,
        wall_time: times.wall,
        control_time: times.control.as_secs_f64(),
        integration_time: times.integration.as_secs_f64(),
        real_time_factor: ended.t / times.wall.max(1e-12),
        stopped: ended.stopped,
        settings: settings_report(model, scenario, filter),
    }
}
