//! The operator's corner readings place each plate: a sweep of the simulated CTA with a
//! hidden `plate_tilt` journals corners that show the tilt (as a real plate's would), and
//! `cta analyze` on the run's data.csv places the plates with them, so the tilt is explained
//! by what was measured; taken as level (`--ignore-corners`), the same data name
//! `plate_tilt`.

use cta_lab::analyze::{analyze, Options};
use cta_lab::data::Dataset;
use cta_lab::progress::Silent;
use cta_lab::sim::Truth;
use cta_lab::sweep::corners::{RunCorners, ROD_XY_IN};
use cta_lab::sweep::{self, engine::Ending, SweepOptions};
use cta_tests::{sweep_args, write_plan, TestDir};

const PLAN: &str = r#"
name = "corners"
separations_in = [4, 6, 8, 12, 16, 20]
beacons = "all"
frequencies_hz = [4050]
power_levels = [2]
sensitivities = [4]
samples = 4
settle_ms = 0
"#;

#[test]
fn corner_readings_explain_a_tilted_plate() {
    let d = TestDir::new("plate-corners");
    let plan = write_plan(&d, PLAN);
    let a = SweepOptions {
        sim_noise: Some(32.8),
        sim_seed: Some(11),
        sim_effect: vec!["plate_tilt=0.3".into()],
        no_sync: true,
        ..sweep_args(&plan, &d.join("run"))
    };
    assert_eq!(sweep::sweep(&a).unwrap().ending, Ending::Complete);
    let data = sweep::data_path(&d.join("run"));
    let truth = Truth::load_for(&data).unwrap().unwrap();
    let rc = RunCorners::beside(&data).unwrap().unwrap();
    assert_eq!(rc.plates.len(), 6, "{rc:?}");
    // Each plate's corners give its true tilt to within what the simulated readings allow
    // (each within 1.5 mil of the truth: 1.5 mil over the rods' 8.5 in, 0.010 deg).
    let mil_deg = (0.0015 / ROD_XY_IN).atan().to_degrees();
    for (p, t) in rc.plates.iter().zip(&truth.plate_tilts_deg) {
        let got = p.tilt.unwrap().tilt_deg;
        for j in 0..2 {
            assert!((got[j] - t[j]).abs() <= mil_deg, "{p:?}: truth {t:?}");
        }
    }
    let ds = Dataset::read(&data).unwrap();
    let placed = analyze(
        &ds,
        &Options {
            corners: Some(rc),
            ..Options::default()
        },
        &Silent,
    )
    .unwrap();
    let c = placed.corners.as_ref().unwrap();
    let level = c.chi2_dof_level.unwrap();
    assert!(placed.causes.is_empty(), "{}", placed.verdict);
    assert!(
        placed
            .verdict
            .starts_with("no significant effect beyond the plate tilts the corner readings"),
        "{}",
        placed.verdict
    );
    assert!(
        placed.chi2_dof_before < 1.2 && level > 2.0,
        "{level}: {}",
        placed.verdict
    );
    assert!(c.tilt_deg.iter().all(|t| t.is_some()), "{c:?}");
    assert!(
        placed
            .data_notes
            .iter()
            .any(|n| n.contains("at 6 of 6 separations")),
        "{:?}",
        placed.data_notes
    );
    // The same data with the plates taken as level: the tilt is found in the data.
    let level = analyze(&ds, &Options::default(), &Silent).unwrap();
    let names: Vec<&str> = level.causes.iter().map(|c| c.effect.as_str()).collect();
    assert_eq!(names, ["plate_tilt"], "{}", level.verdict);
    assert!(level.corners.is_none());
}
