//! The command line: clap's flags, progress bars, printing and exit codes — the thin edge of
//! the `companion` binary. Each command turns its flags once into the library's typed values
//! (`Scenario`, `HilConfig`, `LatencyOptions`), calls the library, prints what it returns and
//! chooses the exit code. Nothing below this layer parses a flag or prints.

mod args;
mod certs;
mod exit;
mod explore;
mod hil;
mod latency;
mod mujoco;
mod sim;
mod terminal;
mod tune;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use self::exit::EXIT_ERROR;

/// The companion-frame controller for mobile manipulators: simulation, hardware-in-the-loop
/// demo over shared memory, and latency benchmark.
#[derive(Parser, Debug)]
#[command(name = "companion", version, about, long_about = None, propagate_version = true, after_help = exit::help())]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Hardware-in-the-loop demo: starts the plant as a child process and runs the controller
    /// against it over iceoryx2 shared memory, in real time (or lockstep), and writes
    /// timeseries.csv, summary.json, latency.json and plots.
    #[command(after_help = exit::help())]
    Hil(hil::HilArgs),
    /// Simulate a scenario in one process (fast, deterministic) and write timeseries.csv,
    /// summary.json and plots; `--all` reproduces the paper's Figures 3–10.
    #[command(after_help = exit::help())]
    Sim(sim::SimArgs),
    /// The plant role of the HIL demo alone (for two terminals, or a bridge to hardware).
    #[command(after_help = exit::help())]
    Plant(hil::HilArgs),
    /// The controller role of the HIL demo alone.
    #[command(after_help = exit::help())]
    Control(hil::HilArgs),
    /// Monte Carlo over initial conditions and parameters: which starts converge, with which
    /// parameters. Writes results.csv, summary.json and plots (a success map, histograms, the
    /// bound on ‖e_p‖ against ε); resumable, shardable (`--shard K/N`, `explore merge`).
    Explore(explore::ExploreArgs),
    /// Search the transverse function's parameters, the steering gain, K̄ and the gains on a
    /// set of runs (tracked fraction first, then effort); writes a --config preset and a
    /// Pareto-front report.
    Tune(tune::TuneArgs),
    /// Worst-case latency benchmark: controller step, bare iceoryx2 and Unix-socket ping-pong,
    /// and the full HIL cycle in each wait mode.
    #[command(after_help = exit::help())]
    Latency(latency::LatencyArgs),
    /// The TLS material of a deployment: a CA, and a certificate and key per host, for the
    /// Zenoh transport's mutual TLS (`--hosts plant.local,ctrl.local`).
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
        Command::Latency(a) => latency::run(a).map(|()| ExitCode::SUCCESS),
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
