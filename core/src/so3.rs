//! SO(3): rotations of space, as 3×3 orthonormal matrices — the rotational part of
//! [`Pose3`](crate::se3::Pose3).
//!
//! **Why matrices and not unit quaternions.** The spatial law spends its time on what a
//! matrix does best: building the frames of a serial chain (each joint's rotation is a
//! sine and a cosine written into two columns), rotating vectors (9 multiplications
//! against 15 or more for a quaternion), and reading a joint's axis, which is a column. A
//! matrix also has no double cover, so the logarithm below is one function with no sign to
//! choose, and nothing is re-normalised: the controller builds every rotation afresh from
//! joint angles and measurements each step, so there is no long product in which
//! orthonormality could drift. The price — 9 numbers instead of 4, and an orthonormality
//! that is not structural — is paid where rotations come from outside: [`orthonormality`]
//! checks them when an arm description is validated. [`to_quaternion`] converts for tools
//! that want quaternions (Foxglove's transforms).
//!
//! Conventions: a rotation `R_ab` maps coordinates in frame `b` to frame `a`. Angular
//! velocities are *body* velocities: `Ṙ = R [ω]×`. Rotation vectors `φ = θ n` (`|n| = 1`).
//!
//! ```text
//! [φ]×  = [0 −φ₃ φ₂; φ₃ 0 −φ₁; −φ₂ φ₁ 0],       θ = |φ|
//! exp φ = I + A [φ]× + B [φ]×²                        (Rodrigues)
//! A = sin θ / θ,  B = (1 − cos θ)/θ²,  C = (θ − sin θ)/θ³
//! log R : cos θ = (tr R − 1)/2,  sin θ n = ½ vee(R − Rᵀ),  θ ∈ [0, π]
//! J_r(φ)   = I − B [φ]× + C [φ]×²        exp(φ + δ) ≈ exp(φ) exp(J_r(φ) δ)
//! J_r(φ)⁻¹ = I + ½ [φ]× + β [φ]×²,  β = 1/θ² − (1 + cos θ)/(2 θ sin θ) = 1/θ² − sin θ/(2 θ (1 − cos θ))
//!            log(R exp(δ)) ≈ log(R) + J_r(log R)⁻¹ δ
//! J_l(φ) = J_r(φ)ᵀ = J_r(−φ)
//! ```
//!
//! Near `θ = 0` the ratios `A, B, C, β` come from their Taylor series (to `θ¹⁰`) below a
//! threshold where series and closed form agree to ~1e−14 relative in `f64` (`θ < 0.3`),
//! or to `f32`'s precision (`θ < 1`); `log` divides by `sin θ` only where it is not small
//! and takes the axis from the symmetric part of `R` near `θ = π` (`cos θ < −0.9`), where
//! the antisymmetric part vanishes. At `θ = π` the logarithm is discontinuous (`n` and `−n`
//! give the same rotation): it returns the `n` whose sign follows `vee(R − Rᵀ)`, or the one
//! with a positive largest component when that part is zero.

use nalgebra::{Matrix3, Vector3};

use crate::scalar::Real;

/// `[φ]×`: the matrix of `v ↦ φ × v`.
#[inline]
pub fn hat<T: Real>(phi: &Vector3<T>) -> Matrix3<T> {
    let z = T::zero();
    Matrix3::new(z, -phi[2], phi[1], phi[2], z, -phi[0], -phi[1], phi[0], z)
}

/// `vee(M)` of the antisymmetric part of `M`: `½ (M₃₂ − M₂₃, M₁₃ − M₃₁, M₂₁ − M₁₂)`.
#[inline]
pub fn vee<T: Real>(m: &Matrix3<T>) -> Vector3<T> {
    let h = T::of(0.5);
    Vector3::new((m[(2, 1)] - m[(1, 2)]) * h, (m[(0, 2)] - m[(2, 0)]) * h, (m[(1, 0)] - m[(0, 1)]) * h)
}

/// Below this `θ²` the ratios come from their series: `0.09` (`θ < 0.3`) in `f64`, `1` in
/// `f32` (whose precision the series reach up to `θ = 1`).
#[inline]
pub(crate) fn series_below<T: Real>() -> T {
    if T::default_epsilon() > T::of(1e-10) {
        T::one()
    } else {
        T::of(0.09)
    }
}

/// `c₀ + c₁ t + c₂ t² + …` by Horner's rule.
#[inline]
pub(crate) fn horner<T: Real>(t: T, c: &[f64]) -> T {
    let mut acc = T::zero();
    for k in c.iter().rev() {
        acc = acc * t + T::of(*k);
    }
    acc
}

/// The ratios of the module docs at `θ² = t`: `(A, B, C)` with `(sin θ, cos θ)`.
#[inline]
pub(crate) fn ratios<T: Real>(t: T) -> (T, T, T, T, T) {
    if t < series_below::<T>() {
        let a =
            horner(t, &[1.0, -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362_880.0, -1.0 / 39_916_800.0]);
        let b = horner(
            t,
            &[0.5, -1.0 / 24.0, 1.0 / 720.0, -1.0 / 40_320.0, 1.0 / 3_628_800.0, -1.0 / 479_001_600.0],
        );
        let c = horner(
            t,
            &[
                1.0 / 6.0,
                -1.0 / 120.0,
                1.0 / 5040.0,
                -1.0 / 362_880.0,
                1.0 / 39_916_800.0,
                -1.0 / 6_227_020_800.0,
            ],
        );
        // sin θ = θ A, cos θ = 1 − θ² B.
        let theta = t.square_root();
        (a, b, c, theta * a, T::one() - t * b)
    } else {
        let theta = t.square_root();
        let (s, co) = theta.sincos();
        (s / theta, (T::one() - co) / t, (theta - s) / (t * theta), s, co)
    }
}

/// `β = 1/θ² − (1 + cos θ)/(2 θ sin θ)` of `J_r⁻¹` at `θ² = t`.
#[inline]
pub(crate) fn beta<T: Real>(t: T) -> T {
    if t < series_below::<T>() {
        horner(
            t,
            &[
                1.0 / 12.0,
                1.0 / 720.0,
                1.0 / 30_240.0,
                1.0 / 1_209_600.0,
                1.0 / 47_900_160.0,
                691.0 / 1_307_674_368_000.0,
            ],
        )
    } else {
        let theta = t.square_root();
        let (s, c) = theta.sincos();
        // (1 + cos θ)/sin θ = sin θ/(1 − cos θ): no cancellation near π.
        T::one() / t - s / (T::of(2.0) * theta * (T::one() - c))
    }
}

/// `I + a [φ]× + b [φ]×²`, with `[φ]×² = φ φᵀ − θ² I`.
#[inline]
pub(crate) fn poly<T: Real>(phi: &Vector3<T>, a: T, b: T) -> Matrix3<T> {
    let (x, y, z) = (phi[0], phi[1], phi[2]);
    let t = x * x + y * y + z * z;
    let d = T::one() - b * t;
    Matrix3::new(
        d + b * x * x,
        b * x * y - a * z,
        b * x * z + a * y,
        b * x * y + a * z,
        d + b * y * y,
        b * y * z - a * x,
        b * x * z - a * y,
        b * y * z + a * x,
        d + b * z * z,
    )
}

/// The rotation `exp φ` (Rodrigues' formula).
#[inline]
pub fn exp<T: Real>(phi: &Vector3<T>) -> Matrix3<T> {
    let (a, b, _, _, _) = ratios(phi.dot(phi));
    poly(phi, a, b)
}

/// The rotation vector `log R ∈ {|φ| ≤ π}` of a rotation matrix (see the module docs for
/// `θ = π`).
#[inline]
pub fn log<T: Real>(r: &Matrix3<T>) -> Vector3<T> {
    let v = vee(r);
    let c = (r[(0, 0)] + r[(1, 1)] + r[(2, 2)] - T::one()) * T::of(0.5);
    let s = v.norm_squared().square_root();
    let theta = s.arctan2(c);
    if c > T::of(-0.9) {
        // θ / sin θ: no cancellation; θ = 0 exactly only when v = 0.
        if s > T::zero() {
            v * (theta / s)
        } else {
            v
        }
    } else {
        // Near π: n nᵀ = (sym(R) − cos θ I)/(1 − cos θ), from the largest diagonal.
        let k = if r[(0, 0)] >= r[(1, 1)] && r[(0, 0)] >= r[(2, 2)] {
            0
        } else if r[(1, 1)] >= r[(2, 2)] {
            1
        } else {
            2
        };
        let one_c = T::one() - c;
        let nk = ((r[(k, k)] - c) / one_c).max(T::zero()).square_root();
        let mut n = Vector3::zeros();
        for j in 0..3 {
            n[j] = if j == k { nk } else { (r[(j, k)] + r[(k, j)]) * T::of(0.5) / (one_c * nk) };
        }
        if n.dot(&v) < T::zero() {
            n = -n;
        }
        n * theta
    }
}

/// The right Jacobian `J_r(φ) = I − B [φ]× + C [φ]×²`.
#[inline]
pub fn right_jacobian<T: Real>(phi: &Vector3<T>) -> Matrix3<T> {
    let (_, b, c, _, _) = ratios(phi.dot(phi));
    poly(phi, -b, c)
}

/// Its inverse `J_r(φ)⁻¹ = I + ½ [φ]× + β [φ]×²` (finite for `|φ| < 2π`).
#[inline]
pub fn right_jacobian_inv<T: Real>(phi: &Vector3<T>) -> Matrix3<T> {
    poly(phi, T::of(0.5), beta(phi.dot(phi)))
}

/// `R_x(a)`, `R_y(a)`, `R_z(a)` from a sine and cosine: rotations about a coordinate axis.
#[inline]
pub fn about_axis<T: Real>(axis: usize, s: T, c: T) -> Matrix3<T> {
    let (z, o) = (T::zero(), T::one());
    match axis {
        0 => Matrix3::new(o, z, z, z, c, -s, z, s, c),
        1 => Matrix3::new(c, z, s, z, o, z, -s, z, c),
        _ => Matrix3::new(c, -s, z, s, c, z, z, z, o),
    }
}

/// `sin a, cos a` with values within 4 ε of 0 or ±1 rounded to them, so that right angles
/// given in radians (`π/2` is not a floating-point number) give exact rotations. For
/// descriptions, built once; never on the hot path.
#[inline]
pub fn exact_sincos<T: Real>(a: T) -> (T, T) {
    let (s, c) = a.sincos();
    let tiny = T::default_epsilon() * T::of(4.0);
    let snap = |x: T| {
        if x.abs() <= tiny {
            T::zero()
        } else if (x - T::one()).abs() <= tiny {
            T::one()
        } else if (x + T::one()).abs() <= tiny {
            -T::one()
        } else {
            x
        }
    };
    (snap(s), snap(c))
}

/// `R = R_z(yaw) R_y(pitch) R_x(roll)` (URDF's `rpy`, fixed axes x, y, z), right angles
/// exact ([`exact_sincos`]).
pub fn from_rpy<T: Real>(roll: T, pitch: T, yaw: T) -> Matrix3<T> {
    let (sr, cr) = exact_sincos(roll);
    let (sp, cp) = exact_sincos(pitch);
    let (sy, cy) = exact_sincos(yaw);
    about_axis(2, sy, cy) * about_axis(1, sp, cp) * about_axis(0, sr, cr)
}

/// How far `R` is from a rotation: `max |RᵀR − I|` elementwise, or infinity when
/// `det R ≤ 0` (a reflection or a degenerate matrix) or an entry is not finite.
pub fn orthonormality<T: Real>(r: &Matrix3<T>) -> T {
    if !r.iter().all(|x| x.finite()) || r.determinant() <= T::zero() {
        return T::of(f64::INFINITY);
    }
    (r.transpose() * r - Matrix3::identity()).amax()
}

/// The unit quaternion `(x, y, z, w)` of a rotation matrix, `w ≥ 0` (Shepperd's method:
/// from the largest of `w², x², y², z²`).
pub fn to_quaternion<T: Real>(r: &Matrix3<T>) -> [T; 4] {
    let (m00, m11, m22) = (r[(0, 0)], r[(1, 1)], r[(2, 2)]);
    let tr = m00 + m11 + m22;
    let q4 = T::of(0.25);
    let one = T::one();
    let (x, y, z, w);
    if tr >= m00 && tr >= m11 && tr >= m22 {
        let s = (one + tr).square_root() * T::of(2.0); // 4w
        w = q4 * s;
        x = (r[(2, 1)] - r[(1, 2)]) / s;
        y = (r[(0, 2)] - r[(2, 0)]) / s;
        z = (r[(1, 0)] - r[(0, 1)]) / s;
    } else if m00 >= m11 && m00 >= m22 {
        let s = (one + m00 - m11 - m22).square_root() * T::of(2.0); // 4x
        x = q4 * s;
        w = (r[(2, 1)] - r[(1, 2)]) / s;
        y = (r[(0, 1)] + r[(1, 0)]) / s;
        z = (r[(0, 2)] + r[(2, 0)]) / s;
    } else if m11 >= m22 {
        let s = (one + m11 - m00 - m22).square_root() * T::of(2.0); // 4y
        y = q4 * s;
        w = (r[(0, 2)] - r[(2, 0)]) / s;
        x = (r[(0, 1)] + r[(1, 0)]) / s;
        z = (r[(1, 2)] + r[(2, 1)]) / s;
    } else {
        let s = (one + m22 - m00 - m11).square_root() * T::of(2.0); // 4z
        z = q4 * s;
        w = (r[(1, 0)] - r[(0, 1)]) / s;
        x = (r[(0, 2)] + r[(2, 0)]) / s;
        y = (r[(1, 2)] + r[(2, 1)]) / s;
    }
    if w < T::zero() {
        [-x, -y, -z, -w]
    } else {
        [x, y, z, w]
    }
}
