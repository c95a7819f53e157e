//! Errors: invalid parameters (rejected when a controller is built) and rejected
//! measurements (answered with the safe command).

use core::fmt;

use crate::scalar::Real;

/// The rule a parameter breaks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rule {
    /// The value is NaN or infinite.
    NonFinite,
    /// The value must be strictly positive.
    NotPositive,
    /// The value must be positive or zero.
    Negative,
    /// The value must lie in [0, 1].
    NotInUnitInterval,
    /// A lower joint limit must be strictly below the upper one (`q⁻ < q⁺`).
    EmptyInterval,
    /// The margins of the joint-limit penalty (21) must leave a free band:
    /// `δ > 0` and `2δ < q⁺ − q⁻`.
    PenaltyMarginTooWide,
    /// Eq. (52) needs `0 < δ⁻⁻ < δ⁻` and `0 < δ⁺⁺ < δ⁺` (the ramp has a width), and the two
    /// bands must not overlap: `δ⁻ + δ⁺ < q⁺ − q⁻`.
    WeightMarginOrder,
    /// Lemma 2's transversality condition `6 η₂ η₃ > 8 η₃ + η₁ η₂` does not hold.
    Transversality,
    /// Decomposition (51) is exact only for `h_s = h_s1`: it needs the constant weight `Ψ = 1`.
    Decomposition51NeedsPsiOne,
    /// The arm geometry is not usable (e.g. a non-positive link length).
    Geometry,
    /// The value is above the bound that keeps every step computable (in `f32` too).
    TooLarge(Bound),
    /// A rotation matrix is not orthonormal with determinant 1 (`|RᵀR − I| ≤ 10⁻⁹` in
    /// `f64`, `10⁻⁵` in `f32`).
    NotOrthonormal,
    /// A joint axis is not a unit vector (to within `10⁻⁹` in `f64`, `10⁻⁵` in `f32`).
    NotUnitVector,
    /// The arm has fewer joints than the task has dimensions (3 in the plane, 6 in space).
    TooFewJoints,
    /// A joint's home position is not strictly inside its limits.
    HomeOutsideLimits,
    /// A planar arm's joints must turn about the vertical and slide in the plane, and its
    /// fixed frames must be rotations about the vertical at height 0.
    NotPlanar,
    /// `max_time_step` is longer than the period bound derived from the law's rates:
    /// `max_time_step · r_max ≤ 0.1`, with `r_max` the largest of the arm gains `gᵢ`, the
    /// filter rates `σ/ξ` of (26) and `σᵢ/ξ` of (28), and `λ/ξ` of (53)–(54)
    /// (see [`Params::period_bound`](crate::Params::period_bound)).
    PeriodTooLong,
}

/// An upper bound of [`Rule::TooLarge`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bound {
    /// Lengths, poses and joint limits: 10³ (m or rad).
    Length,
    /// The transverse functions' sizes `ε₁`, `ε` (m): 10.
    TransverseSize,
    /// Gains, rates, weights and shape factors: 10⁶ (in their units).
    Magnitude,
    /// Times (`max_time_step`, `max_delay`): 1 s.
    Time,
}

impl Bound {
    /// The bound's value.
    pub const fn value(self) -> f64 {
        match self {
            Bound::Length => 1e3,
            Bound::TransverseSize => 10.0,
            Bound::Magnitude => 1e6,
            Bound::Time => 1.0,
        }
    }
}

/// An invalid parameter: which one, which joint (if per joint), and the rule it breaks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParamError {
    /// The parameter's name, as in the paper where it has one (e.g. `"epsilon_1"`).
    pub param: &'static str,
    /// The joint index (from 0) for per-joint parameters.
    pub joint: Option<u8>,
    /// The rule broken.
    pub rule: Rule,
}

impl ParamError {
    /// An error for a scalar parameter.
    pub const fn new(param: &'static str, rule: Rule) -> Self {
        Self { param, joint: None, rule }
    }

    /// An error for joint `joint` (from 0) of a per-joint parameter.
    pub const fn joint(param: &'static str, joint: usize, rule: Rule) -> Self {
        Self { param, joint: Some(joint as u8), rule }
    }
}

impl fmt::Display for Rule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Rule::NonFinite => "must be finite",
            Rule::NotPositive => "must be > 0",
            Rule::Negative => "must be >= 0",
            Rule::NotInUnitInterval => "must lie in [0, 1]",
            Rule::EmptyInterval => "lower limit must be < upper limit",
            Rule::PenaltyMarginTooWide => "penalty margin delta must satisfy 0 < 2*delta < q+ - q-",
            Rule::WeightMarginOrder => {
                "weight margins must satisfy 0 < delta-- < delta-, 0 < delta++ < delta+, delta- + delta+ < q+ - q- (eq. 52)"
            }
            Rule::Transversality => "Lemma 2 needs 6*eta2*eta3 > 8*eta3 + eta1*eta2",
            Rule::Decomposition51NeedsPsiOne => {
                "decomposition (51) is exact only for h_s = h_s1: use the constant weight psi = 1"
            }
            Rule::Geometry => "arm geometry is not usable",
            Rule::NotOrthonormal => "must be a rotation matrix (orthonormal, determinant 1)",
            Rule::NotUnitVector => "must be a unit vector",
            Rule::TooFewJoints => "the arm has fewer joints than the task has dimensions (3 planar, 6 spatial)",
            Rule::HomeOutsideLimits => "home position must lie strictly inside the joint limits",
            Rule::NotPlanar => {
                "a planar arm's joints must turn about the vertical (axis (0, 0, +-1)) or slide in the plane (axis z = 0), its frames be rotations about z"
            }
            Rule::TooLarge(b) => return write!(f, "must be <= {:e}", b.value()),
            Rule::PeriodTooLong => {
                "max_time_step times the law's largest rate (the gains, sigma/xi of the filters, lambda/xi) must be <= 0.1"
            }
        })
    }
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.joint {
            Some(j) => write!(f, "parameter `{}` (joint {}): {}", self.param, j + 1, self.rule),
            None => write!(f, "parameter `{}`: {}", self.param, self.rule),
        }
    }
}

impl core::error::Error for ParamError {}

/// A field of a [`Measurement`](crate::Measurement), to say which one was bad.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    /// The time `t`.
    Time,
    /// The platform pose `r_b`.
    BasePose,
    /// The steering state `ξ` (car-like platform).
    Steering,
    /// The joint positions `q`.
    Joints,
    /// The target pose `r_d`.
    TargetPose,
    /// The target body velocity `u_d`.
    TargetVelocity,
}

/// Why a step was rejected. The controller answered with the safe command (all
/// velocities zero) and left its state as it was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepError {
    /// A measured value is NaN or infinite. (A negative or backward time is accepted:
    /// `Γ(t)` counts from the first step and never before it.)
    NonFinite(Field),
    /// The time step is not finite, `≤ 0`, or above the configured maximum.
    BadTimeStep,
    /// Joint `0` (index from 0) is at or beyond one of its limits.
    JointAtLimit(u8),
    /// The arm is at or near a singular configuration (for the RPR arm: `q₂ ≤ 0`; for a
    /// spatial arm, see [`SpatialArm`](crate::SpatialArm)).
    SingularArm,
    /// `∂e_m/∂q` (eq. 24) cannot be inverted.
    SingularTaskJacobian,
    /// The target's yaw, which the platform law uses (§5's projection), is undefined: its
    /// `x` axis is vertical.
    TargetYawUndefined,
    /// The delay is not finite, negative, above `max_delay`, or longer than the command
    /// history covers ([`HISTORY`](crate::HISTORY) periods).
    BadDelay,
    /// The law produced a non-finite value (an overflow on extreme input), also after
    /// re-initialising its filters from the measurement.
    NumericalFailure,
}

impl fmt::Display for StepError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StepError::NonFinite(field) => write!(f, "measurement {field:?} is not finite"),
            StepError::BadTimeStep => f.write_str("time step is not finite, <= 0 or above the maximum"),
            StepError::JointAtLimit(j) => write!(f, "joint {} is at or beyond its limit", j + 1),
            StepError::SingularArm => f.write_str("arm configuration is singular"),
            StepError::SingularTaskJacobian => f.write_str("task Jacobian de_m/dq is singular"),
            StepError::TargetYawUndefined => f.write_str("target's x axis is vertical: its yaw is undefined"),
            StepError::BadDelay => {
                f.write_str("delay is not finite, < 0, above max_delay or beyond the command history")
            }
            StepError::NumericalFailure => f.write_str("the law produced a non-finite value"),
        }
    }
}

impl core::error::Error for StepError {}

// ---------------------------------------------------------------------------------------
// The checks every `validate` is made of.

pub(crate) fn check_nonneg<T: Real>(name: &'static str, v: T, bound: Bound) -> Result<(), ParamError> {
    if !v.finite() {
        Err(ParamError::new(name, Rule::NonFinite))
    } else if v < T::zero() {
        Err(ParamError::new(name, Rule::Negative))
    } else {
        at_most(name, v, bound)
    }
}

/// `v` finite, `> 0` and at most `bound`.
pub(crate) fn check_positive<T: Real>(name: &'static str, v: T, bound: Bound) -> Result<(), ParamError> {
    positive(name, v)?;
    at_most(name, v, bound)
}

pub(crate) fn at_most<T: Real>(name: &'static str, v: T, bound: Bound) -> Result<(), ParamError> {
    if v.abs() > T::of(bound.value()) {
        Err(ParamError::new(name, Rule::TooLarge(bound)))
    } else {
        Ok(())
    }
}

pub(crate) fn positive<T: Real>(name: &'static str, v: T) -> Result<(), ParamError> {
    if !v.finite() {
        Err(ParamError::new(name, Rule::NonFinite))
    } else if v <= T::zero() {
        Err(ParamError::new(name, Rule::NotPositive))
    } else {
        Ok(())
    }
}
