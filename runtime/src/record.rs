//! Trajectory record of a run: one row per control tick (`t`, `q`, `q̇`, `τ`, `τ_nom`, `b`
//! and named extra columns), preallocated so that recording allocates nothing per tick.
//!
//! The column layout ([`Columns`]) is fixed at construction. Rows are stored row-major in
//! one buffer; [`Record::push_row`] copies a [`Row`] into it. The CSV form (header
//! `t,q0,…,qd0,…,tau0,…,taunom0,…,b0,…` then the extra names) is written by
//! [`Record::write_csv`], streamed during a run by [`CsvWriter`] and read back by
//! [`Record::read_csv`]; the three share one formatting and parsing code path (in `record/csv.rs`).
//!
//! ```
//! use softcbf::record::{Record, Row};
//! let mut record = Record::with_capacity(1, 1, &["loop_us"], 10_001)?;
//! let row = Row { t: 0.0, q: &[0.01], qd: &[0.0], tau: &[0.5], tau_nom: &[0.7], b: &[0.02], extra: &[12.0] };
//! record.push_row(&row)?; // no allocation: 10 001 rows were reserved
//! let mut csv = Vec::new();
//! record.write_csv_to(&mut csv)?;
//! assert_eq!(String::from_utf8(csv)?, "t,q0,qd0,tau0,taunom0,b0,loop_us\n0,0.01,0,0.5,0.7,0.02,12\n");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod csv;

use std::path::PathBuf;

pub use csv::CsvWriter;

/// Why a record cannot be built, written or read. File errors name the file, line and
/// column.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// Reading or writing the file failed.
    #[error("{}: {source}", file.display())]
    Io {
        /// The file.
        file: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The file has no header line.
    #[error("{}:1: empty file, expected the header `t,q0,…`", file.display())]
    MissingHeader {
        /// The file.
        file: PathBuf,
    },
    /// A header column is not the one the format requires.
    #[error("{}:1: column {column} is `{found}`, expected {expected}", file.display())]
    Header {
        /// The file.
        file: PathBuf,
        /// 1-based column number.
        column: usize,
        /// The name found there.
        found: String,
        /// What the format requires there.
        expected: String,
    },
    /// A data line has the wrong number of fields.
    #[error("{}:{line}: {found} fields, the header has {expected}", file.display())]
    FieldCount {
        /// The file.
        file: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Number of header columns.
        expected: usize,
        /// Number of fields on the line.
        found: usize,
    },
    /// A field is not a number.
    #[error("{}:{line}: column `{column}`: `{text}` is not a number", file.display())]
    Number {
        /// The file.
        file: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Name of the column (from the header).
        column: String,
        /// The offending text.
        text: String,
    },
    /// A row given to `push_row` does not match the record's sizes.
    #[error("row field `{field}` has {found} values, the record has {expected}")]
    RowSize {
        /// Which field of [`Row`].
        field: &'static str,
        /// Size the record was built with.
        expected: usize,
        /// Size given.
        found: usize,
    },
    /// An extra column name cannot be used.
    #[error("extra column name `{name}`: {reason}")]
    ExtraName {
        /// The name.
        name: String,
        /// Why it is refused.
        reason: &'static str,
    },
}

/// The column layout: `n` coordinates, `m` barriers and named extra scalar columns.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Columns {
    n: usize,
    m: usize,
    extra: Vec<String>,
}

/// Base names of the per-coordinate and per-barrier groups, in column order.
const GROUPS: [&str; 5] = ["q", "qd", "tau", "taunom", "b"];

impl Columns {
    /// Layout for `n` coordinates, `m` barriers and the extra columns `extra_names`
    /// (e.g. `["loop_us", "overrun", "clamps"]`). An extra name must be non-empty, unique,
    /// made of ASCII letters, digits and `_`, and not a standard name (`t`, `q3`, `b0`, …).
    pub fn new(n: usize, m: usize, extra_names: &[&str]) -> Result<Columns, RecordError> {
        for (k, name) in extra_names.iter().enumerate() {
            let refuse = |reason| {
                Err(RecordError::ExtraName {
                    name: (*name).to_string(),
                    reason,
                })
            };
            if name.is_empty() {
                return refuse("it is empty");
            }
            if !name.bytes().all(|c| c.is_ascii_alphanumeric() || c == b'_') {
                return refuse("use only ASCII letters, digits and `_`");
            }
            if is_standard_name(name) {
                return refuse("it is the name of a standard column");
            }
            if extra_names[..k].contains(name) {
                return refuse("it is given twice");
            }
        }
        Ok(Columns {
            n,
            m,
            extra: extra_names.iter().map(|s| (*s).to_string()).collect(),
        })
    }

    /// Number of generalized coordinates `n`.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of barriers `m`.
    pub fn m(&self) -> usize {
        self.m
    }

    /// Names of the extra columns, in order.
    pub fn extra_names(&self) -> &[String] {
        &self.extra
    }

    /// Values per row: `1 + 4n + m + extras`.
    pub fn width(&self) -> usize {
        1 + 4 * self.n + self.m + self.extra.len()
    }

    /// Name of column `index` (0-based), as written in the header.
    pub fn name(&self, index: usize) -> Option<String> {
        if index == 0 {
            return Some("t".to_string());
        }
        let mut start = 1;
        for (group, size) in GROUPS.iter().zip(self.group_sizes()) {
            if index < start + size {
                return Some(format!("{group}{}", index - start));
            }
            start += size;
        }
        self.extra.get(index - start).cloned()
    }

    /// Index of the column named `name`, if there is one.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        (0..self.width()).find(|&k| self.name(k).as_deref() == Some(name))
    }

    /// The CSV header line (without line end).
    pub fn header(&self) -> String {
        let names: Vec<String> = (0..self.width()).filter_map(|k| self.name(k)).collect();
        names.join(",")
    }

    fn group_sizes(&self) -> [usize; 5] {
        [self.n, self.n, self.n, self.n, self.m]
    }

    /// Checks the sizes of `row` against this layout.
    pub fn check(&self, row: &Row) -> Result<(), RecordError> {
        let fields = [
            ("q", row.q.len(), self.n),
            ("qd", row.qd.len(), self.n),
            ("tau", row.tau.len(), self.n),
            ("tau_nom", row.tau_nom.len(), self.n),
            ("b", row.b.len(), self.m),
            ("extra", row.extra.len(), self.extra.len()),
        ];
        for (field, found, expected) in fields {
            if found != expected {
                return Err(RecordError::RowSize {
                    field,
                    expected,
                    found,
                });
            }
        }
        Ok(())
    }
}

/// Whether `name` is `t` or a group name followed by decimal digits (`q0`, `taunom12`).
fn is_standard_name(name: &str) -> bool {
    name == "t"
        || GROUPS.iter().any(|group| {
            name.strip_prefix(group).is_some_and(|digits| {
                !digits.is_empty() && digits.bytes().all(|c| c.is_ascii_digit())
            })
        })
}

/// One control tick, borrowed from the caller (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row<'a> {
    /// Time `t` \[s\].
    pub t: f64,
    /// Generalized coordinates `q` (n) \[m\].
    pub q: &'a [f64],
    /// Generalized velocities `q̇` (n) \[m/s\].
    pub qd: &'a [f64],
    /// Applied (filtered) command `τ` (n) \[N\].
    pub tau: &'a [f64],
    /// Nominal command `τ_nom` (n) \[N\].
    pub tau_nom: &'a [f64],
    /// Barrier values `b` (m) \[m\].
    pub b: &'a [f64],
    /// Extra columns, in the order of [`Columns::extra_names`].
    pub extra: &'a [f64],
}

impl Row<'_> {
    /// The row's values in column order.
    pub fn values(&self) -> impl Iterator<Item = f64> + '_ {
        std::iter::once(self.t)
            .chain(self.q.iter().copied())
            .chain(self.qd.iter().copied())
            .chain(self.tau.iter().copied())
            .chain(self.tau_nom.iter().copied())
            .chain(self.b.iter().copied())
            .chain(self.extra.iter().copied())
    }
}

/// A trajectory held in memory: rows of [`Columns::width`] values, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Record {
    columns: Columns,
    data: Vec<f64>,
}

impl Record {
    /// An empty record with room for `rows` rows of `n` coordinates, `m` barriers and the
    /// extra columns `extra_names` (see [`Columns::new`] for allowed names).
    pub fn with_capacity(
        n: usize,
        m: usize,
        extra_names: &[&str],
        rows: usize,
    ) -> Result<Record, RecordError> {
        Ok(Record::for_columns(Columns::new(n, m, extra_names)?, rows))
    }

    /// An empty record of layout `columns` with room for `rows` rows.
    pub fn for_columns(columns: Columns, rows: usize) -> Record {
        let data = Vec::with_capacity(rows.saturating_mul(columns.width()));
        Record { columns, data }
    }

    /// Appends one row. Does not allocate while [`Record::len`] < [`Record::capacity`];
    /// beyond that the buffer grows (doubling, copying every row held so far): size the
    /// capacity for the whole run (duration × rate + 1) on a real-time path.
    /// A row of the wrong sizes is refused and nothing is appended.
    pub fn push_row(&mut self, row: &Row) -> Result<(), RecordError> {
        self.columns.check(row)?;
        self.data.push(row.t);
        for part in [row.q, row.qd, row.tau, row.tau_nom, row.b, row.extra] {
            self.data.extend_from_slice(part);
        }
        Ok(())
    }

    /// The column layout.
    pub fn columns(&self) -> &Columns {
        &self.columns
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.data.len() / self.columns.width()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Rows that fit without reallocating.
    pub fn capacity(&self) -> usize {
        self.data.capacity() / self.columns.width()
    }

    /// Removes every row, keeping the capacity.
    pub fn clear(&mut self) {
        self.data.clear();
    }

    /// All values, row-major (`len() × columns().width()`).
    pub fn values(&self) -> &[f64] {
        &self.data
    }

    /// Row `i` (0-based); `None` past the end.
    pub fn row(&self, i: usize) -> Option<Row<'_>> {
        let width = self.columns.width();
        let values = self.data.get(i * width..(i + 1) * width)?;
        let (t, rest) = values.split_first()?;
        let n = self.columns.n;
        let (q, rest) = rest.split_at(n);
        let (qd, rest) = rest.split_at(n);
        let (tau, rest) = rest.split_at(n);
        let (tau_nom, rest) = rest.split_at(n);
        let (b, extra) = rest.split_at(self.columns.m);
        Some(Row {
            t: *t,
            q,
            qd,
            tau,
            tau_nom,
            b,
            extra,
        })
    }

    /// The rows in order.
    pub fn rows(&self) -> impl Iterator<Item = Row<'_>> + '_ {
        (0..self.len()).map_while(|i| self.row(i))
    }

    /// The values of column `index` (see [`Columns::index_of`]) over all rows, in order.
    pub fn column(&self, index: usize) -> impl Iterator<Item = f64> + '_ {
        let width = self.columns.width();
        let start = if index < width {
            index
        } else {
            self.data.len()
        };
        self.data[start..].iter().step_by(width).copied()
    }

    /// Times of all rows \[s\].
    pub fn times(&self) -> impl Iterator<Item = f64> + '_ {
        self.column(0)
    }

    /// Coordinate `q_i` over all rows \[m\].
    pub fn q(&self, i: usize) -> impl Iterator<Item = f64> + '_ {
        self.group_column(0, i, self.columns.n)
    }

    /// Velocity `q̇_i` over all rows \[m/s\].
    pub fn qd(&self, i: usize) -> impl Iterator<Item = f64> + '_ {
        self.group_column(1, i, self.columns.n)
    }

    /// Applied command `τ_i` over all rows \[N\].
    pub fn tau(&self, i: usize) -> impl Iterator<Item = f64> + '_ {
        self.group_column(2, i, self.columns.n)
    }

    /// Nominal command `τ_nom,i` over all rows \[N\].
    pub fn tau_nom(&self, i: usize) -> impl Iterator<Item = f64> + '_ {
        self.group_column(3, i, self.columns.n)
    }

    /// Barrier `b_j` over all rows \[m\].
    pub fn b(&self, j: usize) -> impl Iterator<Item = f64> + '_ {
        self.group_column(4, j, self.columns.m)
    }

    /// Column `k`-th of group `group` (0 = q … 4 = b); empty if `k` is out of range.
    fn group_column(&self, group: usize, k: usize, size: usize) -> impl Iterator<Item = f64> + '_ {
        let index = if k < size {
            1 + self.columns.n * group + k
        } else {
            usize::MAX
        };
        self.column(index)
    }
}
