//! The glitch check: samples far beyond the noise from their point's median (an ID mix-up, a
//! corrupted report), found with a robust sigma so that they cannot hide themselves.

use std::collections::HashMap;
use std::path::Path;

use super::sample::key_bits;
use super::{any_sample_pinned, Dataset, Point, Sample};

impl Dataset {
    /// The glitch check ([`Glitches`]): each sample of a point with
    /// [`GLITCH_MIN_SAMPLES`] or more samples (points at the 16-bit rail,
    /// [`any_sample_pinned`], left out) against its point's median, per axis, in units of
    /// the robust noise of its separation and setting. Nothing is dropped: it only says which
    /// rows stand out and what they do to the pooled noise.
    pub fn glitches(&self) -> Glitches {
        glitch_check(self)
    }

    /// The dataset without the samples the glitch check flags ([`Dataset::glitches`]): what
    /// `--drop-glitches` fits (`cta analyze`, `cta fit`, `cta calibrate`) and evaluates
    /// (`cta evaluate`), with what was left out. `None` when nothing is flagged. The file is
    /// not changed.
    pub fn without_glitches(&self) -> Option<WithoutGlitches> {
        let g = self.glitches();
        if g.samples == 0 {
            return None;
        }
        let flagged: std::collections::BTreeSet<usize> = g.rows.iter().copied().collect();
        let data = Dataset {
            path: self.path.clone(),
            samples: (self.samples.iter().enumerate())
                .filter(|(i, _)| !flagged.contains(i))
                .map(|(_, s)| *s)
                .collect(),
        };
        let mut lines: Vec<usize> = g.rows.iter().map(|&r| self.samples[r].line).collect();
        lines.sort_unstable();
        Some(WithoutGlitches {
            data,
            samples: g.samples,
            lines,
        })
    }
}

/// The glitch threshold, in robust sigma: a sample this far from its point's median is a
/// glitch. Gaussian noise gets there about once in 10^15 samples, while an ID mix-up or a
/// corrupted report lies far beyond it.
pub const GLITCH_SIGMA: f64 = 8.0;

/// Samples a point needs for the glitch check: with 2, either sample may be the odd one out.
pub const GLITCH_MIN_SAMPLES: usize = 3;

/// The robust sigma is never taken below this (counts): the NorthStar reports whole counts, so
/// with a sub-count noise most deviations are 0 and their median says nothing.
pub const GLITCH_FLOOR_COUNTS: f64 = 1.0;

/// Deviations a group (separation and setting; else separation; else the file) needs before
/// its median absolute deviation is used as the robust sigma (to ~20 %).
const GLITCH_MIN_DEVIATIONS: usize = 50;

/// Median of `|x_i - median(x)|` over the samples of a point of `n` standard Gaussian samples
/// (for odd `n` without the median sample itself, whose deviation is 0), `n` = 3..=64: the
/// factor that turns the median absolute deviation of points of `n` samples into sigma. Odd
/// and even `n` differ (0.69 and 0.49 at 3 and 4: of an even count the two middle samples lie
/// half their spacing from the median). Monte Carlo, 8,000,000 samples per `n` (to ~0.1 %).
const MAD_FACTOR: [f64; 62] = [
    0.6900, 0.4865, 0.6853, 0.5280, 0.6829, 0.5637, 0.6806, 0.5878, 0.6800, 0.6040, 0.6787, 0.6151,
    0.6786, 0.6235, 0.6778, 0.6296, 0.6782, 0.6346, 0.6769, 0.6386, 0.6768, 0.6420, 0.6762, 0.6448,
    0.6769, 0.6464, 0.6766, 0.6482, 0.6765, 0.6503, 0.6765, 0.6519, 0.6763, 0.6528, 0.6760, 0.6548,
    0.6760, 0.6557, 0.6763, 0.6562, 0.6758, 0.6575, 0.6753, 0.6581, 0.6758, 0.6589, 0.6757, 0.6594,
    0.6756, 0.6600, 0.6753, 0.6605, 0.6755, 0.6613, 0.6753, 0.6622, 0.6751, 0.6623, 0.6760, 0.6624,
    0.6756, 0.6628,
];

/// [`MAD_FACTOR`] for any `n` >= 3; beyond the table (within 1.5 % of it at 64) the large-`n` law
/// `0.6745 sqrt(1 - (2 - pi/2)/n)` (the deviation from the median has variance
/// `sigma^2 (1 - 2/n + var(median)/sigma^2)`, `var(median) = pi sigma^2/(2n)`).
fn mad_factor(n: usize) -> f64 {
    match MAD_FACTOR.get(n.wrapping_sub(3)) {
        Some(f) => *f,
        None => 0.674_489_75 * (1.0 - (2.0 - std::f64::consts::FRAC_PI_2) / n as f64).sqrt(),
    }
}

/// The glitch check of one axis (X or Y).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct AxisGlitches {
    /// `X` or `Y`.
    pub axis: String,
    /// Robust one-sample sigma over the file, counts: the median absolute deviation from each
    /// point's median, each scaled to sigma for its point's number of samples. `NaN` (`null`)
    /// when no point has [`GLITCH_MIN_SAMPLES`] samples.
    pub robust_sigma: f64,
    /// One-sample std pooled over the points checked (deviations from each point's mean over
    /// its degrees of freedom), counts: what the fits weight by.
    pub std_with: f64,
    /// The same without this axis's glitches.
    pub std_without: f64,
    /// Samples beyond [`GLITCH_SIGMA`] robust sigma on this axis.
    pub samples: usize,
    /// Their 1-based line numbers, in file order.
    pub lines: Vec<usize>,
}

impl AxisGlitches {
    /// How many times the glitches inflate the pooled std (`std_with / std_without`).
    pub fn inflation(&self) -> f64 {
        self.std_with / self.std_without
    }
}

/// The glitch check ([`Dataset::glitches`]).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Glitches {
    /// The threshold, robust sigma ([`GLITCH_SIGMA`]).
    pub threshold_sigma: f64,
    /// Points checked: [`GLITCH_MIN_SAMPLES`] or more samples, none pinned at the rail.
    pub points_checked: usize,
    /// Their samples.
    pub samples_checked: usize,
    /// Samples that are glitches on either axis.
    pub samples: usize,
    /// Their indices in [`Dataset::samples`] (not in JSON: `axes` has their lines).
    #[serde(skip)]
    pub rows: Vec<usize>,
    /// X, then Y.
    pub axes: Vec<AxisGlitches>,
}

impl Glitches {
    /// The load-time warning (without `warning: `), when there are glitches; `rows` is the
    /// file's number of rows.
    pub fn warning(&self, path: &Path, rows: usize) -> Option<String> {
        if self.samples == 0 {
            return None;
        }
        let hit: Vec<&AxisGlitches> = self.axes.iter().filter(|a| a.samples > 0).collect();
        let lines = hit
            .iter()
            .map(|a| {
                let shown: Vec<String> = a.lines.iter().take(5).map(|l| l.to_string()).collect();
                format!(
                    "{} at line{} {}{}",
                    a.axis,
                    if a.lines.len() == 1 { "" } else { "s" },
                    shown.join(", "),
                    if a.lines.len() > 5 { ", ..." } else { "" }
                )
            })
            .collect::<Vec<_>>()
            .join("; ");
        let inflate = hit
            .iter()
            .map(|a| {
                format!(
                    "from {} {:.1}-fold (std {:.2} counts with them, {:.2} without; robust sigma {:.2})",
                    a.axis,
                    a.inflation(),
                    a.std_with,
                    a.std_without,
                    a.robust_sigma
                )
            })
            .collect::<Vec<_>>()
            .join(" and ");
        let percent = 100.0 * self.samples as f64 / rows.max(1) as f64;
        let share = if percent < 0.05 {
            "under 0.1 %".to_string()
        } else {
            format!("{percent:.1} %")
        };
        Some(format!(
            "{}: {} sample{} ({share} of the rows) lie{} more than {} robust sigma from {} point's \
             median ({lines}): glitches (an ID mix-up, a corrupted report?) that inflate the noise \
             pooled {inflate}; every fit weights by that noise. Remove those lines, or re-measure \
             (`--drop-glitches` leaves them out of `cta fit`, `cta evaluate`, `cta calibrate` \
             and `cta analyze`, the file unchanged)",
            path.display(),
            self.samples,
            if self.samples == 1 { "" } else { "s" },
            if self.samples == 1 { "s" } else { "" },
            self.threshold_sigma,
            if self.samples == 1 { "its" } else { "their" },
        ))
    }
}

/// A dataset without its glitches ([`Dataset::without_glitches`]).
#[derive(Debug, Clone)]
pub struct WithoutGlitches {
    /// The rows that are not flagged, in file order.
    pub data: Dataset,
    /// How many samples were left out.
    pub samples: usize,
    /// Their 1-based lines, ascending.
    pub lines: Vec<usize>,
}

impl WithoutGlitches {
    /// Where they are, for messages: `line 4242`, `lines 9, 402`, the first five then `...`.
    pub fn where_(&self) -> String {
        let shown: Vec<String> = self.lines.iter().take(5).map(|l| l.to_string()).collect();
        format!(
            "line{} {}{}",
            if self.samples == 1 { "" } else { "s" },
            shown.join(", "),
            if self.lines.len() > 5 { ", ..." } else { "" }
        )
    }

    /// The note `cta analyze`, `cta fit`, `cta evaluate` and `cta calibrate` print when
    /// `--drop-glitches` left them out: `3 glitched samples left out (--drop-glitches; lines
    /// 9, 402, 977); the file is unchanged`.
    pub fn note(&self) -> String {
        format!(
            "{} glitched sample{} left out (--drop-glitches; {}); the file is unchanged",
            self.samples,
            if self.samples == 1 { "" } else { "s" },
            self.where_()
        )
    }
}

/// The median of `v` (sorted in place); `NaN` when empty.
fn median_of(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// [`Dataset::glitches`].
fn glitch_check(ds: &Dataset) -> Glitches {
    // One deviation from a point's median: its row, and `|d| / mad_factor(n)` (an estimate
    // of sigma whose median over Gaussian samples is sigma) when it enters the scale.
    struct Dev {
        row: usize,
        point: usize,
        dev: f64,
        scaled: Option<f64>,
        group: [u64; 4],
    }
    let points: Vec<Point> = ds
        .points()
        .into_iter()
        .filter(|p| {
            p.rows.len() >= GLITCH_MIN_SAMPLES
                && !any_sample_pinned(p.rows.iter().map(|&i| &ds.samples[i]))
        })
        .collect();
    let value = |s: &Sample, a: usize| if a == 0 { s.x } else { s.y };
    let mut glitched = vec![false; ds.samples.len()];
    let mut axes = Vec::new();
    for (a, name) in ["X", "Y"].into_iter().enumerate() {
        let mut devs: Vec<Dev> = Vec::new();
        for (k, p) in points.iter().enumerate() {
            let s0 = &p.first;
            let group = [
                key_bits(s0.separation_in),
                key_bits(s0.frequency_hz.unwrap_or(f64::NAN)),
                key_bits(s0.power.unwrap_or(f64::NAN)),
                key_bits(s0.sensitivity.unwrap_or(f64::NAN)),
            ];
            let n = p.rows.len();
            let mut order: Vec<usize> = p.rows.clone();
            order.sort_by(|&i, &j| value(&ds.samples[i], a).total_cmp(&value(&ds.samples[j], a)));
            let mut v: Vec<f64> = order.iter().map(|&i| value(&ds.samples[i], a)).collect();
            let med = median_of(&mut v);
            let f = mad_factor(n);
            for (j, &row) in order.iter().enumerate() {
                let dev = value(&ds.samples[row], a) - med;
                // The median sample of an odd count deviates by 0 by construction.
                let scaled = (n % 2 == 0 || j != n / 2).then(|| dev.abs() / f);
                devs.push(Dev {
                    row,
                    point: k,
                    dev,
                    scaled,
                    group,
                });
            }
        }
        // Robust sigma per separation and setting, per separation, and over the file.
        let mut by_setting: HashMap<[u64; 4], Vec<f64>> = HashMap::new();
        let mut by_sep: HashMap<u64, Vec<f64>> = HashMap::new();
        let mut all: Vec<f64> = Vec::new();
        for d in &devs {
            if let Some(v) = d.scaled {
                by_setting.entry(d.group).or_default().push(v);
                by_sep.entry(d.group[0]).or_default().push(v);
                all.push(v);
            }
        }
        let robust = |v: &mut Vec<f64>| (v.len() >= GLITCH_MIN_DEVIATIONS).then(|| median_of(v));
        let setting_sigma: HashMap<[u64; 4], Option<f64>> = by_setting
            .into_iter()
            .map(|(k, mut v)| (k, robust(&mut v)))
            .collect();
        let sep_sigma: HashMap<u64, Option<f64>> = by_sep
            .into_iter()
            .map(|(k, mut v)| (k, robust(&mut v)))
            .collect();
        let file_sigma = robust(&mut all.clone());
        let robust_sigma = median_of(&mut all);
        let mut lines = Vec::new();
        let mut out = vec![false; devs.len()];
        for (i, d) in devs.iter().enumerate() {
            let sigma = setting_sigma[&d.group]
                .or(sep_sigma[&d.group[0]])
                .or(file_sigma);
            if let Some(sigma) = sigma {
                if d.dev.abs() > GLITCH_SIGMA * sigma.max(GLITCH_FLOOR_COUNTS) {
                    out[i] = true;
                    glitched[d.row] = true;
                    lines.push(ds.samples[d.row].line);
                }
            }
        }
        lines.sort_unstable();
        // The pooled std with and without them (deviations from each point's mean).
        let pooled = |keep: &dyn Fn(usize) -> bool| {
            let (mut ss, mut dof) = (0.0, 0usize);
            let mut i = 0;
            while i < devs.len() {
                let k = devs[i].point;
                let j = i + devs[i..].iter().take_while(|d| d.point == k).count();
                let v: Vec<f64> = (i..j)
                    .filter(|&m| keep(m))
                    .map(|m| value(&ds.samples[devs[m].row], a))
                    .collect();
                if v.len() >= 2 {
                    let mean = v.iter().sum::<f64>() / v.len() as f64;
                    ss += v.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
                    dof += v.len() - 1;
                }
                i = j;
            }
            if dof == 0 {
                f64::NAN
            } else {
                (ss / dof as f64).sqrt()
            }
        };
        axes.push(AxisGlitches {
            axis: name.into(),
            robust_sigma,
            std_with: pooled(&|_| true),
            std_without: pooled(&|m| !out[m]),
            samples: lines.len(),
            lines,
        });
    }
    Glitches {
        threshold_sigma: GLITCH_SIGMA,
        points_checked: points.len(),
        samples_checked: points.iter().map(|p| p.rows.len()).sum(),
        samples: glitched.iter().filter(|g| **g).count(),
        rows: (0..glitched.len()).filter(|&r| glitched[r]).collect(),
        axes,
    }
}
