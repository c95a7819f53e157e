//! The hardware-in-the-loop demo: the plant and the controller as two OS processes exchanging
//! one message each way per period over iceoryx2 shared memory.
//!
//! ## Processes and files
//!
//! `companion hil` is the controller. It starts the plant as a child process (the same binary,
//! `companion plant` with the same flags), answers its measurements, and waits for it to
//! finish. `companion plant` and `companion control` run the two roles alone (two terminals,
//! or a bridge to real hardware in place of the plant); give both the same scenario flags and
//! `--name`.
//!
//! The plant owns time and the truth, so it writes the run's files into `--out`:
//! `timeseries.csv`, `summary.json`, `scenario.json` and the plots (the same as `companion
//! sim`: each command carries the law's logged diagnostics), plus `latency.json` and
//! `latency.svg`. The controller's compute time reaches it in every command. The controller
//! writes a file only when the plant dies under it: `fault.json` (what happened, when), and it
//! trims `timeseries.csv` to its last complete line.
//!
//! ## Modes
//!
//! *Real time* (default): after a handshake (measurement 0, whose command is awaited up to
//! `--peer-timeout`, so that a cold first step is not a miss; `start` is when it arrives) the
//! plant publishes measurement `n` at the absolute release time
//! `start + n·period` (never "sleep a period after the work"), waits for command `n` until
//! `release + --deadline-us`, and applies it over the period (zero-order hold). A command
//! that is late or missing is a counted deadline miss; the plant then holds the last fresh
//! command for at most `--hold-periods` periods and after that stops the robot (all
//! velocities zero), reports it, and resumes as soon as fresh commands arrive again.
//! *Lockstep* (`--lockstep`): the plant waits for every command; the run is deterministic and
//! its `timeseries.csv` is byte-identical to `companion sim` for the same scenario (the loop is
//! [`crate::sim::run_loop`] itself with an iceoryx2 [`crate::sim::Exchange`]).
//!
//! ## Waiting (`--wait`)
//!
//! - `spin` (default on two or more CPUs without `--rt`): busy-poll `receive()` (and the
//!   clock, for the plant's release time). Lowest latency; one core per process.
//! - `event`: the iceoryx2 event service: the sender notifies, the receiver sleeps in
//!   `timed_wait` (always bounded) and re-checks `receive()` after every wake; the plant sleeps
//!   to its release time with `clock_nanosleep(TIMER_ABSTIME)`.
//! - `hybrid`: sleep until `--spin-margin-us` before the expected message (the
//!   plant: before its release time; the controller: before the next period's measurement),
//!   then spin. A spin that finds nothing for 200 µs falls back to 50 µs sleeps, so a silent
//!   peer does not cost a core. The default with `--rt` or on one CPU
//!   ([`HilArgs::wait_mode`] says why).
//!
//! ## Faults
//!
//! Each side notices a silent peer: after `--silence-ms` without a message (or, for the
//! plant, once it has stopped the robot) it lists the iceoryx2 nodes. A peer that died is
//! reported at once (exit code [`EXIT_PEER_LOST`]) and its shared memory is cleaned; a peer
//! that is alive but silent for `--peer-timeout` seconds ends the run with
//! [`EXIT_PEER_HUNG`]. A second demo with the same `--name` stops with [`EXIT_NAME_IN_USE`].
//! Malformed messages (wrong sequence number, session or protocol version, non-finite
//! velocities) are counted and dropped ([`crate::wire::check_command`]).
//!
//! ## The cycle's cost
//!
//! One cycle allocates nothing, takes no lock of its own and makes no system call but the
//! transport's (iceoryx2 send/receive are shared-memory operations; `--wait event` adds the
//! event's syscalls, `hybrid`/`event` one `clock_nanosleep`). Latency samples go into
//! preallocated HDR histograms; log rows go into a preallocated lock-free ring buffer that a
//! normal-priority thread drains into `timeseries.csv`, flushing every 50 ms — so the file
//! is on disk up to the last ~50 ms if the plant is killed.

pub mod control;
pub mod plant;
pub mod report;
pub mod wait;

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command as Process, ExitCode, Stdio};

use anyhow::{anyhow, bail, Result};
use clap::{Args, ValueEnum};

use crate::ipc::{self, NameInUse, Role};
use crate::scenario::{Scenario, ScenarioArgs};

/// Exit code: the peer process died or vanished during the run.
pub const EXIT_PEER_LOST: u8 = 3;
/// Exit code: the peer process is alive but stopped answering for `--peer-timeout`.
pub const EXIT_PEER_HUNG: u8 = 4;
/// Exit code: a demo with the same `--name` is running.
pub const EXIT_NAME_IN_USE: u8 = 5;
/// Exit code: ended early by SIGINT or SIGTERM (files are written).
pub const EXIT_INTERRUPTED: u8 = 130;

/// The default simulated duration of a HIL run when `--duration` is not given (s).
pub const DEFAULT_DURATION: f64 = 30.0;

/// How a process waits for its peer's message.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum WaitMode {
    /// Busy-poll.
    Spin,
    /// iceoryx2 event service with bounded `timed_wait`.
    Event,
    /// Sleep until shortly before the expected message, then spin.
    Hybrid,
}

impl WaitMode {
    /// The command-line spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Spin => "spin",
            Self::Event => "event",
            Self::Hybrid => "hybrid",
        }
    }
}

/// Flags of `companion hil`, `companion plant` and `companion control` (one set, so that the
/// demo can hand its own flags to the plant it starts; each role uses the flags it needs).
#[derive(Args, Clone, Debug)]
pub struct HilArgs {
    #[command(flatten)]
    /// The scenario (give both roles the same one). `--duration` defaults to 30 s here.
    pub scenario: ScenarioArgs,
    /// Control rate in Hz (default: 1/--dt, so that simulated time runs at wall-clock speed).
    #[arg(long, value_name = "HZ")]
    pub rate: Option<f64>,
    /// Deadline of each command after its period's release, in microseconds.
    #[arg(long, default_value_t = 500, value_name = "US")]
    pub deadline_us: u64,
    /// Lockstep: the plant waits for every command (deterministic, no deadlines; the same
    /// timeseries.csv as `companion sim`).
    #[arg(long)]
    pub lockstep: bool,
    /// How each process waits for the other's message [default: spin on a machine with two
    /// or more CPUs, hybrid with --rt (a SCHED_FIFO spinner is parked by the kernel's
    /// real-time throttling) or on one CPU].
    #[arg(long, value_enum)]
    pub wait: Option<WaitMode>,
    /// Real-time setup: mlockall, SCHED_FIFO, one CPU per process, pre-faulted stack (a missing
    /// privilege is a warning).
    #[arg(long)]
    pub rt: bool,
    /// SCHED_FIFO priority with --rt.
    #[arg(long, default_value_t = 80, value_parser = clap::value_parser!(i32).range(1..=99))]
    pub rt_priority: i32,
    /// The plant's CPU with --rt (default: 1 on a machine with two or more CPUs).
    #[arg(long, value_name = "CPU")]
    pub plant_cpu: Option<usize>,
    /// The controller's CPU with --rt (default: 0).
    #[arg(long, value_name = "CPU")]
    pub control_cpu: Option<usize>,
    /// The demo's name: its iceoryx2 services are companion/NAME/…, so demos with different
    /// names never meet.
    #[arg(long, default_value = "demo")]
    pub name: String,
    /// Output folder (the plant writes it).
    #[arg(long, default_value = "out/hil", value_name = "DIR")]
    pub out: PathBuf,
    /// Periods the plant holds the last command after a miss before it stops the robot.
    #[arg(long, default_value_t = 20, value_name = "K")]
    pub hold_periods: u32,
    /// Hybrid waiting: how long before the expected message to stop sleeping and spin (µs).
    #[arg(long, default_value_t = 100, value_name = "US")]
    pub spin_margin_us: u64,
    /// Silence (no message) after which a process checks whether its peer is alive (ms).
    #[arg(long, default_value_t = 20, value_name = "MS")]
    pub silence_ms: u64,
    /// Give up when the peer is alive but silent for this long (s).
    #[arg(long, default_value_t = 2.0, value_name = "SECONDS")]
    pub peer_timeout: f64,
    /// How long to wait for the peer to join at start (s).
    #[arg(long, default_value_t = 20.0, value_name = "SECONDS")]
    pub startup_timeout: f64,
    /// Skip the plots (CSV and JSON only).
    #[arg(long)]
    pub no_plots: bool,
    /// No live progress line.
    #[arg(long)]
    pub quiet: bool,
    /// Testing: the controller also sends corrupted commands, e.g. `version@100,nan@200,seq@300,
    /// session@400` (each is sent once, before the good answer to the first measurement with
    /// at least that sequence number).
    #[arg(long, hide = true, value_name = "LIST")]
    pub inject: Option<String>,
    /// Set by `companion hil` on the plant it starts.
    #[arg(long, hide = true)]
    pub child: bool,
}

/// `companion plant` flags (the same set as `hil`).
pub type PlantArgs = HilArgs;
/// `companion control` flags (the same set as `hil`).
pub type ControlArgs = HilArgs;

/// The timing options both loops use, resolved from flags.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// The period (ns); 0 in lockstep.
    pub period_ns: u64,
    /// The deadline after release (ns).
    pub deadline_ns: u64,
    /// Hold periods before stopping.
    pub hold_periods: u32,
    /// The wait mode.
    pub wait: WaitMode,
    /// Hybrid spin margin (ns).
    pub spin_margin_ns: u64,
    /// Silence before a liveness check (ns).
    pub silence_ns: u64,
    /// Alive-but-silent limit (ns).
    pub peer_timeout_ns: u64,
    /// Lockstep.
    pub lockstep: bool,
}

#[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
fn secs_to_ns(s: f64) -> u64 {
    (s * 1e9).round() as u64
}

impl HilArgs {
    /// The scenario, with the HIL's default duration.
    ///
    /// # Errors
    /// A bad scenario flag.
    pub fn scenario(&self) -> Result<Scenario> {
        let mut a = self.scenario.clone();
        if a.duration.is_none() {
            a.duration = Some(DEFAULT_DURATION);
        }
        let mut s = Scenario::from_args(&a)?;
        if !self.lockstep {
            // The plant may hold a command for `hold_periods` periods after the one it was
            // meant for: the joint guard leaves room for all of them, so that a held command
            // never drives a joint onto its limit.
            let o = &mut s.controller.overrides;
            let kappa = o.joint_step_fraction.unwrap_or(0.5).min(1.0 / (f64::from(self.hold_periods) + 2.0));
            o.joint_step_fraction = Some(kappa);
        }
        Ok(s)
    }

    /// The timing options.
    ///
    /// # Errors
    /// A rate, deadline or timeout out of range.
    pub fn timing(&self, s: &Scenario) -> Result<Timing> {
        let rate = self.rate.unwrap_or(1.0 / s.dt);
        if !(rate.is_finite() && (1.0..=100_000.0).contains(&rate)) {
            bail!("--rate must be between 1 and 100000 Hz, got {rate}");
        }
        let period_ns = secs_to_ns(1.0 / rate);
        let deadline_ns = self.deadline_us * 1000;
        if !self.lockstep && (deadline_ns == 0 || deadline_ns > period_ns) {
            bail!(
                "--deadline-us must be in (0, period] = (0, {}] µs at {rate} Hz, got {}",
                period_ns / 1000,
                self.deadline_us
            );
        }
        if !(self.peer_timeout.is_finite() && self.peer_timeout > 0.0) {
            bail!("--peer-timeout must be a positive number of seconds");
        }
        if self.silence_ms == 0 {
            bail!("--silence-ms must be at least 1");
        }
        Ok(Timing {
            period_ns: if self.lockstep { 0 } else { period_ns },
            deadline_ns,
            hold_periods: self.hold_periods,
            wait: self.wait_mode(),
            spin_margin_ns: self.spin_margin_us * 1000,
            silence_ns: self.silence_ms * 1_000_000,
            peer_timeout_ns: secs_to_ns(self.peer_timeout),
            lockstep: self.lockstep,
        })
    }

    /// `--wait`, or its default: `spin` where each process can have a CPU of its own and
    /// `--rt` is off; `hybrid` otherwise.
    ///
    /// On this project's 2-vCPU VMs a timed sleep at 1 kHz wakes ~30 µs late at the median but
    /// milliseconds late at p99 (a bare `clock_nanosleep` loop), so the modes that sleep miss
    /// far more 500 µs deadlines than spinning does (10 s runs: spin 19 and 23 misses, hybrid
    /// 26 and 793, event 69 and 1 102). With `SCHED_FIFO` a spinner is parked for ~50 ms of
    /// every second by the kernel's real-time throttling, and on one CPU two spinners take
    /// turns by time slices: hybrid there.
    pub fn wait_mode(&self) -> WaitMode {
        self.wait.unwrap_or(if self.rt || crate::rt::online_cpus() < 2 {
            WaitMode::Hybrid
        } else {
            WaitMode::Spin
        })
    }

    /// The CPUs of `(plant, controller)` with `--rt`.
    pub fn cpus(&self) -> (usize, usize) {
        let two = crate::rt::online_cpus() >= 2;
        (self.plant_cpu.unwrap_or(usize::from(two)), self.control_cpu.unwrap_or(0))
    }

    /// A warning if `--rt` puts both processes on one CPU with busy waiting (a `SCHED_FIFO`
    /// spinner never yields its CPU to a peer of the same priority).
    pub fn cpu_warning(&self) -> Option<String> {
        let (p, c) = self.cpus();
        let wait = self.wait_mode();
        (self.rt && p == c && wait != WaitMode::Event).then(|| {
            format!(
                "--rt puts plant and controller on the same CPU ({p}); with --wait {} they take turns \
                 only when the kernel throttles real-time tasks: use --wait event, or two CPUs",
                wait.as_str()
            )
        })
    }

    /// The real-time setup for `role`, if `--rt`.
    pub fn rt_config(&self, role: Role) -> Option<crate::rt::RtConfig> {
        self.rt.then(|| {
            let (p, c) = self.cpus();
            let cpu = if role == Role::Plant { p } else { c };
            crate::rt::RtConfig { priority: self.rt_priority, ..crate::rt::RtConfig::with_cpu(Some(cpu)) }
        })
    }
}

/// Prints a [`NameInUse`] error and returns its exit code; other errors go up.
fn name_in_use_or(e: anyhow::Error) -> Result<ExitCode> {
    if let Some(n) = e.downcast_ref::<NameInUse>() {
        eprintln!("error: {n}");
        return Ok(ExitCode::from(EXIT_NAME_IN_USE));
    }
    Err(e)
}

/// The flags after the `hil` subcommand in this process's command line (handed to the plant).
fn forwarded_args() -> Vec<OsString> {
    let args: Vec<OsString> = std::env::args_os().collect();
    match args.iter().position(|a| a == "hil") {
        Some(i) => args[i + 1..].to_vec(),
        None => Vec::new(),
    }
}

/// `companion hil`: starts the plant, runs the controller against it, waits for it.
///
/// # Errors
/// A bad flag, or the plant could not be started.
pub fn run_hil(a: &HilArgs) -> Result<ExitCode> {
    ipc::quiet_logs();
    crate::rt::install_termination_handler();
    crate::rt::tight_timer_slack();
    let s = a.scenario()?;
    a.timing(&s)?;
    ipc::validate_name(&a.name)?;
    if let Some(w) = a.cpu_warning() {
        eprintln!("warning: {w}");
    }
    let cfg = ipc::config()?;
    for role in [Role::Control, Role::Plant] {
        if let Err(e) = ipc::ensure_name_free(&cfg, &a.name, role) {
            return name_in_use_or(e);
        }
    }
    let exe = std::env::current_exe().map_err(|e| anyhow!("locating this program: {e}"))?;
    // The plant gets the same flags, except the controller-only `--inject` (and its value).
    let mut fwd = Vec::new();
    let mut skip = false;
    for x in forwarded_args() {
        if skip {
            skip = false;
        } else if x == "--inject" {
            skip = true;
        } else if !x.to_string_lossy().starts_with("--inject=") {
            fwd.push(x);
        }
    }
    let child = Process::new(&exe)
        .arg("plant")
        .args(&fwd)
        .arg("--child")
        .stdin(Stdio::null())
        .spawn()
        .map_err(|e| anyhow!("starting the plant ({} plant): {e}", exe.display()))?;
    eprintln!("started the plant (pid {}); controller is pid {}", child.id(), std::process::id());
    control::run_as_parent(a, &s, child)
}

/// `companion plant`.
///
/// # Errors
/// A bad flag, a transport failure, or files that cannot be written.
pub fn run_plant(a: &PlantArgs) -> Result<ExitCode> {
    ipc::quiet_logs();
    crate::rt::install_termination_handler();
    crate::rt::tight_timer_slack();
    plant::run(a).or_else(name_in_use_or)
}

/// `companion control`.
///
/// # Errors
/// A bad flag or a transport failure.
pub fn run_control(a: &ControlArgs) -> Result<ExitCode> {
    ipc::quiet_logs();
    crate::rt::install_termination_handler();
    crate::rt::tight_timer_slack();
    control::run_alone(a).or_else(name_in_use_or)
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
    use clap::Parser;

    use super::*;

    #[derive(Parser, Debug)]
    struct T {
        #[command(flatten)]
        a: HilArgs,
    }

    #[test]
    fn defaults_give_30_s_at_1_khz_with_a_500_us_deadline() {
        let t = T::parse_from(["x"]);
        let s = t.a.scenario().unwrap();
        assert_eq!(s.duration, 30.0);
        let tm = t.a.timing(&s).unwrap();
        assert_eq!(tm.period_ns, 1_000_000);
        assert_eq!(tm.deadline_ns, 500_000);
        assert_eq!(tm.hold_periods, 20);
        let expected = if crate::rt::online_cpus() >= 2 { WaitMode::Spin } else { WaitMode::Hybrid };
        assert_eq!(tm.wait, expected);
        assert!(!tm.lockstep);
        let t = T::parse_from(["x", "--rt"]);
        assert_eq!(t.a.timing(&s).unwrap().wait, WaitMode::Hybrid);
        let t = T::parse_from(["x", "--rt", "--wait", "spin"]);
        assert_eq!(t.a.timing(&s).unwrap().wait, WaitMode::Spin);
    }

    #[test]
    fn a_deadline_beyond_the_period_is_refused() {
        let t = T::parse_from(["x", "--rate", "2000", "--deadline-us", "600"]);
        let s = t.a.scenario().unwrap();
        let e = t.a.timing(&s).unwrap_err().to_string();
        assert!(e.contains("--deadline-us"), "{e}");
    }

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
