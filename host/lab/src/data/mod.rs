//! The CTA measurement file: what sweeps write, what `cta simulate` writes, and what users
//! bring from their own rigs. The format is documented in `host/MEASUREMENTS.md`.
//!
//! CSV with a header line. Required columns: `separation_in`, `beacon_x_in`, `beacon_y_in`,
//! `beacon_z_in`, `x`, `y`. Optional: `beacon`, `frequency_hz`, `power`, `sensitivity`,
//! `sample`, `magnitude`. Unknown columns are ignored; lines starting with `#` are comments.
//! Beacon positions are in the N frame (inches); `x`, `y` are NorthStar counts.

pub mod weights;

use std::collections::{BTreeMap, HashMap};
use std::fmt;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};

/// The required columns, in the order `cta` writes them.
pub const REQUIRED: [&str; 6] = [
    "separation_in",
    "beacon_x_in",
    "beacon_y_in",
    "beacon_z_in",
    "x",
    "y",
];
/// The optional columns `cta` understands.
pub const OPTIONAL: [&str; 6] = [
    "beacon",
    "frequency_hz",
    "power",
    "sensitivity",
    "sample",
    "magnitude",
];

/// One row: one NorthStar report of one beacon.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sample {
    /// Plate separation, inches.
    pub separation_in: f64,
    /// Beacon position in N, inches.
    pub r: [f64; 3],
    /// NorthStar X, counts.
    pub x: f64,
    /// NorthStar Y, counts.
    pub y: f64,
    /// Beacon id on the array (0-99 for one 10 x 10 array).
    pub beacon: Option<u32>,
    /// Modulation frequency, Hz.
    pub frequency_hz: Option<f64>,
    /// Power level (drive setting).
    pub power: Option<f64>,
    /// NorthStar sensitivity setting (1-4).
    pub sensitivity: Option<f64>,
    /// Sample index within the point.
    pub sample: Option<u32>,
    /// Reported signal magnitude.
    pub magnitude: Option<f64>,
    /// 1-based line number in the file (0 when made in memory).
    pub line: usize,
}

/// A measurement file in memory.
#[derive(Debug, Clone, Default)]
pub struct Dataset {
    /// Where it came from (empty when made in memory).
    pub path: PathBuf,
    /// The rows, in file order.
    pub samples: Vec<Sample>,
}

/// The highest beacon id: `100 * array + LED`, LED 0-99 row-major on one 10 x 10 array,
/// array 0-3 (the sweep's four-array `quad` layout; one array is 0-99).
pub const MAX_BEACON_ID: u32 = 399;

/// What a column may hold (MEASUREMENTS.md), checked on every row.
#[derive(Debug, Clone, Copy)]
enum Domain {
    /// Any finite number.
    Finite,
    /// A finite number in `lo..=hi` (`lo_open`: `lo` itself excluded).
    Range {
        lo: f64,
        lo_open: bool,
        hi: f64,
        text: &'static str,
    },
    /// An integer in `lo..=hi`.
    Int {
        lo: f64,
        hi: f64,
        text: &'static str,
    },
}

fn domain(column: &str) -> Domain {
    let above = |lo: f64, text| Domain::Range {
        lo,
        lo_open: true,
        hi: f64::INFINITY,
        text,
    };
    match column {
        "separation_in" => above(0.0, "> 0 in"),
        "x" | "y" => Domain::Range {
            lo: -32768.0,
            lo_open: false,
            hi: 32767.0,
            text: "-32768..32767 counts (signed 16-bit)",
        },
        "beacon" => Domain::Int {
            lo: 0.0,
            hi: MAX_BEACON_ID as f64,
            text: "0..399 (100 x array + LED)",
        },
        "frequency_hz" => above(0.0, "> 0 Hz"),
        "power" => Domain::Int {
            lo: 1.0,
            hi: 2.0,
            text: "1..2 (1 = 1 kOhm, 2 = 360 Ohm)",
        },
        "sensitivity" => Domain::Int {
            lo: 1.0,
            hi: 4.0,
            text: "1..4",
        },
        "sample" => Domain::Int {
            lo: 0.0,
            hi: u32::MAX as f64,
            text: "0..4294967295",
        },
        "magnitude" => Domain::Range {
            lo: 0.0,
            lo_open: false,
            hi: f64::INFINITY,
            text: ">= 0",
        },
        _ => Domain::Finite,
    }
}

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
    /// sensitivity and sample index.
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
                 frequency, power, sensitivity and sample index {sample}): is (part of) the file in twice?",
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
        }
    }
}

impl std::error::Error for ReadError {}

/// Whether `text` reads as a measurement file: its first line that is neither blank nor a `#`
/// comment names the required columns (so a command given one where a JSON file belongs can
/// say what it got).
pub fn looks_like_measurements(text: &str) -> bool {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    text.lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .is_some_and(|h| {
            let names: Vec<&str> = h.split(',').map(|f| f.trim().trim_matches('"')).collect();
            REQUIRED.iter().all(|r| names.contains(r))
        })
}

/// [`looks_like_measurements`] of the start of the file at `path` (its first 64 KiB; false when
/// it cannot be read).
pub fn file_looks_like_measurements(path: &Path) -> bool {
    let mut start = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(64 * 1024).read_to_end(&mut start))
        .is_ok()
        && looks_like_measurements(&String::from_utf8_lossy(&start))
}

/// `s` for a message: control characters shown as escapes (`\u{7f}`), never sent to the
/// terminal as they are.
fn printable(s: &str) -> String {
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

/// A header for messages: the fields joined by commas, cut to a readable length.
fn show_header(h: &[String]) -> String {
    let s = printable(&h.join(","));
    match s.char_indices().nth(160) {
        Some((i, _)) => format!("{}...", &s[..i]),
        None => s,
    }
}

/// The likely reason a header lacks the required columns.
fn header_hint(h: &[String]) -> Option<String> {
    let known = |n: &str| REQUIRED.contains(&n) || OPTIONAL.contains(&n);
    let joined = h.join(",");
    let start = joined.trim_start();
    if start.starts_with('<') {
        return Some(
            "this is an HTML or XML document, not a CSV file (a web page saved in place of the \
             file? download the raw file)"
                .into(),
        );
    }
    if start.starts_with('{') || start.starts_with('[') {
        return Some(
            "this looks like a JSON file (a saved fit, a calibration?), not a measurement CSV \
             file"
                .into(),
        );
    }
    if !h.iter().any(|n| known(n)) {
        for (sep, name) in [(';', "semicolons"), ('\t', "tabs")] {
            // Only when the fields split there are the column names CTA knows.
            let names = joined
                .split([sep, ','])
                .filter(|n| known(&n.trim().trim_matches('"').to_lowercase()))
                .count();
            if joined.contains(sep) && names >= 2 {
                return Some(format!(
                    "the fields look separated by {name}: CTA reads comma-separated files \
                     (export with `,` between fields and `.` as the decimal mark)"
                ));
            }
        }
    }
    if let Some(n) = h.iter().find(|n| !known(n) && known(&n.to_lowercase())) {
        return Some(format!(
            "column names are lower-case: `{n}` should be `{}`",
            n.to_lowercase()
        ));
    }
    if !h.iter().any(|n| known(n)) {
        return Some(
            "the first line that is neither blank nor a `#` comment is the header: \
             start a title or note line with `#`"
                .into(),
        );
    }
    None
}

/// Split one line into fields: commas separate; a field may be quoted (`"a, b"`, `""` for
/// a quote inside), and blanks around a field are dropped. A quoted field must end on its
/// line. The fields go to `buf`, field `k` being `buf[ends[k-1]..ends[k]]`.
fn split_line(line: &[u8], buf: &mut Vec<u8>, ends: &mut Vec<usize>) -> Result<(), &'static str> {
    buf.clear();
    ends.clear();
    let mut i = 0;
    loop {
        while i < line.len() && (line[i] == b' ' || line[i] == b'\t') {
            i += 1;
        }
        if i < line.len() && line[i] == b'"' {
            i += 1;
            loop {
                match line[i..].iter().position(|&c| c == b'"') {
                    None => return Err("a quoted field is not closed on its line"),
                    Some(q) => {
                        buf.extend_from_slice(&line[i..i + q]);
                        i += q + 1;
                        if line.get(i) == Some(&b'"') {
                            buf.push(b'"');
                            i += 1;
                        } else {
                            break;
                        }
                    }
                }
            }
            while i < line.len() && (line[i] == b' ' || line[i] == b'\t') {
                i += 1;
            }
            if i < line.len() && line[i] != b',' {
                return Err("text after the closing quote of a field");
            }
        } else {
            let end = line[i..]
                .iter()
                .position(|&c| c == b',')
                .map_or(line.len(), |e| i + e);
            buf.extend_from_slice(line[i..end].trim_ascii_end());
            i = end;
        }
        ends.push(buf.len());
        if i >= line.len() {
            return Ok(());
        }
        i += 1; // the comma
    }
}

/// Bit pattern of a number for keys (0 and -0 alike).
fn key_bits(v: f64) -> u64 {
    (v + 0.0).to_bits()
}

const BOM: &[u8] = b"\xEF\xBB\xBF";

impl Dataset {
    /// Read a measurement file.
    pub fn read(path: &Path) -> Result<Dataset, ReadError> {
        Self::from_reader(path, Self::open(path)?)
    }

    /// Read a measurement file, with every warning an analysis command prints on load
    /// (without `warning: `): what reading noticed of the file itself (a last value that may
    /// be cut short, [`Dataset::from_reader_warned`]), then [`Dataset::warnings`].
    pub fn read_warned(path: &Path) -> Result<(Dataset, Vec<String>), ReadError> {
        Self::from_reader_warned(path, Self::open(path)?)
    }

    /// Open a measurement file (a folder given instead is refused; `sweep::read_measurements`
    /// names the run's data file when it is a run directory).
    fn open(path: &Path) -> Result<std::fs::File, ReadError> {
        if path.is_dir() {
            return Err(ReadError::Folder {
                path: path.to_path_buf(),
                data: None,
            });
        }
        std::fs::File::open(path).map_err(|e| ReadError::Io(path.to_path_buf(), e))
    }

    /// Read from any reader; `path` is used in messages.
    pub fn from_reader(path: &Path, r: impl Read) -> Result<Dataset, ReadError> {
        Self::parse(path, r).map(|(ds, _)| ds)
    }

    /// [`Dataset::from_reader`], with the warnings of [`Dataset::read_warned`]. A file whose
    /// last row is whole (as many fields as the header, every value valid) but not followed
    /// by a line break may have been cut inside that row's last value (`-1234` cut to `-12`
    /// still reads): warned about, naming the line and the value. (A row cut short of its
    /// fields is an error, [`ReadError::ShortRow`].)
    pub fn from_reader_warned(
        path: &Path,
        r: impl Read,
    ) -> Result<(Dataset, Vec<String>), ReadError> {
        let (ds, unended) = Self::parse(path, r)?;
        let mut w: Vec<String> = unended.into_iter().collect();
        w.extend(ds.warnings());
        Ok((ds, w))
    }

    /// The rows, and the warning on a last row without a line break after it.
    fn parse(path: &Path, r: impl Read) -> Result<(Dataset, Option<String>), ReadError> {
        let p = path.to_path_buf();
        let mut br = BufReader::new(r);
        let mut raw: Vec<u8> = Vec::new();
        let mut buf: Vec<u8> = Vec::new();
        let mut ends: Vec<usize> = Vec::new();
        let mut line = 0usize;
        let mut header = true;
        // The next line that is neither blank nor a comment, split into `buf`/`ends`: its
        // number, and its last byte (a newline, except on a file's last line, which has none
        // when the file was cut off mid-write).
        let mut next = |buf: &mut Vec<u8>,
                        ends: &mut Vec<usize>|
         -> Result<Option<(usize, Option<u8>)>, ReadError> {
            loop {
                raw.clear();
                let n = br
                    .read_until(b'\n', &mut raw)
                    .map_err(|e| ReadError::Io(p.clone(), e))?;
                if n == 0 {
                    return Ok(None);
                }
                line += 1;
                let mut t: &[u8] = &raw;
                // A UTF-8 byte-order mark (as Excel writes) is not part of the first column.
                if line == 1 && t.starts_with(BOM) {
                    t = &t[BOM.len()..];
                }
                let t = t.trim_ascii();
                if t.is_empty() || t.starts_with(b"#") {
                    continue;
                }
                // The header of a binary file (a program, an image, a spreadsheet) is not
                // text: said so, and its bytes never reach the terminal.
                if header {
                    header = false;
                    let control = t.iter().any(|&b| (b < 0x20 && b != b'\t') || b == 0x7f);
                    if control || std::str::from_utf8(t).is_err() {
                        return Err(ReadError::NotText {
                            path: p.clone(),
                            line,
                            control,
                        });
                    }
                }
                split_line(t, buf, ends).map_err(|m| ReadError::Syntax {
                    path: p.clone(),
                    line,
                    message: m,
                })?;
                return Ok(Some((line, raw.last().copied())));
            }
        };
        let field = |ends: &[usize], k: usize| -> std::ops::Range<usize> {
            (if k == 0 { 0 } else { ends[k - 1] })..ends[k]
        };
        // Header: the first line that is neither blank nor a comment.
        let Some((header_line, _)) = next(&mut buf, &mut ends)? else {
            return Err(ReadError::Empty(p.clone()));
        };
        let header: Vec<String> = (0..ends.len())
            .map(|k| String::from_utf8_lossy(&buf[field(&ends, k)]).into_owned())
            .collect();
        let col = |name: &str| header.iter().position(|h| h == name);
        for name in REQUIRED.iter().chain(OPTIONAL.iter()) {
            if header.iter().filter(|h| h == name).count() > 1 {
                return Err(ReadError::DuplicateColumn {
                    path: p.clone(),
                    line: header_line,
                    column: name,
                    header: show_header(&header),
                });
            }
        }
        let mut req = [0usize; 6];
        for (k, name) in REQUIRED.iter().enumerate() {
            req[k] = col(name).ok_or_else(|| ReadError::MissingColumn {
                path: p.clone(),
                line: header_line,
                column: name,
                header: show_header(&header),
                hint: header_hint(&header),
            })?;
        }
        let opt: Vec<Option<usize>> = OPTIONAL.iter().map(|n| col(n)).collect();
        let domains: Vec<Domain> = header.iter().map(|h| domain(h)).collect();
        let mut samples = Vec::new();
        // First line of each (separation, position, beacon, settings, sample index).
        let mut seen: HashMap<[u64; 9], usize> = HashMap::new();
        // The last row, when no line break follows it: its line, last column and last value.
        let mut unended: Option<(usize, String, String)> = None;
        while let Some((line, last_byte)) = next(&mut buf, &mut ends)? {
            let ended = last_byte == Some(b'\n');
            let nf = ends.len();
            if nf < header.len() {
                return Err(ReadError::ShortRow {
                    path: p.clone(),
                    line,
                    found: nf,
                    expected: header.len(),
                    cut_off: !ended,
                });
            }
            if nf > header.len() {
                return Err(ReadError::LongRow {
                    path: p.clone(),
                    line,
                    found: nf,
                    expected: header.len(),
                    header_line,
                });
            }
            let bad = |idx: usize, value: &str, reason: Reason| ReadError::BadValue {
                path: p.clone(),
                line,
                column: header[idx].clone(),
                value: value.to_string(),
                reason,
            };
            // The checked value of field `idx` (None when empty), per its column's domain.
            let value = |idx: usize| -> Result<Option<f64>, ReadError> {
                let raw = &buf[field(&ends, idx)];
                let s = std::str::from_utf8(raw)
                    .map_err(|_| bad(idx, &String::from_utf8_lossy(raw), Reason::NotUtf8))?;
                if s.is_empty() {
                    return Ok(None);
                }
                let v = s.parse::<f64>().ok().filter(|v| v.is_finite());
                match (domains[idx], v) {
                    (Domain::Int { lo, hi, text }, v) => match v {
                        Some(v) if v.fract() == 0.0 && v >= lo && v <= hi => Ok(Some(v)),
                        _ => Err(bad(idx, s, Reason::NotInteger(text))),
                    },
                    (_, None) => Err(bad(idx, s, Reason::NotFinite)),
                    (Domain::Finite, Some(v)) => Ok(Some(v)),
                    (
                        Domain::Range {
                            lo,
                            lo_open,
                            hi,
                            text,
                        },
                        Some(v),
                    ) => {
                        if v < lo || (lo_open && v == lo) || v > hi {
                            Err(bad(idx, s, Reason::OutOfRange(text)))
                        } else {
                            Ok(Some(v))
                        }
                    }
                }
            };
            let num = |idx: usize| -> Result<f64, ReadError> {
                value(idx)?.ok_or_else(|| bad(idx, "", Reason::NotFinite))
            };
            let opt_num = |k: usize| -> Result<Option<f64>, ReadError> {
                match opt[k] {
                    Some(idx) => value(idx),
                    None => Ok(None),
                }
            };
            let s = Sample {
                separation_in: num(req[0])?,
                r: [num(req[1])?, num(req[2])?, num(req[3])?],
                x: num(req[4])?,
                y: num(req[5])?,
                beacon: opt_num(0)?.map(|v| v as u32),
                frequency_hz: opt_num(1)?,
                power: opt_num(2)?,
                sensitivity: opt_num(3)?,
                sample: opt_num(4)?.map(|v| v as u32),
                magnitude: opt_num(5)?,
                line,
            };
            if let Some(k) = s.sample {
                let o = |v: Option<f64>| key_bits(v.unwrap_or(f64::NAN));
                let key = [
                    key_bits(s.separation_in),
                    key_bits(s.r[0]),
                    key_bits(s.r[1]),
                    key_bits(s.r[2]),
                    s.beacon.map_or(u64::MAX, u64::from),
                    o(s.frequency_hz),
                    o(s.power),
                    o(s.sensitivity),
                    u64::from(k),
                ];
                if let Some(&first) = seen.get(&key) {
                    return Err(ReadError::DuplicateReport {
                        path: p.clone(),
                        line,
                        first,
                        sample: k,
                    });
                }
                seen.insert(key, line);
            }
            samples.push(s);
            // Only a file's last line can lack a line break (`\r` alone is one too: a CRLF
            // file cut between the two bytes has its last value whole).
            if !matches!(last_byte, Some(b'\n' | b'\r')) {
                let raw = &buf[field(&ends, nf - 1)];
                unended = Some((
                    line,
                    header[nf - 1].clone(),
                    String::from_utf8_lossy(raw).into_owned(),
                ));
            }
        }
        if samples.is_empty() {
            return Err(ReadError::Empty(p));
        }
        let warning = unended.map(|(line, column, value)| {
            // A long value (a note column) is shown by its end, where a cut would be.
            let shown = printable(&value);
            let shown = match shown.char_indices().rev().nth(39) {
                Some((i, _)) => format!("...{}", &shown[i..]),
                None => shown,
            };
            let value = if value.is_empty() {
                format!(
                    "its last field (column `{}`) is empty, and",
                    printable(&column)
                )
            } else {
                format!(
                    "its last value, `{shown}` (column `{}`),",
                    printable(&column)
                )
            };
            format!(
                "{}:{line}: the file's last line has no end of line: {value} may be cut short \
                 (`-1234` cut to `-12` still reads as a number; a copy not finished, a sweep \
                 still writing?). If the file was cut, delete that line, or copy or export the \
                 file again once complete; if it is whole, end it with a line break",
                p.display()
            )
        });
        Ok((Dataset { path: p, samples }, warning))
    }

    /// The distinct separations, ascending.
    pub fn separations(&self) -> Vec<f64> {
        let mut v: Vec<f64> = self.samples.iter().map(|s| s.separation_in).collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        v
    }

    /// Warnings about values that read without error but do not look like the CTA in
    /// inches: separations beyond [`FAR_SEPARATION_IN`] (a file in millimetres?), and beacons
    /// far from the plate (`beacon_z_in` given from the plate, not in N), and glitches: samples
    /// far beyond the noise from their point's median ([`Dataset::glitches`]). Each names the
    /// file and its first line(s); every analysis command prints them before its results.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        let file = self.path.display();
        if let Some(s) = self
            .samples
            .iter()
            .find(|s| s.separation_in > FAR_SEPARATION_IN)
        {
            let max = self
                .separations()
                .last()
                .copied()
                .unwrap_or(s.separation_in);
            w.push(format!(
                "{file}:{}: separation_in {} in (the file's largest {max} in), far beyond the \
                 CTA's 0-30 in: is the file in millimetres (divide by 25.4) or centimetres (by \
                 2.54)? Every length column is in inches",
                s.line, s.separation_in
            ));
        }
        let off: Vec<&Sample> = self
            .samples
            .iter()
            .filter(|s| (s.r[2] - s.separation_in).abs() > (0.25 * s.separation_in).max(1.0))
            .collect();
        if let Some(s) = off.first() {
            w.push(format!(
                "{file}:{}: beacon_z_in {} in with separation_in {} in ({} of {} rows like \
                 it): beacon positions are in the sensor-board frame N, so on the CTA \
                 beacon_z_in is the plate's separation, not 0",
                s.line,
                s.r[2],
                s.separation_in,
                off.len(),
                self.samples.len()
            ));
        }
        if let Some(t) = self.separation_typos() {
            w.push(t);
        }
        if let Some(g) = self.glitches().warning(&self.path, self.samples.len()) {
            w.push(g);
        }
        w
    }

    /// The warning (without `warning: `) on separations that look like typos of another: a
    /// value within [`SEP_TYPO_IN`] of one with at least [`SEP_TYPO_RATIO`] times its rows
    /// (`2.0001` on one row beside `2` on 99). One plate position records one value
    /// (MEASUREMENTS.md), so such rows make a separation of their own, which `--separations`
    /// then never selects (it takes the nearest). Names the values and their lines.
    fn separation_typos(&self) -> Option<String> {
        // Each separation's rows and first lines, ascending.
        let mut by: BTreeMap<u64, (usize, Vec<usize>)> = BTreeMap::new();
        for s in &self.samples {
            let e = by.entry(s.separation_in.to_bits()).or_default();
            e.0 += 1;
            if e.1.len() < 5 {
                e.1.push(s.line);
            }
        }
        // Positive numbers sort as their bits do.
        let seps: Vec<(f64, usize, Vec<usize>)> = by
            .into_iter()
            .map(|(b, (n, lines))| (f64::from_bits(b), n, lines))
            .collect();
        let rows = |n: usize| format!("{n} row{}", if n == 1 { "" } else { "s" });
        let mut odd: Vec<(usize, String)> = Vec::new();
        for (i, (v, n, lines)) in seps.iter().enumerate() {
            let lo = seps[..i].iter().rev();
            let hi = seps[i + 1..].iter();
            let beside = lo
                .take_while(|o| v - o.0 < SEP_TYPO_IN)
                .chain(hi.take_while(|o| o.0 - v < SEP_TYPO_IN))
                .filter(|o| o.1 >= SEP_TYPO_RATIO * n)
                .max_by_key(|o| o.1);
            if let Some((b, m, _)) = beside {
                let shown: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
                odd.push((
                    lines[0],
                    format!(
                        "separation_in {v} on {} (line{} {}{}) beside {b} on {}",
                        rows(*n),
                        if *n == 1 { "" } else { "s" },
                        shown.join(", "),
                        if *n > lines.len() { ", ..." } else { "" },
                        rows(*m)
                    ),
                ));
            }
        }
        let (first, _) = *odd.iter().min_by_key(|o| o.0)?;
        let n = odd.len();
        let listed: Vec<String> = odd.into_iter().take(5).map(|o| o.1).collect();
        Some(format!(
            "{}:{first}: {}{}: within {SEP_TYPO_IN} in of a separation with at least \
             {SEP_TYPO_RATIO} times the rows, closer than two plate positions can be told apart. \
             One plate position records one value of separation_in (a sweep writes the mean of \
             its corner readings on every row), so these rows make a separation of their own, \
             which --separations never selects: a typo? Correct them to the value beside them (a plate \
             placed again within one separation, as a resumed sweep may do, reads a little \
             differently: then they are real, and the warning can be ignored)",
            self.path.display(),
            listed.join("; "),
            if n > 5 {
                format!("; and {} more", n - 5)
            } else {
                String::new()
            },
        ))
    }

    /// The glitch check ([`Glitches`]): each sample of a point with
    /// [`GLITCH_MIN_SAMPLES`] or more samples (points at the 16-bit rail,
    /// [`any_sample_pinned`], left out) against its point's median, per axis, in units of
    /// the robust noise of its separation and setting. Nothing is dropped: it only says which
    /// rows stand out and what they do to the pooled noise.
    pub fn glitches(&self) -> Glitches {
        glitch_check(self)
    }

    /// The dataset without the samples the glitch check flags ([`Dataset::glitches`]): what
    /// `--drop-glitches` fits (`cta analyze`, `cta fit`, `cta calibrate`) and evaluates
    /// (`cta evaluate`), with what was left out. `None` when nothing is flagged. The file is
    /// not changed.
    pub fn without_glitches(&self) -> Option<WithoutGlitches> {
        let g = self.glitches();
        if g.samples == 0 {
            return None;
        }
        let flagged: std::collections::BTreeSet<usize> = g.rows.iter().copied().collect();
        let data = Dataset {
            path: self.path.clone(),
            samples: (self.samples.iter().enumerate())
                .filter(|(i, _)| !flagged.contains(i))
                .map(|(_, s)| *s)
                .collect(),
        };
        let mut lines: Vec<usize> = g.rows.iter().map(|&r| self.samples[r].line).collect();
        lines.sort_unstable();
        Some(WithoutGlitches {
            data,
            samples: g.samples,
            lines,
        })
    }

    /// The file's separation nearest to `want`, when one lies within [`SEP_MATCH_IN`]: a
    /// swept file records the measured mean of the four corner readings (`10.0125` for a
    /// nominal 10 in), so a requested `10` must find it.
    pub fn nearest_separation(&self, want: f64) -> Option<f64> {
        nearest_within(&self.separations(), want)
    }

    /// Keep only the given separations, each matched to the file's nearest separation within
    /// [`SEP_MATCH_IN`] (so `25,30` finds the measured 24.995 and 30.005). Errors name the
    /// requested separations with no file separation that near.
    pub fn select(&self, seps: &[f64]) -> Result<Dataset, String> {
        let have = self.separations();
        let mut keep: Vec<f64> = Vec::new();
        let mut missing: Vec<String> = Vec::new();
        for &s in seps {
            match nearest_within(&have, s) {
                Some(h) => keep.push(h),
                None => missing.push(format!("{s}")),
            }
        }
        if !missing.is_empty() {
            return Err(format!(
                "{}: separation(s) {} not in the file, nor any within {SEP_MATCH_IN} in (it has {})",
                self.path.display(),
                missing.join(", "),
                fmt_list(&have)
            ));
        }
        Ok(Dataset {
            path: self.path.clone(),
            samples: self
                .samples
                .iter()
                .filter(|s| keep.contains(&s.separation_in))
                .copied()
                .collect(),
        })
    }

    /// Group the rows into points: one point per (separation, beacon position, frequency,
    /// power, sensitivity), in first-seen order, each with the indices of its samples.
    pub fn points(&self) -> Vec<Point> {
        let mut index: BTreeMap<[u64; 7], usize> = BTreeMap::new();
        let mut out: Vec<Point> = Vec::new();
        for (i, s) in self.samples.iter().enumerate() {
            let key = [
                s.separation_in.to_bits(),
                s.r[0].to_bits(),
                s.r[1].to_bits(),
                s.r[2].to_bits(),
                s.frequency_hz.unwrap_or(f64::NAN).to_bits(),
                s.power.unwrap_or(f64::NAN).to_bits(),
                s.sensitivity.unwrap_or(f64::NAN).to_bits(),
            ];
            let k = *index.entry(key).or_insert_with(|| {
                out.push(Point {
                    first: *s,
                    rows: Vec::new(),
                });
                out.len() - 1
            });
            out[k].rows.push(i);
        }
        out
    }

    /// Write in the documented format (all columns, `comments` as leading `#` lines).
    pub fn write(&self, w: &mut impl Write, comments: &[String]) -> std::io::Result<()> {
        for c in comments {
            writeln!(w, "# {c}")?;
        }
        writeln!(w, "{},{}", REQUIRED.join(","), OPTIONAL.join(","))?;
        for s in &self.samples {
            write_row(w, s)?;
        }
        Ok(())
    }
}

/// Write one row in the documented column order (REQUIRED then OPTIONAL).
pub fn write_row(w: &mut impl Write, s: &Sample) -> std::io::Result<()> {
    let o = |v: Option<f64>| v.map(|v| format!("{v}")).unwrap_or_default();
    let u = |v: Option<u32>| v.map(|v| v.to_string()).unwrap_or_default();
    writeln!(
        w,
        "{},{},{},{},{},{},{},{},{},{},{},{}",
        s.separation_in,
        s.r[0],
        s.r[1],
        s.r[2],
        s.x,
        s.y,
        u(s.beacon),
        o(s.frequency_hz),
        o(s.power),
        o(s.sensitivity),
        u(s.sample),
        o(s.magnitude)
    )
}

/// Repeated samples of one beacon at one setting.
#[derive(Debug, Clone)]
pub struct Point {
    /// The first sample (carries the point's position and settings).
    pub first: Sample,
    /// Indices into [`Dataset::samples`].
    pub rows: Vec<usize>,
}

/// The NorthStar's outputs are signed 16-bit counts: an output at or beyond this magnitude is
/// pinned (a cell in shadow or saturated) and says nothing about where the beacon is.
pub const RAIL: f64 = 32767.0;

/// The rail rule `cta calibrate` and `cta noise` share, first half: whether a coordinate of
/// any of these samples (the repeated samples of one point) is pinned at +/-[`RAIL`].
pub fn any_sample_pinned<'a>(samples: impl IntoIterator<Item = &'a Sample>) -> bool {
    samples
        .into_iter()
        .any(|s| s.x.abs() >= RAIL || s.y.abs() >= RAIL)
}

/// The rail rule, second half: whether the mean `(X, Y)` of `n` samples with one-sample noise
/// `noise` (counts) has a coordinate within 3 sigma of the mean (`3 noise / sqrt(n)`) of
/// +/-[`RAIL`]. Such a point's true output was at or past the rail (a cell in shadow) and only
/// its noise kept its samples inside: its spread and mean are clipped, not measured.
pub fn mean_near_rail(mean: [f64; 2], noise: f64, n: usize) -> bool {
    let margin = 3.0 * noise / (n.max(1) as f64).sqrt();
    mean.iter().any(|m| m.abs() >= RAIL - margin)
}

/// The glitch threshold, in robust sigma: a sample whose deviation from its point's median
/// exceeds this many is a glitch. Gaussian noise reaches 8 sigma once in ~10^15 samples (the
/// spacing of 3 samples, the heaviest tail checked, once in ~10^7 points), so clean data does
/// not trip it, while an ID mix-up or a corrupted report (hundreds to thousands of counts
/// against a noise of ~30) lies far beyond it.
pub const GLITCH_SIGMA: f64 = 8.0;

/// Samples a point needs for the glitch check: with 2, either sample may be the odd one out.
pub const GLITCH_MIN_SAMPLES: usize = 3;

/// The robust sigma is never taken below this (counts): the NorthStar reports whole counts, so
/// with a sub-count noise most deviations are 0 and their median says nothing.
pub const GLITCH_FLOOR_COUNTS: f64 = 1.0;

/// Deviations a group (separation and setting; else separation; else the file) needs before
/// its median absolute deviation is used as the robust sigma (to ~20 %).
const GLITCH_MIN_DEVIATIONS: usize = 50;

/// Median of `|x_i - median(x)|` over the samples of a point of `n` standard Gaussian samples
/// (for odd `n` without the median sample itself, whose deviation is 0), `n` = 3..=64: the
/// factor that turns the median absolute deviation of points of `n` samples into sigma. Odd
/// and even `n` differ (0.69 and 0.49 at 3 and 4: of an even count the two middle samples lie
/// half their spacing from the median). Monte Carlo, 8,000,000 samples per `n` (to ~0.1 %).
const MAD_FACTOR: [f64; 62] = [
    0.6900, 0.4865, 0.6853, 0.5280, 0.6829, 0.5637, 0.6806, 0.5878, 0.6800, 0.6040, 0.6787, 0.6151,
    0.6786, 0.6235, 0.6778, 0.6296, 0.6782, 0.6346, 0.6769, 0.6386, 0.6768, 0.6420, 0.6762, 0.6448,
    0.6769, 0.6464, 0.6766, 0.6482, 0.6765, 0.6503, 0.6765, 0.6519, 0.6763, 0.6528, 0.6760, 0.6548,
    0.6760, 0.6557, 0.6763, 0.6562, 0.6758, 0.6575, 0.6753, 0.6581, 0.6758, 0.6589, 0.6757, 0.6594,
    0.6756, 0.6600, 0.6753, 0.6605, 0.6755, 0.6613, 0.6753, 0.6622, 0.6751, 0.6623, 0.6760, 0.6624,
    0.6756, 0.6628,
];

/// [`MAD_FACTOR`] for any `n` >= 3; beyond the table (within 1.5 % of it at 64) the large-`n` law
/// `0.6745 sqrt(1 - (2 - pi/2)/n)` (the deviation from the median has variance
/// `sigma^2 (1 - 2/n + var(median)/sigma^2)`, `var(median) = pi sigma^2/(2n)`).
fn mad_factor(n: usize) -> f64 {
    match MAD_FACTOR.get(n.wrapping_sub(3)) {
        Some(f) => *f,
        None => 0.674_489_75 * (1.0 - (2.0 - std::f64::consts::FRAC_PI_2) / n as f64).sqrt(),
    }
}

/// The glitch check of one axis (X or Y).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct AxisGlitches {
    /// `X` or `Y`.
    pub axis: String,
    /// Robust one-sample sigma over the file, counts: the median absolute deviation from each
    /// point's median, each scaled to sigma for its point's number of samples. `NaN` (`null`)
    /// when no point has [`GLITCH_MIN_SAMPLES`] samples.
    pub robust_sigma: f64,
    /// One-sample std pooled over the points checked (deviations from each point's mean over
    /// its degrees of freedom), counts: what the fits weight by.
    pub std_with: f64,
    /// The same without this axis's glitches.
    pub std_without: f64,
    /// Samples beyond [`GLITCH_SIGMA`] robust sigma on this axis.
    pub samples: usize,
    /// Their 1-based line numbers, in file order.
    pub lines: Vec<usize>,
}

impl AxisGlitches {
    /// How many times the glitches inflate the pooled std (`std_with / std_without`).
    pub fn inflation(&self) -> f64 {
        self.std_with / self.std_without
    }
}

/// The glitch check ([`Dataset::glitches`]).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Glitches {
    /// The threshold, robust sigma ([`GLITCH_SIGMA`]).
    pub threshold_sigma: f64,
    /// Points checked: [`GLITCH_MIN_SAMPLES`] or more samples, none pinned at the rail.
    pub points_checked: usize,
    /// Their samples.
    pub samples_checked: usize,
    /// Samples that are glitches on either axis.
    pub samples: usize,
    /// Their indices in [`Dataset::samples`] (not in JSON: `axes` has their lines).
    #[serde(skip)]
    pub rows: Vec<usize>,
    /// X, then Y.
    pub axes: Vec<AxisGlitches>,
}

impl Glitches {
    /// The load-time warning (without `warning: `), when there are glitches; `rows` is the
    /// file's number of rows.
    pub fn warning(&self, path: &Path, rows: usize) -> Option<String> {
        if self.samples == 0 {
            return None;
        }
        let hit: Vec<&AxisGlitches> = self.axes.iter().filter(|a| a.samples > 0).collect();
        let lines = hit
            .iter()
            .map(|a| {
                let shown: Vec<String> = a.lines.iter().take(5).map(|l| l.to_string()).collect();
                format!(
                    "{} at line{} {}{}",
                    a.axis,
                    if a.lines.len() == 1 { "" } else { "s" },
                    shown.join(", "),
                    if a.lines.len() > 5 { ", ..." } else { "" }
                )
            })
            .collect::<Vec<_>>()
            .join("; ");
        let inflate = hit
            .iter()
            .map(|a| {
                format!(
                    "from {} {:.1}-fold (std {:.2} counts with them, {:.2} without; robust sigma {:.2})",
                    a.axis,
                    a.inflation(),
                    a.std_with,
                    a.std_without,
                    a.robust_sigma
                )
            })
            .collect::<Vec<_>>()
            .join(" and ");
        let percent = 100.0 * self.samples as f64 / rows.max(1) as f64;
        let share = if percent < 0.05 {
            "under 0.1 %".to_string()
        } else {
            format!("{percent:.1} %")
        };
        Some(format!(
            "{}: {} sample{} ({share} of the rows) lie{} more than {} robust sigma from {} point's \
             median ({lines}): glitches (an ID mix-up, a corrupted report?) that inflate the noise \
             pooled {inflate}; every fit weights by that noise. Remove those lines, or re-measure \
             (`--drop-glitches` leaves them out of `cta fit`, `cta evaluate`, `cta calibrate` \
             and `cta analyze`, the file unchanged)",
            path.display(),
            self.samples,
            if self.samples == 1 { "" } else { "s" },
            if self.samples == 1 { "s" } else { "" },
            self.threshold_sigma,
            if self.samples == 1 { "its" } else { "their" },
        ))
    }
}

/// A dataset without its glitches ([`Dataset::without_glitches`]).
#[derive(Debug, Clone)]
pub struct WithoutGlitches {
    /// The rows that are not flagged, in file order.
    pub data: Dataset,
    /// How many samples were left out.
    pub samples: usize,
    /// Their 1-based lines, ascending.
    pub lines: Vec<usize>,
}

impl WithoutGlitches {
    /// Where they are, for messages: `line 4242`, `lines 9, 402`, the first five then `...`.
    pub fn where_(&self) -> String {
        let shown: Vec<String> = self.lines.iter().take(5).map(|l| l.to_string()).collect();
        format!(
            "line{} {}{}",
            if self.samples == 1 { "" } else { "s" },
            shown.join(", "),
            if self.lines.len() > 5 { ", ..." } else { "" }
        )
    }

    /// The note `cta analyze`, `cta fit`, `cta evaluate` and `cta calibrate` print when
    /// `--drop-glitches` left them out: `3 glitched samples left out (--drop-glitches; lines
    /// 9, 402, 977); the file is unchanged`.
    pub fn note(&self) -> String {
        format!(
            "{} glitched sample{} left out (--drop-glitches; {}); the file is unchanged",
            self.samples,
            if self.samples == 1 { "" } else { "s" },
            self.where_()
        )
    }
}

/// The median of `v` (sorted in place); `NaN` when empty.
fn median_of(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// [`Dataset::glitches`].
fn glitch_check(ds: &Dataset) -> Glitches {
    // One deviation from a point's median: its row, and `|d| / mad_factor(n)` (an estimate
    // of sigma whose median over Gaussian samples is sigma) when it enters the scale.
    struct Dev {
        row: usize,
        point: usize,
        dev: f64,
        scaled: Option<f64>,
        group: [u64; 4],
    }
    let points: Vec<Point> = ds
        .points()
        .into_iter()
        .filter(|p| {
            p.rows.len() >= GLITCH_MIN_SAMPLES
                && !any_sample_pinned(p.rows.iter().map(|&i| &ds.samples[i]))
        })
        .collect();
    let value = |s: &Sample, a: usize| if a == 0 { s.x } else { s.y };
    let mut glitched = vec![false; ds.samples.len()];
    let mut axes = Vec::new();
    for (a, name) in ["X", "Y"].into_iter().enumerate() {
        let mut devs: Vec<Dev> = Vec::new();
        for (k, p) in points.iter().enumerate() {
            let s0 = &p.first;
            let group = [
                key_bits(s0.separation_in),
                key_bits(s0.frequency_hz.unwrap_or(f64::NAN)),
                key_bits(s0.power.unwrap_or(f64::NAN)),
                key_bits(s0.sensitivity.unwrap_or(f64::NAN)),
            ];
            let n = p.rows.len();
            let mut order: Vec<usize> = p.rows.clone();
            order.sort_by(|&i, &j| value(&ds.samples[i], a).total_cmp(&value(&ds.samples[j], a)));
            let mut v: Vec<f64> = order.iter().map(|&i| value(&ds.samples[i], a)).collect();
            let med = median_of(&mut v);
            let f = mad_factor(n);
            for (j, &row) in order.iter().enumerate() {
                let dev = value(&ds.samples[row], a) - med;
                // The median sample of an odd count deviates by 0 by construction.
                let scaled = (n % 2 == 0 || j != n / 2).then(|| dev.abs() / f);
                devs.push(Dev {
                    row,
                    point: k,
                    dev,
                    scaled,
                    group,
                });
            }
        }
        // Robust sigma per separation and setting, per separation, and over the file.
        let mut by_setting: HashMap<[u64; 4], Vec<f64>> = HashMap::new();
        let mut by_sep: HashMap<u64, Vec<f64>> = HashMap::new();
        let mut all: Vec<f64> = Vec::new();
        for d in &devs {
            if let Some(v) = d.scaled {
                by_setting.entry(d.group).or_default().push(v);
                by_sep.entry(d.group[0]).or_default().push(v);
                all.push(v);
            }
        }
        let robust = |v: &mut Vec<f64>| (v.len() >= GLITCH_MIN_DEVIATIONS).then(|| median_of(v));
        let setting_sigma: HashMap<[u64; 4], Option<f64>> = by_setting
            .into_iter()
            .map(|(k, mut v)| (k, robust(&mut v)))
            .collect();
        let sep_sigma: HashMap<u64, Option<f64>> = by_sep
            .into_iter()
            .map(|(k, mut v)| (k, robust(&mut v)))
            .collect();
        let file_sigma = robust(&mut all.clone());
        let robust_sigma = median_of(&mut all);
        let mut lines = Vec::new();
        let mut out = vec![false; devs.len()];
        for (i, d) in devs.iter().enumerate() {
            let sigma = setting_sigma[&d.group]
                .or(sep_sigma[&d.group[0]])
                .or(file_sigma);
            if let Some(sigma) = sigma {
                if d.dev.abs() > GLITCH_SIGMA * sigma.max(GLITCH_FLOOR_COUNTS) {
                    out[i] = true;
                    glitched[d.row] = true;
                    lines.push(ds.samples[d.row].line);
                }
            }
        }
        lines.sort_unstable();
        // The pooled std with and without them (deviations from each point's mean).
        let pooled = |keep: &dyn Fn(usize) -> bool| {
            let (mut ss, mut dof) = (0.0, 0usize);
            let mut i = 0;
            while i < devs.len() {
                let k = devs[i].point;
                let j = i + devs[i..].iter().take_while(|d| d.point == k).count();
                let v: Vec<f64> = (i..j)
                    .filter(|&m| keep(m))
                    .map(|m| value(&ds.samples[devs[m].row], a))
                    .collect();
                if v.len() >= 2 {
                    let mean = v.iter().sum::<f64>() / v.len() as f64;
                    ss += v.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
                    dof += v.len() - 1;
                }
                i = j;
            }
            if dof == 0 {
                f64::NAN
            } else {
                (ss / dof as f64).sqrt()
            }
        };
        axes.push(AxisGlitches {
            axis: name.into(),
            robust_sigma,
            std_with: pooled(&|_| true),
            std_without: pooled(&|m| !out[m]),
            samples: lines.len(),
            lines,
        });
    }
    Glitches {
        threshold_sigma: GLITCH_SIGMA,
        points_checked: points.len(),
        samples_checked: points.iter().map(|p| p.rows.len()).sum(),
        samples: glitched.iter().filter(|g| **g).count(),
        rows: (0..glitched.len()).filter(|&r| glitched[r]).collect(),
        axes,
    }
}

/// Format a list of separations compactly.
pub fn fmt_list(v: &[f64]) -> String {
    v.iter()
        .map(|s| format!("{s}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The most separations a list or range may give (`cta simulate --separations`, a sweep
/// plan's `separations_in`): the count is computed before anything is expanded, so a range
/// like `1..1e12` or `2..30:0.0000001` is refused at once instead of filling the memory.
pub const MAX_SEPARATIONS: usize = 10_000;

/// Separations above this (in) are far beyond the CTA (0-30 in) and the sweep plans' 60 in
/// limit, and beyond the 100 in of the README's Figure 57 example: [`Dataset::warnings`]
/// asks whether the file is in millimetres.
pub const FAR_SEPARATION_IN: f64 = 120.0;

/// Separations closer than this (in) are one plate position written two ways when one has
/// far more rows ([`SEP_TYPO_RATIO`]), and warned about: 0.01 in is twice Ch IV's +/-5 mil
/// bound on a separation's uncertainty (plates leveled to 5 mils per foot, the corners'
/// mean read to 1 mil), so the CTA cannot set two positions that close and tell them apart,
/// while a typo in the last digits (`2.0001`, `10.0152` for `10.0125`) falls well inside it.
/// It is also ten times finer than [`SEP_MATCH_IN`], which would take either for the other.
pub const SEP_TYPO_IN: f64 = 0.01;

/// A separation is warned about as a typo when a neighbour within [`SEP_TYPO_IN`] has at least
/// this many times its rows: a few rows beside a whole plate position. (Two values with
/// comparable rows are rather two positions, or a plate re-measured mid-sweep.)
pub const SEP_TYPO_RATIO: usize = 4;

/// How far (in) a requested separation may lie from a recorded one and still select it: a
/// few times the scatter of a measured plate position (the mean of four corner readings,
/// +/-0.015 in on the CTA), and well under the 1 in between the CTA's closest separations.
pub const SEP_MATCH_IN: f64 = 0.1;

/// The value of `have` nearest to `want`, when it lies within [`SEP_MATCH_IN`].
pub fn nearest_within(have: &[f64], want: f64) -> Option<f64> {
    have.iter()
        .copied()
        .filter(|h| (h - want).abs() <= SEP_MATCH_IN)
        .min_by(|a, b| (a - want).abs().total_cmp(&(b - want).abs()))
}

/// Parse a separation list: `20,25`, `2..30` (step 1), `2..30:2` (step 2), or a mix
/// `3,5,20..30:5`. Every end and step must be finite, and the whole list may give at most
/// [`MAX_SEPARATIONS`] separations.
pub fn parse_separations(s: &str) -> Result<Vec<f64>, String> {
    let mut out = Vec::new();
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        if let Some((a, rest)) = part.split_once("..") {
            let (b, step) = match rest.split_once(':') {
                Some((b, st)) => (
                    b,
                    st.trim()
                        .parse::<f64>()
                        .map_err(|_| format!("bad step in `{part}`"))?,
                ),
                None => (rest, 1.0),
            };
            let a: f64 = a
                .trim()
                .parse()
                .map_err(|_| format!("bad range start in `{part}`"))?;
            let b: f64 = b
                .trim()
                .parse()
                .map_err(|_| format!("bad range end in `{part}`"))?;
            if !(a.is_finite() && b.is_finite() && step.is_finite()) {
                return Err(format!(
                    "range `{part}`: the ends and the step must be finite numbers of inches"
                ));
            }
            if !(step > 0.0) || b < a {
                return Err(format!(
                    "empty range `{part}` (use A..B with A <= B, step > 0)"
                ));
            }
            // Count first (in floating point: no overflow), expand only when it is small.
            let count = ((b - a) / step + 1e-9).floor() + 1.0;
            if count + out.len() as f64 > MAX_SEPARATIONS as f64 {
                return Err(format!(
                    "range `{part}` gives {count:.0} separations{}, more than the {MAX_SEPARATIONS} allowed \
                     (use a larger step, e.g. `{a}..{b}:{}`)",
                    if out.is_empty() {
                        String::new()
                    } else {
                        format!(" (after {} before it)", out.len())
                    },
                    suggest_step(a, b)
                ));
            }
            let n = count as usize - 1;
            for k in 0..=n {
                out.push(a + step * k as f64);
            }
        } else {
            out.push(
                part.parse::<f64>()
                    .map_err(|_| format!("`{part}` is not a separation in inches"))?,
            );
            if out.len() > MAX_SEPARATIONS {
                return Err(format!(
                    "more than the {MAX_SEPARATIONS} separations allowed in `{s}`"
                ));
            }
        }
    }
    if out.is_empty() {
        return Err("no separations given".into());
    }
    if let Some(bad) = out.iter().find(|s| !(**s > 0.0 && s.is_finite())) {
        return Err(format!(
            "separation {bad} in must be a positive, finite number of inches"
        ));
    }
    Ok(out)
}

/// [`parse_separations`] for a list that makes data (`simulate --separations`): a separation
/// given twice is refused, as it would be simulated twice, a file its readers refuse as pasted
/// in twice. (A selection may overlap: `2..10,10..30:5` selects 10 in once.)
pub fn parse_new_separations(s: &str) -> Result<Vec<f64>, String> {
    let out = parse_separations(s)?;
    let mut sorted = out.clone();
    sorted.sort_by(f64::total_cmp);
    if let Some(w) = sorted.windows(2).find(|w| w[1] - w[0] < 1e-9) {
        return Err(format!("{} in is listed twice in `{s}`", w[0]));
    }
    Ok(out)
}

/// A step that keeps `a..b` within [`MAX_SEPARATIONS`] (a round number), for the message.
fn suggest_step(a: f64, b: f64) -> f64 {
    let need = (b - a) / (MAX_SEPARATIONS as f64 - 1.0);
    let p = 10f64.powf(need.log10().ceil());
    if p.is_finite() && p > 0.0 {
        p
    } else {
        1.0
    }
}

/// Create the folders missing above the output file `path` (`--save nd1/fit.json` creates
/// `nd1`): every `cta` output does so, so that a computed result is never lost to a missing
/// folder. Errors read `cannot write PATH: cannot create the folder DIR: reason`.
pub fn create_parent_folders(path: &Path) -> Result<(), String> {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() && !dir.is_dir() => std::fs::create_dir_all(dir)
            .map_err(|e| {
                format!(
                    "cannot write {}: cannot create the folder {}: {e}",
                    path.display(),
                    dir.display()
                )
            }),
        _ => Ok(()),
    }
}

/// Write an output file of a `cta` command (`fit --save`, `calibrate --out`, every `--plot`
/// SVG, ...) the one way they are all written: missing parent folders are created
/// ([`create_parent_folders`]), and the bytes go to `PATH.partial`, renamed into place only
/// when complete, so an earlier file is replaced whole or not at all. On error the partial
/// file is removed and the message reads `cannot write PATH: reason`. Whether `path` may be
/// replaced is the caller's check (e.g. [`check_derived_output`]).
pub fn write_output(path: &Path, bytes: &[u8]) -> Result<(), String> {
    create_parent_folders(path)?;
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    let tmp = path.with_file_name(name);
    let write = || -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    };
    write().map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        format!("cannot write {}: {e}", path.display())
    })
}

/// Whether a file derived from the measurement file `data` (a saved fit, a calibration) may
/// be written to `out`, given on the command line as `flag`: never a folder or `data` itself;
/// an existing file only when `earlier` recognises it as this command's own output (`what`
/// names that in the refusal), or with `force`. Nothing is modified.
pub fn check_derived_output(
    flag: &str,
    out: &Path,
    data: &Path,
    example: &str,
    what: &str,
    earlier: impl Fn(&Path) -> bool,
    force: bool,
) -> anyhow::Result<()> {
    if out.is_dir() {
        anyhow::bail!(
            "{flag} {}: is a folder; give a file name (e.g. {example})",
            out.display()
        );
    }
    if !out.exists() {
        return Ok(());
    }
    if let (Ok(a), Ok(b)) = (out.canonicalize(), data.canonicalize()) {
        if a == b {
            anyhow::bail!("{flag} {}: is the measurement file", out.display());
        }
    }
    if force || earlier(out) {
        return Ok(());
    }
    anyhow::bail!(
        "{flag} {}: exists and is not {what}; not replaced: give another file name, or \
         --force to replace it",
        out.display()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rail_rule() {
        let at = |x: f64, y: f64| Sample {
            x,
            y,
            ..Default::default()
        };
        assert!(any_sample_pinned(&[at(0.0, 0.0), at(10.0, -32767.0)]));
        assert!(!any_sample_pinned(&[at(0.0, 0.0), at(32766.0, -32766.0)]));
        // 3 sigma of a mean of 9 samples of noise 30 is 30 counts.
        assert!(mean_near_rail([32740.0, 0.0], 30.0, 9));
        assert!(mean_near_rail([0.0, -32740.0], 30.0, 9));
        assert!(!mean_near_rail([32730.0, 0.0], 30.0, 9));
    }

    /// Missing folders are made, an earlier file is replaced whole, nothing partial is left,
    /// and a folder that cannot be made is named in `cannot write PATH: ...`.
    #[test]
    fn write_output_makes_folders_and_names_the_file() {
        let d = std::env::temp_dir().join(format!("cta-write-output-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        let f = d.join("a/b/out.json");
        write_output(&f, b"one").unwrap();
        write_output(&f, b"two").unwrap();
        assert_eq!(std::fs::read_to_string(&f).unwrap(), "two");
        assert!(!d.join("a/b/out.json.partial").exists());
        let bad = f.join("x.json");
        let e = write_output(&bad, b"three").unwrap_err();
        assert!(
            e.starts_with(&format!(
                "cannot write {}: cannot create the folder",
                bad.display()
            )),
            "{e}"
        );
        assert_eq!(std::fs::read_to_string(&f).unwrap(), "two");
        let e = write_output(&d.join("a"), b"x").unwrap_err();
        assert!(
            e.starts_with(&format!("cannot write {}: ", d.join("a").display())),
            "{e}"
        );
        assert!(!d.join("a.partial").exists());
        std::fs::remove_dir_all(&d).unwrap();
    }

    fn read(s: &str) -> Result<Dataset, ReadError> {
        Dataset::from_reader(Path::new("m.csv"), s.as_bytes())
    }

    /// A file cut inside its last value (`-1234` to `-12`) still reads, so a last row with no
    /// line break after it is warned about, naming its line and value and what to do; a file
    /// ending with a line break (`\n`, `\r\n`, or a lone `\r`), or with a comment after its
    /// last row, is not.
    #[test]
    fn a_last_value_without_a_line_break_may_be_cut_short() {
        let warned = |text: &str| {
            let (ds, w) = Dataset::from_reader_warned(Path::new("m.csv"), text.as_bytes())
                .unwrap_or_else(|e| panic!("{text:?}: {e}"));
            assert_eq!(ds.samples.len(), 2, "{text:?}");
            (ds, w)
        };
        let head = "# title\nseparation_in,beacon_x_in,beacon_y_in,beacon_z_in,x,y\n\
                    20,0,0,20,10,-1234\n";
        let (ds, w) = warned(&format!("{head}20,1,0,20,11,-12"));
        assert_eq!(ds.samples[1].y, -12.0);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with(
                "m.csv:4: the file's last line has no end of line: its last value, `-12` \
                 (column `y`), may be cut short"
            ) && w[0].contains("delete that line, or copy or export the file again"),
            "{w:?}"
        );
        // The plain reader reads the same rows.
        let plain = Dataset::from_reader(
            Path::new("m.csv"),
            format!("{head}20,1,0,20,11,-12").as_bytes(),
        );
        assert_eq!(plain.unwrap().samples, ds.samples);
        for ending in ["\n", "\r\n", "\r", "\n# the end", "\n\n"] {
            let (_, w) = warned(&format!("{head}20,1,0,20,11,-12{ending}"));
            assert!(w.is_empty(), "{ending:?}: {w:?}");
        }
        // An optional last column left empty by the cut, and a long value shown by its end.
        let (_, w) = warned(
            "separation_in,beacon_x_in,beacon_y_in,beacon_z_in,x,y,magnitude\n\
             20,0,0,20,10,-1234,0.5\n20,1,0,20,11,-1234,",
        );
        assert!(
            w[0].starts_with(
                "m.csv:3: the file's last line has no end of line: its last field (column \
                 `magnitude`) is empty, and may be cut short"
            ),
            "{w:?}"
        );
        let note = format!("{}cut here", "x".repeat(100));
        let (_, w) = warned(&format!(
            "separation_in,beacon_x_in,beacon_y_in,beacon_z_in,x,y,note\n\
             20,0,0,20,10,-1234,a\n20,1,0,20,11,-1234,{note}"
        ));
        assert!(
            w[0].contains(&format!(
                "its last value, `...{}` (column `note`)",
                &note[68..]
            )),
            "{w:?}"
        );
    }

    #[test]
    fn reads_with_comments_unknown_and_optional_columns() {
        let d = read("# a comment\nx,y,extra,separation_in,beacon_x_in,beacon_y_in,beacon_z_in,beacon\n1.5,-2,foo,20,0.5,-0.5,20,7\n# mid\n3,4,bar,20,1.5,-0.5,20,\n").unwrap();
        assert_eq!(d.samples.len(), 2);
        assert_eq!(d.samples[0].beacon, Some(7));
        assert_eq!(d.samples[1].beacon, None);
        assert_eq!(d.samples[1].line, 5);
        assert_eq!(d.samples[0].r, [0.5, -0.5, 20.0]);
    }

    #[test]
    fn errors_name_column_and_line() {
        let e = read("x,y,separation_in,beacon_x_in,beacon_y_in\n1,2,3,4,5\n").unwrap_err();
        assert!(
            e.to_string()
                .contains("missing required column `beacon_z_in`"),
            "{e}"
        );
        let e = read(
            "x,y,separation_in,beacon_x_in,beacon_y_in,beacon_z_in\n1,2,3,4,5,6\n1,NaN,3,4,5,6\n",
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "m.csv:3: column `y`: `NaN` is not a finite number"
        );
        let e = read("x,y,separation_in,beacon_x_in,beacon_y_in,beacon_z_in\n1,inf,3,4,5,6\n")
            .unwrap_err();
        assert!(e.to_string().contains(":2: column `y`"));
        let e = read("x,y,separation_in,beacon_x_in,beacon_y_in,beacon_z_in\n1,abc,3,4,5,6\n")
            .unwrap_err();
        assert!(e.to_string().contains("`abc`"));
        assert!(matches!(read(""), Err(ReadError::Empty(_))));
        assert!(matches!(
            read("# only\nx,y,separation_in,beacon_x_in,beacon_y_in,beacon_z_in\n"),
            Err(ReadError::Empty(_))
        ));
    }

    const H: &str = "separation_in,beacon_x_in,beacon_y_in,beacon_z_in,x,y";

    #[test]
    fn line_numbers_count_comments_blanks_and_indented_comments() {
        let d = read(&format!(
            "# c\n\n{H}\n   \n  # indented, with, commas\n20,0,0,20,1,2\n"
        ))
        .unwrap();
        assert_eq!(d.samples.len(), 1);
        assert_eq!(d.samples[0].line, 6);
        let e = read(&format!("# c\n\n{H}\n# x\n\n20,0,0,20,1,NaN\n")).unwrap_err();
        assert!(e.to_string().starts_with("m.csv:6: column `y`"), "{e}");
        // Two files joined: the second header is named as one.
        let e = read(&format!("{H}\n20,0,0,20,1,2\n{H}\n20,0,0,20,1,3\n")).unwrap_err();
        assert!(
            e.to_string()
                .contains("m.csv:3: column `separation_in`: `separation_in` is the column's name: a second header line"),
            "{e}"
        );
    }

    #[test]
    fn bom_and_quoted_header_names_are_accepted() {
        let d = read(&format!("\u{feff}{H}\n20,0,0,20,1,2\n")).unwrap();
        assert_eq!(d.samples[0].x, 1.0);
        let d = read("\u{feff}\"separation_in\",\"beacon_x_in\", \"beacon_y_in\",beacon_z_in,\"x\",y\n20,0,0,20,\"1\",2\n").unwrap();
        assert_eq!(d.samples[0].separation_in, 20.0);
        assert_eq!(d.samples[0].x, 1.0);
        // A quoted note with a comma in an unknown column is one field.
        let d = read(&format!("{H},note\n20,0,0,20,1,2,\"a, b\"\n")).unwrap();
        assert_eq!(d.samples.len(), 1);
        let d = read(&format!("{H},note\n20,0,0,20,1,2,\"say \"\"hi\"\"\"\n")).unwrap();
        assert_eq!(d.samples.len(), 1);
        let e = read(&format!("{H},note\n20,0,0,20,1,2,\"open\n")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "m.csv:2: a quoted field is not closed on its line"
        );
    }

    #[test]
    fn header_problems_show_the_header_and_the_likely_cause() {
        let e = read("separation_in;beacon_x_in;beacon_y_in;beacon_z_in;x;y\n20;0;0;20;1;2\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("m.csv:1: missing required column `separation_in`"),
            "{e}"
        );
        assert!(
            e.contains("`separation_in;beacon_x_in;beacon_y_in;beacon_z_in;x;y`"),
            "{e}"
        );
        assert!(e.contains("semicolons"), "{e}");
        let e = read(&H.replace(',', "\t")).unwrap_err().to_string();
        assert!(e.contains("tabs"), "{e}");
        let e = read(&format!("{}\n20,0,0,20,1,2\n", H.to_uppercase()))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`SEPARATION_IN` should be `separation_in`"),
            "{e}"
        );
        let e = read(&format!("My CTA run, 2024\n{H}\n20,0,0,20,1,2\n"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("m.csv:1:") && e.contains("`My CTA run,2024`"),
            "{e}"
        );
        assert!(e.contains("start a title or note line with `#`"), "{e}");
    }

    #[test]
    fn duplicate_header_columns_and_long_rows_are_refused() {
        let e = read(&format!("# c\n{H},x\n20,0,0,20,1,2,3\n"))
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(
                "m.csv:2: column `x` appears more than once in the header `separation_in,"
            ),
            "{e}"
        );
        // Unknown columns may repeat (they are ignored).
        assert!(read(&format!("{H},note,note\n20,0,0,20,1,2,a,b\n")).is_ok());
        // A decimal comma in the magnitude: one field too many.
        let e = read(&format!(
            "{H},magnitude\n20,0,0,20,1,2,0.5\n20,0,0,20,1,2,0,0024\n"
        ))
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("m.csv:3: 8 fields, the header (line 1) has 7"),
            "{e}"
        );
        assert!(e.contains("decimal comma"), "{e}");
    }

    #[test]
    fn documented_ranges_are_checked() {
        let row = |extra_h: &str, extra: &str, sep: &str, x: &str| {
            read(&format!("{H}{extra_h}\n{sep},0,0,20,{x},2{extra}\n"))
        };
        let err = |r: Result<Dataset, ReadError>| r.unwrap_err().to_string();
        assert_eq!(
            err(row("", "", "20", "99999")),
            "m.csv:2: column `x`: `99999` is out of range (allowed: -32768..32767 counts (signed 16-bit))"
        );
        assert!(row("", "", "20", "-32768").is_ok());
        assert!(row("", "", "20", "32767.4").is_err());
        assert_eq!(
            err(row("", "", "20", " ")),
            "m.csv:2: column `x` is empty: it needs a value on every line"
        );
        for sep in ["0", "-2"] {
            assert!(
                err(row("", "", sep, "1")).contains("column `separation_in`"),
                "{sep}"
            );
        }
        for (col, v, why) in [
            ("sensitivity", "9", "is not an integer in 1..4"),
            ("sensitivity", "2.5", "is not an integer in 1..4"),
            (
                "power",
                "9",
                "is not an integer in 1..2 (1 = 1 kOhm, 2 = 360 Ohm)",
            ),
            (
                "power",
                "0",
                "is not an integer in 1..2 (1 = 1 kOhm, 2 = 360 Ohm)",
            ),
            ("frequency_hz", "-4050", "is out of range (allowed: > 0 Hz)"),
            (
                "beacon",
                "500",
                "is not an integer in 0..399 (100 x array + LED)",
            ),
            (
                "beacon",
                "-3",
                "is not an integer in 0..399 (100 x array + LED)",
            ),
            (
                "beacon",
                "7.5",
                "is not an integer in 0..399 (100 x array + LED)",
            ),
            (
                "beacon",
                "-32768",
                "is not an integer in 0..399 (100 x array + LED)",
            ),
            (
                "beacon",
                "abc",
                "is not an integer in 0..399 (100 x array + LED)",
            ),
            ("sample", "-1", "is not an integer in 0..4294967295"),
            ("magnitude", "-0.5", "is out of range (allowed: >= 0)"),
            ("magnitude", "NaN", "is not a finite number"),
        ] {
            let e = err(row(&format!(",{col}"), &format!(",{v}"), "20", "1"));
            assert_eq!(e, format!("m.csv:2: column `{col}`: `{v}` {why}"));
        }
        // The documented "not recorded": an empty optional field.
        let d = read(&format!("{H},beacon,frequency_hz,power,sensitivity,sample,magnitude\n20,0,0,20,1,2,,,,,,\n20,0,0,20,1,2,399,4050,2,4,7,0\n")).unwrap();
        assert_eq!(d.samples[0].magnitude, None);
        assert_eq!(d.samples[1].beacon, Some(399));
        assert_eq!(d.samples[1].magnitude, Some(0.0));
    }

    #[test]
    fn latin1_bytes_name_the_line_and_column() {
        let mut f = format!("{H},note\n20,0,0,20,1,2,ok\n").into_bytes();
        f.extend_from_slice(b"20,0,0,20,1\xb5,2,ok\n");
        let e = Dataset::from_reader(Path::new("m.csv"), &f[..])
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("m.csv:3: column `x`: `1\u{fffd}` is not UTF-8 text"),
            "{e}"
        );
        // In an ignored column it is ignored, like the column.
        let mut f = format!("{H},note\n").into_bytes();
        f.extend_from_slice(b"20,0,0,20,1,2,M\xfcller\n");
        assert!(Dataset::from_reader(Path::new("m.csv"), &f[..]).is_ok());
    }

    #[test]
    fn repeated_reports_are_refused_with_both_lines() {
        let body = "20,0,0,20,1,2,3,0\n20,0,0,20,1,3,3,1\n";
        let e = read(&format!("{H},beacon,sample\n{body}# again\n{body}"))
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "m.csv:5: repeats the report of line 2 (same separation, beacon position, beacon, frequency, \
             power, sensitivity and sample index 0): is (part of) the file in twice?"
        );
        // Another setting, another report; without sample indices rows are repeated samples.
        assert!(read(&format!(
            "{H},beacon,sample,power\n20,0,0,20,1,2,3,0,1\n20,0,0,20,1,2,3,0,2\n"
        ))
        .is_ok());
        assert!(read(&format!("{H}\n20,0,0,20,1,2\n20,0,0,20,1,2\n")).is_ok());
    }

    #[test]
    fn round_trip_and_select() {
        let s = Sample {
            separation_in: 20.0,
            r: [0.5, 1.5, 20.0],
            x: 10.25,
            y: -3.0,
            beacon: Some(3),
            sample: Some(0),
            ..Default::default()
        };
        let d = Dataset {
            path: "t.csv".into(),
            samples: vec![
                s,
                Sample {
                    separation_in: 25.0,
                    ..s
                },
            ],
        };
        let mut buf = Vec::new();
        d.write(&mut buf, &["made by a test".into()]).unwrap();
        let back = Dataset::from_reader(Path::new("t.csv"), &buf[..]).unwrap();
        assert_eq!(back.samples[0].x, 10.25);
        assert_eq!(back.samples[0].beacon, Some(3));
        assert_eq!(back.separations(), vec![20.0, 25.0]);
        assert_eq!(back.select(&[25.0]).unwrap().samples.len(), 1);
        // A measured plate position (mean of four corners) is found from its nominal value.
        let mut m = back.clone();
        m.samples[1].separation_in = 25.0125;
        let got = m.select(&[25.0]).unwrap();
        assert_eq!(got.samples.len(), 1);
        assert_eq!(got.samples[0].separation_in, 25.0125);
        assert_eq!(m.nearest_separation(19.95), Some(20.0));
        assert_eq!(m.nearest_separation(24.8), None);
        assert!(back.warnings().is_empty(), "{:?}", back.warnings());
        // A file in millimetres, and beacon z given from the plate: read, but warned about,
        // naming the file and the first line.
        let mut mm = back.clone();
        for s in &mut mm.samples {
            s.separation_in *= 25.4;
            s.r = s.r.map(|v| v * 25.4);
        }
        let w = mm.warnings();
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with("t.csv:3: separation_in 508 in (the file's largest 635 in)"),
            "{w:?}"
        );
        assert!(w[0].contains("millimetres"), "{w:?}");
        let mut z0 = back.clone();
        z0.samples[1].r[2] = 0.0;
        let w = z0.warnings();
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with("t.csv:4: beacon_z_in 0 in with separation_in 25 in (1 of 2 rows"),
            "{w:?}"
        );
        let e = back.select(&[30.0]).unwrap_err();
        assert!(
            e.contains("separation(s) 30 not in the file, nor any within 0.1 in (it has 20, 25)"),
            "{e}"
        );
    }

    /// The typo warning's row ratio at its boundary: 2 rows at 2.0001 in beside 8 at 2 in
    /// (4 times theirs) are warned about, beside 7 (3.5 times) are not; whichever side of
    /// the value the few rows lie.
    #[test]
    fn a_separation_typo_needs_four_times_the_rows_beside_it() {
        let file = |many: usize, odd: f64| {
            let mut samples = Vec::new();
            for (sep, n) in [(2.0, many), (odd, 2)] {
                for k in 0..n {
                    samples.push(Sample {
                        separation_in: sep,
                        r: [k as f64 - 4.0, 0.5, sep],
                        x: 100.0 * k as f64,
                        y: -50.0,
                        line: samples.len() + 2,
                        ..Default::default()
                    });
                }
            }
            Dataset {
                path: "t.csv".into(),
                samples,
            }
        };
        for odd in [2.0001, 1.9999] {
            let w = file(4 * 2, odd).warnings();
            assert_eq!(w.len(), 1, "{w:?}");
            assert!(
                w[0].starts_with(&format!(
                    "t.csv:10: separation_in {odd} on 2 rows (lines 10, 11) beside 2 on 8 rows: \
                     within 0.01 in of a separation with at least 4 times the rows"
                )),
                "{w:?}"
            );
            let w = file(4 * 2 - 1, odd).warnings();
            assert!(w.is_empty(), "{odd}: {w:?}");
        }
    }

    /// The robust sigma is the noise for any number of samples per point (odd and even: the
    /// [`MAD_FACTOR`] table), and a glitch is named, counted and kept.
    #[test]
    fn glitch_check_scales_to_sigma_and_names_glitches() {
        for samples in [3, 4, 5, 10, 20, 70] {
            let ds = crate::sim::SimConfig {
                separations: vec![10.0, 20.0, 30.0],
                noise: 30.0,
                samples,
                seed: samples as u64,
                ..Default::default()
            }
            .run()
            .0;
            let g = ds.glitches();
            assert_eq!(g.samples, 0, "{samples}: {g:?}");
            for a in &g.axes {
                // 300 points: the MAD to ~3 % at 3 samples per point.
                assert!(
                    (a.robust_sigma / 30.0 - 1.0).abs() < 0.1,
                    "{samples}: {a:?}"
                );
                assert!(
                    (a.std_with / a.robust_sigma - 1.0).abs() < 0.1,
                    "{samples}: {a:?}"
                );
            }
            assert!(ds.warnings().is_empty(), "{:?}", ds.warnings());
            let mut bad = ds.clone();
            bad.path = "g.csv".into();
            for (k, s) in bad.samples.iter_mut().enumerate() {
                s.line = k + 2;
            }
            bad.samples[7].y += 3000.0;
            bad.samples[400].y -= 500.0;
            let g = bad.glitches();
            assert_eq!((g.samples, g.axes[0].samples), (2, 0), "{samples}: {g:?}");
            assert_eq!(g.axes[1].lines, vec![9, 402]);
            let y = &g.axes[1];
            assert!(
                y.inflation() > 1.1 && (y.std_without / 30.0 - 1.0).abs() < 0.1,
                "{y:?}"
            );
            assert_eq!(bad.samples.len(), ds.samples.len());
            let w = bad.warnings();
            assert_eq!(w.len(), 1, "{w:?}");
            // 2 of 900-21,000 rows; from 20 samples per point (0.033 %, 0.0095 %), `{:.1}`
            // would print 0.0 %: under 0.1 % instead.
            let share = match samples {
                20 | 70 => "under 0.1 %".to_string(),
                _ => format!("{:.1} %", 200.0 / ds.samples.len() as f64),
            };
            assert!(
                w[0].starts_with(&format!(
                    "g.csv: 2 samples ({share} of the rows) lie more than 8 robust sigma from \
                     their point's median (Y at lines 9, 402): glitches"
                )),
                "{w:?}"
            );
        }
        // A noise below the count resolution: the floor, not a robust sigma of 0, sets the
        // threshold (8 counts), so a 1-count step is no glitch and a 9-count one is.
        let mut ds = crate::sim::SimConfig {
            separations: vec![20.0],
            noise: 0.2,
            samples: 5,
            ..Default::default()
        }
        .run()
        .0;
        assert_eq!(ds.glitches().samples, 0);
        ds.samples[0].x += 1.0;
        assert_eq!(ds.glitches().samples, 0);
        ds.samples[0].x += 8.0;
        assert_eq!(ds.glitches().axes[0].samples, 1);
    }

    #[test]
    fn separation_lists() {
        assert_eq!(parse_separations("20,25").unwrap(), vec![20.0, 25.0]);
        assert_eq!(parse_separations("2..5").unwrap(), vec![2.0, 3.0, 4.0, 5.0]);
        assert_eq!(
            parse_separations("2..30:14").unwrap(),
            vec![2.0, 16.0, 30.0]
        );
        assert!(parse_separations("a").is_err());
        assert!(parse_separations("-1").is_err());
        assert!(parse_separations("5..2").is_err());
        assert_eq!(
            parse_new_separations("25,25").unwrap_err(),
            "25 in is listed twice in `25,25`"
        );
        assert!(parse_new_separations("2..30:2,10").is_err());
        assert!(parse_new_separations("2..30:2,25").is_ok());
        assert!(parse_separations("2..10,10..30:5").is_ok());
    }

    #[test]
    fn huge_or_unbounded_separation_ranges_are_refused_before_expanding() {
        // These used to expand in full (7.6 GB for `1..1e12`) or loop forever.
        for s in [
            "1..1e12",
            "2..30:0.0000001",
            "2..inf",
            "2..30:inf",
            "nan..3",
            "2..NaN",
        ] {
            let e = parse_separations(s).unwrap_err();
            assert!(e.contains(s), "{s}: {e}");
        }
        let e = parse_separations("1..1e12").unwrap_err();
        assert!(e.contains("more than the 10000 allowed"), "{e}");
        let e = parse_separations("2..inf").unwrap_err();
        assert!(e.contains("finite"), "{e}");
        assert!(parse_separations("inf").is_err());
        // The cap counts the whole list.
        assert_eq!(
            parse_separations("1..10000").unwrap().len(),
            MAX_SEPARATIONS
        );
        assert!(parse_separations("1..10000,20000").is_err());
        assert!(parse_separations("0.5,1..10000").is_err());
    }
}
