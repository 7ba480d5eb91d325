//! `cta sensor accuracy` and `cta sensor floor`: the pose tables' options, and their output
//! as text or JSON with a plot.

use std::path::Path;

use anyhow::Result;
use clap::{Args, ValueEnum};
use cta_lab::pose::accuracy::{accuracy_table_on, AccuracyOptions};
use cta_lab::pose::floor::{floor_table_on, FloorOptions};
use cta_lab::pose::plate::{Plate, Scene, TestScene};
use serde::Serialize;

use super::render;

/// Which beacon arrays are on the plate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PlateArg {
    /// One 10 x 10 array centred over the sensor: x, y in -4.5 .. 4.5 in.
    One,
    /// Four arrays in the quadrants: x, y in +/-1.5 .. +/-10.5 in (a 20 x 20 grid with a
    /// 3 in gap at the centre).
    Four,
}

impl From<PlateArg> for Plate {
    fn from(p: PlateArg) -> Self {
        match p {
            PlateArg::One => Plate::One,
            PlateArg::Four => Plate::Four,
        }
    }
}

/// The target of a pose analysis (`cta sensor accuracy`, `cta sensor floor`): which
/// constellation, on which plate, raised how far.
#[derive(Debug, Clone, Default, Args)]
pub struct SceneArgs {
    /// The constellation: a built-in name (one-10, one-19, four-10, four-19: beacons on one
    /// array or spread over four, 10 or all 19 NorthStar frequencies) or a JSON file (the shape
    /// of `cta sensor template constellation`). Default one-10, the chip's benchmark.
    #[arg(long, value_name = "NAME|FILE")]
    pub constellation: Option<String>,
    /// The plate the calibration sweeps see: `one` array or `four` in the quadrants.
    /// Default: the built-in's own; for a file, `four` if a beacon lies beyond 4.5 in.
    #[arg(long, value_enum)]
    pub plate: Option<PlateArg>,
    /// Raise every beacon after the first five this far toward the sensor, in (beacons on
    /// posts: a 3-D target decorrelates tilt from lateral offset), on top of the height a
    /// file gives them. 0: as given (the built-ins are flat).
    #[arg(long, default_value_t = 0.0)]
    pub depth: f64,
}

impl SceneArgs {
    /// The target as the pose analyses take it.
    pub fn scene(&self) -> Scene {
        Scene {
            constellation: self.constellation.clone(),
            plate: self.plate.map(Plate::from),
            depth: self.depth,
        }
    }
}

/// Options of the accuracy table.
#[derive(Debug, Clone, Args)]
pub struct AccuracyArgs {
    /// Noise draws (and random poses) per range (1 or more).
    #[arg(long, default_value_t = 40)]
    pub trials: usize,
    /// Ranges, inches, comma-separated (each above 0, at most 1000).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "2,3,4,5,6,8,10,15,20,25,30",
        allow_hyphen_values = true
    )]
    pub ranges: Vec<f64>,
    /// Noise, fraction of beta (0.001 = 0.1 %; 1e-6 to 0.3).
    #[arg(long, default_value_t = 0.001, allow_negative_numbers = true)]
    pub noise_fraction: f64,
    /// Random seed.
    #[arg(long, default_value_t = 2010)]
    pub seed: u64,
    /// Solve in f64 (default: f32, as on the chip).
    #[arg(long)]
    pub f64: bool,
    /// The target: constellation, plate, raise.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Samples averaged per beacon and separation in the simulated calibration sweep that
    /// the near-field calibration is fitted to (Ch VI takes 100-200; 1 or more).
    #[arg(long, default_value_t = 100)]
    pub cal_samples: usize,
    /// Give the near-field solver the true head instead of a fitted calibration (the
    /// model-error-free ideal).
    #[arg(long)]
    pub true_calibration: bool,
    /// Scatter of the simulated NorthStar's spot magnitudes, percent (1-sigma, on top of
    /// their rounding to counts), 0 to 100. 0.07 % is what the 0.1 % of beta spot noise
    /// implies if both come from independent noise in the four cells (`cta sensor floor`);
    /// the real detector's is not known until a sweep of it is measured (`cta noise`).
    #[arg(long, value_name = "PCT", default_value_t = 0.07)]
    pub magnitude_noise: f64,
    /// Solve the near-field pose from the spots alone (the magnitudes are not fitted; the
    /// "spots only" column is then the near-field one).
    #[arg(long)]
    pub no_magnitudes: bool,
    /// Draw the errors against range (near-field, pinhole, noise floor, systematic) to this
    /// SVG file.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<std::path::PathBuf>,
    /// Print JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Exit with an error unless every design target holds (near-field at least 5x more
    /// accurate than pinhole at 2-10 in, in position and attitude; both within 1.5x of the
    /// noise floor at 30 in).
    #[arg(long)]
    pub check: bool,
    /// Draw poses over a docking envelope instead, each frame solved from the cold start:
    /// any roll about the line of sight (+/-180 deg), tilts up to the angle at which 4
    /// beacons stay in view, lateral offsets to the field of view's edge (both found per
    /// range). Per range: the cold acquisition rate, the near-field and pinhole errors and
    /// their ratio, and the failed frames with why. Uses --trials (frames per range; 1000
    /// for a per-mille rate), --ranges, --noise-fraction, --seed, --f64, the target options
    /// and --json; the near-field solver has the true head.
    #[arg(long, conflicts_with_all = ["plot", "check", "no_magnitudes", "true_calibration"])]
    pub envelope: bool,
}

impl AccuracyArgs {
    /// The options of the table.
    pub fn options(&self) -> AccuracyOptions {
        AccuracyOptions {
            trials: self.trials,
            ranges: self.ranges.clone(),
            noise_fraction: self.noise_fraction,
            seed: self.seed,
            f64: self.f64,
            scene: self.scene.scene(),
            cal_samples: self.cal_samples,
            true_calibration: self.true_calibration,
            magnitude_noise: self.magnitude_noise,
            no_magnitudes: self.no_magnitudes,
        }
    }
}

/// Options of `cta sensor floor`.
#[derive(Debug, Clone, Args)]
pub struct FloorArgs {
    /// Ranges, inches, comma-separated (each above 0, at most 1000).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "2,4,6,8,10,15,20,30",
        allow_hyphen_values = true
    )]
    pub ranges: Vec<f64>,
    /// Magnitude noise levels to try, percent of the magnitude (1-sigma). 0.07 % is the
    /// level the spot noise implies if both come from independent noise in the four cells
    /// (near the boresight sigma_M / M = sigma_X / (sqrt 2 beta)); larger levels stand for
    /// LED flicker, drift and the NorthStar's own processing. Each above 0 (a huge level
    /// stands for magnitudes that carry nothing).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0.07,0.3,1,3",
        allow_hyphen_values = true
    )]
    pub magnitude_noise: Vec<f64>,
    /// Spot noise, fraction of beta (0.001 = 0.1 %, 32.8 counts; 1e-6 to 0.3).
    #[arg(long, default_value_t = 0.001, allow_negative_numbers = true)]
    pub noise_fraction: f64,
    /// Random poses per range (lateral offset +/-0.5 in, attitude up to 3 deg, as in
    /// `cta sensor accuracy`); the floors are RMS over them (1 or more).
    #[arg(long, default_value_t = 20)]
    pub poses: usize,
    /// Also solve this many noisy frames per pose with the magnitudes (host GLSDC) and
    /// report the RMS error reached, to check the bound is attainable.
    #[arg(long, default_value_t = 0)]
    pub monte_carlo: usize,
    /// Random seed.
    #[arg(long, default_value_t = 2010)]
    pub seed: u64,
    /// The target: constellation, plate (of the pinhole calibration sweep), raise.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Draw the attitude and position floors against range (spots only, each magnitude
    /// noise, and the attitude floor needed for 5x) to this SVG file.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<std::path::PathBuf>,
    /// Print JSON instead of the table.
    #[arg(long)]
    pub json: bool,
}

impl FloorArgs {
    /// The options of the table.
    pub fn options(&self) -> FloorOptions {
        FloorOptions {
            ranges: self.ranges.clone(),
            magnitude_noise: self.magnitude_noise.clone(),
            noise_fraction: self.noise_fraction,
            poses: self.poses,
            monte_carlo: self.monte_carlo,
            seed: self.seed,
            scene: self.scene.scene(),
        }
    }
}

/// The target of a table, after its options are checked, with the warnings about its
/// constellation file said on stderr.
fn target(check: cta_lab::pose::Result<()>, scene: &Scene) -> Result<TestScene> {
    check?;
    let target = scene.resolve()?;
    for w in &target.warnings {
        crate::say::warning(w);
    }
    Ok(target)
}

/// Print a table (JSON or its text) and draw its plot when asked.
fn print_table(
    table: &impl Serialize,
    text: String,
    json: bool,
    plot: Option<&Path>,
    draw: impl FnOnce(&Path) -> Result<()>,
) -> Result<()> {
    if json {
        println!("{}", crate::json_with_provenance(table, &[])?);
    } else {
        print!("{text}");
    }
    if let Some(p) = plot {
        draw(p)?;
        crate::args::announce_plot(p);
    }
    Ok(())
}

/// Run `cta sensor accuracy --envelope`.
fn envelope(a: &AccuracyArgs) -> Result<()> {
    let options = cta_lab::pose::envelope::EnvelopeOptions {
        trials: a.trials,
        ranges: a.ranges.clone(),
        noise_fraction: a.noise_fraction,
        seed: a.seed,
        f64: a.f64,
    };
    let scene = a.scene.scene();
    let target = target(options.check(), &scene)?;
    let table = cta_lab::pose::envelope::envelope_table_on(&options, target)?;
    print_table(&table, render::envelope(&table), a.json, None, |_| Ok(()))
}

/// Run `cta sensor accuracy`.
pub(super) fn accuracy(a: &AccuracyArgs) -> Result<()> {
    if a.envelope {
        return envelope(a);
    }
    if let Some(p) = &a.plot {
        cta_lab::plot::check_plot_path(p)?;
    }
    let options = a.options();
    let target = target(options.check(), &options.scene)?;
    let table = accuracy_table_on(&options, target)?;
    print_table(
        &table,
        render::accuracy(&table),
        a.json,
        a.plot.as_deref(),
        |p| Ok(table.plot(p)?),
    )?;
    if a.check {
        table.check()?;
    }
    Ok(())
}

/// Run `cta sensor floor`.
pub(super) fn floor(a: &FloorArgs) -> Result<()> {
    if let Some(p) = &a.plot {
        cta_lab::plot::check_plot_path(p)?;
    }
    let options = a.options();
    let target = target(options.check(), &options.scene)?;
    let table = floor_table_on(&options, target)?;
    print_table(
        &table,
        render::floor(&table),
        a.json,
        a.plot.as_deref(),
        |p| Ok(table.plot(p)?),
    )
}
