//! Why a message is dropped ([`WireError`]) and the `status` codes of a step (accepted, or
//! the core's rejection reason).

use companion_core::{Field, StepError};

use super::layout::{MAX_JOINTS, PROTOCOL_VERSION};
use super::target::TargetError;

/// Why a message was dropped (or, [`WireError::Refused`], why the run ends).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WireError {
    /// Another protocol version.
    Version(u32),
    /// Another session (a message of an earlier or another plant run).
    Session,
    /// An answer to an earlier period (arrived after its deadline), or a measurement not newer
    /// than the last one.
    Stale(u64),
    /// A sequence number from the future (no such measurement was sent).
    Future(u64),
    /// A `joint_count` other than the expected one.
    JointCount(u32),
    /// An unknown `status` code.
    Status(u32),
    /// A non-finite velocity.
    NonFinite,
    /// A measurement whose announcement differs from the session's first.
    Changed,
    /// The controller refused the run (the [`Refusal`](super::Refusal) code).
    Refused(u32),
    /// A planar target off the plane (`z`, `v_z`, `ω_x` or `ω_y` not 0).
    NotPlanar,
    /// A spatial target whose finite rotation is not orthonormal ([`ROTATION_TOLERANCE`](super::target::ROTATION_TOLERANCE)).
    NotARotation,
}

impl core::fmt::Display for WireError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Version(v) => write!(f, "protocol version {v} (expected {PROTOCOL_VERSION})"),
            Self::Session => f.write_str("message of another session"),
            Self::Stale(s) => write!(f, "stale sequence number {s}"),
            Self::Future(s) => write!(f, "sequence number {s} from the future"),
            Self::JointCount(n) => write!(f, "joint count {n}"),
            Self::Status(c) => write!(f, "unknown status code {c:#x}"),
            Self::NonFinite => f.write_str("non-finite velocity"),
            Self::Changed => f.write_str("announcement changed within the session"),
            Self::Refused(c) => write!(f, "the controller refused the run (status {c:#x})"),
            Self::NotPlanar => f.write_str("planar target off the plane (z, v_z, ω_x or ω_y not 0)"),
            Self::NotARotation => f.write_str("target rotation not orthonormal"),
        }
    }
}

impl core::error::Error for WireError {}

impl From<TargetError> for WireError {
    fn from(e: TargetError) -> Self {
        match e {
            TargetError::NotPlanar => Self::NotPlanar,
            TargetError::NotARotation => Self::NotARotation,
        }
    }
}

impl WireError {
    /// A short stable name (for counters in `latency.json`).
    pub fn name(&self) -> &'static str {
        match self {
            Self::Version(_) => "version",
            Self::Session => "session",
            Self::Stale(_) => "stale",
            Self::Future(_) => "future_seq",
            Self::JointCount(_) => "joint_count",
            Self::Status(_) => "status",
            Self::NonFinite => "non_finite",
            Self::Changed => "changed",
            Self::Refused(_) => "refused",
            Self::NotPlanar => "not_planar",
            Self::NotARotation => "not_a_rotation",
        }
    }
}

fn field_code(f: Field) -> u32 {
    match f {
        Field::Time => 0,
        Field::BasePose => 1,
        Field::Steering => 2,
        Field::Joints => 3,
        Field::TargetPose => 4,
        Field::TargetVelocity => 5,
    }
}

/// The `status` code of a step: 0 when it was accepted, else the rejection reason.
pub fn encode_status(e: Option<StepError>) -> u32 {
    match e {
        None => 0,
        Some(StepError::NonFinite(f)) => 0x100 + field_code(f),
        Some(StepError::BadTimeStep) => 0x200,
        Some(StepError::JointAtLimit(j)) => 0x300 + u32::from(j),
        Some(StepError::SingularArm) => 0x400,
        Some(StepError::SingularTaskJacobian) => 0x500,
        Some(StepError::NumericalFailure) => 0x600,
        Some(StepError::BadDelay) => 0x700,
        Some(StepError::TargetYawUndefined) => 0x800,
    }
}

/// The inverse of [`encode_status`].
///
/// # Errors
/// [`WireError::Status`] for a code no step produces.
pub fn decode_status(code: u32) -> Result<Option<StepError>, WireError> {
    let field = |c: u32| match c {
        0 => Some(Field::Time),
        1 => Some(Field::BasePose),
        2 => Some(Field::Steering),
        3 => Some(Field::Joints),
        4 => Some(Field::TargetPose),
        5 => Some(Field::TargetVelocity),
        _ => None,
    };
    Ok(match code {
        0 => None,
        0x100..=0x1ff => Some(StepError::NonFinite(field(code - 0x100).ok_or(WireError::Status(code))?)),
        0x200 => Some(StepError::BadTimeStep),
        0x300..=0x3ff if ((code - 0x300) as usize) < MAX_JOINTS => {
            Some(StepError::JointAtLimit((code - 0x300) as u8))
        }
        0x400 => Some(StepError::SingularArm),
        0x500 => Some(StepError::SingularTaskJacobian),
        0x600 => Some(StepError::NumericalFailure),
        0x700 => Some(StepError::BadDelay),
        0x800 => Some(StepError::TargetYawUndefined),
        _ => return Err(WireError::Status(code)),
    })
}
