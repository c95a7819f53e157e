//! The simulated robot every loop drives, whatever its arm: a plant ([`Simulated`]: the
//! paper's planar arm, or a spatial chain) and `r*_ed`, against which each row records the
//! true tracking error. The in-process simulation and the HIL plant's lockstep and real-time
//! loops measure it, advance it over one period (the command that was acting, then the fresh
//! one from when it arrived) and describe each period for the record with it.

use companion_core::{Command, Measurement, Rpr, Space};
use companion_plant::{AdvanceError, Plant, Simulated};

use crate::domain::controller::{StepReport, JOINTS};
use crate::domain::record::{CommandSource, PlantSample, Row, Task};
use crate::domain::scenario::Scenario;

/// The plant's state for the record, with the true tracking error for the desired pose
/// `target_in_effector` (`r*_ed`); the end effector's pose only when `logged` (its forward
/// kinematics are the costly part; a step that is not logged keeps the identity, which the
/// summary does not read).
pub fn sample<P: Simulated<N>, const N: usize>(
    plant: &P,
    target_in_effector: &<P::Space as Space<f64>>::Pose,
    logged: bool,
) -> PlantSample<P::Space, N>
where
    P::Space: Task,
{
    let x = plant.truth();
    let e_p = plant.tracking_error(target_in_effector);
    PlantSample {
        t: x.t,
        base: x.base,
        steering: x.steering,
        joints: x.joints,
        end_effector: if logged { plant.end_effector() } else { <P::Space as Task>::identity() },
        target: x.target,
        target_velocity: x.target_velocity,
        e_p,
        ep_norm: <P::Space as Task>::norm(&e_p),
    }
}

/// A simulated robot: its plant and `r*_ed`.
#[derive(Debug)]
pub struct Robot<'p, P: Simulated<N>, const N: usize> {
    /// The plant.
    pub plant: &'p mut P,
    /// `r*_ed`, for the true tracking error recorded with each row.
    pub target_in_effector: <P::Space as Space<f64>>::Pose,
}

impl<'p> Robot<'p, Plant<Rpr<f64>, JOINTS>, JOINTS> {
    /// The paper's robot of scenario `s`: its `plant` and the `r*_ed` of its law.
    pub fn of(plant: &'p mut Plant<Rpr<f64>, JOINTS>, s: &Scenario) -> Self {
        Self { plant, target_in_effector: s.controller.params::<f64>().primary.target_in_effector }
    }
}

impl<P: Simulated<N>, const N: usize> Robot<'_, P, N>
where
    P::Space: Task,
{
    /// The measurement now.
    #[inline]
    pub fn measure(&self) -> Measurement<f64, N, P::Space> {
        self.plant.measure()
    }

    /// Its time (s).
    #[inline]
    pub fn time(&self) -> f64 {
        self.plant.truth().t
    }

    /// One period of `dt` seconds: `previous` for the first `switch_at` seconds, `command`
    /// for the rest.
    ///
    /// # Errors
    /// A refused step (a non-finite command, a bad time step or switch time).
    #[inline]
    pub fn advance(
        &mut self,
        previous: &Command<f64, N>,
        command: &Command<f64, N>,
        switch_at: f64,
        dt: f64,
    ) -> Result<(), AdvanceError> {
        self.plant.try_advance_delayed(previous, command, switch_at, dt)
    }

    /// The record of the current step with `report` applied over the next period, its
    /// command from `source`; the end effector only if `logged`.
    #[inline]
    pub fn row(&self, report: &StepReport<N>, source: CommandSource, logged: bool) -> Row<P::Space, N> {
        Row { plant: sample(&*self.plant, &self.target_in_effector, logged), report: *report, source }
    }
}
