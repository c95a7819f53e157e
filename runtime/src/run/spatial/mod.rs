//! Spatial runs (`companion sim --arm ur5|panda|FILE`, §5): the spatial law on a
//! [`SpatialPlant`] in one process — deterministic, like the planar [`sim`](crate::run::sim).
//!
//! A [`SpatialScenario`] is a planar [`Scenario`] (platform, run (a)–(d), scalar type,
//! period, duration, logging, config overrides of the platform law, plant imperfections)
//! plus the arm ([`SpatialArmSpec`]) and the spatial target. [`run_spatial`] builds and
//! checks everything — arm, law, plant, the target's height against the arm's reach — before
//! it writes anything, then runs steps `0..=steps` and writes `timeseries.csv`,
//! `summary.json` and `scenario.json` into the run's folder; the plots are the CLI's
//! choice (`plots::spatial`).
//!
//! A target outside the reachable workspace is not an error once the run has started: the
//! law stays finite (it damps near singular configurations and refuses steps at them), and
//! the summary reports the joint margins and the rejected steps.

pub mod replay;
pub mod stream;

use std::convert::Infallible;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Instant;

use companion_core::nalgebra::{Matrix3, SVector, Vector3};
use companion_core::{Chain, Manipulator, Measurement, PlatformKind, Pose, Pose3, Spatial, SpatialArm};
use companion_plant::{
    vertical_reach, Imperfections, LiftedTrajectory, PaperTrajectory, PiecewiseTrajectory, PlantConfig,
    PlantError, SpatialInitial, SpatialPlant, SpatialTarget, TrajectoryError,
};

use crate::domain::arm::{ArmError, SpatialArmSpec, MAX_JOINTS};
use crate::domain::controller::{
    boxed_spatial_controller, planar_only_keys, SpatialControllerError, SpatialStep, StepReport,
    TARGET_DISTANCE,
};
use crate::domain::observe::Observer;
use crate::domain::plant_setup::matched_steering;
use crate::domain::plots::spatial::SpatialFigures;
use crate::domain::record::spatial::{write_csv, SpatialAccumulator, SpatialRecord, SpatialSummary};
use crate::domain::record::CommandSource;
use crate::domain::scenario::Scenario;
use crate::run::sim::{DelayLine, LoopError};
use crate::transport::link::LinkError;

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
    /// A folder or `timeseries.csv` cannot be created.
    #[error("creating {}", path.display())]
    Create {
        /// The folder or file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// `timeseries.csv` cannot be written.
    #[error("writing {}", path.display())]
    Csv {
        /// The file.
        path: PathBuf,
        /// The CSV writer's error.
        #[source]
        source: csv::Error,
    },
    /// `summary.json` or `scenario.json` cannot be written.
    #[error("writing {}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The summary or the scenario cannot be put as JSON.
    #[error(transparent)]
    Serialize(#[from] serde_json::Error),
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

/// What a spatial run gives back: its summary and the logged records.
#[derive(Clone, Debug)]
pub struct SpatialOutcome {
    /// The scenario.
    pub scenario: SpatialScenario,
    /// The figures.
    pub summary: SpatialSummary,
    /// The logged steps.
    pub records: Vec<SpatialRecord>,
    /// The joints' limits `(lower, upper)`, for the plots.
    pub limits: Vec<(f64, f64)>,
}

impl SpatialOutcome {
    /// What the figures are drawn from.
    pub fn figures(&self) -> SpatialFigures<'_> {
        SpatialFigures {
            name: &self.scenario.name,
            records: &self.records,
            summary: &self.summary,
            limits: &self.limits,
        }
    }
}

/// Builds and checks a spatial scenario, runs it, and writes its files into `dir`; rejected
/// steps beyond `max_rejected` (a fraction) make the summary's verdict `failed`.
///
/// # Errors
/// A bad arm, parameter, target or plant (before anything is written), or an I/O failure.
pub fn run_spatial(
    s: &SpatialScenario,
    dir: &Path,
    observer: &dyn Observer,
    max_rejected: f64,
) -> Result<SpatialOutcome, SpatialRunError> {
    match s.arm.joints() {
        6 => run_n::<6>(s, dir, observer, max_rejected),
        7 => run_n::<7>(s, dir, observer, max_rejected),
        8 => run_n::<8>(s, dir, observer, max_rejected),
        n => Err(ArmError::JointCount { found: n }.into()),
    }
}

/// Builds the controller of `s` for `N` joints, in its scalar type on its platform, and runs.
fn run_n<const N: usize>(
    s: &SpatialScenario,
    dir: &Path,
    observer: &dyn Observer,
    max_rejected: f64,
) -> Result<SpatialOutcome, SpatialRunError>
where
    SpatialArm<f64, N>: Manipulator<f64, N, Space = Spatial>,
    SpatialArm<f32, N>: Manipulator<f32, N, Space = Spatial>,
{
    let chain = s.arm.chain::<f64, N>()?;
    let mut controller = boxed_spatial_controller::<N>(&s.base.controller, &s.arm)?;
    let star = controller.target_in_effector();
    let delay = if s.base.delay_compensation { s.base.delay } else { 0.0 };
    let mut exchange = InProcess { controller: controller.as_mut(), dt: s.base.dt, delay };
    let mut plant = build_plant(s, &chain, &star)?;
    let (outcome, failed) = execute(s, &mut plant, &star, &mut exchange, dir, observer, max_rejected)?;
    match failed {
        None => Ok(outcome),
        Some(Halt::Failed(e)) => Err(e.into()),
        Some(Halt::Ended(never)) => match never {},
    }
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

/// Turns a spatial measurement into the controller's report: in this process, or over the
/// wire (the HIL plant's lockstep exchange), so that both write the same bytes.
pub trait SpatialExchange<const N: usize> {
    /// Why an exchange may end the run early, as a value (as [`Exchange::End`]).
    ///
    /// [`Exchange::End`]: crate::run::sim::Exchange::End
    type End;

    /// The report for the measurement of step `n`, or the end of the run.
    ///
    /// # Errors
    /// The exchange itself failed (HIL: the transport).
    fn exchange(
        &mut self,
        n: u64,
        meas: &Measurement<f64, N, Spatial>,
    ) -> Result<ControlFlow<Self::End, StepReport<N>>, LinkError>;
}

/// Why [`execute`] stopped before its last step (its records up to there are kept and
/// written).
#[derive(Debug)]
pub enum Halt<X> {
    /// The exchange ended the run ([`SpatialExchange::End`]).
    Ended(X),
    /// The exchange or the plant failed.
    Failed(LoopError),
}

/// What [`execute`] gives back: the run's outcome, and why it stopped early if it did.
pub type Executed<X> = (SpatialOutcome, Option<Halt<X>>);

/// The controller in this process.
struct InProcess<'c, const N: usize> {
    controller: &'c mut (dyn SpatialStep<N> + Send),
    dt: f64,
    /// The delay the controller is told (s): the scenario's, or 0 without compensation.
    delay: f64,
}

impl<const N: usize> SpatialExchange<N> for InProcess<'_, N> {
    type End = Infallible;

    #[inline]
    fn exchange(
        &mut self,
        _n: u64,
        meas: &Measurement<f64, N, Spatial>,
    ) -> Result<ControlFlow<Infallible, StepReport<N>>, LinkError> {
        Ok(ControlFlow::Continue(self.controller.step(meas, self.dt, self.delay)))
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
    let initial = SpatialInitial { base: Pose::identity(), steering, joints, r_bd };
    SpatialPlant::new(config, *chain, &initial, target).map_err(SpatialRunError::Plant)
}

/// How often the loop reports progress and looks for SIGINT/SIGTERM (steps).
const PROGRESS_EVERY: u64 = 4096;

/// The record of the plant's current step and the controller's report; the frames only when
/// `frames` (logged steps).
pub(crate) fn record_of<const N: usize>(
    plant: &SpatialPlant<N>,
    star: &Pose3<f64>,
    report: &StepReport<N>,
    source: CommandSource,
    frames: bool,
) -> SpatialRecord {
    let st = plant.truth();
    let mut q = [0.0; MAX_JOINTS];
    let mut rates = [0.0; MAX_JOINTS];
    q[..N].copy_from_slice(st.joints.as_slice());
    rates[..N].copy_from_slice(report.command.joints.as_slice());
    let mut links = [Pose3::identity(); MAX_JOINTS];
    let mut effector = Pose3::identity();
    if frames {
        let (l, e) = plant.frames();
        links[..N].copy_from_slice(&l);
        effector = e;
    }
    let e_p = plant.tracking_error(star);
    SpatialRecord {
        t: st.t,
        joints: N,
        base: Pose3::from_planar(&st.base),
        heading: st.base.theta,
        steering: st.steering,
        q,
        links,
        effector,
        target: st.target,
        target_twist: st.target_velocity,
        command: report.command.platform,
        joint_rates: rates,
        e_p,
        ep_norm: e_p.norm(),
        h_s: report.h_s,
        joint_scale: report.joint_scale,
        saturation: report.saturation,
        error: report.error,
        source,
    }
}

/// Runs steps `0..=steps` of `plant` (built by [`build_plant`] for `r*_ed` = `star`):
/// measure, exchange, record, advance (the planar loop's order, with its `--delay`), and writes the run's files
/// into `dir`. The loop of `companion sim --arm` and of the lockstep HIL plant.
///
/// A failed exchange (the HIL controller lost) or a step the plant refused ends the loop
/// early: the files are written up to that step, and the error comes back beside the
/// outcome (whose summary says the run ended early).
///
/// # Errors
/// An I/O failure.
pub fn execute<const N: usize, X: SpatialExchange<N>>(
    s: &SpatialScenario,
    plant: &mut SpatialPlant<N>,
    star: &Pose3<f64>,
    exchange: &mut X,
    dir: &Path,
    observer: &dyn Observer,
    max_rejected: f64,
) -> Result<Executed<X::End>, SpatialRunError> {
    let (lower, upper) = limits(plant.chain());
    let mut acc = SpatialAccumulator::new(&s.name, s.arm.name(), &lower, &upper);
    let steps = s.steps();
    let every = s.base.log_every.max(1);
    let mut records = Vec::new();
    let start = Instant::now();
    let mut ended_early = false;
    let mut failed = None;
    // `--delay`: the commands take effect late, as in the planar loop.
    let mut delay = (s.base.delay > 0.0).then(|| DelayLine::<N>::new(s.base.delay, s.base.dt));
    for n in 0..=steps {
        let meas = plant.measure();
        let report = match exchange.exchange(n, &meas) {
            Ok(ControlFlow::Continue(r)) => r,
            Ok(ControlFlow::Break(end)) => {
                failed = Some(Halt::Ended(end));
                break;
            }
            Err(e) => {
                failed = Some(Halt::Failed(e.into()));
                break;
            }
        };
        let interrupted =
            n % PROGRESS_EVERY == 0 && n < steps && crate::sys::signals::termination_requested();
        let last = n == steps || interrupted;
        let logged = n % every == 0 || last;
        let rec = record_of(plant, star, &report, CommandSource::Fresh, logged);
        acc.add(&rec);
        if logged {
            records.push(rec);
        }
        if interrupted {
            ended_early = true;
            break;
        }
        if n < steps {
            let advanced = match &mut delay {
                None => plant.try_advance(&report.command, s.base.dt),
                Some(line) => {
                    let (previous, current, within) = line.push(n, &report.command);
                    plant.try_advance_delayed(&previous, &current, within, s.base.dt)
                }
            };
            if let Err(e) = advanced {
                failed = Some(Halt::Failed(e.into()));
                break;
            }
        }
        if n % PROGRESS_EVERY == 0 {
            observer.advance(PROGRESS_EVERY.min(steps + 1 - n));
        }
    }
    let summary = acc.finish(start.elapsed().as_secs_f64(), ended_early || failed.is_some(), max_rejected);
    let outcome = SpatialOutcome {
        scenario: s.clone(),
        summary,
        records,
        limits: lower.into_iter().zip(upper).collect(),
    };
    write_files(&outcome, star, dir)?;
    Ok((outcome, failed))
}

/// The joints' lower and upper limits.
pub fn limits<const N: usize>(chain: &Chain<f64, N>) -> (Vec<f64>, Vec<f64>) {
    (chain.joints.iter().map(|j| j.lower).collect(), chain.joints.iter().map(|j| j.upper).collect())
}

/// Writes a spatial run's `timeseries.csv`, `summary.json` and `scenario.json` into `dir`
/// (created if missing); `star` is the controller's `r*_ed`.
///
/// # Errors
/// An I/O failure.
pub fn write_files(o: &SpatialOutcome, star: &Pose3<f64>, dir: &Path) -> Result<(), SpatialRunError> {
    std::fs::create_dir_all(dir)
        .map_err(|source| SpatialRunError::Create { path: dir.to_path_buf(), source })?;
    let csv = dir.join("timeseries.csv");
    let file = match std::fs::File::create(&csv) {
        Ok(f) => f,
        Err(source) => return Err(SpatialRunError::Create { path: csv, source }),
    };
    write_csv(std::io::BufWriter::new(file), &o.records)
        .map_err(|source| SpatialRunError::Csv { path: csv, source })?;
    write_summary_files(o, star, dir)
}

/// Writes a spatial run's `summary.json` and `scenario.json` into `dir` (its
/// `timeseries.csv` written as the run went: [`stream`]).
///
/// # Errors
/// An I/O failure.
pub fn write_summary_files(o: &SpatialOutcome, star: &Pose3<f64>, dir: &Path) -> Result<(), SpatialRunError> {
    let s = &o.scenario;
    let path = dir.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&o.summary)? + "\n")
        .map_err(|source| SpatialRunError::Json { path, source })?;
    let path = dir.join("scenario.json");
    let described = serde_json::json!({
        "name": s.name,
        "arm": s.arm.name(),
        "joints": o.limits.len(),
        "target": match &s.target {
            SpatialTargetChoice::Lifted(t) => format!("lifted trajectory {}", crate::domain::scenario::trajectory_number(*t)),
            SpatialTargetChoice::File(p) => p.display().to_string(),
        },
        "target_in_effector": { "xyz": star.translation.as_slice(), "distance": TARGET_DISTANCE },
        "base": s.base,
    });
    std::fs::write(&path, serde_json::to_string_pretty(&described)? + "\n")
        .map_err(|source| SpatialRunError::Json { path, source })?;
    Ok(())
}
