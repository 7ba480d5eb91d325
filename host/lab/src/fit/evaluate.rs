//! The error in angle of a fit (eq 67) per separation against the CTA's own uncertainty (eq 36):
//! the thesis's Figure 57.

use crate::data::{fmt_list, Dataset, Sample, RAIL};
use crate::plot::{write_svg, Panel, PlotError, Series};
use cta_core::collinearity::{self, Params};
use cta_core::emulator::Emulator;
use cta_core::pose::Calibration;
use cta_core::uncertainty;
use nalgebra::Vector3;
use serde::Serialize;
use std::path::Path;

/// Figure 57 for one fit: per separation, the standard deviation over the reports of the
/// error in angle (eq 67) and the mean CTA angle uncertainty (eq 36, Table 2 or a lab's own
/// budget).
#[derive(Debug, Clone, Serialize)]
pub struct Evaluation {
    /// Separations, inches.
    pub separation_in: Vec<f64>,
    /// Standard deviation of the error in angle, degrees.
    pub angle_std_deg: Vec<f64>,
    /// Mean error in angle, degrees.
    pub angle_mean_deg: Vec<f64>,
    /// Mean CTA angle uncertainty (eq 36 with the budget), degrees.
    pub cta_uncertainty_deg: Vec<f64>,
    /// Reports per separation.
    pub reports: Vec<usize>,
    /// Reports with an output at the 16-bit rail (|count| >= 32767: a cell in shadow). By
    /// default they are among `reports`, as the thesis's Figure 57 counts every report, but
    /// their error in angle is that of a clipped output, not a measurement; with
    /// `rail_left_out` they are not among `reports` and not in the statistics.
    pub at_rail: Vec<usize>,
    /// Whether reports at the rail were left out (`cta evaluate --without-rail`).
    pub rail_left_out: bool,
    /// Separations left out of the table because every report there is at the rail (only with
    /// `rail_left_out`), inches.
    pub all_at_rail_in: Vec<f64>,
    /// Where the angle is measured from ([`Reference::name`]): "truth" (the file's truth
    /// sidecar), "head" (the head centre measured on the CTA, `--head`) or "fit" (the fit's
    /// own eye point: only the model's consistency with itself, not Figure 57's error).
    pub reference: String,
    /// The point the angle is measured from, inches in N (the truth's head, `--head`, or the
    /// fit's eye point).
    pub reference_in: [f64; 3],
    /// The CTA uncertainty budget behind `cta_uncertainty_deg`: "thesis Table 2" or the file.
    pub budget: String,
    /// The model whose directions are evaluated: "pinhole (eq 65)" or "near-field (eqs
    /// 60-63)".
    pub model: String,
    /// Reports per separation whose direction the model could not give (the near-field
    /// model has no beacon position on the plate that reproduces them, e.g. an output at the
    /// rail); left out of `reports` and the statistics.
    pub unsolved: Vec<usize>,
    /// Separations left out because the model gave no report there a direction, inches.
    pub all_unsolved_in: Vec<f64>,
}

impl Evaluation {
    /// Per separation with reports at the rail: the separation, those reports, and the
    /// reports there in all (left out or not).
    pub fn at_rail_counts(&self) -> Vec<(f64, usize, usize)> {
        (0..self.separation_in.len())
            .filter(|&i| self.at_rail[i] > 0)
            .map(|i| {
                let left_out = if self.rail_left_out {
                    self.at_rail[i]
                } else {
                    0
                };
                (
                    self.separation_in[i],
                    self.at_rail[i],
                    self.reports[i] + left_out,
                )
            })
            .collect()
    }

    /// Whether separation `i` has a spread to compare with the CTA uncertainty: 2 or more
    /// reports and a positive uncertainty.
    fn compared(&self, i: usize) -> bool {
        self.reports[i] > 1 && self.cta_uncertainty_deg[i] > 0.0
    }

    /// Figure 57's comparison: per separation with a spread, the std of the error in angle
    /// over the CTA uncertainty.
    pub fn std_over_uncertainty(&self) -> Vec<(f64, f64)> {
        (0..self.separation_in.len())
            .filter(|&i| self.compared(i))
            .map(|i| {
                (
                    self.separation_in[i],
                    self.angle_std_deg[i] / self.cta_uncertainty_deg[i],
                )
            })
            .collect()
    }

    /// The separations where the thesis's claim holds on these data: the CTA uncertainty an
    /// order of magnitude (10x or more) below the std of the error in angle.
    pub fn order_of_magnitude_below(&self) -> Vec<f64> {
        (0..self.separation_in.len())
            .filter(|&i| {
                self.compared(i) && self.angle_std_deg[i] >= 10.0 * self.cta_uncertainty_deg[i]
            })
            .map(|i| self.separation_in[i])
            .collect()
    }

    /// The largest |mean| over std of the error in angle over the separations (0 when none has
    /// a spread): a bias shared by a separation's beacons, which Figure 57 does not show.
    pub fn worst_bias_ratio(&self) -> f64 {
        self.angle_mean_deg
            .iter()
            .zip(&self.angle_std_deg)
            .filter(|(_, s)| **s > 0.0)
            .map(|(m, s)| m.abs() / s)
            .fold(0.0f64, f64::max)
    }

    /// Draw Figure 57 (the std and |mean| of the error in angle and the mean CTA uncertainty
    /// against separation) to the SVG file `path`; `fit_separations` are the fit's (none
    /// for a calibration); the std of each of `others`, another model on the same data, is
    /// drawn beside.
    pub fn plot(
        &self,
        fit_separations: &[f64],
        others: &[&Evaluation],
        path: &Path,
    ) -> Result<(), PlotError> {
        let pts = |v: &[f64]| {
            self.separation_in
                .iter()
                .copied()
                .zip(v.iter().copied())
                .collect::<Vec<_>>()
        };
        let abs_mean: Vec<f64> = self.angle_mean_deg.iter().map(|m| m.abs()).collect();
        write_svg(
            path,
            "Error in angle vs separation (thesis Figure 57)",
            &[Panel {
                title: format!(
                    "{}; angle against the {}{}",
                    if fit_separations.is_empty() {
                        format!("{} of a calibration", self.model)
                    } else {
                        format!("fit on {} in", fmt_list(fit_separations))
                    },
                    self.reference,
                    if self.rail_left_out {
                        "; reports at the rail left out"
                    } else {
                        ""
                    }
                ),
                x_desc: "separation (in)".into(),
                y_desc: "error in angle (deg)".into(),
                log_x: false,
                log_y: true,
                // One value per separation: marked, so that a few separations joined by
                // straight lines do not read as a measured curve.
                series: [
                    vec![Series::new(
                        if others.is_empty() {
                            "std of the error in angle".to_string()
                        } else {
                            format!("std of the error in angle, {}", self.model)
                        },
                        pts(&self.angle_std_deg),
                    )
                    .with_markers()],
                    others
                        .iter()
                        .map(|o| {
                            Series::new(
                                format!("std of the error in angle, {}", o.model),
                                o.separation_in
                                    .iter()
                                    .copied()
                                    .zip(o.angle_std_deg.iter().copied())
                                    .collect(),
                            )
                            .with_markers()
                        })
                        .collect(),
                    vec![
                        // Not in the thesis's figure, but part of the error: a bias common to
                        // the beacons of a separation (attitude the fit absorbed), often larger.
                        Series::new(
                            "|mean| of the error in angle (not in Figure 57)",
                            pts(&abs_mean)
                                .into_iter()
                                .filter(|(_, m)| *m > 0.0)
                                .collect(),
                        )
                        .with_markers(),
                        Series::dashed(
                            format!("mean CTA uncertainty (eq 36, {})", self.budget),
                            pts(&self.cta_uncertainty_deg),
                        )
                        .with_markers(),
                    ],
                ]
                .concat(),
            }],
            1,
        )
    }
}

/// Where [`evaluate`] measures the error in angle from: the true direction to each beacon is
/// taken from this point.
#[derive(Debug, Clone, Copy)]
pub enum Reference {
    /// The true head offset, from a simulation's truth sidecar.
    Truth(Vector3<f64>),
    /// The head centre measured on the apparatus, inches in N.
    Head(Vector3<f64>),
    /// The fit's own eye point `d` (eq 65): on the fitted model's own terms, so the error
    /// shows only how consistent the model is with itself (far smaller than Figure 57's).
    Fit,
}

impl Reference {
    /// "truth", "head" or "fit".
    pub fn name(&self) -> &'static str {
        match self {
            Reference::Truth(_) => "truth",
            Reference::Head(_) => "head",
            Reference::Fit => "fit",
        }
    }
}

/// The model whose directions [`evaluate`] compares with the truth.
#[derive(Debug, Clone, Copy)]
pub enum DirectionModel<'a> {
    /// The 7-parameter collinearity model (eq 65): the direction of eq 67 from its eye point.
    Pinhole(&'a Params<f64>),
    /// A sensor calibration's near-field model (eqs 60-63): the beacon position on its plate
    /// (the plane of the beacon's recorded z) whose modelled output is the report, seen from
    /// the calibration's head centre `d`.
    NearField(&'a Calibration),
}

impl DirectionModel<'_> {
    /// "pinhole (eq 65)" or "near-field (eqs 60-63)".
    pub fn name(&self) -> &'static str {
        match self {
            DirectionModel::Pinhole(_) => "pinhole (eq 65)",
            DirectionModel::NearField(_) => "near-field (eqs 60-63)",
        }
    }

    /// The model's own head point: the eye point `d` of eq 65, or the calibration's `d`.
    pub fn own_point(&self) -> Vector3<f64> {
        match self {
            DirectionModel::Pinhole(x) => Vector3::new(x[0], x[1], x[2]),
            DirectionModel::NearField(c) => {
                Vector3::new(c.d[0] as f64, c.d[1] as f64, c.d[2] as f64)
            }
        }
    }
}

/// The beacon position on the plane `z = r.z` whose output under `em` is `y`, by Newton's
/// method on the two in-plane coordinates from the recorded position `r`; `None` when it
/// does not converge (no position gives that output, or a cell has no signal on the way).
fn position_on_plate(em: &Emulator<f64>, y: [f64; 2], r: &Vector3<f64>) -> Option<Vector3<f64>> {
    let mut q = *r;
    for _ in 0..30 {
        let (out, dr, _) = em.output_gradient(&q)?;
        let res = [y[0] - out[0], y[1] - out[1]];
        let j = nalgebra::Matrix2::new(dr[0].x, dr[0].y, dr[1].x, dr[1].y);
        let step = j.lu().solve(&nalgebra::Vector2::new(res[0], res[1]))?;
        // No wild jumps off the plate: a step longer than the plate's half width is no root.
        if !(step.norm() < 10.0) {
            return None;
        }
        q.x += step.x;
        q.y += step.y;
        if step.norm() < 1e-10 {
            return Some(q);
        }
    }
    None
}

/// Evaluate a model on a dataset, the error in angle measured from `reference`; `u` is the
/// CTA's 1-sigma position uncertainty per axis, inches (eq 26's root-sum-square). With
/// `without_rail`, reports with an output at the 16-bit rail are left out (counted in
/// [`Evaluation::at_rail`]).
pub fn evaluate(
    model: DirectionModel<'_>,
    ds: &Dataset,
    reference: Reference,
    u: [f64; 3],
    without_rail: bool,
) -> Evaluation {
    let d = match reference {
        Reference::Truth(d) | Reference::Head(d) => d,
        Reference::Fit => model.own_point(),
    };
    let em = match model {
        DirectionModel::NearField(cal) => Some(cta_firmware_sensor::sim::physics(cal)),
        DirectionModel::Pinhole(_) => None,
    };
    let own = model.own_point();
    let error = |s: &Sample| -> Option<f64> {
        let r = Vector3::from(s.r);
        match (model, &em) {
            (DirectionModel::Pinhole(x), _) => {
                Some(collinearity::angle_error(x, [s.x, s.y], &r, &d).to_degrees())
            }
            (DirectionModel::NearField(_), Some(em)) => {
                let est = position_on_plate(em, [s.x, s.y], &r)? - own;
                let truth = r - d;
                Some(est.cross(&truth).norm().atan2(est.dot(&truth)).to_degrees())
            }
            (DirectionModel::NearField(_), None) => None,
        }
    };
    let mut ev = Evaluation {
        separation_in: Vec::new(),
        angle_std_deg: Vec::new(),
        angle_mean_deg: Vec::new(),
        cta_uncertainty_deg: Vec::new(),
        reports: Vec::new(),
        at_rail: Vec::new(),
        rail_left_out: without_rail,
        all_at_rail_in: Vec::new(),
        reference: reference.name().into(),
        reference_in: [d.x, d.y, d.z],
        budget: "thesis Table 2".into(),
        model: model.name().into(),
        unsolved: Vec::new(),
        all_unsolved_in: Vec::new(),
    };
    let railed = |s: &Sample| s.x.abs() >= RAIL || s.y.abs() >= RAIL;
    for sep in ds.separations() {
        let mut rows: Vec<_> = ds
            .samples
            .iter()
            .filter(|s| s.separation_in == sep)
            .collect();
        let at_rail = rows.iter().filter(|s| railed(s)).count();
        if without_rail {
            rows.retain(|s| !railed(s));
            if rows.is_empty() {
                ev.all_at_rail_in.push(sep);
                continue;
            }
        }
        let solved: Vec<(&Sample, f64)> = rows
            .iter()
            .filter_map(|s| error(s).map(|e| (*s, e)))
            .collect();
        let unsolved = rows.len() - solved.len();
        if solved.is_empty() {
            ev.all_unsolved_in.push(sep);
            continue;
        }
        let n = solved.len() as f64;
        let mean = solved.iter().map(|(_, e)| e).sum::<f64>() / n;
        let var = if solved.len() > 1 {
            solved.iter().map(|(_, e)| (e - mean).powi(2)).sum::<f64>() / (n - 1.0)
        } else {
            0.0
        };
        let cta = solved
            .iter()
            .map(|(s, _)| uncertainty::angle_3d(&(Vector3::from(s.r) - d), u).to_degrees())
            .sum::<f64>()
            / n;
        ev.separation_in.push(sep);
        ev.angle_std_deg.push(var.sqrt());
        ev.angle_mean_deg.push(mean);
        ev.cta_uncertainty_deg.push(cta);
        ev.reports.push(solved.len());
        ev.at_rail.push(at_rail);
        ev.unsolved.push(unsolved);
    }
    ev
}
