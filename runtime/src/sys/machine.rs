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
            cpus: crate::sys::rt::online_cpus(),
            load_average: read("/proc/loadavg"),
            rt_throttling_us: crate::sys::rt::rt_throttling(),
            kernel: read("/proc/sys/kernel/osrelease"),
        }
    }
}

/// The trimmed contents of a `/proc` file, empty if unreadable.
pub fn read(path: &str) -> String {
    std::fs::read_to_string(path).map(|s| s.trim().to_string()).unwrap_or_default()
}

/// The CPU time (s) this process has used so far, all its threads, user and system: fields
/// 14 and 15 of `/proc/self/stat`, in the kernel's fixed 100 ticks per second (`USER_HZ`).
/// `None` where `/proc` is not there. Throughput on a shared machine is honest only per CPU
/// second: wall time counts the time other processes had the cores.
pub fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name (field 2) is in parentheses and may hold spaces: count after it.
    let rest = stat.rsplit_once(')')?.1;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let (utime, stime) = (fields.get(11)?.parse::<u64>().ok()?, fields.get(12)?.parse::<u64>().ok()?);
    Some((utime + stime) as f64 / 100.0)
}

#[cfg(test)]
mod tests {
    #[test]
    fn process_cpu_time_grows_with_work() {
        let before = super::process_cpu_seconds().expect("/proc/self/stat");
        let start = std::time::Instant::now();
        let mut x = 0u64;
        while start.elapsed().as_secs_f64() < 0.3 {
            x = std::hint::black_box(x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1));
        }
        let after = super::process_cpu_seconds().unwrap();
        // Busy for 0.3 s of wall time: some CPU time was counted (the machine may be shared,
        // so not necessarily all of it), and never more than wall time times the cores.
        assert!(after > before, "{before} -> {after}");
        assert!(after - before <= 0.3 * 64.0 + 0.02);
    }
}
