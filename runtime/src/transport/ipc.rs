//! The iceoryx2 transport of the HIL loop: names, service settings, one endpoint per role,
//! peer liveness, and the checks that make a mismatched peer a clear error.
//!
//! `docs/book/src/bridge.md` in the repository is the protocol as a bridge author reads it; this is
//! its implementation for both roles.
//!
//! ## Names
//!
//! All resources live under iceoryx2's `global.prefix` [`PREFIX`] (`companion_`; files
//! `/tmp/iceoryx2/…` and `/dev/shm/companion_…`), so that programs with the default prefix
//! (`iox2_`) neither see nor clean them. A demo named `N` (`--name`, default `demo`) uses,
//! for protocol version 4:
//!
//! | service | pattern | from → to | payload |
//! |---|---|---|---|
//! | `companion/N/v4/measurement` | publish–subscribe | plant → controller | [`MeasurementMsg`] |
//! | `companion/N/v4/command` | publish–subscribe | controller → plant | [`CommandMsg`] |
//! | `companion/N/v4/measurement-ready` | event | plant → controller | — |
//! | `companion/N/v4/command-ready` | event | controller → plant | — |
//!
//! The version in the names keeps peers of different versions apart; while waiting for its
//! peer each side looks for a peer of another version on the same demo and names it
//! ([`OtherVersion`]).
//!
//! ## Settings
//!
//! Whoever comes first creates a publish–subscribe service with one publisher, one
//! subscriber, no history, a subscriber buffer of [`BUFFER`] samples and safe overflow (the
//! oldest sample is replaced: a slow reader finds the newest, a writer never blocks); event
//! services with iceoryx2's defaults. The second **opens without requirements** and adapts:
//! its subscriber buffer is at most the service's, its publisher discards rather than blocks
//! on a full buffer. So a bridge that created the services with iceoryx2's defaults (or any
//! other settings) is served. Only the payload type must match (name, size, alignment, and
//! the empty user header); if it does not, the error names both types
//! ([`incompatible_types`]).
//!
//! ## Liveness
//!
//! A dead peer is not an error for iceoryx2: `send` still succeeds. Each side therefore
//! watches for silence (no message within a timeout) and then asks
//! [`Endpoint::peer_state`]: the peer is the node that published the last received sample
//! (iceoryx2's sample header names it), or before the first sample the node of the
//! subscribed service's publisher. Its state comes from iceoryx2's node list: a process that
//! died is reported [`PeerState::Dead`] at once, a node that was removed [`PeerState::Absent`].
//! Nothing depends on node names. [`Endpoint::cleanup_dead_nodes`] then removes that dead
//! peer's shared memory, and the next run of the same name removes what its dead processes
//! left ([`remove_dead_nodes_of_demo`]). No process of this project removes another demo's dead
//! nodes: iceoryx2's clean-up of every dead node whenever a node is created or dropped is off
//! ([`config`]), since it let a third process erase a just-killed peer before its partner looked
//! (the partner then reported a death as a clean leave).
//!
//! The project's own processes name their nodes `N/plant` and `N/control`, and a second demo
//! with the *same* name finds the first one's node alive and stops with [`NameInUse`]; a
//! second publisher on a service (whatever its node's name) is refused the same way.

use std::time::{Duration, Instant};

use iceoryx2::identifiers::UniqueNodeId;
use iceoryx2::node::NodeView;
use iceoryx2::port::listener::{Listener, ListenerWaitError};
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::{Publisher, PublisherCreateError};
use iceoryx2::port::subscriber::{Subscriber, SubscriberCreateError};
use iceoryx2::prelude::*;
use iceoryx2::service::builder::event::{EventCreateError, EventOpenError};
use iceoryx2::service::builder::publish_subscribe::{PublishSubscribeCreateError, PublishSubscribeOpenError};
use iceoryx2::service::port_factory::{event as event_factory, publish_subscribe as pubsub_factory};
use iceoryx2::service::static_config::message_type_details::TypeDetail;
use iceoryx2::service::static_config::messaging_pattern::MessagingPattern as StaticPattern;

use crate::sys::lock::{DemoName, NameInUse, Role};
pub use crate::transport::error::OtherVersion;
use crate::transport::error::{OpenError, StartError};
use crate::transport::link::{Link, LinkError, PeerState};
use crate::transport::wire::{CommandMsg, MeasurementMsg, WireMessage, PROTOCOL_VERSION};

/// iceoryx2's `global.prefix` for every file and shared-memory segment of this project.
pub const PREFIX: &[u8] = b"companion_";

/// The subscriber buffer (samples) of the services this program creates.
pub const BUFFER: usize = 4;

/// How long creating or opening a service is retried while the peer creates it.
const OPEN_RETRY: Duration = Duration::from_secs(2);

/// How often a waiting side looks for a peer of another protocol version.
const VERSION_SCAN_EVERY: Duration = Duration::from_millis(200);

/// The service `role` publishes on and the one it subscribes to.
fn services(role: Role) -> (&'static str, &'static str) {
    match role {
        Role::Plant => ("measurement", "command"),
        Role::Control => ("command", "measurement"),
    }
}

/// The iceoryx2 configuration of this project: the global one with `global.prefix` =
/// [`PREFIX`].
///
/// # Errors
/// [`StartError::Iceoryx2`]: the prefix is not a valid file name (never, it is a constant).
///
/// iceoryx2's implicit clean-up of *every* dead node of the prefix, whenever any node is
/// created or dropped, is turned off: it let any other process of this project (another demo,
/// a test beside it) remove a peer that had just been killed before its own partner looked,
/// and the partner then said "left" for a process that died. Each side removes only what is
/// its demo's: the dead peer it found ([`Endpoint::cleanup_dead_nodes`]) and, at start-up, the
/// dead nodes an earlier run of the same name left ([`remove_dead_nodes_of_demo`]).
pub fn config() -> Result<Config, StartError> {
    let mut cfg = Config::global_config().clone();
    cfg.global.prefix = FileName::new(PREFIX).map_err(|e| iceoryx2_error("iceoryx2 prefix", e))?;
    cfg.global.node.cleanup_dead_nodes_on_creation = false;
    cfg.global.node.cleanup_dead_nodes_on_destruction = false;
    Ok(cfg)
}

/// Removes the resources of the dead nodes that `pick` selects by id; returns how many were
/// removed. (Listed first, removed after the list: removing inside iceoryx2's iteration would
/// change the folder it walks.)
fn remove_dead_nodes(cfg: &Config, mut pick: impl FnMut(&UniqueNodeId, &str) -> bool) -> u64 {
    let mut dead = Vec::new();
    let _ = Node::<ipc::Service>::list(cfg, |state| {
        if let NodeState::Dead(v) = state {
            let name = v.details().as_ref().map(|d| d.name().to_string()).unwrap_or_default();
            if pick(v.id(), &name) {
                dead.push(v);
            }
        }
        CallbackProgression::Continue
    });
    dead.into_iter().map(|v| u64::from(v.try_remove_stale_resources().is_ok())).sum()
}

/// Removes what dead processes of demo `name` left: nodes named `NAME/plant` or
/// `NAME/control`, and any other dead node attached to a service `companion/NAME/…` (a
/// bridge's node has no particular name). Other demos' residue is theirs to remove. Returns
/// how many nodes were removed.
pub fn remove_dead_nodes_of_demo(cfg: &Config, name: &str) -> u64 {
    let base = format!("companion/{name}/");
    let mut attached = Vec::new();
    let _ = ipc::Service::list(cfg, |details| {
        if details.static_details.name().as_str().starts_with(&base) {
            if let Some(d) = &details.dynamic_details {
                attached.extend(d.nodes.iter().filter_map(|n| match n {
                    NodeState::Dead(v) => Some(*v.id()),
                    _ => None,
                }));
            }
        }
        CallbackProgression::Continue
    });
    let roles = [node_name(name, Role::Plant), node_name(name, Role::Control)];
    remove_dead_nodes(cfg, |id, n| attached.contains(id) || roles.iter().any(|r| r == n))
}

/// Silences iceoryx2's own log (expected failures, such as a refused second publisher, are
/// reported by this program in plain words) unless `IOX2_LOG_LEVEL` says otherwise.
pub fn quiet_logs() {
    set_log_level_from_env_or(LogLevel::Fatal);
}

fn node_name(name: &str, role: Role) -> String {
    format!("{name}/{}", role.as_str())
}

/// The name of service `what` of demo `name` in this protocol version:
/// `companion/NAME/v4/WHAT`.
pub fn service_name(name: &str, what: &str) -> String {
    format!("companion/{name}/v{PROTOCOL_VERSION}/{what}")
}

/// iceoryx2 refused a set-up step: `what` and its error's words.
fn iceoryx2_error(what: impl Into<String>, e: impl std::fmt::Debug) -> StartError {
    StartError::Iceoryx2 { what: what.into(), cause: format!("{e:?}") }
}

fn service(name: &str, what: &str) -> Result<ServiceName, StartError> {
    let s = service_name(name, what);
    ServiceName::new(&s).map_err(|e| iceoryx2_error(format!("service name {s}"), e))
}

/// Publishing failed at iceoryx2's `step` (formatted only then).
#[cold]
fn publish_failed(step: &'static str, e: impl std::fmt::Debug) -> LinkError {
    LinkError::Publish { step, cause: format!("{e:?}") }
}

/// iceoryx2's node list could not be read (its words): a [`LinkError::PeerUnreadable`] on a
/// running link, a [`StartError::Iceoryx2`] while starting.
#[derive(Debug)]
struct NodeListError(String);

impl NodeListError {
    const WHAT: &'static str = "listing iceoryx2 nodes";
}

impl From<NodeListError> for LinkError {
    fn from(e: NodeListError) -> Self {
        Self::PeerUnreadable { step: NodeListError::WHAT, cause: e.0 }
    }
}

impl From<NodeListError> for StartError {
    fn from(e: NodeListError) -> Self {
        Self::Iceoryx2 { what: NodeListError::WHAT.into(), cause: e.0 }
    }
}

fn own_pid() -> i32 {
    i32::try_from(std::process::id()).unwrap_or(0)
}

/// The state of the first node that `keep(id, node name)` picks, from iceoryx2's node list (a
/// live one is preferred to a dead one).
///
/// Nodes are told apart by id, never by process: the two ends of a demo may live in one
/// process (the in-process tests do), and a filter on the own pid made each end find its peer
/// "absent" after the first silence, as if it had left.
fn node_state(
    cfg: &Config,
    mut keep: impl FnMut(&UniqueNodeId, &str) -> bool,
) -> Result<PeerState, NodeListError> {
    let mut found = PeerState::Absent;
    Node::<ipc::Service>::list(cfg, |state| {
        let (id, details, alive) = match &state {
            NodeState::Alive(v) => (*v.id(), v.details().clone(), true),
            NodeState::Dead(v) => (*v.id(), v.details().clone(), false),
            NodeState::Inaccessible(_) | NodeState::Undefined(_) => return CallbackProgression::Continue,
        };
        let (pid, name) =
            details.map_or((0, String::new()), |d| (d.process_id().value(), d.name().to_string()));
        if keep(&id, &name) {
            found = if alive { PeerState::Alive(pid) } else { PeerState::Dead(pid) };
            if alive {
                return CallbackProgression::Stop;
            }
        }
        CallbackProgression::Continue
    })
    .map_err(|e| NodeListError(format!("{e:?}")))?;
    Ok(found)
}

/// Finds this program's node of `role` in demo `name` (by its node name, `NAME/ROLE`).
///
/// # Errors
/// [`StartError::Iceoryx2`]: the node list cannot be read.
pub fn find_node(cfg: &Config, name: &str, role: Role) -> Result<PeerState, StartError> {
    let want = node_name(name, role);
    Ok(node_state(cfg, |_, n| n == want)?)
}

/// Fails with [`NameInUse`] if a live process of this program already plays `role` in demo
/// `name`.
///
/// # Errors
/// [`StartError::NameInUse`], or [`StartError::Iceoryx2`]: the node list cannot be read.
pub fn ensure_name_free(cfg: &Config, name: &DemoName, role: Role) -> Result<(), StartError> {
    if let PeerState::Alive(pid) = find_node(cfg, name, role)? {
        return Err(NameInUse { name: name.to_string(), role: role.as_str(), pid }.into());
    }
    Ok(())
}

/// A live process waiting on demo `name` with another protocol version, if any: a service
/// `companion/NAME/measurement` (version 1) or `companion/NAME/vK/measurement`
/// (K ≠ [`PROTOCOL_VERSION`]) with a live node of another process.
///
/// # Errors
/// [`StartError::Iceoryx2`]: the service list cannot be read.
pub fn other_version(cfg: &Config, name: &str) -> Result<Option<OtherVersion>, StartError> {
    let base = format!("companion/{name}/");
    let own = own_pid();
    let mut found = None;
    ipc::Service::list(cfg, |details| {
        let sn = details.static_details.name().as_str().to_string();
        let Some(rest) = sn.strip_prefix(&base) else { return CallbackProgression::Continue };
        let version = if rest == "measurement" || rest == "command" {
            Some(1)
        } else {
            rest.strip_prefix('v')
                .and_then(|r| r.split_once('/'))
                .filter(|(_, what)| *what == "measurement" || *what == "command")
                .and_then(|(v, _)| v.parse::<u32>().ok())
        };
        let Some(version) = version.filter(|v| *v != PROTOCOL_VERSION) else {
            return CallbackProgression::Continue;
        };
        let live = details.dynamic_details.as_ref().and_then(|d| {
            d.nodes.iter().find_map(|n| match n {
                NodeState::Alive(v) => {
                    v.details().as_ref().map(|d| d.process_id().value()).filter(|p| *p != own)
                }
                _ => None,
            })
        });
        if let Some(pid) = live {
            found = Some(OtherVersion { name: name.to_string(), version, service: sn, pid });
            return CallbackProgression::Stop;
        }
        CallbackProgression::Continue
    })
    .map_err(|e| iceoryx2_error("listing iceoryx2 services", e))?;
    Ok(found)
}

fn describe_type(t: &TypeDetail) -> String {
    format!("{} ({} bytes, alignment {})", t.type_name(), t.size(), t.alignment())
}

/// The error for a service `sn` that exists with another payload type than `T`: both types,
/// and the user headers if they differ ([`StartError::IncompatibleTypes`]).
pub fn incompatible_types<T: WireMessage>(cfg: &Config, sn: &str) -> StartError {
    let ours = format!("{} ({} bytes, alignment {})", T::TYPE_NAME, size_of::<T>(), align_of::<T>());
    let mut theirs = None;
    let _ = ipc::Service::list(cfg, |details| {
        if details.static_details.name().as_str() == sn {
            if let StaticPattern::PublishSubscribe(p) = details.static_details.messaging_pattern() {
                let t = p.message_type_details();
                let mut s = describe_type(&t.payload);
                if t.user_header.size() != 0 {
                    s.push_str(&format!(" with user header {}", describe_type(&t.user_header)));
                }
                theirs = Some(s);
            }
            return CallbackProgression::Stop;
        }
        CallbackProgression::Continue
    });
    StartError::IncompatibleTypes {
        service: sn.to_string(),
        theirs: theirs.unwrap_or_else(|| "another type".into()),
        ours,
    }
}

/// Opens service `sn` as it is (any settings), or creates it with this project's settings.
fn pubsub<T: WireMessage>(
    cfg: &Config,
    node: &Node<ipc::Service>,
    sn: &ServiceName,
) -> Result<pubsub_factory::PortFactory<ipc::Service, T, ()>, StartError> {
    let start = Instant::now();
    loop {
        let err = match node.service_builder(sn).publish_subscribe::<T>().open() {
            Ok(s) => return Ok(s),
            Err(PublishSubscribeOpenError::IncompatibleTypes) => {
                return Err(incompatible_types::<T>(cfg, sn.as_str()))
            }
            Err(PublishSubscribeOpenError::DoesNotExist) => {
                match node
                    .service_builder(sn)
                    .publish_subscribe::<T>()
                    .max_publishers(1)
                    .max_subscribers(1)
                    .history_size(0)
                    .subscriber_max_buffer_size(BUFFER)
                    .enable_safe_overflow(true)
                    .create()
                {
                    Ok(s) => return Ok(s),
                    // The peer created it meanwhile: open it.
                    Err(PublishSubscribeCreateError::AlreadyExists) => continue,
                    Err(e) => format!("{e:?}"),
                }
            }
            Err(e) => format!("{e:?}"),
        };
        // Transient (being created or removed by the peer): retry briefly.
        if start.elapsed() > OPEN_RETRY {
            return Err(StartError::Iceoryx2 { what: format!("opening iceoryx2 service {sn}"), cause: err });
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Opens event service `sn` as it is, or creates it with iceoryx2's defaults.
fn event(
    node: &Node<ipc::Service>,
    sn: &ServiceName,
) -> Result<event_factory::PortFactory<ipc::Service>, StartError> {
    let start = Instant::now();
    loop {
        let err = match node.service_builder(sn).event().open() {
            Ok(s) => return Ok(s),
            Err(EventOpenError::DoesNotExist) => match node.service_builder(sn).event().create() {
                Ok(s) => return Ok(s),
                Err(EventCreateError::AlreadyExists) => continue,
                Err(e) => format!("{e:?}"),
            },
            Err(e) => format!("{e:?}"),
        };
        if start.elapsed() > OPEN_RETRY {
            return Err(StartError::Iceoryx2 {
                what: format!("opening iceoryx2 event service {sn}"),
                cause: err,
            });
        }
        std::thread::sleep(Duration::from_millis(5));
    }
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
    /// Kept for the ports' lifetime: dropping it would remove this process's node.
    _node: Node<ipc::Service>,
    tx_service: pubsub_factory::PortFactory<ipc::Service, Tx, ()>,
    rx_service: pubsub_factory::PortFactory<ipc::Service, Rx, ()>,
    publisher: Publisher<ipc::Service, Tx, ()>,
    subscriber: Subscriber<ipc::Service, Rx, ()>,
    notifier: Option<Notifier<ipc::Service>>,
    listener: Option<Listener<ipc::Service>>,
    /// The node that published the last received sample.
    peer: Option<UniqueNodeId>,
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

impl<Tx: WireMessage, Rx: WireMessage> Endpoint<Tx, Rx> {
    /// Opens `role`'s side of demo `name`: checks that the name is free, removes what dead
    /// processes of this demo left ([`remove_dead_nodes_of_demo`]), creates the node, the
    /// services and the ports; `events`: the
    /// event services too (a notifier on ours, a listener on the peer's).
    ///
    /// # Errors
    /// [`StartError::NameInUse`], [`StartError::IncompatibleTypes`], or an iceoryx2 failure
    /// ([`StartError::Iceoryx2`]).
    pub fn open(name: &DemoName, role: Role, events: bool) -> Result<Self, StartError> {
        let cfg = config()?;
        ensure_name_free(&cfg, name, role)?;
        remove_dead_nodes_of_demo(&cfg, name);
        let (tx, rx) = services(role);
        let node_name = NodeName::new(&node_name(name, role)).map_err(|e| iceoryx2_error("node name", e))?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .config(&cfg)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| iceoryx2_error("creating iceoryx2 node", e))?;
        let tx_service = pubsub::<Tx>(&cfg, &node, &service(name, tx)?)?;
        let rx_service = pubsub::<Rx>(&cfg, &node, &service(name, rx)?)?;
        let in_use = |pid: i32| -> StartError {
            NameInUse { name: name.to_string(), role: role.as_str(), pid }.into()
        };
        // Another live publisher on our service (whatever its node's name) plays our role.
        if let PeerState::Alive(pid) = publisher_state(&cfg, &tx_service)? {
            return Err(in_use(pid));
        }
        let publisher = match tx_service
            .publisher_builder()
            .backpressure_strategy(BackpressureStrategy::DiscardData)
            .create()
        {
            Ok(p) => p,
            Err(PublisherCreateError::ExceedsMaxSupportedPublishers) => {
                let pid = match publisher_state(&cfg, &tx_service)? {
                    PeerState::Alive(p) => p,
                    _ => 0,
                };
                return Err(in_use(pid));
            }
            Err(e) => {
                return Err(iceoryx2_error(format!("creating publisher on {}", service_name(name, tx)), e))
            }
        };
        let buffer = BUFFER.min(rx_service.static_config().subscriber_max_buffer_size()).max(1);
        let subscriber = match rx_service.subscriber_builder().buffer_size(buffer).create() {
            Ok(s) => s,
            Err(SubscriberCreateError::ExceedsMaxSupportedSubscribers) => return Err(in_use(0)),
            Err(e) => {
                return Err(iceoryx2_error(format!("creating subscriber on {}", service_name(name, rx)), e))
            }
        };
        let (notifier, listener) = if events {
            let tx_ev = event(&node, &service(name, &format!("{tx}-ready"))?)?;
            let rx_ev = event(&node, &service(name, &format!("{rx}-ready"))?)?;
            let n = tx_ev.notifier_builder().create().map_err(|e| iceoryx2_error("creating notifier", e))?;
            let l = rx_ev.listener_builder().create().map_err(|e| iceoryx2_error("creating listener", e))?;
            (Some(n), Some(l))
        } else {
            (None, None)
        };
        Ok(Self {
            name: name.to_string(),
            role,
            cfg,
            _node: node,
            tx_service,
            rx_service,
            publisher,
            subscriber,
            notifier,
            listener,
            peer: None,
        })
    }

    /// Whether this endpoint notifies the peer after each message (event mode).
    pub fn notifies(&self) -> bool {
        self.notifier.is_some()
    }

    /// Publishes one message (zero copy: loan, write, send), then notifies in event mode.
    ///
    /// # Errors
    /// [`LinkError::Publish`]: an iceoryx2 failure.
    #[inline]
    pub fn send(&self, msg: &Tx) -> Result<(), LinkError> {
        let sample = self.publisher.loan_uninit().map_err(|e| publish_failed("loan", e))?;
        sample.write_payload(*msg).send().map_err(|e| publish_failed("send", e))?;
        if let Some(n) = &self.notifier {
            n.notify().map_err(|e| publish_failed("notify", e))?;
        }
        Ok(())
    }

    /// Takes the oldest waiting message, if any, and remembers its publisher's node.
    ///
    /// # Errors
    /// [`LinkError::Receive`]: an iceoryx2 failure.
    #[inline]
    pub fn try_receive(&mut self) -> Result<Option<Rx>, LinkError> {
        match self.subscriber.receive() {
            Ok(Some(s)) => {
                self.peer = Some(s.header().node_id());
                Ok(Some(*s.payload()))
            }
            Ok(None) => Ok(None),
            Err(e) => Err(LinkError::Receive { step: "receive", cause: format!("{e:?}") }),
        }
    }

    /// In event mode: sleeps until the peer notifies or `timeout` passes (never unbounded),
    /// draining all pending notifications. Without events: returns at once.
    ///
    /// # Errors
    /// [`LinkError::Wait`]: an iceoryx2 failure.
    #[inline]
    pub fn wait_event(&self, timeout: Duration) -> Result<(), LinkError> {
        if let Some(l) = &self.listener {
            // Not `l.timed_wait`: it rounds a short timeout up to whole scheduler ticks (8 ms
            // here; see `sys::rt::wait_readable`). Poll the listener's descriptor with a precise
            // timeout, then take what arrived without blocking.
            let readable = crate::sys::rt::wait_readable(l.file_descriptor(), timeout)
                .map_err(|e| LinkError::Wait { step: "ppoll", cause: e.to_string() })?;
            if readable {
                match l.try_wait(|_| {}) {
                    // A signal (SIGSTOP/SIGCONT, SIGINT) ended the wait early: the caller re-checks.
                    Ok(_) | Err(ListenerWaitError::InterruptSignal) => {}
                    Err(e) => return Err(LinkError::Wait { step: "try_wait", cause: format!("{e:?}") }),
                }
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
    /// each time whether to give up (e.g. the child process exited). Meanwhile it looks for a
    /// peer of another protocol version on the same demo ([`OtherVersion`]).
    ///
    /// # Errors
    /// The timeout passed ([`StartError::NoPeer`]), a peer of another version waits
    /// ([`StartError::OtherVersion`]), `abort` said so ([`StartError::Aborted`]), a signal came
    /// ([`StartError::Interrupted`]), or iceoryx2's service list cannot be read.
    pub fn wait_for_peer(
        &self,
        timeout: Duration,
        mut abort: impl FnMut() -> Option<String>,
    ) -> Result<(), StartError> {
        let start = Instant::now();
        let mut next_scan = start;
        while !self.peer_connected() {
            if let Some(why) = abort() {
                return Err(StartError::Aborted(why));
            }
            if crate::sys::signals::termination_requested() {
                return Err(StartError::Interrupted(self.role.peer().as_str()));
            }
            if Instant::now() >= next_scan {
                if let Some(other) = other_version(&self.cfg, &self.name)? {
                    // Stay a moment, so that the peer's own scan finds us and says so too.
                    std::thread::sleep(VERSION_SCAN_EVERY * 3);
                    return Err(other.into());
                }
                next_scan += VERSION_SCAN_EVERY;
            }
            if start.elapsed() > timeout {
                return Err(StartError::NoPeer(format!(
                    "no {} joined demo '{}' within {:.0} s (services {} and {}, iceoryx2 prefix {})",
                    self.role.peer().as_str(),
                    self.name,
                    timeout.as_secs_f64(),
                    service_name(&self.name, "measurement"),
                    service_name(&self.name, "command"),
                    String::from_utf8_lossy(PREFIX)
                )));
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        Ok(())
    }

    /// Waits (at most `max`) until the peer's subscriber has left our service: after a last
    /// message (the answer to the end of the run, a refusal), so that the peer reads it before
    /// this process exits and takes its samples with it.
    pub fn linger(&self, max: Duration) {
        let end = Instant::now() + max;
        while self.tx_service.dynamic_config().number_of_subscribers() > 0 && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// The peer's state (a few file-system calls: call it only when the peer has been
    /// silent): the node of the last received sample, or else of the subscribed service's
    /// publisher, looked up in iceoryx2's node list.
    ///
    /// # Errors
    /// [`LinkError::PeerUnreadable`]: the node list cannot be read.
    pub fn peer_state(&self) -> Result<PeerState, LinkError> {
        let state = match self.peer {
            Some(id) => node_state(&self.cfg, |n, _| *n == id),
            None => publisher_state(&self.cfg, &self.rx_service),
        };
        Ok(state?)
    }

    /// Removes the dead peer's resources (its shared memory), and only its: the peer that
    /// published the last received sample, or before the first sample the subscribed service's
    /// publisher. Returns how many nodes were cleaned.
    pub fn cleanup_dead_nodes(&self) -> u64 {
        let publishers = match self.peer {
            Some(id) => vec![id],
            None => {
                let mut ids = Vec::new();
                self.rx_service.dynamic_config().list_publishers(|p| {
                    ids.push(p.node_id);
                    CallbackProgression::Continue
                });
                ids
            }
        };
        remove_dead_nodes(&self.cfg, |id, _| publishers.contains(id))
    }
}

/// The state of the node of a service's (first) publisher of another process; `Absent` if
/// there is none.
fn publisher_state<T: std::fmt::Debug + ZeroCopySend + 'static>(
    cfg: &Config,
    s: &pubsub_factory::PortFactory<ipc::Service, T, ()>,
) -> Result<PeerState, NodeListError> {
    let mut ids = Vec::new();
    s.dynamic_config().list_publishers(|p| {
        ids.push(p.node_id);
        CallbackProgression::Continue
    });
    if ids.is_empty() {
        return Ok(PeerState::Absent);
    }
    node_state(cfg, |id, _| ids.contains(id))
}

impl<Tx: WireMessage, Rx: WireMessage> Link for Endpoint<Tx, Rx> {
    type Tx = Tx;
    type Rx = Rx;

    #[inline]
    fn publish(&mut self, msg: &Tx) -> Result<(), LinkError> {
        self.send(msg)
    }

    #[inline]
    fn try_receive(&mut self) -> Result<Option<Rx>, LinkError> {
        Endpoint::try_receive(self)
    }

    #[inline]
    fn wait_event(&mut self, timeout: Duration) -> Result<(), LinkError> {
        Endpoint::wait_event(self, timeout)
    }

    fn peer_state(&mut self) -> Result<PeerState, LinkError> {
        Endpoint::peer_state(self)
    }

    fn notifies(&self) -> bool {
        Endpoint::notifies(self)
    }
}

impl PlantEndpoint {
    /// The plant's side of demo `name`.
    ///
    /// # Errors
    /// [`OpenError`], its cause as [`Endpoint::open`]'s.
    pub fn plant(name: &DemoName, events: bool) -> Result<Self, OpenError> {
        Self::open(name, Role::Plant, events).map_err(|cause| OpenError { role: Role::Plant, cause })
    }
}

impl ControlEndpoint {
    /// The controller's side of demo `name`.
    ///
    /// # Errors
    /// [`OpenError`], its cause as [`Endpoint::open`]'s.
    pub fn control(name: &DemoName, events: bool) -> Result<Self, OpenError> {
        Self::open(name, Role::Control, events).map_err(|cause| OpenError { role: Role::Control, cause })
    }
}

/// A random 64-bit session id (time and process id mixed; never 0).
pub fn new_session_id() -> u64 {
    let t = crate::sys::rt::monotonic_ns();
    let wall = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos() & u128::from(u64::MAX)).unwrap_or(0));
    let mut h = crate::transport::wire::fnv1a(&t.to_le_bytes())
        ^ wall.rotate_left(17)
        ^ u64::from(std::process::id());
    h ^= h >> 33;
    h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
    h ^= h >> 33;
    h.max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn service_names_carry_the_protocol_version() {
        assert_eq!(service_name("demo", "measurement"), "companion/demo/v4/measurement");
        assert_eq!(service_name("x", "command-ready"), "companion/x/v4/command-ready");
    }

    #[test]
    fn session_ids_differ() {
        let a = new_session_id();
        let b = new_session_id();
        assert_ne!(a, 0);
        assert_ne!(a, b);
    }
}
