//! How a `softcbf run` ended and what it means: the stop reason, the summary of the ticks,
//! and the verdict (safe, unsafe, fault) that becomes the command's exit status.

use crate::hardware::mapping::Clamps;
use crate::hardware::run_loop::RATE_WINDOW;
use crate::protocol::BusCounters;
use crate::sim::{BarrierMinimum, LowestByKind};

/// Why a run ended.
#[derive(Clone, Debug, PartialEq)]
pub enum StopReason {
    /// The duration elapsed.
    Duration,
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
        !matches!(self, StopReason::Duration | StopReason::Interrupted)
    }
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StopReason::Duration => write!(f, "duration elapsed"),
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
    /// Ticks that missed their deadline.
    pub overruns: u64,
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
    /// Longest interval between two commands \[s\].
    pub max_interval: f64,
    /// Ticks whose prediction failed (the command then used the state read).
    pub prediction_failures: u64,
    /// Per servo (bus order): whether its torque-off was confirmed at the stop.
    pub torque_off: Vec<(u8, bool)>,
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

    /// Whether the run was safe: a fault stop or an unconfirmed torque-off is a
    /// [`Verdict::Fault`]; a lowest barrier below `threshold` (in the barrier's unit, \[m\]
    /// for all but bend limits, \[rad\]) or a tick that fell back
    /// to the zero command is [`Verdict::Unsafe`].
    pub fn verdict(&self, threshold: f64) -> Verdict {
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
        let mut reasons = Vec::new();
        let b = &self.min_barrier;
        if b.value < threshold {
            reasons.push(format!(
                "lowest barrier {:.3e} {unit} ({}, t = {:.3} s) is below the threshold \
                 {threshold:e} {unit} (--barrier-threshold)",
                b.value,
                b.label,
                b.t,
                unit = b.unit
            ));
        }
        if self.fallbacks > 0 {
            reasons.push(format!(
                "{} ticks fell back to the zero command ({} with an invalid state, {} failed QPs)",
                self.fallbacks,
                self.invalid,
                self.fallbacks - self.invalid
            ));
        }
        if reasons.is_empty() {
            Verdict::Safe
        } else {
            Verdict::Unsafe(reasons.join("; "))
        }
    }
}

/// What a run's outcome means for the robot.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// It stopped as asked, every barrier above the threshold, every tick valid.
    Safe,
    /// It stopped as asked, but a barrier fell below the threshold or ticks were invalid.
    Unsafe(String),
    /// It stopped on a fault.
    Fault(String),
}
