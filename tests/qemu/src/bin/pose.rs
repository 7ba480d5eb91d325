//! Instruction count of one warm-started 10-beacon pose solve on a Cortex-M3 (QEMU
//! lm3s6965evb), f32 soft-float as on the sensor board's STM32F103C8, and the f32 answer
//! for the host's f64 comparison (firmware-sensor/ci.sh).
//!
//! The scenario is [`cta_core::pose::benchmark_frames`]: frame 1 is solved from the cold
//! start (not measured), then each measured segment is one solve of frame 2 from the
//! solver's state after frame 1 (its solution as the warm start, its last linearisation
//! carried), exactly as the board does from one NorthStar frame to the next. The model is
//! chosen at build time: `POSE_MODEL=pinhole`, `nearfield` (default) or `nearfield-mag` (the
//! near-field model with the spot magnitudes: the calibration carries the simulated
//! NorthStar's magnitude law, [`cta_core::pose::Magnitude::simulated`] at 0.07 %, and the
//! frames' magnitudes, exact but for their rounding to counts, are fitted with the spots);
//! so is the constellation: `POSE_BEACONS=20` solves the 20-beacon
//! [`cta_core::pose::four_array_constellation`] instead of the 10-beacon
//! [`cta_core::pose::cta_constellation`] (same poses and noise). Every solve is the board's,
//! [`PoseSolver::solve_frame`] at the frames' sensitivity (4, the law's).
//!
//! `POSE_COLD=1` measures cold frames instead: each segment solves one of the three frames
//! of [`cta_core::pose::cold_frames_of`] (the target turned 90, 180 and -150 deg about the
//! line of sight and tilted 20 deg) from nothing, as the board's first frame or the first
//! after losing the target: the attitude-independent cold start and GLSDC from it. It
//! prints `COLD f32 ...` with the largest position and attitude differences from GLSDC
//! started at the true pose, and fails unless every frame is solved Ok at that minimum.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use cta_core::mrp;
use cta_core::pose::{
    benchmark_frames_of, cold_frames_of, cta_constellation, four_array_constellation, Calibration,
    Magnitude, ModelKind, PoseSolver, PoseStatus, SolverSettings,
};
use cta_qemu::{done, end, fail, mark, paint_stack, stack_used};

/// Measured solves (each from the same warm start).
const RUNS: usize = 3;
/// Stack region painted below the current stack pointer.
const PAINT: usize = 16 * 1024;
/// The NorthStar sensitivity the frames are reported at: the simulated magnitude law's.
const SENSITIVITY: u8 = 4;

#[entry]
fn main() -> ! {
    let (model, name) = match option_env!("POSE_MODEL") {
        Some("pinhole") => (ModelKind::Pinhole, "pinhole"),
        Some("nearfield-mag") => (ModelKind::NearField, "nearfield-mag"),
        _ => (ModelKind::NearField, "nearfield"),
    };
    let mut cal = Calibration::table3();
    if name == "nearfield-mag" {
        cal.magnitude = Some(Magnitude::simulated(0.07));
    }
    let con = match option_env!("POSE_BEACONS") {
        Some("20") => four_array_constellation(),
        _ => cta_constellation(),
    };
    let (mut f1, mut f2, _, _) = benchmark_frames_of(&con);
    // A diagnostic (firmware-sensor/README.md, "Budgets"): POSE_MAG_SCALE=K multiplies the
    // frames' magnitudes by K (saturated below 65535), which shrinks their rounding's share
    // of the magnitude noise; the simulated law is linear, so nothing else changes.
    if let Some(k) = option_env!("POSE_MAG_SCALE").and_then(|k| k.parse::<u32>().ok()) {
        for s in f1.iter_mut().chain(f2.iter_mut()) {
            s.magnitude = (u32::from(s.magnitude) * k).min(65534) as u16;
        }
    }
    let settings = SolverSettings {
        model,
        ..SolverSettings::default()
    };
    let Ok(mut solver) = PoseSolver::<f32>::new(&cal, &con, settings) else {
        fail("solver rejected the configuration")
    };
    if option_env!("POSE_COLD") == Some("1") {
        cold(solver, name, &con)
    }
    let (lo, sp) = paint_stack(PAINT);
    let first = solver.solve_frame(&f1, SENSITIVITY);
    if first.status != PoseStatus::Ok {
        fail("cold-start solve of frame 1 failed");
    }
    if solver.warm_start().is_none() {
        fail("no warm start")
    }
    // The state after frame 1 (warm start and carried linearisation), restored before each
    // measured solve (outside the segment).
    let after_f1 = solver.clone();
    // Empty segments: the marker overhead run.sh subtracts.
    for _ in 0..4 {
        mark();
    }
    let mut sol = first;
    for _ in 0..RUNS {
        solver = after_f1.clone();
        mark();
        sol = solver.solve_frame(&f2, SENSITIVITY);
    }
    // The last segment ends with the solve, not after the stack scan and the printing below.
    end();
    if sol.status != PoseStatus::Ok {
        fail("warm solve of frame 2 failed");
    }
    // Every beacon's magnitude fitted with the magnitude law, none without.
    let fitted = if cal.magnitude.is_some() {
        sol.beacons
    } else {
        0
    };
    if sol.magnitudes != fitted || first.magnitudes != fitted {
        fail("the magnitudes fitted are not every beacon's (with the law) or none (without)");
    }
    hprintln!(
        "STACK solve_peak_bytes={} (cold and warm solves, below the caller's frame)",
        stack_used(lo, sp)
    );
    hprintln!(
        "POSE f32 model={} beacons={} magnitudes={} iterations={} cold_iterations={} t= {:.6} {:.6} {:.6} q= {:.8} {:.8} {:.8}",
        name,
        sol.beacons,
        sol.magnitudes,
        sol.iterations,
        first.iterations,
        sol.position.x,
        sol.position.y,
        sol.position.z,
        sol.mrp.x,
        sol.mrp.y,
        sol.mrp.z
    );
    done("pose: ok")
}

/// The cold frames (see the module documentation): each solved by a fresh copy of the
/// configured `solver` (copied outside the segment).
fn cold(solver: PoseSolver<f32>, name: &str, con: &cta_core::pose::Constellation) -> ! {
    let frames = cold_frames_of(con);
    let (lo, sp) = paint_stack(PAINT);
    for _ in 0..4 {
        mark();
    }
    let mut sols = [None; 3];
    for (k, (spots, _, _)) in frames.iter().enumerate() {
        let mut s = solver.clone();
        mark();
        sols[k] = Some(s.solve_frame(spots, SENSITIVITY));
    }
    end();
    // Each answer against the model's own minimum at that frame: GLSDC started at the true
    // pose (the pinhole model's is biased in the near field, so the truth itself is not it).
    let (mut dt, mut dq, mut iters) = (0.0f32, 0.0f32, 0u8);
    for (sol, (spots, t, q)) in sols.iter().zip(&frames) {
        let Some(sol) = sol else {
            fail("a cold frame was not solved")
        };
        if sol.status != PoseStatus::Ok || !sol.cold_start {
            fail("a cold frame was not solved Ok from the cold start");
        }
        let mut s = solver.clone();
        s.set_warm_start(t.map(|v| v as f32), q.map(|v| v as f32));
        let best = s.solve_frame(spots, SENSITIVITY);
        if best.status != PoseStatus::Ok {
            fail("the solve from the true pose failed");
        }
        dt = dt.max((sol.position - best.position).norm());
        let c = mrp::dcm(&sol.mrp) * mrp::dcm(&best.mrp).transpose();
        let cos = ((c.trace() - 1.0) * 0.5).clamp(-1.0, 1.0);
        dq = dq.max(libm::acosf(cos).to_degrees());
        iters = iters.max(sol.iterations);
    }
    // The same minimum, to the f32 solve's tolerances; a wrong roll or the mirror tilt is
    // off by degrees.
    if !(dt < 1e-2 && dq < 0.1) {
        fail("a cold frame converged away from the model's minimum");
    }
    hprintln!(
        "STACK solve_peak_bytes={} (cold solves, below the caller's frame)",
        stack_used(lo, sp)
    );
    hprintln!(
        "COLD f32 model={} beacons={} frames=3 max_iterations={} max_dt_vs_true_start_in={:.5} max_dq_deg={:.4}",
        name,
        sols[0].map_or(0, |s| s.beacons),
        iters,
        dt,
        dq
    );
    done("pose: ok")
}
