//! The 3-D NorthStar emulator (thesis Ch V, eqs 60-63), every near-field effect switchable,
//! plus the parametric effects of CTA's analysis vocabulary.
//!
//! Conventions (REFERENCE.md section 1):
//! - Cell k has normal `n_k` and centre `o_k` in the head frame O (eqs 60, 61), convex
//!   pyramid as printed: `n1 = [sin a, 0, cos a]` at `[+s, 0, 0]`, `n2 = [-sin a, 0, cos a]` at
//!   `[-s, 0, 0]`, `n3 = [0, sin a, cos a]` at `[0, +s, 0]`, `n4 = [0, -sin a, cos a]` at
//!   `[0, -s, 0]`, `a = 30 deg`, `s = 0.175 in`.
//! - The cells are fixed in the head: in N they sit at `d + C^T o_k` with normals `C^T n_k`.
//! - A beacon at `r` (N) reaches cell k along `b_k = r - d - C^T o_k`; cosine response
//!   `V_k = (C^T n_k) . b_k / |b_k|` (eq 62; 0 in shadow), intensity `I_k = 1/|b_k|^2`,
//!   beacon pattern `c_k = P(g_k)` with `g_k` the angle between the LED boresight (default
//!   `-z` of N: the grid faces the board) and the ray beacon -> cell k.
//! - Output (eq 63): `X = beta (S1 - S2)/(S1 + S2)`, `Y = beta (S3 - S4)/(S3 + S4)` with
//!   `S_k = c_k I_k V_k`, `beta = 32768`; the NorthStar reports signed 16-bit counts.
//!
//! Far field (proximity and intensity off, uniform beacon) this is exactly the collinearity
//! model of eq 65 with `H = beta tan a` (tested).
//!
//! Beyond the thesis, [`Effects`] carries the parametric effects the analysis
//! (`cta analyze`) knows by name; each is documented on its field.

use crate::mrp;
use crate::pattern::Pattern;
use crate::real::rad;
use crate::Real;
use nalgebra::{Matrix3, Vector3};

/// NorthStar full-scale factor `beta` of eq 63.
pub const BETA: f64 = 32768.0;

/// The sensor head geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Head<T> {
    /// Face angle of the X pair (cells 1, 2), radians (30 deg nominal).
    pub alpha_x: T,
    /// Face angle of the Y pair (cells 3, 4), radians (30 deg nominal).
    pub alpha_y: T,
    /// Cell-centre offset from the head centre `s`, inches (eq 61: 0.175).
    pub s: T,
    /// Output scale `beta` (eq 63: 32768).
    pub beta: T,
}

impl<T: Real> Head<T> {
    /// The thesis's NorthStar: `a = 30 deg`, `s = 0.175 in`, `beta = 32768`.
    pub fn northstar() -> Self {
        Head {
            alpha_x: rad(T::lit(30.0)),
            alpha_y: rad(T::lit(30.0)),
            s: T::lit(0.175),
            beta: T::lit(BETA),
        }
    }

    /// The far-field scale height `H = beta tan a` (18918.6 for the NorthStar).
    pub fn h(&self) -> T {
        self.beta * self.alpha_x.tan()
    }

    /// Cell normals in O (eq 60).
    pub fn normals(&self) -> [Vector3<T>; 4] {
        let (sx, cx) = self.alpha_x.sin_cos_small();
        let (sy, cy) = self.alpha_y.sin_cos_small();
        let z = T::zero();
        [
            Vector3::new(sx, z, cx),
            Vector3::new(-sx, z, cx),
            Vector3::new(z, sy, cy),
            Vector3::new(z, -sy, cy),
        ]
    }

    /// Cell centres in O (eq 61) for a cell offset `s`.
    pub fn centres(s: T) -> [Vector3<T>; 4] {
        let z = T::zero();
        [
            Vector3::new(s, z, z),
            Vector3::new(-s, z, z),
            Vector3::new(z, s, z),
            Vector3::new(z, -s, z),
        ]
    }
}

/// The sensor-head pose relative to the board: `d` (N origin -> O origin, in N, inches) and
/// the MRP `p` of `C` (N -> O).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose<T: Real> {
    /// Offset of the head centre, inches, N components.
    pub d: Vector3<T>,
    /// MRP of the DCM `C` mapping N to O.
    pub p: Vector3<T>,
}

impl<T: Real> Pose<T> {
    /// The true pose used for Table 3: `d = (0.6, 0.1, 0.062) in`, `p = (0.001, 0.002, 0.001)`.
    pub fn table3() -> Self {
        Pose {
            d: Vector3::new(T::lit(0.6), T::lit(0.1), T::lit(0.062)),
            p: Vector3::new(T::lit(0.001), T::lit(0.002), T::lit(0.001)),
        }
    }
}

/// Which near-field physics is on, and the parametric effects of the analysis vocabulary.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Effects<T> {
    /// `proximity`: the cells sit at `+/- s` from the head centre (parallax). Off: every
    /// cell sees the beacon from the head centre.
    pub proximity: bool,
    /// `intensity`: inverse-square intensity `1/|b_k|^2` per cell. Off: `I_k = 1`.
    pub intensity: bool,
    /// `beacon_pattern`: the LED radiation pattern (default Lambertian, 60 deg half angle).
    pub pattern: Pattern<T>,
    /// `beacon_tilt`: LED boresight tilt from `-z` of N, radians.
    pub tilt: T,
    /// `beacon_tilt` azimuth: the boresight tilts toward this azimuth (radians, 0 = +x of N).
    pub tilt_az: T,
    /// `cell_gain`: cell k's signal is multiplied by `gain[k]` (the vocabulary's `GX` scales
    /// cell 1 by `1 + GX`, `GY` cell 3 by `1 + GY`: responsivity mismatch within a pair).
    pub gain: [T; 4],
    /// `cell_bias`: added to cell k's signal, in the signal's units (1/in^2): ambient light
    /// or dark current (the vocabulary's `BX` on cell 1, `BY` on cell 3).
    pub bias: [T; 4],
    /// `saturation`: each cell's signal is clipped at this value (1/in^2): the cells saturate
    /// close to the beacon. `None`: no clipping.
    pub saturation: Option<T>,
    /// Cross-talk between the pairs: each cell's signal picks up this fraction of the
    /// signal of the matching cell of the other pair (1<->3, 2<->4). *Not* in the analysis
    /// vocabulary: it exists so tests can check that unexplained structure is reported.
    pub crosstalk: T,
}

impl<T: Real> Default for Effects<T> {
    /// The thesis's physics: proximity, intensity and the Lambertian 60 deg beacon, nothing
    /// else.
    fn default() -> Self {
        Effects {
            proximity: true,
            intensity: true,
            pattern: Pattern::vsml3710(),
            tilt: T::zero(),
            tilt_az: T::zero(),
            gain: [T::one(); 4],
            bias: [T::zero(); 4],
            saturation: None,
            crosstalk: T::zero(),
        }
    }
}

impl<T: Real> Effects<T> {
    /// Far field: no proximity, no intensity, uniform beacon (equals eq 65).
    pub fn far_field() -> Self {
        Effects {
            proximity: false,
            intensity: false,
            pattern: Pattern::Uniform,
            ..Default::default()
        }
    }

    /// The LED boresight unit vector in N.
    pub fn boresight(&self) -> Vector3<T> {
        let st = self.tilt.sin();
        Vector3::new(
            st * self.tilt_az.cos(),
            st * self.tilt_az.sin(),
            -self.tilt.cos(),
        )
    }
}

/// A NorthStar on a board, seeing beacons through the physics of eq 63.
#[derive(Debug, Clone, Copy)]
pub struct Emulator<T: Real> {
    /// Head geometry.
    pub head: Head<T>,
    /// Pose of the head on the board.
    pub pose: Pose<T>,
    /// Physics switches and effects (read at construction too: build a new emulator to
    /// change them).
    pub effects: Effects<T>,
    // Cached: normals and centres in N, the LED boresight unit vector in N, and whether the
    // raw cell signals pass unchanged (unit gains, no bias, cross-talk or saturation).
    n_n: [Vector3<T>; 4],
    o_n: [Vector3<T>; 4],
    bore: Vector3<T>,
    plain: bool,
}

/// One cell's signal before gain, bias, cross-talk and saturation, and its gradient in
/// coefficient form (see [`Emulator::cell`]): with `ray = r - o_k` (not normalised),
/// `dS/dr = a n_k + b e + c ray` and `dS/de = b ray`. All zero in shadow.
#[derive(Debug, Clone, Copy)]
struct Cell<T: Real> {
    s: T,
    a: T,
    b: T,
    c: T,
    ray: Vector3<T>,
}

impl<T: Real> Emulator<T> {
    /// Build an emulator (caches the cell geometry in N).
    pub fn new(head: Head<T>, pose: Pose<T>, effects: Effects<T>) -> Self {
        Self::with_led_boresight(head, pose, effects, &effects.boresight())
    }

    /// [`Self::new`] with the LEDs' boresight given directly as the unit vector `bore`
    /// (N) rather than by `effects.tilt`/`tilt_az`: no trigonometry (the chip's pose
    /// solver, which sets the boresight from the target's attitude anyway).
    pub fn with_led_boresight(
        head: Head<T>,
        pose: Pose<T>,
        effects: Effects<T>,
        bore: &Vector3<T>,
    ) -> Self {
        let c: Matrix3<T> = mrp::dcm(&pose.p);
        let ct = c.transpose();
        let s = if effects.proximity { head.s } else { T::zero() };
        let n_o = head.normals();
        let o_o = Head::centres(s);
        let n_n = core::array::from_fn(|k| ct * n_o[k]);
        let o_n = core::array::from_fn(|k| pose.d + ct * o_o[k]);
        let bore = *bore;
        let plain = effects.gain.iter().all(|&g| g == T::one())
            && effects.bias.iter().all(|&b| b == T::zero())
            && effects.crosstalk == T::zero()
            && effects.saturation.is_none();
        Emulator {
            head,
            pose,
            effects,
            n_n,
            o_n,
            bore,
            plain,
        }
    }

    /// The same emulator with the LEDs' boresight set directly to the unit vector `b` (N):
    /// for a target whose attitude rotates its LEDs (the pose solver), without trigonometry.
    /// `effects.tilt`/`tilt_az` are left as they were (they only describe the default).
    pub fn with_boresight(&self, b: &Vector3<T>) -> Self {
        let mut e = *self;
        e.bore = *b;
        e
    }

    /// The LED boresight unit vector in use (N).
    pub fn boresight(&self) -> Vector3<T> {
        self.bore
    }

    /// The cell signals `S_k` (after gain, bias, cross-talk and saturation) for a beacon at
    /// `r` (N, inches). Cells in shadow give 0 before bias.
    pub fn signals(&self, r: &Vector3<T>) -> [T; 4] {
        self.mixed(core::array::from_fn(|k| self.cell(k, r, false).s))
            .0
    }

    /// Cell `k`'s raw signal `S = c I V` (pattern, intensity, cosine response) and, when
    /// `grad`, its gradient. With `ray = r - o_k`, `l = 1/|ray|`, `V = (n . ray) l`,
    /// `w = -(e . ray) l` (cosine of the angle off the LED boresight `e`), `I = l^2`:
    /// `dV/dr = l n - V l^2 ray`, `dI/dr = -2 I l^2 ray`, `dw/dr = -l e - w l^2 ray`,
    /// `dw/de = -l ray`; by the product rule `dS/dr = a n + b e + c ray` and
    /// `dS/de = b ray` with `a = c I l`, `b = -k2 I l`, `c = -k3 I l^2`, `k2 = V dc/dw`,
    /// `k3 = c V (1 + 2 [intensity]) + k2 w` (scalars only: the vectors are combined once
    /// per output in [`Self::output_gradient`]).
    fn cell(&self, k: usize, r: &Vector3<T>, grad: bool) -> Cell<T> {
        let e = &self.effects;
        let z = T::zero();
        let ray = r - self.o_n[k];
        let mut out = Cell {
            s: z,
            a: z,
            b: z,
            c: z,
            ray,
        };
        let nr = self.n_n[k].dot(&ray);
        if nr <= z {
            return out; // in shadow: no signal, no gradient
        }
        let len2 = ray.norm_squared();
        let l = T::one() / len2.sqrt();
        let v = nr * l;
        let i = if e.intensity { l * l } else { T::one() };
        // A cosine: within [-1, 1] but for rounding, which only acos (below) minds.
        let w = -(ray.dot(&self.bore) * l);
        // c and dc/dw.
        let (c, dcdw) = match e.pattern {
            Pattern::Uniform => (T::one(), z),
            Pattern::Lambertian { m } => {
                if w <= z {
                    (z, z)
                } else if m == T::one() {
                    (w, T::one())
                } else {
                    let c = w.powf(m);
                    (c, m * c / w)
                }
            }
            p => {
                let gam = w.max(-T::one()).min(T::one()).acos();
                let c = p.eval(gam);
                let dcdw = if grad {
                    // d/dgamma by a central difference of the (polynomial) pattern,
                    // dgamma/dw = -1/sqrt(1 - w^2).
                    let h = T::lit(1e-4);
                    let dcdg = (p.eval(gam + h) - p.eval(gam - h)) / (h + h);
                    -dcdg / (T::one() - w * w).max(T::lit(1e-12)).sqrt()
                } else {
                    z
                };
                (c, dcdw)
            }
        };
        let cv = c * v;
        out.s = cv * i;
        if grad {
            let k2 = dcdw * v;
            let k3 = if e.intensity { cv * T::lit(3.0) } else { cv } + k2 * w;
            let il = i * l;
            out.a = c * il;
            out.b = -(k2 * il);
            out.c = -(k3 * il * l);
        }
        out
    }

    /// Cross-talk, gain, bias and saturation on the raw cell signals: the signals `S_k` and
    /// `dS_k/draw_k` (the gain, or 0 when clipped; cross-talk adds `x` times that to
    /// `dS_k/draw_{k^2}`).
    fn mixed(&self, raw: [T; 4]) -> ([T; 4], [T; 4]) {
        if self.plain {
            return (raw, [T::one(); 4]);
        }
        let e = &self.effects;
        let x = e.crosstalk;
        let mut s = [T::zero(); 4];
        let mut ds = [T::zero(); 4];
        for k in 0..4 {
            let m = if x == T::zero() {
                raw[k]
            } else {
                raw[k] + x * raw[k ^ 2]
            };
            let v = m * e.gain[k] + e.bias[k];
            match e.saturation {
                Some(sat) if v >= sat => s[k] = sat, // clipped: flat
                _ => {
                    s[k] = v;
                    ds[k] = e.gain[k];
                }
            }
        }
        (s, ds)
    }

    /// The output of eq 63 with its gradients: `(y, dy/dr, dy/de)` for a beacon at `r` (N)
    /// and the LED boresight `e`: `dX/dr = 2 beta (S2 dS1 - S1 dS2)/(S1 + S2)^2`, likewise
    /// for Y and for `e`. `None` when a pair has no signal. Costs about three outputs, where
    /// a finite-difference Jacobian over `r` and the attitude costs seven.
    ///
    /// The chain rule runs on scalars first: `alpha_k = dX/draw_k` (through saturation, gain
    /// and cross-talk), then `dX/dr = sum_k alpha_k (a_k n_k + c_k ray_k) + (sum_k alpha_k
    /// b_k) e` and `dX/de = sum_k alpha_k b_k ray_k` with each cell's coefficients (see
    /// `Self::cell`): a handful of vector products per output on the chip.
    #[allow(clippy::type_complexity)]
    pub fn output_gradient(
        &self,
        r: &Vector3<T>,
    ) -> Option<([T; 2], [Vector3<T>; 2], [Vector3<T>; 2])> {
        self.gradients(r, false).map(|(y, dr, de, _)| (y, dr, de))
    }

    /// [`Self::output_gradient`] and the [`Self::magnitude`] with its gradients:
    /// `(y, dy/dr, dy/de, (M, dM/dr, dM/de))`, `M = sum_k S_k`, `dM/draw_k` the same
    /// mixing derivative as the outputs' (gain, 0 when clipped, plus cross-talk). The
    /// magnitude costs one more combination of the cells' coefficients (no new cell model):
    /// the pose solver's magnitude rows.
    #[allow(clippy::type_complexity)]
    pub fn output_magnitude_gradient(
        &self,
        r: &Vector3<T>,
    ) -> Option<(
        [T; 2],
        [Vector3<T>; 2],
        [Vector3<T>; 2],
        (T, Vector3<T>, Vector3<T>),
    )> {
        self.gradients(r, true)
            .map(|(y, dr, de, m)| (y, dr, de, m.unwrap_or_default()))
    }

    #[allow(clippy::type_complexity)]
    fn gradients(
        &self,
        r: &Vector3<T>,
        magnitude: bool,
    ) -> Option<(
        [T; 2],
        [Vector3<T>; 2],
        [Vector3<T>; 2],
        Option<(T, Vector3<T>, Vector3<T>)>,
    )> {
        let cells: [Cell<T>; 4] = core::array::from_fn(|k| self.cell(k, r, true));
        let (s, ds) = self.mixed(core::array::from_fn(|k| cells[k].s));
        let x = self.effects.crosstalk;
        let beta = self.head.beta;
        let mut y = [T::zero(); 2];
        let mut dr = [Vector3::zeros(); 2];
        let mut de = [Vector3::zeros(); 2];
        // alpha_k times cell k's gradient: (the r part without e, the e coefficient, the e part).
        let term = |k: usize, alpha: T| {
            let c = &cells[k];
            let ab = alpha * c.b;
            (
                self.n_n[k] * (alpha * c.a) + c.ray * (alpha * c.c),
                ab,
                c.ray * ab,
            )
        };
        for (a, p) in [0usize, 2].into_iter().enumerate() {
            let q = p + 1;
            let sum = s[p] + s[q];
            if !(sum > T::zero()) {
                return None;
            }
            let inv = T::one() / sum;
            y[a] = beta * (s[p] - s[q]) * inv;
            let f = (beta + beta) * inv * inv;
            let (ap, aq) = (f * s[q] * ds[p], -(f * s[p] * ds[q]));
            let (tp, tq) = (term(p, ap), term(q, aq));
            let (mut g, mut eb, mut h) = (tp.0 + tq.0, tp.1 + tq.1, tp.2 + tq.2);
            if x != T::zero() {
                // Cross-talk: S_p and S_q also carry x times cells p^2 and q^2.
                for t in [term(p ^ 2, ap * x), term(q ^ 2, aq * x)] {
                    g += t.0;
                    eb += t.1;
                    h += t.2;
                }
            }
            dr[a] = g + self.bore * eb;
            de[a] = h;
        }
        let m = magnitude.then(|| {
            // dM/draw_k = ds_k, plus x ds_{k^2} with cross-talk (S_{k^2} carries x raw_k).
            let (mut g, mut eb, mut h) = (Vector3::zeros(), T::zero(), Vector3::zeros());
            let mut m = T::zero();
            for k in 0..4 {
                m += s[k];
                let alpha = if x == T::zero() {
                    ds[k]
                } else {
                    ds[k] + x * ds[k ^ 2]
                };
                let t = term(k, alpha);
                g += t.0;
                eb += t.1;
                h += t.2;
            }
            (m, g + self.bore * eb, h)
        });
        Some((y, dr, de, m))
    }

    /// The output `(X, Y)` of eq 63 in counts, unclipped. `None` when a pair has no signal.
    pub fn output(&self, r: &Vector3<T>) -> Option<[T; 2]> {
        Self::ratios(self.head.beta, &self.signals(r))
    }

    /// [`Self::output`] and [`Self::magnitude`] from one evaluation of the cells.
    pub fn output_magnitude(&self, r: &Vector3<T>) -> Option<([T; 2], T)> {
        let s = self.signals(r);
        Self::ratios(self.head.beta, &s).map(|y| (y, s[0] + s[1] + s[2] + s[3]))
    }

    fn ratios(b: T, s: &[T; 4]) -> Option<[T; 2]> {
        let dx = s[0] + s[1];
        let dy = s[2] + s[3];
        if !(dx > T::zero() && dy > T::zero()) {
            return None;
        }
        // As in `output_gradient` (the same rounding).
        Some([
            b * (s[0] - s[1]) * (T::one() / dx),
            b * (s[2] - s[3]) * (T::one() / dy),
        ])
    }

    /// The output as the NorthStar reports it: saturated to signed 16 bits
    /// (-32768..=32767) and rounded to whole counts.
    pub fn counts(&self, r: &Vector3<T>) -> Option<[i16; 2]> {
        self.output(r).map(|o| o.map(saturate_i16))
    }

    /// Signal magnitude: the sum of the four cell signals (1/in^2), a proxy for the
    /// NorthStar's reported spot magnitude.
    pub fn magnitude(&self, r: &Vector3<T>) -> T {
        self.signals(r).iter().fold(T::zero(), |a, &b| a + b)
    }
}

/// Round and saturate a count to the NorthStar's signed 16-bit range.
#[inline]
pub fn saturate_i16<T: Real>(v: T) -> i16 {
    let f = v.to_f64();
    if !(f.is_finite()) {
        return if f > 0.0 { i16::MAX } else { i16::MIN };
    }
    let r = libm::round(f);
    if r >= 32767.0 {
        i16::MAX
    } else if r <= -32768.0 {
        i16::MIN
    } else {
        r as i16
    }
}

/// The CTA beacon grid of Ch V: `n x n` beacons at `pitch` inches, centred on the N origin,
/// the plate at `z = separation`. Beacon `i` is at column `i % n`, row `i / n`.
pub fn grid_position<T: Real>(n: usize, pitch: T, separation: T, i: usize) -> Vector3<T> {
    let half = T::lit((n as f64 - 1.0) / 2.0);
    let col = T::lit((i % n) as f64);
    let row = T::lit((i / n) as f64);
    Vector3::new((col - half) * pitch, (row - half) * pitch, separation)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collinearity::{self, ParamsExt};

    #[test]
    fn far_field_equals_eq65() {
        let head = Head::<f64>::northstar();
        let pose = Pose::table3();
        let em = Emulator::new(head, pose, Effects::far_field());
        let x = collinearity::Params::from_pose(&pose, head.h());
        // How many beacons each separation must compare at least. A cell is lit while the
        // beacon is less than 90 deg off its normal, i.e. (the head nearly level at d =
        // (0.6, 0.1, 0.062)) while |x - 0.6| and |y - 0.1| stay below (sep - 0.062) / tan 30:
        // at 1 in, 1.62 in: x in {-0.5, 0.5, 1.5}, y in {-1.5 (barely), -0.5, 0.5, 1.5}, at
        // least the 3 x 3 well inside; at 3 in, 5.09 in: all but the x = -4.5 column (which
        // the head's 0.5 deg tilt may let in), at least 9 x 9 well inside; at 10 and 30 in,
        // every beacon.
        for (sep, min) in [(1.0, 9), (3.0, 81), (10.0, 100), (30.0, 100)] {
            let mut compared = 0;
            for i in 0..100 {
                let r = grid_position(10, 1.0, sep, i);
                // Only inside the field of view (every cell lit): past 60 deg off boresight
                // a cell is in shadow and the output pins at +/- beta, where eq 65 does not.
                if em.signals(&r).iter().any(|&s| s <= 0.0) {
                    continue;
                }
                let a = em.output(&r).unwrap();
                let b = collinearity::predict(&x, &r).unwrap();
                assert!(
                    (a[0] - b[0]).abs() < 1e-8 && (a[1] - b[1]).abs() < 1e-8,
                    "{a:?} {b:?}"
                );
                compared += 1;
            }
            assert!(
                compared >= min,
                "{sep} in: only {compared} beacons compared (want >= {min})"
            );
        }
    }

    #[test]
    fn convex_pairing_pushes_beacons_off_boresight() {
        let head = Head::<f64>::northstar();
        let pose = Pose {
            d: Vector3::zeros(),
            p: Vector3::zeros(),
        };
        let near = Emulator::new(head, pose, Effects::default());
        let far = Emulator::new(head, pose, Effects::far_field());
        let r = Vector3::new(1.0, 0.5, 5.0);
        let a = near.output(&r).unwrap();
        let b = far.output(&r).unwrap();
        assert!(a[0] > b[0] && a[1] > b[1]);
    }

    #[test]
    fn output_gradient_matches_finite_differences() {
        let head = Head::<f64>::northstar();
        let pose = Pose::table3();
        let mut fx = Effects::default();
        fx.gain[0] = 1.03;
        fx.bias[2] = 1e-4;
        fx.crosstalk = 0.02;
        for pattern in [
            Pattern::vsml3710(),
            Pattern::lambertian_half_angle(40.0),
            Pattern::Quartic,
            Pattern::Uniform,
        ] {
            fx.pattern = pattern;
            let e0 = Vector3::new(0.1, -0.05, -1.0).normalize();
            let em = Emulator::new(head, pose, fx).with_boresight(&e0);
            let r = Vector3::new(1.3, -0.7, 4.0);
            check_gradient(&em, &r, &e0, &format!("{pattern:?}"));
        }
    }

    /// The analytic `dy/dr` and `dy/de` of `em` at `r` (LED boresight `e0`) against central
    /// differences.
    fn check_gradient(em: &Emulator<f64>, r: &Vector3<f64>, e0: &Vector3<f64>, label: &str) {
        let (y, dr, de) = em.output_gradient(r).unwrap();
        assert_eq!(y, em.output(r).unwrap());
        // The magnitude's gradient, and the outputs unchanged beside it.
        let (y2, dr2, de2, (m, dm_r, dm_e)) = em.output_magnitude_gradient(r).unwrap();
        assert_eq!((y2, dr2, de2), (y, dr, de));
        assert_eq!(m, em.magnitude(r));
        let h = 1e-6;
        for k in 0..3 {
            let mut rp = *r;
            rp[k] += h;
            let mut rm = *r;
            rm[k] -= h;
            let mut ep = *e0;
            ep[k] += h;
            let mut emm = *e0;
            emm[k] -= h;
            let (bp, bm) = (em.with_boresight(&ep), em.with_boresight(&emm));
            let fd = (em.magnitude(&rp) - em.magnitude(&rm)) / (2.0 * h);
            assert!(
                (fd - dm_r[k]).abs() < 1e-6 * m + 1e-4 * fd.abs(),
                "{label} dM/dr{k}: {fd} vs {}",
                dm_r[k]
            );
            let fe = (bp.magnitude(r) - bm.magnitude(r)) / (2.0 * h);
            assert!(
                (fe - dm_e[k]).abs() < 1e-5 * m + 1e-3 * fe.abs(),
                "{label} dM/de{k}: {fe} vs {}",
                dm_e[k]
            );
            let (yp, ym) = (em.output(&rp).unwrap(), em.output(&rm).unwrap());
            let (zp, zm) = (bp.output(r).unwrap(), bm.output(r).unwrap());
            for a in 0..2 {
                let fd = (yp[a] - ym[a]) / (2.0 * h);
                assert!(
                    (fd - dr[a][k]).abs() < 1e-4 * (1.0 + fd.abs()),
                    "{label} dy{a}/dr{k}: {fd} vs {}",
                    dr[a][k]
                );
                let fe = (zp[a] - zm[a]) / (2.0 * h);
                assert!(
                    (fe - de[a][k]).abs() < 1e-3 * (1.0 + fe.abs()),
                    "{label} dy{a}/de{k}: {fe} vs {}",
                    de[a][k]
                );
            }
        }
    }

    /// The saturation branch: with the brightest cell clipped (and the others not), the
    /// gradient treats the clipped signal as flat, exactly as finite differences see it.
    #[test]
    fn output_gradient_with_a_clipped_cell_matches_finite_differences() {
        let head = Head::<f64>::northstar();
        let pose = Pose::table3();
        let r = Vector3::new(1.1, 0.6, 3.0);
        let free = Emulator::new(head, pose, Effects::default());
        let mut sig = free.signals(&r);
        sig.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let fx = Effects {
            saturation: Some(0.5 * (sig[2] + sig[3])),
            ..Effects::default()
        };
        let em = Emulator::new(head, pose, fx);
        let clipped = em.signals(&r);
        assert_eq!(
            clipped
                .iter()
                .filter(|&&v| v == fx.saturation.unwrap())
                .count(),
            1
        );
        assert_ne!(
            em.output(&r).unwrap(),
            free.output(&r).unwrap(),
            "the clip must change the output"
        );
        let e0 = Vector3::new(0.0, 0.0, -1.0);
        check_gradient(&em.with_boresight(&e0), &r, &e0, "clipped");
    }

    #[test]
    fn saturates_to_i16() {
        assert_eq!(saturate_i16(40000.0f64), i16::MAX);
        assert_eq!(saturate_i16(-40000.0f64), i16::MIN);
        assert_eq!(saturate_i16(12.4f64), 12);
        assert_eq!(saturate_i16(f64::NAN), i16::MIN);
    }

    /// A cell's gain scales that cell's signal and nothing else (eq 63): from the plain
    /// output `X0`, the pair's ratio is `rho = S1/S2 = (beta + X0)/(beta - X0)`, and a gain
    /// `g` on cell 1 gives `X = beta (g rho - 1)/(g rho + 1)` with Y unchanged; on cell 2 the
    /// same with `rho/g`; on cell 3 or 4 the same for Y. A 5 deg beacon tilt moves X by more
    /// than a count (its direction and size: the closed-form `beacon_tilt` tests below).
    #[test]
    fn effects_change_the_output() {
        let head = Head::<f64>::northstar();
        let pose = Pose::table3();
        let base = Emulator::new(head, pose, Effects::default());
        let r = Vector3::new(2.0, -1.0, 6.0);
        let o0 = base.output(&r).unwrap();
        let b = BETA;
        let ratio = |y: f64| (b + y) / (b - y);
        let of_ratio = |rho: f64| b * (rho - 1.0) / (rho + 1.0);
        for (cell, g) in [(0, 1.05), (1, 1.05), (2, 0.9), (3, 1.2)] {
            let mut gain = Effects::default().gain;
            gain[cell] = g;
            let e = Effects {
                gain,
                ..Effects::default()
            };
            let out = Emulator::new(head, pose, e).output(&r).unwrap();
            let (pair, other) = if cell < 2 { (0, 1) } else { (1, 0) };
            let rho = if cell % 2 == 0 {
                ratio(o0[pair]) * g
            } else {
                ratio(o0[pair]) / g
            };
            assert!(
                (out[pair] - of_ratio(rho)).abs() < 1e-9 * b,
                "cell {cell}: {} want {}",
                out[pair],
                of_ratio(rho)
            );
            assert!((out[pair] - o0[pair]).abs() > 100.0, "cell {cell}");
            assert_eq!(out[other], o0[other], "cell {cell}");
        }
        let e = Effects {
            tilt: rad(5.0),
            ..Effects::default()
        };
        let t = Emulator::new(head, pose, e).output(&r).unwrap();
        assert!((t[0] - o0[0]).abs() > 1.0);
    }

    // Closed-form checks of each effect's direction and sign. The expected values come from
    // the conventions (module docs, REFERENCE.md section 1) by hand, not from the code: a
    // head at the N origin, level (`C = I`), so cell 1 sits at `+s` on x facing `+x`, cell 3
    // at `+s` on y facing `+y`.

    fn level() -> Pose<f64> {
        Pose {
            d: Vector3::zeros(),
            p: Vector3::zeros(),
        }
    }

    const DEG: f64 = core::f64::consts::PI / 180.0;

    fn close(a: f64, b: f64, tol: f64, what: &str) {
        assert!((a - b).abs() <= tol, "{what}: {a} want {b}");
    }

    /// `beacon_tilt`: the boresight leaves `-z` of N by `tilt` toward the azimuth `tilt_az`
    /// (0 = +x, 90 deg = +y): `(sin t cos az, sin t sin az, -cos t)`.
    #[test]
    fn boresight_tilts_toward_its_azimuth() {
        let t = 10.0 * DEG;
        for (az, want) in [
            (0.0, Vector3::new(t.sin(), 0.0, -t.cos())),
            (90.0, Vector3::new(0.0, t.sin(), -t.cos())),
            (180.0, Vector3::new(-t.sin(), 0.0, -t.cos())),
            (-90.0, Vector3::new(0.0, -t.sin(), -t.cos())),
        ] {
            let e = Effects::<f64> {
                tilt: t,
                tilt_az: az * DEG,
                ..Effects::default()
            };
            let b = e.boresight();
            assert!((b - want).norm() < 1e-15, "az {az}: {b:?} want {want:?}");
            assert_eq!(
                Emulator::new(Head::northstar(), level(), e).boresight(),
                b,
                "the emulator uses the effects' boresight"
            );
        }
        assert_eq!(
            Effects::<f64>::default().boresight(),
            Vector3::new(0.0, 0.0, -1.0)
        );
    }

    /// A beacon straight above the level head at height `h`, its LED (Lambertian, m = 1)
    /// tilted by `t` toward +x: cells 1 and 2 see it under the same cosine and intensity (the
    /// rays `(-s, 0, h)` and `(s, 0, h)` have one length and meet mirrored normals), so only
    /// the pattern differs: `c = -(ray . e)/|ray|` = `(h cos t +/- s sin t)/|ray|`, and
    /// `X = beta (c1 - c2)/(c1 + c2) = beta (s/h) tan t`, `Y = 0`: the LED tilted toward +x
    /// lights the +x cell more. At azimuth 90 deg the same holds for Y.
    #[test]
    fn beacon_tilt_lights_the_cell_it_tilts_toward() {
        let head = Head::<f64>::northstar();
        let (h, t) = (5.0, 10.0 * DEG);
        let r = Vector3::new(0.0, 0.0, h);
        let want = BETA * 0.175 / h * t.tan(); // 202.23 counts
        for (az, wx, wy) in [
            (0.0, want, 0.0),
            (90.0, 0.0, want),
            (180.0, -want, 0.0),
            (270.0, 0.0, -want),
        ] {
            let e = Effects {
                tilt: t,
                tilt_az: az * DEG,
                ..Effects::default()
            };
            let o = Emulator::new(head, level(), e).output(&r).unwrap();
            close(o[0], wx, 1e-9, &format!("X, tilt azimuth {az}"));
            close(o[1], wy, 1e-9, &format!("Y, tilt azimuth {az}"));
        }
        // No tilt: the beacon straight above reads (0, 0).
        let o = Emulator::new(head, level(), Effects::default())
            .output(&r)
            .unwrap();
        close(o[0], 0.0, 1e-9, "X untilted");
        close(o[1], 0.0, 1e-9, "Y untilted");
    }

    /// `cell_gain`: with the beacon straight above the level head, the cells of a pair see
    /// equal signals `S`, so a gain `g` on cell 1 gives `X = beta (g - 1)/(g + 1)` (GX > 0:
    /// X > 0), and on cell 3 the same for Y.
    #[test]
    fn cell_gain_scales_cell_1_and_cell_3() {
        let head = Head::<f64>::northstar();
        let r = Vector3::new(0.0, 0.0, 4.0);
        let g = 1.05;
        let want = BETA * 0.05 / 2.05; // 799.22 counts
        for (k, wx, wy) in [
            (0, want, 0.0),
            (1, -want, 0.0),
            (2, 0.0, want),
            (3, 0.0, -want),
        ] {
            let mut e = Effects::default();
            e.gain[k] = g;
            let o = Emulator::new(head, level(), e).output(&r).unwrap();
            close(o[0], wx, 1e-9, &format!("X, gain on cell {}", k + 1));
            close(o[1], wy, 1e-9, &format!("Y, gain on cell {}", k + 1));
        }
    }

    /// `cell_bias`: in the far field (no proximity or intensity, uniform beacon) every cell
    /// straight below the beacon reads its cosine `cos 30 deg`; a bias `b` on cell 1 gives
    /// `X = beta b / (2 cos 30 deg + b)` (BX > 0: X > 0), on cell 3 the same for Y.
    #[test]
    fn cell_bias_adds_to_cell_1_and_cell_3() {
        let head = Head::<f64>::northstar();
        let r = Vector3::new(0.0, 0.0, 7.0);
        let b = 0.1;
        let want = BETA * b / (2.0 * (30.0 * DEG).cos() + b); // 1788.7 counts
        for (k, wx, wy) in [
            (0, want, 0.0),
            (1, -want, 0.0),
            (2, 0.0, want),
            (3, 0.0, -want),
        ] {
            let mut e = Effects::far_field();
            e.bias[k] = b;
            let o = Emulator::new(head, level(), e).output(&r).unwrap();
            close(o[0], wx, 1e-9, &format!("X, bias on cell {}", k + 1));
            close(o[1], wy, 1e-9, &format!("Y, bias on cell {}", k + 1));
        }
    }

    /// `saturation` and cross-talk, far field, a beacon 20 deg off boresight toward +x:
    /// cell 1 (normal 30 deg toward +x) sees it 10 deg off its normal, cell 2 50 deg, cells 3
    /// and 4 under `cos 30 cos 20`. Unclipped `X = beta (cos 10 - cos 50)/(cos 10 + cos 50)`
    /// `= beta tan 30 tan 20` (eq 65's `H tan theta`). Clipped at `cos 30` (between the
    /// two), cell 1 reads `cos 30`: X falls toward the boresight, Y stays 0. Cross-talk `x`:
    /// cell 1 picks up `x` of cell 3 and cell 3 `x` of cell 1 (1<->3, 2<->4), so Y turns
    /// positive with X.
    #[test]
    fn saturation_and_crosstalk_in_closed_form() {
        let head = Head::<f64>::northstar();
        let r = Vector3::new((20.0 * DEG).sin(), 0.0, (20.0 * DEG).cos()) * 6.0;
        let (s1, s2) = ((10.0 * DEG).cos(), (50.0 * DEG).cos());
        let s3 = (30.0 * DEG).cos() * (20.0 * DEG).cos();
        let free = Emulator::new(head, level(), Effects::far_field())
            .output(&r)
            .unwrap();
        close(
            free[0],
            BETA * (30.0 * DEG).tan() * (20.0 * DEG).tan(),
            1e-9,
            "X free",
        );
        close(
            free[0],
            BETA * (s1 - s2) / (s1 + s2),
            1e-9,
            "X free (cells)",
        );
        close(free[1], 0.0, 1e-9, "Y free");

        let sat = (30.0 * DEG).cos();
        let e = Effects {
            saturation: Some(sat),
            ..Effects::far_field()
        };
        let o = Emulator::new(head, level(), e).output(&r).unwrap();
        close(o[0], BETA * (sat - s2) / (sat + s2), 1e-9, "X clipped");
        assert!(o[0] < free[0] && o[0] > 0.0, "{o:?} {free:?}");
        close(o[1], 0.0, 1e-9, "Y clipped");

        let x = 0.02;
        let e = Effects {
            crosstalk: x,
            ..Effects::far_field()
        };
        let o = Emulator::new(head, level(), e).output(&r).unwrap();
        let (c1, c2, c3, c4) = (s1 + x * s3, s2 + x * s3, s3 + x * s1, s3 + x * s2);
        close(o[0], BETA * (c1 - c2) / (c1 + c2), 1e-9, "X cross-talk");
        close(o[1], BETA * (c3 - c4) / (c3 + c4), 1e-9, "Y cross-talk");
        assert!(o[1] > 0.0, "cross-talk 1<->3: Y follows X: {o:?}");
    }

    /// Proximity (parallax), intensity and the beacon pattern, one at a time, for a beacon at
    /// `(1, 0, 3)` in over the level head. Proximity alone: cell 1 at `+s` sees it
    /// `phi1 = atan((1 - s)/3)` toward +x, i.e. `30 - phi1` off its normal, cell 2 at `-s`
    /// `30 + phi2` with `phi2 = atan((1 + s)/3)`; intensity and pattern as noted below. Each
    /// effect makes the beacon look farther off boresight (REFERENCE.md section 3: with the
    /// convex pairing all three errors have one sign): intensity (cell 1 is nearer) and the Lambertian pattern (cell 1 is nearer
    /// the LED's axis) both raise X above proximity alone, which is above the far field's
    /// `H/3`; mirrored at `x = -1`.
    #[test]
    fn near_field_effects_push_beacons_off_boresight() {
        let head = Head::<f64>::northstar();
        let s = 0.175;
        let a = 30.0 * DEG;
        for side in [1.0, -1.0] {
            let r = Vector3::new(side, 0.0, 3.0);
            let out = |e: Effects<f64>| Emulator::new(head, level(), e).output(&r).unwrap();
            let far = out(Effects::far_field());
            close(far[0], side * BETA * a.tan() / 3.0, 1e-9, "far field");
            let prox = Effects {
                proximity: true,
                ..Effects::far_field()
            };
            let p = out(prox);
            let (phi1, phi2) = (((1.0 - s) / 3.0f64).atan(), ((1.0 + s) / 3.0f64).atan());
            let (v1, v2) = ((a - phi1).cos(), (a + phi2).cos());
            close(p[0], side * BETA * (v1 - v2) / (v1 + v2), 1e-9, "proximity");
            assert!(side * p[0] > side * far[0], "proximity: {p:?} vs {far:?}");
            // Intensity: cell k at distance `L_k = 3 / cos phi_k` gets `1/L_k^2`; the
            // Lambertian LED (boresight -z) gives it `cos phi_k = 3/L_k`.
            let (l1, l2) = (3.0 / phi1.cos(), 3.0 / phi2.cos());
            let x = |s1: f64, s2: f64| side * BETA * (s1 - s2) / (s1 + s2);
            let i = out(Effects {
                intensity: true,
                ..prox
            });
            close(i[0], x(v1 / (l1 * l1), v2 / (l2 * l2)), 1e-9, "intensity");
            assert!(side * i[0] > side * p[0], "intensity: {i:?} vs {p:?}");
            let l = out(Effects {
                pattern: Pattern::vsml3710(),
                ..prox
            });
            close(l[0], x(v1 * phi1.cos(), v2 * phi2.cos()), 1e-9, "pattern");
            assert!(side * l[0] > side * p[0], "pattern: {l:?} vs {p:?}");
            for o in [far, p, i, l] {
                close(o[1], 0.0, 1e-9, "Y on the x axis");
            }
        }
    }

    /// The pose: `d` is where the head sits (a beacon straight above it reads (0, 0)), and
    /// `C` maps N to O: a head turned +90 deg about z sees N's +x as its own -y, so a beacon
    /// at `(1, 0, 4)` reads `X = 0`, `Y = -H/4` in the far field.
    #[test]
    fn pose_offset_and_rotation_signs() {
        let head = Head::<f64>::northstar();
        let r = Vector3::new(1.0, 0.0, 4.0);
        let shifted = Pose {
            d: Vector3::new(1.0, 0.0, 0.0),
            p: Vector3::zeros(),
        };
        let o = Emulator::new(head, shifted, Effects::default())
            .output(&r)
            .unwrap();
        close(o[0], 0.0, 1e-9, "X above the head");
        close(o[1], 0.0, 1e-9, "Y above the head");
        let turned = Pose {
            d: Vector3::zeros(),
            p: Vector3::new(0.0, 0.0, (22.5 * DEG).tan()),
        };
        let o = Emulator::new(head, turned, Effects::far_field())
            .output(&r)
            .unwrap();
        close(o[0], 0.0, 1e-9, "X turned");
        close(o[1], -BETA * (30.0 * DEG).tan() / 4.0, 1e-9, "Y turned");
    }
}
