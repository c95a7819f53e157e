//! `companion explore` and `companion explore merge`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use companion_runtime::study::explore::{self, Exploration, Shard, SpaceFile, SpatialSetup};
use companion_runtime::sys::signals;

use super::args::ScenarioArgs;
use super::exit::{EXIT_FOLDER_BUSY, EXIT_INTERRUPTED};
use super::footer::{long_after, short_after};
use super::terminal::Terminal;

/// `companion explore` flags.
#[derive(Args, Clone, Debug)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct ExploreArgs {
    #[command(subcommand)]
    pub command: Option<ExploreCommand>,
    #[command(flatten)]
    pub run: ExploreRunArgs,
}

/// `companion explore merge`.
#[derive(Subcommand, Clone, Debug)]
pub enum ExploreCommand {
    /// Merge the shards of one exploration into the files of the unsharded run.
    ///
    /// Merge the folders of the shards of one exploration (`--shard K/N`) into the files an
    /// unsharded run writes, byte for byte. Every shard must be finished and intact.
    #[command(after_help = short_after("explore-tune.md"), after_long_help = long_after("explore-tune.md"))]
    Merge(MergeArgs),
}

/// `companion explore merge` flags.
#[derive(Args, Clone, Debug)]
pub struct MergeArgs {
    /// The shards' output folders.
    #[arg(required = true, value_name = "DIR")]
    pub dirs: Vec<PathBuf>,
    /// The merged output folder.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

/// The flags of one exploration.
#[derive(Args, Clone, Debug)]
pub struct ExploreRunArgs {
    #[command(flatten)]
    /// The scenario every sample starts from (its start and parameters are then sampled);
    /// `--seed` seeds the samples' draws (and the plant's noise, with --noise).
    pub scenario: ScenarioArgs,
    /// A TOML file of the ranges to sample.
    ///
    /// A TOML file of ranges to sample: `[initial]` (distance, bearing, heading, q1–q3,
    /// alpha_1, alpha_2, steering), `[parameters]` (epsilon, eta_1..3, k, epsilon_1,
    /// epsilon_2, k_bar_1..3, d, gain, lambda, stroke; with a spatial --arm joint_speed,
    /// reach and damping_below), `[map]` and `[judge]`. Without it: starts around the
    /// target (distance 0.5–6 m, any bearing and relative heading; the planar arm only).
    #[arg(long, value_name = "FILE")]
    pub space: Option<PathBuf>,
    /// rpr (default, the paper's), ur5, panda, or a TOML or URDF file
    ///
    /// The arm: `rpr` (the paper's planar arm), or a spatial arm (`ur5`, `panda`, an arm
    /// file) run as `sim --arm` runs it (its platform settings, the lifted --trajectory, the
    /// start at home). With a spatial arm the space file draws α(0) and parameters only, and
    /// may scale the arm: `joint_speed` (every joint's published speed times it) and `reach`
    /// (every length of the arm times it), to see what limits its tracking and by how much.
    #[arg(long, default_value = "rpr", hide_default_value = true, value_name = "ARM")]
    pub arm: String,
    /// How many samples.
    #[arg(long, default_value_t = 1000, value_name = "N")]
    pub samples: u64,
    /// Output folder; the same command again resumes it.
    ///
    /// Output folder: results.csv, summary.json, plots; run the same command again to resume
    /// after an interruption.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Only part K of N of the samples (explore merge joins them).
    ///
    /// Run only part K of N of the samples (for a cluster); `explore merge` joins the parts.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
    /// Worker threads [default: one per core].
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// `explore`'s duration when `--duration` is not given (s).
const DEFAULT_DURATION: f64 = 40.0;

/// `companion explore`.
///
/// # Errors
/// A bad flag, space file, or an I/O failure.
pub fn run(args: &ExploreArgs) -> Result<ExitCode> {
    if let Some(ExploreCommand::Merge(m)) = &args.command {
        let s = explore::merge(&m.dirs, &m.out)?;
        println!(
            "merged {} shards: {} samples, {} converged ({:.1} %); wrote {}",
            m.dirs.len(),
            s.samples,
            s.counts.converged,
            100.0 * s.converged_fraction,
            m.out.display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    let a = &args.run;
    let out = a.out.clone().context("--out DIR is required")?;
    let shard = a.shard.as_deref().map(Shard::parse).transpose()?.unwrap_or(Shard::WHOLE);
    let sc = &a.scenario;
    let (builder, spatial) = match sc.arm_spec(&a.arm)? {
        None => (
            sc.builder(
                sc.config_file()?,
                sc.target(),
                sc.choice.into(),
                sc.platform.into(),
                DEFAULT_DURATION,
            ),
            None,
        ),
        Some(arm) => {
            // The run `sim --arm` would make, checked as it checks it.
            sc.spatial_scenario(arm.clone(), DEFAULT_DURATION, |b| b)?;
            let (builder, target) = sc.spatial_parts(&arm, DEFAULT_DURATION)?;
            (builder, Some(SpatialSetup { arm, target }))
        }
    };
    let file = match (&a.space, &spatial) {
        (Some(p), _) => SpaceFile::load(p)?,
        (None, None) => SpaceFile::around_the_target(),
        (None, Some(_)) => anyhow::bail!(
            "a spatial --arm needs a --space file: its start is sim --arm's (the arm at home), so there are no \
             starts around the target to draw; draw parameters (e.g. joint_speed, reach, epsilon_1) instead"
        ),
    };
    let exploration = Exploration::with_arm(builder, spatial, &file, a.samples, sc.seed)?;
    signals::install_termination_handler()?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(a.threads.unwrap_or(0)).build()?;
    let mine = shard.samples(a.samples).count() as u64;
    let term = Terminal::bar_of(mine, "samples", a.quiet);
    let outcome = match pool.install(|| exploration.run(&out, shard, &term, &signals::termination_requested))
    {
        Ok(o) => o,
        Err(e) => {
            term.finish();
            return match e {
                explore::ExploreError::Busy(busy) => {
                    eprintln!("error: {busy}");
                    Ok(ExitCode::from(EXIT_FOLDER_BUSY))
                }
                e => Err(e.into()),
            };
        }
    };
    term.finish();
    for n in &outcome.notes {
        eprintln!("note: {n}");
    }
    let threads = pool.current_num_threads();
    if outcome.ran > 0 {
        // Per CPU second where the system tells it (a shared machine gives the cores to
        // others too), else per thread second of wall time.
        let (cpu, what) = match outcome.cpu_s.filter(|c| *c > 0.0) {
            Some(c) => (c, "CPU"),
            None => (outcome.wall_s * threads as f64, "thread"),
        };
        let per_hour = outcome.ran as f64 / cpu * 3600.0;
        let step_ns = cpu / outcome.steps.max(1) as f64 * 1e9;
        eprintln!(
            "ran {} samples in {:.1} s on {threads} threads, {cpu:.1} {what} s: {per_hour:.0} runs per {what}-hour, \
             {step_ns:.0} ns per closed-loop step{}",
            outcome.ran,
            outcome.wall_s,
            if outcome.resumed > 0 { format!(" ({} resumed from the journal)", outcome.resumed) } else { String::new() }
        );
    }
    match &outcome.summary {
        None => {
            eprintln!(
                "interrupted: {} of {mine} samples are in {}; run the same command again to resume",
                outcome.resumed + outcome.ran,
                out.join("journal.csv").display()
            );
            Ok(ExitCode::from(EXIT_INTERRUPTED))
        }
        Some(s) => {
            let c = &s.counts;
            println!(
                "{}: {} samples, {} converged ({:.1} %), {} not converged, {} diverged, {} rejected{}",
                s.scenario,
                s.samples,
                c.converged,
                100.0 * s.converged_fraction,
                c.not_converged,
                c.diverged,
                c.rejected,
                if c.invalid > 0 { format!(", {} invalid", c.invalid) } else { String::new() }
            );
            if let Some(t) = &s.settling_time_s {
                println!(
                    "settling time of the converged: median {:.2} s, 90 % {:.2} s, max {:.2} s",
                    t.median, t.p90, t.max
                );
            }
            println!("wrote {} (open {})", out.display(), out.join("index.html").display());
            Ok(ExitCode::SUCCESS)
        }
    }
}
