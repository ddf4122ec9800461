//! What `softcbf run` logs: one [`Row`] per tick into a [`RunLog`], streamed to
//! `trajectory.csv` (the `simulate` columns plus [`extra_columns`]), beside it the hardware
//! description it was taken with (`hardware.json`, [`LogDescription`]), then the figures.

use std::fs::File;
use std::path::{Path, PathBuf};

use crate::hardware_description::Hardware;
use crate::log_description::LogDescription;
use crate::model::Model;
use crate::plot::{FigureOptions, write_figures};
use crate::record::{Columns, CsvWriter, Record, Row, as_strs, coordinate_names};
use crate::sim::barriers_per_module;

/// Where the loop writes its rows; flushed at every stop.
pub trait RunLog {
    /// Appends one row.
    fn push(&mut self, row: &Row<'_>) -> Result<(), String>;
    /// Writes everything buffered.
    fn flush(&mut self) -> Result<(), String>;
}

/// Names of the extra log columns for `servos` servos (servo `3i + k` pulls tendon `k` of
/// module `i`) and the coordinates `coordinates` (as named in the CSV, `dx1`, …), each with
/// its unit in brackets where it has one:
///
/// | column | meaning |
/// |---|---|
/// | `fresh` | 1: the command came from this tick's reading |
/// | `status` | −1 no reading, 0 unfiltered, 1 filtered, 2 relaxed, 3 QP failed, 4 invalid state, 5 uncertified |
/// | `reason` | why an invalid or uncertified tick was (0: no reason; the codes of [`crate::record::status`]) |
/// | `attempts` | sync reads this tick |
/// | `comm_errors` | ticks in a row without a reading (held) |
/// | `read [us]`, `compute [us]`, `write [us]` | bus wait, software, write |
/// | `late [us]` | start after schedule |
/// | `overrun` | 1: a deadline overrun, the tick ended more than a period after it was due |
/// | `clamp_low`, `clamp_high` | tensions clamped at `f_min`, `f_max` this tick |
/// | `age [us]` | age of the reading when the command reaches the servos |
/// | `period [us]` | time since the previous command |
/// | `hold [us]` | the hold period the controller assumed |
/// | `hold_excess [us]` | how much longer than its hold the previous command stayed in force (> 0: a hold overrun; NaN: no command this tick) |
/// | `gain_scale` | the factor of the HOCBF gains, `nominal period / hold` |
/// | `sampled [us]` | how long before `t` the servos sampled the reading (the state's own time is `t − sampled`) |
/// | `step` | the step of an identification experiment (a tension set, or an operating point); NaN in a plain run |
/// | `rest` | 1: a static experiment's step has come to rest, this row's reading is part of its rest state |
/// | `f module i tendon k [N]` | tensions sent |
/// | `qpred <c> [m]` | the `q` the command was computed at: the state read, predicted `age` ahead |
/// | `I module i tendon k [mA]` | the goal current sent (register × unit, signed as the servo's register) |
///
/// `q`, `q̇` and `b` are at the state read; a command reaches the servos `compute + write`
/// after `t`. Logs written before `hold_excess [us]` (or the identification columns
/// `sampled [us]`, `step`, `rest`, `I …`, or `reason`) existed lack them and read as well
/// (columns are found by name).
pub fn extra_columns(servos: usize, coordinates: &[String]) -> Vec<String> {
    let mut names: Vec<String> = Extra::ALL.iter().map(|c| c.name().to_string()).collect();
    names.extend((0..servos).map(|s| format!("f module {} tendon {} [N]", s / 3 + 1, s % 3 + 1)));
    names.extend(coordinates.iter().map(|c| format!("qpred {c} [m]")));
    names.extend(current_columns(servos));
    names
}

/// Names of the goal-current columns of `servos` servos (`I module i tendon k [mA]`).
pub fn current_columns(servos: usize) -> Vec<String> {
    (0..servos)
        .map(|s| format!("I module {} tendon {} [mA]", s / 3 + 1, s % 3 + 1))
        .collect()
}

/// The fixed extra columns of a run's log ([`extra_columns`]), in the order they are
/// written: the one table from which the header, the row (written by position,
/// [`Extra::at`], in `run_loop`) and the readers (`identify` by [`Extra::name`], the
/// status line by position) all come.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Extra {
    Fresh,
    Status,
    Reason,
    Attempts,
    CommErrors,
    Read,
    Compute,
    Write,
    Late,
    Overrun,
    ClampLow,
    ClampHigh,
    Age,
    Period,
    Hold,
    HoldExcess,
    GainScale,
    Sampled,
    Step,
    Rest,
}

impl Extra {
    /// Every fixed extra column, in the order of the log.
    pub const ALL: [Extra; 20] = [
        Extra::Fresh,
        Extra::Status,
        Extra::Reason,
        Extra::Attempts,
        Extra::CommErrors,
        Extra::Read,
        Extra::Compute,
        Extra::Write,
        Extra::Late,
        Extra::Overrun,
        Extra::ClampLow,
        Extra::ClampHigh,
        Extra::Age,
        Extra::Period,
        Extra::Hold,
        Extra::HoldExcess,
        Extra::GainScale,
        Extra::Sampled,
        Extra::Step,
        Extra::Rest,
    ];

    /// Its position among a row's extra values (and after the `simulate` columns of the
    /// header).
    pub const fn at(self) -> usize {
        self as usize
    }

    /// Its name in the header, with its unit in brackets where it has one.
    pub const fn name(self) -> &'static str {
        match self {
            Extra::Fresh => "fresh",
            Extra::Status => crate::record::status::STATUS,
            Extra::Reason => crate::record::status::REASON,
            Extra::Attempts => "attempts",
            Extra::CommErrors => "comm_errors",
            Extra::Read => "read [us]",
            Extra::Compute => "compute [us]",
            Extra::Write => "write [us]",
            Extra::Late => "late [us]",
            Extra::Overrun => "overrun",
            Extra::ClampLow => "clamp_low",
            Extra::ClampHigh => "clamp_high",
            Extra::Age => "age [us]",
            Extra::Period => "period [us]",
            Extra::Hold => "hold [us]",
            Extra::HoldExcess => "hold_excess [us]",
            Extra::GainScale => "gain_scale",
            Extra::Sampled => "sampled [us]",
            Extra::Step => "step",
            Extra::Rest => "rest",
        }
    }
}

/// Number of extra columns before the tensions.
pub const FIXED_EXTRA: usize = Extra::ALL.len();

// The last column closes the table: a column added after it and not to `ALL` is refused.
const _: () = assert!(Extra::Rest.at() + 1 == FIXED_EXTRA);

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

/// Writes `dir/hardware.json`, the description of `model`'s robot driven through
/// `hardware` (with the run's overrides), and creates `dir/trajectory.csv` for the run.
pub fn open(dir: &Path, model: &Model, hardware: &Hardware) -> Result<CsvLog, String> {
    LogDescription::of(&model.robot, hardware)
        .write(dir)
        .map_err(|e| e.to_string())?;
    let servos = 3 * hardware.modules.len();
    let names = extra_columns(servos, &coordinate_names(model.nq()));
    let columns = Columns::for_model(model, &as_strs(&names)).map_err(|e| e.to_string())?;
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
    let per_module = barriers_per_module(model.generated.barrier_table(), model.n_modules());
    let options = FigureOptions {
        barriers_per_module: &per_module,
        model: Some(model),
        ..FigureOptions::default()
    };
    files.extend(
        write_figures(dir, &[(title, &record)], set_point, &options).map_err(|e| e.to_string())?,
    );
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_fixed_column_is_written_and_read_where_the_header_names_it() {
        let names = extra_columns(6, &coordinate_names(6));
        for (k, column) in Extra::ALL.iter().enumerate() {
            assert_eq!(
                column.at(),
                k,
                "{column:?} stands at its place in the table"
            );
            assert_eq!(names[column.at()], column.name(), "{column:?}");
        }
        // The header as the table above lists it: the fixed columns, then tensions,
        // predicted coordinates and currents.
        assert_eq!(names[..4], ["fresh", "status", "reason", "attempts"]);
        assert_eq!(names[FIXED_EXTRA - 1], "rest");
        assert_eq!(names[FIXED_EXTRA], "f module 1 tendon 1 [N]");
        assert_eq!(names[FIXED_EXTRA + 6], "qpred dx1 [m]");
        assert_eq!(names[FIXED_EXTRA + 12], "I module 1 tendon 1 [mA]");
        assert_eq!(names.len(), FIXED_EXTRA + 18);
    }

    /// docs/hardware.md names every column a run log has: each extra column, with the
    /// first and last servo's tension and current and the first coordinate's prediction
    /// standing for their families.
    #[test]
    fn the_docs_list_every_log_column() {
        let docs = include_str!("../../../docs/hardware.md");
        let docs = docs.split_whitespace().collect::<Vec<_>>().join(" ");
        let names = extra_columns(6, &coordinate_names(6));
        let mut missing = Vec::new();
        for name in &names {
            let first_or_last = ["module 1 tendon 1", "module 2 tendon 3"]
                .iter()
                .any(|s| name.contains(s));
            let family = name.starts_with("f module ") || name.starts_with("I module ");
            if (family && !first_or_last) || (name.starts_with("qpred ") && name != "qpred dx1 [m]")
            {
                continue;
            }
            if !docs.contains(&format!("`{name}`")) {
                missing.push(name.clone());
            }
        }
        assert!(
            missing.is_empty(),
            "docs/hardware.md does not list {missing:?}"
        );
    }
}
