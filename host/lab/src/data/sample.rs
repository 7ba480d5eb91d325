//! The rows of a measurement file in memory: [`Sample`], [`Dataset`] and [`Point`], the
//! columns in the order `cta` writes them, and the 16-bit rail of the NorthStar's outputs.

use std::collections::BTreeMap;
use std::io::Write;

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
pub const OPTIONAL: [&str; 9] = [
    "beacon",
    "frequency_hz",
    "power",
    "sensitivity",
    "sample",
    "magnitude",
    "group",
    "time_s",
    "report",
];

/// The optional columns after `magnitude`, which [`Dataset::write`] writes only when a row
/// records them: `group`, `time_s`, `report`.
const LATE: usize = 6;

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
    /// The sweep point the row was measured in: rows sharing it were lit together, in one
    /// group of a grouped plan (`group = N`); a beacon measured alone has a point of its own.
    pub group: Option<u32>,
    /// When the report was taken: seconds since the run started (a sweep: from the sensor
    /// board's report clock; a simulation: when the sweep order would take it).
    pub time_s: Option<f64>,
    /// The sensor board's report counter (every report of a session, spots and poses alike).
    pub report: Option<u32>,
    /// 1-based line number in the file (0 when made in memory).
    pub line: usize,
}

/// A measurement file in memory.
#[derive(Debug, Clone, Default)]
pub struct Dataset {
    /// Where it came from (empty when made in memory).
    pub path: std::path::PathBuf,
    /// The rows, in file order.
    pub samples: Vec<Sample>,
}

/// The highest beacon id: `100 * array + LED`, LED 0-99 row-major on one 10 x 10 array,
/// array 0-3 (the sweep's four-array `quad` layout; one array is 0-99).
pub const MAX_BEACON_ID: u32 = 399;

/// Bit pattern of a number for keys (0 and -0 alike).
pub(super) fn key_bits(v: f64) -> u64 {
    (v + 0.0).to_bits()
}

impl Dataset {
    /// Group the rows into points: one point per (separation, beacon position, frequency,
    /// power, sensitivity, sweep point), in first-seen order, each with the indices of its
    /// samples. The sweep point (`group`) keeps a beacon measured alone apart from the same
    /// beacon measured in its group.
    pub fn points(&self) -> Vec<Point> {
        let mut index: BTreeMap<[u64; 8], usize> = BTreeMap::new();
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
                s.group.map_or(u64::MAX, u64::from),
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

    /// Write in the documented format (`comments` as leading `#` lines): every column, but
    /// `group`, `time_s` and `report` only when a row records them (a sweep's file has all
    /// three; a simulated one the time alone).
    pub fn write(&self, w: &mut impl Write, comments: &[String]) -> std::io::Result<()> {
        for c in comments {
            writeln!(w, "# {}", comment_text(c))?;
        }
        let late = [
            self.samples.iter().any(|s| s.group.is_some()),
            self.samples.iter().any(|s| s.time_s.is_some()),
            self.samples.iter().any(|s| s.report.is_some()),
        ];
        let columns: Vec<&str> = OPTIONAL
            .iter()
            .enumerate()
            .filter(|(k, _)| *k < LATE || late[k - LATE])
            .map(|(_, c)| *c)
            .collect();
        writeln!(w, "{},{}", REQUIRED.join(","), columns.join(","))?;
        for s in &self.samples {
            write_fields(w, s, late)?;
        }
        Ok(())
    }
}

/// Free text (a plan's `name`, a note) made fit for one `#` comment line of a measurement
/// file: every line break or other control character becomes a space, so no part of it can
/// start a line of its own and be read as the header or a row.
pub fn comment_text(text: &str) -> String {
    text.chars()
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect()
}

/// Write one row in the documented column order (REQUIRED then OPTIONAL), every column.
pub fn write_row(w: &mut impl Write, s: &Sample) -> std::io::Result<()> {
    write_fields(w, s, [true; 3])
}

/// One row, with the late columns `late` says (`group`, `time_s`, `report`).
fn write_fields(w: &mut impl Write, s: &Sample, late: [bool; 3]) -> std::io::Result<()> {
    let o = |v: Option<f64>| v.map(|v| format!("{v}")).unwrap_or_default();
    let u = |v: Option<u32>| v.map(|v| v.to_string()).unwrap_or_default();
    write!(
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
        o(s.magnitude),
    )?;
    if late[0] {
        write!(w, ",{}", u(s.group))?;
    }
    if late[1] {
        write!(w, ",{}", o(s.time_s))?;
    }
    if late[2] {
        write!(w, ",{}", u(s.report))?;
    }
    writeln!(w)
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
