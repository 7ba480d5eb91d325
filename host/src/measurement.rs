//! The CTA measurement file: what sweeps write, what `cta simulate` writes, and what users
//! bring from their own rigs. The format is documented in `host/MEASUREMENTS.md`.
//!
//! CSV with a header line. Required columns: `separation_in`, `beacon_x_in`, `beacon_y_in`,
//! `beacon_z_in`, `x`, `y`. Optional: `beacon`, `frequency_hz`, `power`, `sensitivity`,
//! `sample`, `magnitude`. Unknown columns are ignored; lines starting with `#` are comments.
//! Beacon positions are in the N frame (inches); `x`, `y` are NorthStar counts.

use std::collections::BTreeMap;
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

/// Why a measurement file was rejected. Every variant names the file, and the line and
/// column where there is one.
#[derive(Debug)]
pub enum ReadError {
    /// The file could not be opened or read.
    Io(PathBuf, std::io::Error),
    /// No header / no data rows.
    Empty(PathBuf),
    /// A required column is missing from the header.
    MissingColumn(PathBuf, &'static str),
    /// A value is not a finite number.
    BadValue {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// Column name.
        column: String,
        /// The offending text.
        value: String,
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
    },
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReadError::Io(p, e) => write!(f, "{}: {e}", p.display()),
            ReadError::Empty(p) => write!(
                f,
                "{}: no measurements (empty file or header only)",
                p.display()
            ),
            ReadError::MissingColumn(p, c) => write!(
                f,
                "{}: missing required column `{c}` (required: {})",
                p.display(),
                REQUIRED.join(", ")
            ),
            ReadError::BadValue {
                path,
                line,
                column,
                value,
            } => write!(
                f,
                "{}:{line}: column `{column}`: `{value}` is not a finite number",
                path.display()
            ),
            ReadError::ShortRow {
                path,
                line,
                found,
                expected,
            } => write!(
                f,
                "{}:{line}: {found} fields, the header has {expected}",
                path.display()
            ),
        }
    }
}

impl std::error::Error for ReadError {}

impl Dataset {
    /// Read a measurement file.
    pub fn read(path: &Path) -> Result<Dataset, ReadError> {
        let f = std::fs::File::open(path).map_err(|e| ReadError::Io(path.to_path_buf(), e))?;
        Self::from_reader(path, f)
    }

    /// Read from any reader; `path` is used in messages.
    pub fn from_reader(path: &Path, r: impl Read) -> Result<Dataset, ReadError> {
        let p = path.to_path_buf();
        let mut lines = BufReader::new(r).lines().enumerate();
        // Header: the first line that is neither blank nor a comment.
        let header: Vec<String> = loop {
            match lines.next() {
                None => return Err(ReadError::Empty(p)),
                Some((_, l)) => {
                    let l = l.map_err(|e| ReadError::Io(p.clone(), e))?;
                    let t = l.trim();
                    if t.is_empty() || t.starts_with('#') {
                        continue;
                    }
                    break t.split(',').map(|s| s.trim().to_string()).collect();
                }
            }
        };
        let col = |name: &str| header.iter().position(|h| h == name);
        let mut req = [0usize; 6];
        for (k, name) in REQUIRED.iter().enumerate() {
            req[k] = col(name).ok_or(ReadError::MissingColumn(p.clone(), name))?;
        }
        let opt: Vec<Option<usize>> = OPTIONAL.iter().map(|n| col(n)).collect();
        let mut samples = Vec::new();
        for (i, l) in lines {
            let line = i + 1;
            let l = l.map_err(|e| ReadError::Io(p.clone(), e))?;
            let t = l.trim();
            if t.is_empty() || t.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = t.split(',').map(str::trim).collect();
            if fields.len() < header.len() {
                return Err(ReadError::ShortRow {
                    path: p,
                    line,
                    found: fields.len(),
                    expected: header.len(),
                });
            }
            let num = |idx: usize| -> Result<f64, ReadError> {
                let s = fields[idx];
                match s.parse::<f64>() {
                    Ok(v) if v.is_finite() => Ok(v),
                    _ => Err(ReadError::BadValue {
                        path: p.clone(),
                        line,
                        column: header[idx].clone(),
                        value: s.to_string(),
                    }),
                }
            };
            let opt_num = |k: usize| -> Result<Option<f64>, ReadError> {
                match opt[k] {
                    Some(idx) if !fields[idx].is_empty() => num(idx).map(Some),
                    _ => Ok(None),
                }
            };
            let as_u32 = |v: Option<f64>, k: usize| -> Result<Option<u32>, ReadError> {
                match v {
                    Some(f) if f < 0.0 || f.fract() != 0.0 || f > u32::MAX as f64 => {
                        Err(ReadError::BadValue {
                            path: p.clone(),
                            line,
                            column: OPTIONAL[k].to_string(),
                            value: fields[opt[k].unwrap()].to_string(),
                        })
                    }
                    Some(f) => Ok(Some(f as u32)),
                    None => Ok(None),
                }
            };
            samples.push(Sample {
                separation_in: num(req[0])?,
                r: [num(req[1])?, num(req[2])?, num(req[3])?],
                x: num(req[4])?,
                y: num(req[5])?,
                beacon: as_u32(opt_num(0)?, 0)?,
                frequency_hz: opt_num(1)?,
                power: opt_num(2)?,
                sensitivity: opt_num(3)?,
                sample: as_u32(opt_num(4)?, 4)?,
                magnitude: opt_num(5)?,
                line,
            });
        }
        if samples.is_empty() {
            return Err(ReadError::Empty(p));
        }
        Ok(Dataset { path: p, samples })
    }

    /// The distinct separations, ascending.
    pub fn separations(&self) -> Vec<f64> {
        let mut v: Vec<f64> = self.samples.iter().map(|s| s.separation_in).collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        v
    }

    /// Keep only the given separations (matched to 1e-6 in). Errors name the separations
    /// that are not in the file.
    pub fn select(&self, seps: &[f64]) -> Result<Dataset, String> {
        let have = self.separations();
        let missing: Vec<String> = seps
            .iter()
            .filter(|s| !have.iter().any(|h| (h - *s).abs() < 1e-6))
            .map(|s| format!("{s}"))
            .collect();
        if !missing.is_empty() {
            return Err(format!(
                "{}: separation(s) {} not in the file (it has {})",
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
                .filter(|s| seps.iter().any(|h| (h - s.separation_in).abs() < 1e-6))
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

#[cfg(test)]
mod tests {
    use super::*;

    fn read(s: &str) -> Result<Dataset, ReadError> {
        Dataset::from_reader(Path::new("m.csv"), s.as_bytes())
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
        let e = back.select(&[30.0]).unwrap_err();
        assert!(
            e.contains("separation(s) 30 not in the file (it has 20, 25)"),
            "{e}"
        );
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
