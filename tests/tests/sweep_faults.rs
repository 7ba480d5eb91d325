//! `cta sweep` through faults injected into the simulated boards: dropped and corrupted
//! bytes on both serial lines, a board unplugged mid-run and plugged back, a silent board,
//! a stalled sensor. The run pauses, reconnects, retries and completes with every point
//! exactly once; without byte damage the data equal a fault-free run with the same seed.
//! Also: ports that answer as the wrong board, ports that do not exist.

use std::path::Path;

use cta_host::measurement::Dataset;
use cta_host::sweep::plan::Plan;
use cta_host::sweep::sim::{SimCta, SimSettings};
use cta_host::sweep::{self, engine::Ending, SweepArgs};
use cta_tests::{data_rows, journal, journal_field, sweep_args, write_plan, TestDir};

const PLAN: &str = r#"
name = "fault test"
separations_in = [5, 15, 25]
beacons = [0, 19, 45, 80, 99]
frequencies_hz = [4050]
power_levels = [2]
sensitivities = [2, 4]
samples = 6
settle_ms = 0
[timing]
request_timeout_ms = 60
retries = 2
report_timeout_ms = 150
no_signal_reports = 5
backoff_max_s = 0.2
give_up_s = 30
"#;

/// A test directory holding [`PLAN`] as `plan.toml`.
fn dir(name: &str) -> TestDir {
    let d = TestDir::new(&format!("sweep-faults-{name}"));
    write_plan(&d, PLAN);
    d
}

fn args(d: &Path, out: &str, faults: Option<&str>) -> SweepArgs {
    SweepArgs {
        no_sync: true,
        sim_seed: Some(3),
        sim_noise: Some(20.0),
        sim_fault: faults.map(String::from),
        ..sweep_args(&d.join("plan.toml"), &d.join(out))
    }
}

/// Every plan point committed once, in order.
fn points_once(run: &Path, n: usize) {
    let j = journal(run);
    let idx: Vec<u64> = j
        .lines()
        .filter(|l| l.contains("\"event\":\"point\""))
        .map(|l| journal_field(l, "i"))
        .collect();
    assert_eq!(idx, (0..n as u64).collect::<Vec<_>>());
}

#[test]
fn unplugged_silent_and_stalled_boards_pause_and_resume_with_identical_data() {
    let d = dir("vanish");
    let clean = sweep::sweep(&args(&d, "clean", None)).unwrap();
    assert_eq!(clean.ending, Ending::Complete);
    let spec = "vanish=sensor@4:400,vanish=beacon@9:400,silent=beacon@14:300,stall=sensor@20:500,silent=sensor@25:200";
    let s = sweep::sweep(&args(&d, "faulty", Some(spec))).unwrap();
    assert_eq!(s.ending, Ending::Complete);
    assert!(s.stats.faults >= 5, "{:?}", s.stats);
    assert!(s.stats.reconnects >= 2, "{:?}", s.stats);
    points_once(&d.join("faulty"), clean.points);
    // The retried points were measured again from scratch: same data as without faults.
    assert_eq!(data_rows(&d.join("clean")), data_rows(&d.join("faulty")));
    let j = journal(&d.join("faulty"));
    assert!(j.contains("\"board\":\"beacon\"") && j.contains("\"board\":\"sensor\""));
    assert!(j.contains("no spot report"), "the stall is journalled");
    let m = std::fs::read_to_string(d.join("faulty/manifest.json")).unwrap();
    assert!(m.contains("retry point"));
}

#[test]
fn dropped_and_corrupted_bytes_lose_nothing() {
    let d = dir("bytes");
    let s = sweep::sweep(&args(&d, "run", Some("drop=0.0005,corrupt=0.0005"))).unwrap();
    assert_eq!(s.ending, Ending::Complete);
    points_once(&d.join("run"), s.points);
    let data = Dataset::read(&sweep::data_path(&d.join("run"))).unwrap();
    // Every point with signal has exactly its samples, numbered 0..n.
    for p in data.points() {
        let k: Vec<u32> = p
            .rows
            .iter()
            .map(|&r| data.samples[r].sample.unwrap())
            .collect();
        assert_eq!(k, (0..6).collect::<Vec<_>>());
    }
    assert!(
        s.stats.lost_reports > 0 || s.stats.faults > 0,
        "{:?}",
        s.stats
    );
}

#[test]
fn wrong_or_missing_ports_are_named() {
    let d = dir("ports");
    let plan = Plan::parse("plan.toml", PLAN).unwrap();
    let sim = SimCta::spawn(&plan, &SimSettings::default()).unwrap();
    let mut a = args(&d, "swapped", None);
    a.sim_seed = None;
    a.sim_noise = None;
    a.yes = true;
    a.beacon = Some(sim.sensor_path().display().to_string());
    a.sensor = Some(sim.beacon_path().display().to_string());
    let e = format!("{:#}", sweep::sweep(&a).unwrap_err());
    assert!(
        e.contains("expected a beacon board") && e.contains("a sensor board"),
        "{e}"
    );
    assert!(e.contains(&sim.sensor_path().display().to_string()), "{e}");
    assert!(
        !d.join("swapped").exists(),
        "no run directory for a run that never started"
    );
    a.out = Some(d.join("missing"));
    a.beacon = Some("/dev/cta-no-such-port".into());
    let e = format!("{:#}", sweep::sweep(&a).unwrap_err());
    assert!(
        e.contains("/dev/cta-no-such-port") && e.contains("beacon"),
        "{e}"
    );
}

#[test]
fn giving_up_names_the_board_that_stayed_away() {
    let d = dir("give-up");
    write_plan(&d, &PLAN.replace("give_up_s = 30", "give_up_s = 0.5"));
    let s = sweep::sweep(&args(&d, "run", Some("vanish=beacon@2:5000"))).unwrap();
    match &s.ending {
        Ending::GaveUp(what) => assert!(what.starts_with("beacon: "), "{what}"),
        e => panic!("{e:?}"),
    }
}
