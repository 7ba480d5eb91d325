//! The attitude-independent cold start ([`super::super::cold`]): any roll about the line of
//! sight, tilted and offset targets, both models.

use super::super::cold::plate_pose;
use super::*;
use super::{truth_emulator as physics, uniform_from};

/// The MRP of the target turned by `roll` deg about the line of sight (`z`), then tilted by
/// `tilt` deg about `axis`.
pub(super) fn attitude(roll: f64, tilt: f64, axis: Vector3<f64>) -> Vector3<f64> {
    let r = mrp::from_axis_angle(&Vector3::z(), rad(roll));
    if tilt == 0.0 {
        return r;
    }
    mrp::compose(&mrp::from_axis_angle(&axis, rad(tilt)), &r)
}

/// Angle between two attitudes, degrees.
pub(super) fn angle_between(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let c = mrp::dcm(a) * mrp::dcm(b).transpose();
    ((c.trace() - 1.0) / 2.0)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// Spots of the pinhole model (eq 65 with the Table 3 head) for the target at `(t, q)`,
/// rounded to counts, plus `noise` counts (uniform, that 1-sigma); beacons past the rails
/// left out.
pub(super) fn pinhole_spots(
    con: &Constellation,
    t: &Vector3<f64>,
    q: &Vector3<f64>,
    noise: f64,
    seed: u32,
) -> std::vec::Vec<Spot> {
    let model = SolverSettings {
        model: ModelKind::Pinhole,
        ..Default::default()
    };
    let truth = PoseSolver::<f64>::new(&Calibration::table3(), con, model).unwrap();
    let x = SVector::<f64, 6>::new(t.x, t.y, t.z, q.x, q.y, q.z);
    let mut u = uniform_from(seed);
    con.beacons
        .iter()
        .filter_map(|b| {
            let y = truth.predict(&x, &v3(&b.r))?;
            let n = [u() * 3.46 * noise, u() * 3.46 * noise];
            let y = [y[0] + n[0], y[1] + n[1]];
            (y[0].abs() < 32000.0 && y[1].abs() < 32000.0).then(|| Spot {
                id: b.id,
                x: y[0].round() as i16,
                y: y[1].round() as i16,
                magnitude: 9000,
            })
        })
        .collect()
}

/// Poses over rolls of a quarter turn and more (where the `q = 0` start diverged), with
/// tilts and offsets: (t, roll deg, tilt deg, tilt axis).
fn poses() -> std::vec::Vec<(Vector3<f64>, f64, f64, Vector3<f64>)> {
    let mut v = std::vec::Vec::new();
    let x = Vector3::x();
    let xy = Vector3::new(1.0, 1.0, 0.0);
    for roll in [0.0, 90.0, -90.0, 150.0, 180.0, -135.0] {
        v.push((Vector3::new(0.0, 0.0, 8.0), roll, 0.0, x));
        v.push((Vector3::new(1.5, -1.0, 6.0), roll, 25.0, x));
        v.push((Vector3::new(-2.0, 3.0, 20.0), roll, 20.0, xy));
        v.push((Vector3::new(0.2, 0.1, 3.0), roll, -15.0, xy));
    }
    v
}

/// On exact pinhole lines of sight the plate pose is the pose (to the counts' rounding),
/// whatever the roll.
#[test]
fn plate_pose_is_the_pose_on_pinhole_lines_of_sight() {
    let con = cta_constellation();
    let model = SolverSettings {
        model: ModelKind::Pinhole,
        ..Default::default()
    };
    let s = PoseSolver::<f64>::new(&Calibration::table3(), &con, model).unwrap();
    let cal = Calibration::table3();
    let (d, c_p) = (v3::<f64>(&cal.d), mrp::dcm(&v3::<f64>(&cal.p)));
    for (t, roll, tilt, axis) in poses() {
        let q = attitude(roll, tilt, axis);
        let spots = pinhole_spots(&con, &t, &q, 0.0, 1);
        let obs = s.match_spots(&spots);
        let pp = plate_pose(&obs, cal.h as f64).unwrap();
        let x = pp.unknowns(&d, &c_p);
        let (tp, qp) = (
            Vector3::new(x[0], x[1], x[2]),
            Vector3::new(x[3], x[4], x[5]),
        );
        let case = format!("t {t:?} roll {roll} tilt {tilt}");
        assert!((tp - t).norm() < 0.02 * t.z, "{case}: t {tp:?}");
        assert!(angle_between(&qp, &q) < 1.0, "{case}: q {qp:?} vs {q:?}");
    }
}

/// The cold start reaches the pose at rolls of 90, -90, 150, 180 deg, tilted and offset,
/// with both models (pinhole spots for the pinhole model, the eq 60-63 physics for the
/// near-field one), in f64 and on the chip's f32.
#[test]
fn cold_start_converges_at_any_roll() {
    let con = cta_constellation();
    let em = physics();
    for model in [ModelKind::NearField, ModelKind::Pinhole] {
        let settings = SolverSettings {
            model,
            ..Default::default()
        };
        for (k, (t, roll, tilt, axis)) in poses().into_iter().enumerate() {
            let q = attitude(roll, tilt, axis);
            let spots: std::vec::Vec<Spot> = match model {
                ModelKind::Pinhole => pinhole_spots(&con, &t, &q, 3.0, k as u32 + 1),
                ModelKind::NearField => {
                    let mut u = uniform_from(k as u32 + 1);
                    simulate_spots(&em, &con, &t, &q, |_| u() * 3.46 * 3.0).to_vec()
                }
            };
            let case = format!("{model:?} t {t:?} roll {roll} tilt {tilt}");
            let mut s64 = PoseSolver::<f64>::new(&Calibration::table3(), &con, settings).unwrap();
            let sol = s64.solve(&spots);
            assert_eq!(sol.status, PoseStatus::Ok, "{case}: {sol:?}");
            assert!(sol.cold_start, "{case}");
            let dt = (sol.position - t).norm();
            let dq = angle_between(&sol.mrp, &q);
            let st = sol.sigma_position.norm();
            assert!(dt < 5.0 * st + 1e-3, "{case}: |dt| {dt} sigma {st}");
            assert!(
                dq < 5.0 * sol.sigma_attitude_deg.norm() + 0.01,
                "{case}: {dq} deg"
            );
            let mut s32 = PoseSolver::<f32>::new(&Calibration::table3(), &con, settings).unwrap();
            let sol32 = s32.solve(&spots);
            assert_eq!(sol32.status, PoseStatus::Ok, "{case} f32: {sol32:?}");
            let p32 = sol32.position.map(|v| v as f64);
            assert!(
                (p32 - sol.position).norm() < 1e-3 * t.z,
                "{case} f32: {sol32:?}"
            );
        }
    }
}

/// The QEMU cold-frame benchmark ([`cold_frames_of`]): each frame, solved from nothing in
/// f32, reaches the minimum GLSDC reaches from the true pose, for both models and both the
/// 10- and the 20-beacon constellation.
#[test]
fn cold_benchmark_frames_reach_the_minimum() {
    for con in [cta_constellation(), four_array_constellation()] {
        for model in [ModelKind::NearField, ModelKind::Pinhole] {
            let settings = SolverSettings {
                model,
                ..Default::default()
            };
            for (spots, t, q) in cold_frames_of(&con) {
                let s = PoseSolver::<f32>::new(&Calibration::table3(), &con, settings).unwrap();
                let sol = s.clone().solve(&spots);
                assert!(sol.status == PoseStatus::Ok && sol.cold_start, "{sol:?}");
                let mut from_truth = s.clone();
                from_truth.set_warm_start(t.map(|v| v as f32), q.map(|v| v as f32));
                let best = from_truth.solve(&spots);
                assert!(
                    (sol.position - best.position).norm() < 1e-3,
                    "{sol:?} {best:?}"
                );
                let (a, b) = (sol.mrp.map(|v| v as f64), best.mrp.map(|v| v as f64));
                assert!(angle_between(&a, &b) < 0.05, "{sol:?} {best:?}");
                if model == ModelKind::NearField {
                    assert!(
                        (sol.position.map(|v| v as f64) - t).norm() < 0.05,
                        "{sol:?}"
                    );
                    assert!(angle_between(&a, &q) < 1.0, "{sol:?}");
                }
            }
        }
    }
}

/// `attitude_xyz` turns about the board's x, y, z in that order: turned 90 deg about x then
/// 90 deg about z, the plate's normal (T's z) points along the board's x; a yaw alone is the
/// rotation about z.
#[test]
fn attitude_xyz_turns_about_the_board_axes_in_order() {
    let q = attitude_xyz([90.0, 0.0, 90.0]);
    let normal = mrp::dcm(&q).transpose() * Vector3::z();
    assert!((normal - Vector3::x()).norm() < 1e-12, "{normal:?}");
    // Turned about y then x instead, or z first: elsewhere.
    let q = attitude_xyz([0.0, 90.0, 0.0]);
    let normal = mrp::dcm(&q).transpose() * Vector3::z();
    assert!((normal - Vector3::x()).norm() < 1e-12, "{normal:?}");
    let yaw = attitude_xyz([0.0, 0.0, 150.0]);
    let z = mrp::from_axis_angle(&Vector3::z(), rad(150.0));
    assert!((yaw - z).norm() < 1e-12);
}

/// `mislabel` moves one ID onto another spot and removes that ID's own spot.
#[test]
fn mislabel_puts_an_id_on_another_spot() {
    let con = cta_constellation();
    let (t, q) = (Vector3::new(0.0, 0.0, 8.0), Vector3::zeros());
    let clean = simulate_spots(&physics(), &con, &t, &q, |_| 0.0);
    let mut spots = clean.clone();
    assert_eq!(mislabel(&mut spots, 1, 4), Some(clean[4].id));
    assert_eq!(spots.len(), clean.len() - 1);
    assert_eq!((spots[1].id, spots[1].x), (clean[4].id, clean[1].x));
    assert!(spots.iter().filter(|s| s.id == clean[4].id).count() == 1);
    assert_eq!(mislabel(&mut spots, 2, 2), None);
}

/// The cold start's compact DCM -> MRP is `mrp::from_dcm`, at every angle (half turns and
/// each branch of the largest diagonal among them).
#[test]
fn mrp_of_matches_from_dcm() {
    let mut u = uniform_from(3);
    for k in 0..400 {
        let axis = Vector3::new(u(), u(), u());
        let angle = match k % 4 {
            0 => 180.0,
            1 => 179.9 - 0.1 * u(),
            _ => 360.0 * u(),
        };
        let q = mrp::from_axis_angle(&axis, rad(angle));
        let c = mrp::dcm(&q);
        let (want, got) = (mrp::from_dcm(&c), super::super::cold::mrp_of(&c));
        assert!(
            (want - got).norm() < 1e-9 || angle_between(&want, &got) < 1e-6,
            "{angle}: {want:?} {got:?}"
        );
    }
}
