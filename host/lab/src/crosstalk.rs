//! Is multiplexing safe on this detector? The crosstalk check of a grouped sweep: beacons
//! measured both alone and in their group, at the same separation, frequency and settings,
//! compared.
//!
//! A grouped sweep lights many beacons at once, each at its own frequency, and the NorthStar
//! separates their spots by demodulating the same four cell signals at each frequency. If
//! its filters let part of the other spots' signal through, a spot's reading is pulled
//! toward the others' (`spot_crosstalk=C`, the share of each other spot's signal in a spot's
//! channel): `o'_i = (m_i o_i + C sum_j m_j o_j) / (m_i + C sum_j m_j)`, to first order
//! `o_i + C sum_j m_j (o_j - o_i) / m_i`, over the others `j` with readings `o` and
//! magnitudes `m`. The check fits `C` to the differences (group minus alone) by weighted
//! least squares, each weighted by its noise (both points' sample variance over their
//! samples), and tests it against zero; a chi-square of the differences says whether they
//! exceed their noise at all, whatever the cause.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::data::{Dataset, Point};

/// The readings of spots lit together when the detector leaks a fraction `c` of every other
/// spot's signal into each spot's channel (`spot_crosstalk=C`): the NorthStar separates spots
/// by demodulating the same four cell signals at each spot's frequency, and a filter that
/// rejects the other frequencies only in part adds their cell signals, weighted by their
/// magnitude, to the spot's own. A spot's reading is then pulled toward the others':
/// `(m_i o_i + c sum_j m_j o_j) / (m_i + c sum_j m_j)` over the others `j`, for readings `o`
/// and magnitudes `m`. A spot lit alone reads as without it.
pub fn spot_crosstalk(c: f64, spots: &[([f64; 2], f64)]) -> Vec<[f64; 2]> {
    let total_m: f64 = spots.iter().map(|s| s.1).sum();
    let total: [f64; 2] = [0, 1].map(|k| spots.iter().map(|s| s.0[k] * s.1).sum());
    spots
        .iter()
        .map(|&(o, m)| {
            if c == 0.0 {
                return o;
            }
            let w = c * (total_m - m);
            [0, 1].map(|k| (m * o[k] + c * (total[k] - o[k] * m)) / (m + w))
        })
        .collect()
}

/// `C / sigma` from which `spot_crosstalk` is named: far beyond what the many pairs of a run
/// give by chance.
pub const NAMED_SIGMA: f64 = 5.0;

/// What the crosstalk check found.
#[derive(Debug, Clone, Serialize)]
pub struct Check {
    /// Points of a beacon measured alone that have a counterpart in a group, compared.
    pub pairs: usize,
    /// Such points left out: a magnitude at the 16-bit rail in the group (its pull unknown)
    /// or a coordinate pinned at the rail.
    pub clipped: usize,
    /// Beacons lit together in the largest group.
    pub largest_group: usize,
    /// RMS of the differences group minus alone, over the pairs and both axes, counts.
    pub rms_difference: f64,
    /// RMS of the differences the noise alone gives (both points' standard errors), counts.
    pub rms_noise: f64,
    /// Sum of the squared differences over their noise variance.
    pub chi2: f64,
    /// Its degrees of freedom (two per pair).
    pub dof: usize,
    /// Its expectation when the group changes nothing: each term is a Student's t squared
    /// (the noise estimated from the points' own samples), a little above 1.
    pub chi2_expected: f64,
    /// Its standard deviation then.
    pub chi2_spread: f64,
    /// `spot_crosstalk` fitted to the differences.
    pub c: f64,
    /// Its 1-sigma.
    pub c_sigma: f64,
    /// RMS over every grouped point of the pull the fitted `C` gives, counts: how much the
    /// grouped data are biased.
    pub bias_rms: f64,
    /// The largest such pull, counts.
    pub bias_max: f64,
    /// `C` is at least [`NAMED_SIGMA`] sigma above zero: the grouped readings are pulled
    /// toward the other spots, and the cause is named.
    pub named: bool,
}

impl Check {
    /// The chi-square's distance from its expectation in standard deviations: above about 3
    /// the differences exceed their noise.
    pub fn chi2_sigma(&self) -> f64 {
        (self.chi2 - self.chi2_expected) / self.chi2_spread
    }

    /// A short warning when `spot_crosstalk` is named, for every command that reads the file
    /// (`None` otherwise).
    pub fn warning(&self) -> Option<String> {
        self.named.then(|| {
            format!(
                "the crosstalk check names spot_crosstalk (C = {:.2e} +/- {:.1e}, from {} beacons \
                 measured alone and in their group): the grouped rows are biased by {:.2} counts \
                 RMS, at most {:.2}; rerun with smaller groups (`cta noise` gives the check)",
                self.c, self.c_sigma, self.pairs, self.bias_rms, self.bias_max
            )
        })
    }

    /// One line for people: what the check found and, when named, what to do.
    pub fn summary(&self) -> String {
        if self.pairs == 0 {
            return format!(
                "crosstalk check: none of the {} beacons measured alone and in their group \
                 could be compared: their groups hold spots at the 16-bit rail (saturated \
                 magnitudes or coordinates); check at lower sensitivity or farther out",
                self.clipped
            );
        }
        let left = match self.clipped {
            0 => String::new(),
            n => format!(", {n} more left out at the 16-bit rail"),
        };
        let head = format!(
            "crosstalk check: {} beacons measured alone and in their group (up to {} lit at \
             once{left}): group minus alone {:.2} counts RMS, noise alone {:.2} (chi2 {:.1} on \
             {} dof, {:+.1} sigma from its expectation); spot_crosstalk C = {:.2e} +/- {:.1e}",
            self.pairs,
            self.largest_group,
            self.rms_difference,
            self.rms_noise,
            self.chi2,
            self.dof,
            self.chi2_sigma(),
            self.c,
            self.c_sigma
        );
        if self.named {
            format!(
                "{head}: named (C is {:.0} sigma above 0). The grouped data are biased by \
                 {:.2} counts RMS, at most {:.2}: each spot is pulled toward the others lit \
                 with it. Rerun with smaller groups (a lower `group` in the plan), or keep \
                 the one-at-a-time points only",
                self.c / self.c_sigma,
                self.bias_rms,
                self.bias_max
            )
        } else {
            if self.chi2_sigma() > 3.0 {
                format!(
                    "{head}: not crosstalk, but the readings alone and in the group differ \
                     beyond their noise (drift between the two, or another cause)"
                )
            } else {
                format!("{head}: within its noise, grouped data unbiased")
            }
        }
    }
}

/// Key of a beacon's setting: separation, position, frequency, power, sensitivity.
type Setting = [u64; 7];

/// The largest magnitude the NorthStar reports (16 bits): a spot at it is saturated, its
/// true magnitude unknown.
const MAGNITUDE_RAIL: f64 = 65535.0;

/// One point of a measurement file (a beacon's samples at one setting in one sweep point),
/// summed up for the check.
#[derive(Debug, Clone, Copy)]
pub struct PointSums {
    /// The setting: separation, position, frequency, power, sensitivity.
    setting: Setting,
    /// The sweep point (`group` column).
    group: Option<u32>,
    /// Mean (x, y), counts.
    mean: [f64; 2],
    /// Sum of squared deviations from the mean per axis.
    ss: [f64; 2],
    /// Samples.
    n: usize,
    /// Mean magnitude (1 when the file records none).
    magnitude: f64,
    /// A magnitude at the rail or a coordinate pinned at it: the pull cannot be computed, or
    /// the spread is clipped.
    clipped: bool,
}

/// The points of `ds` summed up ([`PointSums`]), in the order of [`Dataset::points`].
pub fn point_sums(ds: &Dataset) -> Vec<PointSums> {
    ds.points().iter().map(|p| sums(ds, p)).collect()
}

fn sums(ds: &Dataset, p: &Point) -> PointSums {
    let f = &p.first;
    let n = p.rows.len() as f64;
    let mut mean = [0.0; 2];
    let mut magnitude = 0.0;
    let mut clipped = crate::data::any_sample_pinned(p.rows.iter().map(|&i| &ds.samples[i]));
    for &i in &p.rows {
        let s = &ds.samples[i];
        mean[0] += s.x / n;
        mean[1] += s.y / n;
        let m = s.magnitude.unwrap_or(1.0);
        clipped |= m >= MAGNITUDE_RAIL;
        magnitude += m / n;
    }
    let mut ss = [0.0; 2];
    for &i in &p.rows {
        let s = &ds.samples[i];
        ss[0] += (s.x - mean[0]).powi(2);
        ss[1] += (s.y - mean[1]).powi(2);
    }
    PointSums {
        setting: [
            f.separation_in.to_bits(),
            f.r[0].to_bits(),
            f.r[1].to_bits(),
            f.r[2].to_bits(),
            f.frequency_hz.unwrap_or(f64::NAN).to_bits(),
            f.power.unwrap_or(f64::NAN).to_bits(),
            f.sensitivity.unwrap_or(f64::NAN).to_bits(),
        ],
        group: f.group,
        mean,
        ss,
        n: p.rows.len(),
        magnitude,
        clipped,
    }
}

/// The crosstalk check of a measurement file: `None` when it has no beacon measured both
/// alone and in a group (a file without the `group` column, a one-at-a-time sweep).
pub fn check(ds: &Dataset) -> Option<Check> {
    check_sums(&point_sums(ds))
}

/// [`check`] over points already summed up (a sweep keeps those of the points it compares).
pub fn check_sums(stat: &[PointSums]) -> Option<Check> {
    // Points by sweep point (`group`), and each group's size.
    let mut by_group: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
    for (k, p) in stat.iter().enumerate() {
        if let Some(g) = p.group {
            by_group.entry(g).or_default().push(k);
        }
    }
    let size = |k: usize| stat[k].group.map_or(0, |g| by_group[&g].len());
    // A beacon's setting in a group of two or more: its point.
    let mut grouped: BTreeMap<Setting, usize> = BTreeMap::new();
    for (k, p) in stat.iter().enumerate() {
        if size(k) > 1 {
            grouped.insert(p.setting, k);
        }
    }
    let group_of = |k: usize| &by_group[&stat[k].group.expect("grouped points have one")];
    // The first-order pull of point `k` per unit C: sum_j m_j (o_j - o_k) / m_k over the
    // other points of its group (`own` = the reading taken for o_k).
    let pull = |k: usize, own: [f64; 2]| -> [f64; 2] {
        let m_k = stat[k].magnitude.max(1e-9);
        let mut v = [0.0; 2];
        for &j in group_of(k) {
            if j != k {
                let (o, m) = (stat[j].mean, stat[j].magnitude);
                v[0] += m * (o[0] - own[0]) / m_k;
                v[1] += m * (o[1] - own[1]) / m_k;
            }
        }
        v
    };
    let (mut pairs, mut clipped, mut largest) = (0usize, 0usize, 0usize);
    let (mut ss_d, mut ss_noise, mut chi2, mut expected, mut spread) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut dv, mut vv) = (0.0, 0.0);
    for (k, p) in stat.iter().enumerate() {
        if size(k) != 1 {
            continue;
        }
        let Some(&g) = grouped.get(&p.setting) else {
            continue;
        };
        let (a, b) = (stat[k], stat[g]);
        // Student's t of each difference needs 5 degrees of freedom for its variance.
        let nu = (a.n + b.n).saturating_sub(2);
        if nu < 5 {
            continue;
        }
        if a.clipped || group_of(g).iter().any(|&j| stat[j].clipped) {
            clipped += 1;
            continue;
        }
        pairs += 1;
        largest = largest.max(size(g));
        let v = pull(g, a.mean);
        let nu = nu as f64;
        for ax in 0..2 {
            let d = b.mean[ax] - a.mean[ax];
            // One noise for both points (the null hypothesis: the group changes nothing),
            // pooled over their samples.
            let var =
                ((a.ss[ax] + b.ss[ax]) / nu * (1.0 / a.n as f64 + 1.0 / b.n as f64)).max(1e-12);
            ss_d += d * d;
            ss_noise += var;
            chi2 += d * d / var;
            // d^2 / var is the square of a Student's t with nu degrees of freedom.
            expected += nu / (nu - 2.0);
            spread += 2.0 * nu * nu * (nu - 1.0) / ((nu - 2.0).powi(2) * (nu - 4.0));
            dv += d * v[ax] / var;
            vv += v[ax] * v[ax] / var;
        }
    }
    if pairs + clipped == 0 {
        return None;
    }
    let c = if vv > 0.0 { dv / vv } else { 0.0 };
    let c_sigma = if vv > 0.0 {
        vv.powf(-0.5)
    } else {
        f64::INFINITY
    };
    // The bias the fitted C gives every grouped point.
    let (mut sb, mut nb, mut max) = (0.0, 0usize, 0.0f64);
    for &g in grouped.values() {
        if group_of(g).iter().any(|&j| stat[j].clipped) {
            continue;
        }
        let v = pull(g, stat[g].mean);
        let b = c.max(0.0) * v[0].hypot(v[1]);
        sb += b * b;
        nb += 1;
        max = max.max(b);
    }
    let n = (2 * pairs) as f64;
    Some(Check {
        pairs,
        clipped,
        chi2_expected: expected,
        chi2_spread: spread.sqrt(),
        largest_group: largest,
        rms_difference: (ss_d / n).sqrt(),
        rms_noise: (ss_noise / n).sqrt(),
        chi2,
        dof: 2 * pairs,
        c,
        c_sigma,
        bias_rms: (sb / nb.max(1) as f64).sqrt(),
        bias_max: max,
        named: c_sigma.is_finite() && c >= NAMED_SIGMA * c_sigma,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Sample;

    /// Three beacons lit together (group 7) and beacon 0 also alone (group 9), with noise
    /// `noise` and readings pulled by `c`.
    fn file(c: f64, noise: f64) -> Dataset {
        let truth = [[-300.0, 0.0], [300.0, 100.0], [0.0, -400.0]];
        let mags = [1000.0, 2000.0, 1000.0];
        let mixed = spot_crosstalk(
            c,
            &truth
                .iter()
                .zip(mags)
                .map(|(&o, m)| (o, m))
                .collect::<Vec<_>>(),
        );
        let mut samples = Vec::new();
        let mut rng = 12345u64;
        let mut gauss = || {
            // A sum of 12 uniforms: near enough to Gaussian for a test.
            (0..12)
                .map(|_| {
                    rng = rng
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    (rng >> 11) as f64 / (1u64 << 53) as f64
                })
                .sum::<f64>()
                - 6.0
        };
        let row = |b: usize, o: [f64; 2], group: u32, k: u32| Sample {
            separation_in: 10.0,
            r: [b as f64, 0.0, 10.0],
            x: o[0],
            y: o[1],
            beacon: Some(b as u32),
            frequency_hz: Some(4050.0 + b as f64 * 120.0),
            power: Some(2.0),
            sensitivity: Some(4.0),
            sample: Some(k),
            magnitude: Some(mags[b]),
            group: Some(group),
            line: 0,
            ..Default::default()
        };
        for k in 0..200 {
            for b in 0..3 {
                let o = [mixed[b][0] + noise * gauss(), mixed[b][1] + noise * gauss()];
                samples.push(row(b, o, 7, k));
            }
            let o = [truth[0][0] + noise * gauss(), truth[0][1] + noise * gauss()];
            samples.push(row(0, o, 9, k));
        }
        Dataset {
            path: Default::default(),
            samples,
        }
    }

    #[test]
    fn crosstalk_is_found_and_measured() {
        let c = check(&file(2e-3, 5.0)).unwrap();
        assert_eq!((c.pairs, c.largest_group), (1, 3));
        // The pull on beacon 0: C (2000 (600, 100) + 1000 (300, -400)) / 1000 = (3.0, -0.4).
        assert!((c.c - 2e-3).abs() < 3.0 * c.c_sigma, "{c:?}");
        assert!(c.named, "{}", c.summary());
        assert!(c.summary().contains("named") && c.summary().contains("smaller groups"));
        assert!(c.bias_max > 2.0 && c.bias_max < 5.0, "{c:?}");
    }

    #[test]
    fn clean_grouped_data_name_nothing() {
        let c = check(&file(0.0, 5.0)).unwrap();
        assert!(!c.named && c.c.abs() < 4.0 * c.c_sigma, "{c:?}");
        assert!(c.chi2_sigma() < 3.0, "{c:?}");
        assert!(c.summary().contains("within its noise"));
    }

    #[test]
    fn a_file_without_groups_has_no_check() {
        let mut ds = file(0.0, 1.0);
        ds.samples.iter_mut().for_each(|s| s.group = None);
        assert!(check(&ds).is_none());
    }
}
