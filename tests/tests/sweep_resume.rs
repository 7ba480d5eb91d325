//! `cta sweep` killed mid-run (SIGKILL, the process gone without warning) and resumed: the
//! measurement file equals, byte for byte and point for point, an uninterrupted run with the
//! same seed (the simulation's settings journalled: the LEDs' brightness scatter too, which
//! the magnitudes show).
//!
//! The killed process is this test binary re-executed with `CTA_SWEEP_CHILD` set, running
//! only `child_sweep`.

use std::path::Path;
use std::time::{Duration, Instant};

use cta_lab::data::Dataset;
use cta_lab::sweep::plan::Plan;
use cta_lab::sweep::store::RunDir;
use cta_lab::sweep::{self, engine::Ending, SweepOptions};
use cta_tests::{
    assert_same_data, child, child_paths, journal, journal_points, resume_args, sweep_args,
    write_plan, TestDir,
};

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

fn args(out: &Path, plan: &Path) -> SweepOptions {
    SweepOptions {
        sim_noise: Some(25.0),
        sim_seed: Some(42),
        sim_effect: vec!["plate_offset=0.05".into()],
        sim_led_brightness: Some(8.0),
        ..sweep_args(plan, out)
    }
}

/// Runs the sweep described by `CTA_SWEEP_CHILD=OUT|PLAN` (only in the re-executed child).
#[test]
fn child_sweep() {
    let Some([out, plan]) = child_paths("CTA_SWEEP_CHILD") else {
        return;
    };
    sweep::sweep(&args(&out, &plan)).unwrap();
}

#[test]
fn killed_and_resumed_equals_uninterrupted() {
    let d = TestDir::new("sweep-resume");
    let plan = write_plan(&d, PLAN);

    // The reference: uninterrupted.
    let full = sweep::sweep(&args(&d.join("full"), &plan)).unwrap();
    assert_eq!(full.ending, Ending::Complete);

    // The same run, killed twice at different places, then resumed to the end.
    let run = d.join("killed");
    let mut kills = 0;
    for (k, at) in [15usize, 150].into_iter().enumerate() {
        let mut child = if k == 0 {
            child("child_sweep", "CTA_SWEEP_CHILD", &[&run, &plan])
                .spawn()
                .unwrap()
        } else {
            // Resume in a child process too, so it can be killed.
            child("child_resume", "CTA_SWEEP_CHILD_RESUME", &[&run])
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
    let a = resume_args(&run);
    // While another session holds the run, a resume is refused (no interleaved journal).
    let held = RunDir::open(&run, false, &Plan::load(&run.join("plan.toml")).unwrap()).unwrap();
    let e = format!("{:#}", sweep::sweep(&a).unwrap_err());
    assert!(
        e.contains("sweep.lock") && e.contains(&format!("pid {}", std::process::id())),
        "{e}"
    );
    drop(held);
    // A resume simulates what the run did: another brightness scatter is refused.
    let e = format!(
        "{:#}",
        sweep::sweep(&SweepOptions {
            sim_led_brightness: Some(3.0),
            ..resume_args(&run)
        })
        .unwrap_err()
    );
    assert!(e.contains("LED brightness scatter 8 %"), "{e}");
    let resumed = sweep::sweep(&a).unwrap();
    assert_eq!(resumed.ending, Ending::Complete);
    assert!(resumed.stats.ok + resumed.stats.no_signal + resumed.stats.partial < full.points);

    // Line for line the uninterrupted run's (after the first, which names the plan file).
    assert_same_data(&d.join("full"), &run);
    let da = Dataset::read(&sweep::data_path(&d.join("full"))).unwrap();
    let db = Dataset::read(&sweep::data_path(&run)).unwrap();
    let (pa, pb) = (da.points(), db.points());
    assert_eq!(pa.len(), pb.len());
    for (x, y) in pa.iter().zip(&pb) {
        assert_eq!(x.rows.len(), y.rows.len());
        assert_eq!(x.first.x, y.first.x);
    }
    let journal = journal(&run);
    assert_eq!(journal.matches("\"event\":\"session\"").count(), 3);
    // The killed child's resume took over the lock the first killed process left, and said so
    // (the last resume found it released by the session that held it above).
    assert_eq!(journal.matches("took over sweep.lock from pid").count(), 1);
}

/// Resumes the run in `CTA_SWEEP_CHILD_RESUME` (only in the re-executed child).
#[test]
fn child_resume() {
    let Some([run]) = child_paths("CTA_SWEEP_CHILD_RESUME") else {
        return;
    };
    if std::env::var("CTA_SWEEP_CHILD").is_ok() {
        return;
    }
    sweep::sweep(&resume_args(&run)).unwrap();
}
