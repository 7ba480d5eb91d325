//! The truth sidecar `FILE.truth.json` beside a simulated measurement file: the hidden head,
//! physics, effects and draws behind the data, for `cta fit` and `cta evaluate` to compare with.

use cta_core::emulator::Pose;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A truth sidecar that cannot be read or parsed: the file and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {error}", .path.display())]
pub struct TruthError {
    /// The sidecar.
    pub path: PathBuf,
    /// Why (the I/O or JSON error's message).
    pub error: String,
}

/// The truth behind a simulated file: written next to it as `FILE.truth.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Truth {
    /// What wrote this.
    pub generator: String,
    /// True head offset d, in.
    pub d: [f64; 3],
    /// True MRP p.
    pub p: [f64; 3],
    /// The far-field scale height `H = beta tan(a_x)` of the true head.
    pub h: f64,
    /// Cell offset s, in.
    pub s: f64,
    /// Face angles of the X and Y pairs, deg.
    pub alpha_deg: [f64; 2],
    /// Base physics: "thesis" or "far-field".
    pub physics: String,
    /// Base beacon pattern, e.g. "lambertian H=60".
    pub pattern: String,
    /// Injected effects, `NAME=VALUE` as on the command line.
    pub effects: Vec<String>,
    /// Per separation: the plate's true lateral offset (x, y) in (plate_offset effect).
    pub plate_offsets: Vec<[f64; 2]>,
    /// Per separation: true separation minus recorded separation, in (separation_error).
    pub separation_errors: Vec<f64>,
    /// Per separation: the plate's tilt vector (tx, ty), deg (plate_tilt; see
    /// [`Placement::tilt_deg`]). Empty in files written before it existed.
    #[serde(default)]
    pub plate_tilts_deg: Vec<[f64; 2]>,
    /// Per LED (by beacon id): its true in-plane offset (dx, dy) from its nominal place, in
    /// (`led_position`); absent when every LED sits on its place.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub led_offsets: Vec<[f64; 2]>,
    /// Per LED (by beacon id): its boresight's own tilt vector (tx, ty), deg (`led_tilt`);
    /// absent when no LED is tilted.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub led_tilts_deg: Vec<[f64; 2]>,
    /// Per array on the plate (the quad layout, array `a` holding beacon ids `100 a` to
    /// `100 a + 99`): its nominal centre (x, y), in; absent with one array.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub array_centres: Vec<[f64; 2]>,
    /// Per array: where it truly sits against its nominal place (`array_pose`): shift
    /// (dx, dy) in and turn dtheta deg about its centre (counter-clockwise seen from the
    /// sensor's +z); absent when every array sits on its place.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub array_poses: Vec<[f64; 3]>,
    /// Recorded separations, in.
    pub separations: Vec<f64>,
    /// Noise 1-sigma, counts.
    pub noise_counts: f64,
    /// How the noise varies, when it is not `noise_counts` everywhere (the sweep
    /// simulator's grows as a spot dims).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_law: Option<String>,
    /// Spot magnitude noise, percent (1-sigma); 0 (also in files written before it existed):
    /// none.
    #[serde(default)]
    pub magnitude_noise_percent: f64,
    /// The LEDs' brightness scatter, percent (1-sigma of the logarithm); 0 (also in files
    /// written before it existed): all alike.
    #[serde(default)]
    pub led_brightness_percent: f64,
    /// Each LED's brightness factor (its magnitudes are multiplied by it), by beacon id (the
    /// array's LED for a sweep: the four-array layout's beacon `100 a + i` is LED `i`); absent
    /// when all are 1.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub led_brightness: Vec<f64>,
    /// Samples per point.
    pub samples: usize,
    /// Seed.
    pub seed: u64,
    /// Beacons skipped because a cell pair saw nothing (outside the field of view).
    pub skipped_points: usize,
}

impl Truth {
    /// Sidecar path for a measurement file: `FILE.csv` -> `FILE.truth.json`.
    pub fn path_for(csv: &Path) -> PathBuf {
        csv.with_extension("truth.json")
    }

    /// Load the sidecar of `csv` if there is one.
    pub fn load_for(csv: &Path) -> Option<Result<Truth, TruthError>> {
        let p = Self::path_for(csv);
        if !p.exists() {
            return None;
        }
        let err = |e: &dyn std::fmt::Display| TruthError {
            path: p.clone(),
            error: e.to_string(),
        };
        Some(
            crate::bounded::read_text(&p, crate::bounded::MAX_JSON_BYTES, "a JSON file")
                .map_err(|e| err(&e))
                .and_then(|s| serde_json::from_str(&s).map_err(|e| err(&e))),
        )
    }

    /// The sidecar of `csv` for `cta fit`, which can do without it: an unreadable sidecar
    /// gives a warning (naming the file and the parse error) instead of an error.
    pub fn load_for_fit(csv: &Path) -> (Option<Truth>, Option<String>) {
        match Self::load_for(csv) {
            None => (None, None),
            Some(Ok(t)) => (Some(t), None),
            Some(Err(e)) => (
                None,
                Some(format!(
                    "{e} (unreadable truth sidecar: the fit is not compared with the truth)"
                )),
            ),
        }
    }

    /// The true pose.
    pub fn pose(&self) -> Pose<f64> {
        Pose {
            d: Vector3::from(self.d),
            p: Vector3::from(self.p),
        }
    }
}
