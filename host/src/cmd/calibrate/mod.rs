//! `cta calibrate`: the sensor board's calibration from a measured sweep, the JSON file `cta
//! sensor load-calibration` stores in the board's flash.

mod render;

use std::path::PathBuf;

use anyhow::{anyhow, bail, Result};
use clap::Args;
use cta_lab::data::parse_separations;
use cta_lab::fit::calibrate::{self, CalibrateOptions};

/// `cta calibrate`: fit the sensor board's calibration to a measured sweep.
#[derive(Debug, Args)]
#[command(
    long_about = "Fit the sensor board's calibration to a measured (or simulated) CTA sweep and write \
the JSON file `cta sensor load-calibration` stores in the board's flash.\n\n\
Two fits: the pinhole model (eq 65: d, p, H) on the far separations, then the near-field model \
(eqs 60-63: d, p, the face angles of both pairs, cell offset s, cell gains gx, gy, cell offsets \
bx, by) on every separation, started from it. Then the spot magnitude law the near-field pose \
fits the magnitudes with, M = offset + A (b S)^exponent (S: eq 63's summed cell signal of the \
fitted head; b: each LED's brightness, written as `led_brightness` for `cta sensor \
load-constellation --brightness`; A: a scale every pose estimates), at one sensitivity setting, \
saturated readings left out (host/CALIBRATE.md, item 3; --no-magnitude leaves it out). The file holds both: the near-field fit's d, p (the \
head) and the pinhole fit's own (`pinhole`: its eye point, about 1 in above the head), which the \
chip's pinhole model uses with H. Repeated samples are averaged per point and weighted by their noise, pooled per separation and axis. The \
report gives every parameter with its 1-sigma, the residual RMS per separation of both models (what \
the near-field model gains on this sensor), and warns when the data hold structure the chip's \
model cannot represent (then run `cta analyze` on the same file).\n\n\
Example:\n  cta sweep --sim --out run && cta calibrate run/data.csv --out cal.json\n  \
cta sensor --port /dev/ttyUSB1 load-calibration cal.json"
)]
pub struct CalibrateArgs {
    /// Measurement file (CSV, host/MEASUREMENTS.md), e.g. a sweep's `data.csv`.
    pub file: PathBuf,
    /// Write the calibration here (JSON for `cta sensor load-calibration`). An earlier
    /// calibration written by `cta calibrate` is replaced; any other file only with --force.
    #[arg(long, value_name = "CAL.json")]
    pub out: Option<PathBuf>,
    /// Let --out replace a file that is not an earlier calibration.
    #[arg(long)]
    pub force: bool,
    /// Fit the near-field model to these separations only (list or range, e.g. `2..30`);
    /// default: every separation in the file.
    #[arg(long, value_name = "SEPS")]
    pub separations: Option<String>,
    /// Fit the pinhole model (eq 65) to these separations; default: 25 and 30 in when the
    /// file has both (the thesis's calibration; a measured 24.995 counts as 25: within 0.1
    /// in), else the file's two largest.
    #[arg(long, value_name = "SEPS")]
    pub pinhole_separations: Option<String>,
    /// One-sample noise of a coordinate, counts: the calibration's `noise` and the weights.
    /// Default: measured from the repeated samples; a file with one sample per point needs
    /// it (0.1 % of beta is 32.8).
    #[arg(long, value_name = "COUNTS")]
    pub noise: Option<f64>,
    /// Beacon pattern exponent m of the LEDs (`cos^m`; 1 = the VSML3710's 60 deg
    /// half-intensity angle), held in the fit and written to the calibration.
    #[arg(long = "pattern-m", value_name = "M", default_value_t = 1.0)]
    pub pattern_m: f64,
    /// Draw the residual RMS per separation of both models against the noise (SVG): where
    /// the near-field model pays on this sensor, and where it still misses.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
    /// Leave out the samples the glitch check flags (more than 8 robust sigma from their
    /// point's median; the warning names their lines), as `cta analyze --drop-glitches`
    /// does. The file is not changed; the output (and the calibration's `fitted`) says how
    /// many were left out.
    #[arg(long)]
    pub drop_glitches: bool,
    /// Leave the spot magnitude law out of the calibration (by default it is fitted to the
    /// file's `magnitude` column with the fitted head, and the pose uses the magnitudes).
    #[arg(long, conflicts_with = "magnitude_sensitivity")]
    pub no_magnitude: bool,
    /// The NorthStar sensitivity setting (1-4) whose magnitudes the law is fitted to (the chip
    /// uses the law only at it). Default: the setting with the most magnitudes in the file
    /// (rows without a `sensitivity` count as 4, the board's start-up setting).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=4))]
    pub magnitude_sensitivity: Option<u8>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Run `cta calibrate`.
pub fn run(a: &CalibrateArgs) -> Result<()> {
    if let Some(out) = &a.out {
        calibrate::check_out(out, &a.file, a.force)?;
    }
    if let Some(p) = &a.plot {
        cta_lab::plot::check_plot_path(p)?;
    }
    if let Some(v) = a.noise {
        if !(v.is_finite() && v > 0.0) {
            bail!("--noise {v}: a positive number of counts");
        }
    }
    let (all, warnings) = cta_lab::sweep::read_measurements(&a.file).map_err(|e| anyhow!("{e}"))?;
    for w in warnings {
        crate::say::warning(w);
    }
    let separations = match &a.separations {
        None => None,
        Some(s) => Some(parse_separations(s).map_err(|e| anyhow!("--separations: {e}"))?),
    };
    let pinhole_separations = match &a.pinhole_separations {
        None => None,
        Some(s) => Some(parse_separations(s).map_err(|e| anyhow!("--pinhole-separations: {e}"))?),
    };
    let opts = CalibrateOptions {
        separations,
        pinhole_separations,
        noise: a.noise,
        pattern_m: a.pattern_m,
        drop_glitches: a.drop_glitches,
        magnitude: !a.no_magnitude,
        magnitude_sensitivity: a.magnitude_sensitivity,
    };
    let mut rep = calibrate::calibrate_file(all, &opts)?;
    rep.file.fitted.run = Some(crate::provenance(&[a.file.as_path()]));
    // The report is printed whether or not the writes succeed, and a failed write is the
    // error after it.
    let saved = match &a.out {
        Some(out) => calibrate::save(&rep, out)
            .map_err(|e| anyhow!("{e}; the calibration above was not saved"))
            .map(|()| Some(out.as_path())),
        None => Ok(None),
    };
    let plotted = match &a.plot {
        Some(p) => calibrate::plot(&rep, p)
            .map(|()| crate::args::announce_plot(p))
            .map_err(|e| anyhow!("{e}; the plot was not written")),
        None => Ok(()),
    };
    if a.json {
        println!(
            "{}",
            crate::json_with_provenance(&rep, &[a.file.as_path()])?
        );
    } else {
        render::print_report(&rep, saved.as_ref().map(|o| o.as_deref()).ok());
    }
    saved?;
    plotted
}
