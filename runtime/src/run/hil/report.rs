//! `latency.json`, `latency.svg` and the latency table of a HIL run.

use std::path::Path;

use serde::Serialize;

use super::chaos::DoneStop;
use super::config::{HilConfig, RtPlan, WaitMode};
use super::end::PlantEnd;
use super::stats::{InvalidCounts, PlantStats};
use super::wait::WaitCounts;
use crate::domain::histogram::Percentiles;
use crate::domain::plots::PlotError;
use crate::domain::record::error::RecordError;
use crate::domain::record::Failure;
use crate::domain::scenario::Scenario;
use crate::sys::machine::Machine;
use crate::sys::rt::RtReport;
use crate::transport::Transport;

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

/// The `SCHED_FIFO` priority `latency.json` reports when `--rt` is off (the flag's default).
pub const DEFAULT_PRIORITY: i32 = 80;

/// `latency.json`: the timing of a HIL run, as the plant measured it.
#[derive(Clone, Debug, Serialize)]
pub struct LatencyReport {
    /// The scenario's name.
    pub scenario: String,
    /// `real-time` or `lockstep`.
    pub mode: &'static str,
    /// The wait mode.
    pub wait: WaitMode,
    /// How the plant slept to its releases where its wait mode sleeps (`--release-timer`).
    pub release_timer: super::config::ReleaseTimer,
    /// Control rate (Hz); 0 in lockstep.
    pub rate_hz: f64,
    /// Deadline after release (ns).
    pub deadline_ns: u64,
    /// Hold periods before the stop.
    pub hold_periods: u32,
    /// The wire's protocol version.
    pub protocol_version: u32,
    /// The scenario hash the plant announced (hex).
    pub scenario_hash: String,
    /// The joint guard κ the controller runs with for this plant (see `hil::handshake`).
    pub joint_step_fraction: f64,
    /// The plant polled instead of waiting on the command event (the controller did not
    /// notify it).
    pub event_fallback: bool,
    /// Real-time setup.
    pub rt: RtSummary,
    /// Periods run.
    pub cycles: u64,
    /// Commands applied fresh.
    pub fresh_commands: u64,
    /// Periods whose command missed its deadline.
    pub deadline_misses: u64,
    /// The deadline misses by cause, from both processes' stamps ([`super::misses`]): the
    /// plant published late, the controller woke late or stepped long, the answer was sent
    /// in time but came back late, or none came.
    pub miss_causes: super::misses::MissCauses,
    /// Commands that arrived after their deadline (dropped).
    pub late_commands: u64,
    /// Answers to an earlier measurement applied as the newest answer (`--max-command-age`).
    pub aged_commands: u64,
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
    /// The longest time between two fresh commands (ns, wall clock).
    pub longest_command_gap_ns: u64,
    /// Gaps between two fresh commands longer than the hold (wall clock).
    pub command_gaps_over_hold: u64,
    /// Periods the plant itself published after the deadline.
    pub plant_overruns: u64,
    /// Times the plant fell more than a period behind its schedule and skipped ahead.
    pub plant_stalls: u64,
    /// Releases skipped after those stalls.
    pub skipped_releases: u64,
    /// The longest stall (ns).
    pub longest_stall_ns: u64,
    /// How long the plant's loop thread was runnable but waited for a CPU (ns; the kernel's
    /// `schedstat`; null where it keeps none): a starved plant, not one that overslept.
    pub plant_runqueue_wait_ns: Option<u64>,
    /// The plant's loop, first release to end (`CLOCK_MONOTONIC`, ns).
    pub run_window_ns: (u64, u64),
    /// What the plant's adaptive wait did (zero in the other modes).
    pub wait_counts: WaitCounts,
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
    /// Why the run failed (empty: it did what a run must), as in `summary.json`.
    pub failures: Vec<Failure>,
    /// `--chaos`: the controller's stops that this plant made.
    pub chaos_stops: Vec<DoneStop>,
    /// What the plant's transport counted of the measurements it sent and the commands it got
    /// (Zenoh; `null` on iceoryx2): against the controller's counts, the messages lost in
    /// transit (`link.json` of `companion hil`).
    pub link_counts: Option<crate::transport::link::LinkCounts>,
    /// A hung controller's threads when the plant found it silent, on one machine (empty
    /// otherwise; [`crate::sys::threads`]): running, runnable, asleep and where, or stopped.
    pub hung_controller_threads: Vec<crate::sys::threads::ThreadState>,
    /// Wall-clock time (s).
    pub wall_time_s: f64,
    /// The machine.
    pub machine: Machine,
}

impl LatencyReport {
    /// The report of a finished run.
    pub fn new(
        s: &Scenario,
        cfg: &HilConfig,
        st: &PlantStats,
        rt: Option<&RtReport>,
        end: &PlantEnd,
        wall_time_s: f64,
    ) -> Self {
        let t = &cfg.timing;
        let plan = cfg.rt;
        let rate_hz = if t.period_ns > 0 { 1e9 / t.period_ns as f64 } else { 0.0 };
        Self {
            scenario: s.name.clone(),
            mode: if t.lockstep { "lockstep" } else { "real-time" },
            wait: t.wait,
            release_timer: t.release,
            rate_hz,
            deadline_ns: if t.lockstep { 0 } else { t.deadline_ns },
            hold_periods: t.hold_periods,
            protocol_version: crate::transport::wire::PROTOCOL_VERSION,
            scenario_hash: format!("{:#018x}", super::handshake::controller_hash(&s.controller)),
            joint_step_fraction: super::handshake::joint_step_fraction(
                &s.controller,
                t.lockstep,
                t.hold_periods,
            ),
            event_fallback: st.event_fallback,
            rt: RtSummary {
                requested: plan.is_some(),
                fifo: rt.is_some_and(|r| r.fifo),
                priority: plan.map_or(DEFAULT_PRIORITY, |p: RtPlan| p.priority),
                memory_locked: rt.is_some_and(|r| r.locked),
                plant_cpu: rt.and_then(|r| r.pinned).or(plan.map(|p| p.plant_cpu)),
                controller_cpu: plan.map(|p| p.control_cpu),
                warnings: rt.map(|r| r.warnings.clone()).unwrap_or_default(),
            },
            cycles: st.cycles,
            fresh_commands: st.fresh,
            deadline_misses: st.deadline_misses,
            miss_causes: st.miss_causes,
            late_commands: st.late_commands,
            aged_commands: st.aged_commands,
            held_periods: st.held_periods,
            stopped_periods: st.stopped_periods,
            stop_events: st.stop_events,
            first_stop_at_s: st.first_stop_t,
            max_consecutive_misses: st.max_consecutive_misses,
            longest_command_gap_ns: st.longest_command_gap_ns,
            command_gaps_over_hold: st.command_gaps_over_hold,
            plant_overruns: st.plant_overruns,
            plant_stalls: st.plant_stalls,
            skipped_releases: st.skipped_releases,
            longest_stall_ns: st.longest_stall_ns,
            plant_runqueue_wait_ns: st.runqueue_wait_ns,
            run_window_ns: st.run_window_ns,
            wait_counts: st.wait,
            invalid_messages: st.invalid,
            invalid_total: st.invalid.total(),
            controller_skipped: st.controller_skipped,
            log_rows_dropped: st.log_rows_dropped,
            controller_compute_ns: st.compute.percentiles(),
            round_trip_ns: st.round_trip.percentiles(),
            release_jitter_ns: st.jitter.percentiles(),
            end: end.describe(),
            failures: Vec::new(),
            chaos_stops: Vec::new(),
            link_counts: None,
            hung_controller_threads: match end {
                // The pid is this machine's only over shared memory.
                PlantEnd::ControllerHung { pid, .. } if matches!(cfg.transport, Transport::Iceoryx2) => {
                    crate::sys::threads::threads_of(*pid)
                }
                _ => Vec::new(),
            },
            wall_time_s,
            machine: Machine::now(),
        }
    }
}

/// Writes `dir/latency.json`.
///
/// # Errors
/// Writing failed.
pub fn write_json(dir: &Path, r: &LatencyReport) -> Result<(), RecordError> {
    let path = dir.join("latency.json");
    std::fs::write(&path, serde_json::to_string_pretty(r)? + "\n")
        .map_err(|source| RecordError::Json { path, source })
}

/// Writes `dir/latency.svg`: the three distributions.
///
/// # Errors
/// Drawing failed.
pub fn write_svg(dir: &Path, st: &PlantStats, r: &LatencyReport) -> Result<(), PlotError> {
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
    crate::domain::plots::latency_svg(&dir.join("latency.svg"), &title, &series, deadline)
}
