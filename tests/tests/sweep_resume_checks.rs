//! `cta sweep --resume` refuses a run directory whose files no longer agree with each other
//! (edited, emptied, replaced) instead of silently cutting or re-measuring data, and says
//! what it discards when it cuts a crashed session's uncommitted leftovers. Of the plan, only
//! the timing keys that govern waiting and retrying may change: said, and journalled. Nothing
//! is cut or written before the boards answered, and a run continues only on the kind of
//! boards it was recorded on (hardware or simulated, as each board says of itself).
//!
//! The resume whose terminal output is checked is this test binary re-executed with
//! `CTA_SWEEP_CHECKS_CHILD` set, running only `child_resume`.

use std::path::{Path, PathBuf};

use cta_lab::sweep::plan::Plan;
use cta_lab::sweep::sim::{Posing, SimCta, SimSettings};
use cta_lab::sweep::store::{Event, RunDir};
use cta_lab::sweep::{self, engine::Ending, SweepOptions};
use cta_tests::{
    child, child_paths, crash_after, journal, journal_field, older_journal, resume_args, snapshot,
    sweep_args, without_clock, write_plan, TestDir,
};

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
fn complete_run(name: &str) -> (TestDir, PathBuf) {
    let d = TestDir::new(&format!("sweep-checks-{name}"));
    let plan = write_plan(&d, PLAN);
    let run = d.join("run");
    let s = sweep::sweep(&SweepOptions {
        no_sync: true,
        sim_seed: Some(5),
        ..sweep_args(&plan, &run)
    })
    .unwrap();
    assert_eq!(s.ending, Ending::Complete);
    (d, run)
}

fn resume(run: &Path) -> Result<sweep::Summary, String> {
    sweep::sweep(&SweepOptions {
        no_sync: true,
        ..resume_args(run)
    })
    .map_err(|e| format!("{e:#}"))
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap()
}

/// Resumes the run in `CTA_SWEEP_CHECKS_CHILD` to the end (only in the re-executed child).
#[test]
fn child_resume() {
    let Some([run]) = child_paths("CTA_SWEEP_CHECKS_CHILD") else {
        return;
    };
    // As the command runs it, saying its notes on stderr.
    let args = cta_cli::cmd::sweep::SweepArgs {
        resume: Some(run),
        quiet: true,
        ..Default::default()
    };
    assert_eq!(
        cta_cli::cmd::sweep::sweep(&args).unwrap().ending,
        Ending::Complete
    );
}

/// The journal's last `session` line.
fn last_session(run: &Path) -> String {
    journal(run)
        .lines()
        .rfind(|l| l.contains("\"event\":\"session\""))
        .unwrap()
        .to_string()
}

#[test]
fn an_emptied_journal_is_refused_not_a_restart_that_wipes_the_data() {
    let (_dir, run) = complete_run("empty-journal");
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
}

#[test]
fn an_edited_data_file_is_refused_not_cut_mid_row() {
    let (_dir, run) = complete_run("edited");
    let end = crash_after(&run, 20) as usize;
    let data = read(&run.join("data.csv"));
    // A note inserted at the top: every committed byte moves; cutting at the journalled
    // length would splice a row in the middle of the file.
    std::fs::write(run.join("data.csv"), format!("# note\n{data}")).unwrap();
    let e = resume(&run).unwrap_err();
    assert!(
        e.contains(&run.join("data.csv").display().to_string())
            && e.contains("not what was written")
            && e.contains("Not resuming"),
        "{e}"
    );
    // A value changed in the middle: found, with the last point that still matches.
    let k = end / 2 + data[end / 2..].find(|c: char| c.is_ascii_digit()).unwrap();
    let mut edited = data.clone().into_bytes();
    edited[k] = if edited[k] == b'7' { b'8' } else { b'7' };
    std::fs::write(run.join("data.csv"), &edited).unwrap();
    let e = resume(&run).unwrap_err();
    assert!(e.contains("it matches up to point"), "{e}");
    assert_eq!(
        std::fs::read(run.join("data.csv")).unwrap(),
        edited,
        "not touched"
    );
}

#[test]
fn uncommitted_leftovers_are_discarded_and_said() {
    let (_dir, run) = complete_run("leftovers");
    let full = read(&run.join("data.csv"));
    // Killed after point 19's journal line, with the rows of points 20.. already written.
    let end = crash_after(&run, 20);
    let leftover = &full[end as usize..];
    let rows = leftover.lines().filter(|l| !l.starts_with('#')).count();
    assert!(rows > 0);
    // ... and killed in the middle of the next journal line.
    let torn = "{\"event\":\"point\",\"i\":20,\"sta";
    let mut j = std::fs::OpenOptions::new()
        .append(true)
        .open(run.join("journal.jsonl"))
        .unwrap();
    std::io::Write::write_all(&mut j, torn.as_bytes()).unwrap();
    drop(j);
    let s = resume(&run).unwrap();
    assert_eq!(s.ending, Ending::Complete);
    let j = read(&run.join("journal.jsonl"));
    let note = format!(
        "data.csv: set aside {} bytes ({rows} data rows, 0 comment lines) past the last \
         committed point, 19: not committed",
        leftover.len()
    );
    assert!(j.contains(&note), "{note}\n{j}");
    assert!(
        j.contains("journal.jsonl: dropped its torn last line (28 bytes)"),
        "{j}"
    );
    // The points were measured again: the file is the uninterrupted run's.
    assert_eq!(
        without_clock(&read(&run.join("data.csv"))),
        without_clock(&full)
    );
    // Rows appended after the end of a complete run: cut, and said.
    let complete = read(&run.join("data.csv"));
    std::fs::write(run.join("data.csv"), format!("{complete}5,1,2,3\n")).unwrap();
    resume(&run).unwrap();
    let j = read(&run.join("journal.jsonl"));
    assert!(
        j.contains(
            "set aside 8 bytes (1 data row, 0 comment lines) past the last committed point, 29"
        ),
        "{j}"
    );
    assert_eq!(read(&run.join("data.csv")), complete);
}

#[test]
fn a_changed_plan_is_refused_naming_the_keys() {
    let (_dir, run) = complete_run("plan");
    crash_after(&run, 20);
    let plan = run.join("plan.toml");
    for (from, to, key) in [
        // `timing.max_reports` is left at its default, which follows `samples`: not a change
        // of its own.
        (
            "samples = 4",
            "samples = 6",
            "): `samples`: 4 -> 6; `timing.max_reports`: 16 -> 24 (its default follows \
             `samples`). A resume",
        ),
        (
            "beacons = [0, 19, 45, 80, 99]",
            "beacons = [0, 19, 45, 80]",
            "`beacons`: [0, 19, 45, 80, 99] -> [0, 19, 45, 80]",
        ),
        (
            "separations_in = [5, 15, 25]",
            "separations_in = \"5..25:10\"",
            "",
        ),
        (
            "separations_in = [5, 15, 25]",
            "separations_in = [5, 15, 30]",
            "`separations_in`: [5.0, 15.0, 25.0] -> [5.0, 15.0, 30.0]",
        ),
        (
            "no_signal_reports = 5",
            "no_signal_reports = 7",
            "`timing.no_signal_reports`: 5 -> 7",
        ),
        (
            "no_signal_reports = 5",
            "no_signal_reports = 30",
            "): `timing.no_signal_reports`: 5 -> 30; `timing.max_reports`: 16 -> 30 (its \
             default follows `timing.no_signal_reports`). A resume",
        ),
        (
            "no_signal_reports = 5",
            "no_signal_reports = 5\nmax_reports = 40",
            "`timing.max_reports`: 16 -> 40",
        ),
        ("settle_ms = 0", "settle_ms = 100", "`settle_ms`: 0 -> 100"),
        (
            "settle_ms = 0",
            "settle_ms = 0\nrate_hz = 20",
            "`rate_hz`: 10 -> 20",
        ),
    ] {
        std::fs::write(&plan, PLAN.replace(from, to)).unwrap();
        let data = read(&run.join("data.csv"));
        let journal = read(&run.join("journal.jsonl"));
        match resume(&run) {
            Err(e) if !key.is_empty() => {
                assert!(
                    e.starts_with(&format!("{}: the plan was changed", plan.display()))
                        && e.contains(key)
                        && e.contains("not resuming"),
                    "{e}"
                );
                assert_eq!(read(&run.join("data.csv")), data, "not touched");
                assert_eq!(read(&run.join("journal.jsonl")), journal, "not touched");
            }
            // The same plan written differently: a resume.
            Ok(s) if key.is_empty() => assert_eq!(s.ending, Ending::Complete),
            r => panic!("{to}: {r:?}"),
        }
    }
}

/// A `[timing] max_reports` written in the plan (40; its default would be 16, 4 x `samples`)
/// is journalled with its value, which is what a resume compares: taking the line out, or a
/// changed `samples` that its default would follow, cannot slip through; the same value,
/// written or left to the default, is no change.
#[test]
fn an_explicit_max_reports_is_journalled_and_held_on_resume() {
    let d = TestDir::new("sweep-checks-max-reports");
    let explicit = with_timing("max_reports = 40");
    let plan = write_plan(&d, &explicit);
    let run = d.join("run");
    let s = sweep::sweep(&SweepOptions {
        no_sync: true,
        sim_seed: Some(5),
        ..sweep_args(&plan, &run)
    })
    .unwrap();
    assert_eq!(s.ending, Ending::Complete);
    assert!(last_session(&run).contains("\"max_reports\":40"));
    crash_after(&run, 20);
    let pp = run.join("plan.toml");
    let given = d.join("given.toml");
    for (text, said) in [
        // The line taken out: its default, 16, is not the run's 40.
        (PLAN.to_string(), "`timing.max_reports`: 40 -> 16. A resume"),
        // `samples` changed, `max_reports` kept: only `samples` is named.
        (
            explicit.replace("samples = 4", "samples = 6"),
            "): `samples`: 4 -> 6. A resume",
        ),
        // ... or taken out too: its default follows `samples`, 24, still not the run's 40.
        (
            PLAN.replace("samples = 4", "samples = 6"),
            "): `samples`: 4 -> 6; `timing.max_reports`: 40 -> 24. A resume",
        ),
    ] {
        let journal = read(&run.join("journal.jsonl"));
        std::fs::write(&given, &text).unwrap();
        for (e, file) in [
            (resume_with(&run, &given).unwrap_err(), &given),
            (
                {
                    std::fs::write(&pp, &text).unwrap();
                    resume(&run).unwrap_err()
                },
                &pp,
            ),
        ] {
            assert!(
                e.starts_with(&format!("{}: the plan was changed", file.display()))
                    && e.contains(said)
                    && e.contains("not resuming"),
                "{e}"
            );
        }
        assert_eq!(read(&run.join("journal.jsonl")), journal, "not touched");
        std::fs::write(&pp, &explicit).unwrap();
    }
    // The run's value with a timing change: resumes, the session journalling 40 again.
    std::fs::write(&pp, with_timing("max_reports = 40\nretries = 4")).unwrap();
    assert_eq!(resume(&run).unwrap().ending, Ending::Complete);
    let session = last_session(&run);
    assert!(
        session.contains("\"max_reports\":40")
            && session.contains("`timing.retries`: 2 -> 4")
            && !session.contains("max_reports`:"),
        "{session}"
    );
    // 16 written out is the default: no change from a run that left it out.
    let (_dir, other) = complete_run("max-reports-default");
    crash_after(&other, 20);
    std::fs::write(other.join("plan.toml"), with_timing("max_reports = 16")).unwrap();
    assert_eq!(resume(&other).unwrap().ending, Ending::Complete);
    assert!(!last_session(&other).contains("changed"));
}

/// [`PLAN`] with its `[timing]` table extended by `lines`.
fn with_timing(lines: &str) -> String {
    format!("{PLAN}{lines}\n")
}

#[test]
fn a_timing_change_resumes_with_a_note_and_the_same_data() {
    let (_dir, run) = complete_run("timing");
    let full = read(&run.join("data.csv"));
    // Stopped at point 20 (as by a timeout too short), then the timing lengthened.
    crash_after(&run, 20);
    let plan = run.join("plan.toml");
    std::fs::write(
        &plan,
        with_timing(
            "request_timeout_ms = 900\nretries = 4\nreport_timeout_ms = 5000\nheartbeat_ms = 1000\n\
             backoff_max_s = 5\ngive_up_s = 120",
        ),
    )
    .unwrap();
    let out = child("child_resume", "CTA_SWEEP_CHECKS_CHILD", &[&run])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let note = format!(
        "cta: note: {}: plan.toml: timing changed since the last session (as recorded in \
         journal.jsonl): `timing.request_timeout_ms`: 500 -> 900; `timing.retries`: 2 -> 4; \
         `timing.report_timeout_ms`: 2000 -> 5000; `timing.heartbeat_ms`: 2000 -> 1000; \
         `timing.backoff_max_s`: 30.0 -> 5.0; `timing.give_up_s`: 3600.0 -> 120.0; ",
        run.display()
    );
    assert!(stderr.contains(&note), "{note}\n{stderr}");
    // Points 20.. measured again under the new timing: the uninterrupted run's file.
    assert_eq!(
        without_clock(&read(&run.join("data.csv"))),
        without_clock(&full)
    );
    // The session journals the note and the plan it used; the manifest shows that plan.
    let session = last_session(&run);
    assert!(
        session.contains("timing changed since the last session")
            && session.contains("\"retries\":4")
            && session.contains("\"request_timeout_ms\":900"),
        "{session}"
    );
    let m = read(&run.join("manifest.json"));
    assert!(
        m.contains("\"retries\": 4") && m.contains("\"state\": \"complete\""),
        "{m}"
    );

    // The next resume compares with the plan that session used: nothing changed, no note.
    // (Each resume here has points to measure: a complete run's resume opens no session.)
    crash_after(&run, 25);
    resume(&run).unwrap();
    let session = last_session(&run);
    assert!(!session.contains("timing changed"), "{session}");
    // ... and a key set back to the run's first value is a change again, from the last.
    std::fs::write(
        &plan,
        with_timing(
            "request_timeout_ms = 900\nreport_timeout_ms = 5000\nheartbeat_ms = 1000\n\
             backoff_max_s = 5\ngive_up_s = 120",
        ),
    )
    .unwrap();
    crash_after(&run, 27);
    resume(&run).unwrap();
    let session = last_session(&run);
    assert!(
        session.contains("timing changed since the last session")
            && session.contains("`timing.retries`: 4 -> 2;")
            && !session.contains("request_timeout_ms`:"),
        "{session}"
    );
    assert_eq!(
        without_clock(&read(&run.join("data.csv"))),
        without_clock(&full)
    );
}

#[test]
fn a_timing_change_with_another_is_refused_naming_the_other() {
    let (_dir, run) = complete_run("mixed");
    crash_after(&run, 20);
    let plan = run.join("plan.toml");
    std::fs::write(
        &plan,
        with_timing("retries = 5").replace("sensitivities = [2, 4]", "sensitivities = [2, 3]"),
    )
    .unwrap();
    let data = read(&run.join("data.csv"));
    let journal = read(&run.join("journal.jsonl"));
    let e = resume(&run).unwrap_err();
    assert!(
        e.starts_with(&format!(
            "{}: the plan was changed since the run started (as recorded in {}): `sensitivities`: [2, 4] -> [2, 3]. ",
            plan.display(),
            run.join("journal.jsonl").display()
        )) && e.contains("(the change of `timing.retries` alone would be accepted)")
            && e.contains("not resuming, nothing was changed: restore plan.toml"),
        "{e}"
    );
    assert!(!e.contains("`timing.retries`: 2 -> 5"), "{e}");
    assert_eq!(read(&run.join("data.csv")), data, "not touched");
    assert_eq!(read(&run.join("journal.jsonl")), journal, "not touched");
    // With `sensitivities` restored, the timing change alone resumes.
    std::fs::write(&plan, with_timing("retries = 5")).unwrap();
    assert_eq!(resume(&run).unwrap().ending, Ending::Complete);
    assert!(last_session(&run).contains("`timing.retries`: 2 -> 5"));
}

/// `cta sweep --resume RUN --plan FILE`.
fn resume_with(run: &Path, plan: &Path) -> Result<sweep::Summary, String> {
    sweep::sweep(&SweepOptions {
        no_sync: true,
        plan: Some(plan.to_path_buf()),
        ..resume_args(run)
    })
    .map_err(|e| format!("{e:#}"))
}

#[test]
fn a_given_plan_with_a_timing_change_resumes_as_an_edited_one_and_becomes_the_runs_plan() {
    let (dir, run) = complete_run("given-timing");
    let full = read(&run.join("data.csv"));
    let plan = run.join("plan.toml");
    // The run's own plan as another file: a plain resume, nothing replaced or said.
    crash_after(&run, 20);
    let same = dir.join("same.toml");
    std::fs::write(&same, PLAN).unwrap();
    assert_eq!(resume_with(&run, &same).unwrap().ending, Ending::Complete);
    let session = last_session(&run);
    assert!(
        !session.contains("timing changed") && !session.contains("replaced by"),
        "{session}"
    );
    assert_eq!(read(&plan), PLAN);

    // Longer timing in another file: accepted with the note an edit of plan.toml gets.
    crash_after(&run, 20);
    let new = dir.join("longer.toml");
    let text = with_timing("retries = 4\ngive_up_s = 120");
    std::fs::write(&new, &text).unwrap();
    assert_eq!(resume_with(&run, &new).unwrap().ending, Ending::Complete);
    let session = last_session(&run);
    let note = format!(
        "{}: timing changed since the last session (as recorded in journal.jsonl): \
         `timing.retries`: 2 -> 4; `timing.give_up_s`: 3600.0 -> 120.0; these govern only \
         waiting and retrying",
        new.display()
    );
    assert!(session.contains(&note), "{note}\n{session}");
    assert!(
        session.contains(&format!(
            "plan.toml: replaced by {} (--plan), the plan this session continues with",
            new.display()
        )) && session.contains("\"retries\":4"),
        "{session}"
    );
    assert_eq!(
        without_clock(&read(&run.join("data.csv"))),
        without_clock(&full)
    );
    // The run directory records the plan used: plan.toml is the given file, the manifest
    // shows it, and the next resume, from plan.toml, finds nothing changed.
    assert_eq!(read(&plan), text);
    let m = read(&run.join("manifest.json"));
    assert!(m.contains("\"retries\": 4"), "{m}");
    crash_after(&run, 25);
    resume(&run).unwrap();
    let session = last_session(&run);
    assert!(
        !session.contains("timing changed") && session.contains("\"retries\":4"),
        "{session}"
    );
}

#[test]
fn a_given_plan_with_another_change_is_refused_as_an_edited_one() {
    let (dir, run) = complete_run("given-refused");
    crash_after(&run, 20);
    let plan = run.join("plan.toml");
    let jp = run.join("journal.jsonl");
    let changed = with_timing("retries = 5").replace("samples = 4", "samples = 6");
    let new = dir.join("more-samples.toml");
    std::fs::write(&new, &changed).unwrap();
    let (data, journal) = (read(&run.join("data.csv")), read(&jp));
    let e = resume_with(&run, &new).unwrap_err();
    let (said, remedy) = e.split_once("nothing was changed: ").unwrap();
    assert!(
        said.starts_with(&format!(
            "{}: the plan was changed since the run started (as recorded in {}): `samples`: \
             4 -> 6; `timing.max_reports`: 16 -> 24 (its default follows `samples`). ",
            new.display(),
            jp.display()
        )) && said.contains("(the change of `timing.retries` alone would be accepted)"),
        "{e}"
    );
    assert!(
        remedy.starts_with(&format!(
            "resume with the run's own {} (leave out --plan), or start a new run with --out",
            plan.display()
        )),
        "{e}"
    );
    assert!(!e.contains("`timing.retries`: 2 -> 5"), "{e}");
    assert_eq!(read(&run.join("data.csv")), data, "not touched");
    assert_eq!(read(&jp), journal, "not touched");
    assert_eq!(read(&plan), PLAN, "not replaced");
    // The same change made in plan.toml is refused with the same words, but for the file.
    std::fs::write(&plan, &changed).unwrap();
    let edited = resume(&run).unwrap_err();
    let (edited_said, _) = edited.split_once("nothing was changed: ").unwrap();
    assert_eq!(
        edited_said.replacen(&plan.display().to_string(), &new.display().to_string(), 1),
        said
    );
    assert_eq!(read(&jp), journal, "not touched");
}

#[test]
fn without_a_journalled_plan_a_given_plan_is_checked_against_plan_toml() {
    // A journal of an older version records no plan: a given file is then compared with the
    // run's own plan.toml, with the same rules.
    let (dir, run) = complete_run("given-old-journal");
    crash_after(&run, 20);
    let jp = run.join("journal.jsonl");
    let old: String = older_journal(&read(&jp))
        .lines()
        .map(
            |l| match (l.find(",\"plan\":{"), l.find("},\"from_point\"")) {
                (Some(a), Some(b)) => format!("{}{}\n", &l[..a], &l[b + 1..]),
                _ => format!("{l}\n"),
            },
        )
        .collect();
    assert!(!old.contains("\"plan\""), "{old}");
    std::fs::write(&jp, &old).unwrap();
    let new = dir.join("new.toml");
    std::fs::write(&new, PLAN.replace("samples = 4", "samples = 5")).unwrap();
    let e = resume_with(&run, &new).unwrap_err();
    assert!(
        e.starts_with(&format!(
            "{}: the plan was changed since the run started (as recorded in {}): `samples`: 4 -> 5",
            new.display(),
            run.join("plan.toml").display()
        )),
        "{e}"
    );
    assert_eq!(read(&jp), old, "not touched");
    std::fs::write(&new, with_timing("retries = 3")).unwrap();
    assert_eq!(resume_with(&run, &new).unwrap().ending, Ending::Complete);
    assert!(
        last_session(&run).contains("`timing.retries`: 2 -> 3"),
        "{}",
        last_session(&run)
    );
    assert_eq!(read(&run.join("plan.toml")), with_timing("retries = 3"));
}

#[test]
fn a_journal_with_the_older_spread_loads_and_resumes_with_the_ch_iv_uncertainty() {
    // Earlier versions journalled each separation's `spread`, the corners' standard deviation;
    // the uncertainty is now Ch IV's (the largest difference between a corner and the mean).
    // Such a run still resumes, and its separations carry the uncertainty derived from their
    // corners, not the old value (a sentinel here, to be sure it is not carried over).
    let (_dir, run) = complete_run("older-spread");
    crash_after(&run, 20);
    let jp = run.join("journal.jsonl");
    let mut separations = 0;
    let old: String = older_journal(&read(&jp))
        .lines()
        .map(|l| {
            let Some(a) = l.find(",\"uncertainty\":") else {
                return format!("{l}\n");
            };
            separations += 1;
            let b = a + l[a..].find(",\"source\"").unwrap();
            format!("{},\"spread\":0.123456{}\n", &l[..a], &l[b..])
        })
        .collect();
    assert!(separations > 0 && !old.contains("uncertainty"), "{old}");
    std::fs::write(&jp, &old).unwrap();
    let plan = Plan::load(&run.join("plan.toml")).unwrap();
    let store = RunDir::open(&run, false, &plan).unwrap();
    let (mut seen, mut tilted) = (0, 0);
    for e in &store.events {
        if let Event::Separation(s) = e {
            seen += 1;
            assert_eq!(s.corners.len(), 4, "{s:?}");
            let m = s.corners.iter().sum::<f64>() / 4.0;
            let bound = s.corners.iter().map(|c| (c - m).abs()).fold(0.0, f64::max);
            assert!((s.uncertainty - bound).abs() < 1e-12, "{s:?}");
            tilted += usize::from(bound > 0.0);
        }
    }
    assert_eq!(seen, separations);
    // Not all level: some derived uncertainty differs from zero as well as from the sentinel.
    assert!(tilted > 0, "every simulated plate level");
    drop(store);
    assert_eq!(resume(&run).unwrap().ending, Ending::Complete);
    let manifest = read(&run.join("manifest.json"));
    assert!(
        manifest.contains("\"uncertainty\"")
            && !manifest.contains("spread")
            && !manifest.contains("\"uncertainty\": 0.123456"),
        "{manifest}"
    );
    // The journal is never rewritten: its older lines keep what they said.
    let j = read(&jp);
    assert!(j.starts_with(&old), "{j}");
}

/// A run with its journal or its data gone cannot be resumed; the refusal names what is left
/// and warns that starting over with --force would delete it.
#[test]
fn half_a_run_is_named_not_taken_for_no_run() {
    for (gone, left) in [("journal.jsonl", "data.csv"), ("data.csv", "journal.jsonl")] {
        let (_dir, run) = complete_run(&format!("half-{gone}"));
        let kept = read(&run.join(left));
        std::fs::remove_file(run.join(gone)).unwrap();
        let e = resume(&run).unwrap_err();
        assert!(
            e.contains(&format!("has {left} but no {gone}"))
                && e.contains(&format!("--force` would delete {left}")),
            "{e}"
        );
        assert_eq!(read(&run.join(left)), kept, "{left} touched");
    }
}

/// One separation: the test puts the boards' simulated plate there (`--yes` moves nothing).
const PORTS_PLAN: &str = r#"
name = "apparatus check"
separations_in = [20]
beacons = [0, 19, 45, 80, 99]
sensitivities = [3, 4]
samples = 3
settle_ms = 0
"#;

/// Simulated boards on ports, standing in for the run's boards; those `posing` names say they
/// are hardware.
fn boards(posing: Posing) -> SimCta {
    let plan = Plan::parse("plan.toml", PORTS_PLAN).unwrap();
    let sim = SimCta::spawn_posing_as(&plan, &SimSettings::default(), posing).unwrap();
    sim.move_plate(0, 20.0, 0);
    sim
}

/// `cta sweep ... --beacon B --sensor S --yes --quiet --no-sync` on `boards`' ports.
fn on_ports(boards: &SimCta) -> SweepOptions {
    SweepOptions {
        beacon: Some(boards.beacon_path().display().to_string()),
        sensor: Some(boards.sensor_path().display().to_string()),
        yes: true,
        no_sync: true,
        ..SweepOptions::default()
    }
}

/// `cta sweep --resume RUN` on `boards`' ports.
fn resume_on(run: &Path, boards: &SimCta) -> Result<sweep::Summary, String> {
    sweep::sweep(&SweepOptions {
        resume: Some(run.to_path_buf()),
        ..on_ports(boards)
    })
    .map_err(|e| format!("{e:#}"))
}

const HARDWARE: Posing = Posing {
    beacon_hardware: true,
    sensor_hardware: true,
};

/// The data file's header says what the data come from (the first session's boards): a
/// resume on boards of another kind would put their points under it. It is refused, naming
/// both kinds and every port, before anything is cut or written.
#[test]
fn a_resume_on_another_kind_of_board_is_refused_naming_both() {
    let d = TestDir::new("sweep-checks-apparatus");
    let plan = write_plan(&d, PORTS_PLAN);
    for (first, label, kind) in [
        (
            Posing::default(),
            "simulated beacon and sensor boards",
            "simulated",
        ),
        (HARDWARE, "CTA hardware", "hardware"),
    ] {
        let run = d.join(kind);
        let started = boards(first);
        let s = sweep::sweep(&SweepOptions {
            plan: Some(plan.clone()),
            out: Some(run.clone()),
            ..on_ports(&started)
        })
        .unwrap();
        assert_eq!(s.ending, Ending::Complete);
        let full = read(&run.join("data.csv"));
        let header: Vec<&str> = full.lines().take_while(|l| l.starts_with('#')).collect();
        assert!(header[1].ends_with(&format!("; {label}")), "{header:?}");
        // Stopped after point 3, the rows of the next points written but not committed.
        crash_after(&run, 4);
        let (data, journal, plan_toml) = (
            read(&run.join("data.csv")),
            read(&run.join("journal.jsonl")),
            read(&run.join("plan.toml")),
        );
        let port = |b: &SimCta| (b.beacon_path(), b.sensor_path());
        let (b0, s0) = port(&started);
        drop(started);
        for (posing, now, beacon_kind, sensor_kind) in [
            (
                Posing::default(),
                "simulated beacon and sensor boards",
                "simulated",
                "simulated",
            ),
            (HARDWARE, "CTA hardware", "hardware", "hardware"),
            (
                Posing {
                    beacon_hardware: true,
                    sensor_hardware: false,
                },
                "CTA hardware with a simulated sensor board",
                "hardware",
                "simulated",
            ),
            (
                Posing {
                    beacon_hardware: false,
                    sensor_hardware: true,
                },
                "CTA hardware with a simulated beacon board",
                "simulated",
                "hardware",
            ),
        ] {
            if now == label {
                continue;
            }
            let other = boards(posing);
            let (b, s) = port(&other);
            let e = resume_on(&run, &other).unwrap_err();
            let said = format!(
                "{}: the run was recorded on {label} (its first session in journal.jsonl: \
                 beacon board on {}: {kind}, sensor board on {}: {kind}), but the boards \
                 answering now are {now} (beacon board on {}: {beacon_kind}, sensor board on \
                 {}: {sensor_kind}): data.csv would hold points of both under one header. Not \
                 resuming, nothing was changed: resume the run on {label} again, or start a \
                 new run with --out for these boards",
                run.display(),
                b0.display(),
                s0.display(),
                b.display(),
                s.display()
            );
            assert_eq!(e, said);
            // Nothing cut, nothing journalled: the uncommitted rows are still there.
            assert_eq!(read(&run.join("data.csv")), data, "{now}: data touched");
            assert_eq!(
                read(&run.join("journal.jsonl")),
                journal,
                "{now}: journal touched"
            );
            assert_eq!(read(&run.join("plan.toml")), plan_toml);
        }
        // On the run's kind of boards it resumes: the leftovers cut and measured again.
        let same = boards(first);
        assert_eq!(resume_on(&run, &same).unwrap().ending, Ending::Complete);
        assert_eq!(
            without_clock(&read(&run.join("data.csv"))),
            without_clock(&full)
        );
        assert!(
            last_session(&run).contains("data.csv: set aside"),
            "{}",
            last_session(&run)
        );
    }
}

/// A resume decides what to cut before the boards are opened, but cuts it only once they
/// answered: one that stops at its boards (a port that does not open) leaves the run as it was,
/// the uncommitted rows included, for the resume that does go ahead to say what it discards.
#[test]
fn a_resume_whose_boards_do_not_answer_changes_nothing() {
    let d = TestDir::new("sweep-checks-no-boards");
    let plan = write_plan(&d, PORTS_PLAN);
    let run = d.join("run");
    let first = boards(Posing::default());
    let s = sweep::sweep(&SweepOptions {
        plan: Some(plan),
        out: Some(run.clone()),
        ..on_ports(&first)
    })
    .unwrap();
    assert_eq!(s.ending, Ending::Complete);
    let full = read(&run.join("data.csv"));
    crash_after(&run, 4);
    let journal = read(&run.join("journal.jsonl"));
    let gone = d.join("no-such-port");
    let e = sweep::sweep(&SweepOptions {
        resume: Some(run.clone()),
        beacon: Some(gone.display().to_string()),
        ..on_ports(&first)
    })
    .map(|_| ())
    .unwrap_err();
    assert!(
        format!("{e:#}").contains(&gone.display().to_string()),
        "{e:#}"
    );
    assert_eq!(
        without_clock(&read(&run.join("data.csv"))),
        without_clock(&full),
        "data.csv cut"
    );
    assert_eq!(read(&run.join("journal.jsonl")), journal, "journal touched");
    // The resume that goes ahead cuts the leftovers, says so, and completes the run.
    assert_eq!(resume_on(&run, &first).unwrap().ending, Ending::Complete);
    assert!(last_session(&run).contains("data.csv: set aside"));
    assert_eq!(
        without_clock(&read(&run.join("data.csv"))),
        without_clock(&full)
    );
}

/// The last point whose data end within the first `len` bytes of the run's data file, by the
/// journal: (its index, its end).
fn last_whole(run: &Path, len: u64) -> (u64, u64) {
    journal(run)
        .lines()
        .filter(|l| l.contains("\"event\":\"point\""))
        .map(|l| (journal_field(l, "i"), journal_field(l, "csv_end")))
        .rfind(|&(_, end)| end <= len)
        .unwrap()
}

/// A data file cut short (a copy that stopped, a disk that filled, a slip of `truncate`):
/// the resume says which points the file still holds whole, checked against their hashes,
/// and what to do, changing nothing. With `--recover-truncated` it continues after that
/// point, keeps what it cuts in `recovered-1/`, and measures the rest again: on the simulated
/// CTA the data are the uninterrupted run's.
#[test]
fn a_data_file_cut_short_names_what_it_holds_and_recovers_on_request() {
    let (_d, run) = complete_run("cut-short");
    let full = read(&run.join("data.csv"));
    let journal_before = read(&run.join("journal.jsonl"));
    // Cut in the middle of a row, past half of the file.
    let len = full.len() as u64 * 3 / 5;
    let (i, whole) = last_whole(&run, len);
    assert!(whole < len && i < 29, "{i} {whole} {len}");
    let cut = full.as_bytes()[..len as usize].to_vec();
    std::fs::write(run.join("data.csv"), &cut).unwrap();
    let before = snapshot(&run);
    let e = resume(&run).unwrap_err();
    let dp = run.join("data.csv").display().to_string();
    assert!(
        e.contains(&format!(
            "{dp}: {len} bytes, but the journal committed {} (through point 29): the data file \
             was cut short. It still holds points 0 to {i} whole (its first {whole} bytes are as \
             written: checked against the hash journalled with point {i}); the rows of points {} \
             to 29 are gone from it. Not resuming, nothing was changed.",
            full.len(),
            i + 1
        )) && e.contains(&format!(
            "or continue from point {} with `cta sweep --resume {} --recover-truncated`",
            i + 1,
            run.display()
        )),
        "{e}"
    );
    assert_eq!(snapshot(&run), before, "the refusal changed the run");

    // The same file, edited within the bytes left: refused even with the recovery, as an
    // edited file is.
    let mut edited = cut.clone();
    let k = edited.len() / 2
        + edited[edited.len() / 2..]
            .iter()
            .position(|c| c.is_ascii_digit())
            .unwrap();
    edited[k] = if edited[k] == b'7' { b'8' } else { b'7' };
    std::fs::write(run.join("data.csv"), &edited).unwrap();
    let recover = |run: &Path| {
        sweep::sweep(&SweepOptions {
            no_sync: true,
            recover_truncated: true,
            ..resume_args(run)
        })
        .map_err(|e| format!("{e:#}"))
    };
    let e = recover(&run).unwrap_err();
    assert!(
        e.contains("not what was written") && e.contains("Not resuming"),
        "{e}"
    );
    assert_eq!(std::fs::read(run.join("data.csv")).unwrap(), edited);
    assert!(!run.join("recovered-1").exists());

    // The file as cut: recovered. The plate is where the run last recorded it (25 in, cut
    // from the journal with the points after point i), so the point after i, at 15 in, asks
    // for it to be moved rather than taken as still there.
    std::fs::write(run.join("data.csv"), &cut).unwrap();
    {
        let plan = Plan::load(&run.join("plan.toml")).unwrap();
        let opened = RunDir::resume_recovering(&run, false, &plan, None, true).unwrap();
        assert_eq!(opened.next_point(), i as usize + 1);
        assert_eq!(plan.point(opened.next_point()).sep_idx, 1);
        assert_eq!(opened.plate.as_ref().map(|p| p.sep_idx), Some(2));
    }
    assert_eq!(
        std::fs::read(run.join("data.csv")).unwrap(),
        cut,
        "opened is not begun"
    );
    let s = recover(&run).unwrap();
    assert_eq!(s.ending, Ending::Complete);
    assert_eq!(
        s.stats.ok + s.stats.no_signal + s.stats.partial,
        29 - i as usize
    );
    assert_eq!(
        without_clock(&read(&run.join("data.csv"))),
        without_clock(&full),
        "not the uninterrupted run's data"
    );
    // What was cut is kept: the journal's lines after point i, the bytes past it.
    let kept = run.join("recovered-1");
    let line = journal_before
        .find(&format!("{{\"event\":\"point\",\"i\":{i},"))
        .unwrap();
    let at = line + journal_before[line..].find('\n').unwrap() + 1;
    assert_eq!(read(&kept.join("journal-tail.jsonl")), journal_before[at..]);
    assert_eq!(
        std::fs::read(kept.join("data-tail.csv")).unwrap(),
        &cut[whole as usize..]
    );
    // The journal holds what it held up to point i, then the recovering session with its note.
    let j = read(&run.join("journal.jsonl"));
    assert!(j.starts_with(&journal_before[..at]));
    let note = format!(
        "data.csv: cut short at {len} bytes, where the journal committed {} (through point 29): \
         resuming after point {i}, the last it holds whole",
        full.len()
    );
    assert!(last_session(&run).contains(&note), "{}", last_session(&run));
}

/// `--resume` and `--status` name a run directory that does not exist, or a file given for
/// one (with its run when it is a run's file); `--out` names a file where its folder would be;
/// `--plan` names a measurement file given as the plan. Nothing is created.
#[test]
fn paths_of_the_wrong_kind_are_named() {
    let (d, run) = complete_run("paths");
    let missing = d.join("run2");
    let e = resume(&missing).unwrap_err();
    assert_eq!(
        e,
        format!(
            "{}: does not exist: there is no run there (--resume takes the folder a run was \
             started in with --out; a run is started with `cta sweep --plan PLAN.toml --out \
             RUN_DIR`)",
            missing.display()
        )
    );
    let e = format!("{:#}", sweep::status::status(&missing).unwrap_err());
    assert!(
        e.contains("does not exist") && e.contains("--status"),
        "{e}"
    );
    let e = resume(&run.join("data.csv")).unwrap_err();
    assert!(
        e.contains("data.csv: is a file, not a run directory")
            && e.contains(&format!("`cta sweep --resume {}`", run.display())),
        "{e}"
    );
    // --out on a file, and under one.
    let csv = run.join("data.csv");
    let plan = d.join("plan.toml");
    for out in [csv.clone(), csv.join("run")] {
        let e = format!("{:#}", sweep::sweep(&sweep_args(&plan, &out)).unwrap_err());
        assert!(
            e.starts_with(&format!(
                "{}: is a file, not a folder: --out names the folder a new run creates",
                csv.display()
            )) && e.contains("nothing was started"),
            "{e}"
        );
    }
    // A measurement file given as the plan.
    let e = format!(
        "{:#}",
        sweep::sweep(&sweep_args(&csv, &d.join("new"))).unwrap_err()
    );
    assert!(
        e.contains("does not look like a plan TOML file") && e.contains("a CSV header or row"),
        "{e}"
    );
    assert!(!d.join("new").exists() && !missing.exists());
}

/// Resuming a run whose every point is committed says so and opens no board: a hardware run
/// needs no ports for it (these boards are gone). Nothing is written when the journal already
/// ends with the complete stop; a run killed between its last point and its stop gets that
/// stop, and a manifest that says complete.
#[test]
fn a_complete_run_resumed_says_so_and_opens_no_board() {
    let (_d, run) = complete_run("complete");
    let before = snapshot(&run);
    let s = resume(&run).unwrap();
    assert!(s.already_complete && s.ending == Ending::Complete, "{s:?}");
    assert_eq!((s.next_point, s.points, s.stats.samples), (30, 30, 0));
    assert_eq!(snapshot(&run), before, "a complete run was written to");

    let d = TestDir::new("sweep-checks-complete-ports");
    let plan = write_plan(&d, PORTS_PLAN);
    let hw = d.join("hw");
    {
        let b = boards(HARDWARE);
        let s = sweep::sweep(&SweepOptions {
            plan: Some(plan),
            out: Some(hw.clone()),
            ..on_ports(&b)
        })
        .unwrap();
        assert_eq!(s.ending, Ending::Complete);
    }
    // Killed after its last point: no stop, the manifest still running.
    let j = read(&hw.join("journal.jsonl"));
    let last_point = j.rfind("{\"event\":\"point\"").unwrap();
    let end = last_point + j[last_point..].find('\n').unwrap() + 1;
    std::fs::write(hw.join("journal.jsonl"), &j[..end]).unwrap();
    let m = read(&hw.join("manifest.json")).replace("\"complete\"", "\"running\"");
    std::fs::write(hw.join("manifest.json"), m).unwrap();
    let s = resume(&hw).unwrap();
    assert!(s.already_complete, "{s:?}");
    let j = read(&hw.join("journal.jsonl"));
    assert!(
        j[end..].starts_with("{\"event\":\"stop\"") && j[end..].contains("\"reason\":\"complete\""),
        "{}",
        &j[end..]
    );
    assert_eq!(j[end..].lines().count(), 1, "{}", &j[end..]);
    assert!(read(&hw.join("manifest.json")).contains("\"state\": \"complete\""));
}

/// `--sim-realtime` is journalled with the session: a resume keeps the mode the last session
/// ran in, and a change (`--sim-realtime` on an unthrottled run, `--sim-unthrottled` on a
/// real-time one) is said in a note.
#[test]
fn the_simulated_ctas_real_time_is_kept_on_resume() {
    let d = TestDir::new("sweep-checks-realtime");
    let plan = write_plan(
        &d,
        "separations_in = [20]\nbeacons = [44, 45, 54, 55]\nsamples = 2\nsettle_ms = 0\n\
         rate_hz = 50\n",
    );
    let run = d.join("run");
    sweep::sweep(&SweepOptions {
        no_sync: true,
        sim_realtime: true,
        ..sweep_args(&plan, &run)
    })
    .unwrap();
    let realtime = |run: &Path| {
        let s = last_session(run);
        assert!(s.contains("\"realtime\":"), "{s}");
        s.contains("\"realtime\":true")
    };
    assert!(realtime(&run));
    crash_after(&run, 1);
    resume(&run).unwrap();
    assert!(realtime(&run), "the resume dropped --sim-realtime");
    assert!(
        !last_session(&run).contains("from this session on"),
        "{}",
        last_session(&run)
    );
    crash_after(&run, 2);
    sweep::sweep(&SweepOptions {
        no_sync: true,
        sim_unthrottled: true,
        ..resume_args(&run)
    })
    .unwrap();
    assert!(!realtime(&run));
    assert!(
        last_session(&run).contains(
            "simulated unthrottled from this session on (--sim-unthrottled); the last session \
             ran in real time (--sim-realtime)"
        ),
        "{}",
        last_session(&run)
    );
    crash_after(&run, 3);
    sweep::sweep(&SweepOptions {
        no_sync: true,
        sim_realtime: true,
        ..resume_args(&run)
    })
    .unwrap();
    assert!(realtime(&run));
    assert!(
        last_session(&run).contains("simulated in real time from this session on"),
        "{}",
        last_session(&run)
    );
}

/// A plan's `[metadata]` is journalled with each session's plan, in the manifest and in
/// `--status`; a resume may bring it up to date (a note says what changed), the earlier
/// session keeping the metadata it ran under, and the data are those of an unchanged run.
#[test]
fn metadata_is_journalled_shown_and_may_change_on_resume() {
    let d = TestDir::new("sweep-checks-metadata");
    let first =
        "[metadata]\noperator = \"A. Lab\"\nsensor_serial = \"NS-0412\"\ntemperature_c = 21.5\n";
    let plan = write_plan(&d, &format!("{PLAN}{first}"));
    let run = d.join("run");
    let s = sweep::sweep(&SweepOptions {
        no_sync: true,
        sim_seed: Some(5),
        ..sweep_args(&plan, &run)
    })
    .unwrap();
    assert_eq!(s.ending, Ending::Complete);
    let full = read(&run.join("data.csv"));
    let manifest = |run: &Path| -> serde_json::Value {
        serde_json::from_str(&read(&run.join("manifest.json"))).unwrap()
    };
    let m = manifest(&run);
    assert_eq!(m["metadata"]["sensor_serial"], "NS-0412");
    assert_eq!(m["metadata"]["temperature_c"], 21.5);
    assert_eq!(m["plan"]["metadata"], m["metadata"]);
    let st = sweep::status::status(&run).unwrap();
    assert!(
        st.render().contains(
            "  metadata: operator = \"A. Lab\", sensor_serial = \"NS-0412\", temperature_c = 21.5\n"
        ),
        "{}",
        st.render()
    );
    assert_eq!(st.to_json()["plan"]["metadata"]["operator"], "A. Lab");

    // Stopped at point 20; the afternoon shift resumes, warmer.
    crash_after(&run, 20);
    let second = first.replace("A. Lab", "B. Lab").replace("21.5", "23.0");
    std::fs::write(run.join("plan.toml"), format!("{PLAN}{second}")).unwrap();
    assert_eq!(resume(&run).unwrap().ending, Ending::Complete);
    let session = last_session(&run);
    assert!(
        session.contains(
            "plan.toml: [metadata] changed since the last session (as recorded in journal.jsonl): \
             `operator`: \\\"A. Lab\\\" -> \\\"B. Lab\\\"; `temperature_c`: 21.5 -> 23.0; it \
             describes the run"
        ) && session.contains("\"temperature_c\":23.0"),
        "{session}"
    );
    // The measured values as an uninterrupted run's (the clock columns aside).
    assert_eq!(
        without_clock(&read(&run.join("data.csv"))),
        without_clock(&full)
    );
    let m = manifest(&run);
    assert_eq!(m["metadata"]["operator"], "B. Lab");
    let sessions: Vec<&serde_json::Value> = m["sessions"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| s["plan"].is_object())
        .collect();
    assert_eq!(sessions.len(), 2);
    assert_eq!(sessions[0]["plan"]["metadata"]["operator"], "A. Lab");
    assert_eq!(sessions[1]["plan"]["metadata"]["operator"], "B. Lab");

    // With another change, the metadata is named among what alone would be accepted.
    crash_after(&run, 25);
    std::fs::write(
        run.join("plan.toml"),
        format!("{}{first}", PLAN.replace("samples = 4", "samples = 5")),
    )
    .unwrap();
    let e = resume(&run).unwrap_err();
    assert!(
        e.contains("`samples`: 4 -> 5")
            && e.contains("(the change of `metadata` alone would be accepted)"),
        "{e}"
    );
}
