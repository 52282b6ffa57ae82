//! The float type the CPU path is generic over: `f32` for speed, `f64` as the oracle.

use num_traits::Float;
use std::fmt::Debug;
use std::iter::Sum;
use std::ops::{AddAssign, MulAssign, SubAssign};

/// A float the CPU rasterizer can run in.
pub trait Real:
    Float + Debug + Default + Send + Sync + Sum + AddAssign + SubAssign + MulAssign + 'static
{
    /// Converts an `f64` constant (exact for f64, rounded for f32).
    fn lit(v: f64) -> Self;
    /// Widens to `f64` (for radii, tile bounds and reports).
    fn to_f64_lossy(self) -> f64;
}

impl Real for f32 {
    #[inline(always)]
    fn lit(v: f64) -> Self {
        v as f32
    }
    #[inline(always)]
    fn to_f64_lossy(self) -> f64 {
        self as f64
    }
}

impl Real for f64 {
    #[inline(always)]
    fn lit(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn to_f64_lossy(self) -> f64 {
        self
    }
}
