//! Argument parsing shared by the commands: number lists, value enums mirroring the library's,
//! and the checks whose messages name a `--flag`.

use anyhow::{anyhow, bail, Context, Result};
use clap::ValueEnum;
use cta_core::pattern::Pattern;
use cta_lab::data::weights::Weights;

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

/// How residuals are weighted (eq 56's `W`): the command line's names for
/// [`cta_lab::data::weights::Weights`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WeightsArg {
    /// `W = I`: every sample is one observation (the thesis's choice).
    None,
    /// Point means weighted by `n / variance` from the repeated samples of each point, with
    /// a floor of 1/12 count^2 (the quantisation of integer counts). Needs at least 6
    /// samples per point (`REPEAT_MIN_SAMPLES`).
    Repeat,
    /// Point means weighted by `n / variance` with the one-sample variance pooled per
    /// separation and axis (over the points with no sample at the 16-bit rail), floored at
    /// 1/12 count^2: `cta calibrate`'s and `cta analyze`'s weights, good from 2 samples.
    Pooled,
}

impl From<WeightsArg> for Weights {
    fn from(w: WeightsArg) -> Weights {
        match w {
            WeightsArg::None => Weights::None,
            WeightsArg::Repeat => Weights::Repeat,
            WeightsArg::Pooled => Weights::Pooled,
        }
    }
}

/// Comma-separated numbers (`--theta 6,18`, `--d 0.6,0.1,0.062`).
pub fn parse_list(s: &str) -> Result<Vec<f64>> {
    s.split(',')
        .map(|p| {
            p.trim()
                .parse::<f64>()
                .map_err(|_| anyhow!("`{p}` is not a number"))
        })
        .collect()
}

/// Three comma-separated numbers for the option `what` (`--d`, `--p`).
pub fn parse_vector3(s: &str, what: &str) -> Result<nalgebra::Vector3<f64>> {
    let v = parse_list(s).with_context(|| what.to_string())?;
    if v.len() != 3 {
        bail!("{what}: expected three comma-separated numbers");
    }
    Ok(nalgebra::Vector3::new(v[0], v[1], v[2]))
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

/// `--head X,Y,Z`.
pub fn parse_xyz(s: &str) -> std::result::Result<[f64; 3], String> {
    parse_floats(s, "x,y,z", "0.6,0.1,0.06")
}

/// `--separations` of a command that selects from a file: `None` when not given.
pub fn separations(s: Option<&str>) -> Result<Option<Vec<f64>>> {
    s.map(|s| cta_lab::data::parse_separations(s).map_err(|e| anyhow!("--separations: {e}")))
        .transpose()
}

/// `--diameter-in`: the sensor diameter D, inches.
pub fn check_diameter(d: f64) -> Result<()> {
    if !(d > 0.0 && d.is_finite()) {
        bail!("--diameter-in {d}: the sensor diameter must be > 0 in (NorthStar: 0.35)");
    }
    Ok(())
}

/// Print the warnings a command's library call returned, as `warning: ...` on stderr.
pub fn print_warnings(warnings: &[String]) {
    for w in warnings {
        crate::say::warning(w);
    }
}

/// Announce a plot written (on stderr, after the table it draws).
pub fn announce_plot(path: &std::path::Path) {
    crate::say::line(format_args!("plot: {}", path.display()));
}

/// Parse `x,y` (two numbers, comma-separated: `--offset 0.3,-0.2`).
pub fn parse_xy(s: &str) -> std::result::Result<[f64; 2], String> {
    parse_floats(s, "x,y", "0.3,-0.2")
}
