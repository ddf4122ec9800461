//! `softcbf run`: the loop sync read → mapping → prediction → [`control::tick`] → tensions →
//! sync write, with the safe start and safe stop of [`servo_io`], a log row every tick and
//! a summary at the end.
//!
//! **Experiments.** With [`RunSettings::experiment`], the nominal command of each tick is
//! not PD+ but the generalized force `τ = A f` of the [`Experiment`]'s tensions, passed
//! through the same filter, tension limits and prediction ([`control::tick_feedforward`]);
//! the log's `step` and `rest` columns say where the experiment is, and the run ends when
//! it is over ([`StopReason::ExperimentOver`]) or by any of the stops below.
//!
//! **The bus first.** Once the servos are prepared (torque off, zero goal current),
//! [`bus_check::measure`] times the loop's read-and-write cycle; a rate the bus cannot hold
//! is refused (torque stays off), or with [`RateRule::Adapt`] (`--rate auto`) the rate it
//! allows with a margin is chosen ([`bus_check::choose_rate`]).
//!
//! **Ticks and their timing.** Ticks are scheduled at `start + k / rate`; a tick whose
//! write ends after the next tick's start is an overrun, and the next tick then starts at
//! once (no burst to catch up), so a slow bus runs the loop at the rate it can. The loop
//! measures what it really gets and uses it: a reading was sampled by the servos one wire
//! time after its request left, and is `age` seconds old when the command computed from it
//! reaches them; the controller acts on the state predicted `age` seconds ahead by the
//! model under the command then in force (`predict`). The command is held until the next
//! one; the safety rows are computed for a hold of [`HOLD_ALLOWANCE`] times the longest of
//! the last [`RATE_WINDOW`] intervals (at least the nominal period), and the HOCBF class-K
//! gains are scaled by `nominal / achieved` (the mean of those intervals), so that their product with
//! the hold, on which the sampled loop's behaviour depends, stays what it is at the
//! nominal rate (smaller gains are also a stricter constraint). When the achieved rate
//! falls below `min_rate`, the loop stops safely and says so. Every deadline is watched: a
//! tick that ends more than a period after it was due is a deadline overrun, and a command
//! that stays in force longer than the hold it was computed for (until the next command or
//! the safe stop) a hold overrun, both counted in the summary and logged per tick.
//!
//! **Faults.** A tick without a fresh reading of every servo (after the retries of the
//! robot file's `[hardware]` table) sends nothing: the servos keep the previous command,
//! the tick is counted as held, and `max_consecutive_errors` held ticks in a row stop the
//! run. A servo's alert bit, a port that fails, a pause longer than the servos' Bus
//! Watchdog (they have stopped by themselves), a terminating signal (through `stop`) and a
//! panic inside the loop all end in the same safe stop: zero tension, torque off, the
//! watchdog disarmed, the log closed.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::hardware_description::VelocitySource;
use softcbf_description::domain;

use crate::bus_check::{self, BusTiming, RateChoice, RateRefusal};
use crate::control::{
    self, Controller, ControllerError, ControllerSettings, Reference, TickStatus,
};
use crate::emulator::{wait_until, wire_time};
use crate::experiment::{Experiment, Mark};
use crate::integrator::{IntegratorError, Tolerances};
use crate::mapping::{CLAMP_TOLERANCE, Clamps, TendonMap};
use crate::model::Model;
use crate::plant::Plant;
use crate::protocol::{Bus, BusCounters};
use crate::record::status;
use crate::servo_io::{self, ServoIo, ServoPort, StartError};
use crate::sim::{BarrierMinimum, LowestByKind};

pub use crate::bus_check::RateRule;
use crate::log::{Extra, FIXED_EXTRA};
pub use crate::log::{RunLog, extra_columns};
pub use crate::record::Row;
pub use crate::run_outcome::{Deadlines, RunSummary, StopReason, Verdict};
pub use crate::run_settings::{DEFAULT_BUS_WATCHDOG_FLOOR, RATE_WINDOW, RunSettings};

/// Time on the wire \[s\] of the goal-current sync write to `servos` servos at `baud`:
/// the servos act on a command when its last byte has arrived (Protocol 2.0: 14 bytes of
/// frame, address and length, and 3 per servo, 10 bits a byte).
pub fn command_wire_time(servos: usize, baud: u32) -> f64 {
    wire_time(14 + 3 * servos, baud).as_secs_f64()
}

/// Tolerances of the state prediction: `rtol = 1e-4`, `atol = 1e-7` (m, m/s). Over a 2 ms
/// (33 ms) age they leave 3e-9 m (5e-7 m) and 1e-6 m/s (3e-5 m/s) of error against a
/// tight-tolerance run, a hundred times below what the servos resolve (0.07 mm of tendon,
/// about 1 mm/s), in 20 µs (120 µs) instead of the simulation default's 87 µs (550 µs).
pub fn prediction_tolerances() -> Tolerances {
    Tolerances {
        rtol: 1e-4,
        atol: 1e-7,
        ..Tolerances::default()
    }
}

/// The factor on the longest recent interval that gives the hold a command is computed for:
/// a 10 % allowance for the loop's jitter.
pub const HOLD_ALLOWANCE: f64 = 1.1;

/// Share of the period a certified tick may spend on its attempts before it takes the
/// predicted rows' command (`Controller::set_compute_budget`): the rest of the period is
/// for that command, the state's prediction and the bus. Measured against the emulator on
/// this 2-core machine under load, without it a third of the ticks of a run with a declared
/// box overran their deadline (docs/hardware.md).
pub const COMPUTE_BUDGET: f64 = 0.25;

/// Why a run could not start.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A setting is unusable.
    #[error("{0}")]
    Setting(String),
    /// The controller could not be built.
    #[error(transparent)]
    Controller(#[from] ControllerError),
    /// The state predictor could not be built.
    #[error("state predictor: {0}")]
    Predictor(#[from] IntegratorError),
    /// The safe start refused to enable torque (torque was then switched off everywhere).
    #[error("safe start failed, torque left off: {0}")]
    Start(#[from] StartError),
    /// The bus cannot hold the rate asked for (torque was never enabled).
    #[error("{0}; torque left off")]
    RateRefused(#[from] RateRefusal),
}

/// What the start of a run reports as it happens (the command line prints it).
pub trait StartReport {
    /// The round trip of the loop's traffic was measured.
    fn bus_measured(&mut self, _timing: &BusTiming) {}
    /// The rate is decided; `settings` are the ones the loop runs with.
    fn running(&mut self, _choice: RateChoice, _settings: &RunSettings) {}
}

/// Reports nothing.
impl StartReport for () {}

/// Fraction of the Bus Watchdog a pause between instructions may reach before the loop
/// stops, not knowing whether the servos stopped by themselves.
const WATCHDOG_MARGIN: f64 = 0.8;

/// Sync-read retries allowed for the safe start's reading (torque is still off).
const START_READ_RETRIES: u32 = 9;

/// The loop's preallocated workspace.
struct Workspace<'m> {
    angles: Vec<f64>,
    rates: Vec<f64>,
    /// The state read, and the state the controller acts on (predicted).
    q: Vec<f64>,
    qd: Vec<f64>,
    q_used: Vec<f64>,
    qd_used: Vec<f64>,
    q_prev: Vec<f64>,
    /// Barriers at the state read.
    barriers: Vec<f64>,
    /// An experiment's guard: the state read carried ahead at its velocity to when the
    /// next command lands, and the barriers there.
    q_ahead: Vec<f64>,
    barriers_ahead: Vec<f64>,
    tensions: Vec<f64>,
    /// The generalized force of the tensions last sent (in force until the next command).
    tau_applied: Vec<f64>,
    /// An experiment's tensions this tick, and their generalized force (the nominal
    /// command the filter is given).
    experiment_tensions: Vec<f64>,
    tau_experiment: Vec<f64>,
    /// The experiment's mark of the last fresh tick (`None`: no experiment).
    mark: Option<Mark>,
    currents: Vec<i16>,
    /// The Goal Current unit \[mA\] (the log's currents).
    current_unit: f64,
    zeros: Vec<f64>,
    nan_q: Vec<f64>,
    nan_b: Vec<f64>,
    extra: Vec<f64>,
    predictor: Plant<'m>,
    /// Intervals between the last commands \[s\] (a ring).
    intervals: [f64; RATE_WINDOW],
    /// The first failure of the log, reported at the stop.
    log_error: Option<String>,
    /// When the first tick started.
    first_tick: Option<Instant>,
    /// When the last command was computed, and the hold `Δ` it was computed for \[s\].
    last_command: Option<(Instant, f64)>,
}

/// Timing of one tick, for its log row.
#[derive(Clone, Copy, Default)]
struct TickTiming {
    late: Duration,
    read: Duration,
    compute: Duration,
    write: Duration,
    overrun: bool,
    age: f64,
    interval: f64,
    hold: f64,
    /// How much longer than its hold the previous command stayed in force \[s\] (NaN: no
    /// command this tick).
    hold_excess: f64,
    gain_scale: f64,
    /// How long before the row's `t` the servos sampled the reading \[s\].
    sampled: f64,
}

/// Runs the controller on the servos behind `bus` until the duration, `stop`, or a fault.
/// The servos prepared (torque off), the bus check, then the rest of the safe start (on a
/// failure, or a rate the bus cannot hold, torque is switched off and the error returned);
/// safe stop always, also after a panic inside the loop. `log` gets one row per tick.
pub fn run<P: ServoPort>(
    model: &Model,
    map: &TendonMap,
    bus: &mut Bus<P>,
    settings: &RunSettings,
    log: &mut dyn RunLog,
    stop: &AtomicBool,
) -> Result<RunSummary, RunError> {
    run_reporting(model, map, bus, settings, log, stop, &mut ())
}

/// [`run`], telling `report` what the bus check found and which rate the loop runs at.
pub fn run_reporting<P: ServoPort>(
    model: &Model,
    map: &TendonMap,
    bus: &mut Bus<P>,
    settings: &RunSettings,
    log: &mut dyn RunLog,
    stop: &AtomicBool,
    report: &mut dyn StartReport,
) -> Result<RunSummary, RunError> {
    let nq = model.nq();
    settings.validate(nq).map_err(RunError::Setting)?;
    let hardware = map.hardware();
    let period = 1.0 / settings.rate;
    let controller_settings = ControllerSettings {
        filter: settings.filter,
        // The filter chooses among the commands the cables can realize.
        input_limits: map.tension_limit_rows(),
        safety: hardware.safety.unwrap_or_default(),
        hold: period,
        ..settings.gains_for(&model.robot).controller_settings()
    };
    let mut controller = Controller::new(model, controller_settings.clone())?;
    controller.set_compute_budget(COMPUTE_BUDGET * period);
    let n = map.n_servos();
    let mut io = ServoIo::new(hardware.servo_ids());
    let mut ws = Workspace {
        angles: vec![0.0; n],
        rates: vec![0.0; n],
        q: vec![0.0; nq],
        qd: vec![0.0; nq],
        q_used: vec![0.0; nq],
        qd_used: vec![0.0; nq],
        q_prev: vec![0.0; nq],
        barriers: vec![0.0; model.nb()],
        q_ahead: vec![0.0; nq],
        barriers_ahead: vec![0.0; model.nb()],
        tensions: vec![0.0; n],
        tau_applied: vec![0.0; nq],
        experiment_tensions: vec![0.0; n],
        tau_experiment: vec![0.0; nq],
        mark: None,
        currents: vec![0; n],
        current_unit: hardware.current_unit,
        zeros: vec![0.0; nq],
        nan_q: vec![f64::NAN; nq],
        nan_b: vec![f64::NAN; model.nb()],
        extra: vec![0.0; FIXED_EXTRA + 2 * n + nq],
        predictor: Plant::new(model, prediction_tolerances())?,
        intervals: [period; RATE_WINDOW],
        log_error: None,
        first_tick: None,
        last_command: None,
    };
    let watchdog = settings.bus_watchdog_units() > 0;
    // Start-up transactions are retried as patiently as the loop's readings.
    let attempts = ((1 + hardware.retries) * hardware.max_consecutive_errors).max(3);

    let mut summary = RunSummary {
        stop: StopReason::Duration,
        ticks: 0,
        commands: 0,
        held: 0,
        fallbacks: 0,
        invalid: 0,
        relaxed: 0,
        uncertified: 0,
        uncertified_reasons: Default::default(),
        unfiltered: 0,
        interventions: 0,
        deadlines: Deadlines::default(),
        clamps: Clamps::default(),
        bus: BusCounters::default(),
        min_barrier: BarrierMinimum::none(),
        lowest_by_kind: LowestByKind::new(model.generated.barrier_table()),
        elapsed: 0.0,
        max_compute: 0.0,
        max_age: 0.0,
        prediction_failures: 0,
        torque_off: Vec::new(),
        bus_timing: None,
        rate_choice: None,
        experiment: None,
    };
    let tension_limits: Vec<[f64; 2]> = hardware.modules.iter().map(|m| m.tension_limits).collect();
    let mut experiment: Option<Experiment> = None;
    let outcome = catch_unwind(AssertUnwindSafe(|| -> Result<StopReason, RunError> {
        // Told to stop before the start (a signal while the port opened): torque stays off.
        if stop.load(Ordering::Relaxed) {
            return Ok(StopReason::Interrupted);
        }
        let units = settings.bus_watchdog_units();
        servo_io::prepare(bus, io.ids(), hardware.model_number, units > 0, attempts)?;
        // The loop's own traffic, torque off, zero tension.
        let zero_currents = vec![0; n];
        let timing = bus_check::measure(bus, &mut io, &zero_currents, hardware.retries)?;
        // The loop's computation too: a command from the state just read, on a controller
        // of its own (the run's starts fresh), at the hold the loop would run.
        let hold = (1.0 / settings.rate).max(timing.slow);
        let compute = time_computation(
            model,
            map,
            &io,
            &mut ws,
            controller_settings.clone(),
            &settings.set_point,
            hold,
            timing.median,
        )?;
        let timing = timing.with_compute(compute);
        summary.bus_timing = Some(timing);
        report.bus_measured(&timing);
        let choice = bus_check::choose_rate(settings.rate, settings.rate_rule, &timing)?;
        let settings = settings.at_rate(choice.rate());
        settings.validate(nq).map_err(RunError::Setting)?;
        summary.rate_choice = Some(choice);
        report.running(choice, &settings);
        controller.set_hold(1.0 / settings.rate);
        // The experiment at the rate decided (its band depends on it), before torque on.
        if let Some(design) = &settings.experiment {
            let mut built = Experiment::new(design, &model.robot, &tension_limits, settings.rate)
                .map_err(RunError::Setting)?;
            built.watch(model.nb());
            experiment = Some(built);
        }
        // A signal during the bus check: torque stays off.
        if stop.load(Ordering::Relaxed) {
            return Ok(StopReason::Interrupted);
        }
        safe_start(model, map, bus, &mut io, &mut ws, attempts)?;
        enable(bus, &mut io, &mut ws, &settings, &timing, attempts)?;
        Ok(control_loop(
            model,
            map,
            bus,
            &mut io,
            &mut ws,
            &mut controller,
            &settings,
            log,
            stop,
            &mut summary,
            experiment.as_mut(),
        ))
    }));
    summary.experiment = experiment.as_ref().map(Experiment::report);
    let stop_reason = match outcome {
        Ok(Ok(reason)) => reason,
        Ok(Err(error)) => {
            servo_io::safe_stop(bus, &mut io, watchdog);
            return Err(error);
        }
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown".into());
            StopReason::Fault(format!(
                "internal error in the control loop (a bug, please report it): {what}"
            ))
        }
    };
    summary.elapsed = ws.first_tick.map_or(0.0, |t| t.elapsed().as_secs_f64());
    // The last command is in force until the safe stop's zero tension.
    if let Some((computed, hold)) = ws.last_command {
        summary
            .deadlines
            .command(computed.elapsed().as_secs_f64(), hold);
    }
    let confirmed = servo_io::safe_stop(bus, &mut io, watchdog);
    summary.torque_off = io.ids().iter().copied().zip(confirmed).collect();
    summary.bus = bus.counters();
    let log_error = log.flush().err().or(ws.log_error.take());
    summary.stop = match log_error {
        Some(e) if !stop_reason.is_fault() => {
            StopReason::Fault(format!("cannot write the log: {e}"))
        }
        _ => stop_reason,
    };
    Ok(summary)
}

/// Commands computed at the start to time the loop's computation (after one more that
/// warms the controller up, untimed).
pub const COMPUTE_SAMPLES: usize = 9;

/// The median of [`COMPUTE_SAMPLES`] computations of a command from the state the bus check
/// read last (torque off, nothing sent), after one untimed (a fresh controller's first
/// tick has no warm start) \[s\]: the state predicted `age` seconds ahead, the controller's
/// tick toward `set_point` with a hold of `hold` seconds (on a controller built from
/// `settings`), tensions and currents, as each tick of the loop does. The median, since a
/// busy host stretches single ticks that the bus check's quantile does not count either.
/// 0 when the state is outside the model's domain (the safe start refuses it next).
#[allow(clippy::too_many_arguments)]
fn time_computation(
    model: &Model,
    map: &TendonMap,
    io: &ServoIo,
    ws: &mut Workspace<'_>,
    settings: ControllerSettings,
    set_point: &[f64],
    hold: f64,
    age: f64,
) -> Result<f64, ControllerError> {
    measure(map, io, ws, VelocitySource::Servo, 0.0, 0.0);
    if domain::state_problem(&model.robot, &ws.q, &ws.qd).is_some() {
        return Ok(0.0);
    }
    let mut controller = Controller::new(model, settings)?;
    controller.set_hold(hold);
    controller.set_margin_age(age);
    controller.set_compute_budget(COMPUTE_BUDGET * hold);
    let mut times = [0.0_f64; COMPUTE_SAMPLES + 1];
    for time in &mut times {
        let start = Instant::now();
        ws.q_used.copy_from_slice(&ws.q);
        ws.qd_used.copy_from_slice(&ws.qd);
        predict(model, ws, age);
        control::tick(
            model,
            &mut controller,
            &ws.q_used,
            &ws.qd_used,
            Reference {
                q: set_point,
                qd: &ws.zeros,
                qdd: &ws.zeros,
            },
        );
        map.tensions_from_tau(controller.tau(), &mut ws.tensions);
        for (k, f) in ws.tensions.iter().enumerate() {
            ws.currents[k] = map.current_from_tension(k, *f);
        }
        *time = start.elapsed().as_secs_f64();
    }
    let timed = &mut times[1..];
    timed.sort_by(f64::total_cmp);
    Ok(timed[COMPUTE_SAMPLES / 2])
}

/// The safe start after [`servo_io::prepare`] and the bus check, up to torque on: a
/// finite state read, the goal currents of taut cables (`f_min`) written, torque still off.
fn safe_start<P: ServoPort>(
    model: &Model,
    map: &TendonMap,
    bus: &mut Bus<P>,
    io: &mut ServoIo,
    ws: &mut Workspace<'_>,
    attempts: u32,
) -> Result<(), StartError> {
    io.read_states(bus, START_READ_RETRIES.max(attempts))
        .map_err(StartError::State)?;
    measure(map, io, ws, VelocitySource::Servo, 0.0, 0.0);
    if let Some(problem) = domain::state_problem(&model.robot, &ws.q, &ws.qd) {
        return Err(StartError::OutOfDomain {
            problem: problem.to_string(),
            q: ws.q.clone(),
            qd: ws.qd.clone(),
        });
    }
    // Taut cables (f_min) before torque on.
    map.tensions_from_tau(&ws.zeros, &mut ws.tensions);
    for (k, f) in ws.tensions.iter().enumerate() {
        ws.currents[k] = map.current_from_tension(k, *f);
    }
    map.tau_from_tensions(&ws.tensions, &mut ws.tau_applied);
    io.write_currents(bus, &ws.currents)
        .map_err(StartError::State)?;
    Ok(())
}

/// The safe start's end, at the rate decided: the Bus Watchdog armed, torque on (cables at
/// `f_min`). The first commands are held as long as the bus's median cycle, at least a
/// period.
fn enable<P: ServoPort>(
    bus: &mut Bus<P>,
    io: &mut ServoIo,
    ws: &mut Workspace<'_>,
    settings: &RunSettings,
    timing: &BusTiming,
    attempts: u32,
) -> Result<(), StartError> {
    servo_io::enable_torque(bus, io.ids(), settings.bus_watchdog_units(), attempts)?;
    ws.qd.fill(0.0);
    ws.q_prev.copy_from_slice(&ws.q);
    bus.reset_counters();
    ws.intervals = [timing.median.max(1.0 / settings.rate); RATE_WINDOW];
    Ok(())
}

/// The ticks, until a stop reason.
#[allow(clippy::too_many_arguments)]
fn control_loop<P: ServoPort>(
    model: &Model,
    map: &TendonMap,
    bus: &mut Bus<P>,
    io: &mut ServoIo,
    ws: &mut Workspace<'_>,
    controller: &mut Controller,
    settings: &RunSettings,
    log: &mut dyn RunLog,
    stop: &AtomicBool,
    summary: &mut RunSummary,
    mut experiment: Option<&mut Experiment>,
) -> StopReason {
    let hardware = map.hardware();
    let baud = hardware.baud;
    let period = Duration::from_secs_f64(1.0 / settings.rate);
    let nominal = period.as_secs_f64();
    let write_wire = command_wire_time(map.n_servos(), baud);
    let barrier_table = model.generated.barrier_table();
    let (min_rate, bus_watchdog) = (settings.min_rate(), settings.bus_watchdog());
    let start = Instant::now();
    ws.first_tick = Some(start);
    let mut next = start;
    let mut last_reading: Option<Instant> = None;
    let mut commands_timed = 0usize;
    let mut compute_estimate = 0.0_f64;
    let mut consecutive = 0u32;
    let alerts_at_start = bus.counters().alerts;
    loop {
        if stop.load(Ordering::Relaxed) {
            return StopReason::Interrupted;
        }
        if let Some(experiment) = experiment.as_deref()
            && experiment.finished()
        {
            if let Some(stop) = experiment.stopped() {
                let j = stop.barrier();
                let (label, unit) = barrier_table
                    .get(j)
                    .map_or(("a barrier", ""), |b| (b.label, b.kind.unit()));
                return StopReason::ExperimentStopped {
                    why: stop.describe(label, unit),
                    left: experiment.steps_left(),
                };
            }
            return StopReason::ExperimentOver {
                left: experiment.steps_left(),
            };
        }
        if settings
            .duration
            .is_some_and(|d| next.duration_since(start).as_secs_f64() >= d)
        {
            return StopReason::Duration;
        }
        wait_until(next);
        let tick_start = Instant::now();
        if bus_watchdog > 0.0
            && let Some((sent, _)) = bus.last_sent()
        {
            // A margin for the wire and the servo's own clock: past 80 % of the watchdog
            // nobody can tell whether the servos are still pulling.
            let gap = tick_start.duration_since(sent).as_secs_f64();
            if gap > WATCHDOG_MARGIN * bus_watchdog {
                return StopReason::WatchdogExpired {
                    gap,
                    watchdog: bus_watchdog,
                };
            }
        }
        let mut timing = TickTiming {
            late: tick_start.duration_since(next),
            hold_excess: f64::NAN,
            ..TickTiming::default()
        };
        summary.ticks += 1;
        let read = io.read_states(bus, hardware.retries);
        let read_done = Instant::now();
        timing.read = read_done - tick_start;
        let t = read_done.duration_since(start).as_secs_f64();
        let mut clamps = Clamps::default();
        let (fresh, status) = match read {
            Ok(()) => {
                consecutive = 0;
                let dt = last_reading.map_or(0.0, |l| read_done.duration_since(l).as_secs_f64());
                last_reading = Some(read_done);
                measure(
                    map,
                    io,
                    ws,
                    hardware.velocity_source,
                    dt,
                    hardware.velocity_filter,
                );
                // The servos sampled one wire time after the request left; the command
                // reaches them after the computation and its own wire time.
                let sampled = io
                    .reading_sent()
                    .map_or(read_done, |(sent, len)| sent + wire_time(len, baud));
                timing.sampled = read_done.saturating_duration_since(sampled).as_secs_f64();
                let age = timing.sampled + compute_estimate + write_wire;
                timing.age = age;
                // The hold this command is computed for: the longest interval of the last
                // few (never less than the nominal period), with an allowance for jitter,
                // so that a command seldom stays in force longer than the sampled-data rows
                // looked ahead (docs/model.md §5). The class-K gains keep their product
                // with the mean period achieved, p·Δ, at what the file's gains give at the
                // nominal period (smaller gains: a stricter constraint, and the sampled
                // loop as stable as at full rate).
                let achieved = ws.intervals.iter().sum::<f64>() / RATE_WINDOW as f64;
                let longest = ws.intervals.iter().fold(nominal, |m, &v| m.max(v));
                let hold = longest * HOLD_ALLOWANCE;
                timing.hold = hold;
                timing.gain_scale = nominal / achieved.max(nominal);
                controller.set_barrier_gain_scale(timing.gain_scale);
                controller.set_hold(hold);
                // The state is predicted from a reading `age` old by the model: the robust
                // margin of a declared uncertainty covers the plant's deviation over it too.
                controller.set_margin_age(age);
                ws.q_used.copy_from_slice(&ws.q);
                ws.qd_used.copy_from_slice(&ws.qd);
                if settings.predict && !predict(model, ws, age) {
                    summary.prediction_failures += 1;
                }
                // The barriers at the state read: what the robot really did (and what
                // an experiment's guard and levels watch).
                model
                    .generated
                    .barriers(&model.params, &ws.q, &mut ws.barriers);
                let tick_status = match experiment.as_deref_mut() {
                    // The experiment judges rest on the state read, and its tensions are
                    // the nominal command.
                    Some(experiment) => {
                        // Where the robot will be when the command after this one lands,
                        // at its present velocity: the guard stops before that, not after.
                        let ahead = age + hold;
                        for (k, q) in ws.q_ahead.iter_mut().enumerate() {
                            *q = ws.q[k] + ws.qd[k] * ahead;
                        }
                        model.generated.barriers(
                            &model.params,
                            &ws.q_ahead,
                            &mut ws.barriers_ahead,
                        );
                        experiment.observe(&ws.barriers, &ws.barriers_ahead);
                        ws.mark = Some(experiment.command(t, &ws.q, &mut ws.experiment_tensions));
                        map.tau_from_tensions(&ws.experiment_tensions, &mut ws.tau_experiment);
                        control::tick_feedforward(
                            model,
                            controller,
                            &ws.q_used,
                            &ws.qd_used,
                            &ws.tau_experiment,
                        )
                    }
                    None => control::tick(
                        model,
                        controller,
                        &ws.q_used,
                        &ws.qd_used,
                        Reference {
                            q: &settings.set_point,
                            qd: &ws.zeros,
                            qdd: &ws.zeros,
                        },
                    ),
                };
                // A relaxed QP changes the command too (its rows had no common point).
                if matches!(tick_status, TickStatus::Filtered | TickStatus::Relaxed)
                    && controller
                        .tau()
                        .iter()
                        .zip(controller.tau_nom())
                        .any(|(a, b)| (a - b).abs() > CLAMP_TOLERANCE)
                {
                    summary.interventions += 1;
                }
                clamps = map.tensions_from_tau(controller.tau(), &mut ws.tensions);
                for (k, f) in ws.tensions.iter().enumerate() {
                    ws.currents[k] = map.current_from_tension(k, *f);
                }
                let computed = Instant::now();
                timing.compute = computed.duration_since(read_done);
                compute_estimate = timing.compute.as_secs_f64();
                let written = io.write_currents(bus, &ws.currents);
                let write_end = Instant::now();
                timing.write = write_end.duration_since(computed);
                if let Err(error) = written {
                    return StopReason::Fault(format!("cannot write the goal currents: {error}"));
                }
                map.tau_from_tensions(&ws.tensions, &mut ws.tau_applied);
                timing.hold_excess = 0.0;
                if let Some((previous, previous_hold)) = ws.last_command {
                    let interval = computed.duration_since(previous).as_secs_f64();
                    timing.interval = interval;
                    ws.intervals[commands_timed % RATE_WINDOW] = interval;
                    commands_timed += 1;
                    // The previous command was computed for a hold of `previous_hold`.
                    timing.hold_excess = summary.deadlines.command(interval, previous_hold);
                }
                ws.last_command = Some((computed, hold));
                summary.commands += 1;
                summary.max_age = summary.max_age.max(age);
                match tick_status {
                    TickStatus::QpFailed => summary.fallbacks += 1,
                    TickStatus::InvalidState(_) => {
                        summary.fallbacks += 1;
                        summary.invalid += 1;
                    }
                    TickStatus::Relaxed => summary.relaxed += 1,
                    TickStatus::Uncertified(why) => {
                        summary.uncertified += 1;
                        summary.uncertified_reasons.add(why);
                    }
                    TickStatus::Unfiltered => summary.unfiltered += 1,
                    TickStatus::Filtered => {}
                }
                summary.clamps.add(clamps);
                for (j, &b) in ws.barriers.iter().enumerate() {
                    // A NaN barrier (a state outside the model) counts as the lowest.
                    let value = if b.is_nan() { f64::NEG_INFINITY } else { b };
                    if b < summary.min_barrier.value || b.is_nan() {
                        summary.min_barrier = BarrierMinimum::of(barrier_table, j, value, t);
                    }
                    summary.lowest_by_kind.observe(barrier_table, j, value, t);
                }
                summary.max_compute = summary.max_compute.max(timing.compute.as_secs_f64());
                (true, status::codes(tick_status))
            }
            Err(error) => {
                consecutive += 1;
                summary.held += 1;
                if consecutive >= hardware.max_consecutive_errors {
                    push_row(
                        log,
                        ws,
                        false,
                        t,
                        controller,
                        (status::NO_READING, status::NO_REASON),
                        io,
                        consecutive,
                        timing,
                        clamps,
                    );
                    return StopReason::CommunicationLost {
                        ticks: consecutive,
                        last_error: error.to_string(),
                    };
                }
                (false, (status::NO_READING, status::NO_REASON))
            }
        };
        let end = Instant::now();
        timing.overrun = summary.deadlines.tick(next, period, end);
        push_row(
            log,
            ws,
            fresh,
            t,
            controller,
            status,
            io,
            consecutive,
            timing,
            clamps,
        );
        if bus.counters().alerts > alerts_at_start {
            return StopReason::Fault(
                "a servo reports a hardware error (alert bit); read its Hardware Error Status"
                    .into(),
            );
        }
        if commands_timed >= RATE_WINDOW {
            let mean = ws.intervals.iter().sum::<f64>() / RATE_WINDOW as f64;
            if mean * min_rate > 1.0 {
                return StopReason::RateTooLow {
                    achieved: 1.0 / mean,
                    min: min_rate,
                };
            }
        }
        next += period;
        if next < end {
            next = end;
        }
    }
}

/// Advances the state read (`ws.q`, `ws.qd`) by `age` seconds under the force in effect,
/// into `ws.q_used`, `ws.qd_used`. On failure (the model cannot integrate from this state)
/// these keep the state read and `false` is returned.
fn predict(model: &Model, ws: &mut Workspace<'_>, age: f64) -> bool {
    if !age.is_finite() {
        return false;
    }
    // Nothing to predict, or a state the controller will refuse anyway.
    if age <= 0.0 || domain::state_problem(&model.robot, &ws.q, &ws.qd).is_some() {
        return true;
    }
    ws.predictor.reset(&ws.q, &ws.qd, 0.0);
    ws.predictor.tau_mut().copy_from_slice(&ws.tau_applied);
    match ws.predictor.advance(age) {
        Ok(()) => {
            ws.q_used.copy_from_slice(ws.predictor.q());
            ws.qd_used.copy_from_slice(ws.predictor.qd());
            true
        }
        Err(_) => false,
    }
}

/// `q` from the servo angles, and `q̇` from the servos or from filtered differences over
/// `dt` seconds (`dt = 0`: no previous reading, `q̇` unchanged).
fn measure(
    map: &TendonMap,
    io: &ServoIo,
    ws: &mut Workspace<'_>,
    source: VelocitySource,
    dt: f64,
    filter: f64,
) {
    for (k, state) in io.states().iter().enumerate() {
        ws.angles[k] = map.angle_from_position(state.position);
        ws.rates[k] = map.rate_from_velocity(state.velocity);
    }
    map.q_from_angles(&ws.angles, &mut ws.q);
    match source {
        VelocitySource::Servo => map.qd_from_rates(&ws.rates, &mut ws.qd),
        VelocitySource::Difference => {
            if dt > 0.0 {
                // First-order low-pass, backward Euler: v += dt/(T + dt) · (raw − v).
                let gain = dt / (filter + dt);
                for i in 0..ws.q.len() {
                    let raw = (ws.q[i] - ws.q_prev[i]) / dt;
                    ws.qd[i] += gain * (raw - ws.qd[i]);
                }
            }
            ws.q_prev.copy_from_slice(&ws.q);
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn push_row(
    log: &mut dyn RunLog,
    ws: &mut Workspace<'_>,
    fresh: bool,
    t: f64,
    controller: &Controller,
    (status, reason): (f64, f64),
    io: &ServoIo,
    consecutive: u32,
    timing: TickTiming,
    clamps: Clamps,
) {
    let us = |d: Duration| d.as_secs_f64() * 1e6;
    for column in Extra::ALL {
        ws.extra[column.at()] = match column {
            Extra::Fresh => f64::from(u8::from(fresh)),
            Extra::Status => status,
            Extra::Reason => reason,
            Extra::Attempts => f64::from(io.attempts()),
            Extra::CommErrors => f64::from(consecutive),
            Extra::Read => us(timing.read),
            Extra::Compute => us(timing.compute),
            Extra::Write => us(timing.write),
            Extra::Late => us(timing.late),
            Extra::Overrun => f64::from(u8::from(timing.overrun)),
            Extra::ClampLow => f64::from(clamps.low),
            Extra::ClampHigh => f64::from(clamps.high),
            Extra::Age => timing.age * 1e6,
            Extra::Period => timing.interval * 1e6,
            Extra::Hold => timing.hold * 1e6,
            Extra::HoldExcess => timing.hold_excess * 1e6,
            Extra::GainScale => timing.gain_scale,
            Extra::Sampled => timing.sampled * 1e6,
            Extra::Step => ws.mark.map_or(f64::NAN, |m| m.step as f64),
            Extra::Rest => f64::from(u8::from(fresh && ws.mark.is_some_and(|m| m.rest))),
        };
    }
    let (n, nq) = (ws.tensions.len(), ws.q.len());
    let row = if fresh {
        ws.extra[FIXED_EXTRA..FIXED_EXTRA + n].copy_from_slice(&ws.tensions);
        ws.extra[FIXED_EXTRA + n..FIXED_EXTRA + n + nq].copy_from_slice(&ws.q_used);
        for (slot, &register) in ws.extra[FIXED_EXTRA + n + nq..]
            .iter_mut()
            .zip(&ws.currents)
        {
            *slot = f64::from(register) * ws.current_unit;
        }
        Row {
            t,
            q: &ws.q,
            qd: &ws.qd,
            tau: controller.tau(),
            tau_nom: controller.tau_nom(),
            b: &ws.barriers,
            extra: &ws.extra,
        }
    } else {
        ws.extra[FIXED_EXTRA..].fill(f64::NAN);
        Row {
            t,
            q: &ws.nan_q,
            qd: &ws.nan_q,
            tau: controller.tau(),
            tau_nom: &ws.nan_q,
            b: &ws.nan_b,
            extra: &ws.extra,
        }
    };
    // A log that fails is reported at the stop; the loop goes on.
    if let Err(e) = log.push(&row) {
        ws.log_error.get_or_insert(e);
    }
}
