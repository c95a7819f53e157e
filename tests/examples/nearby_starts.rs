//! The chaotic runs with the Ψ̇ term, by statistics over nearby starts (SPEC §4: runs (b) and
//! (d) are compared over many runs, never one by one) — the figures of the book's
//! "Reproducing the paper" and precision chapters on the Ψ̇ chatter:
//!
//! ```text
//! cargo run --release -p companion-tests --example nearby_starts [K] [PERIOD]
//! ```
//!
//! T1 (b), T2 (b) and T2 (d), each without and with the `Ψ̇ (h_s1 − h_s2)` term, under the
//! default law and the literal sampling (`--discretisation sampled`), from the `2K` starts
//! [`nearby_start`] `k = ±1…±K` (default `K = 12`, the starts of `docs/explore/alpha-step`)
//! at `PERIOD` (default 1 ms): the peak `|v|` (median, quartiles, range), the sign changes of
//! `v` (median, quartiles), the fraction of the time tracked after 20 s (mean ± sd), and the
//! paper's start alone beside them (one run of a chaotic run: not a statistic).
//! `tests/tests/paper_claims.rs`'s `psi_rate_term_makes_b_and_d_chatter` asserts on a subset.

use companion_core::PaperRun;
use companion_plant::PaperTrajectory::{One, Two};
use companion_runtime::domain::controller::DiscretisationConfig;
use companion_runtime::domain::record::Summary;
use companion_tests::{median, nearby_summaries};

/// The quartiles of `x` (medians of the lower and upper halves).
fn quartiles(x: &[f64]) -> (f64, f64) {
    let mut v = x.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    (median(&v[..n / 2]), median(&v[n.div_ceil(2)..]))
}

fn main() {
    let mut args = std::env::args().skip(1);
    let k_max: i32 = args.next().map_or(12, |a| a.parse().expect("K: a whole number of starts"));
    let period: f64 = args.next().map_or(1e-3, |a| a.parse().expect("PERIOD: seconds"));
    let starts: Vec<i32> = (-k_max..=k_max).collect(); // k = 0: the paper's start, apart
    let cases = [(One, PaperRun::B, "T1 (b)"), (Two, PaperRun::B, "T2 (b)"), (Two, PaperRun::D, "T2 (d)")];
    let laws = [(DiscretisationConfig::Midpoint, "default"), (DiscretisationConfig::Sampled, "sampled")];
    let mut out = Vec::new();
    for (t, r, _) in cases {
        for psidot in [false, true] {
            for (d, _) in laws {
                out.extend(nearby_summaries(t, r, d, psidot, period, &starts));
            }
        }
    }
    println!(
        "{} starts k = ±1…±{k_max} (target x and q₁(0) offset by k·1e-4 m, rad), period {period} s\n",
        2 * k_max
    );
    println!(
        "| run | law | peak \\|v\\| (m/s): median (quartiles; range) | paper's start | v sign changes: \
         median (quartiles) | paper's start | tracked after 20 s: mean ± sd | paper's start |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut rows = out.chunks(starts.len());
    for (_, _, name) in cases {
        for psidot in [false, true] {
            for (_, law) in laws {
                let runs: &[Summary] = rows.next().expect("one chunk per row");
                let paper = &runs[k_max as usize];
                let near: Vec<&Summary> =
                    runs.iter().zip(&starts).filter(|(_, k)| **k != 0).map(|(s, _)| s).collect();
                let peak: Vec<f64> = near.iter().map(|s| s.max_abs_v).collect();
                let signs: Vec<f64> = near.iter().map(|s| s.v_sign_changes as f64).collect();
                let tracked: Vec<f64> =
                    near.iter().map(|s| 100.0 * s.fraction_ep_below_1e_3_after_20s).collect();
                let n = tracked.len() as f64;
                let mean = tracked.iter().sum::<f64>() / n;
                let sd = (tracked.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
                let (p25, p75) = quartiles(&peak);
                let (s25, s75) = quartiles(&signs);
                let lo = peak.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = peak.iter().copied().fold(0.0, f64::max);
                let run = if psidot { format!("{name}+Ψ̇") } else { name.to_string() };
                println!(
                    "| {run} | {law} | {:.1} ({p25:.1}–{p75:.1}; {lo:.1}–{hi:.1}) | {:.1} | {:.0} ({s25:.0}–{s75:.0}) | \
                     {} | {mean:.1} ± {sd:.1} % | {:.1} % |",
                    median(&peak),
                    paper.max_abs_v,
                    median(&signs),
                    paper.v_sign_changes,
                    100.0 * paper.fraction_ep_below_1e_3_after_20s
                );
            }
        }
    }
}
