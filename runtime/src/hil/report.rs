//! `latency.json`, `latency.svg` and the latency table of a HIL run.

use std::path::Path;

use anyhow::{Context, Result};
use serde::Serialize;

use super::plant::{InvalidCounts, PlantEnd, PlantStats};
use super::{HilArgs, Timing, WaitMode};
use crate::latency::stats::{fmt_ns, Percentiles};
use crate::rt::RtReport;
use crate::scenario::Scenario;

/// The real-time setup as it was in force.
#[derive(Clone, Debug, Default, Serialize)]
pub struct RtSummary {
    /// `--rt` given.
    pub requested: bool,
    /// `SCHED_FIFO` in force on the plant's loop thread.
    pub fifo: bool,
    /// The `SCHED_FIFO` priority asked for.
    pub priority: i32,
    /// Memory locked.
    pub memory_locked: bool,
    /// The plant's CPU.
    pub plant_cpu: Option<usize>,
    /// The controller's CPU.
    pub controller_cpu: Option<usize>,
    /// Warnings.
    pub warnings: Vec<String>,
}

/// The machine the run was on.
#[derive(Clone, Debug, Serialize)]
pub struct Machine {
    /// Online CPUs.
    pub cpus: usize,
    /// `/proc/loadavg` at the end of the run.
    pub load_average: String,
    /// `sched_rt_runtime_us / sched_rt_period_us`.
    pub rt_throttling_us: Option<(i64, i64)>,
    /// `uname -r`.
    pub kernel: String,
}

impl Machine {
    /// The machine now.
    pub fn now() -> Self {
        let read = |p: &str| std::fs::read_to_string(p).map(|s| s.trim().to_string()).unwrap_or_default();
        Self {
            cpus: crate::rt::online_cpus(),
            load_average: read("/proc/loadavg"),
            rt_throttling_us: crate::rt::rt_throttling(),
            kernel: read("/proc/sys/kernel/osrelease"),
        }
    }
}

/// `latency.json`: the timing of a HIL run, as the plant measured it.
#[derive(Clone, Debug, Serialize)]
pub struct LatencyReport {
    /// The scenario's name.
    pub scenario: String,
    /// `real-time` or `lockstep`.
    pub mode: &'static str,
    /// The wait mode.
    pub wait: WaitMode,
    /// Control rate (Hz); 0 in lockstep.
    pub rate_hz: f64,
    /// Deadline after release (ns).
    pub deadline_ns: u64,
    /// Hold periods before the stop.
    pub hold_periods: u32,
    /// Real-time setup.
    pub rt: RtSummary,
    /// Periods run.
    pub cycles: u64,
    /// Commands applied fresh.
    pub fresh_commands: u64,
    /// Periods whose command missed its deadline.
    pub deadline_misses: u64,
    /// Commands that arrived after their deadline (dropped).
    pub late_commands: u64,
    /// Periods on a held command.
    pub held_periods: u64,
    /// Periods stopped (zero command).
    pub stopped_periods: u64,
    /// Times the hold ran out and the robot was stopped.
    pub stop_events: u64,
    /// Simulated time of the first stop (s).
    pub first_stop_at_s: Option<f64>,
    /// The longest run of consecutive misses.
    pub max_consecutive_misses: u64,
    /// Periods the plant itself published after the deadline.
    pub plant_overruns: u64,
    /// Malformed commands dropped, by reason.
    pub invalid_messages: InvalidCounts,
    /// Their total.
    pub invalid_total: u64,
    /// Measurements the controller skipped as superseded.
    pub controller_skipped: u64,
    /// Log rows lost (writer thread starved).
    pub log_rows_dropped: u64,
    /// Controller compute time per command (ns).
    pub controller_compute_ns: Percentiles,
    /// Measurement publication to command receipt on the plant's clock (ns).
    pub round_trip_ns: Percentiles,
    /// Period jitter: publication time minus scheduled release time (ns). Empty in lockstep.
    pub release_jitter_ns: Percentiles,
    /// How the run ended.
    pub end: String,
    /// Wall-clock time (s).
    pub wall_time_s: f64,
    /// The machine.
    pub machine: Machine,
}

impl LatencyReport {
    /// The report of a finished run.
    pub fn new(
        s: &Scenario,
        a: &HilArgs,
        t: &Timing,
        st: &PlantStats,
        rt: Option<&RtReport>,
        end: &PlantEnd,
        wall_time_s: f64,
    ) -> Self {
        let (pc, cc) = a.cpus();
        #[allow(clippy::cast_precision_loss)]
        let rate_hz = if t.period_ns > 0 { 1e9 / t.period_ns as f64 } else { 0.0 };
        Self {
            scenario: s.name.clone(),
            mode: if t.lockstep { "lockstep" } else { "real-time" },
            wait: t.wait,
            rate_hz,
            deadline_ns: if t.lockstep { 0 } else { t.deadline_ns },
            hold_periods: t.hold_periods,
            rt: RtSummary {
                requested: a.rt,
                fifo: rt.is_some_and(|r| r.fifo),
                priority: a.rt_priority,
                memory_locked: rt.is_some_and(|r| r.locked),
                plant_cpu: rt.and_then(|r| r.pinned).or(a.rt.then_some(pc)),
                controller_cpu: a.rt.then_some(cc),
                warnings: rt.map(|r| r.warnings.clone()).unwrap_or_default(),
            },
            cycles: st.cycles,
            fresh_commands: st.fresh,
            deadline_misses: st.deadline_misses,
            late_commands: st.late_commands,
            held_periods: st.held_periods,
            stopped_periods: st.stopped_periods,
            stop_events: st.stop_events,
            first_stop_at_s: st.first_stop_t,
            max_consecutive_misses: st.max_consecutive_misses,
            plant_overruns: st.plant_overruns,
            invalid_messages: st.invalid,
            invalid_total: st.invalid.total(),
            controller_skipped: st.controller_skipped,
            log_rows_dropped: st.log_rows_dropped,
            controller_compute_ns: st.compute.percentiles(),
            round_trip_ns: st.round_trip.percentiles(),
            release_jitter_ns: st.jitter.percentiles(),
            end: end.describe(),
            wall_time_s,
            machine: Machine::now(),
        }
    }
}

/// Writes `dir/latency.json`.
///
/// # Errors
/// Writing failed.
pub fn write_json(dir: &Path, r: &LatencyReport) -> Result<()> {
    let path = dir.join("latency.json");
    std::fs::write(&path, serde_json::to_string_pretty(r)? + "\n")
        .with_context(|| format!("writing {}", path.display()))
}

/// Writes `dir/latency.svg`: the three distributions.
///
/// # Errors
/// Drawing failed.
pub fn write_svg(dir: &Path, st: &PlantStats, r: &LatencyReport) -> Result<()> {
    let mut series = vec![("controller compute", &st.compute), ("round trip", &st.round_trip)];
    if st.jitter.count() > 0 {
        series.push(("release jitter", &st.jitter));
    }
    let title = format!(
        "{} — {} {}, {} cycles, {} deadline misses",
        r.scenario,
        r.mode,
        r.wait.as_str(),
        r.cycles,
        r.deadline_misses
    );
    let deadline = (r.deadline_ns > 0).then_some(r.deadline_ns);
    crate::latency::plot::latency_svg(&dir.join("latency.svg"), &title, &series, deadline)
}

/// Prints the latency table.
pub fn print(r: &LatencyReport) {
    println!(
        "{:<20} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>9}",
        "latency", "p50", "p90", "p99", "p99.9", "p99.99", "max", "samples"
    );
    let mut rows = vec![("controller compute", &r.controller_compute_ns), ("round trip", &r.round_trip_ns)];
    if r.release_jitter_ns.count > 0 {
        rows.push(("release jitter", &r.release_jitter_ns));
    }
    for (name, p) in rows {
        println!(
            "{:<20} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>9}",
            name,
            fmt_ns(p.p50),
            fmt_ns(p.p90),
            fmt_ns(p.p99),
            fmt_ns(p.p99_9),
            fmt_ns(p.p99_99),
            fmt_ns(p.max),
            p.count
        );
    }
    let rt = if r.rt.requested {
        format!(
            "--rt (SCHED_FIFO {}, memory {}, CPU {:?}/{:?})",
            if r.rt.fifo { "on" } else { "REFUSED" },
            if r.rt.memory_locked { "locked" } else { "not locked" },
            r.rt.plant_cpu,
            r.rt.controller_cpu
        )
    } else {
        "no --rt".to_string()
    };
    if r.mode == "lockstep" {
        println!(
            "{} cycles, lockstep, wait {}, {rt}; {} malformed commands dropped",
            r.cycles,
            r.wait.as_str(),
            r.invalid_total
        );
    } else {
        println!(
            "{} cycles at {:.0} Hz, deadline {}, wait {}, {rt}: {} deadline misses ({} late), {} held, {} stopped \
             ({} stops), {} malformed commands dropped",
            r.cycles,
            r.rate_hz,
            fmt_ns(r.deadline_ns),
            r.wait.as_str(),
            r.deadline_misses,
            r.late_commands,
            r.held_periods,
            r.stopped_periods,
            r.stop_events,
            r.invalid_total
        );
    }
}
