//! Zenoh ping-pong (cargo feature `zenoh`): the same messages as the other transports
//! between two processes over a Zenoh session on loopback, over plain TCP and over mutual TLS
//! (the default across machines; [`Tls`]), with the session set-up's time too
//! ([`session_setup`]), both sides sleeping until the
//! message arrives ([`crate::transport::zenoh_link`]'s wait) — the transport of two-machine HIL runs,
//! measured next to iceoryx2 and the Unix socket — and, where network namespaces are
//! permitted (root), the same across a veth pair into a namespace of its own ([`Veth`]): the
//! path of two machines without the wire.

use std::path::{Path, PathBuf};
use std::time::Duration;

use super::error::LatencyError;
use super::hops::{HopRecorder, HopReport, Stamps};
use super::pingpong::{echo, ping, rt_cpus, spawn_peer_in, RtScope, Samples, SecondClock, Transport};
use crate::domain::histogram::LatencyHistogram;
use crate::domain::observe::Observer;
use crate::sys::lock::{DemoName, Role};
use crate::sys::rt;
use crate::transport::link::PeerState;
use crate::transport::wire::flags;
use crate::transport::zenoh_link::{
    Security, TcpEndpoint, TlsFiles, Tuning, ZenohControl, ZenohLink, ZenohPlant,
};

/// How each side's loop thread waits for the next message.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Handoff {
    /// Sleeps (`thread::park`) until Zenoh's callback wakes it: the HIL's way over Zenoh.
    #[default]
    Park,
    /// Spins on the ring (never sleeps): no wake-up, a CPU taken.
    Spin,
}

/// One configuration of the Zenoh ping-pong.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Variant {
    /// Zenoh's settings.
    pub tuning: Tuning,
    /// How the loops wait.
    pub handoff: Handoff,
}

impl Variant {
    /// The configurations `companion latency` measures over loopback TCP, the default first.
    pub const ALL: [Self; 4] = [
        Self { tuning: Tuning { low_latency: false }, handoff: Handoff::Park },
        Self { tuning: Tuning { low_latency: true }, handoff: Handoff::Park },
        Self { tuning: Tuning { low_latency: false }, handoff: Handoff::Spin },
        Self { tuning: Tuning { low_latency: true }, handoff: Handoff::Spin },
    ];

    /// `default` or the settings changed, e.g. `low-latency, spin`.
    pub fn label(self) -> String {
        let mut parts = Vec::new();
        if self.tuning.low_latency {
            parts.push("low-latency");
        }
        if self.handoff == Handoff::Spin {
            parts.push("spin");
        }
        if parts.is_empty() {
            "default".into()
        } else {
            parts.join(", ")
        }
    }

    /// The peer's flags for it.
    fn args(self) -> Vec<String> {
        let mut a = Vec::new();
        if self.tuning.low_latency {
            a.push("--zenoh-low-latency".to_string());
        }
        if self.handoff == Handoff::Spin {
            a.push("--zenoh-spin".to_string());
        }
        a
    }
}

// The echo's stamps for the benchmark's hop account ([`super::hops`]) travel in fields of the
// command that the ping-pong does not otherwise use: `received_ns` = the peer's callback,
// `compute_ns` = its loop awake, `scenario_hash` = its `put` call, `arm_hash` = the previous
// echo's `put` duration (all `CLOCK_MONOTONIC` ns).

/// Waits for the next message as `handoff` says: parked up to 100 ms, or one spin.
#[inline]
fn wait<Tx, Rx>(ep: &crate::transport::zenoh_link::ZenohEndpoint<Tx, Rx>, handoff: Handoff)
where
    Tx: zerocopy::IntoBytes + zerocopy::Immutable,
    Rx: zerocopy::FromBytes + Send + 'static,
{
    match handoff {
        Handoff::Park => ep.wait_event(Duration::from_millis(100)),
        Handoff::Spin => core::hint::spin_loop(),
    }
}

/// The benchmark's sessions' peer timeout (the HIL's default): over QUIC it sets the lease
/// ([`crate::transport::zenoh_link::quic_lease`]).
const BENCH_PEER_TIMEOUT: Duration = Duration::from_secs(2);

/// A throwaway CA and certificates for the benchmark's TLS runs (hosts `plant`, valid for
/// 127.0.0.1, and `control`), in an owner-only folder removed when dropped.
#[derive(Debug)]
pub struct Tls {
    dir: PathBuf,
}

impl Tls {
    /// Makes them.
    ///
    /// # Errors
    /// The folder or the certificates cannot be made.
    pub fn make() -> Result<Self, LatencyError> {
        let dir = std::env::temp_dir().join(format!("companion-latency-tls-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let hosts = crate::transport::certs::Host::parse_list("plant=127.0.0.1,control")?;
        crate::transport::certs::make(&dir, &hosts, crate::transport::certs::Validity::days(1))?;
        Ok(Self { dir })
    }

    /// The folder (handed to the peer process).
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

impl Drop for Tls {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// `role`'s security with the material in `dir` (`None`: plain TCP).
fn security(dir: Option<&Path>, role: Role) -> Security {
    let Some(dir) = dir else { return Security::Insecure };
    let (own, peer) = match role {
        Role::Plant => ("plant", "control"),
        Role::Control => ("control", "plant"),
    };
    Security::Tls(TlsFiles {
        ca: dir.join("ca.pem"),
        cert: dir.join(format!("{own}.pem")),
        key: dir.join(format!("{own}.key")),
        peer_names: vec![peer.to_string()],
    })
}

/// The echoing side: connects to `endpoint` (over TLS with the material in `tls`), answers
/// until the end-of-run flag.
///
/// # Errors
/// A bad endpoint, a Zenoh failure, or the benchmark gone.
pub fn peer(
    name: &DemoName,
    endpoint: &str,
    tls: Option<&Path>,
    variant: Variant,
) -> Result<(), LatencyError> {
    let link = ZenohLink::Connect(TcpEndpoint::parse(endpoint)?);
    let mut ep = ZenohControl::open_tuned(
        name,
        Role::Control,
        link,
        &security(tls, Role::Control),
        BENCH_PEER_TIMEOUT,
        variant.tuning,
    )?;
    ep.wait_for_peer(Duration::from_secs(10), || None)?;
    let mut silent_since = rt::monotonic_ns();
    let mut previous_put = 0;
    let mut spins = 0u32;
    loop {
        if let Some((m, arrived)) = ep.try_receive_stamped() {
            let t = rt::monotonic_ns();
            let mut c = echo(&m, arrived);
            c.compute_ns = t;
            c.arm_hash = previous_put;
            let call = rt::monotonic_ns();
            c.scenario_hash = call;
            ep.send(&c)?;
            previous_put = rt::monotonic_ns() - call;
            silent_since = t;
            if m.has(flags::END_OF_RUN) {
                ep.linger(Duration::from_secs(1));
                return Ok(());
            }
            continue;
        }
        wait(&ep, variant.handoff);
        spins = spins.wrapping_add(1);
        if variant.handoff == Handoff::Spin && spins % 4096 != 0 {
            continue;
        }
        let now = rt::monotonic_ns();
        if now - silent_since > 2_000_000_000 {
            if matches!(ep.peer_state(), PeerState::Dead(_) | PeerState::Expired(_) | PeerState::Absent) {
                return Err(LatencyError::BenchmarkGone);
            }
            silent_since = now;
        }
    }
}

/// A network namespace of this process with a veth pair to the machine's own: this side
/// `10.254.X.1/30`, the namespace's `10.254.X.2/30`. Deleting the namespace (on drop) removes
/// the pair.
#[derive(Debug)]
pub struct Veth {
    /// The namespace's name.
    pub netns: String,
    /// This side's address.
    pub here: String,
}

fn ip(args: &[&str]) -> Result<(), LatencyError> {
    let o = std::process::Command::new("ip")
        .args(args)
        .output()
        .map_err(|e| LatencyError::Ip { args: args.join(" "), cause: e.to_string() })?;
    if !o.status.success() {
        let cause = String::from_utf8_lossy(&o.stderr).trim().to_string();
        return Err(LatencyError::Ip { args: args.join(" "), cause });
    }
    Ok(())
}

impl Veth {
    /// Creates it.
    ///
    /// # Errors
    /// `ip` is missing or namespaces are not permitted (not root): the reason.
    pub fn create() -> Result<Self, LatencyError> {
        let pid = std::process::id();
        let netns = format!("companion-lat-{pid}");
        let (outer, inner) = (format!("clat{pid}a"), format!("clat{pid}b"));
        let x = pid % 64 * 4;
        let (here, there) =
            (format!("10.254.{}.{}", pid / 64 % 250, x + 1), format!("10.254.{}.{}", pid / 64 % 250, x + 2));
        ip(&["netns", "add", &netns])?;
        let v = Self { netns, here };
        ip(&["link", "add", &outer, "type", "veth", "peer", "name", &inner, "netns", &v.netns])?;
        ip(&["addr", "add", &format!("{}/30", v.here), "dev", &outer])?;
        ip(&["link", "set", &outer, "up"])?;
        ip(&["-n", &v.netns, "addr", "add", &format!("{there}/30"), "dev", &inner])?;
        ip(&["-n", &v.netns, "link", "set", &inner, "up"])?;
        ip(&["-n", &v.netns, "link", "set", "lo", "up"])?;
        Ok(v)
    }
}

impl Drop for Veth {
    fn drop(&mut self) {
        let _ = ip(&["netns", "del", &self.netns]);
    }
}

/// Round trips over Zenoh on TCP (over mutual TLS with `tls`), `warmup` unrecorded first,
/// in configuration `variant`, each split at its hops ([`super::hops`]). On loopback, or with
/// `veth` the peer in its namespace, connecting across the pair (plain TCP).
///
/// # Errors
/// The peer could not be started or stopped answering.
#[allow(clippy::too_many_arguments)]
pub fn round_trips(
    exe: &Path,
    iterations: u64,
    warmup: u64,
    use_rt: bool,
    veth: Option<&Veth>,
    tls: Option<&Tls>,
    variant: Variant,
    observer: &dyn Observer,
) -> Result<(LatencyHistogram, SecondClock, HopReport), LatencyError> {
    let tls_dir = tls.map(Tls::dir);
    let endpoint = match veth {
        None => crate::transport::free_local_endpoint(tls.is_none())?,
        Some(v) => {
            let l = std::net::TcpListener::bind((v.here.as_str(), 0))
                .map_err(|cause| LatencyError::FreePort { here: v.here.clone(), cause })?;
            format!("tcp/{}:{}", v.here, l.local_addr()?.port())
        }
    };
    let name = DemoName::new(&format!(
        "latency-{}-zenoh{}{}{}{}",
        std::process::id(),
        if veth.is_some() { "-netns" } else { "" },
        if tls.is_some() { "-tls" } else { "" },
        if variant.tuning.low_latency { "-ll" } else { "" },
        if variant.handoff == Handoff::Spin { "-spin" } else { "" },
    ))?;
    let config = format!(
        "{}, {}",
        match (tls.is_some(), veth.is_some()) {
            (true, _) => "quic+mtls loopback",
            (false, true) => "tcp across network namespaces",
            (false, false) => "tcp loopback",
        },
        variant.label()
    );
    let link = ZenohLink::Listen(TcpEndpoint::parse(&endpoint)?);
    let mut ep = ZenohPlant::open_tuned(
        &name,
        Role::Plant,
        link,
        &security(tls_dir, Role::Plant),
        BENCH_PEER_TIMEOUT,
        variant.tuning,
    )?;
    let (own_cpu, peer_cpu) = rt_cpus();
    let mut args = vec![
        "--transport".to_string(),
        Transport::Zenoh.as_str().to_string(),
        "--name".to_string(),
        name.to_string(),
        "--endpoint".to_string(),
        endpoint,
    ];
    if use_rt {
        args.extend(["--rt-cpu".to_string(), peer_cpu.to_string()]);
    }
    if let Some(d) = tls_dir {
        args.extend(["--tls-dir".to_string(), d.display().to_string()]);
    }
    args.extend(variant.args());
    let mut child = spawn_peer_in(veth.map(|v| v.netns.as_str()), exe, &args)?;
    ep.wait_for_peer(Duration::from_secs(10), || None)?;
    let _rt = use_rt.then(|| RtScope::enter(own_cpu, observer));
    let mut samples = Samples::new(warmup);
    let mut hops = HopRecorder::default();
    let total = warmup + iterations;
    for i in 0..total {
        samples.begin(i);
        let msg = ping(i, i + 1 == total);
        let t0 = msg.plant_time_ns;
        let put_call = rt::monotonic_ns();
        ep.send(&msg)?;
        let put_return = rt::monotonic_ns();
        let mut spins = 0u32;
        let (c, callback, awake) = loop {
            if let Some((c, arrived)) = ep.try_receive_stamped() {
                if c.seq == i {
                    break (c, arrived, rt::monotonic_ns());
                }
                continue;
            }
            wait(&ep, variant.handoff);
            spins = spins.wrapping_add(1);
            if (variant.handoff == Handoff::Park || spins % 4096 == 0)
                && rt::monotonic_ns() - t0 > 5_000_000_000
            {
                return Err(LatencyError::PeerStopped { transport: "Zenoh", iteration: i });
            }
        };
        samples.record(i, rt::monotonic_ns() - t0);
        let stamps = Stamps {
            put_call,
            put_return,
            peer_callback: c.received_ns,
            peer_awake: c.compute_ns,
            peer_put_call: c.scenario_hash,
            previous_peer_put_ns: c.arm_hash,
            callback,
            awake,
        };
        hops.record(&stamps, i >= warmup);
    }
    drop(_rt);
    child.finish(Duration::from_secs(5))?;
    let (hist, clock) = samples.finish();
    let report = hops.finish(config, &hist);
    Ok((hist, clock, report))
}

/// The time from opening a connecting session to seeing the listening peer and being heard
/// by it (TCP connect, the TLS handshake with `tls`, Zenoh's own session handshake, the
/// declarations both ways), `n` times in this process against one listening session.
///
/// # Errors
/// A session cannot be opened, or the peer is not seen within 10 s.
pub fn session_setup(n: u32, tls: Option<&Tls>) -> Result<LatencyHistogram, LatencyError> {
    let tls_dir = tls.map(Tls::dir);
    let endpoint = TcpEndpoint::parse(&crate::transport::free_local_endpoint(tls.is_none())?)?;
    let name = DemoName::new(&format!(
        "latency-{}-setup{}",
        std::process::id(),
        if tls.is_some() { "-tls" } else { "" }
    ))?;
    let plant = ZenohPlant::open(
        &name,
        Role::Plant,
        ZenohLink::Listen(endpoint.clone()),
        &security(tls_dir, Role::Plant),
        BENCH_PEER_TIMEOUT,
    )?;
    let mut h = LatencyHistogram::new();
    for _ in 0..n {
        let t0 = rt::monotonic_ns();
        let c = ZenohControl::open(
            &name,
            Role::Control,
            ZenohLink::Connect(endpoint.clone()),
            &security(tls_dir, Role::Control),
            BENCH_PEER_TIMEOUT,
        )?;
        // (Not `wait_for_peer`, which waits 50 ms more for rivals' tokens.)
        while !c.peer_connected() {
            if rt::monotonic_ns() - t0 > 10_000_000_000 {
                return Err(LatencyError::NoSession { endpoint: endpoint.to_string() });
            }
            std::thread::sleep(Duration::from_micros(100));
        }
        h.record(rt::monotonic_ns() - t0);
        drop(c);
    }
    drop(plant);
    Ok(h)
}
