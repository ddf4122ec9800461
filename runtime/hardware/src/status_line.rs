//! The live status line of `softcbf run` on a terminal: loop rate, lowest barrier, QP and
//! bus fault counts, deadline overruns, redrawn a few times a second from the logged rows;
//! and an experiment's progress, a line on standard output per step.
//!
//! It wraps the run's log ([`RunLog`]): every row goes to the log first, then updates the
//! counts; drawing happens at most every [`REDRAW`] and only when standard error is a
//! terminal. An experiment's step lines ([`ExperimentProgress`]) are printed whatever the
//! output is, when the log's `step` column moves on. Nothing here touches the bus or the
//! controller.

use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

use crate::experiment::ExperimentKind;
use crate::log::{Extra, RunLog};
use crate::output::Console;
use crate::record::Row;

/// Least time between two redraws.
pub const REDRAW: Duration = Duration::from_millis(250);

/// Index of the `status` extra column (−1 no reading, 0 unfiltered, 1 filtered, 2 relaxed,
/// 3 QP failed, 4 invalid state; [`crate::log::extra_columns`]).
const STATUS: usize = Extra::Status.at();
/// Index of the `attempts` extra column (sync reads this tick).
const ATTEMPTS: usize = Extra::Attempts.at();
/// Index of the `overrun` extra column (1: a deadline overrun).
const OVERRUN: usize = Extra::Overrun.at();
/// Index of the `step` extra column (an experiment's step; NaN in a plain run).
const STEP: usize = Extra::Step.at();
/// Index of the `rest` extra column (1: a row of a static step's rest state).
const REST: usize = Extra::Rest.at();

/// What the progress lines know of an experiment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExperimentProgress {
    /// Static or dynamic.
    pub kind: ExperimentKind,
    /// Steps planned.
    pub steps: usize,
    /// How long a step takes \[s\]: a dynamic operating point's share of the length; the
    /// least a static set takes (held, then its rest window).
    pub step_length: f64,
}

/// Where an experiment is, as the logged rows tell.
#[derive(Clone, Copy, Debug, PartialEq)]
struct StepTracker {
    plan: ExperimentProgress,
    /// The step of the last row, when it began \[s\], and its rest rows.
    step: Option<usize>,
    began: f64,
    rest_rows: u64,
    /// The first row's time \[s\].
    start: Option<f64>,
}

impl StepTracker {
    /// The line for the step just ended (at time `t`), if one did.
    fn ended(&self, t: f64, last: bool) -> Option<String> {
        let step = self.step?;
        let plan = &self.plan;
        let left_steps = plan.steps.saturating_sub(step + 1);
        let left = if last || left_steps == 0 {
            String::new()
        } else {
            let prefix = match plan.kind {
                ExperimentKind::Static => "at least ",
                ExperimentKind::Dynamic => "",
            };
            format!(
                "; {left_steps} to go, {prefix}{:.0} s",
                left_steps as f64 * plan.step_length
            )
        };
        let held = t - self.began;
        Some(match plan.kind {
            ExperimentKind::Static if self.rest_rows > 0 => format!(
                "experiment: step {} of {}: at rest, {} rows logged ({held:.1} s){left}",
                step + 1,
                plan.steps,
                self.rest_rows
            ),
            ExperimentKind::Static if last => format!(
                "experiment: step {} of {}: not at rest when the run stopped ({held:.1} s)",
                step + 1,
                plan.steps
            ),
            ExperimentKind::Static => format!(
                "experiment: step {} of {}: no rest within {held:.1} s{left}",
                step + 1,
                plan.steps
            ),
            ExperimentKind::Dynamic => format!(
                "experiment: operating point {} of {} done (t = {:.1} s){left}",
                step + 1,
                plan.steps,
                t - self.start.unwrap_or(t)
            ),
        })
    }

    /// Adds a row; the line of a step that ended with it.
    fn add(&mut self, row: &Row<'_>) -> Option<String> {
        let step = row.extra.get(STEP).copied().unwrap_or(f64::NAN);
        if step.is_nan() || step < 0.0 {
            return None;
        }
        let step = step as usize;
        self.start.get_or_insert(row.t);
        let mut line = None;
        if self.step != Some(step) {
            line = self.ended(row.t, false);
            self.step = Some(step);
            self.began = row.t;
            self.rest_rows = 0;
        }
        if row.extra.get(REST).copied() == Some(1.0) {
            self.rest_rows += 1;
        }
        line
    }
}

/// Counts shown on the status line.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StatusCounts {
    /// Ticks logged.
    pub ticks: u64,
    /// Ticks without a fresh reading of every servo (nothing new sent).
    pub held: u64,
    /// Sync reads repeated within a tick.
    pub retries: u64,
    /// QPs whose barrier rows had to be relaxed.
    pub relaxed: u64,
    /// QPs without a verified solution (zero command).
    pub failed: u64,
    /// Ticks with a state outside the model (zero command).
    pub invalid: u64,
    /// Ticks that ended more than a period after they were due.
    pub overruns: u64,
    /// Lowest barrier read so far \[m\] (infinite before the first reading).
    pub lowest: f64,
    /// Loop rate over the last redraw interval \[Hz\].
    pub rate: f64,
}

impl StatusCounts {
    /// Counts before any row.
    pub fn new() -> StatusCounts {
        StatusCounts {
            lowest: f64::INFINITY,
            ..StatusCounts::default()
        }
    }

    /// Adds one logged row.
    pub fn add(&mut self, row: &Row<'_>) {
        self.ticks += 1;
        let status = row.extra.get(STATUS).copied().unwrap_or(f64::NAN);
        match status as i64 {
            -1 => self.held += 1,
            2 => self.relaxed += 1,
            3 => self.failed += 1,
            4 => self.invalid += 1,
            _ => {}
        }
        let attempts = row.extra.get(ATTEMPTS).copied().unwrap_or(0.0);
        if attempts > 1.0 {
            self.retries += attempts as u64 - 1;
        }
        if row.extra.get(OVERRUN).copied() == Some(1.0) {
            self.overruns += 1;
        }
        for &b in row.b {
            // NaN (no reading) never lowers the minimum.
            if b < self.lowest {
                self.lowest = b;
            }
        }
    }

    /// The line, e.g. `t 12.3 s  33.0 Hz  lowest barrier +1.234 mm  QP: 0 relaxed, 0 failed,
    /// 0 invalid  bus: 2 held, 1 retries  overruns: 0`.
    pub fn line(&self, t: f64) -> String {
        let lowest = if self.lowest.is_finite() {
            format!("{:+.3} mm", self.lowest * 1e3)
        } else {
            "—".to_string()
        };
        format!(
            "t {t:.1} s  {:.1} Hz  lowest barrier {lowest}  QP: {} relaxed, {} failed, {} \
             invalid  bus: {} held, {} retries  overruns: {}",
            self.rate,
            self.relaxed,
            self.failed,
            self.invalid,
            self.held,
            self.retries,
            self.overruns
        )
    }
}

/// A [`RunLog`] that also keeps [`StatusCounts`] and draws them on standard error.
pub struct StatusLine<L: RunLog> {
    inner: L,
    counts: StatusCounts,
    enabled: bool,
    last_draw: Option<(Instant, u64)>,
    drawn: bool,
    experiment: Option<StepTracker>,
    /// The last row's time \[s\].
    last_t: f64,
    console: Console,
}

impl<L: RunLog> StatusLine<L> {
    /// Wraps `inner`; draws only when `enabled` and standard error is a terminal.
    pub fn new(inner: L, enabled: bool) -> StatusLine<L> {
        StatusLine {
            inner,
            counts: StatusCounts::new(),
            enabled: enabled && std::io::stderr().is_terminal(),
            last_draw: None,
            drawn: false,
            experiment: None,
            last_t: 0.0,
            console: Console::new(),
        }
    }

    /// Also prints a line on standard output as each step of the experiment `plan` ends,
    /// and shows the step on the status line.
    pub fn with_experiment(mut self, plan: ExperimentProgress) -> StatusLine<L> {
        self.experiment = Some(StepTracker {
            plan,
            step: None,
            began: 0.0,
            rest_rows: 0,
            start: None,
        });
        self
    }

    /// The first failure to write a progress line (standard output gone bad).
    pub fn console_error(&self) -> Option<&str> {
        self.console.error()
    }

    /// Prints a progress line on standard output, the status line cleared first.
    fn say(&mut self, line: &str) {
        if self.drawn {
            let mut stderr = std::io::stderr().lock();
            let _ = write!(stderr, "\r\x1b[K");
            let _ = stderr.flush();
        }
        self.console.say(line);
    }

    /// The counts so far.
    pub fn counts(&self) -> &StatusCounts {
        &self.counts
    }

    /// Ends the line (so that later output starts on a fresh one), prints the last step's
    /// line of an experiment, and returns the log.
    pub fn into_inner(mut self) -> L {
        if let Some(line) = self
            .experiment
            .as_ref()
            .and_then(|e| e.ended(self.last_t, true))
        {
            self.say(&line);
            self.drawn = false;
        }
        if self.drawn {
            let mut stderr = std::io::stderr().lock();
            let _ = writeln!(stderr);
            let _ = stderr.flush();
        }
        self.inner
    }

    fn draw(&mut self, t: f64) {
        let now = Instant::now();
        let Some((then, ticks)) = self.last_draw else {
            self.last_draw = Some((now, self.counts.ticks));
            return;
        };
        let elapsed = now.duration_since(then);
        if elapsed < REDRAW {
            return;
        }
        self.counts.rate = (self.counts.ticks - ticks) as f64 / elapsed.as_secs_f64();
        self.last_draw = Some((now, self.counts.ticks));
        let mut stderr = std::io::stderr().lock();
        // `\r` and clear-to-end-of-line: the line is redrawn in place.
        let step = match &self.experiment {
            Some(StepTracker {
                plan,
                step: Some(step),
                ..
            }) => format!("  step {}/{}", step + 1, plan.steps),
            _ => String::new(),
        };
        let _ = write!(stderr, "\r\x1b[K{}{step}", self.counts.line(t));
        let _ = stderr.flush();
        self.drawn = true;
    }
}

impl<L: RunLog> RunLog for StatusLine<L> {
    fn push(&mut self, row: &Row<'_>) -> Result<(), String> {
        let logged = self.inner.push(row);
        self.counts.add(row);
        self.last_t = row.t;
        if let Some(line) = self.experiment.as_mut().and_then(|e| e.add(row)) {
            self.say(&line);
        }
        if self.enabled {
            self.draw(row.t);
        }
        logged
    }

    fn flush(&mut self) -> Result<(), String> {
        self.inner.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::{FIXED_EXTRA, extra_columns};

    #[test]
    fn the_columns_read_are_the_status_the_attempts_and_the_overrun() {
        let names = extra_columns(6, &crate::record::coordinate_names(6));
        assert_eq!(names[STATUS], "status");
        assert_eq!(names[ATTEMPTS], "attempts");
        assert_eq!(names[OVERRUN], "overrun");
        assert_eq!(names[STEP], "step");
        assert_eq!(names[REST], "rest");
    }

    #[test]
    fn a_line_tells_how_each_step_ended() {
        let mut tracker = StepTracker {
            plan: ExperimentProgress {
                kind: ExperimentKind::Static,
                steps: 3,
                step_length: 2.0,
            },
            step: None,
            began: 0.0,
            rest_rows: 0,
            start: None,
        };
        let q = [0.0; 3];
        let mut extra = [0.0; FIXED_EXTRA];
        let mut lines = Vec::new();
        // (t, step, rest): step 0 comes to rest for two rows, step 1 never does.
        for (t, step, rest) in [
            (0.0, f64::NAN, 0.0),
            (1.0, 0.0, 0.0),
            (2.0, 0.0, 1.0),
            (2.5, 0.0, 1.0),
            (3.0, 1.0, 0.0),
            (9.0, 2.0, 0.0),
            (10.0, 2.0, 1.0),
        ] {
            extra[STEP] = step;
            extra[REST] = rest;
            let row = Row {
                t,
                q: &q,
                qd: &q,
                tau: &q,
                tau_nom: &q,
                b: &q,
                extra: &extra,
            };
            lines.extend(tracker.add(&row));
        }
        lines.extend(tracker.ended(10.5, true));
        assert_eq!(
            lines,
            [
                "experiment: step 1 of 3: at rest, 2 rows logged (2.0 s); 2 to go, at least 4 s",
                "experiment: step 2 of 3: no rest within 6.0 s; 1 to go, at least 2 s",
                "experiment: step 3 of 3: at rest, 1 rows logged (1.5 s)",
            ]
        );
    }

    #[test]
    fn rows_are_counted_by_status_attempts_and_barriers() {
        let mut counts = StatusCounts::new();
        let q = [0.0; 3];
        let mut extra = [0.0; FIXED_EXTRA];
        // (status, attempts, overrun, barrier)
        let rows = [
            (-1.0, 3.0, 1.0, f64::NAN),
            (1.0, 1.0, 0.0, 0.004),
            (2.0, 2.0, 1.0, -0.001),
            (3.0, 1.0, 0.0, 0.002),
            (4.0, 1.0, 0.0, 0.003),
        ];
        for (status, attempts, overrun, b) in rows {
            extra[STATUS] = status;
            extra[ATTEMPTS] = attempts;
            extra[OVERRUN] = overrun;
            counts.add(&Row {
                t: 0.0,
                q: &q,
                qd: &q,
                tau: &q,
                tau_nom: &q,
                b: &[b, 0.01],
                extra: &extra,
            });
        }
        assert_eq!(counts.ticks, 5);
        assert_eq!(
            (counts.held, counts.relaxed, counts.failed, counts.invalid),
            (1, 1, 1, 1)
        );
        assert_eq!(counts.retries, 3);
        assert_eq!(counts.overruns, 2);
        assert_eq!(counts.lowest, -0.001);
        let line = counts.line(1.25);
        assert!(line.contains("lowest barrier -1.000 mm"), "{line}");
        assert!(line.contains("1 relaxed, 1 failed, 1 invalid"), "{line}");
        assert!(line.contains("1 held, 3 retries  overruns: 2"), "{line}");
    }
}
