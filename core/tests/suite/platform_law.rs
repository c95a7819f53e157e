//! The platform law (37) and the controller's state through the whole step, at random
//! valid points, for every platform, every weight `Ψ` (constant, (53), (54), from `q̂`) and
//! every pre-compensation choice (Choice 1 with (51) or (40), Choice 2, Choice 3), with and
//! without the `Ψ̇ (h_s1 − h_s2)` drift term.
//!
//! The reference is built from definitions only: the companion frame `r̄_b = r_b f(α)⁻¹`
//! from eqs. (16)/Lemma 2; `h_s = Ψ ½ d_γ(r_*, r_d⁻¹ r̄_b)² + (1 − Ψ) d_γ(r̄_b, r̂)²` with the
//! virtual frame `r̂ = r̄_b r̃_b` (27)–(29); its gradient `a` by finite differences along
//! the three body directions of `r̄_b`; `∂h_s/∂t` by differences along the target's motion
//! and `r̂`'s motion at the `û` of (28); `b₁` of (51) as the body velocity of `r̄` under
//! the target's motion; then (36)–(37) and `w = H̄⁻¹ ū_b`.
//!
//! Tolerances: `a` and `∂h_s/∂t` are differences with `h = 1e−5` of O(1)–O(10) costs,
//! accurate to ~1e−9. `ū_b` is a smooth function of them with O(1) sensitivity except
//! through `(aᵀKa + μ)⁻¹`, and `μ ≥ 1e−4` bounds that to 1e4: ~1e−5 absolute at worst;
//! we ask 1e−5 relative with a floor of 1. The platform inputs `w = H̄⁻¹ ū_b` inherit
//! `|H̄⁻¹|`, up to ~1e3 for the car (`det H ≈ ε⁵/6`): 1e−5 relative with a floor of
//! `|H̄⁻¹|∞`. State updates are exact formulas: 1e−12.

use crate::common::*;
use companion_core::nalgebra::{Matrix3, Vector2};
use companion_core::{
    ControlLaw, PaperRun, Params, Platform, PlatformKind, Precompensation, RestFilter, Rpr, State, Weight,
    WeightMargins,
};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

const DT: f64 = 1e-3;
const H: f64 = 1e-5;

/// A law variant: weight × pre-compensation × Ψ̇-term, with random `K̄`, `D`, `μ`.
#[derive(Clone, Copy, Debug)]
struct Variant {
    k: usize,
    psi: f64,
    k_bar: V3,
    d: V3,
    mu: f64,
}

const VARIANTS: usize = 12;

fn variant() -> impl Strategy<Value = Variant> {
    (0usize..VARIANTS, 0.0..0.999f64, vec3(0.5, 100.0), vec3(0.2, 3.0), 1e-4..1e-1f64)
        .prop_map(|(k, psi, k_bar, d, mu)| Variant { k, psi, k_bar, d, mu })
}

fn margins() -> WeightMargins<f64, 3> {
    WeightMargins::paper(&Params::paper_limits(), &Params::paper_q_star())
}

fn params(v: &Variant) -> Params<f64, 3> {
    let mut p = paper(PaperRun::B);
    let s = &mut p.secondary;
    let filtered = s.weight;
    let nu = Precompensation::Full40 { nu: 1e-4 };
    let per_joint = Weight::PerJoint { margins: margins(), lambda: 1.66, xi: 1.0 };
    let from_q_hat = Weight::FromFilteredJoints { margins: margins() };
    let constant = Weight::Constant(v.psi);
    let (weight, pre, psi_dot) = match v.k {
        0 => (Weight::Constant(1.0), Precompensation::Full51, false), // run (a)
        1 => (filtered, nu, false),                                   // run (b)
        2 => (filtered, Precompensation::Off, false),                 // run (c)
        3 => (filtered, Precompensation::Partial, false),             // run (d)
        4 => (filtered, nu, true),
        5 => (filtered, Precompensation::Partial, true),
        6 => (constant, nu, false),
        7 => (constant, Precompensation::Partial, false),
        8 => (constant, Precompensation::Off, false),
        9 => (per_joint, Precompensation::Partial, true),
        10 => (from_q_hat, Precompensation::Partial, true),
        _ => (Weight::Constant(1.0), nu, false),
    };
    s.weight = weight;
    s.precompensation = pre;
    // (37) itself, evaluated at the start-of-step state; the linearly implicit default is
    // checked against it in `implicit_rest_filter_*` below.
    s.rest_filter = RestFilter::Explicit;
    s.psi_rate_in_drift = psi_dot;
    s.k_bar = v.k_bar;
    s.d = v.d;
    s.mu = v.mu;
    p
}

/// `Ψ` and `Ψ̇` the law should use, from (52)–(54) and the state.
fn weight_and_rate(w: &Weight<f64, 3>, st: &State<f64, 3>, q: &Q, q_hat_rate: &Q) -> (f64, f64) {
    let rate = |x: f64, target: f64, lambda: f64, xi: f64| -lambda * (x - target) / (xi + (x - target).abs());
    match w {
        Weight::Constant(psi) => (*psi, 0.0),
        Weight::Filtered { margins, lambda, xi } => {
            (st.psi, rate(st.psi, psi_tilde_reference(margins, q), *lambda, *xi))
        }
        Weight::PerJoint { margins, lambda, xi } => {
            let psi = st.sigma.norm_squared() / 3.0;
            let dot: f64 = (0..3)
                .map(|i| {
                    let s = st.sigma[i];
                    2.0 * s * rate(s, sigma_tilde_reference(margins, i, q[i]), *lambda, *xi) / 3.0
                })
                .sum();
            (psi, dot)
        }
        Weight::FromFilteredJoints { margins } => {
            let psi = psi_tilde_reference(margins, &st.q_hat);
            let dot = central_scalar(|s| psi_tilde_reference(margins, &(st.q_hat + q_hat_rate * s)), 0.0, H);
            (psi, dot)
        }
    }
}

fn check_step<P: Platform<f64>>(
    law: &ControlLaw<f64, P, Rpr<f64>, 3>,
    pt: &Point,
) -> Result<(), TestCaseError> {
    let (out, next) = step_point(law, pt, DT)?;
    let dg = &out.diagnostics;
    let prm = law.params();
    let sec = &prm.secondary;
    let (m, st) = (&pt.meas, &pt.state);
    let q = m.joints;
    let u_d = m.target_velocity;
    let prim = &prm.primary;
    let q_hat_rate = -(st.q_hat - q) * prim.filter_sigma / (prim.filter_xi + (st.q_hat - q).norm());

    // The companion frame (11).
    let alpha = st.alpha;
    let r_bar_b = mul(&v3(&m.base), &inv(&f_reference(P::KIND, &alpha)));
    check_close("companion frame r_b f(α)⁻¹", &v3(&dg.companion), &r_bar_b, 1e-12, 1.0)?;
    prop_assert_eq!(dg.alpha, alpha);

    // h_s (29) from its definition.
    // Ψ̃(q̂) has a kink where a joint's σ̃ reaches 1 (q̂ᵢ = q⁻ᵢ + δ⁻⁻ᵢ or q⁺ᵢ − δ⁺⁺ᵢ): its
    // gradient jumps from ±2/(3(δ − δ⁻⁻)) to 0. A central difference that straddles it is
    // not Ψ̇ (it averages the two sides), and through `(aᵀKa + μ)⁻¹` that error reaches ū_b
    // as O(1): such points are not a test of the law. (CI once drew q̂₁ 4.9e−7 from the kink,
    // within the difference's reach H|q̂̇₁| = 3.6e−6; the seed is kept in the regressions.)
    if let Weight::FromFilteredJoints { margins } = &sec.weight {
        for i in 0..3 {
            let reach = 2.0 * H * q_hat_rate[i].abs();
            let kinks = [LOWER[i] + margins.lower_inner[i], UPPER[i] - margins.upper_inner[i]];
            if kinks.iter().any(|k| (st.q_hat[i] - k).abs() <= reach) {
                return Err(TestCaseError::reject("q̂ within the difference's reach of Ψ̃'s kink"));
            }
        }
    }
    let (psi, psi_dot) = weight_and_rate(&sec.weight, st, &q, &q_hat_rate);
    let rest = sec.weight != Weight::Constant(1.0);
    let r_star = v3(&sec.preferred_pose);
    let r_d = v3(&m.target);
    let r_tilde = v3(&st.r_tilde);
    let r_hat = mul(&r_bar_b, &r_tilde);
    let h1 = |rb: &V3, rd: &V3| 0.5 * d_gamma(&r_star, &mul(&inv(rd), rb), sec.gamma_1).powi(2);
    let h2 = |rb: &V3, rh: &V3| if rest { d_gamma(rb, rh, sec.gamma_2).powi(2) } else { 0.0 };
    let h_s = |rb: &V3, rd: &V3, rh: &V3| psi * h1(rb, rd) + (1.0 - psi) * h2(rb, rh);
    check_close_scalar("Ψ", dg.psi, psi, 1e-12, 1e-12)?;
    check_close_scalar("h_s1", dg.h_s1, h1(&r_bar_b, &r_d), 1e-12, 1.0)?;
    check_close_scalar("h_s2", dg.h_s2, h2(&r_bar_b, &r_hat), 1e-12, 1.0)?;
    check_close_scalar("h_s", dg.h_s, h_s(&r_bar_b, &r_d, &r_hat), 1e-12, 1.0)?;

    // a by differences along the body directions of r̄_b.
    let a = V3::from_fn(|i, _| {
        central_scalar(|s| h_s(&flow(&r_bar_b, &V3::ith(i, 1.0), s), &r_d, &r_hat), 0.0, H)
    });
    // ∂h_s/∂t: the target moves with u_d, r̂ with û of (28); Ψ frozen (plus Ψ̇ (h_s1 − h_s2)
    // when the option asks for it).
    let u_hat = -sec.rest_sigma.component_mul(&r_tilde)
        / (sec.rest_xi + d_gamma(&V3::zeros(), &r_tilde, sec.gamma_2));
    let mut dh_dt = central_scalar(|s| h_s(&r_bar_b, &flow(&r_d, &u_d, s), &flow(&r_hat, &u_hat, s)), 0.0, H);
    if sec.psi_rate_in_drift {
        dh_dt += psi_dot * (h1(&r_bar_b, &r_d) - h2(&r_bar_b, &r_hat));
    }

    // (36)–(37).
    let frame = law.platform().companion(&alpha).expect("transverse");
    let hbar = frame.hbar;
    let k = hbar * Matrix3::from_diagonal(&sec.k_bar) * hbar.transpose();
    let (b1, b2) = match sec.precompensation {
        Precompensation::Full51 => {
            let r_bar = |s: f64| mul(&inv(&r_star), &mul(&inv(&flow(&r_d, &u_d, s)), &r_bar_b));
            (body(&r_bar(0.0), &central(r_bar, 0.0, H)), 0.0)
        }
        Precompensation::Full40 { nu } => {
            let n = a.norm_squared() + nu;
            (a * (dh_dt / n), dh_dt * nu / n)
        }
        Precompensation::Off => (V3::zeros(), 0.0),
        Precompensation::Partial => (V3::zeros(), dh_dt),
    };
    let coef = (a.dot(&sec.d.component_mul(&a)) + b2) / (a.dot(&(k * a)) + sec.mu);
    let u_bar = -b1 - k * a * coef;
    prop_assert_eq!(dg.saturation, 1.0);
    check_close("ū_b, eq. (37)", &dg.u_bar, &u_bar, 1e-5, 1.0)?;

    // Platform inputs w = H̄⁻¹ ū_b, and the command.
    let w = frame.hbar_inv * u_bar;
    let w_floor = frame.hbar_inv.amax().max(1.0);
    let c = &out.command.platform;
    let (got_w, alpha_rate) = match P::KIND {
        PlatformKind::Unicycle => (V3::new(c.v, c.omega, dg.alpha_rate[0]), Vector2::new(w[2], 0.0)),
        PlatformKind::Car => (V3::new(c.v, dg.alpha_rate[0], dg.alpha_rate[1]), Vector2::new(w[1], w[2])),
        PlatformKind::Omni => (V3::new(c.v, c.v_lat, c.omega), Vector2::zeros()),
    };
    check_close("(v, ·, α̇) = H̄⁻¹ ū_b", &got_w, &w, 1e-5, w_floor)?;
    check_close("α̇", &dg.alpha_rate, &alpha_rate, 1e-5, w_floor)?;
    match P::KIND {
        PlatformKind::Unicycle => prop_assert!(c.v_lat == 0.0 && c.v_xi == 0.0),
        PlatformKind::Omni => prop_assert!(c.v_xi == 0.0),
        PlatformKind::Car => {
            prop_assert_eq!(c.v_lat, 0.0);
            check_close_scalar("ω = v ξ", c.omega, c.v * m.steering, 1e-12, 1e-12)?;
            // (59) with ξ̇_f = ∂ξ_f/∂α · α̇ by differences of Lemma 2's ξ_f.
            // The step is scaled so that α moves by at most 1e−5 (α̇ can reach ~1e3).
            let h = H / dg.alpha_rate.amax().max(1.0);
            let xi_f_dot = central_scalar(|s| xi_f_reference(&(alpha + dg.alpha_rate * s)), 0.0, h);
            let want = -crate::common::car().k * (m.steering - xi_f_reference(&alpha)) + xi_f_dot;
            check_close_scalar("v_ξ, eq. (59)", c.v_xi, want, 1e-6, 1.0)?;
        }
    }

    // The state after the step: one Euler step of each filter, α exact (rate held).
    let wrap_all = |v: Vector2<f64>| Vector2::new(wrap(v[0]), wrap(v[1]));
    check_close("α + dt α̇", &next.alpha, &wrap_all(alpha + dg.alpha_rate * DT), 1e-12, 1.0)?;
    // q̂ is kept within the joint limits (a state bound; q̂ filters q, which is inside them).
    let q_hat_next = Q::from_fn(|i, _| (st.q_hat[i] + q_hat_rate[i] * DT).clamp(LOWER[i], UPPER[i]));
    check_close("q̂ + dt q̂̇", &next.q_hat, &q_hat_next, 1e-12, 1.0)?;
    match &sec.weight {
        Weight::Filtered { .. } => {
            check_close_scalar("Ψ + dt Ψ̇", next.psi, (st.psi + psi_dot * DT).clamp(0.0, 1.0), 1e-12, 1e-12)?;
        }
        Weight::PerJoint { margins, lambda, xi } => {
            for i in 0..3 {
                let s = st.sigma[i];
                let target = sigma_tilde_reference(margins, i, q[i]);
                let want = (s - DT * lambda * (s - target) / (xi + (s - target).abs())).clamp(0.0, 1.0);
                check_close_scalar("σᵢ + dt σ̇ᵢ", next.sigma[i], want, 1e-12, 1e-12)?;
            }
            check_close_scalar("Ψ = Σσᵢ²/3", next.psi, next.sigma.norm_squared() / 3.0, 1e-12, 1e-12)?;
        }
        Weight::Constant(_) | Weight::FromFilteredJoints { .. } => prop_assert_eq!(next.psi, st.psi),
    }
    if rest {
        // (28) driven by the companion frame's velocity actually applied: ū_b, and for the car
        // also the part [I₂ −S p_f; 0 1] (0, 0, v (ξ − ξ_f)) of (57).
        let q_mat = Matrix3::new(1.0, 0.0, -r_tilde[1], 0.0, 1.0, r_tilde[0], 0.0, 0.0, 1.0);
        let mut applied = dg.u_bar;
        if P::KIND == PlatformKind::Car {
            let z = c.v * (m.steering - xi_f_reference(&alpha));
            applied += V3::new(frame.f.y * z, -frame.f.x * z, z);
        }
        let rate = rbar(r_tilde[2]) * u_hat - q_mat * applied;
        let want = r_tilde + rate * DT;
        check_close(
            "r̃_b + dt ṙ̃_b",
            &v3(&next.r_tilde),
            &V3::new(want[0], want[1], wrap(want[2])),
            1e-12,
            1.0,
        )?;
    } else {
        // Not part of the law when Ψ ≡ 1: kept at its initial value.
        prop_assert_eq!(next.r_tilde, companion_core::Pose::identity());
    }
    prop_assert!(next.initialized && next.t0 == st.t0);
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn unicycle(pt in point(0.01), v in variant()) {
        check_step(&unicycle_law(params(&v)), &pt)?;
    }

    #[test]
    fn car(pt in point(0.01), v in variant()) {
        check_step(&car_law(params(&v)), &pt)?;
    }

    #[test]
    fn omnidirectional(pt in point(0.01), v in variant()) {
        check_step(&omni_law(params(&v)), &pt)?;
    }

    /// The documented option: with `psi_rate_in_drift` the drift gains `Ψ̇ (h_s1 − h_s2)`,
    /// which changes the command of Choice 3 whenever `Ψ̇ ≠ 0` (checked in value above).
    #[test]
    fn psi_rate_term_changes_the_command(pt in point(0.01)) {
        let mut p = paper(PaperRun::D);
        let without = step_point(&unicycle_law(p), &pt, DT)?.0;
        p.secondary.psi_rate_in_drift = true;
        let with = step_point(&unicycle_law(p), &pt, DT)?.0;
        let d = &without.diagnostics;
        let q = pt.meas.joints;
        let target = psi_tilde_reference(&margins(), &q);
        if (pt.state.psi - target).abs() > 1e-3 && (d.h_s1 - d.h_s2).abs() > 1e-3 {
            prop_assert!(with.diagnostics.u_bar != d.u_bar);
        }
    }
}

/// ū_b of (37) with Choice 2 (no pre-compensation) from definitions, as a function of the
/// rest filter's state `r̃_b` (everything else as at `pt`).
fn u_bar_choice2_reference<P: Platform<f64>>(
    law: &ControlLaw<f64, P, Rpr<f64>, 3>,
    pt: &Point,
    r_tilde: &V3,
) -> V3 {
    let sec = &law.params().secondary;
    let m = &pt.meas;
    let st = &pt.state;
    let prim = &law.params().primary;
    let q_hat_rate =
        -(st.q_hat - m.joints) * prim.filter_sigma / (prim.filter_xi + (st.q_hat - m.joints).norm());
    let (psi, _) = weight_and_rate(&sec.weight, st, &m.joints, &q_hat_rate);
    let r_bar_b = mul(&v3(&m.base), &inv(&f_reference(P::KIND, &st.alpha)));
    let r_hat = mul(&r_bar_b, r_tilde);
    let (r_star, r_d) = (v3(&sec.preferred_pose), v3(&m.target));
    let h_s = |rb: &V3| {
        psi * 0.5 * d_gamma(&r_star, &mul(&inv(&r_d), rb), sec.gamma_1).powi(2)
            + (1.0 - psi) * d_gamma(rb, &r_hat, sec.gamma_2).powi(2)
    };
    let a = V3::from_fn(|i, _| central_scalar(|s| h_s(&flow(&r_bar_b, &V3::ith(i, 1.0), s)), 0.0, H));
    let hbar = law.platform().companion(&st.alpha).expect("transverse").hbar;
    let k = hbar * Matrix3::from_diagonal(&sec.k_bar) * hbar.transpose();
    -(k * a) * (a.dot(&sec.d.component_mul(&a)) / (a.dot(&(k * a)) + sec.mu))
}

/// The linearly implicit rest filter (the default): ū_b is (37) evaluated at the end-of-step
/// filter state, linearised — `ū = (I + dt J Q)⁻¹ (ū₀ + dt J R̄(θ̃) û)` with
/// `J = ∂ū/∂r̃_b` — checked with Choice 2, where the core's `J` is exact, against a `J` by
/// differences of the reference (37). `J` is a difference (step 1e−5: (37) is strongly
/// nonlinear where `aᵀKa` is small, so larger steps carry truncation error) of a difference
/// (accurate to ~1e−9), amplified by cond K ~1e3: 1e−4 relative for the unicycle and omni.
fn check_implicit<P: Platform<f64>>(
    law: &ControlLaw<f64, P, Rpr<f64>, 3>,
    pt: &Point,
    rtol: f64,
) -> Result<(), TestCaseError> {
    let (out, _) = step_point(law, pt, DT)?;
    prop_assume!(out.diagnostics.saturation == 1.0);
    let sec = &law.params().secondary;
    let r_tilde = v3(&pt.state.r_tilde);
    let u0 = u_bar_choice2_reference(law, pt, &r_tilde);
    let j = {
        let mut j = Matrix3::zeros();
        for c in 0..3 {
            let h = 1e-5;
            let e = V3::ith(c, h);
            let d = (u_bar_choice2_reference(law, pt, &(r_tilde + e))
                - u_bar_choice2_reference(law, pt, &(r_tilde - e)))
                / (2.0 * h);
            j.set_column(c, &d);
        }
        j
    };
    let u_hat = -sec.rest_sigma.component_mul(&r_tilde)
        / (sec.rest_xi + d_gamma(&V3::zeros(), &r_tilde, sec.gamma_2));
    let q_mat = Matrix3::new(1.0, 0.0, -r_tilde[1], 0.0, 1.0, r_tilde[0], 0.0, 0.0, 1.0);
    let lhs = Matrix3::identity() + j * q_mat * DT;
    let want = lhs.try_inverse().expect("invertible") * (u0 + j * rbar(r_tilde[2]) * u_hat * DT);
    check_close("implicit ū_b", &out.diagnostics.u_bar, &want, rtol, 1.0)?;
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn implicit_rest_filter_unicycle(pt in point(0.01)) {
        check_implicit(&unicycle_law(paper(PaperRun::C)), &pt, 1e-4)?;
    }

    #[test]
    fn implicit_rest_filter_car(pt in point(0.01)) {
        let mut p = paper(PaperRun::C);
        p.secondary.k_bar = V3::new(1.0, 10.0, 10.0);
        // The car's K = H̄ K̄ H̄ᵀ has a condition number up to ~1e5 (det H ≈ 1e−3), which
        // multiplies the rounding of the reference's difference-of-a-difference J: 1e−3.
        check_implicit(&car_law(p), &pt, 1e-3)?;
    }

    #[test]
    fn implicit_rest_filter_omni(pt in point(0.01)) {
        check_implicit(&omni_law(paper(PaperRun::C)), &pt, 1e-4)?;
    }
}

/// The first step sets the state (SPEC §3): `q̂(0) = q(0)`, `Ψ(0) = Ψ̃(q(0))`,
/// `σᵢ(0) = σ̃ᵢ(qᵢ(0))`, `r̃_b(0) = 0`, `α` kept, time counted from the first step.
#[test]
fn first_step_initialises_the_state() {
    let q0 = Q::new(0.9, 0.66, -1.4); // q₁ and q₃ in their ramps, q₂ in the upper band.
    let meas = companion_core::Measurement {
        t: 7.0,
        base: companion_core::Pose::new(0.0, 0.0, 0.0),
        steering: 0.0,
        joints: q0,
        target: companion_core::Pose::new(2.6, 1.0, 0.0),
        target_velocity: trajectory_1(0.0),
    };
    for k in [1usize, 9, 10] {
        let law = unicycle_law(params(&Variant {
            k,
            psi: 0.5,
            k_bar: V3::new(1.0, 1.0, 100.0),
            d: V3::repeat(1.0),
            mu: 1e-4,
        }));
        let mut st = State::new();
        st.alpha = Vector2::new(0.3, 0.0);
        let out = law.step(&mut st, &meas, DT).expect("valid");
        let psi0 = psi_tilde_reference(&margins(), &q0);
        assert!(psi0 > 0.1 && psi0 < 1.0, "the point is meant to have an intermediate Ψ̃: {psi0}");
        assert!((out.diagnostics.psi - psi0).abs() < 1e-14, "Ψ(0) = Ψ̃(q(0)), variant {k}");
        assert!(st.initialized);
        assert_eq!(st.t0, 7.0);
        assert_eq!(st.q_hat, q0, "q̂(0) = q(0) and q̂̇(0) = 0");
        assert_eq!(out.diagnostics.alpha, Vector2::new(0.3, 0.0));
        assert_eq!(out.diagnostics.h_s2, 0.0, "r̃_b(0) = 0");
        // r̃_b after one step: 0 + dt (R̄(0) û(0) − ū_b) with û(0) = 0.
        let r = -out.diagnostics.u_bar * DT;
        assert!((v3(&st.r_tilde) - r).amax() < 1e-15);
        if k == 9 {
            for i in 0..3 {
                let s = sigma_tilde_reference(&margins(), i, q0[i]);
                // σ̇ᵢ(0) = 0: σᵢ stays σ̃ᵢ(qᵢ(0)).
                assert!((st.sigma[i] - s).abs() < 1e-14);
            }
        }
    }
}
