//! Performance of `cta sweep` on the simulated CTA: the full thesis Ch VI scheme, grouped
//! (`host/plans/chvi.toml`: up to 19 beacons per NorthStar frame, 3,485,800 samples) and one
//! beacon at a time (`host/plans/chvi-single.toml`: 69,600 points, 3,480,000 samples), with the
//! simulated sensor unthrottled, through the whole path (ptys, both boards' firmware logic,
//! protocol, engine, CSV and journal synced per point). A measurement, not a test: run it in
//! release and read the times.
//!
//! ```text
//! cargo test --release -p cta-tests --test sweep_perf -- --ignored --nocapture
//! ```
//! (or one plan with the CLI: `cta sweep --plan host/plans/chvi.toml --out /tmp/chvi --quiet`)

use cta_lab::sweep::{self, SweepOptions};
use cta_tests::{sweep_args, TestDir};

fn run(name: &str) {
    let plan = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../host/plans")
        .join(name);
    let d = TestDir::new("sweep-perf");
    let a = SweepOptions {
        ..sweep_args(&plan, &d.join("run"))
    };
    let s = sweep::sweep(&a).unwrap();
    println!(
        "{name}: {} points ({} ok, {} no signal, {} partial), {} samples in {:.1} s ({:.0} samples/s)",
        s.points,
        s.stats.ok,
        s.stats.no_signal,
        s.stats.partial,
        s.stats.samples,
        s.seconds,
        s.stats.samples as f64 / s.seconds
    );
}

#[test]
#[ignore = "performance measurement: run in release with --ignored --nocapture"]
fn full_chvi_plan_grouped_on_the_simulated_cta() {
    run("chvi.toml");
}

#[test]
#[ignore = "performance measurement: run in release with --ignored --nocapture"]
fn full_chvi_plan_one_at_a_time_on_the_simulated_cta() {
    run("chvi-single.toml");
}
