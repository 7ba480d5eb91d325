//! The host's f64 answer to the QEMU pose benchmark (`tests/qemu/src/bin/pose.rs`), printed
//! in the same format so that `firmware-sensor/ci.sh` can compare the on-target f32 answer
//! with it: `cargo run -p cta-firmware-sensor --example pose_reference --
//! [pinhole|nearfield|nearfield-mag] [20]` (`nearfield-mag`: the near-field model with the
//! spot magnitudes, the calibration carrying the simulated NorthStar's magnitude law at
//! 0.07 %, as `POSE_MODEL=nearfield-mag` on the target; `20`: the 20-beacon four-array
//! constellation, as `POSE_BEACONS=20`).

use cta_core::pose::{
    benchmark_frames_of, cta_constellation, four_array_constellation, Calibration, Magnitude,
    ModelKind, PoseSolver, PoseStatus, SolverSettings,
};

/// The NorthStar sensitivity of the frames (the simulated magnitude law's), as on the target.
const SENSITIVITY: u8 = 4;

fn main() {
    let (model, name) = match std::env::args().nth(1).as_deref() {
        Some("pinhole") => (ModelKind::Pinhole, "pinhole"),
        Some("nearfield-mag") => (ModelKind::NearField, "nearfield-mag"),
        Some("nearfield") | None => (ModelKind::NearField, "nearfield"),
        Some(other) => {
            eprintln!("unknown model {other}: pinhole, nearfield or nearfield-mag");
            std::process::exit(2);
        }
    };
    let mut cal = Calibration::table3();
    if name == "nearfield-mag" {
        cal.magnitude = Some(Magnitude::simulated(0.07));
    }
    let con = match std::env::args().nth(2).as_deref() {
        Some("20") => four_array_constellation(),
        _ => cta_constellation(),
    };
    let (f1, f2, t2, q2) = benchmark_frames_of(&con);
    let settings = SolverSettings {
        model,
        ..SolverSettings::default()
    };
    let mut solver = PoseSolver::<f64>::new(&cal, &con, settings).expect("valid configuration");
    let first = solver.solve_frame(&f1, SENSITIVITY);
    let sol = solver.solve_frame(&f2, SENSITIVITY);
    if first.status != PoseStatus::Ok || sol.status != PoseStatus::Ok {
        eprintln!("reference solve failed: {first:?} {sol:?}");
        std::process::exit(1);
    }
    println!(
        "POSE f64 model={} beacons={} magnitudes={} iterations={} cold_iterations={} t= {:.6} {:.6} {:.6} q= {:.8} {:.8} {:.8}",
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
    println!(
        "TRUTH t= {:.6} {:.6} {:.6} q= {:.8} {:.8} {:.8}",
        t2.x, t2.y, t2.z, q2.x, q2.y, q2.z
    );
}
