//! The rules that decide whether a message is used: a command on the plant's side, a
//! measurement of a running session on the controller's.

use super::handshake::{refusal, Announcement};
use super::layout::{count_u32, CommandMsg, MeasurementMsg, PROTOCOL_VERSION};
use super::status::{decode_status, WireError};

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
/// [`ControllerIdentity::admit`](super::ControllerIdentity::admit) instead.
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
