//! The hold-aware discretisation: where the robot will be while the command acts.
//!
//! A command computed from the measurement taken at `t_k` starts to act at `t_k + τ` (the
//! delay: compute, transport) and is held for one period `h`. The law
//! ([`Discretisation::Midpoint`](crate::Discretisation::Midpoint)) is evaluated at the
//! state predicted for the middle of that interval, `t_e = t_k + τ + h/2`:
//!
//! ```text
//! base:    r_b(t_k + τ) = r_b · E_τ,   E_τ = ∏ exp(d_j u_b,j)   (the commands in flight)
//!          r_b(t_e)     = r_b(t_k + τ) · exp(h/2 · u_b)          (u_b: guess, then the new one)
//! target:  r_d(t_e)     = r_d · exp(s (u_d + s/2 u̇_d + s²/6 ü_d)),  s = τ + h/2  (first Magnus term)
//! joints:  q(t_e)       = q + Σ d_j u_q,j + h/2 · u_q,guess
//! steering ξ(t_k + τ)   = ξ + Σ d_j v_ξ,j
//! relative r_bd(t_e)    = E⁻¹ · r_bd · exp(…),  E = r_b⁻¹ r_b(t_e)
//! ```
//!
//! `exp` is the exponential of a body twist held constant — SE(2) ([`PoseSc::exp`]) for the
//! base, SE(2) or SE(3) ([`crate::Space::advance`]) for the target; the
//! car's heading rate `v ξ(t)` changes with the steering, and its mean over the segment is
//! used. Every prediction of the joints is kept strictly inside the limits: a displacement
//! that would cover more than a given fraction of a joint's distance to its limit is
//! shortened (all joints by one factor).
//!
//! Why this is second order: with `x` the closed loop's state and `u(x, t)` the continuous
//! law, a command held over `[t, t + h]` and equal to `u(x(t + h/2), t + h/2) + O(h²)`
//! reproduces the continuous solution to `O(h³)` per step (the midpoint rule); a prediction
//! of `x(t + h/2)` from a guess of the command that is `O(h)` off is `O(h²)` off, and the
//! law's linearised correction ([`crate::platform_law`], [`crate::arm_law`]) removes even
//! that to first order. The target's rate `u̇_d` is needed for the same order: without it
//! the arm's feed-forward misses `u̇_d h/2`, which leaves a floor `≈ |u̇_d| h / (2g)` with
//! the gain `g` (3·10⁻⁵ m at 1 ms on the paper's trajectory 1).

use nalgebra::SVector;

use crate::measurement::Measurement;
use crate::params::JointLimits;
use crate::platform::{Platform, PlatformKind};
use crate::scalar::Real;
use crate::se2::PoseSc;
use crate::space::Space;
use crate::state::{State, HISTORY};

/// The robot when a new command starts to act (`t_k + τ`), relative to the measurement.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Start<T, const N: usize> {
    /// `E_τ = r_b⁻¹ r_b(t_k + τ)`: the base's displacement during the delay.
    pub base: PoseSc<T>,
    /// The joints at `t_k + τ`.
    pub q: SVector<T, N>,
    /// The steering state at `t_k + τ` (car-like platform).
    pub xi: T,
}

impl<T: Real, const N: usize> Start<T, N> {
    /// No delay: the measured robot.
    pub fn measured<S: Space<T>>(meas: &Measurement<T, N, S>) -> Self {
        Self { base: PoseSc::identity(), q: meas.joints, xi: meas.steering }
    }
}

/// The robot at `t_k + τ`: the measurement advanced through the commands still in flight.
///
/// The command sent `j` steps ago (`j = 1, 2, …`) acts over
/// `[t_k + τ − Σ_{i<j} hᵢ − h_j, t_k + τ − Σ_{i<j} hᵢ]`, so the interval `[t_k, t_k + τ]`
/// is covered by the most recent commands, the oldest one partly. Before the first command
/// the robot was at rest.
pub(crate) fn in_flight<T: Real, P: Platform<T>, S: Space<T>, const N: usize>(
    state: &State<T, N, S>,
    meas: &Measurement<T, N, S>,
    delay: T,
    limits: &JointLimits<T, N>,
) -> Start<T, N> {
    let mut start = Start::measured(meas);
    if delay <= T::zero() {
        return start;
    }
    // The durations of the commands in flight, newest first.
    let mut spans = [T::zero(); HISTORY];
    let mut count = 0;
    let mut remaining = delay;
    for (i, span) in spans.iter_mut().enumerate() {
        if remaining <= T::zero() {
            break;
        }
        let Some(sent) = state.sent(i) else { break };
        let d = if sent.period < remaining { sent.period } else { remaining };
        *span = d;
        remaining -= d;
        count = i + 1;
    }
    // Oldest first: the base's motion does not commute.
    let mut dq = SVector::<T, N>::zeros();
    for i in (0..count).rev() {
        let (Some(sent), Some(&d)) = (state.sent(i), spans.get(i)) else { continue };
        let xi_mean = start.xi + sent.platform.v_xi * d * T::of(0.5);
        let u_b = P::body_velocity_of(&sent.platform, xi_mean);
        start.base = start.base.compose(&PoseSc::exp(&u_b, d));
        if P::KIND == PlatformKind::Car {
            start.xi += sent.platform.v_xi * d;
        }
        dq += sent.joints * d;
    }
    start.q = advance_inside(&meas.joints, &dq, limits, T::of(0.9));
    start
}

/// `q + c·dq` with the largest `c ∈ [0, 1]` such that no joint moves by more than
/// `fraction` of its distance to the limit it moves towards (`q` strictly inside).
#[inline]
pub(crate) fn advance_inside<T: Real, const N: usize>(
    q: &SVector<T, N>,
    dq: &SVector<T, N>,
    limits: &JointLimits<T, N>,
    fraction: T,
) -> SVector<T, N> {
    let mut c = T::one();
    for i in 0..N {
        let d = dq[i];
        let room = if d > T::zero() { limits.upper[i] - q[i] } else { limits.lower[i] - q[i] };
        // d and room have the same sign (or d = 0).
        let allowed = fraction * room;
        if (d > T::zero() && d > allowed) || (d < T::zero() && d < allowed) {
            let ci = allowed / d;
            if ci < c {
                c = ci;
            }
        }
    }
    q + dq * c
}
