//! Beacon radiation patterns: the relative radiant intensity `c = P(gamma)` of an LED at
//! angle `gamma` off its boresight (thesis Ch II, eq 17 and eq 20).
//!
//! The default is the generalized Lambertian `P(g) = cos^m g` with
//! `m = ln 0.5 / ln cos(g_half)`; the VSML3710's half-intensity angle of 60 deg gives `m = 1`.
//! The thesis's printed quartic (eq 17) is kept for reproduction only: REFERENCE.md 2.1
//! shows it is not a 60 deg half-intensity profile (0.5 at 31.5 deg, 0 at 37.8 deg, -4.93 at
//! 60 deg — its coefficients look rounded to one significant figure).

use crate::real::{deg, rad};
use crate::Real;

/// Angle (deg) past which the printed quartic stops being a radiation pattern.
pub const QUARTIC_VALID_DEG: f64 = 31.0;

/// A beacon radiation pattern.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pattern<T> {
    /// Generalized Lambertian `cos^m gamma` (0 behind the LED).
    Lambertian {
        /// Exponent `m = ln 0.5 / ln cos(g_half)`.
        m: T,
    },
    /// An isotropic source: `c = 1` everywhere (the thesis's "uniform" beacon).
    Uniform,
    /// The thesis's printed eq 17 quartic with `gamma` in degrees. Reproduction only.
    Quartic,
}

impl<T: Real> Pattern<T> {
    /// Lambertian pattern from a half-intensity angle in degrees (must be in (0, 90)).
    pub fn lambertian_half_angle(half_deg: T) -> Self {
        let m = T::lit(0.5).ln() / rad(half_deg).cos().ln();
        Pattern::Lambertian { m }
    }

    /// The default: Lambertian with the VSML3710's 60 deg half-intensity angle (`m = 1`).
    pub fn vsml3710() -> Self {
        Pattern::Lambertian { m: T::one() }
    }

    /// Half-intensity angle in degrees, where defined.
    pub fn half_angle_deg(&self) -> Option<T> {
        match *self {
            Pattern::Lambertian { m } => Some(deg((T::lit(0.5).ln() / m).exp().acos())),
            Pattern::Uniform => None,
            Pattern::Quartic => Some(T::lit(31.5)),
        }
    }

    /// Relative intensity at `gamma` radians off the LED boresight.
    #[inline]
    pub fn eval(&self, gamma: T) -> T {
        match *self {
            Pattern::Lambertian { m } => {
                let c = gamma.cos();
                if c <= T::zero() {
                    T::zero()
                } else if m == T::one() {
                    c
                } else {
                    c.powf(m)
                }
            }
            Pattern::Uniform => T::one(),
            Pattern::Quartic => quartic_eq17(deg(gamma)),
        }
    }

    /// Whether evaluating at `gamma` (radians) is outside the pattern's valid range (only the
    /// printed quartic has one: past ~31 deg it is no longer a radiation pattern).
    pub fn out_of_range(&self, gamma: T) -> bool {
        matches!(self, Pattern::Quartic) && deg(gamma.abs()) > T::lit(QUARTIC_VALID_DEG)
    }
}

/// Eq 17 as printed, `gamma` in degrees:
/// `c = -4e-7 g^4 - 4e-6 g^3 + 5e-5 g^2 - 1e-3 g + 1`.
#[inline]
pub fn quartic_eq17<T: Real>(g: T) -> T {
    let g2 = g * g;
    T::lit(-4e-7) * g2 * g2 - T::lit(4e-6) * g2 * g + T::lit(5e-5) * g2 - T::lit(1e-3) * g
        + T::one()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lambertian_60_is_cosine() {
        let p = Pattern::<f64>::lambertian_half_angle(60.0);
        match p {
            Pattern::Lambertian { m } => assert!((m - 1.0).abs() < 1e-12),
            _ => unreachable!(),
        }
        assert!((p.eval(rad(60.0)) - 0.5).abs() < 1e-12);
        assert!((p.half_angle_deg().unwrap() - 60.0).abs() < 1e-9);
        let narrow = Pattern::<f64>::lambertian_half_angle(20.0);
        assert!((narrow.eval(rad(20.0)) - 0.5).abs() < 1e-12);
        assert_eq!(p.eval(rad(95.0)), 0.0);
    }

    #[test]
    fn quartic_is_not_a_60_degree_pattern() {
        // REFERENCE.md 2.1: 0.5 at 31.5 deg, 0 at 37.8 deg, -4.93 at 60 deg.
        assert!((quartic_eq17(31.5f64) - 0.5).abs() < 0.01);
        assert!(quartic_eq17(37.8f64).abs() < 0.01);
        assert!((quartic_eq17(60.0f64) + 4.93).abs() < 0.01);
        let q = Pattern::<f64>::Quartic;
        assert!(q.out_of_range(rad(40.0)));
        assert!(!q.out_of_range(rad(20.0)));
    }
}
