//! `cta analyze`: from measured data to a named cause, an extended model and a measured
//! gain. The method is documented in `host/ANALYZE.md`.
//!
//! 1. Average the repeated samples of each point and weight the means by their inverse
//!    variance ([`data`]).
//! 2. Fit the starting model (`thesis`: the eq 63 near-field physics with the pose free;
//!    `pinhole`: the 7-parameter eq 65 model) by GLSDC (eqs 56-59) and diagnose its
//!    residuals ([`diag`]).
//! 3. Forward selection over the effect vocabulary ([`model`], [`select`]): each candidate is
//!    a parametric extension; the best by information criterion that also predicts held-out
//!    separations better is added, until nothing significant remains; then a named cause
//!    that no longer earns its place beside the later ones is dropped and the search rerun
//!    without it ([`DroppedOut`]).
//! 4. Report the causes with their parameters (in the model's order), 1-sigma and strong
//!    correlations ([`Correlation`], also between two causes; values rounded as [`digits`]
//!    says), the held-out gain, chi-square per degree of freedom and the angle-error spread
//!    per separation before and after; say "unexplained structure remains" (and where) when
//!    the best extension still leaves chi-square per degree of freedom clearly above 1. For
//!    every candidate tried on top of the final model and not accepted, report its estimates
//!    +/- 1-sigma and strong correlations (how tightly the data rule it out, [`RuledOut`]).

mod analysis;
pub mod arrays;
mod corners;
pub mod data;
pub mod diag;
pub mod digits;
mod error;
pub mod model;
mod options;
mod params;
pub mod plausible;
pub mod report;
mod result;
pub mod scatter;
pub mod select;
#[cfg(test)]
mod tests;
mod text;
mod trend;

pub use analysis::{
    analyze, board_note, MIN_POINTS_PER_SEPARATION, NOISE_TOO_LARGE_CHI2_DOF, UNEXPLAINED_CHI2_DOF,
};
pub use corners::{CornersOut, CORNER_TWIST_WARN_IN};
pub use digits::{pm, pm_parts};
pub use error::Error;
pub use options::Options;
pub use params::spreads;
pub use plausible::BEYOND_BUDGET;
pub use result::{
    Analysis, BudgetCheck, Cause, Correlation, Detail, DroppedOut, Param, ParamMap, Rival,
    RuledOut, SepSpread, TrialOut, Untested, BASE_CORRELATION_MIN, CORRELATION_MIN, RIVAL_DBIC,
};
pub use text::{correlation_lines, correlations_text, cross_correlation_line, g, unit};
