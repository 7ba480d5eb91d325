//! `cta simulate`: emulated NorthStar reports of the CTA beacon grid, with the truth beside them.

use crate::args::{parse_vector3, Profile};
use anyhow::{anyhow, bail, Result};
use clap::Args;
use cta_lab::sim::effects::Effect;
use cta_lab::sim::{self, SimConfig, MAX_LED_BRIGHTNESS, MAX_MAGNITUDE_NOISE};
use std::path::PathBuf;

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
    /// The quad layout: four copies of --grid (at most 100 LEDs each) in the plate's
    /// quadrants, their centres SPACING in apart in x and y (12: centres at +/-6 in, the
    /// thesis's four 12 in boards); beacon ids 100 * array + LED, as `cta sweep`'s quad.
    #[arg(long, value_name = "SPACING")]
    pub quad: Option<f64>,
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
    /// plate_tilt=SIGMA (deg), ambient=B, led_position=SIGMA, led_tilt=SIGMA (deg),
    /// array_pose=SIGMA_IN[,SIGMA_DEG] (with --quad), crosstalk=K (simulation only).
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

/// The simulation the arguments ask for, with the checks that name their option.
pub fn sim_config(a: &SimulateArgs) -> Result<SimConfig> {
    let seps = cta_lab::data::parse_new_separations(&a.separations)
        .map_err(|e| anyhow!("--separations: {e}"))?;
    let grid = sim::parse_grid(&a.grid).map_err(|e| anyhow!("--grid: {e}"))?;
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
    if !(0.0..=MAX_MAGNITUDE_NOISE).contains(&a.magnitude_noise) {
        bail!(
            "--magnitude-noise {}: between 0 and {} percent",
            a.magnitude_noise,
            MAX_MAGNITUDE_NOISE
        );
    }
    if !(0.0..=MAX_LED_BRIGHTNESS).contains(&a.led_brightness) {
        bail!(
            "--led-brightness {}: between 0 and {} percent",
            a.led_brightness,
            MAX_LED_BRIGHTNESS
        );
    }
    let d = parse_vector3(&a.d, "--d")?;
    let p = parse_vector3(&a.p, "--p")?;
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
        quad: a.quad,
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
pub fn run(a: &SimulateArgs) -> Result<()> {
    let cfg = sim_config(a)?;
    // Refuse an --out that may not be replaced before simulating (write_files checks it
    // again, with the same words, when it writes).
    sim::check_out(&a.out, a.force)?;
    let (ds, truth) = cfg.try_run()?;
    let tp = sim::write_files(&a.out, &ds, &truth, a.force)
        .map_err(|e| anyhow!("{e}; the simulation was not saved"))?;
    let plural =
        |n: usize, one: &str, many: &str| format!("{n} {}", if n == 1 { one } else { many });
    crate::say::line(format_args!(
        "wrote {} ({} x {} x {}, {} outside the field of view) to {} (truth: {})",
        plural(ds.samples.len(), "report", "reports"),
        plural(cfg.separations.len(), "separation", "separations"),
        plural(cfg.beacon_ids().len(), "beacon", "beacons"),
        plural(cfg.samples, "sample", "samples"),
        plural(truth.skipped_points, "point", "points"),
        a.out.display(),
        tp.display()
    ));
    if let Some(w) = sim::rail_note(&cfg, &ds) {
        crate::say::line(w);
    }
    Ok(())
}
