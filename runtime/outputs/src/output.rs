//! What `softcbf simulate` leaves behind and shows: trajectory CSVs, `summary.json`, the
//! figures, a progress bar on a terminal and the one-line summary; and the output
//! directory every command that writes files creates.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};

use serde_json::json;

use crate::model::Model;
use crate::plot::{FigureOptions, write_figures};
use crate::sim::{Run, RunSummary, barriers_per_module};

/// The hardware description a hardware log was taken with, beside its `trajectory.csv`
/// (written by `softcbf run`, read by identification and the MCAP log).
pub const HARDWARE_DESCRIPTION_FILE: &str = "hardware.json";

/// Why outputs could not be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The output directory or a file in it could not be written.
    #[error("{path}: {source}", path = path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A trajectory could not be written.
    #[error(transparent)]
    Record(#[from] crate::record::RecordError),
    /// The figures could not be drawn.
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
}

/// Creates `dir` for a run's outputs (any command's `--out`, named `option` in the
/// error); refuses a path that is a file.
pub fn output_directory(dir: &Path, option: &str) -> Result<(), String> {
    if dir.exists() && !dir.is_dir() {
        return Err(format!(
            "{option}: {} is a file, not a directory; give a directory for the outputs",
            dir.display()
        ));
    }
    std::fs::create_dir_all(dir)
        .map_err(|e| format!("{option}: cannot create {}: {e}", dir.display()))
}

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> OutputError + '_ {
    move |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes `trajectory.csv` (the main run), `trajectory_pd.csv` (the comparison, if any),
/// `summary.json` and the figures into `out_dir` (created if needed): `figure.png` /
/// `figure.svg`, the 3-D view `robot.png` / `robot.svg` of `model`, and with `animate` the
/// animation `robot.gif` ([`crate::plot::write_figures`]). Returns the paths written.
pub fn write_outputs(
    out_dir: &Path,
    main: &Run,
    comparison: Option<&Run>,
    model: &Model,
    animate: bool,
) -> Result<Vec<PathBuf>, OutputError> {
    std::fs::create_dir_all(out_dir).map_err(io_error(out_dir))?;
    let mut written = Vec::new();
    let trajectory = out_dir.join("trajectory.csv");
    main.record.write_csv(&trajectory)?;
    written.push(trajectory);
    if let Some(pd) = comparison {
        let path = out_dir.join("trajectory_pd.csv");
        pd.record.write_csv(&path)?;
        written.push(path);
    }

    let summary = summary_value(main, comparison);
    let summary_path = out_dir.join("summary.json");
    let text = serde_json::to_string_pretty(&json!(summary)).unwrap_or_default() + "\n";
    std::fs::write(&summary_path, text).map_err(io_error(&summary_path))?;
    written.push(summary_path);

    let title = |summary: &RunSummary| crate::plot::controller_title(summary.controller);
    let mut panels = vec![(title(&main.summary), &main.record)];
    if let Some(pd) = comparison {
        panels.push((title(&pd.summary), &pd.record));
    }
    let per_module = barriers_per_module(model.generated.barrier_table(), model.n_modules());
    let options = FigureOptions {
        barriers_per_module: &per_module,
        model: Some(model),
        animate,
        ..FigureOptions::default()
    };
    written.extend(write_figures(
        out_dir,
        &panels,
        &main.summary.set_point,
        &options,
    )?);
    Ok(written)
}

/// What `summary.json` holds: the summary of `main`, with the PD+ comparison's under
/// `comparison`.
pub fn summary_value(main: &Run, comparison: Option<&Run>) -> serde_json::Value {
    let mut summary = serde_json::to_value(&main.summary).unwrap_or_default();
    if let (Some(pd), Some(object)) = (comparison, summary.as_object_mut()) {
        object.insert(
            "comparison".to_string(),
            serde_json::to_value(&pd.summary).unwrap_or_default(),
        );
    }
    summary
}

/// The one line printed at the end of a run; for a robot with barriers of more than one
/// kind group it names the lowest of each ([`crate::sim::LowestByKind::line`]). A run
/// recorded between ticks says so after its lowest barrier: `(dense, every 1 ms)`.
pub fn one_line(summary: &RunSummary) -> String {
    let counts = &summary.counts;
    let dense = match summary.record_period {
        Some(period) if summary.dense => {
            format!(" (dense, every {})", crate::settings::period_text(period))
        }
        _ => String::new(),
    };
    let b = &summary.min_barrier;
    let valid = format!("{:.3e} {} ({}, t = {:.3} s)", b.value, b.unit, b.label, b.t);
    // Rows with an invalid state have no barrier value: the lowest over the others alone
    // would read as a margin the run did not keep.
    let lowest = match summary.invalid_rows {
        0 => valid,
        n if n >= summary.rows => format!(
            "none: all {n} recorded rows have an invalid state (outside the model's domain)"
        ),
        n => format!(
            "none at {n} of {} recorded rows (an invalid state, outside the model's domain); \
             {valid} over the others",
            summary.rows
        ),
    };
    let mut line = format!(
        "{} on {} [{}]: {:.3} s simulated in {:.3} s ({:.0}× real time); lowest barrier\
         {dense} {lowest}; set-point error {:.4} m; max |τ| {:.3} N",
        summary.scenario,
        summary.robot,
        summary.controller,
        summary.duration,
        summary.wall_time,
        summary.real_time_factor,
        summary.set_point_error,
        summary.max_abs_tau,
    );
    if let Some(per_kind) = summary.lowest_by_kind.line() {
        line += &format!("; {per_kind}");
    }
    if counts.qp_solves > 0 {
        line += &format!(
            "; {} QP solves ({} with active barriers, {} relaxed, {} failed)",
            counts.qp_solves, counts.active, counts.relaxed, counts.failed
        );
        if counts.uncertified > 0 {
            // The certified mode's ticks whose bound did not close: filtered, not proven.
            line += &format!(
                "; {} of {} ticks not proven over their hold (the prediction's rows alone; {})",
                counts.uncertified,
                counts.ticks,
                counts.uncertified_reasons.describe()
            );
        }
    }
    if counts.invalid_state > 0 {
        line += &format!("; {} ticks with an invalid state", counts.invalid_state);
    }
    if let Some(why) = &summary.stopped {
        line += &format!("; STOPPED EARLY: {why}");
    }
    line
}

/// Standard output for the command's lines, never a panic: each line is written and
/// flushed at once. Once a write fails, because the reader has gone (a closed pipe,
/// `softcbf … | head`) or for any other reason (a full disk, `> /dev/full`, a lost
/// terminal), later lines are dropped and the failure is kept for [`Console::error`]: the
/// output was not all written, which the exit status says. The work goes on either way: a
/// hardware run still stops safely and writes its log.
#[derive(Debug, Default)]
pub struct Console {
    closed: bool,
    error: Option<String>,
}

impl Console {
    /// A console on standard output.
    pub fn new() -> Console {
        Console::default()
    }

    /// Prints one line.
    pub fn say(&mut self, text: &str) {
        if self.closed {
            return;
        }
        let mut out = std::io::stdout().lock();
        let written = writeln!(out, "{text}").and_then(|()| out.flush());
        if let Err(error) = written {
            self.closed = true;
            self.error = Some(if error.kind() == std::io::ErrorKind::BrokenPipe {
                "cannot write standard output: its reader closed it (a pipe such as `| head`), \
                 the lines after that were lost"
                    .to_string()
            } else {
                format!("cannot write standard output: {error}")
            });
        }
    }

    /// The first failure to write, a reader that went away included.
    pub fn error(&self) -> Option<&str> {
        self.error.as_deref()
    }
}

/// A progress bar on standard error, drawn only when it is a terminal.
pub struct Progress {
    label: String,
    enabled: bool,
    last: usize,
}

impl Progress {
    /// A bar labelled `label`; silent unless standard error is a terminal.
    pub fn new(label: &str) -> Progress {
        Progress {
            label: label.to_string(),
            enabled: std::io::stderr().is_terminal(),
            last: usize::MAX,
        }
    }

    /// Shows `fraction` ∈ [0, 1] done.
    pub fn update(&mut self, fraction: f64) {
        if !self.enabled {
            return;
        }
        let percent = (fraction.clamp(0.0, 1.0) * 100.0).round() as usize;
        if percent == self.last {
            return;
        }
        self.last = percent;
        let width = 40;
        let filled = percent * width / 100;
        let bar: String = (0..width)
            .map(|k| if k < filled { '#' } else { '.' })
            .collect();
        let mut stderr = std::io::stderr().lock();
        let _ = write!(stderr, "\r{:<12} [{bar}] {percent:>3}%", self.label);
        if percent == 100 {
            let _ = writeln!(stderr);
        }
        let _ = stderr.flush();
    }
}
