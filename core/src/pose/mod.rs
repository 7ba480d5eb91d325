//! On-chip 6-dof pose: the relative position and attitude of a beacon constellation (the
//! target) from the NorthStar's spot reports, by GLSDC (thesis eqs 56-59) over the position
//! and the MRP attitude (eqs 54/55), with either the pinhole model (eq 53/65) or the
//! near-field model (the eq 60-63 emulator). The thesis leaves this as future work (Ch VI,
//! "a real-time 6-dof solution (using a GLSDC ...) can be programmed onto the NorthStar
//! sensor board microprocessor"); VISNAV showed the approach for LED beacons.
//!
//! # Frames and unknowns
//!
//! - T: the target frame, in which the constellation's beacon positions `r_T` are given
//!   (inches), each beacon with its NorthStar frequency channel (the spot ID).
//! - N: the sensor-board frame; O: the head frame. The *calibration* gives the head on the
//!   board: `d`, `p` (MRP of `C`, N -> O) and `H` (eq 65), for the near-field model the
//!   head geometry (face angle `a`, cell offset `s`, scale `beta`) and the beacon pattern,
//!   and optionally the pinhole model's own `d, p` ([`PinholeHead`]: a 7-parameter eq 65
//!   fit puts its eye point about 1 in above the head the near-field fit finds).
//! - Unknowns `x = [t, q]`: `t` = position of the T origin in N (inches), `q` = MRP of the
//!   DCM `C(q)` mapping N components to T components. A beacon is at
//!   `r_N = t + C(q)^T r_T`, and the LEDs' boresight (in T) turns with the target:
//!   `b_N = C(q)^T b_T`. On the CTA the plate faces the board: `t = (0, 0, separation)`,
//!   `q = 0`, `b_T = -z`.
//!
//! # Models
//!
//! - [`ModelKind::Pinhole`]: eq 65 through [`crate::collinearity::Linearisation`] with the
//!   calibration's `H` and its pinhole head's `d, p` ([`Calibration::pinhole`]; the
//!   calibration's `d, p` when it has none) (analytic Jacobian: `dy/dt = -dy/dd`, and
//!   `dy/dq_i = dy/dr . (dC/dq_i)^T r_T`, evaluated as `dy/dq = K ((C^T r_T) x dy/dr)`
//!   with [`mrp::gradient_map`]).
//! - [`ModelKind::NearField`]: the eq 60-63 emulator ([`Emulator`]) with the calibration's
//!   near-field parameters; analytic Jacobian by the chain rule through
//!   [`Emulator::output_gradient`] (beacon position and LED boresight) and the same `K`.
//!
//! # Solve
//!
//! Spots are matched to beacons by ID. A coordinate at the 16-bit rails (a cell in the dark:
//! the eq 63 ratio at +/-beta, or saturated), or within [`RAIL_SIGMAS`] noise sigmas of them
//! (clipped: the noise kept it a few counts inside), carries no position information and is
//! not used; the spot's other coordinate still is (near the edge of the field of view, at 2 in,
//! that keeps about four of the CTA constellation's ten beacons). With fewer than
//! [`MIN_BEACONS`] matched beacons, or fewer usable coordinates than [`MIN_BEACONS`] whole
//! spots give, the status is [`PoseStatus::TooFewBeacons`] (and the warm start is forgotten:
//! the target was lost). Otherwise GLSDC starts from the previous good solution (warm start)
//! or, without one, from the *cold start*, which assumes no attitude: each whole spot gives a
//! pinhole line of sight `(X/H, Y/H, 1)` in the eye frame (eq 65; for the pinhole model, its
//! own eye's `d` and `C`), the plate's beacons (coplanar, `z` constant in T) map to those by a
//! planar homography, solved by a direct linear transform (8 unknowns, an equation per used
//! coordinate), whose columns give the plate's axes and centroid, hence `t` and `q` at any roll
//! about the line of sight, tilt or offset, which starts GLSDC. A spot with one coordinate at
//! the rails gives one equation; fewer than eight in all give no cold start (reported
//! diverged). A warm-started solve that
//! diverges (the target turned or moved too far since the last frame) is done again from the
//! cold start in the same frame.
//!
//! Every residual has the same weight (unit: one multiplication less per Jacobian element
//! on the chip); the stopping tolerances are in units of `noise^2` (noise from the
//! calibration), so that `sum r^2 / noise^2` is chi-square; the covariance is scaled by the
//! residual variance, so model misfit shows in the 1-sigma.
//!
//! A warm solve also starts from the last solve's linearisation when the same coordinates
//! of the same beacons are in view ([`glsdc::solve_with`]): its first step uses the model
//! values that linearisation predicts at the last solution (the warm start) against the new
//! spots, so it evaluates no model at all; the point it reaches is linearised afresh before
//! any stop, so the answer is Gauss-Newton's. A last step predicted to gain less than 0.1
//! chi-square is taken without another pass. A warm solve is thus one Jacobian pass.
//!
//! # Spot magnitudes
//!
//! Beyond the thesis (its model is the spots' `X, Y`): when the calibration carries a
//! magnitude law ([`Calibration::magnitude`], [`Magnitude`]) the near-field solve also fits
//! each spot's reported magnitude against the model's summed cell signal `S` (eq 63's
//! `sum_k c_k I_k V_k`), as `ln S` up to a scale common to the frame (LED drive, power
//! setting, drift) that is eliminated exactly: the magnitudes' residuals enter as their
//! weighted Helmert contrasts (`Contrasts`), `k` magnitudes giving `k - 1` rows in counts, so
//! the solve keeps its six unknowns and unit weights. Their ratios carry the beacons'
//! relative distances, which a flat target's tilt changes and the spots show only through
//! perspective: at 8-10 in they cut the one-frame attitude error of the 10-beacon target
//! about four-fold, if the magnitudes scatter as little as the spots (`cta sensor floor`,
//! `cta sensor accuracy`). A reading at or above the law's `max` (saturated), or not a count
//! above its offset, is not used; a frame at another light-sensitivity setting than the
//! law's is solved from the spots alone ([`PoseSolver::solve_frame`]). Each beacon's
//! relative brightness ([`Beacon::brightness`]) is divided out. A solve whose magnitudes
//! disagree with its spots (a residual RMS over [`MAGNITUDE_RMS_SIGMAS`] noise sigmas: a
//! wrong brightness, a law that does not hold, a drifting LED), or that fails with them, is
//! done again from the spots alone, and reports no magnitudes fitted.
//!
//! Status: [`PoseStatus::Ok`]; [`PoseStatus::IllConditioned`] when GLSDC reports a rank
//! deficiency, the condition number exceeds the limit, or the position 1-sigma exceeds
//! [`SolverSettings::max_sigma_fraction`] of the range; [`PoseStatus::Diverged`] when the
//! iteration does not converge, leaves the model's domain, ends behind the sensor, beyond
//! the constellation's far limit ([`FAR_SIGMAS`]) or with a residual RMS above the limit (a
//! false minimum). The pose is never NaN: a failed solve reports the last finite estimate,
//! its sigmas are `-1`, and the next solve cold-starts.
//!
//! # Layout
//!
//! `config`: the constellation and the calibration, and their validation; `solver`:
//! [`PoseSolver`]; `cold`: the cold start's homography; `problem`: the least-squares rows GLSDC solves; `magnitude`: the spot
//! magnitudes' readings and contrasts; `fixtures`: simulated spots, the built-in
//! constellations and the benchmark frames. Everything public is re-exported here.
//!
//! [`mrp::gradient_map`]: crate::mrp::gradient_map
//! [`Emulator`]: crate::emulator::Emulator
//! [`Emulator::output_gradient`]: crate::emulator::Emulator::output_gradient
//! [`glsdc::solve_with`]: crate::glsdc::solve_with

mod cold;
mod config;
mod fixtures;
mod magnitude;
mod obs;
mod problem;
mod solver;
#[cfg(test)]
mod tests;

pub use config::{
    Beacon, CalField, Calibration, ConfigError, Constellation, Magnitude, NearField, PinholeHead,
    MAX_BRIGHTNESS, MIN_BRIGHTNESS,
};
pub use fixtures::{
    attitude_xyz, benchmark_frames, benchmark_frames_of, cold_frames_of, cta_constellation,
    flat_constellation, four_array_constellation, mislabel, simulate_spots, simulate_spots_scaled,
    simulate_spots_with, BenchmarkFrames, SIM_MAGNITUDE_SCALE,
};
pub use magnitude::MAGNITUDE_RMS_SIGMAS;
pub use obs::Obs;
pub use solver::{
    ModelKind, PoseSolution, PoseSolver, PoseStatus, SolverSettings, WRONG_SPOT_GAIN,
    WRONG_SPOT_SIGMAS,
};

use crate::Real;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Most beacons in a constellation (the NorthStar tracks at most 20 spots).
pub const MAX_BEACONS: usize = 20;
/// Fewest matched beacons for a 6-dof solution (4 beacons give 8 equations for 6 unknowns).
pub const MIN_BEACONS: usize = 4;
/// Highest NorthStar frequency channel (spot ID).
pub const MAX_CHANNEL: u8 = 19;
/// The 16-bit output rail, counts: an output at or past it is clipped to it.
pub const RAIL: i16 = i16::MAX;
/// A coordinate within this many calibration noise sigmas ([`Calibration::noise`]) of
/// +/-[`RAIL`] counts as railed: its true value was at or past the rail (a cell in the dark,
/// or saturated) and only the noise kept it inside, so it is clipped, not measured. The rule
/// `cta calibrate` applies to a point's mean (`measurement::mean_near_rail`).
pub const RAIL_SIGMAS: f32 = 3.0;
/// The constellation's far limit: the range at which its radius about its centroid
/// subtends this many noise sigmas of the pinhole (`radius x H / (3 noise)`: 908 in for
/// [`cta_constellation`], 2,860 in for [`four_array_constellation`], with
/// [`Calibration::table3`]). There its spots are barely apart in the noise and the position
/// 1-sigma is a quarter of the range: a solution beyond it is a false minimum, reported
/// diverged.
pub const FAR_SIGMAS: f32 = 3.0;

/// One IR spot as the NorthStar reports it.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Spot {
    /// Frequency channel 0..=19 (beacon `k` uses channels `2k` and `2k + 1`).
    pub id: u8,
    /// X output, signed counts (eq 63).
    pub x: i16,
    /// Y output, signed counts (eq 63).
    pub y: i16,
    /// Signal strength 0..65535 (about 5000 is the noise floor, above 47000 is strong).
    pub magnitude: u16,
}

/// A configuration vector (`f32`, as stored and sent) in `T`.
fn v3<T: Real>(a: &[f32; 3]) -> Vector3<T> {
    Vector3::new(
        T::lit(a[0] as f64),
        T::lit(a[1] as f64),
        T::lit(a[2] as f64),
    )
}
