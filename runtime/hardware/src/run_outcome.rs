//! How a `softcbf run` ended and what it means: the stop reason, the summary of the ticks
//! and their deadlines, and the verdict (safe, unsafe, fault) that becomes the exit status.

use std::time::{Duration, Instant};

use crate::bus_check::{BusTiming, RateChoice};
use crate::experiment::ExperimentReport;
use crate::mapping::Clamps;
use crate::protocol::BusCounters;
use crate::run_settings::RATE_WINDOW;
use crate::sim::{BarrierMinimum, LowestByKind};
pub use crate::verdict::Verdict;
use crate::verdict::{Limits, Lowest, Outcome, Overruns, judge};

/// Why a run ended.
#[derive(Clone, Debug, PartialEq)]
pub enum StopReason {
    /// The duration elapsed.
    Duration,
    /// The identification experiment is over: every step run (`left = 0`), or its cap
    /// (`--duration`) reached with `left` steps not run.
    ExperimentOver {
        /// Steps not run.
        left: usize,
    },
    /// The identification experiment's guard stopped it before its end, the robot safe: a
    /// barrier at the state read below the stop distance, or no level left that keeps the
    /// barriers their distance ([`crate::experiment::ExperimentStop`]). Not a
    /// fault; the command line exits with [`softcbf_core::exit::ERROR`] at least (not all done).
    ExperimentStopped {
        /// What happened, naming the barrier.
        why: String,
        /// Steps not run.
        left: usize,
    },
    /// A terminating signal (Ctrl-C, a closed terminal, `kill`) through the stop flag.
    Interrupted,
    /// `max_consecutive_errors` ticks in a row without a good reading.
    CommunicationLost {
        /// Held ticks in a row.
        ticks: u32,
        /// The last bus error.
        last_error: String,
    },
    /// The loop could not keep `min_rate`.
    RateTooLow {
        /// Rate achieved over the last [`RATE_WINDOW`] commands \[Hz\].
        achieved: f64,
        /// The minimum \[Hz\].
        min: f64,
    },
    /// No instruction reached the servos for most of their Bus Watchdog (80 %): they may
    /// have stopped by themselves, and the run stops with them.
    WatchdogExpired {
        /// The pause \[s\].
        gap: f64,
        /// The watchdog \[s\].
        watchdog: f64,
    },
    /// A servo reported a hardware error, the port failed, the log could not be written,
    /// or the loop itself failed (a panic, caught).
    Fault(String),
}

impl StopReason {
    /// Whether the run ended on a fault.
    pub fn is_fault(&self) -> bool {
        !matches!(
            self,
            StopReason::Duration
                | StopReason::Interrupted
                | StopReason::ExperimentOver { .. }
                | StopReason::ExperimentStopped { .. }
        )
    }
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StopReason::Duration => write!(f, "duration elapsed"),
            StopReason::ExperimentOver { left: 0 } => write!(f, "experiment complete"),
            StopReason::ExperimentOver { left } => write!(
                f,
                "experiment ended by --duration with {left} of its steps not run"
            ),
            StopReason::ExperimentStopped { why, left } => write!(
                f,
                "experiment stopped by its guard with {left} of its steps not run: {why}"
            ),
            StopReason::Interrupted => write!(f, "interrupted"),
            StopReason::CommunicationLost { ticks, last_error } => {
                write!(
                    f,
                    "communication lost: {ticks} ticks in a row without a good reading (last: {last_error})"
                )
            }
            StopReason::RateTooLow { achieved, min } => write!(
                f,
                "the loop ran at {achieved:.1} Hz over the last {RATE_WINDOW} commands, below \
                 the minimum {min} Hz (--min-rate): the bus or the machine is too slow for \
                 the barrier guarantee"
            ),
            StopReason::WatchdogExpired { gap, watchdog } => write!(
                f,
                "the loop paused {:.0} ms between instructions, too close to the servos' Bus \
                 Watchdog ({:.0} ms) to know whether they stopped by themselves",
                gap * 1000.0,
                watchdog * 1000.0
            ),
            StopReason::Fault(what) => write!(f, "fault: {what}"),
        }
    }
}

/// The deadlines of a run's ticks and the holds of its commands.
///
/// A tick is due every period; it overruns its deadline when its read, computation and
/// write end more than one period after it was due (the next tick is then late). A command
/// is computed for a hold `Δ` (the sampled-data guarantee holds for that long); it
/// overruns its hold when it stays in force longer, until the next command or the safe
/// stop: after a late or slow tick, a tick without a reading, or jitter of the bus.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Deadlines {
    /// Ticks that ended more than a period after they were due.
    pub deadline_overruns: u64,
    /// Commands in force longer than the hold they were computed for.
    pub hold_overruns: u64,
    /// The most a command stayed in force beyond its hold \[s\] (`0` when none did).
    pub longest_hold_excess: f64,
    /// The longest time one command stayed in force \[s\].
    pub longest_period: f64,
}

impl Deadlines {
    /// A tick due at `due` that ended at `end`, at `period`: whether it overran its deadline
    /// (then counted).
    pub fn tick(&mut self, due: Instant, period: Duration, end: Instant) -> bool {
        let overran = end > due + period;
        if overran {
            self.deadline_overruns += 1;
        }
        overran
    }

    /// A command computed for a hold of `hold` seconds stayed in force `in_force` seconds;
    /// returns how much longer than its hold (`> 0`: a hold overrun, counted).
    pub fn command(&mut self, in_force: f64, hold: f64) -> f64 {
        self.longest_period = self.longest_period.max(in_force);
        let excess = in_force - hold;
        if excess > 0.0 {
            self.hold_overruns += 1;
            self.longest_hold_excess = self.longest_hold_excess.max(excess);
        }
        excess
    }
}

/// What happened in a run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSummary {
    /// Why it ended.
    pub stop: StopReason,
    /// Ticks run.
    pub ticks: u64,
    /// Ticks that sent a command computed from a fresh reading.
    pub commands: u64,
    /// Ticks without a fresh reading (nothing sent).
    pub held: u64,
    /// Ticks whose command was the controller's safe fallback (zero): a failed QP or an
    /// invalid state.
    pub fallbacks: u64,
    /// Of those, ticks whose state or model was invalid (non-finite, outside the model's
    /// domain, `M` not positive definite).
    pub invalid: u64,
    /// Ticks whose QP had to relax barrier rows.
    pub relaxed: u64,
    /// Ticks whose command could not be certified over its hold
    /// ([`crate::control::TickStatus::Uncertified`]).
    pub uncertified: u64,
    /// Those ticks per reason.
    pub uncertified_reasons: crate::control::UncertifiedCounts,
    /// Ticks whose command was computed without the safety filter (`--no-filter`).
    pub unfiltered: u64,
    /// Ticks whose command the safety filter changed (by more than
    /// [`CLAMP_TOLERANCE`](crate::mapping::CLAMP_TOLERANCE) in some entry of `τ`).
    pub interventions: u64,
    /// Deadline and hold overruns, and the longest period.
    pub deadlines: Deadlines,
    /// Tensions held at their limits, summed over ticks.
    pub clamps: Clamps,
    /// Bus event counts.
    pub bus: BusCounters,
    /// Lowest barrier value at a reading (the state read, not predicted), and which;
    /// `value` is infinite when no reading was made.
    pub min_barrier: BarrierMinimum,
    /// The same per kind group of the model's barriers.
    pub lowest_by_kind: LowestByKind,
    /// Time from the first tick to the stop \[s\].
    pub elapsed: f64,
    /// Largest software time of one tick (mapping, prediction, controller, tensions) \[s\].
    pub max_compute: f64,
    /// Largest age of a reading when its command reached the servos \[s\].
    pub max_age: f64,
    /// Ticks whose prediction failed (the command then used the state read).
    pub prediction_failures: u64,
    /// Per servo (bus order): whether its torque-off was confirmed at the stop.
    pub torque_off: Vec<(u8, bool)>,
    /// The round trip measured at the start (`None`: the run stopped before).
    pub bus_timing: Option<BusTiming>,
    /// The loop rate run at, asked or chosen from the bus (`None`: not decided).
    pub rate_choice: Option<RateChoice>,
    /// The identification experiment's design and counts (`None`: a run toward a set
    /// point, or stopped before the experiment was built).
    pub experiment: Option<ExperimentReport>,
}

impl RunSummary {
    /// Ticks per second reached.
    pub fn rate(&self) -> f64 {
        if self.elapsed > 0.0 {
            self.ticks as f64 / self.elapsed
        } else {
            0.0
        }
    }

    /// What the run did, for its verdict ([`crate::verdict::judge`]): ticks are those
    /// with a command computed from a fresh reading; a reading outside the model's domain
    /// is its lowest barrier `-∞`; deadlines over the ticks, holds over the commands.
    pub fn outcome(&self) -> Outcome<'_> {
        let b = &self.min_barrier;
        Outcome {
            ticks: self.commands,
            lowest: Lowest {
                value: b.value,
                label: b.label,
                unit: b.unit,
                t: b.t,
            },
            invalid_rows: 0,
            rows: self.ticks,
            invalid_ticks: self.invalid,
            failed_ticks: self.fallbacks.saturating_sub(self.invalid),
            unfiltered_ticks: self.unfiltered,
            relaxed_ticks: self.relaxed,
            stopped: None,
            overruns: Some(Overruns {
                deadlines: self.deadlines.deadline_overruns,
                ticks: self.ticks,
                holds: self.deadlines.hold_overruns,
                commands: self.commands,
            }),
        }
    }

    /// The run's verdict: a fault stop or an unconfirmed torque-off is a
    /// [`Verdict::Fault`]; otherwise [`crate::verdict::judge`] of its
    /// [`outcome`](RunSummary::outcome): no command computed is [`Verdict::NotRun`]; a
    /// lowest barrier below the threshold, a tick that fell back to the zero command or ran
    /// without the filter, or overruns beyond the fraction of `limits` are
    /// [`Verdict::Unsafe`].
    pub fn verdict(&self, limits: &Limits) -> Verdict {
        if self.stop.is_fault() {
            return Verdict::Fault(format!("stopped on a fault: {}", self.stop));
        }
        let unconfirmed: Vec<String> = self
            .torque_off
            .iter()
            .filter(|(_, ok)| !ok)
            .map(|(id, _)| id.to_string())
            .collect();
        if !unconfirmed.is_empty() {
            return Verdict::Fault(format!(
                "torque-off not confirmed by servo {} (broadcast sent): check them",
                unconfirmed.join(", ")
            ));
        }
        judge(&self.outcome(), limits)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tick_overruns_when_it_ends_more_than_a_period_after_it_was_due() {
        let mut d = Deadlines::default();
        let due = Instant::now();
        let period = Duration::from_millis(30);
        assert!(!d.tick(due, period, due + Duration::from_millis(29)));
        assert!(!d.tick(due, period, due + period));
        assert!(d.tick(due, period, due + Duration::from_millis(31)));
        assert!(d.tick(due, period, due + Duration::from_millis(200)));
        assert_eq!(d.deadline_overruns, 2);
        assert_eq!(d.hold_overruns, 0);
    }

    #[test]
    fn a_command_overruns_its_hold_when_it_stays_in_force_longer() {
        let mut d = Deadlines::default();
        // Holds of 30 ms: in force 29, 30, 32.5 and 90 ms (two ticks without a reading).
        assert_eq!(d.command(0.029, 0.030), 0.029 - 0.030);
        assert_eq!(d.command(0.030, 0.030), 0.0);
        assert!((d.command(0.0325, 0.030) - 0.0025).abs() < 1e-15);
        assert!((d.command(0.090, 0.030) - 0.060).abs() < 1e-15);
        // A longer hold computed for (a slow loop) covers a longer period.
        assert!(d.command(0.045, 0.050) < 0.0);
        assert_eq!(d.hold_overruns, 2);
        assert!((d.longest_hold_excess - 0.060).abs() < 1e-15);
        assert_eq!(d.longest_period, 0.090);
        assert_eq!(d.deadline_overruns, 0);
    }
}
