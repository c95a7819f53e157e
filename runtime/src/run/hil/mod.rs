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
//! ## Arms
//!
//! `--arm rpr` (the default) is the paper's planar arm (§4); `--arm ur5|panda|FILE` a spatial
//! arm of 6 to 8 joints (§5), the same run as `companion sim --arm` ([`HilScenario`]). The
//! loops and the plant's run are the same for every arm: the plant drives a
//! [`crate::run::robot::Robot`] (the planar plant, or the spatial one) and records its
//! [`crate::domain::record::Row`]s, the controller serves a [`law::Served`] (the planar law, or
//! the spatial law for `N` joints). Both roles announce the arm's joint count, target space
//! and hash; a plant and a controller with different arms refuse each other by name. Lockstep
//! runs go through `companion sim`'s own loop ([`crate::run::sim::run_loop`]) and are
//! byte-identical to it, with either arm. `--chaos` and `--delay` work with every arm.
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
//! [`crate::run::sim::run_loop`] itself with the lockstep [`crate::run::sim::Exchange`],
//! [`plant_loop::Lockstep`]).
//!
//! ## Waiting (`--wait`)
//!
//! - `adaptive` (the default): waits on the event, as `event` does, on a machine of one or
//!   two CPUs (two loops spinning there leave no CPU for anything else); with three or more it
//!   spins, and after a preemption or under CPU pressure waits on the event for a back-off
//!   ([`wait`] has the details, `companion latency --repeat` the figures).
//! - `spin`: busy-poll `receive()` (and the clock, for the plant's release time). Lowest
//!   latency; one core per process, and nothing else that wants it.
//! - `event`: the iceoryx2 event service: the sender notifies, the receiver sleeps on the
//!   listener's descriptor (always bounded) and re-checks `receive()` after every wake; the
//!   plant sleeps to its release time by its `--release-timer` ([`ReleaseTimer`]; by default
//!   to 100 µs before it, then spins).
//! - `hybrid`: sleep until `--spin-margin-us` before the expected message (the
//!   plant: before its release time; the controller: before the next period's measurement),
//!   then spin. A spin that finds nothing for 200 µs falls back to 50 µs sleeps, so a silent
//!   peer does not cost a core.
//!
//! ## Faults
//!
//! Each side notices a silent peer: after `--silence-ms` without a message (or, for the
//! plant, once it has stopped the robot) it lists the iceoryx2 nodes. A peer that died is
//! reported at once ([`PlantEnd::ControllerDied`], [`ControlEnd::PlantDied`]) and its shared
//! memory is cleaned; a peer that is alive but silent for `--peer-timeout` seconds ends the run
//! ([`PlantEnd::ControllerHung`], [`ControlEnd::PlantHung`]). A second demo with the same
//! `--name` stops with [`crate::sys::lock::NameInUse`]. (The command line turns these into exit
//! codes.)
//! Malformed messages (wrong sequence number, session or protocol version, non-finite
//! velocities) are counted and dropped ([`crate::transport::wire::check_command`]).
//!
//! ## The cycle's cost
//!
//! One cycle allocates nothing, takes no lock of its own and makes no system call but the
//! transport's (iceoryx2 send/receive are shared-memory operations; `--wait event` adds the
//! event's syscalls, `hybrid`/`event` one `clock_nanosleep`, or a timerfd's arming and read
//! with `--release-timer timerfd`). Latency samples go into
//! preallocated HDR histograms; log rows go into a preallocated lock-free ring buffer that a
//! normal-priority thread drains into `timeseries.csv`, flushing every 50 ms — so the file
//! is on disk up to the last ~50 ms if the plant is killed.
//!
//! ## Modules
//!
//! Domain first, then the loops, then the processes:
//! [`config`] (typed options and the run's scenario), [`end`] (how a run ended), [`stats`]
//! (what is counted), [`hold`] (hold, then stop), [`messages`] (the one header builder,
//! command ↔ report), [`watch`] (the one peer-liveness check), [`misses`] (whose deadline miss), [`wait`] (the wait
//! modes), [`wakes`] (why the controller took a measurement late), [`law`] (what the controller serves);
//! [`plant_loop`] (real time and lockstep), [`serve`] (the controller's loop), [`fault`]
//! (the fault-injecting link decorator, for tests); [`report`] (`latency.json`), [`plant`]
//! and [`control`] (the two processes).

pub mod chaos;
pub mod config;
pub mod control;
pub mod end;
pub mod fault;
pub mod handshake;
pub mod hold;
pub mod law;
pub mod messages;
pub mod misses;
pub mod plant;
pub mod plant_loop;
pub mod report;
pub mod serve;
pub mod stats;
pub mod wait;
pub mod wakes;
pub mod watch;

pub use self::config::{
    ChaosConfig, HilConfig, HilScenario, ReleaseTimer, RtPlan, Timing, WaitMode, MAX_COMMAND_AGE,
};
pub use self::end::{ControlEnd, PlantEnd};
