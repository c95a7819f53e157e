//! The manipulator arm: its forward kinematics `r_eb(q)` with first and second
//! derivatives, behind a trait with a const-generic joint count `N`.
//!
//! The law needs only `r_eb(q)` — the platform's pose seen from the end effector — and
//! its derivatives (§4.1), so any planar arm can be plugged in without touching the law.
//! The paper's RPR arm (45) is [`Rpr`].

use nalgebra::{SMatrix, SVector};

use crate::error::{Bound, ParamError, Rule};
use crate::scalar::Real;
use crate::se2::Pose;

/// `r_eb(q)` with its derivatives at one joint configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArmKinematics<T, const N: usize> {
    /// `r_eb(q) = (x_eb, y_eb, θ_eb)`: the platform frame seen from the end effector.
    pub r_eb: Pose<T>,
    /// `∂r_eb/∂q` (3×N), ordinary partial derivatives of `(x_eb, y_eb, θ_eb)`.
    pub jacobian: SMatrix<T, 3, N>,
    /// The Hessians `∂²x_eb/∂q²`, `∂²y_eb/∂q²`, `∂²θ_eb/∂q²` (each N×N, symmetric).
    pub hessian: [SMatrix<T, N, N>; 3],
    /// `(sin θ_eb, cos θ_eb)`: arms usually know them from their own trigonometry, which
    /// saves the law a call.
    pub sin_cos_theta: (T, T),
}

/// A planar manipulator arm with `N` joints mounted on the platform.
pub trait Arm<T: Real, const N: usize>: Copy + core::fmt::Debug {
    /// Whether `∂²θ_eb/∂q²` may be non-zero. Planar arms of revolute and prismatic joints
    /// have `θ_eb` linear in `q` (minus a sum of joint angles) and may set this to `false`,
    /// which lets the law skip that term of (24); the default is the safe `true`.
    const THETA_CURVED: bool = true;

    /// Checks the geometry (e.g. positive link lengths).
    ///
    /// # Errors
    /// The first parameter that breaks a rule.
    fn validate(&self) -> Result<(), ParamError>;

    /// `r_eb(q)` with first and second derivatives.
    fn kinematics(&self, q: &SVector<T, N>) -> ArmKinematics<T, N>;

    /// Whether `q` is a singular configuration of the arm, where `∂r_eb/∂q` loses rank.
    fn is_singular(&self, q: &SVector<T, N>) -> bool;
}

/// The paper's RPR arm, eq. (45): a revolute joint at `(L, 0)` on the platform, a
/// prismatic joint of extension `q₂`, a revolute joint, and the end effector `L_e` further.
///
/// ```text
/// r_eb(q) = ( −R(−q₁−q₃)(L, 0)ᵀ − R(−q₃)(q₂, 0)ᵀ − (L_e, 0)ᵀ ,  −q₁ − q₃ )
/// det ∂r_eb/∂q = q₂            (singular at q₂ = 0)
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rpr<T> {
    /// `L` (m): position of the first joint's axis on the platform's axis.
    pub l: T,
    /// `L_e` (m): distance from the last joint's axis to the end effector.
    pub l_e: T,
}

impl<T: Real> Rpr<T> {
    /// The paper's §4.3 geometry `L = 0.4 m`, `L_e = 0.15 m`.
    pub fn paper() -> Self {
        Self { l: T::of(0.4), l_e: T::of(0.15) }
    }

    /// The end effector's pose seen from the platform, `r_be = r_eb⁻¹`.
    pub fn end_effector(&self, q: &SVector<T, 3>) -> Pose<T> {
        let (s1, c1) = q[0].sincos();
        let (s13, c13) = (q[0] + q[2]).sincos();
        Pose::new(self.l + q[1] * c1 + self.l_e * c13, q[1] * s1 + self.l_e * s13, q[0] + q[2])
    }
}

impl<T: Real> Arm<T, 3> for Rpr<T> {
    /// `θ_eb = −(q₁ + q₃)` is linear.
    const THETA_CURVED: bool = false;

    fn validate(&self) -> Result<(), ParamError> {
        for (name, v) in [("l", self.l), ("l_e", self.l_e)] {
            if !v.finite() {
                return Err(ParamError::new(name, Rule::NonFinite));
            }
            if v < T::zero() {
                return Err(ParamError::new(name, Rule::Geometry));
            }
            if v > T::of(Bound::Length.value()) {
                return Err(ParamError::new(name, Rule::TooLarge(Bound::Length)));
            }
        }
        Ok(())
    }

    #[inline]
    fn kinematics(&self, q: &SVector<T, 3>) -> ArmKinematics<T, 3> {
        let (l, le) = (self.l, self.l_e);
        let q2 = q[1];
        let (s13, c13) = (q[0] + q[2]).sincos();
        let (s3, c3) = q[2].sincos();
        let r_eb = Pose::new(-l * c13 - q2 * c3 - le, l * s13 + q2 * s3, -q[0] - q[2]);
        let z = T::zero();
        let one = T::one();
        #[rustfmt::skip]
        let jacobian = SMatrix::<T, 3, 3>::new(
            l * s13, -c3, l * s13 + q2 * s3,
            l * c13,  s3, l * c13 + q2 * c3,
            -one,      z, -one,
        );
        #[rustfmt::skip]
        let hx = SMatrix::<T, 3, 3>::new(
            l * c13, z,  l * c13,
            z,       z,  s3,
            l * c13, s3, l * c13 + q2 * c3,
        );
        #[rustfmt::skip]
        let hy = SMatrix::<T, 3, 3>::new(
            -l * s13, z,  -l * s13,
            z,        z,  c3,
            -l * s13, c3, -l * s13 - q2 * s3,
        );
        // θ_eb = −(q₁ + q₃).
        ArmKinematics { r_eb, jacobian, hessian: [hx, hy, SMatrix::zeros()], sin_cos_theta: (-s13, c13) }
    }

    #[inline]
    fn is_singular(&self, q: &SVector<T, 3>) -> bool {
        // det ∂r_eb/∂q = q₂: the arm is singular at q₂ = 0 and folded beyond it.
        q[1] <= T::zero()
    }
}
