//! Dynamixel Protocol 2.0 codec: packet encoding, streaming decoding and a small bus client.
//! One codec serves the controller (instructions out, status in) and a servo emulator (the reverse).
//!
//! Wire format (ROBOTIS e-Manual, "Protocol 2.0"):
//!
//! ```text
//! FF FF FD 00 | ID | LEN_L LEN_H | INST | [ERR] | PARAM... | CRC_L CRC_H
//! ```
//!
//! `LEN` counts the instruction byte, the error byte of a status packet, the parameters and
//! the two CRC bytes, all after byte stuffing. Stuffing inserts `FD` after every `FF FF FD`
//! inside the instruction..parameter range. The CRC-16 (polynomial 0x8005, initial value 0,
//! not reflected) covers every byte from the header up to the last parameter, as sent.
//!
//! - [`crc16`]: the checksum.
//! - [`encode_instruction`], [`encode_status`] and the `encode_*` helpers: append one packet
//!   to a `Vec<u8>`, reusing its capacity; [`parse_read`] and friends read instruction
//!   parameters on the servo side.
//! - [`Decoder`]: a bounded streaming decoder that skips garbage and resynchronizes after
//!   corrupt packets, allocating nothing after construction.
//! - [`Bus`]: blocking request/reply transactions over any [`Port`] (`Read + Write`), with
//!   a reply timeout and error counters ([`BusCounters`]).
//!
//! ```
//! use softcbf_protocol::{Decoder, Instruction, encode_ping};
//!
//! // The e-Manual's PING example for ID 1 ...
//! let mut out = Vec::new();
//! encode_ping(1, &mut out).unwrap();
//! assert_eq!(out, [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E]);
//!
//! // ... and its reply, behind a stray byte: model 1030 (0x0406), firmware 38.
//! let reply = [0x00, 0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x55, 0x00, 0x06, 0x04, 0x26, 0x65, 0x5D];
//! let mut decoder = Decoder::default();
//! assert_eq!(decoder.push(&reply), reply.len());
//! let status = decoder.next_packet().unwrap().unwrap();
//! assert_eq!((status.id, status.instruction), (1, Instruction::Status));
//! assert_eq!(status.params, [0x06, 0x04, 0x26]);
//! assert!(status.error.unwrap().is_ok());
//! assert!(decoder.next_packet().is_none());
//! ```

mod bus;
mod crc;
mod decode;
mod encode;

pub use bus::{Bus, BusCounters, BusError, PingInfo, Port};
pub use crc::{crc16, crc16_update};
pub use decode::{DEFAULT_MAX_LENGTH, DecodeError, Decoder, PacketBuf, PacketRef};
pub use encode::{
    EncodeError, SyncWriteItems, encode_action, encode_factory_reset, encode_instruction,
    encode_ping, encode_read, encode_reboot, encode_reg_write, encode_status, encode_sync_read,
    encode_sync_write, encode_write, parse_read, parse_sync_read, parse_sync_write, parse_write,
};

use std::fmt;

/// The four bytes that open every packet: `FF FF FD` and the reserved `00`.
pub const HEADER: [u8; 4] = [0xFF, 0xFF, 0xFD, 0x00];
/// Packet ID addressing every servo on the bus. Servos do not answer READ/WRITE sent to it.
pub const BROADCAST_ID: u8 = 0xFE;
/// Largest ID a single servo may have (0..=252).
pub const MAX_SERVO_ID: u8 = 0xFC;
/// Bytes before the instruction field: header (4), ID (1), length (2).
pub const PREFIX_LEN: usize = 7;
/// Bytes of the CRC field.
pub const CRC_LEN: usize = 2;

/// Instruction codes of Protocol 2.0 (e-Manual "Protocol 2.0", section Instruction).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Instruction {
    /// 0x01: check that a device exists; it answers model number and firmware version.
    Ping = 0x01,
    /// 0x02: read `len` bytes of the control table from `addr`.
    Read = 0x02,
    /// 0x03: write bytes to the control table at `addr`.
    Write = 0x03,
    /// 0x04: register a write, executed later by [`Instruction::Action`].
    RegWrite = 0x04,
    /// 0x05: execute the registered write.
    Action = 0x05,
    /// 0x06: reset the control table to factory defaults (parameter: what to keep).
    FactoryReset = 0x06,
    /// 0x08: reboot the device.
    Reboot = 0x08,
    /// 0x10: reset certain information (e.g. the multi-turn count).
    Clear = 0x10,
    /// 0x55: the status (return) packet sent by a device.
    Status = 0x55,
    /// 0x82: read the same address and length from several devices.
    SyncRead = 0x82,
    /// 0x83: write the same address and length to several devices.
    SyncWrite = 0x83,
    /// 0x92: read different addresses and lengths from several devices.
    BulkRead = 0x92,
    /// 0x93: write different addresses and lengths to several devices.
    BulkWrite = 0x93,
}

impl Instruction {
    /// The byte sent on the wire.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The instruction with this wire code, if Protocol 2.0 defines one.
    pub const fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0x01 => Self::Ping,
            0x02 => Self::Read,
            0x03 => Self::Write,
            0x04 => Self::RegWrite,
            0x05 => Self::Action,
            0x06 => Self::FactoryReset,
            0x08 => Self::Reboot,
            0x10 => Self::Clear,
            0x55 => Self::Status,
            0x82 => Self::SyncRead,
            0x83 => Self::SyncWrite,
            0x92 => Self::BulkRead,
            0x93 => Self::BulkWrite,
            _ => return None,
        })
    }
}

/// The error byte of a status packet: bit 7 is the alert flag, bits 0..6 the error number.
///
/// `alert` means the device has a hardware error (read its Hardware Error Status register);
/// the packet's data is still valid. A non-zero `code` means the instruction failed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct StatusError {
    /// Bit 7: the device reports a hardware problem.
    pub alert: bool,
    /// Bits 0..6: 0 = no error, 1..=7 = documented errors, others undefined.
    pub code: u8,
}

impl StatusError {
    /// 0x01: failed to process the instruction packet.
    pub const RESULT_FAIL: u8 = 0x01;
    /// 0x02: undefined instruction, or Action without Reg Write.
    pub const INSTRUCTION_ERROR: u8 = 0x02;
    /// 0x03: the CRC of the received packet does not match.
    pub const CRC_ERROR: u8 = 0x03;
    /// 0x04: the value is outside the address's min/max range.
    pub const DATA_RANGE_ERROR: u8 = 0x04;
    /// 0x05: the data is shorter than the address's item.
    pub const DATA_LENGTH_ERROR: u8 = 0x05;
    /// 0x06: the value is outside the address's limit.
    pub const DATA_LIMIT_ERROR: u8 = 0x06;
    /// 0x07: read-only / write-only / undefined address, or ROM write with torque on.
    pub const ACCESS_ERROR: u8 = 0x07;

    /// Splits a raw error byte.
    pub const fn from_byte(byte: u8) -> Self {
        Self {
            alert: byte & 0x80 != 0,
            code: byte & 0x7F,
        }
    }

    /// The raw error byte.
    pub const fn to_byte(self) -> u8 {
        (if self.alert { 0x80 } else { 0 }) | (self.code & 0x7F)
    }

    /// True when the instruction succeeded (error number 0); the alert bit may still be set.
    pub const fn is_ok(self) -> bool {
        self.code == 0
    }

    /// The e-Manual's name and description of the error number.
    pub const fn meaning(self) -> &'static str {
        match self.code {
            0 => "no error",
            Self::RESULT_FAIL => "result fail: failed to process the instruction packet",
            Self::INSTRUCTION_ERROR => {
                "instruction error: undefined instruction, or Action without Reg Write"
            }
            Self::CRC_ERROR => "CRC error: the CRC of the sent packet does not match",
            Self::DATA_RANGE_ERROR => {
                "data range error: the value is outside the address's minimum/maximum range"
            }
            Self::DATA_LENGTH_ERROR => {
                "data length error: the data is shorter than the data length of the address"
            }
            Self::DATA_LIMIT_ERROR => {
                "data limit error: the value is outside the limit value of the address"
            }
            Self::ACCESS_ERROR => {
                "access error: read-only, write-only or undefined address, or ROM write while torque is enabled"
            }
            _ => "undefined error number",
        }
    }
}

impl fmt::Display for StatusError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "error {:#04x} ({})", self.code, self.meaning())?;
        if self.alert {
            write!(f, ", alert: hardware error reported")?;
        }
        Ok(())
    }
}
