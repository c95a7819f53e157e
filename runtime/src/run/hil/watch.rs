//! The one peer-liveness watch of both processes: after a silence (no message for
//! `--silence-ms`) ask the transport whether the peer is alive, at most once per silence
//! interval; a dead or departed peer is found at once, a live one that stays silent for the
//! timeout is hung.
//!
//! Silence is the peer's, not the watcher's: any valid message from the peer is news, also an
//! answer that came too late to be applied (a late peer is alive, and the hold policy, not
//! the watch, deals with its lateness), and the time the watcher itself was not scheduled
//! (a stall it measured) is excused. On a loaded machine both processes starve; before, a
//! plant that had waited 0.67 s for a CPU, and whose controller answered late, called its
//! controller hung after 2.2 s (`runtime/tests/hil.rs`, load 8–9 on two CPUs).

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
    last_news_ns: u64,
    last_check_ns: u64,
}

impl PeerWatch {
    /// A watch that checks after `silence_ns` without news, starting at `now_ns`.
    pub fn new(silence_ns: u64, now_ns: u64) -> Self {
        Self { silence_ns, last_heard_ns: now_ns, last_news_ns: now_ns, last_check_ns: now_ns }
    }

    /// The peer was heard from (or the silence starts now).
    #[inline]
    pub fn heard(&mut self, now_ns: u64) {
        self.last_heard_ns = now_ns;
        self.last_news_ns = now_ns;
        self.last_check_ns = now_ns;
    }

    /// A valid message from the peer arrived at `at_ns` that was not taken as heard (an
    /// answer too late to apply): the peer is alive then; the silence counts from it.
    #[inline]
    pub fn news(&mut self, at_ns: u64) {
        if at_ns > self.last_news_ns {
            self.last_news_ns = at_ns;
            self.last_check_ns = self.last_check_ns.max(at_ns);
        }
    }

    /// The watcher itself stalled for `stall_ns` (not scheduled): that time is not the
    /// peer's silence.
    #[inline]
    pub fn excuse(&mut self, stall_ns: u64) {
        self.last_news_ns = self.last_news_ns.saturating_add(stall_ns);
    }

    /// When the peer was last heard from (ns): its last applied message.
    #[inline]
    pub fn last_heard_ns(&self) -> u64 {
        self.last_heard_ns
    }

    /// Silence so far (ns): since the peer's last valid message, less the watcher's own
    /// stalls since.
    #[inline]
    pub fn silent_ns(&self, now_ns: u64) -> u64 {
        now_ns.saturating_sub(self.last_news_ns)
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

    /// A late answer is news (the peer is alive), and the watcher's own stall is not the
    /// peer's silence; a peer that sends nothing is still found hung.
    #[test]
    fn late_answers_are_news_and_the_watchers_stall_is_excused() {
        let mut alive = Peer(PeerState::Alive(7), 0);
        let mut w = PeerWatch::new(20, 100);
        w.news(140);
        assert_eq!(w.last_heard_ns(), 100, "a late answer is not an applied one");
        assert_eq!(w.silent_ns(170), 30);
        assert_eq!(w.check(170, 50, &mut alive).unwrap(), None);
        w.news(130);
        assert_eq!(w.silent_ns(170), 30, "older news changes nothing");
        w.excuse(25);
        assert_eq!(w.silent_ns(190), 25, "the 25 ns the watcher stalled are excused");
        assert_eq!(w.check(190, 50, &mut alive).unwrap(), None);
        assert_eq!(w.check(215, 50, &mut alive).unwrap(), Some(PeerLoss::Hung { silent_ns: 50, pid: 7 }));
    }
}
