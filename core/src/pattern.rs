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

    /// The half-intensity angle of `cos^m`: `acos(0.5^(1/m))`. By hand, `m = 2` is 45 deg
    /// (`cos^2 45 = 1/2`), `m = 1/2` is 75.52 deg (`cos = 1/4`) and `m = ln 0.5 / ln cos 20`
    /// (about 11.14) is 20 deg; the printed quartic's is 31.5 deg (REFERENCE.md 2.1) and the
    /// uniform source has none.
    #[test]
    fn half_angle_of_other_exponents() {
        let half = |m: f64| Pattern::Lambertian { m }.half_angle_deg().unwrap();
        assert!((half(2.0) - 45.0).abs() < 1e-12, "{}", half(2.0));
        assert!((half(0.5) - 0.25f64.acos().to_degrees()).abs() < 1e-12);
        assert!((half(0.5) - 75.522_487_814).abs() < 1e-8);
        let narrow = Pattern::<f64>::lambertian_half_angle(20.0);
        assert!((narrow.half_angle_deg().unwrap() - 20.0).abs() < 1e-9);
        match narrow {
            Pattern::Lambertian { m } => {
                assert!((m - 0.5f64.ln() / 20f64.to_radians().cos().ln()).abs() < 1e-12);
                assert!((m - 11.1434).abs() < 1e-4, "{m}");
            }
            _ => unreachable!(),
        }
        assert_eq!(Pattern::<f64>::Quartic.half_angle_deg(), Some(31.5));
        assert_eq!(Pattern::<f64>::Uniform.half_angle_deg(), None);
        assert_eq!(Pattern::<f64>::vsml3710(), Pattern::Lambertian { m: 1.0 });
    }

    /// `cos^m` for `m` other than 1: `cos^2 60 = 1/4`, `cos^0.5 60 = sqrt(1/2)`; 0 behind
    /// the LED whatever `m`; the uniform source is 1 everywhere.
    #[test]
    fn lambertian_of_other_exponents_and_uniform() {
        let p2 = Pattern::Lambertian { m: 2.0f64 };
        assert!((p2.eval(rad(60.0)) - 0.25).abs() < 1e-15);
        assert!((p2.eval(rad(-60.0)) - 0.25).abs() < 1e-15);
        let ph = Pattern::Lambertian { m: 0.5f64 };
        assert!((ph.eval(rad(60.0)) - 0.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(p2.eval(rad(120.0)), 0.0);
        assert_eq!(ph.eval(rad(180.0)), 0.0);
        assert_eq!(p2.eval(0.0), 1.0);
        for g in [0.0f64, 45.0, 120.0, 180.0] {
            assert_eq!(Pattern::<f64>::Uniform.eval(rad(g)), 1.0);
        }
    }

    /// The quartic by hand at 10 deg: `-0.004 - 0.004 + 0.005 - 0.01 + 1 = 0.987`; at
    /// 20 deg: `-0.064 - 0.032 + 0.02 - 0.02 + 1 = 0.904`. Only the quartic has a valid range.
    #[test]
    fn quartic_by_hand_and_only_it_has_a_range() {
        assert!((quartic_eq17(10.0f64) - 0.987).abs() < 1e-14);
        assert!((quartic_eq17(20.0f64) - 0.904).abs() < 1e-14);
        assert!((Pattern::<f64>::Quartic.eval(rad(20.0)) - 0.904).abs() < 1e-12);
        let q = Pattern::<f64>::Quartic;
        assert!(q.out_of_range(rad(-40.0)));
        assert!(!q.out_of_range(rad(-20.0)));
        // "Past 31 deg": 31 deg itself (which round-trips exactly in f64) is in range, the
        // next angle up is not.
        let at = rad(QUARTIC_VALID_DEG);
        assert_eq!(deg(at), 31.0);
        assert!(!q.out_of_range(at) && !q.out_of_range(-at));
        assert!(q.out_of_range(f64::from_bits(at.to_bits() + 1)));
        for p in [Pattern::vsml3710(), Pattern::<f64>::Uniform] {
            assert!(!p.out_of_range(rad(40.0)) && !p.out_of_range(rad(89.0)));
        }
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
