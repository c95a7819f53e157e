//! `companion`: run the HIL demo, the paper's simulations, and the latency benchmark.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// The companion-frame controller for mobile manipulators: simulation, hardware-in-the-loop
/// demo over shared memory, and latency benchmark.
#[derive(Parser, Debug)]
#[command(name = "companion", version, about, long_about = None, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Hardware-in-the-loop demo: starts the plant as a child process and runs the controller
    /// against it over iceoryx2 shared memory, in real time (or lockstep), and writes
    /// timeseries.csv, summary.json, latency.json and plots.
    Hil(companion_runtime::hil::HilArgs),
    /// Simulate a scenario in one process (fast, deterministic) and write timeseries.csv,
    /// summary.json and plots; `--all` reproduces the paper's Figures 3–10.
    Sim(companion_runtime::sim::SimArgs),
    /// The plant role of the HIL demo alone (for two terminals, or a bridge to hardware).
    Plant(companion_runtime::hil::PlantArgs),
    /// The controller role of the HIL demo alone.
    Control(companion_runtime::hil::ControlArgs),
    /// Worst-case latency benchmark: controller step, bare iceoryx2 and Unix-socket ping-pong,
    /// and the full HIL cycle in each wait mode.
    Latency(companion_runtime::latency::LatencyArgs),
    /// The echoing side of `companion latency`'s ping-pong (started by it).
    #[command(hide = true)]
    LatencyPeer(companion_runtime::latency::pingpong::PeerArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Hil(a) => companion_runtime::hil::run_hil(a),
        Command::Sim(a) => companion_runtime::sim::run(a).map(|()| ExitCode::SUCCESS),
        Command::Plant(a) => companion_runtime::hil::run_plant(a),
        Command::Control(a) => companion_runtime::hil::run_control(a),
        Command::Latency(a) => companion_runtime::latency::run(a).map(|()| ExitCode::SUCCESS),
        Command::LatencyPeer(a) => {
            companion_runtime::latency::pingpong::run_peer(a).map(|()| ExitCode::SUCCESS)
        }
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
