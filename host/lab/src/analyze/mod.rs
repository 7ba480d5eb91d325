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

pub mod data;
pub mod diag;
pub mod digits;
pub mod model;
pub mod report;
pub mod select;
pub use crate::fit::wiring;

use crate::data::{parse_separations, Dataset};
use crate::sweep::corners::RunCorners;
use data::{Data, Weights};
pub use digits::{pm, pm_parts};
use model::{Base, Cand, FitResult, Model};
use nalgebra::DMatrix;
use serde::Serialize;
use std::borrow::Borrow;
use std::path::PathBuf;

/// Chi-square per degree of freedom above which the final model is said to leave
/// unexplained structure (and no cause is named with confidence).
pub const UNEXPLAINED_CHI2_DOF: f64 = 1.2;

/// Fewest usable points at every separation for the per-separation corrections
/// (`plate_offset`, `separation_error`, `plate_tilt`) to be tried.
pub const MIN_POINTS_PER_SEPARATION: usize = 8;

/// A starting-model chi2/dof below this says the noise the fits weight by is far larger than
/// the residuals (with hundreds of degrees of freedom chi2/dof scatters by ~0.05 around 1).
pub const NOISE_TOO_LARGE_CHI2_DOF: f64 = 0.5;

/// `cta analyze`: find what the model misses in measured data, name the physical cause,
/// and measure how much better the extended model predicts data it was not fitted on.
#[derive(Debug, Clone, clap::Args)]
#[command(after_long_help = "\
METHOD (host/ANALYZE.md has the details):
  Repeated samples of one point are averaged and weighted by 1/sigma^2 (the noise pooled per
  separation by default). The starting model is fitted by GLSDC, then every candidate effect
  is fitted on top of it. A candidate is accepted when it lowers the Bayesian information
  criterion by more than 10 AND predicts held-out separations better (cross-validation: fit on
  some separations, predict the others). The best accepted one is added and the search
  repeats until nothing significant remains. Then each named cause but the last must pass
  the same test against all the others; one that fails stood in for them: it is dropped and
  the search rerun without it.

  Candidates: proximity (from pinhole), intensity (from pinhole), beacon_pattern, beacon_tilt,
  cell_gain, cell_bias, face_angle, saturation, plate_offset, separation_error, plate_tilt.

VERDICTS:
  named causes        the extended model brings chi2/dof near 1 (<= 1.2)
  no significant effect  the starting model already explains the data
  unexplained structure remains  the best extension still leaves chi2/dof > 1.2: nothing is
                      named with confidence; the output shows where the residuals are
  dropped             a cause named in an early round that the later causes made redundant
  not named           every candidate tried on top of the final model and not accepted, with
                      its estimate +/- 1-sigma: the data still allow about estimate +/- 2 sigma
                      (one with dBIC > 10 says why it was not accepted: it may be there)
  correlation: DX,DY +0.71  under a candidate's estimates: two of its parameters correlate
                      (|rho| >= 0.5), so their 1-sigma alone mislead; `with the starting
                      model`: |rho| >= 0.9 with d, p or H. Every value +/- 1-sigma is rounded
                      to the 2nd significant digit of the 1-sigma (JSON: full precision)
  correlation between causes: beacon_pattern.H_deg,proximity.S +1.00
                      after the causes: parameters of two causes correlate (|rho| >= 0.9) in
                      the final model, so their sizes trade against each other

EXAMPLE:
  cta simulate --out tilt.csv --separations 2..30 --noise 32.8 --samples 5 --effect beacon_tilt=3,45
  cta analyze tilt.csv --report tilt-report    # then open tilt-report/index.html
  cta analyze tilt.csv --json | jq .causes")]
pub struct AnalyzeArgs {
    /// Measurement file (CSV, host/MEASUREMENTS.md).
    pub file: PathBuf,
    /// Starting model: `thesis` (eq 63 near-field physics, pose free) or `pinhole` (the
    /// 7-parameter eq 65 collinearity model).
    #[arg(long = "from", value_enum, default_value = "thesis")]
    pub from: Base,
    /// Cross-validation folds across separations (separation k goes to fold k mod FOLDS).
    #[arg(long, default_value_t = 5)]
    pub folds: usize,
    /// Use ONE explicit held-out fold instead: these separations are predicted by a model
    /// fitted on the others (e.g. `5,15,25` or `20..30`). Needs at least one left to fit.
    #[arg(long, value_name = "SEPS")]
    pub holdout: Option<String>,
    /// Analyze only these separations (e.g. `2..30:2`).
    #[arg(long, value_name = "SEPS")]
    pub separations: Option<String>,
    /// How repeated samples weight the point means: pooled per `separation`, per separation
    /// and `setting` (frequency, power, sensitivity: `cta noise` says when), per `point`, or
    /// `global`.
    #[arg(long, value_enum, default_value = "separation")]
    pub weights: Weights,
    /// One-sample noise in counts, when the file has one sample per point (default 32.8 =
    /// 0.1 % of beta) or to override the measured noise.
    #[arg(long, value_name = "COUNTS")]
    pub noise: Option<f64>,
    /// Only consider these candidates (comma-separated vocabulary names).
    #[arg(long, value_name = "LIST")]
    pub candidates: Option<String>,
    /// Never consider these candidates.
    #[arg(long, value_name = "LIST")]
    pub exclude: Option<String>,
    /// Stop after naming this many causes.
    #[arg(long, default_value_t = 5)]
    pub max_effects: usize,
    /// Leave out the samples the glitch check flags (more than 8 robust sigma from their
    /// point's median; the warning names their lines). The file is not changed; the output
    /// says how many were left out.
    #[arg(long)]
    pub drop_glitches: bool,
    /// Take every plate as level. By default, when the file sits in a sweep's run directory,
    /// each separation's plate is placed with the tilt the operator's four corner readings
    /// in its journal.jsonl measured (far finer than the fit can tell: 1 mil over the
    /// rods is 0.007 deg), and `plate_tilt` is the tilt beyond them.
    #[arg(long)]
    pub ignore_corners: bool,
    /// Write a self-contained HTML report (index.html, inline SVG plots) into this folder.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Print the result as JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Options of the analysis (the library form of [`AnalyzeArgs`]).
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
    /// Leave out the samples the glitch check flags ([`Dataset::glitches`]).
    pub drop_glitches: bool,
    /// The run's corner readings: each separation's plate is placed with the tilt they
    /// measured ([`crate::sweep::corners`]); `None`: level plates.
    pub corners: Option<RunCorners>,
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
        }
    }
}

/// A named (or tentative) cause.
#[derive(Debug, Clone, Serialize)]
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
    /// What the sensor board can do with it ([`board_note`]).
    pub board: String,
    /// A reading of the file that explains the cause as well (`proximity` with S 2.54x the
    /// NorthStar's: lengths in centimetres, [`wiring::s_unit_note`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub caution: Option<String>,
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

/// What the sensor board's pose solver can do with a named effect: whether its calibration
/// (`cta calibrate`, firmware-sensor) or its constellation holds it, or it stays outside the
/// chip's model (host/CALIBRATE.md).
pub fn board_note(effect: &str) -> String {
    match effect {
        "cell_gain" => "the board's calibration holds it (gx, gy): `cta calibrate` fits it",
        "cell_bias" => "the board's calibration holds it (bx, by): `cta calibrate` fits it",
        "face_angle" => {
            "the board's calibration holds it (the pairs' face angles a, ay): `cta calibrate` \
             fits it"
        }
        "proximity" => {
            "the board's calibration holds it (the cell offset s): `cta calibrate` fits it"
        }
        "intensity" => "the board's near-field model includes it (eq 63's inverse square)",
        "beacon_pattern" => {
            "the board's calibration holds the LEDs' pattern exponent, but `cta calibrate` \
             cannot tell it from s and d3: give `--pattern-m` from the LED datasheet \
             (host/CALIBRATE.md)"
        }
        "beacon_tilt" => {
            "the board holds it in the constellation's LED boresight (`cta sensor template \
             constellation`), not in the calibration"
        }
        "saturation" => {
            "outside the board's model: its poses use saturated spots as they are; keep the \
             beacons outside the range where the cells clip"
        }
        "plate_offset" | "separation_error" | "plate_tilt" => {
            "an error of the apparatus, not of the sensor: nothing for the board to hold; the \
             sensor's calibration from these data absorbs part of it"
        }
        _ => "outside the board's model",
    }
    .to_string()
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

/// `A,B +0.66, C,D -0.51`.
pub fn correlations_text(c: &[Correlation]) -> String {
    c.iter()
        .map(|c| format!("{},{} {:+.2}", c.a, c.b, c.rho))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The correlation lines of a candidate (empty when none reaches its threshold):
/// `correlation: DX,DY +0.66`, `correlation with the starting model: S,d3 +0.93`.
pub fn correlation_lines(own: &[Correlation], base: &[Correlation]) -> Vec<String> {
    let mut v = Vec::new();
    if !own.is_empty() {
        v.push(format!("correlation: {}", correlations_text(own)));
    }
    if !base.is_empty() {
        v.push(format!(
            "correlation with the starting model: {}",
            correlations_text(base)
        ));
    }
    v
}

/// `correlation between causes: beacon_pattern.H_deg,proximity.S +1.00`, or None when there
/// is none
/// ([`Analysis::cross_correlations`]).
pub fn cross_correlation_line(c: &[Correlation]) -> Option<String> {
    (!c.is_empty()).then(|| format!("correlation between causes: {}", correlations_text(c)))
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

/// The rivals of the cause `cand` accepted in `round` with BIC improvement `dbic`: the other
/// candidates of that round significant on their own (`dBIC > 10`) whose improvement is
/// within [`RIVAL_DBIC`] of it, above or below. (One far above it fits the data better but was
/// not accepted, having failed to predict the held-out separations: not a tie.)
fn rivals(trials: &[select::Trial], round: usize, cand: Cand, dbic: f64) -> Vec<Rival> {
    trials
        .iter()
        .filter(|t| {
            t.round == round
                && t.cand != cand
                && t.dbic > 10.0
                && (t.dbic - dbic).abs() < RIVAL_DBIC
        })
        .map(|t| Rival {
            effect: t.cand.name().into(),
            dbic: t.dbic,
        })
        .collect()
}

impl Cause {
    /// "`X` explains the data about as well ..." when the cause has rivals.
    pub fn rivals_line(&self) -> Option<String> {
        if self.rivals.is_empty() {
            return None;
        }
        let list: Vec<String> = self
            .rivals
            .iter()
            .map(|r| format!("{} (dBIC {:.1} vs {:.1})", r.effect, r.dbic, self.dbic))
            .collect();
        Some(format!(
            "but {} {} the data about as well: a BIC difference below {RIVAL_DBIC} does not \
             tell them apart (host/ANALYZE.md, Detection limits)",
            list.join(", "),
            if list.len() == 1 {
                "explains"
            } else {
                "explain"
            }
        ))
    }

    /// The global (not per-separation) parameters as `name = value PM sigma` strings
    /// ([`digits`]: the value to the decimal place of its 1-sigma's second digit).
    pub fn global_params(&self, pmark: &str) -> Vec<String> {
        self.params
            .iter()
            .filter(|(n, _)| !n.contains('@'))
            .map(|(n, v)| {
                let u = unit(&self.effect, n);
                if v.is_nan() {
                    // beacon_pattern's H_deg with m <= 0.
                    return format!(
                        "{n} = none (no half-intensity angle: the pattern does not fall off \
                         the axis)"
                    );
                }
                match self.sigma.get(n) {
                    Some(sg) => format!("{n} = {}{u}", pm(*v, *sg, pmark)),
                    None => format!("{n} = {}{u}", g(*v)),
                }
            })
            .collect()
    }
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
    /// not fitted): the global ones as [`model::Cand::trial_report`] gives them, then every
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

impl DroppedOut {
    /// One line of text: why it was dropped.
    pub fn line(&self) -> String {
        let why = match self.heldout_rms_without {
            None => format!(
                "keeping its {} parameters gains dBIC {:.0} (dchi2 {:.0}), at most {}",
                self.k,
                self.dbic_keep,
                self.dchi2_keep,
                select::BIC_MIN
            ),
            Some(w) => format!(
                "without it the held-out RMS is {w:.2} counts, {:.2} with it",
                self.heldout_rms_with
            ),
        };
        format!(
            "{}: named in round {} (dBIC {:.0}), but once {} {} named, {why}: it stood in for \
             them, so the search was rerun without it",
            self.effect,
            self.round,
            self.dbic_named,
            self.others.join(", "),
            if self.others.len() == 1 {
                "was"
            } else {
                "were"
            },
        )
    }
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

fn parse_cands(s: &str) -> Result<Vec<Cand>, String> {
    s.split(',')
        .map(str::trim)
        .filter(|p| !p.is_empty())
        .map(|n| {
            Cand::from_name(n).ok_or_else(|| {
                if n == "crosstalk" {
                    "`crosstalk` is simulation-only, not an analysis candidate".to_string()
                } else {
                    format!(
                        "unknown candidate `{n}`; known: {}",
                        model::ALL.map(|c| c.name()).join(", ")
                    )
                }
            })
        })
        .collect()
}

impl AnalyzeArgs {
    /// The library options of these arguments.
    pub fn options(&self) -> Result<Options, String> {
        let mut candidates = match &self.candidates {
            Some(s) => parse_cands(s)?,
            None => model::ALL.to_vec(),
        };
        if let Some(s) = &self.exclude {
            let ex = parse_cands(s)?;
            candidates.retain(|c| !ex.contains(c));
        }
        if self.folds < 2 {
            return Err(format!("--folds {}: need at least 2", self.folds));
        }
        if self.max_effects == 0 {
            return Err(
                "--max-effects 0: no effect could be named; give at least 1 (default 5)".into(),
            );
        }
        Ok(Options {
            from: self.from,
            folds: self.folds,
            holdout: (self.holdout.as_deref().map(parse_separations).transpose())
                .map_err(|e| e.to_string())?,
            weights: self.weights,
            noise: self.noise,
            candidates,
            max_effects: self.max_effects,
            drop_glitches: self.drop_glitches,
            corners: None,
        })
    }
}

fn params_of(model: &Model, f: &FitResult, seps: &[f64], globals_only: bool) -> Vec<Param> {
    let names = model.names(seps);
    let n = if globals_only {
        model.n_global_params()
    } else {
        names.len()
    };
    (0..n)
        .map(|i| Param {
            name: names[i].clone(),
            value: f.x[i],
            sigma: f.sigma[i],
            no_effect: None,
        })
        .collect()
}

/// Quantities derived from effect `c`'s global parameters in the fit `f` of `model`, with
/// their covariance by the delta method (numerical gradient of the quantities through the
/// fitted covariance of those parameters, `J P J^T`), and their covariance with the starting
/// model's parameters from the same fit (no second fit).
struct Propagated<'n> {
    /// Name, value and 1-sigma of each quantity.
    q: Vec<(&'n str, f64, f64)>,
    /// Their covariance.
    cov: DMatrix<f64>,
    /// How many fitted parameters they derive from (fewer than 2: any correlation between
    /// them is the identity of one parameter, e.g. `beacon_pattern`'s H_deg and m).
    raw: usize,
    /// Each free parameter of the starting model: name, variance, covariance with each
    /// quantity.
    base: Vec<(&'static str, f64, Vec<f64>)>,
}

/// Correlation coefficient from a covariance and two variances; None when a variance is not
/// positive and finite.
fn rho(cov: f64, var_a: f64, var_b: f64) -> Option<f64> {
    let d = var_a * var_b;
    let r = cov / d.sqrt();
    (d > 0.0 && d.is_finite() && r.is_finite()).then(|| r.clamp(-1.0, 1.0))
}

impl Propagated<'_> {
    /// Every pair of the quantities whose correlation is at least [`CORRELATION_MIN`] in
    /// magnitude, in the order of the quantities.
    fn correlations(&self) -> Vec<Correlation> {
        let n = self.q.len();
        let mut out = Vec::new();
        if self.raw < 2 {
            return out;
        }
        for i in 0..n {
            for j in i + 1..n {
                let Some(r) = rho(self.cov[(i, j)], self.cov[(i, i)], self.cov[(j, j)]) else {
                    continue;
                };
                if r.abs() >= CORRELATION_MIN {
                    out.push(Correlation {
                        a: self.q[i].0.into(),
                        b: self.q[j].0.into(),
                        rho: r,
                    });
                }
            }
        }
        out
    }

    /// Every (quantity, starting-model parameter) pair whose correlation is at least
    /// [`BASE_CORRELATION_MIN`] in magnitude. With one underlying parameter
    /// (`beacon_pattern`'s H_deg and m) the quantities are transforms of it: only the first is
    /// listed.
    fn base_correlations(&self) -> Vec<Correlation> {
        let mut out = Vec::new();
        let shown = if self.raw < 2 { 1 } else { self.q.len() };
        for (i, q) in self.q.iter().enumerate().take(shown) {
            for (name, var, cross) in &self.base {
                let Some(r) = rho(cross[i], self.cov[(i, i)], *var) else {
                    continue;
                };
                if r.abs() >= BASE_CORRELATION_MIN {
                    out.push(Correlation {
                        a: q.0.into(),
                        b: (*name).into(),
                        rho: r,
                    });
                }
            }
        }
        out
    }
}

/// Quantities `rep` of effect `c`'s global parameters in the fit `f` of `model`: each name and
/// value, the gradient of each with respect to the fit's free parameters (one row per
/// quantity, in the order of `f.cov`; numerical, zero for parameters held fixed), and how many
/// fitted parameters they derive from.
fn gradients<'n>(
    model: &Model,
    c: Cand,
    f: &FitResult,
    rep: impl Fn(&[f64]) -> Vec<(&'n str, f64)>,
) -> (Vec<(&'n str, f64)>, DMatrix<f64>, usize) {
    let idx: Vec<usize> = model.global_indices(c).collect();
    let v: Vec<f64> = idx.iter().map(|&i| f.x[i]).collect();
    let values = rep(&v);
    let mut g = DMatrix::zeros(values.len(), f.free.len());
    for (j, &i) in idx.iter().enumerate() {
        // Where the parameter sits in the covariance of the free parameters.
        let Some(pj) = f.free.iter().position(|&fi| fi == i) else {
            continue;
        };
        let h = 1e-7 * (1.0 + v[j].abs());
        let mut vp = v.clone();
        vp[j] += h;
        let moved = rep(&vp);
        for (k, &(_, val)) in values.iter().enumerate() {
            g[(k, pj)] = (moved[k].1 - val) / h;
        }
    }
    (values, g, v.len())
}

/// Quantities `rep` of effect `c`'s global parameters in the fit `f` of `model`, propagated
/// by the delta method ([`Propagated`]).
fn delta_method<'n>(
    model: &Model,
    c: Cand,
    f: &FitResult,
    rep: impl Fn(&[f64]) -> Vec<(&'n str, f64)>,
) -> Propagated<'n> {
    let (values, g, raw) = gradients(model, c, f, rep);
    // Covariance of the quantities with every free parameter (J P), and between them.
    let gp = &g * &f.cov;
    let cov = &gp * g.transpose();
    let q = values
        .iter()
        .enumerate()
        .map(|(k, &(name, val))| (name, val, cov[(k, k)].max(0.0).sqrt()))
        .collect();
    let base = model
        .base
        .names()
        .iter()
        .enumerate()
        .filter_map(|(i, &name)| {
            let pb = f.free.iter().position(|&j| j == i)?;
            Some((
                name,
                f.cov[(pb, pb)],
                gp.column(pb).iter().copied().collect(),
            ))
        })
        .collect();
    Propagated { q, cov, raw, base }
}

/// Correlations between the reported global quantities ([`Cand::report`]) of two different
/// effects of `model`, in the order of `effects`, from the one fit `f` (delta method, as
/// [`delta_method`]), at least [`BASE_CORRELATION_MIN`] in magnitude. Names are qualified by
/// effect (`proximity.S`); `a` is the earlier effect's. An effect whose quantities derive from
/// one fitted parameter (`beacon_pattern`'s H_deg and m) contributes its first only;
/// per-separation parameters are not included.
fn cross_correlations(model: &Model, f: &FitResult, effects: &[Cand]) -> Vec<Correlation> {
    /// One effect's quantities: qualified names, gradient rows (J) and J P.
    struct Quantities {
        names: Vec<String>,
        g: DMatrix<f64>,
        gp: DMatrix<f64>,
    }
    impl Quantities {
        fn var(&self, k: usize) -> f64 {
            self.gp.row(k).dot(&self.g.row(k))
        }
    }
    let per: Vec<Quantities> = effects
        .iter()
        .map(|&c| {
            let (values, g, raw) = gradients(model, c, f, |v| c.report(model.base, v));
            let shown = if raw < 2 {
                values.len().min(1)
            } else {
                values.len()
            };
            let g = g.rows(0, shown).into_owned();
            Quantities {
                names: values
                    .iter()
                    .take(shown)
                    .map(|(n, _)| format!("{}.{n}", c.name()))
                    .collect(),
                gp: &g * &f.cov,
                g,
            }
        })
        .collect();
    let mut out = Vec::new();
    for (i, a) in per.iter().enumerate() {
        for b in &per[i + 1..] {
            for (k, na) in a.names.iter().enumerate() {
                for (l, nb) in b.names.iter().enumerate() {
                    let cov = a.gp.row(k).dot(&b.g.row(l));
                    let Some(r) = rho(cov, a.var(k), b.var(l)) else {
                        continue;
                    };
                    if r.abs() >= BASE_CORRELATION_MIN {
                        out.push(Correlation {
                            a: na.clone(),
                            b: nb.clone(),
                            rho: r,
                        });
                    }
                }
            }
        }
    }
    out
}

/// The reported parameters of a cause: values, 1-sigma, correlations between them and with
/// the starting model.
type CauseParams = (ParamMap, ParamMap, Vec<Correlation>, Vec<Correlation>);

/// The reported parameters of `c` in the fit `f` of `model`, with 1-sigma and correlations by
/// the delta method (numerical gradient of the reported quantities through the fitted
/// covariance). In the model's order: the reported global quantities as [`Cand::report`]
/// lists them, then (per-separation effects) `rms_in` and every `x@2in`, separation by
/// separation.
fn cause_params(model: &Model, c: Cand, f: &FitResult, seps: &[f64]) -> CauseParams {
    let mut p = ParamMap::default();
    let mut s = ParamMap::default();
    let prop = delta_method(model, c, f, |v| c.report(model.base, v));
    for &(name, val, sg) in &prop.q {
        p.insert(name, val);
        s.insert(name, sg);
    }
    if !c.local_names().is_empty() {
        // name, value, 1-sigma of every per-separation parameter, separation by separation.
        let locals: Vec<(String, f64, f64)> = seps
            .iter()
            .enumerate()
            .flat_map(|(k, sep)| {
                model
                    .local_indices(c, k)
                    .zip(c.local_names())
                    .map(move |(i, n)| (format!("{n}@{sep}in"), f.x[i], f.sigma[i]))
            })
            .collect();
        let sumsq: f64 = locals.iter().map(|l| l.1 * l.1).sum();
        p.insert(
            c.local_rms_name(),
            (sumsq / locals.len().max(1) as f64).sqrt(),
        );
        for (name, val, sg) in locals {
            p.insert(name.clone(), val);
            s.insert(name, sg);
        }
    }
    (p, s, prop.correlations(), prop.base_correlations())
}

/// The parameters of candidate `c` in its trial fit `f` of `model` (the round's model plus
/// `c`), as [`Cand::trial_report`] gives them (smooth through the no-effect value, which each
/// carries), 1-sigma by the delta method; then every per-separation value (`x@2in`, no-effect
/// value 0). With the correlations between the global ones, and of those with the starting
/// model.
fn trial_params(
    model: &Model,
    c: Cand,
    f: &FitResult,
    seps: &[f64],
) -> (Vec<Param>, Vec<Correlation>, Vec<Correlation>) {
    let idx: Vec<usize> = model.global_indices(c).collect();
    let v: Vec<f64> = idx.iter().map(|&i| f.x[i]).collect();
    let nulls: Vec<Option<f64>> = c.trial_report(model.base, &v).iter().map(|r| r.2).collect();
    let rep = |v: &[f64]| {
        c.trial_report(model.base, v)
            .into_iter()
            .map(|(n, x, _)| (n, x))
            .collect::<Vec<_>>()
    };
    let prop = delta_method(model, c, f, rep);
    let mut out: Vec<Param> = prop
        .q
        .iter()
        .zip(nulls)
        .map(|(&(name, value, sigma), no_effect)| Param {
            name: name.into(),
            value,
            sigma,
            no_effect,
        })
        .collect();
    for (k, sep) in seps.iter().enumerate() {
        for (j, i) in model.local_indices(c, k).enumerate() {
            out.push(Param {
                name: format!("{}@{}in", c.local_names()[j], sep),
                value: f.x[i],
                sigma: f.sigma[i],
                no_effect: Some(0.0),
            });
        }
    }
    (out, prop.correlations(), prop.base_correlations())
}

/// The spread of per-separation values `NAME@SEPin` in `params`, per name, in order of first
/// appearance: the inverse-variance weighted RMS of the estimates and the value noise alone
/// would give it (values without a positive 1-sigma are skipped).
pub fn spreads(params: &[Param]) -> Vec<SepSpread> {
    // name, sum of x^2 / sigma^2, sum of 1 / sigma^2, count.
    let mut out: Vec<(String, f64, f64, usize)> = Vec::new();
    for p in params {
        let Some((name, _)) = p.name.split_once('@') else {
            continue;
        };
        if !(p.sigma > 0.0 && p.sigma.is_finite()) {
            continue;
        }
        let e = match out.iter().position(|o| o.0 == name) {
            Some(k) => &mut out[k],
            None => {
                out.push((name.to_string(), 0.0, 0.0, 0));
                out.last_mut().expect("just pushed")
            }
        };
        let w = 1.0 / (p.sigma * p.sigma);
        e.1 += w * p.value * p.value;
        e.2 += w;
        e.3 += 1;
    }
    out.into_iter()
        .map(|(name, swx2, sw, n)| SepSpread {
            name,
            rms: (swx2 / sw).sqrt(),
            noise_rms: (n as f64 / sw).sqrt(),
            separations: n,
        })
        .collect()
}

/// The candidates of the last round (tried on top of the final model) that were not
/// accepted, or why there are none.
fn ruled_out(
    trials: &[TrialOut],
    sel: &select::Selection,
    max_effects: usize,
) -> (Vec<RuledOut>, Option<String>) {
    let last = trials.iter().map(|t| t.round).max();
    let Some(last) = last else {
        return (Vec::new(), Some("no candidate was tried".into()));
    };
    if trials.iter().any(|t| t.round == last && t.accepted) {
        let why = if sel.steps.len() >= max_effects {
            format!("the search stopped at --max-effects {max_effects}")
        } else {
            "every candidate was accepted: none is left to rule out".to_string()
        };
        return (Vec::new(), Some(why));
    }
    let list = trials
        .iter()
        .filter(|t| t.round == last)
        .map(|t| {
            let note = if let Some(f) = &t.failure {
                Some(f.clone())
            } else if !t.fitted && t.effect == Cand::Saturation.name() {
                Some(
                    "not fitted: no scanned clipping level (each clips >= 0.5 % of the points) \
                     fits better than none"
                        .into(),
                )
            } else if let Some(d) = sel.dropped.iter().find(|d| d.cand.name() == t.effect) {
                Some(format!("named in round {}, then dropped (above)", d.round))
            } else if t.dbic > select::BIC_MIN {
                Some(format!(
                    "dBIC above {} but the held-out chi-square did not drop{}",
                    select::BIC_MIN,
                    t.heldout_rms
                        .map(|r| format!(" (held-out RMS {r:.2} counts)"))
                        .unwrap_or_default()
                ))
            } else {
                None
            };
            RuledOut {
                effect: t.effect.clone(),
                k: t.k,
                dchi2: t.dchi2,
                dbic: t.dbic,
                fitted: t.fitted,
                params: t
                    .params
                    .iter()
                    .filter(|p| !p.name.contains('@'))
                    .cloned()
                    .collect(),
                per_separation: spreads(&t.params),
                correlations: t.correlations.clone(),
                base_correlations: t.base_correlations.clone(),
                note,
            }
        })
        .collect();
    (list, None)
}

/// Analyze a dataset. `progress` is called after each fit with a short message.
pub fn analyze(
    ds: &Dataset,
    opts: &Options,
    progress: select::Progress,
) -> Result<Analysis, String> {
    let (ds, mut data_notes) = data_notes(ds, opts)?;
    let ds = ds.as_ref();
    let mut data = Data::from_dataset(ds, opts.weights, opts.noise)?;
    let mut corners = opts
        .corners
        .as_ref()
        .map(|rc| place_by_corners(rc, &mut data));
    let nsep = data.seps.len();
    let file = ds.path.display().to_string();
    if nsep < 2 {
        return Err(format!(
            "{file}: cross-validation across separations needs at least 2 separations (fit on \
             some, predict the others); the file has {} ({} in). No candidate could be tested: \
             {}",
            nsep,
            data.seps_text(),
            opts.candidates
                .iter()
                .map(|c| c.name())
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    let per_sep = data.points_per_sep();
    let fold_seps: Vec<Vec<usize>> = match &opts.holdout {
        Some(h) => {
            let mut idx = Vec::new();
            for s in h {
                let near = crate::data::nearest_within(&data.seps, *s);
                match near.and_then(|v| data.seps.iter().position(|w| *w == v)) {
                    Some(k) => idx.push(k),
                    None => {
                        return Err(format!(
                            "{file}: --holdout separation {s} in is not in the file, nor any \
                             within {} in (it has {})",
                            crate::data::SEP_MATCH_IN,
                            data.seps_text()
                        ))
                    }
                }
            }
            if idx.len() >= nsep {
                return Err("--holdout: hold out some separations, not all".into());
            }
            vec![idx]
        }
        None => select::folds(nsep, opts.folds),
    };
    // What noise alone gives as held-out RMS: every held-out row's variance (the point
    // means' noise), over the separations the folds hold out.
    let mut noise_ss = vec![(0.0, 0usize); nsep];
    for p in &data.points {
        noise_ss[p.sep].0 += 1.0 / p.w[0] + 1.0 / p.w[1];
        noise_ss[p.sep].1 += 2;
    }
    let noise_rms_by_sep: Vec<f64> = noise_ss
        .iter()
        .map(|(ss, n)| (ss / (*n).max(1) as f64).sqrt())
        .collect();
    let heldout_noise_rms = {
        let held: std::collections::BTreeSet<usize> = fold_seps.iter().flatten().copied().collect();
        let (ss, n) = held.iter().fold((0.0, 0), |(a, b), &k| {
            (a + noise_ss[k].0, b + noise_ss[k].1)
        });
        (ss / n.max(1) as f64).sqrt()
    };
    let systematic = |rms: f64| {
        (rms * rms - heldout_noise_rms * heldout_noise_rms)
            .max(0.0)
            .sqrt()
    };
    let min_pts = per_sep.iter().copied().min().unwrap_or(0);
    // Per-separation corrections need enough points at every separation: with fewer they are
    // neither fitted nor named (listed as untested below).
    let few_points = min_pts < MIN_POINTS_PER_SEPARATION;
    let sel_opts = select::Options {
        base: opts.from,
        folds: opts.folds,
        candidates: opts
            .candidates
            .iter()
            .filter(|c| !few_points || c.local_names().is_empty())
            .cloned()
            .collect(),
        max_effects: opts.max_effects,
    };
    let sel = select::select_with_folds(&data, &sel_opts, &fold_seps, progress)
        .map_err(|e| wiring::explain(ds, format!("{file}: {e}")))?;
    let mut untested: Vec<Untested> = sel
        .untested
        .iter()
        .map(|(c, r)| Untested {
            effect: c.name().into(),
            reason: r.clone(),
        })
        .collect();
    if few_points {
        for c in &opts.candidates {
            if !c.local_names().is_empty() && !untested.iter().any(|u| u.effect == c.name()) {
                untested.push(Untested {
                    effect: c.name().into(),
                    reason: format!(
                        "a separation has only {min_pts} usable points: too few to estimate a \
                         per-separation correction with any confidence"
                    ),
                });
            }
        }
    }
    let n_constraints = |m: &Model| m.n_constraints();
    let dof_chi2 = |m: &Model, f: &FitResult| f.chi2 / f.dof(n_constraints(m));
    let base_chi2 = dof_chi2(&sel.base_model, &sel.base_fit);
    if let Some(c) = &mut corners {
        if !data.measured_tilts_deg.is_empty() {
            // The gain of placing the plates: the starting model with them level.
            let level = Data {
                measured_tilts_deg: Vec::new(),
                ..data.clone()
            };
            progress("starting model with level plates");
            if let Ok(v) = select::base_chi2_dof(&level, opts.from) {
                c.chi2_dof_level = Some(v);
                c.note.push_str(&format!(
                    "; the starting model's chi2/dof {v:.2} with the plates level, {base_chi2:.2} \
                     placed by the corners"
                ));
            }
        }
        data_notes.push(c.note.clone());
    }
    let (fm, ff, fcv) = sel.last();
    let final_chi2 = dof_chi2(fm, ff);
    let unexplained = final_chi2 > UNEXPLAINED_CHI2_DOF;
    let mut causes = Vec::new();
    for st in &sel.steps {
        // The parameters as the final model (every named cause together) has them: the step
        // that added a cause fitted it without the causes named after it, which it may have
        // stood in for (from `pinhole`, `proximity` alone reads S = 0.85 in on thesis data,
        // near the truth, 0.175, once `intensity` and `beacon_pattern` are in).
        let (params, sigma, correlations, base_correlations) =
            cause_params(fm, st.cand, ff, &data.seps);
        let round = sel
            .trials
            .iter()
            .find(|t| t.accepted && t.cand == st.cand)
            .map(|t| t.round);
        let rivals = round.map_or_else(Vec::new, |r| rivals(&sel.trials, r, st.cand, st.dbic));
        let caution = match st.cand {
            Cand::Proximity => params.get("S").and_then(|&s| wiring::s_unit_note(s, "S")),
            _ => None,
        };
        causes.push(Cause {
            effect: st.cand.name().into(),
            params,
            sigma,
            gain_rms_counts: st.cv_before.rms - st.cv_after.rms,
            heldout_noise_rms,
            systematic_rms_before: systematic(st.cv_before.rms),
            systematic_rms_after: systematic(st.cv_after.rms),
            dchi2: st.dchi2,
            dbic: st.dbic,
            heldout_rms_before: st.cv_before.rms,
            heldout_rms_after: st.cv_after.rms,
            chi2_dof_after: dof_chi2(&st.model, &st.fit),
            correlations,
            base_correlations,
            rivals,
            board: board_note(st.cand.name()),
            caution,
        });
    }
    let effects: Vec<Cand> = sel.steps.iter().map(|st| st.cand).collect();
    let cross_correlations = cross_correlations(fm, ff, &effects);
    let (causes, tentative) = if unexplained {
        (Vec::new(), causes)
    } else {
        (causes, Vec::new())
    };
    let before_res = diag::residuals(&sel.base_model, &sel.base_fit.x, &data);
    let after_res = diag::residuals(fm, &ff.x, &data);
    let ab = diag::angle_errors(&sel.base_model, &sel.base_fit.x, &data);
    let aa = diag::angle_errors(fm, &ff.x, &data);
    // Compare the two models' angle errors over the same points: near the output rail one
    // model may not reach the measured output at all (no direction) while the other turns
    // a few counts into degrees where the output hardly changes with angle.
    let both = |e: &[f64]| -> Vec<f64> {
        e.iter()
            .zip(ab.iter().zip(&aa))
            .map(|(&v, (b, a))| {
                if b.is_finite() && a.is_finite() {
                    v
                } else {
                    f64::NAN
                }
            })
            .collect()
    };
    let angle_left_out = ab
        .iter()
        .zip(&aa)
        .filter(|(b, a)| !(b.is_finite() && a.is_finite()))
        .count();
    let diagnostics_before = diag::diagnose(&sel.base_model, &sel.base_fit.x, &data);
    let diagnostics_after = diag::diagnose(fm, &ff.x, &data);
    let structure = if final_chi2 > UNEXPLAINED_CHI2_DOF {
        diagnostics_after.notes()
    } else {
        Vec::new()
    };
    if let Some(n) = noise_too_large(&data, opts, base_chi2, sel.base_cv.rms) {
        data_notes.push(n);
    }
    let verdict = if unexplained {
        let part = if tentative.is_empty() {
            String::new()
        } else {
            format!(
                "; partial improvement from {} (not named: the structure is not explained)",
                tentative
                    .iter()
                    .map(|c| c.effect.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        };
        // One sample per point and no --noise: the chi-square rests on an assumed noise. When
        // no extension gains even 1 % of the held-out RMS, the excess is most likely the
        // sensor's own noise, larger than assumed, not structure: say what to rerun with.
        let assumed = !data.noise_measured && opts.noise.is_none();
        let gain = sel.base_cv.rms - fcv.rms;
        let hint = if assumed && gain < 0.01 * sel.base_cv.rms {
            format!(
                ". But the noise was assumed ({:.1} counts; one sample per \
                 point) and no extension gains 1 % of the held-out RMS ({:.1} -> {:.1} counts): \
                 the residuals look like noise of about {:.0} counts rather than structure. If \
                 that is the sensor's noise, rerun with --noise {:.0} (better: sweep with \
                 repeated samples, which measure it)",
                data::DEFAULT_NOISE_COUNTS,
                sel.base_cv.rms,
                fcv.rms,
                sel.base_cv.rms,
                sel.base_cv.rms
            )
        } else {
            String::new()
        };
        format!(
            "unexplained structure remains: chi2/dof {:.2} after the best extension (starting model {:.2}){part}{hint}",
            final_chi2, base_chi2
        )
    } else if causes.is_empty() {
        match corners.as_ref().and_then(|c| c.chi2_dof_level) {
            Some(level) if level > UNEXPLAINED_CHI2_DOF => format!(
                "no significant effect beyond the plate tilts the corner readings measured: the \
                 `{}` model, its plates placed by them, explains the data (chi2/dof {:.2}; {:.2} \
                 with the plates level)",
                opts.from.name(),
                base_chi2,
                level
            ),
            _ => format!(
                "no significant effect: the `{}` model explains the data (chi2/dof {:.2})",
                opts.from.name(),
                base_chi2
            ),
        }
    } else {
        format!(
            "named: {} (chi2/dof {:.2} -> {:.2}, held-out RMS {:.1} -> {:.1} counts)",
            causes
                .iter()
                .map(|c| c.effect.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            base_chi2,
            final_chi2,
            sel.base_cv.rms,
            fcv.rms
        )
    };
    let trials: Vec<TrialOut> = sel
        .trials
        .iter()
        .map(|t| {
            let (params, correlations, base_correlations) = t
                .fit
                .as_deref()
                .map(|(m, f)| trial_params(m, t.cand, f, &data.seps))
                .unwrap_or_default();
            TrialOut {
                round: t.round,
                effect: t.cand.name().into(),
                k: t.k,
                dchi2: t.dchi2,
                dbic: t.dbic,
                heldout_rms: t.cv_rms,
                accepted: t.accepted,
                failure: t.failure.clone(),
                fitted: t.fit.is_some(),
                params,
                correlations,
                base_correlations,
            }
        })
        .collect();
    let (ruled_out, ruled_out_note) = ruled_out(&trials, &sel, opts.max_effects);
    // A head turned far from square fits as well as a square one (a pose like any other):
    // say so, with the reading of X and Y that squares it.
    let params_after = params_of(fm, ff, &data.seps, true);
    let value = |n: &str| params_after.iter().find(|q| q.name == n).map(|q| q.value);
    data_notes.extend(wiring::turned_head_note(
        ["p1", "p2", "p3"].map(|n| value(n).unwrap_or(0.0)),
        value("H"),
    ));
    Ok(Analysis {
        file,
        model_from: opts.from.name().into(),
        causes,
        tentative,
        cross_correlations,
        dropped: sel
            .dropped
            .iter()
            .map(|d| DroppedOut {
                effect: d.cand.name().into(),
                round: d.round,
                dbic_named: d.dbic_named,
                others: d.others.iter().map(|c| c.name().to_string()).collect(),
                k: d.k,
                dchi2_keep: d.dchi2_keep,
                dbic_keep: d.dbic_keep,
                heldout_rms_with: d.cv_rms_with,
                heldout_rms_without: d.cv_rms_without,
            })
            .collect(),
        untested,
        unexplained,
        verdict,
        chi2_dof_before: base_chi2,
        chi2_dof_after: final_chi2,
        rms_before: sel.base_cv.rms,
        rms_after: fcv.rms,
        separations: data.seps.clone(),
        angle_std_before_deg: diag::angle_std_by_sep(&both(&ab), &data),
        angle_std_after_deg: diag::angle_std_by_sep(&both(&aa), &data),
        angle_left_out,
        heldout_noise_rms,
        noise_rms_by_sep,
        heldout_rms_by_sep_before: sel.base_cv.rms_by_sep.clone(),
        heldout_rms_by_sep_after: fcv.rms_by_sep.clone(),
        params_before: params_of(&sel.base_model, &sel.base_fit, &data.seps, true),
        params_after,
        noise: data.noise_note.clone(),
        data_notes,
        corners,
        noise_by_sep: data.noise_by_sep.clone(),
        samples: data.samples,
        points: data.points.len(),
        excluded_points: data.excluded,
        folds: fold_seps
            .iter()
            .map(|f| f.iter().map(|&k| data.seps[k]).collect())
            .collect(),
        structure,
        diagnostics_before,
        diagnostics_after,
        trials,
        ruled_out,
        ruled_out_note,
        detail: Some(Box::new(Detail {
            data,
            before: before_res,
            after: after_res,
            angle_before: ab,
            angle_after: aa,
        })),
    })
}

/// The corner readings' tilts applied to an analysis ([`Analysis::corners`]).
#[derive(Debug, Clone, Serialize)]
pub struct CornersOut {
    /// The journal they were read from.
    pub journal: String,
    /// Per analyzed separation (in the order of [`Analysis::separations`]): the tilt (tx,
    /// ty) applied, deg; `None` where no readings with a known order were journalled (the
    /// plate taken as level).
    pub tilt_deg: Vec<Option<[f64; 2]>>,
    /// Per separation, the corners' twist, in ([`crate::sweep::corners::CornerTilt`]).
    pub twist_in: Vec<Option<f64>>,
    /// The starting model's chi2/dof with every plate taken as level (the gain of placing
    /// them: against [`Analysis::chi2_dof_before`]); `None` when no tilt was applied.
    pub chi2_dof_level: Option<f64>,
    /// What was applied, in words (also among the data notes).
    pub note: String,
}

/// A twist (in) above this says a corner was misread or the plate is not flat: the note
/// warns, naming the separation.
pub const CORNER_TWIST_WARN_IN: f64 = 0.002;

/// Place each separation's plate of `data` with the tilt its corner readings in `rc`
/// measured ([`Data::measured_tilts_deg`]), and say what was applied.
fn place_by_corners(rc: &RunCorners, data: &mut Data) -> CornersOut {
    let journal = rc.journal.display().to_string();
    let found: Vec<Option<crate::sweep::corners::CornerTilt>> = data
        .seps
        .iter()
        .map(|s| rc.at(*s).and_then(|p| p.tilt))
        .collect();
    let n = found.iter().flatten().count();
    let unordered = data
        .seps
        .iter()
        .filter(|s| rc.at(**s).is_some_and(|p| p.tilt.is_none()))
        .count();
    let tilt_deg: Vec<Option<[f64; 2]>> = found.iter().map(|t| t.map(|t| t.tilt_deg)).collect();
    let twist_in: Vec<Option<f64>> = found.iter().map(|t| t.map(|t| t.twist_in)).collect();
    let note = if n == 0 {
        format!(
            "{journal} records no corner readings {} for the file's separations: the plates are \
             taken as level",
            if unordered > 0 {
                "with a known order (journalled by an older version)"
            } else {
                "(a --yes run, or the file is not this run's)"
            }
        )
    } else {
        data.measured_tilts_deg = tilt_deg.iter().map(|t| t.unwrap_or_default()).collect();
        let mags: Vec<(f64, f64)> = data
            .seps
            .iter()
            .zip(&tilt_deg)
            .filter_map(|(s, t)| t.map(|t| (*s, t[0].hypot(t[1]))))
            .collect();
        let (at, most) = mags
            .iter()
            .copied()
            .fold((f64::NAN, 0.0), |m, v| if v.1 > m.1 { v } else { m });
        let rms = (mags.iter().map(|m| m.1 * m.1).sum::<f64>() / mags.len() as f64).sqrt();
        let missing: Vec<String> = data
            .seps
            .iter()
            .zip(&tilt_deg)
            .filter(|(_, t)| t.is_none())
            .map(|(s, _)| format!("{s}"))
            .collect();
        let (twist_at, twist) = data
            .seps
            .iter()
            .zip(&twist_in)
            .filter_map(|(s, t)| t.map(|t| (*s, t.abs())))
            .fold((f64::NAN, 0.0), |m, v| if v.1 > m.1 { v } else { m });
        let mut note = format!(
            "plates placed as their corner readings in {journal} tilt them, at {n} of {} \
             separations: |tilt| up to {most:.3} deg (at {at} in), RMS {rms:.3} deg; any \
             plate_tilt named below is the tilt beyond the corners' (--ignore-corners takes \
             the plates as level)",
            data.seps.len()
        );
        if !missing.is_empty() {
            note.push_str(&format!(
                "; level at {} in (no corner readings{})",
                missing.join(", "),
                if unordered > 0 {
                    " with a known order"
                } else {
                    ""
                }
            ));
        }
        if twist > CORNER_TWIST_WARN_IN {
            note.push_str(&format!(
                "; the corners at {twist_at} in twist by {:.1} mils (a flat plate read to 1 mil: \
                 under 1): a corner misread or a plate not flat, and its tilt uncertain by about \
                 that over the rods",
                twist * 1000.0
            ));
        }
        note
    };
    CornersOut {
        journal,
        tilt_deg,
        twist_in,
        chi2_dof_level: None,
        note,
    }
}

/// The dataset the analysis uses (without the flagged glitches with `--drop-glitches`) and
/// the notes on it: glitches and how much they inflate the noise the fits weight by, and
/// settings whose noise differs while the weights pool them.
fn data_notes<'d>(
    ds: &'d Dataset,
    opts: &Options,
) -> Result<(std::borrow::Cow<'d, Dataset>, Vec<String>), String> {
    let mut notes = Vec::new();
    let mut used = std::borrow::Cow::Borrowed(ds);
    if let Some(clean) = ds.without_glitches() {
        let one = clean.samples == 1;
        let where_ = clean.where_();
        if opts.drop_glitches {
            notes.push(clean.note());
            used = std::borrow::Cow::Owned(clean.data);
        } else if opts.noise.is_none() {
            // The noise per separation and axis the fits weight by, with and without them.
            let with = Data::from_dataset(ds, opts.weights, None)?;
            let without = Data::from_dataset(&clean.data, opts.weights, None)?;
            if with.noise_measured {
                let (mut worst, mut at, mut axis) = (1.0, f64::NAN, 0);
                for (k, sep) in with.seps.iter().enumerate() {
                    let Some(j) = without.seps.iter().position(|v| v == sep) else {
                        continue;
                    };
                    for a in 0..2 {
                        let r = with.noise_by_sep[k][a] / without.noise_by_sep[j][a];
                        if r > worst {
                            (worst, at, axis) = (r, *sep, a);
                        }
                    }
                }
                let them = if one { "it" } else { "them" };
                if opts.weights == Weights::Point {
                    notes.push(format!(
                        "the glitch{} ({where_}) inflate{} the variance of {} point{}, which \
                         weight{} by it: --drop-glitches leaves {them} out (the file is not changed)",
                        if one { "" } else { "es" },
                        if one { "s" } else { "" },
                        if one { "its" } else { "their" },
                        if one { "" } else { "s" },
                        if one { "s" } else { "" },
                    ));
                } else if worst > 1.2 {
                    notes.push(format!(
                        "the glitch{} ({where_}) inflate{} the noise the fits weight by, most at \
                         {at} in on {}: {worst:.1}-fold. There the weights and the noise-alone \
                         figures are off. --drop-glitches leaves {them} out (the file is not \
                         changed)",
                        if one { "" } else { "es" },
                        if one { "s" } else { "" },
                        ["X", "Y"][axis],
                    ));
                }
            }
        }
    }
    // Settings (frequency, power, sensitivity) whose noise differs within a separation, while
    // the default weights pool them: `cta noise`'s test, run only when a separation has more
    // than one setting.
    if opts.weights == Weights::Separation && opts.noise.is_none() {
        let mut pairs: Vec<(u64, [u64; 3])> = (used.samples.iter())
            .map(|s| {
                let setting = [s.frequency_hz, s.power, s.sensitivity]
                    .map(|v| v.unwrap_or(f64::NAN).to_bits());
                (s.separation_in.to_bits(), setting)
            })
            .collect();
        pairs.sort_unstable();
        pairs.dedup();
        if pairs.len() > used.separations().len() {
            if let Ok(r) = crate::noise::analyze_noise(&used) {
                let differ = crate::noise::settings_that_differ(&r);
                if !differ.is_empty() {
                    notes.push(format!(
                        "the noise differs between settings within a separation: {}; these \
                         weights pool them per separation: `--weights setting` weights each \
                         setting by its own noise (`cta noise {}` shows it)",
                        differ
                            .iter()
                            .map(|f| format!("{} (max/min std {:.2})", f.factor, f.spread_ratio))
                            .collect::<Vec<_>>()
                            .join(", "),
                        ds.path.display()
                    ));
                }
            }
        }
    }
    Ok((used, notes))
}

/// A chi-square far below its expectation: the noise the fits weight by is far larger than
/// the scatter of the point means, so no effect could be significant against it.
fn noise_too_large(data: &Data, opts: &Options, chi2_dof: f64, rms: f64) -> Option<String> {
    if !(chi2_dof < NOISE_TOO_LARGE_CHI2_DOF) {
        return None;
    }
    Some(if data.noise_measured {
        format!(
            "chi2/dof {chi2_dof:.2}: the point means scatter far less than their repeated \
             samples say (held-out RMS {rms:.1} counts): the noise the fits weight by looks \
             overestimated (glitches? samples that are not independent?), and an effect can \
             hide under it"
        )
    } else {
        let (what, n) = match opts.noise {
            Some(n) => ("set by --noise", n),
            None => (
                "assumed for one sample per point",
                data::DEFAULT_NOISE_COUNTS,
            ),
        };
        format!(
            "chi2/dof {chi2_dof:.2}: the residuals (held-out RMS {rms:.1} counts) are far \
             smaller than the noise {what} ({n:.1} counts): no effect can be significant \
             against it. If the sensor is that quiet, rerun with --noise {:.1} (better: \
             repeated samples, which measure it)",
            rms.max(0.1)
        )
    })
}

/// Text summary.
pub fn render_text(a: &Analysis) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "cta analyze {} (from `{}`)", a.file, a.model_from);
    let _ = writeln!(
        s,
        "  {} samples -> {} points ({} left out: output at or near the 16-bit rail), separations {}",
        a.samples,
        a.points,
        a.excluded_points,
        crate::data::fmt_list(&a.separations)
    );
    let _ = writeln!(s, "  {}", a.noise);
    for n in &a.data_notes {
        let _ = writeln!(s, "  note: {n}");
    }
    let _ = writeln!(s, "\n{}\n", a.verdict);
    for (k, c) in a.causes.iter().chain(&a.tentative).enumerate() {
        let tag = if k < a.causes.len() {
            ""
        } else {
            " (tentative, not named)"
        };
        let _ = writeln!(
            s,
            "{}. {}{tag}: held-out RMS {:.1} -> {:.1} counts ({:.1} from noise alone: systematic {:.1} -> {:.1}), dchi2 {:.0}, dBIC {:.0}, chi2/dof after {:.2}",
            k + 1,
            c.effect,
            c.heldout_rms_before,
            c.heldout_rms_after,
            c.heldout_noise_rms,
            c.systematic_rms_before,
            c.systematic_rms_after,
            c.dchi2,
            c.dbic,
            c.chi2_dof_after
        );
        let shown = c.global_params("+/-");
        if !shown.is_empty() {
            let _ = writeln!(s, "     {}", shown.join(", "));
        }
        for line in correlation_lines(&c.correlations, &c.base_correlations) {
            let _ = writeln!(s, "     {line}");
        }
        if let Some(line) = c.rivals_line() {
            let _ = writeln!(s, "     {line}");
        }
        if let Some(c) = &c.caution {
            let _ = writeln!(s, "     caution: {c}");
        }
        let _ = writeln!(s, "     on the sensor board: {}", c.board);
    }
    if let Some(line) = cross_correlation_line(&a.cross_correlations) {
        let _ = writeln!(s, "{line}");
    }
    for d in &a.dropped {
        let _ = writeln!(s, "\ndropped: {}", d.line());
    }
    if !a.ruled_out.is_empty() {
        let _ = writeln!(
            s,
            "{}not named (tried on top of the final model, not accepted): estimate +/- \
             1-sigma; the data allow about estimate +/- 2 sigma{}",
            if a.causes.is_empty() && a.tentative.is_empty() {
                ""
            } else {
                "\n"
            },
            if a.unexplained {
                " (too small here: structure remains)"
            } else {
                ""
            }
        );
        for r in &a.ruled_out {
            let est = r.estimates("+/-");
            let note = r.note.as_deref().unwrap_or_default();
            let _ = if est.is_empty() {
                writeln!(s, "  {}: {note}", r.effect)
            } else if note.is_empty() {
                writeln!(s, "  {}: {est} (dBIC {:.0})", r.effect, r.dbic)
            } else {
                writeln!(s, "  {}: {est} (dBIC {:.0}): {note}", r.effect, r.dbic)
            };
            for line in correlation_lines(&r.correlations, &r.base_correlations) {
                let _ = writeln!(s, "    {line}");
            }
        }
    } else if let Some(n) = &a.ruled_out_note {
        let _ = writeln!(s, "\nnot named: none tried on top of the final model ({n})");
    }
    if !a.structure.is_empty() {
        let _ = writeln!(s, "\nwhere the residuals stand out (chi2 per residual):");
        for n in &a.structure {
            let _ = writeln!(s, "  - {n}");
        }
    }
    for u in &a.untested {
        let _ = writeln!(s, "could not test `{}`: {}", u.effect, u.reason);
    }
    let _ = writeln!(
        s,
        "\nchi2/dof {:.3} -> {:.3}; held-out RMS {:.2} -> {:.2} counts",
        a.chi2_dof_before, a.chi2_dof_after, a.rms_before, a.rms_after
    );
    let _ = writeln!(
        s,
        "\n sep(in)  angle std before  after (deg)   held-out RMS before  after  noise alone (counts)"
    );
    for (k, sep) in a.separations.iter().enumerate() {
        let _ = writeln!(
            s,
            " {:>6}   {:>16.4}  {:>11.4}   {:>19.1}  {:>5.1}  {:>11.1}",
            sep,
            a.angle_std_before_deg[k],
            a.angle_std_after_deg[k],
            a.heldout_rms_by_sep_before[k],
            a.heldout_rms_by_sep_after[k],
            a.noise_rms_by_sep[k]
        );
    }
    if a.angle_left_out > 0 {
        let _ = writeln!(
            s,
            "  (angle std over the points both models turn into a direction: {} near the \
             output rail left out, where one of them cannot)",
            a.angle_left_out
        );
    }
    let _ = writeln!(s, "\nfinal parameters:");
    for p in &a.params_after {
        let (v, sg) = pm_parts(p.value, p.sigma);
        let unit = match p.name.split_once('.') {
            Some((effect, param)) => unit(effect, param),
            None if ["d1", "d2", "d3"].contains(&p.name.as_str()) => " in",
            None if p.name == "H" => " counts",
            None => "",
        };
        let _ = writeln!(s, "  {:<26} {v:>14} +/- {sg}{unit}", p.name);
    }
    s
}

/// The unit of a candidate's parameter as printed (` in`, ` deg`, ...; empty for ratios and
/// names that carry their unit).
pub fn unit(effect: &str, param: &str) -> &'static str {
    match (effect, param) {
        ("proximity", "S") => " in",
        ("cell_bias", _) | ("saturation", "S") => " /in^2",
        ("face_angle", _) => " deg",
        _ => "",
    }
}

/// A candidate's estimates in one line: global parameters as `name = value PM sigma unit`
/// (with the no-effect value when it is not 0), per-separation ones as the RMS over the
/// separations against the RMS noise alone would give. "a switch, no parameter" for a fitted
/// candidate without parameters (`intensity`), empty when it was not fitted.
fn estimates_text(
    effect: &str,
    globals: &[&Param],
    spreads: &[SepSpread],
    fitted: bool,
    pmark: &str,
) -> String {
    let mut parts: Vec<String> = globals
        .iter()
        .map(|p| {
            let base = format!(
                "{} = {}{}",
                p.name,
                pm(p.value, p.sigma, pmark),
                unit(effect, &p.name)
            );
            match p.no_effect {
                Some(n) if n != 0.0 => format!("{base} (no effect: {})", g(n)),
                _ => base,
            }
        })
        .collect();
    if let Some(sp) = spreads.first() {
        let each: Vec<String> = spreads
            .iter()
            .map(|p| {
                // Names that carry their unit (`tx_deg`) print without one; the rest are in.
                let u = if p.name.ends_with("_deg") { "" } else { " in" };
                format!(
                    "{} weighted RMS {:.1e}{u} (noise alone {:.1e})",
                    p.name, p.rms, p.noise_rms
                )
            })
            .collect();
        parts.push(format!(
            "per separation ({}): {}",
            sp.separations,
            each.join(", ")
        ));
    }
    if parts.is_empty() && fitted {
        parts.push("a switch, no parameter".into());
    }
    parts.join(", ")
}

impl RuledOut {
    /// The estimates in one line (empty when the candidate was not fitted).
    pub fn estimates(&self, pmark: &str) -> String {
        let globals: Vec<&Param> = self.params.iter().collect();
        estimates_text(
            &self.effect,
            &globals,
            &self.per_separation,
            self.fitted,
            pmark,
        )
    }
}

impl TrialOut {
    /// The estimates in one line (empty when the candidate was not fitted).
    pub fn estimates(&self, pmark: &str) -> String {
        let globals: Vec<&Param> = self
            .params
            .iter()
            .filter(|p| !p.name.contains('@'))
            .collect();
        estimates_text(
            &self.effect,
            &globals,
            &spreads(&self.params),
            self.fitted,
            pmark,
        )
    }
}

/// Compact number formatting.
pub fn g(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if (1e-3..1e5).contains(&a) {
        format!("{:.6}", v)
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        format!("{v:.4e}")
    }
}

/// Run `cta analyze`.
pub fn run(args: &AnalyzeArgs) -> anyhow::Result<()> {
    let opts = args.options().map_err(anyhow::Error::msg)?;
    if let Some(dir) = &args.report {
        // Before the work: a folder whose index.html cta did not write costs nothing.
        crate::plot::refuse_to_replace(&dir.join("index.html"))?;
    }
    let bar = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        let b = indicatif::ProgressBar::new_spinner();
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {pos} fits  {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        );
        b.enable_steady_tick(std::time::Duration::from_millis(120));
        b
    };
    bar.set_message(format!("reading {}", args.file.display()));
    let (mut ds, warnings) = crate::sweep::read_measurements(&args.file).map_err(anyhow::Error::msg)?;
    for w in warnings {
        bar.suspend(|| eprintln!("warning: {w}"));
    }
    if let Some(s) = &args.separations {
        let seps = parse_separations(s).map_err(anyhow::Error::msg)?;
        ds = ds.select(&seps).map_err(anyhow::Error::msg)?;
    }
    let mut opts = opts;
    if !args.ignore_corners {
        match RunCorners::beside(&args.file) {
            Some(Ok(rc)) => opts.corners = Some(rc),
            Some(Err(e)) => bar.suspend(|| {
                eprintln!(
                    "warning: {e}: the run's corner readings cannot be used, so the plates are \
                     taken as level (--ignore-corners says so without this warning)"
                )
            }),
            None => {}
        }
    }
    bar.set_message(format!("{} samples read; fitting", ds.samples.len()));
    let progress = |m: &str| {
        bar.inc(1);
        bar.set_message(m.to_string());
    };
    let a = analyze(&ds, &opts, &progress).map_err(anyhow::Error::msg)?;
    bar.finish_and_clear();
    // Printed before the report is written: the analysis is never lost to a failed write.
    if args.json {
        println!("{}", serde_json::to_string_pretty(&a)?);
    } else {
        print!("{}", render_text(&a));
    }
    if let Some(dir) = &args.report {
        report::write(dir, &a).map_err(|e| {
            anyhow::anyhow!("{e}; the analysis above is complete, the report was not written")
        })?;
        eprintln!("report: {}", dir.join("index.html").display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::model::{Base, Cand, FitResult, Model};
    use super::{analyze, delta_method, render_text, Analysis, Options, Weights};
    use crate::sim::effects::Effect;
    use crate::sim::SimConfig;
    use nalgebra::DMatrix;

    /// What the corner readings' note says: which separations were placed and which not
    /// (no readings, or readings of a journal that did not record their order), and a warning
    /// when the corners twist beyond what 1 mil readings of a flat plate give.
    #[test]
    fn corner_readings_are_applied_where_known_and_their_twist_is_checked() {
        use crate::sweep::corners::{corner_tilt, PlateCorners, RunCorners, ROD_XY_IN};
        let (ds, _) = SimConfig {
            separations: vec![5.0, 10.0, 20.0],
            grid: (3, 3),
            ..Default::default()
        }
        .run();
        let plate = |sep: f64, c: [f64; 4], ordered: bool| PlateCorners {
            separation: sep,
            corners: c.to_vec(),
            tilt: ordered.then(|| corner_tilt(&c, ROD_XY_IN).unwrap()),
        };
        let rc = |plates: Vec<PlateCorners>| RunCorners {
            journal: "run/journal.jsonl".into(),
            plates,
        };
        let data = || super::Data::from_dataset(&ds, Weights::Separation, None).unwrap();
        // 5 in placed (higher on +x), 10 in read by an older version, 20 in not read.
        let mut d = data();
        let out = super::place_by_corners(
            &rc(vec![
                plate(5.0, [5.003, 5.003, 4.997, 4.997], true),
                plate(10.0, [10.0; 4], false),
            ]),
            &mut d,
        );
        assert!(
            d.measured_tilts_deg[0][0] > 0.01,
            "{:?}",
            d.measured_tilts_deg
        );
        assert_eq!(&d.measured_tilts_deg[1..], [[0.0; 2]; 2]);
        assert_eq!(out.tilt_deg[1], None);
        assert!(out.note.contains("at 1 of 3 separations"), "{}", out.note);
        assert!(
            out.note
                .contains("level at 10, 20 in (no corner readings with a known order)"),
            "{}",
            out.note
        );
        assert!(!out.note.contains("twist"), "{}", out.note);
        // One corner misread by 5 mils: a twist of 1.25 mils is within...
        let mut d = data();
        let out = super::place_by_corners(
            &rc(vec![plate(20.0, [20.005, 20.0, 20.0, 20.0], true)]),
            &mut d,
        );
        assert!(!out.note.contains("twist"), "{}", out.note);
        // ...one misread by 10 mils is not.
        let out = super::place_by_corners(
            &rc(vec![plate(20.0, [20.010, 20.0, 20.0, 20.0], true)]),
            &mut d,
        );
        assert!(
            out.note.contains("the corners at 20 in twist by 2.5 mils"),
            "{}",
            out.note
        );
        // Only unordered readings: nothing applied, and the note says why.
        let mut d = data();
        let out = super::place_by_corners(&rc(vec![plate(5.0, [5.0; 4], false)]), &mut d);
        assert!(d.measured_tilts_deg.is_empty());
        assert!(
            out.note
                .contains("with a known order (journalled by an older version)"),
            "{}",
            out.note
        );
    }

    /// The hidden-effect setup of tests/tests/hidden_effects.rs: 10 x 10 grid, 13
    /// separations 2-30 in, 4 samples per point, 0.1 % of beta noise.
    fn sim(effect: &str, seed: u64) -> SimConfig {
        SimConfig {
            separations: vec![
                2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 15.0, 18.0, 21.0, 25.0, 30.0,
            ],
            effects: vec![Effect::parse(effect).unwrap()],
            noise: 32.768,
            samples: 4,
            seed,
            ..Default::default()
        }
    }

    /// A rival is a tie: a candidate of the same round within RIVAL_DBIC of the cause, above
    /// or below, and significant on its own. One far above (it fit better but failed the
    /// held-out test, or it would have been named) is no tie, nor one of another round.
    #[test]
    fn rivals_are_candidates_within_the_bic_tie_of_the_cause() {
        let trial = |round: usize, cand: Cand, dbic: f64| super::select::Trial {
            round,
            cand,
            dchi2: dbic,
            k: 1,
            dbic,
            cv_rms: None,
            cv_chi2: None,
            accepted: false,
            failure: None,
            fit: None,
        };
        let trials = [
            trial(1, Cand::CellGain, 1000.0),
            trial(1, Cand::Proximity, 995.0),
            trial(1, Cand::BeaconPattern, 1008.0),
            trial(1, Cand::BeaconTilt, 357_865.0),
            trial(1, Cand::FaceAngle, 985.0),
            trial(2, Cand::Intensity, 1001.0),
        ];
        let r = super::rivals(&trials, 1, Cand::CellGain, 1000.0);
        let names: Vec<&str> = r.iter().map(|r| r.effect.as_str()).collect();
        assert_eq!(names, ["proximity", "beacon_pattern"]);
        // Small causes: a rival must be significant on its own.
        let trials = [
            trial(1, Cand::CellGain, 14.0),
            trial(1, Cand::Proximity, 8.0),
        ];
        assert!(super::rivals(&trials, 1, Cand::CellGain, 14.0).is_empty());
    }

    /// A glitch is named with how much it inflates the noise the fits weight by, where, and
    /// how to leave it out; `--drop-glitches` leaves it out and says so. Clean data: no note.
    #[test]
    fn a_glitch_is_named_with_its_inflation_and_can_be_left_out() {
        let cfg = SimConfig {
            effects: Vec::new(),
            separations: vec![3.0, 6.0, 12.0, 20.0, 30.0],
            ..sim("cell_gain=0", 5)
        };
        let (mut ds, _) = cfg.run();
        let clean = analyze(&ds, &Options::default(), &|_: &str| {}).unwrap();
        assert!(clean.data_notes.is_empty(), "{:?}", clean.data_notes);
        // One sample at 12 in, X off by 7,000 counts (an ID mix-up).
        let row = (ds.samples.iter())
            .position(|s| s.separation_in == 12.0 && s.x.abs() < 20_000.0)
            .unwrap();
        ds.samples[row].x += 7000.0;
        ds.samples[row].line = 4242;
        let a = analyze(&ds, &Options::default(), &|_: &str| {}).unwrap();
        let note = a.data_notes.join(" | ");
        assert!(
            note.contains(
                "the glitch (line 4242) inflates the noise the fits weight by, most at 12 in on X"
            ) && note.contains("--drop-glitches leaves it out"),
            "{note}"
        );
        let fold: f64 = note
            .split(" on X: ")
            .nth(1)
            .unwrap()
            .split('-')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!(fold > 10.0, "{note}");
        assert!(render_text(&a).contains("  note: the glitch (line 4242)"));
        let opts = Options {
            drop_glitches: true,
            ..Options::default()
        };
        let d = analyze(&ds, &opts, &|_: &str| {}).unwrap();
        assert_eq!(
            d.data_notes,
            ["1 glitched sample left out (--drop-glitches; line 4242); the file is unchanged"]
        );
        assert_eq!(d.samples, ds.samples.len() - 1);
        // Without it the 12 in noise is the clean run's again.
        let k = d.separations.iter().position(|&s| s == 12.0).unwrap();
        let r = d.noise_by_sep[k][0] / clean.noise_by_sep[k][0];
        assert!((0.9..1.1).contains(&r), "{r}");
        // Weighted per point: the note names the glitched point's variance.
        let opts = Options {
            weights: Weights::Point,
            ..Options::default()
        };
        let p = analyze(&ds, &opts, &|_: &str| {}).unwrap();
        let note = p.data_notes.join(" | ");
        assert!(
            note.contains("the glitch (line 4242) inflates the variance of its point"),
            "{note}"
        );
        // A glitch that inflates the pooled noise by less than 1.2-fold (a flagged sample
        // at 12 sigma: 1.12-fold at its separation, measured) gets the load-time warning but
        // no note; one at 30 sigma (1.70-fold) gets both.
        for (sigma, noted) in [(12.0, false), (30.0, true)] {
            let mut small = cfg.run().0;
            small.samples[row].x += sigma * 32.768;
            small.samples[row].line = 4242;
            assert_eq!(small.glitches().samples, 1, "{sigma}");
            let a = analyze(&small, &Options::default(), &|_: &str| {}).unwrap();
            assert_eq!(
                !a.data_notes.is_empty(),
                noted,
                "{sigma}: {:?}",
                a.data_notes
            );
        }
    }

    /// Settings whose noise differs within a separation, pooled by the default weights: the
    /// note names the setting and `--weights setting`; with those weights, no note.
    #[test]
    fn settings_whose_noise_differs_are_pointed_out() {
        let cfg = SimConfig {
            effects: Vec::new(),
            separations: vec![4.0, 8.0, 15.0, 30.0],
            ..sim("cell_gain=0", 6)
        };
        let (mut ds, _) = cfg.run();
        // Power 2 on every other point, with 40 counts more noise (alternating signs, so the
        // means stay put).
        let groups = ds.points();
        for (k, g) in groups.iter().enumerate() {
            let loud = k % 2 == 0;
            for (j, &i) in g.rows.iter().enumerate() {
                let s = &mut ds.samples[i];
                s.power = Some(if loud { 2.0 } else { 1.0 });
                if loud && s.x.abs() < 30_000.0 && s.y.abs() < 30_000.0 {
                    let d = if j % 2 == 0 { 40.0 } else { -40.0 };
                    s.x += d;
                    s.y += d;
                }
            }
        }
        let a = analyze(&ds, &Options::default(), &|_: &str| {}).unwrap();
        let note = a.data_notes.join(" | ");
        assert!(
            note.contains("the noise differs between settings within a separation: power level")
                && note.contains("`--weights setting`"),
            "{note}"
        );
        let opts = Options {
            weights: Weights::Setting,
            ..Options::default()
        };
        let b = analyze(&ds, &opts, &|_: &str| {}).unwrap();
        assert!(b.data_notes.is_empty(), "{:?}", b.data_notes);
    }

    /// The settings note for each setting alone: a separation's points differing only in
    /// frequency, only in power or only in sensitivity (every other setting the same) make
    /// more than one setting there, so the noise test runs and names it. Settings that
    /// differ, with the same noise: no note.
    #[test]
    fn each_setting_alone_is_told_apart_by_the_settings_note() {
        type Set = fn(&mut crate::data::Sample, bool);
        let cases: [(Set, &str); 3] = [
            (
                |s, loud| s.frequency_hz = Some(if loud { 4050.0 } else { 2000.0 }),
                "modulation frequency",
            ),
            (
                |s, loud| s.power = Some(if loud { 2.0 } else { 1.0 }),
                "power level",
            ),
            (
                |s, loud| s.sensitivity = Some(if loud { 4.0 } else { 1.0 }),
                "sensitivity setting",
            ),
        ];
        let cfg = SimConfig {
            effects: Vec::new(),
            separations: vec![4.0, 8.0, 15.0, 30.0],
            ..sim("cell_gain=0", 6)
        };
        let base = cfg.run().0;
        for (set, name) in cases {
            for louder in [40.0, 0.0] {
                let mut ds = base.clone();
                // Every other point at the other setting, with `louder` counts more noise
                // (alternating signs, so the means stay put).
                for (k, g) in ds.points().iter().enumerate() {
                    let loud = k % 2 == 0;
                    for (j, &i) in g.rows.iter().enumerate() {
                        let s = &mut ds.samples[i];
                        set(s, loud);
                        if loud && s.x.abs() < 30_000.0 && s.y.abs() < 30_000.0 {
                            let d = if j % 2 == 0 { louder } else { -louder };
                            s.x += d;
                            s.y += d;
                        }
                    }
                }
                let (_, notes) = super::data_notes(&ds, &Options::default()).unwrap();
                let note = notes.join(" | ");
                let want = format!(
                    "the noise differs between settings within a separation: {name} (max/min std"
                );
                assert_eq!(
                    note.contains(&want),
                    louder > 0.0,
                    "{name} {louder}: {note}"
                );
            }
        }
    }

    /// One sample per point, 10 counts of noise, 32.8 assumed: chi2/dof ~0.1, and the note
    /// says the assumed noise is far too large and what to rerun with.
    #[test]
    fn a_noise_far_larger_than_the_residuals_is_pointed_out() {
        let cfg = SimConfig {
            effects: Vec::new(),
            noise: 10.0,
            samples: 1,
            separations: vec![3.0, 6.0, 12.0, 20.0, 30.0],
            ..sim("cell_gain=0", 7)
        };
        let (ds, _) = cfg.run();
        let a = analyze(&ds, &Options::default(), &|_: &str| {}).unwrap();
        assert!(a.chi2_dof_before < 0.2, "{}", a.chi2_dof_before);
        let note = a.data_notes.join(" | ");
        assert!(
            note.contains(
                "far smaller than the noise assumed for one sample per point (32.8 counts)"
            ),
            "{note}"
        );
        let rerun: f64 = (note.split("rerun with --noise ").nth(1))
            .and_then(|t| t.split(' ').next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("{note}"));
        assert!((8.0..12.0).contains(&rerun), "{note}");
        // At the true noise, no note; far above it, the note names --noise.
        let opts = Options {
            noise: Some(10.0),
            ..Options::default()
        };
        let b = analyze(&ds, &opts, &|_: &str| {}).unwrap();
        assert!(b.data_notes.is_empty(), "{:?}", b.data_notes);
        let opts = Options {
            noise: Some(200.0),
            ..Options::default()
        };
        let c = analyze(&ds, &opts, &|_: &str| {}).unwrap();
        let note = c.data_notes.join(" | ");
        assert!(
            note.contains("far smaller than the noise set by --noise (200.0 counts)"),
            "{note}"
        );
        // Measured noise: 4 samples per point, each moved by +/-60 counts in turn, so the
        // samples scatter ~4x more than their means (which stay put) do.
        let cfg = SimConfig { samples: 4, ..cfg };
        let (mut ds, _) = cfg.run();
        for g in ds.points() {
            for (j, &i) in g.rows.iter().enumerate() {
                let s = &mut ds.samples[i];
                if s.x.abs() < 30_000.0 && s.y.abs() < 30_000.0 {
                    let d = if j % 2 == 0 { 60.0 } else { -60.0 };
                    s.x += d;
                    s.y += d;
                }
            }
        }
        let m = analyze(&ds, &Options::default(), &|_: &str| {}).unwrap();
        assert!(m.chi2_dof_before < 0.5, "{}", m.chi2_dof_before);
        let note = m.data_notes.join(" | ");
        assert!(
            note.contains("the point means scatter far less than their repeated samples say"),
            "{note}"
        );
    }

    /// One sample per point with 3x the assumed noise: the excess chi-square is no structure
    /// (no extension gains), and the verdict says to rerun with the noise it sees; with that
    /// noise nothing is named.
    #[test]
    fn a_noise_larger_than_assumed_is_pointed_out() {
        let cfg = SimConfig {
            effects: Vec::new(),
            noise: 100.0,
            samples: 1,
            ..sim("cell_gain=0", 3)
        };
        let (ds, _) = cfg.run();
        let a = analyze(&ds, &Options::default(), &|_: &str| {}).unwrap();
        assert!(a.unexplained, "{}", a.verdict);
        assert!(
            a.verdict.contains("rerun with --noise 10") && a.causes.is_empty(),
            "{}",
            a.verdict
        );
        let opts = Options {
            noise: Some(100.0),
            ..Options::default()
        };
        let a = analyze(&ds, &opts, &|_: &str| {}).unwrap();
        assert!(!a.unexplained && a.causes.is_empty(), "{}", a.verdict);
    }

    fn run(effect: &str, seed: u64) -> Analysis {
        let (ds, _) = sim(effect, seed).run();
        let a = analyze(&ds, &Options::default(), &|_: &str| {}).unwrap();
        let name = effect.split('=').next().unwrap();
        assert_eq!(
            a.causes.first().map(|c| c.effect.as_str()),
            Some(name),
            "{}",
            a.verdict
        );
        a
    }

    /// face_angle's DX and DY are positively correlated (+0.66 over the 200 clean seeds of
    /// host/ANALYZE.md, "Detection limits"): the named cause says so in JSON and in the text.
    #[test]
    fn face_angle_reports_its_dx_dy_correlation() {
        let a = run("face_angle=1,-0.5", 16);
        let c = &a.causes[0];
        assert_eq!(c.correlations.len(), 1, "{:?}", c.correlations);
        let r = &c.correlations[0];
        assert_eq!((r.a.as_str(), r.b.as_str()), ("DX", "DY"));
        assert!(r.rho > 0.55 && r.rho < 0.85, "rho {}", r.rho);
        let text = render_text(&a);
        let line = format!("     correlation: DX,DY {:+.2}\n", r.rho);
        assert!(text.contains(&line), "{text}");
        let json = serde_json::to_value(&a).unwrap();
        let j = &json["causes"][0]["correlations"][0];
        assert_eq!((j["a"].as_str(), j["b"].as_str()), (Some("DX"), Some("DY")));
        assert_eq!(j["rho"].as_f64(), Some(r.rho));
        // The ruled-out entries carry the field too (empty or not).
        assert!(json["ruled_out"][0]["correlations"].is_array());
    }

    /// cell_gain's GX and GY are nearly uncorrelated (within +/-0.1): no correlation line.
    /// beacon_pattern's H_deg and m derive from one fitted parameter (their correlation is
    /// -1 by construction, not information): none either.
    #[test]
    fn uncorrelated_or_one_parameter_causes_report_none() {
        for (effect, seed) in [("cell_gain=0.03,-0.02", 14), ("beacon_pattern=45", 12)] {
            let a = run(effect, seed);
            let c = &a.causes[0];
            assert!(c.correlations.is_empty(), "{effect}: {:?}", c.correlations);
            let text = render_text(&a);
            let named = text.split("not named (tried").next().unwrap();
            assert!(!named.contains("correlation:"), "{text}");
        }
    }

    /// The reported correlation is the real one: over 400 seeds, the sample correlation of
    /// face_angle's (DX, DY) estimates agrees with the correlation each fit reports (a
    /// smaller setup than the analysis tests to keep this fast: 6 separations, 1 sample per
    /// point, the model fitted directly from the true pose).
    #[test]
    fn reported_correlation_matches_the_scatter_over_seeds() {
        use super::data::{Data, Weights};
        let model = Model::new(Base::Thesis, 6).with(Cand::FaceAngle);
        let (mut dx, mut dy, mut reported) = (Vec::new(), Vec::new(), Vec::new());
        for seed in 0..400 {
            let mut cfg = sim("face_angle=1,-0.5", 1000 + seed);
            cfg.separations = vec![2.0, 4.0, 6.0, 10.0, 18.0, 30.0];
            cfg.samples = 1;
            let (ds, _) = cfg.run();
            let data = Data::from_dataset(&ds, Weights::Separation, Some(32.768)).unwrap();
            let all: Vec<usize> = (0..data.points.len()).collect();
            let x0 = [0.6, 0.1, 0.062, 0.001, 0.002, 0.001, 0.0, 0.0];
            let f = super::select::fit_all(&model, &data, &all, &x0).unwrap();
            dx.push(f.x[6]);
            dy.push(f.x[7]);
            let p = delta_method(&model, Cand::FaceAngle, &f, |v| {
                Cand::FaceAngle.report(Base::Thesis, v)
            });
            reported.push(p.cov[(0, 1)] / (p.cov[(0, 0)] * p.cov[(1, 1)]).sqrt());
        }
        let n = dx.len() as f64;
        let (mx, my) = (dx.iter().sum::<f64>() / n, dy.iter().sum::<f64>() / n);
        let sxy: f64 = dx.iter().zip(&dy).map(|(a, b)| (a - mx) * (b - my)).sum();
        let sxx: f64 = dx.iter().map(|a| (a - mx).powi(2)).sum();
        let syy: f64 = dy.iter().map(|b| (b - my).powi(2)).sum();
        let sample = sxy / (sxx * syy).sqrt();
        let rep = reported.iter().sum::<f64>() / n;
        println!(
            "face_angle DX, DY over 400 seeds: sample correlation {sample:.3}, reported {rep:.3}"
        );
        // The sampling error of a correlation near 0.7 from 400 pairs is ~0.026 (60 pairs
        // gave 0.80 against 0.68: too few).
        assert!(rep > 0.5, "reported {rep}");
        assert!(
            (sample - rep).abs() < 0.1,
            "sample correlation {sample}, reported {rep}"
        );
    }

    /// A FitResult of the thesis model plus `beacon_tilt` at (tx, ty) with the given
    /// covariance (free parameters: all 8).
    fn tilt_fit(tx: f64, ty: f64, cov: DMatrix<f64>) -> (Model, FitResult) {
        let m = Model::new(Base::Thesis, 3).with(Cand::BeaconTilt);
        let x = vec![0.6, 0.1, 0.062, 0.001, 0.002, 0.001, tx, ty];
        let sigma = (0..8).map(|i| cov[(i, i)].sqrt()).collect();
        let f = FitResult {
            x,
            sigma,
            cov,
            free: (0..8).collect(),
            chi2: 0.0,
            ss: 0.0,
            m: 100,
        };
        (m, f)
    }

    /// The delta method carries a correlation through a nonlinear reparametrisation with the
    /// right sign, and the thresholds (0.5 own, 0.9 with the starting model) hold.
    #[test]
    fn correlations_through_the_delta_method() {
        // sigma_tx = 0.1, sigma_ty = 0.2, rho(tx, ty) = 0.8; rho(tx, d1) = 0.95,
        // rho(ty, d2) = 0.85 (below the starting-model threshold).
        let mut cov = DMatrix::<f64>::identity(8, 8) * 1e-6;
        cov[(6, 6)] = 0.01;
        cov[(7, 7)] = 0.04;
        cov[(6, 7)] = 0.8 * 0.1 * 0.2;
        cov[(7, 6)] = cov[(6, 7)];
        cov[(0, 6)] = 0.95 * 1e-3 * 0.1;
        cov[(6, 0)] = cov[(0, 6)];
        cov[(1, 7)] = 0.85 * 1e-3 * 0.2;
        cov[(7, 1)] = cov[(1, 7)];
        // Tilt along +x: T moves with tx, AZ with ty: rho(T, AZ) = rho(tx, ty).
        let (m, f) = tilt_fit(3.0, 0.0, cov.clone());
        let p = delta_method(&m, Cand::BeaconTilt, &f, |v| {
            Cand::BeaconTilt.report(Base::Thesis, v)
        });
        let c = p.correlations();
        assert_eq!(c.len(), 1, "{c:?}");
        assert_eq!((c[0].a.as_str(), c[0].b.as_str()), ("T_deg", "AZ_deg"));
        assert!((c[0].rho - 0.8).abs() < 1e-3, "{c:?}");
        let b = p.base_correlations();
        assert_eq!(b.len(), 1, "{b:?}");
        assert_eq!((b[0].a.as_str(), b[0].b.as_str()), ("T_deg", "d1"));
        assert!((b[0].rho - 0.95).abs() < 1e-3, "{b:?}");
        // Tilt along +y: T moves with ty, AZ against tx: rho(T, AZ) = -rho(tx, ty).
        let (m, f) = tilt_fit(0.0, 3.0, cov.clone());
        let p = delta_method(&m, Cand::BeaconTilt, &f, |v| {
            Cand::BeaconTilt.report(Base::Thesis, v)
        });
        let c = p.correlations();
        assert!(c.len() == 1 && (c[0].rho + 0.8).abs() < 1e-3, "{c:?}");
        // AZ moves against tx, which correlates +0.95 with d1.
        let b = p.base_correlations();
        assert_eq!(b.len(), 1, "{b:?}");
        assert_eq!((b[0].a.as_str(), b[0].b.as_str()), ("AZ_deg", "d1"));
        assert!((b[0].rho + 0.95).abs() < 1e-3, "{b:?}");
        // Weaker than 0.5: not listed.
        cov[(6, 7)] = 0.45 * 0.1 * 0.2;
        cov[(7, 6)] = cov[(6, 7)];
        let (m, f) = tilt_fit(3.0, 0.0, cov);
        let p = delta_method(&m, Cand::BeaconTilt, &f, |v| {
            Cand::BeaconTilt.report(Base::Thesis, v)
        });
        assert!(p.correlations().is_empty());
    }

    /// Every effect `analyze` can name says what the sensor board does with it; those its
    /// calibration holds name the field `cta calibrate` writes.
    #[test]
    fn every_nameable_effect_says_what_the_board_does_with_it() {
        let generic = crate::analyze::board_note("not an effect");
        for name in crate::sim::effects::VOCABULARY {
            assert_ne!(crate::analyze::board_note(name), generic, "{name}");
        }
        for (name, field) in [
            ("cell_gain", "gx, gy"),
            ("cell_bias", "bx, by"),
            ("face_angle", "a, ay"),
            ("proximity", "cell offset s"),
        ] {
            let n = crate::analyze::board_note(name);
            assert!(n.contains("holds it") && n.contains(field), "{name}: {n}");
        }
        assert!(crate::analyze::board_note("saturation").starts_with("outside the board's model"));
    }

    /// A named cause's parameters are the final model's: from `pinhole` on thesis data,
    /// `proximity` is named first and, fitted alone, stands in for `intensity` (S ~0.85 in);
    /// the cause reports the S of the final model, which holds `intensity` too, near the
    /// thesis's 0.175 in, and equal to the final parameter `proximity.S`. `beacon_pattern`,
    /// named too, lists its tie to d3 once.
    #[test]
    fn a_cause_reports_its_parameters_in_the_final_model() {
        let (ds, _) = SimConfig {
            effects: Vec::new(),
            samples: 10,
            ..sim("cell_gain=0", 24)
        }
        .run();
        let opts = Options {
            from: Base::Pinhole,
            ..Options::default()
        };
        let a = analyze(&ds, &opts, &|_: &str| {}).unwrap();
        let names: Vec<&str> = a.causes.iter().map(|c| c.effect.as_str()).collect();
        assert!(
            names.first() == Some(&"proximity") && names.contains(&"intensity"),
            "{}",
            a.verdict
        );
        let c = &a.causes[0];
        let (s, sigma) = (c.params["S"], c.sigma["S"]);
        assert!(
            (s - 0.175).abs() < 5.0 * sigma && sigma < 0.01,
            "S = {s} +/- {sigma}"
        );
        let fin = a
            .params_after
            .iter()
            .find(|p| p.name == "proximity.S")
            .expect("proximity.S in the final parameters");
        assert!((fin.value - s).abs() < 1e-12, "{} vs {s}", fin.value);
        // beacon_pattern's H_deg and m are one parameter: its strong tie to d3 is listed
        // once, for H_deg.
        let bp = a
            .causes
            .iter()
            .find(|c| c.effect == "beacon_pattern")
            .expect("beacon_pattern named");
        let base: Vec<&str> = bp.base_correlations.iter().map(|r| r.a.as_str()).collect();
        assert_eq!(base, ["H_deg"], "{:?}", bp.base_correlations);
    }

    /// A cause lists its parameters in the model's order, not alphabetically: `beacon_tilt`'s
    /// T_deg before AZ_deg in the text and in the JSON objects `params` and `sigma` (same keys
    /// as before); `plate_offset`'s summary `rms_in` first, then x, y separation by separation
    /// (2 in before 10 in).
    #[test]
    fn a_cause_lists_its_parameters_in_the_model_order() {
        let a = run("beacon_tilt=3,45", 100);
        let c = &a.causes[0];
        let keys: Vec<&str> = c.params.keys().map(String::as_str).collect();
        assert_eq!(keys, ["T_deg", "AZ_deg"]);
        let text = render_text(&a);
        let line = text
            .lines()
            .find(|l| l.contains("T_deg = "))
            .expect("a parameter line");
        assert!(
            line.trim_start().starts_with("T_deg = ") && line.contains(", AZ_deg = "),
            "{text}"
        );
        let json = serde_json::to_string(&a).unwrap();
        for field in ["params", "sigma"] {
            let at = format!("\"{field}\":{{\"T_deg\":");
            assert!(json.contains(&at), "{field}: {json}");
        }
        let v = serde_json::to_value(&a).unwrap();
        assert_eq!(
            v["causes"][0]["params"]["T_deg"].as_f64(),
            Some(c.params["T_deg"])
        );
        assert_eq!(
            v["causes"][0]["sigma"]["AZ_deg"].as_f64(),
            Some(c.sigma["AZ_deg"])
        );

        let a = run("plate_offset=0.05", 100);
        let c = &a.causes[0];
        let mut want = vec!["rms_in".to_string()];
        for sep in &a.separations {
            want.push(format!("x@{sep}in"));
            want.push(format!("y@{sep}in"));
        }
        assert_eq!(c.params.keys().cloned().collect::<Vec<_>>(), want);
        assert_eq!(
            c.sigma.keys().collect::<Vec<_>>(),
            want[1..].iter().collect::<Vec<_>>()
        );
    }

    /// A cause's gain is measured against the noise: the held-out RMS with noise alone is
    /// that of the point means (32.8 counts / sqrt(4 samples) = 16.4), and a tilt the model
    /// then holds leaves a systematic part well below the one before (8.6 -> 3.1 counts here:
    /// what is left is mostly the folds' own estimation error), where the plain difference of
    /// held-out RMS (about 1 count) said little.
    #[test]
    fn a_cause_measures_its_gain_against_the_noise() {
        let a = run("beacon_tilt=3,45", 100);
        let c = &a.causes[0];
        assert!(
            (c.heldout_noise_rms - 16.4).abs() < 0.5,
            "{}",
            c.heldout_noise_rms
        );
        assert_eq!(c.heldout_noise_rms, a.heldout_noise_rms);
        assert!(
            c.systematic_rms_before > 2.0 * c.systematic_rms_after.max(0.5),
            "{} -> {}",
            c.systematic_rms_before,
            c.systematic_rms_after
        );
        assert!(c.heldout_rms_after > 0.95 * c.heldout_noise_rms);
        let text = render_text(&a);
        assert!(
            text.contains(&format!(
                "({:.1} from noise alone: systematic {:.1} -> {:.1})",
                c.heldout_noise_rms, c.systematic_rms_before, c.systematic_rms_after
            )),
            "{text}"
        );
        assert_eq!(a.noise_rms_by_sep.len(), a.separations.len());
        assert!(a.noise_rms_by_sep.iter().all(|v| (12.0..22.0).contains(v)));
    }

    /// The analysis (defaults) of the setup of [`sim`] with two effects hidden at once.
    fn run_two(first: &str, second: &str, seed: u64) -> Analysis {
        let (ds, _) = SimConfig {
            effects: vec![
                Effect::parse(first).unwrap(),
                Effect::parse(second).unwrap(),
            ],
            ..sim(first, seed)
        }
        .run();
        analyze(&ds, &Options::default(), &|_: &str| {}).unwrap()
    }

    /// Hidden `proximity` and `beacon_pattern` are both named, and their sizes trade against
    /// each other through d3 (H_deg,d3 -0.98 and S,d3 -0.99 here): the final model's fit
    /// correlates S and H_deg by about +1.00 (the sample correlation of the two estimates
    /// over seeds 200-239 is +0.999). The text says so in one line after the causes, the
    /// report next to the causes table, JSON in `cross_correlations`.
    #[test]
    fn two_causes_that_trade_report_their_correlation() {
        let a = run_two("proximity=0.21", "beacon_pattern=45", 100);
        let names: Vec<&str> = a.causes.iter().map(|c| c.effect.as_str()).collect();
        assert_eq!(names.len(), 2, "{}", a.verdict);
        assert!(
            names.contains(&"proximity") && names.contains(&"beacon_pattern"),
            "{}",
            a.verdict
        );
        let q = |e: &str| {
            if e == "proximity" {
                "proximity.S"
            } else {
                "beacon_pattern.H_deg"
            }
        };
        assert_eq!(a.cross_correlations.len(), 1, "{:?}", a.cross_correlations);
        let r = &a.cross_correlations[0];
        assert_eq!((r.a.as_str(), r.b.as_str()), (q(names[0]), q(names[1])));
        assert!(r.rho > 0.99, "rho {}", r.rho);
        let text = render_text(&a);
        let line = format!(
            "\ncorrelation between causes: {},{} {:+.2}\n",
            r.a, r.b, r.rho
        );
        let at = text.find(&line).unwrap_or_else(|| panic!("{text}"));
        let last_cause = text.rfind("on the sensor board:").unwrap();
        let ruled_out = text.find("not named (tried").unwrap();
        assert!(last_cause < at && at < ruled_out, "{text}");
        let json = serde_json::to_value(&a).unwrap();
        let j = &json["cross_correlations"][0];
        assert_eq!(
            (j["a"].as_str(), j["b"].as_str()),
            (Some(q(names[0])), Some(q(names[1])))
        );
        assert_eq!(j["rho"].as_f64(), Some(r.rho));
        let html = super::report::render(&a).unwrap();
        let causes_table = html.find("<h2>Named causes</h2>").unwrap();
        let shown = html
            .find(&format!("<i>{}</i>", line.trim()))
            .expect("in the report");
        assert!(causes_table < shown && shown < html.find("<h2>Not named</h2>").unwrap());
    }

    /// Hidden `cell_gain` and `face_angle` are both named and nearly independent in the final
    /// fit (|rho| <= 0.11): no correlation between causes in the text, JSON or the report.
    #[test]
    fn independent_causes_report_no_correlation_between_them() {
        let a = run_two("cell_gain=0.03,-0.02", "face_angle=1,-0.5", 100);
        let names: Vec<&str> = a.causes.iter().map(|c| c.effect.as_str()).collect();
        assert_eq!(names, ["face_angle", "cell_gain"], "{}", a.verdict);
        assert!(
            a.cross_correlations.is_empty(),
            "{:?}",
            a.cross_correlations
        );
        assert!(!render_text(&a).contains("correlation between causes"));
        let json = serde_json::to_value(&a).unwrap();
        assert_eq!(json["cross_correlations"].as_array().map(Vec::len), Some(0));
        let html = super::report::render(&a).unwrap();
        assert!(!html.contains("correlation between causes"));
    }
}
