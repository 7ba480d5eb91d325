//! The subcommands that talk to the sensor board: the requests, and the rendering of the
//! board's status, spot reports and poses.

use std::io::Write as _;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, LazyLock};

use anyhow::Result;
use cta_core::pose::{ModelKind, PoseStatus};
use cta_core::wire::sensor::{
    Mode, NorthStarStats, PoseReport, SensorResponse, SensorStatus, SpotReport,
};
use cta_lab::boards::sensor::{attitude_deg, constellation_file, SensorBoard};
use serde::Serialize;

use super::{ModelArg, SensorCommand, SensorConn};
use crate::cmd::beacon::{print_identity, FrameCounts};

/// Run a subcommand that talks to the board, with the connection options `conn`.
pub(super) fn run(command: &SensorCommand, conn: &SensorConn) -> Result<()> {
    let mut board = SensorBoard::open(&conn.at()?, conn.link_config())?;
    match command {
        SensorCommand::Identify { .. } => print_identity(board.identity(), &mut std::io::stdout())?,
        SensorCommand::Status { json, .. } => {
            let s = board.status()?;
            if *json {
                println!("{}", serde_json::to_string_pretty(&StatusJson::from(&s))?)
            } else {
                print_status(&s)
            }
        }
        SensorCommand::Heartbeat { .. } => {
            board.heartbeat()?;
            println!("heartbeat acknowledged");
        }
        SensorCommand::LoadCalibration {
            file, no_magnitude, ..
        } => {
            let without = if board.load_calibration(file, *no_magnitude)? {
                " without its magnitude law (--no-magnitude)"
            } else {
                ""
            };
            println!(
                "calibration from {file}{without} stored in flash{}",
                sim_note(conn)
            );
        }
        SensorCommand::LoadConstellation {
            file, brightness, ..
        } => {
            let con = constellation_file(file, brightness.as_deref())?;
            let bright = match (brightness, con.brightness_set) {
                (Some(cal), Some(set)) => format!(" (the brightness of {set} from {cal})"),
                _ => String::new(),
            };
            for w in &con.warnings {
                crate::say::warning(w);
            }
            let n = con.constellation.beacons.len();
            board.load_constellation(con.constellation, file)?;
            println!(
                "constellation of {n} beacons from {file}{bright} stored in flash{}",
                sim_note(conn)
            );
        }
        SensorCommand::Config { .. } => {
            let c = board.config()?;
            println!("flash record generation {}", c.generation);
            println!(
                "calibration: {}",
                match &c.calibration {
                    Some(cal) => serde_json::to_string(cal)?,
                    None => "none".into(),
                }
            );
            println!(
                "constellation: {}",
                match &c.constellation {
                    Some(con) => serde_json::to_string(con)?,
                    None => "none".into(),
                }
            );
        }
        SensorCommand::Sensitivity { level, .. } => {
            board.set_sensitivity(*level)?;
            println!("sensitivity {level}{}", set_note(conn));
        }
        SensorCommand::Rate { hz, .. } => {
            board.set_rate(*hz)?;
            println!("rate {hz} Hz{}", set_note(conn));
        }
        SensorCommand::Idle { .. } => {
            board.idle()?;
            println!("idle");
        }
        SensorCommand::Stream { count, json, .. } => {
            catch_stop();
            board.set_mode(Mode::Stream)?;
            let mut out = Ok(());
            let r = board.read_reports(*count, &STOP, |r| {
                if let SensorResponse::Spots(s) = r {
                    if *json {
                        if out.is_ok() {
                            out = serde_json::to_string(&s).map(|line| println!("{line}"));
                        }
                    } else {
                        print_spots(&s);
                    }
                }
                std::io::stdout().flush()
            });
            back_to_idle(&mut board, r)?;
            out?;
        }
        SensorCommand::Pose {
            model, count, json, ..
        } => {
            catch_stop();
            if matches!(model, ModelArg::NearField) && board.lacks_near_field()? {
                crate::say::warning(format_args!(
                    "the board's calibration has no near-field part (`near_field` \
                     null): near-field poses use the nominal head (face angles 30 deg, cells \
                     0.175 in off centre, no gains or offsets); load one from `cta calibrate`, \
                     or use --model pinhole"
                ));
            }
            board.set_mode(Mode::Pose((*model).into()))?;
            if !*json {
                println!("{}", pose_header());
            }
            let mut out = Ok(());
            let r = board.read_reports(*count, &STOP, |r| {
                if let SensorResponse::Pose(p) = r {
                    if *json {
                        if out.is_ok() {
                            out = pose_json(&p).map(|line| println!("{line}"));
                        }
                    } else {
                        println!("{}", pose_line(&p));
                    }
                }
                std::io::stdout().flush()
            });
            back_to_idle(&mut board, r)?;
            out?;
        }
        SensorCommand::Sim(_)
        | SensorCommand::Accuracy(_)
        | SensorCommand::Floor(_)
        | SensorCommand::Template { .. } => {
            unreachable!("they talk to no board")
        }
    }
    Ok(())
}

/// Set by Ctrl-C (SIGINT), SIGTERM or SIGHUP during `stream` and `pose` ([`catch_stop`]):
/// the reading of reports then returns, and the board is set idle before the command ends.
static STOP: LazyLock<Arc<AtomicBool>> = LazyLock::new(Default::default);

/// Catch Ctrl-C, SIGTERM and SIGHUP while reports stream: the first stops the reading (the
/// board is then set idle: otherwise it would go on solving and sending until the next
/// command), a second one leaves at once (128 + the signal). A signal ignored at the start
/// (SIGHUP under `nohup`) stays ignored, as in `cta sweep`.
fn catch_stop() {
    let _ = crate::signals::catch_stop(&STOP, None);
}

/// After `stream` or `pose` read their reports (or failed to): the board back to idle, and
/// the reading's result, or the idle request's error.
fn back_to_idle(
    board: &mut SensorBoard,
    read: std::result::Result<(), cta_lab::boards::sensor::Error>,
) -> Result<()> {
    let idle = board.idle();
    if STOP.load(Ordering::SeqCst) {
        eprintln!(
            "stopped by a signal: the board is {}",
            if idle.is_ok() {
                "idle"
            } else {
                "still sending (it did not answer the idle request)"
            }
        );
    }
    read?;
    idle?;
    Ok(())
}

/// The header of `cta sensor pose`'s table (the columns of [`pose_line`]).
pub fn pose_header() -> String {
    format!(
        "{:>6} {:>10} {:>9} {:>9} {:>9} {:>8} {:>8} {:>8} {:>7} {:>7} {:>7} {:>8} {:>7} {:>7} {:>7} {:>3} {:>3} {:>3} {:>8} {:>4} {:>4} {}",
        "seq", "t (ms)", "x (in)", "y (in)", "z (in)", "rx (deg)", "ry", "rz", "sx(in)", "sy", "sz",
        "srx(deg)", "sry", "srz", "rms", "it", "bcn", "mag", "solve us", "cold", "drop", "status"
    )
}

/// One row of `cta sensor pose`'s table: position, attitude (rotation vector, deg), their
/// 1-sigma ("-" where the board has none), residual RMS, iterations, beacons used, spot
/// magnitudes fitted, solve time on the board, cold start, the beacon left out (its ID: a
/// spot that disagreed with the rest, or an ID reported twice; "-" for none), status.
pub fn pose_line(p: &PoseReport) -> String {
    let e = attitude_deg(p);
    // Sigma fields are -1 when not available.
    let sig = |v: f32| {
        if v >= 0.0 {
            format!("{v:>7.4}")
        } else {
            format!("{:>7}", "-")
        }
    };
    format!(
        "{:>6} {:>10.1} {:>9.4} {:>9.4} {:>9.4} {:>8.3} {:>8.3} {:>8.3} {} {} {}  {} {} {} {:>7.1} {:>3} {:>3} {:>3} {:>8} {:>4} {:>4} {:?}",
        p.seq,
        p.t_us as f64 / 1000.0,
        p.position[0],
        p.position[1],
        p.position[2],
        e[0],
        e[1],
        e[2],
        sig(p.sigma_position[0]),
        sig(p.sigma_position[1]),
        sig(p.sigma_position[2]),
        sig(p.sigma_attitude_deg[0]),
        sig(p.sigma_attitude_deg[1]),
        sig(p.sigma_attitude_deg[2]),
        p.rms,
        p.iterations,
        p.beacons,
        p.magnitudes,
        p.solve_us,
        if p.cold_start { "yes" } else { "no" },
        p.dropped.map_or("-".to_string(), |id| id.to_string()),
        p.status
    )
}

/// A pose report as one line of JSON: every field of the [`PoseReport`], plus
/// `attitude_deg` (the rotation vector of the MRP, deg, as in the table).
pub fn pose_json(p: &PoseReport) -> serde_json::Result<String> {
    #[derive(Serialize)]
    struct Line<'a> {
        #[serde(flatten)]
        report: &'a PoseReport,
        attitude_deg: [f64; 3],
    }
    serde_json::to_string(&Line {
        report: p,
        attitude_deg: attitude_deg(p),
    })
}

/// After "stored in flash": with `--sim` the board lives for this one command, so what it
/// stored is gone when it ends.
fn sim_note(conn: &SensorConn) -> &'static str {
    if conn.sim {
        " of the simulated board (--sim: it lives for this command only, so the next command \
         starts from its defaults; `cta sensor sim` keeps one running on a pty for --port)"
    } else {
        ""
    }
}

/// After a setting: with `--sim` it is gone when the command ends.
fn set_note(conn: &SensorConn) -> &'static str {
    if conn.sim {
        " on the simulated board (--sim: it lives for this command only, so the next command \
         starts from its defaults; `cta sensor sim` keeps one running on a pty for --port)"
    } else {
        ""
    }
}

fn print_spots(s: &SpotReport) {
    print!(
        "#{} t={:.1} ms ns_seq={} sens={} spots={}:",
        s.seq,
        s.t_us as f64 / 1000.0,
        s.ns_seq,
        s.sensitivity,
        s.spots.len()
    );
    for sp in &s.spots {
        print!(" [{} {} {} m{}]", sp.id, sp.x, sp.y, sp.magnitude);
    }
    println!();
}

fn print_status(s: &SensorStatus) {
    println!("uptime          {:.1} s", s.uptime_ms as f64 / 1000.0);
    println!("last reset      {}", s.reset_cause);
    println!("mode            {}", describe_mode(&s.mode));
    println!(
        "northstar       sensitivity {}, {} Hz",
        s.sensitivity, s.rate_hz
    );
    println!(
        "stored          calibration: {}, constellation: {} (flash generation {})",
        s.calibrated, s.constellation, s.config_generation
    );
    println!(
        "pc frames       {} good, {} bad (oversized {}, encoding {}, truncated {}, crc {}, malformed {}, version {})",
        s.pc.ok,
        s.pc.bad(),
        s.pc.oversized,
        s.pc.encoding,
        s.pc.truncated,
        s.pc.crc,
        s.pc.malformed,
        s.pc.version
    );
    println!(
        "northstar link  {} frames, {} CRC errors, {} bytes discarded",
        s.northstar.frames, s.northstar.crc_errors, s.northstar.discarded
    );
    println!(
        "reports         {} sent, {} dropped; {} requests refused",
        s.reports, s.dropped, s.refused
    );
    println!("host silent     {} ms", s.since_host_ms);
    println!("last pose       {}", describe_last_pose(s.last_pose));
}

/// `cta sensor status --json`: every field of the text, under the names of the board's
/// status reply ([`SensorStatus`]), the reset cause and mode in the text's words.
#[derive(Debug, Serialize)]
struct StatusJson {
    uptime_ms: u64,
    reset_cause: &'static str,
    mode: &'static str,
    sensitivity: u8,
    rate_hz: u8,
    calibrated: bool,
    constellation: bool,
    config_generation: u32,
    pc: FrameCounts,
    northstar: NorthStarStats,
    reports: u32,
    dropped: u32,
    refused: u32,
    since_host_ms: u32,
    last_pose: Option<PoseStatus>,
}

impl From<&SensorStatus> for StatusJson {
    fn from(s: &SensorStatus) -> Self {
        StatusJson {
            uptime_ms: s.uptime_ms,
            reset_cause: s.reset_cause.name(),
            mode: describe_mode(&s.mode),
            sensitivity: s.sensitivity,
            rate_hz: s.rate_hz,
            calibrated: s.calibrated,
            constellation: s.constellation,
            config_generation: s.config_generation,
            pc: FrameCounts::from(&s.pc),
            northstar: s.northstar,
            reports: s.reports,
            dropped: s.dropped,
            refused: s.refused,
            since_host_ms: s.since_host_ms,
            last_pose: s.last_pose,
        }
    }
}

/// The board's mode in words (the status line `mode`).
fn describe_mode(m: &Mode) -> &'static str {
    match m {
        Mode::Idle => "Idle",
        Mode::Stream => "Stream (spot reports)",
        Mode::Pose(ModelKind::NearField) => "Pose (near-field model)",
        Mode::Pose(ModelKind::Pinhole) => "Pose (pinhole model)",
    }
}

/// The status of the board's last pose solve in words (the status line `last pose`), under
/// the name `cta sensor pose` prints in its `status` column.
fn describe_last_pose(p: Option<PoseStatus>) -> &'static str {
    match p {
        None => "none (no pose solved since the board started)",
        Some(PoseStatus::Ok) => "Ok (converged)",
        Some(PoseStatus::TooFewBeacons) => {
            "TooFewBeacons (fewer usable beacons of the constellation than a pose needs)"
        }
        Some(PoseStatus::Diverged) => {
            "Diverged (no convergence, or a false minimum: residual too large or the target \
             beyond the constellation's far limit)"
        }
        Some(PoseStatus::IllConditioned) => {
            "IllConditioned (the beacons seen do not determine the pose)"
        }
    }
}

#[cfg(test)]
mod tests {
    /// The status line's mode names each mode and model as itself (a swap of the two models'
    /// words would read one for the other).
    #[test]
    fn the_mode_in_words_names_the_model() {
        use super::{Mode, ModelKind};
        assert_eq!(super::describe_mode(&Mode::Idle), "Idle");
        assert_eq!(super::describe_mode(&Mode::Stream), "Stream (spot reports)");
        assert_eq!(
            super::describe_mode(&Mode::Pose(ModelKind::NearField)),
            "Pose (near-field model)"
        );
        assert_eq!(
            super::describe_mode(&Mode::Pose(ModelKind::Pinhole)),
            "Pose (pinhole model)"
        );
    }
}
