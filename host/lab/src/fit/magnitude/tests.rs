//! The magnitude law on synthetic points and simulated files.

use super::*;
use cta_core::emulator::{grid_position, Effects, Head, Pose};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

/// Points of the law `offset + a (b S)^exponent` on the 10 x 10 grid at `seps`, `n`
/// samples each with `rel` relative scatter, rounded to counts; the LEDs' brightness drawn
/// log-normal with `spread`. Returns the points and the brightnesses.
fn synthetic(
    offset: f64,
    exponent: f64,
    spread: f64,
    rel: f64,
    seps: &[f64],
    n: usize,
    seed: u64,
) -> (Vec<MagPoint>, Vec<f64>) {
    let em = Emulator::new(Head::northstar(), Pose::table3(), Effects::default());
    let mut rng = StdRng::seed_from_u64(seed);
    let b: Vec<f64> = (0..100)
        .map(|_| (spread * rng.sample::<f64, _>(StandardNormal)).exp())
        .collect();
    // The brightest point (at the closest separation) reads about 60000.
    let top = seps
        .iter()
        .flat_map(|&s| (0..100).map(move |i| (s, i)))
        .map(|(s, i)| (b[i] * em.magnitude(&grid_position(10, 1.0, s, i))).powf(exponent))
        .fold(0.0, f64::max);
    let a = (60000.0 - offset) / top;
    let mut points = Vec::new();
    for &sep in seps {
        for (i, bi) in b.iter().enumerate() {
            let s = em.magnitude(&grid_position(10, 1.0, sep, i));
            let d = a * (bi * s).powf(exponent);
            let readings = (0..n)
                .map(|_| {
                    let z: f64 = rng.sample(StandardNormal);
                    (offset + d * (1.0 + rel * z)).round()
                })
                .collect();
            points.push(MagPoint {
                led: i,
                setting: 0,
                separation_in: sep,
                s,
                readings,
            });
        }
    }
    (points, b)
}

/// The brief's case: offset 5000 counts, exponent 0.8, LEDs 10 % apart, 0.3 % noise.
/// The fit recovers each within a few of its 1-sigma (which are small: the test could not
/// pass on loose bounds), the noise within 15 %, and every LED's brightness within its
/// own; the brightnesses' z-scores have an RMS near 1 (their 1-sigma are honest).
#[test]
fn a_synthetic_law_is_recovered_within_its_sigma() {
    let seps: Vec<f64> = (2..=15).map(|k| 2.0 * k as f64).collect();
    for seed in [1, 2] {
        let (points, b) = synthetic(5000.0, 0.8, 0.1, 0.003, &seps, 5, seed);
        let f = fit_law(&points, 100, 1, true).unwrap();
        let z_o = (f.offset - 5000.0) / f.offset_sigma;
        let z_g = (f.exponent - 0.8) / f.exponent_sigma;
        assert!(
            z_o.abs() < 4.0 && f.offset_sigma < 5.0,
            "seed {seed}: offset {} +/- {}",
            f.offset,
            f.offset_sigma
        );
        assert!(
            z_g.abs() < 4.0 && f.exponent_sigma < 0.001,
            "seed {seed}: exponent {} +/- {}",
            f.exponent,
            f.exponent_sigma
        );
        assert!(
            (f.rel() / 0.003 - 1.0).abs() < 0.15,
            "seed {seed}: noise {} % (within {}, between {})",
            100.0 * f.rel(),
            100.0 * f.rel_within,
            100.0 * f.rel_between
        );
        let mean_ln = b.iter().map(|v| v.ln()).sum::<f64>() / b.len() as f64;
        let z: Vec<f64> = (0..100)
            .map(|i| {
                (f.ln_brightness[i].unwrap() - (b[i].ln() - mean_ln))
                    / f.ln_brightness_sigma[i].unwrap()
            })
            .collect();
        let rms = (z.iter().map(|z| z * z).sum::<f64>() / z.len() as f64).sqrt();
        let worst = z.iter().map(|z| z.abs()).fold(0.0, f64::max);
        assert!(
            (0.6..1.5).contains(&rms) && worst < 5.0,
            "seed {seed}: brightness z RMS {rms}, worst {worst}"
        );
    }
}

/// A simulated file (`cta simulate`'s magnitudes are `S` times the LED's brightness)
/// turned into counts of the law `300 + k S`, with the sensor saturating at 50000 (below
/// the 16-bit rail): the pile-up is found and its points left out, the law is recovered,
/// and the fit reads the file's sensitivity.
#[test]
fn a_file_saturating_below_the_rail_gives_its_law_and_max() {
    use crate::sim::SimConfig;
    let cfg = SimConfig {
        separations: vec![6.0, 10.0, 14.0, 17.0, 20.0, 24.0, 30.0],
        samples: 3,
        noise: 10.0,
        magnitude_noise: 0.3,
        led_brightness: 5.0,
        seed: 4,
        ..Default::default()
    };
    let (mut ds, truth) = cfg.run();
    let em = cfg.physics().emulator;
    // 6 in on the axis reads about 100000: the closest separation saturates. The file's
    // counts (the NorthStar's magnitude law, `cta_core::magnitude_law`) are turned back into
    // the signal times the LED's brightness; the law's own saturation (6-14 in, power level 2,
    // sensitivity 4) stays saturation.
    let k = 100_000.0 / em.magnitude(&Vector3::new(0.0, 0.0, 6.0));
    let counts_per_signal =
        cta_core::magnitude_law::reading(1.0, cta_core::magnitude_law::signal_at_30(&em), 2, 4);
    for s in &mut ds.samples {
        let m = s.magnitude.unwrap();
        s.magnitude = Some(if m >= 65535.0 {
            50_000.0
        } else {
            (300.0 + k * m / counts_per_signal).round().min(50_000.0)
        });
        s.sensitivity = Some(3.0);
    }
    let Outcome::Law(m) = fit_dataset(&ds, &em, None).unwrap() else {
        panic!("no law")
    };
    assert_eq!((m.law.max, m.law.sensitivity), (50_000.0, 3));
    assert!(m.saturated_points > 20, "{}", m.saturated_points);
    // The law's range below: the weakest reading of a point it fitted (not a saturated
    // point's).
    let weakest = ds
        .samples
        .iter()
        .map(|s| s.magnitude.unwrap())
        .filter(|&m| m < 50_000.0)
        .fold(f64::INFINITY, f64::min);
    assert_eq!(f64::from(m.law.min), weakest.floor(), "{:?}", m.law);
    assert!(
        m.warnings
            .iter()
            .any(|w| w.contains("taken as the sensor's saturation")),
        "{:?}",
        m.warnings
    );
    let o = m.offset_sigma.unwrap();
    assert!(
        (f64::from(m.law.offset) - 300.0).abs() < 4.0 * o && o < 10.0,
        "offset {} +/- {o}",
        m.law.offset
    );
    assert!(
        (f64::from(m.law.exponent) - 1.0).abs() < 4.0 * m.exponent_sigma,
        "exponent {} +/- {}",
        m.law.exponent,
        m.exponent_sigma
    );
    assert!(
        (f64::from(m.law.noise_percent) / 0.3 - 1.0).abs() < 0.15,
        "{}",
        m.law.noise_percent
    );
    // The brightness against the truth's, normalised alike.
    let gm = (m
        .led_brightness
        .iter()
        .map(|l| truth.led_brightness[l.beacon.unwrap() as usize].ln())
        .sum::<f64>()
        / m.led_brightness.len() as f64)
        .exp();
    for l in &m.led_brightness {
        let t = truth.led_brightness[l.beacon.unwrap() as usize] / gm;
        assert!((l.brightness - t).abs() < 5.0 * l.sigma, "{l:?}: truth {t}");
    }
    // No saturation seen: the law's max is the rail.
    let mut low = ds.clone();
    low.samples.retain(|s| s.magnitude.unwrap() < 50_000.0);
    let Outcome::Law(m) = fit_dataset(&low, &em, Some(3)).unwrap() else {
        panic!("no law")
    };
    assert_eq!((m.law.max, m.saturated_points), (RAIL as f32, 0));
    // Another sensitivity: an error naming what the file has.
    let e = fit_dataset(&ds, &em, Some(2)).unwrap_err().to_string();
    assert!(
        e.contains("no magnitudes at sensitivity 2") && e.contains("3: "),
        "{e}"
    );
}

/// No law, and no error: a file without magnitudes, and one with them at one separation.
#[test]
fn files_that_cannot_give_a_law_say_why() {
    use crate::sim::SimConfig;
    // 20 and 30 in: nearer, the magnitude law's spots saturate at power level 2.
    let cfg = SimConfig {
        separations: vec![20.0, 30.0],
        ..Default::default()
    };
    let (ds, _) = cfg.run();
    let em = cfg.physics().emulator;
    let mut none = ds.clone();
    for s in &mut none.samples {
        s.magnitude = None;
    }
    match fit_dataset(&none, &em, None).unwrap() {
        Outcome::NoLaw(w) => assert!(w.contains("records no spot magnitudes"), "{w}"),
        Outcome::Law(_) => panic!("a law without magnitudes"),
    }
    let mut one = ds.clone();
    for s in &mut one.samples {
        if s.separation_in == 30.0 {
            s.magnitude = None;
        }
    }
    match fit_dataset(&one, &em, None).unwrap() {
        Outcome::NoLaw(w) => assert!(w.contains("1 separation(s) (20 in)"), "{w}"),
        Outcome::Law(_) => panic!("a law from one separation"),
    }
    // Both separations: a law (the noise-free file's scatter is the board's floor).
    let Outcome::Law(m) = fit_dataset(&ds, &em, None).unwrap() else {
        panic!("no law")
    };
    assert_eq!(m.law.noise_percent, 0.001);
    assert!((m.law.exponent - 1.0).abs() < 1e-4, "{:?}", m.law);
}
