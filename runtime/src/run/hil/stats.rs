//! What each process counts and measures during a HIL run.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use serde::{Deserialize, Serialize};

use super::misses::MissCauses;
use super::wait::WaitCounts;
use super::wakes::WakeLog;
use crate::domain::histogram::LatencyHistogram;
use crate::domain::record::Rejections;
use crate::transport::wire::{CommandMsg, WireError};

/// Dropped commands, by reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct InvalidCounts {
    /// Wrong protocol version.
    pub version: u64,
    /// Another session.
    pub session: u64,
    /// A sequence number no measurement had.
    pub future_seq: u64,
    /// Wrong joint count.
    pub joint_count: u64,
    /// Unknown status code.
    pub status: u64,
    /// Non-finite velocity.
    pub non_finite: u64,
}

impl InvalidCounts {
    /// Counts one dropped message.
    pub fn count(&mut self, e: WireError) {
        match e {
            WireError::Version(_) => self.version += 1,
            // (A changed announcement and a malformed target concern measurements, not
            // commands.)
            WireError::Session | WireError::Changed | WireError::NotPlanar | WireError::NotARotation => {
                self.session += 1;
            }
            WireError::Future(_) | WireError::Stale(_) => self.future_seq += 1,
            WireError::JointCount(_) => self.joint_count += 1,
            // (A refusal of this session ends the run before it would be counted.)
            WireError::Status(_) | WireError::Refused(_) => self.status += 1,
            WireError::NonFinite => self.non_finite += 1,
        }
    }

    /// All of them.
    pub fn total(&self) -> u64 {
        self.version + self.session + self.future_seq + self.joint_count + self.status + self.non_finite
    }
}

/// What the plant measured about the exchange.
#[derive(Clone, Debug, Default)]
pub struct PlantStats {
    /// When the last valid answer arrived, applied or too late to be (ns; 0: none): the
    /// controller is alive then (the peer watch's news).
    pub last_valid_answer_ns: u64,
    /// Controller compute time, from each command (ns).
    pub compute: LatencyHistogram,
    /// Measurement publication to command receipt, on the plant's clock (ns); late commands
    /// included.
    pub round_trip: LatencyHistogram,
    /// Publication time minus scheduled release time (ns); real-time mode only.
    pub jitter: LatencyHistogram,
    /// Periods run.
    pub cycles: u64,
    /// Commands applied fresh.
    pub fresh: u64,
    /// Periods whose command did not arrive by the deadline.
    pub deadline_misses: u64,
    /// The deadline misses by cause (real time; they sum to `deadline_misses` at the end).
    pub miss_causes: MissCauses,
    /// Commands that arrived after their deadline (dropped).
    pub late_commands: u64,
    /// Answers to an earlier period's measurement applied as the newest answer
    /// (`--max-command-age`; counted in `fresh` too).
    pub aged_commands: u64,
    /// Periods run on a held command.
    pub held_periods: u64,
    /// Periods run stopped (zero command).
    pub stopped_periods: u64,
    /// Times the robot was stopped (hold exhausted).
    pub stop_events: u64,
    /// Simulated time of the first stop (s).
    pub first_stop_t: Option<f64>,
    /// The longest run of consecutive misses.
    pub max_consecutive_misses: u64,
    /// The longest time between two fresh commands (ns, wall clock).
    pub longest_command_gap_ns: u64,
    /// Gaps between two fresh commands longer than the hold (`hold + 1` periods, wall clock).
    pub command_gaps_over_hold: u64,
    /// Periods whose measurement the plant itself published after the deadline.
    pub plant_overruns: u64,
    /// Times the plant fell more than a period behind its schedule (it was not scheduled, or
    /// stopped) and skipped the releases it missed.
    pub plant_stalls: u64,
    /// Releases skipped after stalls.
    pub skipped_releases: u64,
    /// The longest stall (ns).
    pub longest_stall_ns: u64,
    /// How long the loop's thread was runnable but waited for a CPU over the loop (ns; the
    /// kernel's account, [`runqueue_wait_ns`](crate::sys::rt::runqueue_wait_ns); `None`
    /// where it keeps none): stalls with this near their length were the machine's
    /// scheduling, not the plant's own waits.
    pub runqueue_wait_ns: Option<u64>,
    /// The loop's first release and its end (`CLOCK_MONOTONIC`, ns).
    pub run_window_ns: (u64, u64),
    /// What the adaptive wait did.
    pub wait: WaitCounts,
    /// Malformed commands dropped.
    pub invalid: InvalidCounts,
    /// Measurements the controller skipped as superseded (sum of `skipped`).
    pub controller_skipped: u64,
    /// Log rows lost because the writer thread fell behind (0 unless the machine starves it).
    pub log_rows_dropped: u64,
    /// Waiting on the command event was given up because the controller does not notify it.
    pub event_fallback: bool,
}

impl PlantStats {
    /// Records one received command's timing.
    #[inline]
    pub fn timing(&mut self, now: u64, c: &CommandMsg) {
        self.round_trip.record(now.saturating_sub(c.plant_time_ns));
        self.compute.record(c.compute_ns);
    }
}

/// What the controller measured.
#[derive(Clone, Debug, Default)]
pub struct ControlStats {
    /// Compute time per answer (ns).
    pub compute: LatencyHistogram,
    /// Measurements answered.
    pub answered: u64,
    /// Measurements skipped as superseded by a newer one.
    pub skipped: u64,
    /// Measurements dropped as malformed or out of order.
    pub invalid: u64,
    /// Steps the law rejected (safe command sent).
    pub rejected: u64,
    /// The rejections by reason.
    pub rejections: Rejections,
    /// What the adaptive wait did.
    pub wait: WaitCounts,
    /// The delay the law predicted over, per answer (ns).
    pub delay: LatencyHistogram,
    /// Announced delays outside what the law admits, clamped.
    pub delay_clamped: u64,
    /// Times the plant reported that it stopped the robot (its `STOPPED` flag turning on
    /// after the first answer).
    pub stop_events: u64,
    /// The measurement that first reported a stop.
    pub first_stop_seq: Option<u64>,
    /// Waiting on the measurement event was given up because the plant does not notify it.
    pub event_fallback: bool,
    /// Every wake, and why the late ones were late ([`super::wakes`]).
    pub wakes: WakeLog,
}

/// Live figures of the plant's loop for a progress line (written with relaxed stores, read by
/// another thread).
#[derive(Debug, Default)]
pub struct LiveFigures {
    /// Cycles run.
    pub cycle: AtomicU64,
    /// Deadline misses.
    pub misses: AtomicU64,
    /// Round-trip p99 so far (ns), refreshed every 256 cycles.
    pub p99_ns: AtomicU64,
    /// Robot stopped.
    pub stopped: AtomicBool,
    /// The run is over.
    pub done: AtomicBool,
}

impl LiveFigures {
    /// Marks the run as over.
    pub fn finish(&self) {
        self.done.store(true, Ordering::Release);
    }

    /// Whether the run is over.
    pub fn is_done(&self) -> bool {
        self.done.load(Ordering::Acquire)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalid_counts_by_reason() {
        let mut c = InvalidCounts::default();
        c.count(WireError::Version(9));
        c.count(WireError::NonFinite);
        c.count(WireError::NonFinite);
        c.count(WireError::Future(3));
        assert_eq!((c.version, c.non_finite, c.future_seq, c.total()), (1, 2, 1, 4));
    }
}
