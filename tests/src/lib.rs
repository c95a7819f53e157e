//! # companion-tests
//!
//! Cross-crate tests: the paper's claims on the eight reproduced runs, the car-like and
//! omnidirectional platforms, f32 against f64, determinism, the firmware check against the
//! host, and (in the runtime's own tests) the HIL loop end to end. This library holds the
//! helpers those tests share.

use std::path::PathBuf;

use companion_runtime::domain::observe::Silent;
use companion_runtime::domain::record::{RunOutcome, Summary};
use companion_runtime::domain::scenario::{Scenario, ScenarioBuilder};
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
