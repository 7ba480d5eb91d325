//! `cta sweep` end to end on the simulated CTA (both boards behind pseudo-terminals).

use std::path::Path;

use cta_lab::data::Dataset;
use cta_lab::sweep::{self, engine::Ending, SweepOptions};
use cta_tests::{sweep_args, write_plan, TestDir};

const PLAN: &str = r#"
name = "test"
separations_in = [3, 12, 30]
beacons = [0, 9, 45, 90, 99]
frequencies_hz = [4050]
power_levels = [1, 2]
sensitivities = [1, 4]
samples = 8
settle_ms = 0
[timing]
no_signal_reports = 6
"#;

fn args(dir: &Path, plan: &Path) -> SweepOptions {
    SweepOptions {
        sim_noise: Some(15.0),
        sim_seed: Some(7),
        no_sync: true,
        ..sweep_args(plan, &dir.join("run"))
    }
}

#[test]
fn short_sweep_end_to_end() {
    let d = TestDir::new("sweep-e2e");
    let plan = write_plan(&d, PLAN);
    let a = args(&d, &plan);
    let s = sweep::sweep(&a).unwrap();
    assert_eq!(s.ending, Ending::Complete);
    assert_eq!(s.next_point, 3 * 5 * 2 * 2);
    let st = s.stats;
    assert_eq!(st.ok + st.no_signal + st.partial, 60);
    assert!(
        st.no_signal > 0,
        "weak settings at 30 in must see nothing: {st:?}"
    );
    assert!(st.ok > 30, "{st:?}");
    let data = Dataset::read(&sweep::data_path(&d.join("run"))).unwrap();
    assert_eq!(data.samples.len() as u64, st.samples);
    assert_eq!(data.points().len(), st.ok + st.partial);
    // Recorded separation is the corners' mean; beacon 99 sits at +4.5, +4.5.
    let s99 = data.samples.iter().find(|s| s.beacon == Some(99)).unwrap();
    assert_eq!([s99.r[0], s99.r[1]], [4.5, 4.5]);
    assert!([3.0, 12.0, 30.0]
        .iter()
        .any(|n| (s99.separation_in - n).abs() < 0.01));
    // The sign of x follows the beacon's x (collinearity: far beacons at +x read +X or -X
    // consistently; check the pair of opposite beacons disagree).
    let x0 = data
        .samples
        .iter()
        .find(|s| s.beacon == Some(0) && s.separation_in > 10.0)
        .unwrap()
        .x;
    let x99 = data
        .samples
        .iter()
        .find(|s| s.beacon == Some(99) && s.separation_in > 10.0)
        .unwrap()
        .x;
    assert!(x0.signum() != x99.signum(), "{x0} {x99}");
    // No overwrite without --force.
    let e = sweep::sweep(&a).unwrap_err().to_string();
    assert!(e.contains("--resume") && e.contains("--force"), "{e}");
    // Manifest and journal exist and say complete.
    let m = std::fs::read_to_string(d.join("run/manifest.json")).unwrap();
    assert!(m.contains("\"state\": \"complete\""), "{m}");
    assert!(m.contains("\"done\": 60"), "{m}");
    assert!(d.join("run/data.truth.json").exists());
}

#[test]
fn realtime_sensor_runs_at_the_plan_rate() {
    let d = TestDir::new("sweep-e2e-realtime");
    let plan = write_plan(
        &d,
        "separations_in = [20]\nbeacons = [44, 55]\nsamples = 3\nsettle_ms = 50\nrate_hz = 10\n",
    );
    let mut a = args(&d, &plan);
    a.sim_realtime = true;
    let s = sweep::sweep(&a).unwrap();
    assert_eq!(s.stats.ok, 2);
    // 6 reports at 10 Hz (the first of each point may come at once) plus two settles.
    assert!(s.seconds > 0.4, "{} s: not throttled to 10 Hz", s.seconds);
}

/// `--sim-magnitude-noise`: the spot magnitudes of the simulated sweep repeat to the given
/// percent (as `cta noise` measures it), x and y are exactly those of the same run without
/// it, and the truth records it.
#[test]
fn simulated_magnitude_noise_is_measured_by_cta_noise() {
    let d = TestDir::new("sweep-e2e-magnitude");
    let plan = write_plan(&d, PLAN);
    let run = |name: &str, pct: Option<f64>| {
        let a = SweepOptions {
            sim_magnitude_noise: pct,
            ..args(&d.join(name), &plan)
        };
        assert_eq!(sweep::sweep(&a).unwrap().ending, Ending::Complete);
        Dataset::read(&sweep::data_path(&d.join(name).join("run"))).unwrap()
    };
    let plain = run("plain", None);
    let noisy = run("noisy", Some(0.5));
    assert_eq!(plain.samples.len(), noisy.samples.len());
    for (a, b) in plain.samples.iter().zip(&noisy.samples) {
        assert_eq!([a.x, a.y], [b.x, b.y]);
    }
    let zero = cta_lab::noise::analyze_noise(&plain)
        .unwrap()
        .magnitude
        .unwrap();
    assert!(zero.percent < 1e-9, "{zero:?}");
    // ~30 unpinned points x 7 degrees of freedom: the estimate is within ~5 % (1-sigma) of
    // 0.5 %. Points whose magnitude is pinned at 65535 (close, sensitive) are left out.
    let m = cta_lab::noise::analyze_noise(&noisy)
        .unwrap()
        .magnitude
        .unwrap();
    assert!((m.percent - 0.5).abs() < 0.08, "{m:?}");
    let truth = std::fs::read_to_string(d.join("noisy/run/data.truth.json")).unwrap();
    assert!(
        truth.contains("\"magnitude_noise_percent\": 0.5"),
        "{truth}"
    );
}

/// The simulated sweep's magnitudes through the boards (whole counts, the NorthStar's no-signal
/// floor of 5000 and its 16-bit rail) with the LEDs 10 % apart and 0.3 % magnitude noise:
/// `cta calibrate` finds the simulator's linear law (exponent 1, offset 0, each within a few
/// of its 1-sigma), leaves the saturated points out (the law's max is the rail, and no point
/// it used reads it), measures the noise, and gives each LED's brightness as the truth file
/// records it.
#[test]
fn a_simulated_sweeps_magnitudes_give_a_linear_law_and_the_leds_brightness() {
    use cta_lab::fit::calibrate::{calibrate, fit_magnitude};
    let d = TestDir::new("sweep-e2e-law");
    let plan = write_plan(
        &d,
        r#"
name = "magnitude law"
separations_in = [8, 12, 16, 20, 25, 30]
beacons = "all"
frequencies_hz = [4050]
power_levels = [2]
sensitivities = [4]
samples = 3
settle_ms = 0
"#,
    );
    let a = SweepOptions {
        sim_led_brightness: Some(10.0),
        sim_magnitude_noise: Some(0.3),
        ..args(&d, &plan)
    };
    assert_eq!(sweep::sweep(&a).unwrap().ending, Ending::Complete);
    let run = d.join("run");
    let ds = Dataset::read(&sweep::data_path(&run)).unwrap();
    let saturated = ds
        .samples
        .iter()
        .filter(|s| s.magnitude == Some(65535.0))
        .count();
    assert!(
        saturated > 100,
        "{saturated}: the close points must saturate"
    );
    let mut rep = calibrate(&ds, &ds, None, None, 1.0).unwrap();
    fit_magnitude(&mut rep, &ds, None).unwrap();
    let m = rep.magnitude.as_ref().expect("a magnitude law");
    let law = rep
        .file
        .calibration
        .magnitude
        .expect("the law in the calibration");
    assert_eq!(law, m.law);
    assert_eq!((law.max, law.sensitivity), (65535.0, 4));
    assert!(m.counts, "the sweep's magnitudes are whole counts");
    assert!(m.saturated_points > 30, "{}", m.saturated_points);
    assert_eq!(m.points + m.saturated_points, ds.points().len());
    assert!(
        (f64::from(law.exponent) - 1.0).abs() < 4.0 * m.exponent_sigma && m.exponent_sigma < 0.002,
        "exponent {} +/- {}",
        law.exponent,
        m.exponent_sigma
    );
    let o = m.offset_sigma.unwrap();
    assert!(
        m.offset_at_zero || f64::from(law.offset) < 4.0 * o,
        "offset {} +/- {o}",
        law.offset
    );
    assert!(o < 100.0, "offset 1-sigma {o}");
    assert!(
        (f64::from(law.noise_percent) / 0.3 - 1.0).abs() < 0.15,
        "{}",
        law.noise_percent
    );
    assert_eq!(rep.file.led_brightness, m.led_brightness);
    assert!(rep.file.fitted.sigma.contains_key("magnitude.exponent"));
    // Each LED's brightness against the truth's, normalised alike (geometric mean 1).
    let truth = cta_lab::sim::Truth::load_for(&sweep::data_path(&run))
        .unwrap()
        .unwrap();
    assert_eq!(truth.led_brightness_percent, 10.0);
    let tb = truth.led_brightness;
    assert_eq!(tb.len(), 100);
    let leds = &m.led_brightness;
    assert_eq!(leds.len(), 100);
    let gm = (leds
        .iter()
        .map(|l| tb[l.beacon.unwrap() as usize].ln())
        .sum::<f64>()
        / leds.len() as f64)
        .exp();
    let z: Vec<f64> = leds
        .iter()
        .map(|l| (l.brightness - tb[l.beacon.unwrap() as usize] / gm) / l.sigma)
        .collect();
    let rms = (z.iter().map(|z| z * z).sum::<f64>() / z.len() as f64).sqrt();
    assert!(
        z.iter().all(|z| z.abs() < 4.5) && (0.6..1.5).contains(&rms),
        "brightness z-scores: RMS {rms}, {z:?}"
    );
    assert!(
        (8.0..12.0).contains(&m.brightness_rms_percent),
        "{}",
        m.brightness_rms_percent
    );
}

/// `--sim-effect led_position`: each LED read where its truth sidecar says it sits. Without
/// noise, the sweep's mean output of every beacon moves from the clean sweep's by as much as
/// the offset the truth records for it predicts (eq 65's collinearity: X moves by about
/// H dx / z at the plate's distance), and a beacon the truth leaves in place does not move.
#[test]
fn led_positions_are_simulated_as_recorded() {
    let d = TestDir::new("sweep-ledpos");
    let plan = write_plan(
        &d,
        r#"
name = "led positions"
separations_in = [20]
beacons = [0, 11, 44, 55, 88, 99]
frequencies_hz = [4050]
samples = 2
settle_ms = 0
"#,
    );
    let run = |out: &str, effect: Option<&str>| {
        let a = SweepOptions {
            sim_noise: Some(0.0),
            sim_seed: Some(3),
            sim_effect: effect.map(|e| vec![e.to_string()]).unwrap_or_default(),
            no_sync: true,
            ..sweep_args(&plan, &d.join(out))
        };
        assert_eq!(sweep::sweep(&a).unwrap().ending, Ending::Complete);
        Dataset::read(&sweep::data_path(&d.join(out))).unwrap()
    };
    let clean = run("clean", None);
    let moved = run("moved", Some("led_position=0.05"));
    let truth = cta_lab::sim::Truth::load_for(&sweep::data_path(&d.join("moved")))
        .expect("a truth sidecar")
        .unwrap();
    let offsets = &truth.led_offsets;
    assert_eq!(offsets.len(), 100, "led_offsets recorded");
    let mean_x = |ds: &Dataset, id: u32| {
        let xs: Vec<f64> = ds
            .samples
            .iter()
            .filter(|s| s.beacon == Some(id))
            .map(|s| s.x)
            .collect();
        xs.iter().sum::<f64>() / xs.len() as f64
    };
    // Counts per inch of beacon x at 20 in: H / z, H = beta tan a = 18918.6.
    let per_in = 18918.6 / 20.0;
    for id in [0u32, 11, 44, 55, 88, 99] {
        let dx = offsets[id as usize][0];
        let moved_by = mean_x(&moved, id) - mean_x(&clean, id);
        let want = dx * per_in;
        assert!(
            (moved_by - want).abs() < 0.25 * want.abs() + 3.0,
            "beacon {id}: dx {dx} in predicts {want:.0} counts, moved {moved_by:.0}"
        );
    }
}
