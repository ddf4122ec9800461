//! Packet encoding (header, byte stuffing, length, CRC) appended to a caller's `Vec<u8>`,
//! plus the parameter layouts of the common instructions, built here and parsed back.

use super::{BROADCAST_ID, CRC_LEN, HEADER, Instruction, MAX_SERVO_ID, PREFIX_LEN, crc16};
use thiserror::Error;

/// Why a packet could not be encoded. On error nothing is appended to `out`.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum EncodeError {
    /// IDs 0xFD and 0xFF are never valid; 0xFE (broadcast) is valid only for instructions,
    /// and never inside a sync read/write list.
    #[error("packet ID {id:#04x} is not valid here")]
    InvalidId {
        /// The rejected ID.
        id: u8,
    },
    /// The length field (instruction, error, stuffed parameters, CRC) exceeds 65535.
    #[error("packet too long: its length field would be {length} (at most 65535)")]
    TooLong {
        /// The length the field would need.
        length: usize,
    },
    /// A sync write item's data is not the declared length.
    #[error("sync write data for ID {id} has {got} bytes, expected {expected}")]
    DataLength {
        /// The item's ID.
        id: u8,
        /// The declared data length.
        expected: usize,
        /// The item's data length.
        got: usize,
    },
}

/// Byte-stuffing state after `byte`: 0 = nothing, 1 = `FF`, 2 = `FF FF`, 3 = `FF FF FD` seen
/// (a stuffing `FD` follows on the wire). The decoder uses the same machine to remove it.
pub(super) const fn stuff_state(state: u8, byte: u8) -> u8 {
    match (state, byte) {
        (0 | 1, 0xFF) => state + 1,
        (2, 0xFF) => 2,
        (2, 0xFD) => 3,
        _ => 0,
    }
}

/// One packet being appended to `out`: header written at `begin`, body bytes stuffed as
/// they are pushed, length and CRC filled in by `finish`.
struct Frame<'o> {
    out: &'o mut Vec<u8>,
    start: usize,
    state: u8,
}

impl<'o> Frame<'o> {
    fn begin(out: &'o mut Vec<u8>, id: u8, instruction: Instruction, body_hint: usize) -> Self {
        out.reserve(PREFIX_LEN + 1 + body_hint + CRC_LEN);
        let start = out.len();
        out.extend_from_slice(&HEADER);
        out.extend_from_slice(&[id, 0, 0]);
        let mut frame = Self {
            out,
            start,
            state: 0,
        };
        frame.push(instruction.code());
        frame
    }

    fn push(&mut self, byte: u8) {
        self.out.push(byte);
        self.state = stuff_state(self.state, byte);
        if self.state == 3 {
            self.out.push(0xFD);
            self.state = 0;
        }
    }

    fn extend(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.push(b);
        }
    }

    fn u16(&mut self, value: u16) {
        self.extend(&value.to_le_bytes());
    }

    fn abort(self) {
        self.out.truncate(self.start);
    }

    fn finish(self) -> Result<(), EncodeError> {
        let length = self.out.len() - self.start - PREFIX_LEN + CRC_LEN;
        let Ok(field) = u16::try_from(length) else {
            self.abort();
            return Err(EncodeError::TooLong { length });
        };
        let [lo, hi] = field.to_le_bytes();
        self.out[self.start + 5] = lo;
        self.out[self.start + 6] = hi;
        let crc = crc16(&self.out[self.start..]);
        self.out.extend_from_slice(&crc.to_le_bytes());
        Ok(())
    }
}

fn check_instruction_id(id: u8) -> Result<(), EncodeError> {
    if id <= MAX_SERVO_ID || id == BROADCAST_ID {
        Ok(())
    } else {
        Err(EncodeError::InvalidId { id })
    }
}

fn check_servo_id(id: u8) -> Result<(), EncodeError> {
    if id <= MAX_SERVO_ID {
        Ok(())
    } else {
        Err(EncodeError::InvalidId { id })
    }
}

/// Appends an instruction packet for `id` (0..=252 or [`BROADCAST_ID`]) with `params`
/// (unstuffed; stuffing is applied here). Reuses `out`'s capacity.
pub fn encode_instruction(
    id: u8,
    instruction: Instruction,
    params: &[u8],
    out: &mut Vec<u8>,
) -> Result<(), EncodeError> {
    check_instruction_id(id)?;
    let mut frame = Frame::begin(out, id, instruction, params.len());
    frame.extend(params);
    frame.finish()
}

/// Appends a status packet from servo `id` (0..=252) with the raw `error` byte (see
/// [`super::StatusError::to_byte`]) and `params` (unstuffed).
pub fn encode_status(
    id: u8,
    error: u8,
    params: &[u8],
    out: &mut Vec<u8>,
) -> Result<(), EncodeError> {
    check_servo_id(id)?;
    let mut frame = Frame::begin(out, id, Instruction::Status, 1 + params.len());
    frame.push(error);
    frame.extend(params);
    frame.finish()
}

/// PING: the servo answers model number (u16) and firmware version (u8).
pub fn encode_ping(id: u8, out: &mut Vec<u8>) -> Result<(), EncodeError> {
    encode_instruction(id, Instruction::Ping, &[], out)
}

/// READ `len` bytes from control-table address `addr`.
pub fn encode_read(id: u8, addr: u16, len: u16, out: &mut Vec<u8>) -> Result<(), EncodeError> {
    check_instruction_id(id)?;
    let mut frame = Frame::begin(out, id, Instruction::Read, 4);
    frame.u16(addr);
    frame.u16(len);
    frame.finish()
}

fn encode_addr_data(
    id: u8,
    instruction: Instruction,
    addr: u16,
    data: &[u8],
    out: &mut Vec<u8>,
) -> Result<(), EncodeError> {
    check_instruction_id(id)?;
    let mut frame = Frame::begin(out, id, instruction, 2 + data.len());
    frame.u16(addr);
    frame.extend(data);
    frame.finish()
}

/// WRITE `data` at control-table address `addr` (multi-byte values little-endian).
pub fn encode_write(id: u8, addr: u16, data: &[u8], out: &mut Vec<u8>) -> Result<(), EncodeError> {
    encode_addr_data(id, Instruction::Write, addr, data, out)
}

/// REG WRITE: like WRITE, executed on the next ACTION.
pub fn encode_reg_write(
    id: u8,
    addr: u16,
    data: &[u8],
    out: &mut Vec<u8>,
) -> Result<(), EncodeError> {
    encode_addr_data(id, Instruction::RegWrite, addr, data, out)
}

/// ACTION: execute registered writes.
pub fn encode_action(id: u8, out: &mut Vec<u8>) -> Result<(), EncodeError> {
    encode_instruction(id, Instruction::Action, &[], out)
}

/// REBOOT the servo.
pub fn encode_reboot(id: u8, out: &mut Vec<u8>) -> Result<(), EncodeError> {
    encode_instruction(id, Instruction::Reboot, &[], out)
}

/// FACTORY RESET; `option`: 0xFF resets all, 0x01 all but the ID, 0x02 all but ID and baud.
pub fn encode_factory_reset(id: u8, option: u8, out: &mut Vec<u8>) -> Result<(), EncodeError> {
    encode_instruction(id, Instruction::FactoryReset, &[option], out)
}

/// SYNC READ `len` bytes at `addr` from each of `ids` (sent to [`BROADCAST_ID`]); the servos
/// answer one status packet each, in the order of `ids`.
pub fn encode_sync_read(
    addr: u16,
    len: u16,
    ids: &[u8],
    out: &mut Vec<u8>,
) -> Result<(), EncodeError> {
    for &id in ids {
        check_servo_id(id)?;
    }
    let mut frame = Frame::begin(out, BROADCAST_ID, Instruction::SyncRead, 4 + ids.len());
    frame.u16(addr);
    frame.u16(len);
    frame.extend(ids);
    frame.finish()
}

/// SYNC WRITE `len` bytes at `addr` to several servos: `items` yields `(id, data)` with
/// `data.len() == len`. Sent to [`BROADCAST_ID`]; no servo answers.
pub fn encode_sync_write<'a>(
    addr: u16,
    len: u16,
    items: impl IntoIterator<Item = (u8, &'a [u8])>,
    out: &mut Vec<u8>,
) -> Result<(), EncodeError> {
    let mut frame = Frame::begin(out, BROADCAST_ID, Instruction::SyncWrite, 4);
    frame.u16(addr);
    frame.u16(len);
    for (id, data) in items {
        if let Err(e) = check_servo_id(id) {
            frame.abort();
            return Err(e);
        }
        if data.len() != usize::from(len) {
            frame.abort();
            return Err(EncodeError::DataLength {
                id,
                expected: usize::from(len),
                got: data.len(),
            });
        }
        frame.push(id);
        frame.extend(data);
    }
    frame.finish()
}

fn le16(bytes: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([bytes[at], bytes[at + 1]])
}

/// READ parameters: `(addr, len)`, or `None` unless exactly 4 bytes.
pub fn parse_read(params: &[u8]) -> Option<(u16, u16)> {
    (params.len() == 4).then(|| (le16(params, 0), le16(params, 2)))
}

/// WRITE / REG WRITE parameters: `(addr, data)`, or `None` if shorter than 2 bytes.
pub fn parse_write(params: &[u8]) -> Option<(u16, &[u8])> {
    (params.len() >= 2).then(|| (le16(params, 0), &params[2..]))
}

/// SYNC READ parameters: `(addr, len, ids)`, or `None` if shorter than 4 bytes.
pub fn parse_sync_read(params: &[u8]) -> Option<(u16, u16, &[u8])> {
    (params.len() >= 4).then(|| (le16(params, 0), le16(params, 2), &params[4..]))
}

/// SYNC WRITE parameters: `(addr, len, items)`, or `None` if shorter than 4 bytes or the
/// rest is not a whole number of `id + len bytes` items.
pub fn parse_sync_write(params: &[u8]) -> Option<(u16, u16, SyncWriteItems<'_>)> {
    if params.len() < 4 {
        return None;
    }
    let (addr, len) = (le16(params, 0), le16(params, 2));
    let item = 1 + usize::from(len);
    let rest = &params[4..];
    rest.len().is_multiple_of(item).then(|| {
        let items = SyncWriteItems {
            chunks: rest.chunks_exact(item),
        };
        (addr, len, items)
    })
}

/// The `(id, data)` items of a SYNC WRITE, from [`parse_sync_write`].
#[derive(Clone, Debug)]
pub struct SyncWriteItems<'a> {
    chunks: std::slice::ChunksExact<'a, u8>,
}

impl<'a> Iterator for SyncWriteItems<'a> {
    type Item = (u8, &'a [u8]);

    fn next(&mut self) -> Option<Self::Item> {
        self.chunks.next().map(|c| (c[0], &c[1..]))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.chunks.size_hint()
    }
}

impl ExactSizeIterator for SyncWriteItems<'_> {}
