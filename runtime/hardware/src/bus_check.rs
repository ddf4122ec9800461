//! What the servo bus allows `softcbf run`: the round trip of the loop's sync read and sync
//! write measured at the start, the loop rate it permits, and the USB adapter's latency timer.
//!
//! **The rule.** [`measure`] times [`CYCLES`] back-to-back read-and-write cycles (the
//! loop's own traffic, torque off, writing zero goal currents), retries included: the loop
//! pays for them too; the run loop then times the computation of a few commands from the
//! state read ([`BusTiming::compute`], their median). The rate allowed is one cycle and one computation
//! per period for nine cycles in ten: `1 / (90th percentile + computation)`
//! ([`BusTiming::rate_limit`]); two slow cycles in twenty (a lost reply, a scheduler
//! hiccup) do not decide. [`choose_rate`] refuses a rate above it, or with `--rate auto`
//! runs at [`AUTO_RATE_MARGIN`] of it.
//!
//! **The latency timer.** A USB serial adapter (FTDI, as in the U2D2) holds received bytes
//! up to its latency timer (16 ms by default) before passing them on, so each reply may wait
//! that long. On Linux the timer is `/sys/bus/usb-serial/devices/<tty>/latency_timer`;
//! [`latency_timer`] finds it for a port (following symlinks such as
//! `/dev/serial/by-id/…`), under a sysfs root given by the caller (tests use a fake tree).

use std::path::{Path, PathBuf};
use std::time::Instant;

use softcbf_description::limits;

use crate::protocol::Bus;
use crate::servo_io::{ServoIo, ServoPort, StartError};

/// Read-and-write cycles timed at the start.
pub const CYCLES: usize = 20;

/// The quantile of the cycle times that sets the rate the bus allows.
pub const CYCLE_QUANTILE: f64 = 0.9;

/// Fraction of the rate the bus allows that `--rate auto` runs at: the rest is left for the
/// computation (tens to hundreds of µs), the write's wire time and slower cycles than
/// measured.
pub const AUTO_RATE_MARGIN: f64 = 0.8;

/// The default root of sysfs.
pub const SYSFS: &str = "/sys";

/// The measured round trip of one sync read and sync write \[s\].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BusTiming {
    /// Cycles timed.
    pub cycles: usize,
    /// Of those, cycles whose read needed a retry or failed.
    pub retried: usize,
    /// Median cycle time \[s\].
    pub median: f64,
    /// The [`CYCLE_QUANTILE`] of the cycle times (nearest rank) \[s\].
    pub slow: f64,
    /// Longest cycle time \[s\].
    pub max: f64,
    /// The computation of one command (prediction, controller, tensions), the median of
    /// those timed at the start \[s\] (0 until timed).
    pub compute: f64,
}

impl BusTiming {
    /// The statistics of the cycle times `samples` (sorted in place), `retried` of which
    /// needed a retry; `None` without a sample, or with one that is not finite and positive.
    pub fn from_samples(samples: &mut [f64], retried: usize) -> Option<BusTiming> {
        if samples.is_empty() || samples.iter().any(|s| !s.is_finite() || *s <= 0.0) {
            return None;
        }
        samples.sort_by(f64::total_cmp);
        let n = samples.len();
        let median = if n % 2 == 1 {
            samples[n / 2]
        } else {
            0.5 * (samples[n / 2 - 1] + samples[n / 2])
        };
        // Nearest rank: the smallest sample with at least that fraction at or below it.
        let rank = (CYCLE_QUANTILE * n as f64).ceil() as usize;
        Some(BusTiming {
            cycles: n,
            retried,
            median,
            slow: samples[rank.clamp(1, n) - 1],
            max: samples[n - 1],
            compute: 0.0,
        })
    }

    /// The same with the computation of a command, `compute` \[s\].
    pub fn with_compute(self, compute: f64) -> BusTiming {
        BusTiming {
            compute: if compute.is_finite() {
                compute.max(0.0)
            } else {
                0.0
            },
            ..self
        }
    }

    /// The time one tick needs for nine in ten: a cycle and a computation \[s\].
    pub fn tick_time(&self) -> f64 {
        self.slow + self.compute
    }

    /// The highest loop rate the bus and the computation hold: one cycle and one
    /// computation per period for nine cycles in ten \[Hz\].
    pub fn rate_limit(&self) -> f64 {
        1.0 / self.tick_time()
    }

    /// E.g. `bus: one read+write cycle takes 16.20 ms median, 16.80 ms for 90 % of 20
    /// cycles, 17.00 ms max → at most 59 Hz`, with the cycles whose read was retried.
    pub fn line(&self) -> String {
        let retried = match self.retried {
            0 => String::new(),
            n if 2 * n >= self.cycles => format!(
                " ({n} reads retried: a reply timeout (hardware.reply_timeout_ms) too short \
                 for this baud rate, or a bus that loses replies)"
            ),
            n => format!(" ({n} reads retried)"),
        };
        format!(
            "bus: one read+write cycle takes {:.2} ms median, {:.2} ms for 90 % of {} cycles, \
             {:.2} ms max; computing a command {:.2} ms → at most {:.0} Hz{retried}",
            self.median * 1e3,
            self.slow * 1e3,
            self.cycles,
            self.max * 1e3,
            self.compute * 1e3,
            self.rate_limit().floor()
        )
    }
}

/// What a run does about a rate the bus cannot hold.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RateRule {
    /// Refuses it (`--rate HZ`).
    #[default]
    Hold,
    /// Runs at what the bus allows with a margin, at most the rate asked (`--rate auto`).
    Adapt,
    /// Runs at it anyway: every tick overruns and the next starts at once, the loop as fast
    /// as the bus goes (for measurements and tests; `softcbf run` does not offer it).
    Overrun,
}

/// The loop rate a run settles on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RateChoice {
    /// The rate asked for, which the bus holds \[Hz\].
    Asked(f64),
    /// The rate `--rate auto` chose from the bus \[Hz\].
    Adapted(f64),
    /// The rate asked for, beyond what the bus holds, under [`RateRule::Overrun`] \[Hz\].
    Overrunning(f64),
}

impl RateChoice {
    /// The rate \[Hz\].
    pub fn rate(self) -> f64 {
        match self {
            RateChoice::Asked(rate) | RateChoice::Adapted(rate) | RateChoice::Overrunning(rate) => {
                rate
            }
        }
    }
}

/// A rate the bus cannot hold.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RateRefusal {
    /// The rate asked for is above what the bus allows.
    #[error(
        "--rate {asked} Hz: the bus cannot hold it: one read+write cycle takes {:.2} ms \
         (90 % of the cycles measured) and computing a command {:.2} ms, at most {:.0} Hz; \
         ask for at most that, or give --rate auto{}",
        timing.slow * 1e3,
        timing.compute * 1e3,
        timing.rate_limit().floor(),
        auto.map_or(String::new(), |r| format!(" to run at {r} Hz"))
    )]
    TooFast {
        /// The rate asked for \[Hz\].
        asked: f64,
        /// The measured round trip.
        timing: BusTiming,
        /// What `--rate auto` would choose \[Hz\].
        auto: Option<f64>,
    },
    /// Even the slowest loop rate is too fast for the bus.
    #[error(
        "--rate auto: one read+write cycle and a command's computation take {:.0} ms (90 % \
         of the cycles measured): with the margin the bus allows less than the slowest loop \
         rate, {} Hz",
        timing.tick_time() * 1e3,
        limits::RATE_HZ.min
    )]
    TooSlow {
        /// The measured round trip.
        timing: BusTiming,
    },
}

/// The rate `--rate auto` runs at on a bus that allows `rate_limit` Hz: a whole number of
/// Hz at most [`AUTO_RATE_MARGIN`] of it, at most `ceiling` and the fastest loop rate;
/// `None` below the slowest loop rate.
pub fn auto_rate(rate_limit: f64, ceiling: f64) -> Option<f64> {
    let rate = (AUTO_RATE_MARGIN * rate_limit)
        .floor()
        .min(ceiling)
        .min(limits::RATE_HZ.max);
    (rate >= limits::RATE_HZ.min).then_some(rate)
}

/// The loop rate of a run that asked for `rate` under `rule` (with [`RateRule::Adapt`],
/// `rate` is the ceiling), or why the bus cannot hold it.
pub fn choose_rate(
    rate: f64,
    rule: RateRule,
    timing: &BusTiming,
) -> Result<RateChoice, RateRefusal> {
    let limit = timing.rate_limit();
    let held = rate * timing.tick_time() <= 1.0;
    match rule {
        RateRule::Adapt => auto_rate(limit, rate)
            .map(RateChoice::Adapted)
            .ok_or(RateRefusal::TooSlow { timing: *timing }),
        _ if held => Ok(RateChoice::Asked(rate)),
        RateRule::Overrun => Ok(RateChoice::Overrunning(rate)),
        RateRule::Hold => Err(RateRefusal::TooFast {
            asked: rate,
            timing: *timing,
            auto: auto_rate(limit, limits::RATE_HZ.max),
        }),
    }
}

/// Times [`CYCLES`] cycles of the loop's traffic: a sync read of every servo (with
/// `retries`) and a sync write of `currents`, back to back; a cycle lasts from the start of
/// its read to the start of the next one's. Fails when a write fails or no read succeeds.
pub fn measure<P: ServoPort>(
    bus: &mut Bus<P>,
    io: &mut ServoIo,
    currents: &[i16],
    retries: u32,
) -> Result<BusTiming, StartError> {
    let mut samples = [0.0; CYCLES];
    let (mut retried, mut succeeded) = (0, 0);
    let mut failure = None;
    let mut start = Instant::now();
    // One read more than timed: the last one only ends the cycle before.
    for cycle in 0..=CYCLES {
        let now = Instant::now();
        if cycle > 0 {
            samples[cycle - 1] = now.duration_since(start).as_secs_f64();
        }
        if cycle == CYCLES {
            break;
        }
        start = now;
        match io.read_states(bus, retries) {
            Ok(()) => {
                succeeded += 1;
                retried += usize::from(io.attempts() > 1);
            }
            Err(error) => {
                retried += 1;
                failure = Some(error);
            }
        }
        io.write_currents(bus, currents)
            .map_err(StartError::State)?;
    }
    match (succeeded, failure) {
        (0, Some(error)) => Err(StartError::State(error)),
        _ => BusTiming::from_samples(&mut samples, retried)
            .ok_or(StartError::NoReading { cycles: CYCLES }),
    }
}

/// The latency timer of the adapter behind a serial port.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LatencyTimer {
    /// A USB serial adapter with a latency timer.
    Found {
        /// The tty (`ttyUSB0`).
        device: String,
        /// Its sysfs file.
        path: PathBuf,
        /// The timer \[ms\].
        ms: u32,
        /// The kernel driver (`ftdi_sio`), when sysfs names it.
        driver: Option<String>,
    },
    /// No latency timer: a pseudo-terminal (the emulator), an on-board UART, a CDC-ACM
    /// device, or a port that does not exist.
    Absent,
    /// The sysfs file exists but could not be read as a number of ms.
    Unreadable {
        /// The file.
        path: PathBuf,
        /// Why.
        error: String,
    },
}

/// The latency timer of the adapter behind `port` (symlinks resolved), looked up under the
/// sysfs root `sysfs` (normally [`SYSFS`]).
pub fn latency_timer(port: &Path, sysfs: &Path) -> LatencyTimer {
    let Ok(device) = std::fs::canonicalize(port) else {
        return LatencyTimer::Absent;
    };
    let Some(name) = device.file_name().and_then(|n| n.to_str()) else {
        return LatencyTimer::Absent;
    };
    let dir = sysfs.join("bus/usb-serial/devices").join(name);
    let path = dir.join("latency_timer");
    if !path.exists() {
        return LatencyTimer::Absent;
    }
    let text = match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(error) => {
            return LatencyTimer::Unreadable {
                path,
                error: error.to_string(),
            };
        }
    };
    let ms = match text.trim().parse::<u32>() {
        Ok(ms) => ms,
        Err(_) => {
            return LatencyTimer::Unreadable {
                path,
                error: format!("`{}` is not a number of ms", text.trim()),
            };
        }
    };
    let driver = std::fs::read_link(dir.join("driver"))
        .ok()
        .and_then(|target| target.file_name()?.to_str().map(str::to_string));
    LatencyTimer::Found {
        device: name.to_string(),
        path,
        ms,
        driver,
    }
}

/// The reply timeout a USB adapter with a latency timer of `timer_ms` lets every reply meet
/// \[ms\]: 2.5 timer periods, in whole ms. The adapter passes bytes on when a USB packet
/// fills or its timer expires, counted from the last packet it sent, so the reply that
/// ends a read waits up to one whole period in it; the rest covers the reply's own time on
/// the bus (Return Delay Time, wire) and the host's scheduling. 40 ms for FTDI's factory
/// 16 ms (with the file's 10 ms the last servo's reply of every read is lost), 3 ms for a
/// tuned 1 ms, 0 without an adapter.
pub fn reply_timeout_needed_ms(timer_ms: u32) -> f64 {
    (2.5 * f64::from(timer_ms)).ceil()
}

/// Whether a reply timeout of `reply_timeout_ms` (given by `source`, e.g. `--reply-timeout-ms
/// 10`) can be met behind `timer`; if not, what to do instead, for an error before the
/// first packet.
pub fn check_reply_timeout(
    timer: &LatencyTimer,
    reply_timeout_ms: f64,
    source: &str,
) -> Result<(), String> {
    let LatencyTimer::Found {
        device, path, ms, ..
    } = timer
    else {
        return Ok(());
    };
    let needed = reply_timeout_needed_ms(*ms);
    if reply_timeout_ms >= needed {
        return Ok(());
    }
    Err(format!(
        "{source}: a reply timeout of {reply_timeout_ms} ms is shorter than the latency timer \
         of {device} ({ms} ms) lets replies arrive: the adapter holds each reply up to {ms} ms, \
         and reads would time out; give --reply-timeout-ms {needed} (at least 2.5 timer \
         periods), or lower the timer to 1 ms: echo 1 | sudo tee {}",
        path.display()
    ))
}

impl LatencyTimer {
    /// Whether the timer is above 1 ms: replies wait in the adapter.
    pub fn too_long(&self) -> bool {
        matches!(self, LatencyTimer::Found { ms, .. } if *ms > 1)
    }

    /// What to tell the operator, one line each; above 1 ms, how to lower it now and for
    /// good.
    pub fn lines(&self) -> Vec<String> {
        match self {
            LatencyTimer::Absent => {
                vec!["bus: no latency timer (not a USB serial adapter)".to_string()]
            }
            LatencyTimer::Unreadable { path, error } => vec![format!(
                "bus: cannot read the latency timer {}: {error}",
                path.display()
            )],
            LatencyTimer::Found {
                device, ms: 0 | 1, ..
            } => {
                vec![format!("bus: latency timer of {device}: ≤ 1 ms")]
            }
            LatencyTimer::Found {
                device,
                path,
                ms,
                driver,
            } => {
                let driver = driver
                    .as_ref()
                    .map_or(String::new(), |d| format!("DRIVER==\"{d}\", "));
                vec![
                    format!(
                        "bus: the latency timer of {device} is {ms} ms: the adapter may hold \
                         each reply up to {ms} ms. Lower it to 1 ms until the adapter is \
                         unplugged:"
                    ),
                    format!("  echo 1 | sudo tee {}", path.display()),
                    "and for good with a udev rule (e.g. in \
                     /etc/udev/rules.d/99-usb-serial-latency.rules, then replug the adapter):"
                        .to_string(),
                    format!(
                        "  ACTION==\"add\", SUBSYSTEM==\"usb-serial\", {driver}\
                         ATTR{{latency_timer}}=\"1\""
                    ),
                ]
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn timing(slow: f64) -> BusTiming {
        BusTiming {
            cycles: 20,
            retried: 0,
            median: 0.9 * slow,
            slow,
            max: 1.1 * slow,
            compute: 0.0,
        }
    }

    #[test]
    fn the_statistics_are_the_median_the_ninetieth_percentile_and_the_maximum() {
        // 1..=20 ms, shuffled: median 10.5 ms, 90 % (nearest rank 18) 18 ms, max 20 ms.
        let mut samples: Vec<f64> = (1..=20)
            .map(|k| f64::from((k * 7) % 20 + 1) / 1000.0)
            .collect();
        let t = BusTiming::from_samples(&mut samples, 2).unwrap();
        assert_eq!((t.cycles, t.retried), (20, 2));
        assert!((t.median - 10.5e-3).abs() < 1e-15, "{}", t.median);
        assert_eq!(t.slow, 18e-3);
        assert_eq!(t.max, 20e-3);
        // An odd count: the middle one; a single sample is everything.
        let t = BusTiming::from_samples(&mut [3e-3, 1e-3, 2e-3], 0).unwrap();
        assert_eq!((t.median, t.slow, t.max), (2e-3, 3e-3, 3e-3));
        let t = BusTiming::from_samples(&mut [4e-3], 0).unwrap();
        assert_eq!((t.median, t.slow, t.max), (4e-3, 4e-3, 4e-3));
        // Nothing to measure, or a measurement that is not a time.
        assert_eq!(BusTiming::from_samples(&mut [], 0), None);
        assert_eq!(BusTiming::from_samples(&mut [1e-3, f64::NAN], 0), None);
        assert_eq!(BusTiming::from_samples(&mut [0.0], 0), None);
    }

    #[test]
    fn two_slow_cycles_in_twenty_do_not_set_the_rate() {
        let mut samples = [2e-3; 20];
        samples[7] = 40e-3;
        samples[12] = 30e-3;
        let t = BusTiming::from_samples(&mut samples, 2).unwrap();
        assert_eq!((t.slow, t.max), (2e-3, 40e-3));
        assert_eq!(t.rate_limit(), 500.0);
        // Three in twenty do.
        samples[3] = 25e-3;
        let t = BusTiming::from_samples(&mut samples, 3).unwrap();
        assert_eq!(t.rate_limit(), 40.0);
    }

    #[test]
    fn the_line_reports_the_round_trip_and_the_rate() {
        let mut t = BusTiming {
            cycles: 20,
            retried: 0,
            median: 16.2e-3,
            slow: 16.8e-3,
            max: 17.0e-3,
            compute: 0.0,
        };
        assert_eq!(
            t.line(),
            "bus: one read+write cycle takes 16.20 ms median, 16.80 ms for 90 % of 20 \
             cycles, 17.00 ms max; computing a command 0.00 ms → at most 59 Hz"
        );
        t.retried = 2;
        assert!(
            t.line().ends_with("→ at most 59 Hz (2 reads retried)"),
            "{}",
            t.line()
        );
        // Most reads retried: a setting to look at.
        t.retried = 10;
        assert!(
            t.line().contains("(10 reads retried: a reply timeout"),
            "{}",
            t.line()
        );
    }

    #[test]
    fn a_rate_the_bus_holds_is_kept_and_a_faster_one_refused() {
        // A 16 ms cycle allows 62.5 Hz.
        let t = timing(16e-3);
        assert_eq!(
            choose_rate(33.0, RateRule::Hold, &t),
            Ok(RateChoice::Asked(33.0))
        );
        assert_eq!(
            choose_rate(62.5, RateRule::Hold, &t),
            Ok(RateChoice::Asked(62.5))
        );
        let refusal = choose_rate(63.0, RateRule::Hold, &t).unwrap_err();
        assert_eq!(
            refusal,
            RateRefusal::TooFast {
                asked: 63.0,
                timing: t,
                // 0.8 · 62.5 = 50.
                auto: Some(50.0),
            }
        );
        let message = refusal.to_string();
        assert!(
            message.starts_with("--rate 63 Hz: the bus cannot hold it"),
            "{message}"
        );
        assert!(message.contains("16.00 ms"), "{message}");
        assert!(message.contains("at most 62 Hz"), "{message}");
        assert!(message.contains("--rate auto to run at 50 Hz"), "{message}");
        // 5000 Hz on a 1 Mbit/s bus of six servos (≈ 2 ms).
        assert!(choose_rate(5000.0, RateRule::Hold, &timing(2e-3)).is_err());
        // Unless asked to overrun.
        assert_eq!(
            choose_rate(5000.0, RateRule::Overrun, &timing(2e-3)),
            Ok(RateChoice::Overrunning(5000.0))
        );
        assert_eq!(
            choose_rate(400.0, RateRule::Overrun, &timing(2e-3)),
            Ok(RateChoice::Asked(400.0))
        );
    }

    #[test]
    fn the_computation_of_a_command_counts_against_the_rate() {
        // The bus: a 20.9 ms cycle allows 47 Hz, and 45 Hz was run though every
        // tick then overran; with a 2 ms computation 43 Hz is the most.
        let t = timing(20.9e-3);
        assert_eq!(
            choose_rate(45.0, RateRule::Hold, &t),
            Ok(RateChoice::Asked(45.0))
        );
        let t = t.with_compute(2e-3);
        assert!((t.rate_limit() - 1.0 / 22.9e-3).abs() < 1e-9);
        let refusal = choose_rate(45.0, RateRule::Hold, &t).unwrap_err();
        let message = refusal.to_string();
        assert!(message.contains("computing a command 2.00 ms"), "{message}");
        assert!(message.contains("at most 43 Hz"), "{message}");
        assert!(
            t.line()
                .contains("; computing a command 2.00 ms → at most 43 Hz")
        );
        assert_eq!(
            choose_rate(33.0, RateRule::Hold, &t),
            Ok(RateChoice::Asked(33.0))
        );
        // 0.8 · 43.67 = 34.9 → 34 Hz.
        assert_eq!(
            choose_rate(limits::RATE_HZ.max, RateRule::Adapt, &t),
            Ok(RateChoice::Adapted(34.0))
        );
        // A computation that is not a time counts as none.
        assert_eq!(t.with_compute(f64::NAN).compute, 0.0);
    }

    #[test]
    fn auto_runs_at_a_whole_rate_with_the_margin_within_the_loop_limits() {
        // 2 ms: 500 Hz allowed, 400 Hz run.
        assert_eq!(
            choose_rate(limits::RATE_HZ.max, RateRule::Adapt, &timing(2e-3)),
            Ok(RateChoice::Adapted(400.0))
        );
        // 48.3 ms: 20.7 Hz allowed, 0.8 · 20.70 = 16.56 → 16 Hz.
        assert_eq!(
            choose_rate(limits::RATE_HZ.max, RateRule::Adapt, &timing(48.3e-3)),
            Ok(RateChoice::Adapted(16.0))
        );
        // Never above the ceiling, nor above the fastest loop rate.
        assert_eq!(
            choose_rate(33.0, RateRule::Adapt, &timing(2e-3)),
            Ok(RateChoice::Adapted(33.0))
        );
        assert_eq!(auto_rate(1e6, f64::INFINITY), Some(limits::RATE_HZ.max));
        // A bus slower than the slowest loop: 0.8 / 0.9 s < 1 Hz.
        let slow = timing(0.9);
        assert_eq!(
            choose_rate(limits::RATE_HZ.max, RateRule::Adapt, &slow),
            Err(RateRefusal::TooSlow { timing: slow })
        );
        assert_eq!(auto_rate(1.25, 100.0), Some(1.0));
        // And a fixed rate on that bus has no auto to offer.
        let refusal = choose_rate(2.0, RateRule::Hold, &slow).unwrap_err();
        assert!(matches!(refusal, RateRefusal::TooFast { auto: None, .. }));
        assert!(!refusal.to_string().contains(" to run at"), "{refusal}");
    }

    /// A fake `/dev` and `/sys` under a fresh temporary directory.
    struct FakeTree {
        root: PathBuf,
    }

    impl FakeTree {
        fn new(name: &str) -> FakeTree {
            let root = std::env::temp_dir()
                .join(format!("softcbf-bus-check-{}-{name}", std::process::id()));
            let _ = std::fs::remove_dir_all(&root);
            std::fs::create_dir_all(root.join("dev/serial/by-id")).unwrap();
            std::fs::create_dir_all(root.join("dev/pts")).unwrap();
            std::fs::create_dir_all(root.join("sys/bus/usb-serial/drivers/ftdi_sio")).unwrap();
            FakeTree { root }
        }

        fn sysfs(&self) -> PathBuf {
            self.root.join("sys")
        }

        /// `dev/<tty>` and, with `timer`, its sysfs directory with that latency_timer text.
        fn adapter(&self, tty: &str, timer: Option<&str>, driver: bool) -> PathBuf {
            let device = self.root.join("dev").join(tty);
            std::fs::write(&device, "").unwrap();
            let dir = self.sysfs().join("bus/usb-serial/devices").join(tty);
            std::fs::create_dir_all(&dir).unwrap();
            if let Some(text) = timer {
                std::fs::write(dir.join("latency_timer"), text).unwrap();
            }
            if driver {
                #[cfg(unix)]
                std::os::unix::fs::symlink("../../drivers/ftdi_sio", dir.join("driver")).unwrap();
            }
            device
        }
    }

    impl Drop for FakeTree {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.root);
        }
    }

    #[test]
    #[cfg(unix)]
    fn the_latency_timer_is_found_through_a_by_id_link() {
        let tree = FakeTree::new("by-id");
        tree.adapter("ttyUSB0", Some("16\n"), true);
        let link = tree
            .root
            .join("dev/serial/by-id/usb-FTDI_USB__-__Serial_Converter_FT1234-if00-port0");
        std::os::unix::fs::symlink("../../ttyUSB0", &link).unwrap();
        let timer = latency_timer(&link, &tree.sysfs());
        let path = tree
            .root
            .join("sys/bus/usb-serial/devices/ttyUSB0/latency_timer");
        assert_eq!(
            timer,
            LatencyTimer::Found {
                device: "ttyUSB0".into(),
                path: path.clone(),
                ms: 16,
                driver: Some("ftdi_sio".into()),
            }
        );
        assert!(timer.too_long());
        let lines = timer.lines();
        assert!(lines[0].contains("ttyUSB0 is 16 ms"), "{lines:?}");
        assert_eq!(lines[1], format!("  echo 1 | sudo tee {}", path.display()));
        assert_eq!(
            lines[3],
            "  ACTION==\"add\", SUBSYSTEM==\"usb-serial\", DRIVER==\"ftdi_sio\", \
             ATTR{latency_timer}=\"1\""
        );
    }

    #[test]
    fn a_timer_of_one_ms_needs_no_advice_and_a_missing_driver_is_left_out() {
        let tree = FakeTree::new("one-ms");
        let port = tree.adapter("ttyUSB1", Some("1"), false);
        let timer = latency_timer(&port, &tree.sysfs());
        assert!(matches!(
            &timer,
            LatencyTimer::Found {
                ms: 1,
                driver: None,
                ..
            }
        ));
        assert!(!timer.too_long());
        assert_eq!(timer.lines(), ["bus: latency timer of ttyUSB1: ≤ 1 ms"]);
        // Without the driver's name the udev rule matches every usb-serial adapter.
        let port = tree.adapter("ttyUSB2", Some("8"), false);
        let lines = latency_timer(&port, &tree.sysfs()).lines();
        assert_eq!(
            lines[3],
            "  ACTION==\"add\", SUBSYSTEM==\"usb-serial\", ATTR{latency_timer}=\"1\""
        );
    }

    #[test]
    fn a_pseudo_terminal_or_a_missing_port_has_no_latency_timer() {
        let tree = FakeTree::new("absent");
        let pty = tree.root.join("dev/pts/3");
        std::fs::write(&pty, "").unwrap();
        assert_eq!(latency_timer(&pty, &tree.sysfs()), LatencyTimer::Absent);
        // A usb-serial device without the file (a driver that has no timer).
        let port = tree.adapter("ttyUSB3", None, true);
        assert_eq!(latency_timer(&port, &tree.sysfs()), LatencyTimer::Absent);
        assert_eq!(
            latency_timer(&tree.root.join("dev/nothing"), &tree.sysfs()),
            LatencyTimer::Absent
        );
        assert_eq!(
            LatencyTimer::Absent.lines(),
            ["bus: no latency timer (not a USB serial adapter)"]
        );
    }

    #[test]
    #[cfg(unix)]
    fn a_reply_timeout_the_latency_timer_cannot_meet_is_refused_with_the_fix() {
        let tree = FakeTree::new("reply-timeout");
        let port = tree.adapter("ttyUSB5", Some("16"), true);
        let timer = latency_timer(&port, &tree.sysfs());
        assert_eq!(reply_timeout_needed_ms(16), 40.0);
        assert_eq!(reply_timeout_needed_ms(1), 3.0);
        assert_eq!(reply_timeout_needed_ms(0), 0.0);
        let error = check_reply_timeout(&timer, 10.0, "hardware.reply_timeout_ms").unwrap_err();
        assert!(
            error.starts_with(
                "hardware.reply_timeout_ms: a reply timeout of 10 ms is shorter than the \
                 latency timer of ttyUSB5 (16 ms)"
            ),
            "{error}"
        );
        assert!(error.contains("give --reply-timeout-ms 40"), "{error}");
        assert!(error.contains("echo 1 | sudo tee "), "{error}");
        assert_eq!(
            check_reply_timeout(&timer, 40.0, "--reply-timeout-ms"),
            Ok(())
        );
        // A tuned adapter, or none: the file's 10 ms is enough.
        let tuned = latency_timer(&tree.adapter("ttyUSB6", Some("1"), true), &tree.sysfs());
        assert_eq!(check_reply_timeout(&tuned, 10.0, "x"), Ok(()));
        assert_eq!(check_reply_timeout(&LatencyTimer::Absent, 1.0, "x"), Ok(()));
    }

    #[test]
    fn a_latency_timer_that_is_not_a_number_is_reported_unreadable() {
        let tree = FakeTree::new("garbage");
        let port = tree.adapter("ttyUSB4", Some("sixteen"), true);
        let timer = latency_timer(&port, &tree.sysfs());
        assert!(
            matches!(&timer, LatencyTimer::Unreadable { error, .. } if error.contains("`sixteen`")),
            "{timer:?}"
        );
        assert!(!timer.too_long());
        assert!(timer.lines()[0].starts_with("bus: cannot read the latency timer"));
    }
}
