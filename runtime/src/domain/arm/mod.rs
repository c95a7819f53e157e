//! Arms described as data for `--arm`: the presets (`rpr`, `ur5`, `panda`) and TOML files.
//!
//! # The arm file
//!
//! The form of companion-core's [`Chain`]: joints as in URDF, each joint's frame seen from
//! the previous joint's moving frame (`xyz` in metres, `rpy` in radians — or `rotation`, a
//! matrix by rows), its unit `axis` in its own frame; the end effector (`[tool]`) seen from
//! the last joint's moving frame; the arm's base on the platform (`[mount]`: the platform's
//! frame has `x` forward, `z` up, its origin on the ground). A Denavit–Hartenberg row
//! `(a, α, d, θ)` is written as the joint `xyz = [a_{i−1}, −sin α_{i−1} d_i, cos α_{i−1}
//! d_i]`, `rpy = [α_{i−1}, 0, 0]` with `θ_i` in `home` (modified convention; for the
//! standard one shift `a` and `α` down a row), as `examples/arms/ur5.toml` shows for the UR5.
//!
//! ```toml
//! name = "my-arm"                  # optional (default: the file's name)
//! [mount]                          # optional (default: identity)
//! xyz = [0.1, 0.0, 0.5]
//! rpy = [0.0, 0.0, 3.141592653589793]
//! [tool]                           # optional (default: identity)
//! xyz = [0.0, 0.0, 0.1]
//! [[joint]]                        # 6 to 8 of them, from the base outwards
//! name = "shoulder_pan_joint"      # optional (default: joint1, joint2, …)
//! type = "revolute"                # or "prismatic"
//! xyz = [0.0, 0.0, 0.089159]       # optional (default 0)
//! rpy = [0.0, 0.0, 0.0]            # optional (default 0); or rotation = [[…], […], […]]
//! axis = [0.0, 0.0, 1.0]           # unit vector
//! limits = [-6.28, 6.28]           # [lower, upper] (rad or m); [-inf, inf]: no limits (revolute)
//! home = 0.0                       # strictly inside the limits (rad or m)
//! max_velocity = 3.14              # rad/s or m/s (optional: no limit)
//! [unicycle]                       # optional: the platform law's settings this arm needs
//! epsilon_1 = 0.2                  #   (the keys of --config's [unicycle] and [car];
//! epsilon_2 = 0.8                  #   a --config table of the same name wins)
//! ```
//!
//! # The platform settings an arm carries
//!
//! The paper's transverse functions ask the arm to compensate the platform's manoeuvres; an
//! arm whose published joint speeds cannot ([`PlatformDefaults`]) carries the settings that
//! do — the `panda` preset and `examples/arms/panda.toml` the unicycle's `ε₂ = 0.8 m`
//! ([`PANDA_UNICYCLE`]) and the car's Lemma 2 parameters ([`PANDA_CAR`]) — and they apply
//! wherever the run's `--config` has no table of its own for that platform.
//!
//! Every error names the field (`joint 3: limits`, `mount.rotation`) and the rule, and the
//! CLI reports it with exit code 2 before anything runs.
//!
//! # A URDF
//!
//! `--arm robot.urdf --base-link B --tip-link T` reads the chain between two links of a
//! vendor's URDF ([`urdf`]) into the same [`ArmDescription`].

use std::path::{Path, PathBuf};

use companion_core::nalgebra::Matrix3;
use companion_core::{so3, Chain, FrameData, JointData, JointKind, ParamError, Real};
use serde::Deserialize;

use self::urdf::check_home;
use crate::domain::platform_config::{CarConfig, UnicycleConfig};

mod size;
pub mod urdf;

pub use self::urdf::{HomeList, UrdfError, UrdfRequest};

pub use self::size::{MAX_JOINTS, MIN_SPATIAL_JOINTS};

/// What `--arm` names.
#[derive(Clone, Debug, PartialEq)]
pub enum ArmChoice {
    /// The paper's planar RPR arm: the planar law and plant.
    Rpr,
    /// Universal Robots' UR5 (`Chain::ur5`).
    Ur5,
    /// Franka Emika's Panda (`Chain::panda`).
    Panda,
    /// A TOML arm file (module docs).
    File(PathBuf),
    /// The chain between two links of a URDF ([`urdf`]).
    Urdf(Box<UrdfRequest>),
}

impl ArmChoice {
    /// `rpr`, `ur5`, `panda`, or else a file's path: a URDF (with no cut nor home yet: see
    /// [`ArmChoice::Urdf`]) if it ends in `.urdf` or `.xacro`, else a TOML arm file.
    pub fn parse(s: &str) -> Self {
        match s {
            "rpr" => Self::Rpr,
            "ur5" => Self::Ur5,
            "panda" => Self::Panda,
            path if urdf::is_urdf(Path::new(path)) => {
                Self::Urdf(Box::new(UrdfRequest { path: PathBuf::from(path), ..UrdfRequest::default() }))
            }
            path => Self::File(PathBuf::from(path)),
        }
    }
}

/// The Panda's unicycle transverse function: Lemma 1's `ε₂ = 0.8 m` instead of the paper's
/// 0.4 m. With the paper's, run (a) of lifted trajectory 1 makes the platform manoeuvre at up
/// to 0.83 m/s and asks the Panda's shoulder (joint 2) for 2.59 rad/s, beyond its published
/// 2.175 rad/s: the joint guard slows the whole arm, and `e_p` stays at ~2e−2 until the
/// manoeuvres calm (final ‖e_p‖ 1.9e−4 after 40 s). The wider function buys the same lateral
/// motion with slower manoeuvres (0.54 m/s), which the published speeds follow (final
/// ‖e_p‖ 4.4e−8; core's `panda_unicycle_tracks_lifted_trajectory_1` says the same).
pub const PANDA_UNICYCLE: UnicycleConfig = UnicycleConfig { epsilon_1: 0.2, epsilon_2: 0.8 };

/// The Panda's car-like transverse function and steering gain: Lemma 2's `(ε, η₁, η₂, η₃) =
/// (0.176, 12.1, 3.33, 28.2)` and `k = 19.9` instead of the car's defaults (0.152, 21.9, 1.9,
/// 15.4; 26.6: `examples/arms/panda-car-defaults.toml`). With those, run (a) of lifted
/// trajectory 1 keeps the car manoeuvring all run long — its curvature swinging to ±3.2 1/m,
/// its heading turning at up to 2.3 rad/s — and asks the Panda's base joint (1) for up to
/// 5.4 rad/s and its last (7) for 5.6, beyond their published 2.175 and 2.61 rad/s: in sharp
/// turns, and where the target passes within centimetres of joint 1's axis as the car
/// reverses (joint 1's rate grows as the inverse of that distance; 8 mm at the closest). The
/// joint guard then slows the whole arm, and bursts of `e_p` (up to 1.1e−1) come back until
/// the end (final ‖e_p‖ 1.3e−5 at 40 s; `scripts/joint_guard.py` gives these figures). These
/// settings, sample 207 of `docs/explore/panda-car.toml` rounded to three digits, calm the car
/// (curvature within ±1, turns within 0.36 rad/s after 20 s) and settle it: ‖e_p‖ at most
/// 3.8e−7 from 20 s to 120 s, the guard idle. Only 2 of that study's 1 000 samples settle,
/// and 9 of 100 within ±10 % of this one (`docs/explore/panda-car-207.toml`): a narrow
/// island, not a robust setting (docs/book/src/spatial-arms.md says what that means).
pub const PANDA_CAR: CarConfig = CarConfig { epsilon: 0.176, eta_1: 12.1, eta_2: 3.33, eta_3: 28.2, k: 19.9 };

/// The platform law's settings an arm carries (module docs): each, if given, replaces the
/// runtime's default (the paper's) for its platform unless the run's `--config` has the table.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlatformDefaults {
    /// Lemma 1's parameters for the unicycle (`[unicycle]`).
    pub unicycle: Option<UnicycleConfig>,
    /// Lemma 2's parameters for the car (`[car]`).
    pub car: Option<CarConfig>,
}

impl PlatformDefaults {
    /// Whether the arm carries no settings (the paper's apply).
    pub fn is_empty(&self) -> bool {
        self.unicycle.is_none() && self.car.is_none()
    }
}

/// A spatial arm ready to be built in either scalar type.
#[derive(Clone, Debug, PartialEq)]
pub enum SpatialArmSpec {
    /// The UR5 preset.
    Ur5,
    /// The Panda preset.
    Panda,
    /// An arm read from a file.
    File(Box<ArmDescription>),
    /// Another arm made faster or larger, for a study of what limits it
    /// (`companion explore --arm`'s `joint_speed` and `reach`): [`ArmScale`].
    Scaled(Box<SpatialArmSpec>, ArmScale),
    /// Another arm with another home (rad or m per joint, in the chain's order): the
    /// perturbed starts of `companion settle` and `companion tune --starts`. The home is the
    /// law's `q*` and where the run starts (`companion_runtime::study::starts`).
    Rehomed(Box<SpatialArmSpec>, Vec<f64>),
}

/// Factors on an arm's published figures ([`SpatialArmSpec::Scaled`]); `1` changes nothing,
/// bit for bit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArmScale {
    /// Every joint's largest speed (`max_velocity`) times this (> 0).
    pub joint_speed: f64,
    /// Every length of the arm times this (> 0): each joint's and the tool's `xyz`, and a
    /// prismatic joint's limits, home and speed — a geometric copy of the arm, mounted where
    /// the arm is (`[mount]` unchanged).
    pub reach: f64,
}

impl ArmScale {
    /// No change.
    pub const ONE: Self = Self { joint_speed: 1.0, reach: 1.0 };

    /// `chain` scaled.
    ///
    /// # Errors
    /// A factor that is not finite and positive (named `joint_speed` or `reach`).
    pub fn apply<T: Real, const N: usize>(self, chain: &Chain<T, N>) -> Result<Chain<T, N>, ArmError> {
        for (field, x) in [("joint_speed", self.joint_speed), ("reach", self.reach)] {
            if !(x.is_finite() && x > 0.0) {
                return Err(ArmError::Scale { field, value: x });
            }
        }
        let (speed, reach) = (T::of(self.joint_speed), T::of(self.reach));
        let mut c = *chain;
        for j in &mut c.joints {
            j.origin.translation *= reach;
            j.max_velocity *= speed;
            if j.kind == JointKind::Prismatic {
                j.lower *= reach;
                j.upper *= reach;
                j.home *= reach;
                j.max_velocity *= reach;
            }
        }
        c.tool.translation *= reach;
        Ok(c)
    }
}

impl SpatialArmSpec {
    /// The spatial arm `choice` names; `None` for `rpr` (planar).
    ///
    /// # Errors
    /// The file cannot be read, or breaks a rule ([`ArmError`]).
    pub fn from_choice(choice: &ArmChoice) -> Result<Option<Self>, ArmError> {
        Ok(match choice {
            ArmChoice::Rpr => None,
            ArmChoice::Ur5 => Some(Self::Ur5),
            ArmChoice::Panda => Some(Self::Panda),
            ArmChoice::File(p) => Some(Self::File(Box::new(ArmDescription::load(p)?))),
            ArmChoice::Urdf(r) => Some(Self::File(Box::new(ArmDescription::from_urdf(r)?))),
        })
    }

    /// The joints' names, from the base outwards: a URDF's, a file's `name` keys (`joint1`, …
    /// where it has none), the presets' as in their vendors' URDFs.
    pub fn joint_names(&self) -> Vec<String> {
        match self {
            Self::Ur5 => UR5_JOINTS.iter().map(|s| s.to_string()).collect(),
            Self::Panda => (1..=7).map(|i| format!("panda_joint{i}")).collect(),
            Self::File(d) => d.joint_names.clone(),
            Self::Scaled(a, _) | Self::Rehomed(a, _) => a.joint_names(),
        }
    }

    /// The arm's name (`ur5`, `panda`, the file's `name`).
    pub fn name(&self) -> &str {
        match self {
            Self::Ur5 => "ur5",
            Self::Panda => "panda",
            Self::File(d) => &d.name,
            Self::Scaled(a, _) | Self::Rehomed(a, _) => a.name(),
        }
    }

    /// The platform law's settings the arm carries: the Panda's [`PANDA_UNICYCLE`] and
    /// [`PANDA_CAR`], a file's `[unicycle]` and `[car]`; none for the UR5 (the paper's and the
    /// car's default settings track with it).
    pub fn platform_defaults(&self) -> PlatformDefaults {
        match self {
            Self::Ur5 => PlatformDefaults::default(),
            Self::Panda => PlatformDefaults { unicycle: Some(PANDA_UNICYCLE), car: Some(PANDA_CAR) },
            Self::File(d) => d.platform,
            Self::Scaled(a, _) | Self::Rehomed(a, _) => a.platform_defaults(),
        }
    }

    /// The number of joints.
    pub fn joints(&self) -> usize {
        match self {
            Self::Ur5 => 6,
            Self::Panda => 7,
            Self::File(d) => d.joints.len(),
            Self::Scaled(a, _) | Self::Rehomed(a, _) => a.joints(),
        }
    }

    /// The chain in scalar type `T` with `N` joints (`N` must be [`joints`](Self::joints)).
    ///
    /// # Errors
    /// `N` is not the arm's joint count, or the description breaks a rule of [`Chain`].
    pub fn chain<T: Real, const N: usize>(&self) -> Result<Chain<T, N>, ArmError> {
        let wrong = || ArmError::JointCount { found: self.joints() };
        match self {
            Self::Ur5 => resize(Chain::<T, 6>::ur5()).ok_or_else(wrong),
            Self::Panda => resize(Chain::<T, 7>::panda()).ok_or_else(wrong),
            Self::File(d) => d.chain(),
            Self::Scaled(a, scale) => scale.apply(&a.chain::<T, N>()?),
            Self::Rehomed(a, home) => {
                if home.len() != N {
                    return Err(wrong());
                }
                let mut c = a.chain::<T, N>()?;
                for (j, h) in c.joints.iter_mut().zip(home) {
                    j.home = T::of(*h);
                }
                c.validate().map_err(ArmError::from_param)?;
                Ok(c)
            }
        }
    }

    /// The home, in the chain's order (rad or m).
    ///
    /// # Errors
    /// The chain cannot be built.
    pub fn home(&self) -> Result<Vec<f64>, ArmError> {
        fn of<const N: usize>(a: &SpatialArmSpec) -> Result<Vec<f64>, ArmError> {
            Ok(a.chain::<f64, N>()?.home().iter().copied().collect())
        }
        match self.joints() {
            6 => of::<6>(self),
            7 => of::<7>(self),
            8 => of::<8>(self),
            n => Err(ArmError::JointCount { found: n }),
        }
    }

    /// This arm with its home at `home` (rad or m per joint, in the chain's order; checked
    /// strictly inside the limits when the law is built).
    pub fn rehomed(self, home: Vec<f64>) -> Self {
        match self {
            Self::Rehomed(a, _) => Self::Rehomed(a, home),
            a => Self::Rehomed(Box::new(a), home),
        }
    }

    /// This arm with its joints' speeds and its lengths scaled (`ArmScale::ONE`: itself).
    pub fn scaled(self, scale: ArmScale) -> Self {
        if scale == ArmScale::ONE {
            return self;
        }
        match self {
            Self::Scaled(a, s) => Self::Scaled(
                a,
                ArmScale { joint_speed: s.joint_speed * scale.joint_speed, reach: s.reach * scale.reach },
            ),
            a => Self::Scaled(Box::new(a), scale),
        }
    }
}

/// The UR5's joints as Universal Robots' URDF names them.
const UR5_JOINTS: [&str; 6] = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
];

/// `c` as a chain of `N` joints, if it has `N`.
fn resize<T: Copy, const M: usize, const N: usize>(c: Chain<T, M>) -> Option<Chain<T, N>> {
    (M == N).then(|| Chain { mount: c.mount, joints: core::array::from_fn(|i| c.joints[i]), tool: c.tool })
}

/// An arm file's content as numbers (module docs), checked for shape; the chain's own rules
/// are checked when it is built ([`ArmDescription::chain`], done once by [`load`](Self::load)).
#[derive(Clone, Debug, PartialEq)]
pub struct ArmDescription {
    /// The arm's name.
    pub name: String,
    /// The mounting pose on the platform.
    pub mount: FrameData<f64>,
    /// The joints, from the base outwards.
    pub joints: Vec<JointData<f64>>,
    /// The end effector in the last joint's moving frame.
    pub tool: FrameData<f64>,
    /// The platform law's settings the file carries (`[unicycle]`, `[car]`).
    pub platform: PlatformDefaults,
    /// The joints' names, from the base outwards (a URDF's; a TOML file's `name` keys, or
    /// `joint1`, `joint2`, …).
    pub joint_names: Vec<String>,
}

impl From<UrdfError> for ArmError {
    fn from(e: UrdfError) -> Self {
        Self::Urdf(Box::new(e))
    }
}

/// Why an arm file was refused.
#[derive(Debug, thiserror::Error)]
pub enum ArmError {
    /// The file could not be read.
    #[error("cannot read arm file {}: {error}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        error: std::io::Error,
    },
    /// Malformed TOML, an unknown or missing key, a value of the wrong type (the message
    /// gives the line and the key).
    #[error("arm file is not valid: {0}")]
    Parse(toml::de::Error),
    /// Not 6 to 8 `[[joint]]` tables.
    #[error("arm file: `joint`: a spatial arm needs 6 to 8 joints ([[joint]] tables), the file has {found}")]
    JointCount {
        /// The number of joints found.
        found: usize,
    },
    /// An array of the wrong length.
    #[error("arm file: {field} has {found} entries: it must have {expected}")]
    WrongLength {
        /// The field, e.g. `joint 3: limits`.
        field: String,
        /// The required length.
        expected: usize,
        /// The length found.
        found: usize,
    },
    /// Both `rpy` and `rotation` in one frame.
    #[error("arm file: {field}: give `rpy` or `rotation`, not both")]
    TwoRotations {
        /// The frame, e.g. `mount`.
        field: String,
    },
    /// A scale factor ([`ArmScale`]) is not finite and positive.
    #[error("arm scale: {field} = {value} must be finite and > 0")]
    Scale {
        /// `joint_speed` or `reach`.
        field: &'static str,
        /// The factor.
        value: f64,
    },
    /// A URDF (or its SRDF, or the home) was refused.
    #[error(transparent)]
    Urdf(Box<UrdfError>),
    /// A joint's home within [`urdf::HOME_MARGIN`] of a limit (the URDF reader's rule).
    #[error("arm file: {0}")]
    Home(Box<UrdfError>),
    /// A value breaks one of the chain's rules.
    #[error("arm file: {field}: {rule}")]
    Invalid {
        /// The field in the file's words, e.g. `joint 2: limits` or `mount.rotation`.
        field: String,
        /// The rule (companion-core's).
        rule: companion_core::Rule,
    },
}

impl ArmError {
    /// A chain's [`ParamError`] in the file's words.
    fn from_param(e: ParamError) -> Self {
        let key = match e.param {
            "joints.lower" | "joints.upper" => "limits",
            "joints.home" => "home",
            "joints.axis" => "axis",
            "joints.max_velocity" => "max_velocity",
            "joints.origin.translation" => "xyz",
            "joints.origin.rotation" => "rpy/rotation",
            other => other,
        };
        let field = match e.joint {
            Some(j) => format!("joint {}: {key}", j + 1),
            None => key.to_string(),
        };
        Self::Invalid { field, rule: e.rule }
    }
}

impl ArmDescription {
    /// The chain `request` cuts from a URDF, as an arm description, checked: a rule the
    /// chain breaks is named by the URDF's joint.
    ///
    /// # Errors
    /// [`UrdfError`], naming the file and the joint or link.
    pub fn from_urdf(request: &UrdfRequest) -> Result<Self, UrdfError> {
        let c = urdf::read(request)?;
        let d = Self {
            name: c.name.clone(),
            mount: c.mount,
            joints: c.joints.clone(),
            tool: c.tool,
            platform: PlatformDefaults::default(),
            joint_names: c.joint_names.clone(),
        };
        match d.param_error() {
            None => Ok(d),
            Some(e) => Err(urdf_rule(&request.path, &c, e)),
        }
    }

    /// Reads, parses and checks an arm file (its chain is built once in `f64` to check every
    /// rule).
    ///
    /// # Errors
    /// [`ArmError`] naming the field.
    pub fn load(path: &Path) -> Result<Self, ArmError> {
        let text = std::fs::read_to_string(path)
            .map_err(|error| ArmError::Io { path: path.to_path_buf(), error })?;
        let stem = path.file_stem().map_or_else(|| "arm".to_string(), |s| s.to_string_lossy().into_owned());
        Self::from_toml_str(&text, &stem)
    }

    /// Parses and checks an arm file's text; `default_name` if it has no `name`.
    ///
    /// # Errors
    /// [`ArmError`] naming the field.
    pub fn from_toml_str(text: &str, default_name: &str) -> Result<Self, ArmError> {
        let file: ArmFile = toml::from_str(text).map_err(ArmError::Parse)?;
        let n = file.joint.len();
        if !(MIN_SPATIAL_JOINTS..=MAX_JOINTS).contains(&n) {
            return Err(ArmError::JointCount { found: n });
        }
        let mount = frame(file.mount.as_ref(), "mount")?;
        let tool = frame(file.tool.as_ref(), "tool")?;
        let joints = file
            .joint
            .iter()
            .enumerate()
            .map(|(i, j)| {
                let field = |k: &str| format!("joint {}: {k}", i + 1);
                let origin =
                    FrameFile { xyz: j.xyz.clone(), rpy: j.rpy.clone(), rotation: j.rotation.clone() };
                let origin = frame(Some(&origin), &format!("joint {}", i + 1))?;
                let axis = array::<3>(&j.axis, field("axis"))?;
                let limits = array::<2>(&j.limits, field("limits"))?;
                Ok(JointData {
                    kind: match j.kind {
                        KindFile::Revolute => JointKind::Revolute,
                        KindFile::Prismatic => JointKind::Prismatic,
                    },
                    origin,
                    axis,
                    limits,
                    home: j.home,
                    max_velocity: j.max_velocity.unwrap_or(f64::INFINITY),
                })
            })
            .collect::<Result<Vec<_>, ArmError>>()?;
        let platform = PlatformDefaults { unicycle: file.unicycle, car: file.car };
        let name = file.name.unwrap_or_else(|| default_name.to_string());
        let joint_names = file
            .joint
            .iter()
            .enumerate()
            .map(|(i, j)| j.name.clone().unwrap_or(format!("joint{}", i + 1)))
            .collect();
        let d = Self { name, mount, joints, tool, platform, joint_names };
        d.check()?;
        for (j, name) in d.joints.iter().zip(&d.joint_names) {
            check_home(name, j.limits, j.home).map_err(|e| ArmError::Home(Box::new(e)))?;
        }
        Ok(d)
    }

    /// Builds the chain once in `f64` to check every rule of [`Chain`].
    ///
    /// # Errors
    /// Not 6 to 8 joints, or a rule of [`Chain::validate`] (in the file's words).
    pub fn check(&self) -> Result<(), ArmError> {
        if !(MIN_SPATIAL_JOINTS..=MAX_JOINTS).contains(&self.joints.len()) {
            return Err(ArmError::JointCount { found: self.joints.len() });
        }
        self.param_error().map_or(Ok(()), |e| Err(ArmError::from_param(e)))
    }

    /// The rule of [`Chain::validate`] the description breaks, if any (6 to 8 joints).
    fn param_error(&self) -> Option<ParamError> {
        match self.joints.len() {
            6 => self.built::<f64, 6>().err(),
            7 => self.built::<f64, 7>().err(),
            8 => self.built::<f64, 8>().err(),
            _ => None,
        }
    }

    /// The chain in scalar type `T` (`N` must be the number of joints).
    ///
    /// # Errors
    /// Another joint count, or a rule of [`Chain::validate`] (in the file's words).
    pub fn chain<T: Real, const N: usize>(&self) -> Result<Chain<T, N>, ArmError> {
        if self.joints.len() != N {
            return Err(ArmError::JointCount { found: self.joints.len() });
        }
        self.built().map_err(ArmError::from_param)
    }

    /// The chain of `N` joints (`N` the number of joints), or the rule it breaks.
    fn built<T: Real, const N: usize>(&self) -> Result<Chain<T, N>, ParamError> {
        let f = |d: &FrameData<f64>| FrameData {
            xyz: d.xyz.map(T::of),
            rotation: d.rotation.map(|r| r.map(T::of)),
        };
        let joints: [JointData<T>; N] = core::array::from_fn(|i| {
            let j = &self.joints[i];
            JointData {
                kind: j.kind,
                origin: f(&j.origin),
                axis: j.axis.map(T::of),
                limits: j.limits.map(T::of),
                home: T::of(j.home),
                max_velocity: T::of(j.max_velocity),
            }
        });
        Chain::from_arrays(&f(&self.mount), &joints, &f(&self.tool))
    }
}

/// A rule of companion-core's chain that a URDF's chain breaks, in the URDF's words: the
/// joint, its line and the attribute (the mount is the config file's `[robot] mount`).
fn urdf_rule(path: &Path, c: &urdf::UrdfChain, e: ParamError) -> UrdfError {
    let attribute = match e.param {
        "joints.lower" | "joints.upper" => "<limit lower upper>",
        "joints.home" => "its home",
        "joints.axis" => "<axis xyz>",
        "joints.max_velocity" => "<limit velocity>",
        "joints.origin.translation" => "<origin xyz> (the fixed joints above it folded in)",
        "joints.origin.rotation" => "<origin rpy> (the fixed joints above it folded in)",
        "tool.translation" => "<origin xyz> of the fixed joints down to the tip link",
        "tool.rotation" => "<origin rpy> of the fixed joints down to the tip link",
        "mount.translation" | "mount.rotation" => "[robot] mount",
        other => other,
    };
    let (line, joint) = match e.joint {
        Some(i) => {
            let i = usize::from(i);
            (c.joint_lines.get(i).copied(), c.joint_names.get(i).cloned().unwrap_or_default())
        }
        None if e.param.starts_with("tool") => (Some(c.tool_line), String::new()),
        None => (None, String::new()),
    };
    UrdfError::Invalid {
        path: path.to_path_buf(),
        line,
        joint,
        attribute: attribute.to_string(),
        rule: e.rule,
    }
}

/// The file's layout (private: the public type is [`ArmDescription`]).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ArmFile {
    name: Option<String>,
    mount: Option<FrameFile>,
    tool: Option<FrameFile>,
    #[serde(default)]
    joint: Vec<JointFile>,
    unicycle: Option<UnicycleConfig>,
    car: Option<CarConfig>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct FrameFile {
    // Vectors, not arrays: toml 0.9 silently drops extra elements of a fixed-size array.
    xyz: Option<Vec<f64>>,
    rpy: Option<Vec<f64>>,
    rotation: Option<Vec<Vec<f64>>>,
}

#[derive(Debug, Deserialize)]
#[serde(rename_all = "lowercase")]
enum KindFile {
    Revolute,
    Prismatic,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct JointFile {
    name: Option<String>,
    #[serde(rename = "type")]
    kind: KindFile,
    // Not `#[serde(flatten)]`: serde does not deny unknown keys through a flattened struct.
    xyz: Option<Vec<f64>>,
    rpy: Option<Vec<f64>>,
    rotation: Option<Vec<Vec<f64>>>,
    axis: Vec<f64>,
    limits: Vec<f64>,
    home: f64,
    max_velocity: Option<f64>,
}

fn array<const K: usize>(v: &[f64], field: String) -> Result<[f64; K], ArmError> {
    <[f64; K]>::try_from(v).map_err(|_| ArmError::WrongLength { field, expected: K, found: v.len() })
}

/// A frame from `xyz` (default 0) and `rpy` (default 0), named `name` in errors (a config
/// file's `[robot.mount]`).
///
/// # Errors
/// An array of the wrong length.
pub fn frame_from_xyz_rpy(
    xyz: Option<&[f64]>,
    rpy: Option<&[f64]>,
    name: &str,
) -> Result<FrameData<f64>, ArmError> {
    let f = FrameFile { xyz: xyz.map(<[f64]>::to_vec), rpy: rpy.map(<[f64]>::to_vec), rotation: None };
    frame(Some(&f), name)
}

/// A frame's numbers: `xyz` (default 0) and `rpy` or `rotation` (default identity).
fn frame(f: Option<&FrameFile>, name: &str) -> Result<FrameData<f64>, ArmError> {
    let f = f.map_or_else(FrameFile::default, |f| FrameFile {
        xyz: f.xyz.clone(),
        rpy: f.rpy.clone(),
        rotation: f.rotation.clone(),
    });
    let xyz = match &f.xyz {
        Some(v) => array::<3>(v, format!("{name}.xyz"))?,
        None => [0.0; 3],
    };
    let rotation = match (&f.rpy, &f.rotation) {
        (Some(_), Some(_)) => return Err(ArmError::TwoRotations { field: name.to_string() }),
        (Some(rpy), None) => {
            let [r, p, y] = array::<3>(rpy, format!("{name}.rpy"))?;
            let m = so3::from_rpy(r, p, y);
            core::array::from_fn(|i| core::array::from_fn(|j| m[(i, j)]))
        }
        (None, Some(rows)) => {
            if rows.len() != 3 {
                return Err(ArmError::WrongLength {
                    field: format!("{name}.rotation"),
                    expected: 3,
                    found: rows.len(),
                });
            }
            let mut m = [[0.0; 3]; 3];
            for (i, row) in rows.iter().enumerate() {
                m[i] = array::<3>(row, format!("{name}.rotation[{i}]"))?;
            }
            m
        }
        (None, None) => {
            let m = Matrix3::<f64>::identity();
            core::array::from_fn(|i| core::array::from_fn(|j| m[(i, j)]))
        }
    };
    Ok(FrameData { xyz, rotation })
}

#[cfg(test)]
mod tests {
    use companion_core::nalgebra::SVector;
    use companion_core::Rule;

    use crate::domain::scenario::ConfigFile;

    use super::*;

    fn example(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/arms").join(name)
    }

    /// The shipped UR5 file is the preset: the same chain, field for field.
    #[test]
    fn the_ur5_file_is_the_preset() {
        let d = ArmDescription::load(&example("ur5.toml")).expect("valid");
        let file = d.chain::<f64, 6>().unwrap();
        let preset = Chain::<f64, 6>::ur5();
        assert_eq!(file.limits(), preset.limits());
        assert_eq!(file.home(), preset.home());
        assert_eq!(file.max_velocities(), preset.max_velocities());
        // The frames: equal to the last bit but for sign of zero, and the end effector at
        // configurations across the range.
        assert_eq!(file, preset);
        for k in 0..50 {
            let q = SVector::<f64, 6>::from_fn(|i, _| ((k * 7 + i * 3) as f64).sin() * 2.0);
            let (a, b) = (file.end_effector(&q), preset.end_effector(&q));
            assert_eq!(a, b, "q = {q}");
        }
        // And in f32.
        assert_eq!(d.chain::<f32, 6>().unwrap().home(), Chain::<f32, 6>::ur5().home());
        // So the HIL handshake takes one for the other: the same arm hash, though the file's
        // rotations (from rpy) carry −0.0 where the preset's carry 0.0.
        let hash = crate::transport::wire::canonical::arm_hash;
        assert_eq!(hash(&file), hash(&preset));
        assert_eq!(crate::transport::wire::canonical::arm_name(hash(&file)), Some("ur5"));
        let mut narrower = file;
        narrower.joints[0].upper = 3.0;
        assert_ne!(hash(&narrower), hash(&preset), "a limit is part of the arm");
    }

    #[test]
    fn the_panda_file_is_valid_and_has_seven_joints() {
        let d = ArmDescription::load(&example("panda.toml")).expect("valid");
        let file = d.chain::<f64, 7>().unwrap();
        let preset = Chain::<f64, 7>::panda();
        assert_eq!(file.limits(), preset.limits());
        for k in 0..20 {
            let q = SVector::<f64, 7>::from_fn(|i, _| ((k * 5 + i) as f64).cos());
            let (a, b) = (file.end_effector(&q), preset.end_effector(&q));
            assert!((a.translation - b.translation).norm() < 1e-12);
            assert!((a.rotation - b.rotation).norm() < 1e-12);
        }
        // And it carries the preset's platform settings.
        assert_eq!(d.platform, SpatialArmSpec::Panda.platform_defaults());
        assert_eq!(d.platform.unicycle, Some(PANDA_UNICYCLE));
        assert_eq!(d.platform.car, Some(PANDA_CAR));
    }

    /// The UR5 file carries no platform settings, as the preset; a file's `[car]` and
    /// `[unicycle]` fill a config file's missing tables only.
    #[test]
    fn platform_settings_fill_only_what_the_config_lacks() {
        let d = ArmDescription::load(&example("ur5.toml")).expect("valid");
        assert!(d.platform.is_empty());
        assert!(SpatialArmSpec::Ur5.platform_defaults().is_empty());
        let car = "[car]\nepsilon = 0.2\neta_1 = 1.0\neta_2 = 2.0\neta_3 = 1.0\nk = 10.0\n";
        let d = ArmDescription::from_toml_str(&format!("{}\n{car}", ur5_text()), "x").expect("valid");
        let carried = d.platform.car.expect("[car] read");
        assert_eq!(carried.eta_2, 2.0);
        assert_eq!(d.platform.unicycle, None);
        let filled = ConfigFile::default().with_arm_settings(d.platform);
        assert_eq!(filled.car, Some(carried));
        assert_eq!(filled.unicycle, None);
        let mut own = ConfigFile::default();
        own.car = Some(CarConfig::default());
        assert_eq!(own.with_arm_settings(d.platform).car, Some(CarConfig::default()), "--config wins");
        let panda = ConfigFile::default().with_arm_settings(SpatialArmSpec::Panda.platform_defaults());
        assert_eq!(panda.unicycle, Some(PANDA_UNICYCLE));
        let bad = format!("{}\n[unicycle]\nepsilon_1 = 0.2\nepsilon = 0.8\n", ur5_text());
        let e = ArmDescription::from_toml_str(&bad, "x").unwrap_err().to_string();
        assert!(e.contains("unknown field `epsilon`"), "{e}");
    }

    /// A scaled arm: its speeds times `joint_speed`, its lengths times `reach` (the end
    /// effector's offset from the mount at any configuration scales with it, its orientation
    /// does not), its limits and name the arm's; the factor 1 is the arm bit for bit, and a
    /// factor that is not positive is refused by name.
    #[test]
    fn a_scaled_arm_is_a_faster_or_larger_copy() {
        let scale = ArmScale { joint_speed: 1.5, reach: 0.8 };
        let spec = SpatialArmSpec::Panda.scaled(scale);
        assert_eq!((spec.name(), spec.joints()), ("panda", 7));
        assert_eq!(spec.platform_defaults(), SpatialArmSpec::Panda.platform_defaults());
        let (a, b) = (Chain::<f64, 7>::panda(), spec.chain::<f64, 7>().unwrap());
        assert_eq!(a.limits(), b.limits());
        assert_eq!(b.max_velocities(), a.max_velocities() * 1.5);
        for k in 0..10 {
            let q = SVector::<f64, 7>::from_fn(|i, _| ((k * 3 + i) as f64).sin());
            let (ea, eb) = (a.end_effector(&q), b.end_effector(&q));
            let offset = |e: &companion_core::Pose3<f64>| e.translation - a.mount.translation;
            assert!((offset(&eb) - offset(&ea) * 0.8).norm() < 1e-12, "q = {q}");
            assert!((eb.rotation - ea.rotation).norm() < 1e-12);
        }
        // Scaled twice: the factors multiply.
        let twice = spec.clone().scaled(ArmScale { joint_speed: 2.0, reach: 1.0 });
        assert_eq!(twice.chain::<f64, 7>().unwrap().max_velocities(), a.max_velocities() * 3.0);
        assert_eq!(SpatialArmSpec::Ur5.scaled(ArmScale::ONE), SpatialArmSpec::Ur5);
        assert_eq!(ArmScale::ONE.apply(&Chain::<f32, 6>::ur5()).unwrap(), Chain::<f32, 6>::ur5());
        let bad = SpatialArmSpec::Ur5.scaled(ArmScale { joint_speed: 1.0, reach: -1.0 });
        let e = bad.chain::<f64, 6>().unwrap_err().to_string();
        assert_eq!(e, "arm scale: reach = -1 must be finite and > 0");
    }

    fn ur5_text() -> String {
        std::fs::read_to_string(example("ur5.toml")).unwrap()
    }

    #[test]
    fn bad_files_name_the_field() {
        let err = |t: &str| ArmDescription::from_toml_str(t, "x").unwrap_err().to_string();
        let one = "[[joint]]\ntype = \"revolute\"\naxis = [0, 0, 1]\nlimits = [-1, 1]\nhome = 0\n";
        assert!(err(&one.repeat(3)).contains("needs 6 to 8 joints ([[joint]] tables), the file has 3"));
        assert!(err(&one.repeat(9)).contains("the file has 9"));
        let empty =
            ur5_text().replacen("limits = [-6.283185307179586, 6.283185307179586]", "limits = [1.0, 1.0]", 1);
        assert_eq!(err(&empty), format!("arm file: joint 1: limits: {}", Rule::EmptyInterval));
        let outside = ur5_text().replacen("home = 0.0", "home = 7.0", 1);
        assert_eq!(err(&outside), format!("arm file: joint 1: home: {}", Rule::HomeOutsideLimits));
        let skew = ur5_text().replacen(
            "rpy = [0.0, 0.0, 3.141592653589793]",
            "rotation = [[1, 0, 0], [0, 1, 0.1], [0, 0, 1]]",
            1,
        );
        assert_eq!(err(&skew), format!("arm file: mount.rotation: {}", Rule::NotOrthonormal));
        let axis = ur5_text().replacen("axis = [0.0, 0.0, 1.0]", "axis = [0.0, 0.0, 2.0]", 1);
        assert_eq!(err(&axis), format!("arm file: joint 1: axis: {}", Rule::NotUnitVector));
        let short = ur5_text().replacen("axis = [0.0, 0.0, 1.0]", "axis = [0.0, 1.0]", 1);
        assert_eq!(err(&short), "arm file: joint 1: axis has 2 entries: it must have 3");
        let unknown = ur5_text().replacen("home = 0.0", "home = 0.0\nspeed = 1", 1);
        let e = err(&unknown);
        assert!(e.contains("unknown field `speed`") && e.contains("line"), "{e}");
    }
}
