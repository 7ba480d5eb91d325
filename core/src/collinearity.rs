//! The 7-parameter NorthStar collinearity model (thesis eqs 53 and 65) and its analytic
//! Jacobian (eq 66), as a GLSDC problem.
//!
//! `x = [d1 d2 d3 p1 p2 p3 H]^T` (eq 64). With `u = C(p) (r - d)`:
//! `y_x = H u1 / u3`, `y_y = H u2 / u3` (eq 65). Partials (eq 66):
//! - `du/dd = -C`, `du/dp_i = (dC/dp_i)(r - d)`;
//! - `d(H u_a/u3)/dz = H (du_a/dz u3 - u_a du3/dz) / u3^2`, `d(H u_a/u3)/dH = u_a/u3`.

use crate::emulator::Pose;
use crate::glsdc::{ModelError, Problem};
use crate::mrp;
use crate::Real;
use nalgebra::{Matrix3, SVector, Vector3, U7};

/// The parameter vector `[d1 d2 d3 p1 p2 p3 H]` (eq 64).
pub type Params<T> = SVector<T, 7>;

/// Parameter names, in order.
pub const NAMES: [&str; 7] = ["d1", "d2", "d3", "p1", "p2", "p3", "H"];

/// Helpers on [`Params`].
pub trait ParamsExt<T: Real> {
    /// Build from a pose and a scale height.
    fn from_pose(pose: &Pose<T>, h: T) -> Self;
    /// The pose part.
    fn pose(&self) -> Pose<T>;
    /// The scale height `H`.
    fn h(&self) -> T;
}

impl<T: Real> ParamsExt<T> for Params<T> {
    fn from_pose(pose: &Pose<T>, h: T) -> Self {
        Params::from_column_slice(&[
            pose.d.x, pose.d.y, pose.d.z, pose.p.x, pose.p.y, pose.p.z, h,
        ])
    }
    fn pose(&self) -> Pose<T> {
        Pose {
            d: Vector3::new(self[0], self[1], self[2]),
            p: Vector3::new(self[3], self[4], self[5]),
        }
    }
    fn h(&self) -> T {
        self[6]
    }
}

/// Predicted `(y_x, y_y)` in counts for a beacon at `r` (eq 65). `None` when the beacon is
/// not in front of the head (`u3 <= 0`).
pub fn predict<T: Real>(x: &Params<T>, r: &Vector3<T>) -> Option<[T; 2]> {
    let c = mrp::dcm(&Vector3::new(x[3], x[4], x[5]));
    predict_c(&c, x, r)
}

#[inline]
fn predict_c<T: Real>(c: &Matrix3<T>, x: &Params<T>, r: &Vector3<T>) -> Option<[T; 2]> {
    let u = c * (r - Vector3::new(x[0], x[1], x[2]));
    if !(u.z > T::zero()) {
        return None;
    }
    Some([x[6] * u.x / u.z, x[6] * u.y / u.z])
}

/// Precomputed `C(p)` and `dC/dp` for evaluating many beacons at one parameter vector.
#[derive(Debug, Clone, Copy)]
pub struct Linearisation<T: Real> {
    c: Matrix3<T>,
    dc: [Matrix3<T>; 3],
    d: Vector3<T>,
    h: T,
}

impl<T: Real> Linearisation<T> {
    /// Precompute at `x`.
    pub fn new(x: &Params<T>) -> Self {
        let p = Vector3::new(x[3], x[4], x[5]);
        Linearisation {
            c: mrp::dcm(&p),
            dc: mrp::dcm_partials(&p),
            d: Vector3::new(x[0], x[1], x[2]),
            h: x[6],
        }
    }

    /// Prediction and its gradient with respect to the beacon position `r` only:
    /// `dy_a/dr = H (C_a u3 - u_a C_3) / u3^2` (rows of `C`), the negative of eq 66's `d`
    /// columns. Cheaper than [`Self::eval`] when the calibration is fixed (the pose solver).
    pub fn eval_dr(&self, r: &Vector3<T>) -> Option<([T; 2], [Vector3<T>; 2])> {
        let u = self.c * (r - self.d);
        if !(u.z > T::zero()) {
            return None;
        }
        let inv = T::one() / u.z;
        let k = self.h * inv * inv;
        let c3 = self.c.row(2).transpose();
        let g = |a: usize| (self.c.row(a).transpose() * u.z - c3 * u[a]) * k;
        Some(([self.h * u.x * inv, self.h * u.y * inv], [g(0), g(1)]))
    }

    /// Prediction and the two Jacobian rows (eq 66) for a beacon at `r`.
    pub fn eval(&self, r: &Vector3<T>) -> Option<([T; 2], [[T; 7]; 2])> {
        let b = r - self.d;
        let u = self.c * b;
        if !(u.z > T::zero()) {
            return None;
        }
        let h = self.h;
        let inv = T::one() / u.z;
        let y = [h * u.x * inv, h * u.y * inv];
        let mut jac = [[T::zero(); 7]; 2];
        // du/dz_j for j = d1..d3 (-C columns) and p1..p3.
        let mut du = [Vector3::zeros(); 6];
        for j in 0..3 {
            du[j] = -self.c.column(j);
            du[3 + j] = self.dc[j] * b;
        }
        let h_inv2 = h * inv * inv;
        for j in 0..6 {
            jac[0][j] = h_inv2 * (du[j].x * u.z - u.x * du[j].z);
            jac[1][j] = h_inv2 * (du[j].y * u.z - u.y * du[j].z);
        }
        jac[0][6] = u.x * inv;
        jac[1][6] = u.y * inv;
        Some((y, jac))
    }
}

/// One measurement: a beacon at `r` (N, inches), the NorthStar output `y` (counts), and the
/// weights of the two residuals (the diagonal of eq 56's `W`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obs<T: Real> {
    /// Beacon position, N, inches.
    pub r: Vector3<T>,
    /// Measured `(X, Y)`, counts.
    pub y: [T; 2],
    /// Weights of the X and Y residuals.
    pub w: [T; 2],
}

/// The Ch V calibration problem: fit eq 65 to a set of observations.
pub struct Fit<'a, T: Real> {
    /// The observations.
    pub obs: &'a [Obs<T>],
}

impl<T: Real> Problem<T> for Fit<'_, T> {
    type D = U7;
    fn dim(&self) -> U7 {
        U7
    }
    fn n_rows(&self) -> usize {
        2 * self.obs.len()
    }
    fn rows(
        &self,
        x: &Params<T>,
        jac: bool,
        sink: &mut dyn FnMut(T, T, &[T]),
    ) -> Result<(), ModelError> {
        let lin = Linearisation::new(x);
        for o in self.obs {
            if jac {
                let (y, j) = lin.eval(&o.r).ok_or(ModelError::NonFinite)?;
                sink(o.y[0] - y[0], o.w[0], &j[0]);
                sink(o.y[1] - y[1], o.w[1], &j[1]);
            } else {
                let y = predict_c(&lin.c, x, &o.r).ok_or(ModelError::NonFinite)?;
                sink(o.y[0] - y[0], o.w[0], &[]);
                sink(o.y[1] - y[1], o.w[1], &[]);
            }
        }
        Ok(())
    }
    fn param_name(&self, i: usize, w: &mut dyn core::fmt::Write) -> core::fmt::Result {
        w.write_str(NAMES[i])
    }
}

/// The direction to a beacon estimated from a measurement, eq 67:
/// `b_est = C^T [X, Y, H]^T` (N components, not unit length).
pub fn estimated_direction<T: Real>(x: &Params<T>, y: [T; 2]) -> Vector3<T> {
    let c = mrp::dcm(&Vector3::new(x[3], x[4], x[5]));
    c.transpose() * Vector3::new(y[0], y[1], x[6])
}

/// Error in angle (radians) between the direction estimated from `y` through the fitted
/// model `x` (eq 67) and the true direction `r - d_true` from the head to the beacon (the
/// quantity whose spread is Figure 57).
pub fn angle_error<T: Real>(x: &Params<T>, y: [T; 2], r: &Vector3<T>, d_true: &Vector3<T>) -> T {
    let est = estimated_direction(x, y);
    let truth = r - d_true;
    // atan2(|a x b|, a . b): accurate for small angles.
    est.cross(&truth).norm().atan2(est.dot(&truth))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::emulator::{grid_position, Effects, Emulator, Head};
    use crate::glsdc::{self, Error, Settings};

    /// The parameter vector's order (eq 64) and its pose and `H` back.
    #[test]
    fn params_order_and_round_trip() {
        let pose = Pose {
            d: Vector3::new(0.6, 0.1, 0.062),
            p: Vector3::new(0.001, -0.002, 0.003),
        };
        let x = Params::<f64>::from_pose(&pose, 18918.6);
        assert_eq!(
            x.as_slice(),
            &[0.6, 0.1, 0.062, 0.001, -0.002, 0.003, 18918.6]
        );
        assert_eq!(x.pose(), pose);
        assert_eq!(x.h(), 18918.6);
    }

    /// Eq 65 by hand, level head (`C = I`) at the origin, `H = 100`: a beacon at `(1, 2, 4)`
    /// is seen at `(100 / 4, 200 / 4) = (25, 50)`; moving the head to `d = (1, 0, 0)` puts it
    /// at `(0, 50)`. A beacon level with the head (`u3 = 0`) or behind it is not seen.
    #[test]
    fn eq65_by_hand() {
        let x = Params::<f64>::from_column_slice(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 100.0]);
        let r = Vector3::new(1.0, 2.0, 4.0);
        assert_eq!(predict(&x, &r), Some([25.0, 50.0]));
        let lin = Linearisation::new(&x);
        assert_eq!(lin.eval(&r).unwrap().0, [25.0, 50.0]);
        assert_eq!(lin.eval_dr(&r).unwrap().0, [25.0, 50.0]);
        // dy/dH = u_a / u3; dy_x/dd1 = -H / u3 (the beacon moves the other way).
        let (_, j) = lin.eval(&r).unwrap();
        assert_eq!((j[0][6], j[1][6]), (0.25, 0.5));
        assert_eq!((j[0][0], j[1][0]), (-25.0, 0.0));
        let mut moved = x;
        moved[0] = 1.0;
        assert_eq!(predict(&moved, &r), Some([0.0, 50.0]));
        for r in [Vector3::new(1.0, 2.0, 0.0), Vector3::new(1.0, 2.0, -4.0)] {
            assert_eq!(predict(&x, &r), None);
            assert!(lin.eval(&r).is_none() && lin.eval_dr(&r).is_none());
        }
    }

    /// The fit's residuals are measured minus predicted (eq 56), each with its weight, two
    /// rows per observation, the Jacobian rows those of eq 66.
    #[test]
    fn fit_rows_are_measured_minus_predicted() {
        let x = Params::<f64>::from_column_slice(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 100.0]);
        let obs = [
            Obs {
                r: Vector3::new(1.0, 2.0, 4.0),
                y: [30.0, 40.0],
                w: [2.0, 3.0],
            },
            Obs {
                r: Vector3::new(-2.0, 1.0, 5.0),
                y: [-40.0, 20.0],
                w: [1.0, 0.5],
            },
            Obs {
                r: Vector3::new(0.0, 0.0, 2.0),
                y: [1.0, -1.0],
                w: [4.0, 5.0],
            },
        ];
        let fit = Fit { obs: &obs };
        // Three observations: 2 * 3, not 2 + 3 (equal for two).
        assert_eq!(fit.n_rows(), 6);
        for jac in [false, true] {
            let mut rows = std::vec::Vec::new();
            fit.rows(&x, jac, &mut |r, w, j| rows.push((r, w, j.to_vec())))
                .unwrap();
            let want = [
                (5.0, 2.0),
                (-10.0, 3.0),
                (0.0, 1.0),
                (0.0, 0.5),
                (1.0, 4.0),
                (-1.0, 5.0),
            ];
            assert_eq!(rows.len(), 6);
            for (k, (r, w, j)) in rows.iter().enumerate() {
                assert_eq!((*r, *w), want[k], "row {k}");
                assert_eq!(j.len(), if jac { 7 } else { 0 });
            }
            if jac {
                let (_, j) = Linearisation::new(&x).eval(&obs[1].r).unwrap();
                assert_eq!(rows[3].2, j[1].to_vec());
            }
        }
        let behind = [Obs {
            r: Vector3::new(0.0, 0.0, -1.0),
            y: [0.0; 2],
            w: [1.0; 2],
        }];
        for jac in [false, true] {
            let e = Fit { obs: &behind }.rows(&x, jac, &mut |_, _, _| {});
            assert_eq!(e, Err(ModelError::NonFinite));
        }
        let mut name = heapless::String::<8>::new();
        fit.param_name(6, &mut name).unwrap();
        fit.param_name(3, &mut name).unwrap();
        assert_eq!(name, "Hp1");
    }

    /// Eq 67 by hand: level, `b_est = (X, Y, H)`, and `(H, 0)` is 45 deg off the boresight.
    /// The head turned +90 deg about z (its x axis along +y of N): `b_est = C^T (X, Y, H)`
    /// is `(0, H, H)` for `(H, 0)`, which a beacon at `(0, 5, 5)` from the head has exactly.
    #[test]
    fn eq67_by_hand() {
        let h = 100.0;
        let level = Params::<f64>::from_column_slice(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, h]);
        assert_eq!(
            estimated_direction(&level, [3.0, -4.0]),
            Vector3::new(3.0, -4.0, h)
        );
        let d = Vector3::new(1.0, 1.0, 0.0);
        let e = angle_error(&level, [h, 0.0], &Vector3::new(1.0, 1.0, 10.0), &d);
        assert!((e - core::f64::consts::FRAC_PI_4).abs() < 1e-15, "{e}");
        let p = mrp::from_axis_angle(&Vector3::z(), core::f64::consts::FRAC_PI_2);
        let turned = Params::from_column_slice(&[0.0, 0.0, 0.0, p.x, p.y, p.z, h]);
        let est = estimated_direction(&turned, [h, 0.0]);
        assert!((est - Vector3::new(0.0, h, h)).norm() < 1e-12, "{est:?}");
        let e = angle_error(&turned, [h, 0.0], &Vector3::new(1.0, 6.0, 5.0), &d);
        assert!(e.abs() < 1e-15, "{e}");
        let e = angle_error(&turned, [0.0, h], &Vector3::new(1.0, 6.0, 5.0), &d);
        assert!((e - core::f64::consts::FRAC_PI_3).abs() < 1e-12, "{e}");
    }

    #[test]
    fn eval_dr_is_minus_the_d_columns() {
        let x = Params::<f64>::from_column_slice(&[0.6, 0.1, 0.062, 0.01, -0.02, 0.03, 18918.6]);
        let lin = Linearisation::new(&x);
        let r = Vector3::new(1.0, 2.0, 5.0);
        let (y, j) = lin.eval(&r).unwrap();
        let (y2, g) = lin.eval_dr(&r).unwrap();
        assert_eq!(y, y2);
        for a in 0..2 {
            for k in 0..3 {
                assert!((g[a][k] + j[a][k]).abs() < 1e-9 * (1.0 + j[a][k].abs()));
            }
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let x = Params::<f64>::from_column_slice(&[0.6, 0.1, 0.062, 0.01, -0.02, 0.03, 18918.6]);
        let lin = Linearisation::new(&x);
        for r in [Vector3::new(1.0, 2.0, 5.0), Vector3::new(-3.0, 4.0, 12.0)] {
            let (_, j) = lin.eval(&r).unwrap();
            for k in 0..7 {
                let h = if k == 6 { 1e-3 } else { 1e-7 };
                let mut xp = x;
                xp[k] += h;
                let mut xm = x;
                xm[k] -= h;
                let yp = predict(&xp, &r).unwrap();
                let ym = predict(&xm, &r).unwrap();
                for a in 0..2 {
                    let fd = (yp[a] - ym[a]) / (2.0 * h);
                    assert!(
                        (fd - j[a][k]).abs() <= 1e-5 * (1.0 + fd.abs()),
                        "d{a}/d{} {fd} vs {}",
                        NAMES[k],
                        j[a][k]
                    );
                }
            }
        }
    }

    /// Hard check: GLSDC recovers the true parameters from noise-free far-field data.
    #[test]
    fn glsdc_recovers_truth_from_far_field_data() {
        let head = Head::<f64>::northstar();
        let pose = Pose::table3();
        let em = Emulator::new(head, pose, Effects::far_field());
        let mut obs = [Obs {
            r: Vector3::zeros(),
            y: [0.0; 2],
            w: [1.0; 2],
        }; 200];
        for (k, sep) in [20.0, 25.0].iter().enumerate() {
            for i in 0..100 {
                let r = grid_position(10, 1.0, *sep, i);
                obs[k * 100 + i] = Obs {
                    r,
                    y: em.output(&r).unwrap(),
                    w: [1.0; 2],
                };
            }
        }
        let truth = Params::from_pose(&pose, head.h());
        let x0 = Params::from_column_slice(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, head.h()]);
        let s = glsdc::solve(&Fit { obs: &obs }, x0, &Settings::default()).unwrap();
        for k in 0..7 {
            assert!(
                (s.x[k] - truth[k]).abs() <= 1e-9 * truth[k].abs(),
                "{} {} vs {}",
                NAMES[k],
                s.x[k],
                truth[k]
            );
        }
    }

    #[test]
    fn one_separation_names_d3_and_h() {
        let head = Head::<f64>::northstar();
        let pose = Pose {
            d: Vector3::new(0.6, 0.1, 0.062),
            p: Vector3::zeros(),
        };
        let em = Emulator::new(head, pose, Effects::far_field());
        let obs: [Obs<f64>; 100] = core::array::from_fn(|i| {
            let r = grid_position(10, 1.0, 20.0, i);
            Obs {
                r,
                y: em.output(&r).unwrap(),
                w: [1.0; 2],
            }
        });
        let fit = Fit { obs: &obs };
        let x0 = Params::from_column_slice(&[0.5, 0.0, 0.0, 0.0, 0.0, 0.0, head.h()]);
        match glsdc::solve(&fit, x0, &Settings::default()) {
            Err(Error::RankDeficient { x, null, .. }) => {
                assert!(x.iter().all(|v| v.is_finite()));
                let mut s = heapless::String::<64>::new();
                glsdc::describe_null(&fit, &null, &mut s).unwrap();
                assert!(s.contains("d3") && s.contains("H"), "{s}");
            }
            other => panic!("expected rank deficiency, got {other:?}"),
        }
    }
}
