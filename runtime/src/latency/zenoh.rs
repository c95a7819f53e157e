//! Zenoh ping-pong (cargo feature `zenoh`): the same messages as the other transports
//! between two processes over a Zenoh TCP session on loopback, both sides sleeping until the
//! message arrives ([`crate::zenoh_link`]'s wait) — the transport of two-machine HIL runs,
//! measured next to iceoryx2 and the Unix socket.

use std::path::Path;
use std::time::Duration;

use anyhow::{bail, Result};

use super::pingpong::{echo, ping, rt_cpus, spawn_peer, RtScope, Transport};
use crate::histogram::LatencyHistogram;
use crate::ipc::Role;
use crate::link::PeerState;
use crate::observe::Observer;
use crate::rt;
use crate::wire::flags;
use crate::zenoh_link::{TcpEndpoint, ZenohControl, ZenohLink, ZenohPlant};

/// The echoing side: connects to `endpoint`, answers until the end-of-run flag.
///
/// # Errors
/// A bad endpoint, a Zenoh failure, or the benchmark gone.
pub fn peer(name: &str, endpoint: &str) -> Result<()> {
    let mut ep = ZenohControl::open(name, Role::Control, ZenohLink::Connect(TcpEndpoint::parse(endpoint)?))?;
    ep.wait_for_peer(Duration::from_secs(10), || None)?;
    let mut silent_since = rt::monotonic_ns();
    loop {
        if let Some(m) = ep.try_receive() {
            let t = rt::monotonic_ns();
            ep.send(&echo(&m, t))?;
            silent_since = t;
            if m.has(flags::END_OF_RUN) {
                ep.linger(Duration::from_secs(1));
                return Ok(());
            }
            continue;
        }
        ep.wait_event(Duration::from_millis(100));
        let now = rt::monotonic_ns();
        if now - silent_since > 2_000_000_000 {
            if matches!(ep.peer_state(), PeerState::Dead(_) | PeerState::Absent) {
                bail!("the benchmark process is gone");
            }
            silent_since = now;
        }
    }
}

/// Round trips over Zenoh on loopback TCP, `warmup` unrecorded first; both sides sleep until
/// the message arrives.
///
/// # Errors
/// The peer could not be started or stopped answering.
pub fn round_trips(
    exe: &Path,
    iterations: u64,
    warmup: u64,
    use_rt: bool,
    observer: &dyn Observer,
) -> Result<LatencyHistogram> {
    let endpoint = crate::transport::free_local_endpoint()?;
    let name = format!("latency-{}-zenoh", std::process::id());
    let mut ep = ZenohPlant::open(&name, Role::Plant, ZenohLink::Listen(TcpEndpoint::parse(&endpoint)?))?;
    let (own_cpu, peer_cpu) = rt_cpus();
    let mut args = vec![
        "--transport".to_string(),
        Transport::Zenoh.as_str().to_string(),
        "--name".to_string(),
        name,
        "--endpoint".to_string(),
        endpoint,
    ];
    if use_rt {
        args.extend(["--rt-cpu".to_string(), peer_cpu.to_string()]);
    }
    let mut child = spawn_peer(exe, &args)?;
    ep.wait_for_peer(Duration::from_secs(10), || None)?;
    let _rt = use_rt.then(|| RtScope::enter(own_cpu, observer));
    let mut hist = LatencyHistogram::new();
    let total = warmup + iterations;
    for i in 0..total {
        let msg = ping(i, i + 1 == total);
        let t0 = msg.plant_time_ns;
        ep.send(&msg)?;
        loop {
            if let Some(c) = ep.try_receive() {
                if c.seq == i {
                    break;
                }
                continue;
            }
            ep.wait_event(Duration::from_millis(100));
            if rt::monotonic_ns() - t0 > 5_000_000_000 {
                bail!("the Zenoh ping-pong peer stopped answering at iteration {i}");
            }
        }
        let t1 = rt::monotonic_ns();
        if i >= warmup {
            hist.record(t1 - t0);
        }
    }
    drop(_rt);
    child.finish(Duration::from_secs(5))?;
    Ok(hist)
}
