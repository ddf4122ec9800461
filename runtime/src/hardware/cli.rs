//! The `softcbf emulate` and `softcbf run` subcommands: options, opening ports, printing
//! the summary. The work itself is in [`super::emulator`] and [`super::run_loop`].

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use clap::Args;

use crate::cli::parse_vector;
use crate::hardware::emulator::{self, EmulatorSettings, Faults};
use crate::hardware::mapping::TendonMap;
use crate::hardware::run_loop::{self, RunSettings, RunSummary};
use crate::hardware::signal;
use crate::model::Model;
use crate::protocol::Bus;
use softcbf_codegen::robot::Robot;

/// Options of `softcbf emulate`.
#[derive(Args, Debug)]
pub struct EmulateArgs {
    /// Robot file with a `[hardware]` table (e.g. robots/hardware-example.toml).
    #[arg(long)]
    pub robot: PathBuf,
    /// Baud rate used to pace replies [bit/s] (default: the robot file's).
    #[arg(long)]
    pub baud: Option<u32>,
    /// Return Delay Time of the servos (µs) (X-series factory default 500; 0 is usual).
    #[arg(long, default_value_t = 0)]
    pub return_delay_us: u64,
    /// Fraction of status packets not sent (0..1).
    #[arg(long, default_value_t = 0.0)]
    pub drop: f64,
    /// Fraction of status packets sent with a wrong CRC (0..1).
    #[arg(long, default_value_t = 0.0)]
    pub corrupt: f64,
    /// Extra delay of delayed status packets (ms).
    #[arg(long, default_value_t = 0.0)]
    pub delay_ms: f64,
    /// Fraction of status packets delayed by --delay-ms (0..1).
    #[arg(long, default_value_t = 1.0)]
    pub delay_fraction: f64,
    /// ID of a servo that stops answering (it still obeys instructions).
    #[arg(long)]
    pub silent_servo: Option<u8>,
    /// Seconds after the start when --silent-servo falls silent.
    #[arg(long, default_value_t = 0.0)]
    pub silent_after: f64,
    /// Seed of the fault draws.
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
    /// Loop rate (Hz).
    #[arg(long, default_value_t = 33.0)]
    pub rate: f64,
    /// Stop after this many seconds (default: run until Ctrl-C).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Set point `Δx,Δy,δL,…` (m) (default: the robot file's hardware.set_point).
    #[arg(long, allow_hyphen_values = true)]
    pub set_point: Option<String>,
    /// Plain PD+ without the safety filter.
    #[arg(long)]
    pub no_filter: bool,
    /// Directory for the log and figures.
    #[arg(long, default_value = "out/run")]
    pub out: PathBuf,
    /// Baud rate [bit/s] (default: the robot file's).
    #[arg(long)]
    pub baud: Option<u32>,
    /// Ticks in a row without a good reading before the safe stop (default: the robot
    /// file's hardware.max_consecutive_errors).
    #[arg(long)]
    pub max_errors: Option<u32>,
}

fn load(path: &std::path::Path) -> Result<Robot, String> {
    let robot = Robot::load(path).map_err(|e| e.to_string())?;
    if robot.hardware.is_none() {
        return Err(format!(
            "{}: no [hardware] table (see robots/README.md)",
            path.display()
        ));
    }
    Ok(robot)
}

/// `softcbf emulate`: serves until Ctrl-C.
#[cfg(unix)]
pub fn emulate(args: EmulateArgs) -> Result<(), String> {
    use serialport::{SerialPort, TTYPort};
    let robot = load(&args.robot)?;
    let hardware = robot.hardware.as_ref().expect("checked by load");
    let baud = args.baud.unwrap_or(hardware.baud);
    let settings = EmulatorSettings {
        baud,
        return_delay: Duration::from_micros(args.return_delay_us),
        settle: 3.0,
        faults: Faults {
            drop: args.drop,
            corrupt: args.corrupt,
            delay: Duration::from_secs_f64(args.delay_ms.max(0.0) / 1000.0),
            delay_fraction: args.delay_fraction,
            silent_servo: args.silent_servo,
            silent_after: Duration::from_secs_f64(args.silent_after.max(0.0)),
            seed: args.seed,
        },
    };
    let stop = signal::stop_flag();
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
    let mut announce = || {
        println!(
            "softcbf emulate: servos {} of `{}` at {baud} bit/s",
            ids.join(", "),
            robot.name
        );
        println!("port: {path}");
        println!(
            "connect with: softcbf run --robot {} --port {path}",
            args.robot.display()
        );
        println!("Ctrl-C to stop");
        let _ = std::io::stdout().flush();
    };
    let log = emulator::serve(&robot, &settings, &mut master, stop, &mut announce, None)
        .map_err(|e| e.to_string())?;
    drop(slave);
    println!(
        "emulator stopped: {} requests; status packets sent {}, delayed {}, dropped {}, corrupted {}, silent {}",
        log.requests, log.fates[0], log.fates[1], log.fates[2], log.fates[3], log.fates[4]
    );
    Ok(())
}

/// `softcbf run`: the safe controller on the servos; a fault is an error (non-zero exit).
pub fn run(args: RunArgs) -> Result<(), String> {
    let robot = load(&args.robot)?;
    let mut hardware = robot.hardware.clone().expect("checked by load");
    if let Some(n) = args.max_errors {
        if n == 0 {
            return Err("--max-errors must be at least 1".into());
        }
        hardware.max_consecutive_errors = n;
    }
    let mut robot = robot;
    robot.hardware = Some(hardware.clone());
    let map = TendonMap::new(&robot).map_err(|e| e.to_string())?;
    let model = Model::new(robot.clone()).map_err(|e| e.to_string())?;
    let set_point = match &args.set_point {
        Some(text) => parse_vector("--set-point", text, model.nq())?,
        None => hardware.set_point.clone(),
    };
    if let Some(d) = args.duration
        && !(d.is_finite() && d > 0.0)
    {
        return Err(format!("--duration must be > 0 s, got {d}"));
    }
    let settings = RunSettings {
        rate: args.rate,
        duration: args.duration,
        set_point,
        filter: !args.no_filter,
    };
    let baud = args.baud.unwrap_or(hardware.baud);
    let port = serialport::new(&args.port, baud)
        .timeout(Duration::from_millis(1))
        .open()
        .map_err(|e| format!("cannot open {}: {e}", args.port))?;
    let mut bus = Bus::new(port, Duration::from_secs_f64(hardware.reply_timeout));
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let mut log = super::log::open(&args.out, &model, map.n_servos())?;
    let stop = signal::stop_flag();
    println!(
        "softcbf run: `{}` on {} at {baud} bit/s, {} Hz, filter {}, set point {:?}",
        robot.name,
        args.port,
        settings.rate,
        if settings.filter { "on" } else { "off" },
        settings.set_point
    );
    let summary = run_loop::run(&model, &map, &mut bus, &settings, &mut log, stop)
        .map_err(|e| e.to_string())?;
    report(&summary);
    match super::log::finish(log, &args.out, settings.filter, &settings.set_point, &model) {
        Ok(files) => {
            let names: Vec<String> = files.iter().map(|p| p.display().to_string()).collect();
            println!("wrote {}", names.join(", "));
        }
        Err(e) => eprintln!("warning: the log or figures could not be written: {e}"),
    }
    if summary.stop.is_fault() {
        return Err(format!("stopped on a fault: {}", summary.stop));
    }
    Ok(())
}

fn report(s: &RunSummary) {
    let b = &s.bus;
    println!("stopped: {}", s.stop);
    println!(
        "{} ticks in {:.2} s ({:.1} Hz): {} commands, {} held (no fresh reading), {} safe fallbacks, {} overruns",
        s.ticks,
        s.elapsed,
        s.rate(),
        s.commands,
        s.held,
        s.fallbacks,
        s.overruns
    );
    println!(
        "tensions clamped: {} at f_min, {} at f_max",
        s.clamps.low, s.clamps.high
    );
    println!(
        "bus: {} requests, {} replies, {} timeouts, {} CRC errors, {} other corrupt, {} wrong ID, {} retries",
        b.transactions, b.replies, b.timeouts, b.crc_errors, b.decode_errors, b.wrong_id, b.retries
    );
    println!(
        "smallest barrier {:.3e} m; longest software time per tick {:.1} µs",
        s.min_barrier,
        s.max_compute * 1e6
    );
    let off: Vec<String> = s
        .torque_off
        .iter()
        .map(|(id, ok)| format!("{id}:{}", if *ok { "off" } else { "unconfirmed" }))
        .collect();
    println!("torque: {}", off.join(" "));
}

/// `softcbf emulate` needs a Unix pseudo-terminal.
#[cfg(not(unix))]
pub fn emulate(_args: EmulateArgs) -> Result<(), String> {
    Err("softcbf emulate needs a Unix pseudo-terminal".into())
}
