//! What the benchmark reads of a HIL run — the plant's `latency.json`, the controller's
//! `controller.json` — and the load it ran under.

use serde::{Deserialize, Serialize};

use crate::domain::histogram::Percentiles;
use crate::run::hil::misses::MissCauses;
use crate::run::hil::wait::WaitCounts;
use crate::run::hil::wakes::WakeReport;

/// The load on the machine while a HIL run is measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Load {
    /// Nothing added (other programs may run).
    Idle,
    /// One busy-looping thread per online CPU (`BusyLoad`).
    Busy,
}

impl Load {
    /// `idle` or `busy`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Idle => "idle",
            Self::Busy => "busy",
        }
    }
}

/// One HIL run's figures as the benchmark reads them from its `latency.json` (every key
/// must be there: a missing one is an error, not a zero).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct HilFigures {
    /// Round trip (ns).
    pub round_trip_ns: Percentiles,
    /// Controller compute (ns).
    pub controller_compute_ns: Percentiles,
    /// Release jitter (ns).
    pub release_jitter_ns: Percentiles,
    /// Cycles.
    pub cycles: u64,
    /// Deadline misses.
    pub deadline_misses: u64,
    /// Their causes.
    pub miss_causes: MissCauses,
    /// The deadline (ns).
    pub deadline_ns: u64,
    /// Times the robot was stopped.
    pub stop_events: u64,
    /// The real-time setup in force.
    pub rt: RtFigures,
}

/// The part of `latency.json`'s `rt` the benchmark reads.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct RtFigures {
    /// Whether `SCHED_FIFO` was in force.
    pub fifo: bool,
}

/// What the benchmark reads of a run's `controller.json` (every key must be there).
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct ControllerFigures {
    /// What the adaptive wait did.
    pub wait_counts: WaitCounts,
    /// The wake log.
    pub wakes: WakeReport,
}
