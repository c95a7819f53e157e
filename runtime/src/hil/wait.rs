//! Waiting: for a point in time (the plant's release) and for a message (one idle step at a
//! time, between two `receive()` calls), in the three `--wait` modes.

use std::time::Duration;

use anyhow::Result;

use super::config::WaitMode;
use crate::clock::Clock;

/// After this long spinning without a message, hybrid waiting naps instead (ns).
pub const SPIN_BUDGET_NS: u64 = 200_000;
/// The nap of hybrid waiting once the spin budget is spent (ns).
pub const NAP_NS: u64 = 50_000;
/// The longest single event wait (ns): the caller re-checks its timeouts at least this often.
pub const MAX_EVENT_WAIT_NS: u64 = 10_000_000;

/// Waits until `t_ns`: spinning on the clock, sleeping to the absolute time, or sleeping until
/// `margin_ns` before it and spinning the rest.
#[inline]
pub fn until<C: Clock>(clock: &C, mode: WaitMode, t_ns: u64, margin_ns: u64) {
    match mode {
        WaitMode::Spin => {}
        WaitMode::Event => clock.sleep_until_ns(t_ns),
        WaitMode::Hybrid => {
            if clock.now_ns() + margin_ns < t_ns {
                clock.sleep_until_ns(t_ns - margin_ns);
            }
        }
    }
    while clock.now_ns() < t_ns {
        clock.spin_hint();
    }
}

/// What a receiver does between two empty `receive()` calls.
#[derive(Clone, Copy, Debug)]
pub struct Idler {
    mode: WaitMode,
    margin_ns: u64,
    spin_start: Option<u64>,
}

impl Idler {
    /// An idler for `mode`; `margin_ns` is the hybrid spin margin.
    pub fn new(mode: WaitMode, margin_ns: u64) -> Self {
        Self { mode, margin_ns, spin_start: None }
    }

    /// A message arrived: the next wait starts afresh.
    #[inline]
    pub fn reset(&mut self) {
        self.spin_start = None;
    }

    /// One idle step. `expected_ns`: when the message should arrive (hybrid sleeps until
    /// `margin` before it), `limit_ns`: never block past this time; `event_wait(timeout)`
    /// waits on the transport's event (event mode only).
    ///
    /// # Errors
    /// The event wait failed.
    #[inline]
    pub fn idle<C: Clock>(
        &mut self,
        clock: &C,
        expected_ns: Option<u64>,
        limit_ns: u64,
        event_wait: impl FnOnce(Duration) -> Result<()>,
    ) -> Result<()> {
        let now = clock.now_ns();
        match self.mode {
            WaitMode::Spin => clock.spin_hint(),
            WaitMode::Event => {
                let ns = limit_ns.saturating_sub(now).clamp(1_000, MAX_EVENT_WAIT_NS);
                event_wait(Duration::from_nanos(ns))?;
            }
            WaitMode::Hybrid => {
                if let Some(e) = expected_ns {
                    if now + self.margin_ns < e {
                        clock.sleep_until_ns((e - self.margin_ns).min(limit_ns));
                        return Ok(());
                    }
                }
                let start = *self.spin_start.get_or_insert(now);
                if now - start > SPIN_BUDGET_NS {
                    clock.sleep_until_ns((now + NAP_NS).min(limit_ns));
                } else {
                    clock.spin_hint();
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clock::FakeClock;

    #[test]
    fn until_reaches_the_time_in_every_mode() {
        for mode in [WaitMode::Spin, WaitMode::Event, WaitMode::Hybrid] {
            let c = FakeClock::new(0, 100);
            until(&c, mode, 1_000_000, 100_000);
            assert!(c.now_ns() >= 1_000_000 && c.now_ns() < 1_000_200, "{mode:?}: {}", c.now_ns());
        }
    }

    #[test]
    fn hybrid_sleeps_to_the_margin_then_spins_then_naps() {
        let c = FakeClock::new(0, 1_000);
        let mut idler = Idler::new(WaitMode::Hybrid, 100_000);
        let no_event = |_d: Duration| -> Result<()> { panic!("no event in hybrid mode") };
        idler.idle(&c, Some(1_000_000), u64::MAX, no_event).unwrap();
        assert_eq!(c.now_ns(), 900_000);
        // Spinning: 1 µs per step while within the budget.
        idler.idle(&c, Some(1_000_000), u64::MAX, no_event).unwrap();
        assert_eq!(c.now_ns(), 901_000);
        c.advance(SPIN_BUDGET_NS + 1);
        idler.idle(&c, Some(1_000_000), u64::MAX, no_event).unwrap();
        assert_eq!(c.now_ns(), 901_000 + SPIN_BUDGET_NS + 1 + NAP_NS);
        // Never past the limit.
        let limit = c.now_ns() + 10;
        idler.idle(&c, None, limit, no_event).unwrap();
        assert_eq!(c.now_ns(), limit);
    }

    #[test]
    fn event_waits_are_bounded_by_the_limit() {
        let c = FakeClock::new(0, 1);
        let mut idler = Idler::new(WaitMode::Event, 0);
        let mut asked = Duration::ZERO;
        idler
            .idle(&c, None, 300_000, |d| {
                asked = d;
                Ok(())
            })
            .unwrap();
        assert_eq!(asked, Duration::from_micros(300));
        idler
            .idle(&c, None, u64::MAX, |d| {
                asked = d;
                Ok(())
            })
            .unwrap();
        assert_eq!(asked, Duration::from_nanos(MAX_EVENT_WAIT_NS));
    }
}
