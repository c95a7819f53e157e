//! The scenario flags shared by `sim`, `hil`, `plant` and `control` (the command line's
//! "low-level" arguments), and the one place where they become a typed [`Scenario`].

use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, ValueEnum};
use companion_core::{PaperRun, PlatformKind};
use companion_plant::PaperTrajectory;
use companion_runtime::domain::arm::{self, ArmChoice, HomeList, SpatialArmSpec, UrdfRequest};
use companion_runtime::domain::controller::{DiscretisationConfig, Scalar};
use companion_runtime::domain::record::verdict::DEFAULT_MAX_REJECTED;
use companion_runtime::domain::record::Acceptance;
use companion_runtime::domain::scenario::{
    ConfigFile, HomeConfig, LimitsChoice, Options, RobotConfig, Scenario, ScenarioBuilder, Target,
    DEFAULT_MAX_OUTPUT_BYTES,
};
use companion_runtime::run::spatial::{SpatialScenario, SpatialTargetChoice};

/// The wheeled platform.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
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
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ChoiceArg {
    /// Ψ = 1, Choice 1 with (51).
    A,
    /// Ψ by (52)–(53), Choice 1 with (40).
    B,
    /// Ψ by (52)–(53), Choice 2 (no pre-compensation).
    C,
    /// Ψ by (52)–(53), Choice 3 (partial pre-compensation).
    D,
}

impl From<ChoiceArg> for PaperRun {
    fn from(c: ChoiceArg) -> Self {
        match c {
            ChoiceArg::A => PaperRun::A,
            ChoiceArg::B => PaperRun::B,
            ChoiceArg::C => PaperRun::C,
            ChoiceArg::D => PaperRun::D,
        }
    }
}

/// The controller's scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ScalarArg {
    /// Double precision (the reference).
    F64,
    /// Single precision (what a Cortex-M4F runs).
    F32,
}

impl From<ScalarArg> for Scalar {
    fn from(s: ScalarArg) -> Self {
        match s {
            ScalarArg::F64 => Scalar::F64,
            ScalarArg::F32 => Scalar::F32,
        }
    }
}

/// The discretisation on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum DiscretisationArg {
    /// The law at the state predicted for the middle of the hold (the default).
    Midpoint,
    /// The law at the measured state (the literal sampling; first order in the period).
    Sampled,
}

impl From<DiscretisationArg> for DiscretisationConfig {
    fn from(d: DiscretisationArg) -> Self {
        match d {
            DiscretisationArg::Midpoint => DiscretisationConfig::Midpoint,
            DiscretisationArg::Sampled => DiscretisationConfig::Sampled,
        }
    }
}

/// Velocity limits on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LimitsArg {
    /// None (the paper's runs): no velocity and no acceleration limits, the config file's
    /// dropped.
    None,
    /// A realistic robot's velocity limits (see `companion_plant::realistic_limits`).
    Realistic,
    /// The TIAGo's base as PAL configures it: 1 m/s and 1 m/s², 2.09 rad/s and 2.09 rad/s².
    Tiago,
}

/// The scenario flags shared by `sim` and `hil`.
#[derive(Args, Clone, Debug)]
pub struct ScenarioArgs {
    /// The paper's trajectory: 1 or 2.
    ///
    /// The target's motion: the paper's trajectory 1 (circle) or 2 (Table 1); with a spatial
    /// --arm, lifted with a vertical sine.
    #[arg(long, visible_alias = "traj", default_value = "1", value_name = "1|2", value_parser = clap::value_parser!(u8).range(1..=2), allow_hyphen_values = true)]
    pub trajectory: u8,
    /// Your own target: a TOML file of body velocities.
    ///
    /// A user-defined target motion: a TOML file of piecewise-constant body velocities
    /// (replaces --trajectory); planar, or with a spatial --arm 6-DOF body twists
    /// (sim-plant/examples/target3d.toml).
    #[arg(long, value_name = "FILE")]
    pub target_file: Option<PathBuf>,
    /// The paper's control variant (§4.3).
    ///
    /// The control variant of the paper's §4.3: a = Ψ≡1 + Choice 1 (51); b = Ψ filtered +
    /// Choice 1 (40); c = Ψ filtered + Choice 2; d = Ψ filtered + Choice 3.
    #[arg(long, value_enum, default_value = "a", value_name = "a|b|c|d", hide_possible_values = true)]
    pub choice: ChoiceArg,
    /// The base: unicycle, car or omni.
    ///
    /// The wheeled platform: `unicycle` (differential drive, the paper's §4), `car` (car-like,
    /// the paper's §5, Lemma 2) or `omni` (omnidirectional).
    #[arg(
        long,
        value_enum,
        default_value = "unicycle",
        value_name = "PLATFORM",
        hide_possible_values = true
    )]
    pub platform: PlatformArg,
    /// Control period and integration step, in s.
    #[arg(long, default_value_t = 0.001, value_name = "SECONDS", allow_hyphen_values = true)]
    pub dt: f64,
    /// Simulated time in s [sim: 120, hil and plant: 30].
    ///
    /// The simulated duration, in seconds [default: 120 for `sim`; 30 for `hil` and `plant`;
    /// `control` ignores it (warning): its run ends at the plant's END_OF_RUN measurement].
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true)]
    pub duration: Option<f64>,
    /// The controller's scalar type.
    ///
    /// The controller's scalar type: `f64` (the reference) or `f32` (what a Cortex-M4F runs).
    #[arg(long, value_enum, default_value = "f64", value_name = "f64|f32", hide_possible_values = true)]
    pub scalar: ScalarArg,
    /// A TOML file overriding parameters.
    ///
    /// A TOML file overriding parameters, in tables `controller`, `unicycle`, `car`,
    /// `velocity_limits`, `acceleration_limits` and `plant`; each key is the name of the field it sets in
    /// companion-core (e.g. `gain`, `filter_sigma`) or companion-plant; unknown keys are errors.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Add the Ψ̇ term to ∂h_s/∂t (the paper preset leaves it out).
    ///
    /// Put the Ψ̇ (h_s1 − h_s2) term in the pre-compensated drift ∂h_s/∂t (the paper preset
    /// leaves it out; with it runs b and d chatter).
    #[arg(long)]
    pub psi_rate_in_drift: bool,
    /// Advance the rest filter (28) by explicit Euler.
    ///
    /// Advance the rest filter (28) by explicit Euler, as a literal discretisation of the
    /// paper would; at dt = 1 ms runs b–d then chatter at the Nyquist frequency during
    /// transients. The default is linearly implicit (see companion-core's `RestFilter`).
    #[arg(long)]
    pub explicit_rest_filter: bool,
    /// midpoint (the default, 2nd order) or sampled (the literal law).
    ///
    /// How the control law becomes a command held over one period: `midpoint` evaluates it
    /// at the state predicted for the middle of the hold (second order in the period,
    /// compensates the measurement delay; the default); `sampled` at the measured state
    /// (first order: the literal sampling of the paper's continuous law). The book's chapter
    /// "Precise at real control rates" (docs/book/src/precision.md) has the figures.
    #[arg(long, value_enum, value_name = "MODE", hide_possible_values = true)]
    pub discretisation: Option<DiscretisationArg>,
    /// Limits: none, realistic or tiago (accelerations too), merged with --config's.
    ///
    /// Named platform limits, merged with the --config file's `[velocity_limits]` and
    /// `[acceleration_limits]` key by key, the stricter value winning (a key only one of them
    /// sets, such as the file's `alpha_rate`, is kept): `realistic` (a realistic robot's
    /// velocity limits, see `companion_plant::realistic_limits`); `tiago` (the TIAGo base as
    /// PAL configures it, velocities and accelerations); `none` (the paper's runs: no limit at
    /// all, the file's dropped). Velocity limits are met by one common scale factor,
    /// acceleration limits by a second one on the change of the command. scenario.json records
    /// every limit that ran and where it came from (`limits`). The book's chapter "The law"
    /// (docs/book/src/law.md) has the details.
    #[arg(long, value_enum, value_name = "NAME", hide_possible_values = true)]
    pub limits: Option<LimitsArg>,
    /// Plant: a first-order actuator lag of this time constant, in s.
    ///
    /// Plant imperfection: first-order actuator lag with this time constant, in seconds.
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true)]
    pub actuator_lag: Option<f64>,
    /// Plant: Gaussian measurement noise (σ = 1 mm, 1 mrad).
    ///
    /// Plant imperfection: Gaussian measurement noise (σ = 1 mm, 1 mrad, 0.5 mrad on joints).
    #[arg(long)]
    pub noise: bool,
    /// Plant: the wheels turn (1 + E) times as fast as commanded.
    ///
    /// Plant imperfection: the wheels turn (1 + E) times faster than commanded (E > -1; e.g.
    /// -0.05: 5 % slower).
    #[arg(long, value_name = "E", allow_hyphen_values = true)]
    pub wheel_scale_error: Option<f64>,
    /// Seed of the plant's noise generator.
    #[arg(long, default_value_t = 1, allow_hyphen_values = true)]
    pub seed: u64,
    /// One row of timeseries.csv every N steps.
    ///
    /// Log one row of timeseries.csv every N steps (the first and last steps always).
    #[arg(long, default_value_t = 10, value_name = "N", allow_hyphen_values = true)]
    pub log_every: u64,
    /// The largest timeseries.csv allowed, in MB.
    ///
    /// Refuse a run whose timeseries.csv would exceed this size, in MB (estimated at 330
    /// bytes per row; the message says the size and the --log-every that fits).
    #[arg(long, default_value_t = DEFAULT_MAX_OUTPUT_BYTES / 1_000_000, value_name = "MB", allow_hyphen_values = true)]
    pub max_output_mb: u64,
    /// Exit 6 above this fraction of rejected steps.
    ///
    /// A run in which the law rejects more than this fraction of the steps (answering them
    /// with the safe zero command) fails, with exit code 6; 0 fails on any rejection.
    #[arg(long, default_value_t = DEFAULT_MAX_REJECTED, value_name = "FRAC", allow_hyphen_values = true)]
    pub max_rejected: f64,
    /// Where a URDF arm is cut, and its home.
    #[command(flatten)]
    pub robot: RobotArgs,
}

/// The flags of a URDF arm (`--arm robot.urdf`); each may be given instead as a key of the
/// `--config` file's `[robot]` table (the flag wins).
#[derive(Args, Clone, Debug, Default)]
pub struct RobotArgs {
    /// URDF: the chain's first link, the platform's frame [default: the root]
    #[arg(long, value_name = "LINK", help_heading = "Robot from a URDF (--arm robot.urdf)")]
    pub base_link: Option<String>,
    /// URDF: the end effector's link (a refusal lists the candidates)
    #[arg(long, value_name = "LINK", help_heading = "Robot from a URDF (--arm robot.urdf)")]
    pub tip_link: Option<String>,
    /// URDF: an SRDF whose <group_state> --home-state gives the home
    #[arg(long, value_name = "FILE", help_heading = "Robot from a URDF (--arm robot.urdf)")]
    pub srdf: Option<PathBuf>,
    /// URDF: the SRDF's <group_state> to use as the home
    #[arg(long, value_name = "NAME", help_heading = "Robot from a URDF (--arm robot.urdf)")]
    pub home_state: Option<String>,
    /// URDF: the home, q1,…,qN in the chain's order or name=value,…
    ///
    /// By name, the values replace or complete those of --home-state (e.g. the TIAGo's torso
    /// beside an arm state). Strictly inside each joint's limits.
    #[arg(
        long,
        value_name = "LIST",
        allow_hyphen_values = true,
        help_heading = "Robot from a URDF (--arm robot.urdf)"
    )]
    pub home: Option<String>,
}

impl RobotArgs {
    /// Whether any flag is given.
    fn any(&self) -> bool {
        self.base_link.is_some()
            || self.tip_link.is_some()
            || self.srdf.is_some()
            || self.home_state.is_some()
            || self.home.is_some()
    }

    /// `request` with these flags over the config file's `[robot]` keys (paths in the file
    /// relative to `config_dir`).
    fn fill(
        &self,
        request: &mut UrdfRequest,
        config: Option<&RobotConfig>,
        config_dir: &std::path::Path,
    ) -> Result<()> {
        let c = config.cloned().unwrap_or_default();
        request.base_link = self.base_link.clone().or(c.base_link);
        request.tip_link = self.tip_link.clone().or(c.tip_link);
        request.srdf = self.srdf.clone().or(c.srdf.map(|p| config_dir.join(p)));
        request.home_state = self.home_state.clone().or(c.home_state);
        request.home = match (&self.home, c.home) {
            (Some(text), _) => Some(HomeList::parse(text)?),
            (None, Some(HomeConfig::Values(v))) => Some(HomeList::Values(v)),
            (None, Some(HomeConfig::Named(m))) => Some(HomeList::Named(m.into_iter().collect())),
            (None, None) => None,
        };
        if let Some(m) = c.mount {
            request.mount =
                Some(arm::frame_from_xyz_rpy(m.xyz.as_deref(), m.rpy.as_deref(), "[robot.mount]")?);
        }
        Ok(())
    }
}

impl ScenarioArgs {
    /// The target the flags name.
    pub fn target(&self) -> Target {
        match &self.target_file {
            Some(p) => Target::File(p.clone()),
            None if self.trajectory == 2 => Target::Paper(PaperTrajectory::Two),
            None => Target::Paper(PaperTrajectory::One),
        }
    }

    /// The spatial arm `--arm` names (`None` for the planar `rpr`): a preset, a TOML arm
    /// file, or a URDF cut by the robot flags and the config file's `[robot]` table.
    ///
    /// # Errors
    /// A file that cannot be read or breaks a rule, or robot flags without a URDF.
    pub fn arm_spec(&self, arm: &str) -> Result<Option<SpatialArmSpec>> {
        let mut choice = ArmChoice::parse(arm);
        let config = self.config_file()?;
        match &mut choice {
            ArmChoice::Urdf(request) => {
                let dir = self.config.as_deref().and_then(std::path::Path::parent).unwrap_or(std::path::Path::new(""));
                self.robot.fill(request, config.robot.as_ref(), dir)?;
            }
            _ if self.robot.any() => anyhow::bail!(
                "--base-link, --tip-link, --srdf, --home-state and --home read a URDF: give --arm FILE.urdf (--arm is {arm})"
            ),
            _ if config.robot.is_some() => anyhow::bail!(
                "the config file's [robot] table reads a URDF: give --arm FILE.urdf (--arm is {arm})"
            ),
            _ => {}
        }
        Ok(SpatialArmSpec::from_choice(&choice)?)
    }

    /// The `--config` file (empty without the flag).
    ///
    /// # Errors
    /// The file cannot be read or has an error.
    pub fn config_file(&self) -> Result<ConfigFile> {
        Ok(match &self.config {
            Some(path) => ConfigFile::load(path)?,
            None => ConfigFile::default(),
        })
    }

    /// The builder of `target`, `choice` on `platform` with the config `file`'s overrides and
    /// every other flag applied (flags override the file); `default_duration` if
    /// `--duration` is not given.
    pub fn builder(
        &self,
        file: ConfigFile,
        target: Target,
        choice: PaperRun,
        platform: PlatformKind,
        default_duration: f64,
    ) -> ScenarioBuilder {
        self.options().builder(file, target, choice, platform, default_duration)
    }

    /// The typed options these flags set (everything but the target, variant and platform).
    pub fn options(&self) -> Options {
        Options {
            scalar: self.scalar.into(),
            dt: self.dt,
            duration: self.duration,
            log_every: self.log_every,
            max_output_bytes: self.max_output_mb.saturating_mul(1_000_000),
            psi_rate_in_drift: self.psi_rate_in_drift,
            explicit_rest_filter: self.explicit_rest_filter,
            discretisation: self.discretisation.map(Into::into),
            limits: self.limits.map(|l| match l {
                LimitsArg::Realistic => LimitsChoice::Realistic,
                LimitsArg::Tiago => LimitsChoice::Tiago,
                LimitsArg::None => LimitsChoice::Unlimited,
            }),
            actuator_lag: self.actuator_lag,
            noise: self.noise,
            wheel_scale_error: self.wheel_scale_error,
            seed: self.seed,
        }
    }

    /// The scenario the flags describe (`default_duration` if `--duration` is not given), with
    /// `more` applied to the builder (flags of one command), and its plant built once to check
    /// the target file and the plant's parameters.
    ///
    /// # Errors
    /// A bad flag value, config or target file, with a message saying which and why.
    pub fn scenario_with(
        &self,
        default_duration: f64,
        more: impl FnOnce(ScenarioBuilder) -> ScenarioBuilder,
    ) -> Result<Scenario> {
        let file = self.config_file()?;
        let b = self.builder(file, self.target(), self.choice.into(), self.platform.into(), default_duration);
        let s = more(b).build()?;
        companion_runtime::domain::plant_setup::build(&s)?;
        Ok(s)
    }

    /// The spatial run these flags describe with `arm` (§5): the paper's trajectory
    /// (`--trajectory`) lifted, or a spatial `--target-file` of 6-DOF body twists; every
    /// other flag as for a planar run, `more` applied to the builder. The target's height is
    /// checked against the arm's reach and the plant built once, before anything runs.
    ///
    /// # Errors
    /// A bad flag value, config, arm or target file, with a message saying which and why.
    pub fn spatial_scenario(
        &self,
        arm: SpatialArmSpec,
        default_duration: f64,
        more: impl FnOnce(ScenarioBuilder) -> ScenarioBuilder,
    ) -> Result<SpatialScenario> {
        let (b, target) = self.spatial_parts(&arm, default_duration)?;
        let s = SpatialScenario::new(more(b).build()?, arm, target)?;
        companion_runtime::run::spatial::check(&s)?;
        Ok(s)
    }

    /// The parts of the spatial run these flags describe with `arm`: the builder of its planar
    /// scenario, which carries every other flag (its own target is not used) and the arm's
    /// platform settings where the config file has no table of its own, and the target
    /// (the paper's trajectory lifted, or a spatial `--target-file`).
    ///
    /// # Errors
    /// The config file cannot be read or has an error.
    pub fn spatial_parts(
        &self,
        arm: &SpatialArmSpec,
        default_duration: f64,
    ) -> Result<(ScenarioBuilder, SpatialTargetChoice)> {
        let target = match &self.target_file {
            Some(p) => SpatialTargetChoice::File(p.clone()),
            None if self.trajectory == 2 => SpatialTargetChoice::Lifted(PaperTrajectory::Two),
            None => SpatialTargetChoice::Lifted(PaperTrajectory::One),
        };
        let b = self.builder(
            self.config_file()?.with_arm_settings(arm.platform_defaults()),
            Target::Paper(PaperTrajectory::One),
            self.choice.into(),
            self.platform.into(),
            default_duration,
        );
        Ok((b, target))
    }

    /// What a run is held to (`--max-rejected`; `max_miss_fraction` for real-time runs).
    ///
    /// # Errors
    /// A fraction outside [0, 1].
    pub fn acceptance(&self, max_miss_fraction: f64) -> Result<Acceptance> {
        for (flag, x) in [("--max-rejected", self.max_rejected), ("--max-miss-fraction", max_miss_fraction)] {
            if !(0.0..=1.0).contains(&x) {
                anyhow::bail!(
                    "{flag} must be a fraction in [0, 1], got {}",
                    companion_runtime::domain::scenario::short(x)
                );
            }
        }
        Ok(Acceptance { max_rejected: self.max_rejected, max_miss_fraction })
    }
}
