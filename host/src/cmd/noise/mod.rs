//! `cta noise`: the noise of repeated samples by separation, angle, magnitude and setting, and
//! the weighting it implies.

mod render;
#[cfg(test)]
mod tests;

pub use render::render_text;

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

/// `cta noise`: how noisy are the repeated samples, and on what does the noise depend?
#[derive(Debug, Clone, Args)]
#[command(after_long_help = "\
Needs repeated samples (several rows per beacon, separation and setting). For each factor the
file records (separation, off-boresight angle, signal magnitude, modulation frequency, power
level, sensitivity setting) the table gives the pooled one-sample standard deviation of X and
Y in counts with its standard error from sampling, whether the groups differ beyond sampling
(Bartlett's test, 1 %), and the verdict says which weighting to use in `cta analyze --weights`.
Points at the 16-bit rail (a coordinate at +/-32767 in any sample, or the mean within 3 sigma
of it: a cell in shadow or saturated) are left out of everything, as `cta calibrate` does, and
counted. The robust sigma (median absolute deviation from each point's median, points of 3+
samples) is given against the std per axis, with the samples more than 8 robust sigma from their
point's median (glitches: an ID mix-up, a corrupted report) and their lines, which every figure
still includes. Last, the repeatability of the spot magnitude (one-sample std over mean, in %): what
`cta sensor floor --magnitude-noise` takes to tell what the magnitudes would add to the pose.

EXAMPLE:
  cta simulate --out sim.csv --separations 2..30 --noise 32.8 --samples 20
  cta noise sim.csv --plot noise-plots")]
pub struct NoiseArgs {
    /// Measurement file (CSV, host/MEASUREMENTS.md).
    pub file: PathBuf,
    /// Write SVG plots (noise.svg) and a small HTML page into this folder.
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    /// Print the result as JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Run `cta noise`.
pub fn run(args: &NoiseArgs) -> Result<()> {
    let (ds, warnings) =
        cta_lab::sweep::read_measurements(&args.file).map_err(anyhow::Error::msg)?;
    for w in warnings {
        crate::say::warning(w);
    }
    let r = cta_lab::noise::analyze_noise(&ds)?;
    // The report first: a plot that cannot be written loses nothing.
    if args.json {
        println!(
            "{}",
            crate::json_with_provenance(&r, &[args.file.as_path()])?
        );
    } else {
        print!("{}", render_text(&r));
    }
    if let Some(dir) = &args.plot {
        let index = cta_lab::noise::write_plots(dir, &r, &render_text(&r))?;
        crate::say::line(format_args!("plots: {}", index.display()));
    }
    Ok(())
}
