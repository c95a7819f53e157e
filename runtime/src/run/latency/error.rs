//! Why `companion latency` (or its hidden `latency-peer`) failed: a part's scenario, a
//! transport, a child process, a file, or a peer that stopped answering. Every variant's text
//! is the message the command line prints.

use std::path::PathBuf;
use std::process::ExitStatus;

use crate::domain::plant_setup::PlantSetupError;
use crate::domain::scenario::ScenarioError;
use crate::sys::lock::NameError;
#[cfg(feature = "zenoh")]
use crate::transport::certs::CertsError;
use crate::transport::error::{OpenError, StartError};
use crate::transport::link::LinkError;

/// Why a latency measurement failed.
#[derive(Debug, thiserror::Error)]
pub enum LatencyError {
    /// `--cycles 0`.
    #[error("--cycles must be at least 1")]
    NoCycles,
    /// A flag the peer's transport needs is missing (the message names it).
    #[error("{0}")]
    MissingFlag(&'static str),
    /// `--transport zenoh` in a build without the feature.
    #[error("{}", crate::transport::BUILD_WITH_ZENOH)]
    NoZenoh,
    /// `--transport dds` in a build without the `ros2` feature.
    #[error("the DDS ping-pong needs a build with --features ros2")]
    NoDds,
    /// The DDS ping-pong's participant, topics or samples (RustDDS's message).
    #[error("DDS ping-pong: {0}")]
    Dds(String),
    /// A demo name made of this process's id is too long (a pid of 7 digits).
    #[error(transparent)]
    Name(#[from] NameError),
    /// The scenario of part (1) cannot be built.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The plant of part (1) cannot be built.
    #[error(transparent)]
    Setup(#[from] PlantSetupError),
    /// A transport cannot be opened.
    #[error(transparent)]
    Open(#[from] OpenError),
    /// A transport cannot be chosen, or its peer met.
    #[error(transparent)]
    Start(#[from] StartError),
    /// A transport failed while running.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The test certificates cannot be made.
    #[cfg(feature = "zenoh")]
    #[error(transparent)]
    Certs(#[from] CertsError),
    /// An operating system call failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// An operating system call failed while doing `what` (a socket, a thread, a file, a
    /// child process).
    #[error("{what}")]
    Os {
        /// What was being done.
        what: String,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A file cannot be read as JSON.
    #[error("reading {}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// The decoder's error.
        #[source]
        source: serde_json::Error,
    },
    /// The benchmark's figures cannot be put as JSON.
    #[error(transparent)]
    Serialize(serde_json::Error),
    /// A `companion hil` run of part (4) failed.
    #[error("companion hil --wait {mode} failed ({status}); see {}", log.display())]
    HilFailed {
        /// Its wait mode.
        mode: &'static str,
        /// Its exit status.
        status: ExitStatus,
        /// Its log.
        log: PathBuf,
    },
    /// A HIL run's deadline is not the one the bare transport's misses were counted against.
    #[error("the HIL run's deadline is {hil_ns} ns, the transport's count is against {transport_ns} ns")]
    DeadlineMismatch {
        /// The HIL run's (ns).
        hil_ns: u64,
        /// The transport's count's (ns).
        transport_ns: u64,
    },
    /// The peer's parent, the benchmark, is gone.
    #[error("the benchmark process is gone")]
    BenchmarkGone,
    /// The ping-pong peer stopped answering.
    #[error("the {transport} ping-pong peer stopped answering at iteration {iteration}")]
    PeerStopped {
        /// `iceoryx2` or `Zenoh`.
        transport: &'static str,
        /// The iteration.
        iteration: u64,
    },
    /// The socket peer received a datagram of another size.
    #[error("peer received {0} bytes")]
    PeerReceived(usize),
    /// The benchmark received a datagram of another size.
    #[error("received {0} bytes")]
    Received(usize),
    /// The socket peer's first datagram is not its greeting.
    #[error("unexpected greeting from the socket peer")]
    Greeting,
    /// `ip` (network namespaces) cannot run or failed.
    #[error("ip {args}: {cause}")]
    Ip {
        /// Its arguments.
        args: String,
        /// Why.
        cause: String,
    },
    /// No free port on an address.
    #[error("a free port on {here}: {cause}")]
    FreePort {
        /// The address.
        here: String,
        /// The operating system's error.
        cause: std::io::Error,
    },
    /// No Zenoh session opened within 10 s.
    #[error("no session to {endpoint} within 10 s")]
    NoSession {
        /// The endpoint.
        endpoint: String,
    },
}

/// `what` (made only on failure) around an operating system error.
pub(super) fn os(what: impl FnOnce() -> String) -> impl FnOnce(std::io::Error) -> LatencyError {
    move |source| LatencyError::Os { what: what(), source }
}
