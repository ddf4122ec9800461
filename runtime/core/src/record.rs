//! Trajectory record of a run: one row per control tick, or per recorded instant of a dense
//! simulation (`t`, `q`, `q̇`, `τ`, `τ_nom`, `b` and named extra columns), preallocated so
//! that recording allocates nothing per row.
//!
//! The column layout ([`Columns`]) is fixed at construction: the coordinates' names, the
//! barriers' labels and units (from the model's barrier table) and the extra columns. Rows
//! are stored row-major in one buffer; [`Record::push_row`] copies a [`Row`] into it. The
//! CSV form is written by [`Record::write_csv`], streamed during a run by [`CsvWriter`] and
//! read back by [`Record::read_csv`]; the three share one formatting and parsing code path
//! (in `record/csv.rs`).
//!
//! # Column names
//!
//! One header line, then one line per row; every name is unique, ASCII for the standard
//! columns, without commas, quotes or line breaks, so a spreadsheet or
//! `pandas.read_csv("trajectory.csv")` reads the file as it is and `df["dx1 [m]"]` can be
//! typed. Each name carries its unit in brackets:
//!
//! | columns | name | example |
//! |---|---|---|
//! | time | `t [s]` | `t [s]` |
//! | coordinates `q` | `<c> [m]` | `dx1 [m]`, `dy1 [m]`, `dL1 [m]` (`Δx₁`, `Δy₁`, `δL₁`) |
//! | velocities `q̇` | `<c>/dt [m/s]` | `dx1/dt [m/s]` |
//! | applied command `τ` | `tau <c> [N]` | `tau dL2 [N]` |
//! | nominal command `τ_nom` | `tau_nom <c> [N]` | `tau_nom dL2 [N]` |
//! | barriers `b` | `b <label> [<unit>]` | `b module 1 corner 3 [m]`, `b module 2 bend [rad]` |
//! | extras | as given, unit in brackets | `read [us]`, `f module 1 tendon 2 [N]` |
//!
//! Coordinates are named by [`coordinate_names`] (module numbers from 1, as in the paper's
//! `Δx₁`); barrier labels are taken as the model's barrier table gives them
//! (`softcbf_generated::BarrierInfo::label`), and a barrier's unit is its kind's
//! ([`BARRIER_UNITS`]: `m`, or `rad` for a bend limit). [`Record::read_csv`] also reads the
//! older header `t,q0,…,qd0,…,tau0,…,taunom0,…,b0,…` (then the coordinates get the
//! standard names, the barriers the labels `barrier 1`, `barrier 2`, … and the unit `m`).
//!
//! ```
//! use softcbf_core::record::{Columns, Record, Row};
//! let columns = Columns::named(&["dx1"], &["module 1 corner 1"], &["loop [us]"])?;
//! let mut record = Record::for_columns(columns, 10_001);
//! let row = Row { t: 0.0, q: &[0.01], qd: &[0.0], tau: &[0.5], tau_nom: &[0.7], b: &[0.02], extra: &[12.0] };
//! record.push_row(&row)?; // no allocation: 10 001 rows were reserved
//! let mut csv = Vec::new();
//! record.write_csv_to(&mut csv)?;
//! assert_eq!(
//!     String::from_utf8(csv)?,
//!     "t [s],dx1 [m],dx1/dt [m/s],tau dx1 [N],tau_nom dx1 [N],b module 1 corner 1 [m],loop [us]\n\
//!      0,0.01,0,0.5,0.7,0.02,12\n"
//! );
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod csv;
pub mod status;

use std::path::PathBuf;

pub use csv::CsvWriter;

use crate::model::Model;

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
    #[error("{}:1: empty file, expected the header `t [s],…`", file.display())]
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
    /// A coordinate name, barrier label, barrier unit or extra column name cannot be used.
    #[error("{what} `{name}`: {reason}")]
    ColumnName {
        /// What kind of name: `coordinate name`, `barrier label`, `barrier unit` or
        /// `extra column name`.
        what: &'static str,
        /// The name.
        name: String,
        /// Why it is refused.
        reason: &'static str,
    },
    /// A layout's barrier units are not one per barrier.
    #[error("{found} barrier units for {expected} barriers")]
    UnitCount {
        /// Number of barriers.
        expected: usize,
        /// Number of units given.
        found: usize,
    },
    /// A new layout for a record does not have the record's sizes.
    #[error("the new columns have {found} {what}, the record has {expected}")]
    Relabel {
        /// `coordinates`, `barriers` or `extra columns`.
        what: &'static str,
        /// The record's count.
        expected: usize,
        /// The new layout's count.
        found: usize,
    },
}

/// Name of the time column.
pub const TIME: &str = "t [s]";

/// The units a barrier column may have: `m` (corners, elongation limits, obstacles) and
/// `rad` (bend limits), as `softcbf_generated::BarrierKind::unit` gives them.
pub const BARRIER_UNITS: [&str; 2] = ["m", "rad"];

/// The groups of per-coordinate columns, in column order (the barrier columns follow
/// them: [`barrier_column`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Group {
    Q,
    Qd,
    Tau,
    TauNom,
}

impl Group {
    const ALL: [Group; 4] = [Group::Q, Group::Qd, Group::Tau, Group::TauNom];

    /// `(prefix, suffix)` around a coordinate name.
    fn affixes(self) -> (&'static str, &'static str) {
        match self {
            Group::Q => ("", " [m]"),
            Group::Qd => ("", "/dt [m/s]"),
            Group::Tau => ("tau ", " [N]"),
            Group::TauNom => ("tau_nom ", " [N]"),
        }
    }

    /// The column name of coordinate `name` in this group.
    fn column(self, name: &str) -> String {
        let (prefix, suffix) = self.affixes();
        format!("{prefix}{name}{suffix}")
    }

    /// The coordinate name inside `column`, if it has this group's form.
    fn strip(self, column: &str) -> Option<&str> {
        let (prefix, suffix) = self.affixes();
        column
            .strip_prefix(prefix)?
            .strip_suffix(suffix)
            .filter(|inner| !inner.is_empty())
    }
}

/// The column name of a barrier: `b <label> [<unit>]`.
fn barrier_column(label: &str, unit: &str) -> String {
    format!("b {label} [{unit}]")
}

/// The label and unit of a barrier column `b <label> [<unit>]` with one of
/// [`BARRIER_UNITS`], if `column` has that form.
fn strip_barrier(column: &str) -> Option<(&str, &'static str)> {
    let inner = column.strip_prefix("b ")?;
    BARRIER_UNITS.iter().find_map(|&unit| {
        let label = inner
            .strip_suffix(']')?
            .strip_suffix(unit)?
            .strip_suffix(" [")?;
        (!label.is_empty()).then_some((label, unit))
    })
}

/// Names of `n` generalized coordinates in CSV columns: `dx1, dy1, dL1, dx2, …` for the
/// paper's `Δx₁, Δy₁, δL₁, Δx₂, …` (docs/model.md §1) when `n` is a multiple of 3, else
/// `q1, q2, …`. Modules are numbered from 1.
pub fn coordinate_names(n: usize) -> Vec<String> {
    if !n.is_multiple_of(3) {
        return (1..=n).map(|k| format!("q{k}")).collect();
    }
    (0..n)
        .map(|k| format!("{}{}", ["dx", "dy", "dL"][k % 3], k / 3 + 1))
        .collect()
}

/// Labels of `m` barriers when nothing better is known (an old log): `barrier 1, …`.
pub fn default_barrier_labels(m: usize) -> Vec<String> {
    (1..=m).map(|j| format!("barrier {j}")).collect()
}

/// The names as string slices, for [`Columns::named`].
pub fn as_strs(names: &[String]) -> Vec<&str> {
    names.iter().map(String::as_str).collect()
}

/// Why `name` cannot be used in a header, if it cannot: empty, blank at either end, or
/// holding a comma, a quote or a control character (a line break, a tab).
fn csv_name_problem(name: &str) -> Option<&'static str> {
    if name.is_empty() {
        Some("it is empty")
    } else if name.trim() != name {
        Some("it starts or ends with a blank")
    } else if name.chars().any(|c| c == ',' || c == '"' || c.is_control()) {
        Some("commas, quotes and control characters are not allowed")
    } else {
        None
    }
}

/// The column layout: named coordinates, labelled barriers with their units and named
/// extra scalar columns.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Columns {
    coordinates: Vec<String>,
    barriers: Vec<String>,
    barrier_units: Vec<&'static str>,
    extra: Vec<String>,
}

impl Columns {
    /// Layout for `n` coordinates named by [`coordinate_names`], `m` barriers labelled by
    /// [`default_barrier_labels`] and the extra columns `extra_names` (see
    /// [`Columns::named`]).
    pub fn new(n: usize, m: usize, extra_names: &[&str]) -> Result<Columns, RecordError> {
        let coordinates = coordinate_names(n);
        let barriers = default_barrier_labels(m);
        Columns::named(&as_strs(&coordinates), &as_strs(&barriers), extra_names)
    }

    /// Layout for `model`: its coordinates ([`coordinate_names`]), its barriers labelled as
    /// its barrier table labels them with their kinds' units, and the extra columns
    /// `extra_names`.
    pub fn for_model(model: &Model, extra_names: &[&str]) -> Result<Columns, RecordError> {
        let coordinates = coordinate_names(model.nq());
        let coordinates: Vec<&str> = coordinates.iter().map(String::as_str).collect();
        let table = model.generated.barrier_table();
        let labels: Vec<&str> = table.iter().map(|b| b.label).collect();
        let units: Vec<&str> = table.iter().map(|b| b.kind.unit()).collect();
        Columns::named_with_units(&coordinates, &labels, &units, extra_names)
    }

    /// Layout from the coordinates' names (ASCII letters, digits and `_`, e.g. `dx1`), the
    /// barriers' labels (any text without brackets, e.g. `module 1 corner 3`), all in
    /// metres, and the extra columns' names (e.g. `read [us]`). No name may be empty, start
    /// or end with a blank, or hold a comma, a quote or a control character; an extra name
    /// may not have the form of a barrier column (`b … [m]`, `b … [rad]`); every column name
    /// of the header must be unique.
    pub fn named(
        coordinates: &[&str],
        barriers: &[&str],
        extra_names: &[&str],
    ) -> Result<Columns, RecordError> {
        let units = vec!["m"; barriers.len()];
        Columns::named_with_units(coordinates, barriers, &units, extra_names)
    }

    /// As [`Columns::named`], with each barrier's unit (one of [`BARRIER_UNITS`], one per
    /// barrier label).
    pub fn named_with_units(
        coordinates: &[&str],
        barriers: &[&str],
        barrier_units: &[&str],
        extra_names: &[&str],
    ) -> Result<Columns, RecordError> {
        let refuse = |what, name: &str, reason| {
            Err(RecordError::ColumnName {
                what,
                name: name.to_string(),
                reason,
            })
        };
        for name in coordinates {
            if let Some(reason) = csv_name_problem(name) {
                return refuse("coordinate name", name, reason);
            }
            if !name.bytes().all(|c| c.is_ascii_alphanumeric() || c == b'_') {
                return refuse(
                    "coordinate name",
                    name,
                    "use only ASCII letters, digits and `_`",
                );
            }
        }
        for label in barriers {
            if let Some(reason) = csv_name_problem(label) {
                return refuse("barrier label", label, reason);
            }
            if label.contains(['[', ']']) {
                return refuse("barrier label", label, "brackets are kept for units");
            }
        }
        if barrier_units.len() != barriers.len() {
            return Err(RecordError::UnitCount {
                expected: barriers.len(),
                found: barrier_units.len(),
            });
        }
        let mut units = Vec::with_capacity(barrier_units.len());
        for unit in barrier_units {
            match BARRIER_UNITS.iter().find(|known| *known == unit) {
                Some(known) => units.push(*known),
                None => return refuse("barrier unit", unit, "a barrier is in `m` or `rad`"),
            }
        }
        for name in extra_names {
            if let Some(reason) = csv_name_problem(name) {
                return refuse("extra column name", name, reason);
            }
            if strip_barrier(name).is_some() {
                return refuse(
                    "extra column name",
                    name,
                    "`b … [m]` and `b … [rad]` are the forms of a barrier column",
                );
            }
        }
        let columns = Columns {
            coordinates: coordinates.iter().map(|s| (*s).to_string()).collect(),
            barriers: barriers.iter().map(|s| (*s).to_string()).collect(),
            barrier_units: units,
            extra: extra_names.iter().map(|s| (*s).to_string()).collect(),
        };
        let mut names: Vec<(String, usize)> = (0..columns.width())
            .filter_map(|k| columns.name(k).map(|name| (name, k)))
            .collect();
        names.sort();
        if let Some(pair) = names.windows(2).find(|pair| pair[0].0 == pair[1].0) {
            let (what, name) = columns.source_of(pair[0].1.max(pair[1].1));
            return refuse(what, &name, "it makes a column name that is given twice");
        }
        Ok(columns)
    }

    /// What kind of name made column `index`, and that name.
    fn source_of(&self, index: usize) -> (&'static str, String) {
        let n = self.n();
        let m = self.m();
        if index == 0 {
            ("time column", TIME.to_string())
        } else if index <= 4 * n {
            ("coordinate name", self.coordinates[(index - 1) % n].clone())
        } else if index <= 4 * n + m {
            ("barrier label", self.barriers[index - 1 - 4 * n].clone())
        } else {
            (
                "extra column name",
                self.extra
                    .get(index - 1 - 4 * n - m)
                    .cloned()
                    .unwrap_or_default(),
            )
        }
    }

    /// Number of generalized coordinates `n`.
    pub fn n(&self) -> usize {
        self.coordinates.len()
    }

    /// Number of barriers `m`.
    pub fn m(&self) -> usize {
        self.barriers.len()
    }

    /// Names of the coordinates (e.g. `dx1`), in order.
    pub fn coordinate_names(&self) -> &[String] {
        &self.coordinates
    }

    /// Labels of the barriers (e.g. `module 1 corner 3`), in order.
    pub fn barrier_labels(&self) -> &[String] {
        &self.barriers
    }

    /// Units of the barriers (`m`, or `rad` for a bend limit), in order.
    pub fn barrier_units(&self) -> &[&'static str] {
        &self.barrier_units
    }

    /// Names of the extra columns, in order.
    pub fn extra_names(&self) -> &[String] {
        &self.extra
    }

    /// Values per row: `1 + 4n + m + extras`.
    pub fn width(&self) -> usize {
        1 + 4 * self.n() + self.m() + self.extra.len()
    }

    /// Name of column `index` (0-based), as written in the header.
    pub fn name(&self, index: usize) -> Option<String> {
        if index == 0 {
            return Some(TIME.to_string());
        }
        let mut start = 1;
        for group in Group::ALL {
            if let Some(name) = self.coordinates.get(index - start) {
                return Some(group.column(name));
            }
            start += self.n();
        }
        if let Some((label, unit)) = self
            .barriers
            .get(index - start)
            .zip(self.barrier_units.get(index - start))
        {
            return Some(barrier_column(label, unit));
        }
        self.extra.get(index - start - self.m()).cloned()
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

    /// Checks the sizes of `row` against this layout.
    pub fn check(&self, row: &Row) -> Result<(), RecordError> {
        let (n, m) = (self.n(), self.m());
        let fields = [
            ("q", row.q.len(), n),
            ("qd", row.qd.len(), n),
            ("tau", row.tau.len(), n),
            ("tau_nom", row.tau_nom.len(), n),
            ("b", row.b.len(), m),
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

/// One row: a control tick, or an instant between ticks of a dense simulation, borrowed
/// from the caller (SI units).
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
    /// Barrier values `b` (`m` of them), each in its unit ([`Columns::barrier_units`]:
    /// \[m\], or \[rad\] for a bend limit).
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

    /// Replaces the names of the columns (e.g. the barrier labels of a robot file, for an
    /// old log that has none) by `columns`, which must have the same numbers of
    /// coordinates, barriers and extra columns; the values are kept.
    pub fn relabel(&mut self, columns: Columns) -> Result<(), RecordError> {
        let counts = [
            ("coordinates", self.columns.n(), columns.n()),
            ("barriers", self.columns.m(), columns.m()),
            (
                "extra columns",
                self.columns.extra_names().len(),
                columns.extra_names().len(),
            ),
        ];
        for (what, expected, found) in counts {
            if expected != found {
                return Err(RecordError::Relabel {
                    what,
                    expected,
                    found,
                });
            }
        }
        self.columns = columns;
        Ok(())
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
        let n = self.columns.n();
        let (q, rest) = rest.split_at(n);
        let (qd, rest) = rest.split_at(n);
        let (tau, rest) = rest.split_at(n);
        let (tau_nom, rest) = rest.split_at(n);
        let (b, extra) = rest.split_at(self.columns.m());
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
        self.group_column(0, i, self.columns.n())
    }

    /// Velocity `q̇_i` over all rows \[m/s\].
    pub fn qd(&self, i: usize) -> impl Iterator<Item = f64> + '_ {
        self.group_column(1, i, self.columns.n())
    }

    /// Applied command `τ_i` over all rows \[N\].
    pub fn tau(&self, i: usize) -> impl Iterator<Item = f64> + '_ {
        self.group_column(2, i, self.columns.n())
    }

    /// Nominal command `τ_nom,i` over all rows \[N\].
    pub fn tau_nom(&self, i: usize) -> impl Iterator<Item = f64> + '_ {
        self.group_column(3, i, self.columns.n())
    }

    /// Barrier `b_j` over all rows, in its unit ([`Columns::barrier_units`]).
    pub fn b(&self, j: usize) -> impl Iterator<Item = f64> + '_ {
        self.group_column(4, j, self.columns.m())
    }

    /// Column `k`-th of group `group` (0 = q … 4 = b); empty if `k` is out of range.
    fn group_column(&self, group: usize, k: usize, size: usize) -> impl Iterator<Item = f64> + '_ {
        let index = if k < size {
            1 + self.columns.n() * group + k
        } else {
            usize::MAX
        };
        self.column(index)
    }
}
