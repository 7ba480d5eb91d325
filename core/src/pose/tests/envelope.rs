//! Acquisition over a docking envelope: every frame solved from the cold start.

use super::cold::{angle_between, attitude};
use super::*;
use super::{truth_emulator as physics, uniform_from};

/// Cold-start acquisition over the envelope at each range: any roll, tilts to 30 deg,
/// lateral offsets to a quarter of the range; frames with 4 or more whole spots. Returns
/// (frames, converged within 5 sigma of the truth or, for the pinhole, of its solve from the
/// truth) per range.
pub(super) fn acquisition(
    model: ModelKind,
    frames: usize,
    seed: u32,
) -> std::vec::Vec<(f64, usize, usize)> {
    let con = cta_constellation();
    let em = physics();
    let settings = SolverSettings {
        model,
        ..Default::default()
    };
    let base = PoseSolver::<f32>::new(&Calibration::table3(), &con, settings).unwrap();
    let mut u = uniform_from(seed);
    let mut out = std::vec::Vec::new();
    for range in [2.0, 4.0, 8.0, 15.0, 30.0] {
        let (mut n, mut ok) = (0, 0);
        while n < frames {
            let t = Vector3::new(0.5 * range * u(), 0.5 * range * u(), range);
            let q = attitude(360.0 * u(), 60.0 * u(), Vector3::new(u(), u(), 0.0));
            let spots = simulate_spots(&em, &con, &t, &q, |_| u() * 3.46 * 32.768);
            let obs = base.match_spots(&spots);
            if obs.iter().filter(|o| o.rows() == 2).count() < 4 {
                continue;
            }
            n += 1;
            let sol = base.clone().solve(&spots);
            let mut from_truth = base.clone();
            from_truth.set_warm_start(t.map(|v| v as f32), q.map(|v| v as f32));
            let best = from_truth.solve(&spots);
            if sol.status != PoseStatus::Ok || best.status != PoseStatus::Ok {
                continue;
            }
            let p = sol.position.map(|v| v as f64);
            let m = sol.mrp.map(|v| v as f64);
            let bp = best.position.map(|v| v as f64);
            let bm = best.mrp.map(|v| v as f64);
            let st = best.sigma_position.map(|v| v as f64).norm();
            let sq = best.sigma_attitude_deg.map(|v| v as f64).norm();
            if (p - bp).norm() <= 5.0 * st && angle_between(&m, &bm) <= 5.0 * sq {
                ok += 1;
            }
        }
        out.push((range, n, ok));
    }
    out
}

#[test]
#[ignore]
fn envelope_acquisition_figures() {
    for model in [ModelKind::NearField, ModelKind::Pinhole] {
        for (range, n, ok) in acquisition(model, 1000, 99) {
            std::println!("{model:?} {range} in: {ok} of {n}");
        }
    }
}
