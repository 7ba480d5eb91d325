//! The `cta analyze` result as text.

use crate::cmd::num;
use cta_lab::analyze::{correlation_lines, cross_correlation_line, pm_parts, unit, Analysis};

/// The analysis as `cta analyze` prints it: the verdict, the causes, the candidates not
/// named, the residuals per separation and the final parameters.
pub fn render_text(a: &Analysis) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "cta analyze {} (from `{}`)", a.file, a.model_from);
    let _ = writeln!(
        s,
        "  {} samples -> {} points ({} left out: output at or near the 16-bit rail), separations {}",
        a.samples,
        a.points,
        a.excluded_points,
        cta_lab::data::fmt_list(&a.separations)
    );
    let _ = writeln!(s, "  {}", a.noise);
    for n in &a.data_notes {
        let _ = writeln!(s, "  note: {n}");
    }
    let _ = writeln!(s, "\n{}\n", a.verdict);
    if let Some(c) = &a.crosstalk {
        let _ = writeln!(s, "{}\n", c.summary());
    }
    for (k, c) in a.causes.iter().chain(&a.tentative).enumerate() {
        let tag = if k < a.causes.len() {
            ""
        } else {
            " (tentative, not named)"
        };
        let _ = writeln!(
            s,
            "{}. {}{tag}: held-out RMS {:.1} -> {:.1} counts ({:.1} from noise alone: systematic {:.1} -> {:.1}), dchi2 {:.0}, dBIC {:.0}, chi2/dof after {:.2}",
            k + 1,
            c.effect,
            c.heldout_rms_before,
            c.heldout_rms_after,
            c.heldout_noise_rms,
            c.systematic_rms_before,
            c.systematic_rms_after,
            c.dchi2,
            c.dbic,
            c.chi2_dof_after
        );
        let shown = c.global_params("+/-");
        if !shown.is_empty() {
            let _ = writeln!(s, "     {}", shown.join(", "));
        }
        for line in correlation_lines(&c.correlations, &c.base_correlations) {
            let _ = writeln!(s, "     {line}");
        }
        if let Some(line) = c.rivals_line() {
            let _ = writeln!(s, "     {line}");
        }
        if let Some(c) = &c.caution {
            let _ = writeln!(s, "     caution: {c}");
        }
        if let Some(b) = &c.budget {
            let _ = writeln!(
                s,
                "     against the apparatus budget: {:.1} mils fitted, {:.1} times the {}",
                b.fitted_mils, b.ratio, b.line
            );
            if let Some(w) = &b.warning {
                let _ = writeln!(s, "     warning: {w}");
            }
        }
        let _ = writeln!(s, "     on the sensor board: {}", c.board);
    }
    if let Some(line) = cross_correlation_line(&a.cross_correlations) {
        let _ = writeln!(s, "{line}");
    }
    for d in &a.dropped {
        let _ = writeln!(s, "\ndropped: {}", d.line());
    }
    if !a.ruled_out.is_empty() {
        let _ = writeln!(
            s,
            "{}not named (tried on top of the final model, not accepted): estimate +/- \
             1-sigma; the data allow about estimate +/- 2 sigma{}",
            if a.causes.is_empty() && a.tentative.is_empty() {
                ""
            } else {
                "\n"
            },
            if a.unexplained {
                " (too small here: structure remains)"
            } else {
                ""
            }
        );
        for r in &a.ruled_out {
            let est = r.estimates("+/-");
            let note = r.note.as_deref().unwrap_or_default();
            let _ = if est.is_empty() {
                writeln!(s, "  {}: {note}", r.effect)
            } else if note.is_empty() {
                writeln!(s, "  {}: {est} (dBIC {:.0})", r.effect, r.dbic)
            } else {
                writeln!(s, "  {}: {est} (dBIC {:.0}): {note}", r.effect, r.dbic)
            };
            for line in correlation_lines(&r.correlations, &r.base_correlations) {
                let _ = writeln!(s, "    {line}");
            }
        }
    } else if let Some(n) = &a.ruled_out_note {
        let _ = writeln!(s, "\nnot named: none tried on top of the final model ({n})");
    }
    if !a.structure.is_empty() {
        let _ = writeln!(s, "\nwhere the residuals stand out (chi2 per residual):");
        for n in &a.structure {
            let _ = writeln!(s, "  - {n}");
        }
    }
    for u in &a.untested {
        let _ = writeln!(s, "could not test `{}`: {}", u.effect, u.reason);
    }
    let _ = writeln!(
        s,
        "\nchi2/dof {:.3} -> {:.3}; held-out RMS {:.2} -> {:.2} counts",
        a.chi2_dof_before, a.chi2_dof_after, a.rms_before, a.rms_after
    );
    // One width a column, for the header and the rows alike: a separation of the form
    // 19.9992 or 100.25 stays in its column.
    let _ = writeln!(
        s,
        "\n{:>8}  {:>16}  {:>11}  {:>19}  {:>6}  {:>11}",
        "sep (in)",
        "angle std before",
        "after (deg)",
        "held-out RMS before",
        "after",
        "noise alone (counts)"
    );
    for (k, sep) in a.separations.iter().enumerate() {
        let _ = writeln!(
            s,
            "{:>8}  {}  {}  {}  {}  {}",
            sep.to_string(),
            num(a.angle_std_before_deg[k], 16, 4, "-"),
            num(a.angle_std_after_deg[k], 11, 4, "-"),
            num(a.heldout_rms_by_sep_before[k], 19, 1, "-"),
            num(a.heldout_rms_by_sep_after[k], 6, 1, "-"),
            num(a.noise_rms_by_sep[k], 11, 1, "-")
        );
    }
    if a.angle_left_out > 0 {
        let _ = writeln!(
            s,
            "  (angle std over the points both models turn into a direction: {} near the \
             output rail left out, where one of them cannot)",
            a.angle_left_out
        );
    }
    let _ = writeln!(s, "\nfinal parameters:");
    for p in &a.params_after {
        let (v, sg) = pm_parts(p.value, p.sigma);
        let unit = match p.name.split_once('.') {
            Some((effect, param)) => unit(effect, param),
            None if ["d1", "d2", "d3"].contains(&p.name.as_str()) => " in",
            None if p.name == "H" => " counts",
            None => "",
        };
        let _ = writeln!(s, "  {:<26} {v:>14} +/- {sg}{unit}", p.name);
    }
    s
}
