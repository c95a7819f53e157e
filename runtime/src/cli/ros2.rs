//! `companion ros2`: the controller as a ROS 2 node (cargo feature `ros2`; docs/ros2.md). Its
//! flags, its `--ros-config` file (the same settings as TOML keys; a flag wins), the defaults
//! (ROS 2 conventions and a TIAGo's names) and its exit codes.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context as _, Result};
use clap::{Args, ValueEnum};
use companion_runtime::domain::arm::SpatialArmSpec;
use companion_runtime::domain::scenario::short;
use serde::Deserialize;

use super::args::ScenarioArgs;
#[cfg(feature = "ros2")]
use super::exit::{EXIT_DEADLINES, EXIT_INTERRUPTED, EXIT_REJECTED, EXIT_SECOND_WRITER};
#[cfg(feature = "ros2")]
use super::terminal::Terminal;
#[cfg(feature = "ros2")]
use companion_core::{Manipulator, Spatial, SpatialArm};
#[cfg(feature = "ros2")]
use companion_runtime::domain::controller::{boxed_spatial_controller, AnyController};
#[cfg(feature = "ros2")]
use companion_runtime::domain::scenario::{Scenario, ScenarioError};
#[cfg(feature = "ros2")]
use companion_runtime::run::ros2::inputs::Ages;
#[cfg(feature = "ros2")]
use companion_runtime::run::ros2::security::{self, Decision};
#[cfg(feature = "ros2")]
use companion_runtime::run::ros2::target::Generator;
#[cfg(feature = "ros2")]
use companion_runtime::run::ros2::{self, NodeConfig, NodeEnd, RunDescription, TargetSource};
#[cfg(feature = "ros2")]
use companion_runtime::run::spatial::SpatialScenario;
#[cfg(feature = "ros2")]
use companion_runtime::transport::ros2::{BasePoseKind, EndpointConfig, Qos, TargetTopics, TwistKind};

/// `--target`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TargetArg {
    /// The scenario's trajectory (`--trajectory`, `--target-file`) generated in the node, from
    /// where the platform stands when the run starts; its pose is published on --target-pose.
    Trajectory,
    /// Read from --target-pose (`geometry_msgs/PoseStamped`) and --target-twist
    /// (`geometry_msgs/TwistStamped`, the target's body twist).
    Topics,
}

/// `--base-pose-type`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BasePoseArg {
    /// `nav_msgs/Odometry` (a `diff_drive_controller`'s `~/odom`).
    Odometry,
    /// `geometry_msgs/PoseStamped` (motion capture).
    PoseStamped,
}

/// `--reliability`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ReliabilityArg {
    /// Reliable (ROS 2's default).
    Reliable,
    /// Best effort (ROS 2's sensor-data QoS).
    BestEffort,
}

/// The node's settings, as flags and as keys of `--ros-config` (snake_case).
#[derive(Args, Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeSettings {
    /// ROS_DOMAIN_ID (0–232)
    ///
    /// [default: $ROS_DOMAIN_ID, else 0].
    #[arg(long, value_name = "ID")]
    pub domain_id: Option<u16>,
    /// The node's name
    ///
    /// [default: companion].
    #[arg(long, value_name = "NAME")]
    pub node_name: Option<String>,
    /// The node's namespace
    ///
    /// [default: /].
    #[arg(long, value_name = "NS")]
    pub namespace: Option<String>,
    /// The robot's sensor_msgs/JointState topic
    ///
    /// [default: /joint_states, joint_state_broadcaster's].
    #[arg(long, value_name = "TOPIC")]
    pub joint_states: Option<String>,
    /// The platform's pose topic
    ///
    /// [default: /mobile_base_controller/odom, the TIAGo's diff_drive_controller].
    #[arg(long, value_name = "TOPIC")]
    pub base_pose: Option<String>,
    /// The base pose's type
    ///
    /// [default: odometry].
    #[arg(long, value_enum, value_name = "TYPE")]
    pub base_pose_type: Option<BasePoseArg>,
    /// The target's source
    ///
    /// [default: trajectory].
    #[arg(long, value_enum)]
    pub target: Option<TargetArg>,
    /// The target's pose topic, read or published
    ///
    /// Read with `--target topics`, published with `--target trajectory`
    /// [default: /companion/target_pose].
    #[arg(long, value_name = "TOPIC")]
    pub target_pose: Option<String>,
    /// The target's body twist topic (--target topics)
    ///
    /// [default: /companion/target_twist].
    #[arg(long, value_name = "TOPIC")]
    pub target_twist: Option<String>,
    /// The platform's velocity command topic
    ///
    /// [default: /mobile_base_controller/cmd_vel, Jazzy's diff_drive_controller: TwistStamped].
    #[arg(long, value_name = "TOPIC")]
    pub base_command: Option<String>,
    /// Send the base command as geometry_msgs/Twist (Humble)
    ///
    /// Humble's diff_drive_controller with use_stamped_vel false, on ~/cmd_vel_unstamped.
    #[arg(long)]
    #[serde(default)]
    pub twist_unstamped: bool,
    /// The joint velocities' topic (Float64MultiArray)
    ///
    /// A std_msgs/Float64MultiArray for a JointGroupVelocityController
    /// [default: /arm_velocity_controller/commands].
    #[arg(long, value_name = "TOPIC")]
    pub joint_command: Option<String>,
    /// The node's diagnostics topic
    ///
    /// A diagnostic_msgs/DiagnosticArray [default: /diagnostics].
    #[arg(long, value_name = "TOPIC")]
    pub diagnostics: Option<String>,
    /// Diagnostics per second, 0 for none
    ///
    /// [default: 10].
    #[arg(long, value_name = "HZ")]
    pub diagnostics_hz: Option<f64>,
    /// The arm's joint names in its order, as JointState lists them
    ///
    /// [default: the arm's own: a URDF's, an arm file's `name` keys, the presets' URDF names].
    #[arg(long, value_name = "A,B,…", value_delimiter = ',')]
    pub joint_names: Option<Vec<String>>,
    /// The velocity controller's joints in its order
    ///
    /// Every joint of the arm once, and any other joint of the controller (sent 0)
    /// [default: --joint-names].
    #[arg(long, value_name = "A,B,…", value_delimiter = ',')]
    pub command_joints: Option<Vec<String>>,
    /// QoS reliability
    ///
    /// [default: reliable].
    #[arg(long, value_enum, value_name = "R")]
    pub reliability: Option<ReliabilityArg>,
    /// Every topic's history depth, keep last N (1–1000)
    ///
    /// [default: 10].
    #[arg(long, value_name = "N")]
    pub depth: Option<u16>,
    /// A measurement older than this gives the zero command (s)
    ///
    /// By its stamp against the system clock [default and largest: the delay the law predicts
    /// over, min(0.05, 8 periods), less --command-latency].
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true)]
    pub max_age: Option<f64>,
    /// A publisher silent this long gives the zero command (ms)
    ///
    /// On the node's clock [default: 20, at least 3 periods].
    #[arg(long, value_name = "MS")]
    pub silence_ms: Option<f64>,
    /// The time from sending a command to the robot applying it (s)
    ///
    /// The transport and the robot's controller cycle (ros2_control: about half its update
    /// period); added to the delay the law predicts over [default: 0].
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true)]
    pub command_latency: Option<f64>,
    /// Real-time setup: SCHED_FIFO threads, memory locked
    ///
    /// SCHED_FIFO for the node's threads (RustDDS's among them) at --rt-priority, memory
    /// locked (a missing privilege is a warning).
    #[arg(long)]
    #[serde(default)]
    pub rt: bool,
    /// SCHED_FIFO priority with --rt (1–99)
    ///
    /// [default: 80].
    #[arg(long, value_name = "P")]
    pub rt_priority: Option<i32>,
    /// Exit 2 if an input has not come after this long (s)
    ///
    /// [default: 20].
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true)]
    pub startup_timeout: Option<f64>,
    /// Exit 7 above this fraction of faulty periods
    ///
    /// A run whose periods were more than this fraction zero commands for an input fault,
    /// late or skipped fails (exit code 7) [default: 0.05].
    #[arg(long, value_name = "FRACTION", allow_hyphen_values = true)]
    pub max_miss_fraction: Option<f64>,
    /// The base command's frame
    ///
    /// [default: base_link].
    #[arg(long, value_name = "FRAME")]
    pub base_frame: Option<String>,
    /// The generated target's frame, the odometry's
    ///
    /// [default: odom].
    #[arg(long, value_name = "FRAME")]
    pub world_frame: Option<String>,
}

/// Flags of `companion ros2`.
#[derive(Args, Clone, Debug)]
pub struct Ros2Args {
    #[command(flatten)]
    /// The law and the generated target (`--dt` is the node's period; `--duration` the run's
    /// length from its first step, none: until SIGINT or SIGTERM).
    pub scenario: ScenarioArgs,
    /// rpr (default, the paper's), ur5, panda, or a TOML or URDF file
    ///
    /// As `companion hil --arm`; a URDF with --base-link, --tip-link and --home.
    #[arg(long, default_value = "rpr", hide_default_value = true, value_name = "ARM")]
    pub arm: String,
    #[command(flatten)]
    /// The node.
    pub node: NodeSettings,
    /// The node's settings as TOML (a flag wins)
    ///
    /// The keys of the flags above in snake_case; a flag given on the command line wins.
    #[arg(long, value_name = "FILE")]
    pub ros_config: Option<PathBuf>,
    /// Where `summary.json` goes.
    #[arg(long, default_value = "out/ros2", value_name = "DIR")]
    pub out: PathBuf,
    /// The SROS 2 enclave (with ROS_SECURITY_ENABLE=true)
    ///
    /// Its files are ROS_SECURITY_KEYSTORE/enclaves/NAME; ROS_SECURITY_ENCLAVE_OVERRIDE wins;
    /// ROS_SECURITY_STRATEGY=Enforce refuses to start without them (docs/ros2.md, "Secured on a
    /// robot") [default: /].
    #[arg(long, value_name = "NAME")]
    pub enclave: Option<String>,
    /// Print the DDS topics of these flags and exit
    ///
    /// `publish TOPIC` and `subscribe TOPIC` lines, ROS 2's DDS names: the enclave's
    /// permissions for exactly this node (scripts/sros2-keystore enclave ... --topics -).
    #[arg(long)]
    pub sros2_topics: bool,
}

/// The paper's planar arm's joints (it has no URDF: these names are the node's own).
pub const RPR_JOINTS: [&str; 3] = ["rpr_joint_1", "rpr_joint_2", "rpr_joint_3"];

impl NodeSettings {
    /// `self` with every setting it lacks taken from `file`.
    fn or(self, file: Self) -> Self {
        Self {
            domain_id: self.domain_id.or(file.domain_id),
            node_name: self.node_name.or(file.node_name),
            namespace: self.namespace.or(file.namespace),
            joint_states: self.joint_states.or(file.joint_states),
            base_pose: self.base_pose.or(file.base_pose),
            base_pose_type: self.base_pose_type.or(file.base_pose_type),
            target: self.target.or(file.target),
            target_pose: self.target_pose.or(file.target_pose),
            target_twist: self.target_twist.or(file.target_twist),
            base_command: self.base_command.or(file.base_command),
            twist_unstamped: self.twist_unstamped || file.twist_unstamped,
            joint_command: self.joint_command.or(file.joint_command),
            diagnostics: self.diagnostics.or(file.diagnostics),
            diagnostics_hz: self.diagnostics_hz.or(file.diagnostics_hz),
            joint_names: self.joint_names.or(file.joint_names),
            command_joints: self.command_joints.or(file.command_joints),
            reliability: self.reliability.or(file.reliability),
            depth: self.depth.or(file.depth),
            max_age: self.max_age.or(file.max_age),
            silence_ms: self.silence_ms.or(file.silence_ms),
            startup_timeout: self.startup_timeout.or(file.startup_timeout),
            command_latency: self.command_latency.or(file.command_latency),
            rt: self.rt || file.rt,
            rt_priority: self.rt_priority.or(file.rt_priority),
            max_miss_fraction: self.max_miss_fraction.or(file.max_miss_fraction),
            base_frame: self.base_frame.or(file.base_frame),
            world_frame: self.world_frame.or(file.world_frame),
        }
    }

    fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading --ros-config {}", path.display()))?;
        toml::from_str(&text).with_context(|| format!("--ros-config {}", path.display()))
    }
}

/// The node's settings: the flags, then `--ros-config`'s keys for those not given.
///
/// # Errors
/// The file cannot be read or has an unknown key.
fn settings(a: &Ros2Args) -> Result<NodeSettings> {
    let file = match &a.ros_config {
        Some(p) => NodeSettings::load(p)?,
        None => NodeSettings::default(),
    };
    Ok(a.node.clone().or(file))
}

/// The arm's joint names: given (checked against the arm's count), or the arm's own (a
/// URDF's, an arm file's `name` keys, the presets' URDF names; the planar RPR's are the node's,
/// [`RPR_JOINTS`]).
///
/// # Errors
/// A count other than the arm's, or a name given twice or empty.
pub fn joint_names(arm: Option<&SpatialArmSpec>, given: Option<Vec<String>>) -> Result<Vec<String>> {
    let own = arm
        .map_or_else(|| RPR_JOINTS.iter().map(|s| (*s).to_string()).collect(), SpatialArmSpec::joint_names);
    let names = given.unwrap_or_else(|| own.clone());
    if names.len() != own.len() {
        bail!("--joint-names lists {} names, the arm has {} joints", names.len(), own.len());
    }
    unique("--joint-names", &names)?;
    Ok(names)
}

fn unique(flag: &str, names: &[String]) -> Result<()> {
    for (i, n) in names.iter().enumerate() {
        if n.trim().is_empty() {
            bail!("{flag}: name {} is empty", i + 1);
        }
        if names[..i].contains(n) {
            bail!("{flag}: {n:?} is listed twice");
        }
    }
    Ok(())
}

/// The command's joints: given (each of the arm's once, others allowed), or the arm's.
///
/// # Errors
/// An arm joint missing, a name twice, more than the message carries.
pub fn command_joints(arm: &[String], given: Option<Vec<String>>) -> Result<Vec<String>> {
    let Some(list) = given else { return Ok(arm.to_vec()) };
    unique("--command-joints", &list)?;
    if let Some(missing) = arm.iter().find(|n| !list.contains(n)) {
        bail!("--command-joints does not list the arm's joint {missing:?}: every joint of the arm must be commanded");
    }
    let max = MAX_COMMAND_JOINTS;
    if list.len() > max {
        bail!("--command-joints lists {} joints, at most {max}", list.len());
    }
    Ok(list)
}

/// The most joints of one command message (the node's `msgs::MAX_COMMAND_JOINTS`; a test of
/// the `ros2` build compares them).
const MAX_COMMAND_JOINTS: usize = 32;

/// A number in `[lo, hi]`, or the error naming `flag`.
fn within(flag: &str, x: f64, lo: f64, hi: f64) -> Result<f64> {
    if x.is_finite() && x >= lo && x <= hi {
        Ok(x)
    } else {
        bail!("{flag} must be in [{}, {}], got {}", short(lo), short(hi), short(x))
    }
}

/// `companion ros2`.
///
/// # Errors
/// A bad flag or file, or (with the feature) the node could not run.
pub fn run(a: &Ros2Args) -> Result<ExitCode> {
    #[cfg(feature = "ros2")]
    {
        run_node(a)
    }
    #[cfg(not(feature = "ros2"))]
    {
        // The flags checked as in a build with the node, then the missing feature said.
        let n = settings(a)?;
        let names = joint_names(a.scenario.arm_spec(&a.arm)?.as_ref(), n.joint_names)?;
        command_joints(&names, n.command_joints)?;
        within("--max-miss-fraction", n.max_miss_fraction.unwrap_or(0.05), 0.0, 1.0)?;
        bail!(
            "companion ros2 needs a build with the ROS 2 node: cargo build --release -p companion-runtime --features ros2"
        )
    }
}

#[cfg(feature = "ros2")]
/// The delay the law can predict over at `period` (s): its `max_delay` and its history.
fn admissible_delay(s: &Scenario, period: f64) -> f64 {
    let p = s.controller.params::<f64>();
    p.max_delay.min(period * companion_core::HISTORY as f64)
}

#[cfg(feature = "ros2")]
fn resolve(a: &Ros2Args, base: &Scenario, arm: Option<&SpatialArmSpec>) -> Result<NodeConfig> {
    let joints = arm.map_or(3, SpatialArmSpec::joints);
    let n = settings(a)?;
    let period = base.dt;
    let period_ns = (period * 1e9).round() as u64;
    let bound = admissible_delay(base, period);
    let latency = within("--command-latency", n.command_latency.unwrap_or(0.0), 0.0, bound)?;
    let max_age = match n.max_age {
        Some(x) if x > bound => bail!(
            "--max-age {} s exceeds the delay the law predicts over at this period ({} s: max_delay and 8 periods)",
            short(x),
            short(bound)
        ),
        Some(x) => within("--max-age", x, 1e-6, bound)?,
        // What the law can predict over, less the robot's share.
        None => bound - latency,
    };
    if max_age + latency > bound * (1.0 + 1e-12) {
        bail!(
            "--max-age {} s and --command-latency {} s add up to more than the delay the law predicts over at \
             this period ({} s)",
            short(max_age),
            short(latency),
            short(bound)
        );
    }
    let silence = match n.silence_ms {
        Some(ms) => within("--silence-ms", ms, 0.001, 60_000.0)? * 1e-3,
        None => (20e-3f64).max(3.0 * period),
    };
    let domain_id = match n.domain_id {
        Some(d) => d,
        None => match std::env::var("ROS_DOMAIN_ID") {
            Ok(v) if !v.trim().is_empty() => {
                v.trim().parse().map_err(|_| anyhow::anyhow!("ROS_DOMAIN_ID={v:?} is not a number"))?
            }
            _ => 0,
        },
    };
    if domain_id > 232 {
        bail!("--domain-id must be in [0, 232] (ROS 2's), got {domain_id}");
    }
    let depth = n.depth.unwrap_or(10);
    if !(1..=1000).contains(&depth) {
        bail!("--depth must be in [1, 1000], got {depth}");
    }
    let names = joint_names(arm, n.joint_names)?;
    let command = command_joints(&names, n.command_joints)?;
    let target = n.target.unwrap_or(TargetArg::Trajectory);
    let duration_ns = a.scenario.duration.map(|d| (d * 1e9).round() as u64);
    if let Some(p) = n.rt_priority {
        if !(1..=99).contains(&p) {
            bail!("--rt-priority must be in [1, 99], got {p}");
        }
    }
    let st = within("--startup-timeout", n.startup_timeout.unwrap_or(20.0), 0.0, 86_400.0)?;
    let security = if a.sros2_topics {
        Decision::Off
    } else {
        security::decide(a.enclave.as_deref(), &|k| std::env::var(k).ok())?
    };
    match (&security, &a.enclave) {
        (Decision::Unsecured { warning }, _) => eprintln!("warning: ros2: {warning}"),
        (Decision::Off, Some(e)) => eprintln!(
            "warning: ros2: --enclave {e} is given but ROS_SECURITY_ENABLE is not true: the node runs WITHOUT security"
        ),
        _ => {}
    }
    let endpoint = EndpointConfig {
        domain_id,
        security: security.enclave().cloned(),
        node_name: n.node_name.unwrap_or_else(|| "companion".into()),
        namespace: n.namespace.unwrap_or_else(|| "/".into()),
        qos: Qos { reliable: n.reliability != Some(ReliabilityArg::BestEffort), depth },
        joint_states: n.joint_states.unwrap_or_else(|| "/joint_states".into()),
        base_pose: n.base_pose.unwrap_or_else(|| "/mobile_base_controller/odom".into()),
        base_pose_kind: match n.base_pose_type.unwrap_or(BasePoseArg::Odometry) {
            BasePoseArg::Odometry => BasePoseKind::Odometry,
            BasePoseArg::PoseStamped => BasePoseKind::PoseStamped,
        },
        target_pose: n.target_pose.unwrap_or_else(|| "/companion/target_pose".into()),
        target_twist: n.target_twist.unwrap_or_else(|| "/companion/target_twist".into()),
        target: match target {
            TargetArg::Topics => TargetTopics::Read,
            TargetArg::Trajectory => TargetTopics::Write,
        },
        base_command: n.base_command.unwrap_or_else(|| "/mobile_base_controller/cmd_vel".into()),
        twist: if n.twist_unstamped { TwistKind::Unstamped } else { TwistKind::Stamped },
        joint_command: n.joint_command.unwrap_or_else(|| "/arm_velocity_controller/commands".into()),
        diagnostics: n.diagnostics.unwrap_or_else(|| "/diagnostics".into()),
        base_frame: n.base_frame.unwrap_or_else(|| "base_link".into()),
        world_frame: n.world_frame.unwrap_or_else(|| "odom".into()),
    };
    let target_text = match (target, &a.scenario.target_file) {
        (TargetArg::Topics, _) => "topics".to_string(),
        (TargetArg::Trajectory, Some(f)) => format!("file {}", f.display()),
        (TargetArg::Trajectory, None) if joints == 3 => format!("trajectory {}", a.scenario.trajectory),
        (TargetArg::Trajectory, None) => format!("lifted trajectory {}", a.scenario.trajectory),
    };
    Ok(NodeConfig {
        endpoint,
        period_ns,
        ages: Ages { max_age_ns: (max_age * 1e9).round() as u64, silence_ns: (silence * 1e9).round() as u64 },
        command_latency_ns: (latency * 1e9).round() as u64,
        rt_priority: n.rt.then(|| n.rt_priority.unwrap_or(80)),
        startup_timeout_ns: (st * 1e9).round() as u64,
        duration_ns,
        joint_names: names,
        command_joints: command,
        diagnostics_hz: within("--diagnostics-hz", n.diagnostics_hz.unwrap_or(10.0), 0.0, 1000.0)?,
        max_miss_fraction: within("--max-miss-fraction", n.max_miss_fraction.unwrap_or(0.05), 0.0, 1.0)?,
        max_rejected: within("--max-rejected", a.scenario.max_rejected, 0.0, 1.0)?,
        out: a.out.clone(),
        describe: RunDescription {
            arm: a.arm.clone(),
            platform: companion_runtime::domain::controller::platform_name(base.controller.platform)
                .to_string(),
            run: RunDescription::run_letter(base.controller.choice),
            target: target_text,
        },
        security: security.summary(),
    })
}

#[cfg(feature = "ros2")]
/// The plant flags that simulate a robot: meaningless for a node that drives one.
fn refuse_plant_flags(a: &Ros2Args) -> Result<()> {
    let s = &a.scenario;
    for (flag, given) in [
        ("--noise", s.noise),
        ("--actuator-lag", s.actuator_lag.is_some()),
        ("--wheel-scale-error", s.wheel_scale_error.is_some()),
    ] {
        if given {
            bail!("{flag} simulates a robot's imperfection; companion ros2 drives a real one");
        }
    }
    if a.scenario.platform != super::args::PlatformArg::Unicycle
        && a.scenario.platform != super::args::PlatformArg::Omni
    {
        bail!(
            "companion ros2 drives a unicycle (differential drive: --platform unicycle) or an omnidirectional \
             base (--platform omni); a car-like base needs its steering angle, which no standard message carries"
        );
    }
    Ok(())
}

#[cfg(feature = "ros2")]
/// `--sros2-topics`: the node's DDS topics with these flags, one `publish T` or `subscribe T`
/// a line (nothing joins the domain).
fn print_topics(a: &Ros2Args) -> Result<ExitCode> {
    let d = a.scenario.duration.unwrap_or(120.0);
    let cfg = match a.scenario.arm_spec(&a.arm)? {
        None => resolve(a, &a.scenario.scenario_with(d, |b| b)?, None)?,
        Some(arm) => {
            let ss = a.scenario.spatial_scenario(arm, d, |b| b)?;
            resolve(a, &ss.base, Some(&ss.arm))?
        }
    };
    for (access, topic) in companion_runtime::transport::ros2::dds_topics(&cfg.endpoint) {
        println!("{} {topic}", access.as_str());
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(feature = "ros2")]
fn run_node(a: &Ros2Args) -> Result<ExitCode> {
    if a.sros2_topics {
        return print_topics(a);
    }
    companion_runtime::sys::signals::install_termination_handler()?;
    companion_runtime::sys::rt::tight_timer_slack();
    refuse_plant_flags(a)?;
    let term = Terminal::lines();
    let default_duration = a.scenario.duration.unwrap_or(120.0);
    let outcome = match a.scenario.arm_spec(&a.arm)? {
        None => {
            let s = a.scenario.scenario_with(default_duration, |b| b)?;
            let cfg = resolve(a, &s, None)?;
            let law = AnyController::new(&s.controller).map_err(ScenarioError::Param)?;
            let target = match cfg.endpoint.target {
                TargetTopics::Read => TargetSource::Topics,
                TargetTopics::Write => TargetSource::Generated(Generator::new(
                    companion_runtime::run::sim::build_plant(&s)?,
                    s.dt,
                )),
            };
            ros2::run(&cfg, law, target, &term)?
        }
        Some(arm) => {
            let ss = a.scenario.spatial_scenario(arm, default_duration, |b| b)?;
            match ss.arm.joints() {
                6 => spatial::<6>(a, &ss, &term)?,
                7 => spatial::<7>(a, &ss, &term)?,
                _ => spatial::<8>(a, &ss, &term)?,
            }
        }
    };
    let s = &outcome.summary;
    println!(
        "{} periods, {} steps; {} zero commands for an input fault, {} rejected by the law, {} late, {} skipped; \
         measurement age p50 {:.3} ms max {:.3} ms; final ‖e_p‖ {:.3e}",
        s.periods,
        s.steps,
        s.zero_commands,
        s.rejections.total(),
        s.late,
        s.skipped_releases,
        s.measurement_age_ns.p50 as f64 / 1e6,
        s.measurement_age_ns.max as f64 / 1e6,
        s.final_ep_norm
    );
    if let Some(d) = &s.command_delay {
        println!(
            "the robot's joints followed the commands {:.2} ms after their stamps (fitted to its joint states; residual {:.1e} of motion {:.1e})",
            d.latency_s * 1e3,
            d.residual_rms,
            d.motion_rms
        );
    }
    println!("wrote {}", a.out.join("summary.json").display());
    for f in &s.failures {
        eprintln!("warning: ros2: RUN FAILED: {f}");
    }
    Ok(ExitCode::from(match s.end {
        NodeEnd::Interrupted => EXIT_INTERRUPTED,
        NodeEnd::Completed if outcome.second_writer() => EXIT_SECOND_WRITER,
        NodeEnd::Completed if outcome.rejected() => EXIT_REJECTED,
        NodeEnd::Completed if !s.failures.is_empty() => EXIT_DEADLINES,
        NodeEnd::Completed => 0,
    }))
}

#[cfg(feature = "ros2")]
fn spatial<const N: usize>(a: &Ros2Args, ss: &SpatialScenario, term: &Terminal) -> Result<ros2::NodeOutcome>
where
    SpatialArm<f64, N>: companion_core::Manipulator<f64, N, Space = Spatial>,
    SpatialArm<f32, N>: Manipulator<f32, N, Space = Spatial>,
{
    let cfg = resolve(a, &ss.base, Some(&ss.arm))?;
    let law = boxed_spatial_controller::<N>(&ss.base.controller, &ss.arm)?;
    let target = match cfg.endpoint.target {
        TargetTopics::Read => TargetSource::Topics,
        TargetTopics::Write => {
            let chain = ss.arm.chain::<f64, N>()?;
            let star = law.target_in_effector();
            let plant = companion_runtime::run::spatial::build_plant(ss, &chain, &star)?;
            TargetSource::Generated(Generator::new(plant, ss.base.dt))
        }
    };
    Ok(ros2::run(&cfg, law, target, term)?)
}

#[cfg(test)]
mod tests {
    use clap::Parser;
    use companion_runtime::domain::arm::ArmChoice;

    use super::*;

    #[derive(Parser, Debug)]
    struct T {
        #[command(flatten)]
        a: Ros2Args,
    }

    #[test]
    fn joint_names_default_to_the_arms_own_and_are_checked() {
        let spec = |arm: &str| SpatialArmSpec::from_choice(&ArmChoice::parse(arm)).unwrap();
        assert_eq!(joint_names(spec("ur5").as_ref(), None).unwrap()[0], "shoulder_pan_joint");
        assert_eq!(joint_names(spec("panda").as_ref(), None).unwrap()[6], "panda_joint7");
        assert_eq!(joint_names(None, None).unwrap(), RPR_JOINTS);
        // An arm file without `name` keys: the reader's `joint1` … `joint6`.
        let file = spec(concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/arms/ur5.toml"));
        assert_eq!(joint_names(file.as_ref(), None).unwrap(), file.unwrap().joint_names());
        let two = |v: &[&str]| Some(v.iter().map(|s| s.to_string()).collect::<Vec<_>>());
        let e = joint_names(None, two(&["a", "b"])).unwrap_err().to_string();
        assert_eq!(e, "--joint-names lists 2 names, the arm has 3 joints");
        let e = joint_names(None, two(&["a", "b", "a"])).unwrap_err().to_string();
        assert_eq!(e, "--joint-names: \"a\" is listed twice");
        let arm: Vec<String> = ["a", "b", "c"].iter().map(|s| s.to_string()).collect();
        assert_eq!(command_joints(&arm, None).unwrap(), arm);
        assert_eq!(command_joints(&arm, two(&["c", "torso", "a", "b"])).unwrap(), ["c", "torso", "a", "b"]);
        let e = command_joints(&arm, two(&["a", "c"])).unwrap_err().to_string();
        assert!(e.contains("\"b\""), "{e}");
    }

    #[test]
    fn flags_win_over_the_file_and_unknown_keys_are_refused() {
        let dir = std::env::temp_dir().join(format!("companion-ros2-cfg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("node.toml");
        std::fs::write(&f, "joint_states = \"/a\"\ndepth = 3\ntwist_unstamped = true\n").unwrap();
        let t = T::parse_from(["x", "--ros-config", f.to_str().unwrap(), "--depth", "5"]);
        let file = NodeSettings::load(&f).unwrap();
        let n = t.a.node.clone().or(file);
        assert_eq!((n.joint_states.as_deref(), n.depth, n.twist_unstamped), (Some("/a"), Some(5), true));
        std::fs::write(&f, "joint_state = \"/a\"\n").unwrap();
        let e = format!("{:#}", NodeSettings::load(&f).unwrap_err());
        assert!(e.contains("unknown field `joint_state`"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[cfg(feature = "ros2")]
    #[test]
    fn the_command_holds_as_many_joints_as_the_message() {
        assert_eq!(MAX_COMMAND_JOINTS, companion_runtime::transport::ros2::msgs::MAX_COMMAND_JOINTS);
    }

    #[test]
    fn bad_numbers_are_refused_by_name() {
        assert_eq!(
            within("--max-miss-fraction", 2.0, 0.0, 1.0).unwrap_err().to_string(),
            "--max-miss-fraction must be in [0, 1], got 2"
        );
        assert!(within("--max-age", f64::NAN, 0.0, 1.0).is_err());
    }
}
