//! The typed configuration of a HIL run: timing, waiting, real-time setup, names and folders
//! (made from the command line by the CLI layer, or in one expression by a test).

use std::path::PathBuf;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::domain::record::Acceptance;
use crate::domain::scenario::Scenario;
use crate::run::spatial::SpatialScenario;
use crate::sys::lock::{DemoName, Role};
use crate::sys::rt::RtConfig;

/// How a process waits for its peer's message.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WaitMode {
    /// Busy-poll.
    Spin,
    /// iceoryx2 event service with bounded `timed_wait`.
    Event,
    /// Sleep until shortly before the expected message, then spin.
    Hybrid,
    /// Wait on the iceoryx2 event below three CPUs; with more, busy-poll while the process
    /// keeps its CPU and wait on the event for a while after a preemption (see
    /// [`super::wait`]). The default.
    Adaptive,
}

impl WaitMode {
    /// The command-line spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Spin => "spin",
            Self::Event => "event",
            Self::Hybrid => "hybrid",
            Self::Adaptive => "adaptive",
        }
    }

    /// Whether the mode sleeps to the plant's release time (at least at times), so that the
    /// plant's [`ReleaseTimer`] matters: `event`, and `adaptive` while it waits on the event
    /// (`spin` spins to it, `hybrid` sleeps to its own margin).
    pub fn sleeps_to_release(self) -> bool {
        matches!(self, Self::Event | Self::Adaptive)
    }

    /// Whether the mode needs the iceoryx2 event services (the sender then notifies every
    /// message).
    pub fn uses_events(self) -> bool {
        matches!(self, Self::Event | Self::Adaptive)
    }

    /// The default: `adaptive`, with or without `--rt`, on any number of CPUs.
    ///
    /// No fixed mode is right everywhere. A spinner that keeps its CPU has the lowest latency,
    /// and one that is preempted loses whole time slices: with other work on two CPUs `spin`
    /// missed about half its deadlines. On this project's 2-vCPU VMs even an otherwise idle
    /// machine preempts a spinner: two loops spinning take both CPUs, and every other thread
    /// that wakes has to preempt one of them — there `adaptive`, when it spun, missed 1–53
    /// deadlines in ten 10 s runs (29 and 33 of 34 and 38 in two more the controller waking
    /// late), and `event` 1–12 in eight, none of them the controller's where that was
    /// recorded (issue 39). So `adaptive` waits on the event below three CPUs,
    /// and spins, falling back to the event after a preemption or under CPU pressure, where
    /// a CPU is left over ([`super::wait`]). With `SCHED_FIFO` a spinner is parked for ~50 ms
    /// of every second by the kernel's real-time throttling, which `adaptive` notices as a
    /// preemption. `companion latency --repeat N` measures every mode, idle and under load,
    /// in interleaved rounds.
    pub fn default_for(_rt: bool) -> Self {
        Self::Adaptive
    }
}

/// How the plant sleeps to its release time where its wait mode sleeps for it (`event`, and
/// `adaptive` while it waits on the event; `spin` spins to it, `hybrid` sleeps to its own
/// margin): `--release-timer`.
///
/// The default is `margin`: on this project's 2-vCPU VMs a timed sleep at 1 kHz wakes ~30 µs
/// late at the median and 0.1–3 ms late at the tail (the hypervisor has to run the halted
/// vCPU again), and a plant that publishes more than half the deadline late misses it. Waking
/// `--spin-margin-us` (100 µs) early and spinning the rest absorbs the lateness up to the
/// margin, at a tenth of a CPU at 1 kHz. In interleaved repeated runs (`companion latency
/// --hil-modes event --release-timers sleep,timerfd,margin,fifo`) `margin` missed least;
/// `timerfd` was no better than `sleep`; `fifo` kept the plant's releases on time, but the
/// controller's misses went up more than the plant's came down.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ReleaseTimer {
    /// `clock_nanosleep(TIMER_ABSTIME)` to the release (timer slack 1 ns).
    Sleep,
    /// A `timerfd` armed to the release, read.
    Timerfd,
    /// `clock_nanosleep` to `--spin-margin-us` before the release, then spin.
    #[default]
    Margin,
    /// `clock_nanosleep` under `SCHED_FIFO` (the plant's loop thread, where permitted; not
    /// pinned, memory not locked: what `--rt` adds).
    Fifo,
}

impl ReleaseTimer {
    /// Every timer, in the command line's order.
    pub const ALL: [Self; 4] = [Self::Sleep, Self::Timerfd, Self::Margin, Self::Fifo];

    /// The command-line spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Sleep => "sleep",
            Self::Timerfd => "timerfd",
            Self::Margin => "margin",
            Self::Fifo => "fifo",
        }
    }
}

/// The timing options both loops use.
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
    /// How the plant sleeps to its release (where its wait mode sleeps for it).
    pub release: ReleaseTimer,
    /// Hybrid spin margin (ns); also the margin of `--release-timer margin`.
    pub spin_margin_ns: u64,
    /// Silence before a liveness check (ns).
    pub silence_ns: u64,
    /// Alive-but-silent limit (ns).
    pub peer_timeout_ns: u64,
    /// Lockstep.
    pub lockstep: bool,
    /// The oldest answer the real-time plant applies, in periods: a command answering
    /// measurement `n − k`, `k ≤ max_command_age`, is applied in period `n` when no answer to
    /// `n` came and it is the newest answer yet (a network whose round trip is longer than the
    /// deadline). 0: only the answer to `n` (iceoryx2 on one machine).
    pub max_command_age: u32,
}

impl Timing {
    /// How long before a release the plant wakes to spin the rest, where it sleeps to it
    /// (`--release-timer margin`: the spin margin; otherwise 0).
    pub fn release_margin_ns(&self) -> u64 {
        if self.release == ReleaseTimer::Margin {
            self.spin_margin_ns
        } else {
            0
        }
    }
}

/// The largest `--max-command-age`: the law predicts over at most 8 periods.
pub const MAX_COMMAND_AGE: u32 = 8;

/// The real-time setup (`--rt`): priority and the CPU of each process.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RtPlan {
    /// `SCHED_FIFO` priority (1–99).
    pub priority: i32,
    /// The plant's CPU.
    pub plant_cpu: usize,
    /// The controller's CPU.
    pub control_cpu: usize,
}

impl RtPlan {
    /// The CPUs by default: the plant on CPU 1 and the controller on 0 (both on 0 with one
    /// CPU).
    pub fn default_cpus() -> (usize, usize) {
        (usize::from(crate::sys::rt::online_cpus() >= 2), 0)
    }

    /// The setup of `role`'s loop thread.
    pub fn for_role(&self, role: Role) -> RtConfig {
        let cpu = if role == Role::Plant { self.plant_cpu } else { self.control_cpu };
        RtConfig { priority: self.priority, ..RtConfig::with_cpu(Some(cpu)) }
    }
}

/// Everything a HIL role needs besides the scenario.
#[derive(Clone, Debug, PartialEq)]
pub struct HilConfig {
    /// The demo's name (its iceoryx2 services are `companion/NAME/…`).
    pub name: DemoName,
    /// The output folder (the plant writes it).
    pub out: PathBuf,
    /// Timing.
    pub timing: Timing,
    /// How long to wait for the peer to join at start.
    pub startup_timeout: Duration,
    /// The real-time setup, if asked for.
    pub rt: Option<RtPlan>,
    /// Skip the plots.
    pub no_plots: bool,
    /// What the run is held to (law rejections, deadline misses).
    pub acceptance: Acceptance,
    /// `--chaos SEED`: faults injected on purpose (see [`super::chaos`]).
    pub chaos: Option<ChaosConfig>,
    /// The transport (iceoryx2 unless `--transport zenoh`).
    pub transport: crate::transport::Transport,
    /// `--mcap FILE`: the plant also writes the run as an MCAP replay for Foxglove.
    pub mcap: Option<PathBuf>,
}

/// A chaos run's seed and the time its faults count from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChaosConfig {
    /// The seed of the plan.
    pub seed: u64,
    /// `CLOCK_MONOTONIC` (ns) the plan's times count from (the same in both processes).
    pub epoch_ns: u64,
}

impl HilConfig {
    /// A warning if the real-time setup puts both processes on one CPU with busy waiting (a
    /// `SCHED_FIFO` spinner never yields its CPU to a peer of the same priority).
    pub fn cpu_warning(&self) -> Option<String> {
        let rt = self.rt?;
        let wait = self.timing.wait;
        (rt.plant_cpu == rt.control_cpu && wait != WaitMode::Event).then(|| {
            format!(
                "--rt puts plant and controller on the same CPU ({}); with --wait {} they take turns \
                 only when the kernel throttles real-time tasks: use --wait event, or two CPUs",
                rt.plant_cpu,
                wait.as_str()
            )
        })
    }

    /// The real-time setup of `role`, if any.
    pub fn rt_config(&self, role: Role) -> Option<RtConfig> {
        self.rt.map(|r| r.for_role(role))
    }
}

/// The run both roles are given: the paper's planar arm, or a spatial arm (`--arm
/// ur5|panda|FILE`, §5). Both roles must be given the same one: the handshake compares the
/// scenario's and the arm's hashes, and the target's space and joint count.
#[derive(Clone, Debug, PartialEq)]
pub enum HilScenario {
    /// The paper's RPR arm (§4).
    Planar(Scenario),
    /// A 6- to 8-joint arm in SE(3) (§5).
    Spatial(SpatialScenario),
}

impl HilScenario {
    /// The planar scenario: the whole run, or everything but the arm and the target.
    pub fn base(&self) -> &Scenario {
        match self {
            Self::Planar(s) => s,
            Self::Spatial(s) => &s.base,
        }
    }

    /// The spatial scenario, if the arm is spatial.
    pub fn spatial(&self) -> Option<&SpatialScenario> {
        match self {
            Self::Planar(_) => None,
            Self::Spatial(s) => Some(s),
        }
    }
}
