//! The hold-then-stop policy for missing commands: hold the last fresh command for at most
//! `--hold-periods` periods, then stop the robot (every velocity zero) until fresh commands
//! arrive again.

use crate::domain::controller::{StepReport, JOINTS};
use crate::domain::record::CommandSource;

/// The hold-then-stop policy for missing commands.
/// `N`: the arm's joints (the paper's arm by default).
#[derive(Clone, Copy, Debug)]
pub struct HoldPolicy<const N: usize = JOINTS> {
    hold_periods: u32,
    consecutive: u32,
    last: Option<StepReport<N>>,
}

/// The report applied while stopped: every velocity zero, no diagnostics.
pub fn stop_report<const N: usize>() -> StepReport<N> {
    StepReport::zero(None)
}

impl<const N: usize> HoldPolicy<N> {
    /// Hold for at most `hold_periods` periods.
    pub fn new(hold_periods: u32) -> Self {
        Self { hold_periods, consecutive: 0, last: None }
    }

    /// A fresh command arrived in time.
    #[inline]
    pub fn fresh(&mut self, r: StepReport<N>) -> (StepReport<N>, CommandSource) {
        self.consecutive = 0;
        self.last = Some(r);
        (r, CommandSource::Fresh)
    }

    /// The period's command is missing: hold the last fresh one for `hold_periods` periods,
    /// then stop (also when there never was a fresh one).
    #[inline]
    pub fn missed(&mut self) -> (StepReport<N>, CommandSource) {
        self.consecutive = self.consecutive.saturating_add(1);
        match self.last {
            Some(r) if self.consecutive <= self.hold_periods => (r, CommandSource::Held),
            _ => (stop_report(), CommandSource::Stopped),
        }
    }

    /// Whether the robot is stopped now.
    pub fn stopped(&self) -> bool {
        self.consecutive > self.hold_periods || (self.consecutive > 0 && self.last.is_none())
    }

    /// Whether a fresh command was ever applied.
    pub fn has_commanded(&self) -> bool {
        self.last.is_some()
    }

    /// Consecutive misses so far.
    pub fn consecutive(&self) -> u32 {
        self.consecutive
    }
}

#[cfg(test)]
mod tests {
    use companion_core::Command;

    use super::*;

    fn report(v: f64) -> StepReport {
        let mut r = stop_report();
        r.command.platform.v = v;
        r.ep_norm = 0.1;
        r
    }

    #[test]
    fn hold_then_stop_then_resume() {
        let mut p = HoldPolicy::new(3);
        assert_eq!(p.fresh(report(1.0)).1, CommandSource::Fresh);
        for _ in 0..3 {
            let (r, src) = p.missed();
            assert_eq!(src, CommandSource::Held);
            assert_eq!(r.command.platform.v, 1.0);
            assert!(!p.stopped());
        }
        let (r, src) = p.missed();
        assert_eq!(src, CommandSource::Stopped);
        assert_eq!(r.command, Command::zero());
        assert!(p.stopped());
        assert_eq!(p.consecutive(), 4);
        assert_eq!(p.fresh(report(2.0)).1, CommandSource::Fresh);
        assert!(!p.stopped());
    }

    #[test]
    fn no_fresh_command_yet_means_stopped() {
        let mut p = HoldPolicy::<3>::new(5);
        assert_eq!(p.missed().1, CommandSource::Stopped);
        assert!(p.stopped());
        let mut p = HoldPolicy::new(0);
        p.fresh(report(1.0));
        assert_eq!(p.missed().1, CommandSource::Stopped);
    }
}
