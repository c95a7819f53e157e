//! `companion settle`: one setting from many perturbed starts — how many settle, and the
//! spreads of the figures that say how well.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use companion_runtime::domain::spread::Spread;
use companion_runtime::study::starts::{self, Perturbation, Settle, SettleReport, Starts};

use super::args::ScenarioArgs;
use super::terminal::Terminal;

/// `companion settle` flags.
#[derive(Args, Clone, Debug)]
pub struct SettleArgs {
    #[command(flatten)]
    /// The run (as `sim --arm`): its trajectory, platform, config, limits; `--seed` seeds the
    /// starts.
    pub scenario: ScenarioArgs,
    /// ur5, panda, or a TOML or URDF file (a spatial arm)
    ///
    /// The arm, as `sim --arm` takes it: `ur5`, `panda`, a TOML arm file, or a URDF cut by
    /// --base-link/--tip-link (or the --config file's `[robot]` table). Its home is the one
    /// the starts are drawn around.
    #[arg(long, value_name = "ARM")]
    pub arm: String,
    /// How many starts.
    #[arg(long, default_value_t = 30, value_name = "N")]
    pub starts: usize,
    /// Each joint moved up to ± A (rad or m), or anywhere.
    ///
    /// Each start's home: every joint moved from the arm's home by a uniform draw within ± this
    /// (rad for a revolute joint, m for a prismatic one), kept out of the law's penalty margins
    /// near its limits (the robot's, or the narrower [controller.joint_limits]); 0 with --starts
    /// 1: the home itself. `anywhere`: every joint drawn uniformly between those margins. Seeded
    /// by --seed: start k is the same whatever --starts.
    #[arg(long, default_value = "0.1", value_name = "A|anywhere", allow_hyphen_values = true)]
    pub perturb: Perturbation,
    /// Settled: ‖e_p‖ below this from --settle-by on.
    #[arg(long, default_value_t = 1e-3, value_name = "TOL", allow_hyphen_values = true)]
    pub tolerance: f64,
    /// From when a settled run stays within --tolerance (s).
    #[arg(long, default_value_t = 20.0, value_name = "SECONDS", allow_hyphen_values = true)]
    pub settle_by: f64,
    /// Also write settle.json (every start, the spreads) here.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Worker threads [default: one per core].
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// `companion settle`.
///
/// # Errors
/// A bad flag, config or arm, or settle.json cannot be written.
pub fn run(args: &SettleArgs) -> Result<()> {
    let sc = &args.scenario;
    let Some(arm) = sc.arm_spec(&args.arm)? else {
        anyhow::bail!(
            "settle perturbs a spatial arm's home: give --arm ur5|panda|FILE (the paper's planar arm has a \
             fixed start; explore draws its starts)"
        );
    };
    let default_duration = if sc.trajectory == 2 && sc.target_file.is_none() { 120.0 } else { 40.0 };
    let s = sc.spatial_scenario(arm, default_duration, |b| b)?;
    let set = Starts::new(args.starts, args.perturb, sc.seed)?;
    let judge = Settle { tolerance: args.tolerance, after: args.settle_by };
    judge.check(s.base.duration)?;
    if let Some(out) = &args.out {
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(args.threads.unwrap_or(0)).build()?;
    let term = Terminal::bar_of(args.starts as u64, "starts", args.quiet);
    let report = pool.install(|| starts::settle(&s, &set, &judge, &term));
    term.finish();
    let report = report?;
    print(&report);
    if let Some(out) = &args.out {
        let path = out.join("settle.json");
        std::fs::write(&path, serde_json::to_string_pretty(&report)? + "\n")
            .with_context(|| format!("writing {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// One row of the spreads' table; `pct`: as percentages.
fn row(name: &str, s: Option<&Spread>, pct: bool) {
    let f = |x: f64| if pct { format!("{:>9.1} %", 100.0 * x) } else { format!("{x:>11.2e}") };
    match s {
        Some(s) => {
            println!("  {name:<22} {} {} {} {} {}", f(s.median), f(s.q1), f(s.q3), f(s.best), f(s.worst))
        }
        None => println!("  {name:<22} {:>11}", "n/a"),
    }
}

/// Prints the report: the count that settled, the spreads, each start that did not settle.
fn print(r: &SettleReport) {
    let st = &r.starts;
    let from = if st.is_home() {
        "the home itself".to_string()
    } else {
        format!("homes {} (seed {})", st.perturbation, st.seed)
    };
    println!(
        "{}: {} start(s), {from}: {} of {} settled (‖e_p‖ < {:e} from {} s on)",
        r.run,
        r.runs.len(),
        r.settled,
        r.runs.len(),
        r.settle.tolerance,
        r.settle.after
    );
    println!(
        "  {:<22} {:>11} {:>11} {:>11} {:>11} {:>11}",
        "over the starts", "median", "q1", "q3", "best", "worst"
    );
    row("final ‖e_p‖", r.final_ep_norm.as_ref(), false);
    row(&format!("max ‖e_p‖ from {} s", r.settle.after), r.max_ep_after.as_ref(), false);
    row(&format!("tracked from {} s", r.settle.after), r.tracked.as_ref(), true);
    row("limits acted ≥ 20 s", r.limits_fraction.as_ref(), true);
    row("accel./guard ≥ 20 s", r.beyond_saturation_fraction.as_ref(), true);
    println!("  tracked from {} s, mean over the starts: {:.1} %", r.settle.after, 100.0 * r.tracked_mean);
    for u in r.runs.iter().filter(|u| !u.settled) {
        let home: Vec<String> = u.home.iter().map(|q| format!("{q}")).collect();
        let why = match (&u.error, u.diverged_at, u.rejected_steps) {
            (Some(e), _, _) => format!("could not run: {e}"),
            (None, Some(t), _) => format!("diverged at {t:.2} s"),
            (None, None, n) if n > 0 => format!("{n} steps rejected"),
            _ => format!(
                "max ‖e_p‖ from {} s {:.2e}, final {:.2e}, tracked {:.1} %",
                r.settle.after,
                u.max_ep_after,
                u.final_ep_norm,
                100.0 * u.tracked
            ),
        };
        println!("  start {} did not settle: {why} (replay: sim … --home {})", u.index, home.join(","));
    }
}
