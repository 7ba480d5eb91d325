//! How the samples of a measurement file are weighted (eq 56's `W`): the noise of repeated
//! samples pooled per separation, the point means and the chi-square a right model gives.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use cta_core::collinearity::Obs;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::data::Dataset;

/// How residuals are weighted (eq 56's `W`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Weights {
    /// `W = I`: every sample is one observation (the thesis's choice).
    None,
    /// Point means weighted by `n / variance` from the repeated samples of each point, with
    /// a floor of 1/12 count^2 (the quantisation of integer counts). Needs at least 6
    /// samples per point (`REPEAT_MIN_SAMPLES`).
    Repeat,
    /// Point means weighted by `n / variance` with the one-sample variance pooled per
    /// separation and axis (over the points with no sample at the 16-bit rail), floored at
    /// 1/12 count^2: `cta calibrate`'s and `cta analyze`'s weights, good from 2 samples.
    Pooled,
}

/// The fewest samples per point `--weights repeat` takes: below 6 the inverse of a sample
/// variance (the weight) has an infinite variance (an infinite mean at 3 or fewer), so the few
/// points whose samples happen to agree would carry the fit.
pub const REPEAT_MIN_SAMPLES: usize = 6;

/// A chi2/dof above this is warned about even when no expectation is known.
pub const CHI2_FAR: f64 = 2.0;

impl Weights {
    /// How the text output names the weighting.
    pub fn describe(self) -> &'static str {
        match self {
            Weights::None => "unweighted",
            Weights::Repeat => "weighted by the spread of the repeated samples of each point",
            Weights::Pooled => {
                "weighted by the noise of the repeated samples pooled per separation and axis"
            }
        }
    }

    /// What one observation is under this weighting, plural (`6000 reports`).
    pub fn observations(self) -> &'static str {
        match self {
            Weights::None => "reports",
            Weights::Repeat | Weights::Pooled => "point means",
        }
    }
}

/// The chi2/dof a right model gives with `repeat` weights: each point is weighted by the
/// inverse of its own sample variance from `n` samples, whose mean is `(n - 1) / (n - 3)`
/// times the inverse true variance (an inverse chi-square), so chi2/dof averages that over
/// the points (1.29 with 10 samples, 1.67 with 6). `None` when a point has 3 samples or fewer
/// (the mean is infinite: no line to compare with; `--weights repeat` refuses such files).
pub fn repeat_chi2_expected(ds: &Dataset) -> Option<f64> {
    let (mut sum, mut k) = (0.0, 0usize);
    for p in ds.points() {
        let n = p.rows.len() as f64;
        if n <= 3.0 {
            return None;
        }
        sum += (n - 1.0) / (n - 3.0);
        k += 1;
    }
    (k > 0).then(|| sum / k as f64)
}

/// The chi2/dof a right model gives with `weights` on `ds`: with `repeat`
/// [`repeat_chi2_expected`]; with `pooled` the same law for a variance pooled over `nu`
/// degrees of freedom, `nu / (nu - 2)`, averaged over the points and axes (1.02 with 100
/// points of 2 samples at a separation); `None` with `none` weights (no noise to compare with).
pub fn chi2_expected(ds: &Dataset, weights: Weights) -> Option<f64> {
    match weights {
        Weights::None => None,
        Weights::Repeat => repeat_chi2_expected(ds),
        Weights::Pooled => {
            let pool = pooled_noise(ds);
            let (mut sum, mut k) = (0.0, 0usize);
            for p in ds.points() {
                let nu = pool
                    .get(&p.first.separation_in.to_bits())
                    .map_or(0, |(_, dof)| *dof) as f64;
                if nu <= 2.0 {
                    return None;
                }
                sum += nu / (nu - 2.0);
                k += 1;
            }
            (k > 0).then(|| sum / k as f64)
        }
    }
}

/// The one-sample noise pooled per separation over the points with no sample at the 16-bit
/// rail ([`crate::data::any_sample_pinned`], as `cta calibrate` pools it): separation
/// (as bits) to `([sum of squared deviations X, Y], degrees of freedom)`.
pub fn pooled_noise(ds: &Dataset) -> BTreeMap<u64, ([f64; 2], usize)> {
    let mut out: BTreeMap<u64, ([f64; 2], usize)> = BTreeMap::new();
    for p in ds.points() {
        let rows: Vec<_> = p.rows.iter().map(|&i| &ds.samples[i]).collect();
        if crate::data::any_sample_pinned(rows.iter().copied()) {
            continue;
        }
        let n = rows.len() as f64;
        let mean = [
            rows.iter().map(|s| s.x).sum::<f64>() / n,
            rows.iter().map(|s| s.y).sum::<f64>() / n,
        ];
        let e = out.entry(p.first.separation_in.to_bits()).or_default();
        for s in &rows {
            e.0[0] += (s.x - mean[0]).powi(2);
            e.0[1] += (s.y - mean[1]).powi(2);
        }
        e.1 += rows.len() - 1;
    }
    out
}

/// The one-sample variance of `axis` pooled at separation `sep` in `pool`
/// ([`pooled_noise`]), `None` without repeated samples there.
pub fn pooled_variance(
    pool: &BTreeMap<u64, ([f64; 2], usize)>,
    sep: f64,
    axis: usize,
) -> Option<f64> {
    let (ss, dof) = pool.get(&sep.to_bits())?;
    (*dof > 0).then(|| ss[axis] / *dof as f64)
}

/// The point means of `ds`, each weighted by `n / var(separation, axis)` floored at 1/12
/// count^2 (absolute weights).
pub fn point_means(ds: &Dataset, var: &dyn Fn(f64, usize) -> f64) -> Vec<Obs<f64>> {
    ds.points()
        .iter()
        .map(|p| {
            let n = p.rows.len() as f64;
            let mut mean = [0.0; 2];
            for &i in &p.rows {
                mean[0] += ds.samples[i].x / n;
                mean[1] += ds.samples[i].y / n;
            }
            let sep = p.first.separation_in;
            Obs {
                r: Vector3::from(p.first.r),
                y: mean,
                w: [0, 1].map(|a| n / var(sep, a).max(1.0 / 12.0)),
            }
        })
        .collect()
}

/// Why a file cannot be weighted as asked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WeightsError {
    /// `repeat` weights and a point with fewer than [`REPEAT_MIN_SAMPLES`] samples.
    #[error(
        "{}:{line}: --weights repeat needs repeated samples, at least {REPEAT_MIN_SAMPLES} \
         per point, and this point has {}: a variance from so few samples is \
         too rough to weight by (its inverse has an infinite variance, or mean; \
         two equal integer samples give a variance of 0), so the points whose \
         samples happen to agree would carry the fit. Use --weights pooled (the \
         noise pooled per separation, as `cta calibrate` weights) or --weights \
         none",
        .path.display(),
        count_word(.samples)
    )]
    TooFewRepeats {
        /// The measurement file.
        path: PathBuf,
        /// The point's first line.
        line: usize,
        /// Its samples.
        samples: usize,
    },
    /// `pooled` weights and a separation without repeated samples.
    #[error(
        "{}: --weights pooled needs repeated samples at every separation, and {separation} \
         in has none (one sample per point, or every point at the 16-bit rail): use \
         --weights none",
        .path.display()
    )]
    NoRepeats {
        /// The measurement file.
        path: PathBuf,
        /// The separation, in.
        separation: f64,
    },
}

/// `one`, or the number, for [`WeightsError::TooFewRepeats`].
fn count_word(n: &usize) -> String {
    if *n == 1 {
        "one".to_string()
    } else {
        n.to_string()
    }
}

/// Build the GLSDC observations from a dataset (eq 56's residuals and `W`).
pub fn observations(ds: &Dataset, weights: Weights) -> Result<Vec<Obs<f64>>, WeightsError> {
    match weights {
        Weights::None => Ok(ds
            .samples
            .iter()
            .map(|s| Obs {
                r: Vector3::from(s.r),
                y: [s.x, s.y],
                w: [1.0; 2],
            })
            .collect()),
        Weights::Repeat => {
            let mut out = Vec::new();
            for p in ds.points() {
                let n = p.rows.len();
                if n < REPEAT_MIN_SAMPLES {
                    return Err(WeightsError::TooFewRepeats {
                        path: ds.path.clone(),
                        line: p.first.line,
                        samples: n,
                    });
                }
                let mut mean = [0.0; 2];
                for &i in &p.rows {
                    mean[0] += ds.samples[i].x / n as f64;
                    mean[1] += ds.samples[i].y / n as f64;
                }
                let mut var = [0.0; 2];
                for &i in &p.rows {
                    var[0] += (ds.samples[i].x - mean[0]).powi(2) / (n - 1) as f64;
                    var[1] += (ds.samples[i].y - mean[1]).powi(2) / (n - 1) as f64;
                }
                let w = var.map(|v| n as f64 / v.max(1.0 / 12.0));
                out.push(Obs {
                    r: Vector3::from(p.first.r),
                    y: mean,
                    w,
                });
            }
            Ok(out)
        }
        Weights::Pooled => {
            let pool = pooled_noise(ds);
            if let Some(sep) = ds
                .separations()
                .into_iter()
                .find(|&s| pooled_variance(&pool, s, 0).is_none())
            {
                return Err(WeightsError::NoRepeats {
                    path: ds.path.clone(),
                    separation: sep,
                });
            }
            Ok(point_means(ds, &|sep, a| {
                pooled_variance(&pool, sep, a).unwrap_or(f64::NAN)
            }))
        }
    }
}

/// Near-field chi2/dof above which the report warns that the data hold structure the chip's
/// model cannot represent.
pub const CHI2_WARN: f64 = 1.2;

/// The warning for a fit whose chi-square exceeds what the noise gives by `ratio` (above
/// [`CHI2_WARN`]), shared by `cta calibrate` and `cta fit`: `head` states the figure, `model`
/// names the model that cannot represent the data, `file` is the file to analyze.
pub fn misfit_warning(head: &str, ratio: f64, model: &str, file: &Path) -> String {
    format!(
        "{head}: the residuals are {:.1}x the noise, so the data hold structure the {model} \
         cannot represent. The 1-sigma above assume it can: that structure biases the \
         parameters by an amount they do not bound (it can be many 1-sigma; scaling them by \
         that factor, {:.1}x, covers the scatter, not the bias). `cta analyze {}` names what \
         it is.",
        ratio.sqrt(),
        ratio.sqrt(),
        file.display()
    )
}

/// The pooled one-sample noise per separation ([`pooled_noise`], the rule `cta fit
/// --weights pooled` uses): its variance and degrees of freedom, and the file's overall noise.
pub struct Pooled(pub BTreeMap<u64, ([f64; 2], usize)>);

impl Pooled {
    /// The one-sample variance of `axis` (0 = X, 1 = Y) at separation `sep`, counts^2.
    pub fn var(&self, sep: f64, axis: usize) -> Option<f64> {
        pooled_variance(&self.0, sep, axis)
    }
    /// The degrees of freedom behind [`Self::var`] (0 without it).
    pub fn dof(&self, sep: f64) -> usize {
        self.0.get(&sep.to_bits()).map_or(0, |(_, dof)| *dof)
    }
    /// The one-sample noise over the file and both axes, counts.
    pub fn overall(&self) -> Option<f64> {
        let (ss, dof) = self.0.values().fold((0.0, 0), |(s, d), (ss, dof)| {
            (s + ss[0] + ss[1], d + 2 * dof)
        });
        (dof > 0).then(|| (ss / dof as f64).sqrt())
    }
}
