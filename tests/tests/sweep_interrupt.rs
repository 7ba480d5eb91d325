//! `cta sweep` stopped by Ctrl-C (a real SIGINT) fails: the run is saved and resumable, but the
//! command must not report success, or `cta sweep ... && cta fit ...` would go on with partial
//! data.
//!
//! The interrupted process is this test binary re-executed with `CTA_SWEEP_INT_CHILD` set,
//! running only `child_run`, which calls `cli::run` (the `cta sweep` command: Ctrl-C handler,
//! summary, result) and exits the way the binary does.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cta_cli::cmd::sweep::{self as cli, SweepArgs};
use cta_tests::{
    child, child_paths, journal, journal_points, sweep_cli_args, write_plan, TestDir, SLOW_PLAN,
};

/// Runs `cta sweep --plan PLAN --out OUT` as the binary would (only in the re-executed child).
#[test]
fn child_run() {
    let Some([out, plan]) = child_paths("CTA_SWEEP_INT_CHILD") else {
        return;
    };
    let a = SweepArgs {
        no_sync: true,
        sim_realtime: true,
        ..sweep_cli_args(&plan, &out)
    };
    // What the binary does with the command's result (`cta_cli::main`).
    cta_cli::exit_on_error(cli::run(&a));
    std::process::exit(0);
}

#[test]
fn ctrl_c_exits_non_zero_with_the_resume_hint() {
    let d = TestDir::new("sweep-interrupt");
    let plan = write_plan(&d, SLOW_PLAN);
    let run = d.join("run");
    let mut child = child("child_run", "CTA_SWEEP_INT_CHILD", &[&run, &plan])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while journal_points(&run) < 3 {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "the sweep never started"
        );
        assert!(child.try_wait().unwrap().is_none(), "the sweep ended early");
        std::thread::sleep(Duration::from_millis(5));
    }
    let ok = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(130),
        "stdout: {stdout}\nstderr: {stderr}"
    );
    // The summary and the error both say how far the run got and how to continue: the
    // points done as the journal counts them, the next by its index, as the journal numbers
    // points (from 0).
    let done = cta_tests::journal_points(&run);
    let progress = format!("with {done} of 2100 points done (next: point {done})");
    assert!(
        stdout.contains(&format!("interrupted by Ctrl-C {progress}")),
        "{stdout}"
    );
    let hint = format!("cta sweep --resume {}", run.display());
    assert!(stdout.contains(&hint), "{stdout}");
    assert!(
        stderr.contains(&format!("cta: error: interrupted (Ctrl-C) {progress}"))
            && stderr.contains(&hint),
        "{stderr}"
    );
    // The run stopped cleanly (journalled) and is resumable.
    assert!(journal(&run).contains("\"reason\":\"interrupted (Ctrl-C)\""));
    let m = std::fs::read_to_string(run.join("manifest.json")).unwrap();
    assert!(m.contains("\"state\": \"stopped\""), "{m}");
}
