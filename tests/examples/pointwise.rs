//! The default law's pointwise distance from the continuous closed loop, beside its tracking
//! floor — the table of the book's precision chapter:
//!
//! ```text
//! cargo run --release -p companion-tests --example pointwise
//! ```
//!
//! For T1 (a), T2 (a) and T1 (c) (unicycle, the paper's parameters): the continuous closed
//! loop integrated by RK4 at 1e-5 s ([`companion_tests::pointwise::reference`]; its own
//! accuracy shown by the same at 2e-5 s), the default law at 2, 1, 0.5 and 0.25 ms, the
//! largest difference of any of `x_b`, `y_b`, `θ_b`, `q₁..q₃` over `t ∈ [0, 10]` s at the
//! 1 ms instants (the 2 ms instants for 2 ms), the observed order of each halving, and the
//! floor (the largest true ‖e_p‖ after 20 s of `companion sim`); then the same distances for
//! the literal sampling of the law (`--discretisation sampled`).

use companion_core::{PaperRun, PlatformKind};
use companion_plant::PaperTrajectory::{self, One, Two};
use companion_runtime::domain::scenario::Scenario;
use companion_tests::pointwise::{distance, every, reference, sampled, sampled_literal, worst};
use companion_tests::{scenario, summaries};
use rayon::prelude::*;

const PERIODS: [f64; 4] = [2e-3, 1e-3, 5e-4, 2.5e-4];
const STEP: f64 = 1e-5;
const DURATION: f64 = 10.0;

fn main() {
    let runs: [(PaperTrajectory, PaperRun, &str); 3] =
        [(One, PaperRun::A, "T1 (a)"), (Two, PaperRun::A, "T2 (a)"), (One, PaperRun::C, "T1 (c)")];
    // The references at 1e-5 s and 2e-5 s, sampled every millisecond.
    let refs: Vec<_> = runs
        .par_iter()
        .flat_map(|(t, r, _)| [(*t, *r, STEP), (*t, *r, 2.0 * STEP)])
        .map(|(t, r, step)| {
            let stride = (1e-3 / step).round() as usize;
            reference(t, r, step, DURATION, stride)
        })
        .collect();
    let list: Vec<(String, Scenario)> = runs
        .iter()
        .flat_map(|(t, r, _)| {
            PERIODS.iter().map(move |dt| {
                let s =
                    scenario(Scenario::builder(*t, *r, PlatformKind::Unicycle).dt(*dt).log_every(100_000));
                (format!("pointwise-{}-{dt}", s.name), s)
            })
        })
        .collect();
    let named: Vec<(&str, Scenario)> = list.iter().map(|(n, s)| (n.as_str(), s.clone())).collect();
    let floors = summaries(&named);
    println!("| run | reference 1e-5 vs 2e-5 s | 2 ms | 1 ms | 0.5 ms | 0.25 ms |");
    println!("|---|---|---|---|---|---|");
    for (i, (t, r, name)) in runs.iter().enumerate() {
        let fine = &refs[2 * i];
        let self_check = distance(fine, &refs[2 * i + 1]);
        let d: Vec<f64> = PERIODS
            .par_iter()
            .map(|dt| {
                let at = dt.max(1e-3);
                let (a, b) = (every(&sampled(*t, *r, *dt, DURATION), *dt, at), every(fine, 1e-3, at));
                if std::env::var_os("POINTWISE_WHERE").is_some() {
                    let (d, i, c) = worst(&a, &b);
                    let when = i as f64 * at;
                    eprintln!("{name} at {dt}: {d:.2e} at t = {when} s, component {c}");
                    for lo in [0.0, 0.1, 1.0] {
                        let k = (lo / at).round() as usize;
                        eprintln!("    after {lo} s: {:.2e}", distance(&a[k..], &b[k..]));
                    }
                }
                distance(&a, &b)
            })
            .collect();
        let cells: Vec<String> = d
            .iter()
            .enumerate()
            .map(|(k, v)| {
                let f = &floors[i * PERIODS.len() + k];
                if k == 0 {
                    format!("{v:.2e} (floor {:.2e})", f.max_ep_norm_after_20s)
                } else {
                    format!("{v:.2e} ÷{:.1} (floor {:.2e})", d[k - 1] / v, f.max_ep_norm_after_20s)
                }
            })
            .collect();
        println!("| {name} | {self_check:.1e} | {} |", cells.join(" | "));
    }
    // Beside it, the same distance for the literal sampling of the law (`--discretisation
    // sampled`, the law at the measured state): the continuous law's path at first order.
    println!("\nthe literal sampling (`--discretisation sampled`):\n");
    println!("| run | 2 ms | 1 ms | 0.5 ms | 0.25 ms | order of the last halving |");
    println!("|---|---|---|---|---|---|");
    for (i, (t, r, name)) in runs.iter().enumerate() {
        let fine = &refs[2 * i];
        let d: Vec<f64> = PERIODS
            .par_iter()
            .map(|dt| {
                let at = dt.max(1e-3);
                distance(&every(&sampled_literal(*t, *r, *dt, DURATION), *dt, at), &every(fine, 1e-3, at))
            })
            .collect();
        let cells: Vec<String> = d
            .iter()
            .enumerate()
            .map(|(k, v)| if k == 0 { format!("{v:.2e}") } else { format!("{v:.2e} ÷{:.1}", d[k - 1] / v) })
            .collect();
        let order = (d[2] / d[3]).log2();
        println!("| {name} | {} | {order:.2} |", cells.join(" | "));
    }
}
