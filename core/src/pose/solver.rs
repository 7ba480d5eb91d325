//! The pose solver: GLSDC (eqs 56-59) over `x = [t, q]` with the pinhole (eq 65) or the
//! near-field (eqs 60-63) model; spot matching, the cold and warm starts, the carried
//! linearisation, the fallback from the magnitudes to the spots alone, and the status gates.

use super::cold;
use super::magnitude::{MagSolve, MAGNITUDE_RMS_SIGMAS};
use super::obs::Obs;
use super::problem::PoseProblem;
use super::{
    v3, Calibration, ConfigError, Constellation, NearField, Spot, FAR_SIGMAS, MAX_BEACONS,
    MIN_BEACONS, RAIL, RAIL_SIGMAS,
};
use crate::collinearity::{Linearisation, Params, ParamsExt};
use crate::emulator::{Effects, Emulator, Head, Pose as HeadPose};
use crate::glsdc::{self, Problem, Settings};
use crate::mrp;
use crate::pattern::Pattern;
use crate::real::{deg, rad};
use crate::Real;
use heapless::Vec;
use nalgebra::{Matrix3, SVector, Vector3, U6};
use serde::{Deserialize, Serialize};

/// Which measurement model the solver uses.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelKind {
    /// Eq 65 (far-field collinearity) with the calibration's `H` and its pinhole head
    /// ([`Calibration::pinhole`]'s `d, p`; without one, the calibration's `d, p`).
    Pinhole,
    /// The eq 60-63 physics with the calibration's near-field parameters.
    NearField,
}

/// Outcome of a solve.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub enum PoseStatus {
    /// Converged; pose and 1-sigma valid.
    Ok,
    /// Fewer than [`MIN_BEACONS`] beacons of the constellation were seen, or fewer usable
    /// coordinates (farther than [`RAIL_SIGMAS`] noise sigmas from the 16-bit rails) than
    /// that many whole spots give.
    TooFewBeacons,
    /// No convergence, left the model's domain, or a false minimum (residual too large, or
    /// the target beyond the constellation's far limit, [`FAR_SIGMAS`]).
    Diverged,
    /// The geometry does not determine the pose (rank deficient, condition too large, or a
    /// position 1-sigma over [`SolverSettings::max_sigma_fraction`] of the range).
    IllConditioned,
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverSettings {
    /// Measurement model.
    pub model: ModelKind,
    /// GLSDC iteration cap.
    pub max_iter: usize,
    /// Largest acceptable condition number of the scaled Jacobian.
    pub max_condition: f64,
    /// Largest acceptable residual RMS, counts (larger: a false minimum, reported diverged).
    pub max_rms: f64,
    /// Largest acceptable position 1-sigma (the norm of the three) as a fraction of the
    /// range `|t|` (larger: the data do not fix where the target is, reported
    /// ill-conditioned). 0.25 by default: on the CTA (2-30 in) it is at most 0.08 (the
    /// pinhole's misfit at 2 in; the near-field's at most 0.007); one-10 at 500 in reaches
    /// 0.17.
    pub max_sigma_fraction: f64,
    /// Fit the spot magnitudes too when the calibration has a magnitude model
    /// ([`Calibration::magnitude`]) and the model is [`ModelKind::NearField`] (the pinhole
    /// model has no intensity). `true` by default; `false` solves from the spots alone.
    pub magnitudes: bool,
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            model: ModelKind::NearField,
            max_iter: 20,
            max_condition: 1e4,
            max_rms: 2000.0,
            max_sigma_fraction: 0.25,
            magnitudes: true,
        }
    }
}

/// A pose solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSolution<T: Real> {
    /// Status.
    pub status: PoseStatus,
    /// Target origin in N, inches (never NaN).
    pub position: Vector3<T>,
    /// MRP of `C(q)` (N -> T), `|q| <= 1` (never NaN).
    pub mrp: Vector3<T>,
    /// 1-sigma of the position, inches (`-1` unless the status is Ok or IllConditioned
    /// with a covariance).
    pub sigma_position: Vector3<T>,
    /// 1-sigma of the attitude about the three axes, degrees (small-angle: `4 sigma_q`).
    pub sigma_attitude_deg: Vector3<T>,
    /// Residual RMS, counts.
    pub rms: T,
    /// GLSDC iterations.
    pub iterations: u8,
    /// Beacons used.
    pub beacons: u8,
    /// Spot magnitudes fitted (0: the spots alone; one magnitude alone carries nothing, its
    /// scale being unknown).
    pub magnitudes: u8,
    /// Condition number of the scaled, weighted Jacobian (0 when not computed).
    pub condition: T,
    /// Whether this solve started from the cold start.
    pub cold_start: bool,
    /// The ID of a beacon of the constellation left out of this solve: its spot's residual
    /// disagreed with all the others' (a spot under another beacon's ID: see
    /// [`WRONG_SPOT_SIGMAS`]), or the frame reported its ID twice (neither spot used).
    pub dropped: Option<u8>,
}

/// A solve whose residual RMS exceeds this many noise sigmas (or that diverged) is screened
/// for a wrong spot: solved again without each of its two worst-fitting spots in turn, from
/// the cold start, and a spot is left out when the RMS without it is [`WRONG_SPOT_GAIN`]
/// times smaller. Clean near-field frames sit near 1 sigma at 2-30 in; the pinhole model's
/// misfit passes it within about 6 in, where the gain test keeps its answer unless one spot
/// alone makes it.
pub const WRONG_SPOT_SIGMAS: f32 = 4.0;
/// How much smaller the residual RMS must be without a spot for it to be left out (see
/// [`WRONG_SPOT_SIGMAS`]).
pub const WRONG_SPOT_GAIN: f32 = 3.0;

/// The pose solver: calibration and constellation converted to `T`, and the warm start.
#[derive(Debug, Clone)]
pub struct PoseSolver<T: Real> {
    settings: SolverSettings,
    cal: Params<T>,
    pub(super) lin: Linearisation<T>,
    pub(super) emulator: Option<Emulator<T>>,
    pub(super) beacons: Vec<(u8, Vector3<T>), MAX_BEACONS>,
    pub(super) boresight: Vector3<T>,
    /// The head's boresight (the O frame's z axis) in N.
    head_axis: Vector3<T>,
    /// `noise^2` (counts^2): the unit of the stopping tolerances.
    noise2: T,
    /// A coordinate with `|v| >= rail` is railed: [`RAIL`] less [`RAIL_SIGMAS`] noise.
    rail: i32,
    /// The distance of the constellation's centroid from the T origin, inches.
    centroid_offset: T,
    /// The square of the largest range `|t|` a pose may have (see [`Self::configure`]).
    max_range2: T,
    /// The square of [`SolverSettings::max_sigma_fraction`].
    max_sigma_fraction2: T,
    /// The magnitude model in `T`, when the magnitudes are fitted.
    pub(super) mag: Option<MagSolve<T>>,
    /// `ln b` of each beacon's brightness ([`Beacon::brightness`]), in the order of `beacons`.
    ///
    /// [`Beacon::brightness`]: super::Beacon::brightness
    ln_brightness: [T; MAX_BEACONS],
    /// [`SolverSettings::max_condition`] and [`SolverSettings::max_rms`] in `T`, converted
    /// once by [`Self::configure`]: no double-precision conversion (a soft-float routine of
    /// its own on the chip) in the solve.
    max_condition: T,
    max_rms: T,
    warm: Option<SVector<T, 6>>,
    /// The last solve's linearisation, carried to the next frame's first step
    /// ([`glsdc::solve_with`]): its weighted Jacobian rows (2 per beacon) with the model
    /// values predicted at the solution, the factored normal matrix, and which coordinates
    /// of which beacons the rows belong to.
    rows: [T; 2 * MAX_BEACONS * 7],
    pub(super) carry: Option<glsdc::Carry<T, U6>>,
    carry_key: u64,
    /// The magnitudes' weights of the carried linearisation, by observation: a frame solved
    /// from it keeps them (a reading's weight moves with its rounding term from frame to
    /// frame, and the carried rows are the contrasts of those weights).
    pub(super) carry_mw: [T; MAX_BEACONS],
    /// Solve with the pinhole model whatever the settings (the pinhole pass of a failed
    /// near-field cold start, see [`Self::solve_keyed`]).
    pinhole_pass: bool,
}

impl<T: Real> PoseSolver<T> {
    /// Build a solver; validates both inputs. `ModelKind::NearField` without near-field
    /// parameters in the calibration uses the nominal ones ([`NearField::nominal`]).
    pub fn new(
        cal: &Calibration,
        con: &Constellation,
        settings: SolverSettings,
    ) -> Result<Self, ConfigError> {
        let mut s = Self::blank();
        s.configure(cal, con, settings)?;
        Ok(s)
    }

    /// A solver with nothing configured (every solve reports too few beacons), as a board
    /// holds one before [`Self::configure`] first succeeds.
    pub fn blank() -> Self {
        let params = Params::<T>::zeros();
        PoseSolver {
            settings: SolverSettings::default(),
            cal: params,
            lin: Linearisation::new(&params),
            emulator: None,
            beacons: Vec::new(),
            boresight: Vector3::new(T::zero(), T::zero(), -T::one()),
            head_axis: Vector3::new(T::zero(), T::zero(), T::one()),
            noise2: T::one(),
            rail: i32::from(RAIL),
            centroid_offset: T::zero(),
            max_range2: T::zero(),
            max_sigma_fraction2: T::zero(),
            mag: None,
            ln_brightness: [T::zero(); MAX_BEACONS],
            max_condition: T::lit(SolverSettings::default().max_condition),
            max_rms: T::lit(SolverSettings::default().max_rms),
            warm: None,
            rows: [T::zero(); 2 * MAX_BEACONS * 7],
            carry: None,
            carry_key: 0,
            carry_mw: [T::zero(); MAX_BEACONS],
            pinhole_pass: false,
        }
    }

    /// [`Self::new`] in place: validate both inputs, then replace the configuration and
    /// forget the warm start. On the chip the solver is the largest object (about 2 KiB):
    /// configuring it where it lives keeps a second copy off the stack. On an error the
    /// solver is left blank.
    ///
    /// It also sets the two limits the calibration and the constellation imply: the rail
    /// margin ([`RAIL_SIGMAS`] x the calibration's noise) and the constellation's far limit
    /// (see [`FAR_SIGMAS`]). Its bound on `|t|` adds the centroid's distance from the T
    /// origin.
    pub fn configure(
        &mut self,
        cal: &Calibration,
        con: &Constellation,
        settings: SolverSettings,
    ) -> Result<(), ConfigError> {
        self.beacons.clear();
        self.emulator = None;
        self.mag = None;
        self.warm = None;
        self.carry = None;
        cal.validate()?;
        con.validate()?;
        let head_pose = HeadPose {
            d: v3(&cal.d),
            p: v3(&cal.p),
        };
        // The pinhole model's eye: its own fitted d, p when the calibration has them.
        let eye = match (settings.model, &cal.pinhole) {
            (ModelKind::Pinhole, Some(ph)) => HeadPose {
                d: v3(&ph.d),
                p: v3(&ph.p),
            },
            _ => head_pose,
        };
        let params = Params::from_pose(&eye, T::lit(cal.h as f64));
        if settings.model == ModelKind::NearField {
            let nf = cal.near_field.unwrap_or(NearField::nominal());
            let [ax, ay] = nf.face_angles_deg().map(|a| rad(T::lit(a as f64)));
            let head = Head {
                alpha_x: ax,
                alpha_y: ay,
                s: T::lit(nf.s as f64),
                beta: T::lit(nf.beta as f64),
            };
            let effects = Effects {
                pattern: Pattern::Lambertian {
                    m: T::lit(nf.pattern_m as f64),
                },
                gain: nf.cell_gains(),
                bias: nf.cell_biases(),
                ..Effects::default()
            };
            // The LEDs' boresight is set per pass from the attitude (rows): none here.
            self.emulator = Some(Emulator::with_led_boresight(
                head,
                head_pose,
                effects,
                &Vector3::new(T::zero(), T::zero(), -T::one()),
            ));
        }
        for (i, b) in con.beacons.iter().enumerate() {
            // Cannot overflow: both hold MAX_BEACONS.
            let _ = self.beacons.push((b.id, v3(&b.r)));
            self.ln_brightness[i] = T::lit(b.brightness as f64).ln();
        }
        let noise = T::lit(cal.noise as f64);
        if let (Some(m), true, ModelKind::NearField) =
            (&cal.magnitude, settings.magnitudes, settings.model)
        {
            self.mag = Some(MagSolve::new(m, noise));
        }
        // Cannot overflow: the noise is at most 10,000 counts (validated).
        self.rail = i32::from(RAIL) - (RAIL_SIGMAS * cal.noise) as i32;
        let n = T::lit(self.beacons.len() as f64);
        let centroid = self
            .beacons
            .iter()
            .fold(Vector3::zeros(), |c, (_, r)| c + r / n);
        let radius = self
            .beacons
            .iter()
            .fold(T::zero(), |m, (_, r)| m.max((r - centroid).norm()));
        self.centroid_offset = centroid.norm();
        let far = self.centroid_offset
            + radius * T::lit(cal.h as f64) / (T::lit(FAR_SIGMAS as f64) * noise);
        self.max_range2 = far * far;
        let fraction = T::lit(settings.max_sigma_fraction);
        self.max_sigma_fraction2 = fraction * fraction;
        self.max_condition = T::lit(settings.max_condition);
        self.max_rms = T::lit(settings.max_rms);
        self.settings = settings;
        self.cal = params;
        self.lin = Linearisation::new(&params);
        self.boresight = v3::<T>(&con.boresight).normalize();
        self.head_axis = mrp::dcm(&eye.p).row(2).transpose();
        self.noise2 = noise * noise;
        Ok(())
    }

    /// The settings in use.
    pub fn settings(&self) -> &SolverSettings {
        &self.settings
    }

    /// Forget the warm start (the next solve cold-starts).
    pub fn reset(&mut self) {
        self.warm = None;
        self.carry = None;
    }

    /// Set the warm start explicitly (position in inches, MRP). The linearisation carried
    /// from the last solve is dropped.
    pub fn set_warm_start(&mut self, position: Vector3<T>, mrp: Vector3<T>) {
        self.carry = None;
        self.warm = Some(SVector::<T, 6>::new(
            position.x, position.y, position.z, mrp.x, mrp.y, mrp.z,
        ));
    }

    /// The warm start, if any.
    pub fn warm_start(&self) -> Option<(Vector3<T>, Vector3<T>)> {
        self.warm.map(|x| {
            (
                Vector3::new(x[0], x[1], x[2]),
                Vector3::new(x[3], x[4], x[5]),
            )
        })
    }

    /// Match spots to beacons by ID (first spot of each ID). Coordinates at or within
    /// [`RAIL_SIGMAS`] noise sigmas of the 16-bit rails are marked unused; a spot with both
    /// there is skipped. With a magnitude model in use, each spot's magnitude is weighed
    /// ([`Obs::m`], [`Obs::mw`]); a saturated or too weak one is not used.
    pub fn match_spots(&self, spots: &[Spot]) -> Vec<Obs<T>, MAX_BEACONS> {
        let mut obs = Vec::new();
        self.match_keyed(spots, &mut obs, true, &mut None);
        obs
    }

    /// [`Self::match_spots`] into `obs` (cleared first; filled in place, no copy of 480
    /// bytes on the chip's stack), the magnitudes only when `magnitudes`, returning which
    /// coordinates of which beacons were used: bits `2i` (X) and `2i + 1` (Y) for beacon `i`
    /// of the constellation, and bit `2 MAX_BEACONS + i` for its magnitude. An ID of the
    /// constellation that came twice leaves its beacon out, and is set in `twice`.
    fn match_keyed(
        &self,
        spots: &[Spot],
        obs: &mut Vec<Obs<T>, MAX_BEACONS>,
        magnitudes: bool,
        twice: &mut Option<u8>,
    ) -> u64 {
        obs.clear();
        *twice = None;
        let mut key = 0u64;
        let mag = self.mag.as_ref().filter(|_| magnitudes);
        for (i, (id, r)) in self.beacons.iter().enumerate() {
            let mut same = spots.iter().filter(|s| s.id == *id);
            let spot = same.next();
            // An ID reported twice: which spot is the beacon's is unknown, neither is used.
            if same.next().is_some() {
                *twice = Some(*id);
                continue;
            }
            if let Some(s) = spot {
                let rail = |v: i16| i32::from(v).abs() >= self.rail;
                let used = [!rail(s.x), !rail(s.y)];
                if !(used[0] || used[1]) {
                    continue;
                }
                key |= (u64::from(used[0]) | u64::from(used[1]) << 1) << (2 * i);
                let (m, mw) = match mag.and_then(|g| g.reading(s.magnitude, self.ln_brightness[i]))
                {
                    Some(mw) => {
                        key |= 1 << (2 * MAX_BEACONS + i);
                        mw
                    }
                    None => (T::zero(), T::zero()),
                };
                let _ = obs.push(Obs {
                    // Element by element: a copy of the whole vector here is a `memmove` on
                    // the chip (1.6 KB of flash).
                    r: Vector3::new(r.x, r.y, r.z),
                    y: [T::lit(s.x as f64), T::lit(s.y as f64)],
                    used,
                    m,
                    mw,
                });
            }
        }
        key
    }

    /// The cold start, whatever the attitude: the plate pose of the homography of the spots'
    /// pinhole lines of sight ([`cold::plate_pose`]; for the pinhole model, its own eye's
    /// `d, C`), when every beacon is then in front; `None` otherwise (or a singular fit).
    // Never inlined: its matrices stay off the solve's frame, which the whole GLSDC run
    // keeps on the chip's stack.
    #[inline(never)]
    pub fn cold_start(&self, obs: &[Obs<T>]) -> Option<SVector<T, 6>> {
        let d = Vector3::new(self.cal[0], self.cal[1], self.cal[2]);
        let c_p = mrp::dcm(&Vector3::new(self.cal[3], self.cal[4], self.cal[5]));
        let x = SVector::<T, 6>::from(cold::plate_pose(obs, self.cal.h())?.unknowns(&d, &c_p));
        (x.iter().all(|v| v.is_finite()) && self.in_front(&x, obs)).then_some(x)
    }

    /// Solve for the pose from one frame of spots (with their magnitudes when the
    /// calibration has a magnitude model, whatever the frame's sensitivity: see
    /// [`Self::solve_frame`]).
    pub fn solve(&mut self, spots: &[Spot]) -> PoseSolution<T> {
        let mut obs = Vec::new();
        let mut twice = None;
        let key = self.match_keyed(spots, &mut obs, true, &mut twice);
        self.solve_carried(&mut obs, key, twice)
    }

    /// [`Self::solve`] for a frame the NorthStar reported at light-sensitivity setting
    /// `sensitivity`: the magnitudes are used only at the setting their law was fitted at
    /// ([`Magnitude::sensitivity`]); at another, the spots alone.
    ///
    /// [`Magnitude::sensitivity`]: super::Magnitude::sensitivity
    pub fn solve_frame(&mut self, spots: &[Spot], sensitivity: u8) -> PoseSolution<T> {
        let mut obs = Vec::new();
        let same = self
            .mag
            .as_ref()
            .is_some_and(|m| m.sensitivity == sensitivity);
        let mut twice = None;
        let key = self.match_keyed(spots, &mut obs, same, &mut twice);
        self.solve_carried(&mut obs, key, twice)
    }

    /// [`Self::solve_keyed`] for matched spots: where the last linearisation will be carried
    /// (a warm start, the same beacons, coordinates and magnitudes in view), the magnitudes
    /// keep that linearisation's weights, so that its rows still hold for them (their weights
    /// follow each reading's rounding term, which moves a little from frame to frame: a step
    /// from rows of other weights misses, and costs another Jacobian pass). The weights
    /// used are kept for the next frame.
    ///
    /// Then the wrong-spot screen (see [`WRONG_SPOT_SIGMAS`]); `twice` (an ID the frame
    /// reported twice, see [`Self::match_keyed`]) is reported as dropped unless the screen
    /// drops a spot.
    fn solve_carried(
        &mut self,
        obs: &mut [Obs<T>],
        key: u64,
        twice: Option<u8>,
    ) -> PoseSolution<T> {
        if self.warm.is_some() && self.carry.is_some() && key == self.carry_key {
            for (o, w) in obs.iter_mut().zip(&self.carry_mw) {
                if o.magnitude_used() {
                    o.mw = *w;
                }
            }
        }
        let mut sol = self.solve_keyed(obs, Some(key));
        for (w, o) in self.carry_mw.iter_mut().zip(obs.iter()) {
            *w = o.mw;
        }
        sol.dropped = twice;
        // A wrong spot: the two worst-fitting spots left out in turn (see WRONG_SPOT_SIGMAS).
        let k = T::lit(WRONG_SPOT_SIGMAS as f64);
        let suspect = match sol.status {
            PoseStatus::Ok => sol.rms * sol.rms > k * k * self.noise2,
            PoseStatus::Diverged => true,
            _ => false,
        };
        if !(suspect && obs.len() > MIN_BEACONS) {
            return sol;
        }
        let rms = if sol.rms > T::zero() {
            sol.rms
        } else {
            T::max_value().unwrap_or_else(T::one)
        };
        let gain = T::lit(WRONG_SPOT_GAIN as f64);
        for i in self.worst_fits(obs, &sol) {
            let Some(o) = obs.get_mut(i) else { continue };
            let keep = *o;
            o.used = [false; 2];
            o.mw = T::zero();
            self.warm = None;
            self.carry = None;
            let mut s = self.solve_keyed(obs, None);
            obs[i] = keep;
            if s.status == PoseStatus::Ok && s.rms * gain <= rms {
                s.beacons -= 1;
                // Observation i is the i-th beacon of the constellation with a spot in use.
                s.dropped = (0..self.beacons.len())
                    .filter(|b| (key >> (2 * b)) & 3 != 0)
                    .nth(i)
                    .map(|b| self.beacons[b].0);
                return s;
            }
        }
        // No single spot explains the misfit: the first answer stands, and the next frame
        // starts from it when it was good.
        self.warm = if sol.status == PoseStatus::Ok {
            Some(SVector::<T, 6>::new(
                sol.position.x,
                sol.position.y,
                sol.position.z,
                sol.mrp.x,
                sol.mrp.y,
                sol.mrp.z,
            ))
        } else {
            None
        };
        sol
    }

    /// The indices of the two observations that fit the solution `sol` worst (largest sum of
    /// squared residuals over their used coordinates, from the problem's own rows without the
    /// magnitudes). `usize::MAX` where there is none, or when the model cannot place a beacon.
    #[inline(never)]
    fn worst_fits(&self, obs: &[Obs<T>], sol: &PoseSolution<T>) -> [usize; 2] {
        let x = SVector::<T, 6>::new(
            sol.position.x,
            sol.position.y,
            sol.position.z,
            sol.mrp.x,
            sol.mrp.y,
            sol.mrp.z,
        );
        let problem = PoseProblem {
            lin: &self.lin,
            emulator: self.emulator.as_ref(),
            boresight: self.boresight,
            obs,
            magnitudes: false,
        };
        let mut e = [T::zero(); MAX_BEACONS];
        let mut row = 0;
        // One row per used coordinate, in the observations' order.
        let placed = problem.rows(&x, false, &mut |r, _, _| {
            let (mut k, mut i) = (row, 0);
            while i < obs.len() && k >= obs[i].rows() {
                k -= obs[i].rows();
                i += 1;
            }
            if let Some(e) = e.get_mut(i) {
                *e += r * r;
            }
            row += 1;
        });
        let mut best = [usize::MAX; 2];
        if placed.is_err() {
            return best;
        }
        let mut top = [-T::one(); 2];
        for (i, &r) in e.iter().enumerate().take(obs.len()) {
            if r > top[0] {
                (best[1], top[1]) = (best[0], top[0]);
                (best[0], top[0]) = (i, r);
            } else if r > top[1] {
                (best[1], top[1]) = (i, r);
            }
        }
        best
    }

    /// Solve for the pose from matched observations (without the linearisation carried
    /// from the last solve: which beacons these are is not known).
    pub fn solve_obs(&mut self, obs: &[Obs<T>]) -> PoseSolution<T> {
        self.solve_keyed(obs, None)
    }

    /// Solve; `key` names the observations' beacons and coordinates (see
    /// [`Self::match_keyed`]). With magnitudes, a solve that fails or whose residual RMS
    /// exceeds [`MAGNITUDE_RMS_SIGMAS`] noise sigmas is done again from the spots alone
    /// (from the same start), and that answer is reported. A warm-started solve that diverges
    /// is done again from the cold start; a near-field one that fails from the cold start is
    /// done with the pinhole model first, then from its answer.
    // Never inlined: the frame handler calls it for the frame and for the wrong-spot trials,
    // one copy of its code on the chip.
    #[inline(never)]
    fn solve_keyed(&mut self, obs: &[Obs<T>], key: Option<u64>) -> PoseSolution<T> {
        let warm = self.warm;
        let limit = T::lit(MAGNITUDE_RMS_SIGMAS as f64);
        let (mut key, mut magnitudes) = (key, true);
        // 0: not yet; 1: this pass; 2: done (see below).
        let mut pinhole_pass = 0u8;
        // One call site, one solution on the stack (on the chip this is inlined into the
        // board's frame handler): each pass is the first solve, or its retry.
        loop {
            self.pinhole_pass = pinhole_pass == 1;
            let sol = self.solve_once(obs, key.filter(|_| pinhole_pass != 1), magnitudes);
            self.pinhole_pass = false;
            if pinhole_pass == 1 {
                pinhole_pass = 2;
                // Its answer is the near-field solve's warm start; a failure is reported.
                if sol.status == PoseStatus::Ok {
                    continue;
                }
                return sol;
            }
            // A warm start that diverged (the target turned or moved too far since the last
            // frame for Gauss-Newton to follow; `fail` forgot it): the same frame from the
            // cold start. A cold solve never diverges with `cold_start` false.
            if !sol.cold_start && sol.status == PoseStatus::Diverged {
                continue;
            }
            // A near-field solve that fails from the cold start (steep tilts near the target,
            // where the homography's pinhole pose puts beacons where the model has no
            // gradient): the pinhole model (eq 65, smooth everywhere in front) from the same
            // start first, then the near-field model from its answer.
            if sol.cold_start
                && pinhole_pass == 0
                && matches!(
                    sol.status,
                    PoseStatus::Diverged | PoseStatus::IllConditioned
                )
                && self.emulator.is_some()
            {
                pinhole_pass = 1;
                continue;
            }
            if sol.magnitudes == 0
                || (sol.status == PoseStatus::Ok
                    && sol.rms * sol.rms <= limit * limit * self.noise2)
            {
                return sol;
            }
            self.warm = warm;
            self.carry = None;
            // The spots' rows alone: the key without the magnitudes' bits.
            key = key.map(|k| k & ((1u64 << (2 * MAX_BEACONS)) - 1));
            magnitudes = false;
        }
    }

    /// One solve (see [`Self::solve_keyed`]), with the magnitudes when `magnitudes`, from the
    /// warm start or, without one, the cold start. The last solve's linearisation serves the
    /// first step when the warm start is in use and the key is the same: no model evaluation
    /// when the warm start is that solve's answer, else one pass without the Jacobian. Too
    /// few beacons forget the warm start: the target was lost, and the next frame with
    /// enough starts cold (at any attitude) rather than from where it was.
    // Never inlined: on the chip its frame (the solve's matrices) is its own, not added to
    // the caller's (the board's reply being built).
    #[inline(never)]
    fn solve_once(
        &mut self,
        obs: &[Obs<T>],
        key: Option<u64>,
        magnitudes: bool,
    ) -> PoseSolution<T> {
        // The carried linearisation serves only a warm start on the same beacons. It is
        // handed to the solver in place (a copy would be another 400 bytes of stack).
        if !(self.warm.is_some() && key == Some(self.carry_key)) {
            self.carry = None;
        }
        let fallback = self.warm.unwrap_or_else(SVector::zeros);
        let n = obs.len() as u8;
        let rows: usize = obs.iter().map(|o| o.rows()).sum();
        if obs.len() < MIN_BEACONS || rows < 2 * MIN_BEACONS {
            return self.fail(PoseStatus::TooFewBeacons, fallback, n, 0, false);
        }
        let (x0, cold) = match self.warm {
            Some(x) => (x, false),
            None => match self.cold_start(obs) {
                Some(x) => (x, true),
                None => return failed(PoseStatus::Diverged, fallback, n, 0, true),
            },
        };
        let eps = T::default_epsilon();
        // The limits in T: no double-precision arithmetic (a soft-float library of its own)
        // on the chip.
        let (max_condition, max_rms) = (self.max_condition, self.max_rms);
        let settings = Settings {
            max_iter: self.settings.max_iter,
            step_tol: eps.sqrt() * T::lit(0.1),
            cost_tol: eps.sqrt() * T::lit(0.01),
            weights_absolute: false,
            rank_tol: T::one() / (max_condition * max_condition),
            max_damping: 12,
            // The weights are 1, so sum r^2 / noise^2 is chi-square: a step worth less than
            // 0.01 of it is far below the noise and not worth another pass.
            cost_abs_tol: T::lit(0.01) * self.noise2,
            // A last step worth less than 0.1 of chi-square (0.3 standard deviations) is
            // taken as predicted, without another pass.
            final_step_tol: T::lit(0.1) * self.noise2,
            // The condition is compared with max_condition: its cheap upper bound is enough
            // (conservative by at most sqrt(6)) and saves eigen iterations on the chip.
            exact_condition: false,
            // Analytic Jacobians and a warm start: trial steps are almost always accepted.
            jacobian_in_trial: true,
        };
        let problem = PoseProblem {
            lin: &self.lin,
            emulator: self.emulator.as_ref().filter(|_| !self.pinhole_pass),
            boresight: self.boresight,
            obs,
            magnitudes,
        };
        let result = glsdc::solve_with(&problem, x0, &settings, &mut self.rows, &mut self.carry);
        match key {
            Some(k) => self.carry_key = k,
            None => self.carry = None,
        }
        match result {
            Ok(sol) => {
                let x = canonical(sol.x);
                // The plausibility gate: a range beyond the constellation's far limit, or a
                // position 1-sigma over `max_sigma_fraction` of the range (the norms; the
                // range bounded above by `|t|` plus the centroid's offset), is never Ok.
                // Written so that a NaN sigma fails it; the square root only when `|t|`
                // alone does not pass it.
                let range2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
                let sigma2 = sol.sigma[0] * sol.sigma[0]
                    + sol.sigma[1] * sol.sigma[1]
                    + sol.sigma[2] * sol.sigma[2];
                let f2 = self.max_sigma_fraction2;
                let c = self.centroid_offset;
                let determined = sigma2 <= f2 * range2
                    || (c > T::zero() && {
                        let r = range2.sqrt() + c;
                        sigma2 <= f2 * r * r
                    });
                let status = if !x.iter().all(|v| v.is_finite()) {
                    return self.fail(PoseStatus::Diverged, x0, n, sol.iterations, cold);
                } else if !self.in_front(&x, obs) || sol.rms > max_rms || range2 > self.max_range2 {
                    return self.fail(PoseStatus::Diverged, x, n, sol.iterations, cold);
                } else if sol.condition > max_condition || !determined {
                    PoseStatus::IllConditioned
                } else {
                    PoseStatus::Ok
                };
                if status == PoseStatus::Ok {
                    self.warm = Some(x);
                }
                let att = |i: usize| deg(T::lit(4.0) * sol.sigma[i]);
                PoseSolution {
                    status,
                    position: Vector3::new(x[0], x[1], x[2]),
                    mrp: Vector3::new(x[3], x[4], x[5]),
                    sigma_position: Vector3::new(sol.sigma[0], sol.sigma[1], sol.sigma[2]),
                    sigma_attitude_deg: Vector3::new(att(3), att(4), att(5)),
                    rms: sol.rms,
                    iterations: sol.iterations.min(255) as u8,
                    beacons: n,
                    magnitudes: problem.magnitudes_fitted(),
                    condition: sol.condition,
                    cold_start: cold,
                    dropped: None,
                }
            }
            Err(glsdc::Error::RankDeficient { x, .. }) => {
                let x = if x.iter().all(|v| v.is_finite()) {
                    x
                } else {
                    x0
                };
                failed(PoseStatus::IllConditioned, canonical(x), n, 0, cold)
            }
            Err(glsdc::Error::NotConverged { x, iterations, .. }) => {
                let x = if x.iter().all(|v| v.is_finite()) {
                    x
                } else {
                    x0
                };
                self.fail(PoseStatus::Diverged, canonical(x), n, iterations, cold)
            }
            Err(_) => self.fail(PoseStatus::Diverged, x0, n, 0, cold),
        }
    }

    fn fail(
        &mut self,
        status: PoseStatus,
        x: SVector<T, 6>,
        n: u8,
        iterations: usize,
        cold: bool,
    ) -> PoseSolution<T> {
        self.warm = None;
        failed(status, x, n, iterations, cold)
    }

    /// Every beacon in front of the head (positive depth along the head's boresight): with
    /// `a` the head's boresight in N (third row of `C(p)`), `a . (t + C(q)^T r_T - d) > 0`,
    /// evaluated as `(C(q) a) . r_T + a . (t - d)`.
    fn in_front(&self, x: &SVector<T, 6>, obs: &[Obs<T>]) -> bool {
        let a = self.head_axis;
        let u = mrp::dcm(&Vector3::new(x[3], x[4], x[5])) * a;
        let d = Vector3::new(self.cal[0], self.cal[1], self.cal[2]);
        let k = a.dot(&(Vector3::new(x[0], x[1], x[2]) - d));
        obs.iter().all(|o| u.dot(&o.r) + k > T::zero())
    }

    /// Predicted `(X, Y)` for a beacon at `r_T` with the target at `x = [t, q]`.
    pub fn predict(&self, x: &SVector<T, 6>, r_t: &Vector3<T>) -> Option<[T; 2]> {
        let (t, ct) = split(x);
        let rn = t + ct * r_t;
        match &self.emulator {
            None => self.lin.eval(&rn).map(|(y, _)| y),
            Some(em) => em.with_boresight(&(ct * self.boresight)).output(&rn),
        }
    }
}

pub(super) fn split<T: Real>(x: &SVector<T, 6>) -> (Vector3<T>, Matrix3<T>) {
    let t = Vector3::new(x[0], x[1], x[2]);
    let ct = mrp::dcm(&Vector3::new(x[3], x[4], x[5])).transpose();
    (t, ct)
}

fn canonical<T: Real>(mut x: SVector<T, 6>) -> SVector<T, 6> {
    let q = mrp::canonical(&Vector3::new(x[3], x[4], x[5]));
    x[3] = q.x;
    x[4] = q.y;
    x[5] = q.z;
    x
}

fn failed<T: Real>(
    status: PoseStatus,
    x: SVector<T, 6>,
    n: u8,
    iterations: usize,
    cold: bool,
) -> PoseSolution<T> {
    let m1 = Vector3::repeat(-T::one());
    PoseSolution {
        status,
        position: Vector3::new(x[0], x[1], x[2]),
        mrp: Vector3::new(x[3], x[4], x[5]),
        sigma_position: m1,
        sigma_attitude_deg: m1,
        rms: -T::one(),
        iterations: iterations.min(255) as u8,
        beacons: n,
        magnitudes: 0,
        condition: T::zero(),
        cold_start: cold,
        dropped: None,
    }
}
