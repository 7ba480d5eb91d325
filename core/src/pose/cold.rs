//! The attitude-independent cold start: a closed-form pose from one frame's identified spots,
//! for GLSDC (eqs 56-59) to refine. The beacons of a plate lie in a plane of the target frame
//! (`z` constant in T; a constellation off that plane is taken by its `x, y`), so the pinhole
//! lines of sight (eq 65's `(X/H, Y/H, 1)` in the eye frame O) are a planar homography of
//! the beacons' plate coordinates. Its eight unknowns come from a direct linear transform
//! (DLT: a linear equation per used coordinate, normal equations solved by Cholesky, points
//! and lines of sight centred and scaled first), and its columns give the rotation and the
//! position: `[s r1, s r2, tau]` up to scale, `r1, r2` the plate's axes in O and `tau` its
//! centroid. Any roll about the line of sight, any tilt and offset: no starting attitude is
//! assumed. A plate far away or seen face-on is barely told from its mirror tilt about the
//! line of sight (the perspective that separates them is small); both are ranked by their
//! lines-of-sight residual and the better one starts the solve.

use super::problem::Obs;
use crate::mrp;
use crate::Real;
use nalgebra::{Matrix3, Vector3};

/// Unknowns of the homography with its last element fixed to 1.
const N: usize = 8;

/// A rotation `R` (T components to O components) and the centroid `c` (T) of the spots'
/// beacons with its position `p` in O: a beacon `r_T` is at `R (r_T - c) + p` in O.
#[derive(Debug, Clone, Copy)]
pub(super) struct PlatePose<T: Real> {
    pub(super) rot: Matrix3<T>,
    pub(super) centroid: Vector3<T>,
    pub(super) pos: Vector3<T>,
}

impl<T: Real> PlatePose<T> {
    /// Sum of squared lines-of-sight misfits (tangent units) of the used coordinates of
    /// `obs`; `None` when a beacon would be behind the eye.
    pub(super) fn residual(&self, obs: &[Obs<T>], h: T) -> Option<T> {
        let mut sum = T::zero();
        for o in obs {
            let v = self.rot * (o.r - self.centroid) + self.pos;
            if !(v.z > T::zero()) {
                return None;
            }
            for a in 0..2 {
                if o.used[a] {
                    let e = v[a] / v.z - o.y[a] / h;
                    sum += e * e;
                }
            }
        }
        Some(sum)
    }

    /// The mirror tilt: the plate's normal reflected about the line of sight `l` to its
    /// centroid, `R' = (2 l l^T - I) R diag(-1, -1, 1)`, which projects every plate point
    /// (`z = 0` about the centroid) along `l` where `R` does: the two poses a far or
    /// face-on plate cannot tell apart.
    #[inline(never)]
    pub(super) fn twin(&self) -> Self {
        let l = self.pos.normalize();
        let mut rot = self.rot;
        for k in 0..3 {
            let r = rot.column(k).into_owned();
            let f = r - l * (T::lit(2.0) * l.dot(&r));
            rot.set_column(k, &if k == 2 { -f } else { f });
        }
        PlatePose { rot, ..*self }
    }

    /// The solver's unknowns `[t, q]` for an eye at `d` (N) with DCM `c_p` (N -> O): a
    /// beacon is at `t + C(q)^T r_T` in N, so `C(q) = R^T C_p` and `t = d + C_p^T (p - R c)`.
    #[inline(never)]
    pub(super) fn unknowns(&self, d: &Vector3<T>, c_p: &Matrix3<T>) -> [T; 6] {
        let t = d + c_p.transpose() * (self.pos - self.rot * self.centroid);
        let q = mrp::from_dcm(&(self.rot.transpose() * c_p));
        [t.x, t.y, t.z, q.x, q.y, q.z]
    }
}

/// The plate pose from the homography of the used coordinates of `obs` (pinhole lines of
/// sight `(X/H, Y/H, 1)` in O; a coordinate alone, its other one railed, gives its own
/// equation); `None` with fewer than eight coordinates, beacons all in one line or one spot,
/// or a singular fit.
// Never inlined: its 8 x 8 normal equations live on the stack only before the solve.
#[inline(never)]
pub(super) fn plate_pose<T: Real>(obs: &[Obs<T>], h: T) -> Option<PlatePose<T>> {
    let rows: usize = obs.iter().map(|o| o.rows()).sum();
    if rows < N {
        return None;
    }
    let inv_h = T::one() / h;
    // Means and spreads of the beacons (T; plate coordinates x, y) and of each line-of-sight
    // coordinate over the spots that have it: sums of values and squares.
    let mut c = Vector3::zeros();
    let mut s2 = T::zero();
    // [count, sum, sum of squares] of the lines of sight's x and y.
    let mut l = [[T::zero(); 3]; 2];
    for o in obs {
        c += o.r;
        s2 += o.r.x * o.r.x + o.r.y * o.r.y;
        for a in 0..2 {
            if o.used[a] {
                let u = o.y[a] * inv_h;
                l[a][0] += T::one();
                l[a][1] += u;
                l[a][2] += u * u;
            }
        }
    }
    let inv_n = T::one() / T::lit(obs.len() as f64);
    c *= inv_n;
    let s2 = s2 * inv_n - c.x * c.x - c.y * c.y;
    let mut mean = [T::zero(); 2];
    let mut sa2 = T::zero();
    for a in 0..2 {
        mean[a] = l[a][1] / l[a][0];
        sa2 += l[a][2] / l[a][0] - mean[a] * mean[a];
    }
    if !(s2 > T::zero() && sa2 > T::zero()) {
        return None;
    }
    let (s, sa) = (s2.sqrt(), sa2.sqrt());
    // Normal equations of the DLT rows (normalised: x, y the plate point, a, b the line of
    // sight, all centred and scaled):
    //   [x y 1 0 0 0 -a x -a y] g = a,  [0 0 0 x y 1 -b x -b y] g = b.
    let mut m = [[T::zero(); N]; N];
    let mut v = [T::zero(); N];
    let z = T::zero();
    for o in obs {
        let (x, y) = ((o.r.x - c.x) / s, (o.r.y - c.y) / s);
        for a in 0..2 {
            if o.used[a] {
                let u = (o.y[a] * inv_h - mean[a]) / sa;
                let mut row = [z; N];
                row[3 * a] = x;
                row[3 * a + 1] = y;
                row[3 * a + 2] = T::one();
                row[6] = -u * x;
                row[7] = -u * y;
                rank1(&mut m, &mut v, &row, u);
            }
        }
    }
    let g = solve_spd(&mut m, v)?;
    // Undo the lines of sight' normalisation: row1 = sa g1 + am g3, row2 = sa g2 + bm g3.
    let col = |j: usize| {
        let r3 = if j == 2 { T::one() } else { g[6 + j] };
        Vector3::new(sa * g[j] + mean[0] * r3, sa * g[3 + j] + mean[1] * r3, r3)
    };
    let (g1, g2, g3) = (col(0), col(1), col(2));
    // g1 = k s r1, g2 = k s r2, g3 = k p (the points were scaled by 1/s).
    let (n1, n2) = (g1.norm(), g2.norm());
    let k = (n1 * n2).sqrt();
    if !(k > T::zero()) {
        return None;
    }
    // The nearest orthonormal pair to g1/|g1|, g2/|g2| (symmetric about their bisector).
    let (u1, u2) = (g1 / n1, g2 / n2);
    let (p, q) = (
        (u1 + u2).try_normalize(T::zero())?,
        (u1 - u2).try_normalize(T::zero())?,
    );
    let half = T::lit(core::f64::consts::FRAC_1_SQRT_2);
    let r1 = (p + q) * half;
    let r2 = (p - q) * half;
    let rot = Matrix3::from_columns(&[r1, r2, r1.cross(&r2)]);
    let pos = g3 * (s / k);
    if !(pos.z > T::zero() && pos.iter().all(|v| v.is_finite())) {
        return None;
    }
    Some(PlatePose {
        rot,
        centroid: c,
        pos,
    })
}

/// Add `row^T row` to the lower triangle of `m` and `row rhs` to `v` (its zeros skipped).
// The loops' bound hidden from the optimiser (here and in `solve_spd`): unrolled, the 8 x 8
// updates of soft-float calls would cost the chip over a kilobyte of flash.
#[inline(never)]
fn rank1<T: Real>(m: &mut [[T; N]; N], v: &mut [T; N], row: &[T; N], rhs: T) {
    let n = core::hint::black_box(N);
    for i in 0..n {
        if row[i] == T::zero() {
            continue;
        }
        v[i] += row[i] * rhs;
        for j in 0..=i {
            m[i][j] += row[i] * row[j];
        }
    }
}

/// Solve `M g = v` for symmetric positive definite `M` (lower triangle given) by Cholesky
/// in place; `None` on a non-positive pivot.
#[inline(never)]
fn solve_spd<T: Real>(m: &mut [[T; N]; N], mut v: [T; N]) -> Option<[T; N]> {
    let n = core::hint::black_box(N);
    for j in 0..n {
        let mut d = m[j][j];
        for k in 0..j {
            d -= m[j][k] * m[j][k];
        }
        if !(d > T::zero()) {
            return None;
        }
        let dj = d.sqrt();
        m[j][j] = dj;
        for i in j + 1..n {
            let mut e = m[i][j];
            for k in 0..j {
                e -= m[i][k] * m[j][k];
            }
            m[i][j] = e / dj;
        }
    }
    for i in 0..n {
        for k in 0..i {
            v[i] = v[i] - m[i][k] * v[k];
        }
        v[i] /= m[i][i];
    }
    for i in (0..n).rev() {
        for k in i + 1..n {
            v[i] = v[i] - m[k][i] * v[k];
        }
        v[i] /= m[i][i];
    }
    Some(v)
}
