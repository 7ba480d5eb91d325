//! The Ch V calibration: the 7-parameter collinearity model (eq 65) fitted to a measurement
//! file by GLSDC (eqs 56-59), and its evaluation (eq 67, Figure 57); the sensor board's
//! calibration, the spot magnitude law and a miswired head beside them.

pub mod calibrate;
mod evaluate;
mod file;
pub mod magnitude;
pub mod nearfield;
mod pinhole;
mod report;
#[cfg(test)]
mod tests;
pub mod wiring;

pub use evaluate::{evaluate, DirectionModel, Evaluation, Reference};
pub use file::{fit_file, prepare, FileFitError, Prepared};
pub use pinhole::{chi2_warning, fit, fit_observations, FitError};
pub use report::{describe_stop, FitFileError, FitReport, InvalidFit, MAX_H, MODEL};
