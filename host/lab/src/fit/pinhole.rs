//! The Ch V calibration: the 7-parameter pinhole (collinearity) model of eq 65 fitted by GLSDC
//! (eqs 56-59), with the 1-sigma of its weighting and the warnings a misfit deserves.

use super::report::{split_variance, FitReport, MODEL};
use crate::data::weights::{
    chi2_expected, misfit_warning, observations, Weights, WeightsError, CHI2_FAR, CHI2_WARN,
};
use crate::data::Dataset;
use cta_core::collinearity::{Fit, Obs, Params, ParamsExt, NAMES};
use cta_core::emulator::{Head, Pose};
use cta_core::glsdc::{self, Settings};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// Why the pinhole model could not be fitted to a file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// The file cannot be weighted as asked.
    #[error(transparent)]
    Weights(#[from] WeightsError),
    /// Fewer than 4 beacon positions: fewer equations than parameters.
    #[error(
        "{}: {beacons} beacon position(s) give {} equations, fewer than the 7 parameters",
        .path.display(), 2 * .beacons
    )]
    TooFewBeacons {
        /// The measurement file.
        path: PathBuf,
        /// Distinct beacon positions.
        beacons: usize,
    },
    /// Too few beacon positions are left once the points with an output at the 16-bit rail
    /// are set aside: a fit to clipped outputs would be meaningless (the rule `cta analyze`
    /// and `cta noise` apply; [`crate::data::any_sample_pinned`]).
    #[error(
        "{}: {pinned} of {points} points have an output at the 16-bit limit (|count| >= 32767 \
         in a sample): the {beacons} beacon position(s) off it give {} equations, fewer than \
         the 7 parameters, and clipped outputs fit nothing: nothing fitted (beacons at the edge \
         of the field of view, a sensitivity too high for the separation?)",
        .path.display(), 2 * .beacons
    )]
    AtTheRail {
        /// The measurement file.
        path: PathBuf,
        /// Points with a sample at the rail.
        pinned: usize,
        /// Points in the file.
        points: usize,
        /// Distinct beacon positions of the points off the rail.
        beacons: usize,
    },
    /// The data leave a direction of the parameters undetermined.
    #[error(
        "{}: the data cannot separate the parameters along [{null}] (eigenvalue ratio {ratio:.1e}); \
         add a second separation or more beacons",
        .path.display()
    )]
    Inseparable {
        /// The measurement file.
        path: PathBuf,
        /// The undetermined direction, in words.
        null: String,
        /// The eigenvalue ratio.
        ratio: f64,
    },
    /// GLSDC reached its iteration cap.
    #[error(
        "{}: GLSDC did not converge in {iterations} iterations (last cost {cost:.6e}); reason: iteration cap reached",
        .path.display()
    )]
    NotConverged {
        /// The measurement file.
        path: PathBuf,
        /// Iterations done.
        iterations: usize,
        /// The last cost.
        cost: f64,
    },
    /// The model cannot be evaluated at the start point.
    #[error(
        "{}: the model cannot be evaluated at the start ({why}): a beacon behind the head?",
        .path.display()
    )]
    NotEvaluable {
        /// The measurement file.
        path: PathBuf,
        /// Why, in words.
        why: &'static str,
    },
    /// Fewer residuals than parameters.
    #[error("{}: {m} residuals for {n} parameters", .path.display())]
    TooFewRows {
        /// The measurement file.
        path: PathBuf,
        /// Residuals.
        m: usize,
        /// Parameters.
        n: usize,
    },
}

/// The warning for a weighted fit whose chi2/dof is above [`CHI2_WARN`] times what a right
/// model gives (the fit's `chi2_expected`, else `expected`; without either, above
/// [`CHI2_FAR`]), in `cta calibrate`'s words; `None` with `none` weights.
pub fn chi2_warning(rep: &FitReport, file: &Path, expected: Option<f64>) -> Option<String> {
    let c = rep.chi2_per_dof?;
    let model = "pinhole model (eq 65: d, p, H)";
    let whose = match rep.weights {
        Weights::Pooled => "the noise pooled per separation",
        _ => "each point's own samples",
    };
    match rep.chi2_expected.or(expected) {
        Some(e) => (c > CHI2_WARN * e).then(|| {
            misfit_warning(
                &format!("chi2/dof {c:.2} (a right model gives {e:.2} with weights from {whose})"),
                c / e,
                model,
                file,
            )
        }),
        None => (c > CHI2_FAR).then(|| {
            misfit_warning(
                &format!(
                    "chi2/dof {c:.2} (far above the 1 a right model gives with weights from \
                     {whose})"
                ),
                c,
                model,
                file,
            )
        }),
    }
}

/// Fit eq 65 to `ds` (already restricted to the wanted separations).
pub fn fit(ds: &Dataset, weights: Weights) -> Result<FitReport, FitError> {
    let points = ds.points();
    let mut off: Vec<[u64; 3]> = Vec::new();
    let mut pinned = 0;
    for p in &points {
        if crate::data::any_sample_pinned(p.rows.iter().map(|&i| &ds.samples[i])) {
            pinned += 1;
        } else {
            off.push(p.first.r.map(f64::to_bits));
        }
    }
    off.sort();
    off.dedup();
    if pinned > 0 && 2 * off.len() < 7 {
        return Err(FitError::AtTheRail {
            path: ds.path.clone(),
            pinned,
            points: points.len(),
            beacons: off.len(),
        });
    }
    let obs = observations(ds, weights)?;
    let mut rep = fit_observations(ds, weights, obs)?;
    rep.chi2_expected = chi2_expected(ds, weights);
    Ok(rep)
}

/// Fit eq 65 to observations `obs` made from `ds` with `weights` (absolute unless `none`):
/// what [`fit`] does after [`observations`], for a caller with weights of its own (`cta
/// calibrate`'s pinhole stage). `chi2_expected` is left unset.
pub fn fit_observations(
    ds: &Dataset,
    weights: Weights,
    obs: Vec<Obs<f64>>,
) -> Result<FitReport, FitError> {
    let mut beacons: Vec<[u64; 3]> = obs
        .iter()
        .map(|o| [o.r.x.to_bits(), o.r.y.to_bits(), o.r.z.to_bits()])
        .collect();
    beacons.sort();
    beacons.dedup();
    if 2 * beacons.len() < 7 {
        return Err(FitError::TooFewBeacons {
            path: ds.path.clone(),
            beacons: beacons.len(),
        });
    }
    let seps = ds.separations();
    let mut warnings = Vec::new();
    if seps.len() == 1 {
        warnings.push(
            "one separation only: d3 and H are (nearly) parallel there (Ch V); fit two separations, e.g. 20,25".into(),
        );
    }
    // 20 in within the separation matching of the whole tool: a plate measured at 19.9992
    // is the recommended 20 in.
    let near = |s: f64| s < 20.0 - crate::data::SEP_MATCH_IN;
    if seps.iter().any(|&s| near(s)) {
        warnings.push(format!(
            "separations below 20 in ({}) carry near-field errors the pinhole model cannot follow: they bias the fit \
             (virtual eye, H); the thesis recommends calibrating at 20-30 in (Ch VI), or use `cta analyze` for the \
             near-field model",
            seps.iter().filter(|&&s| near(s)).map(|s| s.to_string()).collect::<Vec<_>>().join(", ")
        ));
    }
    let sat = ds
        .samples
        .iter()
        .filter(|s| s.x.abs() >= 32767.0 || s.y.abs() >= 32767.0)
        .count();
    if sat > 0 {
        warnings.push(format!(
            "{sat} report(s) at the 16-bit limit (beacon at the edge of the field of view)"
        ));
    }
    let head = Head::<f64>::northstar();
    let x0 = Params::from_pose(
        &Pose {
            d: Vector3::zeros(),
            p: Vector3::zeros(),
        },
        head.h(),
    );
    let settings = Settings {
        weights_absolute: weights != Weights::None,
        ..Settings::default()
    };
    let problem = Fit { obs: &obs };
    let mut sol = match glsdc::solve(&problem, x0, &settings) {
        Ok(s) => s,
        Err(glsdc::Error::RankDeficient { null, ratio, .. }) => {
            let mut s = String::new();
            glsdc::describe_null(&problem, &null, &mut s).ok();
            return Err(FitError::Inseparable {
                path: ds.path.clone(),
                null: s,
                ratio,
            });
        }
        Err(glsdc::Error::NotConverged {
            cost, iterations, ..
        }) => {
            return Err(FitError::NotConverged {
                path: ds.path.clone(),
                iterations,
                cost,
            })
        }
        Err(glsdc::Error::Model(e)) => {
            let why = match e {
                glsdc::ModelError::NonFinite => "a prediction is not a finite number",
                glsdc::ModelError::NoData => "no usable observation",
            };
            return Err(FitError::NotEvaluable {
                path: ds.path.clone(),
                why,
            });
        }
        Err(glsdc::Error::TooFewRows { m, n }) => {
            return Err(FitError::TooFewRows {
                path: ds.path.clone(),
                m,
                n,
            })
        }
    };
    if sol.condition > 1e6 {
        let mut s = String::new();
        if let Ok((null, _)) = glsdc::weakest_direction(&problem, &sol.x) {
            glsdc::describe_null(&problem, &null, &mut s).ok();
        }
        warnings.push(format!(
            "ill-conditioned (condition {:.2e}): [{s}] is poorly determined (Table 3: d3 and H nearly parallel)",
            sol.condition
        ));
    }
    if weights == Weights::Repeat {
        // Each point's weight is its own variance from a few samples, which (J'WJ)^-1 would
        // take for the truth, understating the scatter. The sandwich P B P with
        // B = m/(m-n) sum (w r)^2 J'J (White's HC1) gives the scatter these weights give
        // whatever the noise of each point.
        if let Some(cov) = sandwich(&problem, &sol.x, &sol.covariance) {
            sol.sigma = cov.diagonal().map(|v| v.max(0.0).sqrt());
            sol.covariance = cov;
        }
    }
    let map = |v: &dyn Fn(usize) -> f64| {
        NAMES
            .iter()
            .enumerate()
            .map(|(i, n)| (n.to_string(), v(i)))
            .collect()
    };
    Ok(FitReport {
        model: MODEL.into(),
        source: ds.path.display().to_string(),
        separations: seps,
        weights,
        params: map(&|i| sol.x[i]),
        sigma: map(&|i| sol.sigma[i]),
        covariance: sol.covariance.transpose().iter().copied().collect(),
        rms_counts: sol.rms,
        residual_variance_counts2: split_variance(weights, sol.variance_factor).0,
        chi2_per_dof: split_variance(weights, sol.variance_factor).1,
        chi2_expected: None,
        chi2_dof: sol.variance_factor,
        iterations: sol.iterations,
        condition: sol.condition,
        stop: format!("{:?}", sol.stop),
        observations: obs.len(),
        warnings,
        data_notes: Vec::new(),
    })
}

/// The sandwich covariance `P B P` of a weighted fit at `x`, `P` its `(J'WJ)^-1` and
/// `B = m/(m - 7) sum_i (w_i r_i)^2 J_i' J_i` (White's HC1): the parameters' scatter whatever
/// the weights, judged by the residuals. `None` when the model cannot be evaluated there.
fn sandwich(
    problem: &Fit<'_, f64>,
    x: &nalgebra::SVector<f64, 7>,
    p: &nalgebra::SMatrix<f64, 7, 7>,
) -> Option<nalgebra::SMatrix<f64, 7, 7>> {
    use cta_core::glsdc::Problem;
    let mut b = nalgebra::SMatrix::<f64, 7, 7>::zeros();
    let mut m = 0usize;
    problem
        .rows(x, true, &mut |r, w, j| {
            let j = nalgebra::SVector::<f64, 7>::from_column_slice(j);
            b += (w * r).powi(2) * j * j.transpose();
            m += 1;
        })
        .ok()?;
    (m > 7).then(|| p * (b * (m as f64 / (m - 7) as f64)) * p)
}
