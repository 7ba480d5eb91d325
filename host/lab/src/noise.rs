//! `cta noise`: the noise questions the thesis leaves open (Ch VI, "Future Work": "work also
//! needs to be performed to determine a suitable weighting matrix").
//!
//! From the repeated samples of each point (one beacon at one separation and one setting,
//! [`Dataset::points`]) it takes the sample variance, and pools it (sum of squared
//! deviations over sum of degrees of freedom) by each factor the file records: separation,
//! off-boresight angle, signal magnitude, modulation frequency, power level and
//! sensitivity setting. It reports the one-sample standard deviation per axis for each
//! group, the X-Y correlation, and the weighting the spread implies for `cta fit` and
//! `cta analyze` (eq 56's `W` taken as `R^-1`, the thesis's reference 15, Crassidis &
//! Junkins): one variance for the file when the groups agree, per separation when they
//! differ by separation (the `analyze --weights separation` default), per point when they
//! differ within a separation. Whether the groups of a factor
//! differ is Bartlett's chi-square test of equal variances (each axis at 0.5 %), which holds
//! its false-alarm rate however many groups there are; each group's standard deviation carries
//! its standard error from sampling, `std / sqrt(2 dof)`, the error bar of the plot.
//!
//! Points at the 16-bit rail are left out, by `cta calibrate`'s rule
//! ([`crate::data::any_sample_pinned`], [`crate::data::mean_near_rail`]): a
//! coordinate pinned at +/-32767 in any sample, or the mean within 3 sigma of it. A cell in
//! shadow or saturated clips the spread, so such a point reads quieter than the sensor is.
//!
//! Every figure is a standard deviation, which a few glitches (an ID mix-up, a corrupted
//! report) inflate many-fold, so it also gives per axis the robust sigma (the median absolute
//! deviation from each point's median, [`Dataset::glitches`]) against the std, and the samples
//! beyond [`crate::data::GLITCH_SIGMA`] robust sigma with their lines: a std well above
//! the robust sigma is a heavy tail. Those samples stay in every figure (the load-time warning
//! names them too); removing them is the user's call.
//!
//! It also gives the repeatability of the spot magnitude (the one-sample standard deviation
//! of each point's magnitude relative to its mean, pooled overall and per separation): the
//! figure `cta sensor floor --magnitude-noise` needs to tell what the magnitudes would add to
//! the pose. It covers noise only; brightness differences between LEDs are a calibration.
//!
//! The off-boresight angle here is geometric (no model): the angle of the beacon from the
//! board normal seen from the N origin, `atan(hypot(x, y) / z)`.

use crate::data::{any_sample_pinned, mean_near_rail, Dataset, Glitches, Sample};
use crate::plot::{render_svg, Panel, Series};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Why the noise cannot be measured, or its plots not written.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NoiseError {
    /// Every point with repeated samples is at the 16-bit rail.
    #[error(
        "{}: no point with repeated samples is left once the points at the 16-bit rail are \
         left out ({pinned} with a coordinate pinned at +/-32767 in some sample, {near_rail} \
         with a mean within 3 sigma of it: a cell in shadow or saturated clips the spread)",
        path.display()
    )]
    AllAtTheRail {
        /// The measurement file.
        path: PathBuf,
        /// Points with a coordinate pinned in some sample.
        pinned: usize,
        /// Points with a mean within 3 sigma of the rail.
        near_rail: usize,
    },
    /// No point has repeated samples.
    #[error(
        "{}: every point has a single sample: the noise needs repeated samples of one \
         beacon at one setting (e.g. `cta simulate --samples 20`, or a sweep with several \
         samples per beacon)",
        path.display()
    )]
    SingleSamples {
        /// The measurement file.
        path: PathBuf,
    },
    /// A plot file may not be replaced, or could not be written.
    #[error("{0}")]
    Write(String),
    /// The plots could not be drawn.
    #[error("plotting failed: {0}")]
    Plot(String),
}

/// Pooled noise of one group of points.
#[derive(Debug, Clone, Serialize)]
pub struct Group {
    /// Group label (e.g. "10 in", "20-30 deg").
    pub label: String,
    /// Numeric key for plots (separation, angle bin centre, ...).
    pub key: f64,
    /// Points with repeated samples.
    pub points: usize,
    /// Degrees of freedom pooled (samples minus points).
    pub dof: usize,
    /// One-sample standard deviation of X, counts.
    pub std_x: f64,
    /// Of Y.
    pub std_y: f64,
    /// Standard error of `std_x` from sampling alone ([`std_standard_error`]), counts: the
    /// error bar of the plot.
    pub se_x: f64,
    /// Of `std_y`.
    pub se_y: f64,
}

/// The sampling law behind both the error bars and the homogeneity test: a variance pooled
/// over `dof` degrees of freedom of Gaussian noise has relative standard deviation
/// `sqrt(2 / dof)` (chi-square), so its root, the standard deviation, has standard error
/// `std / sqrt(2 dof)`.
pub fn std_standard_error(std: f64, dof: usize) -> f64 {
    if dof == 0 {
        f64::NAN
    } else {
        std / (2.0 * dof as f64).sqrt()
    }
}

/// Noise by one factor.
#[derive(Debug, Clone, Serialize)]
pub struct Factor {
    /// Factor name.
    pub factor: String,
    /// Groups (empty when the file does not record the factor).
    pub groups: Vec<Group>,
    /// Largest over smallest group std (both axes), 1 when uniform; `NaN` (`null` in JSON)
    /// with fewer than 2 groups of 2 or more degrees of freedom (no ratio between groups).
    pub spread_ratio: f64,
    /// Bartlett's homogeneity statistic of the group variances, X and Y (chi-square with
    /// `test_dof` degrees of freedom when only sampling separates the groups); `NaN` when
    /// fewer than 2 groups have 2 or more degrees of freedom.
    pub statistic: [f64; 2],
    /// Degrees of freedom of the statistic: groups tested minus 1.
    pub test_dof: usize,
    /// The statistic's 99.5 % point for `test_dof` (each axis at 0.5 %, so about 1 % that
    /// either axis passes it by sampling alone, however many groups).
    pub bound: f64,
    /// Whether the spread exceeds what sampling alone explains: a statistic above `bound`.
    pub significant: bool,
}

/// The `cta noise` result.
#[derive(Debug, Clone, Serialize)]
pub struct NoiseReport {
    /// File.
    pub file: String,
    /// Samples read.
    pub samples: usize,
    /// Points with repeated samples.
    pub points_repeated: usize,
    /// Points with one sample (no variance).
    pub points_single: usize,
    /// Points left out of the X, Y noise (their spread is clipped by the 16-bit rail).
    pub left_out: LeftOut,
    /// Pooled one-sample std over the file (X, Y), counts.
    pub std_all: [f64; 2],
    /// Pooled X-Y correlation of the deviations.
    pub xy_correlation: f64,
    /// The glitch check ([`Dataset::glitches`]): per axis the robust sigma (median absolute
    /// deviation from each point's median) against the std, and the samples beyond
    /// [`crate::data::GLITCH_SIGMA`] robust sigma with their lines. A std well above the
    /// robust sigma is a heavy tail: glitches, which every figure here still includes.
    pub glitches: Glitches,
    /// Noise by factor.
    pub factors: Vec<Factor>,
    /// Standard deviation of the point variances within a separation relative to what
    /// sampling alone gives (1 = homogeneous within a separation).
    pub within_separation_dispersion: f64,
    /// The same within a separation and a setting (modulation frequency, power level,
    /// sensitivity): near 1 when only the settings make the noise differ within a separation.
    pub within_setting_dispersion: f64,
    /// The weighting it implies.
    pub weighting: String,
    /// Spot magnitude repeatability (`None` when the file records no magnitudes).
    pub magnitude: Option<MagnitudeNoise>,
    /// The crosstalk check of a grouped sweep: beacons measured alone and in their group
    /// (`None` when the file has none).
    pub crosstalk: Option<crate::crosstalk::Check>,
}

/// Points left out of the X, Y noise by `cta calibrate`'s rail rule: a coordinate pinned at
/// +/-32767 in any sample, or the point's mean within 3 sigma of it (sigma: the one-sample
/// noise pooled over the other points, over the root of the point's samples). A cell in shadow
/// or saturated clips the spread, so such a point would read quieter than the sensor is.
#[derive(Debug, Clone, Serialize)]
pub struct LeftOut {
    /// Points left out.
    pub points: usize,
    /// Of which with a coordinate pinned at +/-32767 in some sample.
    pub pinned_sample: usize,
    /// Of which with no pinned sample but a mean within 3 sigma of the rail.
    pub mean_near_rail: usize,
    /// By separation: (separation in, points left out), only separations with some.
    pub by_separation: Vec<(f64, usize)>,
}

/// Repeatability of the spot magnitude: one-sample standard deviation relative to the
/// point's mean magnitude, pooled (root of the summed relative squared deviations over the
/// summed degrees of freedom).
#[derive(Debug, Clone, Serialize)]
pub struct MagnitudeNoise {
    /// Points pooled (repeated samples, not left out at the X, Y rail, every sample with a
    /// positive magnitude below the 16-bit ceiling [`MAGNITUDE_CEILING`]: a pinned magnitude
    /// has no spread to measure).
    pub points: usize,
    /// Over the file, percent.
    pub percent: f64,
    /// By separation: (separation in, percent, points).
    pub by_separation: Vec<(f64, f64, usize)>,
}

/// Samples per point from which a point's own variance is good enough to weight by
/// (`cta analyze --weights point`): to 47 % at 10 samples, with its inverse biased high by
/// 9/7; at 5 samples 71 % and 2x, which turns clean data into "unexplained structure".
pub const POINT_MIN_SAMPLES: usize = 10;

/// The NorthStar reports magnitudes as 16-bit counts: at this value the magnitude is pinned
/// (a bright spot), and a point with any pinned sample is left out of the repeatability.
pub const MAGNITUDE_CEILING: f64 = 65535.0;

struct Pt {
    first: Sample,
    n: usize,
    /// Mean (X, Y), counts.
    mean: [f64; 2],
    ss: [f64; 2],
    sxy: f64,
    /// Sum of squared relative deviations of the magnitude (`None` unless every sample has a
    /// positive magnitude).
    ss_mag_rel: Option<f64>,
}

fn pool(label: String, key: f64, pts: &[&Pt]) -> Group {
    let dof: usize = pts.iter().map(|p| p.n - 1).sum();
    let d = dof.max(1) as f64;
    let std_x = (pts.iter().map(|p| p.ss[0]).sum::<f64>() / d).sqrt();
    let std_y = (pts.iter().map(|p| p.ss[1]).sum::<f64>() / d).sqrt();
    Group {
        label,
        key,
        points: pts.len(),
        dof,
        std_x,
        std_y,
        se_x: std_standard_error(std_x, dof),
        se_y: std_standard_error(std_y, dof),
    }
}

/// Upper `p` point of the chi-square distribution with `k` degrees of freedom (Wilson and
/// Hilferty's cube-root approximation: within 1 % of the table from 1 degree of freedom on, at
/// the 99.5 % point used here), `z` the standard normal's upper `p` point.
fn chi2_upper(k: usize, z: f64) -> f64 {
    let k = k as f64;
    let c = 2.0 / (9.0 * k);
    k * (1.0 - c + z * c.sqrt()).powi(3)
}

/// Standard normal's 99.5 % point.
const Z_995: f64 = 2.575_829;

/// Bartlett's statistic for equal variances over groups `(variance, dof)`: under Gaussian
/// noise of one variance it is chi-square with (groups - 1) degrees of freedom, whatever the
/// number of groups (testing every pair against a fixed bound instead flags one of many
/// groups as different by chance alone). `NaN` with fewer than 2 groups; infinite when some
/// variances are 0 and others are not.
fn bartlett(groups: &[(f64, usize)]) -> f64 {
    let k = groups.len();
    if k < 2 {
        return f64::NAN;
    }
    let n: f64 = groups.iter().map(|g| g.1 as f64).sum();
    let pooled = groups.iter().map(|g| g.0 * g.1 as f64).sum::<f64>() / n;
    if pooled <= 0.0 {
        return 0.0;
    }
    if groups.iter().any(|g| g.0 <= 0.0) {
        return f64::INFINITY;
    }
    let num = n * pooled.ln() - groups.iter().map(|g| g.1 as f64 * g.0.ln()).sum::<f64>();
    let c = 1.0
        + (groups.iter().map(|g| 1.0 / g.1 as f64).sum::<f64>() - 1.0 / n)
            / (3.0 * (k as f64 - 1.0));
    num / c
}

fn factor(name: &str, groups: Vec<Group>) -> Factor {
    let g: Vec<&Group> = groups.iter().filter(|g| g.dof >= 2).collect();
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for v in g.iter().flat_map(|g| [g.std_x, g.std_y]) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    let statistic = [0, 1].map(|a| {
        let v: Vec<(f64, usize)> = g
            .iter()
            .map(|g| ((if a == 0 { g.std_x } else { g.std_y }).powi(2), g.dof))
            .collect();
        bartlett(&v)
    });
    let test_dof = g.len().saturating_sub(1);
    let bound = if test_dof > 0 {
        chi2_upper(test_dof, Z_995)
    } else {
        f64::NAN
    };
    Factor {
        factor: name.into(),
        spread_ratio: if g.len() >= 2 && lo > 0.0 && lo.is_finite() {
            hi / lo
        } else {
            f64::NAN
        },
        significant: statistic.iter().any(|t| *t > bound),
        statistic,
        test_dof,
        bound,
        groups,
    }
}

fn by_value(name: &str, pts: &[Pt], get: impl Fn(&Sample) -> Option<f64>, unit: &str) -> Factor {
    let mut m: BTreeMap<u64, Vec<&Pt>> = BTreeMap::new();
    for p in pts.iter().filter(|p| p.n > 1) {
        if let Some(v) = get(&p.first) {
            m.entry(v.to_bits()).or_default().push(p);
        }
    }
    let mut groups: Vec<Group> = m
        .into_iter()
        .map(|(k, v)| {
            let x = f64::from_bits(k);
            pool(format!("{x}{unit}"), x, &v)
        })
        .collect();
    groups.sort_by(|a, b| a.key.total_cmp(&b.key));
    factor(name, groups)
}

fn by_bins(
    name: &str,
    pts: &[Pt],
    get: impl Fn(&Sample) -> Option<f64>,
    edges: &[f64],
    unit: &str,
) -> Factor {
    let mut bins: Vec<Vec<&Pt>> = vec![Vec::new(); edges.len() - 1];
    for p in pts.iter().filter(|p| p.n > 1) {
        if let Some(v) = get(&p.first) {
            // Bins are [lo, hi), the last one [lo, hi]: a magnitude at the 16-bit ceiling is
            // the last bin's upper edge.
            let last = edges.len() - 2;
            if let Some(b) = (0..edges.len() - 1)
                .find(|&b| v >= edges[b] && (v < edges[b + 1] || (b == last && v == edges[b + 1])))
            {
                bins[b].push(p);
            }
        }
    }
    let groups = bins
        .iter()
        .enumerate()
        .filter(|(_, v)| !v.is_empty())
        .map(|(b, v)| {
            pool(
                format!(
                    "{}-{}{unit}",
                    crate::plot::tick(edges[b]),
                    crate::plot::tick(edges[b + 1])
                ),
                0.5 * (edges[b] + edges[b + 1]),
                v,
            )
        })
        .collect();
    factor(name, groups)
}

fn magnitude_noise(rep: &[&Pt]) -> Option<MagnitudeNoise> {
    let with: Vec<&&Pt> = rep.iter().filter(|p| p.ss_mag_rel.is_some()).collect();
    if with.is_empty() {
        return None;
    }
    let pooled = |pts: &[&&Pt]| {
        let ss: f64 = pts.iter().filter_map(|p| p.ss_mag_rel).sum();
        let dof: usize = pts.iter().map(|p| p.n - 1).sum();
        100.0 * (ss / dof.max(1) as f64).sqrt()
    };
    let mut seps: BTreeMap<u64, Vec<&&Pt>> = BTreeMap::new();
    for p in &with {
        seps.entry(p.first.separation_in.to_bits())
            .or_default()
            .push(p);
    }
    let mut by_separation: Vec<(f64, f64, usize)> = seps
        .into_iter()
        .map(|(k, v)| (f64::from_bits(k), pooled(&v), v.len()))
        .collect();
    by_separation.sort_by(|a, b| a.0.total_cmp(&b.0));
    Some(MagnitudeNoise {
        points: with.len(),
        percent: pooled(&with),
        by_separation,
    })
}

/// How far the points' variances spread around a pooled variance, in units of the spread
/// Gaussian noise gives: each point with 3 or more samples, on each axis, compares its
/// variance with `pooled(point)` (`None`, or a pooled variance of 0, leaves it out); under
/// homogeneous Gaussian noise `(n-1) s^2 / sigma^2` is chi-square(n-1), so the ratio has
/// variance `2 / (n-1)`. The RMS of the ratios' z-scores: about 1 when homogeneous, NaN
/// without a comparison.
fn variance_dispersion(rep: &[&Pt], pooled: impl Fn(&Pt) -> Option<[f64; 2]>) -> f64 {
    let (mut z2, mut cnt) = (0.0, 0.0);
    for p in rep.iter().filter(|p| p.n >= 3) {
        let Some(v) = pooled(p) else { continue };
        for (a, pooled) in v.into_iter().enumerate() {
            if pooled > 0.0 {
                let r = p.ss[a] / (p.n - 1) as f64 / pooled;
                z2 += (r - 1.0).powi(2) / (2.0 / (p.n - 1) as f64);
                cnt += 1.0;
            }
        }
    }
    if cnt > 0.0 {
        (z2 / cnt).sqrt()
    } else {
        f64::NAN
    }
}

/// The settings (modulation frequency, power level, sensitivity) whose noise differs
/// significantly within a separation: `cta analyze --weights setting` is then the weighting.
pub fn settings_that_differ(r: &NoiseReport) -> Vec<&Factor> {
    settings_among(&r.factors)
}

fn settings_among(factors: &[Factor]) -> Vec<&Factor> {
    factors
        .iter()
        .filter(|f| {
            f.significant
                && ["modulation frequency", "power level", "sensitivity setting"]
                    .contains(&f.factor.as_str())
        })
        .collect()
}

/// Analyze the noise of a dataset.
pub fn analyze_noise(ds: &Dataset) -> Result<NoiseReport, NoiseError> {
    let groups = ds.points();
    // The rail rule of `cta calibrate` ([`any_sample_pinned`], [`mean_near_rail`]): a point
    // with a coordinate pinned at +/-32767 in any sample, or its mean within 3 sigma of the
    // rail, has its spread clipped by the rail (a cell in shadow or saturated): it is left out.
    let (groups, pinned): (Vec<_>, Vec<_>) = groups
        .into_iter()
        .partition(|g| !any_sample_pinned(g.rows.iter().map(|&i| &ds.samples[i])));
    let mut pts = Vec::with_capacity(groups.len());
    for g in &groups {
        let n = g.rows.len();
        let (mut mx, mut my) = (0.0, 0.0);
        for &i in &g.rows {
            mx += ds.samples[i].x;
            my += ds.samples[i].y;
        }
        mx /= n as f64;
        my /= n as f64;
        let (mut ss, mut sxy) = ([0.0; 2], 0.0);
        for &i in &g.rows {
            let (dx, dy) = (ds.samples[i].x - mx, ds.samples[i].y - my);
            ss[0] += dx * dx;
            ss[1] += dy * dy;
            sxy += dx * dy;
        }
        let mags: Option<Vec<f64>> = g
            .rows
            .iter()
            .map(|&i| {
                ds.samples[i]
                    .magnitude
                    .filter(|m| *m > 0.0 && *m < MAGNITUDE_CEILING)
            })
            .collect();
        let ss_mag_rel = mags.map(|m| {
            let mean = m.iter().sum::<f64>() / n as f64;
            m.iter().map(|v| ((v - mean) / mean).powi(2)).sum::<f64>()
        });
        pts.push(Pt {
            first: g.first,
            n,
            mean: [mx, my],
            ss,
            sxy,
            ss_mag_rel,
        });
    }
    // The margin's sigma: the one-sample noise pooled over both axes of the points that
    // passed the first half of the rule (as `cta calibrate` takes it).
    let (ss, dof) = pts.iter().fold((0.0, 0), |(s, d), p| {
        (s + p.ss[0] + p.ss[1], d + 2 * (p.n - 1))
    });
    let mut out_seps: Vec<f64> = pinned.iter().map(|g| g.first.separation_in).collect();
    let mut near_rail = 0;
    if dof > 0 {
        let noise = (ss / dof as f64).sqrt();
        pts.retain(|p| {
            let out = mean_near_rail(p.mean, noise, p.n);
            if out {
                near_rail += 1;
                out_seps.push(p.first.separation_in);
            }
            !out
        });
    }
    let mut by_sep: BTreeMap<u64, usize> = BTreeMap::new();
    for sep in out_seps {
        *by_sep.entry(sep.to_bits()).or_default() += 1;
    }
    let left_out = LeftOut {
        points: pinned.len() + near_rail,
        pinned_sample: pinned.len(),
        mean_near_rail: near_rail,
        by_separation: by_sep
            .into_iter()
            .map(|(k, v)| (f64::from_bits(k), v))
            .collect(),
    };
    let rep: Vec<&Pt> = pts.iter().filter(|p| p.n > 1).collect();
    if rep.is_empty() && left_out.points > 0 {
        return Err(NoiseError::AllAtTheRail {
            path: ds.path.clone(),
            pinned: left_out.pinned_sample,
            near_rail: left_out.mean_near_rail,
        });
    }
    if rep.is_empty() {
        return Err(NoiseError::SingleSamples {
            path: ds.path.clone(),
        });
    }
    let all = pool("all".into(), 0.0, &rep);
    let sxy: f64 = rep.iter().map(|p| p.sxy).sum();
    let corr = sxy / ((all.std_x * all.std_y) * all.dof.max(1) as f64);
    let angle = |s: &Sample| Some(s.r[0].hypot(s.r[1]).atan2(s.r[2]).to_degrees());
    let mut factors = vec![
        by_value("separation", &pts, |s| Some(s.separation_in), " in"),
        by_bins(
            "off-boresight angle",
            &pts,
            angle,
            &[0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 90.0],
            " deg",
        ),
    ];
    // Magnitude: log bins (factor-of-2) over the recorded range.
    let mags: Vec<f64> = rep
        .iter()
        .filter_map(|p| p.first.magnitude)
        .filter(|m| *m > 0.0)
        .collect();
    if !mags.is_empty() {
        let lo = mags.iter().cloned().fold(f64::INFINITY, f64::min);
        let hi = mags.iter().cloned().fold(0.0, f64::max);
        let mut edges = vec![lo];
        while *edges.last().unwrap_or(&hi) <= hi {
            let e = edges.last().copied().unwrap_or(hi) * 2.0;
            edges.push(e);
        }
        // Magnitudes are 16-bit counts: the last bin ends at the ceiling, not beyond it.
        let k = edges.len();
        if hi <= MAGNITUDE_CEILING
            && edges[k - 1] > MAGNITUDE_CEILING
            && edges[k - 2] < MAGNITUDE_CEILING
        {
            edges[k - 1] = MAGNITUDE_CEILING;
        }
        factors.push(by_bins(
            "signal magnitude",
            &pts,
            |s| s.magnitude,
            &edges,
            "",
        ));
    } else {
        factors.push(factor("signal magnitude", Vec::new()));
    }
    factors.push(by_value(
        "modulation frequency",
        &pts,
        |s| s.frequency_hz,
        " Hz",
    ));
    factors.push(by_value("power level", &pts, |s| s.power, ""));
    factors.push(by_value("sensitivity setting", &pts, |s| s.sensitivity, ""));
    // Within-separation homogeneity: each point's variance over its separation's pooled
    // variance; under homogeneous Gaussian noise (n-1) s^2/sigma^2 is chi-square(n-1), so the
    // ratio has variance 2/(n-1).
    let sep = &factors[0];
    let dispersion = variance_dispersion(&rep, |p| {
        let g = sep.groups.iter().find(|g| g.key == p.first.separation_in)?;
        Some([g.std_x.powi(2), g.std_y.powi(2)])
    });
    // The same dispersion within a separation and a setting (frequency, power, sensitivity):
    // near 1 when the settings alone make the noise differ within a separation.
    let setting = |s: &Sample| {
        [s.frequency_hz, s.power, s.sensitivity].map(|v| v.unwrap_or(f64::NAN).to_bits())
    };
    let mut by_setting: BTreeMap<(u64, [u64; 3]), (f64, f64, usize)> = BTreeMap::new();
    for p in &rep {
        let e = by_setting
            .entry((p.first.separation_in.to_bits(), setting(&p.first)))
            .or_default();
        e.0 += p.ss[0];
        e.1 += p.ss[1];
        e.2 += p.n - 1;
    }
    let setting_dispersion = variance_dispersion(&rep, |p| {
        let (sx, sy, dof) = by_setting[&(p.first.separation_in.to_bits(), setting(&p.first))];
        // A point alone in its setting has nothing to be compared with.
        (dof >= p.n).then(|| [sx / dof as f64, sy / dof as f64])
    });
    // Samples per point, the median over the points with repeated samples.
    let mut ns: Vec<usize> = rep.iter().map(|p| p.n).collect();
    ns.sort_unstable();
    let n_typ = ns[ns.len() / 2];
    let settings_differ = settings_among(&factors);
    // Angle or magnitude: the noise depends on the beacon's place or signal, point by point.
    let signal_differs = factors[1..3].iter().any(|f| f.significant);
    let point_advice = |what: String, keep: &str| {
        if n_typ >= POINT_MIN_SAMPLES {
            format!(
                "{what}: weight each point by its own variance, `cta analyze --weights point` \
                 ({n_typ} samples per point; ~{POINT_MIN_SAMPLES}+ are needed for stable weights)"
            )
        } else {
            format!(
                "{what}, but with {n_typ} samples per point a point's own variance is too rough to \
                 weight by (good to {:.0} %, and its inverse biases chi-square high by \
                 (n - 1)/(n - 3)), so `--weights point` would report structure that is not there: \
                 it needs ~{POINT_MIN_SAMPLES}+ samples per point. Keep {keep} and read a chi2/dof a little above 1 with this in mind, or record more \
                 samples per point",
                100.0 * (2.0 / (n_typ as f64 - 1.0)).sqrt()
            )
        }
    };
    let weighting = if !settings_differ.is_empty() {
        let names = settings_differ
            .iter()
            .map(|f| format!("{} (max/min {:.2})", f.factor, f.spread_ratio))
            .collect::<Vec<_>>()
            .join(", ");
        let mut w = format!(
            "the noise differs between settings within a separation: {names} (dispersion of \
             point variances {dispersion:.2} within a separation, {setting_dispersion:.2} within \
             a separation and setting; 1 = homogeneous): weight by the variance pooled per \
             separation and setting, `cta analyze --weights setting` (or analyze each setting \
             on its own)"
        );
        // Angle and magnitude differ with the settings too (power and sensitivity set the
        // signal): only a dispersion left within a setting says the points differ.
        if setting_dispersion > 1.3 {
            w.push_str("; ");
            w.push_str(&point_advice(
                format!(
                    "the noise also differs from point to point within a setting (dispersion \
                     {setting_dispersion:.2})"
                ),
                "`cta analyze --weights setting`",
            ));
        }
        w
    } else if dispersion > 1.3 || (signal_differs && !factors[0].significant) {
        point_advice(
            format!(
                "the noise differs within a separation (dispersion {dispersion:.2}, 1 = \
                 homogeneous)"
            ),
            "`cta analyze --weights separation` (the default)",
        )
    } else if factors[0].significant {
        "the noise changes with separation: weight by the variance pooled per separation \
         (`cta analyze --weights separation`, the default); W = diag(n_i / sigma_sep^2)"
            .into()
    } else {
        format!(
            "the noise is uniform: one variance for the file (`cta analyze --weights global`); \
             W = diag(n_i / sigma^2) with sigma = {:.1} (X), {:.1} (Y) counts",
            all.std_x, all.std_y
        )
    };
    let magnitude = magnitude_noise(&rep);
    Ok(NoiseReport {
        magnitude,
        crosstalk: crate::crosstalk::check(ds),
        file: ds.path.display().to_string(),
        samples: ds.samples.len(),
        left_out,
        points_repeated: rep.len(),
        points_single: pts.len() - rep.len(),
        std_all: [all.std_x, all.std_y],
        xy_correlation: corr,
        glitches: ds.glitches(),
        factors,
        within_separation_dispersion: dispersion,
        within_setting_dispersion: setting_dispersion,
        weighting,
    })
}

/// The x-axis label of a factor's panel, with its unit.
fn axis_label(factor: &str) -> String {
    let unit = match factor {
        "separation" => "in",
        "off-boresight angle" => "deg, bin centre",
        "signal magnitude" => "sensor units, bin centre",
        "modulation frequency" => "Hz",
        "power level" => "drive level",
        "sensitivity setting" => "NorthStar setting",
        _ => return factor.into(),
    };
    format!("{factor} ({unit})")
}

/// The panel of one factor: the one-sample std of X and Y per group with their standard
/// errors.
fn panel(f: &Factor, log_x: bool) -> Panel {
    let series = |a: usize| {
        let pts = f
            .groups
            .iter()
            .map(|g| (g.key, if a == 0 { g.std_x } else { g.std_y }))
            .collect();
        let se = f
            .groups
            .iter()
            .map(|g| if a == 0 { g.se_x } else { g.se_y })
            .collect();
        // From 0: a constant noise level whose points scatter by +/-1 s.e. must not fill
        // the panel and read as a trend.
        Series::new(if a == 0 { "X" } else { "Y" }, pts)
            .with_markers()
            .with_error_bars(se)
            .from_zero()
    };
    Panel {
        title: format!(
            "noise by {} ({})",
            f.factor,
            if f.significant {
                "differs beyond sampling"
            } else {
                "within sampling"
            }
        ),
        x_desc: axis_label(&f.factor),
        y_desc: "one-sample std (counts), bars +/-1 s.e.".into(),
        log_x,
        log_y: false,
        series: vec![series(0), series(1)],
    }
}

/// Write the plots of `r` into the folder `dir`: `noise.svg` (one panel per factor with more
/// than one group) and `index.html` holding it with `text`, the report as the command line
/// prints it. Neither file may replace one `cta` did not write. Returns the page's path.
pub fn write_plots(dir: &Path, r: &NoiseReport, text: &str) -> Result<PathBuf, NoiseError> {
    let (svg_path, index) = (dir.join("noise.svg"), dir.join("index.html"));
    fn write(e: impl std::fmt::Display) -> NoiseError {
        NoiseError::Write(e.to_string())
    }
    crate::plot::refuse_to_replace(&svg_path).map_err(write)?;
    crate::plot::refuse_to_replace(&index).map_err(write)?;
    let panels: Vec<Panel> = r
        .factors
        .iter()
        .filter(|f| f.groups.len() > 1)
        .map(|f| panel(f, f.factor == "signal magnitude"))
        .collect();
    let svg = render_svg(&format!("CTA noise: {}", r.file), &panels, 2)
        .map_err(|e| NoiseError::Plot(e.to_string()))?;
    crate::plot::write_marked(&svg_path, &svg).map_err(write)?;
    let html = format!(
        "<!doctype html><meta charset=utf-8><title>cta noise</title>\
         <body style='font-family:sans-serif'>{svg}<pre>{}</pre></body>",
        crate::html::escape(text)
    );
    crate::plot::write_marked(&index, &html).map_err(write)?;
    Ok(index)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::SimConfig;

    /// 10 samples per point at 5 and 20 in, noise 30 counts.
    fn two_separations() -> Dataset {
        SimConfig {
            separations: vec![5.0, 20.0],
            noise: 30.0,
            samples: 10,
            ..Default::default()
        }
        .run()
        .0
    }

    #[test]
    fn recovers_the_simulated_noise_and_sees_separation_dependence() {
        let ds = two_separations();
        let r = analyze_noise(&ds).unwrap();
        assert!((r.std_all[0] - 30.0).abs() < 1.5, "{:?}", r.std_all);
        assert!(!r.factors[0].significant, "uniform noise flagged");
        assert!(r.weighting.contains("uniform"), "{}", r.weighting);
        // Make the far separation noisier (+/-40 counts alternating over the samples of each
        // point): the separation factor must notice.
        let mut ds2 = ds.clone();
        for s in ds2.samples.iter_mut().filter(|s| s.separation_in == 20.0) {
            if let Some(k) = s.sample {
                s.x += if k % 2 == 0 { 40.0 } else { -40.0 };
            }
        }
        let r2 = analyze_noise(&ds2).unwrap();
        assert!(r2.factors[0].significant);
        assert!(r2.weighting.contains("separation"), "{}", r2.weighting);
        let single = SimConfig {
            separations: vec![5.0],
            ..Default::default()
        }
        .run()
        .0;
        assert!(analyze_noise(&single)
            .unwrap_err()
            .to_string()
            .contains("single sample"));
    }

    /// A point whose samples all stay inside the rail but whose mean is within 3 sigma of it
    /// is left out too (its spread is clipped by the samples that would have reached it).
    #[test]
    fn a_mean_near_the_rail_is_left_out() {
        let mut ds = two_separations();
        let first = ds.samples[0];
        let same = |s: &Sample| s.separation_in == first.separation_in && s.r == first.r;
        let n = ds.samples.iter().filter(|s| same(s)).count();
        // Move the point to 2 sigma-of-the-mean below the rail, keeping its spread (30
        // counts, well inside it at 10 samples: no sample reaches the rail).
        let mean = ds
            .samples
            .iter()
            .filter(|s| same(s))
            .map(|s| s.x)
            .sum::<f64>()
            / n as f64;
        let shift = 32767.0 - 2.0 * 30.0 / (n as f64).sqrt() - mean;
        for s in ds.samples.iter_mut().filter(|s| same(s)) {
            s.x = (s.x + shift).min(32766.0);
        }
        let r = analyze_noise(&ds).unwrap();
        assert_eq!(
            (r.left_out.pinned_sample, r.left_out.mean_near_rail),
            (0, 1),
            "{:?}",
            r.left_out
        );
        assert_eq!(r.left_out.by_separation, vec![(first.separation_in, 1)]);
    }

    /// Add +/-`a` counts (alternating over the samples) to X and Y of the points `pick`
    /// chooses (by point index), and set their `power` by the same choice (1 or 2) when
    /// `power`.
    fn noisier(ds: &mut Dataset, a: f64, power: bool, pick: impl Fn(usize) -> bool) {
        let points = ds.points();
        for (k, p) in points.iter().enumerate() {
            let on = pick(k);
            for (j, &i) in p.rows.iter().enumerate() {
                let s = &mut ds.samples[i];
                if power {
                    s.power = Some(if on { 2.0 } else { 1.0 });
                }
                if on {
                    let d = if j % 2 == 0 { a } else { -a };
                    s.x += d;
                    s.y += d;
                }
            }
        }
    }

    /// Noise that differs between power levels within a separation (a Ch VI sweep): pool per
    /// separation and setting, never per point (5 or 10 samples per point: with 5, `point`
    /// turns clean data into "unexplained structure").
    #[test]
    fn settings_that_differ_recommend_setting_weights() {
        let mut ds = two_separations();
        noisier(&mut ds, 40.0, true, |k| k % 2 == 0);
        let r = analyze_noise(&ds).unwrap();
        assert!(r.within_separation_dispersion > 1.3, "{r:?}");
        assert!(r.within_setting_dispersion < 1.3, "{r:?}");
        assert!(
            r.weighting.contains("differs between settings")
                && r.weighting.contains("power level")
                && r.weighting.contains("`cta analyze --weights setting`")
                && !r.weighting.contains("--weights point`"),
            "{}",
            r.weighting
        );
    }

    /// Noise that differs from point to point: `point` only from 10 samples per point.
    #[test]
    fn point_weights_only_with_enough_samples() {
        for (samples, point) in [(5, false), (20, true)] {
            let mut ds = SimConfig {
                separations: vec![5.0, 20.0],
                noise: 30.0,
                samples,
                ..Default::default()
            }
            .run()
            .0;
            noisier(&mut ds, 60.0, false, |k| k % 3 == 0);
            let r = analyze_noise(&ds).unwrap();
            assert!(r.within_separation_dispersion > 1.3, "{r:?}");
            let w = &r.weighting;
            assert_eq!(w.contains("`cta analyze --weights point`"), point, "{w}");
            if !point {
                assert!(
                    w.contains("with 5 samples per point a point's own variance is too rough")
                        && w.contains("Keep `cta analyze --weights separation` (the default)"),
                    "{w}"
                );
            }
        }
    }

    #[test]
    fn chi_square_bound_matches_the_table() {
        // 99.5 % points: 7.879 (1 dof), 18.548 (6), 50.993 (28).
        for (k, table) in [(1, 7.879), (6, 18.548), (28, 50.993)] {
            let v = chi2_upper(k, Z_995);
            assert!((v / table - 1.0).abs() < 0.01, "{k}: {v} vs {table}");
        }
    }
}
