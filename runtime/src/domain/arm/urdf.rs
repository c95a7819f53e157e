//! Robots read from their vendors' URDF files: the serial chain between two links, as
//! companion-core's [`Chain`](companion_core::Chain).
//!
//! # What is read
//!
//! A URDF (`<robot>`) is a tree of `<link>`s joined by `<joint>`s, each joint with its frame
//! in its parent link (`<origin xyz rpy>`, rpy about fixed axes x, y, z: `R = R_z(y) R_y(p)
//! R_x(r)`), its `<axis>` in its own frame and, for a moving joint, its `<limit>`. The
//! chain the law drives is the path from a base link (the platform's frame for a mobile
//! manipulator, e.g. the TIAGo's `base_footprint`; the URDF's root by default) to a tip
//! link (the end effector, e.g. `arm_tool_link`). Along it:
//!
//! - **fixed joints** are folded: into the next moving joint's origin, or, after the last,
//!   into the tool (`E`); the chain's mount (`M`) is the arm's base link on the platform,
//!   identity unless the run's config file says (`[robot] mount`);
//! - **revolute** and **prismatic** joints become the chain's joints, with `<limit lower
//!   upper>` as their limits and `<limit velocity>` as their speed limit;
//! - **continuous** joints are revolute joints without position limits (`(−∞, +∞)`: the law
//!   puts no penalty on them, companion-core's `JointLimits`), with `<limit velocity>` if
//!   given (no speed limit otherwise);
//! - an axis is normalised; a zero axis is refused; a `floating` or `planar` joint, or a
//!   `<mimic>` joint, inside the chain is refused by name (outside it they are ignored, as
//!   are the robot's other branches, meshes, inertias and `<transmission>`s);
//! - `<safety_controller>`'s soft limits are not read: the law keeps its own margins inside
//!   the hard limits (its penalty band, SPEC §3).
//!
//! # What is refused
//!
//! What urdfdom (ROS's reader, which Pinocchio uses) refuses, in every joint of the file, not
//! only the chain's: a revolute or prismatic joint without `<limit>`, a `<limit>` without
//! `effort` or `velocity`, a number that is not finite (`inf`, `nan`, `1e400`), a negative
//! `effort` or `velocity`, an `xyz` or `rpy` that is not three numbers, a joint type that is
//! not URDF's, a link that is the child of two joints, two root links, and XML nested more
//! than [`MAX_DEPTH`] elements deep (tinyxml2's bound). And what urdfdom lets through but is
//! no tree: a joint whose parent is its own child, and joints in a loop anywhere in the file
//! (urdfdom walks the tree down from the root and never sees a loop that does not hold it).
//! Along the chain: an empty range (`lower ≥ upper`), a zero `velocity` (the law needs every
//! joint to move), and lengths or limits beyond companion-core's bound (10³ m, rad).
//!
//! The reader works in bounded time and memory: a file over [`MAX_BYTES`] or with more than
//! [`MAX_NODES`] XML nodes is refused before it is read further, every walk of the tree is
//! bounded by the number of joints (the tree is checked first), a number list stops at its
//! fourth number, and a message quotes at most [`EXCERPT`] characters of the file
//! (`runtime/tests/urdf_fuzz.rs` holds it to this under a memory limit, against 330 seeded
//! mutations of two real robots, and compares what it accepts with Pinocchio).
//!
//! # The home configuration
//!
//! The law needs a home `q*` inside the limits (companion-core's `Chain`): from an SRDF
//! `<group_state>` (`--srdf FILE --home-state NAME`; MoveIt's files carry them), from a list
//! (`--home q1,…,qN` in the chain's order, or `--home name=value,…` to give or override
//! joints by name, e.g. the TIAGo's torso beside an arm state), or both (the list's names
//! win). A robot without either is refused with a message that names the joints and says
//! how to give them. Each value must be a finite number, each joint named once, and a
//! bounded joint's home must lie at least [`HOME_MARGIN`] of its range (1 %) inside each
//! limit:
//!
//! ```text
//! q⁻ + m (q⁺ − q⁻) ≤ q* ≤ q⁺ − m (q⁺ − q⁻),   m = 0.01
//! ```
//!
//! Why: the law's joint-limit penalty (eq. 21) has the curvature `2δ²/b³` at a distance `b`
//! from a limit inside its band `δ` (a fifth of the range for 7 or 8 joints, a twentieth for
//! 6: `Params::for_arm`), so the law's weight on a joint grows as `1/b³` towards its limit: at
//! 1 % of the range it is `(δ/b)³` = 8 000 (125) times its value at the band's edge, a home the
//! law still works from;
//! at `1e−320` from the limit it is not a number, and every step fails (issue 45 found 1 001 of
//! 1 001). The rule leaves the home's choice to the user everywhere else.
//!
//! Every refusal is one sentence naming the file, the line and the URDF attribute (or the
//! flag) and quoting at most [`EXCERPT`] characters, and the command line reports it with
//! exit code 2 before anything runs or is written.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use companion_core::nalgebra::{Matrix3, Vector3};
use companion_core::{so3, FrameData, JointData, JointKind, Pose3};

use super::size::{MAX_JOINTS, MIN_SPATIAL_JOINTS};

/// The xacro namespace (ROS's macro language for URDFs).
const XACRO_NS: &str = "http://www.ros.org/wiki/xacro";

/// The largest file read (bytes): 32 MiB, 150 times example-robot-data's largest URDF
/// (`tiago_dual.urdf`, 0.2 MB). A bound on the reader's memory.
pub const MAX_BYTES: u64 = 32 << 20;

/// The most XML nodes (elements, text, comments) a file may have: 10⁶, over a hundred times
/// example-robot-data's largest URDF (`tiago_dual.urdf`, 3 851 elements). A bound on the
/// reader's memory (the parsed tree is about 70 bytes a node).
pub const MAX_NODES: u32 = 1_000_000;

/// The deepest nesting of elements read: tinyxml2's (urdfdom's parser) bound, 500.
pub const MAX_DEPTH: usize = 500;

/// The most characters of the file's text a message quotes (longer text is cut, with `…`
/// and its length).
pub const EXCERPT: usize = 80;

/// The smallest distance of a bounded joint's home from each of its limits, as a fraction of
/// its range (module docs: why).
pub const HOME_MARGIN: f64 = 0.01;

/// What to read from a URDF: the file, where to cut the chain, and its home.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct UrdfRequest {
    /// The `.urdf` file.
    pub path: PathBuf,
    /// The link the chain starts from (the platform's frame); the URDF's root if `None`.
    pub base_link: Option<String>,
    /// The link the chain ends at (the end effector); required (the refusal lists the
    /// candidates).
    pub tip_link: Option<String>,
    /// An SRDF file whose `<group_state>` named [`home_state`](Self::home_state) gives the home.
    pub srdf: Option<PathBuf>,
    /// The `<group_state name>` of [`srdf`](Self::srdf).
    pub home_state: Option<String>,
    /// The home as numbers, or joints by name over the SRDF's.
    pub home: Option<HomeList>,
    /// The arm's base link seen from the platform's frame (identity if `None`).
    pub mount: Option<FrameData<f64>>,
}

/// `--home`: every joint in the chain's order, or some joints by name.
#[derive(Clone, Debug, PartialEq)]
pub enum HomeList {
    /// `q1,…,qN` (rad or m), in the chain's order.
    Values(Vec<f64>),
    /// `name=value,…`.
    Named(Vec<(String, f64)>),
}

impl HomeList {
    /// Parses `0.2,1.0,…` or `torso_lift_joint=0.2,arm_1_joint=1.0`.
    ///
    /// # Errors
    /// An empty list, an empty item (`0.2,,0.5`: its position is named), a value that is not
    /// a finite number, a joint named twice, or the two forms mixed.
    pub fn parse(s: &str) -> Result<Self, UrdfError> {
        let bad = |item: &str, why: String| UrdfError::HomeSyntax { item: excerpt(item), why };
        if s.trim().is_empty() {
            return Err(bad(s, "the list is empty".into()));
        }
        let items: Vec<&str> = s.split(',').map(str::trim).collect();
        let count = items.len();
        if let Some(k) = items.iter().position(|x| x.is_empty()) {
            return Err(bad(s, format!("value {} of {count} is empty", k + 1)));
        }
        let number = |item: &str, text: &str| -> Result<f64, UrdfError> {
            match text.trim().parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(x),
                _ => Err(bad(item, "not a finite number".into())),
            }
        };
        if items.iter().any(|x| x.contains('=')) {
            let mut named: Vec<(String, f64)> = Vec::with_capacity(count);
            for item in &items {
                match item.split_once('=') {
                    Some((name, v)) if !name.trim().is_empty() => {
                        let name = name.trim();
                        if named.iter().any(|(n, _)| n == name) {
                            return Err(bad(
                                item,
                                format!("joint `{}` is named twice: give each joint once", excerpt(name)),
                            ));
                        }
                        named.push((name.to_string(), number(item, v)?));
                    }
                    _ => {
                        return Err(bad(
                            item,
                            "give every joint as name=value, or every value in the chain's order".into(),
                        ))
                    }
                }
            }
            Ok(Self::Named(named))
        } else {
            items.iter().map(|item| number(item, item)).collect::<Result<_, _>>().map(Self::Values)
        }
    }
}

/// At most [`EXCERPT`] characters of `s`: longer text is cut at a character's boundary and
/// ends with `…` and its length.
pub fn excerpt(s: &str) -> String {
    if s.chars().nth(EXCERPT).is_none() {
        return s.to_string();
    }
    let cut: String = s.chars().take(EXCERPT - 20).collect();
    format!("{cut}… ({} characters)", s.chars().count())
}

/// A number for a message: as Rust writes it (as the file does), in scientific notation if it
/// is tiny or huge (Rust would write 1e-320 with 320 digits).
fn num(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e9).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// A bound for a message: six significant digits, as short as they allow.
fn sig(x: f64) -> String {
    let r: f64 = format!("{x:.5e}").parse().unwrap_or(x);
    num(r)
}

/// Why a URDF (or its SRDF, or the home) was refused: one sentence naming the file and the
/// joint or link.
#[derive(Debug, thiserror::Error)]
pub enum UrdfError {
    /// The file could not be read.
    #[error("cannot read {}: {error}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        error: std::io::Error,
    },
    /// The file is larger than [`MAX_BYTES`].
    #[error(
        "{} is {bytes} bytes: companion reads URDF and SRDF files up to {MAX_BYTES} bytes (32 MiB; a robot's \
         URDF is at most a few hundred kB)",
        path.display()
    )]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size.
        bytes: u64,
    },
    /// A xacro template, not a URDF.
    #[error(
        "{} is a xacro template, not a URDF: expand it first, e.g. `xacro {} > robot.urdf` (ROS's xacro, \
         or `pip install xacro`), and give robot.urdf",
        path.display(),
        path.display()
    )]
    Xacro {
        /// The file.
        path: PathBuf,
    },
    /// Not well-formed XML.
    #[error("{}:{}: not well-formed XML: {}", path.display(), error.pos().row, excerpt(&error.to_string()))]
    Xml {
        /// The file.
        path: PathBuf,
        /// The parser's message (with the line and column).
        error: roxmltree::Error,
    },
    /// More than [`MAX_NODES`] XML nodes.
    #[error("{} has more than {MAX_NODES} XML nodes: companion reads robot descriptions up to that size", path.display())]
    TooManyNodes {
        /// The file.
        path: PathBuf,
    },
    /// Elements nested deeper than [`MAX_DEPTH`].
    #[error(
        "{}:{line}: <{}> is nested more than {MAX_DEPTH} elements deep: urdfdom refuses such XML, and so does \
         companion",
        path.display(),
        excerpt(element)
    )]
    TooDeep {
        /// The file.
        path: PathBuf,
        /// The line of the first element too deep.
        line: u32,
        /// Its tag.
        element: String,
    },
    /// The root element is not the one expected (`robot`, or `robot` for an SRDF).
    #[error("{} is not a{} file: its root element is <{}>, not <robot>", path.display(), if *srdf { "n SRDF" } else { " URDF" }, excerpt(found))]
    NotRobot {
        /// The file.
        path: PathBuf,
        /// Whether an SRDF was expected.
        srdf: bool,
        /// The root element found.
        found: String,
    },
    /// A required attribute or element is missing.
    #[error("{}:{line}: {what} has no {missing}", path.display())]
    Missing {
        /// The file.
        path: PathBuf,
        /// The line.
        line: u32,
        /// The element, e.g. "joint `arm_1_joint`".
        what: String,
        /// What is missing, e.g. "`type` attribute" or "`<parent link>`".
        missing: String,
    },
    /// An attribute's value is not what it must be.
    #[error("{}:{line}: {what}: {attribute}=\"{}\" {why}", path.display(), excerpt(text))]
    BadValue {
        /// The file.
        path: PathBuf,
        /// The line.
        line: u32,
        /// The element.
        what: String,
        /// The attribute, as the file writes it (e.g. `xyz`, `<limit velocity>`).
        attribute: String,
        /// Its text.
        text: String,
        /// The rule, e.g. "is not three numbers".
        why: String,
    },
    /// Two links or two joints of one name.
    #[error("{}:{line}: two {kind}s are named `{}`", path.display(), excerpt(name))]
    Duplicate {
        /// The file.
        path: PathBuf,
        /// The second one's line.
        line: u32,
        /// `link` or `joint`.
        kind: &'static str,
        /// The name.
        name: String,
    },
    /// A file without links.
    #[error("{} has no <link>: a URDF is a tree of links", path.display())]
    NoLinks {
        /// The file.
        path: PathBuf,
    },
    /// A link is the child of two joints: not a tree.
    #[error("{}:{line}: link `{}` is the child of two joints (`{}` and `{}`): a URDF is a tree", path.display(), excerpt(link), excerpt(first), excerpt(second))]
    TwoParents {
        /// The file.
        path: PathBuf,
        /// The second joint's line.
        line: u32,
        /// The link.
        link: String,
        /// The first joint.
        first: String,
        /// The second.
        second: String,
    },
    /// A joint whose parent link is its child.
    #[error("{}:{line}: joint `{}` has `{}` as both parent and child link: a URDF is a tree", path.display(), excerpt(joint), excerpt(link))]
    SelfParent {
        /// The file.
        path: PathBuf,
        /// The joint's line.
        line: u32,
        /// The joint.
        joint: String,
        /// The link.
        link: String,
    },
    /// Joints in a loop: each one's child is the next one's parent.
    #[error("{}:{line}: joints {} form a loop (each one's child link is the next one's parent): a URDF is a tree", path.display(), loop_text(joints))]
    Loop {
        /// The file.
        path: PathBuf,
        /// The first joint's line.
        line: u32,
        /// The joints around the loop.
        joints: Vec<String>,
    },
    /// More than one link is no joint's child.
    #[error(
        "{}:{line}: link `{}` is a second root (no joint's child) beside `{}` (line {first_line}): urdfdom refuses \
         a URDF of two trees, and so does companion",
        path.display(),
        excerpt(second),
        excerpt(first)
    )]
    TwoRoots {
        /// The file.
        path: PathBuf,
        /// The second root's line.
        line: u32,
        /// The first root link (in the file's order).
        first: String,
        /// Its line.
        first_line: u32,
        /// The second.
        second: String,
    },
    /// A joint names a link the file does not have.
    #[error("{}:{line}: joint `{}` names the {role} link `{}`, which is not in the file", path.display(), excerpt(joint), excerpt(link))]
    DanglingJoint {
        /// The file.
        path: PathBuf,
        /// The joint's line.
        line: u32,
        /// The joint.
        joint: String,
        /// `parent` or `child`.
        role: &'static str,
        /// The link.
        link: String,
    },
    /// `--base-link` or `--tip-link` names no link of the file.
    #[error("{flag} {}: {} has no such link{}", excerpt(link), path.display(), suggest(suggestions))]
    UnknownLink {
        /// The file.
        path: PathBuf,
        /// `--base-link` or `--tip-link`.
        flag: &'static str,
        /// The name given.
        link: String,
        /// Links of the file with a similar name, or its candidates.
        suggestions: Vec<String>,
    },
    /// No `--tip-link`.
    #[error("{}: give --tip-link, the end effector's link{}", path.display(), tips(base, candidates))]
    NoTip {
        /// The file.
        path: PathBuf,
        /// The base link.
        base: String,
        /// Links at the end of a chain of 6 to 8 moving joints from the base.
        candidates: Vec<String>,
    },
    /// The tip is not below the base.
    #[error("{}:{line}: link `{}` is not below `{}`: from `{}` up, the tree goes {path_up}", path.display(), excerpt(tip), excerpt(base), excerpt(tip))]
    NotBelow {
        /// The file.
        path: PathBuf,
        /// The tip link's line.
        line: u32,
        /// The base link.
        base: String,
        /// The tip link.
        tip: String,
        /// The links from the tip up to the root, joined by " -> " (shortened if long).
        path_up: String,
    },
    /// A joint in the chain that the law cannot drive.
    #[error("{}:{line}: joint `{}` between `{}` and `{}` is {kind}: a serial arm's joints are revolute, continuous, prismatic or fixed", path.display(), excerpt(joint), excerpt(base), excerpt(tip))]
    UnsupportedJoint {
        /// The file.
        path: PathBuf,
        /// The line.
        line: u32,
        /// The joint.
        joint: String,
        /// `floating`, `planar`, or "a mimic of `x`".
        kind: String,
        /// The base link.
        base: String,
        /// The tip link.
        tip: String,
    },
    /// A revolute or prismatic joint without `<limit>`, or a `<limit>` without a required
    /// attribute.
    #[error("{}:{line}: joint `{}` ({kind}) has no {what}: urdfdom refuses it too; add <limit lower=\"…\" upper=\"…\" effort=\"…\" velocity=\"…\"/>", path.display(), excerpt(joint))]
    NoLimit {
        /// The file.
        path: PathBuf,
        /// The line.
        line: u32,
        /// The joint.
        joint: String,
        /// `revolute`, `prismatic` or `continuous`.
        kind: &'static str,
        /// `<limit>`, or its missing attribute.
        what: &'static str,
    },
    /// A zero axis.
    #[error("{}:{line}: joint `{}` has a zero <axis>: a moving joint needs a direction", path.display(), excerpt(joint))]
    ZeroAxis {
        /// The file.
        path: PathBuf,
        /// The line.
        line: u32,
        /// The joint.
        joint: String,
    },
    /// Not 6 to 8 moving joints between the links.
    #[error(
        "{}:{line}: the chain from `{}` to `{}` has {} moving joint(s){}: a spatial arm needs 6 to 8",
        path.display(),
        excerpt(base),
        excerpt(tip),
        joints.len(),
        joint_list(joints)
    )]
    JointCount {
        /// The file.
        path: PathBuf,
        /// The tip link's line.
        line: u32,
        /// The base link.
        base: String,
        /// The tip link.
        tip: String,
        /// The moving joints found.
        joints: Vec<String>,
    },
    /// A joint breaks one of the chain's rules (companion-core's), in the URDF's words.
    #[error("{}{}: {}{attribute}: {rule}", path.display(), line.map_or(String::new(), |l| format!(":{l}")), if joint.is_empty() { String::new() } else { format!("joint `{}`: ", excerpt(joint)) })]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The joint's line (none for the config file's mount).
        line: Option<u32>,
        /// The joint (empty for the mount or the tool).
        joint: String,
        /// The URDF's attribute, e.g. `<limit velocity="0">`, or `[robot] mount`.
        attribute: String,
        /// The rule.
        rule: companion_core::Rule,
    },
    /// `--home`'s text.
    #[error("--home: {item:?}: {why}")]
    HomeSyntax {
        /// The item (at most [`EXCERPT`] characters).
        item: String,
        /// The rule.
        why: String,
    },
    /// No home given.
    #[error(
        "{}: the chain's {} joints need a home (the law's preferred configuration, strictly inside the limits): \
         give --home q1,…,q{} in this order: {}; or --srdf FILE --home-state NAME",
        path.display(),
        joints.len(),
        joints.len(),
        joints.join(", ")
    )]
    NoHome {
        /// The URDF.
        path: PathBuf,
        /// The chain's joints.
        joints: Vec<String>,
    },
    /// `--home` has the wrong number of values.
    #[error("--home has {found} values: the chain has {} joints ({})", joints.len(), joints.join(", "))]
    HomeLength {
        /// The values given.
        found: usize,
        /// The chain's joints.
        joints: Vec<String>,
    },
    /// `--home name=value` names no joint of the chain.
    #[error("--home {}=…: `{}` is not a joint of the chain ({})", excerpt(name), excerpt(name), joints.join(", "))]
    HomeUnknownJoint {
        /// The name.
        name: String,
        /// The chain's joints.
        joints: Vec<String>,
    },
    /// Some joints have no home value.
    #[error("{source_name} gives no value for {} of the chain's joints: add --home {}", missing.len(), missing.iter().map(|m| format!("{m}=…")).collect::<Vec<_>>().join(","))]
    HomeIncomplete {
        /// Where the other values came from, e.g. "--srdf pr2.srdf --home-state tuck_right_arm".
        source_name: String,
        /// The joints without a value.
        missing: Vec<String>,
    },
    /// A home at or outside a limit.
    #[error("home of joint `{joint}`: {} is not strictly inside its limits [{}, {}]", num(*value), num(*lower), num(*upper))]
    HomeOutside {
        /// The joint.
        joint: String,
        /// The value.
        value: f64,
        /// Its lower limit.
        lower: f64,
        /// Its upper limit.
        upper: f64,
    },
    /// A home inside the limits but within [`HOME_MARGIN`] of one.
    #[error(
        "home of joint `{joint}`: {} lies within 1 % of the range [{}, {}] of its {} limit, where the law's \
         joint-limit penalty is too steep to step from (docs/book/src/your-robot.md): give a value in [{}, {}]",
        num(*value),
        num(*lower),
        num(*upper),
        if (value - lower).abs() <= (upper - value).abs() { "lower" } else { "upper" },
        sig(lower + HOME_MARGIN * (upper - lower)),
        sig(upper - HOME_MARGIN * (upper - lower))
    )]
    HomeNearLimit {
        /// The joint.
        joint: String,
        /// The value.
        value: f64,
        /// Its lower limit.
        lower: f64,
        /// Its upper limit.
        upper: f64,
    },
    /// A home that is not a finite number (from a list given as numbers, e.g. Python's).
    #[error("home of joint `{joint}`: {value} is not a finite number")]
    HomeNotFinite {
        /// The joint.
        joint: String,
        /// The value.
        value: f64,
    },
    /// `--home-state` without `--srdf`, or the reverse.
    #[error("{0}")]
    HomeFlags(&'static str),
    /// The SRDF has no such `<group_state>`.
    #[error("{}: no <group_state name=\"{}\">{}", path.display(), excerpt(state), if available.is_empty() { " (it has none)".to_string() } else { format!(" (it has: {})", short_list(available)) })]
    NoState {
        /// The SRDF.
        path: PathBuf,
        /// The name asked for.
        state: String,
        /// The names it has.
        available: Vec<String>,
    },
}

fn suggest(s: &[String]) -> String {
    if s.is_empty() {
        String::new()
    } else {
        format!(" (did you mean {}?)", short_list(s))
    }
}

fn tips(base: &str, c: &[String]) -> String {
    if c.is_empty() {
        format!(": no link below `{}` ends a chain of 6 to 8 moving joints", excerpt(base))
    } else {
        format!(
            ": links that end a chain of 6 to 8 moving joints from `{}`: {}",
            excerpt(base),
            short_list(c)
        )
    }
}

/// Names joined by ", ", each cut to [`EXCERPT`] and at most twelve of them.
fn short_list(names: &[String]) -> String {
    let mut s: Vec<String> = names.iter().take(12).map(|n| excerpt(n)).collect();
    if names.len() > 12 {
        s.push(format!("and {} more", names.len() - 12));
    }
    s.join(", ")
}

fn joint_list(joints: &[String]) -> String {
    if joints.is_empty() {
        String::new()
    } else {
        format!(" ({})", short_list(joints))
    }
}

fn loop_text(joints: &[String]) -> String {
    let shown: Vec<String> = joints.iter().take(6).map(|j| format!("`{}`", excerpt(j))).collect();
    let more = if joints.len() > 6 { format!(" and {} more", joints.len() - 6) } else { String::new() };
    format!("{}{more}", shown.join(" -> "))
}

/// A joint's type in the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Revolute,
    Continuous,
    Prismatic,
    Fixed,
    Floating,
    Planar,
}

impl Kind {
    fn moves(self) -> bool {
        matches!(self, Self::Revolute | Self::Continuous | Self::Prismatic)
    }

    fn word(self) -> &'static str {
        match self {
            Self::Revolute => "revolute",
            Self::Continuous => "continuous",
            Self::Prismatic => "prismatic",
            Self::Fixed => "fixed",
            Self::Floating => "floating",
            Self::Planar => "planar",
        }
    }
}

/// `<limit>`: the attributes present (each finite; `velocity` and `effort` required and
/// not negative, as urdfdom reads them).
#[derive(Clone, Copy, Debug)]
struct Limit {
    lower: f64,
    upper: f64,
    velocity: f64,
}

/// One `<joint>` as read.
#[derive(Clone, Debug)]
struct UrdfJoint {
    name: String,
    line: u32,
    kind: Kind,
    parent: usize,
    child: usize,
    origin: Pose3<f64>,
    axis: Vector3<f64>,
    limit: Option<Limit>,
    mimic: Option<String>,
}

/// A URDF's tree: its links and joints (the rest of the file is not read), checked to be one
/// tree: every link but the root is the child of exactly one joint, and no joint is below
/// itself.
#[derive(Clone, Debug)]
struct Tree {
    path: PathBuf,
    name: String,
    /// The links' names, in the file's order.
    links: Vec<String>,
    /// Each link's line.
    link_lines: Vec<u32>,
    /// A link's index by name.
    index: HashMap<String, usize>,
    joints: Vec<UrdfJoint>,
    /// Each link's parent joint (index into `joints`), `None` for the root.
    parent_of: Vec<Option<usize>>,
    /// The root link.
    root: usize,
}

/// The chain read from a URDF, before the home: the description's parts and the joints'
/// names, in order from the base, with the lines of their joints.
#[derive(Clone, Debug)]
struct Cut {
    joints: Vec<(String, JointData<f64>)>,
    lines: Vec<u32>,
    tool: FrameData<f64>,
    tool_line: u32,
}

/// The line of a byte offset of a text, from the offsets of its line starts (computed once:
/// roxmltree's own `text_pos_at` scans the text from its start every time).
struct Lines(Vec<usize>);

impl Lines {
    fn of(text: &str) -> Self {
        let mut starts = vec![0];
        starts.extend(text.bytes().enumerate().filter(|(_, b)| *b == b'\n').map(|(i, _)| i + 1));
        Self(starts)
    }

    fn at(&self, pos: usize) -> u32 {
        u32::try_from(self.0.partition_point(|&s| s <= pos)).unwrap_or(u32::MAX)
    }

    fn of_node(&self, n: roxmltree::Node<'_, '_>) -> u32 {
        self.at(n.range().start)
    }
}

/// The text of `path`, at most [`MAX_BYTES`].
fn read_text(path: &Path) -> Result<String, UrdfError> {
    use std::io::Read;
    let io = |error| UrdfError::Io { path: path.to_path_buf(), error };
    let file = std::fs::File::open(path).map_err(io)?;
    let bytes = file.metadata().map_err(io)?.len();
    if bytes > MAX_BYTES {
        return Err(UrdfError::TooLarge { path: path.to_path_buf(), bytes });
    }
    let mut text = String::new();
    // Read through a bound as well: a file may grow between the size and the read.
    let read = file.take(MAX_BYTES + 1).read_to_string(&mut text).map_err(io)?;
    if read as u64 > MAX_BYTES {
        return Err(UrdfError::TooLarge { path: path.to_path_buf(), bytes: read as u64 });
    }
    Ok(text)
}

/// `text` parsed as XML, with at most [`MAX_NODES`] nodes, nested at most [`MAX_DEPTH`]
/// elements deep.
fn parse_xml<'a>(path: &Path, text: &'a str, lines: &Lines) -> Result<roxmltree::Document<'a>, UrdfError> {
    let options =
        roxmltree::ParsingOptions { nodes_limit: MAX_NODES, ..roxmltree::ParsingOptions::default() };
    let doc = roxmltree::Document::parse_with_options(text, options).map_err(|error| match error {
        roxmltree::Error::NodesLimitReached => UrdfError::TooManyNodes { path: path.to_path_buf() },
        // An undeclared `xacro:` prefix is an XML error; the template is the news.
        _ if text.contains("<xacro:") => UrdfError::Xacro { path: path.to_path_buf() },
        error => UrdfError::Xml { path: path.to_path_buf(), error },
    })?;
    // The depth, by a walk with an explicit stack (no recursion, each node once).
    let mut stack = vec![(doc.root_element(), 1usize)];
    while let Some((n, depth)) = stack.pop() {
        if depth > MAX_DEPTH {
            return Err(UrdfError::TooDeep {
                path: path.to_path_buf(),
                line: lines.of_node(n),
                element: n.tag_name().name().to_string(),
            });
        }
        stack.extend(n.children().filter(roxmltree::Node::is_element).map(|c| (c, depth + 1)));
    }
    Ok(doc)
}

/// Whether `path` names a xacro template (`.xacro`, `.urdf.xacro`).
pub fn is_xacro(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("xacro"))
}

/// Whether `path` names a URDF by its extension (`.urdf`) or a xacro template.
pub fn is_urdf(path: &Path) -> bool {
    is_xacro(path) || path.extension().is_some_and(|e| e.eq_ignore_ascii_case("urdf"))
}

/// The chain a URDF gives between two links, with its home: what an arm description is
/// made of (`ArmDescription::from_urdf` builds and checks it).
#[derive(Clone, Debug, PartialEq)]
pub struct UrdfChain {
    /// The robot's name (`<robot name>`).
    pub name: String,
    /// The base link seen from the platform's frame (the request's mount, or the identity).
    pub mount: FrameData<f64>,
    /// The moving joints from the base link outwards, each with its home.
    pub joints: Vec<JointData<f64>>,
    /// The tip link in the last moving joint's frame (the fixed joints after it folded in).
    pub tool: FrameData<f64>,
    /// The moving joints' names, in the same order.
    pub joint_names: Vec<String>,
    /// The line of each moving joint's `<joint>` in the file.
    pub joint_lines: Vec<u32>,
    /// The line of the joint above the tip link (the tool's last folded joint).
    pub tool_line: u32,
}

/// Reads the chain `request` asks for.
///
/// # Errors
/// [`UrdfError`], naming the file and the joint or link.
pub fn read(request: &UrdfRequest) -> Result<UrdfChain, UrdfError> {
    let path = &request.path;
    if is_xacro(path) {
        return Err(UrdfError::Xacro { path: path.clone() });
    }
    let text = read_text(path)?;
    let tree = Tree::parse(path, &text)?;
    let base = match &request.base_link {
        Some(b) => tree.link("--base-link", b)?,
        None => tree.root,
    };
    let Some(tip) = &request.tip_link else {
        return Err(UrdfError::NoTip {
            path: path.clone(),
            base: tree.links[base].clone(),
            candidates: tree.tips(base),
        });
    };
    let tip = tree.link("--tip-link", tip)?;
    let cut = tree.cut(base, tip)?;
    let names: Vec<String> = cut.joints.iter().map(|(n, _)| n.clone()).collect();
    let home = home(request, &cut)?;
    let joints: Vec<JointData<f64>> =
        cut.joints.iter().zip(&home).map(|((_, j), &h)| JointData { home: h, ..*j }).collect();
    let identity = FrameData { xyz: [0.0; 3], rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]] };
    Ok(UrdfChain {
        name: tree.name.clone(),
        mount: request.mount.unwrap_or(identity),
        joints,
        tool: cut.tool,
        joint_names: names,
        joint_lines: cut.lines,
        tool_line: cut.tool_line,
    })
}

/// A URDF number (`<limit>`'s attributes): finite, as urdfdom reads it (`inf`, `nan` and
/// `1e400` are not numbers there).
fn finite(text: &str) -> Option<f64> {
    text.trim().parse::<f64>().ok().filter(|x| x.is_finite())
}

/// Three finite numbers separated by whitespace (a fourth is not read: an attribute of a
/// million numbers is refused after four).
fn three(text: &str) -> Option<[f64; 3]> {
    let mut it = text.split_whitespace();
    let mut v = [0.0; 3];
    for x in &mut v {
        *x = it.next().and_then(finite)?;
    }
    it.next().is_none().then_some(v)
}

impl Tree {
    fn parse(path: &Path, text: &str) -> Result<Self, UrdfError> {
        let lines = Lines::of(text);
        let doc = parse_xml(path, text, &lines)?;
        // Generated URDFs often keep the xacro namespace's declaration: only its elements
        // (macros, properties, includes) or `${…}` expressions make a template.
        let template = doc.descendants().any(|n| {
            n.is_element() && n.tag_name().namespace() == Some(XACRO_NS)
                || n.attributes().any(|a| a.value().contains("${") || a.value().contains("$("))
        });
        if template {
            return Err(UrdfError::Xacro { path: path.to_path_buf() });
        }
        let root = doc.root_element();
        if !root.has_tag_name("robot") {
            return Err(UrdfError::NotRobot {
                path: path.to_path_buf(),
                srdf: false,
                found: root.tag_name().name().to_string(),
            });
        }
        let line = |n: roxmltree::Node<'_, '_>| lines.of_node(n);
        let missing = |n: roxmltree::Node<'_, '_>, what: String, m: &str| UrdfError::Missing {
            path: path.to_path_buf(),
            line: line(n),
            what,
            missing: m.to_string(),
        };
        let mut links = Vec::new();
        let mut link_lines = Vec::new();
        let mut index = HashMap::new();
        for n in root.children().filter(|n| n.has_tag_name("link")) {
            let name =
                n.attribute("name").ok_or_else(|| missing(n, "a <link>".into(), "`name` attribute"))?;
            if index.insert(name.to_string(), links.len()).is_some() {
                return Err(UrdfError::Duplicate {
                    path: path.to_path_buf(),
                    line: line(n),
                    kind: "link",
                    name: name.into(),
                });
            }
            links.push(name.to_string());
            link_lines.push(line(n));
        }
        if links.is_empty() {
            return Err(UrdfError::NoLinks { path: path.to_path_buf() });
        }
        let mut joints: Vec<UrdfJoint> = Vec::new();
        let mut joint_names = HashSet::new();
        let mut parent_of: Vec<Option<usize>> = vec![None; links.len()];
        for n in root.children().filter(|n| n.has_tag_name("joint")) {
            let name =
                n.attribute("name").ok_or_else(|| missing(n, "a <joint>".into(), "`name` attribute"))?;
            let what = format!("joint `{}`", excerpt(name));
            if !joint_names.insert(name) {
                return Err(UrdfError::Duplicate {
                    path: path.to_path_buf(),
                    line: line(n),
                    kind: "joint",
                    name: name.into(),
                });
            }
            let bad =
                |el: roxmltree::Node<'_, '_>, attribute: &str, text: &str, why: &str| UrdfError::BadValue {
                    path: path.to_path_buf(),
                    line: line(el),
                    what: what.clone(),
                    attribute: attribute.to_string(),
                    text: text.to_string(),
                    why: why.to_string(),
                };
            let kind_text =
                n.attribute("type").ok_or_else(|| missing(n, what.clone(), "`type` attribute"))?;
            let kind =
                match kind_text {
                    "revolute" => Kind::Revolute,
                    "continuous" => Kind::Continuous,
                    "prismatic" => Kind::Prismatic,
                    "fixed" => Kind::Fixed,
                    "floating" => Kind::Floating,
                    "planar" => Kind::Planar,
                    other => return Err(bad(
                        n,
                        "type",
                        other,
                        "is not a URDF joint type (revolute, continuous, prismatic, fixed, floating, planar)",
                    )),
                };
            let child_el = |tag: &str| n.children().find(|c| c.has_tag_name(tag));
            let link_of = |tag: &str| -> Result<usize, UrdfError> {
                let el =
                    child_el(tag).ok_or_else(|| missing(n, what.clone(), &format!("<{tag} link=\"…\">")))?;
                let link = el
                    .attribute("link")
                    .ok_or_else(|| missing(el, what.clone(), &format!("`link` attribute in <{tag}>")))?;
                index.get(link).copied().ok_or_else(|| UrdfError::DanglingJoint {
                    path: path.to_path_buf(),
                    line: line(el),
                    joint: name.into(),
                    role: tag_role(tag),
                    link: link.to_string(),
                })
            };
            let parent = link_of("parent")?;
            let child = link_of("child")?;
            if parent == child {
                return Err(UrdfError::SelfParent {
                    path: path.to_path_buf(),
                    line: line(n),
                    joint: name.into(),
                    link: links[child].clone(),
                });
            }
            let triple = |el: Option<roxmltree::Node<'_, '_>>, attr: &str, default: [f64; 3]| {
                let Some(el) = el else { return Ok(default) };
                let Some(text) = el.attribute(attr) else { return Ok(default) };
                three(text).ok_or_else(|| bad(el, attr, text, "is not three finite numbers"))
            };
            let origin_el = child_el("origin");
            let xyz = triple(origin_el, "xyz", [0.0; 3])?;
            let [r, p, y] = triple(origin_el, "rpy", [0.0; 3])?;
            let origin = Pose3::new(so3::from_rpy(r, p, y), Vector3::from(xyz));
            let axis = Vector3::from(triple(child_el("axis"), "xyz", [1.0, 0.0, 0.0])?);
            let limit = match child_el("limit") {
                None => None,
                Some(l) => {
                    let word = kind.word();
                    let num = |attr: &'static str, required: bool| -> Result<Option<f64>, UrdfError> {
                        let attribute = format!("<limit {attr}>");
                        match l.attribute(attr) {
                            None if required => Err(UrdfError::NoLimit {
                                path: path.to_path_buf(),
                                line: line(l),
                                joint: name.into(),
                                kind: word,
                                what: if attr == "effort" {
                                    "`effort` in its <limit>"
                                } else {
                                    "`velocity` in its <limit>"
                                },
                            }),
                            None => Ok(None),
                            Some(t) => match finite(t) {
                                None => Err(bad(
                                    l,
                                    &attribute,
                                    t,
                                    "is not a finite number (urdfdom refuses it too)",
                                )),
                                Some(x) if required && x < 0.0 => {
                                    Err(bad(l, &attribute, t, "is negative (urdfdom refuses it too)"))
                                }
                                Some(x) => Ok(Some(x)),
                            },
                        }
                    };
                    let lower = num("lower", false)?;
                    let upper = num("upper", false)?;
                    num("effort", true)?;
                    let velocity = num("velocity", true)?.unwrap_or(0.0);
                    // urdfdom's defaults: 0 for a missing lower or upper.
                    Some(Limit { lower: lower.unwrap_or(0.0), upper: upper.unwrap_or(0.0), velocity })
                }
            };
            if limit.is_none() && matches!(kind, Kind::Revolute | Kind::Prismatic) {
                return Err(UrdfError::NoLimit {
                    path: path.to_path_buf(),
                    line: line(n),
                    joint: name.into(),
                    kind: kind.word(),
                    what: "<limit>",
                });
            }
            let mimic = child_el("mimic").map(|m| m.attribute("joint").unwrap_or("?").to_string());
            if let Some(first) = parent_of[child] {
                return Err(UrdfError::TwoParents {
                    path: path.to_path_buf(),
                    line: line(n),
                    link: links[child].clone(),
                    first: joints[first].name.clone(),
                    second: name.into(),
                });
            }
            parent_of[child] = Some(joints.len());
            joints.push(UrdfJoint {
                name: name.into(),
                line: line(n),
                kind,
                parent,
                child,
                origin,
                axis,
                limit,
                mimic,
            });
        }
        let name = root.attribute("name").unwrap_or("robot").to_string();
        let mut tree =
            Self { path: path.to_path_buf(), name, links, link_lines, index, joints, parent_of, root: 0 };
        tree.root = tree.check_tree()?;
        Ok(tree)
    }

    /// The root, once the links are checked to make one tree: one link without a parent,
    /// every other link below it (else some joints form a loop, which is named).
    fn check_tree(&self) -> Result<usize, UrdfError> {
        let mut roots = (0..self.links.len()).filter(|&l| self.parent_of[l].is_none());
        let first = roots.next();
        if let (Some(a), Some(b)) = (first, roots.next()) {
            return Err(UrdfError::TwoRoots {
                path: self.path.clone(),
                line: self.link_lines[b],
                first: self.links[a].clone(),
                first_line: self.link_lines[a],
                second: self.links[b].clone(),
            });
        }
        // The links below the root, by a walk down with an explicit stack.
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); self.links.len()];
        for j in &self.joints {
            children[j.parent].push(j.child);
        }
        let mut reached = vec![false; self.links.len()];
        if let Some(r) = first {
            let mut stack = vec![r];
            reached[r] = true;
            while let Some(l) = stack.pop() {
                for &c in &children[l] {
                    if !reached[c] {
                        reached[c] = true;
                        stack.push(c);
                    }
                }
            }
        }
        let Some(start) = reached.iter().position(|r| !r) else {
            return Ok(first.unwrap_or(0));
        };
        // A link not below the root: walking up from it (each link has one parent) comes back
        // to a link already seen within as many steps as there are links: the loop.
        let mut seen = vec![usize::MAX; self.links.len()];
        let mut order = Vec::new();
        let mut link = start;
        while seen[link] == usize::MAX {
            seen[link] = order.len();
            let Some(j) = self.parent_of[link] else { break };
            order.push(j);
            link = self.joints[j].parent;
        }
        let from = seen[link].min(order.len());
        let mut cycle: Vec<usize> = order[from..].to_vec();
        cycle.reverse();
        // Named from the joint written first in the file.
        let first = (0..cycle.len()).min_by_key(|&k| self.joints[cycle[k]].line).unwrap_or(0);
        cycle.rotate_left(first);
        let line = cycle.first().map_or(0, |&j| self.joints[j].line);
        Err(UrdfError::Loop {
            path: self.path.clone(),
            line,
            joints: cycle.iter().map(|&j| self.joints[j].name.clone()).collect(),
        })
    }

    /// `name`'s index if it is a link of the file.
    fn link(&self, flag: &'static str, name: &str) -> Result<usize, UrdfError> {
        if let Some(&i) = self.index.get(name) {
            return Ok(i);
        }
        let lower = name.to_lowercase();
        let mut suggestions: Vec<String> = self
            .links
            .iter()
            .filter(|l| {
                let l = l.to_lowercase();
                l.contains(&lower) || lower.contains(&l) || common_prefix(&l, &lower) >= 4
            })
            .take(6)
            .cloned()
            .collect();
        if suggestions.is_empty() && flag == "--base-link" {
            suggestions.push(self.links[self.root].clone());
        }
        Err(UrdfError::UnknownLink { path: self.path.clone(), flag, link: name.into(), suggestions })
    }

    /// The joints from `base` down to `tip` (indices, base first), or `None` if `tip` is not
    /// below `base`. At most as many steps as there are joints (the tree has no loop).
    fn path_down(&self, base: usize, tip: usize) -> Option<Vec<usize>> {
        let mut up = Vec::new();
        let mut link = tip;
        while link != base {
            let j = self.parent_of[link]?;
            if up.len() >= self.joints.len() {
                return None;
            }
            up.push(j);
            link = self.joints[j].parent;
        }
        up.reverse();
        Some(up)
    }

    /// The links at the end of an arm below `base`: their chain from `base` has 6 to 8
    /// moving joints and none that cannot be driven, and nothing below them moves (the last
    /// moving joint's link and the frames fixed to it: a flange, a tool, a sensor).
    fn tips(&self, base: usize) -> Vec<String> {
        // Whether anything below a link moves, from the leaves up.
        let mut moving_below = vec![false; self.links.len()];
        for j in &self.joints {
            if j.kind.moves() {
                let mut link = j.parent;
                while !moving_below[link] {
                    moving_below[link] = true;
                    match self.parent_of[link] {
                        Some(k) => link = self.joints[k].parent,
                        None => break,
                    }
                }
            }
        }
        (0..self.links.len())
            .filter(|&l| !moving_below[l])
            .filter(|&l| {
                self.path_down(base, l).is_some_and(|p| {
                    let js = p.iter().map(|&j| &self.joints[j]);
                    let n = js.clone().filter(|j| j.kind.moves()).count();
                    (MIN_SPATIAL_JOINTS..=MAX_JOINTS).contains(&n)
                        && js
                            .clone()
                            .all(|j| !matches!(j.kind, Kind::Floating | Kind::Planar) && j.mimic.is_none())
                })
            })
            .take(12)
            .map(|l| self.links[l].clone())
            .collect()
    }

    /// The chain from `base` to `tip`, fixed joints folded (module docs).
    fn cut(&self, base: usize, tip: usize) -> Result<Cut, UrdfError> {
        let path = &self.path;
        let (base_name, tip_name) = (&self.links[base], &self.links[tip]);
        let Some(down) = self.path_down(base, tip) else {
            let mut chain = vec![tip_name.as_str()];
            let mut link = tip;
            while let Some(j) = self.parent_of[link] {
                link = self.joints[j].parent;
                chain.push(&self.links[link]);
            }
            let path_up = if chain.len() > 8 {
                let n = chain.len();
                format!(
                    "{} -> … ({} links) -> {}",
                    chain[..4].join(" -> "),
                    n - 6,
                    chain[n - 2..].join(" -> ")
                )
            } else {
                chain.join(" -> ")
            };
            return Err(UrdfError::NotBelow {
                path: path.clone(),
                line: self.link_lines[tip],
                base: base_name.clone(),
                tip: tip_name.clone(),
                path_up,
            });
        };
        let mut joints = Vec::new();
        let mut lines = Vec::new();
        let mut pending = Pose3::<f64>::identity();
        let mut tool_line = self.link_lines[tip];
        for &k in &down {
            let j = &self.joints[k];
            tool_line = j.line;
            let unsupported = |kind: String| UrdfError::UnsupportedJoint {
                path: path.clone(),
                line: j.line,
                joint: j.name.clone(),
                kind,
                base: base_name.clone(),
                tip: tip_name.clone(),
            };
            match j.kind {
                Kind::Floating => return Err(unsupported("floating".into())),
                Kind::Planar => return Err(unsupported("planar".into())),
                _ if j.mimic.is_some() => {
                    return Err(unsupported(format!(
                        "a mimic of `{}`",
                        excerpt(j.mimic.as_deref().unwrap_or("?"))
                    )))
                }
                Kind::Fixed => {
                    pending = pending.compose(&j.origin);
                    continue;
                }
                Kind::Revolute | Kind::Continuous | Kind::Prismatic => {}
            }
            let norm = j.axis.norm();
            if norm == 0.0 || !norm.is_finite() {
                return Err(UrdfError::ZeroAxis { path: path.clone(), line: j.line, joint: j.name.clone() });
            }
            let (limits, velocity) = match (j.kind, j.limit) {
                (Kind::Continuous, l) => ([f64::NEG_INFINITY, f64::INFINITY], l.map(|l| l.velocity)),
                (_, None) => {
                    return Err(UrdfError::NoLimit {
                        path: path.clone(),
                        line: j.line,
                        joint: j.name.clone(),
                        kind: j.kind.word(),
                        what: "<limit>",
                    })
                }
                (_, Some(l)) => {
                    if l.lower >= l.upper {
                        return Err(UrdfError::BadValue {
                            path: path.clone(),
                            line: j.line,
                            what: format!("joint `{}`", excerpt(&j.name)),
                            attribute: "<limit lower upper>".into(),
                            text: format!("{} {}", num(l.lower), num(l.upper)),
                            why: "is an empty range: a joint the law drives needs lower < upper".into(),
                        });
                    }
                    ([l.lower, l.upper], Some(l.velocity))
                }
            };
            if velocity == Some(0.0) {
                return Err(UrdfError::BadValue {
                    path: path.clone(),
                    line: j.line,
                    what: format!("joint `{}`", excerpt(&j.name)),
                    attribute: "<limit velocity>".into(),
                    text: "0".into(),
                    why:
                        "is no speed: a joint the law drives must be able to move (give its speed limit, > 0)"
                            .into(),
                });
            }
            let origin = pending.compose(&j.origin);
            pending = Pose3::identity();
            lines.push(j.line);
            joints.push((
                j.name.clone(),
                JointData {
                    kind: if j.kind == Kind::Prismatic { JointKind::Prismatic } else { JointKind::Revolute },
                    origin: frame_data(&origin),
                    axis: (j.axis / norm).into(),
                    limits,
                    home: 0.0,
                    max_velocity: velocity.unwrap_or(f64::INFINITY),
                },
            ));
        }
        if !(MIN_SPATIAL_JOINTS..=MAX_JOINTS).contains(&joints.len()) {
            return Err(UrdfError::JointCount {
                path: path.clone(),
                line: self.link_lines[tip],
                base: base_name.clone(),
                tip: tip_name.clone(),
                joints: joints.into_iter().map(|(n, _)| n).collect(),
            });
        }
        Ok(Cut { joints, lines, tool: frame_data(&pending), tool_line })
    }
}

fn tag_role(tag: &str) -> &'static str {
    if tag == "parent" {
        "parent"
    } else {
        "child"
    }
}

fn common_prefix(a: &str, b: &str) -> usize {
    a.chars().zip(b.chars()).take_while(|(x, y)| x == y).count()
}

/// A pose as plain numbers.
pub fn frame_data(p: &Pose3<f64>) -> FrameData<f64> {
    let r: &Matrix3<f64> = &p.rotation;
    FrameData {
        xyz: [p.translation[0], p.translation[1], p.translation[2]],
        rotation: core::array::from_fn(|i| core::array::from_fn(|j| r[(i, j)])),
    }
}

/// The home of `cut`'s joints from the request (module docs).
fn home(request: &UrdfRequest, cut: &Cut) -> Result<Vec<f64>, UrdfError> {
    let names: Vec<String> = cut.joints.iter().map(|(n, _)| n.clone()).collect();
    let mut values: Vec<Option<f64>> = vec![None; names.len()];
    let mut source = Vec::new();
    match (&request.srdf, &request.home_state) {
        (Some(srdf), Some(state)) => {
            let named = srdf_state(srdf, state)?;
            for (i, n) in names.iter().enumerate() {
                if let Some(&(_, v)) = named.iter().find(|(m, _)| m == n) {
                    values[i] = Some(v);
                }
            }
            source.push(format!("--srdf {} --home-state {}", srdf.display(), excerpt(state)));
        }
        (Some(_), None) => {
            return Err(UrdfError::HomeFlags("--srdf needs --home-state NAME (a <group_state> of the file)"))
        }
        (None, Some(_)) => return Err(UrdfError::HomeFlags("--home-state needs --srdf FILE")),
        (None, None) => {}
    }
    match &request.home {
        Some(HomeList::Values(v)) => {
            if request.srdf.is_some() {
                return Err(UrdfError::HomeFlags(
                    "--home with every joint's value replaces --home-state: give one, or --home name=value,… to \
                     override the state's joints",
                ));
            }
            if v.len() != names.len() {
                return Err(UrdfError::HomeLength { found: v.len(), joints: names });
            }
            values = v.iter().copied().map(Some).collect();
        }
        Some(HomeList::Named(pairs)) => {
            let mut given = HashSet::new();
            for (n, v) in pairs {
                let Some(i) = names.iter().position(|m| m == n) else {
                    return Err(UrdfError::HomeUnknownJoint { name: n.clone(), joints: names });
                };
                if !given.insert(i) {
                    return Err(UrdfError::HomeSyntax {
                        item: excerpt(n),
                        why: format!("joint `{}` is named twice: give each joint once", excerpt(n)),
                    });
                }
                values[i] = Some(*v);
            }
            source.push("--home".into());
        }
        None => {}
    }
    if values.iter().all(Option::is_none) {
        return Err(UrdfError::NoHome { path: request.path.clone(), joints: names });
    }
    let missing: Vec<String> =
        names.iter().zip(&values).filter(|(_, v)| v.is_none()).map(|(n, _)| n.clone()).collect();
    if !missing.is_empty() {
        return Err(UrdfError::HomeIncomplete { source_name: source.join(" and "), missing });
    }
    let home: Vec<f64> = values.into_iter().map(|v| v.unwrap_or_default()).collect();
    for ((name, j), &h) in cut.joints.iter().zip(&home) {
        check_home(name, j.limits, h)?;
    }
    Ok(home)
}

/// A joint's home against its limits (module docs): finite, strictly inside, and at least
/// [`HOME_MARGIN`] of a bounded joint's range from each limit.
///
/// # Errors
/// The rule the home breaks, naming the joint.
pub fn check_home(joint: &str, limits: [f64; 2], home: f64) -> Result<(), UrdfError> {
    let [lower, upper] = limits;
    if !home.is_finite() {
        return Err(UrdfError::HomeNotFinite { joint: joint.into(), value: home });
    }
    // Empty limits (or NaN ones) are the chain's rule to refuse, not the home's.
    if lower.partial_cmp(&upper) != Some(std::cmp::Ordering::Less) {
        return Ok(());
    }
    if !(home > lower && home < upper) {
        return Err(UrdfError::HomeOutside { joint: joint.into(), value: home, lower, upper });
    }
    if lower.is_finite() && upper.is_finite() {
        let m = HOME_MARGIN * (upper - lower);
        if home < lower + m || home > upper - m {
            return Err(UrdfError::HomeNearLimit { joint: joint.into(), value: home, lower, upper });
        }
    }
    Ok(())
}

/// The joint values of an SRDF's `<group_state name="state">` (every group state of that
/// name, in the file's order).
///
/// # Errors
/// The file cannot be read or parsed, or has no such state.
pub fn srdf_state(path: &Path, state: &str) -> Result<Vec<(String, f64)>, UrdfError> {
    let text = read_text(path)?;
    let lines = Lines::of(&text);
    let doc = parse_xml(path, &text, &lines)?;
    let root = doc.root_element();
    if !root.has_tag_name("robot") {
        return Err(UrdfError::NotRobot {
            path: path.to_path_buf(),
            srdf: true,
            found: root.tag_name().name().into(),
        });
    }
    let states: Vec<_> = root.children().filter(|n| n.has_tag_name("group_state")).collect();
    let chosen: Vec<_> = states.iter().filter(|n| n.attribute("name") == Some(state)).collect();
    if chosen.is_empty() {
        let mut available: Vec<String> =
            states.iter().filter_map(|n| n.attribute("name")).map(str::to_string).collect();
        available.dedup();
        return Err(UrdfError::NoState { path: path.to_path_buf(), state: state.into(), available });
    }
    let mut out = Vec::new();
    for s in chosen {
        for j in s.children().filter(|n| n.has_tag_name("joint")) {
            let line = lines.of_node(j);
            let name = j.attribute("name").ok_or_else(|| UrdfError::Missing {
                path: path.to_path_buf(),
                line,
                what: format!("a <joint> of group_state `{}`", excerpt(state)),
                missing: "`name` attribute".into(),
            })?;
            let text = j.attribute("value").unwrap_or("");
            // A group state's value may list several numbers (a multi-DOF joint): those are
            // not joints of a serial chain; the first number is kept for a single-DOF one.
            let v = text.split_whitespace().next().and_then(finite);
            let v = v.ok_or_else(|| UrdfError::BadValue {
                path: path.to_path_buf(),
                line,
                what: format!("joint `{}` of group_state `{}`", excerpt(name), excerpt(state)),
                attribute: "value".into(),
                text: text.into(),
                why: "is not a finite number".into(),
            })?;
            out.push((name.to_string(), v));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reader and the arm description's checks, as `--arm robot.urdf` runs them.
    fn load(request: &UrdfRequest) -> Result<crate::domain::arm::ArmDescription, UrdfError> {
        crate::domain::arm::ArmDescription::from_urdf(request)
    }

    /// A small mobile manipulator: a fixed mount, a prismatic torso, six revolute joints of
    /// which the fifth is continuous, a fixed tool; and a wheel and a camera off the chain.
    fn robot(change: impl Fn(String) -> String) -> String {
        let mut joints = String::new();
        let mut links = String::from(r#"<link name="base_footprint"/><link name="base_link"/>"#);
        joints.push_str(
            r#"<joint name="base_joint" type="fixed"><parent link="base_footprint"/><child link="base_link"/><origin xyz="0 0 0.1" rpy="0 0 0"/></joint>"#,
        );
        joints.push_str(r#"<joint name="torso" type="prismatic"><parent link="base_link"/><child link="l0"/><origin xyz="0 0 0.5"/><axis xyz="0 0 1"/><limit lower="0" upper="0.35" effort="100" velocity="0.07"/></joint>"#);
        links.push_str(r#"<link name="l0"/>"#);
        for i in 1..=6 {
            let kind = if i == 5 { "continuous" } else { "revolute" };
            let axis = if i % 2 == 0 { "0 1 0" } else { "0 0 2" };
            joints.push_str(&format!(
                r#"<joint name="j{i}" type="{kind}"><parent link="l{p}"/><child link="l{i}"/><origin xyz="0.1 0 0.2" rpy="0.1 0.2 0.3"/><axis xyz="{axis}"/><limit lower="-2" upper="2" effort="10" velocity="2"/></joint>"#,
                p = i - 1
            ));
            links.push_str(&format!(r#"<link name="l{i}"/>"#));
        }
        joints.push_str(r#"<joint name="tool_joint" type="fixed"><parent link="l6"/><child link="tool"/><origin xyz="0 0 0.05" rpy="1.5707963267948966 0 0"/></joint>"#);
        joints.push_str(r#"<joint name="wheel" type="continuous"><parent link="base_link"/><child link="wheel_link"/><axis xyz="0 1 0"/></joint>"#);
        joints.push_str(
            r#"<joint name="camera" type="fixed"><parent link="l3"/><child link="camera_link"/></joint>"#,
        );
        links.push_str(r#"<link name="tool"/><link name="wheel_link"/><link name="camera_link"/>"#);
        change(format!(
            r#"<?xml version="1.0"?><robot name="mini">{links}{joints}<transmission><joint name="j1"/></transmission></robot>"#
        ))
    }

    fn write(name: &str, text: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("companion-urdf-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    fn request(text: &str, name: &str) -> UrdfRequest {
        UrdfRequest {
            path: write(name, text),
            base_link: Some("base_footprint".into()),
            tip_link: Some("tool".into()),
            home: Some(HomeList::Values(vec![0.1, 0.2, 0.3, 0.4, 0.5, 7.0, 0.6])),
            ..UrdfRequest::default()
        }
    }

    fn refusal(change: impl Fn(String) -> String, name: &str) -> String {
        load(&request(&robot(change), name)).unwrap_err().to_string()
    }

    /// The chain: fixed joints folded into the next joint's origin and the tool, the axes
    /// normalised, the continuous joint unbounded, the names and speeds read; the end
    /// effector equals the product of the file's transforms along the path, computed here
    /// from the XML's numbers.
    #[test]
    fn the_chain_is_the_path_between_the_links() {
        let d = load(&request(&robot(|s| s), "ok.urdf")).expect("valid");
        assert_eq!(d.name, "mini");
        assert_eq!(d.joint_names, ["torso", "j1", "j2", "j3", "j4", "j5", "j6"]);
        assert_eq!(d.joints[0].kind, JointKind::Prismatic);
        assert_eq!(d.joints[0].limits, [0.0, 0.35]);
        assert_eq!(d.joints[0].max_velocity, 0.07);
        assert_eq!(d.joints[0].origin.xyz, [0.0, 0.0, 0.6], "the fixed base_joint folded in");
        assert_eq!(d.joints[1].axis, [0.0, 0.0, 1.0], "normalised");
        assert_eq!(d.joints[5].limits, [f64::NEG_INFINITY, f64::INFINITY], "continuous");
        assert_eq!(d.joints[5].home, 7.0);
        let c = d.chain::<f64, 7>().expect("valid chain");
        // The reference: the file's transforms multiplied along the path.
        let o = Pose3::new(so3::from_rpy(0.1, 0.2, 0.3), Vector3::new(0.1, 0.0, 0.2));
        let q = companion_core::nalgebra::SVector::<f64, 7>::from_fn(|i, _| 0.3 * i as f64 - 0.5);
        let mut f = Pose3::new(Matrix3::identity(), Vector3::new(0.0, 0.0, 0.6 + q[0]));
        for i in 1..7 {
            let axis = if i % 2 == 0 { Vector3::y() } else { Vector3::z() };
            f = f.compose(&o).compose(&Pose3::new(so3::exp(&(axis * q[i])), Vector3::zeros()));
        }
        f = f.compose(&Pose3::new(
            so3::from_rpy(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
            Vector3::new(0.0, 0.0, 0.05),
        ));
        let e = c.end_effector(&q);
        assert!((e.translation - f.translation).norm() < 1e-14 && (e.rotation - f.rotation).norm() < 1e-14);
    }

    /// Every refusal names the joint or link (and the line of the file).
    #[test]
    fn bad_files_are_refused_by_name() {
        let no_limit =
            |s: String| s.replacen(r#"<limit lower="-2" upper="2" effort="10" velocity="2"/>"#, "", 1);
        let e = refusal(no_limit, "nolimit.urdf");
        assert!(e.contains("joint `j1` (revolute) has no <limit>") && e.contains("nolimit.urdf:1"), "{e}");
        let e = refusal(|s| s.replacen(r#" velocity="2""#, "", 1), "novel.urdf");
        assert!(e.contains("joint `j1` (revolute) has no `velocity` in its <limit>"), "{e}");
        let e = refusal(|s| s.replace(r#"<axis xyz="0 1 0"/>"#, r#"<axis xyz="0 0 0"/>"#), "zero.urdf");
        assert!(e.contains("joint `j2` has a zero <axis>"), "{e}");
        let e = refusal(|s| s.replacen(r#"type="revolute""#, r#"type="floating""#, 1), "float.urdf");
        assert!(e.contains("joint `j1` between `base_footprint` and `tool` is floating"), "{e}");
        let e = refusal(|s| s.replacen(r#"type="revolute""#, r#"type="planar""#, 1), "planar.urdf");
        assert!(e.contains("joint `j1`") && e.contains("is planar"), "{e}");
        let e = refusal(
            |s| {
                s.replacen("</joint>", r#"<mimic joint="j9"/></joint>"#, 2).replacen(
                    r#"<mimic joint="j9"/></joint>"#,
                    "</joint>",
                    1,
                )
            },
            "mimic.urdf",
        );
        assert!(e.contains("joint `torso`") && e.contains("a mimic of `j9`"), "{e}");
        let e = refusal(|s| s.replacen(r#"type="revolute""#, r#"type="hinge""#, 1), "type.urdf");
        assert!(e.contains(r#"joint `j1`: type="hinge" is not a URDF joint type"#), "{e}");
        let e = refusal(|s| s.replacen(r#"xyz="0.1 0 0.2""#, r#"xyz="0.1 0""#, 1), "xyz.urdf");
        assert!(e.contains(r#"joint `j1`: xyz="0.1 0" is not three finite numbers"#), "{e}");
        let e = refusal(|s| s.replace("</robot>", r#"<link name="l2"/></robot>"#), "dup.urdf");
        assert!(e.contains("two links are named `l2`"), "{e}");
        let e = refusal(|s| s.replace(r#"<child link="camera_link"/>"#, r#"<child link="l4"/>"#), "two.urdf");
        assert!(e.contains("link `l4` is the child of two joints (`j4` and `camera`)"), "{e}");
        let e = refusal(
            |s| s.replace(r#"<child link="camera_link"/>"#, r#"<child link="nowhere"/>"#),
            "dangle.urdf",
        );
        assert!(e.contains("joint `camera` names the child link `nowhere`"), "{e}");
        let e = refusal(|s| s.replace("<robot", "<robo").replace("</robot>", "</robo>"), "root.urdf");
        assert!(e.contains("not a URDF file: its root element is <robo>"), "{e}");
        let e = refusal(|s| s.replace("</robot>", "<link"), "broken.urdf");
        assert!(e.contains("broken.urdf:1: not well-formed XML"), "{e}");
        let e = refusal(
            |s| {
                s.replace(r#"<robot name="mini">"#, r#"<robot name="mini" xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:property name="a" value="1"/>"#)
            },
            "tmpl.urdf",
        );
        assert!(e.contains("is a xacro template") && e.contains("xacro "), "{e}");
        // A generated URDF keeps the namespace's declaration: that alone is no template.
        let declared = robot(|s| {
            s.replace(
                r#"<robot name="mini">"#,
                r#"<robot name="mini" xmlns:xacro="http://www.ros.org/wiki/xacro">"#,
            )
        });
        assert!(load(&request(&declared, "declared.urdf")).is_ok());
        let mut r = request(&robot(|s| s), "a.urdf.xacro");
        assert!(load(&r).unwrap_err().to_string().contains("a.urdf.xacro is a xacro template"));
        r.path = PathBuf::from("/nonexistent/robot.urdf");
        assert!(load(&r).unwrap_err().to_string().starts_with("cannot read /nonexistent/robot.urdf"));
        // A limit the chain's rules refuse, named by the joint.
        let e = refusal(|s| s.replacen(r#" velocity="2""#, r#" velocity="0""#, 1), "zerov.urdf");
        assert!(e.contains("zerov.urdf:1: joint `j1`: <limit velocity>=\"0\" is no speed"), "{e}");
        let e = refusal(|s| s.replacen(r#"lower="-2" upper="2""#, r#"lower="2" upper="2""#, 1), "empty.urdf");
        assert!(e.contains("empty.urdf:1: joint `j1`: <limit lower upper>=\"2 2\" is an empty range"), "{e}");
    }

    /// The links: the base defaults to the root, the tip is required (the candidates listed),
    /// a wrong name gets suggestions, and the chain must go down from the base to the tip with
    /// 6 to 8 moving joints.
    #[test]
    fn the_cut_is_checked() {
        let text = robot(|s| s);
        let mut r = request(&text, "cut.urdf");
        r.base_link = None;
        assert_eq!(load(&r).expect("the root is the base").joint_names.len(), 7);
        r.tip_link = None;
        let e = load(&r).unwrap_err().to_string();
        assert!(e.contains("give --tip-link") && e.contains("from `base_footprint`: l6, tool"), "{e}");
        r.tip_link = Some("tol".into());
        let e = load(&r).unwrap_err().to_string();
        assert_eq!(e, format!("--tip-link tol: {} has no such link", r.path.display()));
        r.tip_link = Some("too".into());
        assert!(load(&r).unwrap_err().to_string().ends_with("(did you mean tool?)"));
        r.tip_link = Some("wheel_link".into());
        r.base_link = Some("l1".into());
        let e = load(&r).unwrap_err().to_string();
        assert!(e.contains("link `wheel_link` is not below `l1`: from `wheel_link` up, the tree goes wheel_link -> base_link -> base_footprint"), "{e}");
        r.base_link = Some("l1".into());
        r.tip_link = Some("tool".into());
        let e = load(&r).unwrap_err().to_string();
        assert!(e.contains("the chain from `l1` to `tool` has 5 moving joint(s) (j2, j3, j4, j5, j6): a spatial arm needs 6 to 8"), "{e}");
    }

    /// The home: a list (its length checked), names over an SRDF state (missing joints named,
    /// an unknown name refused), no home at all (the message says how), a value at a limit.
    #[test]
    fn the_home_is_given_and_checked() {
        let text = robot(|s| s);
        let mut r = request(&text, "home.urdf");
        r.home = None;
        let e = load(&r).unwrap_err().to_string();
        assert!(e.contains("need a home") && e.contains("give --home q1,…,q7 in this order: torso, j1, j2, j3, j4, j5, j6; or --srdf FILE --home-state NAME"), "{e}");
        r.home = Some(HomeList::Values(vec![0.1; 6]));
        assert_eq!(
            load(&r).unwrap_err().to_string(),
            "--home has 6 values: the chain has 7 joints (torso, j1, j2, j3, j4, j5, j6)"
        );
        r.home = Some(HomeList::Values(vec![0.1, 0.2, 0.3, 2.0, 0.5, 0.6, 0.7]));
        assert_eq!(
            load(&r).unwrap_err().to_string(),
            "home of joint `j3`: 2 is not strictly inside its limits [-2, 2]"
        );
        let srdf = write(
            "mini.srdf",
            r#"<robot name="mini"><group_state name="ready" group="arm"><joint name="j1" value="0.1"/><joint name="j2" value="0.2"/><joint name="j3" value="0.3"/><joint name="j4" value="0.4"/><joint name="j5" value="9"/><joint name="j6" value="0.6"/><joint name="other" value="5"/></group_state><group_state name="up" group="arm"/></robot>"#,
        );
        r.srdf = Some(srdf.clone());
        r.home_state = Some("ready".into());
        r.home = None;
        let e = load(&r).unwrap_err().to_string();
        assert!(
            e.contains("--home-state ready gives no value for 1 of the chain's joints: add --home torso=…"),
            "{e}"
        );
        r.home = Some(HomeList::parse("torso=0.2, j6=-0.5").unwrap());
        let d = load(&r).expect("the torso by name, j6 overridden");
        assert_eq!(d.joints.iter().map(|j| j.home).collect::<Vec<_>>(), [0.2, 0.1, 0.2, 0.3, 0.4, 9.0, -0.5]);
        r.home = Some(HomeList::parse("elbow=0.2").unwrap());
        assert!(load(&r)
            .unwrap_err()
            .to_string()
            .starts_with("--home elbow=…: `elbow` is not a joint of the chain (torso, j1"));
        r.home_state = Some("nap".into());
        let e = load(&r).unwrap_err().to_string();
        assert_eq!(e, format!("{}: no <group_state name=\"nap\"> (it has: ready, up)", srdf.display()));
        r.home_state = None;
        assert_eq!(
            load(&r).unwrap_err().to_string(),
            "--srdf needs --home-state NAME (a <group_state> of the file)"
        );
        assert!(HomeList::parse("1,x").unwrap_err().to_string().contains("not a finite number"));
        assert!(HomeList::parse("a=1,2").unwrap_err().to_string().contains("give every joint as name=value"));
        assert!(HomeList::parse(" , ").is_err());
        assert_eq!(HomeList::parse("1, -2.5").unwrap(), HomeList::Values(vec![1.0, -2.5]));
    }

    /// `robot` with one element per line, as files are written: line numbers mean something.
    fn lined(change: impl Fn(String) -> String) -> String {
        change(robot(|s| s).replace("><", ">\n<"))
    }

    /// The line of the first occurrence of `pat` in `text` (1-based).
    fn line_of(text: &str, pat: &str) -> usize {
        text[..text.find(pat).expect(pat)].matches('\n').count() + 1
    }

    /// A tree that is no tree is refused by name and line, whatever the loop: a joint whose
    /// parent is its child, two joints in a loop off the chain, a loop through the root (no
    /// root at all), a second root, a link with two parents — each in time and memory bounded
    /// by the file (the fuzz in runtime/tests/urdf_fuzz.rs measures both).
    #[test]
    fn a_tree_that_loops_is_refused_naming_the_joints_and_the_line() {
        let text = lined(|s| s.replace(r#"<child link="camera_link"/>"#, r#"<child link="l3"/>"#));
        // camera: parent l3, child l3.
        let e = load(&request(&text, "selfp.urdf")).unwrap_err().to_string();
        let at = line_of(&text, r#"<joint name="camera""#);
        assert!(
            e.contains(&format!("selfp.urdf:{at}: joint `camera` has `l3` as both parent and child link")),
            "{e}"
        );
        // Two joints in a loop off the chain: x (a -> b) and y (b -> a).
        let loop2 = lined(|s| {
            s.replace(
                "<transmission>",
                "<link name=\"a\"/>\n<link name=\"b\"/>\n<joint name=\"x\" type=\"fixed\">\n<parent link=\"a\"/><child link=\"b\"/></joint>\n<joint name=\"y\" type=\"fixed\">\n<parent link=\"b\"/><child link=\"a\"/></joint>\n<transmission>",
            )
        });
        let e = load(&request(&loop2, "loop.urdf")).unwrap_err().to_string();
        let at = line_of(&loop2, r#"<joint name="x""#);
        assert!(e.contains(&format!("loop.urdf:{at}: joints ")) && e.contains("form a loop"), "{e}");
        assert!(e.contains("`x`") && e.contains("`y`"), "{e}");
        // A loop through the root: base_footprint made the child of the tool.
        let through = lined(|s| {
            s.replace(
                "<transmission>",
                "<joint name=\"back\" type=\"fixed\">\n<parent link=\"tool\"/><child link=\"base_footprint\"/></joint>\n<transmission>",
            )
        });
        let e = load(&request(&through, "root.urdf")).unwrap_err().to_string();
        assert!(
            e.contains("form a loop") && e.contains("`base_joint` -> `torso`") && e.contains("and 4 more"),
            "{e}"
        );
        // A second root.
        let two = lined(|s| s.replace("<transmission>", "<link name=\"lonely\"/>\n<transmission>"));
        let e = load(&request(&two, "roots.urdf")).unwrap_err().to_string();
        let at = line_of(&two, r#"<link name="lonely""#);
        assert!(
            e.contains(&format!("roots.urdf:{at}: link `lonely` is a second root (no joint's child) beside `base_footprint` (line 3)")),
            "{e}"
        );
        // A link with two parents, on the second joint's line.
        let text = lined(|s| s.replace(r#"<child link="camera_link"/>"#, r#"<child link="l4"/>"#));
        let e = load(&request(&text, "two.urdf")).unwrap_err().to_string();
        let at = line_of(&text, r#"<joint name="camera""#);
        assert!(
            e.contains(&format!("two.urdf:{at}: link `l4` is the child of two joints (`j4` and `camera`)")),
            "{e}"
        );
        // A long loop (1 000 joints around it) is walked once and named shortly.
        let mut ring = String::new();
        for i in 0..1000 {
            ring.push_str(&format!(
                "<link name=\"r{i}\"/><joint name=\"rj{i}\" type=\"fixed\"><parent link=\"r{i}\"/><child link=\"r{}\"/></joint>\n",
                (i + 1) % 1000
            ));
        }
        let big = lined(|s| s.replace("<transmission>", &format!("{ring}<transmission>")));
        let e = load(&request(&big, "ring.urdf")).unwrap_err().to_string();
        assert!(e.contains("form a loop") && e.contains("and 994 more"), "{e}");
        assert!(e.len() < 400, "{} characters: {e}", e.len());
    }

    /// What urdfdom refuses, refused here too, with the line and the URDF's attribute: a
    /// number that is not finite anywhere, a negative or missing effort or velocity, a joint
    /// without limits, XML nested deeper than tinyxml2 reads — also off the chain.
    #[test]
    fn what_urdfdom_refuses_is_refused_naming_the_attribute_and_the_line() {
        let limit = r#"<limit lower="-2" upper="2" effort="10" velocity="2"/>"#;
        let at = |text: &str| line_of(text, limit);
        for (to, says) in [
            (
                r#"<limit lower="-2" upper="2" effort="10" velocity="inf"/>"#,
                r#"<limit velocity>="inf" is not a finite number"#,
            ),
            (
                r#"<limit lower="-2" upper="2" effort="-5" velocity="2"/>"#,
                r#"<limit effort>="-5" is negative"#,
            ),
            (
                r#"<limit lower="-2" upper="2" effort="10" velocity="-1"/>"#,
                r#"<limit velocity>="-1" is negative"#,
            ),
            (
                r#"<limit lower="nan" upper="2" effort="10" velocity="2"/>"#,
                r#"<limit lower>="nan" is not a finite number"#,
            ),
            (
                r#"<limit lower="-1e400" upper="2" effort="10" velocity="2"/>"#,
                r#"<limit lower>="-1e400" is not a finite number"#,
            ),
            (r#"<limit lower="-2" upper="2" velocity="2"/>"#, "(revolute) has no `effort` in its <limit>"),
        ] {
            let text = lined(|s| s.replacen(limit, to, 1));
            let e = load(&request(&text, "limit.urdf")).unwrap_err().to_string();
            assert!(
                e.contains(&format!("limit.urdf:{}: joint `j1`", at(&lined(|s| s)))) && e.contains(says),
                "{to}: {e}"
            );
        }
        // Off the chain: the wheel (continuous) with a limit without effort, a camera's origin.
        let wheel = r#"<child link="wheel_link"/><axis xyz="0 1 0"/>"#;
        let text =
            robot(|s| s.replace(wheel, &format!(r#"{wheel}<limit velocity="1"/>"#))).replace("><", ">\n<");
        let e = load(&request(&text, "wheel.urdf")).unwrap_err().to_string();
        assert!(e.contains("joint `wheel` (continuous) has no `effort` in its <limit>"), "{e}");
        let text = lined(|s| {
            s.replace(
                r#"<child link="camera_link"/>"#,
                r#"<child link="camera_link"/><origin xyz="0 0 infinity"/>"#,
            )
        });
        let e = load(&request(&text, "cam.urdf")).unwrap_err().to_string();
        let line = line_of(&text, "<origin xyz=\"0 0 infinity\"");
        assert!(
            e.contains(&format!(
                "cam.urdf:{line}: joint `camera`: xyz=\"0 0 infinity\" is not three finite numbers"
            )),
            "{e}"
        );
        // Nested deeper than 500 elements (in an extension element), and just within it.
        let deep = |n: usize| {
            lined(|s| {
                s.replace("<transmission>", &format!("{}{}<transmission>", "<g>".repeat(n), "</g>".repeat(n)))
            })
        };
        let e = load(&request(&deep(600), "deep.urdf")).unwrap_err().to_string();
        assert!(e.contains("deep.urdf:") && e.contains("<g> is nested more than 500 elements deep"), "{e}");
        assert!(load(&request(&deep(400), "deep400.urdf")).is_ok());
        let e = load(&request(&deep(200_000), "deeper.urdf")).unwrap_err().to_string();
        assert!(e.contains("nested more than 500 elements deep"), "{e}");
    }

    /// A refusal quotes at most EXCERPT characters of the file, however long the text: an
    /// `xyz` of a million numbers, a joint's name of 100 000 characters.
    #[test]
    fn a_refusal_quotes_a_short_excerpt_of_a_huge_attribute() {
        let numbers = "1 ".repeat(1_000_000);
        let text = lined(|s| s.replacen(r#"xyz="0.1 0 0.2""#, &format!(r#"xyz="{numbers}""#), 1));
        let e = load(&request(&text, "huge.urdf")).unwrap_err().to_string();
        assert!(e.contains("joint `j1`: xyz=\"1 1 1") && e.contains("… (2000000 characters)"), "{e}");
        assert!(e.len() < 300, "{} characters", e.len());
        let name = "n".repeat(100_000);
        let text = lined(|s| {
            s.replace(r#"<child link="nowhere"/>"#, "")
                .replace(r#"<child link="camera_link"/>"#, &format!(r#"<child link="{name}"/>"#))
        });
        let e = load(&request(&text, "name.urdf")).unwrap_err().to_string();
        assert!(e.contains("names the child link `nnn") && e.contains("(100000 characters)`"), "{e}");
        assert!(e.len() < 400, "{} characters", e.len());
    }

    /// Every refusal of the chain's own rules names the line and the URDF attribute, never an
    /// internal field name.
    #[test]
    fn the_chains_rules_are_named_by_line_and_attribute() {
        let text = lined(|s| s.replacen(r#"xyz="0.1 0 0.2""#, r#"xyz="5000 0 0.2""#, 1));
        let e = load(&request(&text, "far.urdf")).unwrap_err().to_string();
        let at = line_of(&text, r#"<joint name="j1""#);
        assert_eq!(
            e,
            format!(
                "{}:{at}: joint `j1`: <origin xyz> (the fixed joints above it folded in): must be <= 1e3",
                request(&text, "far.urdf").path.display()
            )
        );
        let text = lined(|s| {
            s.replacen(r#"<limit lower="-2" upper="2""#, r#"<limit lower="-2000" upper="2000""#, 1)
        });
        let e = load(&request(&text, "wide.urdf")).unwrap_err().to_string();
        assert!(
            e.contains(&format!(
                ":{}: joint `j1`: <limit lower upper>: must be <= 1e3",
                line_of(&text, r#"<joint name="j1""#)
            )),
            "{e}"
        );
        for internal in ["max_velocity", "limits:", "joints."] {
            assert!(!e.contains(internal), "{e}");
        }
    }

    /// `--home`: an empty value named by its position, a joint named twice, a value 1e-320
    /// from a limit (inside it, and every step of the law non-finite before this rule) refused
    /// in one sentence that gives the usable interval; 1 % of the range is enough.
    #[test]
    fn a_home_is_finite_named_once_and_a_usable_margin_inside_its_limits() {
        let e = HomeList::parse("0.2,,-0.5").unwrap_err().to_string();
        assert_eq!(e, r#"--home: "0.2,,-0.5": value 2 of 3 is empty"#);
        let e = HomeList::parse("j1=0.1,j2=0.2,j1=0.3").unwrap_err().to_string();
        assert_eq!(e, r#"--home: "j1=0.3": joint `j1` is named twice: give each joint once"#);
        assert!(HomeList::parse("0.1,").is_err(), "a trailing comma is an empty value");
        let text = robot(|s| s);
        let mut r = request(&text, "margin.urdf");
        // torso [0, 0.35]: 1e-320 above its lower limit.
        r.home = Some(HomeList::Values(vec![1e-320, 0.2, 0.3, 0.4, 0.5, 7.0, 0.6]));
        let e = load(&r).unwrap_err().to_string();
        assert_eq!(
            e,
            "home of joint `torso`: 1e-320 lies within 1 % of the range [0, 0.35] of its lower limit, where the law's \
             joint-limit penalty is too steep to step from (docs/book/src/your-robot.md): give a value in [0.0035, 0.3465]"
        );
        assert_eq!(e.matches(". ").count(), 0, "one sentence");
        r.home = Some(HomeList::Values(vec![0.0035, 0.2, 0.3, 0.4, 0.5, 7.0, 1.96]));
        assert!(load(&r).is_ok(), "1 % of the range from each limit");
        r.home = Some(HomeList::Values(vec![0.1, 0.2, 0.3, 0.4, 0.5, 7.0, 1.9601]));
        assert!(load(&r).unwrap_err().to_string().contains("of its upper limit"), "j6 [-2, 2]");
        r.home = Some(HomeList::Values(vec![0.1, 0.2, 0.3, 0.4, 0.5, f64::NAN, 0.6]));
        assert_eq!(load(&r).unwrap_err().to_string(), "home of joint `j5`: NaN is not a finite number");
        r.home = Some(HomeList::Named(vec![("torso".into(), 0.1), ("torso".into(), 0.2)]));
        assert!(load(&r).unwrap_err().to_string().contains("joint `torso` is named twice"));
    }
}
