//! Plausibility against the apparatus: an apparatus cause (`plate_offset`,
//! `separation_error`, `plate_tilt`) whose fitted size is far beyond what the CTA's
//! uncertainty budget allows (thesis Ch IV, Table 2's root-sum-square of eq 26, or the user's
//! `--budget`) is not a plate that is that far off: it is something else the per-separation
//! freedom absorbs (a cell gain that drifts over the run moves the output like a plate moved
//! sideways). Such a cause keeps its fit but carries a warning that says so and names the
//! alternatives the data point to.

use super::model::Cand;
use super::result::{BudgetCheck, ParamMap};
use crate::budget::Budget;

/// A fitted apparatus error this many times the budget line it is compared with is "far
/// beyond" it: the budget's items are 1-sigma uncertainties (Ch IV), so an RMS of 3 of them over
/// a dozen separations is not a draw from it (the RMS of 13 draws is within 1 +/- 0.2 of the
/// sigma).
pub const BEYOND_BUDGET: f64 = 3.0;

/// A per-separation series whose straight-line fit against the run's separation order explains
/// at least this share of its variance is said to trend (under no trend the share is about
/// 1/(n-1): 0.08 for 13 separations).
pub const TREND_R2: f64 = 0.5;

/// Share of the variance of `v` (in the run's order) that a straight line against its index
/// explains (0 for fewer than 4 values or no variance).
fn trend_r2(v: &[f64]) -> f64 {
    let n = v.len();
    if n < 4 {
        return 0.0;
    }
    let nf = n as f64;
    let mx = (nf - 1.0) / 2.0;
    let my = v.iter().sum::<f64>() / nf;
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (i, y) in v.iter().enumerate() {
        let dx = i as f64 - mx;
        sxy += dx * (y - my);
        sxx += dx * dx;
        syy += (y - my) * (y - my);
    }
    if syy <= 0.0 {
        return 0.0;
    }
    sxy * sxy / (sxx * syy)
}

/// The per-separation values `NAME@...` of `params`, in separation order.
fn series(params: &ParamMap, name: &str) -> Vec<f64> {
    let pre = format!("{name}@");
    params
        .iter()
        .filter(|(n, _)| n.starts_with(&pre))
        .map(|(_, v)| *v)
        .collect()
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// What else makes a per-separation apparatus estimate this large, per cause.
fn alternatives(c: Cand) -> &'static str {
    match c {
        Cand::PlateOffset => {
            "a cell gain or bias that changes between separations (a detector warming up over \
             the run: `gain_drift`), LEDs off their pads (`led_position`), or a head that moved \
             during the run"
        }
        Cand::SeparationError => {
            "a scale error of the recorded separations, light on all four cells (`ambient`) or a \
             beacon pattern that grows wrong with distance, or a gain that drifts over the run"
        }
        Cand::LedPosition => {
            "a head or plate that moved between separations (`plate_offset`), or a beacon \
             pattern that differs from LED to LED"
        }
        Cand::ArrayPose => {
            "LEDs off their pads one by one (`led_position`), or a head or plate that moved \
             between separations (`plate_offset`)"
        }
        Cand::PlateTilt => {
            "LED boresights tilted one by one (`led_tilt`) or all alike (`beacon_tilt`), or a \
             gain that drifts over the run"
        }
        _ => "",
    }
}

/// The budget check of a named apparatus cause `c` with the final model's `params` (None for
/// a cause that is not an apparatus error). The budget line: Table 2's (or `budget`'s)
/// root-sum-square per axis (eq 26, the larger side), X and Y for `plate_offset` (the worse
/// axis is reported), Z for `separation_error`, and Z for `plate_tilt` as the height change
/// `r tan T` its RMS tilt makes at the beacon farthest from the plate's centre, `r_max` in.
pub fn check(c: Cand, params: &ParamMap, budget: &Budget, r_max: f64) -> Option<BudgetCheck> {
    let rss = budget.rss_inches();
    let src = match &budget.file {
        Some(p) => format!("the budget {}", p.display()),
        None => "thesis Table 2".to_string(),
    };
    // (axis name, fitted in, budget in, series for the trend test)
    let (axis, fitted, allowed, trends): (&str, f64, f64, Vec<(&str, Vec<f64>)>) = match c {
        Cand::PlateOffset => {
            let (x, y) = (series(params, "x"), series(params, "y"));
            let (rx, ry) = (rms(&x) / rss[0], rms(&y) / rss[1]);
            if rx >= ry {
                ("X", rms(&x), rss[0], vec![("x", x), ("y", y)])
            } else {
                ("Y", rms(&y), rss[1], vec![("x", x), ("y", y)])
            }
        }
        Cand::SeparationError => {
            let z = series(params, "z");
            ("Z", rms(&z), rss[2], vec![("z", z)])
        }
        Cand::PlateTilt => {
            let (tx, ty) = (series(params, "tx_deg"), series(params, "ty_deg"));
            let t = (rms(&tx).powi(2) + rms(&ty).powi(2)).sqrt();
            let h = r_max * t.to_radians().tan();
            ("Z", h, rss[2], vec![("tx_deg", tx), ("ty_deg", ty)])
        }
        // The arrays' shifts against the placement lines, as the LEDs' (each array is placed
        // on the plate as an LED is on its pads; Table 2 has no line of its own for it).
        Cand::LedPosition | Cand::ArrayPose => {
            let (x, y) = (series(params, "dx"), series(params, "dy"));
            let (rx, ry) = (rms(&x) / rss[0], rms(&y) / rss[1]);
            if rx >= ry {
                ("X", rms(&x), rss[0], Vec::new())
            } else {
                ("Y", rms(&y), rss[1], Vec::new())
            }
        }
        _ => return None,
    };
    let (budget_mils, fitted_mils) = (allowed * 1e3, fitted * 1e3);
    let line = format!("{axis} root-sum-square of {src} (eq 26): {budget_mils:.1} mils");
    let ratio = if budget_mils > 0.0 {
        fitted_mils / budget_mils
    } else {
        f64::INFINITY
    };
    let warning = (ratio > BEYOND_BUDGET).then(|| {
        let what = match c {
            Cand::PlateTilt => {
                format!("its RMS tilt moves the farthest beacon by {fitted_mils:.1} mils in Z")
            }
            _ => format!("its RMS over the separations is {fitted_mils:.1} mils in {axis}"),
        };
        let trend: Vec<String> = trends
            .iter()
            .map(|(n, v)| (n, trend_r2(v)))
            .filter(|(_, r2)| *r2 >= TREND_R2)
            .map(|(n, r2)| format!("{n} (R^2 {r2:.2})"))
            .collect();
        let trend = if trend.is_empty() {
            String::new()
        } else {
            format!(
                "; its per-separation values follow the separation order, the run's order \
                 when the sweep went one way: {}, which a drift over the run makes and a \
                 misplaced plate does not (without a time column a drift cannot be told from \
                 per-separation apparatus errors)",
                trend.join(", ")
            )
        };
        format!(
            "{what}, {ratio:.1} times the {line}: an apparatus that far off is implausible, so \
             `{}` is not named as found. The data point to {}{trend}",
            c.name(),
            alternatives(c)
        )
    });
    Some(BudgetCheck {
        line,
        budget_mils,
        fitted_mils,
        ratio,
        warning,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_is_a_trend_and_noise_is_not() {
        let line: Vec<f64> = (0..13).map(|i| 0.01 * i as f64 - 0.06).collect();
        assert!((trend_r2(&line) - 1.0).abs() < 1e-12);
        // Alternating values: no linear trend at all.
        let alt: Vec<f64> = (0..13)
            .map(|i| if i % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        assert!(trend_r2(&alt) < 0.05, "{}", trend_r2(&alt));
        assert_eq!(trend_r2(&[1.0, 2.0]), 0.0);
    }

    fn offsets(x: f64) -> ParamMap {
        let mut p = ParamMap::default();
        for (k, sep) in [2, 3, 4, 5, 6].iter().enumerate() {
            let s = if k % 2 == 0 { x } else { -x };
            p.insert(format!("x@{sep}in"), s);
            p.insert(format!("y@{sep}in"), 0.0);
        }
        p
    }

    #[test]
    fn plate_offset_is_compared_with_the_x_root_sum_square() {
        let t2 = Budget::table2();
        // Table 2's X root-sum-square is 31.5 mils: 0.05 in RMS is 1.6 times it, 0.11 in 3.5.
        let ok = check(Cand::PlateOffset, &offsets(0.05), &t2, 6.4).unwrap();
        assert!((ok.budget_mils - 31.5).abs() < 0.1, "{}", ok.budget_mils);
        assert!((ok.ratio - 50.0 / ok.budget_mils).abs() < 1e-9);
        assert!(ok.warning.is_none());
        assert!(
            ok.line.starts_with("X root-sum-square of thesis Table 2"),
            "{}",
            ok.line
        );
        let far = check(Cand::PlateOffset, &offsets(0.11), &t2, 6.4).unwrap();
        let w = far.warning.unwrap();
        assert!(w.contains("3.5 times") && w.contains("gain_drift"), "{w}");
        // Not a trend (alternating).
        assert!(!w.contains("separation order"), "{w}");
        // A global effect is no apparatus error.
        assert!(check(Cand::CellGain, &ParamMap::default(), &t2, 6.4).is_none());
    }
}
