//! REFERENCE.md section 3, Ch V Table 3: eq 65 fitted by GLSDC to the eq 63 emulator, two
//! separations at once, W = I, noise-free.

use cta_core::collinearity::{Fit, Obs, Params, ParamsExt, NAMES};
use cta_core::emulator::{grid_position, Effects, Emulator, Head, Pose};
use cta_core::glsdc::{self, Settings};
use cta_core::pattern::Pattern;
use nalgebra::Vector3;

fn fit_pair(seps: [f64; 2], pattern: Pattern<f64>, clip: bool) -> (Params<f64>, f64) {
    fit_pair_head(Head::northstar(), seps, pattern, clip)
}

fn fit_pair_head(
    head: Head<f64>,
    seps: [f64; 2],
    pattern: Pattern<f64>,
    clip: bool,
) -> (Params<f64>, f64) {
    let pose = Pose::table3();
    let effects = Effects {
        pattern,
        ..Effects::default()
    };
    let em = Emulator::new(head, pose, effects);
    let mut obs = Vec::new();
    for sep in seps {
        for i in 0..100 {
            let r = grid_position(10, 1.0, sep, i);
            let mut y = em.output(&r).unwrap();
            if clip {
                y = y.map(|v| v.clamp(-32768.0, 32768.0));
            }
            obs.push(Obs { r, y, w: [1.0; 2] });
        }
    }
    let x0 = Params::from_pose(
        &Pose {
            d: Vector3::zeros(),
            p: Vector3::zeros(),
        },
        head.h(),
    );
    let s = glsdc::solve(&Fit { obs: &obs }, x0, &Settings::default()).expect("fit");
    (s.x, s.rms)
}

fn check(name: &str, x: &Params<f64>, rms: f64, want: [f64; 8]) {
    let tol = [0.002, 0.002, 0.03];
    for k in 0..3 {
        assert!(
            (x[k] - want[k]).abs() <= tol[k],
            "{name} {} = {} want {}",
            NAMES[k],
            x[k],
            want[k]
        );
    }
    for k in 3..6 {
        assert!(
            (x[k] - want[k]).abs() <= 0.02 * want[k].abs(),
            "{name} {} = {} want {}",
            NAMES[k],
            x[k],
            want[k]
        );
    }
    assert!(
        (x[6] - want[6]).abs() <= 0.003 * want[6],
        "{name} H = {} want {}",
        x[6],
        want[6]
    );
    assert!(
        (rms - want[7]).abs() <= 0.2 * want[7] + 0.05,
        "{name} rms = {rms} want {}",
        want[7]
    );
}

#[test]
fn table3_default_conventions() {
    let lam = Pattern::vsml3710();
    let (x, rms) = fit_pair([20.0, 25.0], lam, false);
    eprintln!("20,25: {x:?} rms {rms}");
    check(
        "(20,25)",
        &x,
        rms,
        [
            0.60777, 0.09704, 1.0630, 0.00100, 0.00196, 0.00100, 19077.0, 3.6,
        ],
    );
    let (x, rms) = fit_pair([25.0, 30.0], lam, false);
    eprintln!("25,30: {x:?} rms {rms}");
    check(
        "(25,30)",
        &x,
        rms,
        [
            0.60738, 0.09674, 1.1378, 0.00100, 0.00198, 0.00100, 19016.0, 1.6,
        ],
    );
    let (x, rms) = fit_pair([95.0, 100.0], lam, false);
    eprintln!("95,100: {x:?} rms {rms}");
    check(
        "(95,100)",
        &x,
        rms,
        [
            0.60783, 0.09612, 1.3285, 0.00100, 0.00200, 0.00100, 18924.0, 0.01,
        ],
    );
}

#[test]
fn table3_near_pair_fails_clearly() {
    let (x, rms) = fit_pair([3.0, 5.0], Pattern::vsml3710(), true);
    eprintln!("3,5: {x:?} rms {rms}");
    // REFERENCE: 0.690 0.108 -0.22 0.00141 -0.00365 0.00099 22579, rms 868; H off > 10 %.
    assert!((x[6] - 18918.6).abs() > 0.10 * 18918.6, "H = {}", x[6]);
    assert!((x[6] - 22579.0).abs() < 0.01 * 22579.0, "H = {}", x[6]);
    assert!(
        (x[0] - 0.690).abs() < 0.005 && (x[2] + 0.22).abs() < 0.03,
        "{x:?}"
    );
    assert!((rms - 868.0).abs() < 0.05 * 868.0, "rms {rms}");
}

/// Compare the first `want.len()` parameters with REFERENCE tolerances (d1, d2 0.002 in,
/// d3 0.03 in, p 2 %, H 0.3 %).
fn check_params(name: &str, x: &Params<f64>, want: &[f64]) {
    for (k, w) in want.iter().enumerate() {
        let tol = match k {
            0 | 1 => 0.002,
            2 => 0.03,
            6 => 0.003 * w,
            _ => 0.02 * w,
        };
        assert!(
            (x[k] - w).abs() <= tol,
            "{name} {} = {} want {w}",
            NAMES[k],
            x[k]
        );
    }
}

#[test]
fn table3_printed_quartic() {
    let q = Pattern::Quartic;
    let (x, _) = fit_pair([20.0, 25.0], q, false);
    check_params(
        "quartic (20,25)",
        &x,
        &[0.60104, 0.09611, 1.5511, 0.00100, 0.00212, 0.00100, 18698.0],
    );
    let (x, _) = fit_pair([25.0, 30.0], q, false);
    check_params(
        "quartic (25,30)",
        &x,
        &[0.60499, 0.09637, 1.4148, 0.00100, 0.00204, 0.00100, 18809.0],
    );
    // (95,100): REFERENCE gives d and H (the p are elided there).
    let (x, _) = fit_pair([95.0, 100.0], q, false);
    check_params("quartic (95,100)", &x, &[0.60978, 0.09634, 1.0192]);
    assert!(
        (x[6] - 18991.0).abs() <= 0.003 * 18991.0,
        "quartic (95,100) H = {}",
        x[6]
    );
}

/// README, inconsistency 2 (REFERENCE.md 2.2): the thesis's negative d3 (a virtual eye
/// below the board) needs the mirror-image cell pairing. Mirroring the pairing is `s -> -s`:
/// cell 1, whose face tilts toward +x, then sits at -x (concave). With it every near-field
/// effect pulls the beacon toward the boresight instead of pushing it away, and the fitted
/// eye point of the (25,30) pair moves below the board, where with the printed (convex)
/// pairing it sits above it (d3 = +1.1378, `table3_default_conventions`).
#[test]
fn table3_mirror_pairing_puts_the_eye_below_the_board() {
    let mirror = Head {
        s: -0.175,
        ..Head::northstar()
    };
    let (x, rms) = fit_pair_head(mirror, [25.0, 30.0], Pattern::vsml3710(), false);
    eprintln!("mirror 25,30: {x:?} rms {rms}");
    // Below the board by a shift of the size the convex pairing has above it (1.08 in from
    // the true 0.062): the thesis's -0.79 has this sign; CTA measures -1.228 (a shift of
    // 1.29 in).
    assert!(x[2] < -0.5, "mirror pairing d3 = {} (want < 0)", x[2]);
    let shift = (x[2] - 0.062).abs();
    assert!(
        shift > 0.5 * (1.1378 - 0.062) && shift < 2.0 * (1.1378 - 0.062),
        "mirror pairing d3 = {}: shift {shift}",
        x[2]
    );
    // The rest stays near the truth (d1, d2 = 0.6, 0.1 in: CTA measures 0.591, 0.104; p to
    // REFERENCE's 2 %; H to 0.3 %: 18893): only d3 flips.
    assert!(
        (x[0] - 0.6).abs() < 0.02 && (x[1] - 0.1).abs() < 0.02,
        "{x:?}"
    );
    for (k, p) in [(3, 0.001), (4, 0.002), (5, 0.001)] {
        assert!(
            (x[k] - p).abs() <= 0.02 * p,
            "mirror {} = {}",
            NAMES[k],
            x[k]
        );
    }
    assert!(
        (x[6] - 18918.6).abs() <= 0.003 * 18918.6,
        "mirror H = {}",
        x[6]
    );
}
