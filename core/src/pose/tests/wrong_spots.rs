//! Wrong spots and bad frames: a spot under another beacon's ID is found by its residual
//! and left out (or the frame is not Ok), an ID reported twice leaves its beacon out, and
//! frames of nothing usable give a status, never a NaN pose.

use super::cold::{angle_between, attitude};
use super::*;
use super::{truth_emulator as physics, uniform_from};

/// `spots` with spot `j`'s ID replaced by spot `k`'s, and spot `k` removed (the detector
/// reports one spot per channel): beacon `k`'s ID now marks beacon `j`'s position. Returns
/// the wrong ID.
fn mislabel(spots: &mut std::vec::Vec<Spot>, j: usize, k: usize) -> u8 {
    let id = spots[k].id;
    spots[j].id = id;
    spots.remove(k);
    id
}

/// A pose error in sigmas: the largest of the position's and the attitude's, each the
/// error's norm over the 1-sigma's norm.
fn sigmas(sol: &PoseSolution<f64>, t: &Vector3<f64>, q: &Vector3<f64>) -> f64 {
    let dt = (sol.position - t).norm() / sol.sigma_position.norm();
    let dq = angle_between(&sol.mrp, q) / sol.sigma_attitude_deg.norm();
    dt.max(dq)
}

/// One wrong ID in every frame over tilted, rolled and offset poses at 2-30 in, both
/// models: no frame gives an Ok pose more than 5 sigma from the pose the clean frame gives
/// (the truth for the near-field model), and the wrong ID is the beacon reported dropped in
/// almost every frame.
#[test]
fn a_wrong_id_is_left_out_never_pulls_an_ok_pose() {
    let con = cta_constellation();
    let em = physics();
    for model in [ModelKind::NearField, ModelKind::Pinhole] {
        let settings = SolverSettings {
            model,
            ..Default::default()
        };
        let (mut frames, mut flagged, mut right, mut not_ok, mut bad) = (0, 0, 0, 0, 0);
        let mut u = uniform_from(77);
        for f in 0..240 {
            let range = [2.5, 4.0, 8.0, 12.0, 20.0, 30.0][f % 6];
            let t = Vector3::new(0.1 * range * u(), 0.1 * range * u(), range);
            let q = attitude(360.0 * u(), 30.0 * u(), Vector3::new(u(), u(), 0.0));
            let clean = simulate_spots(&em, &con, &t, &q, |_| u() * 3.46 * 32.768).to_vec();
            if clean.len() < 6 {
                continue;
            }
            let mut s = PoseSolver::<f64>::new(&Calibration::table3(), &con, settings).unwrap();
            let reference = s.clone().solve(&clean);
            if reference.status != PoseStatus::Ok {
                continue;
            }
            let (rt, rq) = match model {
                ModelKind::NearField => (t, q),
                ModelKind::Pinhole => (reference.position, reference.mrp),
            };
            let mut spots = clean.clone();
            let n = spots.len();
            let j = (f * 7) % n;
            let k = (j + 1 + (f * 3) % (n - 1)) % n;
            let wrong = mislabel(&mut spots, j, k);
            let sol = s.solve(&spots);
            frames += 1;
            assert!(sol
                .position
                .iter()
                .chain(sol.mrp.iter())
                .all(|v| v.is_finite()));
            if sol.dropped.is_some() {
                flagged += 1;
                right += usize::from(sol.dropped == Some(wrong));
            }
            if sol.status != PoseStatus::Ok {
                not_ok += 1;
            } else if sigmas(&sol, &rt, &rq) > 5.0 {
                bad += 1;
                std::println!("{model:?} frame {f} at {range} in: {sol:?} (wrong ID {wrong})");
            }
        }
        std::println!(
            "{model:?}: {frames} frames with a wrong ID: {flagged} dropped a beacon ({right} the \
             wrong ID), {not_ok} not Ok, {bad} Ok beyond 5 sigma"
        );
        assert_eq!(bad, 0, "{model:?}");
        assert!(frames >= 200, "{frames}");
        assert!(right * 10 >= frames * 9, "{model:?}: {right} of {frames}");
    }
}

/// A clean frame is screened only when it misfits: the near-field model's never is, and drops
/// nothing.
#[test]
fn a_clean_frame_drops_nothing() {
    let con = cta_constellation();
    let mut u = uniform_from(5);
    for range in [2.5, 8.0, 30.0] {
        let t = Vector3::new(0.3, -0.2, range);
        let q = attitude(120.0, 15.0, Vector3::x());
        let spots = simulate_spots(&physics(), &con, &t, &q, |_| u() * 3.46 * 32.768);
        let sol = PoseSolver::<f32>::new(&Calibration::table3(), &con, SolverSettings::default())
            .unwrap()
            .solve(&spots);
        assert_eq!(sol.status, PoseStatus::Ok, "{sol:?}");
        assert_eq!(sol.dropped, None, "{sol:?}");
        assert_eq!(usize::from(sol.beacons), spots.len());
    }
}

/// An ID reported twice (a reflection of one beacon beside it): that beacon is left out and
/// named; the rest give the pose. IDs outside the constellation are ignored; spots all at
/// the rails, or only unknown IDs, are too few beacons, with a finite pose.
#[test]
fn bad_frames_give_a_status_not_a_nan() {
    let con = cta_constellation();
    let (t, q) = (
        Vector3::new(0.3, -0.2, 8.0),
        attitude(170.0, 10.0, Vector3::x()),
    );
    let clean = simulate_spots(&physics(), &con, &t, &q, |_| 0.0).to_vec();
    let solver =
        PoseSolver::<f32>::new(&Calibration::table3(), &con, SolverSettings::default()).unwrap();
    let mut twice = clean.clone();
    let mut echo = twice[2];
    echo.x = echo.x.saturating_add(4000);
    twice.push(echo);
    let sol = solver.clone().solve(&twice);
    assert_eq!(sol.status, PoseStatus::Ok, "{sol:?}");
    assert_eq!(sol.dropped, Some(clean[2].id), "{sol:?}");
    assert_eq!(usize::from(sol.beacons), clean.len() - 1);
    assert!(
        (sol.position.map(|v| v as f64) - t).norm() < 0.01,
        "{sol:?}"
    );
    // Unknown IDs (beyond the constellation's ten, and past the NorthStar's 19) are ignored.
    let mut unknown = clean.clone();
    unknown.extend(clean.iter().map(|s| Spot {
        id: s.id + 10,
        ..*s
    }));
    unknown.push(Spot {
        id: 200,
        ..clean[0]
    });
    let sol = solver.clone().solve(&unknown);
    assert_eq!(sol.status, PoseStatus::Ok, "{sol:?}");
    assert_eq!(usize::from(sol.beacons), clean.len());
    let only_unknown: std::vec::Vec<Spot> = clean
        .iter()
        .map(|s| Spot {
            id: s.id + 10,
            ..*s
        })
        .collect();
    let railed: std::vec::Vec<Spot> = clean
        .iter()
        .map(|s| Spot {
            x: i16::MAX,
            y: i16::MIN,
            ..*s
        })
        .collect();
    let all_twice: std::vec::Vec<Spot> = clean.iter().chain(clean.iter()).copied().collect();
    for (name, frame) in [
        ("unknown IDs", &only_unknown),
        ("rails", &railed),
        ("all twice", &all_twice),
    ] {
        let sol = solver.clone().solve(frame);
        assert_eq!(sol.status, PoseStatus::TooFewBeacons, "{name}: {sol:?}");
        assert!(
            sol.position
                .iter()
                .chain(sol.mrp.iter())
                .all(|v| v.is_finite()),
            "{name}: {sol:?}"
        );
    }
}
