//! `cta sweep` and the beacon board's frequency table, and the hints of a stopped hardware
//! run. The simulated boards stand in for real ones (`--beacon`/`--sensor` given their ports):
//!
//! * a point lights a table *entry* and records the plan's frequency, so a board whose table
//!   no longer holds the NorthStar frequencies at the entries the plan uses (left over from
//!   `cta beacon table --set ...`) is refused before anything is lit or recorded, naming the
//!   entries, both values and the command that restores the table; the same when a board
//!   with such a table answers a reconnection mid-run (the run stops, resumable);
//! * `cta beacon table --default` restores the NorthStar table, and the run then records
//!   the table it lit from in its journal, agreeing with every row's `frequency_hz`;
//! * a hardware run that stops (a board gone for good, an error, Ctrl-C) says how to resume
//!   it with its ports: `cta sweep --resume RUN --beacon B --sensor S`.

use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cta_cli::cmd::beacon::{self, BeaconArgs, BeaconCommand, BeaconConn};
use cta_cli::cmd::sweep::{self as cli, SweepArgs};
use cta_core::schedule::NORTHSTAR_TABLE_MHZ;
use cta_firmware_beacon::sim::SimBoard;
use cta_lab::sweep::engine::Ending;
use cta_lab::sweep::plan::Plan;
use cta_lab::sweep::sim::{Faults, SimCta, SimSettings};
use cta_tests::{
    child, child_paths, data_rows, journal, journal_points, write_plan, TestDir, SLOW_PLAN,
};

/// Two frequencies: table entries 2 (4050 Hz) and 3 (3090 Hz). One separation: the
/// simulated plate is put there by the test (`--yes` moves nothing).
const PLAN: &str = r#"
name = "table test"
separations_in = [20]
beacons = [0, 45, 99]
frequencies_hz = [4050, 3090]
samples = 3
settle_ms = 0
[timing]
request_timeout_ms = 60
retries = 2
report_timeout_ms = 300
no_signal_reports = 5
backoff_max_s = 0.2
give_up_s = 30
"#;

/// Generous: a loaded machine must not fail the tests.
const PATIENCE: Duration = Duration::from_secs(120);

/// `cta beacon --port PORT table [--set HZ,...] [--default]`; what it prints.
fn table(port: &str, set: Option<&[f64]>, default: bool) -> String {
    let args = BeaconArgs {
        conn: BeaconConn {
            port: Some(port.into()),
            ..BeaconConn::default()
        },
        command: BeaconCommand::Table {
            set: set.map(<[f64]>::to_vec),
            default,
            conn: BeaconConn::default(),
        },
    };
    let mut out = Vec::new();
    beacon::run_to(&args, &mut out).unwrap();
    String::from_utf8(out).unwrap()
}

/// The table `cta beacon table` lists, Hz.
fn listed(out: &str) -> Vec<f64> {
    // `i  F Hz`, with a note after entries that share a frequency.
    out.lines()
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (f.len() >= 3 && f[2] == "Hz" && f[0].parse::<usize>().is_ok())
                .then(|| f[1].parse().unwrap())
        })
        .collect()
}

/// `cta sweep --plan d/plan.toml --out d/OUT --beacon B --sensor S --yes --quiet`.
fn hardware_args(d: &Path, out: &str, beacon: &str, sensor: &str) -> SweepArgs {
    SweepArgs {
        plan: Some(d.join("plan.toml")),
        out: Some(d.join(out)),
        beacon: Some(beacon.into()),
        sensor: Some(sensor.into()),
        yes: true,
        quiet: true,
        no_sync: true,
        ..SweepArgs::default()
    }
}

/// The simulated boards standing in for real ones, the plate at [`PLAN`]'s separation.
fn boards(plan: &Plan, settings: &SimSettings) -> SimCta {
    let sim = SimCta::spawn(plan, settings).unwrap();
    sim.move_plate(0, 20.0, 0);
    sim
}

/// The hint a stopped hardware run must give.
fn hint(run: &Path, beacon: &str, sensor: &str) -> String {
    format!(
        "cta sweep --resume {} --beacon {beacon} --sensor {sensor}",
        run.display()
    )
}

/// The `table_hz` of the journal's session lines.
fn journalled_tables(run: &Path) -> Vec<Vec<f64>> {
    journal(run)
        .lines()
        .filter(|l| l.contains("\"event\":\"session\""))
        .map(|l| {
            let at = l.find("\"table_hz\":[").expect("table_hz in the session") + 12;
            l[at..l[at..].find(']').unwrap() + at]
                .split(',')
                .map(|v| v.parse().unwrap())
                .collect()
        })
        .collect()
}

fn northstar_hz() -> Vec<f64> {
    NORTHSTAR_TABLE_MHZ
        .iter()
        .map(|&m| m as f64 / 1000.0)
        .collect()
}

#[test]
fn a_changed_table_is_refused_and_table_default_restores_it() {
    let d = TestDir::new("sweep-table-changed");
    write_plan(&d, PLAN);
    let plan = Plan::parse("plan.toml", PLAN).unwrap();
    let sim = boards(&plan, &SimSettings::default());
    let (b, s) = (
        sim.beacon_path().display().to_string(),
        sim.sensor_path().display().to_string(),
    );

    // The README's example table, left on the board: entries 2 and 3 swapped.
    table(&b, Some(&[3040.0, 2010.0, 3090.0, 4050.0]), false);
    let e = format!(
        "{:#}",
        cli::sweep(&hardware_args(&d, "run", &b, &s)).unwrap_err()
    );
    for said in [
        format!("beacon board on {b}"),
        "entry 2 is 3090 Hz, the plan records 4050 Hz".into(),
        "entry 3 is 4050 Hz, the plan records 3090 Hz".into(),
        format!("`cta beacon --port {b} table --default`"),
    ] {
        assert!(e.contains(&said), "`{said}` not in: {e}");
    }
    assert!(!d.join("run").exists(), "a refused run leaves no directory");

    // A table too short for the plan's entries: named too.
    table(&b, Some(&[3040.0, 2010.0, 4050.0]), false);
    let e = format!(
        "{:#}",
        cli::sweep(&hardware_args(&d, "run", &b, &s)).unwrap_err()
    );
    assert!(
        e.contains("entry 3 is missing (the table has 3 entries), the plan records 3090 Hz")
            && !e.contains("entry 2"),
        "{e}"
    );

    // `table --default` restores the NorthStar table...
    let out = table(&b, None, true);
    assert!(
        out.starts_with("table replaced by the NorthStar table"),
        "{out}"
    );
    assert_eq!(listed(&out), northstar_hz(), "{out}");
    assert_eq!(listed(&table(&b, None, false)), northstar_hz());

    // ...and the run goes: every row's frequency is the one its table entry holds, and the
    // journal says the table it lit from.
    let summary = cli::sweep(&hardware_args(&d, "run", &b, &s)).unwrap();
    assert_eq!(summary.ending, Ending::Complete);
    let run = d.join("run");
    assert_eq!(journalled_tables(&run), vec![northstar_hz()]);
    let rows = data_rows(&run);
    let header: Vec<&str> = rows[0].split(',').collect();
    let col = header.iter().position(|h| *h == "frequency_hz").unwrap();
    let freqs: Vec<f64> = rows[1..]
        .iter()
        .map(|r| r.split(',').nth(col).unwrap().parse().unwrap())
        .collect();
    assert!(
        freqs.contains(&4050.0) && freqs.contains(&3090.0),
        "{freqs:?}"
    );
    for f in freqs {
        let entry = cta_lab::sweep::plan::channel_of(f).unwrap() as usize;
        assert_eq!(northstar_hz()[entry], f);
    }
}

#[test]
fn a_table_only_differing_where_the_plan_does_not_light_is_accepted() {
    let d = TestDir::new("sweep-table-unused");
    let plan_path = write_plan(&d, &PLAN.replace("[4050, 3090]", "[4050]"));
    let plan = Plan::load(&plan_path).unwrap();
    let sim = boards(&plan, &SimSettings::default());
    let (b, s) = (
        sim.beacon_path().display().to_string(),
        sim.sensor_path().display().to_string(),
    );
    let t = [3040.0, 2010.0, 4050.0, 1000.0];
    table(&b, Some(&t), false);
    let summary = cli::sweep(&hardware_args(&d, "run", &b, &s)).unwrap();
    assert_eq!(summary.ending, Ending::Complete);
    assert_eq!(journalled_tables(&d.join("run")), vec![t.to_vec()]);
}

/// The beacon port is a symbolic link the test repoints, while the run holds the port open,
/// to another beacon board whose table was changed: the reconnection after the first board
/// went silent finds it. The run stops there, saved, before lighting anything from that
/// table, and says how to resume on its ports. The first board stays silent for longer than
/// the test's patience, and the run gives up only after as long: whenever the test repoints
/// the link, before the fault or during the reconnections, only the other board answers.
#[test]
fn a_changed_table_found_at_a_reconnection_stops_the_run() {
    let d = TestDir::new("sweep-table-reconnect");
    write_plan(
        &d,
        &PLAN
            .replace("settle_ms = 0", "settle_ms = 0\nrate_hz = 20")
            .replace("give_up_s = 30", "give_up_s = 120"),
    );
    let plan = Plan::load(&d.join("plan.toml")).unwrap();
    let sim = boards(
        &plan,
        &SimSettings {
            realtime: true,
            faults: Faults::parse("silent=beacon@4:600000").unwrap(),
            ..SimSettings::default()
        },
    );
    let other = SimBoard::spawn().unwrap();
    table(other.path(), Some(&[3040.0, 2010.0, 3090.0, 4050.0]), false);
    let link = d.join("beacon");
    std::os::unix::fs::symlink(sim.beacon_path(), &link).unwrap();
    let (b, s) = (
        link.display().to_string(),
        sim.sensor_path().display().to_string(),
    );
    let run = d.join("run");
    let a = hardware_args(&d, "run", &b, &s);
    let sweeping = std::thread::spawn(move || cli::sweep(&a));
    // Once the session started, the run has its port open: repoint the link.
    let t0 = Instant::now();
    while !journal(&run).contains("\"event\":\"session\"") {
        assert!(
            t0.elapsed() < PATIENCE && !sweeping.is_finished(),
            "no session"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    let tmp = d.join("beacon.new");
    std::os::unix::fs::symlink(other.path(), &tmp).unwrap();
    std::fs::rename(&tmp, &link).unwrap();

    let e = format!("{:#}", sweeping.join().unwrap().unwrap_err());
    for said in [
        format!("beacon board on {b} (reconnected)"),
        "entry 2 is 3090 Hz, the plan records 4050 Hz".into(),
        format!("continue with `{}`", hint(&run, &b, &s)),
    ] {
        assert!(e.contains(&said), "`{said}` not in: {e}");
    }
    // Only the points measured on the first board, before the fault, are recorded.
    let done = journal_points(&run);
    assert_eq!(done, 3, "{}", journal(&run));
    assert_eq!(
        data_rows(&run).len(),
        1 + 3 * 3,
        "header and 3 samples per point"
    );
    let j = journal(&run);
    assert!(
        j.contains("\"board\":\"beacon\"") && j.contains("\"action\":\"stop\""),
        "{j}"
    );
    assert_eq!(journalled_tables(&run), vec![northstar_hz()]);
}

#[test]
fn a_hardware_run_that_gives_up_names_its_ports_in_the_hint() {
    let d = TestDir::new("sweep-table-give-up");
    write_plan(&d, &PLAN.replace("give_up_s = 30", "give_up_s = 0.5"));
    let plan = Plan::load(&d.join("plan.toml")).unwrap();
    let sim = SimCta::spawn(
        &plan,
        &SimSettings {
            faults: Faults::parse("vanish=beacon@2:5000").unwrap(),
            ..SimSettings::default()
        },
    )
    .unwrap();
    let (b, s) = (
        sim.beacon_path().display().to_string(),
        sim.sensor_path().display().to_string(),
    );
    let e = format!(
        "{:#}",
        cli::run(&hardware_args(&d, "run", &b, &s)).unwrap_err()
    );
    assert!(e.contains("a board stayed unreachable"), "{e}");
    assert!(
        e.contains(&format!("continue with `{}`", hint(&d.join("run"), &b, &s))),
        "{e}"
    );
    // A resume without the ports is refused, naming the ones its last session used.
    let resume = SweepArgs {
        resume: Some(d.join("run")),
        yes: true,
        quiet: true,
        ..SweepArgs::default()
    };
    let e = format!("{:#}", cli::sweep(&resume).unwrap_err());
    // Said as it was: simulated boards (these say so of themselves) at those ports, not
    // "real boards".
    assert!(
        e.contains(&format!(
            "the run was recorded on simulated beacon and sensor boards at ports (beacon board \
             on {b}, sensor board on {s}), not on the simulated CTA of --sim: give --beacon and \
             --sensor to resume it, as its last session did: `{}`",
            hint(&d.join("run"), &b, &s)
        )) && !e.contains("real boards"),
        "{e}"
    );
}

/// `cta sweep --plan PLAN --out OUT --beacon B --sensor S --yes --quiet` (`cli::run`: the
/// command, with its signal handlers and summary), then prints its error on stdout. Only in
/// the re-executed child.
#[test]
fn child_interrupted_hardware_run() {
    let Some([plan, out, beacon, sensor]) = child_paths("CTA_SWEEP_TABLE_CHILD") else {
        return;
    };
    let a = SweepArgs {
        plan: Some(plan),
        out: Some(out),
        beacon: Some(beacon.display().to_string()),
        sensor: Some(sensor.display().to_string()),
        yes: true,
        quiet: true,
        no_sync: true,
        ..SweepArgs::default()
    };
    match cli::run(&a) {
        Ok(()) => println!("completed"),
        Err(e) => println!("error: {e:#}"),
    }
    std::process::exit(0);
}

#[test]
fn an_interrupted_hardware_run_names_its_ports_in_the_hint() {
    let d = TestDir::new("sweep-table-interrupt");
    let plan_path = write_plan(&d, SLOW_PLAN);
    let plan = Plan::load(&plan_path).unwrap();
    let sim = SimCta::spawn(
        &plan,
        &SimSettings {
            realtime: true,
            ..SimSettings::default()
        },
    )
    .unwrap();
    let run = d.join("run");
    let (b, s) = (sim.beacon_path(), sim.sensor_path());
    let mut c = child(
        "child_interrupted_hardware_run",
        "CTA_SWEEP_TABLE_CHILD",
        &[&plan_path, &run, &b, &s],
    )
    .stdout(Stdio::piped())
    .stderr(Stdio::null())
    .spawn()
    .unwrap();
    let t0 = Instant::now();
    while journal_points(&run) < 2 {
        if t0.elapsed() > PATIENCE || c.try_wait().unwrap().is_some() {
            let _ = c.kill();
            panic!("2 points committed: never happened (or the sweep ended early)");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let ok = Command::new("kill")
        .args(["-INT", &c.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    while c.try_wait().unwrap().is_none() {
        if t0.elapsed() > PATIENCE {
            let _ = c.kill();
            panic!("SIGINT: the sweep did not stop");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let mut stdout = String::new();
    c.stdout
        .take()
        .unwrap()
        .read_to_string(&mut stdout)
        .unwrap();
    let hint = hint(&run, &b.display().to_string(), &s.display().to_string());
    // The summary and the error both say it.
    assert!(
        stdout.contains("interrupted by Ctrl-C with ")
            && stdout.contains(&format!(" (continue with `{hint}`)")),
        "{stdout}"
    );
    assert!(
        stdout.contains("error: interrupted (Ctrl-C) with ")
            && stdout.contains(&format!("continue with `{hint}`")),
        "{stdout}"
    );
}
