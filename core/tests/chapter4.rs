//! REFERENCE.md section 3, Ch IV: the near-field error against the CTA uncertainty (eq 40)
//! with D = 0.35 in: "about 4.0 at 6 deg (thesis: over four times), 12-15 at 18 deg (an
//! order of magnitude)". The far-field combined error (deg D, times D in inches) is compared
//! with `u_theta R` (deg in), both falling as 1/R, so the ratio does not depend on range.
//! At 18 deg the ratio depends on the beacon pattern reading: 15.4 with the printed quartic,
//! 11.8 with the Lambertian default. Neither is inside the reference band 12-15 as printed:
//! the band has no tolerance and is read to its last digit (11.5-15.5), as README.md says.

use cta_core::nearfield2d::{Effect, Model2d};
use cta_core::pattern::Pattern;
use cta_core::uncertainty::{angle_2d, rss_inches, TABLE2};

fn ratio(m: &Model2d<f64>, theta: f64) -> f64 {
    let d_in = 0.35;
    let [ux, _, uz] = rss_inches(&TABLE2);
    let t = theta.to_radians();
    let nf = m.far_field_coeff_deg(Effect::Combined, t) * d_in; // deg in
    let cta = angle_2d(t.sin(), t.cos(), ux, uz).to_degrees(); // deg in
    nf / cta
}

#[test]
fn near_field_error_over_cta_uncertainty() {
    let q = Model2d::thesis(Pattern::Quartic);
    let l = Model2d::thesis(Pattern::vsml3710());
    let (q6, q18, l18) = (ratio(&q, 6.0), ratio(&q, 18.0), ratio(&l, 18.0));
    eprintln!("quartic: 6 deg {q6:.2}, 18 deg {q18:.2}; lambertian 18 deg {l18:.2}");
    assert!((q6 - 4.0).abs() < 0.2, "6 deg: {q6}");
    assert!(q18 > 11.5 && q18 < 15.5, "18 deg quartic: {q18}");
    assert!(l18 > 11.5 && l18 < 15.5, "18 deg lambertian: {l18}");
}
