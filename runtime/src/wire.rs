//! The two messages of the HIL loop — the interface a bridge to real hardware implements.
//!
//! Every control period the plant publishes one [`MeasurementMsg`] and the controller answers
//! it with one [`CommandMsg`]. Both are `#[repr(C)]`, fixed size, made only of `u32`, `u64`
//! and `f64` fields laid out without padding, and travel by iceoryx2 publish–subscribe in
//! shared memory (zero copy: the bytes below *are* the message). A bridge written in another
//! language opens the same services (see [`crate::ipc`] for their names and settings) with a
//! struct of the same layout and the same iceoryx2 type name ([`MEASUREMENT_TYPE_NAME`],
//! [`COMMAND_TYPE_NAME`]); a bridge over another transport sends the same bytes
//! ([`MeasurementMsg::to_bytes`], little-endian).
//!
//! ## Rules of the exchange
//!
//! - The plant owns time. It numbers measurements `seq = 0, 1, 2, …` (one per period, never
//!   reused within a session) and stamps them with `plant_time_ns`, its `CLOCK_MONOTONIC` at
//!   publication.
//! - The controller answers measurement `seq` with a command carrying the same `seq`, the same
//!   `session`, and `plant_time_ns` copied unchanged, so that the plant measures the round trip
//!   on its own clock. If several measurements are waiting it answers only the newest one and
//!   reports how many it skipped (`skipped`).
//! - A command is applied only if it answers the measurement of the current period (same
//!   `session`, same `seq`), has this `version`, the expected `joint_count`, a known `status`
//!   and finite velocities; anything else is counted and dropped, never applied
//!   ([`check_command`]). A command for an earlier period (it arrived after its deadline) is
//!   counted as late and dropped.
//! - A measurement is used only if it has this `version` and `joint_count`, comes from the
//!   session the controller is serving, and is newer than the last one ([`check_measurement`]).
//!   Non-finite *values* in a well-formed measurement are the control law's business: it
//!   answers them with a typed error and the safe command (all velocities zero), reported in
//!   `status`.
//! - `flags` of the measurement: [`flags::END_OF_RUN`] on the last one (the controller answers
//!   it, then exits), [`flags::LOCKSTEP`] when the plant waits for every command (no period),
//!   [`flags::STOPPED`] while the plant has stopped the robot because commands were missing.
//!
//! ## Joints
//!
//! Both messages have room for [`MAX_JOINTS`] = 8 joints and a `joint_count` saying how many
//! are used (the rest are zero). The paper's arm has 3; a bridge for another arm keeps the
//! layout and the protocol version, and a controller built for `N` joints rejects messages
//! whose `joint_count` is not `N`.
//!
//! ## Units
//!
//! SI throughout: metres, radians, seconds; velocities in m/s and rad/s; the car's steering
//! state `ξ = tan φ / ℓ` in 1/m and its rate `v_ξ` in 1/(m·s). Poses are `(x, y, θ)` in the
//! fixed frame; the target velocity is the *body* velocity `u_d` (`ṙ_d = R̄(θ_d) u_d`).
//!
//! ## Layout of [`MeasurementMsg`] (216 bytes)
//!
//! ```text
//! offset type      field            meaning
//!      0 u32       version          PROTOCOL_VERSION (1)
//!      4 u32       flags            END_OF_RUN = 1, LOCKSTEP = 2, STOPPED = 4
//!      8 u64       seq              period number, from 0
//!     16 u64       session          random id of this plant run, echoed by the controller
//!     24 u64       scenario_hash    FNV-1a of the scenario (a controller built for another
//!                                   scenario refuses to run); 0 = not checked
//!     32 u64       plant_time_ns    CLOCK_MONOTONIC at publication (ns), echoed
//!     40 u64       period_ns        the control period in real-time mode; 0 in lockstep
//!     48 f64       sim_time         simulated time t (s)
//!     56 f64       dt               the step the controller integrates over per period (s)
//!     64 f64[3]    base             platform pose r_b = (x, y, θ)
//!     88 f64       steering         car-like steering ξ (1/m); 0 otherwise
//!     96 f64[3]    target           target pose r_d = (x, y, θ)
//!    120 f64[3]    target_velocity  target body velocity u_d (m/s, m/s, rad/s)
//!    144 u32       joint_count      joints used (3 for the paper's arm)
//!    148 u32       reserved         0
//!    152 f64[8]    joints           joint positions q (rad or m)
//! ```
//!
//! ## Layout of [`CommandMsg`] (200 bytes)
//!
//! ```text
//! offset type      field            meaning
//!      0 u32       version          PROTOCOL_VERSION (1)
//!      4 u32       status           0 = ok; else the law's rejection reason (see below)
//!      8 u64       seq              the measurement this answers
//!     16 u64       session          copied from the measurement
//!     24 u64       plant_time_ns    copied from the measurement
//!     32 u64       compute_ns       controller time from receiving the measurement to
//!                                   publishing this command (ns)
//!     40 u64       received_ns      controller's CLOCK_MONOTONIC when the measurement arrived
//!     48 u32       skipped          newer-measurement skips since the previous answer
//!     52 u32       joint_count      joints used
//!     56 f64       v                forward speed (m/s)
//!     64 f64       v_lat            lateral speed (m/s), omnidirectional platform
//!     72 f64       omega            angular speed (rad/s)
//!     80 f64       v_xi             steering rate (1/(m·s)), car-like platform
//!     88 f64[8]    joints           joint velocities u_q (rad/s or m/s)
//!    152 f64       ep_norm          ‖e_p‖ (logged; NaN when rejected)
//!    160 f64       h_s              h_s (logged; NaN when rejected)
//!    168 f64       psi              Ψ (logged; NaN when rejected)
//!    176 f64       saturation       common saturation factor ≥ 1 (logged; NaN when rejected)
//!    184 f64[2]    alpha_rate       α̇ (logged; NaN when rejected)
//! ```
//!
//! `status` codes (the law answered with the safe command, all velocities zero):
//! `0x100 + f` a non-finite measured field `f` (0 time, 1 base pose, 2 steering, 3 joints,
//! 4 target pose, 5 target velocity); `0x200` bad time step; `0x300 + j` joint `j` (from 0)
//! at or beyond its limit; `0x400` singular arm; `0x500` singular task Jacobian; `0x600`
//! numerical failure.

use companion_core::nalgebra::{SVector, Vector3};
use companion_core::{Command, Field, Measurement, PlatformCommand, Pose, StepError};
use iceoryx2::prelude::ZeroCopySend;
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout};

/// The protocol version both messages carry. Changed whenever the layout or meaning changes.
pub const PROTOCOL_VERSION: u32 = 1;

/// Room for joints in both messages.
pub const MAX_JOINTS: usize = 8;

/// The iceoryx2 type name of [`MeasurementMsg`] (what a bridge in another language declares).
pub const MEASUREMENT_TYPE_NAME: &str = "companion::MeasurementV1";
/// The iceoryx2 type name of [`CommandMsg`].
pub const COMMAND_TYPE_NAME: &str = "companion::CommandV1";

/// Bits of [`MeasurementMsg::flags`].
pub mod flags {
    /// The last measurement of the run: answer it, then exit.
    pub const END_OF_RUN: u32 = 1;
    /// Lockstep mode: the plant waits for every command (no period, no deadline).
    pub const LOCKSTEP: u32 = 2;
    /// The plant has stopped the robot (commands missed too many deadlines).
    pub const STOPPED: u32 = 4;
}

// The derives below generate `unsafe impl`s (`ZeroCopySend`; zerocopy's byte conversions,
// which zerocopy checks at compile time: `#[repr(C)]`, numbers and arrays of numbers only, no
// padding), hence the allow.
/// One measurement of the plant, published once per period. See the module docs for the
/// layout and the rules.
#[allow(unsafe_code)]
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend, IntoBytes, FromBytes, Immutable, KnownLayout)]
#[type_name("companion::MeasurementV1")]
#[repr(C)]
pub struct MeasurementMsg {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// [`flags`] bits.
    pub flags: u32,
    /// Period number, from 0.
    pub seq: u64,
    /// Random id of this plant run.
    pub session: u64,
    /// FNV-1a hash of the scenario; 0 = not checked.
    pub scenario_hash: u64,
    /// The plant's `CLOCK_MONOTONIC` at publication (ns).
    pub plant_time_ns: u64,
    /// The control period (ns); 0 in lockstep.
    pub period_ns: u64,
    /// Simulated time `t` (s).
    pub sim_time: f64,
    /// The step the controller integrates over per period (s).
    pub dt: f64,
    /// Platform pose `r_b = (x, y, θ)` (m, m, rad).
    pub base: [f64; 3],
    /// Car-like steering `ξ` (1/m); 0 otherwise.
    pub steering: f64,
    /// Target pose `r_d` (m, m, rad).
    pub target: [f64; 3],
    /// Target body velocity `u_d` (m/s, m/s, rad/s).
    pub target_velocity: [f64; 3],
    /// Joints used.
    pub joint_count: u32,
    /// Zero.
    pub reserved: u32,
    /// Joint positions `q` (rad or m); entries past `joint_count` are zero.
    pub joints: [f64; MAX_JOINTS],
}

/// One command of the controller, answering one measurement. See the module docs.
#[allow(unsafe_code)]
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend, IntoBytes, FromBytes, Immutable, KnownLayout)]
#[type_name("companion::CommandV1")]
#[repr(C)]
pub struct CommandMsg {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// 0 = ok, else [`encode_status`] of the law's rejection.
    pub status: u32,
    /// The measurement this answers.
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
    /// Joints used.
    pub joint_count: u32,
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
}

/// The size of [`MeasurementMsg`] in bytes.
pub const MEASUREMENT_SIZE: usize = 216;
/// The size of [`CommandMsg`] in bytes.
pub const COMMAND_SIZE: usize = 200;

const _: () = assert!(core::mem::size_of::<MeasurementMsg>() == MEASUREMENT_SIZE);
const _: () = assert!(core::mem::size_of::<CommandMsg>() == COMMAND_SIZE);
// The wire is little-endian and the bytes are the in-memory layout.
const _: () = assert!(cfg!(target_endian = "little"), "the wire format is little-endian");

/// Why a message was dropped.
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
    /// A `joint_count` other than the controller's.
    JointCount(u32),
    /// An unknown `status` code.
    Status(u32),
    /// A non-finite velocity.
    NonFinite,
    /// A controller built for another scenario.
    Scenario,
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
            Self::Scenario => f.write_str("scenario mismatch"),
        }
    }
}

impl core::error::Error for WireError {}

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
            Self::Scenario => "scenario",
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
        #[allow(clippy::cast_possible_truncation)]
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

#[allow(clippy::cast_possible_truncation)]
const fn count_u32(n: usize) -> u32 {
    n as u32
}

impl MeasurementMsg {
    /// A measurement of `N` joints with the given header fields.
    ///
    /// # Panics
    /// At compile time if `N > MAX_JOINTS`.
    pub fn new<const N: usize>(header: MeasurementHeader, m: &Measurement<f64, N>) -> Self {
        const { assert!(N <= MAX_JOINTS) };
        let mut joints = [0.0; MAX_JOINTS];
        for (j, q) in joints.iter_mut().zip(m.joints.iter()) {
            *j = *q;
        }
        Self {
            version: PROTOCOL_VERSION,
            flags: header.flags,
            seq: header.seq,
            session: header.session,
            scenario_hash: header.scenario_hash,
            plant_time_ns: header.plant_time_ns,
            period_ns: header.period_ns,
            sim_time: m.t,
            dt: header.dt,
            base: [m.base.x, m.base.y, m.base.theta],
            steering: m.steering,
            target: [m.target.x, m.target.y, m.target.theta],
            target_velocity: [m.target_velocity[0], m.target_velocity[1], m.target_velocity[2]],
            joint_count: count_u32(N),
            reserved: 0,
            joints,
        }
    }

    /// The measurement for a controller of `N` joints (`None` if `joint_count` is not `N`).
    pub fn measurement<const N: usize>(&self) -> Option<Measurement<f64, N>> {
        if self.joint_count != count_u32(N) {
            return None;
        }
        Some(Measurement {
            t: self.sim_time,
            base: Pose::new(self.base[0], self.base[1], self.base[2]),
            steering: self.steering,
            joints: SVector::<f64, N>::from_fn(|i, _| self.joints[i]),
            target: Pose::new(self.target[0], self.target[1], self.target[2]),
            target_velocity: Vector3::new(
                self.target_velocity[0],
                self.target_velocity[1],
                self.target_velocity[2],
            ),
        })
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
    /// Publication time (ns).
    pub plant_time_ns: u64,
    /// Period (ns), 0 in lockstep.
    pub period_ns: u64,
    /// Step (s).
    pub dt: f64,
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
}

impl CommandMsg {
    /// The answer to `meas`: a command of `N` joints, its status and diagnostics, and timing.
    ///
    /// # Panics
    /// At compile time if `N > MAX_JOINTS`.
    pub fn answer<const N: usize>(
        meas: &MeasurementMsg,
        command: &Command<f64, N>,
        error: Option<StepError>,
        diag: &LoggedDiagnostics,
        received_ns: u64,
        skipped: u32,
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
            received_ns,
            skipped,
            joint_count: count_u32(N),
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
        }
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
        }
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
/// validation. `Ok` means it may be applied; [`WireError::Stale`] is a late answer to an
/// earlier period; every other error is a malformed message.
///
/// # Errors
/// Why the command must be dropped.
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

/// Checks a measurement on the controller side: version, joint count, session (`None` = the
/// first one, any session accepted), scenario (0 on either side = not checked) and order
/// (`last_seq`: the newest one answered or skipped).
///
/// # Errors
/// Why the measurement must be dropped.
pub fn check_measurement<const N: usize>(
    msg: &MeasurementMsg,
    session: Option<u64>,
    last_seq: Option<u64>,
    scenario_hash: u64,
) -> Result<(), WireError> {
    if msg.version != PROTOCOL_VERSION {
        return Err(WireError::Version(msg.version));
    }
    if msg.joint_count != count_u32(N) {
        return Err(WireError::JointCount(msg.joint_count));
    }
    if session.is_some_and(|s| s != msg.session) {
        return Err(WireError::Session);
    }
    if scenario_hash != 0 && msg.scenario_hash != 0 && msg.scenario_hash != scenario_hash {
        return Err(WireError::Scenario);
    }
    if last_seq.is_some_and(|l| msg.seq <= l) {
        return Err(WireError::Stale(msg.seq));
    }
    Ok(())
}

/// FNV-1a, 64 bits (for the scenario hash).
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

#[cfg(test)]
mod tests {
    use core::mem::offset_of;

    use super::*;

    fn meas() -> Measurement<f64, 3> {
        Measurement {
            t: 1.5,
            base: Pose::new(0.1, -0.2, 0.3),
            steering: 0.0,
            joints: SVector::<f64, 3>::new(0.1, 0.35, -0.2),
            target: Pose::new(2.6, 1.0, 0.0),
            target_velocity: Vector3::new(0.0, -0.157, 0.0),
        }
    }

    fn header() -> MeasurementHeader {
        MeasurementHeader {
            seq: 7,
            flags: flags::LOCKSTEP,
            session: 42,
            scenario_hash: 9,
            plant_time_ns: 123_456,
            period_ns: 1_000_000,
            dt: 1e-3,
        }
    }

    fn good_command() -> CommandMsg {
        let m = MeasurementMsg::new(header(), &meas());
        let diag =
            LoggedDiagnostics { ep_norm: 0.5, h_s: 0.1, psi: 1.0, saturation: 1.0, alpha_rate: [0.2, 0.0] };
        let mut cmd = Command::<f64, 3>::zero();
        cmd.platform.v = 0.3;
        cmd.platform.omega = -0.1;
        cmd.joints[1] = 0.05;
        CommandMsg::answer(&m, &cmd, None, &diag, 200_000, 0)
    }

    #[test]
    fn documented_offsets_hold() {
        assert_eq!(offset_of!(MeasurementMsg, seq), 8);
        assert_eq!(offset_of!(MeasurementMsg, plant_time_ns), 32);
        assert_eq!(offset_of!(MeasurementMsg, sim_time), 48);
        assert_eq!(offset_of!(MeasurementMsg, base), 64);
        assert_eq!(offset_of!(MeasurementMsg, steering), 88);
        assert_eq!(offset_of!(MeasurementMsg, target), 96);
        assert_eq!(offset_of!(MeasurementMsg, target_velocity), 120);
        assert_eq!(offset_of!(MeasurementMsg, joint_count), 144);
        assert_eq!(offset_of!(MeasurementMsg, joints), 152);
        assert_eq!(offset_of!(CommandMsg, compute_ns), 32);
        assert_eq!(offset_of!(CommandMsg, skipped), 48);
        assert_eq!(offset_of!(CommandMsg, v), 56);
        assert_eq!(offset_of!(CommandMsg, joints), 88);
        assert_eq!(offset_of!(CommandMsg, ep_norm), 152);
        assert_eq!(offset_of!(CommandMsg, alpha_rate), 184);
    }

    #[test]
    fn bytes_follow_the_in_memory_layout() {
        let m = MeasurementMsg::new(header(), &meas());
        let b = m.to_bytes();
        assert_eq!(MeasurementMsg::from_bytes(&b), m);
        assert_eq!(&b[8..16], &7u64.to_le_bytes());
        assert_eq!(&b[152 + 8..152 + 16], &0.35f64.to_le_bytes());
        let c = good_command();
        let b = c.to_bytes();
        assert_eq!(CommandMsg::from_bytes(&b), c);
        assert_eq!(&b[56..64], &0.3f64.to_le_bytes());
        assert_eq!(&b[88 + 8..88 + 16], &0.05f64.to_le_bytes());
    }

    #[test]
    fn measurement_round_trips() {
        let m = meas();
        let msg = MeasurementMsg::new(header(), &m);
        assert_eq!(msg.joint_count, 3);
        assert_eq!(msg.measurement::<3>(), Some(m));
        assert_eq!(msg.measurement::<2>(), None);
        assert!(msg.has(flags::LOCKSTEP) && !msg.has(flags::END_OF_RUN));
    }

    #[test]
    fn every_step_error_round_trips_through_status() {
        let mut all = vec![
            None,
            Some(StepError::BadTimeStep),
            Some(StepError::SingularArm),
            Some(StepError::SingularTaskJacobian),
            Some(StepError::NumericalFailure),
            Some(StepError::BadDelay),
            Some(StepError::TargetYawUndefined),
        ];
        for f in [
            Field::Time,
            Field::BasePose,
            Field::Steering,
            Field::Joints,
            Field::TargetPose,
            Field::TargetVelocity,
        ] {
            all.push(Some(StepError::NonFinite(f)));
        }
        for j in 0..3 {
            all.push(Some(StepError::JointAtLimit(j)));
        }
        for e in all {
            assert_eq!(decode_status(encode_status(e)), Ok(e));
        }
        assert_eq!(decode_status(0x106), Err(WireError::Status(0x106)));
        assert_eq!(decode_status(0x7), Err(WireError::Status(0x7)));
        assert_eq!(decode_status(0x300 + 8), Err(WireError::Status(0x308)));
    }

    #[test]
    fn a_good_command_passes() {
        let c = good_command();
        assert_eq!(check_command::<3>(&c, 42, 7), Ok(()));
        assert_eq!(c.command::<3>().platform.v, 0.3);
    }

    #[test]
    fn malformed_commands_are_rejected_with_their_reason() {
        let c = good_command();
        assert_eq!(check_command::<3>(&CommandMsg { version: 2, ..c }, 42, 7), Err(WireError::Version(2)));
        assert_eq!(check_command::<3>(&c, 43, 7), Err(WireError::Session));
        assert_eq!(check_command::<3>(&c, 42, 8), Err(WireError::Stale(7)));
        assert_eq!(check_command::<3>(&c, 42, 6), Err(WireError::Future(7)));
        assert_eq!(
            check_command::<3>(&CommandMsg { joint_count: 4, ..c }, 42, 7),
            Err(WireError::JointCount(4))
        );
        assert_eq!(
            check_command::<3>(&CommandMsg { status: 0x999, ..c }, 42, 7),
            Err(WireError::Status(0x999))
        );
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(check_command::<3>(&CommandMsg { v: bad, ..c }, 42, 7), Err(WireError::NonFinite));
            assert_eq!(check_command::<3>(&CommandMsg { omega: bad, ..c }, 42, 7), Err(WireError::NonFinite));
            assert_eq!(check_command::<3>(&CommandMsg { v_lat: bad, ..c }, 42, 7), Err(WireError::NonFinite));
            assert_eq!(check_command::<3>(&CommandMsg { v_xi: bad, ..c }, 42, 7), Err(WireError::NonFinite));
            let mut joints = c.joints;
            joints[2] = bad;
            assert_eq!(check_command::<3>(&CommandMsg { joints, ..c }, 42, 7), Err(WireError::NonFinite));
        }
        // NaN diagnostics (a rejected step) are not velocities: accepted.
        let rejected = CommandMsg { status: 0x400, ep_norm: f64::NAN, h_s: f64::NAN, ..c };
        assert_eq!(check_command::<3>(&rejected, 42, 7), Ok(()));
        // Unused joint slots are not checked.
        let mut joints = c.joints;
        joints[5] = f64::NAN;
        assert_eq!(check_command::<3>(&CommandMsg { joints, ..c }, 42, 7), Ok(()));
    }

    #[test]
    fn measurements_are_checked_for_order_session_and_shape() {
        let m = MeasurementMsg::new(header(), &meas());
        assert_eq!(check_measurement::<3>(&m, None, None, 0), Ok(()));
        assert_eq!(check_measurement::<3>(&m, Some(42), Some(6), 9), Ok(()));
        assert_eq!(check_measurement::<3>(&m, Some(42), Some(7), 9), Err(WireError::Stale(7)));
        assert_eq!(check_measurement::<3>(&m, Some(41), None, 9), Err(WireError::Session));
        assert_eq!(check_measurement::<3>(&m, None, None, 10), Err(WireError::Scenario));
        assert_eq!(check_measurement::<2>(&m, None, None, 0), Err(WireError::JointCount(3)));
        assert_eq!(
            check_measurement::<3>(&MeasurementMsg { version: 0, ..m }, None, None, 0),
            Err(WireError::Version(0))
        );
    }

    #[test]
    fn fnv1a_matches_reference_values() {
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
    }
}
