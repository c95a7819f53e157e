//! Status codes: every [`ParamError`] rule and every [`StepError`] as one named number.
//!
//! The numbers are stable (a new code gets a new number; none is reused):
//!
//! | range | meaning |
//! |---|---|
//! | 0 | ok |
//! | 1–9 | the call itself: a NULL or misaligned pointer, storage not initialised, the other scalar type, an enum field out of range |
//! | 100–119 | a parameter breaks a rule ([`Rule`]; `TooLarge` one code per [`Bound`]) |
//! | 200–233 | a step was rejected ([`StepError`]); the command written is the safe (zero) one |

use core::ffi::{c_char, CStr};

use companion_core::{Bound, Field, ParamError, Rule, StepError};

/// What a call of this library did: `COMPANION_STATUS_OK` (0) or why not.
///
/// The numbers are stable; `companion_status_name` gives each one's name.
#[repr(i32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompanionStatus {
    /// Success.
    Ok = 0,
    /// A pointer argument is NULL.
    NullPointer = 1,
    /// A pointer argument is not aligned for its type (controller storage: 8 bytes).
    Misaligned = 2,
    /// The controller storage was not initialised by a successful `companion_*_init`.
    NotInitialised = 3,
    /// The controller was initialised for the other scalar type (`f64` vs `f32`).
    WrongScalar = 4,
    /// An enum field (platform, run, weight, ...) holds a value outside its enum.
    BadEnum = 5,

    /// Parameter: NaN or infinite.
    ParamNonFinite = 100,
    /// Parameter: must be > 0.
    ParamNotPositive = 101,
    /// Parameter: must be >= 0.
    ParamNegative = 102,
    /// Parameter: must lie in [0, 1].
    ParamNotInUnitInterval = 103,
    /// Parameter: a lower joint limit is not below the upper one.
    ParamEmptyInterval = 104,
    /// Parameter: the joint-limit penalty margin leaves no free band (eq. 21).
    ParamPenaltyMarginTooWide = 105,
    /// Parameter: the weight margins of eq. (52) are out of order.
    ParamWeightMarginOrder = 106,
    /// Parameter: Lemma 2's transversality condition fails (car-like).
    ParamTransversality = 107,
    /// Parameter: decomposition (51) needs the constant weight psi = 1.
    ParamDecomposition51NeedsPsiOne = 108,
    /// Parameter: the arm geometry is not usable.
    ParamGeometry = 109,
    /// Parameter: above 1e3 (lengths, poses, joint limits).
    ParamTooLargeLength = 110,
    /// Parameter: above 10 (transverse-function sizes).
    ParamTooLargeTransverseSize = 111,
    /// Parameter: above 1e6 (gains, rates, weights).
    ParamTooLargeMagnitude = 112,
    /// Parameter: above 1 s (max_time_step, max_delay).
    ParamTooLargeTime = 113,
    /// Parameter: a rotation matrix is not orthonormal.
    ParamNotOrthonormal = 114,
    /// Parameter: a joint axis is not a unit vector.
    ParamNotUnitVector = 115,
    /// Parameter: fewer joints than task dimensions.
    ParamTooFewJoints = 116,
    /// Parameter: a home position is not strictly inside the joint limits.
    ParamHomeOutsideLimits = 117,
    /// Parameter: a planar arm is not planar.
    ParamNotPlanar = 118,
    /// Parameter: max_time_step is longer than the law's period bound.
    ParamPeriodTooLong = 119,

    /// Step rejected: the measured time is not finite.
    StepNonFiniteTime = 200,
    /// Step rejected: the platform pose is not finite.
    StepNonFiniteBasePose = 201,
    /// Step rejected: the steering state is not finite (car-like).
    StepNonFiniteSteering = 202,
    /// Step rejected: a joint position is not finite.
    StepNonFiniteJoints = 203,
    /// Step rejected: the target pose is not finite.
    StepNonFiniteTargetPose = 204,
    /// Step rejected: the target velocity is not finite.
    StepNonFiniteTargetVelocity = 205,
    /// Step rejected: the period is not finite, <= 0 or above max_time_step.
    StepBadTimeStep = 210,
    /// Step rejected: the delay is not finite, < 0, above max_delay or beyond the history.
    StepBadDelay = 211,
    /// Step rejected: joint 1 (q1) is at or beyond a limit.
    StepJointAtLimitQ1 = 220,
    /// Step rejected: joint 2 (q2) is at or beyond a limit.
    StepJointAtLimitQ2 = 221,
    /// Step rejected: joint 3 (q3) is at or beyond a limit.
    StepJointAtLimitQ3 = 222,
    /// Step rejected: the arm is at a singular configuration (RPR: q2 <= 0).
    StepSingularArm = 230,
    /// Step rejected: the task Jacobian de_m/dq cannot be inverted.
    StepSingularTaskJacobian = 231,
    /// Step rejected: the target's yaw is undefined (spatial law only).
    StepTargetYawUndefined = 232,
    /// Step rejected: the law produced a non-finite value, also from a fresh state.
    StepNumericalFailure = 233,
}

/// Every status, in the order of its number (for tests and the name table).
pub const ALL: [CompanionStatus; 41] = {
    use CompanionStatus as S;
    [
        S::Ok,
        S::NullPointer,
        S::Misaligned,
        S::NotInitialised,
        S::WrongScalar,
        S::BadEnum,
        S::ParamNonFinite,
        S::ParamNotPositive,
        S::ParamNegative,
        S::ParamNotInUnitInterval,
        S::ParamEmptyInterval,
        S::ParamPenaltyMarginTooWide,
        S::ParamWeightMarginOrder,
        S::ParamTransversality,
        S::ParamDecomposition51NeedsPsiOne,
        S::ParamGeometry,
        S::ParamTooLargeLength,
        S::ParamTooLargeTransverseSize,
        S::ParamTooLargeMagnitude,
        S::ParamTooLargeTime,
        S::ParamNotOrthonormal,
        S::ParamNotUnitVector,
        S::ParamTooFewJoints,
        S::ParamHomeOutsideLimits,
        S::ParamNotPlanar,
        S::ParamPeriodTooLong,
        S::StepNonFiniteTime,
        S::StepNonFiniteBasePose,
        S::StepNonFiniteSteering,
        S::StepNonFiniteJoints,
        S::StepNonFiniteTargetPose,
        S::StepNonFiniteTargetVelocity,
        S::StepBadTimeStep,
        S::StepBadDelay,
        S::StepJointAtLimitQ1,
        S::StepJointAtLimitQ2,
        S::StepJointAtLimitQ3,
        S::StepSingularArm,
        S::StepSingularTaskJacobian,
        S::StepTargetYawUndefined,
        S::StepNumericalFailure,
    ]
};

impl CompanionStatus {
    /// The status of an invalid parameter (its rule).
    pub const fn from_param(e: &ParamError) -> Self {
        use CompanionStatus as S;
        match e.rule {
            Rule::NonFinite => S::ParamNonFinite,
            Rule::NotPositive => S::ParamNotPositive,
            Rule::Negative => S::ParamNegative,
            Rule::NotInUnitInterval => S::ParamNotInUnitInterval,
            Rule::EmptyInterval => S::ParamEmptyInterval,
            Rule::PenaltyMarginTooWide => S::ParamPenaltyMarginTooWide,
            Rule::WeightMarginOrder => S::ParamWeightMarginOrder,
            Rule::Transversality => S::ParamTransversality,
            Rule::Decomposition51NeedsPsiOne => S::ParamDecomposition51NeedsPsiOne,
            Rule::Geometry => S::ParamGeometry,
            Rule::TooLarge(Bound::Length) => S::ParamTooLargeLength,
            Rule::TooLarge(Bound::TransverseSize) => S::ParamTooLargeTransverseSize,
            Rule::TooLarge(Bound::Magnitude) => S::ParamTooLargeMagnitude,
            Rule::TooLarge(Bound::Time) => S::ParamTooLargeTime,
            Rule::NotOrthonormal => S::ParamNotOrthonormal,
            Rule::NotUnitVector => S::ParamNotUnitVector,
            Rule::TooFewJoints => S::ParamTooFewJoints,
            Rule::HomeOutsideLimits => S::ParamHomeOutsideLimits,
            Rule::NotPlanar => S::ParamNotPlanar,
            Rule::PeriodTooLong => S::ParamPeriodTooLong,
        }
    }

    /// The status of a rejected step.
    pub const fn from_step(e: StepError) -> Self {
        use CompanionStatus as S;
        match e {
            StepError::NonFinite(Field::Time) => S::StepNonFiniteTime,
            StepError::NonFinite(Field::BasePose) => S::StepNonFiniteBasePose,
            StepError::NonFinite(Field::Steering) => S::StepNonFiniteSteering,
            StepError::NonFinite(Field::Joints) => S::StepNonFiniteJoints,
            StepError::NonFinite(Field::TargetPose) => S::StepNonFiniteTargetPose,
            StepError::NonFinite(Field::TargetVelocity) => S::StepNonFiniteTargetVelocity,
            StepError::BadTimeStep => S::StepBadTimeStep,
            StepError::BadDelay => S::StepBadDelay,
            StepError::JointAtLimit(0) => S::StepJointAtLimitQ1,
            StepError::JointAtLimit(1) => S::StepJointAtLimitQ2,
            // The planar arm has three joints: the index is 0, 1 or 2.
            StepError::JointAtLimit(_) => S::StepJointAtLimitQ3,
            StepError::SingularArm => S::StepSingularArm,
            StepError::SingularTaskJacobian => S::StepSingularTaskJacobian,
            StepError::TargetYawUndefined => S::StepTargetYawUndefined,
            StepError::NumericalFailure => S::StepNumericalFailure,
        }
    }

    /// The status's name as in the C header (`COMPANION_STATUS_...`).
    pub const fn name(self) -> &'static CStr {
        use CompanionStatus as S;
        match self {
            S::Ok => c"COMPANION_STATUS_OK",
            S::NullPointer => c"COMPANION_STATUS_NULL_POINTER",
            S::Misaligned => c"COMPANION_STATUS_MISALIGNED",
            S::NotInitialised => c"COMPANION_STATUS_NOT_INITIALISED",
            S::WrongScalar => c"COMPANION_STATUS_WRONG_SCALAR",
            S::BadEnum => c"COMPANION_STATUS_BAD_ENUM",
            S::ParamNonFinite => c"COMPANION_STATUS_PARAM_NON_FINITE",
            S::ParamNotPositive => c"COMPANION_STATUS_PARAM_NOT_POSITIVE",
            S::ParamNegative => c"COMPANION_STATUS_PARAM_NEGATIVE",
            S::ParamNotInUnitInterval => c"COMPANION_STATUS_PARAM_NOT_IN_UNIT_INTERVAL",
            S::ParamEmptyInterval => c"COMPANION_STATUS_PARAM_EMPTY_INTERVAL",
            S::ParamPenaltyMarginTooWide => c"COMPANION_STATUS_PARAM_PENALTY_MARGIN_TOO_WIDE",
            S::ParamWeightMarginOrder => c"COMPANION_STATUS_PARAM_WEIGHT_MARGIN_ORDER",
            S::ParamTransversality => c"COMPANION_STATUS_PARAM_TRANSVERSALITY",
            S::ParamDecomposition51NeedsPsiOne => c"COMPANION_STATUS_PARAM_DECOMPOSITION51_NEEDS_PSI_ONE",
            S::ParamGeometry => c"COMPANION_STATUS_PARAM_GEOMETRY",
            S::ParamTooLargeLength => c"COMPANION_STATUS_PARAM_TOO_LARGE_LENGTH",
            S::ParamTooLargeTransverseSize => c"COMPANION_STATUS_PARAM_TOO_LARGE_TRANSVERSE_SIZE",
            S::ParamTooLargeMagnitude => c"COMPANION_STATUS_PARAM_TOO_LARGE_MAGNITUDE",
            S::ParamTooLargeTime => c"COMPANION_STATUS_PARAM_TOO_LARGE_TIME",
            S::ParamNotOrthonormal => c"COMPANION_STATUS_PARAM_NOT_ORTHONORMAL",
            S::ParamNotUnitVector => c"COMPANION_STATUS_PARAM_NOT_UNIT_VECTOR",
            S::ParamTooFewJoints => c"COMPANION_STATUS_PARAM_TOO_FEW_JOINTS",
            S::ParamHomeOutsideLimits => c"COMPANION_STATUS_PARAM_HOME_OUTSIDE_LIMITS",
            S::ParamNotPlanar => c"COMPANION_STATUS_PARAM_NOT_PLANAR",
            S::ParamPeriodTooLong => c"COMPANION_STATUS_PARAM_PERIOD_TOO_LONG",
            S::StepNonFiniteTime => c"COMPANION_STATUS_STEP_NON_FINITE_TIME",
            S::StepNonFiniteBasePose => c"COMPANION_STATUS_STEP_NON_FINITE_BASE_POSE",
            S::StepNonFiniteSteering => c"COMPANION_STATUS_STEP_NON_FINITE_STEERING",
            S::StepNonFiniteJoints => c"COMPANION_STATUS_STEP_NON_FINITE_JOINTS",
            S::StepNonFiniteTargetPose => c"COMPANION_STATUS_STEP_NON_FINITE_TARGET_POSE",
            S::StepNonFiniteTargetVelocity => c"COMPANION_STATUS_STEP_NON_FINITE_TARGET_VELOCITY",
            S::StepBadTimeStep => c"COMPANION_STATUS_STEP_BAD_TIME_STEP",
            S::StepBadDelay => c"COMPANION_STATUS_STEP_BAD_DELAY",
            S::StepJointAtLimitQ1 => c"COMPANION_STATUS_STEP_JOINT_AT_LIMIT_Q1",
            S::StepJointAtLimitQ2 => c"COMPANION_STATUS_STEP_JOINT_AT_LIMIT_Q2",
            S::StepJointAtLimitQ3 => c"COMPANION_STATUS_STEP_JOINT_AT_LIMIT_Q3",
            S::StepSingularArm => c"COMPANION_STATUS_STEP_SINGULAR_ARM",
            S::StepSingularTaskJacobian => c"COMPANION_STATUS_STEP_SINGULAR_TASK_JACOBIAN",
            S::StepTargetYawUndefined => c"COMPANION_STATUS_STEP_TARGET_YAW_UNDEFINED",
            S::StepNumericalFailure => c"COMPANION_STATUS_STEP_NUMERICAL_FAILURE",
        }
    }

    /// The status with this number, if there is one.
    pub fn from_code(code: i32) -> Option<Self> {
        ALL.iter().copied().find(|s| *s as i32 == code)
    }
}

/// The name of a status number, e.g. `"COMPANION_STATUS_STEP_JOINT_AT_LIMIT_Q2"` for 221;
/// `"COMPANION_STATUS_UNKNOWN"` for a number that is not a status. The string is static
/// (never free it) and NUL-terminated.
#[no_mangle]
pub extern "C" fn companion_status_name(status: i32) -> *const c_char {
    match CompanionStatus::from_code(status) {
        Some(s) => s.name().as_ptr(),
        None => c"COMPANION_STATUS_UNKNOWN".as_ptr(),
    }
}
