//! `cta sweep` killed mid-run (SIGKILL, the process gone without warning) and resumed: the
//! measurement file equals, byte for byte and point for point, an uninterrupted run with the
//! same seed.
//!
//! The killed process is this test binary re-executed with `CTA_SWEEP_CHILD` set, running
//! only `child_sweep`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use cta_host::measurement::Dataset;
use cta_host::sweep::plan::Plan;
use cta_host::sweep::store::RunDir;
use cta_host::sweep::{self, engine::Ending, SweepArgs};

const PLAN: &str = r#"
name = "resume test"
separations_in = [4, 10, 16, 22, 28]
beacons = [0, 11, 22, 33, 44, 55, 66, 77, 88, 99]
frequencies_hz = [4050, 3090]
power_levels = [1, 2]
sensitivities = [2, 4]
samples = 6
settle_ms = 0
[timing]
no_signal_reports = 5
"#;

fn args(out: &Path, plan: &Path) -> SweepArgs {
    SweepArgs {
        plan: Some(plan.to_path_buf()),
        out: Some(out.to_path_buf()),
        quiet: true,
        sim_noise: Some(25.0),
        sim_seed: Some(42),
        sim_effect: vec!["plate_offset=0.05".into()],
        ..Default::default()
    }
}

/// Runs the sweep described by `CTA_SWEEP_CHILD=OUT|PLAN` (only in the re-executed child).
#[test]
fn child_sweep() {
    let Ok(spec) = std::env::var("CTA_SWEEP_CHILD") else {
        return;
    };
    let (out, plan) = spec.split_once('|').unwrap();
    sweep::sweep(&args(Path::new(out), Path::new(plan))).unwrap();
}

fn journal_points(dir: &Path) -> usize {
    std::fs::read_to_string(dir.join("journal.jsonl"))
        .map(|s| {
            s.lines()
                .filter(|l| l.contains("\"event\":\"point\""))
                .count()
        })
        .unwrap_or(0)
}

#[test]
fn killed_and_resumed_equals_uninterrupted() {
    let d: PathBuf = std::env::temp_dir().join(format!("cta-sweep-resume-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let plan = d.join("plan.toml");
    std::fs::write(&plan, PLAN).unwrap();

    // The reference: uninterrupted.
    let full = sweep::sweep(&args(&d.join("full"), &plan)).unwrap();
    assert_eq!(full.ending, Ending::Complete);

    // The same run, killed twice at different places, then resumed to the end.
    let run = d.join("killed");
    let mut kills = 0;
    for (k, at) in [15usize, 150].into_iter().enumerate() {
        let mut cmd = Command::new(std::env::current_exe().unwrap());
        cmd.args(["child_sweep", "--exact", "--nocapture", "--test-threads=1"])
            .env(
                "CTA_SWEEP_CHILD",
                format!("{}|{}", run.display(), plan.display()),
            );
        let mut child = if k == 0 {
            cmd.spawn().unwrap()
        } else {
            // Resume in a child process too, so it can be killed.
            Command::new(std::env::current_exe().unwrap())
                .args(["child_resume", "--exact", "--nocapture", "--test-threads=1"])
                .env("CTA_SWEEP_CHILD_RESUME", run.display().to_string())
                .spawn()
                .unwrap()
        };
        let t0 = Instant::now();
        while journal_points(&run) < at && t0.elapsed() < Duration::from_secs(120) {
            if let Ok(Some(_)) = child.try_wait() {
                break;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap();
            kills += 1;
        }
        child.wait().unwrap();
        let n = journal_points(&run);
        assert!(n >= at && n < full.points, "killed after {n} points");
    }
    assert_eq!(kills, 2, "both runs must be killed mid-way");
    let mut a = args(&run, &plan);
    a.out = None;
    a.plan = None;
    a.sim_noise = None;
    a.sim_seed = None;
    a.sim_effect.clear();
    a.resume = Some(run.clone());
    // While another session holds the run, a resume is refused (no interleaved journal).
    let held = RunDir::open(&run, false, &Plan::load(&run.join("plan.toml")).unwrap()).unwrap();
    let e = format!("{:#}", sweep::sweep(&a).unwrap_err());
    assert!(
        e.contains("sweep.lock") && e.contains(&format!("pid {}", std::process::id())),
        "{e}"
    );
    drop(held);
    let resumed = sweep::sweep(&a).unwrap();
    assert_eq!(resumed.ending, Ending::Complete);
    assert!(resumed.stats.ok + resumed.stats.no_signal + resumed.stats.partial < full.points);

    let fa = std::fs::read_to_string(sweep::data_path(&d.join("full"))).unwrap();
    let fb = std::fs::read_to_string(sweep::data_path(&run)).unwrap();
    let body = |s: &str| s.lines().skip(1).map(String::from).collect::<Vec<_>>();
    // First comment line names the output directory's plan path; the rest is identical.
    assert_eq!(body(&fa).len(), body(&fb).len());
    if let Some(k) = (0..body(&fa).len()).find(|&k| body(&fa)[k] != body(&fb)[k]) {
        panic!(
            "resumed data differs from the uninterrupted run at line {}:\n{}\n{}",
            k + 2,
            body(&fa)[k],
            body(&fb)[k]
        );
    }
    let da = Dataset::read(&sweep::data_path(&d.join("full"))).unwrap();
    let db = Dataset::read(&sweep::data_path(&run)).unwrap();
    let (pa, pb) = (da.points(), db.points());
    assert_eq!(pa.len(), pb.len());
    for (x, y) in pa.iter().zip(&pb) {
        assert_eq!(x.rows.len(), y.rows.len());
        assert_eq!(x.first.x, y.first.x);
    }
    let journal = std::fs::read_to_string(run.join("journal.jsonl")).unwrap();
    assert_eq!(journal.matches("\"event\":\"session\"").count(), 3);
    // The killed child's resume took over the lock the first killed process left, and said so
    // (the last resume found it released by the session that held it above).
    assert_eq!(journal.matches("took over sweep.lock from pid").count(), 1);
    let _ = std::fs::remove_dir_all(&d);
}

/// Resumes the run in `CTA_SWEEP_CHILD_RESUME` (only in the re-executed child).
#[test]
fn child_resume() {
    let Ok(dir) = std::env::var("CTA_SWEEP_CHILD_RESUME") else {
        return;
    };
    if std::env::var("CTA_SWEEP_CHILD").is_ok() {
        return;
    }
    let a = SweepArgs {
        resume: Some(PathBuf::from(dir)),
        quiet: true,
        ..Default::default()
    };
    sweep::sweep(&a).unwrap();
}
