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
//!   upper>` as their limits and `<limit velocity>` as their speed limit; without `<limit>`
//!   they are refused, as urdfdom (ROS's reader) refuses them, and so is a `<limit>` without
//!   `effort` or `velocity`;
//! - **continuous** joints are revolute joints without position limits (`(−∞, +∞)`: the law
//!   puts no penalty on them, companion-core's `JointLimits`), with `<limit velocity>` if
//!   given (no speed limit otherwise);
//! - an axis is normalised; a zero axis is refused; a `floating` or `planar` joint, or a
//!   `<mimic>` joint, inside the chain is refused by name (outside it they are ignored, as
//!   are the robot's other branches, meshes, inertias and `<transmission>`s);
//! - `<safety_controller>`'s soft limits are not read: the law keeps its own margins inside
//!   the hard limits (its penalty band, SPEC §3).
//!
//! # The home configuration
//!
//! The law needs a home `q*` strictly inside the limits (companion-core's `Chain`): from an
//! SRDF `<group_state>` (`--srdf FILE --home-state NAME`; MoveIt's files carry them), from a
//! list (`--home q1,…,qN` in the chain's order, or `--home name=value,…` to give or override
//! joints by name, e.g. the TIAGo's torso beside an arm state), or both (the list's names
//! win). A robot without either is refused with a message that names the joints and says
//! how to give them; a home at or outside a limit is refused naming the joint.
//!
//! Every refusal is one sentence naming the file and the joint or link (with the line in the
//! file where there is one), and the command line reports it with exit code 2 before
//! anything runs or is written.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use companion_core::nalgebra::{Matrix3, Vector3};
use companion_core::{so3, FrameData, JointData, JointKind, Pose3};

use super::size::{MAX_JOINTS, MIN_SPATIAL_JOINTS};

/// The xacro namespace (ROS's macro language for URDFs).
const XACRO_NS: &str = "http://www.ros.org/wiki/xacro";

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
    /// A value that is not a finite number, an empty list, or the two forms mixed.
    pub fn parse(s: &str) -> Result<Self, UrdfError> {
        let bad =
            |item: &str, why: &str| UrdfError::HomeSyntax { item: item.to_string(), why: why.to_string() };
        let items: Vec<&str> = s.split(',').map(str::trim).filter(|x| !x.is_empty()).collect();
        if items.is_empty() {
            return Err(bad(s, "the list is empty"));
        }
        let number = |item: &str, text: &str| -> Result<f64, UrdfError> {
            match text.trim().parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(x),
                _ => Err(bad(item, "not a finite number")),
            }
        };
        if items.iter().any(|x| x.contains('=')) {
            items
                .iter()
                .map(|item| match item.split_once('=') {
                    Some((name, v)) if !name.trim().is_empty() => {
                        Ok((name.trim().to_string(), number(item, v)?))
                    }
                    _ => {
                        Err(bad(item, "give every joint as name=value, or every value in the chain's order"))
                    }
                })
                .collect::<Result<_, _>>()
                .map(Self::Named)
        } else {
            items.iter().map(|item| number(item, item)).collect::<Result<_, _>>().map(Self::Values)
        }
    }
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
    #[error("{} is not well-formed XML: {error}", path.display())]
    Xml {
        /// The file.
        path: PathBuf,
        /// The parser's message (with the line and column).
        error: roxmltree::Error,
    },
    /// The root element is not the one expected (`robot`, or `robot` for an SRDF).
    #[error("{} is not a{} file: its root element is <{found}>, not <robot>", path.display(), if *srdf { "n SRDF" } else { " URDF" })]
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
    #[error("{}:{line}: {what}: {attribute}=\"{text}\" {why}", path.display())]
    BadValue {
        /// The file.
        path: PathBuf,
        /// The line.
        line: u32,
        /// The element.
        what: String,
        /// The attribute.
        attribute: String,
        /// Its text.
        text: String,
        /// The rule, e.g. "is not three numbers".
        why: String,
    },
    /// Two links or two joints of one name.
    #[error("{}:{line}: two {kind}s are named `{name}`", path.display())]
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
    /// A link is the child of two joints: not a tree.
    #[error("{}:{line}: link `{link}` is the child of two joints (`{first}` and `{second}`): a URDF is a tree", path.display())]
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
    /// A joint names a link the file does not have.
    #[error("{}:{line}: joint `{joint}` names the {role} link `{link}`, which is not in the file", path.display())]
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
    #[error("{flag} {link}: {} has no such link{}", path.display(), suggest(suggestions))]
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
    #[error("{}: link `{tip}` is not below `{base}`: from `{tip}` up, the tree goes {path_up}", path.display())]
    NotBelow {
        /// The file.
        path: PathBuf,
        /// The base link.
        base: String,
        /// The tip link.
        tip: String,
        /// The links from the tip up to the root, joined by " -> ".
        path_up: String,
    },
    /// A joint in the chain that the law cannot drive.
    #[error("{}:{line}: joint `{joint}` between `{base}` and `{tip}` is {kind}: a serial arm's joints are revolute, continuous, prismatic or fixed", path.display())]
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
    #[error("{}:{line}: joint `{joint}` ({kind}) has no {what}: urdfdom refuses it too; add <limit lower=\"…\" upper=\"…\" effort=\"…\" velocity=\"…\"/>", path.display())]
    NoLimit {
        /// The file.
        path: PathBuf,
        /// The line.
        line: u32,
        /// The joint.
        joint: String,
        /// `revolute` or `prismatic`.
        kind: &'static str,
        /// `<limit>`, or its missing attribute.
        what: &'static str,
    },
    /// A zero axis.
    #[error("{}:{line}: joint `{joint}` has a zero <axis>: a moving joint needs a direction", path.display())]
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
        "{}: the chain from `{base}` to `{tip}` has {} moving joint(s){}: a spatial arm needs 6 to 8",
        path.display(),
        joints.len(),
        if joints.is_empty() { String::new() } else { format!(" ({})", joints.join(", ")) }
    )]
    JointCount {
        /// The file.
        path: PathBuf,
        /// The base link.
        base: String,
        /// The tip link.
        tip: String,
        /// The moving joints found.
        joints: Vec<String>,
    },
    /// A joint breaks one of the chain's rules (companion-core's).
    #[error("{}: joint `{joint}`: {field}: {rule}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The joint (or `mount`, `tool`).
        joint: String,
        /// The field, e.g. `limits` or `max_velocity`.
        field: String,
        /// The rule.
        rule: companion_core::Rule,
    },
    /// `--home`'s text.
    #[error("--home: {item:?}: {why}")]
    HomeSyntax {
        /// The item.
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
    #[error("--home {name}=…: `{name}` is not a joint of the chain ({})", joints.join(", "))]
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
    #[error("home of joint `{joint}`: {value} is not strictly inside its limits [{lower}, {upper}]")]
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
    /// `--home-state` without `--srdf`, or the reverse.
    #[error("{0}")]
    HomeFlags(&'static str),
    /// The SRDF has no such `<group_state>`.
    #[error("{}: no <group_state name=\"{state}\">{}", path.display(), if available.is_empty() { " (it has none)".to_string() } else { format!(" (it has: {})", available.join(", ")) })]
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
        format!(" (did you mean {}?)", s.join(", "))
    }
}

fn tips(base: &str, c: &[String]) -> String {
    if c.is_empty() {
        format!(": no link below `{base}` ends a chain of 6 to 8 moving joints")
    } else {
        format!(": links that end a chain of 6 to 8 moving joints from `{base}`: {}", c.join(", "))
    }
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
}

/// `<limit>`: the attributes present.
#[derive(Clone, Copy, Debug)]
struct Limit {
    lower: f64,
    upper: f64,
    velocity: Option<f64>,
    effort: Option<f64>,
}

/// One `<joint>` as read.
#[derive(Clone, Debug)]
struct UrdfJoint {
    name: String,
    line: u32,
    kind: Kind,
    parent: String,
    origin: Pose3<f64>,
    axis: Vector3<f64>,
    limit: Option<Limit>,
    mimic: Option<String>,
}

/// A URDF's tree: its links and joints (the rest of the file is not read).
#[derive(Clone, Debug)]
struct Tree {
    path: PathBuf,
    name: String,
    links: Vec<String>,
    joints: Vec<UrdfJoint>,
    /// A link's parent joint (index into `joints`).
    parent_of: HashMap<String, usize>,
}

/// The chain read from a URDF, before the home: the description's parts and the joints'
/// names, in order from the base.
#[derive(Clone, Debug)]
struct Cut {
    joints: Vec<(String, JointData<f64>)>,
    tool: FrameData<f64>,
}

fn read_text(path: &Path) -> Result<String, UrdfError> {
    std::fs::read_to_string(path).map_err(|error| UrdfError::Io { path: path.to_path_buf(), error })
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
        None => tree.root(),
    };
    let Some(tip) = &request.tip_link else {
        return Err(UrdfError::NoTip {
            path: path.clone(),
            base: base.clone(),
            candidates: tree.tips(&base),
        });
    };
    let tip = tree.link("--tip-link", tip)?;
    let cut = tree.cut(&base, &tip)?;
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
    })
}

impl Tree {
    fn parse(path: &Path, text: &str) -> Result<Self, UrdfError> {
        let doc = roxmltree::Document::parse(text).map_err(|error| {
            // An undeclared `xacro:` prefix is an XML error; the template is the news.
            if text.contains("<xacro:") {
                UrdfError::Xacro { path: path.to_path_buf() }
            } else {
                UrdfError::Xml { path: path.to_path_buf(), error }
            }
        })?;
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
        let line = |n: roxmltree::Node<'_, '_>| doc.text_pos_at(n.range().start).row;
        let missing = |n: roxmltree::Node<'_, '_>, what: String, m: &str| UrdfError::Missing {
            path: path.to_path_buf(),
            line: line(n),
            what,
            missing: m.to_string(),
        };
        let mut links = Vec::new();
        for n in root.children().filter(|n| n.has_tag_name("link")) {
            let name =
                n.attribute("name").ok_or_else(|| missing(n, "a <link>".into(), "`name` attribute"))?;
            if links.iter().any(|l| l == name) {
                return Err(UrdfError::Duplicate {
                    path: path.to_path_buf(),
                    line: line(n),
                    kind: "link",
                    name: name.into(),
                });
            }
            links.push(name.to_string());
        }
        let mut joints: Vec<UrdfJoint> = Vec::new();
        let mut parent_of = HashMap::new();
        for n in root.children().filter(|n| n.has_tag_name("joint")) {
            let name =
                n.attribute("name").ok_or_else(|| missing(n, "a <joint>".into(), "`name` attribute"))?;
            let what = format!("joint `{name}`");
            if joints.iter().any(|j| j.name == name) {
                return Err(UrdfError::Duplicate {
                    path: path.to_path_buf(),
                    line: line(n),
                    kind: "joint",
                    name: name.into(),
                });
            }
            let bad = |attribute: &str, text: &str, why: &str| UrdfError::BadValue {
                path: path.to_path_buf(),
                line: line(n),
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
                        "type",
                        other,
                        "is not a URDF joint type (revolute, continuous, prismatic, fixed, floating, planar)",
                    )),
                };
            let child_el = |tag: &str| n.children().find(|c| c.has_tag_name(tag));
            let link_of = |tag: &str| -> Result<String, UrdfError> {
                let el =
                    child_el(tag).ok_or_else(|| missing(n, what.clone(), &format!("<{tag} link=\"…\">")))?;
                el.attribute("link")
                    .map(str::to_string)
                    .ok_or_else(|| missing(el, what.clone(), &format!("`link` attribute in <{tag}>")))
            };
            let parent = link_of("parent")?;
            let child = link_of("child")?;
            let triple = |el: Option<roxmltree::Node<'_, '_>>, attr: &str, default: [f64; 3]| {
                let Some(text) = el.and_then(|e| e.attribute(attr)) else { return Ok(default) };
                let v: Vec<f64> = text
                    .split_whitespace()
                    .map(str::parse::<f64>)
                    .collect::<Result<_, _>>()
                    .map_err(|_| bad(attr, text, "is not three numbers"))?;
                match <[f64; 3]>::try_from(v) {
                    Ok(a) if a.iter().all(|x| x.is_finite()) => Ok(a),
                    _ => Err(bad(attr, text, "is not three finite numbers")),
                }
            };
            let origin_el = child_el("origin");
            let xyz = triple(origin_el, "xyz", [0.0; 3])?;
            let [r, p, y] = triple(origin_el, "rpy", [0.0; 3])?;
            let origin = Pose3::new(so3::from_rpy(r, p, y), Vector3::from(xyz));
            let axis = Vector3::from(triple(child_el("axis"), "xyz", [1.0, 0.0, 0.0])?);
            let limit = match child_el("limit") {
                None => None,
                Some(l) => {
                    let num = |attr: &str| -> Result<Option<f64>, UrdfError> {
                        match l.attribute(attr) {
                            None => Ok(None),
                            Some(t) => match t.trim().parse::<f64>() {
                                Ok(x) if !x.is_nan() => Ok(Some(x)),
                                _ => Err(bad(&format!("limit {attr}"), t, "is not a number")),
                            },
                        }
                    };
                    Some(Limit {
                        // urdfdom's defaults: 0 for a missing lower or upper.
                        lower: num("lower")?.unwrap_or(0.0),
                        upper: num("upper")?.unwrap_or(0.0),
                        velocity: num("velocity")?,
                        effort: num("effort")?,
                    })
                }
            };
            let mimic = child_el("mimic").map(|m| m.attribute("joint").unwrap_or("?").to_string());
            if let Some(&first) = parent_of.get(&child) {
                let first: &UrdfJoint = &joints[first];
                return Err(UrdfError::TwoParents {
                    path: path.to_path_buf(),
                    line: line(n),
                    link: child,
                    first: first.name.clone(),
                    second: name.into(),
                });
            }
            for (role, link) in [("parent", &parent), ("child", &child)] {
                if !links.contains(link) {
                    return Err(UrdfError::DanglingJoint {
                        path: path.to_path_buf(),
                        line: line(n),
                        joint: name.into(),
                        role,
                        link: link.clone(),
                    });
                }
            }
            parent_of.insert(child.clone(), joints.len());
            joints.push(UrdfJoint {
                name: name.into(),
                line: line(n),
                kind,
                parent,
                origin,
                axis,
                limit,
                mimic,
            });
        }
        let name = root.attribute("name").unwrap_or("robot").to_string();
        Ok(Self { path: path.to_path_buf(), name, links, joints, parent_of })
    }

    /// The root link: the first link that is no joint's child.
    fn root(&self) -> String {
        self.links.iter().find(|l| !self.parent_of.contains_key(*l)).cloned().unwrap_or_default()
    }

    /// `name` if it is a link of the file.
    fn link(&self, flag: &'static str, name: &str) -> Result<String, UrdfError> {
        if self.links.iter().any(|l| l == name) {
            return Ok(name.to_string());
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
            suggestions.push(self.root());
        }
        Err(UrdfError::UnknownLink { path: self.path.clone(), flag, link: name.into(), suggestions })
    }

    /// The joints from `base` down to `tip` (indices, base first), or `None` if `tip` is not
    /// below `base`.
    fn path_down(&self, base: &str, tip: &str) -> Option<Vec<usize>> {
        let mut up = Vec::new();
        let mut link = tip;
        while link != base {
            let &j = self.parent_of.get(link)?;
            up.push(j);
            link = &self.joints[j].parent;
        }
        up.reverse();
        Some(up)
    }

    /// The links at the end of an arm below `base`: their chain from `base` has 6 to 8
    /// moving joints and none that cannot be driven, and nothing below them moves (the last
    /// moving joint's link and the frames fixed to it: a flange, a tool, a sensor).
    fn tips(&self, base: &str) -> Vec<String> {
        // Whether anything below a link moves, from the leaves up.
        let mut moving_below: std::collections::HashSet<&str> = std::collections::HashSet::new();
        for j in &self.joints {
            if j.kind.moves() {
                let mut link = j.parent.as_str();
                loop {
                    if !moving_below.insert(link) {
                        break;
                    }
                    match self.parent_of.get(link) {
                        Some(&k) => link = &self.joints[k].parent,
                        None => break,
                    }
                }
            }
        }
        self.links
            .iter()
            .filter(|l| !moving_below.contains(l.as_str()))
            .filter(|l| {
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
            .cloned()
            .collect()
    }

    /// The chain from `base` to `tip`, fixed joints folded (module docs).
    fn cut(&self, base: &str, tip: &str) -> Result<Cut, UrdfError> {
        let path = &self.path;
        let Some(down) = self.path_down(base, tip) else {
            let mut chain = vec![tip.to_string()];
            let mut link = tip;
            while let Some(&j) = self.parent_of.get(link) {
                link = &self.joints[j].parent;
                chain.push(link.to_string());
            }
            return Err(UrdfError::NotBelow {
                path: path.clone(),
                base: base.into(),
                tip: tip.into(),
                path_up: chain.join(" -> "),
            });
        };
        let mut joints = Vec::new();
        let mut pending = Pose3::<f64>::identity();
        for &k in &down {
            let j = &self.joints[k];
            let unsupported = |kind: String| UrdfError::UnsupportedJoint {
                path: path.clone(),
                line: j.line,
                joint: j.name.clone(),
                kind,
                base: base.into(),
                tip: tip.into(),
            };
            match j.kind {
                Kind::Floating => return Err(unsupported("floating".into())),
                Kind::Planar => return Err(unsupported("planar".into())),
                _ if j.mimic.is_some() => {
                    return Err(unsupported(format!("a mimic of `{}`", j.mimic.as_deref().unwrap_or("?"))))
                }
                Kind::Fixed => {
                    pending = pending.compose(&j.origin);
                    continue;
                }
                Kind::Revolute | Kind::Continuous | Kind::Prismatic => {}
            }
            let norm = j.axis.norm();
            if norm == 0.0 {
                return Err(UrdfError::ZeroAxis { path: path.clone(), line: j.line, joint: j.name.clone() });
            }
            let no_limit = |what| UrdfError::NoLimit {
                path: path.clone(),
                line: j.line,
                joint: j.name.clone(),
                kind: if j.kind == Kind::Prismatic { "prismatic" } else { "revolute" },
                what,
            };
            let (limits, velocity) = match (j.kind, j.limit) {
                (Kind::Continuous, l) => ([f64::NEG_INFINITY, f64::INFINITY], l.and_then(|l| l.velocity)),
                (_, None) => return Err(no_limit("<limit>")),
                (_, Some(l)) => {
                    if l.effort.is_none() {
                        return Err(no_limit("`effort` in its <limit>"));
                    }
                    if l.velocity.is_none() {
                        return Err(no_limit("`velocity` in its <limit>"));
                    }
                    ([l.lower, l.upper], l.velocity)
                }
            };
            let origin = pending.compose(&j.origin);
            pending = Pose3::identity();
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
                base: base.into(),
                tip: tip.into(),
                joints: joints.into_iter().map(|(n, _)| n).collect(),
            });
        }
        Ok(Cut { joints, tool: frame_data(&pending) })
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
            source.push(format!("--srdf {} --home-state {state}", srdf.display()));
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
            for (n, v) in pairs {
                let Some(i) = names.iter().position(|m| m == n) else {
                    return Err(UrdfError::HomeUnknownJoint { name: n.clone(), joints: names });
                };
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
        let [lower, upper] = j.limits;
        // Empty limits are the chain's rule to refuse (as `limits`), not the home's.
        if lower < upper && !(h > lower && h < upper) {
            return Err(UrdfError::HomeOutside { joint: name.clone(), value: h, lower, upper });
        }
    }
    Ok(home)
}

/// The joint values of an SRDF's `<group_state name="state">` (every group state of that
/// name, in the file's order).
///
/// # Errors
/// The file cannot be read or parsed, or has no such state.
pub fn srdf_state(path: &Path, state: &str) -> Result<Vec<(String, f64)>, UrdfError> {
    let text = read_text(path)?;
    let doc = roxmltree::Document::parse(&text)
        .map_err(|error| UrdfError::Xml { path: path.to_path_buf(), error })?;
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
            let line = doc.text_pos_at(j.range().start).row;
            let name = j.attribute("name").ok_or_else(|| UrdfError::Missing {
                path: path.to_path_buf(),
                line,
                what: format!("a <joint> of group_state `{state}`"),
                missing: "`name` attribute".into(),
            })?;
            let text = j.attribute("value").unwrap_or("");
            // A group state's value may list several numbers (a multi-DOF joint): those are
            // not joints of a serial chain; the first number is kept for a single-DOF one.
            let v =
                text.split_whitespace().next().and_then(|t| t.parse::<f64>().ok()).filter(|x| x.is_finite());
            let v = v.ok_or_else(|| UrdfError::BadValue {
                path: path.to_path_buf(),
                line,
                what: format!("joint `{name}` of group_state `{state}`"),
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
        assert!(e.contains("is not well-formed XML"), "{e}");
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
        assert!(e.contains("joint `j1`: max_velocity"), "{e}");
        let e = refusal(|s| s.replacen(r#"lower="-2" upper="2""#, r#"lower="2" upper="2""#, 1), "empty.urdf");
        assert!(e.contains("joint `j1`: limits"), "{e}");
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
}
