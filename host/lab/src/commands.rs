//! The thesis subcommands: `nearfield`, `uncertainty`, `simulate`, `fit`, `evaluate`.

use crate::data::weights::{self, Weights};
use crate::data::{fmt_list, parse_separations, Dataset};
use crate::fit::{self, FitReport};
use crate::plot::{write_svg, Panel, Series};
use crate::sim::effects::Effect;
use crate::sim::{describe_pattern, parse_grid, SimConfig, Truth};
use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, ValueEnum};
use cta_core::nearfield2d::{Crossing, Effect as NfEffect, Model2d, CROSSING_MAX_D};
use cta_core::pattern::{Pattern, QUARTIC_VALID_DEG};
use cta_core::real::rad;
use cta_core::uncertainty::{self, Item};
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::path::{Path, PathBuf};

/// Beacon radiation profile choices.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Profile {
    /// Generalized Lambertian cos^m from the half-intensity angle (default 60 deg: m = 1).
    Lambertian,
    /// The thesis's printed eq 17 quartic (reproduction only; not a radiation pattern past ~31 deg).
    Quartic,
    /// An isotropic beacon (no pattern effect).
    Uniform,
}

impl Profile {
    /// The pattern, given a half-intensity angle for the Lambertian.
    pub fn pattern(self, half_deg: f64) -> Pattern<f64> {
        match self {
            Profile::Lambertian => Pattern::lambertian_half_angle(half_deg),
            Profile::Quartic => Pattern::Quartic,
            Profile::Uniform => Pattern::Uniform,
        }
    }
}

fn parse_list(s: &str) -> Result<Vec<f64>> {
    s.split(',')
        .map(|p| {
            p.trim()
                .parse::<f64>()
                .map_err(|_| anyhow!("`{p}` is not a number"))
        })
        .collect()
}

// ---------------------------------------------------------------------------------------
// nearfield

/// Ch II: where near-field errors fall below the sensor noise (2-D model, eqs 1-22).
#[derive(Debug, Args)]
pub struct NearfieldArgs {
    /// Pyramid face angle a, degrees (eq 2).
    #[arg(long, default_value_t = 30.0)]
    pub alpha: f64,
    /// Off-boresight angles theta of the beacon, degrees, comma-separated.
    #[arg(long, default_value = "6,18,30,45")]
    pub theta: String,
    /// Sensor noise the errors are compared with, degrees (the thesis assumes 0.1).
    #[arg(long = "noise-deg", default_value_t = 0.1)]
    pub noise_deg: f64,
    /// Beacon radiation profile for the non-uniform-beacon error.
    #[arg(long, value_enum, default_value_t = Profile::Lambertian)]
    pub profile: Profile,
    /// Half-intensity angle of the Lambertian profile, degrees (VSML3710: 60).
    #[arg(long = "half-angle", default_value_t = 60.0)]
    pub half_angle: f64,
    /// Sensor diameter D in inches, to also give distances in inches (NorthStar: 2 s = 0.35).
    #[arg(long = "diameter-in", default_value_t = 0.35)]
    pub diameter_in: f64,
    /// Draw the error-versus-distance curves (Figures 14-24) to this SVG file.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

fn check_diameter(d: f64) -> Result<()> {
    if !(d > 0.0 && d.is_finite()) {
        bail!("--diameter-in {d}: the sensor diameter must be > 0 in (NorthStar: 0.35)");
    }
    Ok(())
}

/// Run `cta nearfield`.
pub fn nearfield(a: &NearfieldArgs) -> Result<()> {
    if !(a.alpha > 0.0 && a.alpha < 90.0) {
        bail!("--alpha {}: the face angle must be in (0, 90) deg", a.alpha);
    }
    if !(a.noise_deg > 0.0) {
        bail!("--noise-deg must be > 0");
    }
    if !(a.half_angle > 0.0 && a.half_angle < 90.0) {
        bail!("--half-angle must be in (0, 90) deg");
    }
    check_diameter(a.diameter_in)?;
    if let Some(p) = &a.plot {
        crate::plot::check_plot_path(p)?;
    }
    let thetas = parse_list(&a.theta).context("--theta")?;
    let max_theta = 90.0 - a.alpha;
    if let Some(t) = thetas.iter().find(|t| !(**t > 0.0 && **t < max_theta)) {
        bail!("--theta {t}: must be in (0, {max_theta}) deg (the field of view ends where tan theta = cot a)");
    }
    let model = Model2d {
        alpha: rad(a.alpha),
        half_sep: 0.5,
        pattern: a.profile.pattern(a.half_angle),
    };
    let mut warnings = Vec::new();
    let noise = rad(a.noise_deg);
    // The nearest distance (D) evaluated for what is shown at each theta: the plot's, and
    // how far in each crossing search went (the outermost crossing: a step inside it).
    let mut nearest: Vec<f64> = vec![
        if a.plot.is_some() {
            PLOT_NEAREST_D
        } else {
            f64::INFINITY
        };
        thetas.len()
    ];
    // `crossing_D` holds the distance or null; `crossing_kind` says what a null means.
    let mut crossing = serde_json::Map::new();
    let mut crossing_kind = serde_json::Map::new();
    for e in NfEffect::ALL {
        let c: Vec<Crossing<f64>> = thetas
            .iter()
            .map(|t| model.crossing(e, rad(*t), noise, NEAREST_D))
            .collect();
        for (n, c) in nearest.iter_mut().zip(&c) {
            *n = n.min(match c {
                Crossing::At(r) => r / 1.1,
                Crossing::BelowNoise => NEAREST_D,
                Crossing::AboveNoise => CROSSING_MAX_D,
            });
        }
        let at = |c: &Crossing<f64>| match c {
            Crossing::At(r) => Some(*r),
            _ => None,
        };
        let kind = |c: &Crossing<f64>| match c {
            Crossing::At(_) => "crossing",
            Crossing::BelowNoise => "below_noise",
            Crossing::AboveNoise => "above_noise_to_1e7_D",
        };
        crossing.insert(e.name().into(), json!(c.iter().map(at).collect::<Vec<_>>()));
        crossing_kind.insert(
            e.name().into(),
            json!(c.iter().map(kind).collect::<Vec<_>>()),
        );
    }
    if a.profile == Profile::Quartic {
        let past = quartic_out_of_range(&model, &thetas, &nearest, a.diameter_in);
        if !past.is_empty() {
            warnings.push(format!(
                "the printed eq 17 quartic is evaluated past {QUARTIC_VALID_DEG} deg off the beacon's axis, where it is no \
                 longer a radiation pattern (0 at 37.8 deg, -4.93 at 60 deg; README, thesis inconsistency 1): pattern and \
                 combined errors there are not physical: {}",
                past.join("; ")
            ));
        }
    }
    let mut coeff = serde_json::Map::new();
    for e in [NfEffect::Proximity, NfEffect::Intensity, NfEffect::Pattern] {
        let v: Vec<f64> = thetas
            .iter()
            .map(|t| model.far_field_coeff_deg(e, rad(*t)))
            .collect();
        coeff.insert(e.name().into(), json!(v));
    }
    if a.json {
        let out = json!({
            "alpha_deg": a.alpha,
            "noise_deg": a.noise_deg,
            "profile": describe_pattern(&model.pattern),
            "theta_deg": thetas,
            "crossing_D": crossing,
            "crossing_kind": crossing_kind,
            "coeff_deg_D": coeff,
            "diameter_in": a.diameter_in,
            "sign": "all errors make the beacon appear farther off boresight (convex pairing)",
            "warnings": warnings,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
        "Near-field errors in angle (thesis Ch II, 2-D, a = {} deg, beacon: {}), noise {} deg, D = {} in",
        a.alpha,
        describe_pattern(&model.pattern),
        a.noise_deg,
        a.diameter_in
    );
        println!(
            "Distance (sensor diameters D [inches]) beyond which each effect is below the noise:"
        );
        println!(
            "{:>9} {:>18} {:>18} {:>18} {:>18}",
            "theta", "proximity", "intensity", "pattern", "combined"
        );
        for (i, t) in thetas.iter().enumerate() {
            let cell = |e: NfEffect| match (
                crossing[e.name()][i].as_f64(),
                crossing_kind[e.name()][i].as_str(),
            ) {
                (Some(v), _) => format!("{v:.1} [{:.1}]", v * a.diameter_in),
                (None, Some("below_noise")) => "below noise".into(),
                _ => format!(
                    "> {CROSSING_MAX_D:.0e} [> {:.0e}]",
                    CROSSING_MAX_D * a.diameter_in
                ),
            };
            println!(
                "{:>7} ° {:>18} {:>18} {:>18} {:>18}",
                t,
                cell(NfEffect::Proximity),
                cell(NfEffect::Intensity),
                cell(NfEffect::Pattern),
                cell(NfEffect::Combined)
            );
        }
        println!("Far-field coefficients R x |delta theta| (deg D; the error falls as coeff / R):");
        for (i, t) in thetas.iter().enumerate() {
            println!(
                "{:>7} ° proximity {:>8.3}  intensity {:>8.3}  pattern {:>8.3}",
                t,
                coeff["proximity"][i].as_f64().unwrap_or(f64::NAN),
                coeff["intensity"][i].as_f64().unwrap_or(f64::NAN),
                coeff["pattern"][i].as_f64().unwrap_or(f64::NAN)
            );
        }
        println!("All three errors make the beacon appear farther off boresight (convex pairing, README, thesis inconsistency 2).");
        println!("Intensity (eq 15) weighs the far-field voltages of eq 3, the reading that reproduces Ch II (inconsistency 3).");
        for w in warnings {
            println!("warning: {w}");
        }
    }
    if let Some(p) = &a.plot {
        let panels: Vec<Panel> = NfEffect::ALL
            .iter()
            .map(|&e| {
                let mut series: Vec<Series> = thetas
                    .iter()
                    .map(|&t| {
                        let pts = (0..=120)
                            .map(|k| {
                                let r = PLOT_NEAREST_D * 10f64.powf(k as f64 / 40.0);
                                (r, model.error(e, rad(t), r).abs().to_degrees())
                            })
                            .collect();
                        Series::new(format!("theta = {t} deg"), pts)
                    })
                    .collect();
                series.push(Series::dashed(
                    format!("noise {} deg", a.noise_deg),
                    vec![(3.0, a.noise_deg), (3000.0, a.noise_deg)],
                ));
                Panel {
                    title: format!("|error in angle|: {}", e.name()),
                    x_desc: "beacon distance (sensor diameters D)".into(),
                    y_desc: "|delta theta| (deg)".into(),
                    log_x: true,
                    log_y: true,
                    series,
                }
            })
            .collect();
        write_svg(
            p,
            &format!(
                "Near-field errors, a = {} deg (thesis Figures 14-24)",
                a.alpha
            ),
            &panels,
            2,
        )
        .map_err(|e| anyhow!("{e}; the table above is complete, the plot was not written"))?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// uncertainty

/// Ch IV: the CTA uncertainty budget (eq 26) and the 2-D angle uncertainty it implies (eq 40).
#[derive(Debug, Args)]
pub struct UncertaintyArgs {
    /// Budget file (TOML, `[[item]]` tables with `name` and mils `x`, `y`, `z` or
    /// `x_plus`/`x_minus`...); default: thesis Table 2.
    #[arg(long)]
    pub budget: Option<PathBuf>,
    /// Sensor diameter D in inches, to compare with the Ch II near-field error.
    #[arg(long = "diameter-in", default_value_t = 0.35)]
    pub diameter_in: f64,
    /// Draw Figure 40 (CTA angle uncertainty vs near-field error) to this SVG file.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BudgetFile {
    item: Vec<BudgetItem>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BudgetItem {
    name: String,
    x: Option<f64>,
    y: Option<f64>,
    z: Option<f64>,
    x_plus: Option<f64>,
    x_minus: Option<f64>,
    y_plus: Option<f64>,
    y_minus: Option<f64>,
    z_plus: Option<f64>,
    z_minus: Option<f64>,
}

fn load_budget(path: &PathBuf) -> Result<Vec<(String, [f64; 6])>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
    let b: BudgetFile = toml::from_str(&text).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let mut out = Vec::new();
    for it in b.item {
        if [
            it.x, it.y, it.z, it.x_plus, it.x_minus, it.y_plus, it.y_minus, it.z_plus, it.z_minus,
        ]
        .iter()
        .all(Option::is_none)
        {
            bail!(
                "{}: item `{}` has no uncertainty: give mils as x, y, z (symmetric) or x_plus, x_minus, ...",
                path.display(),
                it.name
            );
        }
        for (axis, sym, plus, minus) in [
            ("x", it.x, it.x_plus, it.x_minus),
            ("y", it.y, it.y_plus, it.y_minus),
            ("z", it.z, it.z_plus, it.z_minus),
        ] {
            if sym.is_some() && (plus.is_some() || minus.is_some()) {
                bail!(
                    "{}: item `{}` gives both `{axis}` and `{axis}_plus`/`{axis}_minus`: give one (symmetric) or the sides",
                    path.display(),
                    it.name
                );
            }
        }
        let pick = |sym: Option<f64>, side: Option<f64>| side.or(sym).unwrap_or(0.0);
        let v = [
            pick(it.x, it.x_plus),
            pick(it.x, it.x_minus),
            pick(it.y, it.y_plus),
            pick(it.y, it.y_minus),
            pick(it.z, it.z_plus),
            pick(it.z, it.z_minus),
        ];
        if let Some(bad) = v
            .iter()
            .find(|m| !(m.is_finite() && **m >= 0.0 && **m <= MAX_BUDGET_MILS))
        {
            bail!(
                "{}: item `{}`: uncertainty {} mils must be in 0..={MAX_BUDGET_MILS} (1,000 in)",
                path.display(),
                it.name,
                if bad.abs() < 1e7 {
                    format!("{bad}")
                } else {
                    format!("{bad:e}")
                }
            );
        }
        out.push((it.name, v));
    }
    if out.is_empty() {
        bail!("{}: no [[item]] in the budget", path.display());
    }
    if out.iter().all(|(_, v)| v.iter().all(|m| *m == 0.0)) {
        bail!(
            "{}: every uncertainty in the budget is 0: there is no apparatus uncertainty to compare",
            path.display()
        );
    }
    if let Some(w) = budget_unit_warning(&out) {
        eprintln!("warning: {}: {w}", path.display());
    }
    Ok(out)
}

/// A caution when a budget's values look like inches rather than mils: every value below
/// 0.1 mil (Table 2's items are 0.5-21 mils; 0.005 in is 5 mils), or one above 1 in.
fn budget_unit_warning(items: &[(String, [f64; 6])]) -> Option<String> {
    let values = || items.iter().flat_map(|(_, v)| v.iter().copied());
    let largest = values().fold(0.0f64, f64::max);
    if largest < 0.1 {
        return Some(format!(
            "the largest uncertainty is {largest} mils: the budget is in mils (thousandths of an \
             inch; Table 2's items are 0.5-21 mils), are these inches?"
        ));
    }
    items
        .iter()
        .find(|(_, v)| v.iter().any(|m| *m > 1000.0))
        .map(|(name, v)| {
            format!(
            "item `{name}`: {} mils is more than 1 in: the budget is in mils (Table 2's items are \
             0.5-21 mils)",
            v.iter().copied().fold(0.0f64, f64::max)
        )
        })
}

/// Largest uncertainty of a budget item, mils: 1,000 in, far beyond any apparatus (the
/// root-sum-square of larger values can overflow to infinity).
const MAX_BUDGET_MILS: f64 = 1e6;

/// The budget file's items (`--budget`), or thesis Table 2's.
fn budget_or_table2(path: Option<&PathBuf>) -> Result<Vec<(String, [f64; 6])>> {
    Ok(match path {
        Some(p) => load_budget(p)?,
        None => uncertainty::TABLE2
            .iter()
            .map(|i| (i.name.to_string(), i.mils))
            .collect(),
    })
}

/// [`budget_or_table2`]'s items as the uncertainty functions take them.
fn budget_items(owned: &[(String, [f64; 6])]) -> Vec<Item<'_>> {
    owned
        .iter()
        .map(|(n, m)| Item { name: n, mils: *m })
        .collect()
}

/// Where the printed quartic is evaluated past its valid angle in what the command shows: for
/// each `theta` (deg) whose pattern angle (the ray to the farther cell, eq 20) exceeds
/// [`QUARTIC_VALID_DEG`] at the nearest distance evaluated for it (`nearest`, D: the plot's,
/// or the crossing searches'), the distance inside which it does, in words.
fn quartic_out_of_range(
    model: &Model2d<f64>,
    thetas: &[f64],
    nearest: &[f64],
    diameter_in: f64,
) -> Vec<String> {
    let past = |th: f64, r: f64| model.pattern.out_of_range(model.pattern_angle(th, r));
    thetas
        .iter()
        .zip(nearest)
        .filter(|&(&t, &n)| past(rad(t), n))
        .map(|(&t, _)| {
            let th = rad(t);
            if past(th, CROSSING_MAX_D) {
                return format!("theta = {t} deg at every distance");
            }
            // The angle falls towards theta with distance: bisect on a log scale.
            let (mut lo, mut hi) = (NEAREST_D, CROSSING_MAX_D);
            for _ in 0..100 {
                let mid = (lo * hi).sqrt();
                if past(th, mid) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            format!(
                "theta = {t} deg closer than {hi:.1} D [{:.2} in]",
                hi * diameter_in
            )
        })
        .collect()
}

/// The nearest distance (D) `cta nearfield` evaluates: the crossing search's inner end.
const NEAREST_D: f64 = 0.6;
/// The nearest distance (D) its plot draws.
const PLOT_NEAREST_D: f64 = 3.0;

/// Run `cta uncertainty`.
pub fn uncertainty_cmd(a: &UncertaintyArgs) -> Result<()> {
    check_diameter(a.diameter_in)?;
    if let Some(p) = &a.plot {
        crate::plot::check_plot_path(p)?;
    }
    let owned = budget_or_table2(a.budget.as_ref())?;
    let items = budget_items(&owned);
    let r = uncertainty::rss(&items);
    let [ux, uy, uz] = uncertainty::rss_inches(&items);
    // Eq 40 and the near-field comparison at the Ch IV angles.
    let nf = Model2d::thesis(Pattern::vsml3710());
    let nfq = Model2d::thesis(Pattern::Quartic);
    let rows: Vec<_> = [6.0f64, 18.0]
        .iter()
        .map(|&t| {
            let th = rad(t);
            let u = uncertainty::angle_2d(th.sin(), th.cos(), ux, uz).to_degrees();
            let e = nf.far_field_coeff_deg(NfEffect::Combined, th) * a.diameter_in;
            let eq = nfq.far_field_coeff_deg(NfEffect::Combined, th) * a.diameter_in;
            (t, u, e / u, eq / u)
        })
        .collect();
    if a.json {
        let out = json!({
            "items": owned.iter().map(|(n, m)| json!({"name": n, "mils": m})).collect::<Vec<_>>(),
            "rss_mils": {"x": r[0].max(r[1]), "y": r[2].max(r[3]), "z": r[4].max(r[5]),
                          "x_plus": r[0], "x_minus": r[1], "y_plus": r[2], "y_minus": r[3], "z_plus": r[4], "z_minus": r[5]},
            "eq40_u_theta_times_R_deg_in": rows.iter().map(|r| json!({"theta_deg": r.0, "value": r.1})).collect::<Vec<_>>(),
            "nearfield_over_cta": rows.iter().map(|r| json!({"theta_deg": r.0, "lambertian": r.2, "quartic": r.3})).collect::<Vec<_>>(),
            "uy_in": uy,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!("CTA uncertainty budget (thesis Ch IV, eq 26), mils:");
        println!(
            "{:<36} {:>6} {:>6} {:>6} {:>6} {:>6} {:>6}",
            "item", "X+", "X-", "Y+", "Y-", "Z+", "Z-"
        );
        for (n, m) in &owned {
            println!(
                "{:<36} {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>6.2}",
                n, m[0], m[1], m[2], m[3], m[4], m[5]
            );
        }
        println!(
            "{:<36} {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>6.2}",
            "root-sum-square", r[0], r[1], r[2], r[3], r[4], r[5]
        );
        if a.budget.is_none() {
            println!(
                "(Table 2 rounds the text's 21.25 mil plate offset to 21.3: with it X is 31.54, Y 24.41, printed 31.5, 24.4; 21.25 is used here)"
            );
        }
        println!("Angle uncertainty in 2-D (eq 40), u_theta x R, and the near-field error over it (D = {} in):", a.diameter_in);
        for (t, u, l, q) in &rows {
            println!("  theta {t:>4} deg: {u:.3} deg in; near-field / CTA = {l:.1} (Lambertian), {q:.1} (printed quartic)");
        }
        println!("Note: the 3-D angle uncertainty (eq 36), which `cta evaluate` gives per separation, does not use the");
        println!("thesis's sensitivities (eqs 34/35: singular at x = y = z) but the corrected |d theta/d x| =");
        println!("sqrt(y^2+z^2)/|b|^2 (README, thesis inconsistency 4), about 1.4x larger.");
    }
    if let Some(p) = &a.plot {
        let mut panels = Vec::new();
        for &(t, _, _, _) in &rows {
            let th = rad(t);
            let range: Vec<f64> = (0..=60).map(|k| 10f64.powf(k as f64 / 30.0)).collect(); // 1..100 in
            let cta: Vec<(f64, f64)> = range
                .iter()
                .map(|&r| {
                    (
                        r,
                        uncertainty::angle_2d(r * th.sin(), r * th.cos(), ux, uz).to_degrees(),
                    )
                })
                .collect();
            let near: Vec<(f64, f64)> = range
                .iter()
                .map(|&r| {
                    (
                        r,
                        nf.error(NfEffect::Combined, th, r / a.diameter_in)
                            .abs()
                            .to_degrees(),
                    )
                })
                .collect();
            panels.push(Panel {
                title: format!("theta = {t} deg"),
                x_desc: "range along the beacon ray (in)".into(),
                y_desc: "angle (deg)".into(),
                log_x: true,
                log_y: true,
                series: vec![
                    Series::new("combined near-field error (Lambertian)", near),
                    Series::dashed("CTA uncertainty (eq 40)", cta),
                ],
            });
        }
        write_svg(
            p,
            "CTA angle uncertainty vs near-field error (thesis Figure 40)",
            &panels,
            2,
        )
        .map_err(|e| anyhow!("{e}; the table above is complete, the plot was not written"))?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// simulate

/// Ch V: emulated CTA data from the eq 60-63 NorthStar emulator.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Output measurement file (CSV, see MEASUREMENTS.md); the truth goes to FILE.truth.json.
    /// An earlier `cta simulate` output is replaced; any other existing file only with --force.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace --out even if it is not an earlier simulation (e.g. a sweep's data.csv).
    #[arg(long)]
    pub force: bool,
    /// Plate separations in inches: a list `20,25`, a range `2..30` (1 in steps) or `2..30:2`.
    #[arg(long, default_value = "2..30")]
    pub separations: String,
    /// Beacon grid, COLSxROWS at 1 in pitch, centred on the board origin.
    #[arg(long, default_value = "10x10")]
    pub grid: String,
    /// Beacon radiation profile.
    #[arg(long, value_enum, default_value_t = Profile::Lambertian)]
    pub profile: Profile,
    /// Half-intensity angle of the Lambertian profile, degrees.
    #[arg(long = "half-angle", default_value_t = 60.0)]
    pub half_angle: f64,
    /// Far-field physics (proximity and intensity off, uniform beacon): eq 65 exactly.
    #[arg(long = "far-field")]
    pub far_field: bool,
    /// Inject an effect of the vocabulary, NAME=VALUE (repeatable): proximity=S, intensity,
    /// beacon_pattern=H, beacon_tilt=T[,AZ], cell_gain=GX[,GY], cell_bias=BX[,BY],
    /// face_angle=DX[,DY], saturation=S, plate_offset=SIGMA, separation_error=SIGMA,
    /// plate_tilt=SIGMA (deg), crosstalk=K (simulation only).
    // The brackets are --help text (optional parts), not doc links.
    #[allow(rustdoc::broken_intra_doc_links)]
    #[arg(long = "effect", value_name = "NAME=VALUE")]
    pub effects: Vec<String>,
    /// Gaussian noise, counts (1-sigma); 0 = noise-free as in the thesis. 0.1 % of beta is 32.8.
    #[arg(long, default_value_t = 0.0)]
    pub noise: f64,
    /// Samples per point (repeated reports of one beacon).
    #[arg(long, default_value_t = 1)]
    pub samples: usize,
    /// Round to whole counts like the sensor (always done when --noise > 0).
    #[arg(long)]
    pub round: bool,
    /// Spot magnitude noise, percent of the magnitude (1-sigma, 0-25); 0 = every report of a
    /// point has the same magnitude. The NorthStar's real figure is unmeasured: this is a
    /// what-if, e.g. to rehearse `cta noise` -> `cta sensor floor --magnitude-noise`. It never
    /// changes the x, y noise of a seed.
    #[arg(
        long = "magnitude-noise",
        value_name = "PERCENT",
        default_value_t = 0.0
    )]
    pub magnitude_noise: f64,
    /// Scatter of the LEDs' brightness, percent (0-50): each LED's is drawn once, log-normal
    /// with this 1-sigma of its logarithm, and multiplies its magnitudes (not x, y); the
    /// truth file records the factors. 0 = all alike. What `cta calibrate` measures back.
    #[arg(long = "led-brightness", value_name = "PERCENT", default_value_t = 0.0)]
    pub led_brightness: f64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// True head offset d (in), `d1,d2,d3`.
    #[arg(long, default_value = "0.6,0.1,0.062")]
    pub d: String,
    /// True head attitude, MRP `p1,p2,p3`.
    #[arg(long, default_value = "0.001,0.002,0.001")]
    pub p: String,
}

/// Build a simulation config from the arguments.
pub fn sim_config(a: &SimulateArgs) -> Result<SimConfig> {
    let seps = crate::data::parse_new_separations(&a.separations)
        .map_err(|e| anyhow!("--separations: {e}"))?;
    let grid = parse_grid(&a.grid).map_err(|e| anyhow!("--grid: {e}"))?;
    let effects: Vec<Effect> = a
        .effects
        .iter()
        .map(|s| Effect::parse(s).map_err(|e| anyhow!("--effect: {e}")))
        .collect::<Result<_>>()?;
    if !(a.noise >= 0.0 && a.noise.is_finite()) {
        bail!("--noise must be >= 0 counts");
    }
    if a.samples == 0 {
        bail!("--samples must be at least 1");
    }
    if !(0.0..=crate::sim::MAX_MAGNITUDE_NOISE).contains(&a.magnitude_noise) {
        bail!(
            "--magnitude-noise {}: between 0 and {} percent",
            a.magnitude_noise,
            crate::sim::MAX_MAGNITUDE_NOISE
        );
    }
    if !(0.0..=crate::sim::MAX_LED_BRIGHTNESS).contains(&a.led_brightness) {
        bail!(
            "--led-brightness {}: between 0 and {} percent",
            a.led_brightness,
            crate::sim::MAX_LED_BRIGHTNESS
        );
    }
    let v3 = |s: &str, what: &str| -> Result<nalgebra::Vector3<f64>> {
        let v = parse_list(s).with_context(|| what.to_string())?;
        if v.len() != 3 {
            bail!("{what}: expected three comma-separated numbers");
        }
        Ok(nalgebra::Vector3::new(v[0], v[1], v[2]))
    };
    let d = v3(&a.d, "--d")?;
    let p = v3(&a.p, "--p")?;
    if seps.iter().any(|&s| s <= d.z) {
        bail!(
            "--separations: every separation must be above the head (d3 = {} in)",
            d.z
        );
    }
    Ok(SimConfig {
        separations: seps,
        grid,
        pitch: 1.0,
        pattern: a.profile.pattern(a.half_angle),
        far_field: a.far_field,
        pose: cta_core::emulator::Pose { d, p },
        effects,
        noise: a.noise,
        samples: a.samples,
        round: a.round,
        magnitude_noise: a.magnitude_noise,
        led_brightness: a.led_brightness,
        seed: a.seed,
    })
}

/// Run `cta simulate`.
pub fn simulate(a: &SimulateArgs) -> Result<()> {
    let cfg = sim_config(a)?;
    // Refuse an --out that may not be replaced before simulating (write_files checks it
    // again, with the same words, when it writes).
    crate::sim::check_out(&a.out, a.force).map_err(|e| anyhow!("{e}"))?;
    let (ds, truth) = cfg.try_run().map_err(|e| anyhow!("{e}"))?;
    let tp = crate::sim::write_files(&a.out, &ds, &truth, a.force)
        .map_err(|e| anyhow!("{e}; the simulation was not saved"))?;
    let plural =
        |n: usize, one: &str, many: &str| format!("{n} {}", if n == 1 { one } else { many });
    eprintln!(
        "wrote {} ({} x {} x {}, {} outside the field of view) to {} (truth: {})",
        plural(ds.samples.len(), "report", "reports"),
        plural(cfg.separations.len(), "separation", "separations"),
        plural(cfg.grid.0 * cfg.grid.1, "beacon", "beacons"),
        plural(cfg.samples, "sample", "samples"),
        plural(truth.skipped_points, "point", "points"),
        a.out.display(),
        tp.display()
    );
    if let Some(w) = rail_note(&cfg, &ds) {
        eprintln!("{w}");
    }
    Ok(())
}

/// The note (or warning) on a simulation's reports at the 16-bit rail, when it has any: how
/// many, at which separations, and the likely cause. Close in, beacons at the grid's edge
/// leave a cell of a pair in the dark (a note: the CTA gives the same at 2-3 in, and evaluate,
/// calibrate, analyze and noise know such reports); a head far off the board (`--d` in
/// millimetres?) or a view that misses the grid rails reports farther out (a warning).
fn rail_note(cfg: &SimConfig, ds: &crate::data::Dataset) -> Option<String> {
    let railed: Vec<f64> = ds
        .samples
        .iter()
        .filter(|s| crate::data::any_sample_pinned([*s]))
        .map(|s| s.separation_in)
        .collect();
    if railed.is_empty() {
        return None;
    }
    let total = ds.samples.len();
    let mut at: Vec<f64> = railed.clone();
    at.sort_by(f64::total_cmp);
    at.dedup();
    let shown: Vec<String> = at.iter().take(8).map(|v| format!("{v}")).collect();
    let where_ = format!(
        "at {} in{}",
        shown.join(", "),
        if at.len() > 8 {
            format!(" and {} more separations", at.len() - 8)
        } else {
            String::new()
        }
    );
    let head = format!(
        "{} of {} reports ({:.1} %) are at the 16-bit rail (x or y at +/-32767: a cell of a pair \
         in the dark, so the report says nothing of where the beacon is), {where_}",
        railed.len(),
        total,
        100.0 * railed.len() as f64 / total as f64
    );
    let d = cfg.pose.d;
    let far = d.iter().any(|v| v.abs() > 12.0);
    let close_in = at.last().is_some_and(|&s| s <= 5.0);
    if far {
        Some(format!(
            "warning: {head}: the head offset --d {},{},{} puts the head {:.1} in from the board \
             origin, beyond the beacons' view (a head on the CTA board sits within 12 in of it): \
             --d is in inches (was it given in millimetres? divide by 25.4)",
            d.x,
            d.y,
            d.z,
            d.norm()
        ))
    } else if close_in && 2 * railed.len() <= total {
        Some(format!(
            "note: {head}: close in, beacons at the grid's edge leave a cell of a pair in the \
             dark, as on the CTA (evaluate counts such reports and says so; calibrate, analyze \
             and noise leave their points out)"
        ))
    } else {
        Some(format!(
            "warning: {head}: beacons outside the head's view (the head's attitude --p, the \
             grid, or the effects [{}]?): those reports say nothing of the head",
            cfg.effects
                .iter()
                .map(|e| e.to_string())
                .collect::<Vec<_>>()
                .join(" ")
        ))
    }
}

// ---------------------------------------------------------------------------------------
// fit

/// Ch V: fit the 7-parameter collinearity model (eq 65) by GLSDC.
#[derive(Debug, Args)]
pub struct FitArgs {
    /// Measurement file (CSV).
    pub file: PathBuf,
    /// Use only these separations (list or range, e.g. `25,30`); default: all in the file.
    #[arg(long)]
    pub separations: Option<String>,
    /// Weighting: `none` (W = I, every report), `pooled` (point means, by the noise pooled per
    /// separation and axis, as calibrate weights) or `repeat` (point means, each by its own
    /// samples' variance: at least 6 per point; its 1-sigma from the sandwich covariance).
    #[arg(long, value_enum, default_value_t = Weights::None)]
    pub weights: Weights,
    /// Save the fit (parameters, covariance) as JSON for `cta evaluate`. An earlier saved
    /// fit is replaced; any other existing file only with --force.
    #[arg(long)]
    pub save: Option<PathBuf>,
    /// Let --save replace a file that is not an earlier saved fit.
    #[arg(long)]
    pub force: bool,
    /// Leave out the samples the glitch check flags (more than 8 robust sigma from their
    /// point's median; the warning names their lines), as `cta analyze --drop-glitches`
    /// does. The file is not changed; the output says how many were left out.
    #[arg(long)]
    pub drop_glitches: bool,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Load and restrict a dataset.
pub fn load(file: &Path, separations: Option<&str>) -> Result<Dataset> {
    let (ds, warnings) = crate::sweep::read_measurements(file).map_err(|e| anyhow!("{e}"))?;
    for w in warnings {
        eprintln!("warning: {w}");
    }
    match separations {
        None => Ok(ds),
        Some(s) => {
            let seps = parse_separations(s).map_err(|e| anyhow!("--separations: {e}"))?;
            ds.select(&seps).map_err(|e| anyhow!(e))
        }
    }
}

/// `--save` may replace an earlier saved fit; never the measurement file, and anything else
/// only with `--force`.
fn check_fit_save(save: &Path, data: &Path, force: bool) -> Result<()> {
    crate::data::check_derived_output(
        "--save",
        save,
        data,
        "fit.json",
        "an earlier saved fit",
        |p| FitReport::load(p).is_ok(),
        force,
    )
}

/// Run `cta fit`. The report (text or JSON) is printed before `--save` is written, so a
/// failing write loses nothing; the error then says the fit was not saved.
pub fn fit_cmd(a: &FitArgs) -> Result<()> {
    if let Some(p) = &a.save {
        check_fit_save(p, &a.file, a.force)?;
    }
    let mut ds = load(&a.file, a.separations.as_deref())?;
    // `cta analyze --drop-glitches`'s rule, on the separations fitted.
    let mut notes = Vec::new();
    if a.drop_glitches {
        if let Some(clean) = ds.without_glitches() {
            notes.push(clean.note());
            ds = clean.data;
        }
    }
    let mut rep =
        fit::fit(&ds, a.weights).map_err(|e| anyhow!(crate::fit::wiring::explain(&ds, e)))?;
    rep.data_notes = notes;
    rep.warnings
        .extend(crate::fit::wiring::h_warning(&ds, rep.params["H"]));
    // A head turned about its boresight (or X and Y read so) fits as well as a square one.
    rep.warnings.extend(crate::fit::wiring::turned_head_note(
        ["p1", "p2", "p3"].map(|n| rep.params[n]),
        Some(rep.params["H"]),
    ));
    rep.warnings.extend(fit::chi2_warning(
        &rep,
        &a.file,
        weights::repeat_chi2_expected(&ds),
    ));
    let json = serde_json::to_string_pretty(&rep)?;
    if a.json {
        println!("{json}");
    } else {
        print_fit(&rep, &a.file);
    }
    if let Some(p) = &a.save {
        crate::data::write_output(p, json.as_bytes())
            .map_err(|e| anyhow!("{e}; the fit above was not saved"))?;
        if !a.json {
            println!("saved to {}", p.display());
        }
    }
    Ok(())
}

/// `v` to `n` significant digits, in fixed point from 1e-3 to 1e6, else in exponent form.
fn sig(v: f64, n: i32) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let mag = v.abs().log10().floor() as i32;
    if (-3..6).contains(&mag) {
        let d = (n - 1 - mag).max(0) as usize;
        format!("{v:.d$}")
    } else {
        format!("{v:.*e}", (n - 1).max(0) as usize)
    }
}

/// The text report of `cta fit`: each estimate to the digits its 1-sigma resolves (as
/// `cta calibrate` and `cta analyze` print them), the truth when the file has a sidecar.
fn print_fit(rep: &FitReport, file: &Path) {
    println!(
        "Collinearity model (eq 65) fitted by GLSDC to {} {} at {} in, {}:",
        rep.observations,
        rep.weights.observations(),
        fmt_list(&rep.separations),
        rep.weights.describe()
    );
    for n in &rep.data_notes {
        println!("  note: {n}");
    }
    let (truth, truth_warning) = Truth::load_for_fit(file);
    if let Some(w) = truth_warning {
        eprintln!("warning: {w}");
    }
    for n in cta_core::collinearity::NAMES {
        let t = truth.as_ref().map(|t| match n {
            "d1" => t.d[0],
            "d2" => t.d[1],
            "d3" => t.d[2],
            "p1" => t.p[0],
            "p2" => t.p[1],
            "p3" => t.p[2],
            _ => t.h,
        });
        let unit = match n {
            "H" => "counts",
            _ if n.starts_with('d') => "in",
            _ => "",
        };
        let (v, sd) = crate::analyze::digits::pm_parts(rep.params[n], rep.sigma[n]);
        let what = t.map_or(String::new(), |t| {
            format!(
                "(truth {})",
                crate::analyze::digits::pm_parts(t, rep.sigma[n]).0
            )
        });
        let line = format!("    {n:>2} = {v:>12} ± {sd:<9} {unit:<6} {what}");
        println!("{}", line.trim_end());
    }
    let spread = match (rep.residual_variance_counts2, rep.chi2_per_dof) {
        (_, Some(c)) => format!("chi2/dof {c:.3}"),
        (Some(v), None) => format!(
            "residual variance {} counts^2 per degree of freedom (the 1-sigma are scaled by it)",
            sig(v, 4)
        ),
        (None, None) => format!(
            "weighted residual variance per degree of freedom {}",
            sig(rep.chi2_dof, 4)
        ),
    };
    println!("  residual RMS {:.2} counts, {spread}", rep.rms_counts);
    println!(
        "  {} iterations (converged: {}), condition number {}",
        rep.iterations,
        fit::describe_stop(&rep.stop),
        sig(rep.condition, 3)
    );
    println!(
        "  note: d is the pinhole model's eye point, not the head's centre: on a NorthStar (cells \
         0.175 in off centre, faces at 30 deg) near-field structure the pinhole model cannot \
         hold puts that point about 1 in above the board at 20-100 in (CTA's reproduction of \
         Table 3: d3 = 1.06 to 1.33 in, where the thesis prints -0.73 to -0.79 with the \
         mirror-image cell pairing: README, inconsistency 2), and the 1-sigma bound the point, not the head. `cta \
         calibrate` fits the head itself."
    );
    for w in &rep.warnings {
        println!("warning: {w}");
    }
}

// ---------------------------------------------------------------------------------------
// evaluate

/// Ch V: the error in angle of a fit per separation (eq 67, Figure 57).
#[derive(Debug, Args)]
pub struct EvaluateArgs {
    /// A fit saved by `cta fit --save`.
    pub fit: PathBuf,
    /// Measurement file to evaluate on.
    pub file: PathBuf,
    /// Only these separations.
    #[arg(long)]
    pub separations: Option<String>,
    /// The head centre measured on the CTA (inches, sensor-board frame N), the point the true
    /// direction to each beacon is taken from, as the thesis's Figure 57 does; each component
    /// within +/-12 in (the calibration's range for d). A simulation's truth sidecar
    /// (`FILE.truth.json`) gives it by itself; without either the error is measured from the
    /// fit's own eye point `d`, which shows only how consistent the model is with itself, not
    /// Figure 57's error (far smaller near the fit's separations: 0.0022 against 0.098 deg at
    /// 30 in on the README's example; comparable or larger close in), and a warning says so.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_xyz, allow_hyphen_values = true)]
    pub head: Option<[f64; 3]>,
    /// The CTA uncertainty budget for the "CTA uncert." column (the file `cta uncertainty
    /// --budget` reads); default: thesis Table 2.
    #[arg(long, value_name = "FILE.toml")]
    pub budget: Option<PathBuf>,
    /// Leave out reports with an output at the 16-bit rail (a cell in shadow, close in). By
    /// default they are counted, as the thesis's Figure 57 counts every report, and a note
    /// says how many; their error in angle is that of a clipped output, not a measurement.
    #[arg(long)]
    pub without_rail: bool,
    /// Leave out the samples the glitch check flags (more than 8 robust sigma from their
    /// point's median; the warning names their lines), as `cta fit --drop-glitches` does, on
    /// the separations evaluated. The file is not changed; the output says how many were
    /// left out.
    #[arg(long)]
    pub drop_glitches: bool,
    /// Draw Figure 57 (angle-error std and CTA uncertainty vs separation) to this SVG file.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// `N` comma-separated finite numbers (`--head X,Y,Z`, `sensor sim --offset X,Y`); `example`
/// is shown in the error.
pub fn parse_floats<const N: usize>(
    s: &str,
    names: &str,
    example: &str,
) -> std::result::Result<[f64; N], String> {
    let bad = || format!("{s:?}: expected {N} comma-separated numbers {names} (e.g. {example})");
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != N {
        return Err(bad());
    }
    let mut v = [0.0f64; N];
    for (x, p) in v.iter_mut().zip(parts) {
        *x = p.trim().parse().map_err(|_| bad())?;
        if !x.is_finite() {
            return Err(bad());
        }
    }
    Ok(v)
}

fn parse_xyz(s: &str) -> std::result::Result<[f64; 3], String> {
    parse_floats(s, "x,y,z", "0.6,0.1,0.06")
}

/// `cta evaluate --json`: the evaluation's fields, with what `--drop-glitches` left out (as
/// `cta calibrate`'s `glitches_left_out` and `cta fit`'s `data_notes`; 0 and empty without it).
#[derive(Serialize)]
struct EvaluationOutput<'a> {
    #[serde(flatten)]
    evaluation: &'a fit::Evaluation,
    glitches_left_out: usize,
    data_notes: &'a [String],
}

/// Run `cta evaluate`. The table (or JSON) is printed before `--plot` is written.
pub fn evaluate_cmd(a: &EvaluateArgs) -> Result<()> {
    // A measurement file where the fit belongs: the arguments swapped, or no fit saved yet.
    if crate::data::file_looks_like_measurements(&a.fit) {
        if FitReport::load(&a.file).is_ok() {
            bail!(
                "the arguments look swapped: {} is a measurement file and {} a saved fit; `cta \
                 evaluate` takes the fit first: cta evaluate {} {}",
                a.fit.display(),
                a.file.display(),
                a.file.display(),
                a.fit.display()
            );
        }
        bail!(
            "{}: this is a measurement file (CSV), not a saved fit: `cta evaluate FIT.json \
             DATA.csv` takes a fit first; save one with `cta fit {} --save fit.json`",
            a.fit.display(),
            a.fit.display()
        );
    }
    let rep = FitReport::load(&a.fit).map_err(|e| anyhow!(e))?;
    let mut ds = load(&a.file, a.separations.as_deref())?;
    // `cta fit --drop-glitches`'s rule, on the separations evaluated.
    let mut data_notes = Vec::new();
    let mut glitches_left_out = 0;
    if a.drop_glitches {
        if let Some(clean) = ds.without_glitches() {
            data_notes.push(clean.note());
            glitches_left_out = clean.samples;
            ds = clean.data;
        }
    }
    let truth = match Truth::load_for(&a.file) {
        Some(Ok(t)) => Some(t),
        Some(Err(e)) => bail!("{e}"),
        None => None,
    };
    let reference = match (&truth, a.head) {
        (Some(_), Some(_)) => bail!(
            "{} has a truth sidecar ({}), which gives the head: leave out --head",
            a.file.display(),
            Truth::path_for(&a.file).display()
        ),
        (Some(t), None) => fit::Reference::Truth(t.pose().d),
        (None, Some(h)) => {
            if h.iter().any(|v| v.abs() > 12.0) {
                bail!(
                    "--head {},{},{}: each component of the head centre must be within +/-12 \
                     in of the board origin (inches, not cm or mm)",
                    h[0],
                    h[1],
                    h[2]
                );
            }
            fit::Reference::Head(nalgebra::Vector3::from(h))
        }
        (None, None) => {
            eprintln!(
                "warning: {}: no truth sidecar and no --head, so the error in angle is measured \
                 from the fit's own eye point (d = {:.3}, {:.3}, {:.3} in): it shows only how \
                 consistent the model is with itself, not the error Figure 57 plots (far \
                 smaller near the fit's separations, comparable or larger close in). Give the \
                 head centre measured on the CTA with --head X,Y,Z (inches, board frame N)",
                a.file.display(),
                rep.x()[0],
                rep.x()[1],
                rep.x()[2]
            );
            fit::Reference::Fit
        }
    };
    let budget = budget_or_table2(a.budget.as_ref())?;
    let mut ev = fit::evaluate(
        &rep.x(),
        &ds,
        reference,
        uncertainty::rss_inches(&budget_items(&budget)),
        a.without_rail,
    );
    if ev.separation_in.is_empty() {
        bail!(
            "{}: every report is at the 16-bit rail, so --without-rail leaves nothing to \
             evaluate; leave out --without-rail to count them",
            a.file.display()
        );
    }
    ev.budget = match &a.budget {
        Some(p) => p.display().to_string(),
        None => "thesis Table 2".into(),
    };
    if let Some(p) = &a.plot {
        crate::plot::check_plot_path(p)?;
    }
    if a.json {
        let out = EvaluationOutput {
            evaluation: &ev,
            glitches_left_out,
            data_notes: &data_notes,
        };
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        print_evaluation(&rep, &ev, &data_notes);
    }
    if let Some(p) = &a.plot {
        let pts = |v: &Vec<f64>| {
            ev.separation_in
                .iter()
                .copied()
                .zip(v.iter().copied())
                .collect::<Vec<_>>()
        };
        write_svg(
            p,
            "Error in angle vs separation (thesis Figure 57)",
            &[Panel {
                title: format!(
                    "fit on {} in; angle against the {}{}",
                    fmt_list(&rep.separations),
                    ev.reference,
                    if ev.rail_left_out {
                        "; reports at the rail left out"
                    } else {
                        ""
                    }
                ),
                x_desc: "separation (in)".into(),
                y_desc: "error in angle (deg)".into(),
                log_x: false,
                log_y: true,
                // One value per separation: marked, so that a few separations joined by
                // straight lines do not read as a measured curve.
                series: vec![
                    Series::new("std of the error in angle", pts(&ev.angle_std_deg)).with_markers(),
                    // Not in the thesis's figure, but part of the error: a bias common to
                    // the beacons of a separation (attitude the fit absorbed), often larger.
                    Series::new(
                        "|mean| of the error in angle (not in Figure 57)",
                        pts(&ev.angle_mean_deg.iter().map(|m| m.abs()).collect())
                            .into_iter()
                            .filter(|(_, m)| *m > 0.0)
                            .collect(),
                    )
                    .with_markers(),
                    Series::dashed(
                        format!("mean CTA uncertainty (eq 36, {})", ev.budget),
                        pts(&ev.cta_uncertainty_deg),
                    )
                    .with_markers(),
                ],
            }],
            1,
        )
        .map_err(|e| anyhow!("{e}; the table above is complete, the plot was not written"))?;
    }
    Ok(())
}

/// The text table of `cta evaluate`: the mean error with its standard error (to the digits
/// that resolves), the standard deviation and the CTA uncertainty to 3 significant digits.
fn print_evaluation(rep: &FitReport, ev: &fit::Evaluation, data_notes: &[String]) {
    println!(
        "Error in angle (eq 67) of the fit on {} in, against the {}:",
        fmt_list(&rep.separations),
        match ev.reference.as_str() {
            "truth" => "true head offset (truth sidecar)",
            "head" => "head centre given (--head)",
            _ => "fit's own eye point (no truth known: self-consistency only)",
        }
    );
    println!(
        "{:>14} {:>10} {:>22} {:>18} {:>8}",
        "separation in", "std (deg)", "mean ± s.e. (deg)", "CTA uncert. (deg)", "reports"
    );
    for i in 0..ev.separation_in.len() {
        let n = ev.reports[i];
        let mean = if n > 1 {
            let (m, se) = crate::analyze::digits::pm_parts(
                ev.angle_mean_deg[i],
                ev.angle_std_deg[i] / (n as f64).sqrt(),
            );
            format!("{m} ± {se}")
        } else {
            sig(ev.angle_mean_deg[i], 3)
        };
        let std = if n > 1 {
            sig(ev.angle_std_deg[i], 3)
        } else {
            "-".into()
        };
        println!(
            "{:>14} {:>10} {:>22} {:>18} {:>8}",
            ev.separation_in[i],
            std,
            mean,
            sig(ev.cta_uncertainty_deg[i], 3),
            n
        );
    }
    for n in data_notes {
        println!("note: {n}");
    }
    let mut railed: Vec<String> = (0..ev.separation_in.len())
        .filter(|&i| ev.at_rail[i] > 0)
        .map(|i| {
            let of = ev.reports[i] + if ev.rail_left_out { ev.at_rail[i] } else { 0 };
            format!("{} of {of} at {} in", ev.at_rail[i], ev.separation_in[i])
        })
        .collect();
    railed.extend(ev.all_at_rail_in.iter().map(|s| format!("all at {s} in")));
    if !railed.is_empty() {
        if ev.rail_left_out {
            println!(
                "note: reports with an output at the 16-bit rail (a cell in shadow) are left out \
                 (--without-rail; Figure 57 counts every report): {}",
                railed.join(", ")
            );
        } else {
            println!(
                "note: reports with an output at the 16-bit rail (a cell in shadow) are counted, \
                 as Figure 57 counts every report, but their error is that of a clipped output \
                 (leave them out with --without-rail): {}",
                railed.join(", ")
            );
        }
    }
    // Figure 57's claim: the CTA uncertainty an order of magnitude below the error.
    let ratios: Vec<String> = (0..ev.separation_in.len())
        .filter(|&i| ev.reports[i] > 1 && ev.cta_uncertainty_deg[i] > 0.0)
        .map(|i| {
            format!(
                "{:.1}x at {} in",
                ev.angle_std_deg[i] / ev.cta_uncertainty_deg[i],
                ev.separation_in[i]
            )
        })
        .collect();
    if let (Some(first), Some(last)) = (ratios.first(), ratios.last()) {
        let span = if ratios.len() > 1 {
            format!("{first} to {last}")
        } else {
            first.clone()
        };
        // Where the thesis's claim holds on these data: a ratio of 10 or more.
        let holds: Vec<String> = (0..ev.separation_in.len())
            .filter(|&i| {
                ev.reports[i] > 1
                    && ev.cta_uncertainty_deg[i] > 0.0
                    && ev.angle_std_deg[i] >= 10.0 * ev.cta_uncertainty_deg[i]
            })
            .map(|i| ev.separation_in[i].to_string())
            .collect();
        let holds = if holds.is_empty() {
            "at none of these separations".to_string()
        } else {
            format!("at {} in", holds.join(", "))
        };
        println!(
            "note: std over the CTA uncertainty: {span}; the thesis's \"an order of magnitude \
             below\" (10x or more) holds {holds} (on its data only near 1 in: README, thesis \
             inconsistency 6); the uncertainty is eq 36 with the corrected sensitivities, about \
             1.4x the thesis's eqs 34/35 (inconsistency 4)"
        );
    }
    // The thesis plots the std; a bias shared by a separation's beacons comes on top.
    let worst = ev
        .angle_mean_deg
        .iter()
        .zip(&ev.angle_std_deg)
        .filter(|(_, s)| **s > 0.0)
        .map(|(m, s)| m.abs() / s)
        .fold(0.0f64, f64::max);
    if worst > 1.0 {
        println!(
            "note: Figure 57 shows the std only; the mean error (a bias shared by a separation's \
             beacons, e.g. attitude the fit absorbed) is up to {worst:.1}x the std here and \
             adds to it (the plot draws both)"
        );
    }
}
