//! `cta demo`: the whole job on the built-in simulated CTA, no hardware.

use crate::commands::{self, EvaluateArgs, FitArgs, NearfieldArgs, Profile, SimulateArgs, UncertaintyArgs};
use crate::fit::Weights;
use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::PathBuf;

/// Run the main job on the simulated CTA: near-field analysis, uncertainty, a simulated
/// characterization (thesis physics, noise, a hidden effect), calibration, evaluation.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Output folder (created; must not exist unless --force).
    #[arg(long, default_value = "cta-demo")]
    pub out: PathBuf,
    /// Replace an existing output folder.
    #[arg(long)]
    pub force: bool,
    /// The hidden effect injected into the simulated data (NAME=VALUE).
    #[arg(long, default_value = "beacon_tilt=3,30")]
    pub effect: String,
    /// Random seed.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
}

/// Run `cta demo`.
pub fn run(a: &DemoArgs) -> Result<()> {
    if a.out.exists() {
        if !a.force {
            bail!("{} exists; pass --force to replace it", a.out.display());
        }
        std::fs::remove_dir_all(&a.out).with_context(|| format!("{}", a.out.display()))?;
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}", a.out.display()))?;
    let p = |f: &str| a.out.join(f);
    println!("== 1. Ch II: near-field errors (2-D)");
    commands::nearfield(&NearfieldArgs {
        alpha: 30.0,
        theta: "6,18,30,45".into(),
        noise_deg: 0.1,
        profile: Profile::Lambertian,
        half_angle: 60.0,
        diameter_in: 0.35,
        plot: Some(p("nearfield.svg")),
        json: false,
    })?;
    println!("\n== 2. Ch IV: CTA uncertainty");
    commands::uncertainty_cmd(&UncertaintyArgs { budget: None, diameter_in: 0.35, plot: Some(p("uncertainty.svg")), json: false })?;
    println!("\n== 3. Ch V: a simulated characterization, 2-30 in, noise 0.1 % of beta, hidden effect `{}`", a.effect);
    let data = p("cta.csv");
    commands::simulate(&SimulateArgs {
        out: data.clone(),
        separations: "2..30".into(),
        grid: "10x10".into(),
        profile: Profile::Lambertian,
        half_angle: 60.0,
        far_field: false,
        effects: vec![a.effect.clone()],
        noise: 32.8,
        samples: 8,
        round: true,
        seed: a.seed,
        d: "0.6,0.1,0.062".into(),
        p: "0.001,0.002,0.001".into(),
    })?;
    println!("\n== 4. Ch V: calibrate the pinhole model at 25-30 in (thesis recommendation)");
    let fit = p("fit.json");
    commands::fit_cmd(&FitArgs {
        file: data.clone(),
        separations: Some("25..30".into()),
        weights: Weights::Repeat,
        save: Some(fit.clone()),
        json: false,
    })?;
    println!("\n== 5. Figure 57: error in angle of that calibration at every separation");
    commands::evaluate_cmd(&EvaluateArgs {
        fit,
        file: data.clone(),
        separations: None,
        plot: Some(p("figure57.svg")),
        json: false,
    })?;
    println!("\nDemo output in {}: nearfield.svg, uncertainty.svg, cta.csv (+ truth), fit.json, figure57.svg", a.out.display());
    Ok(())
}
