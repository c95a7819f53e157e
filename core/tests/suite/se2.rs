//! SE(2) (§2.1–2.2): group axioms, the distance (2), `Ad` (5), and the velocity relations
//! (3), (4), (6)–(9) against central finite differences along closed-form curves.
//!
//! Tolerances. Poses here have coordinates up to ~10 and angles up to ~10 rad, so exact
//! group identities hold to a few ulps of 10 (~1e−14): 1e−12 leaves margin for the
//! sin/cos of the core (`libm`) and of the reference (`std`) differing by an ulp.
//! Finite differences use `h = 1e−5`: the curves' third derivatives are at most ~50, so
//! the truncation error is `h²·50/6 ≈ 1e−9` and rounding `ε·10/h ≈ 2e−10`; the
//! tolerance 1e−7 (relative, floor 1) is 100× above both and far below any sign or
//! factor error (which shows at O(1)).

use crate::common::*;
use companion_core::nalgebra::Matrix3;
use companion_core::se2::{
    inverse3, inverse_velocity, pose_rate, product_velocity, quotient_velocity, rbar as core_rbar,
    relative_velocity, rot,
};
use companion_core::{wrap_angle, Pose};
use proptest::prelude::*;

const EXACT: f64 = 1e-12;
const H: f64 = 1e-5;
const FD_TOL: f64 = 1e-7;

fn p(v: &V3) -> Pose<f64> {
    pose(v)
}

fn same_pose(what: &str, a: &Pose<f64>, b: &V3) -> Result<(), TestCaseError> {
    check_close(what, &v3(a), b, EXACT, 1.0)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn product_is_the_homogeneous_matrix_product(a in pose_in(10.0, 10.0), b in pose_in(10.0, 10.0)) {
        same_pose("a·b", &p(&a).compose(&p(&b)), &mul(&a, &b))?;
    }

    #[test]
    fn product_is_associative(a in pose_in(10.0, 10.0), b in pose_in(10.0, 10.0), c in pose_in(10.0, 10.0)) {
        let (a, b, c) = (p(&a), p(&b), p(&c));
        let left = a.compose(&b).compose(&c);
        let right = a.compose(&b.compose(&c));
        same_pose("(ab)c vs a(bc)", &left, &v3(&right))?;
    }

    #[test]
    fn identity_is_neutral(a in pose_in(10.0, 10.0)) {
        let e = Pose::<f64>::identity();
        prop_assert_eq!(v3(&e), V3::zeros());
        same_pose("a·e", &p(&a).compose(&e), &a)?;
        same_pose("e·a", &e.compose(&p(&a)), &a)?;
    }

    #[test]
    fn inverse_is_two_sided(a in pose_in(10.0, 10.0)) {
        let a_inv = p(&a).inverse();
        // Against the inverse of the homogeneous matrix, and r⁻¹ = −R̄(−θ) r (§2.1).
        same_pose("a⁻¹", &a_inv, &inv(&a))?;
        same_pose("a⁻¹ = −R̄(−θ) a", &a_inv, &(-(rbar(-a[2]) * a)))?;
        same_pose("a·a⁻¹", &p(&a).compose(&a_inv), &V3::zeros())?;
        same_pose("a⁻¹·a", &a_inv.compose(&p(&a)), &V3::zeros())?;
    }

    /// `between(a, b) = a⁻¹ b` with the angle wrapped to (−π, π].
    #[test]
    fn between_is_the_wrapped_difference(a in pose_in(10.0, 20.0), b in pose_in(10.0, 20.0)) {
        let d = p(&a).between(&p(&b));
        let want = mul(&inv(&a), &b);
        check_close("between xy", &v3(&d).xy(), &want.xy(), EXACT, 1.0)?;
        prop_assert!(d.theta > -PI && d.theta <= PI, "angle {} not in (−π, π]", d.theta);
        check_close_scalar("between θ", d.theta, wrap(want[2]), 1e-12, 1.0)?;
    }

    #[test]
    fn wrap_angle_lands_in_the_half_open_interval(a in -1e6..1e6f64) {
        let w = wrap_angle(a);
        prop_assert!(w > -PI && w <= PI, "wrap({a}) = {w}");
        // Same angle: the difference is a multiple of 2π (to the rounding of a ~1e6).
        let k = (a - w) / (2.0 * PI);
        prop_assert!((k - k.round()).abs() < 1e-9, "wrap({a}) = {w} is not a − 2πk");
        if a > -PI && a <= PI {
            prop_assert_eq!(w, a);
        }
    }

    /// `d_γ` is left-invariant, equals `d_γ(e, a⁻¹ b)` (eq. 2), and is a metric.
    #[test]
    fn distance_is_a_left_invariant_metric(
        g in pose_in(10.0, 10.0), a in pose_in(10.0, 10.0), b in pose_in(10.0, 10.0),
        c in pose_in(10.0, 10.0), gamma in 0.01..5.0f64,
    ) {
        let d = |x: &V3, y: &V3| p(x).distance(&p(y), gamma);
        let dab = d(&a, &b);
        check_close_scalar("left invariance", d(&mul(&g, &a), &mul(&g, &b)), dab, 1e-10, 1.0)?;
        check_close_scalar("d(a,b) = d(e, a⁻¹b)", d(&V3::zeros(), &mul(&inv(&a), &b)), dab, 1e-10, 1.0)?;
        check_close_scalar("independent d_γ", dab, d_gamma(&a, &b, gamma), 1e-10, 1.0)?;
        check_close_scalar("symmetry", d(&b, &a), dab, 1e-12, 1.0)?;
        prop_assert!(d(&a, &a).abs() < 1e-12);
        prop_assert!(dab <= d(&a, &c) + d(&c, &b) + 1e-12, "triangle inequality");
    }

    /// With γ = 2 the distance is the Frobenius norm of `R̄_ab − I₃` (§2.1, after eq. 2).
    #[test]
    fn distance_with_gamma_2_is_a_frobenius_norm(a in pose_in(10.0, 10.0), b in pose_in(10.0, 10.0)) {
        let frob = (hom(&mul(&inv(&a), &b)) - Matrix3::identity()).norm();
        check_close_scalar("γ = 2", p(&a).distance(&p(&b), 2.0), frob, 1e-10, 1.0)?;
    }

    #[test]
    fn adjoint_is_a_homomorphism(a in pose_in(10.0, 10.0), b in pose_in(10.0, 10.0)) {
        let (pa, pb) = (p(&a), p(&b));
        check_close("Ad_ab = Ad_a Ad_b", &pa.compose(&pb).ad(), &(pa.ad() * pb.ad()), EXACT, 1.0)?;
        check_close("Ad_{a⁻¹} = Ad(a⁻¹)", &pa.ad_inv(), &pa.inverse().ad(), EXACT, 1.0)?;
        check_close("Ad_{a⁻¹} Ad_a = I", &(pa.ad_inv() * pa.ad()), &Matrix3::identity(), EXACT, 1.0)?;
        check_close("Ad_a Ad_{a⁻¹} = I", &(pa.ad() * pa.ad_inv()), &Matrix3::identity(), EXACT, 1.0)?;
    }

    /// `Ad_r u` is the body velocity of the conjugated curve `r · exp(t u) · r⁻¹` at t = 0
    /// (the definition behind eq. 5).
    #[test]
    fn adjoint_is_conjugation(r in pose_in(3.0, 3.0), u in vec3(-2.0, 2.0)) {
        let c = |t: f64| mul(&mul(&r, &exp(&(u * t))), &inv(&r));
        let fd = body(&c(0.0), &central(c, 0.0, H));
        check_close("Ad_r u", &(p(&r).ad() * u), &fd, FD_TOL, 1.0)?;
    }

    /// Eq. (3): a pose moving at body velocity `u` has `ṙ = R̄(θ) u`.
    #[test]
    fn eq3_pose_rate(r in pose_in(3.0, 3.0), u in vec3(-2.0, 2.0)) {
        let fd = central(|t| flow(&r, &u, t), 0.0, H);
        check_close("eq. (3)", &pose_rate(&p(&r), &u), &fd, FD_TOL, 1.0)?;
        check_close("R̄", &core_rbar(r[2]), &rbar(r[2]), EXACT, 1.0)?;
        let (s, c) = r[2].sin_cos();
        check_close("R", &rot(r[2]), &companion_core::nalgebra::Matrix2::new(c, -s, s, c), EXACT, 1.0)?;
    }

    /// Eq. (4): `d/dt (r_c r_d) = R̄(θ_c + θ_d)(u_d + Ad_{r_d⁻¹} u_c)`.
    #[test]
    fn eq4_product_velocity(c in curve(), d in curve(), t in 0.0..2.0f64) {
        let fd = body(&mul(&c.at(t), &d.at(t)), &central(|s| mul(&c.at(s), &d.at(s)), t, H));
        let got = product_velocity(&p(&d.at(t)), &c.body(t), &d.body(t));
        check_close("eq. (4)", &got, &fd, FD_TOL, 1.0)?;
    }

    /// Eq. (6): `d/dt r⁻¹ = R̄(−θ)(−Ad_r u)`.
    #[test]
    fn eq6_inverse_velocity(c in curve(), t in 0.0..2.0f64) {
        let fd = body(&inv(&c.at(t)), &central(|s| inv(&c.at(s)), t, H));
        check_close("eq. (6)", &inverse_velocity(&p(&c.at(t)), &c.body(t)), &fd, FD_TOL, 1.0)?;
        // The coordinate rate itself, as printed in (6).
        let rate = rbar(-c.at(t)[2]) * -(p(&c.at(t)).ad() * c.body(t));
        check_close("eq. (6) rate", &rate, &central(|s| inv(&c.at(s)), t, H), FD_TOL, 1.0)?;
    }

    /// Eq. (7): `d/dt (r_c r_d⁻¹) = R̄(θ_c − θ_d) Ad_{r_d}(u_c − u_d)`.
    #[test]
    fn eq7_quotient_velocity(c in curve(), d in curve(), t in 0.0..2.0f64) {
        let f = |s: f64| mul(&c.at(s), &inv(&d.at(s)));
        let fd = body(&f(t), &central(f, t, H));
        let got = quotient_velocity(&p(&d.at(t)), &c.body(t), &d.body(t));
        check_close("eq. (7)", &got, &fd, FD_TOL, 1.0)?;
    }

    /// Eqs. (8)–(9): `r_cd = r_c⁻¹ r_d` moves with `u_cd = u_d − Ad_{r_dc} u_c`.
    #[test]
    fn eq8_eq9_relative_velocity(c in curve(), d in curve(), t in 0.0..2.0f64) {
        let f = |s: f64| mul(&inv(&c.at(s)), &d.at(s));
        let fd_rate = central(f, t, H);
        let got = relative_velocity(&p(&c.at(t)), &p(&d.at(t)), &c.body(t), &d.body(t));
        check_close("eq. (9)", &got, &body(&f(t), &fd_rate), FD_TOL, 1.0)?;
        // Eq. (8) as printed: the coordinate rate R̄(θ_d − θ_c)(u_d − Ad_{r_d⁻¹ r_c} u_c).
        let r_dc = mul(&inv(&d.at(t)), &c.at(t));
        let rate = rbar(d.at(t)[2] - c.at(t)[2]) * (d.body(t) - p(&r_dc).ad() * c.body(t));
        check_close("eq. (8)", &rate, &fd_rate, FD_TOL, 1.0)?;
    }

    /// The cofactor inverse: `M⁻¹ M = I` and the determinant, or `None` when singular.
    #[test]
    fn inverse3_inverts(m in proptest::array::uniform9(-2.0..2.0f64)) {
        let m = Matrix3::from_row_slice(&m);
        let det = m.determinant();
        prop_assume!(det.abs() > 1e-3);
        let (inv_m, d) = inverse3(&m).expect("invertible");
        check_close_scalar("det", d, det, 1e-12, 1.0)?;
        // ‖M⁻¹‖ ≤ ~(2·3)²/1e−3: the residual is bounded by κ ε ≈ 4e4 · 1e−16.
        check_close("M⁻¹ M", &(inv_m * m), &Matrix3::identity(), 1e-9, 1.0)?;
    }

    #[test]
    fn inverse3_rejects_singular_matrices(r in vec3(-2.0, 2.0), s in vec3(-2.0, 2.0), k in -2.0..2.0f64) {
        // Rows r, s and the exact combination r·k (a power of two makes it exact) ...
        let k = k.round() * 0.5;
        let m = Matrix3::from_rows(&[r.transpose(), s.transpose(), (r * k).transpose()]);
        if let Some((_, d)) = inverse3(&m) {
            // ... whose cofactor expansion may still round to a tiny non-zero value.
            prop_assert!(d.abs() < 1e-14, "det of a rank-2 matrix = {d}");
        }
        let mut n = m;
        n[(1, 1)] = f64::NAN;
        prop_assert!(inverse3(&n).is_none());
        n[(1, 1)] = f64::INFINITY;
        prop_assert!(inverse3(&n).is_none());
    }
}

#[test]
fn pose_vector_round_trip_and_finiteness() {
    let r = Pose::new(1.0, -2.0, 3.0);
    assert_eq!(Pose::from_vector(&r.to_vector()), r);
    assert_eq!(r.position(), companion_core::nalgebra::Vector2::new(1.0, -2.0));
    assert!(r.is_finite());
    assert!(!Pose::new(f64::NAN, 0.0, 0.0).is_finite());
    assert!(!Pose::new(0.0, f64::INFINITY, 0.0).is_finite());
    assert!(!Pose::new(0.0, 0.0, f64::NEG_INFINITY).is_finite());
    // wrap_angle's edge cases: π stays, −π maps to π.
    assert_eq!(wrap_angle(PI), PI);
    assert_eq!(wrap_angle(-PI), PI);
    assert!(wrap_angle(f64::NAN).is_nan());
}
