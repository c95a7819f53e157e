//! Fault injection for tests: a [`Link`] decorator that sends corrupted copies of the
//! controller's commands before the real ones, to check the plant's validation end to end.
//! The production loop knows nothing of it; `companion control --inject` (hidden, for the
//! HIL tests) wraps its transport in it.

use std::time::Duration;

use anyhow::Result;

use crate::link::{Link, PeerState};
use crate::wire::CommandMsg;

/// A corrupted command to send.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Corruption {
    /// Another protocol version.
    Version,
    /// A NaN forward speed.
    Nan,
    /// A sequence number from the future.
    Seq,
    /// Another session.
    Session,
}

impl Corruption {
    /// `c` corrupted this way.
    pub fn apply(self, c: &CommandMsg) -> CommandMsg {
        match self {
            Self::Version => CommandMsg { version: c.version + 1, ..*c },
            Self::Nan => CommandMsg { v: f64::NAN, ..*c },
            Self::Seq => CommandMsg { seq: c.seq + 1_000_000, ..*c },
            Self::Session => CommandMsg { session: c.session ^ 0x5a5a, ..*c },
        }
    }
}

/// A controller link that sends each planned corruption once, just before the answer to the
/// first measurement whose sequence number is at least the planned one (in real time a
/// measurement can be skipped as superseded, so an exact match could never come).
#[derive(Debug)]
pub struct Injecting<L> {
    inner: L,
    plan: Vec<(u64, Corruption)>,
    next: usize,
}

impl<L> Injecting<L> {
    /// Wraps `inner`; `plan` lists `(sequence number, corruption)` in any order.
    pub fn new(inner: L, mut plan: Vec<(u64, Corruption)>) -> Self {
        plan.sort_by_key(|x| x.0);
        Self { inner, plan, next: 0 }
    }

    /// The wrapped link.
    pub fn into_inner(self) -> L {
        self.inner
    }
}

impl<L: Link<Tx = CommandMsg>> Link for Injecting<L> {
    type Tx = CommandMsg;
    type Rx = L::Rx;

    fn publish(&mut self, msg: &CommandMsg) -> Result<()> {
        while let Some(&(at, kind)) = self.plan.get(self.next) {
            if at > msg.seq {
                break;
            }
            self.inner.publish(&kind.apply(msg))?;
            self.next += 1;
        }
        self.inner.publish(msg)
    }

    fn try_receive(&mut self) -> Result<Option<L::Rx>> {
        self.inner.try_receive()
    }

    fn wait_event(&mut self, timeout: Duration) -> Result<()> {
        self.inner.wait_event(timeout)
    }

    fn peer_state(&mut self) -> Result<PeerState> {
        self.inner.peer_state()
    }
}
