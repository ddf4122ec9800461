//! Gain matrices in description files (`kp`, `kd` of a robot's or a scenario's `[gains]`):
//! a number, a diagonal or the rows of a matrix, read with spans and checked once.

use std::fmt;

use nalgebra::{DMatrix, SymmetricEigen};
use serde::Deserialize;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use toml::Spanned;

use crate::limits::{Limit, short};
use crate::toml_file::{Checker, FileError};

/// A gain: a number (times the identity), a list (the diagonal) or a list of rows (the
/// matrix). Read by a visitor so that a wrong type says which forms are allowed.
#[derive(Clone, Debug)]
pub enum RawGain {
    /// `k`: `k·I`.
    Scalar(f64),
    /// `[k1, k2, …]`: the diagonal.
    Diagonal(Vec<Spanned<f64>>),
    /// `[[…], […], …]`: the rows of the matrix.
    Matrix(Vec<Spanned<Vec<Spanned<f64>>>>),
}

/// What [`RawGain`]'s visitor expects.
const GAIN_FORMS: &str = "a number, a list (the diagonal) or a list of rows";

impl<'de> Deserialize<'de> for RawGain {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct GainVisitor;
        impl<'de> Visitor<'de> for GainVisitor {
            type Value = RawGain;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str(GAIN_FORMS)
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<RawGain, E> {
                Ok(RawGain::Scalar(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<RawGain, E> {
                Ok(RawGain::Scalar(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<RawGain, E> {
                Ok(RawGain::Scalar(v as f64))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<RawGain, A::Error> {
                let mut numbers = Vec::new();
                let mut rows = Vec::new();
                while let Some(entry) = seq.next_element::<Spanned<GainEntry>>()? {
                    let span = entry.span();
                    match entry.into_inner() {
                        GainEntry::Number(v) => numbers.push(Spanned::new(span, v)),
                        GainEntry::Row(row) => rows.push(Spanned::new(span, row)),
                    }
                    if !numbers.is_empty() && !rows.is_empty() {
                        return Err(de::Error::custom(format!(
                            "mixes numbers and rows; expected {GAIN_FORMS}"
                        )));
                    }
                }
                Ok(if rows.is_empty() {
                    RawGain::Diagonal(numbers)
                } else {
                    RawGain::Matrix(rows)
                })
            }
        }
        deserializer.deserialize_any(GainVisitor)
    }
}

/// An entry of a gain list: a number (of the diagonal) or a row.
enum GainEntry {
    Number(f64),
    Row(Vec<Spanned<f64>>),
}

impl<'de> Deserialize<'de> for GainEntry {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct EntryVisitor;
        impl<'de> Visitor<'de> for EntryVisitor {
            type Value = GainEntry;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number (an entry of the diagonal) or a row (a list of numbers)")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<GainEntry, E> {
                Ok(GainEntry::Number(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<GainEntry, E> {
                Ok(GainEntry::Number(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<GainEntry, E> {
                Ok(GainEntry::Number(v as f64))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<GainEntry, A::Error> {
                let mut row = Vec::new();
                while let Some(value) = seq.next_element::<Spanned<f64>>()? {
                    row.push(value);
                }
                Ok(GainEntry::Row(row))
            }
        }
        deserializer.deserialize_any(EntryVisitor)
    }
}

/// A gain matrix `nq × nq` (row-major) from a number, a diagonal or rows. A number and the
/// diagonal lie in `limit`; a matrix has its diagonal in `limit`, every other entry within
/// `±limit.max`, and a positive semidefinite symmetric part.
pub fn gain(
    c: &Checker<'_>,
    raw: &Spanned<RawGain>,
    field: &str,
    nq: usize,
    limit: &Limit,
) -> Result<Vec<f64>, FileError> {
    let span = raw.span();
    match raw.get_ref() {
        RawGain::Scalar(k) => {
            let k = c.limited(*k, &span, field, "", limit)?;
            Ok(scaled_identity(nq, k))
        }
        RawGain::Diagonal(diagonal) => {
            if diagonal.len() != nq {
                return Err(c.invalid(
                    &span,
                    field,
                    format!(
                        "has {} entries, the robot has {nq} coordinates",
                        diagonal.len()
                    ),
                ));
            }
            let diagonal = c.list_within(diagonal, field, limit)?;
            let mut matrix = vec![0.0; nq * nq];
            for (i, k) in diagonal.iter().enumerate() {
                matrix[i * nq + i] = *k;
            }
            Ok(matrix)
        }
        RawGain::Matrix(rows) => {
            if rows.len() != nq {
                return Err(c.invalid(
                    &span,
                    field,
                    format!(
                        "has {} rows, expected {nq} (one per coordinate)",
                        rows.len()
                    ),
                ));
            }
            let off_diagonal = limit.either_sign();
            let mut matrix = vec![0.0; nq * nq];
            for (i, row) in rows.iter().enumerate() {
                let what = format!("row {}", i + 1);
                if row.get_ref().len() != nq {
                    return Err(c.invalid(
                        &row.span(),
                        &format!("{field} {what}"),
                        format!(
                            "has {} entries, the robot has {nq} coordinates",
                            row.get_ref().len()
                        ),
                    ));
                }
                for (j, entry) in row.get_ref().iter().enumerate() {
                    matrix[i * nq + j] = c.limited(
                        *entry.get_ref(),
                        &entry.span(),
                        field,
                        &format!("{what} entry {} ", j + 1),
                        if i == j { limit } else { &off_diagonal },
                    )?;
                }
            }
            if let Some(message) = indefinite(&matrix, nq) {
                return Err(c.invalid(&span, field, message));
            }
            Ok(matrix)
        }
    }
}

/// Why the symmetric part `(K + Kᵀ)/2` of a square matrix (row-major, `n × n`, finite
/// entries) is not positive semidefinite, or `None` when it is (to rounding: eigenvalues
/// down to `−1e-10·max|K_ij|` pass).
fn indefinite(matrix: &[f64], n: usize) -> Option<String> {
    let symmetric = DMatrix::from_fn(n, n, |i, j| 0.5 * (matrix[i * n + j] + matrix[j * n + i]));
    let scale = matrix.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let Some(eigen) = SymmetricEigen::try_new(symmetric, f64::EPSILON, 10_000) else {
        return Some("its eigenvalues could not be computed; give a diagonal instead".into());
    };
    let lowest = eigen
        .eigenvalues
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    (lowest < -1e-10 * scale).then(|| {
        format!(
            "the symmetric part (K + Kᵀ)/2 has the eigenvalue {}; a gain matrix must be \
             positive semidefinite (a negative eigenvalue pushes the robot away from the \
             reference)",
            short(lowest)
        )
    })
}

/// The built-in `K_P`, `K_D` of a run whose command line, scenario and robot file give
/// none: the paper's simulation gains, `K_P = 5·I` [N/m] and `K_D = 1·I` [N·s/m].
pub const PAPER_GAINS: (f64, f64) = (5.0, 1.0);

/// Default HOCBF gains `p1`, `p2` when the robot file gives none [1/s] (§5 of the model
/// notes).
pub const DEFAULT_BARRIER_GAINS: [f64; 2] = [10.0, 10.0];

/// `k·I` as an `n × n` row-major matrix.
pub fn scaled_identity(n: usize, k: f64) -> Vec<f64> {
    let mut matrix = vec![0.0; n * n];
    for i in 0..n {
        matrix[i * n + i] = k;
    }
    matrix
}

/// The shortest form of an `n × n` row-major gain matrix as a file would write it: a
/// number for `k·I`, a list for a diagonal, otherwise the rows.
pub fn written_form(matrix: &[f64], n: usize) -> GainForm {
    let entry = |i: usize, j: usize| matrix[i * n + j];
    let diagonal = (0..n).all(|i| (0..n).all(|j| i == j || entry(i, j) == 0.0));
    if !diagonal {
        return GainForm::Matrix(matrix.chunks(n.max(1)).map(<[f64]>::to_vec).collect());
    }
    let values: Vec<f64> = (0..n).map(|i| entry(i, i)).collect();
    match values.first() {
        Some(&first) if values.iter().all(|&v| v == first) => GainForm::Scalar(first),
        _ => GainForm::Diagonal(values),
    }
}

/// A gain matrix in the form a file writes it ([`written_form`]); serializes as that form.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(untagged)]
pub enum GainForm {
    /// `k·I`.
    Scalar(f64),
    /// A diagonal matrix.
    Diagonal(Vec<f64>),
    /// Any other matrix, by rows.
    Matrix(Vec<Vec<f64>>),
}

impl fmt::Display for GainForm {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        let list = |values: &[f64]| {
            let items: Vec<String> = values.iter().map(|v| short(*v)).collect();
            format!("[{}]", items.join(", "))
        };
        match self {
            GainForm::Scalar(k) => write!(f, "{}", short(*k)),
            GainForm::Diagonal(values) => write!(f, "diag{}", list(values)),
            GainForm::Matrix(rows) => {
                let rows: Vec<String> = rows.iter().map(|r| list(r)).collect();
                write!(f, "[{}]", rows.join(", "))
            }
        }
    }
}
