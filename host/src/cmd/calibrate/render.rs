//! The `cta calibrate` report as text.

use std::path::Path;

use cta_core::pose::NearField;
use cta_lab::analyze::digits::pm_parts;
use cta_lab::data::fmt_list;
use cta_lab::fit::calibrate::{CalibrationReport, MISFIT_Z};
use cta_lab::fit::magnitude::SettingLight;

/// `out`: `Some(Some(path))` written, `Some(None)` not asked for, `None` its write failed (the
/// error follows the report).
pub(super) fn print_report(rep: &CalibrationReport, out: Option<Option<&Path>>) {
    let f = &rep.file.fitted;
    let c = &rep.file.calibration;
    let nf = c.near_field.unwrap_or(NearField::nominal());
    let seps = match f.separations.as_slice() {
        [a, .., b] if f.separations.len() > 6 => {
            format!("{} separations, {a}-{b} in", f.separations.len())
        }
        v => format!("{} in", fmt_list(v)),
    };
    println!(
        "Sensor calibration from {} ({} points at {seps}; {} left out)",
        f.source, f.points, f.pinned_points
    );
    for n in &rep.data_notes {
        println!("  note: {n}");
    }
    // Each estimate to the digits its 1-sigma resolves (`cta analyze`'s convention).
    let pm = |v: f32, n: &str| pm_parts(f64::from(v), f.sigma[n]);
    let (h, hs) = pm_parts(rep.pinhole_h, f.sigma["H"]);
    println!(
        "  pinhole (eq 65) at {} in: H = {h} ± {hs} counts (chi2/dof {:.2})",
        fmt_list(&f.pinhole_separations),
        rep.pinhole_chi2_dof,
    );
    if let Some(ph) = &c.pinhole {
        let v = |a: &[f32; 3], n: &str| {
            (0..3)
                .map(|k| {
                    let (v, s) = pm(a[k], &format!("pinhole.{n}{}", k + 1));
                    format!("{v} ± {s}")
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        println!(
            "    its d = {} in (its eye point, not the head: README, \"virtual eye\")",
            v(&ph.d, "d")
        );
        println!("    its p = {}", v(&ph.p, "p"));
        println!(
            "    (in the file as `pinhole`: the chip's pinhole model uses this d, p with this H)"
        );
    }
    println!("  near-field (eqs 60-63), started from it:");
    let row = |n: &str, v: f32, unit: &str, what: &str| {
        let (v, s) = pm(v, n);
        let line = format!("    {n:<2} = {v:>12} ± {s:<9} {unit:<5} {what}");
        println!("{}", line.trim_end());
    };
    for (k, n) in ["d1", "d2", "d3"].iter().enumerate() {
        row(n, c.d[k], "in", "");
    }
    for (k, n) in ["p1", "p2", "p3"].iter().enumerate() {
        row(n, c.p[k], "", "");
    }
    let ay = nf.face_angles_deg()[1];
    row("a", nf.alpha_deg, "deg", "(face angle, X pair; 30 nominal)");
    row("ay", ay, "deg", "(face angle, Y pair; 30 nominal)");
    row("s", nf.s, "in", "(cell offset; 0.175 nominal)");
    row("gx", nf.gain[0], "", "(cell 1 gain - 1; 0 nominal)");
    row("gy", nf.gain[1], "", "(cell 3 gain - 1; 0 nominal)");
    row("bx", nf.bias[0], "/in2", "(cell 1 offset; 0 nominal)");
    row("by", nf.bias[1], "/in2", "(cell 3 offset; 0 nominal)");
    println!(
        "    held: beta = {}, beacon pattern m = {}; noise = {:.2} counts ({})",
        nf.beta, nf.pattern_m, c.noise, rep.noise_source
    );
    println!(
        "  chi2/dof {:.3}, residual RMS {:.2} counts, {} iterations, condition {:.2e}",
        f.chi2_dof, f.rms_counts, rep.iterations, rep.condition
    );
    if !f.correlations.is_empty() {
        println!(
            "  strongly correlated (each 1-sigma above is marginal): {}",
            f.correlations
                .iter()
                .map(|(a, b, r)| format!("{a},{b} {r:+.2}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    println!("\n sep(in)  points   RMS pinhole  near-field   noise (counts, point means)");
    for b in &rep.by_separation {
        let line = format!(
            " {:>7}  {:>6}  {:>12}  {:>10.2}  {:>6.2}  {}",
            b.separation_in,
            b.points,
            b.pinhole_counts
                .map(|v| format!("{v:.2}"))
                .unwrap_or_else(|| "-".into()),
            b.near_field_counts,
            b.noise_counts,
            if b.near_field_z > MISFIT_Z {
                format!("<- near-field misses ({:.0} sd)", b.near_field_z)
            } else {
                String::new()
            }
        );
        println!("{}", line.trim_end());
    }
    print_magnitude(rep);
    for w in rep.pinhole_warnings.iter().chain(&rep.warnings) {
        println!("warning: {w}");
    }
    if !rep.warnings.iter().any(|w| w.contains("cta analyze")) {
        println!(
            "note: the 1-sigma above hold if the data hold no effect outside the chip's model; \
             an apparatus error such as a small plate tilt is absorbed by d and p without \
             showing here. `cta analyze {}` checks for it.",
            rep.file.fitted.source
        );
    }
    match out {
        Some(Some(p)) => println!(
            "\nwritten to {}: load it with `cta sensor --port PORT load-calibration {}`",
            p.display(),
            p.display()
        ),
        Some(None) => println!("\n(not written: give --out CAL.json)"),
        None => {}
    }
}

/// The magnitude law's section of the report: the law with its 1-sigma, the noise, the LEDs'
/// brightness, what was used and left out, the residuals per separation and the warnings; or
/// one line saying why there is none.
fn print_magnitude(rep: &CalibrationReport) {
    let Some(m) = &rep.magnitude else {
        if let Some(n) = &rep.magnitude_note {
            println!("\n  spot magnitudes: no law ({n})");
        }
        return;
    };
    let l = &m.law;
    let unit = if m.counts { " counts" } else { "" };
    println!(
        "\n  spot magnitudes (sensitivity {}): {} samples, {} points, {} LEDs at {} in",
        l.sensitivity,
        m.samples,
        m.points,
        m.led_brightness.len(),
        match m.separations.as_slice() {
            [a, .., b] if m.separations.len() > 6 => {
                format!("{} separations, {a}-{b}", m.separations.len())
            }
            v => fmt_list(v),
        }
    );
    let offset = match m.offset_sigma {
        _ if m.offset_at_zero => format!(
            "0 (its bound; 1-sigma {})",
            m.offset_sigma
                .map_or("undetermined".into(), |s| format!("{s:.2e}"))
        ),
        Some(s) => {
            let (v, s) = pm_parts(f64::from(l.offset), s);
            format!("{v} ± {s}")
        }
        None => format!("{:.1} (undetermined)", l.offset),
    };
    let (g, gs) = pm_parts(f64::from(l.exponent), m.exponent_sigma);
    println!("    M = offset + A (b S)^exponent: offset = {offset}{unit}, exponent = {g} ± {gs}");
    println!(
        "    noise {:.3} % of M - offset per reading (within points {:.3} %, points about the \
         law {:.3} %{}); readings at or above {} taken as saturated",
        l.noise_percent,
        m.noise_within_percent,
        m.noise_between_percent,
        if m.counts { "; rounding apart" } else { "" },
        l.max
    );
    println!(
        "    LED brightness b: {:.3}-{:.3}, RMS {:.1} % about 1 (in the file as `led_brightness`, \
         for `cta sensor load-constellation --brightness`)",
        m.brightness_min, m.brightness_max, m.brightness_rms_percent
    );
    if m.settings.len() > 1 {
        let what = |s: &SettingLight| {
            let mut w = Vec::new();
            if let Some(p) = s.power {
                w.push(format!("power {p}"));
            }
            if let Some(f) = s.frequency_hz {
                w.push(format!("{f} Hz"));
            }
            w.join(", ")
        };
        println!(
            "    light per drive setting, relative to {}: {}",
            what(&m.settings[0]),
            m.settings[1..]
                .iter()
                .map(|s| format!("{} {:.4} ± {:.4}", what(s), s.light, s.sigma))
                .collect::<Vec<_>>()
                .join("; ")
        );
    }
    let by = &m.by_separation;
    if by.len() <= 10 {
        println!(
            "    residual RMS per separation (%): {}",
            by.iter()
                .map(|b| format!("{} in {:.3}", b.separation_in, b.rms_percent))
                .collect::<Vec<_>>()
                .join(", ")
        );
    } else {
        let rms = by.iter().map(|b| b.rms_percent);
        println!(
            "    residual RMS per separation: {:.3}-{:.3} % (each in --json)",
            rms.clone().fold(f64::INFINITY, f64::min),
            rms.fold(0.0, f64::max)
        );
    }
    let mut left = Vec::new();
    if m.saturated_points > 0 {
        left.push(format!(
            "{} saturated points ({} readings at or above {})",
            m.saturated_points, m.saturated_samples, l.max
        ));
    }
    if m.pinned_points > 0 {
        left.push(format!(
            "{} points with an output at the 16-bit rail",
            m.pinned_points
        ));
    }
    if m.no_signal_points > 0 {
        left.push(format!("{} points without signal", m.no_signal_points));
    }
    if m.other_sensitivity_samples > 0 {
        left.push(format!(
            "{} samples at other sensitivities ({}; --magnitude-sensitivity chooses)",
            m.other_sensitivity_samples,
            m.sensitivities
                .iter()
                .filter(|(k, _)| *k != l.sensitivity)
                .map(|(k, n)| format!("{k}: {n}"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    if !left.is_empty() {
        println!("    left out: {}", left.join("; "));
    }
    for w in &m.warnings {
        println!("warning: spot magnitudes: {w}");
    }
}
