//! The state a simulation starts from.

use companion_core::nalgebra::SVector;
use companion_core::Pose;

use crate::error::PlantError;

/// The state at `t = 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InitialConditions<const N: usize> {
    /// Platform pose `r_b` in the fixed frame (m, m, rad).
    pub base: Pose<f64>,
    /// Car-like platform: steering state `ξ = tan φ / ℓ` (1/m), 0 for straight wheels.
    /// Other platforms keep it constant (it means nothing for them).
    pub steering: f64,
    /// Joint positions `q` (rad or m).
    pub joints: SVector<f64, N>,
    /// Target pose `r_d` in the fixed frame (m, m, rad).
    pub target: Pose<f64>,
}

impl<const N: usize> InitialConditions<N> {
    /// Initial conditions with the target given relative to the platform: `r_d = r_b · r_bd`
    /// (poses in m, m, rad; joints in rad or m); steering straight.
    pub fn with_relative_target(base: Pose<f64>, r_bd: Pose<f64>, joints: SVector<f64, N>) -> Self {
        Self { base, steering: 0.0, joints, target: base.compose(&r_bd) }
    }

    pub(crate) fn validate(&self) -> Result<(), PlantError> {
        let base = self.base.to_vector();
        let target = self.target.to_vector();
        for v in base.iter() {
            PlantError::check_finite("initial.base", *v)?;
        }
        PlantError::check_finite("initial.steering", self.steering)?;
        for v in self.joints.iter() {
            PlantError::check_finite("initial.joints", *v)?;
        }
        for v in target.iter() {
            PlantError::check_finite("initial.target", *v)?;
        }
        Ok(())
    }
}
