//! `cta sweep` when the disk fails under it (here: a file size limit, `ulimit -f`, which makes
//! writes past it fail with EFBIG like a full disk's ENOSPC): the error names the file, the
//! session's stop is journalled and the manifest says it stopped on an error, and the run
//! resumes, once the disk is fine, to the same data as an uninterrupted run.
//!
//! And when the run folder, or one of its files, is read-only: a resume, or a new run, is
//! refused before anything is opened, locked, cut or written, naming the path and the reason;
//! once writable again the run resumes to the same data. Root writes whatever the permission
//! bits say, so under root those sweeps run as the user `nobody` (uid 65534), the folders
//! handed to it; where that cannot be done the check is skipped, saying why.
//!
//! The failing process is this test binary re-executed (under `sh -c 'ulimit -f ...'`, or as
//! another user) with `CTA_SWEEP_IO_CHILD`, `CTA_SWEEP_IO_RESUME` or `CTA_SWEEP_IO_NEW` set,
//! running only `child_run`, `child_resume` or `child_new_run`.

use std::os::unix::fs::PermissionsExt;
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Output};

use cta_lab::sweep::{self, engine::Ending, SweepOptions};
use cta_tests::{
    assert_same_data, child, child_in_shell, child_paths, crash_after, resume_args, snapshot,
    sweep_args, write_plan, TestDir,
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

fn args(out: &Path, plan: &Path) -> SweepOptions {
    SweepOptions {
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
    // Unsynced, each point is journalled as it commits: the points before the failure are in
    // the journal whatever the timing (synced, they wait up to 250 ms for the next sync, and the
    // unthrottled run fills the file sooner; a failed sync leaves them out, as it must).
    let a = SweepOptions {
        no_sync: true,
        ..args(&out, &plan)
    };
    if let Err(e) = sweep::sweep(&a) {
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

/// Resumes the run it is given (only in the re-executed child).
#[test]
fn child_resume() {
    let Some([run]) = child_paths("CTA_SWEEP_IO_RESUME") else {
        return;
    };
    if let Err(e) = sweep::sweep(&resume_args(&run)) {
        eprintln!("cta: error: {e:#}");
        std::process::exit(1);
    }
}

/// Starts a new run of the plan it is given on the boards at `PORTS/beacon` and
/// `PORTS/sensor` (only in the re-executed child).
#[test]
fn child_new_run() {
    let Some([out, plan, ports]) = child_paths("CTA_SWEEP_IO_NEW") else {
        return;
    };
    let a = SweepOptions {
        beacon: Some(ports.join("beacon").display().to_string()),
        sensor: Some(ports.join("sensor").display().to_string()),
        yes: true,
        ..sweep_args(&plan, &out)
    };
    if let Err(e) = sweep::sweep(&a) {
        eprintln!("cta: error: {e:#}");
        std::process::exit(1);
    }
}

/// The user `nobody`, who runs the child sweeps when this test runs as root.
const NOBODY: u32 = 65534;

fn chmod(p: &Path, mode: u32) {
    std::fs::set_permissions(p, std::fs::Permissions::from_mode(mode)).unwrap();
}

/// `path` and everything in it handed to [`NOBODY`].
fn give_to_nobody(path: &Path) {
    std::os::unix::fs::chown(path, Some(NOBODY), Some(NOBODY)).unwrap();
    if path.is_dir() {
        for e in std::fs::read_dir(path).unwrap() {
            give_to_nobody(&e.unwrap().path());
        }
    }
}

/// Whether this test runs as root: the owner of the folder `d` it has just created.
fn root(d: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(d).unwrap().uid() == 0
}

/// Runs `c` (a child sweep) so that permission bits bind it: as it is, or, under `root`, as
/// [`NOBODY`] (the test folder was handed to it). `None`, said on stderr, when a root test
/// cannot start a process as another user (a container without the capability, or a
/// checkout `nobody` cannot read): then nothing here can make a folder read-only to the
/// sweep. Under CI (`CI=true`, as `.ci/run` sets) that is a failure, not a skip: the test
/// would otherwise pass while checking nothing.
fn run_bound_by_permissions(mut c: Command, root: bool) -> Option<Output> {
    if !root {
        return Some(c.output().unwrap());
    }
    match c.uid(NOBODY).gid(NOBODY).output() {
        Ok(o) => Some(o),
        Err(e) => {
            let why = format!(
                "running as root, where read-only permissions do not stop writes, and a child \
                 sweep cannot be started as uid {NOBODY} ({e}; it must be able to run {} and \
                 the cta binary: a checkout in a folder only root can read stops it)",
                std::env::current_exe().unwrap().display()
            );
            assert!(std::env::var("CI").as_deref() != Ok("true"), "{why}");
            eprintln!("skipped: {why}");
            None
        }
    }
}

/// A copy of the run in `from` (its files) as `to`.
fn copy_run(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
    }
}

/// A resumed session appends to data.csv and the journal and writes new files in the run
/// folder (the manifest through a temporary file, the simulated run's truth): a folder or a
/// file it cannot write is refused before the resume locks, cuts or writes anything, naming
/// it and the reason (a read-only folder with writable files used to fail only at the
/// manifest, after the uncommitted rows were cut and a session journalled). Made writable
/// again, the run resumes to the uninterrupted run's data.
#[test]
fn a_read_only_run_folder_or_file_is_refused_before_anything_changes() {
    let d = TestDir::new("sweep-io-read-only");
    let root = root(&d);
    let plan = write_plan(&d, PLAN);
    let full = d.join("full");
    assert_eq!(
        sweep::sweep(&args(&full, &plan)).unwrap().ending,
        Ending::Complete
    );
    // Stopped after point 5, the rows of later points written but not committed: a resume
    // would cut them.
    let stopped = d.join("stopped");
    copy_run(&full, &stopped);
    crash_after(&stopped, 5);
    // What is made read-only: the folder or not, which of its files (`*`: all); the path the
    // refusal must name (the folder when empty).
    let cases: [(bool, &str, &str); 5] = [
        (true, "*", ""),
        (true, "", ""),
        (false, "data.csv", "data.csv"),
        (false, "journal.jsonl", "journal.jsonl"),
        (false, "data.truth.json", "data.truth.json"),
    ];
    for (k, (folder, files, named)) in cases.into_iter().enumerate() {
        let what = format!("folder read-only: {folder}, files: {files:?}");
        let run = d.join(format!("run{k}"));
        copy_run(&stopped, &run);
        let c = child("child_resume", "CTA_SWEEP_IO_RESUME", &[&run]);
        // Handed to nobody first (under root), then made read-only, as its owner would.
        if root {
            give_to_nobody(&d);
        }
        for e in std::fs::read_dir(&run).unwrap() {
            let p = e.unwrap().path();
            if files == "*" || p.file_name().is_some_and(|n| n == files) {
                chmod(&p, 0o444);
            }
        }
        if folder {
            chmod(&run, 0o555);
        }
        let before = snapshot(&run);
        let Some(out) = run_bound_by_permissions(c, root) else {
            return;
        };
        let stderr = String::from_utf8_lossy(&out.stderr);
        let path = if named.is_empty() {
            run.clone()
        } else {
            run.join(named)
        };
        assert_eq!(out.status.code(), Some(1), "{what}: {stderr}");
        assert!(
            stderr.contains(&format!(
                "cta: error: {}: cannot write: Permission denied (os error 13). A resumed \
                 session writes in the run directory {} ",
                path.display(),
                run.display()
            )) && stderr.contains(
                "not resuming, nothing was changed; make it and its files writable again"
            ),
            "{what}: {stderr}"
        );
        assert_eq!(snapshot(&run), before, "{what}: the run was changed");
        // Writable again: the resume cuts the uncommitted rows and completes the run.
        chmod(&run, 0o755);
        for e in std::fs::read_dir(&run).unwrap() {
            chmod(&e.unwrap().path(), 0o644);
        }
        let r = sweep::sweep(&resume_args(&run)).unwrap();
        assert_eq!(r.ending, Ending::Complete, "{what}");
        assert_same_data(&full, &run);
    }
}

/// A new run's folder is created (or emptied, with --force) once both boards answered; a
/// place it cannot be written in is refused before any port is opened (the ports here do not
/// exist: the error is about the folder, not them), naming it and the reason, and nothing is
/// created.
#[test]
fn a_new_run_in_a_read_only_place_is_refused_before_the_boards() {
    let d = TestDir::new("sweep-io-read-only-new");
    let root = root(&d);
    let plan = write_plan(&d, PLAN);
    let ports = d.join("no-such-ports");
    let existing = d.join("existing");
    let parent = d.join("parent");
    for (out, named, said) in [
        (
            existing.clone(),
            existing.clone(),
            "A new run writes its files in it".to_string(),
        ),
        (
            parent.join("run"),
            parent.clone(),
            format!(
                "A new run would create {} in it",
                parent.join("run").display()
            ),
        ),
    ] {
        std::fs::create_dir_all(&named).unwrap();
        let c = child("child_new_run", "CTA_SWEEP_IO_NEW", &[&out, &plan, &ports]);
        if root {
            give_to_nobody(&d);
        }
        chmod(&named, 0o555);
        let Some(o) = run_bound_by_permissions(c, root) else {
            return;
        };
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains(&format!(
                "cta: error: {}: cannot write: Permission denied (os error 13). {said}: nothing \
                 was started; choose another --out, or make {} writable",
                named.display(),
                named.display()
            )) && !stderr.contains("no-such-ports"),
            "{stderr}"
        );
        assert!(snapshot(&named).is_empty(), "{}", named.display());
        chmod(&named, 0o755);
    }
}
