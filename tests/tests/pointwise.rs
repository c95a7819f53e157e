//! The default law on the continuous law's path: its pointwise distance from the continuous
//! closed loop ([`companion_tests::pointwise::reference`]: RK4 at 1e−5 s, the law evaluated
//! at every stage, no hold; halving its step changes it by < 2e−10), over `t ∈ [0, 10]` s,
//! the largest difference of any of `x_b`, `y_b`, `θ_b`, `q₁`, `q₂`, `q₃` at the 1 ms
//! instants, for T1 (a), T2 (a) and T1 (c) (unicycle, the paper's parameters).
//!
//! Measured at 1 ms / 0.5 ms: T1 (a) 3.05e−3 / 7.7e−4, T2 (a) 4.08e−3 / 1.02e−3, T1 (c)
//! 2.36e−3 / 5.8e−4 (with the unicycle's α step at its earlier first-order weight, 3.76e−3,
//! 5.31e−3 and 2.38e−3 at 1 ms; with the θ-weighted platform step and the first step
//! predicted with the robot at rest before that, 2.85e−2, 3.92e−2, 1.20e−2). Thresholds:
//! issue 25's aim, 5e−3 at 1 ms for all three (T2 (a) failed it at 5.31e−3 before the α
//! step took the exact weight); halving the period divides the distance by ≥ 3.2 (measured
//! 3.96, 3.98, 4.10: second order). T2 (a)'s 4.08e−3 is still `q₁` at 7.52 s displaced along
//! the motion by the phase of the transverse function's `α` (3.3e−3 rad ahead, made before
//! 5 s; the book's precision chapter and `--example pointwise_where`). Beside it the literal
//! sampling of the law (`--discretisation sampled`): first order, 4.16e−2 / 1.52e−1 /
//! 1.28e−2 at 1 ms.

use companion_core::wrap_angle;
use companion_core::PaperRun;
use companion_plant::PaperTrajectory::{self, One, Two};
use companion_tests::pointwise::{
    distance, every, reference, reference_alpha, sampled, sampled_literal, sampled_motion, worst,
};
use rayon::prelude::*;

const DURATION: f64 = 10.0;

#[test]
fn the_default_law_follows_the_continuous_law_to_second_order() {
    let runs: [(PaperTrajectory, PaperRun, &str, f64); 3] = [
        (One, PaperRun::A, "T1 (a)", 5e-3),
        (Two, PaperRun::A, "T2 (a)", 5e-3),
        (One, PaperRun::C, "T1 (c)", 5e-3),
    ];
    let out: Vec<[f64; 4]> = runs
        .par_iter()
        .map(|(t, r, _, _)| {
            let fine = reference(*t, *r, 1e-5, DURATION, 100);
            let at_1ms = distance(&sampled(*t, *r, 1e-3, DURATION), &fine);
            let at_half = distance(&every(&sampled(*t, *r, 5e-4, DURATION), 5e-4, 1e-3), &fine);
            let literal_1ms = distance(&sampled_literal(*t, *r, 1e-3, DURATION), &fine);
            let literal_half = distance(&every(&sampled_literal(*t, *r, 5e-4, DURATION), 5e-4, 1e-3), &fine);
            [at_1ms, at_half, literal_1ms, literal_half]
        })
        .collect();
    for ((_, _, name, bound), [d1, d2, l1, l2]) in runs.iter().zip(&out) {
        eprintln!("{name}: {d1:.3e} at 1 ms, {d2:.3e} at 0.5 ms (÷{:.2})", d1 / d2);
        eprintln!("{name}, literal sampling: {l1:.3e} at 1 ms, {l2:.3e} at 0.5 ms (÷{:.2})", l1 / l2);
        assert!(d1 <= bound, "{name}: {d1:e} at 1 ms > {bound:e}");
        assert!(d1 >= &(3.2 * d2), "{name}: halving the period divides the distance by {:.2} < 3.2", d1 / d2);
        // The literal sampling of the law (`--discretisation sampled`) takes the continuous
        // law's path too, at first order (measured ÷2.0, ÷3.0, ÷2.0 from 1 to 0.5 ms; T2 (a) not
        // yet in its asymptotic regime), and stays ≥ 2.5× farther from it than the default at
        // 1 ms (measured 14×, 37×, 5.4×).
        assert!(l1 >= &(1.8 * l2), "{name}: the literal sampling divides by {:.2} < 1.8", l1 / l2);
        assert!(
            l1 >= &(2.5 * d1),
            "{name}: the literal sampling is only {:.2}× the default's distance",
            l1 / d1
        );
    }
}

/// What T2 (a)'s largest distance at 1 ms is: `q₁` displaced along the loop's motion by the
/// phase of the transverse function's `α`, `Δα q̇₁/α̇`, which explains all of it but a few
/// percent (measured: 4.08e−3 at t = 7.522 s, `Δα` = 3.30e−3 rad, `Δα q̇₁/α̇` = 3.98e−3,
/// residual 1.0e−4; with the earlier weight of the `α` step 5.31e−3, `Δα` = 4.31e−3 rad;
/// asserted within 5 %); and the phase was there before the target started to turn
/// (measured `Δα` = 4.0e−3 rad at 5 s: it is made earlier and kept, not made at 7.5 s).
#[test]
fn t2a_largest_distance_is_the_phase_of_alpha() {
    let fine = reference(Two, PaperRun::A, 1e-5, DURATION, 100);
    let fine_alpha = reference_alpha(Two, PaperRun::A, 1e-5, DURATION, 100);
    let (s, motion) = sampled_motion(Two, PaperRun::A, 1e-3, DURATION);
    let (d, i, c) = worst(&s, &fine);
    let m = motion[i.min(motion.len() - 1)];
    let d_alpha = wrap_angle(m.alpha - fine_alpha[i]);
    let along = d_alpha * m.u_q[0] / m.alpha_rate;
    let diff = s[i][3] - fine[i][3];
    eprintln!(
        "T2 (a): {d:.3e} at t = {:.3} s in component {c}; Δα {d_alpha:.3e} rad explains {along:.3e}",
        i as f64 * 1e-3
    );
    assert_eq!(c, 3, "the largest difference is in q1");
    assert!(
        (diff - along).abs() <= 0.05 * diff.abs(),
        "q1 differs by {diff:e}, the phase of α explains {along:e}"
    );
    let d_alpha_5s = wrap_angle(motion[5000].alpha - fine_alpha[5000]);
    assert!(d_alpha_5s >= d_alpha, "Δα {d_alpha_5s:e} at 5 s, {d_alpha:e} at the largest difference");
}
