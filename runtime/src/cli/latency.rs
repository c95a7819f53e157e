//! `companion latency` and its hidden echoing peer.

use std::path::PathBuf;

use anyhow::{anyhow, Result};
use clap::Args;
use companion_runtime::histogram::fmt_ns;
use companion_runtime::latency::pingpong::{run_peer as peer, PeerOptions, Transport};
use companion_runtime::latency::{Benchmark, LatencyOptions};

use super::hil::WaitArg;
use super::terminal::Terminal;

/// `companion latency` flags.
#[derive(Args, Clone, Debug)]
pub struct LatencyArgs {
    /// Samples per measurement (HIL: cycles at 1 kHz, so 100000 takes 100 s per wait mode).
    #[arg(long, default_value_t = 20_000, value_name = "N")]
    pub cycles: u64,
    /// Unrecorded warm-up iterations before each ping-pong and step measurement.
    #[arg(long, default_value_t = 1_000, value_name = "N")]
    pub warmup: u64,
    /// Output folder (created if missing).
    #[arg(long, default_value = "out/latency", value_name = "DIR")]
    pub out: PathBuf,
    /// Real-time setup for every part (mlockall, SCHED_FIFO, one CPU per process).
    #[arg(long)]
    pub rt: bool,
    /// The HIL wait modes to measure.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "spin,hybrid,event")]
    pub hil_modes: Vec<WaitArg>,
    /// Skip part (4), the full HIL cycle.
    #[arg(long)]
    pub skip_hil: bool,
}

/// `companion latency`.
///
/// # Errors
/// A child process or a file failed.
pub fn run(a: &LatencyArgs) -> Result<()> {
    companion_runtime::ipc::quiet_logs();
    let opts = LatencyOptions {
        cycles: a.cycles,
        warmup: a.warmup,
        out: a.out.clone(),
        rt: a.rt,
        hil_modes: if a.skip_hil { Vec::new() } else { a.hil_modes.iter().map(|m| (*m).into()).collect() },
    };
    let bench = companion_runtime::latency::run(&opts, &Terminal::lines())?;
    print_table(&bench);
    println!(
        "wrote {} and {}",
        a.out.join("latency-benchmark.json").display(),
        a.out.join("latency-benchmark.svg").display()
    );
    Ok(())
}

fn transport(s: &str) -> Result<Transport, String> {
    match s {
        "iox-spin" => Ok(Transport::IoxSpin),
        "iox-event" => Ok(Transport::IoxEvent),
        "uds" => Ok(Transport::Uds),
        "zenoh" => Ok(Transport::Zenoh),
        _ => Err(format!("unknown transport {s:?} (iox-spin, iox-event, uds, zenoh)")),
    }
}

/// Flags of the hidden `latency-peer` subcommand (the echoing side).
#[derive(Args, Clone, Debug)]
pub struct PeerArgs {
    /// The transport: iox-spin, iox-event, uds or zenoh.
    #[arg(long, value_parser = transport)]
    pub transport: Transport,
    /// The iceoryx2 demo name.
    #[arg(long, default_value = "latency")]
    pub name: String,
    /// The folder of the sockets (uds).
    #[arg(long)]
    pub socket_dir: Option<PathBuf>,
    /// The endpoint to connect to (zenoh).
    #[arg(long)]
    pub endpoint: Option<String>,
    /// Real-time setup, pinned to this CPU.
    #[arg(long)]
    pub rt_cpu: Option<usize>,
}

/// The hidden `latency-peer` subcommand.
///
/// # Errors
/// A transport failure.
pub fn run_peer(a: &PeerArgs) -> Result<()> {
    companion_runtime::ipc::quiet_logs();
    if a.transport == Transport::Uds && a.socket_dir.is_none() {
        return Err(anyhow!("--socket-dir is required with uds"));
    }
    let opts = PeerOptions {
        transport: a.transport,
        name: a.name.clone(),
        socket_dir: a.socket_dir.clone(),
        endpoint: a.endpoint.clone(),
        rt_cpu: a.rt_cpu,
    };
    peer(&opts, &Terminal::lines())
}

fn print_table(b: &Benchmark) {
    println!(
        "companion latency: {} samples each, messages {}/{} bytes, {}; {} CPUs, load {} → {}",
        b.cycles,
        b.message_bytes.0,
        b.message_bytes.1,
        if b.rt { "--rt" } else { "no --rt" },
        b.machine.cpus,
        b.load_average_at_start,
        b.machine.load_average
    );
    println!(
        "{:<3} {:<44} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "", "measurement", "p50", "p90", "p99", "p99.9", "p99.99", "max"
    );
    for r in &b.rows {
        let p = &r.ns;
        println!(
            "{:<3} {:<44} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
            format!("({})", r.part),
            r.name,
            fmt_ns(p.p50),
            fmt_ns(p.p90),
            fmt_ns(p.p99),
            fmt_ns(p.p99_9),
            fmt_ns(p.p99_99),
            fmt_ns(p.max)
        );
    }
    for (mode, f) in &b.hil {
        println!(
            "HIL {:<6}: {} cycles, {} deadline misses (500 µs), compute p50 {} max {}, release jitter p99.99 {} \
             max {}{}",
            mode.as_str(),
            f.cycles,
            f.deadline_misses,
            fmt_ns(f.controller_compute_ns.p50),
            fmt_ns(f.controller_compute_ns.max),
            fmt_ns(f.release_jitter_ns.p99_99),
            fmt_ns(f.release_jitter_ns.max),
            if b.rt && !f.rt.fifo { " (SCHED_FIFO refused)" } else { "" }
        );
    }
    println!("ratios of medians:");
    for (name, r) in &b.ratios {
        println!("  {name:<54} {r:>6.2}");
    }
}
