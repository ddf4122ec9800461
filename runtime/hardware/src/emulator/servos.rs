//! The emulated servos: one X-series control table per servo and what each Protocol 2.0
//! instruction does to it, with the robot's motion from the simulated plant. No I/O, no clock.
//!
//! Tensions come from the goal currents through the actuator gain (a negative current
//! unwinds the pulley: the cable goes slack, zero tension); a servo with torque off, not in
//! current control mode, or stopped by its Bus Watchdog pulls with nothing. Register values
//! are sampled from the plant at the time an instruction is executed, with the sensor
//! noise asked for ([`SensorNoise`]) added before they are rounded to register units.
//!
//! Instructions (ROBOTIS e-Manual, "Protocol 2.0" and the X-series control table):
//!
//! - Addressing: a servo obeys packets sent to its ID (register 7, so a written ID takes
//!   effect at once) or to the broadcast ID. A servo whose Baud Rate register no longer
//!   matches the bus, or whose Protocol Type is 1, hears nothing.
//! - Replies: Ping is always answered; Read, Sync Read and Bulk Read from Status Return
//!   Level 1; every other instruction at level 2 only. Nothing sent to the broadcast ID is
//!   answered except Ping, Sync Read and Bulk Read. Sync and Bulk instructions addressed to
//!   anything but the broadcast ID are ignored. A servo answers with the ID, level and
//!   Return Delay Time it had when the packet arrived (a write of its ID is acknowledged
//!   from the old one).
//! - Writes (Write, Reg Write + Action, Sync Write, Bulk Write) are all or nothing. They are
//!   refused with an Access Error if a byte is undefined, read-only, or in the EEPROM area
//!   while torque is on; a Data Length Error if there is no data or an item is covered in
//!   part; a Data Range Error for a value outside [`table::X_SERIES`]'s range, or for a
//!   Goal value while the Bus Watchdog has stopped the servo; a Data Limit Error for a goal
//!   beyond its limit (e.g. Goal Current beyond ± Current Limit). Sync and Bulk Writes
//!   report nothing; a refused item is not applied.
//! - Reads inside the modelled table return its bytes, undefined ones as 0; a read past it
//!   (Present Temperature, 146, is the last byte) or of no defined byte gets an Access Error.
//! - Reg Write checks the write and keeps it (Registered Instruction reads 1); Action
//!   applies it, or answers an Instruction Error when nothing is registered.
//! - Factory Reset (option 0xFF all, 0x01 all but the ID, 0x02 all but ID and Baud Rate)
//!   answers first, then restores the factory table; refused while torque is on (it writes
//!   the EEPROM area); sent to the broadcast ID with option 0xFF it does nothing, as on
//!   firmware 42 and later.
//! - Reboot answers, then restores the RAM area (torque off) and forgets a Reg Write.
//! - Clear (0x01 and the fixed bytes 44 58 4C 22) brings Present Position within one turn;
//!   it fails (Result Fail) while the servo moves faster than its Moving Threshold.
//! - Switching the Operating Mode resets Goal PWM and Goal Current to their limits and the
//!   profile to 0, as the e-Manual says.
//!
//! Not modelled: the Secondary ID, Drive Mode's effects, hardware errors and Shutdown,
//! position/velocity/PWM control (only current control moves the plant).

use std::time::Duration;

use rand::SeedableRng;
use rand::rngs::Xoshiro256PlusPlus;

use crate::control_table::{self as table, Access, Area, Item, ServoState, Values};
use crate::integrator::IntegratorError;
use crate::mapping::TendonMap;
use crate::noise::SensorNoise;
use crate::noise::standard_normal;
use crate::plant::Plant;
use crate::protocol::{
    BROADCAST_ID, Instruction, PacketRef, StatusError, parse_read, parse_sync_read,
    parse_sync_write, parse_write,
};

/// Firmware version the emulated servos report.
pub const FIRMWARE_VERSION: u8 = 46;

/// Present Input Voltage the emulated servos report (12.0 V, the recommended supply).
pub const INPUT_VOLTAGE: u16 = 120;

/// Present Temperature the emulated servos report \[°C\].
pub const TEMPERATURE: u8 = 25;

/// The fixed bytes after option 0x01 of a Clear instruction.
const CLEAR_KEY: [u8; 4] = [0x44, 0x58, 0x4C, 0x22];

/// One status packet to send: who sends it, its content (unencoded) and the sender's
/// Return Delay Time.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reply {
    /// Sender ID.
    pub id: u8,
    /// Error byte.
    pub error: u8,
    /// Parameters.
    pub params: Vec<u8>,
    /// The sender's Return Delay Time when it answered.
    pub return_delay: Duration,
}

/// Which instructions a Status Return Level answers.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Ping,
    Read,
    Other,
}

/// Who answers a packet, as it was when the packet arrived.
#[derive(Clone, Copy)]
struct Sender {
    id: u8,
    level: u8,
    delay: u8,
}

/// Appends `sender`'s status packet if its Status Return Level answers `kind`.
fn answer(sender: Sender, kind: Kind, error: u8, params: Vec<u8>, replies: &mut Vec<Reply>) {
    let answers = match kind {
        Kind::Ping => true,
        Kind::Read => sender.level >= 1,
        Kind::Other => sender.level >= 2,
    };
    if answers {
        replies.push(Reply {
            id: sender.id,
            error,
            params,
            return_delay: Duration::from_micros(2 * u64::from(sender.delay)),
        });
    }
}

/// The servos of one robot and the plant they move.
pub struct Servos<'m> {
    map: TendonMap,
    plant: Plant<'m>,
    ids: Vec<u8>,
    bus_baud: u8,
    factory: [u8; table::TABLE_SIZE],
    tables: Vec<[u8; table::TABLE_SIZE]>,
    registered: Vec<Option<Vec<u8>>>,
    turns: Vec<i64>,
    angles: Vec<f64>,
    rates: Vec<f64>,
    tensions: Vec<f64>,
    noise: SensorNoise,
    noise_draws: Xoshiro256PlusPlus,
}

/// Offset between the fault draws' seed and the noise draws' (any odd constant): the same
/// `--seed` gives the two unrelated streams.
const NOISE_STREAM: u64 = 0x9E37_79B9_7F4A_7C15;

fn range(addr: u16, size: u16) -> std::ops::Range<usize> {
    usize::from(addr)..usize::from(addr) + usize::from(size)
}

/// The value of the item at `addr` in `t` (0 if no item starts there).
fn get(t: &[u8; table::TABLE_SIZE], addr: u16) -> i64 {
    table::item_starting_at(addr).map_or(0, |i| i.value(&t[range(i.address, i.size)]))
}

/// Sets the item at `addr` in `t` (nothing if no item starts there).
fn set(t: &mut [u8; table::TABLE_SIZE], addr: u16, value: i64) {
    if let Some(i) = table::item_starting_at(addr) {
        i.encode(value, &mut t[range(i.address, i.size)]);
    }
}

/// The goal items the Bus Watchdog makes read-only.
fn is_goal(item: &Item) -> bool {
    [
        table::GOAL_PWM,
        table::GOAL_CURRENT,
        table::GOAL_VELOCITY,
        table::GOAL_POSITION,
    ]
    .contains(&item.address)
}

impl<'m> Servos<'m> {
    /// Servos with factory tables (Operating Mode 3, position control; torque off) moving
    /// `plant`, except for their IDs (the robot file's), Model Number (the file's),
    /// `baud_register` (the bus's Baud Rate value) and `return_delay_register`.
    pub fn new(
        map: TendonMap,
        plant: Plant<'m>,
        baud_register: u8,
        return_delay_register: u8,
    ) -> Servos<'m> {
        let ids = map.hardware().servo_ids();
        let n = ids.len();
        let mut factory = [0u8; table::TABLE_SIZE];
        for item in table::X_SERIES {
            item.encode(item.initial, &mut factory[range(item.address, item.size)]);
        }
        set(
            &mut factory,
            table::MODEL_NUMBER,
            i64::from(map.hardware().model_number),
        );
        set(
            &mut factory,
            table::FIRMWARE_VERSION,
            i64::from(FIRMWARE_VERSION),
        );
        let tables = ids
            .iter()
            .map(|&id| {
                let mut t = factory;
                set(&mut t, table::ID, i64::from(id));
                set(&mut t, table::BAUD_RATE, i64::from(baud_register));
                set(
                    &mut t,
                    table::RETURN_DELAY_TIME,
                    i64::from(return_delay_register),
                );
                t
            })
            .collect();
        Servos {
            map,
            plant,
            ids,
            bus_baud: baud_register,
            factory,
            tables,
            registered: vec![None; n],
            turns: vec![0; n],
            angles: vec![0.0; n],
            rates: vec![0.0; n],
            tensions: vec![0.0; n],
            noise: SensorNoise::NONE,
            noise_draws: Xoshiro256PlusPlus::seed_from_u64(NOISE_STREAM),
        }
    }

    /// Adds `noise` to the readings from now on (its seed restarts the draws).
    pub fn set_noise(&mut self, noise: SensorNoise) {
        self.noise = noise;
        self.noise_draws = Xoshiro256PlusPlus::seed_from_u64(noise.seed ^ NOISE_STREAM);
    }

    /// The servo IDs the robot file gives, in bus order (an ID written later is in the
    /// table, see [`Servos::id`]).
    pub fn ids(&self) -> &[u8] {
        &self.ids
    }

    /// The ID servo `index` answers to now.
    pub fn id(&self, index: usize) -> u8 {
        self.tables[index][usize::from(table::ID)]
    }

    /// The plant.
    pub fn plant(&self) -> &Plant<'m> {
        &self.plant
    }

    /// The control table of servo `index`, as last sampled.
    pub fn table(&self, index: usize) -> &[u8] {
        &self.tables[index]
    }

    /// Whether servo `index` has torque enabled.
    pub fn torque_enabled(&self, index: usize) -> bool {
        self.tables[index][usize::from(table::TORQUE_ENABLE)] != 0
    }

    /// Goal Current register of servo `index`.
    pub fn goal_current(&self, index: usize) -> i16 {
        get(&self.tables[index], table::GOAL_CURRENT) as i16
    }

    /// Bus Watchdog register of servo `index` (−1: it expired and stopped the servo).
    pub fn watchdog(&self, index: usize) -> i8 {
        self.tables[index][usize::from(table::BUS_WATCHDOG)] as i8
    }

    /// The longest gap between instruction packets servo `index` tolerates now: set when
    /// torque is on, the Bus Watchdog holds 1..=127 (units of 20 ms) and the servo hears
    /// the bus.
    pub fn watchdog_period(&self, index: usize) -> Option<Duration> {
        let w = self.watchdog(index);
        (self.torque_enabled(index) && w > 0 && self.hears(index))
            .then(|| Duration::from_millis(20 * w as u64))
    }

    /// The Bus Watchdog of servo `index` expired: it stops (pulls with nothing) and its
    /// Bus Watchdog reads −1 until a write clears it.
    pub fn stop_by_watchdog(&mut self, index: usize) {
        self.tables[index][usize::from(table::BUS_WATCHDOG)] = (-1i8) as u8;
        self.update_forces();
    }

    /// Tension servo `index` pulls with now \[N\].
    pub fn tension(&self, index: usize) -> f64 {
        self.tensions[index]
    }

    /// The state block servo `index` reports (call [`Servos::advance_to`] first).
    pub fn state(&self, index: usize) -> ServoState {
        let start = usize::from(table::STATE_ADDRESS);
        ServoState::from_bytes(&self.tables[index][start..start + usize::from(table::STATE_LENGTH)])
    }

    /// Whether servo `index` understands the bus: same baud rate, Protocol 2.0.
    pub fn hears(&self, index: usize) -> bool {
        let t = &self.tables[index];
        t[usize::from(table::BAUD_RATE)] == self.bus_baud
            && t[usize::from(table::PROTOCOL_TYPE)] == 2
    }

    /// Advances the plant to time `t` \[s\] with the tensions held, and samples every
    /// servo's Present values.
    pub fn advance_to(&mut self, t: f64) -> Result<(), IntegratorError> {
        let dt = t - self.plant.time();
        if dt > 0.0 {
            self.plant.advance(dt)?;
        }
        self.map.angles_from_q(self.plant.q(), &mut self.angles);
        self.map.rates_from_qd(self.plant.qd(), &mut self.rates);
        let tick = ((self.plant.time() * 1000.0).max(0.0) as u64 % 32768) as i64;
        if self.noise.is_on() {
            // One register unit in radians and in rad/s; both draws every time, so one
            // deviation's setting does not shift the other's sequence.
            let (position_unit, velocity_unit) = (
                self.map.angle_from_position(1),
                self.map.rate_from_velocity(1),
            );
            for s in 0..self.ids.len() {
                let [position, velocity] = [(); 2].map(|_| standard_normal(&mut self.noise_draws));
                self.angles[s] += self.noise.position * position_unit * position;
                self.rates[s] += self.noise.velocity * velocity_unit * velocity;
            }
        }
        for s in 0..self.ids.len() {
            let current = if self.pulls(s) {
                self.goal_current(s)
            } else {
                0
            };
            let velocity = self.map.velocity_from_rate(self.rates[s]);
            let t = &mut self.tables[s];
            let position = i64::from(self.map.position_from_angle(self.angles[s]))
                + get(t, table::HOMING_OFFSET)
                - self.turns[s];
            let position = position.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
            let state = ServoState {
                current,
                velocity,
                position,
            };
            let start = usize::from(table::STATE_ADDRESS);
            state.to_bytes(&mut t[start..start + usize::from(table::STATE_LENGTH)]);
            let moving = i64::from(velocity).abs() > get(t, table::MOVING_THRESHOLD);
            set(t, table::MOVING, i64::from(moving));
            set(t, table::REALTIME_TICK, tick);
            set(t, table::PRESENT_INPUT_VOLTAGE, i64::from(INPUT_VOLTAGE));
            set(t, table::PRESENT_TEMPERATURE, i64::from(TEMPERATURE));
        }
        Ok(())
    }

    fn pulls(&self, s: usize) -> bool {
        self.torque_enabled(s)
            && self.tables[s][usize::from(table::OPERATING_MODE)] == table::CURRENT_CONTROL_MODE
            && self.watchdog(s) != -1
    }

    /// Recomputes the tensions and the plant's held `τ = A f` from the registers.
    fn update_forces(&mut self) {
        for s in 0..self.ids.len() {
            self.tensions[s] = if self.pulls(s) {
                self.map
                    .tension_from_current(s, self.goal_current(s))
                    .max(0.0)
            } else {
                0.0
            };
        }
        let tensions = &self.tensions;
        self.map.tau_from_tensions(tensions, self.plant.tau_mut());
    }

    /// The servos that take a packet sent to `id`, in bus order.
    fn addressed(&self, id: u8) -> Vec<usize> {
        (0..self.ids.len())
            .filter(|&s| self.hears(s) && (id == BROADCAST_ID || self.id(s) == id))
            .collect()
    }

    /// The servos named `id` in a sync or bulk instruction's list (never all of them).
    fn named(&self, id: u8) -> Vec<usize> {
        (0..self.ids.len())
            .filter(|&s| self.hears(s) && self.id(s) == id)
            .collect()
    }

    /// Servo `s` as it answers a packet arriving now: the ID, Status Return Level and
    /// Return Delay Time in force when the packet arrived, whatever the packet changes.
    fn sender(&self, s: usize) -> Sender {
        let t = &self.tables[s];
        Sender {
            id: t[usize::from(table::ID)],
            level: t[usize::from(table::STATUS_RETURN_LEVEL)],
            delay: t[usize::from(table::RETURN_DELAY_TIME)],
        }
    }

    /// A packet for `id` arrived with a bad CRC: that servo answers a CRC Error (at Status
    /// Return Level 2, as the instruction cannot be known).
    pub fn crc_error(&self, id: u8, replies: &mut Vec<Reply>) {
        if id != BROADCAST_ID {
            for s in self.addressed(id) {
                let error = StatusError::CRC_ERROR;
                answer(self.sender(s), Kind::Other, error, Vec::new(), replies);
            }
        }
    }

    /// A packet for `id` with an instruction code Protocol 2.0 does not define: that
    /// servo answers an Instruction Error (at Status Return Level 2).
    pub fn undefined_instruction(&self, id: u8, replies: &mut Vec<Reply>) {
        if id != BROADCAST_ID {
            for s in self.addressed(id) {
                let error = StatusError::INSTRUCTION_ERROR;
                answer(self.sender(s), Kind::Other, error, Vec::new(), replies);
            }
        }
    }

    /// Executes `packet` at time `t` (the plant is advanced there first) and appends the
    /// status packets the servos send, in bus order.
    pub fn execute(
        &mut self,
        packet: &PacketRef<'_>,
        t: f64,
        replies: &mut Vec<Reply>,
    ) -> Result<(), IntegratorError> {
        self.advance_to(t)?;
        let broadcast = packet.id == BROADCAST_ID;
        let params = packet.params;
        let senders: Vec<Sender> = (0..self.ids.len()).map(|s| self.sender(s)).collect();
        match packet.instruction {
            Instruction::Ping => {
                for s in self.addressed(packet.id) {
                    let own = &self.tables[s];
                    let params = vec![own[0], own[1], own[usize::from(table::FIRMWARE_VERSION)]];
                    answer(senders[s], Kind::Ping, 0, params, replies);
                }
            }
            Instruction::Read if !broadcast => {
                for s in self.addressed(packet.id) {
                    let (error, data) = self.read(s, parse_read(params));
                    answer(senders[s], Kind::Read, error, data, replies);
                }
            }
            Instruction::Write => {
                for s in self.addressed(packet.id) {
                    let error = match parse_write(params) {
                        Some((addr, data)) => self.write(s, addr, data),
                        None => StatusError::DATA_LENGTH_ERROR,
                    };
                    if !broadcast {
                        answer(senders[s], Kind::Other, error, Vec::new(), replies);
                    }
                }
            }
            Instruction::RegWrite => {
                for s in self.addressed(packet.id) {
                    let error = self.register(s, params);
                    if !broadcast {
                        answer(senders[s], Kind::Other, error, Vec::new(), replies);
                    }
                }
            }
            Instruction::Action => {
                for s in self.addressed(packet.id) {
                    let error = self.action(s);
                    if !broadcast {
                        answer(senders[s], Kind::Other, error, Vec::new(), replies);
                    }
                }
            }
            Instruction::FactoryReset if !(broadcast && params == [0xFF]) => {
                for s in self.addressed(packet.id) {
                    let error = self.reset_check(s, params);
                    if !broadcast {
                        answer(senders[s], Kind::Other, error, Vec::new(), replies);
                    }
                    if error == 0 {
                        self.factory_reset(s, params[0]);
                    }
                }
            }
            Instruction::Reboot => {
                for s in self.addressed(packet.id) {
                    if !broadcast {
                        answer(senders[s], Kind::Other, 0, Vec::new(), replies);
                    }
                    self.reboot(s);
                }
            }
            Instruction::Clear => {
                for s in self.addressed(packet.id) {
                    let error = self.clear(s, params);
                    if !broadcast {
                        answer(senders[s], Kind::Other, error, Vec::new(), replies);
                    }
                }
            }
            Instruction::SyncRead if broadcast => {
                if let Some((addr, len, ids)) = parse_sync_read(params) {
                    let reads = ids.iter().map(|&id| (id, addr, len));
                    self.read_each(reads, &senders, replies);
                }
            }
            Instruction::SyncWrite if broadcast => {
                if let Some((addr, _, items)) = parse_sync_write(params) {
                    self.write_each(items.map(|(id, data)| (id, addr, data)));
                }
            }
            Instruction::BulkRead if broadcast => {
                if let Some(entries) = parse_bulk_read(params) {
                    self.read_each(entries, &senders, replies);
                }
            }
            Instruction::BulkWrite if broadcast => {
                if let Some(entries) = parse_bulk_write(params) {
                    self.write_each(entries);
                }
            }
            // Broadcast reads, unicast sync/bulk instructions, a broadcast factory reset of
            // everything, and other devices' status packets are ignored.
            _ => {}
        }
        self.update_forces();
        Ok(())
    }

    /// The reads `(id, addr, len)` of a sync or bulk read, answered in order by the servos
    /// named; an ID named again in the same packet is ignored.
    fn read_each(
        &self,
        reads: impl IntoIterator<Item = (u8, u16, u16)>,
        senders: &[Sender],
        replies: &mut Vec<Reply>,
    ) {
        for (id, addr, len) in first_per_id(reads, |r| r.0) {
            for s in self.named(id) {
                let (error, data) = self.read(s, Some((addr, len)));
                answer(senders[s], Kind::Read, error, data, replies);
            }
        }
    }

    /// The writes `(id, addr, data)` of a sync or bulk write, applied by the servos named;
    /// an ID named again in the same packet is ignored. No status packet: a refused write
    /// is silently not applied.
    fn write_each<'p>(&mut self, writes: impl IntoIterator<Item = (u8, u16, &'p [u8])>) {
        for (id, addr, data) in first_per_id(writes, |w| w.0) {
            for s in self.named(id) {
                let _ = self.write(s, addr, data);
            }
        }
    }

    /// The bytes a read of `len` at `addr` returns, or the error number.
    fn read(&self, s: usize, request: Option<(u16, u16)>) -> (u8, Vec<u8>) {
        let Some((addr, len)) = request else {
            return (StatusError::DATA_LENGTH_ERROR, Vec::new());
        };
        let bytes = usize::from(addr)..usize::from(addr) + usize::from(len);
        if bytes.end > table::TABLE_SIZE || !bytes.clone().any(|a| table::item_at(a).is_some()) {
            return (StatusError::ACCESS_ERROR, Vec::new());
        }
        let t = &self.tables[s];
        let data = bytes
            .map(|a| if table::item_at(a).is_some() { t[a] } else { 0 })
            .collect();
        (0, data)
    }

    /// Why writing `data` at `addr` of servo `s` is refused, as an error number, or the
    /// items it covers.
    fn check_write(&self, s: usize, addr: u16, data: &[u8]) -> Result<Vec<&'static Item>, u8> {
        if data.is_empty() {
            return Err(StatusError::DATA_LENGTH_ERROR);
        }
        let (start, end) = (usize::from(addr), usize::from(addr) + data.len());
        if end > table::TABLE_SIZE {
            return Err(StatusError::ACCESS_ERROR);
        }
        let torque_on = self.torque_enabled(s);
        for a in start..end {
            match table::item_at(a) {
                Some(item)
                    if item.access == Access::ReadWrite
                        && !(item.area == Area::Eeprom && torque_on) => {}
                _ => return Err(StatusError::ACCESS_ERROR),
            }
        }
        let items: Vec<&'static Item> = table::X_SERIES
            .iter()
            .filter(|i| usize::from(i.address) < end && start < usize::from(i.end()))
            .collect();
        if items
            .iter()
            .any(|i| usize::from(i.address) < start || usize::from(i.end()) > end)
        {
            return Err(StatusError::DATA_LENGTH_ERROR);
        }
        let t = &self.tables[s];
        let value = |i: &Item| {
            let at = usize::from(i.address) - start;
            i.value(&data[at..at + usize::from(i.size)])
        };
        let stopped = self.watchdog(s) == -1;
        for &i in &items {
            let v = value(i);
            let in_range = match i.values {
                Values::Any | Values::WithinLimit(_) => true,
                Values::Range(lo, hi) => (lo..=hi).contains(&v),
                Values::OneOf(set) => set.contains(&v),
                Values::Bits(mask) => v & !i64::from(mask) == 0,
                Values::GoalPosition => (-1_048_575..=1_048_575).contains(&v),
            };
            if !in_range || (stopped && is_goal(i)) {
                return Err(StatusError::DATA_RANGE_ERROR);
            }
        }
        for &i in &items {
            let v = value(i);
            let within = match i.values {
                Values::WithinLimit(limit) => v.abs() <= get(t, limit),
                Values::GoalPosition if get(t, table::OPERATING_MODE) == 3 => {
                    (get(t, table::MIN_POSITION_LIMIT)..=get(t, table::MAX_POSITION_LIMIT))
                        .contains(&v)
                }
                _ => true,
            };
            if !within {
                return Err(StatusError::DATA_LIMIT_ERROR);
            }
        }
        Ok(items)
    }

    /// Writes `data` at `addr` of servo `s` if [`Servos::check_write`] allows it; the error
    /// number.
    fn write(&mut self, s: usize, addr: u16, data: &[u8]) -> u8 {
        if let Err(e) = self.check_write(s, addr, data) {
            return e;
        }
        let t = &mut self.tables[s];
        let mode = t[usize::from(table::OPERATING_MODE)];
        let start = usize::from(addr);
        t[start..start + data.len()].copy_from_slice(data);
        if t[usize::from(table::OPERATING_MODE)] != mode {
            let pwm = get(t, table::PWM_LIMIT);
            let current = get(t, table::CURRENT_LIMIT);
            set(t, table::GOAL_PWM, pwm);
            set(t, table::GOAL_CURRENT, current);
            set(t, table::PROFILE_ACCELERATION, 0);
            set(t, table::PROFILE_VELOCITY, 0);
        }
        0
    }

    /// Reg Write: checks the write and keeps it for [`Servos::action`].
    fn register(&mut self, s: usize, params: &[u8]) -> u8 {
        let Some((addr, data)) = parse_write(params) else {
            return StatusError::DATA_LENGTH_ERROR;
        };
        if let Err(e) = self.check_write(s, addr, data) {
            return e;
        }
        self.registered[s] = Some(params.to_vec());
        self.tables[s][usize::from(table::REGISTERED_INSTRUCTION)] = 1;
        0
    }

    /// Action: applies the registered write (checked again), or an Instruction Error.
    fn action(&mut self, s: usize) -> u8 {
        let Some(params) = self.registered[s].take() else {
            return StatusError::INSTRUCTION_ERROR;
        };
        self.tables[s][usize::from(table::REGISTERED_INSTRUCTION)] = 0;
        match parse_write(&params) {
            Some((addr, data)) => self.write(s, addr, data),
            None => StatusError::DATA_LENGTH_ERROR,
        }
    }

    /// Whether a Factory Reset with `params` may run on servo `s`: 0, or the error number.
    fn reset_check(&self, s: usize, params: &[u8]) -> u8 {
        match params {
            [0x01 | 0x02 | 0xFF] if self.torque_enabled(s) => StatusError::ACCESS_ERROR,
            [0x01 | 0x02 | 0xFF] => 0,
            [_] => StatusError::DATA_RANGE_ERROR,
            _ => StatusError::DATA_LENGTH_ERROR,
        }
    }

    /// Factory Reset: the factory table, keeping the ID (option 0x01) or the ID and the
    /// Baud Rate (0x02).
    fn factory_reset(&mut self, s: usize, option: u8) {
        let old = self.tables[s];
        let mut fresh = self.factory;
        if option != 0xFF {
            fresh[usize::from(table::ID)] = old[usize::from(table::ID)];
        }
        if option == 0x02 {
            fresh[usize::from(table::BAUD_RATE)] = old[usize::from(table::BAUD_RATE)];
        }
        self.tables[s] = fresh;
        self.registered[s] = None;
        self.turns[s] = 0;
    }

    /// Reboot: the RAM area back to its initial values (Goal PWM at the PWM Limit), no
    /// registered write.
    fn reboot(&mut self, s: usize) {
        let t = &mut self.tables[s];
        for item in table::X_SERIES.iter().filter(|i| i.area == Area::Ram) {
            item.encode(item.initial, &mut t[range(item.address, item.size)]);
        }
        let pwm = get(t, table::PWM_LIMIT);
        set(t, table::GOAL_PWM, pwm);
        self.registered[s] = None;
    }

    /// Clear: with option 0x01 and its key, Present Position within one turn.
    fn clear(&mut self, s: usize, params: &[u8]) -> u8 {
        if params.len() != 5 {
            return StatusError::DATA_LENGTH_ERROR;
        }
        if params[0] != 0x01 || params[1..] != CLEAR_KEY {
            return StatusError::DATA_RANGE_ERROR;
        }
        let t = &self.tables[s];
        if get(t, table::MOVING) != 0 {
            return StatusError::RESULT_FAIL;
        }
        let position = get(t, table::PRESENT_POSITION);
        let whole_turns = position - position.rem_euclid(4096);
        self.turns[s] += whole_turns;
        set(
            &mut self.tables[s],
            table::PRESENT_POSITION,
            position - whole_turns,
        );
        0
    }
}

/// The entries of a sync or bulk instruction whose ID no earlier entry named: a servo
/// named twice in one packet takes its first entry only.
fn first_per_id<T>(
    entries: impl IntoIterator<Item = T>,
    id: fn(&T) -> u8,
) -> impl Iterator<Item = T> {
    let mut done = Vec::new();
    entries.into_iter().filter(move |e| {
        let fresh = !done.contains(&id(e));
        if fresh {
            done.push(id(e));
        }
        fresh
    })
}

/// Bulk Read parameters: `(id, addr, len)` per servo, or `None` unless a whole number of
/// 5-byte entries.
fn parse_bulk_read(params: &[u8]) -> Option<Vec<(u8, u16, u16)>> {
    (!params.is_empty() && params.len().is_multiple_of(5)).then(|| {
        params
            .chunks_exact(5)
            .map(|c| {
                (
                    c[0],
                    u16::from_le_bytes([c[1], c[2]]),
                    u16::from_le_bytes([c[3], c[4]]),
                )
            })
            .collect()
    })
}

/// Bulk Write parameters: `(id, addr, data)` per servo, or `None` unless the entries
/// (id, address, length, that many bytes) fill the parameters exactly.
fn parse_bulk_write(params: &[u8]) -> Option<Vec<(u8, u16, &[u8])>> {
    let mut entries = Vec::new();
    let mut rest = params;
    while !rest.is_empty() {
        if rest.len() < 5 {
            return None;
        }
        let addr = u16::from_le_bytes([rest[1], rest[2]]);
        let len = usize::from(u16::from_le_bytes([rest[3], rest[4]]));
        let data = rest.get(5..5 + len)?;
        entries.push((rest[0], addr, data));
        rest = &rest[5 + len..];
    }
    (!entries.is_empty()).then_some(entries)
}
