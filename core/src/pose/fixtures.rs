//! Simulated spots and reference constellations: what a NorthStar would report for a
//! constellation at a pose (the eq 60-63 emulator), the CTA's built-in constellations, and the
//! frames of the on-chip benchmark (QEMU instruction count, f32-vs-f64 check).

use super::{v3, Beacon, Calibration, Constellation, Spot, MAX_BEACONS};
use crate::emulator::{Effects, Emulator, Head, Pose as HeadPose};
use crate::mrp;
use crate::real::rad;
use crate::Real;
use heapless::Vec;
use nalgebra::Vector3;

/// The simulated NorthStar's magnitude per unit of summed cell signal, counts per 1/in^2: a
/// beacon 1 in away on the boresight reads about 60000, at 10 in about 520, at 30 in about
/// 58 (the real detector's scale is unknown: see [`Magnitude`]).
///
/// [`Magnitude`]: super::Magnitude
pub const SIM_MAGNITUDE_SCALE: f64 = 15000.0;

/// Spots a NorthStar with the physics of `em` (the head on the board) would report for
/// the constellation at pose `(t, q)`: beacons whose both cell pairs see light, outputs
/// rounded and saturated to 16 bits, with `noise(k)` (counts) added to coordinate `k`
/// (0, 1 for the first spot, ...). The magnitude is the summed cell signal times the
/// beacon's brightness times [`SIM_MAGNITUDE_SCALE`] (a beacon 1 in away on boresight reads
/// about 60000), rounded and saturated to 16 bits, without noise (see
/// [`simulate_spots_with`]). Used by the simulated board, the accuracy table and the tests.
pub fn simulate_spots<T: Real>(
    em: &Emulator<T>,
    con: &Constellation,
    t: &Vector3<T>,
    q: &Vector3<T>,
    noise: impl FnMut(usize) -> T,
) -> Vec<Spot, MAX_BEACONS> {
    simulate_spots_with(em, con, t, q, noise, |_| T::zero())
}

/// [`simulate_spots`] with magnitude noise: spot `i`'s magnitude is multiplied by
/// `1 + mag_noise(i)` before it is rounded (a draw of its own, so the coordinates' noise is
/// as [`simulate_spots`] draws it).
pub fn simulate_spots_with<T: Real>(
    em: &Emulator<T>,
    con: &Constellation,
    t: &Vector3<T>,
    q: &Vector3<T>,
    noise: impl FnMut(usize) -> T,
    mag_noise: impl FnMut(usize) -> T,
) -> Vec<Spot, MAX_BEACONS> {
    simulate_spots_scaled(em, con, t, q, SIM_MAGNITUDE_SCALE, noise, mag_noise)
}

/// [`simulate_spots_with`] with the magnitude `scale` (counts per 1/in^2 of summed cell
/// signal) given: the simulated board's NorthStar passes the magnitude law's
/// ([`crate::magnitude_law::reading`] of a unit signal), which saturates nearer than this
/// module's fixture scale. The reading is rounded and saturated as the law says
/// ([`crate::magnitude_law::counts`]).
pub fn simulate_spots_scaled<T: Real>(
    em: &Emulator<T>,
    con: &Constellation,
    t: &Vector3<T>,
    q: &Vector3<T>,
    scale: f64,
    mut noise: impl FnMut(usize) -> T,
    mut mag_noise: impl FnMut(usize) -> T,
) -> Vec<Spot, MAX_BEACONS> {
    let ct = mrp::dcm(q).transpose();
    let em = em.with_boresight(&(ct * v3::<T>(&con.boresight).normalize()));
    let mut out = Vec::new();
    for b in &con.beacons {
        let rn = t + ct * v3::<T>(&b.r);
        let Some(y) = em.output(&rn) else { continue };
        let k = out.len() * 2;
        let x = y[0] + noise(k);
        let yy = y[1] + noise(k + 1);
        let m = em.magnitude(&rn)
            * T::lit(scale * b.brightness as f64)
            * (T::one() + mag_noise(out.len()));
        let mag = crate::magnitude_law::counts(m.to_f64());
        let _ = out.push(Spot {
            id: b.id,
            x: crate::emulator::saturate_i16(x),
            y: crate::emulator::saturate_i16(yy),
            magnitude: mag,
        });
    }
    out
}

/// A flat constellation on the plate `z = 0` of T, LEDs along `-z` (the plate faces the
/// board): beacon `i` (channel `i`) at `(r[i][0], r[i][1], 0)` in; at most [`MAX_BEACONS`]
/// (more are left out).
pub fn flat_constellation(r: &[[f32; 2]]) -> Constellation {
    let mut beacons = Vec::new();
    for (i, r) in r.iter().take(MAX_BEACONS).enumerate() {
        // Cannot fail: at most MAX_BEACONS are taken.
        let _ = beacons.push(Beacon {
            id: i as u8,
            r: [r[0], r[1], 0.0],
            brightness: 1.0,
        });
    }
    Constellation {
        beacons,
        boresight: [0.0, 0.0, -1.0],
    }
}

/// A 10-beacon constellation on the CTA's 1 in grid (channels 0..=9): five beacons within
/// about 2 in of the centre (seen down to 2 in separation) and five out to 4.5 in (lever
/// arm at range). LEDs along `-z` of T (the plate faces the board).
pub fn cta_constellation() -> Constellation {
    const R: [[f32; 2]; 10] = [
        [-1.5, -0.5],
        [1.5, 0.5],
        [-0.5, 1.5],
        [0.5, -1.5],
        [0.5, 0.5],
        [-3.5, -2.5],
        [3.5, 2.5],
        [-2.5, 3.5],
        [2.5, -3.5],
        [4.5, -0.5],
    ];
    flat_constellation(&R)
}

/// All 20 NorthStar channel IDs spread over the CTA plate with four arrays in its quadrants
/// (LEDs at +/-1.5 .. +/-10.5 in; REFERENCE.md section 4): the first five are inner beacons
/// (seen from 2 in), the next five near the plate's edge (attitude at 8-10 in), then five
/// more inner and five more outer. Its first ten alone are the host's `four-10`. Channels 2
/// and 19 share 4050 Hz in the NorthStar table, so a detector cannot tell those two apart: the
/// host's built-in `four-19` (what `cta sensor floor` and `cta sensor accuracy` compare with
/// [`cta_constellation`]) leaves channel 19 out. This 20-beacon layout is the chip's
/// capacity, on which the QEMU harness counts a 20-beacon solve.
pub fn four_array_constellation() -> Constellation {
    const R: [[f32; 2]; 20] = [
        [-1.5, -2.5],
        [2.5, -1.5],
        [1.5, 2.5],
        [-2.5, 1.5],
        [1.5, 1.5],
        [-10.5, -3.5],
        [10.5, 3.5],
        [-3.5, 10.5],
        [3.5, -10.5],
        [8.5, -8.5],
        [-1.5, -1.5],
        [3.5, 2.5],
        [-3.5, -1.5],
        [2.5, -3.5],
        [-2.5, 3.5],
        [-8.5, 8.5],
        [10.5, 10.5],
        [-10.5, -10.5],
        [6.5, -5.5],
        [-6.5, 5.5],
    ];
    flat_constellation(&R)
}

/// The benchmark of the on-chip solve (QEMU instruction count and the f32-vs-f64 check):
/// the [`cta_constellation`] seen through the eq 63 physics by the Table 3 head, the target
/// at `t = (0.3, -0.2, 8.0)` in, rotated 3 deg about `(0.3, -0.5, 1.0)`; frame 2 after a
/// step of `(0.02, -0.01, 0.05)` in and 0.1 deg (a docking control loop at 50 Hz). Both
/// frames carry deterministic pseudo-random noise of 0.1 % of beta (uniform, same
/// variance as the Gaussian) and are rounded to counts, so every machine produces the same
/// integer spots. Returns `(frame1, frame2, true t2, true q2)`.
pub fn benchmark_frames() -> BenchmarkFrames {
    benchmark_frames_of(&cta_constellation())
}

/// Frame 1, frame 2, and the true position and MRP of frame 2.
pub type BenchmarkFrames = (
    Vec<Spot, MAX_BEACONS>,
    Vec<Spot, MAX_BEACONS>,
    Vector3<f64>,
    Vector3<f64>,
);

/// The eq 63 emulator of the Table 3 head, the benchmarks' sensor.
fn table3_emulator() -> Emulator<f64> {
    let cal = Calibration::table3();
    Emulator::new(
        Head::northstar(),
        HeadPose {
            d: v3(&cal.d),
            p: v3(&cal.p),
        },
        Effects::default(),
    )
}

/// The benchmarks' spot noise: 0.1 % of beta, uniform on [-sqrt(3), sqrt(3)] sigma (unit
/// variance times sigma), from a xorshift generator started at `seed`, so that the host and
/// the target draw the same frames.
fn benchmark_noise(mut seed: u32) -> impl FnMut(usize) -> f64 {
    let sigma = 0.001 * crate::emulator::BETA;
    move |_| {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        ((seed as f64) / 4294967296.0 - 0.5) * 2.0 * 1.7320508075688772 * sigma
    }
}

/// [`benchmark_frames`] for another constellation `con` (same poses, noise and rounding).
pub fn benchmark_frames_of(con: &Constellation) -> BenchmarkFrames {
    let em = table3_emulator();
    let axis = Vector3::new(0.3, -0.5, 1.0);
    let t1 = Vector3::new(0.3, -0.2, 8.0);
    let q1 = mrp::from_axis_angle(&axis, rad(3.0));
    let t2 = t1 + Vector3::new(0.02, -0.01, 0.05);
    let q2 = mrp::from_axis_angle(&axis, rad(3.1));
    let mut noise = benchmark_noise(0x2545_f491);
    let f1 = simulate_spots(&em, con, &t1, &q1, &mut noise);
    let f2 = simulate_spots(&em, con, &t2, &q2, &mut noise);
    (f1, f2, t2, q2)
}

/// The cold-start benchmark: three frames of `con` (the Table 3 head, eq 63 physics), each
/// to be solved from nothing, the target turned about the line of sight by 90, 180 and -150
/// deg, tilted 20 deg about `(1, -0.6, 0)` and offset, at 8 in, with the noise and rounding of
/// [`benchmark_frames_of`]. Returns each frame with its true position and MRP.
pub fn cold_frames_of(
    con: &Constellation,
) -> [(Vec<Spot, MAX_BEACONS>, Vector3<f64>, Vector3<f64>); 3] {
    let em = table3_emulator();
    let mut noise = benchmark_noise(0x9e37_79b9);
    let tilt = mrp::from_axis_angle(&Vector3::new(1.0, -0.6, 0.0), rad(20.0));
    [90.0, 180.0, -150.0].map(|roll| {
        let q = mrp::compose(&tilt, &mrp::from_axis_angle(&Vector3::z(), rad(roll)));
        let t = Vector3::new(0.8, -0.5, 8.0);
        (simulate_spots(&em, con, &t, &q, &mut noise), t, q)
    })
}

/// A wrong ID in a frame: spot `j` reported under spot `k`'s ID, and spot `k` removed (the
/// NorthStar reports one spot per channel), so that beacon `k`'s ID marks beacon `j`'s
/// position (a reflection or an ID mix-up). Returns the wrong ID; `None` (nothing changed)
/// unless `j` and `k` are two spots of the frame.
pub fn mislabel(spots: &mut Vec<Spot, MAX_BEACONS>, j: usize, k: usize) -> Option<u8> {
    if j == k || j >= spots.len() || k >= spots.len() {
        return None;
    }
    let id = spots[k].id;
    spots[j].id = id;
    spots.remove(k);
    Some(id)
}

/// The MRP of a target turned by `deg[0]`, `deg[1]`, `deg[2]` degrees about the board
/// frame's x, y and z axes, in that order (`cta sensor sim --attitude-deg`): the DCM
/// `C(x) C(y) C(z)` of the three single-axis rotations (N -> T), the last turn taken first
/// in the target's frame.
pub fn attitude_xyz<T: Real>(deg: [T; 3]) -> Vector3<T> {
    let q = |axis: Vector3<T>, a: T| mrp::from_axis_angle(&axis, rad(a));
    mrp::compose(
        &q(Vector3::x(), deg[0]),
        &mrp::compose(&q(Vector3::y(), deg[1]), &q(Vector3::z(), deg[2])),
    )
}
