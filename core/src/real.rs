//! The scalar type: `f32` on the chip (no FPU; soft-float), `f64` on the host.

use nalgebra::RealField;

/// A real scalar usable by every model and by GLSDC: `f32` or `f64`.
pub trait Real: RealField + Copy + Default {
    /// Convert an `f64` literal to this type.
    fn lit(x: f64) -> Self;
    /// Convert to `f64` (for reports).
    fn to_f64(self) -> f64;
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
