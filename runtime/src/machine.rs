//! The machine a run was on, as reports record it.

use serde::{Deserialize, Serialize};

/// The machine at one moment.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Machine {
    /// Online CPUs.
    pub cpus: usize,
    /// `/proc/loadavg`.
    pub load_average: String,
    /// `sched_rt_runtime_us / sched_rt_period_us`.
    pub rt_throttling_us: Option<(i64, i64)>,
    /// `uname -r`.
    pub kernel: String,
}

impl Machine {
    /// The machine now.
    pub fn now() -> Self {
        Self {
            cpus: crate::rt::online_cpus(),
            load_average: read("/proc/loadavg"),
            rt_throttling_us: crate::rt::rt_throttling(),
            kernel: read("/proc/sys/kernel/osrelease"),
        }
    }
}

/// The trimmed contents of a `/proc` file, empty if unreadable.
pub fn read(path: &str) -> String {
    std::fs::read_to_string(path).map(|s| s.trim().to_string()).unwrap_or_default()
}
