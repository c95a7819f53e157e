//! One conformance suite for the Lie groups SE(2) and SE(3) ([`LieGroup`]), run against
//! both: the same axioms and the same finite differences, instantiated per group.
//!
//! The reference is independent of the core: every element is also a homogeneous matrix
//! (3×3 or 4×4), the product is the matrix product, the inverse the matrix inverse, `exp`
//! the matrix exponential of the twist's matrix (a Taylor series with scaling and squaring,
//! written here), and `Ad_x ξ` is read off `x ξ^ x⁻¹`. Jacobians are checked by central
//! differences of the core's own `exp`/`log`, which are checked against the references
//! first.
//!
//! Tolerances. Twists have components up to 3 (rotations up to ~5 rad, wrapped), so group
//! identities hold to a few ulps of 10: 1e−11. Central differences with `h = 1e−6` have a
//! truncation error `h² |f'''|/6 ≲ 1e−11` and a rounding error `ε |f|/h ≈ 1e−9`; they are
//! held to 1e−6 (relative, floor 1), far below any sign or factor error. The small-angle
//! branches are checked on both sides of every switch.

use companion_core::nalgebra::{Matrix3, Matrix4, SMatrix, SVector, Vector3, Vector6};
use companion_core::{so3, LieGroup, Pose, Pose3};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

use crate::common::{check_close, hom, mul, PI};

/// A group with its independent matrix representation (`M×M`) and its twists' matrices.
trait Reference<const D: usize, const M: usize>: LieGroup<f64, D> {
    fn matrix(&self) -> SMatrix<f64, M, M>;
    fn hat(xi: &SVector<f64, D>) -> SMatrix<f64, M, M>;
    fn vee(m: &SMatrix<f64, M, M>) -> SVector<f64, D>;
    /// The rotation angle of a twist.
    fn angle(xi: &SVector<f64, D>) -> f64;
}

impl Reference<3, 3> for Pose<f64> {
    fn matrix(&self) -> Matrix3<f64> {
        hom(&Vector3::new(self.x, self.y, self.theta))
    }
    fn hat(xi: &Vector3<f64>) -> Matrix3<f64> {
        Matrix3::new(0.0, -xi[2], xi[0], xi[2], 0.0, xi[1], 0.0, 0.0, 0.0)
    }
    fn vee(m: &Matrix3<f64>) -> Vector3<f64> {
        Vector3::new(m[(0, 2)], m[(1, 2)], m[(1, 0)])
    }
    fn angle(xi: &Vector3<f64>) -> f64 {
        xi[2].abs()
    }
}

fn skew(w: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -w[2], w[1], w[2], 0.0, -w[0], -w[1], w[0], 0.0)
}

impl Reference<6, 4> for Pose3<f64> {
    fn matrix(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rotation);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }
    fn hat(xi: &Vector6<f64>) -> Matrix4<f64> {
        let mut m = Matrix4::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&skew(&Vector3::new(xi[3], xi[4], xi[5])));
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&Vector3::new(xi[0], xi[1], xi[2]));
        m
    }
    fn vee(m: &Matrix4<f64>) -> Vector6<f64> {
        Vector6::new(m[(0, 3)], m[(1, 3)], m[(2, 3)], m[(2, 1)], m[(0, 2)], m[(1, 0)])
    }
    fn angle(xi: &Vector6<f64>) -> f64 {
        Vector3::new(xi[3], xi[4], xi[5]).norm()
    }
}

/// The matrix exponential: Taylor series to degree 24 after scaling by `2⁻ᵏ` so that the
/// norm is below ½, then `k` squarings.
fn expm<const M: usize>(a: &SMatrix<f64, M, M>) -> SMatrix<f64, M, M> {
    let mut k = 0;
    let mut s = *a;
    while s.norm() > 0.5 {
        s /= 2.0;
        k += 1;
    }
    let mut term = SMatrix::<f64, M, M>::identity();
    let mut sum = term;
    for n in 1..=24 {
        term = term * s / f64::from(n);
        sum += term;
    }
    for _ in 0..k {
        sum = sum * sum;
    }
    sum
}

const EXACT: f64 = 1e-11;
const H: f64 = 1e-6;
const FD: f64 = 1e-6;

/// The group law and `exp` against the matrix references.
fn check_matrix_forms<G: Reference<D, M>, const D: usize, const M: usize>(
    xa: &SVector<f64, D>,
    xb: &SVector<f64, D>,
    xc: &SVector<f64, D>,
) -> Result<(), TestCaseError> {
    let (a, b, c) = (G::exp(xa), G::exp(xb), G::exp(xc));
    check_close("exp ξ = expm(ξ^)", &a.matrix(), &expm(&G::hat(xa)), EXACT, 1.0)?;
    check_close("a·b", &a.compose(&b).matrix(), &(a.matrix() * b.matrix()), EXACT, 1.0)?;
    let inv = a.matrix().try_inverse().ok_or_else(|| TestCaseError::fail("singular"))?;
    check_close("a⁻¹", &a.inverse().matrix(), &inv, EXACT, 1.0)?;
    check_close("a·a⁻¹ = e", &a.compose(&a.inverse()).matrix(), &SMatrix::identity(), EXACT, 1.0)?;
    check_close("e·a", &G::identity().compose(&a).matrix(), &a.matrix(), EXACT, 1.0)?;
    let left = a.compose(&b).compose(&c);
    let right = a.compose(&b.compose(&c));
    check_close("(ab)c = a(bc)", &left.matrix(), &right.matrix(), EXACT, 1.0)?;
    Ok(())
}

/// `log` inverts `exp` on the principal domain, `exp` inverts `log` everywhere.
fn check_log<G: Reference<D, M>, const D: usize, const M: usize>(
    xi: &SVector<f64, D>,
) -> Result<(), TestCaseError> {
    let x = G::exp(xi);
    check_close("exp(log x) = x", &G::exp(&x.log()).matrix(), &x.matrix(), EXACT, 1.0)?;
    prop_assert!(G::angle(&x.log()) <= PI + 1e-12, "log's angle beyond π");
    if G::angle(xi) < PI - 1e-6 {
        check_close("log(exp ξ) = ξ", &x.log(), xi, 1e-9, 1.0)?;
    }
    Ok(())
}

/// `Ad_x ξ = vee(x ξ^ x⁻¹)`, a homomorphism, and the Jacobians of the product and the
/// inverse it gives.
fn check_adjoint<G: Reference<D, M>, const D: usize, const M: usize>(
    xa: &SVector<f64, D>,
    xb: &SVector<f64, D>,
    xi: &SVector<f64, D>,
) -> Result<(), TestCaseError> {
    let (a, b) = (G::exp(xa), G::exp(xb));
    let am = a.matrix();
    let conj = am * G::hat(xi) * am.try_inverse().ok_or_else(|| TestCaseError::fail("singular"))?;
    check_close("Ad_x ξ", &(a.adjoint() * xi), &G::vee(&conj), EXACT, 1.0)?;
    check_close("Ad_ab = Ad_a Ad_b", &a.compose(&b).adjoint(), &(a.adjoint() * b.adjoint()), EXACT, 1.0)?;
    // d/dδ log((ab)⁻¹ (a exp δ) b) = Ad_{b⁻¹};  d/dδ log(a (a exp δ)⁻¹) = −Ad_a.
    let ab_inv = a.compose(&b).inverse();
    let d_left = fd::<D, _>(|d| ab_inv.compose(&a.compose(&G::exp(d)).compose(&b)).log());
    check_close("∂(ab)/∂a", &d_left, &b.inverse().adjoint(), FD, 1.0)?;
    let d_inv = fd::<D, _>(|d| a.compose(&a.compose(&G::exp(d)).inverse()).log());
    check_close("∂a⁻¹/∂a", &d_inv, &(-a.adjoint()), FD, 1.0)?;
    Ok(())
}

/// Central differences of `f` at `δ = 0`, column by column.
fn fd<const D: usize, F: Fn(&SVector<f64, D>) -> SVector<f64, D>>(f: F) -> SMatrix<f64, D, D> {
    let mut j = SMatrix::<f64, D, D>::zeros();
    for i in 0..D {
        let mut d = SVector::<f64, D>::zeros();
        d[i] = H;
        let col = (f(&d) - f(&(-d))) / (2.0 * H);
        j.set_column(i, &col);
    }
    j
}

/// `J_r` and `J_r⁻¹` by central differences, and `J_r J_r⁻¹ = I`.
fn check_jacobians<G: Reference<D, M>, const D: usize, const M: usize>(
    xi: &SVector<f64, D>,
) -> Result<(), TestCaseError> {
    let e_inv = G::exp(xi).inverse();
    let jr = fd::<D, _>(|d| e_inv.compose(&G::exp(&(xi + d))).log());
    check_close("J_r", &G::right_jacobian(xi), &jr, FD, 1.0)?;
    let x = G::exp(xi);
    let lx = x.log();
    let jri = fd::<D, _>(|d| x.compose(&G::exp(d)).log() - lx);
    check_close("J_r⁻¹", &G::right_jacobian_inv(&lx), &jri, FD, 1.0)?;
    check_close(
        "J_r J_r⁻¹ = I",
        &(G::right_jacobian(xi) * G::right_jacobian_inv(xi)),
        &SMatrix::identity(),
        1e-10,
        1.0,
    )?;
    Ok(())
}

/// Twists with linear parts up to `lin` and rotation components up to `ang`.
fn twist3(lin: f64, ang: f64) -> impl Strategy<Value = Vector3<f64>> {
    (-lin..lin, -lin..lin, -ang..ang).prop_map(|(a, b, c)| Vector3::new(a, b, c))
}

fn twist6(lin: f64, ang: f64) -> impl Strategy<Value = Vector6<f64>> {
    (-lin..lin, -lin..lin, -lin..lin, -ang..ang, -ang..ang, -ang..ang)
        .prop_map(|(a, b, c, d, e, f)| Vector6::new(a, b, c, d, e, f))
}

/// A twist whose rotation has the given angle exactly, along a random axis.
fn with_angle6(angle: f64) -> impl Strategy<Value = Vector6<f64>> {
    (twist6(2.0, 1.0), twist6(1.0, 1.0)).prop_filter_map("axis", move |(v, a)| {
        let axis = Vector3::new(a[3], a[4], a[5]);
        let n = axis.norm();
        (n > 1e-3).then(|| {
            let w = axis * (angle / n);
            Vector6::new(v[0], v[1], v[2], w[0], w[1], w[2])
        })
    })
}

fn with_angle3(angle: f64) -> impl Strategy<Value = Vector3<f64>> {
    (twist3(2.0, 1.0), prop::bool::ANY)
        .prop_map(move |(v, s)| Vector3::new(v[0], v[1], if s { angle } else { -angle }))
}

/// Angles on both sides of every switch of the small-angle branches (0.3 and 1 for the
/// SO(3) ratios, 0.6 for `Q`), tiny ones and ones next to π.
const ANGLES: [f64; 13] =
    [0.0, 1e-9, 1e-4, 0.05, 0.299, 0.301, 0.599, 0.601, 0.999, 1.001, 2.5, PI - 1e-3, PI - 1e-7];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn se2_matrix_forms(a in twist3(3.0, 3.0), b in twist3(3.0, 3.0), c in twist3(3.0, 3.0)) {
        check_matrix_forms::<Pose<f64>, 3, 3>(&a, &b, &c)?;
        // And the core's product against the test's own SE(2) product.
        let (pa, pb) = (Pose::<f64>::exp(&a), Pose::<f64>::exp(&b));
        let got = LieGroup::compose(&pa, &pb);
        check_close("a·b (common::mul)", &Vector3::new(got.x, got.y, got.theta), &mul(&Vector3::new(pa.x, pa.y, pa.theta), &Vector3::new(pb.x, pb.y, pb.theta)), EXACT, 1.0)?;
    }

    #[test]
    fn se3_matrix_forms(a in twist6(3.0, 3.0), b in twist6(3.0, 3.0), c in twist6(3.0, 3.0)) {
        check_matrix_forms::<Pose3<f64>, 6, 4>(&a, &b, &c)?;
        let r = Pose3::<f64>::exp(&a).rotation;
        prop_assert!(so3::orthonormality(&r) < 1e-14, "exp gives a rotation");
    }

    #[test]
    fn se2_log(xi in twist3(3.0, 6.0)) { check_log::<Pose<f64>, 3, 3>(&xi)?; }

    #[test]
    fn se3_log(xi in twist6(3.0, 3.0)) { check_log::<Pose3<f64>, 6, 4>(&xi)?; }

    #[test]
    fn se2_adjoint(a in twist3(3.0, 3.0), b in twist3(3.0, 3.0), xi in twist3(2.0, 2.0)) {
        check_adjoint::<Pose<f64>, 3, 3>(&a, &b, &xi)?;
    }

    #[test]
    fn se3_adjoint(a in twist6(3.0, 2.0), b in twist6(3.0, 2.0), xi in twist6(2.0, 2.0)) {
        check_adjoint::<Pose3<f64>, 6, 4>(&a, &b, &xi)?;
        let x = Pose3::<f64>::exp(&a);
        check_close("Ad⁻¹ applied", &x.adjoint_inv_apply(&xi), &(x.inverse().adjoint() * xi), EXACT, 1.0)?;
    }

    #[test]
    fn se2_jacobians(xi in twist3(3.0, 3.0)) { check_jacobians::<Pose<f64>, 3, 3>(&xi)?; }

    #[test]
    fn se3_jacobians(xi in twist6(2.0, 1.8)) { check_jacobians::<Pose3<f64>, 6, 4>(&xi)?; }

    /// Every branch, on both sides of its switch and next to π.
    #[test]
    fn se2_branches(i in 0..ANGLES.len(), seed in with_angle3(1.0)) {
        let xi = Vector3::new(seed[0], seed[1], ANGLES[i].copysign(seed[2]));
        check_matrix_forms::<Pose<f64>, 3, 3>(&xi, &xi, &xi)?;
        check_log::<Pose<f64>, 3, 3>(&xi)?;
        if ANGLES[i] < 3.0 {
            check_jacobians::<Pose<f64>, 3, 3>(&xi)?;
        }
    }

    #[test]
    fn se3_branches(xi in (0..ANGLES.len()).prop_flat_map(|i| with_angle6(ANGLES[i]))) {
        check_matrix_forms::<Pose3<f64>, 6, 4>(&xi, &xi, &xi)?;
        let x = Pose3::<f64>::exp(&xi);
        let err = (Pose3::<f64>::exp(&x.log()).matrix() - x.matrix()).amax();
        prop_assert!(err < 1e-11, "exp(log x) at angle {}: {err:e}", <Pose3<f64> as Reference<6, 4>>::angle(&xi));
        check_log::<Pose3<f64>, 6, 4>(&xi)?;
        if <Pose3<f64> as Reference<6, 4>>::angle(&xi) < 3.0 {
            check_jacobians::<Pose3<f64>, 6, 4>(&xi)?;
        }
    }

    /// `f32`: the same functions within f32's precision of the `f64` ones.
    #[test]
    fn se3_f32_follows_f64(xi in twist6(2.0, 2.0)) {
        let x32 = xi.map(|v| v as f32);
        let x64 = x32.map(f64::from);
        let (a, b) = (Pose3::<f32>::exp(&x32), Pose3::<f64>::exp(&x64));
        let m32 = <Pose3<f64> as Reference<6, 4>>::matrix(&Pose3::new(a.rotation.map(f64::from), a.translation.map(f64::from)));
        check_close("exp f32", &m32, &b.matrix(), 2e-6, 1.0)?;
        check_close("log f32", &a.log().map(f64::from), &b.log(), 1e-5, 1.0)?;
        check_close("J_r f32", &Pose3::<f32>::right_jacobian(&x32).map(f64::from), &Pose3::<f64>::right_jacobian(&x64), 1e-5, 1.0)?;
        check_close("J_r⁻¹ f32", &Pose3::<f32>::right_jacobian_inv(&x32).map(f64::from), &Pose3::<f64>::right_jacobian_inv(&x64), 1e-5, 1.0)?;
    }
}

/// `log` next to and at `π`: the axis from the symmetric part, its sign from `vee`.
#[test]
fn so3_log_at_pi() {
    for axis in
        [Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, -1.0, 0.0), Vector3::new(1.0, 2.0, -2.0) / 3.0]
    {
        for angle in [PI, PI - 1e-9, PI - 1e-5, PI - 0.2] {
            let phi = axis * angle;
            let r = expm(&skew(&phi));
            let got = so3::log(&r);
            let back = expm(&skew(&got));
            assert!((back - r).amax() < 1e-12, "exp(log R) = R at {angle}");
            if angle < PI {
                assert!((got - phi).amax() < 1e-7, "log R = φ at {angle}: {got} vs {phi}");
            } else {
                assert!((got.norm() - PI).abs() < 1e-12 && got.cross(&axis).amax() < 1e-9, "log at π: {got}");
            }
        }
    }
}

/// The series of `A, B, C, β` against their closed forms, at the switch (0.3 in `f64`).
#[test]
fn so3_series_meet_closed_forms() {
    for t in [0.299f64, 0.301] {
        let phi = Vector3::new(t, 0.0, 0.0);
        let (s, c) = t.sin_cos();
        let a = s / t;
        let b = (1.0 - c) / (t * t);
        let cc = (t - s) / (t * t * t);
        let beta = 1.0 / (t * t) - (1.0 + c) / (2.0 * t * s);
        let r = so3::exp(&phi);
        assert!((r[(1, 1)] - (1.0 - b * t * t)).abs() < 1e-14 && (r[(2, 1)] - a * t).abs() < 1e-14);
        let jr = so3::right_jacobian(&Vector3::new(0.0, t, 0.0));
        // J_r(φ)[0][0] = 1 + C (φφᵀ − θ² I)[0][0] = 1 − C θ².
        assert!((jr[(0, 0)] - (1.0 - cc * t * t)).abs() < 1e-14, "C at {t}");
        let ji = so3::right_jacobian_inv(&Vector3::new(0.0, t, 0.0));
        assert!((ji[(0, 0)] - (1.0 - beta * t * t)).abs() < 1e-13, "β at {t}");
    }
}

#[test]
fn so3_helpers() {
    // rpy: R_z(y) R_y(p) R_x(r), right angles exact.
    let r = so3::from_rpy(PI / 2.0, 0.0, 0.0);
    assert_eq!(r, Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0));
    let r = so3::from_rpy(0.3, -0.7, 1.1);
    let want = expm(&skew(&Vector3::new(0.0, 0.0, 1.1)))
        * expm(&skew(&Vector3::new(0.0, -0.7, 0.0)))
        * expm(&skew(&Vector3::new(0.3, 0.0, 0.0)));
    assert!((r - want).amax() < 1e-14);
    // Orthonormality: a rotation, a scaled one, a reflection, a NaN.
    assert!(so3::orthonormality(&r) < 1e-15);
    assert!((so3::orthonormality(&(r * 1.01)) - 0.0201).abs() < 1e-12);
    assert!(so3::orthonormality(&(-r)).is_infinite());
    assert!(so3::orthonormality(&Matrix3::from_element(f64::NAN)).is_infinite());
    // Quaternions: the rotation of (x, y, z, w) back to R, w ≥ 0, every branch.
    for phi in [
        Vector3::new(0.1, 0.2, 0.3),
        Vector3::new(3.0, 0.1, 0.0),
        Vector3::new(0.0, -3.1, 0.2),
        Vector3::new(0.1, 0.0, 3.1),
    ] {
        let r: Matrix3<f64> = so3::exp(&phi);
        let [x, y, z, w] = so3::to_quaternion(&r);
        assert!(w >= 0.0 && ((x * x + y * y + z * z + w * w) - 1.0).abs() < 1e-14);
        let v = Vector3::new(x, y, z);
        let back = Matrix3::identity() * (w * w - v.dot(&v)) + v * v.transpose() * 2.0 + skew(&v) * (2.0 * w);
        assert!((back - r).amax() < 1e-14, "quaternion of {phi}");
    }
}

/// The planar lift and §5's projection invert each other; the projection has no yaw for a
/// vertical `x` axis.
#[test]
fn planar_lift_and_projection() {
    let p = Pose::<f64>::new(1.5, -0.5, 2.9);
    let lifted = Pose3::from_planar(&p);
    let back = lifted.planar().expect("yaw defined");
    assert!((back.pose.x - p.x).abs() < 1e-15 && (back.pose.theta - p.theta).abs() < 1e-15);
    let tilted = lifted.compose(&Pose3::new(so3::from_rpy(0.4, -0.3, 0.0), Vector3::new(0.0, 0.0, 2.0)));
    // Roll about x keeps the heading of x; pitch only tilts it: the yaw is unchanged.
    assert!((tilted.planar().expect("defined").pose.theta - p.theta).abs() < 1e-15);
    let vertical = Pose3::new(so3::from_rpy(0.0, -PI / 2.0, 0.0), Vector3::zeros());
    assert!(vertical.planar().is_none());
}
