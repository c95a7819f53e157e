//! The sampled-data controller end to end (`companion sim`, the robot's true tracking error
//! from the plant): the hold-aware default (`Discretisation::Midpoint`) against the literal
//! sampling of the paper's continuous law (`Sampled`), at real control rates.
//!
//! - the tracking floor is second order in the period (log-log slope ≥ 1.8 between 4 ms and
//!   0.5 ms on T1 (a), T1 (c), T2 (a)); the sampled law's is first order;
//! - the aims at 1 ms and at 100 Hz;
//! - a measurement delay of 2 ms at 1 kHz, compensated, keeps the floor within 2× of the
//!   undelayed one;
//! - stationary far targets (5 to 1 000 m) are reached from rest without velocity limits at
//!   1 ms and at the largest admitted period (10 ms), runs a–d, unicycle and omni;
//! - the joint guard (a sampling safeguard) never acts in the paper's runs.
//!
//! Measured values are in the comments; thresholds keep a stated margin above them.

use companion_core::{PaperRun, PlatformKind};
use companion_plant::PaperTrajectory::{self, One, Two};
use companion_runtime::domain::controller::{DiscretisationConfig, Scalar};
use companion_runtime::domain::record::Summary;
use companion_runtime::domain::scenario::{LimitsChoice, Scenario, ScenarioBuilder, Target};
use companion_tests::{out_dir, scenario, summaries};

const RUNS: [PaperRun; 4] = [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D];

fn paper(t: PaperTrajectory, r: PaperRun) -> ScenarioBuilder {
    Scenario::builder(t, r, PlatformKind::Unicycle)
}

/// The floor of a run: the largest true ‖e_p‖ after 20 s (the last 20 s of trajectory 1's
/// 40 s, the transient being over by 10 s; on trajectory 2, the whole tracking phase).
fn floor(s: &Summary) -> f64 {
    s.max_ep_norm_after_20s
}

/// The least-squares slope of `log y` against `log x`.
fn log_slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (lx, ly): (Vec<f64>, Vec<f64>) = points.iter().map(|(x, y)| (x.ln(), y.ln())).unzip();
    let (mx, my) = (lx.iter().sum::<f64>() / n, ly.iter().sum::<f64>() / n);
    let sxy: f64 = lx.iter().zip(&ly).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = lx.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

const PERIODS: [f64; 4] = [4e-3, 2e-3, 1e-3, 5e-4];

fn sweep(d: DiscretisationConfig) -> Vec<(String, Vec<(f64, f64)>)> {
    let cases = [(One, PaperRun::A), (One, PaperRun::C), (Two, PaperRun::A)];
    let mut list = Vec::new();
    for (t, r) in cases {
        for dt in PERIODS {
            let s = scenario(paper(t, r).dt(dt).discretisation(d).log_every(1000));
            list.push((format!("sweep-{:?}-{}-{dt}", d, s.name), s));
        }
    }
    let refs: Vec<(&str, Scenario)> = list.iter().map(|(n, s)| (n.as_str(), s.clone())).collect();
    let out = summaries(&refs);
    out.chunks(PERIODS.len())
        .map(|c| (c[0].scenario.clone(), PERIODS.iter().zip(c).map(|(dt, s)| (*dt, floor(s))).collect()))
        .collect()
}

/// The floor against the period, log-log: slope ≥ 1.8 for the default (measured 2.01, 2.00,
/// 1.96 on T1 (a), T1 (c), T2 (a)); about 1 for the sampled law (measured 1.00, 1.00, 1.00),
/// which the default replaces.
#[test]
fn the_floor_is_second_order_in_the_period() {
    for (name, points) in sweep(DiscretisationConfig::Midpoint) {
        let slope = log_slope(&points);
        eprintln!("midpoint {name}: floors {points:?}, slope {slope:.2}");
        assert!(slope >= 1.8, "{name}: slope {slope:.2} < 1.8; floors {points:?}");
    }
    for (name, points) in sweep(DiscretisationConfig::Sampled) {
        let slope = log_slope(&points);
        eprintln!("sampled {name}: floors {points:?}, slope {slope:.2}");
        assert!((0.8..1.3).contains(&slope), "{name}: sampled slope {slope:.2}; floors {points:?}");
    }
}

/// The aims at 1 ms (unicycle, paper parameters): T1 (a) and (c) final ‖e_p‖ ≤ 1e−6
/// (measured 2.9e−7 and 2.5e−8); T2 (a) max ‖e_p‖ after 20 s ≤ 1e−3 (measured 1.3e−5) and
/// tracked ≥ 99 % (measured 100 %).
#[test]
fn aims_at_one_millisecond() {
    let out = summaries(&[
        ("aim1-1a", scenario(paper(One, PaperRun::A))),
        ("aim1-1c", scenario(paper(One, PaperRun::C))),
        ("aim1-2a", scenario(paper(Two, PaperRun::A))),
    ]);
    assert!(out[0].final_ep_norm <= 1e-6, "T1 (a) final {}", out[0].final_ep_norm);
    assert!(out[1].final_ep_norm <= 1e-6, "T1 (c) final {}", out[1].final_ep_norm);
    assert!(out[2].max_ep_norm_after_20s <= 1e-3, "T2 (a) max {}", out[2].max_ep_norm_after_20s);
    assert!(
        out[2].fraction_ep_below_1e_3_after_20s >= 0.99,
        "T2 (a) tracked {}",
        out[2].fraction_ep_below_1e_3_after_20s
    );
}

/// The aims at 100 Hz: T1 (a) and (c) final ‖e_p‖ ≤ 1e−4 (measured 2.8e−5, 2.4e−6);
/// T2 (a) tracked ≥ 95 % (measured 98.9 %); none of the eight paper runs diverges over
/// 120 s on any platform, in f32 or f64 (the joints stay inside their limits, no step is
/// rejected, and ‖e_p‖ stays bounded).
#[test]
fn aims_at_one_hundred_hertz() {
    let out = summaries(&[
        ("aim100-1a", scenario(paper(One, PaperRun::A).dt(0.01))),
        ("aim100-1c", scenario(paper(One, PaperRun::C).dt(0.01))),
        ("aim100-2a", scenario(paper(Two, PaperRun::A).dt(0.01))),
    ]);
    assert!(out[0].final_ep_norm <= 1e-4, "T1 (a) final {}", out[0].final_ep_norm);
    assert!(out[1].final_ep_norm <= 1e-4, "T1 (c) final {}", out[1].final_ep_norm);
    assert!(
        out[2].fraction_ep_below_1e_3_after_20s >= 0.95,
        "T2 (a) tracked {}",
        out[2].fraction_ep_below_1e_3_after_20s
    );

    let mut list = Vec::new();
    for t in [One, Two] {
        for r in RUNS {
            for p in [PlatformKind::Unicycle, PlatformKind::Car, PlatformKind::Omni] {
                for scalar in [Scalar::F64, Scalar::F32] {
                    let s = scenario(
                        Scenario::builder(t, r, p).dt(0.01).duration(120.0).scalar(scalar).log_every(1000),
                    );
                    list.push((format!("div100-{}", s.name), s));
                }
            }
        }
    }
    let refs: Vec<(&str, Scenario)> = list.iter().map(|(n, s)| (n.as_str(), s.clone())).collect();
    for s in summaries(&refs) {
        assert_eq!(s.rejected_steps, 0, "{}: rejected steps", s.scenario);
        assert!(s.min_joint_margin.iter().all(|m| *m > 0.0), "{}: a joint reached its limit", s.scenario);
        // Bounded: the car with the paper's RPR arm does not always track (see docs/book/src/paper.md),
        // but nothing runs away (measured worst 1.4 m, the car on trajectory 2).
        assert!(
            s.final_ep_norm < 3.0 && s.max_ep_norm_after_20s < 3.0,
            "{}: ‖e_p‖ {} / {}",
            s.scenario,
            s.final_ep_norm,
            s.max_ep_norm_after_20s
        );
    }
}

/// A pure delay of 2 ms (two periods) at 1 kHz between the measurement and the moment its
/// command takes effect: told the delay, the law predicts over it and keeps T1 (a)'s floor
/// within 2× of the undelayed one (measured 1.0×); not told, the floor is ~1 500× worse
/// (measured 6.9e−4 against 4.7e−7). T1 (c) likewise (measured 1.0× and 3 400×).
#[test]
fn a_compensated_delay_keeps_the_floor() {
    for r in [PaperRun::A, PaperRun::C] {
        let out = summaries(&[
            ("delay-none", scenario(paper(One, r))),
            ("delay-comp", scenario(paper(One, r).delay(2e-3))),
            ("delay-raw", scenario(paper(One, r).delay(2e-3).delay_compensation(false))),
        ]);
        let (none, comp, raw) = (floor(&out[0]), floor(&out[1]), floor(&out[2]));
        eprintln!("T1 ({r:?}): floor without delay {none:e}, compensated {comp:e}, uncompensated {raw:e}");
        assert!(comp <= 2.0 * none, "T1 ({r:?}): compensated {comp:e} vs undelayed {none:e}");
        assert!(raw >= 100.0 * none, "T1 ({r:?}): uncompensated {raw:e} vs undelayed {none:e}");
    }
}

/// A stationary target `d` metres away (bearing atan(4/3), heading 0.5 rad), the robot at
/// rest with the paper's initial joints.
fn far_target(d: f64) -> Target {
    let dir = out_dir(&format!("far-{d}"));
    let path = dir.join("target.toml");
    let text = format!(
        "[initial]\nr_bd = [{}, {}, 0.5]\n\n[[segment]]\nduration = 400.0\nvelocity = [0.0, 0.0, 0.0]\n",
        0.6 * d,
        0.8 * d
    );
    std::fs::write(&path, text).expect("target file");
    Target::File(path)
}

/// Far targets are reached: final ‖e_p‖ < 1e−3 within 300 s for runs a–d, unicycle and
/// omnidirectional platforms without velocity limits, at 1 ms and at 10 ms (the largest
/// admitted period for the paper's gains). Measured: every run converges, in 4.5 s (5 m) to
/// 134 s (1 000 m, runs c and d, which have no pre-compensation and take their time).
/// (The car-like platform with the paper's RPR arm does not converge from 5 m for runs a, c
/// and d: its transverse function's excursions exceed the arm's reach — the same with the
/// continuous law — see docs/book/src/precision.md, "Far targets".)
#[test]
fn far_targets_are_reached() {
    let mut list = Vec::new();
    for d in [5.0, 30.0, 100.0, 1000.0] {
        let target = far_target(d);
        for dt in [1e-3, 1e-2] {
            for r in RUNS {
                for p in [PlatformKind::Unicycle, PlatformKind::Omni] {
                    let s = scenario(
                        Scenario::builder(target.clone(), r, p)
                            .dt(dt)
                            .duration(300.0)
                            .limits(LimitsChoice::Unlimited)
                            .log_every(100_000),
                    );
                    list.push((format!("far-{d}-{dt}-{}", s.name), s));
                }
            }
        }
    }
    let refs: Vec<(&str, Scenario)> = list.iter().map(|(n, s)| (n.as_str(), s.clone())).collect();
    for ((name, _), s) in list.iter().zip(summaries(&refs)) {
        assert!(s.final_ep_norm < 1e-3, "{name}: final ‖e_p‖ {}", s.final_ep_norm);
        assert_eq!(s.rejected_steps, 0, "{name}: rejected steps");
    }
}

/// The joint guard (the law's safeguard against a held command stepping over a joint limit)
/// never acts in the paper's eight runs, as docs/book/src/law.md says: the arm law (30) is applied as
/// is at every step.
#[test]
fn the_joint_guard_never_acts_in_the_papers_runs() {
    let mut list = Vec::new();
    for t in [One, Two] {
        for r in RUNS {
            let s = scenario(paper(t, r).log_every(100_000));
            list.push((format!("guard-{}", s.name), s));
        }
    }
    let refs: Vec<(&str, Scenario)> = list.iter().map(|(n, s)| (n.as_str(), s.clone())).collect();
    for s in summaries(&refs) {
        assert_eq!(
            s.joint_guard_steps, 0,
            "{}: the joint guard acted (max factor {})",
            s.scenario, s.max_joint_scale
        );
        assert_eq!(s.max_joint_scale, 1.0);
    }
}
