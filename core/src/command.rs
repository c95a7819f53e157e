//! The command for one cycle, what a step reports besides it, and a rejected step.

use nalgebra::{SVector, Vector2, Vector3};

use crate::error::StepError;
use crate::platform::PlatformCommand;
use crate::scalar::Real;
use crate::se2::Pose;
use crate::space::{Planar, Space, Vector};

/// The command for one cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Command<T, const N: usize> {
    /// Platform velocities.
    pub platform: PlatformCommand<T>,
    /// Joint velocities `u_q = q̇` (rad/s or m/s), eq. (30).
    pub joints: SVector<T, N>,
}

impl<T: Real, const N: usize> Command<T, N> {
    /// The safe command: every velocity zero.
    pub fn zero() -> Self {
        let z = T::zero();
        Self { platform: PlatformCommand { v: z, v_lat: z, omega: z, v_xi: z }, joints: SVector::zeros() }
    }

    /// Whether every component is finite.
    pub fn is_finite(&self) -> bool {
        let p = &self.platform;
        p.v.finite()
            && p.v_lat.finite()
            && p.omega.finite()
            && p.v_xi.finite()
            && self.joints.iter().all(|x| x.finite())
    }
}

/// What a step reports besides the command. Every value is finite in an accepted step.
///
/// With [`Discretisation::Midpoint`](crate::Discretisation::Midpoint) the task quantities
/// (`e_p`, `e_m`, `h_s`, ...) are those of the state predicted for the middle of the hold,
/// where the law was evaluated; with `Sampled`, those of the measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diagnostics<T: Real, const N: usize, S: Space<T> = Planar> {
    /// `e_p`, eq. (42): the tracking error — `(m, m, rad)` in the plane, `(p̃, φ̃)` (m,
    /// rad) in space (see [`SpatialArm`](crate::SpatialArm)).
    pub e_p: S::Vector,
    /// `e_m`, eq. (23).
    pub e_m: SVector<T, N>,
    /// `h_s`, eq. (29).
    pub h_s: T,
    /// `h_s1`, eq. (49).
    pub h_s1: T,
    /// `h_s2`, eq. (27) (0 when `Ψ ≡ 1`, where it is not needed).
    pub h_s2: T,
    /// The weight `Ψ ∈ [0, 1]`.
    pub psi: T,
    /// `h_ℓ(q)`, eq. (20): positive when a joint is within its penalty margin.
    pub joint_penalty: T,
    /// The common saturation factor of the platform velocities and `α̇` (≥ 1; 1 means no
    /// saturation): velocity limits and the turn-per-step bound.
    pub saturation: T,
    /// The common factor (≥ 1) the joint velocities were divided by so that no joint covers
    /// more than [`Params::joint_step_fraction`](crate::Params::joint_step_fraction) of its
    /// distance to a limit in one step, and none exceeds its velocity limit; 1 means the arm
    /// law (30) was applied as is. With joint acceleration limits, also so that each joint
    /// can still stop within that fraction ([`crate::acceleration`]).
    pub joint_scale: T,
    /// `1/β_b ≥ 1`: the common factor the change of the platform command (from the previous
    /// command sent) was divided by to meet the platform's acceleration limits; 1 means they
    /// did not act ([`crate::acceleration`]).
    pub platform_acceleration: T,
    /// `1/β_q ≥ 1`: the same for the joint commands; 1 means the joints' acceleration limits
    /// did not act.
    pub joint_acceleration: T,
    /// `det H̄(α)` (1 for the omnidirectional platform).
    pub det_h: T,
    /// The heading filter's lag `δ = θ_d − θ̂_d` (rad): how far the heading the platform's
    /// law follows trails the target's (0 without the filter,
    /// [`HeadingFilter`](crate::HeadingFilter)).
    pub heading_lag: T,
    /// The 1-norm condition number of `∂e_m/∂q`, eq. (24).
    pub condition: T,
    /// `α` at the start of the hold (unused components zero).
    pub alpha: Vector2<T>,
    /// `α̇` commanded (after saturation).
    pub alpha_rate: Vector2<T>,
    /// `ū_b` applied (after saturation), the companion frame's body velocity.
    pub u_bar: Vector3<T>,
    /// The companion frame `r̄_b` (11) in the fixed frame, where the law was evaluated.
    pub companion: Pose<T>,
    /// The weight `θ ∈ [½, 1]` of the linearly implicit platform step (½: the midpoint rule;
    /// towards 1 when the platform loops are stiff over one period; 1 with `Sampled`).
    pub implicitness: T,
    /// Whether this step re-initialised the law's filters from the measurement after a
    /// numerical failure (see [`ControlLaw::step`](crate::ControlLaw::step)).
    pub recovered: bool,
}

impl<T: Real, const N: usize, S: Space<T>> Diagnostics<T, N, S> {
    /// Every value zero (the factors 1, the companion frame at the origin): a value to write
    /// a step's diagnostics over.
    pub fn zero() -> Self {
        let (z, one) = (T::zero(), T::one());
        Self {
            e_p: S::Vector::zeros(),
            e_m: SVector::zeros(),
            h_s: z,
            h_s1: z,
            h_s2: z,
            psi: z,
            joint_penalty: z,
            saturation: one,
            joint_scale: one,
            platform_acceleration: one,
            joint_acceleration: one,
            det_h: z,
            heading_lag: z,
            condition: z,
            alpha: Vector2::zeros(),
            alpha_rate: Vector2::zeros(),
            u_bar: Vector3::zeros(),
            companion: Pose::identity(),
            implicitness: z,
            recovered: false,
        }
    }
}

/// The result of a successful step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Output<T: Real, const N: usize, S: Space<T> = Planar> {
    /// The command to apply until the next step.
    pub command: Command<T, N>,
    /// Values for logging and monitoring.
    pub diagnostics: Diagnostics<T, N, S>,
}

impl<T: Real, const N: usize, S: Space<T>> Output<T, N, S> {
    /// The safe command and [`Diagnostics::zero`]: where a caller keeps the output that
    /// [`ControlLaw::step_delayed_into`](crate::ControlLaw::step_delayed_into) writes.
    pub fn zero() -> Self {
        Self { command: Command::zero(), diagnostics: Diagnostics::zero() }
    }
}

/// A rejected step: why, and the safe command to send instead (every velocity zero).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rejected<T, const N: usize> {
    /// Why the step was rejected.
    pub error: StepError,
    /// The safe command.
    pub command: Command<T, N>,
}

impl<T: Real, const N: usize> From<StepError> for Rejected<T, N> {
    /// The rejection with the safe command.
    #[inline]
    fn from(error: StepError) -> Self {
        Self { error, command: Command::zero() }
    }
}

impl<T: Real, const N: usize> core::fmt::Display for Rejected<T, N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "step rejected: {}", self.error)
    }
}
