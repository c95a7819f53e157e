//! `companion sim`: controller and plant in one process — no IPC, fast, deterministic.
//!
//! The loop here ([`run_loop`]) is also the HIL plant's lockstep loop: only the way a
//! measurement becomes a [`StepReport`] differs ([`Exchange`]), so both write the same bytes.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use companion_core::{Measurement, Pose, Rpr};
use companion_plant::Plant;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use crate::control::{AnyController, StepReport, JOINTS};
use crate::record::{CommandSource, PlantSample, Recorder, Row, Summary, SummaryAccumulator};
use crate::scenario::{Choice, PlatformArg, Scalar, Scenario, ScenarioArgs, TargetSpec};

/// `companion sim` flags.
#[derive(Args, Clone, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    /// The scenario.
    pub scenario: ScenarioArgs,
    /// Run every paper run (trajectories 1 and 2 × a–d), b and d with the Ψ̇ term, the car-like
    /// and omnidirectional platforms, and write an index page laying them out like the paper's
    /// Figures 3–10. Scenario flags other than --dt, --scalar, --log-every are ignored.
    #[arg(long)]
    pub all: bool,
    /// Output folder (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Skip the plots (CSV and JSON only).
    #[arg(long)]
    pub no_plots: bool,
}

/// Turns a measurement into the controller's report: in process, or over the wire.
pub trait Exchange {
    /// The report for the measurement of step `n`.
    ///
    /// # Errors
    /// The controller could not be reached (HIL).
    fn exchange(&mut self, n: u64, meas: &Measurement<f64, JOINTS>) -> Result<StepReport>;
}

/// The controller in this process.
#[derive(Debug)]
pub struct InProcess {
    /// The controller.
    pub controller: AnyController,
    /// The control period (s).
    pub dt: f64,
}

impl Exchange for InProcess {
    #[inline]
    fn exchange(&mut self, _n: u64, meas: &Measurement<f64, JOINTS>) -> Result<StepReport> {
        Ok(self.controller.step(meas, self.dt))
    }
}

/// The plant of a scenario.
///
/// # Errors
/// A bad target file or plant parameter.
pub fn build_plant(s: &Scenario) -> Result<Plant<Rpr<f64>, JOINTS>> {
    crate::plant_setup::build(s)
}

/// The plant's state as recorded.
pub fn sample(plant: &Plant<Rpr<f64>, JOINTS>) -> PlantSample {
    PlantSample { end_effector: plant.end_effector(), ..summary_sample(plant) }
}

/// The plant's state for a step that is not logged: what the summary reads, without the
/// end effector's pose (its forward kinematics cost four sin/cos; the pose is left at the
/// identity).
fn summary_sample(plant: &Plant<Rpr<f64>, JOINTS>) -> PlantSample {
    let x = plant.truth();
    PlantSample {
        t: plant.time(),
        base: x.base,
        steering: x.steering,
        joints: x.joints,
        end_effector: Pose::identity(),
        target: x.target,
    }
}

/// Runs steps `0..=steps` of a scenario in lockstep: measure, exchange, record, advance.
///
/// # Errors
/// The exchange or the recorder failed.
pub fn run_loop<E: Exchange>(
    s: &Scenario,
    plant: &mut Plant<Rpr<f64>, JOINTS>,
    exchange: &mut E,
    recorder: &mut Recorder,
    progress: &ProgressBar,
) -> Result<()> {
    let steps = s.steps();
    for n in 0..=steps {
        let meas = plant.measure();
        let report = exchange.exchange(n, &meas)?;
        let last = n == steps;
        let plant_sample = if recorder.logs(n, last) { sample(plant) } else { summary_sample(plant) };
        let row = Row { plant: plant_sample, report, source: CommandSource::Fresh };
        recorder.record(n, &row, last)?;
        if n < steps {
            plant.advance(&report.command, s.dt);
        }
        if n % 4096 == 0 {
            progress.inc(4096.min(steps + 1 - n));
        }
    }
    recorder.flush()
}

/// The recorder for a scenario writing into `dir`.
///
/// # Errors
/// The folder or file cannot be created.
pub fn recorder_for(s: &Scenario, dir: &Path) -> Result<Recorder> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let params = s.controller.params::<f64>();
    let lim = params.joint_limits;
    let acc = SummaryAccumulator::new(
        &s.name,
        [lim.lower[0], lim.lower[1], lim.lower[2]],
        [lim.upper[0], lim.upper[1], lim.upper[2]],
    );
    #[allow(clippy::cast_possible_truncation)]
    let rows = (s.steps() / s.log_every) as usize + 2;
    Recorder::create(dir, s.controller.kind(), s.log_every, acc, rows)
}

/// Writes `summary.json` and `scenario.json` into `dir`.
///
/// # Errors
/// Writing failed.
pub fn write_summary(dir: &Path, s: &Scenario, summary: &Summary) -> Result<()> {
    let path = dir.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(summary)? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;
    let path = dir.join("scenario.json");
    std::fs::write(&path, serde_json::to_string_pretty(s)? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// The outcome of one simulated run.
#[derive(Debug)]
pub struct RunOutcome {
    /// The scenario.
    pub scenario: Scenario,
    /// Its summary.
    pub summary: Summary,
    /// The logged rows.
    pub rows: Vec<Row>,
}

/// Runs one scenario in process and writes its files into `dir`.
///
/// # Errors
/// A bad scenario or an I/O failure.
pub fn run_one(s: &Scenario, dir: &Path, progress: &ProgressBar) -> Result<RunOutcome> {
    let mut plant = build_plant(s)?;
    let controller =
        AnyController::new(&s.controller).map_err(|e| anyhow::anyhow!("invalid parameter: {e}"))?;
    let mut exchange = InProcess { controller, dt: s.dt };
    // The CSV is formatted on a thread of its own (a quarter of the work of a run).
    let mut recorder = recorder_for(s, dir)?.in_background()?;
    let start = Instant::now();
    run_loop(s, &mut plant, &mut exchange, &mut recorder, progress)?;
    let summary = recorder.summary.finish(start.elapsed().as_secs_f64());
    write_summary(dir, s, &summary)?;
    Ok(RunOutcome { scenario: s.clone(), summary, rows: std::mem::take(&mut recorder.rows) })
}

fn bar(len: u64) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} steps ({eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb
}

/// The scenarios of `--all`.
pub fn all_scenarios(base: &ScenarioArgs) -> Result<Vec<Scenario>> {
    let mut list = Vec::new();
    let mk = |traj: u8, choice: Choice, platform: PlatformArg, psidot: bool| -> Result<Scenario> {
        let mut a = base.clone();
        a.trajectory = traj;
        a.target_file = None;
        a.choice = choice;
        a.platform = platform;
        a.psi_rate_in_drift = psidot;
        a.duration = Some(if traj == 1 { 40.0 } else { 120.0 });
        Scenario::from_args(&a)
    };
    for traj in [1, 2] {
        for choice in [Choice::A, Choice::B, Choice::C, Choice::D] {
            list.push(mk(traj, choice, PlatformArg::Unicycle, false)?);
        }
        for choice in [Choice::B, Choice::D] {
            list.push(mk(traj, choice, PlatformArg::Unicycle, true)?);
        }
        list.push(mk(traj, Choice::A, PlatformArg::Car, false)?);
        list.push(mk(traj, Choice::C, PlatformArg::Car, false)?);
        list.push(mk(traj, Choice::A, PlatformArg::Omni, false)?);
        list.push(mk(traj, Choice::C, PlatformArg::Omni, false)?);
    }
    Ok(list)
}

/// `companion sim`.
///
/// # Errors
/// A bad flag, config file or I/O failure.
pub fn run(args: &SimArgs) -> Result<()> {
    if args.all {
        let list = all_scenarios(&args.scenario)?;
        let total: u64 = list.iter().map(|s| s.steps() + 1).sum();
        let pb = bar(total);
        let outcomes: Vec<RunOutcome> =
            list.par_iter().map(|s| run_one(s, &args.out.join(&s.name), &pb)).collect::<Result<Vec<_>>>()?;
        pb.finish_and_clear();
        if !args.no_plots {
            crate::plots::render_all(&args.out, &outcomes)?;
        }
        print_table(&outcomes);
        println!("wrote {} runs into {}", outcomes.len(), args.out.display());
        if !args.no_plots {
            println!("open {}", args.out.join("index.html").display());
        }
    } else {
        let s = Scenario::from_args(&args.scenario)?;
        let pb = bar(s.steps() + 1);
        let outcome = run_one(&s, &args.out, &pb)?;
        pb.finish_and_clear();
        if !args.no_plots {
            crate::plots::render_run(&args.out, &outcome)?;
        }
        print_table(std::slice::from_ref(&outcome));
        println!("wrote {}", args.out.display());
    }
    Ok(())
}

/// Prints one line per run with the main figures.
pub fn print_table(outcomes: &[RunOutcome]) {
    println!(
        "{:<26} {:>10} {:>10} {:>8} {:>9} {:>7} {:>8} {:>8} {:>9}",
        "run", "final|ep|", "max|ep|>20", "tracked", "path m", "v sgn", "max|v|", "max|w|", "wall s"
    );
    for o in outcomes {
        let s = &o.summary;
        println!(
            "{:<26} {:>10.2e} {:>10.2e} {:>7.1}% {:>9.2} {:>7} {:>8.3} {:>8.3} {:>9.3}",
            s.scenario,
            s.final_ep_norm,
            s.max_ep_norm_after_20s,
            100.0 * s.fraction_ep_below_1e_3_after_20s,
            s.path_length,
            s.v_sign_changes,
            s.max_abs_v,
            s.max_abs_omega,
            s.wall_time_s
        );
    }
}

/// Whether a scenario is one of the paper's eight (unicycle, trajectory 1 or 2, no Ψ̇ term).
pub fn is_paper_run(s: &Scenario) -> bool {
    matches!(s.target, TargetSpec::Paper(_))
        && s.controller.platform == PlatformArg::Unicycle
        && s.controller.scalar == Scalar::F64
        && s.controller.overrides.psi_rate_in_drift != Some(true)
}
