//! A matched observation of the pose problem: a beacon of the constellation and the spot the
//! NorthStar reported for it (eq 63's outputs and the spot magnitude).

use crate::Real;
use nalgebra::Vector3;

/// A matched observation: beacon position in T and the measured spot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obs<T: Real> {
    /// Beacon position, T frame, inches.
    pub r: Vector3<T>,
    /// Measured `(X, Y)`, counts.
    pub y: [T; 2],
    /// Which of `X`, `Y` are used (`false`: at or near the 16-bit rail).
    pub used: [bool; 2],
    /// The magnitude as a measured log signal, `ln(M - offset) / exponent - ln b`
    /// ([`Magnitude`]), to set against the model's `ln S` (up to the frame's common scale).
    ///
    /// [`Magnitude`]: super::Magnitude
    pub m: T,
    /// The magnitude's weight, `(noise / sigma_ln)^2` with `noise` the spots' 1-sigma in
    /// counts and `sigma_ln` the magnitude's in `ln S`: its row is in counts as the spots'
    /// are. 0: not used.
    pub mw: T,
}

impl<T: Real> Obs<T> {
    /// Both coordinates used, no magnitude.
    pub fn new(r: Vector3<T>, y: [T; 2]) -> Self {
        Obs {
            r,
            y,
            used: [true; 2],
            m: T::zero(),
            mw: T::zero(),
        }
    }

    /// Whether the magnitude is used.
    pub fn magnitude_used(&self) -> bool {
        self.mw > T::zero()
    }

    /// Usable coordinates (0-2).
    pub fn rows(&self) -> usize {
        usize::from(self.used[0]) + usize::from(self.used[1])
    }
}
