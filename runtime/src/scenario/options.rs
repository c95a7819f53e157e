//! The scenario options of `companion sim` and `companion hil` as typed values
//! ([`Options`]): what the command line's scenario flags set, applied to a
//! [`ScenarioBuilder`] in one place, so that the CLI and the Python package
//! (`companion-py`) build the same scenario from the same options.

use companion_core::{PaperRun, PlatformKind};

use super::{
    ConfigFile, LimitsChoice, NoiseConfig, Scenario, ScenarioBuilder, Target, DEFAULT_MAX_OUTPUT_BYTES,
};
use crate::controller::{DiscretisationConfig, RestFilterConfig, Scalar};

/// The scenario options beyond the target, the variant and the platform (each as the flag of
/// the same name; `None` or `false`: the flag not given).
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
