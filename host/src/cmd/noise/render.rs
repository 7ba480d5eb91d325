//! The `cta noise` report as text: the table per factor, the glitch check, the weighting and
//! the magnitudes' repeatability.

use cta_lab::data::Glitches;
use cta_lab::noise::NoiseReport;

use crate::cmd::num;

/// The report as the table `cta noise` prints.
pub fn render_text(r: &NoiseReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "cta noise {}: {} samples, {} points with repeated samples ({} single)",
        r.file, r.samples, r.points_repeated, r.points_single
    );
    let lo = &r.left_out;
    if lo.points > 0 {
        let by: Vec<String> = lo
            .by_separation
            .iter()
            .map(|(sep, n)| format!("{sep} in: {n}"))
            .collect();
        let _ = writeln!(
            s,
            "{} points left out ({} with a coordinate pinned at +/-32767 in some sample, {} with \
             a mean within 3 sigma of it):\n  a cell in shadow or saturated clips the spread, so \
             they would read quieter than the sensor is ({})",
            lo.points,
            lo.pinned_sample,
            lo.mean_near_rail,
            by.join(", ")
        );
    }
    let _ = writeln!(
        s,
        "one-sample std over the file: X {}, Y {} counts; X-Y correlation {}\n",
        num(r.std_all[0], 0, 2, "undefined"),
        num(r.std_all[1], 0, 2, "undefined"),
        if r.xy_correlation.is_finite() {
            format!("{:+.3}", r.xy_correlation)
        } else {
            "undefined (an axis does not vary)".into()
        }
    );
    let _ = write!(s, "{}", render_glitches(&r.glitches));
    for f in &r.factors {
        if f.groups.is_empty() {
            let _ = writeln!(s, "by {}: not recorded in the file\n", f.factor);
            continue;
        }
        let test = if f.test_dof > 0 && !(f.statistic[0].is_finite() && f.statistic[1].is_finite())
        {
            "no test: a group's samples do not vary (noise-free or constant data)".into()
        } else if f.test_dof > 0 {
            format!(
                "{}: Bartlett chi2 X {:.1}, Y {:.1} on {} dof, 1 % bound {:.1}",
                if f.significant {
                    "differs beyond sampling"
                } else {
                    "within sampling"
                },
                f.statistic[0],
                f.statistic[1],
                f.test_dof,
                f.bound
            )
        } else {
            "one group: nothing to compare".into()
        };
        let ratio = if f.spread_ratio.is_finite() {
            format!("max/min {:.2}, ", f.spread_ratio)
        } else {
            String::new()
        };
        let unit = match f.factor.as_str() {
            "signal magnitude" => " (groups in the file's magnitude units)",
            _ => "",
        };
        let _ = writeln!(s, "by {}{unit} ({ratio}{test}):", f.factor);
        let _ = writeln!(
            s,
            "  {:<16} {:>7} {:>8} {:>10} {:>10}",
            "group", "points", "dof", "std X", "std Y"
        );
        for g in &f.groups {
            let _ = writeln!(
                s,
                "  {:<16} {:>7} {:>8} {} {}",
                g.label,
                g.points,
                g.dof,
                num(g.std_x, 10, 2, "-"),
                num(g.std_y, 10, 2, "-")
            );
        }
        let _ = writeln!(s);
    }
    let within_setting = if r.within_setting_dispersion.is_finite()
        && (r.within_setting_dispersion - r.within_separation_dispersion).abs() > 0.005
    {
        format!(
            "; within a separation and setting: {:.2}",
            r.within_setting_dispersion
        )
    } else {
        String::new()
    };
    let _ = writeln!(
        s,
        "within-separation dispersion of point variances: {}{within_setting}",
        if r.within_separation_dispersion.is_finite() {
            format!("{:.2} (1 = homogeneous)", r.within_separation_dispersion)
        } else {
            "undefined (no point's samples vary)".into()
        }
    );
    let _ = writeln!(s, "weighting: {}", r.weighting);
    match &r.magnitude {
        None => {
            let _ = writeln!(s, "\nspot magnitude: not recorded in the file");
        }
        Some(m) => {
            let _ = writeln!(
                s,
                "\nspot magnitude repeatability (one-sample std / mean, {} points): {:.3} % over the file",
                m.points, m.percent
            );
            let by: Vec<String> = m
                .by_separation
                .iter()
                .map(|(sep, pc, _)| format!("{sep} in {pc:.3} %"))
                .collect();
            for (k, chunk) in by.chunks(6).enumerate() {
                let head = if k == 0 { "by separation:" } else { "" };
                let _ = writeln!(s, "  {head:<14} {}", chunk.join(", "));
            }
            if m.percent < 1e-9 {
                let _ = writeln!(
                    s,
                    "  no spread at all: a simulation without magnitude noise (the NorthStar's is \
                     unmeasured; `cta simulate --magnitude-noise PERCENT` adds some as a what-if)"
                );
            } else {
                let _ = writeln!(
                    s,
                    "  what the magnitudes would add to the pose at this noise: \
                     `cta sensor floor --magnitude-noise {:.2}` (brightness differences between LEDs\n  \
                     are not in this figure: they need their own calibration)",
                    m.percent
                );
            }
        }
    }
    if let Some(c) = &r.crosstalk {
        let _ = writeln!(s, "\n{}", c.summary());
    }
    s
}

/// The glitch lines of the table: robust sigma against std, and the heavy tail when there is one.
fn render_glitches(g: &Glitches) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    if g.points_checked == 0 || g.axes.len() != 2 {
        let _ = writeln!(
            s,
            "glitch check: no point with {} or more samples off the 16-bit rail (nothing to check)\n",
            cta_lab::data::GLITCH_MIN_SAMPLES
        );
        return s;
    }
    let (x, y) = (&g.axes[0], &g.axes[1]);
    let floor = cta_lab::data::GLITCH_FLOOR_COUNTS;
    let ratio = if x.robust_sigma >= floor && y.robust_sigma >= floor {
        format!(
            "std / robust sigma X {:.2}, Y {:.2} (about 1 for Gaussian noise)",
            x.std_with / x.robust_sigma,
            y.std_with / y.robust_sigma
        )
    } else {
        format!("a robust sigma below the {floor} count resolution: no ratio")
    };
    let _ = writeln!(
        s,
        "robust sigma (median absolute deviation from each point's median, {} points of {}+ \
         samples): X {:.2}, Y {:.2} counts;\n  std over the same points X {:.2}, Y {:.2}: {ratio}",
        g.points_checked,
        cta_lab::data::GLITCH_MIN_SAMPLES,
        x.robust_sigma,
        y.robust_sigma,
        x.std_with,
        y.std_with,
    );
    if g.samples == 0 {
        let _ = writeln!(
            s,
            "  no sample lies more than {} robust sigma from its point's median: no glitches\n",
            g.threshold_sigma
        );
    } else {
        let lines = |a: &cta_lab::data::AxisGlitches| {
            let shown: Vec<String> = a.lines.iter().take(8).map(|l| l.to_string()).collect();
            format!(
                "{}{}",
                shown.join(", "),
                if a.lines.len() > 8 { ", ..." } else { "" }
            )
        };
        let _ = writeln!(
            s,
            "  HEAVY TAIL: {} of {} samples lie more than {} robust sigma from their point's \
             median (glitches: an ID mix-up, a corrupted report?), kept in every figure here:",
            g.samples, g.samples_checked, g.threshold_sigma
        );
        for a in [x, y] {
            if a.samples > 0 {
                let _ = writeln!(
                    s,
                    "    {}: {} samples (lines {}); std {:.2} with them, {:.2} without ({:.1}-fold)",
                    a.axis,
                    a.samples,
                    lines(a),
                    a.std_with,
                    a.std_without,
                    a.inflation()
                );
            }
        }
        let _ = writeln!(
            s,
            "  every fit weights by the std: remove those lines, or re-measure\n"
        );
    }
    s
}
