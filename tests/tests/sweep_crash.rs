//! Crash consistency of a run directory: each of its files (data, journal, manifest, plan) is
//! cut or has one byte corrupted at many offsets, in a complete run and in one killed part
//! way, and the run resumed. Every resume either continues to the uninterrupted run's data
//! (nothing lost, nothing duplicated: on the simulated CTA a re-measured point is the same)
//! with what it cut kept in `recovered-N/`, or refuses with a message naming the file,
//! changing nothing (fault audit, issue 32).
//!
//! `cargo test -p cta-tests --test sweep_crash` tries a spread of offsets in each file (a few
//! seconds); `cargo test -p cta-tests --test sweep_crash -- --ignored` tries every byte
//! offset (minutes). Each prints the counts it tried.

use std::path::{Path, PathBuf};

use cta_lab::sweep::{self, engine::Ending, SweepOptions};
use cta_tests::{
    crash_after, resume_args, snapshot, sweep_args, without_clock, write_plan, TestDir,
};

const PLAN: &str = r#"
name = "crash"
separations_in = [5, 25]
beacons = [0, 99]
sensitivities = [2, 4]
samples = 2
settle_ms = 0
[timing]
no_signal_reports = 4
"#;

const FILES: [&str; 4] = ["data.csv", "journal.jsonl", "manifest.json", "plan.toml"];

/// What one file mutation did on resume.
#[derive(Default, Debug)]
struct Counts {
    tried: usize,
    continued: usize,
    refused: usize,
}

/// Copy the files of `from` into a fresh `to`.
fn copy_run(from: &Path, to: &Path) {
    let _ = std::fs::remove_dir_all(to);
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_file() {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

/// The number of `recovered-N/` folders in `run`.
fn kept(run: &Path) -> usize {
    std::fs::read_dir(run)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with("recovered-"))
        .count()
}

/// Mutate `file` of a copy of `base` (cut at `at`, or byte `at` changed), resume, and check
/// the outcome; `full` is the uninterrupted run's data.
fn trial(base: &Path, work: &Path, file: &str, at: usize, cut: bool, full: &[u8], c: &mut Counts) {
    copy_run(base, work);
    let p = work.join(file);
    let mut bytes = std::fs::read(&p).unwrap();
    if cut {
        bytes.truncate(at);
    } else {
        // A digit becomes another digit (a value that still parses), anything else a `#`.
        bytes[at] = match bytes[at] {
            b'0'..=b'8' => bytes[at] + 1,
            b'9' => b'0',
            b'#' => b'x',
            _ => b'#',
        };
    }
    std::fs::write(&p, &bytes).unwrap();
    let before = snapshot(work);
    c.tried += 1;
    let what = format!("{file} {} at {at}", if cut { "cut" } else { "corrupted" });
    match sweep::sweep(&SweepOptions {
        no_sync: true,
        ..resume_args(work)
    }) {
        Ok(s) => {
            assert_eq!(s.ending, Ending::Complete, "{what}");
            let data = std::fs::read(work.join("data.csv")).unwrap();
            // Every measured value; when each report was taken differs, and says so.
            let measured = |b: &[u8]| without_clock(&String::from_utf8_lossy(b));
            if measured(&data) != measured(full) {
                panic!(
                    "{what}: resumed to other data than the uninterrupted run's ({} bytes, not {})",
                    data.len(),
                    full.len()
                );
            }
            c.continued += 1;
        }
        Err(e) => {
            let e = format!("{e:#}");
            assert!(
                e.contains(&p.display().to_string()),
                "{what}: the refusal does not name {}: {e}",
                p.display()
            );
            assert_eq!(
                snapshot(work),
                before,
                "{what}: the refusal changed the run: {e}"
            );
            assert_eq!(kept(work), 0, "{what}: a refusal kept something aside");
            c.refused += 1;
        }
    }
}

/// A complete run and the same run as a session killed after 5 of its 16 points left it.
fn bases(d: &TestDir) -> (Vec<PathBuf>, Vec<u8>) {
    let plan = write_plan(d, PLAN);
    let complete = d.join("complete");
    let s = sweep::sweep(&SweepOptions {
        no_sync: true,
        sim_seed: Some(9),
        ..sweep_args(&plan, &complete)
    })
    .unwrap();
    assert_eq!(s.ending, Ending::Complete);
    let full = std::fs::read(complete.join("data.csv")).unwrap();
    let killed = d.join("killed");
    copy_run(&complete, &killed);
    crash_after(&killed, 5);
    (vec![complete, killed], full)
}

/// `offsets` offsets spread over each file (its first and last bytes among them), or every
/// one with `None`.
fn run(name: &str, offsets: Option<usize>) {
    let d = TestDir::new(&format!("sweep-crash-{name}"));
    let (bases, full) = bases(&d);
    let work = d.join("work");
    let mut total = Counts::default();
    let mut per_file = Vec::new();
    for file in FILES {
        let mut c = Counts::default();
        for base in &bases {
            let len = std::fs::metadata(base.join(file)).unwrap().len() as usize;
            let at: Vec<usize> = match offsets {
                None => (0..len).collect(),
                Some(n) => {
                    let mut v: Vec<usize> = (0..n).map(|k| k * (len - 1) / (n - 1)).collect();
                    v.dedup();
                    v
                }
            };
            for &a in &at {
                trial(base, &work, file, a, true, &full, &mut c);
                trial(base, &work, file, a, false, &full, &mut c);
            }
        }
        per_file.push(format!(
            "{file}: {} tried ({} continued, {} refused)",
            c.tried, c.continued, c.refused
        ));
        total.tried += c.tried;
        total.continued += c.continued;
        total.refused += c.refused;
    }
    eprintln!(
        "crash consistency: {} resumes of a cut or corrupted file ({} continued, {} refused): {}",
        total.tried,
        total.continued,
        total.refused,
        per_file.join("; ")
    );
}

#[test]
fn a_cut_or_corrupted_file_is_refused_or_resumed_with_nothing_lost() {
    run("spread", Some(6));
}

#[test]
#[ignore = "every byte offset of every file: minutes; run with --ignored"]
fn every_byte_offset_of_every_file() {
    run("every", None);
}
