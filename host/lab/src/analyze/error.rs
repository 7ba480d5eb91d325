//! Why an analysis could not be made.

use super::data::DataError;
use super::model::Cand;
use super::select;
use crate::data::{fmt_list, SEP_MATCH_IN};
use crate::fit::wiring;

/// Why [`super::analyze`] could not analyze a file.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The file gives no weighted points, or the noise given is not a positive number.
    #[error(transparent)]
    Data(#[from] DataError),
    /// Cross-validation across separations needs at least 2 of them.
    #[error(
        "{file}: cross-validation across separations needs at least 2 separations (fit on \
         some, predict the others); the file has {} ({} in). No candidate could be tested: {}",
        separations.len(),
        fmt_list(separations),
        candidates.iter().map(|c| c.name()).collect::<Vec<_>>().join(", ")
    )]
    TooFewSeparations {
        /// The measurement file.
        file: String,
        /// Its separations.
        separations: Vec<f64>,
        /// The candidates asked for.
        candidates: Vec<Cand>,
    },
    /// A held-out separation is not in the file.
    #[error(
        "{file}: --holdout separation {separation} in is not in the file, nor any within {} \
         in (it has {})",
        SEP_MATCH_IN,
        fmt_list(have)
    )]
    HoldoutMissing {
        /// The measurement file.
        file: String,
        /// The separation asked for, inches.
        separation: f64,
        /// The file's separations.
        have: Vec<f64>,
    },
    /// Every separation held out: nothing left to fit.
    #[error("--holdout: hold out some separations, not all")]
    HoldoutAll,
    /// Even the starting model could not be fitted.
    #[error(
        "{}",
        wiring::explained(&format!("{file}: {error}"), diagnosis.as_deref())
    )]
    Selection {
        /// The measurement file.
        file: String,
        /// Why.
        error: select::Error,
        /// A common lab mistake that explains it ([`wiring::diagnose`]).
        diagnosis: Option<String>,
    },
}
