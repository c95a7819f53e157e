//! The transport as the loops see it: publish one message, take the next, wait for one, and
//! ask whether the peer is alive. The loops are generic over [`Link`]; the iceoryx2 endpoints
//! ([`crate::transport::ipc`]) are the production implementation, fakes in tests are others, and
//! [`crate::run::hil::fault::Injecting`] is a decorator that adds corrupted messages (for tests).

use std::time::Duration;

use crate::transport::wire::{CommandMsg, MeasurementMsg};

/// What one side's transport counted of the messages it sent and got (Zenoh; iceoryx2 has
/// no silent loss to count: its publish fails or the sample is delivered).
///
/// Zenoh drops a publication silently when its link's queue stays full (congestion control
/// *drop*, `zenoh_link::Tuning`): `put` still returns `Ok`. Such a loss
/// shows only as the sender's `published` exceeding the receiver's `received`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct LinkCounts {
    /// Messages handed to the transport, accepted by it.
    pub published: u64,
    /// Messages the transport delivered to this process (kept or dropped below).
    pub received: u64,
    /// Of those, dropped because the loop had not taken the ring before them.
    pub dropped_full_ring: u64,
    /// Of those, dropped for their size.
    pub malformed: u64,
}

impl LinkCounts {
    /// Messages `self` published that `peer` never received (lost in transit, or still on
    /// their way when `peer` counted).
    pub fn not_received_by(&self, peer: &Self) -> u64 {
        self.published.saturating_sub(peer.received)
    }
}

/// What went wrong on a [`Link`]: which of its four operations failed, the transport's step
/// (`loan`, `send`, `notify`, `zenoh put`, `receive`, `ppoll`, `try_wait`, `listing iceoryx2 nodes`)
/// and the transport's own words.
///
/// Made only when something failed: the success path of every operation neither allocates nor
/// formats (`tests/no_alloc.rs`). The cause is a string because the transports' error types
/// differ per step and per transport, and a message is all a loop does with one.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LinkError {
    /// Publishing a message failed.
    #[error("{step}: {cause}")]
    Publish {
        /// The transport's step.
        step: &'static str,
        /// The transport's words.
        cause: String,
    },
    /// Taking a message failed.
    #[error("{step}: {cause}")]
    Receive {
        /// The transport's step.
        step: &'static str,
        /// The transport's words.
        cause: String,
    },
    /// Waiting on the transport's event failed.
    #[error("{step}: {cause}")]
    Wait {
        /// The transport's step.
        step: &'static str,
        /// The transport's words.
        cause: String,
    },
    /// The peer's state cannot be read.
    #[error("{step}: {cause}")]
    PeerUnreadable {
        /// The transport's step.
        step: &'static str,
        /// The transport's words.
        cause: String,
    },
}

/// What [`Link::peer_state`] found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PeerState {
    /// The peer's node exists and its process is alive (pid).
    Alive(i32),
    /// The peer's process died without cleaning up (pid).
    Dead(i32),
    /// The peer's session ended without a closed connection (pid): its lease ran out with
    /// nothing heard (Zenoh over QUIC, where a killed process closes nothing). Dead, or
    /// unreachable across the network: the two look the same.
    Expired(i32),
    /// No node of the peer exists (it has not started, or it exited cleanly).
    Absent,
}

/// One side of a message exchange.
pub trait Link {
    /// What this side sends.
    type Tx: Copy;
    /// What this side receives.
    type Rx: Copy;

    /// Publishes a message.
    ///
    /// # Errors
    /// [`LinkError::Publish`]: a transport failure.
    fn publish(&mut self, msg: &Self::Tx) -> Result<(), LinkError>;

    /// Takes the oldest waiting message.
    ///
    /// # Errors
    /// [`LinkError::Receive`]: a transport failure.
    fn try_receive(&mut self) -> Result<Option<Self::Rx>, LinkError>;

    /// Waits on the transport's event for at most `timeout` (event mode; else returns at
    /// once).
    ///
    /// # Errors
    /// [`LinkError::Wait`]: a transport failure.
    fn wait_event(&mut self, timeout: Duration) -> Result<(), LinkError>;

    /// Whether the peer is alive (a few system calls: call it only after a silence).
    ///
    /// # Errors
    /// [`LinkError::PeerUnreadable`]: the peer's state cannot be read.
    fn peer_state(&mut self) -> Result<PeerState, LinkError>;

    /// Whether this side notifies the peer's event after each message (so that the peer may
    /// sleep on it; announced on the wire as `flags::NOTIFIES`).
    fn notifies(&self) -> bool {
        false
    }
}

/// The plant's side: sends measurements, receives commands.
pub trait PlantLink: Link<Tx = MeasurementMsg, Rx = CommandMsg> {}
impl<L: Link<Tx = MeasurementMsg, Rx = CommandMsg>> PlantLink for L {}

/// The controller's side: sends commands, receives measurements.
pub trait ControlLink: Link<Tx = CommandMsg, Rx = MeasurementMsg> {}
impl<L: Link<Tx = CommandMsg, Rx = MeasurementMsg>> ControlLink for L {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_link_error_says_the_step_and_the_transports_words() {
        let e = LinkError::Publish { step: "loan", cause: "ExceedsMaxLoans".into() };
        assert_eq!(e.to_string(), "loan: ExceedsMaxLoans");
        let e = LinkError::PeerUnreadable {
            step: "listing iceoryx2 nodes",
            cause: "InsufficientPermissions".into(),
        };
        assert_eq!(e.to_string(), "listing iceoryx2 nodes: InsufficientPermissions");
    }
}
