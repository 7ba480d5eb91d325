//! The host's f64 answer to the QEMU pose benchmark (`tests/qemu/src/bin/pose.rs`), printed
//! in the same format so that `firmware-sensor/ci.sh` can compare the on-target f32 answer
//! with it: `cargo run -p cta-firmware-sensor --example pose_reference -- [pinhole|nearfield]
//! [20]` (`20`: the 20-beacon four-array constellation, as `POSE_BEACONS=20` on the target).

use cta_core::pose::{
    benchmark_frames_of, cta_constellation, four_array_constellation, Calibration, ModelKind,
    PoseSolver, PoseStatus, SolverSettings,
};

fn main() {
    let model = match std::env::args().nth(1).as_deref() {
        Some("pinhole") => ModelKind::Pinhole,
        _ => ModelKind::NearField,
    };
    let con = match std::env::args().nth(2).as_deref() {
        Some("20") => four_array_constellation(),
        _ => cta_constellation(),
    };
    let (f1, f2, t2, q2) = benchmark_frames_of(&con);
    let settings = SolverSettings {
        model,
        ..SolverSettings::default()
    };
    let mut solver = PoseSolver::<f64>::new(&Calibration::table3(), &con, settings)
        .expect("valid configuration");
    let first = solver.solve(&f1);
    let sol = solver.solve(&f2);
    if first.status != PoseStatus::Ok || sol.status != PoseStatus::Ok {
        eprintln!("reference solve failed: {first:?} {sol:?}");
        std::process::exit(1);
    }
    println!(
        "POSE f64 model={} beacons={} iterations={} cold_iterations={} t= {:.6} {:.6} {:.6} q= {:.8} {:.8} {:.8}",
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
    println!(
        "TRUTH t= {:.6} {:.6} {:.6} q= {:.8} {:.8} {:.8}",
        t2.x, t2.y, t2.z, q2.x, q2.y, q2.z
    );
}
