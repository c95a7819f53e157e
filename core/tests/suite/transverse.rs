//! Transverse functions and the companion frame (§2.3, §5): Lemma 1's determinant,
//! Lemma 2's transversality, and `H̄(α)` (eqs. 13–15, 57–60) checked as what it claims to
//! be — the map from the platform's inputs and `α̇` to the body velocity of the companion
//! frame `r̄_b = r_b f(α)⁻¹` — by finite differences of that frame along real platform
//! motions.
//!
//! The transverse functions are re-implemented here from eqs. (16) and Lemma 2 with
//! `std`'s trigonometry; the frame is composed with the test's own SE(2).
//!
//! Tolerances: `f` and its derivatives are O(ε) ≤ O(1) and the velocities O(1), so
//! central differences with `h = 1e−5` are accurate to ~1e−10; we ask 1e−7 (relative,
//! floor 1). Closed forms are compared at 1e−12.

use crate::common::*;
use companion_core::nalgebra::{Matrix3, Vector2};
use companion_core::{
    CarLike, ControlLaw, Omnidirectional, PaperRun, ParamError, Params, Platform, Rpr, Rule, Unicycle,
};
use proptest::prelude::*;

const H: f64 = 1e-5;
const FD_TOL: f64 = 1e-7;

/// Lemma 1's closed form, `det H = −(ε₁ε₂/2) cos(arctan(ε₂ cos α)) = −(ε₁ε₂/2)/√(1 + ε₂² cos² α)`.
fn lemma1_det(e1: f64, e2: f64, a: f64) -> f64 {
    -(e1 * e2 / 2.0) / (1.0 + (e2 * a.cos()).powi(2)).sqrt()
}

/// `[I₂ −S p; 0 1] (0, 0, z)`: the (57) term of a car whose steering is off `ξ_f`.
fn steering_mismatch_term(pf: &V3, z: f64) -> V3 {
    V3::new(pf[1] * z, -pf[0] * z, z)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn lemma1_determinant_closed_form(a in -20.0..20.0f64, e1 in 0.01..3.0f64, e2 in 0.01..5.0f64) {
        let uni = Unicycle::new(e1, e2);
        let c = uni.companion(&Vector2::new(a, 0.0)).expect("transverse");
        let want = lemma1_det(e1, e2, a);
        check_close_scalar("det_h vs Lemma 1", c.det_h, want, 1e-12, 0.0)?;
        check_close_scalar("det_h_closed_form", uni.det_h_closed_form(a), want, 1e-12, 0.0)?;
        check_close_scalar("det H̄ = det H", c.hbar.determinant(), want, 1e-10, 0.0)?;
        // |det H| ≥ (ε₁ε₂/2)/√(1 + ε₂²) > 0 for every α.
        prop_assert!(c.det_h.abs() >= 0.999_999 * (e1 * e2 / 2.0) / (1.0 + e2 * e2).sqrt());
        check_close("f(α), eq. (16)", &v3(&c.f), &f_unicycle(e1, e2, a), 1e-12, 1.0)?;
        check_close("H̄⁻¹ H̄", &(c.hbar_inv * c.hbar), &Matrix3::identity(), 1e-9, 1.0)?;
    }

    /// Eqs. (13)–(15): moving the unicycle with `(v, ω)` and `α` with `α̇`, the companion
    /// frame `r_b f(α)⁻¹` has body velocity `H̄(α) (v, ω, α̇)`.
    #[test]
    fn unicycle_hbar_is_the_companion_frames_velocity(
        r_b in pose_in(3.0, PI), a0 in -PI..PI, w in vec3(-1.5, 1.5),
        e1 in 0.05..1.0f64, e2 in 0.05..2.0f64,
    ) {
        let uni = Unicycle::new(e1, e2);
        let c = uni.companion(&Vector2::new(a0, 0.0)).expect("transverse");
        let u_b = V3::new(w[0], 0.0, w[1]);
        let frame = |t: f64| mul(&flow(&r_b, &u_b, t), &inv(&f_unicycle(e1, e2, a0 + w[2] * t)));
        let fd = body(&frame(0.0), &central(frame, 0.0, H));
        check_close("ū_b = H̄ w", &(c.hbar * w), &fd, FD_TOL, 1.0)?;
    }

    /// Eqs. (57)–(60): the car moves with `(v, 0, v ξ)`, `α` with `(α̇₁, α̇₂)`; with
    /// `ξ = ξ_f(α)` the companion frame's body velocity is `H̄(α)(v, α̇₁, α̇₂)` (60), and
    /// with `ξ ≠ ξ_f(α)` it has the extra term `[I₂ −S p_f; 0 1](0, 0, v(ξ − ξ_f))` (57).
    #[test]
    fn car_hbar_is_the_companion_frames_velocity(
        r_b in pose_in(3.0, PI), a0 in (-PI..PI, -PI..PI), w in vec3(-1.5, 1.5),
        eps in 0.1..1.0f64, eta in (0.2..3.0f64, 0.2..3.0f64), dxi in -1.0..1.0f64,
    ) {
        // η₂ from η₁, η₃ so that 6 η₂ η₃ > 8 η₃ + η₁ η₂ holds: η₂ > 8 η₃ / (6 η₃ − η₁).
        let (n1, n3) = eta;
        prop_assume!(6.0 * n3 > n1 * 1.2);
        let n2 = 1.1 * 8.0 * n3 / (6.0 * n3 - n1);
        let car = CarLike::new(eps, [n1, n2, n3], 1.0);
        prop_assert_eq!(Platform::<f64>::validate(&car), Ok(()));
        let alpha0 = Vector2::new(a0.0, a0.1);
        let c = car.companion(&alpha0).expect("transverse");
        let (pf, xi_f) = f_car(eps, [n1, n2, n3], &alpha0);
        check_close("f(α), Lemma 2", &v3(&c.f), &pf, 1e-12, 1.0)?;
        check_close_scalar("ξ_f(α), Lemma 2", c.xi_f, xi_f, 1e-12, 1.0)?;
        let rate = Vector2::new(w[1], w[2]);
        for xi in [xi_f, xi_f + dxi] {
            let u_b = V3::new(w[0], 0.0, w[0] * xi);
            let frame = |t: f64| mul(&flow(&r_b, &u_b, t), &inv(&f_car(eps, [n1, n2, n3], &(alpha0 + rate * t)).0));
            let fd = body(&frame(0.0), &central(frame, 0.0, H));
            let want = c.hbar * w + steering_mismatch_term(&pf, w[0] * (xi - xi_f));
            check_close("ū_b, eq. (57)", &want, &fd, FD_TOL, 1.0)?;
        }
        check_close_scalar("det_h", c.det_h, c.hbar.determinant(), 1e-9, 1e-12)?;
        check_close("H̄⁻¹ H̄", &(c.hbar_inv * c.hbar), &Matrix3::identity(), 1e-6, 1.0)?;
    }

    /// `∂ξ_f/∂α` (used by the steering law (59)) against finite differences of Lemma 2's `ξ_f`.
    #[test]
    fn car_dxi_f_matches_finite_differences(a0 in (-PI..PI, -PI..PI), eps in 0.1..1.5f64) {
        let eta = [1.0, 2.0, 1.0];
        let car = CarLike::new(eps, eta, 1.0);
        let alpha = Vector2::new(a0.0, a0.1);
        let c = car.companion(&alpha).expect("transverse");
        let fd = Vector2::new(
            central_scalar(|s| f_car(eps, eta, &Vector2::new(s, alpha[1])).1, alpha[0], H),
            central_scalar(|s| f_car(eps, eta, &Vector2::new(alpha[0], s)).1, alpha[1], H),
        );
        // ξ_f is O(ε): a floor of 0.01 makes the bound ~1e−9 absolute.
        check_close("∂ξ_f/∂α", &c.dxi_f, &fd, 1e-7, 0.01)?;
    }

    /// The steering law (59): `v_ξ = −k (ξ − ξ_f(α)) + ∂ξ_f/∂α · α̇`.
    #[test]
    fn car_steering_rate_is_eq59(a0 in (-PI..PI, -PI..PI), xi in -2.0..2.0f64, rate in (-3.0..3.0f64, -3.0..3.0f64), k in 0.1..20.0f64) {
        let car = CarLike::new(0.4, [1.0, 2.0, 1.0], k);
        let alpha = Vector2::new(a0.0, a0.1);
        let c = car.companion(&alpha).expect("transverse");
        let rate = Vector2::new(rate.0, rate.1);
        let xi_f = |a: &Vector2<f64>| f_car(0.4, [1.0, 2.0, 1.0], a).1;
        // ξ̇_f along α(t) = α + t α̇, by differences of the independent ξ_f.
        let xi_f_dot = central_scalar(|t| xi_f(&(alpha + rate * t)), 0.0, H);
        let want = -k * (xi - xi_f(&alpha)) + xi_f_dot;
        check_close_scalar("v_ξ", car.steering_rate(&c, xi, &rate), want, 1e-7, 1.0)?;
    }

    #[test]
    fn omnidirectional_companion_is_the_platform(a0 in (-PI..PI, -PI..PI)) {
        let c = Platform::<f64>::companion(&Omnidirectional, &Vector2::new(a0.0, a0.1)).expect("always");
        prop_assert_eq!(v3(&c.f), V3::zeros());
        prop_assert_eq!(c.hbar, Matrix3::identity());
        prop_assert_eq!(c.hbar_inv, Matrix3::identity());
        prop_assert_eq!(c.det_h, 1.0);
    }
}

/// Lemma 1 on a dense grid: `|det H(α)| ≥ (ε₁ε₂/2)/√(1 + ε₂²)` and the sign never changes.
#[test]
fn lemma1_transversal_on_a_dense_grid() {
    for (e1, e2) in [(0.2f64, 0.4f64), (0.01, 0.01), (1.0, 3.0), (0.5, 10.0)] {
        let uni = Unicycle::new(e1, e2);
        let bound = (e1 * e2 / 2.0) / (1.0 + e2 * e2).sqrt();
        for i in 0..4096 {
            let a = i as f64 * 2.0 * PI / 4096.0;
            let d = uni.companion(&Vector2::new(a, 0.0)).expect("transverse").det_h;
            assert!(d < 0.0 && -d >= 0.999_999 * bound, "ε = ({e1}, {e2}), α = {a}: det H = {d}");
        }
    }
}

/// The determinant of Lemma 2's `H(α)` on an `n × n` grid of `T²`.
fn car_det_grid(car: &CarLike<f64>, n: usize) -> Vec<f64> {
    let step = 2.0 * PI / n as f64;
    let mut out = Vec::with_capacity(n * n);
    for i in 0..n {
        for j in 0..n {
            let a = Vector2::new(i as f64 * step, j as f64 * step);
            out.push(car.companion(&a).expect("H̄ invertible").det_h);
        }
    }
    out
}

/// Lemma 2 on a dense grid, for `η = (1, 2, 1)` and several `ε`: `det H` keeps one sign and
/// stays away from zero *between* the grid points too. The argument, cell by cell: with
/// `L` a bound on `|∂det/∂αᵢ|` over a cell of side `Δ`, every point of the cell is within
/// `Δ` (in each coordinate) of its corners, so `|det|` there is at least
/// `min_corners |det| − 2 L Δ`. `L` is estimated by the largest difference quotient on the
/// edges of the cell and of its eight neighbours, and doubled for safety.
#[test]
fn lemma2_transversal_on_a_dense_grid() {
    let n = 256;
    let step = 2.0 * PI / n as f64;
    for eps in [0.05, 0.2, 0.4, 1.0, 2.0] {
        let car = CarLike::new(eps, [1.0, 2.0, 1.0], 1.0);
        let det = car_det_grid(&car, n);
        let at = |i: usize, j: usize| det[(i % n) * n + (j % n)];
        // Largest edge difference quotient leaving node (i, j).
        let edge = |i: usize, j: usize| {
            ((at(i + 1, j) - at(i, j)).abs() / step).max((at(i, j + 1) - at(i, j)).abs() / step)
        };
        let all_one_sign = det.iter().all(|d| *d > 0.0) || det.iter().all(|d| *d < 0.0);
        assert!(all_one_sign, "ε = {eps}: det H changes sign");
        for i in 0..n {
            for j in 0..n {
                let mut lip: f64 = 0.0;
                for di in 0..4 {
                    for dj in 0..4 {
                        lip = lip.max(edge(i + n - 1 + di, j + n - 1 + dj));
                    }
                }
                let corner_min = [at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)]
                    .iter()
                    .fold(f64::INFINITY, |m, d| m.min(d.abs()));
                assert!(
                    corner_min > 2.0 * (2.0 * lip) * step,
                    "ε = {eps}, cell ({i}, {j}): min |det H| = {corner_min:e}, L = {lip:e}"
                );
            }
        }
        if eps == 0.4 {
            // Cross-check of the scale: for small ε the minimum of det H is close to ε⁵/6.
            let min = det.iter().fold(f64::INFINITY, |m, d| m.min(d.abs()));
            assert!((min / eps.powi(5) - 1.0 / 6.0).abs() < 0.02, "min det/ε⁵ = {}", min / eps.powi(5));
        }
    }
    // SPEC §3: "≈1e−3 for ε = 0.3, η = (1, 2, 1)".
    let det = car_det_grid(&CarLike::new(0.3, [1.0, 2.0, 1.0], 1.0), 64);
    let (lo, hi) = det.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), d| (lo.min(d.abs()), hi.max(d.abs())));
    assert!(lo > 1e-4 && hi < 1e-2 && lo < 1e-3 && hi > 1e-3, "|det H| in [{lo:e}, {hi:e}]");
}

/// A car function that breaks Lemma 2's inequality is rejected, and this one really is
/// not transverse: its `det H` changes sign on `T²`.
#[test]
fn lemma2_violation_is_rejected_and_really_singular() {
    let bad = CarLike::new(0.3, [1.0, 1.0, 1.0], 1.0); // 6 < 8 + 1
    assert_eq!(Platform::<f64>::validate(&bad), Err(ParamError::new("eta", Rule::Transversality)));
    let det = car_det_grid(&bad, 128);
    assert!(det.iter().any(|d| *d > 0.0) && det.iter().any(|d| *d < 0.0), "expected a sign change");
    // The boundary 6η₂η₃ = 8η₃ + η₁η₂ (12 = 8 + 4) is rejected too (the inequality is strict).
    let edge = CarLike::new(0.3, [2.0, 2.0, 1.0], 1.0);
    assert_eq!(Platform::<f64>::validate(&edge), Err(ParamError::new("eta", Rule::Transversality)));
    // Through the law's constructor.
    let err = ControlLaw::new(Params::<f64, 3>::paper(PaperRun::C), bad, Rpr::paper()).unwrap_err();
    assert_eq!(err, ParamError::new("eta", Rule::Transversality));
}

#[test]
fn transverse_function_parameters_are_validated() {
    let uni = |e1: f64, e2: f64| Platform::<f64>::validate(&Unicycle::new(e1, e2));
    assert_eq!(uni(0.2, 0.4), Ok(()));
    assert_eq!(uni(0.0, 0.4), Err(ParamError::new("epsilon_1", Rule::NotPositive)));
    assert_eq!(uni(-0.1, 0.4), Err(ParamError::new("epsilon_1", Rule::NotPositive)));
    assert_eq!(uni(0.2, 0.0), Err(ParamError::new("epsilon_2", Rule::NotPositive)));
    assert_eq!(uni(f64::NAN, 0.4), Err(ParamError::new("epsilon_1", Rule::NonFinite)));
    assert_eq!(uni(0.2, f64::INFINITY), Err(ParamError::new("epsilon_2", Rule::NonFinite)));

    let car = |e: f64, eta: [f64; 3], k: f64| Platform::<f64>::validate(&CarLike::new(e, eta, k));
    assert_eq!(car(0.3, [1.0, 2.0, 1.0], 1.0), Ok(()));
    assert_eq!(car(0.0, [1.0, 2.0, 1.0], 1.0), Err(ParamError::new("epsilon", Rule::NotPositive)));
    assert_eq!(car(0.3, [0.0, 2.0, 1.0], 1.0), Err(ParamError::new("eta_1", Rule::NotPositive)));
    assert_eq!(car(0.3, [1.0, -2.0, 1.0], 1.0), Err(ParamError::new("eta_2", Rule::NotPositive)));
    assert_eq!(car(0.3, [1.0, 2.0, f64::NAN], 1.0), Err(ParamError::new("eta_3", Rule::NonFinite)));
    assert_eq!(car(0.3, [1.0, 2.0, 1.0], 0.0), Err(ParamError::new("k", Rule::NotPositive)));

    // Through the law's constructor, for f32 too.
    let err =
        ControlLaw::new(Params::<f32, 3>::paper(PaperRun::A), Unicycle::new(0.2f32, -1.0), Rpr::paper())
            .unwrap_err();
    assert_eq!(err, ParamError::new("epsilon_2", Rule::NotPositive));
    assert_eq!(Platform::<f64>::validate(&Omnidirectional), Ok(()));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// `∂H̄/∂α` (used to advance `α` linearly implicitly over a hold) against central
    /// differences of `H̄(α)`, for both transverse functions.
    #[test]
    fn hbar_derivative_matches_finite_differences(
        a1 in -PI..PI, a2 in -PI..PI,
        e1 in 0.05..1.0f64, e2 in 0.05..2.0f64,
        eps in 0.05..0.5f64, n1 in 0.5..3.0f64, n3 in 0.5..3.0f64, k in 0.5..10.0f64,
    ) {
        let uni = Unicycle::new(e1, e2);
        let c = uni.companion_with_derivative(&Vector2::new(a1, 0.0)).expect("transverse");
        let hp = uni.companion(&Vector2::new(a1 + H, 0.0)).expect("transverse").hbar;
        let hm = uni.companion(&Vector2::new(a1 - H, 0.0)).expect("transverse").hbar;
        check_close("unicycle ∂H̄/∂α", &c.dhbar[0], &((hp - hm) / (2.0 * H)), FD_TOL, 1.0)?;
        check_close("unicycle ∂H̄/∂α₂", &c.dhbar[1], &Matrix3::zeros(), 0.0, 1.0)?;

        // η₂ chosen inside Lemma 2's region: 6η₂η₃ > 8η₃ + η₁η₂ ⇔ η₂ (6η₃ − η₁) > 8η₃.
        prop_assume!(6.0 * n3 > n1);
        let n2 = 1.5 * 8.0 * n3 / (6.0 * n3 - n1);
        let car = CarLike::new(eps, [n1, n2, n3], k);
        let alpha = Vector2::new(a1, a2);
        let c = car.companion_with_derivative(&alpha).expect("transverse");
        for i in 0..2 {
            let mut ap = alpha;
            let mut am = alpha;
            ap[i] += H;
            am[i] -= H;
            let hp = car.companion(&ap).expect("transverse").hbar;
            let hm = car.companion(&am).expect("transverse").hbar;
            check_close("car ∂H̄/∂αᵢ", &c.dhbar[i], &((hp - hm) / (2.0 * H)), FD_TOL, 1.0)?;
        }
    }
}
