//! The configuration a pose solve needs, and its validation: the beacon constellation (the
//! target, frame T) and the sensor calibration (eq 65's head pose and scale, the eq 60-63
//! near-field parameters, the pinhole model's own head pose, the spot magnitude law).
//! [`Calibration::validate`] and [`Constellation::validate`] are the only checks of them.

use super::{MAX_BEACONS, MAX_CHANNEL, MIN_BEACONS};
use crate::Real;
use core::fmt;
use heapless::Vec;
use serde::{Deserialize, Serialize};

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
    ///
    /// [`Effects::gain`]: crate::emulator::Effects::gain
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
    ///
    /// [`Effects::bias`]: crate::emulator::Effects::bias
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

/// The spot magnitude law, with which the near-field pose also fits the NorthStar's
/// magnitudes (beyond the thesis, whose model is the spots' `X, Y`):
/// `M = offset + A (b S)^exponent`, with `S` the summed cell signal of eq 63
/// (`sum_k c_k I_k V_k`, 1/in^2: [`Emulator::magnitude`]), `b` the beacon's relative
/// brightness ([`Beacon::brightness`]) and `A` a scale common to the frame that every pose
/// estimates. Only the ratios between beacons count: they carry the beacons' relative
/// distances, which a flat target's tilt changes and the spots show only through perspective.
///
/// The NorthStar's real magnitude output is not public: the law is an assumption wide enough
/// for a linear, compressive or offset response, which `cta calibrate` fits to a sweep's
/// `magnitude` column, its scatter about the fit giving [`Self::noise_percent`].
///
/// [`Emulator::magnitude`]: crate::emulator::Emulator::magnitude
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
    ///
    /// [`simulate_spots`]: super::simulate_spots
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

/// The pinhole model's own head pose: the `d, p` of a 7-parameter eq 65 fit (`d, p, H`,
/// thesis eqs 64-66, at the far separations), which the [`ModelKind::Pinhole`] solve uses
/// with [`Calibration::h`] when the calibration has it.
///
/// The fit's `d` is the pinhole's eye point, about 1 in above the head (it absorbs the
/// data's near-field structure: README, "virtual eye"), so a calibration fitted with both
/// models holds two poses: the head's in [`Calibration::d`], [`Calibration::p`], the eye's
/// here. Eq 65 with the head's pose and the pinhole's `H` reads ranges short (about 0.9 in
/// at 12 in).
///
/// [`ModelKind::Pinhole`]: super::ModelKind::Pinhole
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
    ///
    /// [`ModelKind::Pinhole`]: super::ModelKind::Pinhole
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
