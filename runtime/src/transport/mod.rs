//! The transport layer: how the two HIL processes exchange the wire's messages.
//!
//! - [`wire`]: the two `#[repr(C)]` messages, the interface a hardware bridge implements;
//! - [`link`]: the transport as the loops see it ([`Link`], [`PeerState`]);
//! - [`ipc`]: iceoryx2 shared memory on one machine (the default);
//! - `zenoh_link` (QUIC under mutual TLS across machines), `zenoh_log` (zenoh's refusals as
//!   messages) and `certs` (the deployment's certificates), with the cargo feature `zenoh`.
//!
//! This module's own items are `--transport`'s choice and the one endpoint type the two
//! processes open: iceoryx2 ([`ipc`]) or Zenoh (`zenoh_link`). Both carry the same wire
//! messages under the same policies; the loops see only [`Link`].

#[cfg(feature = "zenoh")]
pub mod certs;
pub mod ipc;
pub mod link;
pub mod wire;
#[cfg(feature = "zenoh")]
pub mod zenoh_link;
#[cfg(feature = "zenoh")]
pub mod zenoh_log;

use std::time::Duration;

use anyhow::{bail, Result};

use crate::sys::lock::Role;
use link::{Link, PeerState};
use wire::{CommandMsg, MeasurementMsg, WireMessage};
use zerocopy::{FromBytes, Immutable, IntoBytes};

/// How this program was told to build when it lacks the Zenoh transport.
pub const BUILD_WITH_ZENOH: &str =
    "this companion was built without the Zenoh transport; rebuild it with `cargo build --release -p \
     companion-runtime --features zenoh` (or `cargo install --path runtime --features zenoh`)";

/// A wire message as both transports carry it: an iceoryx2 payload and plain bytes.
pub trait Message: WireMessage + IntoBytes + FromBytes + Immutable + Send {}
impl<T: WireMessage + IntoBytes + FromBytes + Immutable + Send> Message for T {}

/// The transport of a HIL run.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum Transport {
    /// iceoryx2 shared memory (one machine).
    #[default]
    Iceoryx2,
    /// Zenoh over TLS (or plain TCP with `--insecure`): this side listens or connects.
    #[cfg(feature = "zenoh")]
    Zenoh(crate::transport::zenoh_link::ZenohLink, crate::transport::zenoh_link::Security),
}

impl Transport {
    /// `iceoryx2`, or `zenoh (listening on tcp/…)`.
    pub fn describe(&self) -> String {
        match self {
            Self::Iceoryx2 => "iceoryx2".into(),
            #[cfg(feature = "zenoh")]
            Self::Zenoh(l, sec) => format!("zenoh ({l}, {})", sec.describe()),
        }
    }

    /// Whether this run's link lets anyone in (Zenoh with `--insecure`).
    pub fn insecure(&self) -> bool {
        match self {
            Self::Iceoryx2 => false,
            #[cfg(feature = "zenoh")]
            Self::Zenoh(_, sec) => *sec == crate::transport::zenoh_link::Security::Insecure,
        }
    }

    /// Whether this is zenoh's TLS-over-TCP link (`tls/`), which zenoh#2557 makes fail
    /// under load ([`Scheme`](crate::transport::zenoh_link::Scheme)).
    pub fn tls_over_tcp(&self) -> bool {
        match self {
            Self::Iceoryx2 => false,
            #[cfg(feature = "zenoh")]
            Self::Zenoh(l, _) => l.endpoint().scheme == crate::transport::zenoh_link::Scheme::Tls,
        }
    }
}

/// The Zenoh link's security as the command line gives it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SecurityFlags {
    /// `--tls-ca`.
    pub ca: Option<std::path::PathBuf>,
    /// `--tls-cert`.
    pub cert: Option<std::path::PathBuf>,
    /// `--tls-key`.
    pub key: Option<std::path::PathBuf>,
    /// `--tls-peer` (comma-separated names).
    pub peer: Option<String>,
    /// `--insecure`.
    pub insecure: bool,
}

/// The Zenoh transport from `--listen`/`--connect` (exactly one) and the TLS flags: TLS with
/// every file and the peer's name, or `--insecure` with a `tcp/` endpoint.
///
/// # Errors
/// Both or neither endpoint given, a malformed endpoint, a `tcp/` endpoint without
/// `--insecure`, a missing TLS flag, or a build without the feature ([`BUILD_WITH_ZENOH`]).
pub fn zenoh(listen: Option<&str>, connect: Option<&str>, sec: &SecurityFlags) -> Result<Transport> {
    #[cfg(feature = "zenoh")]
    {
        use crate::transport::zenoh_link::{Security, TcpEndpoint, TlsFiles, ZenohLink};
        let link = match (listen, connect) {
            (Some(l), None) => ZenohLink::Listen(TcpEndpoint::parse(l)?),
            (None, Some(c)) => ZenohLink::Connect(TcpEndpoint::parse(c)?),
            (Some(_), Some(_)) => bail!("--transport zenoh: give --listen or --connect, not both"),
            (None, None) => bail!(
                "--transport zenoh needs an endpoint: --listen quic/ADDR:PORT (usually the plant) or --connect \
                 quic/ADDR:PORT (usually the controller)"
            ),
        };
        let tls_given = sec.ca.is_some() || sec.cert.is_some() || sec.key.is_some() || sec.peer.is_some();
        let security = if sec.insecure {
            if tls_given {
                bail!("--insecure turns TLS off: drop it, or drop --tls-ca, --tls-cert, --tls-key and --tls-peer");
            }
            Security::Insecure
        } else if link.endpoint().scheme == crate::transport::zenoh_link::Scheme::Tcp {
            return Err(crate::transport::zenoh_link::plaintext_refused(link.endpoint()));
        } else {
            let need = |v: &Option<std::path::PathBuf>, flag: &str, what: &str| {
                v.clone().ok_or_else(|| {
                    anyhow::anyhow!(
                        "--transport zenoh over TLS needs {flag} FILE ({what}; `companion certs --out DIR --hosts \
                         plant.local,ctrl.local` makes them)"
                    )
                })
            };
            let ca = need(&sec.ca, "--tls-ca", "the deployment's CA certificate, ca.pem")?;
            let cert = need(&sec.cert, "--tls-cert", "this host's certificate, HOST.pem")?;
            let key = need(&sec.key, "--tls-key", "this host's private key, HOST.key")?;
            let Some(peer) = &sec.peer else {
                bail!(
                    "--transport zenoh over TLS needs --tls-peer NAME: the name on the certificate of the peer \
                     this side may serve (e.g. ctrl.local on the plant, plant.local on the controller)"
                );
            };
            let peer_names = peer.split(',').map(|n| n.trim().to_string()).collect();
            Security::Tls(TlsFiles { ca, cert, key, peer_names })
        };
        security.check(link.endpoint())?;
        Ok(Transport::Zenoh(link, security))
    }
    #[cfg(not(feature = "zenoh"))]
    {
        let _ = (listen, connect, sec);
        bail!("--transport zenoh: {BUILD_WITH_ZENOH}")
    }
}

/// `quic/127.0.0.1:PORT` (`tcp/…` if `insecure`) with a port that was free a moment ago (the
/// kernel's pick): where `companion hil --transport zenoh` lets its plant listen.
///
/// # Errors
/// No local TCP port can be bound.
pub fn free_local_endpoint(insecure: bool) -> Result<String> {
    let port = if insecure {
        let l = std::net::TcpListener::bind(("127.0.0.1", 0));
        l.and_then(|l| l.local_addr())
            .map_err(|e| anyhow::anyhow!("finding a free local TCP port: {e}"))?
            .port()
    } else {
        let s = std::net::UdpSocket::bind(("127.0.0.1", 0));
        s.and_then(|s| s.local_addr())
            .map_err(|e| anyhow::anyhow!("finding a free local UDP port: {e}"))?
            .port()
    };
    Ok(format!("{}/127.0.0.1:{port}", if insecure { "tcp" } else { "quic" }))
}

/// The transport that connects where `t` listens (`t` itself otherwise).
pub fn listen_to_connect(t: &Transport) -> Transport {
    match t {
        #[cfg(feature = "zenoh")]
        Transport::Zenoh(crate::transport::zenoh_link::ZenohLink::Listen(e), sec) => {
            Transport::Zenoh(crate::transport::zenoh_link::ZenohLink::Connect(e.clone()), sec.clone())
        }
        other => other.clone(),
    }
}

/// One side of the exchange on the chosen transport.
// One endpoint per process, on the loop's stack: a box would only add an indirection to
// every message (iceoryx2's ports are large, Zenoh's handles small).
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
pub enum Endpoint<Tx: Message, Rx: Message> {
    /// iceoryx2.
    Iceoryx2(ipc::Endpoint<Tx, Rx>),
    /// Zenoh.
    #[cfg(feature = "zenoh")]
    Zenoh(crate::transport::zenoh_link::ZenohEndpoint<Tx, Rx>),
}

/// The plant's endpoint.
pub type PlantEndpoint = Endpoint<MeasurementMsg, CommandMsg>;
/// The controller's endpoint.
pub type ControlEndpoint = Endpoint<CommandMsg, MeasurementMsg>;

/// Opens `role`'s side of demo `name` on `transport`; `events`: iceoryx2's event services
/// too (Zenoh always wakes a waiting receiver); `peer_timeout`: the loops' `--peer-timeout`
/// (over Zenoh's QUIC it sets the lease, [`crate::transport::zenoh_link::quic_lease`]).
///
/// # Errors
/// As [`ipc::Endpoint::open`] or [`crate::transport::zenoh_link::ZenohEndpoint::open`].
pub fn open<Tx: Message, Rx: Message>(
    transport: &Transport,
    name: &str,
    role: Role,
    events: bool,
    peer_timeout: Duration,
) -> Result<Endpoint<Tx, Rx>> {
    let what = if role == Role::Plant {
        "opening the plant's transport"
    } else {
        "opening the controller's transport"
    };
    #[cfg(not(feature = "zenoh"))]
    let _ = peer_timeout;
    match transport {
        Transport::Iceoryx2 => {
            Ok(Endpoint::Iceoryx2(anyhow::Context::context(ipc::Endpoint::open(name, role, events), what)?))
        }
        #[cfg(feature = "zenoh")]
        Transport::Zenoh(l, sec) => Ok(Endpoint::Zenoh(anyhow::Context::context(
            crate::transport::zenoh_link::ZenohEndpoint::open(name, role, l.clone(), sec, peer_timeout),
            what,
        )?)),
    }
}

impl<Tx: Message, Rx: Message> Endpoint<Tx, Rx> {
    /// Waits until the peer is there and hears us (at most `timeout`); `abort` is asked while
    /// waiting whether to give up.
    ///
    /// # Errors
    /// The timeout passed, a peer of another version waits, a second process of this role
    /// is on the demo (Zenoh), or `abort` said so.
    pub fn wait_for_peer(&self, timeout: Duration, abort: impl FnMut() -> Option<String>) -> Result<()> {
        match self {
            Self::Iceoryx2(e) => e.wait_for_peer(timeout, abort),
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => e.wait_for_peer(timeout, abort),
        }
    }

    /// Peers refused since the last call, each named and with the reason (Zenoh over TLS;
    /// iceoryx2 refuses nobody: only the same Unix user can open its shared memory).
    pub fn take_refusals(&self) -> Vec<String> {
        match self {
            Self::Iceoryx2(_) => Vec::new(),
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => e.take_refusals(),
        }
    }

    /// The last refusal so far, shown by [`Self::take_refusals`] or not.
    pub fn last_refusal(&self) -> Option<String> {
        match self {
            Self::Iceoryx2(_) => None,
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => e.last_refusal(),
        }
    }

    /// Peers refused so far, in all (0 on iceoryx2).
    pub fn refusals(&self) -> u64 {
        match self {
            Self::Iceoryx2(_) => 0,
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => e.refusals(),
        }
    }

    /// Waits (at most `max`) for the peer to leave after a last message.
    pub fn linger(&self, max: Duration) {
        match self {
            Self::Iceoryx2(e) => e.linger(max),
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => e.linger(max),
        }
    }

    /// Removes a dead peer's resources (iceoryx2's shared memory; nothing over Zenoh).
    pub fn cleanup_dead_nodes(&self) -> u64 {
        match self {
            Self::Iceoryx2(e) => e.cleanup_dead_nodes(),
            #[cfg(feature = "zenoh")]
            Self::Zenoh(_) => 0,
        }
    }

    /// Messages the transport dropped before the loop saw them: Zenoh payloads of the wrong
    /// size (iceoryx2 checks the type when the service is opened: 0).
    pub fn transport_malformed(&self) -> u64 {
        match self {
            Self::Iceoryx2(_) => 0,
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => e.malformed(),
        }
    }
}

impl<Tx: Message, Rx: Message> Link for Endpoint<Tx, Rx> {
    type Tx = Tx;
    type Rx = Rx;

    #[inline]
    fn publish(&mut self, msg: &Tx) -> Result<()> {
        match self {
            Self::Iceoryx2(e) => e.send(msg),
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => e.send(msg),
        }
    }

    #[inline]
    fn try_receive(&mut self) -> Result<Option<Rx>> {
        match self {
            Self::Iceoryx2(e) => e.try_receive(),
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => Ok(crate::transport::zenoh_link::ZenohEndpoint::try_receive(e)),
        }
    }

    #[inline]
    fn wait_event(&mut self, timeout: Duration) -> Result<()> {
        match self {
            Self::Iceoryx2(e) => e.wait_event(timeout),
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => {
                crate::transport::zenoh_link::ZenohEndpoint::wait_event(e, timeout);
                Ok(())
            }
        }
    }

    fn peer_state(&mut self) -> Result<PeerState> {
        match self {
            Self::Iceoryx2(e) => e.peer_state(),
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => Ok(crate::transport::zenoh_link::ZenohEndpoint::peer_state(e)),
        }
    }

    fn notifies(&self) -> bool {
        match self {
            Self::Iceoryx2(e) => e.notifies(),
            #[cfg(feature = "zenoh")]
            Self::Zenoh(_) => true,
        }
    }
}
