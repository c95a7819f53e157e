//! `companion latency`: the worst-case latency benchmark.
//!
//! In one run, with the HIL's message sizes (216-byte measurement, 200-byte command):
//!
//! 1. the controller step alone, per platform and scalar type (in process, one sample per
//!    step of a simulated run of trajectory 1, variant a);
//! 2. a bare iceoryx2 ping-pong between two processes, both busy-polling — the transport's
//!    floor on this machine — back to back and paced at one round trip per millisecond (the
//!    HIL's rate: caches and predictors cool between exchanges), and the same with the event
//!    service;
//! 3. a Unix-domain datagram socket ping-pong with blocking receives — what a user would
//!    otherwise pick;
//! 4. the full HIL cycle (`companion hil`, real time at 1 kHz) in each wait mode: the
//!    measurement-to-command round trip on the plant's clock.
//!
//! Every figure comes from a histogram of individual samples (criterion cannot give a
//! per-iteration maximum). The table, `latency-benchmark.json` and `latency-benchmark.svg`
//! give p50 … p99.99 and the maximum, and the ratios (4)/(2) and (3)/(2) of the medians.
//! Children are the hidden subcommands `latency-peer` (ping-pong echo) and `hil`.

pub mod pingpong;
pub mod plot;
pub mod stats;

use std::path::{Path, PathBuf};
use std::process::{Command as Process, Stdio};

use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Parser};
use serde::Serialize;

use self::pingpong::RtScope;
use self::stats::{fmt_ns, LatencyHistogram, Percentiles};
use crate::clock::{Clock, MonotonicClock};
use crate::control::AnyController;
use crate::hil::report::Machine;
use crate::hil::WaitMode;
use crate::scenario::{Scenario, ScenarioArgs};

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
    pub hil_modes: Vec<WaitMode>,
    /// Skip part (4), the full HIL cycle.
    #[arg(long)]
    pub skip_hil: bool,
}

#[derive(Parser, Debug)]
struct ScenarioOnly {
    #[command(flatten)]
    s: ScenarioArgs,
}

fn scenario(platform: &str, scalar: &str, duration_s: f64) -> Result<Scenario> {
    let d = format!("{duration_s}");
    let a = ScenarioOnly::try_parse_from(["x", "--platform", platform, "--scalar", scalar, "--duration", &d])
        .map_err(|e| anyhow!("{e}"))?;
    Scenario::from_args(&a.s)
}

/// Part (1): one controller's step times over a simulated run.
///
/// # Errors
/// A scenario that cannot be built.
pub fn controller_step(platform: &str, scalar: &str, cycles: u64, warmup: u64) -> Result<LatencyHistogram> {
    #[allow(clippy::cast_precision_loss)]
    let s = scenario(platform, scalar, (cycles + warmup + 1) as f64 * 1e-3)?;
    let mut plant = crate::sim::build_plant(&s)?;
    let mut ctrl = AnyController::new(&s.controller).map_err(|e| anyhow!("invalid parameter: {e}"))?;
    let clock = MonotonicClock;
    let mut h = LatencyHistogram::new();
    for n in 0..cycles + warmup {
        let meas = plant.measure();
        let t0 = clock.now_ns();
        let r = ctrl.step(&meas, s.dt);
        let t1 = clock.now_ns();
        if n >= warmup {
            h.record(t1 - t0);
        }
        plant.advance(&r.command, s.dt);
    }
    Ok(h)
}

/// One HIL run's figures as the benchmark reads them from its `latency.json`.
#[derive(Clone, Debug, Serialize)]
pub struct HilFigures {
    /// Round trip (ns).
    pub round_trip_ns: Percentiles,
    /// Controller compute (ns).
    pub controller_compute_ns: Percentiles,
    /// Release jitter (ns).
    pub release_jitter_ns: Percentiles,
    /// Cycles.
    pub cycles: u64,
    /// Deadline misses.
    pub deadline_misses: u64,
    /// Whether SCHED_FIFO was in force.
    pub fifo: bool,
}

fn percentiles_from(v: &serde_json::Value) -> Percentiles {
    let g = |k: &str| v.get(k).and_then(serde_json::Value::as_u64).unwrap_or(0);
    Percentiles {
        count: g("count"),
        min: g("min"),
        p50: g("p50"),
        p90: g("p90"),
        p99: g("p99"),
        p99_9: g("p99.9"),
        p99_99: g("p99.99"),
        max: g("max"),
        mean: v.get("mean").and_then(serde_json::Value::as_f64).unwrap_or(0.0),
    }
}

/// Part (4): a real-time `companion hil` run of `cycles` periods at 1 kHz in `mode`, its output
/// in `dir`.
///
/// # Errors
/// The run failed.
pub fn hil_run(exe: &Path, dir: &Path, mode: WaitMode, cycles: u64, use_rt: bool) -> Result<HilFigures> {
    std::fs::create_dir_all(dir)?;
    #[allow(clippy::cast_precision_loss)]
    let duration = format!("{}", cycles as f64 * 1e-3);
    let name = format!("latency-{}-{}", std::process::id(), mode.as_str());
    let log = std::fs::File::create(dir.join("log.txt"))?;
    let mut cmd = Process::new(exe);
    cmd.args([
        "hil",
        "--duration",
        &duration,
        "--wait",
        mode.as_str(),
        "--name",
        &name,
        "--no-plots",
        "--quiet",
    ])
    .arg("--out")
    .arg(dir)
    .stdin(Stdio::null())
    .stdout(log.try_clone()?)
    .stderr(log);
    if use_rt {
        cmd.arg("--rt");
    }
    let status = cmd.status().context("running companion hil")?;
    if !status.success() {
        bail!(
            "companion hil --wait {} failed ({status}); see {}",
            mode.as_str(),
            dir.join("log.txt").display()
        );
    }
    let text = std::fs::read_to_string(dir.join("latency.json"))?;
    let v: serde_json::Value = serde_json::from_str(&text)?;
    Ok(HilFigures {
        round_trip_ns: percentiles_from(&v["round_trip_ns"]),
        controller_compute_ns: percentiles_from(&v["controller_compute_ns"]),
        release_jitter_ns: percentiles_from(&v["release_jitter_ns"]),
        cycles: v["cycles"].as_u64().unwrap_or(0),
        deadline_misses: v["deadline_misses"].as_u64().unwrap_or(0),
        fifo: v["rt"]["fifo"].as_bool().unwrap_or(false),
    })
}

/// One row of the table.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// Part (1–4).
    pub part: &'static str,
    /// What was measured.
    pub name: String,
    /// Its percentiles (ns).
    pub ns: Percentiles,
}

/// `latency-benchmark.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Benchmark {
    /// The command line.
    pub command: String,
    /// Samples per measurement.
    pub cycles: u64,
    /// Message sizes (bytes): measurement, command.
    pub message_bytes: (usize, usize),
    /// `--rt`.
    pub rt: bool,
    /// The machine at the end of the run.
    pub machine: Machine,
    /// The load average at the start.
    pub load_average_at_start: String,
    /// The rows.
    pub rows: Vec<Row>,
    /// The HIL runs.
    pub hil: Vec<(WaitMode, HilFigures)>,
    /// Ratios of medians.
    pub ratios: Vec<(String, f64)>,
}

#[allow(clippy::cast_precision_loss)]
fn ratio(a: u64, b: u64) -> f64 {
    if b == 0 {
        f64::NAN
    } else {
        a as f64 / b as f64
    }
}

/// `companion latency`.
///
/// # Errors
/// A child process or a file failed.
pub fn run(a: &LatencyArgs) -> Result<()> {
    crate::ipc::quiet_logs();
    if a.cycles == 0 {
        bail!("--cycles must be at least 1");
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let exe = std::env::current_exe().context("locating this program")?;
    let load_start = std::fs::read_to_string("/proc/loadavg").unwrap_or_default().trim().to_string();
    let (own_cpu, _) = pingpong::rt_cpus();
    let mut rows: Vec<Row> = Vec::new();
    let mut hists: Vec<(String, LatencyHistogram)> = Vec::new();
    let mut push = |part: &'static str, name: String, h: LatencyHistogram, rows: &mut Vec<Row>| {
        eprintln!("  {name}: p50 {}  max {}", fmt_ns(h.percentiles().p50), fmt_ns(h.percentiles().max));
        rows.push(Row { part, name: name.clone(), ns: h.percentiles() });
        hists.push((name, h));
    };
    eprintln!("(1) controller step, {} steps per platform and scalar type", a.cycles);
    for platform in ["unicycle", "car", "omni"] {
        for scalar in ["f64", "f32"] {
            let h = {
                let _rt = a.rt.then(|| RtScope::enter(own_cpu));
                controller_step(platform, scalar, a.cycles, a.warmup)?
            };
            push("1", format!("controller step {platform} {scalar}"), h, &mut rows);
        }
    }
    eprintln!("(2) iceoryx2 ping-pong, {} round trips", a.cycles);
    let iox = pingpong::iceoryx(&exe, a.cycles, a.warmup, false, a.rt, None)?;
    let iox_p50 = iox.percentiles().p50;
    push("2", "iceoryx2 ping-pong, busy-poll".into(), iox, &mut rows);
    let paced = pingpong::iceoryx(&exe, a.cycles, a.warmup.min(100), false, a.rt, Some(1_000_000))?;
    let paced_p50 = paced.percentiles().p50;
    push("2", "iceoryx2 ping-pong, busy-poll, one per ms".into(), paced, &mut rows);
    let iox_ev = pingpong::iceoryx(&exe, a.cycles, a.warmup, true, a.rt, None)?;
    let iox_ev_p50 = iox_ev.percentiles().p50;
    push("2", "iceoryx2 ping-pong, events".into(), iox_ev, &mut rows);
    eprintln!("(3) Unix-domain socket ping-pong, {} round trips", a.cycles);
    let uds = pingpong::unix_socket(&exe, a.cycles, a.warmup, a.rt)?;
    let uds_p50 = uds.percentiles().p50;
    push("3", "unix datagram socket ping-pong, blocking".into(), uds, &mut rows);
    let step_p50 = rows.first().map_or(0, |r| r.ns.p50);
    let mut hil = Vec::new();
    if !a.skip_hil {
        for mode in &a.hil_modes {
            eprintln!("(4) HIL cycle, --wait {}, {} cycles at 1 kHz", mode.as_str(), a.cycles);
            let f = hil_run(&exe, &a.out.join(format!("hil-{}", mode.as_str())), *mode, a.cycles, a.rt)?;
            eprintln!(
                "  round trip p50 {}  max {}",
                fmt_ns(f.round_trip_ns.p50),
                fmt_ns(f.round_trip_ns.max)
            );
            rows.push(Row {
                part: "4",
                name: format!("HIL cycle round trip, {}", mode.as_str()),
                ns: f.round_trip_ns,
            });
            hil.push((*mode, f));
        }
    }
    let mut ratios = vec![
        ("unix socket / iceoryx2 busy-poll".to_string(), ratio(uds_p50, iox_p50)),
        ("iceoryx2 events / iceoryx2 busy-poll".to_string(), ratio(iox_ev_p50, iox_p50)),
    ];
    for (mode, f) in &hil {
        ratios.push((
            format!("HIL {} / iceoryx2 busy-poll", mode.as_str()),
            ratio(f.round_trip_ns.p50, iox_p50),
        ));
        if *mode == WaitMode::Spin {
            ratios.push((
                "HIL spin / (iceoryx2 busy-poll + step unicycle f64)".to_string(),
                ratio(f.round_trip_ns.p50, iox_p50 + step_p50),
            ));
            ratios.push((
                "HIL spin / (iceoryx2 one per ms + HIL compute)".to_string(),
                ratio(f.round_trip_ns.p50, paced_p50 + f.controller_compute_ns.p50),
            ));
        }
        if *mode == WaitMode::Event {
            ratios.push(("HIL event / iceoryx2 events".to_string(), ratio(f.round_trip_ns.p50, iox_ev_p50)));
        }
    }
    let bench = Benchmark {
        command: std::env::args().collect::<Vec<_>>().join(" "),
        cycles: a.cycles,
        message_bytes: (crate::wire::MEASUREMENT_SIZE, crate::wire::COMMAND_SIZE),
        rt: a.rt,
        machine: Machine::now(),
        load_average_at_start: load_start,
        rows,
        hil,
        ratios,
    };
    print_table(&bench);
    let path = a.out.join("latency-benchmark.json");
    std::fs::write(&path, serde_json::to_string_pretty(&bench)? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;
    let series: Vec<(&str, &LatencyHistogram)> =
        hists.iter().filter(|(n, _)| !n.contains("f32")).map(|(n, h)| (n.as_str(), h)).collect();
    let svg = a.out.join("latency-benchmark.svg");
    if let Err(e) =
        plot::latency_svg(&svg, "companion latency: step, transports (HIL runs: see hil-*/)", &series, None)
    {
        eprintln!("warning: plot: {e:#}");
    }
    println!("wrote {} and {}", path.display(), svg.display());
    Ok(())
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
            if b.rt && !f.fifo { " (SCHED_FIFO refused)" } else { "" }
        );
    }
    println!("ratios of medians:");
    for (name, r) in &b.ratios {
        println!("  {name:<54} {r:>6.2}");
    }
}
