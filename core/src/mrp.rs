//! Modified Rodrigues Parameters (MRP) and direction cosine matrices (thesis eqs 54/55,
//! after Schaub & Junkins).
//!
//! Convention (REFERENCE.md section 1): `C = C(p)` maps N-frame components to O-frame
//! components, `v_O = C v_N`. MRPs are `p = e tan(phi/4)` for principal axis `e` and angle
//! `phi`; they are singular only at `phi = 2 pi`. The *shadow set* `-p / |p|^2` describes the
//! same attitude; switching to it whenever `|p| > 1` keeps `|p| <= 1` (`phi <= pi`).

use crate::Real;
use nalgebra::{Matrix3, Vector3};

/// The skew-symmetric cross-product matrix `[p x]` of eq 54.
#[inline]
pub fn skew<T: Real>(p: &Vector3<T>) -> Matrix3<T> {
    let z = T::zero();
    Matrix3::new(z, -p.z, p.y, p.z, z, -p.x, -p.y, p.x, z)
}

/// DCM from MRP, eq 54: `C = I + (8 [p x]^2 - 4 (1 - p^T p) [p x]) / (1 + p^T p)^2`,
/// computed element by element as eq 55.
#[inline]
pub fn dcm<T: Real>(p: &Vector3<T>) -> Matrix3<T> {
    // Eq 55, element by element (a third of the soft-float work of the matrix products of
    // eq 54): over (1 + s)^2, the diagonal 4 (p_i^2 - p_j^2 - p_k^2) + (1 - s)^2, and the
    // off-diagonal 8 p_i p_j +/- 4 p_k (1 - s), with s = p^T p.
    let (p1, p2, p3) = (p.x, p.y, p.z);
    let (q1, q2, q3) = (p1 * p1, p2 * p2, p3 * p3);
    let s = q1 + q2 + q3;
    let one = T::one();
    let (four, eight) = (T::lit(4.0), T::lit(8.0));
    let m = one - s;
    let k = one / ((one + s) * (one + s));
    let m2 = m * m;
    let (a1, a2, a3) = (four * m * p1, four * m * p2, four * m * p3);
    let (b12, b13, b23) = (eight * p1 * p2, eight * p1 * p3, eight * p2 * p3);
    Matrix3::new(
        four * (q1 - q2 - q3) + m2,
        b12 + a3,
        b13 - a2,
        b12 - a3,
        four * (q2 - q1 - q3) + m2,
        b23 + a1,
        b13 + a2,
        b23 - a1,
        four * (q3 - q1 - q2) + m2,
    ) * k
}

/// Partial derivatives `dC/dp_i` (i = 1, 2, 3) of eq 54, for analytic Jacobians (eq 66).
///
/// With `S = [p x]`, `sigma = p^T p`, `a = 1 + sigma` and `E_i = [e_i x]`:
/// `dC/dp_i = (8 (E_i S + S E_i) - 4 (1 - sigma) E_i + 8 p_i S) / a^2
///            - 4 p_i (8 S^2 - 4 (1 - sigma) S) / a^3`.
pub fn dcm_partials<T: Real>(p: &Vector3<T>) -> [Matrix3<T>; 3] {
    let s = skew(p);
    let sig = p.norm_squared();
    let one = T::one();
    let a = one + sig;
    let a2 = a * a;
    let a3 = a2 * a;
    let f = s * s * T::lit(8.0) - s * (T::lit(4.0) * (one - sig));
    let mut out = [Matrix3::zeros(); 3];
    for (i, o) in out.iter_mut().enumerate() {
        let e = skew(&Vector3::ith(i, one));
        let pi = p[i];
        let num = (e * s + s * e) * T::lit(8.0) - e * (T::lit(4.0) * (one - sig))
            + s * (T::lit(8.0) * pi);
        *o = num / a2 - f * (T::lit(4.0) * pi / a3);
    }
    out
}

/// The attitude gradient of a rotated vector in a few products: for `p` with DCM
/// `c = C(p)`, returns `K` such that for any fixed `v` and `u`
/// `d/dp (u . C(p)^T v) = K ((C(p)^T v) x u)`.
///
/// A change `dp` turns the frame by `dtheta = 4 B^T dp / (1 + p^T p)^2` (the MRP kinematics
/// `dp = B dtheta / 4`, `B = (1 - p^T p) I + 2 [p x] + 2 p p^T`, `B^T B = (1 + p^T p)^2 I`),
/// so `d(C^T v) = (C^T dtheta) x (C^T v)` and `K = 4 B C / (1 + p^T p)^2`. The pose
/// solver's Jacobian rows use it in place of the three [`dcm_partials`] products per beacon.
pub fn gradient_map<T: Real>(p: &Vector3<T>, c: &Matrix3<T>) -> Matrix3<T> {
    let (p1, p2, p3) = (p.x, p.y, p.z);
    let sig = p.norm_squared();
    let one = T::one();
    let a = one + sig;
    // f B with f = 4 / (1 + p^T p)^2, element by element.
    let f = T::lit(4.0) / (a * a);
    let (d, t) = (f * (one - sig), f + f);
    let (q1, q2, q3) = (t * p1, t * p2, t * p3);
    let b = Matrix3::new(
        d + q1 * p1,
        q1 * p2 - q3,
        q1 * p3 + q2,
        q1 * p2 + q3,
        d + q2 * p2,
        q2 * p3 - q1,
        q1 * p3 - q2,
        q2 * p3 + q1,
        d + q3 * p3,
    );
    b * c
}

/// MRP from a proper orthogonal DCM (Shepperd-style via the quaternion, robust for every
/// attitude). Returns the set with `|p| <= 1`.
pub fn from_dcm<T: Real>(c: &Matrix3<T>) -> Vector3<T> {
    // Quaternion (q0 scalar) of the rotation whose DCM is C, choosing the largest component.
    let one = T::one();
    let quarter = T::lit(0.25);
    let tr = c[(0, 0)] + c[(1, 1)] + c[(2, 2)];
    let cand = [tr, c[(0, 0)], c[(1, 1)], c[(2, 2)]];
    let mut k = 0;
    for i in 1..4 {
        if cand[i] > cand[k] {
            k = i;
        }
    }
    let (q0, q1, q2, q3);
    match k {
        0 => {
            let s = (one + tr).sqrt() * T::lit(2.0);
            q0 = quarter * s;
            q1 = (c[(1, 2)] - c[(2, 1)]) / s;
            q2 = (c[(2, 0)] - c[(0, 2)]) / s;
            q3 = (c[(0, 1)] - c[(1, 0)]) / s;
        }
        1 => {
            let s = (one + c[(0, 0)] - c[(1, 1)] - c[(2, 2)]).sqrt() * T::lit(2.0);
            q0 = (c[(1, 2)] - c[(2, 1)]) / s;
            q1 = quarter * s;
            q2 = (c[(0, 1)] + c[(1, 0)]) / s;
            q3 = (c[(2, 0)] + c[(0, 2)]) / s;
        }
        2 => {
            let s = (one + c[(1, 1)] - c[(0, 0)] - c[(2, 2)]).sqrt() * T::lit(2.0);
            q0 = (c[(2, 0)] - c[(0, 2)]) / s;
            q1 = (c[(0, 1)] + c[(1, 0)]) / s;
            q2 = quarter * s;
            q3 = (c[(1, 2)] + c[(2, 1)]) / s;
        }
        _ => {
            let s = (one + c[(2, 2)] - c[(0, 0)] - c[(1, 1)]).sqrt() * T::lit(2.0);
            q0 = (c[(0, 1)] - c[(1, 0)]) / s;
            q1 = (c[(2, 0)] + c[(0, 2)]) / s;
            q2 = (c[(1, 2)] + c[(2, 1)]) / s;
            q3 = quarter * s;
        }
    }
    // Choose the hemisphere q0 >= 0 so that |p| <= 1.
    let sign = if q0 < T::zero() { -one } else { one };
    let d = one + q0 * sign;
    Vector3::new(q1 * sign / d, q2 * sign / d, q3 * sign / d)
}

/// The shadow set `-p / |p|^2`: the same attitude, the other side of `|p| = 1`.
#[inline]
pub fn shadow<T: Real>(p: &Vector3<T>) -> Vector3<T> {
    let n2 = p.norm_squared();
    if n2 == T::zero() {
        return *p;
    }
    -*p / n2
}

/// Switch to the shadow set when `|p| > 1`, keeping the principal angle within pi.
#[inline]
pub fn canonical<T: Real>(p: &Vector3<T>) -> Vector3<T> {
    if p.norm_squared() > T::one() {
        shadow(p)
    } else {
        *p
    }
}

/// Composition: the MRP of `C(p2) C(p1)` (first rotate by `p1`, then by `p2`), in the
/// canonical (`|p| <= 1`) set (Schaub & Junkins eq. 3.152).
pub fn compose<T: Real>(p2: &Vector3<T>, p1: &Vector3<T>) -> Vector3<T> {
    let one = T::one();
    let s1 = p1.norm_squared();
    let s2 = p2.norm_squared();
    let den = one + s1 * s2 - T::lit(2.0) * p1.dot(p2);
    if den.abs() < T::lit(1e-6) {
        // Near the 360 deg singularity of the formula: go through the DCM.
        return from_dcm(&(dcm(p2) * dcm(p1)));
    }
    let num = p1 * (one - s2) + p2 * (one - s1) - p2.cross(p1) * T::lit(2.0);
    canonical(&(num / den))
}

/// MRP of a principal rotation by `angle` (radians) about unit `axis`.
#[inline]
pub fn from_axis_angle<T: Real>(axis: &Vector3<T>, angle: T) -> Vector3<T> {
    axis.normalize() * (angle / T::lit(4.0)).tan()
}

/// Principal rotation angle (radians) of an MRP: `phi = 4 atan |p|`.
#[inline]
pub fn angle<T: Real>(p: &Vector3<T>) -> T {
    T::lit(4.0) * p.norm().atan()
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use core::f64::consts::PI;

    #[test]
    fn rotation_about_z_maps_n_to_o() {
        // A frame O rotated +90 deg about z relative to N: the N x axis appears as -y in O.
        let p = from_axis_angle(&Vector3::z(), PI / 2.0);
        let c = dcm(&p);
        let v = c * Vector3::x();
        assert_relative_eq!(v, -Vector3::y(), epsilon = 1e-12);
        assert_relative_eq!(c * Vector3::z(), Vector3::z(), epsilon = 1e-12);
    }

    #[test]
    fn known_rotations_and_orthogonality() {
        for (axis, ang) in [
            (Vector3::x(), 0.3f64),
            (Vector3::new(1.0, 2.0, -0.5), 2.5),
            (Vector3::new(-0.2, 0.1, 1.0), -1.2),
        ] {
            let p = from_axis_angle(&axis, ang);
            let c = dcm(&p);
            assert_relative_eq!(c * c.transpose(), Matrix3::identity(), epsilon = 1e-12);
            assert_relative_eq!(c.determinant(), 1.0, epsilon = 1e-12);
            // Rodrigues' formula for the same frame rotation: C = cos I + (1-cos) e e^T - sin [e x].
            let e = axis.normalize();
            let r = Matrix3::identity() * ang.cos() + e * e.transpose() * (1.0 - ang.cos())
                - skew(&e) * ang.sin();
            assert_relative_eq!(c, r, epsilon = 1e-12);
            assert_relative_eq!(angle(&p), ang.abs(), epsilon = 1e-12);
        }
    }

    #[test]
    fn eq55_element_form_matches_eq54() {
        let p = Vector3::new(0.1f64, -0.2, 0.3);
        let (p1, p2, p3) = (p.x, p.y, p.z);
        let s = p.norm_squared();
        let k = 1.0 / (1.0 + s).powi(2);
        let m = Matrix3::new(
            4.0 * (p1 * p1 - p2 * p2 - p3 * p3) + (1.0 - s).powi(2),
            8.0 * p1 * p2 + 4.0 * p3 * (1.0 - s),
            8.0 * p1 * p3 - 4.0 * p2 * (1.0 - s),
            8.0 * p1 * p2 - 4.0 * p3 * (1.0 - s),
            4.0 * (-p1 * p1 + p2 * p2 - p3 * p3) + (1.0 - s).powi(2),
            8.0 * p2 * p3 + 4.0 * p1 * (1.0 - s),
            8.0 * p1 * p3 + 4.0 * p2 * (1.0 - s),
            8.0 * p2 * p3 - 4.0 * p1 * (1.0 - s),
            4.0 * (-p1 * p1 - p2 * p2 + p3 * p3) + (1.0 - s).powi(2),
        ) * k;
        assert_relative_eq!(dcm(&p), m, epsilon = 1e-14);
        // Eq 54 as printed (matrix form).
        let sk = skew(&p);
        let eq54 =
            Matrix3::identity() + (sk * sk * 8.0 - sk * (4.0 * (1.0 - s))) / (1.0 + s).powi(2);
        assert_relative_eq!(dcm(&p), eq54, epsilon = 1e-14);
    }

    #[test]
    fn round_trip_and_shadow() {
        for p in [
            Vector3::new(0.001, 0.002, 0.001),
            Vector3::new(0.5, -0.4, 0.3),
            Vector3::new(0.0, 0.0, 0.99),
            Vector3::new(-0.7, 0.1, 0.6),
        ] {
            let c = dcm(&p);
            assert_relative_eq!(from_dcm(&c), canonical(&p), epsilon = 1e-10);
            assert_relative_eq!(dcm(&shadow(&p)), c, epsilon = 1e-12);
        }
    }

    /// Near 180 deg the trace is no longer the largest candidate of [`from_dcm`]: the
    /// diagonal element of the dominant axis is (`C_ii = cos phi + (1 - cos phi) e_i^2`), so
    /// rotations of 170-179.9 deg about x, y and z, and about axes mostly along one of them
    /// (then the off-diagonal terms of that branch are not zero), go through each of the
    /// x-, y- and z-dominant branches; small angles through the trace branch.
    #[test]
    fn round_trip_near_180_deg_through_every_branch() {
        let axes = [
            (Vector3::x(), 0),
            (Vector3::y(), 1),
            (Vector3::z(), 2),
            (Vector3::new(1.0, 0.3, -0.2), 0),
            (Vector3::new(-0.25, 1.0, 0.35), 1),
            (Vector3::new(0.3, -0.2, -1.0), 2),
            (Vector3::new(-1.0, -0.4, 0.3), 0),
            (Vector3::new(0.2, -1.0, -0.3), 1),
        ];
        for (axis, dominant) in axes {
            for deg in [170.0f64, 175.0, 178.0, 179.0, 179.9] {
                let p = from_axis_angle(&axis, deg.to_radians());
                assert!(p.norm() < 1.0);
                let c = dcm(&p);
                // The branch this attitude takes: the largest of trace and diagonal.
                let diag = [c[(0, 0)], c[(1, 1)], c[(2, 2)]];
                let tr = diag.iter().sum::<f64>();
                let k = (0..3)
                    .max_by(|&i, &j| diag[i].partial_cmp(&diag[j]).unwrap())
                    .unwrap();
                assert!(k == dominant && diag[k] > tr, "{axis:?} {deg}");
                let q = from_dcm(&c);
                assert_relative_eq!(q, p, epsilon = 1e-12);
                assert_relative_eq!(dcm(&q), c, epsilon = 1e-12);
                // The attitude reversed (the rotation by -phi): the same branch.
                let q = from_dcm(&c.transpose());
                assert_relative_eq!(q, -p, epsilon = 1e-12);
            }
            // The trace branch: a small rotation about the same axis.
            let p = from_axis_angle(&axis, 0.5);
            assert_relative_eq!(from_dcm(&dcm(&p)), p, epsilon = 1e-12);
        }
    }

    /// Exactly 180 deg the quaternion's scalar part is 0 and both `e` and `-e` are MRPs of
    /// unit length for the attitude: [`from_dcm`] returns the one [`canonical`] keeps,
    /// `from_dcm(C(p)) = p` (the `q0 >= 0` hemisphere), about each axis and about `-x`
    /// (the same attitude as about `+x`).
    #[test]
    fn from_dcm_at_exactly_180_deg() {
        for p in [Vector3::<f64>::x(), Vector3::y(), Vector3::z()] {
            assert_eq!(from_dcm(&dcm(&p)), p);
            assert_eq!(from_dcm(&dcm(&-p)), p);
        }
    }

    #[test]
    fn composition_matches_dcm_product() {
        let p1 = Vector3::new(0.2, -0.1, 0.05);
        let p2 = Vector3::new(-0.3, 0.4, 0.6);
        let p = compose(&p2, &p1);
        assert_relative_eq!(dcm(&p), dcm(&p2) * dcm(&p1), epsilon = 1e-12);
        assert!(p.norm() <= 1.0);
    }

    #[test]
    fn partials_match_finite_differences() {
        let p = Vector3::new(0.3, -0.2, 0.1);
        let d = dcm_partials(&p);
        let h = 1e-6;
        for i in 0..3 {
            let mut pp = p;
            pp[i] += h;
            let mut pm = p;
            pm[i] -= h;
            let fd = (dcm(&pp) - dcm(&pm)) / (2.0 * h);
            assert_relative_eq!(d[i], fd, epsilon = 1e-8);
        }
    }

    #[test]
    fn gradient_map_matches_partials() {
        for p in [
            Vector3::new(0.3f64, -0.2, 0.1),
            Vector3::new(-0.7, 0.1, 0.6),
        ] {
            let (c, d) = (dcm(&p), dcm_partials(&p));
            let k = gradient_map(&p, &c);
            let (v, u) = (Vector3::new(1.5, -0.5, 0.2), Vector3::new(-0.3, 2.0, 0.7));
            let g = k * (c.transpose() * v).cross(&u);
            for i in 0..3 {
                assert_relative_eq!(g[i], u.dot(&(d[i].transpose() * v)), epsilon = 1e-12);
            }
        }
    }

    /// The f32 DCM is the f64 one to f32 precision, element by element, at an attitude far
    /// from the identity (46 deg): a transposed (inverse-rotation) or mis-signed DCM differs
    /// from it by up to 0.7, far outside 1e-6.
    #[test]
    fn f32_works() {
        let p64 = Vector3::new(0.1f64, -0.2, 0.3);
        let p32 = p64.map(|v| v as f32);
        let (c32, c64) = (dcm(&p32), dcm(&p64));
        for i in 0..3 {
            for j in 0..3 {
                let d = (c32[(i, j)] as f64 - c64[(i, j)]).abs();
                assert!(
                    d < 1e-6,
                    "({i}, {j}): f32 {} f64 {}",
                    c32[(i, j)],
                    c64[(i, j)]
                );
            }
        }
        // And the antisymmetric part, which a transpose flips, is large here.
        assert!((c64[(0, 1)] - c64[(1, 0)]).abs() > 0.5);
        assert!((c32.determinant() - 1.0).abs() < 1e-6);
        let q32 = from_dcm(&c32);
        assert!((q32 - p32).norm() < 1e-6, "{q32:?}");
    }

    /// The shadow set `-p / |p|^2` by hand: `(0, 0, 2)` (253.7 deg about z) has the shadow
    /// `(0, 0, -0.5)` (106.3 deg about -z: the same attitude); `(1, 2, 2)`, `|p|^2 = 9`, has
    /// `-(1, 2, 2) / 9`; the zero MRP (the identity) is its own.
    #[test]
    fn shadow_by_hand() {
        assert_eq!(
            shadow(&Vector3::new(0.0f64, 0.0, 2.0)),
            Vector3::new(0.0, 0.0, -0.5)
        );
        assert_eq!(
            shadow(&Vector3::new(0.0f64, 0.0, -0.5)),
            Vector3::new(0.0, 0.0, 2.0)
        );
        assert_relative_eq!(
            shadow(&Vector3::new(1.0f64, 2.0, 2.0)),
            Vector3::new(-1.0, -2.0, -2.0) / 9.0,
            epsilon = 1e-15
        );
        assert_eq!(shadow(&Vector3::<f64>::zeros()), Vector3::zeros());
        // The same attitude: 4 atan 2 about z, and 4 atan 0.5 about -z. By eq 55 with
        // s = 4: the diagonal (4 (0 - 0 - 4) + 9) / 25 = -0.28, the z row and column of the
        // identity, C_12 = 4 (1 - 4) 2 / 25 = -0.96 = -C_21 (cos and sin of 253.7 deg).
        let p = Vector3::new(0.0f64, 0.0, 2.0);
        assert_relative_eq!(angle(&p), 4.0 * 2f64.atan(), epsilon = 1e-15);
        assert_relative_eq!(dcm(&shadow(&p)), dcm(&p), epsilon = 1e-15);
        assert_relative_eq!(
            dcm(&p),
            Matrix3::new(-0.28, -0.96, 0.0, 0.96, -0.28, 0.0, 0.0, 0.0, 1.0),
            epsilon = 1e-15
        );
    }

    /// [`canonical`] switches to the shadow set only past `|p| = 1`: `(0, 0, 2)` becomes
    /// `(0, 0, -0.5)`; `|p| <= 1` stays, the 180 deg MRP `(1, 0, 0)` too (its shadow
    /// `(-1, 0, 0)` is the same attitude, but the set does not switch at equality).
    #[test]
    fn canonical_by_hand() {
        assert_eq!(
            canonical(&Vector3::new(0.0f64, 0.0, 2.0)),
            Vector3::new(0.0, 0.0, -0.5)
        );
        assert_eq!(
            canonical(&Vector3::new(0.0f32, 0.0, 2.0)),
            Vector3::new(0.0, 0.0, -0.5)
        );
        for p in [
            Vector3::new(0.3f64, -0.2, 0.1),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 0.0, -1.0),
            Vector3::zeros(),
        ] {
            assert_eq!(canonical(&p), p);
        }
        // Every attitude past 180 deg comes back within it, the same DCM.
        for deg in [181.0f64, 200.0, 270.0, 359.0] {
            let p = from_axis_angle(&Vector3::new(1.0, -2.0, 0.5), deg.to_radians());
            assert!(p.norm() > 1.0);
            let q = canonical(&p);
            assert_relative_eq!(angle(&q), (360.0 - deg).to_radians(), epsilon = 1e-12);
            assert_relative_eq!(dcm(&q), dcm(&p), epsilon = 1e-12);
        }
    }

    /// A composition past 180 deg is returned in the canonical set: 120 deg then 120 deg
    /// about z is 240 deg about z, whose MRP `tan 60 deg` is past 1: the result is the shadow,
    /// -120 deg about z, `(0, 0, -tan 30 deg)`.
    #[test]
    fn composition_past_180_deg_is_canonical() {
        let p = Vector3::new(0.0f64, 0.0, (30f64).to_radians().tan());
        let q = compose(&p, &p);
        assert_relative_eq!(q, -p, epsilon = 1e-12);
        // Not commutative in general: the order of the product.
        let (a, b) = (
            from_axis_angle(&Vector3::x(), 0.7f64),
            from_axis_angle(&Vector3::y(), 0.4f64),
        );
        assert_relative_eq!(dcm(&compose(&b, &a)), dcm(&b) * dcm(&a), epsilon = 1e-12);
        assert_relative_eq!(dcm(&compose(&a, &b)), dcm(&a) * dcm(&b), epsilon = 1e-12);
        assert!((dcm(&compose(&b, &a)) - dcm(&compose(&a, &b))).norm() > 0.1);
    }

    /// Near 360 deg the composition formula divides 0 by 0 (`1 + |p1|^2 |p2|^2 - 2 p1.p2 = 0`
    /// for 180 deg twice about one axis): the fallback through the DCM returns the identity.
    /// Two rotations of `180 - e` deg about z make `360 - e` deg, i.e. `-e` deg, the MRP
    /// `(0, 0, -tan(e/4 deg))`, where the formula's denominator is about `(e pi / 180)^2 / 4`.
    #[test]
    fn composition_near_360_deg_goes_through_the_dcm() {
        let z = Vector3::new(0.0f64, 0.0, 1.0);
        assert_eq!(compose(&z, &z), Vector3::zeros());
        let x = Vector3::new(-1.0f64, 0.0, 0.0);
        assert_relative_eq!(compose(&x, &x), Vector3::zeros(), epsilon = 1e-15);
        for e in [1e-3f64, 0.01, 0.05, 0.1] {
            let p = from_axis_angle(&Vector3::z(), (180.0 - e / 2.0).to_radians());
            let q = compose(&p, &p);
            let want = -(e / 4.0).to_radians().tan();
            assert_relative_eq!(q, Vector3::new(0.0, 0.0, want), epsilon = 1e-12);
        }
        // Just past the fallback's 1e-6 (0.12 deg off 360, the denominator 1.1e-6) the
        // formula itself holds.
        let p = from_axis_angle(&Vector3::z(), (180.0f64 - 0.06).to_radians());
        let q = compose(&p, &p);
        assert_relative_eq!(
            q,
            Vector3::new(0.0, 0.0, -(0.03f64).to_radians().tan()),
            epsilon = 1e-12
        );
    }
}
