//! `companion sim` end to end: determinism, f32 against f64, the car-like and
//! omnidirectional platforms, and the files a run writes.

use companion_core::{PaperRun, PlatformKind};
use companion_plant::PaperTrajectory::{One, Two};
use companion_runtime::domain::controller::{DiscretisationConfig, RestFilterConfig, Scalar};
use companion_runtime::domain::observe::Silent;
use companion_runtime::domain::scenario::Scenario;
use companion_tests::{out_dir, run_in, scenario, summaries};

/// Same inputs, same bits: running a scenario twice gives byte-identical `timeseries.csv`.
/// Run (b) on trajectory 2 is the most sensitive (it is chaotic: any difference grows).
#[test]
fn a_scenario_run_twice_gives_identical_files() {
    for b in [
        Scenario::builder(Two, PaperRun::B, PlatformKind::Unicycle).duration(40.0),
        Scenario::builder(One, PaperRun::C, PlatformKind::Car).scalar(Scalar::F32).duration(10.0),
    ] {
        let s = scenario(b);
        let (first, dir1) = run_in(&s, "det-1");
        let (second, dir2) = run_in(&s, "det-2");
        let a = std::fs::read(dir1.join("timeseries.csv")).unwrap();
        let b = std::fs::read(dir2.join("timeseries.csv")).unwrap();
        assert!(a.len() > 1000, "timeseries.csv is too short");
        assert!(a == b, "{}: the two runs' timeseries.csv differ", s.name);
        assert_eq!(first.summary.path_length.to_bits(), second.summary.path_length.to_bits());
    }
}

/// A run writes its CSV with the documented columns, its summary and its plots.
#[test]
fn a_run_writes_csv_summary_and_plots() {
    let s = scenario(Scenario::builder(One, PaperRun::A, PlatformKind::Car).duration(2.0).log_every(100));
    let dir = out_dir("files");
    let outcome = companion_runtime::run::sim::run_one(&s, &dir, &Silent).unwrap();
    companion_runtime::domain::plots::render_run(&dir, &outcome).unwrap();
    let csv = std::fs::read_to_string(dir.join("timeseries.csv")).unwrap();
    let mut lines = csv.lines();
    let header = lines.next().unwrap();
    for col in [
        "t",
        "x_b",
        "y_b",
        "theta_b",
        "q1",
        "q2",
        "q3",
        "x_e",
        "y_e",
        "theta_e",
        "x_d",
        "y_d",
        "theta_d",
        "ep_norm",
        "h_s",
        "psi",
        "v",
        "omega",
        "alpha_dot",
        "sat",
        "xi",
        "v_xi",
    ] {
        assert!(header.split(',').any(|c| c == col), "column {col} missing from {header}");
    }
    // Steps 0, 100, ..., 2000: 21 rows (the first and the last always).
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 21);
    assert!(rows[0].starts_with("0,"));
    assert!(rows[20].starts_with("2,"), "last row {}", rows[20]);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    for key in [
        "final_ep_norm",
        "max_ep_norm_after_20s",
        "fraction_ep_below_1e-3_after_20s",
        "min_joint_margin",
        "path_length",
        "path_length_after_20s",
        "v_sign_changes",
        "max_abs_v",
        "max_abs_omega",
        "final_h_s",
        "steps",
        "wall_time_s",
    ] {
        assert!(summary.get(key).is_some(), "summary.json lacks {key}");
    }
    assert_eq!(summary["steps"], 2001);
    // A 2 s run has no step after 20 s: its figures "after 20 s" are unknown (null), never 0
    // (which would read as a perfect tracking it never measured).
    assert_eq!(summary["steps_after_20s"], 0);
    assert!(summary["max_ep_norm_after_20s"].is_null(), "{}", summary["max_ep_norm_after_20s"]);
    assert!(summary["fraction_ep_below_1e-3_after_20s"].is_null());
    let index = std::fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(index.contains("<td>n/a</td>"), "the index shows the unknown figures as n/a");
    for f in ["path.svg", "ep.svg", "velocities.svg", "hs.svg", "joints.svg", "index.html"] {
        let text = std::fs::read_to_string(dir.join(f)).unwrap();
        assert!(text.len() > 500, "{f} is nearly empty");
    }
}

/// f32 against f64 on the same scenarios. Runs (a) and (c) are robust (a 1e−10 perturbation
/// stays ~1e−10, SPEC §4), so their summaries agree closely: the paths to 0.1 %, the
/// maneuver counts to ±2, the tracked fractions to 1 point, the peak speed to 1 %. f32 rounds every intermediate
/// result to ~6e−8 relative, so `e_p`'s floor is ~1e−7 instead of ~1e−15, which matters only
/// below the 1e−3 tracking threshold. Runs (b) and (d) are chaotic and compared by
/// statistics: tracked fractions within 10 points, paths within 10 %.
#[test]
fn f32_runs_agree_with_f64_runs() {
    let mut list = Vec::new();
    for traj in [One, Two] {
        for choice in [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D] {
            for scalar in [Scalar::F64, Scalar::F32] {
                let s = scenario(Scenario::builder(traj, choice, PlatformKind::Unicycle).scalar(scalar));
                list.push((format!("prec-{}", s.name), s));
            }
        }
    }
    let refs: Vec<(&str, _)> = list.iter().map(|(n, s)| (n.as_str(), s.clone())).collect();
    let out = summaries(&refs);
    for pair in out.chunks(2) {
        let (x, y) = (&pair[0], &pair[1]);
        let robust = x.scenario.contains("-a-") || x.scenario.contains("-c-");
        let rel_path = (x.path_length - y.path_length).abs() / x.path_length;
        let tracked = (x.fraction_ep_below_1e_3_after_20s - y.fraction_ep_below_1e_3_after_20s).abs();
        if robust {
            assert!(rel_path < 1e-3, "{}: paths differ by {rel_path}", x.scenario);
            assert!(
                x.maneuvers.abs_diff(y.maneuvers) <= 2,
                "{}: maneuvers {} vs {}",
                x.scenario,
                x.maneuvers,
                y.maneuvers
            );
            assert!(tracked < 0.01, "{}: tracked fractions differ by {tracked}", x.scenario);
            // The largest speed occurs in the initial transient, where the joint-limit penalty
            // switches on and amplifies rounding differences: 1 % there.
            let dv = (x.max_abs_v - y.max_abs_v).abs() / x.max_abs_v.max(1e-3);
            assert!(dv < 0.01, "{}: max |v| differ by {dv}", x.scenario);
        } else {
            assert!(rel_path < 0.1, "{}: paths differ by {rel_path}", x.scenario);
            assert!(tracked < 0.1, "{}: tracked fractions differ by {tracked}", x.scenario);
        }
        assert!(y.min_joint_margin.iter().all(|m| *m > 0.0), "{}: joint limit reached", y.scenario);
    }
}

/// The omnidirectional platform tracks both trajectories: run (a) (Ψ ≡ 1) keeps the target
/// at the hold floor throughout, run (c) once its transient is over.
#[test]
fn omnidirectional_platform_tracks_both_trajectories() {
    let list: Vec<(&str, _)> = vec![
        ("omni-1a", Scenario::paper(One, PaperRun::A, PlatformKind::Omni)),
        ("omni-2a", Scenario::paper(Two, PaperRun::A, PlatformKind::Omni)),
        ("omni-1c", Scenario::paper(One, PaperRun::C, PlatformKind::Omni)),
    ];
    let out = summaries(&list);
    for s in &out {
        assert!(
            s.max_ep_norm_after_20s < 1e-3,
            "{}: max |e_p| after 20 s {}",
            s.scenario,
            s.max_ep_norm_after_20s
        );
        assert!(s.min_joint_margin.iter().all(|m| *m > 0.0));
    }
    // The omnidirectional platform needs no maneuvers: it moves sideways.
    assert!(out[1].max_abs_v <= 1.0 + 1e-9, "omni (a) traj 2 max |v| {}", out[1].max_abs_v);
}

/// The car-like platform with its built-in parameters (found by `companion tune`, see the
/// docs/book/src/law.md, "The car-like platform": ε = 0.152, η = (21.9, 1.9, 15.4), k = 26.6,
/// K̄ = diag(1, 2.07, 254)) and realistic velocity limits tracks trajectory 1 with runs (a) and
/// (c) — (c) parks behind the target and stops, (a) keeps manoeuvring — which the issue asks
/// ≥ 95 % of the time after 20 s. On trajectory 2 it tracks run (c) about half the time
/// (53 % measured; the aim of 60 % is not met): following a target that moves
/// sideways takes parallel parking, whose excursions the arm's 0.7 m stroke absorbs only in
/// part (`companion explore` over the stroke quantifies it). Asserted as measured, with room
/// for rounding differences across machines.
#[test]
fn car_like_platform_tracks_trajectory_1_and_half_of_trajectory_2() {
    let list: Vec<(&str, _)> = vec![
        ("car-1a", Scenario::paper(One, PaperRun::A, PlatformKind::Car)),
        ("car-1c", Scenario::paper(One, PaperRun::C, PlatformKind::Car)),
        ("car-2c", Scenario::paper(Two, PaperRun::C, PlatformKind::Car)),
    ];
    let out = summaries(&list);
    let (t1a, t1c, t2) = (&out[0], &out[1], &out[2]);
    for t1 in [t1a, t1c] {
        assert!(
            t1.max_ep_norm_after_20s < 1e-3,
            "{}: max |e_p| after 20 s {}",
            t1.scenario,
            t1.max_ep_norm_after_20s
        );
    }
    assert!(t1c.path_length_after_20s < 1e-3, "car traj 1 (c) keeps moving: {}", t1c.path_length_after_20s);
    assert!(t1a.path_length_after_20s > 0.1, "car traj 1 (a) stops: {}", t1a.path_length_after_20s);
    let tracked = t2.fraction_ep_below_1e_3_after_20s;
    assert!((0.45..0.9).contains(&tracked), "car traj 2 (c) tracked {tracked}");
    for s in &out {
        assert!(s.min_joint_margin.iter().all(|m| *m > 0.0), "{}: joint limit reached", s.scenario);
        assert_eq!(s.rejected_steps, 0, "{}", s.scenario);
        // The realistic limits bind (the common factor scales the command down at some
        // step: measured 4.0–12.4), so the speed bound below is the saturation's doing.
        assert!(s.max_saturation > 1.5, "{}: the limits never bind: {}", s.scenario, s.max_saturation);
        assert!(s.max_abs_v <= 1.0 + 1e-9, "{}: speed limit exceeded: {}", s.scenario, s.max_abs_v);
    }
}

/// Counts runs of at least 5 consecutive steps where the step-to-step change of `α̇` flips
/// sign: an oscillation at the Nyquist frequency of the control loop.
fn nyquist_oscillations(csv: &str) -> usize {
    let col = csv.lines().next().unwrap().split(',').position(|c| c == "alpha_dot").unwrap();
    let values: Vec<f64> =
        csv.lines().skip(1).map(|l| l.split(',').nth(col).unwrap().parse().unwrap()).collect();
    let (mut runs, mut run) = (0, 0);
    for w in values.windows(3) {
        if (w[2] - w[1]) * (w[1] - w[0]) < 0.0 {
            run += 1;
            if run == 5 {
                runs += 1;
            }
        } else {
            run = 0;
        }
    }
    runs
}

/// The sampled law with an explicit update of the rest filter (28) oscillates at the Nyquist
/// frequency in the transients of runs (b)–(d) at dt = 1 ms (a loop gain of ~2·10³/s through
/// `K = H̄ K̄ H̄ᵀ`); the default linearly implicit update does not, and leaves the paper's
/// statistics as they were (path within 1 %, same maneuvers).
#[test]
fn implicit_rest_filter_removes_the_nyquist_oscillation() {
    for (choice, name) in [(PaperRun::B, "b"), (PaperRun::C, "c")] {
        // The rest filter's update is an option of the sampled law (the hold-aware default
        // treats every stiff loop linearly implicitly).
        let b = Scenario::builder(One, choice, PlatformKind::Unicycle)
            .duration(10.0)
            .log_every(1)
            .discretisation(DiscretisationConfig::Sampled);
        let (implicit, dir_i) = run_in(&scenario(b.clone()), &format!("nyq-{name}-implicit"));
        let explicit = scenario(b.rest_filter(RestFilterConfig::Explicit));
        let (explicit, dir_e) = run_in(&explicit, &format!("nyq-{name}-explicit"));
        let n_i = nyquist_oscillations(&std::fs::read_to_string(dir_i.join("timeseries.csv")).unwrap());
        let n_e = nyquist_oscillations(&std::fs::read_to_string(dir_e.join("timeseries.csv")).unwrap());
        assert!(n_e >= 2, "({name}) explicit: {n_e} oscillation bursts; expected the Nyquist oscillation");
        assert_eq!(n_i, 0, "({name}) implicit: {n_i} oscillation bursts");
        let (a, b) = (&implicit.summary, &explicit.summary);
        assert!(
            (a.path_length - b.path_length).abs() < 0.01 * b.path_length,
            "({name}) paths {} vs {}",
            a.path_length,
            b.path_length
        );
        assert_eq!(a.maneuvers, b.maneuvers, "({name}) maneuvers");
    }
}
