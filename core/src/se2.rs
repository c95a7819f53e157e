//! SE(2): planar poses ("situations"), their group law and velocities — §2.1–2.2.
//!
//! A pose `r = (x, y, θ)` is the situation of a frame with respect to another one: `r_ab`
//! is frame `b` seen from frame `a`, exactly as in the paper (`r_bd` is the target seen
//! from the base, `r_eb` the base seen from the end effector). A pose without a second
//! index is seen from the fixed frame. Velocities are *body* velocities
//! `u = (v₁, v₂, ω)`: `ṙ = R̄(θ) u` (eq. 3).
//!
//! The product does not wrap angles (so that a pose integrated over time stays
//! continuous); a *difference* between poses ([`Pose::between`]) wraps its angle to
//! (−π, π].

use nalgebra::{Matrix3, Vector2, Vector3};

use crate::scalar::{wrap_angle, Real};

/// A planar pose `(x, y, θ)`: metres, metres, radians.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pose<T> {
    /// Position along the first axis of the reference frame (m).
    pub x: T,
    /// Position along the second axis of the reference frame (m).
    pub y: T,
    /// Orientation (rad).
    pub theta: T,
}

impl<T: Real> Pose<T> {
    /// A pose from its coordinates (m, m, rad).
    #[inline]
    pub const fn new(x: T, y: T, theta: T) -> Self {
        Self { x, y, theta }
    }

    /// The identity `e = (0, 0, 0)`.
    #[inline]
    pub fn identity() -> Self {
        Self::new(T::zero(), T::zero(), T::zero())
    }

    /// The pose as the column `(x, y, θ)`.
    #[inline]
    pub fn to_vector(&self) -> Vector3<T> {
        Vector3::new(self.x, self.y, self.theta)
    }

    /// The pose with coordinates `v = (x, y, θ)`.
    #[inline]
    pub fn from_vector(v: &Vector3<T>) -> Self {
        Self::new(v[0], v[1], v[2])
    }

    /// The position `p = (x, y)`.
    #[inline]
    pub fn position(&self) -> Vector2<T> {
        Vector2::new(self.x, self.y)
    }

    /// Group product `self · other`, eq. (1): `(p_a + R(θ_a) p_b, θ_a + θ_b)`.
    #[inline]
    pub fn compose(&self, other: &Self) -> Self {
        let (s, c) = self.theta.sincos();
        self.compose_sc(other, s, c)
    }

    /// [`compose`](Self::compose) with `sin θ_self`, `cos θ_self` already known.
    #[inline]
    pub(crate) fn compose_sc(&self, other: &Self, s: T, c: T) -> Self {
        Self::new(
            self.x + c * other.x - s * other.y,
            self.y + s * other.x + c * other.y,
            self.theta + other.theta,
        )
    }

    /// Inverse `r⁻¹ = (−R(−θ) p, −θ)` (§2.1).
    #[inline]
    pub fn inverse(&self) -> Self {
        let (s, c) = self.theta.sincos();
        self.inverse_sc(s, c)
    }

    /// [`inverse`](Self::inverse) with `sin θ`, `cos θ` already known.
    #[inline]
    pub(crate) fn inverse_sc(&self, s: T, c: T) -> Self {
        Self::new(-(c * self.x + s * self.y), s * self.x - c * self.y, -self.theta)
    }

    /// The difference `self⁻¹ · other` (the pose of `other` seen from `self`), its angle
    /// wrapped to (−π, π].
    #[inline]
    pub fn between(&self, other: &Self) -> Self {
        let (s, c) = self.theta.sincos();
        let dx = other.x - self.x;
        let dy = other.y - self.y;
        Self::new(c * dx + s * dy, -s * dx + c * dy, wrap_angle(other.theta - self.theta))
    }

    /// [`between`](Self::between) with `sin θ_self`, `cos θ_self` already known.
    #[inline]
    pub(crate) fn between_sc(&self, other: &Self, s: T, c: T) -> Self {
        let dx = other.x - self.x;
        let dy = other.y - self.y;
        Self::new(c * dx + s * dy, -s * dx + c * dy, wrap_angle(other.theta - self.theta))
    }

    /// The same pose with its angle wrapped to (−π, π].
    #[inline]
    pub fn wrapped(&self) -> Self {
        Self::new(self.x, self.y, wrap_angle(self.theta))
    }

    /// The adjoint `Ad_r = [R(θ) −S p; 0 1]`, eq. (5).
    #[inline]
    pub fn ad(&self) -> Matrix3<T> {
        let (s, c) = self.theta.sincos();
        let z = T::zero();
        Matrix3::new(c, -s, self.y, s, c, -self.x, z, z, T::one())
    }

    /// `Ad_{r⁻¹} = (Ad_r)⁻¹ = [R(−θ) R(−θ) S p; 0 1]`, eq. (5).
    #[inline]
    pub fn ad_inv(&self) -> Matrix3<T> {
        let (s, c) = self.theta.sincos();
        let z = T::zero();
        // R(−θ) S p with S p = (−y, x).
        let (spx, spy) = (-self.y, self.x);
        Matrix3::new(c, s, c * spx + s * spy, -s, c, -s * spx + c * spy, z, z, T::one())
    }

    /// The left-invariant distance `d_γ(self, other)`, eq. (2), with `γ > 0`.
    #[inline]
    pub fn distance(&self, other: &Self, gamma: T) -> T {
        let dx = self.x - other.x;
        let dy = self.y - other.y;
        let (_, c) = (self.theta - other.theta).sincos();
        let two = T::one() + T::one();
        (dx * dx + dy * dy + two * gamma * (T::one() - c)).square_root()
    }

    /// Whether all three coordinates are finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.x.finite() && self.y.finite() && self.theta.finite()
    }
}

/// A pose with the sine and cosine of its angle, which products and inverses need.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseSc<T> {
    /// The pose.
    pub pose: Pose<T>,
    /// `(sin θ, cos θ)`.
    pub sc: (T, T),
}

impl<T: Real> PoseSc<T> {
    /// The identity.
    #[inline]
    pub fn identity() -> Self {
        Self { pose: Pose::identity(), sc: (T::zero(), T::one()) }
    }

    /// A pose whose sine and cosine are computed here.
    #[inline]
    pub fn new(pose: Pose<T>) -> Self {
        Self { pose, sc: pose.theta.sincos() }
    }

    /// The exponential of the body twist `u = (v₁, v₂, ω)` held for `s` seconds: the pose
    /// reached from the identity (eq. 3 integrated with `u` constant),
    ///
    /// ```text
    /// exp(s u) = ( V(φ) s (v₁, v₂),  φ ),   φ = s ω,
    /// V(φ) = [ sin φ/φ   −(1 − cos φ)/φ ;  (1 − cos φ)/φ   sin φ/φ ]
    /// ```
    ///
    /// Near `φ = 0` (|φ| ≤ 0.05, every prediction of one control period in practice) the two
    /// ratios come from their Taylor series to `φ⁷`, exact to the last bit of `f64`, with
    /// no trigonometric call.
    #[inline]
    pub fn exp(u: &Vector3<T>, s: T) -> Self {
        let phi = u[2] * s;
        let (vx, vy) = (u[0] * s, u[1] * s);
        let (sinc, cosc, sc) = if phi.abs() <= T::of(0.05) {
            let p2 = phi * phi;
            // sin φ/φ = 1 − φ²/6 + φ⁴/120 − φ⁶/5040; (1 − cos φ)/φ = φ/2 − φ³/24 + φ⁵/720 − φ⁷/40320.
            let sinc =
                T::one() - p2 * (T::of(1.0 / 6.0) - p2 * (T::of(1.0 / 120.0) - p2 * T::of(1.0 / 5040.0)));
            let cosc = phi
                * (T::of(0.5)
                    - p2 * (T::of(1.0 / 24.0) - p2 * (T::of(1.0 / 720.0) - p2 * T::of(1.0 / 40320.0))));
            (sinc, cosc, (phi * sinc, T::one() - phi * cosc))
        } else {
            let (sp, cp) = phi.sincos();
            let inv = T::one() / phi;
            (sp * inv, (T::one() - cp) * inv, (sp, cp))
        };
        let pose = Pose::new(sinc * vx - cosc * vy, cosc * vx + sinc * vy, phi);
        Self { pose, sc }
    }

    /// The product `self · other`, eq. (1).
    #[inline]
    pub fn compose(&self, other: &Self) -> Self {
        Self { pose: self.pose.compose_sc(&other.pose, self.sc.0, self.sc.1), sc: add_sc(self.sc, other.sc) }
    }

    /// The inverse `self⁻¹`.
    #[inline]
    pub fn inverse(&self) -> Self {
        Self { pose: self.pose.inverse_sc(self.sc.0, self.sc.1), sc: (-self.sc.0, self.sc.1) }
    }
}

/// `(sin(a + b), cos(a + b))` from the sines and cosines of `a` and `b`.
#[inline]
pub(crate) fn add_sc<T: Real>(a: (T, T), b: (T, T)) -> (T, T) {
    (a.0 * b.1 + a.1 * b.0, a.1 * b.1 - a.0 * b.0)
}

/// `R(θ)` as a 2×2 matrix (§2).
#[inline]
pub fn rot<T: Real>(theta: T) -> nalgebra::Matrix2<T> {
    let (s, c) = theta.sincos();
    nalgebra::Matrix2::new(c, -s, s, c)
}

/// `R̄(θ) = diag(R(θ), 1)` (§2).
#[inline]
pub fn rbar<T: Real>(theta: T) -> Matrix3<T> {
    let (s, c) = theta.sincos();
    rbar_sc(s, c)
}

/// `R̄(θ)` from `sin θ` and `cos θ`.
#[inline]
pub fn rbar_sc<T: Real>(s: T, c: T) -> Matrix3<T> {
    let z = T::zero();
    Matrix3::new(c, -s, z, s, c, z, z, z, T::one())
}

/// `S p` with `S = R(π/2)`: `(−p_y, p_x)`.
#[inline]
pub fn s_times<T: Real>(px: T, py: T) -> (T, T) {
    (-py, px)
}

/// Time derivative of a pose moving with body velocity `u`: `ṙ = R̄(θ) u`, eq. (3).
#[inline]
pub fn pose_rate<T: Real>(r: &Pose<T>, u: &Vector3<T>) -> Vector3<T> {
    rbar(r.theta) * u
}

/// Body velocity of the product `r_c r_d`: `u_d + Ad_{r_d⁻¹} u_c`, eq. (4).
#[inline]
pub fn product_velocity<T: Real>(r_d: &Pose<T>, u_c: &Vector3<T>, u_d: &Vector3<T>) -> Vector3<T> {
    u_d + r_d.ad_inv() * u_c
}

/// Body velocity of `r⁻¹` when `r` moves with body velocity `u`: `−Ad_r u`, eq. (6).
#[inline]
pub fn inverse_velocity<T: Real>(r: &Pose<T>, u: &Vector3<T>) -> Vector3<T> {
    -(r.ad() * u)
}

/// Body velocity `u_cd = u_d − Ad_{r_dc} u_c` of `r_cd = r_c⁻¹ r_d`, eqs. (8)–(9).
#[inline]
pub fn relative_velocity<T: Real>(
    r_c: &Pose<T>,
    r_d: &Pose<T>,
    u_c: &Vector3<T>,
    u_d: &Vector3<T>,
) -> Vector3<T> {
    let r_dc = r_d.inverse().compose(r_c);
    u_d - r_dc.ad() * u_c
}

/// Body velocity of `r_c r_d⁻¹`: `Ad_{r_d} (u_c − u_d)`, eq. (7).
#[inline]
pub fn quotient_velocity<T: Real>(r_d: &Pose<T>, u_c: &Vector3<T>, u_d: &Vector3<T>) -> Vector3<T> {
    r_d.ad() * (u_c - u_d)
}

/// Inverse of a 3×3 matrix by cofactors, with its determinant; `None` when the
/// determinant is zero or not finite.
#[inline]
pub fn inverse3<T: Real>(m: &Matrix3<T>) -> Option<(Matrix3<T>, T)> {
    let c00 = m[(1, 1)] * m[(2, 2)] - m[(1, 2)] * m[(2, 1)];
    let c01 = m[(1, 2)] * m[(2, 0)] - m[(1, 0)] * m[(2, 2)];
    let c02 = m[(1, 0)] * m[(2, 1)] - m[(1, 1)] * m[(2, 0)];
    let det = m[(0, 0)] * c00 + m[(0, 1)] * c01 + m[(0, 2)] * c02;
    if det == T::zero() || !det.finite() {
        return None;
    }
    let inv_det = T::one() / det;
    let inv = Matrix3::new(
        c00,
        m[(0, 2)] * m[(2, 1)] - m[(0, 1)] * m[(2, 2)],
        m[(0, 1)] * m[(1, 2)] - m[(0, 2)] * m[(1, 1)],
        c01,
        m[(0, 0)] * m[(2, 2)] - m[(0, 2)] * m[(2, 0)],
        m[(0, 2)] * m[(1, 0)] - m[(0, 0)] * m[(1, 2)],
        c02,
        m[(0, 1)] * m[(2, 0)] - m[(0, 0)] * m[(2, 1)],
        m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)],
    ) * inv_det;
    Some((inv, det))
}
