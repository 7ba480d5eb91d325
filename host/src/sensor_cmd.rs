//! `cta sensor ...`: talk to the sensor board (or the simulated one) by hand, and the
//! pose-accuracy table (near-field-aware pose vs pinhole pose).
//!
//! ```text
//! cta sensor sim --range 12              # simulated board on a pty, target 12 in away
//! cta sensor --port /dev/ttyUSB0 identify
//! cta sensor --port P template calibration > cal.json    # edit, then:
//! cta sensor --port P load-calibration cal.json
//! cta sensor --port P load-constellation con.json
//! cta sensor --port P config                              # what the board has in flash
//! cta sensor --port P sensitivity 3
//! cta sensor --port P stream --count 5                    # raw spot reports
//! cta sensor --port P pose --model near-field --count 10  # 6-dof poses
//! cta sensor --sim pose --count 5                         # same, against an in-process simulated board
//! cta sensor accuracy                                     # the accuracy table (simulated data)
//! ```

use std::io::Write as _;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use cta_core::collinearity::{self, Fit, Obs as FitObs, Params, ParamsExt};
use cta_core::emulator::{grid_position, Emulator, Head, Pose as HeadPose};
use cta_core::glsdc::{self, Settings};
use cta_core::mrp;
use cta_core::pose::{
    cta_constellation, simulate_spots, Calibration, Constellation, ModelKind, PoseSolver,
    PoseStatus, SolverSettings,
};
use cta_core::real::rad;
use cta_core::wire::sensor::{
    Mode, SensorProtocol, SensorRequest, SensorResponse, SensorStatus, SpotReport,
};
use cta_core::wire::{FrameDecoder, Reply, Response, MAX_FRAME, SEQ_NONE};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::Serialize;

/// The sensor firmware's library (board logic, NorthStar link, simulated board).
pub use cta_firmware_sensor as firmware;
use cta_firmware_sensor::sim::{SimBoard, SimNorthStar};
/// The vector type of the pose API (for callers without their own nalgebra dependency).
pub use nalgebra::Vector3;

use crate::link::{open_serial, Link, LinkConfig};

/// `cta sensor`: command the sensor board over its serial link.
#[derive(Debug, Args)]
pub struct SensorArgs {
    /// Serial port of the board (e.g. /dev/ttyUSB0, or the pty printed by `cta sensor sim`).
    #[arg(long, global = true)]
    pub port: Option<String>,
    /// Talk to a simulated board started in this process (instead of --port).
    #[arg(long, global = true)]
    pub sim: bool,
    /// Reply timeout per attempt, ms.
    #[arg(long, default_value_t = 500, global = true)]
    pub timeout_ms: u64,
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
    /// The Table 3 calibration with nominal near-field parameters.
    Calibration,
    /// The 10-beacon CTA constellation.
    Constellation,
}

/// `cta sensor` subcommands.
#[derive(Debug, Subcommand)]
pub enum SensorCommand {
    /// Which board answers, its firmware and protocol version.
    Identify,
    /// Mode, NorthStar settings, stored configuration, link counters.
    Status,
    /// Send one heartbeat.
    Heartbeat,
    /// Print a JSON template (calibration or constellation) to edit and load.
    Template {
        /// Which one.
        kind: TemplateKind,
    },
    /// Load a calibration (JSON file, see `template calibration`) into the board's flash.
    LoadCalibration {
        /// JSON file.
        file: String,
    },
    /// Load a constellation (JSON file, see `template constellation`) into the board's flash.
    LoadConstellation {
        /// JSON file.
        file: String,
    },
    /// Show the stored calibration and constellation.
    Config,
    /// Set the NorthStar light sensitivity (1..=4).
    Sensitivity {
        /// Setting.
        level: u8,
    },
    /// Set the NorthStar report rate (Hz, 1..=50).
    Rate {
        /// Rate, Hz.
        hz: u8,
    },
    /// Stream mode: print every spot report.
    Stream {
        /// Stop after this many reports (0: until Ctrl-C).
        #[arg(long, default_value_t = 10)]
        count: u64,
    },
    /// Pose mode: print every pose the board solves.
    Pose {
        /// Measurement model.
        #[arg(long, value_enum, default_value_t = ModelArg::NearField)]
        model: ModelArg,
        /// Stop after this many poses (0: until Ctrl-C).
        #[arg(long, default_value_t = 10)]
        count: u64,
    },
    /// Set the board idle (no reports).
    Idle,
    /// Run a simulated sensor board on a pseudo-terminal and print its path.
    Sim(SimArgs),
    /// Print the accuracy table: near-field-aware vs pinhole pose on simulated data.
    Accuracy(AccuracyArgs),
}

/// The simulated board's scene.
#[derive(Debug, Clone, Args)]
pub struct SimArgs {
    /// Target range (z of the target origin in the board frame), in.
    #[arg(long, default_value_t = 12.0)]
    pub range: f64,
    /// Target lateral offset x, y, in.
    #[arg(long, value_delimiter = ',', default_values_t = [0.2, -0.1])]
    pub offset: Vec<f64>,
    /// Target rotation about z, degrees.
    #[arg(long, default_value_t = 2.0)]
    pub yaw_deg: f64,
    /// Spot noise, counts (1-sigma).
    #[arg(long, default_value_t = 32.768)]
    pub noise: f64,
    /// Probability of line noise before a NorthStar frame.
    #[arg(long, default_value_t = 0.0)]
    pub garbage: f64,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Load the Table 3 calibration and the CTA constellation at start.
    #[arg(long)]
    pub configured: bool,
}

impl Default for SimArgs {
    fn default() -> Self {
        SimArgs {
            range: 12.0,
            offset: vec![0.2, -0.1],
            yaw_deg: 2.0,
            noise: 32.768,
            garbage: 0.0,
            seconds: None,
            configured: true,
        }
    }
}

impl SimArgs {
    /// The simulated NorthStar of this scene (Table 3 head, CTA constellation).
    pub fn northstar(&self) -> SimNorthStar {
        let t = Vector3::new(
            self.offset.first().copied().unwrap_or(0.0),
            self.offset.get(1).copied().unwrap_or(0.0),
            self.range,
        );
        let q = mrp::from_axis_angle(&Vector3::z(), rad(self.yaw_deg));
        let mut ns = SimNorthStar::new(
            &Calibration::table3(),
            cta_constellation(),
            t,
            q,
            self.noise,
            1,
        );
        ns.garbage = self.garbage;
        ns
    }
}

/// Options of the accuracy table.
#[derive(Debug, Clone, Args)]
pub struct AccuracyArgs {
    /// Noise draws (and random poses) per range.
    #[arg(long, default_value_t = 40)]
    pub trials: usize,
    /// Ranges, in.
    #[arg(long, value_delimiter = ',', default_values_t = [2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 15.0, 20.0, 25.0, 30.0])]
    pub ranges: Vec<f64>,
    /// Noise, fraction of beta (0.001 = 0.1 %).
    #[arg(long, default_value_t = 0.001)]
    pub noise_fraction: f64,
    /// Random seed.
    #[arg(long, default_value_t = 2010)]
    pub seed: u64,
    /// Solve in f64 (default: f32, as on the chip).
    #[arg(long)]
    pub f64: bool,
    /// Raise the five outer beacons of the constellation this far toward the sensor, in
    /// (beacons on posts: a 3-D target decorrelates tilt from lateral offset). 0: the flat
    /// CTA plate.
    #[arg(long, default_value_t = 0.0)]
    pub depth: f64,
    /// Print JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Exit with an error unless the issue's claims hold (>= 5x at 2-10 in, both at the
    /// noise floor at 30 in).
    #[arg(long)]
    pub check: bool,
}

impl Default for AccuracyArgs {
    fn default() -> Self {
        AccuracyArgs {
            trials: 40,
            ranges: vec![2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 15.0, 20.0, 25.0, 30.0],
            noise_fraction: 0.001,
            seed: 2010,
            f64: false,
            depth: 0.0,
            json: false,
            check: false,
        }
    }
}

/// Run `cta sensor`.
pub fn run(args: &SensorArgs) -> Result<()> {
    match &args.command {
        SensorCommand::Sim(s) => return run_sim(s),
        SensorCommand::Accuracy(a) => {
            let table = accuracy_table(a)?;
            if a.json {
                println!("{}", serde_json::to_string_pretty(&table)?);
            } else {
                print!("{}", table.render());
            }
            if a.check {
                table.check()?;
            }
            return Ok(());
        }
        SensorCommand::Template { kind } => {
            let text = match kind {
                TemplateKind::Calibration => serde_json::to_string_pretty(&Calibration::table3())?,
                TemplateKind::Constellation => serde_json::to_string_pretty(&cta_constellation())?,
            };
            println!("{text}");
            return Ok(());
        }
        _ => {}
    }
    // In-process simulated board when --sim (kept alive for the whole command).
    let sim = if args.sim {
        let sim = SimBoard::spawn(SimArgs::default().northstar())
            .context("starting the simulated sensor board")?;
        Some(sim)
    } else {
        None
    };
    let path = match (&sim, &args.port) {
        (Some(s), _) => s.path().to_string(),
        (None, Some(p)) => p.clone(),
        (None, None) => bail!(
            "--port PATH is required (the board's serial port, or the pty of `cta sensor sim`), or use --sim"
        ),
    };
    let port = open_serial(&path)?;
    let mut link = Link::<SensorProtocol, _>::new(
        port,
        LinkConfig {
            timeout: Duration::from_millis(args.timeout_ms),
            retries: 2,
        },
    );
    let id = link
        .check_board()
        .with_context(|| format!("identifying the board on {path}"))?;
    if sim.is_some() {
        // The in-process board starts with empty flash: load the defaults.
        link.call(SensorRequest::LoadCalibration(Calibration::table3()))?;
        link.call(SensorRequest::LoadConstellation(cta_constellation()))?;
    }
    match &args.command {
        SensorCommand::Identify => println!(
            "{} board, firmware {}, protocol {}{}, max frame {} bytes",
            id.board,
            id.firmware,
            id.protocol,
            if id.simulated { " (simulated)" } else { "" },
            id.max_frame
        ),
        SensorCommand::Status => match link.call(SensorRequest::Status)? {
            Some(SensorResponse::Status(s)) => print_status(&s),
            other => bail!("unexpected reply to Status: {other:?}"),
        },
        SensorCommand::Heartbeat => {
            link.heartbeat()?;
            println!("heartbeat acknowledged");
        }
        SensorCommand::LoadCalibration { file } => {
            let cal: Calibration = read_json(file)?;
            link.call(SensorRequest::LoadCalibration(cal))
                .with_context(|| format!("loading the calibration of {file}"))?;
            println!("calibration from {file} stored in flash");
        }
        SensorCommand::LoadConstellation { file } => {
            let con: Constellation = read_json(file)?;
            let n = con.beacons.len();
            link.call(SensorRequest::LoadConstellation(con))
                .with_context(|| format!("loading the constellation of {file}"))?;
            println!("constellation of {n} beacons from {file} stored in flash");
        }
        SensorCommand::Config => match link.call(SensorRequest::GetConfig)? {
            Some(SensorResponse::Config(c)) => {
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
            other => bail!("unexpected reply to GetConfig: {other:?}"),
        },
        SensorCommand::Sensitivity { level } => {
            link.call(SensorRequest::SetSensitivity(*level))?;
            println!("sensitivity {level}");
        }
        SensorCommand::Rate { hz } => {
            link.call(SensorRequest::SetRate(*hz))?;
            println!("rate {hz} Hz");
        }
        SensorCommand::Idle => {
            link.call(SensorRequest::SetMode(Mode::Idle))?;
            println!("idle");
        }
        SensorCommand::Stream { count } => {
            link.call(SensorRequest::SetMode(Mode::Stream))?;
            let mut n = 0;
            read_reports(&mut link, *count, |r| {
                if let SensorResponse::Spots(s) = r {
                    print_spots(&s);
                    n += 1;
                }
            })?;
            link.call(SensorRequest::SetMode(Mode::Idle))?;
        }
        SensorCommand::Pose { model, count } => {
            link.call(SensorRequest::SetMode(Mode::Pose((*model).into())))?;
            println!(
                "{:>6} {:>10} {:>9} {:>9} {:>9} {:>8} {:>8} {:>8} {:>7} {:>7} {:>7} {:>7} {:>3} {:>6}",
                "seq", "t (ms)", "x (in)", "y (in)", "z (in)", "roll", "pitch", "yaw", "sx(in)", "sy", "sz", "rms", "it", "status"
            );
            read_reports(&mut link, *count, |r| {
                if let SensorResponse::Pose(p) = r {
                    let q = Vector3::new(p.mrp[0] as f64, p.mrp[1] as f64, p.mrp[2] as f64);
                    let e = small_angles_deg(&q);
                    println!(
                        "{:>6} {:>10.1} {:>9.4} {:>9.4} {:>9.4} {:>8.3} {:>8.3} {:>8.3} {:>7.4} {:>7.4} {:>7.4} {:>7.1} {:>3} {:?}",
                        p.seq,
                        p.t_us as f64 / 1000.0,
                        p.position[0],
                        p.position[1],
                        p.position[2],
                        e[0],
                        e[1],
                        e[2],
                        p.sigma_position[0],
                        p.sigma_position[1],
                        p.sigma_position[2],
                        p.rms,
                        p.iterations,
                        p.status
                    );
                }
            })?;
            link.call(SensorRequest::SetMode(Mode::Idle))?;
        }
        SensorCommand::Sim(_) | SensorCommand::Accuracy(_) | SensorCommand::Template { .. } => {
            unreachable!("handled above")
        }
    }
    Ok(())
}

/// Attitude angles (deg) about x, y, z of an MRP, `4 atan(|q|) q/|q|` (exact rotation
/// vector; reads as roll/pitch/yaw for small angles).
fn small_angles_deg(q: &Vector3<f64>) -> [f64; 3] {
    let n = q.norm();
    if n == 0.0 {
        return [0.0; 3];
    }
    let v = q * (4.0 * n.atan() / n);
    [v.x.to_degrees(), v.y.to_degrees(), v.z.to_degrees()]
}

fn read_json<T: serde::de::DeserializeOwned>(file: &str) -> Result<T> {
    let text = std::fs::read_to_string(file).with_context(|| format!("reading {file}"))?;
    serde_json::from_str(&text).with_context(|| {
        format!(
            "{file}: not a valid JSON document of the expected shape (see `cta sensor template`)"
        )
    })
}

/// Read unsolicited reports (seq SEQ_NONE) until `count` arrived (0: forever); fails after
/// 5 s without a report.
pub fn read_reports<S: std::io::Read + std::io::Write>(
    link: &mut Link<SensorProtocol, S>,
    count: u64,
    mut on_report: impl FnMut(SensorResponse),
) -> Result<()> {
    let mut decoder = FrameDecoder::<MAX_FRAME>::new();
    let mut buf = [0u8; 256];
    let mut seen = 0u64;
    let mut last = Instant::now();
    while count == 0 || seen < count {
        let n = match link.port_mut().read(&mut buf) {
            Ok(n) => n,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                ) =>
            {
                0
            }
            Err(e) => return Err(e.into()),
        };
        if n == 0 && last.elapsed() > Duration::from_secs(5) {
            bail!("no report from the board for 5 s (is the NorthStar connected?)");
        }
        for &b in &buf[..n] {
            if let Some(Ok((h, Ok(Response::Board(r))))) =
                decoder.push::<Reply<SensorResponse, cta_core::wire::sensor::SensorError>>(b)
            {
                if h.seq == SEQ_NONE
                    && matches!(r, SensorResponse::Spots(_) | SensorResponse::Pose(_))
                {
                    seen += 1;
                    last = Instant::now();
                    on_report(r);
                }
            }
        }
        std::io::stdout().flush()?;
    }
    Ok(())
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
    println!("mode            {:?}", s.mode);
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
    println!("last pose       {:?}", s.last_pose);
}

fn run_sim(args: &SimArgs) -> Result<()> {
    let sim = SimBoard::spawn(args.northstar()).context("starting the simulated sensor board")?;
    if args.configured {
        let port = open_serial(sim.path())?;
        let mut link = Link::<SensorProtocol, _>::new(port, LinkConfig::default());
        link.call(SensorRequest::LoadCalibration(Calibration::table3()))?;
        link.call(SensorRequest::LoadConstellation(cta_constellation()))?;
    }
    println!("simulated sensor board on {}", sim.path());
    println!(
        "try: cta sensor --port {} pose --count 5   (Ctrl-C stops the board)",
        sim.path()
    );
    std::io::stdout().flush()?;
    let start = Instant::now();
    loop {
        std::thread::sleep(Duration::from_millis(100));
        if let Some(s) = args.seconds {
            if start.elapsed().as_secs_f64() >= s {
                break;
            }
        }
    }
    Ok(())
}

/// One row of the accuracy table (RMS over the trials).
#[derive(Debug, Clone, Serialize)]
pub struct AccuracyRow {
    /// Range (target z), in.
    pub range: f64,
    /// Mean number of beacons seen.
    pub beacons: f64,
    /// Near-field pose: RMS position error, in.
    pub nf_pos: f64,
    /// Pinhole pose: RMS position error, in.
    pub ph_pos: f64,
    /// Near-field pose: RMS attitude error, deg.
    pub nf_att: f64,
    /// Pinhole pose: RMS attitude error, deg.
    pub ph_att: f64,
    /// Noise floor: RMS of the near-field solver's predicted 1-sigma (position, in).
    pub floor_pos: f64,
    /// Noise floor: RMS predicted attitude 1-sigma, deg.
    pub floor_att: f64,
    /// Trials where a solver did not return status Ok.
    pub failures: usize,
}

/// The accuracy table.
#[derive(Debug, Clone, Serialize)]
pub struct AccuracyTable {
    /// Rows by range.
    pub rows: Vec<AccuracyRow>,
    /// The pinhole calibration used (fitted per Table 3 at 25 and 30 in).
    pub pinhole_calibration: Calibration,
    /// Trials per range.
    pub trials: usize,
    /// Noise, counts.
    pub noise_counts: f64,
    /// Height of the outer beacons above the plate, in.
    pub depth: f64,
    /// Arithmetic of the solver.
    pub arithmetic: &'static str,
}

impl AccuracyTable {
    /// Human-readable table.
    pub fn render(&self) -> String {
        let mut s = String::new();
        let pc = &self.pinhole_calibration;
        s += &format!(
            "Pose accuracy on simulated data: eq 63 physics (proximity, intensity, Lambertian beacon), Table 3 head,\n\
             noise {:.1} counts (1-sigma), {} trials per range (random lateral offset +/-0.5 in, attitude +/-3 deg),\n\
             10-beacon CTA constellation (outer five raised {:.1} in), {} solver, cold start.\n\
             near-field = the eq 60-63 model with the true head; pinhole = eq 65 with the 7-parameter calibration\n\
             fitted at 25 and 30 in as the thesis recommends (d = {:.4} {:.4} {:.4} in, H = {:.1}).\n\
             floor = RMS of the near-field solver's predicted 1-sigma (the noise floor). Errors are RMS.\n\n",
            self.noise_counts,
            self.trials,
            self.depth,
            self.arithmetic,
            pc.d[0],
            pc.d[1],
            pc.d[2],
            pc.h
        );
        s += "range  seen |  position error (in)                    |  attitude error (deg)                  | fail\n";
        s += " (in)       |  near-field   pinhole   ratio    floor  |  near-field  pinhole   ratio    floor |\n";
        for r in &self.rows {
            s += &format!(
                "{:5.1} {:5.1} |  {:10.5} {:9.5} {:7.1} {:8.5}  |  {:9.4} {:8.4} {:7.1} {:8.4} | {}\n",
                r.range,
                r.beacons,
                r.nf_pos,
                r.ph_pos,
                r.ph_pos / r.nf_pos,
                r.floor_pos,
                r.nf_att,
                r.ph_att,
                r.ph_att / r.nf_att,
                r.floor_att,
                r.failures
            );
        }
        s
    }

    /// The issue's claims: near-field at least 5x better (position and attitude) at 2-10 in,
    /// and both within 1.5x of the noise floor at 30 in.
    pub fn check(&self) -> Result<()> {
        let mut problems = Vec::new();
        for r in &self.rows {
            if r.range <= 10.0 && (r.ph_pos < 5.0 * r.nf_pos || r.ph_att < 5.0 * r.nf_att) {
                problems.push(format!(
                    "{} in: pinhole/near-field ratio {:.1} (position), {:.1} (attitude) < 5",
                    r.range,
                    r.ph_pos / r.nf_pos,
                    r.ph_att / r.nf_att
                ));
            }
            if (r.range - 30.0).abs() < 1e-9 {
                for (name, err, floor) in [
                    ("near-field position", r.nf_pos, r.floor_pos),
                    ("pinhole position", r.ph_pos, r.floor_pos),
                    ("near-field attitude", r.nf_att, r.floor_att),
                    ("pinhole attitude", r.ph_att, r.floor_att),
                ] {
                    if err > 1.5 * floor {
                        problems.push(format!(
                            "30 in: {name} error {err:.4} is above 1.5x the noise floor {floor:.4}"
                        ));
                    }
                }
            }
        }
        if !problems.is_empty() {
            bail!("accuracy claims not met:\n  {}", problems.join("\n  "));
        }
        Ok(())
    }
}

/// The 7-parameter pinhole calibration fitted (GLSDC, eq 65) to noise-free eq 63 data of
/// the 10 x 10 grid at 25 and 30 in (Table 3's recommended procedure).
pub fn pinhole_calibration(truth: &Calibration) -> Result<Calibration> {
    let em = cta_firmware_sensor::sim::physics(truth);
    let mut obs = Vec::new();
    for sep in [25.0, 30.0] {
        for i in 0..100 {
            let r = grid_position(10, 1.0, sep, i);
            if let Some(y) = em.output(&r) {
                obs.push(FitObs { r, y, w: [1.0; 2] });
            }
        }
    }
    let head = Head::<f64>::northstar();
    let x0 = Params::from_pose(
        &HeadPose {
            d: Vector3::zeros(),
            p: Vector3::zeros(),
        },
        head.h(),
    );
    let sol = glsdc::solve(&Fit { obs: &obs }, x0, &Settings::default())
        .map_err(|e| anyhow::anyhow!("pinhole calibration fit failed: {e:?}"))?;
    let x = sol.x;
    Ok(Calibration {
        d: [x[0] as f32, x[1] as f32, x[2] as f32],
        p: [x[3] as f32, x[4] as f32, x[5] as f32],
        h: collinearity::ParamsExt::h(&x) as f32,
        noise: truth.noise,
        near_field: None,
    })
}

fn angle_between_deg(q_est: &Vector3<f64>, q_true: &Vector3<f64>) -> f64 {
    let err = mrp::dcm(q_est) * mrp::dcm(q_true).transpose();
    mrp::angle(&mrp::from_dcm(&err)).to_degrees()
}

/// Compute the accuracy table.
pub fn accuracy_table(args: &AccuracyArgs) -> Result<AccuracyTable> {
    let mut truth = Calibration::table3();
    let noise = args.noise_fraction * cta_core::emulator::BETA;
    truth.noise = noise as f32;
    let ph_cal = pinhole_calibration(&truth)?;
    let mut con = cta_constellation();
    for b in con.beacons.iter_mut().skip(5) {
        b.r[2] = -args.depth as f32;
    }
    let em: Emulator<f64> = cta_firmware_sensor::sim::physics(&truth);
    let normal = Normal::new(0.0, noise).context("noise")?;
    let mut rng = StdRng::seed_from_u64(args.seed);
    let mut rows = Vec::new();
    let nf_set = SolverSettings {
        model: ModelKind::NearField,
        ..Default::default()
    };
    let ph_set = SolverSettings {
        model: ModelKind::Pinhole,
        ..Default::default()
    };
    for &range in &args.ranges {
        let (mut nf_p, mut ph_p, mut nf_a, mut ph_a, mut fl_p, mut fl_a, mut seen) =
            (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let mut failures = 0;
        for _ in 0..args.trials {
            let t = Vector3::new(
                rng.random_range(-0.5..0.5),
                rng.random_range(-0.5..0.5),
                range,
            );
            let axis = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let q = mrp::from_axis_angle(&axis, rad(rng.random_range(0.0..3.0)));
            let spots = simulate_spots(&em, &con, &t, &q, |_| normal.sample(&mut rng));
            seen += spots.len() as f64;
            let solve = |cal: &Calibration,
                         set: SolverSettings|
             -> Result<(
                PoseStatus,
                Vector3<f64>,
                Vector3<f64>,
                Vector3<f64>,
                Vector3<f64>,
            )> {
                if args.f64 {
                    let mut s = PoseSolver::<f64>::new(cal, &con, set)
                        .map_err(|e| anyhow::anyhow!("{e}"))?;
                    let r = s.solve(&spots);
                    Ok((
                        r.status,
                        r.position,
                        r.mrp,
                        r.sigma_position,
                        r.sigma_attitude_deg,
                    ))
                } else {
                    let mut s = PoseSolver::<f32>::new(cal, &con, set)
                        .map_err(|e| anyhow::anyhow!("{e}"))?;
                    let r = s.solve(&spots);
                    let c = |v: Vector3<f32>| v.map(|x| x as f64);
                    Ok((
                        r.status,
                        c(r.position),
                        c(r.mrp),
                        c(r.sigma_position),
                        c(r.sigma_attitude_deg),
                    ))
                }
            };
            let nf = solve(&truth, nf_set)?;
            let ph = solve(&ph_cal, ph_set)?;
            if nf.0 != PoseStatus::Ok || ph.0 != PoseStatus::Ok {
                failures += 1;
            }
            nf_p += (nf.1 - t).norm_squared();
            ph_p += (ph.1 - t).norm_squared();
            nf_a += angle_between_deg(&nf.2, &q).powi(2);
            ph_a += angle_between_deg(&ph.2, &q).powi(2);
            if nf.0 == PoseStatus::Ok {
                fl_p += nf.3.norm_squared();
                fl_a += nf.4.norm_squared();
            }
        }
        let n = args.trials.max(1) as f64;
        let ok = (args.trials - failures).max(1) as f64;
        rows.push(AccuracyRow {
            range,
            beacons: seen / n,
            nf_pos: (nf_p / n).sqrt(),
            ph_pos: (ph_p / n).sqrt(),
            nf_att: (nf_a / n).sqrt(),
            ph_att: (ph_a / n).sqrt(),
            floor_pos: (fl_p / ok).sqrt(),
            floor_att: (fl_a / ok).sqrt(),
            failures,
        });
    }
    Ok(AccuracyTable {
        rows,
        pinhole_calibration: ph_cal,
        trials: args.trials,
        noise_counts: noise,
        depth: args.depth,
        arithmetic: if args.f64 {
            "f64"
        } else {
            "f32 (as on the chip)"
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pinhole_calibration_reproduces_table3_far_pair() {
        let c = pinhole_calibration(&Calibration::table3()).unwrap();
        // REFERENCE.md Table 3, (25, 30) in: d3 = +1.1378, H = 19016.
        assert!((c.d[2] - 1.1378).abs() < 0.03, "{c:?}");
        assert!((c.h - 19016.0).abs() / 19016.0 < 0.003, "{c:?}");
    }

    #[test]
    fn small_angles() {
        let q = mrp::from_axis_angle(&Vector3::z(), 0.1);
        let e = small_angles_deg(&q);
        assert!((e[2] - 0.1f64.to_degrees()).abs() < 1e-9);
    }
}
