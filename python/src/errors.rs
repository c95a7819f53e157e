//! The Python exceptions: one class per `StepError` variant (a rejected measurement, under
//! `StepError`) and per `ParamError` rule (an invalid parameter, under `ParamError`), all under
//! `CompanionError`; `ScenarioError` and `ConfigError` for the runtime's other refusals.
//!
//! A rejected step's exception carries the law's answer: `command` (the safe zero command, as
//! a numpy array) and `output` (the whole [`Output`](crate::law::Output), diagnostics NaN).

use companion_core::{Field, ParamError as CoreParamError, Rule, StepError as CoreStepError};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(companion, CompanionError, PyException, "Every error of the companion package.");
create_exception!(
    companion,
    StepError,
    CompanionError,
    "The law rejected a measurement (companion-core's `StepError`) and answered with the safe zero \
     command, available as `.command` (and `.output`); its state is as before the step."
);
create_exception!(
    companion,
    ParamError,
    CompanionError,
    "An invalid parameter (companion-core's `ParamError`): `.param` names it, `.joint` is its joint \
     (from 0) or None, `.rule` the rule broken (the subclass's name)."
);
create_exception!(
    companion,
    ScenarioError,
    CompanionError,
    "A scenario or law that cannot be built for another reason than one parameter (a bad dt, \
     duration, delay, arm or target): the message says which and why."
);
create_exception!(
    companion,
    ConfigError,
    ScenarioError,
    "A config, arm or target file that cannot be read or parsed."
);

create_exception!(
    companion,
    NonFinite,
    StepError,
    "A measured value is NaN or infinite (`.field` says which)."
);
create_exception!(
    companion,
    BadTimeStep,
    StepError,
    "The period is not finite, <= 0, or above max_time_step."
);
create_exception!(
    companion,
    JointAtLimit,
    StepError,
    "Joint `.joint` (from 0) is at or beyond one of its limits."
);
create_exception!(companion, SingularArm, StepError, "The arm is at or near a singular configuration.");
create_exception!(companion, SingularTaskJacobian, StepError, "de_m/dq (eq. 24) cannot be inverted.");
create_exception!(
    companion,
    TargetYawUndefined,
    StepError,
    "The target's x axis is vertical: its yaw is undefined."
);
create_exception!(
    companion,
    BadDelay,
    StepError,
    "The delay is not finite, negative, above max_delay or beyond the command history."
);
create_exception!(companion, NumericalFailure, StepError, "The law produced a non-finite value.");

create_exception!(
    companion,
    NonFiniteParameter,
    ParamError,
    "A parameter is NaN or infinite (the rule `NonFinite`; named apart from the StepError `NonFinite`)."
);
create_exception!(companion, NotPositive, ParamError, "A parameter must be > 0.");
create_exception!(companion, Negative, ParamError, "A parameter must be >= 0.");
create_exception!(companion, NotInUnitInterval, ParamError, "A parameter must lie in [0, 1].");
create_exception!(companion, EmptyInterval, ParamError, "A lower joint limit must be < the upper one.");
create_exception!(
    companion,
    PenaltyMarginTooWide,
    ParamError,
    "Penalty margins must satisfy 0 < 2 delta < q+ - q-."
);
create_exception!(
    companion,
    WeightMarginOrder,
    ParamError,
    "The weight margins of eq. (52) are out of order."
);
create_exception!(
    companion,
    Transversality,
    ParamError,
    "Lemma 2's 6 eta2 eta3 > 8 eta3 + eta1 eta2 does not hold."
);
create_exception!(
    companion,
    Decomposition51NeedsPsiOne,
    ParamError,
    "Decomposition (51) needs the constant weight psi = 1."
);
create_exception!(companion, Geometry, ParamError, "The arm geometry is not usable.");
create_exception!(
    companion,
    TooLarge,
    ParamError,
    "A parameter is above the bound that keeps every step computable."
);
create_exception!(
    companion,
    NotOrthonormal,
    ParamError,
    "A rotation matrix is not orthonormal with determinant 1."
);
create_exception!(companion, NotUnitVector, ParamError, "A joint axis is not a unit vector.");
create_exception!(
    companion,
    TooFewJoints,
    ParamError,
    "The arm has fewer joints than the task has dimensions."
);
create_exception!(
    companion,
    HomeOutsideLimits,
    ParamError,
    "A joint's home position is not strictly inside its limits."
);
create_exception!(companion, NotPlanar, ParamError, "A planar arm's joints and frames are not planar.");
create_exception!(
    companion,
    PeriodTooLong,
    ParamError,
    "max_time_step times the law's largest rate is above 0.1."
);

/// The `StepError` variant's name (the exception's class name), as in companion-core.
pub fn step_error_name(e: CoreStepError) -> &'static str {
    match e {
        CoreStepError::NonFinite(_) => "NonFinite",
        CoreStepError::BadTimeStep => "BadTimeStep",
        CoreStepError::JointAtLimit(_) => "JointAtLimit",
        CoreStepError::SingularArm => "SingularArm",
        CoreStepError::SingularTaskJacobian => "SingularTaskJacobian",
        CoreStepError::TargetYawUndefined => "TargetYawUndefined",
        CoreStepError::BadDelay => "BadDelay",
        CoreStepError::NumericalFailure => "NumericalFailure",
    }
}

/// The `StepError` variants in the order of the batch call's `error` codes (code `i + 1` is
/// variant `i`; 0 is an accepted step).
pub const STEP_ERRORS: [&str; 8] = [
    "NonFinite",
    "BadTimeStep",
    "JointAtLimit",
    "SingularArm",
    "SingularTaskJacobian",
    "TargetYawUndefined",
    "BadDelay",
    "NumericalFailure",
];

/// The batch call's code of a step: 0 accepted, else 1 + the variant's index in
/// [`STEP_ERRORS`].
pub fn step_error_code(e: Option<CoreStepError>) -> u8 {
    e.map_or(0, |e| {
        let name = step_error_name(e);
        let i = STEP_ERRORS.iter().position(|n| *n == name).unwrap_or(0) as u8;
        i + 1
    })
}

fn field_name(f: Field) -> &'static str {
    match f {
        Field::Time => "t",
        Field::BasePose => "base",
        Field::Steering => "steering",
        Field::Joints => "joints",
        Field::TargetPose => "target",
        Field::TargetVelocity => "target_velocity",
    }
}

/// The exception of a rejected step, with `command`, `output` and the variant's fields set.
pub fn step_error(py: Python<'_>, e: CoreStepError, output: Py<PyAny>, command: Py<PyAny>) -> PyErr {
    let msg = e.to_string();
    let err = match e {
        CoreStepError::NonFinite(_) => NonFinite::new_err(msg),
        CoreStepError::BadTimeStep => BadTimeStep::new_err(msg),
        CoreStepError::JointAtLimit(_) => JointAtLimit::new_err(msg),
        CoreStepError::SingularArm => SingularArm::new_err(msg),
        CoreStepError::SingularTaskJacobian => SingularTaskJacobian::new_err(msg),
        CoreStepError::TargetYawUndefined => TargetYawUndefined::new_err(msg),
        CoreStepError::BadDelay => BadDelay::new_err(msg),
        CoreStepError::NumericalFailure => NumericalFailure::new_err(msg),
    };
    let v = err.value(py);
    let field: Option<&str> = match e {
        CoreStepError::NonFinite(f) => Some(field_name(f)),
        _ => None,
    };
    let joint = match e {
        CoreStepError::JointAtLimit(j) => Some(j),
        _ => None,
    };
    // Setting attributes on a fresh exception instance cannot fail but for memory.
    let _ = v.setattr("command", command);
    let _ = v.setattr("output", output);
    let _ = v.setattr("field", field);
    let _ = v.setattr("joint", joint);
    let _ = v.setattr("variant", step_error_name(e));
    err
}

/// The exception of an invalid parameter, with `param`, `joint` and `rule` set.
pub fn param_error(py: Python<'_>, e: CoreParamError) -> PyErr {
    rule_error(py, e.to_string(), e.param, e.joint, e.rule)
}

/// The `ParamError` subclass of `rule` with message `msg`, `param`, `joint` set (an arm file's
/// rule names the field in the file's words: `joint 2: axis`).
fn rule_error(py: Python<'_>, msg: String, param: &str, joint: Option<u8>, rule: Rule) -> PyErr {
    let (err, name) = match rule {
        Rule::NonFinite => (NonFiniteParameter::new_err(msg), "NonFinite"),
        Rule::NotPositive => (NotPositive::new_err(msg), "NotPositive"),
        Rule::Negative => (Negative::new_err(msg), "Negative"),
        Rule::NotInUnitInterval => (NotInUnitInterval::new_err(msg), "NotInUnitInterval"),
        Rule::EmptyInterval => (EmptyInterval::new_err(msg), "EmptyInterval"),
        Rule::PenaltyMarginTooWide => (PenaltyMarginTooWide::new_err(msg), "PenaltyMarginTooWide"),
        Rule::WeightMarginOrder => (WeightMarginOrder::new_err(msg), "WeightMarginOrder"),
        Rule::Transversality => (Transversality::new_err(msg), "Transversality"),
        Rule::Decomposition51NeedsPsiOne => {
            (Decomposition51NeedsPsiOne::new_err(msg), "Decomposition51NeedsPsiOne")
        }
        Rule::Geometry => (Geometry::new_err(msg), "Geometry"),
        Rule::TooLarge(_) => (TooLarge::new_err(msg), "TooLarge"),
        Rule::NotOrthonormal => (NotOrthonormal::new_err(msg), "NotOrthonormal"),
        Rule::NotUnitVector => (NotUnitVector::new_err(msg), "NotUnitVector"),
        Rule::TooFewJoints => (TooFewJoints::new_err(msg), "TooFewJoints"),
        Rule::HomeOutsideLimits => (HomeOutsideLimits::new_err(msg), "HomeOutsideLimits"),
        Rule::NotPlanar => (NotPlanar::new_err(msg), "NotPlanar"),
        Rule::PeriodTooLong => (PeriodTooLong::new_err(msg), "PeriodTooLong"),
    };
    let v = err.value(py);
    let _ = v.setattr("param", param);
    let _ = v.setattr("joint", joint);
    let _ = v.setattr("rule", name);
    err
}

/// A runtime error as a Python exception: an invalid parameter (of the law, or of an arm file's
/// chain) as its `ParamError` subclass (wherever it sits in the chain of causes), a file as
/// `ConfigError`, the rest as `ScenarioError`, with the whole chain of causes in the message.
pub fn runtime_error(py: Python<'_>, e: &anyhow::Error) -> PyErr {
    for cause in e.chain() {
        if let Some(companion_runtime::domain::arm::ArmError::Invalid { field, rule }) =
            cause.downcast_ref::<companion_runtime::domain::arm::ArmError>()
        {
            return rule_error(py, format!("{e:#}"), field, None, *rule);
        }
        if let Some(p) = cause.downcast_ref::<CoreParamError>() {
            return param_error(py, *p);
        }
        if let Some(companion_runtime::domain::scenario::ScenarioError::Param(p)) =
            cause.downcast_ref::<companion_runtime::domain::scenario::ScenarioError>()
        {
            return param_error(py, *p);
        }
    }
    let msg = format!("{e:#}");
    let file = e.chain().any(|c| {
        c.is::<companion_runtime::domain::scenario::ConfigError>()
            || c.is::<companion_runtime::domain::arm::ArmError>()
    });
    if file {
        ConfigError::new_err(msg)
    } else {
        ScenarioError::new_err(msg)
    }
}

/// A planar run's error as [`runtime_error`] reads it: its cause (the scenario, the plant)
/// itself, so that a parameter's class is found as when the cause came up alone.
pub fn sim_error(py: Python<'_>, e: companion_runtime::run::sim::SimError) -> PyErr {
    use companion_runtime::run::sim::SimError;
    let e = match e {
        SimError::Setup(e) => anyhow::Error::new(e),
        SimError::Scenario(e) => anyhow::Error::new(e),
        other => anyhow::Error::new(other),
    };
    runtime_error(py, &e)
}

/// A spatial run's error as [`runtime_error`] reads it: its cause (the scenario, the arm,
/// the law) itself, so that a parameter's class is found as when the cause came up alone.
pub fn spatial_error(py: Python<'_>, e: companion_runtime::run::spatial::SpatialRunError) -> PyErr {
    use companion_runtime::run::spatial::SpatialRunError;
    let e = match e {
        SpatialRunError::Scenario(e) => anyhow::Error::new(e),
        SpatialRunError::Arm(e) => anyhow::Error::new(e),
        SpatialRunError::Controller(e) => anyhow::Error::new(e),
        other => anyhow::Error::new(other),
    };
    runtime_error(py, &e)
}

/// Adds every exception class to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    macro_rules! add {
        ($($t:ident),* $(,)?) => { $( m.add(stringify!($t), py.get_type::<$t>())?; )* };
    }
    add!(
        CompanionError,
        StepError,
        ParamError,
        ScenarioError,
        ConfigError,
        NonFinite,
        BadTimeStep,
        JointAtLimit,
        SingularArm,
        SingularTaskJacobian,
        TargetYawUndefined,
        BadDelay,
        NumericalFailure,
        NonFiniteParameter,
        NotPositive,
        Negative,
        NotInUnitInterval,
        EmptyInterval,
        PenaltyMarginTooWide,
        WeightMarginOrder,
        Transversality,
        Decomposition51NeedsPsiOne,
        Geometry,
        TooLarge,
        NotOrthonormal,
        NotUnitVector,
        TooFewJoints,
        HomeOutsideLimits,
        NotPlanar,
        PeriodTooLong,
    );
    m.add("STEP_ERRORS", STEP_ERRORS.to_vec())?;
    Ok(())
}
