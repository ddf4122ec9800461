//! What `softcbf run` logs: one [`Row`] per tick into a [`RunLog`], streamed to
//! `trajectory.csv` (the `simulate` columns plus [`extra_columns`]), then the figures.

use std::fs::File;
use std::path::{Path, PathBuf};

use crate::model::Model;
use crate::plot::draw_figures;
use crate::record::{Columns, CsvWriter, Record, Row};
use crate::sim::barriers_per_module;

/// Where the loop writes its rows; flushed at every stop.
pub trait RunLog {
    /// Appends one row.
    fn push(&mut self, row: &Row<'_>) -> Result<(), String>;
    /// Writes everything buffered.
    fn flush(&mut self) -> Result<(), String>;
}

/// Names of the extra log columns for `servos` servos and `nq` coordinates: `fresh` (1: command from this
/// tick's reading), `status` (−1 no reading, 0 unfiltered, 1 filtered, 2 relaxed, 3 QP
/// failed, 4 invalid state), `attempts` (sync reads), `comm_errors` (held ticks in a row),
/// `read_us`, `compute_us`, `write_us` (bus wait, software, write), `late_us` (start after
/// schedule), `overrun` (0/1), `clamp_low`, `clamp_high`, `age_us` (age of the reading when
/// the command reaches the servos), `period_us` (time since the previous command), `hold_us`
/// (the hold period the controller assumed), `gain_scale` (the factor of the HOCBF gains,
/// `nominal period / hold_us`), then `f0…` (tensions sent \[N\]), then `qpred0…` (the `q`
/// the command was computed at: the state read, predicted `age_us` ahead). `q`, `q̇` and
/// `b` are at the state read.
pub fn extra_columns(servos: usize, nq: usize) -> Vec<String> {
    let mut names: Vec<String> = [
        "fresh",
        "status",
        "attempts",
        "comm_errors",
        "read_us",
        "compute_us",
        "write_us",
        "late_us",
        "overrun",
        "clamp_low",
        "clamp_high",
        "age_us",
        "period_us",
        "hold_us",
        "gain_scale",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    names.extend((0..servos).map(|k| format!("f{k}")));
    names.extend((0..nq).map(|k| format!("qpred{k}")));
    names
}

/// Number of extra columns before the tensions.
pub const FIXED_EXTRA: usize = 15;

/// The streaming CSV log of a run.
pub struct CsvLog {
    writer: CsvWriter<File>,
    path: PathBuf,
}

impl RunLog for CsvLog {
    fn push(&mut self, row: &Row<'_>) -> Result<(), String> {
        self.writer.push_row(row).map_err(|e| e.to_string())
    }

    fn flush(&mut self) -> Result<(), String> {
        self.writer.flush().map_err(|e| e.to_string())
    }
}

/// Creates `dir/trajectory.csv` for a run of `model` on `servos` servos.
pub fn open(dir: &Path, model: &Model, servos: usize) -> Result<CsvLog, String> {
    let names = extra_columns(servos, model.nq());
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let columns = Columns::new(model.nq(), model.nb(), &names).map_err(|e| e.to_string())?;
    let path = dir.join("trajectory.csv");
    let writer = CsvWriter::create(&path, columns).map_err(|e| e.to_string())?;
    Ok(CsvLog { writer, path })
}

/// Closes the log, reads it back and draws the figures beside it; returns the files.
pub fn finish(
    log: CsvLog,
    dir: &Path,
    filter: bool,
    set_point: &[f64],
    model: &Model,
) -> Result<Vec<PathBuf>, String> {
    let CsvLog { writer, path } = log;
    writer.finish().map_err(|e| e.to_string())?;
    let record = Record::read_csv(&path).map_err(|e| e.to_string())?;
    let title = if filter {
        "safety filter (HOCBF-QP), hardware"
    } else {
        "PD+ only, hardware"
    };
    let mut files = vec![path];
    if record.is_empty() {
        return Ok(files);
    }
    files.extend(
        draw_figures(
            dir,
            "figure",
            &[(title, &record)],
            set_point,
            &barriers_per_module(model.generated.barrier_table(), model.n_modules()),
        )
        .map_err(|e| e.to_string())?,
    );
    Ok(files)
}
