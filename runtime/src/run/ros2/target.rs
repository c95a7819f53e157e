//! The law's poses from ROS 2's and back ([`NodeSpace`]), and the target the node generates
//! ([`Generator`]).
//!
//! The platform's pose is read in the plane: `(x, y)` of the position and the yaw of the
//! orientation, `ψ = atan2(2(wz + xy), 1 − 2(y² + z²))`. The target is read in the arm's space:
//! its position and orientation (the planar arm: `x`, `y` and the yaw), and its twist as its
//! *body* twist, `v` and `ω` in the target's own frame (`ṗ = R v`, `Ṙ = R [ω]×`; the planar
//! arm: `(v_x, v_y, ω_z)`).
//!
//! A target read at stamp `s` is moved to the measurement's time `t` by its twist held
//! constant, `r_d(t) = r_d(s) · exp((t − s) ξ)` (exact for a target moving at a constant body
//! twist).
//!
//! A generated target is the scenario's own ([`crate::run::sim`]'s plant of the run: the
//! paper's trajectory, lifted for a spatial arm, or a target file), seen from where the
//! platform stood when the run started: `r_d = r_b(0) · r_d^plant(t)`. The plant is advanced
//! with the zero command on a fixed grid of `h` seconds (the period, at most 1 ms) and the
//! target moved from the last grid point to `t` by its twist.

use companion_core::nalgebra::{Matrix3, Vector3, Vector6};
use companion_core::{so3, Command, Planar, Pose, Pose3, PoseSc, Space, Spatial};
use companion_plant::Simulated;

use crate::transport::ros2::msgs::{self, Quaternion};

/// A quaternion's rotation matrix, if its norm is within 10⁻³ of 1 (normalised first).
pub fn rotation(q: &Quaternion) -> Option<Matrix3<f64>> {
    let n = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
    if n.is_nan() || (n - 1.0).abs() > 1e-3 {
        return None;
    }
    let (x, y, z, w) = (q.x / n, q.y / n, q.z / n, q.w / n);
    Some(Matrix3::new(
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y - z * w),
        2.0 * (x * z + y * w),
        2.0 * (x * y + z * w),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z - x * w),
        2.0 * (x * z - y * w),
        2.0 * (y * z + x * w),
        1.0 - 2.0 * (x * x + y * y),
    ))
}

/// The yaw of a quaternion (rad), if it is a unit quaternion (as [`rotation`]).
pub fn yaw(q: &Quaternion) -> Option<f64> {
    let r = rotation(q)?;
    Some(r[(1, 0)].atan2(r[(0, 0)]))
}

/// The platform's pose in the plane from a ROS pose.
pub fn planar_pose(p: &msgs::Pose) -> Option<Pose<f64>> {
    Some(Pose::new(p.position.x, p.position.y, yaw(&p.orientation)?))
}

/// A ROS pose of a planar pose (at height 0, a rotation about `z`).
pub fn ros_planar(p: &Pose<f64>) -> msgs::Pose {
    ros_pose(&Pose3::from_planar(p))
}

/// A ROS pose of a pose in space.
pub fn ros_pose(p: &Pose3<f64>) -> msgs::Pose {
    let [x, y, z, w] = so3::to_quaternion(&p.rotation);
    let t = &p.translation;
    msgs::Pose {
        position: msgs::Vector3 { x: t[0], y: t[1], z: t[2] },
        orientation: Quaternion { x, y, z, w },
    }
}

/// The law's space as the node reads and writes it (module docs).
pub trait NodeSpace: Space<f64> {
    /// The target's pose and body twist from ROS's, if the quaternion is a unit one.
    fn target(pose: &msgs::Pose, twist: &msgs::Twist) -> Option<(Self::Pose, Self::Vector)>;
    /// `pose · exp(s ξ)`.
    fn moved(pose: &Self::Pose, twist: &Self::Vector, s: f64) -> Self::Pose;
    /// `base · pose` (a pose of the platform's start frame in the world).
    fn seen_from(base: &Pose<f64>, pose: &Self::Pose) -> Self::Pose;
    /// The pose as ROS writes it.
    fn ros(pose: &Self::Pose) -> msgs::Pose;
}

impl NodeSpace for Planar {
    fn target(pose: &msgs::Pose, twist: &msgs::Twist) -> Option<(Pose<f64>, Vector3<f64>)> {
        Some((planar_pose(pose)?, Vector3::new(twist.linear.x, twist.linear.y, twist.angular.z)))
    }

    fn moved(pose: &Pose<f64>, twist: &Vector3<f64>, s: f64) -> Pose<f64> {
        PoseSc::new(*pose).compose(&PoseSc::exp(twist, s)).pose
    }

    fn seen_from(base: &Pose<f64>, pose: &Pose<f64>) -> Pose<f64> {
        base.compose(pose)
    }

    fn ros(pose: &Pose<f64>) -> msgs::Pose {
        ros_planar(pose)
    }
}

impl NodeSpace for Spatial {
    fn target(pose: &msgs::Pose, twist: &msgs::Twist) -> Option<(Pose3<f64>, Vector6<f64>)> {
        let p = &pose.position;
        let (l, a) = (&twist.linear, &twist.angular);
        Some((
            Pose3::new(rotation(&pose.orientation)?, Vector3::new(p.x, p.y, p.z)),
            Vector6::new(l.x, l.y, l.z, a.x, a.y, a.z),
        ))
    }

    fn moved(pose: &Pose3<f64>, twist: &Vector6<f64>, s: f64) -> Pose3<f64> {
        pose.compose(&Pose3::exp(&(twist * s)))
    }

    fn seen_from(base: &Pose<f64>, pose: &Pose3<f64>) -> Pose3<f64> {
        Pose3::from_planar(base).compose(pose)
    }

    fn ros(pose: &Pose3<f64>) -> msgs::Pose {
        ros_pose(pose)
    }
}

/// A target's pose and body twist in space `S`.
pub type TargetAt<S> = (<S as Space<f64>>::Pose, <S as Space<f64>>::Vector);

/// The longest grid step of a generated target (s).
pub const MAX_GRID: f64 = 1e-3;

/// A target generated from the scenario's plant (module docs).
#[derive(Debug)]
pub struct Generator<P, const N: usize> {
    plant: P,
    h: f64,
    steps: u64,
}

impl<P: Simulated<N>, const N: usize> Generator<P, N>
where
    P::Space: NodeSpace,
{
    /// The target of `plant` (at its start), on a grid of `min(period, 1 ms)`.
    pub fn new(plant: P, period: f64) -> Self {
        Self { plant, h: period.min(MAX_GRID), steps: 0 }
    }

    /// The target's pose and twist `t` seconds into the run, seen from the platform's start
    /// `base0`.
    ///
    /// # Errors
    /// The plant refused a step (it cannot with the zero command and a finite grid).
    pub fn at(
        &mut self,
        t: f64,
        base0: &Pose<f64>,
    ) -> Result<TargetAt<P::Space>, companion_plant::AdvanceError> {
        let zero = Command::<f64, N>::zero();
        while (self.steps + 1) as f64 * self.h <= t {
            self.plant.try_advance(&zero, self.h)?;
            self.steps += 1;
        }
        let x = self.plant.truth();
        let s = t - x.t;
        let pose = <P::Space as NodeSpace>::moved(&x.target, &x.target_velocity, s.max(0.0));
        Ok((<P::Space as NodeSpace>::seen_from(base0, &pose), x.target_velocity))
    }
}

#[cfg(test)]
mod tests {
    use companion_core::nalgebra::Vector3;

    use super::*;

    #[test]
    fn a_quaternion_gives_its_rotation_and_yaw_and_back() {
        for yaw_in in [0.0, 0.3, -2.0, 3.0] {
            let p = Pose::new(1.0, -2.0, yaw_in);
            let ros = ros_planar(&p);
            let back = planar_pose(&ros).unwrap();
            assert!((back.x - 1.0).abs() < 1e-15 && (back.y + 2.0).abs() < 1e-15);
            assert!((back.theta - yaw_in).abs() < 1e-14, "{yaw_in}: {}", back.theta);
        }
        let r = so3::from_rpy(0.3, -0.2, 1.1);
        let q = ros_pose(&Pose3::new(r, Vector3::zeros())).orientation;
        assert!((rotation(&q).unwrap() - r).norm() < 1e-14);
        assert_eq!(rotation(&Quaternion { x: 0.0, y: 0.0, z: 0.0, w: 0.5 }), None, "not a unit quaternion");
        assert_eq!(yaw(&Quaternion { x: f64::NAN, y: 0.0, z: 0.0, w: 1.0 }), None);
    }

    #[test]
    fn a_target_moved_by_its_body_twist_turns_on_a_circle() {
        // v = 1 m/s forward, ω = 1 rad/s: a unit circle; after π/2 s at (1, 1), facing y.
        let start = Pose::new(0.0, 0.0, 0.0);
        let p = Planar::moved(&start, &Vector3::new(1.0, 0.0, 1.0), core::f64::consts::FRAC_PI_2);
        assert!((p.x - 1.0).abs() < 1e-12 && (p.y - 1.0).abs() < 1e-12, "{p:?}");
        let s = Spatial::moved(
            &Pose3::identity(),
            &Vector6::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0),
            core::f64::consts::FRAC_PI_2,
        );
        assert!((s.translation - Vector3::new(1.0, 1.0, 0.0)).norm() < 1e-12, "{s:?}");
    }
}
