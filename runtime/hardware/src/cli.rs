//! The `softcbf emulate` and `softcbf run` subcommands: options (each checked by the same
//! rule as the robot file's field, [`crate::hardware_description::limits`]), ports, the summary and the
//! exit status. The work itself is in [`super::emulator`] and [`super::run_loop`];
//! `softcbf run --experiment` drives [`super::experiment`].

use std::path::{Path, PathBuf};
use std::time::Duration;

use clap::Args;
use softcbf_description::limits::{self, Limit};
use softcbf_description::robot::Robot;

use crate::bus_check::{self, BusTiming, LatencyTimer, RateChoice, RateRule};
use crate::control::SafetyMode;
use crate::emulator::{self, EmulatorSettings, Faults, Preset};
use crate::exit;
use crate::experiment::{
    self as experiment, Experiment, ExperimentKind, ExperimentReport, ExperimentSettings,
};
use crate::hardware_description::limits as servo;
use crate::hardware_description::{self as description, Hardware};
use crate::mapping::TendonMap;
use crate::model::Model;
use crate::output::{Console, output_directory};
use crate::protocol::Bus;
use crate::run_loop::{self, RunError, RunSettings, RunSummary, StartReport, StopReason, Verdict};
use crate::settings::{
    Described, GainOptions, ScenarioGains, SettingsReport, Source, Sourced, check_number,
    file_name, resolve_gains, software, vector_text,
};
use crate::signal;
use crate::sim::BarrierMinimum;
use crate::status_line::{ExperimentProgress, StatusLine};
use crate::summary_file::{
    self, BusCheck, Clamps, ExperimentDesign, ExperimentSummary, HardwareSummary, LevelSummary,
    Lowest, TorqueOff,
};
use crate::verdict::Limits as VerdictLimits;
use softcbf_description::toml_file::shell_word;
use softcbf_outputs::parse::{parse_coordinates, parse_number};

/// Options of `softcbf emulate`.
#[derive(Args, Debug)]
pub struct EmulateArgs {
    /// Robot file with a `[hardware]` table (e.g. robots/hardware-example.toml).
    #[arg(long)]
    pub robot: PathBuf,
    /// Baud rate used to pace replies (bit/s) (default: the robot file's).
    #[arg(long, allow_negative_numbers = true)]
    pub baud: Option<i64>,
    /// Realism to start from: `ideal` (replies as soon as the wire allows, exact readings)
    /// or `factory` (also `realistic`: an FTDI adapter such as the U2D2 and X-series servos
    /// as shipped: latency timer 16 ms, Return Delay Time 500 µs, noise of 1 unit). The
    /// options below win over it.
    #[arg(long, value_name = "NAME", default_value = "ideal", value_parser = Preset::parse)]
    pub preset: Preset,
    /// A second robot file, the "true" robot: its numbers (stiffness, damping, masses,
    /// geometry) move the servos, while IDs, units and calibration come from --robot. It
    /// must have the same structure.
    #[arg(long, value_name = "FILE")]
    pub plant: Option<PathBuf>,
    /// Latency timer of the USB adapter (ms), 0 to 255: bytes from the servos reach the
    /// host when it expires or 62 of them fill a USB packet (FTDI's factory value 16; 1 is
    /// the usual tuned one; 0: no adapter) (default: the preset's).
    #[arg(long, allow_negative_numbers = true)]
    pub latency_timer_ms: Option<i64>,
    /// Return Delay Time of the servos (µs), 0 to 508 (X-series factory default 500; 0 is
    /// usual) (default: the preset's). A write to the register changes it.
    #[arg(long, allow_negative_numbers = true)]
    pub return_delay_us: Option<f64>,
    /// Standard deviation of Gaussian noise on Present Position, in position units, 0 to
    /// 1000 (default: the preset's).
    #[arg(long, allow_negative_numbers = true)]
    pub noise_position: Option<f64>,
    /// Standard deviation of Gaussian noise on Present Velocity, in velocity units, 0 to
    /// 1000 (default: the preset's).
    #[arg(long, allow_negative_numbers = true)]
    pub noise_velocity: Option<f64>,
    /// Fraction of status packets not sent (0..1).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub drop: f64,
    /// Fraction of status packets sent with a wrong CRC (0..1).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub corrupt: f64,
    /// Extra delay of delayed status packets (ms), 0 to 600000.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub delay_ms: f64,
    /// Fraction of status packets delayed by --delay-ms (0..1).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub delay_fraction: f64,
    /// ID of a servo that stops answering (it still obeys instructions).
    #[arg(long, allow_negative_numbers = true)]
    pub silent_servo: Option<i64>,
    /// Seconds after the first packet received (not the emulator's start) when
    /// --silent-servo falls silent.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub silent_after: f64,
    /// Seed of the fault draws and of the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Options of `softcbf run`.
#[derive(Args, Debug)]
pub struct RunArgs {
    /// Robot file with a `[hardware]` table.
    #[arg(long)]
    pub robot: PathBuf,
    /// Serial port of the servo bus (a USB adapter such as /dev/ttyUSB0, or the path
    /// `softcbf emulate` printed).
    #[arg(long)]
    pub port: String,
    /// Loop rate (Hz), 1 to 10000, or `auto`: the rate the bus allows, with a margin
    /// (default: 33, the paper's). A rate the bus cannot hold is refused at the start.
    #[arg(long, allow_hyphen_values = true)]
    pub rate: Option<String>,
    /// How the filter keeps the barriers between ticks: `certified`, `predicted`, `paper` or
    /// `hold-correction` (default: the robot file's `[hardware] safety`, else `certified`;
    /// docs/model.md §5).
    #[arg(long, value_name = "MODE", value_parser = SafetyMode::parse)]
    pub safety: Option<SafetyMode>,
    /// Lowest rate the loop may fall to (a slow bus) before it stops safely (Hz)
    /// (default: half of the loop rate; with --rate auto at most 16.5 Hz).
    #[arg(long, allow_negative_numbers = true)]
    pub min_rate: Option<f64>,
    /// Stop after this many seconds (default: run until Ctrl-C). With --experiment
    /// dynamic: its length (default 60); with --experiment static: a cap.
    #[arg(long, allow_negative_numbers = true)]
    pub duration: Option<f64>,
    /// Set point `Δx,Δy,δL,…` (m) (default: the robot file's hardware.set_point).
    #[arg(long, allow_hyphen_values = true)]
    pub set_point: Option<String>,
    /// An identification experiment instead of a set point, under the safety filter:
    /// `static` (constant tension sets, each held until the robot is at rest) or
    /// `dynamic` (multisines in tension around three operating points). Then
    /// `softcbf identify` reads the log.
    #[arg(long, value_name = "NAME", value_parser = ExperimentKind::parse)]
    pub experiment: Option<ExperimentKind>,
    /// Experiment amplitude (N), one value or one per module: the static sets' increment,
    /// the largest deviation of a dynamic servo's multisine (default: from the robot
    /// file's stiffness, masses and limits, within half of the room the barriers leave).
    #[arg(long, value_name = "N[,N…]", allow_hyphen_values = true)]
    pub amplitude: Option<String>,
    /// Experiment base tension (N), one value or one per module: the static sets' base,
    /// the dynamic experiment's lowest operating point (default: f_min static, f_min +
    /// amplitude dynamic).
    #[arg(long, value_name = "N[,N…]", allow_hyphen_values = true)]
    pub base_tension: Option<String>,
    /// Static experiment: longest wait for a tension set to come to rest (s) (default 6);
    /// a set that does not is counted and left.
    #[arg(long, allow_negative_numbers = true)]
    pub step_time: Option<f64>,
    /// Static experiment: the band within which every coordinate counts as at rest (m)
    /// (default 3e-4): over 0.5 s, its standard deviation at most this over 2√2 (a
    /// sinusoid spanning it) and its mean drifting by at most half of it.
    #[arg(long, allow_negative_numbers = true)]
    pub rest_threshold: Option<f64>,
    /// Experiment: how far the robot may be from its file, a fraction of its stiffness,
    /// damping and actuator gains (default 0.5): the first level of the amplitudes is safe
    /// for any robot within it, the next ones grow from what the barriers did.
    #[arg(long, value_name = "FRACTION", allow_negative_numbers = true)]
    pub experiment_uncertainty: Option<f64>,
    /// Experiment: stop (cables to f_min, then torque off) when a barrier at the state read
    /// falls below this (m, or rad for a bend limit) (default 1e-3).
    #[arg(long, allow_negative_numbers = true)]
    pub stop_distance: Option<f64>,
    /// Experiment: grow the amplitudes only while every barrier, extrapolated from what it
    /// did at the levels run, stays above this (m, or rad) (default 3e-3).
    #[arg(long, allow_negative_numbers = true)]
    pub growth_distance: Option<f64>,
    /// Proportional gain K_P = kp·I (N/m) (default: the robot file's `[gains] kp`, else 5).
    #[arg(long, allow_negative_numbers = true)]
    pub kp: Option<f64>,
    /// Derivative gain K_D = kd·I (N·s/m) (default: the robot file's `[gains] kd`, else 1).
    #[arg(long, allow_negative_numbers = true)]
    pub kd: Option<f64>,
    /// Both HOCBF class-K gains p1 = p2 (1/s) (default: the robot file's `[barrier]`).
    #[arg(long, allow_negative_numbers = true)]
    pub p: Option<f64>,
    /// HOCBF class-K gain p1 (1/s).
    #[arg(long, allow_negative_numbers = true)]
    pub p1: Option<f64>,
    /// HOCBF class-K gain p2 (1/s).
    #[arg(long, allow_negative_numbers = true)]
    pub p2: Option<f64>,
    /// Plain PD+ without the safety filter.
    #[arg(long)]
    pub no_filter: bool,
    /// No live status line on the terminal (it is drawn only when standard error is one).
    #[arg(long)]
    pub quiet: bool,
    /// Compute each command at the state read, not at the state predicted for when the
    /// command reaches the servos.
    #[arg(long)]
    pub no_prediction: bool,
    /// A run whose lowest barrier falls below this (m) is unsafe (exit status 3).
    #[arg(long, default_value_t = limits::DEFAULT_BARRIER_THRESHOLD, allow_negative_numbers = true)]
    pub barrier_threshold: f64,
    /// The fraction of ticks that may overrun their deadline, and of commands their hold,
    /// before the run is unsafe (exit status 3), 0 to 1 (default 0.05: one in twenty).
    #[arg(long, value_name = "F", allow_negative_numbers = true)]
    pub max_overrun_fraction: Option<f64>,
    /// The servos' Bus Watchdog (ms): they stop by themselves when no instruction comes for
    /// this long (a killed host); 0 turns it off (firmware older than v38). Default: three
    /// periods at --min-rate, at least 100 ms.
    #[arg(long, allow_negative_numbers = true)]
    pub bus_watchdog_ms: Option<f64>,
    /// Directory for the log and figures.
    #[arg(long, default_value = "out/run")]
    pub out: PathBuf,
    /// Also write the run as an MCAP log, `run.mcap`, after it ends (from trajectory.csv,
    /// summary.json and hardware.json; README.md, "MCAP logs").
    #[arg(long)]
    pub mcap: bool,
    /// Baud rate (bit/s) (default: the robot file's).
    #[arg(long, allow_negative_numbers = true)]
    pub baud: Option<i64>,
    /// Ticks in a row without a good reading before the safe stop, 1 to 1000 (default: the
    /// robot file's hardware.max_consecutive_errors).
    #[arg(long, allow_negative_numbers = true)]
    pub max_errors: Option<i64>,
    /// Longest wait for one status packet (ms) (default: the robot file's
    /// hardware.reply_timeout_ms). It must exceed the USB adapter's latency timer: 40 with
    /// a factory-set one (16 ms), or the emulator's `--preset factory`.
    #[arg(long, allow_negative_numbers = true)]
    pub reply_timeout_ms: Option<f64>,
}

/// The loop rate of `softcbf run` when `--rate` is not given \[Hz\] (the paper's 33 Hz).
pub const DEFAULT_RATE: f64 = 33.0;

/// A robot file and its hardware, read and checked.
fn load(path: &Path) -> Result<(Robot, Hardware), String> {
    let robot = Robot::load(path).map_err(|e| e.to_string())?;
    match description::load(&robot) {
        Ok(Some(hardware)) => Ok((robot, hardware)),
        Ok(None) => Err(format!(
            "{}: no [hardware] table (see robots/README.md)",
            path.display()
        )),
        Err(error) => Err(error.to_string()),
    }
}

/// The plant robot of `--plant`, if given: read, checked and of `robot`'s structure.
pub fn plant_robot(args: &EmulateArgs, robot: &Robot) -> Result<Option<Robot>, String> {
    let Some(path) = &args.plant else {
        return Ok(None);
    };
    let plant = Robot::load(path).map_err(|e| format!("--plant: {e}"))?;
    emulator::check_plant(robot, &plant).map_err(|e| format!("--plant: {e}"))?;
    Ok(Some(plant))
}

/// One line saying how real the emulator is asked to be.
pub fn realism_line(args: &EmulateArgs, settings: &EmulatorSettings) -> String {
    let mut parts = vec![format!("preset {}", args.preset.name())];
    parts.push(if settings.latency_timer.is_zero() {
        "no adapter latency".to_string()
    } else {
        format!(
            "adapter latency timer {} ms",
            settings.latency_timer.as_millis()
        )
    });
    parts.push(format!(
        "return delay {} µs",
        settings.return_delay.as_micros()
    ));
    parts.push(if settings.noise.is_on() {
        format!(
            "noise σ {} position / {} velocity units (seed {})",
            settings.noise.position, settings.noise.velocity, settings.noise.seed
        )
    } else {
        "no noise".to_string()
    });
    if let Some(path) = &args.plant {
        parts.push(format!("plant {}", path.display()));
    }
    format!("realism: {}", parts.join(", "))
}

/// The emulator's settings from its options, each checked against its range (the plant
/// robot is [`plant_robot`]'s).
pub fn emulator_settings(
    args: &EmulateArgs,
    hardware: &Hardware,
) -> Result<EmulatorSettings, String> {
    let baud = match args.baud {
        Some(b) => servo::check_baud(b).map_err(|m| format!("--baud: {m}"))?,
        None => hardware.baud,
    };
    let delay = check_number("--delay-ms", args.delay_ms, &servo::DELAY_MS)?;
    let silent_after = check_number("--silent-after", args.silent_after, &servo::SILENT_AFTER_S)?;
    let silent_servo = match args.silent_servo {
        Some(id) => {
            let id = servo::SERVO_ID
                .check_integer(id)
                .map_err(|m| format!("--silent-servo: {m}"))?;
            let ids = hardware.servo_ids();
            if !ids.iter().any(|&s| i64::from(s) == id) {
                return Err(format!(
                    "--silent-servo: the robot has no servo {id} (its servos: {ids:?})"
                ));
            }
            Some(id as u8)
        }
        None => None,
    };
    let mut settings = EmulatorSettings::new(baud);
    args.preset.apply(&mut settings);
    if let Some(us) = args.return_delay_us {
        let us = check_number("--return-delay-us", us, &servo::RETURN_DELAY_US)?;
        settings.return_delay = Duration::from_secs_f64(us * 1e-6);
    }
    if let Some(ms) = args.latency_timer_ms {
        let ms = servo::LATENCY_TIMER_MS
            .check_integer(ms)
            .map_err(|m| format!("--latency-timer-ms: {m}"))?;
        settings.latency_timer = Duration::from_millis(ms.unsigned_abs());
    }
    if let Some(units) = args.noise_position {
        settings.noise.position = check_number("--noise-position", units, &servo::NOISE_UNITS)?;
    }
    if let Some(units) = args.noise_velocity {
        settings.noise.velocity = check_number("--noise-velocity", units, &servo::NOISE_UNITS)?;
    }
    settings.noise.seed = args.seed;
    settings.faults = Faults {
        drop: check_number("--drop", args.drop, &servo::FRACTION)?,
        corrupt: check_number("--corrupt", args.corrupt, &servo::FRACTION)?,
        delay: Duration::from_secs_f64(delay / 1000.0),
        delay_fraction: check_number("--delay-fraction", args.delay_fraction, &servo::FRACTION)?,
        silent_servo,
        silent_after: Duration::from_secs_f64(silent_after),
        seed: args.seed,
    };
    Ok(settings)
}

/// `softcbf emulate`: serves until a terminating signal; the exit status.
#[cfg(unix)]
pub fn emulate(args: EmulateArgs, console: &mut Console) -> Result<u8, String> {
    use serialport::{SerialPort, TTYPort};
    let stop = signal::stop_flag();
    let (robot, hardware) = load(&args.robot)?;
    let mut settings = emulator_settings(&args, &hardware)?;
    settings.plant = plant_robot(&args, &robot)?;
    let realism = realism_line(&args, &settings);
    let (mut master, slave) =
        TTYPort::pair().map_err(|e| format!("cannot open a pseudo-terminal: {e}"))?;
    master
        .set_timeout(Duration::from_millis(20))
        .map_err(|e| e.to_string())?;
    let path = slave.name().unwrap_or_default();
    let ids: Vec<String> = hardware
        .servo_ids()
        .iter()
        .map(|id| id.to_string())
        .collect();
    let baud = settings.baud;
    // The command printed works as printed: with the reply timeout this adapter needs
    // when the robot file's is shorter.
    let timer_ms = u32::try_from(settings.latency_timer.as_millis()).unwrap_or(u32::MAX);
    let needed = bus_check::reply_timeout_needed_ms(timer_ms);
    let timeout_option = if hardware.reply_timeout * 1000.0 < needed {
        format!(" --reply-timeout-ms {needed}")
    } else {
        String::new()
    };
    let baud_option = if baud == hardware.baud {
        String::new()
    } else {
        format!(" --baud {baud}")
    };
    let mut announce = || {
        console.say(&format!(
            "softcbf emulate: servos {} of `{}` at {baud} bit/s",
            ids.join(", "),
            robot.name
        ));
        console.say(&realism);
        console.say(&format!("port: {path}"));
        if !timeout_option.is_empty() {
            console.say(&format!(
                "note: the adapter's {timer_ms} ms latency timer holds replies longer than \
                 the robot file's reply timeout ({} ms): runs need --reply-timeout-ms {needed}",
                hardware.reply_timeout * 1000.0
            ));
        }
        console.say(&format!(
            "connect with: softcbf run --robot {} --port {path}{baud_option}{timeout_option}",
            shell_word(&args.robot)
        ));
        console.say("Ctrl-C to stop");
    };
    let log = emulator::serve(&robot, &settings, &mut master, stop, &mut announce, None)
        .map_err(|e| e.to_string())?;
    drop(slave);
    let why = signal::received().map_or("stopped".to_string(), |s| {
        format!("stopped by {}", signal::name(s))
    });
    console.say(&format!(
        "emulator {why}: {} requests; status packets sent {}, delayed {}, dropped {}, corrupted {}, silent {}",
        log.requests, log.fates[0], log.fates[1], log.fates[2], log.fates[3], log.fates[4]
    ));
    Ok(console.error().map_or(exit::OK, |_| exit::ERROR))
}

/// `softcbf emulate` needs a Unix pseudo-terminal.
#[cfg(not(unix))]
pub fn emulate(_args: EmulateArgs, _console: &mut Console) -> Result<u8, String> {
    Err("softcbf emulate needs a Unix pseudo-terminal".into())
}

/// The run's settings from its options and the robot file, each checked against its range,
/// and what its verdict is judged by (threshold, overrun fraction). `hardware` receives the
/// command line's overrides.
pub fn run_settings(
    args: &RunArgs,
    robot: &Robot,
    hardware: &mut Hardware,
) -> Result<(RunSettings, VerdictLimits), String> {
    if let Some(baud) = args.baud {
        hardware.baud = servo::check_baud(baud).map_err(|m| format!("--baud: {m}"))?;
    }
    if args.safety.is_some() {
        hardware.safety = args.safety;
    }
    if let Some(n) = args.max_errors {
        hardware.max_consecutive_errors = servo::MAX_CONSECUTIVE_ERRORS
            .check_integer(n)
            .map_err(|m| format!("--max-errors: {m}"))?
            as u32;
    }
    if let Some(ms) = args.reply_timeout_ms {
        hardware.reply_timeout =
            check_number("--reply-timeout-ms", ms, &servo::REPLY_TIMEOUT_MS)? / 1000.0;
    }
    let default_set_point = hardware.set_point.clone();
    let (rate, rate_rule) = match args.rate.as_deref() {
        Some(text) => parse_rate(text)?,
        None => (DEFAULT_RATE, RateRule::Hold),
    };
    let set_point = match &args.set_point {
        Some(text) => parse_coordinates("--set-point", text, robot)?,
        None => default_set_point,
    };
    let mut settings = RunSettings::new(rate, set_point);
    settings.rate_rule = rate_rule;
    settings.experiment = experiment_settings(args)?;
    if let Some(min_rate) = args.min_rate {
        settings.min_rate = Some(check_number("--min-rate", min_rate, &limits::RATE_HZ)?);
    }
    if let Some(duration) = args.duration {
        let duration = check_number("--duration", duration, &limits::DURATION_S)?;
        // An experiment ends the run itself: its length, or its cap.
        match &mut settings.experiment {
            Some(experiment) => experiment.duration = Some(duration),
            None => settings.duration = Some(duration),
        }
    }
    if let Some(ms) = args.bus_watchdog_ms {
        settings.bus_watchdog =
            Some(check_number("--bus-watchdog-ms", ms, &servo::BUS_WATCHDOG_MS)? / 1000.0);
    }
    settings.filter = !args.no_filter;
    settings.predict = !args.no_prediction;
    let options = GainOptions::checked(args.kp, args.kd, args.p, args.p1, args.p2)?;
    settings.gains = Some(resolve_gains(&options, &ScenarioGains::default(), robot));
    settings.validate(3 * robot.modules.len())?;
    // The experiment on this robot at the rate asked (built again at the rate run at).
    if let Some(design) = &settings.experiment {
        Experiment::new(design, robot, &tension_limits(hardware), settings.rate)?;
    }
    let threshold = check_number(
        "--barrier-threshold",
        args.barrier_threshold,
        &limits::BARRIER_THRESHOLD_M,
    )?;
    let mut verdict_limits = VerdictLimits::new(threshold);
    if let Some(fraction) = args.max_overrun_fraction {
        verdict_limits.max_overrun_fraction =
            check_number("--max-overrun-fraction", fraction, &servo::FRACTION)?;
    }
    Ok((settings, verdict_limits))
}

/// Each module's `[f_min, f_max]` \[N\].
fn tension_limits(hardware: &Hardware) -> Vec<[f64; 2]> {
    hardware.modules.iter().map(|m| m.tension_limits).collect()
}

/// A list of one number, or one per module, given for option `name`, each in `limit`.
fn parse_list(name: &str, text: &str, limit: &Limit) -> Result<Vec<f64>, String> {
    text.split(',')
        .map(|part| parse_number(name, part, limit))
        .collect()
}

/// The experiment of `--experiment` and its options; options of an experiment without
/// one, and options of a set point with one, are refused.
fn experiment_settings(args: &RunArgs) -> Result<Option<ExperimentSettings>, String> {
    let Some(kind) = args.experiment else {
        for (given, name) in [
            (args.amplitude.is_some(), "--amplitude"),
            (args.base_tension.is_some(), "--base-tension"),
            (args.step_time.is_some(), "--step-time"),
            (args.rest_threshold.is_some(), "--rest-threshold"),
            (
                args.experiment_uncertainty.is_some(),
                "--experiment-uncertainty",
            ),
            (args.stop_distance.is_some(), "--stop-distance"),
            (args.growth_distance.is_some(), "--growth-distance"),
        ] {
            if given {
                return Err(format!(
                    "{name}: an option of --experiment; give --experiment static or dynamic"
                ));
            }
        }
        return Ok(None);
    };
    for (given, name, why) in [
        (
            args.set_point.is_some(),
            "--set-point",
            "an experiment commands tensions, not a set point",
        ),
        (
            args.no_filter,
            "--no-filter",
            "experiments run with the safety filter on",
        ),
        (
            args.kp.is_some() || args.kd.is_some(),
            if args.kp.is_some() { "--kp" } else { "--kd" },
            "an experiment commands tensions directly, without PD+",
        ),
    ] {
        if given {
            return Err(format!("{name}: not with --experiment: {why}"));
        }
    }
    let static_only = [
        (args.step_time.is_some(), "--step-time"),
        (args.rest_threshold.is_some(), "--rest-threshold"),
    ];
    if kind == ExperimentKind::Dynamic
        && let Some((_, name)) = static_only.iter().find(|(given, _)| *given)
    {
        return Err(format!(
            "{name}: an option of --experiment static, not dynamic"
        ));
    }
    let mut settings = ExperimentSettings::new(kind);
    if let Some(text) = &args.amplitude {
        settings.amplitude = Some(parse_list("--amplitude", text, &experiment::AMPLITUDE_N)?);
    }
    if let Some(text) = &args.base_tension {
        settings.base_tension = Some(parse_list(
            "--base-tension",
            text,
            &experiment::BASE_TENSION_N,
        )?);
    }
    if let Some(seconds) = args.step_time {
        settings.step_time = check_number("--step-time", seconds, &experiment::STEP_TIME_S)?;
    }
    if let Some(metres) = args.rest_threshold {
        settings.rest_threshold =
            check_number("--rest-threshold", metres, &experiment::REST_THRESHOLD_M)?;
    }
    if let Some(fraction) = args.experiment_uncertainty {
        settings.uncertainty = check_number(
            "--experiment-uncertainty",
            fraction,
            &experiment::EXPERIMENT_UNCERTAINTY,
        )?;
    }
    if let Some(metres) = args.stop_distance {
        settings.stop_distance =
            check_number("--stop-distance", metres, &experiment::GUARD_DISTANCE)?;
    }
    if let Some(metres) = args.growth_distance {
        settings.growth_distance =
            check_number("--growth-distance", metres, &experiment::GUARD_DISTANCE)?;
    }
    Ok(Some(settings))
}

/// `--rate`: a number of Hz in [`limits::RATE_HZ`], refused when the bus cannot hold it, or
/// `auto` (the fastest loop rate as the ceiling, adapted to the bus).
pub fn parse_rate(text: &str) -> Result<(f64, RateRule), String> {
    let text = text.trim();
    if text == "auto" {
        return Ok((limits::RATE_HZ.max, RateRule::Adapt));
    }
    let rate: f64 = text
        .parse()
        .map_err(|_| format!("--rate: `{text}` is neither a number of Hz nor `auto`"))?;
    Ok((
        check_number("--rate", rate, &limits::RATE_HZ)?,
        RateRule::Hold,
    ))
}

/// The adapter's latency timer of `port` (Linux only: elsewhere nothing is known).
fn port_latency_timer(port: &str) -> Option<LatencyTimer> {
    if cfg!(target_os = "linux") {
        Some(bus_check::latency_timer(
            Path::new(port),
            Path::new(bus_check::SYSFS),
        ))
    } else {
        None
    }
}

/// Prints the bus check and the rate decided as the run starts, and keeps the settings
/// report of the rate run at.
struct StartPrinter<'a> {
    console: &'a mut Console,
    args: &'a RunArgs,
    robot: &'a Robot,
    hardware: &'a Hardware,
    used: Option<SettingsReport>,
}

impl StartReport for StartPrinter<'_> {
    fn bus_measured(&mut self, timing: &BusTiming) {
        self.console.say(&timing.line());
    }

    fn running(&mut self, choice: RateChoice, settings: &RunSettings) {
        let rate = match choice {
            RateChoice::Asked(rate) => format!("{rate} Hz"),
            RateChoice::Adapted(rate) => format!(
                "{rate} Hz, chosen by --rate auto ({:.0} % of what the bus allows)",
                bus_check::AUTO_RATE_MARGIN * 100.0
            ),
            RateChoice::Overrunning(rate) => {
                format!("{rate} Hz, beyond what the bus allows: ticks back to back")
            }
        };
        let watchdog = settings.bus_watchdog();
        self.console.say(&format!(
            "loop: {rate}, at least {} Hz, prediction {}, bus watchdog {}",
            settings.min_rate(),
            if settings.predict { "on" } else { "off" },
            if watchdog > 0.0 {
                format!("{:.0} ms", watchdog * 1000.0)
            } else {
                "off".to_string()
            },
        ));
        let used = run_settings_report(self.args, self.robot, self.hardware, settings);
        self.console.say(&used.line());
        self.used = Some(used);
    }
}

/// `softcbf run`: the safe controller on the servos; the exit status says whether the run
/// was safe ([`crate::exit`]).
pub fn run(args: RunArgs, console: &mut Console) -> Result<u8, String> {
    // First, so that a signal at any later moment ends in the safe stop.
    let stop = signal::stop_flag();
    let (robot, mut hardware) = load(&args.robot)?;
    let (settings, limits) = run_settings(&args, &robot, &mut hardware)?;
    let planned = match &settings.experiment {
        Some(design) => Some(Experiment::new(
            design,
            &robot,
            &tension_limits(&hardware),
            settings.rate,
        )?),
        None => None,
    };
    // Before the first packet: a reply timeout the adapter's latency timer cannot meet.
    let latency = port_latency_timer(&args.port);
    if let Some(timer) = &latency {
        let source = if args.reply_timeout_ms.is_some() {
            "--reply-timeout-ms".to_string()
        } else {
            format!("hardware.reply_timeout_ms in {}", args.robot.display())
        };
        bus_check::check_reply_timeout(timer, hardware.reply_timeout * 1000.0, &source)?;
    }
    let map = TendonMap::with_hardware(&robot, hardware.clone()).map_err(|e| e.to_string())?;
    let model = Model::new(robot.clone()).map_err(|e| e.to_string())?;
    output_directory(&args.out, "--out")?;
    let port = serialport::new(&args.port, hardware.baud)
        .timeout(Duration::from_millis(1))
        .open()
        .map_err(|e| format!("--port: cannot open {}: {e}", args.port))?;
    let mut bus = Bus::new(port, Duration::from_secs_f64(hardware.reply_timeout));
    let log = super::log::open(&args.out, &model, map.hardware())?;
    console.say(&format!(
        "softcbf run: `{}` on {} at {} bit/s, {}",
        robot.name,
        args.port,
        hardware.baud,
        if settings.rate_rule == RateRule::Adapt {
            "rate auto (from the bus)".to_string()
        } else {
            format!("{} Hz asked", settings.rate)
        },
    ));
    for line in latency.iter().flat_map(LatencyTimer::lines) {
        console.say(&line);
    }
    let mut log = StatusLine::new(log, !args.quiet);
    if let Some(planned) = &planned {
        console.say(&experiment_line(planned));
        log = log.with_experiment(progress_plan(planned));
    }
    let mut printer = StartPrinter {
        console,
        args: &args,
        robot: &robot,
        hardware: &hardware,
        used: None,
    };
    let result = run_loop::run_reporting(
        &model,
        &map,
        &mut bus,
        &settings,
        &mut log,
        stop,
        &mut printer,
    );
    let used = printer.used.take();
    let summary = match result {
        Ok(summary) => summary,
        Err(error @ RunError::RateRefused(_)) => {
            let mut message = error.to_string();
            if let Some(LatencyTimer::Found { ms, .. }) = latency.as_ref().filter(|l| l.too_long())
            {
                message.push_str(&format!(
                    "; the adapter's latency timer of {ms} ms lengthens every reply: lower it \
                     to 1 ms (see above)"
                ));
            }
            return Err(message);
        }
        Err(error) => return Err(error.to_string()),
    };
    // Stopped before the rate was decided (a signal at the start): the settings asked.
    let used = used.unwrap_or_else(|| run_settings_report(&args, &robot, &hardware, &settings));
    let progress_error = log.console_error().map(str::to_string);
    let log = log.into_inner();
    report(&summary, &limits, console);
    // After a guard's stop the robot file (or the experiment's levels) needs looking at
    // first: `stopped:` said why.
    if let Some(experiment) = &summary.experiment
        && !summary.stop.is_fault()
        && experiment.stopped.is_none()
    {
        console.say(&super::next_step::after_experiment(
            experiment.settings.kind,
            &args.robot,
            &robot.name,
            &args.out,
            &args.port,
        ));
    }
    let verdict = summary.verdict(&limits);
    match &verdict {
        Verdict::Safe => {}
        Verdict::Unsafe(why) => eprintln!("error: unsafe run: {why}"),
        Verdict::NotRun(why) | Verdict::Fault(why) => eprintln!("error: {why}"),
    }
    let mut code = verdict.status();
    // An experiment its guard stopped did not do all it was asked (the robot is safe).
    if matches!(summary.stop, StopReason::ExperimentStopped { .. }) {
        code = exit::worst(code, exit::ERROR);
    }
    // The log is closed and drawn whatever becomes of the summary, and the other way round.
    // An experiment has no set point to draw or record.
    let set_point: &[f64] = match settings.experiment {
        Some(_) => &[],
        None => &settings.set_point,
    };
    let logged = super::log::finish(log, &args.out, settings.filter, set_point, &model);
    let latency_ms = match latency {
        Some(LatencyTimer::Found { ms, .. }) => Some(ms),
        _ => None,
    };
    let summarized = write_summary(&args.out, &used, set_point, &summary, &limits, latency_ms);
    // The MCAP log from the files just written (the CSV stays the log a crash leaves whole).
    let mcap = match (&logged, &summarized) {
        (Ok(_), Ok(_)) if args.mcap => Some(
            crate::mcap_log::write_directory(&args.out, &model)
                .map(|written| vec![written.path])
                .map_err(|e| e.to_string()),
        ),
        (_, _) if args.mcap => Some(Err(
            "not written: the log or the summary it is made from is missing".to_string(),
        )),
        _ => None,
    };
    let mut files = Vec::new();
    for (written, what) in [
        (logged, "the log or figures"),
        (summarized.map(|path| vec![path]), "the summary"),
        (mcap.unwrap_or(Ok(Vec::new())), "the MCAP log"),
    ] {
        match written {
            Ok(written) => files.extend(written),
            Err(e) => {
                eprintln!("error: {what} could not be written: {e}");
                code = exit::worst(code, exit::ERROR);
            }
        }
    }
    if !files.is_empty() {
        let names: Vec<String> = files.iter().map(|p| p.display().to_string()).collect();
        console.say(&format!("wrote {}", names.join(", ")));
    }
    if let Some(error) = console.error().map(str::to_string).or(progress_error) {
        eprintln!("error: {error}; the log is in {}", args.out.display());
        code = exit::worst(code, exit::ERROR);
    }
    Ok(code)
}

/// What the experiment will do, in one line: its steps, tensions per module and length.
fn experiment_line(experiment: &Experiment) -> String {
    let list = |values: &[f64]| {
        values
            .iter()
            .map(|v| format!("{v:.3}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let report = experiment.report();
    let [least, most] = experiment.expected_length();
    match experiment.kind() {
        ExperimentKind::Static => format!(
            "experiment: static, {} tension sets (base b + amplitude a on single tendons, \
             pairs, all three), b = [{}] N, a = [{}] N per module; each held until at rest \
             (spread and drift within {} m over {} s, at most {} s), then {} s of rest rows; {least:.0} to \
             {most:.0} s; levels from {:.0} % of a, growing ×{} while the barriers keep {} m \
             (robot within ±{:.0} % of its file), stop below {} m",
            report.steps,
            list(&report.base_tension),
            list(&report.amplitude),
            report.settings.rest_threshold,
            report.settings.quiet_window,
            report.settings.step_time,
            report.settings.rest_window,
            100.0 * report.start_scale,
            report.settings.growth,
            report.settings.growth_distance,
            100.0 * report.settings.uncertainty,
            report.settings.stop_distance,
        ),
        ExperimentKind::Dynamic => format!(
            "experiment: dynamic, {least:.0} s: multisines of amplitude [{}] N per module, \
             {} lines each from {:.2} to {:.2} Hz, around {} operating points from [{}] N; \
             levels from {:.0} %, reconsidered every {} s, growing ×{} while the barriers \
             keep {} m (robot within ±{:.0} % of its file), stop below {} m",
            list(&report.amplitude),
            report
                .lines_per_servo
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join("/"),
            report.band[0],
            report.band[1],
            report.steps,
            list(&report.base_tension),
            100.0 * report.start_scale,
            report.settings.check_window,
            report.settings.growth,
            report.settings.growth_distance,
            100.0 * report.settings.uncertainty,
            report.settings.stop_distance,
        ),
    }
}

/// What the progress lines need to know of `experiment`.
fn progress_plan(experiment: &Experiment) -> ExperimentProgress {
    let report = experiment.report();
    let s = &report.settings;
    ExperimentProgress {
        kind: experiment.kind(),
        steps: report.steps,
        step_length: match experiment.kind() {
            ExperimentKind::Static => s.settle_time.max(s.quiet_window) + s.rest_window,
            ExperimentKind::Dynamic => experiment.expected_length()[0] / report.steps.max(1) as f64,
        },
    }
}

/// Every setting of a run, with where it came from (command line, robot file, built-in).
pub fn run_settings_report(
    args: &RunArgs,
    robot: &Robot,
    hardware: &Hardware,
    settings: &RunSettings,
) -> SettingsReport {
    let nq = 3 * robot.modules.len();
    let gains = settings.gains_for(robot);
    let given = |option: bool| {
        if option {
            Source::CommandLine
        } else {
            Source::BuiltIn
        }
    };
    let (reference_source, hold_source) = (
        given(args.set_point.is_some()),
        if args.safety.is_some() {
            Source::CommandLine
        } else if hardware.safety.is_some() {
            Source::RobotFile
        } else {
            Source::BuiltIn
        },
    );
    SettingsReport {
        software: software(),
        robot: Described {
            name: robot.name.clone(),
            file: file_name(&robot.source),
        },
        scenario: None,
        filter: Sourced::new(settings.filter, given(args.no_filter)),
        gains: gains.report(nq),
        safety: Sourced::new(hardware.safety.unwrap_or_default(), hold_source),
        control_period: Sourced::new(1.0 / settings.rate, given(args.rate.is_some())),
        duration: match &settings.experiment {
            Some(experiment) => experiment
                .length()
                .map(|d| Sourced::new(d, given(args.duration.is_some()))),
            None => settings
                .duration
                .map(|d| Sourced::new(d, Source::CommandLine)),
        },
        reference: match &settings.experiment {
            Some(experiment) => Sourced::new(
                format!("experiment {}", experiment.kind.name()),
                Source::CommandLine,
            ),
            None => Sourced::new(
                format!("set point {}", vector_text(&settings.set_point)),
                if reference_source == Source::CommandLine {
                    Source::CommandLine
                } else {
                    Source::RobotFile
                },
            ),
        },
        integrator: None,
        record_period: None,
        plant: None,
        sensor_noise: None,
    }
}

/// Writes `dir/summary.json` ([`HardwareSummary`], which says what each field holds): the
/// settings, the verdict and the counts of a hardware run, with `controller` and
/// `set_point` as `softcbf simulate` writes them.
fn write_summary(
    dir: &Path,
    settings: &SettingsReport,
    set_point: &[f64],
    s: &RunSummary,
    limits: &VerdictLimits,
    latency_timer_ms: Option<u32>,
) -> Result<PathBuf, String> {
    let verdict = match s.verdict(limits) {
        Verdict::Safe => "safe".to_string(),
        Verdict::Unsafe(why) => format!("unsafe: {why}"),
        Verdict::NotRun(why) => format!("not run: {why}"),
        Verdict::Fault(why) => format!("fault: {why}"),
    };
    let finite = |v: f64| v.is_finite().then_some(v);
    let lowest = |b: &BarrierMinimum| Lowest {
        value: finite(b.value),
        label: b.label.to_string(),
        t: b.t,
        unit: b.unit.to_string(),
    };
    let summary = HardwareSummary {
        controller: if settings.filter.value {
            "filter"
        } else {
            "pd"
        }
        .to_string(),
        robot: settings.robot.name.clone(),
        hardware: true,
        set_point: (!set_point.is_empty()).then(|| set_point.to_vec()),
        verdict,
        stopped: s.stop.to_string(),
        ticks: s.ticks,
        commands: s.commands,
        held: s.held,
        fallbacks: s.fallbacks,
        invalid_state: s.invalid,
        relaxed: s.relaxed,
        uncertified: s.uncertified,
        uncertified_reasons: s.uncertified_reasons,
        unfiltered: s.unfiltered,
        interventions: s.interventions,
        deadline_overruns: s.deadlines.deadline_overruns,
        hold_overruns: s.deadlines.hold_overruns,
        longest_period: s.deadlines.longest_period,
        longest_hold_excess: s.deadlines.longest_hold_excess,
        elapsed: s.elapsed,
        rate: s.rate(),
        loop_rate: s.rate_choice.map(RateChoice::rate),
        rate_from_bus: matches!(s.rate_choice, Some(RateChoice::Adapted(_))),
        bus_check: s.bus_timing.map(|t| BusCheck {
            cycles: t.cycles,
            retried: t.retried,
            median: t.median,
            p90: t.slow,
            max: t.max,
            compute: t.compute,
            rate_limit: t.rate_limit(),
        }),
        latency_timer_ms,
        min_barrier: lowest(&s.min_barrier),
        lowest_by_kind: s
            .lowest_by_kind
            .iter()
            .map(|(group, b)| (group.key().to_string(), lowest(b)))
            .collect(),
        clamps: Clamps {
            low: s.clamps.low.into(),
            high: s.clamps.high.into(),
        },
        bus: summary_file::Bus {
            transactions: s.bus.transactions,
            replies: s.bus.replies,
            timeouts: s.bus.timeouts,
            crc_errors: s.bus.crc_errors,
            decode_errors: s.bus.decode_errors,
            wrong_id: s.bus.wrong_id,
            retries: s.bus.retries,
        },
        torque_off: s
            .torque_off
            .iter()
            .map(|&(id, confirmed)| TorqueOff { id, confirmed })
            .collect(),
        experiment: s.experiment.as_ref().map(experiment_summary),
        settings: serde_json::to_value(settings).unwrap_or_default(),
    };
    summary.write(dir)
}

/// The experiment of a run as `summary.json` holds it ([`ExperimentSummary`]).
fn experiment_summary(e: &ExperimentReport) -> ExperimentSummary {
    let s = &e.settings;
    let finite = |v: f64| v.is_finite().then_some(v);
    ExperimentSummary {
        duration: s.duration,
        base_tension: e.base_tension.clone(),
        amplitude: e.amplitude.clone(),
        steps: e.steps,
        steps_run: e.steps_run,
        steps_at_rest: e.steps_at_rest,
        steps_without_rest: e.steps_without_rest,
        rest_rows: e.rest_rows,
        complete: e.complete,
        uncertainty: s.uncertainty,
        stop_distance: s.stop_distance,
        growth_distance: s.growth_distance,
        growth: s.growth,
        start_scale: e.start_scale,
        levels: e
            .levels
            .iter()
            .map(|l| LevelSummary {
                scale: l.scale,
                lowest: finite(l.lowest),
                next: l.next,
                predicted: finite(l.predicted),
            })
            .collect(),
        stopped_by_guard: e.stopped.is_some(),
        synthetic: false,
        design: match s.kind {
            ExperimentKind::Static => ExperimentDesign::Static {
                step_time: Some(s.step_time),
                settle_time: Some(s.settle_time),
                ramp: Some(s.ramp),
                quiet_window: Some(s.quiet_window),
                rest_window: Some(s.rest_window),
                rest_threshold: Some(s.rest_threshold),
            },
            ExperimentKind::Dynamic => ExperimentDesign::Dynamic {
                fade: Some(s.fade),
                band: Some(e.band),
                resolution: Some(s.resolution),
                lines_per_servo: Some(e.lines_per_servo.clone()),
                operating_points: Some(e.operating_points.clone()),
            },
        },
    }
}

fn report(s: &RunSummary, limits: &VerdictLimits, console: &mut Console) {
    let threshold = limits.threshold;
    let b = &s.bus;
    let stop = match (&s.stop, signal::received()) {
        (StopReason::Interrupted, Some(number)) => {
            format!("interrupted by {}", signal::name(number))
        }
        (reason, _) => reason.to_string(),
    };
    console.say(&format!("stopped: {stop}"));
    console.say(&format!(
        "{} ticks in {:.2} s ({:.1} Hz): {} commands, {} held (no fresh reading), {} safe fallbacks ({} invalid states), {} relaxed, {} not proven over their hold, {} deadline overruns",
        s.ticks,
        s.elapsed,
        s.rate(),
        s.commands,
        s.held,
        s.fallbacks,
        s.invalid,
        s.relaxed,
        s.uncertified,
        s.deadlines.deadline_overruns
    ));
    if s.uncertified > 0 {
        console.say(&format!(
            "not proven, why: {}",
            s.uncertified_reasons.describe()
        ));
    }
    console.say(&format!(
        "deadlines: {} ticks overran (ended more than a period after they were due); {} \
         commands overran their hold (in force longer than the Δ they were computed for, by \
         at most {:.2} ms); longest in force {:.1} ms",
        s.deadlines.deadline_overruns,
        s.deadlines.hold_overruns,
        s.deadlines.longest_hold_excess * 1e3,
        s.deadlines.longest_period * 1e3
    ));
    console.say(&format!(
        "timing: oldest reading {:.1} ms when its command arrived, longest software time {:.1} µs{}",
        s.max_age * 1e3,
        s.max_compute * 1e6,
        if s.prediction_failures > 0 {
            format!(", {} predictions failed", s.prediction_failures)
        } else {
            String::new()
        }
    ));
    console.say(&format!(
        "tensions clamped: {} at f_min, {} at f_max; the filter changed {} of {} commands",
        s.clamps.low, s.clamps.high, s.interventions, s.commands
    ));
    if let Some(e) = &s.experiment {
        let counts = match e.settings.kind {
            ExperimentKind::Static => format!(
                "{} of {} steps run, {} came to rest ({} rest rows logged), {} did not within \
                 {} s",
                e.steps_run,
                e.steps,
                e.steps_at_rest,
                e.rest_rows,
                e.steps_without_rest,
                e.settings.step_time
            ),
            ExperimentKind::Dynamic => format!(
                "{} of {} operating points run{}",
                e.steps_run,
                e.steps,
                if e.complete { ", complete" } else { "" }
            ),
        };
        console.say(&format!("experiment: {}: {counts}", e.settings.kind.name()));
        if e.steps_without_rest > 0 {
            console.say(
                "experiment: a step without rest has no rest rows; a noisy robot may need a \
                 larger --rest-threshold, a slow one a longer --step-time",
            );
        }
    }
    console.say(&format!(
        "bus: {} requests, {} replies, {} timeouts, {} CRC errors, {} other corrupt, {} wrong ID, {} retries",
        b.transactions, b.replies, b.timeouts, b.crc_errors, b.decode_errors, b.wrong_id, b.retries
    ));
    let m = &s.min_barrier;
    if m.value.is_finite() {
        console.say(&format!(
            "lowest barrier {:.3e} {unit} ({}, t = {:.3} s); threshold {threshold:e} {unit}",
            m.value,
            m.label,
            m.t,
            unit = m.unit
        ));
        if let Some(per_kind) = s.lowest_by_kind.line() {
            console.say(&per_kind);
        }
    } else if s.commands > 0 {
        console.say("lowest barrier: not finite (a state outside the model)");
    }
    let off: Vec<String> = s
        .torque_off
        .iter()
        .map(|(id, ok)| format!("{id}:{}", if *ok { "off" } else { "unconfirmed" }))
        .collect();
    console.say(&format!("torque: {}", off.join(" ")));
    console.say(&format!(
        "verdict: {}",
        s.verdict(limits)
            .line_with_unproven(s.uncertified as usize, s.ticks as usize)
    ));
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Command {
        #[command(flatten)]
        run: RunArgs,
    }

    fn settings_of(options: &[&str]) -> Result<(RunSettings, SettingsReport), String> {
        let robot = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../robots/hardware-example.toml"
        );
        let mut args = vec!["run", "--robot", robot, "--port", "/dev/null"];
        args.extend_from_slice(options);
        let args = Command::try_parse_from(args)
            .map_err(|e| e.to_string())?
            .run;
        let (robot, mut hardware) = load(&args.robot)?;
        let (settings, _) = run_settings(&args, &robot, &mut hardware)?;
        let report = run_settings_report(&args, &robot, &hardware, &settings);
        Ok((settings, report))
    }

    #[test]
    fn run_gains_come_from_the_robot_file_unless_the_command_line_gives_them() {
        let (settings, report) = settings_of(&[]).unwrap();
        let gains = settings.gains.unwrap();
        assert_eq!(gains.p1, Sourced::new(20.0, Source::RobotFile));
        assert_eq!(gains.kp.source, Source::RobotFile);
        assert_eq!(
            report.control_period,
            Sourced::new(1.0 / 33.0, Source::BuiltIn)
        );
        assert_eq!(report.reference.source, Source::RobotFile);
        assert_eq!(
            report.safety,
            Sourced::new(SafetyMode::Certified, Source::RobotFile)
        );

        let (settings, report) = settings_of(&[
            "--p",
            "15",
            "--kp",
            "8",
            "--rate",
            "20",
            "--no-filter",
            "--safety",
            "paper",
        ])
        .unwrap();
        assert_eq!(
            report.safety,
            Sourced::new(SafetyMode::Paper, Source::CommandLine)
        );
        let gains = settings.gains.unwrap();
        assert_eq!(gains.p1, Sourced::new(15.0, Source::CommandLine));
        assert_eq!(gains.p2, Sourced::new(15.0, Source::CommandLine));
        assert_eq!(gains.kp.value[7], 8.0);
        assert_eq!(gains.kd.source, Source::RobotFile);
        assert_eq!(
            report.control_period,
            Sourced::new(0.05, Source::CommandLine)
        );
        assert_eq!(report.filter, Sourced::new(false, Source::CommandLine));
        let line = report.line();
        assert!(line.contains("K_P = 8 (command line)"), "{line}");
        assert!(line.contains("p2 = 15 (command line)"), "{line}");
    }

    #[test]
    fn rate_auto_adapts_to_the_bus_and_other_words_are_refused() {
        let (settings, report) = settings_of(&["--rate", "auto"]).unwrap();
        assert_eq!(settings.rate_rule, RateRule::Adapt);
        assert_eq!(settings.rate, limits::RATE_HZ.max);
        assert_eq!(settings.min_rate, None);
        assert_eq!(report.control_period.source, Source::CommandLine);
        let (settings, _) = settings_of(&["--rate", "40"]).unwrap();
        assert_eq!(settings.rate_rule, RateRule::Hold);
        assert_eq!(settings.rate, 40.0);
        let error = settings_of(&["--rate", "fast"]).err().unwrap();
        assert_eq!(error, "--rate: `fast` is neither a number of Hz nor `auto`");
        let error = settings_of(&["--rate", "-33"]).err().unwrap();
        assert!(error.starts_with("--rate: must be"), "{error}");
        let error = settings_of(&["--rate", "20000"]).err().unwrap();
        assert!(error.starts_with("--rate: must be"), "{error}");
        // A minimum rate with auto is checked once the rate is chosen.
        let (settings, _) = settings_of(&["--rate", "auto", "--min-rate", "20"]).unwrap();
        assert_eq!(settings.min_rate, Some(20.0));
    }

    #[test]
    fn an_experiment_takes_the_duration_and_refuses_a_set_point() {
        let (settings, report) =
            settings_of(&["--experiment", "dynamic", "--duration", "30"]).unwrap();
        // The experiment ends the run, at its own length.
        assert_eq!(settings.duration, None);
        let experiment = settings.experiment.unwrap();
        assert_eq!(experiment.kind, ExperimentKind::Dynamic);
        assert_eq!(experiment.length(), Some(30.0));
        assert_eq!(
            report.duration,
            Some(Sourced::new(30.0, Source::CommandLine))
        );
        assert_eq!(
            report.reference,
            Sourced::new("experiment dynamic".to_string(), Source::CommandLine)
        );
        let (settings, report) =
            settings_of(&["--experiment", "static", "--amplitude", "0.3,0.9"]).unwrap();
        let experiment = settings.experiment.unwrap();
        assert_eq!(experiment.amplitude, Some(vec![0.3, 0.9]));
        assert_eq!(experiment.length(), None);
        assert_eq!(report.duration, None);
        // A plain run has none.
        let (settings, _) = settings_of(&["--duration", "3"]).unwrap();
        assert_eq!((settings.duration, settings.experiment), (Some(3.0), None));
        let error = settings_of(&["--experiment", "static", "--kp", "3"])
            .err()
            .unwrap();
        assert!(error.starts_with("--kp: not with --experiment"), "{error}");
        let error = settings_of(&["--step-time", "3"]).err().unwrap();
        assert!(
            error.starts_with("--step-time: an option of --experiment"),
            "{error}"
        );
    }

    #[test]
    fn run_gains_are_checked_by_the_files_rules() {
        let error = settings_of(&["--kd", "-3"]).err().unwrap();
        assert!(error.starts_with("--kd: must be ≥ 0"), "{error}");
        let error = settings_of(&["--p", "2", "--p2", "3"]).err().unwrap();
        assert!(error.contains("either --p or --p1/--p2"), "{error}");
    }
}
