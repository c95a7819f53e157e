//! A scenario: which target, which control variant, which platform, step, duration, scalar
//! type, parameters and plant imperfections — one typed value, validated when it is built, and
//! shared by `companion sim` and `companion hil` so that both run the same thing.
//!
//! ```
//! use companion_core::{PaperRun, PlatformKind};
//! use companion_plant::PaperTrajectory;
//! use companion_runtime::domain::scenario::{LimitsChoice, Scenario};
//! use companion_runtime::domain::controller::Scalar;
//!
//! // The paper's run (c) on trajectory 2 (120 s at dt = 1 ms):
//! let s = Scenario::paper(PaperTrajectory::Two, PaperRun::C, PlatformKind::Unicycle);
//! assert_eq!(s.name, "traj2-c-unicycle");
//! // The same on the car, in f32, 10 s, with realistic limits:
//! let s = Scenario::builder(PaperTrajectory::Two, PaperRun::C, PlatformKind::Car)
//!     .scalar(Scalar::F32)
//!     .duration(10.0)
//!     .limits(LimitsChoice::Realistic)
//!     .build()?;
//! assert_eq!(s.steps(), 10_000);
//! # Ok::<(), companion_runtime::domain::scenario::ScenarioError>(())
//! ```

mod config;
pub mod limits;

use std::path::PathBuf;

use companion_core::{PaperRun, ParamError, PlatformKind, RestFilter};
use companion_plant::PaperTrajectory;
use serde::{Serialize, Serializer};

pub use self::config::{
    ConfigError, ConfigFile, HomeConfig, MountConfig, NoiseConfig, PlantFileConfig, RobotConfig,
};
pub use self::limits::{LimitSource, LimitsRecord};
use crate::domain::controller::{
    platform_name, run_name, AnyController, ControllerConfig, ControllerSpec, DiscretisationConfig,
    LimitsConfig, RestFilterConfig, Scalar, JOINTS,
};

/// The target's motion.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Target {
    /// The paper's trajectory 1 or 2.
    Paper(PaperTrajectory),
    /// A TOML file of piecewise-constant velocities.
    File(PathBuf),
}

impl From<PaperTrajectory> for Target {
    fn from(t: PaperTrajectory) -> Self {
        Self::Paper(t)
    }
}

/// `1` or `2`.
pub fn trajectory_number(t: PaperTrajectory) -> u8 {
    match t {
        PaperTrajectory::One => 1,
        PaperTrajectory::Two => 2,
    }
}

impl Serialize for Target {
    /// `{"paper": 1}` or `{"file": "path"}`.
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Self::Paper(t) => s.serialize_newtype_variant("Target", 0, "paper", &trajectory_number(*t)),
            Self::File(p) => s.serialize_newtype_variant("Target", 1, "file", p),
        }
    }
}

/// A named set of velocity (and acceleration) limits for a scenario (`--limits NAME`): merged
/// with the config file's, the stricter value winning per key ([`limits`]), except
/// [`Unlimited`](Self::Unlimited).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LimitsChoice {
    /// None (the paper's runs): no velocity and no acceleration limits, the config file's
    /// dropped.
    Unlimited,
    /// A realistic robot's velocity limits (`companion_plant::realistic_limits`).
    Realistic,
    /// The TIAGo's base, velocity and acceleration, as PAL configures it
    /// ([`LimitsConfig::tiago`], `AccelerationConfig::tiago`); no joint acceleration limits.
    Tiago,
    /// These velocity limits.
    Custom(LimitsConfig),
}

/// A scenario that cannot be run: which parameter, and why.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// `dt` is not a positive number of seconds.
    #[error("dt must be a positive number of seconds, got {}", short(*.0))]
    TimeStep(f64),
    /// `dt` is longer than the law admits (`max_time_step`, at most its period bound).
    #[error(
        "dt = {dt} s is longer than the law's largest admitted period, max_time_step = {max} s \
         (at most 0.1 / the largest rate of the law's gains and filters: {bound} s here)"
    )]
    PeriodTooLong {
        /// The period asked (s).
        dt: f64,
        /// `max_time_step` (s).
        max: f64,
        /// The period bound derived from the gains (s).
        bound: f64,
    },
    /// `delay` is not in `[0, min(max_delay, 8 periods)]`.
    #[error(
        "delay must be a number of seconds in [0, {max}] (at most max_delay and 8 periods), got {delay}"
    )]
    Delay {
        /// The delay asked (s).
        delay: f64,
        /// The largest admitted (s).
        max: f64,
    },
    /// `duration` is not a positive number of seconds.
    #[error("duration must be a positive number of seconds, got {}", short(*.0))]
    Duration(f64),
    /// `duration / dt` is more than 1e9 steps.
    #[error("duration / dt = {steps:.3e} steps, more than 1e9")]
    TooManySteps {
        /// The steps asked for.
        steps: f64,
    },
    /// The run would write more than the admitted size of `timeseries.csv`.
    #[error(
        "the run would write about {} of timeseries.csv ({rows} rows of about {BYTES_PER_ROW} bytes), more than \
         the limit of {} (--max-output-mb): log fewer rows with --log-every {min_log_every} or more, \
         shorten the run, or raise the limit",
        human_bytes(*bytes),
        human_bytes(*limit)
    )]
    OutputTooLarge {
        /// Rows the run would log.
        rows: u64,
        /// Their estimated size (bytes).
        bytes: u64,
        /// The limit (bytes).
        limit: u64,
        /// The smallest `log_every` within the limit.
        min_log_every: u64,
    },
    /// `log_every` is 0.
    #[error("log_every must be at least 1")]
    LogEvery,
    /// The controller's parameters break a rule.
    #[error("invalid parameter: {0}")]
    Param(ParamError),
    /// A value of the start is not finite.
    #[error("start: {0} must be finite")]
    Start(&'static str),
    /// A per-joint array with another number of values than the arm has joints.
    #[error("{key} has {given} values; the arm has {joints} joints")]
    JointCount {
        /// The key (`acceleration_limits.joints`).
        key: &'static str,
        /// The values given.
        given: usize,
        /// The arm's joints.
        joints: usize,
    },
    /// `[controller]` keys of a spatial arm's law in a planar run.
    #[error(
        "{} set(s) a spatial arm's law (its singularity settings; --arm ur5|panda|FILE); the paper's planar \
         arm has none",
        .0.join(", ")
    )]
    SpatialKeys(Vec<&'static str>),
}

/// A start other than the target's (the paper's `r_bd(0)` and `q(0)`): the platform at the
/// origin with `θ_b = 0`, the target at `r_bd(0)` from it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Start {
    /// `r_bd(0) = (x, y, θ)`: the target seen from the platform (m, m, rad).
    pub target: [f64; 3],
    /// `q(0)` (rad, m, rad).
    pub joints: [f64; 3],
    /// The car's steering `ξ(0)` (1/m). `None`: `ξ_f(α(0))`, the paper's assumption that the
    /// steering is at the transverse function's from the start (§5, after (59)).
    pub steering: Option<f64>,
}

/// The size of a row of `timeseries.csv` the output limit assumes (bytes; measured 130–330,
/// the more the numbers change from row to row).
pub const BYTES_PER_ROW: u64 = 330;

/// The default limit on `timeseries.csv` (bytes): 1 GB (about three million rows, which the
/// plots also hold in memory).
pub const DEFAULT_MAX_OUTPUT_BYTES: u64 = 1_000_000_000;

/// `x` for a message: as written if short, else in scientific notation (`1e300`, not 301
/// digits).
pub fn short(x: f64) -> String {
    let s = format!("{x}");
    if s.len() > 12 {
        format!("{x:.3e}")
    } else {
        s
    }
}

/// `1.5 GB`, `20 MB`, `512 kB`, `300 bytes`.
pub fn human_bytes(b: u64) -> String {
    let x = b as f64;
    if b >= 1_000_000_000 {
        format!("{:.1} GB", x / 1e9)
    } else if b >= 1_000_000 {
        format!("{:.1} MB", x / 1e6)
    } else if b >= 1_000 {
        format!("{:.0} kB", x / 1e3)
    } else {
        format!("{b} bytes")
    }
}

/// A fully resolved, validated scenario.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Scenario {
    /// A short name, e.g. `traj1-a-unicycle` (used for output folders).
    pub name: String,
    /// The target.
    pub target: Target,
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
    /// A pure delay (s) between a measurement and the moment its command takes effect
    /// (simulated by the in-process simulation; 0: none).
    pub delay: f64,
    /// Whether the controller is told the delay (the law then predicts over it).
    pub delay_compensation: bool,
    /// A start of its own (`None`: the target's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start: Option<Start>,
    /// The velocity and acceleration limits that run (`controller.limits`,
    /// `controller.acceleration`), each with its source ([`limits`]); not written when there
    /// are none.
    #[serde(skip_serializing_if = "LimitsRecord::is_empty")]
    pub limits: LimitsRecord,
}

/// Builds a [`Scenario`]: the paper's parameters plus what is set, checked by
/// [`build`](Self::build).
#[derive(Clone, Debug)]
#[must_use]
pub struct ScenarioBuilder {
    target: Target,
    choice: PaperRun,
    platform: PlatformKind,
    scalar: Scalar,
    dt: f64,
    duration: Option<f64>,
    log_every: u64,
    config: ConfigFile,
    limits: Option<LimitsChoice>,
    delay: f64,
    delay_compensation: bool,
    max_output_bytes: u64,
    start: Option<Start>,
    initial_alpha: [f64; 2],
}

impl ScenarioBuilder {
    /// A start of its own instead of the target's `r_bd(0)` and `q(0)`.
    pub fn start(mut self, start: Start) -> Self {
        self.start = Some(start);
        self
    }

    /// `α(0)` (rad); default 0 (SPEC §3).
    pub fn initial_alpha(mut self, alpha: [f64; 2]) -> Self {
        self.initial_alpha = alpha;
        self
    }

    /// The largest `timeseries.csv` the run may write (bytes, estimated at [`BYTES_PER_ROW`]
    /// per row); default [`DEFAULT_MAX_OUTPUT_BYTES`]. Checked by [`build`](Self::build), not
    /// part of the scenario.
    pub fn max_output_bytes(mut self, bytes: u64) -> Self {
        self.max_output_bytes = bytes;
        self
    }

    /// A pure delay (s) from a measurement to the moment its command takes effect; default 0.
    pub fn delay(mut self, delay: f64) -> Self {
        self.delay = delay;
        self
    }

    /// For a spatial arm's run (its base scenario): the spatial law's `[controller]` keys
    /// are allowed ([`ConfigFile::with_arm_settings`] does the same).
    pub fn for_spatial_arm(mut self) -> Self {
        self.config.spatial_arm = true;
        self
    }

    /// Whether the controller is told the delay (default: yes).
    pub fn delay_compensation(mut self, on: bool) -> Self {
        self.delay_compensation = on;
        self
    }

    /// How the law becomes a held command (default: the hold-aware midpoint).
    pub fn discretisation(mut self, d: DiscretisationConfig) -> Self {
        self.config.controller.discretisation = Some(d);
        self
    }

    /// The control period and integration step (s); default 1 ms.
    pub fn dt(mut self, dt: f64) -> Self {
        self.dt = dt;
        self
    }

    /// The simulated duration (s); default: the paper's (40 s for trajectory 1, 120 s
    /// otherwise).
    pub fn duration(mut self, duration: f64) -> Self {
        self.duration = Some(duration);
        self
    }

    /// The controller's scalar type; default f64.
    pub fn scalar(mut self, scalar: Scalar) -> Self {
        self.scalar = scalar;
        self
    }

    /// Log one row of `timeseries.csv` every `n` steps; default 10.
    pub fn log_every(mut self, n: u64) -> Self {
        self.log_every = n;
        self
    }

    /// A named set of limits, merged with the config file's `[velocity_limits]` and
    /// `[acceleration_limits]` key by key, the stricter value winning
    /// ([`LimitsChoice::Unlimited`] drops them all). Default: the config file's, else realistic
    /// velocity limits for the car (unsaturated, Lemma 2's high gains can diverge within
    /// seconds, SPEC §3) and none for the other platforms. The module [`limits`] has the
    /// rules; [`Scenario::limits`] records where each limit came from.
    pub fn limits(mut self, limits: LimitsChoice) -> Self {
        self.limits = Some(limits);
        self
    }

    /// Overrides from a config file (replaces earlier overrides: call it first).
    pub fn config(mut self, config: ConfigFile) -> Self {
        self.config = config;
        self
    }

    /// The overrides so far.
    pub fn current_config(&self) -> &ConfigFile {
        &self.config
    }

    /// Overrides of the controller's parameters (replaces the config file's).
    pub fn controller(mut self, c: ControllerConfig) -> Self {
        self.config.controller = c;
        self
    }

    /// Put the `Ψ̇ (h_s1 − h_s2)` term in the pre-compensated drift.
    pub fn psi_rate_in_drift(mut self, on: bool) -> Self {
        self.config.controller.psi_rate_in_drift = Some(on);
        self
    }

    /// How the rest filter (28) is advanced.
    pub fn rest_filter(mut self, r: RestFilterConfig) -> Self {
        self.config.controller.rest_filter = Some(r);
        self
    }

    /// First-order actuator lag with time constant `tau` (s).
    pub fn actuator_lag(mut self, tau: f64) -> Self {
        self.config.plant.actuator_lag = Some(tau);
        self
    }

    /// Gaussian measurement noise.
    pub fn noise(mut self, noise: NoiseConfig) -> Self {
        self.config.plant.noise = Some(noise);
        self
    }

    /// The wheels turn `(1 + e)` times faster than commanded.
    pub fn wheel_scale_error(mut self, e: f64) -> Self {
        self.config.plant.wheel_scale_error = Some(e);
        self
    }

    /// Seed of the plant's noise generator; default 1.
    pub fn seed(mut self, seed: u64) -> Self {
        self.config.plant.seed = Some(seed);
        self
    }

    /// The scenario.
    ///
    /// # Errors
    /// A step, duration or logging interval out of range, or a controller parameter that
    /// breaks a rule (named, with the rule).
    pub fn build(self) -> Result<Scenario, ScenarioError> {
        let dt = self.dt;
        if !(dt.is_finite() && dt > 0.0) {
            return Err(ScenarioError::TimeStep(dt));
        }
        let duration = self.duration.unwrap_or(match self.target {
            Target::Paper(PaperTrajectory::One) => 40.0,
            _ => 120.0,
        });
        if !(duration.is_finite() && duration > 0.0) {
            return Err(ScenarioError::Duration(duration));
        }
        if duration / dt > 1e9 {
            return Err(ScenarioError::TooManySteps { steps: duration / dt });
        }
        if self.log_every == 0 {
            return Err(ScenarioError::LogEvery);
        }
        let steps = (duration / dt).round() as u64;
        let rows = steps / self.log_every + 2;
        let bytes = rows.saturating_mul(BYTES_PER_ROW);
        if bytes > self.max_output_bytes {
            let fit = (self.max_output_bytes / BYTES_PER_ROW).saturating_sub(2).max(1);
            return Err(ScenarioError::OutputTooLarge {
                rows,
                bytes,
                limit: self.max_output_bytes,
                min_log_every: steps.div_ceil(fit).max(1),
            });
        }
        let file = self.config;
        let spatial_arm = file.is_for_spatial_arm();
        let resolved = limits::resolve(
            self.limits,
            file.velocity_limits,
            file.acceleration_limits.as_ref(),
            self.platform,
        );
        let (limits, acceleration) = (resolved.velocity, resolved.acceleration);
        // The planar arm's joints (a spatial arm's are counted when its law is built).
        if let Some(given) = acceleration.as_ref().and_then(|a| a.joints.as_ref()).map(Vec::len) {
            if !spatial_arm && given != JOINTS {
                return Err(ScenarioError::JointCount {
                    key: "acceleration_limits.joints",
                    given,
                    joints: JOINTS,
                });
            }
        }
        let mut plant = file.plant;
        plant.seed.get_or_insert(1);
        let controller = ControllerSpec {
            platform: self.platform,
            scalar: self.scalar,
            choice: self.choice,
            overrides: file.controller,
            unicycle: file.unicycle.unwrap_or_default(),
            car: file.car.unwrap_or_default(),
            limits,
            acceleration,
            arm: file.arm.unwrap_or_default(),
            initial_alpha: self.initial_alpha,
        };
        if let Some(st) = &self.start {
            let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
            if !finite(&st.target) {
                return Err(ScenarioError::Start("the target's pose r_bd(0)"));
            }
            if !finite(&st.joints) {
                return Err(ScenarioError::Start("the joints q(0)"));
            }
            if !st.steering.is_none_or(f64::is_finite) {
                return Err(ScenarioError::Start("the steering xi(0)"));
            }
        }
        let keys = crate::domain::controller::spatial_only_keys(&controller);
        if !spatial_arm && !keys.is_empty() {
            return Err(ScenarioError::SpatialKeys(keys));
        }
        // Build once to report a bad parameter now, with its name and rule.
        AnyController::new(&controller).map_err(ScenarioError::Param)?;
        let params = controller.params::<f64>();
        if dt > params.max_time_step {
            return Err(ScenarioError::PeriodTooLong {
                dt,
                max: params.max_time_step,
                bound: params.period_bound(),
            });
        }
        let max_delay = params.max_delay.min(dt * companion_core::HISTORY as f64);
        if !(self.delay.is_finite() && self.delay >= 0.0 && self.delay <= max_delay) {
            return Err(ScenarioError::Delay { delay: self.delay, max: max_delay });
        }
        let mut s = Scenario {
            name: String::new(),
            target: self.target,
            controller,
            dt,
            duration,
            plant,
            log_every: self.log_every,
            delay: self.delay,
            delay_compensation: self.delay_compensation,
            start: self.start,
            limits: resolved.record,
        };
        s.name = s.default_name();
        Ok(s)
    }
}

impl Scenario {
    /// A builder for `choice` on `platform` tracking `target`, with the paper's parameters.
    pub fn builder(target: impl Into<Target>, choice: PaperRun, platform: PlatformKind) -> ScenarioBuilder {
        ScenarioBuilder {
            target: target.into(),
            choice,
            platform,
            scalar: Scalar::F64,
            dt: 1e-3,
            duration: None,
            log_every: 10,
            config: ConfigFile::default(),
            limits: None,
            delay: 0.0,
            delay_compensation: true,
            max_output_bytes: DEFAULT_MAX_OUTPUT_BYTES,
            start: None,
            initial_alpha: [0.0; 2],
        }
    }

    /// The paper's run `choice` on `trajectory` with `platform`, as `companion sim --all`
    /// runs it: dt = 1 ms, 40 s (trajectory 1) or 120 s (trajectory 2), f64, the runtime's
    /// defaults for the car (its `K̄`, Lemma 2's parameters, realistic limits).
    ///
    /// # Panics
    /// Never: the paper's parameters are valid (a test builds every combination).
    pub fn paper(trajectory: PaperTrajectory, choice: PaperRun, platform: PlatformKind) -> Self {
        #[allow(clippy::expect_used)]
        Self::builder(trajectory, choice, platform).build().expect("the paper's parameters are valid")
    }

    /// `traj1-a-unicycle`, `traj2-b-car-f32`, `custom-c-omni`, `…-psidot`.
    pub fn default_name(&self) -> String {
        let traj = match &self.target {
            Target::Paper(t) => format!("traj{}", trajectory_number(*t)),
            Target::File(_) => "custom".to_string(),
        };
        let c = &self.controller;
        let mut name = format!("{traj}-{}-{}", run_name(c.choice), platform_name(c.platform));
        if c.scalar == Scalar::F32 {
            name.push_str("-f32");
        }
        if c.overrides.psi_rate_in_drift == Some(true) {
            name.push_str("-psidot");
        }
        if c.overrides.rest_filter.map(RestFilter::from) == Some(RestFilter::Explicit) {
            name.push_str("-explicit");
        }
        if c.overrides.discretisation == Some(DiscretisationConfig::Sampled) {
            name.push_str("-sampled");
        }
        name
    }

    /// The delay the controller is told (s): the scenario's, or 0 without compensation.
    pub fn told_delay(&self) -> f64 {
        if self.delay_compensation {
            self.delay
        } else {
            0.0
        }
    }

    /// The number of control periods (the run logs steps `0..=steps`).
    pub fn steps(&self) -> u64 {
        (self.duration / self.dt).round() as u64
    }

    /// Whether this is one of the paper's eight runs (unicycle, trajectory 1 or 2, f64, no
    /// Ψ̇ term).
    pub fn is_paper_run(&self) -> bool {
        matches!(self.target, Target::Paper(_))
            && self.controller.platform == PlatformKind::Unicycle
            && self.controller.scalar == Scalar::F64
            && self.controller.overrides.psi_rate_in_drift != Some(true)
    }
}

/// The scenario options of `companion sim` and `companion hil` as typed values: what the
/// command line's scenario flags set beyond the target, the variant and the platform (each as
/// the flag of the same name; `None` or `false`: the flag not given), applied to a
/// [`ScenarioBuilder`] in one place, so that the CLI and the Python package (`companion-py`)
/// build the same scenario from the same options.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// The controller's scalar type (`--scalar`).
    pub scalar: Scalar,
    /// The control period and integration step (s, `--dt`).
    pub dt: f64,
    /// The simulated duration (s, `--duration`); `None`: the command's default.
    pub duration: Option<f64>,
    /// Log one row every this many steps (`--log-every`).
    pub log_every: u64,
    /// The largest admitted `timeseries.csv` (bytes, `--max-output-mb` × 10⁶).
    pub max_output_bytes: u64,
    /// Put the Ψ̇ term in the drift (`--psi-rate-in-drift`).
    pub psi_rate_in_drift: bool,
    /// Explicit Euler for the rest filter (`--explicit-rest-filter`).
    pub explicit_rest_filter: bool,
    /// `--discretisation`.
    pub discretisation: Option<DiscretisationConfig>,
    /// `--limits` (`None`: the config file's, or the platform's default).
    pub limits: Option<LimitsChoice>,
    /// First-order actuator lag (s, `--actuator-lag`).
    pub actuator_lag: Option<f64>,
    /// Gaussian measurement noise (`--noise`), unless the config file sets its own.
    pub noise: bool,
    /// Wheel scale error `E` (`--wheel-scale-error`).
    pub wheel_scale_error: Option<f64>,
    /// The plant's noise seed (`--seed`), unless the config file sets one.
    pub seed: u64,
}

impl Default for Options {
    /// The flags' defaults.
    fn default() -> Self {
        Self {
            scalar: Scalar::F64,
            dt: 1e-3,
            duration: None,
            log_every: 10,
            max_output_bytes: DEFAULT_MAX_OUTPUT_BYTES,
            psi_rate_in_drift: false,
            explicit_rest_filter: false,
            discretisation: None,
            limits: None,
            actuator_lag: None,
            noise: false,
            wheel_scale_error: None,
            seed: 1,
        }
    }
}

impl Options {
    /// The builder of `target`, `choice` on `platform` with the config `file`'s overrides and
    /// these options applied (options override the file); `default_duration` (s) if
    /// [`duration`](Self::duration) is `None`.
    pub fn builder(
        &self,
        file: ConfigFile,
        target: Target,
        choice: PaperRun,
        platform: PlatformKind,
        default_duration: f64,
    ) -> ScenarioBuilder {
        let file_has_seed = file.plant.seed.is_some();
        let file_has_noise = file.plant.noise.is_some();
        let mut b = Scenario::builder(target, choice, platform)
            .config(file)
            .scalar(self.scalar)
            .dt(self.dt)
            .duration(self.duration.unwrap_or(default_duration))
            .log_every(self.log_every)
            .max_output_bytes(self.max_output_bytes);
        if self.psi_rate_in_drift {
            b = b.psi_rate_in_drift(true);
        }
        if self.explicit_rest_filter {
            b = b.rest_filter(RestFilterConfig::Explicit);
        }
        if let Some(d) = self.discretisation {
            b = b.discretisation(d);
        }
        if let Some(l) = self.limits {
            b = b.limits(l);
        }
        if let Some(tau) = self.actuator_lag {
            b = b.actuator_lag(tau);
        }
        if self.noise && !file_has_noise {
            b = b.noise(NoiseConfig::default());
        }
        if let Some(e) = self.wheel_scale_error {
            b = b.wheel_scale_error(e);
        }
        if !file_has_seed {
            b = b.seed(self.seed);
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `[acceleration_limits]` reaches the law; `--limits tiago` adds the TIAGo's velocity and
    /// acceleration limits to the file's, the stricter value winning per key, and the file's
    /// keys the preset lacks (`alpha_rate`, the joints) kept; `--limits none` drops both; the
    /// scenario records each limit's source; per-joint arrays of another count are refused by
    /// name.
    #[test]
    fn acceleration_limits_from_the_file_and_the_tiago_preset() {
        let b = || Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle);
        let file: ConfigFile = toml::from_str(
            "[velocity_limits]
alpha_rate = 1.5
forward = 2.0
[acceleration_limits]
forward = 0.5
joints = [1.0, 2.0, 3.0]
",
        )
        .expect("TOML");
        let s = b().config(file.clone()).build().expect("valid");
        let p = s.controller.params::<f64>();
        assert_eq!(p.acceleration_limits.forward, 0.5);
        assert_eq!(p.acceleration_limits.angular, f64::INFINITY);
        assert_eq!(p.acceleration_limits.joints.as_slice(), &[1.0, 2.0, 3.0]);
        assert_eq!((p.velocity_limits.forward, p.velocity_limits.alpha_rate), (2.0, 1.5));
        let tiago = b().config(file.clone()).limits(LimitsChoice::Tiago).build().expect("valid");
        let p = tiago.controller.params::<f64>();
        let v = p.velocity_limits;
        assert_eq!((v.forward, v.angular, v.alpha_rate), (1.0, 2.09, 1.5));
        assert_eq!((p.acceleration_limits.forward, p.acceleration_limits.angular), (0.5, 2.09));
        assert_eq!(p.acceleration_limits.joints.as_slice(), &[1.0, 2.0, 3.0]);
        // scenario.json says what ran and where it came from.
        let json = serde_json::to_value(&tiago).expect("JSON");
        let applied = json["limits"]["applied"].as_array().expect("applied limits");
        let from = |key: &str| {
            let s = applied.iter().find(|s| s["key"] == key).unwrap_or_else(|| panic!("{key}: {json}"));
            (s["value"].as_f64().unwrap_or(f64::NAN), s["from"].as_str().unwrap_or("").to_string())
        };
        assert_eq!(from("velocity_limits.alpha_rate"), (1.5, "config file".into()));
        assert_eq!(from("velocity_limits.forward"), (1.0, "limits tiago".into()));
        assert_eq!(from("acceleration_limits.forward"), (0.5, "config file".into()));
        assert_eq!(from("acceleration_limits.joints[1]"), (2.0, "config file".into()));
        assert_eq!(json["controller"]["limits"]["alpha_rate"], 1.5);
        assert!(serde_json::to_value(b().build().expect("valid")).expect("JSON").get("limits").is_none());
        let none = b().config(file.clone()).limits(LimitsChoice::Unlimited).build().expect("valid");
        assert_eq!(none.limits.dropped.len(), 4, "{:?}", none.limits);
        let none = none.controller;
        assert_eq!((none.limits, none.acceleration.clone()), (None, None));
        assert_eq!(none.params::<f64>().acceleration_limits, companion_core::AccelerationLimits::unlimited());
        // Realistic velocity limits keep the file's acceleration limits.
        let r = b().config(file).limits(LimitsChoice::Realistic).build().expect("valid").controller;
        assert_eq!(r.params::<f64>().acceleration_limits.forward, 0.5);
        let two: ConfigFile = toml::from_str(
            "[acceleration_limits]
joints = [1.0, 2.0]
",
        )
        .expect("TOML");
        let e = b().config(two).build().expect_err("two values for three joints");
        assert_eq!(e.to_string(), "acceleration_limits.joints has 2 values; the arm has 3 joints");
        let bad: ConfigFile = toml::from_str(
            "[acceleration_limits]
angular = 0
",
        )
        .expect("TOML");
        let e = b().config(bad).build().expect_err("not positive");
        assert!(e.to_string().contains("acceleration_limits.angular"), "{e}");
        let unknown = toml::from_str::<ConfigFile>(
            "[acceleration_limits]
linear = 1
",
        )
        .expect_err("unknown key");
        assert!(unknown.to_string().contains("unknown field `linear`"), "{unknown}");
    }

    #[test]
    fn every_paper_scenario_is_valid_and_named() {
        for t in [PaperTrajectory::One, PaperTrajectory::Two] {
            for c in [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D] {
                for p in [PlatformKind::Unicycle, PlatformKind::Car, PlatformKind::Omni] {
                    let s = Scenario::paper(t, c, p);
                    assert_eq!(s.duration, if t == PaperTrajectory::One { 40.0 } else { 120.0 });
                    assert_eq!(s.controller.limits.is_some(), p == PlatformKind::Car);
                    assert!(s.name.starts_with(&format!("traj{}-{}-", trajectory_number(t), run_name(c))));
                }
            }
        }
    }

    #[test]
    fn bad_values_are_refused_with_the_parameters_name() {
        let b = || Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle);
        assert!(matches!(b().dt(0.0).build(), Err(ScenarioError::TimeStep(_))));
        assert!(matches!(b().dt(0.02).build(), Err(ScenarioError::PeriodTooLong { .. })));
        assert!(matches!(b().delay(-1e-3).build(), Err(ScenarioError::Delay { .. })));
        assert!(matches!(b().delay(9e-3).build(), Err(ScenarioError::Delay { .. })));
        assert!(b().delay(2e-3).build().is_ok());
        assert!(matches!(b().dt(f64::NAN).build(), Err(ScenarioError::TimeStep(_))));
        assert!(matches!(b().duration(-1.0).build(), Err(ScenarioError::Duration(_))));
        assert!(matches!(b().dt(1e-9).duration(10.0).build(), Err(ScenarioError::TooManySteps { .. })));
        // 5e8 steps, every 10th logged: 5e7 rows, about 16.5 GB.
        match b().dt(1e-8).duration(5.0).build() {
            Err(e @ ScenarioError::OutputTooLarge { .. }) => {
                let m = e.to_string();
                assert!(
                    m.contains("about 16.5 GB") && m.contains("limit of 1.0 GB") && m.contains("--log-every"),
                    "{m}"
                );
                let ScenarioError::OutputTooLarge { min_log_every, .. } = e else { unreachable!() };
                assert!(b().dt(1e-8).duration(5.0).log_every(min_log_every).build().is_ok());
                assert!(b().dt(1e-8).duration(5.0).log_every(min_log_every - 1).build().is_err());
            }
            other => panic!("{other:?}"),
        }
        assert!(b().max_output_bytes(1_000).build().is_err(), "the default run is 1.3 MB");
        assert_eq!(
            ScenarioError::Duration(-1e300).to_string(),
            "duration must be a positive number of seconds, got -1.000e300"
        );
        assert!(matches!(b().log_every(0).build(), Err(ScenarioError::LogEvery)));
        let c = ControllerConfig { mu: Some(-1.0), ..ControllerConfig::default() };
        match b().controller(c).build() {
            Err(ScenarioError::Param(e)) => assert_eq!(e.param, "mu"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn the_json_of_a_scenario_names_its_target_and_platform() {
        let s = Scenario::builder(PaperTrajectory::Two, PaperRun::B, PlatformKind::Omni)
            .scalar(Scalar::F32)
            .psi_rate_in_drift(true)
            .build()
            .unwrap();
        assert_eq!(s.name, "traj2-b-omni-f32-psidot");
        let v = serde_json::to_value(&s).unwrap();
        assert_eq!(v["target"]["paper"], 2);
        assert_eq!(v["controller"]["platform"], "omni");
        assert_eq!(v["controller"]["choice"], "b");
        assert_eq!(v["plant"]["seed"], 1);
    }
}
