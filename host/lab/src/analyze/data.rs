//! From a measurement file to the weighted point means the analysis fits.
//!
//! The repeated samples of one point (one beacon at one separation and one setting, see
//! [`Dataset::points`]) are averaged; the weight of the mean is `n / sigma^2`, the inverse
//! variance of a mean of `n` samples (eq 56's `W` taken as `R^-1`, the inverse measurement
//! covariance of the thesis's reference 15, Crassidis & Junkins, so chi-square per degree of
//! freedom means something). Where `sigma^2` comes from is the noise model ([`Weights`]):
//!
//! - `separation` (default): the sample variance pooled over every point of a separation,
//!   per axis. Pooling ~100 points gives a variance good to a few percent, where one point's
//!   5-sample variance is good to only ~60 % and its inverse is heavy-tailed (that would bias
//!   chi-square). Noise that changes with separation (the thesis's Ch VI question) is kept.
//! - `setting`: the sample variance pooled over the points of one separation and one setting
//!   (modulation frequency, power level, sensitivity), per axis: for a sweep mixing settings
//!   whose noise differs (a Ch VI sweep), where `separation` would mix them and `point` has too
//!   few samples per point.
//! - `point`: each point's own sample variance (needs ~10+ samples per point; use `cta
//!   noise` first to see whether the noise varies within a separation).
//! - `global`: one pooled variance per axis for the whole file.
//!
//! Every variance is floored at 1/12 count^2, the quantisation noise of integer counts, so
//! noise-free data still has finite weights.
//!
//! Fallback when the file has one sample per point (no repeated samples, no variance): the
//! noise is the `--noise` value in counts, by default [`DEFAULT_NOISE_COUNTS`] = 0.1 % of
//! beta, the level REFERENCE.md's "beyond the thesis" uses. Chi-square is then relative to
//! that assumed noise, and the output says so.
//!
//! Points with any sample at the NorthStar's 16-bit limit (|count| >= 32767: a cell in shadow
//! or a pinned output) carry no usable position information and are left out (counted in
//! [`Data::excluded`]), and so are points whose mean lies within 3 sigma of the limit (their
//! true output was at or past it and only the noise kept the samples inside: clipped, not
//! measured): the rail rule `cta calibrate` and `cta noise` apply
//! ([`crate::data::mean_near_rail`], with the noise pooled per separation whatever
//! the weights: a clipped point's own spread is clipped too).

use crate::data::{fmt_list, Dataset};
use nalgebra::Vector3;

/// Noise assumed when there are no repeated samples: 0.1 % of beta (32.8 counts).
pub const DEFAULT_NOISE_COUNTS: f64 = 32.768;
/// Quantisation floor on every variance, counts^2.
pub const VARIANCE_FLOOR: f64 = 1.0 / 12.0;

/// Why a file gives no weighted points.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DataError {
    /// The one-sample noise given is not a positive number of counts.
    #[error("--noise {0}: must be a positive number of counts")]
    Noise(f64),
    /// Every point is at or near the 16-bit rail.
    #[error(
        "{}: every point has an output at or within 3 sigma of the 16-bit limit \
         (|count| >= 32767): nothing to analyze",
        path.display()
    )]
    AllAtTheRail {
        /// The measurement file.
        path: std::path::PathBuf,
    },
}

/// How the weights are made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
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

/// One averaged point.
#[derive(Debug, Clone, Copy)]
pub struct PointMean {
    /// Index into [`Data::seps`].
    pub sep: usize,
    /// Recorded beacon position, N, inches.
    pub r: Vector3<f64>,
    /// Mean (X, Y), counts.
    pub y: [f64; 2],
    /// Weights of the two means, 1/counts^2.
    pub w: [f64; 2],
    /// Samples averaged.
    pub n: usize,
    /// Beacon id, when the file has one.
    pub beacon: Option<u32>,
    /// Line of the first sample in the file.
    pub line: usize,
}

/// The weighted point means of one file.
#[derive(Debug, Clone)]
pub struct Data {
    /// Distinct recorded separations, ascending, inches.
    pub seps: Vec<f64>,
    /// Averaged points.
    pub points: Vec<PointMean>,
    /// Points left out (an output at or near the 16-bit rail).
    pub excluded: usize,
    /// Samples read.
    pub samples: usize,
    /// Per separation, the 1-sigma noise of one sample (X, Y), counts.
    pub noise_by_sep: Vec<[f64; 2]>,
    /// How the weights were made, in words (printed and reported).
    pub noise_note: String,
    /// True when the noise came from repeated samples, false when assumed.
    pub noise_measured: bool,
    /// Per separation, the plate's tilt (tx, ty) as measured by the corner readings, deg
    /// (set by `cta analyze` from the run's journal, [`crate::sweep::corners`]); empty when
    /// none were read: the plates are taken as level.
    pub measured_tilts_deg: Vec<[f64; 2]>,
}

impl Data {
    /// Average and weight a dataset. `noise`: the one-sample noise (counts) to assume when
    /// the file has no repeated samples (None: [`DEFAULT_NOISE_COUNTS`]); when given and the
    /// file does have repeats, it overrides the measured noise.
    pub fn from_dataset(
        ds: &Dataset,
        weights: Weights,
        noise: Option<f64>,
    ) -> Result<Data, DataError> {
        if let Some(n) = noise {
            if !(n > 0.0 && n.is_finite()) {
                return Err(DataError::Noise(n));
            }
        }
        let seps = ds.separations();
        let sep_index = |s: f64| seps.iter().position(|&v| v == s).unwrap_or(0);
        let groups = ds.points();
        // Per point: mean, sum of squared deviations, count.
        struct Acc {
            sep: usize,
            r: Vector3<f64>,
            mean: [f64; 2],
            ss: [f64; 2],
            n: usize,
            beacon: Option<u32>,
            line: usize,
            pinned: bool,
            /// The setting: frequency, power, sensitivity (as bits, NaN when not recorded).
            setting: [u64; 3],
        }
        let mut acc: Vec<Acc> = Vec::with_capacity(groups.len());
        for g in &groups {
            let n = g.rows.len();
            let mut mean = [0.0; 2];
            // The rail rule's first half, shared with `cta calibrate` and `cta noise`.
            let pinned = crate::data::any_sample_pinned(g.rows.iter().map(|&i| &ds.samples[i]));
            for &i in &g.rows {
                let s = &ds.samples[i];
                mean[0] += s.x;
                mean[1] += s.y;
            }
            mean[0] /= n as f64;
            mean[1] /= n as f64;
            let mut ss = [0.0; 2];
            for &i in &g.rows {
                let s = &ds.samples[i];
                ss[0] += (s.x - mean[0]).powi(2);
                ss[1] += (s.y - mean[1]).powi(2);
            }
            acc.push(Acc {
                sep: sep_index(g.first.separation_in),
                r: Vector3::from(g.first.r),
                mean,
                ss,
                n,
                beacon: g.first.beacon,
                line: g.first.line,
                pinned,
                setting: [g.first.frequency_hz, g.first.power, g.first.sensitivity]
                    .map(|v| v.unwrap_or(f64::NAN).to_bits()),
            });
        }
        let repeated = acc.iter().any(|a| a.n > 1);
        // Pooled variances per separation and globally.
        let mut pool = vec![([0.0f64; 2], 0usize); seps.len()];
        let mut gpool = ([0.0f64; 2], 0usize);
        let mut spool: std::collections::BTreeMap<(usize, [u64; 3]), ([f64; 2], usize)> =
            std::collections::BTreeMap::new();
        for a in acc.iter().filter(|a| !a.pinned && a.n > 1) {
            let sp = spool.entry((a.sep, a.setting)).or_default();
            for k in 0..2 {
                pool[a.sep].0[k] += a.ss[k];
                gpool.0[k] += a.ss[k];
                sp.0[k] += a.ss[k];
            }
            pool[a.sep].1 += a.n - 1;
            gpool.1 += a.n - 1;
            sp.1 += a.n - 1;
        }
        let sep_var = |sep: usize, k: usize| {
            (pool[sep].1 > 0).then(|| (pool[sep].0[k] / pool[sep].1 as f64).max(VARIANCE_FLOOR))
        };
        let gvar = |k: usize| {
            if gpool.1 > 0 {
                (gpool.0[k] / gpool.1 as f64).max(VARIANCE_FLOOR)
            } else {
                VARIANCE_FLOOR
            }
        };
        let (noise_note, noise_measured);
        let var_of = |a: &Acc, k: usize| -> f64 {
            if let Some(n) = noise {
                return n * n;
            }
            if !repeated {
                return DEFAULT_NOISE_COUNTS * DEFAULT_NOISE_COUNTS;
            }
            match weights {
                Weights::Point if a.n > 1 => (a.ss[k] / (a.n - 1) as f64).max(VARIANCE_FLOOR),
                Weights::Setting => match spool.get(&(a.sep, a.setting)) {
                    Some((ss, dof)) if *dof > 0 => (ss[k] / *dof as f64).max(VARIANCE_FLOOR),
                    _ => sep_var(a.sep, k).unwrap_or_else(|| gvar(k)),
                },
                Weights::Separation => sep_var(a.sep, k).unwrap_or_else(|| gvar(k)),
                _ => gvar(k),
            }
        };
        if let Some(n) = noise {
            noise_note = format!("noise set by --noise: {n} counts per sample (both axes)");
            noise_measured = false;
        } else if !repeated {
            noise_note = format!(
                "one sample per point: noise ASSUMED {DEFAULT_NOISE_COUNTS:.1} counts per sample \
                 (0.1 % of beta); chi-square is relative to that assumption (set --noise)"
            );
            noise_measured = false;
        } else {
            noise_note = match weights {
                Weights::Separation => {
                    "noise from repeated samples, pooled per separation and axis".into()
                }
                Weights::Setting => "noise from repeated samples, pooled per separation, setting \
                                     (frequency, power, sensitivity) and axis"
                    .into(),
                Weights::Point => "noise from each point's repeated samples".into(),
                Weights::Global => {
                    "noise from repeated samples, pooled over the file per axis".into()
                }
            };
            noise_measured = true;
        }
        let mut points = Vec::with_capacity(acc.len());
        let mut excluded = 0;
        // The rail rule's noise is the pooled one whatever the weights (a clipped point's own
        // spread is clipped too): per separation, else the file's, else as assumed.
        let rail_sigma = |a: &Acc| -> f64 {
            let v = |k: usize| match noise {
                Some(n) => n * n,
                None if !repeated => DEFAULT_NOISE_COUNTS * DEFAULT_NOISE_COUNTS,
                None => sep_var(a.sep, k).unwrap_or_else(|| gvar(k)),
            };
            v(0).max(v(1)).sqrt()
        };
        for a in &acc {
            if a.pinned || crate::data::mean_near_rail(a.mean, rail_sigma(a), a.n) {
                excluded += 1;
                continue;
            }
            let n = a.n as f64;
            points.push(PointMean {
                sep: a.sep,
                r: a.r,
                y: a.mean,
                w: [n / var_of(a, 0), n / var_of(a, 1)],
                n: a.n,
                beacon: a.beacon,
                line: a.line,
            });
        }
        let noise_by_sep = (0..seps.len())
            .map(|s| {
                let probe = acc.iter().find(|a| a.sep == s && !a.pinned);
                // Pooled per setting, the separation's noise is the one over its settings.
                if let (Weights::Setting, Some(_), true, None) = (weights, probe, repeated, noise) {
                    if let (Some(x), Some(y)) = (sep_var(s, 0), sep_var(s, 1)) {
                        return [x.sqrt(), y.sqrt()];
                    }
                }
                match probe {
                    Some(a) => [var_of(a, 0).sqrt(), var_of(a, 1).sqrt()],
                    None => [f64::NAN; 2],
                }
            })
            .collect();
        if points.is_empty() {
            return Err(DataError::AllAtTheRail {
                path: ds.path.clone(),
            });
        }
        Ok(Data {
            seps,
            points,
            excluded,
            samples: ds.samples.len(),
            noise_by_sep,
            noise_note,
            noise_measured,
            measured_tilts_deg: Vec::new(),
        })
    }

    /// Number of points at each separation.
    pub fn points_per_sep(&self) -> Vec<usize> {
        let mut c = vec![0; self.seps.len()];
        for p in &self.points {
            c[p.sep] += 1;
        }
        c
    }

    /// The separations as a compact list.
    pub fn seps_text(&self) -> String {
        fmt_list(&self.seps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::SimConfig;

    /// The rail rule, both halves: a point with a sample at +/-32767 is left out, and so is
    /// one whose samples all stay inside but whose mean lies within 3 sigma of the rail (a
    /// cell in shadow whose noise kept it a few counts below), as `cta calibrate` does.
    #[test]
    fn points_at_or_near_the_rail_are_left_out() {
        let mut ds = SimConfig {
            separations: vec![20.0],
            noise: 30.0,
            samples: 5,
            ..Default::default()
        }
        .run()
        .0;
        let clean = Data::from_dataset(&ds, Weights::Separation, None).unwrap();
        let points = ds.points();
        let (near, far) = (&points[0], &points[1]);
        // Inside the rail by 10 to 50 counts: well within 3 sigma of the mean (40 counts).
        for (j, &i) in near.rows.iter().enumerate() {
            ds.samples[i].x = 32757.0 - 10.0 * j as f64;
        }
        // Still clearly inside: 20 sigma of the mean below.
        for &i in &far.rows {
            ds.samples[i].y = -32000.0;
        }
        let d = Data::from_dataset(&ds, Weights::Separation, None).unwrap();
        assert_eq!(d.excluded, clean.excluded + 1);
        assert_eq!(d.points.len(), clean.points.len() - 1);
        // With per-point weights too, though the clipped point's own spread is tiny.
        for &i in &near.rows {
            ds.samples[i].x = 32766.0;
            ds.samples[i].y = 400.0;
        }
        let d = Data::from_dataset(&ds, Weights::Point, None).unwrap();
        assert_eq!(d.excluded, clean.excluded + 1);
        ds.samples[near.rows[0]].x = 32767.0;
        let d = Data::from_dataset(&ds, Weights::Separation, None).unwrap();
        assert_eq!(d.excluded, clean.excluded + 1);
    }

    /// `setting` pools per separation and setting: points of a noisier power level get
    /// their level's smaller weight, where `separation` gives every point of a separation one.
    #[test]
    fn setting_weights_pool_per_separation_and_setting() {
        let mut ds = SimConfig {
            separations: vec![5.0, 20.0],
            noise: 30.0,
            samples: 5,
            ..Default::default()
        }
        .run()
        .0;
        for (k, p) in ds.points().iter().enumerate() {
            for (j, &i) in p.rows.iter().enumerate() {
                let s = &mut ds.samples[i];
                s.power = Some(if k % 2 == 0 { 2.0 } else { 1.0 });
                if k % 2 == 0 {
                    s.x += if j % 2 == 0 { 60.0 } else { -60.0 };
                }
            }
        }
        let w = |weights: Weights, power: f64| -> Vec<f64> {
            let d = Data::from_dataset(&ds, weights, None).unwrap();
            let mut out: Vec<f64> = d
                .points
                .iter()
                .filter(|p| {
                    let sep = d.seps[p.sep];
                    let s = ds
                        .samples
                        .iter()
                        .find(|s| s.separation_in == sep && Vector3::from(s.r) == p.r)
                        .unwrap();
                    s.power == Some(power) && sep == 20.0
                })
                .map(|p| p.w[0] / p.n as f64)
                .collect();
            out.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
            out
        };
        // One weight per separation and setting; the noisy level's noise is ~3x the other's.
        let (loud, quiet) = (w(Weights::Setting, 2.0), w(Weights::Setting, 1.0));
        assert_eq!((loud.len(), quiet.len()), (1, 1), "{loud:?} {quiet:?}");
        assert!(quiet[0] / loud[0] > 4.0, "{loud:?} {quiet:?}");
        assert_eq!(w(Weights::Separation, 2.0), w(Weights::Separation, 1.0));
        let d = Data::from_dataset(&ds, Weights::Setting, None).unwrap();
        assert!(
            d.noise_note.contains("per separation, setting"),
            "{}",
            d.noise_note
        );
    }
}
