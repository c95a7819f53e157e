//! `companion latency`: the worst-case latency benchmark.
//!
//! In one run, with the HIL's message sizes (344-byte measurement, 248-byte command):
//!
//! 1. the controller step alone, per platform and scalar type (in process, one sample per
//!    step of a simulated run of trajectory 1, variant a);
//! 2. a bare iceoryx2 ping-pong between two processes, both busy-polling — the transport's
//!    floor on this machine — back to back and paced at one round trip per millisecond (the
//!    HIL's rate: caches and predictors cool between exchanges), and the same with the event
//!    service;
//! 3. a Unix-domain datagram socket ping-pong with blocking receives — what a user would
//!    otherwise pick — and, in a build with the `zenoh` feature, a Zenoh ping-pong over
//!    loopback TCP (the two-machine transport; aim: p50 at most twice the socket's) and,
//!    where network namespaces are permitted (root), across a veth pair into a namespace
//!    (skipped with a warning otherwise); in a build with the `ros2` feature, a DDS ping-pong
//!    (RustDDS on loopback UDP, as `companion ros2` talks to a robot: module `dds`), plain and
//!    under SROS 2 (DDS-Security, as the node with an enclave);
//! 4. the full HIL cycle (`companion hil`, real time at 1 kHz) in each wait mode: the
//!    measurement-to-command round trip on the plant's clock, deadline misses and robot
//!    stops — once on the machine as it is ("idle") and once under a load this program makes
//!    itself ([`BusyLoad`]: one busy-looping thread per online CPU, at normal priority, in
//!    this process), so that one run shows how each mode copes with a shared machine. Under
//!    each load, before the HIL runs, the bare iceoryx2 ping-pong paced at 1 kHz runs as many
//!    round trips as they have cycles: its round trips over the deadline are the transport's
//!    own misses, and each run's misses, by cause (`latency.json` `miss_causes`: the
//!    controller's, the plant's, the way back, unanswered), are set against them
//!    ([`MissAccount`]: the loop's misses beyond the transport's, their ratio, the medians').
//!
//! Every figure comes from a histogram of individual samples (criterion cannot give a
//! per-iteration maximum). The table, `latency-benchmark.json` and `latency-benchmark.svg`
//! give p50 … p99.99 and the maximum, and the ratios (4)/(2) and (3)/(2) of the medians.
//! Children are the hidden subcommands `latency-peer` (ping-pong echo) and `hil`.

#[cfg(feature = "ros2")]
pub mod dds;
pub mod error;
pub mod figures;
pub mod hops;
pub mod pingpong;
pub mod repeat;
#[cfg(feature = "zenoh")]
pub mod zenoh;

use std::path::{Path, PathBuf};
use std::process::{Command as Process, Stdio};

use companion_core::{PaperRun, PlatformKind};
use companion_plant::PaperTrajectory;
use serde::Serialize;

use self::error::{os, LatencyError};
pub use self::figures::{ControllerFigures, HilFigures, Load, RtFigures};
use self::pingpong::{PeerOptions, RtScope, SecondClock, Transport};
use self::repeat::{BareRun, Contender, HilRun, Repeated};
use crate::domain::controller::{platform_name, AnyController, Scalar};
use crate::domain::histogram::{fmt_ns, LatencyHistogram, Percentiles};
use crate::domain::observe::{Causes, Observer};
use crate::domain::scenario::{Scenario, ScenarioError};
use crate::run::hil::misses::MissCauses;
use crate::run::hil::{ReleaseTimer, WaitMode};
use crate::sys::clock::{Clock, MonotonicClock};
use crate::sys::machine::Machine;
use crate::sys::rt;

/// What `companion latency` measures.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LatencyOptions {
    /// Samples per measurement (HIL: cycles at 1 kHz).
    pub cycles: u64,
    /// Unrecorded warm-up iterations before each ping-pong and step measurement.
    pub warmup: u64,
    /// Output folder (created if missing).
    pub out: PathBuf,
    /// Real-time setup for every part.
    pub rt: bool,
    /// The HIL wait modes to measure (none: skip part 4).
    pub hil_modes: Vec<WaitMode>,
    /// The plant's release timers to measure with the modes that sleep to the release
    /// ([`Contender::all`]).
    pub release_timers: Vec<ReleaseTimer>,
    /// The loads to measure them under.
    pub loads: Vec<Load>,
    /// Rounds of part (4), interleaved ([`repeat`]).
    pub repeat: u32,
    /// Only the Zenoh ping-pongs and the Unix socket they are compared with (parts 1, 2 and
    /// 4 skipped).
    pub zenoh_only: bool,
    /// Only part (4).
    pub hil_only: bool,
}

/// The load generator: `threads` threads of this process, each busy-looping (a spin hint and
/// an atomic load) at normal priority until dropped. One per online CPU competes with both
/// HIL processes for every CPU, as a build or another program would.
#[derive(Debug)]
pub struct BusyLoad {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl BusyLoad {
    /// Starts `threads` busy threads.
    ///
    /// # Errors
    /// A thread cannot be started.
    pub fn start(threads: usize) -> Result<Self, LatencyError> {
        use std::sync::atomic::{AtomicBool, Ordering};
        let stop = std::sync::Arc::new(AtomicBool::new(false));
        let mut handles = Vec::with_capacity(threads);
        for i in 0..threads {
            let s = std::sync::Arc::clone(&stop);
            handles.push(
                std::thread::Builder::new()
                    .name(format!("busy-{i}"))
                    .spawn(move || {
                        while !s.load(Ordering::Relaxed) {
                            std::hint::spin_loop();
                        }
                    })
                    .map_err(os(|| "starting a load thread".into()))?,
            );
        }
        Ok(Self { stop, threads: handles })
    }
}

impl Drop for BusyLoad {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// Part (1): one controller's step times over a simulated run.
///
/// # Errors
/// A scenario that cannot be built.
pub fn controller_step(
    platform: PlatformKind,
    scalar: Scalar,
    cycles: u64,
    warmup: u64,
) -> Result<LatencyHistogram, LatencyError> {
    let s = Scenario::builder(PaperTrajectory::One, PaperRun::A, platform)
        .scalar(scalar)
        .duration((cycles + warmup + 1) as f64 * 1e-3)
        .build()?;
    let mut plant = crate::run::sim::build_plant(&s)?;
    let mut ctrl = AnyController::new(&s.controller).map_err(ScenarioError::Param)?;
    let clock = MonotonicClock;
    let mut h = LatencyHistogram::new();
    for n in 0..cycles + warmup {
        let meas = plant.measure();
        let t0 = clock.now_ns();
        let r = ctrl.step(&meas, s.dt, 0.0);
        let t1 = clock.now_ns();
        if n >= warmup {
            h.record(t1 - t0);
        }
        plant.advance(&r.command, s.dt);
    }
    Ok(h)
}

/// The deadline of the HIL runs of part (4): `companion hil`'s default `--deadline-us`.
pub const HIL_DEADLINE_NS: u64 = 500_000;

/// The bare transport under one load, paced at the HIL's period, as many round trips as the
/// HIL runs have cycles: what the loop's misses are measured against.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PacedTransport {
    /// The load.
    pub load: Load,
    /// Its round trips (ns).
    pub round_trip_ns: Percentiles,
    /// Round trips longer than the HIL's deadline: the transport's own misses.
    pub over_deadline: u64,
    /// That deadline (ns).
    pub deadline_ns: u64,
}

/// One HIL run against the paced bare transport under the same load, in the same run
/// (`latency-benchmark.json` `miss_account`).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct MissAccount {
    /// The wait mode.
    pub wait: WaitMode,
    /// The load.
    pub load: Load,
    /// The loop's deadline misses.
    pub loop_misses: u64,
    /// The bare transport's round trips over the deadline.
    pub transport_misses: u64,
    /// The loop's misses minus the transport's (negative: fewer than the bare transport's).
    pub beyond_transport: i64,
    /// Their ratio (aim: at most 1 idle, at most 2 under load; `null` when the transport
    /// missed none and the loop did).
    pub ratio: Option<f64>,
    /// The loop's misses by cause.
    pub causes: MissCauses,
    /// The loop's round-trip median over the paced transport's (aim: at most 2).
    pub p50_ratio: f64,
}

impl MissAccount {
    /// The account of `f` against `t`.
    pub fn new(wait: WaitMode, load: Load, f: &HilFigures, t: &PacedTransport) -> Self {
        let (l, b) = (f.deadline_misses, t.over_deadline);
        Self {
            wait,
            load,
            loop_misses: l,
            transport_misses: b,
            beyond_transport: i64::try_from(l).unwrap_or(i64::MAX) - i64::try_from(b).unwrap_or(i64::MAX),
            ratio: if b == 0 { (l == 0).then_some(1.0) } else { Some(l as f64 / b as f64) },
            causes: f.miss_causes,
            p50_ratio: ratio(f.round_trip_ns.p50, t.round_trip_ns.p50),
        }
    }
}

/// Part (4): a real-time `companion hil` run of `cycles` periods at 1 kHz in `mode` with the
/// plant's `release` timer, its output in `dir`: the plant's figures and the controller's
/// (`None` if it wrote none).
///
/// # Errors
/// The run failed.
pub fn hil_run(
    exe: &Path,
    dir: &Path,
    mode: WaitMode,
    release: ReleaseTimer,
    cycles: u64,
    use_rt: bool,
) -> Result<(HilFigures, Option<ControllerFigures>), LatencyError> {
    std::fs::create_dir_all(dir)?;
    let duration = format!("{}", cycles as f64 * 1e-3);
    let name = format!("latency-{}-{}", std::process::id(), mode.as_str());
    let deadline_us = (HIL_DEADLINE_NS / 1_000).to_string();
    let log = std::fs::File::create(dir.join("log.txt"))?;
    let mut cmd = Process::new(exe);
    cmd.args([
        "hil",
        "--duration",
        &duration,
        "--wait",
        mode.as_str(),
        "--release-timer",
        release.as_str(),
        "--name",
        &name,
        "--deadline-us",
        &deadline_us,
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
    let status = cmd.status().map_err(os(|| "running companion hil".into()))?;
    // 7: real time was not kept — what this benchmark measures, not a failure of it.
    if !(status.success() || status.code() == Some(7)) {
        return Err(LatencyError::HilFailed { mode: mode.as_str(), status, log: dir.join("log.txt") });
    }
    let path = dir.join("latency.json");
    let text = std::fs::read_to_string(&path).map_err(os(|| format!("reading {}", path.display())))?;
    let f = serde_json::from_str(&text).map_err(|source| LatencyError::Json { path, source })?;
    let path = dir.join("controller.json");
    let controller = match std::fs::read_to_string(&path) {
        Ok(text) => Some(serde_json::from_str(&text).map_err(|source| LatencyError::Json { path, source })?),
        Err(_) => None,
    };
    Ok((f, controller))
}

/// The box plot of part (4)'s runs ([`Repeated::plot`]), in the output folder.
pub const REPEAT_SVG: &str = "latency-repeat.svg";
/// Part (4)'s table for the docs ([`Repeated::markdown`]), in the output folder.
pub const REPEAT_MD: &str = "latency-repeat.md";

impl Benchmark {
    /// Part (4)'s table for the docs, with the command and the machine (`None`: no HIL runs).
    pub fn repeated_markdown(&self) -> Option<String> {
        let r = self.repeated.as_ref()?;
        let m = &self.machine;
        let machine = format!(
            "{} CPUs, load average {} at the start, {} at the end{}",
            m.cpus,
            self.load_average_at_start,
            m.load_average,
            if self.rt { ", --rt" } else { "" }
        );
        Some(r.markdown(&self.command, &machine))
    }

    /// `index.html`: the figures and part (4)'s table.
    pub fn index_html(&self) -> String {
        let esc = |t: &str| t.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;");
        let mut html = String::from(
            "<!doctype html><meta charset=utf-8><title>companion latency</title>\n<h1>companion latency</h1>\n",
        );
        html.push_str(&format!("<p><code>{}</code></p>\n", esc(&self.command)));
        if let Some(md) = self.repeated_markdown() {
            html.push_str(&format!(
                "<h2>HIL runs against the bare transport</h2>\n<p><a href=\"{REPEAT_SVG}\"><img src=\"{REPEAT_SVG}\" \
                 style=\"max-width:100%\"></a></p>\n<p>The table for the docs (<a href=\"{REPEAT_MD}\">{REPEAT_MD}</a>):</p>\n\
                 <pre>{}</pre>\n",
                esc(&md)
            ));
        }
        if !self.rows.iter().all(|r| r.part == "4") {
            html.push_str(
                "<h2>Step and transports</h2>\n<p><img src=\"latency-benchmark.svg\" style=\"max-width:100%\"></p>\n",
            );
        }
        html.push_str("<p>All figures: <a href=\"latency-benchmark.json\">latency-benchmark.json</a>.</p>\n");
        html
    }
}

/// Part (4)'s progress: runs done of all, and the time left at the pace so far.
#[derive(Debug)]
struct Progress {
    total: usize,
    done: usize,
    start: std::time::Instant,
}

impl Progress {
    fn new(total: usize) -> Self {
        Self { total, done: 0, start: std::time::Instant::now() }
    }

    fn done(&mut self) {
        self.done += 1;
    }

    /// ` (run k of n, about T left)`.
    fn eta(&self) -> String {
        if self.total <= 1 {
            return String::new();
        }
        let left = if self.done == 0 {
            String::new()
        } else {
            let per = self.start.elapsed().as_secs_f64() / self.done as f64;
            let s = (per * (self.total - self.done) as f64).round() as u64;
            format!(", about {} min {} s left", s / 60, s % 60)
        };
        format!(" (run {} of {}{left})", self.done + 1, self.total)
    }
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
    /// The HIL runs: wait mode, load, figures.
    pub hil: Vec<(WaitMode, Load, HilFigures)>,
    /// The load generator's threads (`busy` runs).
    pub load_threads: usize,
    /// Ratios of medians.
    pub ratios: Vec<(String, f64)>,
    /// The back-to-back ping-pongs against a second clock ([`SecondClock`]).
    pub second_clock: Vec<(String, SecondClock)>,
    /// The Zenoh round trips split at each hop, one per configuration ([`hops`]).
    pub zenoh_hops: Vec<hops::HopReport>,
    /// The bare iceoryx2 transport paced at the HIL's period under each load (part 4).
    pub paced_transport: Vec<PacedTransport>,
    /// Each HIL run's misses against it.
    pub miss_account: Vec<MissAccount>,
    /// Every round of part (4) (`hil`, `paced_transport`, `miss_account` and the rows are the
    /// first round's).
    pub repeated: Option<Repeated>,
}

fn ratio(a: u64, b: u64) -> f64 {
    if b == 0 {
        f64::NAN
    } else {
        a as f64 / b as f64
    }
}

/// `companion latency`: measures every part, writes `latency-benchmark.json` and
/// `latency-benchmark.svg` into `a.out`, and returns the figures.
///
/// # Errors
/// A child process or a file failed.
pub fn run(a: &LatencyOptions, observer: &dyn Observer) -> Result<Benchmark, LatencyError> {
    if a.cycles == 0 {
        return Err(LatencyError::NoCycles);
    }
    std::fs::create_dir_all(&a.out).map_err(os(|| format!("creating {}", a.out.display())))?;
    let exe = std::env::current_exe().map_err(os(|| "locating this program".into()))?;
    let load_start = std::fs::read_to_string("/proc/loadavg").unwrap_or_default().trim().to_string();
    let (own_cpu, _) = pingpong::rt_cpus();
    let mut rows: Vec<Row> = Vec::new();
    let mut hists: Vec<(String, LatencyHistogram)> = Vec::new();
    let mut push = |part: &'static str, name: String, h: LatencyHistogram, rows: &mut Vec<Row>| {
        observer.note(&format!(
            "  {name}: p50 {}  max {}",
            fmt_ns(h.percentiles().p50),
            fmt_ns(h.percentiles().max)
        ));
        rows.push(Row { part, name: name.clone(), ns: h.percentiles() });
        hists.push((name, h));
    };
    let parts_1_2 = !a.zenoh_only && !a.hil_only;
    if parts_1_2 {
        observer.note(&format!("(1) controller step, {} steps per platform and scalar type", a.cycles));
    }
    for platform in
        [PlatformKind::Unicycle, PlatformKind::Car, PlatformKind::Omni].into_iter().filter(|_| parts_1_2)
    {
        for scalar in [Scalar::F64, Scalar::F32] {
            let h = {
                let _rt = a.rt.then(|| RtScope::enter(own_cpu, observer));
                controller_step(platform, scalar, a.cycles, a.warmup)?
            };
            push("1", format!("controller step {} {}", platform_name(platform), scalar.name()), h, &mut rows);
        }
    }
    observer.note(&format!("(2) iceoryx2 ping-pong, {} round trips", a.cycles));
    let mut second_clock: Vec<(String, SecondClock)> = Vec::new();
    let mut checked = |name: &str, c: SecondClock| {
        observer.note(&format!(
            "  second clock: the {} samples sum to {:.1} ms, the batch took {:.1} ms by CLOCK_MONOTONIC_RAW ({:.1} %)",
            c.samples,
            c.samples_sum_ns as f64 / 1e6,
            c.batch_raw_ns as f64 / 1e6,
            100.0 * c.share()
        ));
        if !c.agrees() {
            observer.warn(&format!(
                "{name}: the samples ({:.1} % of the batch) and the second clock disagree",
                100.0 * c.share()
            ));
        }
        second_clock.push((name.to_string(), c));
    };
    let (mut iox_p50, mut paced_p50, mut iox_ev_p50) = (0, 0, 0);
    if parts_1_2 {
        let (iox, c) = pingpong::iceoryx(&exe, a.cycles, a.warmup, false, a.rt, None, observer)?;
        checked("iceoryx2 ping-pong, busy-poll", c);
        iox_p50 = iox.percentiles().p50;
        push("2", "iceoryx2 ping-pong, busy-poll".into(), iox, &mut rows);
        // Paced, the batch is mostly waiting: the second clock says nothing of the samples there.
        let (paced, _) =
            pingpong::iceoryx(&exe, a.cycles, a.warmup.min(100), false, a.rt, Some(1_000_000), observer)?;
        paced_p50 = paced.percentiles().p50;
        push("2", "iceoryx2 ping-pong, busy-poll, one per ms".into(), paced, &mut rows);
        let (iox_ev, c) = pingpong::iceoryx(&exe, a.cycles, a.warmup, true, a.rt, None, observer)?;
        checked("iceoryx2 ping-pong, events", c);
        iox_ev_p50 = iox_ev.percentiles().p50;
        push("2", "iceoryx2 ping-pong, events".into(), iox_ev, &mut rows);
    }
    let mut uds_p50 = 0;
    if !a.hil_only {
        observer.note(&format!("(3) Unix-domain socket ping-pong, {} round trips", a.cycles));
        let (uds, c) = pingpong::unix_socket(&exe, a.cycles, a.warmup, a.rt, observer)?;
        checked("unix datagram socket ping-pong", c);
        uds_p50 = uds.percentiles().p50;
        push("3", "unix datagram socket ping-pong, blocking".into(), uds, &mut rows);
    }
    #[cfg(feature = "ros2")]
    let mut dds_p50 = 0;
    #[cfg(feature = "ros2")]
    if !a.hil_only {
        observer.note(&format!(
            "(3) DDS ping-pong (RustDDS on loopback UDP, as companion ros2), {} round trips",
            a.cycles
        ));
        let (h, c) = dds::round_trips(&exe, a.cycles, a.warmup, a.rt, false, observer)?;
        checked("dds ping-pong", c);
        dds_p50 = h.percentiles().p50;
        push("3", "dds ping-pong (RustDDS), reliable, poll".into(), h, &mut rows);
        observer.note(&format!(
            "(3) DDS ping-pong under SROS 2 (DDS-Security: authenticated, access-controlled, encrypted, as companion \
             ros2 with an enclave), {} round trips",
            a.cycles
        ));
        let (h, c) = dds::round_trips(&exe, a.cycles, a.warmup, a.rt, true, observer)?;
        checked("dds ping-pong, SROS 2", c);
        push("3", "dds ping-pong (RustDDS), reliable, poll, SROS 2".into(), h, &mut rows);
    }
    #[cfg_attr(not(feature = "zenoh"), allow(unused_mut))]
    let mut zenoh_hops: Vec<hops::HopReport> = Vec::new();
    #[cfg(feature = "zenoh")]
    let (zenoh_p50, zenoh_tls_p50) = if a.hil_only {
        (0, 0)
    } else {
        let mut note_hops = |r: hops::HopReport| {
            observer.note(&format!(
                "  hops: {}; their medians add up to {:.1} % of the round trip's, their means to {:.1} %, \
                 the round trip to {:.1} % of the sample's{}",
                r.rows
                    .iter()
                    .map(|h| format!("{} {}", h.name, fmt_ns(h.ns.p50)))
                    .collect::<Vec<_>>()
                    .join(", "),
                100.0 * r.median_share(),
                100.0 * r.mean_share(),
                100.0 * r.sample_share(),
                if r.agrees() { "" } else { "  DISAGREE" }
            ));
            zenoh_hops.push(r);
        };
        let mut p50 = 0;
        for (k, variant) in zenoh::Variant::ALL.into_iter().enumerate() {
            observer.note(&format!(
                "(3) Zenoh ping-pong over loopback TCP, {}, {} round trips",
                variant.label(),
                a.cycles
            ));
            let (z, c, h) =
                zenoh::round_trips(&exe, a.cycles, a.warmup, a.rt, None, None, variant, observer)?;
            let name = format!("zenoh ping-pong, tcp loopback, {}", variant.label());
            checked(&name, c);
            if k == 0 {
                p50 = z.percentiles().p50;
            }
            push("3", name, z, &mut rows);
            note_hops(h);
        }
        observer.note(&format!(
            "(3) Zenoh ping-pong over loopback QUIC with mutual TLS (the default link), {} round trips",
            a.cycles
        ));
        let tls = zenoh::Tls::make()?;
        let (z, c, h) = zenoh::round_trips(
            &exe,
            a.cycles,
            a.warmup,
            a.rt,
            None,
            Some(&tls),
            zenoh::Variant::default(),
            observer,
        )?;
        checked("zenoh ping-pong, quic+mtls loopback", c);
        let tls_p50 = z.percentiles().p50;
        push("3", "zenoh ping-pong, quic+mtls loopback, default".into(), z, &mut rows);
        note_hops(h);
        observer.note("(3) Zenoh session set-up on loopback (connect until the peer is seen), 20 times each");
        push("3", "zenoh session set-up, tcp loopback".into(), zenoh::session_setup(20, None)?, &mut rows);
        push(
            "3",
            "zenoh session set-up, quic+mtls loopback".into(),
            zenoh::session_setup(20, Some(&tls))?,
            &mut rows,
        );
        match zenoh::Veth::create() {
            Ok(v) => {
                observer.note(&format!(
                    "(3) Zenoh ping-pong across a veth pair into network namespace {}, {} round trips",
                    v.netns, a.cycles
                ));
                let (z, c, h) = zenoh::round_trips(
                    &exe,
                    a.cycles,
                    a.warmup,
                    a.rt,
                    Some(&v),
                    None,
                    zenoh::Variant::default(),
                    observer,
                )?;
                checked("zenoh ping-pong, tcp across network namespaces", c);
                push("3", "zenoh ping-pong, tcp across network namespaces, default".into(), z, &mut rows);
                note_hops(h);
            }
            Err(e) => observer.warn(&format!(
                "(3) Zenoh across network namespaces skipped: {} (needs root and `ip netns`)",
                Causes(&e)
            )),
        }
        (p50, tls_p50)
    };
    let step_p50 = rows.first().map_or(0, |r| r.ns.p50);
    let mut hil = Vec::new();
    let (mut paced_transport, mut miss_account) = (Vec::new(), Vec::new());
    let load_threads = crate::sys::rt::online_cpus();
    let contenders = Contender::all(&a.hil_modes, &a.release_timers);
    let rounds = a.repeat.max(1);
    let (mut runs, mut bare) = (Vec::new(), Vec::new());
    let mut progress = Progress::new(if contenders.is_empty() {
        0
    } else {
        rounds as usize * a.loads.len() * (contenders.len() + 1)
    });
    for round in (1..=rounds).filter(|_| !contenders.is_empty()) {
        for load in &a.loads {
            let _busy = match load {
                Load::Idle => None,
                Load::Busy => Some(BusyLoad::start(load_threads)?),
            };
            let mut done = Vec::with_capacity(contenders.len());
            for c in &contenders {
                let label = c.label();
                observer.note(&format!(
                    "(4) {}HIL cycle, --wait {}{}, {}, {} cycles at 1 kHz{}",
                    if rounds > 1 { format!("round {round}/{rounds}: ") } else { String::new() },
                    c.wait.as_str(),
                    if c.release == ReleaseTimer::default() {
                        String::new()
                    } else {
                        format!(" --release-timer {}", c.release.as_str())
                    },
                    load.as_str(),
                    a.cycles,
                    progress.eta()
                ));
                let dir = if rounds == 1 {
                    a.out.join(format!("hil-{label}-{}", load.as_str()))
                } else {
                    a.out.join("runs").join(format!("{round:02}-{label}-{}", load.as_str()))
                };
                let (f, controller) = hil_run(&exe, &dir, c.wait, c.release, a.cycles, a.rt)?;
                progress.done();
                let late = controller.map_or(String::new(), |k| {
                    let w = k.wakes.late_wakes;
                    format!(
                        "; the controller's late wakes {}{}",
                        w.wakes(),
                        w.main_cause()
                            .map_or(String::new(), |m| format!(" (most missed: {})", m.replace('_', " ")))
                    )
                });
                observer.note(&format!(
                    "  round trip p50 {}  max {}; {} deadline misses (plant {}, controller {}), {} robot stops{late}",
                    fmt_ns(f.round_trip_ns.p50),
                    fmt_ns(f.round_trip_ns.max),
                    f.deadline_misses,
                    f.miss_causes.plant_late,
                    f.miss_causes.controller(),
                    f.stop_events
                ));
                if f.deadline_ns != HIL_DEADLINE_NS {
                    return Err(LatencyError::DeadlineMismatch {
                        hil_ns: f.deadline_ns,
                        transport_ns: HIL_DEADLINE_NS,
                    });
                }
                done.push((*c, f, controller, dir));
            }
            // The bare transport last in the round, under the same load.
            observer.note(&format!(
                "(4) {}the bare transport under the same load: iceoryx2 ping-pong, busy-poll, one per ms, {}, {} round \
                 trips{}",
                if rounds > 1 { format!("round {round}/{rounds}: ") } else { String::new() },
                load.as_str(),
                a.cycles,
                progress.eta()
            ));
            let (h, _) =
                pingpong::iceoryx(&exe, a.cycles, a.warmup.min(100), false, a.rt, Some(1_000_000), observer)?;
            progress.done();
            let t = PacedTransport {
                load: *load,
                round_trip_ns: h.percentiles(),
                over_deadline: h.count_above(HIL_DEADLINE_NS),
                deadline_ns: HIL_DEADLINE_NS,
            };
            observer.note(&format!(
                "  round trip p50 {}  max {}; {} over the {} deadline",
                fmt_ns(t.round_trip_ns.p50),
                fmt_ns(t.round_trip_ns.max),
                t.over_deadline,
                fmt_ns(HIL_DEADLINE_NS)
            ));
            bare.push(BareRun {
                round,
                load: *load,
                over_deadline: t.over_deadline,
                round_trip_ns: t.round_trip_ns,
            });
            for (c, f, controller, dir) in done {
                let run = HilRun::new(round, *load, c, &f, controller, t.over_deadline, dir);
                observer.note(&format!(
                    "  {} {}: {} misses, {:+} beyond the bare transport's {}",
                    run.label,
                    load.as_str(),
                    run.misses,
                    run.beyond_bare,
                    t.over_deadline
                ));
                runs.push(run);
                if round == 1 {
                    miss_account.push(MissAccount::new(c.wait, *load, &f, &t));
                    rows.push(Row {
                        part: "4",
                        name: format!("HIL cycle round trip, {}, {}", c.label(), load.as_str()),
                        ns: f.round_trip_ns,
                    });
                    if c.release == ReleaseTimer::default() {
                        hil.push((c.wait, *load, f));
                    }
                }
            }
            if round == 1 {
                paced_transport.push(t);
            }
        }
    }
    let repeated = (!runs.is_empty()).then(|| {
        let default = Contender { wait: WaitMode::default_for(a.rt), release: ReleaseTimer::default() };
        Repeated::new(rounds, a.cycles, HIL_DEADLINE_NS, default, runs, bare)
    });
    let mut ratios = Vec::new();
    if parts_1_2 {
        ratios.push(("unix socket / iceoryx2 busy-poll".to_string(), ratio(uds_p50, iox_p50)));
        ratios.push(("iceoryx2 events / iceoryx2 busy-poll".to_string(), ratio(iox_ev_p50, iox_p50)));
    }
    #[cfg(feature = "ros2")]
    if !a.hil_only {
        ratios.push(("dds / unix socket".to_string(), ratio(dds_p50, uds_p50)));
    }
    #[cfg(feature = "zenoh")]
    if !a.hil_only {
        ratios.push(("zenoh / unix socket (aim: at most 2)".to_string(), ratio(zenoh_p50, uds_p50)));
        ratios.push((
            "zenoh quic+mtls / zenoh tcp (aim: at most 1.3)".to_string(),
            ratio(zenoh_tls_p50, zenoh_p50),
        ));
    }
    for (mode, _, f) in hil.iter().filter(|h| h.1 == Load::Idle && parts_1_2) {
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
        message_bytes: (crate::transport::wire::MEASUREMENT_SIZE, crate::transport::wire::COMMAND_SIZE),
        rt: a.rt,
        machine: Machine::now(),
        load_average_at_start: load_start,
        rows,
        hil,
        load_threads,
        ratios,
        second_clock,
        zenoh_hops,
        paced_transport,
        miss_account,
        repeated,
    };
    let path = a.out.join("latency-benchmark.json");
    let text = serde_json::to_string_pretty(&bench).map_err(LatencyError::Serialize)?;
    std::fs::write(&path, text + "\n").map_err(os(|| format!("writing {}", path.display())))?;
    let series: Vec<(&str, &LatencyHistogram)> =
        hists.iter().filter(|(n, _)| !n.contains("f32")).map(|(n, h)| (n.as_str(), h)).collect();
    let svg = a.out.join("latency-benchmark.svg");
    if !series.is_empty() {
        if let Err(e) = crate::domain::plots::latency_svg(
            &svg,
            "companion latency: step, transports (HIL runs: see hil-*/)",
            &series,
            None,
        ) {
            observer.warn(&format!("plot: {}", Causes(&e)));
        }
    }
    if let Some(r) = &bench.repeated {
        let path = a.out.join(REPEAT_SVG);
        if let Err(e) = r.plot(&path) {
            observer.warn(&format!("plot: {}", Causes(&e)));
        }
    }
    if let Some(md) = bench.repeated_markdown() {
        let path = a.out.join(REPEAT_MD);
        std::fs::write(&path, &md).map_err(os(|| format!("writing {}", path.display())))?;
    }
    let path = a.out.join("index.html");
    std::fs::write(&path, bench.index_html()).map_err(os(|| format!("writing {}", path.display())))?;
    Ok(bench)
}

/// The hidden `latency-peer` subcommand: echoes until the end-of-run flag (or until the parent
/// is gone).
///
/// # Errors
/// A transport failure.
pub fn run_peer(a: &PeerOptions, observer: &dyn Observer) -> Result<(), LatencyError> {
    if let Some(cpu) = a.rt_cpu {
        if let Some(w) = rt::apply(&rt::RtConfig::with_cpu(Some(cpu))).warning("latency peer") {
            observer.warn(&w);
        }
    }
    match a.transport {
        Transport::IoxSpin | Transport::IoxEvent => {
            pingpong::peer_iox(&a.name, a.transport == Transport::IoxEvent)
        }
        Transport::Uds => {
            let dir = a
                .socket_dir
                .as_ref()
                .ok_or(LatencyError::MissingFlag("--socket-dir is required with uds"))?;
            pingpong::peer_uds(dir)
        }
        #[cfg(feature = "zenoh")]
        Transport::Zenoh => {
            let ep = a
                .endpoint
                .as_deref()
                .ok_or(LatencyError::MissingFlag("--endpoint is required with zenoh"))?;
            let variant = zenoh::Variant {
                tuning: crate::transport::zenoh_link::Tuning { low_latency: a.zenoh_low_latency },
                handoff: if a.zenoh_spin { zenoh::Handoff::Spin } else { zenoh::Handoff::Park },
            };
            zenoh::peer(&a.name, ep, a.tls_dir.as_deref(), variant)
        }
        #[cfg(not(feature = "zenoh"))]
        Transport::Zenoh => Err(LatencyError::NoZenoh),
        #[cfg(feature = "ros2")]
        Transport::Dds => dds::peer(&a.name, a.tls_dir.as_deref()),
        #[cfg(not(feature = "ros2"))]
        Transport::Dds => Err(LatencyError::NoDds),
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;
    use crate::run::hil::end::PlantEnd;
    use crate::run::hil::report::LatencyReport;
    use crate::run::hil::stats::PlantStats;
    use crate::run::hil::{HilConfig, Timing};

    fn report_json() -> serde_json::Value {
        let s = Scenario::paper(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle);
        let timing = Timing {
            period_ns: 1_000_000,
            deadline_ns: 500_000,
            hold_periods: 20,
            wait: WaitMode::Spin,
            release: crate::run::hil::config::ReleaseTimer::Sleep,
            spin_margin_ns: 0,
            silence_ns: 1,
            peer_timeout_ns: 1,
            lockstep: false,
            max_command_age: 0,
        };
        let cfg = HilConfig {
            name: crate::sys::lock::DemoName::new("t").unwrap(),
            out: PathBuf::new(),
            timing,
            startup_timeout: Duration::from_secs(1),
            rt: None,
            no_plots: true,
            acceptance: crate::domain::record::Acceptance::default(),
            chaos: None,
            transport: crate::transport::Transport::Iceoryx2,
            mcap: None,
        };
        let mut st = PlantStats { cycles: 7, deadline_misses: 2, ..PlantStats::default() };
        st.round_trip.record(5_000);
        let r = LatencyReport::new(&s, &cfg, &st, None, &PlantEnd::Completed, 1.0);
        serde_json::to_value(&r).unwrap()
    }

    #[test]
    fn the_benchmark_reads_back_what_the_plant_writes() {
        let f: HilFigures = serde_json::from_value(report_json()).unwrap();
        assert_eq!((f.cycles, f.deadline_misses, f.round_trip_ns.count), (7, 2, 1));
        assert!(!f.rt.fifo);
    }

    #[test]
    fn the_loop_is_accounted_against_the_bare_transport_under_its_load() {
        let mut f: HilFigures = serde_json::from_value(report_json()).unwrap();
        assert_eq!(f.deadline_ns, HIL_DEADLINE_NS);
        f.deadline_misses = 12;
        f.round_trip_ns.p50 = 30_000;
        let mut h = LatencyHistogram::new();
        for ns in [8_000, 9_000, 10_000, 499_000, 501_000, 2_000_000] {
            h.record(ns);
        }
        assert_eq!(h.count_above(HIL_DEADLINE_NS), 2);
        let t = PacedTransport {
            load: Load::Busy,
            round_trip_ns: h.percentiles(),
            over_deadline: h.count_above(HIL_DEADLINE_NS),
            deadline_ns: HIL_DEADLINE_NS,
        };
        let m = MissAccount::new(WaitMode::Adaptive, Load::Busy, &f, &t);
        assert_eq!((m.loop_misses, m.transport_misses, m.beyond_transport), (12, 2, 10));
        assert_eq!(m.ratio, Some(6.0));
        // The median of 8, 9, 10, 499, 501, 2000 µs is the third value's bucket.
        assert!((m.p50_ratio - 3.0).abs() < 0.01, "{}", m.p50_ratio);
        // A transport that missed none: the ratio is 1 if the loop missed none, else unbounded.
        let none = PacedTransport { over_deadline: 0, ..t };
        assert_eq!(MissAccount::new(WaitMode::Spin, Load::Idle, &f, &none).ratio, None);
        f.deadline_misses = 0;
        let m = MissAccount::new(WaitMode::Spin, Load::Idle, &f, &none);
        assert_eq!((m.beyond_transport, m.ratio), (0, Some(1.0)));
    }

    #[test]
    fn a_missing_key_in_latency_json_is_an_error_not_a_zero() {
        let mut v = report_json();
        v.as_object_mut().unwrap().remove("deadline_misses");
        let e = serde_json::from_value::<HilFigures>(v).unwrap_err();
        assert!(e.to_string().contains("deadline_misses"), "{e}");
        let mut v = report_json();
        v["round_trip_ns"].as_object_mut().unwrap().remove("p99.99");
        assert!(serde_json::from_value::<HilFigures>(v).is_err());
    }
}
