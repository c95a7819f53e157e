//! The one peer-liveness watch of both processes: after a silence (no message for
//! `--silence-ms`) ask the transport whether the peer is alive, at most once per silence
//! interval; a dead or departed peer is found at once, a live one that stays silent for the
//! timeout is hung.

use crate::transport::link::{Link, LinkError, PeerState};

/// What the watch found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PeerLoss {
    /// The peer's process died (pid), after `silent_ns` of silence.
    Died {
        /// Its pid.
        pid: i32,
        /// Silence before the finding (ns).
        silent_ns: u64,
        /// Found by its session's lease running out ([`PeerState::Expired`]): dead, or
        /// unreachable.
        expired: bool,
    },
    /// The peer's node is gone (it exited).
    Gone,
    /// The peer is alive but has been silent for `silent_ns`.
    Hung {
        /// Silence (ns).
        silent_ns: u64,
        /// The pid its transport reports.
        pid: i32,
    },
}

/// Watches a peer's silence.
#[derive(Clone, Copy, Debug)]
pub struct PeerWatch {
    silence_ns: u64,
    last_heard_ns: u64,
    last_check_ns: u64,
}

impl PeerWatch {
    /// A watch that checks after `silence_ns` without news, starting at `now_ns`.
    pub fn new(silence_ns: u64, now_ns: u64) -> Self {
        Self { silence_ns, last_heard_ns: now_ns, last_check_ns: now_ns }
    }

    /// The peer was heard from (or the silence starts now).
    #[inline]
    pub fn heard(&mut self, now_ns: u64) {
        self.last_heard_ns = now_ns;
        self.last_check_ns = now_ns;
    }

    /// When the peer was last heard from (ns).
    #[inline]
    pub fn last_heard_ns(&self) -> u64 {
        self.last_heard_ns
    }

    /// Silence so far (ns).
    #[inline]
    pub fn silent_ns(&self, now_ns: u64) -> u64 {
        now_ns.saturating_sub(self.last_heard_ns)
    }

    /// Checks the peer if it has been silent for the silence interval since the last check;
    /// `timeout_ns`: how long a live peer may stay silent.
    ///
    /// # Errors
    /// The peer's state cannot be read.
    #[inline]
    pub fn check<L: Link>(
        &mut self,
        now_ns: u64,
        timeout_ns: u64,
        link: &mut L,
    ) -> Result<Option<PeerLoss>, LinkError> {
        let silent_ns = self.silent_ns(now_ns);
        if silent_ns < self.silence_ns || now_ns.saturating_sub(self.last_check_ns) < self.silence_ns {
            return Ok(None);
        }
        self.last_check_ns = now_ns;
        Ok(match link.peer_state()? {
            PeerState::Dead(pid) => Some(PeerLoss::Died { pid, silent_ns, expired: false }),
            PeerState::Expired(pid) => Some(PeerLoss::Died { pid, silent_ns, expired: true }),
            PeerState::Absent => Some(PeerLoss::Gone),
            PeerState::Alive(pid) if silent_ns >= timeout_ns => Some(PeerLoss::Hung { silent_ns, pid }),
            PeerState::Alive(_) => None,
        })
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    struct Peer(PeerState, u32);

    impl Link for Peer {
        type Tx = ();
        type Rx = ();
        fn publish(&mut self, (): &()) -> Result<(), LinkError> {
            Ok(())
        }
        fn try_receive(&mut self) -> Result<Option<()>, LinkError> {
            Ok(None)
        }
        fn wait_event(&mut self, _: Duration) -> Result<(), LinkError> {
            Ok(())
        }
        fn peer_state(&mut self) -> Result<PeerState, LinkError> {
            self.1 += 1;
            Ok(self.0)
        }
    }

    #[test]
    fn checks_once_per_silence_and_tells_dead_gone_and_hung_apart() {
        let mut w = PeerWatch::new(20, 100);
        let mut alive = Peer(PeerState::Alive(7), 0);
        assert_eq!(w.check(119, 50, &mut alive).unwrap(), None);
        assert_eq!(alive.1, 0, "no check before the silence");
        assert_eq!(w.check(120, 50, &mut alive).unwrap(), None);
        assert_eq!(w.check(130, 50, &mut alive).unwrap(), None);
        assert_eq!(alive.1, 1, "one check per silence interval");
        assert_eq!(w.check(150, 50, &mut alive).unwrap(), Some(PeerLoss::Hung { silent_ns: 50, pid: 7 }));
        w.heard(150);
        assert_eq!(w.check(160, 50, &mut alive).unwrap(), None);
        let mut dead = Peer(PeerState::Dead(9), 0);
        assert_eq!(
            w.check(170, 50, &mut dead).unwrap(),
            Some(PeerLoss::Died { pid: 9, silent_ns: 20, expired: false })
        );
        let mut gone = Peer(PeerState::Absent, 0);
        assert_eq!(w.check(190, 50, &mut gone).unwrap(), Some(PeerLoss::Gone));
    }
}
