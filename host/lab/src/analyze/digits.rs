//! How `cta analyze` prints an estimate with its 1-sigma (text and HTML; JSON keeps full
//! precision). `cta calibrate` and `cta fit` print theirs the same way.
//!
//! The convention: the 1-sigma is rounded to 2 significant digits and the estimate to the
//! same decimal place, so every printed digit of the estimate is one the data resolve, and
//! one more (`0.020064 +/- 0.000074`, `60.102 +/- 0.070`, `19687.3 +/- 3.6`).
//!
//! Fixed point when the larger of |estimate| and sigma lies in [1e-2, 1e5) and that needs at
//! most 6 decimals (at most one zero between the decimal point and the first digit). Otherwise exponent form with one exponent shared by
//! the estimate and the sigma, that of the larger of the two, so the two read side by side:
//! `(-1.08 +/- 0.62)e-4`, `(1.9980 +/- 0.0076)e-3`, `(0.8 +/- 6.6)e-5`. The threshold is on
//! magnitude, not on the sigma's place, so parameters of one kind (the `p`s near 1e-3, the
//! gains and offsets) print in one form in one table whatever their 1-sigma.
//!
//! [`pm`] joins the two (`(9.76 +/- 0.35)e-4`), for prose; [`pm_parts`] gives two numbers
//! that stand alone (`9.76e-4`, `0.35e-4`: the shared exponent on both), for table columns.
//!
//! An estimate that rounds to zero at that place prints as `0` with the sigma's decimals
//! (`0.00`, `(0.0 +/- 6.6)e-5`; no `-0`). A 1-sigma of 0 (a fixed parameter) prints the
//! estimate compactly with `0`; a non-finite or negative 1-sigma, or a non-finite estimate,
//! prints both as they are; an estimate with more digits than an f64 holds at the sigma's
//! place prints compactly beside the sigma in its own exponent form.

use super::g;

/// Fixed point only from this magnitude (of the larger of |estimate| and sigma) ...
const FIXED_MIN: f64 = 1e-2;
/// ... up to this one ...
const FIXED_MAX: f64 = 1e5;
/// ... and with at most this many decimals.
const FIXED_DECIMALS: i32 = 6;
/// Beyond this many units of the rounding place the estimate is printed compactly (the
/// digits would exceed what an f64 holds).
const MAX_UNITS: f64 = 1e15;

/// How an estimate and its 1-sigma are written.
enum Form {
    /// Both in fixed point, or (degenerate cases) each as it is.
    Plain(String, String),
    /// Mantissas of the estimate and sigma and their shared power of ten.
    Shared(String, String, i32),
}

/// `value PM sigma` (see the module documentation), e.g. `pm(0.020064, 7.4e-5, "+/-")` is
/// `0.020064 +/- 0.000074` and `pm(9.76e-4, 3.5e-5, "+/-")` is `(9.76 +/- 0.35)e-4`.
pub fn pm(v: f64, s: f64, pm: &str) -> String {
    match form(v, s) {
        Form::Plain(a, b) => format!("{a} {pm} {b}"),
        Form::Shared(a, b, e) => format!("({a} {pm} {b})e{e}"),
    }
}

/// The estimate and its 1-sigma as two numbers that stand alone, in [`pm`]'s form and
/// digits: `("9.76e-4", "0.35e-4")` (one exponent on both), or fixed point.
pub fn pm_parts(v: f64, s: f64) -> (String, String) {
    match form(v, s) {
        Form::Plain(a, b) => (a, b),
        Form::Shared(a, b, e) => (format!("{a}e{e}"), format!("{b}e{e}")),
    }
}

fn form(v: f64, s: f64) -> Form {
    if !v.is_finite() || !s.is_finite() || s < 0.0 {
        return Form::Plain(g(v), g(s));
    }
    if s == 0.0 {
        return Form::Plain(g(v), "0".into());
    }
    // Sigma to 2 significant digits as the formatter rounds it (9.96e-5 -> 1.0e-4): its
    // digits as an integer and the power of ten of the last one.
    let st = format!("{s:.1e}");
    let (mant, exp) = st.split_once('e').unwrap_or((&st, "0"));
    let ns: i64 = mant.replace('.', "").parse().unwrap_or(0);
    let q = exp.parse::<i32>().unwrap_or(0) - 1;
    let units = v / 10f64.powi(q);
    if !(units.abs() < MAX_UNITS) {
        return Form::Plain(g(v), sci(ns, q));
    }
    let n = units.round() as i64;
    let big = v.abs().max(s);
    if (FIXED_MIN..FIXED_MAX).contains(&big) && q >= -FIXED_DECIMALS {
        return Form::Plain(fixed(n, q), fixed(ns, q));
    }
    // The shared exponent: that of the leading digit of the larger of the two as rounded
    // (both have their last digit at 10^q), so its mantissa lies in [1, 10).
    let len = |k: i64| k.unsigned_abs().to_string().len() as i32;
    let e = q + len(n).max(len(ns)) - 1;
    Form::Shared(fixed(n, q - e), fixed(ns, q - e), e)
}

/// `n * 10^q` in fixed point with `max(0, -q)` decimals.
fn fixed(n: i64, q: i32) -> String {
    let sign = if n < 0 { "-" } else { "" };
    let digits = n.unsigned_abs().to_string();
    if n == 0 && q >= 0 {
        return "0".into();
    }
    if q >= 0 {
        return format!("{sign}{digits}{}", "0".repeat(q as usize));
    }
    let d = (-q) as usize;
    let padded = format!("{digits:0>w$}", w = d + 1);
    let (int, frac) = padded.split_at(padded.len() - d);
    format!("{sign}{int}.{frac}")
}

/// `n * 10^q` in exponent form with every digit of `n` (`0` for zero).
fn sci(n: i64, q: i32) -> String {
    if n == 0 {
        return "0".into();
    }
    let sign = if n < 0 { "-" } else { "" };
    let digits = n.unsigned_abs().to_string();
    let e = q + digits.len() as i32 - 1;
    let (first, rest) = digits.split_at(1);
    if rest.is_empty() {
        format!("{sign}{first}e{e}")
    } else {
        format!("{sign}{first}.{rest}e{e}")
    }
}

#[cfg(test)]
mod tests {
    use super::{pm, pm_parts};

    fn p(v: f64, s: f64) -> String {
        pm(v, s, "+/-")
    }

    #[test]
    fn fixed_point_to_the_second_digit_of_sigma() {
        assert_eq!(p(0.020064, 7.4e-5), "0.020064 +/- 0.000074");
        assert_eq!(p(0.997555, 0.002542), "0.9976 +/- 0.0025");
        assert_eq!(p(60.10213, 0.0701), "60.102 +/- 0.070");
        assert_eq!(p(0.174803, 1.4e-4), "0.17480 +/- 0.00014");
        assert_eq!(p(19687.270398, 3.565908), "19687.3 +/- 3.6");
        assert_eq!(p(44.93, 2.14), "44.9 +/- 2.1");
        // Sigma 10 or more: the estimate is rounded to tens (hundreds, ...) too.
        assert_eq!(p(12345.6, 230.0), "12350 +/- 230");
        assert_eq!(p(1234.4, 17.0), "1234 +/- 17");
    }

    #[test]
    fn sigma_rounding_up_to_the_next_decade_moves_the_place() {
        // 0.0996 is 0.10 at 2 significant digits: the estimate goes to 0.01, not 0.001.
        assert_eq!(p(1.23456, 0.0996), "1.23 +/- 0.10");
        assert_eq!(p(1.23456, 0.0994), "1.235 +/- 0.099");
    }

    #[test]
    fn negative_values_and_rounding_to_zero() {
        assert_eq!(p(-0.07, 0.14), "-0.07 +/- 0.14");
        assert_eq!(p(-0.503441, 0.002543), "-0.5034 +/- 0.0025");
        // A negative estimate below the rounding place is 0, not -0.
        assert_eq!(p(-0.0004, 0.14), "0.00 +/- 0.14");
        assert_eq!(p(-3e-7, 6.6e-5), "(0.0 +/- 6.6)e-5");
        assert_eq!(p(-1.5e-8, 8.9e-8), "(-1.5 +/- 8.9)e-8");
    }

    #[test]
    fn small_magnitudes_share_one_exponent() {
        assert_eq!(p(-1.08e-4, 6.2e-5), "(-1.08 +/- 0.62)e-4");
        assert_eq!(p(8e-6, 6.6e-5), "(0.8 +/- 6.6)e-5");
        assert_eq!(p(1e-5, 5e-7), "(1.000 +/- 0.050)e-5");
        assert_eq!(p(9.9242e-4, 7.5709e-6), "(9.924 +/- 0.076)e-4");
        assert_eq!(p(0.001998, 7.6371e-6), "(1.9980 +/- 0.0076)e-3");
        assert_eq!(p(12.3, 1e-9), "(1.23000000000 +/- 0.00000000010)e1");
        assert_eq!(p(3.2e-12, 1.1e-13), "(3.20 +/- 0.11)e-12");
        // The sigma rounding up to the next decade moves the exponent with it.
        assert_eq!(p(1e-6, 9.96e-6), "(0.1 +/- 1.0)e-5");
    }

    #[test]
    fn one_form_for_one_kind_of_parameter() {
        // The review's case: p3 and its neighbour straddled 1e-3 and printed in two forms.
        assert_eq!(p(9.76e-4, 3.5e-5), "(9.76 +/- 0.35)e-4");
        assert_eq!(p(-0.001129, 5.2e-5), "(-1.129 +/- 0.052)e-3");
        // ... and p's near 1e-3 stay in one form whether their sigma needs 6 or 7 decimals.
        assert_eq!(p(0.002065, 1.0e-5), "(2.065 +/- 0.010)e-3");
        assert_eq!(p(0.0010017, 7.0e-6), "(1.0017 +/- 0.0070)e-3");
        // From 0.01 up, fixed point (at most 6 decimals).
        assert_eq!(p(0.06292, 0.00023), "0.06292 +/- 0.00023");
        assert_eq!(p(0.0099, 0.0012), "(9.9 +/- 1.2)e-3");
    }

    #[test]
    fn large_magnitudes_in_exponent_form() {
        assert_eq!(p(123456.0, 230.0), "(1.2346 +/- 0.0023)e5");
        assert_eq!(p(-2.5e8, 3.3e6), "(-2.500 +/- 0.033)e8");
        // Far more digits than an f64 holds: the estimate compactly, each in its own form.
        assert_eq!(p(1e20, 1e-3), "1.0000e20 +/- 1.0e-3");
    }

    #[test]
    fn degenerate_sigmas() {
        assert_eq!(p(1.5, 0.0), "1.5 +/- 0");
        assert_eq!(p(-0.123456789, 0.0), "-0.123457 +/- 0");
        assert_eq!(p(1.5, f64::NAN), "1.5 +/- NaN");
        assert_eq!(p(1.5, f64::INFINITY), "1.5 +/- inf");
        assert_eq!(p(1.5, -0.1), "1.5 +/- -0.1");
        assert_eq!(p(f64::NAN, 0.1), "NaN +/- 0.1");
        assert_eq!(p(f64::NEG_INFINITY, 0.1), "-inf +/- 0.1");
        assert_eq!(p(0.0, 0.25), "0.00 +/- 0.25");
    }

    #[test]
    fn parts_match_the_joined_form() {
        let (v, s) = pm_parts(0.599994, 2.1075e-4);
        assert_eq!((v.as_str(), s.as_str()), ("0.59999", "0.00021"));
        assert_eq!(
            pm(0.599994, 2.1075e-4, "&plusmn;"),
            "0.59999 &plusmn; 0.00021"
        );
        // Exponent form: two numbers that stand alone, with the shared exponent.
        let (v, s) = pm_parts(9.76e-4, 3.5e-5);
        assert_eq!((v.as_str(), s.as_str()), ("9.76e-4", "0.35e-4"));
        assert_eq!(v.parse::<f64>().unwrap(), 9.76e-4);
        assert_eq!(s.parse::<f64>().unwrap(), 3.5e-5);
        let (v, s) = pm_parts(-3e-7, 6.6e-5);
        assert_eq!((v.as_str(), s.as_str()), ("0.0e-5", "6.6e-5"));
    }
}
