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
//!    chi-square per degree of freedom clearly above 1.

pub mod data;
pub mod diag;
pub mod model;
pub mod report;
pub mod select;

use crate::measurement::{parse_separations, Dataset};
use anyhow::Context;
use data::{Data, Weights};
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
}

impl Cause {
    /// The global (not per-separation) parameters as `name = value PM sigma` strings.
    pub fn global_params(&self, pm: &str) -> Vec<String> {
        self.params
            .iter()
            .filter(|(n, _)| !n.contains('@'))
            .map(|(n, v)| match self.sigma.get(n) {
                Some(sg) => format!("{n} = {} {pm} {}", g(*v), g(*sg)),
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
        })
        .collect()
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
    let idx: Vec<usize> = model.global_indices(c).collect();
    let v: Vec<f64> = idx.iter().map(|&i| f.x[i]).collect();
    let rep = c.report(model.base, &v);
    // Covariance block of the global parameters.
    let pos: Vec<Option<usize>> = idx
        .iter()
        .map(|i| f.free.iter().position(|j| j == i))
        .collect();
    for (k, (name, val)) in rep.iter().enumerate() {
        let mut grad = vec![0.0; v.len()];
        for (j, g) in grad.iter_mut().enumerate() {
            let h = 1e-7 * (1.0 + v[j].abs());
            let mut vp = v.clone();
            vp[j] += h;
            *g = (c.report(model.base, &vp)[k].1 - val) / h;
        }
        let mut var = 0.0;
        for a in 0..v.len() {
            for b in 0..v.len() {
                if let (Some(pa), Some(pb)) = (pos[a], pos[b]) {
                    var += grad[a] * grad[b] * f.cov[(pa, pb)];
                }
            }
        }
        p.insert(name.to_string(), *val);
        s.insert(name.to_string(), var.max(0.0).sqrt());
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
        trials: sel
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
            })
            .collect(),
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
        let _ = writeln!(s, "  {:<26} {:>14} +/- {}", p.name, g(p.value), g(p.sigma));
    }
    s
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
