//! What an analysis finds: the named causes with their parameters, the candidates tried and
//! ruled out, the fit quality before and after ([`Analysis`], which `--json` prints).

use std::borrow::Borrow;

use serde::Serialize;

use super::corners::CornersOut;
use super::data::Data;
use super::diag;

/// A named (or tentative) cause.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Cause {
    /// Vocabulary name.
    pub effect: String,
    /// Fitted parameters in the final model, with every named cause (physical units;
    /// per-separation ones as `x@Sin`), in the model's order ([`ParamMap`]). The gains below
    /// are those of the step that added it.
    pub params: ParamMap,
    /// Their 1-sigma.
    pub sigma: ParamMap,
    /// Held-out RMS gain from adding this effect, counts (`heldout_rms_before -
    /// heldout_rms_after`: noise included, so a cause that removes all of a small error reads
    /// a small gain; `systematic_rms_before/after` is the measure).
    pub gain_rms_counts: f64,
    /// The held-out RMS that noise alone gives on the same rows (the noise of the point
    /// means), counts.
    pub heldout_noise_rms: f64,
    /// The systematic part of the held-out RMS before adding it, `sqrt(before^2 - noise^2)`
    /// (0 when below the noise), counts.
    pub systematic_rms_before: f64,
    /// After.
    pub systematic_rms_after: f64,
    /// Chi-square improvement on all data.
    pub dchi2: f64,
    /// BIC improvement (> 10 to be accepted).
    pub dbic: f64,
    /// Held-out RMS before and after adding it, counts.
    pub heldout_rms_before: f64,
    /// After.
    pub heldout_rms_after: f64,
    /// Chi-square per degree of freedom after adding it.
    pub chi2_dof_after: f64,
    /// Correlations between this cause's own (global) parameters as reported, at least
    /// [`CORRELATION_MIN`] in magnitude (from the fit's covariance, delta method for derived
    /// quantities).
    pub correlations: Vec<Correlation>,
    /// Correlations of its parameters with a starting-model parameter (d, p, H) in the same
    /// fit, at least [`BASE_CORRELATION_MIN`] in magnitude.
    pub base_correlations: Vec<Correlation>,
    /// Candidates of the same round that explain the data about as well: significant on
    /// their own (`dBIC > 10`) and within [`RIVAL_DBIC`] of this cause. The data do not
    /// tell them apart (e.g. `proximity` and `beacon_pattern` at small sizes: host/ANALYZE.md,
    /// "Detection limits").
    pub rivals: Vec<Rival>,
    /// What the sensor board can do with it ([`super::board_note`]).
    pub board: String,
    /// A reading of the file that explains the cause as well (`proximity` with S 2.54x the
    /// NorthStar's: lengths in centimetres, [`crate::fit::wiring::s_unit_note`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub caution: Option<String>,
    /// For an apparatus cause (`plate_offset`, `separation_error`, `plate_tilt`): its fitted
    /// size against the budget line it is compared with, and a warning when far beyond it
    /// ([`super::plausible`]). Such a cause is not named as found.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub budget: Option<BudgetCheck>,
}

impl Cause {
    /// Whether the cause is fitted far beyond the apparatus budget (named with a warning,
    /// not as found).
    pub fn beyond_budget(&self) -> bool {
        self.budget.as_ref().is_some_and(|b| b.warning.is_some())
    }
}

/// Named values in the order they were inserted: a cause's parameters in the model's order
/// (`beacon_tilt`: `T_deg` before `AZ_deg`; per-separation ones separation by separation).
/// JSON: an object with the keys in that order (`params.T_deg`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParamMap(Vec<(String, f64)>);

impl ParamMap {
    /// Set `name` to `value`: in place when present, else at the end.
    pub fn insert(&mut self, name: impl Into<String>, value: f64) {
        let name = name.into();
        match self.0.iter_mut().find(|(n, _)| *n == name) {
            Some(e) => e.1 = value,
            None => self.0.push((name, value)),
        }
    }

    /// The value of `name`.
    pub fn get<Q>(&self, name: &Q) -> Option<&f64>
    where
        String: Borrow<Q>,
        Q: Eq + ?Sized,
    {
        self.0
            .iter()
            .find(|(n, _)| n.borrow() == name)
            .map(|(_, v)| v)
    }

    /// (name, value) in order.
    pub fn iter(&self) -> impl Iterator<Item = (&String, &f64)> {
        self.0.iter().map(|(n, v)| (n, v))
    }

    /// The names in order.
    pub fn keys(&self) -> impl Iterator<Item = &String> {
        self.0.iter().map(|(n, _)| n)
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl<Q> std::ops::Index<&Q> for ParamMap
where
    String: Borrow<Q>,
    Q: Eq + ?Sized,
{
    type Output = f64;

    /// Panics when `name` is absent, like `BTreeMap`'s index.
    fn index(&self, name: &Q) -> &f64 {
        self.get(name).expect("no parameter of that name")
    }
}

impl Serialize for ParamMap {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for (n, v) in &self.0 {
            m.serialize_entry(n, v)?;
        }
        m.end()
    }
}

/// Correlations between a candidate's own parameters are shown from this magnitude on.
pub const CORRELATION_MIN: f64 = 0.5;

/// Correlations of a candidate's parameter with a starting-model parameter are shown from
/// this magnitude on.
pub const BASE_CORRELATION_MIN: f64 = 0.9;

/// The correlation coefficient of two parameters' estimates in one fit.
#[derive(Debug, Clone, Serialize)]
pub struct Correlation {
    /// First parameter (the candidate's).
    pub a: String,
    /// Second parameter (the candidate's, or the starting model's).
    pub b: String,
    /// Correlation coefficient, -1..1.
    pub rho: f64,
}

/// A candidate whose BIC is within this of a named cause's is reported as its rival: a BIC
/// difference below 10 is not "very strong" evidence for one model over the other (Kass and
/// Raftery's scale).
pub const RIVAL_DBIC: f64 = 10.0;

/// A candidate that explains the data about as well as a named cause ([`Cause::rivals`]).
#[derive(Debug, Clone, Serialize)]
pub struct Rival {
    /// Vocabulary name.
    pub effect: String,
    /// Its BIC improvement in the same round.
    pub dbic: f64,
}

/// A candidate that could not be tested.
#[derive(Debug, Clone, Serialize)]
pub struct Untested {
    /// Vocabulary name.
    pub effect: String,
    /// Why.
    pub reason: String,
}

/// One candidate tried in one round (the evidence table).
#[derive(Debug, Clone, Serialize)]
pub struct TrialOut {
    /// Round.
    pub round: usize,
    /// Candidate.
    pub effect: String,
    /// Added parameters.
    pub k: usize,
    /// Chi-square improvement.
    pub dchi2: f64,
    /// BIC improvement.
    pub dbic: f64,
    /// Held-out RMS with it (when measured), counts.
    pub heldout_rms: Option<f64>,
    /// Accepted.
    pub accepted: bool,
    /// Fit failure.
    pub failure: Option<String>,
    /// Whether the candidate was fitted on all data (false: a failure, or no saturation level
    /// to start from).
    pub fitted: bool,
    /// The candidate's fitted parameters with 1-sigma and no-effect value (empty when it was
    /// not fitted): the global ones as [`super::model::Cand::trial_report`] gives them, then every
    /// per-separation value (`x@2in`).
    pub params: Vec<Param>,
    /// Correlations between its global parameters (as in `params`), at least
    /// [`CORRELATION_MIN`] in magnitude.
    pub correlations: Vec<Correlation>,
    /// Correlations of its global parameters with a starting-model parameter, at least
    /// [`BASE_CORRELATION_MIN`] in magnitude.
    pub base_correlations: Vec<Correlation>,
}

/// A cause forward selection named and then dropped, because once later causes were named
/// it no longer earned its parameters (host/ANALYZE.md, Method 4).
#[derive(Debug, Clone, Serialize)]
pub struct DroppedOut {
    /// The effect.
    pub effect: String,
    /// The round it was named in.
    pub round: usize,
    /// Its BIC improvement then.
    pub dbic_named: f64,
    /// The other causes of the model it was dropped from.
    pub others: Vec<String>,
    /// Its parameters.
    pub k: usize,
    /// Chi-square lost without it, in that model.
    pub dchi2_keep: f64,
    /// BIC improvement of keeping it (at most 10, or the held-out RMS did not improve).
    pub dbic_keep: f64,
    /// Held-out RMS with it, counts.
    pub heldout_rms_with: f64,
    /// Without it, when the held-out test decided.
    pub heldout_rms_without: Option<f64>,
}

/// A candidate tried on top of the final model and not accepted: how tightly the data rule
/// it out.
#[derive(Debug, Clone, Serialize)]
pub struct RuledOut {
    /// Candidate.
    pub effect: String,
    /// Added parameters.
    pub k: usize,
    /// Chi-square improvement.
    pub dchi2: f64,
    /// BIC improvement.
    pub dbic: f64,
    /// Whether it was fitted (false: see `note`).
    pub fitted: bool,
    /// Global parameters: estimate, 1-sigma, no-effect value.
    pub params: Vec<Param>,
    /// Per-separation parameters, summarised.
    pub per_separation: Vec<SepSpread>,
    /// Correlations between its global parameters, at least [`CORRELATION_MIN`] in
    /// magnitude: the estimates +/- 1-sigma are marginal.
    pub correlations: Vec<Correlation>,
    /// Correlations of its global parameters with a starting-model parameter, at least
    /// [`BASE_CORRELATION_MIN`] in magnitude.
    pub base_correlations: Vec<Correlation>,
    /// Failure, or why a candidate with dBIC > 10 was still not accepted.
    pub note: Option<String>,
}

/// The spread of one per-separation parameter over the separations.
#[derive(Debug, Clone, Serialize)]
pub struct SepSpread {
    /// Parameter (`x`, `y`, `z`), in.
    pub name: String,
    /// RMS of the per-separation estimates x_k, weighted by their inverse variance
    /// `1/sigma_k^2` (the best-measured separations count most): `sqrt(sum(x_k^2/sigma_k^2) /
    /// sum(1/sigma_k^2))`, in.
    pub rms: f64,
    /// What noise alone gives that RMS on average: `sqrt(n / sum(1/sigma_k^2))`, in. An
    /// effect that scatters the separations with standard deviation D raises the square of
    /// `rms` by about D^2.
    pub noise_rms: f64,
    /// Separations.
    pub separations: usize,
}

/// A parameter with its 1-sigma.
#[derive(Debug, Clone, Serialize)]
pub struct Param {
    /// Name.
    pub name: String,
    /// Value.
    pub value: f64,
    /// 1-sigma.
    pub sigma: f64,
    /// For a candidate's parameter, its value when the effect is absent (thesis physics:
    /// `S` 0.175 in, `H_deg` 60, everything else 0; omitted for `saturation`, which has no
    /// finite one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub no_effect: Option<f64>,
}

/// The analysis result (`--json` prints it).
#[derive(Debug, Clone, Serialize)]
pub struct Analysis {
    /// The file analyzed.
    pub file: String,
    /// Starting model.
    pub model_from: String,
    /// Named causes, most important first.
    pub causes: Vec<Cause>,
    /// Effects that improved the fit but are not named, because structure remains.
    pub tentative: Vec<Cause>,
    /// Correlations between the parameters of two different causes (named or tentative) in
    /// the final model's fit, at least [`BASE_CORRELATION_MIN`] in magnitude, each name
    /// qualified by its cause (`proximity.S`): their sizes trade against each other.
    pub cross_correlations: Vec<Correlation>,
    /// Causes named by forward selection and dropped once later causes made them redundant.
    pub dropped: Vec<DroppedOut>,
    /// Candidates that could not be tested, and why.
    pub untested: Vec<Untested>,
    /// The final model leaves chi2/dof clearly above 1.
    pub unexplained: bool,
    /// One-line verdict.
    pub verdict: String,
    /// The crosstalk check of a grouped sweep (beacons measured alone and in their group);
    /// `None` when the file has none.
    pub crosstalk: Option<crate::crosstalk::Check>,
    /// Chi-square per degree of freedom of the starting model (all data).
    pub chi2_dof_before: f64,
    /// Of the final model.
    pub chi2_dof_after: f64,
    /// Held-out RMS of the starting model, counts.
    pub rms_before: f64,
    /// Of the final model.
    pub rms_after: f64,
    /// Separations, in.
    pub separations: Vec<f64>,
    /// Angle-error std per separation, starting model, deg.
    pub angle_std_before_deg: Vec<f64>,
    /// Final model.
    pub angle_std_after_deg: Vec<f64>,
    /// Points left out of both angle columns because one of the models cannot turn their
    /// output into a direction (measured output beyond what it predicts, near the rail).
    pub angle_left_out: usize,
    /// The held-out RMS noise alone gives, over every held-out row, counts.
    pub heldout_noise_rms: f64,
    /// The RMS noise alone gives per separation (the noise of its point means), counts.
    pub noise_rms_by_sep: Vec<f64>,
    /// Held-out RMS per separation before and after, counts.
    pub heldout_rms_by_sep_before: Vec<f64>,
    /// After.
    pub heldout_rms_by_sep_after: Vec<f64>,
    /// Parameters of the starting model's fit.
    pub params_before: Vec<Param>,
    /// Global parameters of the final model's fit.
    pub params_after: Vec<Param>,
    /// Noise model in words.
    pub noise: String,
    /// What the results rest on that needs saying: glitches that inflate the noise the fits
    /// weight by (or were left out), settings whose noise differs under weights that pool
    /// them, a noise far larger than the residuals.
    pub data_notes: Vec<String>,
    /// The plate tilts the run's corner readings measured, applied to every model
    /// (`--ignore-corners` or no journal beside the file: `None`).
    pub corners: Option<CornersOut>,
    /// One-sample noise per separation (X, Y), counts.
    pub noise_by_sep: Vec<[f64; 2]>,
    /// Samples read, points fitted, points left out.
    pub samples: usize,
    /// Points fitted.
    pub points: usize,
    /// Points left out (an output at or near the 16-bit rail).
    pub excluded_points: usize,
    /// Cross-validation folds (held-out separations of each).
    pub folds: Vec<Vec<f64>>,
    /// Where the final model's residuals stand out.
    pub structure: Vec<String>,
    /// Residual diagnostics before and after.
    pub diagnostics_before: diag::Diagnostics,
    /// After.
    pub diagnostics_after: diag::Diagnostics,
    /// Every candidate tried.
    pub trials: Vec<TrialOut>,
    /// The candidates tried on top of the final model and not accepted, with their estimates.
    pub ruled_out: Vec<RuledOut>,
    /// Why `ruled_out` is empty, when it is.
    pub ruled_out_note: Option<String>,
    /// Everything the report plots (not in JSON).
    #[serde(skip)]
    pub detail: Option<Box<Detail>>,
}

/// What the report needs beyond the summary.
#[derive(Debug, Clone)]
pub struct Detail {
    /// The weighted points.
    pub data: Data,
    /// Residuals and predictions of the starting model.
    pub before: Vec<([f64; 2], [f64; 2])>,
    /// Of the final model.
    pub after: Vec<([f64; 2], [f64; 2])>,
    /// Angle errors per point before and after, deg.
    pub angle_before: Vec<f64>,
    /// After.
    pub angle_after: Vec<f64>,
}

/// How a fitted apparatus cause compares with the budget.
#[derive(Debug, Clone, Serialize)]
pub struct BudgetCheck {
    /// The budget line compared with, in words (`X root-sum-square of thesis Table 2 (eq 26):
    /// 31.5 mils`).
    pub line: String,
    /// That line's value, mils.
    pub budget_mils: f64,
    /// The fitted size compared with it, mils (the RMS over the separations; for
    /// `plate_tilt` the height change the RMS tilt makes at the farthest beacon).
    pub fitted_mils: f64,
    /// `fitted_mils / budget_mils`.
    pub ratio: f64,
    /// When `ratio` exceeds [`super::plausible::BEYOND_BUDGET`]: why the cause is not named as found, and the
    /// alternatives the data point to.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub warning: Option<String>,
}
