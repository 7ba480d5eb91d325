//! The limits of the pose analyses' options: the ranges and the spot noise they take.

use crate::pose::error::Error;

/// Largest range the pose tables and the simulated board take, inches (well beyond the
/// NorthStar's use: at 100 in one frame's pose error is already inches).
pub const MAX_RANGE_IN: f64 = 1000.0;

/// Check a list of ranges given as `flag` (each `0 < r <= MAX_RANGE_IN`, at least one).
pub fn check_ranges(flag: &str, ranges: &[f64]) -> Result<(), Error> {
    if ranges.is_empty() {
        return Err(Error::Option(format!(
            "{flag}: give at least one range, inches"
        )));
    }
    for &r in ranges {
        if !(r > 0.0 && r <= MAX_RANGE_IN) {
            return Err(Error::Option(format!(
                "{flag} {r}: a range must be above 0 and at most {MAX_RANGE_IN} inches"
            )));
        }
    }
    Ok(())
}

/// Smallest spot noise of the pose tables, fraction of beta (the calibration's noise field
/// takes 0.01 counts and more).
pub const MIN_NOISE_FRACTION: f64 = 1e-6;
/// Largest spot noise of the pose tables, fraction of beta (the calibration's noise field
/// takes at most 10,000 counts).
pub const MAX_NOISE_FRACTION: f64 = 0.3;

/// Check `--noise-fraction` of the pose tables. Zero is refused: the solver weighs the spots
/// by 1 / noise^2 and the floor would be zero; the noise-free errors are the accuracy
/// table's systematic part.
pub fn check_noise_fraction(f: f64) -> Result<(), Error> {
    if !(MIN_NOISE_FRACTION..=MAX_NOISE_FRACTION).contains(&f) {
        return Err(Error::Option(format!(
            "--noise-fraction {f}: expected {MIN_NOISE_FRACTION:e} to {MAX_NOISE_FRACTION} of beta \
             (0 is not a table: the noise-free errors are the accuracy table's systematic part)"
        )));
    }
    Ok(())
}
