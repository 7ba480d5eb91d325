//! Why `cta calibrate` could not calibrate.

use std::path::PathBuf;

use cta_core::pose::ConfigError;

use super::NearFieldError;
use crate::data::fmt_list;
use crate::fit::magnitude::MagnitudeError;
use crate::fit::wiring;

/// Why a calibration could not be fitted, saved or plotted.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// `--out` names a file that may not be replaced.
    #[error(transparent)]
    Output(crate::data::OutputError),
    /// The plot could not be written.
    #[error(transparent)]
    Plot(crate::plot::PlotError),
    /// The near-field separations asked for are not in the file.
    #[error("--separations: {0}")]
    Separations(crate::data::SeparationError),
    /// One separation: the face angle and the cell offset show only across separations.
    #[error(
        "{}: the near-field fit needs at least 2 separations (it has only {} in): the face \
         angle and the cell offset show only in how the outputs change with range",
        path.display(),
        fmt_list(separations)
    )]
    TooFewSeparations {
        /// The measurement file.
        path: PathBuf,
        /// Its separations.
        separations: Vec<f64>,
    },
    /// One sample per point and no noise given.
    #[error(
        "{}: every point has one sample, so the noise cannot be measured: give --noise \
         COUNTS (0.1 % of beta is 32.8), or sweep with repeated samples",
        path.display()
    )]
    NoiseUnmeasured {
        /// The measurement file.
        path: PathBuf,
    },
    /// A noise the board does not take: given with `--noise`, or measured from the file's
    /// repeated samples (`path`; constant or noise-free data measure 0).
    #[error(
        "{}: the board takes 0.01 to 10,000 counts{}",
        match path {
            None => format!("--noise {}", crate::fit::calibrate::shown(*noise)),
            Some(p) => format!(
                "{}: the noise of its repeated samples is {} counts",
                p.display(),
                crate::fit::calibrate::shown(*noise)
            ),
        },
        if path.is_some() {
            " (do its X, Y vary at all? constant or noise-free data measure no noise): give the \
             sensor's noise with --noise COUNTS"
        } else {
            ""
        }
    )]
    NoiseRange {
        /// The noise, counts.
        noise: f64,
        /// The measurement file, when the noise was measured from it.
        path: Option<PathBuf>,
    },
    /// A beacon pattern exponent the board does not take.
    #[error("--pattern-m {0}: the board takes 0 to 50")]
    PatternM(f64),
    /// Too few points off the rail for the near-field fit.
    #[error(
        "{}: {usable} usable points ({pinned} pinned), the near-field fit needs at least 8",
        path.display()
    )]
    TooFewPoints {
        /// The measurement file.
        path: PathBuf,
        /// Points off the rail.
        usable: usize,
        /// Points at or near the rail.
        pinned: usize,
    },
    /// The pinhole separations are not in the file.
    #[error("pinhole separations: {0}")]
    PinholeSeparations(crate::data::SeparationError),
    /// The pinhole fit (eq 65) failed.
    #[error(
        "{}",
        wiring::explained(
            &format!("pinhole fit at {} in: {why}", fmt_list(separations)),
            diagnosis.as_deref()
        )
    )]
    PinholeFit {
        /// Its separations.
        separations: Vec<f64>,
        /// Why.
        why: String,
        /// A common lab mistake that explains it ([`wiring::diagnose`]).
        diagnosis: Option<String>,
    },
    /// The near-field fit failed from the pinhole fit's head pose and from the nominal one.
    #[error(transparent)]
    NearField(Box<NearFieldFailed>),
    /// The fitted calibration fails [`cta_core::pose::Calibration::validate`].
    #[error(
        "{}: the fitted calibration is outside what the board accepts: {error}{value}. \
         {cause}{unit}",
        path.display()
    )]
    OutOfRange {
        /// The measurement file.
        path: PathBuf,
        /// What the board refuses.
        error: ConfigError,
        /// The refused value with its 1-sigma, in parentheses, when there is one.
        value: String,
        /// The likely cause.
        cause: String,
        /// A note when the offset is a length unit off, after `; `.
        unit: String,
    },
    /// The fitted magnitude law fails [`cta_core::pose::Calibration::validate`].
    #[error("{}: the magnitude law: {error}", path.display())]
    MagnitudeLaw {
        /// The measurement file.
        path: PathBuf,
        /// What the board refuses.
        error: ConfigError,
    },
    /// The magnitude law could not be fitted at the sensitivity asked for.
    #[error(transparent)]
    Magnitude(#[from] MagnitudeError),
    /// The calibration file could not be written.
    #[error(transparent)]
    Write(crate::data::OutputError),
    /// The calibration could not be serialized.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// The near-field fit failed from the pinhole fit's head pose and from the nominal one.
#[derive(Debug, thiserror::Error)]
#[error(
    "{}",
    wiring::explained(
        &format!(
            "{}: {first}; from the nominal head pose (d = {nominal_d} in) too: {second}. {cause}",
            path.display()
        ),
        diagnosis.as_deref()
    )
)]
pub struct NearFieldFailed {
    /// The measurement file.
    pub path: PathBuf,
    /// The failure from the pinhole fit's head pose.
    pub first: NearFieldError,
    /// The nominal head position, inches.
    pub nominal_d: String,
    /// The failure from it.
    pub second: NearFieldError,
    /// The likely cause.
    pub cause: String,
    /// A common lab mistake that explains it ([`wiring::diagnose`]).
    pub diagnosis: Option<String>,
}
