//! Perturbed starts: one setting run from many homes near the robot's own, seeded — how a
//! setting is judged robust (`companion settle`, `companion tune --starts`).
//!
//! Start `k` (from 0) of an arm with home `q*`, the law's joint limits `[q⁻, q⁺]` (the robot's,
//! or the narrower `[controller.joint_limits]`) and its penalty margins `δ`
//! (`PrimaryTask::penalty_margin`: 5 % of each joint's range, 20 % for an arm of more than six
//! joints) stays in the window `[lᵢ, hᵢ] = [min(q*ᵢ, q⁻ᵢ + δᵢ), max(q*ᵢ, q⁺ᵢ − δᵢ)]` and has the
//! home
//!
//! ```text
//! within a:   qᵢ(k) = clamp(q*ᵢ + a (2 uₖ,ᵢ − 1),  lᵢ,  hᵢ)
//! anywhere:   qᵢ(k) = lᵢ + uₖ,ᵢ (hᵢ − lᵢ)
//! ```
//!
//! with `a` the perturbation (rad for a revolute joint, m for a prismatic one) and `uₖ,ᵢ`
//! uniform on [0, 1), the i-th number of ChaCha12 stream `k` of the seed: start `k` is the
//! same whatever the number of starts and whatever thread runs it. A continuous joint is not
//! clamped (anywhere: within ±π of its home). One start within `a = 0` is the home itself
//! ([`Starts::HOME`]).
//!
//! A start's home is the run's home altogether, as `sim --arm … --home q(k)` makes it: the
//! law's `q*` (its preferred pose, the weight's margins) and where the arm starts; the lifted
//! target is placed where the arm at that home holds it. [`StartRun::home`] is the `--home`
//! list that replays a start with `companion sim`.
//!
//! **Settled**: the run was not stopped as diverged, no step was rejected, and `‖e_p‖` stayed
//! below the tolerance (default 1e−3, the tracked fraction's) on every step from `after`
//! (default 20 s) to its end.

use companion_core::{Manipulator, Spatial, SpatialArm};
use rand::rngs::ChaCha12Rng;
use rand::{Rng as _, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;

use crate::domain::arm::{ArmError, SpatialArmSpec};
use crate::domain::controller::{law_limits, spatial_params, ControllerSpec, SpatialControllerError};
use crate::domain::observe::Observer;
use crate::domain::spread::Spread;
use crate::run::spatial::SpatialScenario;
use crate::study::trial::{self, Judge, Trial};

/// Why starts cannot be drawn.
#[derive(Debug, thiserror::Error)]
pub enum StartsError {
    /// No start.
    #[error("--starts must be at least 1")]
    Count,
    /// The perturbation is negative or not a number.
    #[error("--perturb must be a finite number >= 0 (rad or m) or `anywhere`, got {0}")]
    Perturbation(f64),
    /// The tolerance or the settling time is not usable.
    #[error("--tolerance must be > 0 and --settle-by >= 0 s and shorter than the run ({0})")]
    Settle(String),
    /// The arm cannot be built.
    #[error(transparent)]
    Arm(#[from] ArmError),
    /// The law's own joint limits (`[controller.joint_limits]`) do not fit the arm.
    #[error(transparent)]
    Limits(#[from] SpatialControllerError),
    /// The law refuses the arm's parameters.
    #[error("the law's parameters: {0}")]
    Param(companion_core::ParamError),
}

/// How far a start's home is from the arm's (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Perturbation {
    /// `a`: each joint's home moved by up to `±a` (rad or m), kept in the window.
    Within(f64),
    /// Each joint drawn uniformly over its whole window: homes anywhere inside the law's
    /// limits, out of its penalty margins.
    Anywhere,
}

impl std::str::FromStr for Perturbation {
    type Err = String;

    /// `anywhere`, or a finite number ≥ 0 (rad or m).
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "anywhere" {
            return Ok(Self::Anywhere);
        }
        match s.parse::<f64>() {
            Ok(a) if a.is_finite() && a >= 0.0 => Ok(Self::Within(a)),
            _ => Err(format!("`{s}`: give a finite number >= 0 (rad or m) or `anywhere`")),
        }
    }
}

impl std::fmt::Display for Perturbation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Within(a) => write!(f, "within ±{a} of the arm's"),
            Self::Anywhere => write!(f, "anywhere inside the law's joint limits, out of its penalty margins"),
        }
    }
}

/// How many starts, how far from the home, from which seed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Starts {
    /// Starts (≥ 1).
    pub count: usize,
    /// How far each start's home is from the arm's.
    pub perturbation: Perturbation,
    /// The seed of the draws.
    pub seed: u64,
}

impl Starts {
    /// One start, at the home itself.
    pub const HOME: Self = Self { count: 1, perturbation: Perturbation::Within(0.0), seed: 0 };

    /// `count` starts, each home drawn from `seed` as `perturbation` says.
    ///
    /// # Errors
    /// No start, or a negative or non-finite perturbation.
    pub fn new(count: usize, perturbation: Perturbation, seed: u64) -> Result<Self, StartsError> {
        if count == 0 {
            return Err(StartsError::Count);
        }
        if let Perturbation::Within(a) = perturbation {
            if !(a.is_finite() && a >= 0.0) {
                return Err(StartsError::Perturbation(a));
            }
        }
        Ok(Self { count, perturbation, seed })
    }

    /// Whether the one start is the home itself.
    pub fn is_home(&self) -> bool {
        self.count == 1 && self.perturbation == Perturbation::Within(0.0)
    }

    /// `n` uniform numbers on [0, 1): ChaCha12 stream `k` of the seed.
    fn draws(&self, k: usize, n: usize) -> Vec<f64> {
        let mut rng = ChaCha12Rng::seed_from_u64(self.seed);
        rng.set_stream(k as u64);
        (0..n).map(|_| (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64).collect()
    }

    /// The homes of the starts (module docs), for `arm` under the law `spec` builds.
    ///
    /// # Errors
    /// The arm cannot be built or the law refuses it.
    pub fn homes(&self, arm: &SpatialArmSpec, spec: &ControllerSpec) -> Result<Vec<Vec<f64>>, StartsError> {
        let (home, lo, hi) = match arm.joints() {
            6 => window::<6>(arm, spec)?,
            7 => window::<7>(arm, spec)?,
            8 => window::<8>(arm, spec)?,
            n => return Err(ArmError::JointCount { found: n }.into()),
        };
        Ok((0..self.count)
            .map(|k| {
                let u = self.draws(k, home.len());
                (0..home.len())
                    .map(|i| {
                        let bounded = lo[i].is_finite() && hi[i].is_finite();
                        match self.perturbation {
                            Perturbation::Anywhere if bounded => lo[i] + u[i] * (hi[i] - lo[i]),
                            Perturbation::Anywhere => home[i] + std::f64::consts::PI * (2.0 * u[i] - 1.0),
                            Perturbation::Within(a) => {
                                let q = home[i] + a * (2.0 * u[i] - 1.0);
                                if bounded {
                                    q.clamp(lo[i], hi[i])
                                } else {
                                    q
                                }
                            }
                        }
                    })
                    .collect()
            })
            .collect())
    }
}

/// The home and the window a perturbed home stays in: `[min(q*, q⁻ + δ), max(q*, q⁺ − δ)]`
/// per joint, of the law's limits (infinite for a continuous joint).
#[allow(clippy::type_complexity)]
fn window<const N: usize>(
    arm: &SpatialArmSpec,
    spec: &ControllerSpec,
) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>), StartsError>
where
    SpatialArm<f64, N>: Manipulator<f64, N, Space = Spatial>,
{
    let chain = law_limits(spec, &arm.chain::<f64, N>()?, &arm.joint_names())?;
    let law = SpatialArm::new(&chain).map_err(StartsError::Param)?;
    let p = spatial_params(spec, &law).map_err(StartsError::Param)?;
    let (home, limits, delta) = (chain.home(), chain.limits(), p.primary.penalty_margin);
    let lo = (0..N).map(|i| {
        if limits.is_unbounded(i) {
            f64::NEG_INFINITY
        } else {
            home[i].min(limits.lower[i] + delta[i])
        }
    });
    let hi = (0..N).map(|i| {
        if limits.is_unbounded(i) {
            f64::INFINITY
        } else {
            home[i].max(limits.upper[i] - delta[i])
        }
    });
    Ok((home.iter().copied().collect(), lo.collect(), hi.collect()))
}

/// When a run has settled.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Settle {
    /// `‖e_p‖` below this is tracked (m and rad mixed, as `e_p` is); default 1e−3.
    pub tolerance: f64,
    /// From this time on (s); default 20.
    pub after: f64,
}

impl Default for Settle {
    fn default() -> Self {
        Self { tolerance: 1e-3, after: 20.0 }
    }
}

impl Settle {
    /// The trial's judge: tracked from `after`, to `tolerance`.
    pub fn judge(&self) -> Judge {
        Judge { tolerance: self.tolerance, track_after: Some(self.after), ..Judge::default() }
    }

    /// Checks the settings for a run of `duration` seconds.
    ///
    /// # Errors
    /// A tolerance that is not positive, or `after` outside `[0, duration)`.
    pub fn check(&self, duration: f64) -> Result<(), StartsError> {
        if !(self.tolerance.is_finite() && self.tolerance > 0.0 && self.after >= 0.0 && self.after < duration)
        {
            return Err(StartsError::Settle(format!(
                "tolerance {}, settle-by {} s, duration {duration} s",
                self.tolerance, self.after
            )));
        }
        Ok(())
    }
}

/// One start's run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StartRun {
    /// The start (from 0).
    pub index: usize,
    /// Its home (rad or m, the chain's order): `sim --arm … --home` with this list replays it.
    pub home: Vec<f64>,
    /// Whether it settled (module docs).
    pub settled: bool,
    /// `‖e_p‖` at the last step.
    pub final_ep_norm: f64,
    /// The largest `‖e_p‖` from `after` on.
    pub max_ep_after: f64,
    /// The fraction of the steps from `after` on with `‖e_p‖` below the tolerance.
    pub tracked: f64,
    /// The last time `‖e_p‖` was at or above the tolerance (s; 0 if never).
    pub settling_time_s: f64,
    /// Steps the law rejected.
    pub rejected_steps: u64,
    /// The run was stopped as diverged at this time (s).
    pub diverged_at: Option<f64>,
    /// The fraction of the steps after 20 s at which the limits acted (`summary.json`'s
    /// `limits_after_20s.fraction`).
    pub limits_fraction: f64,
    /// … at which the acceleration limits or the joint guard acted
    /// (`limits_after_20s.beyond_saturation_fraction`).
    pub beyond_saturation_fraction: f64,
    /// The commanded forward speed's rms (m/s).
    pub rms_v: f64,
    /// The platform's reversals.
    pub maneuvers: u64,
    /// The smallest joint margin over the run (rad or m).
    pub min_joint_margin: f64,
    /// Why the run could not be made (then every figure is NaN).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

impl StartRun {
    /// The figures of `trial` (start `index` at `home`), judged by `settle`.
    pub fn of(index: usize, home: Vec<f64>, trial: &Trial) -> Self {
        let (s, t) = (&trial.summary, &trial.tail);
        Self {
            index,
            home,
            settled: t.diverged_at.is_none() && s.rejected_steps == 0 && t.tracked_fraction >= 1.0,
            final_ep_norm: s.final_ep_norm,
            max_ep_after: t.ep_bound,
            tracked: t.tracked_fraction,
            settling_time_s: t.settling_time_s,
            rejected_steps: s.rejected_steps,
            diverged_at: t.diverged_at,
            limits_fraction: s.limits_after_20s.fraction,
            beyond_saturation_fraction: s.limits_after_20s.beyond_saturation_fraction,
            rms_v: s.rms_v,
            maneuvers: s.maneuvers,
            min_joint_margin: s.min_joint_margin.iter().copied().fold(f64::INFINITY, f64::min),
            error: None,
        }
    }

    /// A start whose run could not be made.
    pub fn failed(index: usize, home: Vec<f64>, why: String) -> Self {
        Self {
            index,
            home,
            settled: false,
            final_ep_norm: f64::NAN,
            max_ep_after: f64::NAN,
            tracked: 0.0,
            settling_time_s: f64::NAN,
            rejected_steps: 0,
            diverged_at: None,
            limits_fraction: f64::NAN,
            beyond_saturation_fraction: f64::NAN,
            rms_v: f64::NAN,
            maneuvers: 0,
            min_joint_margin: f64::NAN,
            error: Some(why),
        }
    }
}

/// Runs `s` from the home `home` (`None`: its own), judged by `settle`.
pub fn run_from(s: &SpatialScenario, index: usize, home: Option<&[f64]>, settle: &Settle) -> StartRun {
    let own = || s.arm.home().unwrap_or_default();
    let home_list = home.map_or_else(own, <[f64]>::to_vec);
    let rehomed;
    let sc = match home {
        None => s,
        Some(h) => {
            rehomed = SpatialScenario { arm: s.arm.clone().rehomed(h.to_vec()), ..s.clone() };
            &rehomed
        }
    };
    match crate::run::spatial::check(sc)
        .map_err(|e| e.to_string())
        .and_then(|()| trial::run_spatial(sc, &settle.judge()).map_err(|e| e.to_string()))
    {
        Ok(t) => StartRun::of(index, home_list, &t),
        Err(why) => StartRun::failed(index, home_list, why),
    }
}

/// A setting's runs from its starts, and their spreads.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SettleReport {
    /// The run's name (`tiago-traj1-a-unicycle`).
    pub run: String,
    /// The starts.
    pub starts: Starts,
    /// When a run has settled.
    pub settle: Settle,
    /// How many settled.
    pub settled: usize,
    /// `‖e_p‖` at the end, over the starts (`None` if a run has none).
    pub final_ep_norm: Option<Spread>,
    /// The largest `‖e_p‖` from `after` on, over the starts.
    pub max_ep_after: Option<Spread>,
    /// The tracked fraction from `after` on, over the starts.
    pub tracked: Option<Spread>,
    /// Its mean over the starts.
    pub tracked_mean: f64,
    /// The fraction of the steps after 20 s at which the limits acted, over the starts.
    pub limits_fraction: Option<Spread>,
    /// … the acceleration limits or the joint guard, over the starts.
    pub beyond_saturation_fraction: Option<Spread>,
    /// Each start.
    pub runs: Vec<StartRun>,
}

impl SettleReport {
    /// The report of `runs`.
    pub fn new(run: String, starts: Starts, settle: Settle, mut runs: Vec<StartRun>) -> Self {
        runs.sort_by_key(|r| r.index);
        let col = |f: fn(&StartRun) -> f64| Spread::of(&runs.iter().map(f).collect::<Vec<_>>());
        let n = runs.len().max(1) as f64;
        Self {
            run,
            starts,
            settle,
            settled: runs.iter().filter(|r| r.settled).count(),
            final_ep_norm: col(|r| r.final_ep_norm),
            max_ep_after: col(|r| r.max_ep_after),
            tracked: col(|r| r.tracked),
            tracked_mean: runs.iter().map(|r| r.tracked).sum::<f64>() / n,
            limits_fraction: col(|r| r.limits_fraction),
            beyond_saturation_fraction: col(|r| r.beyond_saturation_fraction),
            runs,
        }
    }
}

/// Runs `s` from each of `starts`, in parallel (one `observer.advance` per start done).
///
/// # Errors
/// The homes cannot be drawn (the arm or the law refuses it).
pub fn settle(
    s: &SpatialScenario,
    starts: &Starts,
    settle: &Settle,
    observer: &dyn Observer,
) -> Result<SettleReport, StartsError> {
    settle.check(s.base.duration)?;
    let homes: Vec<Option<Vec<f64>>> = if starts.is_home() {
        vec![None]
    } else {
        starts.homes(&s.arm, &s.base.controller)?.into_iter().map(Some).collect()
    };
    let runs: Vec<StartRun> = homes
        .par_iter()
        .enumerate()
        .map(|(k, h)| {
            let r = run_from(s, k, h.as_deref(), settle);
            observer.advance(1);
            r
        })
        .collect();
    Ok(SettleReport::new(s.name.clone(), *starts, *settle, runs))
}

#[cfg(test)]
mod tests {
    use companion_core::{PaperRun, PlatformKind};
    use companion_plant::PaperTrajectory;

    use super::*;
    use crate::domain::observe::Silent;
    use crate::domain::scenario::Scenario;
    use crate::run::spatial::SpatialTargetChoice;

    fn spec() -> ControllerSpec {
        Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle)
            .for_spatial_arm()
            .build()
            .unwrap()
            .controller
    }

    /// Start k is the same whatever the count and the seed's other streams; each joint moves
    /// by at most the perturbation, and stays out of the penalty margins (5 % of the range for
    /// the UR5's six joints); the draws spread over the whole ±a.
    #[test]
    fn homes_are_seeded_per_start_and_stay_within_the_margins() {
        let arm = SpatialArmSpec::Ur5;
        let home = arm.home().unwrap();
        let ten = Starts::new(10, Perturbation::Within(0.1), 3).unwrap().homes(&arm, &spec()).unwrap();
        let four = Starts::new(4, Perturbation::Within(0.1), 3).unwrap().homes(&arm, &spec()).unwrap();
        assert_eq!(ten[..4], four[..]);
        assert_ne!(ten, Starts::new(10, Perturbation::Within(0.1), 4).unwrap().homes(&arm, &spec()).unwrap());
        let moves: Vec<f64> = ten.iter().flat_map(|h| h.iter().zip(&home).map(|(a, b)| a - b)).collect();
        assert!(moves.iter().all(|m| m.abs() <= 0.1), "{moves:?}");
        assert!(moves.iter().any(|m| *m > 0.07) && moves.iter().any(|m| *m < -0.07), "{moves:?}");
        // A home near a limit: clamped at the margin, never past it.
        let chain = arm.chain::<f64, 6>().unwrap();
        let (lo, up) = (chain.joints[1].lower, chain.joints[1].upper);
        let delta = 0.05 * (up - lo);
        let mut near = home.clone();
        near[1] = lo + delta + 0.01;
        let wide = Starts::new(40, Perturbation::Within(0.5), 1)
            .unwrap()
            .homes(&arm.clone().rehomed(near), &spec())
            .unwrap();
        let q1: Vec<f64> = wide.iter().map(|h| h[1]).collect();
        assert!(q1.iter().all(|q| *q >= lo + delta - 1e-12), "{q1:?}");
        assert!(q1.iter().any(|q| (*q - (lo + delta)).abs() < 1e-12), "some clamped: {q1:?}");
        assert!(
            Starts::new(0, Perturbation::Within(0.1), 1).is_err()
                && Starts::new(2, Perturbation::Within(-0.1), 1).is_err()
        );
        assert!(Starts::new(2, Perturbation::Within(f64::NAN), 1).is_err());
        assert!(Starts::HOME.is_home() && !Starts::new(2, Perturbation::Within(0.0), 1).unwrap().is_home());
    }

    /// `anywhere`: every joint drawn over its whole window, inside the law's own limits
    /// (`[controller.joint_limits]`, narrower than the robot's for one joint here) and out of
    /// their penalty margins (5 % of each range); `--perturb` parses a number or `anywhere`.
    #[test]
    fn anywhere_spreads_over_the_laws_window() {
        let arm = SpatialArmSpec::Ur5;
        let (chain, home, names) = (arm.chain::<f64, 6>().unwrap(), arm.home().unwrap(), arm.joint_names());
        let mut spec = spec();
        let (lo2, hi2) = (home[2] - 0.4, home[2] + 0.6);
        spec.overrides.joint_limits = Some([(names[2].clone(), [lo2, hi2])].into());
        let homes = Starts::new(200, Perturbation::Anywhere, 5).unwrap().homes(&arm, &spec).unwrap();
        for i in 0..6 {
            let (lo, hi) = if i == 2 { (lo2, hi2) } else { (chain.joints[i].lower, chain.joints[i].upper) };
            let (l, h) = (lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo));
            let q: Vec<f64> = homes.iter().map(|h| h[i]).collect();
            let (min, max) =
                q.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(*x), b.max(*x)));
            assert!(min >= l - 1e-12 && max <= h + 1e-12, "joint {i}: {min}..{max} outside [{l}, {h}]");
            assert!(
                min < l + 0.05 * (h - l) && max > h - 0.05 * (h - l),
                "joint {i}: {min}..{max} in [{l}, {h}]"
            );
        }
        assert_eq!("anywhere".parse::<Perturbation>(), Ok(Perturbation::Anywhere));
        assert_eq!("0.3".parse::<Perturbation>(), Ok(Perturbation::Within(0.3)));
        assert!("-0.1".parse::<Perturbation>().is_err() && "inf".parse::<Perturbation>().is_err());
        // The law's limits must hold the home: a narrower range that does not is refused.
        spec.overrides.joint_limits = Some([(names[2].clone(), [home[2] + 0.1, home[2] + 0.6])].into());
        let e = Starts::new(2, Perturbation::Anywhere, 5).unwrap().homes(&arm, &spec).unwrap_err();
        assert!(e.to_string().contains("does not hold the home"), "{e}");
    }

    /// A start's run is the run of the arm at that home: the same summary as a scenario built
    /// with the rehomed arm; one start at home is the arm's own run.
    #[test]
    fn a_starts_run_is_the_run_at_its_home() {
        let base = Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle)
            .duration(21.0)
            .for_spatial_arm()
            .build()
            .unwrap();
        let target = SpatialTargetChoice::Lifted(PaperTrajectory::One);
        let s = SpatialScenario::new(base.clone(), SpatialArmSpec::Ur5, target.clone()).unwrap();
        let settle = Settle::default();
        let starts = Starts::new(2, Perturbation::Within(0.1), 1).unwrap();
        let r = super::settle(&s, &starts, &settle, &Silent).unwrap();
        assert_eq!(r.runs.len(), 2);
        let homes = starts.homes(&s.arm, &s.base.controller).unwrap();
        for (run, h) in r.runs.iter().zip(&homes) {
            assert_eq!(&run.home, h);
            let arm = SpatialArmSpec::Ur5.rehomed(h.clone());
            let direct = trial::run_spatial(
                &SpatialScenario::new(base.clone(), arm, target.clone()).unwrap(),
                &settle.judge(),
            )
            .unwrap();
            assert_eq!(run.final_ep_norm, direct.summary.final_ep_norm);
            assert_eq!(
                run.settled,
                direct.tail.tracked_fraction >= 1.0 && direct.summary.rejected_steps == 0
            );
        }
        let own = super::settle(&s, &Starts::HOME, &settle, &Silent).unwrap();
        let direct = trial::run_spatial(&s, &settle.judge()).unwrap();
        assert_eq!(own.runs[0].final_ep_norm, direct.summary.final_ep_norm);
        assert_eq!(own.runs[0].home, SpatialArmSpec::Ur5.home().unwrap());
        assert!(Settle { tolerance: 1e-3, after: 30.0 }.check(21.0).is_err());
    }
}
