//! Bad spaces refused before anything runs; the search deterministic and its report
//! consistent.

use companion_core::{PaperRun, PlatformKind};
use companion_plant::PaperTrajectory;

use super::*;
use crate::domain::observe::Silent;
use crate::study::starts::{self, Perturbation, Settle, Starts};
use crate::study::trial::Judge;

fn set(platform: PlatformKind, duration: f64) -> Vec<SetRun> {
    [(PaperTrajectory::One, PaperRun::A, "1a"), (PaperTrajectory::One, PaperRun::C, "1c")]
        .into_iter()
        .map(|(t, c, name)| {
            let builder = Scenario::builder(t, c, platform).duration(duration);
            let base = builder.clone().build().unwrap();
            SetRun { name: name.into(), builder, base, spatial: None }
        })
        .collect()
}

fn space(text: &str) -> TuneSpaceFile {
    toml::from_str(text).unwrap()
}

#[test]
fn bad_spaces_are_refused_before_anything_runs() {
    let err = |text: &str, budget: usize| {
        Tuning::new(set(PlatformKind::Car, 1.0), Some(&space(text)), budget, 1).unwrap_err().to_string()
    };
    assert!(err("[parameters]\nepsilonn = [0.1, 0.2]", 50).contains("unknown parameter `epsilonn`"));
    assert!(err("[parameters]\nepsilon_1 = [0.1, 0.2]", 50).contains("unicycle platform"));
    assert!(err("[parameters]\nepsilon = [0.3, 0.1]", 50).contains("empty range"));
    assert!(err("[parameters]\nepsilon = [0.0, 0.1]", 50).contains("> 0"));
    assert!(err("[parameters]\nepsilon = [0.1, 0.3]", 2).contains("--budget 2 is too small"));
    // No point of this box satisfies Lemma 2: 6 η₂ η₃ − 8 η₃ − η₁ η₂ < 0 throughout.
    let e = err("[parameters]\neta_1 = [40.0, 50.0]\neta_2 = [1.34, 1.4]\neta_3 = [0.5, 0.6]", 50);
    assert!(e.contains("no point of the space") && e.contains("Lemma 2"), "{e}");
    assert!(toml::from_str::<TuneSpaceFile>("[objective]\neffort = 1").is_err(), "unknown key");
    let e = Tuning::new(Vec::new(), None, 50, 1).unwrap_err().to_string();
    assert!(e.contains("at least one run"), "{e}");
}

#[test]
fn halton_points_are_the_radical_inverses_shifted() {
    assert_eq!(halton(1, &[0.0, 0.0]), vec![0.5, 1.0 / 3.0]);
    assert_eq!(halton(2, &[0.0, 0.0]), vec![0.25, 2.0 / 3.0]);
    assert_eq!(halton(3, &[0.0]), vec![0.75]);
    let p = halton(1, &[0.75]);
    assert!((p[0] - 0.25).abs() < 1e-15, "shifted modulo 1: {p:?}");
}

#[test]
fn the_search_is_deterministic_and_its_report_consistent() {
    let runs = set(PlatformKind::Unicycle, 2.0);
    let file = space("[parameters]\nepsilon_1 = [0.1, 0.3]\nk_bar_3 = [10.0, 1000.0]");
    let t = Tuning::new(runs, Some(&file), 10, 3).unwrap();
    let a = report::TuneReport::new(&t, t.run(&Silent).unwrap());
    let b = report::TuneReport::new(&t, t.run(&Silent).unwrap());
    assert_eq!(serde_json::to_string(&a).unwrap(), serde_json::to_string(&b).unwrap());
    assert_eq!(a.candidates.len(), 10, "the budget is spent exactly");
    assert_eq!(a.candidates[0].stage, "baseline");
    let best = a.best().unwrap();
    assert!(a.candidates.iter().all(|c| c.cost >= best.cost));
    // Every candidate stays in the box, and its cost is what the objective says.
    for c in &a.candidates {
        for ((k, [lo, hi]), (k2, v)) in t.space.iter().zip(&c.values) {
            assert_eq!(k, k2);
            assert!(*v >= *lo * (1.0 - 1e-12) && *v <= *hi * (1.0 + 1e-12) || c.stage == "baseline", "{v}");
        }
        let mean = |f: fn(&RunScore) -> f64| c.runs.iter().map(f).sum::<f64>() / c.runs.len() as f64;
        assert_eq!(c.tracked, mean(|r| r.tracked));
        assert!((c.cost - ((1.0 - c.tracked) + EFFORT_WEIGHT * mean(|r| r.rms_v))).abs() < 1e-12);
    }
    // The front: no candidate dominates a member of it.
    for &i in &a.pareto {
        let p = &a.candidates[i];
        assert!(!a.candidates.iter().any(|o| o.cost.is_finite()
            && o.tracked >= p.tracked
            && o.effort <= p.effort
            && (o.tracked > p.tracked || o.effort < p.effort)));
    }
    // The preset is a config file the runtime reads back, with the best values.
    let preset = a.preset(&t).unwrap();
    let cfg: crate::domain::scenario::ConfigFile = toml::from_str(&preset).unwrap();
    let u = cfg.unicycle.unwrap();
    assert_eq!(u.epsilon_1, best.values[0].1);
}

/// `tune --arm`: each candidate runs `sim --arm`'s run (its score is the spatial trial's), the
/// arm's scale is not a knob of the law, and the report names the arm.
#[test]
fn a_spatial_arm_is_tuned_on_its_own_runs() {
    use crate::domain::arm::SpatialArmSpec;
    use crate::run::spatial::SpatialTargetChoice;
    let builder = Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle)
        .duration(2.0)
        .for_spatial_arm();
    let base = builder.clone().build().unwrap();
    let setup =
        SpatialSetup { arm: SpatialArmSpec::Ur5, target: SpatialTargetChoice::Lifted(PaperTrajectory::One) };
    let runs = vec![SetRun { name: "1a".into(), builder, base, spatial: Some(setup.clone()) }];
    let e =
        Tuning::new(runs.clone(), Some(&space("[parameters]\njoint_speed = [0.5, 2.0]")), 10, 1).unwrap_err();
    assert!(e.to_string().contains("`joint_speed` scales the arm"), "{e}");
    let file = space("[parameters]\nk_bar_3 = [10.0, 1000.0]\ndamping_below = [1e-3, 1e-2]");
    let t = Tuning::new(runs.clone(), Some(&file), 10, 1).unwrap();
    let a = report::TuneReport::new(&t, t.run(&Silent).unwrap());
    assert_eq!(a.arm.as_deref(), Some("ur5"));
    // (A 2 s run tracks nothing after 20 s: equal costs may end Nelder–Mead before the budget.)
    assert!((4..=10).contains(&a.candidates.len()), "{}", a.candidates.len());
    let r = &runs[0];
    for c in &a.candidates {
        let s = knobs::apply(&r.builder, &r.base, &c.values).build().unwrap();
        let direct = trial::run_spatial(&setup.scenario(s, &c.values).unwrap(), &Judge::default()).unwrap();
        assert_eq!(c.runs[0].rms_v, direct.summary.rms_v, "candidate {}", c.index);
        let margin = direct.summary.min_joint_margin.iter().copied().fold(f64::INFINITY, f64::min);
        assert_eq!(c.runs[0].min_joint_margin, margin);
    }
    assert!(a.preset(&t).unwrap().contains("spatial arm `ur5`"));
}

/// `--starts N`: each run of a spatial arm's set from N perturbed homes — the candidate's
/// figures are the runs from those homes (each equal to `settle`'s run from the same home);
/// the planar arm refuses it; an `[objective] tolerance` is checked.
#[test]
fn each_run_from_perturbed_homes_scores_as_those_runs() {
    use crate::domain::arm::SpatialArmSpec;
    use crate::run::spatial::SpatialTargetChoice;
    let e = Tuning::new(set(PlatformKind::Unicycle, 1.0), None, 10, 1)
        .unwrap()
        .with_starts(Starts::new(3, Perturbation::Within(0.1), 1).unwrap())
        .unwrap_err();
    assert!(e.to_string().contains("--starts 3 perturbs a spatial arm's home"), "{e}");
    let bad = space("[parameters]\nk_bar_3 = [10.0, 1000.0]\n[objective]\ntolerance = 0.0");
    let e = Tuning::new(set(PlatformKind::Unicycle, 1.0), Some(&bad), 10, 1).unwrap_err();
    assert!(e.to_string().contains("objective.tolerance must be > 0"), "{e}");
    let builder = Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle)
        .duration(21.0)
        .for_spatial_arm();
    let base = builder.clone().build().unwrap();
    let setup =
        SpatialSetup { arm: SpatialArmSpec::Ur5, target: SpatialTargetChoice::Lifted(PaperTrajectory::One) };
    let runs = vec![SetRun { name: "1a".into(), builder, base: base.clone(), spatial: Some(setup.clone()) }];
    let file = space("[parameters]\nk_bar_3 = [50.0, 200.0]\n[objective]\ntolerance = 1e-2");
    let starts = Starts::new(3, Perturbation::Within(0.1), 7).unwrap();
    let t = Tuning::new(runs, Some(&file), 4, 1).unwrap().with_starts(starts).unwrap();
    let c = t.evaluate(0, "baseline", vec![(Knob::KBar3, 100.0)]);
    assert_eq!((c.runs[0].starts, c.runs.len()), (3, 1));
    let sc = setup.scenario(base, &[]).unwrap();
    let settle = Settle { tolerance: 1e-2, after: 20.0 };
    let direct = starts::settle(&sc, &starts, &settle, &Silent).unwrap();
    assert_eq!(c.runs[0].settled, direct.settled);
    assert!((c.tracked - direct.tracked_mean).abs() < 1e-15, "{} {}", c.tracked, direct.tracked_mean);
    let rms = direct.runs.iter().map(|r| r.rms_v).sum::<f64>() / 3.0;
    assert_eq!(c.runs[0].rms_v, rms);
    // The homes differ from each other and from the arm's, within ±0.1.
    let home = SpatialArmSpec::Ur5.home().unwrap();
    for r in &direct.runs {
        assert_ne!(r.home, home);
        assert!(r.home.iter().zip(&home).all(|(a, b)| (a - b).abs() <= 0.1), "{:?}", r.home);
    }
}
