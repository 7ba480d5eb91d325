//! Autonomous CTA data collection over serial, resumable, with a simulated CTA (thesis Ch IV
//! "autonomy in data collection", Ch VI data-collection scheme).
//!
//! * [`plan`]: the plan file (TOML), validated with errors naming file, line and key.
//! * [`engine`]: the run: both boards over the shared wire protocol ([`crate::boards::link`]),
//!   the operator's manual steps, faults, retries with backoff.
//! * [`watch`]: what a running sweep reports to whoever shows its progress.
//! * [`error`]: why a sweep could not go on.
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
pub mod error;
pub mod estimate;
pub mod event;
pub mod groups;
mod journal;
pub mod layout;
pub mod metadata;
pub mod plan;
pub mod points;
mod pty;
pub mod signals;
pub mod sim;
pub mod stamp;
pub mod status;
pub mod store;
pub mod watch;

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::Instant;

use error::{bail, Context};
pub use error::{Error, Result};
use serde_json::json;

use engine::{interruption, Ending, Engine, Operator, Scripted, SimOperator, INTERRUPTED, SIGNAL};
use plan::Plan;
use sim::{Faults, SimCta, SimSettings};
use store::{now, Event, PointStatus, RunDir};
use watch::{Unwatched, Watch};

/// What a sweep session is asked to do: a new run or a resume, on which boards, and how the
/// simulated CTA behaves. The command line's `cta sweep` options, without the display ones.
#[derive(Debug, Clone, Default)]
pub struct SweepOptions {
    /// The plan file. With `resume` it may replace the run's plan.toml where only timing
    /// differs.
    pub plan: Option<PathBuf>,
    /// Run directory to create.
    pub out: Option<PathBuf>,
    /// Run directory to continue exactly where it stopped.
    pub resume: Option<PathBuf>,
    /// Overwrite an existing, non-empty `out`.
    pub force: bool,
    /// Serial port of the beacon board; with `sensor`, a run on hardware.
    pub beacon: Option<String>,
    /// Serial port of the sensor board.
    pub sensor: Option<String>,
    /// Simulated CTA: noise of a strong signal, counts 1-sigma.
    pub sim_noise: Option<f64>,
    /// Simulated CTA: spot magnitude noise, percent.
    pub sim_magnitude_noise: Option<f64>,
    /// Simulated CTA: LED brightness scatter, percent.
    pub sim_led_brightness: Option<f64>,
    /// Simulated CTA: effects of the analysis vocabulary (`NAME=VALUE`).
    pub sim_effect: Vec<String>,
    /// Simulated CTA: random seed.
    pub sim_seed: Option<u64>,
    /// Simulated CTA: run at the plan's rate and honour settle times.
    pub sim_realtime: bool,
    /// Simulated CTA, on a resume: run unthrottled although the last session did not.
    pub sim_unthrottled: bool,
    /// Simulated CTA: faults to inject ([`Faults::parse`]).
    pub sim_fault: Option<String>,
    /// Ask nothing: separations are the plan's nominal values, power switches assumed set.
    pub yes: bool,
    /// Do not fsync the data and journal.
    pub no_sync: bool,
    /// On a resume, recover a data.csv cut short ([`RunDir::resume_recovering`]).
    pub recover_truncated: bool,
    /// The command line that started the session, journalled with it.
    pub command: Vec<String>,
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
    /// The crosstalk check over the beacons measured alone and in their group in this session
    /// (`None` when it measured none; `cta noise RUN/data.csv` checks the whole run).
    pub crosstalk: Option<crate::crosstalk::Check>,
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

/// Run (or resume) a sweep, showing nothing and asking nothing: a run on hardware must be
/// scripted (`yes`). See [`sweep_with`].
pub fn sweep(args: &SweepOptions) -> Result<Summary> {
    sweep_with(args, &Unwatched, None)
}

/// Run (or resume) a sweep; returns the session summary. `watch` sees its progress, notes and
/// log; `prompt` is the operator asked for the manual steps of a run on hardware (plate moves,
/// quadrants, power switches) unless `yes`. The stop flag [`INTERRUPTED`] is cleared at the
/// start; whoever sets it (a signal handler) stops the run cleanly.
pub fn sweep_with(
    args: &SweepOptions,
    watch: &dyn Watch,
    prompt: Option<&mut dyn Operator>,
) -> Result<Summary> {
    INTERRUPTED.store(false, Ordering::SeqCst);
    SIGNAL.store(0, Ordering::SeqCst);
    if let (Some(b), Some(s)) = (&args.beacon, &args.sensor) {
        two_ports(b, s)?;
    }
    let t0 = Instant::now();
    let sync = !args.no_sync;
    let command = args.command.clone();

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
            return already_complete(store, &plan, t0, watch);
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
                if plan.one_at_a_time() {
                    format!("{} points x {} samples; {on}", plan.len(), plan.samples)
                } else {
                    format!(
                        "{} points of up to {} beacons lit at once, {} samples each; {on}",
                        plan.len(),
                        plan.group,
                        plan.samples
                    )
                },
                "no-signal and partial points are recorded as comment lines; see journal.jsonl"
                    .into(),
            ];
            RunDir::create(&out, &src, &header, args.force, sync)?
        }
    };
    for note in &store.notes {
        watch.note(&store.dir, note);
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
    let result = (|| -> Result<Ending> {
        if let Some(s) = &sim {
            let path = store.dir.join(store::TRUTH);
            std::fs::write(&path, serde_json::to_string_pretty(&s.truth())?)
                .with_context(|| format!("{}: cannot write", path.display()))?;
        }
        write_manifest(&store, &plan, "running")?;
        let mut scripted = Scripted;
        let mut simulated;
        let operator: &mut dyn Operator = match (&sim, prompt) {
            (Some(s), _) => {
                simulated = SimOperator(s);
                &mut simulated
            }
            (None, _) if args.yes => &mut scripted,
            (None, Some(p)) => p,
            (None, None) => bail!(
                "a run on hardware needs an operator for the plate moves and power switches, or \
                 --yes for a scripted run"
            ),
        };
        watch.log(&format!(
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
        engine.run_start = store
            .events
            .iter()
            .find_map(|e| match e {
                Event::Session { at, .. } => Some(*at),
                _ => None,
            })
            .unwrap_or_else(now);
        engine.run(&mut store, operator, from, watch)
    })();
    let ending = match result {
        Ok(ending) => ending,
        Err(e) => {
            let recorded = store.stop_after_failure(format!("error: {e:#}"));
            if let Err(w) = recorded.and_then(|_| write_manifest(&store, &plan, "stopped")) {
                watch.warning(&format!("the stop could not be recorded in full: {w:#}"));
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
    watch.log(&format!("stopped: {reason}; {next}/{} points", plan.len()));
    Ok(Summary {
        dir: store.dir.clone(),
        ending,
        stats: engine.stats,
        next_point: next,
        points: plan.len(),
        seconds: t0.elapsed().as_secs_f64(),
        resume: resume_command(&store.dir, ports),
        already_complete: false,
        crosstalk: crate::crosstalk::check_sums(&engine.checked),
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
    crate::bounded::read_text(path, crate::bounded::MAX_PLAN_BYTES, "a plan")
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
fn already_complete(
    mut store: RunDir,
    plan: &Plan,
    t0: Instant,
    watch: &dyn Watch,
) -> Result<Summary> {
    let recorded =
        matches!(store.events.last(), Some(Event::Stop { reason, .. }) if reason == "complete");
    if !recorded || !store.notes.is_empty() {
        store.begin()?;
        for note in &store.notes {
            watch.note(&store.dir, note);
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
        crosstalk: None,
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

fn parse_faults(args: &SweepOptions) -> Result<Faults> {
    match &args.sim_fault {
        Some(s) => Faults::parse(s).map_err(|e| Error::Refused(format!("--sim-fault: {e}"))),
        None => Ok(Faults::default()),
    }
}

fn sim_settings(args: &SweepOptions) -> Result<Option<SimSettings>> {
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
    let (_, others) = sim::take_spot_crosstalk(&args.sim_effect)?;
    for e in &others {
        crate::sim::effects::Effect::parse(e)
            .map_err(|m| Error::Refused(format!("--sim-effect {e}: {m}")))?;
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
    let updated = now();
    let v = json!({
        "software": format!("cta {}", env!("CARGO_PKG_VERSION")),
        "state": state,
        "reason": reason,
        "updated": updated,
        "updated_time": stamp::iso8601(updated),
        "plan": plan,
        // The plan's `[metadata]` as the last session ran under it (each session's own is in
        // its `plan` in `sessions`).
        "metadata": plan.metadata,
        "points": { "total": plan.len(), "done": store.next_point(), "ok": ok, "no_signal": no_signal, "partial": partial },
        "samples": samples,
        "files": { "data": store::DATA, "journal": store::JOURNAL, "plan": store::PLAN },
        // What data.csv held through the last committed point: a resume whose journal lost
        // lines checks the rows past it against this (sweep/journal.rs).
        "data": store.events.iter().rev().find_map(|e| match e {
            Event::Point { csv_end, csv_hash: Some(h), .. } => Some(json!({ "bytes": csv_end, "hash": h })),
            _ => None,
        }),
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
/// ([`Dataset::read_warned`], and the crosstalk check's when it names `spot_crosstalk`); a run
/// directory given instead is refused, naming its data file.
pub fn read_measurements(path: &Path) -> Result<(Dataset, Vec<String>), ReadError> {
    let (ds, mut warnings) = Dataset::read_warned(path).map_err(|e| match e {
        ReadError::Folder { path, data: None } => {
            let data = data_path(&path);
            ReadError::Folder {
                data: data.is_file().then_some(data),
                path,
            }
        }
        e => e,
    })?;
    // Grouped rows biased by crosstalk mislead every fit: said on load.
    if ds.samples.iter().any(|s| s.group.is_some()) {
        if let Some(w) = crate::crosstalk::check(&ds).and_then(|c| c.warning()) {
            warnings.push(format!("{}: {w}", ds.path.display()));
        }
    }
    Ok((ds, warnings))
}
