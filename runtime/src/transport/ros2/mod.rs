//! ROS 2's data plane (cargo feature `ros2`): the node's topics over DDS with ROS 2's names,
//! types and layouts, through Atostek's pure-Rust `ros2-client` on RustDDS — no ROS
//! installation, no C library.
//!
//! A ROS 2 topic `/a/b` of type `pkg/Type` is the DDS topic `rt/a/b` of type
//! `pkg::msg::dds_::Type_`, its samples CDR (little-endian, XCDR1) in the field order of the
//! `.msg` file ([`msgs`]). [`Ros2Endpoint`] is the node: one DDS participant on the domain,
//! one ROS node (visible to `ros2 node list` through `ros_discovery_info`), its subscriptions
//! (joint states, base pose, the target) and publishers (base command, joint velocities,
//! target, diagnostics) with the configured QoS ([`Qos`]).
//!
//! Reading is non-blocking ([`Ros2Endpoint::take_inputs`]: every sample that arrived since the
//! last call, the latest of each kind kept); the node's own timer decides when to read. The
//! messages are decoded into fixed storage (no allocation of this crate's code on the node's
//! period); RustDDS allocates each sample's buffer on its own threads and on `write`.

pub mod graph;
pub mod msgs;

pub use self::graph::{GraphNames, WriterId};
pub use self::msgs::{StampedPose, StampedTwist};

use std::path::PathBuf;
use std::sync::Arc;

use self::graph::Graph;
use self::msgs::{
    DiagnosticArray, JointSample, JointStateSeed, JointVelocities, OdometryIn, Pose, PoseStampedIn,
    PoseStampedOut, Ros2Type, Time, Twist, TwistStampedIn, TwistStampedOut,
};
use ros2_client::dds::rustdds::TopicDescription as _;
use ros2_client::dds::{NodeLoggingHandle, RosoutRaw};
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher, QosProfile,
    Subscription,
};

/// Reliability and history depth of every topic of the node (ROS 2's defaults: reliable,
/// keep last 10, volatile — what `ros2_control`'s controllers and `joint_state_broadcaster`
/// use).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Qos {
    /// Reliable (`true`) or best effort.
    pub reliable: bool,
    /// Keep last `depth` samples (1–1000).
    pub depth: u16,
}

impl Default for Qos {
    fn default() -> Self {
        Self { reliable: true, depth: 10 }
    }
}

impl Qos {
    fn profile(self) -> QosProfile {
        use ros2_client::qos::{Durability, History, WhenFull};
        let p = QosProfile::publisher_default()
            .durability(Durability::Volatile)
            .history(History::KeepLast { depth: usize::from(self.depth) });
        if self.reliable {
            // A full send window fails the write at once (counted) rather than holding the
            // node's period up for 100 ms, ros2-client's default.
            p.reliability_reliable(WhenFull::Fail)
        } else {
            p.reliability_best_effort()
        }
    }

    /// `reliable, keep last 10`.
    pub fn describe(self) -> String {
        format!("{}, keep last {}", if self.reliable { "reliable" } else { "best effort" }, self.depth)
    }
}

/// Where the platform's pose comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BasePoseKind {
    /// `nav_msgs/Odometry` (`diff_drive_controller`'s `~/odom`, a localisation's odometry).
    Odometry,
    /// `geometry_msgs/PoseStamped` (a motion-capture system).
    PoseStamped,
}

/// How the base command is sent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TwistKind {
    /// `geometry_msgs/TwistStamped` (Jazzy's `diff_drive_controller`, `~/cmd_vel`).
    Stamped,
    /// `geometry_msgs/Twist` (Humble's, `~/cmd_vel_unstamped`).
    Unstamped,
}

/// Whether the node reads the target or sends the one it generates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetTopics {
    /// Subscribe to the target's pose (`PoseStamped`) and twist (`TwistStamped`).
    Read,
    /// Publish the generated target's pose on the pose topic.
    Write,
}

/// The node's names and settings on the DDS domain.
#[derive(Clone, Debug, PartialEq)]
pub struct EndpointConfig {
    /// `ROS_DOMAIN_ID` (0–232).
    pub domain_id: u16,
    /// DDS-Security (SROS 2) with this enclave's files, or none: a plain participant.
    pub security: Option<Enclave>,
    /// The node's name (`companion`).
    pub node_name: String,
    /// The node's namespace (`/`).
    pub namespace: String,
    /// Every topic's QoS.
    pub qos: Qos,
    /// `sensor_msgs/JointState` in.
    pub joint_states: String,
    /// The base pose in.
    pub base_pose: String,
    /// Its type.
    pub base_pose_kind: BasePoseKind,
    /// The target's pose (in, or out when generated).
    pub target_pose: String,
    /// The target's body twist in (`TwistStamped`).
    pub target_twist: String,
    /// Read or write the target.
    pub target: TargetTopics,
    /// The base command out.
    pub base_command: String,
    /// Its type.
    pub twist: TwistKind,
    /// `std_msgs/Float64MultiArray` of joint velocities out.
    pub joint_command: String,
    /// `diagnostic_msgs/DiagnosticArray` out.
    pub diagnostics: String,
    /// The frame of the base command's header (`base_link`).
    pub base_frame: String,
    /// The world frame of the generated target's header (`odom`).
    pub world_frame: String,
}

/// An SROS 2 enclave: the folder of one participant's security files, in the layout of
/// ROS 2's keystores (`KEYSTORE/enclaves/NAME/`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Enclave {
    /// Its name (`/companion`).
    pub name: String,
    /// Its folder.
    pub dir: PathBuf,
}

impl Enclave {
    /// The files DDS-Security's builtin plugins read, by the names ROS 2 gives them
    /// (rmw_dds_common's): the identity CA's certificate, the participant's certificate and
    /// private key (PKCS#8, unencrypted), the permissions CA's certificate, and the governance
    /// and permissions documents signed (S/MIME) by the permissions CA.
    pub const FILES: [&'static str; 6] = [
        "identity_ca.cert.pem",
        "cert.pem",
        "key.pem",
        "permissions_ca.cert.pem",
        "governance.p7s",
        "permissions.p7s",
    ];

    /// The files of [`Self::FILES`] that are not in the folder (or cannot be read).
    pub fn missing(&self) -> Vec<&'static str> {
        Self::FILES.into_iter().filter(|f| std::fs::File::open(self.dir.join(f)).is_err()).collect()
    }
}

/// Which way a topic goes, for the enclave's permissions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Access {
    /// The node writes it.
    Publish,
    /// The node reads it.
    Subscribe,
}

impl Access {
    /// `publish` or `subscribe` (the words of a DDS permissions document).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Publish => "publish",
            Self::Subscribe => "subscribe",
        }
    }
}

/// A ROS 2 topic's DDS name: `/joint_states` → `rt/joint_states`, a relative name under the
/// node's namespace.
fn dds_name(namespace: &str, topic: &str) -> String {
    match topic.strip_prefix('/') {
        Some(abs) => format!("rt/{abs}"),
        None => {
            let ns = namespace.trim_matches('/');
            if ns.is_empty() {
                format!("rt/{topic}")
            } else {
                format!("rt/{ns}/{topic}")
            }
        }
    }
}

/// Every DDS topic the node with `cfg` writes and reads — its own (the same list
/// [`Ros2Endpoint::open`] makes them from) and those of ros2-client under them: the ROS graph
/// (`ros_discovery_info`), `rt/parameter_events`, `rt/rosout`, the parameter services
/// (`rq/NODE/…Request`, `rr/NODE/…Reply`) and the `/clock` reader of its spinner — each once,
/// sorted: an SROS 2 enclave's permissions for exactly this node.
pub fn dds_topics(cfg: &EndpointConfig) -> Vec<(Access, String)> {
    use Access::{Publish, Subscribe};
    let mut v = own_topics(cfg);
    v.push((Publish, "ros_discovery_info".into()));
    v.push((Subscribe, "ros_discovery_info".into()));
    v.push((Publish, "rt/parameter_events".into()));
    // ros2-client's context makes the `/rosout` topic whether or not the node logs to it, and
    // DDS-Security grants making a topic only to a participant that may publish or read it.
    v.push((Publish, "rt/rosout".into()));
    v.push((Subscribe, "rt/clock".into()));
    let ns = cfg.namespace.trim_matches('/');
    let node = if ns.is_empty() { cfg.node_name.clone() } else { format!("{ns}/{}", cfg.node_name) };
    for service in PARAMETER_SERVICES {
        v.push((Subscribe, format!("rq/{node}/{service}Request")));
        v.push((Publish, format!("rr/{node}/{service}Reply")));
    }
    v.sort();
    v.dedup();
    v
}

/// The parameter services ros2-client's spinner serves for every node.
const PARAMETER_SERVICES: [&str; 6] = [
    "describe_parameters",
    "get_parameter_types",
    "get_parameters",
    "list_parameters",
    "set_parameters",
    "set_parameters_atomically",
];

/// The node's own topics (those [`Ros2Endpoint::open`] makes), by their DDS names.
fn own_topics(cfg: &EndpointConfig) -> Vec<(Access, String)> {
    use Access::{Publish, Subscribe};
    let n = |t: &str| dds_name(&cfg.namespace, t);
    let mut v = vec![
        (Subscribe, n(&cfg.joint_states)),
        (Subscribe, n(&cfg.base_pose)),
        (Publish, n(&cfg.base_command)),
        (Publish, n(&cfg.joint_command)),
        (Publish, n(&cfg.diagnostics)),
    ];
    match cfg.target {
        TargetTopics::Read => {
            v.push((Subscribe, n(&cfg.target_pose)));
            v.push((Subscribe, n(&cfg.target_twist)));
        }
        TargetTopics::Write => v.push((Publish, n(&cfg.target_pose))),
    }
    v
}

/// Why the node could not join the domain.
#[derive(Debug, thiserror::Error)]
pub enum Ros2Error {
    /// DDS-Security refused the enclave's files (a certificate not signed by the identity CA,
    /// a document not signed by the permissions CA, a grant that does not name the
    /// certificate's subject or has expired) or a topic the permissions do not grant.
    #[error(
        "SROS 2: {what} refused by DDS-Security with enclave {enclave} ({dir}): {detail}",
        dir = .dir.display()
    )]
    Security {
        /// What was being made.
        what: String,
        /// The enclave.
        enclave: String,
        /// Its folder.
        dir: PathBuf,
        /// RustDDS's reason.
        detail: String,
    },
    /// The DDS participant or an entity of the node could not be made.
    #[error("ROS 2: {what}: {detail}")]
    Create {
        /// What was being made.
        what: String,
        /// RustDDS's or ros2-client's message.
        detail: String,
    },
    /// A topic, node or namespace name that ROS 2 does not allow.
    #[error("ROS 2: {what} {name:?} is not a valid ROS 2 name: {detail}")]
    Name {
        /// Topic, node or namespace.
        what: &'static str,
        /// The name.
        name: String,
        /// Why.
        detail: String,
    },
    /// The spinner thread cannot be started.
    #[error("ROS 2: starting the node's spinner thread")]
    Thread(#[source] std::io::Error),
}

/// The error of making `what`: a refusal of DDS-Security said as one (naming the enclave).
fn create_in<E: std::fmt::Debug>(
    security: Option<&Enclave>,
    what: impl Into<String>,
) -> impl FnOnce(E) -> Ros2Error + '_ {
    let what = what.into();
    move |e| {
        let detail = format!("{e:?}");
        match security {
            Some(enc) if detail.contains("security") || detail.contains("Security") => Ros2Error::Security {
                what,
                enclave: enc.name.clone(),
                dir: enc.dir.clone(),
                detail: security_reason(&detail),
            },
            _ => Ros2Error::Create { what, detail },
        }
    }
}

/// RustDDS's reason out of the `Debug` of its error (`Middleware { reason: "not allowed by
/// security: …" }`).
fn security_reason(debug: &str) -> String {
    let text = debug.split_once("reason: \"").map_or(debug, |(_, r)| r.trim_end_matches(['"', '}', ' ']));
    text.trim_start_matches("not allowed by security: ").replace("\\\"", "\"")
}

/// A topic name as ROS 2 writes it (`/joint_states`, `mobile_base_controller/odom`), parsed.
///
/// # Errors
/// Not a valid ROS 2 topic name.
pub fn topic_name(name: &str) -> Result<Name, Ros2Error> {
    Name::parse(name).map_err(|e| Ros2Error::Name {
        what: "topic",
        name: name.to_string(),
        detail: format!("{e:?}"),
    })
}

/// The most writers of one input whose samples one read tells apart.
pub const MAX_WRITERS: usize = 4;

/// What arrived on one topic since the last read, writer by writer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Arrived<T> {
    /// The last sample of each writer that sent any, with the writer (DDS GUID), in the order
    /// the writers first came in this read.
    pub by_writer: [Option<(WriterId, T)>; MAX_WRITERS],
    /// How many samples each of them sent.
    pub samples: [u64; MAX_WRITERS],
    /// Samples of writers past the first [`MAX_WRITERS`] (not told apart).
    pub overflow: u64,
    /// Samples that could not be decoded (dropped).
    pub undecodable: u64,
}

impl<T> Default for Arrived<T> {
    fn default() -> Self {
        Self {
            by_writer: std::array::from_fn(|_| None),
            samples: [0; MAX_WRITERS],
            overflow: 0,
            undecodable: 0,
        }
    }
}

impl<T> Arrived<T> {
    /// One sample of `writer`.
    pub fn one(writer: WriterId, v: T) -> Self {
        let mut a = Self::default();
        a.push(writer, v);
        a
    }

    /// A sample of `writer`: the last of its writer's.
    pub fn push(&mut self, writer: WriterId, v: T) {
        for (slot, n) in self.by_writer.iter_mut().zip(self.samples.iter_mut()) {
            match slot {
                Some((w, last)) if *w == writer => {
                    *last = v;
                    *n += 1;
                    return;
                }
                None => {
                    *slot = Some((writer, v));
                    *n = 1;
                    return;
                }
                Some(_) => {}
            }
        }
        self.overflow += 1;
    }

    /// The writers that sent samples in this read.
    pub fn writers(&self) -> usize {
        self.by_writer.iter().filter(|s| s.is_some()).count()
    }
}

/// What arrived on every input since the last read.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inputs {
    /// Joint states.
    pub joints: Arrived<JointSample>,
    /// The base pose.
    pub base: Arrived<StampedPose>,
    /// The target's pose.
    pub target_pose: Arrived<StampedPose>,
    /// The target's twist.
    pub target_twist: Arrived<StampedTwist>,
}

/// The node on the domain: its subscriptions and publishers.
pub struct Ros2Endpoint {
    joint_states: Subscription<JointSample>,
    base_odometry: Option<Subscription<OdometryIn>>,
    base_pose: Option<Subscription<PoseStampedIn>>,
    target_pose: Option<Subscription<PoseStampedIn>>,
    target_twist: Option<Subscription<TwistStampedIn>>,
    base_stamped: Option<Publisher<TwistStampedOut>>,
    base_unstamped: Option<Publisher<Twist>>,
    joint_command: Publisher<JointVelocities>,
    target_out: Option<Publisher<PoseStampedOut>>,
    diagnostics: Option<Publisher<DiagnosticArray>>,
    base_frame: Arc<str>,
    world_frame: Arc<str>,
    graph: Graph,
    // Last: dropped after the entities above.
    node: Node,
    _context: Context,
}

impl std::fmt::Debug for Ros2Endpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ros2Endpoint").field("domain_id", &self.node.domain_id()).finish_non_exhaustive()
    }
}

fn type_of<T: Ros2Type>() -> MessageTypeName {
    MessageTypeName::new(T::PACKAGE, T::NAME)
}

impl Ros2Endpoint {
    /// Joins domain `cfg.domain_id` as node `cfg.node_name`, makes the topics, and starts the
    /// node's spinner (ros2-client's graph and discovery tasks) on a thread of its own.
    ///
    /// # Errors
    /// A name ROS 2 does not allow, or an entity RustDDS could not make.
    pub fn open(cfg: &EndpointConfig) -> Result<Self, Ros2Error> {
        let sec = cfg.security.as_ref();
        let mut options = ContextOptions::new().domain_id(cfg.domain_id);
        if let Some(enc) = sec {
            // The private key is unencrypted (RustDDS 0.15 reads no other, nor does sros2 write one).
            options = options.enable_security(&enc.dir, String::new());
        }
        let context = Context::with_options(options)
            .map_err(create_in(sec, format!("joining DDS domain {}", cfg.domain_id)))?;
        let node_name = NodeName::new(&cfg.namespace, &cfg.node_name).map_err(|e| Ros2Error::Name {
            what: "node",
            name: format!("{}/{}", cfg.namespace, cfg.node_name),
            detail: format!("{e:?}"),
        })?;
        // `/rosout` carries the node's log lines ([`Rosout`]); no parameter services.
        let mut node = context
            .new_node(node_name, NodeOptions::new().enable_rosout(true).start_parameter_services(false))
            .map_err(create_in(sec, "creating the node"))?;
        let qos = cfg.qos.profile();
        macro_rules! topic {
            ($name:expr, $t:ty) => {
                node.create_topic(&topic_name($name)?, type_of::<$t>(), &qos)
                    .map_err(create_in(sec, format!("topic {}", $name)))?
            };
        }
        // Each input's DDS topic and type, for the graph ([`graph`]).
        let mut watched: graph::Watched = Default::default();
        macro_rules! sub {
            ($i:expr, $name:expr, $t:ty, $m:ty) => {{
                let t = topic!($name, $t);
                watched[$i] = Some((t.name(), t.get_type().name().to_string()));
                node.create_subscription::<$m>(&t, Some(qos.clone()))
                    .map_err(create_in(sec, format!("subscription to {}", $name)))?
            }};
        }
        macro_rules! publ {
            ($name:expr, $t:ty, $m:ty) => {{
                let t = topic!($name, $t);
                node.create_publisher::<$m>(&t, Some(qos.clone()))
                    .map_err(create_in(sec, format!("publisher on {}", $name)))?
            }};
        }
        let joint_states = sub!(0, &cfg.joint_states, msgs::JointState, JointSample);
        let (base_odometry, base_pose) = match cfg.base_pose_kind {
            BasePoseKind::Odometry => (Some(sub!(1, &cfg.base_pose, msgs::Odometry, OdometryIn)), None),
            BasePoseKind::PoseStamped => {
                (None, Some(sub!(1, &cfg.base_pose, msgs::PoseStamped, PoseStampedIn)))
            }
        };
        let (target_pose, target_twist, target_out) = match cfg.target {
            TargetTopics::Read => (
                Some(sub!(2, &cfg.target_pose, msgs::PoseStamped, PoseStampedIn)),
                Some(sub!(3, &cfg.target_twist, msgs::TwistStamped, TwistStampedIn)),
                None,
            ),
            TargetTopics::Write => {
                (None, None, Some(publ!(&cfg.target_pose, msgs::PoseStamped, PoseStampedOut)))
            }
        };
        let (base_stamped, base_unstamped) = match cfg.twist {
            TwistKind::Stamped => (Some(publ!(&cfg.base_command, msgs::TwistStamped, TwistStampedOut)), None),
            TwistKind::Unstamped => (None, Some(publ!(&cfg.base_command, Twist, Twist))),
        };
        let joint_command = publ!(&cfg.joint_command, msgs::Float64MultiArray, JointVelocities);
        let diagnostics = Some(publ!(&cfg.diagnostics, DiagnosticArray, DiagnosticArray));
        // No ros2-client spinner: its tasks would add a `/clock` reader typed
        // `builtin_interfaces/msg/Time` (ROS's is `rosgraph_msgs/msg/Clock`) and parameter
        // services the node does not use; the node's graph is its own thread ([`graph`]).
        let graph = Graph::spawn(&context.domain_participant(), watched)
            .map_err(|detail| Ros2Error::Create { what: "the node's graph thread".into(), detail })?;
        Ok(Self {
            joint_states,
            base_odometry,
            base_pose,
            target_pose,
            target_twist,
            base_stamped,
            base_unstamped,
            joint_command,
            target_out,
            diagnostics,
            base_frame: Arc::from(cfg.base_frame.as_str()),
            world_frame: Arc::from(cfg.world_frame.as_str()),
            graph,
            node,
            _context: context,
        })
    }

    /// Every sample that arrived since the last call, the latest of each writer of each input
    /// kept; `names` are the arm's joints (a joint state is read by them).
    pub fn take_inputs(&self, names: &[String]) -> Inputs {
        let seed = JointStateSeed { names };
        let mut inputs = Inputs::default();
        drain(&mut inputs.joints, || self.joint_states.take_seed(seed));
        if let Some(s) = &self.base_odometry {
            drain(&mut inputs.base, || s.take().map(|o| o.map(|(m, i)| (m.0, i))));
        }
        if let Some(s) = &self.base_pose {
            drain(&mut inputs.base, || s.take().map(|o| o.map(|(m, i)| (m.0, i))));
        }
        if let Some(s) = &self.target_pose {
            drain(&mut inputs.target_pose, || s.take().map(|o| o.map(|(m, i)| (m.0, i))));
        }
        if let Some(s) = &self.target_twist {
            drain(&mut inputs.target_twist, || s.take().map(|o| o.map(|(m, i)| (m.0, i))));
        }
        inputs
    }

    /// The number of remote writers of each input's topic and type (joint states, base pose,
    /// target pose, target twist), as DDS discovery last said (no lock, no allocation).
    pub fn writer_counts(&self) -> [u32; 4] {
        self.graph.counts()
    }

    /// The remote writers of input `i` (in [`Self::writer_counts`]'s order), as discovery last
    /// said.
    pub fn writers(&self, i: usize) -> Vec<WriterId> {
        self.graph.writers(i)
    }

    /// Every remote writer discovery listed on input `i` while the node ran.
    pub fn writers_ever(&self, i: usize) -> Vec<WriterId> {
        self.graph.ever(i)
    }

    /// Names writers' ROS nodes, from any thread.
    pub fn graph_names(&self) -> GraphNames {
        self.graph.names()
    }

    /// A handle that writes the node's log lines to `/rosout`, from any thread.
    pub fn rosout(&self) -> Rosout {
        Rosout { handle: self.node.logging_handle() }
    }

    /// Sends the base command (`TwistStamped` stamped `stamp` in the base frame, or `Twist`).
    ///
    /// # Errors
    /// RustDDS refused the sample (its message).
    pub fn send_base(&self, stamp: Time, twist: Twist) -> Result<(), String> {
        if let Some(p) = &self.base_stamped {
            let header = msgs::HeaderOut { stamp, frame_id: Arc::clone(&self.base_frame) };
            p.publish(TwistStampedOut { header, twist }).map_err(|e| format!("{e:?}"))?;
        }
        if let Some(p) = &self.base_unstamped {
            p.publish(twist).map_err(|e| format!("{e:?}"))?;
        }
        Ok(())
    }

    /// Sends the joint velocities.
    ///
    /// # Errors
    /// RustDDS refused the sample.
    pub fn send_joints(&self, v: JointVelocities) -> Result<(), String> {
        self.joint_command.publish(v).map_err(|e| format!("{e:?}"))
    }

    /// Sends the generated target's pose (stamped `stamp` in the world frame), if the node
    /// generates it.
    ///
    /// # Errors
    /// RustDDS refused the sample.
    pub fn send_target(&self, stamp: Time, pose: Pose) -> Result<(), String> {
        if let Some(p) = &self.target_out {
            let header = msgs::HeaderOut { stamp, frame_id: Arc::clone(&self.world_frame) };
            p.publish(PoseStampedOut { header, pose }).map_err(|e| format!("{e:?}"))?;
        }
        Ok(())
    }

    /// The diagnostics publisher, to move to the thread that sends them (once).
    pub fn take_diagnostics(&mut self) -> Option<Publisher<DiagnosticArray>> {
        self.diagnostics.take()
    }
}

/// Takes every sample of one subscription into `into` (the last of each writer kept), counting
/// the ones that cannot be decoded.
fn drain<T, E>(
    into: &mut Arrived<T>,
    mut take: impl FnMut() -> Result<Option<(T, ros2_client::MessageInfo)>, E>,
) {
    loop {
        match take() {
            Ok(Some((m, info))) => into.push(WriterId::from(info.publisher_gid()), m),
            Ok(None) => return,
            Err(_) => into.undecodable += 1,
        }
    }
}

/// The level of a `/rosout` line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogLevel {
    /// INFO.
    Info,
    /// WARN.
    Warn,
    /// ERROR.
    Error,
}

/// Writes the node's log lines to `/rosout` (`rcl_interfaces/msg/Log`, logger name the node's
/// name), as every ROS 2 node does. Not for the node's period: each line allocates.
pub struct Rosout {
    handle: NodeLoggingHandle,
}

impl std::fmt::Debug for Rosout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Rosout").finish_non_exhaustive()
    }
}

impl Rosout {
    /// Logs `msg` at `level`, stamped now on the system clock.
    pub fn log(&self, level: LogLevel, msg: &str) {
        let lv = match level {
            LogLevel::Info => ros2_client::log::LogLevel::Info,
            LogLevel::Warn => ros2_client::log::LogLevel::Warn,
            LogLevel::Error => ros2_client::log::LogLevel::Error,
        };
        let name = self.handle.base_name().to_string();
        self.handle.rosout_raw(
            ros2_client::builtin_interfaces::Time::now(),
            lv,
            &name,
            msg,
            file!(),
            "companion ros2",
            line!(),
        );
    }
}
