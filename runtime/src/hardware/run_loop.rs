//! `softcbf run`: the fixed-rate loop sync read → mapping → [`control::tick`] → tensions →
//! sync write, with the safe start and safe stop of [`servo_io`], a log row every tick and
//! a summary at the end.
//!
//! A tick without a fresh reading of every servo (after the retries of the robot file's
//! `[hardware]` table) sends nothing: the servos keep the previous command, the tick is
//! counted as held, and `max_consecutive_errors` held ticks in a row stop the run. Ticks
//! are scheduled at `start + k / rate`; a tick whose write ends after the next tick's start
//! is an overrun, and the next tick then starts at once (no burst to catch up).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use softcbf_codegen::hardware::VelocitySource;

use crate::control::{
    self, Controller, ControllerError, ControllerSettings, Reference, TickStatus,
};
use crate::hardware::emulator::wait_until;
use crate::hardware::mapping::{Clamps, TendonMap};
use crate::hardware::servo_io::{self, ServoIo, ServoPort, StartError};
use crate::model::Model;
use crate::protocol::{Bus, BusCounters};

/// What one run does.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSettings {
    /// Loop rate \[Hz\] (the paper: 33).
    pub rate: f64,
    /// Stop after this long \[s\]; `None`: until interrupted.
    pub duration: Option<f64>,
    /// Set point `q̄` (length `nq`).
    pub set_point: Vec<f64>,
    /// Run the safety filter (`false`: plain PD+).
    pub filter: bool,
}

/// Why a run ended.
#[derive(Clone, Debug, PartialEq)]
pub enum StopReason {
    /// The duration elapsed.
    Duration,
    /// Ctrl-C (or SIGTERM).
    Interrupted,
    /// `max_consecutive_errors` ticks in a row without a good reading.
    CommunicationLost {
        /// Held ticks in a row.
        ticks: u32,
        /// The last bus error.
        last_error: String,
    },
    /// A servo reported a hardware error, the port failed, or the log could not be written.
    Fault(String),
}

impl StopReason {
    /// Whether the run ended on a fault (the command then exits non-zero).
    pub fn is_fault(&self) -> bool {
        matches!(
            self,
            StopReason::CommunicationLost { .. } | StopReason::Fault(_)
        )
    }
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StopReason::Duration => write!(f, "duration elapsed"),
            StopReason::Interrupted => write!(f, "interrupted"),
            StopReason::CommunicationLost { ticks, last_error } => {
                write!(
                    f,
                    "communication lost: {ticks} ticks in a row without a good reading (last: {last_error})"
                )
            }
            StopReason::Fault(what) => write!(f, "fault: {what}"),
        }
    }
}

/// Why a run could not start.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A setting is unusable.
    #[error("{0}")]
    Setting(String),
    /// The controller could not be built.
    #[error(transparent)]
    Controller(#[from] ControllerError),
    /// The safe start refused to enable torque (torque was then switched off everywhere).
    #[error("safe start failed, torque left off: {0}")]
    Start(#[from] StartError),
}

/// What happened in a run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSummary {
    /// Why it ended.
    pub stop: StopReason,
    /// Ticks run.
    pub ticks: u64,
    /// Ticks that sent a command computed from a fresh reading.
    pub commands: u64,
    /// Ticks without a fresh reading (nothing sent).
    pub held: u64,
    /// Ticks whose command was the controller's safe fallback.
    pub fallbacks: u64,
    /// Ticks that missed their deadline.
    pub overruns: u64,
    /// Tensions held at their limits, summed over ticks.
    pub clamps: Clamps,
    /// Bus event counts.
    pub bus: BusCounters,
    /// Smallest barrier value seen \[m\].
    pub min_barrier: f64,
    /// Time from the first tick to the stop \[s\].
    pub elapsed: f64,
    /// Largest software time of one tick (mapping, controller, tensions) \[s\].
    pub max_compute: f64,
    /// Per servo (bus order): whether its torque-off was confirmed at the stop.
    pub torque_off: Vec<(u8, bool)>,
}

impl RunSummary {
    /// Ticks per second reached.
    pub fn rate(&self) -> f64 {
        if self.elapsed > 0.0 {
            self.ticks as f64 / self.elapsed
        } else {
            0.0
        }
    }
}

use crate::hardware::log::FIXED_EXTRA;
pub use crate::hardware::log::{RunLog, extra_columns};
pub use crate::record::Row;

/// Sync-read retries allowed for the safe start's reading (torque is still off).
const START_READ_RETRIES: u32 = 9;

fn status_code(status: TickStatus) -> f64 {
    match status {
        TickStatus::Unfiltered => 0.0,
        TickStatus::Filtered => 1.0,
        TickStatus::Relaxed => 2.0,
        TickStatus::QpFailed => 3.0,
        TickStatus::InvalidState(_) => 4.0,
    }
}

/// The loop's preallocated workspace.
struct Workspace {
    angles: Vec<f64>,
    rates: Vec<f64>,
    q: Vec<f64>,
    qd: Vec<f64>,
    q_prev: Vec<f64>,
    tensions: Vec<f64>,
    currents: Vec<i16>,
    zeros: Vec<f64>,
    nan_q: Vec<f64>,
    nan_b: Vec<f64>,
    extra: Vec<f64>,
    /// The first failure of the log, reported at the stop.
    log_error: Option<String>,
}

/// Runs the controller on the servos behind `bus` until the duration, `stop`, or a fault.
/// Safe start first (on failure torque is switched off and the error returned), safe stop
/// always. `log` gets one row per tick and is flushed at the stop.
pub fn run<P: ServoPort>(
    model: &Model,
    map: &TendonMap,
    bus: &mut Bus<P>,
    settings: &RunSettings,
    log: &mut dyn RunLog,
    stop: &AtomicBool,
) -> Result<RunSummary, RunError> {
    let nq = model.nq();
    if settings.set_point.len() != nq || settings.set_point.iter().any(|v| !v.is_finite()) {
        return Err(RunError::Setting(format!(
            "the set point needs {nq} finite values"
        )));
    }
    if !(settings.rate.is_finite() && settings.rate > 0.0) {
        return Err(RunError::Setting(format!(
            "the rate must be > 0 Hz, got {}",
            settings.rate
        )));
    }
    let hardware = map.hardware();
    let mut controller_settings = ControllerSettings::paper(model);
    controller_settings.filter = settings.filter;
    // The filter chooses among the commands the cables can realize.
    controller_settings.input_limits = map.tension_limit_rows();
    if hardware.hold_correction {
        controller_settings.hold_correction = 1.0 / settings.rate;
    }
    let mut controller = Controller::new(model, controller_settings)?;
    let n = map.n_servos();
    let mut io = ServoIo::new(hardware.servo_ids());
    let mut ws = Workspace {
        angles: vec![0.0; n],
        rates: vec![0.0; n],
        q: vec![0.0; nq],
        qd: vec![0.0; nq],
        q_prev: vec![0.0; nq],
        tensions: vec![0.0; n],
        currents: vec![0; n],
        zeros: vec![0.0; nq],
        nan_q: vec![f64::NAN; nq],
        nan_b: vec![f64::NAN; model.nb()],
        extra: vec![0.0; FIXED_EXTRA + n],
        log_error: None,
    };

    // Safe start.
    let start_result = (|| {
        servo_io::prepare(bus, io.ids(), hardware.model_number)?;
        io.read_states(bus, START_READ_RETRIES)
            .map_err(StartError::State)?;
        measure(
            map,
            &io,
            &mut ws,
            VelocitySource::Servo,
            0.0,
            hardware.velocity_filter,
        );
        if !(ws.q.iter().chain(&ws.qd).all(|v| v.is_finite())) {
            return Err(StartError::NonFinite {
                q: ws.q.clone(),
                qd: ws.qd.clone(),
            });
        }
        // Taut cables (f_min) before torque on.
        map.tensions_from_tau(&ws.zeros, &mut ws.tensions);
        for (k, f) in ws.tensions.iter().enumerate() {
            ws.currents[k] = map.current_from_tension(k, *f);
        }
        io.write_currents(bus, &ws.currents)
            .map_err(StartError::State)?;
        servo_io::enable_torque(bus, io.ids())
    })();
    if let Err(error) = start_result {
        servo_io::safe_stop(bus, &mut io);
        return Err(error.into());
    }
    ws.qd.fill(0.0);
    ws.q_prev.copy_from_slice(&ws.q);
    bus.reset_counters();

    let period = Duration::from_secs_f64(1.0 / settings.rate);
    let start = Instant::now();
    let mut next = start;
    let mut last_reading: Option<Instant> = None;
    let mut summary = RunSummary {
        stop: StopReason::Duration,
        ticks: 0,
        commands: 0,
        held: 0,
        fallbacks: 0,
        overruns: 0,
        clamps: Clamps::default(),
        bus: BusCounters::default(),
        min_barrier: f64::INFINITY,
        elapsed: 0.0,
        max_compute: 0.0,
        torque_off: Vec::new(),
    };
    let mut consecutive = 0u32;
    let alerts_at_start = bus.counters().alerts;
    let stop_reason = loop {
        if stop.load(Ordering::Relaxed) {
            break StopReason::Interrupted;
        }
        if settings
            .duration
            .is_some_and(|d| next.duration_since(start).as_secs_f64() >= d)
        {
            break StopReason::Duration;
        }
        wait_until(next);
        let tick_start = Instant::now();
        let late = tick_start.duration_since(next);
        summary.ticks += 1;
        let read = io.read_states(bus, hardware.retries);
        let read_done = Instant::now();
        let t = read_done.duration_since(start).as_secs_f64();
        let mut write_time = Duration::ZERO;
        let mut compute_time = Duration::ZERO;
        let mut clamps = Clamps::default();
        let fresh;
        let status;
        match read {
            Ok(()) => {
                consecutive = 0;
                let dt = last_reading.map_or(0.0, |l| read_done.duration_since(l).as_secs_f64());
                last_reading = Some(read_done);
                measure(
                    map,
                    &io,
                    &mut ws,
                    hardware.velocity_source,
                    dt,
                    hardware.velocity_filter,
                );
                let tick_status = control::tick(
                    model,
                    &mut controller,
                    &ws.q,
                    &ws.qd,
                    Reference {
                        q: &settings.set_point,
                        qd: &ws.zeros,
                        qdd: &ws.zeros,
                    },
                );
                clamps = map.tensions_from_tau(controller.tau(), &mut ws.tensions);
                for (k, f) in ws.tensions.iter().enumerate() {
                    ws.currents[k] = map.current_from_tension(k, *f);
                }
                let computed = Instant::now();
                compute_time = computed.duration_since(read_done);
                let written = io.write_currents(bus, &ws.currents);
                write_time = computed.elapsed();
                if let Err(error) = written {
                    break StopReason::Fault(format!("cannot write the goal currents: {error}"));
                }
                summary.commands += 1;
                if tick_status.is_fallback() {
                    summary.fallbacks += 1;
                }
                summary.clamps.add(clamps);
                for b in controller.barriers() {
                    summary.min_barrier = summary.min_barrier.min(*b);
                }
                summary.max_compute = summary.max_compute.max(compute_time.as_secs_f64());
                fresh = 1.0;
                status = status_code(tick_status);
            }
            Err(error) => {
                consecutive += 1;
                summary.held += 1;
                fresh = 0.0;
                status = -1.0;
                if consecutive >= hardware.max_consecutive_errors {
                    push_row(
                        log,
                        &mut ws,
                        None,
                        t,
                        &controller,
                        [fresh, status],
                        &io,
                        consecutive,
                        late,
                        read_done - tick_start,
                        compute_time,
                        write_time,
                        false,
                        clamps,
                    );
                    break StopReason::CommunicationLost {
                        ticks: consecutive,
                        last_error: error.to_string(),
                    };
                }
            }
        }
        let end = Instant::now();
        let overrun = end > next + period;
        if overrun {
            summary.overruns += 1;
        }
        let reading = (fresh == 1.0).then_some(());
        push_row(
            log,
            &mut ws,
            reading,
            t,
            &controller,
            [fresh, status],
            &io,
            consecutive,
            late,
            read_done - tick_start,
            compute_time,
            write_time,
            overrun,
            clamps,
        );
        if bus.counters().alerts > alerts_at_start {
            break StopReason::Fault(
                "a servo reports a hardware error (alert bit); read its Hardware Error Status"
                    .into(),
            );
        }
        next += period;
        if next < end {
            next = end;
        }
    };
    summary.elapsed = start.elapsed().as_secs_f64();
    let confirmed = servo_io::safe_stop(bus, &mut io);
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

/// `q` from the servo angles, and `q̇` from the servos or from filtered differences over
/// `dt` seconds (`dt = 0`: no previous reading, `q̇` unchanged).
fn measure(
    map: &TendonMap,
    io: &ServoIo,
    ws: &mut Workspace,
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
    ws: &mut Workspace,
    reading: Option<()>,
    t: f64,
    controller: &Controller,
    [fresh, status]: [f64; 2],
    io: &ServoIo,
    consecutive: u32,
    late: Duration,
    read: Duration,
    compute: Duration,
    write: Duration,
    overrun: bool,
    clamps: Clamps,
) {
    let us = |d: Duration| d.as_secs_f64() * 1e6;
    let fixed = [
        fresh,
        status,
        f64::from(io.attempts()),
        f64::from(consecutive),
        us(read),
        us(compute),
        us(write),
        us(late),
        f64::from(u8::from(overrun)),
        f64::from(clamps.low),
        f64::from(clamps.high),
    ];
    ws.extra[..FIXED_EXTRA].copy_from_slice(&fixed);
    let n = ws.tensions.len();
    let row = if reading.is_some() {
        ws.extra[FIXED_EXTRA..].copy_from_slice(&ws.tensions);
        Row {
            t,
            q: &ws.q,
            qd: &ws.qd,
            tau: controller.tau(),
            tau_nom: controller.tau_nom(),
            b: controller.barriers(),
            extra: &ws.extra,
        }
    } else {
        ws.extra[FIXED_EXTRA..FIXED_EXTRA + n].fill(f64::NAN);
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
