//! Checked TOML description files (robots, scenarios, hardware): the error type that names
//! the file, line and field, and the number checks and span lookups every parser shares.

use std::ops::Range;
use std::path::{Path, PathBuf};

use toml::Spanned;
use toml::de::{DeTable, DeValue};

/// Why a description file could not be used. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// The file could not be read.
    #[error("{path}: cannot read {kind}: {source}", path = path.display())]
    Io {
        path: PathBuf,
        /// What the file was meant to be ("robot file", "scenario file").
        kind: &'static str,
        source: std::io::Error,
    },
    /// The file is not valid TOML or a field has the wrong type.
    #[error("{path}:{line}:{column}: {message}", path = path.display())]
    Syntax {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
    /// A field has a value that cannot be used.
    #[error("{path}:{line}: field `{field}`: {message}", path = path.display())]
    Invalid {
        path: PathBuf,
        line: usize,
        field: String,
        message: String,
    },
}

/// Reads a description file of the given kind ("robot file", …).
pub fn read(path: &Path, kind: &'static str) -> Result<String, FileError> {
    std::fs::read_to_string(path).map_err(|source| FileError::Io {
        path: path.to_path_buf(),
        kind,
        source,
    })
}

/// What a number must be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rule {
    /// Any finite number.
    Finite,
    /// Finite and > 0.
    Positive,
    /// Finite and ≥ 0.
    NonNegative,
}

/// Checks the values of one file against rules and builds errors located in it.
#[derive(Clone, Copy)]
pub struct Checker<'a> {
    /// The file's text (for line numbers).
    pub text: &'a str,
    /// The file's path (for messages).
    pub path: &'a Path,
}

impl Checker<'_> {
    /// An [`FileError::Invalid`] for the value written at `span`.
    pub fn invalid(&self, span: &Range<usize>, field: &str, message: String) -> FileError {
        FileError::Invalid {
            path: self.path.to_path_buf(),
            line: line_column(self.text, span.start).0,
            field: field.to_string(),
            message,
        }
    }

    /// A [`FileError::Syntax`] from a TOML/serde error, naming the field it concerns.
    pub fn syntax(&self, error: &toml::de::Error) -> FileError {
        let span = error.span().unwrap_or(0..0);
        let (line, column) = line_column(self.text, span.start);
        FileError::Syntax {
            path: self.path.to_path_buf(),
            line,
            column,
            message: describe(self.text, span.start, error.message()),
        }
    }

    /// Checks one number against `rule`; `unit` is for the message.
    pub fn number(
        &self,
        v: &Spanned<f64>,
        field: &str,
        rule: Rule,
        unit: &str,
    ) -> Result<f64, FileError> {
        self.check(*v.get_ref(), &v.span(), field, "", rule, unit)
    }

    /// Checks `value` (written at `span`, described in messages as `what`, e.g. "entry 2 ").
    pub fn check(
        &self,
        value: f64,
        span: &Range<usize>,
        field: &str,
        what: &str,
        rule: Rule,
        unit: &str,
    ) -> Result<f64, FileError> {
        let unit = if unit.is_empty() {
            String::new()
        } else {
            format!(" {unit}")
        };
        let problem = if !value.is_finite() {
            Some(format!("{what}must be a finite number, got {value}"))
        } else {
            match rule {
                Rule::Finite => None,
                Rule::Positive if value <= 0.0 => {
                    Some(format!("{what}must be > 0{unit}, got {value}"))
                }
                Rule::NonNegative if value < 0.0 => {
                    Some(format!("{what}must be ≥ 0{unit}, got {value}"))
                }
                Rule::Positive | Rule::NonNegative => None,
            }
        };
        match problem {
            Some(message) => Err(self.invalid(span, field, message)),
            None => Ok(value),
        }
    }

    /// Checks every entry of an array of numbers.
    pub fn list(
        &self,
        v: &[Spanned<f64>],
        field: &str,
        rule: Rule,
        unit: &str,
    ) -> Result<Vec<f64>, FileError> {
        v.iter()
            .enumerate()
            .map(|(k, x)| {
                self.check(
                    *x.get_ref(),
                    &x.span(),
                    field,
                    &format!("entry {} ", k + 1),
                    rule,
                    unit,
                )
            })
            .collect()
    }

    /// An array that must have exactly three entries.
    pub fn three(
        &self,
        values: Vec<f64>,
        v: &Spanned<Vec<Spanned<f64>>>,
        field: &str,
        what: &str,
    ) -> Result<[f64; 3], FileError> {
        let n = values.len();
        <[f64; 3]>::try_from(values)
            .map_err(|_| self.invalid(&v.span(), field, format!("needs 3 {what}, got {n} entries")))
    }
}

// ---------------------------------------------------------------------------------------
// Positions and messages of syntax errors.

/// 1-based line and column (in characters) of byte offset `at` in `text`.
pub fn line_column(text: &str, at: usize) -> (usize, usize) {
    let bytes = &text.as_bytes()[..at.min(text.len())];
    let line = 1 + bytes.iter().filter(|&&b| b == b'\n').count();
    let start = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1);
    let column = 1 + bytes[start..].iter().filter(|&&b| b & 0xC0 != 0x80).count();
    (line, column)
}

/// Where a byte offset falls in the parsed document.
struct Hit {
    /// Path of the table holding the key (`""`, `barrier`, `module[2]`).
    table: String,
    /// Path of the field (`module[2].mass`).
    field: String,
    /// 1-based entry when inside an array of values.
    entry: Option<usize>,
    /// On the key rather than the value.
    key: bool,
    /// Span length, to keep the innermost hit.
    len: usize,
}

fn keep(best: &mut Option<Hit>, span: Range<usize>, at: usize, hit: impl FnOnce(usize) -> Hit) {
    let inside = span.start <= at && (at < span.end || span.is_empty() && at == span.start);
    let len = span.end.saturating_sub(span.start);
    if inside && best.as_ref().is_none_or(|b| len < b.len) {
        *best = Some(hit(len));
    }
}

fn locate_table(table: &DeTable, prefix: &str, at: usize, best: &mut Option<Hit>) {
    for (key, value) in table.iter() {
        let field = if prefix.is_empty() {
            key.get_ref().to_string()
        } else {
            format!("{prefix}.{}", key.get_ref())
        };
        keep(best, key.span(), at, |len| Hit {
            table: prefix.to_string(),
            field: field.clone(),
            entry: None,
            key: true,
            len,
        });
        locate_value(value, prefix, &field, None, at, best);
    }
}

fn locate_value(
    value: &Spanned<DeValue>,
    table: &str,
    field: &str,
    entry: Option<usize>,
    at: usize,
    best: &mut Option<Hit>,
) {
    keep(best, value.span(), at, |len| Hit {
        table: table.to_string(),
        field: field.to_string(),
        entry,
        key: false,
        len,
    });
    match value.get_ref() {
        DeValue::Table(inner) => locate_table(inner, field, at, best),
        DeValue::Array(items) => {
            for (k, item) in items.iter().enumerate() {
                if matches!(item.get_ref(), DeValue::Table(_)) {
                    let path = format!("{field}[{}]", k + 1);
                    locate_table_in(item, &path, at, best);
                } else {
                    locate_value(item, table, field, Some(k + 1), at, best);
                }
            }
        }
        _ => {}
    }
}

fn locate_table_in(item: &Spanned<DeValue>, path: &str, at: usize, best: &mut Option<Hit>) {
    if let DeValue::Table(inner) = item.get_ref() {
        locate_table(inner, path, at, best);
    }
}

/// The message of a serde/TOML error at byte `at`, with the field or table it concerns.
pub fn describe(text: &str, at: usize, message: &str) -> String {
    let message = message
        .replace("expected f64", "expected a number")
        .replace("expected i64", "expected an integer");
    let Ok(document) = DeTable::parse(text) else {
        return message;
    };
    let mut best = None;
    locate_table(document.get_ref(), "", at, &mut best);
    let Some(hit) = best else {
        return message;
    };
    if hit.key
        && let Some(rest) = message.strip_prefix("unknown field `")
        && let Some((name, expected)) = rest.split_once("`, ")
    {
        let place = if hit.table.is_empty() {
            "at top level".to_string()
        } else if let Some((name, i)) = hit.table.strip_suffix(']').and_then(|s| s.rsplit_once('['))
        {
            format!("in [[{name}]] {i}")
        } else {
            format!("in [{}]", hit.table)
        };
        return format!("unknown field `{name}` {place}; {expected}");
    }
    match hit.entry {
        Some(k) => format!("field `{}`, entry {k}: {message}", hit.field),
        None => format!("field `{}`: {message}", hit.field),
    }
}

/// Assertions shared by the parsers' unit tests.
#[cfg(test)]
pub(crate) mod testing {
    use super::FileError;

    /// Asserts that `result` is an [`FileError::Invalid`] at `line` on `field`, with
    /// `fragment` in the message.
    #[track_caller]
    pub(crate) fn assert_invalid<T: std::fmt::Debug>(
        result: Result<T, FileError>,
        line: usize,
        field: &str,
        fragment: &str,
    ) {
        match result {
            Err(FileError::Invalid {
                line: l,
                field: f,
                message,
                ..
            }) => {
                assert_eq!((l, f.as_str()), (line, field), "message: {message}");
                assert!(message.contains(fragment), "`{message}` lacks `{fragment}`");
            }
            other => panic!("expected an Invalid error on {field}, got {other:?}"),
        }
    }
}
