//! The two messages of the HIL loop — the interface a bridge to real hardware implements —
//! and the rules that decide whether a message is used.
//!
//! The complete protocol (services and their settings, start-up, events, silence, end of
//! run, versioning) is `docs/protocol.md` in the repository: a bridge author needs nothing
//! else. This module is its implementation; a test checks the layouts below against the
//! document's.
//!
//! Every control period the plant publishes one [`MeasurementMsg`] and the controller answers
//! it with one [`CommandMsg`]. Both are `#[repr(C)]`, fixed size, made only of `u32`, `u64`
//! and `f64` fields laid out without padding (alignment 8), little-endian, and travel by
//! iceoryx2 publish–subscribe in shared memory with the type names
//! [`MEASUREMENT_TYPE_NAME`] and [`COMMAND_TYPE_NAME`] (see [`crate::transport::ipc`]); a transport that
//! carries bytes sends [`MeasurementMsg::to_bytes`].
//!
//! ## Rules of the exchange (protocol version 4)
//!
//! - **The plant owns time.** It numbers measurements `seq = 0, 1, 2, …` within a `session`
//!   (a random non-zero id per plant run), stamps each with `plant_time_ns` (its
//!   `CLOCK_MONOTONIC` when the values were measured) and says how long a command is held
//!   (`dt`, on the time scale of `sim_time`) and how often it publishes (`period_ns`).
//! - **The plant announces everything the commands depend on** besides the measured values:
//!   `platform`, `joint_count`, the target's `space`, `arm_hash`, `dt`, `period_ns`,
//!   `hold_periods`, the [`flags::LOCKSTEP`] and [`flags::NOTIFIES`] bits and the
//!   `scenario_hash` ([`Announcement`]). The controller
//!   checks them on the first measurement of a session ([`ControllerIdentity::admit`]) and
//!   refuses a plant it cannot serve with a [`Refusal`] command that names the mismatch;
//!   later measurements of the session must announce the same ([`WireError::Changed`]).
//! - **The plant measures the delay**: `delay` is the time (s, time scale of `dt`) from a
//!   measurement's timestamp to the moment its answer takes effect, as the plant expects it
//!   (the reference plant: what it measured for the previous command; 0 in lockstep). The
//!   controller predicts over it ([`crate::domain::controller::AnyController::step`]).
//! - The controller answers measurement `seq` with a command carrying the same `seq`,
//!   `session` and `plant_time_ns`, its own `platform`, `joint_count` and `scenario_hash`, and
//!   the `delay` it used. If several measurements are waiting it answers only the newest and
//!   reports how many it skipped (`skipped`).
//! - A command is applied only if it answers the measurement of the current period, has this
//!   `version`, the expected `joint_count`, a known `status` and finite velocities
//!   ([`check_command`]); anything else is counted and dropped. A refusal (`status` `0x80nn`)
//!   ends the run.
//! - Non-finite *values* in a well-formed measurement are the law's business: it answers them
//!   with the safe command (all velocities zero) and a `status` saying why.
//!
//! ## Layout of [`MeasurementMsg`] (344 bytes)
//!
//! ```text
//! offset type      field            meaning
//!      0 u32       version          PROTOCOL_VERSION (4)
//!      4 u32       flags            END_OF_RUN 1, LOCKSTEP 2, STOPPED 4, NOTIFIES 8
//!      8 u64       seq              period number, from 0
//!     16 u64       session          random non-zero id of this plant run
//!     24 u64       scenario_hash    canonical hash of the controller's scenario; 0 = unchecked
//!     32 u64       arm_hash         canonical hash of the plant's arm; 0 = unchecked
//!     40 u64       plant_time_ns    plant's CLOCK_MONOTONIC when measured (ns)
//!     48 u64       period_ns        publication period (ns); 0 in lockstep
//!     56 f64       sim_time         the plant's time t (s)
//!     64 f64       dt               how long each command is held (s)
//!     72 f64       delay            expected measurement-to-effect delay of the answer (s)
//!     80 u32       platform         1 unicycle, 2 car-like, 3 omnidirectional
//!     84 u32       hold_periods     periods the plant holds a command after a miss
//!     88 u32       joint_count      joints used (3 for the paper's arm, ≤ 8)
//!     92 u32       space            the target's space: 1 planar (SE(2)), 2 spatial (SE(3))
//!     96 f64[3]    base             platform pose r_b = (x, y, θ) (m, m, rad)
//!    120 f64       steering         car-like steering ξ (1/m); 0 otherwise
//!    128 f64[3]    target_position  target origin p_d = (x, y, z) (m), fixed frame
//!    152 f64[9]    target_rotation  target rotation R_d, row by row (R₁₁ R₁₂ R₁₃ R₂₁ …)
//!    224 f64       target_yaw       target yaw ψ (rad): exact θ of a planar target
//!    232 f64[6]    target_twist     target body twist (v, ω) (m/s, rad/s)
//!    280 f64[8]    joints           joint positions q (rad or m)
//! ```
//!
//! The target's fields and the planar ↔ spatial conversion: [`target`].
//!
//! ## Layout of [`CommandMsg`] (248 bytes)
//!
//! ```text
//! offset type      field            meaning
//!      0 u32       version          PROTOCOL_VERSION (4)
//!      4 u32       status           0 ok; 0x100–0x7ff the law's rejection; 0x80nn refusal
//!      8 u64       seq              the measurement this answers
//!     16 u64       session          copied from the measurement
//!     24 u64       plant_time_ns    copied from the measurement
//!     32 u64       compute_ns       receipt of the measurement to publication (ns)
//!     40 u64       received_ns      controller's CLOCK_MONOTONIC at receipt (ns)
//!     48 u32       skipped          newer-measurement skips since the previous answer
//!     52 u32       joint_count      the controller's joint count
//!     56 u32       flags            NOTIFIES 8
//!     60 u32       platform         the controller's platform (codes as above)
//!     64 u64       scenario_hash    the controller's scenario hash
//!     72 u64       arm_hash         the controller's arm hash
//!     80 u32       space            the controller's target space (codes as above)
//!     84 u32       reserved         0
//!     88 f64       delay            the delay the law predicted over (s)
//!     96 f64       v                forward speed (m/s)
//!    104 f64       v_lat            lateral speed (m/s), omnidirectional platform
//!    112 f64       omega            angular speed (rad/s)
//!    120 f64       v_xi             steering rate (1/(m·s)), car-like platform
//!    128 f64[8]    joints           joint velocities u_q (rad/s or m/s)
//!    192 f64       ep_norm          ‖e_p‖ (logged; NaN when rejected)
//!    200 f64       h_s              h_s (logged; NaN when rejected)
//!    208 f64       psi              Ψ (logged; NaN when rejected)
//!    216 f64       saturation       common saturation factor ≥ 1 (logged; NaN when rejected)
//!    224 f64[2]    alpha_rate       α̇ (logged; NaN when rejected)
//!    240 f64       joint_scale      joint guard's factor ≥ 1 (logged; NaN when rejected)
//! ```
//!
//! `status` codes. The law answered with the safe command (all velocities zero): `0x100 + f`
//! a non-finite measured field `f` (0 time, 1 base pose, 2 steering, 3 joints, 4 target pose,
//! 5 target velocity); `0x200` bad time step; `0x300 + j` joint `j` (from 0) at or beyond its
//! limit; `0x400` singular arm; `0x500` singular task Jacobian; `0x600` numerical failure;
//! `0x700` bad delay; `0x800` target yaw undefined (spatial arms). The controller refuses the
//! run ([`Refusal`]; velocities zero, the controller exits after sending it): `0x8001`
//! protocol version, `0x8002` joint count, `0x8003` platform, `0x8004` scenario, `0x8005`
//! period (`dt`), `0x8006` target space, `0x8007` arm.
//!
//! ## Joints, space and arm
//!
//! Both messages have room for [`MAX_JOINTS`] = 8 joints and a `joint_count` saying how many
//! are used (the rest are zero); a controller built for `N` joints refuses another count.
//! The target is always carried in SE(3) with its yaw ([`target`]); `space` says whether it
//! is planar (the `rpr` arm's task, §4) or spatial (§5), and a controller refuses the other.
//! `arm_hash` ([`canonical::arm_hash`]) names the arm: a plant and a controller with
//! different arms refuse each other (0 on either side: not checked).

pub mod canonical;
pub mod target;

pub use canonical::fnv1a;
use companion_core::nalgebra::SVector;
use companion_core::{Command, Field, Measurement, Planar, PlatformCommand, Pose, StepError};
use iceoryx2::prelude::ZeroCopySend;
pub use target::{TargetError, WireSpace, WireTarget};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout};

/// The protocol version both messages carry. Changed whenever the layout or meaning changes;
/// it is also part of the service names ([`crate::transport::ipc`]), so that peers of different
/// versions never open each other's services.
pub const PROTOCOL_VERSION: u32 = 4;

/// Room for joints in both messages.
pub const MAX_JOINTS: usize = 8;

/// The iceoryx2 type name of [`MeasurementMsg`] (what a bridge in another language declares).
pub const MEASUREMENT_TYPE_NAME: &str = "companion::MeasurementV4";
/// The iceoryx2 type name of [`CommandMsg`].
pub const COMMAND_TYPE_NAME: &str = "companion::CommandV4";

/// Bits of [`MeasurementMsg::flags`] (and [`flags::NOTIFIES`] of [`CommandMsg::flags`]).
pub mod flags {
    /// The last measurement of the run: answer it, then exit.
    pub const END_OF_RUN: u32 = 1;
    /// Lockstep mode: the plant waits for every command (no period, no deadline).
    pub const LOCKSTEP: u32 = 2;
    /// The plant has stopped the robot (commands missed too many deadlines).
    pub const STOPPED: u32 = 4;
    /// The sender notifies its `-ready` event after each message: the peer may sleep on it.
    pub const NOTIFIES: u32 = 8;
    /// The flags that announce the plant's mode (constant within a session).
    pub const ANNOUNCED: u32 = LOCKSTEP | NOTIFIES;
}

/// The `platform` codes of both messages.
pub mod platform {
    use companion_core::PlatformKind;

    /// Unicycle-like (differential drive).
    pub const UNICYCLE: u32 = 1;
    /// Car-like.
    pub const CAR: u32 = 2;
    /// Omnidirectional.
    pub const OMNI: u32 = 3;

    /// The code of a platform.
    pub fn code(k: PlatformKind) -> u32 {
        match k {
            PlatformKind::Unicycle => UNICYCLE,
            PlatformKind::Car => CAR,
            PlatformKind::Omni => OMNI,
        }
    }

    /// The platform of a code.
    pub fn kind(code: u32) -> Option<PlatformKind> {
        match code {
            UNICYCLE => Some(PlatformKind::Unicycle),
            CAR => Some(PlatformKind::Car),
            OMNI => Some(PlatformKind::Omni),
            _ => None,
        }
    }

    /// A code in words (`unicycle`, `car-like`, `omnidirectional`, or `unknown (n)`).
    pub fn describe(code: u32) -> String {
        match code {
            UNICYCLE => "unicycle".into(),
            CAR => "car-like".into(),
            OMNI => "omnidirectional".into(),
            n => format!("unknown ({n})"),
        }
    }
}

// The derives below generate `unsafe impl`s (`ZeroCopySend`; zerocopy's byte conversions,
// which zerocopy checks at compile time: `#[repr(C)]`, numbers and arrays of numbers only, no
// padding), hence the allow.
/// One measurement of the plant, published once per period. See the module docs for the
/// layout and the rules.
#[allow(unsafe_code)]
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend, IntoBytes, FromBytes, Immutable, KnownLayout)]
#[type_name("companion::MeasurementV4")]
#[repr(C)]
pub struct MeasurementMsg {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// [`flags`] bits.
    pub flags: u32,
    /// Period number, from 0.
    pub seq: u64,
    /// Random non-zero id of this plant run.
    pub session: u64,
    /// [`canonical::scenario_hash`] of the controller's scenario; 0 = not checked.
    pub scenario_hash: u64,
    /// [`canonical::arm_hash`] of the plant's arm; 0 = not checked.
    pub arm_hash: u64,
    /// The plant's `CLOCK_MONOTONIC` when the values were measured (ns).
    pub plant_time_ns: u64,
    /// The publication period (ns); 0 in lockstep.
    pub period_ns: u64,
    /// The plant's time `t` (s).
    pub sim_time: f64,
    /// How long each command is held (s): the step the controller integrates over.
    pub dt: f64,
    /// The delay (s, time scale of `dt`) from this measurement's timestamp to the moment its
    /// answer is expected to take effect.
    pub delay: f64,
    /// The plant's [`platform`] code.
    pub platform: u32,
    /// Periods the plant holds the last command after a missed deadline before it stops.
    pub hold_periods: u32,
    /// Joints used.
    pub joint_count: u32,
    /// The target's [`target::space`] code.
    pub space: u32,
    /// Platform pose `r_b = (x, y, θ)` (m, m, rad).
    pub base: [f64; 3],
    /// Car-like steering `ξ` (1/m); 0 otherwise.
    pub steering: f64,
    /// Target origin `p_d = (x, y, z)` (m), fixed frame.
    pub target_position: [f64; 3],
    /// Target rotation `R_d`, row by row.
    pub target_rotation: [f64; 9],
    /// Target yaw `ψ` (rad): the exact `θ` of a planar target ([`target`]).
    pub target_yaw: f64,
    /// Target body twist `(v, ω)`: `ṗ_d = R_d v`, `Ṙ_d = R_d [ω]×` (m/s, rad/s).
    pub target_twist: [f64; 6],
    /// Joint positions `q` (rad or m); entries past `joint_count` are zero.
    pub joints: [f64; MAX_JOINTS],
}

/// One command of the controller, answering one measurement. See the module docs.
#[allow(unsafe_code)]
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend, IntoBytes, FromBytes, Immutable, KnownLayout)]
#[type_name("companion::CommandV4")]
#[repr(C)]
pub struct CommandMsg {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// 0 = ok, else [`encode_status`] of the law's rejection, or a [`Refusal`] code.
    pub status: u32,
    /// The sequence number of the measurement this answers.
    pub seq: u64,
    /// Copied from the measurement.
    pub session: u64,
    /// Copied from the measurement.
    pub plant_time_ns: u64,
    /// Controller time from receipt of the measurement to publication of this command (ns).
    pub compute_ns: u64,
    /// The controller's `CLOCK_MONOTONIC` when the measurement arrived (ns).
    pub received_ns: u64,
    /// Measurements skipped (superseded by a newer one) since the previous answer.
    pub skipped: u32,
    /// The controller's joint count.
    pub joint_count: u32,
    /// [`flags::NOTIFIES`] if the controller notifies `command-ready`.
    pub flags: u32,
    /// The controller's [`platform`] code.
    pub platform: u32,
    /// The controller's scenario hash.
    pub scenario_hash: u64,
    /// The controller's arm hash.
    pub arm_hash: u64,
    /// The controller's [`target::space`] code.
    pub space: u32,
    /// Zero.
    pub reserved: u32,
    /// The delay the law predicted over (s).
    pub delay: f64,
    /// Forward speed `v` (m/s).
    pub v: f64,
    /// Lateral speed `v_lat` (m/s), omnidirectional platform.
    pub v_lat: f64,
    /// Angular speed `ω` (rad/s).
    pub omega: f64,
    /// Steering rate `v_ξ` (1/(m·s)), car-like platform.
    pub v_xi: f64,
    /// Joint velocities `u_q`; entries past `joint_count` are zero.
    pub joints: [f64; MAX_JOINTS],
    /// `‖e_p‖` (NaN when rejected).
    pub ep_norm: f64,
    /// `h_s` (NaN when rejected).
    pub h_s: f64,
    /// `Ψ` (NaN when rejected).
    pub psi: f64,
    /// The common saturation factor (NaN when rejected).
    pub saturation: f64,
    /// `α̇` (NaN when rejected).
    pub alpha_rate: [f64; 2],
    /// The joint guard's factor (≥ 1; 1: the arm law applied as is; NaN when rejected).
    pub joint_scale: f64,
}

/// A message of the wire: a plain `#[repr(C)]` value with its iceoryx2 type name.
pub trait WireMessage: Copy + core::fmt::Debug + ZeroCopySend + 'static {
    /// The iceoryx2 type name (what iceoryx2 compares, with size and alignment, when a
    /// service is opened).
    const TYPE_NAME: &'static str;
}

impl WireMessage for MeasurementMsg {
    const TYPE_NAME: &'static str = MEASUREMENT_TYPE_NAME;
}

impl WireMessage for CommandMsg {
    const TYPE_NAME: &'static str = COMMAND_TYPE_NAME;
}

/// The size of [`MeasurementMsg`] in bytes.
pub const MEASUREMENT_SIZE: usize = 344;
/// The size of [`CommandMsg`] in bytes.
pub const COMMAND_SIZE: usize = 248;

const _: () = assert!(core::mem::size_of::<MeasurementMsg>() == MEASUREMENT_SIZE);
const _: () = assert!(core::mem::size_of::<CommandMsg>() == COMMAND_SIZE);
const _: () = assert!(core::mem::align_of::<MeasurementMsg>() == 8);
const _: () = assert!(core::mem::align_of::<CommandMsg>() == 8);
// The wire is little-endian and the bytes are the in-memory layout.
const _: () = assert!(cfg!(target_endian = "little"), "the wire format is little-endian");

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
    /// The controller refused the run (the [`Refusal`] code).
    Refused(u32),
    /// A planar target off the plane (`z`, `v_z`, `ω_x` or `ω_y` not 0).
    NotPlanar,
    /// A spatial target whose finite rotation is not orthonormal ([`target::ROTATION_TOLERANCE`]).
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

const fn count_u32(n: usize) -> u32 {
    n as u32
}

/// What the plant announces in every measurement of a session: everything besides the
/// measured values that the commands depend on or that must match (constant within a
/// session).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Announcement {
    /// [`flags::ANNOUNCED`] bits: lockstep, notifies.
    pub flags: u32,
    /// [`platform`] code.
    pub platform: u32,
    /// Joints used.
    pub joint_count: u32,
    /// The target's [`target::space`] code.
    pub space: u32,
    /// Hold limit (periods).
    pub hold_periods: u32,
    /// How long each command is held (s).
    pub dt: f64,
    /// Publication period (ns); 0 in lockstep.
    pub period_ns: u64,
    /// Scenario hash; 0 = not checked.
    pub scenario_hash: u64,
    /// Arm hash; 0 = not checked.
    pub arm_hash: u64,
}

impl Announcement {
    /// The announcement a measurement carries.
    pub fn of(m: &MeasurementMsg) -> Self {
        Self {
            flags: m.flags & flags::ANNOUNCED,
            platform: m.platform,
            joint_count: m.joint_count,
            space: m.space,
            hold_periods: m.hold_periods,
            dt: m.dt,
            period_ns: m.period_ns,
            scenario_hash: m.scenario_hash,
            arm_hash: m.arm_hash,
        }
    }

    /// Lockstep: the plant waits for every command.
    pub fn lockstep(&self) -> bool {
        self.flags & flags::LOCKSTEP != 0
    }

    /// The plant notifies `measurement-ready` after each measurement.
    pub fn notifies(&self) -> bool {
        self.flags & flags::NOTIFIES != 0
    }

    /// Equal, with `dt` compared bit for bit.
    fn same_as(&self, o: &Self) -> bool {
        Self { dt: 0.0, ..*self } == Self { dt: 0.0, ..*o } && self.dt.to_bits() == o.dt.to_bits()
    }
}

/// Why the controller refuses to serve a plant (sent as the `status` of a command, then the
/// controller exits). Each names the plant's and the controller's value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Refusal {
    /// The measurement's `version` is not [`PROTOCOL_VERSION`].
    Version {
        /// The plant's version.
        plant: u32,
    },
    /// Another joint count.
    JointCount {
        /// The plant's.
        plant: u32,
        /// The controller's.
        controller: u32,
    },
    /// Another platform.
    Platform {
        /// The plant's code.
        plant: u32,
        /// The controller's code.
        controller: u32,
    },
    /// Another scenario (both hashes non-zero and different).
    Scenario {
        /// The plant's hash.
        plant: u64,
        /// The controller's hash.
        controller: u64,
    },
    /// A `dt` the law does not admit (not finite, `≤ 0`, or above its `max_time_step`).
    Period {
        /// The plant's `dt` (s).
        dt: f64,
    },
    /// Another target space (a planar plant and a spatial controller, or the reverse).
    Space {
        /// The plant's [`target::space`] code.
        plant: u32,
        /// The controller's.
        controller: u32,
    },
    /// Another arm (both hashes non-zero and different).
    Arm {
        /// The plant's arm hash.
        plant: u64,
        /// The controller's.
        controller: u64,
    },
}

/// The refusal codes (`status` of a refusal command).
pub mod refusal {
    /// Another protocol version.
    pub const VERSION: u32 = 0x8001;
    /// Another joint count.
    pub const JOINT_COUNT: u32 = 0x8002;
    /// Another platform.
    pub const PLATFORM: u32 = 0x8003;
    /// Another scenario.
    pub const SCENARIO: u32 = 0x8004;
    /// A `dt` the law does not admit.
    pub const PERIOD: u32 = 0x8005;
    /// Another target space.
    pub const SPACE: u32 = 0x8006;
    /// Another arm.
    pub const ARM: u32 = 0x8007;

    /// Whether a `status` is a refusal.
    pub fn is_refusal(status: u32) -> bool {
        status & 0xff00 == 0x8000
    }
}

impl Refusal {
    /// The `status` code.
    pub fn code(&self) -> u32 {
        match self {
            Self::Version { .. } => refusal::VERSION,
            Self::JointCount { .. } => refusal::JOINT_COUNT,
            Self::Platform { .. } => refusal::PLATFORM,
            Self::Scenario { .. } => refusal::SCENARIO,
            Self::Period { .. } => refusal::PERIOD,
            Self::Space { .. } => refusal::SPACE,
            Self::Arm { .. } => refusal::ARM,
        }
    }

    /// What a plant learns from a refusal command `c` answering its measurement `m`.
    pub fn from_command(c: &CommandMsg, m: &MeasurementMsg) -> Option<Self> {
        Some(match c.status {
            refusal::VERSION => Self::Version { plant: m.version },
            refusal::JOINT_COUNT => Self::JointCount { plant: m.joint_count, controller: c.joint_count },
            refusal::PLATFORM => Self::Platform { plant: m.platform, controller: c.platform },
            refusal::SCENARIO => Self::Scenario { plant: m.scenario_hash, controller: c.scenario_hash },
            refusal::PERIOD => Self::Period { dt: m.dt },
            refusal::SPACE => Self::Space { plant: m.space, controller: c.space },
            refusal::ARM => Self::Arm { plant: m.arm_hash, controller: c.arm_hash },
            _ => return None,
        })
    }
}

impl core::fmt::Display for Refusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Version { plant } => write!(
                f,
                "protocol version mismatch: the plant speaks version {plant}, the controller version \
                 {PROTOCOL_VERSION}"
            ),
            Self::JointCount { plant, controller } => write!(
                f,
                "joint count mismatch: the plant has {plant} joints, the controller is built for {controller}"
            ),
            Self::Platform { plant, controller } => write!(
                f,
                "platform mismatch: the plant is {}, the controller is built for {}",
                platform::describe(*plant),
                platform::describe(*controller)
            ),
            Self::Scenario { plant, controller } => write!(
                f,
                "scenario mismatch: the plant's scenario hash is {plant:#018x}, the controller's {controller:#018x} \
                 (give both roles the same scenario flags, or send 0 to skip the check)"
            ),
            Self::Period { dt } => write!(
                f,
                "the controller does not admit the plant's dt = {dt} s (it must be positive, finite and at most \
                 the law's max_time_step)"
            ),
            Self::Space { plant, controller } => write!(
                f,
                "target space mismatch: the plant's target is {}, the controller's arm tracks a {} one",
                target::space::describe(*plant),
                target::space::describe(*controller)
            ),
            Self::Arm { plant, controller } => write!(
                f,
                "arm mismatch: the plant's arm is {}, the controller is built for {} (arm hashes differ; \
                 send 0 to skip the check)",
                canonical::describe_arm(*plant),
                canonical::describe_arm(*controller)
            ),
        }
    }
}

impl core::error::Error for Refusal {}

/// What the controller is and checks a plant against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerIdentity {
    /// Its [`platform`] code.
    pub platform: u32,
    /// Its joint count.
    pub joint_count: u32,
    /// Its target's [`target::space`] code.
    pub space: u32,
    /// Its arm's hash (0 = do not check).
    pub arm_hash: u64,
    /// Its scenario hash (0 = do not check).
    pub scenario_hash: u64,
    /// The largest `dt` its law admits (s).
    pub max_dt: f64,
}

impl ControllerIdentity {
    /// Checks the first measurement of a session: the plant's version and announcement.
    ///
    /// # Errors
    /// The first mismatch, as a [`Refusal`].
    pub fn admit(&self, m: &MeasurementMsg) -> Result<Announcement, Refusal> {
        if m.version != PROTOCOL_VERSION {
            return Err(Refusal::Version { plant: m.version });
        }
        if m.joint_count != self.joint_count {
            return Err(Refusal::JointCount { plant: m.joint_count, controller: self.joint_count });
        }
        if m.space != self.space {
            return Err(Refusal::Space { plant: m.space, controller: self.space });
        }
        if self.arm_hash != 0 && m.arm_hash != 0 && m.arm_hash != self.arm_hash {
            return Err(Refusal::Arm { plant: m.arm_hash, controller: self.arm_hash });
        }
        if m.platform != self.platform {
            return Err(Refusal::Platform { plant: m.platform, controller: self.platform });
        }
        if self.scenario_hash != 0 && m.scenario_hash != 0 && m.scenario_hash != self.scenario_hash {
            return Err(Refusal::Scenario { plant: m.scenario_hash, controller: self.scenario_hash });
        }
        if !(m.dt.is_finite() && m.dt > 0.0 && m.dt <= self.max_dt) {
            return Err(Refusal::Period { dt: m.dt });
        }
        Ok(Announcement::of(m))
    }
}

impl MeasurementMsg {
    /// A measurement of `N` joints and a planar or spatial target with the given header
    /// fields (the target converted by [`WireSpace::to_wire`]).
    ///
    /// # Panics
    /// At compile time if `N > MAX_JOINTS`.
    pub fn new<const N: usize, S: WireSpace>(header: MeasurementHeader, m: &Measurement<f64, N, S>) -> Self {
        const { assert!(N <= MAX_JOINTS) };
        let mut joints = [0.0; MAX_JOINTS];
        for (j, q) in joints.iter_mut().zip(m.joints.iter()) {
            *j = *q;
        }
        let t = S::to_wire(&m.target, &m.target_velocity);
        Self {
            version: PROTOCOL_VERSION,
            flags: header.flags,
            seq: header.seq,
            session: header.session,
            scenario_hash: header.scenario_hash,
            arm_hash: header.arm_hash,
            plant_time_ns: header.plant_time_ns,
            period_ns: header.period_ns,
            sim_time: m.t,
            dt: header.dt,
            delay: header.delay,
            platform: header.platform,
            hold_periods: header.hold_periods,
            joint_count: count_u32(N),
            space: S::CODE,
            base: [m.base.x, m.base.y, m.base.theta],
            steering: m.steering,
            target_position: t.position,
            target_rotation: t.rotation,
            target_yaw: t.yaw,
            target_twist: t.twist,
            joints,
        }
    }

    /// The target's fields.
    pub fn target(&self) -> WireTarget {
        WireTarget {
            position: self.target_position,
            rotation: self.target_rotation,
            yaw: self.target_yaw,
            twist: self.target_twist,
        }
    }

    /// The measurement for a controller of `N` joints tracking a target in `S`.
    ///
    /// # Errors
    /// [`WireError::JointCount`] if `joint_count` is not `N`, [`WireError::Changed`] if
    /// `space` is not `S`'s, or the target's [`WireSpace::from_wire`] error.
    pub fn read<const N: usize, S: WireSpace>(&self) -> Result<Measurement<f64, N, S>, WireError> {
        if self.joint_count != count_u32(N) {
            return Err(WireError::JointCount(self.joint_count));
        }
        if self.space != S::CODE {
            return Err(WireError::Changed);
        }
        let (target, target_velocity) = S::from_wire(&self.target())?;
        Ok(Measurement {
            t: self.sim_time,
            base: Pose::new(self.base[0], self.base[1], self.base[2]),
            steering: self.steering,
            joints: SVector::<f64, N>::from_fn(|i, _| self.joints[i]),
            target,
            target_velocity,
        })
    }

    /// The measurement for a controller of `N` joints and a planar target (`None` if the
    /// message does not give one: [`read`](Self::read)).
    pub fn measurement<const N: usize>(&self) -> Option<Measurement<f64, N>> {
        self.read::<N, Planar>().ok()
    }

    /// Whether a flag bit is set.
    pub fn has(&self, flag: u32) -> bool {
        self.flags & flag != 0
    }

    /// The message as bytes, little-endian, in the documented layout (the in-memory
    /// layout: no padding, checked by `zerocopy` at compile time).
    pub fn to_bytes(&self) -> [u8; MEASUREMENT_SIZE] {
        zerocopy::transmute!(*self)
    }

    /// The inverse of [`MeasurementMsg::to_bytes`].
    pub fn from_bytes(b: &[u8; MEASUREMENT_SIZE]) -> Self {
        zerocopy::transmute!(*b)
    }
}

/// The header fields of a measurement besides the measured values.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MeasurementHeader {
    /// Period number.
    pub seq: u64,
    /// [`flags`] bits.
    pub flags: u32,
    /// Session id.
    pub session: u64,
    /// Scenario hash.
    pub scenario_hash: u64,
    /// Arm hash.
    pub arm_hash: u64,
    /// Measurement time (ns).
    pub plant_time_ns: u64,
    /// Period (ns), 0 in lockstep.
    pub period_ns: u64,
    /// Hold (s).
    pub dt: f64,
    /// Expected delay of the answer (s).
    pub delay: f64,
    /// [`platform`] code.
    pub platform: u32,
    /// Hold limit (periods).
    pub hold_periods: u32,
}

/// What the law logged for one step (carried back for the plant's `timeseries.csv`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoggedDiagnostics {
    /// `‖e_p‖`.
    pub ep_norm: f64,
    /// `h_s`.
    pub h_s: f64,
    /// `Ψ`.
    pub psi: f64,
    /// Saturation factor.
    pub saturation: f64,
    /// `α̇`.
    pub alpha_rate: [f64; 2],
    /// The joint guard's factor.
    pub joint_scale: f64,
}

impl LoggedDiagnostics {
    /// No diagnostics (a refusal).
    pub const NONE: Self = Self {
        ep_norm: f64::NAN,
        h_s: f64::NAN,
        psi: f64::NAN,
        saturation: f64::NAN,
        alpha_rate: [f64::NAN; 2],
        joint_scale: f64::NAN,
    };

    /// The diagnostics of a step that found nothing to do (benchmarks and tests of the
    /// transport): no error, no saturation, the joint guard idle.
    pub const IDLE: Self =
        Self { ep_norm: 0.0, h_s: 0.0, psi: 1.0, saturation: 1.0, alpha_rate: [0.0; 2], joint_scale: 1.0 };
}

/// The header fields of a command besides the ids copied from the measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandHeader {
    /// The controller's identity.
    pub identity: ControllerIdentity,
    /// [`flags::NOTIFIES`] or 0.
    pub flags: u32,
    /// Receipt of the measurement (ns, controller's clock).
    pub received_ns: u64,
    /// Skipped measurements since the previous answer.
    pub skipped: u32,
    /// The delay the law predicted over (s).
    pub delay: f64,
}

impl CommandMsg {
    /// The answer to `meas`: a command of `N` joints, its status and diagnostics, and timing.
    ///
    /// # Panics
    /// At compile time if `N > MAX_JOINTS`.
    pub fn answer<const N: usize>(
        meas: &MeasurementMsg,
        header: &CommandHeader,
        command: &Command<f64, N>,
        error: Option<StepError>,
        diag: &LoggedDiagnostics,
    ) -> Self {
        const { assert!(N <= MAX_JOINTS) };
        let mut joints = [0.0; MAX_JOINTS];
        for (j, u) in joints.iter_mut().zip(command.joints.iter()) {
            *j = *u;
        }
        let p = &command.platform;
        Self {
            version: PROTOCOL_VERSION,
            status: encode_status(error),
            seq: meas.seq,
            session: meas.session,
            plant_time_ns: meas.plant_time_ns,
            compute_ns: 0,
            received_ns: header.received_ns,
            skipped: header.skipped,
            joint_count: count_u32(N),
            flags: header.flags,
            platform: header.identity.platform,
            scenario_hash: header.identity.scenario_hash,
            arm_hash: header.identity.arm_hash,
            space: header.identity.space,
            reserved: 0,
            delay: header.delay,
            v: p.v,
            v_lat: p.v_lat,
            omega: p.omega,
            v_xi: p.v_xi,
            joints,
            ep_norm: diag.ep_norm,
            h_s: diag.h_s,
            psi: diag.psi,
            saturation: diag.saturation,
            alpha_rate: diag.alpha_rate,
            joint_scale: diag.joint_scale,
        }
    }

    /// The refusal of `meas`: every velocity zero, `status` the refusal's code.
    pub fn refusal<const N: usize>(meas: &MeasurementMsg, header: &CommandHeader, why: &Refusal) -> Self {
        let zero = Command::<f64, N>::zero();
        Self { status: why.code(), ..Self::answer(meas, header, &zero, None, &LoggedDiagnostics::NONE) }
    }

    /// The command for `N` joints (call after [`check_command`]).
    pub fn command<const N: usize>(&self) -> Command<f64, N> {
        Command {
            platform: PlatformCommand { v: self.v, v_lat: self.v_lat, omega: self.omega, v_xi: self.v_xi },
            joints: SVector::<f64, N>::from_fn(|i, _| if i < MAX_JOINTS { self.joints[i] } else { 0.0 }),
        }
    }

    /// The logged diagnostics.
    pub fn diagnostics(&self) -> LoggedDiagnostics {
        LoggedDiagnostics {
            ep_norm: self.ep_norm,
            h_s: self.h_s,
            psi: self.psi,
            saturation: self.saturation,
            alpha_rate: self.alpha_rate,
            joint_scale: self.joint_scale,
        }
    }

    /// Whether a flag bit is set.
    pub fn has(&self, flag: u32) -> bool {
        self.flags & flag != 0
    }

    /// The message as bytes, little-endian, in the documented layout.
    pub fn to_bytes(&self) -> [u8; COMMAND_SIZE] {
        zerocopy::transmute!(*self)
    }

    /// The inverse of [`CommandMsg::to_bytes`].
    pub fn from_bytes(b: &[u8; COMMAND_SIZE]) -> Self {
        zerocopy::transmute!(*b)
    }
}

/// Checks a command against the measurement the plant is waiting for: the plant-side
/// validation. `Ok` means it may be applied; [`WireError::Refused`] ends the run;
/// [`WireError::Stale`] is a late answer to an earlier period; every other error is a
/// malformed message.
///
/// # Errors
/// Why the command must be dropped (or the run ended).
pub fn check_command<const N: usize>(
    msg: &CommandMsg,
    session: u64,
    expected_seq: u64,
) -> Result<(), WireError> {
    if msg.version != PROTOCOL_VERSION {
        return Err(WireError::Version(msg.version));
    }
    if msg.session != session {
        return Err(WireError::Session);
    }
    if refusal::is_refusal(msg.status) {
        return Err(WireError::Refused(msg.status));
    }
    if msg.seq < expected_seq {
        return Err(WireError::Stale(msg.seq));
    }
    if msg.seq > expected_seq {
        return Err(WireError::Future(msg.seq));
    }
    if msg.joint_count != count_u32(N) {
        return Err(WireError::JointCount(msg.joint_count));
    }
    decode_status(msg.status)?;
    let finite = msg.v.is_finite()
        && msg.v_lat.is_finite()
        && msg.omega.is_finite()
        && msg.v_xi.is_finite()
        && msg.joints[..N].iter().all(|x| x.is_finite());
    if !finite {
        return Err(WireError::NonFinite);
    }
    Ok(())
}

/// Checks a measurement of a running session on the controller side: version, session,
/// the announcement (as the session's first measurement made it) and order (`last_seq`:
/// the newest one answered or skipped). The session's first measurement is checked by
/// [`ControllerIdentity::admit`] instead.
///
/// # Errors
/// Why the measurement must be dropped.
pub fn check_measurement(
    msg: &MeasurementMsg,
    session: u64,
    announced: &Announcement,
    last_seq: Option<u64>,
) -> Result<(), WireError> {
    if msg.version != PROTOCOL_VERSION {
        return Err(WireError::Version(msg.version));
    }
    if msg.session != session {
        return Err(WireError::Session);
    }
    if msg.joint_count != announced.joint_count {
        return Err(WireError::JointCount(msg.joint_count));
    }
    if !Announcement::of(msg).same_as(announced) {
        return Err(WireError::Changed);
    }
    if last_seq.is_some_and(|l| msg.seq <= l) {
        return Err(WireError::Stale(msg.seq));
    }
    Ok(())
}

#[cfg(test)]
mod tests;
