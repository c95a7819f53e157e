//! `companion latency` and its hidden echoing peer.

use std::path::PathBuf;

use anyhow::{anyhow, Result};
use clap::Args;
use companion_runtime::domain::histogram::fmt_ns;
use companion_runtime::run::latency::pingpong::{PeerOptions, Transport};
use companion_runtime::run::latency::run_peer as peer;
use companion_runtime::run::latency::{Benchmark, LatencyOptions, Load};

use super::hil::WaitArg;
use super::terminal::Terminal;

/// `companion latency` flags.
#[derive(Args, Clone, Debug)]
pub struct LatencyArgs {
    /// Samples per measurement.
    ///
    /// Samples per measurement (HIL: cycles at 1 kHz, so 100000 takes 100 s per wait mode).
    #[arg(long, default_value_t = 20_000, value_name = "N", allow_hyphen_values = true)]
    pub cycles: u64,
    /// Warm-up iterations before each measurement.
    ///
    /// Unrecorded warm-up iterations before each ping-pong and step measurement.
    #[arg(long, default_value_t = 1_000, value_name = "N", allow_hyphen_values = true)]
    pub warmup: u64,
    /// Output folder (created if missing).
    #[arg(long, default_value = "out/latency", value_name = "DIR")]
    pub out: PathBuf,
    /// Real-time setup for every part.
    ///
    /// Real-time setup for every part (mlockall, SCHED_FIFO, one CPU per process).
    #[arg(long)]
    pub rt: bool,
    /// The HIL wait modes to measure.
    ///
    /// The HIL wait modes to measure, comma-separated: adaptive, spin, hybrid, event (as
    /// `companion hil --wait`).
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "adaptive,spin,hybrid,event",
        value_name = "MODES",
        hide_possible_values = true
    )]
    pub hil_modes: Vec<WaitArg>,
    /// The loads: idle and/or busy (a busy thread per CPU).
    ///
    /// The loads to measure each HIL wait mode under: `idle` (the machine as it is) and
    /// `busy` (this program runs one busy-looping thread per online CPU, at normal priority,
    /// for the whole HIL run).
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "idle,busy",
        value_name = "LOADS",
        hide_possible_values = true
    )]
    pub loads: Vec<LoadArg>,
    /// Skip part (4), the full HIL cycle.
    #[arg(long)]
    pub skip_hil: bool,
    /// Only the Zenoh ping-pongs, hop by hop, and the Unix socket.
    ///
    /// Only the Zenoh ping-pongs (each configuration, split hop by hop) and the Unix socket
    /// they are compared with.
    #[arg(long)]
    pub zenoh_only: bool,
}

/// `--loads`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LoadArg {
    /// The machine as it is.
    Idle,
    /// One busy-looping thread per online CPU.
    Busy,
}

impl From<LoadArg> for Load {
    fn from(l: LoadArg) -> Self {
        match l {
            LoadArg::Idle => Load::Idle,
            LoadArg::Busy => Load::Busy,
        }
    }
}

/// `companion latency`.
///
/// # Errors
/// A child process or a file failed, or the second clock disagreed with the samples (the
/// figures are then not to be trusted; the files are written).
pub fn run(a: &LatencyArgs) -> Result<()> {
    companion_runtime::transport::ipc::quiet_logs();
    let opts = LatencyOptions {
        cycles: a.cycles,
        warmup: a.warmup,
        out: a.out.clone(),
        rt: a.rt,
        hil_modes: if a.skip_hil || a.zenoh_only {
            Vec::new()
        } else {
            a.hil_modes.iter().map(|m| (*m).into()).collect()
        },
        loads: a.loads.iter().map(|l| (*l).into()).collect(),
        zenoh_only: a.zenoh_only,
    };
    let bench = companion_runtime::run::latency::run(&opts, &Terminal::lines())?;
    print_table(&bench);
    println!(
        "wrote {} and {}",
        a.out.join("latency-benchmark.json").display(),
        a.out.join("latency-benchmark.svg").display()
    );
    let off: Vec<&str> =
        bench.second_clock.iter().filter(|(_, c)| !c.agrees()).map(|(n, _)| n.as_str()).collect();
    if !off.is_empty() {
        anyhow::bail!("the second clock disagrees with the samples of: {}", off.join(", "));
    }
    Ok(())
}

fn transport(s: &str) -> Result<Transport, String> {
    match s {
        "iox-spin" => Ok(Transport::IoxSpin),
        "iox-event" => Ok(Transport::IoxEvent),
        "uds" => Ok(Transport::Uds),
        "zenoh" => Ok(Transport::Zenoh),
        "dds" => Ok(Transport::Dds),
        _ => Err(format!("unknown transport {s:?} (iox-spin, iox-event, uds, zenoh, dds)")),
    }
}

/// Flags of the hidden `latency-peer` subcommand (the echoing side).
#[derive(Args, Clone, Debug)]
pub struct PeerArgs {
    /// The transport: iox-spin, iox-event, uds, zenoh or dds.
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
    /// The TLS material of a `tls/` endpoint (zenoh).
    #[arg(long)]
    pub tls_dir: Option<PathBuf>,
    /// Real-time setup, pinned to this CPU.
    #[arg(long, allow_hyphen_values = true)]
    pub rt_cpu: Option<usize>,
    /// Zenoh's low-latency transport (zenoh).
    #[arg(long)]
    pub zenoh_low_latency: bool,
    /// Spin on the ring instead of sleeping until woken (zenoh).
    #[arg(long)]
    pub zenoh_spin: bool,
}

/// The hidden `latency-peer` subcommand.
///
/// # Errors
/// A transport failure.
pub fn run_peer(a: &PeerArgs) -> Result<()> {
    companion_runtime::transport::ipc::quiet_logs();
    if a.transport == Transport::Uds && a.socket_dir.is_none() {
        return Err(anyhow!("--socket-dir is required with uds"));
    }
    let opts = PeerOptions {
        transport: a.transport,
        name: companion_runtime::sys::lock::DemoName::new(&a.name)?,
        socket_dir: a.socket_dir.clone(),
        endpoint: a.endpoint.clone(),
        tls_dir: a.tls_dir.clone(),
        rt_cpu: a.rt_cpu,
        zenoh_low_latency: a.zenoh_low_latency,
        zenoh_spin: a.zenoh_spin,
    };
    Ok(peer(&opts, &Terminal::lines())?)
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
    if !b.hil.is_empty() {
        println!(
            "HIL runs (500 µs deadline; busy = {} busy-looping threads of this program):",
            b.load_threads
        );
        println!(
            "  {:<9} {:<5} {:>8} {:>8} {:>7} {:>6} {:>10} {:>10} {:>10}",
            "wait", "load", "cycles", "misses", "miss %", "stops", "rt p50", "rt p99.9", "rt max"
        );
    }
    for (mode, load, f) in &b.hil {
        let pct = if f.cycles > 0 { 100.0 * f.deadline_misses as f64 / f.cycles as f64 } else { 0.0 };
        println!(
            "  {:<9} {:<5} {:>8} {:>8} {:>6.2}% {:>6} {:>10} {:>10} {:>10}{}",
            mode.as_str(),
            load.as_str(),
            f.cycles,
            f.deadline_misses,
            pct,
            f.stop_events,
            fmt_ns(f.round_trip_ns.p50),
            fmt_ns(f.round_trip_ns.p99_9),
            fmt_ns(f.round_trip_ns.max),
            if b.rt && !f.rt.fifo { " (SCHED_FIFO refused)" } else { "" }
        );
    }
    if !b.miss_account.is_empty() {
        println!("HIL misses against the bare transport paced at 1 kHz under the same load, in this run:");
        for t in &b.paced_transport {
            println!(
                "  bare iceoryx2, {:<5} round trip p50 {:>9}, max {:>9}: {} of {} over the {} deadline",
                t.load.as_str(),
                fmt_ns(t.round_trip_ns.p50),
                fmt_ns(t.round_trip_ns.max),
                t.over_deadline,
                t.round_trip_ns.count,
                fmt_ns(t.deadline_ns)
            );
        }
        println!(
            "  {:<9} {:<5} {:>7} {:>9} {:>7} {:>10} {:>6} {:>9} {:>11} {:>8}",
            "wait",
            "load",
            "misses",
            "bare's",
            "beyond",
            "controller",
            "plant",
            "way back",
            "unanswered",
            "p50 ×"
        );
        for m in &b.miss_account {
            println!(
                "  {:<9} {:<5} {:>7} {:>9} {:>7} {:>10} {:>6} {:>9} {:>11} {:>8.2}",
                m.wait.as_str(),
                m.load.as_str(),
                m.loop_misses,
                m.transport_misses,
                m.beyond_transport,
                m.causes.controller(),
                m.causes.plant_late,
                m.causes.return_path,
                m.causes.unanswered + m.causes.clocks_apart,
                m.p50_ratio
            );
        }
    }
    println!("ratios of medians:");
    for (name, r) in &b.ratios {
        println!("  {name:<54} {r:>6.2}");
    }
    for h in &b.zenoh_hops {
        println!("zenoh round trip hop by hop, {} (one CLOCK_MONOTONIC in both processes):", h.config);
        println!("  {:<54} {:>9} {:>9} {:>9} {:>9}", "hop", "p50", "p99", "p99.9", "mean");
        for r in &h.rows {
            println!(
                "  {:<54} {:>9} {:>9} {:>9} {:>9}",
                r.name,
                fmt_ns(r.ns.p50),
                fmt_ns(r.ns.p99),
                fmt_ns(r.ns.p99_9),
                fmt_ns(r.mean_ns as u64)
            );
        }
        println!(
            "  check: hop medians sum to {:.1} % of the round trip's median (tolerance ±{:.0} %), means to {:.1} % \
             (±{:.0} %); the round trip is {:.1} % of the ping-pong's own sample (±{:.0} %); {} stamps out of order; \
             {} hops delivered before their put returned{}",
            100.0 * h.median_share(),
            100.0 * companion_runtime::run::latency::hops::MEDIAN_TOLERANCE,
            100.0 * h.mean_share(),
            100.0 * companion_runtime::run::latency::hops::MEAN_TOLERANCE,
            100.0 * h.sample_share(),
            100.0 * companion_runtime::run::latency::hops::SAMPLE_TOLERANCE,
            h.out_of_order,
            h.delivered_before_put_returned,
            if h.agrees() { "" } else { "  DISAGREE" }
        );
    }
    println!(
        "second clock (back-to-back ping-pongs: the samples' sum against the batch by CLOCK_MONOTONIC_RAW):"
    );
    for (name, c) in &b.second_clock {
        println!("  {name:<52} {:>6.1} %{}", 100.0 * c.share(), if c.agrees() { "" } else { "  DISAGREE" });
    }
}
