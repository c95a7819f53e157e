//! The command line: clap's flags, progress bars, printing and exit codes — the thin edge of
//! the `companion` binary. Each command turns its flags once into the library's typed values
//! (`Scenario`, `HilConfig`, `LatencyOptions`), calls the library, prints what it returns and
//! chooses the exit code. Nothing below this layer parses a flag or prints.

mod args;
mod exit;
mod hil;
mod latency;
mod sim;
mod terminal;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use self::exit::{EXIT_CODES_HELP, EXIT_ERROR};

/// The companion-frame controller for mobile manipulators: simulation, hardware-in-the-loop
/// demo over shared memory, and latency benchmark.
#[derive(Parser, Debug)]
#[command(name = "companion", version, about, long_about = None, propagate_version = true, after_help = EXIT_CODES_HELP)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Hardware-in-the-loop demo: starts the plant as a child process and runs the controller
    /// against it over iceoryx2 shared memory, in real time (or lockstep), and writes
    /// timeseries.csv, summary.json, latency.json and plots.
    #[command(after_help = EXIT_CODES_HELP)]
    Hil(hil::HilArgs),
    /// Simulate a scenario in one process (fast, deterministic) and write timeseries.csv,
    /// summary.json and plots; `--all` reproduces the paper's Figures 3–10.
    #[command(after_help = EXIT_CODES_HELP)]
    Sim(sim::SimArgs),
    /// The plant role of the HIL demo alone (for two terminals, or a bridge to hardware).
    #[command(after_help = EXIT_CODES_HELP)]
    Plant(hil::HilArgs),
    /// The controller role of the HIL demo alone.
    #[command(after_help = EXIT_CODES_HELP)]
    Control(hil::HilArgs),
    /// Worst-case latency benchmark: controller step, bare iceoryx2 and Unix-socket ping-pong,
    /// and the full HIL cycle in each wait mode.
    #[command(after_help = EXIT_CODES_HELP)]
    Latency(latency::LatencyArgs),
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
        Command::Latency(a) => latency::run(a).map(|()| ExitCode::SUCCESS),
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
