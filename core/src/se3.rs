//! SE(3): poses in space — §5 of the paper, where the target and the end effector of a
//! six- or seven-joint arm live.
//!
//! A pose `r_ab = (R_ab, p_ab)` is frame `b` seen from frame `a`, as in [`crate::se2`]:
//! `R_ab` rotates `b`'s coordinates into `a`'s and `p_ab` is `b`'s origin in `a`. Rotations
//! are matrices ([`crate::so3`] says why). Velocities are *body* twists `ξ = (v, ω)` —
//! linear part first, as `(v₁, v₂, ω)` in SE(2):
//! `Ṙ = R [ω]×`, `ṗ = R v`.
//!
//! ```text
//! r_a r_b   = (R_a R_b, p_a + R_a p_b)            r⁻¹ = (Rᵀ, −Rᵀ p)
//! exp ξ     = (exp φ, V(φ) v),  V = J_l(φ) = I + B [φ]× + C [φ]×²     (ξ = (v, φ))
//! log r     = (V(φ)⁻¹ p, φ),  φ = log R,  V⁻¹ = J_l(φ)⁻¹ = I − ½ [φ]× + β [φ]×²
//! Ad_r      = [R  [p]× R; 0  R]          r exp(ξ) r⁻¹ = exp(Ad_r ξ)
//! J_r(ξ)    = J_l(−ξ),  J_l(ξ) = [J_l(φ)  Q(v, φ); 0  J_l(φ)]
//! Q(v, φ)   = ½ [v] + c₃ ([φ][v] + [v][φ] + [φ][v][φ]) + c₄ ([φ]²[v] + [v][φ]² − 3 [φ][v][φ])
//!             + c₅ ([φ][v][φ]² + [φ]²[v][φ])                ([x] = [x]×)
//! c₃ = (θ − sin θ)/θ³,  c₄ = (θ²/2 + cos θ − 1)/θ⁴,  c₅ = (2θ − 3 sin θ + θ cos θ)/(2θ⁵)
//! J_r(ξ)⁻¹  = [J_r(φ)⁻¹  −J_r(φ)⁻¹ Q(−v, −φ) J_r(φ)⁻¹; 0  J_r(φ)⁻¹]
//! ```
//!
//! (`A, B, C, β` as in [`crate::so3`]; `Q` as in Barfoot and Furgale, "Associating
//! uncertainty with three-dimensional poses", IEEE T-RO 2014, eq. 102, checked here by
//! finite differences.) Near `θ = 0` every ratio comes from its series; `c₄` and `c₅` lose
//! the most to cancellation and switch at `θ = 0.6`. The Jacobians are for users
//! and tests; the law needs only `exp`, `log` of rotations and `J_r(φ)⁻¹`.
//!
//! The controller's platform moves in the plane: [`Pose3::from_planar`] lifts an SE(2) pose
//! (rotation about the vertical `z`), and [`Pose3::planar`] is §5's projection of a frame on
//! the plane — the projection of its origin and its yaw (the `z` angle of its `z-y-x` Euler
//! angles, the heading of its `x` axis).

use nalgebra::{Matrix3, SMatrix, Vector3, Vector6};

use crate::scalar::Real;
use crate::se2::{Pose, PoseSc};
use crate::so3;

/// A 6×6 matrix (adjoints, Jacobians of SE(3)).
pub type Matrix6<T> = SMatrix<T, 6, 6>;

/// A pose in space: rotation `R` (orthonormal, `det = 1`) and translation `p` (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose3<T> {
    /// `R_ab`: rotates coordinates in `b` into `a`.
    pub rotation: Matrix3<T>,
    /// `p_ab`: `b`'s origin in `a` (m).
    pub translation: Vector3<T>,
}

impl<T: Real> Default for Pose3<T> {
    fn default() -> Self {
        Self::identity()
    }
}

impl<T: Real> Pose3<T> {
    /// A pose from a rotation matrix (not checked: see [`so3::orthonormality`]) and a
    /// translation (m).
    #[inline]
    pub fn new(rotation: Matrix3<T>, translation: Vector3<T>) -> Self {
        Self { rotation, translation }
    }

    /// The identity.
    #[inline]
    pub fn identity() -> Self {
        Self::new(Matrix3::identity(), Vector3::zeros())
    }

    /// A pure translation (m).
    #[inline]
    pub fn translation(x: T, y: T, z: T) -> Self {
        Self::new(Matrix3::identity(), Vector3::new(x, y, z))
    }

    /// URDF's `origin`: translation `xyz` (m) and `rpy` (rad, `R = R_z(y) R_y(p) R_x(r)`),
    /// right angles exact ([`so3::exact_sincos`]).
    pub fn from_xyz_rpy(xyz: [T; 3], rpy: [T; 3]) -> Self {
        Self::new(so3::from_rpy(rpy[0], rpy[1], rpy[2]), Vector3::new(xyz[0], xyz[1], xyz[2]))
    }

    /// The planar pose `(x, y, θ)` lifted to space: a rotation by `θ` about `z`, at height 0.
    #[inline]
    pub fn from_planar(p: &Pose<T>) -> Self {
        let (s, c) = p.theta.sincos();
        Self::from_planar_sc(p, s, c)
    }

    /// [`from_planar`](Self::from_planar) with `sin θ`, `cos θ` known.
    #[inline]
    pub fn from_planar_sc(p: &Pose<T>, s: T, c: T) -> Self {
        Self::new(so3::about_axis(2, s, c), Vector3::new(p.x, p.y, T::zero()))
    }

    /// The product `self · other`.
    #[inline]
    pub fn compose(&self, other: &Self) -> Self {
        Self::new(self.rotation * other.rotation, self.translation + self.rotation * other.translation)
    }

    /// The inverse `(Rᵀ, −Rᵀ p)`.
    #[inline]
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Self::new(rt, -(rt * self.translation))
    }

    /// `self⁻¹ · other` without forming the inverse.
    #[inline]
    pub fn between(&self, other: &Self) -> Self {
        let rt = self.rotation.transpose();
        Self::new(rt * other.rotation, rt * (other.translation - self.translation))
    }

    /// A point given in the pose's frame, in the reference frame: `R x + p`.
    #[inline]
    pub fn transform_point(&self, x: &Vector3<T>) -> Vector3<T> {
        self.rotation * x + self.translation
    }

    /// `exp ξ` of the body twist `ξ = (v, ω)` (m, rad): the pose reached from the identity
    /// after one second at constant body velocity `ξ`.
    #[inline]
    pub fn exp(xi: &Vector6<T>) -> Self {
        let v = Vector3::new(xi[0], xi[1], xi[2]);
        let phi = Vector3::new(xi[3], xi[4], xi[5]);
        let (a, b, c, _, _) = so3::ratios(phi.dot(&phi));
        Self::new(so3::poly(&phi, a, b), so3::poly(&phi, b, c) * v)
    }

    /// `log r = (v, φ)` with `|φ| ≤ π`.
    #[inline]
    pub fn log(&self) -> Vector6<T> {
        let phi = so3::log(&self.rotation);
        let v = so3::poly(&phi, T::of(-0.5), so3::beta(phi.dot(&phi))) * self.translation;
        Vector6::new(v[0], v[1], v[2], phi[0], phi[1], phi[2])
    }

    /// The adjoint `Ad_r = [R [p]×R; 0 R]`: `r exp(ξ) r⁻¹ = exp(Ad_r ξ)`.
    pub fn adjoint(&self) -> Matrix6<T> {
        let r = &self.rotation;
        let pr = so3::hat(&self.translation) * r;
        let mut m = Matrix6::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(r);
        m.fixed_view_mut::<3, 3>(0, 3).copy_from(&pr);
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(r);
        m
    }

    /// `Ad_r⁻¹ ξ` without forming a matrix: the body twist `(Rᵀ(v − p × ω), Rᵀ ω)`.
    #[inline]
    pub fn adjoint_inv_apply(&self, xi: &Vector6<T>) -> Vector6<T> {
        let rt = self.rotation.transpose();
        let w = Vector3::new(xi[3], xi[4], xi[5]);
        let v = Vector3::new(xi[0], xi[1], xi[2]) - self.translation.cross(&w);
        let (a, b) = (rt * v, rt * w);
        Vector6::new(a[0], a[1], a[2], b[0], b[1], b[2])
    }

    /// The right Jacobian `J_r(ξ)`: `exp(ξ + δ) ≈ exp(ξ) exp(J_r(ξ) δ)`.
    pub fn right_jacobian(xi: &Vector6<T>) -> Matrix6<T> {
        let v = -Vector3::new(xi[0], xi[1], xi[2]);
        let phi = -Vector3::new(xi[3], xi[4], xi[5]);
        // J_r(ξ) = J_l(−ξ).
        let jl = so3::right_jacobian(&phi).transpose();
        let q = q_matrix(&v, &phi);
        let mut m = Matrix6::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&jl);
        m.fixed_view_mut::<3, 3>(0, 3).copy_from(&q);
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(&jl);
        m
    }

    /// `J_r(ξ)⁻¹`: `log(r exp(δ)) ≈ log(r) + J_r(log r)⁻¹ δ`.
    pub fn right_jacobian_inv(xi: &Vector6<T>) -> Matrix6<T> {
        let v = -Vector3::new(xi[0], xi[1], xi[2]);
        let phi = -Vector3::new(xi[3], xi[4], xi[5]);
        let ji = so3::right_jacobian_inv(&(-phi));
        let q = q_matrix(&v, &phi);
        let mut m = Matrix6::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&ji);
        m.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-(ji * q * ji)));
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(&ji);
        m
    }

    /// §5's projection on the plane: the projected origin `(x, y)` and the yaw
    /// `atan2(R₂₁, R₁₁)`, with the sine and cosine of the yaw; `None` when the frame's `x`
    /// axis is vertical to within `10⁻⁶` rad in `f64` (`R₁₁² + R₂₁² ≤ 10⁻¹²`) or `10⁻⁴` rad
    /// in `f32` (`≤ 10⁻⁸`), where the yaw is not defined.
    #[inline]
    pub fn planar(&self) -> Option<PoseSc<T>> {
        let (c, s) = (self.rotation[(0, 0)], self.rotation[(1, 0)]);
        let rho2 = c * c + s * s;
        if rho2.nan() || rho2 <= yaw_floor::<T>() {
            return None;
        }
        let inv = T::one() / rho2.square_root();
        let yaw = s.arctan2(c);
        Some(PoseSc {
            pose: Pose::new(self.translation[0], self.translation[1], yaw),
            sc: (s * inv, c * inv),
        })
    }

    /// Whether every entry is finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.rotation.iter().chain(self.translation.iter()).all(|x| x.finite())
    }
}

/// `R₁₁² + R₂₁²` at or below which the yaw is undefined.
#[inline]
pub(crate) fn yaw_floor<T: Real>() -> T {
    if T::default_epsilon() > T::of(1e-10) {
        T::of(1e-8)
    } else {
        T::of(1e-12)
    }
}

/// Barfoot's `Q(v, φ)` (module docs).
fn q_matrix<T: Real>(v: &Vector3<T>, phi: &Vector3<T>) -> Matrix3<T> {
    let t = phi.dot(phi);
    let (c3, c4, c6) = if t < T::of(0.36) {
        let f = |c: &[f64]| so3::horner(t, c);
        (
            f(&[
                1.0 / 6.0,
                -1.0 / 120.0,
                1.0 / 5040.0,
                -1.0 / 362_880.0,
                1.0 / 39_916_800.0,
                -1.0 / 6_227_020_800.0,
            ]),
            f(&[
                1.0 / 24.0,
                -1.0 / 720.0,
                1.0 / 40_320.0,
                -1.0 / 3_628_800.0,
                1.0 / 479_001_600.0,
                -1.0 / 87_178_291_200.0,
            ]),
            f(&[
                1.0 / 120.0,
                -1.0 / 2520.0,
                1.0 / 120_960.0,
                -1.0 / 9_979_200.0,
                1.0 / 1_245_404_160.0,
                -1.0 / 217_945_728_000.0,
            ]),
        )
    } else {
        let th = t.square_root();
        let (s, c) = th.sincos();
        let t2 = t * t;
        (
            (th - s) / (t * th),
            (t * T::of(0.5) + c - T::one()) / t2,
            (th * T::of(2.0) - s * T::of(3.0) + th * c) / (t2 * th * T::of(2.0)),
        )
    };
    let pv = so3::hat(v);
    let pp = so3::hat(phi);
    let pvp = pv * pp;
    let pp_v_p = pp * pvp;
    let pp2 = pp * pp;
    pv * T::of(0.5)
        + (pp * pv + pvp + pp_v_p) * c3
        + (pp2 * pv + pv * pp2 - pp_v_p * T::of(3.0)) * c4
        + (pp_v_p * pp + pp2 * pvp) * c6
}
