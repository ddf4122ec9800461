//! One verdict per run, whichever command computes it: `softcbf simulate`, `verify` (each
//! row of a batch), `verify replay` and `run` describe what a run did as an [`Outcome`] and
//! ask [`judge`] whether it was safe. The verdict depends on what happened (the lowest
//! barrier, ticks with an invalid state, without a verified command, without the filter
//! or whose barrier rows were relaxed, rows whose barriers were not numbers, a run that
//! stopped early, missed deadlines), never on which safety mode or command produced it.
//!
//! A hardware run can also end on a fault (communication lost, a servo's error, a
//! torque-off not confirmed): `softcbf::hardware::run_outcome` decides those first and
//! gives the rest of its verdict to [`judge`].

use crate::exit;

/// The lowest barrier a run reached over its valid rows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lowest<'a> {
    /// Its value (m, or rad for a bend limit): `+∞` when no row was valid, `−∞` when the
    /// caller folds invalid states into it (a `runs.csv` row does).
    pub value: f64,
    /// Which barrier (`module 1 corner 3`).
    pub label: &'a str,
    /// Its unit (`m`, `rad`; empty when unknown).
    pub unit: &'a str,
    /// When \[s\].
    pub t: f64,
}

/// Missed deadlines of a run on hardware (a simulation keeps every deadline).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Overruns {
    /// Ticks that ended more than a period after they were due, of `ticks`.
    pub deadlines: u64,
    pub ticks: u64,
    /// Commands in force longer than the hold they were computed for, of `commands`.
    pub holds: u64,
    pub commands: u64,
}

/// What a run did, as far as its safety goes.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome<'a> {
    /// Ticks whose command was computed (from a state; on hardware, from a fresh reading).
    pub ticks: u64,
    /// The lowest barrier over the rows whose barriers were all numbers.
    pub lowest: Lowest<'a>,
    /// Recorded rows whose barriers were not all numbers (a state outside the model's
    /// domain), and the rows recorded.
    pub invalid_rows: u64,
    pub rows: u64,
    /// Ticks whose state was invalid (non-finite, outside the model's domain, `M` not
    /// positive definite): the zero command was applied.
    pub invalid_ticks: u64,
    /// Ticks whose QP had no verified solution: the zero command was applied.
    pub failed_ticks: u64,
    /// Ticks run without the safety filter (plain PD+).
    pub unfiltered_ticks: u64,
    /// Ticks whose QP relaxed barrier rows: their rows had no common point, so the command
    /// applied did not satisfy them all (unsafe: "safe" means every tick was filtered).
    pub relaxed_ticks: u64,
    /// Why the run ended before its duration (a failed plant integration), if it did.
    pub stopped: Option<&'a str>,
    /// Missed deadlines (`None`: a simulation).
    pub overruns: Option<Overruns>,
}

/// What decides a verdict, besides the outcome.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// A lowest barrier below this is unsafe (m, or rad for a bend limit).
    pub threshold: f64,
    /// The fraction of ticks that may overrun their deadline, and of commands that may
    /// overrun their hold, before the run is unsafe (hardware; 0 to 1).
    pub max_overrun_fraction: f64,
}

impl Limits {
    /// `threshold` with the default overrun fraction ([`DEFAULT_MAX_OVERRUN_FRACTION`]).
    pub fn new(threshold: f64) -> Limits {
        Limits {
            threshold,
            max_overrun_fraction: DEFAULT_MAX_OVERRUN_FRACTION,
        }
    }
}

/// The fraction of deadlines (and of holds) a hardware run may miss and still be safe:
/// one tick in twenty.
pub const DEFAULT_MAX_OVERRUN_FRACTION: f64 = 0.05;

/// What a run's outcome means.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Done, every tick filtered with a verified command on a valid state and every barrier
    /// row met (none relaxed), every barrier above the threshold, deadlines kept.
    Safe,
    /// Done, but not safe; the reasons, joined by `; `.
    Unsafe(String),
    /// Nothing to judge: the run completed no tick.
    NotRun(String),
    /// A hardware run stopped on a fault.
    Fault(String),
}

impl Verdict {
    /// The exit status this verdict gives ([`crate::exit`]).
    pub fn status(&self) -> u8 {
        match self {
            Verdict::Safe => exit::OK,
            Verdict::Unsafe(_) => exit::UNSAFE,
            Verdict::NotRun(_) => exit::ERROR,
            Verdict::Fault(_) => exit::FAULT,
        }
    }

    /// `safe`, `UNSAFE: why`, `NOT RUN: why`, `FAULT: why` (the `verdict:` line).
    pub fn line(&self) -> String {
        match self {
            Verdict::Safe => "safe".into(),
            Verdict::Unsafe(why) => format!("UNSAFE: {why}"),
            Verdict::NotRun(why) => format!("NOT RUN: {why}"),
            Verdict::Fault(why) => format!("FAULT: {why}"),
        }
    }

    /// Whether the run was safe.
    pub fn is_safe(&self) -> bool {
        *self == Verdict::Safe
    }

    /// [`Verdict::line`] for a run of which `unproven` of `ticks` ticks were not proven over
    /// their hold (the certified mode's uncertified ticks): a safe run says it was measured
    /// so and that the guarantee leaves those ticks out (the status is the verdict's).
    pub fn line_with_unproven(&self, unproven: usize, ticks: usize) -> String {
        if self.is_safe() && unproven > 0 {
            format!(
                "safe (measured: {unproven} of {ticks} ticks were not proven over their hold, \
                 and the guarantee does not cover those; docs/model.md §5)"
            )
        } else {
            self.line()
        }
    }
}

/// The percentage `part / whole` with one decimal.
fn percent(part: u64, whole: u64) -> String {
    format!("{:.1} %", 100.0 * part as f64 / whole.max(1) as f64)
}

/// The verdict on `outcome` under `limits`: [`Verdict::NotRun`] without a tick, else
/// [`Verdict::Unsafe`] with every reason that applies, else [`Verdict::Safe`].
pub fn judge(outcome: &Outcome<'_>, limits: &Limits) -> Verdict {
    if outcome.ticks == 0 {
        return Verdict::NotRun(
            "no tick completed: no command was computed from a state, so nothing was kept \
             safe"
                .into(),
        );
    }
    let mut reasons = Vec::new();
    let b = &outcome.lowest;
    if b.value < limits.threshold || b.value.is_nan() {
        let unit = if b.unit.is_empty() {
            String::new()
        } else {
            format!(" {}", b.unit)
        };
        reasons.push(format!(
            "lowest barrier {:.3e}{unit} ({}, t = {:.3} s) is below the threshold {:e}{unit} \
             (--barrier-threshold)",
            b.value, b.label, b.t, limits.threshold
        ));
    }
    if outcome.invalid_rows > 0 {
        reasons.push(format!(
            "{} of {} recorded rows have an invalid state (outside the model's domain: no \
             barrier value)",
            outcome.invalid_rows, outcome.rows
        ));
    }
    if outcome.invalid_ticks + outcome.failed_ticks > 0 {
        reasons.push(format!(
            "{} ticks fell back to the zero command ({} with an invalid state, {} failed QPs)",
            outcome.invalid_ticks + outcome.failed_ticks,
            outcome.invalid_ticks,
            outcome.failed_ticks
        ));
    }
    if outcome.unfiltered_ticks > 0 {
        reasons.push(format!(
            "{} of {} ticks ran without the safety filter (plain PD+): nothing kept the \
             barriers",
            outcome.unfiltered_ticks, outcome.ticks
        ));
    }
    if outcome.relaxed_ticks > 0 {
        reasons.push(format!(
            "{} of {} ticks relaxed barrier rows (the rows had no common point: the command \
             applied did not meet them all)",
            outcome.relaxed_ticks, outcome.ticks
        ));
    }
    if let Some(why) = outcome.stopped {
        reasons.push(format!("the run stopped early: {why}"));
    }
    if let Some(o) = &outcome.overruns {
        let most = limits.max_overrun_fraction;
        let beyond = |part: u64, whole: u64| part as f64 > most * whole as f64;
        if beyond(o.deadlines, o.ticks) {
            reasons.push(format!(
                "{} of {} ticks overran their deadline ({}, more than \
                 --max-overrun-fraction {most}): the loop did not keep the period the \
                 guarantee is computed for",
                o.deadlines,
                o.ticks,
                percent(o.deadlines, o.ticks)
            ));
        }
        if beyond(o.holds, o.commands) {
            reasons.push(format!(
                "{} of {} commands stayed in force longer than the hold they were computed \
                 for ({}, more than --max-overrun-fraction {most})",
                o.holds,
                o.commands,
                percent(o.holds, o.commands)
            ));
        }
    }
    if reasons.is_empty() {
        Verdict::Safe
    } else {
        Verdict::Unsafe(reasons.join("; "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn safe_outcome() -> Outcome<'static> {
        Outcome {
            ticks: 100,
            lowest: Lowest {
                value: 1e-3,
                label: "module 1 corner 1",
                unit: "m",
                t: 0.5,
            },
            invalid_rows: 0,
            rows: 100,
            invalid_ticks: 0,
            failed_ticks: 0,
            unfiltered_ticks: 0,
            relaxed_ticks: 0,
            stopped: None,
            overruns: None,
        }
    }

    /// A safe run with unproven ticks says so; other verdicts are left as they are.
    #[test]
    fn a_safe_line_names_the_ticks_not_proven() {
        assert_eq!(Verdict::Safe.line_with_unproven(0, 331), "safe");
        let line = Verdict::Safe.line_with_unproven(227, 331);
        assert!(
            line.starts_with("safe (measured: 227 of 331 ticks were not proven"),
            "{line}"
        );
        let unsafe_run = Verdict::Unsafe("lowest barrier −1 mm".into());
        assert_eq!(unsafe_run.line_with_unproven(227, 331), unsafe_run.line());
    }

    #[test]
    fn every_way_of_being_unsafe_is_named() {
        let limits = Limits::new(-1e-3);
        assert_eq!(judge(&safe_outcome(), &limits), Verdict::Safe);
        type Change = dyn Fn(&mut Outcome<'static>);
        let cases: [(&Change, &str); 8] = [
            (&|o| o.lowest.value = -2e-3, "lowest barrier -2.000e-3 m"),
            (
                &|o| o.lowest.value = f64::NEG_INFINITY,
                "lowest barrier -inf",
            ),
            (&|o| o.lowest.value = f64::NAN, "lowest barrier NaN"),
            (
                &|o| o.invalid_rows = 7,
                "7 of 100 recorded rows have an invalid",
            ),
            (
                &|o| o.invalid_ticks = 2,
                "2 ticks fell back to the zero command (2 with",
            ),
            (
                &|o| o.failed_ticks = 1,
                "(0 with an invalid state, 1 failed QPs)",
            ),
            (
                &|o| o.unfiltered_ticks = 100,
                "100 of 100 ticks ran without",
            ),
            (
                &|o| o.relaxed_ticks = 3,
                "3 of 100 ticks relaxed barrier rows",
            ),
        ];
        for (change, words) in cases {
            let mut outcome = safe_outcome();
            change(&mut outcome);
            let verdict = judge(&outcome, &limits);
            assert_eq!(verdict.status(), exit::UNSAFE, "{words}");
            assert!(verdict.line().contains(words), "{words}: {verdict:?}");
        }
        let mut stopped = safe_outcome();
        stopped.stopped = Some("plant integration failed");
        assert!(judge(&stopped, &limits).line().contains("stopped early"));
    }

    #[test]
    fn a_run_without_a_tick_is_not_a_success() {
        let mut outcome = safe_outcome();
        outcome.ticks = 0;
        let verdict = judge(&outcome, &Limits::new(-1e-3));
        assert!(matches!(verdict, Verdict::NotRun(_)), "{verdict:?}");
        assert_eq!(verdict.status(), exit::ERROR);
    }

    #[test]
    fn overruns_beyond_the_fraction_are_unsafe() {
        let mut limits = Limits::new(-1e-3);
        let mut outcome = safe_outcome();
        // 5 of 100 deadlines: at the default fraction, not beyond it.
        outcome.overruns = Some(Overruns {
            deadlines: 5,
            ticks: 100,
            holds: 0,
            commands: 100,
        });
        assert_eq!(judge(&outcome, &limits), Verdict::Safe);
        outcome.overruns = Some(Overruns {
            deadlines: 199,
            ticks: 199,
            holds: 0,
            commands: 199,
        });
        let verdict = judge(&outcome, &limits);
        assert!(
            verdict
                .line()
                .contains("199 of 199 ticks overran their deadline (100.0 %"),
            "{verdict:?}"
        );
        // Settable: every overrun allowed.
        limits.max_overrun_fraction = 1.0;
        assert_eq!(judge(&outcome, &limits), Verdict::Safe);
        limits.max_overrun_fraction = 0.0;
        outcome.overruns = Some(Overruns {
            deadlines: 0,
            ticks: 100,
            holds: 1,
            commands: 100,
        });
        assert!(
            judge(&outcome, &limits)
                .line()
                .contains("1 of 100 commands")
        );
    }
}
