//! `cta calibrate`: the sensor board's calibration from a measured CTA sweep, written as the
//! JSON file `cta sensor load-calibration` stores in the board's flash.
//!
//! Two fits, as the lab would do them by hand (REFERENCE.md: start the near-field fit from
//! the 7-parameter fit to avoid false minima):
//!
//! 1. **Pinhole** (eq 65, `d, p, H`; [`crate::fit::fit_observations`]) on the far separations
//!    (25 and 30 in when the file has them, or measured values within 0.1 in, else its two
//!    largest): the chip's `pinhole` model (its `H`, and its `d, p` as the calibration's
//!    [`Calibration::pinhole`]) and the near-field fit's start, its point means weighted as
//!    the near-field fit's.
//! 2. **Near-field** (eqs 60-63: `d, p`, the face angles, the cell offset `s`, the cell gains
//!    of [`NearField::gain`] and offsets of [`NearField::bias`], `beta` and the beacon pattern
//!    held; [`fit_near_field`]) on every point of every separation. Points are the means of
//!    their repeated samples weighted by `n / sigma^2`, `sigma` the one-sample noise pooled
//!    per separation and axis (absolute weights: chi2/dof is 1 when the model explains the
//!    data to the noise); points with a pinned output carry no position information and are
//!    left out.
//! 3. **Spot magnitudes** ([`fit_magnitude`], [`crate::fit::magnitude`]): the law
//!    `M = offset + A (b S)^exponent` of [`Calibration::magnitude`], `S` the eq 63 summed cell
//!    signal of the fitted head, at one sensitivity setting.
//!
//! The calibration's `noise` (the chip's per-coordinate 1-sigma) is the one-sample noise
//! pooled over the file. A chi2/dof well above 1 means the data hold structure the chip's
//! model cannot represent: `cta analyze` names it.

pub mod covariance;
mod error;
mod file;
mod report;

pub use super::nearfield::{
    fit_near_field, NearFieldError, NearFieldFit, NearFieldSolution, NfObs, NF_NAMES, NF_PARAMS,
    STRONG_CORRELATION,
};
pub use error::{Error, NearFieldFailed};
pub use file::{check_out, CalibrationFile, Provenance, WRITER};
pub use report::{CalibrationReport, SeparationRms, MISFIT_Z};

use std::collections::BTreeMap;
use std::path::Path;

use cta_core::collinearity::{self, ParamsExt};
use cta_core::pose::{CalField, Calibration, ConfigError, NearField, PinholeHead};
use nalgebra::Vector3;

use crate::data::weights::{self, misfit_warning, Pooled, Weights, CHI2_WARN};
use crate::data::{any_sample_pinned, fmt_list, mean_near_rail, Dataset};
use crate::fit;
use crate::fit::magnitude::Outcome;
use crate::fit::wiring;

/// Closest near-field separation, inches, from which on a calibration out of the board's range
/// is put down to the separations rather than the data: the face angle and cell offset show
/// in how the outputs change close in (a fit of 25 and 30 in alone leaves s free).
const FAR_ONLY_IN: f64 = 10.0;

/// What `cta calibrate` fits, and to which data ([`calibrate_file`]).
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateOptions {
    /// Separations of the near-field fit (`None`: every separation in the file).
    pub separations: Option<Vec<f64>>,
    /// Separations of the pinhole fit (`None`: 25 and 30 in when the file has both, else its
    /// two largest).
    pub pinhole_separations: Option<Vec<f64>>,
    /// One-sample noise of a coordinate, counts (`None`: measured from repeated samples).
    pub noise: Option<f64>,
    /// Beacon pattern exponent `m` of the LEDs (`cos^m`), held in the fit.
    pub pattern_m: f64,
    /// Leave out the samples the glitch check flags ([`Dataset::without_glitches`]).
    pub drop_glitches: bool,
    /// Fit the spot magnitude law ([`fit_magnitude`]).
    pub magnitude: bool,
    /// The sensitivity setting whose magnitudes the law is fitted to (`None`: the file's most
    /// common).
    pub magnitude_sensitivity: Option<u8>,
}

impl Default for CalibrateOptions {
    fn default() -> Self {
        CalibrateOptions {
            separations: None,
            pinhole_separations: None,
            noise: None,
            pattern_m: 1.0,
            drop_glitches: false,
            magnitude: true,
            magnitude_sensitivity: None,
        }
    }
}

/// Calibrate from the whole measurement file `all` as `opts` say: the glitches left out, the
/// near-field separations selected, both fits ([`calibrate`]) and the magnitude law
/// ([`fit_magnitude`]).
pub fn calibrate_file(all: Dataset, opts: &CalibrateOptions) -> Result<CalibrationReport, Error> {
    let mut all = all;
    // `cta analyze --drop-glitches`'s rule, on the whole file: the pinhole stage may take
    // separations the near-field selection leaves out.
    let mut dropped = None;
    if opts.drop_glitches {
        if let Some(clean) = all.without_glitches() {
            dropped = Some((clean.samples, clean.note()));
            all = clean.data;
        }
    }
    let ds = match &opts.separations {
        None => all.clone(),
        Some(seps) => all.select(seps).map_err(Error::Separations)?,
    };
    let mut rep = calibrate(
        &ds,
        &all,
        opts.pinhole_separations.as_deref(),
        opts.noise,
        opts.pattern_m,
    )?;
    if opts.magnitude {
        fit_magnitude(&mut rep, &ds, opts.magnitude_sensitivity)?;
    } else {
        rep.magnitude_note = Some("left out (--no-magnitude)".into());
    }
    if let Some((n, note)) = dropped {
        rep.file.fitted.glitches_left_out = n;
        rep.data_notes.push(note);
    }
    Ok(rep)
}

/// Calibrate from a dataset (already restricted to the near-field separations). `all` is
/// the whole file, for the pinhole fit's separations.
pub fn calibrate(
    ds: &Dataset,
    all: &Dataset,
    pinhole_seps: Option<&[f64]>,
    noise_arg: Option<f64>,
    pattern_m: f64,
) -> Result<CalibrationReport, Error> {
    let seps = ds.separations();
    if seps.len() < 2 {
        return Err(Error::TooFewSeparations {
            path: ds.path.clone(),
            separations: seps,
        });
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
        (Some(v), _) => (v, format!("--noise {} counts", shown(v))),
        (None, Some(v)) => (
            v,
            "measured: one-sample noise of the repeated samples, pooled over the file".into(),
        ),
        (None, None) => {
            return Err(Error::NoiseUnmeasured {
                path: ds.path.clone(),
            })
        }
    };
    if !(noise.is_finite() && (0.01..=10_000.0).contains(&noise)) {
        return Err(Error::NoiseRange {
            noise,
            path: noise_arg.is_none().then(|| ds.path.clone()),
        });
    }
    if !(pattern_m.is_finite() && (0.0..=50.0).contains(&pattern_m)) {
        return Err(Error::PatternM(pattern_m));
    }
    // A point whose mean lies within 3 sigma of the rail had its true output at or past it
    // (a cell in shadow) and only its noise kept some samples inside: it is left out with
    // the pinned ones. (With a cell offset, a pair in shadow reads the rail, where the
    // model without the offset has no output at all.)
    let before = pts.len();
    pts.retain(|p| !mean_near_rail(p.mean, noise, p.n));
    pinned += before - pts.len();
    if pts.len() < 8 {
        return Err(Error::TooFewPoints {
            path: ds.path.clone(),
            usable: pts.len(),
            pinned,
        });
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
        .map_err(Error::PinholeSeparations)?;
    // Weighted as the near-field stage is: the noise pooled per separation and axis (or
    // --noise), never each point's own few samples, whose inverse variances are too rough to
    // weight by (they bias H low). A pinhole separation outside --separations has its noise
    // pooled from the pinhole data.
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
        .map_err(|e| Error::PinholeFit {
            separations: pinhole_seps.clone(),
            why: e.to_string(),
            diagnosis: wiring::diagnose(all),
        })?;
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
                (Err(first), Err(second)) => {
                    return Err(Error::NearField(Box::new(NearFieldFailed {
                        path: ds.path.clone(),
                        first,
                        nominal_d: d(&nominal),
                        second,
                        cause: match &far_only {
                            Some(cause) => cause.clone(),
                            None => format!(
                                "The data do not look like a NorthStar on the CTA (check the \
                                 file's columns, units and --pattern-m; `cta analyze {}` shows \
                                 what the models miss)",
                                ds.path.display()
                            ),
                        },
                        diagnosis: wiring::diagnose(all),
                    })))
                }
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
        Error::OutOfRange {
            path: ds.path.clone(),
            error: e,
            value,
            cause,
            unit,
        }
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
                covariance: Some(covariance::Covariance::near_field(&nf.covariance)),
                run: None,
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
) -> Result<(), Error> {
    let em = cta_firmware_sensor::sim::physics(&rep.file.calibration);
    match crate::fit::magnitude::fit_dataset(ds, &em, sensitivity)? {
        Outcome::Law(m) => {
            let mut cal = rep.file.calibration;
            cal.magnitude = Some(m.law);
            cal.validate().map_err(|error| Error::MagnitudeLaw {
                path: ds.path.clone(),
                error,
            })?;
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

/// Write the calibration file of `rep` (what `cta sensor load-calibration` reads) to `out`,
/// as every `cta` output is written (missing folders created).
pub fn save(rep: &CalibrationReport, out: &Path) -> Result<(), Error> {
    let json = serde_json::to_string_pretty(&rep.file)?;
    crate::data::write_output(out, json.as_bytes()).map_err(Error::Write)
}

/// Draw the residual RMS per separation of both models and the noise's, on a log scale, as
/// an SVG at `path`.
pub fn plot(rep: &CalibrationReport, path: &Path) -> Result<(), Error> {
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
    .map_err(Error::Plot)
}

/// A number for a message, to 4 significant digits (`0.0000000000005312494315246781` is
/// `5.312e-13`; `32.768` stays `32.768`; NaN and infinities as Rust writes them).
pub(crate) fn shown(v: f64) -> String {
    if !v.is_finite() || v == 0.0 {
        return format!("{v}");
    }
    let mag = v.abs().log10().floor() as i32;
    if !(-3..6).contains(&mag) {
        return format!("{v:.3e}");
    }
    let decimals = (3 - mag).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}
