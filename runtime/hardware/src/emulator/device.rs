//! The emulated bus without I/O: bytes in with the time they arrived, bytes out with the
//! time the host gets them (through the USB adapter's latency timer, if one is set), timers
//! (packet timeout, Bus Watchdog) run by [`Device::poll`]. [`super::serve`] wraps it around
//! a port; tests drive it with times of their choosing.
//!
//! Every method takes the time as an argument and none reads the clock, so a run is a pure
//! function of its inputs. Events are handled in time order: a request is executed when
//! its last byte has crossed the bus, a watchdog stops its servo at the instant it expires,
//! and the plant is advanced to each event before it is handled.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};

use crate::control_table::{self as table, ServoState};
use crate::mapping::TendonMap;
use crate::plant::Plant;
use crate::protocol::{
    BROADCAST_ID, CRC_LEN, DecodeError, Decoder, HEADER, Instruction, PREFIX_LEN, PacketBuf,
    encode_status, parse_sync_write, parse_write,
};

use super::adapter::{Adapter, Delivery, later};
use super::servos::{Reply, Servos};
use super::{EmulatorError, EmulatorLog, EmulatorSettings, Faults, ReplyFate, StateReply};

/// What the packet timeout allows beyond the wire time of the announced packet.
pub const PACKET_TIMEOUT_MARGIN: Duration = Duration::from_millis(10);

/// How long a servo waits for the rest of a packet whose first byte it has seen: the wire
/// time of the whole packet at `baud` (the prefix alone while its length field is not yet
/// known), plus [`PACKET_TIMEOUT_MARGIN`].
pub fn packet_timeout(length_field: Option<u16>, baud: u32) -> Duration {
    let bytes = PREFIX_LEN + length_field.map_or(0, usize::from);
    super::wire_time(bytes, baud) + PACKET_TIMEOUT_MARGIN
}

/// A status packet on its way over the bus.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Outgoing {
    /// When its last byte is on the bus.
    due: Instant,
    /// The encoded packet.
    bytes: Vec<u8>,
}

/// What a servo makes of a packet that reached it.
#[derive(Debug)]
enum Received {
    /// A whole instruction packet with a good CRC.
    Packet(PacketBuf),
    /// A good CRC around an instruction code Protocol 2.0 does not define.
    Undefined(u8),
    /// A header, ID and length, but the CRC does not match.
    BadCrc(u8),
}

/// A received packet waiting for its end on the bus.
#[derive(Debug)]
struct Request {
    what: Received,
    arrival: Instant,
    wire: Duration,
}

/// The fault draws: a named generator, so a seed gives the same faults on every platform
/// and `rand` release.
type Draws = Xoshiro256PlusPlus;

/// The servos of one robot on one bus, with the bus's timing and the injected faults.
pub struct Device<'m> {
    servos: Servos<'m>,
    baud: u32,
    faults: Faults,
    decoder: Decoder,
    /// Bytes pushed into the decoder so far.
    received: u64,
    /// `(offset of its first byte, arrival)` of each chunk still partly undecoded.
    chunks: VecDeque<(u64, Instant)>,
    requests: VecDeque<Request>,
    /// Status packets for the host as they end on the bus (no adapter)…
    outgoing: VecDeque<Outgoing>,
    /// …or through the USB adapter's latency timer.
    adapter: Option<Adapter>,
    bus_free: Instant,
    start: Instant,
    origin: f64,
    /// When the first packet received ended on the bus: the silent servo's clock starts
    /// there, so a `run` started later than the emulator still gets its safe start.
    first_packet: Option<Instant>,
    /// When each servo last heard an instruction packet (its Bus Watchdog's reference).
    heard: Vec<Option<Instant>>,
    draws: Draws,
    log: EmulatorLog,
    replies: Vec<Reply>,
}

impl<'m> Device<'m> {
    /// The servos of `map` moving `plant` (already settled: its time is the start's),
    /// serving from `start` with `settings`.
    pub fn new(
        map: TendonMap,
        plant: Plant<'m>,
        settings: &EmulatorSettings,
        start: Instant,
    ) -> Result<Device<'m>, EmulatorError> {
        super::check(settings)?;
        super::check_silent_servo(settings, &map.hardware().servo_ids())?;
        let baud_register =
            crate::hardware_description::limits::baud_register(settings.baud).unwrap_or(3);
        let delay_register = (settings.return_delay.as_micros() / 2).min(254) as u8;
        let origin = plant.time();
        let mut servos = Servos::new(map, plant, baud_register, delay_register);
        servos.set_noise(settings.noise);
        let n = servos.ids().len();
        Ok(Device {
            servos,
            baud: settings.baud,
            faults: settings.faults.clone(),
            decoder: Decoder::default(),
            received: 0,
            chunks: VecDeque::new(),
            requests: VecDeque::new(),
            outgoing: VecDeque::new(),
            adapter: (!settings.latency_timer.is_zero())
                .then(|| Adapter::new(settings.latency_timer, start)),
            bus_free: start,
            start,
            origin,
            first_packet: None,
            heard: vec![None; n],
            draws: Draws::seed_from_u64(settings.faults.seed),
            log: EmulatorLog {
                torque: vec![false; n],
                ..EmulatorLog::default()
            },
            replies: Vec::new(),
        })
    }

    /// The servos.
    pub fn servos(&self) -> &Servos<'m> {
        &self.servos
    }

    /// What the device did so far.
    pub fn log(&self) -> &EmulatorLog {
        &self.log
    }

    /// The record, consuming the device.
    pub fn into_log(self) -> EmulatorLog {
        self.log
    }

    /// Takes `bytes` that arrived at `at` (no earlier than any previous call's time).
    /// Timers due before `at` run first, so an incomplete packet older than its timeout
    /// is dropped before these bytes are appended.
    pub fn receive(&mut self, bytes: &[u8], at: Instant) -> Result<(), EmulatorError> {
        self.poll(at)?;
        let mut rest = bytes;
        while !rest.is_empty() {
            let n = self.decoder.push(rest);
            if n == 0 {
                // Cannot happen after draining (half the buffer is then free); drop the
                // undecodable bytes rather than loop.
                self.decoder.clear();
                self.chunks.clear();
                continue;
            }
            self.chunks.push_back((self.received, at));
            self.received += n as u64;
            rest = &rest[n..];
            self.drain(at);
        }
        Ok(())
    }

    /// Decodes every whole packet held and queues it for execution.
    fn drain(&mut self, at: Instant) {
        loop {
            let size = announced_size(self.decoder.pending_bytes()).unwrap_or(PREFIX_LEN + 3);
            let wire = super::wire_time(size, self.baud);
            let what = match self.decoder.next_packet() {
                None => break,
                Some(Ok(p)) if p.instruction == Instruction::Status => continue,
                Some(Ok(p)) => Received::Packet(p.to_buf()),
                Some(Err(DecodeError::UnknownInstruction { id, .. })) => Received::Undefined(id),
                Some(Err(DecodeError::BadCrc { id, .. })) => Received::BadCrc(id),
                Some(Err(_)) => continue,
            };
            self.requests.push_back(Request {
                what,
                arrival: at,
                wire,
            });
        }
        let pending = self.decoder.pending() as u64;
        if pending == 0 {
            self.chunks.clear();
        } else {
            let first = self.received - pending;
            while self.chunks.len() > 1 && self.chunks[1].0 <= first {
                self.chunks.pop_front();
            }
        }
    }

    /// When the incomplete packet held (if any) times out.
    fn partial_deadline(&self) -> Option<Instant> {
        if self.decoder.pending() == 0 {
            return None;
        }
        let &(_, since) = self.chunks.front()?;
        let pending = self.decoder.pending_bytes();
        let length = (pending.len() >= PREFIX_LEN && pending[..HEADER.len()] == HEADER)
            .then(|| u16::from_le_bytes([pending[5], pending[6]]));
        Some(later(since, packet_timeout(length, self.baud)))
    }

    /// When the next received packet will have crossed the bus.
    fn next_request_end(&self) -> Option<Instant> {
        self.requests
            .front()
            .map(|r| later(r.arrival.max(self.bus_free), r.wire))
    }

    /// The next Bus Watchdog expiry: its time and the servo.
    fn next_expiry(&self) -> Option<(Instant, usize)> {
        (0..self.heard.len())
            .filter_map(|s| {
                let period = self.servos.watchdog_period(s)?;
                Some((later(self.heard[s]?, period), s))
            })
            .min()
    }

    /// The next moment something must happen on time: a request's end on the bus or a
    /// delivery of bytes to the host. Timers ([`Device::poll`]) may run late without
    /// changing the outcome, as they act at their own time.
    pub fn next_due(&self) -> Option<Instant> {
        let reply = match &self.adapter {
            Some(adapter) => adapter.next_delivery().map(|(at, _)| at),
            None => self.outgoing.front().map(|o| o.due),
        };
        match (self.next_request_end(), reply) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// The next timer: a packet timeout or a Bus Watchdog expiry.
    pub fn next_timer(&self) -> Option<Instant> {
        let expiry = self.next_expiry().map(|(t, _)| t);
        match (self.partial_deadline(), expiry) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Runs everything due by `now`, in time order: requests whose last byte has crossed
    /// the bus, Bus Watchdog expiries (a watchdog expires when the gap exceeds its period)
    /// and the timeout of an incomplete packet.
    pub fn poll(&mut self, now: Instant) -> Result<(), EmulatorError> {
        if self.partial_deadline().is_some_and(|d| now > d) {
            self.decoder.clear();
            self.chunks.clear();
            self.log.stale_packets += 1;
        }
        loop {
            let end = self.next_request_end().filter(|&e| e <= now);
            let expiry = self.next_expiry().filter(|&(t, _)| t < now);
            match (end, expiry) {
                (Some(e), Some((t, _))) if e <= t => self.execute_next(e)?,
                (Some(e), None) => self.execute_next(e)?,
                (_, Some((t, s))) => self.expire(s, t)?,
                (None, None) => return Ok(()),
            }
        }
    }

    /// The next bytes for the host due by `now`, in order: a whole status packet when its
    /// last byte has crossed the bus, or what the USB adapter passes on at once (call
    /// [`Device::poll`] with `now` first, so that every request up to then has answered).
    pub fn take_due(&mut self, now: Instant) -> Option<Delivery> {
        if let Some(adapter) = &mut self.adapter {
            return adapter.take_due(now);
        }
        if self.outgoing.front()?.due <= now {
            let Outgoing { due, bytes } = self.outgoing.pop_front()?;
            Some(Delivery { at: due, bytes })
        } else {
            None
        }
    }

    fn plant_time(&self, at: Instant) -> f64 {
        self.origin + at.saturating_duration_since(self.start).as_secs_f64()
    }

    /// The Bus Watchdog of servo `s` expired at `at`.
    fn expire(&mut self, s: usize, at: Instant) -> Result<(), EmulatorError> {
        self.servos.advance_to(self.plant_time(at))?;
        self.servos.stop_by_watchdog(s);
        self.log
            .watchdog_stops
            .push((self.plant_time(at), self.servos.id(s)));
        Ok(())
    }

    /// Executes the first queued request, whose end on the bus is `end`.
    fn execute_next(&mut self, end: Instant) -> Result<(), EmulatorError> {
        let Some(request) = self.requests.pop_front() else {
            return Ok(());
        };
        let t = self.plant_time(end);
        let first_packet = *self.first_packet.get_or_insert(end);
        self.replies.clear();
        let mut packet = None;
        match request.what {
            Received::Packet(p) => {
                self.hear(end);
                self.servos.execute(&p.as_ref(), t, &mut self.replies)?;
                self.log.requests += 1;
                packet = Some(p);
            }
            Received::Undefined(id) => {
                self.hear(end);
                self.servos.undefined_instruction(id, &mut self.replies);
            }
            Received::BadCrc(id) => self.servos.crc_error(id, &mut self.replies),
        }
        let mut cursor = end;
        let mut states = Vec::new();
        let replies = std::mem::take(&mut self.replies);
        for reply in &replies {
            let since_first = end.saturating_duration_since(first_packet);
            let fate = fate_of(reply.id, &self.faults, since_first, &mut self.draws);
            self.log.fates[fate as usize] += 1;
            if let Some(state) = packet.as_ref().and_then(|p| state_block(p, &reply.params)) {
                states.push(StateReply {
                    id: reply.id,
                    fate,
                    state,
                });
            }
            if matches!(fate, ReplyFate::Dropped | ReplyFate::Silent) {
                continue;
            }
            let mut bytes = Vec::with_capacity(PREFIX_LEN + 2 + reply.params.len() + CRC_LEN);
            if encode_status(reply.id, reply.error, &reply.params, &mut bytes).is_err() {
                continue; // an ID the protocol cannot send from: nothing goes out
            }
            if fate == ReplyFate::Corrupted
                && let Some(last) = bytes.last_mut()
            {
                *last ^= 0x5A;
            }
            cursor = later(
                cursor,
                reply.return_delay + super::wire_time(bytes.len(), self.baud),
            );
            if fate == ReplyFate::Delayed {
                cursor = later(cursor, self.faults.delay);
            }
            match &mut self.adapter {
                Some(adapter) => adapter.receive(cursor, &bytes, self.baud),
                None => self.outgoing.push_back(Outgoing { due: cursor, bytes }),
            }
        }
        self.replies = replies;
        self.bus_free = cursor;
        if let Some(p) = &packet {
            record(&mut self.log, p, t, states, &self.servos);
        }
        Ok(())
    }

    /// Every servo that understands the bus heard an instruction packet at `at`.
    fn hear(&mut self, at: Instant) {
        for s in 0..self.heard.len() {
            if self.servos.hears(s) {
                self.heard[s] = Some(at);
            }
        }
    }
}

/// Bytes on the wire of the packet whose header starts the first header in `pending`.
fn announced_size(pending: &[u8]) -> Option<usize> {
    let p = pending.windows(HEADER.len()).position(|w| w == HEADER)?;
    let field = pending.get(p + 5..p + 7)?;
    Some(PREFIX_LEN + usize::from(u16::from_le_bytes([field[0], field[1]])))
}

/// The state block inside a sync-read reply that covers it (the loop reads it with 0–3
/// bytes before it).
fn state_block(packet: &PacketBuf, params: &[u8]) -> Option<ServoState> {
    if packet.instruction != Instruction::SyncRead || packet.id != BROADCAST_ID {
        return None;
    }
    let (addr, len, _) = crate::protocol::parse_sync_read(&packet.params)?;
    let skip = table::STATE_ADDRESS.checked_sub(addr)?;
    (u32::from(addr) + u32::from(len)
        == u32::from(table::STATE_ADDRESS) + u32::from(table::STATE_LENGTH)
        && params.len() == usize::from(len))
    .then(|| ServoState::from_bytes(&params[usize::from(skip)..]))
}

/// What happens to a status packet of servo `id`, sent `since_first` after the first
/// packet the device received.
fn fate_of(id: u8, faults: &Faults, since_first: Duration, draws: &mut Draws) -> ReplyFate {
    if faults.silent_servo == Some(id) && since_first >= faults.silent_after {
        return ReplyFate::Silent;
    }
    // Draw all three every time so one fault's setting does not shift another's sequence.
    let [drop, corrupt, delay]: [f64; 3] = draws.random();
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
        Instruction::SyncWrite if packet.id == BROADCAST_ID => {
            match parse_sync_write(&packet.params) {
                Some((addr, 2, items)) if goal(addr) => items
                    .map(|(id, d)| (id, i16::from_le_bytes([d[0], d[1]])))
                    .collect(),
                _ => Vec::new(),
            }
        }
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
