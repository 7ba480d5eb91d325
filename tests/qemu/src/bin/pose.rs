//! Instruction count of one warm-started 10-beacon pose solve on a Cortex-M3 (QEMU
//! lm3s6965evb), f32 soft-float as on the sensor board's STM32F103C8, and the f32 answer
//! for the host's f64 comparison (firmware-sensor/ci.sh).
//!
//! The scenario is [`cta_core::pose::benchmark_frames`]: frame 1 is solved from the cold
//! start (not measured), then each measured segment is one solve of frame 2 warm-started
//! from frame 1's solution, exactly as the board does from one NorthStar frame to the
//! next. The model is chosen at build time: `POSE_MODEL=pinhole` or `nearfield`
//! (default).
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use cta_core::pose::{
    benchmark_frames, cta_constellation, Calibration, ModelKind, PoseSolver, PoseStatus,
    SolverSettings,
};
use cta_qemu::{done, fail, mark};

/// Measured solves (each from the same warm start).
const RUNS: usize = 3;

#[entry]
fn main() -> ! {
    let model = match option_env!("POSE_MODEL") {
        Some("pinhole") => ModelKind::Pinhole,
        _ => ModelKind::NearField,
    };
    let (f1, f2, _, _) = benchmark_frames();
    let settings = SolverSettings {
        model,
        ..SolverSettings::default()
    };
    let Ok(mut solver) =
        PoseSolver::<f32>::new(&Calibration::table3(), &cta_constellation(), settings)
    else {
        fail("solver rejected the configuration")
    };
    let first = solver.solve(&f1);
    if first.status != PoseStatus::Ok {
        fail("cold-start solve of frame 1 failed");
    }
    let Some((t, q)) = solver.warm_start() else {
        fail("no warm start")
    };
    // Empty segments: the marker overhead run.sh subtracts.
    for _ in 0..4 {
        mark();
    }
    let mut sol = first;
    for _ in 0..RUNS {
        solver.set_warm_start(t, q);
        mark();
        sol = solver.solve(&f2);
    }
    if sol.status != PoseStatus::Ok {
        fail("warm solve of frame 2 failed");
    }
    hprintln!(
        "POSE f32 model={} beacons={} iterations={} cold_iterations={} t= {:.6} {:.6} {:.6} q= {:.8} {:.8} {:.8}",
        if model == ModelKind::Pinhole { "pinhole" } else { "nearfield" },
        sol.beacons,
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
