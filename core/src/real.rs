//! The scalar type: `f32` on the chip (no FPU; soft-float), `f64` on the host.

use nalgebra::{ComplexField, RealField};

/// A real scalar usable by every model and by GLSDC: `f32` or `f64`.
pub trait Real: RealField + Copy + Default {
    /// Convert an `f64` literal to this type.
    fn lit(x: f64) -> Self;
    /// Convert to `f64` (for reports).
    fn to_f64(self) -> f64;
    /// `(sin x, cos x)` of an angle within +/-3 pi / 4: the head's face angles (validated
    /// to 5-85 deg). `(x.sin(), x.cos())` (nalgebra's), except for `f32` without `std` (the chip), where
    /// it is [`crate::trig::sin_cos_f32`]: libm's `sinf` and `cosf` bit for bit in that range
    /// (what `x.sin()` and `x.cos()` are there) without their general argument reduction, and
    /// NaN beyond it.
    fn sin_cos_small(self) -> (Self, Self);
}

impl Real for f64 {
    #[inline(always)]
    fn lit(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline]
    fn sin_cos_small(self) -> (Self, Self) {
        (ComplexField::sin(self), ComplexField::cos(self))
    }
}

impl Real for f32 {
    #[inline(always)]
    fn lit(x: f64) -> Self {
        x as f32
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self as f64
    }
    #[cfg(feature = "std")]
    #[inline]
    fn sin_cos_small(self) -> (Self, Self) {
        (ComplexField::sin(self), ComplexField::cos(self))
    }
    #[cfg(not(feature = "std"))]
    #[inline]
    fn sin_cos_small(self) -> (Self, Self) {
        crate::trig::sin_cos_f32(self)
    }
}

/// Degrees to radians.
#[inline]
pub fn rad<T: Real>(deg: T) -> T {
    deg * T::pi() / T::lit(180.0)
}

/// Radians to degrees.
#[inline]
pub fn deg<T: Real>(rad: T) -> T {
    rad * T::lit(180.0) / T::pi()
}
