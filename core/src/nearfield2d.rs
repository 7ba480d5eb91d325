//! The thesis Ch II two-dimensional near-field error model (eqs 1-22).
//!
//! Two PV cells of a cosine-type pyramid sensor, normals `n1 = [sin a, cos a]`,
//! `n2 = [-sin a, cos a]` (eq 2), centres at `+/- D/2` on the X axis. All lengths are in
//! *sensor diameters* `D` (the distance between the two cell centres; REFERENCE.md 2.5:
//! `D = 2 s = 0.35 in` for the NorthStar). A beacon sits at distance `R` from the sensor
//! origin, `theta` off boresight: `b_inf = R [sin theta, cos theta]` (eq 1).
//!
//! Far field (eqs 3-6): `X_inf = (V1 - V2)/(V1 + V2) = tan a tan theta`, and with the
//! scale height `H = X_inf / tan theta = tan a` (eq 5), `theta_inf = atan(X_inf / H) = theta`.
//!
//! Each near-field effect replaces `X_inf` by a perturbed `X` and gives the error
//! `delta theta = theta_inf - atan(X / H)` (eqs 12, 16, 21):
//! - proximity (eqs 7-12): each cell sees the beacon along its own `b_k = b_inf - d_k`;
//! - intensity (eqs 13-16): inverse-square intensity `I_k = 1/|b_k|^2` per cell, with the
//!   *far-field* voltages of eq 3 (REFERENCE.md 2.3: the thesis's ~100 D reproduces only so);
//! - non-uniform beacon (eqs 17-22): the beacon's radiation pattern `c_k = P(gamma_k)`,
//!   `gamma_k` the angle between the beacon boresight (facing the sensor plane, `-y`) and
//!   the ray beacon -> cell k, with far-field voltages and intensities;
//! - combined: the thesis formulates the three so that they add (Ch II, Figure 23), so the
//!   combined error is their sum.
//!
//! With the convex pairing printed in the thesis all three errors have one sign: the beacon
//! appears *farther* off boresight (`delta theta < 0`).

use crate::pattern::Pattern;
use crate::real::{deg, rad};
use crate::Real;

/// The near-field effects of Ch II.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Effect {
    /// Beacon proximity (parallax between the cells), eqs 7-12.
    Proximity,
    /// Inverse-square intensity differences between the cells, eqs 13-16.
    Intensity,
    /// Non-uniform beacon radiation pattern, eqs 17-22.
    Pattern,
    /// The sum of the three (Figure 23).
    Combined,
}

impl Effect {
    /// All effects, in report order.
    pub const ALL: [Effect; 4] = [
        Effect::Proximity,
        Effect::Intensity,
        Effect::Pattern,
        Effect::Combined,
    ];
    /// Name used in output.
    pub fn name(self) -> &'static str {
        match self {
            Effect::Proximity => "proximity",
            Effect::Intensity => "intensity",
            Effect::Pattern => "pattern",
            Effect::Combined => "combined",
        }
    }
}

/// The 2-D sensor of Ch II.
#[derive(Debug, Clone, Copy)]
pub struct Model2d<T> {
    /// Cell tilt `a` (radians), 30 deg in the thesis.
    pub alpha: T,
    /// Distance of each cell centre from the origin, in D (0.5: cells one diameter apart).
    pub half_sep: T,
    /// Beacon radiation pattern.
    pub pattern: Pattern<T>,
}

impl<T: Real> Model2d<T> {
    /// The thesis's sensor: `a = 30 deg`, cells one diameter apart, given pattern.
    pub fn thesis(pattern: Pattern<T>) -> Self {
        Model2d {
            alpha: rad(T::lit(30.0)),
            half_sep: T::lit(0.5),
            pattern,
        }
    }

    /// Scale height `H = tan a` (eq 5 with `X_inf = tan a tan theta`).
    pub fn h(&self) -> T {
        self.alpha.tan()
    }

    fn normals(&self) -> [[T; 2]; 2] {
        let (s, c) = (self.alpha.sin(), self.alpha.cos());
        [[s, c], [-s, c]]
    }

    /// Far-field output `X_inf` (eq 4) for a beacon `theta` radians off boresight.
    pub fn x_inf(&self, theta: T) -> T {
        let b = [theta.sin(), theta.cos()];
        let [n1, n2] = self.normals();
        let v1 = n1[0] * b[0] + n1[1] * b[1];
        let v2 = n2[0] * b[0] + n2[1] * b[1];
        (v1 - v2) / (v1 + v2)
    }

    /// Perturbed output `X` for one effect (not `Combined`) at range `r` (in D).
    pub fn x_effect(&self, effect: Effect, theta: T, r: T) -> T {
        let binf = [r * theta.sin(), r * theta.cos()];
        let cells = [[self.half_sep, T::zero()], [-self.half_sep, T::zero()]];
        let normals = self.normals();
        let unit = |v: [T; 2]| {
            let n = (v[0] * v[0] + v[1] * v[1]).sqrt();
            [v[0] / n, v[1] / n]
        };
        let dot = |a: [T; 2], b: [T; 2]| a[0] * b[0] + a[1] * b[1];
        let binf_hat = unit(binf);
        let mut sig = [T::zero(); 2];
        for k in 0..2 {
            let bk = [binf[0] - cells[k][0], binf[1] - cells[k][1]];
            let v_far = dot(normals[k], binf_hat);
            sig[k] = match effect {
                // eqs 7-8: each cell's own direction to the beacon (its voltage, eq 9).
                Effect::Proximity => dot(normals[k], unit(bk)),
                // eqs 14-15: I_k V_k with the far-field V of eq 3.
                Effect::Intensity => v_far / dot(bk, bk),
                // eq 20: c_k from the angle between the beacon boresight (-y) and the ray
                // beacon -> cell k; I_inf cancels.
                Effect::Pattern => self.pattern.eval(Self::gamma(bk)) * v_far,
                Effect::Combined => unreachable!("combined is the sum of the errors"),
            };
        }
        (sig[0] - sig[1]) / (sig[0] + sig[1])
    }

    /// Angle (radians) between the beacon's boresight (-y) and the ray beacon -> cell, for
    /// the cell-to-beacon vector `bk` (eq 20's gamma).
    fn gamma(bk: [T; 2]) -> T {
        let n = (bk[0] * bk[0] + bk[1] * bk[1]).sqrt();
        (bk[1] / n).max(-T::one()).min(T::one()).acos()
    }

    /// The largest angle (radians) off the beacon's boresight at which the pattern effect
    /// evaluates the beacon pattern (eq 20's gamma, over both cells) for a beacon `theta`
    /// radians off the sensor's boresight at range `r` (D). Close in it exceeds `theta`: the
    /// printed quartic's validity (see [`Pattern::out_of_range`]) depends on it, not on
    /// `theta` alone.
    pub fn pattern_angle(&self, theta: T, r: T) -> T {
        let binf = [r * theta.sin(), r * theta.cos()];
        let g = |cx: T| Self::gamma([binf[0] - cx, binf[1]]);
        let (a, b) = (g(self.half_sep), g(-self.half_sep));
        if a > b {
            a
        } else {
            b
        }
    }

    /// Error in angle `delta theta = theta_inf - theta_effect` (radians) at range `r` (D)
    /// for a beacon `theta` radians off boresight (eqs 12, 16, 21; combined = their sum).
    pub fn error(&self, effect: Effect, theta: T, r: T) -> T {
        match effect {
            Effect::Combined => {
                self.error(Effect::Proximity, theta, r)
                    + self.error(Effect::Intensity, theta, r)
                    + self.error(Effect::Pattern, theta, r)
            }
            e => {
                let h = self.h();
                (self.x_inf(theta) / h).atan() - (self.x_effect(e, theta, r) / h).atan()
            }
        }
    }

    /// Far-field coefficient `lim R -> inf of R |delta theta|`, in deg x D: the error falls as
    /// `coeff / R`. Evaluated by Richardson extrapolation from two large ranges.
    pub fn far_field_coeff_deg(&self, effect: Effect, theta: T) -> T {
        let r1 = T::lit(1e4);
        let r2 = T::lit(2e4);
        let c1 = r1 * self.error(effect, theta, r1).abs();
        let c2 = r2 * self.error(effect, theta, r2).abs();
        deg(T::lit(2.0) * c2 - c1)
    }

    /// The outermost distance (D) at which `|delta theta|` of `effect` falls to `noise`
    /// radians: beyond it the effect is below the noise. `None` if there is no crossing
    /// between `r_min` D and [`CROSSING_MAX_D`] ([`Self::crossing`] says which side).
    pub fn crossing_distance(&self, effect: Effect, theta: T, noise: T, r_min: T) -> Option<T> {
        match self.crossing(effect, theta, noise, r_min) {
            Crossing::At(r) => Some(r),
            Crossing::BelowNoise | Crossing::AboveNoise => None,
        }
    }

    /// Where `|delta theta|` of `effect` falls to `noise` radians, searched from
    /// [`CROSSING_MAX_D`] inwards to `r_min` D: the outermost crossing, or which side of the
    /// noise the effect stays on over the whole span.
    pub fn crossing(&self, effect: Effect, theta: T, noise: T, r_min: T) -> Crossing<T> {
        let f = |r: T| self.error(effect, theta, r).abs() - noise;
        let mut hi = T::lit(CROSSING_MAX_D);
        if f(hi) > T::zero() {
            return Crossing::AboveNoise;
        }
        // Walk inwards geometrically to bracket the outermost crossing.
        let step = T::lit(1.1);
        let mut lo = hi / step;
        while f(lo) <= T::zero() {
            hi = lo;
            lo /= step;
            if lo < r_min {
                return Crossing::BelowNoise;
            }
        }
        for _ in 0..200 {
            let mid = (lo + hi) / T::lit(2.0);
            if f(mid) > T::zero() {
                lo = mid;
            } else {
                hi = mid;
            }
            if (hi - lo) <= T::lit(1e-10) * hi {
                break;
            }
        }
        Crossing::At((lo + hi) / T::lit(2.0))
    }
}

/// Outer end (D) of the span [`Model2d::crossing`] searches.
pub const CROSSING_MAX_D: f64 = 1e7;

/// Outcome of [`Model2d::crossing`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Crossing<T> {
    /// The effect falls below the noise beyond this distance, D.
    At(T),
    /// The effect is below the noise over the whole span searched.
    BelowNoise,
    /// The effect is still above the noise at [`CROSSING_MAX_D`] (a noise level far below
    /// the effect's far-field tail, which falls as 1/R).
    AboveNoise,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eq 20's gamma, worked by hand: a beacon on the boresight at 1 D sees each cell (0.5 D
    /// off the axis) atan(0.5) = 26.57 deg off its own axis; at 30 deg and 2 D the farther
    /// cell's ray is atan2(1 + 0.5, 1.732) = 40.89 deg; far away the angle is theta.
    #[test]
    fn pattern_angle_is_the_ray_to_the_farther_cell() {
        let m = Model2d::thesis(Pattern::<f64>::Quartic);
        let deg = |t: f64, r: f64| m.pattern_angle(rad(t), r).to_degrees();
        assert!((deg(0.0, 1.0) - 0.5f64.atan().to_degrees()).abs() < 1e-12);
        let want = 1.5f64.atan2(3f64.sqrt()).to_degrees();
        assert!((deg(30.0, 2.0) - want).abs() < 1e-12, "{}", deg(30.0, 2.0));
        assert!((deg(30.0, 1e7) - 30.0).abs() < 1e-5);
    }

    #[test]
    fn a_tiny_noise_is_above_noise_not_below_it() {
        let m = Model2d {
            alpha: rad(30.0),
            half_sep: 0.5,
            pattern: Pattern::vsml3710(),
        };
        let th = rad(18.0);
        // 1e-7 deg: the 1/R tail is still above it at 1e7 D.
        assert_eq!(
            m.crossing(Effect::Proximity, th, rad(1e-7), 0.6),
            Crossing::AboveNoise
        );
        // 90 deg: nothing ever exceeds it.
        assert_eq!(
            m.crossing(Effect::Proximity, th, rad(90.0), 0.6),
            Crossing::BelowNoise
        );
        assert!(matches!(
            m.crossing(Effect::Proximity, th, rad(0.1), 0.6),
            Crossing::At(r) if r > 1.0 && r < 1e3
        ));
    }

    fn within(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * b.abs()
    }

    #[test]
    fn far_field_is_exact() {
        let m = Model2d::<f64>::thesis(Pattern::Uniform);
        for t in [6.0, 18.0, 30.0, 45.0] {
            let th = rad(t);
            assert!((m.x_inf(th) - rad(30.0f64).tan() * th.tan()).abs() < 1e-12);
            for e in Effect::ALL {
                assert!(m.error(e, th, 1e9).abs() < 1e-8);
            }
        }
    }

    #[test]
    fn convex_pairing_errors_have_one_sign() {
        let m = Model2d::<f64>::thesis(Pattern::vsml3710());
        for t in [6.0, 18.0, 30.0] {
            for e in Effect::ALL {
                assert!(m.error(e, rad(t), 50.0) < 0.0, "{:?} at {t}", e);
            }
        }
    }

    /// REFERENCE.md section 3, Ch II table (printed quartic, noise 0.1 deg).
    #[test]
    fn reference_crossings_and_coefficients() {
        let m = Model2d::<f64>::thesis(Pattern::Quartic);
        let noise = rad(0.1);
        let thetas = [6.0, 18.0, 30.0, 45.0];
        let prox = [68.5, 184.9, 247.8, 233.4];
        let inten = [102.2, 267.4, 330.3, 233.1];
        let comb = [203.6, 766.5, 2041.0, 716.4];
        let kp = [6.84, 18.49, 24.81, 23.39];
        let ki = [10.22, 26.76, 33.08, 23.39];
        for i in 0..4 {
            let th = rad(thetas[i]);
            let cp = m
                .crossing_distance(Effect::Proximity, th, noise, 0.6)
                .unwrap();
            let ci = m
                .crossing_distance(Effect::Intensity, th, noise, 0.6)
                .unwrap();
            let cc = m
                .crossing_distance(Effect::Combined, th, noise, 0.6)
                .unwrap();
            assert!(within(cp, prox[i], 0.02), "proximity {} -> {cp}", thetas[i]);
            assert!(
                within(ci, inten[i], 0.02),
                "intensity {} -> {ci}",
                thetas[i]
            );
            assert!(within(cc, comb[i], 0.03), "combined {} -> {cc}", thetas[i]);
            let fp = m.far_field_coeff_deg(Effect::Proximity, th);
            let fi = m.far_field_coeff_deg(Effect::Intensity, th);
            assert!(
                within(fp, kp[i], 0.005),
                "coeff proximity {} -> {fp}",
                thetas[i]
            );
            assert!(
                within(fi, ki[i], 0.005),
                "coeff intensity {} -> {fi}",
                thetas[i]
            );
        }
        // Ratios at 6 deg: proximity/non-uniform 2.07, intensity/non-uniform 3.10 (5 %).
        let th = rad(6.0);
        let kn = m.far_field_coeff_deg(Effect::Pattern, th);
        assert!(within(
            m.far_field_coeff_deg(Effect::Proximity, th) / kn,
            2.07,
            0.05
        ));
        assert!(within(
            m.far_field_coeff_deg(Effect::Intensity, th) / kn,
            3.10,
            0.05
        ));
        // With the Lambertian default the combined crossing at 6 deg is 221.7 D.
        let ml = Model2d::<f64>::thesis(Pattern::vsml3710());
        let cl = ml
            .crossing_distance(Effect::Combined, th, noise, 0.6)
            .unwrap();
        assert!(within(cl, 221.7, 0.03), "lambertian combined -> {cl}");
    }
}
