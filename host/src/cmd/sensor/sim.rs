//! `cta sensor sim`: a simulated sensor board on a pseudo-terminal.

use std::io::Write as _;

use anyhow::{bail, Result};
use clap::Args;
use cta_lab::pose::head::SimScene;

/// The simulated board's scene.
#[derive(Debug, Clone, Args)]
pub struct SimArgs {
    /// Target range (z of the target origin in the board frame), inches (above 0, at most
    /// 1000).
    #[arg(long, default_value_t = 12.0, allow_negative_numbers = true)]
    pub range: f64,
    /// Target lateral offset x,y, inches (two numbers, comma-separated).
    #[arg(long, value_name = "X,Y", default_value = "0.2,-0.1", value_parser = crate::args::parse_xy, allow_hyphen_values = true)]
    pub offset: [f64; 2],
    /// Target rotation about z, degrees (shorthand for --attitude-deg 0,0,RZ).
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    pub yaw_deg: f64,
    /// Target attitude: rotations about the board frame's x, y and z, in that order,
    /// degrees (three numbers, comma-separated; any roll RZ, e.g. 10,-5,150). Replaces
    /// --yaw-deg.
    #[arg(
        long,
        value_name = "RX,RY,RZ",
        allow_hyphen_values = true,
        conflicts_with = "yaw_deg"
    )]
    pub attitude_deg: Option<String>,
    /// Probability that a frame carries one spot under another beacon's ID (0 to 1): a
    /// random spot reported with a random other spot's ID, whose own spot is then missing
    /// (a reflection or an ID mix-up). The board leaves such a spot out by its residual and
    /// names the beacon (column `drop` of `cta sensor pose`).
    #[arg(
        long,
        value_name = "P",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub wrong_id: f64,
    /// Spot noise, counts (1-sigma, 0 or more).
    #[arg(long, default_value_t = 32.768, allow_negative_numbers = true)]
    pub noise: f64,
    /// Spot magnitude noise, percent of the magnitude (1-sigma, 0 to 100; the magnitudes are
    /// then rounded to counts, 0.29 counts 1-sigma). The magnitudes follow the NorthStar's
    /// magnitude law of every simulator (host/MEASUREMENTS.md): about 30000-45000 counts in
    /// the default scene at 12 in (power level 1, sensitivity 4). The default 0.07 % is the level the default spot noise (0.1 %
    /// of beta) implies if both come from independent noise in the four cells (sigma_M / M =
    /// sigma_X / (sqrt 2 beta), see `cta sensor floor --help`). The board fits the magnitudes
    /// when its calibration has a magnitude law (`magnitude`) fitted at the NorthStar's
    /// sensitivity in force.
    #[arg(
        long,
        value_name = "PCT",
        default_value_t = 0.07,
        allow_negative_numbers = true
    )]
    pub magnitude_noise: f64,
    /// Probability of line noise before a NorthStar frame (0 to 1).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub garbage: f64,
    /// The beacons' power level for the spot magnitudes: 1 (1 kOhm, up to ~10-15 in) or 2
    /// (360 Ohm, 2.8x brighter, for 15-30 in: nearer, its spots saturate at sensitivity 4).
    #[arg(long, value_name = "1|2", default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=2))]
    pub power_level: u8,
    /// Stop after this many seconds (above 0; default: until Ctrl-C).
    #[arg(long, allow_negative_numbers = true)]
    pub seconds: Option<f64>,
    /// Load the simulated CTA's calibration (the Table 3 truth head, nominal near-field
    /// parameters, the pinhole model's own eye point) and the CTA constellation at start.
    /// (With --truth or --effect that calibration is not the simulated head's: load your own
    /// over it with `load-calibration`.)
    #[arg(long)]
    pub configured: bool,
    /// Simulate the head of a simulated measurement file: the truth sidecar `cta simulate`
    /// writes next to its file (FILE.truth.json) and a sweep of the simulated CTA (`cta demo`'s
    /// among them) into its run folder (data.truth.json). Its head offset d, attitude p, base physics,
    /// beacon pattern and effects (e.g. the demo's hidden cell gains) make the simulated
    /// NorthStar; `plate_offset`, `separation_error`, `plate_tilt` and `beacon_tilt` describe
    /// the CTA's plate, not the head, and are left out (said on stderr). Default: the Table 3 head with
    /// the nominal near-field physics.
    #[arg(long, value_name = "FILE.truth.json")]
    pub truth: Option<std::path::PathBuf>,
    /// Give the simulated head an effect of the vocabulary, NAME=VALUE (repeatable), as `cta
    /// simulate --effect` does: proximity=S, intensity, beacon_pattern=H, cell_gain=GX[,GY],
    /// cell_bias=BX[,BY], face_angle=DX[,DY], saturation=S, crosstalk=K. (beacon_tilt,
    /// plate_offset, separation_error and plate_tilt describe the CTA's plate, not the head:
    /// refused.)
    // The brackets are --help text (optional parts), not doc links.
    #[allow(rustdoc::broken_intra_doc_links)]
    #[arg(long = "effect", value_name = "NAME=VALUE", conflicts_with = "truth")]
    pub effects: Vec<String>,
}

impl SimArgs {
    /// The scene of the simulated board (an error names a bad --attitude-deg).
    pub fn scene(&self) -> Result<SimScene> {
        Ok(SimScene {
            range: self.range,
            offset: self.offset,
            attitude_deg: match &self.attitude_deg {
                Some(a) => parse_attitude(a).map_err(|e| anyhow::anyhow!("--attitude-deg {e}"))?,
                None => [0.0, 0.0, self.yaw_deg],
            },
            wrong_id: self.wrong_id,
            noise: self.noise,
            magnitude_noise: self.magnitude_noise,
            garbage: self.garbage,
            power_level: self.power_level,
            truth: self.truth.clone(),
            effects: self.effects.clone(),
        })
    }

    /// Check every option (with an error naming the option and its allowed range).
    pub fn check(&self) -> Result<()> {
        let scene = self.scene()?;
        scene.check_values()?;
        if let Some(t) = self.seconds {
            if !(t > 0.0 && t.is_finite()) {
                bail!("--seconds {t}: expected a time above 0, seconds");
            }
        }
        scene.head()?;
        Ok(())
    }
}

/// `--attitude-deg RX,RY,RZ`.
fn parse_attitude(s: &str) -> std::result::Result<[f64; 3], String> {
    crate::args::parse_floats(s, "RX,RY,RZ (degrees)", "10,-5,150")
}

/// Run `cta sensor sim`: start the board, say where it is and what it simulates, and serve
/// until `--seconds` have passed or the process is stopped.
pub(super) fn run(args: &SimArgs) -> Result<()> {
    args.check()?;
    let scene = args.scene()?;
    let head = scene.head()?;
    let sim = cta_lab::boards::sensor::start_sim(&scene, args.configured)?;
    println!("simulated sensor board on {}", sim.path());
    if let Some(h) = &head {
        println!("simulated head: {}", h.describe);
        if !h.left_out.is_empty() {
            crate::say::line(format_args!(
                "note: effects of the file left out: {} (the CTA plate's, not the head's)",
                h.left_out.join(" ")
            ));
        }
    }
    if args.configured {
        println!(
            "try: cta sensor --port {} pose --count 5   (Ctrl-C stops the board)",
            sim.path()
        );
    } else {
        // Pose mode needs a calibration and a constellation, which this board has not got.
        println!(
            "try: cta sensor --port {} stream --count 5   (Ctrl-C stops the board; poses need \
             a calibration and a constellation: load them, or start with --configured)",
            sim.path()
        );
    }
    std::io::stdout().flush()?;
    crate::cmd::beacon::serve_for(args.seconds);
    Ok(())
}
