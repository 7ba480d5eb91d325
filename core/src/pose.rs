//! On-chip 6-dof pose: the relative position and attitude of a beacon constellation (the
//! target) from the NorthStar's spot reports, by GLSDC (thesis eqs 56-59) over the position
//! and the MRP attitude (eqs 54/55), with either the pinhole model (eq 53/65) or the
//! near-field model (the eq 60-63 emulator). The thesis leaves this as future work (Ch VI,
//! "a real-time 6-dof solution (using a GLSDC ...) can be programmed onto the NorthStar
//! sensor board microprocessor"); VISNAV showed the approach for LED beacons.
//!
//! # Frames and unknowns
//!
//! - T: the target frame, in which the constellation's beacon positions `r_T` are given
//!   (inches), each beacon with its NorthStar frequency channel (the spot ID).
//! - N: the sensor-board frame; O: the head frame. The *calibration* gives the head on the
//!   board: `d`, `p` (MRP of `C`, N -> O) and `H` (eq 65), for the near-field model the
//!   head geometry (face angle `a`, cell offset `s`, scale `beta`) and the beacon pattern,
//!   and optionally the pinhole model's own `d, p` ([`PinholeHead`]: a 7-parameter eq 65
//!   fit puts its eye point about 1 in above the head the near-field fit finds).
//! - Unknowns `x = [t, q]`: `t` = position of the T origin in N (inches), `q` = MRP of the
//!   DCM `C(q)` mapping N components to T components. A beacon is at
//!   `r_N = t + C(q)^T r_T`, and the LEDs' boresight (in T) turns with the target:
//!   `b_N = C(q)^T b_T`. On the CTA the plate faces the board: `t = (0, 0, separation)`,
//!   `q = 0`, `b_T = -z`.
//!
//! # Models
//!
//! - [`ModelKind::Pinhole`]: eq 65 through [`crate::collinearity::Linearisation`] with the
//!   calibration's `H` and its pinhole head's `d, p` ([`Calibration::pinhole`]; the
//!   calibration's `d, p` when it has none) (analytic Jacobian: `dy/dt = -dy/dd`, and
//!   `dy/dq_i = dy/dr . (dC/dq_i)^T r_T`, evaluated as `dy/dq = K ((C^T r_T) x dy/dr)`
//!   with [`mrp::gradient_map`]).
//! - [`ModelKind::NearField`]: the eq 60-63 emulator ([`Emulator`]) with the calibration's
//!   near-field parameters; analytic Jacobian by the chain rule through
//!   [`Emulator::output_gradient`] (beacon position and LED boresight) and the same `K`.
//!
//! # Solve
//!
//! Spots are matched to beacons by ID. A coordinate at the 16-bit rails (a cell in the dark:
//! the eq 63 ratio at +/-beta, or saturated), or within [`RAIL_SIGMAS`] noise sigmas of them
//! (clipped: the noise kept it a few counts inside), carries no position information and is
//! not used; the spot's other coordinate still is (near the edge of the field of view, at 2 in,
//! that keeps about four of the CTA constellation's ten beacons). With fewer than
//! [`MIN_BEACONS`] matched beacons, or fewer usable coordinates than [`MIN_BEACONS`] whole
//! spots give, the status is [`PoseStatus::TooFewBeacons`]. Otherwise GLSDC starts from the
//! previous good solution (warm start) or, without one, from the *cold start*: assume the
//! target faces the sensor (`q = 0`), turn each whole spot into a pinhole line of sight
//! `u_N = C^T (x/H, y/H, 1)` from the head at `d` (for the pinhole model, its own eye's `d`
//! and `C`), and solve the linear least-squares
//! problem `(t + r_T - d) x u_N = 0` (3 unknowns, 2 independent equations per beacon) for
//! `t`. Every residual has the same weight (unit: one multiplication less per Jacobian
//! element on the chip); the stopping tolerances are in units of `noise^2` (noise from the
//! calibration), so that `sum r^2 / noise^2` is chi-square; the covariance is scaled by the
//! residual variance, so model misfit shows in the 1-sigma.
//!
//! A warm solve also starts from the last solve's linearisation when the same coordinates
//! of the same beacons are in view ([`glsdc::solve_with`]): its first step uses the model
//! values that linearisation predicts at the last solution (the warm start) against the new
//! spots, so it evaluates no model at all; the point it reaches is linearised afresh before
//! any stop, so the answer is Gauss-Newton's. A last step predicted to gain less than 0.1
//! chi-square is taken without another pass. A warm solve is thus one Jacobian pass.
//!
//! # Spot magnitudes
//!
//! Beyond the thesis (its model is the spots' `X, Y`): when the calibration carries a
//! magnitude law ([`Calibration::magnitude`], [`Magnitude`]) the near-field solve also fits
//! each spot's reported magnitude against the model's summed cell signal `S` (eq 63's
//! `sum_k c_k I_k V_k`), as `ln S` up to a scale common to the frame (LED drive, power
//! setting, drift) that is eliminated exactly: the magnitudes' residuals enter as their
//! weighted Helmert contrasts (`Contrasts`), `k` magnitudes giving `k - 1` rows in counts, so
//! the solve keeps its six unknowns and unit weights. Their ratios carry the beacons'
//! relative distances, which a flat target's tilt changes and the spots show only through
//! perspective: at 8-10 in they cut the one-frame attitude error of the 10-beacon target
//! about four-fold, if the magnitudes scatter as little as the spots (`cta sensor floor`,
//! `cta sensor accuracy`). A reading at or above the law's `max` (saturated), or not a count
//! above its offset, is not used; a frame at another light-sensitivity setting than the
//! law's is solved from the spots alone ([`PoseSolver::solve_frame`]). Each beacon's
//! relative brightness ([`Beacon::brightness`]) is divided out. A solve whose magnitudes
//! disagree with its spots (a residual RMS over [`MAGNITUDE_RMS_SIGMAS`] noise sigmas: a
//! wrong brightness, a law that does not hold, a drifting LED), or that fails with them, is
//! done again from the spots alone, and reports no magnitudes fitted.
//!
//! Status: [`PoseStatus::Ok`]; [`PoseStatus::IllConditioned`] when GLSDC reports a rank
//! deficiency, the condition number exceeds the limit, or the position 1-sigma exceeds
//! [`SolverSettings::max_sigma_fraction`] of the range; [`PoseStatus::Diverged`] when the
//! iteration does not converge, leaves the model's domain, ends behind the sensor, beyond
//! the constellation's far limit ([`FAR_SIGMAS`]) or with a residual RMS above the limit (a
//! false minimum). The pose is never NaN: a failed solve reports the last finite estimate,
//! its sigmas are `-1`, and the next solve cold-starts.

use crate::collinearity::{Linearisation, Params, ParamsExt};
use crate::emulator::{Effects, Emulator, Head, Pose as HeadPose};
use crate::glsdc::{self, ModelError, Problem, Settings};
use crate::mrp;
use crate::pattern::Pattern;
use crate::real::{deg, rad};
use crate::Real;
use core::fmt;
use heapless::Vec;
use nalgebra::{Matrix3, SVector, Vector3, U6};
use serde::{Deserialize, Serialize};

/// Most beacons in a constellation (the NorthStar tracks at most 20 spots).
pub const MAX_BEACONS: usize = 20;
/// Fewest matched beacons for a 6-dof solution (4 beacons give 8 equations for 6 unknowns).
pub const MIN_BEACONS: usize = 4;
/// Highest NorthStar frequency channel (spot ID).
pub const MAX_CHANNEL: u8 = 19;
/// The 16-bit output rail, counts: an output at or past it is clipped to it.
pub const RAIL: i16 = i16::MAX;
/// A coordinate within this many calibration noise sigmas ([`Calibration::noise`]) of
/// +/-[`RAIL`] counts as railed: its true value was at or past the rail (a cell in the dark,
/// or saturated) and only the noise kept it inside, so it is clipped, not measured. The rule
/// `cta calibrate` applies to a point's mean (`measurement::mean_near_rail`).
pub const RAIL_SIGMAS: f32 = 3.0;
/// The constellation's far limit: the range at which its radius about its centroid
/// subtends this many noise sigmas of the pinhole (`radius x H / (3 noise)`: 908 in for
/// [`cta_constellation`] and 2,860 in for [`four_array_constellation`] (2,874 in for the
/// host's `four-19`, which leaves its channel 19 out) with [`Calibration::table3`], 30 and 95
/// times the CTA's 30 in). There its beacons' spots are
/// barely apart in the noise and the position 1-sigma is a quarter of the range (the one-10
/// constellation at 1,000 in: 0.2 median, 0.36 at most): a solution beyond it is a false
/// minimum, reported diverged.
pub const FAR_SIGMAS: f32 = 3.0;

/// One IR spot as the NorthStar reports it.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Spot {
    /// Frequency channel 0..=19 (beacon `k` uses channels `2k` and `2k + 1`).
    pub id: u8,
    /// X output, signed counts (eq 63).
    pub x: i16,
    /// Y output, signed counts (eq 63).
    pub y: i16,
    /// Signal strength 0..65535 (about 5000 is the noise floor, above 47000 is strong).
    pub magnitude: u16,
}

/// A beacon of the constellation.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct Beacon {
    /// Its NorthStar frequency channel (the ID of its spot), 0..=19.
    pub id: u8,
    /// Position in the target frame T, inches.
    pub r: [f32; 3],
    /// Its LED's brightness relative to the others' (1 nominal; [`MIN_BRIGHTNESS`] ..=
    /// [`MAX_BRIGHTNESS`]): the spot magnitude model ([`Magnitude`]) divides it out. Only
    /// ratios between the beacons count (the common scale is estimated with every pose);
    /// `cta calibrate` measures each plate LED's from a sweep. A constellation file without
    /// it reads 1.
    #[serde(default = "unit_brightness")]
    pub brightness: f32,
}

impl Default for Beacon {
    fn default() -> Self {
        Beacon {
            id: 0,
            r: [0.0; 3],
            brightness: 1.0,
        }
    }
}

fn unit_brightness() -> f32 {
    1.0
}

/// A solve with the magnitudes whose residual RMS exceeds this many spot noise sigmas (or
/// that fails) is replaced by the solve from the spots alone: the magnitudes are used only
/// where they agree with the spots (a wrong brightness, a law that does not hold, a drifting
/// LED), and never cost the pose it would have had without them. Clean frames sit near 1
/// (29 rows: 1-sigma of the RMS about 0.13).
pub const MAGNITUDE_RMS_SIGMAS: f32 = 2.0;

/// Dimmest relative beacon brightness ([`Beacon::brightness`]) a constellation may give.
pub const MIN_BRIGHTNESS: f32 = 0.05;
/// Brightest relative beacon brightness ([`Beacon::brightness`]).
pub const MAX_BRIGHTNESS: f32 = 20.0;

/// The beacon constellation: positions in the target frame and the LED boresight.
#[derive(Serialize, Deserialize, Debug, Clone, PartialEq, Default)]
pub struct Constellation {
    /// The beacons (IDs unique).
    pub beacons: Vec<Beacon, MAX_BEACONS>,
    /// LED boresight in T (unit vector; the CTA plate's LEDs point along `-z`).
    pub boresight: [f32; 3],
}

/// The near-field part of the sensor calibration (the eq 60-63 physics).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct NearField {
    /// Cell face angle `a`, degrees (30 nominal): the X pair's (cells 1, 2), and the Y
    /// pair's unless [`Self::alpha_y_deg`] is given.
    pub alpha_deg: f32,
    /// Cell-centre offset `s`, inches (0.175 nominal).
    pub s: f32,
    /// Output scale `beta`, counts (32768 nominal).
    pub beta: f32,
    /// Beacon pattern exponent `m` of `cos^m` (1 for the VSML3710's 60 deg half angle).
    pub pattern_m: f32,
    /// Responsivity mismatch within each cell pair (the analysis vocabulary's `cell_gain`,
    /// on eq 63's `S_k`): cell 1's signal is multiplied by `1 + gain[0]`, cell 3's by
    /// `1 + gain[1]`. 0 nominal; a calibration file without it reads 0.
    #[serde(default)]
    pub gain: [f32; 2],
    /// Offset of each cell pair's first cell (the analysis vocabulary's `cell_bias`, on eq
    /// 63's `S_k`, in its units, 1/in^2): `bias[0]` is added to cell 1's signal, `bias[1]`
    /// to cell 3's (after the gain): ambient light or dark current the demodulation leaves.
    /// It matters far from the beacons, where the signals are small (0.001/in^2 on axis at
    /// 30 in). 0 nominal; a calibration file without it reads 0.
    #[serde(default)]
    pub bias: [f32; 2],
    /// The Y pair's (cells 3, 4) face angle, degrees, when it differs from the X pair's (the
    /// analysis vocabulary's `face_angle=DX,DY`: a pyramid whose faces were not cut alike).
    /// `None` (and a calibration file without it): `alpha_deg`.
    #[serde(default)]
    pub alpha_y_deg: Option<f32>,
}

impl NearField {
    /// The thesis's NorthStar and VSML3710 (REFERENCE.md section 1).
    pub fn nominal() -> Self {
        NearField {
            alpha_deg: 30.0,
            s: 0.175,
            beta: 32768.0,
            pattern_m: 1.0,
            gain: [0.0; 2],
            bias: [0.0; 2],
            alpha_y_deg: None,
        }
    }

    /// The face angles of the X and Y pairs, degrees.
    pub fn face_angles_deg(&self) -> [f32; 2] {
        [self.alpha_deg, self.alpha_y_deg.unwrap_or(self.alpha_deg)]
    }

    /// The per-cell gains of [`Effects::gain`]: `[1 + gain[0], 1, 1 + gain[1], 1]`.
    pub fn cell_gains<T: Real>(&self) -> [T; 4] {
        let one = T::one();
        [
            one + T::lit(self.gain[0] as f64),
            one,
            one + T::lit(self.gain[1] as f64),
            one,
        ]
    }

    /// The per-cell offsets of [`Effects::bias`]: `[bias[0], 0, bias[1], 0]`.
    pub fn cell_biases<T: Real>(&self) -> [T; 4] {
        let z = T::zero();
        [
            T::lit(self.bias[0] as f64),
            z,
            T::lit(self.bias[1] as f64),
            z,
        ]
    }
}

/// The spot magnitude model: how the NorthStar's reported magnitude `M` follows the light
/// its four cells collect, so that the near-field pose can use the magnitudes as a further
/// measurement (beyond the thesis: its model is the spots' `X, Y` only).
///
/// `M = offset + A (b S)^exponent`, with `S` the summed cell signal of eq 63 (`sum_k c_k I_k
/// V_k`, 1/in^2: the emulator's [`Emulator::magnitude`]), `b` the beacon's relative
/// brightness ([`Beacon::brightness`]) and `A` unknown: every pose estimates it with the
/// position and attitude (LED drive, drift, power setting: a scale common to the frame's
/// beacons), so only the magnitudes' ratios between beacons count. They carry the beacons'
/// relative distances and angles, which is what a flat target's tilt changes and the spots
/// show only through perspective (see `cta sensor floor`).
///
/// The NorthStar's real magnitude output is not public and has not been measured here: the
/// law is an assumption wide enough to hold a linear (exponent 1), compressive or offset
/// response, which `cta calibrate` fits to a sweep's `magnitude` column, measuring
/// [`Self::noise_percent`] from the scatter about the fit (repeatability and model misfit
/// alike), so that the pose weighs the magnitudes by what they proved to be worth.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct Magnitude {
    /// The reading with no signal, counts (0 ..= 60000).
    pub offset: f32,
    /// The response's exponent: `M - offset` grows as the signal to this power (0.1 ..= 5).
    pub exponent: f32,
    /// 1-sigma scatter of `M - offset` about the law, percent of it (0.001 ..= 100). Each
    /// reading also carries its rounding to whole counts (1/12 counts^2), which dominates
    /// weak spots.
    pub noise_percent: f32,
    /// The largest reading used, counts (above `offset` + 1, at most 65535): a reading at or
    /// above it is taken as saturated and not used.
    pub max: f32,
    /// The smallest reading used, counts (0 ..= `max`): the law holds where it was measured,
    /// and `cta calibrate` sets this to the weakest reading it fitted, so that a law fitted
    /// on strong spots is not stretched over weak ones (where an offset it barely saw, or a
    /// response that bends below its range, would bias the pose). A calibration file without
    /// it reads 0.
    #[serde(default)]
    pub min: f32,
    /// The NorthStar light-sensitivity setting (1-4) the law was fitted at: frames at
    /// another setting are solved from the spots alone.
    pub sensitivity: u8,
}

impl Magnitude {
    /// The simulated NorthStar's law ([`simulate_spots`]: `M = SIM_MAGNITUDE_SCALE x S`,
    /// linear, no offset, saturating at 65535), with `noise_percent` of scatter, at
    /// sensitivity 4 (the board's start-up setting).
    pub fn simulated(noise_percent: f32) -> Self {
        Magnitude {
            offset: 0.0,
            exponent: 1.0,
            noise_percent,
            max: 65535.0,
            min: 0.0,
            sensitivity: 4,
        }
    }
}

/// The simulated NorthStar's magnitude per unit of summed cell signal, counts per 1/in^2: a
/// beacon 1 in away on the boresight reads about 60000, at 10 in about 520, at 30 in about
/// 58 (the real detector's scale is unknown: see [`Magnitude`]).
pub const SIM_MAGNITUDE_SCALE: f64 = 15000.0;

/// The pinhole model's own head pose: the `d, p` of a 7-parameter eq 65 fit (`d, p, H`,
/// thesis eqs 64-66, at the far separations), which the [`ModelKind::Pinhole`] solve uses
/// with [`Calibration::h`] when the calibration has it.
///
/// The pinhole fit's `d` is not the head's: it is the pinhole's eye point, which the fit
/// moves about 1 in above the head to hold the near-field structure of the data (README,
/// "virtual eye"). A calibration fitted with both models (`cta calibrate`) therefore has two
/// head poses: the near-field fit's in [`Calibration::d`], [`Calibration::p`] (the head
/// itself) and the pinhole fit's here. Solving eq 65 with the head's `d, p` and the pinhole
/// fit's `H` reads ranges short (about 0.9 in at 12 in).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct PinholeHead {
    /// N origin -> the pinhole's eye point, in N, inches (eq 65's `d`).
    pub d: [f32; 3],
    /// MRP of the pinhole's `C` (N -> O; eq 65's `p`).
    pub p: [f32; 3],
}

/// The sensor calibration: the head on the board (eq 65's `d, p, H`), the measurement
/// noise, and optionally the near-field parameters and the pinhole model's own head pose.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// N origin -> head centre, in N, inches.
    pub d: [f32; 3],
    /// MRP of `C` (N -> O).
    pub p: [f32; 3],
    /// Scale height `H`, counts (18918.6 nominal).
    pub h: f32,
    /// 1-sigma noise of a spot coordinate, counts (the pose solver's tolerances are in units
    /// of `noise^2`).
    pub noise: f32,
    /// Near-field parameters (when calibrated with the eq 63 physics).
    pub near_field: Option<NearField>,
    /// The pinhole model's own `d, p` (eq 65, fitted with [`Self::h`]), when they differ from
    /// the head's [`Self::d`], [`Self::p`]: [`ModelKind::Pinhole`] solves with them. `None`
    /// (and a calibration file without it): the pinhole model uses `d, p`.
    #[serde(default)]
    pub pinhole: Option<PinholeHead>,
    /// The spot magnitude model: with it the near-field pose also fits the magnitudes
    /// ([`Magnitude`]). `None` (and a calibration file without it): the spots alone.
    #[serde(default)]
    pub magnitude: Option<Magnitude>,
}

impl Calibration {
    /// The Table 3 truth (`d = (0.6, 0.1, 0.062)`, `p = (0.001, 0.002, 0.001)`,
    /// `H = beta tan 30 deg`), noise 0.1 % of beta, nominal near-field parameters.
    pub fn table3() -> Self {
        Calibration {
            d: [0.6, 0.1, 0.062],
            p: [0.001, 0.002, 0.001],
            h: 18918.6,
            noise: 32.768,
            near_field: Some(NearField::nominal()),
            pinhole: None,
            magnitude: None,
        }
    }
}

/// A calibration field, named in [`ConfigError::CalibrationOutOfRange`].
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub enum CalField {
    /// `d`: finite, each component within +/-12 in.
    D,
    /// `p`: finite, `|p| <= 1`.
    P,
    /// `H`: 1000 ..= 200000 counts.
    H,
    /// `noise`: 0.01 ..= 10000 counts.
    Noise,
    /// Near-field face angle: 5 ..= 85 deg.
    Alpha,
    /// Near-field cell offset: 0 ..= 2 in.
    S,
    /// Near-field beta: 1000 ..= 100000 counts.
    Beta,
    /// Near-field pattern exponent: 0 ..= 50.
    PatternM,
    /// Near-field cell gains: each within +/-0.5.
    Gain,
    /// Near-field cell offsets: each within +/-0.01 per square inch.
    Bias,
    /// The pinhole model's own `d` ([`PinholeHead::d`]): as [`CalField::D`].
    PinholeD,
    /// The pinhole model's own `p` ([`PinholeHead::p`]): as [`CalField::P`].
    PinholeP,
    /// Magnitude offset ([`Magnitude::offset`]): 0 ..= 60000 counts.
    MagnitudeOffset,
    /// Magnitude exponent ([`Magnitude::exponent`]): 0.1 ..= 5.
    MagnitudeExponent,
    /// Magnitude noise ([`Magnitude::noise_percent`]): 0.001 ..= 100 %.
    MagnitudeNoise,
    /// Largest magnitude used ([`Magnitude::max`]): above the offset + 1, at most 65535.
    MagnitudeMax,
    /// Smallest magnitude used ([`Magnitude::min`]): 0 ..= max.
    MagnitudeMin,
    /// Sensitivity of the magnitude law ([`Magnitude::sensitivity`]): 1 ..= 4.
    MagnitudeSensitivity,
}

impl CalField {
    /// Name and allowed range, for messages.
    pub fn describe(self) -> &'static str {
        match self {
            CalField::D => "d (each component finite, within +/-12 in)",
            CalField::P => "p (MRP, finite, |p| <= 1)",
            CalField::H => "H (1000 ..= 200000 counts)",
            CalField::Noise => "noise (0.01 ..= 10000 counts)",
            CalField::Alpha => "near-field face angles (each 5 ..= 85 deg)",
            CalField::S => "near-field cell offset s (0 ..= 2 in)",
            CalField::Beta => "near-field beta (1000 ..= 100000 counts)",
            CalField::PatternM => "near-field pattern exponent m (0 ..= 50)",
            CalField::Gain => "near-field cell gains (each -0.5 ..= 0.5)",
            CalField::Bias => "near-field cell offsets (each -0.01 ..= 0.01 per in^2)",
            CalField::PinholeD => "pinhole d (each component finite, within +/-12 in)",
            CalField::PinholeP => "pinhole p (MRP, finite, |p| <= 1)",
            CalField::MagnitudeOffset => "magnitude offset (0 ..= 60000 counts)",
            CalField::MagnitudeExponent => "magnitude exponent (0.1 ..= 5)",
            CalField::MagnitudeNoise => "magnitude noise (0.001 ..= 100 %)",
            CalField::MagnitudeMax => "magnitude max (above the offset + 1 count, at most 65535)",
            CalField::MagnitudeMin => "magnitude min (0 ..= max counts)",
            CalField::MagnitudeSensitivity => "magnitude sensitivity (1 ..= 4)",
        }
    }
}

/// A constellation or calibration the board refuses.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigError {
    /// Fewer beacons than a 6-dof solution needs.
    TooFewBeacons {
        /// Beacons given.
        count: u8,
        /// Minimum ([`MIN_BEACONS`]).
        min: u8,
    },
    /// Two beacons share a frequency channel.
    DuplicateId {
        /// The repeated ID.
        id: u8,
    },
    /// A beacon ID beyond the NorthStar's channels (0..=19).
    IdOutOfRange {
        /// The ID.
        id: u8,
    },
    /// A beacon position that is not finite or farther than 1000 in from the T origin.
    BeaconOutOfRange {
        /// The beacon's ID.
        id: u8,
    },
    /// A beacon brightness outside [`MIN_BRIGHTNESS`] ..= [`MAX_BRIGHTNESS`].
    BrightnessOutOfRange {
        /// The beacon's ID.
        id: u8,
    },
    /// The boresight is not a finite non-zero vector.
    Boresight,
    /// A calibration value outside its range.
    CalibrationOutOfRange {
        /// Which one.
        field: CalField,
    },
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ConfigError::TooFewBeacons { count, min } => {
                write!(
                    f,
                    "constellation has {count} beacons, at least {min} are needed"
                )
            }
            ConfigError::DuplicateId { id } => write!(f, "duplicate beacon ID {id}"),
            ConfigError::IdOutOfRange { id } => {
                write!(f, "beacon ID {id} out of range (0..={MAX_CHANNEL})")
            }
            ConfigError::BeaconOutOfRange { id } => {
                write!(f, "beacon {id}: position not finite or beyond 1000 in")
            }
            ConfigError::BrightnessOutOfRange { id } => write!(
                f,
                "beacon {id}: brightness outside {MIN_BRIGHTNESS} ..= {MAX_BRIGHTNESS}"
            ),
            ConfigError::Boresight => f.write_str("boresight must be a finite non-zero vector"),
            ConfigError::CalibrationOutOfRange { field } => {
                write!(f, "calibration out of range: {}", field.describe())
            }
        }
    }
}

fn in_range(v: f32, lo: f32, hi: f32) -> bool {
    v.is_finite() && v >= lo && v <= hi
}

impl Constellation {
    /// Check count, IDs and positions.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let n = self.beacons.len();
        if n < MIN_BEACONS {
            return Err(ConfigError::TooFewBeacons {
                count: n as u8,
                min: MIN_BEACONS as u8,
            });
        }
        for (i, b) in self.beacons.iter().enumerate() {
            if b.id > MAX_CHANNEL {
                return Err(ConfigError::IdOutOfRange { id: b.id });
            }
            if self.beacons[..i].iter().any(|o| o.id == b.id) {
                return Err(ConfigError::DuplicateId { id: b.id });
            }
            if !b.r.iter().all(|&c| in_range(c, -1000.0, 1000.0)) {
                return Err(ConfigError::BeaconOutOfRange { id: b.id });
            }
            if !in_range(b.brightness, MIN_BRIGHTNESS, MAX_BRIGHTNESS) {
                return Err(ConfigError::BrightnessOutOfRange { id: b.id });
            }
        }
        let bs = self.boresight;
        let n2 = bs[0] * bs[0] + bs[1] * bs[1] + bs[2] * bs[2];
        if !(n2.is_finite() && n2 > 1e-12) {
            return Err(ConfigError::Boresight);
        }
        Ok(())
    }
}

impl Calibration {
    /// Check every field against its documented range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |field| Err(ConfigError::CalibrationOutOfRange { field });
        // The head, then the pinhole model's own (checked alike, named apart).
        let heads = [
            (Some((&self.d, &self.p)), CalField::D, CalField::P),
            (
                self.pinhole.as_ref().map(|h| (&h.d, &h.p)),
                CalField::PinholeD,
                CalField::PinholeP,
            ),
        ];
        for (head, field_d, field_p) in heads {
            let Some((d, p)) = head else { continue };
            if !d.iter().all(|&v| in_range(v, -12.0, 12.0)) {
                return bad(field_d);
            }
            let p2 = p.iter().map(|v| v * v).sum::<f32>();
            if !(p.iter().all(|v| v.is_finite()) && p2 <= 1.0) {
                return bad(field_p);
            }
        }
        if !in_range(self.h, 1000.0, 200_000.0) {
            return bad(CalField::H);
        }
        if !in_range(self.noise, 0.01, 10_000.0) {
            return bad(CalField::Noise);
        }
        if let Some(nf) = &self.near_field {
            if !nf.face_angles_deg().iter().all(|&a| in_range(a, 5.0, 85.0)) {
                return bad(CalField::Alpha);
            }
            if !in_range(nf.s, 0.0, 2.0) {
                return bad(CalField::S);
            }
            if !in_range(nf.beta, 1000.0, 100_000.0) {
                return bad(CalField::Beta);
            }
            if !in_range(nf.pattern_m, 0.0, 50.0) {
                return bad(CalField::PatternM);
            }
            if !nf.gain.iter().all(|&g| in_range(g, -0.5, 0.5)) {
                return bad(CalField::Gain);
            }
            // 0.01/in^2 is a beacon's on-axis signal at 10 in: ten times the signal at 30 in.
            if !nf.bias.iter().all(|&b| in_range(b, -0.01, 0.01)) {
                return bad(CalField::Bias);
            }
        }
        if let Some(m) = &self.magnitude {
            if !in_range(m.offset, 0.0, 60_000.0) {
                return bad(CalField::MagnitudeOffset);
            }
            if !in_range(m.exponent, 0.1, 5.0) {
                return bad(CalField::MagnitudeExponent);
            }
            if !in_range(m.noise_percent, 0.001, 100.0) {
                return bad(CalField::MagnitudeNoise);
            }
            if !(in_range(m.max, 0.0, 65_535.0) && m.max > m.offset + 1.0) {
                return bad(CalField::MagnitudeMax);
            }
            if !in_range(m.min, 0.0, m.max) {
                return bad(CalField::MagnitudeMin);
            }
            if !(1..=4).contains(&m.sensitivity) {
                return bad(CalField::MagnitudeSensitivity);
            }
        }
        Ok(())
    }
}

/// Which measurement model the solver uses.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelKind {
    /// Eq 65 (far-field collinearity) with the calibration's `H` and its pinhole head
    /// ([`Calibration::pinhole`]'s `d, p`; without one, the calibration's `d, p`).
    Pinhole,
    /// The eq 60-63 physics with the calibration's near-field parameters.
    NearField,
}

/// Outcome of a solve.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub enum PoseStatus {
    /// Converged; pose and 1-sigma valid.
    Ok,
    /// Fewer than [`MIN_BEACONS`] beacons of the constellation were seen, or fewer usable
    /// coordinates (farther than [`RAIL_SIGMAS`] noise sigmas from the 16-bit rails) than
    /// that many whole spots give.
    TooFewBeacons,
    /// No convergence, left the model's domain, or a false minimum (residual too large, or
    /// the target beyond the constellation's far limit, [`FAR_SIGMAS`]).
    Diverged,
    /// The geometry does not determine the pose (rank deficient, condition too large, or a
    /// position 1-sigma over [`SolverSettings::max_sigma_fraction`] of the range).
    IllConditioned,
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverSettings {
    /// Measurement model.
    pub model: ModelKind,
    /// GLSDC iteration cap.
    pub max_iter: usize,
    /// Largest acceptable condition number of the scaled Jacobian.
    pub max_condition: f64,
    /// Largest acceptable residual RMS, counts (larger: a false minimum, reported diverged).
    pub max_rms: f64,
    /// Largest acceptable position 1-sigma (the norm of the three) as a fraction of the
    /// range `|t|` (larger: the data do not fix where the target is, reported
    /// ill-conditioned). 0.25 by default: on the CTA (2-30 in) it is at most 0.08 (the
    /// pinhole's misfit at 2 in; the near-field's at most 0.007); one-10 at 500 in reaches
    /// 0.17.
    pub max_sigma_fraction: f64,
    /// Fit the spot magnitudes too when the calibration has a magnitude model
    /// ([`Calibration::magnitude`]) and the model is [`ModelKind::NearField`] (the pinhole
    /// model has no intensity). `true` by default; `false` solves from the spots alone.
    pub magnitudes: bool,
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            model: ModelKind::NearField,
            max_iter: 20,
            max_condition: 1e4,
            max_rms: 2000.0,
            max_sigma_fraction: 0.25,
            magnitudes: true,
        }
    }
}

/// A pose solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSolution<T: Real> {
    /// Status.
    pub status: PoseStatus,
    /// Target origin in N, inches (never NaN).
    pub position: Vector3<T>,
    /// MRP of `C(q)` (N -> T), `|q| <= 1` (never NaN).
    pub mrp: Vector3<T>,
    /// 1-sigma of the position, inches (`-1` unless the status is Ok or IllConditioned
    /// with a covariance).
    pub sigma_position: Vector3<T>,
    /// 1-sigma of the attitude about the three axes, degrees (small-angle: `4 sigma_q`).
    pub sigma_attitude_deg: Vector3<T>,
    /// Residual RMS, counts.
    pub rms: T,
    /// GLSDC iterations.
    pub iterations: u8,
    /// Beacons used.
    pub beacons: u8,
    /// Spot magnitudes fitted (0: the spots alone; one magnitude alone carries nothing, its
    /// scale being unknown).
    pub magnitudes: u8,
    /// Condition number of the scaled, weighted Jacobian (0 when not computed).
    pub condition: T,
    /// Whether this solve started from the cold start.
    pub cold_start: bool,
}

/// A matched observation: beacon position in T and the measured spot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obs<T: Real> {
    /// Beacon position, T frame, inches.
    pub r: Vector3<T>,
    /// Measured `(X, Y)`, counts.
    pub y: [T; 2],
    /// Which of `X`, `Y` are used (`false`: at or near the 16-bit rail).
    pub used: [bool; 2],
    /// The magnitude as a measured log signal, `ln(M - offset) / exponent - ln b`
    /// ([`Magnitude`]), to set against the model's `ln S` (up to the frame's common scale).
    pub m: T,
    /// The magnitude's weight, `(noise / sigma_ln)^2` with `noise` the spots' 1-sigma in
    /// counts and `sigma_ln` the magnitude's in `ln S`: its row is in counts as the spots'
    /// are. 0: not used.
    pub mw: T,
}

impl<T: Real> Obs<T> {
    /// Both coordinates used, no magnitude.
    pub fn new(r: Vector3<T>, y: [T; 2]) -> Self {
        Obs {
            r,
            y,
            used: [true; 2],
            m: T::zero(),
            mw: T::zero(),
        }
    }

    /// Whether the magnitude is used.
    pub fn magnitude_used(&self) -> bool {
        self.mw > T::zero()
    }

    /// Usable coordinates (0-2).
    pub fn rows(&self) -> usize {
        usize::from(self.used[0]) + usize::from(self.used[1])
    }
}

/// The pose solver: calibration and constellation converted to `T`, and the warm start.
#[derive(Debug, Clone)]
pub struct PoseSolver<T: Real> {
    settings: SolverSettings,
    cal: Params<T>,
    lin: Linearisation<T>,
    emulator: Option<Emulator<T>>,
    beacons: Vec<(u8, Vector3<T>), MAX_BEACONS>,
    boresight: Vector3<T>,
    /// The head's boresight (the O frame's z axis) in N.
    head_axis: Vector3<T>,
    /// `noise^2` (counts^2): the unit of the stopping tolerances.
    noise2: T,
    /// A coordinate with `|v| >= rail` is railed: [`RAIL`] less [`RAIL_SIGMAS`] noise.
    rail: i32,
    /// The distance of the constellation's centroid from the T origin, inches.
    centroid_offset: T,
    /// The square of the largest range `|t|` a pose may have (see [`Self::configure`]).
    max_range2: T,
    /// The square of [`SolverSettings::max_sigma_fraction`].
    max_sigma_fraction2: T,
    /// The magnitude model in `T`, when the magnitudes are fitted.
    mag: Option<MagSolve<T>>,
    /// `ln b` of each beacon's brightness ([`Beacon::brightness`]), in the order of `beacons`.
    ln_brightness: [T; MAX_BEACONS],
    /// [`SolverSettings::max_condition`] and [`SolverSettings::max_rms`] in `T`, converted
    /// once by [`Self::configure`]: no double-precision conversion (a soft-float routine of
    /// its own on the chip) in the solve.
    max_condition: T,
    max_rms: T,
    warm: Option<SVector<T, 6>>,
    /// The last solve's linearisation, carried to the next frame's first step
    /// ([`glsdc::solve_with`]): its weighted Jacobian rows (2 per beacon) with the model
    /// values predicted at the solution, the factored normal matrix, and which coordinates
    /// of which beacons the rows belong to.
    rows: [T; 2 * MAX_BEACONS * 7],
    carry: Option<glsdc::Carry<T, U6>>,
    carry_key: u64,
    /// The magnitudes' weights of the carried linearisation, by observation: a frame solved
    /// from it keeps them (a reading's weight moves with its rounding term from frame to
    /// frame, and the carried rows are the contrasts of those weights).
    carry_mw: [T; MAX_BEACONS],
}

/// [`Magnitude`] as the solver uses it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct MagSolve<T> {
    offset: T,
    inv_exponent: T,
    /// `(noise x exponent)^2`: the numerator of a magnitude's weight.
    w_num: T,
    /// `(noise_percent / 100)^2`.
    rel2: T,
    max: T,
    min: T,
    sensitivity: u8,
}

impl<T: Real> MagSolve<T> {
    fn new(m: &Magnitude, noise: T) -> Self {
        let g = T::lit(m.exponent as f64);
        let rel = T::lit(m.noise_percent as f64) / T::lit(100.0);
        MagSolve {
            offset: T::lit(m.offset as f64),
            inv_exponent: T::one() / g,
            w_num: noise * noise * g * g,
            rel2: rel * rel,
            max: T::lit(m.max as f64),
            min: T::lit(m.min as f64),
            sensitivity: m.sensitivity,
        }
    }

    /// `(m, weight)` of a reading (see [`Obs::m`]; `ln_b` the beacon's `ln` brightness), or
    /// `None` when it is not used: saturated (at or above `max`), below the law's range
    /// (`min`), or not a whole count above the offset. `M - offset = D` has the variance `(rel D)^2 + 1/12` (the scatter and the
    /// rounding to counts), so `ln S = ln D / exponent` has `(rel^2 + 1/(12 D^2)) /
    /// exponent^2`.
    fn reading(&self, magnitude: u16, ln_b: T) -> Option<(T, T)> {
        let mv = T::lit(magnitude as f64);
        let d = mv - self.offset;
        if mv >= self.max || mv < self.min || d < T::one() {
            return None;
        }
        let var = self.rel2 + T::one() / (T::lit(12.0) * d * d);
        Some((d.ln() * self.inv_exponent - ln_b, self.w_num / var))
    }
}

fn v3<T: Real>(a: &[f32; 3]) -> Vector3<T> {
    Vector3::new(
        T::lit(a[0] as f64),
        T::lit(a[1] as f64),
        T::lit(a[2] as f64),
    )
}

impl<T: Real> PoseSolver<T> {
    /// Build a solver; validates both inputs. `ModelKind::NearField` without near-field
    /// parameters in the calibration uses the nominal ones ([`NearField::nominal`]).
    pub fn new(
        cal: &Calibration,
        con: &Constellation,
        settings: SolverSettings,
    ) -> Result<Self, ConfigError> {
        let mut s = Self::blank();
        s.configure(cal, con, settings)?;
        Ok(s)
    }

    /// A solver with nothing configured (every solve reports too few beacons), as a board
    /// holds one before [`Self::configure`] first succeeds.
    pub fn blank() -> Self {
        let params = Params::<T>::zeros();
        PoseSolver {
            settings: SolverSettings::default(),
            cal: params,
            lin: Linearisation::new(&params),
            emulator: None,
            beacons: Vec::new(),
            boresight: Vector3::new(T::zero(), T::zero(), -T::one()),
            head_axis: Vector3::new(T::zero(), T::zero(), T::one()),
            noise2: T::one(),
            rail: i32::from(RAIL),
            centroid_offset: T::zero(),
            max_range2: T::zero(),
            max_sigma_fraction2: T::zero(),
            mag: None,
            ln_brightness: [T::zero(); MAX_BEACONS],
            max_condition: T::lit(SolverSettings::default().max_condition),
            max_rms: T::lit(SolverSettings::default().max_rms),
            warm: None,
            rows: [T::zero(); 2 * MAX_BEACONS * 7],
            carry: None,
            carry_key: 0,
            carry_mw: [T::zero(); MAX_BEACONS],
        }
    }

    /// [`Self::new`] in place: validate both inputs, then replace the configuration and
    /// forget the warm start. On the chip the solver is the largest object (about 2 KiB):
    /// configuring it where it lives keeps a second copy off the stack. On an error the
    /// solver is left blank.
    ///
    /// It also sets the two limits the calibration and the constellation imply: the rail
    /// margin ([`RAIL_SIGMAS`] x the calibration's noise) and the constellation's far limit
    /// (see [`FAR_SIGMAS`]). Its bound on `|t|` adds the centroid's distance from the T
    /// origin.
    pub fn configure(
        &mut self,
        cal: &Calibration,
        con: &Constellation,
        settings: SolverSettings,
    ) -> Result<(), ConfigError> {
        self.beacons.clear();
        self.emulator = None;
        self.mag = None;
        self.warm = None;
        self.carry = None;
        cal.validate()?;
        con.validate()?;
        let head_pose = HeadPose {
            d: v3(&cal.d),
            p: v3(&cal.p),
        };
        // The pinhole model's eye: its own fitted d, p when the calibration has them.
        let eye = match (settings.model, &cal.pinhole) {
            (ModelKind::Pinhole, Some(ph)) => HeadPose {
                d: v3(&ph.d),
                p: v3(&ph.p),
            },
            _ => head_pose,
        };
        let params = Params::from_pose(&eye, T::lit(cal.h as f64));
        if settings.model == ModelKind::NearField {
            let nf = cal.near_field.unwrap_or(NearField::nominal());
            let [ax, ay] = nf.face_angles_deg().map(|a| rad(T::lit(a as f64)));
            let head = Head {
                alpha_x: ax,
                alpha_y: ay,
                s: T::lit(nf.s as f64),
                beta: T::lit(nf.beta as f64),
            };
            let effects = Effects {
                pattern: Pattern::Lambertian {
                    m: T::lit(nf.pattern_m as f64),
                },
                gain: nf.cell_gains(),
                bias: nf.cell_biases(),
                ..Effects::default()
            };
            // The LEDs' boresight is set per pass from the attitude (rows): none here.
            self.emulator = Some(Emulator::with_led_boresight(
                head,
                head_pose,
                effects,
                &Vector3::new(T::zero(), T::zero(), -T::one()),
            ));
        }
        for (i, b) in con.beacons.iter().enumerate() {
            // Cannot overflow: both hold MAX_BEACONS.
            let _ = self.beacons.push((b.id, v3(&b.r)));
            self.ln_brightness[i] = T::lit(b.brightness as f64).ln();
        }
        let noise = T::lit(cal.noise as f64);
        if let (Some(m), true, ModelKind::NearField) =
            (&cal.magnitude, settings.magnitudes, settings.model)
        {
            self.mag = Some(MagSolve::new(m, noise));
        }
        // Cannot overflow: the noise is at most 10,000 counts (validated).
        self.rail = i32::from(RAIL) - (RAIL_SIGMAS * cal.noise) as i32;
        let n = T::lit(self.beacons.len() as f64);
        let centroid = self
            .beacons
            .iter()
            .fold(Vector3::zeros(), |c, (_, r)| c + r / n);
        let radius = self
            .beacons
            .iter()
            .fold(T::zero(), |m, (_, r)| m.max((r - centroid).norm()));
        self.centroid_offset = centroid.norm();
        let far = self.centroid_offset
            + radius * T::lit(cal.h as f64) / (T::lit(FAR_SIGMAS as f64) * noise);
        self.max_range2 = far * far;
        let fraction = T::lit(settings.max_sigma_fraction);
        self.max_sigma_fraction2 = fraction * fraction;
        self.max_condition = T::lit(settings.max_condition);
        self.max_rms = T::lit(settings.max_rms);
        self.settings = settings;
        self.cal = params;
        self.lin = Linearisation::new(&params);
        self.boresight = v3::<T>(&con.boresight).normalize();
        self.head_axis = mrp::dcm(&eye.p).row(2).transpose();
        self.noise2 = noise * noise;
        Ok(())
    }

    /// The settings in use.
    pub fn settings(&self) -> &SolverSettings {
        &self.settings
    }

    /// Forget the warm start (the next solve cold-starts).
    pub fn reset(&mut self) {
        self.warm = None;
        self.carry = None;
    }

    /// Set the warm start explicitly (position in inches, MRP). The linearisation carried
    /// from the last solve is dropped.
    pub fn set_warm_start(&mut self, position: Vector3<T>, mrp: Vector3<T>) {
        self.carry = None;
        self.warm = Some(SVector::<T, 6>::new(
            position.x, position.y, position.z, mrp.x, mrp.y, mrp.z,
        ));
    }

    /// The warm start, if any.
    pub fn warm_start(&self) -> Option<(Vector3<T>, Vector3<T>)> {
        self.warm.map(|x| {
            (
                Vector3::new(x[0], x[1], x[2]),
                Vector3::new(x[3], x[4], x[5]),
            )
        })
    }

    /// Match spots to beacons by ID (first spot of each ID). Coordinates at or within
    /// [`RAIL_SIGMAS`] noise sigmas of the 16-bit rails are marked unused; a spot with both
    /// there is skipped. With a magnitude model in use, each spot's magnitude is weighed
    /// ([`Obs::m`], [`Obs::mw`]); a saturated or too weak one is not used.
    pub fn match_spots(&self, spots: &[Spot]) -> Vec<Obs<T>, MAX_BEACONS> {
        let mut obs = Vec::new();
        self.match_keyed(spots, &mut obs, true);
        obs
    }

    /// [`Self::match_spots`] into `obs` (cleared first; filled in place, no copy of 480
    /// bytes on the chip's stack), the magnitudes only when `magnitudes`, returning which
    /// coordinates of which beacons were used: bits `2i` (X) and `2i + 1` (Y) for beacon `i`
    /// of the constellation, and bit `2 MAX_BEACONS + i` for its magnitude.
    fn match_keyed(
        &self,
        spots: &[Spot],
        obs: &mut Vec<Obs<T>, MAX_BEACONS>,
        magnitudes: bool,
    ) -> u64 {
        obs.clear();
        let mut key = 0u64;
        let mag = self.mag.as_ref().filter(|_| magnitudes);
        for (i, (id, r)) in self.beacons.iter().enumerate() {
            let spot = spots.iter().find(|s| s.id == *id);
            if let Some(s) = spot {
                let rail = |v: i16| i32::from(v).abs() >= self.rail;
                let used = [!rail(s.x), !rail(s.y)];
                if !(used[0] || used[1]) {
                    continue;
                }
                key |= (u64::from(used[0]) | u64::from(used[1]) << 1) << (2 * i);
                let (m, mw) = match mag.and_then(|g| g.reading(s.magnitude, self.ln_brightness[i]))
                {
                    Some(mw) => {
                        key |= 1 << (2 * MAX_BEACONS + i);
                        mw
                    }
                    None => (T::zero(), T::zero()),
                };
                let _ = obs.push(Obs {
                    // Element by element: a copy of the whole vector here is a `memmove` on
                    // the chip (1.6 KB of flash).
                    r: Vector3::new(r.x, r.y, r.z),
                    y: [T::lit(s.x as f64), T::lit(s.y as f64)],
                    used,
                    m,
                    mw,
                });
            }
        }
        key
    }

    /// The documented cold start: `q = 0` and `t` from the linear pinhole lines of sight.
    pub fn cold_start(&self, obs: &[Obs<T>]) -> Option<SVector<T, 6>> {
        let d = Vector3::new(self.cal[0], self.cal[1], self.cal[2]);
        let ct = mrp::dcm(&Vector3::new(self.cal[3], self.cal[4], self.cal[5])).transpose();
        let h = self.cal.h();
        let mut a = Matrix3::<T>::zeros();
        let mut b = Vector3::<T>::zeros();
        // Whole spots only: a railed coordinate gives no line of sight.
        for o in obs.iter().filter(|o| o.rows() == 2) {
            let u = (ct * Vector3::new(o.y[0] / h, o.y[1] / h, T::one())).normalize();
            // (t + r - d) x u = 0  <=>  [u x] t = (r - d) x u.
            let s = mrp::skew(&u);
            let st = s.transpose();
            a += st * s;
            b += st * (o.r - d).cross(&u);
        }
        let t = a.cholesky()?.solve(&b);
        let x = SVector::<T, 6>::new(t.x, t.y, t.z, T::zero(), T::zero(), T::zero());
        if !(t.iter().all(|v| v.is_finite()) && self.in_front(&x, obs)) {
            return None;
        }
        Some(x)
    }

    /// Solve for the pose from one frame of spots (with their magnitudes when the
    /// calibration has a magnitude model, whatever the frame's sensitivity: see
    /// [`Self::solve_frame`]).
    pub fn solve(&mut self, spots: &[Spot]) -> PoseSolution<T> {
        let mut obs = Vec::new();
        let key = self.match_keyed(spots, &mut obs, true);
        self.solve_carried(&mut obs, key)
    }

    /// [`Self::solve`] for a frame the NorthStar reported at light-sensitivity setting
    /// `sensitivity`: the magnitudes are used only at the setting their law was fitted at
    /// ([`Magnitude::sensitivity`]); at another, the spots alone.
    pub fn solve_frame(&mut self, spots: &[Spot], sensitivity: u8) -> PoseSolution<T> {
        let mut obs = Vec::new();
        let same = self
            .mag
            .as_ref()
            .is_some_and(|m| m.sensitivity == sensitivity);
        let key = self.match_keyed(spots, &mut obs, same);
        self.solve_carried(&mut obs, key)
    }

    /// [`Self::solve_keyed`] for matched spots: where the last linearisation will be carried
    /// (a warm start, the same beacons, coordinates and magnitudes in view), the magnitudes
    /// keep that linearisation's weights, so that its rows still hold for them (their weights
    /// follow each reading's rounding term, which moves a little from frame to frame: a step
    /// from rows of other weights misses, and costs another Jacobian pass). The weights
    /// used are kept for the next frame.
    fn solve_carried(&mut self, obs: &mut [Obs<T>], key: u64) -> PoseSolution<T> {
        if self.warm.is_some() && self.carry.is_some() && key == self.carry_key {
            for (o, w) in obs.iter_mut().zip(&self.carry_mw) {
                if o.magnitude_used() {
                    o.mw = *w;
                }
            }
        }
        let sol = self.solve_keyed(obs, Some(key));
        for (w, o) in self.carry_mw.iter_mut().zip(obs.iter()) {
            *w = o.mw;
        }
        sol
    }

    /// Solve for the pose from matched observations (without the linearisation carried
    /// from the last solve: which beacons these are is not known).
    pub fn solve_obs(&mut self, obs: &[Obs<T>]) -> PoseSolution<T> {
        self.solve_keyed(obs, None)
    }

    /// Solve; `key` names the observations' beacons and coordinates (see
    /// [`Self::match_keyed`]). With magnitudes, a solve that fails or whose residual RMS
    /// exceeds [`MAGNITUDE_RMS_SIGMAS`] noise sigmas is done again from the spots alone
    /// (from the same start), and that answer is reported.
    fn solve_keyed(&mut self, obs: &[Obs<T>], key: Option<u64>) -> PoseSolution<T> {
        let warm = self.warm;
        let sol = self.solve_once(obs, key, true);
        if sol.magnitudes == 0 {
            return sol;
        }
        let limit = T::lit(MAGNITUDE_RMS_SIGMAS as f64);
        if sol.status == PoseStatus::Ok && sol.rms * sol.rms <= limit * limit * self.noise2 {
            return sol;
        }
        self.warm = warm;
        self.carry = None;
        // The spots' rows alone: the key without the magnitudes' bits.
        let spots_only = key.map(|k| k & ((1u64 << (2 * MAX_BEACONS)) - 1));
        self.solve_once(obs, spots_only, false)
    }

    /// One solve (see [`Self::solve_keyed`]), with the magnitudes when `magnitudes`. The
    /// last solve's linearisation serves the first step when the warm start is in use and
    /// the key is the same: no model evaluation when the warm start is that solve's answer,
    /// else one pass without the Jacobian.
    // Never inlined: on the chip its frame (the solve's matrices) is its own, not added to
    // the caller's (the board's reply being built).
    #[inline(never)]
    fn solve_once(
        &mut self,
        obs: &[Obs<T>],
        key: Option<u64>,
        magnitudes: bool,
    ) -> PoseSolution<T> {
        // The carried linearisation serves only a warm start on the same beacons. It is
        // handed to the solver in place (a copy would be another 400 bytes of stack).
        if !(self.warm.is_some() && key == Some(self.carry_key)) {
            self.carry = None;
        }
        let fallback = self.warm.unwrap_or_else(SVector::zeros);
        let n = obs.len() as u8;
        let rows: usize = obs.iter().map(|o| o.rows()).sum();
        if obs.len() < MIN_BEACONS || rows < 2 * MIN_BEACONS {
            return failed(PoseStatus::TooFewBeacons, fallback, n, 0, false);
        }
        let (x0, cold) = match self.warm {
            Some(x) => (x, false),
            None => match self.cold_start(obs) {
                Some(x) => (x, true),
                None => return failed(PoseStatus::Diverged, fallback, n, 0, true),
            },
        };
        let eps = T::default_epsilon();
        // The limits in T: no double-precision arithmetic (a soft-float library of its own)
        // on the chip.
        let (max_condition, max_rms) = (self.max_condition, self.max_rms);
        let settings = Settings {
            max_iter: self.settings.max_iter,
            step_tol: eps.sqrt() * T::lit(0.1),
            cost_tol: eps.sqrt() * T::lit(0.01),
            weights_absolute: false,
            rank_tol: T::one() / (max_condition * max_condition),
            max_damping: 12,
            // The weights are 1, so sum r^2 / noise^2 is chi-square: a step worth less than
            // 0.01 of it is far below the noise and not worth another pass.
            cost_abs_tol: T::lit(0.01) * self.noise2,
            // A last step worth less than 0.1 of chi-square (0.3 standard deviations) is
            // taken as predicted, without another pass.
            final_step_tol: T::lit(0.1) * self.noise2,
            // The condition is compared with max_condition: its cheap upper bound is enough
            // (conservative by at most sqrt(6)) and saves eigen iterations on the chip.
            exact_condition: false,
            // Analytic Jacobians and a warm start: trial steps are almost always accepted.
            jacobian_in_trial: true,
        };
        let problem = PoseProblem {
            lin: &self.lin,
            emulator: self.emulator.as_ref(),
            boresight: self.boresight,
            obs,
            magnitudes,
        };
        let result = glsdc::solve_with(&problem, x0, &settings, &mut self.rows, &mut self.carry);
        match key {
            Some(k) => self.carry_key = k,
            None => self.carry = None,
        }
        match result {
            Ok(sol) => {
                let x = canonical(sol.x);
                // The plausibility gate: a range beyond the constellation's far limit, or a
                // position 1-sigma over `max_sigma_fraction` of the range (the norms; the
                // range bounded above by `|t|` plus the centroid's offset), is never Ok.
                // Written so that a NaN sigma fails it; the square root only when `|t|`
                // alone does not pass it.
                let range2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
                let sigma2 = sol.sigma[0] * sol.sigma[0]
                    + sol.sigma[1] * sol.sigma[1]
                    + sol.sigma[2] * sol.sigma[2];
                let f2 = self.max_sigma_fraction2;
                let c = self.centroid_offset;
                let determined = sigma2 <= f2 * range2
                    || (c > T::zero() && {
                        let r = range2.sqrt() + c;
                        sigma2 <= f2 * r * r
                    });
                let status = if !x.iter().all(|v| v.is_finite()) {
                    return self.fail(PoseStatus::Diverged, x0, n, sol.iterations, cold);
                } else if !self.in_front(&x, obs) || sol.rms > max_rms || range2 > self.max_range2 {
                    return self.fail(PoseStatus::Diverged, x, n, sol.iterations, cold);
                } else if sol.condition > max_condition || !determined {
                    PoseStatus::IllConditioned
                } else {
                    PoseStatus::Ok
                };
                if status == PoseStatus::Ok {
                    self.warm = Some(x);
                }
                let att = |i: usize| deg(T::lit(4.0) * sol.sigma[i]);
                PoseSolution {
                    status,
                    position: Vector3::new(x[0], x[1], x[2]),
                    mrp: Vector3::new(x[3], x[4], x[5]),
                    sigma_position: Vector3::new(sol.sigma[0], sol.sigma[1], sol.sigma[2]),
                    sigma_attitude_deg: Vector3::new(att(3), att(4), att(5)),
                    rms: sol.rms,
                    iterations: sol.iterations.min(255) as u8,
                    beacons: n,
                    magnitudes: problem.magnitudes_fitted(),
                    condition: sol.condition,
                    cold_start: cold,
                }
            }
            Err(glsdc::Error::RankDeficient { x, .. }) => {
                let x = if x.iter().all(|v| v.is_finite()) {
                    x
                } else {
                    x0
                };
                failed(PoseStatus::IllConditioned, canonical(x), n, 0, cold)
            }
            Err(glsdc::Error::NotConverged { x, iterations, .. }) => {
                let x = if x.iter().all(|v| v.is_finite()) {
                    x
                } else {
                    x0
                };
                self.fail(PoseStatus::Diverged, canonical(x), n, iterations, cold)
            }
            Err(_) => self.fail(PoseStatus::Diverged, x0, n, 0, cold),
        }
    }

    fn fail(
        &mut self,
        status: PoseStatus,
        x: SVector<T, 6>,
        n: u8,
        iterations: usize,
        cold: bool,
    ) -> PoseSolution<T> {
        self.warm = None;
        failed(status, x, n, iterations, cold)
    }

    /// Every beacon in front of the head (positive depth along the head's boresight): with
    /// `a` the head's boresight in N (third row of `C(p)`), `a . (t + C(q)^T r_T - d) > 0`,
    /// evaluated as `(C(q) a) . r_T + a . (t - d)`.
    fn in_front(&self, x: &SVector<T, 6>, obs: &[Obs<T>]) -> bool {
        let a = self.head_axis;
        let u = mrp::dcm(&Vector3::new(x[3], x[4], x[5])) * a;
        let d = Vector3::new(self.cal[0], self.cal[1], self.cal[2]);
        let k = a.dot(&(Vector3::new(x[0], x[1], x[2]) - d));
        obs.iter().all(|o| u.dot(&o.r) + k > T::zero())
    }

    /// Predicted `(X, Y)` for a beacon at `r_T` with the target at `x = [t, q]`.
    pub fn predict(&self, x: &SVector<T, 6>, r_t: &Vector3<T>) -> Option<[T; 2]> {
        let (t, ct) = split(x);
        let rn = t + ct * r_t;
        match &self.emulator {
            None => self.lin.eval(&rn).map(|(y, _)| y),
            Some(em) => em.with_boresight(&(ct * self.boresight)).output(&rn),
        }
    }
}

/// The magnitudes a solve of `obs` fits: those used, when at least two are (one alone
/// carries nothing: the frame's scale is unknown).
fn magnitudes_fitted<T: Real>(obs: &[Obs<T>]) -> u8 {
    match obs.iter().filter(|o| o.magnitude_used()).count() {
        0 | 1 => 0,
        k => k as u8,
    }
}

/// The magnitude rows of a solve, built beacon by beacon as the weighted Helmert contrasts
/// of the magnitudes' residuals: the common scale `A` of [`Magnitude`] enters every
/// magnitude's `ln` as the same unknown constant, and is eliminated exactly by fitting the
/// residuals less their weighted mean. With `W` the weights so far and `rbar` the weighted
/// mean of the residuals so far, beacon `k` (weight `w`, residual `r`) gives the row
/// `f (r - rbar)`, `f = sqrt(w W / (W + w))` (none for the first), and then `W += w`,
/// `rbar += (w / W) (r - rbar)`; the Jacobian rows alike. The sum of the rows' squares is
/// `sum_i w_i (r_i - rbar)^2` (West's weighted update), so each row has unit weight, as the
/// spots' rows, and `k` magnitudes give `k - 1` rows: no running sum to hold back, the
/// degrees of freedom counted right.
struct Contrasts<T: Real> {
    w: T,
    r: T,
    j: [T; 6],
}

impl<T: Real> Contrasts<T> {
    fn new() -> Self {
        Contrasts {
            w: T::zero(),
            r: T::zero(),
            j: [T::zero(); 6],
        }
    }

    /// Add one magnitude (weight `w`, residual `r`, Jacobian row `j`, empty without the
    /// Jacobian); its contrast row, if any, goes to `sink`.
    fn add(&mut self, w: T, r: T, j: &[T], sink: &mut dyn FnMut(T, T, &[T])) {
        let total = self.w + w;
        let g = w / total;
        let first = self.w == T::zero();
        let f = if first {
            T::zero()
        } else {
            (w * self.w / total).sqrt()
        };
        let dr = r - self.r;
        self.r += g * dr;
        self.w = total;
        if j.is_empty() {
            if !first {
                sink(f * dr, T::one(), &[]);
            }
            return;
        }
        let mut row = [T::zero(); 6];
        for (i, (m, &ji)) in self.j.iter_mut().zip(j).enumerate() {
            let d = ji - *m;
            row[i] = f * d;
            *m += g * d;
        }
        if !first {
            sink(f * dr, T::one(), &row);
        }
    }
}

fn split<T: Real>(x: &SVector<T, 6>) -> (Vector3<T>, Matrix3<T>) {
    let t = Vector3::new(x[0], x[1], x[2]);
    let ct = mrp::dcm(&Vector3::new(x[3], x[4], x[5])).transpose();
    (t, ct)
}

fn canonical<T: Real>(mut x: SVector<T, 6>) -> SVector<T, 6> {
    let q = mrp::canonical(&Vector3::new(x[3], x[4], x[5]));
    x[3] = q.x;
    x[4] = q.y;
    x[5] = q.z;
    x
}

fn failed<T: Real>(
    status: PoseStatus,
    x: SVector<T, 6>,
    n: u8,
    iterations: usize,
    cold: bool,
) -> PoseSolution<T> {
    let m1 = Vector3::repeat(-T::one());
    PoseSolution {
        status,
        position: Vector3::new(x[0], x[1], x[2]),
        mrp: Vector3::new(x[3], x[4], x[5]),
        sigma_position: m1,
        sigma_attitude_deg: m1,
        rms: -T::one(),
        iterations: iterations.min(255) as u8,
        beacons: n,
        magnitudes: 0,
        condition: T::zero(),
        cold_start: cold,
    }
}

/// The pose as a GLSDC problem over `x = [t, q]`.
struct PoseProblem<'a, T: Real> {
    lin: &'a Linearisation<T>,
    emulator: Option<&'a Emulator<T>>,
    boresight: Vector3<T>,
    obs: &'a [Obs<T>],
    /// Fit the magnitudes the observations carry (near-field model only).
    magnitudes: bool,
}

/// The rows of spot `o`'s used coordinates, from the emulator's output `y` and its
/// gradients (see [`PoseProblem::rows`]).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn spot_rows<T: Real>(
    o: &Obs<T>,
    y: &[T; 2],
    dr: &[Vector3<T>; 2],
    de: &[Vector3<T>; 2],
    rho: &Vector3<T>,
    e: &Vector3<T>,
    k: &Matrix3<T>,
    sink: &mut dyn FnMut(T, T, &[T]),
) {
    for a in (0..2).filter(|&a| o.used[a]) {
        let dq = k * (rho.cross(&dr[a]) + e.cross(&de[a]));
        let row = [dr[a].x, dr[a].y, dr[a].z, dq.x, dq.y, dq.z];
        sink(o.y[a] - y[a], T::one(), &row);
    }
}

impl<'a, T: Real> PoseProblem<'a, T> {
    /// The magnitudes fitted (see [`magnitudes_fitted`]; none with the pinhole model).
    fn magnitudes_fitted(&self) -> u8 {
        if self.emulator.is_none() || !self.magnitudes {
            return 0;
        }
        magnitudes_fitted(self.obs)
    }

    /// The magnitude rows: one fewer than the magnitudes fitted.
    fn magnitude_rows(&self) -> usize {
        (self.magnitudes_fitted() as usize).saturating_sub(1)
    }

    /// Whether observation `o`'s magnitude is fitted.
    fn fits_magnitude(&self, o: &Obs<T>) -> bool {
        self.magnitudes && o.magnitude_used()
    }

    /// The problem of `obs` with the model of `s` (field by field: the solve keeps the
    /// solver's row store borrowed mutably beside it).
    #[cfg(test)]
    fn of(s: &'a PoseSolver<T>, obs: &'a [Obs<T>]) -> Self {
        PoseProblem {
            lin: &s.lin,
            emulator: s.emulator.as_ref(),
            boresight: s.boresight,
            obs,
            magnitudes: true,
        }
    }
}

const NAMES: [&str; 6] = ["t1", "t2", "t3", "q1", "q2", "q3"];

impl<T: Real> Problem<T> for PoseProblem<'_, T> {
    type D = U6;
    fn dim(&self) -> U6 {
        U6
    }
    fn n_rows(&self) -> usize {
        let spots: usize = self.obs.iter().map(|o| o.rows()).sum();
        spots + self.magnitude_rows()
    }
    fn rows(
        &self,
        x: &SVector<T, 6>,
        jac: bool,
        sink: &mut dyn FnMut(T, T, &[T]),
    ) -> Result<(), ModelError> {
        let s = self;
        // Unit weights (see the module documentation).
        let w = T::one();
        let q = Vector3::new(x[3], x[4], x[5]);
        let c = mrp::dcm(&q);
        let ct = c.transpose();
        let t = Vector3::new(x[0], x[1], x[2]);
        // Attitude columns by the chain rule through C(q): for r_N = t + C^T r_T,
        // dy/dq = K ((C^T r_T) x dy/dr) (mrp::gradient_map), and likewise for the boresight.
        let k = if jac {
            mrp::gradient_map(&q, &c)
        } else {
            Matrix3::zeros()
        };
        match s.emulator {
            None => {
                for o in self.obs {
                    let rho = ct * o.r;
                    let (y, g) = s.lin.eval_dr(&(t + rho)).ok_or(ModelError::NonFinite)?;
                    if !jac {
                        for a in (0..2).filter(|&a| o.used[a]) {
                            sink(o.y[a] - y[a], w, &[]);
                        }
                        continue;
                    }
                    for a in (0..2).filter(|&a| o.used[a]) {
                        let dq = k * rho.cross(&g[a]);
                        let row = [g[a].x, g[a].y, g[a].z, dq.x, dq.y, dq.z];
                        sink(o.y[a] - y[a], w, &row);
                    }
                }
            }
            Some(em) => {
                // The LEDs rotate with the target: boresight e_N = C^T(q) e_T.
                let e = ct * s.boresight;
                let em0 = em.with_boresight(&e);
                // The magnitudes' contrasts (see `Contrasts`), in counts as the spots' rows.
                let mut mags = Contrasts::new();
                if !jac {
                    for o in self.obs {
                        let rn = t + ct * o.r;
                        if !self.fits_magnitude(o) {
                            let y = em0.output(&rn).ok_or(ModelError::NoData)?;
                            for a in (0..2).filter(|&a| o.used[a]) {
                                sink(o.y[a] - y[a], w, &[]);
                            }
                            continue;
                        }
                        let (y, m) = em0.output_magnitude(&rn).ok_or(ModelError::NoData)?;
                        for a in (0..2).filter(|&a| o.used[a]) {
                            sink(o.y[a] - y[a], w, &[]);
                        }
                        mags.add(o.mw, o.m - m.ln(), &[], sink);
                    }
                    return Ok(());
                }
                // Analytic chain rule through the emulator's gradients:
                // dy/dt = dy/dr, dy/dq = K (rho x dy/dr + e_N x dy/de), rho = C^T r_T; the
                // magnitude's ln S likewise with d ln S = dS / S.
                for o in self.obs {
                    let rho = ct * o.r;
                    let rn = t + rho;
                    if !self.fits_magnitude(o) {
                        let (y, dr, de) = em0.output_gradient(&rn).ok_or(ModelError::NoData)?;
                        spot_rows(o, &y, &dr, &de, &rho, &e, &k, sink);
                        continue;
                    }
                    let (y, dr, de, (m, dmr, dme)) = em0
                        .output_magnitude_gradient(&rn)
                        .ok_or(ModelError::NoData)?;
                    spot_rows(o, &y, &dr, &de, &rho, &e, &k, sink);
                    let inv = T::one() / m;
                    let (dmr, dme) = (dmr * inv, dme * inv);
                    let dq = k * (rho.cross(&dmr) + e.cross(&dme));
                    let row = [dmr.x, dmr.y, dmr.z, dq.x, dq.y, dq.z];
                    mags.add(o.mw, o.m - m.ln(), &row, sink);
                }
            }
        }
        Ok(())
    }
    fn measurements(&self, sink: &mut dyn FnMut(T, T)) -> bool {
        let mut mags = Contrasts::new();
        for o in self.obs {
            for a in (0..2).filter(|&a| o.used[a]) {
                sink(o.y[a], T::one());
            }
            // The magnitudes' contrasts are linear in the measured m: the same contrasts of
            // the measurements (the model part is what the rows' residuals take off).
            if self.emulator.is_some() && self.fits_magnitude(o) {
                mags.add(o.mw, o.m, &[], &mut |y, w, _| sink(y, w));
            }
        }
        true
    }
    fn param_name(&self, i: usize, w: &mut dyn fmt::Write) -> fmt::Result {
        w.write_str(NAMES[i])
    }
}

/// Spots a NorthStar with the physics of `em` (the head on the board) would report for
/// the constellation at pose `(t, q)`: beacons whose both cell pairs see light, outputs
/// rounded and saturated to 16 bits, with `noise(k)` (counts) added to coordinate `k`
/// (0, 1 for the first spot, ...). The magnitude is the summed cell signal times the
/// beacon's brightness times [`SIM_MAGNITUDE_SCALE`] (a beacon 1 in away on boresight reads
/// about 60000), rounded and saturated to 16 bits, without noise (see
/// [`simulate_spots_with`]). Used by the simulated board, the accuracy table and the tests.
pub fn simulate_spots<T: Real>(
    em: &Emulator<T>,
    con: &Constellation,
    t: &Vector3<T>,
    q: &Vector3<T>,
    noise: impl FnMut(usize) -> T,
) -> Vec<Spot, MAX_BEACONS> {
    simulate_spots_with(em, con, t, q, noise, |_| T::zero())
}

/// [`simulate_spots`] with magnitude noise: spot `i`'s magnitude is multiplied by
/// `1 + mag_noise(i)` before it is rounded (a draw of its own, so the coordinates' noise is
/// as [`simulate_spots`] draws it).
pub fn simulate_spots_with<T: Real>(
    em: &Emulator<T>,
    con: &Constellation,
    t: &Vector3<T>,
    q: &Vector3<T>,
    mut noise: impl FnMut(usize) -> T,
    mut mag_noise: impl FnMut(usize) -> T,
) -> Vec<Spot, MAX_BEACONS> {
    let ct = mrp::dcm(q).transpose();
    let em = em.with_boresight(&(ct * v3::<T>(&con.boresight).normalize()));
    let mut out = Vec::new();
    for b in &con.beacons {
        let rn = t + ct * v3::<T>(&b.r);
        let Some(y) = em.output(&rn) else { continue };
        let k = out.len() * 2;
        let x = y[0] + noise(k);
        let yy = y[1] + noise(k + 1);
        let m = em.magnitude(&rn)
            * T::lit(SIM_MAGNITUDE_SCALE * b.brightness as f64)
            * (T::one() + mag_noise(out.len()));
        let mag = libm::round(m.to_f64().clamp(0.0, 65535.0)) as u16;
        let _ = out.push(Spot {
            id: b.id,
            x: crate::emulator::saturate_i16(x),
            y: crate::emulator::saturate_i16(yy),
            magnitude: mag,
        });
    }
    out
}

/// A flat constellation on the plate `z = 0` of T, LEDs along `-z` (the plate faces the
/// board): beacon `i` (channel `i`) at `(r[i][0], r[i][1], 0)` in; at most [`MAX_BEACONS`]
/// (more are left out).
pub fn flat_constellation(r: &[[f32; 2]]) -> Constellation {
    let mut beacons = Vec::new();
    for (i, r) in r.iter().take(MAX_BEACONS).enumerate() {
        // Cannot fail: at most MAX_BEACONS are taken.
        let _ = beacons.push(Beacon {
            id: i as u8,
            r: [r[0], r[1], 0.0],
            brightness: 1.0,
        });
    }
    Constellation {
        beacons,
        boresight: [0.0, 0.0, -1.0],
    }
}

/// A 10-beacon constellation on the CTA's 1 in grid (channels 0..=9): five beacons within
/// about 2 in of the centre (seen down to 2 in separation) and five out to 4.5 in (lever
/// arm at range). LEDs along `-z` of T (the plate faces the board).
pub fn cta_constellation() -> Constellation {
    const R: [[f32; 2]; 10] = [
        [-1.5, -0.5],
        [1.5, 0.5],
        [-0.5, 1.5],
        [0.5, -1.5],
        [0.5, 0.5],
        [-3.5, -2.5],
        [3.5, 2.5],
        [-2.5, 3.5],
        [2.5, -3.5],
        [4.5, -0.5],
    ];
    flat_constellation(&R)
}

/// All 20 NorthStar channel IDs spread over the CTA plate with four arrays in its quadrants
/// (LEDs at +/-1.5 .. +/-10.5 in; REFERENCE.md section 4): the first five are inner beacons
/// (seen from 2 in), the next five near the plate's edge (attitude at 8-10 in), then five
/// more inner and five more outer. Its first ten alone are the host's `four-10`. Channels 2
/// and 19 share 4050 Hz in the NorthStar table, so a detector cannot tell those two apart: the
/// host's built-in `four-19` (what `cta sensor floor` and `cta sensor accuracy` compare with
/// [`cta_constellation`]) leaves channel 19 out. This 20-beacon layout is the chip's
/// capacity, on which the QEMU harness counts a 20-beacon solve.
pub fn four_array_constellation() -> Constellation {
    const R: [[f32; 2]; 20] = [
        [-1.5, -2.5],
        [2.5, -1.5],
        [1.5, 2.5],
        [-2.5, 1.5],
        [1.5, 1.5],
        [-10.5, -3.5],
        [10.5, 3.5],
        [-3.5, 10.5],
        [3.5, -10.5],
        [8.5, -8.5],
        [-1.5, -1.5],
        [3.5, 2.5],
        [-3.5, -1.5],
        [2.5, -3.5],
        [-2.5, 3.5],
        [-8.5, 8.5],
        [10.5, 10.5],
        [-10.5, -10.5],
        [6.5, -5.5],
        [-6.5, 5.5],
    ];
    flat_constellation(&R)
}

/// The benchmark of the on-chip solve (QEMU instruction count and the f32-vs-f64 check):
/// the [`cta_constellation`] seen through the eq 63 physics by the Table 3 head, the target
/// at `t = (0.3, -0.2, 8.0)` in, rotated 3 deg about `(0.3, -0.5, 1.0)`; frame 2 after a
/// step of `(0.02, -0.01, 0.05)` in and 0.1 deg (a docking control loop at 50 Hz). Both
/// frames carry deterministic pseudo-random noise of 0.1 % of beta (uniform, same
/// variance as the Gaussian) and are rounded to counts, so every machine produces the same
/// integer spots. Returns `(frame1, frame2, true t2, true q2)`.
pub fn benchmark_frames() -> BenchmarkFrames {
    benchmark_frames_of(&cta_constellation())
}

/// Frame 1, frame 2, and the true position and MRP of frame 2.
pub type BenchmarkFrames = (
    Vec<Spot, MAX_BEACONS>,
    Vec<Spot, MAX_BEACONS>,
    Vector3<f64>,
    Vector3<f64>,
);

/// [`benchmark_frames`] for another constellation `con` (same poses, noise and rounding).
pub fn benchmark_frames_of(con: &Constellation) -> BenchmarkFrames {
    let cal = Calibration::table3();
    let em = Emulator::new(
        Head::northstar(),
        HeadPose {
            d: v3(&cal.d),
            p: v3(&cal.p),
        },
        Effects::default(),
    );
    let axis = Vector3::new(0.3, -0.5, 1.0);
    let t1 = Vector3::new(0.3, -0.2, 8.0);
    let q1 = mrp::from_axis_angle(&axis, rad(3.0));
    let t2 = t1 + Vector3::new(0.02, -0.01, 0.05);
    let q2 = mrp::from_axis_angle(&axis, rad(3.1));
    let mut seed = 0x2545_f491_u32;
    let sigma = 0.001 * crate::emulator::BETA;
    let mut noise = move |_| {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        // Uniform on [-sqrt(3), sqrt(3)] sigma: unit variance times sigma.
        ((seed as f64) / 4294967296.0 - 0.5) * 2.0 * 1.7320508075688772 * sigma
    };
    let f1 = simulate_spots(&em, con, &t1, &q1, &mut noise);
    let f2 = simulate_spots(&em, con, &t2, &q2, &mut noise);
    (f1, f2, t2, q2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic uniform numbers in [-0.5, 0.5) (xorshift32 from `seed`).
    pub(super) fn uniform_from(mut seed: u32) -> impl FnMut() -> f64 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f64 / 4294967296.0 - 0.5
        }
    }

    pub(super) fn truth_emulator() -> Emulator<f64> {
        let cal = Calibration::table3();
        let head_pose = HeadPose {
            d: v3(&cal.d),
            p: v3(&cal.p),
        };
        Emulator::new(Head::northstar(), head_pose, Effects::default())
    }

    fn target() -> (Vector3<f64>, Vector3<f64>) {
        (
            Vector3::new(0.3, -0.2, 8.0),
            mrp::from_axis_angle(&Vector3::new(0.3, -0.5, 1.0), rad(3.0)),
        )
    }

    #[test]
    fn validation_names_the_problem() {
        let mut con = cta_constellation();
        assert_eq!(con.validate(), Ok(()));
        con.beacons[3].id = 1;
        assert_eq!(con.validate(), Err(ConfigError::DuplicateId { id: 1 }));
        con.beacons.truncate(3);
        assert_eq!(
            con.validate(),
            Err(ConfigError::TooFewBeacons { count: 3, min: 4 })
        );
        let mut cal = Calibration::table3();
        cal.h = f32::NAN;
        assert_eq!(
            cal.validate(),
            Err(ConfigError::CalibrationOutOfRange { field: CalField::H })
        );
        cal = Calibration::table3();
        cal.near_field.as_mut().unwrap().alpha_deg = 90.0;
        assert_eq!(
            cal.validate(),
            Err(ConfigError::CalibrationOutOfRange {
                field: CalField::Alpha
            })
        );
        cal = Calibration::table3();
        cal.near_field.as_mut().unwrap().gain = [0.1, -0.6];
        assert_eq!(
            cal.validate(),
            Err(ConfigError::CalibrationOutOfRange {
                field: CalField::Gain
            })
        );
        cal = Calibration::table3();
        cal.near_field.as_mut().unwrap().alpha_y_deg = Some(4.0);
        assert_eq!(
            cal.validate(),
            Err(ConfigError::CalibrationOutOfRange {
                field: CalField::Alpha
            })
        );
        cal = Calibration::table3();
        cal.near_field.as_mut().unwrap().bias = [0.02, 0.0];
        assert_eq!(
            cal.validate(),
            Err(ConfigError::CalibrationOutOfRange {
                field: CalField::Bias
            })
        );
        // The pinhole head is checked as the head is, and named as its own.
        cal = Calibration {
            pinhole: Some(PinholeHead {
                d: [0.6, 0.1, 1.1],
                p: [0.0; 3],
            }),
            ..Calibration::table3()
        };
        assert_eq!(cal.validate(), Ok(()));
        cal.pinhole.as_mut().unwrap().d[2] = f32::NAN;
        let e = cal.validate().unwrap_err();
        assert_eq!(
            e,
            ConfigError::CalibrationOutOfRange {
                field: CalField::PinholeD
            }
        );
        assert!(e.to_string().contains("pinhole d ("), "{e}");
        cal.pinhole.as_mut().unwrap().d[2] = 1.1;
        cal.pinhole.as_mut().unwrap().p = [0.8, 0.8, 0.0];
        let e = cal.validate().unwrap_err();
        assert_eq!(
            e,
            ConfigError::CalibrationOutOfRange {
                field: CalField::PinholeP
            }
        );
        assert!(e.to_string().contains("pinhole p ("), "{e}");
    }

    /// Solve a noise-free frame at `t` of a head whose cells have `truth`'s face angles,
    /// gains and offsets, once with `truth` as the calibration and once with the nominal one:
    /// the position error with it must stay below `with_max` inches, the one without must be
    /// over 0.01 in and `factor` times larger.
    fn reaches_the_solver(truth: NearField, t: Vector3<f64>, with_max: f64, factor: f64) {
        let cal = Calibration {
            near_field: Some(truth),
            ..Calibration::table3()
        };
        let [ax, ay] = truth.face_angles_deg().map(|a| rad(a as f64));
        let em = Emulator::new(
            Head {
                alpha_x: ax,
                alpha_y: ay,
                ..Head::northstar()
            },
            HeadPose {
                d: v3(&cal.d),
                p: v3(&cal.p),
            },
            Effects {
                gain: truth.cell_gains(),
                bias: truth.cell_biases(),
                ..Effects::default()
            },
        );
        let con = cta_constellation();
        let (_, q) = target();
        let spots = simulate_spots(&em, &con, &t, &q, |_| 0.0);
        let settings = SolverSettings {
            model: ModelKind::NearField,
            ..Default::default()
        };
        let error = |cal: &Calibration| {
            let sol = PoseSolver::<f64>::new(cal, &con, settings)
                .unwrap()
                .solve(&spots);
            assert_eq!(sol.status, PoseStatus::Ok, "{sol:?}");
            (sol.position - t).norm()
        };
        let (with, without) = (error(&cal), error(&Calibration::table3()));
        assert!(with < with_max, "{with}");
        assert!(
            without > factor * with && without > 0.01,
            "{without} vs {with}"
        );
    }

    /// The calibration's cell gains reach the near-field model: frames of a head whose cell 1
    /// reads 3 % high and cell 3 2 % low are solved to rounding level with those gains in the
    /// calibration, and miss by far more without them.
    #[test]
    fn cell_gains_reach_the_solver() {
        let truth = NearField {
            gain: [0.03, -0.02],
            ..NearField::nominal()
        };
        reaches_the_solver(truth, target().0, 2e-4, 50.0);
    }

    /// The calibration's cell offsets reach the near-field model: at 20 in, where a beacon's
    /// signal is about 0.0025/in^2, offsets of 2e-5 and -1e-5/in^2 (under 1 % of it) are
    /// solved to rounding level with them in the calibration, and miss by far more without.
    #[test]
    fn cell_biases_reach_the_solver() {
        let truth = NearField {
            bias: [2e-5, -1e-5],
            ..NearField::nominal()
        };
        reaches_the_solver(truth, Vector3::new(0.3, -0.2, 20.0), 2e-3, 20.0);
    }

    /// The Y pair's own face angle reaches the near-field model: a head whose Y pair is cut at
    /// 31 deg (the X pair at 30) is solved to rounding level with it in the calibration, and
    /// misses by far more without it.
    #[test]
    fn pair_face_angles_reach_the_solver() {
        let truth = NearField {
            alpha_y_deg: Some(31.0),
            ..NearField::nominal()
        };
        reaches_the_solver(truth, target().0, 2e-4, 50.0);
    }

    #[test]
    fn jacobians_match_finite_differences() {
        for model in [ModelKind::Pinhole, ModelKind::NearField] {
            jacobian_matches_finite_differences(model);
        }
    }

    fn jacobian_matches_finite_differences(model: ModelKind) {
        let cal = Calibration::table3();
        let mut con = cta_constellation();
        // A boresight off the plate normal, so its rotation with the target is exercised.
        con.boresight = [0.1, -0.2, -1.0];
        let settings = SolverSettings {
            model,
            ..Default::default()
        };
        let s = PoseSolver::<f64>::new(&cal, &con, settings).unwrap();
        let obs: [Obs<f64>; 2] = [
            Obs::new(Vector3::new(1.0, 2.0, 0.0), [0.0; 2]),
            Obs::new(Vector3::new(-2.0, 0.5, 0.3), [0.0; 2]),
        ];
        let p = PoseProblem::of(&s, &obs);
        let (t, q) = target();
        let x = SVector::<f64, 6>::new(t.x, t.y, t.z, q.x, q.y, q.z);
        check_jacobian(&p, &x, &format!("{model:?}"));
    }

    /// Every row's analytic Jacobian against central differences of the rows' residuals
    /// at `x`; returns the rows (residual, Jacobian row).
    pub(super) fn check_jacobian(
        p: &PoseProblem<'_, f64>,
        x: &SVector<f64, 6>,
        label: &str,
    ) -> std::vec::Vec<(f64, std::vec::Vec<f64>)> {
        let mut rows = std::vec::Vec::new();
        p.rows(x, true, &mut |r, _, j| rows.push((r, j.to_vec())))
            .unwrap();
        for k in 0..6 {
            let h = 1e-6;
            let (mut xp, mut xm) = (*x, *x);
            xp[k] += h;
            xm[k] -= h;
            let mut rp = std::vec::Vec::new();
            let mut rm = std::vec::Vec::new();
            p.rows(&xp, false, &mut |r, _, _| rp.push(r)).unwrap();
            p.rows(&xm, false, &mut |r, _, _| rm.push(r)).unwrap();
            for i in 0..rows.len() {
                // residual = y - f, so df/dx = -(r+ - r-)/2h.
                let fd = -(rp[i] - rm[i]) / (2.0 * h);
                let an = rows[i].1[k];
                assert!(
                    (fd - an).abs() < 1e-4 * (1.0 + an.abs()),
                    "{label}: row {i} x{k}: {fd} {an}"
                );
            }
        }
        rows
    }

    fn solve_case<T: Real>(
        model: ModelKind,
        noise: f64,
    ) -> (PoseSolution<T>, Vector3<f64>, Vector3<f64>) {
        let em = truth_emulator();
        let con = cta_constellation();
        let (t, q) = target();
        let mut seed = 12345u32;
        let spots = simulate_spots(&em, &con, &t, &q, |_| {
            seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
            noise * ((seed >> 8) as f64 / (1u32 << 24) as f64 - 0.5) * 3.46
        });
        let settings = SolverSettings {
            model,
            ..Default::default()
        };
        let mut s = PoseSolver::<T>::new(&Calibration::table3(), &con, settings).unwrap();
        (s.solve(&spots), t, q)
    }

    #[test]
    fn near_field_cold_start_recovers_pose_f64_and_f32() {
        let (sol, t, q) = solve_case::<f64>(ModelKind::NearField, 0.0);
        assert_eq!(sol.status, PoseStatus::Ok, "{sol:?}");
        assert!(sol.cold_start);
        // Only the rounding of the outputs to whole counts perturbs the data.
        assert!((sol.position - t).norm() < 2e-4, "{sol:?}");
        assert!((sol.mrp - q).norm() < 1e-4, "{sol:?}");
        let (sol, t, q) = solve_case::<f32>(ModelKind::NearField, 0.0);
        assert_eq!(sol.status, PoseStatus::Ok, "{sol:?}");
        let p = Vector3::new(
            sol.position.x as f64,
            sol.position.y as f64,
            sol.position.z as f64,
        );
        let m = Vector3::new(sol.mrp.x as f64, sol.mrp.y as f64, sol.mrp.z as f64);
        assert!((p - t).norm() < 2e-3, "{sol:?}");
        assert!((m - q).norm() < 1e-4, "{sol:?}");
    }

    /// A calibration's pinhole head (the eq 65 fit's own eye point, about 1 in above the
    /// head) is what the pinhole model solves with; the near-field model ignores it. Spots
    /// of the pinhole model with that eye at 12 in: solved exactly with it, and 1 in short
    /// with the head's `d, p` (the file `cta calibrate` wrote before it held the eye).
    #[test]
    fn pinhole_head_is_the_pinhole_models_eye() {
        let con = cta_constellation();
        let pinhole = SolverSettings {
            model: ModelKind::Pinhole,
            ..Default::default()
        };
        let eye = PinholeHead {
            d: [0.61, 0.09, 1.14],
            p: [0.0015, 0.0025, 0.0008],
        };
        let as_head = Calibration {
            d: eye.d,
            p: eye.p,
            ..Calibration::table3()
        };
        let truth = PoseSolver::<f64>::new(&as_head, &con, pinhole).unwrap();
        let (_, q) = target();
        let t = Vector3::new(0.3, -0.2, 12.0);
        let x = SVector::<f64, 6>::new(t.x, t.y, t.z, q.x, q.y, q.z);
        let spots: std::vec::Vec<Spot> = con
            .beacons
            .iter()
            .map(|b| {
                let y = truth.predict(&x, &v3(&b.r)).unwrap();
                Spot {
                    id: b.id,
                    x: y[0].round() as i16,
                    y: y[1].round() as i16,
                    magnitude: 9000,
                }
            })
            .collect();
        let with = Calibration {
            pinhole: Some(eye),
            ..Calibration::table3()
        };
        let sol = PoseSolver::<f64>::new(&with, &con, pinhole)
            .unwrap()
            .solve(&spots);
        assert_eq!(sol.status, PoseStatus::Ok, "{sol:?}");
        assert!((sol.position - t).norm() < 2e-3, "{sol:?}");
        let without = PoseSolver::<f64>::new(&Calibration::table3(), &con, pinhole)
            .unwrap()
            .solve(&spots);
        assert!(t.z - without.position.z > 0.9, "{without:?}");
        // The near-field model solves with the head: the pinhole head changes nothing.
        let em = truth_emulator();
        let nf_spots = simulate_spots(&em, &con, &t, &q, |_| 0.0);
        let nf = |cal: &Calibration| {
            PoseSolver::<f64>::new(cal, &con, SolverSettings::default())
                .unwrap()
                .solve(&nf_spots)
        };
        assert_eq!(nf(&with), nf(&Calibration::table3()));
    }

    #[test]
    fn pinhole_is_biased_in_the_near_field() {
        let (nf, t, _) = solve_case::<f64>(ModelKind::NearField, 30.0);
        let (ph, _, _) = solve_case::<f64>(ModelKind::Pinhole, 30.0);
        assert_eq!(nf.status, PoseStatus::Ok);
        assert!((ph.position - t).norm() > 3.0 * (nf.position - t).norm());
        assert!(nf.sigma_position.iter().all(|s| *s > 0.0));
    }

    #[test]
    fn too_few_beacons_and_warm_start() {
        let em = truth_emulator();
        let con = cta_constellation();
        let (t, q) = target();
        let spots = simulate_spots(&em, &con, &t, &q, |_| 0.0);
        let mut s = PoseSolver::<f32>::new(&Calibration::table3(), &con, SolverSettings::default())
            .unwrap();
        let sol = s.solve(&spots[..3]);
        assert_eq!(sol.status, PoseStatus::TooFewBeacons);
        assert!(sol.position.iter().all(|v| v.is_finite()));
        let first = s.solve(&spots);
        assert!(first.cold_start && first.status == PoseStatus::Ok);
        let second = s.solve(&spots);
        assert!(!second.cold_start && second.status == PoseStatus::Ok);
        assert!(second.iterations <= first.iterations);
    }

    /// At 2 in the outer beacons put a cell in the dark: that coordinate sits on the rail
    /// (+/-beta) and is dropped, the other one is used. The pose from the remaining rows is
    /// exact on a noise-free frame, and four spots that give fewer than 8 usable coordinates
    /// are too few.
    #[test]
    fn railed_coordinates_are_dropped_and_the_rest_used() {
        let em = truth_emulator();
        let con = cta_constellation();
        let t = Vector3::new(0.2, -0.1, 2.0);
        let q = mrp::from_axis_angle(&Vector3::new(0.3, -0.5, 1.0), rad(2.0));
        let spots = simulate_spots(&em, &con, &t, &q, |_| 0.0);
        // At or within 3 sigma (98 counts) of the rail.
        let rail = |v: i16| i32::from(v).abs() >= 32767 - 98;
        let half = spots.iter().filter(|s| rail(s.x) != rail(s.y)).count();
        assert!(half >= 2, "the test needs half-railed spots: {spots:?}");
        let mut s = PoseSolver::<f64>::new(&Calibration::table3(), &con, SolverSettings::default())
            .unwrap();
        let obs = s.match_spots(&spots);
        assert_eq!(
            obs.iter().filter(|o| o.rows() == 1).count(),
            half,
            "{obs:?}"
        );
        let sol = s.solve_obs(&obs);
        assert_eq!(sol.status, PoseStatus::Ok, "{sol:?}");
        assert_eq!(sol.beacons as usize, obs.len());
        assert!((sol.position - t).norm() < 1e-4, "{sol:?}");
        assert!((sol.mrp - q).norm() < 1e-5, "{sol:?}");
        // A railed coordinate that was used would pull the pose: move it far off and the
        // answer must not change.
        let mut moved = obs.clone();
        for o in moved.iter_mut().filter(|o| o.rows() == 1) {
            for a in 0..2 {
                if !o.used[a] {
                    o.y[a] = -o.y[a];
                }
            }
        }
        let mut s2 =
            PoseSolver::<f64>::new(&Calibration::table3(), &con, SolverSettings::default())
                .unwrap();
        let sol2 = s2.solve_obs(&moved);
        assert!((sol2.position - sol.position).norm() < 1e-9, "{sol2:?}");
        // Eight usable coordinates are needed (four whole spots' worth): three whole spots
        // and one half are too few, three whole and two halves are enough.
        let whole: std::vec::Vec<Obs<f64>> =
            obs.iter().filter(|o| o.rows() == 2).copied().collect();
        let halves: std::vec::Vec<Obs<f64>> =
            obs.iter().filter(|o| o.rows() == 1).copied().collect();
        let mut few: std::vec::Vec<Obs<f64>> = whole[..3].to_vec();
        few.push(halves[0]);
        assert_eq!(s2.solve_obs(&few).status, PoseStatus::TooFewBeacons);
        few.push(halves[1]);
        let mut s3 =
            PoseSolver::<f64>::new(&Calibration::table3(), &con, SolverSettings::default())
                .unwrap();
        assert_eq!(s3.solve_obs(&few).status, PoseStatus::Ok);
    }

    /// At 30 in the one-array target's attitude is barely observed (floor ~4 deg): the cost
    /// valley is flat and curved on the scale of one sigma, and Gauss-Newton zig-zags
    /// across it (successive steps of ~2 deg in opposite directions, each gaining a few
    /// hundredths of chi-square). About 1 frame in 400 once ran out of its 20 iterations
    /// within a fraction of a sigma of the minimum and was reported Diverged (7 pinhole and 8
    /// near-field of these 3000); stopping on a step that gains less than 0.01 left 0 and 2.
    /// Now the Gauss-Newton step's predicted gain is checked whatever the damping, and a step
    /// that gains less than a quarter of its prediction keeps the damping on (the gain ratio
    /// rule, in `glsdc`): none fails, and no frame needs more than 12 iterations (9 and 10 here; 17-20
    /// before).
    #[test]
    fn flat_valley_at_30_in_converges() {
        let em = truth_emulator();
        let con = cta_constellation();
        let mut uniform = uniform_from(0x9e37_79b9);
        let sigma = 0.001 * crate::emulator::BETA;
        let mut failed = [0usize; 2];
        let mut most = [0u8; 2];
        for _ in 0..3000 {
            let t = Vector3::new(uniform(), uniform(), 30.0);
            let axis = Vector3::new(uniform(), uniform(), uniform());
            let q = mrp::from_axis_angle(&axis, rad(3.0 * (uniform() + 0.5)));
            // Uniform noise of the same variance as the Gaussian, sqrt(12) x sigma wide.
            let spots = simulate_spots(&em, &con, &t, &q, |_| 3.4641016 * sigma * uniform());
            for (k, model) in [ModelKind::Pinhole, ModelKind::NearField]
                .into_iter()
                .enumerate()
            {
                let set = SolverSettings {
                    model,
                    ..SolverSettings::default()
                };
                let mut s = PoseSolver::<f32>::new(&Calibration::table3(), &con, set).unwrap();
                let sol = s.solve(&spots);
                failed[k] += usize::from(sol.status != PoseStatus::Ok);
                most[k] = most[k].max(sol.iterations);
            }
        }
        assert_eq!(
            failed,
            [0, 0],
            "frames not solved of 3000 (pinhole, near-field)"
        );
        assert!(
            most.iter().all(|&m| m <= 12),
            "most iterations (pinhole, near-field): {most:?}"
        );
    }

    /// The linearisation carried from frame to frame against none: frames along a track
    /// (0.05 in and 0.1 deg apart), each solved from the same warm start (the previous
    /// solution) with and without it. Returns the largest difference of any coordinate in
    /// standard deviations, the largest relative difference of any standard deviation,
    /// the frames compared, and how many of them took more passes with the carry.
    fn carried_vs_fresh(con: &Constellation, range: f64) -> (f64, f64, usize, usize) {
        let em = truth_emulator();
        let mut uniform = uniform_from(0x2545_f491 ^ (range as u32));
        let sigma = 0.001 * crate::emulator::BETA;
        let new = || {
            PoseSolver::<f32>::new(&Calibration::table3(), con, SolverSettings::default()).unwrap()
        };
        let (mut carried, mut fresh) = (new(), new());
        let axis = Vector3::new(0.3, -0.5, 1.0);
        let (mut dx_max, mut ds_max, mut n, mut slower) = (0.0f64, 0.0f64, 0, 0);
        for k in 0..60 {
            let t = Vector3::new(0.3, -0.2, range) + Vector3::new(0.02, -0.01, 0.05) * k as f64;
            let q = mrp::from_axis_angle(&axis, rad(3.0 + 0.1 * k as f64));
            let spots = simulate_spots(&em, con, &t, &q, |_| 3.4641016 * sigma * uniform());
            let warm = carried.warm_start();
            if let Some((t0, q0)) = warm {
                fresh.set_warm_start(t0, q0);
            } else {
                fresh.reset();
            }
            let a = carried.solve(&spots);
            let obs = fresh.match_spots(&spots);
            let b = fresh.solve_obs(&obs);
            assert_eq!(a.status, b.status, "frame {k} at {range} in");
            if a.status != PoseStatus::Ok || warm.is_none() {
                continue;
            }
            n += 1;
            slower += usize::from(a.iterations > b.iterations);
            for i in 0..3 {
                let dp = (a.position[i] - b.position[i]).abs() / b.sigma_position[i];
                // Attitude: 4 dq in radians against the 1-sigma in degrees.
                let dq = (4.0 * (a.mrp[i] - b.mrp[i])).abs().to_degrees() / b.sigma_attitude_deg[i];
                dx_max = dx_max.max(f64::from(dp.max(dq)));
                let sp = (a.sigma_position[i] / b.sigma_position[i] - 1.0).abs();
                let sq = (a.sigma_attitude_deg[i] / b.sigma_attitude_deg[i] - 1.0).abs();
                ds_max = ds_max.max(f64::from(sp.max(sq)));
            }
        }
        (dx_max, ds_max, n, slower)
    }

    #[test]
    fn carried_linearisation_gives_the_gauss_newton_answer() {
        for (name, con) in [
            ("one-10", cta_constellation()),
            ("four-20", four_array_constellation()),
        ] {
            for range in [3.0, 5.0, 8.0, 10.0, 20.0, 30.0] {
                let (dx, ds, n, slower) = carried_vs_fresh(&con, range);
                // Both answers are Gauss-Newton's from a fresh linearisation, a last step of
                // at most 0.1 chi-square apart; at 20-30 in one-10's attitude lies in a flat
                // valley, where that step leaves up to a tenth of a standard deviation.
                let (dx_tol, ds_tol) = if range < 15.0 {
                    (0.01, 0.01)
                } else {
                    (0.2, 0.1)
                };
                assert!(
                    n >= 50 && dx <= dx_tol && ds <= ds_tol && slower <= 3,
                    "{name} at {range} in: max |dx|/sigma {dx:.4}, max |dsigma|/sigma {ds:.4}, \
                     frames {n}, slower {slower}"
                );
            }
        }
    }

    #[test]
    fn garbage_spots_never_give_nan() {
        let con = cta_constellation();
        let mut s = PoseSolver::<f32>::new(&Calibration::table3(), &con, SolverSettings::default())
            .unwrap();
        let mut seed = 7u32;
        for _ in 0..200 {
            let mut spots = [Spot::default(); 10];
            for (i, sp) in spots.iter_mut().enumerate() {
                seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
                sp.id = (i as u8 + (seed >> 30) as u8) % 12;
                sp.x = (seed >> 8) as i16;
                sp.y = (seed >> 3) as i16;
            }
            let sol = s.solve(&spots);
            assert!(
                sol.position
                    .iter()
                    .chain(sol.mrp.iter())
                    .all(|v| v.is_finite()),
                "{sol:?}"
            );
        }
    }

    /// A coordinate within 3 noise sigmas of a rail is clipped, not measured: it is marked
    /// unused like one on the rail, and its value does not reach the pose. One farther in is
    /// used; the margin follows the calibration's noise.
    #[test]
    fn near_rail_coordinates_are_not_used() {
        let em = truth_emulator();
        let con = cta_constellation();
        let (t, q) = target();
        let clean = simulate_spots(&em, &con, &t, &q, |_| 0.0);
        assert!(clean.iter().all(|s| s.x.abs() < 20000 && s.y.abs() < 20000));
        let mut spots = clean.clone();
        // The nominal calibration's noise, 32.768 counts: the margin is 98 counts.
        spots[0].x = 32767 - 50;
        spots[1].y = -32768 + 90;
        spots[3].y = -32767;
        let mut inside = spots.clone();
        inside[2].x = 32767 - 120;
        let cal = Calibration::table3();
        let mut s = PoseSolver::<f64>::new(&cal, &con, SolverSettings::default()).unwrap();
        let obs = s.match_spots(&inside);
        assert_eq!(obs.len(), 10);
        assert_eq!(obs[0].used, [false, true]);
        assert_eq!(obs[1].used, [true, false]);
        assert_eq!(obs[2].used, [true, true]);
        assert_eq!(obs[3].used, [true, false]);
        // The near-rail values do not pull the pose: the same frame with them moved to the
        // other rail solves to the same answer.
        let a = s.solve(&spots);
        let mut moved = spots.clone();
        moved[0].x = -32768;
        moved[1].y = 32767;
        s.reset();
        let b = s.solve(&moved);
        assert_eq!(a.status, PoseStatus::Ok, "{a:?}");
        assert!((a.position - b.position).norm() < 1e-9, "{a:?} {b:?}");
        // A calibration with a third of the noise has a third of the margin: 50 counts in
        // is then used, 90 counts in is too.
        let quiet = Calibration { noise: 10.0, ..cal };
        let s = PoseSolver::<f64>::new(&quiet, &con, SolverSettings::default()).unwrap();
        let obs = s.match_spots(&inside);
        assert_eq!(obs[0].used, [true, true]);
        assert_eq!(obs[1].used, [true, true]);
        assert_eq!(obs[3].used, [true, false]);
    }

    /// The sensor simulation's physics (Lambertian beacon, as the simulated board).
    fn board_physics() -> Emulator<f64> {
        let cal = Calibration::table3();
        Emulator::new(
            Head::northstar(),
            HeadPose {
                d: v3(&cal.d),
                p: v3(&cal.p),
            },
            Effects {
                pattern: Pattern::Lambertian { m: 1.0 },
                ..Effects::default()
            },
        )
    }

    /// Targets out of view (the reviewer's `cta sensor sim --offset 30,30 --range 3`, and
    /// others to the side): the simulated NorthStar still reports every beacon, with
    /// coordinates a few noise sigmas from the rail. No frame is ever Ok, with a fresh
    /// solver or a running one. (Before the rail margin and the plausibility gate, 4 of
    /// the reviewer's 40 frames were Ok at 5,800 in, and 262 of 400 at `(30, 0, 5)`.)
    #[test]
    fn out_of_view_frames_are_never_ok() {
        let em = board_physics();
        let cal = Calibration::table3();
        let sigma = cal.noise as f64;
        let mut uniform = uniform_from(0x5eed_0001);
        let q = mrp::from_axis_angle(&Vector3::z(), rad(2.0));
        for (con, t) in [
            (cta_constellation(), [30.0, 30.0, 3.0]),
            (cta_constellation(), [20.0, 20.0, 3.0]),
            (cta_constellation(), [30.0, 0.0, 5.0]),
            (cta_constellation(), [0.0, 40.0, 2.0]),
            (cta_constellation(), [60.0, 10.0, 10.0]),
            (four_array_constellation(), [40.0, 40.0, 3.0]),
            (four_array_constellation(), [50.0, 0.0, 5.0]),
        ] {
            let t = Vector3::from(t);
            for model in [ModelKind::NearField, ModelKind::Pinhole] {
                let set = SolverSettings {
                    model,
                    ..SolverSettings::default()
                };
                let mut running = PoseSolver::<f32>::new(&cal, &con, set).unwrap();
                for _ in 0..100 {
                    let spots =
                        simulate_spots(&em, &con, &t, &q, |_| 3.4641016 * sigma * uniform());
                    assert!(spots.len() >= MIN_BEACONS, "{t:?}: {spots:?}");
                    let mut fresh = PoseSolver::<f32>::new(&cal, &con, set).unwrap();
                    for sol in [fresh.solve(&spots), running.solve(&spots)] {
                        assert_ne!(sol.status, PoseStatus::Ok, "{t:?} {model:?}: {sol:?}");
                    }
                }
            }
        }
    }

    /// The plausibility gate on its own: the reviewer's out-of-view frames with every
    /// coordinate off the exact rail used (the rule before the margin) give solutions
    /// hundreds to thousands of inches away, none of them Ok; a solution beyond the
    /// constellation's far limit is diverged, one whose position 1-sigma exceeds the
    /// settings' fraction of the range ill-conditioned (with its 1-sigma), and a target
    /// well inside the far limit (500 in) is still Ok.
    #[test]
    fn implausible_solutions_are_never_ok() {
        let em = board_physics();
        let cal = Calibration::table3();
        let con = cta_constellation();
        let sigma = cal.noise as f64;
        let mut uniform = uniform_from(0x9e37_79b9);
        let t = Vector3::new(30.0, 30.0, 3.0);
        let q = mrp::from_axis_angle(&Vector3::z(), rad(2.0));
        let mut solved = 0;
        for _ in 0..400 {
            let spots = simulate_spots(&em, &con, &t, &q, |_| 3.4641016 * sigma * uniform());
            let mut s = PoseSolver::<f32>::new(&cal, &con, SolverSettings::default()).unwrap();
            let mut obs = s.match_spots(&[]);
            for (id, r) in &s.beacons {
                let Some(sp) = spots.iter().find(|sp| sp.id == *id) else {
                    continue;
                };
                let off = |v: i16| v != i16::MAX && v != i16::MIN;
                let used = [off(sp.x), off(sp.y)];
                if used[0] || used[1] {
                    let y = [sp.x as f32, sp.y as f32];
                    let _ = obs.push(Obs {
                        used,
                        ..Obs::new(*r, y)
                    });
                }
            }
            let sol = s.solve_obs(&obs);
            assert_ne!(sol.status, PoseStatus::Ok, "{sol:?}");
            solved += usize::from(sol.position.norm() > 908.0);
        }
        // Converged far beyond the far limit (the gate, not the solver, rejected them).
        assert!(solved >= 5, "{solved}");

        // The far limit: 908 in for this constellation; noise-free frames on axis.
        let q0 = Vector3::zeros();
        let at = |z: f64, set: SolverSettings| {
            let spots = simulate_spots(&em, &con, &Vector3::new(0.3, -0.2, z), &q0, |_| 0.0);
            PoseSolver::<f64>::new(&cal, &con, set)
                .unwrap()
                .solve(&spots)
        };
        let loose = SolverSettings {
            max_sigma_fraction: 1e6,
            ..SolverSettings::default()
        };
        assert_eq!(at(500.0, SolverSettings::default()).status, PoseStatus::Ok);
        let near = at(800.0, loose);
        assert_eq!(near.status, PoseStatus::Ok, "{near:?}");
        let far = at(1000.0, loose);
        assert_eq!(far.status, PoseStatus::Diverged, "{far:?}");
        // The sigma fraction: 8 in with the position 1-sigma allowed 1e-6 of the range.
        let strict = SolverSettings {
            max_sigma_fraction: 1e-6,
            ..SolverSettings::default()
        };
        let sol = at(8.0, strict);
        assert_eq!(sol.status, PoseStatus::IllConditioned, "{sol:?}");
        assert!(sol.sigma_position.iter().all(|s| *s > 0.0), "{sol:?}");
        assert_eq!(at(8.0, SolverSettings::default()).status, PoseStatus::Ok);
    }
}

/// The spot magnitudes in the near-field pose ([`Magnitude`]).
#[cfg(test)]
mod magnitude_tests {
    use super::tests::{check_jacobian, truth_emulator as physics, uniform_from};
    use super::*;

    fn with_magnitudes(noise_percent: f32) -> Calibration {
        Calibration {
            magnitude: Some(Magnitude::simulated(noise_percent)),
            ..Calibration::table3()
        }
    }

    fn pose_at(range: f64, k: usize) -> (Vector3<f64>, Vector3<f64>) {
        let a = k as f64;
        (
            Vector3::new(0.3 * (a * 0.7).sin(), -0.2 * (a * 1.3).cos(), range),
            mrp::from_axis_angle(
                &Vector3::new((a * 0.9).sin(), (a * 0.4).cos(), 1.0),
                rad(2.5),
            ),
        )
    }

    /// Attitude error of a solution, degrees.
    fn attitude_error<T: Real>(sol: &PoseSolution<T>, q: &Vector3<f64>) -> f64 {
        let got = Vector3::new(sol.mrp.x.to_f64(), sol.mrp.y.to_f64(), sol.mrp.z.to_f64());
        let c = mrp::dcm(&got) * mrp::dcm(q).transpose();
        let cos = ((c.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
        cos.acos().to_degrees()
    }

    #[test]
    fn validation_names_magnitude_fields_and_brightness() {
        let ok = with_magnitudes(0.07);
        assert_eq!(ok.validate(), Ok(()));
        let field = |f: fn(&mut Magnitude)| {
            let mut c = ok;
            f(c.magnitude.as_mut().unwrap());
            match c.validate() {
                Err(ConfigError::CalibrationOutOfRange { field }) => field,
                other => panic!("{other:?}"),
            }
        };
        assert_eq!(field(|m| m.offset = -1.0), CalField::MagnitudeOffset);
        assert_eq!(field(|m| m.exponent = 0.0), CalField::MagnitudeExponent);
        assert_eq!(
            field(|m| m.exponent = f32::NAN),
            CalField::MagnitudeExponent
        );
        assert_eq!(field(|m| m.noise_percent = 0.0), CalField::MagnitudeNoise);
        assert_eq!(field(|m| m.max = 70000.0), CalField::MagnitudeMax);
        assert_eq!(
            field(|m| {
                m.offset = 5000.0;
                m.max = 5000.5
            }),
            CalField::MagnitudeMax
        );
        assert_eq!(field(|m| m.sensitivity = 5), CalField::MagnitudeSensitivity);
        assert_eq!(field(|m| m.min = 65535.5), CalField::MagnitudeMin);
        assert_eq!(field(|m| m.min = -1.0), CalField::MagnitudeMin);
        assert!(CalField::MagnitudeNoise
            .describe()
            .contains("magnitude noise"));
        let mut con = cta_constellation();
        con.beacons[2].brightness = 0.0;
        let e = con.validate().unwrap_err();
        assert_eq!(e, ConfigError::BrightnessOutOfRange { id: 2 });
        assert!(e.to_string().contains("beacon 2: brightness"), "{e}");
        con.beacons[2].brightness = f32::NAN;
        assert!(con.validate().is_err());
    }

    /// The magnitude rows' Jacobian (through the contrasts) against central differences of
    /// the rows' residuals, for beacons off the plate and a boresight off its normal.
    #[test]
    fn magnitude_jacobian_matches_finite_differences() {
        let cal = with_magnitudes(0.1);
        let mut con = cta_constellation();
        con.boresight = [0.1, -0.2, -1.0];
        let s = PoseSolver::<f64>::new(&cal, &con, SolverSettings::default()).unwrap();
        let mut obs: [Obs<f64>; 3] = [
            Obs::new(Vector3::new(1.0, 2.0, 0.0), [0.0; 2]),
            Obs::new(Vector3::new(-2.0, 0.5, 0.3), [0.0; 2]),
            Obs::new(Vector3::new(0.5, -1.5, -0.2), [0.0; 2]),
        ];
        for (i, o) in obs.iter_mut().enumerate() {
            o.m = -3.0 + 0.1 * i as f64;
            o.mw = 1000.0 * (1.0 + i as f64);
        }
        obs[1].used = [true, false];
        let p = PoseProblem::of(&s, &obs);
        assert_eq!(p.n_rows(), 5 + 2);
        let (t, q) = pose_at(8.0, 1);
        let x = SVector::<f64, 6>::new(t.x, t.y, t.z, q.x, q.y, q.z);
        p.rows(&x, true, &mut |_, w, _| assert_eq!(w, 1.0)).unwrap();
        let rows = check_jacobian(&p, &x, "magnitudes");
        assert_eq!(rows.len(), p.n_rows());
        // The residual pass gives the same residuals as the Jacobian pass.
        let mut plain = std::vec::Vec::new();
        p.rows(&x, false, &mut |r, _, _| plain.push(r)).unwrap();
        for (a, b) in plain.iter().zip(&rows) {
            assert!((a - b.0).abs() <= 1e-12 * (1.0 + a.abs()), "{a} {}", b.0);
        }
        // The contrasts hold the weighted spread of the magnitude residuals about their
        // weighted mean, whatever the common scale: adding a constant to every m changes
        // nothing.
        let spread = |obs: &[Obs<f64>]| {
            let mut v = std::vec::Vec::new();
            PoseProblem::of(&s, obs)
                .rows(&x, false, &mut |r, _, _| v.push(r))
                .unwrap();
            v
        };
        let before = spread(&obs);
        for o in obs.iter_mut() {
            o.m += 0.7;
        }
        for (a, b) in before.iter().zip(spread(&obs)) {
            assert!((a - b).abs() < 1e-9 * (1.0 + a.abs()), "{a} {b}");
        }
        let r: std::vec::Vec<f64> = (0..3)
            .map(|i| {
                let em = s.emulator.unwrap();
                let (tt, ct) = split(&x);
                let e = ct * s.boresight;
                obs[i].m - em.with_boresight(&e).magnitude(&(tt + ct * obs[i].r)).ln()
            })
            .collect();
        let w: std::vec::Vec<f64> = obs.iter().map(|o| o.mw).collect();
        let mean = (0..3).map(|i| w[i] * r[i]).sum::<f64>() / w.iter().sum::<f64>();
        let want: f64 = (0..3).map(|i| w[i] * (r[i] - mean).powi(2)).sum();
        // The two magnitude rows are the 3rd and 7th (after beacon 2's one and beacon 3's
        // two spot rows): rows 0-1 spots, 2-3 beacon 2 (X, magnitude), 4-6 beacon 3.
        let mags = [before[3], before[6]];
        let got: f64 = mags.iter().map(|v| v * v).sum();
        assert!((got - want).abs() < 1e-9 * want, "{got} {want}");
    }

    /// RMS attitude and position error of `trials` noisy frames at `range` (spot noise 0.1 %
    /// of beta, magnitude noise `mag_percent`), solved cold in f32 by the near-field model
    /// with the calibration `cal`; and the RMS of the solver's own attitude 1-sigma.
    fn errors(cal: &Calibration, range: f64, mag_percent: f64, trials: usize) -> [f64; 3] {
        let em = physics();
        let con = cta_constellation();
        let sigma = 0.001 * crate::emulator::BETA;
        let mut u = uniform_from(0x9e37_79b9 ^ range as u32);
        let mut v = uniform_from(0x7f4a_7c15 ^ range as u32);
        let (mut att, mut pos, mut pred) = (0.0, 0.0, 0.0);
        for k in 0..trials {
            let (t, q) = pose_at(range, k);
            let spots = simulate_spots_with(
                &em,
                &con,
                &t,
                &q,
                |_| 3.4641016 * sigma * u(),
                |_| 3.4641016 * mag_percent / 100.0 * v(),
            );
            let mut s = PoseSolver::<f32>::new(cal, &con, SolverSettings::default()).unwrap();
            let sol = s.solve(&spots);
            assert_eq!(sol.status, PoseStatus::Ok, "{range} in, trial {k}: {sol:?}");
            let p = Vector3::new(
                sol.position.x as f64,
                sol.position.y as f64,
                sol.position.z as f64,
            );
            att += attitude_error(&sol, &q).powi(2);
            pos += (p - t).norm_squared();
            pred += sol.sigma_attitude_deg.map(|v| (v as f64).powi(2)).sum();
        }
        let n = trials as f64;
        [(att / n).sqrt(), (pos / n).sqrt(), (pred / n).sqrt()]
    }

    /// The magnitudes at the noise the spot noise implies (0.07 %, `cta sensor floor`) cut
    /// the one-frame attitude error at 8-10 in several-fold, where the spots alone sit on
    /// their floor; the solver's own 1-sigma follows the error it makes.
    #[test]
    fn magnitudes_sharpen_the_attitude_at_range() {
        for range in [8.0, 10.0] {
            let spots = errors(&Calibration::table3(), range, 0.07, 60);
            let both = errors(&with_magnitudes(0.07), range, 0.07, 60);
            std::println!("{range} in: spots {spots:?}, with magnitudes {both:?}");
            assert!(
                both[0] < spots[0] / 2.5,
                "{range} in: {both:?} vs {spots:?}"
            );
            // The 1-sigma is honest: the RMS error within 25 % of it (60 trials).
            assert!((both[0] / both[2] - 1.0).abs() < 0.25, "{both:?}");
        }
    }

    /// One frame at 10 in with 0.07 % magnitude noise, and its truth.
    fn frame(
        con: &Constellation,
        k: usize,
    ) -> (Vec<Spot, MAX_BEACONS>, Vector3<f64>, Vector3<f64>) {
        frame_at(con, k, 10.0)
    }

    fn frame_at(
        con: &Constellation,
        k: usize,
        range: f64,
    ) -> (Vec<Spot, MAX_BEACONS>, Vector3<f64>, Vector3<f64>) {
        let em = physics();
        let sigma = 0.001 * crate::emulator::BETA;
        let mut u = uniform_from(0x1234_5678 ^ k as u32);
        let mut v = uniform_from(0x8765_4321 ^ k as u32);
        let (t, q) = pose_at(range, k);
        let spots = simulate_spots_with(
            &em,
            con,
            &t,
            &q,
            |_| 3.4641016 * sigma * u(),
            |_| 3.4641016 * 0.0007 * v(),
        );
        (spots, t, q)
    }

    /// The common scale of the magnitudes is the solver's to find: the same frame with every
    /// magnitude 1.8 times larger (a brighter drive, another power level) gives the same
    /// pose. Taken on the matched observations, where it adds ln 1.8 to every `m`: the
    /// readings themselves would also round differently (at 10 in they read about 500
    /// counts, so their rounding, 0.06 %, is nearly their whole scatter).
    #[test]
    fn a_common_scale_changes_nothing() {
        let con = cta_constellation();
        let cal = with_magnitudes(0.07);
        let (spots, _, _) = frame(&con, 3);
        let mut s = PoseSolver::<f64>::new(&cal, &con, SolverSettings::default()).unwrap();
        let obs = s.match_spots(&spots);
        let mut brighter = obs.clone();
        for o in brighter.iter_mut() {
            o.m += 1.8f64.ln();
        }
        let a = s.solve_obs(&obs);
        s.reset();
        let b = s.solve_obs(&brighter);
        assert_eq!((a.status, b.status), (PoseStatus::Ok, PoseStatus::Ok));
        assert_eq!((a.magnitudes, b.magnitudes), (10, 10));
        assert!((a.position - b.position).norm() < 1e-9, "{a:?} {b:?}");
        assert!((a.mrp - b.mrp).norm() < 1e-9, "{a:?} {b:?}");
        assert!((a.rms - b.rms).abs() < 1e-9, "{a:?} {b:?}");
    }

    /// Which magnitudes are used: saturated readings (at or above `max`) and readings not a
    /// whole count above the offset are not; frames at another sensitivity than the law's
    /// are solved from the spots alone (`solve_frame`), as are calibrations without a law,
    /// the pinhole model, and `magnitudes: false`.
    #[test]
    fn which_magnitudes_are_used() {
        let con = cta_constellation();
        let (mut spots, _, _) = frame(&con, 5);
        let mut cal = with_magnitudes(0.07);
        cal.magnitude.as_mut().unwrap().max = 60000.0;
        spots[0].magnitude = 60000; // saturated
        spots[1].magnitude = 0; // no signal above the offset
        let weak = spots[3].magnitude;
        cal.magnitude.as_mut().unwrap().min = weak as f32 + 1.0;
        let s = PoseSolver::<f64>::new(&cal, &con, SolverSettings::default()).unwrap();
        let obs = s.match_spots(&spots);
        // Below the law's range: every reading weaker than beacon 3's (and its own).
        for (o, sp) in obs.iter().zip(&spots).skip(2) {
            assert_eq!(o.magnitude_used(), sp.magnitude > weak, "{sp:?}");
        }
        let below = spots
            .iter()
            .skip(2)
            .filter(|sp| sp.magnitude <= weak)
            .count();
        assert!(below >= 1);
        cal.magnitude.as_mut().unwrap().min = 0.0;
        let s = PoseSolver::<f64>::new(&cal, &con, SolverSettings::default()).unwrap();
        let obs = s.match_spots(&spots);
        let used: std::vec::Vec<bool> = obs.iter().map(|o| o.magnitude_used()).collect();
        assert_eq!(&used[..2], &[false, false]);
        assert!(used[2..].iter().all(|u| *u));
        // A one-count reading is used, weighed by its rounding: about (0.07 %)^2 / (1/12) =
        // 6e-6 of a reading of 10,000.
        let law = s.mag.unwrap();
        assert!(law.reading(0, 0.0).is_none());
        let (one, big) = (
            law.reading(1, 0.0).unwrap(),
            law.reading(10_000, 0.0).unwrap(),
        );
        assert_eq!(one.0, 0.0);
        assert!((one.1 / big.1 - 5.9e-6).abs() < 0.2e-6, "{one:?} {big:?}");
        let count = |cal: &Calibration, settings: SolverSettings, sensitivity: u8| {
            let mut s = PoseSolver::<f64>::new(cal, &con, settings).unwrap();
            let sol = s.solve_frame(&spots, sensitivity);
            assert_eq!(sol.status, PoseStatus::Ok, "{sol:?}");
            sol.magnitudes
        };
        let nf = SolverSettings::default();
        assert_eq!(count(&cal, nf, 4), 8);
        assert_eq!(count(&cal, nf, 3), 0);
        assert_eq!(count(&Calibration::table3(), nf, 4), 0);
        let off = SolverSettings {
            magnitudes: false,
            ..nf
        };
        assert_eq!(count(&cal, off, 4), 0);
        let pinhole = SolverSettings {
            model: ModelKind::Pinhole,
            ..nf
        };
        assert_eq!(count(&cal, pinhole, 4), 0);
    }

    /// The beacons' brightness reaches the solver: a constellation whose beacons on the +x
    /// side are 10 % brighter than the rest is solved with the magnitudes to their noise when
    /// the constellation says so. When it does not, the magnitudes misfit by about 14 times
    /// their noise, the solve's residual RMS exceeds `MAGNITUDE_RMS_SIGMAS`, and the pose is
    /// the one from the spots alone: no worse than without the magnitudes.
    #[test]
    fn beacon_brightness_reaches_the_solver() {
        let mut truth = cta_constellation();
        for b in truth.beacons.iter_mut().filter(|b| b.r[0] > 0.0) {
            b.brightness = 1.1;
        }
        let cal = with_magnitudes(0.07);
        let trials = 20;
        let mut att = [0.0; 2];
        for k in 0..trials {
            let (spots, _, q) = frame(&truth, k);
            let solve = |con: &Constellation, settings: SolverSettings| {
                let sol = PoseSolver::<f64>::new(&cal, con, settings)
                    .unwrap()
                    .solve(&spots);
                assert_eq!(sol.status, PoseStatus::Ok, "{sol:?}");
                sol
            };
            let right = solve(&truth, SolverSettings::default());
            assert_eq!(right.magnitudes, 10);
            assert!(right.rms < 1.5 * cal.noise as f64, "{right:?}");
            let wrong = solve(&cta_constellation(), SolverSettings::default());
            let spots_only = solve(
                &cta_constellation(),
                SolverSettings {
                    magnitudes: false,
                    ..Default::default()
                },
            );
            assert_eq!(wrong.magnitudes, 0, "{wrong:?}");
            assert_eq!(wrong.position, spots_only.position);
            assert_eq!(wrong.mrp, spots_only.mrp);
            att[0] += attitude_error(&right, &q).powi(2) / trials as f64;
            att[1] += attitude_error(&wrong, &q).powi(2) / trials as f64;
        }
        let att = att.map(f64::sqrt);
        assert!(att[0] < 0.15 && att[1] > 3.0 * att[0], "{att:?}");
    }

    /// With magnitudes the carried linearisation still gives the Gauss-Newton answer: along a
    /// track at 10 in, a solver carrying it and one linearising afresh from the same warm
    /// start (and with the same magnitude weights: the carrying solver keeps the last
    /// frame's) agree within a small fraction of a standard deviation.
    #[test]
    fn carried_linearisation_with_magnitudes() {
        let con = cta_constellation();
        let cal = with_magnitudes(0.07);
        let new = || PoseSolver::<f32>::new(&cal, &con, SolverSettings::default()).unwrap();
        let (mut carried, mut fresh) = (new(), new());
        let mut worst = 0.0f64;
        let mut compared = 0;
        for k in 0..30 {
            let (spots, _, _) = frame(&con, k);
            let warm = carried.warm_start();
            match warm {
                Some((t0, q0)) => fresh.set_warm_start(t0, q0),
                None => fresh.reset(),
            }
            let kept = carried.carry_mw;
            let carries = carried.carry.is_some();
            let a = carried.solve(&spots);
            let mut obs = fresh.match_spots(&spots);
            if carries {
                for (o, w) in obs.iter_mut().zip(&kept) {
                    o.mw = *w;
                }
            }
            let b = fresh.solve_obs(&obs);
            assert_eq!(a.status, b.status);
            assert_eq!(a.magnitudes, b.magnitudes);
            if warm.is_none() || a.status != PoseStatus::Ok {
                continue;
            }
            compared += 1;
            for i in 0..3 {
                let dp = (a.position[i] - b.position[i]).abs() / b.sigma_position[i];
                let dq = (4.0 * (a.mrp[i] - b.mrp[i])).abs().to_degrees() / b.sigma_attitude_deg[i];
                worst = worst.max(f64::from(dp.max(dq)));
            }
        }
        assert!(compared > 20, "{compared}");
        assert!(worst < 0.05, "{worst}");
    }
}
