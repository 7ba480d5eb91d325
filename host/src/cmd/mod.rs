//! One module a command: its clap arguments, the library call, and the rendering of the
//! result as text or JSON.

pub mod analyze;
pub mod beacon;
pub mod calibrate;
pub mod capture;
pub mod completions;
pub mod demo;
pub mod evaluate;
pub mod fit;
pub mod nearfield;
pub mod noise;
pub mod pose;
pub mod sensor;
pub mod simulate;
pub mod sweep;
pub mod uncertainty;

/// `v` with `prec` decimals right-aligned in `width`, or `missing` (e.g. `-`, `undefined`)
/// when it is not a finite number: a figure that does not exist (the spread of one point,
/// the correlation of an axis that does not vary) is said, never printed as NaN or inf.
pub fn num(v: f64, width: usize, prec: usize, missing: &str) -> String {
    if v.is_finite() {
        format!("{v:>width$.prec$}")
    } else {
        format!("{missing:>width$}")
    }
}

#[cfg(test)]
mod tests {
    /// A number prints as `{:>w.p}` would; NaN and infinities print the stand-in.
    #[test]
    fn a_number_that_does_not_exist_is_said() {
        assert_eq!(super::num(1.23456, 8, 2, "-"), "    1.23");
        assert_eq!(super::num(f64::NAN, 6, 2, "-"), "     -");
        assert_eq!(super::num(f64::INFINITY, 0, 1, "undefined"), "undefined");
        assert_eq!(super::num(f64::NEG_INFINITY, 0, 1, "n/a"), "n/a");
    }
}
