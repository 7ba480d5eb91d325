//! The Ch IV comparison: the 2-D angle uncertainty the apparatus budget causes (eq 40) against
//! the Ch II near-field error it must resolve, at the thesis's angles, and Figure 40.

use crate::budget::Budget;
use crate::plot::{write_svg, Panel, PlotError, Series};
use cta_core::nearfield2d::{Effect, Model2d};
use cta_core::pattern::Pattern;
use cta_core::real::rad;
use cta_core::uncertainty;
use std::path::Path;

/// The off-boresight angles of the Ch IV comparison, degrees.
pub const THETA_DEG: [f64; 2] = [6.0, 18.0];

/// The comparison at one angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AngleRow {
    /// Off-boresight angle, degrees.
    pub theta_deg: f64,
    /// Eq 40's angle uncertainty times the range, deg in.
    pub u_theta_times_r: f64,
    /// The combined near-field error (Lambertian beacon) over it.
    pub lambertian: f64,
    /// The same with the printed eq 17 quartic.
    pub quartic: f64,
}

/// The uncertainty budget's table: the budget, its root-sum-square (eq 26) and the eq 40 rows.
#[derive(Debug, Clone)]
pub struct UncertaintyTable {
    /// The budget.
    pub budget: Budget,
    /// Sensor diameter D, inches, relating the Ch II error (in D) to inches.
    pub diameter_in: f64,
    /// Root-sum-square per side, mils: X+, X-, Y+, Y-, Z+, Z-.
    pub rss_mils: [f64; 6],
    /// 1-sigma per axis, inches.
    pub rss_in: [f64; 3],
    /// Eq 40 and the near-field comparison at [`THETA_DEG`].
    pub rows: Vec<AngleRow>,
}

impl UncertaintyTable {
    /// Tabulate `budget` against the near-field error of a sensor of diameter `diameter_in`.
    pub fn new(budget: Budget, diameter_in: f64) -> UncertaintyTable {
        let rss_mils = budget.rss();
        let rss_in = budget.rss_inches();
        let [ux, _, uz] = rss_in;
        let nf = Model2d::thesis(Pattern::vsml3710());
        let nfq = Model2d::thesis(Pattern::Quartic);
        let rows = THETA_DEG
            .iter()
            .map(|&t| {
                let th = rad(t);
                let u = uncertainty::angle_2d(th.sin(), th.cos(), ux, uz).to_degrees();
                let e = nf.far_field_coeff_deg(Effect::Combined, th) * diameter_in;
                let eq = nfq.far_field_coeff_deg(Effect::Combined, th) * diameter_in;
                AngleRow {
                    theta_deg: t,
                    u_theta_times_r: u,
                    lambertian: e / u,
                    quartic: eq / u,
                }
            })
            .collect();
        UncertaintyTable {
            budget,
            diameter_in,
            rss_mils,
            rss_in,
            rows,
        }
    }

    /// Draw Figure 40 (the CTA angle uncertainty against the near-field error along the beacon
    /// ray, 1-100 in) to the SVG file `path`.
    pub fn plot(&self, path: &Path) -> Result<(), PlotError> {
        let [ux, _, uz] = self.rss_in;
        let nf = Model2d::thesis(Pattern::vsml3710());
        let range: Vec<f64> = (0..=60).map(|k| 10f64.powf(k as f64 / 30.0)).collect();
        let panels: Vec<Panel> = self
            .rows
            .iter()
            .map(|row| {
                let t = row.theta_deg;
                let th = rad(t);
                let cta: Vec<(f64, f64)> = range
                    .iter()
                    .map(|&r| {
                        (
                            r,
                            uncertainty::angle_2d(r * th.sin(), r * th.cos(), ux, uz).to_degrees(),
                        )
                    })
                    .collect();
                let near: Vec<(f64, f64)> = range
                    .iter()
                    .map(|&r| {
                        (
                            r,
                            nf.error(Effect::Combined, th, r / self.diameter_in)
                                .abs()
                                .to_degrees(),
                        )
                    })
                    .collect();
                Panel {
                    title: format!("theta = {t} deg"),
                    x_desc: "range along the beacon ray (in)".into(),
                    y_desc: "angle (deg)".into(),
                    log_x: true,
                    log_y: true,
                    series: vec![
                        Series::new("combined near-field error (Lambertian)", near),
                        Series::dashed("CTA uncertainty (eq 40)", cta),
                    ],
                }
            })
            .collect();
        write_svg(
            path,
            "CTA angle uncertainty vs near-field error (thesis Figure 40)",
            &panels,
            2,
        )
    }
}
