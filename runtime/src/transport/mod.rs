//! The transport layer: how the two HIL processes exchange the wire's messages.
//!
//! - [`wire`]: the two `#[repr(C)]` messages, the interface a hardware bridge implements;
//! - [`link`]: the transport as the loops see it ([`Link`], [`PeerState`], [`LinkError`]);
//! - [`error`]: what goes wrong before the first message ([`StartError`], [`OpenError`]);
//! - [`ipc`]: iceoryx2 shared memory on one machine (the default);
//! - `zenoh_link` (QUIC under mutual TLS across machines), `zenoh_log` (zenoh's refusals as
//!   messages) and `certs` (the deployment's certificates), with the cargo feature `zenoh`.
//!
//! This module's own items are `--transport`'s choice and the one endpoint type the two
//! processes open: iceoryx2 ([`ipc`]) or Zenoh (`zenoh_link`). Both carry the same wire
//! messages under the same policies; the loops see only [`Link`].
//!
//! Errors are typed: [`LinkError`] once the link runs (made only on failure: the hot path
//! neither allocates nor formats), [`StartError`] before the first message (choosing,
//! opening, meeting the peer), [`OpenError`] naming the side that failed to open.
//! [`name_in_use`] finds a [`NameInUse`](crate::sys::lock::NameInUse) in any of them, for the
//! command line's exit code 5.

#[cfg(feature = "zenoh")]
pub mod certs;
pub mod error;
pub mod ipc;
pub mod link;
#[cfg(feature = "ros2")]
pub mod ros2;
pub mod wire;
#[cfg(feature = "zenoh")]
pub mod zenoh_link;
#[cfg(feature = "zenoh")]
pub mod zenoh_log;

use std::time::Duration;

pub use error::{name_in_use, OpenError, StartError, BUILD_WITH_ZENOH};

use crate::sys::lock::{DemoName, Role};
use link::{Link, LinkError, PeerState};
use wire::{CommandMsg, MeasurementMsg, WireMessage};
use zerocopy::{FromBytes, Immutable, IntoBytes};

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
    /// under load (`zenoh_link::Scheme`, with the `zenoh` feature).
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
/// `--insecure`, a missing TLS flag, or a build without the feature ([`BUILD_WITH_ZENOH`]):
/// [`StartError::Endpoints`], [`StartError::BadEndpoint`], [`StartError::PlaintextRefused`],
/// [`StartError::Insecure`], [`StartError::TlsFlag`], [`StartError::TlsFile`],
/// [`StartError::NoZenoh`].
pub fn zenoh(
    listen: Option<&str>,
    connect: Option<&str>,
    sec: &SecurityFlags,
) -> Result<Transport, StartError> {
    #[cfg(feature = "zenoh")]
    {
        use crate::transport::zenoh_link::{Security, TcpEndpoint, TlsFiles, ZenohLink};
        let link = match (listen, connect) {
            (Some(l), None) => ZenohLink::Listen(TcpEndpoint::parse(l)?),
            (None, Some(c)) => ZenohLink::Connect(TcpEndpoint::parse(c)?),
            (Some(_), Some(_)) => {
                return Err(StartError::Endpoints("--transport zenoh: give --listen or --connect, not both"))
            }
            (None, None) => {
                return Err(StartError::Endpoints(
                    "--transport zenoh needs an endpoint: --listen quic/ADDR:PORT (usually the plant) or \
                     --connect quic/ADDR:PORT (usually the controller)",
                ))
            }
        };
        let tls_given = sec.ca.is_some() || sec.cert.is_some() || sec.key.is_some() || sec.peer.is_some();
        let security = if sec.insecure {
            if tls_given {
                return Err(StartError::Insecure(
                    "--insecure turns TLS off: drop it, or drop --tls-ca, --tls-cert, --tls-key and --tls-peer".into(),
                ));
            }
            Security::Insecure
        } else if link.endpoint().scheme == crate::transport::zenoh_link::Scheme::Tcp {
            return Err(crate::transport::zenoh_link::plaintext_refused(link.endpoint()));
        } else {
            let need = |v: &Option<std::path::PathBuf>, flag: &str, what: &str| {
                v.clone().ok_or_else(|| {
                    StartError::TlsFlag(format!(
                        "--transport zenoh over TLS needs {flag} FILE ({what}; `companion certs --out DIR --hosts \
                         plant.local,ctrl.local` makes them)"
                    ))
                })
            };
            let ca = need(&sec.ca, "--tls-ca", "the deployment's CA certificate, ca.pem")?;
            let cert = need(&sec.cert, "--tls-cert", "this host's certificate, HOST.pem")?;
            let key = need(&sec.key, "--tls-key", "this host's private key, HOST.key")?;
            let Some(peer) = &sec.peer else {
                return Err(StartError::TlsFlag(
                    "--transport zenoh over TLS needs --tls-peer NAME: the name on the certificate of the peer \
                     this side may serve (e.g. ctrl.local on the plant, plant.local on the controller)"
                        .into(),
                ));
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
        Err(StartError::NoZenoh)
    }
}

/// `quic/127.0.0.1:PORT` (`tcp/…` if `insecure`) with a port that was free a moment ago (the
/// kernel's pick): where `companion hil --transport zenoh` lets its plant listen.
///
/// # Errors
/// [`StartError::NoFreePort`]: no local port can be bound.
pub fn free_local_endpoint(insecure: bool) -> Result<String, StartError> {
    let port = if insecure {
        let l = std::net::TcpListener::bind(("127.0.0.1", 0));
        l.and_then(|l| l.local_addr())
            .map_err(|cause| StartError::NoFreePort { protocol: "TCP", cause })?
            .port()
    } else {
        let s = std::net::UdpSocket::bind(("127.0.0.1", 0));
        s.and_then(|s| s.local_addr())
            .map_err(|cause| StartError::NoFreePort { protocol: "UDP", cause })?
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
/// (over Zenoh's QUIC it sets the lease, `zenoh_link::quic_lease`).
///
/// # Errors
/// [`OpenError`], its cause as [`ipc::Endpoint::open`] or
/// `zenoh_link::ZenohEndpoint::open`.
pub fn open<Tx: Message, Rx: Message>(
    transport: &Transport,
    name: &DemoName,
    role: Role,
    events: bool,
    peer_timeout: Duration,
) -> Result<Endpoint<Tx, Rx>, OpenError> {
    #[cfg(not(feature = "zenoh"))]
    let _ = peer_timeout;
    let opened = match transport {
        Transport::Iceoryx2 => ipc::Endpoint::open(name, role, events).map(Endpoint::Iceoryx2),
        #[cfg(feature = "zenoh")]
        Transport::Zenoh(l, sec) => {
            crate::transport::zenoh_link::ZenohEndpoint::open(name, role, l.clone(), sec, peer_timeout)
                .map(Endpoint::Zenoh)
        }
    };
    opened.map_err(|cause| OpenError { role, cause })
}

impl<Tx: Message, Rx: Message> Endpoint<Tx, Rx> {
    /// Waits until the peer is there and hears us (at most `timeout`); `abort` is asked while
    /// waiting whether to give up.
    ///
    /// # Errors
    /// The timeout passed ([`StartError::NoPeer`]), a peer of another version waits
    /// ([`StartError::OtherVersion`]), a second process of this role is on the demo
    /// ([`StartError::NameInUse`], Zenoh), `abort` said so ([`StartError::Aborted`]), or a
    /// signal came ([`StartError::Interrupted`]).
    pub fn wait_for_peer(
        &self,
        timeout: Duration,
        abort: impl FnMut() -> Option<String>,
    ) -> Result<(), StartError> {
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

    /// What the transport counted of the messages sent and received (Zenoh; `None` on
    /// iceoryx2, [`link::LinkCounts`]).
    pub fn link_counts(&self) -> Option<link::LinkCounts> {
        match self {
            Self::Iceoryx2(_) => None,
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => Some(e.link_counts()),
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
    fn publish(&mut self, msg: &Tx) -> Result<(), LinkError> {
        match self {
            Self::Iceoryx2(e) => e.send(msg),
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => e.send(msg),
        }
    }

    #[inline]
    fn try_receive(&mut self) -> Result<Option<Rx>, LinkError> {
        match self {
            Self::Iceoryx2(e) => e.try_receive(),
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => Ok(crate::transport::zenoh_link::ZenohEndpoint::try_receive(e)),
        }
    }

    #[inline]
    fn wait_event(&mut self, timeout: Duration) -> Result<(), LinkError> {
        match self {
            Self::Iceoryx2(e) => e.wait_event(timeout),
            #[cfg(feature = "zenoh")]
            Self::Zenoh(e) => {
                crate::transport::zenoh_link::ZenohEndpoint::wait_event(e, timeout);
                Ok(())
            }
        }
    }

    fn peer_state(&mut self) -> Result<PeerState, LinkError> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_process_of_a_role_is_a_name_in_use() {
        let name = DemoName::new(&format!("starterr-{}", std::process::id())).unwrap();
        let first = ipc::PlantEndpoint::plant(&name, false).unwrap();
        let own = i32::try_from(std::process::id()).unwrap();
        let e = ipc::PlantEndpoint::plant(&name, false).unwrap_err();
        let StartError::NameInUse(n) = &e.cause else { panic!("not NameInUse: {e}: {}", e.cause) };
        assert_eq!((n.name.as_str(), n.role, n.pid), (name.as_str(), "plant", own));
        assert_eq!(e.role, Role::Plant);
        let cfg = ipc::config().unwrap();
        let e = ipc::ensure_name_free(&cfg, &name, Role::Plant).unwrap_err();
        assert_eq!(e.name_in_use().map(|n| n.pid), Some(own));
        assert!(ipc::ensure_name_free(&cfg, &name, Role::Control).is_ok());
        drop(first);
    }

    #[cfg(not(feature = "zenoh"))]
    #[test]
    fn zenoh_without_the_feature_says_how_to_build_it() {
        let e = zenoh(Some("quic/127.0.0.1:7447"), None, &SecurityFlags::default()).unwrap_err();
        assert!(matches!(e, StartError::NoZenoh), "{e}");
        assert_eq!(e.to_string(), format!("--transport zenoh: {BUILD_WITH_ZENOH}"));
    }

    #[cfg(feature = "zenoh")]
    #[test]
    fn zenoh_flags_give_their_variants() {
        let none = SecurityFlags::default();
        let e = zenoh(Some("tcp/127.0.0.1:7447"), None, &none).unwrap_err();
        assert!(
            matches!(&e, StartError::PlaintextRefused { endpoint, host, port: 7447 }
                if endpoint == "tcp/127.0.0.1:7447" && host == "127.0.0.1"),
            "{e}"
        );
        assert_eq!(
            e.to_string(),
            "tcp/127.0.0.1:7447 is plain TCP: whoever reaches that port could drive the robot, and anyone on the \
             path read and alter its traffic. Use quic/127.0.0.1:7447 with --tls-ca, --tls-cert, --tls-key and \
             --tls-peer (make them with `companion certs --out DIR --hosts plant.local,ctrl.local`), or pass \
             --insecure to accept that risk"
        );
        let insecure = SecurityFlags { insecure: true, ..SecurityFlags::default() };
        assert!(matches!(zenoh(Some("tcp/127.0.0.1:7447"), None, &insecure), Ok(Transport::Zenoh(..))));
        let e = zenoh(Some("quic/h:1"), Some("quic/h:2"), &none).unwrap_err();
        assert_eq!(e.to_string(), "--transport zenoh: give --listen or --connect, not both");
        assert!(matches!(e, StartError::Endpoints(_)));
        assert!(matches!(zenoh(None, None, &none), Err(StartError::Endpoints(_))));
        let e = zenoh(None, Some("quic/h"), &none).unwrap_err();
        assert!(matches!(&e, StartError::BadEndpoint(m) if m.contains("no port")), "{e}");
        let e = zenoh(None, Some("quic/h:1"), &none).unwrap_err();
        assert!(matches!(&e, StartError::TlsFlag(m) if m.contains("--tls-ca FILE")), "{e}");
        let both = SecurityFlags { insecure: true, peer: Some("ctrl".into()), ..SecurityFlags::default() };
        let e = zenoh(None, Some("tcp/h:1"), &both).unwrap_err();
        assert!(matches!(&e, StartError::Insecure(m) if m.starts_with("--insecure turns TLS off")), "{e}");
        let e = zenoh(None, Some("quic/h:1"), &insecure).unwrap_err();
        assert_eq!(e.to_string(), "--insecure is for plain tcp/ endpoints; quic/h:1 is TLS: drop --insecure");
    }
}
