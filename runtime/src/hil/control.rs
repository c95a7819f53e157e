//! The controller process: answers each measurement with one command; as `companion hil` it
//! also watches the plant process it started and, when the plant dies under it, keeps what
//! the plant wrote (`timeseries.csv` trimmed to its last complete line) and writes
//! `fault.json`.

use std::path::Path;
use std::process::ExitStatus;
use std::time::Duration;

use anyhow::{anyhow, Result};
use serde::Serialize;

use super::config::{HilConfig, WaitMode};
use super::end::ControlEnd;
use super::fault::{Corruption, Injecting};
use super::serve::{serve, ServeOptions};
use super::stats::ControlStats;
use crate::clock::MonotonicClock;
use crate::histogram::fmt_ns;
use crate::ipc::Role;
use crate::observe::Observer;
use crate::process::{exit_text, ChildGuard};
use crate::scenario::Scenario;
use crate::transport::{self, ControlEndpoint};

/// How long the controller waits for the plant to read its last message.
const LINGER: Duration = Duration::from_secs(1);

/// The options of [`serve`] for a configuration and scenario.
pub fn serve_options(cfg: &HilConfig, s: &Scenario) -> ServeOptions {
    let t = &cfg.timing;
    #[allow(clippy::cast_possible_truncation)]
    let startup = cfg.startup_timeout.as_nanos().min(u128::from(u64::MAX)) as u64;
    ServeOptions {
        wait: t.wait,
        spin_margin_ns: t.spin_margin_ns,
        silence_ns: t.silence_ns,
        peer_timeout_ns: t.peer_timeout_ns,
        startup_timeout_ns: startup.max(t.peer_timeout_ns),
        delay_compensation: s.delay_compensation,
    }
}

/// What the controller's session ended with.
#[derive(Debug)]
pub struct Session {
    /// How.
    pub end: ControlEnd,
    /// What it counted.
    pub stats: ControlStats,
}

/// One controller session: opens the transport, waits for the plant (`abort` is asked while
/// waiting whether to give up), serves it. `inject`: corrupted commands to add (tests).
///
/// # Errors
/// A bad parameter, a transport failure, or a plant this controller refused
/// ([`super::serve::Refused`]).
pub fn session(
    cfg: &HilConfig,
    s: &Scenario,
    inject: &[(u64, Corruption)],
    observer: &dyn Observer,
    abort: impl FnMut() -> Option<String>,
) -> Result<Session> {
    let opt = serve_options(cfg, s);
    let ep: ControlEndpoint =
        transport::open(&cfg.transport, &cfg.name, Role::Control, cfg.timing.wait == WaitMode::Event)?;
    ep.wait_for_peer(cfg.startup_timeout, abort)?;
    let rt = cfg.rt_config(Role::Control).map(|c| crate::rt::apply(&c));
    if let Some(w) = rt.as_ref().and_then(|r| r.warning("controller")) {
        observer.warn(&w);
    }
    let mut stats = ControlStats::default();
    let (r, ep) = if inject.is_empty() {
        let mut ep = ep;
        (serve(&MonotonicClock, &mut ep, &s.controller, &opt, &mut stats, observer), ep)
    } else {
        // Testing: corrupted commands go out before the real ones.
        let mut link = Injecting::new(ep, inject.to_vec());
        (serve(&MonotonicClock, &mut link, &s.controller, &opt, &mut stats, observer), link.into_inner())
    };
    if rt.is_some() {
        crate::rt::reset_thread();
    }
    // The last message (the answer to the end of the run, or a refusal) must reach the plant
    // before this process exits and its samples with it.
    if matches!(&r, Ok(ControlEnd::EndOfRun)) || r.as_ref().is_err_and(|e| e.is::<super::serve::Refused>()) {
        ep.linger(LINGER);
    }
    let dropped = ep.transport_malformed();
    if dropped > 0 {
        observer.warn(&format!("controller: {dropped} messages of the wrong size dropped by the transport"));
    }
    let end = r?;
    if matches!(end, ControlEnd::PlantDied { .. }) {
        ep.cleanup_dead_nodes();
    }
    Ok(Session { end, stats })
}

impl ControlStats {
    /// One line: answers, skips, drops, rejections and compute times.
    pub fn line(&self) -> String {
        let p = self.compute.percentiles();
        let d = self.delay.percentiles();
        let mut line = format!(
            "controller: answered {} measurements ({} skipped as superseded, {} dropped as malformed, {} rejected \
             by the law); compute p50 {} p99 {} max {}; delay predicted over p50 {} max {}",
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
        line
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
    /// write its files.
    Failed(anyhow::Error),
    /// The run ended (or was interrupted) and the plant exited with `plant`.
    Finished {
        /// How the controller's side ended.
        end: ControlEnd,
        /// The plant's status.
        plant: Option<ExitStatus>,
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
}

#[allow(clippy::cast_precision_loss)]
fn ms(ns: u64) -> f64 {
    ns as f64 / 1e6
}

/// The controller side of `companion hil`, with the plant `child` it started.
///
/// # Errors
/// Waiting for the plant failed, or `fault.json` cannot be encoded.
pub fn run_as_parent(
    cfg: &HilConfig,
    s: &Scenario,
    inject: &[(u64, Corruption)],
    mut child: ChildGuard,
    observer: &dyn Observer,
) -> Result<ParentOutcome> {
    let pid = child.id();
    let mut exited = None;
    let abort = || -> Option<String> {
        let c = child.0.as_mut()?;
        match c.try_wait() {
            Ok(Some(st)) => {
                exited = Some(st);
                Some(format!("the plant (pid {pid}) ended before the run started ({})", exit_text(st)))
            }
            _ => None,
        }
    };
    let result = session(cfg, s, inject, observer, abort);
    if exited.is_some() {
        child.0 = None;
    }
    let Session { end, stats } = match result {
        Ok(x) => x,
        Err(e) => {
            // The plant may already have explained (e.g. a name in use); its status says more.
            if let Some(st) = exited {
                return Ok(ParentOutcome::PlantExitedEarly(st));
            }
            // Leave the plant to notice the lost controller, stop the robot and write its
            // files (it does so within --silence-ms); kill it only if it does not.
            observer.note(&format!("error: {e:#}"));
            let grace = Duration::from_nanos(cfg.timing.peer_timeout_ns) + Duration::from_secs(5);
            let _ = child.finish(grace);
            return Ok(ParentOutcome::Failed(e));
        }
    };
    match end {
        ControlEnd::EndOfRun | ControlEnd::Interrupted => {
            // The plant writes its files and plots, then exits with the run's status.
            let plant = child.finish(Duration::from_secs(600))?;
            observer.note(&stats.line());
            let failure = stats.failure();
            if let Some(f) = &failure {
                observer.note(&format!("controller: {f}"));
            }
            Ok(ParentOutcome::Finished { end, plant, failure })
        }
        ControlEnd::PlantDied { .. } | ControlEnd::PlantGone { .. } | ControlEnd::PlantHung { .. } => {
            let status = if matches!(end, ControlEnd::PlantHung { .. }) {
                // Alive but silent: stop it (it cannot be trusted to end on its own).
                child.finish(Duration::ZERO)?
            } else {
                child.finish(Duration::from_secs(5))?
            };
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
                ControlEnd::PlantHung { silent_ns } => (None, silent_ns),
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
            };
            let _ = std::fs::create_dir_all(&cfg.out);
            let path = cfg.out.join("fault.json");
            if let Err(e) = std::fs::write(&path, serde_json::to_string_pretty(&fault)? + "\n") {
                observer.warn(&format!("writing {}: {e}", path.display()));
            }
            observer.note(&stats.line());
            Ok(ParentOutcome::PlantLost(end))
        }
    }
}

/// Trims `dir/timeseries.csv` after its last complete line (after the plant was killed
/// mid-write). Returns the number of complete data rows.
///
/// # Errors
/// The file cannot be read or written.
pub fn trim_partial_csv(dir: &Path) -> Result<u64> {
    let path = dir.join("timeseries.csv");
    let mut bytes = std::fs::read(&path).map_err(|e| anyhow!("reading {}: {e}", path.display()))?;
    let keep = bytes.iter().rposition(|b| *b == b'\n').map_or(0, |i| i + 1);
    if keep < bytes.len() {
        bytes.truncate(keep);
        std::fs::write(&path, &bytes).map_err(|e| anyhow!("writing {}: {e}", path.display()))?;
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
        assert_eq!(trim_partial_csv(&dir).unwrap(), 2);
        assert_eq!(std::fs::read_to_string(dir.join("timeseries.csv")).unwrap(), "t,x\n0,1\n0.1,2\n");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
