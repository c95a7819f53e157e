//! `companion sim`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use companion_runtime::domain::arm::SpatialArmSpec;
use companion_runtime::domain::record::{
    Failure, Replay, ReplaySummary, RunOutcome, Summary, LIMITS_ACTED_BEYOND,
};
use companion_runtime::domain::scenario::Target;
use companion_runtime::run::sim::{all_scenarios, run_one_replayed, run_one_with};
use companion_runtime::run::spatial::run_spatial;
use rayon::prelude::*;

use super::args::ScenarioArgs;
use super::exit::{EXIT_INTERRUPTED, EXIT_REJECTED};
use super::terminal::Terminal;

/// `companion sim` flags.
#[derive(Args, Clone, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    /// The scenario.
    pub scenario: ScenarioArgs,
    /// Every run of the paper, laid out as its Figures 3–10.
    ///
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
    /// Simulate a pure delay (s), told to the controller.
    ///
    /// Simulate a pure delay between a measurement and the moment its command takes effect
    /// (compute and transport; a bridge over a network adds 0.1–5 ms), in seconds: from 0 to
    /// 8 periods (and at most the law's max_delay, 50 ms). The controller is told it and
    /// predicts over it.
    #[arg(long, default_value_t = 0.0, value_name = "SECONDS", allow_hyphen_values = true)]
    pub delay: f64,
    /// With --delay: do not tell the controller.
    ///
    /// With --delay: do not tell the controller (to see what the delay does uncompensated).
    #[arg(long)]
    pub no_delay_compensation: bool,
    /// rpr (default, the paper's), ur5, panda, or a TOML or URDF file
    ///
    /// The arm: `rpr` (the paper's planar arm, §4), the presets `ur5` (6 joints) and `panda`
    /// (7 joints), or a TOML arm file of 6–8 joints (see examples/arms/ur5.toml), or a URDF file (.urdf) cut between --base-link and --tip-link with its --home (the book's "Your robot"). A spatial
    /// arm runs the SE(3) law of §5 on the paper's trajectory lifted with a 5 cm vertical
    /// sine at the arm's home height (--trajectory 1|2), or on a spatial --target-file of
    /// 6-DOF body twists (sim-plant/examples/target3d.toml); it writes top and side views.
    /// An arm carries the platform settings it needs where the paper's cannot work with its
    /// published joint speeds (`panda`: the unicycle's epsilon_2 = 0.8 m and its own Lemma 2
    /// parameters on the car); an arm file may carry `[unicycle]` and `[car]` tables as
    /// --config's, and a --config table of the same name overrides the arm's. What each
    /// preset carries and why, and what holds each arm back: the book's chapter "Spatial
    /// arms" (docs/book/src/spatial-arms.md).
    #[arg(long, default_value = "rpr", hide_default_value = true, value_name = "ARM")]
    pub arm: String,
    /// Also write the run as an MCAP file for Foxglove.
    ///
    /// Also write the run as an MCAP file for Foxglove (the robot in 3D: frame transforms,
    /// a scene, joint states, command, tracking error), one frame per row of timeseries.csv
    /// (so --log-every decimates it too). Folders are created if missing; a path that cannot
    /// be written is refused before the run starts.
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
}

/// `sim`'s duration when `--duration` is not given (s).
const DEFAULT_DURATION: f64 = 120.0;

/// `companion sim`: 0, 6 when a run's law rejected more than `--max-rejected` of its steps,
/// 130 when SIGINT or SIGTERM ended it early (its files are written up to that step).
///
/// # Errors
/// A bad flag, config file or I/O failure.
pub fn run(args: &SimArgs) -> Result<ExitCode> {
    companion_runtime::sys::signals::install_termination_handler()?;
    let acceptance = args.scenario.acceptance(0.0)?;
    if let Some(arm) = args.scenario.arm_spec(&args.arm)? {
        return run_spatial_cli(args, arm, acceptance.max_rejected);
    }
    let outcomes = run_scenarios(args, &acceptance)?;
    let mut code = 0;
    for o in &outcomes {
        for f in &o.summary.failures {
            eprintln!("warning: {}: RUN FAILED: {}", o.summary.scenario, f.describe());
            if matches!(f, Failure::Rejected { .. }) {
                code = EXIT_REJECTED;
            }
        }
    }
    if outcomes.iter().any(|o| o.summary.ended_early) {
        eprintln!("interrupted: the runs' files are written up to the step at which the signal came");
        code = EXIT_INTERRUPTED;
    }
    Ok(ExitCode::from(code))
}

fn run_scenarios(
    args: &SimArgs,
    acceptance: &companion_runtime::domain::record::Acceptance,
) -> Result<Vec<RunOutcome>> {
    if args.all {
        if let Some(path) = &args.mcap {
            anyhow::bail!(
                "--mcap writes one run, not the runs of --all: give the run's --trajectory, --choice and \
                 --platform without --all (--mcap {})",
                path.display()
            );
        }
        // Each run's builder has every flag applied; `all_scenarios` sets target, variant,
        // platform, duration and the Ψ̇ term.
        let a = &args.scenario;
        let file = a.config_file()?;
        let list = all_scenarios(&|t, c, p| {
            a.builder(file.clone(), Target::Paper(t), c, p, DEFAULT_DURATION)
                .delay(args.delay)
                .delay_compensation(!args.no_delay_compensation)
        })?;
        let total: u64 = list.iter().map(|s| s.steps() + 1).sum();
        let term = Terminal::bar(total, false);
        let outcomes: Vec<RunOutcome> = list
            .par_iter()
            .map(|s| run_one_with(s, &args.out.join(&s.name), &term, acceptance))
            .collect::<Result<Vec<_>, _>>()?;
        term.finish();
        if !args.no_plots {
            companion_runtime::domain::plots::render_all(&args.out, &outcomes)?;
        }
        print_table(&outcomes.iter().map(|o| &o.summary).collect::<Vec<_>>());
        println!("wrote {} runs into {}", outcomes.len(), args.out.display());
        if !args.no_plots {
            println!("open {}", args.out.join("index.html").display());
        }
        Ok(outcomes)
    } else {
        let a = &args.scenario;
        let b = a.builder(a.config_file()?, a.target(), a.choice.into(), a.platform.into(), DEFAULT_DURATION);
        let s = b.delay(args.delay).delay_compensation(!args.no_delay_compensation).build()?;
        // Created before the run, so that a path that cannot be written stops it here.
        let replay = args.mcap.as_deref().map(|p| Replay::for_scenario(p, &s)).transpose()?;
        let term = Terminal::bar(s.steps() + 1, false);
        let (outcome, replayed) = run_one_replayed(&s, &args.out, &term, acceptance, replay)?;
        term.finish();
        if let Some(r) = &replayed {
            print_replay(r);
        }
        if !args.no_plots {
            companion_runtime::domain::plots::render_run(&args.out, &outcome)?;
        }
        print_table(&[&outcome.summary]);
        println!("wrote {}", args.out.display());
        Ok(vec![outcome])
    }
}

/// `companion sim --arm ur5|panda|FILE`: one spatial run.
fn run_spatial_cli(args: &SimArgs, arm: SpatialArmSpec, max_rejected: f64) -> Result<ExitCode> {
    if args.all {
        anyhow::bail!("--all runs the paper's planar arm; it cannot be combined with --arm {}", args.arm);
    }
    let s = args.scenario.spatial_scenario(arm, DEFAULT_DURATION, |b| {
        b.delay(args.delay).delay_compensation(!args.no_delay_compensation)
    })?;
    let term = Terminal::bar(s.steps() + 1, false);
    // The replay file is created before the run writes anything: a path that cannot be
    // written stops it there.
    let run = run_spatial(&s, &args.out, &term, max_rejected, args.mcap.as_deref());
    term.finish();
    let (outcome, replayed) = run?;
    if let Some(r) = &replayed {
        print_replay(r);
    }
    if !args.no_plots {
        outcome.render(&args.out)?;
    }
    print_table(&[&outcome.summary]);
    let m = &outcome.summary;
    println!("wrote {}", args.out.display());
    let mut code = 0;
    for f in &m.failures {
        eprintln!("warning: {}: RUN FAILED: {}", m.scenario, f.describe());
        code = EXIT_REJECTED;
    }
    if m.ended_early {
        eprintln!("interrupted: the run's files are written up to the step at which the signal came");
        code = EXIT_INTERRUPTED;
    }
    Ok(ExitCode::from(code))
}

/// After a real-time run whose commands were held after 20 s: the maximum without the half
/// second after each held or stopped period (the law's floor apart from the scheduling).
fn print_clear_of_holds(steps_after: u64, clear_steps: u64, clear_max: f64) {
    if steps_after > 0 && clear_steps < steps_after {
        let max = if clear_steps > 0 { format!("{clear_max:.2e}") } else { "n/a".to_string() };
        println!(
            "  max|ep|>20 clear of holds (the {} s after each held or stopped period left out): {max} over {clear_steps} of {steps_after} steps",
            companion_runtime::domain::record::summary::CLEAR_OF_HOLDS_S
        );
    }
}

/// The table's "max ‖e_p‖ after 20 s" and "tracked" columns; `n/a` for a run with no step
/// after 20 s (its figures "after 20 s" say nothing).
fn after_20s_columns(steps_after: u64, max_ep: f64, tracked: f64) -> (String, String) {
    if steps_after > 0 {
        (format!("{max_ep:>10.2e}"), format!("{:>7.1}%", 100.0 * tracked))
    } else {
        (format!("{:>10}", "n/a"), format!("{:>8}", "n/a"))
    }
}

/// Says where the replay is and how to open it.
pub(super) fn print_replay(r: &ReplaySummary) {
    let mb = r.bytes as f64 / 1e6;
    println!(
        "wrote {} ({} frames, {mb:.1} MB): open it in Foxglove (File > Open local file), 3D panel on /tf and /scene",
        r.path.display(),
        r.frames
    );
}

/// `x` in a column of `width` with `precision` decimals, or in scientific notation when it
/// would not fit (a value of 1e300 must not break the table).
fn num(x: f64, width: usize, precision: usize) -> String {
    let fixed = format!("{x:>width$.precision$}");
    if fixed.len() <= width {
        fixed
    } else {
        format!("{x:>width$.2e}")
    }
}

/// Prints one line per run with the main figures: the paper's arm's (path, manoeuvres,
/// speeds), or a spatial arm's (the joint nearest its limit) — the first run's arm says which.
pub fn print_table(summaries: &[&Summary]) {
    let spatial = summaries.first().is_some_and(|s| s.arm.is_some());
    if spatial {
        println!(
            "{:<34} {:>10} {:>10} {:>8} {:>16} {:>9} {:>9}",
            "run", "final|ep|", "max|ep|>20", "tracked", "min margin (j)", "rejected", "wall s"
        );
    } else {
        println!(
            "{:<26} {:>10} {:>10} {:>8} {:>9} {:>7} {:>8} {:>8} {:>9}",
            "run", "final|ep|", "max|ep|>20", "tracked", "path m", "v sgn", "max|v|", "max|w|", "wall s"
        );
    }
    for s in summaries {
        let (after, tracked) =
            after_20s_columns(s.steps_after_20s, s.max_ep_norm_after_20s, s.fraction_ep_below_1e_3_after_20s);
        match &s.arm {
            Some(a) => println!(
                "{:<34} {:>10.2e} {after} {tracked} {:>11.4} ({}) {:>9} {}",
                s.scenario,
                s.final_ep_norm,
                a.smallest_joint_margin,
                a.smallest_margin_joint,
                s.rejected_steps,
                num(s.wall_time_s, 9, 3)
            ),
            None => println!(
                "{:<26} {:>10.2e} {after} {tracked} {} {:>7} {} {} {}",
                s.scenario,
                s.final_ep_norm,
                num(s.path_length, 9, 2),
                s.v_sign_changes,
                num(s.max_abs_v, 8, 3),
                num(s.max_abs_omega, 8, 3),
                num(s.wall_time_s, 9, 3)
            ),
        }
        print_clear_of_holds(
            s.steps_after_20s,
            s.steps_after_20s_clear_of_holds,
            s.max_ep_norm_after_20s_clear_of_holds,
        );
        if s.rejected_steps > 0 {
            println!("  {} steps rejected by the law: {}", s.rejected_steps, s.rejections.describe());
        }
        print_limits_acted(s);
    }
}

/// When the acceleration limits or the joint guard changed the law's command on more than
/// [`LIMITS_ACTED_BEYOND`] of the steps after 20 s: a line saying so (the run after 20 s is the
/// limits' as much as the law's).
fn print_limits_acted(s: &Summary) {
    let l = &s.limits_after_20s;
    if l.beyond {
        println!(
            "  the limits acted on {:.1} % of the steps after 20 s ({}): the acceleration limits or the joint \
             guard on {:.1} %, more than {:.0} %: what the run does after 20 s is theirs as much as the law's; if \
             it settled, the law does not guarantee it would again",
            100.0 * l.fraction,
            l.describe(s.steps_after_20s),
            100.0 * l.beyond_saturation_fraction,
            100.0 * LIMITS_ACTED_BEYOND
        );
    }
}
