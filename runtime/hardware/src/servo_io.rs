//! The servo side of the control loop: the safe start, one tick's sync read with its retry
//! policy and sync write, and the safe stop, over a [`Bus`] on a [`ServoPort`].
//!
//! A reading is accepted only when every servo's status packet arrived complete, with a
//! valid CRC and no error number, in answer to this attempt's request. Three defences keep
//! a late packet of an earlier request from being taken for this one's: the port's input is
//! discarded before each request; after a failed attempt the line is drained until it has
//! been quiet for the reply timeout; and successive sync reads cycle through
//! [`READ_VARIANTS`] block lengths (the state block with 0–3 bytes before it), so a status
//! packet answering any of the previous three requests has the wrong length and is
//! rejected. A stale packet would have to be four requests late to pass.

use std::io::{self, ErrorKind, Read};
use std::time::{Duration, Instant};

use crate::control_table::{self as table, ServoState};
use crate::protocol::{Bus, BusError, Port};

/// A port whose pending input can be thrown away.
pub trait ServoPort: Port {
    /// Discards every byte received and not yet read.
    fn discard_input(&mut self) -> io::Result<()>;
}

#[cfg(all(unix, feature = "serial"))]
impl ServoPort for serialport::TTYPort {
    fn discard_input(&mut self) -> io::Result<()> {
        serialport::SerialPort::clear(self, serialport::ClearBuffer::Input).map_err(io::Error::from)
    }
}

#[cfg(feature = "serial")]
impl ServoPort for Box<dyn serialport::SerialPort> {
    fn discard_input(&mut self) -> io::Result<()> {
        self.clear(serialport::ClearBuffer::Input)
            .map_err(io::Error::from)
    }
}

/// Reads and discards input until none has arrived for `quiet` (at most `limit` in all).
pub fn drain<P: Read + ?Sized>(port: &mut P, quiet: Duration, limit: Duration) -> io::Result<u64> {
    let start = Instant::now();
    let mut last = start;
    let mut buf = [0u8; 256];
    let mut dropped = 0;
    while last.elapsed() < quiet && start.elapsed() < limit {
        match port.read(&mut buf) {
            Ok(0) => std::thread::sleep(Duration::from_micros(200)),
            Ok(n) => {
                dropped += n as u64;
                last = Instant::now();
            }
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) => {}
            Err(e) => return Err(e),
        }
    }
    Ok(dropped)
}

/// Why the safe start refused to enable torque.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// A servo did not answer a ping.
    #[error("servo {id} did not answer a ping: {source}")]
    NoServo {
        /// The servo.
        id: u8,
        /// The last failure.
        #[source]
        source: BusError,
    },
    /// A servo is another model than the robot file says.
    #[error("servo {id} is model {found}, the robot file says {expected} (hardware.model_number)")]
    WrongModel {
        /// The servo.
        id: u8,
        /// Its model number.
        found: u16,
        /// The expected one.
        expected: u16,
    },
    /// A register could not be written or read.
    #[error("servo {id}: cannot {what}: {source}")]
    Register {
        /// The servo.
        id: u8,
        /// What was attempted.
        what: &'static str,
        /// The failure.
        #[source]
        source: BusError,
    },
    /// The state could not be read.
    #[error("cannot read the servos' state: {0}")]
    State(#[source] BusError),
    /// The bus check could not time its cycles (a clock that does not advance).
    #[error("the {cycles} read+write cycles timed at the start gave no usable time")]
    NoReading {
        /// Cycles run.
        cycles: usize,
    },
    /// The measured state lies outside the model's domain (not finite, bent or stretched
    /// beyond what the model describes): a calibration or a robot file that does not fit.
    #[error(
        "the measured state lies outside the model ({problem}): q = {q:?}, q̇ = {qd:?}; check \
         the calibration (zero_angle_deg, direction) and the robot file"
    )]
    OutOfDomain {
        /// What is wrong.
        problem: String,
        /// Measured `q`.
        q: Vec<f64>,
        /// Measured `q̇`.
        qd: Vec<f64>,
    },
}

/// Number of distinct sync-read block lengths cycled through.
pub const READ_VARIANTS: u16 = 4;

/// Preallocated buffers for the per-tick bus traffic of one robot.
pub struct ServoIo {
    ids: Vec<u8>,
    raw: Vec<u8>,
    states: Vec<ServoState>,
    goal: Vec<[u8; 2]>,
    attempts: u32,
    requests: u16,
    sent: Option<(Instant, usize)>,
}

impl ServoIo {
    /// Buffers for the servos `ids` (bus order).
    pub fn new(ids: Vec<u8>) -> ServoIo {
        let n = ids.len();
        ServoIo {
            ids,
            raw: vec![0; n * usize::from(table::STATE_LENGTH + READ_VARIANTS - 1)],
            states: vec![ServoState::default(); n],
            goal: vec![[0; 2]; n],
            attempts: 0,
            requests: 0,
            sent: None,
        }
    }

    /// The servo IDs.
    pub fn ids(&self) -> &[u8] {
        &self.ids
    }

    /// The states of the last successful [`ServoIo::read_states`].
    pub fn states(&self) -> &[ServoState] {
        &self.states
    }

    /// When the request of the last successful [`ServoIo::read_states`] started to be
    /// written, and its length in bytes: the servos sampled their state one wire time
    /// after.
    pub fn reading_sent(&self) -> Option<(Instant, usize)> {
        self.sent
    }

    /// Sync-read attempts made by the last [`ServoIo::read_states`].
    pub fn attempts(&self) -> u32 {
        self.attempts
    }

    /// One fresh reading of every servo: up to `1 + retries` sync reads, the input
    /// discarded before each and the line drained after each failure. On success the
    /// states are in [`ServoIo::states`]; on failure they are untouched.
    pub fn read_states<P: ServoPort>(
        &mut self,
        bus: &mut Bus<P>,
        retries: u32,
    ) -> Result<(), BusError> {
        self.attempts = 0;
        loop {
            self.attempts += 1;
            bus.port_mut().discard_input()?;
            // The state block with `extra` bytes before it: a different length than the
            // previous three requests'.
            let extra = self.requests % READ_VARIANTS;
            self.requests = self.requests.wrapping_add(1);
            let len = table::STATE_LENGTH + extra;
            let raw = &mut self.raw[..self.ids.len() * usize::from(len)];
            match bus.sync_read(table::STATE_ADDRESS - extra, len, &self.ids, raw) {
                Ok(()) => {
                    self.sent = bus.last_sent();
                    let len = usize::from(len);
                    for (state, bytes) in self.states.iter_mut().zip(raw.chunks_exact(len)) {
                        *state = ServoState::from_bytes(&bytes[usize::from(extra)..]);
                    }
                    return Ok(());
                }
                Err(error) => {
                    let timeout = bus.timeout();
                    drain(bus.port_mut(), timeout, 4 * timeout)?;
                    if self.attempts > retries {
                        return Err(error);
                    }
                    bus.note_retry();
                }
            }
        }
    }

    /// Sync-writes Goal Current `currents[k]` to servo `k` (no reply).
    pub fn write_currents<P: ServoPort>(
        &mut self,
        bus: &mut Bus<P>,
        currents: &[i16],
    ) -> Result<(), BusError> {
        for (slot, current) in self.goal.iter_mut().zip(currents) {
            *slot = current.to_le_bytes();
        }
        bus.sync_write(
            table::GOAL_CURRENT,
            2,
            self.ids
                .iter()
                .zip(&self.goal)
                .map(|(&id, data)| (id, &data[..])),
        )
    }
}

/// Runs one request/reply transaction up to `attempts` times (at least once): before each
/// try the input is discarded, after a failed one the port is drained of late bytes.
fn with_retries<P: ServoPort>(
    bus: &mut Bus<P>,
    attempts: u32,
    mut transaction: impl FnMut(&mut Bus<P>) -> Result<(), BusError>,
) -> Result<(), BusError> {
    let mut result = Ok(());
    for attempt in 0..attempts.max(1) {
        if attempt > 0 {
            bus.note_retry();
        }
        bus.port_mut().discard_input()?;
        match transaction(bus) {
            Ok(()) => return Ok(()),
            Err(error) => {
                let timeout = bus.timeout();
                drain(bus.port_mut(), timeout, 4 * timeout)?;
                result = Err(error);
            }
        }
    }
    result
}

/// Writes `data` at `addr` of `id`, trying up to `attempts` times.
pub fn write_register<P: ServoPort>(
    bus: &mut Bus<P>,
    id: u8,
    addr: u16,
    data: &[u8],
    attempts: u32,
) -> Result<(), BusError> {
    with_retries(bus, attempts, |bus| bus.write(id, addr, data).map(|_| ()))
}

/// Reads `out.len()` bytes at `addr` of `id`, trying up to `attempts` times.
pub fn read_register<P: ServoPort>(
    bus: &mut Bus<P>,
    id: u8,
    addr: u16,
    out: &mut [u8],
    attempts: u32,
) -> Result<(), BusError> {
    with_retries(bus, attempts, |bus| bus.read(id, addr, out).map(|_| ()))
}

/// Attempts of one transaction of the safe stop: few, so that a silent servo delays the
/// stop of the others by little (its torque-off is broadcast as well).
pub const STOP_ATTEMPTS: u32 = 3;

/// Safe start, part one: every servo answers a ping with the expected model number, has
/// torque off, its Bus Watchdog cleared (when `watchdog`: a watchdog error of an earlier
/// run makes the goal current read-only), is switched to current control and has Goal
/// Current 0. Torque stays off. Each transaction is tried up to `attempts` times, as the
/// loop retries its readings.
pub fn prepare<P: ServoPort>(
    bus: &mut Bus<P>,
    ids: &[u8],
    model_number: u16,
    watchdog: bool,
    attempts: u32,
) -> Result<(), StartError> {
    for &id in ids {
        let mut model = 0;
        with_retries(bus, attempts, |bus| {
            model = bus.ping(id)?.model_number;
            Ok(())
        })
        .map_err(|source| StartError::NoServo { id, source })?;
        if model != model_number {
            return Err(StartError::WrongModel {
                id,
                found: model,
                expected: model_number,
            });
        }
    }
    for &id in ids {
        let register = |what, source| StartError::Register { id, what, source };
        write_register(bus, id, table::TORQUE_ENABLE, &[0], attempts)
            .map_err(|e| register("disable torque", e))?;
        if watchdog {
            write_register(bus, id, table::BUS_WATCHDOG, &[0], attempts).map_err(|e| {
                register(
                    "clear the Bus Watchdog (firmware v38 or later has it; run with \
                     --bus-watchdog-ms 0 on older firmware)",
                    e,
                )
            })?;
        }
        let mut mode = [0u8];
        read_register(bus, id, table::OPERATING_MODE, &mut mode, attempts)
            .map_err(|e| register("read the operating mode", e))?;
        if mode[0] != table::CURRENT_CONTROL_MODE {
            write_register(
                bus,
                id,
                table::OPERATING_MODE,
                &[table::CURRENT_CONTROL_MODE],
                attempts,
            )
            .map_err(|e| register("select current control", e))?;
        }
        write_register(bus, id, table::GOAL_CURRENT, &0i16.to_le_bytes(), attempts)
            .map_err(|e| register("zero the goal current", e))?;
    }
    Ok(())
}

/// Safe start, part two: arms the Bus Watchdog with `watchdog_units` × 20 ms (`0`: leaves
/// it off), so that a servo stops by itself when the controller falls silent (a killed or
/// crashed host), then enables torque on every servo (after the caller has written the
/// first goal currents).
pub fn enable_torque<P: ServoPort>(
    bus: &mut Bus<P>,
    ids: &[u8],
    watchdog_units: u8,
    attempts: u32,
) -> Result<(), StartError> {
    for &id in ids {
        if watchdog_units > 0 {
            write_register(bus, id, table::BUS_WATCHDOG, &[watchdog_units], attempts).map_err(
                |source| StartError::Register {
                    id,
                    what: "arm the Bus Watchdog",
                    source,
                },
            )?;
        }
        write_register(bus, id, table::TORQUE_ENABLE, &[1], attempts).map_err(|source| {
            StartError::Register {
                id,
                what: "enable torque",
                source,
            }
        })?;
    }
    Ok(())
}

/// Safe stop: zero tension (Goal Current 0) and torque off on every servo, each confirmed
/// by its status packet where possible, and broadcast as well; then the Bus Watchdog
/// disarmed (when `watchdog`), so the idle servos do not report a watchdog error. Returns,
/// per servo, whether its torque-off was confirmed.
pub fn safe_stop<P: ServoPort>(bus: &mut Bus<P>, io: &mut ServoIo, watchdog: bool) -> Vec<bool> {
    let zeros = vec![0i16; io.ids().len()];
    for _ in 0..2 {
        let _ = io.write_currents(bus, &zeros);
    }
    let ids = io.ids().to_vec();
    let confirmed: Vec<bool> = ids
        .iter()
        .map(|&id| write_register(bus, id, table::TORQUE_ENABLE, &[0], STOP_ATTEMPTS).is_ok())
        .collect();
    // Broadcast too: a servo whose replies are lost still obeys.
    let _ = bus.write(crate::protocol::BROADCAST_ID, table::TORQUE_ENABLE, &[0]);
    if watchdog {
        let _ = bus.write(crate::protocol::BROADCAST_ID, table::BUS_WATCHDOG, &[0]);
    }
    confirmed
}
