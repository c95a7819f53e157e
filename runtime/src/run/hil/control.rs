//! The controller process: answers each measurement with one command; as `companion hil` it
//! also watches the plant process it started and, when the plant dies under it, keeps what
//! the plant wrote (`timeseries.csv` trimmed to its last complete line) and writes
//! `fault.json`. With `--chaos` it injects the plan's command faults and plant stops, and
//! checks the plant's counts against them (`chaos.json`).

use std::path::{Path, PathBuf};
use std::process::ExitStatus;
use std::time::Duration;

use serde::Serialize;

use super::chaos::{self, Agent, ChaosError, Observed, Plan};
use super::config::{HilConfig, HilScenario};
use super::end::ControlEnd;
use super::fault::{Corruption, Injected, Injecting};
use super::serve::{serve_scenario, ServeError, ServeOptions};
use super::stats::ControlStats;
use crate::domain::histogram::fmt_ns;
use crate::domain::observe::{Causes, Observer};
use crate::domain::scenario::Scenario;
use crate::sys::clock::MonotonicClock;
use crate::sys::lock::NameLock;
use crate::sys::lock::{NameInUse, Role};
use crate::sys::process::{exit_text, send_signal, ChildGuard, Signal};
use crate::sys::signals::termination_requested;
use crate::sys::threads::{threads_of, ThreadState};
use crate::transport::error::{OpenError, StartError};
use crate::transport::link::LinkCounts;
use crate::transport::{self, ControlEndpoint};

/// Why the controller's session, or `companion hil`'s side of it, failed (its ends, a lost
/// plant among them, are [`ControlEnd`]s).
#[derive(Debug, thiserror::Error)]
pub enum ControlRunError {
    /// The transport cannot be opened.
    #[error(transparent)]
    Open(#[from] OpenError),
    /// The plant did not join.
    #[error(transparent)]
    Start(#[from] StartError),
    /// The loop failed, or refused the plant.
    #[error(transparent)]
    Serve(#[from] ServeError),
    /// The chaos plan or its thread.
    #[error(transparent)]
    Chaos(#[from] ChaosError),
    /// `companion hil` was given no lock of the controller's role.
    #[error("no lock")]
    NoLock,
    /// Waiting for the plant process failed.
    #[error(transparent)]
    Wait(#[from] std::io::Error),
    /// A report cannot be put as JSON.
    #[error(transparent)]
    Serialize(#[from] serde_json::Error),
    /// `link.json` or `chaos.json` cannot be written.
    #[error("writing {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// `timeseries.csv` cannot be read or written back trimmed.
    #[error("{doing} {}: {cause}", path.display())]
    Trim {
        /// `reading` or `writing`.
        doing: &'static str,
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        cause: std::io::Error,
    },
}

impl ControlRunError {
    /// The demo found running, if that is the error (the command line's exit code 5).
    pub fn name_in_use(&self) -> Option<&NameInUse> {
        match self {
            Self::Open(e) => e.cause.name_in_use(),
            Self::Start(e) => e.name_in_use(),
            _ => None,
        }
    }
}

/// How long the controller waits for the plant to read its last message.
const LINGER: Duration = Duration::from_secs(1);

/// The options of [`serve_scenario`] for a configuration and scenario.
pub fn serve_options(cfg: &HilConfig, s: &Scenario) -> ServeOptions {
    let t = &cfg.timing;
    let startup = cfg.startup_timeout.as_nanos().min(u128::from(u64::MAX)) as u64;
    ServeOptions {
        wait: t.wait,
        spin_margin_ns: t.spin_margin_ns,
        silence_ns: t.silence_ns,
        peer_timeout_ns: t.peer_timeout_ns,
        startup_timeout_ns: startup.max(t.peer_timeout_ns),
        forward_interrupt: true,
        delay_compensation: s.delay_compensation,
        deadline_ns: if t.lockstep { 0 } else { t.deadline_ns },
    }
}

/// Faults the controller's link injects (tests' `--inject`, `--chaos`); empty: none.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Faults {
    /// Corrupted commands: `(sequence number, kind)`.
    pub corruptions: Vec<(u64, Corruption)>,
    /// Commands held back: `(sequence number, ns)`.
    pub delays: Vec<(u64, u64)>,
}

/// What the controller's session ended with.
#[derive(Debug)]
pub struct Session {
    /// How.
    pub end: ControlEnd,
    /// What it counted.
    pub stats: ControlStats,
    /// The faults it injected.
    pub injected: Injected,
    /// What its transport counted (Zenoh), read after the last message.
    pub link: Option<LinkCounts>,
}

/// One controller session: opens the transport, waits for the plant (`abort` is asked while
/// waiting whether to give up), serves it, injecting `faults`. `lock`: this process holds
/// the controller's role of the demo's name.
///
/// # Errors
/// A bad parameter, a transport failure, or a plant this controller refused
/// ([`super::serve::Refused`]).
pub fn session(
    cfg: &HilConfig,
    s: &HilScenario,
    faults: &Faults,
    observer: &dyn Observer,
    abort: impl FnMut() -> Option<String>,
    lock: &NameLock,
) -> Result<Session, ControlRunError> {
    debug_assert!(lock.role == Role::Control && lock.name == cfg.name);
    let opt = serve_options(cfg, s.base());
    let ep: ControlEndpoint = transport::open(
        &cfg.transport,
        &cfg.name,
        Role::Control,
        cfg.timing.wait.uses_events(),
        Duration::from_nanos(cfg.timing.peer_timeout_ns),
    )?;
    let mut abort = abort;
    ep.wait_for_peer(cfg.startup_timeout, || {
        for r in ep.take_refusals() {
            observer.warn(&format!("controller: {r}"));
        }
        abort()
    })?;
    let rt = cfg.rt_config(Role::Control).map(|c| crate::sys::rt::apply(&c));
    if let Some(w) = rt.as_ref().and_then(|r| r.warning("controller")) {
        observer.warn(&w);
    }
    let mut stats = ControlStats::default();
    let mut injected = Injected::default();
    let (r, ep) = if *faults == Faults::default() {
        let mut ep = ep;
        (serve_scenario(&MonotonicClock, &mut ep, s, &opt, &mut stats, observer), ep)
    } else {
        // Testing: corrupted commands go out before the real ones, some answers late.
        let mut link = Injecting::new(ep, faults.corruptions.clone()).with_delays(faults.delays.clone());
        let r = serve_scenario(&MonotonicClock, &mut link, s, &opt, &mut stats, observer);
        injected = link.injected();
        (r, link.into_inner())
    };
    if rt.is_some() {
        crate::sys::rt::reset_thread();
    }
    // The last message (the answer to the end of the run, or a refusal) must reach the plant
    // before this process exits and its samples with it.
    if matches!(&r, Ok(ControlEnd::EndOfRun)) || matches!(&r, Err(ServeError::Refused(_))) {
        ep.linger(LINGER);
    }
    let dropped = ep.transport_malformed();
    if dropped > 0 {
        observer.warn(&format!("controller: {dropped} messages of the wrong size dropped by the transport"));
    }
    let link = ep.link_counts();
    let end = r?;
    if matches!(end, ControlEnd::PlantDied { .. }) {
        ep.cleanup_dead_nodes();
    }
    if let ControlEnd::PlantHung { pid, .. } = end {
        // What the silent plant is doing (its pid is this machine's only over shared memory).
        if matches!(cfg.transport, transport::Transport::Iceoryx2) {
            for t in threads_of(pid) {
                observer.note(&format!("controller: the silent plant's thread {}", t.describe()));
            }
        }
    }
    Ok(Session { end, stats, injected, link })
}

impl ControlStats {
    /// One line: answers, skips, drops, rejections (with their reasons) and compute times.
    pub fn line(&self) -> String {
        let p = self.compute.percentiles();
        let d = self.delay.percentiles();
        let why = if self.rejected > 0 { format!(": {}", self.rejections.describe()) } else { String::new() };
        let w = self.wait;
        let adaptive = if w.no_spare_cpu {
            "; adaptive waiting: no CPU to spare for spinning, on the event throughout".to_string()
        } else if w.fallbacks + w.pressure_holds > 0 {
            format!(
                "; adaptive waiting: {} preemptions, {} fallbacks, {} back-offs for CPU pressure ({:.1} s on the event)",
                w.preemptions,
                w.fallbacks,
                w.pressure_holds,
                w.event_phase_ns as f64 / 1e9
            )
        } else {
            String::new()
        };
        let mut line = format!(
            "controller: answered {} measurements ({} skipped as superseded, {} dropped as malformed, {} rejected \
             by the law{why}); compute p50 {} p99 {} max {}; delay predicted over p50 {} max {}",
            self.answered,
            self.skipped,
            self.invalid,
            self.rejected,
            fmt_ns(p.p50),
            fmt_ns(p.p99),
            fmt_ns(p.max),
            fmt_ns(d.p50),
            fmt_ns(d.max)
        );
        if self.delay_clamped > 0 {
            line.push_str(&format!(
                " ({} announced delays clamped to what the law admits)",
                self.delay_clamped
            ));
        }
        line.push_str(&adaptive);
        if let Some(w) = self.wakes_line() {
            line.push_str("; ");
            line.push_str(&w);
        }
        line
    }

    /// The wake log in a few words (`None` before real time: lockstep, or no answer yet).
    pub fn wakes_line(&self) -> Option<String> {
        let w = &self.wakes;
        let p = w.wake.percentiles();
        if p.count == 0 {
            return None;
        }
        let late = w.late;
        let causes: Vec<String> = late
            .causes()
            .iter()
            .chain(&[("long step", late.long_step)])
            .filter(|(_, c)| c.wakes > 0)
            .map(|(n, c)| format!("{} {} ({} periods missed)", n.replace('_', " "), c.wakes, c.missed))
            .chain((late.bunched.missed > 0).then(|| {
                format!("and {} measurements the plant sent late, bunched with the next", late.bunched.missed)
            }))
            .collect();
        Some(format!(
            "taken after publication p50 {} p99.9 {} max {}; {} late (over half the deadline){}{}",
            fmt_ns(p.p50),
            fmt_ns(p.p99_9),
            fmt_ns(p.max),
            late.wakes(),
            if causes.is_empty() { "" } else { ": " },
            causes.join(", ")
        ))
    }

    /// Why the run must not count as a success although it reached its end: the plant
    /// stopped the robot (`None` if it never did).
    pub fn failure(&self) -> Option<String> {
        (self.stop_events > 0).then(|| {
            format!(
                "the plant stopped the robot {} time(s), first at cycle {} (commands missed their deadlines for \
                 more than the plant's hold periods); the run did not follow the controller",
                self.stop_events,
                self.first_stop_seq.unwrap_or(0)
            )
        })
    }
}

/// How `companion hil`'s controller side ended.
#[derive(Debug)]
pub enum ParentOutcome {
    /// The plant exited before the run started (it said why); its status.
    PlantExitedEarly(ExitStatus),
    /// The session failed (printed as the error); the plant was left to stop the robot and
    /// write its files, and exited with this status.
    Failed(ControlRunError, Option<ExitStatus>),
    /// The run ended (or was interrupted) and the plant exited with `plant`.
    Finished {
        /// How the controller's side ended.
        end: ControlEnd,
        /// The plant's status.
        plant: Option<ExitStatus>,
        /// `--chaos`: the check of the plant's counts against what was injected.
        chaos: Option<Box<chaos::Report>>,
        /// Why the run failed although it ended ([`ControlStats::failure`]).
        failure: Option<String>,
    },
    /// The plant died, left or hung during the run.
    PlantLost(ControlEnd),
}

/// What the controller writes when the plant died under it.
#[derive(Debug, Serialize)]
struct Fault {
    fault: String,
    plant_pid: i32,
    plant_exit: String,
    last_cycle_answered: Option<u64>,
    noticed_after_last_measurement_ms: f64,
    rows_on_disk: Option<u64>,
    controller_answered: u64,
    /// A hung plant's threads when it was found silent, before it was killed
    /// ([`crate::sys::threads`]).
    plant_threads: Vec<ThreadState>,
}

fn ms(ns: u64) -> f64 {
    ns as f64 / 1e6
}

/// The controller side of `companion hil`, with the plant `child` it started. `locks`: this
/// process holds both roles of the demo's name (the plant runs under them).
///
/// # Errors
/// Waiting for the plant failed, `fault.json` cannot be encoded, or the chaos plan cannot be
/// made.
pub fn run_as_parent(
    cfg: &HilConfig,
    s: &HilScenario,
    faults: &Faults,
    mut child: ChildGuard,
    observer: &dyn Observer,
    locks: &[NameLock; 2],
) -> Result<ParentOutcome, ControlRunError> {
    let pid = child.id();
    let pid_i32 = i32::try_from(pid).unwrap_or(0);
    let mut faults = faults.clone();
    let mut agent = None;
    if let Some(c) = cfg.chaos {
        let plan = Plan::new(c.seed, s.base().steps(), &cfg.timing)?;
        faults.corruptions.extend(plan.corruptions.iter().copied());
        faults.delays.extend(plan.delays.iter().copied());
        agent = Some(Agent::spawn(plan.stops_by(Role::Control), pid_i32, c.epoch_ns)?);
    }
    let mut exited = None;
    let mut forwarded = false;
    let abort = || -> Option<String> {
        let c = child.0.as_mut()?;
        if termination_requested() && !forwarded {
            // Interrupted while starting: the plant ends too, and writes nothing.
            forwarded = true;
            let _ = send_signal(pid_i32, Signal::Terminate);
        }
        match c.try_wait() {
            Ok(Some(st)) => {
                exited = Some(st);
                Some(format!("the plant (pid {pid}) ended before the run started ({})", exit_text(st)))
            }
            _ => None,
        }
    };
    let control_lock = locks.iter().find(|l| l.role == Role::Control).ok_or(ControlRunError::NoLock)?;
    let result = session(cfg, s, &faults, observer, abort, control_lock);
    let stops = agent.map(Agent::finish).unwrap_or_default();
    if exited.is_some() {
        child.0 = None;
    }
    let Session { end, stats, injected, link } = match result {
        Ok(x) => x,
        Err(e) => {
            // The plant may already have explained (e.g. a name in use); its status says more.
            if let Some(st) = exited {
                return Ok(ParentOutcome::PlantExitedEarly(st));
            }
            // Leave the plant to notice the lost controller, stop the robot and write its
            // files (it does so within --silence-ms); kill it only if it does not.
            observer.note(&format!("error: {}", Causes(&e)));
            let grace = Duration::from_nanos(cfg.timing.peer_timeout_ns) + Duration::from_secs(5);
            let st = child.finish(grace).ok().flatten();
            return Ok(ParentOutcome::Failed(e, st));
        }
    };
    match end {
        ControlEnd::EndOfRun | ControlEnd::Interrupted => {
            // The plant writes its files and plots, then exits with the run's status.
            let plant = child.finish(Duration::from_secs(600))?;
            observer.note(&stats.line());
            controller_report(cfg, &stats, observer);
            if let Some(c) = link {
                link_report(cfg, c, observer)?;
            }
            let chaos = match cfg.chaos {
                Some(c) => Some(Box::new(chaos_report(cfg, s.base(), c.seed, injected, &stops, link)?)),
                None => None,
            };
            let failure = stats.failure();
            if let Some(f) = &failure {
                observer.note(&format!("controller: {f}"));
            }
            Ok(ParentOutcome::Finished { end, plant, chaos, failure })
        }
        ControlEnd::PlantGone { .. } => {
            // The plant's node went away without the end of the run reaching this process
            // (preempted at the end, the last measurement was gone with the plant's ports):
            // the plant's own exit status says how its run ended.
            let plant = child.finish(Duration::from_secs(5))?;
            if plant.is_some_and(|st| st.code().is_some()) {
                observer.note(&stats.line());
                return Ok(ParentOutcome::Finished {
                    end: ControlEnd::EndOfRun,
                    plant,
                    chaos: None,
                    failure: None,
                });
            }
            lost(cfg, end, plant, pid, &stats, observer)
        }
        ControlEnd::PlantDied { .. } => {
            let status = child.finish(Duration::from_secs(5))?;
            lost(cfg, end, status, pid, &stats, observer)
        }
        ControlEnd::PlantHung { .. } => {
            // Alive but silent: what its threads are doing, then stop it (it cannot be
            // trusted to end on its own).
            let threads = threads_of(i32::try_from(pid).unwrap_or(0));
            let status = child.finish(Duration::ZERO)?;
            lost_with(cfg, end, status, pid, &stats, threads, observer)
        }
    }
}

/// The plant was lost: keeps its rows, writes `fault.json`.
fn lost(
    cfg: &HilConfig,
    end: ControlEnd,
    status: Option<ExitStatus>,
    pid: u32,
    stats: &ControlStats,
    observer: &dyn Observer,
) -> Result<ParentOutcome, ControlRunError> {
    lost_with(cfg, end, status, pid, stats, Vec::new(), observer)
}

/// [`lost`], with the threads of a hung plant.
fn lost_with(
    cfg: &HilConfig,
    end: ControlEnd,
    status: Option<ExitStatus>,
    pid: u32,
    stats: &ControlStats,
    plant_threads: Vec<ThreadState>,
    observer: &dyn Observer,
) -> Result<ParentOutcome, ControlRunError> {
    let how = status.map_or("unknown".to_string(), exit_text);
    observer.note(&format!("controller: {} ({how})", end.describe()));
    let rows = trim_partial_csv(&cfg.out).ok();
    if let Some(r) = rows {
        observer.note(&format!(
            "controller: {} rows recorded up to the fault are in {}",
            r,
            cfg.out.join("timeseries.csv").display()
        ));
    }
    let (last, silent) = match end {
        ControlEnd::PlantDied { last_seq, silent_ns, .. } => (last_seq, silent_ns),
        ControlEnd::PlantGone { last_seq } => (last_seq, 0),
        ControlEnd::PlantHung { silent_ns, .. } => (None, silent_ns),
        ControlEnd::EndOfRun | ControlEnd::Interrupted => (None, 0),
    };
    let fault = Fault {
        fault: end.describe(),
        plant_pid: i32::try_from(pid).unwrap_or(0),
        plant_exit: how,
        last_cycle_answered: last.or((stats.answered > 0).then_some(stats.answered - 1)),
        noticed_after_last_measurement_ms: ms(silent),
        rows_on_disk: rows,
        controller_answered: stats.answered,
        plant_threads,
    };
    let _ = std::fs::create_dir_all(&cfg.out);
    let path = cfg.out.join("fault.json");
    if let Err(e) = std::fs::write(&path, serde_json::to_string_pretty(&fault)? + "\n") {
        observer.warn(&format!("writing {}: {e}", path.display()));
    }
    observer.note(&stats.line());
    Ok(ParentOutcome::PlantLost(end))
}

/// The rows a complete run of `s` logs: steps `0..=steps` that are multiples of
/// `log_every`, and the last.
pub fn expected_rows(s: &Scenario) -> u64 {
    let steps = s.steps();
    steps / s.log_every + 1 + u64::from(steps % s.log_every != 0)
}

/// `link.json` of a run over Zenoh: both sides' transport counts and what each never got of
/// the other's messages.
#[derive(Debug, Serialize)]
pub struct LinkReport {
    /// The controller's transport.
    pub controller: LinkCounts,
    /// The plant's (from `latency.json`; `None` if it wrote none).
    pub plant: Option<LinkCounts>,
    /// Commands the controller's transport accepted that the plant's never received.
    pub commands_not_received: Option<u64>,
    /// Measurements the plant's transport accepted that the controller's never received.
    pub measurements_not_received: Option<u64>,
}

/// Writes `link.json` after the plant ended (its `latency.json` has its counts) and says what
/// was lost; over Zenoh a congestion drop is silent at the sender, so this is where it shows.
///
/// # Errors
/// `link.json` cannot be written.
fn link_report(
    cfg: &HilConfig,
    controller: LinkCounts,
    observer: &dyn Observer,
) -> Result<LinkReport, ControlRunError> {
    let plant: Option<LinkCounts> = std::fs::read_to_string(cfg.out.join("latency.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .and_then(|v| serde_json::from_value(v.get("link_counts")?.clone()).ok());
    let report = LinkReport {
        controller,
        plant,
        commands_not_received: plant.map(|p| controller.not_received_by(&p)),
        measurements_not_received: plant.map(|p| p.not_received_by(&controller)),
    };
    if let (Some(p), Some(c), Some(m)) =
        (plant, report.commands_not_received, report.measurements_not_received)
    {
        observer.note(&format!(
            "link: the controller sent {} commands, the plant's transport received {} ({c} never arrived, {} \
             dropped on a full ring); the plant sent {} measurements, the controller's transport received {} \
             ({m} never arrived, {} dropped on a full ring)",
            controller.published,
            p.received,
            p.dropped_full_ring,
            p.published,
            controller.received,
            controller.dropped_full_ring
        ));
        if c + m + p.dropped_full_ring + controller.dropped_full_ring > 0 {
            observer
                .warn("the link lost messages (see link.json): zenoh drops on congestion without an error");
        }
    }
    let path = cfg.out.join("link.json");
    std::fs::write(&path, serde_json::to_string_pretty(&report)? + "\n")
        .map_err(|source| ControlRunError::Write { path, source })?;
    Ok(report)
}

/// `controller.json`: what the controller's side of a run measured: its answers, its waiting
/// and its wakes ([`super::wakes`]).
#[derive(Debug, Serialize)]
pub struct ControllerReport {
    /// The wait mode.
    pub wait: super::config::WaitMode,
    /// Measurements answered.
    pub answered: u64,
    /// Measurements skipped as superseded.
    pub skipped: u64,
    /// The step's time per answer (ns).
    pub compute_ns: crate::domain::histogram::Percentiles,
    /// What the adaptive wait did (zero in the other modes).
    pub wait_counts: super::wait::WaitCounts,
    /// Every wake and the late ones by cause.
    pub wakes: super::wakes::WakeReport,
}

/// Writes `controller.json` into the run's folder (a warning if it cannot: the run's own files
/// are the plant's).
fn controller_report(cfg: &HilConfig, stats: &ControlStats, observer: &dyn Observer) {
    let r = ControllerReport {
        wait: cfg.timing.wait,
        answered: stats.answered,
        skipped: stats.skipped,
        compute_ns: stats.compute.percentiles(),
        wait_counts: stats.wait,
        wakes: stats.wakes.report(),
    };
    let path = cfg.out.join("controller.json");
    let text = serde_json::to_string_pretty(&r).map(|t| t + "\n");
    if let Err(e) = text.map_err(std::io::Error::other).and_then(|t| std::fs::write(&path, t)) {
        observer.warn(&format!("writing {}: {e}", path.display()));
    }
}

/// `--chaos`: reads what the plant counted, compares it with what was injected, writes
/// `chaos.json`.
fn chaos_report(
    cfg: &HilConfig,
    s: &Scenario,
    seed: u64,
    injected: Injected,
    stops: &[chaos::DoneStop],
    sent: Option<LinkCounts>,
) -> Result<chaos::Report, ControlRunError> {
    let path = cfg.out.join("latency.json");
    let observed: Observed = std::fs::read_to_string(&path)
        .map_err(|e| e.to_string())
        .and_then(|t| serde_json::from_str(&t).map_err(|e| e.to_string()))
        .unwrap_or_else(|e| Observed {
            end: format!("no readable {}: {e}", path.display()),
            ..Observed::default()
        });
    let rows = complete_rows(&cfg.out).unwrap_or(0);
    let mut all = stops.to_vec();
    all.extend(observed.chaos_stops.iter().copied());
    let report = chaos::check(seed, &cfg.timing, injected, &all, observed, (rows, expected_rows(s)), sent);
    let path = cfg.out.join("chaos.json");
    std::fs::write(&path, serde_json::to_string_pretty(&report)? + "\n")
        .map_err(|source| ControlRunError::Write { path, source })?;
    Ok(report)
}

/// The complete data rows of `dir/timeseries.csv`: lines ending in a newline with the
/// header's number of fields.
///
/// # Errors
/// The file cannot be read.
pub fn complete_rows(dir: &Path) -> std::io::Result<u64> {
    let text = std::fs::read_to_string(dir.join("timeseries.csv"))?;
    let mut lines = text.split_inclusive('\n');
    let fields = |l: &str| l.split(',').count();
    let Some(header) = lines.next() else { return Ok(0) };
    let n = fields(header);
    Ok(lines.filter(|l| l.ends_with('\n') && fields(l) == n).count() as u64)
}

/// Trims `dir/timeseries.csv` after its last complete line (after the plant was killed
/// mid-write). Returns the number of complete data rows.
///
/// # Errors
/// The file cannot be read or written.
pub fn trim_partial_csv(dir: &Path) -> Result<u64, ControlRunError> {
    let path = dir.join("timeseries.csv");
    let mut bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(cause) => return Err(ControlRunError::Trim { doing: "reading", path, cause }),
    };
    let keep = bytes.iter().rposition(|b| *b == b'\n').map_or(0, |i| i + 1);
    if keep < bytes.len() {
        bytes.truncate(keep);
        if let Err(cause) = std::fs::write(&path, &bytes) {
            return Err(ControlRunError::Trim { doing: "writing", path, cause });
        }
    }
    let lines = bytes.iter().filter(|b| **b == b'\n').count() as u64;
    Ok(lines.saturating_sub(1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partial_csv_lines_are_trimmed() {
        let dir = std::env::temp_dir().join(format!("companion-trim-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("timeseries.csv"), "t,x\n0,1\n0.1,2\n0.2,").unwrap();
        assert_eq!(complete_rows(&dir).unwrap(), 2);
        assert_eq!(trim_partial_csv(&dir).unwrap(), 2);
        assert_eq!(std::fs::read_to_string(dir.join("timeseries.csv")).unwrap(), "t,x\n0,1\n0.1,2\n");
        std::fs::write(dir.join("timeseries.csv"), "t,x\n0,1\n0.1\n0.2,3\n").unwrap();
        assert_eq!(complete_rows(&dir).unwrap(), 2, "a line with a field missing is not complete");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_run_logs_every_nth_step_and_the_last() {
        let s = |d: f64, k: u64| {
            Scenario::builder(
                companion_plant::PaperTrajectory::One,
                companion_core::PaperRun::A,
                companion_core::PlatformKind::Unicycle,
            )
            .duration(d)
            .log_every(k)
            .build()
            .unwrap()
        };
        assert_eq!(expected_rows(&s(1.0, 10)), 101);
        assert_eq!(expected_rows(&s(1.0, 1)), 1001);
        assert_eq!(expected_rows(&s(1.0, 7)), 144, "0, 7, …, 994 and 1000");
    }
}
