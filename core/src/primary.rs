//! The primary (manipulation) task — §3.2 and §4.1.
//!
//! ```text
//! e_p  = (r*_ed)⁻¹ r_ed,  r_ed = r_eb(q) r_bd                                  (42)
//! h_ℓ  = ½ Σ αᵢ fᵢ(qᵢ)²                                                   (20)–(21)
//! h_r  = ½ (q − q̂)ᵀ Γ(t) (q − q̂)                                            (22)
//! e_m  = (∂e_p/∂q)ᵀ e_p + (∂h_ℓ/∂q)ᵀ + Γ(t)(q − q̂)                           (23)
//! ∂e_m/∂q = (∂e_p/∂q)ᵀ ∂e_p/∂q + ∂²h_ℓ/∂q² + Γ(t) + Σ_k e_p,k ∂²e_p,k/∂q²     (24)
//! ```
//!
//! Everything depends on `(q, r_bd, t)`, with `r_bd` the target seen from the base:
//! `ṙ_bd = R̄(θ_bd) u_d − [I₂ S p_bd; 0 1] u_b` (eq. 9). So `∂e_m/∂r_b` and the
//! target's part of `∂e_m/∂t` both follow from one coordinate derivative
//! `∂e_m/∂r_bd` ([`PrimaryTerms::de_m_dr_bd`]).
//!
//! Write `ẽ = r_ed − r*_ed` (componentwise, angle wrapped): `e_p = R̄(−θ*) ẽ`. As
//! `R̄(−θ*)` is a constant rotation, `(∂e_p/∂q)ᵀ e_p`, `‖e_p‖` and `Σ e_p,k ∇²e_p,k` are the
//! same with `ẽ` in place of `e_p`, which is what is computed.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use crate::arm::Arm;
use crate::arm_law::{implicit_rhs, solve_square_into, Linearised};
use crate::error::{ParamError, StepError};
use crate::params::{JointLimits, PrimaryTask};
use crate::scalar::{wrap_angle, Real};
use crate::se2::{rbar_sc, Pose};
use crate::space::Planar;
use crate::task::{Manipulator, TaskPoint, TaskStep};

/// The primary-task quantities at one `(q, r_bd, t)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimaryTerms<T, const N: usize> {
    /// `e_p`, eq. (42).
    pub e_p: Vector3<T>,
    /// `∂e_p/∂q` (3×N), eq. (48) (rotated by `R̄(−θ*)` for a general `r*_ed`).
    pub de_p_dq: SMatrix<T, 3, N>,
    /// `e_m`, eq. (23).
    pub e_m: SVector<T, N>,
    /// `∂e_m/∂q`, eq. (24), with the second-derivative term.
    pub de_m_dq: SMatrix<T, N, N>,
    /// `∂e_m/∂r_bd`: ordinary derivative with respect to the coordinates of `r_bd`.
    pub de_m_dr_bd: SMatrix<T, N, 3>,
    /// The explicit time derivative of `e_m` through `Γ(t)` and `q̂(t)`:
    /// `Γ̇ (q − q̂) − Γ q̂̇`.
    pub de_m_dt_explicit: SVector<T, N>,
    /// `h_ℓ(q)`, eq. (20).
    pub h_l: T,
}

/// `fᵢ(qᵢ)` of eq. (21) with its first two derivatives, for `q⁻ < q < q⁺`.
///
/// With `a` the depth into the band and `b` the distance to the limit (`a + b = δ`):
/// `f = a²/b`, `f' = ∓ a (a + 2b)/b²`, `f'' = 2δ²/b³`.
#[inline]
pub fn penalty<T: Real>(q: T, lower: T, upper: T, delta: T) -> (T, T, T) {
    let two = T::of(2.0);
    if q < lower + delta {
        let a = lower + delta - q;
        let b = q - lower;
        let ib = T::one() / b;
        (a * a * ib, -a * (a + two * b) * ib * ib, two * delta * delta * ib * ib * ib)
    } else if q > upper - delta {
        let a = q - (upper - delta);
        let b = upper - q;
        let ib = T::one() / b;
        (a * a * ib, a * (a + two * b) * ib * ib, two * delta * delta * ib * ib * ib)
    } else {
        (T::zero(), T::zero(), T::zero())
    }
}

/// `q̂̇ = −σ (q̂ − q)/(ξ + ‖q̂ − q‖)`, eq. (26).
#[inline]
pub fn filter_rate<T: Real, const N: usize>(
    q_hat: &SVector<T, N>,
    q: &SVector<T, N>,
    sigma: T,
    xi: T,
) -> SVector<T, N> {
    let d = q_hat - q;
    let n = d.dot(&d).square_root();
    d * (-sigma / (xi + n))
}

/// The arguments of the primary task at one point (`R`: the pose type of `r_bd`, planar by
/// default; [`SpatialPoint`](crate::SpatialPoint) in space).
#[derive(Clone, Copy, Debug)]
pub struct PrimaryPoint<'a, T, const N: usize, R = Pose<T>> {
    /// Joint positions `q`.
    pub q: &'a SVector<T, N>,
    /// The target's pose seen from the base, `r_bd`.
    pub r_bd: &'a R,
    /// `Γ` of (22) (the scalar of `Γ I`).
    pub gamma: T,
    /// `Γ̇`.
    pub gamma_rate: T,
    /// The filtered joints `q̂` of (26).
    pub q_hat: &'a SVector<T, N>,
    /// Their rate `q̂̇`.
    pub q_hat_rate: &'a SVector<T, N>,
}

/// Evaluates the primary task at a point. `rot_star = (sin θ*, cos θ*)` of `r*_ed`.
#[inline(always)]
pub fn primary_terms<T: Real, A: Arm<T, N>, const N: usize>(
    task: &PrimaryTask<T, N>,
    limits: &JointLimits<T, N>,
    arm: &A,
    point: &PrimaryPoint<'_, T, N>,
    rot_star: (T, T),
) -> PrimaryTerms<T, N> {
    let PrimaryPoint { q, r_bd, gamma, gamma_rate, q_hat, q_hat_rate } = *point;
    let kin = arm.kinematics(q);
    let r_eb = kin.r_eb;
    let (s, c) = kin.sin_cos_theta;
    // rp = R(θ_eb) p_bd; r_ed = r_eb r_bd.
    let rp = (c * r_bd.x - s * r_bd.y, s * r_bd.x + c * r_bd.y);
    let target = &task.target_in_effector;
    let e = Vector3::new(
        r_eb.x + rp.0 - target.x,
        r_eb.y + rp.1 - target.y,
        wrap_angle(r_eb.theta + r_bd.theta - target.theta),
    );
    let (ss, cs) = rot_star;
    let e_p = Vector3::new(cs * e[0] + ss * e[1], -ss * e[0] + cs * e[1], e[2]);

    // ∂ẽ/∂q = M ∂r_eb/∂q with M = [I₂ R(θ_eb) S p_bd; 0 1] and R S p_bd = S rp = (−rp_y, rp_x).
    let m = (-rp.1, rp.0);
    let jb = &kin.jacobian;
    let mut j = *jb;
    for k in 0..N {
        j[(0, k)] += m.0 * jb[(2, k)];
        j[(1, k)] += m.1 * jb[(2, k)];
    }
    let jt = j.transpose();

    // Joint-limit penalty (20)–(21).
    let mut grad_l = SVector::<T, N>::zeros();
    let mut hess_l = SVector::<T, N>::zeros();
    let mut h_l = T::zero();
    let half = T::of(0.5);
    for i in 0..N {
        let w = task.penalty_weight[i];
        let (f, f1, f2) = penalty(q[i], limits.lower[i], limits.upper[i], task.penalty_margin[i]);
        h_l += half * w * f * f;
        grad_l[i] = w * f * f1;
        hess_l[i] = w * (f1 * f1 + f * f2);
    }

    let dq = q - q_hat;
    let e_m = jt * e + grad_l + dq * gamma;

    // Σ_k ẽ_k ∇²ẽ_k = ẽx Hx + ẽy Hy + ẽθ Hθ − (ẽ_xy·rp) ∇θ∇θᵀ + (ẽ_xy·S rp) Hθ.
    let [hx, hy, hth] = &kin.hessian;
    let grad_th = jb.row(2).transpose();
    let e_dot_rp = e[0] * rp.0 + e[1] * rp.1;
    let e_dot_srp = e[0] * m.0 + e[1] * m.1;
    // (24), assembled on the upper triangle (the matrix is symmetric) in one pass.
    let k_th = e[2] + e_dot_srp;
    let theta_curved = A::THETA_CURVED;
    let mut de_m_dq = SMatrix::<T, N, N>::zeros();
    for col in 0..N {
        for row in 0..=col {
            let mut v = j[(0, row)] * j[(0, col)] + j[(1, row)] * j[(1, col)] + j[(2, row)] * j[(2, col)];
            v += hx[(row, col)] * e[0] + hy[(row, col)] * e[1];
            if theta_curved {
                v += hth[(row, col)] * k_th;
            }
            v -= grad_th[row] * grad_th[col] * e_dot_rp;
            de_m_dq[(row, col)] = v;
            de_m_dq[(col, row)] = v;
        }
    }
    for i in 0..N {
        de_m_dq[(i, i)] += hess_l[i] + gamma;
    }

    // ∂e_m/∂r_bd = (∂r_eb/∂q)ᵀ B, B = Ṁᵀ-term + Mᵀ R̄(θ_eb) (see the module docs).
    // Row 3 of the Ṁᵀ ẽ term: ẽ_xyᵀ R(θ_eb) S = (a₁, −a₀) with (a₀, a₁) = R(θ_eb)ᵀ ẽ_xy.
    let a0 = c * e[0] + s * e[1];
    let a1 = -s * e[0] + c * e[1];
    let (b20, b21) = (m.0 * c + m.1 * s + a1, -m.0 * s + m.1 * c - a0);
    let de_m_dr_bd = SMatrix::<T, N, 3>::from_fn(|i, col| {
        let (x, y, t) = (jb[(0, i)], jb[(1, i)], jb[(2, i)]);
        match col {
            0 => x * c + y * s + t * b20,
            1 => -x * s + y * c + t * b21,
            _ => t,
        }
    });
    let de_m_dt_explicit = dq * gamma_rate - q_hat_rate * gamma;

    // e_p's Jacobian in the rotated frame of r*_ed (for reporting and tests).
    let mut de_p_dq = j;
    for k in 0..N {
        let (x, y) = (j[(0, k)], j[(1, k)]);
        de_p_dq[(0, k)] = cs * x + ss * y;
        de_p_dq[(1, k)] = -ss * x + cs * y;
    }
    PrimaryTerms { e_p, de_p_dq, e_m, de_m_dq, de_m_dr_bd, de_m_dt_explicit, h_l }
}

/// `[I₂ S p_bd; 0 1]`: `ṙ_bd = R̄(θ_bd) u_d − P u_b` with `P` this matrix (eq. 9).
#[inline]
pub fn base_to_relative<T: Real>(r_bd: &Pose<T>) -> Matrix3<T> {
    let (z, o) = (T::zero(), T::one());
    Matrix3::new(o, z, -r_bd.y, z, o, r_bd.x, z, z, o)
}

/// Every planar arm is a [`Manipulator`] of the plane: (30) with `e_m` (23) over the hold,
/// solved with `(∂e_m/∂q)⁻¹`.
impl<T: Real, A: Arm<T, N>, const N: usize> Manipulator<T, N> for A {
    type Space = Planar;

    fn validate_arm(&self) -> Result<(), ParamError> {
        Arm::validate(self)
    }

    #[inline]
    fn check_joints(&self, q: &SVector<T, N>) -> Result<(), StepError> {
        if self.is_singular(q) {
            Err(StepError::SingularArm)
        } else {
            Ok(())
        }
    }

    #[inline(always)]
    fn arm_law(
        &self,
        task: &PrimaryTask<T, N>,
        limits: &JointLimits<T, N>,
        star: &(T, T),
        pt: &TaskPoint<'_, T, N, Planar>,
        half: T,
    ) -> Result<TaskStep<T, N, Planar>, StepError> {
        let point = PrimaryPoint {
            q: pt.q,
            r_bd: &pt.r_bd.pose,
            gamma: pt.gamma,
            gamma_rate: pt.gamma_rate,
            q_hat: pt.q_hat,
            q_hat_rate: pt.q_hat_rate,
        };
        let prim = primary_terms(task, limits, self, &point, *star);
        let (s, c) = pt.r_bd.sc;
        let r_bd_rate = rbar_sc(s, c) * pt.u_d - base_to_relative(&pt.r_bd.pose) * pt.u_b;
        let transport = prim.de_m_dr_bd * r_bd_rate;
        // ∂rhs/∂u_b = ∂e_m/∂r_bd [I₂ S p_bd; 0 1].
        let (x, y) = (pt.r_bd.pose.x, pt.r_bd.pose.y);
        let b = &prim.de_m_dr_bd;
        let drhs = SMatrix::<T, N, 3>::from_fn(|i, j| match j {
            0 => b[(i, 0)],
            1 => b[(i, 1)],
            _ => b[(i, 2)] - y * b[(i, 0)] + x * b[(i, 1)],
        });
        let lin = Linearised {
            e: &prim.e_m,
            a: &prim.de_m_dq,
            transport: &transport,
            explicit: &prim.de_m_dt_explicit,
            drhs,
        };
        let (rhs, drhs) = implicit_rhs(&lin, &task.gain, pt.guess, half);
        let mut step = TaskStep {
            u_q: SVector::zeros(),
            sensitivity: SMatrix::zeros(),
            condition: T::zero(),
            e_p: prim.e_p,
            e_m: prim.e_m,
            h_l: prim.h_l,
        };
        step.condition = solve_square_into(
            &prim.de_m_dq,
            &rhs,
            &drhs,
            T::zero(),
            half,
            &mut step.u_q,
            &mut step.sensitivity,
        )?;
        Ok(step)
    }
}
