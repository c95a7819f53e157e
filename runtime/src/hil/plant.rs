//! The plant process: publishes measurements, applies commands, owns time, writes the run's
//! files (`timeseries.csv`, `summary.json`, `scenario.json`, `latency.json`, plots).

use std::time::{Duration, Instant};

use anyhow::Result;

use super::config::{HilConfig, WaitMode};
use super::end::PlantEnd;
use super::handshake::controller_hash;
use super::messages::Stamp;
use super::plant_loop::{run_real_time, Lockstep, Lost, PlantSide};
use super::report::{self, LatencyReport};
use super::stats::{LiveFigures, PlantStats};
use crate::clock::MonotonicClock;
use crate::ipc::Role;
use crate::link::Link as _;
use crate::observe::Observer;
use crate::record::{write_summary, LogItem, RecordWriter, Recorder, Row, RowSink, RunOutcome};
use crate::scenario::Scenario;
use crate::sim;
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
    /// The run's summary and logged rows (the rows only when plots were drawn).
    pub run: RunOutcome,
    /// `latency.json`.
    pub latency: LatencyReport,
}

/// The plant role: waits for the controller, runs the loop (real time or lockstep), writes
/// the files into `cfg.out`. `live` is updated for a progress line; `observer` gets the
/// lockstep progress, notes and warnings.
///
/// # Errors
/// A transport failure, or files that cannot be written.
pub fn run(
    cfg: &HilConfig,
    s: &Scenario,
    live: &LiveFigures,
    observer: &dyn Observer,
) -> Result<PlantOutcome> {
    let timing = cfg.timing;
    let mut plant = sim::build_plant(s)?;
    let target_in_effector = s.controller.params::<f64>().primary.target_in_effector;
    let mut ep: PlantEndpoint =
        transport::open(&cfg.transport, &cfg.name, Role::Plant, timing.wait == WaitMode::Event)?;
    let mut announced = if timing.lockstep { flags::LOCKSTEP } else { 0 };
    if ep.notifies() {
        announced |= flags::NOTIFIES;
    }
    let stamp = Stamp {
        session: crate::ipc::new_session_id(),
        scenario_hash: controller_hash(&s.controller),
        period_ns: timing.period_ns,
        dt: s.dt,
        flags: announced,
        platform: platform::code(s.controller.platform),
        hold_periods: timing.hold_periods,
    };
    let dir = &cfg.out;
    let mut recorder = Recorder::for_scenario(s, dir)?;
    let steps = s.steps();
    observer.note(&format!(
        "plant: demo '{}' waiting for its controller (companion control --name {}) over {}; scenario hash {:#018x}",
        cfg.name,
        cfg.name,
        cfg.transport.describe(),
        stamp.scenario_hash
    ));
    ep.wait_for_peer(cfg.startup_timeout, || None)?;
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
            Ok(()) => PlantEnd::Completed,
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
    let summary = recorder.summary.finish(wall_s);
    write_summary(dir, s, &summary)?;
    let latency = LatencyReport::new(s, cfg, &stats, rt_report.as_ref(), &end, wall_s);
    report::write_json(dir, &latency)?;
    if let Err(e) = report::write_svg(dir, &stats, &latency) {
        observer.warn(&format!("latency plot: {e:#}"));
    }
    let rows = if cfg.no_plots { Vec::new() } else { std::mem::take(&mut recorder.log.rows) };
    let run = RunOutcome { scenario: s.clone(), summary, rows };
    if !cfg.no_plots {
        if let Err(e) = crate::plots::render_run(dir, &run) {
            observer.warn(&format!("plots: {e:#}"));
        }
    }
    Ok(PlantOutcome { end, run, latency })
}
