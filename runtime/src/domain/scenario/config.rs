//! The TOML file given with `--config`: overrides of the controller's parameters, the
//! platform's transverse-function parameters, velocity limits and plant imperfections.
//!
//! Every key is the name of the field it sets (in `companion-core` for the controller's
//! tables, in `companion-plant`'s `Imperfections` and `Noise` for `[plant]`); unknown keys are
//! an error, and so is an array of the wrong length.
//!
//! ```toml
//! [controller]
//! gain = [3.0, 3.0, 3.0]        # PrimaryTask::gain (1/s)
//! filter_sigma = 10.0           # PrimaryTask::filter_sigma
//! rest_filter = "explicit"      # SecondaryTask::rest_filter
//!
//! [car]
//! epsilon = 0.3
//! eta_1 = 2.0
//! eta_2 = 3.0
//! eta_3 = 2.0
//! k = 5.0
//!
//! [velocity_limits]
//! forward = 1.0                 # m/s
//!
//! [arm]
//! stroke = 0.9                  # q₂⁺ (m); q₂*, the margins and r_* follow (see ArmConfig)
//!
//! [plant]
//! actuator_lag = 0.05           # s
//! [plant.noise]
//! position = 1e-3
//! angle = 1e-3
//! joints = 5e-4
//! ```

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::domain::arm::PlatformDefaults;
use crate::domain::controller::{ArmConfig, CarConfig, ControllerConfig, LimitsConfig, UnicycleConfig};

/// Plant imperfections in a config file (`companion-plant`'s `Imperfections`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantFileConfig {
    /// Actuator lag time constant (s).
    pub actuator_lag: Option<f64>,
    /// Wheel-speed scale error `e` (speed × (1 + e)).
    pub wheel_scale_error: Option<f64>,
    /// Noise seed.
    pub seed: Option<u64>,
    /// Measurement noise standard deviations.
    pub noise: Option<NoiseConfig>,
}

/// Measurement-noise standard deviations (`companion-plant`'s `Noise`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseConfig {
    /// On positions (m).
    pub position: f64,
    /// On angles (rad).
    pub angle: f64,
    /// On joints (rad or m).
    pub joints: f64,
    /// On the car's steering state `ξ` (1/m); default `Noise::typical()`'s.
    #[serde(default = "typical_steering_noise")]
    pub steering: f64,
}

fn typical_steering_noise() -> f64 {
    companion_plant::Noise::typical().steering
}

impl Default for NoiseConfig {
    /// σ = 1 mm, 1 mrad, 0.5 mrad on joints (what `--noise` turns on).
    fn default() -> Self {
        Self { position: 1e-3, angle: 1e-3, joints: 5e-4, steering: typical_steering_noise() }
    }
}

/// `[robot]`: the keys of `--base-link`, `--tip-link`, `--srdf`, `--home-state` and `--home`
/// for a URDF arm (a flag wins over its key), and the arm's mount on the platform, which has
/// no flag. Paths are relative to the config file's folder.
///
/// ```toml
/// [robot]
/// base_link = "base_footprint"
/// tip_link = "arm_tool_link"
/// home = [0.2, 1.0, -0.5, -1.0, 1.2, 0.0, 0.5, 0.0]   # or { torso_lift_joint = 0.2, … }
/// # srdf = "robot.srdf"  and  home_state = "home"
/// [robot.mount]                                       # the base link on the platform
/// xyz = [0.0, 0.0, 0.0]
/// rpy = [0.0, 0.0, 0.0]
/// ```
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    /// The link the chain starts from.
    pub base_link: Option<String>,
    /// The end effector's link.
    pub tip_link: Option<String>,
    /// An SRDF for `home_state`.
    pub srdf: Option<PathBuf>,
    /// A `<group_state>` of `srdf`.
    pub home_state: Option<String>,
    /// The home: every joint's value in the chain's order, or a table of joints by name.
    pub home: Option<HomeConfig>,
    /// The arm's base link seen from the platform's frame.
    pub mount: Option<MountConfig>,
}

/// `[robot] home`: a list in the chain's order, or a table by joint name.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum HomeConfig {
    /// `[q1, …, qN]`.
    Values(Vec<f64>),
    /// `{ name = value, … }`.
    Named(std::collections::BTreeMap<String, f64>),
}

/// `[robot.mount]`: `xyz` (m) and `rpy` (rad), each optional (zero).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MountConfig {
    /// Translation (m).
    pub xyz: Option<Vec<f64>>,
    /// Roll, pitch, yaw about fixed axes x, y, z (rad).
    pub rpy: Option<Vec<f64>>,
}

/// The TOML file given with `--config`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConfigFile {
    /// Controller overrides.
    #[serde(default)]
    pub controller: ControllerConfig,
    /// Lemma 1's parameters.
    pub unicycle: Option<UnicycleConfig>,
    /// Lemma 2's parameters.
    pub car: Option<CarConfig>,
    /// Velocity limits.
    pub velocity_limits: Option<LimitsConfig>,
    /// The arm's prismatic stroke.
    pub arm: Option<ArmConfig>,
    /// Plant imperfections.
    #[serde(default)]
    pub plant: PlantFileConfig,
    /// Where a URDF arm (`--arm robot.urdf`) is cut, its home and its mount (`[robot]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<RobotConfig>,
    /// Read for a spatial arm ([`with_arm_settings`](Self::with_arm_settings)): its law's
    /// `[controller]` keys are allowed (a planar run refuses them).
    #[serde(skip)]
    pub(super) spatial_arm: bool,
}

/// A config file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file cannot be read.
    #[error("reading {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not TOML of the expected shape.
    #[error("in config file {}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// Why (with the line and the key).
        source: Box<toml::de::Error>,
    },
}

impl ConfigFile {
    /// Reads and checks a config file.
    ///
    /// # Errors
    /// The file cannot be read or is not valid TOML of this shape.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| ConfigError::Read { path: path.into(), source })?;
        toml::from_str(&text).map_err(|e| ConfigError::Parse { path: path.into(), source: Box::new(e) })
    }

    /// This file for a spatial arm, with the platform settings the arm carries wherever it
    /// has no table of its own: a `[unicycle]` or `[car]` of the run's `--config` wins over
    /// the arm's. The spatial law's `[controller]` keys (`damping_below`, `damping_depth`,
    /// `singular_below`) are allowed in it.
    pub fn with_arm_settings(mut self, arm: PlatformDefaults) -> Self {
        self.spatial_arm = true;
        if self.unicycle.is_none() {
            self.unicycle = arm.unicycle;
        }
        if self.car.is_none() {
            self.car = arm.car;
        }
        self
    }

    /// Whether the file was read for a spatial arm ([`with_arm_settings`](Self::with_arm_settings)).
    pub fn is_for_spatial_arm(&self) -> bool {
        self.spatial_arm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_keys_and_long_arrays_are_errors() {
        let e = toml::from_str::<ConfigFile>("[car]\nepsilon = 0.3\neta = [2, 3, 2, 99]\nk = 5").unwrap_err();
        assert!(e.to_string().contains("unknown field `eta`"), "{e}");
        let e =
            toml::from_str::<ConfigFile>("[plant.noise]\nposition = 1\nangle = 1\njoint = 1").unwrap_err();
        assert!(e.to_string().contains("unknown field `joint`"), "{e}");
        let f: ConfigFile = toml::from_str(
            "[velocity_limits]\nforward = 1.0\n[plant.noise]\nposition = 1\nangle = 2\njoints = 3",
        )
        .unwrap();
        assert_eq!(f.velocity_limits.and_then(|l| l.forward), Some(1.0));
        assert_eq!(f.plant.noise.map(|n| n.joints), Some(3.0));
    }
}
