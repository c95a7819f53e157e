//! Targets in space (§5): the paper's trajectories lifted with a vertical motion, and
//! piecewise-constant 6-DOF body velocities read from a TOML file.
//!
//! **Lifted** ([`LiftedTrajectory`]): the paper's planar motion (trajectory 1 or 2, Table 1,
//! integrated by the plant exactly as for the planar arm) with the target's frame kept
//! level (`z` up, yaw `θ_d`), at the height
//!
//! ```text
//! z_d(t) = z₀ + A sin(2π t / T)        (A = 5 cm, T = 10 s by default)
//! u_d    = (u₁, u₂, ż_d, 0, 0, ω)      (body twist: the planar (u₁, u₂, ω) of §4.3 and ż_d)
//! ```
//!
//! with `z₀` chosen by the caller — the runtime takes the height at which the arm at home
//! holds the target at `r*_ed`, so the sine stays inside the arm's reach.
//!
//! **A user's file** (`PiecewiseTrajectory<Spatial>`): the planar target file's form and
//! type ([`crate::trajectory`], [`PiecewiseTrajectory`]) with six numbers where the plane
//! has three. The target's body
//! twist `ξ = (v, ω)` (m/s, rad/s, in the target's own frame) is held over each segment,
//! so the motion is exact: `r_d(t) = r_d(t_k) exp((t − t_k) ξ_k)`. After the last segment
//! the target stops. Unknown keys are errors; every error names the key, the segment and
//! the component (and TOML's own errors the line).
//!
//! ```
//! use companion_core::Spatial;
//! use companion_plant::PiecewiseTrajectory;
//!
//! let target = PiecewiseTrajectory::<Spatial>::from_toml_str(r#"
//!     [initial]
//!     r_bd = [2.5, 1.0, 0.9, 0.0, 0.0, 0.0]   # x, y, z (m), roll, pitch, yaw (rad)
//!
//!     [[segment]]
//!     duration = 5.0                              # s
//!     velocity = [0.1, 0.0, 0.02, 0.0, 0.0, 0.1]  # v (m/s), ω (rad/s), body frame
//! "#)?;
//! assert_eq!(target.duration(), 5.0);
//! assert_eq!(target.velocity(1.0)[2], 0.02);
//! # Ok::<(), companion_plant::TrajectoryError>(())
//! ```
//!
//! A complete example is `sim-plant/examples/target3d.toml`.

use core::f64::consts::PI;

use companion_core::nalgebra::Vector3;
use companion_core::{Pose3, Spatial};

use crate::trajectory::{PaperTrajectory, PiecewiseTrajectory, Trajectory};

/// The default amplitude of the lifted trajectories' vertical sine (m).
pub const LIFT_AMPLITUDE: f64 = 0.05;
/// The default period of the lifted trajectories' vertical sine (s).
pub const LIFT_PERIOD: f64 = 10.0;

/// One of the paper's planar trajectories with a vertical sine (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LiftedTrajectory {
    /// The planar motion.
    pub planar: PaperTrajectory,
    /// `z₀`: the target's height at `t = 0` (m above the ground).
    pub height: f64,
    /// `A` (m).
    pub amplitude: f64,
    /// `T` (s), `> 0`.
    pub period: f64,
}

impl LiftedTrajectory {
    /// `planar` at `height`, with the default sine (5 cm over 10 s).
    pub fn new(planar: PaperTrajectory, height: f64) -> Self {
        Self { planar, height, amplitude: LIFT_AMPLITUDE, period: LIFT_PERIOD }
    }

    /// `z_d(t)` (m).
    pub fn z(&self, t: f64) -> f64 {
        self.height + self.amplitude * libm::sin(2.0 * PI * t / self.period)
    }

    /// `ż_d(t)` (m/s).
    pub fn z_rate(&self, t: f64) -> f64 {
        let w = 2.0 * PI / self.period;
        self.amplitude * w * libm::cos(w * t)
    }

    /// The target's initial pose seen from the platform: the paper's `r_bd(0)` in the plane,
    /// at `z₀`.
    pub fn initial_r_bd(&self) -> Pose3<f64> {
        let p = self.planar.initial_r_bd();
        let planar = Pose3::from_planar(&p);
        Pose3::new(planar.rotation, Vector3::new(p.x, p.y, self.height))
    }
}

impl PiecewiseTrajectory<Spatial> {
    /// The poses at which each segment starts, and the final one, from `r_d(0)`.
    pub fn segment_starts(&self, start: &Pose3<f64>) -> Vec<Pose3<f64>> {
        let mut poses = Vec::with_capacity(self.segments().len() + 1);
        let mut p = *start;
        poses.push(p);
        for s in self.segments() {
            p = p.compose(&Pose3::exp(&(s.velocity * s.duration)));
            poses.push(p);
        }
        poses
    }

    /// `r_d(t)` from the segment starts ([`segment_starts`](Self::segment_starts)): exact.
    pub fn pose(&self, starts: &[Pose3<f64>], t: f64) -> Pose3<f64> {
        match self.segment_at(t) {
            Some((k, t0)) => starts[k].compose(&Pose3::exp(&(self.segments()[k].velocity * (t - t0)))),
            None if t.is_nan() || t < 0.0 => starts[0],
            None => starts[starts.len() - 1],
        }
    }

    /// The lowest and highest `z` of the target over the whole motion from `r_d(0)` (m):
    /// the segments' ends and 64 points inside each.
    pub fn height_range(&self, start: &Pose3<f64>) -> (f64, f64) {
        let starts = self.segment_starts(start);
        let (mut lo, mut hi) = (start.translation[2], start.translation[2]);
        let mut t0 = 0.0;
        for (k, segment) in self.segments().iter().enumerate() {
            let end = t0 + segment.duration;
            for i in 1..=64 {
                let t = t0 + (end - t0) * f64::from(i) / 64.0;
                let z = starts[k].compose(&Pose3::exp(&(segment.velocity * (t - t0)))).translation[2];
                lo = lo.min(z);
                hi = hi.max(z);
            }
            t0 = end;
        }
        (lo, hi)
    }
}

/// The target of a spatial run. (Beside the planar [`Trajectory`], which it contains: a lifted
/// target is a planar trajectory plus a height, a file's target moves exactly in SE(3).)
#[derive(Clone, Debug, PartialEq)]
pub enum SpatialTarget {
    /// A paper trajectory lifted with a vertical sine.
    Lifted(LiftedTrajectory),
    /// Piecewise-constant body twists.
    Piecewise(PiecewiseTrajectory<Spatial>),
}

impl SpatialTarget {
    /// The target's initial pose seen from the platform: the lifted trajectory's, the
    /// file's `r_bd` if it has one, else `default` (m, rad).
    pub fn initial_r_bd(&self, default: &Pose3<f64>) -> Pose3<f64> {
        match self {
            Self::Lifted(l) => l.initial_r_bd(),
            Self::Piecewise(p) => p.initial_r_bd().unwrap_or(*default),
        }
    }

    /// How long the target moves (s): `None` for trajectory 1 (forever).
    pub fn duration(&self) -> Option<f64> {
        match self {
            Self::Lifted(l) => Trajectory::from(l.planar).duration(),
            Self::Piecewise(p) => Some(p.duration()),
        }
    }
}

#[cfg(test)]
mod tests {
    use companion_core::nalgebra::Vector6;

    use super::*;

    #[test]
    fn a_file_moves_the_target_exactly_and_stops() {
        let t = PiecewiseTrajectory::<Spatial>::from_toml_str(
            r#"
            [initial]
            r_bd = [2.0, 1.0, 0.8, 0.0, 0.0, 0.5]
            q = [0, -1.5, 1.5, -1.5, -1.5, 0]
            [[segment]]
            duration = 2
            velocity = [0.1, 0.0, 0.05, 0.0, 0.0, 0.0]
            [[segment]]
            duration = 3
            velocity = [0.0, 0.0, 0.0, 0.0, 0.0, 0.2]
            "#,
        )
        .unwrap();
        let r0 = t.initial_r_bd().unwrap();
        assert_eq!(r0.translation, Vector3::new(2.0, 1.0, 0.8));
        assert_eq!(t.initial_joints().unwrap().len(), 6);
        let starts = t.segment_starts(&r0);
        // A pure translation along the body's x (yaw 0.5) and z for 2 s.
        let p = t.pose(&starts, 1.0);
        let want = r0.translation + r0.rotation * Vector3::new(0.1, 0.0, 0.05);
        assert!((p.translation - want).norm() < 1e-14, "{p:?}");
        // Then a turn about z in place: the position stays, the yaw grows by 0.6.
        let end = t.pose(&starts, 10.0);
        assert!((end.translation - t.pose(&starts, 2.0).translation).norm() < 1e-14);
        let yaw = end.rotation[(1, 0)].atan2(end.rotation[(0, 0)]);
        assert!((yaw - 1.1).abs() < 1e-12, "{yaw}");
        assert_eq!(t.velocity(10.0), Vector6::zeros());
        assert_eq!(t.velocity(2.5)[5], 0.2);
        let (lo, hi) = t.height_range(&r0);
        assert_eq!(lo, 0.8);
        assert!((hi - 0.9).abs() < 1e-12);
    }

    #[test]
    fn bad_files_name_the_field() {
        let err = |s: &str| PiecewiseTrajectory::<Spatial>::from_toml_str(s).unwrap_err().to_string();
        let e = err("[[segment]]\nduration = 1\nvelocity = [0, 0, 0]\n");
        assert!(e.contains("segment 1: `velocity` has 3 entries: it must have 6"), "{e}");
        let e = err("[[segment]]\nduration = -1\nvelocity = [0, 0, 0, 0, 0, 0]\n");
        assert!(e.contains("segment 1: `duration`"), "{e}");
        let e = err("[initial]\nr_bd = [0, 0, 0]\n");
        assert!(e.contains("[initial]: `r_bd` has 3 entries"), "{e}");
        let e = err("[[segment]]\nduration = 1\nvelocity = [0, 0, 0, 0, 0, 0]\nspeed = 1\n");
        assert!(e.contains("unknown field `speed`") && e.contains("line 4"), "{e}");
        let e = err("[[segment]]\nduration = 1\nvelocity = [0, 0, nan, 0, 0, 0]\n");
        assert!(e.contains("segment 1: `velocity[2]`"), "{e}");
    }

    #[test]
    fn the_lift_is_a_sine_with_its_derivative() {
        let l = LiftedTrajectory::new(PaperTrajectory::One, 0.9);
        assert_eq!(l.z(0.0), 0.9);
        for t in [0.3, 2.0, 7.7] {
            let h = 1e-6;
            let fd = (l.z(t + h) - l.z(t - h)) / (2.0 * h);
            assert!((fd - l.z_rate(t)).abs() < 1e-8);
        }
        let r = l.initial_r_bd();
        assert_eq!(r.translation, Vector3::new(2.6, 1.0, 0.9));
    }
}
