//! `softcbf emulate`: a servo bus on a pseudo-terminal that answers Protocol 2.0 as the
//! robot's X-series servos would, their motion given by the simulated plant.
//!
//! [`servos`] holds the control tables and instruction semantics; this file is the
//! transport: it decodes requests, paces replies by wire time at the configured baud (so
//! a loop rate measured against the emulator means something), injects faults
//! ([`Faults`]) and, for tests, records what was sent ([`EmulatorLog`]).
//!
//! Timing model: a request occupies the bus for its wire time (10 bits per byte, 8N1)
//! from when it arrives or the bus is free, whichever is later; each status packet then
//! follows after the return delay and its own wire time, and is written when its last
//! byte would have arrived. Instructions are executed, and the plant sampled, at the end
//! of the request. Dropped and silenced replies take no bus time.

pub mod servos;

use std::io::{self, ErrorKind, Read, Write};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use softcbf_codegen::robot::Robot;

use crate::hardware::control_table::{self as table, ServoState};
use crate::hardware::mapping::{MappingError, TendonMap};
use crate::integrator::{IntegratorError, Tolerances};
use crate::model::{Model, ModelError};
use crate::plant::Plant;
use crate::protocol::{
    Decoder, Instruction, PacketBuf, encode_status, parse_sync_write, parse_write,
};
use servos::{Reply, Servos};

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
    /// When the silent servo falls silent, after the emulator starts serving.
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
    /// Return Delay Time of every servo (the X-series' default is 500 µs; 0 is usual).
    pub return_delay: Duration,
    /// Simulated time the robot rests with zero tension before serving, so it starts at
    /// its equilibrium under gravity \[s\].
    pub settle: f64,
    /// Faults to inject.
    pub faults: Faults,
}

impl EmulatorSettings {
    /// Fault-free settings at `baud`, zero return delay, 3 s settling.
    pub fn new(baud: u32) -> EmulatorSettings {
        EmulatorSettings {
            baud,
            return_delay: Duration::ZERO,
            settle: 3.0,
            faults: Faults::default(),
        }
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
}

/// SplitMix64: the fault draws.
struct Draws(u64);

impl Draws {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Wire time of `bytes` bytes at `baud` (8 data bits, 1 start and 1 stop bit).
pub fn wire_time(bytes: usize, baud: u32) -> Duration {
    Duration::from_secs_f64(10.0 * bytes as f64 / f64::from(baud))
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

fn check(settings: &EmulatorSettings) -> Result<(), EmulatorError> {
    let f = &settings.faults;
    for (name, p) in [
        ("drop", f.drop),
        ("corrupt", f.corrupt),
        ("delay fraction", f.delay_fraction),
    ] {
        if !(0.0..=1.0).contains(&p) {
            return Err(EmulatorError::Setting(format!(
                "{name}: {p} is not a fraction in [0, 1]"
            )));
        }
    }
    if settings.baud == 0 || !(settings.settle.is_finite() && settings.settle >= 0.0) {
        return Err(EmulatorError::Setting(
            "baud must be > 0 and settle ≥ 0".into(),
        ));
    }
    Ok(())
}

/// Answers Protocol 2.0 on `port` as `robot`'s servos until `stop` is set (checked at
/// least every read timeout of the port). `ready` is called once the robot has settled and
/// requests are answered; `log`, if given, is updated after every request.
pub fn serve<P: Read + Write>(
    robot: &Robot,
    settings: &EmulatorSettings,
    port: &mut P,
    stop: &AtomicBool,
    ready: &mut dyn FnMut(),
    log: Option<&Mutex<EmulatorLog>>,
) -> Result<EmulatorLog, EmulatorError> {
    check(settings)?;
    let map = TendonMap::new(robot)?;
    let model = Model::new(robot.clone())?;
    let mut plant = Plant::new(&model, Tolerances::default())?;
    plant.advance(settings.settle)?;
    let baud_register = softcbf_codegen::hardware::baud_register(settings.baud).unwrap_or(3);
    let delay_register = (settings.return_delay.as_micros() / 2).min(254) as u8;
    let mut servos = Servos::new(map, plant, baud_register, delay_register);
    let mut own = EmulatorLog {
        torque: vec![false; servos.ids().len()],
        ..EmulatorLog::default()
    };
    let mut decoder = Decoder::default();
    let mut packet = PacketBuf::default();
    let mut replies = Vec::new();
    let mut out = Vec::with_capacity(256);
    let mut draws = Draws(settings.faults.seed);
    ready();
    let start = Instant::now();
    let mut bus_free = start;
    while !stop.load(Ordering::Relaxed) {
        match decoder.read_from(port) {
            Ok(0) => std::thread::sleep(Duration::from_millis(1)),
            Ok(_) => {}
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) => {}
            Err(e) => return Err(e.into()),
        }
        let arrival = Instant::now();
        loop {
            match decoder.next_packet() {
                None => break,
                Some(Err(_)) => continue, // a servo ignores corrupt packets
                Some(Ok(p)) => packet.copy_from(&p),
            }
            let request_end =
                arrival.max(bus_free) + wire_time(10 + packet.params.len(), settings.baud);
            let t = settings.settle + (request_end - start).as_secs_f64();
            replies.clear();
            servos.execute(&packet.as_ref(), t, &mut replies)?;
            own.requests += 1;
            let mut cursor = request_end;
            let mut states = Vec::new();
            for reply in &replies {
                let fate = fate_of(reply, &settings.faults, request_end - start, &mut draws);
                own.fates[fate as usize] += 1;
                if let Some(state) = state_block(&packet, &reply.params) {
                    states.push(StateReply {
                        id: reply.id,
                        fate,
                        state,
                    });
                }
                if matches!(fate, ReplyFate::Dropped | ReplyFate::Silent) {
                    continue;
                }
                out.clear();
                encode_status(reply.id, reply.error, &reply.params, &mut out)
                    .expect("servo IDs are valid");
                if fate == ReplyFate::Corrupted {
                    let last = out.len() - 1;
                    out[last] ^= 0x5A;
                }
                cursor += settings.return_delay + wire_time(out.len(), settings.baud);
                if fate == ReplyFate::Delayed {
                    cursor += settings.faults.delay;
                }
                wait_until(cursor);
                port.write_all(&out)?;
                port.flush()?;
            }
            bus_free = cursor;
            if let Some(log) = log {
                let mut shared = log.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
                record(&mut shared, &packet, t, states.clone(), &servos);
                shared.requests = own.requests;
                shared.fates = own.fates;
            }
            record(&mut own, &packet, t, states, &servos);
        }
    }
    Ok(own)
}

/// The state block inside a sync-read reply that covers it (the loop reads it with 0–3
/// bytes before it).
fn state_block(packet: &PacketBuf, params: &[u8]) -> Option<ServoState> {
    if packet.instruction != Instruction::SyncRead {
        return None;
    }
    let (addr, len, _) = crate::protocol::parse_sync_read(&packet.params)?;
    let skip = table::STATE_ADDRESS.checked_sub(addr)?;
    (addr + len == table::STATE_ADDRESS + table::STATE_LENGTH && params.len() == usize::from(len))
        .then(|| ServoState::from_bytes(&params[usize::from(skip)..]))
}

fn fate_of(reply: &Reply, faults: &Faults, since_start: Duration, draws: &mut Draws) -> ReplyFate {
    if faults.silent_servo == Some(reply.id) && since_start >= faults.silent_after {
        return ReplyFate::Silent;
    }
    // Draw all three every time so one fault's setting does not shift another's sequence.
    let (drop, corrupt, delay) = (draws.next(), draws.next(), draws.next());
    if drop < faults.drop {
        ReplyFate::Dropped
    } else if corrupt < faults.corrupt {
        ReplyFate::Corrupted
    } else if delay < faults.delay_fraction && !faults.delay.is_zero() {
        ReplyFate::Delayed
    } else {
        ReplyFate::Sent
    }
}

fn record(
    log: &mut EmulatorLog,
    packet: &PacketBuf,
    t: f64,
    states: Vec<StateReply>,
    servos: &Servos<'_>,
) {
    if !states.is_empty() {
        log.state_reads.push((t, states));
    }
    let goal = |addr: u16| addr == table::GOAL_CURRENT;
    let items: Vec<(u8, i16)> = match packet.instruction {
        Instruction::SyncWrite => match parse_sync_write(&packet.params) {
            Some((addr, 2, items)) if goal(addr) => items
                .map(|(id, d)| (id, i16::from_le_bytes([d[0], d[1]])))
                .collect(),
            _ => Vec::new(),
        },
        Instruction::Write => match parse_write(&packet.params) {
            Some((addr, d)) if goal(addr) && d.len() == 2 => {
                vec![(packet.id, i16::from_le_bytes([d[0], d[1]]))]
            }
            _ => Vec::new(),
        },
        _ => Vec::new(),
    };
    if !items.is_empty() {
        log.goal_writes.push((t, items));
        log.read_before_write
            .push(log.state_reads.len().checked_sub(1));
    }
    log.torque.clear();
    log.torque
        .extend((0..servos.ids().len()).map(|s| servos.torque_enabled(s)));
}
