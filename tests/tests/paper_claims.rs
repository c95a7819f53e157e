//! The paper's claims (§4.3, SPEC §4) as assertions on the summaries of its eight runs:
//! unicycle platform, RPR arm, §4.3 parameters, dt = 1 ms, the default (hold-aware)
//! discretisation; trajectory 1 for 40 s, trajectory 2 for 120 s (Table 1). ‖e_p‖ is the
//! robot's true tracking error, from the plant.
//!
//! Every threshold is derived from what the paper says, with the reason in a comment. Two
//! facts shape them:
//! - A controller holds its command over a period, so `e_p` does not reach zero but a floor,
//!   second order in the period with the default discretisation: measured at 1 ms, 4.7e−7 on
//!   trajectory 1 (a) (the platform moving), 5.5e−8 on (b) and (c) (at rest), 1.3e−5 on
//!   trajectory 2 (a) (the target spinning). "e_p → 0" is checked against 3× that floor
//!   ([`FLOOR_T1`], [`FLOOR_T2`]); `tests/tests/sampled_data.rs` checks how it scales.
//! - Runs (b) and (d) are chaotic (SPEC §4): they are compared by statistics (path length,
//!   fraction of time tracked, maneuver counts), never point by point.
//!
//! Where a claim does not hold in these runs, the test asserts what does happen and says so.

use std::collections::HashMap;
use std::sync::OnceLock;

use companion_core::{PaperRun, PlatformKind};
use companion_plant::PaperTrajectory;
use companion_runtime::domain::controller::DiscretisationConfig;
use companion_runtime::domain::record::Summary;
use companion_runtime::domain::scenario::Scenario;
use companion_tests::{median, nearby_summaries, scenario, summaries};

/// The nearby starts on each side of the paper's in the statistical comparisons of chaotic
/// runs: `k = ±1…±NEARBY` (24 starts).
const NEARBY: i32 = 12;

/// Summaries of the paper's eight runs, keyed by (trajectory, choice).
fn runs() -> &'static HashMap<(u8, char), Summary> {
    static RUNS: OnceLock<HashMap<(u8, char), Summary>> = OnceLock::new();
    RUNS.get_or_init(|| {
        let mut keys = Vec::new();
        let mut list = Vec::new();
        for traj in [1u8, 2] {
            let duration = if traj == 1 { 40.0 } else { 120.0 };
            for choice in ['a', 'b', 'c', 'd'] {
                let t = if traj == 1 { PaperTrajectory::One } else { PaperTrajectory::Two };
                let c = match choice {
                    'a' => PaperRun::A,
                    'b' => PaperRun::B,
                    'c' => PaperRun::C,
                    _ => PaperRun::D,
                };
                let s = scenario(Scenario::builder(t, c, PlatformKind::Unicycle).duration(duration));
                keys.push((traj, choice));
                list.push((s.name.clone(), s));
            }
        }
        let refs: Vec<(&str, _)> = list.iter().map(|(n, s)| (n.as_str(), s.clone())).collect();
        keys.into_iter().zip(summaries(&refs)).collect()
    })
}

fn get(traj: u8, choice: char) -> &'static Summary {
    &runs()[&(traj, choice)]
}

/// "→ 0" on trajectory 1 at dt = 1 ms: 3× the largest measured floor (4.7e−7, run (a)).
const FLOOR_T1: f64 = 1.5e-6;

/// "→ 0" on trajectory 2 while the target moves: 3× run (a)'s measured floor (1.25e−5).
const FLOOR_T2: f64 = 4e-5;

/// The paper's eight runs (its claim; the runs with the Ψ̇ term are not the paper's, and
/// (b) with it can diverge: `psi_rate_term_makes_b_and_d_chatter`).
#[test]
fn every_run_keeps_the_joints_strictly_inside_their_limits() {
    for (key, s) in runs() {
        for (i, m) in s.min_joint_margin.iter().enumerate() {
            assert!(*m > 0.0, "{key:?}: joint {} reached its limit (margin {m})", i + 1);
        }
        assert_eq!(s.rejected_steps, 0, "{key:?}: the controller rejected a measurement");
    }
}

/// Trajectory 1 (a): "drives h_s and e_p to zero" (Figs. 4a, 6a).
#[test]
fn traj1_a_drives_h_s_and_e_p_to_zero() {
    let a = get(1, 'a');
    // h_s is non-increasing under Choice 1 with b₂ = 0 and tends to zero: from ≈1.2 it must
    // have lost at least four orders of magnitude in 40 s (it decays like the gradient flow
    // of (39); the core's tests check monotonicity step by step).
    assert!(a.initial_h_s > 1.0, "initial h_s {}", a.initial_h_s);
    assert!(a.final_h_s < 1e-4 * a.initial_h_s, "final h_s {} (initial {})", a.final_h_s, a.initial_h_s);
    // e_p reaches the hold's floor after the transient (≈5 s in the paper's Fig. 4a).
    assert!(a.final_ep_norm < FLOOR_T1, "final |e_p| {}", a.final_ep_norm);
    assert!(a.max_ep_norm_after_20s < FLOOR_T1, "max |e_p| after 20 s {}", a.max_ep_norm_after_20s);
    assert!(a.ep_settling_time_s < 20.0, "settled at {} s", a.ep_settling_time_s);
}

/// Trajectory 1 (a): "...while the platform keeps moving periodically" (Figs. 3a, 5a).
#[test]
fn traj1_a_platform_keeps_moving() {
    let a = get(1, 'a');
    // After the transient the platform follows the target's 4 s circle with periodic
    // motions: over 20 s it travels much more than the circle's 0.1 m radius.
    assert!(a.path_length_after_20s > 1.0, "path after 20 s {} m", a.path_length_after_20s);
    assert!(a.maneuvers >= 10, "maneuvers {}", a.maneuvers);
}

/// Trajectory 1 (b): "reduces the amplitude of the platform's displacements. This does not
/// impede the achievement of the manipulation objective" (Figs. 3b, 4b).
#[test]
fn traj1_b_moves_less_and_still_tracks() {
    let (a, b) = (get(1, 'a'), get(1, 'b'));
    assert!(b.path_length < 0.5 * a.path_length, "path (b) {} vs (a) {}", b.path_length, a.path_length);
    assert!(b.max_ep_norm_after_20s < FLOOR_T1, "max |e_p| after 20 s {}", b.max_ep_norm_after_20s);
    assert!(b.fraction_ep_below_1e_3_after_20s > 0.99, "tracked {}", b.fraction_ep_below_1e_3_after_20s);
}

/// Trajectory 1 (c): "a much smoother motion of the platform and convergence to a fixed
/// posture. The manipulation objective is again perfectly achieved" (Figs. 3c–5c).
#[test]
fn traj1_c_is_smoother_and_comes_to_rest() {
    let (b, c) = (get(1, 'b'), get(1, 'c'));
    assert!(c.maneuvers < b.maneuvers, "maneuvers (c) {} vs (b) {}", c.maneuvers, b.maneuvers);
    assert!(c.max_abs_v < b.max_abs_v, "max |v| (c) {} vs (b) {}", c.max_abs_v, b.max_abs_v);
    // A fixed posture: the platform does not move after the transient (1 mm in 20 s).
    assert!(c.path_length_after_20s < 1e-3, "path after 20 s {}", c.path_length_after_20s);
    assert!(c.max_ep_norm_after_20s < FLOOR_T1, "max |e_p| after 20 s {}", c.max_ep_norm_after_20s);
}

/// Trajectory 1 (c): "...although this phase lasts longer". Holds against (a); against (b)
/// it does not: here (c) settles (‖e_p‖ < 1e−3 for good) about 2 s *before* (b), which is
/// chaotic. Asserted as observed.
#[test]
fn traj1_c_transient_is_longer_than_a_but_not_than_b() {
    let (a, b, c) = (get(1, 'a'), get(1, 'b'), get(1, 'c'));
    assert!(
        c.ep_settling_time_s > a.ep_settling_time_s,
        "(c) {} vs (a) {}",
        c.ep_settling_time_s,
        a.ep_settling_time_s
    );
    assert!(
        c.ep_settling_time_s < b.ep_settling_time_s,
        "(c) {} vs (b) {}",
        c.ep_settling_time_s,
        b.ep_settling_time_s
    );
}

/// Trajectory 1 (d): "not very different from the one obtained in simulation (c)". The
/// platform's motion is alike (path, speeds); but (d) keeps creeping at a few mm/s and
/// `e_p` spikes each time q₂ nears its upper limit, decaying slowly, instead of coming to
/// rest within 40 s. Asserted as observed.
#[test]
fn traj1_d_moves_like_c_but_settles_slowly() {
    let (c, d) = (get(1, 'c'), get(1, 'd'));
    assert!(d.path_length < 1.5 * c.path_length, "path (d) {} vs (c) {}", d.path_length, c.path_length);
    assert!(d.max_abs_v < 1.5 * c.max_abs_v, "max |v| (d) {} vs (c) {}", d.max_abs_v, c.max_abs_v);
    // Creeping, not at rest: more than (c)'s zero but far less than (a)'s periodic motion.
    assert!(d.path_length_after_20s > 10.0 * c.path_length_after_20s.max(1e-4));
    assert!(d.path_length_after_20s < 0.1 * get(1, 'a').path_length_after_20s);
    // Tracking errors after 20 s stay at the centimetre level and end below 1 cm.
    assert!(d.max_ep_norm_after_20s < 0.05, "max |e_p| after 20 s {}", d.max_ep_norm_after_20s);
    assert!(d.final_ep_norm < 1e-2, "final |e_p| {}", d.final_ep_norm);
}

/// Trajectory 2 (a): "tracks with error converging to zero ... at the cost of many
/// maneuvers" (Figs. 7a–9a).
#[test]
fn traj2_a_tracks_with_many_maneuvers() {
    let (a, b) = (get(2, 'a'), get(2, 'b'));
    // Never loses tracking: the error after 20 s stays within 3× the hold floor (largest
    // while the target spins, Table 1's rotations)...
    assert!(a.max_ep_norm_after_20s < FLOOR_T2, "max |e_p| after 20 s {}", a.max_ep_norm_after_20s);
    assert_eq!(a.fraction_ep_below_1e_3_after_20s, 1.0, "tracked");
    // ...and converges to zero once the target stops (t ≥ 115 s).
    assert!(a.final_ep_norm < 1e-6, "final |e_p| {}", a.final_ep_norm);
    assert!(a.maneuvers > b.maneuvers, "maneuvers (a) {} vs (b) {}", a.maneuvers, b.maneuvers);
    assert!(a.maneuvers > 100, "maneuvers {}", a.maneuvers);
}

/// Trajectory 2 (b): "reduces the number of the platform's maneuvers ... no longer ensures
/// perfect tracking of the target all the time" (Figs. 8b, 9b).
#[test]
fn traj2_b_fewer_maneuvers_loses_tracking_at_times() {
    let (a, b) = (get(2, 'a'), get(2, 'b'));
    assert!(b.maneuvers < a.maneuvers);
    assert!(b.path_length < a.path_length, "path (b) {} vs (a) {}", b.path_length, a.path_length);
    assert!(b.fraction_ep_below_1e_3_after_20s < 0.95, "tracked {}", b.fraction_ep_below_1e_3_after_20s);
    assert!(b.max_ep_norm_after_20s > 1e-2, "max |e_p| after 20 s {}", b.max_ep_norm_after_20s);
}

/// Trajectory 2 (c), (d): "even fewer maneuvers and smaller platform's velocities" than (b),
/// "as can be observed by comparing Figures 9(c)–9(d) with 9(a)–9(b)"; "the amount of time
/// during which the tracking ... is perfectly executed is not very different" (Figs. 8, 9).
/// The figures compare typical speeds, so the root-mean-square speed is compared; the single
/// largest speed of (d) (one spike while catching up) is about that of (b).
#[test]
fn traj2_c_d_fewer_maneuvers_smaller_speeds_similar_tracking() {
    let (b, c, d) = (get(2, 'b'), get(2, 'c'), get(2, 'd'));
    for (name, x) in [("c", c), ("d", d)] {
        assert!(x.maneuvers < b.maneuvers, "maneuvers ({name}) {} vs (b) {}", x.maneuvers, b.maneuvers);
        assert!(x.rms_v < 0.5 * b.rms_v, "rms v ({name}) {} vs (b) {}", x.rms_v, b.rms_v);
        assert!(x.rms_omega < 0.5 * b.rms_omega, "rms ω ({name}) {} vs (b) {}", x.rms_omega, b.rms_omega);
        assert!(x.path_length < b.path_length);
        // "Not very different": within 20 percentage points of (b)'s tracked fraction.
        let gap = (x.fraction_ep_below_1e_3_after_20s - b.fraction_ep_below_1e_3_after_20s).abs();
        assert!(gap < 0.2, "tracked ({name}) vs (b) differ by {gap}");
        assert!(x.fraction_ep_below_1e_3_after_20s < 1.0, "({name}) tracks all the time");
    }
    assert!(c.max_abs_v < b.max_abs_v, "max |v| (c) {} vs (b) {}", c.max_abs_v, b.max_abs_v);
}

/// Trajectory 2 (d): "slightly more reactive and effective control than (c) ... coherent with
/// sharper variations of the platform velocities" (Figs. 9c, 9d). The sharper velocities
/// hold; "more effective" (more time tracked) does not here: (d) and (c) track for the same
/// fraction of the time within one percentage point. Asserted as observed.
#[test]
fn traj2_d_is_sharper_than_c() {
    let (c, d) = (get(2, 'c'), get(2, 'd'));
    assert!(d.max_abs_v > c.max_abs_v, "max |v| (d) {} vs (c) {}", d.max_abs_v, c.max_abs_v);
    assert!(d.v_sign_changes > c.v_sign_changes);
    let gap = (d.fraction_ep_below_1e_3_after_20s - c.fraction_ep_below_1e_3_after_20s).abs();
    assert!(gap < 0.05, "tracked (d) vs (c) differ by {gap}");
}

/// SPEC §3: with the Ψ̇ (h_s1 − h_s2) term in the pre-compensated drift, runs (b) and (d)
/// chatter — `b̂₂/(aᵀKa + μ)` and `b̂₁ = ∂h_s/∂t · a/(‖a‖² + ν)` become very high gains near
/// `a = 0`. The runs are chaotic (with the term, differences grow within 0.1 s; SPEC §4), so
/// they are compared by statistics over [`NEARBY`] starts each side of the paper's
/// (`companion_tests::nearby_start`, `k = ±1…±12`: the target's `x` and `q₁(0)` offset by
/// `k·10⁻⁴`), never one by one: the medians of the peak `|v|` and of the sign changes of
/// `v`. One run from the paper's start is no test of it: the default law's T2 (d) with the
/// term peaks at 36.3 m/s there, 9.7 with the α step's earlier weight, 28.8 with that
/// weight's operations merely reordered (`docs/explore/alpha-step`).
///
/// Measured (medians over the 24 starts, peak `|v|` in m/s / sign changes; without the term
/// → with it; `cargo run --release -p companion-tests --example nearby_starts`):
///
/// ```text
///                     sampled                      default
/// T1 (b)   2.3 / 12  → 125.9 / 161       2.3 / 12  →  5.6 / 27
/// T2 (b)   4.3 / 159 → 142.6 / 559       8.9 / 153 → 20.3 / 193
/// T2 (d)   3.9 / 35  →  29.8 / 116       3.1 / 34  → 19.1 / 193
/// ```
///
/// With the literal sampling of the law (`Discretisation::Sampled`) all three chatter. The
/// hold-aware default treats those gains linearly implicitly, and (b)'s chattering nearly
/// vanishes: it is mostly an artifact of sampling a stiff gain explicitly. (d) on
/// trajectory 2 still chatters in direction (sign changes ×5.7), at a lower peak speed
/// than the sampled law's: Choice 3 puts the drift in `b̂₂`, whose gain grows without bound
/// as `a → 0`, not only stiffly. Asserted as observed.
#[test]
fn psi_rate_term_makes_b_and_d_chatter() {
    use DiscretisationConfig::{Midpoint, Sampled};
    use PaperTrajectory::{One, Two};
    let cases = [(One, PaperRun::B, "T1 (b)"), (Two, PaperRun::B, "T2 (b)"), (Two, PaperRun::D, "T2 (d)")];
    let starts: Vec<i32> = (1..=NEARBY).flat_map(|k| [-k, k]).collect();
    // Per case, in this order: sampled without the term, with it; default without, with;
    // each the (median peak |v|, median sign changes of v) over the starts.
    let mut stats = Vec::new();
    for (t, run, _) in cases {
        for law in [Sampled, Midpoint] {
            for psidot in [false, true] {
                let out = nearby_summaries(t, run, law, psidot, 1e-3, &starts);
                let peak: Vec<f64> = out.iter().map(|s| s.max_abs_v).collect();
                let signs: Vec<f64> = out.iter().map(|s| s.v_sign_changes as f64).collect();
                stats.push((median(&peak), median(&signs)));
            }
        }
    }
    for (i, (_, run, name)) in cases.iter().enumerate() {
        let [sampled_without, sampled, default_without, default] = [0, 1, 2, 3].map(|j| stats[4 * i + j]);
        let msg = format!(
            "{name}, medians (peak |v|, sign changes) without → with the term: sampled {sampled_without:?} → \
             {sampled:?}, default {default_without:?} → {default:?}"
        );
        // The sampled law chatters: half as many sign changes again, five times the speed.
        assert!(sampled.1 > 1.5 * sampled_without.1, "{msg}");
        assert!(sampled.0 > 5.0 * sampled_without.0, "{msg}");
        if *run == PaperRun::B {
            // With the default (b) hardly does: under half the sampled law's sign changes
            // and a fifth of its peak speed.
            assert!(2.0 * default.1 < sampled.1, "{msg}");
            assert!(5.0 * default.0 < sampled.0, "{msg}");
        } else {
            // (d) on trajectory 2 chatters with the default too, in direction (over three
            // times the sign changes), at a peak speed below the sampled law's.
            assert!(default.1 > 3.0 * default_without.1, "{msg}");
            assert!(default.0 < sampled.0, "{msg}");
        }
    }
}
