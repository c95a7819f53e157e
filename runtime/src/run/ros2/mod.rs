//! `companion ros2` (cargo feature `ros2`): the controller as a ROS 2 node.
//!
//! The node joins a DDS domain as ROS 2 does ([`crate::transport::ros2`]), reads the robot's
//! joint states (by joint name), the platform's pose (`nav_msgs/Odometry` or
//! `geometry_msgs/PoseStamped`) and the target (a `PoseStamped` and a `TwistStamped`, or the
//! scenario's trajectory generated in the node), and on its own timer — period `n` released at
//! `start + n·period` on `CLOCK_MONOTONIC`, never "a period after the work" — steps the law on
//! the latest of them and sends the platform's command (`TwistStamped`, or `Twist`) and the
//! joint velocities (`std_msgs/Float64MultiArray` in a configured joint order).
//!
//! ## Time
//!
//! ROS 2's stamps are the system clock's (`CLOCK_REALTIME`). A step's measurement time is the
//! newer of the joint state's and the base pose's stamps, the older of the two moved to it by
//! the command the node sent last (the robot's joint state and odometry of one instant come
//! as two messages, which a release may fall between); the law predicts over the delay from
//! that stamp to the moment it steps plus `--command-latency` (the robot's share: transport,
//! its controller's cycle) — its delay compensation, as in the real-time HIL — and holds its
//! command for one period. A target read from topics is moved from its own stamp to
//! the measurement's by its twist ([`target`]). The run's time (the law's `t`, a generated
//! target's) counts from the first step's measurement.
//!
//! ## Safety
//!
//! The HIL's rules ([`inputs`]): a stale measurement (older than `--max-age`), a silent
//! publisher (nothing for `--silence-ms`), a non-finite value, a joint state without one of the
//! arm's joints or with one twice → the zero command for that period, counted by cause and
//! input; a step the law rejects → the zero command, counted by reason. A period whose command
//! went out after the next release is a miss. The run fails (exit code 7) when more than
//! `--max-miss-fraction` of its periods were misses or zero commands for an input fault, and
//! (exit code 6) when the law rejected more than `--max-rejected` of its steps.
//!
//! ## Files
//!
//! `summary.json` in `--out`: the node's settings, the counts, the measurement age and the
//! tick's work time (p50 … max), the last `‖e_p‖`, how the run ended and why it failed if it
//! did. Written when the run ends, also after SIGINT or SIGTERM, after the node has sent the
//! zero command every period for 0.1 s.
//!
//! ## The cost of a period
//!
//! The node's own code allocates nothing on its period: the messages are decoded into fixed
//! storage and sent from it, the counts and histograms are preallocated, the diagnostics are
//! handed to their thread through a wait-free ring ([`rtrb`]) and formatted there. RustDDS
//! allocates a buffer per sample it reads or writes (its own threads, and `write`).

pub mod delay;
pub mod inputs;
pub mod security;
pub mod target;

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use companion_core::{Command, Measurement, PaperRun, Pose, PoseSc};
use serde::Serialize;

use self::inputs::{Ages, Fault, FaultCounts, Input, Latest, Snapshot};
use self::target::{planar_pose, Generator, NodeSpace};
use crate::domain::controller::{Law, StepReport};
use crate::domain::histogram::{LatencyHistogram, Percentiles};
use crate::domain::observe::Observer;
use crate::domain::record::verdict::Rejections;
use crate::sys::rt;
use crate::sys::signals::termination_requested;
use crate::transport::ros2::msgs::{
    DiagnosticArray, DiagnosticStatus, Header, JointVelocities, KeyValue, Time, Twist, Vector3,
    MAX_COMMAND_JOINTS,
};
use crate::transport::ros2::{
    EndpointConfig, GraphNames, LogLevel, Ros2Endpoint, Ros2Error, Rosout, TargetTopics, WriterId,
};

/// The node's settings (the command line's flags and `--ros-config` file, checked).
#[derive(Clone, Debug, PartialEq)]
pub struct NodeConfig {
    /// The DDS side: domain, names, topics, QoS.
    pub endpoint: EndpointConfig,
    /// The period (ns).
    pub period_ns: u64,
    /// How long a sample stays good ([`Ages`]).
    pub ages: Ages,
    /// The expected time from sending a command to the robot applying it (transport and the
    /// robot's controller cycle), added to the delay the law predicts over (ns).
    pub command_latency_ns: u64,
    /// `--rt`: `SCHED_FIFO` at this priority for the node's threads (RustDDS's among them)
    /// and memory locked.
    pub rt_priority: Option<i32>,
    /// How long to wait for every input at start (ns).
    pub startup_timeout_ns: u64,
    /// How long the run lasts from its first step (ns); `None`: until SIGINT or SIGTERM.
    pub duration_ns: Option<u64>,
    /// The arm's joint names, in its order.
    pub joint_names: Vec<String>,
    /// The joints of the `Float64MultiArray`, in its order: each is one of the arm's (its
    /// velocity) or another joint of the controller's (0).
    pub command_joints: Vec<String>,
    /// Diagnostics per second (0: none).
    pub diagnostics_hz: f64,
    /// The share of periods that may be misses or zero commands for an input fault.
    pub max_miss_fraction: f64,
    /// The share of steps the law may reject.
    pub max_rejected: f64,
    /// Where `summary.json` goes.
    pub out: PathBuf,
    /// What the summary names the run by (arm, platform, run (a)–(d), target).
    pub describe: RunDescription,
    /// SROS 2, as decided ([`security::decide`]; the enclave itself is the endpoint's).
    pub security: security::SecuritySummary,
}

/// What the summary says the run is.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunDescription {
    /// The arm (`rpr`, `ur5`, `panda`, a file's name).
    pub arm: String,
    /// The platform.
    pub platform: String,
    /// The law's run (a)–(d).
    pub run: String,
    /// The target: `topics` or the generated trajectory.
    pub target: String,
}

impl RunDescription {
    /// `a`–`d`.
    pub fn run_letter(run: PaperRun) -> String {
        match run {
            PaperRun::A => "a",
            PaperRun::B => "b",
            PaperRun::C => "c",
            PaperRun::D => "d",
        }
        .to_string()
    }
}

/// Why the node could not run.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// Joining the domain.
    #[error(transparent)]
    Ros2(#[from] Ros2Error),
    /// Not every input arrived in time.
    #[error(
        "the robot's inputs did not all come within --startup-timeout ({:.1} s): {}; is the robot publishing on this ROS_DOMAIN_ID, with these topic \
         names and a compatible QoS (a best-effort publisher does not match a reliable subscription){}?",
        .timeout_s, .missing,
        if *.secured { ", and, the node being secured (SROS 2), certified by the keystore's identity CA and granted these topics" } else { "" }
    )]
    NoInputs {
        /// Every input that was missing (or refused) when the time ran out, and why.
        missing: String,
        /// The timeout (s).
        timeout_s: f64,
        /// Whether the node ran under SROS 2 (only certified, permitted robots are heard).
        secured: bool,
    },
    /// The generated target could not be advanced.
    #[error("the generated target: {0:?}")]
    Target(companion_plant::AdvanceError),
    /// `summary.json` could not be written.
    #[error("writing {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The error.
        #[source]
        source: std::io::Error,
    },
    /// The diagnostics thread could not start.
    #[error("starting the diagnostics thread")]
    Thread(#[source] std::io::Error),
}

/// How the run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NodeEnd {
    /// `--duration` elapsed.
    Completed,
    /// SIGINT or SIGTERM.
    Interrupted,
}

/// `summary.json`.
#[derive(Clone, Debug, Serialize)]
pub struct NodeSummary {
    /// `ros2`.
    pub command: &'static str,
    /// The run.
    pub run: RunDescription,
    /// The arm's joint names.
    pub joint_names: Vec<String>,
    /// The joint command's joints, in order.
    pub command_joints: Vec<String>,
    /// The DDS domain.
    pub domain_id: u16,
    /// Topics, by role.
    pub topics: std::collections::BTreeMap<&'static str, String>,
    /// Every topic's QoS.
    pub qos: String,
    /// SROS 2: whether the participant ran under DDS-Security, its enclave and strategy.
    pub security: security::SecuritySummary,
    /// The period (s).
    pub period_s: f64,
    /// `--max-age` (s).
    pub max_age_s: f64,
    /// `--silence-ms` (s).
    pub silence_s: f64,
    /// How the run ended.
    pub end: NodeEnd,
    /// From the first step to the end (s).
    pub duration_s: f64,
    /// Periods from the first step.
    pub periods: u64,
    /// Steps of the law.
    pub steps: u64,
    /// Periods answered with the zero command for an input fault.
    pub zero_commands: u64,
    /// Them by cause and input.
    pub input_faults: FaultCountsByInput,
    /// Each input's writers: its own, and any other (module docs of [`inputs`]).
    pub writers: std::collections::BTreeMap<&'static str, InputWriters>,
    /// Steps the law rejected (zero command), by reason.
    pub rejections: Rejections,
    /// Periods whose command went out after the next release.
    pub late: u64,
    /// Releases skipped (the node woke more than a period late).
    pub skipped_releases: u64,
    /// Samples RustDDS refused to send.
    pub send_failures: u64,
    /// The measurement's age when the law stepped (ns).
    pub measurement_age_ns: Percentiles,
    /// The period's work, from the release to the command sent (ns).
    pub work_ns: Percentiles,
    /// The robot's command delay, estimated from its joint states' response to the commands
    /// ([`delay`]): what `--command-latency` should be, given the measurement's age the node
    /// counts (none: too little motion).
    pub command_delay: Option<delay::DelayEstimate>,
    /// `‖e_p‖` of the last step the law made (NaN if none).
    pub final_ep_norm: f64,
    /// The largest `‖e_p‖` in the last 5 s of steps.
    pub max_ep_norm_last_5_s: f64,
    /// Why the run failed (empty: it did not).
    pub failures: Vec<String>,
}

/// An input's writers, in `summary.json`.
#[derive(Clone, Debug, Serialize)]
pub struct InputWriters {
    /// The input's topic.
    pub topic: String,
    /// The writer whose samples the node used last (its DDS GUID, as `ros2 topic info -v`
    /// prints a GID), if any.
    pub writer: Option<String>,
    /// The ROS node behind it, where `ros_discovery_info` names it.
    pub node: Option<String>,
    /// Its samples taken.
    pub samples: u64,
    /// Writers the input took after its first (a driver restarted).
    pub adopted: u64,
    /// The most remote writers discovery listed on the topic at once.
    pub max_listed: u32,
    /// Every other writer: those that sent samples (refused) and those discovery listed.
    pub others: Vec<OtherWriter>,
}

/// A writer of an input other than its own.
#[derive(Clone, Debug, Serialize)]
pub struct OtherWriter {
    /// Its DDS GUID.
    pub writer: String,
    /// The ROS node behind it, where the graph names it.
    pub node: Option<String>,
    /// Its samples, all refused.
    pub samples_refused: u64,
    /// When its first and last samples arrived, from the node's start (s); none if it sent none.
    pub first_s: Option<f64>,
    /// When its last sample arrived.
    pub last_s: Option<f64>,
}

/// [`FaultCounts`] with each input named.
#[derive(Clone, Debug, Serialize)]
pub struct FaultCountsByInput(
    std::collections::BTreeMap<&'static str, std::collections::BTreeMap<&'static str, u64>>,
);

impl From<&FaultCounts> for FaultCountsByInput {
    fn from(c: &FaultCounts) -> Self {
        let mut m = std::collections::BTreeMap::new();
        for (cause, list) in [
            ("second_writer", &c.second_writer),
            ("missing", &c.missing),
            ("malformed", &c.malformed),
            ("non_finite", &c.non_finite),
            ("silent", &c.silent),
            ("stale", &c.stale),
            ("undecodable", &c.undecodable),
        ] {
            let per: std::collections::BTreeMap<&'static str, u64> =
                Input::ALL.iter().map(|i| (i.as_str(), list[*i as usize])).collect();
            m.insert(cause, per);
        }
        Self(m)
    }
}

/// What the run gives back.
#[derive(Clone, Debug)]
pub struct NodeOutcome {
    /// The summary (written).
    pub summary: NodeSummary,
}

impl NodeOutcome {
    /// Whether a failure is the law's rejections (exit code 6) rather than real time's (7).
    pub fn rejected(&self) -> bool {
        self.summary.failures.iter().any(|f| f.starts_with("the law rejected"))
    }

    /// Whether an input had a second writer (exit code 10, before 6 and 7).
    pub fn second_writer(&self) -> bool {
        self.summary.failures.iter().any(|f| f.starts_with(SECOND_WRITER))
    }
}

/// How a failure for a second writer begins.
const SECOND_WRITER: &str = "a second writer";

/// What the diagnostics thread is handed each period (`Copy`: through a ring, no allocation).
#[derive(Clone, Copy, Debug, Default)]
struct DiagSample {
    stamp_ns: i64,
    ep_norm: f64,
    saturation: f64,
    psi: f64,
    joint_scale: f64,
    steps: u64,
    zero_commands: u64,
    rejected: u64,
    late: u64,
    age_ns: u64,
    fault: Option<Fault>,
    /// With [`Fault::SecondWriter`]: the other writer whose sample came last (none: only
    /// discovery listed it).
    writer: Option<WriterId>,
    running: bool,
}

fn fault_text(f: Fault) -> String {
    match f {
        Fault::SecondWriter(i) => format!("{} has a second writer", i.as_str()),
        Fault::Missing(i) => format!("{} missing", i.as_str()),
        Fault::Malformed(i) => format!("{} malformed", i.as_str()),
        Fault::NonFinite(i) => format!("{} not finite", i.as_str()),
        Fault::Silent(i) => format!("{} silent", i.as_str()),
        Fault::Stale(i) => format!("{} stale", i.as_str()),
    }
}

/// A second writer named: its GUID and, where the graph says, its ROS node.
fn writer_text(w: Option<WriterId>, names: &GraphNames) -> String {
    match w {
        None => "listed by discovery, no sample yet".to_string(),
        Some(w) => match names.node_of(w) {
            Some(n) => format!("writer {w} (node {n})"),
            None => format!("writer {w} (no ROS node names it)"),
        },
    }
}

/// What the diagnostics thread needs besides its ring.
struct DiagOut {
    publisher: Option<ros2_client::Publisher<DiagnosticArray>>,
    rosout: Rosout,
    names: GraphNames,
    hz: f64,
    name: String,
}

/// The diagnostics thread: every `1/hz` seconds, the last sample as a
/// `diagnostic_msgs/DiagnosticArray` (level OK while the law steps, WARN on a zero command,
/// ERROR for a second writer, naming it); and a `/rosout` line whenever the reason for the zero
/// command changes (WARN, ERROR for a second writer) and when tracking resumes (INFO).
fn spawn_diagnostics(
    out: DiagOut,
    mut ring: rtrb::Consumer<DiagSample>,
    stop: Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<()>, NodeError> {
    std::thread::Builder::new()
        .name("ros2-diagnostics".into())
        .spawn(move || {
            let every = std::time::Duration::from_secs_f64(1.0 / out.hz.max(10.0));
            let publish_every = if out.hz > 0.0 { 1.0 / out.hz } else { f64::INFINITY };
            let mut since_publish = 0.0;
            let mut last: Option<DiagSample> = None;
            let mut last_reason: Option<(Option<Fault>, Option<WriterId>)> = None;
            while !stop.load(Ordering::Relaxed) {
                std::thread::sleep(every);
                since_publish += every.as_secs_f64();
                while let Ok(s) = ring.pop() {
                    let reason = (s.fault, s.writer);
                    if s.running && last_reason != Some(reason) {
                        match s.fault {
                            Some(f @ Fault::SecondWriter(_)) => out.rosout.log(
                                LogLevel::Error,
                                &format!(
                                    "zero command: {}: {}",
                                    fault_text(f),
                                    writer_text(s.writer, &out.names)
                                ),
                            ),
                            Some(f) => {
                                out.rosout.log(LogLevel::Warn, &format!("zero command: {}", fault_text(f)))
                            }
                            None if last_reason.is_some() => out.rosout.log(LogLevel::Info, "tracking"),
                            None => {}
                        }
                        last_reason = Some(reason);
                    }
                    last = Some(s);
                }
                let (Some(s), Some(publisher)) = (last, &out.publisher) else { continue };
                if since_publish + 1e-9 < publish_every {
                    continue;
                }
                since_publish = 0.0;
                let (level, message) = match (s.running, s.fault) {
                    (_, Some(f @ Fault::SecondWriter(_))) => {
                        (2, format!("zero command: {}: {}", fault_text(f), writer_text(s.writer, &out.names)))
                    }
                    (false, Some(f)) => (1, format!("waiting for the robot: {}", fault_text(f))),
                    (false, None) => (1, "waiting for the robot".to_string()),
                    (true, Some(f)) => (1, format!("zero command: {}", fault_text(f))),
                    (true, None) if s.ep_norm.is_nan() => {
                        (1, "zero command: the law rejected the step".into())
                    }
                    (true, None) => (0, "tracking".to_string()),
                };
                let kv = |k: &str, v: String| KeyValue { key: k.to_string(), value: v };
                let status = DiagnosticStatus {
                    level,
                    name: out.name.clone(),
                    message,
                    hardware_id: String::new(),
                    values: vec![
                        kv("ep_norm", format!("{:e}", s.ep_norm)),
                        kv("saturation", format!("{}", s.saturation)),
                        kv("psi", format!("{}", s.psi)),
                        kv("joint_scale", format!("{}", s.joint_scale)),
                        kv("steps", s.steps.to_string()),
                        kv("zero_commands", s.zero_commands.to_string()),
                        kv("rejected", s.rejected.to_string()),
                        kv("late", s.late.to_string()),
                        kv("measurement_age_ms", format!("{:.3}", s.age_ns as f64 / 1e6)),
                    ],
                };
                let msg = DiagnosticArray {
                    header: Header { stamp: Time::from_ns(s.stamp_ns), frame_id: String::new() },
                    status: vec![status],
                };
                let _ = publisher.publish(msg);
            }
        })
        .map_err(NodeError::Thread)
}

/// A sample's stamp on the system clock (ns).
fn realtime_ns() -> i64 {
    rt::realtime_ns()
}

/// Where each joint of the command's list takes its velocity from: the arm's joint `i`, or
/// none (0).
fn command_map(cfg: &NodeConfig) -> [Option<u8>; MAX_COMMAND_JOINTS] {
    let mut m = [None; MAX_COMMAND_JOINTS];
    for (k, name) in cfg.command_joints.iter().enumerate().take(MAX_COMMAND_JOINTS) {
        m[k] = cfg.joint_names.iter().position(|n| n == name).and_then(|i| u8::try_from(i).ok());
    }
    m
}

/// Where the target comes from.
#[derive(Debug)]
pub enum TargetSource<P, const N: usize> {
    /// The target topics.
    Topics,
    /// Generated from the scenario's plant.
    Generated(Generator<P, N>),
}

/// Runs the node with `law` (for an arm of `N` joints in space `S`) until `--duration` or a
/// termination signal; writes `summary.json`.
///
/// # Errors
/// The domain cannot be joined, the inputs did not come within `--startup-timeout`, or
/// `summary.json` cannot be written.
pub fn run<S, P, L, const N: usize>(
    cfg: &NodeConfig,
    mut law: L,
    mut target: TargetSource<P, N>,
    observer: &dyn Observer,
) -> Result<NodeOutcome, NodeError>
where
    S: NodeSpace,
    P: companion_plant::Simulated<N, Space = S>,
    L: Law<N, S>,
{
    if let Some(priority) = cfg.rt_priority {
        // Before the endpoint: RustDDS's threads, which carry the messages, inherit it.
        let rep = rt::apply(&rt::RtConfig { priority, inherited: true, ..rt::RtConfig::with_cpu(None) });
        if let Some(w) = rep.warning("ros2") {
            observer.warn(&w);
        }
    }
    let mut ep = Ros2Endpoint::open(&cfg.endpoint)?;
    let stop = Arc::new(AtomicBool::new(false));
    // A period's sample for the diagnostics thread: room for 1 s at 1 kHz between its reads.
    let (mut diag_in, diag_out) = rtrb::RingBuffer::<DiagSample>::new(1024);
    let out = DiagOut {
        publisher: ep.take_diagnostics().filter(|_| cfg.diagnostics_hz > 0.0),
        rosout: ep.rosout(),
        names: ep.graph_names(),
        hz: cfg.diagnostics_hz,
        name: format!("companion: {}", cfg.endpoint.node_name),
    };
    let diag_thread = Some(spawn_diagnostics(out, diag_out, Arc::clone(&stop))?);
    let rosout = ep.rosout();
    let note = |line: &str| {
        observer.note(line);
        rosout.log(LogLevel::Info, line.trim_start_matches("ros2: "));
    };
    if let Some(enc) = &cfg.endpoint.security {
        note(&format!(
            "ros2: secured by SROS 2 (DDS-Security: authenticated, access-controlled, encrypted) with enclave {} ({})",
            enc.name,
            enc.dir.display()
        ));
    }
    note(&format!(
        "ros2: node {} on ROS_DOMAIN_ID {} at {:.0} Hz, {}; waiting for {} and {}{}",
        cfg.endpoint.node_name,
        cfg.endpoint.domain_id,
        1e9 / cfg.period_ns as f64,
        cfg.endpoint.qos.describe(),
        cfg.endpoint.joint_states,
        cfg.endpoint.base_pose,
        if cfg.endpoint.target == TargetTopics::Read {
            format!(", {} and {}", cfg.endpoint.target_pose, cfg.endpoint.target_twist)
        } else {
            String::new()
        }
    ));
    let result = run_loop(cfg, &ep, &mut law, &mut target, &mut diag_in, &note);
    stop.store(true, Ordering::Relaxed);
    if let Some(t) = diag_thread {
        let _ = t.join();
    }
    // The robot's last command: zero, whatever the run's end — sent every period for
    // LINGER_NS, so that it reaches the robot before the participant leaves the domain
    // (ros2-client does not expose the writer's acknowledgements).
    let until = rt::monotonic_ns() + LINGER_NS;
    loop {
        let now = Time::from_ns(realtime_ns());
        let _ = ep.send_base(now, Twist::default());
        let _ = ep.send_joints(zero_joints(cfg));
        let t = rt::monotonic_ns();
        if t >= until {
            break;
        }
        rt::sleep_until_ns((t + cfg.period_ns).min(until));
    }
    let summary = match result {
        Ok(s) => s,
        Err(e) => {
            rosout.log(LogLevel::Error, &e.to_string());
            return Err(e);
        }
    };
    for f in &summary.failures {
        rosout.log(LogLevel::Error, &format!("run failed: {f}"));
    }
    let path = cfg.out.join("summary.json");
    std::fs::create_dir_all(&cfg.out).map_err(|source| NodeError::Write { path: cfg.out.clone(), source })?;
    let text = serde_json::to_string_pretty(&summary)
        .map_err(|e| NodeError::Write { path: path.clone(), source: std::io::Error::other(e) })?;
    std::fs::write(&path, text + "\n").map_err(|source| NodeError::Write { path, source })?;
    Ok(NodeOutcome { summary })
}

/// How long the node keeps sending the zero command after its run ended (ns).
const LINGER_NS: u64 = 100_000_000;

fn zero_joints(cfg: &NodeConfig) -> JointVelocities {
    JointVelocities { data: [0.0; MAX_COMMAND_JOINTS], len: cfg.command_joints.len().min(MAX_COMMAND_JOINTS) }
}

/// The counts of a run.
#[derive(Debug)]
struct Counts {
    periods: u64,
    steps: u64,
    faults: FaultCounts,
    rejections: Rejections,
    rejected: u64,
    late: u64,
    skipped: u64,
    send_failures: u64,
    age: LatencyHistogram,
    work: LatencyHistogram,
    final_ep: f64,
    /// `(run time, ‖e_p‖)` maxima per second of the run, the last 5 kept (a ring).
    ep_by_second: [(u64, f64); 6],
}

impl Counts {
    fn note_ep(&mut self, t: f64, ep: f64) {
        self.final_ep = ep;
        let sec = t.max(0.0) as u64;
        let slot = &mut self.ep_by_second[(sec % 6) as usize];
        if slot.0 != sec || slot.1.is_nan() {
            *slot = (sec, ep);
        } else {
            slot.1 = slot.1.max(ep);
        }
    }

    fn max_ep_last_5_s(&self, t_end: f64) -> f64 {
        let end = t_end.max(0.0) as u64;
        self.ep_by_second
            .iter()
            .filter(|(s, e)| end.saturating_sub(*s) < 5 && !e.is_nan())
            .map(|(_, e)| *e)
            .fold(f64::NAN, f64::max)
    }
}

#[allow(clippy::too_many_lines)]
fn run_loop<S, P, L, const N: usize>(
    cfg: &NodeConfig,
    ep: &Ros2Endpoint,
    law: &mut L,
    target: &mut TargetSource<P, N>,
    diag: &mut rtrb::Producer<DiagSample>,
    note: &dyn Fn(&str),
) -> Result<NodeSummary, NodeError>
where
    S: NodeSpace,
    P: companion_plant::Simulated<N, Space = S>,
    L: Law<N, S>,
{
    let period_ns = cfg.period_ns;
    let period = period_ns as f64 * 1e-9;
    let map = command_map(cfg);
    let mut latest = Latest::new(N, matches!(target, TargetSource::Topics));
    let mut c = Counts {
        periods: 0,
        steps: 0,
        faults: FaultCounts::default(),
        rejections: Rejections::for_joints(N),
        rejected: 0,
        late: 0,
        skipped: 0,
        send_failures: 0,
        age: LatencyHistogram::new(),
        work: LatencyHistogram::new(),
        final_ep: f64::NAN,
        ep_by_second: [(u64::MAX, f64::NAN); 6],
    };
    let t0 = rt::monotonic_ns();
    // Set by the first step: its measurement's stamp, the platform there, its release.
    let mut epoch: Option<(i64, Pose<f64>, u64)> = None;
    let mut k: u64 = 1;
    // The command the robot is executing (what the node sent last): the older of the joint
    // state and the base pose is moved by it to the newer one's stamp.
    let mut last_sent = Command::<f64, N>::zero();
    let mut probe = delay::DelayProbe::<N>::new();
    let end = loop {
        let release = t0 + k * period_ns;
        rt::sleep_until_ns(release);
        if termination_requested() {
            break NodeEnd::Interrupted;
        }
        let woke = rt::monotonic_ns();
        let behind = (woke - release) / period_ns;
        if behind > 0 {
            c.skipped += behind;
            k += behind;
        }
        let inputs = ep.take_inputs(&cfg.joint_names);
        latest.update(&inputs, woke, ep.writer_counts(), cfg.ages.silence_ns, &mut c.faults);
        let now_real = realtime_ns();
        let checked = latest.check(woke, now_real, cfg.ages);
        if epoch.is_none() {
            // Not started: start on the first good set (and step in this period), or give up
            // after the startup timeout.
            match checked {
                Ok(s) => {
                    let stamp = s.joints_stamp.as_ns().min(s.base_stamp.as_ns());
                    epoch = Some((stamp, planar_pose(&s.base).unwrap_or(Pose::identity()), release));
                    note(&format!(
                        "ros2: every input arrived; running{}",
                        cfg.duration_ns.map_or_else(
                            || " until SIGINT or SIGTERM".to_string(),
                            |d| format!(" for {:.1} s", d as f64 * 1e-9)
                        )
                    ));
                }
                Err(f) => {
                    let writer = second_writer_of(&latest, f, woke, cfg);
                    let _ = diag.push(DiagSample {
                        fault: Some(f),
                        writer,
                        stamp_ns: now_real,
                        ..DiagSample::default()
                    });
                    if woke - t0 > cfg.startup_timeout_ns {
                        // Every input's fault, not only the first.
                        let all = latest.faults(woke, now_real, cfg.ages);
                        let missing: Vec<String> = all.iter().flatten().map(|f| fault_text(*f)).collect();
                        return Err(NodeError::NoInputs {
                            missing: missing.join(", "),
                            timeout_s: cfg.startup_timeout_ns as f64 * 1e-9,
                            secured: cfg.endpoint.security.is_some(),
                        });
                    }
                    k += 1;
                    continue;
                }
            }
        }
        let Some((epoch_stamp, base0, start_release)) = epoch else { continue };
        c.periods += 1;
        let mut sample = DiagSample { stamp_ns: now_real, running: true, ..DiagSample::default() };
        let report: StepReport<N> = match checked {
            Err(f) => {
                c.faults.count(f);
                sample.fault = Some(f);
                sample.writer = second_writer_of(&latest, f, woke, cfg);
                StepReport::zero(None)
            }
            Ok(s) => {
                probe.joints(s.joints_stamp.as_ns(), &s.joints[..N]);
                let stamp = s.joints_stamp.as_ns().max(s.base_stamp.as_ns());
                let age_ns = (now_real - stamp).max(0) as u64;
                let t = (stamp - epoch_stamp) as f64 * 1e-9;
                match measurement::<S, P, N>(&s, t, stamp, &base0, target, &last_sent)? {
                    None => {
                        let f = Fault::Malformed(Input::TargetPose);
                        c.faults.count(f);
                        sample.fault = Some(f);
                        StepReport::zero(None)
                    }
                    Some((meas, target_pose)) => {
                        let delay = (age_ns + cfg.command_latency_ns) as f64 * 1e-9;
                        let r = law.step(&meas, period, delay);
                        c.steps += 1;
                        c.age.record(age_ns);
                        sample.age_ns = age_ns;
                        if let Some(e) = r.error {
                            c.rejected += 1;
                            c.rejections.count(e);
                        } else {
                            c.note_ep(t, r.ep_norm);
                        }
                        if let Some(p) = target_pose {
                            if ep.send_target(Time::from_ns(stamp), p).is_err() {
                                c.send_failures += 1;
                            }
                        }
                        r
                    }
                }
            }
        };
        let cmd = if report.command.joints.iter().all(|x| x.is_finite()) {
            report.command
        } else {
            Command::zero()
        };
        last_sent = cmd;
        let mut sent = [0.0; N];
        for (x, v) in sent.iter_mut().zip(cmd.joints.iter()) {
            *x = *v;
        }
        probe.command(now_real, &sent);
        let p = &cmd.platform;
        let twist = Twist {
            linear: Vector3 { x: p.v, y: p.v_lat, z: 0.0 },
            angular: Vector3 { x: 0.0, y: 0.0, z: p.omega },
        };
        let mut joints = zero_joints(cfg);
        for (k, m) in map.iter().enumerate().take(joints.len) {
            if let Some(i) = m {
                joints.data[k] = cmd.joints[usize::from(*i)];
            }
        }
        if ep.send_base(Time::from_ns(now_real), twist).is_err() {
            c.send_failures += 1;
        }
        if ep.send_joints(joints).is_err() {
            c.send_failures += 1;
        }
        let done = rt::monotonic_ns();
        c.work.record(done - release);
        if done > release + period_ns {
            c.late += 1;
        }
        sample.ep_norm = report.ep_norm;
        sample.saturation = report.saturation;
        sample.psi = report.psi;
        sample.joint_scale = report.joint_scale;
        sample.steps = c.steps;
        sample.zero_commands = c.faults.total();
        sample.rejected = c.rejected;
        sample.late = c.late;
        let _ = diag.push(sample);
        if cfg.duration_ns.is_some_and(|d| release - start_release >= d) {
            break NodeEnd::Completed;
        }
        k += 1;
    };
    let t_end = epoch.map_or(0.0, |(_, _, r)| (rt::monotonic_ns() - r) as f64 * 1e-9);
    let mut out = summary(cfg, &c, end, t_end, &writers_summary(cfg, ep, &latest, t0));
    out.command_delay = probe.estimate(period_ns);
    Ok(out)
}

/// The other writer behind a [`Fault::SecondWriter`] (none: another fault, or only discovery
/// lists it).
fn second_writer_of(latest: &Latest, f: Fault, now_ns: u64, cfg: &NodeConfig) -> Option<WriterId> {
    match f {
        Fault::SecondWriter(i) => latest.second_writer(i, now_ns, cfg.ages.silence_ns).flatten(),
        _ => None,
    }
}

/// Each read input's writers for the summary, named by the graph (after the run).
fn writers_summary(
    cfg: &NodeConfig,
    ep: &Ros2Endpoint,
    latest: &Latest,
    t0: u64,
) -> std::collections::BTreeMap<&'static str, InputWriters> {
    let e = &cfg.endpoint;
    let names = ep.graph_names();
    let secs = |ns: u64| ns.saturating_sub(t0) as f64 * 1e-9;
    let mut out = std::collections::BTreeMap::new();
    let topics = [&e.joint_states, &e.base_pose, &e.target_pose, &e.target_twist];
    let n = if e.target == TargetTopics::Read { 4 } else { 2 };
    for (i, input) in Input::ALL.iter().enumerate().take(n) {
        let w = &latest.writers()[i];
        let mut others: Vec<OtherWriter> = w
            .others
            .iter()
            .flatten()
            .map(|o| OtherWriter {
                writer: o.id.to_string(),
                node: names.node_of(o.id),
                samples_refused: o.samples,
                first_s: Some(secs(o.first_ns)),
                last_s: Some(secs(o.last_ns)),
            })
            .collect();
        for id in ep.writers_ever(i) {
            let seen = w.others.iter().flatten().any(|o| o.id == id);
            if Some(id) != w.own && !seen {
                others.push(OtherWriter {
                    writer: id.to_string(),
                    node: names.node_of(id),
                    samples_refused: 0,
                    first_s: None,
                    last_s: None,
                });
            }
        }
        if w.others_overflow > 0 {
            others.push(OtherWriter {
                writer: format!("{} more writers' samples", w.others_overflow),
                node: None,
                samples_refused: w.others_overflow,
                first_s: None,
                last_s: None,
            });
        }
        out.insert(
            input.as_str(),
            InputWriters {
                topic: topics[i].clone(),
                writer: w.own.map(|o| o.to_string()),
                node: w.own.and_then(|o| names.node_of(o)),
                samples: w.own_samples,
                adopted: w.adopted,
                max_listed: w.max_listed,
                others,
            },
        );
    }
    out
}

/// A step's measurement, and the generated target's pose to send.
type StepInputs<S, const N: usize> = (Measurement<f64, N, S>, Option<crate::transport::ros2::msgs::Pose>);

/// The measurement of a step at run time `t` (stamp `stamp_ns`) from the snapshot `s`, and the
/// generated target's pose to send (none when read from topics); `None` if the target read
/// from topics cannot be used.
fn measurement<S, P, const N: usize>(
    s: &Snapshot,
    t: f64,
    stamp_ns: i64,
    base0: &Pose<f64>,
    target: &mut TargetSource<P, N>,
    last: &Command<f64, N>,
) -> Result<Option<StepInputs<S, N>>, NodeError>
where
    S: NodeSpace,
    P: companion_plant::Simulated<N, Space = S>,
{
    let base = planar_pose(&s.base).unwrap_or(Pose::new(f64::NAN, f64::NAN, f64::NAN));
    // The older input moved to the newer one's stamp by the command acting meanwhile (the joint
    // state and the odometry of one instant reach the node as two messages, which a period's
    // release may fall between; a robot's two publishers may keep different clocks' rates).
    let p = &last.platform;
    let base_lag = (stamp_ns - s.base_stamp.as_ns()) as f64 * 1e-9;
    let base = PoseSc::new(base)
        .compose(&PoseSc::exp(&companion_core::nalgebra::Vector3::new(p.v, p.v_lat, p.omega), base_lag))
        .pose;
    let joint_lag = (stamp_ns - s.joints_stamp.as_ns()) as f64 * 1e-9;
    let (pose, twist, out) = match target {
        TargetSource::Topics => {
            // Both are in a snapshot of a run that reads them, the quaternion checked; a
            // target that still cannot be read is refused as malformed (never a panic).
            let Some((pose, twist, p)) =
                s.target.and_then(|(p, tw)| S::target(&p.pose, &tw.twist).map(|(a, b)| (a, b, p)))
            else {
                return Ok(None);
            };
            let moved = S::moved(&pose, &twist, (stamp_ns - p.stamp.as_ns()) as f64 * 1e-9);
            (moved, twist, None)
        }
        TargetSource::Generated(g) => {
            let (pose, twist) = g.at(t, base0).map_err(NodeError::Target)?;
            (pose, twist, Some(S::ros(&pose)))
        }
    };
    let mut joints = companion_core::nalgebra::SVector::<f64, N>::zeros();
    for i in 0..N {
        joints[i] = s.joints[i] + last.joints[i] * joint_lag;
    }
    let meas = Measurement { t, base, steering: 0.0, joints, target: pose, target_velocity: twist };
    Ok(Some((meas, out)))
}

fn summary(
    cfg: &NodeConfig,
    c: &Counts,
    end: NodeEnd,
    t_end: f64,
    writers: &std::collections::BTreeMap<&'static str, InputWriters>,
) -> NodeSummary {
    let e = &cfg.endpoint;
    let mut topics = std::collections::BTreeMap::new();
    topics.insert("joint_states", e.joint_states.clone());
    topics.insert("base_pose", e.base_pose.clone());
    topics.insert("target_pose", e.target_pose.clone());
    if e.target == TargetTopics::Read {
        topics.insert("target_twist", e.target_twist.clone());
    }
    topics.insert("base_command", e.base_command.clone());
    topics.insert("joint_command", e.joint_command.clone());
    topics.insert("diagnostics", e.diagnostics.clone());
    let zero = c.faults.total();
    let mut failures = Vec::new();
    for (input, w) in writers {
        let i = Input::ALL.iter().position(|x| x.as_str() == *input).unwrap_or(0);
        let periods = c.faults.second_writer[i];
        if w.others.is_empty() && periods == 0 {
            continue;
        }
        let named: Vec<String> = w
            .others
            .iter()
            .map(|o| {
                format!(
                    "{}{} ({} samples refused)",
                    o.writer,
                    o.node.as_ref().map_or_else(String::new, |n| format!(" of node {n}")),
                    o.samples_refused
                )
            })
            .collect();
        failures.push(format!(
            "{SECOND_WRITER} published on {} ({input}): {}; the robot got the zero command for {periods} periods",
            w.topic,
            if named.is_empty() { "listed by discovery".to_string() } else { named.join(", ") }
        ));
    }
    if c.steps > 0 && c.rejected as f64 > cfg.max_rejected * c.steps as f64 {
        failures.push(format!(
            "the law rejected {} of {} steps ({:.2} %), more than --max-rejected {}",
            c.rejected,
            c.steps,
            100.0 * c.rejected as f64 / c.steps as f64,
            cfg.max_rejected
        ));
    }
    let missed = zero + c.late + c.skipped;
    if c.periods > 0 && missed as f64 > cfg.max_miss_fraction * c.periods as f64 {
        failures.push(format!(
            "real time was not kept: {} of {} periods ({:.2} %) were zero commands for an input fault ({zero}), \
             late ({}) or skipped ({}), more than --max-miss-fraction {}",
            missed,
            c.periods,
            100.0 * missed as f64 / c.periods as f64,
            c.late,
            c.skipped,
            cfg.max_miss_fraction
        ));
    }
    NodeSummary {
        command: "ros2",
        run: cfg.describe.clone(),
        joint_names: cfg.joint_names.clone(),
        command_joints: cfg.command_joints.clone(),
        domain_id: e.domain_id,
        topics,
        qos: e.qos.describe(),
        security: cfg.security.clone(),
        period_s: cfg.period_ns as f64 * 1e-9,
        max_age_s: cfg.ages.max_age_ns as f64 * 1e-9,
        silence_s: cfg.ages.silence_ns as f64 * 1e-9,
        end,
        duration_s: t_end,
        periods: c.periods,
        steps: c.steps,
        zero_commands: zero,
        input_faults: FaultCountsByInput::from(&c.faults),
        writers: writers.clone(),
        rejections: c.rejections,
        late: c.late,
        skipped_releases: c.skipped,
        send_failures: c.send_failures,
        measurement_age_ns: c.age.percentiles(),
        work_ns: c.work.percentiles(),
        command_delay: None,
        final_ep_norm: c.final_ep,
        max_ep_norm_last_5_s: c.max_ep_last_5_s(t_end),
        failures,
    }
}
