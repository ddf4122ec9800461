//! CSV form of a trajectory record: one formatting path shared by the in-memory writer and
//! the streaming [`CsvWriter`] of the hardware loop, and the reader that parses it back.
//!
//! Numbers are written in the shortest form that parses back to the same `f64` (Rust's
//! `Display`, or `LowerExp` for magnitudes below 1e-5 or from 1e16 on, to keep fields
//! short); `NaN`, `inf` and `-inf` are written as such and read back (a NaN's payload and
//! sign are not kept). Lines end in `\n`; the reader also accepts `\r\n`.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use super::{Columns, Group, Record, RecordError, Row, TIME, strip_barrier};

/// First capacity of the streaming writer's line buffer (a row of the paper robot with the
/// hardware log's columns is about 800 bytes); it grows once if a row is longer.
const LINE_CAPACITY: usize = 4096;

/// Writes `x` so that `str::parse::<f64>` gives back the same value (bit-exact except
/// for NaN payloads). Allocates nothing.
fn write_number<W: Write>(out: &mut W, x: f64) -> io::Result<()> {
    let magnitude = x.abs();
    if x == 0.0 || !x.is_finite() || (1e-5..1e16).contains(&magnitude) {
        write!(out, "{x}")
    } else {
        write!(out, "{x:e}")
    }
}

/// Writes one row (comma-separated, `\n`-terminated). The sizes must already be checked.
fn write_row<W: Write>(out: &mut W, row: &Row) -> io::Result<()> {
    for (k, x) in row.values().enumerate() {
        if k > 0 {
            out.write_all(b",")?;
        }
        write_number(out, x)?;
    }
    out.write_all(b"\n")
}

fn write_header<W: Write>(out: &mut W, columns: &Columns) -> io::Result<()> {
    out.write_all(columns.header().as_bytes())?;
    out.write_all(b"\n")
}

fn io_error(file: &Path) -> impl FnOnce(io::Error) -> RecordError + '_ {
    move |source| RecordError::Io {
        file: file.to_path_buf(),
        source,
    }
}

impl Record {
    /// Writes the record as CSV to `path` (header, then one line per row).
    pub fn write_csv(&self, path: &Path) -> Result<(), RecordError> {
        let file = File::create(path).map_err(io_error(path))?;
        let mut out = BufWriter::new(file);
        self.write_csv_to(&mut out).map_err(io_error(path))?;
        out.flush().map_err(io_error(path))
    }

    /// Writes the record as CSV to `out`.
    pub fn write_csv_to<W: Write>(&self, out: &mut W) -> io::Result<()> {
        write_header(out, self.columns())?;
        for row in self.rows() {
            write_row(out, &row)?;
        }
        Ok(())
    }

    /// Reads a CSV file written by [`Record::write_csv`] or [`CsvWriter`].
    pub fn read_csv(path: &Path) -> Result<Record, RecordError> {
        let text = std::fs::read_to_string(path).map_err(io_error(path))?;
        Record::parse_csv(&text, path)
    }

    /// Parses CSV text; `file` names the source in errors. The layout (n, m, extra
    /// columns) is taken from the header. Empty lines are skipped.
    pub fn parse_csv(text: &str, file: &Path) -> Result<Record, RecordError> {
        let mut lines = text.lines().enumerate();
        let Some((_, header)) = lines.next().filter(|(_, line)| !line.trim().is_empty()) else {
            return Err(RecordError::MissingHeader {
                file: file.to_path_buf(),
            });
        };
        let columns = parse_header(header, file)?;
        let width = columns.width();
        let mut record = Record::for_columns(columns, text.lines().count().saturating_sub(1));
        for (index, line) in lines {
            if line.trim().is_empty() {
                continue;
            }
            let line_number = index + 1;
            let fields: Vec<&str> = line.split(',').collect();
            if fields.len() != width {
                return Err(RecordError::FieldCount {
                    file: file.to_path_buf(),
                    line: line_number,
                    expected: width,
                    found: fields.len(),
                });
            }
            for (k, field) in fields.iter().enumerate() {
                let text = field.trim();
                let value = text.parse::<f64>().map_err(|_| RecordError::Number {
                    file: file.to_path_buf(),
                    line: line_number,
                    column: record.columns().name(k).unwrap_or_default(),
                    text: text.to_string(),
                })?;
                record.data.push(value);
            }
        }
        Ok(record)
    }
}

/// Reads the layout from a header line: the current form (`t [s]`, `<c> [m]`…,
/// `<c>/dt [m/s]`…, `tau <c> [N]`…, `tau_nom <c> [N]`…, `b <label> [<unit>]`… with the
/// unit `m` or `rad`, extras) or the older one (`t`, `q0…`, `qd0…`, `tau0…`, `taunom0…`,
/// `b0…`, extras).
fn parse_header(line: &str, file: &Path) -> Result<Columns, RecordError> {
    let names: Vec<&str> = line.split(',').map(str::trim).collect();
    let mismatch = |column: usize, expected: String| RecordError::Header {
        file: file.to_path_buf(),
        column: column + 1,
        found: names.get(column).unwrap_or(&"<end of line>").to_string(),
        expected,
    };
    match names[0] {
        TIME => parse_named(&names, &mismatch),
        "t" => parse_legacy(&names, &mismatch),
        _ => Err(mismatch(
            0,
            format!("`{TIME}` (or `t` in logs written before the named columns)"),
        )),
    }
}

/// The layout of a header in the current form (`names[0]` is `t [s]`).
fn parse_named(
    names: &[&str],
    mismatch: &dyn Fn(usize, String) -> RecordError,
) -> Result<Columns, RecordError> {
    // The coordinates run up to the first velocity column (a coordinate name has no `/`).
    let n = names[1..]
        .iter()
        .position(|name| Group::Qd.strip(name).is_some())
        .unwrap_or(0);
    let looks_like_coordinate = |name: &str| {
        Group::Q.strip(name).is_some_and(|inner| {
            inner
                .bytes()
                .all(|c| c.is_ascii_alphanumeric() || c == b'_')
        })
    };
    if n == 0 && names.get(1).is_some_and(|name| looks_like_coordinate(name)) {
        let k = 1 + names[1..]
            .iter()
            .take_while(|name| looks_like_coordinate(name))
            .count();
        return Err(mismatch(
            k,
            format!(
                "the velocity column `{}`",
                Group::Qd.column(Group::Q.strip(names[1]).unwrap_or_default())
            ),
        ));
    }
    let mut coordinates = Vec::with_capacity(n);
    for (k, column) in names.iter().enumerate().take(n + 1).skip(1) {
        let name = Group::Q
            .strip(column)
            .ok_or_else(|| mismatch(k, "a coordinate column `<name> [m]`".to_string()))?;
        coordinates.push(name);
    }
    for (g, group) in [Group::Qd, Group::Tau, Group::TauNom]
        .into_iter()
        .enumerate()
    {
        for (i, name) in coordinates.iter().enumerate() {
            let k = 1 + (g + 1) * n + i;
            let expected = group.column(name);
            if names.get(k) != Some(&expected.as_str()) {
                return Err(mismatch(
                    k,
                    format!("`{expected}` (n = {n} from the coordinate columns)"),
                ));
            }
        }
    }
    let first_barrier = 1 + 4 * n;
    let (barriers, units): (Vec<&str>, Vec<&str>) = names[first_barrier.min(names.len())..]
        .iter()
        .map_while(|name| strip_barrier(name))
        .unzip();
    let first_extra = first_barrier + barriers.len();
    let extra = &names[first_extra.min(names.len())..];
    Columns::named_with_units(&coordinates, &barriers, &units, extra)
        .map_err(|error| name_mismatch(error, names, mismatch))
}

/// The layout of a header in the older form (`names[0]` is `t`): `q0…` give `n`, the
/// coordinates get the standard names and the barriers the default labels.
fn parse_legacy(
    names: &[&str],
    mismatch: &dyn Fn(usize, String) -> RecordError,
) -> Result<Columns, RecordError> {
    // Length of the run `group0, group1, …` starting at `start`.
    let run = |group: &str, start: usize| {
        names[start.min(names.len())..]
            .iter()
            .enumerate()
            .take_while(|(k, name)| **name == format!("{group}{k}"))
            .count()
    };
    let n = run(LEGACY_GROUPS[0], 1);
    let mut next = 1 + n;
    for group in &LEGACY_GROUPS[1..4] {
        let found = run(group, next);
        if found != n {
            return Err(mismatch(
                next + found,
                format!("`{group}{found}` (n = {n} from the q columns)"),
            ));
        }
        next += n;
    }
    let m = run(LEGACY_GROUPS[4], next);
    next += m;
    let extra = &names[next.min(names.len())..];
    if let Some(k) = extra.iter().position(|name| is_legacy_standard(name)) {
        return Err(mismatch(
            next + k,
            "an extra column name, not a standard one out of place".to_string(),
        ));
    }
    Columns::new(n, m, extra).map_err(|error| name_mismatch(error, names, mismatch))
}

/// A name refused by [`Columns::named`] as a header error at its column.
fn name_mismatch(
    error: RecordError,
    names: &[&str],
    mismatch: &dyn Fn(usize, String) -> RecordError,
) -> RecordError {
    let column = match &error {
        RecordError::ColumnName { what, name, .. } => {
            let formed = |column: &str| match *what {
                "coordinate name" => column == Group::Q.column(name),
                "barrier label" => strip_barrier(column).is_some_and(|(label, _)| label == name),
                _ => column == name,
            };
            names.iter().rposition(|column| formed(column)).unwrap_or(0)
        }
        _ => 0,
    };
    mismatch(column, format!("a valid column name ({error})"))
}

/// Base names of the column groups of the older header, in column order.
const LEGACY_GROUPS: [&str; 5] = ["q", "qd", "tau", "taunom", "b"];

/// Whether `name` is `t` or an older group name followed by decimal digits (`q0`, `b12`).
fn is_legacy_standard(name: &str) -> bool {
    name == "t"
        || LEGACY_GROUPS.iter().any(|group| {
            name.strip_prefix(group).is_some_and(|digits| {
                !digits.is_empty() && digits.bytes().all(|c| c.is_ascii_digit())
            })
        })
}

/// Streams rows to a CSV file as they come, for a run too long or too fragile to hold in
/// memory. Same header and number format as [`Record::write_csv`].
///
/// Each row is formatted into a reused line buffer and handed to the writer whole, in one
/// `write_all`: a file on disk holds every row pushed so far, at any moment, and a process
/// killed between two rows (SIGKILL, a crash) leaves a log whole up to its last row; one
/// killed inside a write loses at most that row. [`CsvWriter::push_row`] allocates nothing
/// once the line buffer has grown to a row's length (the first row).
pub struct CsvWriter<W: Write> {
    out: W,
    line: Vec<u8>,
    columns: Columns,
    file: PathBuf,
    rows: usize,
}

impl CsvWriter<File> {
    /// Creates (or truncates) `path` and writes the header.
    pub fn create(path: &Path, columns: Columns) -> Result<CsvWriter<File>, RecordError> {
        let file = File::create(path).map_err(io_error(path))?;
        CsvWriter::new(file, columns, path)
    }
}

impl<W: Write> CsvWriter<W> {
    /// Writes the header to `inner`; `file` names it in errors.
    pub fn new(mut inner: W, columns: Columns, file: &Path) -> Result<CsvWriter<W>, RecordError> {
        let mut line = Vec::with_capacity(LINE_CAPACITY);
        write_header(&mut line, &columns).map_err(io_error(file))?;
        inner.write_all(&line).map_err(io_error(file))?;
        Ok(CsvWriter {
            out: inner,
            line,
            columns,
            file: file.to_path_buf(),
            rows: 0,
        })
    }

    /// Appends one row; a row of the wrong sizes is refused and nothing is written.
    pub fn push_row(&mut self, row: &Row) -> Result<(), RecordError> {
        self.columns.check(row)?;
        self.line.clear();
        write_row(&mut self.line, row).map_err(io_error(&self.file))?;
        self.out
            .write_all(&self.line)
            .map_err(io_error(&self.file))?;
        self.rows += 1;
        Ok(())
    }

    /// Flushes the writer (a file has nothing buffered here: rows are written as pushed).
    pub fn flush(&mut self) -> Result<(), RecordError> {
        self.out.flush().map_err(io_error(&self.file))
    }

    /// Flushes and closes, reporting any error.
    pub fn finish(mut self) -> Result<(), RecordError> {
        self.flush()
    }

    /// Rows written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The column layout.
    pub fn columns(&self) -> &Columns {
        &self.columns
    }

    /// The underlying writer (holding every row pushed).
    pub fn get_ref(&self) -> &W {
        &self.out
    }
}
