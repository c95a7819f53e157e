//! Time behind a trait, so that the loops' timing logic (absolute deadlines, hold/stop policy,
//! liveness timeouts) runs against a fake clock in tests.
//!
//! All times are nanoseconds of `CLOCK_MONOTONIC` (or of the fake clock's own origin).

use std::cell::Cell;

/// A monotonic clock with absolute sleeps.
pub trait Clock {
    /// Now, in nanoseconds.
    fn now_ns(&self) -> u64;
    /// Sleeps until `t_ns` (returns at once if it has passed).
    fn sleep_until_ns(&self, t_ns: u64);
    /// Called once per iteration of a busy-wait loop (a CPU hint on the real clock; the fake
    /// clock advances instead, so that busy waits end in tests).
    #[inline]
    fn spin_hint(&self) {
        core::hint::spin_loop();
    }
}

/// The machine's `CLOCK_MONOTONIC` (shared by all processes on the machine).
#[derive(Clone, Copy, Debug, Default)]
pub struct MonotonicClock;

impl Clock for MonotonicClock {
    #[inline]
    fn now_ns(&self) -> u64 {
        crate::sys::rt::monotonic_ns()
    }

    fn sleep_until_ns(&self, t_ns: u64) {
        crate::sys::rt::sleep_until_ns(t_ns);
    }
}

/// The machine's `CLOCK_MONOTONIC`, whose sleeps wait on a [`TimerFd`](crate::sys::rt::TimerFd)
/// when it has one, else in `clock_nanosleep` (the plant's clock: `--release-timer`).
#[derive(Debug, Default)]
pub struct ReleaseClock {
    timer: Option<crate::sys::rt::TimerFd>,
}

impl ReleaseClock {
    /// Sleeping on `timer` (`None`: `clock_nanosleep`, as [`MonotonicClock`]).
    pub fn new(timer: Option<crate::sys::rt::TimerFd>) -> Self {
        Self { timer }
    }
}

impl Clock for ReleaseClock {
    #[inline]
    fn now_ns(&self) -> u64 {
        crate::sys::rt::monotonic_ns()
    }

    fn sleep_until_ns(&self, t_ns: u64) {
        match &self.timer {
            Some(t) => t.sleep_until_ns(t_ns),
            None => crate::sys::rt::sleep_until_ns(t_ns),
        }
    }
}

/// A clock that moves only when told: `sleep_until_ns` jumps to the deadline, each
/// `spin_hint` advances by `spin_step_ns`, and [`FakeClock::advance`] moves it by hand.
#[derive(Debug)]
pub struct FakeClock {
    now: Cell<u64>,
    spin_step_ns: u64,
}

impl FakeClock {
    /// A clock at `start_ns` whose busy-wait iterations each take `spin_step_ns`.
    pub fn new(start_ns: u64, spin_step_ns: u64) -> Self {
        Self { now: Cell::new(start_ns), spin_step_ns }
    }

    /// Moves the clock forward by `dt_ns`.
    pub fn advance(&self, dt_ns: u64) {
        self.now.set(self.now.get() + dt_ns);
    }
}

impl Clock for FakeClock {
    fn now_ns(&self) -> u64 {
        self.now.get()
    }

    fn sleep_until_ns(&self, t_ns: u64) {
        if t_ns > self.now.get() {
            self.now.set(t_ns);
        }
    }

    fn spin_hint(&self) {
        self.advance(self.spin_step_ns);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fake_clock_sleeps_and_spins() {
        let c = FakeClock::new(1_000, 10);
        c.sleep_until_ns(5_000);
        assert_eq!(c.now_ns(), 5_000);
        c.sleep_until_ns(100);
        assert_eq!(c.now_ns(), 5_000);
        c.spin_hint();
        assert_eq!(c.now_ns(), 5_010);
        c.advance(90);
        assert_eq!(c.now_ns(), 5_100);
    }

    #[test]
    fn monotonic_clock_is_monotonic() {
        let c = MonotonicClock;
        let a = c.now_ns();
        let b = c.now_ns();
        assert!(b >= a);
    }
}
