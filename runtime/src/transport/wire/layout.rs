//! The two messages' layout: their `#[repr(C)]` types, sizes, flags, platform codes and
//! iceoryx2 type names (the module docs of [`super`] give the byte tables).

use iceoryx2::prelude::ZeroCopySend;
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

/// The bits of a command's `limits`: which of the law's acceleration limits acted on it
/// (`companion_core::acceleration`). The field was `reserved` (0) before: an earlier
/// controller writes 0, and a plant that does not read it loses nothing.
pub mod limits {
    /// The change of the platform's command was divided by the acceleration factor.
    pub const PLATFORM_ACCELERATION: u32 = 1;
    /// The change of the joints' command was.
    pub const JOINT_ACCELERATION: u32 = 2;
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
    /// [`canonical::scenario_hash`](super::canonical::scenario_hash) of the controller's scenario; 0 = not checked.
    pub scenario_hash: u64,
    /// [`canonical::arm_hash`](super::canonical::arm_hash) of the plant's arm; 0 = not checked.
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
    /// The target's [`target::space`](super::target::space) code.
    pub space: u32,
    /// Platform pose `r_b = (x, y, θ)` (m, m, rad).
    pub base: [f64; 3],
    /// Car-like steering `ξ` (1/m); 0 otherwise.
    pub steering: f64,
    /// Target origin `p_d = (x, y, z)` (m), fixed frame.
    pub target_position: [f64; 3],
    /// Target rotation `R_d`, row by row.
    pub target_rotation: [f64; 9],
    /// Target yaw `ψ` (rad): the exact `θ` of a planar target ([`target`](super::target)).
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
    /// 0 = ok, else [`encode_status`](super::encode_status) of the law's rejection, or a [`Refusal`](super::Refusal) code.
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
    /// The controller's [`target::space`](super::target::space) code.
    pub space: u32,
    /// [`limits`] bits: which acceleration limits acted (0: none, and a rejection).
    pub limits: u32,
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

/// A joint count as the wire carries it (`N ≤ MAX_JOINTS`, so it fits).
pub(super) const fn count_u32(n: usize) -> u32 {
    n as u32
}
