//! `softcbf emulate`: a servo bus on a pseudo-terminal that answers Protocol 2.0 as the
//! robot's X-series servos would, their motion given by the simulated plant.
//!
//! [`servos`] holds the control tables and what each instruction does; [`device`] is the
//! bus without I/O (bytes in with their arrival time, status packets out with the time
//! they are due, timers); [`adapter`] is the USB adapter between bus and host; [`serve`]
//! is the I/O loop around them on a port. It paces replies by wire time at the configured
//! baud (so a loop rate measured against the emulator means something), injects faults
//! ([`Faults`]) and, for tests, records the bus ([`EmulatorLog`]).
//!
//! Realism, each off unless asked ([`Preset::Ideal`] is today's emulator): the physics of
//! another robot file than the controller's, and the actuator gains of its `[hardware]`
//! table if it has one ([`EmulatorSettings::plant`]), the adapter's
//! latency timer ([`adapter`]), the servos' Return Delay Time, and sensor noise before the
//! readings are rounded to register units ([`SensorNoise`]). [`Preset::Factory`] sets them
//! as a U2D2 (or any FTDI adapter) and X-series servos come from the factory.
//!
//! Timing model: a request occupies the bus for its wire time (10 bits per byte, 8N1)
//! from when it arrives or the bus is free, whichever is later; it is executed, and the
//! plant sampled, when its last byte has crossed. Each status packet then follows after
//! the servo's Return Delay Time and its own wire time, and is written when its last byte
//! would have arrived. Dropped and silenced replies take no bus time.
//!
//! Packet timeout: the e-Manual does not say how long an X-series servo waits for the rest
//! of a packet. The emulator gives up on an incomplete packet once the wire time of the
//! whole packet its length field announces (of its 7-byte prefix while that is incomplete)
//! plus 10 ms has passed since its first byte arrived, and drops every byte held. The wire
//! time is the least a sender needs; the 10 ms cover the gaps a USB adapter (1 ms frames)
//! and a loaded host leave inside one packet, and match the 2 ms + adapter latency the
//! ROBOTIS SDK allows a whole packet on its side. A header announcing 1024 bytes thus
//! silences the bus for 20 ms at 1 Mbit/s (1.1 s at 9600 bit/s) instead of until 1024
//! bytes have come.
//!
//! Bus Watchdog: while a servo's torque is on and its Bus Watchdog (98) holds 1–127, it
//! stops (pulls with zero tension) as soon as no instruction packet has reached it for
//! longer than that many 20 ms, whether or not anything arrives; the register then reads
//! −1 and the Goal values refuse writes with a Data Range Error until a valid value
//! (0 clears the error) is written. Every instruction packet on the bus with a good CRC
//! counts, whatever its ID.

pub mod adapter;
pub mod device;
pub mod servos;

use std::io::{self, ErrorKind, Read, Write};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use softcbf_description::robot::Robot;

use crate::control_table::ServoState;
use crate::hardware_description as description;
use crate::integrator::{IntegratorError, Tolerances};
use crate::mapping::{MappingError, TendonMap};
use crate::model::{Model, ModelError};
use crate::noise::SensorNoise;
use crate::plant::Plant;
use device::Device;

/// Faults to inject. Fractions are probabilities per status packet.
#[derive(Clone, Debug, PartialEq)]
pub struct Faults {
    /// Fraction of status packets not sent.
    pub drop: f64,
    /// Fraction of status packets sent with a wrong CRC.
    pub corrupt: f64,
    /// Extra delay before a delayed status packet.
    pub delay: Duration,
    /// Fraction of status packets delayed by `delay`.
    pub delay_fraction: f64,
    /// A servo that stops answering (it still obeys instructions, as with a broken
    /// reply line).
    pub silent_servo: Option<u8>,
    /// When the silent servo falls silent, after the first packet the emulator receives
    /// (not its start: a `run` started later still gets its safe start).
    pub silent_after: Duration,
    /// Seed of the fault draws (reproducible runs).
    pub seed: u64,
}

impl Default for Faults {
    fn default() -> Self {
        Faults {
            drop: 0.0,
            corrupt: 0.0,
            delay: Duration::ZERO,
            delay_fraction: 1.0,
            silent_servo: None,
            silent_after: Duration::ZERO,
            seed: 1,
        }
    }
}

/// How the emulator runs.
#[derive(Clone, Debug, PartialEq)]
pub struct EmulatorSettings {
    /// Baud rate used for pacing [bit/s].
    pub baud: u32,
    /// Return Delay Time of every servo at the start (the X-series' default is 500 µs; 0
    /// is usual; at most 508 µs, in steps of 2 µs). A servo's own register rules after.
    pub return_delay: Duration,
    /// Latency timer of the USB adapter the host reads through ([`adapter`]; FTDI's
    /// factory value is 16 ms, 1 ms the usual tuned one); zero: no adapter, each status
    /// packet reaches the host as its last byte crosses the bus.
    pub latency_timer: Duration,
    /// Noise on Present Position and Present Velocity.
    pub noise: SensorNoise,
    /// The "true" robot whose physics (its numbers, and the tendon geometry the servos
    /// wind) the servos move, if not the one whose `[hardware]` table they are; its
    /// structure must be the same. Of its own `[hardware]` table, if any, only the actuator
    /// gains are taken (the true current → tension of each servo); see [`physics`].
    pub plant: Option<Robot>,
    /// Simulated time the robot rests with zero tension before serving, so it starts at
    /// its equilibrium under gravity \[s\].
    pub settle: f64,
    /// Faults to inject.
    pub faults: Faults,
}

impl EmulatorSettings {
    /// Fault-free settings at `baud`, zero return delay, no adapter, no noise, the robot's
    /// own physics, 3 s settling: [`Preset::Ideal`].
    pub fn new(baud: u32) -> EmulatorSettings {
        EmulatorSettings {
            baud,
            return_delay: Duration::ZERO,
            latency_timer: Duration::ZERO,
            noise: SensorNoise::NONE,
            plant: None,
            settle: 3.0,
            faults: Faults::default(),
        }
    }
}

/// A starting point for the emulator's realism settings; options given one by one win.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Preset {
    /// Replies as soon as the wire allows, exact readings: the emulator as it always was.
    #[default]
    Ideal,
    /// A U2D2 (or another FTDI-based adapter) and X-series servos as they come from the
    /// factory: latency timer 16 ms, Return Delay Time 500 µs (register 250), and noise of
    /// one register unit on position and velocity.
    Factory,
}

impl Preset {
    /// Every preset, by its name on the command line.
    pub const ALL: [(&'static str, Preset); 2] =
        [("ideal", Preset::Ideal), ("factory", Preset::Factory)];

    /// FTDI's factory latency timer.
    pub const FACTORY_LATENCY_TIMER: Duration = Duration::from_millis(16);
    /// The X-series' factory Return Delay Time (register 250 × 2 µs).
    pub const FACTORY_RETURN_DELAY: Duration = Duration::from_micros(500);
    /// Noise of [`Preset::Factory`] \[register units\]: an encoder count now and then.
    pub const FACTORY_NOISE_UNITS: f64 = 1.0;

    /// The preset named `text` (`realistic` is another name of `factory`).
    pub fn parse(text: &str) -> Result<Preset, String> {
        let text = text.trim();
        if text.eq_ignore_ascii_case("realistic") {
            return Ok(Preset::Factory);
        }
        Preset::ALL
            .iter()
            .find(|(name, _)| name.eq_ignore_ascii_case(text))
            .map(|&(_, preset)| preset)
            .ok_or_else(|| {
                let names: Vec<&str> = Preset::ALL.iter().map(|(name, _)| *name).collect();
                format!("`{text}` is not a preset; use one of {}", names.join(", "))
            })
    }

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Ideal => "ideal",
            Preset::Factory => "factory",
        }
    }

    /// Sets the latency timer, the Return Delay Time and the noise (not its seed) of
    /// `settings` to the preset's.
    pub fn apply(self, settings: &mut EmulatorSettings) {
        let (latency_timer, return_delay, noise) = match self {
            Preset::Ideal => (Duration::ZERO, Duration::ZERO, 0.0),
            Preset::Factory => (
                Preset::FACTORY_LATENCY_TIMER,
                Preset::FACTORY_RETURN_DELAY,
                Preset::FACTORY_NOISE_UNITS,
            ),
        };
        settings.latency_timer = latency_timer;
        settings.return_delay = return_delay;
        settings.noise.position = noise;
        settings.noise.velocity = noise;
    }
}

/// Why the emulator stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum EmulatorError {
    /// The robot has no usable hardware table.
    #[error(transparent)]
    Mapping(#[from] MappingError),
    /// No generated model for the robot.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The plant could not be advanced.
    #[error("the simulated robot failed: {0}")]
    Plant(#[from] IntegratorError),
    /// The port failed.
    #[error("pseudo-terminal I/O error: {0}")]
    Io(#[from] io::Error),
    /// A setting is out of range.
    #[error("emulator setting {0}")]
    Setting(String),
    /// The plant's robot file has another structure than the servos' robot file.
    #[error(
        "{plant}: the plant must have the structure of {robot} (the same generated model), \
         only other numbers; it has {difference}"
    )]
    PlantStructure {
        /// The plant's robot file.
        plant: String,
        /// The servos' robot file.
        robot: String,
        /// The first difference found.
        difference: String,
    },
}

/// What happened to one status packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReplyFate {
    /// Sent intact.
    Sent,
    /// Sent intact, after the injected delay.
    Delayed,
    /// Not sent (dropped).
    Dropped,
    /// Sent with a wrong CRC.
    Corrupted,
    /// Not sent: the servo is silent.
    Silent,
}

impl ReplyFate {
    /// Whether a client could have decoded this reply.
    pub fn intact(self) -> bool {
        matches!(self, ReplyFate::Sent | ReplyFate::Delayed)
    }
}

/// One servo's answer to a sync read of the state block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StateReply {
    /// The servo.
    pub id: u8,
    /// What happened to the packet.
    pub fate: ReplyFate,
    /// The state it carried.
    pub state: ServoState,
}

/// Everything the emulator did that a test may check.
#[derive(Clone, Debug, Default)]
pub struct EmulatorLog {
    /// Instruction packets executed.
    pub requests: u64,
    /// Each sync read of the state block, in order: time \[s\] and one entry per servo.
    pub state_reads: Vec<(f64, Vec<StateReply>)>,
    /// Each write of Goal Current (sync or single): time \[s\] and `(id, value)` items.
    pub goal_writes: Vec<(f64, Vec<(u8, i16)>)>,
    /// Index into `state_reads` of the last read before each goal write (`None`: none).
    pub read_before_write: Vec<Option<usize>>,
    /// Torque Enable of every servo, in bus order, after the last instruction.
    pub torque: Vec<bool>,
    /// Status packets by fate: sent, delayed, dropped, corrupted, silent.
    pub fates: [u64; 5],
    /// Each Bus Watchdog expiry: time \[s\] and the servo it stopped.
    pub watchdog_stops: Vec<(f64, u8)>,
    /// Incomplete packets dropped by the packet timeout.
    pub stale_packets: u64,
}

/// Wire time of `bytes` bytes at `baud` (8 data bits, 1 start and 1 stop bit); a baud of
/// 0 counts as 1 bit/s.
pub fn wire_time(bytes: usize, baud: u32) -> Duration {
    Duration::from_secs_f64(10.0 * bytes as f64 / f64::from(baud.max(1)))
}

/// Sleeps until `deadline`, spinning the last 200 µs for precision.
pub fn wait_until(deadline: Instant) {
    let spin = Duration::from_micros(200);
    loop {
        let now = Instant::now();
        if now >= deadline {
            return;
        }
        let left = deadline - now;
        if left > spin {
            std::thread::sleep(left - spin);
        } else {
            std::thread::yield_now();
        }
    }
}

/// A port the emulator serves on: bytes both ways, and reads that give up after a time
/// (so that the emulator reads requests while a reply waits for its time).
pub trait Port: Read + Write {
    /// Makes the next reads return after at most about `timeout` if no byte comes.
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()>;
}

#[cfg(all(unix, feature = "serial"))]
impl Port for serialport::TTYPort {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        serialport::SerialPort::set_timeout(self, timeout).map_err(io::Error::from)
    }
}

/// Bytes in memory: reads never block.
impl Port for io::Cursor<Vec<u8>> {
    fn set_read_timeout(&mut self, _timeout: Duration) -> io::Result<()> {
        Ok(())
    }
}

/// How soon a reply must be due for the emulator to wait for it rather than read.
const READ_AHEAD: Duration = Duration::from_millis(2);

/// Longest read while nothing is due.
const IDLE_READ: Duration = Duration::from_millis(20);

/// Longest sleep between two looks at the stop flag.
const STOP_POLL: Duration = Duration::from_millis(10);

/// [`wait_until`] that returns early, within [`STOP_POLL`], once `stop` is set.
fn wait_until_or_stop(deadline: Instant, stop: &AtomicBool) {
    let spin = Duration::from_micros(200);
    while !stop.load(Ordering::Relaxed) {
        let now = Instant::now();
        if now >= deadline {
            return;
        }
        let left = deadline - now;
        if left > spin {
            std::thread::sleep((left - spin).min(STOP_POLL));
        } else {
            std::thread::yield_now();
        }
    }
}

/// Longest Return Delay Time of an X-series servo (register 254 × 2 µs).
const MAX_RETURN_DELAY: Duration = Duration::from_micros(508);

/// Longest settling time accepted \[s\].
const MAX_SETTLE: f64 = 3600.0;

fn setting(message: String) -> EmulatorError {
    EmulatorError::Setting(message)
}

/// Refuses settings the emulator cannot use, naming the setting.
fn check(settings: &EmulatorSettings) -> Result<(), EmulatorError> {
    use crate::hardware_description::limits::{LATENCY_TIMER_MS, NOISE_UNITS};
    let latency_ms = settings.latency_timer.as_secs_f64() * 1e3;
    if latency_ms > LATENCY_TIMER_MS.max {
        return Err(setting(format!(
            "latency timer {latency_ms} ms: an FTDI adapter's is at most {} ms",
            LATENCY_TIMER_MS.max
        )));
    }
    for (name, units) in [
        ("position noise", settings.noise.position),
        ("velocity noise", settings.noise.velocity),
    ] {
        NOISE_UNITS
            .check(units)
            .map_err(|m| setting(format!("{name}: {m}")))?;
    }
    let f = &settings.faults;
    for (name, p) in [
        ("drop", f.drop),
        ("corrupt", f.corrupt),
        ("delay fraction", f.delay_fraction),
    ] {
        if !(0.0..=1.0).contains(&p) {
            return Err(setting(format!("{name} {p}: not a fraction in [0, 1]")));
        }
    }
    if settings.baud == 0 {
        return Err(setting(
            "baud rate 0 bit/s: must be at least 1 bit/s".into(),
        ));
    }
    if settings.return_delay > MAX_RETURN_DELAY {
        return Err(setting(format!(
            "return delay {} µs: an X-series servo waits at most 508 µs (Return Delay Time 254 × 2 µs)",
            settings.return_delay.as_micros()
        )));
    }
    if !(settings.settle.is_finite() && (0.0..=MAX_SETTLE).contains(&settings.settle)) {
        return Err(setting(format!(
            "settling time {} s: must be between 0 and {MAX_SETTLE} s",
            settings.settle
        )));
    }
    Ok(())
}

/// Refuses a silent servo that is not on the bus.
fn check_silent_servo(settings: &EmulatorSettings, ids: &[u8]) -> Result<(), EmulatorError> {
    match settings.faults.silent_servo {
        Some(id) if !ids.contains(&id) => {
            let list: Vec<String> = ids.iter().map(|i| i.to_string()).collect();
            Err(setting(format!(
                "silent servo {id}: no servo has that ID (the servos are {})",
                list.join(", ")
            )))
        }
        _ => Ok(()),
    }
}

/// What differs first between two structures, in words (`None`: nothing).
fn structure_difference(robot: &Robot, plant: &Robot) -> Option<String> {
    let (a, b) = (robot.structure(), plant.structure());
    let differs = |what: &str, ours: String, theirs: String| {
        Some(format!(
            "{what} {theirs} where the servos' robot has {ours}"
        ))
    };
    if a.modules() != b.modules() {
        differs("modules:", a.modules().to_string(), b.modules().to_string())
    } else if a.corners != b.corners {
        differs(
            "corners per plate",
            format!("{:?}", a.corners),
            format!("{:?}", b.corners),
        )
    } else if a.tendons != b.tendons {
        differs(
            "tendons per module",
            format!("{:?}", a.tendons),
            format!("{:?}", b.tendons),
        )
    } else if a.routing != b.routing {
        differs(
            "routing",
            format!("{:?}", a.routing).to_lowercase(),
            format!("{:?}", b.routing).to_lowercase(),
        )
    } else if a.obstacles != b.obstacles {
        differs(
            "obstacles:",
            format!("{}", a.obstacles.len()),
            format!("{} (or other watched points)", b.obstacles.len()),
        )
    } else {
        (a != b).then(|| "another structure".to_string())
    }
}

/// Refuses a plant whose structure (and so generated model) is not `robot`'s, naming both
/// files and the first difference, or whose `[hardware]` table (if any: [`physics`] takes
/// its actuator gains) is not valid, naming the plant's file, line and field.
pub fn check_plant(robot: &Robot, plant: &Robot) -> Result<(), EmulatorError> {
    if let Some(difference) = structure_difference(robot, plant) {
        return Err(EmulatorError::PlantStructure {
            plant: plant.source.display().to_string(),
            robot: robot.source.display().to_string(),
            difference,
        });
    }
    description::load(plant).map_err(MappingError::from)?;
    Ok(())
}

/// The mapping and the model the emulated servos move: the servo facts of `robot`'s
/// `[hardware]` table (IDs, units, pulleys, calibration, directions, limits) on the tendons
/// and physics of [`EmulatorSettings::plant`], or of `robot` itself. The actuator gains
/// (current → tension) are the plant's when its file has a `[hardware]` table, checked as
/// any robot's, and `robot`'s otherwise; the rest of the plant's table is not used. A
/// plant of another structure is refused, naming its file.
pub fn physics(
    robot: &Robot,
    settings: &EmulatorSettings,
) -> Result<(TendonMap, Model), EmulatorError> {
    let mut hardware = description::load(robot)
        .map_err(MappingError::from)?
        .ok_or_else(|| MappingError::NoHardware {
            file: robot.source.display().to_string(),
        })?;
    let body = match &settings.plant {
        Some(plant) => {
            check_plant(robot, plant)?;
            if let Some(true_hardware) = description::load(plant).map_err(MappingError::from)? {
                // Same structure, so as many modules (load checked one table per module).
                for (ours, theirs) in hardware.modules.iter_mut().zip(&true_hardware.modules) {
                    ours.actuator_gain = theirs.actuator_gain;
                }
            }
            plant
        }
        None => robot,
    };
    let map = TendonMap::with_hardware(body, hardware)?;
    let model = Model::new(body.clone())?;
    Ok((map, model))
}

/// How much of the device's record the shared log already has.
#[derive(Default)]
struct Synced {
    state_reads: usize,
    goal_writes: usize,
    watchdog_stops: usize,
}

/// Brings `shared` up to `own`, appending only what is new.
fn sync(own: &EmulatorLog, shared: &Mutex<EmulatorLog>, done: &mut Synced) {
    let mut log = shared
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    log.state_reads
        .extend_from_slice(&own.state_reads[done.state_reads.min(own.state_reads.len())..]);
    let from = done.goal_writes.min(own.goal_writes.len());
    log.goal_writes.extend_from_slice(&own.goal_writes[from..]);
    log.read_before_write
        .extend_from_slice(&own.read_before_write[from.min(own.read_before_write.len())..]);
    log.watchdog_stops.extend_from_slice(
        &own.watchdog_stops[done.watchdog_stops.min(own.watchdog_stops.len())..],
    );
    log.requests = own.requests;
    log.fates = own.fates;
    log.stale_packets = own.stale_packets;
    log.torque.clone_from(&own.torque);
    *done = Synced {
        state_reads: own.state_reads.len(),
        goal_writes: own.goal_writes.len(),
        watchdog_stops: own.watchdog_stops.len(),
    };
}

/// Answers Protocol 2.0 on `port` as `robot`'s servos until `stop` is set. `stop` is
/// checked at least every read timeout of the port and every 10 ms while a reply waits
/// for its time. `ready` is called once the robot has settled and requests are answered;
/// `log`, if given, is kept up to date as requests are executed.
pub fn serve<P: Port>(
    robot: &Robot,
    settings: &EmulatorSettings,
    port: &mut P,
    stop: &AtomicBool,
    ready: &mut dyn FnMut(),
    log: Option<&Mutex<EmulatorLog>>,
) -> Result<EmulatorLog, EmulatorError> {
    check(settings)?;
    let (map, model) = physics(robot, settings)?;
    check_silent_servo(settings, &map.hardware().servo_ids())?;
    let mut plant = Plant::new(&model, Tolerances::default())?;
    plant.advance(settings.settle)?;
    let mut device = Device::new(map, plant, settings, Instant::now())?;
    ready();
    let mut buf = [0u8; 1024];
    let mut synced = Synced::default();
    let mut seen = u64::MAX;
    while !stop.load(Ordering::Relaxed) {
        let now = Instant::now();
        device.poll(now)?;
        // The record first: whoever reads a reply finds its request logged.
        if let Some(shared) = log {
            let own = device.log();
            let changed = own.requests
                + own.fates.iter().sum::<u64>()
                + own.stale_packets
                + own.watchdog_stops.len() as u64;
            if changed != seen {
                sync(own, shared, &mut synced);
                seen = changed;
            }
        }
        while let Some(delivery) = device.take_due(now) {
            port.write_all(&delivery.bytes)?;
            port.flush()?;
        }
        // A request to finish or bytes to send soon keep the loop off the port (a read
        // could block past them); otherwise wait for bytes, no longer than until then.
        let due = device.next_due();
        let left = due.map(|due| due.saturating_duration_since(Instant::now()));
        if let (Some(due), Some(left)) = (due, left)
            && left <= READ_AHEAD
        {
            wait_until_or_stop(due, stop);
            continue;
        }
        port.set_read_timeout(
            left.map_or(IDLE_READ, |left| (left - READ_AHEAD / 2).min(IDLE_READ)),
        )?;
        match port.read(&mut buf) {
            Ok(0) => std::thread::sleep(Duration::from_millis(1)),
            Ok(n) => device.receive(&buf[..n], Instant::now())?,
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) => {}
            Err(e) => return Err(e.into()),
        }
    }
    if let Some(shared) = log {
        sync(device.log(), shared, &mut synced);
    }
    Ok(device.into_log())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::ScenarioFile;

    #[test]
    fn a_scenarios_sensor_noise_is_the_emulators_noise() {
        // The emulator's readings take the one sensor noise type a scenario reads.
        let text = "[sensor_noise]\nq = 1e-4\nqd = 2e-3\nseed = 5\n";
        let file = ScenarioFile::parse(text, std::path::Path::new("noise.toml")).unwrap();
        let model = crate::model::Model::new(crate::robot_file::load_robot(None).unwrap()).unwrap();
        let noise = file.resolve(&model).unwrap().sensor_noise.unwrap();
        let settings = EmulatorSettings {
            noise,
            ..EmulatorSettings::new(1_000_000)
        };
        assert!(settings.noise.is_on());
    }
}
