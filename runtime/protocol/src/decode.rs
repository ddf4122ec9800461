//! Streaming packet decoder: finds headers in a byte stream, checks length and CRC, removes
//! byte stuffing in place and resynchronizes after garbage; bounded, allocation-free.

use super::encode::stuff_state;
use super::{
    BROADCAST_ID, CRC_LEN, HEADER, Instruction, MAX_SERVO_ID, PREFIX_LEN, StatusError, crc16,
};
use std::io;
use std::ops::Range;
use thiserror::Error;

/// Default largest accepted length field (bytes after the length field).
pub const DEFAULT_MAX_LENGTH: u16 = 1024;

/// A rejected packet. The decoder has already skipped it and goes on with the next bytes.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum DecodeError {
    /// ID 0xFD or 0xFF after a header, or a status packet from the broadcast ID.
    #[error("invalid packet ID {id:#04x}")]
    InvalidId {
        /// The ID field.
        id: u8,
    },
    /// Length field below the minimum (3 for an instruction, 4 for a status packet) or
    /// above the decoder's maximum.
    #[error("packet from ID {id}: bad length field {length}")]
    BadLength {
        /// The ID field.
        id: u8,
        /// The length field.
        length: u16,
    },
    /// The CRC does not match; the packet's fields cannot be trusted, not even the ID.
    #[error(
        "packet from ID {id}: CRC mismatch (computed {computed:#06x}, received {received:#06x})"
    )]
    BadCrc {
        /// The ID field as received.
        id: u8,
        /// CRC computed over the received bytes.
        computed: u16,
        /// CRC field as received.
        received: u16,
    },
    /// The CRC matched but an `FF FF FD` inside the packet is not followed by the stuffing
    /// `FD`: the sender did not stuff.
    #[error("packet from ID {id}: byte stuffing missing after FF FF FD")]
    BadStuffing {
        /// The ID field.
        id: u8,
    },
    /// The CRC matched but the instruction code is not defined by Protocol 2.0.
    #[error("packet from ID {id}: unknown instruction {code:#04x}")]
    UnknownInstruction {
        /// The ID field.
        id: u8,
        /// The instruction byte.
        code: u8,
    },
}

/// A decoded packet borrowing the decoder's buffer (valid until the next call on it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PacketRef<'a> {
    /// Packet ID: the addressee of an instruction, the sender of a status packet.
    pub id: u8,
    /// Instruction; [`Instruction::Status`] for a status packet.
    pub instruction: Instruction,
    /// The error byte of a status packet; `None` for an instruction packet.
    pub error: Option<StatusError>,
    /// Parameters with byte stuffing removed.
    pub params: &'a [u8],
}

impl PacketRef<'_> {
    /// Copies into an owned packet.
    pub fn to_buf(&self) -> PacketBuf {
        let mut buf = PacketBuf::default();
        buf.copy_from(self);
        buf
    }
}

/// An owned packet; [`PacketBuf::copy_from`] reuses its parameter capacity.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PacketBuf {
    /// Packet ID.
    pub id: u8,
    /// Instruction; [`Instruction::Status`] for a status packet.
    pub instruction: Instruction,
    /// The error byte of a status packet; `None` for an instruction packet.
    pub error: Option<StatusError>,
    /// Parameters with byte stuffing removed.
    pub params: Vec<u8>,
}

impl Default for PacketBuf {
    fn default() -> Self {
        Self {
            id: 0,
            instruction: Instruction::Ping,
            error: None,
            params: Vec::new(),
        }
    }
}

impl PacketBuf {
    /// Overwrites this packet with `packet`, reusing the parameter buffer.
    pub fn copy_from(&mut self, packet: &PacketRef<'_>) {
        self.id = packet.id;
        self.instruction = packet.instruction;
        self.error = packet.error;
        self.params.clear();
        self.params.extend_from_slice(packet.params);
    }

    /// Borrows as a [`PacketRef`].
    pub fn as_ref(&self) -> PacketRef<'_> {
        PacketRef {
            id: self.id,
            instruction: self.instruction,
            error: self.error,
            params: &self.params,
        }
    }
}

/// A decoded packet whose parameters are a range of the decoder's buffer.
#[derive(Clone, Debug)]
pub(super) struct Frame {
    pub id: u8,
    pub instruction: Instruction,
    pub error: Option<StatusError>,
    pub params: Range<usize>,
}

/// Streaming decoder for both packet kinds.
///
/// Feed bytes with [`Decoder::push`] (or [`Decoder::read_from`]) and drain packets with
/// [`Decoder::next_packet`] until it returns `None`. It never panics on any input: bytes
/// before a header are skipped (counted in [`Decoder::discarded`]); a packet with a bad ID,
/// length or CRC is reported once and the search resumes one byte after its header, so a
/// good packet hidden behind a corrupt one is still found. The buffer holds two maximal
/// packets and is allocated once, in [`Decoder::new`].
#[derive(Clone, Debug)]
pub struct Decoder {
    buf: Box<[u8]>,
    start: usize,
    end: usize,
    max_length: u16,
    discarded: u64,
}

impl Default for Decoder {
    fn default() -> Self {
        Self::new(DEFAULT_MAX_LENGTH)
    }
}

impl Decoder {
    /// A decoder accepting length fields up to `max_length` (at least 4 is used).
    pub fn new(max_length: u16) -> Self {
        let max_length = max_length.max(4);
        let capacity = 2 * (PREFIX_LEN + usize::from(max_length));
        Self {
            buf: vec![0; capacity].into_boxed_slice(),
            start: 0,
            end: 0,
            max_length,
            discarded: 0,
        }
    }

    /// Largest accepted length field.
    pub fn max_length(&self) -> u16 {
        self.max_length
    }

    /// Bytes held and not yet decoded.
    pub fn pending(&self) -> usize {
        self.end - self.start
    }

    /// The bytes held and not yet decoded. Once [`Decoder::next_packet`] has returned
    /// `None` they are the start of an incomplete packet (or of its header), so a servo
    /// can tell how long that packet announces itself to be and give up on it in time.
    pub fn pending_bytes(&self) -> &[u8] {
        &self.buf[self.start..self.end]
    }

    /// Room for more bytes (after compaction).
    pub fn free(&self) -> usize {
        self.buf.len() - self.pending()
    }

    /// Total bytes skipped as garbage or as the first byte of a rejected packet.
    pub fn discarded(&self) -> u64 {
        self.discarded
    }

    /// Drops every pending byte (not counted as discarded).
    pub fn clear(&mut self) {
        self.start = 0;
        self.end = 0;
    }

    fn compact(&mut self) {
        if self.start > 0 {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
        }
    }

    /// Appends as many of `bytes` as fit and returns how many; the rest must be pushed
    /// again after draining packets with [`Decoder::next_packet`]. After draining, at least
    /// half the buffer is free.
    #[must_use = "bytes beyond the returned count were not accepted"]
    pub fn push(&mut self, bytes: &[u8]) -> usize {
        self.compact();
        let n = bytes.len().min(self.buf.len() - self.end);
        self.buf[self.end..self.end + n].copy_from_slice(&bytes[..n]);
        self.end += n;
        n
    }

    /// Reads once from `reader` into the free space; returns the `read` result.
    pub fn read_from<R: io::Read + ?Sized>(&mut self, reader: &mut R) -> io::Result<usize> {
        self.compact();
        let n = reader.read(&mut self.buf[self.end..])?;
        self.end += n.min(self.buf.len() - self.end);
        Ok(n)
    }

    /// The next packet or rejection in the stream, or `None` when more bytes are needed.
    pub fn next_packet(&mut self) -> Option<Result<PacketRef<'_>, DecodeError>> {
        match self.next_frame()? {
            Ok(frame) => Some(Ok(PacketRef {
                id: frame.id,
                instruction: frame.instruction,
                error: frame.error,
                params: &self.buf[frame.params],
            })),
            Err(e) => Some(Err(e)),
        }
    }

    /// Parameters of a frame returned by [`Decoder::next_frame`], until the next push.
    pub(super) fn params(&self, range: Range<usize>) -> &[u8] {
        &self.buf[range]
    }

    /// Skips the first byte of a rejected header and returns `e`.
    fn reject(&mut self, e: DecodeError) -> Option<Result<Frame, DecodeError>> {
        self.start += 1;
        self.discarded += 1;
        Some(Err(e))
    }

    /// [`Decoder::next_packet`] with the parameters as a buffer range (no borrow kept).
    pub(super) fn next_frame(&mut self) -> Option<Result<Frame, DecodeError>> {
        let pending = &self.buf[self.start..self.end];
        match pending.windows(HEADER.len()).position(|w| w == HEADER) {
            Some(p) => {
                self.start += p;
                self.discarded += p as u64;
            }
            None => {
                // Keep a tail that may be the beginning of a header split across pushes.
                let keep = (1..HEADER.len())
                    .rev()
                    .find(|&k| pending.len() >= k && pending[pending.len() - k..] == HEADER[..k])
                    .unwrap_or(0);
                let drop = pending.len() - keep;
                self.start += drop;
                self.discarded += drop as u64;
                return None;
            }
        }
        let pending = &self.buf[self.start..self.end];
        if pending.len() < PREFIX_LEN {
            return None;
        }
        let id = pending[4];
        let length = u16::from_le_bytes([pending[5], pending[6]]);
        if id > MAX_SERVO_ID && id != BROADCAST_ID {
            return self.reject(DecodeError::InvalidId { id });
        }
        if length < 3 || length > self.max_length {
            return self.reject(DecodeError::BadLength { id, length });
        }
        let total = PREFIX_LEN + usize::from(length);
        if pending.len() < total {
            return None;
        }
        let crc_at = total - CRC_LEN;
        let computed = crc16(&pending[..crc_at]);
        let received = u16::from_le_bytes([pending[crc_at], pending[crc_at + 1]]);
        if computed != received {
            return self.reject(DecodeError::BadCrc {
                id,
                computed,
                received,
            });
        }
        // A whole packet with a good CRC: consume it, whatever its contents.
        let body_start = self.start + PREFIX_LEN;
        let body_end = self.start + crc_at;
        self.start += total;
        let Some(body_len) = unstuff_in_place(&mut self.buf[body_start..body_end]) else {
            return Some(Err(DecodeError::BadStuffing { id }));
        };
        let body = body_start..body_start + body_len;
        let code = self.buf[body.start];
        let Some(instruction) = Instruction::from_code(code) else {
            return Some(Err(DecodeError::UnknownInstruction { id, code }));
        };
        if instruction != Instruction::Status {
            return Some(Ok(Frame {
                id,
                instruction,
                error: None,
                params: body.start + 1..body.end,
            }));
        }
        if id == BROADCAST_ID {
            return Some(Err(DecodeError::InvalidId { id }));
        }
        if body.len() < 2 {
            return Some(Err(DecodeError::BadLength { id, length }));
        }
        Some(Ok(Frame {
            id,
            instruction,
            error: Some(StatusError::from_byte(self.buf[body.start + 1])),
            params: body.start + 2..body.end,
        }))
    }
}

/// Removes byte stuffing (`FF FF FD FD` → `FF FF FD`) in place; returns the new length, or
/// `None` if an `FF FF FD` is not followed by `FD`.
fn unstuff_in_place(body: &mut [u8]) -> Option<usize> {
    let mut state = 0;
    let mut write = 0;
    for read in 0..body.len() {
        let byte = body[read];
        if state == 3 {
            if byte != 0xFD {
                return None;
            }
            state = 0;
            continue;
        }
        body[write] = byte;
        write += 1;
        state = stuff_state(state, byte);
    }
    (state != 3).then_some(write)
}
