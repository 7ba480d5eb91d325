//! The effect vocabulary: named, parametric departures from the thesis physics that CTA can
//! inject into simulated data (`cta simulate --effect NAME=VALUE`) and look for in measured
//! data (`cta analyze`). Each effect's physics is documented on its variant; the signal of
//! cell k is `c_k I_k V_k` of eq 63 (units 1/in^2).

use cta_core::emulator::Effects;
use cta_core::pattern::Pattern;
use cta_core::real::rad;
use std::fmt;

/// Why an effect `NAME=VALUE` is refused: each message names the effect and what it takes.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EffectError {
    /// An effect given without the value it needs.
    #[error("effect `{name}` needs a value: {}", usage(.name))]
    NeedsValue {
        /// The effect's name.
        name: String,
    },
    /// A value that is not a list of numbers.
    #[error("effect `{name}`: `{value}` is not a number list ({})", usage(.name))]
    NotNumbers {
        /// The effect's name.
        name: String,
        /// The value as given.
        value: String,
    },
    /// Too few or too many numbers, or one that is not finite.
    #[error("effect `{name}`: expected {}", usage(.name))]
    Expected {
        /// The effect's name.
        name: String,
    },
    /// A value outside the effect's physics (the reason in words).
    #[error("effect `{name}`: {why}")]
    OutOfRange {
        /// The effect's name.
        name: &'static str,
        /// What the value must be.
        why: String,
    },
    /// `intensity` with a value other than on or off.
    #[error("effect `intensity`: `{0}` is not on/off")]
    NotOnOff(String),
    /// A name outside the vocabulary.
    #[error("unknown effect `{0}`; known: {known}, crosstalk (simulation only)", known = VOCABULARY.join(", "))]
    Unknown(String),
    /// An effect the sweep's simulated CTA does not simulate.
    #[error(
        "effect `{0}` is not simulated by the sweep's simulated CTA (it would be ignored): \
         simulate it with `cta simulate --effect`"
    )]
    NotInSweep(&'static str),
    /// An effect named twice.
    #[error("effect `{name}` given twice (`{first}` and `{second}`): give each effect once")]
    Twice {
        /// The effect's name.
        name: &'static str,
        /// The first.
        first: Effect,
        /// The second.
        second: Effect,
    },
}

/// One effect with its parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Effect {
    /// `proximity=S`: the cells sit at +/-S in from the head's centre (parallax between the
    /// cells). Part of the `thesis` model (S = 0.175 in); a candidate from `pinhole`.
    Proximity(f64),
    /// `intensity` (or `intensity=1`/`0`): inverse-square intensity per cell, `1/|b_k|^2`.
    /// Part of `thesis`; a candidate from `pinhole`.
    Intensity(bool),
    /// `beacon_pattern=H`: the LED is Lambertian with half-intensity angle H deg (default 60,
    /// `cos^m`, `m = ln 0.5 / ln cos H`).
    BeaconPattern(f64),
    /// `beacon_tilt=T[,AZ]`: every LED boresight tilted T deg from -z of N toward azimuth AZ
    /// deg (0 = +x of N): a warped or tilted beacon plate.
    BeaconTilt(f64, f64),
    /// `cell_gain=GX[,GY]`: cell 1's signal times (1+GX), cell 3's times (1+GY):
    /// responsivity mismatch within a pair.
    CellGain(f64, f64),
    /// `cell_bias=BX[,BY]`: BX added to cell 1's signal and BY to cell 3's (1/in^2): ambient
    /// light or dark current.
    CellBias(f64, f64),
    /// `ambient=B`: B added to the signal of all four cells (1/in^2): room light or a dark
    /// current common to the cells. In eq 63 the difference of a pair is unchanged and its sum
    /// grows by 2B, so the outputs are compressed by `S/(S + 2B)` (S the pair's signal sum):
    /// most where the spot is weak, at far separations and off boresight. Unlike `cell_bias`
    /// (cells 1 and 3 alone), it moves no output at zero signal difference.
    Ambient(f64),
    /// `face_angle=DX[,DY]`: the pyramid face angle of the X pair is 30+DX deg, of the Y pair
    /// 30+DY deg.
    FaceAngle(f64, f64),
    /// `saturation=S`: each cell's signal is clipped at S (1/in^2): the cells saturate close
    /// to the beacon.
    Saturation(f64),
    /// `plate_offset=SIGMA`: at each separation the plate sits laterally off its nominal place
    /// by an (x, y) drawn with standard deviation SIGMA in (seeded); analysis estimates one
    /// offset per separation.
    PlateOffset(f64),
    /// `separation_error=SIGMA`: at each separation the recorded separation is off by a value
    /// drawn with standard deviation SIGMA in; analysis estimates one correction per
    /// separation.
    SeparationError(f64),
    /// `plate_tilt=SIGMA`: at each separation the plate is not parallel to the sensor board:
    /// it is tilted about its centre by a tilt vector (tx, ty) whose components are drawn
    /// with standard deviation SIGMA deg (seeded). A tilt T toward azimuth AZ leans the
    /// plate's downward normal T from -z of N toward AZ, so the plate's side toward AZ is
    /// farther from the sensor (by about u T at u in from the centre), and every LED's
    /// boresight tilts with it. The thesis levels both plates to 5 mils/ft (0.024 deg) and
    /// measures the four corners (Ch IV); uneven nuts on the threaded rods tilt the plate.
    /// Unlike `beacon_tilt` (the LEDs' boresights alone, the same at every separation) it
    /// moves the beacons. Analysis estimates one tilt per separation.
    PlateTilt(f64),
    /// `led_position=SIGMA`: each LED sits off its nominal place on the plate by an in-plane
    /// (dx, dy) drawn once with standard deviation SIGMA in per axis (seeded), the same at
    /// every separation: a hand-soldered LED off its pads (Ch IV Table 2, "LED placement on
    /// solder pads"). Analysis estimates one (dx, dy) per LED.
    LedPosition(f64),
    /// `led_tilt=SIGMA`: each LED's boresight tilted by its own tilt vector (tx, ty), each
    /// component drawn once with standard deviation SIGMA deg (seeded; a random azimuth), the
    /// same at every separation: LEDs soldered askew one by one, unlike `beacon_tilt` (all
    /// alike). Analysis estimates one (tx, ty) per LED.
    LedTilt(f64),
    /// `array_pose=SIGMA_IN[,SIGMA_DEG]`: with several arrays on the plate (the quad layout),
    /// each array placed off its nominal place as a rigid body: shifted in the plate's plane by
    /// (dx, dy), each drawn once with standard deviation SIGMA_IN in, and turned about its own
    /// centre by dtheta drawn with SIGMA_DEG deg (0 when omitted), the same at every
    /// separation: four boards mounted on the plate one by one. Analysis estimates one
    /// (dx, dy, dtheta) per array.
    ArrayPose(f64, f64),
    /// `crosstalk=K`: each cell picks up K times the signal of the matching cell of the other
    /// pair. NOT in the analysis vocabulary: simulation only, to test that `analyze` reports
    /// unexplained structure instead of a false name.
    Crosstalk(f64),
}

/// The names `cta analyze` can report (every effect but `crosstalk`).
pub const VOCABULARY: [&str; 15] = [
    "proximity",
    "intensity",
    "beacon_pattern",
    "beacon_tilt",
    "cell_gain",
    "cell_bias",
    "ambient",
    "face_angle",
    "saturation",
    "plate_offset",
    "separation_error",
    "plate_tilt",
    "led_position",
    "led_tilt",
    "array_pose",
];

impl Effect {
    /// The effect's name as it appears in output.
    pub fn name(&self) -> &'static str {
        match self {
            Effect::Proximity(_) => "proximity",
            Effect::Intensity(_) => "intensity",
            Effect::BeaconPattern(_) => "beacon_pattern",
            Effect::BeaconTilt(..) => "beacon_tilt",
            Effect::CellGain(..) => "cell_gain",
            Effect::CellBias(..) => "cell_bias",
            Effect::Ambient(_) => "ambient",
            Effect::FaceAngle(..) => "face_angle",
            Effect::Saturation(_) => "saturation",
            Effect::PlateOffset(_) => "plate_offset",
            Effect::SeparationError(_) => "separation_error",
            Effect::PlateTilt(_) => "plate_tilt",
            Effect::LedPosition(_) => "led_position",
            Effect::LedTilt(_) => "led_tilt",
            Effect::ArrayPose(..) => "array_pose",
            Effect::Crosstalk(_) => "crosstalk",
        }
    }

    /// Parse `NAME=VALUE[,VALUE]` (or a bare `intensity`).
    pub fn parse(s: &str) -> Result<Effect, EffectError> {
        let (name, val) = match s.split_once('=') {
            Some((n, v)) => (n.trim(), Some(v.trim())),
            None => (s.trim(), None),
        };
        let nums = |min: usize, max: usize| -> Result<Vec<f64>, EffectError> {
            let v = val.ok_or_else(|| EffectError::NeedsValue { name: name.into() })?;
            let parts: Result<Vec<f64>, _> =
                v.split(',').map(|p| p.trim().parse::<f64>()).collect();
            let parts = parts.map_err(|_| EffectError::NotNumbers {
                name: name.into(),
                value: v.into(),
            })?;
            if parts.len() < min || parts.len() > max || parts.iter().any(|p| !p.is_finite()) {
                return Err(EffectError::Expected { name: name.into() });
            }
            Ok(parts)
        };
        let range = |name: &'static str, why: String| EffectError::OutOfRange { name, why };
        let e = match name {
            "proximity" => {
                let v = nums(1, 1)?;
                if v[0] < 0.0 {
                    return Err(range("proximity", "S must be >= 0 in".into()));
                }
                Effect::Proximity(v[0])
            }
            "intensity" => match val {
                None | Some("1") | Some("on") | Some("true") => Effect::Intensity(true),
                Some("0") | Some("off") | Some("false") => Effect::Intensity(false),
                Some(v) => return Err(EffectError::NotOnOff(v.into())),
            },
            "beacon_pattern" => {
                let v = nums(1, 1)?;
                if !(v[0] > 0.0 && v[0] < 90.0) {
                    return Err(range("beacon_pattern", "H must be in (0, 90) deg".into()));
                }
                Effect::BeaconPattern(v[0])
            }
            "beacon_tilt" => {
                let v = nums(1, 2)?;
                if !(v[0].abs() < 90.0) {
                    return Err(range(
                        "beacon_tilt",
                        format!(
                            "the tilt T = {} deg must be under 90 deg in size (at 90 deg the \
                             LEDs face sideways and light no cell)",
                            v[0]
                        ),
                    ));
                }
                Effect::BeaconTilt(v[0], v.get(1).copied().unwrap_or(0.0))
            }
            "cell_gain" => {
                let v = nums(1, 2)?;
                if let Some(g) = v.iter().find(|g| !(**g > -1.0)) {
                    return Err(range(
                        "cell_gain",
                        format!(
                            "{g} must be > -1 (the cell's gain is 1 + G, which must stay positive)"
                        ),
                    ));
                }
                Effect::CellGain(v[0], v.get(1).copied().unwrap_or(0.0))
            }
            "cell_bias" => {
                let v = nums(1, 2)?;
                Effect::CellBias(v[0], v.get(1).copied().unwrap_or(0.0))
            }
            "ambient" => Effect::Ambient(nums(1, 1)?[0]),
            "face_angle" => {
                let v = nums(1, 2)?;
                if let Some(d) = v.iter().find(|d| !(**d > -30.0 && **d < 60.0)) {
                    return Err(range(
                        "face_angle",
                        format!(
                            "{d} must be in (-30, 60) deg (the face angle 30 + D must be in (0, \
                             90) deg)"
                        ),
                    ));
                }
                Effect::FaceAngle(v[0], v.get(1).copied().unwrap_or(0.0))
            }
            "saturation" => {
                let v = nums(1, 1)?;
                if !(v[0] > 0.0) {
                    return Err(range("saturation", "S must be > 0 (1/in^2)".into()));
                }
                Effect::Saturation(v[0])
            }
            "plate_offset" => Effect::PlateOffset(nonneg("plate_offset", nums(1, 1)?[0])?),
            "separation_error" => {
                Effect::SeparationError(nonneg("separation_error", nums(1, 1)?[0])?)
            }
            "plate_tilt" => {
                let v = nums(1, 1)?[0];
                if !(0.0..=10.0).contains(&v) {
                    return Err(range(
                        "plate_tilt",
                        format!(
                            "SIGMA = {v} must be in [0, 10] deg (the 1-sigma tilt of the plate at \
                             each separation)"
                        ),
                    ));
                }
                Effect::PlateTilt(v)
            }
            "led_position" => Effect::LedPosition(nonneg("led_position", nums(1, 1)?[0])?),
            "led_tilt" => {
                let v = nums(1, 1)?[0];
                if !(0.0..=20.0).contains(&v) {
                    return Err(range(
                        "led_tilt",
                        format!(
                            "SIGMA = {v} must be in [0, 20] deg (the 1-sigma of each LED's tilt \
                             per axis)"
                        ),
                    ));
                }
                Effect::LedTilt(v)
            }
            "array_pose" => {
                let v = nums(1, 2)?;
                let deg = v.get(1).copied().unwrap_or(0.0);
                if !(0.0..=10.0).contains(&deg) {
                    return Err(range(
                        "array_pose",
                        format!(
                            "SIGMA_DEG = {deg} must be in [0, 10] deg (the 1-sigma of each \
                             array's turn)"
                        ),
                    ));
                }
                Effect::ArrayPose(nonneg("array_pose", v[0])?, deg)
            }
            "crosstalk" => {
                let k = nums(1, 1)?[0];
                if !(0.0..1.0).contains(&k) {
                    return Err(range(
                        "crosstalk",
                        format!(
                            "K = {k} must be in [0, 1) (a cell picks up a fraction K of the other \
                             pair's signal)"
                        ),
                    ));
                }
                Effect::Crosstalk(k)
            }
            "spot_crosstalk" => {
                return Err(range(
                    "spot_crosstalk",
                    "acts between beacons lit together: only the simulated CTA of a grouped \
                     sweep has it (`cta sweep --plan PLAN --sim-effect spot_crosstalk=C`, \
                     with `group` above 1 in the plan)"
                        .into(),
                ))
            }
            other => return Err(EffectError::Unknown(other.into())),
        };
        Ok(e)
    }

    /// Apply a physics effect to the emulator's head/effects. Plate offsets, separation
    /// errors, plate tilts and LED positions act on the geometry instead (see `simulate`), so
    /// they are no-ops here.
    pub fn apply(&self, head: &mut cta_core::emulator::Head<f64>, fx: &mut Effects<f64>) {
        match *self {
            Effect::Proximity(s) => {
                fx.proximity = true;
                head.s = s;
            }
            Effect::Intensity(on) => fx.intensity = on,
            Effect::BeaconPattern(h) => fx.pattern = Pattern::lambertian_half_angle(h),
            Effect::BeaconTilt(t, az) => {
                fx.tilt = rad(t);
                fx.tilt_az = rad(az);
            }
            Effect::CellGain(gx, gy) => {
                fx.gain[0] = 1.0 + gx;
                fx.gain[2] = 1.0 + gy;
            }
            // Added, not set: `ambient` adds to every cell, in whichever order they come.
            Effect::CellBias(bx, by) => {
                fx.bias[0] += bx;
                fx.bias[2] += by;
            }
            Effect::Ambient(b) => fx.bias.iter_mut().for_each(|v| *v += b),
            Effect::FaceAngle(dx, dy) => {
                head.alpha_x = rad(30.0 + dx);
                head.alpha_y = rad(30.0 + dy);
            }
            Effect::Saturation(s) => fx.saturation = Some(s),
            Effect::Crosstalk(k) => fx.crosstalk = k,
            Effect::PlateOffset(_)
            | Effect::SeparationError(_)
            | Effect::PlateTilt(_)
            | Effect::LedPosition(_)
            | Effect::LedTilt(_)
            | Effect::ArrayPose(..) => {}
        }
    }
}

/// Refuse an effect named twice: only one value of each can be simulated, and the truth
/// must say which.
pub fn check_unique(effects: &[Effect]) -> Result<(), EffectError> {
    for (i, e) in effects.iter().enumerate() {
        if let Some(first) = effects[..i].iter().find(|f| f.name() == e.name()) {
            return Err(EffectError::Twice {
                name: e.name(),
                first: *first,
                second: *e,
            });
        }
    }
    Ok(())
}

/// Refuse the effects the sweep's simulated CTA (`cta sweep --sim-effect`) does not
/// simulate: per-LED boresights (`led_tilt`) and several arrays' poses (`array_pose`) are
/// simulated by [`crate::sim::SimConfig`] alone.
pub fn check_sweep(effects: &[Effect]) -> Result<(), EffectError> {
    match effects
        .iter()
        .find(|e| matches!(e, Effect::LedTilt(_) | Effect::ArrayPose(..)))
    {
        Some(e) => Err(EffectError::NotInSweep(e.name())),
        None => Ok(()),
    }
}

/// Parse a list of `NAME=VALUE` effects (the repeatable `--effect`), refusing an effect
/// named twice.
pub fn parse_all<S: AsRef<str>>(specs: &[S]) -> Result<Vec<Effect>, EffectError> {
    let v = specs
        .iter()
        .map(|s| Effect::parse(s.as_ref()))
        .collect::<Result<Vec<_>, _>>()?;
    check_unique(&v)?;
    Ok(v)
}

fn nonneg(name: &'static str, v: f64) -> Result<f64, EffectError> {
    if v < 0.0 {
        Err(EffectError::OutOfRange {
            name,
            why: "SIGMA must be >= 0 in".into(),
        })
    } else {
        Ok(v)
    }
}

fn usage(name: &str) -> &'static str {
    match name {
        "proximity" => "proximity=S (cell offset, in)",
        "beacon_pattern" => "beacon_pattern=H (half-intensity angle, deg)",
        "beacon_tilt" => "beacon_tilt=T[,AZ] (deg)",
        "cell_gain" => "cell_gain=GX[,GY] (fractions)",
        "cell_bias" => "cell_bias=BX[,BY] (1/in^2)",
        "ambient" => "ambient=B (1/in^2, on all four cells)",
        "face_angle" => "face_angle=DX[,DY] (deg)",
        "saturation" => "saturation=S (1/in^2)",
        "plate_offset" => "plate_offset=SIGMA (in)",
        "separation_error" => "separation_error=SIGMA (in)",
        "plate_tilt" => "plate_tilt=SIGMA (deg)",
        "led_position" => "led_position=SIGMA (in, per LED and axis)",
        "led_tilt" => "led_tilt=SIGMA (deg, per LED and axis)",
        "array_pose" => "array_pose=SIGMA_IN[,SIGMA_DEG] (per array: shift in, turn deg)",
        "crosstalk" => "crosstalk=K (fraction)",
        _ => "NAME=VALUE",
    }
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Effect::Proximity(v)
            | Effect::BeaconPattern(v)
            | Effect::Saturation(v)
            | Effect::Ambient(v) => {
                write!(f, "{}={v}", self.name())
            }
            Effect::PlateOffset(v)
            | Effect::SeparationError(v)
            | Effect::PlateTilt(v)
            | Effect::LedPosition(v)
            | Effect::LedTilt(v)
            | Effect::Crosstalk(v) => {
                write!(f, "{}={v}", self.name())
            }
            Effect::Intensity(on) => write!(f, "intensity={}", if on { 1 } else { 0 }),
            Effect::BeaconTilt(a, b)
            | Effect::CellGain(a, b)
            | Effect::CellBias(a, b)
            | Effect::FaceAngle(a, b)
            | Effect::ArrayPose(a, b) => {
                write!(f, "{}={a},{b}", self.name())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_effect_and_round_trips() {
        // Every vocabulary name parses (with a value where it needs one).
        for n in VOCABULARY {
            let e = Effect::parse(n).or_else(|_| Effect::parse(&format!("{n}=0.1")));
            assert_eq!(e.map(|e| e.name()), Ok(n), "{n}");
        }
        for s in [
            "proximity=0.2",
            "intensity=1",
            "beacon_pattern=45",
            "beacon_tilt=3,45",
            "cell_gain=0.02,-0.01",
            "cell_bias=0.0001,0",
            "ambient=2e-5",
            "face_angle=1,0.5",
            "saturation=0.1",
            "plate_offset=0.05",
            "separation_error=0.05",
            "plate_tilt=0.5",
            "led_position=0.004",
            "led_tilt=3",
            "array_pose=0.02,0.3",
            "crosstalk=0.02",
        ] {
            let e = Effect::parse(s).unwrap();
            assert_eq!(Effect::parse(&e.to_string()).unwrap(), e, "{s}");
        }
        assert_eq!(
            Effect::parse("beacon_tilt=3").unwrap(),
            Effect::BeaconTilt(3.0, 0.0)
        );
        assert_eq!(Effect::parse("intensity").unwrap(), Effect::Intensity(true));
    }

    /// `ambient=B` leaves each pair's difference and adds 2B to its sum (eq 63): both outputs
    /// shrink by `S/(S + 2B)`; together with `cell_bias` the two add.
    #[test]
    fn ambient_compresses_both_outputs_by_the_pairs_sum() {
        use cta_core::emulator::{Emulator, Head, Pose};
        let r = nalgebra::Vector3::new(1.0, -2.0, 20.0);
        let em = |effects: &[Effect]| {
            let (mut head, mut fx) = (Head::northstar(), Effects::default());
            for e in effects {
                e.apply(&mut head, &mut fx);
            }
            Emulator::new(head, Pose::table3(), fx)
        };
        let clean = em(&[]);
        let s = clean.signals(&r);
        let o0 = clean.output(&r).unwrap();
        let b = 1e-4;
        let o = em(&[Effect::Ambient(b)]).output(&r).unwrap();
        let k = [
            (s[0] + s[1]) / (s[0] + s[1] + 2.0 * b),
            (s[2] + s[3]) / (s[2] + s[3] + 2.0 * b),
        ];
        for a in 0..2 {
            assert!(k[a] < 0.98, "{k:?}: a visible compression");
            assert!(
                (o[a] - o0[a] * k[a]).abs() < 1e-9 * o0[a].abs(),
                "{o:?} {o0:?} {k:?}"
            );
        }
        let both = em(&[Effect::CellBias(2e-5, 0.0), Effect::Ambient(b)]).signals(&r);
        assert!((both[0] - s[0] - b - 2e-5).abs() < 1e-15 && (both[1] - s[1] - b).abs() < 1e-15);
    }

    #[test]
    fn bad_effects_say_why() {
        assert!(Effect::parse("glare=1")
            .unwrap_err()
            .to_string()
            .contains("unknown effect `glare`"));
        assert!(Effect::parse("cell_gain")
            .unwrap_err()
            .to_string()
            .contains("needs a value"));
        assert!(Effect::parse("cell_gain=x")
            .unwrap_err()
            .to_string()
            .contains("not a number"));
        assert!(Effect::parse("beacon_pattern=95")
            .unwrap_err()
            .to_string()
            .contains("(0, 90)"));
        assert!(Effect::parse("saturation=-1").is_err());
    }

    #[test]
    fn effect_parameters_outside_the_physics_are_refused() {
        // These simulated nothing at all (every beacon outside the field of view).
        for (s, why) in [
            ("beacon_tilt=180", "under 90 deg"),
            ("beacon_tilt=-90,45", "under 90 deg"),
            ("crosstalk=-1", "[0, 1)"),
            ("crosstalk=1", "[0, 1)"),
            ("cell_gain=0,-1", "> -1"),
            ("face_angle=60", "(-30, 60)"),
            ("face_angle=0,-30", "(-30, 60)"),
            ("plate_tilt=-1", "[0, 10]"),
            ("plate_tilt=20", "[0, 10]"),
            ("led_tilt=30", "[0, 20]"),
            ("array_pose=0.02,-0.3", "[0, 10]"),
        ] {
            let e = Effect::parse(s).unwrap_err().to_string();
            let name = s.split('=').next().unwrap();
            assert!(
                e.contains(&format!("effect `{name}`")) && e.contains(why),
                "{s}: {e}"
            );
        }
        for s in [
            "beacon_tilt=89,10",
            "crosstalk=0",
            "cell_gain=-0.5",
            "face_angle=-29,59",
        ] {
            assert!(Effect::parse(s).is_ok(), "{s}");
        }
    }

    #[test]
    fn an_effect_named_twice_is_refused() {
        let e = parse_all(&["cell_gain=0.1", "intensity", "cell_gain=0.2"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("effect `cell_gain` given twice"), "{e}");
        assert!(
            e.contains("cell_gain=0.1,0") && e.contains("cell_gain=0.2,0"),
            "{e}"
        );
        assert_eq!(parse_all(&["cell_gain=0.1", "intensity"]).unwrap().len(), 2);
        assert!(check_unique(&[Effect::Intensity(true), Effect::Intensity(false)]).is_err());
    }
}
