//! `cta sweep`: autonomous CTA data collection over serial, resumable, with a simulated CTA
//! (thesis Ch IV "autonomy in data collection", Ch VI data-collection scheme).
//!
//! * [`plan`]: the plan file (TOML), validated with errors naming file, line and key.
//! * [`engine`]: the run: both boards over the shared wire protocol ([`crate::boards::link`]),
//!   operator prompts, faults, retries with backoff, progress bars.
//! * [`corners`]: the plate's tilt from the operator's corner readings.
//! * [`store`]: the run directory: measurement CSV appended and synced per point, journal,
//!   manifest, exact resume.
//! * [`sim`]: the simulated CTA (both boards' firmware logic behind pseudo-terminals,
//!   coupled through the core emulator), with fault injection.
//!
//! The user documentation is `host/SWEEP.md`.

use crate::data::{Dataset, ReadError};

pub mod corners;
pub mod engine;
pub mod plan;
pub mod sim;
pub mod status;
pub mod store;

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde_json::json;

use engine::{
    interruption, interruption_signal, Bars, Ending, Engine, Operator, Prompt, Scripted,
    SimOperator, INTERRUPTED, SIGNAL,
};
use plan::Plan;
use sim::{Faults, SimCta, SimSettings};
use store::{now, Event, PointStatus, RunDir};

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
    /// Serial port of the beacon board (e.g. /dev/ttyUSB0). With --sensor: real hardware.
    #[arg(long, value_name = "PORT", requires = "sensor")]
    pub beacon: Option<String>,
    /// Serial port of the sensor board (e.g. /dev/ttyUSB1).
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
    /// Simulated CTA: inject faults (testing): `drop=P`, `corrupt=P` (per byte, both lines),
    /// `vanish=BOARD@N:MS` (unplugged), `silent=BOARD@N:MS`, `stall=sensor@N:MS`, triggered at
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
    /// printed).
    #[arg(long, short = 'q')]
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
            "sim_fault", "quiet", "no_sync", "recover_truncated"
        ]
    )]
    pub status: Option<PathBuf>,
    /// With --status: JSON instead of the table.
    #[arg(long, requires = "status")]
    pub json: bool,
}

/// What a finished session did (for tests and callers).
#[derive(Debug, Clone)]
pub struct Summary {
    /// The run directory.
    pub dir: PathBuf,
    /// How the session ended.
    pub ending: Ending,
    /// Session counters.
    pub stats: engine::Stats,
    /// Next point to measure (the plan's length when complete).
    pub next_point: usize,
    /// Points in the plan.
    pub points: usize,
    /// Session wall time, s.
    pub seconds: f64,
    /// The command that continues the run: `cta sweep --resume RUN_DIR`, with the ports
    /// (`--beacon P --sensor P`) when the run is on hardware ([`resume_command`]).
    pub resume: String,
    /// A resume that found every point committed: nothing was measured and no board opened.
    pub already_complete: bool,
}

/// `cta sweep`.
pub fn run(args: &SweepArgs) -> Result<()> {
    if let Some(dir) = &args.status {
        return status::run(dir, args.json);
    }
    catch_stop_signals();
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

/// Catch SIGINT (Ctrl-C), SIGTERM (`kill`, systemd, `docker stop`) and SIGHUP (a closed
/// terminal or SSH session) with `signal_hook`'s flag handlers: the first asks the run to stop
/// cleanly (LEDs off, sensor idle, the stop journalled; [`SIGNAL`] says which), a second one
/// leaves at once with 128 + the signal (everything committed is on disk). A signal ignored
/// when the sweep started stays ignored: under `nohup` a hang-up does not stop the run.
fn catch_stop_signals() {
    use signal_hook::flag;
    for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
        if ignored(sig) {
            continue;
        }
        // In this order: the second signal finds the flag set and exits; the first sets it.
        let registered =
            flag::register_conditional_shutdown(sig, 128 + sig, Arc::clone(&INTERRUPTED))
                .and_then(|_| flag::register_usize(sig, Arc::clone(&SIGNAL), sig as usize))
                .and_then(|_| flag::register(sig, Arc::clone(&INTERRUPTED)));
        if let Err(e) = registered {
            eprintln!(
                "warning: cannot catch signal {sig} ({e}): it would stop the sweep uncleanly"
            );
        }
    }
}

/// Whether `sig` is ignored (SIG_IGN), as `nohup` leaves SIGHUP.
pub(crate) fn ignored(sig: libc::c_int) -> bool {
    // SAFETY: a read-only sigaction query into a zeroed struct.
    unsafe {
        let mut old: libc::sigaction = std::mem::zeroed();
        libc::sigaction(sig, std::ptr::null(), &mut old) == 0 && old.sa_sigaction == libc::SIG_IGN
    }
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

/// `N of M points done (next: point N)`: how far a run has got. Points are numbered from 0,
/// as in the journal (`i`, `next_point`), the log (`fault at point 9`) and data.csv's
/// comments, so the next point's index is the number done.
pub fn points_done(next: usize, points: usize) -> String {
    if next >= points {
        format!("all {points} points done")
    } else {
        format!("{next} of {points} points done (next: point {next})")
    }
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
}

/// Run (or resume) a sweep; returns the session summary. [`run`] is this plus the Ctrl-C
/// handler and the printed summary.
pub fn sweep(args: &SweepArgs) -> Result<Summary> {
    INTERRUPTED.store(false, Ordering::SeqCst);
    SIGNAL.store(0, Ordering::SeqCst);
    if let (Some(b), Some(s)) = (&args.beacon, &args.sensor) {
        two_ports(b, s)?;
    }
    let t0 = Instant::now();
    let sync = !args.no_sync;
    let command: Vec<String> = std::env::args().collect();

    // The run directory, the plan, and what simulates it.
    let (store, plan, sim_settings) = if let Some(dir) = &args.resume {
        let plan_path = dir.join(store::PLAN);
        run_dir_given(dir, "--resume")?;
        // The run's own plan.toml, or the plan file given: checked the same way against the
        // plan the last session ran with (only timing may change); a given file then becomes
        // the run's plan.toml.
        let recover = args.recover_truncated;
        let store = match &args.plan {
            None => {
                let plan = Plan::load(&plan_path)?;
                RunDir::resume_recovering(dir, sync, &plan, None, recover).map(|s| (s, plan))
            }
            Some(p) => {
                let text = read_plan(p)?;
                let plan = Plan::parse(&p.display().to_string(), &text)?;
                let given = store::GivenPlan {
                    path: p,
                    text: &text,
                };
                RunDir::resume_recovering(dir, sync, &plan, Some(given), recover).map(|s| (s, plan))
            }
        };
        let (mut store, plan) = store?;
        // Every point committed: nothing to measure, so no board is opened (a hardware run
        // needs no ports for it).
        if store.next_point() >= plan.len() {
            return already_complete(store, &plan, t0);
        }
        let first_sim = store.events.iter().find_map(|e| match e {
            Event::Session { sim, .. } => Some(sim.clone()),
            _ => None,
        });
        let sim = match first_sim {
            Some(Some(v)) => {
                if args.beacon.is_some() {
                    bail!(
                        "{} was recorded on the simulated CTA: resume it without --beacon/--sensor",
                        dir.display()
                    );
                }
                let mut s: SimSettings =
                    serde_json::from_value(v).context("journal: unreadable simulation settings")?;
                let differs = args.sim_seed.is_some_and(|x| x != s.seed)
                    || args.sim_noise.is_some_and(|x| x != s.noise)
                    || args
                        .sim_magnitude_noise
                        .is_some_and(|x| x != s.magnitude_noise)
                    || args
                        .sim_led_brightness
                        .is_some_and(|x| x != s.led_brightness)
                    || (!args.sim_effect.is_empty() && args.sim_effect != s.effects);
                if differs {
                    bail!(
                        "{} was simulated with seed {}, noise {}, magnitude noise {} %, LED \
                         brightness scatter {} %, effects {:?}; a resume simulates the same \
                         (leave out --sim-seed/--sim-noise/--sim-magnitude-noise/\
                         --sim-led-brightness/--sim-effect)",
                        dir.display(),
                        s.seed,
                        s.noise,
                        s.magnitude_noise,
                        s.led_brightness,
                        s.effects
                    );
                }
                // Real time or unthrottled: as the last session ran (journalled with its
                // simulation settings), unless this resume asks otherwise; said either way
                // when it changes. The data are the same in both.
                let was = store
                    .events
                    .iter()
                    .rev()
                    .find_map(|e| match e {
                        Event::Session { sim: Some(v), .. } => v["realtime"].as_bool(),
                        _ => None,
                    })
                    .unwrap_or(s.realtime);
                s.realtime = if args.sim_unthrottled {
                    false
                } else {
                    args.sim_realtime || was
                };
                if s.realtime != was {
                    store.notes.push(if s.realtime {
                        "simulated in real time from this session on (--sim-realtime: the \
                         NorthStar at the plan's rate_hz, settle times honoured); the last session \
                         ran unthrottled. The data are the same either way"
                            .to_string()
                    } else {
                        "simulated unthrottled from this session on (--sim-unthrottled); the \
                         last session ran in real time (--sim-realtime). The data are the same \
                         either way"
                            .to_string()
                    });
                }
                s.faults = parse_faults(args)?;
                Some(s)
            }
            Some(None) => {
                if args.sim_unthrottled {
                    bail!("--sim-unthrottled applies to a run on the simulated CTA; {} was recorded on ports", dir.display());
                }
                if args.beacon.is_none() {
                    bail!("{}", ports_needed(&store));
                }
                None
            }
            None => sim_settings(args)?,
        };
        (Ok(store), plan, sim)
    } else {
        let Some(out) = &args.out else {
            bail!(
                "give --out RUN_DIR for a new run, --resume RUN_DIR to continue one, or \
                 --status RUN_DIR to see how far one has got"
            );
        };
        let Some(plan_path) = &args.plan else {
            bail!("give --plan PLAN.toml (see host/plans/ and host/SWEEP.md)");
        };
        let src = read_plan(plan_path)?;
        let plan = Plan::parse(&plan_path.display().to_string(), &src)?;
        let sim = sim_settings(args)?;
        // The data file's header, but for what the run is on (known once the boards answered).
        let title = format!(
            "cta {} sweep: plan `{}` ({})",
            env!("CARGO_PKG_VERSION"),
            plan.name,
            plan_path.display()
        );
        // Refuse an existing directory now; create it once both boards answered.
        RunDir::check_new(out, args.force)?;
        (Err((out.clone(), src, title)), plan, sim)
    };

    // The boards.
    let sim = match &sim_settings {
        Some(s) => Some(SimCta::spawn(&plan, s)?),
        None => None,
    };
    let (beacon_path, sensor_path) = match &sim {
        Some(s) => (
            s.beacon_path().display().to_string(),
            s.sensor_path().display().to_string(),
        ),
        None => (
            args.beacon.clone().unwrap_or_default(),
            args.sensor.clone().unwrap_or_default(),
        ),
    };
    let mut engine = Engine::new(&plan, &beacon_path, &sensor_path);
    engine.skip_settle = sim_settings.as_ref().is_some_and(|s| !s.realtime);
    let (bid, sid) = engine.connect()?;
    let on = apparatus(sim.is_some(), bid.simulated, sid.simulated);
    // A hardware run is resumed on its ports: the hints say them.
    let ports = sim
        .is_none()
        .then_some((beacon_path.as_str(), sensor_path.as_str()));
    let mut store = match store {
        Ok(mut s) => {
            // Only now, with the boards known, does the resume change the run directory.
            same_apparatus(
                &s,
                sim.is_some(),
                (&bid, &beacon_path),
                (&sid, &sensor_path),
            )?;
            s.begin()?;
            s
        }
        Err((out, src, title)) => {
            let header = [
                title,
                format!("{} points x {} samples; {on}", plan.len(), plan.samples),
                "no-signal and partial points are recorded as comment lines; see journal.jsonl"
                    .into(),
            ];
            RunDir::create(&out, &src, &header, args.force, sync)?
        }
    };
    for note in &store.notes {
        eprintln!("cta: note: {}: {note}", store.dir.display());
    }
    let from = store.next_point();
    let n = store.sessions() + 1;
    store.log(Event::Session {
        n,
        at: now(),
        software: format!("cta {}", env!("CARGO_PKG_VERSION")),
        command,
        boards: json!({ "beacon": beacon_json(&bid, &beacon_path, &engine.table_mhz), "sensor": identity_json(&sid, &sensor_path) }),
        sim: sim_settings.as_ref().map(|s| serde_json::to_value(s).unwrap_or_default()),
        plan: Some(serde_json::to_value(&plan)?),
        from_point: from,
        notes: store.notes.clone(),
    })?;
    // From here on, whatever fails (a full disk, a read-only file, a board refusing) is
    // recorded as the session's stop, as far as the disk allows, before the error is returned.
    let bars = Bars::new(args.quiet);
    let result = (|| -> Result<Ending> {
        if let Some(s) = &sim {
            let path = store.dir.join(store::TRUTH);
            std::fs::write(&path, serde_json::to_string_pretty(&s.truth())?)
                .with_context(|| format!("{}: cannot write", path.display()))?;
        }
        write_manifest(&store, &plan, "running")?;
        let mut operator: Box<dyn Operator + '_> = match &sim {
            Some(s) => Box::new(SimOperator(s)),
            None if args.yes => Box::new(Scripted),
            None => Box::new(Prompt::new(&bars)),
        };
        bars.log(&format!(
            "sweep {}: plan `{}`, {} points ({} per separation), {} on the {}{}",
            store.dir.display(),
            plan.name,
            plan.len(),
            plan.per_separation(),
            if from == 0 {
                "starting".to_string()
            } else {
                format!("resuming at point {from} ({from} of {} done)", plan.len())
            },
            on,
            match &sim_settings {
                Some(s) if s.realtime => " (in real time: --sim-realtime)",
                _ => "",
            },
        ));
        engine.run(&mut store, operator.as_mut(), from, &bars)
    })();
    bars.finish();
    let ending = match result {
        Ok(ending) => ending,
        Err(e) => {
            let recorded = store.stop_after_failure(format!("error: {e:#}"));
            if let Err(w) = recorded.and_then(|_| write_manifest(&store, &plan, "stopped")) {
                eprintln!("cta: warning: the stop could not be recorded in full: {w:#}");
            }
            return Err(e.context(format!(
                "sweep stopped with {}; the run is saved: continue with `{}`",
                points_done(store.next_point(), plan.len()),
                resume_command(&store.dir, ports)
            )));
        }
    };
    let next = store.next_point();
    let reason = match &ending {
        Ending::Complete => "complete".to_string(),
        Ending::Interrupted => format!("interrupted ({})", interruption()),
        Ending::GaveUp(w) => format!("gave up: {w}"),
    };
    store.log(Event::Stop {
        at: now(),
        reason: reason.clone(),
        next_point: next,
        notes: Vec::new(),
    })?;
    write_manifest(
        &store,
        &plan,
        if ending == Ending::Complete {
            "complete"
        } else {
            "stopped"
        },
    )?;
    bars.log(&format!("stopped: {reason}; {next}/{} points", plan.len()));
    Ok(Summary {
        dir: store.dir.clone(),
        ending,
        stats: engine.stats,
        next_point: next,
        points: plan.len(),
        seconds: t0.elapsed().as_secs_f64(),
        resume: resume_command(&store.dir, ports),
        already_complete: false,
    })
}

/// The plan file given with `--plan`, read: a folder or an unreadable file is named as such.
fn read_plan(path: &Path) -> Result<String> {
    if path.is_dir() {
        bail!(
            "{}: is a folder: --plan takes a plan file (TOML, e.g. host/plans/short.toml; see \
             host/SWEEP.md)",
            path.display()
        );
    }
    std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read the plan", path.display()))
}

/// The run directory given to `option` (`--resume`, `--status`) must be one: a path that does
/// not exist, a file (perhaps a file of a run: its folder is named) and a folder without a
/// run's files are each said as such.
pub(crate) fn run_dir_given(dir: &Path, option: &str) -> Result<()> {
    let start = "a run is started with `cta sweep --plan PLAN.toml --out RUN_DIR`";
    match std::fs::metadata(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => bail!(
            "{}: does not exist: there is no run there ({option} takes the folder a run was \
             started in with --out; {start})",
            dir.display()
        ),
        Err(e) => bail!("{}: cannot read: {e}", dir.display()),
        Ok(m) if !m.is_dir() => {
            let parent = match dir.parent() {
                Some(p) if p.as_os_str().is_empty() => Path::new("."),
                Some(p) => p,
                None => Path::new("/"),
            };
            let in_a_run = parent.join(store::JOURNAL).exists();
            bail!(
                "{}: is a file, not a run directory: {option} takes the folder a run was started \
                 in with --out{}",
                dir.display(),
                if in_a_run {
                    format!(
                        "; this file is in the run {}: `cta sweep {option} {}`",
                        parent.display(),
                        shell_word(&parent.display().to_string())
                    )
                } else {
                    format!(" ({start})")
                }
            )
        }
        Ok(_) => {
            if !dir.join(store::PLAN).exists() && !dir.join(store::JOURNAL).exists() {
                bail!(
                    "{}: not a sweep run directory (no {} or {}); {start}",
                    dir.display(),
                    store::PLAN,
                    store::JOURNAL
                );
            }
            Ok(())
        }
    }
}

/// A resume of a run whose every point is committed: nothing is measured and no board is
/// opened. A run whose journal already ends with its complete stop is left as it is. Otherwise
/// (the last session was killed between its last point and its stop, or the resume found
/// something to cut: bytes appended to data.csv since, a torn journal line; or a --plan to
/// take in) the resume makes those changes as any resume does ([`RunDir::begin`]), says them,
/// and journals the complete stop with them as its `notes`; the manifest says `complete`.
fn already_complete(mut store: RunDir, plan: &Plan, t0: Instant) -> Result<Summary> {
    let recorded =
        matches!(store.events.last(), Some(Event::Stop { reason, .. }) if reason == "complete");
    if !recorded || !store.notes.is_empty() {
        store.begin()?;
        for note in &store.notes {
            eprintln!("cta: note: {}: {note}", store.dir.display());
        }
        store.log(Event::Stop {
            at: now(),
            reason: "complete".into(),
            next_point: store.next_point(),
            notes: store.notes.clone(),
        })?;
        write_manifest(&store, plan, "complete")?;
    }
    let ports = last_ports(&store);
    Ok(Summary {
        dir: store.dir.clone(),
        ending: Ending::Complete,
        stats: engine::Stats::default(),
        next_point: store.next_point(),
        points: plan.len(),
        seconds: t0.elapsed().as_secs_f64(),
        resume: resume_command(
            &store.dir,
            ports.as_ref().map(|(b, s)| (b.as_str(), s.as_str())),
        ),
        already_complete: true,
    })
}

/// The ports of the last session, when the run is on ports (not the simulated CTA of
/// `--sim`), from the journal.
pub(crate) fn last_ports(store: &RunDir) -> Option<(String, String)> {
    last_session_ports(&store.events)
}

/// [`last_ports`] of a journal's events.
pub(crate) fn last_session_ports(events: &[Event]) -> Option<(String, String)> {
    events.iter().rev().find_map(|e| match e {
        Event::Session {
            sim: None, boards, ..
        } => {
            let port = |b: &str| boards[b]["port"].as_str().map(String::from);
            Some((port("beacon")?, port("sensor")?))
        }
        _ => None,
    })
}

/// Why a run on ports cannot be resumed without them: the boards it was recorded on (hardware,
/// or simulated boards served with `cta beacon sim` / `cta sensor sim`, as each said of itself)
/// and the ports its last session used.
fn ports_needed(store: &RunDir) -> String {
    let boards = store.events.iter().find_map(|e| match e {
        Event::Session { boards, .. } => Some(boards),
        _ => None,
    });
    let simulated = |b: &str| boards.and_then(|v| v[b]["simulated"].as_bool());
    let kind = match (simulated("beacon"), simulated("sensor")) {
        (Some(b), Some(s)) => apparatus(false, b, s),
        _ => "boards",
    };
    let pty = simulated("beacon") == Some(true) || simulated("sensor") == Some(true);
    match last_ports(store) {
        Some((b, s)) => format!(
            "{}: the run was recorded on {kind} at ports (beacon board on {b}, sensor board on \
             {s}), not on the simulated CTA of --sim: give --beacon and --sensor to resume it, \
             as its last session did: `{}`{}",
            store.dir.display(),
            resume_command(&store.dir, Some((&b, &s))),
            if pty {
                " (a board served by `cta beacon sim` / `cta sensor sim` must be served again; \
                 its port may have another name now)"
            } else {
                ""
            }
        ),
        None => format!(
            "{}: the run was recorded on {kind} at ports, not on the simulated CTA of --sim: \
             give --beacon and --sensor to resume it",
            store.dir.display()
        ),
    }
}

/// `--beacon` and `--sensor` must be two ports: the same path twice, or two names of one
/// device (a `/dev/serial/by-id/` link and the `/dev/ttyUSB` it points to), is refused before
/// anything is opened (the second open would only say the port is locked).
fn two_ports(beacon: &str, sensor: &str) -> Result<()> {
    if beacon == sensor {
        bail!(
            "--beacon and --sensor are the same port, {beacon}: each board has its own serial \
             port (e.g. --beacon /dev/ttyUSB0 --sensor /dev/ttyUSB1)"
        );
    }
    if let (Ok(b), Ok(s)) = (std::fs::canonicalize(beacon), std::fs::canonicalize(sensor)) {
        if b == s {
            bail!(
                "--beacon {beacon} and --sensor {sensor} are the same port, {}: each board has \
                 its own serial port",
                b.display()
            );
        }
    }
    Ok(())
}

/// What a session runs on, for the data file's header and the log: the simulated CTA of
/// `cta sweep --sim`, or the boards on the ports given, which are hardware or simulated
/// (`cta beacon sim`, `cta sensor sim`) as each board says of itself (`beacon_simulated`,
/// `sensor_simulated`).
pub(crate) fn apparatus(sim: bool, beacon_simulated: bool, sensor_simulated: bool) -> &'static str {
    match (sim, beacon_simulated, sensor_simulated) {
        (true, _, _) => "simulated CTA",
        (false, true, true) => "simulated beacon and sensor boards",
        (false, true, false) => "CTA hardware with a simulated beacon board",
        (false, false, true) => "CTA hardware with a simulated sensor board",
        (false, false, false) => "CTA hardware",
    }
}

/// A resumed run continues on the kind of apparatus it was recorded on ([`apparatus`]): the
/// data file's header, written by the first session, says what the data come from, and every
/// later session's points go under it. Boards that answer as another kind (a run started on
/// `cta beacon sim` / `cta sensor sim` resumed on the real boards, hardware resumed with a
/// simulated board standing in, another mix) are refused, naming both, before the resume
/// changes anything. The first session's boards are read from the journal (`simulated` of
/// each board); a journal without them is not checked.
fn same_apparatus(
    store: &RunDir,
    sim: bool,
    (beacon, beacon_port): (&cta_core::wire::Identity, &str),
    (sensor, sensor_port): (&cta_core::wire::Identity, &str),
) -> Result<()> {
    let Some((first_sim, boards)) = store.events.iter().find_map(|e| match e {
        Event::Session { sim, boards, .. } => Some((sim.is_some(), boards)),
        _ => None,
    }) else {
        return Ok(());
    };
    let simulated = |b: &str| boards[b]["simulated"].as_bool();
    let (Some(was_beacon), Some(was_sensor)) = (simulated("beacon"), simulated("sensor")) else {
        return Ok(());
    };
    let was = apparatus(first_sim, was_beacon, was_sensor);
    let now = apparatus(sim, beacon.simulated, sensor.simulated);
    if was == now {
        return Ok(());
    }
    let kind = |simulated: bool| if simulated { "simulated" } else { "hardware" };
    let port = |b: &str| boards[b]["port"].as_str().unwrap_or("?").to_string();
    bail!(
        "{}: the run was recorded on {was} (its first session in {}: beacon board on {}: {}, \
         sensor board on {}: {}), but the boards answering now are {now} (beacon board on \
         {beacon_port}: {}, sensor board on {sensor_port}: {}): {} would hold points of both \
         under one header. Not resuming, nothing was changed: resume the run on {was} again, \
         or start a new run with --out for these boards",
        store.dir.display(),
        store::JOURNAL,
        port("beacon"),
        kind(was_beacon),
        port("sensor"),
        kind(was_sensor),
        kind(beacon.simulated),
        kind(sensor.simulated),
        store::DATA,
    );
}

fn parse_faults(args: &SweepArgs) -> Result<Faults> {
    match &args.sim_fault {
        Some(s) => Faults::parse(s).map_err(|e| anyhow::anyhow!("--sim-fault: {e}")),
        None => Ok(Faults::default()),
    }
}

fn sim_settings(args: &SweepArgs) -> Result<Option<SimSettings>> {
    if args.beacon.is_some() {
        let sim_only = args.sim_noise.is_some()
            || args.sim_magnitude_noise.is_some()
            || args.sim_led_brightness.is_some()
            || !args.sim_effect.is_empty()
            || args.sim_seed.is_some()
            || args.sim_realtime
            || args.sim_unthrottled
            || args.sim_fault.is_some();
        if sim_only {
            bail!("--sim-* options apply to the simulated CTA, not to --beacon/--sensor hardware");
        }
        return Ok(None);
    }
    let d = SimSettings::default();
    for e in &args.sim_effect {
        crate::sim::effects::Effect::parse(e)
            .map_err(|m| anyhow::anyhow!("--sim-effect {e}: {m}"))?;
    }
    Ok(Some(SimSettings {
        seed: args.sim_seed.unwrap_or(d.seed),
        noise: args.sim_noise.unwrap_or(d.noise),
        magnitude_noise: args.sim_magnitude_noise.unwrap_or(d.magnitude_noise),
        led_brightness: args.sim_led_brightness.unwrap_or(d.led_brightness),
        effects: args.sim_effect.clone(),
        realtime: args.sim_realtime,
        faults: parse_faults(args)?,
    }))
}

/// The command that continues the run in `dir`: `cta sweep --resume DIR`, and for a run on
/// hardware its ports, `--beacon P --sensor P` (a hardware run is refused without them).
/// Words a shell would split or expand are quoted.
pub fn resume_command(dir: &Path, ports: Option<(&str, &str)>) -> String {
    let mut c = format!(
        "cta sweep --resume {}",
        shell_word(&dir.display().to_string())
    );
    if let Some((b, s)) = ports {
        c += &format!(" --beacon {} --sensor {}", shell_word(b), shell_word(s));
    }
    c
}

/// `w` as one shell word: as it is when it is safe, else in single quotes.
fn shell_word(w: &str) -> String {
    let safe = |c: char| c.is_ascii_alphanumeric() || "/._-+:,=@%".contains(c);
    if !w.is_empty() && w.chars().all(safe) {
        w.to_string()
    } else {
        format!("'{}'", w.replace('\'', r"'\''"))
    }
}

/// The beacon board's identity and the frequency table the session lights from
/// (`table_hz`, entry by entry, as read and checked when the session connected).
fn beacon_json(id: &cta_core::wire::Identity, path: &str, table_mhz: &[u32]) -> serde_json::Value {
    let mut v = identity_json(id, path);
    let hz: Vec<f64> = table_mhz.iter().map(|&m| m as f64 / 1000.0).collect();
    v["table_hz"] = json!(hz);
    v
}

fn identity_json(id: &cta_core::wire::Identity, path: &str) -> serde_json::Value {
    json!({
        "port": path,
        "board": id.board.to_string(),
        "protocol": id.protocol,
        "firmware": id.firmware.as_str(),
        "simulated": id.simulated,
        "max_frame": id.max_frame,
    })
}

/// Rebuild `manifest.json` from the journal.
fn write_manifest(store: &RunDir, plan: &Plan, state: &str) -> Result<()> {
    let mut sessions = Vec::new();
    let mut operator = Vec::new();
    let mut faults = Vec::new();
    let (mut ok, mut no_signal, mut partial, mut samples) = (0u64, 0u64, 0u64, 0u64);
    for e in &store.events {
        match e {
            Event::Session { .. } | Event::Stop { .. } => sessions.push(serde_json::to_value(e)?),
            Event::Separation(_) | Event::Quadrant { .. } | Event::Power { .. } => {
                operator.push(serde_json::to_value(e)?)
            }
            Event::Fault { .. } => faults.push(serde_json::to_value(e)?),
            Event::Point {
                status, samples: n, ..
            } => {
                samples += *n as u64;
                match status {
                    PointStatus::Ok => ok += 1,
                    PointStatus::NoSignal => no_signal += 1,
                    PointStatus::Partial => partial += 1,
                }
            }
        }
    }
    // Why the last session stopped (null while one runs).
    let reason = match store.events.last() {
        Some(Event::Stop { reason, .. }) => Some(reason.clone()),
        _ => None,
    };
    let v = json!({
        "software": format!("cta {}", env!("CARGO_PKG_VERSION")),
        "state": state,
        "reason": reason,
        "updated": now(),
        "plan": plan,
        "points": { "total": plan.len(), "done": store.next_point(), "ok": ok, "no_signal": no_signal, "partial": partial },
        "samples": samples,
        "files": { "data": store::DATA, "journal": store::JOURNAL, "plan": store::PLAN },
        "sessions": sessions,
        "operator": operator,
        "faults": faults,
    });
    store.write_manifest(&v)
}

/// The run directory's measurement file.
pub fn data_path(dir: &Path) -> PathBuf {
    dir.join(store::DATA)
}

/// Read a measurement file with the warnings every analysis command prints on load
/// ([`Dataset::read_warned`]); a run directory given instead is refused, naming its data file.
pub fn read_measurements(path: &Path) -> Result<(Dataset, Vec<String>), ReadError> {
    Dataset::read_warned(path).map_err(|e| match e {
        ReadError::Folder { path, data: None } => {
            let data = data_path(&path);
            ReadError::Folder {
                data: data.is_file().then_some(data),
                path,
            }
        }
        e => e,
    })
}
