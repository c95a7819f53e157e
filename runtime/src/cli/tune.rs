//! `companion tune`.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use companion_core::PaperRun;
use companion_plant::PaperTrajectory;
use companion_runtime::domain::controller::run_name;
use companion_runtime::domain::scenario::Target;
use companion_runtime::run::spatial::{self, SpatialTargetChoice};
use companion_runtime::study::starts::{Perturbation, Starts};
use companion_runtime::study::trial::SpatialSetup;
use companion_runtime::study::tune::{self, SetRun, TuneSpaceFile, Tuning};

use super::args::ScenarioArgs;
use super::terminal::Terminal;

/// `companion tune` flags.
#[derive(Args, Clone, Debug)]
pub struct TuneArgs {
    #[command(flatten)]
    /// The scenario the candidates run (platform, limits, config, dt); `--seed` seeds the
    /// design.
    pub scenario: ScenarioArgs,
    /// The runs, as trajectory and choice, e.g. 1a,1c,2c.
    ///
    /// The set of runs, as trajectory and choice, e.g. `1a,1c,2c` [default: trajectories 1 and
    /// 2 with --choice; with --target-file, that file with --choice].
    #[arg(long, value_name = "LIST", value_delimiter = ',')]
    pub runs: Vec<String>,
    /// A TOML file of the ranges to search.
    ///
    /// A TOML file of ranges to search: `[parameters]` knob = [low, high] (low > 0), and
    /// `[objective]` effort_weight and tolerance (‖e_p‖ below it is tracked, default 1e-3)
    /// [default: the platform's space — with a real base's acceleration limits also k_bar_1,
    /// d and alpha_rate; see the book's chapter "Explore and tune",
    /// docs/book/src/explore-tune.md].
    #[arg(long, value_name = "FILE")]
    pub space: Option<PathBuf>,
    /// rpr (default, the paper's), ur5, panda, or a TOML or URDF file
    ///
    /// The arm: `rpr` (the paper's planar arm), or a spatial arm (`ur5`, `panda`, an arm
    /// file), each run of the set as `sim --arm` runs it (its platform settings, the lifted
    /// trajectory or a spatial --target-file, the start at home). The knobs are the platform
    /// law's, `lambda` and the arm's `damping_below`.
    #[arg(long, default_value = "rpr", hide_default_value = true, value_name = "ARM")]
    pub arm: String,
    /// Candidate evaluations (each runs the whole set).
    #[arg(long, default_value_t = 200, value_name = "N")]
    pub budget: usize,
    /// Output folder: preset.toml, report.json, the front.
    ///
    /// Output folder: preset.toml, report.json, candidates.csv, pareto.svg.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Each run from N homes near the arm's (1: its home).
    ///
    /// Score each candidate from N starts per run: homes of the spatial --arm perturbed by up
    /// to --perturb, seeded by --seed (as `companion settle` draws them); the means are over
    /// the runs and their starts, and each run says how many of its starts settled. 1: the
    /// arm's home itself.
    #[arg(long, default_value_t = 1, value_name = "N")]
    pub starts: usize,
    /// Each joint moved up to ± A (rad or m), or anywhere.
    ///
    /// As `companion settle --perturb` draws them: each joint moved from the arm's home by a
    /// uniform draw within ± this, kept out of the law's penalty margins; `anywhere`: every joint
    /// drawn uniformly between those margins.
    #[arg(long, default_value = "0.1", value_name = "A|anywhere", allow_hyphen_values = true)]
    pub perturb: Perturbation,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

fn parse_run(text: &str) -> Result<(PaperTrajectory, PaperRun)> {
    let t = text.trim();
    let traj = match t.get(..1) {
        Some("1") => PaperTrajectory::One,
        Some("2") => PaperTrajectory::Two,
        _ => bail!("--runs: `{t}` must be a trajectory (1 or 2) and a choice (a–d), e.g. 1a"),
    };
    let choice = match t.get(1..) {
        Some("a") => PaperRun::A,
        Some("b") => PaperRun::B,
        Some("c") => PaperRun::C,
        Some("d") => PaperRun::D,
        _ => bail!("--runs: `{t}` must be a trajectory (1 or 2) and a choice (a–d), e.g. 1a"),
    };
    Ok((traj, choice))
}

/// `companion tune`.
///
/// # Errors
/// A bad flag, space file, or an I/O failure.
pub fn run(args: &TuneArgs) -> Result<()> {
    let sc = &args.scenario;
    let arm = args.scenario.arm_spec(&args.arm)?;
    let file = match &arm {
        // As `sim --arm`: the arm's platform settings where the config file has none.
        Some(a) => sc.config_file()?.with_arm_settings(a.platform_defaults()),
        None => sc.config_file()?,
    };
    let mut set: Vec<(String, Target, PaperRun)> = Vec::new();
    if args.runs.is_empty() {
        let choice: PaperRun = sc.choice.into();
        match &sc.target_file {
            Some(p) => set.push((format!("file{}", run_name(choice)), Target::File(p.clone()), choice)),
            None => {
                for (n, t) in [(1, PaperTrajectory::One), (2, PaperTrajectory::Two)] {
                    set.push((format!("{n}{}", run_name(choice)), Target::Paper(t), choice));
                }
            }
        }
    } else {
        for r in &args.runs {
            let (t, c) = parse_run(r)?;
            set.push((r.trim().to_string(), Target::Paper(t), c));
        }
    }
    let mut runs = Vec::new();
    for (name, target, choice) in set {
        let duration = match &target {
            Target::Paper(PaperTrajectory::One) => 40.0,
            _ => 120.0,
        };
        // A spatial run's planar scenario carries the platform law; its own target is unused
        // (a spatial --target-file is not a planar one).
        let (planar_target, spatial) = match (&arm, target) {
            (None, t) => (t, None),
            (Some(a), Target::Paper(t)) => (
                Target::Paper(t),
                Some(SpatialSetup { arm: a.clone(), target: SpatialTargetChoice::Lifted(t) }),
            ),
            (Some(a), Target::File(p)) => (
                Target::Paper(PaperTrajectory::One),
                Some(SpatialSetup { arm: a.clone(), target: SpatialTargetChoice::File(p) }),
            ),
        };
        let builder = sc.builder(file.clone(), planar_target, choice, sc.platform.into(), duration);
        let base = builder.clone().build().with_context(|| format!("run {name}"))?;
        if let Some(setup) = &spatial {
            // The run `sim --arm` would make, checked as it checks it.
            spatial::check(&setup.scenario(base.clone(), &[])?).with_context(|| format!("run {name}"))?;
        }
        runs.push(SetRun { name, builder, base, spatial });
    }
    let space = args.space.as_deref().map(|p| -> Result<TuneSpaceFile> {
        let text = std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
        toml::from_str(&text).with_context(|| format!("in space file {}", p.display()))
    });
    let space = space.transpose()?;
    let starts = match args.starts {
        1 => Starts::HOME,
        n => Starts::new(n, args.perturb, sc.seed)?,
    };
    let tuning = Tuning::new(runs, space.as_ref(), args.budget, sc.seed)?.with_starts(starts)?;
    let term = Terminal::bar_of(args.budget as u64, "candidates", args.quiet);
    let candidates = tuning.run(&term)?;
    term.finish();
    let report = tune::report::TuneReport::new(&tuning, candidates);
    tune::report::write(&args.out, &tuning, &report)?;
    match report.best() {
        Some(b) => {
            let values: Vec<String> =
                b.values.iter().map(|(k, v)| format!("{} = {v:.4}", k.name())).collect();
            println!("best of {} candidates: {}", report.candidates.len(), values.join(", "));
            for r in &b.runs {
                println!(
                    "  {}: tracked {:.1} %, settled from {} of {} start(s), rms |v| {:.3} m/s, {} maneuvers",
                    r.run,
                    100.0 * r.tracked,
                    r.settled,
                    r.starts,
                    r.rms_v,
                    r.maneuvers
                );
            }
            println!(
                "wrote {} (use it: --config {})",
                args.out.display(),
                args.out.join("preset.toml").display()
            );
        }
        None => bail!("no candidate satisfies the law's rules"),
    }
    Ok(())
}
