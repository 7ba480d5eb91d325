//! The pose noise floor (`cta sensor floor`): the noise floor of one frame's pose, from the
//! spots alone and with the NorthStar's spot magnitudes as a further measurement, for several
//! magnitude noise levels: how well the magnitudes must repeat for the design target's
//! per-frame attitude claim, which the spots alone cannot meet at 8-10 in. The chip's
//! near-field solve fits the magnitudes when its calibration holds their law
//! (`cta_core::pose::Magnitude`), and reaches this bound (`cta sensor accuracy
//! --magnitude-noise PCT`).
//!
//! The floor is the Cramer-Rao bound: the covariance `(J^T W J)^-1` of the pose at the true
//! pose, `J` the central-difference Jacobian of the measurements through the eq 60-63
//! physics (the emulator that makes the simulated frames), `W` the inverse measurement
//! variances. No unbiased pose from the same measurements can do better. With spots alone
//! it is what the on-chip near-field solver predicts as its 1-sigma (tested).
//!
//! The magnitude model is an assumption, not a measurement: the reported magnitude is
//! `k * (sum of the four cell signals)` (the emulator's [`Emulator::magnitude`], falling as
//! the inverse square of the range and with the beacon and cell angles), with `k` the same
//! for every beacon and unknown (estimated with the pose, so only ratios between beacons
//! count), and Gaussian noise of a fixed fraction of the magnitude. The NorthStar's real
//! magnitude output (its law, linearity and noise) is not public and has not been measured;
//! the CTA sweep records it for every LED and separation (`magnitude` column), which is what
//! would settle it. LEDs of unequal brightness would need a per-LED calibration from that
//! sweep.
//!
//! Which magnitude noise? If the spot noise comes from independent noise `sigma_c` in the four
//! cell signals, then near the boresight (`X = beta (a - b)/(a + b)` with `a = b = S`)
//! `sigma_X = beta sigma_c / (sqrt 2 S)`, and the magnitude `M = 4 S` has
//! `sigma_M / M = sigma_c / (2 S) = sigma_X / (sqrt 2 beta)`: 0.07 % for the 0.1 % of beta
//! spot noise. LED flicker and drift cancel in `X, Y` (ratios) but not in `M`; a common
//! drift is absorbed by `k`, a per-LED one is not. Hence the range of levels tried.
//!
//! `--monte-carlo N` checks that the bound is reached: N noisy frames per pose solved by
//! GLSDC (f64, central differences; a host prototype, not the chip's solver) with the
//! magnitudes as extra rows.

use cta_core::emulator::Emulator;
use cta_core::glsdc::{self, Settings};
use cta_core::mrp;
use cta_core::pose::{
    Calibration, Constellation, ModelKind, PoseSolver, PoseStatus, SolverSettings,
};
use nalgebra::{DMatrix, DVector, Vector3};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use crate::pose::calibrations::{angle_between_deg, pinhole_calibration, random_pose};
use crate::pose::error::Error;
use crate::pose::limits::{check_noise_fraction, check_ranges};
use crate::pose::plate::{Scene, TestScene};

/// Options of the floor table.
#[derive(Debug, Clone, PartialEq)]
pub struct FloorOptions {
    /// Ranges, inches (each above 0, at most 1000).
    pub ranges: Vec<f64>,
    /// Magnitude noise levels to try, percent of the magnitude (1-sigma, each above 0).
    pub magnitude_noise: Vec<f64>,
    /// Spot noise, fraction of beta (1e-6 to 0.3).
    pub noise_fraction: f64,
    /// Random poses per range; the floors are RMS over them (1 or more).
    pub poses: usize,
    /// Noisy frames per pose solved with the magnitudes, to check the bound is reached.
    pub monte_carlo: usize,
    /// Random seed.
    pub seed: u64,
    /// The target: constellation, plate (of the pinhole calibration sweep), raise.
    pub scene: Scene,
}

impl Default for FloorOptions {
    fn default() -> Self {
        FloorOptions {
            ranges: vec![2.0, 4.0, 6.0, 8.0, 10.0, 15.0, 20.0, 30.0],
            magnitude_noise: vec![0.07, 0.3, 1.0, 3.0],
            noise_fraction: 0.001,
            poses: 20,
            monte_carlo: 0,
            seed: 2010,
            scene: Scene::default(),
        }
    }
}

/// The floor of one measurement set: RMS over the poses of `|1-sigma vector|`.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Floor {
    /// Position, in.
    pub position: f64,
    /// Attitude, deg.
    pub attitude_deg: f64,
}

/// One magnitude-noise level at one range.
#[derive(Debug, Clone, Serialize)]
pub struct WithMagnitude {
    /// Magnitude noise, percent.
    pub noise_percent: f64,
    /// The bound.
    pub floor: Floor,
    /// RMS error reached by the host GLSDC prototype (`--monte-carlo`).
    pub reached: Option<Floor>,
}

/// One range.
#[derive(Debug, Clone, Serialize)]
pub struct FloorRow {
    /// Range, in.
    pub range: f64,
    /// Poses with a bound (at least 4 beacons off the rails and a full-rank information
    /// matrix); the rest are left out of every figure of the row.
    pub poses_used: usize,
    /// Mean beacons used (seen, and off the 16-bit rails).
    pub beacons: f64,
    /// Mean coordinates left out because they sit on the 16-bit rail (a cell in the dark:
    /// `|X|` or `|Y|` = beta).
    pub railed: f64,
    /// Spots only (what the chip's solver uses).
    pub spots: Floor,
    /// The near-field solver's own 1-sigma on the noise-free frames, before its scaling by
    /// the residual variance (the check that `spots` is the bound the solver sits on).
    pub solver_predicted: Floor,
    /// Frames whose near-field solve was not Ok (left out of `solver_predicted`).
    pub solver_not_ok: usize,
    /// The pinhole pose's systematic attitude error (noise-free frames, Table 3 (25, 30)
    /// calibration), deg.
    pub pinhole_systematic_deg: f64,
    /// The attitude floor a pose must reach for the pinhole pose to be >= 5x worse per frame:
    /// `pinhole_systematic / sqrt(24)` (pinhole per frame >= sqrt(sys^2 + floor^2)), deg.
    pub needed_for_5x_deg: f64,
    /// The best one-frame attitude ratio pinhole / near-field that a pose from the spots
    /// alone can show here: `sqrt(1 + (pinhole_systematic / spots floor)^2)` (a pose on the
    /// floor against a pinhole pose with that systematic error and the same noise).
    pub best_ratio_spots: f64,
    /// With magnitudes, per noise level.
    pub with_magnitude: Vec<WithMagnitude>,
}

/// The result of `cta sensor floor`.
#[derive(Debug, Clone, Serialize)]
pub struct FloorTable {
    /// Rows by range.
    pub rows: Vec<FloorRow>,
    /// Spot noise, counts.
    pub noise_counts: f64,
    /// Poses per range.
    pub poses: usize,
    /// Noisy frames per pose solved with magnitudes.
    pub monte_carlo: usize,
    /// The constellation.
    pub constellation: String,
    /// The constellation, short (plot title).
    pub constellation_short: String,
}

/// The measurements of one frame as a function of the pose: for each beacon of `visible`,
/// `[X, Y]` (counts, eq 63) and the magnitude `exp(lk) * sum of cell signals`. Parameters:
/// `t` (3, in), MRP `q` (3, additive as in the pose solver), `lk`.
struct Frames<'a> {
    em: &'a Emulator<f64>,
    con: &'a Constellation,
}

impl Frames<'_> {
    fn frame(&self, x: &[f64], visible: Option<&[usize]>) -> Option<Vec<(usize, [f64; 3])>> {
        let t = Vector3::new(x[0], x[1], x[2]);
        let q = Vector3::new(x[3], x[4], x[5]);
        let k = x.get(6).copied().unwrap_or(0.0).exp();
        let ct = mrp::dcm(&q).transpose();
        let b = self.con.boresight;
        let bore = Vector3::new(b[0] as f64, b[1] as f64, b[2] as f64).normalize();
        let em = self.em.with_boresight(&(ct * bore));
        let mut out = Vec::new();
        for (i, beacon) in self.con.beacons.iter().enumerate() {
            if let Some(v) = visible {
                if !v.contains(&i) {
                    continue;
                }
            }
            let r = Vector3::new(beacon.r[0] as f64, beacon.r[1] as f64, beacon.r[2] as f64);
            let rn = t + ct * r;
            match em.output(&rn) {
                Some(y) => out.push((i, [y[0], y[1], k * em.magnitude(&rn)])),
                // A beacon of the visible set that vanished under a perturbation: the
                // Jacobian is not defined there.
                None if visible.is_some() => return None,
                None => {}
            }
        }
        Some(out)
    }
}

/// The design target's per-frame claim covers 2-10 in.
pub const CLAIM_RANGE: f64 = 10.0;

const STEP: [f64; 7] = [1e-6, 1e-6, 1e-6, 1e-7, 1e-7, 1e-7, 1e-7];

/// A pose fit to one frame (spots, and the magnitudes when `mag_sigma` is set).
struct PoseFit<'a> {
    frames: &'a Frames<'a>,
    visible: &'a [usize],
    /// Which of `X, Y` are used per visible beacon (`false`: on the 16-bit rail, as the
    /// solver's `match_spots` decides).
    used: &'a [[bool; 2]],
    /// Measured `[X, Y, magnitude]` per visible beacon.
    y: &'a [[f64; 3]],
    /// Spot noise, counts.
    sigma: f64,
    /// Magnitude noise as a fraction of each beacon's true magnitude (`None`: spots only).
    mag_sigma: Option<&'a [f64]>,
}

impl glsdc::Problem<f64> for PoseFit<'_> {
    type D = nalgebra::Dyn;
    fn dim(&self) -> nalgebra::Dyn {
        nalgebra::Dyn(if self.mag_sigma.is_some() { 7 } else { 6 })
    }
    fn n_rows(&self) -> usize {
        let spots: usize = self
            .used
            .iter()
            .map(|u| usize::from(u[0]) + usize::from(u[1]))
            .sum();
        spots
            + if self.mag_sigma.is_some() {
                self.y.len()
            } else {
                0
            }
    }
    fn rows(
        &self,
        x: &DVector<f64>,
        jac: bool,
        sink: &mut dyn FnMut(f64, f64, &[f64]),
    ) -> Result<(), glsdc::ModelError> {
        let n = x.len();
        let eval = |x: &[f64]| {
            self.frames
                .frame(x, Some(self.visible))
                .ok_or(glsdc::ModelError::NonFinite)
        };
        let base = eval(x.as_slice())?;
        let mut cols = Vec::new();
        if jac {
            for k in 0..n {
                let (mut a, mut b) = (x.clone(), x.clone());
                a[k] += STEP[k];
                b[k] -= STEP[k];
                cols.push((eval(a.as_slice())?, eval(b.as_slice())?));
            }
        }
        let axes = if self.mag_sigma.is_some() { 3 } else { 2 };
        let mut row = [0.0; 7];
        for (j, (_, p)) in base.iter().enumerate() {
            #[allow(clippy::needless_range_loop)] // the axis of three arrays
            for axis in 0..axes {
                if axis < 2 && !self.used[j][axis] {
                    continue;
                }
                for (k, (a, b)) in cols.iter().enumerate() {
                    row[k] = (a[j].1[axis] - b[j].1[axis]) / (2.0 * STEP[k]);
                }
                let s = match (axis, self.mag_sigma) {
                    (2, Some(m)) => m[j],
                    _ => self.sigma,
                };
                let r: &[f64] = if jac { &row[..n] } else { &[] };
                sink(self.y[j][axis] - p[axis], 1.0 / (s * s), r);
            }
        }
        Ok(())
    }
    fn param_name(&self, i: usize, w: &mut dyn std::fmt::Write) -> std::fmt::Result {
        w.write_str(["t1", "t2", "t3", "q1", "q2", "q3", "ln k"][i])
    }
}

/// `(J^T W J)^-1` at `x` for `fit`: the Cramer-Rao covariance.
fn bound(fit: &PoseFit, x: &DVector<f64>) -> Option<DMatrix<f64>> {
    let n = x.len();
    let mut info = DMatrix::<f64>::zeros(n, n);
    glsdc::Problem::rows(fit, x, true, &mut |_, w, row| {
        for a in 0..n {
            for b in 0..n {
                info[(a, b)] += w * row[a] * row[b];
            }
        }
    })
    .ok()?;
    info.cholesky().map(|c| c.inverse())
}

/// Position and attitude `|1-sigma|` of a pose covariance (attitude as the solver reports
/// it: 4 x the MRP sigma, in degrees).
fn floor_of(p: &DMatrix<f64>) -> (f64, f64) {
    let pos = (p[(0, 0)] + p[(1, 1)] + p[(2, 2)]).sqrt();
    let att = 4.0 * (p[(3, 3)] + p[(4, 4)] + p[(5, 5)]).sqrt();
    (pos, att.to_degrees())
}

impl FloorOptions {
    /// Check every option (with an error naming the option and its allowed range).
    pub fn check(&self) -> Result<(), Error> {
        check_ranges("--ranges", &self.ranges)?;
        for &m in &self.magnitude_noise {
            if !(m > 0.0 && m.is_finite()) {
                return Err(Error::Option(format!(
                    "--magnitude-noise {m}: a level must be a finite percentage above 0"
                )));
            }
        }
        check_noise_fraction(self.noise_fraction)?;
        if self.poses == 0 {
            return Err(Error::Option(
                "--poses 0: expected 1 or more poses per range".into(),
            ));
        }
        Ok(())
    }
}

/// Compute the floor table.
pub fn floor_table(args: &FloorOptions) -> Result<FloorTable, Error> {
    args.check()?;
    floor_table_on(args, args.scene.resolve()?)
}

/// Compute the table on the target `test` (`args.scene` resolved; the caller may show its
/// warnings first).
pub fn floor_table_on(args: &FloorOptions, test: TestScene) -> Result<FloorTable, Error> {
    args.check()?;
    let mut truth = Calibration::table3();
    let noise = args.noise_fraction * cta_core::emulator::BETA;
    truth.noise = noise as f32;
    test.check_ranges(&args.ranges)?;
    let con = test.con;
    let em: Emulator<f64> = cta_firmware_sensor::sim::physics(&truth);
    let frames = Frames { em: &em, con: &con };
    let ph_cal = pinhole_calibration(&truth, test.plate)?;
    // A fresh solver per frame: every solve is a cold start, as in the accuracy table.
    let solver = |cal: &Calibration, model: ModelKind| {
        PoseSolver::<f64>::new(
            cal,
            &con,
            SolverSettings {
                model,
                ..Default::default()
            },
        )
        .map_err(Error::Solver)
    };
    let mut rng = StdRng::seed_from_u64(args.seed);
    // The Monte Carlo noise has its own stream, so the poses are the same with or without it.
    let mut mc_rng = StdRng::seed_from_u64(args.seed ^ 0x5EED_0F4D);
    let unit = Normal::new(0.0, 1.0).map_err(|error| Error::Noise {
        what: "noise",
        error,
    })?;
    let mut rows = Vec::new();
    for &range in &args.ranges {
        let mut seen = 0.0;
        let mut railed = 0.0;
        let mut spots = [0.0f64; 2];
        let mut predicted = [0.0f64; 2];
        let mut ph_sys = 0.0;
        let mut mag = vec![[0.0f64; 2]; args.magnitude_noise.len()];
        let mut reached = vec![[0.0f64; 2]; args.magnitude_noise.len()];
        let mut n_ok = 0usize;
        // Near-field solves of the noisy frames that returned Ok (the others have no sigma).
        let mut n_solved = 0usize;
        for _ in 0..args.poses {
            let (t, q) = random_pose(&mut rng, range);
            let x6 = [t[0], t[1], t[2], q[0], q[1], q[2]];
            let x7 = DVector::from_vec(vec![t[0], t[1], t[2], q[0], q[1], q[2], 0.0]);
            let Some(clean) = frames.frame(x7.as_slice(), None) else {
                continue;
            };
            // Coordinates at the 16-bit rails carry no information: the solver drops them,
            // and a spot with both there.
            let rail = |v: f64| {
                let c = cta_core::emulator::saturate_i16(v);
                c == i16::MAX || c == i16::MIN
            };
            let mut n_railed = 0;
            let mut visible = Vec::new();
            let mut used = Vec::new();
            let mut y = Vec::new();
            for (i, v) in clean {
                let u = [!rail(v[0]), !rail(v[1])];
                n_railed += usize::from(!u[0]) + usize::from(!u[1]);
                if u[0] || u[1] {
                    visible.push(i);
                    used.push(u);
                    y.push(v);
                }
            }
            let rows: usize = used
                .iter()
                .map(|u| usize::from(u[0]) + usize::from(u[1]))
                .sum();
            if visible.len() < 4 || rows < 8 {
                continue;
            }
            let spots_fit = PoseFit {
                frames: &frames,
                visible: &visible,
                used: &used,
                y: &y,
                sigma: noise,
                mag_sigma: None,
            };
            let Some(p) = bound(&spots_fit, &DVector::from_row_slice(&x6)) else {
                continue;
            };
            n_ok += 1;
            seen += visible.len() as f64;
            railed += n_railed as f64;
            let (fp, fa) = floor_of(&p);
            spots[0] += fp * fp;
            spots[1] += fa * fa;
            // The chip's solver (f64 here) on the noise-free frame (rounded to counts): its
            // 1-sigma before the scaling by the residual variance (the solver's own bound at
            // the truth), and the pinhole pose's systematic error.
            let frame = cta_core::pose::simulate_spots(&em, &con, &t, &q, |_| 0.0);
            let s = solver(&truth, ModelKind::NearField)?.solve(&frame);
            if s.status == PoseStatus::Ok && s.rms > 0.0 {
                n_solved += 1;
                // Rows the solver used: its usable coordinates (the same rail rule).
                let m = rows as f64;
                let variance_factor = s.rms * s.rms * m / ((m - 6.0) * noise * noise);
                predicted[0] += s.sigma_position.norm_squared() / variance_factor;
                predicted[1] += s.sigma_attitude_deg.norm_squared() / variance_factor;
            }
            ph_sys +=
                angle_between_deg(&solver(&ph_cal, ModelKind::Pinhole)?.solve(&frame).mrp, &q)
                    .powi(2);
            for (l, &pct) in args.magnitude_noise.iter().enumerate() {
                let msig: Vec<f64> = y.iter().map(|v| v[2] * pct / 100.0).collect();
                let fit = PoseFit {
                    mag_sigma: Some(&msig),
                    ..spots_fit
                };
                let Some(p) = bound(&fit, &x7) else { continue };
                let (fp, fa) = floor_of(&p);
                mag[l][0] += fp * fp;
                mag[l][1] += fa * fa;
                for _ in 0..args.monte_carlo {
                    let noisy: Vec<[f64; 3]> = y
                        .iter()
                        .zip(&msig)
                        .map(|(v, ms)| {
                            [
                                v[0] + noise * unit.sample(&mut mc_rng),
                                v[1] + noise * unit.sample(&mut mc_rng),
                                v[2] + ms * unit.sample(&mut mc_rng),
                            ]
                        })
                        .collect();
                    let fit = PoseFit { y: &noisy, ..fit };
                    let sol = glsdc::solve(&fit, x7.clone(), &Settings::default());
                    let (ep, ea) = match sol {
                        Ok(s) => (
                            (Vector3::new(s.x[0], s.x[1], s.x[2]) - t).norm(),
                            angle_between_deg(&Vector3::new(s.x[3], s.x[4], s.x[5]), &q),
                        ),
                        Err(_) => (f64::NAN, f64::NAN),
                    };
                    reached[l][0] += ep * ep;
                    reached[l][1] += ea * ea;
                }
            }
        }
        let n = n_ok.max(1) as f64;
        let fl = |a: [f64; 2], n: f64| Floor {
            position: (a[0] / n).sqrt(),
            attitude_deg: (a[1] / n).sqrt(),
        };
        let ph_sys = (ph_sys / n).sqrt();
        let mc = (n_ok * args.monte_carlo).max(1) as f64;
        rows.push(FloorRow {
            range,
            beacons: seen / n,
            railed: railed / n,
            poses_used: n_ok,
            spots: fl(spots, n),
            solver_predicted: fl(predicted, n_solved.max(1) as f64),
            solver_not_ok: n_ok - n_solved,
            pinhole_systematic_deg: ph_sys,
            needed_for_5x_deg: ph_sys / 24f64.sqrt(),
            best_ratio_spots: (1.0 + (ph_sys / fl(spots, n).attitude_deg).powi(2)).sqrt(),
            with_magnitude: args
                .magnitude_noise
                .iter()
                .enumerate()
                .map(|(l, &pct)| WithMagnitude {
                    noise_percent: pct,
                    floor: fl(mag[l], n),
                    reached: (args.monte_carlo > 0).then(|| fl(reached[l], mc)),
                })
                .collect(),
        });
    }
    Ok(FloorTable {
        rows,
        noise_counts: noise,
        poses: args.poses,
        monte_carlo: args.monte_carlo,
        constellation: test.label,
        constellation_short: test.short,
    })
}

impl FloorTable {
    /// Draw the floors against range: attitude (with the floor needed for 5x at 2-10 in) and
    /// position.
    pub fn plot(&self, path: &std::path::Path) -> Result<(), Error> {
        use crate::plot::{write_svg, Panel, Series};
        let rows: Vec<&FloorRow> = self.rows.iter().filter(|r| r.poses_used > 0).collect();
        let panel = |att: bool| {
            let get = |f: &Floor| if att { f.attitude_deg } else { f.position };
            let mut series = vec![Series::new(
                "spots only",
                rows.iter().map(|r| (r.range, get(&r.spots))).collect(),
            )];
            if let Some(first) = rows.first() {
                for (l, m) in first.with_magnitude.iter().enumerate() {
                    series.push(Series::new(
                        format!("with magnitudes, {} % noise", m.noise_percent),
                        rows.iter()
                            .map(|r| (r.range, get(&r.with_magnitude[l].floor)))
                            .collect(),
                    ));
                }
            }
            if att {
                series.push(Series::dashed(
                    "needed for 5x over the pinhole (2-10 in)",
                    rows.iter()
                        .filter(|r| r.range <= CLAIM_RANGE)
                        .map(|r| (r.range, r.needed_for_5x_deg))
                        .collect(),
                ));
            }
            Panel {
                title: if att {
                    "attitude floor"
                } else {
                    "position floor"
                }
                .into(),
                x_desc: "range (in)".into(),
                y_desc: if att { "1-sigma (deg)" } else { "1-sigma (in)" }.into(),
                log_x: true,
                log_y: true,
                series,
            }
        };
        write_svg(
            path,
            &format!(
                "Pose noise floor of one frame ({}, spot noise {:.1} counts; magnitude model assumed)",
                self.constellation_short, self.noise_counts
            ),
            &[panel(true), panel(false)],
            2,
        )
        .map_err(Error::Plot)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The spots-only bound is what the pose solver predicts as its 1-sigma (same Jacobian
    /// up to finite differences), and magnitudes can only add information.
    #[test]
    fn spots_bound_matches_the_solver_and_magnitudes_only_help() {
        let args = FloorOptions {
            // 2 in: coordinates on the rail; 3 and 10 in: none.
            ranges: vec![2.0, 3.0, 10.0],
            magnitude_noise: vec![1.0, 1e6],
            poses: 4,
            ..FloorOptions::default()
        };
        let t = floor_table(&args).unwrap();
        for r in &t.rows {
            let rel = |a: f64, b: f64| (a - b).abs() / b;
            assert!(
                rel(r.spots.attitude_deg, r.solver_predicted.attitude_deg) < 0.02,
                "{r:?}"
            );
            assert!(
                rel(r.spots.position, r.solver_predicted.position) < 0.02,
                "{r:?}"
            );
            let (m1, huge) = (&r.with_magnitude[0], &r.with_magnitude[1]);
            assert!(m1.floor.attitude_deg < r.spots.attitude_deg, "{r:?}");
            // Magnitudes with enormous noise carry nothing: back to spots alone.
            assert!(
                rel(huge.floor.attitude_deg, r.spots.attitude_deg) < 0.01,
                "{r:?}"
            );
        }
    }

    /// A range without any usable pose is left out of the plot; the plot has every curve and
    /// the JSON every row.
    #[test]
    fn empty_ranges_plot_and_json() {
        let args = FloorOptions {
            ranges: vec![0.3, 8.0],
            magnitude_noise: vec![0.3],
            poses: 2,
            ..FloorOptions::default()
        };
        let t = floor_table(&args).unwrap();
        assert_eq!(t.rows[0].poses_used, 0);
        let path = std::env::temp_dir().join(format!("cta-floor-{}.svg", std::process::id()));
        t.plot(&path).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        let _ = std::fs::remove_file(&path);
        for label in ["spots only", "0.3 % noise", "needed for 5x"] {
            assert!(svg.contains(label), "{label} missing from the plot");
        }
        let json = serde_json::to_value(&t).unwrap();
        assert_eq!(json["rows"].as_array().unwrap().len(), 2);
    }

    /// What the beacons' spread buys at 10 in, from the spots alone: on one array (one-10)
    /// the best one-frame attitude ratio stays far below 5x; all 19 frequencies over four
    /// arrays (four-19) lift it just above, by shrinking the floor more than the pinhole's
    /// error.
    #[test]
    fn spread_and_channels_lift_the_best_ratio_at_10_in() {
        let run = |c: &str| {
            floor_table(&FloorOptions {
                ranges: vec![10.0],
                magnitude_noise: vec![],
                poses: 20,
                scene: Scene {
                    constellation: Some(c.into()),
                    ..Scene::default()
                },
                ..FloorOptions::default()
            })
            .unwrap()
            .rows[0]
                .clone()
        };
        let (one, four) = (run("one-10"), run("four-19"));
        assert!(one.best_ratio_spots < 2.5, "{one:?}");
        assert!(four.best_ratio_spots > 5.0, "{four:?}");
        assert!(
            four.spots.attitude_deg < one.spots.attitude_deg / 5.0,
            "{four:?} {one:?}"
        );
        assert!(
            four.pinhole_systematic_deg < one.pinhole_systematic_deg,
            "{four:?} {one:?}"
        );
    }

    /// The bound with magnitudes is reached by an actual fit (so the table's figures are
    /// attainable, not an artefact of the Jacobian).
    #[test]
    fn magnitude_bound_is_reached_by_a_fit() {
        let args = FloorOptions {
            ranges: vec![10.0],
            magnitude_noise: vec![1.0],
            poses: 3,
            monte_carlo: 60,
            ..FloorOptions::default()
        };
        let t = floor_table(&args).unwrap();
        let m = &t.rows[0].with_magnitude[0];
        let reached = m.reached.unwrap();
        // 180 draws: the RMS is within ~10 % of the bound at 1 sigma; allow 30 %.
        let q = reached.attitude_deg / m.floor.attitude_deg;
        assert!((0.7..1.3).contains(&q), "{m:?}");
        let q = reached.position / m.floor.position;
        assert!((0.7..1.3).contains(&q), "{m:?}");
    }
}
