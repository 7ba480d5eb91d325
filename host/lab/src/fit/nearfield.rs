//! The near-field calibration fit: the eq 60-63 model of the NorthStar (pose `d, p`, face
//! angles, cell offset, cell gains and offsets) fitted to point means by GLSDC (eqs 56-59).
//! `cta calibrate` fits it to a sweep; the pose floor fits it to simulated sweeps.

use cta_core::emulator::{Emulator, Head, Pose as HeadPose};
use cta_core::glsdc::{self, Settings};
use cta_core::pose::{Calibration, NearField};
use nalgebra::{DVector, Vector3};

/// Why the near-field fit failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NearFieldError {
    /// The model has no output for some beacon at the start or at a step of the fit.
    #[error(
        "near-field calibration fit failed: the model has no output for some beacon (both \
         cells of a pair in shadow) at the start or a step of the fit"
    )]
    NoOutput,
    /// The model has no output for any beacon at the start.
    #[error(
        "near-field calibration fit failed: the model has no output for any beacon (every \
         pair in shadow) at the start"
    )]
    NoData,
    /// GLSDC did not converge.
    #[error(
        "near-field calibration fit failed: it did not converge in {iterations} iterations \
         (chi-square {cost:.1})"
    )]
    NotConverged {
        /// Iterations run.
        iterations: usize,
        /// Chi-square reached.
        cost: f64,
    },
    /// The normal matrix is singular: the data cannot tell these parameters apart.
    #[error(
        "near-field calibration fit failed: these data cannot tell {} apart (the normal \
         matrix is singular)",
        names.join(", ")
    )]
    Singular {
        /// The parameters along the unobservable direction, largest first.
        names: Vec<&'static str>,
    },
    /// Fewer residuals than parameters.
    #[error("near-field calibration fit failed: {m} residuals for {n} parameters")]
    TooFewRows {
        /// Residuals.
        m: usize,
        /// Parameters.
        n: usize,
    },
}

/// One point for the near-field fit: a beacon at `r` (N, inches), the mean output `y`
/// (counts) and the weights of its two residuals (inverse variances of the mean).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NfObs {
    /// Beacon position, N, inches.
    pub r: Vector3<f64>,
    /// Measured (mean) `(X, Y)`, counts.
    pub y: [f64; 2],
    /// Weights of the X and Y residuals, 1/counts^2.
    pub w: [f64; 2],
}

/// The eq 60-63 calibration fit: 8 parameters (`d1..3` in, `p1..3` MRP, the face angle `a`
/// in degrees, `s` in), or 13 with the cell gains `gx, gy` ([`NearField::gain`]), offsets
/// `bx, by` (1/in^2, [`NearField::bias`]) and the Y pair's own face angle `ay` (degrees,
/// [`NearField::alpha_y_deg`]; `a` is then the X pair's), central-difference Jacobian, the
/// physics of `base` (its `beta` and beacon pattern) with these parameters.
pub struct NearFieldFit<'a> {
    /// The points.
    pub obs: &'a [NfObs],
    /// The physics whose `beta` and beacon pattern (and, unless fitted, cell gains and
    /// offsets) are held.
    pub base: Emulator<f64>,
    /// Fit the cells' gains and offsets and the Y pair's own face angle too (13
    /// parameters); else one face angle for both pairs.
    pub extended: bool,
}

/// Parameters of the extended [`NearFieldFit`].
pub const NF_PARAMS: usize = 13;

/// Parameter names of [`NearFieldFit`], in order (the first 8 when not extended).
pub const NF_NAMES: [&str; NF_PARAMS] = [
    "d1", "d2", "d3", "p1", "p2", "p3", "a", "s", "gx", "gy", "bx", "by", "ay",
];

impl NearFieldFit<'_> {
    fn n(&self) -> usize {
        if self.extended {
            NF_PARAMS
        } else {
            8
        }
    }

    /// The emulator at parameter vector `x` (8 or 13 values).
    pub fn model(&self, x: &[f64]) -> Emulator<f64> {
        let mut effects = self.base.effects;
        let mut ay = x[6];
        if let [gx, gy, bx, by, a] = x[8..] {
            effects.gain = [1.0 + gx, 1.0, 1.0 + gy, 1.0];
            effects.bias = [bx, 0.0, by, 0.0];
            ay = a;
        }
        Emulator::new(
            Head {
                alpha_x: x[6].to_radians(),
                alpha_y: ay.to_radians(),
                s: x[7],
                ..self.base.head
            },
            HeadPose {
                d: Vector3::new(x[0], x[1], x[2]),
                p: Vector3::new(x[3], x[4], x[5]),
            },
            effects,
        )
    }
}

impl glsdc::Problem<f64> for NearFieldFit<'_> {
    type D = nalgebra::Dyn;
    fn dim(&self) -> nalgebra::Dyn {
        nalgebra::Dyn(self.n())
    }
    fn n_rows(&self) -> usize {
        2 * self.obs.len()
    }
    fn rows(
        &self,
        x: &DVector<f64>,
        jac: bool,
        sink: &mut dyn FnMut(f64, f64, &[f64]),
    ) -> Result<(), glsdc::ModelError> {
        // The offsets' step is small against the signals at 30 in (0.001/in^2).
        const STEP: [f64; NF_PARAMS] = [
            1e-5, 1e-5, 1e-5, 1e-6, 1e-6, 1e-6, 1e-4, 1e-5, 1e-5, 1e-5, 1e-8, 1e-8, 1e-4,
        ];
        let n = self.n();
        let base = self.model(x.as_slice());
        let pert: Vec<(Emulator<f64>, Emulator<f64>)> = if jac {
            (0..n)
                .map(|k| {
                    let mut a = x.clone();
                    let mut b = x.clone();
                    a[k] += STEP[k];
                    b[k] -= STEP[k];
                    (self.model(a.as_slice()), self.model(b.as_slice()))
                })
                .collect()
        } else {
            Vec::new()
        };
        let mut j = [[0.0; NF_PARAMS]; 2];
        for o in self.obs {
            let p = base.output(&o.r).ok_or(glsdc::ModelError::NonFinite)?;
            for (k, (a, b)) in pert.iter().enumerate() {
                let (ya, yb) = (
                    a.output(&o.r).ok_or(glsdc::ModelError::NonFinite)?,
                    b.output(&o.r).ok_or(glsdc::ModelError::NonFinite)?,
                );
                for axis in 0..2 {
                    j[axis][k] = (ya[axis] - yb[axis]) / (2.0 * STEP[k]);
                }
            }
            for axis in 0..2 {
                let row: &[f64] = if jac { &j[axis][..n] } else { &[] };
                sink(o.y[axis] - p[axis], o.w[axis], row);
            }
        }
        Ok(())
    }
    fn param_name(&self, i: usize, w: &mut dyn std::fmt::Write) -> std::fmt::Result {
        w.write_str(NF_NAMES[i])
    }
}

/// A near-field calibration fit.
#[derive(Debug, Clone)]
pub struct NearFieldSolution {
    /// `start` with the fitted `d, p, a, s` (and the cells' gains and offsets and the Y
    /// pair's face angle).
    pub calibration: Calibration,
    /// 1-sigma of `d1..3, p1..3, a (deg), s` (and `gx, gy, bx, by, ay`; 0 when not fitted).
    pub sigma: [f64; NF_PARAMS],
    /// The fitted parameters in f64 (the calibration holds them in f32); when not extended,
    /// `start`'s gains and offsets, and `ay = a`.
    pub x: [f64; NF_PARAMS],
    /// Chi-square per degree of freedom (absolute weights).
    pub chi2_dof: f64,
    /// Iterations.
    pub iterations: usize,
    /// Condition number of the scaled, weighted Jacobian.
    pub condition: f64,
    /// Pairs of fitted parameters whose estimates correlate at [`STRONG_CORRELATION`] or
    /// more in magnitude: `(a, b, rho)`.
    pub correlations: Vec<(String, String, f64)>,
    /// The covariance of the fitted parameters (the first 8 of [`NF_NAMES`], all 13 when
    /// extended), scaled by the residual variance as the 1-sigma are.
    pub covariance: nalgebra::DMatrix<f64>,
}

/// Correlations of fitted parameters from this magnitude on are reported: their 1-sigma
/// alone then mislead (each is known far better once the other is).
pub const STRONG_CORRELATION: f64 = 0.8;

/// Fit `d, p, a, s` (and when `extended` the cells' gains and offsets and the Y pair's own
/// face angle) of the eq 60-63 model to `obs` (weights absolute), starting from `start`'s
/// `d, p` and near-field parameters (nominal when it has none); `start`'s `beta`, beacon
/// pattern, `H`, `noise` and pinhole head ([`Calibration::pinhole`]) are kept. Not extended,
/// both pairs share the face angle.
pub fn fit_near_field(
    obs: &[NfObs],
    start: &Calibration,
    extended: bool,
) -> Result<NearFieldSolution, NearFieldError> {
    let nominal = start.near_field.unwrap_or(NearField::nominal());
    let f = |a: [f32; 3]| a.map(f64::from);
    let (d, p) = (f(start.d), f(start.p));
    let [gx, gy] = nominal.gain.map(f64::from);
    let [bx, by] = nominal.bias.map(f64::from);
    let [ax, ay] = nominal.face_angles_deg().map(f64::from);
    let g = [gx, gy, bx, by, ay];
    let mut x0 = vec![d[0], d[1], d[2], p[0], p[1], p[2], ax, nominal.s as f64];
    if extended {
        x0.extend(g);
    }
    let problem = NearFieldFit {
        obs,
        base: cta_firmware_sensor::sim::physics(start),
        extended,
    };
    let x0 = DVector::from_vec(x0);
    let settings = Settings {
        weights_absolute: true,
        ..Settings::default()
    };
    let sol = glsdc::solve(&problem, x0, &settings).map_err(|e| match e {
        glsdc::Error::Model(glsdc::ModelError::NonFinite) => NearFieldError::NoOutput,
        glsdc::Error::Model(glsdc::ModelError::NoData) => NearFieldError::NoData,
        glsdc::Error::NotConverged {
            cost, iterations, ..
        } => NearFieldError::NotConverged { iterations, cost },
        glsdc::Error::RankDeficient { null, .. } => {
            // The parameters along the unobservable direction, largest first.
            let mut along: Vec<(usize, f64)> = null.iter().map(|v| v.abs()).enumerate().collect();
            along.sort_by(|a, b| b.1.total_cmp(&a.1));
            NearFieldError::Singular {
                names: along
                    .iter()
                    .enumerate()
                    .filter(|(rank, (_, v))| *rank == 0 || *v >= 0.3)
                    .map(|(_, (k, _))| NF_NAMES.get(*k).copied().unwrap_or("?"))
                    .collect(),
            }
        }
        glsdc::Error::TooFewRows { m, n } => NearFieldError::TooFewRows { m, n },
    })?;
    let mut x = [0.0; NF_PARAMS];
    let mut sigma = [0.0; NF_PARAMS];
    x[8..].copy_from_slice(&g);
    for k in 0..sol.x.len() {
        x[k] = sol.x[k];
        sigma[k] = sol.sigma[k];
    }
    if !extended {
        x[12] = x[6];
    }
    let c = |k: usize| x[k] as f32;
    Ok(NearFieldSolution {
        calibration: Calibration {
            d: [c(0), c(1), c(2)],
            p: [c(3), c(4), c(5)],
            near_field: Some(NearField {
                alpha_deg: c(6),
                s: c(7),
                gain: [c(8), c(9)],
                bias: [c(10), c(11)],
                alpha_y_deg: extended.then(|| c(12)),
                ..nominal
            }),
            ..*start
        },
        sigma,
        x,
        chi2_dof: sol.variance_factor,
        iterations: sol.iterations,
        condition: sol.condition,
        correlations: strong_correlations(&sol.covariance),
        covariance: sol.covariance,
    })
}

/// The pairs of [`NF_NAMES`] whose correlation in `cov` is at least [`STRONG_CORRELATION`]
/// in magnitude.
fn strong_correlations(cov: &nalgebra::DMatrix<f64>) -> Vec<(String, String, f64)> {
    let n = cov.nrows();
    let mut out = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            let d = (cov[(i, i)] * cov[(j, j)]).sqrt();
            if !(d > 0.0) {
                continue;
            }
            let rho = cov[(i, j)] / d;
            if rho.abs() >= STRONG_CORRELATION {
                out.push((NF_NAMES[i].to_string(), NF_NAMES[j].to_string(), rho));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Only pairs at or beyond [`STRONG_CORRELATION`] are reported, by name, with their sign;
    /// a zero variance (a parameter not fitted) gives none.
    #[test]
    fn strong_correlations_are_named_with_their_sign() {
        let mut cov = nalgebra::DMatrix::<f64>::identity(NF_PARAMS, NF_PARAMS);
        cov[(0, 0)] = 4.0;
        // d1,p1: -0.95 with d1's variance 4.
        cov[(0, 3)] = -0.95 * 2.0;
        cov[(3, 0)] = -0.95 * 2.0;
        // a,ay: +0.84; s,gx: 0.5 (below the line).
        cov[(6, 12)] = 0.84;
        cov[(12, 6)] = 0.84;
        cov[(7, 8)] = 0.5;
        cov[(8, 7)] = 0.5;
        // by not fitted: variance 0, its covariance with bx ignored.
        cov[(11, 11)] = 0.0;
        cov[(10, 11)] = 0.3;
        cov[(11, 10)] = 0.3;
        let c = strong_correlations(&cov);
        let names: Vec<(&str, &str)> = c.iter().map(|(a, b, _)| (a.as_str(), b.as_str())).collect();
        assert_eq!(names, [("d1", "p1"), ("a", "ay")], "{c:?}");
        assert!((c[0].2 + 0.95).abs() < 1e-12 && (c[1].2 - 0.84).abs() < 1e-12);
    }
}
