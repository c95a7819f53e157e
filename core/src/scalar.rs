//! The scalar types the controller runs in: `f64` and `f32`.
//!
//! Every elementary function the law needs goes through [`Real`], so that the host and the
//! firmware call exactly the same implementation and give the same bits, and so that a
//! faster implementation can be swapped in per type: `f64` uses libm (pinned in the
//! workspace); `f32` uses the crate's own f32-native sin/cos, exp, atan, atan2 and round
//! (within 1–2 ulp, see `fastmath.rs`), because libm's `sincosf` works in f64, which a
//! Cortex-M4F does in software, and the FPU's square root (`companion-fpu`: `vsqrt.f32` on a
//! hard-float ARM core, libm's `sqrtf` elsewhere; both correctly rounded, the same bits).

use nalgebra::RealField;

/// A floating-point scalar the controller can run in (`f64` or `f32`).
///
/// The methods are named apart from nalgebra's `ComplexField` ones on purpose: the law
/// calls these, never the platform's, so the arithmetic is the same on every target.
pub trait Real: RealField + Copy + Default + core::fmt::Debug {
    /// Sine and cosine of `self` (radians).
    fn sincos(self) -> (Self, Self);
    /// Arc tangent of `self`, in (−π/2, π/2).
    fn arctan(self) -> Self;
    /// Four-quadrant arc tangent of `self / x`, in (−π, π].
    fn arctan2(self, x: Self) -> Self;
    /// `e^self`.
    fn exponential(self) -> Self;
    /// Square root of `self` (NaN for negative input).
    fn square_root(self) -> Self;
    /// `self` rounded to the nearest integer, halfway cases away from zero.
    fn round_nearest(self) -> Self;
    /// The remainder of `self / y` with the sign of `self`, computed exactly (IEEE `fmod`).
    fn fmod(self, y: Self) -> Self;
    /// Whether `self` is neither infinite nor NaN.
    fn finite(self) -> bool;
    /// Whether `self` is NaN.
    fn nan(self) -> bool;
    /// Converts an `f64` constant (rounding to nearest for `f32`).
    fn of(x: f64) -> Self;
    /// Converts to `f64` (exact for both types).
    fn as_f64(self) -> f64;
}

impl Real for f64 {
    #[inline]
    fn sincos(self) -> (Self, Self) {
        libm::sincos(self)
    }
    #[inline]
    fn arctan(self) -> Self {
        libm::atan(self)
    }
    #[inline]
    fn arctan2(self, x: Self) -> Self {
        libm::atan2(self, x)
    }
    #[inline]
    fn exponential(self) -> Self {
        libm::exp(self)
    }
    #[inline]
    fn square_root(self) -> Self {
        libm::sqrt(self)
    }
    #[inline]
    fn round_nearest(self) -> Self {
        libm::round(self)
    }
    #[inline]
    fn fmod(self, y: Self) -> Self {
        libm::fmod(self, y)
    }
    #[inline]
    fn finite(self) -> bool {
        self.is_finite()
    }
    #[inline]
    fn nan(self) -> bool {
        self.is_nan()
    }
    #[inline]
    fn of(x: f64) -> Self {
        x
    }
    #[inline]
    fn as_f64(self) -> f64 {
        self
    }
}

/// `f32` uses the f32-native functions of `fastmath` (libm's `sincosf` computes in `f64`,
/// in software on a Cortex-M4F); their accuracy is stated and tested there.
impl Real for f32 {
    #[inline]
    fn sincos(self) -> (Self, Self) {
        crate::fastmath::sin_cos(self)
    }
    #[inline]
    fn arctan(self) -> Self {
        crate::fastmath::atan(self)
    }
    #[inline]
    fn arctan2(self, x: Self) -> Self {
        crate::fastmath::atan2(self, x)
    }
    #[inline]
    fn exponential(self) -> Self {
        crate::fastmath::exp(self)
    }
    #[inline]
    fn square_root(self) -> Self {
        // The FPU's instruction on the M4F (one instruction against libm's ~50 of integer
        // code), libm's sqrtf elsewhere: both correctly rounded, so the same bits.
        companion_fpu::sqrt_f32(self)
    }
    #[inline]
    fn round_nearest(self) -> Self {
        crate::fastmath::round(self)
    }
    #[inline]
    fn fmod(self, y: Self) -> Self {
        libm::fmodf(self, y)
    }
    #[inline]
    fn finite(self) -> bool {
        self.is_finite()
    }
    #[inline]
    fn nan(self) -> bool {
        self.is_nan()
    }
    #[inline]
    fn of(x: f64) -> Self {
        x as f32
    }
    #[inline]
    fn as_f64(self) -> f64 {
        f64::from(self)
    }
}

/// Wraps an angle (radians) to (−π, π], for any finite magnitude (NaN for a non-finite
/// one).
///
/// Up to |a| = 10⁵ the angle is reduced as `a − 2π·round(a/2π)`; beyond, where that
/// product would lose the result's bits, by the exact remainder `fmod(a, 2π)` (a cold
/// path). Either way a last correction of ±2π, exact by Sterbenz's lemma, puts the result
/// on the right side of ±π. (2π here is the scalar type's `2π`, so an angle of
/// 10¹⁷ rad wraps to its remainder modulo that number: at such magnitudes the angle
/// itself carries no information, and the point is a value in range.)
#[inline]
pub fn wrap_angle<T: Real>(a: T) -> T {
    let two_pi = T::two_pi();
    let pi = T::pi();
    if a > -pi && a <= pi {
        return a;
    }
    let mut w =
        if a.abs() <= T::of(1e5) { a - two_pi * (a / two_pi).round_nearest() } else { a.fmod(two_pi) };
    // Rounding (or fmod's sign convention) can leave the result beyond ±π.
    if w <= -pi {
        w += two_pi;
    } else if w > pi {
        w -= two_pi;
    }
    w
}
