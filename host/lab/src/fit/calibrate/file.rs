//! The calibration file `cta calibrate --out` writes: the board's calibration with where it
//! came from.

use std::collections::BTreeMap;
use std::path::Path;

use cta_core::pose::Calibration;
use serde::{Deserialize, Serialize};

use super::Error;
use crate::fit::magnitude::LedBrightness;

/// What `--out` files carry in `fitted` (and how an earlier one is recognised).
pub const WRITER: &str = "cta calibrate";

/// The file `--out` writes: the board's calibration (what `load-calibration` reads) and,
/// under `fitted`, where it came from (ignored by the board).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CalibrationFile {
    /// The calibration (its fields at the top level, as `cta sensor template calibration`).
    #[serde(flatten)]
    pub calibration: Calibration,
    /// Provenance and fit quality.
    pub fitted: Provenance,
    /// Each LED's brightness relative to the others', from the spot magnitudes (host-side
    /// data the board ignores: `cta sensor load-constellation --brightness` puts it into a
    /// constellation's beacons). Empty (and absent from the file) without a magnitude law.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub led_brightness: Vec<LedBrightness>,
}

/// Where a calibration came from.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Provenance {
    /// [`WRITER`] and its version.
    pub by: String,
    /// The measurement file.
    pub source: String,
    /// Separations of the near-field fit, inches.
    pub separations: Vec<f64>,
    /// Separations of the pinhole fit, inches.
    pub pinhole_separations: Vec<f64>,
    /// 1-sigma by parameter (`d1..3` in, `p1..3`, `a` and `ay` deg, `s` in, `gx, gy`,
    /// `bx, by` /in^2, `H` counts, and the pinhole fit's `pinhole.d1..3` in, `pinhole.p1..3`,
    /// when the calibration holds the pinhole head).
    pub sigma: BTreeMap<String, f64>,
    /// Near-field fit chi-square per degree of freedom.
    pub chi2_dof: f64,
    /// Near-field fit residual RMS, counts (unweighted, point means).
    pub rms_counts: f64,
    /// Points fitted.
    pub points: usize,
    /// Points left out because an output was pinned.
    pub pinned_points: usize,
    /// Samples the glitch check flagged that `--drop-glitches` left out (0 without it, or
    /// when absent from the file).
    #[serde(default)]
    pub glitches_left_out: usize,
    /// Near-field parameters whose estimates correlate at 0.8 or more in magnitude:
    /// `[a, b, rho]` (empty when absent from the file).
    #[serde(default)]
    pub correlations: Vec<(String, String, f64)>,
    /// The near-field fit's full covariance, with its parameters' names and units (absent
    /// from files written before it was kept); checked when read ([`super::covariance::read`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance: Option<super::covariance::Covariance>,
    /// The run that wrote the file: the tool and its commit, the date, the command line and
    /// the measurement file's SHA-256 (absent from files written before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub run: Option<crate::provenance::Provenance>,
}

/// `--out` may replace an earlier calibration written by `cta calibrate`; never the
/// measurement file, and anything else only with `--force`.
pub fn check_out(out: &Path, data: &Path, force: bool) -> Result<(), Error> {
    let earlier = |p: &Path| {
        crate::bounded::read_text(p, crate::bounded::MAX_JSON_BYTES, "a JSON file")
            .ok()
            .and_then(|s| serde_json::from_str::<CalibrationFile>(&s).ok())
            .is_some_and(|f| f.fitted.by.starts_with(WRITER))
    };
    crate::data::check_derived_output(
        "--out",
        out,
        data,
        "cal.json",
        "an earlier `cta calibrate` calibration",
        earlier,
        force,
    )
    .map_err(Error::Output)
}
