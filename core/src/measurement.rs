//! What the controller measures each cycle.

use nalgebra::SVector;

use crate::scalar::Real;
use crate::se2::Pose;
use crate::space::{Planar, Space};

/// What the controller measures each cycle (SPEC §3): time, platform pose (and steering),
/// joint positions, target pose and target body velocity — the target in the plane
/// ([`Planar`], the default) or in space ([`Spatial`](crate::Spatial)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement<T: Real, const N: usize, S: Space<T> = Planar> {
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
    /// Target pose `r_d` in the fixed frame: `(x, y, θ)` (m, m, rad) in the plane,
    /// a [`Pose3`](crate::Pose3) in space (`z` up, the platform's plane at `z = 0`).
    pub target: S::Pose,
    /// Target body velocity `u_d`: `ṙ_d = R̄(θ_d) u_d` (m/s, m/s, rad/s) in the plane;
    /// `(v, ω)` with `Ṙ_d = R_d [ω]×`, `ṗ_d = R_d v` (m/s, rad/s) in space.
    pub target_velocity: S::Vector,
}
