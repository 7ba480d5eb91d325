//! The spot magnitudes in the solve (beyond the thesis, whose model is the spots' `X, Y`):
//! a reading's log signal and weight under the calibration's magnitude law, and the weighted
//! Helmert contrasts that eliminate the frame's common scale (the `A` of
//! [`super::Magnitude`]) exactly.

use super::obs::Obs;
use super::Magnitude;
use crate::Real;

/// A solve with the magnitudes whose residual RMS exceeds this many spot noise sigmas (or
/// that fails) is replaced by the solve from the spots alone: the magnitudes are used only
/// where they agree with the spots (a wrong brightness, a law that does not hold, a drifting
/// LED), and never cost the pose it would have had without them. Clean frames sit near 1
/// (29 rows: 1-sigma of the RMS about 0.13).
pub const MAGNITUDE_RMS_SIGMAS: f32 = 2.0;

/// [`Magnitude`] as the solver uses it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct MagSolve<T> {
    offset: T,
    inv_exponent: T,
    /// `(noise x exponent)^2`: the numerator of a magnitude's weight.
    w_num: T,
    /// `(noise_percent / 100)^2`.
    rel2: T,
    max: T,
    min: T,
    pub(super) sensitivity: u8,
}

impl<T: Real> MagSolve<T> {
    pub(super) fn new(m: &Magnitude, noise: T) -> Self {
        let g = T::lit(m.exponent as f64);
        let rel = T::lit(m.noise_percent as f64) / T::lit(100.0);
        MagSolve {
            offset: T::lit(m.offset as f64),
            inv_exponent: T::one() / g,
            w_num: noise * noise * g * g,
            rel2: rel * rel,
            max: T::lit(m.max as f64),
            min: T::lit(m.min as f64),
            sensitivity: m.sensitivity,
        }
    }

    /// `(m, weight)` of a reading (see [`Obs::m`]; `ln_b` the beacon's `ln` brightness), or
    /// `None` when it is not used: saturated (at or above `max`), below the law's range
    /// (`min`), or not a whole count above the offset. `M - offset = D` has the variance
    /// `(rel D)^2 + 1/12` (the scatter and the rounding to counts), so `ln S = ln D /
    /// exponent` has `(rel^2 + 1/(12 D^2)) / exponent^2`.
    pub(super) fn reading(&self, magnitude: u16, ln_b: T) -> Option<(T, T)> {
        let mv = T::lit(magnitude as f64);
        let d = mv - self.offset;
        if mv >= self.max || mv < self.min || d < T::one() {
            return None;
        }
        let var = self.rel2 + T::one() / (T::lit(12.0) * d * d);
        Some((d.ln() * self.inv_exponent - ln_b, self.w_num / var))
    }
}

/// The magnitudes a solve of `obs` fits: those used, when at least two are (one alone
/// carries nothing: the frame's scale is unknown).
pub(super) fn magnitudes_fitted<T: Real>(obs: &[Obs<T>]) -> u8 {
    match obs.iter().filter(|o| o.magnitude_used()).count() {
        0 | 1 => 0,
        k => k as u8,
    }
}

/// The magnitude rows of a solve, built beacon by beacon as the weighted Helmert contrasts
/// of the magnitudes' residuals: the common scale `A` of [`Magnitude`] enters every
/// magnitude's `ln` as the same unknown constant, and is eliminated exactly by fitting the
/// residuals less their weighted mean. With `W` the weights so far and `rbar` the weighted
/// mean of the residuals so far, beacon `k` (weight `w`, residual `r`) gives the row
/// `f (r - rbar)`, `f = sqrt(w W / (W + w))` (none for the first), and then `W += w`,
/// `rbar += (w / W) (r - rbar)`; the Jacobian rows alike. The sum of the rows' squares is
/// `sum_i w_i (r_i - rbar)^2` (West's weighted update), so each row has unit weight, as the
/// spots' rows, and `k` magnitudes give `k - 1` rows: no running sum to hold back, the
/// degrees of freedom counted right.
pub(super) struct Contrasts<T: Real> {
    w: T,
    r: T,
    j: [T; 6],
}

impl<T: Real> Contrasts<T> {
    pub(super) fn new() -> Self {
        Contrasts {
            w: T::zero(),
            r: T::zero(),
            j: [T::zero(); 6],
        }
    }

    /// Add one magnitude (weight `w`, residual `r`, Jacobian row `j`, empty without the
    /// Jacobian); its contrast row, if any, goes to `sink`.
    pub(super) fn add(&mut self, w: T, r: T, j: &[T], sink: &mut dyn FnMut(T, T, &[T])) {
        let total = self.w + w;
        let g = w / total;
        let first = self.w == T::zero();
        let f = if first {
            T::zero()
        } else {
            (w * self.w / total).sqrt()
        };
        let dr = r - self.r;
        self.r += g * dr;
        self.w = total;
        if j.is_empty() {
            if !first {
                sink(f * dr, T::one(), &[]);
            }
            return;
        }
        let mut row = [T::zero(); 6];
        for (i, (m, &ji)) in self.j.iter_mut().zip(j).enumerate() {
            let d = ji - *m;
            row[i] = f * d;
            *m += g * d;
        }
        if !first {
            sink(f * dr, T::one(), &row);
        }
    }
}
