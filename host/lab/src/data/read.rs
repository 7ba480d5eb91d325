//! Reading a measurement file: the header, the fields of each line, every value checked
//! against its column's documented range (MEASUREMENTS.md).

use std::collections::HashMap;
use std::io::{BufReader, Read};
use std::path::Path;

use super::error::printable;
use super::sample::key_bits;
use super::{Dataset, ReadError, Reason, Sample, MAX_BEACON_ID, OPTIONAL, REQUIRED};
use crate::bounded::{read_line, Line, MAX_CSV_BYTES, MAX_LINE_BYTES};

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

/// The largest separation or beacon coordinate a measurement file may hold, inches.
pub const MAX_INCHES: f64 = 1000.0;

fn domain(column: &str) -> Domain {
    // The upper bounds are far past any rig (a CTA is a few feet across) and keep sums of
    // squares finite: a position of 1e308 would turn fits and means into NaN and inf.
    let above = |lo: f64, hi: f64, text| Domain::Range {
        lo,
        lo_open: true,
        hi,
        text,
    };
    match column {
        "separation_in" => above(0.0, MAX_INCHES, "> 0 in, at most 1000 in"),
        "beacon_x_in" | "beacon_y_in" | "beacon_z_in" => Domain::Range {
            lo: -MAX_INCHES,
            lo_open: false,
            hi: MAX_INCHES,
            text: "-1000..1000 in",
        },
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
        "frequency_hz" => above(0.0, 1e9, "> 0 Hz, at most 1e9 Hz"),
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
        "time_s" => Domain::Range {
            lo: 0.0,
            lo_open: false,
            hi: 1e9,
            text: "0..1e9 s",
        },
        "report" => Domain::Int {
            lo: 0.0,
            hi: u32::MAX as f64,
            text: "0..4294967295",
        },
        "group" => Domain::Int {
            lo: 0.0,
            hi: u32::MAX as f64,
            text: "0..4294967295",
        },
        "magnitude" => Domain::Range {
            lo: 0.0,
            lo_open: false,
            hi: 1e9,
            text: "0..1e9",
        },
        _ => Domain::Finite,
    }
}

/// Whether `text` reads as a measurement file: its first line that is neither blank nor a `#`
/// comment names the required columns (so a command given one where a JSON file belongs can
/// say what it got).
pub fn looks_like_measurements(text: &str) -> bool {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    text.split(['\n', '\r'])
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
        let mut total = 0u64;
        let mut header = true;
        // The next line that is neither blank nor a comment, split into `buf`/`ends`: its
        // number, and its last byte (a newline, except on a file's last line, which has none
        // when the file was cut off mid-write).
        let mut next = |buf: &mut Vec<u8>,
                        ends: &mut Vec<usize>|
         -> Result<Option<(usize, Option<u8>)>, ReadError> {
            loop {
                let got = read_line(&mut br, &mut raw, MAX_LINE_BYTES)
                    .map_err(|e| ReadError::Io(p.clone(), e))?;
                if got == Line::End {
                    return Ok(None);
                }
                line += 1;
                if got == Line::TooLong {
                    return Err(ReadError::LineTooLong {
                        path: p.clone(),
                        line,
                    });
                }
                total += raw.len() as u64;
                if total > MAX_CSV_BYTES {
                    return Err(ReadError::TooBig(p.clone()));
                }
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
        // First line of each (separation, position, beacon, settings, group, sample index).
        let mut seen: HashMap<[u64; 10], usize> = HashMap::new();
        // The last row, when no line break follows it: its line, last column and last value.
        let mut unended: Option<(usize, String, String)> = None;
        while let Some((line, last_byte)) = next(&mut buf, &mut ends)? {
            let ended = matches!(last_byte, Some(b'\n' | b'\r'));
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
                group: opt_num(6)?.map(|v| v as u32),
                time_s: opt_num(7)?,
                report: opt_num(8)?.map(|v| v as u32),
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
                    s.group.map_or(u64::MAX, u64::from),
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
}
