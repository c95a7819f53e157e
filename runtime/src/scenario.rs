//! A scenario: which target, which control variant, which platform, step, duration, scalar
//! type, parameters and plant imperfections. Built from command-line flags and an optional
//! TOML file; shared by `companion sim` and `companion hil` so both run the same thing.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use companion_core::nalgebra::{SVector, Vector3};
use companion_core::{CarLike, PaperRun, Params, PlatformKind, Real, Rpr, Unicycle, VelocityLimits};
use serde::{Deserialize, Serialize};

/// The wheeled platform (command-line spelling).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PlatformArg {
    /// Unicycle-like (differential drive), the paper's §4.
    Unicycle,
    /// Car-like, the paper's §5 (Lemma 2).
    Car,
    /// Omnidirectional.
    Omni,
}

impl From<PlatformArg> for PlatformKind {
    fn from(p: PlatformArg) -> Self {
        match p {
            PlatformArg::Unicycle => PlatformKind::Unicycle,
            PlatformArg::Car => PlatformKind::Car,
            PlatformArg::Omni => PlatformKind::Omni,
        }
    }
}

/// The paper's control variants (a)–(d) of §4.3.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Choice {
    /// Ψ = 1, Choice 1 with (51).
    A,
    /// Ψ by (52)–(53), Choice 1 with (40).
    B,
    /// Ψ by (52)–(53), Choice 2 (no pre-compensation).
    C,
    /// Ψ by (52)–(53), Choice 3 (partial pre-compensation).
    D,
}

impl From<Choice> for PaperRun {
    fn from(c: Choice) -> Self {
        match c {
            Choice::A => PaperRun::A,
            Choice::B => PaperRun::B,
            Choice::C => PaperRun::C,
            Choice::D => PaperRun::D,
        }
    }
}

/// The controller's scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scalar {
    /// Double precision (the reference).
    F64,
    /// Single precision (what a Cortex-M4F runs).
    F32,
}

/// Velocity limits on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LimitsArg {
    /// None (the paper's runs), unless the config file sets some.
    None,
    /// A realistic robot's limits (see `companion_plant::realistic_limits`).
    Realistic,
}

/// The scenario flags shared by `sim` and `hil`.
#[derive(Args, Clone, Debug)]
pub struct ScenarioArgs {
    /// The target's motion: the paper's trajectory 1 (circle) or 2 (Table 1).
    #[arg(long, default_value = "1", value_parser = clap::value_parser!(u8).range(1..=2))]
    pub trajectory: u8,
    /// A user-defined target motion: a TOML file of piecewise-constant body velocities
    /// (replaces --trajectory).
    #[arg(long, value_name = "FILE")]
    pub target_file: Option<PathBuf>,
    /// The control variant of the paper's §4.3: a = Ψ≡1 + Choice 1 (51); b = Ψ filtered +
    /// Choice 1 (40); c = Ψ filtered + Choice 2; d = Ψ filtered + Choice 3.
    #[arg(long, value_enum, default_value = "a")]
    pub choice: Choice,
    /// The wheeled platform.
    #[arg(long, value_enum, default_value = "unicycle")]
    pub platform: PlatformArg,
    /// The control period and integration step, in seconds.
    #[arg(long, default_value_t = 0.001, value_name = "SECONDS")]
    pub dt: f64,
    /// The simulated duration, in seconds [default: 120 for `sim`; 30 for `hil`, `plant` and
    /// `control`].
    #[arg(long, value_name = "SECONDS")]
    pub duration: Option<f64>,
    /// The controller's scalar type.
    #[arg(long, value_enum, default_value = "f64")]
    pub scalar: Scalar,
    /// A TOML file overriding parameters (controller, transverse functions, limits, plant).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Put the Ψ̇ (h_s1 − h_s2) term in the pre-compensated drift ∂h_s/∂t (the paper preset
    /// leaves it out; with it runs b and d chatter).
    #[arg(long)]
    pub psi_rate_in_drift: bool,
    /// Advance the rest filter (28) by explicit Euler, as a literal discretisation of the
    /// paper would; at dt = 1 ms runs b–d then chatter at the Nyquist frequency during
    /// transients. The default is linearly implicit (see companion-core's `RestFilter`).
    #[arg(long)]
    pub explicit_rest_filter: bool,
    /// Platform velocity limits, met by one common scale factor.
    #[arg(long, value_enum)]
    pub limits: Option<LimitsArg>,
    /// Plant imperfection: first-order actuator lag with this time constant, in seconds.
    #[arg(long, value_name = "SECONDS")]
    pub actuator_lag: Option<f64>,
    /// Plant imperfection: Gaussian measurement noise (σ = 1 mm, 1 mrad, 0.5 mrad on joints).
    #[arg(long)]
    pub noise: bool,
    /// Plant imperfection: the wheels turn (1 + E) times faster than commanded.
    #[arg(long, value_name = "E")]
    pub wheel_scale_error: Option<f64>,
    /// Seed of the plant's noise generator.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Log one row of timeseries.csv every N steps (the first and last steps always).
    #[arg(long, default_value_t = 10, value_name = "N")]
    pub log_every: u64,
}

/// Overrides of the paper's §4.3 controller parameters (SI units; see companion-core).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerConfig {
    /// `X*` of `r*_ed = (X*, 0, 0)` (m).
    pub x_star: Option<f64>,
    /// Gains of `G = −diag(g)` (1/s).
    pub gain: Option<[f64; 3]>,
    /// `γ₀` of `Γ(t) = γ₀ e^{−λ_Γ t}`.
    pub regularisation_gain: Option<f64>,
    /// `λ_Γ` (1/s).
    pub regularisation_decay: Option<f64>,
    /// `K̄` diagonal of (36).
    pub k_bar: Option<[f64; 3]>,
    /// `D` diagonal of (37).
    pub d: Option<[f64; 3]>,
    /// `μ` of (37).
    pub mu: Option<f64>,
    /// `ν` of (40) (run b).
    pub nu: Option<f64>,
    /// `λ` of the Ψ filter (53) (1/s).
    pub lambda: Option<f64>,
    /// `γ` of the distances in `h_s1` and `h_s2`.
    pub gamma: Option<f64>,
    /// Include `Ψ̇ (h_s1 − h_s2)` in `∂h_s/∂t`.
    pub psi_rate_in_drift: Option<bool>,
    /// Advance the rest filter (28) by explicit Euler instead of linearly implicit Euler.
    pub explicit_rest_filter: Option<bool>,
    /// The largest accepted time step (s).
    pub max_time_step: Option<f64>,
    /// `κ`: no joint covers more than this fraction of its distance to a limit in one step.
    pub joint_step_fraction: Option<f64>,
}

/// Lemma 1's parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnicycleConfig {
    /// `ε₁` (m).
    pub epsilon_1: f64,
    /// `ε₂`.
    pub epsilon_2: f64,
}

impl Default for UnicycleConfig {
    fn default() -> Self {
        Self { epsilon_1: 0.2, epsilon_2: 0.4 }
    }
}

/// Lemma 2's parameters and the steering gain of (59).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CarConfig {
    /// `ε`.
    pub epsilon: f64,
    /// `(η₁, η₂, η₃)`, with `6 η₂ η₃ > 8 η₃ + η₁ η₂`.
    pub eta: [f64; 3],
    /// `k` (1/s).
    pub k: f64,
}

impl Default for CarConfig {
    /// The car-like defaults, chosen in DESIGN notes of the README (transverse-function
    /// shaping, SPEC §3).
    fn default() -> Self {
        Self { epsilon: 0.3, eta: [2.0, 3.0, 2.0], k: 5.0 }
    }
}

/// The car's default `K̄ = diag(k̄_v, k̄_α, k̄_α)` for `w = (v, α̇₁, α̇₂)`.
pub const CAR_K_BAR: [f64; 3] = [1.0, 10.0, 10.0];

/// Velocity limits in a config file (omitted fields: no limit).
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
    fn to_limits(self) -> VelocityLimits<f64> {
        let inf = f64::INFINITY;
        VelocityLimits {
            forward: self.forward.unwrap_or(inf),
            lateral: self.lateral.unwrap_or(inf),
            angular: self.angular.unwrap_or(inf),
            alpha_rate: self.alpha_rate.unwrap_or(inf),
            steering_rate: self.steering_rate.unwrap_or(inf),
        }
    }
}

/// Plant imperfections in a config file.
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

/// Measurement-noise standard deviations.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseConfig {
    /// On positions (m).
    pub position: f64,
    /// On angles (rad).
    pub angle: f64,
    /// On joints (rad or m).
    pub joint: f64,
}

impl Default for NoiseConfig {
    fn default() -> Self {
        Self { position: 1e-3, angle: 1e-3, joint: 5e-4 }
    }
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
    pub limits: Option<LimitsConfig>,
    /// Plant imperfections.
    #[serde(default)]
    pub plant: PlantFileConfig,
}

impl ConfigFile {
    /// Reads and checks a config file.
    ///
    /// # Errors
    /// The file cannot be read or is not valid TOML of this shape.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        toml::from_str(&text).with_context(|| format!("in config file {}", path.display()))
    }
}

/// Everything needed to build the controller (in f64 or f32).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ControllerSpec {
    /// The platform.
    pub platform: PlatformArg,
    /// The scalar type.
    pub scalar: Scalar,
    /// The paper's variant.
    pub choice: Choice,
    /// Overrides of the paper's parameters.
    pub overrides: ControllerConfig,
    /// Lemma 1's parameters.
    pub unicycle: UnicycleConfig,
    /// Lemma 2's parameters.
    pub car: CarConfig,
    /// Velocity limits (None: unlimited).
    pub limits: Option<LimitsConfig>,
}

fn t<T: Real>(x: f64) -> T {
    T::of(x)
}

fn v3<T: Real>(a: [f64; 3]) -> SVector<T, 3> {
    SVector::<T, 3>::new(t(a[0]), t(a[1]), t(a[2]))
}

impl ControllerSpec {
    /// The platform kind.
    pub fn kind(&self) -> PlatformKind {
        self.platform.into()
    }

    /// The law's parameters in scalar type `T`.
    pub fn params<T: Real>(&self) -> Params<T, 3> {
        let mut p = Params::<T, 3>::paper(self.choice.into());
        let o = &self.overrides;
        if let Some(x) = o.x_star {
            p.primary.target_in_effector.x = t(x);
            p.secondary.preferred_pose.x = -(t::<T>(x) + t(0.15) + t(0.4) + t(0.45));
        }
        if let Some(g) = o.gain {
            p.primary.gain = v3(g);
        }
        if let Some(x) = o.regularisation_gain {
            p.primary.regularisation_gain = t(x);
        }
        if let Some(x) = o.regularisation_decay {
            p.primary.regularisation_decay = t(x);
        }
        // K̄ weighs the generalised inputs w: (v, ω, α̇) for the unicycle but (v, α̇₁, α̇₂) for
        // the car, whose two α̇ get the paper's α̇ weight.
        if self.platform == PlatformArg::Car {
            p.secondary.k_bar = v3(CAR_K_BAR);
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
        if let (Some(nu), companion_core::Precompensation::Full40 { .. }) =
            (o.nu, p.secondary.precompensation)
        {
            p.secondary.precompensation = companion_core::Precompensation::Full40 { nu: t(nu) };
        }
        if let (Some(l), companion_core::Weight::Filtered { margins, xi, .. }) =
            (o.lambda, p.secondary.weight)
        {
            p.secondary.weight = companion_core::Weight::Filtered { margins, lambda: t(l), xi };
        }
        if let Some(g) = o.gamma {
            p.secondary.gamma_1 = t(g);
            p.secondary.gamma_2 = t(g);
        }
        if let Some(b) = o.psi_rate_in_drift {
            p.secondary.psi_rate_in_drift = b;
        }
        if o.explicit_rest_filter == Some(true) {
            p.secondary.rest_filter = companion_core::RestFilter::Explicit;
        }
        if let Some(x) = o.max_time_step {
            p.max_time_step = t(x);
        }
        if let Some(x) = o.joint_step_fraction {
            p.joint_step_fraction = t(x);
        }
        if let Some(l) = self.limits {
            let l = l.to_limits();
            p.velocity_limits = VelocityLimits {
                forward: t(l.forward),
                lateral: t(l.lateral),
                angular: t(l.angular),
                alpha_rate: t(l.alpha_rate),
                steering_rate: t(l.steering_rate),
            };
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
        CarLike::new(t(c.epsilon), [t(c.eta[0]), t(c.eta[1]), t(c.eta[2])], t(c.k))
    }

    /// The paper's RPR arm in `T`.
    pub fn arm<T: Real>(&self) -> Rpr<T> {
        Rpr::paper()
    }
}

/// The target's motion.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TargetSpec {
    /// The paper's trajectory 1 or 2.
    Paper(u8),
    /// A TOML file of piecewise-constant velocities.
    File(PathBuf),
}

/// A fully resolved scenario.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scenario {
    /// A short name, e.g. `traj1-a-unicycle` (used for output folders).
    pub name: String,
    /// The target.
    pub target: TargetSpec,
    /// The controller.
    pub controller: ControllerSpec,
    /// The control period and integration step (s).
    pub dt: f64,
    /// The simulated duration (s).
    pub duration: f64,
    /// Plant imperfections.
    pub plant: PlantFileConfig,
    /// Log every N steps.
    pub log_every: u64,
}

impl Scenario {
    /// Resolves command-line flags (and the config file they name) into a scenario.
    ///
    /// # Errors
    /// A bad flag value or config file, with a message saying which and why.
    pub fn from_args(a: &ScenarioArgs) -> Result<Self> {
        let file = match &a.config {
            Some(path) => ConfigFile::load(path)?,
            None => ConfigFile::default(),
        };
        if !(a.dt.is_finite() && a.dt > 0.0 && a.dt <= 0.1) {
            bail!("--dt must be a number of seconds in (0, 0.1], got {}", a.dt);
        }
        let duration = a.duration.unwrap_or(120.0);
        if !(duration.is_finite() && duration > 0.0) {
            bail!("--duration must be a positive number of seconds, got {duration}");
        }
        if duration / a.dt > 1e9 {
            bail!("--duration / --dt is more than 1e9 steps");
        }
        if a.log_every == 0 {
            bail!("--log-every must be at least 1");
        }
        let mut overrides = file.controller.clone();
        if a.psi_rate_in_drift {
            overrides.psi_rate_in_drift = Some(true);
        }
        if a.explicit_rest_filter {
            overrides.explicit_rest_filter = Some(true);
        }
        let limits = match a.limits {
            Some(LimitsArg::Realistic) => Some(realistic_limits_config()),
            Some(LimitsArg::None) => None,
            None => file.limits.or_else(|| default_limits(a.platform)),
        };
        let mut plant = file.plant;
        if let Some(tau) = a.actuator_lag {
            plant.actuator_lag = Some(tau);
        }
        if a.noise && plant.noise.is_none() {
            plant.noise = Some(NoiseConfig::default());
        }
        if let Some(e) = a.wheel_scale_error {
            plant.wheel_scale_error = Some(e);
        }
        if plant.seed.is_none() {
            plant.seed = Some(a.seed);
        }
        let target = match &a.target_file {
            Some(p) => TargetSpec::File(p.clone()),
            None => TargetSpec::Paper(a.trajectory),
        };
        let controller = ControllerSpec {
            platform: a.platform,
            scalar: a.scalar,
            choice: a.choice,
            overrides,
            unicycle: file.unicycle.unwrap_or_default(),
            car: file.car.unwrap_or_default(),
            limits,
        };
        let mut s = Self {
            name: String::new(),
            target,
            controller,
            dt: a.dt,
            duration,
            plant,
            log_every: a.log_every,
        };
        s.name = s.default_name();
        // Build once to report a bad parameter now, with its name and rule.
        crate::control::AnyController::new(&s.controller)
            .map_err(|e| anyhow::anyhow!("invalid parameter: {e}"))?;
        Ok(s)
    }

    /// `traj1-a-unicycle`, `traj2-b-car-f32`, `custom-c-omni`, `…-psidot`.
    pub fn default_name(&self) -> String {
        let traj = match &self.target {
            TargetSpec::Paper(n) => format!("traj{n}"),
            TargetSpec::File(_) => "custom".to_string(),
        };
        let c = &self.controller;
        let choice = format!("{:?}", c.choice).to_lowercase();
        let platform = format!("{:?}", c.platform).to_lowercase();
        let mut name = format!("{traj}-{choice}-{platform}");
        if c.scalar == Scalar::F32 {
            name.push_str("-f32");
        }
        if c.overrides.psi_rate_in_drift == Some(true) {
            name.push_str("-psidot");
        }
        if c.overrides.explicit_rest_filter == Some(true) {
            name.push_str("-explicit");
        }
        name
    }

    /// The number of control periods (the run logs steps `0..=steps`).
    pub fn steps(&self) -> u64 {
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let n = (self.duration / self.dt).round() as u64;
        n
    }
}

fn realistic_limits_config() -> LimitsConfig {
    let l = companion_plant::realistic_limits();
    let opt = |x: f64| if x.is_finite() { Some(x) } else { None };
    LimitsConfig {
        forward: opt(l.forward),
        lateral: opt(l.lateral),
        angular: opt(l.angular),
        alpha_rate: opt(l.alpha_rate),
        steering_rate: opt(l.steering_rate),
    }
}

/// The car-like platform runs with saturation by default (SPEC §3: unsaturated, the high
/// gains of Lemma 2's function can diverge within seconds); the others run unlimited.
fn default_limits(platform: PlatformArg) -> Option<LimitsConfig> {
    match platform {
        PlatformArg::Car => Some(realistic_limits_config()),
        PlatformArg::Unicycle | PlatformArg::Omni => None,
    }
}
