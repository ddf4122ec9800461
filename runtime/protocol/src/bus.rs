//! Controller side of the servo bus: blocking request/reply transactions over any byte port,
//! with a reply timeout, garbage skipping and error counters; retries are the caller's policy.

use super::decode::Frame;
use super::{
    BROADCAST_ID, DEFAULT_MAX_LENGTH, DecodeError, Decoder, EncodeError, Instruction, StatusError,
    encode_instruction, encode_ping, encode_read, encode_reboot, encode_sync_read,
    encode_sync_write, encode_write,
};
use std::io::{self, ErrorKind, Read, Write};
use std::ops::Range;
use std::time::{Duration, Instant};
use thiserror::Error;

/// A byte port to the servo bus: anything `Read + Write` (a boxed `serialport::SerialPort`,
/// a TCP stream, a test pipe).
///
/// Reads may block, but should return within a short time (e.g. a serial port opened with
/// a 1 ms read timeout): the bus checks its own deadline between reads. Reads returning
/// `Ok(0)`, `TimedOut`, `WouldBlock` or `Interrupted` mean "nothing yet".
pub trait Port: Read + Write {}

impl<T: Read + Write + ?Sized> Port for T {}

/// Event counts since the bus was made or [`Bus::reset_counters`] was called.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusCounters {
    /// Instruction packets sent.
    pub transactions: u64,
    /// Good status packets accepted.
    pub replies: u64,
    /// Replies not complete within the timeout.
    pub timeouts: u64,
    /// Packets rejected for a CRC mismatch.
    pub crc_errors: u64,
    /// Other rejected packets (bad ID or length field, missing stuffing, unknown instruction).
    pub decode_errors: u64,
    /// Status packets from another ID than the one awaited.
    pub wrong_id: u64,
    /// Status packets with a non-zero error number.
    pub status_errors: u64,
    /// Status packets with the alert bit (hardware error) set.
    pub alerts: u64,
    /// Instruction packets received and ignored (e.g. the echo of a half-duplex adapter).
    pub stray_packets: u64,
    /// Bytes skipped as garbage.
    pub garbage_bytes: u64,
    /// Retries, as reported by the caller through [`Bus::note_retry`].
    pub retries: u64,
}

/// Why a bus transaction failed. The caller decides whether to retry.
#[derive(Debug, Error)]
pub enum BusError {
    /// The port failed.
    #[error("servo bus I/O error: {0}")]
    Io(#[from] io::Error),
    /// The request could not be encoded (invalid ID, too long, inconsistent sync data).
    #[error("cannot encode the request: {0}")]
    Encode(#[from] EncodeError),
    /// A request that needs a reply was addressed to the broadcast ID.
    #[error("ID {id:#04x} cannot be used for a request that needs a reply")]
    NoReplyId {
        /// The ID.
        id: u8,
    },
    /// The caller's buffer does not match the request.
    #[error("buffer of {got} bytes, the request needs {expected}")]
    BufferSize {
        /// Bytes needed.
        expected: usize,
        /// Bytes given.
        got: usize,
    },
    /// No complete reply within the timeout.
    #[error("no reply from servo {id} within {timeout:?}")]
    Timeout {
        /// The ID awaited.
        id: u8,
        /// The timeout.
        timeout: Duration,
    },
    /// A corrupt packet arrived where the reply was awaited.
    #[error("corrupt reply while waiting for servo {expected}: {source}")]
    Corrupt {
        /// The ID awaited.
        expected: u8,
        /// What was wrong with the packet.
        #[source]
        source: DecodeError,
    },
    /// A status packet from another servo arrived where the reply was awaited.
    #[error("reply from servo {got} while waiting for servo {expected}")]
    WrongId {
        /// The ID awaited.
        expected: u8,
        /// The ID received.
        got: u8,
    },
    /// The servo reported an error number in its status packet.
    #[error("servo {id} reported {error}")]
    Status {
        /// The servo.
        id: u8,
        /// Its error byte.
        error: StatusError,
    },
    /// The reply carries a different number of parameter bytes than requested.
    #[error("reply from servo {id} has {got} parameter bytes, expected {expected}")]
    ReplyLength {
        /// The servo.
        id: u8,
        /// Bytes expected.
        expected: usize,
        /// Bytes received.
        got: usize,
    },
}

/// A PING reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PingInfo {
    /// Model number (e.g. 1030 for an XM430-W210).
    pub model_number: u16,
    /// Firmware version.
    pub firmware: u8,
    /// The reply's error byte (error number 0; check `alert`).
    pub status: StatusError,
}

/// A Protocol 2.0 bus client over a [`Port`].
///
/// Every request clears the decoder, sends one instruction packet and, unless it was
/// broadcast, waits for the status packet(s): each reply must be complete within the
/// timeout measured from when it starts being awaited. Bytes arrive in any fragments;
/// garbage and instruction packets (echoes) are skipped; a reply with a bad CRC, from
/// another ID, with an error number or of the wrong size is an error, never data.
/// Replies with the alert bit set are accepted (data is valid) and counted in
/// [`BusCounters::alerts`]. Servos are assumed to answer every instruction (Status
/// Return Level 2). Nothing is allocated per request after the first few.
///
/// After a timeout a late reply may still arrive and be taken for the next request's
/// reply; before retrying, clear the port's input through [`Bus::port_mut`] (for a
/// serial port, `clear(ClearBuffer::Input)`).
#[derive(Debug)]
pub struct Bus<P: Port> {
    port: P,
    timeout: Duration,
    decoder: Decoder,
    tx: Vec<u8>,
    counters: BusCounters,
    garbage_base: u64,
    /// When the last instruction packet started to be written, and its length in bytes.
    sent: Option<(Instant, usize)>,
}

impl<P: Port> Bus<P> {
    /// A bus on `port` waiting at most `timeout` for each reply.
    pub fn new(port: P, timeout: Duration) -> Self {
        Self {
            port,
            timeout,
            decoder: Decoder::new(DEFAULT_MAX_LENGTH),
            tx: Vec::with_capacity(256),
            counters: BusCounters::default(),
            garbage_base: 0,
            sent: None,
        }
    }

    /// The reply timeout.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// Changes the reply timeout.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// Event counts so far.
    pub fn counters(&self) -> BusCounters {
        BusCounters {
            garbage_bytes: self.decoder.discarded() - self.garbage_base,
            ..self.counters
        }
    }

    /// Zeroes the counters.
    pub fn reset_counters(&mut self) {
        self.counters = BusCounters::default();
        self.garbage_base = self.decoder.discarded();
    }

    /// Records that the caller retried a failed request.
    pub fn note_retry(&mut self) {
        self.counters.retries += 1;
    }

    /// When the last instruction packet started to be written, and its length in bytes
    /// (`None` before the first): the servos act on it one wire time later.
    pub fn last_sent(&self) -> Option<(Instant, usize)> {
        self.sent
    }

    /// The port (e.g. to clear its input buffer after errors).
    pub fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }

    /// Gives the port back.
    pub fn into_port(self) -> P {
        self.port
    }

    /// PING `id`: its model number and firmware version.
    pub fn ping(&mut self, id: u8) -> Result<PingInfo, BusError> {
        no_broadcast(id)?;
        self.tx.clear();
        encode_ping(id, &mut self.tx)?;
        self.send()?;
        let (status, params) = self.receive(id)?;
        let p = self.reply_params(id, params, 3)?;
        Ok(PingInfo {
            model_number: u16::from_le_bytes([p[0], p[1]]),
            firmware: p[2],
            status,
        })
    }

    /// READ `out.len()` bytes at `addr` of servo `id` into `out`.
    pub fn read(&mut self, id: u8, addr: u16, out: &mut [u8]) -> Result<StatusError, BusError> {
        no_broadcast(id)?;
        let len = request_len(out.len())?;
        self.tx.clear();
        encode_read(id, addr, len, &mut self.tx)?;
        self.send()?;
        let (status, params) = self.receive(id)?;
        out.copy_from_slice(self.reply_params(id, params, out.len())?);
        Ok(status)
    }

    /// WRITE `data` at `addr` of servo `id`; a broadcast write returns at once.
    pub fn write(&mut self, id: u8, addr: u16, data: &[u8]) -> Result<StatusError, BusError> {
        self.tx.clear();
        encode_write(id, addr, data, &mut self.tx)?;
        self.request_ack(id)
    }

    /// REBOOT servo `id`; a broadcast reboot returns at once.
    pub fn reboot(&mut self, id: u8) -> Result<StatusError, BusError> {
        self.tx.clear();
        encode_reboot(id, &mut self.tx)?;
        self.request_ack(id)
    }

    /// Any instruction to a single servo; the reply's parameters are copied into `reply`.
    pub fn transfer(
        &mut self,
        id: u8,
        instruction: Instruction,
        params: &[u8],
        reply: &mut Vec<u8>,
    ) -> Result<StatusError, BusError> {
        no_broadcast(id)?;
        self.tx.clear();
        encode_instruction(id, instruction, params, &mut self.tx)?;
        self.send()?;
        let (status, range) = self.receive(id)?;
        reply.clear();
        reply.extend_from_slice(self.decoder.params(range));
        Ok(status)
    }

    /// SYNC READ `len` bytes at `addr` from each of `ids`; servo `ids[k]`'s bytes land in
    /// `out[k * len..(k + 1) * len]`. The first failing reply ends the request.
    pub fn sync_read(
        &mut self,
        addr: u16,
        len: u16,
        ids: &[u8],
        out: &mut [u8],
    ) -> Result<(), BusError> {
        let n = usize::from(len);
        if out.len() != ids.len() * n {
            return Err(BusError::BufferSize {
                expected: ids.len() * n,
                got: out.len(),
            });
        }
        self.tx.clear();
        encode_sync_read(addr, len, ids, &mut self.tx)?;
        self.send()?;
        for (k, &id) in ids.iter().enumerate() {
            let (_, params) = self.receive(id)?;
            let data = self.reply_params(id, params, n)?;
            out[k * n..(k + 1) * n].copy_from_slice(data);
        }
        Ok(())
    }

    /// SYNC WRITE `len` bytes at `addr`: `items` yields `(id, data)`; no servo answers.
    pub fn sync_write<'a>(
        &mut self,
        addr: u16,
        len: u16,
        items: impl IntoIterator<Item = (u8, &'a [u8])>,
    ) -> Result<(), BusError> {
        self.tx.clear();
        encode_sync_write(addr, len, items, &mut self.tx)?;
        self.send()
    }

    fn request_ack(&mut self, id: u8) -> Result<StatusError, BusError> {
        self.send()?;
        if id == BROADCAST_ID {
            return Ok(StatusError::default());
        }
        let (status, params) = self.receive(id)?;
        self.reply_params(id, params, 0)?;
        Ok(status)
    }

    fn send(&mut self) -> Result<(), BusError> {
        // Whatever is still buffered answers no request of ours.
        self.decoder.clear();
        self.sent = Some((Instant::now(), self.tx.len()));
        self.port.write_all(&self.tx)?;
        self.port.flush()?;
        self.counters.transactions += 1;
        Ok(())
    }

    fn reply_params(
        &self,
        id: u8,
        range: Range<usize>,
        expected: usize,
    ) -> Result<&[u8], BusError> {
        let params = self.decoder.params(range);
        if params.len() == expected {
            Ok(params)
        } else {
            Err(BusError::ReplyLength {
                id,
                expected,
                got: params.len(),
            })
        }
    }

    /// Waits for the status packet of `id`: its error byte and parameter range.
    fn receive(&mut self, id: u8) -> Result<(StatusError, Range<usize>), BusError> {
        let deadline = Instant::now() + self.timeout;
        loop {
            while let Some(result) = self.decoder.next_frame() {
                if let Some(done) = self.judge(id, result) {
                    return done;
                }
            }
            if Instant::now() >= deadline {
                self.counters.timeouts += 1;
                return Err(BusError::Timeout {
                    id,
                    timeout: self.timeout,
                });
            }
            match self.decoder.read_from(&mut self.port) {
                Ok(0) => std::thread::yield_now(),
                Ok(_) => {}
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(e.into()),
            }
        }
    }

    /// What a decoded frame means while awaiting `id`: `None` to keep waiting.
    #[allow(clippy::type_complexity)]
    fn judge(
        &mut self,
        id: u8,
        result: Result<Frame, DecodeError>,
    ) -> Option<Result<(StatusError, Range<usize>), BusError>> {
        let frame = match result {
            Ok(frame) => frame,
            // A header-like pattern with an impossible ID or length: garbage, keep looking.
            Err(DecodeError::InvalidId { .. } | DecodeError::BadLength { .. }) => {
                self.counters.decode_errors += 1;
                return None;
            }
            Err(source) => {
                if matches!(source, DecodeError::BadCrc { .. }) {
                    self.counters.crc_errors += 1;
                } else {
                    self.counters.decode_errors += 1;
                }
                return Some(Err(BusError::Corrupt {
                    expected: id,
                    source,
                }));
            }
        };
        if frame.instruction != Instruction::Status {
            self.counters.stray_packets += 1;
            return None;
        }
        if frame.id != id {
            self.counters.wrong_id += 1;
            return Some(Err(BusError::WrongId {
                expected: id,
                got: frame.id,
            }));
        }
        let status = frame.error.unwrap_or_default();
        if status.alert {
            self.counters.alerts += 1;
        }
        if !status.is_ok() {
            self.counters.status_errors += 1;
            return Some(Err(BusError::Status { id, error: status }));
        }
        self.counters.replies += 1;
        Some(Ok((status, frame.params)))
    }
}

fn no_broadcast(id: u8) -> Result<(), BusError> {
    if id == BROADCAST_ID {
        Err(BusError::NoReplyId { id })
    } else {
        Ok(())
    }
}

fn request_len(len: usize) -> Result<u16, BusError> {
    u16::try_from(len).map_err(|_| BusError::BufferSize {
        expected: usize::from(u16::MAX),
        got: len,
    })
}
