//! What the plant's loops need of the simulated robot, whatever its arm: measure it, advance
//! it over one period (the command that was acting, then the fresh one from when it arrived),
//! and describe the period for the record. [`PlanarRobot`] is the paper's RPR arm (its rows
//! are the planar [`Row`]s of `companion sim`); [`SpatialRobot`] a 6- to 8-joint arm in
//! SE(3) (§5; its rows are the [`SpatialRecord`]s of `companion sim --arm`).

use companion_core::{Command, Measurement, Planar, Pose, Pose3, Rpr, Spatial};
use companion_plant::{AdvanceError, Plant, SpatialPlant};

use crate::domain::controller::{StepReport, JOINTS};
use crate::domain::record::spatial::SpatialRecord;
use crate::domain::record::{CommandSource, Row};
use crate::run::sim;
use crate::transport::wire::target::WireSpace;

/// A simulated robot the plant's loops drive: `N` joints, targets in `Space`.
pub trait Robot<const N: usize> {
    /// Where its target lives (planar or SE(3)), as the wire carries it.
    type Space: WireSpace;
    /// What the record keeps of one period.
    type Row: Copy;

    /// The measurement now.
    fn measure(&self) -> Measurement<f64, N, Self::Space>;

    /// Its time (s).
    fn time(&self) -> f64;

    /// One period of `dt` seconds: `previous` for the first `switch_at` seconds, `command`
    /// for the rest.
    ///
    /// # Errors
    /// A refused step (a non-finite command, a bad time step or switch time).
    fn advance(
        &mut self,
        previous: &Command<f64, N>,
        command: &Command<f64, N>,
        switch_at: f64,
        dt: f64,
    ) -> Result<(), AdvanceError>;

    /// The record of the current step with the report applied over the next period.
    fn row(&self, report: &StepReport<N>, source: CommandSource) -> Self::Row;
}

/// The paper's robot: a platform with the RPR arm (§4).
#[derive(Debug)]
pub struct PlanarRobot<'p> {
    /// The plant.
    pub plant: &'p mut Plant<Rpr<f64>, JOINTS>,
    /// `r*_ed`, for the true tracking error recorded with each row.
    pub target_in_effector: Pose<f64>,
}

impl Robot<JOINTS> for PlanarRobot<'_> {
    type Space = Planar;
    type Row = Row;

    #[inline]
    fn measure(&self) -> Measurement<f64, JOINTS> {
        self.plant.measure()
    }

    fn time(&self) -> f64 {
        self.plant.time()
    }

    #[inline]
    fn advance(
        &mut self,
        previous: &Command<f64, JOINTS>,
        command: &Command<f64, JOINTS>,
        switch_at: f64,
        dt: f64,
    ) -> Result<(), AdvanceError> {
        self.plant.try_advance_delayed(previous, command, switch_at, dt)
    }

    #[inline]
    fn row(&self, report: &StepReport<JOINTS>, source: CommandSource) -> Row {
        Row { plant: sim::sample(self.plant, &self.target_in_effector), report: *report, source }
    }
}

/// A platform with a spatial arm of `N` joints (§5).
#[derive(Debug)]
pub struct SpatialRobot<'p, const N: usize> {
    /// The plant.
    pub plant: &'p mut SpatialPlant<N>,
    /// `r*_ed`, for the true tracking error recorded with each row.
    pub target_in_effector: Pose3<f64>,
}

impl<const N: usize> Robot<N> for SpatialRobot<'_, N> {
    type Space = Spatial;
    type Row = SpatialRecord;

    #[inline]
    fn measure(&self) -> Measurement<f64, N, Spatial> {
        self.plant.measure()
    }

    fn time(&self) -> f64 {
        self.plant.time()
    }

    #[inline]
    fn advance(
        &mut self,
        previous: &Command<f64, N>,
        command: &Command<f64, N>,
        switch_at: f64,
        dt: f64,
    ) -> Result<(), AdvanceError> {
        self.plant.try_advance_delayed(previous, command, switch_at, dt)
    }

    #[inline]
    fn row(&self, report: &StepReport<N>, source: CommandSource) -> SpatialRecord {
        crate::run::spatial::record_of(self.plant, &self.target_in_effector, report, source, true)
    }
}
