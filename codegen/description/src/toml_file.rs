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
    /// The file is not UTF-8 text, not valid TOML, or a field has the wrong type or is
    /// unknown.
    #[error("{path}:{line}:{column}: {message}", path = path.display())]
    Syntax {
        path: PathBuf,
        line: usize,
        column: usize,
        /// The field the message names (`module[2].mass`; for an entry of an array, the
        /// array), `None` when the problem is not one field's (not UTF-8, a table header
        /// not closed).
        field: Option<String>,
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
            field: None,
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
        let (field, message) = describe_toml_field(self.text, error);
        self.syntax_at(error, field, message)
    }

    fn syntax_at(
        &self,
        error: &toml::de::Error,
        field: Option<String>,
        message: String,
    ) -> FileError {
        let span = error.span().unwrap_or(0..0);
        let (line, column) = line_column(self.text, span.start);
        FileError::Syntax {
            path: self.path.to_path_buf(),
            line,
            column,
            field,
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
            let inner = error.inner();
            // A missing field is named as the field it would be, in the table that lacks it.
            let missing = inner
                .message()
                .strip_prefix("missing field `")
                .and_then(|m| m.strip_suffix('`'));
            let (field, place) = place(error.path(), missing);
            let message = match missing {
                Some(_) => format!("missing; {} must give it", table_words(error.path())),
                None => plain_words(inner.message()),
            };
            let message = if place.is_empty() {
                message
            } else {
                format!("{place}: {message}")
            };
            self.syntax_at(inner, field, message)
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

/// The message of a TOML error in terms of the field being written where it lies, worked
/// out from the text (``field `module[1].margin`: `0.005 0.1` is not a number; …``): what
/// is wrong and how to write it. A duplicate key also names the line of its first definition.
pub fn describe_toml(text: &str, error: &toml::de::Error) -> String {
    describe_toml_field(text, error).1
}

/// [`describe_toml`], with the field the message names (`None`: it names none).
fn describe_toml_field(text: &str, error: &toml::de::Error) -> (Option<String>, String) {
    let message = error.message();
    let Some(span) = error.span() else {
        return (None, message.to_string());
    };
    if message.starts_with("duplicate key") {
        return duplicate(text, &span);
    }
    let scan = scan(text, span.start);
    let written = text.get(span.clone()).unwrap_or("").trim();
    let line_of = |at: usize| line_column(text, at).0;
    let in_list = matches!(scan.frames.last(), Some(Frame::Array { .. }));
    let what = if message.starts_with("string values must be quoted") {
        unquoted(text, span.start, written, in_list)
    } else if message.starts_with("unexpected key or value") {
        let rest = rest_of_line(text, span.start);
        format!(
            "`{rest}` follows the value; write one `key = value` a line (a comment starts \
             with `#`)"
        )
    } else if message.starts_with("key with no value") {
        let line = rest_of_line(text, line_start(text, span.start));
        format!("`{line}` has no `=`; write `key = value`")
    } else if let Some(at) = scan.string {
        format!(
            "the text opened on line {} is not closed: end it with its quote on the same line \
             (text over several lines goes between \"\"\" and \"\"\")",
            line_of(at)
        )
    } else if let Some(at) = scan.header {
        format!(
            "the table header `{}` is not closed: write it as `[name]` or `[[name]]`",
            rest_of_line(text, at)
        )
    } else if message.starts_with("unclosed") {
        match scan.frames.last() {
            Some(Frame::Array { at, .. }) => format!(
                "the list opened on line {} is not closed: end it with `]`",
                line_of(*at)
            ),
            Some(Frame::Inline { at, .. }) => format!(
                "the inline table opened on line {} is not closed: end it with `}}` on the \
                 same line",
                line_of(*at)
            ),
            None => message.to_string(),
        }
    } else {
        match scan.value {
            Some(at) if !in_list && !rest_of_line(text, at).is_empty() => {
                format!("`{}`: {message}", rest_of_line(text, at))
            }
            _ => message.to_string(),
        }
    };
    let field = scan.field();
    match (field.is_empty(), scan.entry()) {
        (true, _) => (None, what),
        (false, None) => (Some(field.clone()), format!("field `{field}`: {what}")),
        (false, Some(k)) => (
            Some(field.clone()),
            format!("field `{field}`, entry {k}: {what}"),
        ),
    }
}

/// What is wrong with a value TOML does not know, written at `at` (`written`, trimmed):
/// nothing, several numbers without a list, or a word without quotes.
fn unquoted(text: &str, at: usize, written: &str, in_list: bool) -> String {
    if written.is_empty() {
        let before = text.get(..at).unwrap_or("").trim_end();
        return if before.ends_with('=') {
            "no value after `=`; write a number, \"text\", true or false, or a list [a, b]"
                .to_string()
        } else {
            "a value is missing here".to_string()
        };
    }
    let words: Vec<&str> = written
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|w| !w.is_empty())
        .collect();
    let numbers = words.len() > 1
        && words
            .iter()
            .all(|w| w.replace('_', "").parse::<f64>().is_ok());
    if numbers && in_list {
        format!(
            "`{written}` is not one value; separate the entries of a list with commas: {}",
            words.join(", ")
        )
    } else if numbers {
        format!(
            "`{written}` is not a number; write one number, or a list as [{}]",
            words.join(", ")
        )
    } else {
        format!(
            "`{written}` is not a value; write text in quotes (\"{}\"), numbers as digits \
             (0.1, 2e-3), true or false, or a list [a, b]",
            written.replace(['"', '\\'], "")
        )
    }
}

/// The text from `at` to the end of its line, without a comment, trimmed.
fn rest_of_line(text: &str, at: usize) -> &str {
    let rest = text.get(at..).unwrap_or("");
    let line = rest.split('\n').next().unwrap_or("");
    line.split('#').next().unwrap_or("").trim()
}

/// The byte offset where the line of `at` starts.
fn line_start(text: &str, at: usize) -> usize {
    text.get(..at)
        .and_then(|before| before.rfind('\n'))
        .map_or(0, |p| p + 1)
}

// ---------------------------------------------------------------------------------------
// Which field a position of a TOML text lies in, for files that do not parse.

/// An open bracket or brace around a position.
#[derive(Debug)]
enum Frame {
    /// `[ … ]`: the array's field, its current entry (from 1), where it opened.
    Array {
        path: String,
        entry: usize,
        at: usize,
    },
    /// `{ … }`: the inline table's field, the key being written in it, where it opened.
    Inline {
        path: String,
        key: Option<String>,
        at: usize,
    },
}

/// What the text says up to a position: the table, the statement and the brackets it lies
/// in. The parser gives a position only; this is read from the text with TOML's lexical
/// rules (strings, comments, headers, dotted and quoted keys).
#[derive(Debug, Default)]
struct Scan {
    /// The current table, arrays of tables with their 1-based index: `hardware.module[2]`.
    table: String,
    /// The key of the statement being written at top level of the table, if any.
    key: Option<String>,
    /// Where that statement's value starts.
    value: Option<usize>,
    /// The brackets and braces open at the position, outermost first.
    frames: Vec<Frame>,
    /// Where a string that never closes opened, if the position lies after its start.
    string: Option<usize>,
    /// Where a table header that never closes starts, if the position lies in it.
    header: Option<usize>,
}

impl Scan {
    /// The field at the position: `module[2].margin`; for an entry of an array, the array.
    fn field(&self) -> String {
        match self.frames.last() {
            Some(Frame::Array { path, .. }) => path.clone(),
            _ => self.path(),
        }
    }

    /// The 1-based entry of the innermost array the position lies in.
    fn entry(&self) -> Option<usize> {
        match self.frames.last() {
            Some(Frame::Array { entry, .. }) => Some(*entry),
            _ => None,
        }
    }

    /// The path of what is written at the position (inside an array: its current entry).
    fn path(&self) -> String {
        match self.frames.last() {
            Some(Frame::Array { path, entry, .. }) => format!("{path}[{entry}]"),
            Some(Frame::Inline { path, key, .. }) => match key {
                Some(key) => join(path, key),
                None => path.clone(),
            },
            None => match &self.key {
                Some(key) => join(&self.table, key),
                None => self.table.clone(),
            },
        }
    }
}

fn join(a: &str, b: &str) -> String {
    if a.is_empty() {
        b.to_string()
    } else {
        format!("{a}.{b}")
    }
}

/// The end (exclusive) of the string starting at `at` (a one-line or multi-line basic or
/// literal string), or `None` if it never closes (a one-line string at its line's end).
fn string_end(b: &[u8], at: usize) -> Option<usize> {
    let quote = b[at];
    let triple = b.get(at..at + 3) == Some(&[quote, quote, quote][..]);
    let mut i = at + if triple { 3 } else { 1 };
    while i < b.len() {
        match b[i] {
            b'\\' if quote == b'"' => i += 2,
            b'\n' if !triple => return None,
            c if c == quote => {
                if !triple {
                    return Some(i + 1);
                }
                if b.get(i..i + 3) == Some(&[quote, quote, quote][..]) {
                    // Up to two more quotes belong to the text (`""""` ends with one in it).
                    let mut end = i + 3;
                    while end < b.len() && b[end] == quote && end < i + 5 {
                        end += 1;
                    }
                    return Some(end);
                }
                i += 1;
            }
            _ => i += 1,
        }
    }
    None
}

/// The first of `stops` from `at` on, outside strings (or the text's end).
fn until(b: &[u8], mut at: usize, stops: &[u8]) -> usize {
    while at < b.len() && !stops.contains(&b[at]) {
        if b[at] == b'"' || b[at] == b'\'' {
            match string_end(b, at) {
                Some(end) => at = end,
                None => return b.len(),
            }
        } else {
            at += 1;
        }
    }
    at
}

/// A written key (`a. "b c" .d`) as its dotted path (`a.b c.d`).
fn key_path(written: &str) -> String {
    let b = written.as_bytes();
    let mut parts = Vec::new();
    let mut start = 0;
    loop {
        let end = until(b, start, b".");
        let part = written.get(start..end).unwrap_or("").trim();
        let part = part
            .strip_prefix('"')
            .and_then(|p| p.strip_suffix('"'))
            .or_else(|| part.strip_prefix('\'').and_then(|p| p.strip_suffix('\'')))
            .unwrap_or(part);
        parts.push(part.to_string());
        if end >= b.len() {
            break;
        }
        start = end + 1;
    }
    parts.join(".")
}

/// Reads `text` up to byte `at` (and the rest of a header or key line it falls in): the
/// table, statement, brackets and strings open there.
fn scan(text: &str, at: usize) -> Scan {
    let b = text.as_bytes();
    let end = at.min(b.len());
    // Arrays of tables seen so far: their path (with the indices of enclosing arrays of
    // tables) and how many elements.
    let mut counts: std::collections::HashMap<String, usize> = Default::default();
    let mut scan = Scan::default();
    let mut statement_start = true;
    let mut i = 0;
    while i < end {
        let c = b[i];
        match c {
            b'\n' => {
                statement_start |= scan.frames.is_empty();
                i += 1;
            }
            b' ' | b'\t' | b'\r' => i += 1,
            b'#' => {
                // A comment runs to the line's end, quotes and all.
                i = b[i..]
                    .iter()
                    .position(|&c| c == b'\n')
                    .map_or(b.len(), |k| i + k);
            }
            b'[' if statement_start && scan.frames.is_empty() => {
                // A table header, `[a.b]` or `[[a.b]]`.
                statement_start = false;
                let double = b.get(i + 1) == Some(&b'[');
                let inner = i + if double { 2 } else { 1 };
                let close = until(b, inner, b"]\n");
                let closed =
                    b.get(close) == Some(&b']') && (!double || b.get(close + 1) == Some(&b']'));
                let written = key_path(text.get(inner..close).unwrap_or(""));
                // Enclosing arrays of tables resolve to their current element.
                let mut path = String::new();
                let parts: Vec<&str> = written.split('.').collect();
                for (k, part) in parts.iter().enumerate() {
                    path = join(&path, part);
                    if k + 1 < parts.len()
                        && let Some(n) = counts.get(&path)
                    {
                        path = format!("{path}[{n}]");
                    }
                }
                if double {
                    let n = counts.entry(path.clone()).or_insert(0);
                    *n += 1;
                    path = format!("{path}[{n}]");
                }
                scan.table = path;
                scan.key = None;
                scan.value = None;
                if closed {
                    i = close + if double { 2 } else { 1 };
                } else {
                    let line_end = until(b, close, b"\n");
                    if end <= line_end {
                        scan.header = Some(i);
                    }
                    i = close.max(i + 1);
                }
            }
            _ if statement_start && scan.frames.is_empty() => {
                // A key, up to its `=` (or, if the line has none, its first word).
                statement_start = false;
                let stop = until(b, i, b"=\n");
                let written = text.get(i..stop).unwrap_or("");
                if b.get(stop) == Some(&b'=') {
                    scan.key = Some(key_path(written));
                    scan.value = Some(stop + 1);
                    i = stop + 1;
                } else {
                    let word = written.split_whitespace().next().unwrap_or("");
                    scan.key = Some(key_path(word));
                    scan.value = None;
                    i = stop;
                }
            }
            b'"' | b'\'' => match string_end(b, i) {
                Some(close) => i = close,
                None => {
                    scan.string = Some(i);
                    break;
                }
            },
            b'[' => {
                scan.frames.push(Frame::Array {
                    path: scan.path(),
                    entry: 1,
                    at: i,
                });
                i += 1;
            }
            b'{' => {
                scan.frames.push(Frame::Inline {
                    path: scan.path(),
                    key: None,
                    at: i,
                });
                i += 1;
            }
            b']' | b'}' => {
                scan.frames.pop();
                i += 1;
            }
            b',' => {
                match scan.frames.last_mut() {
                    Some(Frame::Array { entry, .. }) => *entry += 1,
                    Some(Frame::Inline { key, .. }) => *key = None,
                    None => {}
                }
                i += 1;
            }
            _ => {
                if let Some(Frame::Inline {
                    key: key @ None, ..
                }) = scan.frames.last_mut()
                {
                    let stop = until(b, i, b"=,}\n");
                    if b.get(stop) == Some(&b'=') {
                        *key = Some(key_path(text.get(i..stop).unwrap_or("")));
                        i = stop + 1;
                    } else {
                        i = stop.max(i + 1);
                    }
                } else {
                    i += 1;
                }
            }
        }
    }
    scan
}

/// Where a serde error lies, from its path and the field it lacks, if that is the error:
/// ``field `module[2].mass` ``, ``field `gravity`, entry 2``, ``field `gains.kd`, row 1
/// entry 2``, ``field `hardware.module[2].servo_ids` ``. Arrays of tables count from 1; the
/// private keys of `toml::Spanned` are left out. Returns the field alone (`None` for the
/// file as a whole) and the text.
fn place(path: &serde_path_to_error::Path, missing: Option<&str>) -> (Option<String>, String) {
    let mut field = String::new();
    let mut entries: Vec<usize> = Vec::new();
    let missing = missing.map(|key| Segment::Map {
        key: key.to_string(),
    });
    for segment in path.iter().chain(missing.as_ref()) {
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
        return (None, String::new());
    }
    let text = match entries[..] {
        [] => format!("field `{field}`"),
        [k] => format!("field `{field}`, entry {k}"),
        [i, j] => format!("field `{field}`, row {i} entry {j}"),
        ref deeper => {
            let path: Vec<String> = deeper.iter().map(|k| k.to_string()).collect();
            format!("field `{field}`, entry {}", path.join("."))
        }
    };
    (Some(field), text)
}

/// The table a serde path ends in, as written in a file: `every [[hardware.module]]
/// table`, `the [barrier] table`, `the file`.
fn table_words(path: &serde_path_to_error::Path) -> String {
    let mut keys = Vec::new();
    let mut array = false;
    for segment in path.iter() {
        match segment {
            Segment::Map { key } if key.starts_with("$__serde_spanned_private") => {}
            Segment::Map { key } | Segment::Enum { variant: key } => {
                keys.push(key.as_str());
                array = false;
            }
            Segment::Seq { .. } => array = true,
            Segment::Unknown => {}
        }
    }
    match (keys.is_empty(), array) {
        (true, _) => "the file".to_string(),
        (false, true) => format!("every [[{}]] table", keys.join(".")),
        (false, false) => format!("the [{}] table", keys.join(".")),
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
/// its first definition (the closest earlier key of that name in the recovered document),
/// with that field if it is known.
fn duplicate(text: &str, span: &Range<usize>) -> (Option<String>, String) {
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
        Some((_, at, field)) => (
            Some(field.clone()),
            format!(
                "duplicate key `{name}`: field `{field}` is already given on line {}; give \
                 each key (and each [table]) once",
                line_column(text, at.start).0
            ),
        ),
        None => match earlier_line(text, span.start, name) {
            Some(line) => (
                None,
                format!(
                    "duplicate key `{name}`: already given on line {line}; give each key (and \
                     each [table]) once"
                ),
            ),
            None => (
                None,
                format!("duplicate key `{name}`: give each key (and each [table]) once"),
            ),
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

/// `path` as one shell word, for commands printed to be copied (`softcbf-codegen add
/// PATH`): as it is when it has only letters, digits and `/._-+,:=@%`, else in single
/// quotes.
pub fn shell_word(path: &Path) -> String {
    let text = path.to_string_lossy();
    let plain = !text.is_empty()
        && text
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "/._-+,:=@%".contains(c));
    if plain {
        text.into_owned()
    } else {
        format!("'{}'", text.replace('\'', "'\\''"))
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

    /// A syntax error names its field in `field`, as its message does: a wrong type, an
    /// unknown field, a value TOML cannot read, a duplicate key; none for what is no
    /// field's (not UTF-8).
    #[test]
    fn syntax_errors_carry_the_field_they_name() {
        let field = |text: &str| match Robot::parse(text, Path::new("robots/x.toml")) {
            Err(FileError::Syntax { field, message, .. }) => (field, message),
            other => panic!("expected a Syntax error, got {other:?}"),
        };
        for (text, expected) in [
            ("[[module]]\nmass = \"heavy\"\n", "module[1].mass"),
            ("[[module]]\n[[module]]\nmas = 1\n", "module[2].mas"),
            ("gravity = [0, 0 -9.81]\n[[module]]\n", "gravity"),
            (
                "modules = 2\n[gains]\nkp = [[1, 2], [3, \"x\"]]\n",
                "gains.kp",
            ),
            ("[[module]]\nmass = 0.1\nmass = 0.2\n", "module[1].mass"),
            ("modules = 2\nfoo = 1\n", "foo"),
        ] {
            let (got, message) = field(text);
            assert_eq!(got.as_deref(), Some(expected), "{message}");
            assert!(message.contains(&format!("`{expected}`")), "{message}");
        }
        let error = decode(vec![0xFF], Path::new("x")).unwrap_err();
        assert!(
            matches!(error, FileError::Syntax { field: None, .. }),
            "{error:?}"
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

    #[test]
    fn syntax_errors_name_the_field_from_the_text() {
        let cases = [
            "[[module]]\n[[module]]\nmargin = 0.005 0.1\n",
            "routing = local # a comment [x]\n",
            "[[module]]\ncorner_angles_deg = [0, 60 120]\n",
            "gravity = [0, 0,\n  -9.81\n",
            "[[module]]\n[hardware\nbaud = 1\n",
            "[[module]]\n[[module]]\nmass 0.1\n",
            "[hardware]\n[[hardware.module]]\n[[hardware.module]]\nservo_ids = [1, 2, 3] x\n",
            "name = \"abc\n",
            "[barrier]\np1 = 1e\n",
            "barrier.p1 = 1 2\n",
            "module = [{mass = 0.1}, { mass = 1 2 }]\n",
            "# [[module]] in a comment\nname = \"a = [\" # \"\n\"barrier\" . 'p2' = x\n",
            "[[module]]\nmass =\n",
            "[[a]]\n[[a.b]]\n[[a.b]]\n[[a]]\n[[a.b]]\nc = 1 2\n",
            "[[module]]\nmargin = [0.01, 0.02,\n  0.03 0.04]\n",
        ];
        let expected = [
            "robots/x.toml:3:10: field `module[2].margin`: `0.005 0.1` is not a number; write \
             one number, or a list as [0.005, 0.1]",
            "robots/x.toml:1:11: field `routing`: `local` is not a value; write text in quotes \
             (\"local\"), numbers as digits (0.1, 2e-3), true or false, or a list [a, b]",
            "robots/x.toml:2:25: field `module[1].corner_angles_deg`, entry 2: `60 120` is not \
             one value; separate the entries of a list with commas: 60, 120",
            "robots/x.toml:2:8: field `gravity`, entry 3: the list opened on line 1 is not \
             closed: end it with `]`",
            "robots/x.toml:2:10: field `hardware`: the table header `[hardware` is not closed: \
             write it as `[name]` or `[[name]]`",
            "robots/x.toml:3:6: field `module[2].mass`: `mass 0.1` has no `=`; write \
             `key = value`",
            "robots/x.toml:4:23: field `hardware.module[2].servo_ids`: `x` follows the value; \
             write one `key = value` a line (a comment starts with `#`)",
            "robots/x.toml:1:12: field `name`: the text opened on line 1 is not closed: end it \
             with its quote on the same line (text over several lines goes between \"\"\" and \
             \"\"\")",
            "robots/x.toml:2:8: field `barrier.p1`: `1e`: invalid exponent, expected digits",
            "robots/x.toml:1:14: field `barrier.p1`: `1 2` is not a number; write one number, \
             or a list as [1, 2]",
            "robots/x.toml:1:34: field `module[2].mass`: `1 2` is not a number; write one \
             number, or a list as [1, 2]",
            "robots/x.toml:3:20: field `barrier.p2`: `x` is not a value; write text in quotes \
             (\"x\"), numbers as digits (0.1, 2e-3), true or false, or a list [a, b]",
            "robots/x.toml:2:7: field `module[1].mass`: no value after `=`; write a number, \
             \"text\", true or false, or a list [a, b]",
            "robots/x.toml:6:5: field `a[2].b[1].c`: `1 2` is not a number; write one number, \
             or a list as [1, 2]",
            "robots/x.toml:3:3: field `module[1].margin`, entry 3: `0.03 0.04` is not one \
             value; separate the entries of a list with commas: 0.03, 0.04",
        ];
        for (k, (text, expected)) in cases.iter().zip(expected).enumerate() {
            assert_eq!(robot_error(text), expected, "case {k}: {text:?}");
        }
    }

    #[test]
    fn scanning_never_panics_on_any_prefix() {
        // Every prefix of awkward text, cut inside strings, headers and multi-byte
        // characters, is scanned and described without a panic.
        let text =
            "# é [\n[[a . \"b.c\"]]\nk = '''x\n'y''''\n\"q\\\"\" = [1, {z = \"}\"}, [2]]\n[é]\n";
        for at in 0..=text.len() + 2 {
            let _ = scan(text, at).field();
        }
        for cut in 0..=text.len() {
            if let Some(prefix) = text.get(..cut)
                && let Err(error) = toml::Deserializer::parse(prefix)
            {
                let _ = describe_toml(prefix, &error);
            }
        }
    }
}
