//! The saved fit (`cta fit --save`, read by `cta evaluate`): the pinhole model's parameters,
//! their covariance and how the fit went, checked field by field when it is read.

use crate::data::weights::Weights;
use cta_core::collinearity::{Params, NAMES};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Why a file is not a saved fit `cta` can use: the file, and the reason.
#[derive(Debug, thiserror::Error)]
pub enum FitFileError {
    /// The file could not be read.
    #[error("{}: {error}", .path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// A sensor calibration given where a fit belongs.
    #[error(
        "{}: this is a sensor calibration (`cta calibrate --out`), not a fit: give a \
         file saved by `cta fit --save`",
        .path.display()
    )]
    Calibration {
        /// The file.
        path: PathBuf,
    },
    /// Not the JSON of a saved fit.
    #[error("{}: not a CTA fit file: {error}", .path.display())]
    NotAFit {
        /// The file.
        path: PathBuf,
        /// serde_json's message.
        error: String,
    },
    /// A field out of its range.
    #[error("{}: not a valid CTA fit: {error}", .path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Which field, and why.
        error: InvalidFit,
    },
}

use super::calibrate::shown;

/// The largest MRP component a saved fit may hold ([`InvalidFit::Range`]).
pub const MAX_MRP: f64 = 1000.0;

/// A field of a saved fit that `cta` refuses ([`FitReport::validate`]), named.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InvalidFit {
    /// A model other than [`MODEL`].
    #[error("field `model`: `{0}` is not the model `cta` fits (`{MODEL}`)")]
    Model(String),
    /// A parameter missing.
    #[error("field `params` lacks `{0}` (it needs {names})", names = NAMES.join(", "))]
    MissingParam(&'static str),
    /// A parameter that is not finite.
    #[error("field `params.{0}`: {1} is not a finite number")]
    Param(&'static str, f64),
    /// A sigma missing.
    #[error("field `sigma` lacks `{0}`")]
    MissingSigma(&'static str),
    /// A sigma that is not finite and >= 0.
    #[error("field `sigma.{name}`: {v} is not a finite number >= 0", name = .0, v = shown(*.1))]
    Sigma(&'static str, f64),
    /// An eye point or attitude no rig has: `d` beyond 1000 in
    /// ([`crate::data::MAX_INCHES`]), an MRP component beyond 1000 (a turn of 359.6 deg;
    /// larger ones overflow the attitude's arithmetic into NaN).
    #[error("field `params.{name}`: {v} is out of range (allowed: {text})", name = .0, v = shown(*.1), text = .2)]
    Range(&'static str, f64, &'static str),
    /// `H` outside (0, [`MAX_H`]].
    #[error(
        "field `params.H`: {v} is out of range (allowed: 0 < H <= {MAX_H:e} counts; \
         the NorthStar's is about 18918.6)",
        v = shown(*.0)
    )]
    H(f64),
    /// A covariance that is not 7 x 7.
    #[error("field `covariance`: {0} entries, a 7 x 7 matrix has 49")]
    CovarianceSize(usize),
    /// A covariance entry that is not finite.
    #[error("field `covariance`: {0} is not a finite number")]
    Covariance(f64),
    /// No separations.
    #[error("field `separations` is empty")]
    NoSeparations,
    /// A separation that is not positive.
    #[error("field `separations`: {0} in is not a positive separation")]
    Separation(f64),
    /// A spread that is not finite and >= 0.
    #[error("field `{name}`: {v} is not a finite number >= 0", name = .0, v = shown(*.1))]
    Spread(&'static str, f64),
}

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
    /// `chi2_expected` when the model holds; above [`CHI2_WARN`](crate::data::weights::CHI2_WARN) times it
    /// the 1-sigma are too small by about the square root of the ratio); `null` with `none`
    /// weights.
    #[serde(default)]
    pub chi2_per_dof: Option<f64>,
    /// What a right model gives as `chi2_per_dof` with these weights ([`chi2_expected`](crate::data::weights::chi2_expected));
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
    pub fn load(path: &Path) -> Result<FitReport, FitFileError> {
        let s = crate::bounded::read_text(path, crate::bounded::MAX_JSON_BYTES, "a JSON file")
            .map_err(|error| FitFileError::Read {
                path: path.to_path_buf(),
                error,
            })?;
        let mut r: FitReport = serde_json::from_str(&s).map_err(|e| {
            // A sensor calibration (`cta calibrate --out`) is the usual mix-up.
            let cal = serde_json::from_str::<serde_json::Value>(&s)
                .is_ok_and(|v| v.get("near_field").is_some() && v.get("h").is_some());
            if cal {
                FitFileError::Calibration {
                    path: path.to_path_buf(),
                }
            } else {
                FitFileError::NotAFit {
                    path: path.to_path_buf(),
                    error: e.to_string(),
                }
            }
        })?;
        // A fit saved before the two named fields existed: derive them from `chi2_dof`.
        if r.residual_variance_counts2.is_none() && r.chi2_per_dof.is_none() {
            (r.residual_variance_counts2, r.chi2_per_dof) = split_variance(r.weights, r.chi2_dof);
        }
        r.validate().map_err(|error| FitFileError::Invalid {
            path: path.to_path_buf(),
            error,
        })?;
        Ok(r)
    }

    /// Check a loaded fit: the model, every parameter and sigma present and finite, `H` in
    /// (0, [`MAX_H`]] counts, a 7 x 7 finite covariance, positive separations. Errors
    /// name the field.
    pub fn validate(&self) -> Result<(), InvalidFit> {
        if self.model != MODEL {
            return Err(InvalidFit::Model(self.model.clone()));
        }
        for n in NAMES {
            let v = *self.params.get(n).ok_or(InvalidFit::MissingParam(n))?;
            if !v.is_finite() {
                return Err(InvalidFit::Param(n, v));
            }
            let s = *self.sigma.get(n).ok_or(InvalidFit::MissingSigma(n))?;
            if !(s.is_finite() && s >= 0.0) {
                return Err(InvalidFit::Sigma(n, s));
            }
        }
        for (n, limit, text) in [
            ("d1", crate::data::MAX_INCHES, "-1000..1000 in"),
            ("d2", crate::data::MAX_INCHES, "-1000..1000 in"),
            ("d3", crate::data::MAX_INCHES, "-1000..1000 in"),
            ("p1", MAX_MRP, "-1000..1000"),
            ("p2", MAX_MRP, "-1000..1000"),
            ("p3", MAX_MRP, "-1000..1000"),
        ] {
            let v = self.params[n];
            if v.abs() > limit {
                return Err(InvalidFit::Range(n, v, text));
            }
        }
        let h = self.params["H"];
        if !(h > 0.0 && h <= MAX_H) {
            return Err(InvalidFit::H(h));
        }
        if self.covariance.len() != NAMES.len() * NAMES.len() {
            return Err(InvalidFit::CovarianceSize(self.covariance.len()));
        }
        if let Some(v) = self.covariance.iter().find(|v| !v.is_finite()) {
            return Err(InvalidFit::Covariance(*v));
        }
        if self.separations.is_empty() {
            return Err(InvalidFit::NoSeparations);
        }
        if let Some(s) = self
            .separations
            .iter()
            .find(|s| !(s.is_finite() && **s > 0.0))
        {
            return Err(InvalidFit::Separation(*s));
        }
        for (name, v) in [
            ("rms_counts", Some(self.rms_counts)),
            ("chi2_dof", Some(self.chi2_dof)),
            ("residual_variance_counts2", self.residual_variance_counts2),
            ("chi2_per_dof", self.chi2_per_dof),
        ] {
            if let Some(v) = v.filter(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(InvalidFit::Spread(name, v));
            }
        }
        Ok(())
    }
}

/// GLSDC's variance factor as `(residual_variance_counts2, chi2_per_dof)`: which one it is
/// depends on the weighting.
pub(super) fn split_variance(weights: Weights, variance_factor: f64) -> (Option<f64>, Option<f64>) {
    match weights {
        Weights::None => (Some(variance_factor), None),
        Weights::Repeat | Weights::Pooled => (None, Some(variance_factor)),
    }
}
