//! The iceoryx2 transport of the HIL loop: names, service settings, one endpoint per role, and
//! peer liveness.
//!
//! ## Names
//!
//! All resources live under the project's iceoryx2 prefix [`PREFIX`] (files
//! `/tmp/iceoryx2/…companion_…` and `/dev/shm/companion_…`), so that other iceoryx2 programs on
//! the machine neither see nor clean them. A demo named `N` (`--name`, default `demo`) uses:
//!
//! | service | pattern | from → to | payload |
//! |---|---|---|---|
//! | `companion/N/measurement` | publish–subscribe | plant → controller | [`MeasurementMsg`] |
//! | `companion/N/command` | publish–subscribe | controller → plant | [`CommandMsg`] |
//! | `companion/N/measurement-ready` | event (`--wait event` only) | plant → controller | — |
//! | `companion/N/command-ready` | event (`--wait event` only) | controller → plant | — |
//!
//! and nodes named `N/plant` and `N/control`. Publish–subscribe settings: one publisher, one
//! subscriber, no history, a subscriber buffer of [`BUFFER`] samples with safe overflow (the
//! oldest sample is replaced: a slow reader finds the newest ones, a writer never blocks).
//!
//! Two demos with different names never share anything. A second demo with the *same* name
//! finds the first one's node alive and stops with [`NameInUse`] (and if two start at the same
//! instant, the one-publisher limit refuses the second with the same error).
//!
//! ## Liveness
//!
//! A dead peer is not an error for iceoryx2: `send` still succeeds. Each side therefore
//! watches for silence (no message within a timeout) and then asks [`Endpoint::peer_state`],
//! which lists the nodes: a process that died holds no lock on its node's monitor any more and
//! is reported [`PeerState::Dead`] at once. [`Endpoint::cleanup_dead_nodes`] then removes its
//! shared memory, so that the next run starts clean (creating a node also cleans dead nodes).

use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use iceoryx2::node::NodeView;
use iceoryx2::port::listener::{Listener, ListenerWaitError};
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::{Publisher, PublisherCreateError};
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

use crate::link::{Link, PeerState};
use crate::wire::{CommandMsg, MeasurementMsg};

/// The iceoryx2 prefix of every file and shared-memory segment of this project.
pub const PREFIX: &[u8] = b"companion_";

/// The subscriber buffer (samples) of both services.
pub const BUFFER: usize = 4;

/// The two roles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Publishes measurements, subscribes to commands.
    Plant,
    /// Publishes commands, subscribes to measurements.
    Control,
}

impl Role {
    /// `plant` or `control`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Plant => "plant",
            Self::Control => "control",
        }
    }

    /// The other role.
    pub fn peer(self) -> Self {
        match self {
            Self::Plant => Self::Control,
            Self::Control => Self::Plant,
        }
    }
}

/// A demo with this name is already running.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "a demo named '{name}' is already running (its {role} is process {pid}); stop it or choose another --name"
)]
pub struct NameInUse {
    /// The demo's name.
    pub name: String,
    /// The role found alive.
    pub role: &'static str,
    /// Its process id (0 if unknown).
    pub pid: i32,
}

/// Checks a demo name: 1–32 characters of `A–Z a–z 0–9 _ -`.
///
/// # Errors
/// The name is empty, too long, or has another character.
pub fn validate_name(name: &str) -> Result<()> {
    let ok = !name.is_empty()
        && name.len() <= 32
        && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-');
    if ok {
        Ok(())
    } else {
        Err(anyhow!("--name must be 1 to 32 characters of A-Z, a-z, 0-9, '_' and '-', got {name:?}"))
    }
}

/// The iceoryx2 configuration of this project: the global one with [`PREFIX`].
///
/// # Errors
/// The prefix is not a valid file name (never, it is a constant).
pub fn config() -> Result<Config> {
    let mut cfg = Config::global_config().clone();
    cfg.global.prefix = FileName::new(PREFIX).map_err(|e| anyhow!("iceoryx2 prefix: {e:?}"))?;
    Ok(cfg)
}

/// Silences iceoryx2's own log (expected failures, such as a refused second publisher, are
/// reported by this program in plain words) unless `IOX2_LOG_LEVEL` says otherwise.
pub fn quiet_logs() {
    set_log_level_from_env_or(LogLevel::Fatal);
}

fn node_name(name: &str, role: Role) -> String {
    format!("{name}/{}", role.as_str())
}

/// Finds the node of `role` in demo `name`.
///
/// # Errors
/// The node list cannot be read.
pub fn find_node(cfg: &Config, name: &str, role: Role) -> Result<PeerState> {
    let want = node_name(name, role);
    let own = std::process::id();
    let mut found = PeerState::Absent;
    Node::<ipc::Service>::list(cfg, |state| {
        let (details, alive) = match &state {
            NodeState::Alive(v) => (v.details().clone(), true),
            NodeState::Dead(v) => (v.details().clone(), false),
            NodeState::Inaccessible(_) | NodeState::Undefined(_) => (None, false),
        };
        if let Some(d) = details {
            let pid = d.process_id().value();
            #[allow(clippy::cast_sign_loss)]
            let is_self = pid as u32 == own;
            if d.name().as_str() == want && !is_self {
                found = if alive { PeerState::Alive(pid) } else { PeerState::Dead(pid) };
                if alive {
                    return CallbackProgression::Stop;
                }
            }
        }
        CallbackProgression::Continue
    })
    .map_err(|e| anyhow!("listing iceoryx2 nodes: {e:?}"))?;
    Ok(found)
}

/// Fails with [`NameInUse`] if a live process already plays `role` in demo `name`.
///
/// # Errors
/// [`NameInUse`], or the node list cannot be read.
pub fn ensure_name_free(cfg: &Config, name: &str, role: Role) -> Result<()> {
    if let PeerState::Alive(pid) = find_node(cfg, name, role)? {
        return Err(NameInUse { name: name.to_string(), role: role.as_str(), pid }.into());
    }
    Ok(())
}

/// One side of the exchange: a node, a publisher of `Tx`, a subscriber of `Rx`, and (in event
/// mode) a notifier and a listener.
pub struct Endpoint<
    Tx: std::fmt::Debug + ZeroCopySend + 'static,
    Rx: std::fmt::Debug + ZeroCopySend + 'static,
> {
    name: String,
    role: Role,
    cfg: Config,
    node: Node<ipc::Service>,
    tx_service: iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, Tx, ()>,
    rx_service: iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, Rx, ()>,
    publisher: Publisher<ipc::Service, Tx, ()>,
    subscriber: Subscriber<ipc::Service, Rx, ()>,
    notifier: Option<Notifier<ipc::Service>>,
    listener: Option<Listener<ipc::Service>>,
}

impl<Tx, Rx> std::fmt::Debug for Endpoint<Tx, Rx>
where
    Tx: std::fmt::Debug + ZeroCopySend + 'static,
    Rx: std::fmt::Debug + ZeroCopySend + 'static,
{
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Endpoint").field("name", &self.name).field("role", &self.role).finish_non_exhaustive()
    }
}

/// The plant's endpoint.
pub type PlantEndpoint = Endpoint<MeasurementMsg, CommandMsg>;
/// The controller's endpoint.
pub type ControlEndpoint = Endpoint<CommandMsg, MeasurementMsg>;

fn service_name(name: &str, what: &str) -> Result<ServiceName> {
    ServiceName::new(&format!("companion/{name}/{what}")).map_err(|e| anyhow!("service name: {e:?}"))
}

fn pubsub<T: std::fmt::Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    name: &str,
    what: &str,
) -> Result<iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()>> {
    let sn = service_name(name, what)?;
    // Creation can race with the peer creating the same service: retry briefly.
    let start = Instant::now();
    loop {
        let r = node
            .service_builder(&sn)
            .publish_subscribe::<T>()
            .max_publishers(1)
            .max_subscribers(1)
            .history_size(0)
            .subscriber_max_buffer_size(BUFFER)
            .enable_safe_overflow(true)
            .open_or_create();
        match r {
            Ok(s) => return Ok(s),
            Err(e) if start.elapsed() < Duration::from_secs(2) => {
                let _ = e;
                std::thread::sleep(Duration::from_millis(5));
            }
            Err(e) => return Err(anyhow!("opening iceoryx2 service {sn}: {e:?}")),
        }
    }
}

fn event(
    node: &Node<ipc::Service>,
    name: &str,
    what: &str,
) -> Result<iceoryx2::service::port_factory::event::PortFactory<ipc::Service>> {
    let sn = service_name(name, what)?;
    let start = Instant::now();
    loop {
        match node.service_builder(&sn).event().max_notifiers(1).max_listeners(1).open_or_create() {
            Ok(s) => return Ok(s),
            Err(e) if start.elapsed() < Duration::from_secs(2) => {
                let _ = e;
                std::thread::sleep(Duration::from_millis(5));
            }
            Err(e) => return Err(anyhow!("opening iceoryx2 event service {sn}: {e:?}")),
        }
    }
}

impl<Tx, Rx> Endpoint<Tx, Rx>
where
    Tx: std::fmt::Debug + ZeroCopySend + Copy + 'static,
    Rx: std::fmt::Debug + ZeroCopySend + Copy + 'static,
{
    /// Opens `role`'s side of demo `name`: checks that the name is free, creates the node (which
    /// also cleans the resources of dead nodes), the services and the ports.
    ///
    /// # Errors
    /// [`NameInUse`], or an iceoryx2 failure.
    pub fn open(name: &str, role: Role, tx: &str, rx: &str, events: bool) -> Result<Self> {
        validate_name(name)?;
        let cfg = config()?;
        ensure_name_free(&cfg, name, role)?;
        let node_name = NodeName::new(&node_name(name, role)).map_err(|e| anyhow!("node name: {e:?}"))?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .config(&cfg)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| anyhow!("creating iceoryx2 node: {e:?}"))?;
        let tx_service = pubsub::<Tx>(&node, name, tx)?;
        let rx_service = pubsub::<Rx>(&node, name, rx)?;
        let in_use = || -> anyhow::Error {
            let pid = match find_node(&cfg, name, role) {
                Ok(PeerState::Alive(p)) => p,
                _ => 0,
            };
            NameInUse { name: name.to_string(), role: role.as_str(), pid }.into()
        };
        let publisher = match tx_service.publisher_builder().create() {
            Ok(p) => p,
            Err(PublisherCreateError::ExceedsMaxSupportedPublishers) => return Err(in_use()),
            Err(e) => return Err(anyhow!("creating publisher on {tx}: {e:?}")),
        };
        let subscriber = match rx_service.subscriber_builder().buffer_size(BUFFER).create() {
            Ok(s) => s,
            Err(iceoryx2::port::subscriber::SubscriberCreateError::ExceedsMaxSupportedSubscribers) => {
                return Err(in_use())
            }
            Err(e) => return Err(anyhow!("creating subscriber on {rx}: {e:?}")),
        };
        let (notifier, listener) = if events {
            let tx_ev = event(&node, name, &format!("{tx}-ready"))?;
            let rx_ev = event(&node, name, &format!("{rx}-ready"))?;
            let n = tx_ev.notifier_builder().create().map_err(|e| anyhow!("creating notifier: {e:?}"))?;
            let l = rx_ev.listener_builder().create().map_err(|e| anyhow!("creating listener: {e:?}"))?;
            (Some(n), Some(l))
        } else {
            (None, None)
        };
        Ok(Self {
            name: name.to_string(),
            role,
            cfg,
            node,
            tx_service,
            rx_service,
            publisher,
            subscriber,
            notifier,
            listener,
        })
    }

    /// Publishes one message (zero copy: loan, write, send), then notifies in event mode.
    ///
    /// # Errors
    /// An iceoryx2 failure.
    #[inline]
    pub fn send(&self, msg: &Tx) -> Result<()> {
        let sample = self.publisher.loan_uninit().map_err(|e| anyhow!("loan: {e:?}"))?;
        sample.write_payload(*msg).send().map_err(|e| anyhow!("send: {e:?}"))?;
        if let Some(n) = &self.notifier {
            n.notify().map_err(|e| anyhow!("notify: {e:?}"))?;
        }
        Ok(())
    }

    /// Takes the oldest waiting message, if any.
    ///
    /// # Errors
    /// An iceoryx2 failure.
    #[inline]
    pub fn try_receive(&self) -> Result<Option<Rx>> {
        match self.subscriber.receive() {
            Ok(Some(s)) => Ok(Some(*s.payload())),
            Ok(None) => Ok(None),
            Err(e) => Err(anyhow!("receive: {e:?}")),
        }
    }

    /// In event mode: sleeps until the peer notifies or `timeout` passes (never unbounded),
    /// draining all pending notifications. Without events: returns at once.
    ///
    /// # Errors
    /// An iceoryx2 failure.
    #[inline]
    pub fn wait_event(&self, timeout: Duration) -> Result<()> {
        if let Some(l) = &self.listener {
            match l.timed_wait(|_| {}, timeout) {
                // A signal (SIGSTOP/SIGCONT, SIGINT) ended the wait early: the caller re-checks.
                Ok(_) | Err(ListenerWaitError::InterruptSignal) => {}
                Err(e) => return Err(anyhow!("timed_wait: {e:?}")),
            }
        }
        Ok(())
    }

    /// Whether the peer's ports are connected: our publisher has its subscriber and our
    /// subscriber its publisher (the first message is lost otherwise, with no history).
    pub fn peer_connected(&self) -> bool {
        self.tx_service.dynamic_config().number_of_subscribers() >= 1
            && self.rx_service.dynamic_config().number_of_publishers() >= 1
    }

    /// Waits until [`Endpoint::peer_connected`], polling every millisecond; `abort` is asked
    /// each time whether to give up (e.g. the child process exited).
    ///
    /// # Errors
    /// The timeout passed or `abort` said so.
    pub fn wait_for_peer(&self, timeout: Duration, mut abort: impl FnMut() -> Option<String>) -> Result<()> {
        let start = Instant::now();
        while !self.peer_connected() {
            if let Some(why) = abort() {
                return Err(anyhow!("{why}"));
            }
            if crate::signals::termination_requested() {
                return Err(anyhow!("interrupted while waiting for the {}", self.role.peer().as_str()));
            }
            if start.elapsed() > timeout {
                return Err(anyhow!(
                    "no {} joined demo '{}' within {:.0} s",
                    self.role.peer().as_str(),
                    self.name,
                    timeout.as_secs_f64()
                ));
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        Ok(())
    }

    /// The peer's state, from the node list (a few file-system calls: call it only when the
    /// peer has been silent).
    ///
    /// # Errors
    /// The node list cannot be read.
    pub fn peer_state(&self) -> Result<PeerState> {
        find_node(&self.cfg, &self.name, self.role.peer())
    }

    /// Removes the resources of dead nodes (a dead peer's shared memory). Returns how many
    /// nodes were cleaned.
    pub fn cleanup_dead_nodes(&self) -> u64 {
        self.node.try_cleanup_dead_nodes().cleanups
    }
}

impl<Tx, Rx> Link for Endpoint<Tx, Rx>
where
    Tx: std::fmt::Debug + ZeroCopySend + Copy + 'static,
    Rx: std::fmt::Debug + ZeroCopySend + Copy + 'static,
{
    type Tx = Tx;
    type Rx = Rx;

    #[inline]
    fn publish(&mut self, msg: &Tx) -> Result<()> {
        self.send(msg)
    }

    #[inline]
    fn try_receive(&mut self) -> Result<Option<Rx>> {
        Endpoint::try_receive(self)
    }

    #[inline]
    fn wait_event(&mut self, timeout: Duration) -> Result<()> {
        Endpoint::wait_event(self, timeout)
    }

    fn peer_state(&mut self) -> Result<PeerState> {
        Endpoint::peer_state(self)
    }
}

impl PlantEndpoint {
    /// The plant's side of demo `name`.
    ///
    /// # Errors
    /// As [`Endpoint::open`].
    pub fn plant(name: &str, events: bool) -> Result<Self> {
        Self::open(name, Role::Plant, "measurement", "command", events)
            .context("opening the plant's transport")
    }
}

impl ControlEndpoint {
    /// The controller's side of demo `name`.
    ///
    /// # Errors
    /// As [`Endpoint::open`].
    pub fn control(name: &str, events: bool) -> Result<Self> {
        Self::open(name, Role::Control, "command", "measurement", events)
            .context("opening the controller's transport")
    }
}

/// A random 64-bit session id (time and process id mixed; never 0).
pub fn new_session_id() -> u64 {
    let t = crate::rt::monotonic_ns();
    let wall = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos() & u128::from(u64::MAX)).unwrap_or(0));
    let mut h = crate::wire::fnv1a(&t.to_le_bytes()) ^ wall.rotate_left(17) ^ u64::from(std::process::id());
    h ^= h >> 33;
    h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
    h ^= h >> 33;
    h.max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_checked() {
        assert!(validate_name("demo").is_ok());
        assert!(validate_name("a_b-9").is_ok());
        assert!(validate_name("").is_err());
        assert!(validate_name("a/b").is_err());
        assert!(validate_name(&"x".repeat(33)).is_err());
    }

    #[test]
    fn session_ids_differ() {
        let a = new_session_id();
        let b = new_session_id();
        assert_ne!(a, 0);
        assert_ne!(a, b);
    }
}
