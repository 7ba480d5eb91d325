//! `cta calibrate`: the sensor board's calibration from a measured CTA sweep, written as the
//! JSON file `cta sensor load-calibration` stores in the board's flash.
//!
//! Two fits, as the lab would do them by hand (REFERENCE.md: start the near-field fit from
//! the 7-parameter fit to avoid false minima):
//!
//! 1. **Pinhole** (eq 65, `d, p, H`; [`crate::fit::fit_observations`]) on the far separations
//!    (25 and 30 in when the file has them, or measured values within 0.1 in, else its two
//!    largest): the chip's `pinhole` model (its `H`, and its `d, p` as the calibration's
//!    [`Calibration::pinhole`]) and the near-field fit's start. Its point means are
//!    weighted as the near-field fit's below (`cta fit --weights pooled`), and its chi2/dof is
//!    printed.
//! 2. **Near-field** (eqs 60-63, `d, p`, the face angle `a`, the cell offset `s`, the cell
//!    gains `gx, gy` of [`NearField::gain`] and the cell offsets `bx, by` of
//!    [`NearField::bias`], with the calibration's `beta` and beacon pattern held) on every
//!    point of every separation, by
//!    GLSDC with a central-difference Jacobian ([`NearFieldFit`]). Points are the means of
//!    their repeated samples, each weighted by `n / sigma^2` with `sigma` the one-sample
//!    noise pooled per separation and axis (weights are absolute, so chi2/dof is 1 when the
//!    model explains the data to the noise). Points with a pinned output (a coordinate at
//!    +/-32767 in any sample, or its mean within 3 sigma of it) carry no position
//!    information and are left out.
//! 3. **Spot magnitudes** ([`fit_magnitude`], [`crate::fit::magnitude`]; `--no-magnitude` leaves
//!    them out): the law `M = offset + A (b S)^exponent` of [`Calibration::magnitude`], `S`
//!    the eq 63 summed cell signal of the fitted head at each beacon, with each LED's
//!    brightness `b` (the file's `led_brightness`, host-side) and the law's 1-sigma in
//!    `fitted.sigma`, at one sensitivity setting.
//!
//! The calibration's `noise` (the chip's per-coordinate 1-sigma) is the one-sample noise
//! pooled over the file (or `--noise`). The residual RMS per separation of both models is
//! printed: what the near-field model gains over the pinhole one on this sensor. A chi2/dof
//! well above 1 means the data hold structure the chip's model cannot represent: `cta
//! analyze` names it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Result};
use clap::Args;
use cta_core::collinearity::{self, ParamsExt};
use cta_core::pose::{CalField, Calibration, ConfigError, NearField, PinholeHead};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::data::weights::{self, misfit_warning, Pooled, Weights, CHI2_WARN};
use crate::data::{any_sample_pinned, fmt_list, mean_near_rail, parse_separations, Dataset};
use crate::fit::magnitude::{LedBrightness, MagnitudeReport, Outcome};
use crate::fit::wiring;
use crate::fit;


/// A separation whose near-field chi-square lies more than this many standard deviations
/// above what the noise gives is reported as one where the model misses the data (see
/// [`SeparationRms::near_field_z`]).
pub const MISFIT_Z: f64 = 5.0;


/// What `--out` files carry in `fitted` (and how an earlier one is recognised).
pub const WRITER: &str = "cta calibrate";

pub use super::nearfield::{
    fit_near_field, NearFieldError, NearFieldFit, NearFieldSolution, NfObs, NF_NAMES, NF_PARAMS,
    STRONG_CORRELATION,
};

/// Closest near-field separation, inches, from which on a calibration out of the board's range
/// is put down to the separations rather than the data: the face angle and cell offset show
/// in how the outputs change close in (a fit of 25 and 30 in alone leaves s free).
const FAR_ONLY_IN: f64 = 10.0;


/// `cta calibrate`: fit the sensor board's calibration to a measured sweep.
#[derive(Debug, Args)]
#[command(
    long_about = "Fit the sensor board's calibration to a measured (or simulated) CTA sweep and write \
the JSON file `cta sensor load-calibration` stores in the board's flash.\n\n\
Two fits: the pinhole model (eq 65: d, p, H) on the far separations, then the near-field model \
(eqs 60-63: d, p, the face angles of both pairs, cell offset s, cell gains gx, gy, cell offsets \
bx, by) on every separation, started from it. Then the spot magnitude law the near-field pose \
fits the magnitudes with, M = offset + A (b S)^exponent (S: eq 63's summed cell signal of the \
fitted head; b: each LED's brightness, written as `led_brightness` for `cta sensor \
load-constellation --brightness`; A: a scale every pose estimates), at one sensitivity setting, \
saturated readings left out (host/CALIBRATE.md, item 3; --no-magnitude leaves it out). The file holds both: the near-field fit's d, p (the \
head) and the pinhole fit's own (`pinhole`: its eye point, about 1 in above the head), which the \
chip's pinhole model uses with H. Repeated samples are averaged per point and weighted by their noise, pooled per separation and axis. The \
report gives every parameter with its 1-sigma, the residual RMS per separation of both models (what \
the near-field model gains on this sensor), and warns when the data hold structure the chip's \
model cannot represent (then run `cta analyze` on the same file).\n\n\
Example:\n  cta sweep --sim --out run && cta calibrate run/data.csv --out cal.json\n  \
cta sensor --port /dev/ttyUSB1 load-calibration cal.json"
)]
pub struct CalibrateArgs {
    /// Measurement file (CSV, host/MEASUREMENTS.md), e.g. a sweep's `data.csv`.
    pub file: PathBuf,
    /// Write the calibration here (JSON for `cta sensor load-calibration`). An earlier
    /// calibration written by `cta calibrate` is replaced; any other file only with --force.
    #[arg(long, value_name = "CAL.json")]
    pub out: Option<PathBuf>,
    /// Let --out replace a file that is not an earlier calibration.
    #[arg(long)]
    pub force: bool,
    /// Fit the near-field model to these separations only (list or range, e.g. `2..30`);
    /// default: every separation in the file.
    #[arg(long, value_name = "SEPS")]
    pub separations: Option<String>,
    /// Fit the pinhole model (eq 65) to these separations; default: 25 and 30 in when the
    /// file has both (the thesis's calibration; a measured 24.995 counts as 25: within 0.1
    /// in), else the file's two largest.
    #[arg(long, value_name = "SEPS")]
    pub pinhole_separations: Option<String>,
    /// One-sample noise of a coordinate, counts: the calibration's `noise` and the weights.
    /// Default: measured from the repeated samples; a file with one sample per point needs
    /// it (0.1 % of beta is 32.8).
    #[arg(long, value_name = "COUNTS")]
    pub noise: Option<f64>,
    /// Beacon pattern exponent m of the LEDs (`cos^m`; 1 = the VSML3710's 60 deg
    /// half-intensity angle), held in the fit and written to the calibration.
    #[arg(long = "pattern-m", value_name = "M", default_value_t = 1.0)]
    pub pattern_m: f64,
    /// Draw the residual RMS per separation of both models against the noise (SVG): where
    /// the near-field model pays on this sensor, and where it still misses.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
    /// Leave out the samples the glitch check flags (more than 8 robust sigma from their
    /// point's median; the warning names their lines), as `cta analyze --drop-glitches`
    /// does. The file is not changed; the output (and the calibration's `fitted`) says how
    /// many were left out.
    #[arg(long)]
    pub drop_glitches: bool,
    /// Leave the spot magnitude law out of the calibration (by default it is fitted to the
    /// file's `magnitude` column with the fitted head, and the pose uses the magnitudes).
    #[arg(long, conflicts_with = "magnitude_sensitivity")]
    pub no_magnitude: bool,
    /// The NorthStar sensitivity setting (1-4) whose magnitudes the law is fitted to (the chip
    /// uses the law only at it). Default: the setting with the most magnitudes in the file
    /// (rows without a `sensitivity` count as 4, the board's start-up setting).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=4))]
    pub magnitude_sensitivity: Option<u8>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The file `--out` writes: the board's calibration (what `load-calibration` reads) and,
/// under `fitted`, where it came from (ignored by the board).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CalibrationFile {
    /// The calibration (its fields at the top level, as `cta sensor template calibration`).
    #[serde(flatten)]
    pub calibration: Calibration,
    /// Provenance and fit quality.
    pub fitted: Provenance,
    /// Each LED's brightness relative to the others', from the spot magnitudes (host-side
    /// data the board ignores: `cta sensor load-constellation --brightness` puts it into a
    /// constellation's beacons). Empty (and absent from the file) without a magnitude law.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub led_brightness: Vec<LedBrightness>,
}

/// Where a calibration came from.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Provenance {
    /// [`WRITER`] and its version.
    pub by: String,
    /// The measurement file.
    pub source: String,
    /// Separations of the near-field fit, inches.
    pub separations: Vec<f64>,
    /// Separations of the pinhole fit, inches.
    pub pinhole_separations: Vec<f64>,
    /// 1-sigma by parameter (`d1..3` in, `p1..3`, `a` and `ay` deg, `s` in, `gx, gy`,
    /// `bx, by` /in^2, `H` counts, and the pinhole fit's `pinhole.d1..3` in, `pinhole.p1..3`;
    /// the last absent in files written before the calibration held the pinhole head).
    pub sigma: BTreeMap<String, f64>,
    /// Near-field fit chi-square per degree of freedom.
    pub chi2_dof: f64,
    /// Near-field fit residual RMS, counts (unweighted, point means).
    pub rms_counts: f64,
    /// Points fitted.
    pub points: usize,
    /// Points left out because an output was pinned.
    pub pinned_points: usize,
    /// Samples the glitch check flagged that `--drop-glitches` left out (0 without it, and
    /// in files written before it).
    #[serde(default)]
    pub glitches_left_out: usize,
    /// Near-field parameters whose estimates correlate at 0.8 or more in magnitude:
    /// `[a, b, rho]` (absent in files written before it).
    #[serde(default)]
    pub correlations: Vec<(String, String, f64)>,
}

/// Residual RMS of both models at one separation.
#[derive(Debug, Clone, Serialize)]
pub struct SeparationRms {
    /// Separation, inches.
    pub separation_in: f64,
    /// Points.
    pub points: usize,
    /// Pinhole model (eq 65), counts; `None` where it predicts no point.
    pub pinhole_counts: Option<f64>,
    /// Near-field model, counts.
    pub near_field_counts: f64,
    /// What the noise alone gives: the RMS of a point mean's error, counts.
    pub noise_counts: f64,
    /// How far the near-field residuals exceed the noise here, in standard deviations:
    /// `ln(chi2 / k) / sqrt(2 / k + 1 / nu)`, chi-square (the residuals in units of their
    /// point mean's noise) over its `k = 2 x points` degrees of freedom, against its spread
    /// when the model is right: `2 / k` from the residuals, and `1 / nu` from the noise
    /// estimate when it is measured at this separation from `nu` degrees of freedom per axis
    /// (with 2 samples per point a noise known to 14 % makes chi2/k scatter as much as the
    /// residuals do). The logarithm (Fisher's z of the variance ratio) makes the ratio of
    /// two chi-squares nearly normal. Above [`MISFIT_Z`] the model misses the data at this
    /// separation.
    pub near_field_z: f64,
}

/// The `cta calibrate` report.
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationReport {
    /// The file written (or that would be written).
    pub file: CalibrationFile,
    /// Pinhole fit: `H`, counts (its 1-sigma is `fitted.sigma.H`).
    pub pinhole_h: f64,
    /// Pinhole fit: chi-square per degree of freedom (point means weighted as the near-field
    /// fit's, so about 1 when the pinhole model explains the far separations to the noise).
    pub pinhole_chi2_dof: f64,
    /// Pinhole fit warnings.
    pub pinhole_warnings: Vec<String>,
    /// Where the noise figure came from.
    pub noise_source: String,
    /// Near-field fit iterations.
    pub iterations: usize,
    /// Near-field fit condition number.
    pub condition: f64,
    /// Residual RMS per separation, both models.
    pub by_separation: Vec<SeparationRms>,
    /// Things the user should know.
    pub warnings: Vec<String>,
    /// Notes on the data fitted: the glitched samples `--drop-glitches` left out, as `cta
    /// analyze`'s `data_notes`.
    pub data_notes: Vec<String>,
    /// The spot magnitude law fitted ([`fit_magnitude`]), when there is one.
    pub magnitude: Option<MagnitudeReport>,
    /// Why the calibration has no magnitude law, when it has none.
    pub magnitude_note: Option<String>,
}



/// Calibrate from a dataset (already restricted to the near-field separations). `all` is
/// the whole file, for the pinhole fit's separations.
pub fn calibrate(
    ds: &Dataset,
    all: &Dataset,
    pinhole_seps: Option<&[f64]>,
    noise_arg: Option<f64>,
    pattern_m: f64,
) -> Result<CalibrationReport> {
    let seps = ds.separations();
    if seps.len() < 2 {
        bail!(
            "{}: the near-field fit needs at least 2 separations (it has only {} in): the face \
             angle and \
             the cell offset show only in how the outputs change with range",
            ds.path.display(),
            fmt_list(&seps)
        );
    }
    // Point means and the pooled noise.
    struct Pt {
        sep: f64,
        r: Vector3<f64>,
        mean: [f64; 2],
        n: usize,
    }
    let mut pts = Vec::new();
    let pooled = Pooled(weights::pooled_noise(ds));
    let mut pinned = 0;
    for p in ds.points() {
        let rows: Vec<_> = p.rows.iter().map(|&i| &ds.samples[i]).collect();
        if any_sample_pinned(rows.iter().copied()) {
            pinned += 1;
            continue;
        }
        let n = rows.len();
        let mean = [
            rows.iter().map(|s| s.x).sum::<f64>() / n as f64,
            rows.iter().map(|s| s.y).sum::<f64>() / n as f64,
        ];
        pts.push(Pt {
            sep: p.first.separation_in,
            r: Vector3::from(p.first.r),
            mean,
            n,
        });
    }
    let (noise, noise_source) = match (noise_arg, pooled.overall()) {
        (Some(v), _) => (v, format!("--noise {v} counts")),
        (None, Some(v)) => (
            v,
            "measured: one-sample noise of the repeated samples, pooled over the file".into(),
        ),
        (None, None) => bail!(
            "{}: every point has one sample, so the noise cannot be measured: give --noise \
             COUNTS (0.1 % of beta is 32.8), or sweep with repeated samples",
            ds.path.display()
        ),
    };
    if !(noise.is_finite() && (0.01..=10_000.0).contains(&noise)) {
        bail!("noise {noise} counts: the board takes 0.01 to 10,000 counts");
    }
    if !(pattern_m.is_finite() && (0.0..=50.0).contains(&pattern_m)) {
        bail!("--pattern-m {pattern_m}: the board takes 0 to 50");
    }
    // A point whose mean lies within 3 sigma of the rail had its true output at or past it
    // (a cell in shadow) and only its noise kept some samples inside: it is left out with
    // the pinned ones. (With a cell offset, a pair in shadow reads the rail, where the
    // model without the offset has no output at all.)
    let before = pts.len();
    pts.retain(|p| !mean_near_rail(p.mean, noise, p.n));
    pinned += before - pts.len();
    if pts.len() < 8 {
        bail!(
            "{}: {} usable points ({pinned} pinned), the near-field fit needs at least 8",
            ds.path.display(),
            pts.len()
        );
    }
    // Weights: the separation's pooled variance when it has one and --noise is not given.
    // The floor is the quantisation of integer counts.
    let measured = noise_arg.is_none();
    let var = |sep: f64, axis: usize| -> f64 {
        measured
            .then(|| pooled.var(sep, axis))
            .flatten()
            .unwrap_or(noise * noise)
            .max(1.0 / 12.0)
    };
    let obs: Vec<NfObs> = pts
        .iter()
        .map(|p| NfObs {
            r: p.r,
            y: p.mean,
            w: [0, 1].map(|a| p.n as f64 / var(p.sep, a)),
        })
        .collect();

    // 1. Pinhole.
    let pinhole_seps: Vec<f64> = match pinhole_seps {
        Some(s) => s.to_vec(),
        None => {
            let have = all.separations();
            match (all.nearest_separation(25.0), all.nearest_separation(30.0)) {
                (Some(a), Some(b)) => vec![a, b],
                _ => have.iter().rev().take(2).rev().copied().collect(),
            }
        }
    };
    let far = all
        .select(&pinhole_seps)
        .map_err(|e| anyhow!("pinhole separations: {e}"))?;
    // Weighted as the near-field stage is: the noise pooled per separation and axis (or
    // --noise), never each point's own few samples, whose inverse variances are too rough to
    // weight by (with 2 samples H came out 18 sigma low). A pinhole separation outside
    // --separations has its noise pooled from the pinhole data.
    let far_pool = weights::pooled_noise(&far);
    let var_ph = |sep: f64, axis: usize| -> f64 {
        measured
            .then(|| {
                pooled
                    .var(sep, axis)
                    .or_else(|| weights::pooled_variance(&far_pool, sep, axis))
            })
            .flatten()
            .unwrap_or(noise * noise)
    };
    let mut ph = fit::fit_observations(&far, Weights::Pooled, weights::point_means(&far, &var_ph))
        .map_err(|e| anyhow!("pinhole fit at {} in: {e}", fmt_list(&pinhole_seps)))
        .map_err(|e| anyhow!("{}", wiring::explain(all, e.to_string())))?;
    // Judged as `cta fit --weights pooled` judges the same data: the same weights, the same
    // expectation (1 with --noise), the same warning line.
    ph.chi2_expected = if measured {
        weights::chi2_expected(&far, Weights::Pooled)
    } else {
        Some(1.0)
    };
    if let Some(w) = fit::chi2_warning(&ph, &all.path, None) {
        ph.warnings.push(format!(
            "the pinhole stage at {} in: {w} Its d, p and H are what the chip's `pinhole` model \
             uses; the near-field stage (its chi2/dof above) is judged on its own.",
            fmt_list(&ph.separations)
        ));
    }
    ph.warnings.extend(wiring::h_warning(all, ph.x().h()));
    let pinhole_chi2_dof = ph.chi2_per_dof.unwrap_or(f64::NAN);
    let xp = ph.x();
    let d = [xp[0], xp[1], xp[2]].map(|v| v as f32);
    let p = [xp[3], xp[4], xp[5]].map(|v| v as f32);
    // The pinhole fit's own d, p go into the file with its H (the chip's `pinhole` model):
    // its eye point is not the head the near-field fit finds (README, "virtual eye"). The
    // near-field fit keeps them (it replaces d, p only).
    let start = Calibration {
        d,
        p,
        h: xp.h() as f32,
        noise: noise as f32,
        near_field: Some(NearField {
            pattern_m: pattern_m as f32,
            ..NearField::nominal()
        }),
        pinhole: Some(PinholeHead { d, p }),
        magnitude: None,
    };

    // What to say when the near-field fit fails, or ends outside what the board takes, on
    // separations that start far out: the face angles and the cell offset show only close in.
    let closest = seps.iter().copied().fold(f64::INFINITY, f64::min);
    let far_only = (closest >= FAR_ONLY_IN).then(|| {
        // Closer separations left out by --separations, or never measured.
        let have = all.separations();
        let remedy = match have.iter().find(|s| **s < closest) {
            Some(first) => format!(
                "the file also has closer ones, from {first} in: include them (leave out \
                 --separations, or e.g. --separations {first}..{})",
                have.last().copied().unwrap_or(closest)
            ),
            None => "measure separations down to a few inches (a sweep of 2..30 in, as \
                     host/plans/chvi.toml), and calibrate from that file"
                .into(),
        };
        format!(
            "The face angles and the cell offset show only close in, and these separations \
             start at {closest} in: {remedy}; or check the file's columns and units"
        )
    });

    // 2. Near field, from the pinhole fit (REFERENCE.md). When that start fails or leaves
    // chi2/dof above the warning line, the fit is tried again from the nominal head pose
    // (Table 3's d, p) and the better one kept: far-range structure the pinhole model
    // cannot hold (a cell offset of 10 % of the 30 in signal) can pull its d inches off, to a
    // start where beacons close in fall in a cell's shadow.
    let mut warnings = Vec::new();
    let nf = match fit_near_field(&obs, &start, true) {
        Ok(nf) if nf.chi2_dof <= CHI2_WARN => nf,
        first => {
            let nominal = Calibration {
                d: Calibration::table3().d,
                p: Calibration::table3().p,
                ..start
            };
            let d = |c: &Calibration| c.d.map(|v| format!("{v:.3}")).join(", ");
            let first_said = match &first {
                Ok(nf) => format!("it reached chi2/dof {:.2} only", nf.chi2_dof),
                Err(e) => e.to_string(),
            };
            // The restart is kept only when its chi-square is lower by more than 10 (strong
            // evidence, as `cta analyze` counts it): both often reach the same minimum of
            // data the model cannot hold.
            let dof = (2 * obs.len()).saturating_sub(NF_PARAMS).max(1) as f64;
            match (first, fit_near_field(&obs, &nominal, true)) {
                (Ok(a), Ok(b)) if (a.chi2_dof - b.chi2_dof) * dof <= 10.0 => a,
                (_, Ok(b)) => {
                    warnings.push(format!(
                        "the near-field fit started from the nominal head pose (d = {} in): \
                         from the pinhole fit's (d = {} in): {first_said}",
                        d(&nominal),
                        d(&start)
                    ));
                    b
                }
                (Ok(a), Err(_)) => a,
                (Err(e), Err(e2)) => Err(anyhow!(
                    "{}: {e}; from the nominal head pose (d = {} in) too: {e2}. {}",
                    ds.path.display(),
                    d(&nominal),
                    match &far_only {
                        Some(cause) => cause.clone(),
                        None => format!(
                            "The data do not look like a NorthStar on the CTA (check the \
                             file's columns, units and --pattern-m; `cta analyze {}` shows \
                             what the models miss)",
                            ds.path.display()
                        ),
                    }
                ))
                .map_err(|e| anyhow!("{}", wiring::explain(all, e.to_string())))?,
            }
        }
    };
    let mut cal = nf.calibration;
    // The pinhole fit's eye point is only the pinhole model's: when it falls outside what the
    // board takes (noisy data, few far separations), the file goes without it (the pinhole
    // model then uses the head's d, p) rather than not at all.
    if let Err(ConfigError::CalibrationOutOfRange {
        field: field @ (CalField::PinholeD | CalField::PinholeP),
    }) = cal.validate()
    {
        let xp = ph.x();
        let sd = |k: &str| ph.sigma.get(k).copied().unwrap_or(f64::NAN);
        warnings.push(format!(
            "the pinhole fit's eye point is outside what the board takes ({}): d = ({:.2} +/- \
             {:.2}, {:.2} +/- {:.2}, {:.2} +/- {:.2}) in, so the file has no `pinhole` and the \
             board's pinhole model uses the head's d, p (ranges read short close in)",
            field.describe(),
            xp[0],
            sd("d1"),
            xp[1],
            sd("d2"),
            xp[2],
            sd("d3"),
        ));
        cal.pinhole = None;
    }
    cal.validate().map_err(|e| {
        let unit = wiring::s_unit_note(nf.x[7], "s").map_or(String::new(), |n| format!("; {n}"));
        let value = match e {
            ConfigError::CalibrationOutOfRange { field: CalField::S } => {
                format!(" (fitted s = {:.3} +/- {:.3} in)", nf.x[7], nf.sigma[7])
            }
            ConfigError::CalibrationOutOfRange { field: CalField::H } => {
                format!(" (the pinhole fit's H = {:.0} counts)", xp.h())
            }
            _ => String::new(),
        };
        // H out of range: negative when the image is turned half a turn (a head turned
        // about its boresight, or X and Y read so), or far off with a length unit; the
        // pinhole fits of [`wiring::diagnose`] name either.
        let named = match e {
            ConfigError::CalibrationOutOfRange { field: CalField::H } => {
                wiring::diagnose(all).map(|d| d.trim_end_matches('.').to_string())
            }
            _ => None,
        };
        let cause = named.or_else(|| far_only.clone()).unwrap_or_else(|| {
            "The data do not look like a NorthStar on the CTA (check the file's columns and \
             units)"
                .into()
        });
        anyhow!(
            "{}: the fitted calibration is outside what the board accepts: {e}{value}. \
             {cause}{unit}",
            ds.path.display()
        )
    })?;

    // Residuals by separation.
    let fitted = NearFieldFit {
        obs: &obs,
        base: cta_firmware_sensor::sim::physics(&start),
        extended: true,
    }
    .model(&nf.x);
    let mut by: BTreeMap<u64, (usize, f64, f64, usize, f64, f64)> = BTreeMap::new();
    // The relative variance of the weights' noise estimate at a separation (0: given).
    let noise_rel_var = |sep: f64| -> f64 {
        // The mean of the two axes' weight errors (2/nu each, the same nu), over 2:
        // (2/nu + 2/nu) / 4.
        match (measured, pooled.dof(sep)) {
            (true, nu) if nu > 0 => 1.0 / nu as f64,
            _ => 0.0,
        }
    };
    for (p, o) in pts.iter().zip(&obs) {
        let e = by.entry(p.sep.to_bits()).or_default();
        e.0 += 1;
        if let Some(y) = fitted.output(&p.r) {
            let r = [p.mean[0] - y[0], p.mean[1] - y[1]];
            e.1 += r[0].powi(2) + r[1].powi(2);
            e.5 += r[0].powi(2) * o.w[0] + r[1].powi(2) * o.w[1];
        }
        if let Some(y) = collinearity::predict(&xp, &p.r) {
            e.2 += (p.mean[0] - y[0]).powi(2) + (p.mean[1] - y[1]).powi(2);
            e.3 += 1;
        }
        e.4 += 1.0 / o.w[0] + 1.0 / o.w[1];
    }
    let by_separation: Vec<SeparationRms> = by
        .into_iter()
        .map(|(k, (n, nf_ss, ph_ss, ph_n, var_sum, chi2))| {
            let dof = (2 * n) as f64;
            let sep = f64::from_bits(k);
            SeparationRms {
                separation_in: f64::from_bits(k),
                points: n,
                pinhole_counts: (ph_n > 0).then(|| (ph_ss / (2 * ph_n) as f64).sqrt()),
                near_field_counts: (nf_ss / dof).sqrt(),
                noise_counts: (var_sum / dof).sqrt(),
                near_field_z: (chi2 / dof).ln() / (2.0 / dof + noise_rel_var(sep)).sqrt(),
            }
        })
        .collect();
    let total_n: usize = by_separation.iter().map(|b| b.points).sum();
    let rms = (by_separation
        .iter()
        .map(|b| b.near_field_counts.powi(2) * b.points as f64)
        .sum::<f64>()
        / total_n as f64)
        .sqrt();

    if nf.chi2_dof > CHI2_WARN {
        warnings.push(misfit_warning(
            &format!("chi2/dof {:.2}", nf.chi2_dof),
            nf.chi2_dof,
            "chip's near-field model (d, p, face angles, s, cell gains and offsets)",
            &all.path,
        ));
    }
    // Where the model misses: a misfit confined to a few separations (a plate tilt shows
    // close in) hardly moves the overall chi2/dof, yet d and p absorb part of it.
    let missed: Vec<&SeparationRms> = by_separation
        .iter()
        .filter(|b| b.near_field_z > MISFIT_Z)
        .collect();
    if !missed.is_empty() {
        let list = |f: &dyn Fn(&SeparationRms) -> String| {
            missed.iter().map(|b| f(b)).collect::<Vec<_>>().join(", ")
        };
        warnings.push(format!(
            "the near-field model misses the data at {} in (residual RMS {} counts against the \
             noise's {}; {} standard deviations beyond it): the data hold an effect the chip's \
             model cannot represent (a plate tilt or offset, saturation, cross-talk, ...), and \
             d and p may have absorbed part of it beyond their 1-sigma. `cta analyze {}` names \
             it.",
            list(&|b| b.separation_in.to_string()),
            list(&|b| format!("{:.1}", b.near_field_counts)),
            list(&|b| format!("{:.1}", b.noise_counts)),
            list(&|b| format!("{:.0}", b.near_field_z)),
            all.path.display()
        ));
    }
    // A head turned about its boresight (or X and Y read so) fits as well as a square one:
    // the head's attitude in the file, with the pinhole H it goes with.
    warnings.extend(wiring::turned_head_note(
        cal.p.map(f64::from),
        Some(f64::from(cal.h)),
    ));
    // A file with every length in cm or mm fits perfectly, with s and d scaled so.
    if let Some(note) = wiring::s_unit_note(nf.x[7], "s") {
        warnings.push(note);
    }
    if pinned > 0 {
        warnings.push(format!(
            "{pinned} points left out: an output pinned at +/-32767, or its mean within 3 sigma \
             of it (a cell in shadow or saturated), carries no position information"
        ));
    }
    for b in &by_separation {
        if b.pinhole_counts.is_none() {
            warnings.push(format!(
                "at {} in the pinhole model puts beacons behind the head: its RMS there is not \
                 given",
                b.separation_in
            ));
        }
    }
    let mut sigma: BTreeMap<String, f64> = NF_NAMES
        .iter()
        .zip(nf.sigma)
        .map(|(n, s)| (n.to_string(), s))
        .collect();
    sigma.insert("H".into(), ph.sigma["H"]);
    for n in ["d1", "d2", "d3", "p1", "p2", "p3"] {
        sigma.insert(format!("pinhole.{n}"), ph.sigma[n]);
    }
    Ok(CalibrationReport {
        file: CalibrationFile {
            calibration: cal,
            fitted: Provenance {
                by: format!("{WRITER} {}", env!("CARGO_PKG_VERSION")),
                source: all.path.display().to_string(),
                separations: seps,
                pinhole_separations: ph.separations.clone(),
                sigma,
                chi2_dof: nf.chi2_dof,
                rms_counts: rms,
                points: pts.len(),
                pinned_points: pinned,
                glitches_left_out: 0,
                correlations: nf.correlations.clone(),
            },
            led_brightness: Vec::new(),
        },
        pinhole_h: xp.h(),
        pinhole_chi2_dof,
        pinhole_warnings: ph.warnings.clone(),
        noise_source,
        iterations: nf.iterations,
        condition: nf.condition,
        by_separation,
        warnings,
        data_notes: Vec::new(),
        magnitude: None,
        magnitude_note: Some("not fitted".into()),
    })
}

/// Fit the spot magnitude law ([`crate::fit::magnitude`]) to the magnitudes of `ds` (the
/// near-field fit's data) with the head `rep`'s calibration holds, at `sensitivity` (default:
/// the file's most common), and put it into `rep`: the calibration's `magnitude`, the file's
/// `led_brightness`, the 1-sigma `magnitude.offset` and `magnitude.exponent` in
/// `fitted.sigma`. A file whose magnitudes give no law leaves the calibration without one and
/// says why in [`CalibrationReport::magnitude_note`]; an error only for a `sensitivity` the
/// file does not have.
pub fn fit_magnitude(
    rep: &mut CalibrationReport,
    ds: &Dataset,
    sensitivity: Option<u8>,
) -> Result<()> {
    let em = cta_firmware_sensor::sim::physics(&rep.file.calibration);
    match crate::fit::magnitude::fit_dataset(ds, &em, sensitivity)? {
        Outcome::Law(m) => {
            let mut cal = rep.file.calibration;
            cal.magnitude = Some(m.law);
            cal.validate()
                .map_err(|e| anyhow!("{}: the magnitude law: {e}", ds.path.display()))?;
            rep.file.calibration = cal;
            rep.file.led_brightness = m.led_brightness.clone();
            let sigma = &mut rep.file.fitted.sigma;
            if let Some(s) = m.offset_sigma {
                sigma.insert("magnitude.offset".into(), s);
            }
            sigma.insert("magnitude.exponent".into(), m.exponent_sigma);
            rep.magnitude = Some(*m);
            rep.magnitude_note = None;
        }
        Outcome::NoLaw(why) => {
            rep.file.calibration.magnitude = None;
            rep.file.led_brightness.clear();
            rep.magnitude = None;
            rep.magnitude_note = Some(why);
        }
    }
    Ok(())
}

/// `--out` may replace an earlier calibration written by `cta calibrate`; never the
/// measurement file, and anything else only with `--force`.
fn check_out(out: &Path, data: &Path, force: bool) -> Result<()> {
    let earlier = |p: &Path| {
        std::fs::read_to_string(p)
            .ok()
            .and_then(|s| serde_json::from_str::<CalibrationFile>(&s).ok())
            .is_some_and(|f| f.fitted.by.starts_with(WRITER))
    };
    crate::data::check_derived_output(
        "--out",
        out,
        data,
        "cal.json",
        "an earlier `cta calibrate` calibration",
        earlier,
        force,
    )
}

/// Run `cta calibrate`.
pub fn run(a: &CalibrateArgs) -> Result<()> {
    if let Some(out) = &a.out {
        check_out(out, &a.file, a.force)?;
    }
    if let Some(p) = &a.plot {
        crate::plot::check_plot_path(p)?;
    }
    if let Some(v) = a.noise {
        if !(v.is_finite() && v > 0.0) {
            bail!("--noise {v}: a positive number of counts");
        }
    }
    let (mut all, warnings) = crate::sweep::read_measurements(&a.file).map_err(|e| anyhow!("{e}"))?;
    for w in warnings {
        eprintln!("warning: {w}");
    }
    // `cta analyze --drop-glitches`'s rule, on the whole file: the pinhole stage may take
    // separations --separations leaves out.
    let mut dropped = None;
    if a.drop_glitches {
        if let Some(clean) = all.without_glitches() {
            dropped = Some((clean.samples, clean.note()));
            all = clean.data;
        }
    }
    let ds = match &a.separations {
        None => all.clone(),
        Some(s) => {
            let seps = parse_separations(s).map_err(|e| anyhow!("--separations: {e}"))?;
            all.select(&seps)
                .map_err(|e| anyhow!("--separations: {e}"))?
        }
    };
    let ph = match &a.pinhole_separations {
        None => None,
        Some(s) => Some(parse_separations(s).map_err(|e| anyhow!("--pinhole-separations: {e}"))?),
    };
    let mut rep = calibrate(&ds, &all, ph.as_deref(), a.noise, a.pattern_m)?;
    if a.no_magnitude {
        rep.magnitude_note = Some("left out (--no-magnitude)".into());
    } else {
        fit_magnitude(&mut rep, &ds, a.magnitude_sensitivity)?;
    }
    if let Some((n, note)) = dropped {
        rep.file.fitted.glitches_left_out = n;
        rep.data_notes.push(note);
    }
    // Written as every `cta` output is (missing folders created); the report is printed
    // whether or not the writes succeed, and a failed write is the error after it.
    let saved = match &a.out {
        Some(out) => {
            let json = serde_json::to_string_pretty(&rep.file)?;
            crate::data::write_output(out, json.as_bytes())
                .map_err(|e| anyhow!("{e}; the calibration above was not saved"))
                .map(|()| Some(out.as_path()))
        }
        None => Ok(None),
    };
    let plotted = match &a.plot {
        Some(p) => plot(&rep, p).map_err(|e| anyhow!("{e}; the plot was not written")),
        None => Ok(()),
    };
    if a.json {
        println!("{}", serde_json::to_string_pretty(&rep)?);
    } else {
        print_report(&rep, saved.as_ref().map(|o| o.as_deref()).ok());
    }
    saved?;
    plotted
}

/// The residual RMS per separation of both models and the noise's, on a log scale.
fn plot(rep: &CalibrationReport, path: &Path) -> Result<()> {
    use crate::plot::{write_svg, Panel, Series};
    let by = &rep.by_separation;
    let series = vec![
        Series::new(
            "pinhole (eq 65)",
            by.iter()
                .filter_map(|b| b.pinhole_counts.map(|v| (b.separation_in, v)))
                .collect(),
        ),
        Series::new(
            "near-field (eqs 60-63), the chip's model",
            by.iter()
                .map(|b| (b.separation_in, b.near_field_counts))
                .collect(),
        ),
        Series::dashed(
            "noise (RMS error of a point mean)",
            by.iter()
                .map(|b| (b.separation_in, b.noise_counts))
                .collect(),
        ),
    ];
    let f = &rep.file.fitted;
    write_svg(
        path,
        &format!(
            "Calibration residuals, {}: chi2/dof {:.2}",
            Path::new(&f.source)
                .file_name()
                .map_or(f.source.clone(), |n| n.to_string_lossy().into_owned()),
            f.chi2_dof
        ),
        &[Panel {
            title: "residual RMS of the point means per separation".into(),
            x_desc: "separation (in)".into(),
            y_desc: "RMS (counts)".into(),
            log_x: false,
            log_y: true,
            series,
        }],
        1,
    )
}

/// `out`: `Some(Some(path))` written, `Some(None)` not asked for, `None` its write failed (the
/// error follows the report).
fn print_report(rep: &CalibrationReport, out: Option<Option<&Path>>) {
    let f = &rep.file.fitted;
    let c = &rep.file.calibration;
    let nf = c.near_field.unwrap_or(NearField::nominal());
    let seps = match f.separations.as_slice() {
        [a, .., b] if f.separations.len() > 6 => {
            format!("{} separations, {a}-{b} in", f.separations.len())
        }
        v => format!("{} in", fmt_list(v)),
    };
    println!(
        "Sensor calibration from {} ({} points at {seps}; {} left out)",
        f.source, f.points, f.pinned_points
    );
    for n in &rep.data_notes {
        println!("  note: {n}");
    }
    // Each estimate to the digits its 1-sigma resolves (`cta analyze`'s convention).
    let pm = |v: f32, n: &str| crate::analyze::digits::pm_parts(f64::from(v), f.sigma[n]);
    let (h, hs) = crate::analyze::digits::pm_parts(rep.pinhole_h, f.sigma["H"]);
    println!(
        "  pinhole (eq 65) at {} in: H = {h} ± {hs} counts (chi2/dof {:.2})",
        fmt_list(&f.pinhole_separations),
        rep.pinhole_chi2_dof,
    );
    if let Some(ph) = &c.pinhole {
        let v = |a: &[f32; 3], n: &str| {
            (0..3)
                .map(|k| {
                    let (v, s) = pm(a[k], &format!("pinhole.{n}{}", k + 1));
                    format!("{v} ± {s}")
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        println!(
            "    its d = {} in (its eye point, not the head: README, \"virtual eye\")",
            v(&ph.d, "d")
        );
        println!("    its p = {}", v(&ph.p, "p"));
        println!(
            "    (in the file as `pinhole`: the chip's pinhole model uses this d, p with this H)"
        );
    }
    println!("  near-field (eqs 60-63), started from it:");
    let row = |n: &str, v: f32, unit: &str, what: &str| {
        let (v, s) = pm(v, n);
        let line = format!("    {n:<2} = {v:>12} ± {s:<9} {unit:<5} {what}");
        println!("{}", line.trim_end());
    };
    for (k, n) in ["d1", "d2", "d3"].iter().enumerate() {
        row(n, c.d[k], "in", "");
    }
    for (k, n) in ["p1", "p2", "p3"].iter().enumerate() {
        row(n, c.p[k], "", "");
    }
    let ay = nf.face_angles_deg()[1];
    row("a", nf.alpha_deg, "deg", "(face angle, X pair; 30 nominal)");
    row("ay", ay, "deg", "(face angle, Y pair; 30 nominal)");
    row("s", nf.s, "in", "(cell offset; 0.175 nominal)");
    row("gx", nf.gain[0], "", "(cell 1 gain - 1; 0 nominal)");
    row("gy", nf.gain[1], "", "(cell 3 gain - 1; 0 nominal)");
    row("bx", nf.bias[0], "/in2", "(cell 1 offset; 0 nominal)");
    row("by", nf.bias[1], "/in2", "(cell 3 offset; 0 nominal)");
    println!(
        "    held: beta = {}, beacon pattern m = {}; noise = {:.2} counts ({})",
        nf.beta, nf.pattern_m, c.noise, rep.noise_source
    );
    println!(
        "  chi2/dof {:.3}, residual RMS {:.2} counts, {} iterations, condition {:.2e}",
        f.chi2_dof, f.rms_counts, rep.iterations, rep.condition
    );
    if !f.correlations.is_empty() {
        println!(
            "  strongly correlated (each 1-sigma above is marginal): {}",
            f.correlations
                .iter()
                .map(|(a, b, r)| format!("{a},{b} {r:+.2}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    println!("\n sep(in)  points   RMS pinhole  near-field   noise (counts, point means)");
    for b in &rep.by_separation {
        let line = format!(
            " {:>7}  {:>6}  {:>12}  {:>10.2}  {:>6.2}  {}",
            b.separation_in,
            b.points,
            b.pinhole_counts
                .map(|v| format!("{v:.2}"))
                .unwrap_or_else(|| "-".into()),
            b.near_field_counts,
            b.noise_counts,
            if b.near_field_z > MISFIT_Z {
                format!("<- near-field misses ({:.0} sd)", b.near_field_z)
            } else {
                String::new()
            }
        );
        println!("{}", line.trim_end());
    }
    print_magnitude(rep);
    for w in rep.pinhole_warnings.iter().chain(&rep.warnings) {
        println!("warning: {w}");
    }
    if !rep.warnings.iter().any(|w| w.contains("cta analyze")) {
        println!(
            "note: the 1-sigma above hold if the data hold no effect outside the chip's model; \
             an apparatus error such as a small plate tilt is absorbed by d and p without \
             showing here. `cta analyze {}` checks for it.",
            rep.file.fitted.source
        );
    }
    match out {
        Some(Some(p)) => println!(
            "\nwritten to {}: load it with `cta sensor --port PORT load-calibration {}`",
            p.display(),
            p.display()
        ),
        Some(None) => println!("\n(not written: give --out CAL.json)"),
        None => {}
    }
}

/// The magnitude law's section of the report: the law with its 1-sigma, the noise, the LEDs'
/// brightness, what was used and left out, the residuals per separation and the warnings; or
/// one line saying why there is none.
fn print_magnitude(rep: &CalibrationReport) {
    let Some(m) = &rep.magnitude else {
        if let Some(n) = &rep.magnitude_note {
            println!("\n  spot magnitudes: no law ({n})");
        }
        return;
    };
    let l = &m.law;
    let unit = if m.counts { " counts" } else { "" };
    println!(
        "\n  spot magnitudes (sensitivity {}): {} samples, {} points, {} LEDs at {} in",
        l.sensitivity,
        m.samples,
        m.points,
        m.led_brightness.len(),
        match m.separations.as_slice() {
            [a, .., b] if m.separations.len() > 6 => {
                format!("{} separations, {a}-{b}", m.separations.len())
            }
            v => fmt_list(v),
        }
    );
    let offset = match m.offset_sigma {
        _ if m.offset_at_zero => format!(
            "0 (its bound; 1-sigma {})",
            m.offset_sigma
                .map_or("undetermined".into(), |s| format!("{s:.2e}"))
        ),
        Some(s) => {
            let (v, s) = crate::analyze::digits::pm_parts(f64::from(l.offset), s);
            format!("{v} ± {s}")
        }
        None => format!("{:.1} (undetermined)", l.offset),
    };
    let (g, gs) = crate::analyze::digits::pm_parts(f64::from(l.exponent), m.exponent_sigma);
    println!("    M = offset + A (b S)^exponent: offset = {offset}{unit}, exponent = {g} ± {gs}");
    println!(
        "    noise {:.3} % of M - offset per reading (within points {:.3} %, points about the \
         law {:.3} %{}); readings at or above {} taken as saturated",
        l.noise_percent,
        m.noise_within_percent,
        m.noise_between_percent,
        if m.counts { "; rounding apart" } else { "" },
        l.max
    );
    println!(
        "    LED brightness b: {:.3}-{:.3}, RMS {:.1} % about 1 (in the file as `led_brightness`, \
         for `cta sensor load-constellation --brightness`)",
        m.brightness_min, m.brightness_max, m.brightness_rms_percent
    );
    if m.settings.len() > 1 {
        let what = |s: &crate::fit::magnitude::SettingLight| {
            let mut w = Vec::new();
            if let Some(p) = s.power {
                w.push(format!("power {p}"));
            }
            if let Some(f) = s.frequency_hz {
                w.push(format!("{f} Hz"));
            }
            w.join(", ")
        };
        println!(
            "    light per drive setting, relative to {}: {}",
            what(&m.settings[0]),
            m.settings[1..]
                .iter()
                .map(|s| format!("{} {:.4} ± {:.4}", what(s), s.light, s.sigma))
                .collect::<Vec<_>>()
                .join("; ")
        );
    }
    let by = &m.by_separation;
    if by.len() <= 10 {
        println!(
            "    residual RMS per separation (%): {}",
            by.iter()
                .map(|b| format!("{} in {:.3}", b.separation_in, b.rms_percent))
                .collect::<Vec<_>>()
                .join(", ")
        );
    } else {
        let rms = by.iter().map(|b| b.rms_percent);
        println!(
            "    residual RMS per separation: {:.3}-{:.3} % (each in --json)",
            rms.clone().fold(f64::INFINITY, f64::min),
            rms.fold(0.0, f64::max)
        );
    }
    let mut left = Vec::new();
    if m.saturated_points > 0 {
        left.push(format!(
            "{} saturated points ({} readings at or above {})",
            m.saturated_points, m.saturated_samples, l.max
        ));
    }
    if m.pinned_points > 0 {
        left.push(format!(
            "{} points with an output at the 16-bit rail",
            m.pinned_points
        ));
    }
    if m.no_signal_points > 0 {
        left.push(format!("{} points without signal", m.no_signal_points));
    }
    if m.other_sensitivity_samples > 0 {
        left.push(format!(
            "{} samples at other sensitivities ({}; --magnitude-sensitivity chooses)",
            m.other_sensitivity_samples,
            m.sensitivities
                .iter()
                .filter(|(k, _)| *k != l.sensitivity)
                .map(|(k, n)| format!("{k}: {n}"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    if !left.is_empty() {
        println!("    left out: {}", left.join("; "));
    }
    for w in &m.warnings {
        println!("warning: spot magnitudes: {w}");
    }
}
