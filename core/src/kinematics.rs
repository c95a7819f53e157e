//! The arm's frames at one configuration: what the spatial task (`crate::spatial`) and the
//! reach (`crate::reach`) both read of a chain's forward kinematics — each joint's axis `zᵢ`
//! and a point `oᵢ` on it, and the end effector's pose, in the platform's frame.

use nalgebra::SMatrix;

use crate::se3::Pose3;

/// The arm's frames at one configuration, in the platform's frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpatialKinematics<T, const N: usize> {
    /// The joint axes `zᵢ` (unit columns).
    pub axes: SMatrix<T, 3, N>,
    /// A point `oᵢ` on each axis (the joint frame's origin).
    pub points: SMatrix<T, 3, N>,
    /// Which joints are revolute.
    pub revolute: [bool; N],
    /// The end effector `r_be`.
    pub effector: Pose3<T>,
}
