//! The parametric models `cta analyze` fits: a starting model (the eq 63 near-field physics,
//! `thesis`, or the 7-parameter collinearity model of eq 65, `pinhole`) plus any set of
//! candidate effects from the vocabulary, each adding its own parameters.
//!
//! Every model is evaluated through the core emulator (eqs 60-63, `cta_core::emulator`), so
//! the physics the analysis fits is exactly the physics `cta simulate` injects. The
//! parameter vector is laid out as: the starting model's parameters, then each global
//! effect's parameters in the order the effects were added, then the per-separation blocks
//! (`plate_offset`: x, y per separation; `separation_error`: z per separation; `plate_tilt`:
//! tx, ty per separation).
//!
//! Jacobians are forward finite differences (host only; the per-separation parameters touch
//! only their own separation's rows, so they cost one evaluation of that separation each).

use super::arrays::{arrays_of, displacement, Array};
use super::data::{Data, PointMean};
use crate::sim::Placement;
use cta_core::emulator::{Effects, Emulator, Head, BETA};
use cta_core::glsdc::{self, ModelError, Problem, Settings};
use cta_core::pattern::Pattern;
use cta_core::real::{deg, rad};
use nalgebra::{DMatrix, DVector, Dyn, Vector3};

/// The starting model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Base {
    /// The eq 63 near-field physics (proximity at s = 0.175 in, inverse-square intensity,
    /// Lambertian 60 deg beacons, face angles 30 deg, beta = 32768) with the pose d, p free
    /// (6 parameters). REFERENCE.md "beyond the thesis".
    Thesis,
    /// The 7-parameter collinearity model of eq 65: d, p and the scale height H free; the
    /// far-field emulator with `H = beta tan a`.
    Pinhole,
}

impl Base {
    /// Name as printed.
    pub fn name(self) -> &'static str {
        match self {
            Base::Thesis => "thesis",
            Base::Pinhole => "pinhole",
        }
    }
    /// Names of the starting model's parameters (the first entries of every model's vector).
    pub fn names(self) -> &'static [&'static str] {
        match self {
            Base::Thesis => &["d1", "d2", "d3", "p1", "p2", "p3"],
            Base::Pinhole => &["d1", "d2", "d3", "p1", "p2", "p3", "H"],
        }
    }
}

/// A candidate effect (the vocabulary of `sim::effects`, minus the simulation-only
/// `crosstalk`). Physics and parameters are documented on each variant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Cand {
    /// `proximity`: the cells sit at +/-S from the head centre. From `pinhole`: proximity on
    /// with S free (start 0.175 in); from `thesis`: S free instead of fixed at 0.175 in.
    /// Parameter `S` (in).
    Proximity,
    /// `intensity`: inverse-square intensity per cell, `I_k = 1/|b_k|^2`. A switch (no
    /// parameter); only a candidate from `pinhole`, and it only shows once `proximity` puts
    /// the cells at different distances.
    Intensity,
    /// `beacon_pattern`: Lambertian `cos^m g` with m free; reported as the half-intensity
    /// angle `H_deg` (m = ln 0.5 / ln cos H). From `pinhole` the beacon starts uniform (m = 0
    /// would be uniform; the fit starts at the nominal m = 1).
    BeaconPattern,
    /// `beacon_tilt`: every LED boresight tilted from -z of N. Fitted as the tilt vector
    /// (`tx`, `ty`) in deg (smooth through zero tilt), reported as `T_deg` and `AZ_deg`.
    BeaconTilt,
    /// `cell_gain`: cell 1's signal times (1+GX), cell 3's times (1+GY). Parameters `GX`, `GY`.
    CellGain,
    /// `cell_bias`: BX added to cell 1's signal, BY to cell 3's (1/in^2). Parameters `BX`, `BY`.
    CellBias,
    /// `ambient`: B added to all four cells' signals (1/in^2), compressing both outputs by
    /// `S/(S + 2B)` (eq 63). Parameter `B`.
    Ambient,
    /// `face_angle`: the X pair's face angle is 30+DX deg, the Y pair's 30+DY deg
    /// (`thesis`). From `pinhole`, where H already sets a common face angle, only the Y
    /// pair's difference `DY` is added.
    FaceAngle,
    /// `saturation`: every cell signal clipped at S (1/in^2). Fitted as ln S (positive by
    /// construction), started from a scan of the predicted signal levels; reported as `S`.
    Saturation,
    /// `plate_offset`: one lateral plate offset (x, y) per separation, in. Their mean is held
    /// at zero (a common offset is the head offset d1, d2).
    PlateOffset,
    /// `separation_error`: one separation correction z per separation, in (true minus
    /// recorded). Their mean is held at zero (a common error is d3).
    SeparationError,
    /// `plate_tilt`: one tilt vector (tx, ty) of the plate per separation, deg (the plate
    /// turned about its centre, its LEDs' boresights with it; see
    /// [`crate::sim::Placement`]). A plate turned about its centre `c = (0, 0, z)` is
    /// the whole scene turned about the head (which the head attitude absorbs) plus the plate
    /// moved sideways by about `z T`: a tilt common to every separation is a head rotation
    /// plus lateral offsets in proportion to the separation. Alone it is told by those
    /// offsets, so its mean is free; with `plate_offset`, whose offsets absorb them, its mean
    /// is held at zero ([`Model::zero_mean`]).
    PlateTilt,
    /// `led_position`: one in-plane offset (dx, dy) per LED, in, the same at every
    /// separation (each LED off its pads). Needs each LED identified (the `beacon` column).
    /// Gauge ([`Model::led_gauge`]): a common shift of every LED is the head offset d1, d2,
    /// and a common turn about the plate's centre (the N z axis) is the head's p3 (plus a
    /// shift), so the offsets' mean and their mean turn are held at zero; with
    /// `separation_error` in the model their mean radial stretch is held too (a plate that
    /// looks larger is a plate closer, which the per-separation corrections absorb). Reported
    /// as their RMS `rms_in` and each LED's `dx@bID`, `dy@bID`.
    LedPosition,
    /// `led_tilt`: one boresight tilt vector (tx, ty) per LED, deg, the same at every
    /// separation, turned on top of the plate's ([`crate::sim::led_emulator`]). A tilt common
    /// to every LED is `beacon_tilt`'s, so their mean is held at zero. Reported as their RMS
    /// `rms_deg` and each LED's `tx_deg@bID`, `ty_deg@bID`.
    LedTilt,
    /// `array_pose`: one rigid pose (dx, dy in, dtheta deg) per array on the plate, the same
    /// at every separation (the quad layout's arrays placed by hand, [`super::arrays`]).
    /// Needs two or more arrays (beacon ids `100 a + LED`). Gauge: the arrays' mean dx, dy
    /// and dtheta held at zero (their common part is the head's d1, d2, p3). Reported as
    /// `rms_in`, `rms_deg` and each array's `dx@aN`, `dy@aN`, `dtheta_deg@aN`.
    ArrayPose,
}

/// Every candidate, in the order they are tried.
pub const ALL: [Cand; 15] = [
    Cand::Proximity,
    Cand::Intensity,
    Cand::BeaconPattern,
    Cand::BeaconTilt,
    Cand::CellGain,
    Cand::CellBias,
    Cand::Ambient,
    Cand::FaceAngle,
    Cand::Saturation,
    Cand::PlateOffset,
    Cand::SeparationError,
    Cand::PlateTilt,
    Cand::LedPosition,
    Cand::LedTilt,
    Cand::ArrayPose,
];

/// A name in a candidate list that is no analysis candidate.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CandidateError {
    /// An effect the simulator has but the analysis does not fit.
    #[error("`{name}` is simulation-only, not an analysis candidate")]
    SimulationOnly {
        /// The name given.
        name: String,
    },
    /// No effect of the vocabulary.
    #[error(
        "unknown candidate `{name}`; known: {}",
        ALL.map(|c| c.name()).join(", ")
    )]
    Unknown {
        /// The name given.
        name: String,
    },
}

/// The candidates of a comma-separated list of vocabulary names (`cell_gain,face_angle`;
/// empty entries ignored).
pub fn parse_candidates(s: &str) -> Result<Vec<Cand>, CandidateError> {
    s.split(',')
        .map(str::trim)
        .filter(|p| !p.is_empty())
        .map(|n| {
            Cand::from_name(n).ok_or_else(|| {
                if n == "crosstalk" {
                    CandidateError::SimulationOnly { name: n.into() }
                } else {
                    CandidateError::Unknown { name: n.into() }
                }
            })
        })
        .collect()
}

impl Cand {
    /// The vocabulary name.
    pub fn name(self) -> &'static str {
        match self {
            Cand::Proximity => "proximity",
            Cand::Intensity => "intensity",
            Cand::BeaconPattern => "beacon_pattern",
            Cand::BeaconTilt => "beacon_tilt",
            Cand::CellGain => "cell_gain",
            Cand::CellBias => "cell_bias",
            Cand::Ambient => "ambient",
            Cand::FaceAngle => "face_angle",
            Cand::Saturation => "saturation",
            Cand::PlateOffset => "plate_offset",
            Cand::SeparationError => "separation_error",
            Cand::PlateTilt => "plate_tilt",
            Cand::LedPosition => "led_position",
            Cand::LedTilt => "led_tilt",
            Cand::ArrayPose => "array_pose",
        }
    }

    /// From a vocabulary name.
    pub fn from_name(s: &str) -> Option<Cand> {
        ALL.iter().copied().find(|c| c.name() == s)
    }

    /// Whether this is a candidate on top of `base` (intensity is part of `thesis`).
    pub fn available(self, base: Base) -> bool {
        !(base == Base::Thesis && self == Cand::Intensity)
    }

    /// Names of the global (not per-separation) parameters.
    pub fn global_names(self, base: Base) -> &'static [&'static str] {
        match self {
            Cand::Proximity => &["S"],
            Cand::Intensity => &[],
            Cand::BeaconPattern => &["m"],
            Cand::BeaconTilt => &["tx_deg", "ty_deg"],
            Cand::CellGain => &["GX", "GY"],
            Cand::CellBias => &["BX", "BY"],
            Cand::Ambient => &["B"],
            Cand::FaceAngle if base == Base::Pinhole => &["DY"],
            Cand::FaceAngle => &["DX", "DY"],
            Cand::Saturation => &["lnS"],
            Cand::PlateOffset
            | Cand::SeparationError
            | Cand::PlateTilt
            | Cand::LedPosition
            | Cand::LedTilt
            | Cand::ArrayPose => &[],
        }
    }

    /// Names of the per-LED parameters (one block per LED, among the global parameters: an
    /// LED is the same at every separation).
    pub fn led_names(self) -> &'static [&'static str] {
        match self {
            Cand::LedPosition => &["dx", "dy"],
            Cand::LedTilt => &["tx_deg", "ty_deg"],
            _ => &[],
        }
    }

    /// Names of the per-array parameters (one block per array, among the global parameters,
    /// after any per-LED ones).
    pub fn array_names(self) -> &'static [&'static str] {
        match self {
            Cand::ArrayPose => &["dx", "dy", "dtheta_deg"],
            _ => &[],
        }
    }

    /// Where the per-LED parameters sit in an LED's values (dx, dy, tx_deg, ty_deg).
    fn led_slot(self) -> usize {
        match self {
            Cand::LedTilt => 2,
            _ => 0,
        }
    }

    /// Finite-difference step of the per-LED parameters.
    fn led_step(self) -> f64 {
        match self {
            Cand::LedTilt => 1e-3,
            _ => 1e-6,
        }
    }

    /// Names of the per-separation parameters (one block per separation).
    pub fn local_names(self) -> &'static [&'static str] {
        match self {
            Cand::PlateOffset => &["x", "y"],
            Cand::SeparationError => &["z"],
            Cand::PlateTilt => &["tx_deg", "ty_deg"],
            _ => &[],
        }
    }

    /// Name of the summary of the per-separation values (their RMS), with its unit.
    pub fn local_rms_name(self) -> &'static str {
        match self {
            Cand::PlateTilt => "rms_deg",
            _ => "rms_in",
        }
    }

    /// Finite-difference step of the per-separation parameters.
    fn local_step(self) -> f64 {
        match self {
            Cand::PlateTilt => 1e-5,
            _ => 1e-6,
        }
    }

    /// Starting values of the global parameters (the nominal, "effect absent" values, or
    /// the nominal physics for proximity and the beacon pattern).
    fn start(self, base: Base) -> Vec<f64> {
        match self {
            Cand::Proximity => vec![0.175],
            Cand::BeaconPattern => vec![1.0],
            Cand::Saturation => vec![0.0],
            _ => vec![0.0; self.global_names(base).len()],
        }
    }

    /// Values of the global parameters at which the effect is absent (the starting model's
    /// physics).
    pub fn absent(self, base: Base) -> Vec<f64> {
        match (self, base) {
            (Cand::Proximity, Base::Thesis) => vec![0.175],
            (Cand::BeaconPattern, Base::Thesis) => vec![1.0],
            (Cand::Saturation, _) => vec![1e30f64.ln()],
            _ => vec![0.0; self.global_names(base).len()],
        }
    }

    /// Finite-difference steps of the global parameters.
    fn steps(self, base: Base) -> Vec<f64> {
        let n = self.global_names(base).len();
        let h = match self {
            Cand::Proximity => 1e-6,
            Cand::BeaconPattern => 1e-6,
            Cand::BeaconTilt => 1e-5,
            Cand::CellGain => 1e-7,
            Cand::CellBias | Cand::Ambient => 1e-10,
            Cand::FaceAngle => 1e-5,
            Cand::Saturation => 1e-6,
            _ => 1e-6,
        };
        vec![h; n]
    }

    /// The reported parameters (physical names and values) from the fitted ones.
    pub fn report(self, base: Base, v: &[f64]) -> Vec<(&'static str, f64)> {
        match self {
            Cand::BeaconPattern => {
                let m = v[0];
                // m <= 0: no half-intensity angle (the pattern does not fall off the axis);
                // NaN, which the text prints as "none" and JSON as null.
                let h = if m > 0.0 {
                    deg((0.5f64.powf(1.0 / m)).acos())
                } else {
                    f64::NAN
                };
                vec![("H_deg", h), ("m", m)]
            }
            Cand::BeaconTilt => vec![
                ("T_deg", v[0].hypot(v[1])),
                ("AZ_deg", deg(v[1].atan2(v[0]))),
            ],
            Cand::Saturation => vec![("S", v[0].exp())],
            Cand::LedPosition => vec![("rms_in", rms(v))],
            Cand::LedTilt => vec![("rms_deg", rms(v))],
            Cand::ArrayPose => {
                let (mut sh, mut tu) = (Vec::new(), Vec::new());
                for p in v.chunks(3) {
                    sh.extend(&p[..2]);
                    tu.push(p[2]);
                }
                vec![("rms_in", rms(&sh)), ("rms_deg", rms(&tu))]
            }
            _ => self
                .global_names(base)
                .iter()
                .copied()
                .zip(v.iter().copied())
                .collect(),
        }
    }

    /// The parameters of a candidate as shown for every trial, in particular a rejected one:
    /// (name, value, value at which the effect is absent). Unlike [`Cand::report`] these stay
    /// smooth through the no-effect value, so an estimate +/- 1-sigma there is meaningful:
    /// `beacon_tilt` as the tilt vector (`tx_deg`, `ty_deg`; T and AZ are degenerate at zero
    /// tilt), `beacon_pattern` from `pinhole` as `m` (the half-angle is flat at m = 0).
    /// `saturation` has no finite no-effect value (None): any level above the brightest
    /// signal is no saturation.
    pub fn trial_report(self, base: Base, v: &[f64]) -> Vec<(&'static str, f64, Option<f64>)> {
        let absent = self.absent(base);
        match (self, base) {
            (Cand::BeaconPattern, Base::Thesis) if v[0] > 0.0 => {
                let h = self.report(base, v)[0].1;
                vec![("H_deg", h, Some(60.0))]
            }
            (Cand::Saturation, _) => vec![("S", v[0].exp(), None)],
            // Only the per-LED values (their weighted RMS against noise alone, as for the
            // per-separation ones): the RMS of noise-only estimates is no estimate near 0.
            (Cand::LedPosition | Cand::LedTilt | Cand::ArrayPose, _) => Vec::new(),
            _ => self
                .global_names(base)
                .iter()
                .zip(v)
                .zip(absent)
                .map(|((n, &x), a)| (*n, x, Some(a)))
                .collect(),
        }
    }
}

/// Root mean square of `v` (0 when empty).
fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// An LED of the data: its beacon id and nominal place on the plate (x, y), in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Led {
    /// Beacon id.
    pub id: u32,
    /// Nominal (recorded) x, y, in.
    pub xy: [f64; 2],
}

/// A starting model plus effects, for a dataset with `nsep` separations.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// Starting model.
    pub base: Base,
    /// Effects added, in order.
    pub effects: Vec<Cand>,
    /// Separations in the dataset (sizes the per-separation blocks).
    pub nsep: usize,
    /// Each separation's plate tilt (tx, ty) as the corner readings measured it, deg
    /// ([`Data::measured_tilts_deg`]): where the plate is placed before any `plate_tilt`
    /// (which is then the tilt beyond the corners'). Empty: level plates.
    pub measured_tilts_deg: Vec<[f64; 2]>,
    /// The LEDs of the data, by beacon id ascending ([`Model::leds_of`]); empty when a point
    /// has no beacon id (per-LED candidates cannot be tried).
    pub leds: Vec<Led>,
    /// The arrays on the plate ([`super::arrays::arrays_of`]); empty with one.
    pub arrays: Vec<Array>,
}

/// Where a model's parameters sit in its vector.
#[derive(Debug, Clone, Copy)]
struct Slot {
    start: usize,
    len: usize,
}

impl Model {
    /// The starting model alone.
    pub fn new(base: Base, nsep: usize) -> Self {
        Model {
            base,
            effects: Vec::new(),
            nsep,
            measured_tilts_deg: Vec::new(),
            leds: Vec::new(),
            arrays: Vec::new(),
        }
    }

    /// The starting model alone for `data`: its separations, its plates placed as their
    /// corner readings measured them.
    pub fn for_data(base: Base, data: &Data) -> Self {
        let leds = Model::leds_of(data);
        Model {
            measured_tilts_deg: data.measured_tilts_deg.clone(),
            arrays: arrays_of(&leds),
            leds,
            ..Model::new(base, data.seps.len())
        }
    }

    /// This model with its effects replaced by `effects` (the same base and plates).
    pub fn with_effects(&self, effects: Vec<Cand>) -> Model {
        Model {
            effects,
            ..self.clone()
        }
    }

    /// This model with one more effect.
    pub fn with(&self, c: Cand) -> Model {
        let mut m = self.clone();
        m.effects.push(c);
        m
    }

    fn n_base(&self) -> usize {
        self.base.names().len()
    }

    /// The LEDs of `data` by beacon id: empty unless every point names its beacon. An LED's
    /// nominal place is its first point's recorded (x, y).
    pub fn leds_of(data: &Data) -> Vec<Led> {
        if data.points.iter().any(|p| p.beacon.is_none()) {
            return Vec::new();
        }
        let mut leds: Vec<Led> = Vec::new();
        for p in &data.points {
            let id = p.beacon.unwrap_or(0);
            if let Err(k) = leds.binary_search_by_key(&id, |l| l.id) {
                leds.insert(
                    k,
                    Led {
                        id,
                        xy: [p.r.x, p.r.y],
                    },
                );
            }
        }
        leds
    }

    /// Number of global parameters of effect `c`: its own plus its per-LED and per-array
    /// blocks.
    fn global_len(&self, c: Cand) -> usize {
        c.global_names(self.base).len()
            + c.led_names().len() * self.leds.len()
            + c.array_names().len() * self.arrays.len()
    }

    fn global_slot(&self, c: Cand) -> Option<Slot> {
        let mut at = self.n_base();
        for &e in &self.effects {
            let len = self.global_len(e);
            if e == c {
                return Some(Slot { start: at, len });
            }
            at += len;
        }
        None
    }

    fn n_global(&self) -> usize {
        self.n_base()
            + self
                .effects
                .iter()
                .map(|&e| self.global_len(e))
                .sum::<usize>()
    }

    /// The LED (index into [`Model::leds`]) and slot in its values (0: dx, 1: dy, 2: tx_deg,
    /// 3: ty_deg) parameter `i` is, if it is a per-LED one.
    pub fn led_param(&self, i: usize) -> Option<(usize, usize)> {
        let mut at = self.n_base();
        for &e in &self.effects {
            let own = e.global_names(self.base).len();
            let w = e.led_names().len();
            if i >= at + own && i < at + own + w * self.leds.len() && w > 0 {
                let j = i - at - own;
                return Some((j / w, j % w + e.led_slot()));
            }
            at += self.global_len(e);
        }
        None
    }

    /// The array (index into [`Model::arrays`]) parameter `i` is a pose parameter of, if it
    /// is one.
    pub fn array_param(&self, i: usize) -> Option<usize> {
        let s = self.global_slot(Cand::ArrayPose)?;
        (i >= s.start && i < s.start + s.len).then(|| (i - s.start) / 3)
    }

    /// The index into [`Model::leds`] of beacon `id`.
    pub fn led_index(&self, id: Option<u32>) -> Option<usize> {
        self.leds.binary_search_by_key(&id?, |l| l.id).ok()
    }

    /// The gauge of `led_position` (see [`Cand::LedPosition`]): the coefficient lists whose
    /// weighted sums of the per-LED offsets are held at zero: the mean dx, the mean dy, the
    /// mean turn `(x dy - y dx) / rho` about the plate's centre and, with `separation_error`
    /// in the model, the mean stretch `(x dx + y dy) / rho` (`rho` the LEDs' RMS distance from
    /// the centre, so every row is a mean in inches). Empty without `led_position`.
    pub fn led_gauge(&self) -> Vec<Vec<(usize, f64)>> {
        let n = self.leds.len();
        let nf = n as f64;
        let mut rows = Vec::new();
        if let Some(s) = self.global_slot(Cand::ArrayPose) {
            rows.extend(super::arrays::gauge(s.start, self.arrays.len()));
        }
        // `led_tilt`: the mean tilt is `beacon_tilt`'s.
        if let (Some(s), true) = (self.global_slot(Cand::LedTilt), n > 0) {
            for c in 0..2 {
                rows.push((0..n).map(|k| (s.start + 2 * k + c, 1.0 / nf)).collect());
            }
        }
        let Some(s) = self.global_slot(Cand::LedPosition) else {
            return rows;
        };
        if n == 0 {
            return rows;
        }
        let rho = (self
            .leds
            .iter()
            .map(|l| l.xy[0] * l.xy[0] + l.xy[1] * l.xy[1])
            .sum::<f64>()
            / nf)
            .sqrt()
            .max(1e-9);
        let (dx, dy) = (|k: usize| s.start + 2 * k, |k: usize| s.start + 2 * k + 1);
        // With `array_pose` each array's shift and turn are its pose's: the offsets' mean and
        // mean turn are held per array, about its centre.
        let groups: Vec<([f64; 2], Vec<usize>)> = if self.effects.contains(&Cand::ArrayPose) {
            self.arrays
                .iter()
                .map(|a| {
                    let ks = (0..n)
                        .filter(|&k| self.leds[k].id / super::arrays::IDS_PER_ARRAY == a.id)
                        .collect();
                    (a.centre, ks)
                })
                .collect()
        } else {
            vec![([0.0; 2], (0..n).collect())]
        };
        for (c, ks) in groups.iter().filter(|g| !g.1.is_empty()) {
            let m = ks.len() as f64;
            let (u, v) = (
                |k: usize| self.leds[k].xy[0] - c[0],
                |k: usize| self.leds[k].xy[1] - c[1],
            );
            let r = (ks.iter().map(|&k| u(k) * u(k) + v(k) * v(k)).sum::<f64>() / m)
                .sqrt()
                .max(1e-9);
            rows.extend([
                ks.iter().map(|&k| (dx(k), 1.0 / m)).collect::<Vec<_>>(),
                ks.iter().map(|&k| (dy(k), 1.0 / m)).collect(),
                ks.iter()
                    .flat_map(|&k| [(dx(k), -v(k) / (m * r)), (dy(k), u(k) / (m * r))])
                    .collect(),
            ]);
        }
        if self.effects.contains(&Cand::SeparationError) {
            rows.push(
                self.leds
                    .iter()
                    .enumerate()
                    .flat_map(|(k, l)| {
                        [(dx(k), l.xy[0] / (nf * rho)), (dy(k), l.xy[1] / (nf * rho))]
                    })
                    .collect(),
            );
        }
        rows
    }

    /// Per-separation block of effect `c`: start of separation 0's parameters and the block
    /// width.
    fn local_slot(&self, c: Cand) -> Option<Slot> {
        let mut at = self.n_global();
        for &e in &self.effects {
            let w = e.local_names().len();
            if w == 0 {
                continue;
            }
            if e == c {
                return Some(Slot { start: at, len: w });
            }
            at += w * self.nsep;
        }
        None
    }

    /// Whether the mean over the separations of each of effect `c`'s per-separation
    /// parameters is held at zero in this model: always for `plate_offset` (a common lateral
    /// offset is the head offset d1, d2) and `separation_error` (a common error is d3);
    /// for `plate_tilt` when `plate_offset` is in the model too (a common tilt is then a head
    /// rotation plus offsets, see [`Cand::PlateTilt`]). False for global effects.
    pub fn zero_mean(&self, c: Cand) -> bool {
        match c {
            Cand::PlateOffset | Cand::SeparationError => true,
            Cand::PlateTilt => self.effects.contains(&Cand::PlateOffset),
            _ => false,
        }
    }

    /// Number of zero-mean constraints (one per per-separation parameter held at zero mean).
    pub fn n_constraints(&self) -> usize {
        self.effects
            .iter()
            .filter(|&&e| self.zero_mean(e))
            .map(|e| e.local_names().len())
            .sum::<usize>()
            + self.led_gauge().len()
    }

    /// Total number of parameters.
    pub fn n_params(&self) -> usize {
        self.n_global()
            + self
                .effects
                .iter()
                .map(|e| e.local_names().len() * self.nsep)
                .sum::<usize>()
    }

    /// Number of global parameters (the rest are per separation).
    pub fn n_global_params(&self) -> usize {
        self.n_global()
    }

    /// Parameter names (per-separation ones as `x@k`, k the separation index).
    pub fn names(&self, seps: &[f64]) -> Vec<String> {
        let mut v: Vec<String> = self.base.names().iter().map(|s| s.to_string()).collect();
        for &e in &self.effects {
            for n in e.global_names(self.base) {
                v.push(format!("{}.{n}", e.name()));
            }
            for l in self.leds.iter().filter(|_| !e.led_names().is_empty()) {
                for n in e.led_names() {
                    v.push(format!("{}.{n}@b{}", e.name(), l.id));
                }
            }
            for a in self.arrays.iter().filter(|_| !e.array_names().is_empty()) {
                for n in e.array_names() {
                    v.push(format!("{}.{n}@a{}", e.name(), a.id));
                }
            }
        }
        for &e in &self.effects {
            for sep in &seps[..self.nsep] {
                for n in e.local_names() {
                    v.push(format!("{}.{n}@{}in", e.name(), sep));
                }
            }
        }
        v
    }

    /// The fitted values of effect `c`'s global parameters.
    pub fn global_values<'a>(&self, c: Cand, x: &'a [f64]) -> &'a [f64] {
        match self.global_slot(c) {
            Some(s) => &x[s.start..s.start + s.len],
            None => &[],
        }
    }

    /// Indices of effect `c`'s global parameters.
    pub fn global_indices(&self, c: Cand) -> std::ops::Range<usize> {
        match self.global_slot(c) {
            Some(s) => s.start..s.start + s.len,
            None => 0..0,
        }
    }

    /// Indices of effect `c`'s parameters for separation `k` (empty for global effects).
    pub fn local_indices(&self, c: Cand, k: usize) -> std::ops::Range<usize> {
        match self.local_slot(c) {
            Some(s) => {
                let a = s.start + k * s.len;
                a..a + s.len
            }
            None => 0..0,
        }
    }

    /// Indices of every per-separation parameter of separation `k`.
    pub fn locals_of_sep(&self, k: usize) -> Vec<usize> {
        self.effects
            .iter()
            .flat_map(|&e| self.local_indices(e, k))
            .collect()
    }

    /// Finite-difference step of every parameter.
    pub fn steps(&self) -> Vec<f64> {
        let mut v = vec![1e-6, 1e-6, 1e-6, 1e-8, 1e-8, 1e-8];
        if self.base == Base::Pinhole {
            v.push(1e-3);
        }
        for &e in &self.effects {
            v.extend(e.steps(self.base));
            v.extend(std::iter::repeat_n(
                e.led_step(),
                e.led_names().len() * self.leds.len(),
            ));
            for _ in self.arrays.iter().filter(|_| !e.array_names().is_empty()) {
                v.extend([1e-6, 1e-6, 1e-5]);
            }
        }
        // The per-separation blocks, in their layout order (see `local_slot`).
        for &e in &self.effects {
            let w = e.local_names().len();
            v.extend(std::iter::repeat_n(e.local_step(), w * self.nsep));
        }
        debug_assert_eq!(v.len(), self.n_params());
        v
    }

    /// Starting parameters: `prev` (a fit of `prev_model`, a sub-model of this one) carried
    /// over, new effects at their start values, per-separation corrections at zero.
    pub fn start_from(&self, prev_model: &Model, prev: &[f64]) -> DVector<f64> {
        let mut x = DVector::zeros(self.n_params());
        let nb = self.n_base();
        x.as_mut_slice()[..nb].copy_from_slice(&prev[..nb.min(prev_model.n_base())]);
        for &e in &self.effects {
            let dst = self.global_indices(e);
            let src = prev_model.global_indices(e);
            if prev_model.effects.contains(&e) {
                x.as_mut_slice()[dst].copy_from_slice(&prev[src]);
            } else {
                x.as_mut_slice()[dst].copy_from_slice(&self.start_values(e));
            }
            for k in 0..self.nsep {
                let dst = self.local_indices(e, k);
                if prev_model.effects.contains(&e) {
                    let src = prev_model.local_indices(e, k);
                    x.as_mut_slice()[dst].copy_from_slice(&prev[src]);
                }
            }
        }
        x
    }

    /// Starting values of effect `c`'s global parameters: [`Cand::start`], each LED on its
    /// place.
    fn start_values(&self, c: Cand) -> Vec<f64> {
        let mut v = c.start(self.base);
        v.resize(self.global_len(c), 0.0);
        v
    }

    /// Values of effect `c`'s global parameters at which it is absent: [`Cand::absent`],
    /// each LED on its place.
    pub fn absent_values(&self, c: Cand) -> Vec<f64> {
        let mut v = c.absent(self.base);
        v.resize(self.global_len(c), 0.0);
        v
    }

    /// The emulator of the global parameters in `x`.
    pub fn emulator(&self, x: &[f64]) -> Emulator<f64> {
        let mut head = Head::northstar();
        let mut fx = match self.base {
            Base::Thesis => Effects::default(),
            Base::Pinhole => Effects::far_field(),
        };
        if self.base == Base::Pinhole {
            let a = (x[6] / BETA).atan();
            head.alpha_x = a;
            head.alpha_y = a;
        }
        for &e in &self.effects {
            let v = self.global_values(e, x);
            match e {
                Cand::Proximity => {
                    fx.proximity = true;
                    head.s = v[0];
                }
                Cand::Intensity => fx.intensity = true,
                Cand::BeaconPattern => fx.pattern = Pattern::Lambertian { m: v[0] },
                Cand::BeaconTilt => {
                    let (tx, ty) = (rad(v[0]), rad(v[1]));
                    fx.tilt = tx.hypot(ty);
                    fx.tilt_az = ty.atan2(tx);
                }
                Cand::CellGain => {
                    fx.gain[0] = 1.0 + v[0];
                    fx.gain[2] = 1.0 + v[1];
                }
                Cand::CellBias => {
                    fx.bias[0] += v[0];
                    fx.bias[2] += v[1];
                }
                Cand::Ambient => fx.bias.iter_mut().for_each(|b| *b += v[0]),
                Cand::FaceAngle => match self.base {
                    Base::Thesis => {
                        head.alpha_x = rad(30.0 + v[0]);
                        head.alpha_y = rad(30.0 + v[1]);
                    }
                    Base::Pinhole => head.alpha_y = head.alpha_x + rad(v[0]),
                },
                Cand::Saturation => fx.saturation = Some(v[0].exp()),
                Cand::PlateOffset
                | Cand::SeparationError
                | Cand::PlateTilt
                | Cand::LedPosition
                | Cand::LedTilt
                | Cand::ArrayPose => {}
            }
        }
        let pose = cta_core::emulator::Pose {
            d: Vector3::new(x[0], x[1], x[2]),
            p: Vector3::new(x[3], x[4], x[5]),
        };
        Emulator::new(head, pose, fx)
    }

    /// Where the plate of separation `k` truly is by the per-separation parameters in `x`
    /// (plate offset, separation error, plate tilt on top of the corners' tilt; none of them
    /// in the model: the recorded place, turned by the corners' tilt).
    pub fn placement(&self, x: &[f64], k: usize) -> Placement {
        let mut pl = Placement {
            tilt_deg: self.measured_tilts_deg.get(k).copied().unwrap_or_default(),
            ..Placement::default()
        };
        for &e in &self.effects {
            let r = self.local_indices(e, k);
            match e {
                Cand::PlateOffset => pl.offset = [x[r.start], x[r.start + 1]],
                Cand::SeparationError => pl.sep_error = x[r.start],
                Cand::PlateTilt => {
                    pl.tilt_deg = [pl.tilt_deg[0] + x[r.start], pl.tilt_deg[1] + x[r.start + 1]]
                }
                _ => {}
            }
        }
        pl
    }

    /// The model at `x`, separation by separation: each separation's plate placement and
    /// emulator (the LEDs' boresights turn with a tilted plate).
    pub fn view(&self, x: &[f64]) -> View {
        let em = self.emulator(x);
        let places: Vec<Placement> = (0..self.nsep).map(|k| self.placement(x, k)).collect();
        let ems = places.iter().map(|pl| pl.emulator(&em)).collect();
        View {
            ems,
            places,
            leds: self.led_values(x),
        }
    }

    /// Each LED's values by `x` (beacon id, (dx, dy, tx_deg, ty_deg)), by id ascending; empty
    /// without per-LED effects.
    /// The offset (dx, dy) is the LED's own (`led_position`) moved with its array
    /// (`array_pose`, [`super::arrays::displacement`]).
    pub fn led_values(&self, x: &[f64]) -> Vec<(u32, [f64; 4])> {
        let (p, t, a) = (
            self.global_values(Cand::LedPosition, x),
            self.global_values(Cand::LedTilt, x),
            self.global_values(Cand::ArrayPose, x),
        );
        if p.is_empty() && t.is_empty() && a.is_empty() {
            return Vec::new();
        }
        let at = |v: &[f64], i: usize| v.get(i).copied().unwrap_or(0.0);
        self.leds
            .iter()
            .enumerate()
            .map(|(k, l)| {
                let j = 2 * k;
                let mut d = [at(p, j), at(p, j + 1)];
                let arr = self
                    .arrays
                    .iter()
                    .position(|r| r.id == l.id / super::arrays::IDS_PER_ARRAY);
                if let (Some(q), false) = (arr, a.is_empty()) {
                    let pose = [a[3 * q], a[3 * q + 1], a[3 * q + 2]];
                    let (xr, yr) = (l.xy[0] + d[0], l.xy[1] + d[1]);
                    let m = displacement(self.arrays[q].centre, pose, xr, yr);
                    d = [d[0] + m[0], d[1] + m[1]];
                }
                (l.id, [d[0], d[1], at(t, j), at(t, j + 1)])
            })
            .collect()
    }

    /// Predicted (X, Y) of every point in `subset`.
    pub fn predict(
        &self,
        x: &[f64],
        data: &Data,
        subset: &[usize],
    ) -> Result<Vec<[f64; 2]>, ModelError> {
        let v = self.view(x);
        subset
            .iter()
            .map(|&i| {
                v.output(&data.points[i])
                    .filter(|o| o[0].is_finite() && o[1].is_finite())
                    .ok_or(ModelError::NonFinite)
            })
            .collect()
    }
}

/// A model evaluated at one parameter vector (see [`Model::view`]).
pub struct View {
    ems: Vec<Emulator<f64>>,
    places: Vec<Placement>,
    leds: Vec<(u32, [f64; 4])>,
}

impl View {
    /// The true beacon position (N, in) of point `p` by the model: its recorded place moved
    /// by its LED's offset on the plate (`led_position`), then placed with the plate.
    pub fn beacon(&self, p: &PointMean) -> Vector3<f64> {
        let v = self.led_vals(p);
        self.places[p.sep].beacon(&(p.r + Vector3::new(v[0], v[1], 0.0)))
    }

    /// Point `p`'s LED's values: in-plane offset (dx, dy) on the plate and its boresight's
    /// own tilt (tx_deg, ty_deg); zero without per-LED effects.
    pub fn led_vals(&self, p: &PointMean) -> [f64; 4] {
        p.beacon
            .and_then(|id| self.leds.binary_search_by_key(&id, |l| l.0).ok())
            .map_or([0.0; 4], |k| self.leds[k].1)
    }

    /// The model's output for point `p` were its LED's values `v` ([`View::led_vals`]).
    pub fn output_with(&self, p: &PointMean, v: [f64; 4]) -> Option<[f64; 2]> {
        let r = self.places[p.sep].beacon(&(p.r + Vector3::new(v[0], v[1], 0.0)));
        crate::sim::led_emulator(&self.ems[p.sep], [v[2], v[3]]).output(&r)
    }

    /// The emulator of separation `k`.
    pub fn emulator(&self, k: usize) -> &Emulator<f64> {
        &self.ems[k]
    }

    /// The model's output for point `p`.
    pub fn output(&self, p: &PointMean) -> Option<[f64; 2]> {
        self.output_with(p, self.led_vals(p))
    }
}

/// A fit of (some of) a model's parameters to (some of) the points, as a GLSDC problem.
pub struct FitProblem<'a> {
    /// The model.
    pub model: &'a Model,
    /// The data.
    pub data: &'a Data,
    /// Points used.
    pub subset: &'a [usize],
    /// The full parameter vector; the free entries are replaced by the solver's.
    pub fixed: &'a [f64],
    /// Indices of the free parameters.
    pub free: &'a [usize],
    /// Constraints (pseudo-observations): each a list of (parameter index, coefficient)
    /// whose weighted sum is held at zero (a zero mean: every coefficient 1/n).
    pub constraints: &'a [Vec<(usize, f64)>],
    /// Parameter names (for rank-deficiency messages).
    pub names: &'a [String],
}

/// Weight of a zero-mean pseudo-observation (1-sigma 1e-5 in): it only pins a direction the
/// data leaves free, so it is satisfied exactly and adds nothing to chi-square.
const CONSTRAINT_WEIGHT: f64 = 1e10;

impl FitProblem<'_> {
    fn full(&self, xf: &DVector<f64>) -> Vec<f64> {
        let mut x = self.fixed.to_vec();
        for (j, &i) in self.free.iter().enumerate() {
            x[i] = xf[j];
        }
        x
    }
}

impl Problem<f64> for FitProblem<'_> {
    type D = Dyn;
    fn dim(&self) -> Dyn {
        Dyn(self.free.len())
    }
    fn n_rows(&self) -> usize {
        2 * self.subset.len() + self.constraints.len()
    }
    fn rows(
        &self,
        xf: &DVector<f64>,
        jac: bool,
        sink: &mut dyn FnMut(f64, f64, &[f64]),
    ) -> Result<(), ModelError> {
        let x = self.full(xf);
        let m = self.model;
        let data = self.data;
        let y0 = m.predict(&x, data, self.subset)?;
        let nf = self.free.len();
        if !jac {
            for (j, &i) in self.subset.iter().enumerate() {
                let p = &data.points[i];
                sink(p.y[0] - y0[j][0], p.w[0], &[]);
                sink(p.y[1] - y0[j][1], p.w[1], &[]);
            }
        } else {
            let steps = m.steps();
            // Jacobian, row-major: point j, axis a, parameter f.
            let mut jm = vec![0.0; self.subset.len() * 2 * nf];
            let n_global = m.n_global_params();
            // The model at x: the LEDs' offsets, and what a per-LED step moves.
            let v0 = m.view(&x);
            for (f, &i) in self.free.iter().enumerate() {
                let h = steps[i];
                let mut xp = x.clone();
                xp[i] += h;
                if let Some((k, c)) = m.led_param(i) {
                    // A per-LED parameter: only its LED's points move, and nothing else.
                    let id = m.leds[k].id;
                    for (j, &pi) in self.subset.iter().enumerate() {
                        let p = &data.points[pi];
                        if p.beacon != Some(id) {
                            continue;
                        }
                        let mut v = v0.led_vals(p);
                        v[c] += h;
                        let yp = v0.output_with(p, v).ok_or(ModelError::NonFinite)?;
                        for a in 0..2 {
                            jm[(j * 2 + a) * nf + f] = (yp[a] - y0[j][a]) / h;
                        }
                    }
                } else if let Some(q) = m.array_param(i) {
                    // An array's pose: only its LEDs' points move.
                    let vp = m.led_values(&xp);
                    let id = m.arrays[q].id;
                    for (j, &pi) in self.subset.iter().enumerate() {
                        let p = &data.points[pi];
                        let Some(k) = m.led_index(p.beacon) else {
                            continue;
                        };
                        if m.leds[k].id / super::arrays::IDS_PER_ARRAY != id {
                            continue;
                        }
                        let yp = v0.output_with(p, vp[k].1).ok_or(ModelError::NonFinite)?;
                        for a in 0..2 {
                            jm[(j * 2 + a) * nf + f] = (yp[a] - y0[j][a]) / h;
                        }
                    }
                } else if i < n_global {
                    let yp = m.predict(&xp, data, self.subset)?;
                    for j in 0..self.subset.len() {
                        for a in 0..2 {
                            jm[(j * 2 + a) * nf + f] = (yp[j][a] - y0[j][a]) / h;
                        }
                    }
                } else {
                    // A per-separation parameter: only its separation's points move.
                    let sep = (0..m.nsep)
                        .find(|&k| m.locals_of_sep(k).contains(&i))
                        .unwrap_or(0);
                    let place = m.placement(&xp, sep);
                    let em = place.emulator(&m.emulator(&xp));
                    for (j, &pi) in self.subset.iter().enumerate() {
                        let p = &data.points[pi];
                        if p.sep != sep {
                            continue;
                        }
                        let v = v0.led_vals(p);
                        let r = place.beacon(&(p.r + Vector3::new(v[0], v[1], 0.0)));
                        let yp = crate::sim::led_emulator(&em, [v[2], v[3]])
                            .output(&r)
                            .ok_or(ModelError::NonFinite)?;
                        for a in 0..2 {
                            jm[(j * 2 + a) * nf + f] = (yp[a] - y0[j][a]) / h;
                        }
                    }
                }
            }
            for (j, &i) in self.subset.iter().enumerate() {
                let p = &data.points[i];
                for a in 0..2 {
                    let row = &jm[(j * 2 + a) * nf..(j * 2 + a + 1) * nf];
                    if row.iter().any(|v| !v.is_finite()) {
                        return Err(ModelError::NonFinite);
                    }
                    sink(p.y[a] - y0[j][a], p.w[a], row);
                }
            }
        }
        let mut row = vec![0.0; if jac { nf } else { 0 }];
        for c in self.constraints {
            let sum: f64 = c.iter().map(|&(i, w)| w * x[i]).sum();
            if jac {
                row.iter_mut().for_each(|v| *v = 0.0);
                for &(i, w) in c {
                    if let Some(f) = self.free.iter().position(|&j| j == i) {
                        row[f] = w;
                    }
                }
            }
            sink(-sum, CONSTRAINT_WEIGHT, &row);
        }
        Ok(())
    }
    fn param_name(&self, i: usize, w: &mut dyn core::fmt::Write) -> core::fmt::Result {
        w.write_str(&self.names[self.free[i]])
    }
}

/// A converged fit.
#[derive(Debug, Clone)]
pub struct FitResult {
    /// Full parameter vector.
    pub x: Vec<f64>,
    /// 1-sigma of every parameter (0 for parameters held fixed).
    pub sigma: Vec<f64>,
    /// Covariance of the free parameters (absolute weights: not rescaled).
    pub cov: DMatrix<f64>,
    /// Indices of the free parameters (rows of `cov`).
    pub free: Vec<usize>,
    /// Weighted sum of squared residuals of the data rows.
    pub chi2: f64,
    /// Unweighted sum of squared residuals of the data rows.
    pub ss: f64,
    /// Data rows.
    pub m: usize,
}

impl FitResult {
    /// Degrees of freedom: data rows minus free parameters plus constraints.
    pub fn dof(&self, n_constraints: usize) -> f64 {
        (self.m as f64 - self.free.len() as f64 + n_constraints as f64).max(1.0)
    }
}

/// Why a fit failed, in words (names the unconstrained parameter combination).
#[derive(Debug, Clone, thiserror::Error)]
#[error("{0}")]
pub struct FitFailure(pub String);

/// Solver settings for the analysis: absolute weights, tolerances suited to
/// finite-difference Jacobians.
pub fn settings() -> Settings<f64> {
    Settings {
        max_iter: 40,
        step_tol: 1e-7,
        cost_tol: 1e-10,
        weights_absolute: true,
        ..Settings::default()
    }
}

/// Fit the `free` parameters of `model` to the points in `subset`, from `x0` (full vector).
/// `constrain`: hold the mean of each per-separation correction at zero over the
/// separations present in `subset`.
pub fn fit(
    model: &Model,
    data: &Data,
    subset: &[usize],
    x0: &[f64],
    free: &[usize],
    constrain: bool,
    seps_names: &[f64],
) -> Result<FitResult, FitFailure> {
    let names = model.names(seps_names);
    let mut present = vec![false; model.nsep];
    for &i in subset {
        present[data.points[i].sep] = true;
    }
    let mut constraints = Vec::new();
    if constrain {
        for &e in model.effects.iter().filter(|&&e| model.zero_mean(e)) {
            for c in 0..e.local_names().len() {
                let idx: Vec<usize> = (0..model.nsep)
                    .filter(|&k| present[k])
                    .map(|k| model.local_indices(e, k).start + c)
                    .filter(|i| free.contains(i))
                    .collect();
                if !idx.is_empty() {
                    let w = 1.0 / idx.len() as f64;
                    constraints.push(idx.into_iter().map(|i| (i, w)).collect());
                }
            }
        }
        // The per-LED gauge, over the LED parameters this fit frees.
        for row in model.led_gauge() {
            let row: Vec<(usize, f64)> =
                row.into_iter().filter(|(i, _)| free.contains(i)).collect();
            if !row.is_empty() {
                constraints.push(row);
            }
        }
    }
    let prob = FitProblem {
        model,
        data,
        subset,
        fixed: x0,
        free,
        constraints: &constraints,
        names: &names,
    };
    let xf0 = DVector::from_iterator(free.len(), free.iter().map(|&i| x0[i]));
    let sol = match glsdc::solve(&prob, xf0, &settings()) {
        Ok(s) => s,
        Err(glsdc::Error::RankDeficient { null, .. }) => {
            let mut s = String::new();
            let _ = glsdc::describe_null(&prob, &null, &mut s);
            return Err(FitFailure(format!(
                "the data cannot tell these parameters apart: {s}"
            )));
        }
        Err(glsdc::Error::NotConverged { iterations, .. }) => {
            return Err(FitFailure(format!(
                "the fit did not converge in {iterations} iterations"
            )))
        }
        Err(glsdc::Error::TooFewRows { m, n }) => {
            return Err(FitFailure(format!(
                "{m} residuals for {n} parameters: too few points"
            )))
        }
        Err(glsdc::Error::Model(_)) => {
            return Err(FitFailure(
                "the model cannot be evaluated at some points (a cell pair sees nothing)".into(),
            ))
        }
    };
    let x = prob.full(&sol.x);
    let mut sigma = vec![0.0; x.len()];
    for (j, &i) in free.iter().enumerate() {
        sigma[i] = sol.sigma[j];
    }
    // Data-only sums (the constraints add ~0 at the solution, but keep them out).
    let y = model
        .predict(&x, data, subset)
        .map_err(|_| FitFailure("the fitted model cannot be evaluated".into()))?;
    let (mut chi2, mut ss) = (0.0, 0.0);
    for (j, &i) in subset.iter().enumerate() {
        let p: &PointMean = &data.points[i];
        #[allow(clippy::needless_range_loop)] // the two axes of three arrays
        for a in 0..2 {
            let r = p.y[a] - y[j][a];
            chi2 += p.w[a] * r * r;
            ss += r * r;
        }
    }
    Ok(FitResult {
        x,
        sigma,
        cov: sol.covariance,
        free: free.to_vec(),
        chi2,
        ss,
        m: 2 * subset.len(),
    })
}
