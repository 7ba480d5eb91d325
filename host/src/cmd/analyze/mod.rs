//! `cta analyze`: from measured data to a named cause, the extended model and its held-out
//! gain.

mod render;
mod spinner;
#[cfg(test)]
mod tests;

pub use render::render_text;
pub use spinner::Spinner;

use std::path::PathBuf;

use anyhow::{anyhow, bail, Result};
use clap::{Args, ValueEnum};
use cta_lab::analyze::model::{self, parse_candidates};
use cta_lab::analyze::{analyze, report, Options};
use cta_lab::data::parse_separations;
use cta_lab::sweep::corners::RunCorners;

/// The starting model (`--from`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Base {
    /// The eq 63 near-field physics (proximity at s = 0.175 in, inverse-square intensity,
    /// Lambertian 60 deg beacons, face angles 30 deg, beta = 32768) with the pose d, p free
    /// (6 parameters). REFERENCE.md "beyond the thesis".
    Thesis,
    /// The 7-parameter collinearity model of eq 65: d, p and the scale height H free; the
    /// far-field emulator with `H = beta tan a`.
    Pinhole,
}

impl From<Base> for model::Base {
    fn from(b: Base) -> Self {
        match b {
            Base::Thesis => model::Base::Thesis,
            Base::Pinhole => model::Base::Pinhole,
        }
    }
}

/// How repeated samples weight the point means (`--weights`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Weights {
    /// Sample variance pooled per separation and axis (default).
    Separation,
    /// Sample variance pooled per separation, setting (frequency, power, sensitivity) and
    /// axis.
    Setting,
    /// Each point's own sample variance.
    Point,
    /// One pooled variance per axis for the whole file.
    Global,
}

impl From<Weights> for cta_lab::analyze::data::Weights {
    fn from(w: Weights) -> Self {
        use cta_lab::analyze::data::Weights as W;
        match w {
            Weights::Separation => W::Separation,
            Weights::Setting => W::Setting,
            Weights::Point => W::Point,
            Weights::Global => W::Global,
        }
    }
}

/// `cta analyze`: find what the model misses in measured data, name the physical cause,
/// and measure how much better the extended model predicts data it was not fitted on.
#[derive(Debug, Clone, Args)]
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
    /// The apparatus uncertainty budget (TOML, the file `cta uncertainty --budget` reads;
    /// default thesis Table 2): a plate offset, separation error or plate tilt fitted far
    /// beyond its root-sum-square is not named as found.
    #[arg(long, value_name = "FILE")]
    pub budget: Option<PathBuf>,
    /// Write a self-contained HTML report (index.html, inline SVG plots) into this folder.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Print the result as JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// No progress bar: the global `--quiet`.
    #[arg(skip)]
    pub quiet: bool,
}

impl AnalyzeArgs {
    /// The library options of these arguments (no corner readings: [`run`] finds them).
    pub fn options(&self) -> Result<Options> {
        let mut candidates = match &self.candidates {
            Some(s) => parse_candidates(s)?,
            None => model::ALL.to_vec(),
        };
        if let Some(s) = &self.exclude {
            let ex = parse_candidates(s)?;
            candidates.retain(|c| !ex.contains(c));
        }
        if self.folds < 2 {
            bail!("--folds {}: need at least 2", self.folds);
        }
        if self.max_effects == 0 {
            bail!("--max-effects 0: no effect could be named; give at least 1 (default 5)");
        }
        Ok(Options {
            from: self.from.into(),
            folds: self.folds,
            holdout: self
                .holdout
                .as_deref()
                .map(parse_separations)
                .transpose()
                .map_err(anyhow::Error::msg)?,
            weights: self.weights.into(),
            noise: self.noise,
            candidates,
            max_effects: self.max_effects,
            drop_glitches: self.drop_glitches,
            corners: None,
            budget: crate::cmd::uncertainty::load_budget(self.budget.as_deref())?,
        })
    }
}

/// Run `cta analyze`.
pub fn run(args: &AnalyzeArgs) -> Result<()> {
    let mut opts = args.options()?;
    if let Some(dir) = &args.report {
        // Before the work: a folder whose index.html cta did not write costs nothing.
        report::check(dir)?;
    }
    let bar = Spinner::new(args.quiet);
    bar.set_message(format!("reading {}", args.file.display()));
    let (mut ds, warnings) =
        cta_lab::sweep::read_measurements(&args.file).map_err(anyhow::Error::msg)?;
    for w in warnings {
        bar.suspend(|| crate::say::warning(w));
    }
    if let Some(s) = &args.separations {
        let seps = parse_separations(s).map_err(anyhow::Error::msg)?;
        ds = ds.select(&seps).map_err(anyhow::Error::msg)?;
    }
    if !args.ignore_corners {
        match RunCorners::beside(&args.file) {
            Some(Ok(rc)) => opts.corners = Some(rc),
            Some(Err(e)) => bar.suspend(|| {
                crate::say::warning(format_args!(
                    "{e:#}: the run's corner readings cannot be used, so the plates are \
                     taken as level (--ignore-corners says so without this warning)"
                ))
            }),
            None => {}
        }
    }
    bar.set_message(format!("{} samples read; fitting", ds.samples.len()));
    let a = analyze(&ds, &opts, &bar)?;
    bar.finish_and_clear();
    // Printed before the report is written: the analysis is never lost to a failed write.
    if args.json {
        println!(
            "{}",
            crate::json_with_provenance(&a, &[args.file.as_path()])?
        );
    } else {
        print!("{}", render_text(&a));
    }
    if let Some(dir) = &args.report {
        report::write(dir, &a, Some(&crate::provenance(&[args.file.as_path()]))).map_err(|e| {
            anyhow!("{e}; the analysis above is complete, the report was not written")
        })?;
        crate::say::line(format_args!("report: {}", dir.join("index.html").display()));
    }
    Ok(())
}
