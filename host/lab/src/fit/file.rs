//! Fitting a measurement file as `cta fit` does and preparing one for `cta evaluate`: the
//! separations chosen, the glitches left out, and the notes the pinhole fit's numbers need.

use super::pinhole::{chi2_warning, fit, FitError};
use super::report::FitReport;
use super::wiring;
use crate::data::weights::{repeat_chi2_expected, Weights};
use crate::data::{Dataset, SeparationError};
use std::path::Path;

/// A measurement file restricted to the separations asked for, without its glitches when
/// they are to be left out.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The rows to fit or evaluate.
    pub data: Dataset,
    /// What was left out, in words (the `--drop-glitches` note), for the output's `data_notes`.
    pub notes: Vec<String>,
    /// How many glitched samples were left out.
    pub glitches_left_out: usize,
}

/// Keep the file's separations nearest to `separations` (all when `None`) and, with
/// `drop_glitches`, leave out the samples the glitch check flags in them.
pub fn prepare(
    ds: Dataset,
    separations: Option<&[f64]>,
    drop_glitches: bool,
) -> Result<Prepared, SeparationError> {
    let mut data = match separations {
        Some(s) => ds.select(s)?,
        None => ds,
    };
    let mut notes = Vec::new();
    let mut glitches_left_out = 0;
    if drop_glitches {
        if let Some(clean) = data.without_glitches() {
            notes.push(clean.note());
            glitches_left_out = clean.samples;
            data = clean.data;
        }
    }
    Ok(Prepared {
        data,
        notes,
        glitches_left_out,
    })
}

/// The pinhole fit of a file failed: why, and what a miswired head would explain of it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}", explained(.error, .diagnosis))]
pub struct FileFitError {
    /// Why the fit failed.
    pub error: FitError,
    /// A miswired head's signature in the data ([`wiring::diagnose`]), when it has one.
    pub diagnosis: Option<String>,
}

/// The fit's error, with the diagnosis after it when there is one.
fn explained(error: &FitError, diagnosis: &Option<String>) -> String {
    let e = error.to_string();
    match diagnosis {
        Some(d) => format!("{}. {d}", e.trim_end_matches('.')),
        None => e,
    }
}

/// Fit eq 65 to a prepared file with `weights`, and add what the numbers need said: an `H` far
/// from the NorthStar's, a head turned about its boresight, a chi-square above what the noise
/// gives. `file` is the measurement file as named on the command line.
pub fn fit_file(
    prepared: Prepared,
    weights: Weights,
    file: &Path,
) -> Result<FitReport, FileFitError> {
    let ds = &prepared.data;
    let mut rep = fit(ds, weights).map_err(|error| FileFitError {
        diagnosis: wiring::diagnose(ds),
        error,
    })?;
    rep.data_notes = prepared.notes;
    rep.warnings.extend(wiring::h_warning(ds, rep.params["H"]));
    // A head turned about its boresight (or X and Y read so) fits as well as a square one.
    rep.warnings.extend(wiring::turned_head_note(
        ["p1", "p2", "p3"].map(|n| rep.params[n]),
        Some(rep.params["H"]),
    ));
    rep.warnings
        .extend(chi2_warning(&rep, file, repeat_chi2_expected(ds)));
    Ok(rep)
}
