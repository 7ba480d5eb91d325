//! The run directory's unit tests.

use super::*;

/// Corners within +/-5 mils of their mean pass; one 6 mils high is asked about.
#[test]
fn corners_beyond_ch_iv_levelness_are_questioned() {
    assert!(levelness_question(&[10.0, 10.004, 9.996, 10.0]).is_none());
    // Exactly 5 mils at any separation (unrounded, 10.005 - 10 is above 0.005).
    for sep in [10.0, 12.0, 20.0, 30.0] {
        let c = [sep + 0.005, sep - 0.005, sep, sep];
        assert!(levelness_question(&c).is_none(), "{c:?}");
        assert_eq!(corner_uncertainty(&c), 0.005);
    }
    assert!(levelness_question(&[]).is_none());
    let q = levelness_question(&[10.008, 10.0, 10.0, 10.0]).unwrap();
    assert!(
        q.contains("up to 6.0 mils") && q.contains("Keep them?"),
        "{q}"
    );
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("cta-store-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn plan() -> Plan {
    Plan::parse("plan.toml", "separations_in = [10]\nsamples = 1\n").unwrap()
}

fn new_run(d: &Path) -> RunDir {
    RunDir::create(d, "samples = 1\n", &["test".into()], false, false).unwrap()
}

/// A `separation` line of an earlier version, with `spread` (the corners' standard
/// deviation), still loads: its uncertainty is Ch IV's, derived again from the corners, and
/// it is written back under the new name.
#[test]
fn an_older_separation_line_loads_with_the_ch_iv_uncertainty() {
    let old = r#"{"event":"separation","sep_idx":2,"nominal":10.0,"corners":[10.006,9.998,9.998,9.998],"mean":10.0,"spread":0.004,"source":"operator"}"#;
    let Event::Separation(e) = serde_json::from_str::<Event>(old).unwrap() else {
        panic!("not a separation");
    };
    assert_eq!((e.sep_idx, e.mean, e.corners.len()), (2, 10.0, 4));
    assert!((e.uncertainty - 0.006).abs() < 1e-9, "{e:?}");
    let line = serde_json::to_string(&Event::Separation(e.clone())).unwrap();
    assert!(
        line.contains("\"uncertainty\":") && !line.contains("spread"),
        "{line}"
    );
    assert_eq!(
        serde_json::from_str::<Event>(&line).unwrap(),
        Event::Separation(e)
    );
    // Not measured (`--yes`): nothing to derive, the recorded 0 is kept.
    let scripted = r#"{"event":"separation","sep_idx":0,"nominal":5.0,"corners":[],"mean":5.0,"spread":0.0,"source":"scripted (--yes): nominal, not measured"}"#;
    let Event::Separation(e) = serde_json::from_str::<Event>(scripted).unwrap() else {
        panic!("not a separation");
    };
    assert_eq!((e.mean, e.uncertainty), (5.0, 0.0));
}

#[test]
fn one_session_at_a_time_and_a_dead_holder_is_taken_over() {
    let d = tmp("lock");
    let a = new_run(&d);
    let me = std::process::id().to_string();
    assert_eq!(std::fs::read_to_string(d.join(LOCK)).unwrap().trim(), me);
    // A second session (a second process, or a second open here: flock locks are per
    // open file) is refused, naming the lock file and the holder.
    for e in [
        RunDir::open(&d, false, &plan()).err().unwrap(),
        RunDir::create(&d, "samples = 1\n", &[], true, false)
            .err()
            .unwrap(),
    ] {
        let e = format!("{e:#}");
        assert!(e.contains(&d.join(LOCK).display().to_string()), "{e}");
        assert!(e.contains(&format!("pid {me}")), "{e}");
    }
    assert!(d.join(DATA).exists(), "--force did not remove a live run");
    // Released at the end of the session: the next one opens without a note.
    drop(a);
    assert_eq!(std::fs::read_to_string(d.join(LOCK)).unwrap(), "");
    let b = RunDir::open(&d, false, &plan()).unwrap();
    assert!(b.notes.is_empty(), "{:?}", b.notes);
    drop(b);
    // A holder killed with SIGKILL leaves its pid but no lock: taken over, with a note.
    std::fs::write(d.join(LOCK), "4000000\n").unwrap();
    let c = RunDir::open(&d, false, &plan()).unwrap();
    assert!(
        c.notes
            .iter()
            .any(|n| n.contains("took over") && n.contains("4000000")),
        "{:?}",
        c.notes
    );
    assert_eq!(std::fs::read_to_string(d.join(LOCK)).unwrap().trim(), me);
    drop(c);
    let _ = std::fs::remove_dir_all(&d);
}
