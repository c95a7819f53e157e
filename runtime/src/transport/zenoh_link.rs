//! The Zenoh transport of the HIL loop (cargo feature `zenoh`): the same two wire messages,
//! byte for byte, between two processes on one machine or two, over QUIC under mutual TLS
//! 1.3 by default ([`Scheme`]).
//!
//! ## Endpoints
//!
//! One side listens (`--listen quic/ADDR:PORT`, by default the plant), the other connects
//! (`--connect quic/ADDR:PORT`, by default the controller). Both are Zenoh *peers* with
//! multicast scouting and gossip off: they meet only through the endpoint given, never
//! another program's Zenoh network. The connecting side retries until its peer listens, so
//! either may start first; a listening side whose port is taken fails at once. `tls/` (TLS
//! over TCP) is accepted with a warning; `tcp/` only with `--insecure` ([`Security`]).
//!
//! ## Key expressions (protocol version 4)
//!
//! | key expression | from → to | payload |
//! |---|---|---|
//! | `companion/N/v4/measurement` | plant → controller | [`MeasurementMsg::to_bytes`] (344 bytes) |
//! | `companion/N/v4/command` | controller → plant | [`CommandMsg::to_bytes`] (248 bytes) |
//! | `companion/N/v4/alive/ROLE/PID` | liveliness token of each side | — |
//!
//! (`N` is `--name`.) Publications are express (not batched), priority real time, and dropped
//! rather than blocked on congestion: a late message is worth less than the next one. A
//! payload of another size is counted and dropped ([`ZenohEndpoint::malformed`]); its
//! content is checked by the loops as on every transport ([`crate::transport::wire::check_command`]).
//!
//! ## Receiving without allocating in the loop
//!
//! Zenoh delivers each sample on one of its own threads to a callback, which copies the bytes
//! into a preallocated single-producer single-consumer ring ([`RING`] messages; a full ring
//! drops the newest and counts it) and wakes the loop's thread if it sleeps in
//! [`ZenohEndpoint::wait_event`] (`thread::park_timeout`: every message wakes its receiver, so
//! this transport always announces `NOTIFIES`). The loop's `try_receive` is a ring pop. Zenoh
//! itself allocates per message, on its own threads and in `put` (see the `no_alloc` test for
//! the measured count).
//!
//! ## Liveness
//!
//! Each side declares a liveliness token after its subscriber, so seeing the peer's token
//! means the peer can hear us; [`ZenohEndpoint::wait_for_peer`] waits for it and for our
//! publisher to match the peer's subscriber. The token disappears when the peer's session
//! ends — its process exited, or was killed and its TCP connection closed at once, or the
//! link stayed silent past the lease the peer announced (10 s over TCP; over QUIC, where a
//! killed process closes nothing, half the peer's `--peer-timeout`: [`quic_lease`]) — and
//! [`ZenohEndpoint::peer_state`] then reports the peer [`PeerState::Dead`] (over QUIC
//! [`PeerState::Expired`]: across a network a killed process and a cut link look the same). A peer that stays connected but silent is alive: the loops call it hung after
//! `--peer-timeout`, as on iceoryx2.
//!
//! ## Mismatched peers
//!
//! Each side watches every token of its demo, whatever the version
//! (`companion/N/*/alive/*/*`): a token of another protocol version (`companion/N/vK/…`,
//! K ≠ 3) makes [`ZenohEndpoint::wait_for_peer`] fail with [`OtherVersion`] naming it (both
//! sides, if the other side does the same); a second process of our own role on the same demo
//! (e.g. a second controller connecting to a plant already served) fails with [`NameInUse`]
//! (exit 5) before it sends anything. The first peer token seen is *the* peer: tokens of
//! other processes never change its state. Mismatched scenarios, joints or periods are found
//! by the handshake, as on iceoryx2.

use std::marker::PhantomData;
use std::path::PathBuf;
use std::sync::atomic::{AtomicI32, AtomicU64, AtomicU8, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread::Thread;
use std::time::{Duration, Instant};

use zenoh::sample::SampleKind;
use zenoh::Wait;
use zerocopy::{FromBytes, Immutable, IntoBytes};

use crate::sys::lock::{DemoName, NameInUse, Role};
use crate::transport::error::StartError;
use crate::transport::ipc::OtherVersion;
use crate::transport::link::{Link, LinkCounts, LinkError, PeerState};
use crate::transport::wire::{CommandMsg, MeasurementMsg, PROTOCOL_VERSION};

/// Received messages waiting for the loop (allocated once).
pub const RING: usize = 16;

/// A link's protocol: QUIC under mutual TLS 1.3 (the default), TLS over TCP, or plain TCP
/// (only with `--insecure`).
///
/// QUIC is the default because zenoh 1.10's TLS-over-TCP link is not sound: it reads and
/// writes one rustls connection from its receiving and its sending task at once through an
/// `UnsafeCell` (eclipse-zenoh/zenoh#2557, open). Measured here: every 20 s `companion hil
/// --transport zenoh` run over `tls/` on the loaded 2-CPU machine (3 of 3) lost its link within
/// 3–19 s ("TX task failed: handshake not complete", rustls's state seen mid-update by the
/// other task), and both sides then reported the other dead; over `quic/` (quinn: separate
/// send and receive streams) 0 of 3. `tls/` stays accepted, for networks that pass no UDP, with
/// a warning at start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scheme {
    /// `tls/`: TCP under mutual TLS (zenoh#2557: warned at start).
    Tls,
    /// `quic/`: QUIC (UDP) under mutual TLS 1.3; the default.
    Quic,
    /// `tcp/`: plain TCP, neither authenticated nor encrypted.
    Tcp,
}

impl Scheme {
    /// `tls` or `tcp`, as in the endpoint.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Tls => "tls",
            Self::Quic => "quic",
            Self::Tcp => "tcp",
        }
    }
}

/// A Zenoh endpoint, `quic/HOST:PORT`, `tls/HOST:PORT` or `tcp/HOST:PORT`, checked.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TcpEndpoint {
    /// TLS or plain TCP.
    pub scheme: Scheme,
    /// The host (a name or an address; IPv6 in brackets). Over TLS the connecting side
    /// checks that the listener's certificate is valid for this name or address.
    pub host: String,
    /// The port.
    pub port: u16,
}

impl TcpEndpoint {
    /// Parses `quic/HOST:PORT`, `tls/HOST:PORT` or `tcp/HOST:PORT`.
    ///
    /// # Errors
    /// [`StartError::BadEndpoint`]: another protocol, no host, or no valid port.
    pub fn parse(s: &str) -> Result<Self, StartError> {
        let (scheme, rest) = if let Some(rest) = s.strip_prefix("tls/") {
            (Scheme::Tls, rest)
        } else if let Some(rest) = s.strip_prefix("quic/") {
            (Scheme::Quic, rest)
        } else if let Some(rest) = s.strip_prefix("tcp/") {
            (Scheme::Tcp, rest)
        } else {
            return Err(StartError::BadEndpoint(format!(
                "endpoint {s:?}: expected quic/HOST:PORT, e.g. quic/192.168.1.20:7447 (tls/HOST:PORT for TLS over \
                 TCP, or tcp/HOST:PORT with --insecure)"
            )));
        };
        let p = scheme.as_str();
        let Some((host, port)) = rest.rsplit_once(':') else {
            return Err(StartError::BadEndpoint(format!(
                "endpoint {s:?}: no port; expected {p}/HOST:PORT, e.g. {p}/127.0.0.1:7447"
            )));
        };
        let port: u16 = port.parse().map_err(|_| {
            StartError::BadEndpoint(format!(
                "endpoint {s:?}: the port {port:?} is not a number from 0 to 65535; expected {p}/HOST:PORT"
            ))
        })?;
        let bad_host = host.is_empty()
            || !host.bytes().all(|b| b.is_ascii_alphanumeric() || b"-._:[]".contains(&b))
            || host.contains(':') && !(host.starts_with('[') && host.ends_with(']'));
        if bad_host {
            return Err(StartError::BadEndpoint(format!(
                "endpoint {s:?}: bad host {host:?}; expected {p}/HOST:PORT (an IPv6 address in brackets)"
            )));
        }
        Ok(Self { scheme, host: host.to_string(), port })
    }
}

impl std::fmt::Display for TcpEndpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}:{}", self.scheme.as_str(), self.host, self.port)
    }
}

/// The TLS material of one side: the deployment's CA, this side's certificate and key (PEM
/// files, as `companion certs` writes them), and the names the peer's certificate may carry.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TlsFiles {
    /// The CA certificate both sides' certificates are checked against (`--tls-ca`).
    pub ca: PathBuf,
    /// This side's certificate, signed by the CA (`--tls-cert`).
    pub cert: PathBuf,
    /// This side's private key (`--tls-key`; owner-only, `0600`).
    pub key: PathBuf,
    /// The common names (CN) a peer's certificate must carry to be served (`--tls-peer`);
    /// a peer with another certificate of the same CA is refused by Zenoh's access control.
    pub peer_names: Vec<String>,
}

/// Why a `tcp/` endpoint is refused without `--insecure`, and what to do instead
/// ([`StartError::PlaintextRefused`]).
pub fn plaintext_refused(endpoint: &TcpEndpoint) -> StartError {
    StartError::PlaintextRefused {
        endpoint: endpoint.to_string(),
        host: endpoint.host.clone(),
        port: endpoint.port,
    }
}

/// Who may join this side's demo.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Security {
    /// Mutual TLS: only a peer with a certificate of the CA and one of the expected names.
    Tls(TlsFiles),
    /// `--insecure`: plain TCP, anyone who reaches the port; nothing is encrypted.
    Insecure,
}

impl Security {
    /// `mutual TLS (peer ctrl.local)` or `INSECURE plain TCP`.
    pub fn describe(&self) -> String {
        match self {
            Self::Tls(t) => format!("mutual TLS, peer certificate {}", t.peer_names.join(" or ")),
            Self::Insecure => "INSECURE plain TCP (--insecure)".into(),
        }
    }

    /// Checks that the endpoint's scheme matches (`tls/` with TLS, `tcp/` only when
    /// insecure), the files can be read and the names are not empty.
    ///
    /// # Errors
    /// A message saying what to change: [`StartError::Insecure`],
    /// [`StartError::PlaintextRefused`], [`StartError::TlsFile`] or [`StartError::TlsFlag`].
    pub fn check(&self, endpoint: &TcpEndpoint) -> Result<(), StartError> {
        match (self, endpoint.scheme) {
            (Self::Insecure, Scheme::Tcp) => Ok(()),
            (Self::Insecure, Scheme::Tls | Scheme::Quic) => Err(StartError::Insecure(format!(
                "--insecure is for plain tcp/ endpoints; {endpoint} is TLS: drop --insecure"
            ))),
            (Self::Tls(_), Scheme::Tcp) => Err(plaintext_refused(endpoint)),
            (Self::Tls(t), Scheme::Tls | Scheme::Quic) => {
                for (flag, p) in [("--tls-ca", &t.ca), ("--tls-cert", &t.cert), ("--tls-key", &t.key)] {
                    std::fs::metadata(p).map_err(|source| StartError::TlsFile {
                        flag,
                        path: p.clone(),
                        source,
                    })?;
                }
                if t.peer_names.is_empty() || t.peer_names.iter().any(|n| n.trim().is_empty()) {
                    return Err(StartError::TlsFlag(
                        "--tls-peer: the name on the peer's certificate, e.g. ctrl.local (not empty)".into(),
                    ));
                }
                Ok(())
            }
        }
    }
}

/// Which way this side's link is set up.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ZenohLink {
    /// Listen on the endpoint (the peer connects).
    Listen(TcpEndpoint),
    /// Connect to the endpoint (retried until the peer listens).
    Connect(TcpEndpoint),
}

impl ZenohLink {
    /// The endpoint listened on or connected to.
    pub fn endpoint(&self) -> &TcpEndpoint {
        match self {
            Self::Listen(e) | Self::Connect(e) => e,
        }
    }
}

impl std::fmt::Display for ZenohLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Listen(e) => write!(f, "listening on {e}"),
            Self::Connect(e) => write!(f, "connecting to {e}"),
        }
    }
}

/// The key expression of `what` in demo `name`: `companion/NAME/v4/WHAT`.
pub fn key(name: &str, what: &str) -> String {
    crate::transport::ipc::service_name(name, what)
}

/// Peer states in [`Shared::peer`] (0: not seen yet).
const ALIVE: u8 = 1;
const LOST: u8 = 2;

/// What the Zenoh callbacks and the loop share.
#[derive(Debug, Default)]
struct Shared {
    /// The loop's thread, once it has waited ([`ZenohEndpoint::wait_event`]).
    waiter: OnceLock<Thread>,
    /// 0 (not seen yet), [`ALIVE`] or [`LOST`].
    peer: AtomicU8,
    /// The peer's process id (from its token's key).
    peer_pid: AtomicI32,
    /// Payloads of the wrong size.
    malformed: AtomicU64,
    /// Messages dropped on a full ring.
    overflow: AtomicU64,
    /// Messages delivered by Zenoh to the subscriber's callback (of any size, kept or not).
    received: AtomicU64,
    /// Messages handed to Zenoh's `put` that it accepted (it may still drop them: [`Tuning`]).
    published: AtomicU64,
    /// A process of our own role on the same demo, version and name (pid; 0: none seen).
    rival: AtomicI32,
    /// A process of another protocol version on the same demo.
    other: Mutex<Option<OtherVersion>>,
    /// Peers refused for their certificate's name, not yet taken (at most [`KEEP_REFUSED`]).
    refused: Mutex<Vec<String>>,
    /// Every peer refused for its certificate's name.
    refused_names: AtomicU64,
    /// The last refusal taken (for the message of a startup timeout).
    last_refusal: Mutex<Option<String>>,
    /// Refusals returned by [`ZenohEndpoint::take_refusals`] so far.
    shown: AtomicU64,
}

/// Refusals [`ZenohEndpoint::take_refusals`] returns in all (the rest are counted).
pub const SHOWN_REFUSALS: u64 = 10;

/// Refusals kept until taken ([`ZenohEndpoint::take_refusals`]; more are only counted).
const KEEP_REFUSED: usize = 16;

/// What a liveliness token of demo `name` says: (version, role, pid), from
/// `companion/NAME/vK/alive/ROLE/PID`.
fn parse_token<'a>(name: &str, key: &'a str) -> Option<(u32, &'a str, i32)> {
    let rest = key.strip_prefix("companion/")?.strip_prefix(name)?.strip_prefix('/')?;
    let mut parts = rest.split('/');
    let version = parts.next()?.strip_prefix('v')?.parse().ok()?;
    if parts.next()? != "alive" {
        return None;
    }
    let role = parts.next()?;
    let pid = parts.next()?.parse().ok()?;
    parts.next().is_none().then_some((version, role, pid))
}

impl Shared {
    fn wake(&self) {
        if let Some(t) = self.waiter.get() {
            t.unpark();
        }
    }
}

/// One side of the exchange over Zenoh.
pub struct ZenohEndpoint<Tx, Rx> {
    name: String,
    role: Role,
    link: ZenohLink,
    session: zenoh::Session,
    publisher: zenoh::pubsub::Publisher<'static>,
    rx: rtrb::Consumer<(Rx, u64)>,
    shared: Arc<Shared>,
    _subscriber: zenoh::pubsub::Subscriber<()>,
    _liveliness: zenoh::pubsub::Subscriber<()>,
    _token: zenoh::liveliness::LivelinessToken,
    _tx: PhantomData<fn(&Tx)>,
}

/// The longest wait for Zenoh to close a session when an endpoint is dropped.
///
/// Zenoh's own is 10 s, and over QUIC a session whose peer was killed takes all of it (its
/// connector keeps trying the dead peer's address): measured, a controller that found its
/// killed plant 1 012 ms after the last measurement printed so only 11.6 s after the kill.
/// A close cut short leaves nothing that outlives the process; the peer, if alive, ends its
/// side by its lease.
pub const CLOSE_WAIT: Duration = Duration::from_millis(500);

impl<Tx, Rx> Drop for ZenohEndpoint<Tx, Rx> {
    fn drop(&mut self) {
        // (zenoh's `timeout` is behind its `internal` feature, for this.)
        if let Err(e) = self.session.close().timeout(CLOSE_WAIT).wait() {
            tracing::debug!("closing the zenoh session of demo {}: {e}", self.name);
        }
    }
}

impl<Tx, Rx> std::fmt::Debug for ZenohEndpoint<Tx, Rx> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ZenohEndpoint")
            .field("name", &self.name)
            .field("role", &self.role)
            .field("link", &self.link)
            .finish_non_exhaustive()
    }
}

/// The plant's endpoint.
pub type ZenohPlant = ZenohEndpoint<MeasurementMsg, CommandMsg>;
/// The controller's endpoint.
pub type ZenohControl = ZenohEndpoint<CommandMsg, MeasurementMsg>;

/// Zenoh refused a set-up step: `what` (made only on failure) and zenoh's words.
fn zerr(what: impl FnOnce() -> String) -> impl FnOnce(zenoh::Error) -> StartError {
    move |e| StartError::Zenoh { what: what(), cause: e.to_string() }
}

/// A JSON string (a path or a name, quoted and escaped).
fn json(s: &str) -> String {
    serde_json::Value::String(s.to_string()).to_string()
}

/// Every kind of message Zenoh's access control knows: a peer of the right name may do
/// anything on this demo's keys, any other nothing.
const ACL_MESSAGES: &str = "[\"put\", \"delete\", \"declare_subscriber\", \"query\", \"declare_queryable\", \
                            \"reply\", \"liveliness_token\", \"declare_liveliness_subscriber\", \"liveliness_query\"]";

/// The lease this side announces over QUIC: half the loops' `--peer-timeout`, within
/// [[`MIN_QUIC_LEASE`], 10 s] (zenoh's default, which TCP keeps).
///
/// Over TCP a killed peer's kernel closes the connection and its session ends at once (the
/// peer is found dead within ~20 ms). A killed QUIC peer sends nothing — UDP has no
/// connection for the kernel to close — so its session ends only when its lease runs out
/// with no message (zenoh sends keep-alives four times per lease). Under 10 s the loops
/// would first call the dead peer hung (`--peer-timeout`, 2 s by default: measured "alive
/// but silent for 2014 ms"); at half the peer timeout it is found dead first (measured: a
/// killed controller found dead 514 ms after its last command at a 500 ms lease, 1 007 ms
/// at 1 s). The peer expires *our* session by the lease *we* announce, so each side's
/// `--peer-timeout` sets how soon the other finds it dead.
pub fn quic_lease(peer_timeout: Duration) -> Duration {
    (peer_timeout / 2).clamp(MIN_QUIC_LEASE, Duration::from_secs(10))
}

/// The shortest QUIC lease: keep-alives every 125 ms at most.
pub const MIN_QUIC_LEASE: Duration = Duration::from_millis(500);

/// Zenoh settings measured by `companion latency` (the defaults are what the HIL uses).
///
/// Publications are congestion-control *drop*: when the link's real-time queue (two batches,
/// zenoh's default) has no free batch for `wait_before_drop` (1 ms), zenoh 1.10 drops the
/// message and `put` still returns `Ok` (`zenoh-transport`'s `TransmissionPipelineProducer::
/// push_network_message`; its count is only behind zenoh's `stats` feature). Such a drop is
/// seen end to end instead: the sender's [`ZenohEndpoint::published`] against the receiver's
/// [`ZenohEndpoint::received`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Tuning {
    /// Zenoh's low-latency transport (`transport/unicast/lowlatency`, QoS off): no
    /// transmission queue and its task, the sender writes the link itself.
    pub low_latency: bool,
}

/// The Zenoh configuration of one side: a peer that meets only the given endpoint; with
/// TLS, mutual authentication by the CA and access control by the peer certificate's name;
/// over QUIC, the lease of [`quic_lease`].
fn config(
    name: &str,
    link: &ZenohLink,
    security: &Security,
    peer_timeout: Duration,
    tuning: Tuning,
) -> Result<zenoh::Config, StartError> {
    let mut c = zenoh::Config::default();
    let mut set = |k: &str, v: &str| c.insert_json5(k, v).map_err(zerr(|| format!("zenoh config {k} = {v}")));
    set("mode", "\"peer\"")?;
    if let Security::Tls(t) = security {
        let path = |p: &PathBuf| json(&p.to_string_lossy());
        set("transport/link/tls/root_ca_certificate", &path(&t.ca))?;
        // Both pairs: zenoh presents the listen pair on accepted links, the connect pair on
        // the links it opens.
        set("transport/link/tls/listen_certificate", &path(&t.cert))?;
        set("transport/link/tls/listen_private_key", &path(&t.key))?;
        set("transport/link/tls/connect_certificate", &path(&t.cert))?;
        set("transport/link/tls/connect_private_key", &path(&t.key))?;
        set("transport/link/tls/enable_mtls", "true")?;
        set("transport/link/tls/verify_name_on_connect", "true")?;
        // Zenoh gives the application no certificate, only its common name (in link events
        // and to its access control): the name check is an access-control policy, default
        // deny, allowing the expected names everything on this demo's keys, both ways.
        let names: Vec<String> = t.peer_names.iter().map(|n| json(n)).collect();
        let acl = format!(
            "{{ enabled: true, default_permission: \"deny\", \
               rules: [{{ id: \"demo\", messages: {ACL_MESSAGES}, flows: [\"egress\", \"ingress\"], \
                          permission: \"allow\", key_exprs: [{}, {}] }}], \
               subjects: [{{ id: \"peer\", cert_common_names: [{}] }}], \
               policies: [{{ rules: [\"demo\"], subjects: [\"peer\"] }}] }}",
            json(&format!("companion/{name}")),
            json(&format!("companion/{name}/**")),
            names.join(", ")
        );
        set("access_control", &acl)?;
    }
    set("scouting/multicast/enabled", "false")?;
    set("scouting/gossip/enabled", "false")?;
    if link.endpoint().scheme == Scheme::Quic {
        let ms = quic_lease(peer_timeout).as_millis().to_string();
        set("transport/link/tx/lease", &ms)?;
    }
    // Zenoh's low-latency transport is measured by `companion latency` beside the default
    // (docs/book/src/two-machines.md, "Where the time goes, hop by hop"); not the default.
    if tuning.low_latency {
        set("transport/unicast/lowlatency", "true")?;
        set("transport/unicast/qos/enabled", "false")?;
    }
    match link {
        ZenohLink::Listen(e) => {
            set("listen/endpoints", &format!("[\"{e}\"]"))?;
            set("listen/exit_on_failure", "true")?;
        }
        ZenohLink::Connect(e) => {
            set("listen/endpoints", "[]")?;
            set("connect/endpoints", &format!("[\"{e}\"]"))?;
            // Open at once and keep trying in the background (no timeout, no exit on failure:
            // zenoh then connects from a task of its own): the peer may start later; the
            // startup timeout bounds the wait (`wait_for_peer`).
            set("connect/timeout_ms", "-1")?;
            set("connect/exit_on_failure", "false")?;
            set("connect/retry", "{ period_init_ms: 50, period_max_ms: 250, period_increase_factor: 2 }")?;
        }
    }
    Ok(c)
}

fn own_pid() -> i32 {
    i32::try_from(std::process::id()).unwrap_or(0)
}

impl<Tx, Rx> ZenohEndpoint<Tx, Rx>
where
    Tx: IntoBytes + Immutable,
    Rx: FromBytes + Send + 'static,
{
    /// Opens `role`'s side of demo `name` over `link`: the session, a subscriber to the
    /// peer's messages, a publisher of ours, then our liveliness token and a watch on the
    /// peer's. `peer_timeout`: the loops' `--peer-timeout`, which sets the lease over QUIC
    /// ([`quic_lease`]).
    ///
    /// # Errors
    /// An endpoint that `security` does not allow ([`Security::check`]), or Zenoh cannot open the session ([`StartError::Listen`],
    /// [`StartError::Connect`]: e.g. the port to listen on is taken, a TLS file is bad) or set
    /// up its parts ([`StartError::Zenoh`]).
    pub fn open(
        name: &DemoName,
        role: Role,
        link: ZenohLink,
        security: &Security,
        peer_timeout: Duration,
    ) -> Result<Self, StartError> {
        Self::open_tuned(name, role, link, security, peer_timeout, Tuning::default())
    }

    /// [`Self::open`] with Zenoh settings other than the defaults (`companion latency`).
    ///
    /// # Errors
    /// As [`Self::open`].
    pub fn open_tuned(
        name: &DemoName,
        role: Role,
        link: ZenohLink,
        security: &Security,
        peer_timeout: Duration,
        tuning: Tuning,
    ) -> Result<Self, StartError> {
        let (tx, rx_what) = match role {
            Role::Plant => ("measurement", "command"),
            Role::Control => ("command", "measurement"),
        };
        security.check(link.endpoint())?;
        crate::transport::zenoh_log::install();
        let session = zenoh::open(config(name, &link, security, peer_timeout, tuning)?).wait().map_err(
            |e| match &link {
                ZenohLink::Listen(ep) => {
                    StartError::Listen { endpoint: ep.to_string(), cause: e.to_string() }
                }
                ZenohLink::Connect(ep) => {
                    StartError::Connect { endpoint: ep.to_string(), cause: e.to_string() }
                }
            },
        )?;
        let shared = Arc::new(Shared::default());
        let (producer, consumer) = rtrb::RingBuffer::<(Rx, u64)>::new(RING);
        // Only Zenoh's thread that delivers this subscriber's samples takes the lock.
        let producer = Mutex::new(producer);
        let sh = Arc::clone(&shared);
        let subscriber = session
            .declare_subscriber(key(name, rx_what))
            .callback(move |sample: zenoh::sample::Sample| {
                // The first thing on Zenoh's thread: when the message reached this process.
                let arrived = crate::sys::rt::monotonic_ns();
                sh.received.fetch_add(1, Ordering::Relaxed);
                let bytes = sample.payload().to_bytes();
                match Rx::read_from_bytes(&bytes) {
                    Ok(msg) => {
                        let mut p = producer.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                        if p.push((msg, arrived)).is_err() {
                            sh.overflow.fetch_add(1, Ordering::Relaxed);
                        }
                        sh.wake();
                    }
                    Err(_) => {
                        sh.malformed.fetch_add(1, Ordering::Relaxed);
                    }
                }
            })
            .wait()
            .map_err(zerr(|| format!("subscribing to {}", key(name, rx_what))))?;
        let publisher = session
            .declare_publisher(key(name, tx))
            .congestion_control(zenoh::qos::CongestionControl::Drop)
            .priority(zenoh::qos::Priority::RealTime)
            .express(true)
            .wait()
            .map_err(zerr(|| format!("declaring the publisher of {}", key(name, tx))))?;
        // Every token of this demo, of any version: the peer's, a rival's, another version's.
        let watch_key = format!("companion/{name}/*/alive/*/*");
        let sh = Arc::clone(&shared);
        let (demo, own_role, peer_role, own) =
            (name.to_string(), role.as_str(), role.peer().as_str(), own_pid());
        let liveliness = session
            .liveliness()
            .declare_subscriber(&watch_key)
            .history(true)
            .callback(move |sample: zenoh::sample::Sample| {
                let key = sample.key_expr().as_str();
                let Some((version, r, pid)) = parse_token(&demo, key) else { return };
                let put = sample.kind() == SampleKind::Put;
                if version != PROTOCOL_VERSION {
                    if put && pid != own {
                        let o = OtherVersion { name: demo.clone(), version, service: key.to_string(), pid };
                        *sh.other.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(o);
                        sh.wake();
                    }
                } else if r == peer_role {
                    // The first peer seen is the peer; another's token never changes its state.
                    let first = sh.peer.load(Ordering::Acquire) == 0;
                    if put && first {
                        sh.peer_pid.store(pid, Ordering::Relaxed);
                        sh.peer.store(ALIVE, Ordering::Release);
                        sh.wake();
                    } else if !put && !first && sh.peer_pid.load(Ordering::Relaxed) == pid {
                        sh.peer.store(LOST, Ordering::Release);
                        sh.wake();
                    }
                } else if r == own_role && pid != own {
                    sh.rival.store(if put { pid } else { 0 }, Ordering::Relaxed);
                }
            })
            .wait()
            .map_err(zerr(|| format!("watching {watch_key}")))?;
        if let Security::Tls(t) = security {
            // Name the peers access control refuses (zenoh gives their certificate's CN).
            let (sh, expected) = (Arc::clone(&shared), t.peer_names.clone());
            session
                .info()
                .link_events_listener()
                .history(true)
                .callback(move |ev: zenoh::session::LinkEvent| {
                    if ev.kind() != SampleKind::Put {
                        return;
                    }
                    let l = ev.link();
                    let cn = l.auth_identifier();
                    if cn.is_some_and(|cn| expected.iter().any(|e| e == cn)) {
                        return;
                    }
                    let why = format!(
                        "refused the peer at {} (zenoh id {}): its certificate's name is {}, not {} \
                         (access control drops everything it sends)",
                        l.dst(),
                        l.zid(),
                        cn.map_or_else(|| "absent".to_string(), |c| format!("{c:?}")),
                        expected.iter().map(|e| format!("{e:?}")).collect::<Vec<_>>().join(" or "),
                    );
                    sh.refused_names.fetch_add(1, Ordering::Relaxed);
                    let mut r = sh.refused.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                    if r.len() < KEEP_REFUSED {
                        r.push(why);
                    }
                })
                .background()
                .wait()
                .map_err(zerr(|| "watching the links of the session".into()))?;
        }
        let own_key = key(name, &format!("alive/{}/{}", role.as_str(), own_pid()));
        let token = session
            .liveliness()
            .declare_token(&own_key)
            .wait()
            .map_err(zerr(|| format!("declaring the liveliness token {own_key}")))?;
        Ok(Self {
            name: name.to_string(),
            role,
            link,
            session,
            publisher,
            rx: consumer,
            shared,
            _subscriber: subscriber,
            _liveliness: liveliness,
            _token: token,
            _tx: PhantomData,
        })
    }

    /// Publishes one message (its bytes; Zenoh copies them into a buffer of its own).
    ///
    /// # Errors
    /// [`LinkError::Publish`]: a Zenoh failure.
    #[inline]
    pub fn send(&self, msg: &Tx) -> Result<(), LinkError> {
        self.publisher
            .put(msg.as_bytes())
            .wait()
            .map_err(|e| LinkError::Publish { step: "zenoh put", cause: e.to_string() })?;
        self.shared.published.fetch_add(1, Ordering::Relaxed);
        Ok(())
    }

    /// Takes the oldest waiting message, if any.
    #[inline]
    pub fn try_receive(&mut self) -> Option<Rx> {
        self.rx.pop().ok().map(|(m, _)| m)
    }

    /// Takes the oldest waiting message with the `CLOCK_MONOTONIC` time (ns) at which Zenoh's
    /// thread entered the subscriber's callback with it.
    #[inline]
    pub fn try_receive_stamped(&mut self) -> Option<(Rx, u64)> {
        self.rx.pop().ok()
    }

    /// Sleeps until a message arrives, the peer's liveliness changes, or `timeout` passes.
    #[inline]
    pub fn wait_event(&self, timeout: Duration) {
        let _ = self.shared.waiter.get_or_init(std::thread::current);
        if self.rx.is_empty() {
            std::thread::park_timeout(timeout);
        }
    }

    /// The peer's state, from its liveliness token: [`PeerState::Alive`] while it exists,
    /// [`PeerState::Dead`] once it disappeared ([`PeerState::Expired`] over QUIC, where the
    /// token of a killed peer goes only when its lease runs out), [`PeerState::Absent`] before
    /// it was seen.
    pub fn peer_state(&self) -> PeerState {
        let pid = self.shared.peer_pid.load(Ordering::Relaxed);
        match self.shared.peer.load(Ordering::Acquire) {
            ALIVE => PeerState::Alive(pid),
            LOST if self.link.endpoint().scheme == Scheme::Quic => PeerState::Expired(pid),
            LOST => PeerState::Dead(pid),
            _ => PeerState::Absent,
        }
    }

    /// Payloads of the wrong size received so far (dropped).
    pub fn malformed(&self) -> u64 {
        self.shared.malformed.load(Ordering::Relaxed)
    }

    /// Messages dropped because the loop had not taken the [`RING`] before them.
    pub fn overflow(&self) -> u64 {
        self.shared.overflow.load(Ordering::Relaxed)
    }

    /// Messages Zenoh delivered to this side so far (kept, dropped on a full ring, or
    /// malformed): against the peer's [`Self::published`], what the link lost.
    pub fn received(&self) -> u64 {
        self.shared.received.load(Ordering::Relaxed)
    }

    /// Every count of this side's messages ([`LinkCounts`]).
    pub fn link_counts(&self) -> LinkCounts {
        LinkCounts {
            published: self.published(),
            received: self.received(),
            dropped_full_ring: self.overflow(),
            malformed: self.malformed(),
        }
    }

    /// Messages this side handed to Zenoh so far (`put` returned `Ok`; zenoh may still have
    /// dropped them on congestion, see [`Tuning`]).
    pub fn published(&self) -> u64 {
        self.shared.published.load(Ordering::Relaxed)
    }

    /// The refusals since the last call, oldest first: peers refused for their certificate's
    /// name, and TLS handshakes the listener refused (no certificate, another CA, expired,
    /// not TLS at all), in zenoh's words.
    ///
    /// At most [`SHOWN_REFUSALS`] are returned in all (a peer retrying, or a flood of
    /// connections, would fill the log): the rest are only counted ([`Self::refusals`]).
    pub fn take_refusals(&self) -> Vec<String> {
        let mut out = self.drain_refusals();
        let shown = self.shared.shown.load(Ordering::Relaxed);
        let room = SHOWN_REFUSALS.saturating_sub(shown);
        if out.len() as u64 > room {
            out.truncate(room as usize);
            if room > 0 {
                out.push("further refusals are counted, not shown".to_string());
            }
        }
        self.shared.shown.store(shown + out.len() as u64, Ordering::Relaxed);
        out
    }

    /// Every refusal not yet taken; the last one kept for [`Self::last_refusal`].
    fn drain_refusals(&self) -> Vec<String> {
        let mut out: Vec<String> = std::mem::take(
            &mut *self.shared.refused.lock().unwrap_or_else(std::sync::PoisonError::into_inner),
        );
        out.extend(
            crate::transport::zenoh_log::take_refused()
                .into_iter()
                .map(|e| format!("refused a TLS handshake: {e}")),
        );
        if let Some(last) = out.last() {
            *self.shared.last_refusal.lock().unwrap_or_else(std::sync::PoisonError::into_inner) =
                Some(last.clone());
        }
        out
    }

    /// The last refusal so far, shown or not.
    pub fn last_refusal(&self) -> Option<String> {
        let _ = self.drain_refusals();
        self.shared.last_refusal.lock().unwrap_or_else(std::sync::PoisonError::into_inner).clone()
    }

    /// How many peers were refused so far: for their certificate's name, and at the TLS
    /// handshake (this process's listeners).
    pub fn refusals(&self) -> u64 {
        self.shared.refused_names.load(Ordering::Relaxed) + crate::transport::zenoh_log::refused()
    }

    /// Whether the peer is there and hears us: its token is seen and our publisher matches
    /// its subscriber.
    pub fn peer_connected(&self) -> bool {
        self.shared.peer.load(Ordering::Acquire) == ALIVE
            && self.publisher.matching_status().wait().is_ok_and(|m| m.matching())
    }

    /// Waits until [`ZenohEndpoint::peer_connected`], polling every millisecond; `abort` is
    /// asked each time whether to give up.
    ///
    /// # Errors
    /// The timeout passed ([`StartError::NoPeer`], the message names the endpoint), `abort`
    /// said so ([`StartError::Aborted`]), a signal came ([`StartError::Interrupted`]), or
    /// [`Self::check_mismatch`] failed.
    pub fn wait_for_peer(
        &self,
        timeout: Duration,
        mut abort: impl FnMut() -> Option<String>,
    ) -> Result<(), StartError> {
        let start = Instant::now();
        loop {
            self.check_mismatch()?;
            if self.peer_connected() {
                // A moment for tokens of rivals and other versions that came with the peer's.
                std::thread::sleep(Duration::from_millis(50));
                return self.check_mismatch();
            }
            if let Some(why) = abort() {
                return Err(StartError::Aborted(why));
            }
            if crate::sys::signals::termination_requested() {
                return Err(StartError::Interrupted(self.role.peer().as_str()));
            }
            if start.elapsed() > timeout {
                let peer = self.role.peer().as_str();
                let hint = match &self.link {
                    ZenohLink::Connect(e) => format!(
                        "nothing answered at {e} (is `companion {peer} --transport zenoh --listen {e} --name {}` \
                         running, and the address reachable from here?)",
                        self.name
                    ),
                    ZenohLink::Listen(e) => format!(
                        "nobody connected to {e} (start `companion {peer} --transport zenoh --connect {e} --name {}`)",
                        self.name
                    ),
                };
                let last = self.last_refusal();
                let refused = match (self.refusals(), &self.link) {
                    (0, ZenohLink::Connect(_)) => crate::transport::zenoh_log::last_connect_error()
                        .map_or_else(String::new, |e| format!("; the last attempt: {e}")),
                    (0, ZenohLink::Listen(_)) => String::new(),
                    (n, _) => format!("; {n} connection(s) refused, the last: {}", last.unwrap_or_default()),
                };
                return Err(StartError::NoPeer(format!(
                    "no {peer} joined demo '{}' over Zenoh within {:.0} s: {hint}{refused}; key expressions {} \
                     and {}, protocol version {PROTOCOL_VERSION}",
                    self.name,
                    timeout.as_secs_f64(),
                    key(&self.name, "measurement"),
                    key(&self.name, "command"),
                )));
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Fails if a process of another protocol version, or a second one of our role, is on
    /// this demo.
    ///
    /// # Errors
    /// [`StartError::OtherVersion`] or [`StartError::NameInUse`].
    pub fn check_mismatch(&self) -> Result<(), StartError> {
        if let Some(o) = self.shared.other.lock().unwrap_or_else(std::sync::PoisonError::into_inner).clone() {
            // Stay a moment, so that the other side's own check finds us and says so too.
            std::thread::sleep(Duration::from_millis(300));
            return Err(o.into());
        }
        let pid = self.shared.rival.load(Ordering::Relaxed);
        if pid != 0 {
            return Err(NameInUse { name: self.name.clone(), role: self.role.as_str(), pid }.into());
        }
        Ok(())
    }

    /// Waits (at most `max`) until the peer's token has gone: after a last message, so that
    /// the peer reads it before this session closes.
    pub fn linger(&self, max: Duration) {
        let end = Instant::now() + max;
        while self.shared.peer.load(Ordering::Acquire) == ALIVE && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// The Zenoh session id of this side (for messages).
    pub fn zid(&self) -> String {
        self.session.zid().to_string()
    }
}

impl<Tx, Rx> Link for ZenohEndpoint<Tx, Rx>
where
    Tx: IntoBytes + Immutable + Copy,
    Rx: FromBytes + Send + Copy + 'static,
{
    type Tx = Tx;
    type Rx = Rx;

    #[inline]
    fn publish(&mut self, msg: &Tx) -> Result<(), LinkError> {
        self.send(msg)
    }

    #[inline]
    fn try_receive(&mut self) -> Result<Option<Rx>, LinkError> {
        Ok(ZenohEndpoint::try_receive(self))
    }

    #[inline]
    fn wait_event(&mut self, timeout: Duration) -> Result<(), LinkError> {
        ZenohEndpoint::wait_event(self, timeout);
        Ok(())
    }

    fn peer_state(&mut self) -> Result<PeerState, LinkError> {
        Ok(ZenohEndpoint::peer_state(self))
    }

    fn notifies(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Waits until `f` holds (at most 20 s: a count, not a time, is what is tested).
    fn until(what: &str, mut f: impl FnMut() -> bool) {
        let end = Instant::now() + Duration::from_secs(20);
        while !f() {
            assert!(Instant::now() < end, "{what}: not within 20 s");
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Every message is counted where it went: published by the sender, received by the
    /// receiver, and of those, the ones that found the ring full dropped and counted; the ring
    /// keeps the oldest [`RING`] with the time each arrived.
    #[test]
    fn every_message_is_counted_published_received_or_dropped_on_a_full_ring() {
        let ep = crate::transport::free_local_endpoint(true).unwrap();
        let ep = TcpEndpoint::parse(&ep).unwrap();
        let name = DemoName::new(&format!("counts-{}", std::process::id())).unwrap();
        let t = Duration::from_secs(2);
        let mut plant =
            ZenohPlant::open(&name, Role::Plant, ZenohLink::Listen(ep.clone()), &Security::Insecure, t)
                .unwrap();
        let control =
            ZenohControl::open(&name, Role::Control, ZenohLink::Connect(ep), &Security::Insecure, t).unwrap();
        plant.wait_for_peer(Duration::from_secs(20), || None).unwrap();
        control.wait_for_peer(Duration::from_secs(20), || None).unwrap();
        let extra = 5u64;
        let before = crate::sys::rt::monotonic_ns();
        for seq in 0..RING as u64 + extra {
            // One at a time (each received before the next is sent): zenoh's own queue never
            // fills, so only the plant's ring, never emptied here, drops.
            let c = CommandMsg { seq, ..zerocopy::FromZeros::new_zeroed() };
            control.send(&c).unwrap();
            until("the plant's transport receives it", || plant.received() == seq + 1);
        }
        let counts = control.link_counts();
        assert_eq!((counts.published, counts.received), (RING as u64 + extra, 0));
        let counts = plant.link_counts();
        assert_eq!(
            counts,
            LinkCounts {
                published: 0,
                received: RING as u64 + extra,
                dropped_full_ring: extra,
                malformed: 0
            }
        );
        assert_eq!(control.link_counts().not_received_by(&counts), 0);
        let mut seqs = Vec::new();
        while let Some((c, arrived)) = plant.try_receive_stamped() {
            assert!(arrived >= before && arrived <= crate::sys::rt::monotonic_ns());
            seqs.push(c.seq);
        }
        assert_eq!(seqs, (0..RING as u64).collect::<Vec<_>>());
    }

    #[test]
    fn tokens_are_read_by_demo_version_role_and_pid() {
        assert_eq!(parse_token("d", "companion/d/v3/alive/plant/42"), Some((3, "plant", 42)));
        assert_eq!(parse_token("d", "companion/d/v4/alive/control/7"), Some((4, "control", 7)));
        for other in [
            "companion/dd/v3/alive/plant/42",
            "companion/d/v3/alive/plant/x",
            "companion/d/3/alive/plant/42",
            "companion/d/v3/measurement",
            "companion/d/v3/alive/plant/42/more",
        ] {
            assert_eq!(parse_token("d", other), None, "{other}");
        }
    }

    #[test]
    fn endpoints_are_checked() {
        assert_eq!(
            TcpEndpoint::parse("tcp/127.0.0.1:7447").unwrap(),
            TcpEndpoint { scheme: Scheme::Tcp, host: "127.0.0.1".into(), port: 7447 }
        );
        assert_eq!(
            TcpEndpoint::parse("tls/plant.local:7447").unwrap(),
            TcpEndpoint { scheme: Scheme::Tls, host: "plant.local".into(), port: 7447 }
        );
        assert_eq!(TcpEndpoint::parse("tls/[::1]:7447").unwrap().to_string(), "tls/[::1]:7447");
        assert_eq!(TcpEndpoint::parse("tcp/robot-1.local:0").unwrap().port, 0);
        let quic = TcpEndpoint::parse("quic/plant.local:7447").unwrap();
        assert_eq!((quic.scheme, quic.to_string()), (Scheme::Quic, "quic/plant.local:7447".to_string()));
        assert_eq!(TcpEndpoint::parse("tcp/[::1]:7447").unwrap().to_string(), "tcp/[::1]:7447");
        for bad in [
            "127.0.0.1:7447",
            "udp/1.2.3.4:5",
            "tcp/1.2.3.4",
            "tcp/:7447",
            "tcp/h:99999",
            "tcp/h:x",
            "tcp/::1:5",
            "tls/h:x",
            "quic/h",
            "quic/h:x",
        ] {
            let e = TcpEndpoint::parse(bad).unwrap_err();
            assert!(matches!(e, StartError::BadEndpoint(_)), "{bad}: {e}");
            let e = e.to_string();
            assert!(e.contains("/HOST:PORT") || e.contains("port"), "{bad}: {e}");
        }
    }

    #[test]
    fn opening_a_plaintext_endpoint_with_tls_is_refused_before_zenoh_starts() {
        let files = TlsFiles {
            ca: "/nonexistent/ca.pem".into(),
            cert: "/nonexistent/c.pem".into(),
            key: "/nonexistent/c.key".into(),
            peer_names: vec!["ctrl".into()],
        };
        let ep = TcpEndpoint::parse("tcp/127.0.0.1:7447").unwrap();
        let e = ZenohPlant::open(
            &DemoName::new("d").unwrap(),
            Role::Plant,
            ZenohLink::Listen(ep),
            &Security::Tls(files),
            Duration::from_secs(2),
        )
        .unwrap_err();
        assert!(
            matches!(&e, StartError::PlaintextRefused { endpoint, .. } if endpoint == "tcp/127.0.0.1:7447"),
            "{e}"
        );
    }

    #[test]
    fn security_and_scheme_must_agree() {
        let tcp = TcpEndpoint::parse("tcp/127.0.0.1:7447").unwrap();
        let tls = TcpEndpoint::parse("tls/127.0.0.1:7447").unwrap();
        assert!(Security::Insecure.check(&tcp).is_ok());
        let e = Security::Insecure.check(&tls).unwrap_err();
        assert!(matches!(e, StartError::Insecure(_)), "{e}");
        let e = e.to_string();
        assert!(e.contains("drop --insecure"), "{e}");
        let files = TlsFiles {
            ca: "/nonexistent/ca.pem".into(),
            cert: "/nonexistent/c.pem".into(),
            key: "/nonexistent/c.key".into(),
            peer_names: vec!["ctrl".into()],
        };
        let e = Security::Tls(files.clone()).check(&tcp).unwrap_err();
        assert!(matches!(e, StartError::PlaintextRefused { port: 7447, .. }), "{e}");
        let e = e.to_string();
        assert!(
            e.contains("is plain TCP") && e.contains("--insecure") && e.contains("quic/127.0.0.1:7447"),
            "{e}"
        );
        let e = Security::Tls(files.clone()).check(&tls).unwrap_err();
        let StartError::TlsFile { flag, path, source } = &e else { panic!("not TlsFile: {e}") };
        assert_eq!(
            (*flag, path.as_path(), source.kind()),
            ("--tls-ca", files.ca.as_path(), std::io::ErrorKind::NotFound)
        );
        let e = format!("{e:#}");
        assert!(e.contains("--tls-ca /nonexistent/ca.pem"), "{e}");
        // Files that can be read (their content is zenoh's to check), an empty peer name.
        let null = PathBuf::from("/dev/null");
        let blank =
            TlsFiles { ca: null.clone(), cert: null.clone(), key: null, peer_names: vec![" ".into()] };
        let e = Security::Tls(blank).check(&tls).unwrap_err();
        assert!(matches!(&e, StartError::TlsFlag(m) if m.starts_with("--tls-peer: ")), "{e}");
    }
}
