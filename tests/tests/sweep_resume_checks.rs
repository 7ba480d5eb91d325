//! `cta sweep --resume` refuses a run directory whose files no longer agree with each other
//! (edited, emptied, replaced) instead of silently cutting or re-measuring data, and says
//! what it discards when it cuts a crashed session's uncommitted leftovers.

use std::path::{Path, PathBuf};

use cta_host::sweep::{self, engine::Ending, SweepArgs};

const PLAN: &str = r#"
name = "resume checks"
separations_in = [5, 15, 25]
beacons = [0, 19, 45, 80, 99]
power_levels = [2]
sensitivities = [2, 4]
samples = 4
settle_ms = 0
[timing]
no_signal_reports = 5
"#;

/// A complete run of [`PLAN`] in a fresh directory; returns (test dir, run dir).
fn complete_run(name: &str) -> (PathBuf, PathBuf) {
    let d = std::env::temp_dir().join(format!("cta-sweep-checks-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(d.join("plan.toml"), PLAN).unwrap();
    let run = d.join("run");
    let s = sweep::sweep(&SweepArgs {
        plan: Some(d.join("plan.toml")),
        out: Some(run.clone()),
        quiet: true,
        no_sync: true,
        sim_seed: Some(5),
        ..Default::default()
    })
    .unwrap();
    assert_eq!(s.ending, Ending::Complete);
    (d, run)
}

fn resume(run: &Path) -> Result<sweep::Summary, String> {
    sweep::sweep(&SweepArgs {
        resume: Some(run.to_path_buf()),
        quiet: true,
        no_sync: true,
        ..Default::default()
    })
    .map_err(|e| format!("{e:#}"))
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap()
}

#[test]
fn an_emptied_journal_is_refused_not_a_restart_that_wipes_the_data() {
    let (d, run) = complete_run("empty-journal");
    let data = read(&run.join("data.csv"));
    std::fs::write(run.join("journal.jsonl"), "").unwrap();
    let e = resume(&run).unwrap_err();
    assert!(
        e.contains(&run.join("journal.jsonl").display().to_string())
            && e.contains("data rows")
            && e.contains("not resuming"),
        "{e}"
    );
    assert_eq!(read(&run.join("data.csv")), data, "the data were touched");
    // Without the data rows, the manifest still says points were committed.
    let header: String = data
        .lines()
        .take_while(|l| l.starts_with('#'))
        .collect::<Vec<_>>()
        .join("\n");
    let header = format!(
        "{header}\n{}\n",
        data.lines().nth(header.lines().count()).unwrap()
    );
    std::fs::write(run.join("data.csv"), &header).unwrap();
    let e = resume(&run).unwrap_err();
    assert!(
        e.contains("manifest.json") && e.contains("30 were done"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&d);
}
