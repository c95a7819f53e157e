//! Spatial runs (`companion sim --arm ur5|panda|FILE`, §5): the spatial law on a
//! [`SpatialPlant`] in one process — the same loop and records as the paper's arm
//! ([`sim::simulate`](crate::run::sim::simulate)), deterministic.
//!
//! A [`SpatialScenario`] is a planar [`Scenario`] (platform, run (a)–(d), scalar type,
//! period, duration, logging, pure delay, config overrides of the platform law, plant
//! imperfections) plus the arm ([`SpatialArmSpec`]) and the spatial target. [`run_spatial`]
//! builds and checks everything — arm, law, plant, the target's height against the arm's
//! reach — before it writes anything, then runs steps `0..=steps` and writes
//! `timeseries.csv`, `summary.json` and `scenario.json` into the run's folder (and, asked
//! for, the replay file); the plots are the caller's choice ([`SpatialOutcome::render`]).
//!
//! A target outside the reachable workspace is not an error once the run has started: the
//! law stays finite (it damps near singular configurations and refuses steps at them), and
//! the summary reports the joint margins and the rejected steps.

use std::path::{Path, PathBuf};

use companion_core::nalgebra::{Matrix3, SVector, Vector3};
use companion_core::{Chain, Manipulator, PlatformKind, Pose, Pose3, Spatial, SpatialArm};
use companion_plant::{
    vertical_reach, Imperfections, InitialConditions, LiftedTrajectory, PaperTrajectory, PiecewiseTrajectory,
    PlantConfig, PlantError, SpatialPlant, SpatialTarget, TrajectoryError,
};

use crate::domain::arm::{ArmError, SpatialArmSpec};
use crate::domain::controller::{
    boxed_spatial_controller, planar_only_keys, SpatialControllerError, TARGET_DISTANCE,
};
use crate::domain::observe::Observer;
use crate::domain::plant_setup::matched_steering;
use crate::domain::plots::spatial::SpatialFigures;
use crate::domain::plots::PlotError;
use crate::domain::record::error::RecordError;
use crate::domain::record::mcap::ReplayError;
use crate::domain::record::recorder::{expected_rows, Log};
use crate::domain::record::{Replay, ReplaySummary, Row, Summary, SummaryAccumulator};
use crate::domain::scenario::Scenario;
use crate::run::sim::{simulate, LoopError, Robot};

/// The target of a spatial run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SpatialTargetChoice {
    /// The paper's trajectory lifted with a vertical sine at the arm's home height.
    Lifted(PaperTrajectory),
    /// A TOML file of 6-DOF body twists (`companion_plant::spatial_target`).
    File(PathBuf),
}

/// A spatial run's description.
#[derive(Clone, Debug, PartialEq)]
pub struct SpatialScenario {
    /// The run's name (its folder under `--all`-like layouts; the summary's `scenario`).
    pub name: String,
    /// The arm.
    pub arm: SpatialArmSpec,
    /// The target.
    pub target: SpatialTargetChoice,
    /// Everything else, as for a planar run (its `target` is not used).
    pub base: Scenario,
}

/// Why a spatial scenario cannot run.
#[derive(Debug, thiserror::Error)]
pub enum SpatialError {
    /// A flag or setting of planar runs that spatial runs do not have.
    #[error("{0} is not available with a spatial arm (--arm ur5|panda|FILE)")]
    Unsupported(&'static str),
    /// `[controller]` keys of the planar arm's task.
    #[error("{} set(s) the planar arm's task; with a spatial arm the task comes from the arm", .0.join(", "))]
    PlanarKeys(Vec<&'static str>),
    /// The target cannot be reached: its height leaves the arm's vertical reach.
    #[error(
        "the arm cannot reach the target's height: the target moves between z = {target_low:.3} and {target_high:.3} m, \
         the arm (mount.xyz[2] ± its links, tool and a target {distance} m beyond the flange) reaches only \
         {reach_low:.3} to {reach_high:.3} m"
    )]
    Unreachable {
        /// The target's lowest height (m).
        target_low: f64,
        /// Its highest (m).
        target_high: f64,
        /// The arm's lowest reach (m).
        reach_low: f64,
        /// Its highest (m).
        reach_high: f64,
        /// `r*_ed`'s distance beyond the flange (m).
        distance: f64,
    },
    /// The target file's `q` does not fit the arm.
    #[error("target file: [initial]: `q` has {found} entries, but the arm has {expected} joints")]
    JointCount {
        /// The arm's joints.
        expected: usize,
        /// The entries given.
        found: usize,
    },
    /// The target file's `q` puts a joint at or outside its limits.
    #[error("target file: [initial]: `q[{index}]` = {value} is not strictly inside joint {}'s limits [{lower}, {upper}]", .index + 1)]
    JointOutside {
        /// The entry (from 0).
        index: usize,
        /// The value.
        value: f64,
        /// The limits.
        lower: f64,
        /// The limits.
        upper: f64,
    },
}

/// Why a spatial run failed: its scenario, arm, law, target or plant (before anything is
/// written), its loop, or its files.
#[derive(Debug, thiserror::Error)]
pub enum SpatialRunError {
    /// The scenario breaks a rule of spatial runs.
    #[error(transparent)]
    Scenario(#[from] SpatialError),
    /// The arm cannot be built.
    #[error(transparent)]
    Arm(#[from] ArmError),
    /// The spatial law cannot be built.
    #[error(transparent)]
    Controller(#[from] SpatialControllerError),
    /// The target file cannot be read or breaks a rule.
    #[error("target file {}", path.display())]
    TargetFile {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        #[source]
        source: TrajectoryError,
    },
    /// A plant parameter breaks a rule.
    #[error("plant parameters")]
    Plant(#[source] PlantError),
    /// The loop failed: the exchange (HIL: the transport), or a step the plant refused.
    #[error(transparent)]
    Loop(#[from] LoopError),
    /// The run's files cannot be written.
    #[error(transparent)]
    Record(#[from] RecordError),
    /// The replay file (`--mcap`) cannot be created.
    #[error(transparent)]
    Replay(#[from] ReplayError),
}

impl SpatialScenario {
    /// A spatial scenario, checked for what spatial runs do not support: measurement noise, a
    /// scenario's own start, `[controller]` keys of the planar arm.
    ///
    /// # Errors
    /// [`SpatialError`] naming the flag or key.
    pub fn new(
        base: Scenario,
        arm: SpatialArmSpec,
        target: SpatialTargetChoice,
    ) -> Result<Self, SpatialError> {
        if base.plant.noise.is_some() {
            return Err(SpatialError::Unsupported("measurement noise (--noise, [plant].noise)"));
        }
        if base.start.is_some() {
            return Err(SpatialError::Unsupported("a scenario's own start"));
        }
        let keys = planar_only_keys(&base.controller);
        if !keys.is_empty() {
            return Err(SpatialError::PlanarKeys(keys));
        }
        let traj = match &target {
            SpatialTargetChoice::Lifted(PaperTrajectory::One) => "traj1".to_string(),
            SpatialTargetChoice::Lifted(PaperTrajectory::Two) => "traj2".to_string(),
            SpatialTargetChoice::File(_) => "custom".to_string(),
        };
        let planar = base.default_name();
        // `traj1-a-unicycle[-f32…]` → `ur5-traj1-a-unicycle[-f32…]`.
        let rest = planar.split_once('-').map_or(planar.as_str(), |(_, r)| r);
        let name = format!("{}-{traj}-{rest}", arm.name());
        Ok(Self { name, arm, target, base })
    }

    /// The number of control periods.
    pub fn steps(&self) -> u64 {
        self.base.steps()
    }
}

/// A spatial run's logged rows, whatever its joint count (the row's type carries it; an enum
/// where the joint count is known only at run time, after the arm is read).
#[derive(Clone, Debug)]
pub enum SpatialRows {
    /// Six joints.
    Six(Vec<Row<Spatial, 6>>),
    /// Seven joints.
    Seven(Vec<Row<Spatial, 7>>),
    /// Eight joints.
    Eight(Vec<Row<Spatial, 8>>),
}

impl From<Vec<Row<Spatial, 6>>> for SpatialRows {
    fn from(rows: Vec<Row<Spatial, 6>>) -> Self {
        Self::Six(rows)
    }
}

impl From<Vec<Row<Spatial, 7>>> for SpatialRows {
    fn from(rows: Vec<Row<Spatial, 7>>) -> Self {
        Self::Seven(rows)
    }
}

impl From<Vec<Row<Spatial, 8>>> for SpatialRows {
    fn from(rows: Vec<Row<Spatial, 8>>) -> Self {
        Self::Eight(rows)
    }
}

/// What a spatial run gives back: its summary and the logged rows. (Beside the paper's
/// arm's `RunOutcome` because its scenario adds the arm and the target and its rows' joint
/// count is known only at run time.)
#[derive(Clone, Debug)]
pub struct SpatialOutcome {
    /// The scenario.
    pub scenario: SpatialScenario,
    /// The figures.
    pub summary: Summary,
    /// The logged steps.
    pub rows: SpatialRows,
}

impl SpatialOutcome {
    /// Renders the run's figures and `index.html` into `dir`.
    ///
    /// # Errors
    /// The arm cannot be built again (it was), or writing a file failed.
    pub fn render(&self, dir: &Path) -> Result<(), PlotError> {
        fn draw<const N: usize>(
            o: &SpatialOutcome,
            rows: &[Row<Spatial, N>],
            dir: &Path,
        ) -> Result<(), PlotError> {
            let chain = o.scenario.arm.chain::<f64, N>().map_err(PlotError::plotting)?;
            let figures = SpatialFigures { name: &o.scenario.name, rows, summary: &o.summary, chain: &chain };
            crate::domain::plots::spatial::render(dir, &figures)
        }
        match &self.rows {
            SpatialRows::Six(r) => draw(self, r, dir),
            SpatialRows::Seven(r) => draw(self, r, dir),
            SpatialRows::Eight(r) => draw(self, r, dir),
        }
    }
}

/// Builds and checks a spatial scenario, runs it, and writes its files into `dir` (and, with
/// `mcap`, the replay file, created before anything else is written: a path that cannot be
/// written stops the run); rejected steps beyond `max_rejected` (a fraction) make the
/// summary's verdict `failed`.
///
/// # Errors
/// A bad arm, parameter, target, plant or replay path (before anything is written), or an I/O
/// failure.
pub fn run_spatial(
    s: &SpatialScenario,
    dir: &Path,
    observer: &dyn Observer,
    max_rejected: f64,
    mcap: Option<&Path>,
) -> Result<(SpatialOutcome, Option<ReplaySummary>), SpatialRunError> {
    match s.arm.joints() {
        6 => run_n::<6>(s, dir, observer, max_rejected, mcap),
        7 => run_n::<7>(s, dir, observer, max_rejected, mcap),
        8 => run_n::<8>(s, dir, observer, max_rejected, mcap),
        n => Err(ArmError::JointCount { found: n }.into()),
    }
}

/// Builds the controller of `s` for `N` joints, in its scalar type on its platform, and runs.
fn run_n<const N: usize>(
    s: &SpatialScenario,
    dir: &Path,
    observer: &dyn Observer,
    max_rejected: f64,
    mcap: Option<&Path>,
) -> Result<(SpatialOutcome, Option<ReplaySummary>), SpatialRunError>
where
    SpatialArm<f64, N>: Manipulator<f64, N, Space = Spatial>,
    SpatialArm<f32, N>: Manipulator<f32, N, Space = Spatial>,
    SpatialRows: From<Vec<Row<Spatial, N>>>,
{
    let chain = s.arm.chain::<f64, N>()?;
    let controller = boxed_spatial_controller::<N>(&s.base.controller, &s.arm)?;
    let star = controller.target_in_effector();
    let mut plant = build_plant(s, &chain, &star)?;
    let kind = s.base.controller.platform;
    let replay = mcap.map(|p| Replay::<Spatial, N>::create(p, kind, chain)).transpose()?;
    let log =
        Log::<Spatial, N>::create(dir, kind, s.base.log_every, expected_rows(&s.base))?.with_replay(replay);
    let mut robot = Robot { plant: &mut plant, target_in_effector: star };
    let run = simulate(&s.base, &mut robot, controller, log, summary_for(s, &chain), observer, max_rejected)?;
    write_summary_files(s, &run.summary, &star, dir)?;
    let outcome = SpatialOutcome { scenario: s.clone(), summary: run.summary, rows: run.rows.into() };
    Ok((outcome, run.replay))
}

/// The summary of spatial scenario `s` for the arm `chain` (its name, the arm and its joint
/// limits), empty.
pub fn summary_for<const N: usize>(s: &SpatialScenario, chain: &Chain<f64, N>) -> SummaryAccumulator {
    let lower: Vec<f64> = chain.joints.iter().map(|j| j.lower).collect();
    let upper: Vec<f64> = chain.joints.iter().map(|j| j.upper).collect();
    SummaryAccumulator::new(&s.name, &lower, &upper).with_arm(s.arm.name())
}

/// Checks that `s` can run: the arm, the law's parameters, the target (its file, its height
/// against the arm's reach) and the plant — what [`run_spatial`] and the HIL plant check
/// before they write anything.
///
/// # Errors
/// [`SpatialError`], a bad arm, target file or parameter.
pub fn check(s: &SpatialScenario) -> Result<(), SpatialRunError> {
    fn n<const N: usize>(s: &SpatialScenario) -> Result<(), SpatialRunError>
    where
        SpatialArm<f64, N>: Manipulator<f64, N, Space = Spatial>,
        SpatialArm<f32, N>: Manipulator<f32, N, Space = Spatial>,
    {
        let star = target_in_effector::<N>(s)?;
        build_plant(s, &s.arm.chain::<f64, N>()?, &star).map(|_| ())
    }
    match s.arm.joints() {
        6 => n::<6>(s),
        7 => n::<7>(s),
        8 => n::<8>(s),
        j => Err(ArmError::JointCount { found: j }.into()),
    }
}

/// `r*_ed` of the spatial law for `s` exactly as its controller holds it (in the scenario's
/// scalar type, in `f64`): what the plant measures the true error against.
///
/// # Errors
/// A bad arm or parameter.
pub fn target_in_effector<const N: usize>(s: &SpatialScenario) -> Result<Pose3<f64>, SpatialControllerError>
where
    SpatialArm<f64, N>: Manipulator<f64, N, Space = Spatial>,
    SpatialArm<f32, N>: Manipulator<f32, N, Space = Spatial>,
{
    Ok(boxed_spatial_controller::<N>(&s.base.controller, &s.arm)?.target_in_effector())
}

/// The plant of `s` for the arm `chain` and a controller aiming at `star` (`r*_ed`): the
/// target resolved (the lifted one at the height where the arm at home holds it), the start
/// (platform at the origin, the car's steering matched, joints at home or the file's), and
/// the target's height range checked against the arm's reach.
///
/// # Errors
/// [`SpatialError`], a bad target file, a bad plant parameter.
pub fn build_plant<const N: usize>(
    s: &SpatialScenario,
    chain: &Chain<f64, N>,
    star: &Pose3<f64>,
) -> Result<SpatialPlant<N>, SpatialRunError> {
    let home = chain.home();
    let height = chain.end_effector(&home).compose(star).translation[2];
    let (target, joints) = match &s.target {
        SpatialTargetChoice::Lifted(t) => (SpatialTarget::Lifted(LiftedTrajectory::new(*t, height)), home),
        SpatialTargetChoice::File(path) => {
            let p = PiecewiseTrajectory::<Spatial>::load(path)
                .map_err(|source| SpatialRunError::TargetFile { path: path.clone(), source })?;
            let q = match p.initial_joints() {
                None => home,
                Some(q) if q.len() == N => SVector::<f64, N>::from_column_slice(q),
                Some(q) => return Err(SpatialError::JointCount { expected: N, found: q.len() }.into()),
            };
            for (i, j) in chain.joints.iter().enumerate() {
                if q[i] <= j.lower || q[i] >= j.upper {
                    let e =
                        SpatialError::JointOutside { index: i, value: q[i], lower: j.lower, upper: j.upper };
                    return Err(e.into());
                }
            }
            (SpatialTarget::Piecewise(p), q)
        }
    };
    // A file without `r_bd`: trajectory 2's start in the plane, level, at the home height.
    let r_bd = target.initial_r_bd(&Pose3::new(Matrix3::identity(), Vector3::new(2.5, 1.0, height)));
    let (target_low, target_high) = match &target {
        SpatialTarget::Lifted(l) => (l.height - l.amplitude.abs(), l.height + l.amplitude.abs()),
        SpatialTarget::Piecewise(p) => p.height_range(&r_bd),
    };
    let distance = star.translation.norm();
    let (reach_low, reach_high) = vertical_reach(chain, distance);
    if target_low < reach_low || target_high > reach_high {
        let e = SpatialError::Unreachable { target_low, target_high, reach_low, reach_high, distance };
        return Err(e.into());
    }
    let steering =
        if s.base.controller.platform == PlatformKind::Car { matched_steering(&s.base) } else { 0.0 };
    let p = &s.base.plant;
    let imperfections = Imperfections {
        actuator_lag: p.actuator_lag,
        noise: None,
        wheel_scale_error: p.wheel_scale_error.unwrap_or(0.0),
        seed: p.seed.unwrap_or(1),
    };
    let config = PlantConfig::new(s.base.controller.platform).with_imperfections(imperfections);
    let initial = InitialConditions::<N, Spatial> {
        steering,
        ..InitialConditions::<N, Spatial>::in_space(Pose::identity(), r_bd, joints)
    };
    SpatialPlant::new(config, *chain, &initial, target).map_err(SpatialRunError::Plant)
}

/// Writes a spatial run's `summary.json` and `scenario.json` into `dir`; `star` is the
/// controller's `r*_ed` (its `timeseries.csv` written as the run went).
///
/// # Errors
/// An I/O failure.
pub fn write_summary_files(
    s: &SpatialScenario,
    summary: &Summary,
    star: &Pose3<f64>,
    dir: &Path,
) -> Result<(), RecordError> {
    let write = |name: &str, text: String| {
        let path = dir.join(name);
        std::fs::write(&path, text + "\n").map_err(|source| RecordError::Json { path, source })
    };
    write("summary.json", serde_json::to_string_pretty(summary)?)?;
    let described = serde_json::json!({
        "name": s.name,
        "arm": s.arm.name(),
        "joints": s.arm.joints(),
        "target": match &s.target {
            SpatialTargetChoice::Lifted(t) => format!("lifted trajectory {}", crate::domain::scenario::trajectory_number(*t)),
            SpatialTargetChoice::File(p) => p.display().to_string(),
        },
        "target_in_effector": { "xyz": star.translation.as_slice(), "distance": TARGET_DISTANCE },
        "base": s.base,
    });
    write("scenario.json", serde_json::to_string_pretty(&described)?)
}
