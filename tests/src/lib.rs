//! # companion-tests
//!
//! Cross-crate tests: the paper's claims on the eight reproduced runs, the car-like and
//! omnidirectional platforms, f32 against f64, determinism, the firmware check against the
//! host, and (in the runtime's own tests) the HIL loop end to end. This library holds the
//! helpers those tests share.

use std::path::PathBuf;

use companion_core::{PaperRun, PlatformKind};
use companion_plant::{PaperTrajectory, PAPER_INITIAL_JOINTS};
use companion_runtime::domain::controller::DiscretisationConfig;
use companion_runtime::domain::observe::Silent;
use companion_runtime::domain::record::{RunOutcome, Summary};
use companion_runtime::domain::scenario::{Scenario, ScenarioBuilder, Start};
use companion_runtime::run::sim::run_one;

pub mod fuzz;
pub mod modgraph;
pub mod pointwise;

/// The scenario `b` builds.
///
/// # Panics
/// If it is invalid (a test bug).
pub fn scenario(b: ScenarioBuilder) -> Scenario {
    b.build().unwrap_or_else(|e| panic!("bad test scenario: {e}"))
}

/// A fresh folder for a test's outputs, under the system's temporary folder.
pub fn out_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("companion-test-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temporary folder");
    dir
}

/// Runs a scenario in process, writing into a fresh folder named `tag` that is removed
/// afterwards.
///
/// # Panics
/// If the run fails (a test failure).
pub fn run(s: &Scenario, tag: &str) -> RunOutcome {
    let (outcome, dir) = run_in(s, tag);
    let _ = std::fs::remove_dir_all(dir);
    outcome
}

/// Runs a scenario in process, writing into a fresh folder named `tag`, which is returned.
///
/// # Panics
/// If the run fails (a test failure).
pub fn run_in(s: &Scenario, tag: &str) -> (RunOutcome, PathBuf) {
    let dir = out_dir(tag);
    let outcome = run_one(s, &dir, &Silent).unwrap_or_else(|e| panic!("run {tag} failed: {e:#}"));
    (outcome, dir)
}

/// Runs scenarios in parallel and returns their summaries in the same order.
pub fn summaries(list: &[(&str, Scenario)]) -> Vec<Summary> {
    use rayon::prelude::*;
    list.par_iter().map(|(tag, s)| run(s, tag).summary).collect()
}

/// The offset between nearby starts: `10⁻⁴` (m and rad).
pub const NEARBY_STEP: f64 = 1e-4;

/// A start near the paper's, for comparing chaotic runs by statistics (SPEC §4: runs (b) and
/// (d) are compared over many runs, never one by one): the target's initial `x` (seen from
/// the base) and `q₁(0)` offset by `k` [`NEARBY_STEP`]s (m and rad), the rest as the paper's.
/// `k = 0` is the paper's start; `docs/explore/alpha-step` used `k = ±1…±12`.
pub fn nearby_start(t: PaperTrajectory, k: i32) -> Start {
    let e = f64::from(k) * NEARBY_STEP;
    let r = t.initial_r_bd();
    let mut joints = PAPER_INITIAL_JOINTS;
    joints[0] += e;
    Start { target: [r.x + e, r.y, r.theta], joints, steering: None }
}

/// The summaries of the unicycle's `run` on `t` under `law`, with or without the Ψ̇ term, at
/// `period`, from the starts [`nearby_start`]`(t, k)` for each `k` of `starts`, in that order
/// (in parallel; one row logged in 10⁶ steps: only the summaries are read).
pub fn nearby_summaries(
    t: PaperTrajectory,
    run: PaperRun,
    law: DiscretisationConfig,
    psidot: bool,
    period: f64,
    starts: &[i32],
) -> Vec<Summary> {
    let list: Vec<(String, Scenario)> = starts
        .iter()
        .map(|&k| {
            let b = Scenario::builder(t, run, PlatformKind::Unicycle)
                .dt(period)
                .log_every(1_000_000)
                .discretisation(law)
                .psi_rate_in_drift(psidot)
                .start(nearby_start(t, k));
            let s = scenario(b);
            (format!("nearby-{}-{law:?}-{period}-{k}", s.name), s)
        })
        .collect();
    let refs: Vec<(&str, Scenario)> = list.iter().map(|(n, s)| (n.as_str(), s.clone())).collect();
    summaries(&refs)
}

/// The median of `x` (the mean of the two middle values for an even count; NaN if empty).
pub fn median(x: &[f64]) -> f64 {
    let mut v = x.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => f64::NAN,
        _ if n % 2 == 1 => v[n / 2],
        _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}
