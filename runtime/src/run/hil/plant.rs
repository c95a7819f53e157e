//! The plant process: publishes measurements, applies commands, owns time, writes the run's
//! files (`timeseries.csv`, `summary.json`, `scenario.json`, `latency.json`, plots).

use std::path::Path;
use std::time::{Duration, Instant};

use companion_core::{Chain, Manipulator, Space, Spatial, SpatialArm};
use companion_plant::Simulated;

use super::chaos::{Agent, ChaosError, Plan};
use super::config::{HilConfig, HilScenario, ReleaseTimer};
use super::end::PlantEnd;
use super::handshake::controller_hash;
use super::messages::Stamp;
use super::plant_loop::{run_real_time, Lockstep, PlantSide};
use super::report::{self, LatencyReport};
use super::stats::{LiveFigures, PlantStats};
use crate::domain::arm::ArmError;
use crate::domain::controller::SpatialControllerError;
use crate::domain::observe::{Causes, Observer};
use crate::domain::plant_setup::PlantSetupError;
use crate::domain::plots::spatial::SpatialFigures;
use crate::domain::plots::PlotError;
use crate::domain::record::error::RecordError;
use crate::domain::record::mcap::{ReplayError, ReplaySummary};
use crate::domain::record::output::OutputError;
use crate::domain::record::recorder::{expected_rows, summary_for, Log};
use crate::domain::record::verdict::{deadline_failures, DeadlineFigures};
use crate::domain::record::{
    write_summary, Failure, LogItem, OutputDir, RecordWriter, Recorder, Replay, Row, RowSink, RunOutcome,
    Summary, SummaryAccumulator, Task,
};
use crate::domain::scenario::Scenario;
use crate::run::robot::Robot;
use crate::run::sim::{self, LoopEnd, LoopError};
use crate::run::spatial::{self, SpatialRunError, SpatialScenario};
use crate::sys::clock::ReleaseClock;
use crate::sys::lock::NameLock;
use crate::sys::lock::{DemoName, LockError, NameInUse, Role};
use crate::transport::error::{OpenError, StartError};
use crate::transport::link::Link as _;
use crate::transport::wire::target::WireSpace;
use crate::transport::wire::{canonical, flags, platform};
use crate::transport::{self, PlantEndpoint};

/// The ring between the loop and the writer: 32768 rows (33 s at 1 kHz; 0.5 kB each with a
/// spatial arm of 6 joints), allocated once.
const LOG_RING: usize = 1 << 15;
/// How often the writer thread flushes `timeseries.csv`.
const FLUSH_EVERY: Duration = Duration::from_millis(50);

/// Why the plant's role could not be taken, or its run failed (its ends, a lost controller
/// among them, are [`PlantEnd`]s).
#[derive(Debug, thiserror::Error)]
pub enum PlantRunError {
    /// The plant's role of the demo's name cannot be taken.
    #[error(transparent)]
    Lock(#[from] LockError),
    /// `--child`, but the parent does not hold the plant's role.
    #[error("--child: the plant's role of demo '{name}' is not held by the parent process ({parent})")]
    NotParent {
        /// The demo's name.
        name: String,
        /// The parent's pid.
        parent: i32,
    },
    /// The chaos plan or its thread.
    #[error(transparent)]
    Chaos(#[from] ChaosError),
    /// The arm cannot be built.
    #[error(transparent)]
    Arm(#[from] ArmError),
    /// The spatial law cannot be built.
    #[error(transparent)]
    Controller(#[from] SpatialControllerError),
    /// The planar plant cannot be built.
    #[error(transparent)]
    Setup(#[from] PlantSetupError),
    /// The spatial plant cannot be built, or its lockstep run or files failed.
    #[error(transparent)]
    Spatial(#[from] SpatialRunError),
    /// The transport cannot be opened.
    #[error(transparent)]
    Open(#[from] OpenError),
    /// The controller did not join.
    #[error(transparent)]
    Start(#[from] StartError),
    /// The output folder cannot be used.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// The run's records cannot be written.
    #[error(transparent)]
    Record(#[from] RecordError),
    /// The replay file (`--mcap`) failed.
    #[error(transparent)]
    Replay(#[from] ReplayError),
    /// The loop failed: the transport, or a step the plant refused.
    #[error(transparent)]
    Loop(#[from] LoopError),
}

impl PlantRunError {
    /// The demo found running, if that is the error (the command line's exit code 5).
    pub fn name_in_use(&self) -> Option<&NameInUse> {
        match self {
            Self::Lock(e) => e.name_in_use(),
            Self::Open(e) => e.cause.name_in_use(),
            Self::Start(e) => e.name_in_use(),
            _ => None,
        }
    }
}

/// What a plant run produced.
#[derive(Debug)]
pub struct PlantOutcome {
    /// How it ended.
    pub end: PlantEnd,
    /// The run's summary (`summary.json`, with its failures), of either arm.
    pub summary: Summary,
    /// `latency.json` (with the silent controller's threads, if it went silent).
    pub latency: LatencyReport,
    /// The `--mcap` replay file, finished.
    pub replay: Option<ReplaySummary>,
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
    /// [`crate::sys::lock::NameInUse`], or a child whose parent does not hold the role.
    pub fn acquire(name: &DemoName, child: bool) -> Result<Self, PlantRunError> {
        if !child {
            return Ok(Self::Own(NameLock::acquire(name, Role::Plant)?));
        }
        let parent = crate::sys::process::parent_pid();
        match NameLock::holder(name, Role::Plant) {
            Ok(pid) if pid == parent => Ok(Self::Parent),
            _ => Err(PlantRunError::NotParent { name: name.to_string(), parent }),
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
    s: &HilScenario,
    live: &LiveFigures,
    observer: &dyn Observer,
    _lock: &PlantLock,
) -> Result<PlantOutcome, PlantRunError> {
    match s {
        HilScenario::Planar(s) => run_planar(cfg, s, live, observer),
        HilScenario::Spatial(ss) => match ss.arm.joints() {
            6 => run_spatial::<6>(cfg, ss, live, observer),
            7 => run_spatial::<7>(cfg, ss, live, observer),
            8 => run_spatial::<8>(cfg, ss, live, observer),
            n => Err(ArmError::JointCount { found: n }.into()),
        },
    }
}

/// The transport open and the run's folder prepared, the controller not yet joined.
struct Opened {
    ep: PlantEndpoint,
    stamp: Stamp,
    out: OutputDir,
}

/// Opens the plant's transport for the scenario `s` (its hash) and the arm `arm_hash`, and
/// prepares `cfg.out`.
fn open(cfg: &HilConfig, s: &Scenario, arm_hash: u64) -> Result<Opened, PlantRunError> {
    let timing = cfg.timing;
    let ep: PlantEndpoint = transport::open(
        &cfg.transport,
        &cfg.name,
        Role::Plant,
        timing.wait.uses_events(),
        Duration::from_nanos(timing.peer_timeout_ns),
    )?;
    let mut announced = if timing.lockstep { flags::LOCKSTEP } else { 0 };
    if ep.notifies() {
        announced |= flags::NOTIFIES;
    }
    let stamp = Stamp {
        session: crate::transport::ipc::new_session_id(),
        scenario_hash: controller_hash(&s.controller),
        arm_hash,
        period_ns: timing.period_ns,
        dt: s.dt,
        flags: announced,
        platform: platform::code(s.controller.platform),
        hold_periods: timing.hold_periods,
    };
    let out = OutputDir::prepare(&cfg.out)?;
    Ok(Opened { ep, stamp, out })
}

impl Opened {
    /// Makes the `--mcap` replay file (with `create`: a path that cannot be written stops the
    /// plant here), then waits for the controller to join; if either fails, takes away what
    /// was made (`discard` for the replay) and returns the error.
    fn join<R>(
        self,
        cfg: &HilConfig,
        observer: &dyn Observer,
        create: impl FnOnce(&std::path::Path) -> Result<R, ReplayError>,
        discard: impl FnOnce(R),
    ) -> Result<(Self, Option<R>), PlantRunError> {
        let replay = match cfg.mcap.as_deref().map(create).transpose() {
            Ok(r) => r,
            Err(e) => {
                self.out.discard();
                return Err(e.into());
            }
        };
        if let Err(e) = self.wait_for_controller(cfg, observer) {
            if let Some(r) = replay {
                discard(r);
            }
            self.out.discard();
            return Err(e.into());
        }
        Ok((self, replay))
    }

    /// Waits for the controller to join.
    fn wait_for_controller(&self, cfg: &HilConfig, observer: &dyn Observer) -> Result<(), StartError> {
        observer.note(&format!(
            "plant: demo '{}' waiting for its controller (companion control --name {}) over {}; scenario hash \
             {:#018x}, arm {}",
            cfg.name,
            cfg.name,
            cfg.transport.describe(),
            self.stamp.scenario_hash,
            crate::transport::wire::canonical::describe_arm(self.stamp.arm_hash)
        ));
        // Peers refused on the way (their certificate, their name) are named as they come.
        self.ep.wait_for_peer(cfg.startup_timeout, || {
            for r in self.ep.take_refusals() {
                observer.warn(&format!("plant: {r}"));
            }
            None
        })
    }
}

/// A plant run after its loop, as its files describe it: what it was asked (the
/// configuration, the scenario), where it writes, what the loop counted and how it ended,
/// and whom it tells. What every step from the loop's end to the files reads.
struct RunContext<'a> {
    cfg: &'a HilConfig,
    s: &'a Scenario,
    dir: &'a std::path::Path,
    observer: &'a dyn Observer,
    stats: &'a PlantStats,
    rt: Option<&'a crate::sys::rt::RtReport>,
    end: PlantEnd,
    /// The run's wall time (s).
    wall_s: f64,
}

impl RunContext<'_> {
    /// What `summary.json` records of the link.
    fn link_record(&self) -> crate::domain::record::summary::LinkRecord {
        crate::domain::record::summary::LinkRecord {
            transport: self.cfg.transport.describe(),
            insecure: self.cfg.transport.insecure(),
        }
    }

    /// The real-time failures of a run that ended as it should (a lost controller stops the
    /// robot by design, its end says so; a chaos run stops it on purpose, its own check
    /// applies).
    fn real_time_failures(&self) -> Vec<Failure> {
        let (cfg, stats) = (self.cfg, self.stats);
        let judged = matches!(self.end, PlantEnd::Completed | PlantEnd::Interrupted { .. });
        if cfg.timing.lockstep || !judged || cfg.chaos.is_some() {
            return Vec::new();
        }
        let figures = DeadlineFigures {
            cycles: stats.cycles,
            deadline_misses: stats.deadline_misses,
            stop_events: stats.stop_events,
            stopped_periods: stats.stopped_periods,
        };
        deadline_failures(&figures, stats.first_stop_t, cfg.acceptance.max_miss_fraction)
    }

    /// Writes `latency.json` (and its plot unless `--no-plots`) with the run's `failures`,
    /// the chaos agent's stops and the transport's counts.
    ///
    /// # Errors
    /// `latency.json` cannot be written.
    fn write_latency(
        &self,
        failures: &[Failure],
        chaos_stops: Vec<super::chaos::DoneStop>,
        link_counts: Option<crate::transport::link::LinkCounts>,
    ) -> Result<LatencyReport, RecordError> {
        let mut latency = LatencyReport::new(self.s, self.cfg, self.stats, self.rt, &self.end, self.wall_s);
        latency.failures = failures.to_vec();
        latency.chaos_stops = chaos_stops;
        latency.link_counts = link_counts;
        report::write_json(self.dir, &latency)?;
        if !self.cfg.no_plots {
            if let Err(e) = report::write_svg(self.dir, self.stats, &latency) {
                self.observer.warn(&format!("latency plot: {}", Causes(&e)));
            }
        }
        Ok(latency)
    }
}

/// `--chaos`: the thread by which this process stops the controller (its parent) on the
/// plan's schedule, started before the loop takes a real-time priority.
fn chaos_agent(plan: Option<Plan>, cfg: &HilConfig) -> Result<Option<Agent>, ChaosError> {
    match (plan, cfg.chaos) {
        (Some(p), Some(c)) => {
            Agent::spawn(p.stops_by(Role::Plant), crate::sys::process::parent_pid(), c.epoch_ns).map(Some)
        }
        _ => Ok(None),
    }
}

/// The real-time setup of the plant's loop thread, if asked for (its warning to `observer`):
/// `--rt`'s, or `--release-timer fifo`'s `SCHED_FIFO` alone.
fn apply_rt(cfg: &HilConfig, observer: &dyn Observer) -> Option<crate::sys::rt::RtReport> {
    let rt = cfg.rt_config(Role::Plant).or_else(|| {
        (cfg.timing.release == ReleaseTimer::Fifo).then_some(crate::sys::rt::RtConfig {
            priority: super::report::DEFAULT_PRIORITY,
            cpu: None,
            lock_memory: false,
            prefault_stack: 0,
            inherited: false,
        })
    })?;
    let r = crate::sys::rt::apply(&rt);
    if let Some(w) = r.warning("plant") {
        observer.warn(&w);
    }
    Some(r)
}

/// The plant's clock: its sleeps on a timerfd with `--release-timer timerfd` (a warning and
/// `clock_nanosleep` if none can be made).
fn release_clock(timing: &super::config::Timing, observer: &dyn Observer) -> ReleaseClock {
    if timing.release != ReleaseTimer::Timerfd {
        return ReleaseClock::new(None);
    }
    match crate::sys::rt::TimerFd::new() {
        Ok(t) => ReleaseClock::new(Some(t)),
        Err(e) => {
            observer.warn(&format!("plant: no timerfd ({e}); sleeping with clock_nanosleep"));
            ReleaseClock::new(None)
        }
    }
}

/// After the loop: the transport's warnings, a dead controller's shared memory cleaned.
fn after_loop(ep: &PlantEndpoint, stats: &PlantStats, end: &PlantEnd, observer: &dyn Observer) {
    let dropped = ep.transport_malformed();
    if dropped > 0 {
        observer.warn(&format!("plant: {dropped} messages of the wrong size dropped by the transport"));
    }
    // Peers refused while the run went on (a rogue, a flood of connections): never served.
    if let Some(last) = ep.last_refusal() {
        observer.warn(&format!("plant: {} connection(s) refused in all; the last: {last}", ep.refusals()));
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
}

/// What the plant's run of one arm is built from, before anything is written: its plant and
/// `r*_ed`, its chain (the replay draws it; the paper's arm as `Chain::rpr()`), its arm hash
/// and its summary.
struct Arm<P: Simulated<N>, const N: usize> {
    plant: P,
    star: <P::Space as Space<f64>>::Pose,
    chain: Chain<f64, N>,
    arm_hash: u64,
    summary: SummaryAccumulator,
}

/// The plant of the paper's arm: [`run_arm`] with its plant, its `scenario.json` and the
/// paper's figures.
fn run_planar(
    cfg: &HilConfig,
    s: &Scenario,
    live: &LiveFigures,
    observer: &dyn Observer,
) -> Result<PlantOutcome, PlantRunError> {
    let arm = Arm {
        plant: sim::build_plant(s)?,
        star: s.controller.params::<f64>().primary.target_in_effector,
        chain: Chain::rpr(),
        arm_hash: super::handshake::arm_hash(),
        summary: summary_for(s),
    };
    let files = |dir: &Path, summary: &Summary| write_summary(dir, s, summary);
    let plots = |dir: &Path, summary: &Summary, rows: Vec<Row>| {
        let run = RunOutcome { scenario: s.clone(), summary: summary.clone(), rows };
        crate::domain::plots::render_run(dir, &run)
    };
    run_arm(cfg, s, arm, live, observer, files, plots)
}

/// The plant of a spatial arm of `N` joints (§5): the spatial plant of `companion sim --arm`,
/// its `scenario.json` and figures.
fn run_spatial<const N: usize>(
    cfg: &HilConfig,
    ss: &SpatialScenario,
    live: &LiveFigures,
    observer: &dyn Observer,
) -> Result<PlantOutcome, PlantRunError>
where
    SpatialArm<f64, N>: Manipulator<f64, N, Space = Spatial>,
    SpatialArm<f32, N>: Manipulator<f32, N, Space = Spatial>,
{
    let chain = ss.arm.chain::<f64, N>()?;
    let star = spatial::target_in_effector::<N>(ss)?;
    let arm = Arm {
        plant: spatial::build_plant(ss, &chain, &star)?,
        star,
        chain,
        arm_hash: canonical::arm_hash(&chain),
        summary: spatial::summary_for(ss, &chain),
    };
    let files = |dir: &Path, summary: &Summary| spatial::write_summary_files(ss, summary, &star, dir);
    let plots = |dir: &Path, summary: &Summary, rows: Vec<Row<Spatial, N>>| {
        let figures = SpatialFigures { name: &ss.name, rows: &rows, summary, chain: &chain };
        crate::domain::plots::spatial::render(dir, &figures)
    };
    run_arm(cfg, &ss.base, arm, live, observer, files, plots)
}

/// The plant of either arm: waits for the controller, runs the loop (real time or lockstep)
/// on `arm`'s robot, records its rows (the CSV and, with `--mcap`, the replay, by a thread of
/// their own in real time), and writes the run's files: `files` writes `summary.json` and
/// `scenario.json`, `plots` the figures (unless `--no-plots`).
fn run_arm<P: Simulated<N, Space: Task + WireSpace>, const N: usize>(
    cfg: &HilConfig,
    s: &Scenario,
    arm: Arm<P, N>,
    live: &LiveFigures,
    observer: &dyn Observer,
    files: impl FnOnce(&Path, &Summary) -> Result<(), RecordError>,
    plots: impl FnOnce(&Path, &Summary, Vec<Row<P::Space, N>>) -> Result<(), PlotError>,
) -> Result<PlantOutcome, PlantRunError> {
    let timing = cfg.timing;
    let Arm { mut plant, star, chain, arm_hash, summary } = arm;
    let plan = cfg.chaos.map(|c| Plan::new(c.seed, s.steps(), &timing)).transpose()?;
    let opened = open(cfg, s, arm_hash)?;
    let kind = s.controller.platform;
    let (opened, replay) =
        opened.join(cfg, observer, |p| Replay::<P::Space, N>::create(p, kind, chain), Replay::discard)?;
    let steps = s.steps();
    let Opened { mut ep, stamp, out } = opened;
    let dir = out.path();
    let log = Log::<P::Space, N>::create(dir, kind, s.log_every, expected_rows(s))?.with_replay(replay);
    let mut recorder = Recorder { log, summary };
    let agent = chaos_agent(plan, cfg)?;
    let clock = release_clock(&timing, observer);
    let mut stats = PlantStats::default();
    let wall = Instant::now();
    let mut robot = Robot { plant: &mut plant, target_in_effector: star };
    let side =
        PlantSide { clock: &clock, link: &mut ep, timing, stamp, stats: &mut stats, live, last_sent: None };
    let rt_report;
    let end = if timing.lockstep {
        // (Its warning after the loop: the lockstep progress bar is drawn meanwhile.)
        rt_report = cfg.rt_config(Role::Plant).map(|rt| crate::sys::rt::apply(&rt));
        let mut ex = Lockstep { side, steps, delay: s.delay };
        let r = sim::run_loop(s, &mut robot, &mut ex, &mut recorder, observer);
        crate::sys::rt::reset_thread();
        let end = match r? {
            LoopEnd::Completed => PlantEnd::Completed,
            LoopEnd::Interrupted { last } => PlantEnd::Interrupted { cycle: last },
            LoopEnd::Ended(end) => end,
        };
        recorder.flush()?;
        if let Some(w) = rt_report.as_ref().and_then(|r| r.warning("plant")) {
            observer.warn(&w);
        }
        end
    } else {
        // The writer thread first, so that it does not inherit the real-time CPU and priority.
        let mut writer = RecordWriter::spawn(recorder, LOG_RING, FLUSH_EVERY)?;
        rt_report = apply_rt(cfg, observer);
        let mut sink =
            |n: u64, row: &Row<P::Space, N>, last: bool| writer.try_push(LogItem { n, row: *row, last });
        let mut side = side;
        let r = run_real_time(&mut side, &mut robot, steps, &mut sink);
        crate::sys::rt::reset_thread();
        live.finish();
        recorder = writer.finish()?;
        r?
    };
    let replay = recorder.log.finish_replay()?;
    let chaos_stops = agent.map(Agent::finish).unwrap_or_default();
    live.finish();
    after_loop(&ep, &stats, &end, observer);
    let wall_s = wall.elapsed().as_secs_f64();
    let ctx = RunContext { cfg, s, dir, observer, stats: &stats, rt: rt_report.as_ref(), end, wall_s };
    let mut summary = recorder.summary.finish(wall_s);
    summary.judge(end != PlantEnd::Completed, cfg.acceptance.max_rejected);
    for f in ctx.real_time_failures() {
        summary.fail(f);
    }
    summary.link = Some(ctx.link_record());
    files(dir, &summary)?;
    let latency = ctx.write_latency(&summary.failures, chaos_stops, ep.link_counts())?;
    if !cfg.no_plots {
        if let Err(e) = plots(dir, &summary, std::mem::take(&mut recorder.log.rows)) {
            observer.warn(&format!("plots: {}", Causes(&e)));
        }
    }
    Ok(PlantOutcome { end, summary, latency, replay })
}
