//! The arm law (30) as one phase of a step, and the joint guard.
//!
//! ```text
//! u_q = (∂e_m/∂q)⁻¹ (G e_m − ∂e_m/∂r_b u_b − ∂e_m/∂t)                                (30)
//!     = (∂e_m/∂q)⁻¹ (G e_m − ∂e_m/∂r_bd ṙ_bd − ∂e_m/∂t|explicit),
//! ṙ_bd = R̄(θ_bd) u_d − [I₂ S p_bd; 0 1] u_b                                        (9)
//! ```
//!
//! with `u_b` the platform velocity actually commanded (after saturation), `G = −diag(gᵢ)`.
//!
//! **Over the hold** ([`Discretisation::Midpoint`](crate::Discretisation::Midpoint)) every
//! term is evaluated at the state predicted for the middle of the hold, with the new platform
//! command; the joints there were predicted with the previous `u_q` as a guess, and the
//! difference is corrected to first order: `e_m(q + h/2 u_q) ≈ e_m(q + h/2 u_g) + A h/2
//! (u_q − u_g)`, `A = ∂e_m/∂q`. Writing `v = A u_q`, (30) becomes diagonal in `v`:
//!
//! ```text
//! (1 + gᵢ h/2) vᵢ = (−g ∘ e_m + h/2 g ∘ (A u_g) − ∂e_m/∂r_bd ṙ_bd − ∂e_m/∂t)ᵢ,   u_q = A⁻¹ v
//! ```
//!
//! so `e_m` follows `e_{k+1} = (1 − gh/2)/(1 + gh/2) e_k`: the second-order, A-stable
//! discretisation of `ė_m = G e_m`, for any period. (`A` contains the penalty's curvature
//! `∂²h_ℓ/∂q²`, stiff near a limit, so the correction also keeps the penalty from
//! overshooting.)
//!
//! **The joint guard.** In continuous time the penalty (20)–(21) keeps the joints inside
//! their limits; a held command can still step over one when `u_q` is very large. The guard
//! divides all joint velocities by the smallest factor `s ≥ 1` such that no joint covers more
//! than `κ` of its distance to the limit it moves towards within one period (a
//! fraction-to-the-boundary rule) and none exceeds its velocity limit.

use nalgebra::{SMatrix, SVector, Vector3};

use crate::arm::Arm;
use crate::error::StepError;
use crate::params::Params;
use crate::primary::{base_to_relative, primary_terms, PrimaryPoint, PrimaryTerms};
use crate::scalar::Real;
use crate::se2::{rbar_sc, PoseSc};

/// Where the arm law is evaluated.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ArmPoint<'a, T, const N: usize> {
    /// The primary task's arguments there.
    pub primary: PrimaryPoint<'a, T, N>,
    /// The target seen from the base there, with the sine and cosine of its angle.
    pub r_bd: &'a PoseSc<T>,
    /// The target's body velocity there.
    pub u_d: &'a Vector3<T>,
    /// The platform's body velocity commanded.
    pub u_b: &'a Vector3<T>,
    /// The joints when the command starts to act (the guard's reference).
    pub q_start: &'a SVector<T, N>,
    /// The previous joint command (the guess the point was predicted with).
    pub guess: &'a SVector<T, N>,
}

/// The arm law of a [`ControlLaw`](crate::ControlLaw): its parameters, its arm and the
/// constant `(sin θ*, cos θ*)` of `r*_ed` (borrowed for one step).
#[derive(Clone, Copy, Debug)]
pub(crate) struct ArmLaw<'a, T, A, const N: usize> {
    pub params: &'a Params<T, N>,
    pub arm: &'a A,
    pub rot_star: (T, T),
}

/// The arm part of a step.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ArmStep<T, const N: usize> {
    /// `u_q` after the joint guard.
    pub u_q: SVector<T, N>,
    /// The guard's factor (≥ 1).
    pub joint_scale: T,
    /// The 1-norm condition number of `∂e_m/∂q`.
    pub condition: T,
    /// The primary task at the point.
    pub primary: PrimaryTerms<T, N>,
    /// `∂u_q/∂u_b` at the point: how the joint command answers a change of the platform's
    /// body velocity (the next step's guess uses it).
    pub sensitivity: SMatrix<T, N, 3>,
}

impl<T: Real, A: Arm<T, N>, const N: usize> ArmLaw<'_, T, A, N> {
    /// (30) at `pt` for a hold of `period` seconds, `half` into it.
    #[inline(always)]
    pub(crate) fn arm_step(
        &self,
        pt: &ArmPoint<'_, T, N>,
        period: T,
        half: T,
    ) -> Result<ArmStep<T, N>, StepError> {
        let p = &self.params.primary;
        let prim = primary_terms(p, &self.params.joint_limits, self.arm, &pt.primary, self.rot_star);
        let (s, c) = pt.r_bd.sc;
        let r_bd_rate = rbar_sc(s, c) * pt.u_d - base_to_relative(&pt.r_bd.pose) * pt.u_b;
        let mut rhs = -prim.e_m.component_mul(&p.gain) - prim.de_m_dr_bd * r_bd_rate - prim.de_m_dt_explicit;
        let inv;
        let mut sensitivity = SMatrix::<T, N, 3>::zeros();
        if half > T::zero() {
            // ∂rhs/∂u_b = ∂e_m/∂r_bd [I₂ S p_bd; 0 1], for the next step's guess.
            let (x, y) = (pt.r_bd.pose.x, pt.r_bd.pose.y);
            let b = &prim.de_m_dr_bd;
            let mut drhs = SMatrix::<T, N, 3>::from_fn(|i, j| match j {
                0 => b[(i, 0)],
                1 => b[(i, 1)],
                _ => b[(i, 2)] - y * b[(i, 0)] + x * b[(i, 1)],
            });
            rhs += (prim.de_m_dq * pt.guess).component_mul(&p.gain) * half;
            for i in 0..N {
                let d = T::one() / (T::one() + p.gain[i] * half);
                rhs[i] *= d;
                for j in 0..3 {
                    drhs[(i, j)] *= d;
                }
            }
            inv = prim.de_m_dq.try_inverse().ok_or(StepError::SingularTaskJacobian)?;
            sensitivity = inv * drhs;
        } else {
            inv = prim.de_m_dq.try_inverse().ok_or(StepError::SingularTaskJacobian)?;
        }
        let mut u_q = inv * rhs;
        let condition = one_norm(&prim.de_m_dq) * one_norm(&inv);
        let joint_scale = self.joint_guard(pt.q_start, &u_q, period);
        if joint_scale > T::one() {
            u_q /= joint_scale;
            sensitivity /= joint_scale;
        }
        Ok(ArmStep { u_q, joint_scale, condition, primary: prim, sensitivity })
    }

    /// The joint guard's factor `s ≥ 1` for `u_q` held `period` seconds from `q`.
    #[inline(always)]
    fn joint_guard(&self, q: &SVector<T, N>, u_q: &SVector<T, N>, period: T) -> T {
        let lim = &self.params.joint_limits;
        let kappa = self.params.joint_step_fraction;
        let mut scale = T::one();
        for i in 0..N {
            let u = u_q[i];
            let room = if u > T::zero() { lim.upper[i] - q[i] } else { lim.lower[i] - q[i] };
            // u and room have the same sign; room ≠ 0 (q is strictly inside its limits).
            let r = (u * period) / (kappa * room);
            if r > scale {
                scale = r;
            }
            let v = u.abs() / self.params.joint_velocity_limits[i];
            if v > scale {
                scale = v;
            }
        }
        scale
    }
}

fn one_norm<T: Real, const N: usize>(m: &nalgebra::SMatrix<T, N, N>) -> T {
    let mut best = T::zero();
    for j in 0..N {
        let mut s = T::zero();
        for i in 0..N {
            s += m[(i, j)].abs();
        }
        if s > best || s.nan() {
            best = s;
        }
    }
    best
}
