//! The journal's vocabulary: what a run directory's `journal.jsonl` records, one event a
//! line, and the plate separation measured from the corners (thesis Ch IV). Every time is
//! written twice, as `at` (seconds since the epoch) and `time` (ISO 8601 UTC, [`stamp`]).

use serde::{Deserialize, Serialize};

use super::stamp;

/// What became of a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PointStatus {
    /// All samples taken.
    Ok,
    /// The sensor never reported the beacon's spot: recorded as a comment line, no rows.
    NoSignal,
    /// Some samples, fewer than asked, within the report limit.
    Partial,
}

/// The plate separation from the four corner readings (thesis Ch IV, "Plate levelness and
/// separation distance": the separation is measured at four locations around the outer edges
/// of the plates, the measurements are averaged to obtain the height at the centre, and "the
/// uncertainty in the center height will be the difference between the center height and the
/// maximum and minimum measurements").
///
/// Read from a journal, the uncertainty is derived again from the corners: a journal of an
/// earlier version holds `spread` instead, the corners' sample standard deviation, which is
/// not Ch IV's bound (one high corner, `(3t, -t, -t, -t)` about the mean: std `2t`, bound `3t`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(from = "SeparationRecord")]
pub struct SeparationEntry {
    /// Index in the plan's separations.
    pub sep_idx: usize,
    /// Nominal separation, in.
    pub nominal: f64,
    /// The four corner readings, in (empty when not measured: `--yes` without readings).
    pub corners: Vec<f64>,
    /// Recorded separation: the mean of the corners (the nominal if none), in.
    pub mean: f64,
    /// Its uncertainty (Ch IV), in: the larger of (maximum corner - mean) and (mean - minimum
    /// corner), i.e. the largest |corner - mean|; 0 when not measured. See
    /// [`corner_uncertainty`].
    pub uncertainty: f64,
    /// Who entered it: "operator", "scripted (--yes, not measured)", "simulated plate".
    pub source: String,
    /// Where the corners were read: at x, y = +/-this (in) in frame N, in the order
    /// [`super::corners::CORNER_ORDER`], which gives the plate's tilt
    /// ([`super::corners::corner_tilt`]). `None` without readings, and in journals of
    /// versions that did not ask for the corners in an order.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rods_xy_in: Option<f64>,
}

/// A `separation` event as journalled by any version: `spread` (the corners' standard
/// deviation, before the uncertainty was Ch IV's) is accepted for `uncertainty`.
#[derive(Deserialize)]
struct SeparationRecord {
    sep_idx: usize,
    nominal: f64,
    corners: Vec<f64>,
    mean: f64,
    #[serde(alias = "spread", default)]
    uncertainty: f64,
    source: String,
    #[serde(default)]
    rods_xy_in: Option<f64>,
}

impl From<SeparationRecord> for SeparationEntry {
    fn from(r: SeparationRecord) -> SeparationEntry {
        // Derived again from the corners (the measurement): an older journal's `spread` is a
        // standard deviation, not the uncertainty this field holds.
        let uncertainty = if r.corners.is_empty() {
            r.uncertainty
        } else {
            corner_uncertainty(&r.corners)
        };
        SeparationEntry {
            sep_idx: r.sep_idx,
            nominal: r.nominal,
            corners: r.corners,
            mean: r.mean,
            uncertainty,
            source: r.source,
            rods_xy_in: r.rods_xy_in,
        }
    }
}

/// The mean of corner readings, unrounded (0 for none).
pub fn corner_mean(corners: &[f64]) -> f64 {
    if corners.is_empty() {
        return 0.0;
    }
    corners.iter().sum::<f64>() / corners.len() as f64
}

/// The uncertainty of the mean of corner readings (thesis Ch IV): the difference between the
/// mean and the maximum and minimum readings, the larger of the two, in (0 for none), rounded
/// to 0.1 mil as the recorded mean is (so that 5 mils reads 5 mils at any separation).
pub fn corner_uncertainty(corners: &[f64]) -> f64 {
    let m = corner_mean(corners);
    let u = corners.iter().map(|c| (c - m).abs()).fold(0.0, f64::max);
    (u * 1e4).round() / 1e4
}

/// Ch IV's bound on a separation's uncertainty, in: plates leveled at their centres with a
/// machinist's level of 5 mils per foot are parallel to +/-5 mils one foot out.
pub const LEVEL_BOUND_IN: f64 = 0.005;

/// The operator's question when corner readings differ from their mean by more than
/// [`LEVEL_BOUND_IN`] (the plates are not as level as Ch IV assumes, or a reading is off):
/// `None` within it.
pub fn levelness_question(corners: &[f64]) -> Option<String> {
    let u = corner_uncertainty(corners);
    (u > LEVEL_BOUND_IN).then(|| {
        format!(
            "The corners {corners:?} differ from their mean by up to {:.1} mils, more than the \
             +/-5 mils Ch IV expects of leveled plates (a machinist's level, 5 mils per foot): \
             a tilted plate or a misread corner. Keep them? [y/N = level and measure again] ",
            u * 1000.0
        )
    })
}

/// One journal line.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum Event {
    /// A session (first run or a resume) started.
    Session {
        /// Session number, 1-based.
        n: u32,
        /// Wall-clock time, seconds since the epoch (and `time`, ISO 8601 UTC: [`stamp`]).
        #[serde(flatten, with = "stamp::at")]
        at: f64,
        /// `cta` version.
        software: String,
        /// The command line.
        command: Vec<String>,
        /// Board identities (`beacon`, `sensor`), as answered.
        boards: serde_json::Value,
        /// Simulation settings (`None` for real boards).
        sim: Option<serde_json::Value>,
        /// The plan in use (validated; [`Plan`]'s fields): a resume compares `plan.toml` (or
        /// the file given with `--plan`) with the last session's, accepts changed timing keys
        /// ([`RESUME_MAY_CHANGE`]) with a note and refuses any other change, so every
        /// session's plan says what the first one's did but for timing. Absent in journals of
        /// older versions.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        plan: Option<serde_json::Value>,
        /// First point of this session.
        from_point: usize,
        /// What opening the run directory found and did (a dead holder's lock taken over,
        /// uncommitted data discarded, ...).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        notes: Vec<String>,
    },
    /// The plate was moved (or its position confirmed on resume).
    Separation(SeparationEntry),
    /// The array was (re)mounted in a quadrant (quad layout).
    Quadrant {
        /// Quadrant 0..4.
        quadrant: usize,
        /// Who confirmed it.
        source: String,
    },
    /// The power switches were set.
    Power {
        /// Power level.
        level: u8,
        /// Who confirmed it.
        source: String,
    },
    /// A point was committed.
    Point {
        /// Point index in the plan.
        i: usize,
        /// Outcome.
        status: PointStatus,
        /// Samples written.
        samples: u32,
        /// Sensor reports read for it (with or without the spot).
        reports: u32,
        /// Reports lost on the wire (gaps in the board's report counter).
        lost: u32,
        /// Attempts it took (1 = first try).
        attempts: u32,
        /// Length of data.csv after its rows.
        csv_end: u64,
        /// FNV-1a 64 (16 hex digits) of data.csv's first `csv_end` bytes: a resume checks the
        /// committed data are still what was written. Absent in journals of older versions.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        csv_hash: Option<String>,
        /// When it was committed, seconds since the epoch (and `time`, ISO 8601 UTC:
        /// [`stamp`]; `cta sweep --status`'s last commit and rate). Absent in journals of
        /// older versions.
        #[serde(flatten, with = "stamp::opt_at")]
        at: Option<f64>,
    },
    /// Something went wrong, and what was done about it.
    Fault {
        /// Seconds since the epoch (and `time`, ISO 8601 UTC: [`stamp`]).
        #[serde(flatten, with = "stamp::at")]
        at: f64,
        /// Point being measured.
        point: usize,
        /// "beacon", "sensor" or "host".
        board: String,
        /// What happened.
        what: String,
        /// What the run did ("retry point", "reconnect", "stop").
        action: String,
    },
    /// A session ended.
    Stop {
        /// Seconds since the epoch (and `time`, ISO 8601 UTC: [`stamp`]).
        #[serde(flatten, with = "stamp::at")]
        at: f64,
        /// "complete", "interrupted (Ctrl-C)", "gave up: ...".
        reason: String,
        /// Next point to measure.
        next_point: usize,
        /// What a resume of a complete run changed without opening the boards (the notes a
        /// session would journal: uncommitted bytes cut, a torn line dropped, ...). Absent
        /// otherwise, and in journals of older versions.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        notes: Vec<String>,
    },
}
