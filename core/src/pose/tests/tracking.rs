//! Tracking from frame to frame: a target turning about the line of sight stays on warm
//! starts, and a lost target is re-acquired on the first frame that has enough beacons.

use super::cold::{angle_between, attitude};
use super::*;
use super::{truth_emulator as physics, uniform_from};

/// The frame `k` of a target turning at `rate` deg/s about the line of sight at 10 Hz,
/// tilted 10 deg, at 8 in, with 0.05 % noise: its spots, position and MRP.
fn frame(k: usize, rate: f64, seed: u32) -> (std::vec::Vec<Spot>, Vector3<f64>, Vector3<f64>) {
    let con = cta_constellation();
    let t = Vector3::new(0.4, -0.3, 8.0);
    let q = attitude(
        -170.0 + rate * 0.1 * k as f64,
        10.0,
        Vector3::new(1.0, 0.5, 0.0),
    );
    let mut u = uniform_from(seed + k as u32);
    let spots = simulate_spots(&physics(), &con, &t, &q, |_| u() * 3.46 * 16.0);
    (spots.to_vec(), t, q)
}

fn check_pose(sol: &PoseSolution<f32>, t: &Vector3<f64>, q: &Vector3<f64>, what: &str) {
    assert_eq!(sol.status, PoseStatus::Ok, "{what}: {sol:?}");
    let p = sol.position.map(|v| v as f64);
    let m = sol.mrp.map(|v| v as f64);
    assert!((p - t).norm() < 0.05, "{what}: {sol:?}");
    assert!(angle_between(&m, q) < 1.0, "{what}: {sol:?}");
}

/// 30 deg/s about the line of sight at 10 Hz (3 deg a frame), through the +/-180 deg
/// wrap of the roll: only the first frame starts cold, every other one from the last pose.
#[test]
fn a_turning_target_stays_on_warm_starts() {
    let con = cta_constellation();
    let mut s =
        PoseSolver::<f32>::new(&Calibration::table3(), &con, SolverSettings::default()).unwrap();
    for k in 0..40 {
        let (spots, t, q) = frame(k, 30.0, 11);
        let sol = s.solve(&spots);
        check_pose(&sol, &t, &q, &format!("frame {k}"));
        assert_eq!(sol.cold_start, k == 0, "frame {k}: {sol:?}");
    }
}

/// The target lost (three beacons in view) for 3 s while it turns 90 deg: the first frame
/// with all of them again is solved Ok, from the cold start, at the true pose; so is a frame
/// after the target jumped 90 deg between two good frames (the warm start diverges and the
/// same frame is solved again cold when Gauss-Newton from the last pose does not reach it).
#[test]
fn a_lost_target_is_reacquired_on_the_first_good_frame() {
    let con = cta_constellation();
    for model in [ModelKind::NearField, ModelKind::Pinhole] {
        let settings = SolverSettings {
            model,
            ..Default::default()
        };
        let mut s = PoseSolver::<f32>::new(&Calibration::table3(), &con, settings).unwrap();
        let near = model == ModelKind::NearField;
        for k in 0..3 {
            let (spots, t, q) = frame(k, 30.0, 21);
            let sol = s.solve(&spots);
            if near {
                check_pose(&sol, &t, &q, &format!("{model:?} frame {k}"));
            }
            assert_eq!(sol.status, PoseStatus::Ok);
        }
        for k in 3..33 {
            let (spots, _, _) = frame(k, 30.0, 21);
            let sol = s.solve(&spots[..3]);
            assert_eq!(sol.status, PoseStatus::TooFewBeacons, "frame {k}");
            assert!(sol.position.iter().all(|v| v.is_finite()));
        }
        assert_eq!(
            s.warm_start(),
            None,
            "{model:?}: a lost target keeps no warm start"
        );
        let (spots, t, q) = frame(33, 30.0, 21);
        let sol = s.solve(&spots);
        assert!(sol.cold_start, "{model:?}: {sol:?}");
        if near {
            check_pose(&sol, &t, &q, "re-acquired");
        }
        assert_eq!(sol.status, PoseStatus::Ok, "{model:?}: {sol:?}");
        // Jumps of 90 and 180 deg between two good frames.
        for jump in [30, 60] {
            let (spots, t, q) = frame(33 + jump, 30.0, 21);
            let sol = s.solve(&spots);
            if near {
                check_pose(&sol, &t, &q, &format!("after a jump of {jump} frames"));
            }
            assert_eq!(sol.status, PoseStatus::Ok, "{model:?}: {sol:?}");
        }
    }
}

/// A warm start Gauss-Newton cannot come back from (the plate turned away, 3 times as far):
/// the frame is solved again from the cold start, Ok and at the true pose.
#[test]
fn a_diverging_warm_start_is_solved_again_cold() {
    let con = cta_constellation();
    let (spots, t, q) = frame(5, 30.0, 31);
    let mut s =
        PoseSolver::<f32>::new(&Calibration::table3(), &con, SolverSettings::default()).unwrap();
    s.set_warm_start(
        Vector3::new(6.0, -5.0, 24.0),
        mrp::from_axis_angle(&Vector3::new(1.0, 0.2, 0.0), rad(120.0)).map(|v| v as f32),
    );
    let sol = s.solve(&spots);
    assert!(sol.cold_start, "{sol:?}");
    check_pose(&sol, &t, &q, "after a wrong warm start");
}
