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
//!    separations better is added, until nothing significant remains.
//! 4. Report the causes with their parameters and 1-sigma, the held-out gain, chi-square per
//!    degree of freedom and the angle-error spread per separation before and after; say
//!    "unexplained structure remains" (and where) when the best extension still leaves
//!    chi-square per degree of freedom clearly above 1. For every candidate tried on top of
//!    the final model and not accepted, report its estimates +/- 1-sigma (how tightly the
//!    data rule it out, [`RuledOut`]).

pub mod data;
pub mod diag;
pub mod digits;
pub mod model;
pub mod report;
pub mod select;

use crate::measurement::{parse_separations, Dataset};
use anyhow::Context;
use data::{Data, Weights};
pub use digits::{pm, pm_parts};
use model::{Base, Cand, FitResult, Model};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Chi-square per degree of freedom above which the final model is said to leave
/// unexplained structure (and no cause is named with confidence).
pub const UNEXPLAINED_CHI2_DOF: f64 = 1.2;

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
  repeats until nothing significant remains.

  Candidates: proximity (from pinhole), intensity (from pinhole), beacon_pattern, beacon_tilt,
  cell_gain, cell_bias, face_angle, saturation, plate_offset, separation_error.

VERDICTS:
  named causes        the extended model brings chi2/dof near 1 (<= 1.2)
  no significant effect  the starting model already explains the data
  unexplained structure remains  the best extension still leaves chi2/dof > 1.2: nothing is
                      named with confidence; the output shows where the residuals are
  ruled out           every candidate tried on top of the final model and not accepted, with
                      its estimate +/- 1-sigma: the data still allow about estimate +/- 2 sigma

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
    /// How repeated samples weight the point means: pooled per `separation`, per `point`, or
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
        }
    }
}

/// A named (or tentative) cause.
#[derive(Debug, Clone, Serialize)]
pub struct Cause {
    /// Vocabulary name.
    pub effect: String,
    /// Fitted parameters (physical units; per-separation ones as `x@Sin`).
    pub params: BTreeMap<String, f64>,
    /// Their 1-sigma.
    pub sigma: BTreeMap<String, f64>,
    /// Held-out RMS gain from adding this effect, counts.
    pub gain_rms_counts: f64,
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
    /// Candidates of the same round that explain the data about as well: significant on
    /// their own (`dBIC > 10`) and less than [`RIVAL_DBIC`] below this cause. The data do not
    /// tell them apart (e.g. `proximity` and `beacon_pattern` at small sizes: host/ANALYZE.md,
    /// "Detection limits").
    pub rivals: Vec<Rival>,
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
            "but {} explains the data about as well: a BIC difference below {RIVAL_DBIC} does \
             not tell them apart (host/ANALYZE.md, Detection limits)",
            list.join(", ")
        ))
    }

    /// The global (not per-separation) parameters as `name = value PM sigma` strings
    /// ([`digits`]: the value to the decimal place of its 1-sigma's second digit).
    pub fn global_params(&self, pmark: &str) -> Vec<String> {
        self.params
            .iter()
            .filter(|(n, _)| !n.contains('@'))
            .map(|(n, v)| match self.sigma.get(n) {
                Some(sg) => format!("{n} = {}", pm(*v, *sg, pmark)),
                None => format!("{n} = {}", g(*v)),
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
    /// One-sample noise per separation (X, Y), counts.
    pub noise_by_sep: Vec<[f64; 2]>,
    /// Samples read, points fitted, points left out.
    pub samples: usize,
    /// Points fitted.
    pub points: usize,
    /// Points left out (pinned outputs).
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
            holdout: self.holdout.as_deref().map(parse_separations).transpose()?,
            weights: self.weights,
            noise: self.noise,
            candidates,
            max_effects: self.max_effects,
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

/// Quantities `rep` of effect `c`'s global parameters in the fit `f` of `model`, each with its
/// 1-sigma by the delta method (numerical gradient of the quantity through the fitted
/// covariance of those parameters): (name, value, sigma).
fn delta_method<'n>(
    model: &Model,
    c: Cand,
    f: &FitResult,
    rep: impl Fn(&[f64]) -> Vec<(&'n str, f64)>,
) -> Vec<(&'n str, f64, f64)> {
    let idx: Vec<usize> = model.global_indices(c).collect();
    let v: Vec<f64> = idx.iter().map(|&i| f.x[i]).collect();
    // Covariance block of the global parameters.
    let pos: Vec<Option<usize>> = idx
        .iter()
        .map(|i| f.free.iter().position(|j| j == i))
        .collect();
    let values = rep(&v);
    let mut out = Vec::with_capacity(values.len());
    for (k, &(name, val)) in values.iter().enumerate() {
        let mut grad = vec![0.0; v.len()];
        for (j, g) in grad.iter_mut().enumerate() {
            let h = 1e-7 * (1.0 + v[j].abs());
            let mut vp = v.clone();
            vp[j] += h;
            *g = (rep(&vp)[k].1 - val) / h;
        }
        let mut var = 0.0;
        for a in 0..v.len() {
            for b in 0..v.len() {
                if let (Some(pa), Some(pb)) = (pos[a], pos[b]) {
                    var += grad[a] * grad[b] * f.cov[(pa, pb)];
                }
            }
        }
        out.push((name, val, var.max(0.0).sqrt()));
    }
    out
}

/// The reported parameters of `c` in the fit `f` of `model`, with 1-sigma by the delta
/// method (numerical gradient of the reported quantities through the fitted covariance).
fn cause_params(
    model: &Model,
    c: Cand,
    f: &FitResult,
    seps: &[f64],
) -> (BTreeMap<String, f64>, BTreeMap<String, f64>) {
    let mut p = BTreeMap::new();
    let mut s = BTreeMap::new();
    for (name, val, sg) in delta_method(model, c, f, |v| c.report(model.base, v)) {
        p.insert(name.to_string(), val);
        s.insert(name.to_string(), sg);
    }
    if !c.local_names().is_empty() {
        let mut sumsq = 0.0;
        let mut n = 0;
        for (k, sep) in seps.iter().enumerate() {
            for (j, i) in model.local_indices(c, k).enumerate() {
                let name = format!("{}@{}in", c.local_names()[j], sep);
                p.insert(name.clone(), f.x[i]);
                s.insert(name, f.sigma[i]);
                sumsq += f.x[i] * f.x[i];
                n += 1;
            }
        }
        p.insert("rms_in".into(), (sumsq / n.max(1) as f64).sqrt());
    }
    (p, s)
}

/// The parameters of candidate `c` in its trial fit `f` of `model` (the round's model plus
/// `c`), as [`Cand::trial_report`] gives them (smooth through the no-effect value, which each
/// carries), 1-sigma by the delta method; then every per-separation value (`x@2in`, no-effect
/// value 0).
fn trial_params(model: &Model, c: Cand, f: &FitResult, seps: &[f64]) -> Vec<Param> {
    let idx: Vec<usize> = model.global_indices(c).collect();
    let v: Vec<f64> = idx.iter().map(|&i| f.x[i]).collect();
    let nulls: Vec<Option<f64>> = c.trial_report(model.base, &v).iter().map(|r| r.2).collect();
    let rep = |v: &[f64]| {
        c.trial_report(model.base, v)
            .into_iter()
            .map(|(n, x, _)| (n, x))
            .collect::<Vec<_>>()
    };
    let mut out: Vec<Param> = delta_method(model, c, f, rep)
        .into_iter()
        .zip(nulls)
        .map(|((name, value, sigma), no_effect)| Param {
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
    out
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
    let data = Data::from_dataset(ds, opts.weights, opts.noise)?;
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
                match data.seps.iter().position(|v| (v - s).abs() < 1e-6) {
                    Some(k) => idx.push(k),
                    None => {
                        return Err(format!(
                            "{file}: --holdout separation {s} in is not in the file (it has {})",
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
    let min_pts = per_sep.iter().copied().min().unwrap_or(0);
    let sel_opts = select::Options {
        base: opts.from,
        folds: opts.folds,
        candidates: opts.candidates.clone(),
        max_effects: opts.max_effects,
    };
    let sel = select::select_with_folds(&data, &sel_opts, &fold_seps, progress)?;
    let mut untested: Vec<Untested> = sel
        .untested
        .iter()
        .map(|(c, r)| Untested {
            effect: c.name().into(),
            reason: r.clone(),
        })
        .collect();
    if min_pts < 8 {
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
    let n_constraints = |m: &Model| {
        m.effects
            .iter()
            .map(|e| e.local_names().len())
            .sum::<usize>()
    };
    let dof_chi2 = |m: &Model, f: &FitResult| f.chi2 / f.dof(n_constraints(m));
    let base_chi2 = dof_chi2(&sel.base_model, &sel.base_fit);
    let (fm, ff, fcv) = sel.last();
    let final_chi2 = dof_chi2(fm, ff);
    let unexplained = final_chi2 > UNEXPLAINED_CHI2_DOF;
    let mut causes = Vec::new();
    for st in &sel.steps {
        let (params, sigma) = cause_params(&st.model, st.cand, &st.fit, &data.seps);
        let round = sel
            .trials
            .iter()
            .find(|t| t.accepted && t.cand == st.cand)
            .map(|t| t.round);
        let rivals = sel
            .trials
            .iter()
            .filter(|t| {
                Some(t.round) == round
                    && t.cand != st.cand
                    && t.dbic > 10.0
                    && t.dbic > st.dbic - RIVAL_DBIC
            })
            .map(|t| Rival {
                effect: t.cand.name().into(),
                dbic: t.dbic,
            })
            .collect();
        causes.push(Cause {
            effect: st.cand.name().into(),
            params,
            sigma,
            gain_rms_counts: st.cv_before.rms - st.cv_after.rms,
            dchi2: st.dchi2,
            dbic: st.dbic,
            heldout_rms_before: st.cv_before.rms,
            heldout_rms_after: st.cv_after.rms,
            chi2_dof_after: dof_chi2(&st.model, &st.fit),
            rivals,
        });
    }
    let (causes, tentative) = if unexplained {
        (Vec::new(), causes)
    } else {
        (causes, Vec::new())
    };
    let before_res = diag::residuals(&sel.base_model, &sel.base_fit.x, &data);
    let after_res = diag::residuals(fm, &ff.x, &data);
    let ab = diag::angle_errors(&sel.base_model, &sel.base_fit.x, &data);
    let aa = diag::angle_errors(fm, &ff.x, &data);
    let diagnostics_before = diag::diagnose(&sel.base_model, &sel.base_fit.x, &data);
    let diagnostics_after = diag::diagnose(fm, &ff.x, &data);
    let structure = if final_chi2 > UNEXPLAINED_CHI2_DOF {
        diagnostics_after.notes()
    } else {
        Vec::new()
    };
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
        format!(
            "unexplained structure remains: chi2/dof {:.2} after the best extension (starting model {:.2}){part}",
            final_chi2, base_chi2
        )
    } else if causes.is_empty() {
        format!(
            "no significant effect: the `{}` model explains the data (chi2/dof {:.2})",
            opts.from.name(),
            base_chi2
        )
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
        .map(|t| TrialOut {
            round: t.round,
            effect: t.cand.name().into(),
            k: t.k,
            dchi2: t.dchi2,
            dbic: t.dbic,
            heldout_rms: t.cv_rms,
            accepted: t.accepted,
            failure: t.failure.clone(),
            fitted: t.fit.is_some(),
            params: t
                .fit
                .as_deref()
                .map(|(m, f)| trial_params(m, t.cand, f, &data.seps))
                .unwrap_or_default(),
        })
        .collect();
    let (ruled_out, ruled_out_note) = ruled_out(&trials, &sel, opts.max_effects);
    Ok(Analysis {
        file,
        model_from: opts.from.name().into(),
        causes,
        tentative,
        untested,
        unexplained,
        verdict,
        chi2_dof_before: base_chi2,
        chi2_dof_after: final_chi2,
        rms_before: sel.base_cv.rms,
        rms_after: fcv.rms,
        separations: data.seps.clone(),
        angle_std_before_deg: diag::angle_std_by_sep(&ab, &data),
        angle_std_after_deg: diag::angle_std_by_sep(&aa, &data),
        heldout_rms_by_sep_before: sel.base_cv.rms_by_sep.clone(),
        heldout_rms_by_sep_after: fcv.rms_by_sep.clone(),
        params_before: params_of(&sel.base_model, &sel.base_fit, &data.seps, true),
        params_after: params_of(fm, ff, &data.seps, true),
        noise: data.noise_note.clone(),
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

/// Text summary.
pub fn render_text(a: &Analysis) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "cta analyze {} (from `{}`)", a.file, a.model_from);
    let _ = writeln!(
        s,
        "  {} samples -> {} points ({} left out: pinned output), separations {}",
        a.samples,
        a.points,
        a.excluded_points,
        crate::measurement::fmt_list(&a.separations)
    );
    let _ = writeln!(s, "  {}", a.noise);
    let _ = writeln!(s, "\n{}\n", a.verdict);
    for (k, c) in a.causes.iter().chain(&a.tentative).enumerate() {
        let tag = if k < a.causes.len() {
            ""
        } else {
            " (tentative, not named)"
        };
        let _ = writeln!(
            s,
            "{}. {}{tag}: held-out RMS {:.1} -> {:.1} counts (gain {:.1}), dchi2 {:.0}, dBIC {:.0}, chi2/dof after {:.2}",
            k + 1,
            c.effect,
            c.heldout_rms_before,
            c.heldout_rms_after,
            c.gain_rms_counts,
            c.dchi2,
            c.dbic,
            c.chi2_dof_after
        );
        let shown = c.global_params("+/-");
        if !shown.is_empty() {
            let _ = writeln!(s, "     {}", shown.join(", "));
        }
        if let Some(line) = c.rivals_line() {
            let _ = writeln!(s, "     {line}");
        }
    }
    if !a.ruled_out.is_empty() {
        let _ = writeln!(
            s,
            "{}ruled out (tried on top of the final model, not accepted): estimate +/- \
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
        }
    } else if let Some(n) = &a.ruled_out_note {
        let _ = writeln!(s, "\nruled out: none tried on top of the final model ({n})");
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
        "\n sep(in)  angle std before  after (deg)   held-out RMS before  after (counts)"
    );
    for (k, sep) in a.separations.iter().enumerate() {
        let _ = writeln!(
            s,
            " {:>6}   {:>16.4}  {:>11.4}   {:>19.1}  {:>14.1}",
            sep,
            a.angle_std_before_deg[k],
            a.angle_std_after_deg[k],
            a.heldout_rms_by_sep_before[k],
            a.heldout_rms_by_sep_after[k]
        );
    }
    let _ = writeln!(s, "\nfinal parameters:");
    for p in &a.params_after {
        let (v, sg) = pm_parts(p.value, p.sigma);
        let _ = writeln!(s, "  {:<26} {v:>14} +/- {sg}", p.name);
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
                format!(
                    "{} weighted RMS {:.1e} in (noise alone {:.1e})",
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
    let mut ds = Dataset::read(&args.file).map_err(anyhow::Error::msg)?;
    if let Some(s) = &args.separations {
        let seps = parse_separations(s).map_err(anyhow::Error::msg)?;
        ds = ds.select(&seps).map_err(anyhow::Error::msg)?;
    }
    bar.set_message(format!("{} samples read; fitting", ds.samples.len()));
    let progress = |m: &str| {
        bar.inc(1);
        bar.set_message(m.to_string());
    };
    let a = analyze(&ds, &opts, &progress).map_err(anyhow::Error::msg)?;
    bar.finish_and_clear();
    if let Some(dir) = &args.report {
        report::write(dir, &a)
            .with_context(|| format!("writing the report to {}", dir.display()))?;
        eprintln!("report: {}", dir.join("index.html").display());
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&a)?);
    } else {
        print!("{}", render_text(&a));
    }
    Ok(())
}
