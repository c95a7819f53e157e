//! The tracking floor against the control period for both discretisations — the figure and
//! the table of the book's precision chapter (docs/book/src/precision.md):
//!
//! ```text
//! cargo run --release -p companion-tests --example floors -- docs/book/src/img/floors.svg
//! ```
//!
//! Runs T1 (a), T1 (c) and T2 (a) (unicycle, the paper's parameters) at periods from 0.25
//! to 10 ms with `Discretisation::Midpoint` (the default) and `Sampled`, measures each
//! run's floor (the largest true ‖e_p‖ after 20 s), prints the table and the log-log slopes,
//! and draws the figure.

use companion_core::{PaperRun, PlatformKind};
use companion_plant::PaperTrajectory::{One, Two};
use companion_runtime::domain::controller::DiscretisationConfig;
use companion_runtime::domain::plots::{floor_plot, FloorCurve};
use companion_runtime::domain::scenario::Scenario;
use companion_tests::{scenario, summaries};

const PERIODS: [f64; 6] = [2.5e-4, 5e-4, 1e-3, 2e-3, 4e-3, 1e-2];

fn main() -> anyhow::Result<()> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "floors.svg".to_string());
    let mut curves = Vec::new();
    for (d, tag) in [(DiscretisationConfig::Midpoint, "midpoint"), (DiscretisationConfig::Sampled, "sampled")]
    {
        for (t, r, name) in
            [(One, PaperRun::A, "T1 (a)"), (One, PaperRun::C, "T1 (c)"), (Two, PaperRun::A, "T2 (a)")]
        {
            let list: Vec<(String, Scenario)> = PERIODS
                .iter()
                .map(|dt| {
                    let s = scenario(
                        Scenario::builder(t, r, PlatformKind::Unicycle)
                            .dt(*dt)
                            .discretisation(d)
                            .log_every(100_000),
                    );
                    (format!("floors-{tag}-{}-{dt}", s.name), s)
                })
                .collect();
            let refs: Vec<(&str, Scenario)> = list.iter().map(|(n, s)| (n.as_str(), s.clone())).collect();
            let points: Vec<(f64, f64)> =
                PERIODS.iter().zip(summaries(&refs)).map(|(dt, s)| (*dt, s.max_ep_norm_after_20s)).collect();
            let n = points.len() as f64;
            let (lx, ly): (Vec<f64>, Vec<f64>) = points.iter().map(|(x, y)| (x.ln(), y.ln())).unzip();
            let (mx, my) = (lx.iter().sum::<f64>() / n, ly.iter().sum::<f64>() / n);
            let slope = lx.iter().zip(&ly).map(|(x, y)| (x - mx) * (y - my)).sum::<f64>()
                / lx.iter().map(|x| (x - mx) * (x - mx)).sum::<f64>();
            println!("{name:7} {tag:9} slope {slope:.2}  floors (period ms: m)");
            for (dt, f) in &points {
                println!("          {:6.2}: {f:.2e}", dt * 1e3);
            }
            curves.push(FloorCurve {
                label: format!("{name} {tag}"),
                solid: d == DiscretisationConfig::Midpoint,
                points,
            });
        }
    }
    // Pair each run's two curves by colour: midpoint and sampled of the same run adjacent.
    let (mid, samp): (Vec<_>, Vec<_>) = curves.into_iter().partition(|c| c.solid);
    let paired: Vec<FloorCurve> = mid.into_iter().zip(samp).flat_map(|(a, b)| [a, b]).collect();
    floor_plot(std::path::Path::new(&out), &paired)?;
    println!("wrote {out}");
    Ok(())
}
