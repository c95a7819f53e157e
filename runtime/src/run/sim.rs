//! The in-process simulation (`companion sim`): controller and plant in one process — no IPC,
//! fast, deterministic.
//!
//! The loop here ([`run_loop`]) is also the HIL plant's lockstep loop: only the way a
//! measurement becomes a [`StepReport`] differs ([`Exchange`]), so both write the same bytes.

use std::convert::Infallible;
use std::ops::ControlFlow;
use std::path::Path;
use std::time::{Duration, Instant};

use companion_core::{Command, Measurement, PaperRun, PlatformKind, Pose, Rpr};
use companion_plant::{AdvanceError, PaperTrajectory, Plant};

use crate::domain::controller::{AnyController, StepReport, JOINTS};
use crate::domain::observe::Observer;
pub use crate::domain::plant_setup::build as build_plant;
use crate::domain::plant_setup::PlantSetupError;
use crate::domain::record::error::RecordError;
use crate::domain::record::recorder::{summary_for, Log};
use crate::domain::record::verdict::rejection_failure;
use crate::domain::record::{
    write_summary, Acceptance, CommandSource, PlanarReplay, PlantSample, RecordWriter, ReplaySummary, Row,
    RowSink, RunOutcome, SummaryAccumulator,
};
use crate::domain::scenario::{Scenario, ScenarioBuilder, ScenarioError};
use crate::transport::link::LinkError;

/// Why [`run_loop`] stopped on an error (its ends, SIGINT among them, are [`LoopEnd`]s).
#[derive(Debug, thiserror::Error)]
pub enum LoopError {
    /// The exchange failed (HIL: the transport).
    #[error(transparent)]
    Link(#[from] LinkError),
    /// A row cannot be recorded.
    #[error(transparent)]
    Record(#[from] RecordError),
    /// The plant refused a step.
    #[error(transparent)]
    Advance(#[from] AdvanceError),
}

/// Why a simulation in process ([`run_one`]) failed.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The scenario's plant cannot be built.
    #[error(transparent)]
    Setup(#[from] PlantSetupError),
    /// The scenario's controller cannot be built.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The run's files cannot be written.
    #[error(transparent)]
    Record(#[from] RecordError),
    /// The loop failed.
    #[error(transparent)]
    Loop(#[from] LoopError),
}

/// Turns a measurement into the controller's report: in process, or over the wire.
pub trait Exchange {
    /// Why an exchange may end the run before its last step, as a value the loop hands back
    /// ([`LoopEnd::Ended`]): the HIL plant's lost or refusing controller
    /// ([`PlantEnd`](crate::run::hil::PlantEnd)); [`Infallible`] in process.
    type End;

    /// The report for the measurement of step `n`, or the end of the run.
    ///
    /// # Errors
    /// The exchange itself failed (HIL: the transport).
    fn exchange(
        &mut self,
        n: u64,
        meas: &Measurement<f64, JOINTS>,
    ) -> Result<ControlFlow<Self::End, StepReport>, LinkError>;
}

/// The controller in this process.
#[derive(Debug)]
pub struct InProcess {
    /// The controller.
    pub controller: AnyController,
    /// The control period (s).
    pub dt: f64,
    /// The delay the controller is told (s): the scenario's, or 0 without compensation.
    pub delay: f64,
}

impl InProcess {
    /// The controller of a scenario.
    ///
    /// # Errors
    /// An invalid parameter.
    pub fn new(s: &Scenario) -> Result<Self, ScenarioError> {
        let controller = AnyController::new(&s.controller).map_err(ScenarioError::Param)?;
        Ok(Self { controller, dt: s.dt, delay: if s.delay_compensation { s.delay } else { 0.0 } })
    }

    /// The controller's report for `meas` (an in-process exchange cannot fail or end a run).
    #[inline]
    pub fn report(&mut self, meas: &Measurement<f64, JOINTS>) -> StepReport {
        self.controller.step(meas, self.dt, self.delay)
    }
}

impl Exchange for InProcess {
    type End = Infallible;

    #[inline]
    fn exchange(
        &mut self,
        _n: u64,
        meas: &Measurement<f64, JOINTS>,
    ) -> Result<ControlFlow<Infallible, StepReport>, LinkError> {
        Ok(ControlFlow::Continue(self.report(meas)))
    }
}

/// A pure delay between the controller and the plant: the commands sent, and which of them
/// act over a period. Command `k` (answering measurement `k`) acts over
/// `[t_k + τ, t_{k+1} + τ)`; with `τ = m·dt + r`, period `n` sees command `n − m − 1` for
/// its first `r` seconds and command `n − m` for the rest. Before the first command the
/// robot is at rest. A fixed ring: nothing allocates in the loop.
#[derive(Clone, Debug)]
pub struct DelayLine<const N: usize = JOINTS> {
    ring: [Command<f64, N>; DELAY_RING],
    whole: usize,
    rest: f64,
}

/// Commands the delay line remembers: a delay spans at most `HISTORY` periods.
const DELAY_RING: usize = companion_core::HISTORY + 2;

impl<const N: usize> DelayLine<N> {
    /// A delay of `delay` seconds at period `dt` (`0 ≤ delay ≤ HISTORY·dt`, checked by the
    /// scenario).
    pub fn new(delay: f64, dt: f64) -> Self {
        let whole = ((delay / dt).floor() as usize).min(DELAY_RING - 2);
        let mut rest = delay - whole as f64 * dt;
        if rest < dt * 1e-9 {
            rest = 0.0;
        }
        Self { ring: [Command::zero(); DELAY_RING], whole, rest }
    }

    /// Remembers command `n` and returns `(previous, current, delay within the period)` for
    /// period `n`.
    #[inline]
    pub fn push(&mut self, n: u64, command: &Command<f64, N>) -> (Command<f64, N>, Command<f64, N>, f64) {
        let slot = |k: u64| (k % DELAY_RING as u64) as usize;
        self.ring[slot(n)] = *command;
        let at = |back: usize| {
            let k = n.checked_sub(back as u64);
            k.map_or(Command::zero(), |k| self.ring[slot(k)])
        };
        (at(self.whole + 1), at(self.whole), self.rest)
    }
}

/// The plant's state as recorded, with the true tracking error for the desired pose
/// `target_in_effector` (`r*_ed`).
pub fn sample(plant: &Plant<Rpr<f64>, JOINTS>, target_in_effector: &Pose<f64>) -> PlantSample {
    PlantSample { end_effector: plant.end_effector(), ..summary_sample(plant, target_in_effector) }
}

/// The plant's state for a step that is not logged: what the summary reads, without the
/// end effector's pose (its forward kinematics cost four sin/cos; the pose is left at the
/// identity).
pub fn summary_sample(plant: &Plant<Rpr<f64>, JOINTS>, target_in_effector: &Pose<f64>) -> PlantSample {
    let x = plant.truth();
    PlantSample {
        t: plant.time(),
        base: x.base,
        steering: x.steering,
        joints: x.joints,
        end_effector: Pose::identity(),
        target: x.target,
        ep_norm: plant.tracking_error(target_in_effector).norm(),
    }
}

/// How often the loop reports progress and looks for SIGINT/SIGTERM (steps).
const PROGRESS_EVERY: u64 = 4096;

/// How [`run_loop`] ended; `X` is the exchange's [`Exchange::End`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopEnd<X = Infallible> {
    /// Every step ran.
    Completed,
    /// SIGINT or SIGTERM: the loop recorded step `last` as the last one and stopped.
    Interrupted {
        /// The last step recorded.
        last: u64,
    },
    /// The exchange ended the run (its step not recorded).
    Ended(X),
}

/// Runs steps `0..=steps` of a scenario in lockstep: measure, exchange, record, advance.
/// After SIGINT or SIGTERM (looked for every 4096 steps, one atomic load) the step at hand
/// is recorded as the last one, so that the files end cleanly.
///
/// # Errors
/// The exchange or the recording failed.
pub fn run_loop<E: Exchange, R: RowSink>(
    s: &Scenario,
    plant: &mut Plant<Rpr<f64>, JOINTS>,
    exchange: &mut E,
    sink: &mut R,
    observer: &dyn Observer,
) -> Result<LoopEnd<E::End>, LoopError> {
    let steps = s.steps();
    let mut delay = (s.delay > 0.0).then(|| DelayLine::new(s.delay, s.dt));
    let star = s.controller.params::<f64>().primary.target_in_effector;
    for n in 0..=steps {
        let meas = plant.measure();
        let report = match exchange.exchange(n, &meas)? {
            ControlFlow::Continue(report) => report,
            ControlFlow::Break(end) => return Ok(LoopEnd::Ended(end)),
        };
        let interrupted =
            n % PROGRESS_EVERY == 0 && n < steps && crate::sys::signals::termination_requested();
        let last = n == steps || interrupted;
        let plant_sample =
            if sink.logs(n, last) { sample(plant, &star) } else { summary_sample(plant, &star) };
        let row = Row { plant: plant_sample, report, source: CommandSource::Fresh };
        sink.record(n, &row, last)?;
        if interrupted {
            return Ok(LoopEnd::Interrupted { last: n });
        }
        if n < steps {
            match &mut delay {
                None => plant.advance(&report.command, s.dt),
                Some(line) => {
                    let (previous, current, within) = line.push(n, &report.command);
                    plant.try_advance_delayed(&previous, &current, within, s.dt)?;
                }
            }
        }
        if n % PROGRESS_EVERY == 0 {
            observer.advance(PROGRESS_EVERY.min(steps + 1 - n));
        }
    }
    Ok(LoopEnd::Completed)
}

/// The ring between the simulation and its CSV writer thread (logged rows).
const WRITER_RING: usize = 1 << 14;

/// The simulation's recording: the summary over every step on the loop's thread, the logged
/// rows to the writer thread (which formats the CSV, a quarter of the work of a run, in
/// parallel).
struct Background {
    summary: SummaryAccumulator,
    log: RecordWriter<Log>,
}

impl RowSink for Background {
    fn log_every(&self) -> u64 {
        self.log.log_every()
    }

    #[inline]
    fn record(&mut self, n: u64, row: &Row, last: bool) -> Result<(), RecordError> {
        self.summary.add(row);
        if self.logs(n, last) {
            self.log.record(n, row, last)?;
        }
        Ok(())
    }
}

/// Runs one scenario in process and writes its files into `dir`, held to the default
/// [`Acceptance`] (see [`run_one_with`]).
///
/// # Errors
/// A bad scenario or an I/O failure.
pub fn run_one(s: &Scenario, dir: &Path, observer: &dyn Observer) -> Result<RunOutcome, SimError> {
    run_one_with(s, dir, observer, &Acceptance::default())
}

/// Runs one scenario in process and writes its files into `dir`; the summary's `failures`
/// say whether the run met `acceptance` (and `ended_early`, whether SIGINT or SIGTERM cut it
/// short).
///
/// # Errors
/// A bad scenario or an I/O failure.
pub fn run_one_with(
    s: &Scenario,
    dir: &Path,
    observer: &dyn Observer,
    acceptance: &Acceptance,
) -> Result<RunOutcome, SimError> {
    run_one_replayed(s, dir, observer, acceptance, None).map(|(outcome, _)| outcome)
}

/// [`run_one_with`], writing the logged rows to `replay` too (`--mcap`). The replay file is
/// finished whether the run succeeds or not: after an error part-way it holds the rows up to
/// the error.
///
/// # Errors
/// A bad scenario or an I/O failure.
pub fn run_one_replayed(
    s: &Scenario,
    dir: &Path,
    observer: &dyn Observer,
    acceptance: &Acceptance,
    replay: Option<PlanarReplay>,
) -> Result<(RunOutcome, Option<ReplaySummary>), SimError> {
    let mut plant = build_plant(s)?;
    let mut exchange = InProcess::new(s)?;
    let log = Log::for_scenario(s, dir)?.with_replay(replay);
    let log = RecordWriter::spawn(log, WRITER_RING, Duration::from_secs(1))?;
    let mut sink = Background { summary: summary_for(s), log };
    let start = Instant::now();
    let looped = run_loop(s, &mut plant, &mut exchange, &mut sink, observer);
    let finished = sink.log.finish();
    // The loop's error first: it says what went wrong (the writer's may only say that it
    // stopped). A log dropped here finishes its replay file as it goes.
    let end = looped?;
    let mut log = finished?;
    let replayed = log.finish_replay().map_err(RecordError::from)?;
    let mut summary = sink.summary.finish(start.elapsed().as_secs_f64());
    summary.ended_early = end != LoopEnd::Completed;
    summary.failures.extend(rejection_failure(
        &summary.rejections,
        summary.steps,
        summary.first_rejection_at_s,
        acceptance.max_rejected,
    ));
    write_summary(dir, s, &summary)?;
    Ok((RunOutcome { scenario: s.clone(), summary, rows: log.rows }, replayed))
}

/// The scenarios of `companion sim --all`: every paper run (trajectories 1 and 2 × a–d), b and
/// d with the Ψ̇ term, the car-like platform with a–d and the omnidirectional one with a and c;
/// trajectory 1 for 40 s, trajectory 2 for 120 s. `base` makes each one's builder (and may set anything else).
///
/// # Errors
/// A scenario `base` makes is invalid.
pub fn all_scenarios(
    base: &dyn Fn(PaperTrajectory, PaperRun, PlatformKind) -> ScenarioBuilder,
) -> Result<Vec<Scenario>, ScenarioError> {
    let mut list = Vec::new();
    for traj in [PaperTrajectory::One, PaperTrajectory::Two] {
        let duration = if traj == PaperTrajectory::One { 40.0 } else { 120.0 };
        let mk = |choice, platform, psidot: bool| {
            let b = base(traj, choice, platform).duration(duration);
            if psidot { b.psi_rate_in_drift(true) } else { b }.build()
        };
        for choice in [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D] {
            list.push(mk(choice, PlatformKind::Unicycle, false)?);
        }
        for choice in [PaperRun::B, PaperRun::D] {
            list.push(mk(choice, PlatformKind::Unicycle, true)?);
        }
        for choice in [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D] {
            list.push(mk(choice, PlatformKind::Car, false)?);
        }
        list.push(mk(PaperRun::A, PlatformKind::Omni, false)?);
        list.push(mk(PaperRun::C, PlatformKind::Omni, false)?);
    }
    Ok(list)
}
