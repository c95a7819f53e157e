//! The DDS round trip (a build with the `ros2` feature): the ping-pong of [`super::pingpong`]
//! with the same messages (the 344-byte measurement out, the 248-byte command back, each a CDR
//! array of octets) over RustDDS on loopback UDP, as `companion ros2` talks to a robot. Both
//! sides are ROS 2 nodes of ros2-client (reliable, keep last 10, volatile: ROS 2's default
//! profile) on topics `/companion_latency_<name>/ping` and `…/pong`, and both sleep in
//! `mio`'s poll until their subscription has a sample.

use std::path::Path;
use std::time::Duration;

use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher, QosProfile,
    Subscription,
};
use serde::de::{self, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::error::LatencyError;
use super::pingpong::{echo, ping, rt_cpus, spawn_peer, RtScope, Samples, SecondClock, Transport};
use crate::domain::histogram::LatencyHistogram;
use crate::domain::observe::Observer;
use crate::sys::lock::DemoName;
use crate::sys::rt;
use crate::transport::wire::{flags, CommandMsg, MeasurementMsg, COMMAND_SIZE, MEASUREMENT_SIZE};

/// `N` bytes as a CDR `octet[N]` (no length on the wire).
#[derive(Clone, Copy, Debug)]
struct Fixed<const N: usize>([u8; N]);

impl<const N: usize> Serialize for Fixed<N> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(N)?;
        for b in &self.0 {
            t.serialize_element(b)?;
        }
        t.end()
    }
}

impl<'de, const N: usize> Deserialize<'de> for Fixed<N> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<const N: usize>;
        impl<'de, const N: usize> Visitor<'de> for V<N> {
            type Value = Fixed<N>;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "{N} octets")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Fixed<N>, A::Error> {
                let mut b = [0u8; N];
                for (i, x) in b.iter_mut().enumerate() {
                    *x = seq.next_element()?.ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                Ok(Fixed(b))
            }
        }
        d.deserialize_tuple(N, V::<N>)
    }
}

type Ping = Fixed<MEASUREMENT_SIZE>;
type Pong = Fixed<COMMAND_SIZE>;

fn failed(what: &str, e: impl std::fmt::Debug) -> LatencyError {
    LatencyError::Dds(format!("{what}: {e:?}"))
}

/// One side: its node, what it sends and what it reads, and a poll on the reader.
struct Side<O: Serialize, I: 'static> {
    tx: Publisher<O>,
    rx: Subscription<I>,
    poll: Poll,
    events: Events,
    _node: Node,
    _context: Context,
}

impl<O: Serialize, I: 'static + serde::de::DeserializeOwned> Side<O, I> {
    fn open(name: &DemoName, role: &str, tx: &str, rx: &str) -> Result<Self, LatencyError> {
        let context =
            Context::with_options(ContextOptions::new()).map_err(|e| failed("joining DDS domain 0", e))?;
        let node_name = format!("companion_latency_{}", name.as_str().replace('-', "_"));
        let mut node = context
            .new_node(
                NodeName::new("/", &format!("{node_name}_{role}")).map_err(|e| failed("node name", e))?,
                NodeOptions::new().enable_rosout(false),
            )
            .map_err(|e| failed("creating the node", e))?;
        let qos = QosProfile::publisher_default()
            .durability(Durability::Volatile)
            .history(History::KeepLast { depth: 10 })
            .reliability_reliable(WhenFull::Wait(Duration::from_millis(100)));
        let topic = |t: &str, ty: &str| {
            let n = Name::new("/", &format!("{node_name}_{t}")).map_err(|e| failed("topic name", e))?;
            node.create_topic(&n, MessageTypeName::new("companion", ty), &qos).map_err(|e| failed("topic", e))
        };
        let (tx_topic, rx_topic) = (topic(tx, tx)?, topic(rx, rx)?);
        let tx = node.create_publisher::<O>(&tx_topic, None).map_err(|e| failed("publisher", e))?;
        let mut rx = node.create_subscription::<I>(&rx_topic, None).map_err(|e| failed("subscription", e))?;
        let poll = Poll::new().map_err(|e| failed("poll", e))?;
        poll.registry().register(&mut rx, Token(1), Interest::READABLE).map_err(|e| failed("poll", e))?;
        Ok(Self { tx, rx, poll, events: Events::with_capacity(8), _node: node, _context: context })
    }

    /// The next sample, sleeping in the poll for it up to `timeout`.
    fn next(&mut self, timeout: Duration) -> Result<Option<I>, LatencyError> {
        let until = rt::monotonic_ns() + timeout.as_nanos() as u64;
        loop {
            if let Some((m, _)) = self.rx.take().map_err(|e| failed("take", e))? {
                return Ok(Some(m));
            }
            let now = rt::monotonic_ns();
            if now >= until {
                return Ok(None);
            }
            let left = Duration::from_nanos((until - now).min(100_000_000));
            self.poll.poll(&mut self.events, Some(left)).map_err(|e| failed("poll", e))?;
        }
    }
}

/// Round trips over DDS (module docs), `warmup` unrecorded first, back to back.
///
/// # Errors
/// The peer could not be started, never answered, or stopped answering.
pub fn round_trips(
    exe: &Path,
    iterations: u64,
    warmup: u64,
    use_rt: bool,
    observer: &dyn Observer,
) -> Result<(LatencyHistogram, SecondClock), LatencyError> {
    let name = DemoName::new(&format!("latency-{}-dds", std::process::id()))?;
    let (own_cpu, peer_cpu) = rt_cpus();
    let mut args =
        vec!["--transport".into(), Transport::Dds.as_str().into(), "--name".into(), name.to_string()];
    if use_rt {
        args.extend(["--rt-cpu".to_string(), peer_cpu.to_string()]);
    }
    let mut side = Side::<Ping, Pong>::open(&name, "bench", "ping", "pong")?;
    let mut child = spawn_peer(exe, &args)?;
    // Discovery: ping with sequence number u64::MAX until the peer answers one.
    let start = rt::monotonic_ns();
    'matched: loop {
        let hello = ping(u64::MAX, false);
        side.tx.publish(Fixed(hello.to_bytes())).map_err(|e| failed("publish", e))?;
        while let Some(p) = side.next(Duration::from_millis(50))? {
            if CommandMsg::from_bytes(&p.0).seq == u64::MAX {
                break 'matched;
            }
        }
        if rt::monotonic_ns() - start > 20_000_000_000 {
            return Err(LatencyError::PeerStopped { transport: "dds", iteration: 0 });
        }
    }
    let _rt = use_rt.then(|| RtScope::enter(own_cpu, observer));
    let mut samples = Samples::new(warmup);
    let total = warmup + iterations;
    for i in 0..total {
        samples.begin(i);
        let msg = ping(i, i + 1 == total);
        let t0 = msg.plant_time_ns;
        side.tx.publish(Fixed(msg.to_bytes())).map_err(|e| failed("publish", e))?;
        loop {
            match side.next(Duration::from_secs(5))? {
                Some(p) if CommandMsg::from_bytes(&p.0).seq == i => break,
                Some(_) => {}
                None => return Err(LatencyError::PeerStopped { transport: "dds", iteration: i }),
            }
        }
        samples.record(i, rt::monotonic_ns() - t0);
    }
    drop(_rt);
    child.finish(Duration::from_secs(5))?;
    Ok(samples.finish())
}

/// The echoing side: answers every measurement with a command until `END_OF_RUN`.
///
/// # Errors
/// The transport failed or the benchmark went silent for 10 s.
pub fn peer(name: &DemoName) -> Result<(), LatencyError> {
    let mut side = Side::<Pong, Ping>::open(name, "peer", "pong", "ping")?;
    loop {
        let Some(p) = side.next(Duration::from_secs(10))? else { return Err(LatencyError::BenchmarkGone) };
        let m = MeasurementMsg::from_bytes(&p.0);
        side.tx.publish(Fixed(echo(&m, rt::monotonic_ns()).to_bytes())).map_err(|e| failed("publish", e))?;
        if m.has(flags::END_OF_RUN) {
            // Let the last answer leave before the participant goes.
            std::thread::sleep(Duration::from_millis(200));
            return Ok(());
        }
    }
}
