//! Why a measurement file is refused: [`ReadError`], each message naming the file, and the
//! line and column where there is one (MEASUREMENTS.md, "What is rejected").

use std::fmt;
use std::path::PathBuf;

use super::REQUIRED;

/// Why a value was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum Reason {
    /// Text, `NaN` or an infinity where a number belongs.
    NotFinite,
    /// Not an integer in the column's range (the range as text).
    NotInteger(&'static str),
    /// A number outside the column's documented range (the range as text).
    OutOfRange(&'static str),
    /// Bytes that are not UTF-8 (a Latin-1 or Windows-1252 file).
    NotUtf8,
}

/// Why a measurement file was rejected. Every variant names the file, and the line and
/// column where there is one.
#[derive(Debug)]
pub enum ReadError {
    /// The file could not be opened or read.
    Io(PathBuf, std::io::Error),
    /// The path is a folder; `data`: the `data.csv` inside it, when there is one (a sweep's
    /// run folder).
    Folder {
        /// The folder.
        path: PathBuf,
        /// Its `data.csv`, when it has one.
        data: Option<PathBuf>,
    },
    /// No header / no data rows.
    Empty(PathBuf),
    /// A required column is missing from the header.
    MissingColumn {
        /// File.
        path: PathBuf,
        /// 1-based line of the header.
        line: usize,
        /// The missing column.
        column: &'static str,
        /// The header as found (fields joined by commas).
        header: String,
        /// The likely cause, when one is recognised (delimiter, case, a title line).
        hint: Option<String>,
    },
    /// A known column appears more than once in the header.
    DuplicateColumn {
        /// File.
        path: PathBuf,
        /// 1-based line of the header.
        line: usize,
        /// The column.
        column: &'static str,
        /// The header as found.
        header: String,
    },
    /// A value is refused.
    BadValue {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// Column name.
        column: String,
        /// The offending text.
        value: String,
        /// Why.
        reason: Reason,
    },
    /// A row has fewer fields than the header.
    ShortRow {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// Fields found.
        found: usize,
        /// Fields in the header.
        expected: usize,
        /// It is the file's last line and has no newline at its end: the file looks cut off.
        cut_off: bool,
    },
    /// A row has more fields than the header (a decimal comma, an unquoted comma).
    LongRow {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// Fields found.
        found: usize,
        /// Fields in the header.
        expected: usize,
        /// 1-based line of the header.
        header_line: usize,
    },
    /// The same report twice: same separation, beacon position, beacon, frequency, power,
    /// sensitivity, group and sample index.
    DuplicateReport {
        /// File.
        path: PathBuf,
        /// 1-based line of the repeat.
        line: usize,
        /// 1-based line of the first occurrence.
        first: usize,
        /// The repeated sample index.
        sample: u32,
    },
    /// The first line that is neither blank nor a comment holds bytes that are not text
    /// (control characters, bytes that are not UTF-8): a binary file, not a text CSV file.
    NotText {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// Control characters (binary data), not only bytes that are not UTF-8.
        control: bool,
    },
    /// A line longer than [`crate::bounded::MAX_LINE_BYTES`] (no real row or comment is).
    LineTooLong {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
    },
    /// More than [`crate::bounded::MAX_CSV_BYTES`] (no real measurement file is).
    TooBig(PathBuf),
    /// A line that is not CSV (an unclosed quote).
    Syntax {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: &'static str,
    },
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReadError::Io(p, e) => write!(f, "{}: {e}", p.display()),
            ReadError::Folder { path, data } => match data {
                Some(d) => write!(
                    f,
                    "{}: is a folder, not a measurement file: give the sweep's data file in it, {}",
                    path.display(),
                    d.display()
                ),
                None => write!(
                    f,
                    "{}: is a folder, not a measurement file: give a CSV file (a sweep's run \
                     folder holds its data in data.csv)",
                    path.display()
                ),
            },
            ReadError::Empty(p) => write!(
                f,
                "{}: no measurements (empty file or header only)",
                p.display()
            ),
            ReadError::MissingColumn {
                path,
                line,
                column,
                header,
                hint,
            } => {
                write!(
                    f,
                    "{}:{line}: missing required column `{column}` (required: {}); the header line found is `{header}`",
                    path.display(),
                    REQUIRED.join(", ")
                )?;
                if let Some(h) = hint {
                    write!(f, "; {h}")?;
                }
                Ok(())
            }
            ReadError::DuplicateColumn {
                path,
                line,
                column,
                header,
            } => write!(
                f,
                "{}:{line}: column `{column}` appears more than once in the header `{header}`",
                path.display()
            ),
            ReadError::BadValue {
                path,
                line,
                column,
                value,
                reason,
            } => {
                if value.trim().is_empty() && !matches!(reason, Reason::NotUtf8) {
                    return write!(
                        f,
                        "{}:{line}: column `{column}` is empty: it needs a value on every line",
                        path.display()
                    );
                }
                write!(
                    f,
                    "{}:{line}: column `{column}`: `{}` ",
                    path.display(),
                    printable(value)
                )?;
                match reason {
                    Reason::NotFinite if value == column => write!(
                        f,
                        "is the column's name: a second header line (two files joined?): \
                         delete it"
                    ),
                    Reason::NotFinite => write!(f, "is not a finite number"),
                    Reason::NotInteger(r) => write!(f, "is not an integer in {r}"),
                    Reason::OutOfRange(r) => write!(f, "is out of range (allowed: {r})"),
                    Reason::NotUtf8 => write!(
                        f,
                        "is not UTF-8 text (the file must be UTF-8; was it saved as Latin-1 or Windows-1252?)"
                    ),
                }
            }
            ReadError::ShortRow {
                path,
                line,
                found,
                expected,
                cut_off,
            } => {
                write!(
                    f,
                    "{}:{line}: {found} fields, the header has {expected}",
                    path.display()
                )?;
                if *cut_off {
                    write!(
                        f,
                        ": the file's last line, with no end of line: the file looks cut off (a \
                         copy not finished, a sweep still writing?); copy it again once complete, \
                         or delete that line"
                    )?;
                }
                Ok(())
            }
            ReadError::LongRow {
                path,
                line,
                found,
                expected,
                header_line,
            } => write!(
                f,
                "{}:{line}: {found} fields, the header (line {header_line}) has {expected}: \
                 a decimal comma, or a comma in a value that is not quoted?",
                path.display()
            ),
            ReadError::DuplicateReport {
                path,
                line,
                first,
                sample,
            } => write!(
                f,
                "{}:{line}: repeats the report of line {first} (same separation, beacon position, beacon, \
                 frequency, power, sensitivity, group and sample index {sample}): is (part of) the file in twice?",
                path.display()
            ),
            ReadError::NotText {
                path,
                line,
                control,
            } => {
                write!(f, "{}:{line}: not a text CSV file: ", path.display())?;
                if *control {
                    write!(
                        f,
                        "its first line holds control characters (binary data: a program, an \
                         image, a spreadsheet such as .xlsx or .ods, a compressed file?); give \
                         the measurement file, or export the sheet as CSV (UTF-8)"
                    )
                } else {
                    write!(
                        f,
                        "its first line holds bytes that are not UTF-8 text (binary data, or text \
                         saved as Latin-1 or Windows-1252?); save it as UTF-8 CSV"
                    )
                }
            }
            ReadError::Syntax {
                path,
                line,
                message,
            } => write!(f, "{}:{line}: {message}", path.display()),
            ReadError::LineTooLong { path, line } => write!(
                f,
                "{}:{line}: a line longer than {} (the limit for a line of a measurement file; \
                 a row is under 200 bytes): not a measurement file (a binary file, /dev/zero?)",
                path.display(),
                crate::bounded::show_bytes(crate::bounded::MAX_LINE_BYTES as u64)
            ),
            ReadError::TooBig(path) => write!(
                f,
                "{}: {}",
                path.display(),
                crate::bounded::too_big(crate::bounded::MAX_CSV_BYTES, "a measurement file")
            ),
        }
    }
}

impl std::error::Error for ReadError {}

/// `s` for a message: control characters shown as escapes (`\u{7f}`), never sent to the
/// terminal as they are.
pub(super) fn printable(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}
