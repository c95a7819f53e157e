//! The target's motion: `ṙ_d = R̄(θ_d) u_d(t)` (paper, eq. 3) with the body velocity
//! `u_d(t)` given by one of the paper's two trajectories (§4.3) or by a user's file.
//!
//! A trajectory gives only the velocity; the plant integrates it (RK4, with `u_d`
//! evaluated at the stage times) from the initial target pose. Velocities are body
//! velocities `(v₁, v₂, ω)` in m/s, m/s, rad/s.
//!
//! # A user's target file (TOML)
//!
//! Piecewise-constant body velocities with durations, like the paper's Table 1; after the
//! last segment the target stops. The `[initial]` table is optional, and so is each of its
//! keys: `r_bd` is the target's pose seen from the platform at `t = 0` (m, m, rad), `q` the
//! arm's joint positions at `t = 0` (rad or m, one per joint). Unknown keys are errors.
//!
//! ```
//! use companion_plant::Trajectory;
//!
//! let trajectory = Trajectory::from_toml_str(r#"
//!     [initial]
//!     r_bd = [2.5, 1.0, 0.0]
//!     q = [0.0, 0.35, 0.0]
//!
//!     [[segment]]
//!     duration = 5.0               # s
//!     velocity = [0.0, 0.0, 0.0]   # (m/s, m/s, rad/s)
//!
//!     [[segment]]
//!     duration = 10
//!     velocity = [0.2, 0.0, 0.0]
//! "#)?;
//! assert_eq!(trajectory.velocity(7.0)[0], 0.2);
//! assert_eq!(trajectory.velocity(15.0)[0], 0.0); // stopped after the last segment
//! # Ok::<(), companion_plant::TrajectoryError>(())
//! ```
//!
//! A complete example is `sim-plant/examples/target.toml`.

use core::f64::consts::{FRAC_PI_2, PI};
use std::path::{Path, PathBuf};

use companion_core::nalgebra::{SVector, Vector3, Vector6};
use companion_core::space::Vector as _;
use companion_core::{so3, Planar, Pose, Pose3, Space, Spatial};
use serde::Deserialize;

use crate::initial::InitialConditions;

/// The paper's two target trajectories (§4.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PaperTrajectory {
    /// Trajectory 1: a circle of radius 0.1 m and period 4 s at fixed orientation,
    /// `r_bd(0) = (2.6, 1, 0)`.
    One,
    /// Trajectory 2: Table 1 (rotations and three straight lines, 120 s),
    /// `r_bd(0) = (2.5, 1, 0)`.
    Two,
}

impl PaperTrajectory {
    /// The target's initial pose seen from the platform, `r_bd(0)` (m, m, rad).
    pub fn initial_r_bd(self) -> Pose<f64> {
        match self {
            PaperTrajectory::One => Pose::new(2.6, 1.0, 0.0),
            PaperTrajectory::Two => Pose::new(2.5, 1.0, 0.0),
        }
    }
}

/// The arm's initial joints in both of the paper's runs, `q(0) = (0, 0.35, 0)` (rad, m, rad).
pub const PAPER_INITIAL_JOINTS: [f64; 3] = [0.0, 0.35, 0.0];

/// The initial conditions of the paper's runs: platform at the origin with `θ_b = 0`,
/// steering straight (`ξ = 0`), `q(0) = (0, 0.35, 0)`, and the target placed so that
/// `r_bd(0)` is as the paper gives it.
pub fn paper_initial(trajectory: PaperTrajectory) -> InitialConditions<3> {
    InitialConditions::with_relative_target(
        Pose::identity(),
        trajectory.initial_r_bd(),
        SVector::<f64, 3>::from(PAPER_INITIAL_JOINTS),
    )
}

/// Angular speed amplitude of Table 1's rotations, `π²/20` (rad/s).
const TABLE1_OMEGA: f64 = PI * PI / 20.0;

/// Speed of trajectory 1's circle, `π/20` (m/s).
const TRAJECTORY1_SPEED: f64 = PI / 20.0;

/// The target's motion: its body velocity `u_d(t)`.
#[derive(Clone, Debug, PartialEq)]
pub enum Trajectory {
    /// The paper's trajectory 1: `u_d(t) = −(π/20) (sin(πt/2), cos(πt/2), 0)`; runs forever.
    Paper1,
    /// The paper's trajectory 2, Table 1; zero outside `[0, 120)` s.
    Paper2,
    /// Piecewise-constant body velocities, e.g. read from a TOML file.
    Piecewise(PiecewiseTrajectory),
}

impl From<PaperTrajectory> for Trajectory {
    fn from(p: PaperTrajectory) -> Self {
        match p {
            PaperTrajectory::One => Trajectory::Paper1,
            PaperTrajectory::Two => Trajectory::Paper2,
        }
    }
}

impl Trajectory {
    /// The target's body velocity `u_d(t)` at time `t` (s): (m/s, m/s, rad/s).
    ///
    /// Intervals are closed on the left: at a boundary of Table 1 the next row applies.
    pub fn velocity(&self, t: f64) -> Vector3<f64> {
        self.piece(t).velocity(t)
    }

    /// The smooth piece of `u_d` that applies at `t`.
    ///
    /// The plant picks the piece once per step, at the step's midpoint, and evaluates it at
    /// the RK4 stage times: a boundary that falls on a step's edge (up to the rounding of
    /// `n·dt`) is then integrated exactly, with no stage on the wrong side of a jump.
    pub(crate) fn piece(&self, t: f64) -> Piece {
        match self {
            Trajectory::Paper1 => Piece::Circle,
            Trajectory::Paper2 => table1(t),
            Trajectory::Piecewise(p) => Piece::Constant(p.velocity(t)),
        }
    }

    /// How long the target moves (s): `None` for trajectory 1 (periodic, forever), 120 s for
    /// trajectory 2, the sum of the durations for a piecewise trajectory.
    pub fn duration(&self) -> Option<f64> {
        match self {
            Trajectory::Paper1 => None,
            Trajectory::Paper2 => Some(120.0),
            Trajectory::Piecewise(p) => Some(p.duration()),
        }
    }

    /// The paper's initial conditions for this trajectory (see [`paper_initial`]); for a
    /// piecewise trajectory, those of trajectory 2 overridden by the file's `[initial]`
    /// values.
    ///
    /// # Errors
    /// [`TrajectoryError::JointCount`] if the file's `q` does not have 3 entries.
    pub fn initial_conditions(&self) -> Result<InitialConditions<3>, TrajectoryError> {
        match self {
            Trajectory::Paper1 => Ok(paper_initial(PaperTrajectory::One)),
            Trajectory::Paper2 => Ok(paper_initial(PaperTrajectory::Two)),
            Trajectory::Piecewise(p) => p.initial_conditions(&paper_initial(PaperTrajectory::Two)),
        }
    }

    /// Parses a target file (see the [module docs](self)).
    ///
    /// # Errors
    /// A [`TrajectoryError`] naming the key or segment and the rule it breaks.
    pub fn from_toml_str(text: &str) -> Result<Self, TrajectoryError> {
        PiecewiseTrajectory::from_toml_str(text).map(Trajectory::Piecewise)
    }

    /// Reads and parses a target file.
    ///
    /// # Errors
    /// [`TrajectoryError::Io`] if the file cannot be read, otherwise as
    /// [`from_toml_str`](Self::from_toml_str).
    pub fn load(path: impl AsRef<Path>) -> Result<Self, TrajectoryError> {
        PiecewiseTrajectory::load(path).map(Trajectory::Piecewise)
    }
}

/// A piece of `u_d(t)` on which it is smooth (analytic).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Piece {
    /// A constant body velocity.
    Constant(Vector3<f64>),
    /// Trajectory 1: `−(π/20) (sin(πt/2), cos(πt/2), 0)`.
    Circle,
    /// A rotation of Table 1 starting at `t0` (s): `(0, 0, (π²/20) cos(π(t − t0)/2))`.
    Rotation {
        /// Start of the row (s).
        t0: f64,
    },
}

impl Piece {
    /// `u_d(t)` on this piece (m/s, m/s, rad/s).
    pub(crate) fn velocity(&self, t: f64) -> Vector3<f64> {
        self.velocity_with(t, libm::sincos)
    }

    /// [`velocity`](Self::velocity) with `sincos` in place of `libm::sincos` (the plant
    /// passes a cache that returns libm's very bits).
    #[inline]
    pub(crate) fn velocity_with(&self, t: f64, mut sincos: impl FnMut(f64) -> (f64, f64)) -> Vector3<f64> {
        match *self {
            Piece::Constant(u) => u,
            Piece::Circle => {
                let (s, c) = sincos(FRAC_PI_2 * t);
                Vector3::new(-TRAJECTORY1_SPEED * s, -TRAJECTORY1_SPEED * c, 0.0)
            }
            Piece::Rotation { t0 } => {
                let (_, c) = sincos(FRAC_PI_2 * (t - t0));
                Vector3::new(0.0, 0.0, TABLE1_OMEGA * c)
            }
        }
    }
}

/// Table 1 of the paper (trajectory 2): the row that applies at `t` (s).
fn table1(t: f64) -> Piece {
    let constant = |v1: f64, v2: f64| Piece::Constant(Vector3::new(v1, v2, 0.0));
    if !(0.0..120.0).contains(&t) || t < 5.0 {
        constant(0.0, 0.0)
    } else if t < 27.0 {
        Piece::Rotation { t0: 5.0 }
    } else if t < 37.0 {
        constant(0.2, 0.0)
    } else if t < 59.0 {
        Piece::Rotation { t0: 37.0 }
    } else if t < 99.0 {
        constant(0.0, 0.05)
    } else if t < 105.0 {
        constant(0.0, 0.0)
    } else if t < 115.0 {
        constant(-0.2, 0.0)
    } else {
        constant(0.0, 0.0)
    }
}

/// What a target file's numbers mean in a space: the plane's `(x, y, θ)` and
/// `(v₁, v₂, ω)`, or space's `(x, y, z, roll, pitch, yaw)` and the body twist `(v, ω)`. One
/// file format and one [`PiecewiseTrajectory`] serve both (the spatial form is read by
/// [`crate::spatial_target`]).
pub trait FileSpace: Space<f64> {
    /// `r_bd` from the file's numbers (as many as [`Space::DIM`]).
    fn pose_of(v: &[f64]) -> Self::Pose;
    /// A velocity from the file's numbers (as many as [`Space::DIM`]).
    fn vector_of(v: &[f64]) -> Self::Vector;
}

impl FileSpace for Planar {
    fn pose_of(v: &[f64]) -> Pose<f64> {
        Pose::new(v[0], v[1], v[2])
    }
    fn vector_of(v: &[f64]) -> Vector3<f64> {
        Vector3::new(v[0], v[1], v[2])
    }
}

impl FileSpace for Spatial {
    /// Position and roll, pitch, yaw: `R_z(yaw) R_y(pitch) R_x(roll)`.
    fn pose_of(v: &[f64]) -> Pose3<f64> {
        Pose3::new(so3::from_rpy(v[3], v[4], v[5]), Vector3::new(v[0], v[1], v[2]))
    }
    fn vector_of(v: &[f64]) -> Vector6<f64> {
        Vector6::from_column_slice(v)
    }
}

/// One segment of a piecewise trajectory: a constant body velocity held for a duration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment<S: Space<f64> = Planar> {
    /// How long the velocity is held (s), `> 0`.
    pub duration: f64,
    /// The target's body velocity: `u_d = (v₁, v₂, ω)` in the plane (m/s, m/s, rad/s), the
    /// twist `(v, ω)` in its own frame in space (m/s, rad/s).
    pub velocity: S::Vector,
}

/// Piecewise-constant target velocities, starting at `t = 0`; zero after the last segment
/// (and before `t = 0`). Optionally carries the initial `r_bd(0)` and `q(0)` of a run. In
/// the plane (the default) the plant integrates it with the robot; in space
/// (`PiecewiseTrajectory<Spatial>`) the motion is exact, `r_d(t) = r_d(t_k) exp((t − t_k) ξ_k)`.
#[derive(Clone, Debug, PartialEq)]
pub struct PiecewiseTrajectory<S: Space<f64> = Planar> {
    segments: Vec<Segment<S>>,
    /// `ends[k]`: the time (s) at which segment `k` ends.
    ends: Vec<f64>,
    initial_r_bd: Option<S::Pose>,
    initial_joints: Option<Vec<f64>>,
}

impl<S: FileSpace> PiecewiseTrajectory<S> {
    /// A trajectory from its segments, in order, without initial conditions.
    ///
    /// # Errors
    /// A duration that is not finite or not `> 0`, a velocity component that is not finite,
    /// or a total duration that overflows.
    pub fn new(segments: Vec<Segment<S>>) -> Result<Self, TrajectoryError> {
        let ends = segment_ends(segments.iter().map(|s| (s.duration, s.velocity.as_slice())))?;
        Ok(Self { segments, ends, initial_r_bd: None, initial_joints: None })
    }

    /// The same trajectory with the initial target pose seen from the platform, `r_bd(0)`.
    ///
    /// # Errors
    /// A coordinate that is not finite.
    pub fn with_initial_r_bd(mut self, r_bd: S::Pose) -> Result<Self, TrajectoryError> {
        if !S::pose_is_finite(&r_bd) {
            let location = Location::Initial { key: "r_bd", index: None };
            return Err(TrajectoryError::NonFinite { location, value: f64::NAN });
        }
        self.initial_r_bd = Some(r_bd);
        Ok(self)
    }

    /// The same trajectory with the arm's initial joint positions `q(0)` (rad or m).
    ///
    /// # Errors
    /// A value that is not finite.
    pub fn with_initial_joints(mut self, q: Vec<f64>) -> Result<Self, TrajectoryError> {
        finite(&q, "q")?;
        self.initial_joints = Some(q);
        Ok(self)
    }

    /// The segments, in order.
    pub fn segments(&self) -> &[Segment<S>] {
        &self.segments
    }

    /// The total duration (s); 0 without segments.
    pub fn duration(&self) -> f64 {
        self.ends.last().copied().unwrap_or(0.0)
    }

    /// `r_bd(0)` if the trajectory carries it.
    pub fn initial_r_bd(&self) -> Option<S::Pose> {
        self.initial_r_bd
    }

    /// `q(0)` if the trajectory carries it (rad or m).
    pub fn initial_joints(&self) -> Option<&[f64]> {
        self.initial_joints.as_deref()
    }

    /// The segment containing `t` (segments are closed on the left), if any, and its start
    /// time.
    pub(crate) fn segment_at(&self, t: f64) -> Option<(usize, f64)> {
        if t.is_nan() || t < 0.0 {
            return None;
        }
        let k = self.ends.partition_point(|&end| end <= t);
        (k < self.segments.len()).then(|| (k, if k == 0 { 0.0 } else { self.ends[k - 1] }))
    }

    /// The body velocity at time `t` (s): that of the segment containing `t`, zero before 0
    /// and from the end of the last segment on.
    pub fn velocity(&self, t: f64) -> S::Vector {
        self.segment_at(t).map_or_else(S::Vector::zeros, |(k, _)| self.segments[k].velocity)
    }

    /// Parses a target file (see the [module docs](self); in space,
    /// [`crate::spatial_target`]): `velocity` and `r_bd` have [`Space::DIM`] entries.
    ///
    /// # Errors
    /// [`TrajectoryError::Parse`] for malformed TOML, an unknown or missing key or a value
    /// of the wrong type; the other variants for a value of the wrong length or that breaks a
    /// rule, naming the key and segment.
    pub fn from_toml_str(text: &str) -> Result<Self, TrajectoryError> {
        let file: TargetFile = toml::from_str(text).map_err(TrajectoryError::Parse)?;
        let segments = file
            .segment
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let location = Location::Segment { number: k + 1, key: "velocity", index: None };
                Ok(Segment {
                    duration: s.duration,
                    velocity: S::vector_of(sized::<S>(&s.velocity, location)?),
                })
            })
            .collect::<Result<_, TrajectoryError>>()?;
        let mut trajectory = Self::new(segments)?;
        if let Some(initial) = file.initial {
            if let Some(r_bd) = initial.r_bd {
                let v = sized::<S>(&r_bd, Location::Initial { key: "r_bd", index: None })?;
                finite(v, "r_bd")?;
                trajectory = trajectory.with_initial_r_bd(S::pose_of(v))?;
            }
            if let Some(q) = initial.q {
                trajectory = trajectory.with_initial_joints(q)?;
            }
        }
        Ok(trajectory)
    }

    /// Reads and parses a target file.
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

impl PiecewiseTrajectory {
    /// The initial conditions of a run: `defaults` with the target placed so that
    /// `r_bd(0)` is the trajectory's (if it has one: `r_d = r_b · r_bd`) and the joints
    /// replaced by the trajectory's `q(0)` (if it has one).
    ///
    /// # Errors
    /// [`TrajectoryError::JointCount`] if `q(0)` does not have `N` entries.
    pub fn initial_conditions<const N: usize>(
        &self,
        defaults: &InitialConditions<N>,
    ) -> Result<InitialConditions<N>, TrajectoryError> {
        let mut initial = *defaults;
        if let Some(r_bd) = self.initial_r_bd {
            initial.target = initial.base.compose(&r_bd);
        }
        if let Some(q) = &self.initial_joints {
            if q.len() != N {
                return Err(TrajectoryError::JointCount { expected: N, found: q.len() });
            }
            initial.joints = SVector::<f64, N>::from_column_slice(q);
        }
        Ok(initial)
    }
}

/// Checks that every one of `values` (key `key` of `[initial]`) is finite.
fn finite(values: &[f64], key: &'static str) -> Result<(), TrajectoryError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(TrajectoryError::NonFinite {
            location: Location::Initial { key, index: Some(i) },
            value: values[i],
        }),
        None => Ok(()),
    }
}

/// The end times of consecutive segments given as `(duration, velocity components)`, each
/// checked: a finite duration `> 0`, finite components, a finite total.
fn segment_ends<'a>(segments: impl Iterator<Item = (f64, &'a [f64])>) -> Result<Vec<f64>, TrajectoryError> {
    let mut ends = Vec::new();
    let mut end = 0.0;
    for (k, (duration, velocity)) in segments.enumerate() {
        let number = k + 1;
        if !duration.is_finite() {
            return Err(TrajectoryError::NonFinite {
                location: Location::Segment { number, key: "duration", index: None },
                value: duration,
            });
        }
        if duration <= 0.0 {
            return Err(TrajectoryError::NonPositiveDuration { segment: number, value: duration });
        }
        for (i, v) in velocity.iter().enumerate() {
            if !v.is_finite() {
                return Err(TrajectoryError::NonFinite {
                    location: Location::Segment { number, key: "velocity", index: Some(i) },
                    value: *v,
                });
            }
        }
        end += duration;
        if !f64::is_finite(end) {
            return Err(TrajectoryError::TotalDurationOverflow);
        }
        ends.push(end);
    }
    Ok(ends)
}

/// The file's layout, in the plane and in space (private: the public type is
/// [`PiecewiseTrajectory`]).
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
    // Vectors, not `[f64; 3]`: toml 0.9 silently drops extra elements of a fixed-size
    // array, so the length is checked here.
    r_bd: Option<Vec<f64>>,
    q: Option<Vec<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SegmentFile {
    duration: f64,
    velocity: Vec<f64>,
}

/// `values` if they are as many as a vector of `S` has, or the error naming `location`.
fn sized<S: Space<f64>>(values: &[f64], location: Location) -> Result<&[f64], TrajectoryError> {
    if values.len() == S::DIM {
        Ok(values)
    } else {
        Err(TrajectoryError::WrongLength { location, expected: S::DIM, found: values.len() })
    }
}

/// Where in a target file a bad value is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// Key `key` (component `index`, from 0, for an array) of segment `number`, counted from
    /// 1 in the order of the `[[segment]]` tables.
    Segment {
        /// The segment, from 1.
        number: usize,
        /// `"duration"` or `"velocity"`.
        key: &'static str,
        /// The array component, from 0.
        index: Option<usize>,
    },
    /// Key `key` (component `index`, from 0, for an array) of the `[initial]` table.
    Initial {
        /// `"r_bd"` or `"q"`.
        key: &'static str,
        /// The array component, from 0.
        index: Option<usize>,
    },
}

impl core::fmt::Display for Location {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Location::Segment { number, key, index: Some(i) } => write!(f, "segment {number}: `{key}[{i}]`"),
            Location::Segment { number, key, index: None } => write!(f, "segment {number}: `{key}`"),
            Location::Initial { key, index: Some(i) } => write!(f, "[initial]: `{key}[{i}]`"),
            Location::Initial { key, index: None } => write!(f, "[initial]: `{key}`"),
        }
    }
}

/// Why a target file or trajectory was rejected.
#[derive(Debug, thiserror::Error)]
pub enum TrajectoryError {
    /// The file could not be read.
    #[error("cannot read target file {}: {error}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        error: std::io::Error,
    },
    /// Malformed TOML, an unknown key (rule: only `initial`, `segment`, `r_bd`, `q`,
    /// `duration`, `velocity` are allowed), a missing `duration` or `velocity`, or a value of
    /// the wrong type. The message gives the line and the key.
    #[error("target file is not valid: {0}")]
    Parse(toml::de::Error),
    /// A value is NaN or infinite (rule: every number must be finite).
    #[error("{location} is {value}: every value must be a finite number")]
    NonFinite {
        /// Where the value is.
        location: Location,
        /// The value.
        value: f64,
    },
    /// An array has the wrong number of entries (rule: `velocity` and `r_bd` have 3 in the
    /// plane, 6 in space).
    #[error("{location} has {found} entries: it must have {expected}")]
    WrongLength {
        /// Where the array is.
        location: Location,
        /// The required length.
        expected: usize,
        /// The length found.
        found: usize,
    },
    /// A segment's duration is zero or negative (rule: `duration > 0`).
    #[error("segment {segment}: `duration` is {value} s: it must be > 0")]
    NonPositiveDuration {
        /// The segment, from 1.
        segment: usize,
        /// The duration (s).
        value: f64,
    },
    /// The durations add up to more than the largest finite number.
    #[error("the segments' durations add up to more than the largest finite number")]
    TotalDurationOverflow,
    /// The file's `q` does not have one entry per joint.
    #[error("[initial]: `q` has {found} entries, but the arm has {expected} joints")]
    JointCount {
        /// The arm's joint count.
        expected: usize,
        /// The number of entries in `q`.
        found: usize,
    },
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const GOOD: &str = r#"
        # Wait, drive forward, slide sideways while turning, stop.
        [initial]
        r_bd = [2.0, -0.5, 0.25]
        q = [0.1, 0.4, -0.1]

        [[segment]]
        duration = 2          # an integer is accepted as a number of seconds
        velocity = [0.0, 0.0, 0.0]

        [[segment]]
        duration = 3.5
        velocity = [0.2, 0, 0]

        [[segment]]
        duration = 1e1
        velocity = [0.0, 0.05, -0.1]
    "#;

    #[test]
    fn a_good_file_parses_with_its_initial_conditions() {
        let Trajectory::Piecewise(p) = Trajectory::from_toml_str(GOOD).expect("valid") else {
            panic!("a file gives a piecewise trajectory");
        };
        assert_eq!(p.segments().len(), 3);
        assert_eq!(p.duration(), 15.5);
        assert_eq!(p.initial_r_bd(), Some(Pose::new(2.0, -0.5, 0.25)));
        assert_eq!(p.initial_joints(), Some(&[0.1, 0.4, -0.1][..]));
        assert_eq!(p.velocity(-1.0), Vector3::zeros());
        assert_eq!(p.velocity(0.0), Vector3::zeros());
        assert_eq!(p.velocity(1.999), Vector3::zeros());
        assert_eq!(p.velocity(2.0), Vector3::new(0.2, 0.0, 0.0));
        assert_eq!(p.velocity(5.499), Vector3::new(0.2, 0.0, 0.0));
        assert_eq!(p.velocity(5.5), Vector3::new(0.0, 0.05, -0.1));
        assert_eq!(p.velocity(15.4999), Vector3::new(0.0, 0.05, -0.1));
        assert_eq!(p.velocity(15.5), Vector3::zeros());
        assert_eq!(p.velocity(1e9), Vector3::zeros());
        assert_eq!(p.velocity(f64::NAN), Vector3::zeros());

        // The target is placed at r_b · r_bd.
        let defaults = InitialConditions::with_relative_target(
            Pose::new(1.0, 2.0, FRAC_PI_2),
            Pose::identity(),
            SVector::<f64, 3>::zeros(),
        );
        let init = p.initial_conditions(&defaults).expect("3 joints");
        assert!((init.target.x - 1.5).abs() < 1e-15);
        assert!((init.target.y - 4.0).abs() < 1e-15);
        assert_eq!(init.target.theta, FRAC_PI_2 + 0.25);
        assert_eq!(init.joints, SVector::<f64, 3>::new(0.1, 0.4, -0.1));
        assert_eq!(init.base, defaults.base);
    }

    #[test]
    fn the_shipped_example_file_is_valid() {
        let text = include_str!("../examples/target.toml");
        let t = Trajectory::from_toml_str(text).expect("the example file parses");
        assert!(t.duration().expect("finite") > 0.0);
        t.initial_conditions().expect("the example's q has 3 joints");
    }

    #[test]
    fn an_empty_file_is_a_target_at_rest_with_the_paper_defaults() {
        let t = Trajectory::from_toml_str("").expect("valid");
        assert_eq!(t.duration(), Some(0.0));
        assert_eq!(t.velocity(0.0), Vector3::zeros());
        assert_eq!(t.initial_conditions().expect("ok"), paper_initial(PaperTrajectory::Two));
    }

    fn parse_err(text: &str) -> TrajectoryError {
        Trajectory::from_toml_str(text).expect_err("the file is invalid")
    }

    #[test]
    fn a_negative_or_zero_duration_is_rejected_naming_the_segment() {
        let text =
            "[[segment]]\nduration = 1\nvelocity = [0,0,0]\n[[segment]]\nduration = -2.0\nvelocity = [0,0,0]";
        let e = parse_err(text);
        assert!(matches!(e, TrajectoryError::NonPositiveDuration { segment: 2, value } if value == -2.0));
        let msg = e.to_string();
        assert!(msg.contains("segment 2") && msg.contains("duration") && msg.contains("> 0"), "{msg}");

        let e = parse_err("[[segment]]\nduration = 0\nvelocity = [0,0,0]");
        assert!(matches!(e, TrajectoryError::NonPositiveDuration { segment: 1, .. }));
    }

    #[test]
    fn non_finite_values_are_rejected_naming_the_key() {
        let e = parse_err("[[segment]]\nduration = 1\nvelocity = [0, nan, 0]");
        let TrajectoryError::NonFinite { location, value } = &e else { panic!("{e:?}") };
        assert_eq!(*location, Location::Segment { number: 1, key: "velocity", index: Some(1) });
        assert!(value.is_nan());
        assert!(e.to_string().contains("segment 1: `velocity[1]`"), "{e}");

        let e = parse_err("[[segment]]\nduration = inf\nvelocity = [0, 0, 0]");
        assert!(matches!(
            e,
            TrajectoryError::NonFinite { location: Location::Segment { number: 1, key: "duration", .. }, .. }
        ));

        let e = parse_err("[initial]\nr_bd = [0, 0, -inf]");
        assert!(matches!(
            e,
            TrajectoryError::NonFinite { location: Location::Initial { key: "r_bd", index: Some(2) }, .. }
        ));
        assert!(e.to_string().contains("[initial]: `r_bd[2]`"), "{e}");

        let e = parse_err("[initial]\nq = [0, nan]");
        assert!(matches!(
            e,
            TrajectoryError::NonFinite { location: Location::Initial { key: "q", index: Some(1) }, .. }
        ));
    }

    #[test]
    fn unknown_keys_are_rejected_naming_the_key() {
        for (text, key) in [
            ("speed = 3", "speed"),
            ("[initial]\nr_db = [0, 0, 0]", "r_db"),
            ("[[segment]]\nduration = 1\nvelocity = [0,0,0]\nvelocty = [1,0,0]", "velocty"),
            ("[[segments]]\nduration = 1\nvelocity = [0,0,0]", "segments"),
        ] {
            let e = parse_err(text);
            assert!(matches!(e, TrajectoryError::Parse(_)), "{e:?}");
            let msg = e.to_string();
            assert!(msg.contains("unknown field") && msg.contains(key), "{msg}");
        }
    }

    #[test]
    fn wrong_shapes_missing_keys_and_syntax_errors_are_rejected() {
        let ok = "[[segment]]\nduration = 1\nvelocity = [0, 0, 0]\n";
        let e = parse_err(&format!("{ok}[[segment]]\nduration = 1\nvelocity = [0, 0]"));
        assert!(matches!(
            e,
            TrajectoryError::WrongLength {
                location: Location::Segment { number: 2, key: "velocity", index: None },
                expected: 3,
                found: 2
            }
        ));
        assert!(e.to_string().contains("segment 2: `velocity` has 2 entries: it must have 3"), "{e}");
        let e = parse_err("[initial]\nr_bd = [0, 0, 0, 0]");
        assert!(matches!(e, TrajectoryError::WrongLength { found: 4, .. }));
        assert!(e.to_string().contains("[initial]: `r_bd`"), "{e}");

        for (text, needle) in [
            ("[[segment]]\nvelocity = [0, 0, 0]", "duration"),
            ("[[segment]]\nduration = 1", "velocity"),
            ("[[segment]]\nduration = \"5 s\"\nvelocity = [0, 0, 0]", "duration"),
            ("[[segment]]\nduration = 1\nvelocity = [0, \"a\", 0]", "velocity"),
            ("segment = 3", "segment"),
            ("[[segment]\nduration = 1", ""),
        ] {
            let e = parse_err(text);
            assert!(matches!(e, TrajectoryError::Parse(_)), "{e:?}");
            assert!(e.to_string().contains(needle), "{needle}: {e}");
        }
    }

    #[test]
    fn a_joint_count_mismatch_is_reported_when_the_run_is_set_up() {
        let t = Trajectory::from_toml_str("[initial]\nq = [0.0, 0.35]").expect("parses: N is not known yet");
        let e = t.initial_conditions().expect_err("the paper's arm has 3 joints");
        assert!(matches!(e, TrajectoryError::JointCount { expected: 3, found: 2 }));
        assert!(e.to_string().contains("3 joints"), "{e}");
    }

    #[test]
    fn a_missing_file_is_an_io_error_naming_the_path() {
        let e = Trajectory::load("/nonexistent/companion/target.toml").expect_err("no such file");
        assert!(matches!(e, TrajectoryError::Io { .. }));
        assert!(e.to_string().contains("/nonexistent/companion/target.toml"), "{e}");
    }

    #[test]
    fn trajectory_2_follows_table_1_at_every_boundary() {
        let t = Trajectory::Paper2;
        let w = TABLE1_OMEGA;
        let before = |b: f64| b - 1e-9;
        let close = |a: Vector3<f64>, b: Vector3<f64>| (a - b).amax() < 1e-7;
        let rot = |x: f64| Vector3::new(0.0, 0.0, x);
        // Motionless before 5 s.
        assert_eq!(t.velocity(-1.0), Vector3::zeros());
        assert_eq!(t.velocity(0.0), Vector3::zeros());
        assert_eq!(t.velocity(before(5.0)), Vector3::zeros());
        // Rotation on [5, 27): cos starts at 1 and ends at cos(11π) = −1.
        assert_eq!(t.velocity(5.0), rot(w));
        assert!(close(t.velocity(6.0), rot(0.0)));
        assert!(close(t.velocity(7.0), rot(-w)));
        assert!(close(t.velocity(before(27.0)), rot(-w)));
        // Translation on [27, 37).
        assert_eq!(t.velocity(27.0), Vector3::new(0.2, 0.0, 0.0));
        assert_eq!(t.velocity(before(37.0)), Vector3::new(0.2, 0.0, 0.0));
        // Rotation on [37, 59).
        assert_eq!(t.velocity(37.0), rot(w));
        assert!(close(t.velocity(before(59.0)), rot(-w)));
        // Lateral translation on [59, 99).
        assert_eq!(t.velocity(59.0), Vector3::new(0.0, 0.05, 0.0));
        assert_eq!(t.velocity(before(99.0)), Vector3::new(0.0, 0.05, 0.0));
        // Motionless on [99, 105).
        assert_eq!(t.velocity(99.0), Vector3::zeros());
        assert_eq!(t.velocity(before(105.0)), Vector3::zeros());
        // Backwards on [105, 115).
        assert_eq!(t.velocity(105.0), Vector3::new(-0.2, 0.0, 0.0));
        assert_eq!(t.velocity(before(115.0)), Vector3::new(-0.2, 0.0, 0.0));
        // Motionless on [115, 120) and after the table ends.
        assert_eq!(t.velocity(115.0), Vector3::zeros());
        assert_eq!(t.velocity(120.0), Vector3::zeros());
        assert_eq!(t.velocity(1e6), Vector3::zeros());
        assert_eq!(t.duration(), Some(120.0));
    }

    #[test]
    fn trajectory_1_velocity_has_constant_speed_pi_over_20() {
        for k in 0..100 {
            let u = Trajectory::Paper1.velocity(0.37 * k as f64);
            assert!((u.norm() - PI / 20.0).abs() < 1e-15);
            assert_eq!(u[2], 0.0);
        }
        assert_eq!(Trajectory::Paper1.velocity(0.0), Vector3::new(-0.0, -PI / 20.0, 0.0));
        assert_eq!(Trajectory::Paper1.duration(), None);
    }

    #[test]
    fn paper_initial_places_the_target_at_r_bd() {
        let one = paper_initial(PaperTrajectory::One);
        assert_eq!(one.base, Pose::identity());
        assert_eq!(one.steering, 0.0);
        assert_eq!(one.target, Pose::new(2.6, 1.0, 0.0));
        assert_eq!(one.joints, SVector::<f64, 3>::new(0.0, 0.35, 0.0));
        let two = Trajectory::Paper2.initial_conditions().expect("paper");
        assert_eq!(two.target, Pose::new(2.5, 1.0, 0.0));
        assert_eq!(Trajectory::from(PaperTrajectory::One), Trajectory::Paper1);
    }

    fn finite() -> impl Strategy<Value = f64> {
        prop_oneof![-10.0..10.0f64, -1e12..1e12f64, Just(0.0), Just(-0.0)]
    }

    proptest! {
        /// A file written from any valid segments parses back to the same velocities (Rust's
        /// `{:?}` of an `f64` is a round-trippable TOML number).
        #[test]
        fn written_segments_parse_back_exactly(
            segs in prop::collection::vec((1e-3..100.0f64, finite(), finite(), finite()), 0..8),
            probe in 0.0..1.0f64,
        ) {
            let mut text = String::new();
            for (d, a, b, c) in &segs {
                text.push_str(&format!("[[segment]]\nduration = {d:?}\nvelocity = [{a:?}, {b:?}, {c:?}]\n"));
            }
            let p: PiecewiseTrajectory = PiecewiseTrajectory::from_toml_str(&text).expect("valid");
            prop_assert_eq!(p.segments().len(), segs.len());
            let mut start = 0.0;
            for (s, (d, a, b, c)) in p.segments().iter().zip(&segs) {
                prop_assert_eq!(s.duration.to_bits(), d.to_bits());
                prop_assert_eq!(s.velocity, Vector3::new(*a, *b, *c));
                // A time inside the segment gives its velocity.
                let t = start + probe * d;
                if t < start + d {
                    prop_assert_eq!(p.velocity(t), s.velocity);
                }
                start += d;
            }
            prop_assert_eq!(p.velocity(start), Vector3::zeros());
        }
    }
}
