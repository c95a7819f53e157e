//! One closed-loop run without files, for the commands that run thousands (`companion explore`,
//! `companion tune`): the run's [`Summary`] (the figures of `summary.json`) and the figures an
//! exploration classifies a run by, with a run that diverges stopped early.
//!
//! The loop is `sim::run_loop`'s (measure, step, advance — and the same pure delay), with
//! nothing logged: the summary reads the plant's exact state at every step.

use companion_plant::{AdvanceError, Simulated};
use serde::{Deserialize, Serialize};

use crate::domain::controller::AnyController;
use crate::domain::plant_setup::{self, PlantSetupError};
use crate::domain::record::{CommandSource, Row, Summary};
use crate::domain::scenario::{Scenario, ScenarioError};
use crate::run::sim::{sample, DelayLine};

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

impl Trial {
    /// Whether the run converged: not stopped, no step rejected, and `‖e_p‖` within the
    /// tolerance over the whole final window.
    pub fn converged(&self, judge: &Judge) -> bool {
        self.tail.diverged_at.is_none()
            && self.summary.rejected_steps == 0
            && self.tail.window_max_ep < judge.tolerance
    }
}

/// Runs scenario `s` in process, without files.
///
/// # Errors
/// A bad scenario (its plant or controller cannot be built) or a plant step refused.
pub fn run(s: &Scenario, judge: &Judge) -> Result<Trial, TrialError> {
    let mut plant = plant_setup::build(s)?;
    let mut ctrl = AnyController::new(&s.controller).map_err(ScenarioError::Param)?;
    let told = if s.delay_compensation { s.delay } else { 0.0 };
    let mut delay = (s.delay > 0.0).then(|| DelayLine::new(s.delay, s.dt));
    let star = s.controller.params::<f64>().primary.target_in_effector;
    let mut summary = crate::domain::record::recorder::summary_for(s);
    let steps = s.steps();
    let end = steps as f64 * s.dt;
    let (half, window_start) = (judge.track_after.unwrap_or(0.5 * end), end - judge.window);
    let mut tail = Tail {
        tracked_fraction: 0.0,
        settling_time_s: 0.0,
        ep_bound: 0.0,
        window_max_ep: 0.0,
        time_saturated_s: 0.0,
        diverged_at: None,
    };
    let (mut second_half, mut tracked, mut saturated) = (0u64, 0u64, 0u64);
    for n in 0..=steps {
        let meas = plant.measure();
        let report = ctrl.step(&meas, s.dt, told);
        let state = sample(&plant, &star, false);
        let ep = state.ep_norm;
        summary.add(&Row { plant: state, report, source: CommandSource::Fresh });
        let t = state.t;
        if ep.is_nan() || ep > judge.divergence {
            tail.diverged_at = Some(t);
            break;
        }
        if ep >= judge.tolerance {
            tail.settling_time_s = t;
        }
        if t >= half {
            second_half += 1;
            tracked += u64::from(ep < judge.tolerance);
            tail.ep_bound = tail.ep_bound.max(ep);
        }
        if t >= window_start {
            tail.window_max_ep = tail.window_max_ep.max(ep);
        }
        saturated += u64::from(report.saturation > 1.0 + 1e-12);
        if n < steps {
            match &mut delay {
                None => plant.try_advance(&report.command, s.dt)?,
                Some(line) => {
                    let (previous, current, within) = line.push(n, &report.command);
                    plant.try_advance_delayed(&previous, &current, within, s.dt)?;
                }
            }
        }
    }
    {
        tail.tracked_fraction = if second_half > 0 { tracked as f64 / second_half as f64 } else { 0.0 };
        tail.time_saturated_s = saturated as f64 * s.dt;
    }
    Ok(Trial { summary: summary.finish(0.0), tail })
}
