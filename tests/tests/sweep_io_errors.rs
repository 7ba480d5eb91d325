//! `cta sweep` when the disk fails under it (here: a file size limit, `ulimit -f`, which makes
//! writes past it fail with EFBIG like a full disk's ENOSPC): the error names the file, the
//! session's stop is journalled and the manifest says it stopped on an error, and the run
//! resumes, once the disk is fine, to the same data as an uninterrupted run.
//!
//! The failing process is this test binary re-executed under `sh -c 'ulimit -f ...'` with
//! `CTA_SWEEP_IO_CHILD` set, running only `child_run`.

use std::path::Path;

use cta_host::sweep::{self, engine::Ending, SweepArgs};
use cta_tests::{
    assert_same_data, child_in_shell, child_paths, resume_args, sweep_args, write_plan, TestDir,
};

/// About 900 bytes of data and 150 of journal per point: data.csv reaches the limit first.
const PLAN: &str = r#"
name = "io test"
separations_in = [10, 20]
beacons = [0, 11, 22, 33, 44, 55, 66, 77, 88, 99]
sensitivities = [3, 4]
samples = 20
settle_ms = 0
"#;

/// Limit on the size of any file the child writes, in 512-byte blocks (`ulimit -f` of dash;
/// bash counts 1024-byte blocks: either way far below data.csv's size, above the others').
const LIMIT_BLOCKS: u32 = 48;

fn args(out: &Path, plan: &Path) -> SweepArgs {
    SweepArgs {
        sim_seed: Some(11),
        ..sweep_args(plan, out)
    }
}

/// The sweep, as the binary runs it (only in the re-executed child).
#[test]
fn child_run() {
    let Some([out, plan]) = child_paths("CTA_SWEEP_IO_CHILD") else {
        return;
    };
    if let Err(e) = sweep::sweep(&args(&out, &plan)) {
        eprintln!("cta: error: {e:#}");
        std::process::exit(1);
    }
}

#[test]
fn a_write_error_names_the_file_and_records_the_stop() {
    let d = TestDir::new("sweep-io-errors");
    let plan = write_plan(&d, PLAN);
    let full = sweep::sweep(&args(&d.join("full"), &plan)).unwrap();
    assert_eq!(full.ending, Ending::Complete);

    let run = d.join("run");
    // SIGXFSZ ignored (inherited through exec), so the write fails instead of killing.
    let out = child_in_shell(
        &format!("trap '' XFSZ; ulimit -f {LIMIT_BLOCKS}"),
        "child_run",
        "CTA_SWEEP_IO_CHILD",
        &[&run, &plan],
    )
    .output()
    .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    let data = run.join("data.csv");
    assert!(
        stderr.contains(&format!("{}: cannot write", data.display()))
            && stderr.contains("os error 27")
            && stderr.contains("cta sweep --resume"),
        "{stderr}"
    );
    // The journal ends with the stop and its reason; the manifest says stopped, and why.
    let journal = std::fs::read_to_string(run.join("journal.jsonl")).unwrap();
    let last = journal.lines().last().unwrap();
    assert!(
        last.contains("\"event\":\"stop\"")
            && last.contains("\"reason\":\"error: ")
            && last.contains("data.csv: cannot write"),
        "{last}"
    );
    let m = std::fs::read_to_string(run.join("manifest.json")).unwrap();
    assert!(m.contains("\"state\": \"stopped\""), "{m}");
    let reason = m.lines().find(|l| l.contains("\"reason\": ")).unwrap();
    assert!(
        reason.contains("\"error: ") && reason.contains("data.csv: cannot write"),
        "{reason}"
    );
    let done: usize = m
        .split("\"done\": ")
        .nth(1)
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(done > 0 && done < full.points, "{done}");

    // With room again, the resume continues where the journal says and completes.
    let r = sweep::sweep(&resume_args(&run)).unwrap();
    assert_eq!(r.ending, Ending::Complete);
    assert_same_data(&d.join("full"), &run);
}
