//! The robot's acceleration limits, met by a second common factor on the change of the
//! command (beyond the paper, whose saturation knows only velocities).
//!
//! A drive cannot change its speed at once: a base's wheels slip when pushed harder than
//! their motors' torque and the floor's friction allow, and an arm's servos lag. So the
//! command is kept within `aᵢ h` of the command sent before it, component by component, the
//! way the velocity limits are met: by **one common factor**, here on the *change* of the
//! command, so that the command moves from the previous one straight towards the law's.
//!
//! ```text
//! u_p         the previous command actually sent (zero before the first: the robot at rest)
//! u           the law's command after its velocity saturation (platform: ρ; joints: the guard)
//! Δ = u − u_p,   β = min(1, minᵢ aᵢ h / |Δᵢ|)          (i over the limited components, h the hold)
//! u⁺ = u_p + β Δ                                        so |u⁺ᵢ − u_p,ᵢ| ≤ aᵢ h for every i
//! ```
//!
//! `h` is the period of the hold the new command starts: a drive that ramps at its limit
//! reaches the new set-point within that hold.
//!
//! **Over the hold** (the hold-aware law, module `hold`): the new command takes over from
//! the last one sent — with a delay `τ`, the last of the commands in flight, through which
//! the law predicts the robot — so that is the reference, whatever the delay. The limited
//! commands are what the law then works with: the arm law (30) is evaluated with the
//! platform's limited velocity over the hold, the state advances with the limited `α̇` and
//! `ū_b`, and the next step's guess of the hold is the limited command. The first step's
//! passes all count from rest (a pass's guess is not a command that was sent). The platform and the arm have a factor each
//! (`β_b`, `β_q`), as their velocities have (`ρ` and the joint guard): the platform's factor
//! is applied in the platform law, before the arm law, so that the arm law (30) compensates
//! the platform velocity actually commanded; the arm's after the joint guard.
//!
//! **The platform.** The limited components are the platform's command coordinates —
//! [`forward`](AccelerationLimits::forward) on `v` (every platform),
//! [`lateral`](AccelerationLimits::lateral) on `v_lat` and
//! [`angular`](AccelerationLimits::angular) on `ω` (unicycle and omnidirectional; the car's
//! `ω = v ξ` follows its speed and steering, whose rate has its own velocity limit). The factor
//! multiplies the change of every generalised input `w` (the unicycle's `α̇` and the car's
//! `α̇₁, α̇₂` with the speeds) and of the companion frame's velocity `ū_b`, as `ρ` multiplies
//! them: `w⁺ = w_p + β_b (w − w_p)`, `ū⁺ = ū_p + β_b (ū − ū_p)`; the car's steering rate gets
//! the feed-forward of the new `α̇` (its feedback is not scaled, as with `ρ`). `w` and `w_p`
//! lie within the velocity limits, a box, and so does every point between them: the velocity
//! limits still hold.
//!
//! **The joints, and the joint guard.** The joint guard keeps every joint from covering more
//! than `κ` of its distance `d` to the limit it moves towards in one period. With an
//! acceleration limit `a` the guard also keeps the joint able to *stop* within `κ d`: a
//! command `u` held for one period and then braked by `a h` per period covers
//! `D(u) = h Σₖ max(u − k a h, 0) ≤ B(u) = u²/(2a) + u h` (with `u = (n + f) a h`,
//! `D = D₀ + (a h²/2) f(1 − f)`, `D₀ = u²/(2a) + u h/2`, and `f(1 − f) a h ≤ u`), so
//!
//! ```text
//! B(|u|) ≤ κ d   ⇔   |u| ≤ U = (2κd/h) / (1 + √(1 + 2κd/(a h²)))     (towards the limit)
//! ```
//!
//! (`U → κ d/h`, the per-period rule, as `a → ∞`; `U ≈ √(2aκd)` for a slow drive; written
//! so that nothing overflows or cancels.) This bound is what makes the two kinds of limit
//! compatible: from a command `u_p` that met it, one period's braking `u_p − a h` meets it
//! at the next step, because `B(u − a h) = B(u) − u h − a h²/2` and the joint has come
//! `u h` closer (`κ ≤ 1`). It implies the per-period rule (`B(u) ≥ u h`).
//!
//! **When the previous command is outside the guard** (the robot did not follow: a joint
//! measured closer to its limit than the commands predicted), no common factor keeps both
//! kinds of limit, and the acceleration limits win: each joint's command moves towards the
//! guarded command by at most `aᵢ h` — as hard as the drive may brake, and no harder — and
//! the direction is given up for that step ([`Diagnostics::joint_acceleration`] reports the
//! factor `1/β` of the common move that was not taken). The acceleration limits are never
//! exceeded by an accepted command. If the joint then reaches its limit, the next
//! measurement is rejected (`JointAtLimit`) with the safe command.
//!
//! **The safe command of a rejected step** stops the robot at once (every velocity zero),
//! outside the acceleration limits: it is the answer to a measurement the law cannot use, and
//! the robot's drives brake at their own limits. A rejected step leaves the state as it was,
//! so the next accepted command is limited relative to the last *accepted* one, as the
//! prediction over the delay assumes the accepted commands were sent; a caller that held the
//! safe command for a while restarts the law with [`Controller::start`] (the robot at rest).
//!
//! **A recovery** (a step that failed numerically, computed again from filters re-initialised
//! from the measurement) keeps counting from the last command sent; if that fails too (the
//! state held extreme values), from rest — so a valid measurement is still accepted at once.
//!
//! With every limit `+∞` (the default, and the paper's runs) nothing here runs: the law is
//! bit for bit what it is without this module.
//!
//! [`Diagnostics::joint_acceleration`]: crate::Diagnostics::joint_acceleration
//! [`Controller::start`]: crate::Controller::start

use nalgebra::{SVector, Vector3};

use crate::error::{ParamError, Rule};
use crate::platform::PlatformKind;
use crate::scalar::Real;

/// Acceleration limits of the platform's command coordinates and of the joints, met by a
/// common factor on the change of the command (module docs). `+∞` is no limit (the default).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AccelerationLimits<T, const N: usize> {
    /// Largest `|v̇|`, the forward speed's change per second (m/s²).
    pub forward: T,
    /// Largest `|v̇_lat|` (omnidirectional platform; m/s²).
    pub lateral: T,
    /// Largest `|ω̇|` (unicycle and omnidirectional platforms; rad/s²).
    pub angular: T,
    /// Largest `|q̈ᵢ|` of each joint's command (rad/s² or m/s²).
    pub joints: SVector<T, N>,
}

impl<T: Real, const N: usize> AccelerationLimits<T, N> {
    /// No limits (the paper's runs).
    pub fn unlimited() -> Self {
        let inf = T::of(f64::INFINITY);
        Self { forward: inf, lateral: inf, angular: inf, joints: SVector::repeat(inf) }
    }

    /// Checks every limit: `+∞` (none) or finite and `> 0`.
    ///
    /// # Errors
    /// The first limit that is NaN (`acceleration_limits.forward`, …,
    /// `acceleration_limits.joints` with its joint) or not positive.
    pub(crate) fn validate(&self) -> Result<(), ParamError> {
        let check = |name: &'static str, v: T| {
            if v.nan() {
                Err(ParamError::new(name, Rule::NonFinite))
            } else if v <= T::zero() {
                Err(ParamError::new(name, Rule::NotPositive))
            } else {
                Ok(())
            }
        };
        check("acceleration_limits.forward", self.forward)?;
        check("acceleration_limits.lateral", self.lateral)?;
        check("acceleration_limits.angular", self.angular)?;
        for i in 0..N {
            check("acceleration_limits.joints", self.joints[i])
                .map_err(|e| ParamError::joint(e.param, i, e.rule))?;
        }
        Ok(())
    }

    /// The limits of the generalised inputs `w` of a platform (`+∞` where a component is not
    /// a command coordinate): unicycle `(v, ω, α̇)`, car `(v, α̇₁, α̇₂)`, omnidirectional
    /// `(v₁, v₂, ω)`.
    pub(crate) fn of_inputs(&self, kind: PlatformKind) -> Vector3<T> {
        let inf = T::of(f64::INFINITY);
        match kind {
            PlatformKind::Unicycle => Vector3::new(self.forward, self.angular, inf),
            PlatformKind::Car => Vector3::new(self.forward, inf, inf),
            PlatformKind::Omni => Vector3::new(self.forward, self.lateral, self.angular),
        }
    }

    /// Whether a platform of this kind has a finite limit.
    pub(crate) fn limits_platform(&self, kind: PlatformKind) -> bool {
        self.of_inputs(kind).iter().any(|a| a.finite())
    }

    /// Whether a joint has a finite limit.
    pub(crate) fn limits_joints(&self) -> bool {
        self.joints.iter().any(|a| a.finite())
    }
}

/// `β ∈ [0, 1]`: the largest factor with `|β Δᵢ| ≤ aᵢ h` for every component (module docs),
/// as ratios that cannot overflow (`aᵢ = +∞`: no bound).
#[inline]
pub(crate) fn change_factor<T: Real, const K: usize>(
    change: &SVector<T, K>,
    limits: &SVector<T, K>,
    h: T,
) -> T {
    let mut beta = T::one();
    for i in 0..K {
        let room = limits[i] * h;
        let d = change[i].abs();
        if d > room {
            let b = room / d;
            if b < beta {
                beta = b;
            }
        }
    }
    beta
}

/// `u_p + β (u − u_p)` (the difference is the one the factor was computed from: computed
/// once). Where it overflows (commands of ~10³⁸), `β = 0` and the result is NaN: the step
/// fails numerically and is recovered from rest.
#[inline]
pub(crate) fn towards<T: Real, const K: usize>(
    from: &SVector<T, K>,
    to: &SVector<T, K>,
    beta: T,
) -> SVector<T, K> {
    from + (to - from) * beta
}

/// Each component moved from `u_p` towards `u` by at most `aᵢ h` (the step where the common
/// factor cannot keep the joint guard: module docs).
#[inline]
pub(crate) fn each_towards<T: Real, const K: usize>(
    from: &SVector<T, K>,
    to: &SVector<T, K>,
    limits: &SVector<T, K>,
    h: T,
) -> SVector<T, K> {
    SVector::from_fn(|i, _| {
        let room = limits[i] * h;
        let d = to[i] - from[i];
        if d > room {
            from[i] + room
        } else if d < -room {
            from[i] - room
        } else {
            to[i]
        }
    })
}

/// The joint guard's braking bound (module docs): the factor `|u| / U` that brings `u`
/// (moving towards a limit `room` away: `u` and `room` of the same sign) within it, or 1 when
/// it already is or the joint has no limit (`a = +∞`); the largest finite factor when the
/// bound rounds to 0.
#[inline]
pub(crate) fn braking_factor<T: Real>(u: T, room: T, a: T, kappa: T, h: T) -> T {
    let speed = u.abs();
    let reach = kappa * room.abs();
    // B(|u|) ≤ κ d, i.e. u² + 2 a |u| h ≤ 2 a κ d: within the bound, no root needed (the
    // common case).
    if !a.finite() || speed * speed + T::of(2.0) * a * speed * h <= T::of(2.0) * a * reach {
        return T::one();
    }
    braking_beyond(speed, reach, a, h)
}

/// [`braking_factor`] of a joint beyond its bound: `|u| / U`. Out of line: inlined into the
/// joint guard, its root and divisions kept the compiler from holding a spatial arm's step in
/// registers (two bytewise copies of it, ~1 200 instructions a UR5 step in `f32`, with or
/// without acceleration limits).
#[cold]
#[inline(never)]
fn braking_beyond<T: Real>(speed: T, reach: T, a: T, h: T) -> T {
    let two_reach = T::of(2.0) * reach;
    let bound = (two_reach / h) / (T::one() + (T::one() + two_reach / (a * h * h)).square_root());
    reported_factor(bound / speed)
}

/// The largest factor reported (a command that must stop).
pub(crate) const STOPPED: f64 = 3.0e38;

/// A factor `1/x` as a step reports it (`x ∈ [0, 1]`, the part of a command kept): finite,
/// at most [`STOPPED`] (a stopped command).
#[inline]
pub(crate) fn reported_factor<T: Real>(x: T) -> T {
    if x > T::of(1.0 / STOPPED) {
        T::one() / x
    } else {
        T::of(STOPPED)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_factor_keeps_every_component_within_its_limit_and_the_direction() {
        let lim = Vector3::new(1.0_f64, 2.0, f64::INFINITY);
        let d = Vector3::new(0.01, -0.001, 5.0);
        // 1 m/s² at 1 ms allows 1e-3: the first component binds.
        let b = change_factor(&d, &lim, 1e-3);
        assert!((b - 0.1).abs() < 1e-15, "{b}");
        let moved = d * b;
        assert!(moved[0].abs() <= 1e-3 * (1.0 + 1e-12) && moved[1].abs() <= 2e-3);
        assert_eq!(change_factor(&Vector3::new(1e-4, 0.0, 1e9), &lim, 1e-3), 1.0);
        // Unlimited, nothing changes.
        assert_eq!(change_factor(&d, &Vector3::repeat(f64::INFINITY), 1e-3), 1.0);
    }

    #[test]
    fn each_component_moves_by_at_most_its_limit() {
        let from = Vector3::new(1.0_f64, 0.0, -1.0);
        let to = Vector3::new(0.0, 0.0005, 3.0);
        let u = each_towards(&from, &to, &Vector3::new(100.0, 100.0, 1.0), 1e-3);
        assert_eq!(u, Vector3::new(0.9, 0.0005, -0.999));
    }

    #[test]
    fn the_braking_bound_lets_the_joint_stop_within_the_fraction() {
        let (kappa, h) = (0.5_f64, 1e-3);
        for a in [0.5, 2.0, 50.0, 1e4] {
            for d in [1e-5, 1e-3, 0.01, 0.3] {
                // Far from the bound: no factor.
                assert_eq!(braking_factor(1e-9, d, a, kappa, h), 1.0);
                let s = braking_factor(100.0, d, a, kappa, h);
                assert!(s > 1.0);
                let bound = 100.0 / s;
                // On the bound B(u) = u²/(2a) + u h = κ d.
                let b = bound * bound / (2.0 * a) + bound * h;
                assert!((b - kappa * d).abs() <= 1e-12 * kappa * d, "a {a} d {d}: B = {b}");
                // Held one period and braked by a h per period, the joint stops within κ d.
                let (mut u, mut travelled) = (bound, 0.0);
                while u > 0.0 {
                    travelled += u * h;
                    u -= a * h;
                }
                assert!(travelled <= kappa * d * (1.0 + 1e-12), "a {a} d {d}: {travelled}");
                // And the same from the other side of the joint's range.
                assert_eq!(braking_factor(-100.0, -d, a, kappa, h), s);
            }
        }
        // A drive without limit, or at rest: no factor; the per-period rule as a → ∞.
        assert_eq!(braking_factor(100.0, 0.01, f64::INFINITY, kappa, h), 1.0);
        assert_eq!(braking_factor(0.0, 1e-12, 2.0, kappa, h), 1.0);
        let fast = 100.0 / braking_factor(100.0, 0.01, 1e12, kappa, h);
        assert!((fast - kappa * 0.01 / h).abs() < 1e-6 * fast, "{fast}");
        // At the limit itself the joint must stop: the largest finite factor, never NaN.
        assert_eq!(braking_factor(1.0, 0.0, 2.0, kappa, h), STOPPED);
        assert!(braking_factor(1.0_f32, 1e-30, 2.0, 0.5, 1e-3).is_finite());
    }
}
