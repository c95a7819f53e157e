//! Fault injection for tests and `--chaos`: a [`Link`] decorator that sends corrupted copies
//! of the controller's commands before the real ones, and holds some commands back, to check
//! the plant's validation and deadline accounting end to end. The production loop knows
//! nothing of it; `companion control --inject` (hidden, for the HIL tests) and `companion hil
//! --chaos` wrap their transport in it.

use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::transport::link::{Link, LinkError, PeerState};
use crate::transport::wire::CommandMsg;

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

/// What the decorator actually did (planned faults whose measurement never came are not
/// counted).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Injected {
    /// Commands of another protocol version.
    pub version: u64,
    /// Commands with a NaN velocity.
    pub non_finite: u64,
    /// Commands with a sequence number from the future.
    pub future_seq: u64,
    /// Commands of another session.
    pub session: u64,
    /// Commands held back.
    pub delayed: u64,
}

impl Injected {
    fn count(&mut self, c: Corruption) {
        match c {
            Corruption::Version => self.version += 1,
            Corruption::Nan => self.non_finite += 1,
            Corruption::Seq => self.future_seq += 1,
            Corruption::Session => self.session += 1,
        }
    }
}

/// A controller link that sends each planned corruption once, just before the answer to the
/// first measurement whose sequence number is at least the planned one (in real time a
/// measurement can be skipped as superseded, so an exact match could never come), and holds
/// each planned answer back for its delay in the same way.
#[derive(Debug)]
pub struct Injecting<L> {
    inner: L,
    plan: Vec<(u64, Corruption)>,
    next: usize,
    delays: Vec<(u64, u64)>,
    next_delay: usize,
    done: Injected,
}

impl<L> Injecting<L> {
    /// Wraps `inner`; `plan` lists `(sequence number, corruption)` in any order.
    pub fn new(inner: L, mut plan: Vec<(u64, Corruption)>) -> Self {
        plan.sort_by_key(|x| x.0);
        Self { inner, plan, next: 0, delays: Vec::new(), next_delay: 0, done: Injected::default() }
    }

    /// Also holds answers back: `(sequence number, delay in ns)`, in any order.
    #[must_use]
    pub fn with_delays(mut self, mut delays: Vec<(u64, u64)>) -> Self {
        delays.sort_by_key(|x| x.0);
        self.delays = delays;
        self
    }

    /// What was injected so far.
    pub fn injected(&self) -> Injected {
        self.done
    }

    /// The wrapped link.
    pub fn into_inner(self) -> L {
        self.inner
    }
}

impl<L: Link<Tx = CommandMsg>> Link for Injecting<L> {
    type Tx = CommandMsg;
    type Rx = L::Rx;

    fn publish(&mut self, msg: &CommandMsg) -> Result<(), LinkError> {
        while let Some(&(at, kind)) = self.plan.get(self.next) {
            if at > msg.seq {
                break;
            }
            self.inner.publish(&kind.apply(msg))?;
            self.done.count(kind);
            self.next += 1;
        }
        let mut hold = 0;
        while let Some(&(at, ns)) = self.delays.get(self.next_delay) {
            if at > msg.seq {
                break;
            }
            hold = hold.max(ns);
            self.next_delay += 1;
        }
        if hold > 0 {
            std::thread::sleep(Duration::from_nanos(hold));
            self.done.delayed += 1;
        }
        self.inner.publish(msg)
    }

    fn try_receive(&mut self) -> Result<Option<L::Rx>, LinkError> {
        self.inner.try_receive()
    }

    fn wait_event(&mut self, timeout: Duration) -> Result<(), LinkError> {
        self.inner.wait_event(timeout)
    }

    fn peer_state(&mut self) -> Result<PeerState, LinkError> {
        self.inner.peer_state()
    }

    fn notifies(&self) -> bool {
        self.inner.notifies()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Default)]
    struct Sink(Vec<CommandMsg>);

    impl Link for Sink {
        type Tx = CommandMsg;
        type Rx = ();
        fn publish(&mut self, c: &CommandMsg) -> Result<(), LinkError> {
            self.0.push(*c);
            Ok(())
        }
        fn try_receive(&mut self) -> Result<Option<()>, LinkError> {
            Ok(None)
        }
        fn wait_event(&mut self, _: Duration) -> Result<(), LinkError> {
            Ok(())
        }
        fn peer_state(&mut self) -> Result<PeerState, LinkError> {
            Ok(PeerState::Absent)
        }
    }

    #[test]
    fn corruptions_and_delays_are_done_once_and_counted() {
        let mut l = Injecting::new(Sink::default(), vec![(3, Corruption::Seq), (1, Corruption::Nan)])
            .with_delays(vec![(2, 1_000), (2, 2_000), (9, 1_000)]);
        for seq in [0, 2, 4, 5] {
            l.publish(&CommandMsg { seq, ..zerocopy::FromZeros::new_zeroed() }).unwrap();
        }
        let got = l.injected();
        assert_eq!(got, Injected { non_finite: 1, future_seq: 1, delayed: 1, ..Injected::default() });
        let sent: Vec<u64> = l.into_inner().0.iter().map(|c| c.seq).collect();
        assert_eq!(sent, vec![0, 2, 2, 1_000_004, 4, 5]);
    }
}
