//! The pose as a least-squares problem for GLSDC: the matched observations and their rows
//! (residuals and analytic Jacobians, eq 65 or eqs 60-63 through the MRP attitude, eqs
//! 54/55), with the magnitudes' contrast rows.

use super::magnitude::{magnitudes_fitted, Contrasts};
use super::obs::Obs;
#[cfg(test)]
use super::PoseSolver;
use crate::collinearity::Linearisation;
use crate::emulator::Emulator;
use crate::glsdc::{ModelError, Problem};
use crate::mrp;
use crate::Real;
use core::fmt;
use nalgebra::{Matrix3, SVector, Vector3, U6};

/// The pose as a GLSDC problem over `x = [t, q]`.
pub(super) struct PoseProblem<'a, T: Real> {
    pub(super) lin: &'a Linearisation<T>,
    pub(super) emulator: Option<&'a Emulator<T>>,
    pub(super) boresight: Vector3<T>,
    pub(super) obs: &'a [Obs<T>],
    /// Fit the magnitudes the observations carry (near-field model only).
    pub(super) magnitudes: bool,
}

/// The rows of spot `o`'s used coordinates, from the emulator's output `y` and its
/// gradients (see [`PoseProblem::rows`]).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn spot_rows<T: Real>(
    o: &Obs<T>,
    y: &[T; 2],
    dr: &[Vector3<T>; 2],
    de: &[Vector3<T>; 2],
    rho: &Vector3<T>,
    e: &Vector3<T>,
    k: &Matrix3<T>,
    sink: &mut dyn FnMut(T, T, &[T]),
) {
    for a in (0..2).filter(|&a| o.used[a]) {
        let dq = k * (rho.cross(&dr[a]) + e.cross(&de[a]));
        let row = [dr[a].x, dr[a].y, dr[a].z, dq.x, dq.y, dq.z];
        sink(o.y[a] - y[a], T::one(), &row);
    }
}

impl<'a, T: Real> PoseProblem<'a, T> {
    /// The magnitudes fitted (see [`magnitudes_fitted`]; none with the pinhole model).
    pub(super) fn magnitudes_fitted(&self) -> u8 {
        if self.emulator.is_none() || !self.magnitudes {
            return 0;
        }
        magnitudes_fitted(self.obs)
    }

    /// The magnitude rows: one fewer than the magnitudes fitted.
    fn magnitude_rows(&self) -> usize {
        (self.magnitudes_fitted() as usize).saturating_sub(1)
    }

    /// Whether observation `o`'s magnitude is fitted.
    fn fits_magnitude(&self, o: &Obs<T>) -> bool {
        self.magnitudes && o.magnitude_used()
    }

    /// The problem of `obs` with the model of `s` (field by field: the solve keeps the
    /// solver's row store borrowed mutably beside it).
    #[cfg(test)]
    pub(super) fn of(s: &'a PoseSolver<T>, obs: &'a [Obs<T>]) -> Self {
        PoseProblem {
            lin: &s.lin,
            emulator: s.emulator.as_ref(),
            boresight: s.boresight,
            obs,
            magnitudes: true,
        }
    }
}

const NAMES: [&str; 6] = ["t1", "t2", "t3", "q1", "q2", "q3"];

impl<T: Real> Problem<T> for PoseProblem<'_, T> {
    type D = U6;
    fn dim(&self) -> U6 {
        U6
    }
    fn n_rows(&self) -> usize {
        let spots: usize = self.obs.iter().map(|o| o.rows()).sum();
        spots + self.magnitude_rows()
    }
    fn rows(
        &self,
        x: &SVector<T, 6>,
        jac: bool,
        sink: &mut dyn FnMut(T, T, &[T]),
    ) -> Result<(), ModelError> {
        let s = self;
        // Unit weights (see the module documentation).
        let w = T::one();
        let q = Vector3::new(x[3], x[4], x[5]);
        let c = mrp::dcm(&q);
        let ct = c.transpose();
        let t = Vector3::new(x[0], x[1], x[2]);
        // Attitude columns by the chain rule through C(q): for r_N = t + C^T r_T,
        // dy/dq = K ((C^T r_T) x dy/dr) (mrp::gradient_map), and likewise for the boresight.
        let k = if jac {
            mrp::gradient_map(&q, &c)
        } else {
            Matrix3::zeros()
        };
        match s.emulator {
            None => {
                for o in self.obs {
                    let rho = ct * o.r;
                    let (y, g) = s.lin.eval_dr(&(t + rho)).ok_or(ModelError::NonFinite)?;
                    if !jac {
                        for a in (0..2).filter(|&a| o.used[a]) {
                            sink(o.y[a] - y[a], w, &[]);
                        }
                        continue;
                    }
                    for a in (0..2).filter(|&a| o.used[a]) {
                        let dq = k * rho.cross(&g[a]);
                        let row = [g[a].x, g[a].y, g[a].z, dq.x, dq.y, dq.z];
                        sink(o.y[a] - y[a], w, &row);
                    }
                }
            }
            Some(em) => {
                // The LEDs rotate with the target: boresight e_N = C^T(q) e_T.
                let e = ct * s.boresight;
                let em0 = em.with_boresight(&e);
                // The magnitudes' contrasts (see `Contrasts`), in counts as the spots' rows.
                let mut mags = Contrasts::new();
                if !jac {
                    for o in self.obs {
                        let rn = t + ct * o.r;
                        if !self.fits_magnitude(o) {
                            let y = em0.output(&rn).ok_or(ModelError::NoData)?;
                            for a in (0..2).filter(|&a| o.used[a]) {
                                sink(o.y[a] - y[a], w, &[]);
                            }
                            continue;
                        }
                        let (y, m) = em0.output_magnitude(&rn).ok_or(ModelError::NoData)?;
                        for a in (0..2).filter(|&a| o.used[a]) {
                            sink(o.y[a] - y[a], w, &[]);
                        }
                        mags.add(o.mw, o.m - m.ln(), &[], sink);
                    }
                    return Ok(());
                }
                // Analytic chain rule through the emulator's gradients:
                // dy/dt = dy/dr, dy/dq = K (rho x dy/dr + e_N x dy/de), rho = C^T r_T; the
                // magnitude's ln S likewise with d ln S = dS / S.
                for o in self.obs {
                    let rho = ct * o.r;
                    let rn = t + rho;
                    if !self.fits_magnitude(o) {
                        let (y, dr, de) = em0.output_gradient(&rn).ok_or(ModelError::NoData)?;
                        spot_rows(o, &y, &dr, &de, &rho, &e, &k, sink);
                        continue;
                    }
                    let (y, dr, de, (m, dmr, dme)) = em0
                        .output_magnitude_gradient(&rn)
                        .ok_or(ModelError::NoData)?;
                    spot_rows(o, &y, &dr, &de, &rho, &e, &k, sink);
                    let inv = T::one() / m;
                    let (dmr, dme) = (dmr * inv, dme * inv);
                    let dq = k * (rho.cross(&dmr) + e.cross(&dme));
                    let row = [dmr.x, dmr.y, dmr.z, dq.x, dq.y, dq.z];
                    mags.add(o.mw, o.m - m.ln(), &row, sink);
                }
            }
        }
        Ok(())
    }
    fn measurements(&self, sink: &mut dyn FnMut(T, T)) -> bool {
        let mut mags = Contrasts::new();
        for o in self.obs {
            for a in (0..2).filter(|&a| o.used[a]) {
                sink(o.y[a], T::one());
            }
            // The magnitudes' contrasts are linear in the measured m: the same contrasts of
            // the measurements (the model part is what the rows' residuals take off).
            if self.emulator.is_some() && self.fits_magnitude(o) {
                mags.add(o.mw, o.m, &[], &mut |y, w, _| sink(y, w));
            }
        }
        true
    }
    fn param_name(&self, i: usize, w: &mut dyn fmt::Write) -> fmt::Result {
        w.write_str(NAMES[i])
    }
}
