//! One recorded step: a row of `timeseries.csv`.

use companion_core::nalgebra::SVector;
use companion_core::Pose;

use crate::domain::controller::{StepReport, JOINTS};

/// The plant's true state at one step, as recorded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantSample {
    /// Time (s).
    pub t: f64,
    /// Platform pose.
    pub base: Pose<f64>,
    /// Car steering `ξ` (1/m); 0 for other platforms.
    pub steering: f64,
    /// Joints.
    pub joints: SVector<f64, JOINTS>,
    /// End-effector pose (world).
    pub end_effector: Pose<f64>,
    /// Target pose (world).
    pub target: Pose<f64>,
    /// The true tracking error `‖e_p‖`, eq. (42), from the plant's exact state (what the
    /// summary and the `ep_norm` column report: the robot's error, not the law's estimate).
    pub ep_norm: f64,
}

/// How the command of a step was obtained (HIL adds hold/stop).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommandSource {
    /// The controller's command for this step.
    Fresh,
    /// The previous command, held because this step's command missed its deadline.
    Held,
    /// The safe zero command: commands missed too many deadlines.
    Stopped,
}

/// One logged row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    /// The plant's state.
    pub plant: PlantSample,
    /// The controller's report.
    pub report: StepReport,
    /// Where the command came from.
    pub source: CommandSource,
}

impl Row {
    /// The status column: `ok`, `rejected:` and the law's reason (e.g.
    /// `rejected:JointAtLimit(1)`), `held` or `stopped`.
    pub fn status(&self) -> String {
        let mut s = String::new();
        self.write_status(&mut s);
        s
    }

    /// Appends the status column to `out`.
    pub fn write_status(&self, out: &mut String) {
        use std::fmt::Write as _;
        match (self.source, self.report.error) {
            (CommandSource::Held, _) => out.push_str("held"),
            (CommandSource::Stopped, _) => out.push_str("stopped"),
            (CommandSource::Fresh, None) => out.push_str("ok"),
            (CommandSource::Fresh, Some(e)) => {
                let _ = write!(out, "rejected:{e:?}");
            }
        }
    }
}
