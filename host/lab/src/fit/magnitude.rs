//! The spot magnitude law from a CTA sweep: what `cta calibrate` writes as the calibration's
//! [`Magnitude`] (and each LED's relative brightness), so that the on-chip near-field pose
//! weighs the NorthStar's magnitudes by what they proved to be worth.
//!
//! # Model
//!
//! The chip's law ([`Magnitude`]) is `M = offset + A (b S)^exponent`: `S` the summed cell
//! signal of the eq 60-63 model (eq 63's `sum_k c_k I_k V_k` over the four cells, 1/in^2,
//! [`Emulator::magnitude`]) at the beacon's position, computed with the head the near-field
//! fit found; `b` the LED's brightness; `A` a scale common to a frame. Taking logarithms,
//!
//! `ln(M - offset) = exponent ln S + c_led + c_setting`
//!
//! with one constant `c_led` per LED (its brightness and the common scale together: the
//! `beacon` column when the file has it, else the LED's `(x, y)`) and, when the file holds
//! several drive settings (power level, modulation frequency) at the fitted sensitivity, one
//! constant per setting (the first is 0). For a fixed `offset` this is linear least squares (a
//! one-way analysis of covariance: the exponent from the within-LED regression on `ln S`, each
//! constant from its LED's means), solved with the LED constants eliminated.
//!
//! The points are the means of their repeated samples. A point mean's variance, in `ln`, is
//! `tau^2 + (rel_w^2 + q / D^2) / n`: `rel_w` the samples' scatter about their own mean in
//! relative terms (pooled over the points, the rounding to whole counts, `q = 1/12` counts^2,
//! taken out), `tau` the scatter of the points about the law beyond it (the law's misfit, LED
//! flicker between points), set so that chi-square equals its degrees of freedom (Paule and
//! Mandel's estimator), `D = M - offset`, `n` the samples. Weak readings dominated by rounding
//! thus weigh little. The offset is searched from 0 to a count below the smallest point mean
//! (to a thousandth of it below, for magnitudes that are not whole counts) for the least
//! `-2 ln L` of the point means in the magnitudes' own units (the residuals' chi-square,
//! `sum ln V`, and the Jacobian `2 sum ln D` of the logarithm), over a grid and then by golden
//! section. Its 1-sigma comes from the curvature of that profile; the exponent's and the
//! brightnesses' from the linear fit, with the offset's uncertainty carried through. Points
//! with an output coordinate at the 16-bit rail are left out, as the near-field fit leaves
//! them out.
//!
//! The law's `noise_percent` is the scatter of one reading about the law, `sqrt(rel_w^2 +
//! tau^2)` in percent (the rounding left out: the chip adds 1/12 counts^2 itself), floored at
//! 0.001 %, the least the board takes. `max` is the largest reading used: readings at 65535,
//! or piled up at the file's largest value (read at 3 or more points), are saturated, and
//! every point with such a reading is left out.
//!
//! # Assumptions
//!
//! The model's `S` is right (the near-field fit's head and the Lambertian beacon pattern);
//! the LEDs' patterns are alike (a brightness is one number per LED); the scatter is relative
//! to `M - offset`; one sensitivity setting at a time (the chip uses the law only at the
//! setting it was fitted at). A law of another shape leaves residuals that trend with the
//! separation, which the report warns about (allowing for a separation's +/-5 mil: `S`
//! falls as its square, and within a frame the pose's `A` takes up such an error).

use std::collections::BTreeMap;

use cta_core::emulator::Emulator;
use cta_core::pose::{Magnitude, MAX_BRIGHTNESS, MIN_BRIGHTNESS};
use nalgebra::{DMatrix, DVector, Vector3};
use serde::{Deserialize, Serialize};

use crate::data::{any_sample_pinned, fmt_list, Dataset};

/// The normal equations of the law's linear fit are singular.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("the normal equations are singular")]
pub struct Singular;

/// Why the law cannot be fitted to a set of points ([`fit_law`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LawError {
    /// A point names an LED or setting beyond the counts given.
    #[error("a point's LED {led} or setting {setting} is out of range")]
    OutOfRange {
        /// Its LED index.
        led: usize,
        /// Its setting index.
        setting: usize,
    },
    /// A point without readings or without model signal.
    #[error("a point at {separation_in} in has no readings or no model signal")]
    NoSignal {
        /// Its separation, inches.
        separation_in: f64,
    },
    /// No point at the first (reference) setting.
    #[error("no point at the reference setting")]
    NoReference,
    /// Every LED is read at one signal only.
    #[error(
        "no LED is read at two or more signals (separations): the exponent cannot be told \
         from the LEDs' brightness"
    )]
    OneSignal,
    /// Fewer points than parameters.
    #[error(
        "{points} points for {parameters} parameters (the exponent, {constants} LED and \
         setting constants, the offset and the scatter)"
    )]
    TooFewPoints {
        /// Points.
        points: usize,
        /// Parameters.
        parameters: usize,
        /// LED and setting constants among them.
        constants: usize,
    },
    /// A point's mean reading is not above 0.
    #[error("a point's mean reading is not above 0")]
    NotPositive,
    /// The linear fit is singular at some offset.
    #[error(transparent)]
    Singular(#[from] Singular),
    /// The exponent, the LEDs' and the settings' constants cannot all be told apart.
    #[error(
        "the normal equations are singular: the exponent, the LEDs' and the drive settings' \
         constants cannot all be told apart (a power level or frequency measured only on LEDs \
         no other one has?)"
    )]
    SettingsIndistinct,
    /// The exponent cannot be told from the LEDs' constants.
    #[error(
        "the normal equations are singular: the exponent cannot be told from the LEDs' constants"
    )]
    LedsIndistinct,
}

/// Why a file's magnitudes cannot be fitted as asked ([`fit_dataset`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MagnitudeError {
    /// The file has no magnitudes at the sensitivity asked for.
    #[error(
        "--magnitude-sensitivity {sensitivity}: {file} has no magnitudes at sensitivity \
         {sensitivity} (it has {})",
        have.iter()
            .map(|(k, n)| format!("{k}: {n} samples"))
            .collect::<Vec<_>>()
            .join(", ")
    )]
    NoSensitivity {
        /// The sensitivity asked for.
        sensitivity: u8,
        /// The measurement file.
        file: String,
        /// Its sensitivities with their samples.
        have: Vec<(u8, usize)>,
    },
}

/// The least `noise_percent` the board takes (its validation floor), as a fraction.
pub const NOISE_FLOOR: f64 = 1e-5;

/// The variance of rounding to whole counts, counts^2.
const ROUNDING: f64 = 1.0 / 12.0;

/// Spread of a point's readings (variance, counts^2) from which their rounding to counts acts
/// as noise of its own (Sheppard's 1/12 then holds to a few percent): a count. Readings that
/// straddle one rounding boundary spread by up to half a count with almost no scatter of their
/// own, and would read as a scatter of 0.2-0.3 % at 150 counts.
const DITHER: f64 = 1.0;

/// The highest reading a NorthStar can give (16 bits).
pub const RAIL: f64 = 65535.0;

/// A reading piled up at the file's largest value at this many points or more is taken as
/// saturation.
const PILE_UP_POINTS: usize = 3;

/// Above this noise (percent) the magnitudes carry little weight in the pose.
pub const NOISY_PERCENT: f64 = 1.0;

/// Residuals that trend with the separation more than this many standard deviations beyond
/// chance are reported (as `cta calibrate`'s [`crate::fit::calibrate::MISFIT_Z`]).
const TREND_Z: f64 = 5.0;

/// How well a separation is known, inches: Ch IV's +/-5 mils (plates leveled to 5 mils per
/// foot, corners read to 1 mil). `S` falls as the separation squared, so a separation's mean
/// residual may be off by `2 x 0.005 / separation` (0.07 % at 14 in) without the law being
/// wrong; the trend test allows for it. (Within a frame that error is common to every beacon
/// and the pose's scale `A` takes it up.)
const SEPARATION_UNCERTAINTY_IN: f64 = 0.005;

/// One point of the fit: an LED at one separation and setting, its model signal and its
/// readings.
#[derive(Debug, Clone, PartialEq)]
pub struct MagPoint {
    /// Which LED (`0..leds`).
    pub led: usize,
    /// Which drive setting (`0..settings`; 0 is the reference).
    pub setting: usize,
    /// The separation, inches (for the per-separation residuals).
    pub separation_in: f64,
    /// The model's summed cell signal `S` at the beacon (1/in^2), above 0.
    pub s: f64,
    /// The readings (none saturated), at least one.
    pub readings: Vec<f64>,
}

/// A fitted law, in the fitter's terms.
#[derive(Debug, Clone)]
pub struct LawFit {
    /// The offset, in the readings' units.
    pub offset: f64,
    /// Its 1-sigma (`inf` when the data do not determine it).
    pub offset_sigma: f64,
    /// Whether the offset ended at the lower bound 0.
    pub offset_at_zero: bool,
    /// The exponent.
    pub exponent: f64,
    /// Its 1-sigma (the offset's uncertainty included).
    pub exponent_sigma: f64,
    /// Relative scatter of the samples about their points' means, rounding taken out.
    pub rel_within: f64,
    /// Relative scatter of the points about the law beyond that (`tau`).
    pub rel_between: f64,
    /// `ln` of each LED's brightness (normalised to a geometric mean of 1 over the LEDs with
    /// points), `None` for an LED without points.
    pub ln_brightness: Vec<Option<f64>>,
    /// 1-sigma of each `ln_brightness`.
    pub ln_brightness_sigma: Vec<Option<f64>>,
    /// `ln` of each setting's light relative to setting 0 (`c_setting / exponent`), with its
    /// 1-sigma; `None` for a setting without points.
    pub ln_setting: Vec<Option<(f64, f64)>>,
    /// Per point (in the input order): the residual `ln(D) - model` and its standard error.
    pub residuals: Vec<(f64, f64)>,
    /// Whether the rounding term was used (readings in whole counts).
    pub counts: bool,
}

impl LawFit {
    /// Per-sample scatter about the law (fraction), floored at [`NOISE_FLOOR`].
    pub fn rel(&self) -> f64 {
        (self.rel_within.powi(2) + self.rel_between.powi(2))
            .sqrt()
            .max(NOISE_FLOOR)
    }
}

/// The point data prepared once: `ln S`, sample counts, means and sums of squares.
struct Prepared<'a> {
    points: &'a [MagPoint],
    x: Vec<f64>,
    n: Vec<f64>,
    mean: Vec<f64>,
    ss: Vec<f64>,
    q: f64,
    leds: usize,
    settings: usize,
    /// Degrees of freedom of the residuals.
    dof: f64,
}

/// The linear fit at one offset and one set of variances.
struct Wls {
    /// Exponent, then the settings' constants (1..).
    theta: DVector<f64>,
    /// LED constants (0 for an LED without points).
    c: Vec<f64>,
    /// Weighted residual sum of squares.
    chi2: f64,
    resid: Vec<f64>,
    /// `S^-1` of the reduced (LED constants eliminated) normal matrix.
    s_inv: DMatrix<f64>,
    /// `B D^-1`, small parameters x LEDs.
    g: DMatrix<f64>,
    /// `1 / D` per LED (0 for an LED without points).
    dinv: Vec<f64>,
}

/// Everything at one offset.
struct AtOffset {
    offset: f64,
    rel_w2: f64,
    tau2: f64,
    v: Vec<f64>,
    wls: Wls,
    objective: f64,
}

impl Prepared<'_> {
    /// Point `j`'s setting (`None` for the reference) and LED.
    fn design(&self, j: usize) -> (Option<usize>, usize) {
        let p = &self.points[j];
        ((p.setting > 0).then_some(p.setting), p.led)
    }

    /// Weighted least squares of `y` with variances `v`.
    fn wls(&self, y: &[f64], v: &[f64]) -> Result<Wls, Singular> {
        let m = self.settings;
        let l = self.leds;
        let mut a = DMatrix::<f64>::zeros(m, m);
        let mut b = DMatrix::<f64>::zeros(m, l);
        let mut d = vec![0.0; l];
        let mut ba = DVector::<f64>::zeros(m);
        let mut bl = vec![0.0; l];
        for j in 0..self.points.len() {
            let w = 1.0 / v[j];
            let (k, led) = self.design(j);
            let x = self.x[j];
            a[(0, 0)] += w * x * x;
            b[(0, led)] += w * x;
            ba[0] += w * x * y[j];
            if let Some(k) = k {
                a[(0, k)] += w * x;
                a[(k, 0)] += w * x;
                a[(k, k)] += w;
                b[(k, led)] += w;
                ba[k] += w * y[j];
            }
            d[led] += w;
            bl[led] += w * y[j];
        }
        let dinv: Vec<f64> = d
            .iter()
            .map(|&v| if v > 0.0 { 1.0 / v } else { 0.0 })
            .collect();
        let mut g = b.clone();
        for (led, &di) in dinv.iter().enumerate() {
            g.column_mut(led).scale_mut(di);
        }
        let s = &a - &g * b.transpose();
        let rhs = &ba - &g * DVector::from_vec(bl.clone());
        let s_inv = s.clone().cholesky().map(|c| c.inverse()).ok_or(Singular)?;
        // Near-singular: the exponent (or a setting) barely varies within the LEDs.
        for i in 0..m {
            if !(s_inv[(i, i)] * a[(i, i)] < 1e12) {
                return Err(Singular);
            }
        }
        let theta = &s_inv * rhs;
        let c: Vec<f64> = (0..l)
            .map(|led| {
                if d[led] > 0.0 {
                    (bl[led] - b.column(led).dot(&theta)) * dinv[led]
                } else {
                    0.0
                }
            })
            .collect();
        let mut chi2 = 0.0;
        let resid: Vec<f64> = (0..self.points.len())
            .map(|j| {
                let (k, led) = self.design(j);
                let model = theta[0] * self.x[j] + k.map_or(0.0, |k| theta[k]) + c[led];
                let r = y[j] - model;
                chi2 += r * r / v[j];
                r
            })
            .collect();
        Ok(Wls {
            theta,
            c,
            chi2,
            resid,
            s_inv,
            g,
            dinv,
        })
    }

    /// The fit at `offset` (below every reading).
    fn at(&self, offset: f64) -> Result<AtOffset, Singular> {
        let np = self.points.len();
        let dbar: Vec<f64> = self.mean.iter().map(|m| m - offset).collect();
        let y: Vec<f64> = dbar.iter().map(|d| d.ln()).collect();
        // The samples' relative scatter about their own means, rounding taken out. Rounding
        // acts as noise of its own (1/12 counts^2, Sheppard) only where the scatter spreads
        // the readings over several counts; where it is well below a count, a point's
        // readings round alike (their spread tells nothing and their mean keeps the whole
        // rounding error, which the readings of a standing target do too). So the scatter is
        // pooled over the dithered points (spread of a count or more), or over every
        // point without a rounding correction when the readings are not counts.
        let dithered: Vec<bool> = (0..np)
            .map(|j| self.q == 0.0 || (self.n[j] > 1.0 && self.ss[j] >= DITHER * (self.n[j] - 1.0)))
            .collect();
        let within: f64 = (0..np)
            .filter(|&j| dithered[j])
            .map(|j| self.n[j] - 1.0)
            .sum();
        let rel_w2 = if within > 0.0 {
            let ss: f64 = (0..np)
                .filter(|&j| dithered[j])
                .map(|j| (self.ss[j] - self.q * (self.n[j] - 1.0)) / (dbar[j] * dbar[j]))
                .sum();
            (ss / within).max(0.0)
        } else {
            0.0
        };
        // A point mean's variance: the scatter averages over its readings; the rounding
        // too where they are dithered, not where they round alike.
        let u: Vec<f64> = (0..np)
            .map(|j| {
                let round = self.q / (dbar[j] * dbar[j]);
                if dithered[j] {
                    (rel_w2 + round) / self.n[j]
                } else {
                    rel_w2 / self.n[j] + round
                }
            })
            .collect();
        let tau_min2 = (NOISE_FLOOR * NOISE_FLOOR - rel_w2).max(0.0);
        let var = |t2: f64| -> Vec<f64> { u.iter().map(|u| (u + t2).max(1e-300)).collect() };
        let mut tau2 = tau_min2;
        let mut v = var(tau2);
        let mut wls = self.wls(&y, &v)?;
        if wls.chi2 > self.dof {
            // Paule-Mandel: chi-square equal to its degrees of freedom. Bracket, then bisect
            // in the logarithm.
            let mut lo = tau_min2.max(1e-16);
            let mut hi = lo;
            loop {
                hi *= 4.0;
                let w = self.wls(&y, &var(hi))?;
                if w.chi2 <= self.dof || hi > 1e6 {
                    break;
                }
                lo = hi;
            }
            for _ in 0..100 {
                let mid = (lo * hi).sqrt();
                if self.wls(&y, &var(mid))?.chi2 > self.dof {
                    lo = mid;
                } else {
                    hi = mid;
                }
                if hi / lo < 1.0 + 1e-12 {
                    break;
                }
            }
            tau2 = hi;
            v = var(tau2);
            wls = self.wls(&y, &v)?;
        }
        let objective = wls.chi2
            + v.iter().map(|v| v.ln()).sum::<f64>()
            + 2.0 * dbar.iter().map(|d| d.ln()).sum::<f64>();
        Ok(AtOffset {
            offset,
            rel_w2,
            tau2,
            v,
            wls,
            objective,
        })
    }
}

/// Fit the law to `points` (see the module docs): `leds` and `settings` count the LED and
/// setting indices the points use. `counts`: the readings are whole counts (their rounding,
/// 1/12 counts^2, is part of each reading's variance).
pub fn fit_law(
    points: &[MagPoint],
    leds: usize,
    settings: usize,
    counts: bool,
) -> Result<LawFit, LawError> {
    if let Some(p) = points
        .iter()
        .find(|p| p.led >= leds || p.setting >= settings)
    {
        return Err(LawError::OutOfRange {
            led: p.led,
            setting: p.setting,
        });
    }
    if let Some(p) = points.iter().find(|p| {
        p.readings.is_empty()
            || !(p.s > 0.0 && p.s.is_finite())
            || p.readings.iter().any(|m| !m.is_finite())
    }) {
        return Err(LawError::NoSignal {
            separation_in: p.separation_in,
        });
    }
    let mut used_leds = vec![false; leds];
    let mut used_settings = vec![false; settings];
    for p in points {
        used_leds[p.led] = true;
        used_settings[p.setting] = true;
    }
    if settings == 0 || !used_settings[0] {
        return Err(LawError::NoReference);
    }
    // An LED seen at two signals (two separations, or two places) tells the exponent.
    let mut span: BTreeMap<usize, (f64, f64)> = BTreeMap::new();
    for p in points {
        let e = span
            .entry(p.led)
            .or_insert((f64::INFINITY, f64::NEG_INFINITY));
        e.0 = e.0.min(p.s.ln());
        e.1 = e.1.max(p.s.ln());
    }
    if !span.values().any(|(lo, hi)| hi - lo > 1e-3) {
        return Err(LawError::OneSignal);
    }
    let params = 1
        + used_settings.iter().skip(1).filter(|u| **u).count()
        + used_leds.iter().filter(|u| **u).count();
    // The offset and the scatter are fitted too.
    let dof = points.len() as f64 - params as f64 - 2.0;
    if dof < 1.0 {
        return Err(LawError::TooFewPoints {
            points: points.len(),
            parameters: params + 2,
            constants: params - 1,
        });
    }
    let prep = Prepared {
        points,
        x: points.iter().map(|p| p.s.ln()).collect(),
        n: points.iter().map(|p| p.readings.len() as f64).collect(),
        mean: points
            .iter()
            .map(|p| p.readings.iter().sum::<f64>() / p.readings.len() as f64)
            .collect(),
        ss: points
            .iter()
            .map(|p| {
                let m = p.readings.iter().sum::<f64>() / p.readings.len() as f64;
                p.readings.iter().map(|r| (r - m).powi(2)).sum()
            })
            .collect(),
        q: if counts { ROUNDING } else { 0.0 },
        leds,
        settings,
        dof,
    };
    // The offset stays below every point mean by a count (by a thousandth of the smallest
    // mean when the readings are not counts).
    let low = prep.mean.iter().copied().fold(f64::INFINITY, f64::min);
    if !(low > 0.0) {
        return Err(LawError::NotPositive);
    }
    let top = if counts {
        low - 1.0
    } else {
        low * (1.0 - 1e-3)
    };
    let singular = |_: Singular| {
        if settings > 1 {
            LawError::SettingsIndistinct
        } else {
            LawError::LedsIndistinct
        }
    };
    let best = if top > 0.0 {
        search_offset(&prep, top)
    } else {
        prep.at(0.0)
    }
    .map_err(singular)?;
    let at_zero = best.offset <= 0.0;
    let offset_sigma = if top > 0.0 {
        offset_sigma(&prep, &best, top)
    } else {
        f64::INFINITY
    };
    // Parameters as functions of the offset, for carrying its uncertainty through.
    let l = leds;
    let norm_ln_b = |w: &Wls| -> Vec<Option<f64>> {
        let active: Vec<usize> = (0..l).filter(|&i| used_leds[i]).collect();
        let mean = active.iter().map(|&i| w.c[i]).sum::<f64>() / active.len() as f64;
        (0..l)
            .map(|i| used_leds[i].then(|| (w.c[i] - mean) / w.theta[0]))
            .collect()
    };
    let setting_ln = |w: &Wls, k: usize| w.theta[k] / w.theta[0];
    let ln_b = norm_ln_b(&best.wls);
    let (d_exp, d_lnb, d_set) = if offset_sigma.is_finite() && offset_sigma > 0.0 {
        let h = (offset_sigma * 0.1).max(1e-9 * (1.0 + best.offset.abs()));
        let (a, b) = if best.offset - h >= 0.0 {
            (best.offset - h, best.offset + h)
        } else {
            (best.offset, best.offset + h)
        };
        let b = b.min(top - 0.5 * (top - best.offset));
        let fa = prep.at(a)?;
        let fb = prep.at(b)?;
        let span = b - a;
        let la = norm_ln_b(&fa.wls);
        let lb = norm_ln_b(&fb.wls);
        (
            (fb.wls.theta[0] - fa.wls.theta[0]) / span,
            (0..l)
                .map(|i| match (la[i], lb[i]) {
                    (Some(x), Some(y)) => (y - x) / span,
                    _ => 0.0,
                })
                .collect::<Vec<f64>>(),
            (0..settings)
                .map(|k| {
                    if k == 0 {
                        0.0
                    } else {
                        (setting_ln(&fb.wls, k) - setting_ln(&fa.wls, k)) / span
                    }
                })
                .collect::<Vec<f64>>(),
        )
    } else {
        (0.0, vec![0.0; l], vec![0.0; settings])
    };
    let var_o = if offset_sigma.is_finite() {
        offset_sigma * offset_sigma
    } else {
        0.0
    };
    let w = &best.wls;
    let g = w.theta[0];
    let exponent_sigma = (w.s_inv[(0, 0)] + d_exp * d_exp * var_o).sqrt();
    // ln b_i = (c_i - mean c) / g: the variance of the contrast v'c (v = e_i - 1/L) is
    // v' D^-1 v + (G v)' S^-1 (G v), its covariance with the small parameters -S^-1 G v.
    let active: Vec<usize> = (0..l).filter(|&i| used_leds[i]).collect();
    let na = active.len() as f64;
    let sum_dinv: f64 = active.iter().map(|&i| w.dinv[i]).sum();
    let mut gsum = DVector::<f64>::zeros(settings);
    for &i in &active {
        gsum += w.g.column(i);
    }
    let ln_brightness_sigma: Vec<Option<f64>> = (0..l)
        .map(|i| {
            let lb = ln_b[i]?;
            let gv = w.g.column(i) - &gsum / na;
            let var_vc =
                (1.0 - 2.0 / na) * w.dinv[i] + sum_dinv / (na * na) + gv.dot(&(&w.s_inv * &gv));
            let cov_vc_g = -(&w.s_inv * &gv)[0];
            // d ln b / d(v'c) = 1/g, d ln b / dg = -ln b / g.
            let var = var_vc / (g * g) + (lb / g).powi(2) * w.s_inv[(0, 0)]
                - 2.0 * (1.0 / g) * (lb / g) * cov_vc_g;
            Some((var.max(0.0) + d_lnb[i].powi(2) * var_o).sqrt())
        })
        .collect();
    let ln_setting: Vec<Option<(f64, f64)>> = (0..settings)
        .map(|k| {
            if !used_settings[k] {
                return None;
            }
            if k == 0 {
                return Some((0.0, 0.0));
            }
            let v = setting_ln(w, k);
            // d(s/g) = ds/g - s dg/g^2.
            let var = w.s_inv[(k, k)] / (g * g) + (v / g).powi(2) * w.s_inv[(0, 0)]
                - 2.0 * (v / (g * g)) * w.s_inv[(0, k)];
            Some((v, (var.max(0.0) + d_set[k].powi(2) * var_o).sqrt()))
        })
        .collect();
    let residuals = (0..points.len())
        .map(|j| (w.resid[j], best.v[j].sqrt()))
        .collect();
    Ok(LawFit {
        offset: best.offset,
        offset_sigma,
        offset_at_zero: at_zero,
        exponent: g,
        exponent_sigma,
        rel_within: best.rel_w2.sqrt(),
        rel_between: best.tau2.sqrt(),
        ln_brightness: ln_b,
        ln_brightness_sigma,
        ln_setting,
        residuals,
        counts,
    })
}

/// The offset in `[0, top)` with the least objective: a grid, then golden section about its
/// best point.
fn search_offset(prep: &Prepared, top: f64) -> Result<AtOffset, Singular> {
    const GRID: usize = 40;
    let mut grid: Vec<AtOffset> = Vec::with_capacity(GRID);
    for i in 0..GRID {
        grid.push(prep.at(top * i as f64 / GRID as f64)?);
    }
    let (bi, _) = grid
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.objective.total_cmp(&b.1.objective))
        .expect("a grid");
    let lo = if bi == 0 { 0.0 } else { grid[bi - 1].offset };
    let hi = if bi + 1 < GRID {
        grid[bi + 1].offset
    } else {
        // Between the last grid point and the top, short of the top itself.
        grid[bi].offset + 0.999 * (top - grid[bi].offset)
    };
    let (mut a, mut b) = (lo, hi);
    let phi = (5f64.sqrt() - 1.0) / 2.0;
    let mut c = b - phi * (b - a);
    let mut d = a + phi * (b - a);
    let mut fc = prep.at(c)?;
    let mut fd = prep.at(d)?;
    for _ in 0..200 {
        if (b - a) <= 1e-10 * (1.0 + top) {
            break;
        }
        if fc.objective < fd.objective {
            b = d;
            d = c;
            fd = fc;
            c = b - phi * (b - a);
            fc = prep.at(c)?;
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + phi * (b - a);
            fd = prep.at(d)?;
        }
    }
    let inner = if fc.objective < fd.objective { fc } else { fd };
    // The bound itself may be best (an offset of 0 on data with none).
    let mut best = inner;
    if bi == 0 && grid[0].objective <= best.objective {
        best = grid.swap_remove(0);
    }
    Ok(best)
}

/// The offset's 1-sigma from the curvature of the objective (`-2 ln L`) at `best`: `sqrt(2 /
/// f'')`, by central differences (forward ones at the bound 0), the step shrunk until it is
/// within the sigma it finds (away from the minimum the objective grows only as the
/// logarithm of the scatter, and curves the other way). `inf` when no step finds a curvature.
fn offset_sigma(prep: &Prepared, best: &AtOffset, top: f64) -> f64 {
    let o = best.offset;
    let f0 = best.objective;
    let mut h = 0.01 * (top - o).max(1e-12).min(top);
    let tiny = 1e-9 * top;
    while h > tiny {
        let curv = if o - h >= 0.0 && o + h < top {
            match (prep.at(o - h), prep.at(o + h)) {
                (Ok(a), Ok(b)) => (a.objective - 2.0 * f0 + b.objective) / (h * h),
                _ => return f64::INFINITY,
            }
        } else if o + 2.0 * h < top {
            match (prep.at(o + h), prep.at(o + 2.0 * h)) {
                (Ok(a), Ok(b)) => (f0 - 2.0 * a.objective + b.objective) / (h * h),
                _ => return f64::INFINITY,
            }
        } else {
            h *= 0.1;
            continue;
        };
        if curv > 0.0 {
            let sigma = (2.0 / curv).sqrt();
            if h <= sigma {
                return sigma;
            }
            h = (0.5 * sigma).min(0.5 * h);
        } else {
            h *= 0.1;
        }
    }
    f64::INFINITY
}

/// One LED's fitted brightness, as the calibration file holds it (host-side data the board
/// ignores; `cta sensor load-constellation --brightness` reads it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LedBrightness {
    /// The measurement file's `beacon` id, when it has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beacon: Option<u32>,
    /// The LED's x on the plate as the measurement file gives it (N frame), inches.
    pub x_in: f64,
    /// Its y, inches.
    pub y_in: f64,
    /// Relative brightness (the LEDs' geometric mean is 1).
    pub brightness: f64,
    /// Its 1-sigma.
    pub sigma: f64,
}

/// The light of one drive setting relative to the first (`cta calibrate`'s report).
#[derive(Debug, Clone, Serialize)]
pub struct SettingLight {
    /// Power level, when recorded.
    pub power: Option<f64>,
    /// Modulation frequency, Hz, when recorded.
    pub frequency_hz: Option<f64>,
    /// Points at it.
    pub points: usize,
    /// Its light over the first setting's (1 for the first).
    pub light: f64,
    /// 1-sigma.
    pub sigma: f64,
}

/// The residuals at one separation.
#[derive(Debug, Clone, Serialize)]
pub struct MagSeparation {
    /// Separation, inches.
    pub separation_in: f64,
    /// Points used.
    pub points: usize,
    /// RMS of the point means' residuals about the law, percent.
    pub rms_percent: f64,
    /// Their weighted mean, percent (a trend with the separation: the law's shape is wrong).
    pub mean_percent: f64,
}

/// What `cta calibrate` reports of the magnitude law.
#[derive(Debug, Clone, Serialize)]
pub struct MagnitudeReport {
    /// The law the calibration holds.
    pub law: Magnitude,
    /// 1-sigma of the offset (`null` when the data do not determine it).
    pub offset_sigma: Option<f64>,
    /// Whether the offset ended at its lower bound, 0.
    pub offset_at_zero: bool,
    /// 1-sigma of the exponent.
    pub exponent_sigma: f64,
    /// The samples' scatter about their points' means, percent (rounding taken out).
    pub noise_within_percent: f64,
    /// The points' scatter about the law beyond it, percent.
    pub noise_between_percent: f64,
    /// Whether the readings are whole counts (then each carries 1/12 counts^2 of rounding).
    pub counts: bool,
    /// Samples used.
    pub samples: usize,
    /// Points used.
    pub points: usize,
    /// Separations used, inches.
    pub separations: Vec<f64>,
    /// The sensitivity settings in the file with their samples (with a magnitude).
    pub sensitivities: Vec<(u8, usize)>,
    /// Samples at another sensitivity, not used.
    pub other_sensitivity_samples: usize,
    /// Saturated readings (at or above `law.max`).
    pub saturated_samples: usize,
    /// Points left out for them.
    pub saturated_points: usize,
    /// Points left out because an output coordinate was pinned at the 16-bit rail.
    pub pinned_points: usize,
    /// Points left out for a mean reading or model signal that is not above 0.
    pub no_signal_points: usize,
    /// Drive settings (power, frequency) and their light relative to the first.
    pub settings: Vec<SettingLight>,
    /// Dimmest LED (relative brightness).
    pub brightness_min: f64,
    /// Brightest LED.
    pub brightness_max: f64,
    /// RMS of the LEDs' brightness about 1, percent.
    pub brightness_rms_percent: f64,
    /// Each LED's brightness.
    pub led_brightness: Vec<LedBrightness>,
    /// Residuals per separation.
    pub by_separation: Vec<MagSeparation>,
    /// Things to know.
    pub warnings: Vec<String>,
}

/// The outcome of fitting a file's magnitudes: a law, or why there is none (not an error).
#[derive(Debug, Clone)]
pub enum Outcome {
    /// A law.
    Law(Box<MagnitudeReport>),
    /// No law, and why.
    NoLaw(String),
}

/// The sensitivity a row was read at: its `sensitivity`, else 4 (the board's start-up
/// setting).
fn sensitivity_of(s: &crate::data::Sample) -> u8 {
    s.sensitivity.map_or(4, |v| v as u8)
}

/// Fit the magnitude law to the magnitudes of `ds` with the model `em` (the fitted head, in
/// N; `S` at each beacon's recorded position) at `sensitivity` (default: the setting with the
/// most samples with a magnitude, 4 on a tie; rows without a sensitivity count as 4). An
/// error only for a `sensitivity` the file does not have; a file without magnitudes, or whose
/// magnitudes cannot fix a law, gives [`Outcome::NoLaw`].
pub fn fit_dataset(
    ds: &Dataset,
    em: &Emulator<f64>,
    sensitivity: Option<u8>,
) -> Result<Outcome, MagnitudeError> {
    let name = ds.path.display();
    let with: Vec<&crate::data::Sample> = ds
        .samples
        .iter()
        .filter(|s| s.magnitude.is_some())
        .collect();
    if with.is_empty() {
        return Ok(Outcome::NoLaw(format!(
            "{name} records no spot magnitudes (no `magnitude` column, or every field empty): no \
             magnitude law"
        )));
    }
    let mut by_sens: BTreeMap<u8, usize> = BTreeMap::new();
    for s in &with {
        *by_sens.entry(sensitivity_of(s)).or_default() += 1;
    }
    let sens = match sensitivity {
        Some(v) => {
            if !by_sens.contains_key(&v) {
                return Err(MagnitudeError::NoSensitivity {
                    sensitivity: v,
                    file: name.to_string(),
                    have: by_sens.iter().map(|(k, n)| (*k, *n)).collect(),
                });
            }
            v
        }
        None => {
            let most = *by_sens.values().max().expect("a sensitivity");
            by_sens
                .iter()
                .filter(|(_, n)| **n == most)
                .map(|(k, _)| *k)
                .max_by_key(|k| (*k == 4, *k))
                .expect("a sensitivity")
        }
    };
    let other_sensitivity_samples = with.iter().filter(|s| sensitivity_of(s) != sens).count();

    // The points at that sensitivity, with their magnitudes.
    struct Raw {
        sep: f64,
        r: [f64; 3],
        beacon: Option<u32>,
        setting: (u64, u64),
        power: Option<f64>,
        frequency: Option<f64>,
        readings: Vec<f64>,
    }
    let mut raw = Vec::new();
    let mut pinned_points = 0;
    for p in ds.points() {
        let rows: Vec<&crate::data::Sample> = p
            .rows
            .iter()
            .map(|&i| &ds.samples[i])
            .filter(|s| s.magnitude.is_some() && sensitivity_of(s) == sens)
            .collect();
        if rows.is_empty() {
            continue;
        }
        if any_sample_pinned(rows.iter().copied()) {
            pinned_points += 1;
            continue;
        }
        let f = p.first;
        raw.push(Raw {
            sep: f.separation_in,
            r: f.r,
            beacon: f.beacon,
            setting: (
                f.power.unwrap_or(f64::NAN).to_bits(),
                f.frequency_hz.unwrap_or(f64::NAN).to_bits(),
            ),
            power: f.power,
            frequency: f.frequency_hz,
            readings: rows.iter().filter_map(|s| s.magnitude).collect(),
        });
    }
    // Saturation: the 16-bit rail, or a pile-up at the largest value.
    let vmax = raw
        .iter()
        .flat_map(|p| p.readings.iter().copied())
        .fold(f64::NEG_INFINITY, f64::max);
    let at_max = raw.iter().filter(|p| p.readings.contains(&vmax)).count();
    let (max, piled) = if vmax >= RAIL {
        (RAIL, true)
    } else if at_max >= PILE_UP_POINTS {
        (vmax, true)
    } else {
        (RAIL, false)
    };
    let mut saturated_samples = 0;
    let mut saturated_points = 0;
    let mut no_signal_points = 0;
    raw.retain(|p| {
        let sat = p.readings.iter().filter(|m| **m >= max).count();
        if sat > 0 {
            saturated_samples += sat;
            saturated_points += 1;
            return false;
        }
        true
    });
    // LEDs and settings, numbered in order of appearance.
    let mut leds: Vec<(Option<u32>, i64, i64)> = Vec::new();
    let mut led_xy: Vec<(f64, f64)> = Vec::new();
    let mut settings: Vec<(u64, u64)> = Vec::new();
    let mut setting_info: Vec<(Option<f64>, Option<f64>)> = Vec::new();
    let mut points = Vec::new();
    let mut used_samples = 0;
    for p in &raw {
        let s = em.magnitude(&Vector3::from(p.r));
        let mean = p.readings.iter().sum::<f64>() / p.readings.len() as f64;
        if !(s > 0.0 && s.is_finite() && mean > 0.0) {
            no_signal_points += 1;
            continue;
        }
        // The beacon id names the LED when the file has it; else its place on the plate.
        let key = match p.beacon {
            Some(b) => (Some(b), 0, 0),
            None => (
                None,
                (p.r[0] * 100.0).round() as i64,
                (p.r[1] * 100.0).round() as i64,
            ),
        };
        let led = match leds.iter().position(|k| *k == key) {
            Some(i) => i,
            None => {
                leds.push(key);
                led_xy.push((p.r[0], p.r[1]));
                leds.len() - 1
            }
        };
        let setting = match settings.iter().position(|k| *k == p.setting) {
            Some(i) => i,
            None => {
                settings.push(p.setting);
                setting_info.push((p.power, p.frequency));
                settings.len() - 1
            }
        };
        used_samples += p.readings.len();
        points.push(MagPoint {
            led,
            setting,
            separation_in: p.sep,
            s,
            readings: p.readings.clone(),
        });
    }
    let mut left_out = Vec::new();
    if saturated_points > 0 {
        left_out.push(format!(
            "{saturated_points} points saturated ({saturated_samples} readings at or above {max})"
        ));
    }
    if pinned_points > 0 {
        left_out.push(format!(
            "{pinned_points} points with an output at the 16-bit rail"
        ));
    }
    let no_law = |why: String| {
        let also = if left_out.is_empty() {
            String::new()
        } else {
            format!(" (left out: {})", left_out.join("; "))
        };
        Ok(Outcome::NoLaw(format!(
            "{name}: no magnitude law at sensitivity {sens}: {why}{also}"
        )))
    };
    let mut seps: Vec<f64> = points.iter().map(|p| p.separation_in).collect();
    seps.sort_by(f64::total_cmp);
    seps.dedup();
    if seps.len() < 2 {
        return no_law(format!(
            "the usable magnitudes are at {} separation(s) ({} in); the exponent needs two or \
             more",
            seps.len(),
            fmt_list(&seps)
        ));
    }
    let counts = points
        .iter()
        .all(|p| p.readings.iter().all(|m| m.fract() == 0.0));
    let fit = match fit_law(&points, leds.len(), settings.len(), counts) {
        Ok(f) => f,
        Err(e) => return no_law(e.to_string()),
    };
    // The weakest reading fitted: the law is not stretched below it (Magnitude::min).
    let vmin = points
        .iter()
        .flat_map(|p| p.readings.iter().copied())
        .fold(f64::INFINITY, f64::min);
    let law = Magnitude {
        offset: fit.offset as f32,
        exponent: fit.exponent as f32,
        noise_percent: (100.0 * fit.rel()) as f32,
        max: max as f32,
        // Rounded down, so that the weakest reading itself is in range in f32.
        min: (vmin.floor() as f32).min(max as f32),
        sensitivity: sens,
    };
    // The board's ranges (Calibration::validate): a law outside them is not written.
    let check = cta_core::pose::Calibration {
        magnitude: Some(law),
        ..cta_core::pose::Calibration::table3()
    };
    if let Err(e) = check.validate() {
        return no_law(format!(
            "the fitted law (offset {:.4}, exponent {:.4}, noise {:.3} %, max {max}) is outside \
             what the board takes: {e}",
            fit.offset,
            fit.exponent,
            100.0 * fit.rel()
        ));
    }

    let mut warnings = Vec::new();
    // Per separation, and the trend test: the weighted mean residual of each separation
    // against its standard error.
    let mut by: BTreeMap<u64, (usize, f64, f64, f64)> = BTreeMap::new();
    for (p, (r, se)) in points.iter().zip(&fit.residuals) {
        let e = by.entry(p.separation_in.to_bits()).or_default();
        let w = 1.0 / (se * se);
        e.0 += 1;
        e.1 += r * r;
        e.2 += w * r;
        e.3 += w;
    }
    let by_separation: Vec<MagSeparation> = by
        .iter()
        .map(|(k, (n, ss, wr, w))| MagSeparation {
            separation_in: f64::from_bits(*k),
            points: *n,
            rms_percent: 100.0 * (ss / *n as f64).sqrt(),
            mean_percent: 100.0 * wr / w,
        })
        .collect();
    let chi2: f64 = by
        .iter()
        .map(|(k, (_, _, wr, w))| {
            let allow = 2.0 * SEPARATION_UNCERTAINTY_IN / f64::from_bits(*k);
            (wr / w).powi(2) / (1.0 / w + allow * allow)
        })
        .sum();
    // The exponent and the LED constants take up about two of the separations' means.
    let k = (by.len() as f64 - 2.0).max(1.0);
    let z = (chi2 - k) / (2.0 * k).sqrt();
    if by.len() >= 3 && z > TREND_Z {
        warnings.push(format!(
            "the magnitudes' residuals trend with the separation (mean {} % at {} in; {z:.0} \
             standard deviations beyond chance and the separations' +/-5 mil uncertainty): the \
             law's shape (offset + scale x signal^exponent) does not hold these data, or the \
             model's signal S is off (the head, the beacon pattern); the noise above includes \
             that misfit",
            by_separation
                .iter()
                .map(|b| format!("{:+.2}", b.mean_percent))
                .collect::<Vec<_>>()
                .join(", "),
            fmt_list(&seps)
        ));
    }
    if 100.0 * fit.rel() > NOISY_PERCENT {
        warnings.push(format!(
            "the magnitudes scatter {:.2} % about the law (above {NOISY_PERCENT} %): they will carry \
             little weight in the pose (the spots alone decide it)",
            100.0 * fit.rel()
        ));
    }
    if seps.len() < 3 {
        warnings.push(format!(
            "the magnitudes are at {} separations only ({} in): the exponent and the offset rest \
             on how the LEDs' signals differ within them; measure more separations to fix it",
            seps.len(),
            fmt_list(&seps)
        ));
    }
    if !fit.offset_sigma.is_finite() {
        warnings.push(
            "the data do not determine the offset (the readings are too close to each other, or \
             too few): it is the best value found, without a 1-sigma"
                .into(),
        );
    }
    if piled && max < RAIL {
        warnings.push(format!(
            "{at_max} points read the file's largest magnitude, {max}: taken as the sensor's \
             saturation (the law's max); readings at it are left out"
        ));
    }

    // The brightness per LED.
    let led_brightness: Vec<LedBrightness> = (0..leds.len())
        .filter_map(|i| {
            let lb = fit.ln_brightness[i]?;
            let b = lb.exp();
            Some(LedBrightness {
                beacon: leds[i].0,
                x_in: led_xy[i].0,
                y_in: led_xy[i].1,
                brightness: b,
                sigma: b * fit.ln_brightness_sigma[i].unwrap_or(f64::NAN),
            })
        })
        .collect();
    let bmin = led_brightness
        .iter()
        .map(|l| l.brightness)
        .fold(f64::INFINITY, f64::min);
    let bmax = led_brightness
        .iter()
        .map(|l| l.brightness)
        .fold(f64::NEG_INFINITY, f64::max);
    let brms = 100.0
        * (led_brightness
            .iter()
            .map(|l| (l.brightness - 1.0).powi(2))
            .sum::<f64>()
            / led_brightness.len() as f64)
            .sqrt();
    let out_of_range: Vec<String> = led_brightness
        .iter()
        .filter(|l| !((MIN_BRIGHTNESS as f64)..=(MAX_BRIGHTNESS as f64)).contains(&l.brightness))
        .map(|l| format!("({}, {}) in: {:.3}", l.x_in, l.y_in, l.brightness))
        .collect();
    if !out_of_range.is_empty() {
        warnings.push(format!(
            "LEDs outside the brightness a constellation takes ({MIN_BRIGHTNESS} to \
             {MAX_BRIGHTNESS}): {}",
            out_of_range.join(", ")
        ));
    }
    let setting_points = |k: usize| points.iter().filter(|p| p.setting == k).count();
    let settings_out: Vec<SettingLight> = (0..settings.len())
        .filter_map(|k| {
            let (v, s) = fit.ln_setting[k]?;
            Some(SettingLight {
                power: setting_info[k].0,
                frequency_hz: setting_info[k].1,
                points: setting_points(k),
                light: v.exp(),
                sigma: v.exp() * s,
            })
        })
        .collect();
    Ok(Outcome::Law(Box::new(MagnitudeReport {
        law,
        offset_sigma: fit.offset_sigma.is_finite().then_some(fit.offset_sigma),
        offset_at_zero: fit.offset_at_zero,
        exponent_sigma: fit.exponent_sigma,
        noise_within_percent: 100.0 * fit.rel_within,
        noise_between_percent: 100.0 * fit.rel_between,
        counts,
        samples: used_samples,
        points: points.len(),
        separations: seps,
        sensitivities: by_sens.into_iter().collect(),
        other_sensitivity_samples,
        saturated_samples,
        saturated_points,
        pinned_points,
        no_signal_points,
        settings: settings_out,
        brightness_min: bmin,
        brightness_max: bmax,
        brightness_rms_percent: brms,
        led_brightness,
        by_separation,
        warnings,
    })))
}

#[cfg(test)]
mod tests;
