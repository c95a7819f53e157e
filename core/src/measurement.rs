//! What the controller measures each cycle.

use nalgebra::{SVector, Vector3};

use crate::se2::Pose;

/// What the controller measures each cycle (SPEC §3): time, platform pose (and steering),
/// joint positions, target pose and target body velocity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement<T, const N: usize> {
    /// Time `t` (s) at which the measurement was taken. The law's own time (in `Γ(t)`)
    /// counts from the first step; the difference of successive times gives the target's
    /// acceleration.
    pub t: T,
    /// Platform pose `r_b` in the fixed frame (m, m, rad).
    pub base: Pose<T>,
    /// Steering state `ξ = tan φ / ℓ` (1/m) of a car-like platform; ignored otherwise.
    pub steering: T,
    /// Joint positions `q` (rad or m).
    pub joints: SVector<T, N>,
    /// Target pose `r_d` in the fixed frame (m, m, rad).
    pub target: Pose<T>,
    /// Target body velocity `u_d`, `ṙ_d = R̄(θ_d) u_d` (m/s, m/s, rad/s).
    pub target_velocity: Vector3<T>,
}
