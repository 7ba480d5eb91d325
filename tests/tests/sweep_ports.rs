//! `cta sweep --beacon P --sensor P` on the ports of simulated boards: one port given twice
//! is refused before anything is opened, boards on the wrong ports suggest swapping them, and
//! a run on simulated boards says so in its data file (it used to say "CTA hardware").

use std::path::Path;

use cta_lab::sweep::plan::Plan;
use cta_lab::sweep::sim::{SimCta, SimSettings};
use cta_lab::sweep::{self, engine::Ending, SweepOptions};
use cta_tests::{sweep_args, write_plan, TestDir};

const PLAN: &str = r#"
name = "ports test"
separations_in = [10]
beacons = [0, 45]
frequencies_hz = [4050]
power_levels = [2]
sensitivities = [4]
samples = 2
settle_ms = 0
"#;

/// A sweep of [`PLAN`] into `d/out` on the ports `beacon` and `sensor`, without prompts.
fn on_ports(d: &Path, out: &str, beacon: &Path, sensor: &Path) -> SweepOptions {
    SweepOptions {
        no_sync: true,
        yes: true,
        beacon: Some(beacon.display().to_string()),
        sensor: Some(sensor.display().to_string()),
        ..sweep_args(&d.join("plan.toml"), &d.join(out))
    }
}

fn sim() -> SimCta {
    let plan = Plan::parse("plan.toml", PLAN).unwrap();
    SimCta::spawn(&plan, &SimSettings::default()).unwrap()
}

#[test]
fn one_port_given_twice_is_refused_up_front() {
    let d = TestDir::new("sweep-ports-twice");
    write_plan(&d, PLAN);
    let sim = sim();
    let b = sim.beacon_path();
    let e = format!(
        "{:#}",
        sweep::sweep(&on_ports(&d, "twice", &b, &b)).unwrap_err()
    );
    assert!(
        e.contains("--beacon and --sensor are the same port")
            && e.contains(&b.display().to_string()),
        "{e}"
    );
    assert!(!e.contains("lock"), "{e}");
    // Two names of one device (as /dev/serial/by-id/... and /dev/ttyUSB0).
    let link = d.join("by-id-beacon");
    std::os::unix::fs::symlink(&b, &link).unwrap();
    let e = format!(
        "{:#}",
        sweep::sweep(&on_ports(&d, "linked", &b, &link)).unwrap_err()
    );
    assert!(e.contains("are the same port"), "{e}");
    assert!(!d.join("twice").exists() && !d.join("linked").exists());
    // The same port twice on a resume too.
    let args = SweepOptions {
        out: None,
        plan: None,
        resume: Some(d.join("twice")),
        ..on_ports(&d, "twice", &b, &b)
    };
    let e = format!("{:#}", sweep::sweep(&args).unwrap_err());
    assert!(e.contains("same port"), "{e}");
}

#[test]
fn boards_on_each_others_ports_suggest_a_swap() {
    let d = TestDir::new("sweep-ports-swapped");
    write_plan(&d, PLAN);
    let sim = sim();
    let e = format!(
        "{:#}",
        sweep::sweep(&on_ports(
            &d,
            "swapped",
            &sim.sensor_path(),
            &sim.beacon_path()
        ))
        .unwrap_err()
    );
    assert!(
        e.contains("is this the sensor board's port? the beacon and sensor ports may be swapped"),
        "{e}"
    );
}

#[test]
fn a_run_on_simulated_boards_says_so() {
    let d = TestDir::new("sweep-ports-simulated");
    write_plan(&d, PLAN);
    let sim = sim();
    let s = sweep::sweep(&on_ports(&d, "run", &sim.beacon_path(), &sim.sensor_path())).unwrap();
    assert_eq!(s.ending, Ending::Complete);
    let data = std::fs::read_to_string(sweep::data_path(&d.join("run"))).unwrap();
    let header: Vec<&str> = data.lines().take_while(|l| l.starts_with('#')).collect();
    assert!(
        header
            .iter()
            .any(|l| l.ends_with("; simulated beacon and sensor boards")),
        "{header:?}"
    );
    assert!(!data.contains("CTA hardware"), "{header:?}");
}
