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
        // The latest reconnection's own error, with the port: not "no board connected".
        Ending::GaveUp(what) => assert!(
            what.starts_with("beacon: cannot reconnect: ")
                && what.contains("/beacon")
                && what.contains("No such file or directory"),
            "{what}"
        ),
        e => panic!("{e:?}"),
    }
}

/// Boards that restart behind the sweep's back, the port staying up (a watchdog, a
/// brown-out): the beacon board as a point starts (its LED goes dark: without a check the
/// point would be committed as "no signal" and never measured again), the sensor board
/// between points (it comes back at sensitivity 4: without a check the next points of the
/// sensitivity-2 group would be recorded as sensitivity 2). Each is found, journalled and
/// the point measured again: the data equal a run without resets.
#[test]
fn boards_reset_behind_the_sweep_are_measured_again() {
    let d = dir("reset");
    let clean = sweep::sweep(&args(&d, "clean", None)).unwrap();
    // The plan's groups are 5 beacons at one sensitivity: a sensor reset after the 2nd and
    // the 7th stream lands inside a group either way, one of them a sensitivity-2 group.
    let spec = "reset=beacon@4,reset=sensor@2,reset=sensor@7,reset=beacon@20";
    let s = sweep::sweep(&args(&d, "reset", Some(spec))).unwrap();
    assert_eq!(s.ending, Ending::Complete);
    points_once(&d.join("reset"), clean.points);
    assert_eq!(data_rows(&d.join("clean")), data_rows(&d.join("reset")));
    let j = journal(&d.join("reset"));
    let faults: Vec<&str> = j
        .lines()
        .filter(|l| l.contains("\"event\":\"fault\""))
        .collect();
    let led_off = faults
        .iter()
        .filter(|l| l.contains("\"board\":\"beacon\"") && l.contains("LED is off"))
        .count();
    assert_eq!(led_off, 2, "{faults:#?}");
    let sens = faults
        .iter()
        .filter(|l| {
            l.contains("\"board\":\"sensor\"")
                && l.contains(
                    "the detector reports sensitivity 4 in 3 reports in a row, the point's is 2",
                )
        })
        .count();
    assert_eq!(sens, 1, "{faults:#?}");
    assert_eq!(s.stats.faults, 3, "{:?}", s.stats);
}

/// A beacon board whose dead-man timeout is shorter than twice the plan's heartbeat would
/// darken points mid-way: the sweep refuses to start, naming the port, the timeout and the
/// command that sets it back.
#[test]
fn a_dead_man_timeout_too_short_for_the_heartbeat_is_refused() {
    use cta_core::wire::beacon::{BeaconRequest, Limits};
    use cta_host::link::{open_serial, Link, LinkConfig};
    let d = dir("deadman");
    let plan = Plan::parse("plan.toml", PLAN).unwrap();
    let sim = SimCta::spawn(&plan, &SimSettings::default()).unwrap();
    let beacon = sim.beacon_path().display().to_string();
    {
        let port = open_serial(&beacon).unwrap();
        let mut link = Link::<cta_core::wire::beacon::Beacon, _>::new(port, LinkConfig::default());
        link.call(BeaconRequest::SetLimits(Limits {
            deadman_ms: 1000,
            ..Limits::default()
        }))
        .unwrap();
    }
    let mut a = args(&d, "run", None);
    a.sim_seed = None;
    a.sim_noise = None;
    a.yes = true;
    a.beacon = Some(beacon.clone());
    a.sensor = Some(sim.sensor_path().display().to_string());
    let e = format!("{:#}", sweep::sweep(&a).unwrap_err());
    assert!(
        e.contains(&format!(
            "beacon board on {beacon}: its dead-man timeout is 1000 ms"
        )) && e.contains("limits --deadman-ms 10000"),
        "{e}"
    );
    assert!(
        !d.join("run").exists(),
        "no run directory for a run that never started"
    );
}

/// A beacon board reset long enough after the last reading is known by its uptime, which
/// went back (at the plan's real 10 Hz rate the run is seconds old when the 4th point
/// starts); the point is measured again.
#[test]
fn a_beacon_reset_is_known_by_its_uptime() {
    let d = TestDir::new("sweep-faults-uptime");
    write_plan(
        &d,
        r#"
name = "uptime"
separations_in = [15]
beacons = [19, 45, 80, 54]
frequencies_hz = [4050]
power_levels = [2]
sensitivities = [4]
samples = 5
settle_ms = 0
rate_hz = 10
"#,
    );
    let mut a = args(&d, "run", Some("reset=beacon@4"));
    a.sim_realtime = true;
    let s = sweep::sweep(&a).unwrap();
    assert_eq!(s.ending, Ending::Complete);
    points_once(&d.join("run"), 4);
    let j = journal(&d.join("run"));
    assert!(
        j.contains("the board was reset behind the sweep (up "),
        "{j}"
    );
    assert_eq!(s.stats.faults, 1, "{:?}", s.stats);
}
