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
//! **A user's file** ([`SpatialPiecewise`]): the planar target file's form (see
//! [`crate::trajectory`]) with six numbers where the plane has three. The target's body
//! twist `ξ = (v, ω)` (m/s, rad/s, in the target's own frame) is held over each segment,
//! so the motion is exact: `r_d(t) = r_d(t_k) exp((t − t_k) ξ_k)`. After the last segment
//! the target stops. Unknown keys are errors; every error names the key, the segment and
//! the component (and TOML's own errors the line).
//!
//! ```
//! use companion_plant::SpatialPiecewise;
//!
//! let target = SpatialPiecewise::from_toml_str(r#"
//!     [initial]
//!     r_bd = [2.5, 1.0, 0.9, 0.0, 0.0, 0.0]   # x, y, z (m), roll, pitch, yaw (rad)
//!
//!     [[segment]]
//!     duration = 5.0                              # s
//!     velocity = [0.1, 0.0, 0.02, 0.0, 0.0, 0.1]  # v (m/s), ω (rad/s), body frame
//! "#)?;
//! assert_eq!(target.duration(), 5.0);
//! assert_eq!(target.twist(1.0)[2], 0.02);
//! # Ok::<(), companion_plant::TrajectoryError>(())
//! ```
//!
//! A complete example is `sim-plant/examples/target3d.toml`.

use core::f64::consts::PI;
use std::path::Path;

use companion_core::nalgebra::{Vector3, Vector6};
use companion_core::{so3, Pose3};
use serde::Deserialize;

use crate::trajectory::{segment_ends, Location, PaperTrajectory, Trajectory, TrajectoryError};

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

/// One segment of a spatial piecewise target: a body twist held for a duration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpatialSegment {
    /// How long the twist is held (s), `> 0`.
    pub duration: f64,
    /// The target's body twist `(v, ω)` (m/s, rad/s), in its own frame.
    pub twist: Vector6<f64>,
}

/// Piecewise-constant 6-DOF body twists from `t = 0`, with optional initial conditions
/// (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct SpatialPiecewise {
    segments: Vec<SpatialSegment>,
    ends: Vec<f64>,
    initial_r_bd: Option<Pose3<f64>>,
    initial_joints: Option<Vec<f64>>,
}

impl SpatialPiecewise {
    /// A target from its segments, in order.
    ///
    /// # Errors
    /// A duration that is not finite or not `> 0`, a twist component that is not finite,
    /// or a total duration that overflows.
    pub fn new(segments: Vec<SpatialSegment>) -> Result<Self, TrajectoryError> {
        let ends = segment_ends(segments.iter().map(|s| (s.duration, s.twist.as_slice())))?;
        Ok(Self { segments, ends, initial_r_bd: None, initial_joints: None })
    }

    /// The segments, in order.
    pub fn segments(&self) -> &[SpatialSegment] {
        &self.segments
    }

    /// The total duration (s).
    pub fn duration(&self) -> f64 {
        self.ends.last().copied().unwrap_or(0.0)
    }

    /// `r_bd(0)` if the file gives it.
    pub fn initial_r_bd(&self) -> Option<Pose3<f64>> {
        self.initial_r_bd
    }

    /// `q(0)` if the file gives it (rad or m).
    pub fn initial_joints(&self) -> Option<&[f64]> {
        self.initial_joints.as_deref()
    }

    /// The segment containing `t` (closed on the left), if any, and its start time.
    fn segment_at(&self, t: f64) -> Option<(usize, f64)> {
        if t.is_nan() || t < 0.0 {
            return None;
        }
        let k = self.ends.partition_point(|&end| end <= t);
        (k < self.segments.len()).then(|| (k, if k == 0 { 0.0 } else { self.ends[k - 1] }))
    }

    /// The body twist at `t` (zero before 0 and after the last segment).
    pub fn twist(&self, t: f64) -> Vector6<f64> {
        self.segment_at(t).map_or_else(Vector6::zeros, |(k, _)| self.segments[k].twist)
    }

    /// The poses at which each segment starts, and the final one, from `r_d(0)`.
    pub fn segment_starts(&self, start: &Pose3<f64>) -> Vec<Pose3<f64>> {
        let mut poses = Vec::with_capacity(self.segments.len() + 1);
        let mut p = *start;
        poses.push(p);
        for s in &self.segments {
            p = p.compose(&Pose3::exp(&(s.twist * s.duration)));
            poses.push(p);
        }
        poses
    }

    /// `r_d(t)` from the segment starts ([`segment_starts`](Self::segment_starts)): exact.
    pub fn pose(&self, starts: &[Pose3<f64>], t: f64) -> Pose3<f64> {
        match self.segment_at(t) {
            Some((k, t0)) => starts[k].compose(&Pose3::exp(&(self.segments[k].twist * (t - t0)))),
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
        for (k, end) in self.ends.iter().enumerate() {
            for i in 1..=64 {
                let t = t0 + (end - t0) * f64::from(i) / 64.0;
                let z = starts[k].compose(&Pose3::exp(&(self.segments[k].twist * (t - t0)))).translation[2];
                lo = lo.min(z);
                hi = hi.max(z);
            }
            t0 = *end;
        }
        (lo, hi)
    }

    /// Parses a spatial target file (module docs).
    ///
    /// # Errors
    /// [`TrajectoryError::Parse`] for malformed TOML, an unknown or missing key or a value
    /// of the wrong type (the message gives the line); the other variants for a value that
    /// breaks a rule, naming the key and segment.
    pub fn from_toml_str(text: &str) -> Result<Self, TrajectoryError> {
        let file: TargetFile = toml::from_str(text).map_err(TrajectoryError::Parse)?;
        let segments = file
            .segment
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let location = Location::Segment { number: k + 1, key: "velocity", index: None };
                Ok(SpatialSegment { duration: s.duration, twist: six(&s.velocity, location)? })
            })
            .collect::<Result<_, TrajectoryError>>()?;
        let mut target = Self::new(segments)?;
        if let Some(initial) = file.initial {
            if let Some(r) = initial.r_bd {
                let v = six(&r, Location::Initial { key: "r_bd", index: None })?;
                for (i, x) in v.iter().enumerate() {
                    if !x.is_finite() {
                        let location = Location::Initial { key: "r_bd", index: Some(i) };
                        return Err(TrajectoryError::NonFinite { location, value: *x });
                    }
                }
                target.initial_r_bd =
                    Some(Pose3::new(so3::from_rpy(v[3], v[4], v[5]), Vector3::new(v[0], v[1], v[2])));
            }
            if let Some(q) = initial.q {
                for (i, x) in q.iter().enumerate() {
                    if !x.is_finite() {
                        let location = Location::Initial { key: "q", index: Some(i) };
                        return Err(TrajectoryError::NonFinite { location, value: *x });
                    }
                }
                target.initial_joints = Some(q);
            }
        }
        Ok(target)
    }

    /// Reads and parses a spatial target file.
    ///
    /// # Errors
    /// [`TrajectoryError::Io`] if the file cannot be read, otherwise as
    /// [`from_toml_str`](Self::from_toml_str).
    pub fn load(path: impl AsRef<Path>) -> Result<Self, TrajectoryError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .map_err(|error| TrajectoryError::Io { path: path.to_path_buf(), error })?;
        Self::from_toml_str(&text)
    }
}

/// The target of a spatial run.
#[derive(Clone, Debug, PartialEq)]
pub enum SpatialTarget {
    /// A paper trajectory lifted with a vertical sine.
    Lifted(LiftedTrajectory),
    /// Piecewise-constant body twists.
    Piecewise(SpatialPiecewise),
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

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TargetFile {
    #[serde(default)]
    initial: Option<InitialFile>,
    #[serde(default)]
    segment: Vec<SegmentFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct InitialFile {
    r_bd: Option<Vec<f64>>,
    q: Option<Vec<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SegmentFile {
    duration: f64,
    velocity: Vec<f64>,
}

fn six(values: &[f64], location: Location) -> Result<Vector6<f64>, TrajectoryError> {
    if values.len() == 6 {
        Ok(Vector6::from_column_slice(values))
    } else {
        Err(TrajectoryError::WrongLength { location, expected: 6, found: values.len() })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_moves_the_target_exactly_and_stops() {
        let t = SpatialPiecewise::from_toml_str(
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
        assert_eq!(t.twist(10.0), Vector6::zeros());
        assert_eq!(t.twist(2.5)[5], 0.2);
        let (lo, hi) = t.height_range(&r0);
        assert_eq!(lo, 0.8);
        assert!((hi - 0.9).abs() < 1e-12);
    }

    #[test]
    fn bad_files_name_the_field() {
        let err = |s: &str| SpatialPiecewise::from_toml_str(s).unwrap_err().to_string();
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
