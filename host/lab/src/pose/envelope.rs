//! The docking envelope (`cta sensor accuracy --envelope`): every frame solved from the cold
//! start, as the board solves its first frame, over the poses a docking target can take at
//! each range: any roll about the line of sight, tilts up to the angle at which 4 beacons
//! stay in view, lateral offsets to the edge of the field of view. Per range: the cold
//! acquisition rate of the near-field and the pinhole model (eq 60-63 and eq 65), their
//! errors and ratio over the envelope, and the frames that failed with why.
//!
//! The near-field solver has the true head (Table 3, the simulated NorthStar's), the pinhole
//! solver the eq 65 fit of a simulated far sweep ([`pinhole_calibration`]): the model
//! error of each, without a fitted calibration's scatter.

use cta_core::emulator::Emulator;
use cta_core::mrp;
use cta_core::pose::{
    attitude_xyz, simulate_spots, Calibration, Constellation, ModelKind, PoseSolution, PoseSolver,
    PoseStatus, SolverSettings, Spot, RAIL, RAIL_SIGMAS,
};
use nalgebra::Vector3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use crate::pose::calibrations::{angle_between_deg, pinhole_calibration};
use crate::pose::error::Error;
use crate::pose::limits::{check_noise_fraction, check_ranges};
use crate::pose::plate::TestScene;

/// Fewest whole spots (both coordinates clear of the rails) of a usable frame.
pub const USABLE_SPOTS: usize = 4;
/// A solution within this many of its own 1-sigma of the truth (near-field) or of the
/// solve started at the truth (pinhole, whose model is biased near the target) is acquired.
pub const ACQUIRED_SIGMAS: f64 = 5.0;

/// Options of the envelope table.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvelopeOptions {
    /// Frames drawn per range (1 or more).
    pub trials: usize,
    /// Ranges, inches (each above 0, at most 1000).
    pub ranges: Vec<f64>,
    /// Spot noise, fraction of beta (1e-6 to 0.3).
    pub noise_fraction: f64,
    /// Random seed.
    pub seed: u64,
    /// Solve in f64 (else f32, as on the chip).
    pub f64: bool,
}

impl EnvelopeOptions {
    /// Check every option (with an error naming the option and its allowed range).
    pub fn check(&self) -> Result<(), Error> {
        if self.trials == 0 {
            return Err(Error::Option(
                "--trials 0: expected 1 or more trials per range".into(),
            ));
        }
        check_ranges("--ranges", &self.ranges)?;
        check_noise_fraction(self.noise_fraction)
    }
}

/// Why frames failed, counted.
#[derive(Debug, Clone, Default, Serialize, PartialEq, Eq)]
pub struct Failures {
    /// Reported diverged.
    pub diverged: usize,
    /// Reported ill-conditioned.
    pub ill_conditioned: usize,
    /// Reported too few beacons.
    pub too_few: usize,
    /// Reported Ok, but beyond [`ACQUIRED_SIGMAS`] of the pose it should have reached (a
    /// wrong minimum).
    pub wrong_minimum: usize,
}

impl Failures {
    /// All failed frames.
    pub fn total(&self) -> usize {
        self.diverged + self.ill_conditioned + self.too_few + self.wrong_minimum
    }

    fn count(&mut self, status: PoseStatus) {
        match status {
            PoseStatus::Diverged => self.diverged += 1,
            PoseStatus::IllConditioned => self.ill_conditioned += 1,
            PoseStatus::TooFewBeacons => self.too_few += 1,
            PoseStatus::Ok => self.wrong_minimum += 1,
        }
    }
}

/// One model's figures at one range.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ModelRow {
    /// Usable frames acquired from the cold start.
    pub acquired: usize,
    /// RMS position error of the acquired frames against the truth, in.
    pub pos: f64,
    /// RMS attitude error of the acquired frames against the truth, deg.
    pub att: f64,
    /// The usable frames that failed, by why.
    pub failures: Failures,
}

/// One row of the envelope table.
#[derive(Debug, Clone, Serialize)]
pub struct EnvelopeRow {
    /// Range (target z), in.
    pub range: f64,
    /// Largest tilt drawn, deg: on axis, every roll and tilt direction up to it keeps
    /// [`USABLE_SPOTS`] whole spots.
    pub max_tilt_deg: f64,
    /// Largest lateral offset drawn, in: untilted, every roll and direction up to it keeps
    /// [`USABLE_SPOTS`] whole spots (the field of view's edge for the constellation).
    pub max_offset: f64,
    /// Frames drawn.
    pub frames: usize,
    /// Frames with [`USABLE_SPOTS`] or more whole spots (the others are not solved).
    pub usable: usize,
    /// The near-field model.
    pub near_field: ModelRow,
    /// The pinhole model.
    pub pinhole: ModelRow,
}

impl EnvelopeRow {
    /// Pinhole over near-field RMS position error.
    pub fn ratio_pos(&self) -> f64 {
        self.pinhole.pos / self.near_field.pos
    }
    /// Pinhole over near-field RMS attitude error.
    pub fn ratio_att(&self) -> f64 {
        self.pinhole.att / self.near_field.att
    }
}

/// The envelope table.
#[derive(Debug, Clone, Serialize)]
pub struct EnvelopeTable {
    /// The constellation, its plate, the raise.
    pub label: String,
    /// Spot noise, counts (1-sigma).
    pub noise: f64,
    /// Whether the solves ran in f64.
    pub f64: bool,
    /// One row per range.
    pub rows: Vec<EnvelopeRow>,
}

/// The number of whole spots (both coordinates clear of the rails, as the solver takes
/// them) of a frame.
fn whole(spots: &[Spot], noise: f64) -> usize {
    let rail = f64::from(RAIL) - f64::from(RAIL_SIGMAS) * noise;
    spots
        .iter()
        .filter(|s| f64::from(s.x).abs() < rail && f64::from(s.y).abs() < rail)
        .count()
}

/// The MRP of the target turned `roll` deg about the line of sight, then tilted `tilt` deg
/// about the horizontal axis at `azimuth` deg.
fn envelope_attitude(roll: f64, tilt: f64, azimuth: f64) -> Vector3<f64> {
    let (s, c) = azimuth.to_radians().sin_cos();
    let r = attitude_xyz([0.0, 0.0, roll]);
    let t = mrp::from_axis_angle(&Vector3::new(c, s, 0.0), tilt.to_radians());
    mrp::compose(&t, &r)
}

/// Whether every roll (30 deg steps) and direction (45 deg steps) of the pose at `range`
/// with `tilt` and lateral `offset` keeps [`USABLE_SPOTS`] whole noise-free spots.
fn always_usable(
    em: &Emulator<f64>,
    con: &Constellation,
    range: f64,
    tilt: f64,
    offset: f64,
    noise: f64,
) -> bool {
    (0..8).all(|a| {
        let az = 45.0 * f64::from(a);
        let (s, c) = az.to_radians().sin_cos();
        let t = Vector3::new(offset * c, offset * s, range);
        (0..12).all(|r| {
            let q = envelope_attitude(30.0 * f64::from(r), tilt, az + 90.0);
            whole(&simulate_spots(em, con, &t, &q, |_| 0.0), noise) >= USABLE_SPOTS
        })
    })
}

/// The envelope's limits at `range`: the largest tilt (1 deg steps, on axis) and lateral
/// offset (untilted, steps of 1 % of the range) at which every roll and direction keeps
/// [`USABLE_SPOTS`] whole spots.
pub fn limits(em: &Emulator<f64>, con: &Constellation, range: f64, noise: f64) -> (f64, f64) {
    let tilt = (1..=85)
        .map(f64::from)
        .take_while(|&t| always_usable(em, con, range, t, 0.0, noise))
        .last()
        .unwrap_or(0.0);
    let offset = (1..=300)
        .map(|k| 0.01 * f64::from(k) * range)
        .take_while(|&o| always_usable(em, con, range, 0.0, o, noise))
        .last()
        .unwrap_or(0.0);
    (tilt, offset)
}

/// One cold solve and one from the truth, as `(solution, from the truth)` in f64.
fn solve_pair(
    cal: &Calibration,
    con: &Constellation,
    model: ModelKind,
    spots: &[Spot],
    truth: (Vector3<f64>, Vector3<f64>),
    f64: bool,
) -> Result<(PoseSolution<f64>, PoseSolution<f64>), Error> {
    let set = SolverSettings {
        model,
        magnitudes: false,
        ..Default::default()
    };
    if f64 {
        let s = PoseSolver::<f64>::new(cal, con, set).map_err(Error::Solver)?;
        let mut from_truth = s.clone();
        from_truth.set_warm_start(truth.0, truth.1);
        Ok((s.clone().solve(spots), from_truth.solve(spots)))
    } else {
        let s = PoseSolver::<f32>::new(cal, con, set).map_err(Error::Solver)?;
        let mut from_truth = s.clone();
        from_truth.set_warm_start(truth.0.map(|v| v as f32), truth.1.map(|v| v as f32));
        Ok((
            wide(&s.clone().solve(spots)),
            wide(&from_truth.solve(spots)),
        ))
    }
}

/// An f32 solution in f64.
fn wide(s: &PoseSolution<f32>) -> PoseSolution<f64> {
    let c = |v: Vector3<f32>| v.map(f64::from);
    PoseSolution {
        status: s.status,
        position: c(s.position),
        mrp: c(s.mrp),
        sigma_position: c(s.sigma_position),
        sigma_attitude_deg: c(s.sigma_attitude_deg),
        rms: f64::from(s.rms),
        iterations: s.iterations,
        beacons: s.beacons,
        magnitudes: s.magnitudes,
        condition: f64::from(s.condition),
        cold_start: s.cold_start,
        dropped: s.dropped,
    }
}

/// Whether `sol` is Ok within [`ACQUIRED_SIGMAS`] of its own 1-sigma of `(t, q)`.
fn within(sol: &PoseSolution<f64>, t: &Vector3<f64>, q: &Vector3<f64>) -> bool {
    sol.status == PoseStatus::Ok
        && (sol.position - t).norm() <= ACQUIRED_SIGMAS * sol.sigma_position.norm()
        && angle_between_deg(&sol.mrp, q) <= ACQUIRED_SIGMAS * sol.sigma_attitude_deg.norm()
}

/// Compute the envelope table on the target `scene`.
pub fn envelope_table_on(args: &EnvelopeOptions, scene: TestScene) -> Result<EnvelopeTable, Error> {
    args.check()?;
    scene.check_ranges(&args.ranges)?;
    let mut truth = Calibration::table3();
    let noise = args.noise_fraction * cta_core::emulator::BETA;
    truth.noise = noise as f32;
    let con = scene.con;
    let ph_cal = pinhole_calibration(&truth, scene.plate)?;
    let em: Emulator<f64> = cta_firmware_sensor::sim::physics(&truth);
    let normal = Normal::new(0.0, noise).map_err(|error| Error::Noise {
        what: "noise",
        error,
    })?;
    let mut rng = StdRng::seed_from_u64(args.seed);
    let mut rows = Vec::new();
    for &range in &args.ranges {
        let (max_tilt_deg, max_offset) = limits(&em, &con, range, noise);
        let mut row = EnvelopeRow {
            range,
            max_tilt_deg,
            max_offset,
            frames: 0,
            usable: 0,
            near_field: ModelRow::default(),
            pinhole: ModelRow::default(),
        };
        for _ in 0..args.trials {
            row.frames += 1;
            let az: f64 = rng.random_range(0.0..360.0);
            let rho = max_offset * rng.random::<f64>().sqrt();
            let t = Vector3::new(
                rho * az.to_radians().cos(),
                rho * az.to_radians().sin(),
                range,
            );
            let q = envelope_attitude(
                rng.random_range(-180.0..180.0),
                rng.random_range(0.0..=max_tilt_deg),
                rng.random_range(0.0..360.0),
            );
            let spots = simulate_spots(&em, &con, &t, &q, |_| normal.sample(&mut rng));
            if whole(&spots, noise) < USABLE_SPOTS {
                continue;
            }
            row.usable += 1;
            for (model, cal, out) in [
                (ModelKind::NearField, &truth, &mut row.near_field),
                (ModelKind::Pinhole, &ph_cal, &mut row.pinhole),
            ] {
                let (sol, best) = solve_pair(cal, &con, model, &spots, (t, q), args.f64)?;
                // Acquired: the near-field at the truth, the pinhole at its own minimum
                // there (its model is biased near the target).
                let acquired = match model {
                    ModelKind::NearField => within(&sol, &t, &q),
                    ModelKind::Pinhole => within(&sol, &best.position, &best.mrp),
                };
                if acquired {
                    out.acquired += 1;
                    out.pos += (sol.position - t).norm_squared();
                    out.att += angle_between_deg(&sol.mrp, &q).powi(2);
                } else {
                    out.failures.count(sol.status);
                }
            }
        }
        for m in [&mut row.near_field, &mut row.pinhole] {
            let n = m.acquired.max(1) as f64;
            m.pos = (m.pos / n).sqrt();
            m.att = (m.att / n).sqrt();
        }
        rows.push(row);
    }
    Ok(EnvelopeTable {
        label: scene.label,
        noise,
        f64: args.f64,
        rows,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::plate::Scene;

    /// A small envelope of the one-10 constellation at 3, 8 and 30 in: every usable frame is
    /// acquired from the cold start by the near-field model, rolls of the whole circle are
    /// drawn, the limits shrink the field of view (in angle) and the near-field error stays
    /// far below the pinhole's at 3 in.
    #[test]
    fn a_small_envelope_is_acquired() {
        let opts = EnvelopeOptions {
            trials: 60,
            ranges: vec![3.0, 8.0, 30.0],
            noise_fraction: 0.001,
            seed: 7,
            f64: false,
        };
        let table = envelope_table_on(&opts, Scene::default().resolve().unwrap()).unwrap();
        for r in &table.rows {
            assert!(r.usable >= 50, "{r:?}");
            assert_eq!(r.near_field.acquired, r.usable, "{r:?}");
            assert!(r.max_tilt_deg >= 20.0, "{r:?}");
            assert!(r.max_offset > 0.05 * r.range, "{r:?}");
        }
        assert!(table.rows[0].ratio_pos() > 5.0, "{:?}", table.rows[0]);
        // The lateral limit grows with range (a field of view), slower than it.
        assert!(table.rows[2].max_offset > table.rows[0].max_offset);
    }

    #[test]
    fn options_are_checked() {
        let opts = EnvelopeOptions {
            trials: 0,
            ranges: vec![3.0],
            noise_fraction: 0.001,
            seed: 7,
            f64: false,
        };
        let e = opts.check().unwrap_err().to_string();
        assert!(e.contains("--trials 0"), "{e}");
    }
}
