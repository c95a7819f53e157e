//! `companion hil`, `companion plant` and `companion control`: their flags, their progress
//! line, their tables and their exit codes.

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::{Command as Process, ExitCode, ExitStatus, Stdio};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{anyhow, bail, Result};
use clap::{Args, ValueEnum};
use companion_runtime::domain::histogram::fmt_ns;
use companion_runtime::domain::record::verdict::{rejection_failure, DEFAULT_MAX_MISS_FRACTION};
use companion_runtime::domain::record::Failure;
use companion_runtime::domain::scenario::{short, Scenario, ScenarioBuilder};
use companion_runtime::run::hil::chaos::{self, Plan};
use companion_runtime::run::hil::control::{run_as_parent, session, Faults, ParentOutcome, Session};
use companion_runtime::run::hil::fault::Corruption;
use companion_runtime::run::hil::plant::PlantLock;
use companion_runtime::run::hil::report::LatencyReport;
use companion_runtime::run::hil::stats::LiveFigures;
use companion_runtime::run::hil::{
    ChaosConfig, ControlEnd, HilConfig, HilScenario, PlantEnd, ReleaseTimer, RtPlan, Timing, WaitMode,
    MAX_COMMAND_AGE,
};
use companion_runtime::sys::lock::{self, NameLock, Role};
use companion_runtime::sys::process::ChildGuard;
use companion_runtime::sys::signals::termination_requested;
use companion_runtime::transport::ipc;
use companion_runtime::transport::{self, SecurityFlags, Transport};

use super::args::ScenarioArgs;
use super::exit::{
    EXIT_CHAOS_MISMATCH, EXIT_DEADLINES, EXIT_ERROR, EXIT_INTERRUPTED, EXIT_NAME_IN_USE, EXIT_PEER_HUNG,
    EXIT_PEER_LOST, EXIT_REJECTED,
};
use super::mujoco::{plant_process, DemoFlags, PlantArg};
use super::sim::print_table;
use super::terminal::Terminal;

/// The default simulated duration of a HIL run when `--duration` is not given (s).
pub const DEFAULT_DURATION: f64 = 30.0;

/// The default `--out` of the HIL commands.
const DEFAULT_OUT: &str = "out/hil";

/// `--wait --help`: which mode to pick when.
pub const WAIT_LONG_HELP: &str = "\
How each process waits for the other's message (and the plant for its release time).

Which to pick:
  adaptive  (the default) when in doubt. On 1-2 CPUs it waits on the iceoryx2 event, as
            `event` does: two loops spinning there take every CPU, and whatever else wakes
            preempts one of them. With 3 or more CPUs it spins, and after a preemption or
            under CPU pressure waits on the event for a back-off.
  event     a shared or virtual machine, a laptop, anything that also runs other work: each
            process sleeps until the other's notification (round trip ~40-60 us on this
            project's 2-vCPU VMs); the plant sleeps to each release by --release-timer.
  spin      a core of its own for each process and nothing else running on them (e.g. CPUs
            isolated with isolcpus, with --rt): the lowest round trip (~10 us), but a
            spinner that is preempted loses whole time slices - about half the deadlines
            missed with other work on 2 CPUs.
  hybrid    sleep on a timer until --spin-margin-us before the expected message, then spin
            (200 us at most, then 50 us naps): for comparison; on the VMs it missed more
            than the others when idle.

`companion latency --repeat 10` measures every mode on your machine, idle and under load, in
interleaved rounds; the latency chapter of the docs has this project's figures.";

/// `--wait`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum WaitArg {
    /// The event on 1-2 CPUs; with more, spin while the process keeps its CPU (the default).
    Adaptive,
    /// Busy-poll: a free core per process.
    Spin,
    /// Sleep until the other's notification (iceoryx2 event service).
    Event,
    /// Timer sleep until shortly before the expected message, then spin.
    Hybrid,
}

impl From<WaitArg> for WaitMode {
    fn from(w: WaitArg) -> Self {
        match w {
            WaitArg::Adaptive => WaitMode::Adaptive,
            WaitArg::Spin => WaitMode::Spin,
            WaitArg::Event => WaitMode::Event,
            WaitArg::Hybrid => WaitMode::Hybrid,
        }
    }
}

impl From<WaitMode> for WaitArg {
    fn from(w: WaitMode) -> Self {
        match w {
            WaitMode::Adaptive => Self::Adaptive,
            WaitMode::Spin => Self::Spin,
            WaitMode::Event => Self::Event,
            WaitMode::Hybrid => Self::Hybrid,
        }
    }
}

/// `--release-timer`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ReleaseTimerArg {
    /// clock_nanosleep(TIMER_ABSTIME) to the release.
    Sleep,
    /// A timerfd armed to the release.
    Timerfd,
    /// clock_nanosleep to --spin-margin-us before the release, then spin (the default).
    Margin,
    /// clock_nanosleep under SCHED_FIFO (the plant's loop thread, where permitted).
    Fifo,
}

impl From<ReleaseTimerArg> for ReleaseTimer {
    fn from(r: ReleaseTimerArg) -> Self {
        match r {
            ReleaseTimerArg::Sleep => Self::Sleep,
            ReleaseTimerArg::Timerfd => Self::Timerfd,
            ReleaseTimerArg::Margin => Self::Margin,
            ReleaseTimerArg::Fifo => Self::Fifo,
        }
    }
}

/// The longest `--peer-timeout` (s).
const MAX_PEER_TIMEOUT_S: f64 = 3600.0;
/// The longest `--startup-timeout` (s).
const MAX_STARTUP_TIMEOUT_S: f64 = 86_400.0;

/// `--transport`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum TransportArg {
    /// iceoryx2 shared memory: both roles on one machine.
    Iceoryx2,
    /// Zenoh over mutual TLS (plain TCP with --insecure): the roles on one machine or two (a
    /// build with `--features zenoh`).
    Zenoh,
}

/// Flags of `companion hil`, `companion plant` and `companion control` (one set, so that the
/// demo can hand its own flags to the plant it starts; each role uses the flags it needs).
#[derive(Args, Clone, Debug)]
pub struct HilArgs {
    #[command(flatten)]
    /// The scenario (give both roles the same one). `--duration` defaults to 30 s here.
    pub scenario: ScenarioArgs,
    /// Control rate in Hz [default: 1/--dt].
    ///
    /// Control rate in Hz (default: 1/--dt, so that simulated time runs at wall-clock speed).
    #[arg(long, value_name = "HZ", allow_hyphen_values = true)]
    pub rate: Option<f64>,
    /// Deadline after each period's release, in µs.
    ///
    /// Deadline of each command after its period's release, in microseconds (at most the
    /// period).
    #[arg(long, default_value_t = 500, value_name = "US", value_parser = clap::value_parser!(u64).range(1..=1_000_000), allow_hyphen_values = true)]
    pub deadline_us: u64,
    /// The plant waits for every command: the same run as sim.
    ///
    /// Lockstep: the plant waits for every command (deterministic, no deadlines; the same
    /// timeseries.csv as `companion sim`). For `hil` and `plant`: `control` follows what the
    /// plant announces (it warns that it ignores the flag).
    #[arg(long)]
    pub lockstep: bool,
    /// How each process waits for the other's message ([`WAIT_LONG_HELP`]).
    #[arg(
        long,
        value_enum,
        default_value = "adaptive",
        value_name = "MODE",
        hide_possible_values = true,
        hide_default_value = true,
        help = "How each process waits [default: adaptive]; others: --help",
        long_help = WAIT_LONG_HELP
    )]
    pub wait: WaitArg,
    /// How the plant sleeps to a release (see --help)
    ///
    /// Where its wait mode sleeps (event; adaptive on the event): margin (clock_nanosleep to
    /// --spin-margin-us before it, then spin; it missed least on this project's VMs), sleep
    /// (clock_nanosleep to it), timerfd, or fifo (clock_nanosleep under SCHED_FIFO, where
    /// permitted).
    #[arg(long, value_enum, default_value = "margin", value_name = "TIMER", hide_possible_values = true)]
    pub release_timer: ReleaseTimerArg,
    /// Real-time setup: mlockall, SCHED_FIFO, one CPU per process.
    ///
    /// Real-time setup: mlockall, SCHED_FIFO, one CPU per process, pre-faulted stack (a missing
    /// privilege is a warning).
    #[arg(long)]
    pub rt: bool,
    /// SCHED_FIFO priority with --rt.
    #[arg(long, default_value_t = 80, value_parser = clap::value_parser!(i32).range(1..=99), allow_hyphen_values = true)]
    pub rt_priority: i32,
    /// The plant's CPU with --rt [default: 1 with 2+ CPUs].
    ///
    /// The plant's CPU with --rt (default: 1 on a machine with two or more CPUs).
    #[arg(long, value_name = "CPU", allow_hyphen_values = true)]
    pub plant_cpu: Option<usize>,
    /// The controller's CPU with --rt [default: 0].
    #[arg(long, value_name = "CPU", allow_hyphen_values = true)]
    pub control_cpu: Option<usize>,
    /// The demo's name: its services and its lock.
    ///
    /// The demo's name: its iceoryx2 services are companion/NAME/…, so demos with different
    /// names never meet; one process per role and name (a lock in /tmp/companion).
    #[arg(long, default_value = "demo")]
    pub name: String,
    /// Output folder (the plant writes it).
    ///
    /// Output folder (the plant writes it; `control` writes nothing and warns that it ignores
    /// the flag).
    #[arg(long, default_value = DEFAULT_OUT, value_name = "DIR")]
    pub out: PathBuf,
    /// The plant also writes the run as MCAP, for Foxglove.
    ///
    /// The plant also writes the run as an MCAP file for Foxglove (the robot in 3D: frame
    /// transforms, a scene, joint states, command, tracking error), one frame per row of
    /// timeseries.csv (--log-every decimates it too). For `hil` and `plant`.
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// Periods held after a miss before the robot stops.
    ///
    /// Periods the plant holds the last command after a miss before it stops the robot
    /// (0–100000).
    #[arg(long, default_value_t = 20, value_name = "K", value_parser = clap::value_parser!(u32).range(0..=100_000), allow_hyphen_values = true)]
    pub hold_periods: u32,
    /// Apply answers up to K periods old (slow links).
    ///
    /// Real time: apply an answer to a measurement up to K periods old when the answer to the
    /// current one has not come by the deadline (0–8; 0: only the current period's). For
    /// links whose round trip is longer than the deadline, e.g. Zenoh across a network; the
    /// plant measures and announces the delay, the controller predicts over it.
    #[arg(long, default_value_t = 0, value_name = "K", value_parser = clap::value_parser!(u32).range(0..=i64::from(MAX_COMMAND_AGE)), allow_hyphen_values = true)]
    pub max_command_age: u32,
    /// Exit 7 above this fraction of missed deadlines.
    ///
    /// A real-time run that misses more than this fraction of its deadlines fails (exit code
    /// 7, with a warning); so does one in which the robot was stopped.
    #[arg(long, default_value_t = DEFAULT_MAX_MISS_FRACTION, value_name = "FRAC", allow_hyphen_values = true)]
    pub max_miss_fraction: f64,
    /// µs of spinning before a message or release
    ///
    /// Hybrid waiting: how long before the expected message to stop sleeping and spin; also
    /// how long before a release `--release-timer margin` wakes (µs, at most 1 s).
    #[arg(long, default_value_t = 100, value_name = "US", value_parser = clap::value_parser!(u64).range(0..=1_000_000), allow_hyphen_values = true)]
    pub spin_margin_us: u64,
    /// Silence before checking the peer is alive, in ms.
    ///
    /// Silence (no message) after which a process checks whether its peer is alive (ms,
    /// 1–60000).
    #[arg(long, default_value_t = 20, value_name = "MS", value_parser = clap::value_parser!(u64).range(1..=60_000), allow_hyphen_values = true)]
    pub silence_ms: u64,
    /// Give up on a live but silent peer after this, in s.
    ///
    /// Give up when the peer is alive but silent for this long (s, at most 3600).
    #[arg(long, default_value_t = 2.0, value_name = "SECONDS", allow_hyphen_values = true)]
    pub peer_timeout: f64,
    /// How long to wait for the peer to join, in s.
    ///
    /// How long to wait for the peer to join at start (s, at most 86400).
    #[arg(long, default_value_t = 20.0, value_name = "SECONDS", allow_hyphen_values = true)]
    pub startup_timeout: f64,
    /// Skip the plots (CSV and JSON only).
    #[arg(long)]
    pub no_plots: bool,
    /// Shared memory, or Zenoh across machines.
    ///
    /// The transport between the two roles: iceoryx2 shared memory on one machine, or Zenoh
    /// over mutual TLS across machines (`companion plant --transport zenoh --listen
    /// quic/ADDR:PORT`, `companion control --transport zenoh --connect quic/ADDR:PORT`, each with
    /// --tls-ca, --tls-cert, --tls-key and --tls-peer; `companion hil` picks a free local port
    /// and makes throwaway certificates). Zenoh needs a build with `--features zenoh`. The
    /// book's chapter "Two machines" (docs/book/src/two-machines.md) sets it up step by step.
    #[arg(
        long,
        value_enum,
        default_value = "iceoryx2",
        value_name = "iceoryx2|zenoh",
        hide_possible_values = true
    )]
    pub transport: TransportArg,
    /// Zenoh: the endpoint to listen on (the plant).
    ///
    /// Zenoh: listen on this endpoint, quic/ADDR:PORT (usually the plant; 0.0.0.0 for every
    /// interface; tcp/ADDR:PORT only with --insecure).
    #[arg(long, value_name = "quic/ADDR:PORT")]
    pub listen: Option<String>,
    /// Zenoh: the endpoint to connect to (the controller).
    ///
    /// Zenoh: connect to this endpoint, quic/ADDR:PORT (usually the controller; retried until
    /// the peer listens, up to --startup-timeout). Over TLS the listener's certificate must be
    /// valid for ADDR.
    #[arg(long, value_name = "quic/ADDR:PORT")]
    pub connect: Option<String>,
    /// Zenoh over TLS: the deployment's CA certificate (PEM).
    ///
    /// Zenoh over TLS: the deployment's CA certificate, which the peer's certificate must be
    /// signed by (PEM; `companion certs` writes it as ca.pem).
    #[arg(long, value_name = "FILE")]
    pub tls_ca: Option<PathBuf>,
    /// Zenoh over TLS: this host's certificate (PEM).
    ///
    /// Zenoh over TLS: this host's certificate, signed by the CA (PEM, HOST.pem).
    #[arg(long, value_name = "FILE")]
    pub tls_cert: Option<PathBuf>,
    /// Zenoh over TLS: this host's private key (PEM).
    ///
    /// Zenoh over TLS: this host's private key (PEM, HOST.key, owner-only).
    #[arg(long, value_name = "FILE")]
    pub tls_key: Option<PathBuf>,
    /// Zenoh over TLS: the certificate name of the one peer served.
    ///
    /// Zenoh over TLS: the name (common name) on the certificate of the only peer this side
    /// serves, e.g. ctrl.local on the plant and plant.local on the controller; a peer with
    /// another certificate of the same CA is refused and named in the log.
    #[arg(long, value_name = "NAME[,NAME]")]
    pub tls_peer: Option<String>,
    /// Zenoh: plain TCP, no authentication, no encryption.
    ///
    /// Zenoh: plain TCP (tcp/ endpoints) with neither authentication nor encryption — anyone
    /// who reaches the port can drive the robot and anyone on the path read and alter the
    /// traffic. Warned at start and recorded in summary.json.
    #[arg(long)]
    pub insecure: bool,
    /// Lockstep: simulate this pure delay, in s.
    ///
    /// Lockstep only: the plant simulates a pure delay between a measurement and the moment
    /// its command takes effect (s, 0 to 8 periods and at most the law's max_delay), and
    /// announces it to the controller — the same run as `companion sim --delay`. In real
    /// time the plant measures the delay itself.
    #[arg(long, default_value_t = 0.0, value_name = "SECONDS", allow_negative_numbers = true)]
    pub delay: f64,
    /// The controller ignores the delay the plant announces.
    ///
    /// The controller ignores the delay the plant announces (predicts over 0), to see what the
    /// delay does uncompensated.
    #[arg(long)]
    pub no_delay_compensation: bool,
    /// rpr (default, the paper's), ur5, panda, or a TOML or URDF file
    ///
    /// The arm: `rpr` (the paper's planar arm, §4), the presets `ur5` (6 joints) and `panda`
    /// (7 joints), or a TOML arm file of 6–8 joints (see examples/arms/ur5.toml) — the
    /// spatial law of §5 on the paper's trajectory lifted (--trajectory 1|2) or a spatial
    /// --target-file, as `companion sim --arm`, with the platform settings the arm carries.
    /// Give both roles the same arm: the handshake compares the arms' hashes. What each preset
    /// carries and why: the book's chapter "Spatial arms" (docs/book/src/spatial-arms.md).
    #[arg(long, default_value = "rpr", hide_default_value = true, value_name = "ARM")]
    pub arm: String,
    /// No live progress line.
    #[arg(long)]
    pub quiet: bool,
    /// A soak: inject faults from this seed, check the counts.
    ///
    /// A soak: inject faults from this seed — SIGSTOPs of either process (20–400 ms, every
    /// 1–3 s), corrupted commands (2 per second) and commands held back for 2 to
    /// --hold-periods/2 periods (one every 2 s) — and check that the counts in latency.json
    /// match what was injected (chaos.json; exit code 8 if not). `companion hil` only; at
    /// least 5 s.
    #[arg(long, value_name = "SEED", allow_hyphen_values = true)]
    pub chaos: Option<u64>,
    /// Set by `companion hil --chaos` on the plant it starts: the time the faults count from.
    #[arg(long, hide = true)]
    pub chaos_epoch_ns: Option<u64>,
    /// Testing: the controller also sends corrupted commands, e.g. `version@100,nan@200,seq@300,
    /// session@400` (each is sent once, before the good answer to the first measurement with
    /// at least that sequence number).
    #[arg(long, hide = true, value_name = "LIST")]
    pub inject: Option<String>,
    /// Set by `companion hil` on the plant it starts.
    #[arg(long, hide = true)]
    pub child: bool,
    /// The plant hil starts: kinematic or mujoco.
    ///
    /// The plant `companion hil` starts: `kinematic` (`companion plant`: the kinematics
    /// integrated exactly) or `mujoco` (the MuJoCo plant, bridges/mujoco: the robot's URDF with
    /// wheels, drives, servos and gravity, in target/py's Python). The book's chapter "Physics
    /// plant (MuJoCo)" (docs/book/src/mujoco.md) tells what it simulates and measures.
    #[arg(long, value_enum, default_value = "kinematic", value_name = "PLANT", hide_possible_values = true)]
    pub plant: PlantArg,
    /// --plant mujoco: one more of its own flags.
    ///
    /// With --plant mujoco: one more argument for the MuJoCo plant (repeatable), e.g.
    /// `--plant-arg=--set=arm.time_constant=0.002` or `--plant-arg=--filmstrip=0`
    /// (`target/py/bin/python bridges/mujoco/companion_mujoco.py --help` lists them).
    #[arg(long = "plant-arg", value_name = "ARG", allow_hyphen_values = true)]
    pub plant_args: Vec<String>,
}

fn secs_to_ns(s: f64) -> u64 {
    (s * 1e9).round() as u64
}

/// Checks that `x` seconds is in `(0, max]` (`zero_ok`: `[0, max]`).
fn seconds(flag: &str, x: f64, max: f64, zero_ok: bool) -> Result<f64> {
    let low_ok = if zero_ok { x >= 0.0 } else { x > 0.0 };
    if x.is_finite() && low_ok && x <= max {
        Ok(x)
    } else {
        let low = if zero_ok { "[0" } else { "(0" };
        bail!("{flag} must be a number of seconds in {low}, {max}], got {}", short(x))
    }
}

impl HilArgs {
    /// The timing options.
    ///
    /// # Errors
    /// A rate, deadline or timeout out of range.
    pub fn timing(&self, s: &Scenario) -> Result<Timing> {
        let rate = self.rate.unwrap_or(1.0 / s.dt);
        if !(rate.is_finite() && (1.0..=100_000.0).contains(&rate)) {
            bail!("--rate must be between 1 and 100000 Hz, got {}", short(rate));
        }
        let period_ns = secs_to_ns(1.0 / rate);
        let deadline_ns = self.deadline_us * 1000;
        if !self.lockstep && deadline_ns > period_ns {
            bail!(
                "--deadline-us must be in (0, period] = (0, {}] µs at {rate} Hz, got {}",
                period_ns / 1000,
                self.deadline_us
            );
        }
        let peer_timeout = seconds("--peer-timeout", self.peer_timeout, MAX_PEER_TIMEOUT_S, false)?;
        Ok(Timing {
            period_ns: if self.lockstep { 0 } else { period_ns },
            deadline_ns,
            hold_periods: self.hold_periods,
            wait: self.wait.into(),
            release: self.release_timer.into(),
            spin_margin_ns: self.spin_margin_us * 1000,
            silence_ns: self.silence_ms * 1_000_000,
            peer_timeout_ns: secs_to_ns(peer_timeout),
            lockstep: self.lockstep,
            max_command_age: if self.lockstep { 0 } else { self.max_command_age },
        })
    }

    /// The typed configuration and the scenario. Every flag, the config and target files and
    /// the plant's parameters are checked here, before any process starts or any file is
    /// written.
    ///
    /// # Errors
    /// A bad flag value or file, naming the flag or parameter and the rule.
    pub fn resolve(&self) -> Result<(HilConfig, HilScenario)> {
        // The one check of the demo's name: everything below takes the checked name.
        let name = lock::DemoName::new(&self.name)?;
        if self.delay != 0.0 && !self.lockstep {
            bail!(
                "--delay simulates a pure delay in lockstep (--lockstep); in real time the plant measures the \
                 delay of every command itself"
            );
        }
        let more = |b: ScenarioBuilder| b.delay(self.delay).delay_compensation(!self.no_delay_compensation);
        let hs = match self.scenario.arm_spec(&self.arm)? {
            None => HilScenario::Planar(self.scenario.scenario_with(DEFAULT_DURATION, more)?),
            Some(arm) => HilScenario::Spatial(self.scenario.spatial_scenario(arm, DEFAULT_DURATION, more)?),
        };
        let s = hs.base();
        let timing = self.timing(s)?;
        let startup = seconds("--startup-timeout", self.startup_timeout, MAX_STARTUP_TIMEOUT_S, true)?;
        let startup_timeout = Duration::from_secs_f64(startup);
        let acceptance = self.scenario.acceptance(self.max_miss_fraction)?;
        let (plant_cpu, control_cpu) = RtPlan::default_cpus();
        let rt = self.rt.then(|| RtPlan {
            priority: self.rt_priority,
            plant_cpu: self.plant_cpu.unwrap_or(plant_cpu),
            control_cpu: self.control_cpu.unwrap_or(control_cpu),
        });
        let chaos = match (self.chaos, self.chaos_epoch_ns) {
            (None, _) => None,
            (Some(seed), epoch) => {
                // The plan is made now to check the flags (the run's length, real time).
                Plan::new(seed, s.steps(), &timing)?;
                Some(ChaosConfig { seed, epoch_ns: epoch.unwrap_or(0) })
            }
        };
        let sec = SecurityFlags {
            ca: self.tls_ca.clone(),
            cert: self.tls_cert.clone(),
            key: self.tls_key.clone(),
            peer: self.tls_peer.clone(),
            insecure: self.insecure,
        };
        let transport = match self.transport {
            TransportArg::Iceoryx2 if self.listen.is_some() || self.connect.is_some() => {
                bail!("--listen and --connect are endpoints of --transport zenoh")
            }
            TransportArg::Iceoryx2 if sec != SecurityFlags::default() => {
                bail!("--tls-ca, --tls-cert, --tls-key, --tls-peer and --insecure are for --transport zenoh")
            }
            TransportArg::Iceoryx2 => Transport::Iceoryx2,
            TransportArg::Zenoh => transport::zenoh(self.listen.as_deref(), self.connect.as_deref(), &sec)?,
        };
        if transport.insecure() && !self.child {
            eprintln!(
                "warning: --insecure: plain TCP, no authentication, no encryption — anyone who reaches {} can \
                 drive the robot and anyone on the path read and alter its traffic (recorded in summary.json)",
                self.listen.as_deref().or(self.connect.as_deref()).unwrap_or("the port")
            );
        }
        if transport.tls_over_tcp() && !self.child {
            eprintln!(
                "warning: tls/ is zenoh's TLS-over-TCP link, which reads and writes one TLS connection from two \
                 tasks at once (eclipse-zenoh/zenoh#2557): under load it loses the link within seconds and the \
                 run ends as a dead peer; use quic/ (the same mutual TLS over UDP) unless UDP cannot pass"
            );
        }
        let cfg = HilConfig {
            name,
            out: self.out.clone(),
            timing,
            startup_timeout,
            rt,
            no_plots: self.no_plots,
            acceptance,
            chaos,
            transport,
            mcap: self.mcap.clone(),
        };
        Ok((cfg, hs))
    }

    /// `--inject`, parsed.
    ///
    /// # Errors
    /// An unknown kind or a bad number.
    pub fn injections(&self) -> Result<Vec<(u64, Corruption)>> {
        self.inject.as_deref().map_or_else(|| Ok(Vec::new()), parse_injections)
    }
}

/// Parses `version@100,nan@200,seq@300,session@400`.
///
/// # Errors
/// An unknown kind or a bad number.
pub fn parse_injections(s: &str) -> Result<Vec<(u64, Corruption)>> {
    s.split(',')
        .filter(|x| !x.trim().is_empty())
        .map(|item| {
            let (kind, at) =
                item.trim().split_once('@').ok_or_else(|| anyhow!("--inject item {item:?}: KIND@SEQ"))?;
            let kind = match kind {
                "version" => Corruption::Version,
                "nan" => Corruption::Nan,
                "seq" => Corruption::Seq,
                "session" => Corruption::Session,
                _ => bail!("--inject: unknown kind {kind:?} (version, nan, seq, session)"),
            };
            Ok((at.parse::<u64>().map_err(|e| anyhow!("--inject {item:?}: {e}"))?, kind))
        })
        .collect()
}

/// The exit code of a run that ended (no peer lost) with `failures`: 6 for the law's
/// rejections, else 7 for deadlines, else 0.
fn failures_code(failures: &[Failure]) -> u8 {
    if failures.iter().any(|f| matches!(f, Failure::Rejected { .. })) {
        EXIT_REJECTED
    } else if failures.is_empty() {
        0
    } else {
        EXIT_DEADLINES
    }
}

/// The exit code of a plant's run.
fn plant_exit_code(end: &PlantEnd, failures: &[Failure]) -> u8 {
    match end {
        PlantEnd::Completed => failures_code(failures),
        PlantEnd::Interrupted { .. } => EXIT_INTERRUPTED,
        PlantEnd::ControllerDied { .. } | PlantEnd::ControllerGone { .. } => EXIT_PEER_LOST,
        PlantEnd::ControllerHung { .. } => EXIT_PEER_HUNG,
        PlantEnd::Refused(_) => EXIT_ERROR,
    }
}

/// The exit code of a controller's run.
fn control_exit_code(end: &ControlEnd) -> u8 {
    match end {
        ControlEnd::EndOfRun => 0,
        ControlEnd::PlantDied { .. } | ControlEnd::PlantGone { .. } => EXIT_PEER_LOST,
        ControlEnd::PlantHung { .. } => EXIT_PEER_HUNG,
        ControlEnd::Interrupted => EXIT_INTERRUPTED,
    }
}

/// The exit code of an error `e`: a demo found running (`in_use`, what the typed error's
/// `name_in_use()` found in it; printed) is 5; an error after SIGINT/SIGTERM (e.g. while
/// waiting for the peer) is 130; other errors go up.
fn name_in_use_or(in_use: Option<lock::NameInUse>, e: impl Into<anyhow::Error>) -> Result<ExitCode> {
    let e: anyhow::Error = e.into();
    if let Some(n) = in_use {
        eprintln!("error: {n}");
        return Ok(ExitCode::from(EXIT_NAME_IN_USE));
    }
    if termination_requested() {
        eprintln!("interrupted: {e:#}");
        return Ok(ExitCode::from(EXIT_INTERRUPTED));
    }
    Err(e)
}

/// What every role does first: quiet iceoryx2 logs, SIGINT/SIGTERM handlers, a tight timer
/// slack.
fn setup() -> Result<()> {
    ipc::quiet_logs();
    companion_runtime::sys::signals::install_termination_handler()?;
    companion_runtime::sys::rt::tight_timer_slack();
    Ok(())
}

/// The flags after the `hil` subcommand in this process's command line, without the
/// controller-only `--inject` (handed to the plant).
fn forwarded_args() -> Vec<OsString> {
    let args: Vec<OsString> = std::env::args_os().collect();
    let after = match args.iter().position(|a| a == "hil") {
        Some(i) => &args[i + 1..],
        None => &[][..],
    };
    let mut fwd = Vec::new();
    let mut skip = false;
    for x in after {
        if skip {
            skip = false;
        } else if x == "--inject" {
            skip = true;
        } else if !x.to_string_lossy().starts_with("--inject=") {
            fwd.push(x.clone());
        }
    }
    fwd
}

/// `--out` names a folder, or nothing yet (it is made): never a file.
///
/// # Errors
/// `out` is an existing file (or anything else that is not a folder).
fn out_is_a_folder(out: &std::path::Path) -> Result<()> {
    if out.exists() && !out.is_dir() {
        bail!(
            "--out {}: a file, not a folder: give a folder (made if missing) for the run's files",
            out.display()
        );
    }
    Ok(())
}

/// The plant's exit code as the demo's: one of the book's table (`exit::EXIT_CODES`); a code
/// the table does not have (a plant that crashed: a Python traceback exits 1) or a signal is
/// `otherwise`.
fn code_of(st: Option<ExitStatus>, otherwise: u8) -> u8 {
    st.and_then(table_code).unwrap_or(otherwise)
}

/// The process's exit code if it is one of the exit-code table's.
fn table_code(st: ExitStatus) -> Option<u8> {
    st.code()
        .and_then(|c| u8::try_from(c).ok())
        .filter(|c| super::exit::EXIT_CODES.iter().any(|e| e.code == *c))
}

/// How a plant's end falls outside the exit-code table, for a person (None: inside it).
fn outside_the_table(st: ExitStatus) -> Option<String> {
    use std::os::unix::process::ExitStatusExt as _;
    if table_code(st).is_some() {
        return None;
    }
    Some(match st.signal() {
        Some(n) => format!("was killed by signal {n}"),
        None => format!("ended with {st}, not one of companion's exit codes"),
    })
}

/// The TLS material `companion hil --transport zenoh` makes for its two roles (hosts `plant`,
/// valid for 127.0.0.1, and `control`), removed when dropped.
struct Throwaway {
    dir: PathBuf,
    ca: PathBuf,
    /// (certificate, key) of the plant and of the controller.
    plant: (PathBuf, PathBuf),
    control: (PathBuf, PathBuf),
}

impl Throwaway {
    fn make(name: &str) -> Result<Self> {
        #[cfg(feature = "zenoh")]
        {
            use companion_runtime::transport::certs::{make, Host, Validity};
            let dir = std::env::temp_dir().join(format!("companion-tls-{name}-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&dir);
            let mut m =
                make(&dir, &Host::parse_list("plant=127.0.0.1+localhost,control")?, Validity::days(2))?;
            let (_, cc, ck) = m.hosts.pop().expect("two hosts");
            let (_, pc, pk) = m.hosts.pop().expect("two hosts");
            Ok(Self { dir, ca: m.ca, plant: (pc, pk), control: (cc, ck) })
        }
        #[cfg(not(feature = "zenoh"))]
        {
            let _ = name;
            bail!("--transport zenoh: {}", transport::BUILD_WITH_ZENOH)
        }
    }
}

impl Drop for Throwaway {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// `companion hil`: takes the demo's name, starts the plant, runs the controller against it,
/// waits for it.
///
/// # Errors
/// A bad flag, or the plant could not be started.
pub fn run_hil(a: &HilArgs) -> Result<ExitCode> {
    setup()?;
    if a.connect.is_some() {
        bail!(
            "companion hil runs both roles: give the plant's --listen endpoint (or none: a free local port)"
        );
    }
    // Zenoh on one machine: the plant listens on a free local port unless told where.
    let picked = (a.transport == TransportArg::Zenoh && a.listen.is_none())
        .then(|| transport::free_local_endpoint(a.insecure))
        .transpose()?;
    let mut own = a.clone();
    if let Some(ep) = &picked {
        own.listen = Some(ep.clone());
    }
    // Zenoh over TLS on one machine without certificates given: a throwaway CA and a
    // certificate per role, in an owner-only folder removed when the demo ends.
    let throwaway = (a.transport == TransportArg::Zenoh
        && !a.insecure
        && a.tls_ca.is_none()
        && a.tls_cert.is_none()
        && a.tls_key.is_none()
        && a.tls_peer.is_none())
    .then(|| Throwaway::make(&a.name))
    .transpose()?;
    let mut plant_tls = Vec::new();
    if let Some(t) = &throwaway {
        let arg = |flag: &str, p: &std::path::Path| [flag.to_string(), p.display().to_string()];
        plant_tls.extend(arg("--tls-ca", &t.ca));
        plant_tls.extend(arg("--tls-cert", &t.plant.0));
        plant_tls.extend(arg("--tls-key", &t.plant.1));
        plant_tls.extend(["--tls-peer".to_string(), "control".to_string()]);
        own.tls_ca = Some(t.ca.clone());
        own.tls_cert = Some(t.control.0.clone());
        own.tls_key = Some(t.control.1.clone());
        own.tls_peer = Some("plant".to_string());
    }
    let (mut cfg, s) = own.resolve()?;
    let inject = a.injections()?;
    if a.child {
        bail!("--child is for the plant that `companion hil` starts");
    }
    if a.plant == PlantArg::Kinematic && !a.plant_args.is_empty() {
        bail!("--plant-arg is for --plant mujoco");
    }
    out_is_a_folder(&cfg.out)?;
    // The plant's command, checked whole before anything of the run exists (the MuJoCo plant
    // checks its own flags and builds its robot first: `mujoco::plant_process`).
    let exe = std::env::current_exe().map_err(|e| anyhow!("locating this program: {e}"))?;
    let mut plant = Process::new(&exe);
    if a.plant == PlantArg::Mujoco {
        let unsupported = [
            (a.transport != TransportArg::Iceoryx2, "--transport zenoh"),
            (a.chaos.is_some(), "--chaos"),
            (a.mcap.is_some(), "--mcap"),
            (a.delay != 0.0, "--delay"),
            (a.max_command_age != 0, "--max-command-age"),
        ];
        let unsupported = unsupported.iter().filter(|(given, _)| *given).map(|(_, f)| *f).collect();
        let flags = DemoFlags { arm: &a.arm, scenario: &a.scenario, plant_args: &a.plant_args, unsupported };
        plant = plant_process(&flags, &cfg, &s)?;
    } else {
        plant
            .arg("plant")
            .args(forwarded_args())
            .args(picked.iter().flat_map(|ep| ["--listen".to_string(), ep.clone()]))
            .args(&plant_tls)
            .arg("--child");
    }
    if termination_requested() {
        eprintln!("interrupted before the run started: nothing written");
        return Ok(ExitCode::from(EXIT_INTERRUPTED));
    }
    if let Some(w) = cfg.cpu_warning() {
        eprintln!("warning: {w}");
    }
    // Both roles of the name, before anything of this demo exists: of two demos started at
    // once with one name, exactly one gets them.
    // (One after the other: of two demos, the one without the controller's lock must not
    // take the plant's.)
    let locks = match NameLock::acquire(&cfg.name, Role::Control)
        .and_then(|c| Ok([c, NameLock::acquire(&cfg.name, Role::Plant)?]))
    {
        Ok(l) => l,
        Err(e) => return name_in_use_or(e.name_in_use().cloned(), e),
    };
    if cfg.transport == Transport::Iceoryx2 {
        let iox = ipc::config()?;
        for role in [Role::Control, Role::Plant] {
            if let Err(e) = ipc::ensure_name_free(&iox, &cfg.name, role) {
                return name_in_use_or(e.name_in_use().cloned(), e);
            }
        }
    } else {
        // The controller connects where the plant listens.
        cfg.transport = transport::listen_to_connect(&cfg.transport);
    }
    plant.stdin(Stdio::null());
    if let Some(c) = &mut cfg.chaos {
        // The faults count from a second from now in both processes.
        c.epoch_ns = companion_runtime::sys::rt::monotonic_ns() + 1_000_000_000;
        plant.arg("--chaos-epoch-ns").arg(c.epoch_ns.to_string());
    }
    let child = plant
        .spawn()
        .map_err(|e| anyhow!("starting the plant ({}): {e}", plant.get_program().to_string_lossy()))?;
    eprintln!("started the plant (pid {}); controller is pid {}", child.id(), std::process::id());
    let term = Terminal::lines();
    let faults = Faults { corruptions: inject, delays: Vec::new() };
    let outcome = run_as_parent(&cfg, &s, &faults, ChildGuard::new(child), &term, &locks)?;
    Ok(ExitCode::from(match outcome {
        // Interrupted while the plant started: its end is the signal's (exit 130).
        ParentOutcome::PlantExitedEarly(_) if termination_requested() => EXIT_INTERRUPTED,
        ParentOutcome::PlantExitedEarly(st) => code_of(Some(st), EXIT_ERROR),
        ParentOutcome::Failed(..) if termination_requested() => EXIT_INTERRUPTED,
        ParentOutcome::Failed(..) => EXIT_ERROR,
        ParentOutcome::Finished { end, plant, chaos, failure } => {
            // A plant that ended outside the table after the run started died in it.
            let code = code_of(plant, EXIT_PEER_LOST);
            if let Some(how) = plant.and_then(outside_the_table) {
                eprintln!("error: the plant {how} after its run started");
            }
            let interrupted = end == ControlEnd::Interrupted || code == EXIT_INTERRUPTED;
            match chaos {
                _ if interrupted => EXIT_INTERRUPTED,
                Some(r) => {
                    print_chaos(&r, &cfg);
                    if r.mismatches.is_empty() {
                        code
                    } else {
                        EXIT_CHAOS_MISMATCH
                    }
                }
                None if failure.is_some() && code == 0 => EXIT_DEADLINES,
                None => code,
            }
        }
        ParentOutcome::PlantLost(end) => control_exit_code(&end),
    }))
}

/// Prints the chaos check.
fn print_chaos(r: &chaos::Report, cfg: &HilConfig) {
    let i = &r.injected;
    let (plant, ctl) = r.stops.iter().fold((0, 0), |(p, c), s| if s.plant { (p + 1, c) } else { (p, c + 1) });
    eprintln!(
        "chaos {}: injected {} corrupted commands (version {}, session {}, future seq {}, NaN {}), {} held back, \
         {plant} plant and {ctl} controller stops; {} of {} rows on disk",
        r.seed,
        i.version + i.session + i.future_seq + i.non_finite,
        i.version,
        i.session,
        i.future_seq,
        i.non_finite,
        i.delayed,
        r.rows.0,
        r.rows.1
    );
    if r.mismatches.is_empty() {
        eprintln!("chaos: every count matches what was injected ({})", cfg.out.join("chaos.json").display());
    } else {
        for m in &r.mismatches {
            eprintln!("error: chaos: {m}");
        }
    }
}

/// The progress line of a real-time plant run, drawn by a thread of its own from the loop's
/// live figures.
fn spawn_progress(live: Arc<LiveFigures>, steps: u64, dt: f64) -> Option<std::thread::JoinHandle<()>> {
    std::thread::Builder::new()
        .name("progress".into())
        .spawn(move || {
            while !live.is_done() {
                std::thread::sleep(Duration::from_millis(250));
                let c = live.cycle.load(Ordering::Relaxed);
                let t = c as f64 * dt;
                eprint!(
                    "\r  cycle {c:>7}/{}  t {t:6.1} s  misses {:>5}  round trip p99 {:>9}{}   ",
                    steps + 1,
                    live.misses.load(Ordering::Relaxed),
                    fmt_ns(live.p99_ns.load(Ordering::Relaxed)),
                    if live.stopped.load(Ordering::Relaxed) { "  ROBOT STOPPED" } else { "" }
                );
            }
            eprint!("\r{:100}\r", "");
        })
        .ok()
}

/// Prints why a run failed, loudly (the run's exit code says it too).
fn print_failures(who: &str, failures: &[Failure]) {
    for f in failures {
        eprintln!("warning: {who}: RUN FAILED: {}", f.describe());
    }
    if failures.iter().any(|f| matches!(f, Failure::RobotStopped { .. } | Failure::DeadlinesMissed { .. })) {
        eprintln!(
            "warning: {who}: real time was not kept on this machine; `--wait event` or `--rt` may help, \
             `companion latency` compares the wait modes"
        );
    }
}

/// `companion plant`.
///
/// # Errors
/// A bad flag, a transport failure, or files that cannot be written.
pub fn run_plant(a: &HilArgs) -> Result<ExitCode> {
    setup()?;
    if a.plant == PlantArg::Mujoco || !a.plant_args.is_empty() {
        bail!(
            "--plant and --plant-arg are for `companion hil`; the MuJoCo plant alone is \
             target/py/bin/python bridges/mujoco/companion_mujoco.py (docs/book/src/mujoco.md)"
        );
    }
    let (mut cfg, s) = a.resolve()?;
    out_is_a_folder(&cfg.out)?;
    match (cfg.chaos, a.chaos_epoch_ns) {
        (Some(_), None) => bail!("--chaos is for `companion hil` (it starts the plant with it)"),
        (Some(c), Some(e)) => cfg.chaos = Some(ChaosConfig { epoch_ns: e, ..c }),
        _ => {}
    }
    let lock = match PlantLock::acquire(&cfg.name, a.child) {
        Ok(l) => l,
        Err(e) => return name_in_use_or(e.name_in_use().cloned(), e),
    };
    let show_progress = !a.quiet && std::io::IsTerminal::is_terminal(&std::io::stderr());
    let live = Arc::new(LiveFigures::default());
    // Lockstep: a bar; real time: a line drawn from the live figures. Helper threads start
    // before the loop raises its priority, so that they do not inherit it.
    let steps = s.base().steps();
    let term = match (cfg.timing.lockstep, a.child) {
        (true, false) => Terminal::bar(steps + 1, !show_progress),
        (true, true) => Terminal::bar(steps + 1, !show_progress).without_notes(),
        (false, false) => Terminal::lines(),
        (false, true) => Terminal::warnings_only(),
    };
    let progress = (!cfg.timing.lockstep && show_progress)
        .then(|| spawn_progress(Arc::clone(&live), steps, s.base().dt))
        .flatten();
    let result = companion_runtime::run::hil::plant::run(&cfg, &s, &live, &term, &lock);
    live.finish();
    if let Some(p) = progress {
        let _ = p.join();
    }
    term.finish();
    let outcome = match result {
        Ok(o) => o,
        Err(e) => return name_in_use_or(e.name_in_use().cloned(), e),
    };
    print_table(&[&outcome.summary]);
    print_latency(&outcome.latency);
    if outcome.end != PlantEnd::Completed {
        eprintln!("plant: {}", outcome.end.describe());
    }
    print_failures("plant", &outcome.summary.failures);
    for t in &outcome.latency.hung_controller_threads {
        eprintln!("plant: the silent controller's thread {}", t.describe());
    }
    println!("wrote {}", cfg.out.display());
    if let Some(r) = &outcome.replay {
        super::sim::print_replay(r);
    }
    Ok(ExitCode::from(plant_exit_code(&outcome.end, &outcome.summary.failures)))
}

/// `companion control`.
///
/// # Errors
/// A bad flag or a transport failure.
pub fn run_control(a: &HilArgs) -> Result<ExitCode> {
    setup()?;
    let (cfg, s) = a.resolve()?;
    if cfg.chaos.is_some() {
        bail!("--chaos is for `companion hil`");
    }
    if cfg.mcap.is_some() {
        bail!("--mcap is for the plant, which records the run (`companion hil` or `companion plant`)");
    }
    if let Some(w) = ignored_by_control(a) {
        eprintln!("warning: {w}");
    }
    let inject = a.injections()?;
    let lock = match NameLock::acquire(&cfg.name, Role::Control) {
        Ok(l) => l,
        Err(e) => return name_in_use_or(e.name_in_use().cloned(), e),
    };
    eprintln!(
        "controller: demo '{}' waiting for its plant (companion plant --name {}) over {}; protocol version {}, \
         services {}, scenario hash {:#018x}, arm {}",
        cfg.name,
        cfg.name,
        cfg.transport.describe(),
        companion_runtime::transport::wire::PROTOCOL_VERSION,
        ipc::service_name(&cfg.name, "{measurement,command}"),
        companion_runtime::run::hil::handshake::controller_hash(&s.base().controller),
        companion_runtime::transport::wire::canonical::describe_arm(arm_hash(&s)?)
    );
    let faults = Faults { corruptions: inject, delays: Vec::new() };
    let Session { end, stats, .. } = match session(&cfg, &s, &faults, &Terminal::lines(), || None, &lock) {
        Ok(x) => x,
        Err(e) => return name_in_use_or(e.name_in_use().cloned(), e),
    };
    eprintln!("{}", stats.line());
    if end != ControlEnd::EndOfRun {
        eprintln!("controller: {}", end.describe());
    } else if let Some(f) = stats.failure() {
        eprintln!("controller: {f}");
        return Ok(ExitCode::from(EXIT_DEADLINES));
    }
    let rejected = rejection_failure(&stats.rejections, stats.answered, None, cfg.acceptance.max_rejected);
    let code = control_exit_code(&end);
    if code == 0 {
        if let Some(f) = rejected {
            print_failures("controller", std::slice::from_ref(&f));
            return Ok(ExitCode::from(EXIT_REJECTED));
        }
    }
    Ok(ExitCode::from(code))
}

/// The plant's flags given to `companion control`, which accepts them (one set of flags for
/// every role) but does not use them: the plant decides the run's length (its `END_OF_RUN`
/// measurement), whether it runs in lockstep and its simulated delay (announced in every
/// measurement), and writes the files. `None` if none was given.
fn ignored_by_control(a: &HilArgs) -> Option<String> {
    let given = [
        ("--duration", a.scenario.duration.is_some()),
        ("--lockstep", a.lockstep),
        ("--delay", a.delay != 0.0),
        ("--out", a.out != std::path::Path::new(DEFAULT_OUT)),
    ];
    let flags: Vec<&str> = given.iter().filter(|(_, g)| *g).map(|(f, _)| *f).collect();
    (!flags.is_empty()).then(|| {
        format!(
            "companion control ignores {}: the plant decides them (the run ends at the plant's END_OF_RUN \
             measurement, lockstep and the delay are the plant's announcement, the plant writes the files)",
            flags.join(", ")
        )
    })
}

/// The hash of the scenario's arm (the paper's, or the spatial arm's chain).
fn arm_hash(s: &HilScenario) -> Result<u64> {
    use companion_runtime::transport::wire::canonical;
    Ok(match s.spatial() {
        None => companion_runtime::run::hil::handshake::arm_hash(),
        Some(ss) => match ss.arm.joints() {
            6 => canonical::arm_hash(&ss.arm.chain::<f64, 6>()?),
            7 => canonical::arm_hash(&ss.arm.chain::<f64, 7>()?),
            _ => canonical::arm_hash(&ss.arm.chain::<f64, 8>()?),
        },
    })
}

/// Prints the latency table of a HIL run.
fn print_latency(r: &LatencyReport) {
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
        let m = r.miss_causes;
        if m.total() > 0 {
            println!(
                "whose misses: {} the controller's (woke late {}, stepped long {}), {} the plant's (published \
                 late), {} on the way back (sent in time), {} unanswered{}",
                m.controller(),
                m.controller_wake,
                m.controller_compute,
                m.plant_late,
                m.return_path,
                m.unanswered,
                if m.clocks_apart > 0 {
                    format!(", {} not split (the controller's clock is not the plant's)", m.clocks_apart)
                } else {
                    String::new()
                }
            );
        }
        if r.plant_stalls > 0 {
            let starved = r
                .plant_runqueue_wait_ns
                .map(|w| format!("; its loop waited {} in all for a CPU", fmt_ns(w)))
                .unwrap_or_default();
            println!(
                "the plant fell behind its schedule {} times (longest {}) and skipped {} releases{starved}",
                r.plant_stalls,
                fmt_ns(r.longest_stall_ns),
                r.skipped_releases
            );
        }
        let w = r.wait_counts;
        if w.no_spare_cpu {
            println!(
                "adaptive waiting: {} CPUs, none to spare for spinning: waited on the event throughout",
                r.machine.cpus
            );
        } else if w.preemptions + w.pressure_holds > 0 {
            println!(
                "adaptive waiting: {} preemptions noticed while spinning, {} fallbacks to event waiting, {} back-offs \
                 for CPU pressure ({:.1} s on the event)",
                w.preemptions,
                w.fallbacks,
                w.pressure_holds,
                w.event_phase_ns as f64 / 1e9
            );
        }
    }
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
    fn a_name_in_use_is_exit_5_wherever_the_library_put_it() {
        use companion_runtime::run::hil::control::ControlRunError;
        use companion_runtime::run::hil::plant::PlantRunError;
        use companion_runtime::sys::lock::{LockError, NameInUse};
        use companion_runtime::transport::{OpenError, StartError};
        let n = || NameInUse { name: "d".into(), role: "plant", pid: 42 };
        let open = || OpenError { role: Role::Plant, cause: StartError::NameInUse(n()) };
        let found = [
            LockError::NameInUse(n()).name_in_use().cloned(),
            StartError::NameInUse(n()).name_in_use().cloned(),
            PlantRunError::from(LockError::NameInUse(n())).name_in_use().cloned(),
            PlantRunError::from(open()).name_in_use().cloned(),
            PlantRunError::from(StartError::NameInUse(n())).name_in_use().cloned(),
            ControlRunError::from(open()).name_in_use().cloned(),
            ControlRunError::from(StartError::NameInUse(n())).name_in_use().cloned(),
        ];
        for f in found {
            assert_eq!(f, Some(n()));
            assert_eq!(name_in_use_or(f, StartError::NoZenoh).unwrap(), ExitCode::from(EXIT_NAME_IN_USE));
        }
        let other = PlantRunError::from(OpenError { role: Role::Plant, cause: StartError::NoZenoh });
        assert_eq!(other.name_in_use(), None);
        assert!(name_in_use_or(other.name_in_use().cloned(), other).is_err() || termination_requested());
    }

    #[test]
    fn defaults_give_30_s_at_1_khz_with_a_500_us_deadline() {
        let t = T::parse_from(["x"]);
        let (cfg, s) = t.a.resolve().unwrap();
        assert_eq!(s.base().duration, 30.0);
        let tm = cfg.timing;
        assert_eq!(tm.period_ns, 1_000_000);
        assert_eq!(tm.deadline_ns, 500_000);
        assert_eq!(tm.hold_periods, 20);
        assert_eq!(tm.wait, WaitMode::Adaptive);
        assert!(!tm.lockstep);
        assert_eq!(cfg.acceptance, companion_runtime::domain::record::Acceptance::default());
        // The scenario is the one the flags describe (the joint guard is the plant's business,
        // announced on the wire: see hil::handshake).
        assert_eq!(s.base().controller.overrides.joint_step_fraction, None);
        let t = T::parse_from(["x", "--rt"]);
        assert_eq!(t.a.timing(s.base()).unwrap().wait, WaitMode::Adaptive);
        let t = T::parse_from(["x", "--rt", "--wait", "spin"]);
        assert_eq!(t.a.timing(s.base()).unwrap().wait, WaitMode::Spin);
    }

    #[test]
    fn negative_numbers_are_values_and_out_of_range_ones_are_refused_by_name() {
        let t = T::parse_from(["x", "--wheel-scale-error", "-0.05", "--dt", "-1"]);
        assert_eq!(t.a.scenario.wheel_scale_error, Some(-0.05));
        let e = t.a.resolve().unwrap_err().to_string();
        assert!(e.contains("dt must be a positive number of seconds, got -1"), "{e}");
        for (flag, value, rule) in [
            (
                "--peer-timeout",
                "1e300",
                "--peer-timeout must be a number of seconds in (0, 3600], got 1.000e300",
            ),
            ("--peer-timeout", "-2", "--peer-timeout must be a number of seconds in (0, 3600], got -2"),
            (
                "--startup-timeout",
                "nan",
                "--startup-timeout must be a number of seconds in [0, 86400], got NaN",
            ),
            ("--max-miss-fraction", "-0.5", "--max-miss-fraction must be a fraction in [0, 1], got -0.5"),
            ("--max-rejected", "2", "--max-rejected must be a fraction in [0, 1], got 2"),
            ("--rate", "-5", "--rate must be between 1 and 100000 Hz, got -5"),
        ] {
            let t = T::parse_from(["x", flag, value]);
            let e = t.a.resolve().unwrap_err().to_string();
            assert_eq!(e, rule);
        }
    }

    #[test]
    fn a_deadline_beyond_the_period_is_refused() {
        let t = T::parse_from(["x", "--rate", "2000", "--deadline-us", "600"]);
        let e = t.a.resolve().unwrap_err().to_string();
        assert!(e.contains("--deadline-us"), "{e}");
    }

    #[test]
    fn a_delay_is_for_lockstep_and_compensation_can_be_switched_off() {
        let t = T::parse_from(["x", "--delay", "0.002"]);
        let e = t.a.resolve().unwrap_err().to_string();
        assert!(e.contains("--delay") && e.contains("--lockstep"), "{e}");
        let t = T::parse_from(["x", "--lockstep", "--delay", "0.002", "--no-delay-compensation"]);
        let (_, s) = t.a.resolve().unwrap();
        assert_eq!((s.base().delay, s.base().delay_compensation), (0.002, false));
        let t = T::parse_from(["x", "--lockstep", "--delay", "0.5"]);
        assert!(t.a.resolve().is_err());
    }

    #[test]
    fn an_arm_makes_the_run_spatial_and_what_it_cannot_do_is_refused_by_name() {
        let t = T::parse_from(["x", "--arm", "ur5", "--platform", "car", "--trajectory", "2"]);
        let (_, s) = t.a.resolve().unwrap();
        let ss = s.spatial().expect("a spatial run");
        assert_eq!((ss.arm.name(), ss.arm.joints()), ("ur5", 6));
        assert_eq!(ss.name, "ur5-traj2-a-car");
        assert_eq!(s.base().controller.platform, companion_core::PlatformKind::Car);
        let (_, s) = T::parse_from(["x", "--arm", "rpr"]).a.resolve().unwrap();
        assert!(s.spatial().is_none(), "rpr is the paper's planar arm");
        // `--chaos` and `--delay` as with the paper's arm.
        let (cfg, s) = T::parse_from(["x", "--arm", "ur5", "--chaos", "3"]).a.resolve().unwrap();
        assert_eq!((cfg.chaos.map(|c| c.seed), s.spatial().map(|ss| ss.arm.joints())), (Some(3), Some(6)));
        let (_, s) =
            T::parse_from(["x", "--arm", "ur5", "--lockstep", "--delay", "0.002"]).a.resolve().unwrap();
        assert_eq!((s.base().delay, s.spatial().map(|ss| ss.arm.joints())), (0.002, Some(6)));
        for (args, why) in [
            (&["x", "--arm", "ur5", "--chaos", "3", "--lockstep"][..], "--chaos needs real time"),
            (&["x", "--arm", "ur5", "--delay", "0.002"][..], "--delay simulates a pure delay in lockstep"),
            (&["x", "--arm", "nosuch"][..], "nosuch"),
        ] {
            let e = format!("{:#}", T::parse_from(args).a.resolve().unwrap_err());
            assert!(e.contains(why), "{args:?}: {e}");
        }
    }

    #[test]
    fn a_startup_timeout_that_is_not_a_duration_is_an_error() {
        for bad in ["--startup-timeout=nan", "--startup-timeout=-1", "--startup-timeout=inf"] {
            let t = T::parse_from(["x", bad]);
            let e = t.a.resolve().unwrap_err().to_string();
            assert!(e.contains("--startup-timeout"), "{bad}: {e}");
        }
    }

    #[test]
    fn injections_parse() {
        assert_eq!(
            parse_injections("version@1,nan@2,seq@3,session@4").unwrap(),
            vec![
                (1, Corruption::Version),
                (2, Corruption::Nan),
                (3, Corruption::Seq),
                (4, Corruption::Session)
            ]
        );
        assert!(parse_injections("bogus@1").is_err());
        assert!(parse_injections("nan").is_err());
    }
}
