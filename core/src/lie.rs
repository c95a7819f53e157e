//! The operations SE(2) and SE(3) share, as one trait, so that one conformance suite
//! (`core/tests/suite/lie.rs`) checks both groups against the same axioms and the same
//! finite differences — as sophus runs one test suite against every group.
//!
//! Tangent vectors are body twists `ξ` with the linear part first: `(v₁, v₂, ω)` in SE(2),
//! `(v, ω)` in SE(3). Jacobians are right Jacobians (perturbations on the right, in the
//! body frame — the sense of the paper's eq. (10)):
//!
//! ```text
//! exp(ξ + δ)      ≈ exp(ξ) exp(J_r(ξ) δ)
//! log(x exp(δ))   ≈ log(x) + J_r(log x)⁻¹ δ
//! x exp(ξ) x⁻¹    = exp(Ad_x ξ)
//! (x exp δ) y     = x y exp(Ad_{y⁻¹} δ),   (x exp δ)⁻¹ = x⁻¹ exp(−Ad_x δ)
//! ```
//!
//! SE(2), with `θ` wrapped to (−π, π] by `log`, `A = sin θ/θ`, `B = (1 − cos θ)/θ²`,
//! `C = (θ − sin θ)/θ³`:
//!
//! ```text
//! exp ξ   = (V(θ) v, θ),   V = [A  −θB; θB  A]
//! log r   = (V⁻¹ p, θ),    V⁻¹ = [h  θ/2; −θ/2  h],  h = (θ/2) cot(θ/2)
//! J_r(ξ)  = [A  θB  v₁θC − v₂B;  −θB  A  v₁B + v₂θC;  0 0 1]
//! J_r⁻¹   = [M⁻¹  −M⁻¹ m; 0 1],  M⁻¹ = [A −θB; θB A]/(2B)   (M, m: the blocks of J_r)
//! ```
//!
//! SE(3): [`crate::se3`].

use nalgebra::{Matrix3, SMatrix, SVector, Vector3, Vector6};

use crate::scalar::{wrap_angle, Real};
use crate::se2::{Pose, PoseSc};
use crate::se3::{Matrix6, Pose3};
use crate::so3;

/// A matrix Lie group with `DOF`-dimensional body twists.
pub trait LieGroup<T: Real, const DOF: usize>: Copy + core::fmt::Debug {
    /// The identity `e`.
    fn identity() -> Self;
    /// The product `self · other`.
    fn compose(&self, other: &Self) -> Self;
    /// The inverse.
    fn inverse(&self) -> Self;
    /// `exp ξ`: the element reached from `e` after one second at body twist `ξ`.
    fn exp(xi: &SVector<T, DOF>) -> Self;
    /// `log x`, the inverse of `exp` on the principal domain (rotation angle in (−π, π]).
    fn log(&self) -> SVector<T, DOF>;
    /// `Ad_x`: `x exp(ξ) x⁻¹ = exp(Ad_x ξ)`.
    fn adjoint(&self) -> SMatrix<T, DOF, DOF>;
    /// `J_r(ξ)`: `exp(ξ + δ) ≈ exp(ξ) exp(J_r(ξ) δ)`.
    fn right_jacobian(xi: &SVector<T, DOF>) -> SMatrix<T, DOF, DOF>;
    /// `J_r(ξ)⁻¹`: `log(x exp(δ)) ≈ log(x) + J_r(log x)⁻¹ δ`.
    fn right_jacobian_inv(xi: &SVector<T, DOF>) -> SMatrix<T, DOF, DOF>;
}

impl<T: Real> LieGroup<T, 3> for Pose<T> {
    fn identity() -> Self {
        Pose::identity()
    }

    fn compose(&self, other: &Self) -> Self {
        Pose::compose(self, other)
    }

    fn inverse(&self) -> Self {
        Pose::inverse(self)
    }

    fn exp(xi: &Vector3<T>) -> Self {
        PoseSc::exp(xi, T::one()).pose
    }

    fn log(&self) -> Vector3<T> {
        let theta = wrap_angle(self.theta);
        let t = theta * theta;
        let h = if t < so3::series_below::<T>() {
            so3::horner(
                t,
                &[1.0, -1.0 / 12.0, -1.0 / 720.0, -1.0 / 30_240.0, -1.0 / 1_209_600.0, -1.0 / 47_900_160.0],
            )
        } else {
            let (s, c) = theta.sincos();
            theta * T::of(0.5) * s / (T::one() - c)
        };
        let ht = theta * T::of(0.5);
        Vector3::new(h * self.x + ht * self.y, -ht * self.x + h * self.y, theta)
    }

    fn adjoint(&self) -> Matrix3<T> {
        self.ad()
    }

    fn right_jacobian(xi: &Vector3<T>) -> Matrix3<T> {
        let th = xi[2];
        let (a, b, c, _, _) = so3::ratios(th * th);
        let (v1, v2) = (xi[0], xi[1]);
        let z = T::zero();
        Matrix3::new(a, th * b, v1 * th * c - v2 * b, -th * b, a, v1 * b + v2 * th * c, z, z, T::one())
    }

    fn right_jacobian_inv(xi: &Vector3<T>) -> Matrix3<T> {
        let th = xi[2];
        let (a, b, _, _, _) = so3::ratios(th * th);
        let j = Self::right_jacobian(xi);
        let k = T::one() / (b * T::of(2.0));
        let (m00, m01, m10, m11) = (a * k, -th * b * k, th * b * k, a * k);
        let (x, y) = (j[(0, 2)], j[(1, 2)]);
        let z = T::zero();
        Matrix3::new(m00, m01, -(m00 * x + m01 * y), m10, m11, -(m10 * x + m11 * y), z, z, T::one())
    }
}

impl<T: Real> LieGroup<T, 6> for Pose3<T> {
    fn identity() -> Self {
        Pose3::identity()
    }

    fn compose(&self, other: &Self) -> Self {
        Pose3::compose(self, other)
    }

    fn inverse(&self) -> Self {
        Pose3::inverse(self)
    }

    fn exp(xi: &Vector6<T>) -> Self {
        Pose3::exp(xi)
    }

    fn log(&self) -> Vector6<T> {
        Pose3::log(self)
    }

    fn adjoint(&self) -> Matrix6<T> {
        Pose3::adjoint(self)
    }

    fn right_jacobian(xi: &Vector6<T>) -> Matrix6<T> {
        Pose3::right_jacobian(xi)
    }

    fn right_jacobian_inv(xi: &Vector6<T>) -> Matrix6<T> {
        Pose3::right_jacobian_inv(xi)
    }
}
