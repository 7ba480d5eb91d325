//! The simulated NorthStar's spot magnitude law, one for every simulator (`cta simulate`, the
//! simulated sweep, `cta sensor sim`), documented in `host/MEASUREMENTS.md` ("The simulated
//! NorthStar's magnitude").
//!
//! A spot's reading, in counts, is the head's summed cell signal `S` (1/in^2,
//! [`Emulator::magnitude`]) scaled so that a beacon on the board's axis at 30 in, at power
//! level 2 and sensitivity 4, reads [`MAG_AT_30`]; power level 1 (1 kOhm instead of 360 Ohm)
//! drives the LED at [`POWER1_GAIN`] of that, and each sensitivity step below 4 halves it. It is
//! rounded to whole counts and saturates at 0 and 65535 (REFERENCE.md §4: Rovio reports
//! signal strength 0..65535, strong above ~47000, no signal below ~5000). The scale is set by
//! the head's own on-axis signal at 30 in, so the reading of a point depends on where the
//! beacon is relative to the head, the LED's brightness and the settings.

use nalgebra::Vector3;

use crate::emulator::Emulator;
use crate::Real;

/// Reading of a beacon on the board's axis at 30 in, power level 2, sensitivity 4, counts.
pub const MAG_AT_30: f64 = 20_000.0;
/// Drive current ratio of power level 1 (1 kOhm) to level 2 (360 Ohm).
pub const POWER1_GAIN: f64 = 0.36;
/// The largest reading: the NorthStar's magnitude is 16 bits.
pub const MAX_COUNTS: f64 = 65_535.0;

/// The gain of the settings relative to power level 2, sensitivity 4: [`POWER1_GAIN`] at power
/// level 1, times 2^(sensitivity - 4).
pub fn gain(power: u8, sensitivity: u8) -> f64 {
    let p = if power == 1 { POWER1_GAIN } else { 1.0 };
    p * libm::pow(2.0, sensitivity as f64 - 4.0)
}

/// The head's summed cell signal of a beacon on the board's axis at 30 in, 1/in^2: the law's
/// reference ([`reading`]).
pub fn signal_at_30<T: Real>(em: &Emulator<T>) -> f64 {
    let z = T::lit(30.0);
    em.magnitude(&Vector3::new(T::zero(), T::zero(), z))
        .to_f64()
}

/// The reading, counts, before noise, rounding and saturation: the signal `signal` (1/in^2)
/// of a head whose on-axis signal at 30 in is `at_30` ([`signal_at_30`]), at `power` and
/// `sensitivity`. A LED's brightness multiplies it.
pub fn reading(signal: f64, at_30: f64, power: u8, sensitivity: u8) -> f64 {
    signal * (MAG_AT_30 / at_30) * gain(power, sensitivity)
}

/// A reading as the NorthStar reports it: rounded to whole counts (not truncated: that would
/// bias `ln M` by `-0.5 / M`, which depends on the distance) and saturated to 0..=65535; a
/// reading that is not a number reads 0.
pub fn counts(reading: f64) -> u16 {
    if reading.is_nan() {
        return 0;
    }
    libm::round(reading.clamp(0.0, MAX_COUNTS)) as u16
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::emulator::{Effects, Head, Pose};

    #[test]
    fn the_law_reads_its_reference_and_follows_the_settings() {
        let em = Emulator::new(Head::northstar(), Pose::table3(), Effects::default());
        let at_30 = signal_at_30(&em);
        let on_axis = |z: f64| em.magnitude(&Vector3::new(0.0, 0.0, z));
        assert_eq!(counts(reading(on_axis(30.0), at_30, 2, 4)), 20_000);
        // Power level 1 at 0.36 of level 2; one sensitivity step halves; both at once.
        assert_eq!(counts(reading(on_axis(30.0), at_30, 1, 4)), 7_200);
        assert_eq!(counts(reading(on_axis(30.0), at_30, 2, 3)), 10_000);
        assert_eq!(counts(reading(on_axis(30.0), at_30, 1, 1)), 900);
        // Nearer is brighter (about 1/r^2 on the axis), up to saturation.
        let at_20 = reading(on_axis(20.0), at_30, 2, 4);
        assert!((at_20 / 20_000.0 - 2.25).abs() < 0.1, "{at_20}");
        assert_eq!(counts(reading(on_axis(5.0), at_30, 2, 4)), 65_535);
        assert_eq!(counts(-3.0), 0);
        assert_eq!(counts(f64::NAN), 0);
        assert_eq!(counts(1234.5), 1235);
        assert_eq!(counts(1234.4), 1234);
    }
}
