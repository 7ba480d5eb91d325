//! Performance of `cta sweep` on the simulated CTA: the full thesis Ch VI plan
//! (`host/plans/chvi.toml`: 29 separations x 100 beacons x 3 frequencies x 2 power levels
//! x 4 sensitivities x 50 samples = 3,480,000 samples) with the simulated sensor
//! unthrottled, through the whole path (ptys, both boards' firmware logic, protocol, engine,
//! CSV and journal synced per point). A measurement, not a test: run it in release and read the time.
//!
//! ```text
//! cargo test --release -p cta-tests --test sweep_perf -- --ignored --nocapture
//! ```
//! (once `cta sweep` is wired: `cta sweep --plan host/plans/chvi.toml --out /tmp/chvi --quiet`)

use cta_lab::sweep::{self, SweepOptions};
use cta_tests::{sweep_args, TestDir};

#[test]
#[ignore = "performance measurement: run in release with --ignored --nocapture"]
fn full_chvi_plan_on_the_simulated_cta() {
    let plan = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../host/plans/chvi.toml");
    let d = TestDir::new("sweep-perf");
    let a = SweepOptions {
        ..sweep_args(&plan, &d.join("run"))
    };
    let s = sweep::sweep(&a).unwrap();
    println!(
        "full Ch VI plan: {} points ({} ok, {} no signal, {} partial), {} samples in {:.1} s ({:.0} samples/s)",
        s.points,
        s.stats.ok,
        s.stats.no_signal,
        s.stats.partial,
        s.stats.samples,
        s.seconds,
        s.stats.samples as f64 / s.seconds
    );
}
