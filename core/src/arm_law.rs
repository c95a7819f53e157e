//! The arm law (30) as one phase of a step: its discretisation over the hold, shared by
//! every arm ([`crate::task`]), and the joint guard.
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
//! overshooting.) The same step serves any task function `e` with `ė = A u_q + …`: `e_m`
//! (as many task rows as joints: [`solve_square_into`]) or, for an arm with more joints than the
//! task has dimensions, `e_p` itself ([`solve_redundant`]), where `A u_q = v` holds for the
//! pseudo-inverse solution with any null-space motion added.
//!
//! **Redundant arms** (`N` joints, `M < N` task rows): with `W = diag(wᵢ) > 0`,
//!
//! ```text
//! u_q = A_W⁺ v + (I − A_W⁺ A) z,   A_W⁺ = W⁻¹ Aᵀ (A W⁻¹ Aᵀ)⁻¹,   z = −k_n W⁻¹ ∇h_ℓ
//! ```
//!
//! `A u_q = v` exactly (the task is met as if the arm had `M` joints), and the null-space
//! motion changes `h_ℓ` at the rate `∇h_ℓᵀ (I − A_W⁺ A) z = −k_n ∇h_ℓᵀ P_W ∇h_ℓ ≤ 0`, with
//! `P_W = W⁻¹ − W⁻¹Aᵀ(AW⁻¹Aᵀ)⁻¹AW⁻¹` symmetric positive semi-definite: it never raises
//! the penalty. The weights `wᵢ = 1 + ∂²h_ℓ/∂qᵢ²` (the penalty's curvature, zero outside
//! its band) do two things: joints deep in their band take a smaller share of the task's
//! motion (the weighted least norm of Chan and Dubey, IEEE T-RA 1995, with a weight that
//! is smooth in `q` rather than switched by the direction of motion), and `W⁻¹∇h_ℓ` is a
//! damped Newton step on the barrier — near a limit `≈ (b/3)` with `b` the distance to it —
//! so the null-space motion has rate at most `k_n` however steep the penalty, and a held
//! command cannot overshoot a limit through it. Near singular configurations the caller may
//! add `λ² I` to the matrix it inverts (`∂e_m/∂q`, or `S = A W⁻¹ Aᵀ`): the damped,
//! singularity-robust solution ([`crate::spatial`] says when); the planar arm never does.
//!
//! **The joint guard.** In continuous time the penalty (20)–(21) keeps the joints inside
//! their limits; a held command can still step over one when `u_q` is very large. The guard
//! divides all joint velocities by the smallest factor `s ≥ 1` such that no joint covers more
//! than `κ` of its distance to the limit it moves towards within one period (a
//! fraction-to-the-boundary rule) and none exceeds its velocity limit. With joint
//! acceleration limits `aᵢ` it also keeps each joint able to stop within that fraction,
//! `|u| ≤ √(2 a κ d) − a h/2`, and then the change from the previous joint command sent is
//! divided by a second common factor ([`crate::acceleration`], where the equations are).

use nalgebra::{SMatrix, SVector};

use crate::acceleration::{braking_factor, change_factor, each_towards, reported_factor, towards};
use crate::error::StepError;
use crate::linalg;
use crate::params::Params;
use crate::scalar::Real;
use crate::space::Space;
use crate::task::{Manipulator, TaskPoint, TaskStep};

/// A task function `e` linearised at the evaluation point: `ė = A u_q + …`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Linearised<'a, T, const M: usize, const N: usize> {
    /// The task function driven by `ė = G e`: `e_m` (23), or `e_p` for redundant arms.
    pub e: &'a SVector<T, M>,
    /// `A = ∂e/∂q`.
    pub a: &'a SMatrix<T, M, N>,
    /// `∂e/∂r_bd ṙ_bd`: the rate of `e` through the target's motion seen from the base.
    pub transport: &'a SVector<T, M>,
    /// `∂e/∂t`, explicit (through `Γ(t)` and `q̂(t)`).
    pub explicit: &'a SVector<T, M>,
    /// `∂rhs/∂u_b = −∂(transport)/∂u_b`.
    pub drhs: SMatrix<T, M, 3>,
}

/// The right-hand side `v` of (30) over the hold and `∂v/∂u_b` (module docs): `A u_q = v`.
#[inline(always)]
pub(crate) fn implicit_rhs<T: Real, const M: usize, const N: usize>(
    lin: &Linearised<'_, T, M, N>,
    gain: &SVector<T, M>,
    guess: &SVector<T, N>,
    half: T,
) -> (SVector<T, M>, SMatrix<T, M, 3>) {
    let mut rhs = -lin.e.component_mul(gain) - lin.transport - lin.explicit;
    let mut drhs = lin.drhs;
    if half > T::zero() {
        rhs += (lin.a * guess).component_mul(gain) * half;
        for i in 0..M {
            let d = T::one() / (T::one() + gain[i] * half);
            rhs[i] *= d;
            for j in 0..3 {
                drhs[(i, j)] *= d;
            }
        }
    }
    (rhs, drhs)
}

/// `u_q = A⁻¹ v`, its sensitivity `A⁻¹ ∂v/∂u_b` (with the hold-aware discretisation only) and
/// the 1-norm condition number of `A`.
///
/// When `A` cannot be inverted in the scalar type (its determinant rounds to zero) although
/// the configuration is not singular — measured in `f32` with the target tens of kilometres
/// away, where `Σ e_p,k ∇²e_p,k` of (24) dwarfs `(∂e_p/∂q)ᵀ ∂e_p/∂q` — it solves the damped
/// least-squares problem instead, `(AᵀA + μ I) u_q = Aᵀ v` with `μ = 10⁻⁶ tr(AᵀA)/N`
/// (symmetric positive definite, so always solvable unless `A = 0`). Rejecting such steps
/// kept the robot still with its arm where `A` is singular, so every later step was rejected
/// too: a lock-out (fuzz, 10⁷ steps). The fallback never acts where `A` is invertible, so it
/// changes no other step.
///
/// It writes `u_q` and the sensitivity where the caller wants them (its [`TaskStep`]) and
/// returns the condition number: a returned tuple was copied twice on the way, ~300
/// instructions for six joints on the Cortex-M4F.
#[inline(always)]
pub(crate) fn solve_square_into<T: Real, const N: usize>(
    a: &SMatrix<T, N, N>,
    rhs: &SVector<T, N>,
    drhs: &SMatrix<T, N, 3>,
    damping: T,
    half: T,
    u_q: &mut SVector<T, N>,
    sensitivity: &mut SMatrix<T, N, 3>,
) -> Result<T, StepError> {
    // A + λ² I, inverted in place (its off-diagonal entries are A's: `a + 0` is `a`, but
    // for the sign of a zero).
    let mut inv = *a;
    if damping > T::zero() {
        for i in 0..N {
            inv[(i, i)] += damping;
        }
    }
    let norm = one_norm(&inv);
    if !linalg::invert(&mut inv) {
        let damped = if damping > T::zero() { a + SMatrix::<T, N, N>::identity() * damping } else { *a };
        let (u, s, condition) = least_squares(&damped, rhs, drhs, half)?;
        *u_q = u;
        *sensitivity = s;
        return Ok(condition);
    }
    *u_q = linalg::mul(&inv, rhs);
    // Only the hold-aware discretisation guesses with it.
    *sensitivity = if half > T::zero() { linalg::mul(&inv, drhs) } else { SMatrix::zeros() };
    Ok(norm * one_norm(&inv))
}

/// The damped least-squares fallback of [`solve_square_into`] for an `A` that rounds to singular.
#[cold]
#[inline(never)]
fn least_squares<T: Real, const N: usize>(
    a: &SMatrix<T, N, N>,
    rhs: &SVector<T, N>,
    drhs: &SMatrix<T, N, 3>,
    half: T,
) -> Result<(SVector<T, N>, SMatrix<T, N, 3>, T), StepError> {
    let at = a.transpose();
    let mut n = at * a;
    let (mut trace, mut count) = (T::zero(), T::zero());
    for i in 0..N {
        trace += n[(i, i)];
        count += T::one();
    }
    let mu = T::of(1e-6) * trace / count;
    let usable = mu > T::zero() && mu.finite();
    if !usable {
        return Err(StepError::SingularTaskJacobian);
    }
    for i in 0..N {
        n[(i, i)] += mu;
    }
    let inv = linalg::inverse(&n).ok_or(StepError::SingularTaskJacobian)?;
    let pinv = inv * at;
    let u_q = pinv * rhs;
    let sensitivity = if half > T::zero() { pinv * drhs } else { SMatrix::zeros() };
    let condition = one_norm(&n) * one_norm(&inv);
    Ok((u_q, sensitivity, condition))
}

/// The redundant solution of the module docs: `u_q = A_W⁺ v + (I − A_W⁺ A) z` with
/// `W = diag(w)`, its sensitivity `A_W⁺ ∂v/∂u_b`, and the condition number of `A W⁻¹ Aᵀ`.
#[inline(always)]
pub(crate) fn solve_redundant<T: Real, const M: usize, const N: usize>(
    a: &SMatrix<T, M, N>,
    w: &SVector<T, N>,
    z: &SVector<T, N>,
    rhs: &SVector<T, M>,
    drhs: &SMatrix<T, M, 3>,
    damping: impl FnOnce(&SMatrix<T, M, M>) -> T,
    half: T,
) -> Result<(SVector<T, N>, SMatrix<T, N, 3>, T), StepError> {
    let w_inv = w.map(|x| T::one() / x);
    // B = W⁻¹ Aᵀ (N×M), S = A B (+ λ² I).
    let b = SMatrix::<T, N, M>::from_fn(|i, j| a[(j, i)] * w_inv[i]);
    let mut s = a * b;
    let lambda2 = damping(&s);
    if lambda2 > T::zero() {
        for i in 0..M {
            s[(i, i)] += lambda2;
        }
    }
    let s_inv = linalg::inverse(&s).ok_or(StepError::SingularTaskJacobian)?;
    let pinv = b * s_inv;
    // (I − A⁺A) z = z − A⁺ (A z).
    let u_q = pinv * (rhs - a * z) + z;
    let sensitivity = if half > T::zero() { pinv * drhs } else { SMatrix::zeros() };
    let condition = one_norm(&s) * one_norm(&s_inv);
    Ok((u_q, sensitivity, condition))
}

/// The arm law of a [`ControlLaw`](crate::ControlLaw): its parameters, its arm and what the
/// arm's task precomputes from `r*_ed` (borrowed for one step).
#[derive(Clone, Copy, Debug)]
pub(crate) struct ArmLaw<'a, T: Real, A: Manipulator<T, N>, const N: usize> {
    pub params: &'a Params<T, N, A::Space>,
    pub arm: &'a A,
    pub star: &'a <A::Space as Space<T>>::Star,
    /// Whether a joint has an acceleration limit (the guard's braking bound applies).
    pub braking: bool,
}

impl<T: Real, A: Manipulator<T, N>, const N: usize> ArmLaw<'_, T, A, N> {
    /// (30) at `pt` for a hold of `period` seconds, `half` into it, with the joint guard
    /// from the joints `q_start` at which the command starts to act.
    #[inline(always)]
    pub(crate) fn arm_step(
        &self,
        pt: &TaskPoint<'_, T, N, A::Space>,
        q_start: &SVector<T, N>,
        period: T,
        half: T,
    ) -> Result<ArmStep<T, N, A::Space>, StepError> {
        let mut task =
            self.arm.arm_law(&self.params.primary, &self.params.joint_limits, self.star, pt, half)?;
        let joint_scale = self.joint_guard(q_start, &task.u_q, period);
        if joint_scale > T::one() {
            task.u_q /= joint_scale;
            task.sensitivity /= joint_scale;
        }
        Ok(ArmStep { task, joint_scale })
    }

    /// The joint guard's factor `s ≥ 1` for `u_q` held `period` seconds from `q`.
    #[inline(always)]
    fn joint_guard(&self, q: &SVector<T, N>, u_q: &SVector<T, N>, period: T) -> T {
        let mut scale = T::one();
        for i in 0..N {
            let f = self.joint_factor(i, q[i], u_q[i], period);
            if f > scale {
                scale = f;
            }
        }
        if self.braking {
            for i in 0..N {
                let b = self.braking_factor_of(i, q[i], u_q[i], period);
                if b > scale {
                    scale = b;
                }
            }
        }
        scale
    }

    /// The guard's factor for joint `i` alone, at `q` moving at `u`, without the braking
    /// bound: the larger of the fraction of the distance to the limit it moves towards and its
    /// velocity limit; at most 1 when `u` meets both. Each is `|u|` over a bound that depends
    /// only on the direction of `u` (and so is the braking bound's).
    #[inline(always)]
    fn joint_factor(&self, i: usize, q: T, u: T, period: T) -> T {
        let lim = &self.params.joint_limits;
        let kappa = self.params.joint_step_fraction;
        let room = if u > T::zero() { lim.upper[i] - q } else { lim.lower[i] - q };
        // u and room have the same sign; room ≠ 0 (q is strictly inside its limits).
        let mut f = (u * period) / (kappa * room);
        let v = u.abs() / self.params.joint_velocity_limits[i];
        if v > f {
            f = v;
        }
        f
    }

    /// The braking bound's factor for joint `i` (module docs of [`crate::acceleration`]): in
    /// a loop of its own, after the guard's (within the guard's loop, the compiler no longer
    /// held a spatial arm's step in registers: two bytewise copies of it, ~1 200 instructions
    /// a UR5 step in `f32`, with or without acceleration limits).
    #[inline(always)]
    fn braking_factor_of(&self, i: usize, q: T, u: T, period: T) -> T {
        let lim = &self.params.joint_limits;
        let room = if u > T::zero() { lim.upper[i] - q } else { lim.lower[i] - q };
        let a = self.params.acceleration_limits.joints[i];
        braking_factor(u, room, a, self.params.joint_step_fraction, period)
    }

    /// The joints' acceleration limits on a guarded step (module docs of
    /// [`crate::acceleration`]): the change from `previous`, the joint command sent before,
    /// divided by the common factor `1/β_q` — unless `previous` is itself outside the joint
    /// guard at `q`, where that would leave the guard: then each joint moves towards the
    /// guarded command by at most its limit. Returns `1/β_q` (1: the limits did not act).
    ///
    /// Which joints can leave the guard: each criterion of the guard bounds `|u|` in one
    /// direction, so a command between `previous` and the guarded one that moves the same way
    /// as the guarded one, no faster, is within it; only the others are checked.
    #[inline(always)]
    pub(crate) fn limit_change(
        &self,
        step: &mut ArmStep<T, N, A::Space>,
        previous: &SVector<T, N>,
        q: &SVector<T, N>,
        period: T,
    ) -> T {
        let limits = &self.params.acceleration_limits.joints;
        let u = &step.task.u_q;
        let beta = change_factor(&(u - previous), limits, period);
        if beta >= T::one() {
            return T::one();
        }
        let mut limited = towards(previous, u, beta);
        for i in 0..N {
            let (x, g) = (limited[i], u[i]);
            let within = (x > T::zero()) == (g > T::zero()) && x.abs() <= g.abs();
            // Rounding puts a command on the guard's bound a few ulp beyond it: a tolerance.
            let outside = |f: T| f > T::of(1.0 + 1e-4);
            if !within
                && (outside(self.joint_factor(i, q[i], x, period))
                    || outside(self.braking_factor_of(i, q[i], x, period)))
            {
                limited = each_towards(previous, u, limits, period);
                break;
            }
        }
        step.task.u_q = limited;
        step.task.sensitivity *= beta;
        reported_factor(beta)
    }
}

/// The arm part of a step: the arm's law after the joint guard.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ArmStep<T: Real, const N: usize, S: crate::space::Space<T>> {
    /// The law at the point, `u_q` and its sensitivity divided by `joint_scale`.
    pub task: TaskStep<T, N, S>,
    /// The guard's factor (≥ 1).
    pub joint_scale: T,
}

fn one_norm<T: Real, const R: usize, const C: usize>(m: &SMatrix<T, R, C>) -> T {
    let mut best = T::zero();
    for j in 0..C {
        let mut s = T::zero();
        for i in 0..R {
            s += m[(i, j)].abs();
        }
        if s > best || s.nan() {
            best = s;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use nalgebra::{Matrix3, Vector3};

    use super::*;

    /// A matrix that rounds to singular gets the damped least-squares solution: finite, and
    /// the minimum-norm solution of the consistent part (`A u = v` on A's range).
    #[test]
    fn a_singular_matrix_gets_the_damped_least_squares_solution() {
        let a = Matrix3::<f32>::new(1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 2.0);
        assert!(a.try_inverse().is_none());
        let v = Vector3::new(2.0_f32, 2.0, 4.0);
        let (mut u, mut sens) = (Vector3::zeros(), SMatrix::zeros());
        let cond = solve_square_into(&a, &v, &SMatrix::<f32, 3, 3>::identity(), 0.0, 0.5, &mut u, &mut sens)
            .unwrap();
        assert!(u.iter().all(|x| x.is_finite()) && sens.iter().all(|x| x.is_finite()) && cond.is_finite());
        // Minimum norm: u = (1, 1, 2) up to the damping.
        for (got, want) in u.iter().zip([1.0, 1.0, 2.0]) {
            assert!((got - want).abs() < 1e-4, "{u:?}");
        }
        // Invertible matrices are solved exactly as before.
        let b = Matrix3::<f64>::new(2.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 4.0);
        let (mut u, mut sens) = (Vector3::zeros(), SMatrix::zeros());
        solve_square_into(&b, &Vector3::new(2.0, 3.0, 4.0), &SMatrix::zeros(), 0.0, 0.0, &mut u, &mut sens)
            .unwrap();
        assert_eq!(u, Vector3::new(1.0, 1.0, 1.0));
    }

    #[test]
    fn a_zero_matrix_is_still_a_typed_rejection() {
        let z = Matrix3::<f64>::zeros();
        let (mut u, mut sens) = (Vector3::zeros(), SMatrix::zeros());
        let r = solve_square_into(
            &z,
            &Vector3::new(1.0, 0.0, 0.0),
            &SMatrix::zeros(),
            0.0,
            0.0,
            &mut u,
            &mut sens,
        );
        assert_eq!(r.unwrap_err(), StepError::SingularTaskJacobian);
    }
}
