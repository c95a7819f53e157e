//! One closed-loop run without files, for the commands that run thousands (`companion explore`,
//! `companion tune`): the run's [`Summary`] (the figures of `summary.json`) and the figures an
//! exploration classifies a run by, with a run that diverges stopped early.
//!
//! The loop is `sim::run_loop`'s (measure, step, advance — and the same pure delay), with
//! nothing logged: the summary reads the plant's exact state at every step. [`run`] drives
//! the paper's arm, [`run_spatial`] a spatial one (`sim --arm`'s), through the same loop on
//! the common `Robot` into the same [`Summary`].

use companion_core::{Manipulator, Spatial, SpatialArm};
use companion_plant::{AdvanceError, Simulated};
use serde::{Deserialize, Serialize};

use crate::domain::arm::{ArmError, SpatialArmSpec};
use crate::domain::controller::{boxed_spatial_controller, AnyController, Law};
use crate::domain::plant_setup::{self, PlantSetupError};
use crate::domain::record::recorder::summary_for;
use crate::domain::record::summary::SummaryAccumulator;
use crate::domain::record::{CommandSource, Summary, Task};
use crate::domain::scenario::{Scenario, ScenarioError};
use crate::run::robot::Robot;
use crate::run::sim::{advance, DelayLine};
use crate::run::spatial::{self, SpatialError, SpatialRunError, SpatialScenario, SpatialTargetChoice};
use crate::study::knobs::{self, Knob};

/// The spatial arm and target of a study with `--arm` (`explore`, `tune`).
#[derive(Clone, Debug, PartialEq)]
pub struct SpatialSetup {
    /// The arm as given (the knobs `joint_speed` and `reach` scale it per run).
    pub arm: SpatialArmSpec,
    /// The target.
    pub target: SpatialTargetChoice,
}

impl SpatialSetup {
    /// The spatial run of the built planar scenario `s` (the platform law's settings, the
    /// knobs' among them) with the arm scaled by the arm's knobs among `values`.
    ///
    /// # Errors
    /// As [`SpatialScenario::new`].
    pub fn scenario(&self, s: Scenario, values: &[(Knob, f64)]) -> Result<SpatialScenario, SpatialError> {
        let arm = self.arm.clone().scaled(knobs::arm_scale(values));
        SpatialScenario::new(s, arm, self.target.clone())
    }
}

/// Why a trial could not run: its plant or controller cannot be built, or the plant refused a
/// step.
#[derive(Debug, thiserror::Error)]
pub enum TrialError {
    /// The scenario's plant cannot be built.
    #[error(transparent)]
    Plant(#[from] PlantSetupError),
    /// The scenario is invalid (its controller's parameters included).
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The plant refused a step.
    #[error(transparent)]
    Advance(#[from] AdvanceError),
    /// A spatial scenario's arm, law, target or plant cannot be built.
    #[error(transparent)]
    Spatial(#[from] SpatialRunError),
}

/// How a trial judges its run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Judge {
    /// `‖e_p‖` below this is "tracked" (m and rad mixed, as `e_p` is). Default 1e−3.
    pub tolerance: f64,
    /// A run has converged when `‖e_p‖ < tolerance` over the last `window` seconds (and no
    /// step was rejected). Default 5 s.
    pub window: f64,
    /// A run whose `‖e_p‖` exceeds this (or is not finite) has diverged and is stopped.
    /// Default 100.
    pub divergence: f64,
    /// The tracked fraction and the bound on `‖e_p‖` count from this time (s); default
    /// (`None`): half the run's duration.
    pub track_after: Option<f64>,
}

impl Default for Judge {
    fn default() -> Self {
        Self { tolerance: 1e-3, window: 5.0, divergence: 100.0, track_after: None }
    }
}

/// What an exploration reads from one run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Tail {
    /// The fraction of steps from `track_after` (default: the run's second half, `t ≥ T/2`)
    /// with `‖e_p‖ < tolerance` (for the usual 40 s runs: after 20 s, as in `summary.json`).
    pub tracked_fraction: f64,
    /// The last time `‖e_p‖ ≥ tolerance` (s); 0 if never.
    pub settling_time_s: f64,
    /// The largest `‖e_p‖` from `track_after` on: the observed practical-stability bound.
    pub ep_bound: f64,
    /// The largest `‖e_p‖` over the last `window` seconds.
    pub window_max_ep: f64,
    /// Time (s) during which the common saturation factor was above 1.
    pub time_saturated_s: f64,
    /// The run was stopped early because `‖e_p‖` passed the divergence bound, at this time (s).
    pub diverged_at: Option<f64>,
}

/// The outcome of one trial.
#[derive(Clone, Debug, PartialEq)]
pub struct Trial {
    /// The run's summary (as `summary.json` would have it, without the wall time).
    pub summary: Summary,
    /// The exploration's figures.
    pub tail: Tail,
}

impl Tail {
    /// Whether the run converged: not stopped, no step rejected (`rejected_steps`), and
    /// `‖e_p‖` within the tolerance over the whole final window.
    pub fn converged(&self, rejected_steps: u64, judge: &Judge) -> bool {
        self.diverged_at.is_none() && rejected_steps == 0 && self.window_max_ep < judge.tolerance
    }
}

/// The figures of [`Tail`] as a run goes, step by step.
struct TailCounter {
    tail: Tail,
    judge: Judge,
    after: f64,
    window_start: f64,
    counted: u64,
    tracked: u64,
    saturated: u64,
}

impl TailCounter {
    /// For a run of `steps` periods of `dt`.
    fn new(judge: &Judge, steps: u64, dt: f64) -> Self {
        let end = steps as f64 * dt;
        Self {
            tail: Tail {
                tracked_fraction: 0.0,
                settling_time_s: 0.0,
                ep_bound: 0.0,
                window_max_ep: 0.0,
                time_saturated_s: 0.0,
                diverged_at: None,
            },
            judge: *judge,
            after: judge.track_after.unwrap_or(0.5 * end),
            window_start: end - judge.window,
            counted: 0,
            tracked: 0,
            saturated: 0,
        }
    }

    /// Adds the step at `t` with `‖e_p‖ = ep` and the platform's saturation factor; `false`
    /// when the run has diverged (and is to stop).
    fn add(&mut self, t: f64, ep: f64, saturation: f64) -> bool {
        let (tail, judge) = (&mut self.tail, &self.judge);
        if ep.is_nan() || ep > judge.divergence {
            tail.diverged_at = Some(t);
            return false;
        }
        if ep >= judge.tolerance {
            tail.settling_time_s = t;
        }
        if t >= self.after {
            self.counted += 1;
            self.tracked += u64::from(ep < judge.tolerance);
            tail.ep_bound = tail.ep_bound.max(ep);
        }
        if t >= self.window_start {
            tail.window_max_ep = tail.window_max_ep.max(ep);
        }
        self.saturated += u64::from(saturation > 1.0 + 1e-12);
        true
    }

    fn finish(mut self, dt: f64) -> Tail {
        self.tail.tracked_fraction =
            if self.counted > 0 { self.tracked as f64 / self.counted as f64 } else { 0.0 };
        self.tail.time_saturated_s = self.saturated as f64 * dt;
        self.tail
    }
}

/// Runs scenario `s` in process, without files.
///
/// # Errors
/// A bad scenario (its plant or controller cannot be built) or a plant step refused.
pub fn run(s: &Scenario, judge: &Judge) -> Result<Trial, TrialError> {
    let mut plant = plant_setup::build(s)?;
    let ctrl = AnyController::new(&s.controller).map_err(ScenarioError::Param)?;
    let mut robot = Robot::of(&mut plant, s);
    drive(s, &mut robot, ctrl, summary_for(s), judge)
}

/// Runs the spatial scenario `s` in process, without files: `companion sim --arm`'s loop
/// (`run::spatial::run_spatial`) with nothing logged.
///
/// # Errors
/// A bad arm, law, target or plant, or a plant step refused.
pub fn run_spatial(s: &SpatialScenario, judge: &Judge) -> Result<Trial, TrialError> {
    match s.arm.joints() {
        6 => run_spatial_n::<6>(s, judge),
        7 => run_spatial_n::<7>(s, judge),
        8 => run_spatial_n::<8>(s, judge),
        n => Err(SpatialRunError::from(ArmError::JointCount { found: n }).into()),
    }
}

fn run_spatial_n<const N: usize>(s: &SpatialScenario, judge: &Judge) -> Result<Trial, TrialError>
where
    SpatialArm<f64, N>: Manipulator<f64, N, Space = Spatial>,
    SpatialArm<f32, N>: Manipulator<f32, N, Space = Spatial>,
{
    let chain = s.arm.chain::<f64, N>().map_err(SpatialRunError::from)?;
    let ctrl = boxed_spatial_controller::<N>(&s.base.controller, &s.arm).map_err(SpatialRunError::from)?;
    let star = ctrl.target_in_effector();
    let mut plant = spatial::build_plant(s, &chain, &star)?;
    let mut robot = Robot { plant: &mut plant, target_in_effector: star };
    drive(&s.base, &mut robot, ctrl, spatial::summary_for(s, &chain), judge)
}

/// The trial's loop, for either arm: `sim::run_loop`'s (measure, step, advance, with the
/// scenario's pure delay and what the controller is told of it), every row into `summary`
/// and the [`Tail`], stopped at the first step past the divergence bound.
fn drive<P: Simulated<N, Space: Task>, C: Law<N, P::Space>, const N: usize>(
    s: &Scenario,
    robot: &mut Robot<'_, P, N>,
    mut ctrl: C,
    mut summary: SummaryAccumulator,
    judge: &Judge,
) -> Result<Trial, TrialError> {
    let (steps, dt) = (s.steps(), s.dt);
    let told = s.told_delay();
    let mut delay = (s.delay > 0.0).then(|| DelayLine::<N>::new(s.delay, dt));
    let mut tail = TailCounter::new(judge, steps, dt);
    for n in 0..=steps {
        let report = ctrl.step(&robot.measure(), dt, told);
        let row = robot.row(&report, CommandSource::Fresh, false);
        summary.add(&row);
        if !tail.add(row.plant.t, row.plant.ep_norm, report.saturation) {
            break;
        }
        if n < steps {
            advance(robot, delay.as_mut(), n, &report.command, dt)?;
        }
    }
    Ok(Trial { summary: summary.finish(0.0), tail: tail.finish(dt) })
}

/// What an exploration's line reads from a run, planar or spatial (one [`Summary`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Figures {
    /// `‖e_p‖` at the last step.
    pub final_ep_norm: f64,
    /// The smallest distance of any joint to its nearer limit (rad or m).
    pub min_joint_margin: f64,
    /// The largest `|v|` commanded (m/s).
    pub max_abs_v: f64,
    /// Steps the law rejected.
    pub rejected_steps: u64,
    /// The platform's reversals (`summary.json`'s `maneuvers`).
    pub maneuvers: u64,
    /// Steps run.
    pub steps: u64,
}

impl Trial {
    /// The figures an exploration writes.
    pub fn figures(&self) -> Figures {
        let m = &self.summary;
        Figures {
            final_ep_norm: m.final_ep_norm,
            min_joint_margin: m.min_joint_margin.iter().copied().fold(f64::INFINITY, f64::min),
            max_abs_v: m.max_abs_v,
            rejected_steps: m.rejected_steps,
            maneuvers: m.maneuvers,
            steps: m.steps,
        }
    }
}

#[cfg(test)]
mod tests {
    use companion_core::{PaperRun, PlatformKind};
    use companion_plant::PaperTrajectory;

    use super::*;
    use crate::domain::arm::SpatialArmSpec;
    use crate::domain::observe::Silent;
    use crate::domain::record::verdict::Acceptance;
    use crate::run::spatial::SpatialTargetChoice;

    fn dir(tag: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("companion-trial-{}-{tag}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    /// A trial is `sim`'s run without files, for either arm, with a pure delay told to the
    /// controller or not: the same summary to the last bit (its trajectory digest).
    #[test]
    fn a_trial_is_the_simulations_run_for_either_arm_with_or_without_a_delay() {
        let base = |delay: f64, told: bool| {
            Scenario::builder(PaperTrajectory::One, PaperRun::B, PlatformKind::Unicycle)
                .duration(1.0)
                .delay(delay)
                .delay_compensation(told)
        };
        for (delay, told) in [(0.0, true), (2.5e-3, true), (2.5e-3, false)] {
            let s = base(delay, told).build().unwrap();
            let t = run(&s, &Judge::default()).unwrap();
            let d = dir("planar");
            let o = crate::run::sim::run_one_with(&s, &d, &Silent, &Acceptance::default()).unwrap();
            assert_eq!(
                t.summary.trajectory_digest, o.summary.trajectory_digest,
                "planar, delay {delay} told {told}"
            );
            assert_eq!(t.summary.steps, 1001);
            let _ = std::fs::remove_dir_all(&d);

            let b = base(delay, told).for_spatial_arm().build().unwrap();
            let target = SpatialTargetChoice::Lifted(PaperTrajectory::One);
            let sc = SpatialScenario::new(b, SpatialArmSpec::Ur5, target).unwrap();
            let t = run_spatial(&sc, &Judge::default()).unwrap();
            let d = dir("spatial");
            let (o, _) = spatial::run_spatial(&sc, &d, &Silent, 0.01, None).unwrap();
            assert_eq!(
                t.summary.trajectory_digest, o.summary.trajectory_digest,
                "UR5, delay {delay} told {told}"
            );
            let _ = std::fs::remove_dir_all(&d);
        }
    }
}
