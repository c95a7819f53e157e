//! What the runtime needs to build a controller: the platform, the scalar type, the paper's
//! variant and the overrides of the `[controller]`, `[unicycle]`, `[car]`,
//! `[velocity_limits]` and `[acceleration_limits]` tables of a `--config` file.
//!
//! One parameter has one name: every key of these tables is the name of the field of
//! `companion-core` it sets (`gain` is `PrimaryTask::gain`, `filter_sigma` is
//! `PrimaryTask::filter_sigma`, `nu` is the `nu` of `Precompensation::Full40`, …), which is
//! also the name a `ParamError` reports. Unknown keys are an error, and so is an array with
//! more or fewer elements than the field has.

use companion_core::nalgebra::{SVector, Vector3};
use companion_core::{
    AccelerationLimits, CarLike, Discretisation, HeadingFilter, PaperRun, ParamError, Params, PlatformKind,
    Pose, Precompensation, Real, RestFilter, Rpr, Rule, TargetMotion, TermRule, Unicycle, VelocityLimits,
    Weight, WeightMargins,
};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

pub use crate::domain::platform_config::{CarConfig, UnicycleConfig};

/// The controller's scalar type.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scalar {
    /// Double precision (the reference).
    #[default]
    F64,
    /// Single precision (what a Cortex-M4F runs).
    F32,
}

impl Scalar {
    /// `f64` or `f32`, as written in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::F64 => "f64",
            Self::F32 => "f32",
        }
    }
}

/// How the rest filter (28) is advanced, as written in a config file (`companion-core`'s
/// `RestFilter`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RestFilterConfig {
    /// Explicit Euler (a literal discretisation of the paper).
    Explicit,
    /// Linearly implicit Euler (the default).
    LinearlyImplicit,
}

impl From<RestFilterConfig> for RestFilter {
    fn from(r: RestFilterConfig) -> Self {
        match r {
            RestFilterConfig::Explicit => RestFilter::Explicit,
            RestFilterConfig::LinearlyImplicit => RestFilter::LinearlyImplicit,
        }
    }
}

/// How the law becomes a held command, as written in a config file and on the command line
/// (`companion-core`'s `Discretisation`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DiscretisationConfig {
    /// The law at the measured state, held (first order in the period).
    Sampled,
    /// Hold-aware: the law at the state predicted for the middle of the hold (the default;
    /// second order in the period, compensates the measurement delay).
    #[default]
    Midpoint,
}

impl From<DiscretisationConfig> for Discretisation {
    fn from(d: DiscretisationConfig) -> Self {
        match d {
            DiscretisationConfig::Sampled => Discretisation::Sampled,
            DiscretisationConfig::Midpoint => Discretisation::Midpoint,
        }
    }
}

/// How the target's motion is extrapolated, as written in a config file
/// (`companion-core`'s `TargetMotion`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TargetMotionConfig {
    /// The measured velocity held.
    Held,
    /// Extrapolated to second order from the last three measured velocities (the default).
    Extrapolated,
}

impl From<TargetMotionConfig> for TargetMotion {
    fn from(t: TargetMotionConfig) -> Self {
        match t {
            TargetMotionConfig::Held => TargetMotion::Held,
            TargetMotionConfig::Extrapolated => TargetMotion::Extrapolated,
        }
    }
}

/// Reads an array of exactly `N` numbers (TOML and serde would otherwise drop extra ones).
fn exact<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<Option<[f64; N]>, D::Error> {
    let v = Vec::<f64>::deserialize(d)?;
    let n = v.len();
    <[f64; N]>::try_from(v).map(Some).map_err(|_| {
        serde::de::Error::invalid_length(n, &format!("an array of exactly {N} numbers").as_str())
    })
}

/// Overrides of the paper's §4.3 controller parameters (SI units; see `companion-core`).
/// Each key is the core's field name.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerConfig {
    /// `r*_ed = (x, y, θ)`, the target seen from the end effector (m, m, rad); paper
    /// `(0.5, 0, 0)`. Unless `preferred_pose` is given, `preferred_pose` follows its `x` as
    /// the paper's does: `−(x + L_e + L + 0.45, 0, 0)`.
    #[serde(default, deserialize_with = "exact")]
    pub target_in_effector: Option<[f64; 3]>,
    /// `r_*`, the platform's preferred pose seen from the target (m, m, rad).
    #[serde(default, deserialize_with = "exact")]
    pub preferred_pose: Option<[f64; 3]>,
    /// Gains `gᵢ` of `G = −diag(gᵢ)` (1/s).
    #[serde(default, deserialize_with = "exact")]
    pub gain: Option<[f64; 3]>,
    /// Weights `αᵢ` of the joint-limit penalty (20).
    #[serde(default, deserialize_with = "exact")]
    pub penalty_weight: Option<[f64; 3]>,
    /// Margins `δᵢ` of the joint-limit penalty (21) (rad or m).
    #[serde(default, deserialize_with = "exact")]
    pub penalty_margin: Option<[f64; 3]>,
    /// `γ₀` of `Γ(t) = γ₀ e^{−λ_Γ t}`.
    pub regularisation_gain: Option<f64>,
    /// `λ_Γ` (1/s).
    pub regularisation_decay: Option<f64>,
    /// `σ` of the `q̂` filter (26) (joint units per second).
    pub filter_sigma: Option<f64>,
    /// `ξ` of the `q̂` filter (26) (joint units).
    pub filter_xi: Option<f64>,
    /// `K̄` diagonal of (36).
    #[serde(default, deserialize_with = "exact")]
    pub k_bar: Option<[f64; 3]>,
    /// `D` diagonal of (37).
    #[serde(default, deserialize_with = "exact")]
    pub d: Option<[f64; 3]>,
    /// `μ` of (37).
    pub mu: Option<f64>,
    /// `ν` of (40) (run b only).
    pub nu: Option<f64>,
    /// `λ` of the Ψ filter (53) (1/s; runs b–d).
    pub lambda: Option<f64>,
    /// `γ` of the distance in `h_s1` (49) (m²).
    pub gamma_1: Option<f64>,
    /// `γ` of the distance in `h_s2` (27) (m²).
    pub gamma_2: Option<f64>,
    /// `σᵢ` of the rest filter (28) (1/s).
    #[serde(default, deserialize_with = "exact")]
    pub rest_sigma: Option<[f64; 3]>,
    /// `ξ` of the rest filter (28) (m).
    pub rest_xi: Option<f64>,
    /// Include `Ψ̇ (h_s1 − h_s2)` in `∂h_s/∂t`.
    pub psi_rate_in_drift: Option<bool>,
    /// How the rest filter (28) is advanced: `"linearly_implicit"` (default) or `"explicit"`.
    pub rest_filter: Option<RestFilterConfig>,
    /// The largest accepted time step (s).
    pub max_time_step: Option<f64>,
    /// `κ`: no joint covers more than this fraction of its distance to a limit in one step.
    pub joint_step_fraction: Option<f64>,
    /// `|q̇ᵢ|` limits (rad/s or m/s).
    #[serde(default, deserialize_with = "exact")]
    pub joint_velocity_limits: Option<[f64; 3]>,
    /// How the law becomes a held command: `"midpoint"` (default) or `"sampled"`.
    pub discretisation: Option<DiscretisationConfig>,
    /// How the target's motion is extrapolated: `"extrapolated"` (default) or `"held"`.
    pub target_motion: Option<TargetMotionConfig>,
    /// The largest measurement delay the law accepts (s).
    pub max_delay: Option<f64>,
    /// The largest turn of `α` or the heading within one period (rad).
    pub max_turn_per_step: Option<f64>,
    /// How far the rest filter's virtual frame may lag (m).
    pub rest_reach: Option<f64>,
    /// The heading filter's `σ` (rad/s; default 0.05 when `heading_xi` is given): the
    /// platform's reference heading turns at most this fast towards the target's
    /// (`companion_core::HeadingFilter`; neither key: the paper's `h_s1`).
    pub heading_rate: Option<f64>,
    /// The heading filter's `ξ` (rad; default 0.2 when `heading_rate` is given): its gain
    /// near zero lag is `σ/ξ`.
    pub heading_xi: Option<f64>,
    /// A spatial arm's limits as the law keeps them, by joint name (`[lower, upper]`, rad or
    /// m), inside the robot's own: the law's penalty, weight and joint guard keep the joint
    /// within them; the plant keeps the robot's. E.g. an elbow kept on one side of straight.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_limits: Option<std::collections::BTreeMap<String, [f64; 2]>>,
    /// A spatial arm's damping onset `ρ₀ ∈ [0, 1)`: below this measure of its distance to a
    /// singular configuration the arm's inverse is damped (default `10⁻³`; 0: never).
    /// Spatial arms only (`companion_core::SpatialArm::with_damping`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping_below: Option<f64>,
    /// A spatial arm's damping depth `κ ∈ [0, 1)` at a singular configuration, relative to
    /// the mean diagonal (default 0.1). Spatial arms only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping_depth: Option<f64>,
    /// A spatial arm's `ρ_min ∈ [0, 1)`: a step below it is refused as singular (default
    /// `10⁻¹⁰`). Spatial arms only (`companion_core::SpatialArm::with_singular_below`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub singular_below: Option<f64>,
    /// Whether a spatial arm's weight `Ψ̃` (52) sees its reach — the wrist's extension, its
    /// clearance from the first joint's axis, the first joint's bearing (default true; false:
    /// the paper's (52), its joints alone). Spatial arms only (`companion_core::reach`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reach: Option<bool>,
    /// The joints whose origins and axis define a spatial arm's reach, by name: the shoulder,
    /// the wrist and the joint whose axis the clearance is measured from (default: the
    /// chain's second revolute joint, its wrist joint, its first revolute joint).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reach_joints: Option<[String; 3]>,
    /// The fraction of the room from the arm's home to each limit of its reach at which the
    /// weight's ramp starts, in `(0, 1)`: below 1 the home is outside every ramp (default: the
    /// paper's 0.2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reach_margin: Option<f64>,
    /// How the reach's terms enter `Ψ̃` with the joints': `"max"` (default: the largest of
    /// all) or `"mean"` (averaged, as (52) averages the joints).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reach_rule: Option<ReachRuleConfig>,
}

/// How a spatial arm's reach enters its weight, as written in a config file
/// (`companion-core`'s `TermRule`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReachRuleConfig {
    /// The largest of the joints' and the reach's terms (the default).
    Max,
    /// Averaged with them.
    Mean,
}

impl From<ReachRuleConfig> for TermRule {
    fn from(r: ReachRuleConfig) -> Self {
        match r {
            ReachRuleConfig::Max => TermRule::Max,
            ReachRuleConfig::Mean => TermRule::Mean,
        }
    }
}

/// The car's default `K̄ = diag(k̄_v, k̄_α₁, k̄_α₂)` for `w = (v, α̇₁, α̇₂)` (found with
/// [`CarConfig::default`]'s parameters): `α̇₂`, which moves the platform's heading and lateral
/// offset, is cheap; `α̇₁`, which swings the steering, about as dear as driving.
pub const CAR_K_BAR: [f64; 3] = [1.0, 2.07, 254.0];

/// The omnidirectional platform's `K̄`: the paper's form (36) `K̄ = diag(k̄_b, k̄_b, k̄_α)`
/// weighs the platform's velocity `u_b` by `k̄_b` and only `α̇` by `k̄_α`; with `f = 0` there
/// is no `α` and `w = u_b = (v₁, v₂, ω)`, so `K = K̄ = k̄_b I₃` (`k̄_b = 1`). The unicycle's
/// `diag(1, 1, 100)` would make turning a hundred times cheaper than driving.
pub const OMNI_K_BAR: [f64; 3] = [1.0, 1.0, 1.0];
/// The heading filter's default `σ` (rad/s) when a config sets only its `ξ`.
pub const DEFAULT_HEADING_RATE: f64 = 0.05;
/// The heading filter's default `ξ` (rad) when a config sets only its rate.
pub const DEFAULT_HEADING_XI: f64 = 0.2;

/// The paper's RPR arm's prismatic stroke `q₂⁺` (m) and preferred extension `q₂*` (m), §4.3.
pub const PAPER_STROKE: f64 = 0.7;
/// See [`PAPER_STROKE`].
pub const PAPER_PREFERRED_EXTENSION: f64 = 0.45;

/// The arm's prismatic joint, for arms that differ from the paper's only in its stroke (the
/// `[arm]` table of a config file). Not a field of `companion-core`: it sets several of them
/// as §4.3 derives them from the arm — the limit `q₂⁺`, the penalty margin `δ₂ = 0.05 q₂⁺`,
/// the weight margins of (52) around `q₂*`, and `r_* = −(X* + L_e + L + q₂*, 0, 0)` — unless
/// those are given explicitly.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmConfig {
    /// `q₂⁺` (m): the prismatic joint moves in `(0, stroke)`. Paper: 0.7.
    pub stroke: Option<f64>,
    /// `q₂*` (m), in `(0, stroke)`. Default: `0.45 · stroke / 0.7` (the paper's proportion).
    pub preferred_extension: Option<f64>,
}

impl ArmConfig {
    /// `(q₂⁺, q₂*)` (m).
    pub fn stroke_and_extension(&self) -> (f64, f64) {
        let stroke = self.stroke.unwrap_or(PAPER_STROKE);
        let proportional = if stroke == PAPER_STROKE {
            PAPER_PREFERRED_EXTENSION
        } else {
            PAPER_PREFERRED_EXTENSION * stroke / PAPER_STROKE
        };
        let ext = self.preferred_extension.unwrap_or(proportional);
        (stroke, ext)
    }

    /// Checks `0 < q₂* < q₂⁺ ≤ 10³`.
    ///
    /// # Errors
    /// The parameter that breaks the rule.
    pub fn validate(&self) -> Result<(), ParamError> {
        let (stroke, ext) = self.stroke_and_extension();
        if !stroke.is_finite() {
            return Err(ParamError::new("arm.stroke", Rule::NonFinite));
        }
        if stroke <= 0.0 {
            return Err(ParamError::new("arm.stroke", Rule::NotPositive));
        }
        if !ext.is_finite() {
            return Err(ParamError::new("arm.preferred_extension", Rule::NonFinite));
        }
        if ext <= 0.0 || ext >= stroke {
            return Err(ParamError::new("arm.preferred_extension", Rule::Geometry));
        }
        Ok(())
    }
}

/// Velocity limits (`companion-core`'s `VelocityLimits`; omitted fields: no limit).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LimitsConfig {
    /// `|v|` (m/s).
    pub forward: Option<f64>,
    /// `|v_lat|` (m/s).
    pub lateral: Option<f64>,
    /// `|ω|` (rad/s).
    pub angular: Option<f64>,
    /// `|α̇ᵢ|` (rad/s).
    pub alpha_rate: Option<f64>,
    /// `|v_ξ|` (1/(m·s)).
    pub steering_rate: Option<f64>,
}

impl LimitsConfig {
    /// The limits in `T` (an omitted one is `+∞`).
    pub fn to_limits<T: Real>(self) -> VelocityLimits<T> {
        let l = |x: Option<f64>| T::of(x.unwrap_or(f64::INFINITY));
        VelocityLimits {
            forward: l(self.forward),
            lateral: l(self.lateral),
            angular: l(self.angular),
            alpha_rate: l(self.alpha_rate),
            steering_rate: l(self.steering_rate),
        }
    }

    /// The TIAGo's base as PAL configures its controller: 1.0 m/s forward (PAL's
    /// `linear.x.max_velocity`; backwards PAL allows 0.2 m/s, which these symmetric limits do
    /// not model) and 2.09 rad/s (`angular.z.max_velocity`, 120°/s). Source:
    /// `tiago_controller_configuration/config/mobile_base_controller.yaml` in
    /// pal-robotics/tiago_robot (the same figures in pmb2_robot's
    /// `pmb2_controller_configuration`, the TIAGo's base). A differential drive: no lateral
    /// speed, no `α̇` or steering limit.
    pub fn tiago() -> Self {
        Self { forward: Some(1.0), lateral: None, angular: Some(2.09), alpha_rate: None, steering_rate: None }
    }

    /// The realistic robot's limits (`companion_plant::realistic_limits`).
    pub fn realistic() -> Self {
        let l = companion_plant::realistic_limits();
        let opt = |x: f64| x.is_finite().then_some(x);
        Self {
            forward: opt(l.forward),
            lateral: opt(l.lateral),
            angular: opt(l.angular),
            alpha_rate: opt(l.alpha_rate),
            steering_rate: opt(l.steering_rate),
        }
    }
}

/// Acceleration limits (`companion-core`'s `AccelerationLimits`; omitted fields: no limit),
/// met by a second common factor on the change of the command (`companion_core::acceleration`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AccelerationConfig {
    /// `|v̇|` of the forward speed (m/s²).
    pub forward: Option<f64>,
    /// `|v̇_lat|` (m/s²), omnidirectional platform.
    pub lateral: Option<f64>,
    /// `|ω̇|` (rad/s²), unicycle and omnidirectional platforms.
    pub angular: Option<f64>,
    /// Per joint (rad/s² or m/s²): exactly as many values as the arm has joints.
    pub joints: Option<Vec<f64>>,
}

impl AccelerationConfig {
    /// The TIAGo's base as PAL configures its controller (the same file as
    /// [`LimitsConfig::tiago`]): `linear.x.max_acceleration` 1.0 m/s² and
    /// `angular.z.max_acceleration` 2.09 rad/s² (120°/s²). PAL publishes no acceleration limit
    /// for the arm and the torso (`tiago_moveit_config/config/joint_limits.yaml`:
    /// `has_acceleration_limits: false` for every joint), so none here. (A bound from the
    /// URDF instead: two 6 N·m wheel motors on 0.0985 m wheels push 122 N, ≈ 1.9 m/s² for the
    /// 65 kg of links — PAL's 1.0 is below it.)
    pub fn tiago() -> Self {
        Self { forward: Some(1.0), lateral: None, angular: Some(2.09), joints: None }
    }

    /// The joints' limits for an arm of `N` joints (`+∞` for each when `joints` is not set);
    /// `None` when `joints` has another number of values.
    pub fn joints<T: Real, const N: usize>(&self) -> Option<SVector<T, N>> {
        match &self.joints {
            None => Some(SVector::repeat(T::of(f64::INFINITY))),
            Some(v) if v.len() == N => Some(SVector::from_fn(|i, _| T::of(v[i]))),
            Some(_) => None,
        }
    }

    /// The limits in `T` for an arm of `N` joints (an omitted one is `+∞`; the joints `+∞`
    /// when their count is not `N`: the scenario refuses that before).
    pub fn to_limits<T: Real, const N: usize>(&self) -> AccelerationLimits<T, N> {
        let l = |x: Option<f64>| T::of(x.unwrap_or(f64::INFINITY));
        AccelerationLimits {
            forward: l(self.forward),
            lateral: l(self.lateral),
            angular: l(self.angular),
            joints: self.joints::<T, N>().unwrap_or_else(|| SVector::repeat(T::of(f64::INFINITY))),
        }
    }
}

/// The platform's name as written in files and on the command line.
pub fn platform_name(k: PlatformKind) -> &'static str {
    match k {
        PlatformKind::Unicycle => "unicycle",
        PlatformKind::Car => "car",
        PlatformKind::Omni => "omni",
    }
}

/// The paper variant's letter as written in files and on the command line.
pub fn run_name(r: PaperRun) -> &'static str {
    match r {
        PaperRun::A => "a",
        PaperRun::B => "b",
        PaperRun::C => "c",
        PaperRun::D => "d",
    }
}

fn ser_platform<S: Serializer>(k: &PlatformKind, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(platform_name(*k))
}

fn ser_run<S: Serializer>(r: &PaperRun, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(run_name(*r))
}

/// Everything needed to build the controller (in f64 or f32).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ControllerSpec {
    /// The platform.
    #[serde(serialize_with = "ser_platform")]
    pub platform: PlatformKind,
    /// The scalar type.
    pub scalar: Scalar,
    /// The paper's variant.
    #[serde(serialize_with = "ser_run")]
    pub choice: PaperRun,
    /// Overrides of the paper's parameters.
    pub overrides: ControllerConfig,
    /// Lemma 1's parameters.
    pub unicycle: UnicycleConfig,
    /// Lemma 2's parameters.
    pub car: CarConfig,
    /// Velocity limits (None: unlimited).
    pub limits: Option<LimitsConfig>,
    /// Acceleration limits (None: unlimited).
    pub acceleration: Option<AccelerationConfig>,
    /// The arm's prismatic stroke (the paper's by default).
    pub arm: ArmConfig,
    /// `α(0)`: the transverse-function variables the controller starts from (rad; the
    /// unicycle uses the first, the omnidirectional platform none). SPEC §3: 0.
    pub initial_alpha: [f64; 2],
}

fn t<T: Real>(x: f64) -> T {
    T::of(x)
}

fn v3<T: Real>(a: [f64; 3]) -> SVector<T, 3> {
    SVector::<T, 3>::new(t(a[0]), t(a[1]), t(a[2]))
}

fn pose<T: Real>(a: [f64; 3]) -> Pose<T> {
    Pose::new(t(a[0]), t(a[1]), t(a[2]))
}

impl ControllerSpec {
    /// The paper's parameters for `choice` on `platform` in `scalar`, with the runtime's
    /// defaults (the car's `K̄`, Lemma 1's and 2's parameters, no limits).
    pub fn paper(platform: PlatformKind, choice: PaperRun, scalar: Scalar) -> Self {
        Self {
            platform,
            scalar,
            choice,
            overrides: ControllerConfig::default(),
            unicycle: UnicycleConfig::default(),
            car: CarConfig::default(),
            limits: None,
            acceleration: None,
            arm: ArmConfig::default(),
            initial_alpha: [0.0; 2],
        }
    }

    /// The law's parameters in scalar type `T`.
    pub fn params<T: Real>(&self) -> Params<T, 3> {
        let mut p = Params::<T, 3>::paper(self.choice);
        let o = &self.overrides;
        // The arm's stroke and preferred extension, as §4.3 derives the limits, margins and
        // r_* from them (the paper's values unless `[arm]` is given).
        let (stroke, ext) = self.arm.stroke_and_extension();
        if self.arm != ArmConfig::default() {
            p.joint_limits.upper[1] = t(stroke);
            let lim = p.joint_limits;
            p.primary.penalty_margin = (lim.upper - lim.lower) * t::<T>(0.05);
            let q_star = SVector::<T, 3>::new(T::zero(), t(ext), T::zero());
            let margins = WeightMargins::paper(&lim, &q_star);
            if let Weight::Filtered { lambda, xi, .. } = p.secondary.weight {
                p.secondary.weight = Weight::Filtered { margins, lambda, xi };
            }
            p.secondary.preferred_pose.x = -(t::<T>(0.5) + t(0.15) + t(0.4) + t(ext));
        }
        if let Some(x) = o.target_in_effector {
            p.primary.target_in_effector = pose(x);
            p.secondary.preferred_pose.x = -(t::<T>(x[0]) + t(0.15) + t(0.4) + t(ext));
        }
        if let Some(x) = o.preferred_pose {
            p.secondary.preferred_pose = pose(x);
        }
        if let Some(g) = o.gain {
            p.primary.gain = v3(g);
        }
        if let Some(x) = o.penalty_weight {
            p.primary.penalty_weight = v3(x);
        }
        if let Some(x) = o.penalty_margin {
            p.primary.penalty_margin = v3(x);
        }
        if let Some(x) = o.regularisation_gain {
            p.primary.regularisation_gain = t(x);
        }
        if let Some(x) = o.regularisation_decay {
            p.primary.regularisation_decay = t(x);
        }
        if let Some(x) = o.filter_sigma {
            p.primary.filter_sigma = t(x);
        }
        if let Some(x) = o.filter_xi {
            p.primary.filter_xi = t(x);
        }
        // K̄ weighs the generalised inputs w: (v, ω, α̇) for the unicycle but (v, α̇₁, α̇₂) for
        // the car, whose two α̇ get the paper's α̇ weight.
        match self.platform {
            PlatformKind::Car => p.secondary.k_bar = v3(CAR_K_BAR),
            PlatformKind::Omni => p.secondary.k_bar = v3(OMNI_K_BAR),
            PlatformKind::Unicycle => {}
        }
        if let Some(k) = o.k_bar {
            p.secondary.k_bar = Vector3::from(v3::<T>(k));
        }
        if let Some(d) = o.d {
            p.secondary.d = Vector3::from(v3::<T>(d));
        }
        if let Some(x) = o.mu {
            p.secondary.mu = t(x);
        }
        if let (Some(nu), Precompensation::Full40 { .. }) = (o.nu, p.secondary.precompensation) {
            p.secondary.precompensation = Precompensation::Full40 { nu: t(nu) };
        }
        if let (Some(l), Weight::Filtered { margins, xi, .. }) = (o.lambda, p.secondary.weight) {
            p.secondary.weight = Weight::Filtered { margins, lambda: t(l), xi };
        }
        if let Some(g) = o.gamma_1 {
            p.secondary.gamma_1 = t(g);
        }
        if let Some(g) = o.gamma_2 {
            p.secondary.gamma_2 = t(g);
        }
        if let Some(x) = o.rest_sigma {
            p.secondary.rest_sigma = Vector3::from(v3::<T>(x));
        }
        if let Some(x) = o.rest_xi {
            p.secondary.rest_xi = t(x);
        }
        if let Some(b) = o.psi_rate_in_drift {
            p.secondary.psi_rate_in_drift = b;
        }
        if let Some(r) = o.rest_filter {
            p.secondary.rest_filter = r.into();
        }
        if let Some(x) = o.max_time_step {
            p.max_time_step = t(x);
        }
        if let Some(x) = o.joint_step_fraction {
            p.joint_step_fraction = t(x);
        }
        if let Some(x) = o.joint_velocity_limits {
            p.joint_velocity_limits = v3(x);
        }
        if let Some(d) = o.discretisation {
            p.discretisation = d.into();
        }
        if let Some(m) = o.target_motion {
            p.target_motion = m.into();
        }
        if let Some(x) = o.max_delay {
            p.max_delay = t(x);
        }
        if let Some(x) = o.max_turn_per_step {
            p.max_turn_per_step = t(x);
        }
        if o.heading_rate.is_some() || o.heading_xi.is_some() {
            let rate = o.heading_rate.unwrap_or(DEFAULT_HEADING_RATE);
            let xi = o.heading_xi.unwrap_or(DEFAULT_HEADING_XI);
            p.secondary.heading_filter = Some(HeadingFilter { rate: t(rate), xi: t(xi) });
        }
        if let Some(x) = o.rest_reach {
            p.secondary.rest_reach = t(x);
        }
        if let Some(l) = self.limits {
            p.velocity_limits = l.to_limits();
        }
        if let Some(a) = &self.acceleration {
            p.acceleration_limits = a.to_limits();
        }
        p
    }

    /// Lemma 1's function in `T`.
    pub fn unicycle<T: Real>(&self) -> Unicycle<T> {
        Unicycle::new(t(self.unicycle.epsilon_1), t(self.unicycle.epsilon_2))
    }

    /// Lemma 2's function in `T`.
    pub fn car<T: Real>(&self) -> CarLike<T> {
        let c = &self.car;
        CarLike::new(t(c.epsilon), [t(c.eta_1), t(c.eta_2), t(c.eta_3)], t(c.k))
    }

    /// The paper's RPR arm in `T`.
    pub fn arm<T: Real>(&self) -> Rpr<T> {
        Rpr::paper()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct File {
        controller: ControllerConfig,
    }

    fn parse(text: &str) -> Result<ControllerConfig, String> {
        toml::from_str::<File>(text).map(|f| f.controller).map_err(|e| e.to_string())
    }

    #[test]
    fn keys_are_the_cores_field_names() {
        let c =
            parse("[controller]\ngain = [1, 2, 3]\nfilter_sigma = 7\nrest_filter = \"explicit\"").unwrap();
        let spec = ControllerSpec {
            overrides: c,
            ..ControllerSpec::paper(PlatformKind::Unicycle, PaperRun::B, Scalar::F64)
        };
        let p = spec.params::<f64>();
        assert_eq!(p.primary.gain, SVector::<f64, 3>::new(1.0, 2.0, 3.0));
        assert_eq!(p.primary.filter_sigma, 7.0);
        assert_eq!(p.secondary.rest_filter, RestFilter::Explicit);
        assert!(parse("[controller]\nG_gain = [1, 2, 3]").unwrap_err().contains("unknown field"));
        assert!(parse("[controller]\nsigma_qhat = 1").unwrap_err().contains("unknown field"));
    }

    #[test]
    fn omni_k_bar_is_the_papers_form_and_the_unicycles_is_untouched() {
        let k = |p| ControllerSpec::paper(p, PaperRun::A, Scalar::F64).params::<f64>().secondary.k_bar;
        assert_eq!(k(PlatformKind::Omni), Vector3::new(1.0, 1.0, 1.0));
        assert_eq!(k(PlatformKind::Unicycle), Params::<f64, 3>::paper(PaperRun::A).secondary.k_bar);
        assert_eq!(k(PlatformKind::Car), Vector3::from(CAR_K_BAR));
    }

    #[test]
    fn the_arms_stroke_sets_the_limit_margins_and_preferred_pose() {
        for run in [PaperRun::A, PaperRun::B] {
            let paper = ControllerSpec::paper(PlatformKind::Car, run, Scalar::F64);
            // The paper's stroke, given explicitly, changes nothing.
            let same = ControllerSpec {
                arm: ArmConfig { stroke: Some(0.7), preferred_extension: None },
                ..paper.clone()
            };
            let (a, b) = (paper.params::<f64>(), same.params::<f64>());
            assert_eq!(a.joint_limits, b.joint_limits);
            assert_eq!(a.secondary.preferred_pose, b.secondary.preferred_pose);
            assert!((a.primary.penalty_margin - b.primary.penalty_margin).amax() < 1e-15);
            let longer =
                ControllerSpec { arm: ArmConfig { stroke: Some(1.4), preferred_extension: None }, ..paper };
            let p = longer.params::<f64>();
            assert_eq!(p.joint_limits.upper[1], 1.4);
            assert!((p.primary.penalty_margin[1] - 0.07).abs() < 1e-15);
            assert!((p.secondary.preferred_pose.x + (0.5 + 0.15 + 0.4 + 0.9)).abs() < 1e-12);
            p.validate().unwrap();
        }
        let bad = ArmConfig { stroke: Some(0.5), preferred_extension: Some(0.6) };
        assert_eq!(bad.validate().unwrap_err().param, "arm.preferred_extension");
        assert_eq!(
            ArmConfig { stroke: Some(-1.0), preferred_extension: None }.validate().unwrap_err().param,
            "arm.stroke"
        );
    }

    #[test]
    fn arrays_of_the_wrong_length_are_refused() {
        let e = parse("[controller]\ngain = [1, 2, 3, 4]").unwrap_err();
        assert!(e.contains("exactly 3 numbers"), "{e}");
        let e = parse("[controller]\nk_bar = [1, 2]").unwrap_err();
        assert!(e.contains("exactly 3 numbers"), "{e}");
    }
}
