//! What a sweep writes stays readable and what it measured is never thrown away: a plan
//! `name` with a line break stays one comment line of the data file; a frequency listed
//! twice is refused; a journal that lost its tail while the manifest says more was done is a
//! contradiction refused (and with `--recover-truncated` the bytes past the journal's last
//! point are kept aside, as uncommitted leftovers always are); a forged or copied journal
//! line is refused by its check; a journal written before the ISO 8601 `time` beside each
//! `at` resumes.

use std::path::{Path, PathBuf};

use cta_lab::data::Dataset;
use cta_lab::sweep::plan::Plan;
use cta_lab::sweep::stamp::iso8601;
use cta_lab::sweep::{self, engine::Ending, SweepOptions};
use cta_tests::{
    crash_after, data_lines, older_journal, resume_args, snapshot, sweep_args, without_clock,
    write_plan, TestDir,
};

const PLAN: &str = r#"
name = "journal checks"
separations_in = [5, 25]
beacons = [0, 45, 99]
sensitivities = [2, 4]
samples = 3
settle_ms = 0
[timing]
no_signal_reports = 4
"#;

/// A complete run of `plan` in a fresh directory; returns (test dir, run dir).
fn complete_run(name: &str, plan: &str) -> (TestDir, PathBuf) {
    let d = TestDir::new(&format!("sweep-journal-{name}"));
    let plan = write_plan(&d, plan);
    let run = d.join("run");
    let s = sweep::sweep(&SweepOptions {
        no_sync: true,
        sim_seed: Some(3),
        ..sweep_args(&plan, &run)
    })
    .unwrap();
    assert_eq!(s.ending, Ending::Complete);
    (d, run)
}

fn resume(run: &Path, recover: bool) -> Result<sweep::Summary, String> {
    sweep::sweep(&SweepOptions {
        no_sync: true,
        recover_truncated: recover,
        ..resume_args(run)
    })
    .map_err(|e| format!("{e:#}"))
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap()
}

/// Item 2 of the fault audit: free text in a data file's comments stays one comment line.
#[test]
fn a_plan_name_with_line_breaks_stays_one_comment_line() {
    let (_d, run) = complete_run(
        "name",
        &PLAN.replace(
            "name = \"journal checks\"",
            "name = \"two\\nlines\\rseparation_in,beacon_x_in,beacon_y_in,beacon_z_in,x,y\"",
        ),
    );
    let data = read(&run.join("data.csv"));
    let first = data.lines().next().unwrap();
    assert!(
        first.starts_with("# ") && first.contains("two lines"),
        "{first}"
    );
    let ds = Dataset::read(&run.join("data.csv")).unwrap();
    assert!(!ds.samples.is_empty());
}

/// Item 3: a frequency listed twice (or two spellings of one channel) is refused, naming the
/// file, the line and the key.
#[test]
fn a_frequency_listed_twice_is_refused() {
    let src = PLAN.replace(
        "samples = 3",
        "frequencies_hz = [4050, 3040, 4050]\nsamples = 3",
    );
    let e = Plan::parse("p.toml", &src).unwrap_err().to_string();
    assert!(
        e.starts_with("p.toml:6: key `frequencies_hz`") && e.contains("4050 Hz is listed twice"),
        "{e}"
    );
    let src = PLAN.replace(
        "samples = 3",
        "frequencies_hz = [4050, 4050.0001]\nsamples = 3",
    );
    let e = Plan::parse("p.toml", &src).unwrap_err().to_string();
    assert!(e.contains("one NorthStar frequency"), "{e}");
    let src = PLAN.replace("samples = 3", "frequencies_hz = [4050, 3040]\nsamples = 3");
    assert_eq!(Plan::parse("p.toml", &src).unwrap().frequencies_hz.len(), 2);
}

/// The journal's lines (`point` lines only: `"event":"point"`), as (start, end) byte ranges.
fn point_lines(j: &str) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut at = 0;
    for l in j.split_inclusive('\n') {
        if l.contains("\"event\":\"point\"") {
            out.push((at, at + l.len()));
        }
        at += l.len();
    }
    out
}

/// Item 1: the journal of a complete run cut in half. The manifest says every point was
/// done: a contradiction, refused with nothing changed; with `--recover-truncated` the run
/// continues from the journal's last point and every byte of data.csv past it is kept in
/// `recovered-1/` (on the simulator the re-measurement is the same, so the kept bytes are
/// the finished file's tail).
#[test]
fn a_journal_cut_short_never_deletes_measured_rows() {
    let (_d, run) = complete_run("cut-journal", PLAN);
    let full = read(&run.join("data.csv"));
    let j = read(&run.join("journal.jsonl"));
    let points = point_lines(&j);
    let half = (points[points.len() / 2].0 + points[points.len() / 2].1) / 2;
    std::fs::write(run.join("journal.jsonl"), &j[..half]).unwrap();
    let before = snapshot(&run);
    let e = resume(&run, false).unwrap_err();
    assert!(
        e.contains(&run.join("manifest.json").display().to_string())
            && e.contains(&format!("says {} points were done", points.len()))
            && e.contains(&format!("commits {}", points.len() / 2))
            && e.contains(&format!(
                "are as the manifest recorded them (checked against its hash): the rows of \
                 points {} to {} are whole in it",
                points.len() / 2,
                points.len() - 1
            ))
            && e.contains("Not resuming, nothing was changed")
            && e.contains("--recover-truncated"),
        "{e}"
    );
    assert_eq!(snapshot(&run), before, "the refusal changed the run");
    // A row past the journal's end changed: said not to be as recorded.
    let mut changed = full.clone().into_bytes();
    let k = changed.len() - 3;
    changed[k] = if changed[k] == b'1' { b'2' } else { b'1' };
    std::fs::write(run.join("data.csv"), &changed).unwrap();
    let e = resume(&run, false).unwrap_err();
    assert!(e.contains("are not as the manifest recorded them"), "{e}");
    std::fs::write(run.join("data.csv"), &full).unwrap();
    let s = resume(&run, true).unwrap();
    assert_eq!(s.ending, Ending::Complete);
    assert_eq!(
        without_clock(&read(&run.join("data.csv"))),
        without_clock(&full)
    );
    // What the journal no longer committed is kept, byte for byte.
    let end = cta_tests::journal_field(&j[points[points.len() / 2 - 1].0..], "csv_end") as usize;
    let kept = std::fs::read(run.join("recovered-1/data-tail.csv")).unwrap();
    assert_eq!(kept, full.as_bytes()[end..]);
    assert_eq!(
        read(&run.join("recovered-1/journal-tail.jsonl")),
        j[points[points.len() / 2].0..half]
    );
}

/// Uncommitted leftovers (a session killed between the rows and their journal line; the
/// manifest still saying what it said when the session started) are measured again, and
/// kept aside, not deleted.
#[test]
fn uncommitted_rows_are_kept_aside_not_deleted() {
    let (_d, run) = complete_run("leftovers", PLAN);
    let full = read(&run.join("data.csv"));
    let end = cta_tests::crash_after(&run, 5) as usize;
    // The manifest as the killed session left it: written when it started.
    let m = read(&run.join("manifest.json")).replace("\"done\": 12", "\"done\": 0");
    std::fs::write(run.join("manifest.json"), m).unwrap();
    assert_eq!(resume(&run, false).unwrap().ending, Ending::Complete);
    assert_eq!(
        without_clock(&read(&run.join("data.csv"))),
        without_clock(&full)
    );
    assert_eq!(
        std::fs::read(run.join("recovered-1/data-tail.csv")).unwrap(),
        full.as_bytes()[end..]
    );
}

/// Item 6: a copy of the last `point` line with its index raised (the run would end
/// "complete" without that point's rows), an edited line, a line copied verbatim: each is
/// refused by the journal's checks, naming the file and line, with nothing changed.
#[test]
fn a_forged_or_copied_journal_line_is_refused() {
    let (_d, run) = complete_run("forged", PLAN);
    let jp = run.join("journal.jsonl");
    let j = read(&jp);
    let points = point_lines(&j);
    // Cut after point 6, then the copy of point 6's line as point 7.
    let (s6, e6) = points[6];
    let line6 = &j[s6..e6];
    let forged = format!("{}{}", &j[..e6], line6.replace("\"i\":6,", "\"i\":7,"));
    let verbatim = format!("{}{line6}", &j[..e6]);
    let edited = j.replacen("\"samples\":3", "\"samples\":2", 1);
    // Without its chain: refused after lines that have one.
    let unchained = format!(
        "{}{}",
        &j[..e6],
        line6[..line6.rfind(",\"chain\"").unwrap()].to_string() + "}\n"
    );
    // A journal of an older version (no chains at all): the forged point is refused as one
    // that does not follow the point before.
    let strip = |t: &str| {
        t.split_inclusive('\n')
            .map(|l| match l.rfind(",\"chain\"") {
                Some(k) => format!("{}}}\n", &l[..k]),
                None => l.to_string(),
            })
            .collect::<String>()
    };
    let older = strip(&forged);
    let lineno = j[..e6].lines().count() + 1;
    for (what, text) in [
        ("older", older),
        ("forged", forged),
        ("verbatim", verbatim),
        ("edited", edited),
        ("unchained", unchained),
    ] {
        std::fs::write(&jp, &text).unwrap();
        let before = snapshot(&run);
        let e = resume(&run, false).unwrap_err();
        assert!(
            e.contains(&jp.display().to_string()) && e.contains("nothing was changed"),
            "{what}: {e}"
        );
        if what != "edited" {
            assert!(
                e.contains(&format!("journal.jsonl:{lineno}:")),
                "{what}: {e}"
            );
        }
        assert_eq!(
            snapshot(&run),
            before,
            "{what}: the refusal changed the run"
        );
    }
}

/// A journal line's chain as the sweep seals it (sweep/journal.rs, restated here so a journal
/// of the version before `time` can be written exactly as it wrote one): FNV-1a 64 over the
/// previous chain's little-endian bytes, then over the line's JSON without its chain.
fn sealed(text: &str) -> String {
    let fnv = |mut h: u64, bytes: &[u8]| {
        for &b in bytes {
            h = (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
        h
    };
    const START: u64 = 0xcbf2_9ce4_8422_2325;
    let mut prev = START;
    let mut out = String::new();
    for json in text.lines() {
        let h = fnv(fnv(START, &prev.to_le_bytes()), json.as_bytes());
        out.push_str(&format!(
            "{},\"chain\":\"{h:016x}\"}}\n",
            json.strip_suffix('}').unwrap()
        ));
        prev = h;
    }
    out
}

/// The `at` of a journal line (its first: the event's own, before any nested value).
fn at_of(l: &str) -> f64 {
    let from = l.find("\"at\":").unwrap() + 5;
    let to = from + l[from..].find([',', '}']).unwrap();
    l[from..to].parse().unwrap()
}

/// The journal lines' `time` fields removed: times as epoch seconds (`at`) alone.
fn epoch_only(text: &str) -> String {
    text.lines()
        .map(|l| match l.find(",\"time\":\"") {
            Some(a) => {
                let b = a + 9 + l[a + 9..].find('"').unwrap() + 1;
                format!("{}{}\n", &l[..a], &l[b..])
            }
            None => format!("{l}\n"),
        })
        .collect()
}

/// Every time the sweep journals is there twice, `at` (seconds since the epoch) and `time`
/// (ISO 8601 UTC); a run made by the version before `time` (its journal sealed as that
/// version sealed it, with `at` alone), killed after 7 points, still resumes, to the data of
/// the uninterrupted run, and the lines the resume adds carry both times again.
#[test]
fn a_journal_with_epoch_times_alone_resumes() {
    let (_d, run) = complete_run("epoch", PLAN);
    let full = data_lines(&run);
    let jp = run.join("journal.jsonl");
    let j = read(&jp);
    let mut timed = 0;
    for l in j.lines().filter(|l| l.contains("\"at\":")) {
        let at = at_of(l);
        let iso = iso8601(at).unwrap();
        assert!(
            l.contains(&format!("\"at\":{at},\"time\":\"{iso}\"")),
            "{l}"
        );
        timed += 1;
    }
    // A session, a point per committed point, a stop at least.
    assert!(timed >= point_lines(&j).len() + 2, "{j}");
    crash_after(&run, 7);
    let before = older_journal(&read(&jp));
    let old = sealed(&epoch_only(&before));
    assert!(
        !old.contains("\"time\"") && old.contains("\"at\":"),
        "{old}"
    );
    assert_eq!(point_lines(&old).len(), 7);
    std::fs::write(&jp, &old).unwrap();
    let s = resume(&run, false).unwrap();
    assert_eq!(s.ending, Ending::Complete);
    assert_eq!(
        data_lines(&run),
        full,
        "the resumed data differ from the uninterrupted run's"
    );
    let after = read(&jp);
    assert!(
        after.starts_with(&old),
        "the resume rewrote the older lines"
    );
    let added = &after[old.len()..];
    assert!(added.contains("\"event\":\"session\""), "{added}");
    for l in added.lines().filter(|l| l.contains("\"at\":")) {
        let at = at_of(l);
        let iso = iso8601(at).unwrap();
        assert!(l.contains(&format!("\"time\":\"{iso}\"")), "{l}");
    }
}
