//! The Ch V calibration: the 7-parameter collinearity model (eq 65) fitted to a measurement
//! file by GLSDC (eqs 56-59), and its evaluation (eq 67, Figure 57).

pub mod calibrate;
pub mod magnitude;
pub mod nearfield;
pub mod wiring;

use crate::data::weights::{chi2_expected, misfit_warning, observations, Weights, CHI2_FAR, CHI2_WARN};
use crate::data::Dataset;
use cta_core::collinearity::{self, Fit, Obs, Params, ParamsExt, NAMES};
use cta_core::emulator::{Head, Pose};
use cta_core::glsdc::{self, Settings};
use cta_core::uncertainty;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;





/// Why GLSDC stopped, in words (the JSON keeps the name, `FitReport::stop`).
pub fn describe_stop(stop: &str) -> String {
    match stop {
        "SmallStep" => "the step fell below tolerance".into(),
        "SmallCostChange" => "the cost changed by less than tolerance".into(),
        "ZeroCost" => "the residuals are zero".into(),
        "NoFurtherDecrease" => "no step lowers the cost any more".into(),
        "SmallPredictedDecrease" => {
            "the predicted decrease of the cost fell below tolerance".into()
        }
        other => other.into(),
    }
}

/// The model a saved fit holds (`FitReport::model`); a fit file naming another is refused.
pub const MODEL: &str = "pinhole (eq 65, 7 parameters)";

/// The largest scale height `H` a saved fit may hold, counts (the NorthStar's is 18918.6;
/// this is a face angle of about 88 deg).
pub const MAX_H: f64 = 1e6;

/// A saved fit (`cta fit --save`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FitReport {
    /// Model fitted.
    pub model: String,
    /// The measurement file.
    pub source: String,
    /// Separations used, inches.
    pub separations: Vec<f64>,
    /// Weighting.
    pub weights: Weights,
    /// Estimated parameters by name (d in inches, p MRP, H counts).
    pub params: BTreeMap<String, f64>,
    /// Their 1-sigma.
    pub sigma: BTreeMap<String, f64>,
    /// Covariance, row-major 7x7, parameter order d1 d2 d3 p1 p2 p3 H.
    pub covariance: Vec<f64>,
    /// Unweighted residual RMS, counts.
    pub rms_counts: f64,
    /// With `none` weights: the residual variance per degree of freedom, counts^2 (the
    /// sigmas are scaled by it); `null` with `repeat` or `pooled` weights.
    #[serde(default)]
    pub residual_variance_counts2: Option<f64>,
    /// With `repeat` or `pooled` weights: chi-square per degree of freedom (about
    /// `chi2_expected` when the model holds; above [`CHI2_WARN`] times it
    /// the 1-sigma are too small by about the square root of the ratio); `null` with `none`
    /// weights.
    #[serde(default)]
    pub chi2_per_dof: Option<f64>,
    /// What a right model gives as `chi2_per_dof` with these weights ([`chi2_expected`]);
    /// `null` with `none` weights (and in files written before it).
    #[serde(default)]
    pub chi2_expected: Option<f64>,
    /// Kept for readers of earlier fit files: the weighted residual variance per degree of
    /// freedom whatever the weighting, i.e. the one of `residual_variance_counts2` and
    /// `chi2_per_dof` that is set. A chi-square per degree of freedom only with `repeat` or
    /// `pooled`.
    pub chi2_dof: f64,
    /// Iterations.
    pub iterations: usize,
    /// Condition number of the scaled, weighted Jacobian.
    pub condition: f64,
    /// Why GLSDC stopped.
    pub stop: String,
    /// Observations (beacon reports or point means).
    pub observations: usize,
    /// Things the user should know.
    pub warnings: Vec<String>,
    /// Notes on the data fitted: the glitched samples `--drop-glitches` left out, as `cta
    /// analyze`'s `data_notes` (empty in files written before it).
    #[serde(default)]
    pub data_notes: Vec<String>,
}

impl FitReport {
    /// The parameter vector.
    pub fn x(&self) -> Params<f64> {
        Params::from_iterator(NAMES.iter().map(|n| self.params[*n]))
    }

    /// Load a saved fit.
    pub fn load(path: &Path) -> Result<FitReport, String> {
        let s = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut r: FitReport = serde_json::from_str(&s).map_err(|e| {
            // A sensor calibration (`cta calibrate --out`) is the usual mix-up.
            let cal = serde_json::from_str::<serde_json::Value>(&s)
                .is_ok_and(|v| v.get("near_field").is_some() && v.get("h").is_some());
            if cal {
                format!(
                    "{}: this is a sensor calibration (`cta calibrate --out`), not a fit: give a \
                     file saved by `cta fit --save`",
                    path.display()
                )
            } else {
                format!("{}: not a CTA fit file: {e}", path.display())
            }
        })?;
        // A fit saved before the two named fields existed: derive them from `chi2_dof`.
        if r.residual_variance_counts2.is_none() && r.chi2_per_dof.is_none() {
            (r.residual_variance_counts2, r.chi2_per_dof) = split_variance(r.weights, r.chi2_dof);
        }
        r.validate()
            .map_err(|e| format!("{}: not a valid CTA fit: {e}", path.display()))?;
        Ok(r)
    }

    /// Check a loaded fit: the model, every parameter and sigma present and finite, `H` in
    /// (0, [`MAX_H`]] counts, a 7 x 7 finite covariance, positive separations. Errors
    /// name the field.
    pub fn validate(&self) -> Result<(), String> {
        if self.model != MODEL {
            return Err(format!(
                "field `model`: `{}` is not the model `cta` fits (`{MODEL}`)",
                self.model
            ));
        }
        for n in NAMES {
            let v = *self.params.get(n).ok_or_else(|| {
                format!("field `params` lacks `{n}` (it needs {})", NAMES.join(", "))
            })?;
            if !v.is_finite() {
                return Err(format!("field `params.{n}`: {v} is not a finite number"));
            }
            let s = *self
                .sigma
                .get(n)
                .ok_or_else(|| format!("field `sigma` lacks `{n}`"))?;
            if !(s.is_finite() && s >= 0.0) {
                return Err(format!(
                    "field `sigma.{n}`: {s} is not a finite number >= 0"
                ));
            }
        }
        let h = self.params["H"];
        if !(h > 0.0 && h <= MAX_H) {
            return Err(format!(
                "field `params.H`: {h} is out of range (allowed: 0 < H <= {MAX_H:e} counts; \
                 the NorthStar's is about 18918.6)"
            ));
        }
        if self.covariance.len() != NAMES.len() * NAMES.len() {
            return Err(format!(
                "field `covariance`: {} entries, a 7 x 7 matrix has 49",
                self.covariance.len()
            ));
        }
        if let Some(v) = self.covariance.iter().find(|v| !v.is_finite()) {
            return Err(format!("field `covariance`: {v} is not a finite number"));
        }
        if self.separations.is_empty() {
            return Err("field `separations` is empty".into());
        }
        if let Some(s) = self
            .separations
            .iter()
            .find(|s| !(s.is_finite() && **s > 0.0))
        {
            return Err(format!(
                "field `separations`: {s} in is not a positive separation"
            ));
        }
        for (name, v) in [
            ("rms_counts", Some(self.rms_counts)),
            ("chi2_dof", Some(self.chi2_dof)),
            ("residual_variance_counts2", self.residual_variance_counts2),
            ("chi2_per_dof", self.chi2_per_dof),
        ] {
            if let Some(v) = v.filter(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(format!("field `{name}`: {v} is not a finite number >= 0"));
            }
        }
        Ok(())
    }
}

/// GLSDC's variance factor as `(residual_variance_counts2, chi2_per_dof)`: which one it is
/// depends on the weighting.
fn split_variance(weights: Weights, variance_factor: f64) -> (Option<f64>, Option<f64>) {
    match weights {
        Weights::None => (Some(variance_factor), None),
        Weights::Repeat | Weights::Pooled => (None, Some(variance_factor)),
    }
}



/// The warning for a weighted fit whose chi2/dof is above [`CHI2_WARN`]
/// times what a right model gives with these weights (the fit's `chi2_expected`, else
/// `expected`), in `cta calibrate`'s words; `file` is the measurement file to analyze.
/// Without an expectation, above [`CHI2_FAR`]: far above anything a right model gives. `None`
/// with `none` weights (no noise to compare with).
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
pub fn fit(ds: &Dataset, weights: Weights) -> Result<FitReport, String> {
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
) -> Result<FitReport, String> {
    let mut beacons: Vec<[u64; 3]> = obs
        .iter()
        .map(|o| [o.r.x.to_bits(), o.r.y.to_bits(), o.r.z.to_bits()])
        .collect();
    beacons.sort();
    beacons.dedup();
    if 2 * beacons.len() < 7 {
        return Err(format!(
            "{}: {} beacon position(s) give {} equations, fewer than the 7 parameters",
            ds.path.display(),
            beacons.len(),
            2 * beacons.len()
        ));
    }
    let seps = ds.separations();
    let mut warnings = Vec::new();
    if seps.len() == 1 {
        warnings.push(
            "one separation only: d3 and H are (nearly) parallel there (Ch V); fit two separations, e.g. 20,25".into(),
        );
    }
    if seps.iter().any(|&s| s < 20.0) {
        warnings.push(format!(
            "separations below 20 in ({}) carry near-field errors the pinhole model cannot follow: they bias the fit \
             (virtual eye, H); the thesis recommends calibrating at 20-30 in (Ch VI), or use `cta analyze` for the \
             near-field model",
            seps.iter().filter(|&&s| s < 20.0).map(|s| s.to_string()).collect::<Vec<_>>().join(", ")
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
            return Err(format!(
                "{}: the data cannot separate the parameters along [{s}] (eigenvalue ratio {ratio:.1e}); \
                 add a second separation or more beacons",
                ds.path.display()
            ));
        }
        Err(glsdc::Error::NotConverged { cost, iterations, .. }) => {
            return Err(format!(
                "{}: GLSDC did not converge in {iterations} iterations (last cost {cost:.6e}); reason: iteration cap reached",
                ds.path.display()
            ))
        }
        Err(glsdc::Error::Model(e)) => {
            let why = match e {
                glsdc::ModelError::NonFinite => "a prediction is not a finite number",
                glsdc::ModelError::NoData => "no usable observation",
            };
            return Err(format!("{}: the model cannot be evaluated at the start ({why}): a beacon behind the head?", ds.path.display()))
        }
        Err(glsdc::Error::TooFewRows { m, n }) => {
            return Err(format!("{}: {m} residuals for {n} parameters", ds.path.display()))
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
        // Each point's weight is its own variance from a few samples: (J'WJ)^-1 takes those
        // rough variances for the truth and was 5-7x too small with 4 samples (1.2-1.6x with
        // 10; far-field data, where eq 65 is exact). The sandwich does not: P B P with
        // B = m/(m-n) sum (w r)^2 J'J, White's heteroscedasticity-consistent estimate (HC1),
        // the scatter these weights give whatever the noise of each point.
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

/// Evaluate a fit on a dataset, the error in angle measured from `reference`; `u` is the
/// CTA's 1-sigma position uncertainty per axis, inches (eq 26's root-sum-square). With
/// `without_rail`, reports with an output at the 16-bit rail are left out (counted in
/// [`Evaluation::at_rail`]).
pub fn evaluate(
    x: &Params<f64>,
    ds: &Dataset,
    reference: Reference,
    u: [f64; 3],
    without_rail: bool,
) -> Evaluation {
    let d = match reference {
        Reference::Truth(d) | Reference::Head(d) => d,
        Reference::Fit => Vector3::new(x[0], x[1], x[2]),
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
    };
    let railed =
        |s: &crate::data::Sample| s.x.abs() >= crate::data::RAIL || s.y.abs() >= crate::data::RAIL;
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
        let errs: Vec<f64> = rows
            .iter()
            .map(|s| collinearity::angle_error(x, [s.x, s.y], &Vector3::from(s.r), &d).to_degrees())
            .collect();
        let n = errs.len() as f64;
        let mean = errs.iter().sum::<f64>() / n;
        let var = if errs.len() > 1 {
            errs.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0)
        } else {
            0.0
        };
        let cta = rows
            .iter()
            .map(|s| uncertainty::angle_3d(&(Vector3::from(s.r) - d), u).to_degrees())
            .sum::<f64>()
            / n;
        ev.separation_in.push(sep);
        ev.angle_std_deg.push(var.sqrt());
        ev.angle_mean_deg.push(mean);
        ev.cta_uncertainty_deg.push(cta);
        ev.reports.push(rows.len());
        ev.at_rail.push(at_rail);
    }
    ev
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report() -> FitReport {
        let vals = [0.6, 0.1, 0.06, 0.001, 0.002, 0.001, 18918.6];
        let map = |f: &dyn Fn(usize) -> f64| {
            NAMES
                .iter()
                .enumerate()
                .map(|(i, n)| (n.to_string(), f(i)))
                .collect()
        };
        FitReport {
            model: MODEL.into(),
            source: "sim.csv".into(),
            separations: vec![20.0, 25.0],
            weights: Weights::None,
            params: map(&|i| vals[i]),
            sigma: map(&|_| 1e-3),
            covariance: vec![1e-6; 49],
            rms_counts: 1.0,
            residual_variance_counts2: Some(1.0),
            chi2_per_dof: None,
            chi2_expected: None,
            chi2_dof: 1.0,
            iterations: 5,
            condition: 1e3,
            stop: "Converged".into(),
            observations: 200,
            warnings: Vec::new(),
            data_notes: Vec::new(),
        }
    }

    /// Save `r` (as JSON, after `edit`) and load it back.
    fn load_edited(name: &str, edit: impl Fn(&mut serde_json::Value)) -> Result<FitReport, String> {
        let p = std::env::temp_dir().join(format!("cta-fit-{}-{name}.json", std::process::id()));
        let mut v = serde_json::to_value(report()).unwrap();
        edit(&mut v);
        std::fs::write(&p, v.to_string()).unwrap();
        let r = FitReport::load(&p);
        std::fs::remove_file(&p).ok();
        r
    }

    /// A sensor calibration given where a fit belongs is named as such.
    #[test]
    fn a_calibration_file_is_not_taken_for_a_fit() {
        let e = load_edited("cal", |v| {
            *v = serde_json::json!({"d": [0.6, 0.1, 0.06], "p": [0, 0, 0], "h": 19000.0,
                "noise": 32.8, "near_field": {"s": 0.175}});
        })
        .unwrap_err();
        assert!(
            e.contains("this is a sensor calibration (`cta calibrate --out`), not a fit"),
            "{e}"
        );
        let e = load_edited("other", |v| *v = serde_json::json!({"h": 1})).unwrap_err();
        assert!(e.contains("not a CTA fit file"), "{e}");
    }

    /// Every way GLSDC stops is said in words.
    #[test]
    fn stop_reasons_are_in_words() {
        use glsdc::Stop::*;
        for stop in [
            SmallStep,
            SmallCostChange,
            ZeroCost,
            NoFurtherDecrease,
            SmallPredictedDecrease,
        ] {
            let name = format!("{stop:?}");
            let words = describe_stop(&name);
            assert!(
                words.contains(' ') && !words.contains(&name),
                "{name}: {words}"
            );
        }
    }

    /// The chi2/dof warning: only with `repeat` weights, above `cta calibrate`'s line.
    #[test]
    fn chi2_warning_only_for_repeat_weights_above_the_line() {
        let f = Path::new("m.csv");
        let mut r = report();
        r.residual_variance_counts2 = Some(1921.0);
        assert_eq!(chi2_warning(&r, f, Some(1.0)), None);
        r.weights = Weights::Repeat;
        r.residual_variance_counts2 = None;
        r.chi2_per_dof = Some(CHI2_WARN);
        assert_eq!(chi2_warning(&r, f, Some(1.0)), None);
        // 10 samples per point: a right model gives 9/7 = 1.29.
        r.chi2_per_dof = Some(1.31);
        assert_eq!(chi2_warning(&r, f, Some(9.0 / 7.0)), None);
        // Without an expectation (none is known below 4 samples per point): only far above 1.
        r.chi2_per_dof = Some(1.9);
        assert_eq!(chi2_warning(&r, f, None), None);
        r.chi2_per_dof = Some(88.25);
        let w = chi2_warning(&r, f, None).unwrap();
        assert!(
            w.starts_with("chi2/dof 88.25 (far above the 1 a right model gives")
                && w.contains("the residuals are 9.4x the noise"),
            "{w}"
        );
        // The fit's own expectation goes before the caller's.
        r.chi2_expected = Some(3.0);
        assert_eq!(
            chi2_warning(&r, f, Some(1.0)).map(|w| w[..25].to_string()),
            Some("chi2/dof 88.25 (a right m".into())
        );
        r.chi2_per_dof = Some(3.5);
        assert_eq!(chi2_warning(&r, f, Some(1.0)), None);
        r.chi2_expected = None;
        r.chi2_per_dof = Some(2.25);
        let w = chi2_warning(&r, f, Some(1.0)).unwrap();
        assert!(
            w.starts_with("chi2/dof 2.25 (a right model gives 1.00")
                && w.contains("the residuals are 1.5x the noise")
                && w.contains("biases the parameters by an amount they do not bound")
                && w.contains("`cta analyze m.csv`"),
            "{w}"
        );
    }

    /// A fit saved before `residual_variance_counts2` and `chi2_per_dof` existed loads, with
    /// them derived from `chi2_dof` by its weighting.
    #[test]
    fn earlier_fit_files_load_with_the_named_fields() {
        let strip = |v: &mut serde_json::Value| {
            let o = v.as_object_mut().unwrap();
            o.remove("residual_variance_counts2");
            o.remove("chi2_per_dof");
            o.insert("chi2_dof".into(), serde_json::json!(1921.0));
        };
        let r = load_edited("old-none", strip).unwrap();
        assert_eq!(
            (r.residual_variance_counts2, r.chi2_per_dof),
            (Some(1921.0), None)
        );
        let r = load_edited("old-repeat", |v| {
            strip(v);
            v["weights"] = serde_json::json!("repeat");
        })
        .unwrap();
        assert_eq!(
            (r.residual_variance_counts2, r.chi2_per_dof),
            (None, Some(1921.0))
        );
    }

    #[test]
    fn saved_fits_are_validated_on_load() {
        assert!(load_edited("ok", |_| {}).is_ok());
        for (name, value, needle) in [
            (
                "h0",
                serde_json::json!(0.0),
                "field `params.H`: 0 is out of range",
            ),
            (
                "hneg",
                serde_json::json!(-5.0),
                "field `params.H`: -5 is out of range",
            ),
            ("hbig", serde_json::json!(1e308), "field `params.H`"),
        ] {
            let e = load_edited(name, |v| v["params"]["H"] = value.clone()).unwrap_err();
            assert!(
                e.contains(&format!("cta-fit-{}-{name}.json", std::process::id())),
                "{e}"
            );
            assert!(e.contains(needle), "{e}");
        }
        let e = load_edited("cov", |v| {
            v["covariance"] = serde_json::json!([1.0, 0.0, 0.0, 0.0, 1.0])
        })
        .unwrap_err();
        assert!(
            e.contains("field `covariance`: 5 entries, a 7 x 7 matrix has 49"),
            "{e}"
        );
        let e = load_edited("model", |v| {
            v["model"] = serde_json::json!("near-field (analyze)")
        })
        .unwrap_err();
        assert!(e.contains("field `model`: `near-field (analyze)`"), "{e}");
        let e = load_edited("d1", |v| {
            v["params"].as_object_mut().unwrap().remove("d1");
        })
        .unwrap_err();
        assert!(e.contains("field `params` lacks `d1`"), "{e}");
        let e = load_edited("sig", |v| v["sigma"]["p2"] = serde_json::json!(-1.0)).unwrap_err();
        assert!(e.contains("field `sigma.p2`"), "{e}");
        let e = load_edited("seps", |v| v["separations"] = serde_json::json!([])).unwrap_err();
        assert!(e.contains("field `separations` is empty"), "{e}");
    }
}
