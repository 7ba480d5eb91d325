//! `cta sweep` through faults injected into the simulated boards: dropped and corrupted
//! bytes on both serial lines, a board unplugged mid-run and plugged back, a silent board,
//! a stalled sensor. The run pauses, reconnects, retries and completes with every point
//! exactly once; without byte damage the data equal a fault-free run with the same seed.
//! Also: ports that answer as the wrong board, ports that do not exist.

use std::path::Path;

use cta_lab::data::Dataset;
use cta_lab::sweep::plan::Plan;
use cta_lab::sweep::sim::{SimCta, SimSettings};
use cta_lab::sweep::{self, engine::Ending, SweepOptions};
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

fn args(d: &Path, out: &str, faults: Option<&str>) -> SweepOptions {
    SweepOptions {
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
/// between points (it comes back at sensitivity 4 and 10 Hz: without a check the next points
/// of the sensitivity-2 group would be recorded as sensitivity 2). Each is found, journalled
/// with the board's reset cause and the point measured again: the data equal a run without
/// resets.
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
    // The beacon board's uptime went back since the restore before the point (it used to be
    // found by its dark LED only: the uptime check left 1 s of slack).
    let beacon = faults
        .iter()
        .filter(|l| {
            l.contains("\"board\":\"beacon\"")
                && l.contains("the board was reset behind the sweep (up ")
                && l.contains("last reset: watchdog): its LEDs went dark")
        })
        .count();
    assert_eq!(beacon, 2, "{faults:#?}");
    // Both sensor resets, the one in the sensitivity-4 group too, by the board's counters
    // at the next point's first report: before its sensitivity is looked at. (Streams 3 and
    // 4 are point 2's first two attempts, so the 7th stream is point 4's.)
    let sensor: Vec<&&str> = faults
        .iter()
        .filter(|l| l.contains("\"board\":\"sensor\""))
        .collect();
    assert_eq!(sensor.len(), 2, "{faults:#?}");
    for (l, point) in sensor.iter().zip([2, 5]) {
        assert!(
            l.contains("the board was reset behind the sweep (its report counter went from ")
                && l.contains(
                    "last reset: watchdog): it is at sensitivity 4, 10 Hz, the point's are "
                )
                && journal_field(l, "point") == point,
            "{l}"
        );
    }
    assert_eq!(s.stats.faults, 4, "{:?}", s.stats);
}

/// A plan at 20 Hz and sensitivity 4, the sensor board's start-up sensitivity.
const PLAN_20HZ: &str = r#"
name = "20 Hz"
separations_in = [10]
beacons = [0, 19, 45, 80, 99]
frequencies_hz = [4050]
power_levels = [2]
sensitivities = [4]
samples = 6
settle_ms = 0
rate_hz = 20
[timing]
request_timeout_ms = 60
retries = 2
report_timeout_ms = 150
no_signal_reports = 5
backoff_max_s = 0.2
give_up_s = 30
"#;

/// A sensor board reset between two points of a sensitivity-4 group: its reports carry the
/// point's sensitivity, so nothing in them but its report counter and clock, which start
/// again, tells the reset; and it comes back at 10 Hz, not the plan's 20 Hz, for the rest of
/// the run (the sweep used to notice neither). It is found at the next point's first report,
/// before anything of it is recorded, journalled with the board's reset cause, the board's
/// settings restored and the point measured again: the data equal a run without the reset,
/// and the board ends the run at the plan's rate.
#[test]
fn a_sensor_reset_at_its_start_up_sensitivity_is_found_and_its_rate_restored() {
    use cta_core::wire::sensor::{SensorProtocol, SensorRequest, SensorResponse};
    use cta_core::wire::ResetCause;
    use cta_lab::boards::link::{open_serial, Link, LinkConfig};
    let d = TestDir::new("sweep-faults-sensor-reset");
    write_plan(&d, PLAN_20HZ);
    let plan = Plan::parse("plan.toml", PLAN_20HZ).unwrap();
    // On ports, to ask the sensor board for its status after the run.
    let run = |out: &str, faults: &str| {
        let settings = SimSettings {
            faults: cta_lab::sweep::sim::Faults::parse(faults).unwrap(),
            ..SimSettings::default()
        };
        let sim = SimCta::spawn(&plan, &settings).unwrap();
        let a = SweepOptions {
            no_sync: true,
            yes: true,
            beacon: Some(sim.beacon_path().display().to_string()),
            sensor: Some(sim.sensor_path().display().to_string()),
            ..sweep_args(&d.join("plan.toml"), &d.join(out))
        };
        let s = sweep::sweep(&a).unwrap();
        let port = open_serial(&sim.sensor_path().display().to_string()).unwrap();
        let mut link = Link::<SensorProtocol, _>::new(port, LinkConfig::default());
        let status = match link.call(SensorRequest::Status).unwrap() {
            Some(SensorResponse::Status(st)) => st,
            other => panic!("{other:?}"),
        };
        (s, status)
    };
    let (clean, _) = run("clean", "");
    assert_eq!(clean.ending, Ending::Complete);
    // The 2nd point's stream ends with the reset: the 3rd point (index 2) meets it.
    let (s, status) = run("reset", "reset=sensor@2");
    assert_eq!(s.ending, Ending::Complete);
    points_once(&d.join("reset"), clean.points);
    assert_eq!(data_rows(&d.join("clean")), data_rows(&d.join("reset")));
    let j = journal(&d.join("reset"));
    let faults: Vec<&str> = j
        .lines()
        .filter(|l| l.contains("\"event\":\"fault\""))
        .collect();
    assert_eq!(faults.len(), 1, "{faults:#?}");
    let f = faults[0];
    assert!(
        f.contains("\"board\":\"sensor\"")
            && f.contains("the board was reset behind the sweep (its report counter went from ")
            && f.contains(
                "last reset: watchdog): it is at sensitivity 4, 10 Hz, the point's are 4, 20 Hz"
            )
            && journal_field(f, "point") == 2,
        "{f}"
    );
    assert_eq!(s.stats.faults, 1, "{:?}", s.stats);
    // The board the run ended on is the reset one, set to the plan's rate again.
    assert_eq!(status.reset_cause, ResetCause::Watchdog, "{status:?}");
    assert_eq!((status.rate_hz, status.sensitivity), (20, 4), "{status:?}");
}

/// A sensor board reset mid-point comes back idle and sends nothing: the silence that
/// follows is not a stalled NorthStar but the reset, which its status shows (the report
/// counter started again) and the fault names. The simulated board resets only between
/// points, so this is a reset as the 2nd point ends with the NorthStar silent from the 2nd
/// point's first frames (which complete it) on, for 1.5 s: to the sweep the 3rd point's
/// stream never comes, as after a reset mid-point.
#[test]
fn a_sensor_reset_that_silences_a_point_is_named_as_a_reset() {
    let d = dir("reset-silent");
    let clean = sweep::sweep(&args(&d, "clean", None)).unwrap();
    let spec = "reset=sensor@2,stall=sensor@2:1500";
    let s = sweep::sweep(&args(&d, "run", Some(spec))).unwrap();
    assert_eq!(s.ending, Ending::Complete);
    points_once(&d.join("run"), clean.points);
    assert_eq!(data_rows(&d.join("clean")), data_rows(&d.join("run")));
    let j = journal(&d.join("run"));
    let first = j
        .lines()
        .find(|l| l.contains("\"event\":\"fault\""))
        .expect("a fault");
    assert!(
        first.contains("\"board\":\"sensor\"")
            && first.contains(
                "the board was reset behind the sweep (no spot report for 150 ms while \
                 streaming, and its report counter went from "
            )
            && first.contains("last reset: watchdog)")
            && journal_field(first, "point") == 2,
        "{first}"
    );
}

/// A beacon board whose dead-man timeout is shorter than twice the plan's heartbeat would
/// darken points mid-way: the sweep refuses to start, naming the port, the timeout and the
/// command that sets it back.
#[test]
fn a_dead_man_timeout_too_short_for_the_heartbeat_is_refused() {
    use cta_core::wire::beacon::{BeaconRequest, Limits};
    use cta_lab::boards::link::{open_serial, Link, LinkConfig};
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
