//! Reading the logs of `softcbf run` for identification: the columns it needs from
//! `trajectory.csv` (readings, their sampling times, goal currents and when they landed),
//! the robot's name from `summary.json` and the hardware description the log was taken
//! with from `hardware.json` (which must be the robot file's: a log whose servo
//! directions, zero angles or tendon angles differ means other tensions and another `q`
//! for the same numbers), each checked, with errors naming file, line and column.
//!
//! Only the needed columns are parsed (a 100 Hz hour of the example robot is 360 000 rows
//! of 80 columns; the others are skipped unparsed), streaming, one line at a time.

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use crate::hardware::log::{Extra, current_columns};
use crate::hardware::log_description::LogDescription;
use crate::hardware::run_loop::command_wire_time;
use crate::hardware::summary_file::{self, HardwareSummary, SummaryError};
use crate::hardware_description::Hardware;
use crate::mcap_log::{is_mcap, read_mcap};
use crate::record::{TIME, as_strs, coordinate_names};

use super::IdentifyError;

/// What a log's `summary.json` says the run was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExperimentKind {
    /// Constant tension sets held to rest (`softcbf run --experiment static`).
    Static,
    /// An excitation at the loop rate (`--experiment dynamic`).
    Dynamic,
}

/// One run's log, as identification uses it. Each fresh row (a reading) is one reading
/// and one command, with the same index.
#[derive(Clone, Debug)]
pub struct Log {
    /// The run directory.
    pub dir: PathBuf,
    /// Its `trajectory.csv`.
    pub file: PathBuf,
    /// The experiment `summary.json` names, if any.
    pub kind: Option<ExperimentKind>,
    /// Data rows of the file (fresh or not).
    pub rows: usize,
    /// Number of generalized coordinates.
    pub nq: usize,
    /// Number of servos.
    pub servos: usize,
    /// When each reading was sampled, `t − sampled` \[s\], strictly increasing.
    pub time: Vec<f64>,
    /// The file line of each reading (1-based, the header is line 1).
    pub line: Vec<usize>,
    /// `q` of each reading, `nq` per reading \[m\].
    pub q: Vec<f64>,
    /// The experiment step of each reading (NaN outside an experiment).
    pub step: Vec<f64>,
    /// Whether each reading belongs to a static step's rest state.
    pub rest: Vec<bool>,
    /// When the command computed from each reading reached the servos: `t + compute +
    /// write` and its time on the wire at the robot file's baud rate \[s\], non-decreasing;
    /// it holds until the next one lands.
    pub landing: Vec<f64>,
    /// The goal current of each command, `servos` per command, signed as the register
    /// \[mA\].
    pub current: Vec<f64>,
    /// `t` of the last row \[s\]: the last command holds until then.
    pub end: f64,
}

impl Log {
    /// Number of readings (fresh rows).
    pub fn readings(&self) -> usize {
        self.time.len()
    }

    /// `q` of reading `j`.
    pub fn q_of(&self, j: usize) -> &[f64] {
        &self.q[j * self.nq..(j + 1) * self.nq]
    }

    /// Goal currents of command `j` \[mA\].
    pub fn current_of(&self, j: usize) -> &[f64] {
        &self.current[j * self.servos..(j + 1) * self.servos]
    }

    /// The directory's name, for reports.
    pub fn name(&self) -> String {
        self.dir.file_name().map_or_else(
            || self.dir.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        )
    }
}

/// Columns read from `trajectory.csv`, besides `q` and the goal currents.
const FIXED: [&str; 9] = [
    TIME,
    Extra::Fresh.name(),
    Extra::Compute.name(),
    Extra::Write.name(),
    Extra::Sampled.name(),
    Extra::Step.name(),
    Extra::Rest.name(),
    Extra::ClampLow.name(),
    Extra::ClampHigh.name(),
];
const T: usize = 0;
const FRESH: usize = 1;
const COMPUTE: usize = 2;
const WRITE: usize = 3;
const SAMPLED: usize = 4;
const STEP: usize = 5;
const REST: usize = 6;
const CLAMP_LOW: usize = 7;
const CLAMP_HIGH: usize = 8;

/// More than this share of the commands clamped at a tension limit (or at the current
/// register's end) makes a log saturated: its tensions say little about the robot.
pub const SATURATED_SHARE: f64 = 0.5;

/// What the robot file says a log must match.
pub struct Expected<'a> {
    /// The robot's name.
    pub name: &'a str,
    /// The robot file (for messages).
    pub file: &'a Path,
    /// Number of coordinates.
    pub nq: usize,
    /// The hardware description (servo count, current unit).
    pub hardware: &'a Hardware,
    /// What a log's `hardware.json` must say: [`LogDescription::of`] the robot and
    /// `hardware`.
    pub description: LogDescription,
}

/// Reads every log directory, in the order given (each file in parallel chunks).
pub fn read_logs(dirs: &[PathBuf], expected: &Expected<'_>) -> Result<Vec<Log>, IdentifyError> {
    if dirs.is_empty() {
        return Err(IdentifyError::NoLogs);
    }
    dirs.iter().map(|dir| read_log(dir, expected)).collect()
}

/// Reads one run directory: `hardware.json` (required: the hardware description the log was
/// taken with, which must be the robot's), `summary.json` (if present: the robot's name
/// and the experiment) and `trajectory.csv`.
///
/// `dir` may also be an MCAP log of such a run (`run.mcap`, as `softcbf run --mcap` writes
/// it), which holds all three: [`read_mcap_log`].
pub fn read_log(dir: &Path, expected: &Expected<'_>) -> Result<Log, IdentifyError> {
    if dir.is_file() && is_mcap(dir) {
        return read_mcap_log(dir, expected);
    }
    let file = dir.join("trajectory.csv");
    if !dir.is_dir() {
        return Err(IdentifyError::Io {
            file: dir.to_path_buf(),
            message: "not a directory (give the run directories `softcbf run --out` wrote)".into(),
        });
    }
    if !file.is_file() {
        return Err(IdentifyError::MissingTrajectory {
            dir: dir.to_path_buf(),
        });
    }
    let baud = read_description(dir, expected)?;
    let kind = read_summary(dir, expected)?;
    let mut log = read_trajectory(&file, expected, baud, CHUNK_BYTES)?;
    log.dir = dir.to_path_buf();
    log.kind = kind;
    Ok(log)
}

/// Checks `dir/hardware.json` against the robot's description; returns the run's baud rate
/// (commands were timed on the wire at it).
fn read_description(dir: &Path, expected: &Expected<'_>) -> Result<u32, IdentifyError> {
    let log = LogDescription::read(dir)?;
    check_description(
        &log,
        &dir.join(crate::hardware::log_description::FILE_NAME),
        expected,
    )
}

/// Checks a log's description `log` (read from `file`) against the robot's; returns the
/// run's baud rate.
fn check_description(
    log: &LogDescription,
    file: &Path,
    expected: &Expected<'_>,
) -> Result<u32, IdentifyError> {
    if let Some(difference) = log.first_difference(&expected.description) {
        return Err(IdentifyError::DifferentRobot {
            file: file.to_path_buf(),
            what: format!(
                "the log was taken with {} = {}, {} has {}; its readings and currents mean                  other lengths and tensions under this file (identify with the robot file                  the log was taken with, {})",
                difference.field,
                difference.log,
                expected.file.display(),
                difference.robot,
                log.robot_file
            ),
        });
    }
    Ok(log.baud)
}

/// The experiment of `dir/summary.json`, after checking its robot's name; `None` when
/// the file is absent (a run killed before writing it) or names no experiment.
fn read_summary(
    dir: &Path,
    expected: &Expected<'_>,
) -> Result<Option<ExperimentKind>, IdentifyError> {
    let path = dir.join(summary_file::FILE_NAME);
    // (The summary's error names its file; it is said once.)
    let summary = HardwareSummary::read(dir).map_err(|error| match error {
        SummaryError::Io { file, message } => IdentifyError::Io { file, message },
        SummaryError::Format {
            file,
            line,
            message,
        } => IdentifyError::Io {
            file,
            message: format!("line {line}: {message}"),
        },
    })?;
    match summary {
        Some(summary) => summary_kind(&summary, &path, expected),
        None => Ok(None),
    }
}

/// The experiment of a run's `summary` (read from `path`), after checking its robot's
/// name.
fn summary_kind(
    summary: &HardwareSummary,
    path: &Path,
    expected: &Expected<'_>,
) -> Result<Option<ExperimentKind>, IdentifyError> {
    let name = &summary.robot;
    if !name.is_empty() && name != expected.name {
        return Err(IdentifyError::DifferentRobot {
            file: path.to_path_buf(),
            what: format!(
                "the run was of robot `{name}`, {} describes `{}`",
                expected.file.display(),
                expected.name
            ),
        });
    }
    Ok(match summary.experiment_kind() {
        Some("static") => Some(ExperimentKind::Static),
        Some("dynamic") => Some(ExperimentKind::Dynamic),
        _ => None,
    })
}

/// Whether `name` is a coordinate column `dx<i> [m]`, `dy<i> [m]` or `dL<i> [m]`.
fn is_coordinate_column(name: &str) -> bool {
    let Some(inner) = name.strip_suffix(" [m]") else {
        return false;
    };
    ["dx", "dy", "dL"].iter().any(|prefix| {
        inner
            .strip_prefix(prefix)
            .is_some_and(|d| !d.is_empty() && d.bytes().all(|c| c.is_ascii_digit()))
    })
}

/// Reads the needed columns of a `trajectory.csv` of a run at `baud` [bit/s].
fn read_trajectory(
    file: &Path,
    expected: &Expected<'_>,
    baud: u32,
    chunk_bytes: u64,
) -> Result<Log, IdentifyError> {
    let io = |error: std::io::Error| IdentifyError::Io {
        file: file.to_path_buf(),
        message: error.to_string(),
    };
    let mut reader = BufReader::with_capacity(1 << 20, File::open(file).map_err(io)?);
    let mut buffer = Vec::with_capacity(4096);
    if reader.read_until(b'\n', &mut buffer).map_err(io)? == 0 {
        return Err(IdentifyError::Value {
            file: file.to_path_buf(),
            line: 1,
            column: TIME.into(),
            what: "empty file, expected the header `t [s],…`".into(),
        });
    }
    let header = std::str::from_utf8(trim_line(&buffer)).map_err(|_| IdentifyError::Value {
        file: file.to_path_buf(),
        line: 1,
        column: TIME.into(),
        what: "the header is not UTF-8 text".into(),
    })?;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let layout = layout_of(&names, file, expected, baud)?;
    let header_end = buffer.len() as u64;
    drop(reader);
    let size = std::fs::metadata(file).map_err(io)?.len();
    let ranges = chunk_ranges(file, header_end, size, chunk_bytes.max(1)).map_err(io)?;
    let parts = super::parallel_map(ranges.len(), |k| {
        parse_chunk(file, &layout, ranges[k].clone())
    });
    assemble(file, expected, parts)
}

/// Where the columns identification reads stand among `names` (a log's header, read
/// from `file`), after checking that the log is of the robot `expected` describes; its
/// commands were timed on the wire at `baud` \[bit/s\].
fn layout_of(
    names: &[&str],
    file: &Path,
    expected: &Expected<'_>,
    baud: u32,
) -> Result<Layout, IdentifyError> {
    let width = names.len();

    // A different robot first: its columns would be missing for the wrong reason.
    let servos = 3 * expected.hardware.modules.len();
    let log_nq = names.iter().filter(|n| is_coordinate_column(n)).count();
    let log_servos = names
        .iter()
        .filter(|n| n.starts_with("I module ") && n.ends_with(" [mA]"))
        .count();
    if log_nq != expected.nq {
        return Err(IdentifyError::DifferentRobot {
            file: file.to_path_buf(),
            what: format!(
                "the log has {log_nq} coordinates, {} has {}",
                expected.file.display(),
                expected.nq
            ),
        });
    }
    if log_servos != 0 && log_servos != servos {
        return Err(IdentifyError::DifferentRobot {
            file: file.to_path_buf(),
            what: format!(
                "the log has goal currents of {log_servos} servos, {} has {servos}",
                expected.file.display()
            ),
        });
    }

    let q_names: Vec<String> = coordinate_names(expected.nq)
        .iter()
        .map(|c| format!("{c} [m]"))
        .collect();
    let current_names = current_columns(servos);
    let wanted: Vec<&str> = FIXED
        .iter()
        .copied()
        .chain(q_names.iter().map(String::as_str))
        .chain(current_names.iter().map(String::as_str))
        .collect();
    // slot[column of the file] = index into `wanted`.
    let mut slot = vec![usize::MAX; width];
    for (k, name) in wanted.iter().enumerate() {
        let Some(column) = names.iter().position(|n| n == name) else {
            let why = if matches!(*name, "sampled [us]" | "step" | "rest") || name.starts_with("I ")
            {
                " (logs of softcbf before identification existed lack it: record a new run)"
            } else {
                " (is this a `softcbf run` log? `softcbf simulate` writes no servo columns)"
            };
            return Err(IdentifyError::MissingColumn {
                file: file.to_path_buf(),
                column: (*name).to_string(),
                why,
            });
        };
        slot[column] = k;
    }

    let mut order: Vec<(usize, usize)> = slot
        .iter()
        .enumerate()
        .filter(|(_, k)| **k != usize::MAX)
        .map(|(column, k)| (column, *k))
        .collect();
    order.sort_unstable();
    Ok(Layout {
        order,
        wanted: wanted.iter().map(|w| (*w).to_string()).collect(),
        width,
        nq: expected.nq,
        register_end: f64::from(i16::MAX) * expected.hardware.current_unit * (1.0 - 1e-9),
        wire: command_wire_time(servos, baud),
    })
}

/// The log of `file` from its readings, parsed in `parts` (each with its number of lines,
/// in order), checked as a whole: readings in time order, not mostly saturated.
fn assemble(
    file: &Path,
    expected: &Expected<'_>,
    parts: Vec<(Result<Chunk, ChunkError>, usize)>,
) -> Result<Log, IdentifyError> {
    let servos = 3 * expected.hardware.modules.len();
    let mut log = Log {
        dir: PathBuf::new(),
        file: file.to_path_buf(),
        kind: None,
        rows: 0,
        nq: expected.nq,
        servos,
        time: Vec::new(),
        line: Vec::new(),
        q: Vec::new(),
        step: Vec::new(),
        rest: Vec::new(),
        landing: Vec::new(),
        current: Vec::new(),
        end: f64::NEG_INFINITY,
    };
    let mut saturated = 0usize;
    // Lines before the chunk: the header, then every earlier chunk's.
    let mut lines_before = 1;
    for (chunk, lines) in parts {
        let chunk = match chunk {
            Ok(chunk) => chunk,
            Err(ChunkError::At { line, column, what }) => {
                return Err(IdentifyError::Value {
                    file: file.to_path_buf(),
                    line: lines_before + line,
                    column,
                    what,
                });
            }
            Err(ChunkError::Io(message)) => {
                return Err(IdentifyError::Io {
                    file: file.to_path_buf(),
                    message,
                });
            }
        };
        for (k, &time) in chunk.time.iter().enumerate() {
            let line = lines_before + chunk.line[k];
            if let Some(&previous) = log.time.last()
                && time <= previous
            {
                return Err(IdentifyError::Value {
                    file: file.to_path_buf(),
                    line,
                    column: "sampled [us]".into(),
                    what: format!(
                        "this reading was sampled at t − sampled = {time:.6} s, not after the \
                         previous one ({previous:.6} s, line {})",
                        log.line.last().copied().unwrap_or(0)
                    ),
                });
            }
            log.time.push(time);
            log.line.push(line);
            // Commands are written in order: one computed later cannot land earlier.
            let landing = chunk.landing[k];
            log.landing.push(
                log.landing
                    .last()
                    .map_or(landing, |&l: &f64| l.max(landing)),
            );
        }
        log.rows += chunk.rows;
        log.end = log.end.max(chunk.end);
        log.q.extend_from_slice(&chunk.q);
        log.step.extend_from_slice(&chunk.step);
        log.rest.extend_from_slice(&chunk.rest);
        log.current.extend_from_slice(&chunk.current);
        saturated += chunk.saturated;
        lines_before += lines;
    }
    let readings = log.time.len();
    if readings > 0 && saturated as f64 > SATURATED_SHARE * readings as f64 {
        return Err(IdentifyError::Saturated {
            file: file.to_path_buf(),
            message: format!(
                "{saturated} of {readings} commands were clamped at a tension limit \
                 (clamp_low, clamp_high) or at the goal-current register's end; lower the \
                 experiment's amplitudes or widen `tension_limits`"
            ),
        });
    }
    Ok(log)
}

/// Bytes of a log parsed by one thread.
const CHUNK_BYTES: u64 = 16 << 20;

/// Where each column goes.
struct Layout {
    /// `(column of the file, index into wanted)`, by column.
    order: Vec<(usize, usize)>,
    wanted: Vec<String>,
    width: usize,
    nq: usize,
    /// A goal current at least this large \[mA\] is at the register's end.
    register_end: f64,
    /// The command's time on the wire \[s\]: it lands this long after the write.
    wire: f64,
}

/// The readings of a range of lines; line numbers from 1 within the range.
#[derive(Default)]
struct Chunk {
    rows: usize,
    time: Vec<f64>,
    line: Vec<usize>,
    q: Vec<f64>,
    step: Vec<f64>,
    rest: Vec<bool>,
    landing: Vec<f64>,
    current: Vec<f64>,
    end: f64,
    saturated: usize,
}

/// Why a range of lines could not be read (its line number from 1 within the range).
enum ChunkError {
    At {
        line: usize,
        column: String,
        what: String,
    },
    Io(String),
}

/// Byte ranges of about `chunk_bytes` after the header, each starting at a line.
fn chunk_ranges(
    file: &Path,
    start: u64,
    size: u64,
    chunk_bytes: u64,
) -> std::io::Result<Vec<std::ops::Range<u64>>> {
    let mut starts = vec![start];
    let mut reader = BufReader::new(File::open(file)?);
    let mut skipped = Vec::new();
    let mut next = start + chunk_bytes;
    while next < size {
        reader.seek(SeekFrom::Start(next - 1))?;
        skipped.clear();
        let read = reader.read_until(b'\n', &mut skipped)? as u64;
        let line_start = next - 1 + read;
        if line_start >= size {
            break;
        }
        starts.push(line_start);
        next = line_start + chunk_bytes;
    }
    let mut ranges: Vec<std::ops::Range<u64>> = starts.windows(2).map(|w| w[0]..w[1]).collect();
    if let Some(&last) = starts.last() {
        ranges.push(last..size.max(last));
    }
    Ok(ranges)
}

/// Parses the lines in `range` of `file`; returns them and the number of lines read.
fn parse_chunk(
    file: &Path,
    layout: &Layout,
    range: std::ops::Range<u64>,
) -> (Result<Chunk, ChunkError>, usize) {
    let mut lines = 0;
    let result = parse_lines(file, layout, range, &mut lines);
    (result, lines)
}

fn parse_lines(
    file: &Path,
    layout: &Layout,
    range: std::ops::Range<u64>,
    line_number: &mut usize,
) -> Result<Chunk, ChunkError> {
    let io = |e: std::io::Error| ChunkError::Io(e.to_string());
    let mut handle = File::open(file).map_err(io)?;
    handle.seek(SeekFrom::Start(range.start)).map_err(io)?;
    let mut reader = BufReader::with_capacity(1 << 20, handle.take(range.end - range.start));
    let (wanted, width) = (&layout.wanted, layout.width);
    let mut values = vec![f64::NAN; wanted.len()];
    let mut buffer = Vec::with_capacity(4096);
    let mut chunk = Chunk {
        end: f64::NEG_INFINITY,
        ..Chunk::default()
    };
    loop {
        buffer.clear();
        if reader.read_until(b'\n', &mut buffer).map_err(io)? == 0 {
            break;
        }
        *line_number += 1;
        let line_number = *line_number;
        let line = trim_line(&buffer);
        if line.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        // Only the wanted fields are parsed; the others are skipped by counting commas.
        let mut position = 0;
        let mut column = 0;
        for &(wanted_column, k) in &layout.order {
            let Some(start) = skip_fields(line, position, wanted_column - column) else {
                let fields = column + 1 + count_commas(&line[position..]);
                return Err(ChunkError::At {
                    line: line_number,
                    column: TIME.into(),
                    what: format!("{fields} fields, the header has {width}"),
                });
            };
            let end = line[start..]
                .iter()
                .position(|&b| b == b',')
                .map_or(line.len(), |p| start + p);
            let field = &line[start..end];
            let text = std::str::from_utf8(field).unwrap_or("").trim();
            values[k] = text.parse::<f64>().map_err(|_| ChunkError::At {
                line: line_number,
                column: wanted[k].clone(),
                what: format!(
                    "`{}` is not a number",
                    String::from_utf8_lossy(field).trim()
                ),
            })?;
            position = end;
            column = wanted_column;
        }
        let fields = column + 1 + count_commas(&line[position..]);
        if fields != width {
            return Err(ChunkError::At {
                line: line_number,
                column: TIME.into(),
                what: format!("{fields} fields, the header has {width}"),
            });
        }
        take_row(&values, line_number, layout, &mut chunk)?;
    }
    Ok(chunk)
}

/// Takes one row into `chunk`: its wanted `values` (in the order of `layout.wanted`),
/// from line `line_number` of its file.
fn take_row(
    values: &[f64],
    line_number: usize,
    layout: &Layout,
    chunk: &mut Chunk,
) -> Result<(), ChunkError> {
    let (nq, wanted) = (layout.nq, &layout.wanted);
    {
        chunk.rows += 1;
        let non_finite = |k: usize| ChunkError::At {
            line: line_number,
            column: wanted[k].clone(),
            what: format!("{} in a row with a reading (fresh = 1)", values[k]),
        };
        if !values[T].is_finite() {
            return Err(non_finite(T));
        }
        chunk.end = chunk.end.max(values[T]);
        let fresh = values[FRESH];
        if fresh == 0.0 {
            return Ok(());
        }
        if fresh != 1.0 {
            return Err(ChunkError::At {
                line: line_number,
                column: "fresh".into(),
                what: format!("{fresh}, expected 0 or 1"),
            });
        }
        let needed = [T, COMPUTE, WRITE, SAMPLED]
            .into_iter()
            .chain(FIXED.len()..wanted.len());
        for k in needed {
            if !values[k].is_finite() {
                return Err(non_finite(k));
            }
        }
        let currents = &values[FIXED.len() + nq..];
        let clamped = values[CLAMP_LOW] + values[CLAMP_HIGH] > 0.0;
        if clamped || currents.iter().any(|i| i.abs() >= layout.register_end) {
            chunk.saturated += 1;
        }
        chunk.time.push(values[T] - values[SAMPLED] * 1e-6);
        chunk.line.push(line_number);
        chunk
            .q
            .extend_from_slice(&values[FIXED.len()..FIXED.len() + nq]);
        chunk.step.push(values[STEP]);
        chunk.rest.push(values[REST] == 1.0);
        chunk
            .landing
            .push(values[T] + (values[COMPUTE] + values[WRITE]) * 1e-6 + layout.wire);
        chunk.current.extend_from_slice(currents);
    }
    Ok(())
}

/// Reads an MCAP log of a run (`softcbf run --mcap`): its hardware description and summary
/// from its metadata (checked as `hardware.json` and `summary.json` are), its rows through
/// [`crate::mcap_log::read_mcap`] (the CSV's, value for value), each row taken as the
/// CSV's line is. A row's line in errors and in [`Log::line`] is the line it has in the
/// `trajectory.csv` the log was written with (its message number + 1), so that the log
/// gives the same [`Log`] as that file.
pub fn read_mcap_log(file: &Path, expected: &Expected<'_>) -> Result<Log, IdentifyError> {
    let io = |message: String| IdentifyError::Io {
        file: file.to_path_buf(),
        message,
    };
    let read = read_mcap(file).map_err(|e| io(e.to_string()))?;
    let description: LogDescription = match &read.hardware {
        Some(value) => serde_json::from_value(value.clone()).map_err(|e| {
            io(format!(
                "metadata `hardware`: not a hardware description of softcbf: {e}"
            ))
        })?,
        None => {
            return Err(io(
                "no metadata `hardware`: the hardware description the log was \
                 taken with is not in it (is this a log of `softcbf run --mcap`?)"
                    .into(),
            ));
        }
    };
    let baud = check_description(&description, file, expected)?;
    let kind = match &read.summary {
        Some(summary) => {
            let summary: HardwareSummary = serde_json::from_value(summary.clone())
                .map_err(|e| io(format!("metadata `summary`: {e}")))?;
            summary_kind(&summary, file, expected)?
        }
        None => None,
    };
    let Some((_, record)) = read.runs.first() else {
        return Err(io("no run in it".into()));
    };
    let columns = record.columns();
    let names: Vec<String> = (0..columns.width())
        .filter_map(|k| columns.name(k))
        .collect();
    let layout = layout_of(&as_strs(&names), file, expected, baud)?;
    let mut chunk = Chunk {
        end: f64::NEG_INFINITY,
        ..Chunk::default()
    };
    let mut values = vec![f64::NAN; layout.wanted.len()];
    let mut row_values = Vec::with_capacity(columns.width());
    for (index, row) in record.rows().enumerate() {
        row_values.clear();
        row_values.extend(row.values());
        for &(column, k) in &layout.order {
            values[k] = row_values[column];
        }
        // The header is line 1 of the CSV: row `index` is line `index + 2`, line
        // `index + 1` after it, as a chunk counts them.
        let result = take_row(&values, index + 1, &layout, &mut chunk);
        if let Err(error) = result {
            return Err(assemble(file, expected, vec![(Err(error), 0)])
                .err()
                .unwrap_or_else(|| io("a row cannot be used".into())));
        }
    }
    let rows = record.len();
    let mut log = assemble(file, expected, vec![(Ok(chunk), rows)])?;
    log.dir = file
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or_else(|| Path::new("."))
        .to_path_buf();
    log.kind = kind;
    Ok(log)
}

/// Number of commas in `bytes` (vectorizes).
fn count_commas(bytes: &[u8]) -> usize {
    bytes.iter().filter(|&&b| b == b',').count()
}

/// The start of the field `skip` fields after the one starting at `position` (0: that
/// one itself); `None` if the line has fewer.
fn skip_fields(line: &[u8], position: usize, skip: usize) -> Option<usize> {
    let mut position = position;
    let mut left = skip;
    // Whole blocks of 32 bytes with fewer commas than needed are counted, not searched.
    while left > 0 && position + 32 <= line.len() {
        let commas = count_commas(&line[position..position + 32]);
        if commas >= left {
            break;
        }
        left -= commas;
        position += 32;
    }
    while left > 0 {
        let offset = line.get(position..)?.iter().position(|&b| b == b',')?;
        position += offset + 1;
        left -= 1;
    }
    Some(position)
}

/// The line without its end (`\n` or `\r\n`).
fn trim_line(line: &[u8]) -> &[u8] {
    let line = line.strip_suffix(b"\n").unwrap_or(line);
    line.strip_suffix(b"\r").unwrap_or(line)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Model;
    use crate::synthetic::{Phase, SyntheticRun, write_log};
    use softcbf_description::robot::Robot;

    #[test]
    fn fields_are_found_by_counting_commas() {
        let line = b"0,1.5,,x,42,7,8,9,10,11,12,13,14,15,16,17,18,19,20,21,22,23,24,25,26,27,28,29";
        let field = |k: usize| {
            let start = skip_fields(line, 0, k)?;
            let end = line[start..]
                .iter()
                .position(|&b| b == b',')
                .map_or(line.len(), |p| start + p);
            Some(std::str::from_utf8(&line[start..end]).unwrap().to_string())
        };
        assert_eq!(field(0).as_deref(), Some("0"));
        assert_eq!(field(2).as_deref(), Some(""));
        assert_eq!(field(4).as_deref(), Some("42"));
        assert_eq!(field(27).as_deref(), Some("29"));
        assert_eq!(field(28), None);
        assert_eq!(count_commas(line), 27);
    }

    #[test]
    fn a_log_read_in_many_chunks_is_the_log_read_in_one() {
        let path = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../robots/hardware-example.toml"
        ));
        let model = Model::new(Robot::load(path).unwrap()).unwrap();
        let dir =
            std::env::temp_dir().join(format!("softcbf-identify-chunks-{}", std::process::id()));
        let run = SyntheticRun::new(&model, &model, 100.0, 1.0);
        write_log(&dir, &run, |tick, tensions| {
            tensions.fill(1.0 + tick.t);
            Phase {
                step: 0.0,
                rest: tick.t > 0.5,
            }
        })
        .unwrap();
        let hardware = crate::hardware_of(&model.robot).unwrap();
        let expected = Expected {
            name: &model.robot.name,
            file: path,
            nq: 6,
            hardware: &hardware,
            description: LogDescription::of(&model.robot, &hardware),
        };
        let file = dir.join("trajectory.csv");
        let whole = read_trajectory(&file, &expected, hardware.baud, CHUNK_BYTES).unwrap();
        let pieces = read_trajectory(&file, &expected, hardware.baud, 700).unwrap();
        assert_eq!(whole.readings(), 101);
        assert_eq!(whole.line[100], 102);
        assert_eq!(
            (whole.time.clone(), whole.line.clone(), whole.q.clone()),
            (pieces.time, pieces.line, pieces.q)
        );
        assert_eq!(
            (
                whole.landing.clone(),
                whole.current.clone(),
                whole.rest.clone()
            ),
            (pieces.landing, pieces.current, pieces.rest)
        );
        // An error deep in the file names its line, whatever the chunks.
        let text = std::fs::read_to_string(&file).unwrap();
        let broken: Vec<String> = text
            .lines()
            .enumerate()
            .map(|(k, line)| {
                if k + 1 == 77 {
                    line.replacen(',', ",oops", 1)
                } else {
                    line.to_string()
                }
            })
            .collect();
        std::fs::write(&file, broken.join("\n")).unwrap();
        for chunk in [CHUNK_BYTES, 700, 5000] {
            let error = read_trajectory(&file, &expected, hardware.baud, chunk)
                .unwrap_err()
                .to_string();
            assert!(
                error.contains("trajectory.csv:77: column `dx1 [m]`: `oops"),
                "{chunk}: {error}"
            );
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
