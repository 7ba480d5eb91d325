//! Tests of the simulator: seeds, streams, limits, the files it writes.

use super::*;
use cta_core::real::rad;
use std::path::Path;

#[test]
fn noise_free_matches_emulator_and_is_seeded() {
    let cfg = SimConfig {
        separations: vec![20.0, 25.0],
        ..Default::default()
    };
    let (d, t) = cfg.run();
    assert_eq!(d.samples.len(), 200);
    assert_eq!(t.skipped_points, 0);
    let em = cfg.physics().emulator;
    let s = d.samples[37];
    let o = em.output(&Vector3::from(s.r)).unwrap();
    assert_eq!([s.x, s.y], o);
    let noisy = SimConfig {
        noise: 30.0,
        samples: 3,
        seed: 9,
        ..cfg.clone()
    };
    let (a, _) = noisy.run();
    let (b, _) = noisy.run();
    assert_eq!(a.samples, b.samples);
    assert!(a.samples.iter().all(|s| s.x.fract() == 0.0));
}

/// Magnitude noise is drawn from its own stream (x and y of a seed are unchanged), is
/// recovered by `cta noise`, is recorded in the truth, and is refused beyond 25 %.
#[test]
fn magnitude_noise_is_its_own_stream_and_measurable() {
    let base = SimConfig {
        separations: vec![5.0, 20.0],
        noise: 30.0,
        samples: 20,
        seed: 3,
        ..Default::default()
    };
    let (plain, t0) = base.run();
    let with = SimConfig {
        magnitude_noise: 0.5,
        ..base.clone()
    };
    let (noisy, t1) = with.run();
    assert_eq!(t0.magnitude_noise_percent, 0.0);
    assert_eq!(t1.magnitude_noise_percent, 0.5);
    assert_eq!(plain.samples.len(), noisy.samples.len());
    for (a, b) in plain.samples.iter().zip(&noisy.samples) {
        assert_eq!([a.x, a.y], [b.x, b.y]);
    }
    assert!(plain
        .samples
        .iter()
        .zip(&noisy.samples)
        .any(|(a, b)| a.magnitude != b.magnitude));
    let zero = crate::noise::analyze_noise(&plain)
        .unwrap()
        .magnitude
        .unwrap();
    assert!(zero.percent < 1e-9);
    // 200 points x 19 degrees of freedom: the pooled estimate is within ~1.2 % (1-sigma)
    // of the truth; 5 % is four sigma.
    let m = crate::noise::analyze_noise(&noisy)
        .unwrap()
        .magnitude
        .unwrap();
    assert!((m.percent - 0.5).abs() < 0.025, "{m:?}");
    for bad in [-0.1, 25.5, f64::NAN] {
        let e = SimConfig {
            magnitude_noise: bad,
            ..base.clone()
        }
        .check()
        .unwrap_err()
        .to_string();
        assert!(e.contains("magnitude noise"), "{e}");
    }
}

/// The LEDs' brightness scatter multiplies each beacon's magnitudes by its LED's factor
/// (recorded in the truth, drawn from a stream of its own: x, y and the magnitude noise of
/// the seed are unchanged), about as widely as asked; 0 leaves the file as it was, and the
/// truth without factors; beyond 50 % it is refused.
#[test]
fn led_brightness_scales_the_magnitudes_by_their_leds_factor() {
    let base = SimConfig {
        separations: vec![5.0, 20.0],
        noise: 30.0,
        samples: 2,
        magnitude_noise: 0.5,
        seed: 8,
        ..Default::default()
    };
    let (plain, t0) = base.run();
    assert!(t0.led_brightness.is_empty() && t0.led_brightness_percent == 0.0);
    let json = serde_json::to_string(&t0).unwrap();
    assert!(!json.contains("\"led_brightness\""), "{json}");
    let (bright, t1) = SimConfig {
        led_brightness: 10.0,
        ..base.clone()
    }
    .run();
    assert_eq!(t1.led_brightness_percent, 10.0);
    assert_eq!(t1.led_brightness.len(), 100);
    assert_eq!(t1.led_brightness, led_brightness(8, 10.0, 100));
    let mut compared = 0;
    for (a, b) in plain.samples.iter().zip(&bright.samples) {
        assert_eq!([a.x, a.y], [b.x, b.y]);
        let f = t1.led_brightness[a.beacon.unwrap() as usize];
        let (ma, mb) = (a.magnitude.unwrap(), b.magnitude.unwrap());
        // Whole counts (the coordinates are rounded too), saturated at 65535 (5 in, power
        // level 2, sensitivity 4: the magnitude law's spots saturate there).
        if ma.max(mb) >= 65535.0 {
            continue;
        }
        compared += 1;
        assert!(
            (mb / ma / f - 1.0).abs() < 0.6 / ma + 0.6 / mb,
            "{ma} {mb} {f}"
        );
    }
    assert!(compared >= 200, "{compared}");
    let ln: Vec<f64> = t1.led_brightness.iter().map(|b| b.ln()).collect();
    let sd = (ln.iter().map(|v| v * v).sum::<f64>() / ln.len() as f64).sqrt();
    assert!((0.08..0.12).contains(&sd), "{sd}");
    assert!(led_brightness(8, 0.0, 3) == [1.0; 3]);
    for bad in [-1.0, 50.5, f64::NAN] {
        let e = SimConfig {
            led_brightness: bad,
            ..base.clone()
        }
        .check()
        .unwrap_err()
        .to_string();
        assert!(e.contains("LED brightness"), "{e}");
    }
}

#[test]
fn grid_ids_fit_the_beacon_column() {
    assert_eq!(parse_grid("20x20").unwrap(), (20, 20));
    // 10,000 beacons used to be allowed; ids above 399 make files `cta` cannot read.
    assert!(parse_grid("100x100")
        .unwrap_err()
        .to_string()
        .contains("400 beacons"));
    assert!(parse_grid("21x20").is_err());
    assert!(parse_grid("0x5").is_err());
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("cta-simulate-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn huge_sample_counts_are_refused_before_allocating() {
    // `--samples 100000000` used to abort on a 1.36 TB allocation.
    let cfg = SimConfig {
        samples: 100_000_000,
        ..Default::default()
    };
    let e = cfg.try_run().unwrap_err().to_string();
    assert!(e.contains("between 1 and 100000"), "{e}");
    let cfg = SimConfig {
        samples: 0,
        ..Default::default()
    };
    assert!(cfg.try_run().is_err());
    // Within the per-point cap but too many reports in all.
    let cfg = SimConfig {
        samples: MAX_SAMPLES,
        ..Default::default()
    };
    let e = cfg.try_run().unwrap_err().to_string();
    assert!(
        e.contains("29 separations x 100 beacons x 100000 samples"),
        "{e}"
    );
    assert!(e.contains("more than the 10000000"), "{e}");
}

#[test]
fn nothing_simulated_is_an_error() {
    // `--separations 1e300`: the signal underflows; 0 reports used to exit 0.
    let cfg = SimConfig {
        separations: vec![1e300],
        ..Default::default()
    };
    assert!(cfg.run().0.samples.is_empty());
    let e = cfg.try_run().unwrap_err().to_string();
    assert!(
        e.contains("nothing to write: all 100 beacon positions"),
        "{e}"
    );
    assert!(e.contains("1e300"), "{e}");
}

#[test]
fn repeated_effects_are_refused() {
    let cfg = SimConfig {
        separations: vec![20.0],
        effects: vec![Effect::CellGain(0.1, 0.0), Effect::CellGain(0.2, 0.0)],
        ..Default::default()
    };
    assert!(cfg
        .try_run()
        .unwrap_err()
        .to_string()
        .contains("given twice"));
}

#[test]
fn write_files_leaves_no_partial_file_behind() {
    let d = tmpdir("write");
    let cfg = SimConfig {
        separations: vec![20.0],
        ..Default::default()
    };
    let (ds, truth) = cfg.try_run().unwrap();
    let partials = |d: &Path| {
        std::fs::read_dir(d)
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .path()
                    .to_string_lossy()
                    .ends_with(".partial")
            })
            .count()
    };
    // --out is a directory.
    let e = write_files(&d, &ds, &truth, false).unwrap_err().to_string();
    assert!(
        e.contains(&d.display().to_string()) && e.contains("is a folder"),
        "{e}"
    );
    // The truth cannot be put in place: both partial files are removed.
    let out = d.join("x.csv");
    std::fs::create_dir_all(d.join("x.truth.json").join("sub")).unwrap();
    let e = write_files(&out, &ds, &truth, false)
        .unwrap_err()
        .to_string();
    assert!(e.contains("x.truth.json"), "{e}");
    assert_eq!(partials(&d), 0);
    assert!(!out.exists());
    // A folder that does not exist is created; one that cannot be (a file is in the way)
    // is an error naming the file.
    let y = d.join("no").join("y.csv");
    write_files(&y, &ds, &truth, false).unwrap();
    assert!(y.exists() && d.join("no").join("y.truth.json").exists());
    let e = write_files(&y.join("z.csv"), &ds, &truth, false)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("cannot write") && e.contains("z.csv"), "{e}");
    // Success: both files, readable, no partial.
    let tp = write_files(&d.join("ok.csv"), &ds, &truth, false).unwrap();
    assert_eq!(partials(&d), 0);
    assert_eq!(Dataset::read(&d.join("ok.csv")).unwrap().samples.len(), 100);
    assert!(Truth::load_for(&d.join("ok.csv")).unwrap().is_ok());
    assert_eq!(tp, d.join("ok.truth.json"));
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn write_files_replaces_only_an_earlier_simulation() {
    // The guard is in the library: a caller other than `cta simulate` cannot replace a
    // sweep's data either.
    let d = tmpdir("replace");
    let cfg = SimConfig {
        separations: vec![20.0],
        ..Default::default()
    };
    let (ds, truth) = cfg.try_run().unwrap();
    let data = d.join("data.csv");
    let text = "# cta 0.1.0 sweep: plan `x`\nseparation_in,beacon_x_in,beacon_y_in\n";
    std::fs::write(&data, text).unwrap();
    let e = write_files(&data, &ds, &truth, false)
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        format!(
            "--out {}: exists and is not an earlier `cta simulate` output (first line: `# cta \
             0.1.0 sweep: plan `x``); not replaced: give another file name, or --force to \
             replace it",
            data.display()
        )
    );
    assert_eq!(std::fs::read_to_string(&data).unwrap(), text, "untouched");
    assert!(!d.join("data.truth.json").exists() && !d.join("data.csv.partial").exists());
    assert_eq!(check_out(&data, false).unwrap_err().to_string(), e);
    // An earlier simulation is replaced; anything else with `force`.
    let sim = d.join("sim.csv");
    write_files(&sim, &ds, &truth, false).unwrap();
    check_out(&sim, false).unwrap();
    write_files(&sim, &ds, &truth, false).unwrap();
    write_files(&data, &ds, &truth, true).unwrap();
    assert_eq!(Dataset::read(&data).unwrap().samples.len(), 100);
    // A new file name whose truth sidecar exists and is something else: refused, the
    // sidecar untouched.
    let other = d.join("new.truth.json");
    std::fs::write(&other, "{\"notes\": 1}").unwrap();
    let e = write_files(&d.join("new.csv"), &ds, &truth, false)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("new.truth.json") && e.contains("not the truth"),
        "{e}"
    );
    assert_eq!(std::fs::read_to_string(&other).unwrap(), "{\"notes\": 1}");
    assert!(!d.join("new.csv").exists());
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn fit_warns_about_a_corrupt_truth_sidecar() {
    let d = tmpdir("truth");
    let csv = d.join("m.csv");
    assert!(matches!(Truth::load_for_fit(&csv), (None, None)));
    std::fs::write(d.join("m.truth.json"), "{ not json").unwrap();
    let (t, w) = Truth::load_for_fit(&csv);
    assert!(t.is_none());
    let w = w.unwrap();
    assert!(
        w.contains("m.truth.json") && w.contains("key must be a string"),
        "{w}"
    );
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn plate_offset_moves_truth_not_record() {
    let cfg = SimConfig {
        separations: vec![10.0],
        effects: vec![Effect::PlateOffset(0.1)],
        ..Default::default()
    };
    let (d, t) = cfg.run();
    assert!(t.plate_offsets[0][0].abs() > 0.0);
    assert_eq!(d.samples[0].r, [-4.5, -4.5, 10.0]);
}

/// A plate tilted T toward azimuth AZ: its downward normal (and so every LED boresight)
/// leans T toward AZ, the side toward AZ is farther from the sensor by u sin T, the
/// centre stays put and distances on the plate are kept.
#[test]
fn a_tilted_plate_turns_about_its_centre() {
    let t = 2.0f64;
    for az in [0.0f64, 90.0, 135.0, -60.0] {
        let (c, s) = (az.to_radians().cos(), az.to_radians().sin());
        let pl = Placement {
            offset: [0.1, -0.2],
            sep_error: 0.05,
            tilt_deg: [t * c, t * s],
        };
        let n = pl.rotation() * Vector3::new(0.0, 0.0, -1.0);
        let want = Vector3::new(rad(t).sin() * c, rad(t).sin() * s, -rad(t).cos());
        assert!((n - want).norm() < 1e-12, "AZ {az}: {n}");
        let centre = pl.beacon(&Vector3::new(0.0, 0.0, 10.0));
        assert!((centre - Vector3::new(0.1, -0.2, 10.05)).norm() < 1e-12);
        // 4 in from the centre toward AZ: farther by 4 sin T; the opposite side nearer.
        let toward = pl.beacon(&Vector3::new(4.0 * c, 4.0 * s, 10.0));
        let away = pl.beacon(&Vector3::new(-4.0 * c, -4.0 * s, 10.0));
        assert!(
            (toward.z - 10.05 - 4.0 * rad(t).sin()).abs() < 1e-12,
            "AZ {az}"
        );
        assert!(
            (away.z - 10.05 + 4.0 * rad(t).sin()).abs() < 1e-12,
            "AZ {az}"
        );
        assert!(((toward - centre).norm() - 4.0).abs() < 1e-12);
        // Across the azimuth: no change in z.
        let side = pl.beacon(&Vector3::new(-4.0 * s, 4.0 * c, 10.0));
        assert!((side.z - 10.05).abs() < 1e-12, "AZ {az}");
        let em = SimConfig::default().physics().emulator;
        assert!((pl.emulator(&em).boresight() - want).norm() < 1e-12);
    }
    // No tilt: the recorded place plus the offsets, the emulator unchanged.
    let flat = Placement {
        offset: [0.1, 0.0],
        ..Default::default()
    };
    assert_eq!(
        flat.beacon(&Vector3::new(3.0, 1.0, 5.0)),
        Vector3::new(3.1, 1.0, 5.0)
    );
    // A seed's offsets and separation errors do not change when a tilt is added.
    let run = |fx: Vec<Effect>| {
        SimConfig {
            separations: vec![5.0, 10.0],
            effects: fx,
            ..Default::default()
        }
        .physics()
        .geometry
    };
    let a = run(vec![Effect::PlateOffset(0.1), Effect::SeparationError(0.1)]);
    let b = run(vec![
        Effect::PlateOffset(0.1),
        Effect::SeparationError(0.1),
        Effect::PlateTilt(0.5),
    ]);
    for (a, b) in a.iter().zip(&b) {
        assert_eq!((a.offset, a.sep_error), (b.offset, b.sep_error));
        assert!(!a.tilted() && b.tilted());
    }
}

/// The quad layout: four copies of the grid at (+/-6, +/-6) in, ids `100 a + LED`; each
/// array moved by its pose, recorded in the truth; `array_pose` on one array is refused, and
/// the sweep's simulated CTA refuses what it would ignore.
#[test]
fn quad_arrays_are_placed_by_their_poses() {
    let cfg = SimConfig {
        separations: vec![30.0],
        quad: Some(12.0),
        effects: vec![Effect::parse("array_pose=0.02,0.3").unwrap()],
        ..SimConfig::default()
    };
    let phys = cfg.physics();
    let (ds, truth) = cfg.run();
    assert_eq!(
        truth.array_centres,
        [[-6.0, -6.0], [6.0, -6.0], [-6.0, 6.0], [6.0, 6.0]]
    );
    assert_eq!(truth.array_poses.len(), 4);
    let s = ds.samples.iter().find(|s| s.beacon == Some(311)).unwrap();
    // LED 11 of a 10 x 10 grid: column 1, row 1, at (-3.5, -3.5) from its array's centre.
    assert_eq!([s.r[0], s.r[1]], [2.5, 2.5]);
    // Its true place: turned about (6, 6) by dtheta (counter-clockwise), then shifted.
    let [dx, dy, dt] = truth.array_poses[3];
    let (sn, cs) = dt.to_radians().sin_cos();
    let want = [
        6.0 + cs * -3.5 - sn * -3.5 + dx,
        6.0 + sn * -3.5 + cs * -3.5 + dy,
    ];
    let r = phys.beacon(0, 311, &nalgebra::Vector3::new(2.5, 2.5, 30.0));
    assert!(
        (r.x - want[0]).abs() < 1e-12 && (r.y - want[1]).abs() < 1e-12,
        "{r}"
    );
    assert!(dt != 0.0 && dx != 0.0);
    let one = SimConfig {
        quad: None,
        ..cfg.clone()
    };
    assert_eq!(one.check(), Err(SimError::OneArray));
    let e = crate::sim::effects::check_sweep(&cfg.effects).unwrap_err();
    assert!(e.to_string().contains("array_pose"), "{e}");
}
