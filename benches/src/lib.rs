//! # companion-benches
//!
//! Why a crate of its own: the benchmarks need inputs that look like a real run — the
//! controller's branches (joint-limit penalty on or off, saturation, the weight Ψ between
//! 0 and 1) depend on the state — and the same inputs for the criterion benches and for
//! the instruction counts, so that a time and a count measure the same work. This library
//! makes them: it runs the paper's closed loop (plant + controller, trajectories 1 and 2)
//! once in a setup phase and keeps a few thousand `(state, measurement)` pairs spread
//! evenly over both runs. A benchmark then restores a recorded state and steps the law on
//! the recorded measurement, cycling through the pairs.
//!
//! Everything is deterministic (the plant is, and no randomness is used), so the recorded
//! inputs are the same on every run: "seeded" by construction.
//!
//! - `benches/controller_step.rs`: one [`ControlLaw::step`] per platform × scalar type and
//!   per paper variant (a)–(d);
//! - `benches/sim_parts.rs`: the other parts of a simulated step — one plant RK4 step,
//!   one CSV row, one summary update;
//! - `benches/sim_run.rs`: a whole 120 s run of trajectory 2 in process, as
//!   `companion sim` does it;
//! - `src/bin/count_steps.rs` and `callgrind.sh`: instructions per step, from callgrind
//!   (`callgrind.sh --functions CONFIG`: and where they go, function by function);
//! - `profile_run.sh`: where the instructions of a whole `companion sim` run go (controller,
//!   plant, recording, CSV thread).
//!
//! ```text
//! cargo bench -p companion-benches              measure (criterion; medians in target/criterion)
//! cargo bench -p companion-benches -- --test    run every bench once (CI: they keep compiling)
//! benches/callgrind.sh                          instructions per step, every configuration
//! benches/profile_run.sh                        instructions per step of a whole run, by part
//! ```
//!
//! Times depend on the machine and its load; instruction counts do not (they move only when
//! the code does), so decisions are better made on the counts.

use companion_core::{
    CarLike, ControlLaw, Measurement, Omnidirectional, PaperRun, Platform, PlatformKind, Real, Rpr, State,
    Unicycle,
};
use companion_plant::PaperTrajectory;
use companion_runtime::domain::controller::{
    command_f64, measurement_in, platform_name, run_name, ControllerSpec, Scalar,
};
use companion_runtime::domain::scenario::Scenario;

/// The arm's joint count (the paper's RPR arm).
pub const JOINTS: usize = 3;

/// One benchmarked controller configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Config {
    /// The platform (the car with the runtime's default `K̄` and velocity limits).
    pub platform: PlatformKind,
    /// The scalar type.
    pub scalar: Scalar,
    /// The paper's variant.
    pub choice: PaperRun,
}

const fn cfg(platform: PlatformKind, scalar: Scalar, choice: PaperRun) -> Config {
    Config { platform, scalar, choice }
}

/// Each platform × scalar type, variant (a).
pub const PLATFORM_CONFIGS: [Config; 6] = [
    cfg(PlatformKind::Unicycle, Scalar::F64, PaperRun::A),
    cfg(PlatformKind::Unicycle, Scalar::F32, PaperRun::A),
    cfg(PlatformKind::Car, Scalar::F64, PaperRun::A),
    cfg(PlatformKind::Car, Scalar::F32, PaperRun::A),
    cfg(PlatformKind::Omni, Scalar::F64, PaperRun::A),
    cfg(PlatformKind::Omni, Scalar::F32, PaperRun::A),
];

/// The paper's four variants on the unicycle in `f64`.
pub const CHOICE_CONFIGS: [Config; 4] = [
    cfg(PlatformKind::Unicycle, Scalar::F64, PaperRun::A),
    cfg(PlatformKind::Unicycle, Scalar::F64, PaperRun::B),
    cfg(PlatformKind::Unicycle, Scalar::F64, PaperRun::C),
    cfg(PlatformKind::Unicycle, Scalar::F64, PaperRun::D),
];

/// Every distinct configuration ([`PLATFORM_CONFIGS`] then the rest of [`CHOICE_CONFIGS`]).
pub fn all_configs() -> Vec<Config> {
    let mut v = PLATFORM_CONFIGS.to_vec();
    for c in CHOICE_CONFIGS {
        if !v.contains(&c) {
            v.push(c);
        }
    }
    v
}

impl Config {
    /// `unicycle-f64-a`, `car-f32-a`, …
    pub fn name(&self) -> String {
        format!("{}-{}-{}", platform_name(self.platform), self.scalar.name(), run_name(self.choice))
    }

    /// The configuration named `name` (as [`name`](Self::name) writes it).
    pub fn from_name(name: &str) -> Option<Self> {
        all_configs().into_iter().find(|c| c.name() == name)
    }

    /// The runtime's scenario for this configuration on the paper's trajectory 1 (40 s, as
    /// `companion sim --all` runs it) or 2 (120 s), at `dt = 1 ms`. The car gets the
    /// runtime's defaults: its `K̄` (`CAR_K_BAR`), `CarConfig::default()` and the realistic
    /// velocity limits.
    ///
    /// # Panics
    /// If the runtime rejects the paper's parameters (a bug).
    pub fn scenario(&self, trajectory: PaperTrajectory) -> Scenario {
        Scenario::builder(trajectory, self.choice, self.platform)
            .scalar(self.scalar)
            .build()
            .unwrap_or_else(|e| panic!("the paper's scenario {}: {e}", self.name()))
    }
}

/// A platform that can be built from the runtime's controller description.
pub trait BenchPlatform<T: Real>: Platform<T> {
    /// The platform (with its transverse function) that `spec` describes.
    fn from_spec(spec: &ControllerSpec) -> Self;
}

impl<T: Real> BenchPlatform<T> for Unicycle<T> {
    fn from_spec(spec: &ControllerSpec) -> Self {
        spec.unicycle()
    }
}

impl<T: Real> BenchPlatform<T> for CarLike<T> {
    fn from_spec(spec: &ControllerSpec) -> Self {
        spec.car()
    }
}

impl<T: Real> BenchPlatform<T> for Omnidirectional {
    fn from_spec(_: &ControllerSpec) -> Self {
        Omnidirectional
    }
}

/// The validated law of a scenario, in `T` on platform `P`, exactly as the runtime builds it.
///
/// # Panics
/// If the parameters are invalid (they are the runtime's, already validated).
pub fn law<T: Real, P: BenchPlatform<T>>(s: &Scenario) -> ControlLaw<T, P, Rpr<T>, JOINTS> {
    let spec = &s.controller;
    ControlLaw::new(spec.params(), P::from_spec(spec), spec.arm())
        .unwrap_or_else(|e| panic!("invalid parameters for {}: {e}", s.name))
}

/// The controller's input at one recorded step: the state before the step and the
/// measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample<T: Real> {
    /// The law's state before the step.
    pub state: State<T, JOINTS>,
    /// The measurement of the step.
    pub meas: Measurement<T, JOINTS>,
}

/// Recorded inputs of one configuration, with the law that consumes them.
#[derive(Clone, Debug)]
pub struct Recording<T: Real, P> {
    /// The configuration.
    pub config: Config,
    /// The law (trajectory-independent).
    pub law: ControlLaw<T, P, Rpr<T>, JOINTS>,
    /// The control period (s).
    pub dt: T,
    /// The inputs, trajectory 1's then trajectory 2's, each in time order; only steps the
    /// law accepted (a rejected step is an early return, not the law's cost).
    pub samples: Vec<Sample<T>>,
    /// How many steps of the two closed-loop runs the law rejected (safe command sent).
    pub rejected: usize,
}

/// Runs the closed loop of `config` on trajectories 1 and 2 (the runtime's plant, the law
/// in `T` on `P`, the safe command after a rejected step, as `companion sim` does) and keeps
/// up to `per_trajectory` `(state, measurement)` pairs from each, evenly spaced in time,
/// of steps the law accepted.
///
/// `P` and `T` must match `config` (see [`dispatch!`](crate::dispatch)).
///
/// # Panics
/// If the runtime cannot build the plant of the paper's scenarios (a bug).
pub fn record<T: Real, P: BenchPlatform<T>>(config: Config, per_trajectory: usize) -> Recording<T, P> {
    let mut samples = Vec::with_capacity(2 * per_trajectory);
    let mut rejected = 0;
    let mut the_law = None;
    let mut dt = T::zero();
    for trajectory in [PaperTrajectory::One, PaperTrajectory::Two] {
        let s = config.scenario(trajectory);
        let law = law::<T, P>(&s);
        dt = T::of(s.dt);
        let mut plant = companion_runtime::run::sim::build_plant(&s).expect("the paper's plant");
        let steps = s.steps();
        let stride = (steps / per_trajectory.max(1) as u64).max(1);
        let mut state = State::new();
        let mut kept = 0;
        for n in 0..=steps {
            let meas = measurement_in::<T>(&plant.measure());
            let before = state;
            let command = match law.step(&mut state, &meas, dt) {
                Ok(out) => {
                    if n % stride == 0 && kept < per_trajectory {
                        samples.push(Sample { state: before, meas });
                        kept += 1;
                    }
                    command_f64(&out.command)
                }
                Err(rej) => {
                    rejected += 1;
                    command_f64(&rej.command)
                }
            };
            if n < steps {
                plant.advance(&command, s.dt);
            }
        }
        the_law = Some(law);
    }
    Recording { config, law: the_law.expect("two trajectories"), dt, samples, rejected }
}

/// Calls the generic function `$f::<T, P>($args…)` with the scalar type `T` and platform `P`
/// of `$config` (a [`Config`] value): the one place where a run-time configuration becomes
/// compile-time types.
///
/// ```no_run
/// use companion_benches::{dispatch, record, BenchPlatform, Config, PLATFORM_CONFIGS};
/// use companion_core::Real;
///
/// fn show<T: Real, P: BenchPlatform<T>>(config: Config) {
///     let rec = record::<T, P>(config, 100);
///     println!("{}: {} samples", config.name(), rec.samples.len());
/// }
/// for config in PLATFORM_CONFIGS {
///     dispatch!(config, show(config));
/// }
/// ```
#[macro_export]
macro_rules! dispatch {
    ($config:expr, $f:ident ( $($arg:expr),* $(,)? )) => {{
        use $crate::companion_core::{CarLike, Omnidirectional, PlatformKind as __P, Unicycle};
        use $crate::companion_runtime::domain::controller::Scalar as __S;
        let __config: $crate::Config = $config;
        match (__config.platform, __config.scalar) {
            (__P::Unicycle, __S::F64) => $f::<f64, Unicycle<f64>>($($arg),*),
            (__P::Unicycle, __S::F32) => $f::<f32, Unicycle<f32>>($($arg),*),
            (__P::Car, __S::F64) => $f::<f64, CarLike<f64>>($($arg),*),
            (__P::Car, __S::F32) => $f::<f32, CarLike<f32>>($($arg),*),
            (__P::Omni, __S::F64) => $f::<f64, Omnidirectional>($($arg),*),
            (__P::Omni, __S::F32) => $f::<f32, Omnidirectional>($($arg),*),
        }
    }};
}

pub use {companion_core, companion_runtime};

/// One benchmarked step: restore the recorded state, step the law on the recorded
/// measurement. Returns the output and the advanced state, for the caller to `black_box`.
#[inline(always)]
pub fn step_sample<T: Real, P: Platform<T>>(
    law: &ControlLaw<T, P, Rpr<T>, JOINTS>,
    sample: &Sample<T>,
    dt: T,
) -> (Result<companion_core::Output<T, JOINTS>, companion_core::Rejected<T, JOINTS>>, State<T, JOINTS>) {
    let mut state = sample.state;
    let out = law.step(&mut state, &sample.meas, dt);
    (out, state)
}

/// A fresh folder under the system's temporary folder, removed by [`TempDir::drop`].
#[derive(Debug)]
pub struct TempDir(std::path::PathBuf);

impl TempDir {
    /// Creates `companion-bench-<pid>-<tag>` (emptied first if it exists).
    ///
    /// # Panics
    /// If the folder cannot be created.
    pub fn new(tag: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("companion-bench-{}-{tag}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("temporary folder");
        Self(dir)
    }

    /// The folder.
    pub fn path(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn configuration_names_are_distinct_and_parse_back() {
        let all = all_configs();
        assert_eq!(all.len(), 9);
        for c in &all {
            assert_eq!(Config::from_name(&c.name()), Some(*c));
        }
        assert_eq!(Config::from_name("unicycle-f64-e"), None);
        assert_eq!(CHOICE_CONFIGS[0].name(), "unicycle-f64-a");
        assert_eq!(PLATFORM_CONFIGS[3].name(), "car-f32-a");
    }

    #[test]
    fn the_car_gets_the_runtimes_k_bar_and_limits() {
        let s = PLATFORM_CONFIGS[2].scenario(PaperTrajectory::One);
        let p = s.controller.params::<f64>();
        assert_eq!(
            p.secondary.k_bar,
            companion_core::nalgebra::Vector3::from(companion_runtime::domain::controller::CAR_K_BAR)
        );
        assert_eq!(p.velocity_limits, companion_plant::realistic_limits());
        assert_eq!((s.dt, s.duration), (1e-3, 40.0));
        assert_eq!(PLATFORM_CONFIGS[2].scenario(PaperTrajectory::Two).duration, 120.0);
    }

    /// The recorded inputs are the same on every run (the closed loop is deterministic)
    /// and spread over both trajectories. Two 160 s closed loops: run in release builds.
    #[test]
    #[cfg_attr(debug_assertions, ignore = "slow without optimisation")]
    fn recordings_are_reproducible_and_cover_both_trajectories() {
        let a = record::<f64, Unicycle<f64>>(CHOICE_CONFIGS[0], 64);
        let b = record::<f64, Unicycle<f64>>(CHOICE_CONFIGS[0], 64);
        assert_eq!(a.samples, b.samples);
        assert_eq!(a.samples.len(), 128);
        assert_eq!(a.rejected, 0);
        assert_eq!(a.samples[0].meas.t, 0.0);
        assert!(!a.samples[0].state.initialized);
        assert!(a.samples[1].state.initialized);
        let last_t1 = a.samples[63].meas.t;
        assert!(last_t1 > 38.0 && last_t1 <= 40.0, "{last_t1}");
        assert_eq!(a.samples[64].meas.t, 0.0);
        assert!(a.samples[127].meas.t > 118.0);
        for s in &a.samples {
            let mut state = s.state;
            assert!(a.law.step(&mut state, &s.meas, a.dt).is_ok());
        }
    }
}
