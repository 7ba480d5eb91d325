//! The attitude-independent cold start: a closed-form pose from one frame's identified spots,
//! for GLSDC (eqs 56-59) to refine. The beacons of a plate lie in a plane of the target frame
//! (`z` constant in T; a constellation off that plane is taken by its `x, y`), so the pinhole
//! lines of sight (eq 65's `(X/H, Y/H, 1)` in the eye frame O) are a planar homography of
//! the beacons' plate coordinates. Its eight unknowns come from a direct linear transform
//! (DLT: a linear equation per used coordinate, normal equations solved by Cholesky, points
//! and lines of sight centred and scaled first), and its columns give the rotation and the
//! position: `[s r1, s r2, tau]` up to scale, `r1, r2` the plate's axes in O and `tau` its
//! centroid. Any roll about the line of sight, any tilt and offset: no starting attitude is
//! assumed. (A plate far away or seen face-on is barely told from its mirror tilt about the
//! line of sight; over the CTA envelope, tilts to 30 deg at 2-30 in, starting from that
//! mirror pose when it fitted better changed no acquisition, so the chip does without it.)

use super::obs::Obs;
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
    /// The solver's unknowns `[t, q]` for an eye at `d` (N) with DCM `c_p` (N -> O): a
    /// beacon is at `t + C(q)^T r_T` in N, so `C(q) = R^T C_p` and `t = d + C_p^T (p - R c)`.
    #[inline(never)]
    pub(super) fn unknowns(&self, d: &Vector3<T>, c_p: &Matrix3<T>) -> [T; 6] {
        let t = d + c_p.transpose() * (self.pos - self.rot * self.centroid);
        let q = mrp_of(&(self.rot.transpose() * c_p));
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

/// The MRP (`|p| <= 1`) of a proper orthogonal DCM `c`, as [`crate::mrp::from_dcm`] (Shepperd:
/// the quaternion from the column of `4 q q^T` with the largest diagonal, robust at any
/// angle) in a third of its code on the chip.
pub(super) fn mrp_of<T: Real>(c: &Matrix3<T>) -> Vector3<T> {
    let one = T::one();
    let tr = c.trace();
    // 4 q_k^2: k = 0 the scalar part, then the vector's.
    let d = [
        one + tr,
        one + c[(0, 0)] * T::lit(2.0) - tr,
        one + c[(1, 1)] * T::lit(2.0) - tr,
        one + c[(2, 2)] * T::lit(2.0) - tr,
    ];
    // 4 q0 q_i, and 4 q_i q_j for the pairs (2, 3), (1, 3), (1, 2): index 5 - i - j.
    let a = [
        c[(1, 2)] - c[(2, 1)],
        c[(2, 0)] - c[(0, 2)],
        c[(0, 1)] - c[(1, 0)],
    ];
    let b = [
        c[(1, 2)] + c[(2, 1)],
        c[(2, 0)] + c[(0, 2)],
        c[(0, 1)] + c[(1, 0)],
    ];
    let mut k = 0;
    for i in 1..4 {
        if d[i] > d[k] {
            k = i;
        }
    }
    // Column k of 4 q q^T.
    let mut v = [T::zero(); 4];
    for i in 0..4 {
        v[i] = match (i, k) {
            _ if i == k => d[k],
            (0, _) => a[k - 1],
            (_, 0) => a[i - 1],
            _ => b[5 - i - k],
        };
    }
    // q = v / s with s = 2 sqrt(d_k); p = q_vec / (1 + q0), q0 >= 0.
    let s = d[k].sqrt() * T::lit(2.0);
    let den = if v[0] < T::zero() { v[0] - s } else { v[0] + s };
    Vector3::new(v[1] / den, v[2] / den, v[3] / den)
}

/// Add `row^T row` to the lower triangle of `m` and `row rhs` to `v` (its zeros skipped).
// The loops' bound hidden from the optimiser (here and in `solve_spd`), and the inner loops
// in `dot` and `axpy`: unrolled, the 8 x 8 updates of soft-float calls would cost the chip
// a kilobyte of flash.
#[inline(never)]
fn rank1<T: Real>(m: &mut [[T; N]; N], v: &mut [T; N], row: &[T; N], rhs: T) {
    let n = core::hint::black_box(N);
    for i in 0..n {
        if row[i] == T::zero() {
            continue;
        }
        v[i] += row[i] * rhs;
        axpy(&mut m[i][..=i], row[i], &row[..=i]);
    }
}

/// `a . b` over the shorter of the two.
#[inline(never)]
fn dot<T: Real>(a: &[T], b: &[T]) -> T {
    a.iter().zip(b).fold(T::zero(), |s, (x, y)| s + *x * *y)
}

/// `y += a x` over the shorter of the two.
#[inline(never)]
fn axpy<T: Real>(y: &mut [T], a: T, x: &[T]) {
    for (y, x) in y.iter_mut().zip(x) {
        *y += a * *x;
    }
}

/// Solve `M g = v` for symmetric positive definite `M` (lower triangle given) by Cholesky
/// in place (`M = L L^T`, then `L y = v`, `L^T g = y`); `None` on a non-positive pivot.
#[inline(never)]
fn solve_spd<T: Real>(m: &mut [[T; N]; N], mut v: [T; N]) -> Option<[T; N]> {
    let n = core::hint::black_box(N);
    for j in 0..n {
        let d = m[j][j] - dot(&m[j][..j], &m[j][..j]);
        if !(d > T::zero()) {
            return None;
        }
        let dj = d.sqrt();
        m[j][j] = dj;
        for i in j + 1..n {
            let e = m[i][j] - dot(&m[i][..j], &m[j][..j]);
            m[i][j] = e / dj;
        }
    }
    for i in 0..n {
        v[i] = (v[i] - dot(&m[i][..i], &v[..i])) / m[i][i];
    }
    // L^T by columns: each solved unknown taken off the rows above it.
    for i in (0..n).rev() {
        v[i] /= m[i][i];
        let x = v[i];
        axpy(&mut v[..i], -x, &m[i][..i]);
    }
    Some(v)
}
