//! The self-contained HTML report of `cta analyze --report DIR`: one `index.html` with
//! inline SVG plots (plotters' SVG backend) and no external resources.
//!
//! Contents: the verdict; the named causes with parameters, 1-sigma, strong correlations and
//! held-out gain, and the strong correlations between causes; the causes dropped as
//! redundant; the candidates not named on top of the final model with their estimates +/-
//! 1-sigma and strong correlations; the evidence (every candidate of every round with its
//! estimates, chi-square and BIC improvement and held-out RMS); residual quiver maps per
//! separation before and after; held-out RMS versus separation; chi-square per residual
//! versus off-boresight angle; Figure 57's statistic on each model's residual (angle spread
//! versus separation; no truth used) before and after; the final parameter table; and the residual diagnostics. Every
//! value +/- 1-sigma is rounded as `analyze::digits` says.

use super::{
    correlation_lines, cross_correlation_line, g, pm, pm_parts, Analysis, Cause, Correlation,
};
use crate::html::escape as html_escape;
use crate::plot::{render_svg, Panel, Series};
use crate::provenance::Provenance;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Why the report could not be written.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReportError {
    /// `index.html` may not be replaced, or could not be written.
    #[error("{0}")]
    Write(String),
    /// A plot could not be drawn.
    #[error("{}: plotting failed: {why}", path.display())]
    Plot {
        /// The page.
        path: PathBuf,
        /// Why.
        why: DrawError,
    },
}

/// Why a plot of the report could not be drawn.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct DrawError(pub String);

/// Whether the report may be written into `dir`: its `index.html` is new or one `cta` wrote
/// ([`crate::plot::refuse_to_replace`]). Checked before the work, so a refusal costs nothing.
pub fn check(dir: &Path) -> Result<(), ReportError> {
    crate::plot::refuse_to_replace(&dir.join("index.html"))
        .map_err(|e| ReportError::Write(e.to_string()))
}

/// Write `DIR/index.html` (missing folders created; refused over a file `cta` did not write,
/// [`check`]; errors read `cannot write PATH: reason`).
pub fn write(dir: &Path, a: &Analysis, provenance: Option<&Provenance>) -> Result<(), ReportError> {
    let index = dir.join("index.html");
    check(dir)?;
    let html = render(a, provenance).map_err(|why| ReportError::Plot {
        path: index.clone(),
        why,
    })?;
    crate::plot::write_marked(&index, &html).map_err(|e| ReportError::Write(e.to_string()))
}

/// The correlation lines of a candidate as HTML to append to its estimates cell (empty when
/// there are none).
fn correlation_html(own: &[Correlation], base: &[Correlation]) -> String {
    correlation_lines(own, base)
        .iter()
        .map(|l| format!("<br><i>{}</i>", html_escape(l)))
        .collect()
}

fn cause_rows(s: &mut String, causes: &[Cause]) {
    for (k, c) in causes.iter().enumerate() {
        let params = c.global_params("&plusmn;");
        let _ = write!(
            s,
            "<tr><td>{}</td><td><b>{}</b></td><td>{}{}</td><td>{:.1} &rarr; {:.1}<br><small>noise alone {:.1}: systematic {:.1} &rarr; {:.1}</small></td>\
             <td>{:.0}</td><td>{:.0}</td><td>{:.3}</td></tr>",
            k + 1,
            c.effect,
            params.join("<br>"),
            correlation_html(&c.correlations, &c.base_correlations),
            c.heldout_rms_before,
            c.heldout_rms_after,
            c.heldout_noise_rms,
            c.systematic_rms_before,
            c.systematic_rms_after,
            c.dchi2,
            c.dbic,
            c.chi2_dof_after
        );
        if let Some(line) = c.rivals_line() {
            let _ = write!(
                s,
                "<tr><td></td><td colspan=6>{}</td></tr>",
                html_escape(&line)
            );
        }
        if let Some(c) = &c.caution {
            let _ = write!(
                s,
                "<tr><td></td><td colspan=6><b>Caution:</b> {}</td></tr>",
                html_escape(c)
            );
        }
        if let Some(b) = &c.budget {
            let _ = write!(
                s,
                "<tr><td></td><td colspan=6>Against the apparatus budget: {:.1} mils fitted, \
                 {:.1} times the {}</td></tr>",
                b.fitted_mils,
                b.ratio,
                html_escape(&b.line)
            );
            if let Some(w) = &b.warning {
                let _ = write!(
                    s,
                    "<tr><td></td><td colspan=6><b>Warning:</b> {}</td></tr>",
                    html_escape(w)
                );
            }
        }
        let _ = write!(
            s,
            "<tr><td></td><td colspan=6>On the sensor board: {}</td></tr>",
            html_escape(&c.board)
        );
        let locals: Vec<String> = c
            .params
            .iter()
            .filter(|(n, _)| n.contains('@'))
            .map(|(n, v)| match c.sigma.get(n) {
                Some(sg) => format!("{n} = {}", pm(*v, *sg, "&plusmn;")),
                None => format!("{n} = {}", g(*v)),
            })
            .collect();
        if !locals.is_empty() {
            // Held at zero mean as in `Model::zero_mean`: the plate's offsets and separation
            // errors always, its tilts when the offsets are named too.
            let relative = match c.effect.as_str() {
                "plate_offset" | "separation_error" => {
                    " (relative to their mean; the common part is in the head offset d)"
                }
                "plate_tilt" if causes.iter().any(|o| o.effect == "plate_offset") => {
                    " (relative to their mean; the common part is in the head pose and the \
                     plate offsets)"
                }
                _ => "",
            };
            let _ = write!(
                s,
                "<tr><td></td><td colspan=6><details><summary>per-separation values{}</summary>{}</details></td></tr>",
                relative,
                locals.join(", ")
            );
        }
    }
}

/// The candidates tried on top of the final model and not accepted, with how tightly the data
/// bound each.
fn ruled_out(s: &mut String, a: &Analysis) {
    if a.ruled_out.is_empty() {
        if let Some(n) = &a.ruled_out_note {
            let _ = write!(
                s,
                "<h2>Not named</h2><p>None tried on top of the final model ({}).</p>",
                html_escape(n)
            );
        }
        return;
    }
    let _ = write!(
        s,
        "<h2>Not named</h2><p>Candidates tried on top of the final model and not accepted, with \
         their estimates &plusmn; 1-sigma (GLSDC covariance; delta method for derived \
         quantities): the data still allow an effect of about the estimate &plusmn; 2 sigma, \
         measured from the no-effect value. The 1-sigma are marginal: correlations between a \
         candidate's parameters of 0.5 or more in magnitude, and with a starting-model \
         parameter of 0.9 or more, are listed under its estimates. Per-separation effects: the RMS of the \
         per-separation estimates against the RMS that noise alone would give.{}</p><table><tr>\
         <th>candidate</th><th>estimates (1-sigma)</th><th>&Delta;BIC</th><th>note</th></tr>",
        if a.unexplained {
            " Structure remains unexplained, so these 1-sigma are too small."
        } else {
            ""
        }
    );
    for r in &a.ruled_out {
        let est = r.estimates("+/-");
        let _ = write!(
            s,
            "<tr><td>{}</td><td>{}{}</td><td>{}</td><td>{}</td></tr>",
            r.effect,
            html_escape(&est).replace("+/-", "&plusmn;"),
            correlation_html(&r.correlations, &r.base_correlations),
            if r.fitted {
                format!("{:.1}", r.dbic)
            } else {
                String::new()
            },
            html_escape(r.note.as_deref().unwrap_or(""))
        );
    }
    s.push_str("</table>");
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em}\
table{border-collapse:collapse;margin:0.5em 0}td,th{border:1px solid #ccc;padding:3px 8px;\
text-align:left;vertical-align:top}th{background:#eee}.verdict{font-size:1.3em;padding:0.5em;\
background:#f4f4e8;border-left:6px solid #c90}.acc{background:#e6f4e6}svg{max-width:100%;height:auto}";

/// The whole page, with where it came from when `provenance` is given.
pub fn render(a: &Analysis, provenance: Option<&Provenance>) -> Result<String, DrawError> {
    let mut s = String::new();
    let _ = write!(
        s,
        "<!doctype html><html><head><meta charset=utf-8>\
         <meta name=viewport content=\"width=device-width, initial-scale=1\">\
         <title>cta analyze: {}</title><style>{STYLE}</style></head><body>",
        html_escape(&a.file)
    );
    let _ = write!(
        s,
        "<h1>cta analyze</h1><p>{} &mdash; starting model <b>{}</b>; {} samples &rarr; {} points \
         ({} left out: output at or near the 16-bit rail); {}.</p><p class=verdict>{}</p>",
        html_escape(&a.file),
        a.model_from,
        a.samples,
        a.points,
        a.excluded_points,
        html_escape(&a.noise),
        html_escape(&a.verdict)
    );
    for n in &a.data_notes {
        let _ = write!(s, "<p><b>note:</b> {}</p>", html_escape(n));
    }
    let _ = write!(
        s,
        "<p>chi2/dof {:.3} &rarr; {:.3}; held-out RMS {:.2} &rarr; {:.2} counts, against \
         {:.2} from noise alone (cross-validation folds, held-out separations: {}).</p>",
        a.chi2_dof_before,
        a.chi2_dof_after,
        a.rms_before,
        a.rms_after,
        a.heldout_noise_rms,
        a.folds
            .iter()
            .map(|f| format!("[{}]", crate::data::fmt_list(f)))
            .collect::<Vec<_>>()
            .join(" ")
    );
    let head =
        "<tr><th>#</th><th>effect</th><th>parameters (1-sigma)</th><th>held-out RMS, counts</th>\
                <th>&Delta;chi2</th><th>&Delta;BIC</th><th>chi2/dof after</th></tr>";
    if !a.causes.is_empty() {
        let _ = write!(s, "<h2>Named causes</h2><table>{head}");
        cause_rows(&mut s, &a.causes);
        s.push_str("</table>");
    }
    if !a.tentative.is_empty() {
        let _ = write!(
            s,
            "<h2>Partial improvements (not named)</h2><p>These extensions lower chi-square but \
             leave chi2/dof clearly above 1: the data hold structure outside the vocabulary, so \
             none is named with confidence.</p><table>{head}"
        );
        cause_rows(&mut s, &a.tentative);
        s.push_str("</table>");
    }
    if let Some(line) = cross_correlation_line(&a.cross_correlations) {
        let _ = write!(
            s,
            "<p><i>{}</i> (|rho| &ge; 0.9 in the final model's fit: these causes' sizes trade \
             against each other, and their 1-sigma alone mislead)</p>",
            html_escape(&line)
        );
    }
    if !a.dropped.is_empty() {
        s.push_str(
            "<h2>Dropped</h2><p>Named in an early round, then made redundant by the causes \
             named after them (the search was rerun without them):</p><ul>",
        );
        for d in &a.dropped {
            let _ = write!(s, "<li>{}</li>", html_escape(&d.line()));
        }
        s.push_str("</ul>");
    }
    if !a.structure.is_empty() {
        s.push_str("<h2>Where the unexplained structure is</h2><ul>");
        for n in &a.structure {
            let _ = write!(s, "<li>{}</li>", html_escape(n));
        }
        s.push_str("</ul>");
    }
    if !a.untested.is_empty() {
        s.push_str("<h2>Candidates that could not be tested</h2><ul>");
        for u in &a.untested {
            let _ = write!(
                s,
                "<li><b>{}</b>: {}</li>",
                u.effect,
                html_escape(&u.reason)
            );
        }
        s.push_str("</ul>");
    }
    ruled_out(&mut s, a);
    // Evidence.
    s.push_str(
        "<h2>Evidence: every candidate, every round</h2><p>Accepted when &Delta;BIC &gt; 10 \
         and the held-out chi-square drops; the best &Delta;BIC is tried first.</p><table><tr>\
         <th>round</th><th>candidate</th><th>k</th><th>estimates (1-sigma)</th>\
         <th>&Delta;chi2</th><th>&Delta;BIC</th><th>held-out RMS</th><th>note</th></tr>",
    );
    for t in &a.trials {
        let _ = write!(
            s,
            "<tr{}><td>{}</td><td>{}</td><td>{}</td><td>{}{}</td><td>{:.1}</td><td>{:.1}</td><td>{}</td>\
             <td>{}</td></tr>",
            if t.accepted { " class=acc" } else { "" },
            t.round,
            t.effect,
            t.k,
            html_escape(&t.estimates("+/-")).replace("+/-", "&plusmn;"),
            correlation_html(&t.correlations, &t.base_correlations),
            t.dchi2,
            t.dbic,
            t.heldout_rms.map(|v| format!("{v:.2}")).unwrap_or_default(),
            if t.accepted {
                "accepted".to_string()
            } else {
                html_escape(t.failure.as_deref().unwrap_or(""))
            }
        );
    }
    s.push_str("</table>");
    // Plots.
    let seps = &a.separations;
    let before_name = format!("before ({} starting model)", a.model_from);
    let line = |title: &str, y: &str, log_y: bool, b: &[f64], af: &[f64]| Panel {
        title: title.into(),
        x_desc: "separation (in)".into(),
        y_desc: y.into(),
        log_x: false,
        log_y,
        series: vec![
            Series::new(
                before_name.as_str(),
                seps.iter().copied().zip(b.iter().copied()).collect(),
            ),
            Series::new(
                "after (final model)",
                seps.iter().copied().zip(af.iter().copied()).collect(),
            ),
        ],
    };
    let ang = |d: &super::diag::Diagnostics| -> Vec<(f64, f64)> {
        d.by_angle
            .iter()
            .map(|b| {
                let lo: f64 = b
                    .label
                    .split(['-', '+'])
                    .next()
                    .and_then(|v| v.trim().parse().ok())
                    .unwrap_or(0.0);
                (lo + 5.0, b.chi2_per_row)
            })
            .collect()
    };
    let mut heldout = line(
        "held-out residual vs separation",
        "held-out RMS (counts)",
        true,
        &a.heldout_rms_by_sep_before,
        &a.heldout_rms_by_sep_after,
    );
    heldout.series.push(Series::dashed(
        "noise alone",
        seps.iter()
            .copied()
            .zip(a.noise_rms_by_sep.iter().copied())
            .collect(),
    ));
    let panels = vec![
        line(
            "residual as an angle: spread per separation (no truth used)",
            "std of the residual angle (deg)",
            true,
            &a.angle_std_before_deg,
            &a.angle_std_after_deg,
        ),
        heldout,
        Panel {
            title: "residual vs off-boresight angle".into(),
            x_desc: "off-boresight angle (deg)".into(),
            y_desc: "chi2 per residual".into(),
            log_x: false,
            log_y: true,
            series: vec![
                Series::new("before", ang(&a.diagnostics_before)),
                Series::new("after", ang(&a.diagnostics_after)),
                Series::dashed("noise floor", vec![(0.0, 1.0), (80.0, 1.0)]),
            ],
        },
        Panel {
            title: "chi2 per residual by separation (all-data fits)".into(),
            x_desc: "separation (in)".into(),
            y_desc: "chi2 per residual".into(),
            log_x: false,
            log_y: true,
            series: vec![
                Series::new(
                    "before",
                    a.diagnostics_before
                        .by_separation
                        .iter()
                        .zip(seps)
                        .map(|(b, s)| (*s, b.chi2_per_row))
                        .collect(),
                ),
                Series::new(
                    "after",
                    a.diagnostics_after
                        .by_separation
                        .iter()
                        .zip(seps)
                        .map(|(b, s)| (*s, b.chi2_per_row))
                        .collect(),
                ),
                Series::dashed("noise floor", seps.iter().map(|s| (*s, 1.0)).collect()),
            ],
        },
    ];
    s.push_str(
        "<h2>Before and after</h2><p>The first panel takes Figure 57's statistic (the spread \
         over the beacons of a separation) on each model's own residual: the direction the \
         model infers from the measured output against the one it predicts, since real data \
         has no truth. It is not the thesis's Figure 57, the pinhole calibration's error \
         against the true directions, which <code>cta evaluate</code> plots (the demo's \
         <code>figure57.svg</code>). Both columns use the same points. The second panel \
         is each separation as predicted by a model fitted without its fold (the separations \
         held out together): a fold whose training data let the pose absorb more of an \
         effect reads lower at its separations than at their neighbours, so read its trend \
         against the noise alone, not single separations.</p>",
    );
    s.push_str(&render_svg("", &panels, 2).map_err(|e| DrawError(e.to_string()))?);
    if let Some(d) = &a.detail {
        s.push_str(
            "<h2>Residual maps</h2><p>Each arrow is a point's mean residual (measured &minus; \
             model) in the sensor's (X, Y) output counts, drawn from the beacon's position on \
             the plate (x, y in inches, dot); red with the starting model (before), blue with \
             the final one (after). Each map has its own arrow scale, so that what the final \
             model leaves is as visible as what the starting one did: the arrow under each map \
             is its key, in counts; compare the keys to compare the sizes. The colour only \
             tells the models apart.</p>",
        );
        s.push_str(&quivers(a, d)?);
    }
    s.push_str("<h2>Final parameters (1-sigma)</h2>");
    param_table(&mut s, &a.params_after);
    s.push_str("<h3>Starting model</h3>");
    param_table(&mut s, &a.params_before);
    s.push_str("<h2>Residual diagnostics (chi2 per residual; 1 = noise)</h2><table><tr><th>bin</th><th>before</th><th>after</th></tr>");
    let (b, af) = (&a.diagnostics_before, &a.diagnostics_after);
    for (x, y) in b
        .by_axis
        .iter()
        .zip(&af.by_axis)
        .chain(b.radial_tangential.iter().zip(&af.radial_tangential))
        .chain(b.by_angle.iter().zip(&af.by_angle))
    {
        let _ = write!(
            s,
            "<tr><td>{}</td><td>{:.2} (mean z {:+.2})</td><td>{:.2} (mean z {:+.2})</td></tr>",
            x.label, x.chi2_per_row, x.mean_z, y.chi2_per_row, y.mean_z
        );
    }
    s.push_str("</table><h3>Worst beacons after</h3><ul>");
    for w in &af.worst_beacons {
        let _ = write!(s, "<li>{}: {:.2}</li>", w.label, w.chi2_per_row);
    }
    s.push_str(
        "</ul><p>Method: <code>cta analyze --help</code> and the analysis guide shipped with CTA \
         (ANALYZE.md). Equation numbers are Stancliffe (2010)'s.</p>",
    );
    if let Some(p) = provenance {
        provenance_html(&mut s, p);
    }
    s.push_str("</body></html>");
    Ok(s)
}

/// The page's provenance: what made it, when, from which command and which files.
fn provenance_html(s: &mut String, p: &Provenance) {
    let _ = write!(
        s,
        "<h2>Provenance</h2><table><tr><th>made by</th><td>{}</td></tr><tr><th>date (UTC)</th>\
         <td>{}</td></tr><tr><th>command</th><td><code>{}</code></td></tr>",
        html_escape(&p.software),
        html_escape(&p.date_utc),
        html_escape(&p.command.join(" "))
    );
    for f in &p.inputs {
        let _ = write!(
            s,
            "<tr><th>input</th><td>{} ({} bytes), SHA-256 <code>{}</code></td></tr>",
            html_escape(&f.path),
            f.bytes.map_or("?".into(), |b| b.to_string()),
            f.sha256.as_deref().unwrap_or("unreadable")
        );
    }
    s.push_str("</table>");
}

fn param_table(s: &mut String, params: &[super::Param]) {
    s.push_str("<table><tr><th>parameter</th><th>value</th><th>1-sigma</th></tr>");
    for p in params {
        let (v, sg) = pm_parts(p.value, p.sigma);
        let _ = write!(s, "<tr><td>{}</td><td>{v}</td><td>{sg}</td></tr>", p.name);
    }
    s.push_str("</table>");
}

/// Height of the strip under each residual map that holds its arrow key, pixels.
const KEY_STRIP: u32 = 28;

/// The largest 1, 2 or 5 times a power of 10 not above `v` (`v` itself when it is not a
/// positive number).
fn round_down_125(v: f64) -> f64 {
    if !(v.is_finite() && v > 0.0) {
        return v;
    }
    let p10 = 10f64.powf(v.log10().floor());
    [5.0, 2.0, 1.0]
        .iter()
        .map(|m| m * p10)
        .find(|k| *k <= v * (1.0 + 1e-12))
        .unwrap_or(p10)
}

/// Quiver maps: up to 8 separations spread over the range, before and after side by side.
fn quivers(a: &Analysis, d: &super::Detail) -> Result<String, DrawError> {
    let nsep = a.separations.len();
    let pick: Vec<usize> = if nsep <= 8 {
        (0..nsep).collect()
    } else {
        let mut v: Vec<usize> = (0..8).map(|i| i * (nsep - 1) / 7).collect();
        v.dedup();
        v
    };
    let rows = pick.len();
    let (w, h) = (900u32, 420 * rows as u32);
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (w, h)).into_drawing_area();
        let e = |e: DrawingAreaErrorKind<std::io::Error>| DrawError(e.to_string());
        root.fill(&WHITE).map_err(e)?;
        let areas = root.split_evenly((rows, 2));
        let xs: Vec<f64> = d.data.points.iter().map(|p| p.r.x).collect();
        let ys: Vec<f64> = d.data.points.iter().map(|p| p.r.y).collect();
        let ext = xs.iter().chain(&ys).fold(1.0f64, |m, v| m.max(v.abs())) + 1.0;
        for (row, &k) in pick.iter().enumerate() {
            let idx: Vec<usize> = (0..d.data.points.len())
                .filter(|&i| d.data.points[i].sep == k)
                .collect();
            for (col, (res, name)) in [
                (&d.before, "before (starting model)"),
                (&d.after, "after (final model)"),
            ]
            .iter()
            .enumerate()
            {
                // Each map its own scale: its longest arrow spans 1.2 in on the plate (1.2
                // pitches of the 1 in grid), so what the final model leaves shows as clearly
                // as what the starting one did; the keys tell the sizes apart.
                let max_res = idx
                    .iter()
                    .map(|&i| res[i].0[0].hypot(res[i].0[1]))
                    .filter(|v| v.is_finite())
                    .fold(0.0f64, f64::max)
                    .max(1e-9);
                let scale = 1.2 / max_res;
                // The key: a round number of counts (1, 2 or 5 times a power of 10) whose
                // arrow is 0.4 to 1 in long.
                let key = round_down_125(1.0 / scale);
                let (map_area, key_area) =
                    areas[row * 2 + col].split_vertically(h / rows as u32 - KEY_STRIP);
                let mut c = ChartBuilder::on(&map_area)
                    .caption(
                        format!("{} in, {name}", a.separations[k]),
                        ("sans-serif", 17),
                    )
                    .margin(8)
                    .x_label_area_size(42)
                    .y_label_area_size(56)
                    .build_cartesian_2d(-ext..ext, -ext..ext)
                    .map_err(e)?;
                c.configure_mesh()
                    .disable_mesh()
                    .x_desc("beacon x on the plate (in)")
                    .y_desc("beacon y on the plate (in)")
                    .x_label_formatter(&|v: &f64| crate::plot::tick(*v))
                    .y_label_formatter(&|v: &f64| crate::plot::tick(*v))
                    .label_style(("sans-serif", 14))
                    .axis_desc_style(("sans-serif", 15))
                    .draw()
                    .map_err(e)?;
                let color = if col == 0 {
                    RGBColor(214, 39, 40)
                } else {
                    RGBColor(31, 119, 180)
                };
                for &i in &idx {
                    let p = &d.data.points[i];
                    let r = res[i].0;
                    if !(r[0].is_finite() && r[1].is_finite()) {
                        continue;
                    }
                    let (x0, y0) = (p.r.x, p.r.y);
                    let (dx, dy) = (r[0] * scale, r[1] * scale);
                    let (x1, y1) = (x0 + dx, y0 + dy);
                    c.draw_series(std::iter::once(PathElement::new(
                        vec![(x0, y0), (x1, y1)],
                        color,
                    )))
                    .map_err(e)?;
                    let len = dx.hypot(dy);
                    if len > 0.05 {
                        let (ux, uy) = (dx / len, dy / len);
                        let hs = 0.15f64.min(0.4 * len);
                        let head =
                            |s: f64| (x1 - hs * (ux - s * uy * 0.5), y1 - hs * (uy + s * ux * 0.5));
                        c.draw_series(std::iter::once(PathElement::new(
                            vec![head(1.0), (x1, y1), head(-1.0)],
                            color,
                        )))
                        .map_err(e)?;
                    }
                    c.draw_series(std::iter::once(Circle::new((x0, y0), 1, BLACK.filled())))
                        .map_err(e)?;
                }
                // The key under the map, in the map's pixels per inch.
                let ppi =
                    f64::from(c.backend_coord(&(1.0, 0.0)).0 - c.backend_coord(&(0.0, 0.0)).0);
                let len = (key * scale * ppi).round() as i32;
                let (kx, ky) = (56, KEY_STRIP as i32 / 2);
                key_area
                    .draw(&PathElement::new(vec![(kx, ky), (kx + len, ky)], color))
                    .map_err(e)?;
                let hs = (0.15 * ppi).min(0.4 * f64::from(len)).round() as i32;
                key_area
                    .draw(&PathElement::new(
                        vec![
                            (kx + len - hs, ky - hs / 2),
                            (kx + len, ky),
                            (kx + len - hs, ky + hs / 2),
                        ],
                        color,
                    ))
                    .map_err(e)?;
                key_area
                    .draw(&Text::new(
                        format!(
                            "= {} counts of mean residual (X, Y)",
                            crate::plot::tick(key)
                        ),
                        (kx + len + 8, ky),
                        ("sans-serif", 15)
                            .into_font()
                            .color(&BLACK)
                            .pos(Pos::new(HPos::Left, VPos::Center)),
                    ))
                    .map_err(e)?;
            }
        }
        root.present().map_err(e)?;
    }
    Ok(buf)
}

#[cfg(test)]
mod tests {
    use super::round_down_125;

    #[test]
    fn the_arrow_key_is_a_round_number_of_counts() {
        for (v, k) in [
            (76.2, 50.0),
            (36.2, 20.0),
            (19.9, 10.0),
            (20.0, 20.0),
            (0.37, 0.2),
            (1.0, 1.0),
        ] {
            assert!(
                (round_down_125(v) - k).abs() < 1e-12,
                "{v}: {}",
                round_down_125(v)
            );
        }
    }
}
