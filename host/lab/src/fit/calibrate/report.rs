//! What `cta calibrate` reports: the file it writes, both fits' quality and the residuals per
//! separation.

use serde::Serialize;

use super::CalibrationFile;
use crate::fit::magnitude::MagnitudeReport;

/// A separation whose near-field chi-square lies more than this many standard deviations
/// above what the noise gives is reported as one where the model misses the data (see
/// [`SeparationRms::near_field_z`]).
pub const MISFIT_Z: f64 = 5.0;

/// Residual RMS of both models at one separation.
#[derive(Debug, Clone, Serialize)]
pub struct SeparationRms {
    /// Separation, inches.
    pub separation_in: f64,
    /// Points.
    pub points: usize,
    /// Pinhole model (eq 65), counts; `None` where it predicts no point.
    pub pinhole_counts: Option<f64>,
    /// Near-field model, counts.
    pub near_field_counts: f64,
    /// What the noise alone gives: the RMS of a point mean's error, counts.
    pub noise_counts: f64,
    /// How far the near-field residuals exceed the noise here, in standard deviations:
    /// `ln(chi2 / k) / sqrt(2 / k + 1 / nu)`, chi-square (the residuals in units of their
    /// point mean's noise) over its `k = 2 x points` degrees of freedom, against its spread
    /// when the model is right: `2 / k` from the residuals, and `1 / nu` from the noise
    /// estimate when it is measured at this separation from `nu` degrees of freedom per axis
    /// (with 2 samples per point a noise known to 14 % makes chi2/k scatter as much as the
    /// residuals do). The logarithm (Fisher's z of the variance ratio) makes the ratio of
    /// two chi-squares nearly normal. Above [`MISFIT_Z`] the model misses the data at this
    /// separation.
    pub near_field_z: f64,
}

/// The `cta calibrate` report.
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationReport {
    /// The file written (or that would be written).
    pub file: CalibrationFile,
    /// Pinhole fit: `H`, counts (its 1-sigma is `fitted.sigma.H`).
    pub pinhole_h: f64,
    /// Pinhole fit: chi-square per degree of freedom (point means weighted as the near-field
    /// fit's, so about 1 when the pinhole model explains the far separations to the noise).
    pub pinhole_chi2_dof: f64,
    /// Pinhole fit warnings.
    pub pinhole_warnings: Vec<String>,
    /// Where the noise figure came from.
    pub noise_source: String,
    /// Near-field fit iterations.
    pub iterations: usize,
    /// Near-field fit condition number.
    pub condition: f64,
    /// Residual RMS per separation, both models.
    pub by_separation: Vec<SeparationRms>,
    /// Things the user should know.
    pub warnings: Vec<String>,
    /// Notes on the data fitted: the glitched samples `--drop-glitches` left out, as `cta
    /// analyze`'s `data_notes`.
    pub data_notes: Vec<String>,
    /// The spot magnitude law fitted ([`super::fit_magnitude`]), when there is one.
    pub magnitude: Option<MagnitudeReport>,
    /// Why the calibration has no magnitude law, when it has none.
    pub magnitude_note: Option<String>,
}
