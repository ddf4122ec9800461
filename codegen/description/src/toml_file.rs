//! Checked TOML description files (robots, scenarios, hardware): the reading, range checks
//! and span lookups every parser shares, and the error that names the file, line and field.

use std::io::Read;
use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use serde_path_to_error::Segment;
use toml::Spanned;
use toml::de::{DeTable, DeValue};

use crate::limits::Limit;

/// Why a description file could not be used. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// The file could not be read (or is larger than [`MAX_FILE_BYTES`]).
    #[error("{path}: cannot read {kind}: {source}", path = path.display())]
    Io {
        path: PathBuf,
        /// What the file was meant to be ("robot file", "scenario file").
        kind: &'static str,
        source: std::io::Error,
    },
    /// The file is not UTF-8 text, not valid TOML, or a field has the wrong type.
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

/// Largest description file read \[bytes\] (1 MiB): the shipped files have a few kB, and a
/// larger one (`/dev/zero`, a pipe that never ends) is refused before it fills the memory.
pub const MAX_FILE_BYTES: u64 = 1 << 20;

/// Reads a description file of the given kind ("robot file", …): at most
/// [`MAX_FILE_BYTES`], and UTF-8 text ([`decode`]).
pub fn read(path: &Path, kind: &'static str) -> Result<String, FileError> {
    let io = |source| FileError::Io {
        path: path.to_path_buf(),
        kind,
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::new();
    file.take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(io(std::io::Error::new(
            std::io::ErrorKind::FileTooLarge,
            format!(
                "larger than {MAX_FILE_BYTES} bytes (1 MiB), the most a description file may \
                 have"
            ),
        )));
    }
    decode(bytes, path)
}

/// The text of a description file's bytes; not UTF-8 is a [`FileError::Syntax`] at the
/// line and column of the first byte that is not.
pub fn decode(bytes: Vec<u8>, path: &Path) -> Result<String, FileError> {
    String::from_utf8(bytes).map_err(|error| {
        let at = error.utf8_error().valid_up_to();
        let bytes = error.as_bytes();
        let valid = std::str::from_utf8(&bytes[..at]).unwrap_or_default();
        let (line, column) = line_column(valid, at);
        FileError::Syntax {
            path: path.to_path_buf(),
            line,
            column,
            message: format!(
                "not UTF-8 text: byte 0x{:02X} does not belong to a character here; \
                 description files are UTF-8",
                bytes.get(at).copied().unwrap_or(0)
            ),
        }
    })
}

/// Checks the values of one file against their [`Limit`]s and builds errors located in it.
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

    /// A [`FileError::Syntax`] from a TOML error: at its position, with the message of
    /// [`describe_toml`] (a duplicate key also names the line of its first definition).
    pub fn syntax(&self, error: &toml::de::Error) -> FileError {
        self.syntax_at(error, describe_toml(self.text, error))
    }

    fn syntax_at(&self, error: &toml::de::Error, message: String) -> FileError {
        let span = error.span().unwrap_or(0..0);
        let (line, column) = line_column(self.text, span.start);
        FileError::Syntax {
            path: self.path.to_path_buf(),
            line,
            column,
            message,
        }
    }

    /// Checks `value`, written at `span`, against `limit`; `what` names it in the message
    /// (`""`, or `"entry 2 "`): `field `x`: entry 2 must be ≥ 0 and ≤ 1 m, got -1`.
    pub fn limited(
        &self,
        value: f64,
        span: &Range<usize>,
        field: &str,
        what: &str,
        limit: &Limit,
    ) -> Result<f64, FileError> {
        limit
            .check(value)
            .map_err(|message| self.invalid(span, field, format!("{what}{message}")))
    }

    /// Checks one number against `limit`, with the file, line and field in the error.
    pub fn within(&self, v: &Spanned<f64>, field: &str, limit: &Limit) -> Result<f64, FileError> {
        self.limited(*v.get_ref(), &v.span(), field, "", limit)
    }

    /// Checks one integer against `limit` (an integer [`Limit`]).
    pub fn integer_within(
        &self,
        v: &Spanned<i64>,
        field: &str,
        limit: &Limit,
    ) -> Result<i64, FileError> {
        limit
            .check_integer(*v.get_ref())
            .map_err(|message| self.invalid(&v.span(), field, message))
    }

    /// Checks every entry of an array of numbers against `limit` (errors name the entry,
    /// from 1, and its line).
    pub fn list_within(
        &self,
        v: &[Spanned<f64>],
        field: &str,
        limit: &Limit,
    ) -> Result<Vec<f64>, FileError> {
        v.iter()
            .enumerate()
            .map(|(k, x)| {
                self.limited(
                    *x.get_ref(),
                    &x.span(),
                    field,
                    &format!("entry {} ", k + 1),
                    limit,
                )
            })
            .collect()
    }

    /// Checks that every entry of an array is a finite number (for vectors whose range
    /// depends on the robot, checked next with [`Checker::state`]).
    pub fn finite_list(&self, v: &[Spanned<f64>], field: &str) -> Result<Vec<f64>, FileError> {
        v.iter()
            .enumerate()
            .map(|(k, x)| {
                let value = *x.get_ref();
                if value.is_finite() {
                    Ok(value)
                } else {
                    Err(self.invalid(
                        &x.span(),
                        field,
                        format!("entry {} must be a finite number, got {value}", k + 1),
                    ))
                }
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

impl<'a> Checker<'a> {
    /// Reads the file's text into `T` with serde. Not TOML, a value of the wrong type or an
    /// unknown field is a [`FileError::Syntax`] naming the field: its path comes from
    /// `serde_path_to_error`, with arrays of tables and entries counted from 1.
    pub fn deserialize<T: Deserialize<'a>>(&self) -> Result<T, FileError> {
        let document = toml::Deserializer::parse(self.text).map_err(|error| self.syntax(&error))?;
        serde_path_to_error::deserialize(document).map_err(|error| {
            let place = place(error.path());
            let inner = error.inner();
            let message = plain_words(inner.message());
            let message = if place.is_empty() {
                message
            } else {
                format!("{place}: {message}")
            };
            self.syntax_at(inner, message)
        })
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

/// The message of a TOML error: for a duplicate key, the key, its field and the line
/// where it was first given; otherwise TOML's own message.
pub fn describe_toml(text: &str, error: &toml::de::Error) -> String {
    let message = error.message();
    match error.span() {
        Some(span) if message.starts_with("duplicate key") => duplicate(text, &span),
        _ => message.to_string(),
    }
}

/// Where a serde error lies, from its path: ``field `module[2].mass` ``,
/// ``field `gravity`, entry 2``, ``field `gains.kd`, row 1 entry 2``. Arrays of tables
/// count from 1; the private keys of `toml::Spanned` are left out.
fn place(path: &serde_path_to_error::Path) -> String {
    let mut field = String::new();
    let mut entries: Vec<usize> = Vec::new();
    for segment in path.iter() {
        match segment {
            Segment::Map { key } if key.starts_with("$__serde_spanned_private") => {}
            Segment::Map { key } | Segment::Enum { variant: key } => {
                // Indices before a key belong to an array of tables.
                for k in entries.drain(..) {
                    field.push_str(&format!("[{k}]"));
                }
                if !field.is_empty() {
                    field.push('.');
                }
                field.push_str(key);
            }
            Segment::Seq { index } => entries.push(index + 1),
            Segment::Unknown => {}
        }
    }
    if field.is_empty() {
        return String::new();
    }
    match entries[..] {
        [] => format!("field `{field}`"),
        [k] => format!("field `{field}`, entry {k}"),
        [i, j] => format!("field `{field}`, row {i} entry {j}"),
        ref deeper => {
            let path: Vec<String> = deeper.iter().map(|k| k.to_string()).collect();
            format!("field `{field}`, entry {}", path.join("."))
        }
    }
}

/// serde names the Rust type it expected (`expected f64`); the files speak of numbers.
fn plain_words(message: &str) -> String {
    message
        .replace("expected f64", "expected a number")
        .replace("expected i64", "expected an integer")
}

/// Every key of `table` (recursively): its name, span and field path.
fn keys(table: &DeTable, prefix: &str, out: &mut Vec<(String, Range<usize>, String)>) {
    for (key, value) in table.iter() {
        let name = key.get_ref().to_string();
        let field = if prefix.is_empty() {
            name.clone()
        } else {
            format!("{prefix}.{name}")
        };
        out.push((name, key.span(), field.clone()));
        match value.get_ref() {
            DeValue::Table(inner) => keys(inner, &field, out),
            DeValue::Array(items) => {
                for (k, item) in items.iter().enumerate() {
                    if let DeValue::Table(inner) = item.get_ref() {
                        keys(inner, &format!("{field}[{}]", k + 1), out);
                    }
                }
            }
            _ => {}
        }
    }
}

/// The message of a duplicate key written at `span`: the key, and the field and line of
/// its first definition (the closest earlier key of that name in the recovered document).
fn duplicate(text: &str, span: &Range<usize>) -> String {
    let written = text.get(span.clone()).unwrap_or("").trim();
    let name = written
        .strip_prefix('"')
        .and_then(|s| s.strip_suffix('"'))
        .or_else(|| {
            written
                .strip_prefix('\'')
                .and_then(|s| s.strip_suffix('\''))
        })
        .unwrap_or(written);
    let (document, _) = DeTable::parse_recoverable(text);
    let mut all = Vec::new();
    keys(document.get_ref(), "", &mut all);
    let first = all
        .iter()
        .filter(|(key, at, _)| key == name && at.start < span.start)
        .max_by_key(|(_, at, _)| at.start);
    match first {
        Some((_, at, field)) => format!(
            "duplicate key `{name}`: field `{field}` is already given on line {}; give each \
             key (and each [table]) once",
            line_column(text, at.start).0
        ),
        None => match earlier_line(text, span.start, name) {
            Some(line) => format!(
                "duplicate key `{name}`: already given on line {line}; give each key (and \
                 each [table]) once"
            ),
            None => format!("duplicate key `{name}`: give each key (and each [table]) once"),
        },
    }
}

/// The first line before byte `at` that defines `name` again: the same `[table]` header
/// as the line of `at`, or a line starting with `name` (`name = …`, `name.x = …`,
/// `[name]`). For duplicates the recovered document no longer holds.
fn earlier_line(text: &str, at: usize, name: &str) -> Option<usize> {
    let bare = |line: &str| -> String {
        let line = line.split('#').next().unwrap_or("");
        line.chars().filter(|c| !c.is_whitespace()).collect()
    };
    let before = text.get(..at)?;
    let start = before.rfind('\n').map_or(0, |p| p + 1);
    let this = bare(text.get(start..)?.lines().next().unwrap_or(""));
    let header = this.starts_with('[').then_some(this);
    before[..start]
        .lines()
        .position(|line| {
            let line = bare(line);
            header.as_ref() == Some(&line)
                || line
                    .trim_start_matches('[')
                    .strip_prefix(name)
                    .is_some_and(|rest| rest.starts_with(['.', '=', ']']))
        })
        .map(|k| k + 1)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::Robot;

    fn robot_error(text: &str) -> String {
        match Robot::parse(text, Path::new("robots/x.toml")) {
            Ok(_) => panic!("accepted:\n{text}"),
            Err(error) => error.to_string(),
        }
    }

    #[test]
    fn duplicate_keys_name_the_key_the_field_and_both_lines() {
        assert_eq!(
            robot_error("[[module]]\nmass = 0.1\n[[module]]\nmass = 0.2\n\nmass = 0.3\n"),
            "robots/x.toml:6:1: duplicate key `mass`: field `module[2].mass` is already given \
             on line 4; give each key (and each [table]) once"
        );
        assert!(
            robot_error("name = \"a\"\n[[module]]\n[hardware]\nbaud = 1\n[[hardware.module]]\nservo_ids = [1]\nservo_ids = [2]")
                .starts_with("robots/x.toml:7:1: duplicate key `servo_ids`: field `hardware.module[1].servo_ids` is already given on line 6"),
        );
        assert!(robot_error("module = [{mass = 1, mass = 2}]").starts_with(
            "robots/x.toml:1:22: duplicate key `mass`: field `module[1].mass` is already \
                 given on line 1"
        ));
        // A table given twice: the document no longer holds the first, the text does.
        assert!(
            robot_error("[[module]]\n[barrier]\np1 = 1\n[ barrier ]\np2 = 2\n")
                .starts_with("robots/x.toml:4:3: duplicate key `barrier`: already given on line 2")
        );
    }

    #[test]
    fn invalid_utf8_is_located_at_its_first_byte() {
        let mut bytes = b"[[module]]\nmass = 0.1 # \xC3\xA9t\xC3\xA9\n# caf\xE9\n".to_vec();
        let error = decode(bytes.clone(), Path::new("robots/x.toml")).unwrap_err();
        // Line 3 is `# caf`, then 0xE9 (Latin-1 é) is the 6th character.
        assert_eq!(
            error.to_string(),
            "robots/x.toml:3:6: not UTF-8 text: byte 0xE9 does not belong to a character \
             here; description files are UTF-8"
        );
        bytes.truncate(bytes.len() - 3);
        bytes.push(b'\n');
        assert!(decode(bytes, Path::new("x")).is_ok());
        let error = decode(vec![0xFF], Path::new("x")).unwrap_err();
        assert!(error.to_string().starts_with("x:1:1: not UTF-8"), "{error}");
    }

    #[test]
    fn reading_stops_at_the_size_limit() {
        let dir = std::env::temp_dir().join(format!("softcbf-toml-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("big.toml");
        let limit = MAX_FILE_BYTES as usize;
        let mut text = "#".repeat(limit - 1);
        text.push('\n');
        std::fs::write(&path, &text).unwrap();
        assert_eq!(read(&path, "robot file").unwrap().len(), limit);
        text.push('\n');
        std::fs::write(&path, &text).unwrap();
        let error = read(&path, "robot file").unwrap_err();
        assert_eq!(
            error.to_string(),
            format!(
                "{}: cannot read robot file: larger than 1048576 bytes (1 MiB), the most a \
                 description file may have",
                path.display()
            )
        );
        std::fs::remove_dir_all(&dir).unwrap();
        let zero = Path::new("/dev/zero");
        if zero.exists() {
            let started = std::time::Instant::now();
            let error = read(zero, "robot file").unwrap_err();
            assert!(
                error.to_string().contains("larger than 1048576 bytes"),
                "{error}"
            );
            assert!(started.elapsed().as_secs_f64() < 5.0);
        }
    }

    #[test]
    fn line_column_counts_characters_from_one() {
        assert_eq!(line_column("", 0), (1, 1));
        // `c`, `é` (two bytes) precede byte 6: column 3.
        assert_eq!(line_column("ab\ncé d", 6), (2, 3));
        assert_eq!(line_column("ab", 100), (1, 3));
    }
}
