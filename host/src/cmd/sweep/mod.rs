//! `cta sweep`: the command line of a sweep. The run itself is [`cta_lab::sweep`]; this
//! module parses the options, catches the stop signals, draws the progress ([`bars`]), asks
//! the operator ([`prompt`]) and prints the summary.

mod bars;
mod prompt;

use std::path::PathBuf;

use anyhow::{bail, Result};
use cta_lab::sweep::engine::{interruption, interruption_signal, Ending, INTERRUPTED, SIGNAL};
use cta_lab::sweep::estimate::{self, Steps};
use cta_lab::sweep::plan::Plan;
use cta_lab::sweep::{points_done, status, store, Summary, SweepOptions};

pub use bars::Bars;
pub use prompt::Prompt;

/// `cta sweep`: run a plan on the CTA (or the simulated CTA) into a run directory.
#[derive(clap::Args, Debug, Clone, Default)]
#[command(
    about = "Collect CTA data autonomously: a plan of separations x beacons x frequencies x power \
             levels x sensitivities, over serial, resumable",
    long_about = "Collect CTA data autonomously (thesis Ch IV, Ch VI). A plan (TOML, see host/SWEEP.md and \
host/plans/) lists the separations, beacons, frequencies, power levels, sensitivity settings, samples per point, \
settle time and timeouts. For every point the beacon board lights one LED, the sensor board streams NorthStar \
reports, and the samples are appended to RUN_DIR/data.csv (the measurement format of host/MEASUREMENTS.md) and \
synced to disk before the point is journalled. The run asks the operator to move the plate (entering the four \
corner measurements: their mean is recorded as the separation, and the larger of its differences from the \
highest and the lowest corner as its uncertainty, Ch IV) and to flip the power switches; --yes runs without asking.\n\n\
Nothing is lost and nothing is written twice: after Ctrl-C, a killed process or a power cut, \
`cta sweep --resume RUN_DIR` continues with the next point; `cta sweep --status RUN_DIR` says how far a run has \
got without changing anything, also while it runs. An unplugged or silent board pauses the run, which \
retries with backoff and continues when the board is back. Every fault and retry is in RUN_DIR/journal.jsonl \
and RUN_DIR/manifest.json.\n\n\
Without --beacon/--sensor the run uses the simulated CTA: both boards' firmware behind pseudo-terminals, the \
simulated NorthStar seeing what the beacon board lights through the emulator (eqs 60-63), the plate moving \
itself. Example:\n  cta sweep --plan host/plans/short.toml --out run1 --sim-noise 20\n  \
cta sweep --resume run1\n  cta sweep --status run1\n  \
cta sweep --plan plan.toml --out lab1 --beacon /dev/ttyUSB0 --sensor /dev/ttyUSB1"
)]
pub struct SweepArgs {
    /// The plan (TOML; see host/SWEEP.md). Not needed with --resume (the run keeps its copy,
    /// RUN_DIR/plan.toml); given with --resume, it may differ from the run's plan only in the
    /// keys an edit of RUN_DIR/plan.toml may change (timeouts, retries, heartbeat, reconnection
    /// timing), and then replaces RUN_DIR/plan.toml.
    #[arg(long, value_name = "PLAN.toml")]
    pub plan: Option<PathBuf>,
    /// Run directory to create (data.csv, journal.jsonl, manifest.json, plan.toml).
    #[arg(long, value_name = "RUN_DIR", conflicts_with = "resume")]
    pub out: Option<PathBuf>,
    /// Continue the run in RUN_DIR exactly where it stopped.
    #[arg(long, value_name = "RUN_DIR")]
    pub resume: Option<PathBuf>,
    /// Overwrite an existing, non-empty --out directory.
    #[arg(long)]
    pub force: bool,
    /// Serial port of the beacon board (e.g. /dev/ttyUSB0; macOS /dev/cu.usbserial-...; Windows
    /// COM3). With --sensor: real hardware.
    #[arg(long, value_name = "PORT", requires = "sensor")]
    pub beacon: Option<String>,
    /// Serial port of the sensor board (e.g. /dev/ttyUSB1; macOS /dev/cu.usbserial-...; Windows
    /// COM4).
    #[arg(long, value_name = "PORT", requires = "beacon")]
    pub sensor: Option<String>,
    /// Use the simulated CTA (the default when no ports are given).
    #[arg(long, conflicts_with_all = ["beacon", "sensor"])]
    pub sim: bool,
    /// Simulated CTA: noise of a strong signal, counts 1-sigma (grows as the signal weakens);
    /// default 10, and on --resume the run's own.
    #[arg(long, value_name = "COUNTS")]
    pub sim_noise: Option<f64>,
    /// Simulated CTA: spot magnitude noise, percent of the magnitude (1-sigma, 0-25); default
    /// 0, and on --resume the run's own. The NorthStar's real figure is unmeasured: a what-if
    /// for `cta noise` -> `cta sensor floor --magnitude-noise`.
    #[arg(long, value_name = "PERCENT")]
    pub sim_magnitude_noise: Option<f64>,
    /// Simulated CTA: scatter of the LEDs' brightness, percent (0-50; each LED of the array
    /// drawn once, log-normal, multiplying its magnitudes; the truth records the factors);
    /// default 0, and on --resume the run's own. What `cta calibrate` measures back.
    #[arg(long, value_name = "PERCENT")]
    pub sim_led_brightness: Option<f64>,
    /// Simulated CTA: inject an effect of the analysis vocabulary (repeatable), e.g.
    /// `beacon_tilt=2,45`, `plate_offset=0.05`, `cell_gain=0.03`.
    #[arg(long, value_name = "NAME=VALUE")]
    pub sim_effect: Vec<String>,
    /// Simulated CTA: random seed (noise, geometry draws); default 1, and on --resume the
    /// run's own.
    #[arg(long, value_name = "N")]
    pub sim_seed: Option<u64>,
    /// Simulated CTA: run the simulated NorthStar at the plan's rate (10 Hz, as the real
    /// sensor) and honour settle times, instead of unthrottled. Journalled: a resume keeps the
    /// mode the last session ran in (--sim-realtime or --sim-unthrottled change it, with a note).
    #[arg(long, conflicts_with = "sim_unthrottled")]
    pub sim_realtime: bool,
    /// Simulated CTA, with --resume: run unthrottled although the last session ran with
    /// --sim-realtime (the data are the same either way).
    #[arg(long, requires = "resume")]
    pub sim_unthrottled: bool,
    /// Simulated CTA: inject faults (testing): `drop=P`, `corrupt=P` (per byte, both lines,
    /// P at most 0.005), `stray=P` (a NorthStar frame carries a spot under an ID no LED is
    /// lit at, with probability P), `vanish=BOARD@N:MS` (unplugged), `silent=BOARD@N:MS`, `stall=sensor@N:MS`, triggered at
    /// the N-th point attempt of the session, and `reset=BOARD@N` (the board restarts, its
    /// port staying up: the beacon as the N-th attempt starts, the sensor as it ends),
    /// comma-separated.
    #[arg(long, value_name = "SPEC")]
    pub sim_fault: Option<String>,
    /// Do not ask: separations are the plan's nominal values (recorded as not measured),
    /// power switches assumed set. For scripted runs.
    #[arg(long, short = 'y')]
    pub yes: bool,
    /// No progress bars, and no log lines when stderr is not a terminal (the summary is still
    /// printed): the global `--quiet`.
    #[arg(skip)]
    pub quiet: bool,
    /// Do not fsync the data and journal (by default synced after each point, grouped to at
    /// most one sync every 250 ms); faster: a power cut may then lose the last points, a killed
    /// process still loses nothing.
    #[arg(long)]
    pub no_sync: bool,
    /// With --resume, when RUN_DIR/data.csv was cut short (it holds fewer bytes than the
    /// journal committed): resume from the last point it still holds whole, once its bytes and
    /// every earlier point's are checked against the hashes journalled with them. The journal
    /// lines after that point and the bytes past it are moved to RUN_DIR/recovered-N/, and
    /// the points after it are measured again. Refused when the bytes left are not what was
    /// written.
    #[arg(long, requires = "resume")]
    pub recover_truncated: bool,
    /// Say how far the run in RUN_DIR has got, without changing anything (no lock, no cut, no
    /// write; also while another `cta sweep` is running it): points done of all, per
    /// separation, the last commit, sessions, faults, whether it is complete, running or
    /// stopped, and the command that continues it.
    #[arg(
        long,
        value_name = "RUN_DIR",
        conflicts_with_all = [
            "out", "resume", "plan", "beacon", "sensor", "sim", "force", "yes", "sim_noise",
            "sim_magnitude_noise", "sim_led_brightness", "sim_effect", "sim_seed", "sim_realtime", "sim_unthrottled",
            "sim_fault", "no_sync", "recover_truncated"
        ]
    )]
    pub status: Option<PathBuf>,
    /// With --status: JSON instead of the table.
    #[arg(long, requires = "status")]
    pub json: bool,
    /// Say how long the plan (or, with --resume, the rest of the run) takes on the real boards
    /// at the plan's rate, settle times, plate moves and power switches included, and start
    /// nothing. The progress bar's ETA uses the same model, scaled by the pace it measures.
    #[arg(long, conflicts_with_all = ["out", "status", "beacon", "sensor", "force", "yes"])]
    pub estimate: bool,
    /// Minutes the operator takes to move the plate and read its four corners (for --estimate
    /// and the ETA).
    #[arg(long, value_name = "MIN", default_value_t = Steps::default().plate_move_s / 60.0)]
    pub plate_move_min: f64,
    /// Minutes the operator takes to flip the array's power switches.
    #[arg(long, value_name = "MIN", default_value_t = Steps::default().power_switch_s / 60.0)]
    pub power_switch_min: f64,
    /// Minutes the operator takes to mount the array in the next quadrant (quad layout).
    #[arg(long, value_name = "MIN", default_value_t = Steps::default().quadrant_s / 60.0)]
    pub quadrant_min: f64,
}

impl SweepArgs {
    /// The manual steps' durations given.
    pub fn steps(&self) -> Steps {
        Steps {
            plate_move_s: self.plate_move_min * 60.0,
            power_switch_s: self.power_switch_min * 60.0,
            quadrant_s: self.quadrant_min * 60.0,
        }
    }

    /// The run's options: everything but what only the command line shows.
    pub fn options(&self) -> SweepOptions {
        SweepOptions {
            plan: self.plan.clone(),
            out: self.out.clone(),
            resume: self.resume.clone(),
            force: self.force,
            beacon: self.beacon.clone(),
            sensor: self.sensor.clone(),
            sim_noise: self.sim_noise,
            sim_magnitude_noise: self.sim_magnitude_noise,
            sim_led_brightness: self.sim_led_brightness,
            sim_effect: self.sim_effect.clone(),
            sim_seed: self.sim_seed,
            sim_realtime: self.sim_realtime,
            sim_unthrottled: self.sim_unthrottled,
            sim_fault: self.sim_fault.clone(),
            yes: self.yes,
            no_sync: self.no_sync,
            recover_truncated: self.recover_truncated,
            command: std::env::args().collect(),
        }
    }
}

/// `cta sweep`.
pub fn run(args: &SweepArgs) -> Result<()> {
    if let Some(dir) = &args.status {
        let s = status::status(dir)?;
        if args.json {
            println!("{}", crate::json_with_provenance(&s.to_json(), &[])?);
        } else {
            print!("{}", s.render());
        }
        return Ok(());
    }
    if args.estimate {
        print!("{}", estimate_text(args)?);
        return Ok(());
    }
    for (sig, e) in crate::signals::catch_stop(&INTERRUPTED, Some(&SIGNAL)) {
        crate::say::warning(format_args!(
            "cannot catch signal {sig} ({e}): it would stop the sweep uncleanly"
        ));
    }
    let s = sweep(args)?;
    print_summary(&s);
    match &s.ending {
        Ending::Complete => Ok(()),
        Ending::GaveUp(what) => bail!(
            "a board stayed unreachable ({what}); the run is saved: continue with `{}`",
            s.resume
        ),
        // Not a success: `cta sweep ... && cta fit ...` must not go on with partial data.
        Ending::Interrupted => Err(Interrupted {
            signal: interruption(),
            exit_code: 128 + interruption_signal(),
            dir: s.dir.clone(),
            resume: s.resume.clone(),
            next_point: s.next_point,
            points: s.points,
        }
        .into()),
    }
}

/// Run (or resume) the sweep with progress bars (or log lines) on stderr and the operator
/// asked on the terminal.
pub fn sweep(args: &SweepArgs) -> Result<Summary> {
    let bars = Bars::new(args.quiet, args.steps());
    let mut prompt = Prompt::new(&bars);
    let r = cta_lab::sweep::sweep_with(&args.options(), &bars, Some(&mut prompt));
    bars.finish();
    Ok(r?)
}

/// The error [`run`] returns when Ctrl-C (or SIGTERM, SIGHUP) stopped the sweep: the run is
/// saved and resumable but incomplete, so the command must not exit with success. The binary
/// exits with its [`Interrupted::exit_code`] ([`crate::exit_on_error`]), otherwise with its generic
/// error status.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "interrupted ({signal}) with {next_point} of {points} points done (next: point \
     {next_point}); the run is saved: continue with `{resume}`"
)]
pub struct Interrupted {
    /// What stopped it: `Ctrl-C`, `SIGTERM` or `SIGHUP`.
    pub signal: &'static str,
    /// Exit status: 128 + the signal's number, the shell's convention for a command a signal
    /// stopped (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP), so a script can tell them apart; the
    /// sweep stopped itself cleanly, it was not killed.
    pub exit_code: i32,
    /// The run directory.
    pub dir: PathBuf,
    /// The command that continues the run ([`Summary::resume`]).
    pub resume: String,
    /// Next point to measure (its index, from 0; also the number of points done).
    pub next_point: usize,
    /// Points in the plan.
    pub points: usize,
}

/// `cta sweep --estimate`: the duration of the plan given, or of the rest of the run resumed.
fn estimate_text(args: &SweepArgs) -> Result<String> {
    let steps = args.steps();
    for (name, v) in [
        ("--plate-move-min", args.plate_move_min),
        ("--power-switch-min", args.power_switch_min),
        ("--quadrant-min", args.quadrant_min),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            bail!("{name} {v}: give the minutes the step takes, 0 or more");
        }
    }
    let (plan, from, what) = match (&args.resume, &args.plan) {
        (Some(dir), _) => {
            let st = status::status(dir)?;
            let plan = Plan::load(&dir.join(store::PLAN))?;
            (plan, st.done, format!("the rest of {}", dir.display()))
        }
        (None, Some(p)) => (Plan::load(p)?, 0, format!("plan {}", p.display())),
        (None, None) => bail!("--estimate needs --plan PLAN.toml, or --resume RUN_DIR"),
    };
    let e = estimate::estimate(&plan, from, &steps);
    let lit = if plan.group > 1 {
        format!("up to {} beacons lit at once", plan.group)
    } else {
        "one beacon at a time".into()
    };
    Ok(format!(
        "{what} (`{}`): {} points, {lit}, {} samples, at {} Hz\n  \
         measuring: {} ({:.2} s a point: {} ms settle, {} reports, requests)\n  \
         manual steps: {} ({} plate moves at {} min, {} power switch changes at {} min{})\n  \
         total on the real boards: {}\n",
        plan.name,
        e.points,
        e.samples,
        plan.rate_hz,
        estimate::human(e.measuring_s),
        e.point_s,
        plan.settle_ms,
        plan.samples + 1,
        estimate::human(e.manual_s),
        e.plate_moves,
        args.plate_move_min,
        e.power_switches,
        args.power_switch_min,
        if e.quadrant_mounts > 0 {
            format!(
                ", {} array mounts at {} min",
                e.quadrant_mounts, args.quadrant_min
            )
        } else {
            String::new()
        },
        estimate::human(e.total_s)
    ))
}

fn print_summary(s: &Summary) {
    let st = &s.stats;
    if s.already_complete {
        println!(
            "sweep {}: already complete: {}; nothing to measure, no board was opened",
            s.dir.display(),
            points_done(s.next_point, s.points)
        );
        println!("  data: {}", s.dir.join(store::DATA).display());
        return;
    }
    let state = match &s.ending {
        Ending::Complete => "complete".to_string(),
        Ending::Interrupted => format!(
            "interrupted by {} with {} (continue with `{}`)",
            interruption(),
            points_done(s.next_point, s.points),
            s.resume
        ),
        Ending::GaveUp(_) => format!(
            "stopped with {}: a board stayed unreachable",
            points_done(s.next_point, s.points)
        ),
    };
    println!("sweep {}: {state}", s.dir.display());
    println!(
        "  points this session: {} ({} ok, {} no signal, {} partial); run: {}/{}",
        st.ok + st.no_signal + st.partial,
        st.ok,
        st.no_signal,
        st.partial,
        s.next_point,
        s.points
    );
    let (b_ok, b_none, b_part) = st.beacons;
    if b_ok + b_none + b_part != st.ok + st.no_signal + st.partial {
        println!(
            "  beacons measured in them: {} ({b_ok} with all their samples, {b_none} no signal, \
             {b_part} partial)",
            b_ok + b_none + b_part
        );
    }
    println!(
        "  samples: {}   faults: {}   retries: {}   reconnections: {}   lost reports: {}",
        st.samples, st.faults, st.retries, st.reconnects, st.lost_reports
    );
    println!(
        "  time: {:.1} s ({:.0} samples/s)   data: {}",
        s.seconds,
        st.samples as f64 / s.seconds.max(1e-9),
        s.dir.join(store::DATA).display()
    );
    if let Some(c) = &s.crosstalk {
        println!("  {} (this session)", c.summary());
    }
}
