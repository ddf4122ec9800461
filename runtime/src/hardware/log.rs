//! Where `softcbf run` writes: `trajectory.csv`, streamed during the run with the columns of
//! `softcbf simulate` plus the timing and clamp columns of [`extra_columns`], and at the end
//! the figures (`figure.png`, `figure.svg`) drawn from it as `simulate` draws its own.

use std::fs::File;
use std::path::{Path, PathBuf};

use crate::hardware::run_loop::{LogRow, RunLog, extra_columns};
use crate::model::Model;
use crate::plot::draw_figures;
use crate::record::{Columns, CsvWriter, Record, Row};

/// The streaming CSV log of a run.
pub struct CsvLog {
    writer: CsvWriter<File>,
    path: PathBuf,
}

impl RunLog for CsvLog {
    fn push(&mut self, row: &LogRow<'_>) -> Result<(), String> {
        let row = Row {
            t: row.t,
            q: row.q,
            qd: row.qd,
            tau: row.tau,
            tau_nom: row.tau_nom,
            b: row.b,
            extra: row.extra,
        };
        self.writer.push_row(&row).map_err(|e| e.to_string())
    }

    fn flush(&mut self) -> Result<(), String> {
        self.writer.flush().map_err(|e| e.to_string())
    }
}

/// Creates `dir/trajectory.csv` for a run of `model` on `servos` servos.
pub fn open(dir: &Path, model: &Model, servos: usize) -> Result<CsvLog, String> {
    let names = extra_columns(servos);
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
            model.generated.corners(),
        )
        .map_err(|e| e.to_string())?,
    );
    Ok(files)
}
