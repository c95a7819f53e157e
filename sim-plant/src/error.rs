//! Why a plant could not be built or advanced: the errors every other module of the crate
//! reports (a leaf module, so that the modules that validate depend on it and not on the
//! plant).

use companion_core::ParamError;

/// The rule a plant parameter breaks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rule {
    /// The value is NaN or infinite.
    NonFinite,
    /// The value must be `> 0`.
    NotPositive,
    /// The value must be `≥ 0`.
    Negative,
    /// The value must be `> −1` (a wheel-speed scale `1 + e` must stay positive).
    NotAboveMinusOne,
    /// The initial steering state must lie within the steering limit.
    BeyondSteeringLimit,
    /// The actuator lag must be at least [`MIN_ACTUATOR_LAG`](crate::MIN_ACTUATOR_LAG): a
    /// step longer than the lag is integrated in sub-steps no longer than it, so a lag of
    /// 1e-300 s would never finish a step.
    BelowMinimumLag,
    /// The spatial plant does not simulate this imperfection (measurement noise).
    Unsupported,
}

impl core::fmt::Display for Rule {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Rule::NonFinite => "must be finite",
            Rule::NotPositive => "must be > 0",
            Rule::Negative => "must be >= 0",
            Rule::NotAboveMinusOne => "must be > -1",
            Rule::BeyondSteeringLimit => "must lie within the steering limit",
            Rule::BelowMinimumLag => "must be >= 1e-4 s",
            Rule::Unsupported => "is not supported by the spatial plant",
        })
    }
}

/// Why a plant could not be built.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum PlantError {
    /// A plant parameter or initial value breaks a rule.
    #[error("plant parameter `{param}` {rule} (got {})", Shown(*value))]
    Invalid {
        /// The parameter, e.g. `"actuator_lag"` or `"initial.joints"`.
        param: &'static str,
        /// The rule broken.
        rule: Rule,
        /// The value given.
        value: f64,
    },
    /// The arm's geometry is invalid.
    #[error("arm: {0}")]
    Arm(ParamError),
}

/// A value in a message: as usual when of a readable size, in scientific notation when not
/// (`1e-300`, not 300 digits).
struct Shown(f64);

impl core::fmt::Display for Shown {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let a = self.0.abs();
        if a == 0.0 || !a.is_finite() || (1e-4..1e9).contains(&a) {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}

impl PlantError {
    pub(crate) fn check_finite(param: &'static str, value: f64) -> Result<(), PlantError> {
        if value.is_finite() {
            Ok(())
        } else {
            Err(PlantError::Invalid { param, rule: Rule::NonFinite, value })
        }
    }
}

/// Why a step was refused; the plant's state is left as it was.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum AdvanceError {
    /// The time step is NaN, infinite, zero or negative.
    #[error("time step {dt} s must be finite and > 0")]
    BadTimeStep {
        /// The time step given (s).
        dt: f64,
    },
    /// The time step differs from the one of the first step (the plant runs at one fixed
    /// step so that the time of step `n` is exactly `n·dt`).
    #[error("time step {dt} s differs from the plant's fixed step {fixed} s")]
    TimeStepChanged {
        /// The plant's step (s), set by the first step.
        fixed: f64,
        /// The time step given (s).
        dt: f64,
    },
    /// A commanded velocity is NaN or infinite.
    #[error("the command has a non-finite velocity")]
    NonFiniteCommand,
    /// The delay within a step is not finite or not in `[0, dt)`.
    #[error("the delay within a step {delay} s must lie in [0, dt)")]
    BadDelay {
        /// The delay given (s).
        delay: f64,
    },
}

impl AdvanceError {
    /// Checks one step of `dt` seconds in which `previous` acts for `delay` seconds and
    /// `command` for the rest, on a plant whose fixed step is `fixed` (`None` before the
    /// first step): the checks of every plant's `try_advance_delayed`.
    ///
    /// # Errors
    /// The first check that fails.
    pub(crate) fn check<const N: usize>(
        fixed: Option<f64>,
        previous: &companion_core::Command<f64, N>,
        command: &companion_core::Command<f64, N>,
        delay: f64,
        dt: f64,
    ) -> Result<(), Self> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Self::BadTimeStep { dt });
        }
        if let Some(fixed) = fixed {
            if fixed.to_bits() != dt.to_bits() {
                return Err(Self::TimeStepChanged { fixed, dt });
            }
        }
        if !command.is_finite() || !previous.is_finite() {
            return Err(Self::NonFiniteCommand);
        }
        if !(delay.is_finite() && delay >= 0.0 && delay < dt) {
            return Err(Self::BadDelay { delay });
        }
        Ok(())
    }
}
