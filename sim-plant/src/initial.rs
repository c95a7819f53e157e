//! The state a simulation starts from, for either plant: the paper's planar arm's (the
//! default) or a spatial arm's, whose target is a pose in space.

use companion_core::nalgebra::SVector;
use companion_core::{Planar, Pose, Pose3, Space, Spatial};

use crate::error::{PlantError, Rule};

/// The state at `t = 0`: `N` joints, the target in `S`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InitialConditions<const N: usize, S: Space<f64> = Planar> {
    /// Platform pose `r_b` in the fixed frame (m, m, rad).
    pub base: Pose<f64>,
    /// Car-like platform: steering state `ξ = tan φ / ℓ` (1/m), 0 for straight wheels.
    /// Other platforms keep it constant (it means nothing for them).
    pub steering: f64,
    /// Joint positions `q` (rad or m).
    pub joints: SVector<f64, N>,
    /// Target pose `r_d` in the fixed frame (m, m, rad; in space, `z` up).
    pub target: S::Pose,
}

impl<const N: usize> InitialConditions<N> {
    /// Initial conditions with the target given relative to the platform: `r_d = r_b · r_bd`
    /// (poses in m, m, rad; joints in rad or m); steering straight.
    pub fn with_relative_target(base: Pose<f64>, r_bd: Pose<f64>, joints: SVector<f64, N>) -> Self {
        Self { base, steering: 0.0, joints, target: base.compose(&r_bd) }
    }
}

impl<const N: usize> InitialConditions<N, Spatial> {
    /// Initial conditions with the target in space given relative to the platform,
    /// `r_d = r_b · r_bd` (`r_b` lifted: a rotation about `z`, height 0); steering straight.
    pub fn in_space(base: Pose<f64>, r_bd: Pose3<f64>, joints: SVector<f64, N>) -> Self {
        Self { base, steering: 0.0, joints, target: Pose3::from_planar(&base).compose(&r_bd) }
    }
}

impl<const N: usize, S: Space<f64>> InitialConditions<N, S> {
    pub(crate) fn validate(&self) -> Result<(), PlantError> {
        for v in self.base.to_vector().iter() {
            PlantError::check_finite("initial.base", *v)?;
        }
        PlantError::check_finite("initial.steering", self.steering)?;
        for v in self.joints.iter() {
            PlantError::check_finite("initial.joints", *v)?;
        }
        if !S::pose_is_finite(&self.target) {
            return Err(PlantError::Invalid {
                param: "initial.target",
                rule: Rule::NonFinite,
                value: f64::NAN,
            });
        }
        Ok(())
    }
}
