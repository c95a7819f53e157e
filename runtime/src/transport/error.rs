//! What goes wrong before the first message: choosing the transport from the flags, opening
//! one side's endpoint, meeting the peer ([`StartError`]; [`OpenError`] names the side). Once
//! the link runs, its errors are [`crate::transport::link::LinkError`].
//!
//! Every variant's text is the message the command line prints; [`name_in_use`] finds the
//! one error with an exit code of its own (5, [`NameInUse`]) wherever a layer put it.

use crate::sys::lock::{LockError, NameInUse, Role};
use crate::transport::wire::PROTOCOL_VERSION;

/// How this program was told to build when it lacks the Zenoh transport.
pub const BUILD_WITH_ZENOH: &str =
    "this companion was built without the Zenoh transport; rebuild it with `cargo build --release -p \
     companion-runtime --features zenoh` (or `cargo install --path runtime --features zenoh`)";

/// A peer of another protocol version is waiting on the same demo.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "protocol version mismatch: process {pid} waits on demo '{name}' with protocol version {version} (service \
     {service}); this program speaks version {PROTOCOL_VERSION} (services companion/{name}/v{PROTOCOL_VERSION}/…)"
)]
pub struct OtherVersion {
    /// The demo's name.
    pub name: String,
    /// The peer's version.
    pub version: u32,
    /// The service it opened.
    pub service: String,
    /// Its process id.
    pub pid: i32,
}

/// Why a transport could not be chosen, opened, or its peer met: everything that can go wrong
/// before the first message, in the words the command line prints.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// A process of this program already plays this role in the demo (exit 5).
    #[error(transparent)]
    NameInUse(#[from] NameInUse),
    /// A peer of another protocol version waits on the demo.
    #[error(transparent)]
    OtherVersion(#[from] OtherVersion),
    /// An iceoryx2 service of the demo exists with another payload type.
    #[error(
        "incompatible payload type on iceoryx2 service {service}: the peer created it with {theirs}; this \
         program (protocol version {PROTOCOL_VERSION}) uses {ours} and no user header"
    )]
    IncompatibleTypes {
        /// The service.
        service: String,
        /// The peer's payload type (name, size, alignment; its user header if any).
        theirs: String,
        /// This program's payload type.
        ours: String,
    },
    /// iceoryx2 failed to set up a node, a service or a port, or to list them.
    #[error("{what}: {cause}")]
    Iceoryx2 {
        /// What was being done (`creating iceoryx2 node`, `opening iceoryx2 service …`).
        what: String,
        /// iceoryx2's words.
        cause: String,
    },
    /// Zenoh failed to set up the session's configuration, a subscriber, a publisher or a
    /// token.
    #[error("{what}: {cause}")]
    Zenoh {
        /// What was being done (`zenoh config …`, `subscribing to …`).
        what: String,
        /// Zenoh's words.
        cause: String,
    },
    /// A listening side's Zenoh session could not open (the port taken, the address not this
    /// machine's, a TLS file zenoh refuses).
    #[error(
        "cannot listen on {endpoint}: {cause} (is the port in use, or the address not one of this machine's?)"
    )]
    Listen {
        /// The endpoint (`quic/HOST:PORT`).
        endpoint: String,
        /// Zenoh's words.
        cause: String,
    },
    /// A connecting side's Zenoh session could not open.
    #[error("cannot open a Zenoh session to {endpoint}: {cause}")]
    Connect {
        /// The endpoint (`quic/HOST:PORT`).
        endpoint: String,
        /// Zenoh's words.
        cause: String,
    },
    /// No peer joined within the start-up timeout; the message names the services or the
    /// endpoint, and what was heard meanwhile.
    #[error("{0}")]
    NoPeer(String),
    /// Waiting for the peer was given up: the caller's reason (e.g. the child process exited).
    #[error("{0}")]
    Aborted(String),
    /// SIGINT or SIGTERM arrived while waiting for the peer (`plant` or `control`).
    #[error("interrupted while waiting for the {0}")]
    Interrupted(&'static str),
    /// A malformed Zenoh endpoint (`--listen`, `--connect`): what is wrong and what is expected.
    #[error("{0}")]
    BadEndpoint(String),
    /// `--transport zenoh` with both `--listen` and `--connect`, or neither.
    #[error("{0}")]
    Endpoints(&'static str),
    /// A plain `tcp/` endpoint without `--insecure`.
    #[error(
        "{endpoint} is plain TCP: whoever reaches that port could drive the robot, and anyone on the path read \
         and alter its traffic. Use quic/{host}:{port} with --tls-ca, --tls-cert, --tls-key and --tls-peer \
         (make them with `companion certs --out DIR --hosts plant.local,ctrl.local`), or pass --insecure to \
         accept that risk"
    )]
    PlaintextRefused {
        /// The endpoint as given (`tcp/HOST:PORT`).
        endpoint: String,
        /// Its host.
        host: String,
        /// Its port.
        port: u16,
    },
    /// `--insecure` where it does not belong: with TLS flags, or with a TLS endpoint. The
    /// message says which to drop.
    #[error("{0}")]
    Insecure(String),
    /// A TLS flag is missing or empty; the message names it and what it gives.
    #[error("{0}")]
    TlsFlag(String),
    /// A TLS file given cannot be read.
    #[error("{flag} {}: cannot read it", path.display())]
    TlsFile {
        /// `--tls-ca`, `--tls-cert` or `--tls-key`.
        flag: &'static str,
        /// The file.
        path: std::path::PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// `--transport zenoh` in a build without the feature ([`BUILD_WITH_ZENOH`]).
    #[error("--transport zenoh: {BUILD_WITH_ZENOH}")]
    NoZenoh,
    /// No local port could be bound (`TCP` or `UDP`).
    #[error("finding a free local {protocol} port: {cause}")]
    NoFreePort {
        /// `TCP` or `UDP`.
        protocol: &'static str,
        /// The operating system's error.
        cause: std::io::Error,
    },
}

impl StartError {
    /// The demo found running, if that is the error.
    pub fn name_in_use(&self) -> Option<&NameInUse> {
        match self {
            Self::NameInUse(n) => Some(n),
            _ => None,
        }
    }
}

/// Opening one side's transport failed ([`crate::transport::open`],
/// [`crate::transport::ipc::PlantEndpoint::plant`],
/// [`crate::transport::ipc::ControlEndpoint::control`]): which side, and why.
#[derive(Debug, thiserror::Error)]
#[error("opening the {}'s transport", side(.role))]
pub struct OpenError {
    /// The side.
    pub role: Role,
    /// Why.
    #[source]
    pub cause: StartError,
}

/// `plant` or `controller`, as the messages name a side.
fn side(role: &Role) -> &'static str {
    match role {
        Role::Plant => "plant",
        Role::Control => "controller",
    }
}

/// The [`NameInUse`] that `e` is or carries (in a [`LockError`], a [`StartError`] or an
/// [`OpenError`], under any context), for the command line's exit code 5.
pub fn name_in_use<'a>(e: &'a (dyn std::error::Error + 'static)) -> Option<&'a NameInUse> {
    std::iter::successors(Some(e), |e| e.source()).find_map(|e| {
        e.downcast_ref::<NameInUse>()
            .or_else(|| e.downcast_ref::<LockError>().and_then(LockError::name_in_use))
            .or_else(|| e.downcast_ref::<StartError>().and_then(StartError::name_in_use))
            .or_else(|| e.downcast_ref::<OpenError>().and_then(|o| o.cause.name_in_use()))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn in_use() -> NameInUse {
        NameInUse { name: "d".into(), role: "plant", pid: 42 }
    }

    /// A caller's error with `e` as its source (as a context of the layers above adds).
    #[derive(Debug, thiserror::Error)]
    #[error("running the plant")]
    struct Above(#[source] OpenError);

    #[test]
    fn a_name_in_use_is_found_in_every_error_that_carries_it() {
        let n = in_use();
        assert_eq!(name_in_use(&n), Some(&n));
        let lock = LockError::from(in_use());
        assert_eq!(name_in_use(&lock), Some(&n));
        let start = StartError::from(in_use());
        assert_eq!((start.name_in_use(), name_in_use(&start)), (Some(&n), Some(&n)));
        let open = OpenError { role: Role::Plant, cause: StartError::from(in_use()) };
        assert_eq!(name_in_use(&open), Some(&n));
        assert_eq!(name_in_use(&Above(open)), Some(&n));
        // Others carry none.
        let other = OpenError { role: Role::Control, cause: StartError::NoZenoh };
        assert_eq!(name_in_use(&other), None);
    }

    #[test]
    fn an_open_error_names_the_side_and_keeps_its_cause() {
        let e = OpenError { role: Role::Plant, cause: StartError::from(in_use()) };
        assert_eq!(e.to_string(), "opening the plant's transport");
        let cause = std::error::Error::source(&e).map(ToString::to_string);
        assert_eq!(
            cause.as_deref(),
            Some("a demo named 'd' is already running (its plant is process 42); stop it or choose another --name")
        );
        let e = OpenError { role: Role::Control, cause: StartError::Interrupted("plant") };
        assert_eq!(e.to_string(), "opening the controller's transport");
        assert_eq!(e.cause.to_string(), "interrupted while waiting for the plant");
    }
}
