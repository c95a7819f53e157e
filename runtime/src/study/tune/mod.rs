//! `companion tune`: a search for the controller's parameters — the transverse function's
//! (Lemma 1's `ε₁, ε₂`, Lemma 2's `ε, η₁, η₂, η₃`), the steering gain `k`, `K̄`, the gains —
//! on a set of runs, under a robot's velocity limits.
//!
//! **Objective.** Tracked fraction first, then effort: a candidate's cost is
//!
//! ```text
//! cost = (1 − mean tracked fraction) + w · mean rms |v|      (w = 0.01 s/m by default)
//! ```
//!
//! over the runs of the set, "tracked" being the fraction of steps after 20 s with
//! `‖e_p‖ < 1 mm` (as in `summary.json`; `[objective] tolerance` sets another bound); a run
//! that has a step rejected or touches a joint limit counts as tracked 0. With `w = 0.01` and
//! speeds below 1 m/s, effort decides only between candidates within one point of tracked
//! fraction of each other. The report keeps every candidate and their Pareto front (tracked
//! fraction against rms |v|).
//!
//! **Robust.** With a spatial arm and [`Tuning::with_starts`] (`--starts N`), each run of the
//! set runs from `N` homes perturbed within the arm's margins (`crate::study::starts`), and
//! the means are over the runs and their starts: a setting that settles from one home but not
//! from its neighbours scores as it deserves. Each run's score also says how many of its
//! starts settled (`‖e_p‖` below the tolerance on every step from 20 s on).
//!
//! **Where.** Within the space's box (each knob searched on a log scale: all are positive
//! quantities) and within the law's validity region — Lemma 2's `6η₂η₃ > 8η₃ + η₁η₂` for the
//! car and every other rule of `Params::validate`: a candidate the law rejects is not run.
//!
//! **How** (deterministic for a given seed, whatever the thread count):
//!
//! 1. the current parameters (the baseline), then a scrambled Halton sequence (a
//!    low-discrepancy design, shifted by the seed) over the box — half the budget — run in
//!    parallel;
//! 2. Nelder–Mead (argmin's) on the normalised box from each of the three best points so far
//!    in turn, each with a third of the rest of the budget (a simplex shrunk onto one point
//!    only measures noise; three starts keep some diversity). Each candidate runs its set's
//!    runs in parallel.
//!
//! Why these: the cost is a noisy, discontinuous function of the parameters (tracked
//! fractions jump when a manoeuvre succeeds or not; runs b and d are chaotic), so gradients
//! are useless; a space-filling design finds the good regions, and Nelder–Mead, which needs
//! only comparisons of costs, refines within one. argmin is a maintained, pure-Rust
//! optimisation library with a standard Nelder–Mead; its particle swarm would spend a budget
//! of a few hundred runs on tens of particles without refining.

pub mod report;

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use argmin::core::{CostFunction, Error as ArgminError, Executor};
use argmin::solver::neldermead::NelderMead;
use companion_core::PlatformKind;
use rand::rngs::ChaCha12Rng;
use rand::{Rng as _, SeedableRng};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::domain::observe::Observer;
use crate::domain::scenario::{Scenario, ScenarioBuilder};
use crate::run::spatial::SpatialScenario;
use crate::study::knobs::{self, ArmKind, Knob};
use crate::study::shared::{into_inner, lock, Poisoned};
use crate::study::starts::{self, Settle, StartRun, Starts, StartsError};
use crate::study::trial::{self, SpatialSetup};

/// Why a tuning cannot be set up or its search failed; every text is the message the
/// command line prints.
#[derive(Debug, thiserror::Error)]
pub enum TuneError {
    /// The set has no runs.
    #[error("tune needs at least one run in its set")]
    NoRuns,
    /// A key of `[parameters]` is not a knob of the platform: the reason.
    #[error("[parameters]: {0}")]
    Knob(String),
    /// A knob's range has an end that is not finite or not positive.
    #[error("`{knob}` = [{lo}, {hi}]: both ends must be finite and > 0 (knobs are searched on a log scale)")]
    NotPositive {
        /// The knob's name.
        knob: &'static str,
        /// The low end.
        lo: f64,
        /// The high end.
        hi: f64,
    },
    /// A knob's range is empty or reversed.
    #[error("`{knob}` = [{lo}, {hi}] is an empty range: the low end must be below the high end")]
    EmptyRange {
        /// The knob's name.
        knob: &'static str,
        /// The low end.
        lo: f64,
        /// The high end.
        hi: f64,
    },
    /// `objective.effort_weight` is negative or not finite.
    #[error("objective.effort_weight must be >= 0, got {0}")]
    EffortWeight(f64),
    /// `--budget` is below the number of knobs + 2.
    #[error("--budget {budget} is too small: at least {least} (the knobs + 2)")]
    Budget {
        /// The budget given.
        budget: usize,
        /// The least budget.
        least: usize,
    },
    /// No point of the space satisfies the law's rules: why its low corner does not.
    #[error(
        "no point of the space satisfies the law's rules (for the car, Lemma 2: 6 eta_2 eta_3 > 8 eta_3 + \
         eta_1 eta_2); e.g. at its low corner: {0}"
    )]
    NoValidPoint(String),
    /// Nelder–Mead cannot be set up (argmin's words).
    #[error(transparent)]
    Solver(Box<dyn std::error::Error + Send + Sync>),
    /// Nelder–Mead failed for another reason than the spent budget (argmin's words).
    #[error("Nelder–Mead: {cause}")]
    NelderMead {
        /// argmin's error.
        cause: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A run panicked while holding the archive.
    #[error(transparent)]
    Poisoned(#[from] Poisoned),
    /// `objective.tolerance` is not positive.
    #[error("objective.tolerance must be > 0, got {0}")]
    Tolerance(f64),
    /// Perturbed starts with the paper's planar arm.
    #[error(
        "--starts {0} perturbs a spatial arm's home: give --arm ur5|panda|FILE (the paper's planar arm starts \
         where its trajectory puts it; explore draws its starts)"
    )]
    PlanarStarts(usize),
    /// The starts cannot be drawn.
    #[error(transparent)]
    Starts(#[from] StartsError),
}

/// What the search's cost function returns to argmin when a start's share of the budget is
/// spent: the end of that start, not a failure.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("tune: budget spent")]
struct BudgetSpent;

/// A tune space file (`--space FILE`).
///
/// ```toml
/// [parameters]          # knob = [low, high], low > 0 (see companion_runtime::study::knobs)
/// epsilon = [0.05, 0.4]
/// eta_1 = [0.5, 50.0]
///
/// [objective]
/// effort_weight = 0.01  # s/m
/// ```
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TuneSpaceFile {
    /// Knob ranges.
    #[serde(default)]
    pub parameters: std::collections::BTreeMap<String, [f64; 2]>,
    /// The objective's weights.
    pub objective: Option<ObjectiveFile>,
}

/// The `[objective]` table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectiveFile {
    /// `w` (s/m): the weight of the mean rms |v| against the tracked fraction.
    pub effort_weight: Option<f64>,
    /// `‖e_p‖` below this is tracked (default 1e−3): `1e-6` asks a run to hold the target to a
    /// micrometre after 20 s, not merely to a millimetre.
    pub tolerance: Option<f64>,
}

/// The default effort weight `w` (s/m).
pub const EFFORT_WEIGHT: f64 = 0.01;

/// The default space of a platform; for a unicycle or a car whose run has platform
/// acceleration limits (a real base's, `--limits tiago`), also `K̄₁₁`, `D` and the phase-rate
/// cap `alpha_rate`, which shape the manoeuvres such a base can give (the issue's study).
pub fn default_space_for(platform: PlatformKind, accelerations: bool) -> Vec<(Knob, [f64; 2])> {
    let mut v = default_space(platform);
    if accelerations && platform != PlatformKind::Omni {
        v.extend([(Knob::KBar1, [0.1, 10.0]), (Knob::D, [0.1, 10.0]), (Knob::AlphaRate, [0.3, 10.0])]);
        v.sort_by_key(|(k, _)| *k);
    }
    v
}

/// The default space of a platform.
pub fn default_space(platform: PlatformKind) -> Vec<(Knob, [f64; 2])> {
    match platform {
        PlatformKind::Car => vec![
            (Knob::Epsilon, [0.04, 0.4]),
            (Knob::Eta1, [0.5, 50.0]),
            (Knob::Eta2, [1.34, 8.0]),
            (Knob::Eta3, [0.5, 80.0]),
            (Knob::K, [1.0, 50.0]),
            (Knob::KBar2, [1.0, 1000.0]),
            (Knob::KBar3, [1.0, 1000.0]),
        ],
        PlatformKind::Unicycle => vec![
            (Knob::Epsilon1, [0.05, 0.4]),
            (Knob::Epsilon2, [0.1, 2.0]),
            (Knob::KBar2, [0.1, 100.0]),
            (Knob::KBar3, [1.0, 1000.0]),
        ],
        PlatformKind::Omni => vec![(Knob::KBar3, [0.01, 100.0]), (Knob::D, [0.1, 10.0])],
    }
}

/// One run of the set: its name and its scenario's builder.
#[derive(Clone, Debug)]
pub struct SetRun {
    /// E.g. `1a`.
    pub name: String,
    /// The run's scenario before the knobs (with a spatial arm: its platform law's).
    pub builder: ScenarioBuilder,
    /// What the builder builds.
    pub base: Scenario,
    /// With a spatial arm (`tune --arm`): the arm and its target; the run is `sim --arm`'s.
    pub spatial: Option<SpatialSetup>,
}

/// A run of the set with the knobs set: the paper's arm's scenario, or a spatial arm's.
enum Built {
    Planar(Scenario),
    Spatial(SpatialScenario),
}

impl SetRun {
    /// The run with the knobs set to `values` from the home `home` (a spatial arm's; `None`:
    /// its own), judged by `settle`.
    fn start(&self, values: &[(Knob, f64)], index: usize, home: Option<&[f64]>, settle: &Settle) -> StartRun {
        let list = home.map(<[f64]>::to_vec).unwrap_or_default();
        match self.build(values) {
            Err(why) => StartRun::failed(index, list, why),
            Ok(Built::Spatial(sc)) => starts::run_from(&sc, index, home, settle),
            Ok(Built::Planar(s)) => match trial::run(&s, &settle.judge()) {
                Ok(t) => StartRun::of(index, list, &t),
                Err(e) => StartRun::failed(index, list, e.to_string()),
            },
        }
    }

    /// The run with the knobs set to `values`.
    ///
    /// # Errors
    /// The law or (with a spatial arm) the arm or the target refuse it: the message.
    fn build(&self, values: &[(Knob, f64)]) -> Result<Built, String> {
        let s = knobs::apply(&self.builder, &self.base, values).build().map_err(|e| e.to_string())?;
        match &self.spatial {
            None => Ok(Built::Planar(s)),
            Some(setup) => setup.scenario(s, values).map(Built::Spatial).map_err(|e| e.to_string()),
        }
    }

    /// Why the law (or, with a spatial arm, the arm, the target or the plant) refuses the
    /// knobs `values` (`None`: the run can be made).
    fn invalid(&self, values: &[(Knob, f64)]) -> Option<String> {
        match self.build(values) {
            Err(why) => Some(why),
            Ok(Built::Planar(_)) => None,
            Ok(Built::Spatial(sc)) => crate::run::spatial::check(&sc).err().map(|e| e.to_string()),
        }
    }
}

/// A run's figures for one candidate (over its starts: means, the smallest margin, the
/// rejected steps summed).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunScore {
    /// The run's name.
    pub run: String,
    /// Tracked fraction after 20 s (0 for a start with a step rejected or a joint limit
    /// touched), the mean over the starts.
    pub tracked: f64,
    /// The starts that settled.
    pub settled: usize,
    /// The starts.
    pub starts: usize,
    /// rms |v| (m/s), the mean over the starts.
    pub rms_v: f64,
    /// Maneuvers (the mean over the starts, rounded).
    pub maneuvers: u64,
    /// Rejected steps.
    pub rejected_steps: u64,
    /// Smallest joint margin (rad or m).
    pub min_joint_margin: f64,
}

/// One evaluated candidate.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Candidate {
    /// In evaluation order, from 0.
    pub index: usize,
    /// `baseline`, `design` or `refine`.
    pub stage: &'static str,
    /// The knobs' values.
    pub values: Vec<(Knob, f64)>,
    /// Per run (empty if the law rejects the parameters).
    pub runs: Vec<RunScore>,
    /// Mean tracked fraction.
    pub tracked: f64,
    /// The fraction of the runs' starts that settled.
    pub settled: f64,
    /// Mean rms |v| (m/s).
    pub effort: f64,
    /// The cost (lower is better; `+∞` if the law rejects the parameters).
    pub cost: f64,
    /// Why the law rejects the parameters, if it does.
    pub invalid: Option<String>,
}

/// A tuning: the set of runs, the space, the budget.
#[derive(Clone, Debug)]
pub struct Tuning {
    /// The runs of the set.
    pub runs: Vec<SetRun>,
    /// The knobs and their ranges.
    pub space: Vec<(Knob, [f64; 2])>,
    /// Candidate evaluations.
    pub budget: usize,
    /// The seed of the design's shift.
    pub seed: u64,
    /// `w` (s/m).
    pub effort_weight: f64,
    /// The starts each run runs from ([`Starts::HOME`] unless [`with_starts`](Self::with_starts)).
    pub starts: Starts,
    /// Their homes (`None`: the arm's own).
    homes: Vec<Option<Vec<f64>>>,
    /// When a run is tracked and settled: `[objective] tolerance`, from 20 s.
    pub settle: Settle,
}

impl Tuning {
    /// A tuning of `space` (the platform's default space if `None`) on `runs`.
    ///
    /// # Errors
    /// No runs, a budget below the number of knobs + 2, an unknown knob or one of another
    /// platform, an empty, reversed or non-positive range, or a space in which no point
    /// satisfies the law's rules (Lemma 2 for the car) — all before anything runs.
    pub fn new(
        runs: Vec<SetRun>,
        file: Option<&TuneSpaceFile>,
        budget: usize,
        seed: u64,
    ) -> Result<Self, TuneError> {
        let Some(first) = runs.first() else { return Err(TuneError::NoRuns) };
        let platform = first.base.controller.platform;
        let arm = if first.spatial.is_some() { ArmKind::Spatial } else { ArmKind::Planar };
        let accelerations = first
            .base
            .controller
            .acceleration
            .as_ref()
            .is_some_and(|a| a.forward.is_some() || a.lateral.is_some() || a.angular.is_some());
        let space = match file.filter(|f| !f.parameters.is_empty()) {
            None => default_space_for(platform, accelerations),
            Some(f) => {
                let mut v = Vec::new();
                for (name, r) in &f.parameters {
                    let k = Knob::parse_for(name, platform, arm).map_err(TuneError::Knob)?;
                    if matches!(k, Knob::JointSpeed | Knob::Reach) {
                        return Err(TuneError::Knob(format!(
                            "`{name}` scales the arm, not a setting of the law: tune searches the law's \
                             (`explore --arm` maps what the arm's speed and size do)"
                        )));
                    }
                    v.push((k, *r));
                }
                v.sort_by_key(|(k, _)| *k);
                v
            }
        };
        for (k, [lo, hi]) in &space {
            if !(lo.is_finite() && hi.is_finite() && *lo > 0.0) {
                return Err(TuneError::NotPositive { knob: k.name(), lo: *lo, hi: *hi });
            }
            if lo >= hi {
                return Err(TuneError::EmptyRange { knob: k.name(), lo: *lo, hi: *hi });
            }
        }
        let objective = file.and_then(|f| f.objective).unwrap_or_default();
        let effort_weight = objective.effort_weight.unwrap_or(EFFORT_WEIGHT);
        if !(effort_weight.is_finite() && effort_weight >= 0.0) {
            return Err(TuneError::EffortWeight(effort_weight));
        }
        let settle = Settle { tolerance: objective.tolerance.unwrap_or(1e-3), after: 20.0 };
        if !(settle.tolerance.is_finite() && settle.tolerance > 0.0) {
            return Err(TuneError::Tolerance(settle.tolerance));
        }
        if budget < space.len() + 2 {
            return Err(TuneError::Budget { budget, least: space.len() + 2 });
        }
        let t = Self {
            runs,
            space,
            budget,
            seed,
            effort_weight,
            starts: Starts::HOME,
            homes: vec![None],
            settle,
        };
        // The validity region must not be empty: look for one valid point of the design.
        let shift = t.shift();
        let valid = (1..=4096).any(|i| t.invalid(&t.values(&halton(i, &shift))).is_none());
        if !valid {
            let why = t.invalid(&t.values(&vec![0.0; t.space.len()])).unwrap_or_default();
            return Err(TuneError::NoValidPoint(why));
        }
        Ok(t)
    }

    /// Each run from `starts` (a spatial arm's perturbed homes; module docs).
    ///
    /// # Errors
    /// More than one start with the paper's planar arm, or homes that cannot be drawn.
    pub fn with_starts(mut self, starts: Starts) -> Result<Self, TuneError> {
        let first = &self.runs[0];
        self.homes = match &first.spatial {
            _ if starts.is_home() => vec![None],
            None => return Err(TuneError::PlanarStarts(starts.count)),
            Some(setup) => starts.homes(&setup.arm, &first.base.controller)?.into_iter().map(Some).collect(),
        };
        self.starts = starts;
        Ok(self)
    }

    /// The design's shift: one uniform number per knob from the seed.
    fn shift(&self) -> Vec<f64> {
        let mut rng = ChaCha12Rng::seed_from_u64(self.seed);
        (0..self.space.len()).map(|_| (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64).collect()
    }

    /// The knobs' values at normalised coordinates `x ∈ [0, 1]ⁿ` (log scale).
    pub fn values(&self, x: &[f64]) -> Vec<(Knob, f64)> {
        self.space
            .iter()
            .zip(x)
            .map(|((k, [lo, hi]), u)| (*k, lo * (hi / lo).powf(u.clamp(0.0, 1.0))))
            .collect()
    }

    /// The normalised coordinates of values (clamped to the box).
    fn coords(&self, values: &[(Knob, f64)]) -> Vec<f64> {
        self.space
            .iter()
            .map(|(k, [lo, hi])| {
                let v = values.iter().find(|(q, _)| q == k).map_or(*lo, |(_, v)| *v);
                ((v / lo).ln() / (hi / lo).ln()).clamp(0.0, 1.0)
            })
            .collect()
    }

    /// Why the law rejects these values in some run of the set (`None`: valid).
    fn invalid(&self, values: &[(Knob, f64)]) -> Option<String> {
        self.runs.iter().find_map(|r| r.invalid(values))
    }

    /// Evaluates one candidate (its runs in parallel).
    fn evaluate(&self, index: usize, stage: &'static str, values: Vec<(Knob, f64)>) -> Candidate {
        if let Some(why) = self.invalid(&values) {
            return Candidate {
                index,
                stage,
                values,
                runs: Vec::new(),
                tracked: 0.0,
                settled: 0.0,
                effort: f64::NAN,
                cost: f64::INFINITY,
                invalid: Some(why),
            };
        }
        // Every run from every start, in parallel.
        let jobs: Vec<(usize, usize)> =
            (0..self.runs.len()).flat_map(|r| (0..self.homes.len()).map(move |k| (r, k))).collect();
        let done: Vec<StartRun> = jobs
            .par_iter()
            .map(|&(r, k)| self.runs[r].start(&values, k, self.homes[k].as_deref(), &self.settle))
            .collect();
        let runs: Vec<RunScore> = self
            .runs
            .iter()
            .zip(done.chunks(self.homes.len().max(1)))
            .map(|(r, starts)| score(&r.name, starts))
            .collect();
        let n = runs.len() as f64;
        let tracked = runs.iter().map(|r| r.tracked).sum::<f64>() / n;
        let settled = runs.iter().map(|r| r.settled).sum::<usize>() as f64
            / runs.iter().map(|r| r.starts).sum::<usize>().max(1) as f64;
        let effort = runs.iter().map(|r| r.rms_v).sum::<f64>() / n;
        let cost = (1.0 - tracked) + self.effort_weight * effort;
        Candidate { index, stage, values, runs, tracked, settled, effort, cost, invalid: None }
    }

    /// Runs the search.
    ///
    /// # Errors
    /// The optimiser failed for a reason other than the budget.
    pub fn run(&self, observer: &dyn Observer) -> Result<Vec<Candidate>, TuneError> {
        let archive = Mutex::new(Vec::<Candidate>::new());
        let push = |c: Candidate| -> Result<Candidate, Poisoned> {
            observer.advance(1);
            lock(&archive, "lock")?.push(c.clone());
            Ok(c)
        };
        // 1. The baseline and the design.
        let d = self.space.len();
        let baseline: Vec<(Knob, f64)> =
            self.space.iter().map(|(k, _)| (*k, k.value(&self.runs[0].base))).collect();
        let shift = self.shift();
        let n_design = (self.budget / 2).max(d + 1).min(self.budget - 1);
        let mut design = Vec::with_capacity(n_design);
        let mut i = 1;
        while design.len() < n_design && i < 64 * self.budget {
            let v = self.values(&halton(i, &shift));
            if self.invalid(&v).is_none() {
                design.push(v);
            }
            i += 1;
        }
        let first = self.evaluate(0, "baseline", baseline);
        push(first)?;
        let evaluated: Vec<Candidate> =
            design.into_par_iter().enumerate().map(|(j, v)| self.evaluate(j + 1, "design", v)).collect();
        for c in evaluated {
            push(c)?;
        }
        // 2. Nelder–Mead from the best design points in turn (each start gets a share of the
        // rest of the budget: a simplex that has shrunk onto one point only measures noise).
        let starts: Vec<Candidate> = {
            let a = lock(&archive, "lock")?;
            let mut v: Vec<Candidate> = a.iter().filter(|c| c.cost.is_finite()).cloned().collect();
            v.sort_by(|x, y| x.cost.total_cmp(&y.cost).then(x.index.cmp(&y.index)));
            v.dedup_by(|x, y| x.values == y.values);
            v.truncate(START_COUNT);
            v
        };
        let left = self.budget.saturating_sub(lock(&archive, "lock")?.len());
        let share = (left / starts.len().max(1)).max(d + 2);
        for start in starts {
            let used = lock(&archive, "lock")?.len();
            if used + d + 1 > self.budget {
                break;
            }
            let x0 = self.coords(&start.values);
            let mut simplex = vec![x0.clone()];
            for j in 0..d {
                let mut x = x0.clone();
                x[j] = if x[j] + STEP <= 1.0 { x[j] + STEP } else { x[j] - STEP };
                simplex.push(x);
            }
            let limit = (used + share).min(self.budget);
            let spent = AtomicBool::new(false);
            let problem = Problem {
                tuning: self,
                archive: &archive,
                observer,
                cache: Mutex::new(HashMap::new()),
                limit,
                spent: &spent,
            };
            let solver =
                NelderMead::new(simplex).with_sd_tolerance(1e-4).map_err(|e| TuneError::Solver(e.into()))?;
            match Executor::new(problem, solver).configure(|s| s.max_iters(10_000)).run() {
                Ok(_) => {}
                // The cost function said the budget is spent: this start ends.
                Err(_) if spent.load(Ordering::Relaxed) => {}
                Err(e) => return Err(TuneError::NelderMead { cause: e.into() }),
            }
        }
        let candidates = into_inner(archive)?;
        Ok(candidates)
    }
}

/// How many of the best design points Nelder–Mead starts from.
const START_COUNT: usize = 3;

/// The initial simplex's edge, in normalised coordinates (a seventh of each knob's range).
const STEP: f64 = 0.15;

/// The score of the run `name` from its starts' runs.
fn score(name: &str, starts: &[StartRun]) -> RunScore {
    let n = starts.len().max(1) as f64;
    // A start that touched a joint limit, had a step rejected or diverged tracks nothing.
    let tracked = |s: &StartRun| {
        let failed = s.error.is_some()
            || s.rejected_steps > 0
            || s.min_joint_margin.is_nan()
            || s.min_joint_margin <= 0.0
            || s.diverged_at.is_some();
        if failed {
            0.0
        } else {
            s.tracked
        }
    };
    let finite = starts.iter().any(|s| s.error.is_none());
    RunScore {
        run: name.to_string(),
        tracked: starts.iter().map(tracked).sum::<f64>() / n,
        settled: starts.iter().filter(|s| s.settled).count(),
        starts: starts.len(),
        rms_v: if finite { starts.iter().map(|s| s.rms_v).sum::<f64>() / n } else { f64::NAN },
        maneuvers: (starts.iter().map(|s| s.maneuvers as f64).sum::<f64>() / n).round() as u64,
        rejected_steps: starts.iter().map(|s| s.rejected_steps).sum(),
        min_joint_margin: starts.iter().map(|s| s.min_joint_margin).fold(f64::INFINITY, |a, b| {
            if a.is_nan() || b.is_nan() {
                f64::NAN
            } else {
                a.min(b)
            }
        }),
    }
}

/// The valid candidate of least cost (the earliest among equals).
pub fn best_of(c: &[Candidate]) -> Option<&Candidate> {
    c.iter()
        .filter(|c| c.cost.is_finite())
        .min_by(|a, b| a.cost.total_cmp(&b.cost).then(a.index.cmp(&b.index)))
}

/// The `i`-th point (from 1) of the Halton sequence in `shift.len()` dimensions, each
/// coordinate shifted by `shift` modulo 1 (Cranley–Patterson rotation).
pub fn halton(i: usize, shift: &[f64]) -> Vec<f64> {
    const PRIMES: [usize; 16] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53];
    shift
        .iter()
        .enumerate()
        .map(|(d, s)| {
            let b = PRIMES[d % PRIMES.len()];
            let (mut f, mut r, mut n) = (1.0, 0.0, i);
            while n > 0 {
                f /= b as f64;
                r += f * (n % b) as f64;
                n /= b;
            }
            (r + s).fract()
        })
        .collect()
}

/// The search's cost function for argmin: evaluates (once per point), archives, and stops the
/// optimiser when the budget is spent.
struct Problem<'a> {
    tuning: &'a Tuning,
    archive: &'a Mutex<Vec<Candidate>>,
    observer: &'a dyn Observer,
    cache: Mutex<HashMap<Vec<u64>, f64>>,
    /// Stop this start when the archive holds this many candidates.
    limit: usize,
    /// Set when this start stopped because its budget is spent ([`BudgetSpent`]).
    spent: &'a AtomicBool,
}

impl CostFunction for Problem<'_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, x: &Vec<f64>) -> Result<f64, ArgminError> {
        // Outside the box: the cost at the box's edge plus the distance, so the simplex returns.
        let outside: f64 = x.iter().map(|u| (u - u.clamp(0.0, 1.0)).abs()).sum();
        let inside: Vec<f64> = x.iter().map(|u| u.clamp(0.0, 1.0)).collect();
        let key: Vec<u64> = inside.iter().map(|u| u.to_bits()).collect();
        if let Some(c) = lock(&self.cache, "lock")?.get(&key) {
            return Ok(c + outside);
        }
        let mut archive = lock(self.archive, "lock")?;
        if archive.len() >= self.limit {
            self.spent.store(true, Ordering::Relaxed);
            return Err(BudgetSpent.into());
        }
        let index = archive.len();
        drop(archive);
        let c = self.tuning.evaluate(index, "refine", self.tuning.values(&inside));
        // An invalid point costs more than any valid one (costs are at most 1 + w·effort).
        let cost = if c.cost.is_finite() { c.cost } else { 10.0 };
        self.observer.advance(1);
        archive = lock(self.archive, "lock")?;
        archive.push(c);
        drop(archive);
        lock(&self.cache, "lock")?.insert(key, cost);
        Ok(cost + outside)
    }
}

#[cfg(test)]
mod tests;
