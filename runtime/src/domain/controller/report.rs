//! The report of one controller step that the simulation, the HIL loops and the record share
//! ([`StepReport`]), for the paper's arm ([`JOINTS`]) or a spatial one.

use companion_core::{Command, StepError};

/// The number of joints of the paper's arm (the wire and the logs carry this many).
pub const JOINTS: usize = 3;

/// What one controller step gives the plant and the log: the command (zero when the step was
/// rejected) and the diagnostics that are logged.
///
/// `N` is the arm's joint count: the paper's arm ([`JOINTS`]) by default; a spatial arm's
/// report (from a [`SpatialStep`](super::SpatialStep)) has `N` of 6 to 8 and `‖e_p‖` of the six components.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport<const N: usize = JOINTS> {
    /// The command to apply (the safe zero command when `error` is set).
    pub command: Command<f64, N>,
    /// `‖e_p‖` (NaN when rejected).
    pub ep_norm: f64,
    /// `h_s` (NaN when rejected).
    pub h_s: f64,
    /// `Ψ` (NaN when rejected).
    pub psi: f64,
    /// The common saturation factor (NaN when rejected).
    pub saturation: f64,
    /// `α̇` (NaN when rejected).
    pub alpha_rate: [f64; 2],
    /// The joint guard's factor (≥ 1; 1: the arm law (30) applied as is; NaN when rejected
    /// or unknown).
    pub joint_scale: f64,
    /// Whether the platform's acceleration limits acted (`companion_core::acceleration`:
    /// the change of its command was divided by a factor > 1); false when rejected.
    pub platform_acceleration: bool,
    /// Whether the joints' acceleration limits acted; false when rejected.
    pub joint_acceleration: bool,
    /// Why the step was rejected, if it was.
    pub error: Option<StepError>,
}

impl<const N: usize> StepReport<N> {
    /// The zero command with no diagnostics (NaN), rejected for `error` if given.
    pub fn zero(error: Option<StepError>) -> Self {
        Self {
            command: Command::zero(),
            ep_norm: f64::NAN,
            h_s: f64::NAN,
            psi: f64::NAN,
            saturation: f64::NAN,
            alpha_rate: [f64::NAN; 2],
            joint_scale: f64::NAN,
            platform_acceleration: false,
            joint_acceleration: false,
            error,
        }
    }

    /// The report of a rejected step: the safe command and no diagnostics.
    pub fn rejected(error: StepError) -> Self {
        Self::zero(Some(error))
    }
}
