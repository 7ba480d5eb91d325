//! The spot magnitudes in the near-field pose ([`Magnitude`]).

use super::*;
use super::{check_jacobian, truth_emulator as physics, uniform_from};

fn with_magnitudes(noise_percent: f32) -> Calibration {
    Calibration {
        magnitude: Some(Magnitude::simulated(noise_percent)),
        ..Calibration::table3()
    }
}

fn pose_at(range: f64, k: usize) -> (Vector3<f64>, Vector3<f64>) {
    let a = k as f64;
    (
        Vector3::new(0.3 * (a * 0.7).sin(), -0.2 * (a * 1.3).cos(), range),
        mrp::from_axis_angle(
            &Vector3::new((a * 0.9).sin(), (a * 0.4).cos(), 1.0),
            rad(2.5),
        ),
    )
}

/// Attitude error of a solution, degrees.
fn attitude_error<T: Real>(sol: &PoseSolution<T>, q: &Vector3<f64>) -> f64 {
    let got = Vector3::new(sol.mrp.x.to_f64(), sol.mrp.y.to_f64(), sol.mrp.z.to_f64());
    let c = mrp::dcm(&got) * mrp::dcm(q).transpose();
    let cos = ((c.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
    cos.acos().to_degrees()
}

#[test]
fn validation_names_magnitude_fields_and_brightness() {
    let ok = with_magnitudes(0.07);
    assert_eq!(ok.validate(), Ok(()));
    let field = |f: fn(&mut Magnitude)| {
        let mut c = ok;
        f(c.magnitude.as_mut().unwrap());
        match c.validate() {
            Err(ConfigError::CalibrationOutOfRange { field }) => field,
            other => panic!("{other:?}"),
        }
    };
    assert_eq!(field(|m| m.offset = -1.0), CalField::MagnitudeOffset);
    assert_eq!(field(|m| m.exponent = 0.0), CalField::MagnitudeExponent);
    assert_eq!(
        field(|m| m.exponent = f32::NAN),
        CalField::MagnitudeExponent
    );
    assert_eq!(field(|m| m.noise_percent = 0.0), CalField::MagnitudeNoise);
    assert_eq!(field(|m| m.max = 70000.0), CalField::MagnitudeMax);
    assert_eq!(
        field(|m| {
            m.offset = 5000.0;
            m.max = 5000.5
        }),
        CalField::MagnitudeMax
    );
    assert_eq!(field(|m| m.sensitivity = 5), CalField::MagnitudeSensitivity);
    assert_eq!(field(|m| m.min = 65535.5), CalField::MagnitudeMin);
    assert_eq!(field(|m| m.min = -1.0), CalField::MagnitudeMin);
    assert!(CalField::MagnitudeNoise
        .describe()
        .contains("magnitude noise"));
    let mut con = cta_constellation();
    con.beacons[2].brightness = 0.0;
    let e = con.validate().unwrap_err();
    assert_eq!(e, ConfigError::BrightnessOutOfRange { id: 2 });
    assert!(e.to_string().contains("beacon 2: brightness"), "{e}");
    con.beacons[2].brightness = f32::NAN;
    assert!(con.validate().is_err());
}

/// The magnitude rows' Jacobian (through the contrasts) against central differences of
/// the rows' residuals, for beacons off the plate and a boresight off its normal.
#[test]
fn magnitude_jacobian_matches_finite_differences() {
    let cal = with_magnitudes(0.1);
    let mut con = cta_constellation();
    con.boresight = [0.1, -0.2, -1.0];
    let s = PoseSolver::<f64>::new(&cal, &con, SolverSettings::default()).unwrap();
    let mut obs: [Obs<f64>; 3] = [
        Obs::new(Vector3::new(1.0, 2.0, 0.0), [0.0; 2]),
        Obs::new(Vector3::new(-2.0, 0.5, 0.3), [0.0; 2]),
        Obs::new(Vector3::new(0.5, -1.5, -0.2), [0.0; 2]),
    ];
    for (i, o) in obs.iter_mut().enumerate() {
        o.m = -3.0 + 0.1 * i as f64;
        o.mw = 1000.0 * (1.0 + i as f64);
    }
    obs[1].used = [true, false];
    let p = PoseProblem::of(&s, &obs);
    assert_eq!(p.n_rows(), 5 + 2);
    let (t, q) = pose_at(8.0, 1);
    let x = SVector::<f64, 6>::new(t.x, t.y, t.z, q.x, q.y, q.z);
    p.rows(&x, true, &mut |_, w, _| assert_eq!(w, 1.0)).unwrap();
    let rows = check_jacobian(&p, &x, "magnitudes");
    assert_eq!(rows.len(), p.n_rows());
    // The residual pass gives the same residuals as the Jacobian pass.
    let mut plain = std::vec::Vec::new();
    p.rows(&x, false, &mut |r, _, _| plain.push(r)).unwrap();
    for (a, b) in plain.iter().zip(&rows) {
        assert!((a - b.0).abs() <= 1e-12 * (1.0 + a.abs()), "{a} {}", b.0);
    }
    // The contrasts hold the weighted spread of the magnitude residuals about their
    // weighted mean, whatever the common scale: adding a constant to every m changes
    // nothing.
    let spread = |obs: &[Obs<f64>]| {
        let mut v = std::vec::Vec::new();
        PoseProblem::of(&s, obs)
            .rows(&x, false, &mut |r, _, _| v.push(r))
            .unwrap();
        v
    };
    let before = spread(&obs);
    for o in obs.iter_mut() {
        o.m += 0.7;
    }
    for (a, b) in before.iter().zip(spread(&obs)) {
        assert!((a - b).abs() < 1e-9 * (1.0 + a.abs()), "{a} {b}");
    }
    let r: std::vec::Vec<f64> = (0..3)
        .map(|i| {
            let em = s.emulator.unwrap();
            let (tt, ct) = split(&x);
            let e = ct * s.boresight;
            obs[i].m - em.with_boresight(&e).magnitude(&(tt + ct * obs[i].r)).ln()
        })
        .collect();
    let w: std::vec::Vec<f64> = obs.iter().map(|o| o.mw).collect();
    let mean = (0..3).map(|i| w[i] * r[i]).sum::<f64>() / w.iter().sum::<f64>();
    let want: f64 = (0..3).map(|i| w[i] * (r[i] - mean).powi(2)).sum();
    // The two magnitude rows are the 3rd and 7th (after beacon 2's one and beacon 3's
    // two spot rows): rows 0-1 spots, 2-3 beacon 2 (X, magnitude), 4-6 beacon 3.
    let mags = [before[3], before[6]];
    let got: f64 = mags.iter().map(|v| v * v).sum();
    assert!((got - want).abs() < 1e-9 * want, "{got} {want}");
}

/// RMS attitude and position error of `trials` noisy frames at `range` (spot noise 0.1 %
/// of beta, magnitude noise `mag_percent`), solved cold in f32 by the near-field model
/// with the calibration `cal`; and the RMS of the solver's own attitude 1-sigma.
fn errors(cal: &Calibration, range: f64, mag_percent: f64, trials: usize) -> [f64; 3] {
    let em = physics();
    let con = cta_constellation();
    let sigma = 0.001 * crate::emulator::BETA;
    let mut u = uniform_from(0x9e37_79b9 ^ range as u32);
    let mut v = uniform_from(0x7f4a_7c15 ^ range as u32);
    let (mut att, mut pos, mut pred) = (0.0, 0.0, 0.0);
    for k in 0..trials {
        let (t, q) = pose_at(range, k);
        let spots = simulate_spots_with(
            &em,
            &con,
            &t,
            &q,
            |_| 3.4641016 * sigma * u(),
            |_| 3.4641016 * mag_percent / 100.0 * v(),
        );
        let mut s = PoseSolver::<f32>::new(cal, &con, SolverSettings::default()).unwrap();
        let sol = s.solve(&spots);
        assert_eq!(sol.status, PoseStatus::Ok, "{range} in, trial {k}: {sol:?}");
        let p = Vector3::new(
            sol.position.x as f64,
            sol.position.y as f64,
            sol.position.z as f64,
        );
        att += attitude_error(&sol, &q).powi(2);
        pos += (p - t).norm_squared();
        pred += sol.sigma_attitude_deg.map(|v| (v as f64).powi(2)).sum();
    }
    let n = trials as f64;
    [(att / n).sqrt(), (pos / n).sqrt(), (pred / n).sqrt()]
}

/// The magnitudes at the noise the spot noise implies (0.07 %, `cta sensor floor`) cut
/// the one-frame attitude error at 8-10 in several-fold, where the spots alone sit on
/// their floor; the solver's own 1-sigma follows the error it makes.
#[test]
fn magnitudes_sharpen_the_attitude_at_range() {
    for range in [8.0, 10.0] {
        let spots = errors(&Calibration::table3(), range, 0.07, 60);
        let both = errors(&with_magnitudes(0.07), range, 0.07, 60);
        std::println!("{range} in: spots {spots:?}, with magnitudes {both:?}");
        assert!(
            both[0] < spots[0] / 2.5,
            "{range} in: {both:?} vs {spots:?}"
        );
        // The 1-sigma is honest: the RMS error within 25 % of it (60 trials).
        assert!((both[0] / both[2] - 1.0).abs() < 0.25, "{both:?}");
    }
}

/// One frame at 10 in with 0.07 % magnitude noise, and its truth.
fn frame(con: &Constellation, k: usize) -> (Vec<Spot, MAX_BEACONS>, Vector3<f64>, Vector3<f64>) {
    frame_at(con, k, 10.0)
}

fn frame_at(
    con: &Constellation,
    k: usize,
    range: f64,
) -> (Vec<Spot, MAX_BEACONS>, Vector3<f64>, Vector3<f64>) {
    let em = physics();
    let sigma = 0.001 * crate::emulator::BETA;
    let mut u = uniform_from(0x1234_5678 ^ k as u32);
    let mut v = uniform_from(0x8765_4321 ^ k as u32);
    let (t, q) = pose_at(range, k);
    let spots = simulate_spots_with(
        &em,
        con,
        &t,
        &q,
        |_| 3.4641016 * sigma * u(),
        |_| 3.4641016 * 0.0007 * v(),
    );
    (spots, t, q)
}

/// The common scale of the magnitudes is the solver's to find: the same frame with every
/// magnitude 1.8 times larger (a brighter drive, another power level) gives the same
/// pose. Taken on the matched observations, where it adds ln 1.8 to every `m`: the
/// readings themselves would also round differently (at 10 in they read about 500
/// counts, so their rounding, 0.06 %, is nearly their whole scatter).
#[test]
fn a_common_scale_changes_nothing() {
    let con = cta_constellation();
    let cal = with_magnitudes(0.07);
    let (spots, _, _) = frame(&con, 3);
    let mut s = PoseSolver::<f64>::new(&cal, &con, SolverSettings::default()).unwrap();
    let obs = s.match_spots(&spots);
    let mut brighter = obs.clone();
    for o in brighter.iter_mut() {
        o.m += 1.8f64.ln();
    }
    let a = s.solve_obs(&obs);
    s.reset();
    let b = s.solve_obs(&brighter);
    assert_eq!((a.status, b.status), (PoseStatus::Ok, PoseStatus::Ok));
    assert_eq!((a.magnitudes, b.magnitudes), (10, 10));
    assert!((a.position - b.position).norm() < 1e-9, "{a:?} {b:?}");
    assert!((a.mrp - b.mrp).norm() < 1e-9, "{a:?} {b:?}");
    assert!((a.rms - b.rms).abs() < 1e-9, "{a:?} {b:?}");
}

/// Which magnitudes are used: saturated readings (at or above `max`) and readings not a
/// whole count above the offset are not; frames at another sensitivity than the law's
/// are solved from the spots alone (`solve_frame`), as are calibrations without a law,
/// the pinhole model, and `magnitudes: false`.
#[test]
fn which_magnitudes_are_used() {
    let con = cta_constellation();
    let (mut spots, _, _) = frame(&con, 5);
    let mut cal = with_magnitudes(0.07);
    cal.magnitude.as_mut().unwrap().max = 60000.0;
    spots[0].magnitude = 60000; // saturated
    spots[1].magnitude = 0; // no signal above the offset
    let weak = spots[3].magnitude;
    cal.magnitude.as_mut().unwrap().min = weak as f32 + 1.0;
    let s = PoseSolver::<f64>::new(&cal, &con, SolverSettings::default()).unwrap();
    let obs = s.match_spots(&spots);
    // Below the law's range: every reading weaker than beacon 3's (and its own).
    for (o, sp) in obs.iter().zip(&spots).skip(2) {
        assert_eq!(o.magnitude_used(), sp.magnitude > weak, "{sp:?}");
    }
    let below = spots
        .iter()
        .skip(2)
        .filter(|sp| sp.magnitude <= weak)
        .count();
    assert!(below >= 1);
    cal.magnitude.as_mut().unwrap().min = 0.0;
    let s = PoseSolver::<f64>::new(&cal, &con, SolverSettings::default()).unwrap();
    let obs = s.match_spots(&spots);
    let used: std::vec::Vec<bool> = obs.iter().map(|o| o.magnitude_used()).collect();
    assert_eq!(&used[..2], &[false, false]);
    assert!(used[2..].iter().all(|u| *u));
    // A one-count reading is used, weighed by its rounding: about (0.07 %)^2 / (1/12) =
    // 6e-6 of a reading of 10,000.
    let law = s.mag.unwrap();
    assert!(law.reading(0, 0.0).is_none());
    let (one, big) = (
        law.reading(1, 0.0).unwrap(),
        law.reading(10_000, 0.0).unwrap(),
    );
    assert_eq!(one.0, 0.0);
    assert!((one.1 / big.1 - 5.9e-6).abs() < 0.2e-6, "{one:?} {big:?}");
    let count = |cal: &Calibration, settings: SolverSettings, sensitivity: u8| {
        let mut s = PoseSolver::<f64>::new(cal, &con, settings).unwrap();
        let sol = s.solve_frame(&spots, sensitivity);
        assert_eq!(sol.status, PoseStatus::Ok, "{sol:?}");
        sol.magnitudes
    };
    let nf = SolverSettings::default();
    assert_eq!(count(&cal, nf, 4), 8);
    assert_eq!(count(&cal, nf, 3), 0);
    assert_eq!(count(&Calibration::table3(), nf, 4), 0);
    let off = SolverSettings {
        magnitudes: false,
        ..nf
    };
    assert_eq!(count(&cal, off, 4), 0);
    let pinhole = SolverSettings {
        model: ModelKind::Pinhole,
        ..nf
    };
    assert_eq!(count(&cal, pinhole, 4), 0);
}

/// The beacons' brightness reaches the solver: a constellation whose beacons on the +x
/// side are 10 % brighter than the rest is solved with the magnitudes to their noise when
/// the constellation says so. When it does not, the magnitudes misfit by about 14 times
/// their noise, the solve's residual RMS exceeds `MAGNITUDE_RMS_SIGMAS`, and the pose is
/// the one from the spots alone: no worse than without the magnitudes.
#[test]
fn beacon_brightness_reaches_the_solver() {
    let mut truth = cta_constellation();
    for b in truth.beacons.iter_mut().filter(|b| b.r[0] > 0.0) {
        b.brightness = 1.1;
    }
    let cal = with_magnitudes(0.07);
    let trials = 20;
    let mut att = [0.0; 2];
    for k in 0..trials {
        let (spots, _, q) = frame(&truth, k);
        let solve = |con: &Constellation, settings: SolverSettings| {
            let sol = PoseSolver::<f64>::new(&cal, con, settings)
                .unwrap()
                .solve(&spots);
            assert_eq!(sol.status, PoseStatus::Ok, "{sol:?}");
            sol
        };
        let right = solve(&truth, SolverSettings::default());
        assert_eq!(right.magnitudes, 10);
        assert!(right.rms < 1.5 * cal.noise as f64, "{right:?}");
        let wrong = solve(&cta_constellation(), SolverSettings::default());
        let spots_only = solve(
            &cta_constellation(),
            SolverSettings {
                magnitudes: false,
                ..Default::default()
            },
        );
        assert_eq!(wrong.magnitudes, 0, "{wrong:?}");
        assert_eq!(wrong.position, spots_only.position);
        assert_eq!(wrong.mrp, spots_only.mrp);
        att[0] += attitude_error(&right, &q).powi(2) / trials as f64;
        att[1] += attitude_error(&wrong, &q).powi(2) / trials as f64;
    }
    let att = att.map(f64::sqrt);
    assert!(att[0] < 0.15 && att[1] > 3.0 * att[0], "{att:?}");
}

/// With magnitudes the carried linearisation still gives the Gauss-Newton answer: along a
/// track at 10 in, a solver carrying it and one linearising afresh from the same warm
/// start (and with the same magnitude weights: the carrying solver keeps the last
/// frame's) agree within a small fraction of a standard deviation.
#[test]
fn carried_linearisation_with_magnitudes() {
    let con = cta_constellation();
    let cal = with_magnitudes(0.07);
    let new = || PoseSolver::<f32>::new(&cal, &con, SolverSettings::default()).unwrap();
    let (mut carried, mut fresh) = (new(), new());
    let mut worst = 0.0f64;
    let mut compared = 0;
    for k in 0..30 {
        let (spots, _, _) = frame(&con, k);
        let warm = carried.warm_start();
        match warm {
            Some((t0, q0)) => fresh.set_warm_start(t0, q0),
            None => fresh.reset(),
        }
        let kept = carried.carry_mw;
        let carries = carried.carry.is_some();
        let a = carried.solve(&spots);
        let mut obs = fresh.match_spots(&spots);
        if carries {
            for (o, w) in obs.iter_mut().zip(&kept) {
                o.mw = *w;
            }
        }
        let b = fresh.solve_obs(&obs);
        assert_eq!(a.status, b.status);
        assert_eq!(a.magnitudes, b.magnitudes);
        if warm.is_none() || a.status != PoseStatus::Ok {
            continue;
        }
        compared += 1;
        for i in 0..3 {
            let dp = (a.position[i] - b.position[i]).abs() / b.sigma_position[i];
            let dq = (4.0 * (a.mrp[i] - b.mrp[i])).abs().to_degrees() / b.sigma_attitude_deg[i];
            worst = worst.max(f64::from(dp.max(dq)));
        }
    }
    assert!(compared > 20, "{compared}");
    assert!(worst < 0.05, "{worst}");
}
