//! The plant process: publishes measurements, applies commands, owns time, writes the files.

use std::io::IsTerminal;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use companion_core::{Command, Rpr};
use companion_plant::Plant;
use serde::Serialize;

use super::report::{self, LatencyReport};
use super::wait::{self, Idler};
use super::{HilArgs, Timing, WaitMode, EXIT_INTERRUPTED, EXIT_PEER_HUNG, EXIT_PEER_LOST};
use crate::clock::{Clock, MonotonicClock};
use crate::control::{StepReport, JOINTS};
use crate::ipc::{PeerState, PlantEndpoint, Role};
use crate::latency::stats::LatencyHistogram;
use crate::record::{CommandSource, Recorder, Row};
use crate::scenario::Scenario;
use crate::sim::{self, Exchange};
use crate::wire::{
    check_command, decode_status, flags, fnv1a, CommandMsg, MeasurementHeader, MeasurementMsg, WireError,
};

/// The plant's side of the transport, as the loops see it (a fake in tests).
pub trait PlantLink {
    /// Publishes a measurement.
    ///
    /// # Errors
    /// A transport failure.
    fn publish(&mut self, m: &MeasurementMsg) -> Result<()>;
    /// Takes the oldest waiting command.
    ///
    /// # Errors
    /// A transport failure.
    fn try_receive(&mut self) -> Result<Option<CommandMsg>>;
    /// Waits on the transport's event for at most `timeout` (event mode; else returns).
    ///
    /// # Errors
    /// A transport failure.
    fn wait_event(&mut self, timeout: Duration) -> Result<()>;
    /// Whether the controller is alive.
    ///
    /// # Errors
    /// The node list cannot be read.
    fn peer_state(&mut self) -> Result<PeerState>;
}

impl PlantLink for PlantEndpoint {
    #[inline]
    fn publish(&mut self, m: &MeasurementMsg) -> Result<()> {
        self.send(m)
    }
    #[inline]
    fn try_receive(&mut self) -> Result<Option<CommandMsg>> {
        PlantEndpoint::try_receive(self)
    }
    #[inline]
    fn wait_event(&mut self, timeout: Duration) -> Result<()> {
        PlantEndpoint::wait_event(self, timeout)
    }
    fn peer_state(&mut self) -> Result<PeerState> {
        PlantEndpoint::peer_state(self)
    }
}

/// Dropped commands, by reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
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
            WireError::Session | WireError::Scenario => self.session += 1,
            WireError::Future(_) | WireError::Stale(_) => self.future_seq += 1,
            WireError::JointCount(_) => self.joint_count += 1,
            WireError::Status(_) => self.status += 1,
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
    /// Commands that arrived after their deadline (dropped).
    pub late_commands: u64,
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
    /// Periods whose measurement the plant itself published after the deadline.
    pub plant_overruns: u64,
    /// Malformed commands dropped.
    pub invalid: InvalidCounts,
    /// Measurements the controller skipped as superseded (sum of `skipped`).
    pub controller_skipped: u64,
    /// Log rows lost because the writer thread fell behind (0 unless the machine starves it).
    pub log_rows_dropped: u64,
}

impl PlantStats {
    /// Records one received command's timing.
    #[inline]
    fn timing(&mut self, now: u64, c: &CommandMsg) {
        self.round_trip.record(now.saturating_sub(c.plant_time_ns));
        self.compute.record(c.compute_ns);
    }
}

/// Why the plant's run ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PlantEnd {
    /// Every step ran.
    Completed,
    /// SIGINT/SIGTERM: the run ended early, cleanly.
    Interrupted {
        /// The last cycle.
        cycle: u64,
    },
    /// The controller's process died.
    ControllerDied {
        /// Its pid.
        pid: i32,
        /// The cycle at which it was found dead.
        cycle: u64,
        /// Silence before the finding (ns).
        silent_ns: u64,
    },
    /// The controller's node is gone (it exited without waiting for the end of the run).
    ControllerGone {
        /// The cycle.
        cycle: u64,
    },
    /// The controller is alive but has not answered for `--peer-timeout`.
    ControllerHung {
        /// The cycle.
        cycle: u64,
        /// Silence (ns).
        silent_ns: u64,
    },
}

impl PlantEnd {
    /// The process exit code.
    pub fn exit_code(&self) -> u8 {
        match self {
            Self::Completed => 0,
            Self::Interrupted { .. } => EXIT_INTERRUPTED,
            Self::ControllerDied { .. } | Self::ControllerGone { .. } => EXIT_PEER_LOST,
            Self::ControllerHung { .. } => EXIT_PEER_HUNG,
        }
    }

    /// One sentence.
    pub fn describe(&self) -> String {
        #[allow(clippy::cast_precision_loss)]
        let ms = |ns: &u64| *ns as f64 / 1e6;
        match self {
            Self::Completed => "completed".into(),
            Self::Interrupted { cycle } => format!("interrupted at cycle {cycle}"),
            Self::ControllerDied { pid, cycle, silent_ns } => format!(
                "controller process {pid} died: found dead at cycle {cycle}, {:.1} ms after its last command; \
                 robot stopped",
                ms(silent_ns)
            ),
            Self::ControllerGone { cycle } => {
                format!("controller exited before the end of the run (noticed at cycle {cycle}); robot stopped")
            }
            Self::ControllerHung { cycle, silent_ns } => format!(
                "controller alive but silent for {:.0} ms (at cycle {cycle}); robot stopped, run abandoned",
                ms(silent_ns)
            ),
        }
    }
}

/// The hold-then-stop policy for missing commands.
#[derive(Clone, Copy, Debug)]
pub struct HoldPolicy {
    hold_periods: u32,
    consecutive: u32,
    last: Option<StepReport>,
}

/// The report applied while stopped: every velocity zero, no diagnostics.
pub fn stop_report() -> StepReport {
    StepReport {
        command: Command::zero(),
        ep_norm: f64::NAN,
        h_s: f64::NAN,
        psi: f64::NAN,
        saturation: f64::NAN,
        alpha_rate: [f64::NAN; 2],
        error: None,
    }
}

impl HoldPolicy {
    /// Hold for at most `hold_periods` periods.
    pub fn new(hold_periods: u32) -> Self {
        Self { hold_periods, consecutive: 0, last: None }
    }

    /// A fresh command arrived in time.
    #[inline]
    pub fn fresh(&mut self, r: StepReport) -> (StepReport, CommandSource) {
        self.consecutive = 0;
        self.last = Some(r);
        (r, CommandSource::Fresh)
    }

    /// The period's command is missing: hold the last fresh one for `hold_periods` periods,
    /// then stop (also when there never was a fresh one).
    #[inline]
    pub fn missed(&mut self) -> (StepReport, CommandSource) {
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

/// The report a validated command carries (the zero command when the law rejected the step,
/// whatever the message's velocities).
pub fn report_of(c: &CommandMsg) -> StepReport {
    let error = decode_status(c.status).ok().flatten();
    let command = if error.is_some() { Command::zero() } else { c.command::<JOINTS>() };
    StepReport {
        command,
        ep_norm: c.ep_norm,
        h_s: c.h_s,
        psi: c.psi,
        saturation: c.saturation,
        alpha_rate: c.alpha_rate,
        error,
    }
}

/// The ids the plant stamps on its measurements.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ids {
    /// Session.
    pub session: u64,
    /// Scenario hash.
    pub scenario_hash: u64,
}

/// The scenario hash both roles compute: FNV-1a of the controller's specification.
pub fn scenario_hash(s: &Scenario) -> u64 {
    serde_json::to_vec(&s.controller).map_or(0, |b| fnv1a(&b)).max(1)
}

/// Live figures for the progress line (written by the loop with relaxed stores).
#[derive(Debug, Default)]
pub struct Progress {
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

/// Runs the real-time loop over steps `0..=steps`: release at absolute times, publish, wait for
/// the command until the deadline, apply it or the hold/stop policy, log, advance. `sink` gets
/// every row (returns `false` if it could not keep it).
///
/// # Errors
/// A transport failure.
#[allow(clippy::too_many_arguments)]
pub fn run_real_time<C: Clock, L: PlantLink>(
    clock: &C,
    link: &mut L,
    timing: &Timing,
    ids: Ids,
    plant: &mut Plant<Rpr<f64>, JOINTS>,
    steps: u64,
    dt: f64,
    stats: &mut PlantStats,
    progress: &Progress,
    sink: &mut impl FnMut(u64, &Row, bool) -> bool,
) -> Result<PlantEnd> {
    let period = timing.period_ns;
    let mut idler = Idler::new(timing.wait, timing.spin_margin_ns);
    let mut policy = HoldPolicy::new(timing.hold_periods);
    // Step 0 is a handshake: published now, its command awaited up to --peer-timeout (a cold
    // controller's first step, page faults and all, is not a deadline miss). Real time starts
    // when it is answered: release n = start + n·period.
    let mut start = clock.now_ns();
    let mut last_step = steps;
    let mut end = PlantEnd::Completed;
    let mut last_fresh_ns = start;
    let mut last_check_ns = start;
    let mut n: u64 = 0;
    loop {
        let release = start + n * period;
        let meas = plant.measure();
        let mut fl = 0;
        if n == last_step {
            fl |= flags::END_OF_RUN;
        }
        if policy.stopped() {
            fl |= flags::STOPPED;
        }
        let header = MeasurementHeader {
            seq: n,
            flags: fl,
            session: ids.session,
            scenario_hash: ids.scenario_hash,
            plant_time_ns: 0,
            period_ns: period,
            dt,
        };
        let mut msg = MeasurementMsg::new(header, &meas);
        wait::until(clock, timing.wait, release, timing.spin_margin_ns);
        let t_pub = clock.now_ns();
        msg.plant_time_ns = t_pub;
        link.publish(&msg)?;
        let deadline = if n == 0 {
            t_pub + timing.peer_timeout_ns
        } else {
            stats.jitter.record(t_pub - release);
            release + timing.deadline_ns
        };
        if t_pub > deadline {
            stats.plant_overruns += 1;
        }
        // Wait for command n (not once the controller is known to be gone).
        let mut fresh = None;
        idler.reset();
        let peer_lost = matches!(end, PlantEnd::ControllerDied { .. } | PlantEnd::ControllerGone { .. });
        if !peer_lost {
            loop {
                while let Some(c) = link.try_receive()? {
                    let now = clock.now_ns();
                    match check_command::<JOINTS>(&c, ids.session, n) {
                        Ok(()) => {
                            stats.timing(now, &c);
                            stats.controller_skipped += u64::from(c.skipped);
                            fresh = Some(c);
                        }
                        Err(WireError::Stale(_)) => {
                            stats.late_commands += 1;
                            stats.timing(now, &c);
                        }
                        Err(e) => stats.invalid.count(e),
                    }
                }
                if fresh.is_some() || clock.now_ns() >= deadline {
                    break;
                }
                idler.idle(clock, None, deadline, |d| link.wait_event(d))?;
            }
        }
        if n == 0 {
            start = clock.now_ns();
            last_check_ns = start;
        }
        let (report, source) = match fresh {
            Some(c) => {
                stats.fresh += 1;
                last_fresh_ns = clock.now_ns();
                policy.fresh(report_of(&c))
            }
            None => {
                stats.deadline_misses += 1;
                let was_stopped = policy.stopped();
                let r = policy.missed();
                // A stop event is the hold running out on a moving robot (not the start of a
                // run before the first command).
                if policy.stopped() && !was_stopped && policy.has_commanded() {
                    stats.stop_events += 1;
                    stats.first_stop_t.get_or_insert(plant.time());
                }
                stats.max_consecutive_misses =
                    stats.max_consecutive_misses.max(u64::from(policy.consecutive()));
                r
            }
        };
        match source {
            CommandSource::Held => stats.held_periods += 1,
            CommandSource::Stopped => stats.stopped_periods += 1,
            CommandSource::Fresh => {}
        }
        let row = Row { plant: sim::sample(plant), report, source };
        let last = n == last_step;
        if !sink(n, &row, last) {
            stats.log_rows_dropped += 1;
        }
        stats.cycles += 1;
        progress.cycle.store(n + 1, Ordering::Relaxed);
        progress.misses.store(stats.deadline_misses, Ordering::Relaxed);
        progress.stopped.store(policy.stopped(), Ordering::Relaxed);
        if last {
            break;
        }
        plant.advance(&report.command, dt);
        if n % 256 == 255 {
            // A bucket scan (tens of µs) in the slack before the next release.
            progress.p99_ns.store(stats.round_trip.quantile(0.99), Ordering::Relaxed);
        }
        // A silent controller: is it still there? (Degraded state only: a few syscalls.)
        if fresh.is_none() && last_step > n + 1 {
            let now = clock.now_ns();
            let silent = now.saturating_sub(last_fresh_ns);
            if silent >= timing.silence_ns && now - last_check_ns >= timing.silence_ns {
                last_check_ns = now;
                let found = match link.peer_state()? {
                    PeerState::Dead(pid) => {
                        Some(PlantEnd::ControllerDied { pid, cycle: n, silent_ns: silent })
                    }
                    PeerState::Absent => Some(PlantEnd::ControllerGone { cycle: n }),
                    PeerState::Alive(_) if silent >= timing.peer_timeout_ns => {
                        Some(PlantEnd::ControllerHung { cycle: n, silent_ns: silent })
                    }
                    PeerState::Alive(_) => None,
                };
                if let Some(e) = found {
                    end = e;
                    last_step = n + 1;
                }
            }
        }
        if crate::rt::termination_requested() && last_step > n + 1 {
            end = PlantEnd::Interrupted { cycle: n + 1 };
            last_step = n + 1;
        }
        n += 1;
    }
    progress.p99_ns.store(stats.round_trip.quantile(0.99), Ordering::Relaxed);
    Ok(end)
}

/// The controller was lost during a lockstep exchange.
#[derive(Clone, Copy, Debug, thiserror::Error)]
#[error("{}", .0.describe())]
pub struct Lost(pub PlantEnd);

/// The lockstep exchange over iceoryx2: publish, then wait for the answer however long it takes
/// (while the controller is alive and answers within `--peer-timeout`).
#[derive(Debug)]
pub struct LockstepExchange<'a, C: Clock, L: PlantLink> {
    /// The clock.
    pub clock: &'a C,
    /// The transport.
    pub link: &'a mut L,
    /// Timing options.
    pub timing: Timing,
    /// Ids.
    pub ids: Ids,
    /// The last step (its measurement carries the end-of-run flag).
    pub steps: u64,
    /// The step (s).
    pub dt: f64,
    /// Statistics.
    pub stats: &'a mut PlantStats,
    /// Progress figures.
    pub progress: &'a Progress,
}

impl<C: Clock, L: PlantLink> Exchange for LockstepExchange<'_, C, L> {
    fn exchange(
        &mut self,
        n: u64,
        meas: &companion_core::Measurement<f64, JOINTS>,
    ) -> Result<crate::control::StepReport> {
        let mut fl = flags::LOCKSTEP;
        if n == self.steps {
            fl |= flags::END_OF_RUN;
        }
        let header = MeasurementHeader {
            seq: n,
            flags: fl,
            session: self.ids.session,
            scenario_hash: self.ids.scenario_hash,
            plant_time_ns: 0,
            period_ns: 0,
            dt: self.dt,
        };
        let mut msg = MeasurementMsg::new(header, meas);
        let t_pub = self.clock.now_ns();
        msg.plant_time_ns = t_pub;
        self.link.publish(&msg)?;
        self.stats.cycles += 1;
        self.progress.cycle.store(n + 1, Ordering::Relaxed);
        let mut idler = Idler::new(self.timing.wait, self.timing.spin_margin_ns);
        let mut last_check = t_pub;
        loop {
            while let Some(c) = self.link.try_receive()? {
                let now = self.clock.now_ns();
                match check_command::<JOINTS>(&c, self.ids.session, n) {
                    Ok(()) => {
                        self.stats.timing(now, &c);
                        self.stats.fresh += 1;
                        self.stats.controller_skipped += u64::from(c.skipped);
                        return Ok(report_of(&c));
                    }
                    Err(WireError::Stale(_)) => self.stats.late_commands += 1,
                    Err(e) => self.stats.invalid.count(e),
                }
            }
            let now = self.clock.now_ns();
            let silent = now - t_pub;
            if silent >= self.timing.silence_ns && now - last_check >= self.timing.silence_ns {
                last_check = now;
                let lost = match self.link.peer_state()? {
                    PeerState::Dead(pid) => {
                        Some(PlantEnd::ControllerDied { pid, cycle: n, silent_ns: silent })
                    }
                    PeerState::Absent => Some(PlantEnd::ControllerGone { cycle: n }),
                    PeerState::Alive(_) if silent >= self.timing.peer_timeout_ns => {
                        Some(PlantEnd::ControllerHung { cycle: n, silent_ns: silent })
                    }
                    PeerState::Alive(_) => None,
                };
                if let Some(e) = lost {
                    return Err(Lost(e).into());
                }
            }
            if crate::rt::termination_requested() {
                return Err(Lost(PlantEnd::Interrupted { cycle: n }).into());
            }
            idler.idle(self.clock, None, u64::MAX, |d| self.link.wait_event(d))?;
        }
    }
}

/// One row on its way to the CSV writer thread.
#[derive(Clone, Copy, Debug)]
struct LogItem {
    n: u64,
    row: Row,
    last: bool,
}

/// The ring between the loop and the writer: 32768 rows (33 s at 1 kHz), allocated once.
const LOG_RING: usize = 1 << 15;
/// How often the writer thread flushes `timeseries.csv`.
const FLUSH_EVERY: Duration = Duration::from_millis(50);

fn spawn_writer(
    mut recorder: Recorder,
    mut rx: rtrb::Consumer<LogItem>,
    done: Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<Result<Recorder>>> {
    std::thread::Builder::new()
        .name("csv-writer".into())
        .spawn(move || {
            let mut last_flush = Instant::now();
            loop {
                let finishing = done.load(Ordering::Acquire);
                while let Ok(item) = rx.pop() {
                    recorder.record(item.n, &item.row, item.last)?;
                }
                if finishing {
                    recorder.flush()?;
                    return Ok(recorder);
                }
                if last_flush.elapsed() >= FLUSH_EVERY {
                    recorder.flush()?;
                    last_flush = Instant::now();
                }
                std::thread::sleep(Duration::from_millis(5));
            }
        })
        .context("starting the CSV writer thread")
}

fn spawn_progress(progress: Arc<Progress>, steps: u64, dt: f64) -> Option<std::thread::JoinHandle<()>> {
    std::thread::Builder::new()
        .name("progress".into())
        .spawn(move || {
            while !progress.done.load(Ordering::Acquire) {
                std::thread::sleep(Duration::from_millis(250));
                let c = progress.cycle.load(Ordering::Relaxed);
                #[allow(clippy::cast_precision_loss)]
                let t = c as f64 * dt;
                eprint!(
                    "\r  cycle {c:>7}/{}  t {t:6.1} s  misses {:>5}  round trip p99 {:>9}{}   ",
                    steps + 1,
                    progress.misses.load(Ordering::Relaxed),
                    crate::latency::stats::fmt_ns(progress.p99_ns.load(Ordering::Relaxed)),
                    if progress.stopped.load(Ordering::Relaxed) { "  ROBOT STOPPED" } else { "" }
                );
            }
            eprint!("\r{:100}\r", "");
        })
        .ok()
}

/// `companion plant`: the whole plant process.
///
/// # Errors
/// A bad flag, a transport failure, or files that cannot be written.
pub fn run(a: &HilArgs) -> Result<ExitCode> {
    let s = a.scenario()?;
    let timing = a.timing(&s)?;
    let mut plant = sim::build_plant(&s)?;
    let mut ep = PlantEndpoint::plant(&a.name, timing.wait == WaitMode::Event)?;
    let ids = Ids { session: crate::ipc::new_session_id(), scenario_hash: scenario_hash(&s) };
    let dir = a.out.clone();
    let mut recorder = sim::recorder_for(&s, &dir)?;
    let steps = s.steps();
    if !a.child {
        eprintln!(
            "plant: demo '{}' waiting for its controller (companion control --name {})",
            a.name, a.name
        );
    }
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let startup = Duration::from_secs_f64(a.startup_timeout);
    ep.wait_for_peer(startup, || None)?;
    let clock = MonotonicClock;
    let mut stats = PlantStats::default();
    let progress = Arc::new(Progress::default());
    let show_progress = !a.quiet && std::io::stderr().is_terminal();
    let wall = Instant::now();
    let mut rt_report = None;
    let end = if timing.lockstep {
        let pb = if show_progress {
            indicatif::ProgressBar::new(steps + 1)
        } else {
            indicatif::ProgressBar::hidden()
        };
        if let Some(cfg) = a.rt_config(Role::Plant) {
            rt_report = Some(crate::rt::apply(&cfg));
        }
        let mut ex = LockstepExchange {
            clock: &clock,
            link: &mut ep,
            timing,
            ids,
            steps,
            dt: s.dt,
            stats: &mut stats,
            progress: &progress,
        };
        let r = sim::run_loop(&s, &mut plant, &mut ex, &mut recorder, &pb);
        pb.finish_and_clear();
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
        // Helper threads first, so they do not inherit the real-time CPU and priority.
        let (mut tx, rx) = rtrb::RingBuffer::<LogItem>::new(LOG_RING);
        let done = Arc::new(AtomicBool::new(false));
        let writer = spawn_writer(recorder, rx, Arc::clone(&done))?;
        let progress_thread =
            show_progress.then(|| spawn_progress(Arc::clone(&progress), steps, s.dt)).flatten();
        if let Some(cfg) = a.rt_config(Role::Plant) {
            rt_report = Some(crate::rt::apply(&cfg));
        }
        if let Some(r) = &rt_report {
            r.warn("plant");
        }
        let mut sink = |n: u64, row: &Row, last: bool| tx.push(LogItem { n, row: *row, last }).is_ok();
        let r = run_real_time(
            &clock, &mut ep, &timing, ids, &mut plant, steps, s.dt, &mut stats, &progress, &mut sink,
        );
        crate::rt::reset_thread();
        done.store(true, Ordering::Release);
        progress.done.store(true, Ordering::Release);
        if let Some(p) = progress_thread {
            let _ = p.join();
        }
        recorder = writer.join().map_err(|_| anyhow!("the CSV writer thread panicked"))??;
        r?
    };
    if timing.lockstep {
        if let Some(r) = &rt_report {
            r.warn("plant");
        }
    }
    progress.done.store(true, Ordering::Release);
    if matches!(end, PlantEnd::ControllerDied { .. }) {
        ep.cleanup_dead_nodes();
    }
    let wall_s = wall.elapsed().as_secs_f64();
    let summary = recorder.summary.finish(wall_s);
    sim::write_summary(&dir, &s, &summary)?;
    let lat = LatencyReport::new(&s, a, &timing, &stats, rt_report.as_ref(), &end, wall_s);
    report::write_json(&dir, &lat)?;
    if let Err(e) = report::write_svg(&dir, &stats, &lat) {
        eprintln!("warning: latency plot: {e:#}");
    }
    if !a.no_plots {
        let outcome =
            sim::RunOutcome { scenario: s.clone(), summary, rows: std::mem::take(&mut recorder.rows) };
        if let Err(e) = crate::plots::render_run(&dir, &outcome) {
            eprintln!("warning: plots: {e:#}");
        }
        sim::print_table(std::slice::from_ref(&outcome));
    } else {
        let outcome = sim::RunOutcome { scenario: s.clone(), summary, rows: Vec::new() };
        sim::print_table(std::slice::from_ref(&outcome));
    }
    report::print(&lat);
    if end != PlantEnd::Completed {
        eprintln!("plant: {}", end.describe());
    }
    println!("wrote {}", dir.display());
    Ok(ExitCode::from(end.exit_code()))
}

#[cfg(test)]
mod tests {
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
        let mut p = HoldPolicy::new(5);
        assert_eq!(p.missed().1, CommandSource::Stopped);
        assert!(p.stopped());
        let mut p = HoldPolicy::new(0);
        p.fresh(report(1.0));
        assert_eq!(p.missed().1, CommandSource::Stopped);
    }

    #[test]
    fn a_rejected_step_is_applied_as_the_zero_command() {
        let m = MeasurementMsg::new(
            MeasurementHeader { seq: 3, session: 5, ..MeasurementHeader::default() },
            &companion_core::Measurement::<f64, JOINTS> {
                t: 0.0,
                base: companion_core::Pose::new(0.0, 0.0, 0.0),
                steering: 0.0,
                joints: companion_core::nalgebra::SVector::<f64, JOINTS>::new(0.0, 0.35, 0.0),
                target: companion_core::Pose::new(1.0, 0.0, 0.0),
                target_velocity: companion_core::nalgebra::Vector3::zeros(),
            },
        );
        let mut cmd = Command::<f64, JOINTS>::zero();
        cmd.platform.v = 3.0;
        let diag = crate::wire::LoggedDiagnostics {
            ep_norm: f64::NAN,
            h_s: f64::NAN,
            psi: f64::NAN,
            saturation: f64::NAN,
            alpha_rate: [f64::NAN; 2],
        };
        let c = CommandMsg::answer(&m, &cmd, Some(companion_core::StepError::SingularArm), &diag, 0, 0);
        let r = report_of(&c);
        assert_eq!(r.command, Command::zero());
        assert_eq!(r.error, Some(companion_core::StepError::SingularArm));
    }

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
