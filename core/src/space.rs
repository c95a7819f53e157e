//! The space the target lives in: the plane of §4 ([`Planar`], SE(2)) or space, §5
//! ([`Spatial`], SE(3)).
//!
//! The platform always moves in the plane, and its law (37) always works on planar poses.
//! What changes with the space is the target: its pose `r_d` and body velocity `u_d`
//! (three or six numbers), the arm's task `e_p` (as many), and how the hold-aware
//! discretisation moves the target over the hold. The law is written once over this trait;
//! for the platform it takes §5's *projection* of the target on the plane ([`Space::project`]):
//! the projection of its origin, its yaw, and the planar velocity of that projected frame.
//!
//! ```text
//! r_bd        = r_b⁻¹ r_d                       (r_b lifted to SE(3): rotation about z)
//! r_bd(s)     = r_bd exp(s ū_d)                 (the target over s seconds at mean twist ū_d)
//! r_bd(t_e)   = E⁻¹ r_bd(s)                     (E: the base's own motion, planar, lifted)
//! projection  = (x, y, ψ),  ψ = atan2(R₂₁, R₁₁)
//! ū_d,plane   = (R(ψ)ᵀ (R v)_xy,  ψ̇),   ψ̇ = (R₁₁ Ṙ₂₁ − R₂₁ Ṙ₁₁)/(R₁₁² + R₂₁²),  Ṙ = R [ω]×
//! ```
//!
//! With a target that stays in the plane (`R = R_z(θ)`), the projection is the target
//! itself and `ū_d,plane = (v₁, v₂, ω₃)`: the spatial law's platform sees exactly the planar
//! one's.

use core::fmt::Debug;
use core::ops::{Add, Div, Mul, Sub};

use nalgebra::{SVector, Vector3, Vector6};

use crate::error::{Bound, ParamError, Rule};
use crate::scalar::Real;
use crate::se2::{Pose, PoseSc};
use crate::se3::Pose3;
use crate::so3;

/// A vector of a space's dimension: a body twist or a task error `e_p`.
pub trait Vector<T>:
    Copy
    + Debug
    + PartialEq
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<T, Output = Self>
    + Div<T, Output = Self>
{
    /// The zero vector.
    fn zeros() -> Self;
    /// The components.
    fn as_slice(&self) -> &[T];
    /// The largest absolute component.
    fn amax(&self) -> T;
}

impl<T: Real, const D: usize> Vector<T> for SVector<T, D> {
    #[inline]
    fn zeros() -> Self {
        SVector::zeros()
    }
    #[inline]
    fn as_slice(&self) -> &[T] {
        nalgebra::Matrix::as_slice(self)
    }
    #[inline]
    fn amax(&self) -> T {
        nalgebra::Matrix::amax(self)
    }
}

/// A target space: the types of the target's pose and velocity and how the law moves and
/// projects them.
pub trait Space<T: Real>: Copy + Debug + PartialEq + Eq + Default + 'static {
    /// The dimension of a pose's tangent space: 3 for SE(2), 6 for SE(3).
    const DIM: usize;
    /// A pose in the fixed frame: the measured target `r_d`, the task's `r*_ed`.
    type Pose: Copy + Debug + PartialEq;
    /// A body twist (the target's `u_d`) or a task error (`e_p`).
    type Vector: Vector<T>;
    /// The target seen from the base, `r_bd`, with what products need.
    type Relative: Copy + Debug;
    /// What the arm law precomputes from `r*_ed`.
    type Star: Copy + Debug;

    /// Whether every coordinate of a pose is finite.
    fn pose_is_finite(p: &Self::Pose) -> bool;

    /// Checks a pose parameter (finite, within the length bound, a rotation).
    ///
    /// # Errors
    /// The rule it breaks, naming `name`.
    fn validate_pose(name: &'static str, p: &Self::Pose) -> Result<(), ParamError>;

    /// What the arm law precomputes from `r*_ed`.
    fn star(target_in_effector: &Self::Pose) -> Self::Star;

    /// `r_bd = r_b⁻¹ r_d` with `(sin θ_b, cos θ_b)`.
    fn relative(base: &Pose<T>, sc_b: (T, T), target: &Self::Pose) -> Self::Relative;

    /// `r_bd exp(s ū)`: the target moved for `s ≥ 0` seconds at mean body twist `ū`
    /// (unchanged for `s ≤ 0`).
    fn advance(r_bd: &Self::Relative, mean_velocity: &Self::Vector, s: T) -> Self::Relative;

    /// `E⁻¹ r_bd`: the target seen from the base after the base's own motion `E` (planar).
    fn seen_from_moved_base(motion: &PoseSc<T>, r_bd: &Self::Relative) -> Self::Relative;

    /// §5's projection on the plane: the planar `r_bd` and the planar body velocity of the
    /// projected target; `None` where its yaw is undefined (its `x` axis vertical).
    fn project(r_bd: &Self::Relative, u_d: &Self::Vector) -> Option<(PoseSc<T>, Vector3<T>)>;

    /// A vector in another scalar type (rounding to nearest for `f32`).
    fn cast_vector<U: Real>(v: &<Self as Space<T>>::Vector) -> <Self as Space<U>>::Vector
    where
        Self: Space<U>;
}

/// The plane, SE(2): the paper's §4.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Planar;

/// Space, SE(3): the paper's §5.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Spatial;

impl<T: Real> Space<T> for Planar {
    const DIM: usize = 3;
    type Pose = Pose<T>;
    type Vector = Vector3<T>;
    type Relative = PoseSc<T>;
    /// `(sin θ*, cos θ*)`.
    type Star = (T, T);

    #[inline]
    fn pose_is_finite(p: &Pose<T>) -> bool {
        p.is_finite()
    }

    fn validate_pose(name: &'static str, p: &Pose<T>) -> Result<(), ParamError> {
        if !p.is_finite() {
            return Err(ParamError::new(name, Rule::NonFinite));
        }
        for v in [p.x, p.y, p.theta] {
            at_most(name, v)?;
        }
        Ok(())
    }

    fn star(p: &Pose<T>) -> (T, T) {
        p.theta.sincos()
    }

    #[inline]
    fn relative(base: &Pose<T>, sc_b: (T, T), target: &Pose<T>) -> PoseSc<T> {
        PoseSc::new(base.between_sc(target, sc_b.0, sc_b.1))
    }

    #[inline]
    fn advance(r_bd: &PoseSc<T>, mean_velocity: &Vector3<T>, s: T) -> PoseSc<T> {
        r_bd.compose(&target_motion(mean_velocity, s))
    }

    #[inline]
    fn seen_from_moved_base(motion: &PoseSc<T>, r_bd: &PoseSc<T>) -> PoseSc<T> {
        motion.inverse().compose(r_bd)
    }

    #[inline]
    fn project(r_bd: &PoseSc<T>, u_d: &Vector3<T>) -> Option<(PoseSc<T>, Vector3<T>)> {
        Some((*r_bd, *u_d))
    }

    fn cast_vector<U: Real>(v: &Vector3<T>) -> <Self as Space<U>>::Vector {
        v.map(|x| U::of(x.as_f64()))
    }
}

impl<T: Real> Space<T> for Spatial {
    const DIM: usize = 6;
    type Pose = Pose3<T>;
    type Vector = Vector6<T>;
    type Relative = Pose3<T>;
    /// `r*_ed` itself.
    type Star = Pose3<T>;

    #[inline]
    fn pose_is_finite(p: &Pose3<T>) -> bool {
        p.is_finite()
    }

    fn validate_pose(name: &'static str, p: &Pose3<T>) -> Result<(), ParamError> {
        if !p.is_finite() {
            return Err(ParamError::new(name, Rule::NonFinite));
        }
        for v in p.translation.iter() {
            at_most(name, *v)?;
        }
        if so3::orthonormality(&p.rotation) > rotation_tolerance::<T>() {
            return Err(ParamError::new(name, Rule::NotOrthonormal));
        }
        Ok(())
    }

    fn star(p: &Pose3<T>) -> Pose3<T> {
        *p
    }

    #[inline]
    fn relative(base: &Pose<T>, sc_b: (T, T), target: &Pose3<T>) -> Pose3<T> {
        Pose3::from_planar_sc(base, sc_b.0, sc_b.1).between(target)
    }

    #[inline]
    fn advance(r_bd: &Pose3<T>, mean_velocity: &Vector6<T>, s: T) -> Pose3<T> {
        if s <= T::zero() {
            return *r_bd;
        }
        r_bd.compose(&Pose3::exp(&(mean_velocity * s)))
    }

    #[inline]
    fn seen_from_moved_base(motion: &PoseSc<T>, r_bd: &Pose3<T>) -> Pose3<T> {
        Pose3::from_planar_sc(&motion.pose, motion.sc.0, motion.sc.1).between(r_bd)
    }

    #[inline]
    fn project(r_bd: &Pose3<T>, u_d: &Vector6<T>) -> Option<(PoseSc<T>, Vector3<T>)> {
        let plane = r_bd.planar()?;
        let r = &r_bd.rotation;
        let (w_y, w_z) = (u_d[4], u_d[5]);
        // The first column's rate, Ṙ e₁ = R (ω × e₁) = ω_z R e₂ − ω_y R e₃.
        let d00 = w_z * r[(0, 1)] - w_y * r[(0, 2)];
        let d10 = w_z * r[(1, 1)] - w_y * r[(1, 2)];
        let (c, s) = (r[(0, 0)], r[(1, 0)]);
        let yaw_rate = (c * d10 - s * d00) / (c * c + s * s);
        // The origin's velocity R v, in the projected frame.
        let v = r * Vector3::new(u_d[0], u_d[1], u_d[2]);
        let (sp, cp) = plane.sc;
        Some((plane, Vector3::new(cp * v[0] + sp * v[1], -sp * v[0] + cp * v[1], yaw_rate)))
    }

    fn cast_vector<U: Real>(v: &Vector6<T>) -> <Self as Space<U>>::Vector {
        v.map(|x| U::of(x.as_f64()))
    }
}

/// How far from orthonormal a given rotation may be ([`so3::orthonormality`]): `10⁻⁹` in
/// `f64`, `10⁻⁵` in `f32` — rounding of entries typed with ten digits passes, a wrong entry
/// does not.
pub(crate) fn rotation_tolerance<T: Real>() -> T {
    if T::default_epsilon() > T::of(1e-10) {
        T::of(1e-5)
    } else {
        T::of(1e-9)
    }
}

fn at_most<T: Real>(name: &'static str, v: T) -> Result<(), ParamError> {
    if v.abs() > T::of(Bound::Length.value()) {
        Err(ParamError::new(name, Rule::TooLarge(Bound::Length)))
    } else {
        Ok(())
    }
}

/// The target's displacement over `s` seconds at mean body velocity `ū_d`: `exp(s ū_d)`
/// (the first Magnus term; exact for a constant twist).
#[inline]
fn target_motion<T: Real>(mean_velocity: &Vector3<T>, s: T) -> PoseSc<T> {
    if s <= T::zero() {
        return PoseSc::identity();
    }
    PoseSc::exp(mean_velocity, s)
}
