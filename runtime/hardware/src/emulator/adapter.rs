//! The USB serial adapter between the servo bus and the host, as an FTDI chip (the U2D2's)
//! passes received bytes on: held until its latency timer expires or a USB packet fills.
//!
//! FTDI's application note AN232B-04 ("Small amounts of data and end of buffer
//! conditions"): the chip sends what it holds to the host when its buffer makes a full
//! 64-byte USB packet (2 status bytes and [`PACKET_PAYLOAD`] bytes of data), or when its
//! latency timer, which measures the time since data was last sent to the host, expires
//! (16 ms from the factory, 1 to 255 ms). Every packet sent restarts the timer; an expiry
//! with nothing held sends the two status bytes alone, which the host's driver drops. So
//! with nothing else going on, deliveries fall on a grid of timer periods, restarted at
//! each packet sent because it was full.
//!
//! Not modelled: the 1 ms frames (125 µs on high-speed chips) in which the host polls the
//! adapter, the way out (the host's bytes reach the bus at once) and the modem-status and
//! event-character conditions (Protocol 2.0 uses neither).

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// Data bytes in one full USB packet of an FTDI full-speed chip (64 bytes less the two
/// modem-status bytes).
pub const PACKET_PAYLOAD: usize = 62;

/// Far enough in the future to mean "never" and still be a valid `Instant`.
const NEVER: Duration = Duration::from_secs(100 * 365 * 24 * 3600);

/// `t + d`, saturating far in the future instead of overflowing.
pub fn later(t: Instant, d: Duration) -> Instant {
    t.checked_add(d)
        .or_else(|| t.checked_add(NEVER))
        .unwrap_or(t)
}

/// Bytes handed to the host at one moment.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Delivery {
    /// When the host can read them.
    pub at: Instant,
    /// The bytes, in the order they crossed the bus (any part of a status packet).
    pub bytes: Vec<u8>,
}

/// The adapter's receive side: the bytes it holds (or will hold, once they have crossed
/// the bus) and its latency timer.
#[derive(Debug)]
pub struct Adapter {
    timer: Duration,
    /// When data was last sent to the host: the latency timer counts from there.
    last_sent: Instant,
    /// Every byte not yet sent to the host, with the moment its stop bit ends on the bus.
    bytes: VecDeque<(Instant, u8)>,
}

impl Adapter {
    /// An adapter with latency timer `timer` (more than zero), powered up at `start`.
    pub fn new(timer: Duration, start: Instant) -> Adapter {
        Adapter {
            timer: timer.max(Duration::from_nanos(1)),
            last_sent: start,
            bytes: VecDeque::new(),
        }
    }

    /// Takes a status packet whose last byte ends on the bus at `end`, its bytes spaced by
    /// their wire time at `baud`. Packets must come in bus order.
    pub fn receive(&mut self, end: Instant, bytes: &[u8], baud: u32) {
        let n = bytes.len();
        for (k, &byte) in bytes.iter().enumerate() {
            let before_end = super::wire_time(n - 1 - k, baud);
            let at = end.checked_sub(before_end).unwrap_or(end);
            self.bytes.push_back((at, byte));
        }
    }

    /// The first moment at or after `at` when the latency timer expires, counting whole
    /// periods from the last packet sent (at least one).
    fn expiry_after(&self, at: Instant) -> Instant {
        let period = self.timer.as_nanos();
        let waited = at.saturating_duration_since(self.last_sent).as_nanos();
        let periods = waited.div_ceil(period).max(1);
        let span = u64::try_from(periods.saturating_mul(period)).unwrap_or(u64::MAX);
        later(self.last_sent, Duration::from_nanos(span))
    }

    /// When the next packet goes to the host and how many bytes it carries, from what is
    /// known now (a status packet queued later, to arrive before that moment, changes it).
    pub fn next_delivery(&self) -> Option<(Instant, usize)> {
        let &(first, _) = self.bytes.front()?;
        let expiry = self.expiry_after(first);
        if let Some(&(full, _)) = self.bytes.get(PACKET_PAYLOAD - 1)
            && full <= expiry
        {
            return Some((full, PACKET_PAYLOAD));
        }
        let count = self.bytes.iter().take_while(|(t, _)| *t <= expiry).count();
        Some((expiry, count))
    }

    /// The next packet to the host, if it is due by `now`; the latency timer restarts.
    pub fn take_due(&mut self, now: Instant) -> Option<Delivery> {
        let (at, count) = self.next_delivery().filter(|&(at, _)| at <= now)?;
        self.last_sent = at;
        let bytes = self.bytes.drain(..count).map(|(_, b)| b).collect();
        Some(Delivery { at, bytes })
    }

    /// Whether bytes are held or on their way.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn a_short_reply_waits_for_the_timer_and_a_full_packet_does_not() {
        let start = Instant::now();
        let mut adapter = Adapter::new(16 * MS, start);
        // 14 bytes ending 3 ms after power-up: delivered at the first expiry, 16 ms.
        adapter.receive(start + 3 * MS, &[7; 14], 1_000_000);
        assert_eq!(adapter.next_delivery(), Some((start + 16 * MS, 14)));
        assert!(adapter.take_due(start + 15 * MS).is_none());
        let d = adapter.take_due(start + 16 * MS).unwrap();
        assert_eq!((d.at, d.bytes.len()), (start + 16 * MS, 14));
        // 100 bytes at 1 Mbit/s (10 µs each) ending at 40 ms: the 62nd byte fills a packet
        // 380 µs before the end; the other 38 wait a whole period from there.
        let end = start + 40 * MS;
        adapter.receive(end, &[1; 100], 1_000_000);
        let full = end - Duration::from_micros(380);
        let d = adapter.take_due(end).unwrap();
        assert_eq!((d.at, d.bytes.len()), (full, 62));
        assert_eq!(adapter.next_delivery(), Some((full + 16 * MS, 38)));
        // (With nothing held the timer expired again at 32 ms; the full packet at 39.62 ms
        // restarted it.)
        assert!(adapter.take_due(full + 16 * MS).is_some());
        assert!(adapter.is_empty());
    }

    #[test]
    fn an_empty_grid_moves_on_by_whole_periods() {
        let start = Instant::now();
        let mut adapter = Adapter::new(16 * MS, start);
        adapter.receive(start + 50 * MS, &[1, 2, 3], 1_000_000);
        // Expiries at 16, 32, 48 (nothing held), then 64 ms.
        assert_eq!(adapter.next_delivery(), Some((start + 64 * MS, 3)));
        // A byte ending exactly on an expiry goes with it.
        let mut adapter = Adapter::new(16 * MS, start);
        adapter.receive(start + 32 * MS, &[1], 1_000_000);
        assert_eq!(adapter.next_delivery(), Some((start + 32 * MS, 1)));
    }
}
