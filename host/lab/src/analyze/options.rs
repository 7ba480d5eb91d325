//! The options of an analysis.

use super::data::Weights;
use super::model::{self, Base, Cand};
use crate::budget::Budget;
use crate::sweep::corners::RunCorners;

/// What `cta analyze` does: the starting model, the cross-validation, the noise model and the
/// candidates ([`super::analyze`]).
#[derive(Debug, Clone)]
pub struct Options {
    /// Starting model.
    pub from: Base,
    /// Cross-validation folds.
    pub folds: usize,
    /// Explicit held-out separations (one fold), instead of `folds`.
    pub holdout: Option<Vec<f64>>,
    /// Weights.
    pub weights: Weights,
    /// Noise override, counts.
    pub noise: Option<f64>,
    /// Candidates considered.
    pub candidates: Vec<Cand>,
    /// Cap on named causes.
    pub max_effects: usize,
    /// Leave out the samples the glitch check flags ([`crate::data::Dataset::glitches`]).
    pub drop_glitches: bool,
    /// The run's corner readings: each separation's plate is placed with the tilt they
    /// measured ([`crate::sweep::corners`]); `None`: level plates.
    pub corners: Option<RunCorners>,
    /// The apparatus uncertainty budget apparatus causes are compared with (Ch IV; default
    /// thesis Table 2): [`super::plausible`].
    pub budget: Budget,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            from: Base::Thesis,
            folds: 5,
            holdout: None,
            weights: Weights::Separation,
            noise: None,
            candidates: model::ALL.to_vec(),
            max_effects: 5,
            drop_glitches: false,
            corners: None,
            budget: Budget::table2(),
        }
    }
}
