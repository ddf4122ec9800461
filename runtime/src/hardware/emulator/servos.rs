//! The emulated servos: one X-series control table per servo and Protocol 2.0 instruction
//! semantics, with the robot's motion from the simulated plant. No I/O and no clock here.
//!
//! Tensions come from the goal currents through the actuator gain (a negative current
//! unwinds the pulley: the cable goes slack, zero tension); a servo with torque off, or not
//! in current control mode, pulls with nothing. Register values are sampled from the plant
//! at the time an instruction is executed.

use crate::hardware::control_table::{self as table, ServoState};
use crate::hardware::mapping::TendonMap;
use crate::integrator::IntegratorError;
use crate::plant::Plant;
use crate::protocol::{
    BROADCAST_ID, Instruction, PacketRef, StatusError, parse_read, parse_sync_read,
    parse_sync_write, parse_write,
};

/// Firmware version the emulated servos report.
pub const FIRMWARE_VERSION: u8 = 46;

/// One status packet to send: who sends it and its content (unencoded).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reply {
    /// Sender ID.
    pub id: u8,
    /// Error byte.
    pub error: u8,
    /// Parameters.
    pub params: Vec<u8>,
}

/// The servos of one robot and the plant they move.
pub struct Servos<'m> {
    map: TendonMap,
    plant: Plant<'m>,
    ids: Vec<u8>,
    tables: Vec<[u8; table::TABLE_SIZE]>,
    angles: Vec<f64>,
    rates: Vec<f64>,
    tensions: Vec<f64>,
}

impl<'m> Servos<'m> {
    /// Servos with factory-like tables (Operating Mode 3, position control; torque off)
    /// moving `plant`; `baud_register` and `return_delay_register` fill those registers.
    pub fn new(
        map: TendonMap,
        plant: Plant<'m>,
        baud_register: u8,
        return_delay_register: u8,
    ) -> Servos<'m> {
        let ids = map.hardware().servo_ids();
        let n = ids.len();
        let model_number = map.hardware().model_number;
        let tables = ids
            .iter()
            .map(|&id| {
                let mut t = [0u8; table::TABLE_SIZE];
                put(&mut t, table::MODEL_NUMBER, &model_number.to_le_bytes());
                t[usize::from(table::FIRMWARE_VERSION)] = FIRMWARE_VERSION;
                t[usize::from(table::ID)] = id;
                t[usize::from(table::BAUD_RATE)] = baud_register;
                t[usize::from(table::RETURN_DELAY_TIME)] = return_delay_register;
                t[usize::from(table::OPERATING_MODE)] = 3;
                put(
                    &mut t,
                    table::CURRENT_LIMIT,
                    &table::XM430_CURRENT_LIMIT.to_le_bytes(),
                );
                t[usize::from(table::STATUS_RETURN_LEVEL)] = 2;
                t
            })
            .collect();
        Servos {
            map,
            plant,
            ids,
            tables,
            angles: vec![0.0; n],
            rates: vec![0.0; n],
            tensions: vec![0.0; n],
        }
    }

    /// The servo IDs in bus order.
    pub fn ids(&self) -> &[u8] {
        &self.ids
    }

    /// The plant.
    pub fn plant(&self) -> &Plant<'m> {
        &self.plant
    }

    /// Whether servo `index` has torque enabled.
    pub fn torque_enabled(&self, index: usize) -> bool {
        self.tables[index][usize::from(table::TORQUE_ENABLE)] != 0
    }

    /// Goal Current register of servo `index`.
    pub fn goal_current(&self, index: usize) -> i16 {
        i16_at(&self.tables[index], table::GOAL_CURRENT)
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

    /// Advances the plant to time `t` \[s\] with the tensions held, and samples every
    /// servo's Present Position/Velocity/Current.
    pub fn advance_to(&mut self, t: f64) -> Result<(), IntegratorError> {
        let dt = t - self.plant.time();
        if dt > 0.0 {
            self.plant.advance(dt)?;
        }
        self.map.angles_from_q(self.plant.q(), &mut self.angles);
        self.map.rates_from_qd(self.plant.qd(), &mut self.rates);
        for s in 0..self.ids.len() {
            let pulling = self.pulls(s);
            let current = if pulling { self.goal_current(s) } else { 0 };
            let state = ServoState {
                current,
                velocity: self.map.velocity_from_rate(self.rates[s]),
                position: self.map.position_from_angle(self.angles[s]),
            };
            let start = usize::from(table::STATE_ADDRESS);
            state.to_bytes(&mut self.tables[s][start..start + usize::from(table::STATE_LENGTH)]);
        }
        Ok(())
    }

    fn pulls(&self, s: usize) -> bool {
        self.torque_enabled(s)
            && self.tables[s][usize::from(table::OPERATING_MODE)] == table::CURRENT_CONTROL_MODE
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
        let index = self.ids.iter().position(|&id| id == packet.id);
        match packet.instruction {
            Instruction::Ping => {
                for s in 0..self.ids.len() {
                    if broadcast || index == Some(s) {
                        let t = &self.tables[s];
                        let params = vec![t[0], t[1], t[usize::from(table::FIRMWARE_VERSION)]];
                        replies.push(Reply {
                            id: self.ids[s],
                            error: 0,
                            params,
                        });
                    }
                }
            }
            Instruction::Read => {
                if let Some(s) = index {
                    replies.push(self.read(s, parse_read(packet.params)));
                }
            }
            Instruction::Write => {
                let result = parse_write(packet.params);
                for s in 0..self.ids.len() {
                    if broadcast || index == Some(s) {
                        let error = match result {
                            Some((addr, data)) => self.write(s, addr, data),
                            None => StatusError::DATA_LENGTH_ERROR,
                        };
                        if !broadcast {
                            replies.push(Reply {
                                id: self.ids[s],
                                error,
                                params: Vec::new(),
                            });
                        }
                    }
                }
                self.update_forces();
            }
            Instruction::Reboot => {
                for s in 0..self.ids.len() {
                    if broadcast || index == Some(s) {
                        self.tables[s][usize::from(table::TORQUE_ENABLE)] = 0;
                        put(&mut self.tables[s], table::GOAL_CURRENT, &[0, 0]);
                        if !broadcast {
                            replies.push(Reply {
                                id: self.ids[s],
                                error: 0,
                                params: Vec::new(),
                            });
                        }
                    }
                }
                self.update_forces();
            }
            Instruction::SyncRead => {
                if let Some((addr, len, ids)) = parse_sync_read(packet.params) {
                    for id in ids {
                        if let Some(s) = self.ids.iter().position(|x| x == id) {
                            replies.push(self.read(s, Some((addr, len))));
                        }
                    }
                }
            }
            Instruction::SyncWrite => {
                if let Some((addr, _, items)) = parse_sync_write(packet.params) {
                    for (id, data) in items {
                        if let Some(s) = self.ids.iter().position(|&x| x == id) {
                            // No status packet: a refused write is silently not applied.
                            let _ = self.write(s, addr, data);
                        }
                    }
                    self.update_forces();
                }
            }
            Instruction::Status => {}
            _ => {
                if let Some(s) = index {
                    replies.push(Reply {
                        id: self.ids[s],
                        error: StatusError::INSTRUCTION_ERROR,
                        params: Vec::new(),
                    });
                }
            }
        }
        Ok(())
    }

    fn read(&self, s: usize, request: Option<(u16, u16)>) -> Reply {
        let id = self.ids[s];
        let Some((addr, len)) = request else {
            return Reply {
                id,
                error: StatusError::DATA_LENGTH_ERROR,
                params: Vec::new(),
            };
        };
        let (start, end) = (usize::from(addr), usize::from(addr) + usize::from(len));
        if end > table::TABLE_SIZE {
            return Reply {
                id,
                error: StatusError::ACCESS_ERROR,
                params: Vec::new(),
            };
        }
        Reply {
            id,
            error: 0,
            params: self.tables[s][start..end].to_vec(),
        }
    }

    /// Writes `data` at `addr` of servo `s` if every byte is writable; the error number.
    fn write(&mut self, s: usize, addr: u16, data: &[u8]) -> u8 {
        let (start, end) = (usize::from(addr), usize::from(addr) + data.len());
        let torque_on = self.torque_enabled(s);
        let writable = |a: usize| -> bool {
            match a {
                a if a == usize::from(table::OPERATING_MODE) => !torque_on,
                a if a == usize::from(table::RETURN_DELAY_TIME) => !torque_on,
                a if a == usize::from(table::TORQUE_ENABLE) => true,
                65 => true, // LED
                a if (usize::from(table::GOAL_CURRENT)..usize::from(table::GOAL_CURRENT) + 2)
                    .contains(&a) =>
                {
                    true
                }
                _ => false,
            }
        };
        if data.is_empty() || end > table::TABLE_SIZE || !(start..end).all(writable) {
            return StatusError::ACCESS_ERROR;
        }
        let torque = usize::from(table::TORQUE_ENABLE);
        if (start..end).contains(&torque) && data[torque - start] > 1 {
            return StatusError::DATA_RANGE_ERROR;
        }
        let goal = usize::from(table::GOAL_CURRENT);
        if start <= goal && goal + 2 <= end {
            let value = i16::from_le_bytes([data[goal - start], data[goal + 1 - start]]);
            let limit = i16_at(&self.tables[s], table::CURRENT_LIMIT);
            if value.unsigned_abs() > limit.unsigned_abs() {
                return StatusError::DATA_LIMIT_ERROR;
            }
        }
        self.tables[s][start..end].copy_from_slice(data);
        0
    }
}

fn put(table: &mut [u8], addr: u16, bytes: &[u8]) {
    let start = usize::from(addr);
    table[start..start + bytes.len()].copy_from_slice(bytes);
}

fn i16_at(table: &[u8], addr: u16) -> i16 {
    let a = usize::from(addr);
    i16::from_le_bytes([table[a], table[a + 1]])
}
