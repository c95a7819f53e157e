//! The two messages of the HIL loop — the interface a bridge to real hardware implements —
//! and the rules that decide whether a message is used.
//!
//! The complete protocol (services and their settings, start-up, events, silence, end of
//! run, versioning) is `docs/book/src/bridge.md` in the repository: a bridge author needs nothing
//! else. This module is its implementation; a test checks the layouts below against the
//! document's. Its parts, each a file (their items are re-exported here, one path each):
//! `layout` (the two `#[repr(C)]` types, sizes, flags, platform codes, type names), `codec`
//! (the messages built from and read into the core's types), `status` ([`WireError`] and the
//! `status` codes of a step), `handshake` (the plant's [`Announcement`], the
//! [`ControllerIdentity`] it is admitted by, the [`Refusal`]s), `checks` (the rules that
//! decide whether a message is used), [`canonical`] (the scenario's and arm's hashes) and
//! [`target`] (the target in SE(3)).
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
mod checks;
mod codec;
mod handshake;
mod layout;
mod status;
pub mod target;

pub use canonical::fnv1a;
pub use checks::{check_command, check_measurement};
pub use codec::{CommandHeader, LoggedDiagnostics, MeasurementHeader};
pub use handshake::{refusal, Announcement, ControllerIdentity, Refusal};
pub use layout::{
    flags, platform, CommandMsg, MeasurementMsg, WireMessage, COMMAND_SIZE, COMMAND_TYPE_NAME, MAX_JOINTS,
    MEASUREMENT_SIZE, MEASUREMENT_TYPE_NAME, PROTOCOL_VERSION,
};
pub use status::{decode_status, encode_status, WireError};
pub use target::{TargetError, WireSpace, WireTarget};

#[cfg(test)]
mod tests;
