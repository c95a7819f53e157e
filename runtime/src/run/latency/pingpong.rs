//! Bare ping-pong between two processes with the HIL's message sizes: the transport's floor.
//!
//! The parent sends a [`MeasurementMsg`] (344 bytes) and waits for the [`CommandMsg`] (248
//! bytes) the peer — a hidden `latency-peer` subcommand of the same binary — sends back at
//! once; the round trip is timed on the parent's clock. Three transports:
//!
//! - iceoryx2 publish–subscribe, both sides busy-polling `receive()` (`iox-spin`);
//! - the same with the event service: `notify` after each send, `timed_wait` before each
//!   receive (`iox-event`);
//! - a Unix-domain datagram socket with blocking `recv` (`uds`), the messages encoded with
//!   [`MeasurementMsg::to_bytes`] and decoded on arrival: what a user would otherwise write.

use std::os::unix::net::UnixDatagram;
use std::path::{Path, PathBuf};
use std::process::{Command as Process, Stdio};
use std::time::Duration;

use companion_core::Command;
use serde::Serialize;

use super::error::{os, LatencyError};
use crate::domain::histogram::LatencyHistogram;
use crate::domain::observe::Observer;
use crate::sys::lock::DemoName;
use crate::sys::process::ChildGuard;
use crate::sys::rt;
use crate::transport::ipc::{ControlEndpoint, PlantEndpoint};
use crate::transport::link::PeerState;
use crate::transport::wire::target::space;
use crate::transport::wire::{
    flags, platform, CommandHeader, CommandMsg, ControllerIdentity, LoggedDiagnostics, MeasurementHeader,
    MeasurementMsg, COMMAND_SIZE, MEASUREMENT_SIZE,
};

/// A ping-pong transport.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    /// iceoryx2, both sides busy-poll.
    IoxSpin,
    /// iceoryx2 with the event service (`timed_wait`).
    IoxEvent,
    /// Unix-domain datagram socket, blocking.
    Uds,
    /// Zenoh over loopback TCP, both sides sleeping until the message arrives (a build with
    /// the `zenoh` feature).
    Zenoh,
    /// DDS (RustDDS) over loopback UDP, both sides sleeping in a poll (a build with the `ros2`
    /// feature).
    Dds,
}

impl Transport {
    /// The command-line spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::IoxSpin => "iox-spin",
            Self::IoxEvent => "iox-event",
            Self::Uds => "uds",
            Self::Zenoh => "zenoh",
            Self::Dds => "dds",
        }
    }
}

/// What the hidden `latency-peer` subcommand (the echoing side) does.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PeerOptions {
    /// The transport.
    pub transport: Transport,
    /// The iceoryx2 demo name.
    pub name: DemoName,
    /// The folder of the sockets (uds).
    pub socket_dir: Option<PathBuf>,
    /// The endpoint to connect to (zenoh).
    pub endpoint: Option<String>,
    /// The TLS material of a `tls/` endpoint (zenoh; `ca.pem`, `control.pem`, `control.key`).
    pub tls_dir: Option<PathBuf>,
    /// Real-time setup, pinned to this CPU.
    pub rt_cpu: Option<usize>,
    /// Zenoh's low-latency transport (zenoh).
    pub zenoh_low_latency: bool,
    /// Spin on the ring instead of sleeping until woken (zenoh).
    pub zenoh_spin: bool,
}

pub(super) fn echo(m: &MeasurementMsg, received_ns: u64) -> CommandMsg {
    let diag = LoggedDiagnostics::IDLE;
    let identity = ControllerIdentity {
        platform: platform::UNICYCLE,
        joint_count: 3,
        space: space::PLANAR,
        arm_hash: 0,
        scenario_hash: 0,
        max_dt: 1.0,
    };
    let header = CommandHeader { identity, flags: 0, received_ns, skipped: 0, delay: 0.0 };
    CommandMsg::answer::<3>(m, &header, &Command::zero(), None, &diag)
}

pub(super) fn ping(seq: u64, last: bool) -> MeasurementMsg {
    let m = companion_core::Measurement::<f64, 3> {
        t: 0.0,
        base: companion_core::Pose::new(0.0, 0.0, 0.0),
        steering: 0.0,
        joints: companion_core::nalgebra::SVector::<f64, 3>::new(0.0, 0.35, 0.0),
        target: companion_core::Pose::new(2.6, 1.0, 0.0),
        target_velocity: companion_core::nalgebra::Vector3::zeros(),
    };
    let header = MeasurementHeader {
        seq,
        flags: if last { flags::END_OF_RUN } else { 0 },
        session: 1,
        plant_time_ns: rt::monotonic_ns(),
        dt: 1e-3,
        platform: platform::UNICYCLE,
        ..MeasurementHeader::default()
    };
    MeasurementMsg::new(header, &m)
}

pub(super) fn peer_iox(name: &DemoName, events: bool) -> Result<(), LatencyError> {
    let mut ep = ControlEndpoint::control(name, events)?;
    ep.wait_for_peer(Duration::from_secs(10), || None)?;
    let mut silent_since = rt::monotonic_ns();
    loop {
        if let Some(m) = ep.try_receive()? {
            let t = rt::monotonic_ns();
            ep.send(&echo(&m, t))?;
            silent_since = t;
            if m.has(flags::END_OF_RUN) {
                return Ok(());
            }
            continue;
        }
        if events {
            ep.wait_event(Duration::from_millis(100))?;
        } else {
            core::hint::spin_loop();
        }
        let now = rt::monotonic_ns();
        if now - silent_since > 2_000_000_000 {
            if matches!(ep.peer_state()?, PeerState::Dead(_) | PeerState::Expired(_) | PeerState::Absent) {
                return Err(LatencyError::BenchmarkGone);
            }
            silent_since = now;
        }
    }
}

pub(super) fn peer_uds(dir: &Path) -> Result<(), LatencyError> {
    let me = dir.join("peer.sock");
    let sock = UnixDatagram::bind(&me).map_err(os(|| format!("binding {}", me.display())))?;
    sock.connect(dir.join("bench.sock")).map_err(os(|| "connecting to the benchmark's socket".into()))?;
    sock.set_read_timeout(Some(Duration::from_secs(5)))?;
    sock.send(b"hello")?;
    let mut buf = [0u8; MEASUREMENT_SIZE];
    loop {
        let n = sock.recv(&mut buf).map_err(os(|| "peer recv".into()))?;
        if n != MEASUREMENT_SIZE {
            return Err(LatencyError::PeerReceived(n));
        }
        let m = MeasurementMsg::from_bytes(&buf);
        let reply = echo(&m, rt::monotonic_ns()).to_bytes();
        sock.send(&reply).map_err(os(|| "peer send".into()))?;
        if m.has(flags::END_OF_RUN) {
            return Ok(());
        }
    }
}

pub(super) fn spawn_peer(exe: &Path, args: &[String]) -> Result<ChildGuard, LatencyError> {
    spawn_peer_in(None, exe, args)
}

/// [`spawn_peer`] in network namespace `netns` (`ip netns exec`, which execs the program: the
/// child is the peer itself).
pub(super) fn spawn_peer_in(
    netns: Option<&str>,
    exe: &Path,
    args: &[String],
) -> Result<ChildGuard, LatencyError> {
    let mut cmd = match netns {
        Some(ns) => {
            let mut c = Process::new("ip");
            c.args(["netns", "exec", ns]).arg(exe);
            c
        }
        None => Process::new(exe),
    };
    let child = cmd
        .arg("latency-peer")
        .args(args)
        .stdin(Stdio::null())
        .spawn()
        .map_err(os(|| format!("starting {} latency-peer", exe.display())))?;
    Ok(ChildGuard::new(child))
}

/// Where each process runs with `--rt` on this machine: `(benchmark, peer)`. On a single CPU
/// both share it (and busy-polling ping-pong then measures the scheduler, not the transport).
pub fn rt_cpus() -> (usize, usize) {
    if rt::online_cpus() >= 2 {
        (1, 0)
    } else {
        (0, 0)
    }
}

/// Round trips over iceoryx2 (`events`: with the event service), `warmup` unrecorded first;
/// back to back, or one every `pace_ns` (busy-waiting in between, as the HIL plant does).
///
/// # Errors
/// The peer could not be started or stopped answering.
pub fn iceoryx(
    exe: &Path,
    iterations: u64,
    warmup: u64,
    events: bool,
    use_rt: bool,
    pace_ns: Option<u64>,
    observer: &dyn Observer,
) -> Result<(LatencyHistogram, SecondClock), LatencyError> {
    let name = DemoName::new(&format!(
        "latency-{}-{}{}",
        std::process::id(),
        if events { "event" } else { "spin" },
        if pace_ns.is_some() { "-paced" } else { "" }
    ))?;
    let (own_cpu, peer_cpu) = rt_cpus();
    let mut args = vec![
        "--transport".to_string(),
        if events { Transport::IoxEvent } else { Transport::IoxSpin }.as_str().to_string(),
        "--name".to_string(),
        name.to_string(),
    ];
    if use_rt {
        args.extend(["--rt-cpu".to_string(), peer_cpu.to_string()]);
    }
    let mut child = spawn_peer(exe, &args)?;
    let mut ep = PlantEndpoint::plant(&name, events)?;
    ep.wait_for_peer(Duration::from_secs(10), || None)?;
    let _rt = use_rt.then(|| RtScope::enter(own_cpu, observer));
    let mut samples = Samples::new(warmup);
    let total = warmup + iterations;
    let start = rt::monotonic_ns();
    for i in 0..total {
        if let Some(p) = pace_ns {
            let next = start + i * p;
            while rt::monotonic_ns() < next {
                core::hint::spin_loop();
            }
        }
        samples.begin(i);
        let msg = ping(i, i + 1 == total);
        let t0 = msg.plant_time_ns;
        ep.send(&msg)?;
        let mut spins = 0u32;
        loop {
            if let Some(c) = ep.try_receive()? {
                if c.seq == i {
                    break;
                }
                continue;
            }
            if events {
                ep.wait_event(Duration::from_millis(100))?;
            } else {
                core::hint::spin_loop();
            }
            spins = spins.wrapping_add(1);
            if spins % 4096 == 0 && rt::monotonic_ns() - t0 > 5_000_000_000 {
                return Err(LatencyError::PeerStopped { transport: "iceoryx2", iteration: i });
            }
        }
        samples.record(i, rt::monotonic_ns() - t0);
    }
    drop(_rt);
    child.finish(Duration::from_secs(5))?;
    Ok(samples.finish())
}

/// Round trips over a Unix-domain datagram socket (blocking receive on both sides).
///
/// # Errors
/// The sockets or the peer failed.
pub fn unix_socket(
    exe: &Path,
    iterations: u64,
    warmup: u64,
    use_rt: bool,
    observer: &dyn Observer,
) -> Result<(LatencyHistogram, SecondClock), LatencyError> {
    let dir = std::env::temp_dir().join(format!("companion-latency-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir)?;
    let result = unix_socket_in(exe, &dir, iterations, warmup, use_rt, observer);
    let _ = std::fs::remove_dir_all(&dir);
    result
}

fn unix_socket_in(
    exe: &Path,
    dir: &Path,
    iterations: u64,
    warmup: u64,
    use_rt: bool,
    observer: &dyn Observer,
) -> Result<(LatencyHistogram, SecondClock), LatencyError> {
    let sock =
        UnixDatagram::bind(dir.join("bench.sock")).map_err(os(|| "binding the benchmark's socket".into()))?;
    sock.set_read_timeout(Some(Duration::from_secs(10)))?;
    let (own_cpu, peer_cpu) = rt_cpus();
    let mut args = vec![
        "--transport".to_string(),
        "uds".to_string(),
        "--socket-dir".to_string(),
        dir.display().to_string(),
    ];
    if use_rt {
        args.extend(["--rt-cpu".to_string(), peer_cpu.to_string()]);
    }
    let mut child = spawn_peer(exe, &args)?;
    let mut buf = [0u8; COMMAND_SIZE];
    let n = sock.recv(&mut buf).map_err(os(|| "waiting for the socket peer".into()))?;
    if &buf[..n] != b"hello" {
        return Err(LatencyError::Greeting);
    }
    sock.connect(dir.join("peer.sock"))?;
    let _rt = use_rt.then(|| RtScope::enter(own_cpu, observer));
    let mut samples = Samples::new(warmup);
    let total = warmup + iterations;
    for i in 0..total {
        samples.begin(i);
        let msg = ping(i, i + 1 == total);
        let t0 = msg.plant_time_ns;
        sock.send(&msg.to_bytes())?;
        loop {
            let n = sock.recv(&mut buf).map_err(os(|| "socket ping-pong".into()))?;
            if n != COMMAND_SIZE {
                return Err(LatencyError::Received(n));
            }
            if CommandMsg::from_bytes(&buf).seq == i {
                break;
            }
        }
        samples.record(i, rt::monotonic_ns() - t0);
    }
    drop(_rt);
    child.finish(Duration::from_secs(5))?;
    Ok(samples.finish())
}

/// The round trips of one measurement, with a second clock on them: each sample is timed by
/// `CLOCK_MONOTONIC` (the message's own timestamp to its answer's arrival), and the whole batch
/// of recorded back-to-back round trips by `CLOCK_MONOTONIC_RAW`, read apart from the
/// samples. Back to back, the samples fill the batch but for the loop's own work between two
/// round trips, so their sum is a little below the batch's length; a sample lost, counted
/// twice or in the wrong unit would show.
#[derive(Debug)]
pub struct Samples {
    hist: LatencyHistogram,
    warmup: u64,
    check: SecondClock,
    raw_start: u64,
}

/// A measurement's samples against the second clock.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SecondClock {
    /// The sum of the recorded samples (`CLOCK_MONOTONIC`, ns).
    pub samples_sum_ns: u64,
    /// The recorded batch's length (`CLOCK_MONOTONIC_RAW`, ns).
    pub batch_raw_ns: u64,
    /// The samples recorded.
    pub samples: u64,
}

impl SecondClock {
    /// The samples' share of the batch (0 for an empty batch).
    pub fn share(&self) -> f64 {
        if self.batch_raw_ns == 0 {
            0.0
        } else {
            self.samples_sum_ns as f64 / self.batch_raw_ns as f64
        }
    }

    /// Whether the two clocks agree: the samples fill between half the batch and the whole of
    /// it (plus the two clocks' rates' difference, well under 0.1 %).
    pub fn agrees(&self) -> bool {
        self.samples > 0 && (0.5..=1.001).contains(&self.share())
    }
}

impl Samples {
    /// Samples after `warmup` unrecorded iterations.
    pub fn new(warmup: u64) -> Self {
        Self { hist: LatencyHistogram::new(), warmup, check: SecondClock::default(), raw_start: 0 }
    }

    /// Iteration `i` begins (before its message is stamped).
    #[inline]
    pub fn begin(&mut self, i: u64) {
        if i == self.warmup {
            self.raw_start = rt::raw_ns();
        }
    }

    /// Iteration `i`'s round trip took `ns` (recorded after the warm-up).
    #[inline]
    pub fn record(&mut self, i: u64, ns: u64) {
        if i >= self.warmup {
            self.hist.record(ns);
            self.check.samples_sum_ns += ns;
            self.check.samples += 1;
            self.check.batch_raw_ns = rt::raw_ns() - self.raw_start;
        }
    }

    /// The histogram and the second clock's check.
    pub fn finish(self) -> (LatencyHistogram, SecondClock) {
        (self.hist, self.check)
    }
}

/// Real-time setup of the calling thread for a scope; back to the normal scheduler and all
/// CPUs at the end (so that processes and threads started later do not inherit the pinning).
#[derive(Debug)]
pub struct RtScope;

impl RtScope {
    /// Applies `--rt` pinned to `cpu` (warnings to `observer`).
    pub fn enter(cpu: usize, observer: &dyn Observer) -> Self {
        if let Some(w) = rt::apply(&rt::RtConfig::with_cpu(Some(cpu))).warning("latency") {
            observer.warn(&w);
        }
        Self
    }
}

impl Drop for RtScope {
    fn drop(&mut self) {
        rt::reset_thread();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples that fill the batch agree; a batch the samples cannot fill, or samples longer
    /// than the batch (a unit error, a sample counted twice), do not.
    #[test]
    fn the_second_clock_checks_the_samples() {
        let mut s = Samples::new(2);
        for i in 0..12 {
            s.begin(i);
            let t0 = rt::monotonic_ns();
            while rt::monotonic_ns() - t0 < 200_000 {
                core::hint::spin_loop();
            }
            s.record(i, rt::monotonic_ns() - t0);
        }
        let (h, c) = s.finish();
        assert_eq!((h.count(), c.samples), (10, 10));
        assert!(c.agrees(), "{c:?}: {:.3}", c.share());
        assert!(c.share() > 0.9, "back to back the samples fill the batch: {:.3}", c.share());
        let doubled = SecondClock { samples_sum_ns: 2 * c.samples_sum_ns, ..c };
        assert!(!doubled.agrees());
        let sparse = SecondClock { samples_sum_ns: c.batch_raw_ns / 4, ..c };
        assert!(!sparse.agrees());
        assert!(!SecondClock::default().agrees(), "no samples: nothing agrees");
    }
}
