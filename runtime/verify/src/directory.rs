//! A batch's output directory while it is written: `shard.json` first (which batch, which
//! slice), then `runs.csv` and `timing.csv` one whole row at a time, in index order, as the
//! runs finish. So an interrupted batch (a signal, a killed process, a lost machine) keeps
//! every run written, its files are a prefix of the finished batch's byte for byte, and
//! [`open`] with `resume` continues where it stopped, after checking that the directory
//! holds the same batch and slice.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::RunRow;
use crate::table::{
    self, Manifest, TIMING_HEADER, TableError, difference, read_runs, run_line, runs_header,
    timing_line,
};

/// The files of a batch that derive from all its rows: written when the slice is whole,
/// removed when a batch starts afresh (so that an old report never sits beside new rows).
pub const SUMMARY_FILES: [&str; 5] = [
    "report.json",
    "lowest_barrier.png",
    "lowest_barrier.svg",
    "lowest_vs_set_point.png",
    "lowest_vs_set_point.svg",
];

/// A batch's directory open for its next rows.
pub struct BatchFiles {
    runs: File,
    timing: File,
    runs_path: PathBuf,
    timing_path: PathBuf,
}

/// What [`open`] found and kept.
pub struct Opened {
    /// The directory's files, positioned after the rows kept.
    pub files: BatchFiles,
    /// The rows already written (resumed), in index order from the slice's first.
    pub rows: Vec<RunRow>,
    /// Their wall times (those that were written).
    pub timing: Vec<(usize, f64)>,
    /// Whether an earlier batch's directory was found (resumed, or replaced when it had
    /// finished).
    pub found: Found,
}

/// What the directory held before.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Found {
    /// No batch.
    Nothing,
    /// A finished slice of a batch, replaced (without `--resume`).
    Finished,
    /// The same batch and slice, resumed.
    Resumed,
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> TableError + '_ {
    move |source| TableError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Text up to its last line end (a row cut by a killed process is dropped).
fn whole_lines(text: &str) -> &str {
    text.rfind('\n').map_or("", |end| &text[..=end])
}

/// Opens `dir` (which exists) for the slice `manifest` describes. Without `resume` a
/// directory holding an unfinished slice of a batch is refused (its runs would be lost),
/// one holding a finished slice is replaced; with `resume` the same batch and slice are
/// continued (their whole rows kept, a row cut at the end dropped) and another one is
/// refused naming what differs; a directory without a batch starts afresh either way.
pub fn open(dir: &Path, manifest: &Manifest, resume: bool) -> Result<Opened, TableError> {
    let manifest_path = dir.join("shard.json");
    let runs_path = dir.join("runs.csv");
    let timing_path = dir.join("timing.csv");
    let mut found = Found::Nothing;
    if manifest_path.exists() {
        let text = table::read(&manifest_path)?;
        let before: Manifest = serde_json::from_str(&text).map_err(|e| TableError::Format {
            path: manifest_path.clone(),
            line: e.line(),
            message: format!("not a shard manifest of `softcbf verify`: {e}"),
        })?;
        let kept = written_rows(&runs_path, &before)?;
        let unfinished = kept.len() < before.end - before.first;
        if resume {
            if before.batch != manifest.batch || before.shard != manifest.shard {
                let what = if before.batch != manifest.batch {
                    difference(&before.batch, &manifest.batch)
                } else {
                    format!(
                        "shard {}/{} vs {}/{}",
                        before.shard[0], before.shard[1], manifest.shard[0], manifest.shard[1]
                    )
                };
                return Err(TableError::Merge(format!(
                    "--resume: {} holds another batch than this command's ({what}; the \
                     directory's first): resume it with its own settings, or give another \
                     --out",
                    dir.display()
                )));
            }
            let timing = written_timing(&timing_path, &before, kept.len())?;
            // Keep the whole rows as they are; drop a row cut at the end.
            if runs_path.exists() {
                let text = table::read(&runs_path)?;
                let file = OpenOptions::new()
                    .write(true)
                    .open(&runs_path)
                    .map_err(io(&runs_path))?;
                file.set_len(whole_lines(&text).len() as u64)
                    .map_err(io(&runs_path))?;
            }
            if kept.is_empty() {
                table::write(&runs_path, &runs_header(before.batch.coordinates))?;
            }
            let timing_text = TIMING_HEADER.to_string()
                + &timing
                    .iter()
                    .map(|&(run, wall)| timing_line(run, wall))
                    .collect::<String>();
            table::write(&timing_path, &timing_text)?;
            let files = BatchFiles::append(runs_path, timing_path)?;
            return Ok(Opened {
                files,
                rows: kept,
                timing,
                found: Found::Resumed,
            });
        }
        if unfinished {
            return Err(TableError::Merge(format!(
                "{} holds an unfinished batch ({} of its {} runs written): give --resume to \
                 continue it (with the same settings), or remove the directory or give \
                 another --out to start again",
                dir.display(),
                kept.len(),
                before.end - before.first
            )));
        }
        found = Found::Finished;
    }
    // Afresh: the manifest first, then the headers; nothing derived from older rows.
    for name in SUMMARY_FILES {
        let path = dir.join(name);
        if path.is_file() {
            std::fs::remove_file(&path).map_err(io(&path))?;
        }
    }
    let text = serde_json::to_string_pretty(manifest).map_err(|e| TableError::Format {
        path: manifest_path.clone(),
        line: 0,
        message: e.to_string(),
    })?;
    table::write(&manifest_path, &text)?;
    table::write(&runs_path, &runs_header(manifest.batch.coordinates))?;
    table::write(&timing_path, TIMING_HEADER)?;
    let files = BatchFiles::append(runs_path, timing_path)?;
    Ok(Opened {
        files,
        rows: Vec::new(),
        timing: Vec::new(),
        found,
    })
}

/// The whole rows of `path` (a `runs.csv` of `manifest`'s slice), checked to be its first
/// runs in order; none if the file is missing.
fn written_rows(path: &Path, manifest: &Manifest) -> Result<Vec<RunRow>, TableError> {
    if !path.exists() {
        return Ok(Vec::new());
    }
    let text = table::read(path)?;
    let whole = whole_lines(&text);
    if whole.is_empty() {
        return Ok(Vec::new());
    }
    let b = &manifest.batch;
    let rows = read_runs(whole, path, b.coordinates, &b.groups)?;
    if let Some((k, row)) = rows
        .iter()
        .enumerate()
        .find(|(k, row)| row.run != manifest.first + k)
    {
        return Err(TableError::Format {
            path: path.to_path_buf(),
            line: k + 2,
            message: format!(
                "holds run {} where run {} belongs (shard.json: runs {}..{} in order)",
                row.run,
                manifest.first + k,
                manifest.first,
                manifest.end
            ),
        });
    }
    if rows.len() > manifest.end - manifest.first {
        return Err(TableError::Format {
            path: path.to_path_buf(),
            line: manifest.end - manifest.first + 2,
            message: format!(
                "holds more rows than the slice's {} runs",
                manifest.end - manifest.first
            ),
        });
    }
    Ok(rows)
}

/// The wall times in `path` of the first `count` runs of `manifest`'s slice (a line that
/// does not read is left out: wall times are informative only).
fn written_timing(
    path: &Path,
    manifest: &Manifest,
    count: usize,
) -> Result<Vec<(usize, f64)>, TableError> {
    if !path.exists() {
        return Ok(Vec::new());
    }
    let text = table::read(path)?;
    let end = manifest.first + count;
    Ok(whole_lines(&text)
        .lines()
        .skip(1)
        .filter_map(|line| {
            let (run, wall) = line.split_once(',')?;
            Some((run.parse::<usize>().ok()?, wall.parse::<f64>().ok()?))
        })
        .filter(|(run, _)| (manifest.first..end).contains(run))
        .collect())
}

impl BatchFiles {
    fn append(runs_path: PathBuf, timing_path: PathBuf) -> Result<BatchFiles, TableError> {
        let open = |path: &Path| OpenOptions::new().append(true).open(path).map_err(io(path));
        Ok(BatchFiles {
            runs: open(&runs_path)?,
            timing: open(&timing_path)?,
            runs_path,
            timing_path,
        })
    }

    /// Appends `row` to `runs.csv` and its wall time to `timing.csv`, each in one write.
    pub fn push(&mut self, row: &RunRow, wall: f64) -> Result<(), TableError> {
        self.runs
            .write_all(run_line(row).as_bytes())
            .and_then(|()| self.runs.flush())
            .map_err(io(&self.runs_path))?;
        self.timing
            .write_all(timing_line(row.run, wall).as_bytes())
            .and_then(|()| self.timing.flush())
            .map_err(io(&self.timing_path))
    }
}
