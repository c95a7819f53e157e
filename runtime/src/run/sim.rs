//! The in-process simulation (`companion sim`): controller and plant in one process — no IPC,
//! fast, deterministic — of either arm.
//!
//! The loop here ([`run_loop`]) is also the HIL plant's lockstep loop: only the way a
//! measurement becomes a [`StepReport`] differs ([`Exchange`]), so both write the same bytes.
//! It drives a [`Robot`] of either arm (the paper's planar arm is its 3-joint planar case,
//! a spatial arm `run::spatial`'s); [`simulate`] is one run in process with its records.

use std::convert::Infallible;
use std::ops::ControlFlow;
use std::path::Path;
use std::time::{Duration, Instant};

use companion_core::{Command, Measurement, PaperRun, Planar, PlatformKind, Space};
use companion_plant::{AdvanceError, PaperTrajectory, Simulated};

use crate::domain::controller::{AnyController, Law, StepReport, JOINTS};
use crate::domain::observe::Observer;
pub use crate::domain::plant_setup::build as build_plant;
use crate::domain::plant_setup::PlantSetupError;
use crate::domain::record::error::RecordError;
use crate::domain::record::recorder::{summary_for, Log};
use crate::domain::record::{
    write_summary, Acceptance, CommandSource, RecordWriter, Replay, ReplaySummary, Row, RowSink, RunOutcome,
    Summary, SummaryAccumulator, Task,
};
use crate::domain::scenario::{Scenario, ScenarioBuilder, ScenarioError};
pub use crate::run::robot::{sample, Robot};
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

/// Turns a measurement of an arm of `N` joints (targets in `S`) into the controller's report:
/// in process, or over the wire.
pub trait Exchange<const N: usize = JOINTS, S: Space<f64> = Planar> {
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
        meas: &Measurement<f64, N, S>,
    ) -> Result<ControlFlow<Self::End, StepReport<N>>, LinkError>;
}

/// The controller in this process: the paper's law ([`AnyController`], the default) or a
/// spatial one.
#[derive(Debug)]
pub struct InProcess<C = AnyController> {
    /// The controller.
    pub controller: C,
    /// The control period (s).
    pub dt: f64,
    /// The delay the controller is told (s): the scenario's, or 0 without compensation.
    pub delay: f64,
}

impl<C> InProcess<C> {
    /// `controller` stepped at the period of scenario `s`, told its delay unless `s` switched
    /// the compensation off.
    pub fn with(controller: C, s: &Scenario) -> Self {
        Self { controller, dt: s.dt, delay: s.told_delay() }
    }
}

impl InProcess {
    /// The controller of a scenario of the paper's arm.
    ///
    /// # Errors
    /// An invalid parameter.
    pub fn new(s: &Scenario) -> Result<Self, ScenarioError> {
        Ok(Self::with(AnyController::new(&s.controller).map_err(ScenarioError::Param)?, s))
    }

    /// The controller's report for `meas` (an in-process exchange cannot fail or end a run).
    #[inline]
    pub fn report(&mut self, meas: &Measurement<f64, JOINTS>) -> StepReport {
        self.controller.step(meas, self.dt, self.delay)
    }
}

impl<C: Law<N, S>, const N: usize, S: Space<f64>> Exchange<N, S> for InProcess<C> {
    type End = Infallible;

    #[inline]
    fn exchange(
        &mut self,
        _n: u64,
        meas: &Measurement<f64, N, S>,
    ) -> Result<ControlFlow<Infallible, StepReport<N>>, LinkError> {
        Ok(ControlFlow::Continue(self.controller.step(meas, self.dt, self.delay)))
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

/// Period `n` of `robot` with `command` sent at its start: through the pure `delay` if the
/// scenario has one (the command that was acting, then this one from when it arrives).
///
/// # Errors
/// The plant refused the step.
#[inline]
pub fn advance<P: Simulated<N, Space: Task>, const N: usize>(
    robot: &mut Robot<'_, P, N>,
    delay: Option<&mut DelayLine<N>>,
    n: u64,
    command: &Command<f64, N>,
    dt: f64,
) -> Result<(), AdvanceError> {
    match delay {
        None => robot.advance(command, command, 0.0, dt),
        Some(line) => {
            let (previous, current, within) = line.push(n, command);
            robot.advance(&previous, &current, within, dt)
        }
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

/// Runs steps `0..=steps` of scenario `s` in lockstep with the robot of either arm: measure,
/// exchange, record, advance (with `s`'s pure delay, if any). After SIGINT or SIGTERM (looked
/// for every 4096 steps, one atomic load) the step at hand is recorded as the last one, so
/// that the files end cleanly.
///
/// # Errors
/// The exchange or the recording failed, or the plant refused a step.
pub fn run_loop<
    P: Simulated<N, Space: Task>,
    E: Exchange<N, P::Space>,
    K: RowSink<P::Space, N>,
    const N: usize,
>(
    s: &Scenario,
    robot: &mut Robot<'_, P, N>,
    exchange: &mut E,
    sink: &mut K,
    observer: &dyn Observer,
) -> Result<LoopEnd<E::End>, LoopError> {
    let steps = s.steps();
    let mut delay = (s.delay > 0.0).then(|| DelayLine::<N>::new(s.delay, s.dt));
    for n in 0..=steps {
        let meas = robot.measure();
        let report = match exchange.exchange(n, &meas)? {
            ControlFlow::Continue(report) => report,
            ControlFlow::Break(end) => return Ok(LoopEnd::Ended(end)),
        };
        let interrupted =
            n % PROGRESS_EVERY == 0 && n < steps && crate::sys::signals::termination_requested();
        let last = n == steps || interrupted;
        let row = robot.row(&report, CommandSource::Fresh, sink.logs(n, last));
        sink.record(n, &row, last)?;
        if interrupted {
            return Ok(LoopEnd::Interrupted { last: n });
        }
        if n < steps {
            advance(robot, delay.as_mut(), n, &report.command, s.dt)?;
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
struct Background<S: Task, const N: usize> {
    summary: SummaryAccumulator,
    log: RecordWriter<Log<S, N>, S, N>,
}

impl<S: Task, const N: usize> RowSink<S, N> for Background<S, N> {
    fn log_every(&self) -> u64 {
        self.log.log_every()
    }

    #[inline]
    fn record(&mut self, n: u64, row: &Row<S, N>, last: bool) -> Result<(), RecordError> {
        self.summary.add(row);
        if self.logs(n, last) {
            self.log.record(n, row, last)?;
        }
        Ok(())
    }
}

/// What a simulation in process gives back: its summary (judged), logged rows and replay.
#[derive(Debug)]
pub struct Simulation<S: Task, const N: usize> {
    /// The summary.
    pub summary: Summary,
    /// The logged rows.
    pub rows: Vec<Row<S, N>>,
    /// The replay file, if one was written.
    pub replay: Option<ReplaySummary>,
}

/// One run of scenario `s` in process, of either arm: the robot against the controller in this
/// process, the summary over every step here, the logged rows (`log`, with its replay file if
/// any) written by a thread of their own; the summary judged against `max_rejected` (and
/// `ended_early` if SIGINT or SIGTERM cut the run short). The replay file is finished whether
/// the run succeeds or not: after an error part-way it holds the rows up to the error. The
/// caller writes `summary.json` and `scenario.json`.
///
/// # Errors
/// The loop or the recording failed.
pub fn simulate<P, C, const N: usize>(
    s: &Scenario,
    robot: &mut Robot<'_, P, N>,
    controller: C,
    log: Log<P::Space, N>,
    summary: SummaryAccumulator,
    observer: &dyn Observer,
    max_rejected: f64,
) -> Result<Simulation<P::Space, N>, LoopError>
where
    P: Simulated<N>,
    P::Space: Task,
    C: Law<N, P::Space>,
{
    let mut exchange = InProcess::with(controller, s);
    let log = RecordWriter::spawn(log, WRITER_RING, Duration::from_secs(1))?;
    let mut sink = Background { summary, log };
    let start = Instant::now();
    let looped = run_loop(s, robot, &mut exchange, &mut sink, observer);
    let finished = sink.log.finish();
    // The loop's error first: it says what went wrong (the writer's may only say that it
    // stopped). A log dropped here finishes its replay file as it goes.
    let end = looped?;
    let mut log = finished?;
    let replay = log.finish_replay().map_err(RecordError::from)?;
    let mut summary = sink.summary.finish(start.elapsed().as_secs_f64());
    summary.judge(end != LoopEnd::Completed, max_rejected);
    Ok(Simulation { summary, rows: log.rows, replay })
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
    replay: Option<Replay>,
) -> Result<(RunOutcome, Option<ReplaySummary>), SimError> {
    let mut plant = build_plant(s)?;
    let controller = AnyController::new(&s.controller).map_err(ScenarioError::Param)?;
    let mut robot = Robot::of(&mut plant, s);
    let log = Log::for_scenario(s, dir)?.with_replay(replay);
    let run = simulate(s, &mut robot, controller, log, summary_for(s), observer, acceptance.max_rejected)?;
    write_summary(dir, s, &run.summary)?;
    Ok((RunOutcome { scenario: s.clone(), summary: run.summary, rows: run.rows }, run.replay))
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
