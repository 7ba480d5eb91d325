//! Grouped sweeps (`group = N`) on the simulated CTA over pseudo-terminals, end to end: many
//! beacons lit at once, each at its own frequency, every spot of a NorthStar frame a row of its
//! own beacon; a group cut short by a fault or a kill measured again whole, so that a resumed
//! run equals an uninterrupted one; stray spots journalled and never taken as data; the
//! crosstalk check naming `spot_crosstalk` when it is there and nothing when it is not.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::time::{Duration, Instant};

use cta_lab::crosstalk;
use cta_lab::data::Dataset;
use cta_lab::sweep::plan::Plan;
use cta_lab::sweep::{self, engine::Ending, SweepOptions};
use cta_tests::{
    assert_same_data, child, child_paths, journal, journal_points, resume_args, sweep_args,
    write_plan, TestDir,
};

/// Three separations (all beyond the magnitude rail at sensitivity 2), the whole array, every
/// beacon at 2 of 19 frequencies in groups of 19, 3 beacons a separation measured alone.
const PLAN: &str = r#"
name = "grouped test"
separations_in = [14, 20, 27]
beacons = "all"
frequencies_hz = [2010, 3040, 3090, 3210, 3330, 3450, 3570, 3690, 3810, 3930,
                  4050, 4170, 4290, 4410, 4530, 4650, 4770, 4890, 5010]
frequencies_per_beacon = 2
group = 19
crosstalk_check = 3
power_levels = [2]
sensitivities = [2, 4]
samples = 8
settle_ms = 0
[timing]
no_signal_reports = 5
"#;

fn args(out: &Path, plan: &Path) -> SweepOptions {
    SweepOptions {
        sim_noise: Some(6.0),
        sim_seed: Some(7),
        ..sweep_args(plan, out)
    }
}

/// The rows of `run`, by sweep point (`group`): (beacon, frequency) of each, and the samples
/// of each.
fn by_point(run: &Path) -> (Dataset, BTreeMap<u32, BTreeMap<(u32, u64), usize>>) {
    let ds = Dataset::read(&sweep::data_path(run)).unwrap();
    let mut m: BTreeMap<u32, BTreeMap<(u32, u64), usize>> = BTreeMap::new();
    for s in &ds.samples {
        *m.entry(s.group.expect("a sweep writes the group column"))
            .or_default()
            .entry((s.beacon.unwrap(), s.frequency_hz.unwrap().to_bits()))
            .or_default() += 1;
    }
    (ds, m)
}

#[test]
fn a_grouped_sweep_records_every_spot_of_a_frame_under_its_own_beacon() {
    let d = TestDir::new("sweep-groups");
    let plan_path = write_plan(&d, PLAN);
    let plan = Plan::load(&plan_path).unwrap();
    let run = d.join("run");
    let s = sweep::sweep(&args(&run, &plan_path)).unwrap();
    assert_eq!(s.ending, Ending::Complete);
    // 200 measurements a setting in 11 groups (10 of 19, one of 10), 3 beacons alone a
    // separation.
    assert_eq!(plan.per_block(), 11);
    assert_eq!(s.points, 3 * (2 * 11 + 3));
    assert_eq!(s.stats.ok, s.points, "{:?}", s.stats);
    assert_eq!(s.stats.beacons, (3 * (2 * 200 + 3), 0, 0));
    assert_eq!(s.stats.samples, plan.total_samples());
    assert_eq!(plan.total_samples(), 3 * (2 * 200 + 3) * 8);
    let (ds, points) = by_point(&run);
    assert_eq!(ds.samples.len() as u64, plan.total_samples());
    // Each sweep point: its beacons, each at its own frequency, every one with all its
    // samples; the point's lit set is the plan's.
    for (&i, lit) in &points {
        let p = plan.point(i as usize);
        let want: BTreeSet<(u32, u64)> = p
            .lit
            .iter()
            .map(|l| (l.beacon_id(p.quadrant), l.frequency_hz.to_bits()))
            .collect();
        assert_eq!(
            lit.keys().copied().collect::<BTreeSet<_>>(),
            want,
            "point {i}"
        );
        let freqs: BTreeSet<u64> = lit.keys().map(|k| k.1).collect();
        assert_eq!(freqs.len(), lit.len(), "point {i}: a frequency twice");
        assert!(lit.values().all(|&n| n == 8), "point {i}: {lit:?}");
        assert!(
            lit.len() == 1 || lit.len() >= 10,
            "point {i}: {}",
            lit.len()
        );
    }
    // Every beacon at 2 frequencies per setting, and a row's position is its beacon's.
    let mut met: BTreeMap<(u32, u64, u64, u64), BTreeSet<u64>> = BTreeMap::new();
    for r in ds
        .samples
        .iter()
        .filter(|r| points[&r.group.unwrap()].len() > 1)
    {
        let b = r.beacon.unwrap();
        let (x, y) = ((b % 10) as f64 - 4.5, (b / 10) as f64 - 4.5);
        assert_eq!((r.r[0], r.r[1]), (x, y), "line {}", r.line);
        met.entry((
            b,
            r.separation_in.to_bits(),
            r.sensitivity.unwrap().to_bits(),
            r.power.unwrap().to_bits(),
        ))
        .or_default()
        .insert(r.frequency_hz.unwrap().to_bits());
    }
    assert_eq!(met.len(), 100 * 3 * 2);
    assert!(met.values().all(|f| f.len() == 2));
    // The crosstalk check of clean data: nothing named, the difference within its noise.
    let c = s.crosstalk.expect("the plan checks");
    assert!(!c.named, "{}", c.summary());
    assert!(c.pairs + c.clipped == 3 * 3 && c.pairs > 0, "{c:?}");
    assert!(
        c.chi2_sigma() < 3.0 && c.c.abs() < 4.0 * c.c_sigma,
        "{}",
        c.summary()
    );
    // The file says the same to `cta noise` and `cta analyze`.
    let f = crosstalk::check(&ds).unwrap();
    assert_eq!((f.pairs, f.named), (c.pairs, false));
    assert!((f.c - c.c).abs() < 1e-12);
}

#[test]
fn spot_crosstalk_is_named_by_the_check_and_its_size_measured() {
    let d = TestDir::new("sweep-groups-crosstalk");
    let plan = write_plan(&d, PLAN);
    let run = d.join("run");
    let s = sweep::sweep(&SweepOptions {
        sim_effect: vec!["spot_crosstalk=3e-4".into()],
        ..args(&run, &plan)
    })
    .unwrap();
    let c = s.crosstalk.expect("the plan checks");
    assert!(c.named, "{}", c.summary());
    assert!((c.c - 3e-4).abs() < 4.0 * c.c_sigma, "{}", c.summary());
    // A factor 2 off is far outside the estimate's 1-sigma.
    assert!(c.c_sigma < 0.5e-4, "{}", c.summary());
    let text = c.summary();
    assert!(
        text.contains("biased by") && text.contains("smaller groups"),
        "{text}"
    );
    let truth = std::fs::read_to_string(run.join("data.truth.json")).unwrap();
    assert!(truth.contains("spot_crosstalk=0.0003"), "{truth}");
    // The analysis of the file names it before anything its fits find.
    let ds = Dataset::read(&sweep::data_path(&run)).unwrap();
    let a = cta_lab::analyze::analyze(
        &ds,
        &cta_lab::analyze::Options::default(),
        &cta_lab::progress::Silent,
    )
    .unwrap();
    assert!(
        a.verdict
            .starts_with("named: spot_crosstalk by the crosstalk check"),
        "{}",
        a.verdict
    );
    // `cta simulate` lights one beacon at a time: it refuses the effect, saying where it
    // belongs.
    let e = cta_lab::sim::effects::Effect::parse("spot_crosstalk=3e-4").unwrap_err();
    assert!(e.to_string().contains("cta sweep"), "{e}");
}

/// Stray spots (an ID no LED of the point is lit at) are journalled as faults and never
/// recorded: the data equal a run without them, row for row.
#[test]
fn stray_spots_are_journalled_and_never_recorded() {
    let d = TestDir::new("sweep-groups-stray");
    let plan = write_plan(&d, PLAN);
    let clean = d.join("clean");
    sweep::sweep(&args(&clean, &plan)).unwrap();
    let run = d.join("stray");
    let s = sweep::sweep(&SweepOptions {
        sim_fault: Some("stray=0.3".into()),
        ..args(&run, &plan)
    })
    .unwrap();
    assert_eq!(s.ending, Ending::Complete);
    assert_same_data(&clean, &run);
    let j = journal(&run);
    let strays = j
        .lines()
        .filter(|l| l.contains("no LED of the point was lit at"))
        .count();
    // Nearly every point reads more than 8 frames: a stray in 30 % of them hits most points.
    assert!(strays > s.points / 2, "{strays} of {} points", s.points);
    assert!(j.contains("\"action\":\"left out of the data\""), "{j}");
}

/// Runs the sweep described by `CTA_GROUPS_CHILD=OUT|PLAN` (only in the re-executed child).
#[test]
fn child_sweep() {
    let Some([out, plan]) = child_paths("CTA_GROUPS_CHILD") else {
        return;
    };
    sweep::sweep(&SweepOptions {
        // Real time: the child is killed mid-point, with a group half-measured.
        sim_realtime: true,
        ..args(&out, &plan)
    })
    .unwrap();
}

/// A grouped run killed mid-group (SIGKILL) and resumed, and a stall in the middle of another
/// group, measure those groups again whole: the data equal an uninterrupted run's, line for
/// line, with no sample lost and none twice.
#[test]
fn a_group_cut_short_is_measured_again_whole() {
    let d = TestDir::new("sweep-groups-resume");
    let text = PLAN
        .replace("samples = 8", "samples = 4")
        .replace("rate_hz = 10\n", "")
        .replace("settle_ms = 0", "settle_ms = 0\nrate_hz = 50")
        .replace("[timing]\n", "[timing]\nreport_timeout_ms = 300\n");
    let plan = write_plan(&d, &text);
    let full = sweep::sweep(&args(&d.join("full"), &plan)).unwrap();
    assert_eq!(full.ending, Ending::Complete);
    let run = d.join("killed");
    let mut c = child("child_sweep", "CTA_GROUPS_CHILD", &[&run, &plan])
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    // Killed once a few groups are in, at 50 Hz within a group's 5 frames or its settle.
    while journal_points(&run) < 4 && t0.elapsed() < Duration::from_secs(120) {
        if let Ok(Some(_)) = c.try_wait() {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    std::thread::sleep(Duration::from_millis(37));
    assert!(
        c.try_wait().unwrap().is_none(),
        "the child ended before it was killed"
    );
    c.kill().unwrap();
    c.wait().unwrap();
    let done = journal_points(&run);
    assert!(
        done >= 4 && done < full.points,
        "killed after {done} points"
    );
    // Resumed (unthrottled), with the sensor stalling in the middle of the session's third
    // group: that attempt is dropped and the group measured again from its start.
    let resumed = sweep::sweep(&SweepOptions {
        sim_fault: Some("stall=sensor@3:1000".into()),
        sim_unthrottled: true,
        ..resume_args(&run)
    })
    .unwrap();
    assert_eq!(resumed.ending, Ending::Complete);
    assert!(resumed.stats.retries >= 1, "{:?}", resumed.stats);
    assert!(journal(&run).contains("no spot report for 300 ms"));
    assert_same_data(&d.join("full"), &run);
    let (ds, points) = by_point(&run);
    assert_eq!(ds.samples.len() as u64, full.stats.samples);
    assert!(points.values().all(|lit| lit.values().all(|&n| n == 4)));
}

/// A beacon board whose cap of lit LEDs is below the plan's group is refused when the sweep
/// connects, before anything is lit, naming the cap and the command that raises it.
#[test]
fn a_board_that_lights_fewer_leds_than_the_group_is_refused() {
    use cta_core::wire::beacon::{Beacon, BeaconRequest, Limits};
    use cta_lab::boards::link::{open_serial, Link, LinkConfig};
    use cta_lab::sweep::engine::Engine;
    use cta_lab::sweep::sim::{SimCta, SimSettings};

    let d = TestDir::new("sweep-groups-cap");
    let plan = Plan::load(&write_plan(&d, PLAN)).unwrap();
    let sim = SimCta::spawn(&plan, &SimSettings::default()).unwrap();
    let (b, s) = (
        sim.beacon_path().display().to_string(),
        sim.sensor_path().display().to_string(),
    );
    {
        let mut link: Link<Beacon, _> = Link::new(open_serial(&b).unwrap(), LinkConfig::default());
        link.call(BeaconRequest::SetLimits(Limits {
            max_lit: 12,
            ..Limits::default()
        }))
        .unwrap();
    }
    let e = format!("{:#}", Engine::new(&plan, &b, &s).connect().unwrap_err());
    assert!(
        e.contains("lights at most 12 LEDs at once")
            && e.contains("`group` lights 19")
            && e.contains("--max-lit 19"),
        "{e}"
    );
    // A group the board can light passes.
    let small = Plan::parse("p.toml", &PLAN.replace("group = 19", "group = 12")).unwrap();
    Engine::new(&small, &b, &s).connect().unwrap();
}

/// Plans a board or the detector cannot do are refused before anything is lit, naming the
/// key and the limit.
#[test]
fn impossible_groups_are_refused_naming_the_key_and_the_limit() {
    let refused = |from: &str, to: &str| {
        Plan::parse("p.toml", &PLAN.replace(from, to))
            .unwrap_err()
            .to_string()
    };
    let e = refused("group = 19", "group = 25");
    assert!(
        e.contains("key `group`: 25 is not a group size (1..=20"),
        "{e}"
    );
    let few = PLAN
        .replace(
            "frequencies_hz = [2010, 3040, 3090, 3210, 3330, 3450, 3570, 3690, 3810, 3930,\n                  4050, 4170, 4290, 4410, 4530, 4650, 4770, 4890, 5010]",
            "frequencies_hz = [2010, 3040, 3090]",
        )
        .replace("frequencies_per_beacon = 2", "frequencies_per_beacon = 1");
    let e = Plan::parse("p.toml", &few).unwrap_err().to_string();
    assert!(
        e.contains("key `group`: 19 beacons at once need 19 different frequencies, but `frequencies_hz` lists 3")
            && e.contains("19 distinct"),
        "{e}"
    );
    let e = refused("frequencies_per_beacon = 2", "frequencies_per_beacon = 20");
    assert!(e.contains("key `frequencies_per_beacon`: 20 is not allowed: each beacon can be measured at 1..=19"), "{e}");
    let e = refused("5010]", "5010, 4050]");
    assert!(e.contains("4050 Hz is listed twice"), "{e}");
    let e = refused("beacons = \"all\"", "beacons = [1, 2, 3]");
    assert!(e.contains("19 beacons at once, but the plan has 3"), "{e}");
    let e = Plan::parse(
        "p.toml",
        &PLAN
            .replace("group = 19", "group = 1")
            .replace("crosstalk_check = 3", "crosstalk_check = 2"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("key `crosstalk_check`") && e.contains("needs `group` above 1"),
        "{e}"
    );
}
