//! `cta pose`: the poses of logged spot frames, solved on the host with the board's solver.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use cta_core::pose::{Calibration, PoseStatus};
use cta_lab::boards::files::read_json;
use cta_lab::pose::offline::{constellation, read_frames, solve_frames, OfflineOptions};

use crate::cmd::sensor::board::{pose_header, pose_json, pose_line};
use crate::cmd::sensor::ModelArg;

/// Solve logged spot frames on the host, with the same solver as the sensor board.
#[derive(Debug, Args)]
#[command(
    long_about = "Solve logged spot frames on the host with the sensor board's own solver (the same \
core code, in f32 as on the chip), configured from a calibration and a constellation: post-process a run, \
compare the models on your own frames, or check the board's poses.\n\n\
The frames are JSON lines, one spot report a line, as `cta sensor stream --json` prints them. Each frame \
starts from the last good pose, as on the board; --cold solves each on its own. The table is the one \
`cta sensor pose` prints (its `solve us` column is the host's time).",
    after_help = "EXAMPLE:
  cta sensor --port /dev/ttyUSB1 stream --json --count 600 > frames.jsonl
  cta pose frames.jsonl --calibration cal.json --constellation con.json
  cta pose frames.jsonl --calibration cal.json --constellation con.json --model pinhole --json"
)]
pub struct PoseArgs {
    /// The frames: JSON lines of spot reports (`cta sensor stream --json`).
    #[arg(value_name = "FRAMES")]
    pub frames: PathBuf,
    /// The calibration (`cta calibrate --out`, or `cta sensor template calibration`).
    #[arg(long, value_name = "CAL.json")]
    pub calibration: PathBuf,
    /// The constellation: a file (`cta sensor template constellation`) or a built-in name
    /// (one-10, one-19, four-10, four-19).
    #[arg(long, value_name = "FILE|NAME")]
    pub constellation: String,
    /// Set the beacons' brightness from this calibration's `led_brightness` (as
    /// `cta sensor load-constellation --brightness` does).
    #[arg(long, value_name = "CAL.json")]
    pub brightness: Option<String>,
    /// Measurement model.
    #[arg(long, value_enum, default_value_t = ModelArg::NearField)]
    pub model: ModelArg,
    /// Solve every frame from a cold start.
    #[arg(long)]
    pub cold: bool,
    /// One JSON object a frame (the fields of the board's pose report and `attitude_deg`).
    #[arg(long)]
    pub json: bool,
}

/// Run `cta pose`.
pub fn run(a: &PoseArgs) -> Result<()> {
    let cal_file = a.calibration.display().to_string();
    let cal: Calibration = read_json(&cal_file)?;
    let con = constellation(&a.constellation, a.brightness.as_deref())?;
    for w in &con.warnings {
        crate::say::warning(w);
    }
    let frames = read_frames(&a.frames)?;
    let options = OfflineOptions {
        model: a.model.into(),
        cold: a.cold,
    };
    let poses = solve_frames(&cal, &con.constellation, &frames, options)
        .with_context(|| format!("{cal_file} with {}", a.constellation))?;
    if !a.json {
        println!("{}", pose_header());
    }
    for p in &poses {
        if a.json {
            println!("{}", pose_json(p)?);
        } else {
            println!("{}", pose_line(p));
        }
    }
    let ok = poses.iter().filter(|p| p.status == PoseStatus::Ok).count();
    crate::say::line(format_args!(
        "{}: {} frames, {ok} solved ({}), {} not",
        a.frames.display(),
        poses.len(),
        match a.model {
            ModelArg::NearField => "near-field model",
            ModelArg::Pinhole => "pinhole model",
        },
        poses.len() - ok
    ));
    Ok(())
}
