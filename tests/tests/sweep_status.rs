//! `cta sweep --status RUN_DIR`: how far a run has got, read without changing anything:
//! complete, stopped (with the journalled reason and the last fault), interrupted (killed:
//! no stop journalled, a torn last journal line) and running (another process sweeping it,
//! whose lock the status never takes).
//!
//! The running sweep is this test binary re-executed with `CTA_SWEEP_STATUS_CHILD` set,
//! running only `child_run`.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cta_cli::cmd::sweep::{self as cli, SweepArgs};
use cta_lab::sweep::engine::Ending;
use cta_lab::sweep::status::{self, Holder};
use cta_tests::{
    child, child_paths, crash_after, journal_points, snapshot, sweep_cli_args, write_plan, TestDir,
    SLOW_PLAN,
};

const PLAN: &str = r#"
name = "status"
separations_in = [5, 15, 25]
beacons = [0, 19, 45, 80, 99]
sensitivities = [2, 4]
samples = 4
settle_ms = 0
[timing]
no_signal_reports = 5
request_timeout_ms = 60
retries = 2
backoff_max_s = 0.2
give_up_s = 0.5
"#;

/// Generous: a loaded machine must not fail the tests.
const PATIENCE: Duration = Duration::from_secs(120);

#[test]
fn status_of_a_complete_and_an_interrupted_run() {
    let d = TestDir::new("sweep-status-done");
    let plan = write_plan(&d, PLAN);
    let run = d.join("run");
    let s = cli::sweep(&SweepArgs {
        no_sync: true,
        ..sweep_cli_args(&plan, &run)
    })
    .unwrap();
    assert_eq!(s.ending, Ending::Complete);
    let before = snapshot(&run);
    let st = status::status(&run).unwrap();
    assert_eq!((st.state, st.done, st.total), ("complete", 30, 30));
    assert!(st.resume.is_none() && st.pid.is_none() && st.notes.is_empty());
    assert_eq!(st.sessions.len(), 1);
    assert_eq!(st.sessions[0].on, "simulated CTA");
    assert!(st.separations.iter().all(|s| s.done == 10 && s.total == 10));
    assert_eq!(st.data_bytes, st.committed_bytes);
    assert!(matches!(st.last_commit, Some((29, Some(_)))), "{st:?}");
    let text = st.render();
    assert!(
        text.starts_with(&format!(
            "sweep {}: complete; all 30 points done\n",
            run.display()
        )),
        "{text}"
    );
    let json = st.to_json();
    assert_eq!(json["state"], "complete");
    assert_eq!(json["points"]["done"], 30);
    assert_eq!(json["separations"][2]["done"], 10);
    assert_eq!(snapshot(&run), before, "the status changed a complete run");

    // Killed after point 16 (its later rows written, not journalled), in the middle of a
    // journal line.
    let end = crash_after(&run, 17);
    let mut j = std::fs::OpenOptions::new()
        .append(true)
        .open(run.join("journal.jsonl"))
        .unwrap();
    std::io::Write::write_all(&mut j, b"{\"event\":\"point\",\"i\":17,\"sta").unwrap();
    drop(j);
    let before_killed = snapshot(&run);
    let st = status::status(&run).unwrap();
    assert_eq!((st.state, st.done), ("interrupted", 17));
    assert_eq!(st.next_separation, Some(15.0));
    let done: Vec<usize> = st.separations.iter().map(|s| s.done).collect();
    assert_eq!(done, [10, 7, 0]);
    assert_eq!(st.torn_bytes, Some(28));
    assert_eq!(st.committed_bytes, Some(end));
    assert_eq!(
        st.resume.as_deref(),
        Some(format!("cta sweep --resume {}", run.display()).as_str())
    );
    let text = st.render();
    assert!(
        text.contains("interrupted (its last session ended without recording a stop")
            && text.contains("17 of 30 points done (next: point 17), at 15 in")
            && text.contains("     15 in   7/10  <- here")
            && text.contains("bytes past the last committed point")
            && text.contains("its last line is not whole (28 bytes)")
            && text.contains(&format!(
                "continue with: cta sweep --resume {}",
                run.display()
            )),
        "{text}"
    );
    // Nothing was written, cut or locked.
    assert_eq!(snapshot(&run), before_killed);
}

/// A run that stopped itself (a board gone for longer than `give_up_s`): stopped, with the
/// reason and the last fault as journalled.
#[test]
fn status_of_a_run_that_gave_up() {
    let d = TestDir::new("sweep-status-gave-up");
    let plan = write_plan(&d, PLAN);
    let run = d.join("run");
    let s = cli::sweep(&SweepArgs {
        no_sync: true,
        sim_fault: Some("vanish=beacon@3:5000".into()),
        ..sweep_cli_args(&plan, &run)
    })
    .unwrap();
    assert!(matches!(s.ending, Ending::GaveUp(_)), "{:?}", s.ending);
    let st = status::status(&run).unwrap();
    // The beacon board goes as the 3rd point starts: whether that point is committed first
    // depends on when the sweep next speaks to the board.
    assert_eq!(
        (st.state, st.done, s.next_point),
        ("stopped", journal_points(&run), st.done)
    );
    assert!(
        st.reason
            .as_deref()
            .is_some_and(|r| r.starts_with("gave up: beacon: cannot reconnect")),
        "{st:?}"
    );
    assert!(st.faults >= 2, "{st:?}");
    let (point, board, _, action) = st.last_fault.clone().unwrap();
    assert_eq!((point, board.as_str()), (st.done, "beacon"));
    assert!(
        action.starts_with("stop: no recovery within 0.5 s"),
        "{action}"
    );
    assert!(
        st.render()
            .contains("stopped (gave up: beacon: cannot reconnect"),
        "{}",
        st.render()
    );
}

/// Runs `cta sweep --plan PLAN --out OUT --sim-realtime --no-sync --quiet` (only in the
/// re-executed child).
#[test]
fn child_run() {
    let Some([out, plan]) = child_paths("CTA_SWEEP_STATUS_CHILD") else {
        return;
    };
    let a = SweepArgs {
        no_sync: true,
        sim_realtime: true,
        ..sweep_cli_args(&plan, &out)
    };
    cta_cli::exit_on_error(cli::run(&a));
    std::process::exit(0);
}

/// While another process sweeps the run: running, with its pid, the points growing; the
/// status takes no lock (the sweep goes on committing, and stops cleanly on SIGTERM, which it
/// journals), reads a journal being appended to, and never changes the lock file.
#[test]
fn status_while_a_sweep_runs_takes_nothing_from_it() {
    let d = TestDir::new("sweep-status-running");
    let plan = write_plan(&d, SLOW_PLAN);
    let run = d.join("run");
    let mut c = child("child_run", "CTA_SWEEP_STATUS_CHILD", &[&run, &plan])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while journal_points(&run) < 3 {
        if t0.elapsed() > PATIENCE || c.try_wait().unwrap().is_some() {
            let _ = c.kill();
            panic!("3 points committed: never happened (or the sweep ended early)");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let pid = c.id();
    let lock = |run: &Path| std::fs::read_to_string(run.join("sweep.lock")).unwrap();
    assert_eq!(lock(&run).trim(), pid.to_string());
    // Read over and over (at least 40 times) until the points are seen growing: however
    // slowly the sweep goes, only the deadline of a stuck sweep fails the test.
    let mut seen = Vec::new();
    while seen.len() < 40 || seen[0] >= *seen.last().unwrap() {
        if t0.elapsed() > PATIENCE || c.try_wait().unwrap().is_some() {
            let _ = c.kill();
            panic!("the sweep did not go on (or ended early): {seen:?}");
        }
        let st = match status::status(&run) {
            Ok(st) => st,
            Err(e) => {
                let _ = c.kill();
                panic!("{e:#}");
            }
        };
        assert_eq!((st.state, st.pid), ("running", Some(pid)), "{st:?}");
        assert_eq!(status::holder(&run), Holder::Running(Some(pid)));
        assert!(st.resume.is_some() && st.total == 2100);
        assert!(
            st.render().contains(&format!("running (pid {pid})")),
            "{}",
            st.render()
        );
        seen.push(st.done);
        std::thread::sleep(Duration::from_millis(25));
    }
    assert!(
        seen.windows(2).all(|w| w[0] <= w[1]),
        "the points went back: {seen:?}"
    );
    assert_eq!(lock(&run).trim(), pid.to_string(), "the lock file changed");
    assert!(c.try_wait().unwrap().is_none(), "the sweep ended");
    let ok = Command::new("kill")
        .args(["-TERM", &pid.to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let status_code = c.wait().unwrap();
    assert_eq!(status_code.code(), Some(143));
    let st = status::status(&run).unwrap();
    assert_eq!(
        (st.state, st.reason.as_deref(), st.pid),
        ("stopped", Some("interrupted (SIGTERM)"), None)
    );
    assert_eq!(status::holder(&run), Holder::Free(None));
    assert_eq!(st.done, journal_points(&run));
}
