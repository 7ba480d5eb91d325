//! `cta nearfield`: the Ch II table of where each near-field effect falls below the noise.

use crate::args::{announce_plot, check_diameter, parse_list, Profile};
use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use cta_core::nearfield2d::{Crossing, Effect, CROSSING_MAX_D};
use cta_lab::nearfield::{NearfieldOptions, NearfieldTable};
use serde_json::json;
use std::path::PathBuf;

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

/// The library's options from the arguments, checked.
// Checks are written `!(x > 0.0)` on purpose: a NaN fails them.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
fn options(a: &NearfieldArgs) -> Result<NearfieldOptions> {
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
        cta_lab::plot::check_plot_path(p)?;
    }
    let thetas = parse_list(&a.theta).context("--theta")?;
    let max_theta = 90.0 - a.alpha;
    if let Some(t) = thetas.iter().find(|t| !(**t > 0.0 && **t < max_theta)) {
        bail!("--theta {t}: must be in (0, {max_theta}) deg (the field of view ends where tan theta = cot a)");
    }
    Ok(NearfieldOptions {
        alpha_deg: a.alpha,
        theta_deg: thetas,
        noise_deg: a.noise_deg,
        pattern: a.profile.pattern(a.half_angle),
        diameter_in: a.diameter_in,
        plotted: a.plot.is_some(),
    })
}

/// Run `cta nearfield`.
pub fn run(a: &NearfieldArgs) -> Result<()> {
    let table = NearfieldTable::new(&options(a)?);
    if a.json {
        println!("{}", crate::json_with_provenance(&to_json(&table), &[])?);
    } else {
        print_table(&table);
    }
    if let Some(p) = &a.plot {
        table
            .plot(p)
            .map_err(|e| anyhow!("{e}; the table above is complete, the plot was not written"))?;
        announce_plot(p);
    }
    Ok(())
}

/// `crossing_D` holds the distance or null; `crossing_kind` says what a null means.
fn to_json(t: &NearfieldTable) -> serde_json::Value {
    let o = &t.options;
    let mut crossing = serde_json::Map::new();
    let mut crossing_kind = serde_json::Map::new();
    for (e, c) in &t.crossings {
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
    let mut coeff = serde_json::Map::new();
    for (e, v) in &t.coefficients {
        coeff.insert(e.name().into(), json!(v));
    }
    json!({
        "alpha_deg": o.alpha_deg,
        "noise_deg": o.noise_deg,
        "profile": t.profile,
        "theta_deg": o.theta_deg,
        "crossing_D": crossing,
        "crossing_kind": crossing_kind,
        "coeff_deg_D": coeff,
        "diameter_in": o.diameter_in,
        "sign": "all errors make the beacon appear farther off boresight (convex pairing)",
        "warnings": t.warnings,
    })
}

/// The text table.
fn print_table(t: &NearfieldTable) {
    let o = &t.options;
    println!(
        "Near-field errors in angle (thesis Ch II, 2-D, a = {} deg, beacon: {}), noise {} deg, D = {} in",
        o.alpha_deg, t.profile, o.noise_deg, o.diameter_in
    );
    println!("Distance (sensor diameters D [inches]) beyond which each effect is below the noise:");
    println!(
        "{:>9} {:>18} {:>18} {:>18} {:>18}",
        "theta", "proximity", "intensity", "pattern", "combined"
    );
    let crossing = |e: Effect, i: usize| {
        t.crossings
            .iter()
            .find(|(f, _)| *f == e)
            .map_or(Crossing::AboveNoise, |(_, c)| c[i])
    };
    for (i, th) in o.theta_deg.iter().enumerate() {
        let cell = |e: Effect| match crossing(e, i) {
            Crossing::At(v) => format!("{v:.1} [{:.1}]", v * o.diameter_in),
            Crossing::BelowNoise => "below noise".into(),
            Crossing::AboveNoise => format!(
                "> {CROSSING_MAX_D:.0e} [> {:.0e}]",
                CROSSING_MAX_D * o.diameter_in
            ),
        };
        println!(
            "{:>7} ° {:>18} {:>18} {:>18} {:>18}",
            th,
            cell(Effect::Proximity),
            cell(Effect::Intensity),
            cell(Effect::Pattern),
            cell(Effect::Combined)
        );
    }
    println!("Far-field coefficients R x |delta theta| (deg D; the error falls as coeff / R):");
    let coeff = |e: Effect, i: usize| {
        t.coefficients
            .iter()
            .find(|(f, _)| *f == e)
            .map_or(f64::NAN, |(_, v)| v[i])
    };
    for (i, th) in o.theta_deg.iter().enumerate() {
        println!(
            "{:>7} ° proximity {:>8.3}  intensity {:>8.3}  pattern {:>8.3}",
            th,
            coeff(Effect::Proximity, i),
            coeff(Effect::Intensity, i),
            coeff(Effect::Pattern, i)
        );
    }
    println!("All three errors make the beacon appear farther off boresight (convex pairing, README, thesis inconsistency 2).");
    println!("Intensity (eq 15) weighs the far-field voltages of eq 3, the reading that reproduces Ch II (inconsistency 3).");
    for w in &t.warnings {
        println!("warning: {w}");
    }
}
