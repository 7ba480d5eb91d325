//! Per-separation apparatus estimates against time. A sweep measures its separations one after
//! the other, so a drift over the run (a cell gain changing as the detector warms up, room
//! light) leaves a different error at each separation, which a per-separation cause
//! (`plate_offset`, `plate_tilt`, `separation_error`) can absorb. With the data's `time_s`
//! column, each of their components is fitted a straight line against the mean time of its
//! separation's rows (weighted by its 1-sigma), and a slope far from zero is said. Without
//! time, the analysis says that a drift cannot be told from these causes.

use super::result::Cause;
use crate::data::Dataset;

/// Slope significance, in sigma, from which a trend is said.
pub const TREND_SIGMA: f64 = 4.0;

/// The causes whose parameters are one per separation.
const PER_SEPARATION: [&str; 3] = ["plate_offset", "plate_tilt", "separation_error"];

/// The notes on the named per-separation causes: each component that trends with time, or,
/// when the file records no time, that a drift cannot be told from them.
pub fn notes(causes: &[Cause], ds: &Dataset) -> Vec<String> {
    let named: Vec<&Cause> = causes
        .iter()
        .filter(|c| PER_SEPARATION.contains(&c.effect.as_str()))
        .collect();
    if named.is_empty() {
        return Vec::new();
    }
    // Mean time of each separation's rows.
    let mut times: Vec<(f64, f64, usize)> = Vec::new();
    for s in &ds.samples {
        let Some(t) = s.time_s else { continue };
        match times
            .iter_mut()
            .find(|(sep, ..)| (sep - s.separation_in).abs() < 1e-9)
        {
            Some(e) => {
                e.1 += t;
                e.2 += 1;
            }
            None => times.push((s.separation_in, t, 1)),
        }
    }
    if times.is_empty() {
        let names: Vec<&str> = named.iter().map(|c| c.effect.as_str()).collect();
        return vec![format!(
            "the file records no time (`time_s`): a drift over the run (a cell gain or a \
             detector warming up) would leave a different error at each separation, and could \
             be fitted as the per-separation {}; a sweep records the time of every report \
             (host/MEASUREMENTS.md)",
            names.join(", ")
        )];
    }
    let time_at = |sep: f64| {
        times
            .iter()
            .filter(|(s, ..)| (s - sep).abs() <= crate::data::SEP_MATCH_IN)
            .min_by(|a, b| (a.0 - sep).abs().total_cmp(&(b.0 - sep).abs()))
            .map(|&(_, sum, n)| sum / n as f64)
    };
    let mut out = Vec::new();
    for c in named {
        // Components: the name before `@` (`x@20in` is component `x` at 20 in).
        let mut components: Vec<&str> = Vec::new();
        for k in c.params.keys() {
            if let Some((comp, _)) = k.split_once('@') {
                if !components.contains(&comp) {
                    components.push(comp);
                }
            }
        }
        for comp in components {
            let points: Vec<(f64, f64, f64)> = c
                .params
                .iter()
                .filter_map(|(k, &v)| {
                    let (name, at) = k.split_once('@')?;
                    let sep: f64 = at.strip_suffix("in")?.parse().ok()?;
                    let sigma = *c.sigma.get(k.as_str())?;
                    (name == comp && sigma > 0.0)
                        .then_some(())
                        .and(time_at(sep).map(|t| (t, v, sigma)))
                })
                .collect();
            if let Some((slope, sigma)) = weighted_slope(&points) {
                let z = slope / sigma;
                if z.abs() >= TREND_SIGMA {
                    let span = points.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max)
                        - points.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
                    out.push(format!(
                        "{}'s `{comp}` trends with time: {:+.3e} per hour ({:.1} sigma) over the \
                         run's {:.2} h. The separations were measured one after the other, so a \
                         drift (a cell gain, a detector warming up) and a per-separation apparatus \
                         error look alike here: measure the separations in another order, or \
                         repeat the first at the end, to tell them apart",
                        c.effect,
                        slope * 3600.0,
                        z.abs(),
                        span / 3600.0
                    ));
                }
            }
        }
    }
    out
}

/// The slope of `value` against `t` fitted by weighted least squares over `(t, value, sigma)`,
/// with its 1-sigma; `None` with fewer than 4 points or no spread in time. The values scatter
/// about any line by more than their 1-sigma when the cause is real (a plate placed anew at
/// each separation): the slope's 1-sigma is then scaled by the scatter (the root of the
/// residuals' chi-square per degree of freedom, when above 1), so a trend is a trend beyond
/// it.
fn weighted_slope(points: &[(f64, f64, f64)]) -> Option<(f64, f64)> {
    if points.len() < 4 {
        return None;
    }
    let (mut sw, mut st, mut sv, mut stt, mut stv) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(t, v, s) in points {
        let w = 1.0 / (s * s);
        sw += w;
        st += w * t;
        sv += w * v;
        stt += w * t * t;
        stv += w * t * v;
    }
    let det = sw * stt - st * st;
    if det <= 0.0 {
        return None;
    }
    let slope = (sw * stv - st * sv) / det;
    let intercept = (sv - slope * st) / sw;
    let chi2: f64 = points
        .iter()
        .map(|&(t, v, s)| ((v - intercept - slope * t) / s).powi(2))
        .sum();
    let birge = (chi2 / (points.len() - 2) as f64).sqrt().max(1.0);
    Some((slope, (sw / det).sqrt() * birge))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analyze::result::ParamMap;
    use crate::data::Sample;

    fn cause(effect: &str, values: &[(f64, f64)]) -> Cause {
        let mut params = ParamMap::default();
        let mut sigma = ParamMap::default();
        for &(sep, v) in values {
            params.insert(format!("x@{sep}in"), v);
            sigma.insert(format!("x@{sep}in"), 0.001);
        }
        Cause {
            effect: effect.into(),
            params,
            sigma,
            ..Default::default()
        }
    }

    fn file(timed: bool) -> Dataset {
        let samples = (0..6)
            .map(|k| Sample {
                separation_in: 5.0 + 5.0 * k as f64,
                time_s: timed.then_some(600.0 * k as f64),
                ..Default::default()
            })
            .collect();
        Dataset {
            path: Default::default(),
            samples,
        }
    }

    #[test]
    fn a_drift_through_the_separations_is_said_and_scatter_is_not() {
        let drift: Vec<(f64, f64)> = (0..6)
            .map(|k| (5.0 + 5.0 * k as f64, 0.01 * k as f64))
            .collect();
        let n = notes(&[cause("plate_offset", &drift)], &file(true));
        assert_eq!(n.len(), 1, "{n:?}");
        // 0.01 in per 600 s: 0.06 in per hour.
        assert!(
            n[0].contains("plate_offset's `x` trends with time: +6.000e-2 per hour"),
            "{}",
            n[0]
        );
        let scatter: Vec<(f64, f64)> = [0.01, -0.01, 0.012, -0.009, 0.011, -0.012]
            .iter()
            .enumerate()
            .map(|(k, &v)| (5.0 + 5.0 * k as f64, v))
            .collect();
        assert!(notes(&[cause("plate_offset", &scatter)], &file(true)).is_empty());
        // Other causes are not per separation.
        assert!(notes(&[cause("cell_gain", &drift)], &file(true)).is_empty());
    }

    #[test]
    fn without_time_a_drift_cannot_be_told_and_that_is_said() {
        let n = notes(&[cause("separation_error", &[(5.0, 0.0)])], &file(false));
        assert!(n[0].contains("records no time") && n[0].contains("separation_error"));
    }
}
