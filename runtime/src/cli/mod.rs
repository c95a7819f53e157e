//! The command line: clap's flags, progress bars, printing and exit codes — the thin edge of
//! the `companion` binary. Each command turns its flags once into the library's typed values
//! (`Scenario`, `HilConfig`, `LatencyOptions`), calls the library, prints what it returns and
//! chooses the exit code. Nothing below this layer parses a flag or prints.

mod args;
mod certs;
mod exit;
mod explore;
mod footer;
mod hil;
mod latency;
mod mujoco;
mod ros2;
mod settle;
mod sim;
mod terminal;
mod tune;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use self::exit::EXIT_ERROR;
use self::footer::{long_after, short_after};

/// The companion-frame controller for mobile manipulators: simulation, HIL demo, benchmarks.
///
/// The companion-frame controller for mobile manipulators: simulation, hardware-in-the-loop
/// demo over shared memory, and latency benchmark. `companion COMMAND -h` gives one line per
/// flag, `--help` the whole text.
#[derive(Parser, Debug)]
#[command(
    name = "companion",
    version,
    propagate_version = true,
    after_help = short_after("getting-started.md"),
    after_long_help = long_after("getting-started.md")
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// The HIL demo: plant and controller as two processes, in real time.
    ///
    /// Hardware-in-the-loop demo: starts the plant as a child process and runs the controller
    /// against it over iceoryx2 shared memory, in real time (or lockstep), and writes
    /// timeseries.csv, summary.json, latency.json and plots.
    #[command(after_help = short_after("hil.md"), after_long_help = long_after("hil.md"))]
    Hil(hil::HilArgs),
    /// Simulate in one process (fast, deterministic); --all: the paper's figures.
    ///
    /// Simulate a scenario in one process (fast, deterministic) and write timeseries.csv,
    /// summary.json and plots; `--all` reproduces the paper's Figures 3–10.
    #[command(after_help = short_after("paper.md"), after_long_help = long_after("paper.md"))]
    Sim(sim::SimArgs),
    /// The plant role of the HIL demo alone (two terminals, or a bridge's place).
    ///
    /// The plant role of the HIL demo alone (for two terminals, or a bridge to hardware).
    #[command(after_help = short_after("hil.md"), after_long_help = long_after("hil.md"))]
    Plant(hil::HilArgs),
    /// The controller role of the HIL demo alone.
    #[command(after_help = short_after("bridge.md"), after_long_help = long_after("bridge.md"))]
    Control(hil::HilArgs),
    /// Many closed-loop runs over starts and parameters: which converge.
    ///
    /// Monte Carlo over initial conditions and parameters: which starts converge, with which
    /// parameters. Writes results.csv, summary.json and plots (a success map, histograms, the
    /// bound on ‖e_p‖ against ε); resumable, shardable (`--shard K/N`, `explore merge`).
    #[command(after_help = short_after("explore-tune.md"), after_long_help = long_after("explore-tune.md"))]
    Explore(explore::ExploreArgs),
    /// Search the law's parameters and gains on a set of runs; write a preset.
    ///
    /// Search the transverse function's parameters, the steering gain, K̄ and the gains on a
    /// set of runs (tracked fraction first, then effort); writes a --config preset and a
    /// Pareto-front report.
    #[command(after_help = short_after("explore-tune.md"), after_long_help = long_after("explore-tune.md"))]
    Tune(tune::TuneArgs),
    /// One setting from many perturbed homes: how many settle, with spreads.
    ///
    /// Runs a spatial arm's setting (--arm, --config, --limits, as `sim --arm`) from --starts
    /// homes perturbed by up to --perturb, seeded, in parallel, and prints how many settle
    /// (‖e_p‖ below --tolerance from --settle-by on) and the spreads of the final ‖e_p‖, its
    /// largest value after --settle-by, the tracked fraction and how often the limits acted.
    #[command(after_help = short_after("explore-tune.md"), after_long_help = long_after("explore-tune.md"))]
    Settle(settle::SettleArgs),
    /// Worst-case latency: the step, the transports and the HIL cycle.
    ///
    /// Worst-case latency benchmark: controller step, bare iceoryx2 and Unix-socket ping-pong,
    /// and the full HIL cycle in each wait mode.
    #[command(after_help = short_after("latency.md"), after_long_help = long_after("latency.md"))]
    Latency(latency::LatencyArgs),
    /// The controller as a ROS 2 node, over DDS (a build with `--features ros2`).
    ///
    /// Reads joint states, odometry and the target over DDS, sends the base's twist and the
    /// joint velocities at a fixed period, and writes summary.json. No ROS installation needed.
    #[command(after_help = short_after("ros2.md"), after_long_help = long_after("ros2.md"))]
    Ros2(Box<ros2::Ros2Args>),
    /// The TLS material of a deployment: a CA, a certificate and key per host.
    ///
    /// The TLS material of a deployment: a CA, and a certificate and key per host, for the
    /// Zenoh transport's mutual TLS (`--hosts plant.local,ctrl.local`).
    #[command(after_help = short_after("two-machines.md"), after_long_help = long_after("two-machines.md"))]
    Certs(certs::CertsArgs),
    /// The echoing side of `companion latency`'s ping-pong (started by it).
    #[command(hide = true)]
    LatencyPeer(latency::PeerArgs),
}

/// Runs the command line; the process's exit code.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Hil(a) => hil::run_hil(a),
        Command::Sim(a) => sim::run(a),
        Command::Plant(a) => hil::run_plant(a),
        Command::Control(a) => hil::run_control(a),
        Command::Explore(a) => explore::run(a),
        Command::Tune(a) => tune::run(a).map(|()| ExitCode::SUCCESS),
        Command::Settle(a) => settle::run(a).map(|()| ExitCode::SUCCESS),
        Command::Latency(a) => latency::run(a).map(|()| ExitCode::SUCCESS),
        Command::Ros2(a) => ros2::run(a),
        Command::Certs(a) => certs::run(a).map(|()| ExitCode::SUCCESS),
        Command::LatencyPeer(a) => latency::run_peer(a).map(|()| ExitCode::SUCCESS),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(EXIT_ERROR)
        }
    }
}
