//! The Ch II table: how far away each near-field effect (proximity, intensity, beacon pattern)
//! falls below the sensor noise, in the 2-D model of eqs 1-22, with the far-field coefficients
//! and the Figures 14-24 curves.

use crate::plot::{write_svg, Panel, PlotError, Series};
use crate::sim::describe_pattern;
use cta_core::nearfield2d::{Crossing, Effect, Model2d, CROSSING_MAX_D};
use cta_core::pattern::{Pattern, QUARTIC_VALID_DEG};
use cta_core::real::rad;
use std::path::Path;

/// The nearest distance (D) the table evaluates: the crossing search's inner end.
pub const NEAREST_D: f64 = 0.6;

/// The nearest distance (D) the plot draws.
pub const PLOT_NEAREST_D: f64 = 3.0;

/// What to tabulate. The caller checks the ranges: `alpha_deg` in (0, 90), every theta in
/// (0, 90 - alpha), `noise_deg` > 0, `diameter_in` > 0.
#[derive(Debug, Clone)]
pub struct NearfieldOptions {
    /// Pyramid face angle a, degrees (eq 2).
    pub alpha_deg: f64,
    /// Off-boresight angles of the beacon, degrees.
    pub theta_deg: Vec<f64>,
    /// Sensor noise the errors are compared with, degrees.
    pub noise_deg: f64,
    /// Beacon radiation pattern for the non-uniform-beacon error.
    pub pattern: Pattern<f64>,
    /// Sensor diameter D, inches, to give distances in inches too.
    pub diameter_in: f64,
    /// Whether the curves will be drawn down to [`PLOT_NEAREST_D`]: the quartic's warning
    /// then covers the distances drawn.
    pub plotted: bool,
}

impl Default for NearfieldOptions {
    fn default() -> Self {
        NearfieldOptions {
            alpha_deg: 30.0,
            theta_deg: vec![6.0, 18.0, 30.0, 45.0],
            noise_deg: 0.1,
            pattern: Pattern::lambertian_half_angle(60.0),
            diameter_in: 0.35,
            plotted: false,
        }
    }
}

/// The Ch II table: per effect and theta, the distance beyond which the effect is below the
/// noise, and the far-field coefficients `R |delta theta|`.
#[derive(Debug, Clone)]
pub struct NearfieldTable {
    /// The options tabulated.
    pub options: NearfieldOptions,
    /// The 2-D sensor (cells at +/-0.5 D).
    pub model: Model2d<f64>,
    /// The beacon pattern in words.
    pub profile: String,
    /// Per effect ([`Effect::ALL`] order), the crossing at each theta.
    pub crossings: Vec<(Effect, Vec<Crossing<f64>>)>,
    /// Per effect (proximity, intensity, pattern), the far-field coefficient at each theta,
    /// deg D: the error falls as coeff / R.
    pub coefficients: Vec<(Effect, Vec<f64>)>,
    /// Things the reader must know (the printed quartic evaluated past its valid angle).
    pub warnings: Vec<String>,
}

impl NearfieldTable {
    /// Tabulate (eqs 1-22).
    pub fn new(options: &NearfieldOptions) -> NearfieldTable {
        let model = Model2d {
            alpha: rad(options.alpha_deg),
            half_sep: 0.5,
            pattern: options.pattern,
        };
        let thetas = &options.theta_deg;
        let noise = rad(options.noise_deg);
        // The nearest distance (D) evaluated for what is shown at each theta: the plot's, and
        // how far in each crossing search went (the outermost crossing: a step inside it).
        let start = if options.plotted {
            PLOT_NEAREST_D
        } else {
            f64::INFINITY
        };
        let mut nearest = vec![start; thetas.len()];
        let mut crossings = Vec::new();
        for e in Effect::ALL {
            let c: Vec<Crossing<f64>> = thetas
                .iter()
                .map(|t| model.crossing(e, rad(*t), noise, NEAREST_D))
                .collect();
            for (n, c) in nearest.iter_mut().zip(&c) {
                *n = n.min(match c {
                    Crossing::At(r) => r / 1.1,
                    Crossing::BelowNoise => NEAREST_D,
                    Crossing::AboveNoise => CROSSING_MAX_D,
                });
            }
            crossings.push((e, c));
        }
        let mut warnings = Vec::new();
        if options.pattern == Pattern::Quartic {
            let past = quartic_out_of_range(&model, thetas, &nearest, options.diameter_in);
            if !past.is_empty() {
                warnings.push(format!(
                    "the printed eq 17 quartic is evaluated past {QUARTIC_VALID_DEG} deg off the beacon's axis, where it is no \
                     longer a radiation pattern (0 at 37.8 deg, -4.93 at 60 deg; README, thesis inconsistency 1): pattern and \
                     combined errors there are not physical: {}",
                    past.join("; ")
                ));
            }
        }
        let coefficients = [Effect::Proximity, Effect::Intensity, Effect::Pattern]
            .into_iter()
            .map(|e| {
                let v = thetas
                    .iter()
                    .map(|t| model.far_field_coeff_deg(e, rad(*t)))
                    .collect();
                (e, v)
            })
            .collect();
        NearfieldTable {
            options: options.clone(),
            model,
            profile: describe_pattern(&model.pattern),
            crossings,
            coefficients,
            warnings,
        }
    }

    /// Draw the error-versus-distance curves (Figures 14-24) to the SVG file `path`.
    pub fn plot(&self, path: &Path) -> Result<(), PlotError> {
        let o = &self.options;
        let panels: Vec<Panel> = Effect::ALL
            .iter()
            .map(|&e| {
                let mut series: Vec<Series> = o
                    .theta_deg
                    .iter()
                    .map(|&t| {
                        let pts = (0..=120)
                            .map(|k| {
                                let r = PLOT_NEAREST_D * 10f64.powf(k as f64 / 40.0);
                                (r, self.model.error(e, rad(t), r).abs().to_degrees())
                            })
                            .collect();
                        Series::new(format!("theta = {t} deg"), pts)
                    })
                    .collect();
                series.push(Series::dashed(
                    format!("noise {} deg", o.noise_deg),
                    vec![(3.0, o.noise_deg), (3000.0, o.noise_deg)],
                ));
                Panel {
                    title: format!("|error in angle|: {}", e.name()),
                    x_desc: "beacon distance (sensor diameters D)".into(),
                    y_desc: "|delta theta| (deg)".into(),
                    log_x: true,
                    log_y: true,
                    series,
                }
            })
            .collect();
        write_svg(
            path,
            &format!(
                "Near-field errors, a = {} deg (thesis Figures 14-24)",
                o.alpha_deg
            ),
            &panels,
            2,
        )
    }
}

/// Where the printed quartic is evaluated past its valid angle in what the command shows: for
/// each `theta` (deg) whose pattern angle (the ray to the farther cell, eq 20) exceeds
/// [`QUARTIC_VALID_DEG`] at the nearest distance evaluated for it (`nearest`, D), the distance
/// inside which it does, in words.
fn quartic_out_of_range(
    model: &Model2d<f64>,
    thetas: &[f64],
    nearest: &[f64],
    diameter_in: f64,
) -> Vec<String> {
    let past = |th: f64, r: f64| model.pattern.out_of_range(model.pattern_angle(th, r));
    thetas
        .iter()
        .zip(nearest)
        .filter(|&(&t, &n)| past(rad(t), n))
        .map(|(&t, _)| {
            let th = rad(t);
            if past(th, CROSSING_MAX_D) {
                return format!("theta = {t} deg at every distance");
            }
            // The angle falls towards theta with distance: bisect on a log scale.
            let (mut lo, mut hi) = (NEAREST_D, CROSSING_MAX_D);
            for _ in 0..100 {
                let mid = (lo * hi).sqrt();
                if past(th, mid) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            format!(
                "theta = {t} deg closer than {hi:.1} D [{:.2} in]",
                hi * diameter_in
            )
        })
        .collect()
}
