//! Where `softcbf run` writes: the streaming CSV log (the `simulate` columns plus timing and
//! clamp columns) and, at the end, the figures.

use std::path::Path;

use crate::hardware::run_loop::{LogRow, RunLog};
use crate::model::Model;

/// A log that keeps nothing (until the shared record writer is wired in).
struct NullLog;

impl RunLog for NullLog {
    fn push(&mut self, _row: &LogRow<'_>) -> Result<(), String> {
        Ok(())
    }
    fn flush(&mut self) -> Result<(), String> {
        Ok(())
    }
}

/// Opens the log of a run in `dir`.
pub fn open(_dir: &Path, _model: &Model, _servos: usize) -> Result<Box<dyn RunLog>, String> {
    Ok(Box::new(NullLog))
}

/// Closes the log and draws the figures; returns what was written.
pub fn finish(_log: Box<dyn RunLog>, _dir: &Path) -> Result<String, String> {
    Ok(String::new())
}
