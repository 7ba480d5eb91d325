//! `cta sweep` and the signals that end it, and what it prints when stderr is not a terminal:
//!
//! * SIGTERM and SIGHUP stop a sweep like Ctrl-C: LEDs off, sensor idle, the stop journalled,
//!   the manifest `stopped`, the summary printed, status 130.
//! * Ctrl-C (or SIGTERM) at an operator prompt stops at once, recording nothing for it.
//! * With stderr not a terminal, plain log lines replace the progress bars.
//!
//! The sweeps run in this test binary re-executed as a child (`child_hardware_run`,
//! `child_log_run`), which calls `cli::run` (the `cta sweep` command: signal handler,
//! summary, result) and exits the way the binary does. The hardware runs use the simulated
//! boards as if they were real ones (`--beacon`/`--sensor` given their ports), so the operator
//! is asked, and the child checks the boards' state itself once the sweep returns.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use cta_cli::cmd::sweep::{self as cli, SweepArgs};
use cta_core::wire::beacon::{Beacon, BeaconRequest, BeaconResponse};
use cta_core::wire::sensor::{SensorProtocol, SensorRequest, SensorResponse};
use cta_lab::boards::link::{open_serial, Link, LinkConfig};
use cta_lab::sweep::plan::Plan;
use cta_lab::sweep::sim::{SimCta, SimSettings};
use cta_tests::{
    child, child_paths, journal, journal_points, older_journal, write_plan, TestDir, SLOW_PLAN,
};

/// Generous: a loaded machine must not fail the tests.
const PATIENCE: Duration = Duration::from_secs(120);

/// Prints `board check: N lit, sensor Idle` (what the boards say once the sweep returned).
fn print_board_state(sim: &SimCta) {
    let config = LinkConfig::default();
    let port = open_serial(&sim.beacon_path().display().to_string()).unwrap();
    let mut beacon: Link<Beacon, _> = Link::new(port, config);
    let lit = match beacon.call(BeaconRequest::GetLeds).unwrap() {
        Some(BeaconResponse::Leds(modes)) => modes.iter().filter(|m| m.is_lit()).count(),
        other => panic!("GetLeds: {other:?}"),
    };
    let port = open_serial(&sim.sensor_path().display().to_string()).unwrap();
    let mut sensor: Link<SensorProtocol, _> = Link::new(port, config);
    let mode = match sensor.call(SensorRequest::Status).unwrap() {
        Some(SensorResponse::Status(s)) => s.mode,
        other => panic!("Status: {other:?}"),
    };
    println!("board check: {lit} lit, sensor {mode:?}");
}

/// `cta sweep --plan PLAN --out OUT --beacon B --sensor S --quiet [--yes]` on simulated boards
/// taken for real ones; `--yes` when `yes` exists. Only in the re-executed child.
#[test]
fn child_hardware_run() {
    let Some([out, plan, yes]) = child_paths("CTA_SWEEP_SIGNAL_CHILD") else {
        return;
    };
    let p = Plan::load(&plan).unwrap();
    let sim = SimCta::spawn(
        &p,
        &SimSettings {
            realtime: true,
            ..SimSettings::default()
        },
    )
    .unwrap();
    let a = SweepArgs {
        plan: Some(plan),
        out: Some(out),
        beacon: Some(sim.beacon_path().display().to_string()),
        sensor: Some(sim.sensor_path().display().to_string()),
        yes: yes.exists(),
        quiet: true,
        no_sync: true,
        ..SweepArgs::default()
    };
    let r = cli::run(&a);
    print_board_state(&sim);
    cta_cli::exit_on_error(r);
    std::process::exit(0);
}

/// A child's output collected as it comes (`lock()` for the text so far), and whether its
/// end has been read.
struct Collected {
    text: Mutex<String>,
    ended: std::sync::atomic::AtomicBool,
}

impl std::ops::Deref for Collected {
    type Target = Mutex<String>;

    fn deref(&self) -> &Mutex<String> {
        &self.text
    }
}

impl Collected {
    /// The whole text, once the end has been read (the child has exited: its end comes), or
    /// a panic after [`PATIENCE`].
    fn all(&self) -> String {
        let t0 = Instant::now();
        while !self.ended.load(std::sync::atomic::Ordering::Acquire) {
            assert!(t0.elapsed() < PATIENCE, "the output never ended");
            std::thread::sleep(Duration::from_millis(10));
        }
        self.text.lock().unwrap().clone()
    }
}

/// Collects a child's stderr as it comes.
fn collect(mut from: impl Read + Send + 'static) -> Arc<Collected> {
    let text = Arc::new(Collected {
        text: Mutex::new(String::new()),
        ended: false.into(),
    });
    let t = text.clone();
    std::thread::spawn(move || {
        let mut buf = [0u8; 4096];
        while let Ok(n) = from.read(&mut buf) {
            if n == 0 {
                break;
            }
            t.lock()
                .unwrap()
                .push_str(&String::from_utf8_lossy(&buf[..n]));
        }
        t.ended.store(true, std::sync::atomic::Ordering::Release);
    });
    text
}

/// Wait until `ready()` or panic (killing the child) after [`PATIENCE`].
fn wait_for(child: &mut Child, what: &str, mut ready: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !ready() {
        if t0.elapsed() > PATIENCE || child.try_wait().unwrap().is_some() {
            let _ = child.kill();
            panic!("{what}: never happened (or the sweep ended early)");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Send `signal` (`INT`, `TERM`, `HUP`) to the child and wait for it to end (panicking,
/// after killing it, if it does not within [`PATIENCE`]). Returns its status code and stdout.
fn signal_and_wait(mut child: Child, signal: &str) -> (Option<i32>, String) {
    let ok = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let t0 = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t0.elapsed() > PATIENCE {
            let _ = child.kill();
            panic!("SIG{signal}: the sweep did not stop");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let mut stdout = String::new();
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut stdout)
        .unwrap();
    (child.wait().unwrap().code(), stdout)
}

/// Start `child_hardware_run` on `SLOW_PLAN` into `dir/run`; stdin a pipe left open (nobody
/// answers), stdout and stderr piped. Returns the child, the run directory and the stderr
/// collected so far.
fn start_hardware_run(dir: &Path, yes: bool) -> (Child, PathBuf, Arc<Collected>) {
    let plan = write_plan(dir, SLOW_PLAN);
    let run = dir.join("run");
    let yes_marker = dir.join("yes");
    if yes {
        std::fs::write(&yes_marker, "").unwrap();
    }
    let mut child = child(
        "child_hardware_run",
        "CTA_SWEEP_SIGNAL_CHILD",
        &[&run, &plan, &yes_marker],
    )
    .stdin(Stdio::piped())
    .stdout(Stdio::piped())
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    let stderr = collect(child.stderr.take().unwrap());
    (child, run, stderr)
}

/// Whether this process ignores SIGHUP (the tests run under `nohup`): its children then
/// ignore it too, and so does the sweep, on purpose.
fn sighup_ignored() -> bool {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("SigIgn:"))
        .and_then(|m| u64::from_str_radix(m.trim(), 16).ok())
        .is_some_and(|mask| mask & 1 != 0)
}

/// The run stopped cleanly, interrupted by `name`: summary, error, journal, manifest, boards.
#[track_caller]
fn assert_clean_stop(run: &Path, name: &str, code: Option<i32>, stdout: &str, stderr: &Collected) {
    // The child has exited: the reader thread gets the last bytes, then the end.
    let stderr = stderr.all();
    // 128 + the signal, as a shell reports a command that signal stopped.
    let expected = match name {
        "SIGTERM" => 143,
        "SIGHUP" => 129,
        _ => 130,
    };
    assert_eq!(code, Some(expected), "stdout: {stdout}\nstderr: {stderr}");
    let hint = format!("cta sweep --resume {}", run.display());
    // Points done, counted as the journal counts them; the next one by its index, as the
    // journal numbers them (from 0): the same number.
    let done = journal_points(run);
    let progress = format!("with {done} of 2100 points done (next: point {done})");
    assert!(
        stdout.contains(&format!("interrupted by {name} {progress}"))
            // A hardware run: the hint names the ports it used.
            && stdout.contains(&format!(" (continue with `{hint} --beacon ")),
        "{stdout}"
    );
    assert!(
        stderr.contains(&format!(
            "cta: error: interrupted ({name}) {progress}; the run is saved"
        )),
        "{stderr}"
    );
    // Without each line's check (`chain`), the stop ends with its next point.
    let j = older_journal(&journal(run));
    assert!(
        j.contains(&format!("\"next_point\":{done}}}")),
        "the stop's next point: {j}"
    );
    assert!(
        j.contains(&format!("\"reason\":\"interrupted ({name})\"")),
        "{j}"
    );
    let m = std::fs::read_to_string(run.join("manifest.json")).unwrap();
    assert!(m.contains("\"state\": \"stopped\""), "{m}");
    assert!(
        stdout.contains("board check: 0 lit, sensor Idle"),
        "{stdout}"
    );
}

#[test]
fn sigterm_and_sighup_stop_a_sweep_like_ctrl_c() {
    let mut signals = vec![("TERM", "SIGTERM"), ("INT", "Ctrl-C")];
    if sighup_ignored() {
        eprintln!("SIGHUP is ignored here (nohup?): its case is left out");
    } else {
        signals.push(("HUP", "SIGHUP"));
    }
    for (signal, name) in signals {
        let d = TestDir::new(&format!("sweep-signal-{signal}"));
        let (mut child, run, stderr) = start_hardware_run(&d, true);
        wait_for(&mut child, "3 points committed", || {
            journal_points(&run) >= 3
        });
        let (code, stdout) = signal_and_wait(child, signal);
        assert_clean_stop(&run, name, code, &stdout, &stderr);
    }
}

#[test]
fn a_signal_at_the_operator_prompt_stops_at_once_and_records_nothing() {
    for (signal, name) in [("INT", "Ctrl-C"), ("TERM", "SIGTERM")] {
        let d = TestDir::new(&format!("sweep-prompt-{signal}"));
        let (mut child, run, stderr) = start_hardware_run(&d, false);
        let asked = || {
            stderr
                .lock()
                .unwrap()
                .contains("Move the plate to 10 in (all LEDs are off)")
        };
        wait_for(&mut child, "the plate prompt", asked);
        // The child's stdin stays open: nobody answers.
        let (code, stdout) = signal_and_wait(child, signal);
        assert_clean_stop(&run, name, code, &stdout, &stderr);
        assert!(
            stdout.contains("with 0 of 2100 points done (next: point 0)"),
            "{stdout}"
        );
        // Nothing was entered: no separation, no point.
        let j = journal(&run);
        assert!(!j.contains("\"event\":\"separation\""), "{j}");
        assert_eq!(journal_points(&run), 0);
    }
}

/// `cta sweep --plan PLAN --out OUT --sim-fault vanish=sensor@10:500`, not quiet, stderr piped
/// by the parent. Only in the re-executed child.
#[test]
fn child_log_run() {
    let Some([out, plan]) = child_paths("CTA_SWEEP_LOG_CHILD") else {
        return;
    };
    let a = SweepArgs {
        plan: Some(plan),
        out: Some(out),
        sim_fault: Some("vanish=sensor@10:500".into()),
        no_sync: true,
        ..SweepArgs::default()
    };
    cta_cli::exit_on_error(cli::run(&a));
    std::process::exit(0);
}

#[test]
fn without_a_terminal_the_sweep_logs_lines_instead_of_bars() {
    let d = TestDir::new("sweep-log-lines");
    let plan = write_plan(
        &d,
        "name = \"log\"\nseparations_in = [10, 20]\nbeacons = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9]\n\
         samples = 3\nsettle_ms = 0\n",
    );
    let run = d.join("run");
    let out = child("child_log_run", "CTA_SWEEP_LOG_CHILD", &[&run, &plan])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "stdout: {stdout}\nstderr: {stderr}");
    let lines: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("cta sweep [+"))
        .collect();
    let has = |s: &str| lines.iter().any(|l| l.contains(s));
    assert!(
        has(&format!(
            "] sweep {}: plan `log`, 20 points (10 per separation), starting on the simulated CTA",
            run.display()
        )),
        "{stderr}"
    );
    assert!(has("fault at point 9: sensor: "), "{stderr}");
    assert!(has("pause 0.1 s, reconnect, retry point"), "{stderr}");
    // The sensor board is away for 0.5 s: the reconnection 0.1 s after the fault fails
    // (then the retries reopen it). Only the sensor board is reopened: the beacon board,
    // which never failed, keeps its connection through the failed reconnections.
    assert!(
        has("fault at point 9: sensor: cannot reconnect: cannot open serial port "),
        "{stderr}"
    );
    assert!(
        has("reconnected (sensor board); measuring point 9 again"),
        "{stderr}"
    );
    assert!(
        !has("both boards") && !has("reconnected (beacon board)"),
        "{stderr}"
    );
    // Each separation's line has the rate and the ETA, as the terminal's bar (but the last).
    let first = lines
        .iter()
        .find(|l| l.contains("separation 10 in done: 10/20 points"))
        .unwrap_or_else(|| panic!("{stderr}"));
    assert!(
        first.contains("; ") && first.contains(" points/min, ETA "),
        "{first}"
    );
    assert!(
        lines
            .iter()
            .any(|l| l.ends_with("] separation 20 in done: 20/20 points")),
        "{stderr}"
    );
    assert!(has("stopped: complete; 20/20 points"), "{stderr}");
    // The start comes first and the stop last; no progress bar was drawn.
    assert!(lines[0].contains("starting"), "{stderr}");
    assert!(lines.last().unwrap().contains("stopped"), "{stderr}");
    assert!(
        !stderr.contains("[===") && !stderr.contains("run        ["),
        "{stderr}"
    );
    // The summary stays on stdout.
    assert!(stdout.contains("complete"), "{stdout}");
    assert!(stdout.contains("reconnections: 1"), "{stdout}");
}

/// `cta sweep ... 2>log` on a terminal: the question goes to the file, and is asked on the
/// controlling terminal too, so the operator sees what the sweep waits for. Run under
/// `script`, which gives the child a terminal of its own.
#[test]
fn with_stderr_in_a_file_the_question_is_asked_on_the_terminal() {
    let d = TestDir::new("sweep-tty-prompt");
    let plan = write_plan(&d, SLOW_PLAN);
    let run = d.join("run");
    let log = d.join("stderr.log");
    let exe = std::env::current_exe().unwrap();
    let cmd = format!(
        "exec '{}' child_hardware_run --exact --nocapture --test-threads=1 2>'{}'",
        exe.display(),
        log.display()
    );
    let mut term = Command::new("script")
        .args(["-qfec", &cmd, "/dev/null"])
        .env(
            "CTA_SWEEP_SIGNAL_CHILD",
            format!(
                "{}|{}|{}",
                run.display(),
                plan.display(),
                d.join("no").display()
            ),
        )
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let screen = collect(term.stdout.take().unwrap());
    let question = "Move the plate to 10 in (all LEDs are off)";
    wait_for(&mut term, "the question on the terminal", || {
        screen.lock().unwrap().contains(question)
    });
    let logged = std::fs::read_to_string(&log).unwrap();
    // Closing the terminal hangs the sweep up: it stops cleanly.
    let _ = term.kill();
    let _ = term.wait();
    assert!(logged.contains(question), "{logged}");
}
