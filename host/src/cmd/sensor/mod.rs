//! `cta sensor ...`: talk to the sensor board (or the simulated one) by hand, and the
//! pose-accuracy table (near-field-aware pose vs pinhole pose).
//!
//! ```text
//! cta sensor sim --range 12              # simulated board on a pty, target 12 in away
//! cta sensor sim --truth run/data.truth.json --configured   # ... with a simulated sweep's head
//! cta sensor --port /dev/ttyUSB1 identify
//! cta sensor template calibration > cal.json             # edit, then:
//! cta sensor --port P load-calibration cal.json
//! cta sensor --port P load-constellation con.json
//! cta sensor --port P config                              # what the board has in flash
//! cta sensor --port P status --json                       # mode, settings, counters as JSON
//! cta sensor --port P sensitivity 3
//! cta sensor --port P stream --count 5                    # raw spot reports
//! cta sensor --port P pose --model near-field --count 10  # 6-dof poses
//! cta sensor --sim pose --count 5                         # same, against an in-process simulated board
//! cta sensor --sim pose --count 5 --json                  # one JSON object per pose report
//! cta sensor accuracy                                     # the accuracy table (simulated data)
//! ```

pub(crate) mod board;
mod render;
mod sim;
mod tables;

use anyhow::Result;
use clap::{Args, Subcommand, ValueEnum};
use cta_core::pose::ModelKind;

use crate::conn::{self, BoardConn};
pub use sim::SimArgs;
pub use tables::{AccuracyArgs, FloorArgs, PlateArg, SceneArgs};

/// The connection options of `cta sensor`.
pub type SensorConn = BoardConn<conn::Sensor>;

/// `cta sensor`: command the sensor board over its serial link.
///
/// The connection options go before the subcommand (`cta sensor --port P status`) or after
/// it (`cta sensor status --port P`); `template`, `sim`, `accuracy` and `floor` talk to no
/// board and refuse them.
#[derive(Debug, Args)]
pub struct SensorArgs {
    /// How to reach the board.
    #[command(flatten)]
    pub conn: SensorConn,
    /// What to do.
    #[command(subcommand)]
    pub command: SensorCommand,
}

/// Pose model on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModelArg {
    /// The eq 60-63 near-field physics.
    NearField,
    /// The eq 65 pinhole (collinearity) model.
    Pinhole,
}

impl From<ModelArg> for ModelKind {
    fn from(m: ModelArg) -> Self {
        match m {
            ModelArg::NearField => ModelKind::NearField,
            ModelArg::Pinhole => ModelKind::Pinhole,
        }
    }
}

/// Which template to print.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TemplateKind {
    /// The simulated CTA's calibration, to edit: the Table 3 truth head, nominal near-field
    /// parameters, the simulated NorthStar's magnitude law and the pinhole fit's H, with
    /// `pinhole` null (the pinhole model then uses
    /// `d`, `p`; `cta calibrate` writes the fitted eye point there).
    Calibration,
    /// A built-in constellation (`--name`: the 10-beacon CTA one by default).
    Constellation,
}

/// `cta sensor` subcommands.
#[derive(Debug, Subcommand)]
pub enum SensorCommand {
    /// Which board answers, its firmware and protocol version.
    Identify {
        #[command(flatten)]
        conn: SensorConn,
    },
    /// Mode, NorthStar settings, stored configuration, link counters.
    Status {
        /// Print one JSON object instead of text: every field the text prints, the last
        /// reset and the mode in the text's words, the last pose's status by its name as
        /// `pose` prints it (null: none yet), times in ms.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        conn: SensorConn,
    },
    /// Send one heartbeat.
    Heartbeat {
        #[command(flatten)]
        conn: SensorConn,
    },
    /// Print a JSON template (calibration or constellation) to edit and load.
    ///
    /// Calibration fields (`cta calibrate --out` writes the same): `d` the head's position on
    /// the board (in, N frame); `p` its attitude (MRP, C(p) maps N to the head frame); `h` the
    /// pinhole model's focal constant (counts); `noise` one coordinate's 1-sigma (counts);
    /// `near_field` (null: pinhole only): `alpha_deg` the cell faces' angle (deg; the X pair's
    /// when `alpha_y_deg` is set, both pairs' when it is null), `alpha_y_deg` the Y pair's,
    /// `s` the cells' offset from the head centre (in), `beta` the output scale (counts),
    /// `pattern_m` the LED pattern exponent (cos^m; 1 Lambertian, from the datasheet), `gain`
    /// cells 1 and 3's gain minus 1 against their pair, `bias` their offsets (1/in^2, as a
    /// signal); `pinhole` (null: the pinhole model uses `d` and `p`): the pinhole model's own
    /// `d` and `p`, fitted with `h` (eq 65; `cta calibrate` writes its pinhole fit's, whose eye
    /// point sits about 1 in above the head); `magnitude` (null: the pose uses the spots
    /// alone): the spot magnitude law `M = offset + A (b S)^exponent` the near-field pose fits
    /// the magnitudes with, its scatter `noise_percent`, the range of readings it holds
    /// (`min`, `max`) and the NorthStar `sensitivity` it was fitted at (`cta calibrate` fits
    /// it; the template's is the simulated NorthStar's). Out-of-range values are refused by the
    /// board, naming the field.
    ///
    /// Constellation fields: `beacons`, each an `id` (the NorthStar channel, 0-19), its
    /// position `r` (in, target frame) and its LED's relative `brightness` (1 when left out;
    /// `load-constellation --brightness CAL.json` sets it from a calibration); `boresight` the
    /// direction the LEDs face (target frame). 4 to 20 beacons, distinct ids, not both of channels 2 and 19 (the NorthStar
    /// table gives both 4050 Hz).
    Template {
        /// Which one.
        kind: TemplateKind,
        /// For `constellation`: which built-in (one-10, one-19, four-10, four-19; see
        /// `cta sensor accuracy --help`).
        #[arg(long, default_value = "one-10")]
        name: String,
    },
    /// Load a calibration (JSON file, see `template calibration`) into the board's flash.
    LoadCalibration {
        /// JSON file.
        file: String,
        /// Store it without its spot magnitude law (`magnitude`): the pose then uses the spots
        /// alone (to compare, or when the board's magnitudes are not the sweep's: a simulated
        /// board's scale is another than the simulated sweep's).
        #[arg(long)]
        no_magnitude: bool,
        #[command(flatten)]
        conn: SensorConn,
    },
    /// Load a constellation (JSON file, see `template constellation`) into the board's flash.
    LoadConstellation {
        /// JSON file.
        file: String,
        /// Set each beacon's brightness from a calibration's `led_brightness` (`cta calibrate`
        /// fits it from a sweep's spot magnitudes): the LED within 0.05 in of the beacon's
        /// (x, y), the constellation's frame being the plate's. Beacons without one keep theirs.
        #[arg(long, value_name = "CAL.json")]
        brightness: Option<String>,
        #[command(flatten)]
        conn: SensorConn,
    },
    /// Show the stored calibration and constellation.
    Config {
        #[command(flatten)]
        conn: SensorConn,
    },
    /// Set the NorthStar light sensitivity (1..=4).
    Sensitivity {
        /// Setting, 1..=4.
        #[arg(value_parser = clap::value_parser!(u8).range(1..=4))]
        level: u8,
        #[command(flatten)]
        conn: SensorConn,
    },
    /// Set the NorthStar report rate (Hz, 1..=50).
    Rate {
        /// Rate, Hz, 1..=50.
        #[arg(value_parser = clap::value_parser!(u8).range(1..=50))]
        hz: u8,
        #[command(flatten)]
        conn: SensorConn,
    },
    /// Stream mode: print every spot report.
    Stream {
        /// Stop after this many reports (0: until Ctrl-C).
        #[arg(long, default_value_t = 10)]
        count: u64,
        /// Print one JSON object per report (every field of the board's spot report)
        /// instead of text.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        conn: SensorConn,
    },
    /// Pose mode: print every pose the board solves.
    ///
    /// Columns: board sequence number and time; position (in); attitude as the rotation
    /// vector rx, ry, rz (deg: the axis times the angle, from the MRP; not Euler angles,
    /// though close to them below a few degrees); their 1-sigma ("-" when the board has none);
    /// residual RMS (counts); GLSDC iterations; beacons used; spot magnitudes fitted (0: the
    /// spots alone: the calibration has no magnitude law, the model is the pinhole, or the
    /// NorthStar's sensitivity is not the one the law was fitted at); the solve time on the
    /// board (us); whether the solve started cold; status.
    Pose {
        /// Measurement model.
        #[arg(long, value_enum, default_value_t = ModelArg::NearField)]
        model: ModelArg,
        /// Stop after this many poses (0: until Ctrl-C).
        #[arg(long, default_value_t = 10)]
        count: u64,
        /// Print one JSON object per report (every field of the board's pose report, plus
        /// `attitude_deg`: the rotation vector rx, ry, rz) instead of the table.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        conn: SensorConn,
    },
    /// Set the board idle (no reports).
    Idle {
        #[command(flatten)]
        conn: SensorConn,
    },
    /// Run a simulated sensor board on a pseudo-terminal and print its path.
    Sim(SimArgs),
    /// Print the accuracy table: near-field-aware vs pinhole pose on simulated data.
    ///
    /// Simulates frames of the constellation through the eq 63 physics at each range, solves
    /// each with both models (f32, as on the chip) and prints the RMS error of one frame, the
    /// noise floor (the near-field solver's predicted 1-sigma), the systematic error (the same
    /// poses without noise) and the design targets with a verdict each (near-field at least 5x
    /// more accurate than pinhole at 2-10 in; both at the noise floor at 30 in). The near-field
    /// calibration is fitted to a simulated CTA sweep first, as the lab would do.
    ///
    /// The near-field pose also fits the spot magnitudes (their ratios between beacons carry
    /// the target's tilt, which the spots show only through perspective at 8-10 in), with the
    /// scatter `--magnitude-noise` (0.07 % by default: what the spot noise implies; the real
    /// NorthStar's is to be measured, `cta noise`). Its column "spots only" is the same model
    /// without them; `--no-magnitudes` leaves them out altogether.
    ///
    /// The target's spread and beacon count decide the attitude figures: compare the
    /// built-ins, e.g. `for c in one-10 one-19 four-10 four-19; do cta sensor accuracy
    /// --constellation $c; done` (beacons on one array or over four, 10 or all 19
    /// frequencies).
    Accuracy(AccuracyArgs),
    /// Print the noise floor of one frame's pose: from the spots alone, and with the spot
    /// magnitudes as well (an assumed magnitude model, as a what-if).
    ///
    /// The floor is the Cramer-Rao bound of the pose through the eq 60-63 physics: no
    /// unbiased pose from the same measurements does better. Next to it: the pinhole pose's
    /// systematic attitude error and the floor a pose must reach for the pinhole to be 5x
    /// worse per frame. The magnitude rows assume magnitude = k x (sum of the cell signals),
    /// k common to all beacons and unknown, noise a fixed percentage: the NorthStar's real
    /// magnitude output has not been measured. `--monte-carlo N` solves noisy frames with the
    /// magnitudes to show the bound is reached. The "best ratio" column is the largest
    /// one-frame attitude ratio pinhole / near-field any pose from the spots alone can show:
    /// run it per `--constellation` to see what a wider target or more beacons would buy.
    Floor(FloorArgs),
}

impl SensorCommand {
    /// The connection options given after the subcommand; `None` for the subcommands that
    /// talk to no board.
    fn conn(&self) -> Option<&SensorConn> {
        match self {
            SensorCommand::Identify { conn }
            | SensorCommand::Status { conn, .. }
            | SensorCommand::Heartbeat { conn }
            | SensorCommand::LoadCalibration { conn, .. }
            | SensorCommand::LoadConstellation { conn, .. }
            | SensorCommand::Config { conn }
            | SensorCommand::Sensitivity { conn, .. }
            | SensorCommand::Rate { conn, .. }
            | SensorCommand::Stream { conn, .. }
            | SensorCommand::Pose { conn, .. }
            | SensorCommand::Idle { conn } => Some(conn),
            SensorCommand::Template { .. }
            | SensorCommand::Sim(_)
            | SensorCommand::Accuracy(_)
            | SensorCommand::Floor(_) => None,
        }
    }

    /// The name on the command line of a subcommand that talks to no board.
    fn name(&self) -> &'static str {
        match self {
            SensorCommand::Template { .. } => "template",
            SensorCommand::Sim(_) => "sim",
            SensorCommand::Accuracy(_) => "accuracy",
            SensorCommand::Floor(_) => "floor",
            _ => "",
        }
    }
}

/// Run `cta sensor`.
pub fn run(args: &SensorArgs) -> Result<()> {
    let Some(after) = args.command.conn() else {
        args.conn.refuse_for(args.command.name())?;
        return match &args.command {
            SensorCommand::Sim(s) => sim::run(s),
            SensorCommand::Floor(a) => tables::floor(a),
            SensorCommand::Accuracy(a) => tables::accuracy(a),
            SensorCommand::Template { kind, name } => template(*kind, name),
            _ => unreachable!("every board command has connection options"),
        };
    };
    let conn = args.conn.merge(after)?;
    board::run(&args.command, &conn)
}

/// `template`: a calibration or a built-in constellation as JSON, to edit and load.
fn template(kind: TemplateKind, name: &str) -> Result<()> {
    use cta_lab::pose::{calibrations::sim_calibration, head::SimScene, plate};
    let text = match kind {
        // `pinhole` null: an edit of `d`, `p` then moves both models' head (a filled-in
        // eye point would keep the pinhole model where it was).
        TemplateKind::Calibration => serde_json::to_string_pretty(&cta_core::pose::Calibration {
            pinhole: None,
            ..sim_calibration(SimScene::default().magnitude_noise)?
        })?,
        TemplateKind::Constellation => {
            serde_json::to_string_pretty(&plate::built_in_constellation(name)?)?
        }
    };
    println!("{text}");
    Ok(())
}
