//! The plant process: publishes measurements, applies commands, owns time, writes the run's
//! files (`timeseries.csv`, `summary.json`, `scenario.json`, `latency.json`, plots).

use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};

use super::chaos::{Agent, Plan};
use super::config::HilConfig;
use super::end::PlantEnd;
use super::handshake::controller_hash;
use super::messages::Stamp;
use super::plant_loop::{run_real_time, Lockstep, Lost, PlantSide};
use super::report::{self, LatencyReport};
use super::stats::{LiveFigures, PlantStats};
use crate::clock::MonotonicClock;
use crate::ipc::Role;
use crate::link::Link as _;
use crate::lock::NameLock;
use crate::observe::Observer;
use crate::record::verdict::{deadline_failures, rejection_failure, DeadlineFigures};
use crate::record::{
    write_summary, LogItem, OutputDir, PlanarReplay, RecordWriter, Recorder, Row, RowSink, RunOutcome,
};
use crate::scenario::Scenario;
use crate::sim::{self, LoopEnd};
use crate::transport::{self, PlantEndpoint};
use crate::wire::{flags, platform};

/// The ring between the loop and the writer: 32768 rows (33 s at 1 kHz), allocated once.
const LOG_RING: usize = 1 << 15;
/// How often the writer thread flushes `timeseries.csv`.
const FLUSH_EVERY: Duration = Duration::from_millis(50);

/// What a plant run produced.
#[derive(Debug)]
pub struct PlantOutcome {
    /// How it ended.
    pub end: PlantEnd,
    /// The run's summary (with its failures) and logged rows (the rows only when plots were
    /// drawn).
    pub run: RunOutcome,
    /// `latency.json`.
    pub latency: LatencyReport,
}

/// Who holds the plant's role of the demo's name.
#[derive(Debug)]
pub enum PlantLock {
    /// This process (`companion plant`).
    Own(NameLock),
    /// The parent process (`companion hil` started this plant and holds both roles).
    Parent,
}

impl PlantLock {
    /// The plant's role of `name`: taken by this process, or (`child`) checked to be held by
    /// the parent that started it.
    ///
    /// # Errors
    /// [`crate::ipc::NameInUse`], or a child whose parent does not hold the role.
    pub fn acquire(name: &str, child: bool) -> Result<Self> {
        if !child {
            return Ok(Self::Own(NameLock::acquire(name, Role::Plant)?));
        }
        let parent = crate::process::parent_pid();
        match NameLock::holder(name, Role::Plant) {
            Ok(pid) if pid == parent => Ok(Self::Parent),
            _ => Err(anyhow!(
                "--child: the plant's role of demo '{name}' is not held by the parent process ({parent})"
            )),
        }
    }
}

/// The plant role: waits for the controller, runs the loop (real time or lockstep), writes
/// the files into `cfg.out`. `live` is updated for a progress line; `observer` gets the
/// lockstep progress, notes and warnings. `_lock`: the demo's plant role is this process's.
///
/// Nothing is written into `cfg.out` unless the controller joins (a folder made for the run
/// is taken away again).
///
/// # Errors
/// A transport failure, or files that cannot be written.
pub fn run(
    cfg: &HilConfig,
    s: &Scenario,
    live: &LiveFigures,
    observer: &dyn Observer,
    _lock: &PlantLock,
) -> Result<PlantOutcome> {
    let timing = cfg.timing;
    let mut plant = sim::build_plant(s)?;
    let target_in_effector = s.controller.params::<f64>().primary.target_in_effector;
    let plan = cfg.chaos.map(|c| Plan::new(c.seed, s.steps(), &timing)).transpose()?;
    let mut ep: PlantEndpoint =
        transport::open(&cfg.transport, &cfg.name, Role::Plant, timing.wait.uses_events())?;
    let mut announced = if timing.lockstep { flags::LOCKSTEP } else { 0 };
    if ep.notifies() {
        announced |= flags::NOTIFIES;
    }
    let stamp = Stamp {
        session: crate::ipc::new_session_id(),
        scenario_hash: controller_hash(&s.controller),
        arm_hash: super::handshake::arm_hash(),
        period_ns: timing.period_ns,
        dt: s.dt,
        flags: announced,
        platform: platform::code(s.controller.platform),
        hold_periods: timing.hold_periods,
    };
    let out = OutputDir::prepare(&cfg.out)?;
    // `--mcap`: made now, so that a path that cannot be written stops the plant here.
    let replay = match cfg.mcap.as_deref().map(|p| PlanarReplay::create(p, s)).transpose() {
        Ok(r) => r,
        Err(e) => {
            out.discard();
            return Err(e);
        }
    };
    let steps = s.steps();
    observer.note(&format!(
        "plant: demo '{}' waiting for its controller (companion control --name {}) over {}; scenario hash {:#018x}",
        cfg.name,
        cfg.name,
        cfg.transport.describe(),
        stamp.scenario_hash
    ));
    if let Err(e) = ep.wait_for_peer(cfg.startup_timeout, || None) {
        if let Some(r) = replay {
            r.discard();
        }
        out.discard();
        return Err(e);
    }
    let dir = out.path();
    let mut recorder = Recorder::for_scenario(s, dir)?;
    recorder.log = recorder.log.with_replay(replay);
    // `--chaos`: this process stops the controller (its parent) on the plan's schedule; the
    // thread starts before the loop takes a real-time priority.
    let agent = match (plan, cfg.chaos) {
        (Some(p), Some(c)) => {
            Some(Agent::spawn(p.stops_by(Role::Plant), crate::process::parent_pid(), c.epoch_ns)?)
        }
        _ => None,
    };
    let clock = MonotonicClock;
    let mut stats = PlantStats::default();
    let wall = Instant::now();
    let mut rt_report = None;
    let end = if timing.lockstep {
        if let Some(rt) = cfg.rt_config(Role::Plant) {
            rt_report = Some(crate::rt::apply(&rt));
        }
        let side = PlantSide {
            clock: &clock,
            link: &mut ep,
            timing,
            stamp,
            stats: &mut stats,
            live,
            target_in_effector,
            last_sent: None,
        };
        let mut ex = Lockstep { side, steps, delay: s.delay };
        let r = sim::run_loop(s, &mut plant, &mut ex, &mut recorder, observer);
        let end = match r {
            Ok(LoopEnd::Completed) => PlantEnd::Completed,
            Ok(LoopEnd::Interrupted { last }) => PlantEnd::Interrupted { cycle: last },
            Err(e) => match e.downcast_ref::<Lost>() {
                Some(Lost(end)) => *end,
                None => return Err(e),
            },
        };
        recorder.flush()?;
        end
    } else {
        // The writer thread first, so that it does not inherit the real-time CPU and priority.
        let mut writer = RecordWriter::spawn(recorder, LOG_RING, FLUSH_EVERY)?;
        if let Some(rt) = cfg.rt_config(Role::Plant) {
            let r = crate::rt::apply(&rt);
            if let Some(w) = r.warning("plant") {
                observer.warn(&w);
            }
            rt_report = Some(r);
        }
        let mut sink = |n: u64, row: &Row, last: bool| writer.try_push(LogItem { n, row: *row, last });
        let mut side = PlantSide {
            clock: &clock,
            link: &mut ep,
            timing,
            stamp,
            stats: &mut stats,
            live,
            target_in_effector,
            last_sent: None,
        };
        let r = run_real_time(&mut side, &mut plant, steps, &mut sink);
        crate::rt::reset_thread();
        live.finish();
        recorder = writer.finish()?;
        r?
    };
    if let Some(r) = recorder.log.finish_replay()? {
        observer.note(&format!("plant: wrote {} ({} frames, {} bytes)", r.path.display(), r.frames, r.bytes));
    }
    let chaos_stops = agent.map(Agent::finish).unwrap_or_default();
    if timing.lockstep {
        if let Some(r) = &rt_report {
            if let Some(w) = r.warning("plant") {
                observer.warn(&w);
            }
        }
    }
    live.finish();
    let dropped = ep.transport_malformed();
    if dropped > 0 {
        observer.warn(&format!("plant: {dropped} messages of the wrong size dropped by the transport"));
    }
    if stats.event_fallback {
        observer.warn(
            "the controller does not notify command-ready (flag NOTIFIES clear): the plant polled (hybrid) \
             instead of waiting on the event",
        );
    }
    if matches!(end, PlantEnd::ControllerDied { .. }) {
        ep.cleanup_dead_nodes();
    }
    let wall_s = wall.elapsed().as_secs_f64();
    let mut summary = recorder.summary.finish(wall_s);
    summary.ended_early = end != PlantEnd::Completed;
    let a = cfg.acceptance;
    summary.failures.extend(rejection_failure(
        &summary.rejections,
        summary.steps,
        summary.first_rejection_at_s,
        a.max_rejected,
    ));
    // A lost controller stops the robot by design (its end says so), and a chaos run stops it
    // on purpose (its own check applies).
    let judged = matches!(end, PlantEnd::Completed | PlantEnd::Interrupted { .. });
    if !timing.lockstep && judged && cfg.chaos.is_none() {
        let figures = DeadlineFigures {
            cycles: stats.cycles,
            deadline_misses: stats.deadline_misses,
            stop_events: stats.stop_events,
            stopped_periods: stats.stopped_periods,
        };
        summary.failures.extend(deadline_failures(&figures, stats.first_stop_t, a.max_miss_fraction));
    }
    write_summary(dir, s, &summary)?;
    let mut latency = LatencyReport::new(s, cfg, &stats, rt_report.as_ref(), &end, wall_s);
    latency.chaos_stops = chaos_stops;
    latency.failures.clone_from(&summary.failures);
    report::write_json(dir, &latency)?;
    let rows = if cfg.no_plots { Vec::new() } else { std::mem::take(&mut recorder.log.rows) };
    let run = RunOutcome { scenario: s.clone(), summary, rows };
    if !cfg.no_plots {
        if let Err(e) = report::write_svg(dir, &stats, &latency) {
            observer.warn(&format!("latency plot: {e:#}"));
        }
        if let Err(e) = crate::plots::render_run(dir, &run) {
            observer.warn(&format!("plots: {e:#}"));
        }
    }
    Ok(PlantOutcome { end, run, latency })
}
