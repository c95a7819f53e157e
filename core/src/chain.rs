//! Arms described as data: a serial chain of revolute and prismatic joints, their limits,
//! and where the arm is mounted on the platform — with the presets `rpr` (the paper's
//! arm), `ur5` and `panda`.
//!
//! **The description: joint frames as in URDF** (a product of exponentials in local
//! frames). The chain is
//!
//! ```text
//! r_be(q) = M · O₁ · J₁(q₁) · O₂ · J₂(q₂) ⋯ O_N · J_N(q_N) · E
//! Jᵢ(q) = exp(q [aᵢ; 0]) (revolute: rotation by q about aᵢ)   or   (I, q aᵢ) (prismatic)
//! ```
//!
//! with `M` the mounting pose (the arm's base frame seen from the platform's frame: `x`
//! forward, `z` up, on the ground), `Oᵢ` joint `i`'s frame seen from the previous joint's
//! *moving* frame (from the arm's base for the first) at `qᵢ₋₁ = 0`, `aᵢ` its unit axis in
//! its own frame, and `E` the end effector seen from the last joint's moving frame. Why
//! this form rather than Denavit–Hartenberg: it is what URDF files — which every robot
//! vendor publishes — contain (`<origin xyz rpy>`, `<axis>`), it needs no convention for
//! where the frames sit, a planar arm is written with planar numbers (so the `rpr` preset
//! gives the paper's arm *exactly*, [`PlanarArm`](crate::PlanarArm)), and both DH
//! conventions map onto it with no loss ([`Chain::from_dh`]: a link is
//! `R_x(α) T_x(a) R_z(θ) T_z(d)` followed by a joint about or along `z`).
//!
//! **Home.** Every joint has a home position strictly inside its limits: the arm's
//! preferred configuration `q*` (the paper's `q_* = (0, 0.45, 0)` for `rpr`). The law's
//! preset derives from it the platform's preferred pose `r_*` (the pose from which the arm
//! at home holds the target at `r*_ed`) and the margins of the weight `Ψ` (52). Zero need
//! not be inside the limits (the Panda's fourth joint stays in (−3.07, −0.07) rad).
//!
//! **Validation** ([`Chain::validate`]) names the field that breaks a rule: a rotation
//! that is not orthonormal (`mount.rotation`, `joints.origin.rotation` with the joint,
//! `tool.rotation`), an axis that is not a unit vector (`joints.axis`), non-finite values,
//! empty limits (`joints.lower`; a revolute joint may have none: `(−∞, +∞)`, URDF's
//! `continuous`), a home outside them (`joints.home`), a non-positive
//! velocity limit (`joints.max_velocity`). A chain with fewer joints than a task needs is
//! refused by the arm that uses it ([`PlanarArm`](crate::PlanarArm): 3,
//! [`SpatialArm`](crate::SpatialArm): 6).

use nalgebra::{Matrix3, SVector, Vector3};

use crate::error::{Bound, ParamError, Rule};
use crate::params::JointLimits;
use crate::scalar::Real;
use crate::se3::Pose3;
use crate::so3;
use crate::space::rotation_tolerance;

/// A joint's kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum JointKind {
    /// Turns about its axis by `q` radians.
    Revolute,
    /// Slides along its axis by `q` metres.
    Prismatic,
}

/// One joint of a chain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Joint<T> {
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// The joint's frame seen from the previous joint's moving frame (from the arm's base
    /// frame for the first joint), when the previous joint is at 0 (URDF's `origin`).
    pub origin: Pose3<T>,
    /// The unit axis in the joint's frame (URDF's `axis`).
    pub axis: Vector3<T>,
    /// Lower limit `q⁻` (rad or m); `−∞` with `q⁺ = +∞` for a revolute joint without
    /// position limits (URDF's `continuous`; see [`JointLimits`]).
    pub lower: T,
    /// Upper limit `q⁺ > q⁻` (rad or m); `+∞` for a joint without position limits.
    pub upper: T,
    /// Home position, strictly inside the limits (rad or m).
    pub home: T,
    /// Largest `|q̇|` (rad/s or m/s); `+∞` for none.
    pub max_velocity: T,
}

/// A serial arm: where it is mounted on the platform, its joints, and its end effector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chain<T, const N: usize> {
    /// The arm's base frame seen from the platform's frame (`x` forward, `z` up, origin on
    /// the ground).
    pub mount: Pose3<T>,
    /// The joints, from the base outwards.
    pub joints: [Joint<T>; N],
    /// The end effector seen from the last joint's moving frame.
    pub tool: Pose3<T>,
}

/// A frame as plain numbers: a translation (m) and a rotation matrix given by rows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameData<T> {
    /// Translation `(x, y, z)` (m).
    pub xyz: [T; 3],
    /// Rotation matrix, row by row.
    pub rotation: [[T; 3]; 3],
}

/// A joint as plain numbers (see [`Joint`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointData<T> {
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// The joint's frame in the previous joint's moving frame.
    pub origin: FrameData<T>,
    /// The unit axis in the joint's frame.
    pub axis: [T; 3],
    /// `[q⁻, q⁺]` (rad or m).
    pub limits: [T; 2],
    /// Home position (rad or m).
    pub home: T,
    /// Largest `|q̇|` (rad/s or m/s); `+∞` for none.
    pub max_velocity: T,
}

/// A row of a Denavit–Hartenberg table, with the joint's limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DhJoint<T> {
    /// Revolute (`θ` varies) or prismatic (`d` varies).
    pub kind: JointKind,
    /// Link length `a` (m).
    pub a: T,
    /// Link twist `α` (rad).
    pub alpha: T,
    /// Link offset `d` (m): the constant part for a prismatic joint.
    pub d: T,
    /// Joint angle `θ` (rad): the constant part (offset) for a revolute joint.
    pub theta: T,
    /// `[q⁻, q⁺]` of the joint variable (rad or m).
    pub limits: [T; 2],
    /// Home position (rad or m).
    pub home: T,
    /// Largest `|q̇|` (rad/s or m/s).
    pub max_velocity: T,
}

/// The two Denavit–Hartenberg conventions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DhConvention {
    /// Classic (Denavit and Hartenberg; Universal Robots publish theirs so): link `i` is
    /// `R_z(θᵢ) T_z(dᵢ) T_x(aᵢ) R_x(αᵢ)`.
    Standard,
    /// Modified (Craig; Franka Emika publish theirs so): link `i` is
    /// `R_x(αᵢ₋₁) T_x(aᵢ₋₁) R_z(θᵢ) T_z(dᵢ)`, with row `i` holding `aᵢ₋₁`, `αᵢ₋₁`.
    Modified,
}

impl<T: Real> Pose3<T> {
    /// `R_x(α) T_x(a) R_z(θ) T_z(d)`: a modified-DH link before its joint, right angles
    /// exact ([`so3::exact_sincos`]).
    pub fn dh_link(a: T, alpha: T, d: T, theta: T) -> Self {
        let (sa, ca) = so3::exact_sincos(alpha);
        let (st, ct) = so3::exact_sincos(theta);
        let rx = so3::about_axis(0, sa, ca);
        let rotation = rx * so3::about_axis(2, st, ct);
        // R_x(α) (a, 0, 0) + R_x(α) R_z(θ) (0, 0, d) = (a, 0, 0) + R_x(α) (0, 0, d).
        let translation = Vector3::new(a, -sa * d, ca * d);
        Self::new(rotation, translation)
    }
}

impl<T: Real> FrameData<T> {
    fn pose(&self) -> Pose3<T> {
        let r = &self.rotation;
        Pose3::new(
            Matrix3::new(r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2]),
            Vector3::new(self.xyz[0], self.xyz[1], self.xyz[2]),
        )
    }
}

impl<T: Real, const N: usize> Chain<T, N> {
    /// A chain from its parts, validated.
    ///
    /// # Errors
    /// The first field that breaks a rule (see [`Chain::validate`]).
    pub fn new(mount: Pose3<T>, joints: [Joint<T>; N], tool: Pose3<T>) -> Result<Self, ParamError> {
        let chain = Self { mount, joints, tool };
        chain.validate()?;
        Ok(chain)
    }

    /// A chain from plain numbers (what a configuration file holds), validated.
    ///
    /// # Errors
    /// The first field that breaks a rule (see [`Chain::validate`]).
    pub fn from_arrays(
        mount: &FrameData<T>,
        joints: &[JointData<T>; N],
        tool: &FrameData<T>,
    ) -> Result<Self, ParamError> {
        let joints = core::array::from_fn(|i| {
            let j = &joints[i];
            Joint {
                kind: j.kind,
                origin: j.origin.pose(),
                axis: Vector3::new(j.axis[0], j.axis[1], j.axis[2]),
                lower: j.limits[0],
                upper: j.limits[1],
                home: j.home,
                max_velocity: j.max_velocity,
            }
        });
        Self::new(mount.pose(), joints, tool.pose())
    }

    /// A chain from a Denavit–Hartenberg table: every joint about or along its frame's `z`;
    /// `mount` places the DH base frame on the platform, `tool` the end effector in the last
    /// DH frame (for [`DhConvention::Standard`], after the last row's `a` and `α`).
    ///
    /// # Errors
    /// The first field that breaks a rule (see [`Chain::validate`]).
    pub fn from_dh(
        convention: DhConvention,
        mount: Pose3<T>,
        rows: &[DhJoint<T>; N],
        tool: Pose3<T>,
    ) -> Result<Self, ParamError> {
        let chain = Self::dh_unchecked(convention, mount, rows, tool);
        chain.validate()?;
        Ok(chain)
    }

    /// [`from_dh`](Self::from_dh) without validation (the presets' tables are checked by
    /// tests).
    fn dh_unchecked(
        convention: DhConvention,
        mount: Pose3<T>,
        rows: &[DhJoint<T>; N],
        tool: Pose3<T>,
    ) -> Self {
        let z = T::zero();
        let joints = core::array::from_fn(|i| {
            let r = &rows[i];
            // The link before joint i: modified rows carry it; standard rows carry it in
            // row i − 1 (a, α) and row i (d, θ).
            let (a, alpha) = match convention {
                DhConvention::Modified => (r.a, r.alpha),
                DhConvention::Standard => rows.get(i.wrapping_sub(1)).map_or((z, z), |p| (p.a, p.alpha)),
            };
            Joint {
                kind: r.kind,
                origin: Pose3::dh_link(a, alpha, r.d, r.theta),
                axis: Vector3::new(z, z, T::one()),
                lower: r.limits[0],
                upper: r.limits[1],
                home: r.home,
                max_velocity: r.max_velocity,
            }
        });
        let tool = match (convention, rows.last()) {
            (DhConvention::Standard, Some(last)) => Pose3::dh_link(last.a, last.alpha, z, z).compose(&tool),
            _ => tool,
        };
        Self { mount, joints, tool }
    }

    /// Checks the description; see the module docs for the rules and the field names.
    ///
    /// # Errors
    /// The first field that breaks a rule.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_frame("mount.translation", "mount.rotation", None, &self.mount)?;
        check_frame("tool.translation", "tool.rotation", None, &self.tool)?;
        for (i, j) in self.joints.iter().enumerate() {
            check_frame("joints.origin.translation", "joints.origin.rotation", Some(i), &j.origin)?;
            if !j.axis.iter().all(|x| x.finite()) {
                return Err(ParamError::joint("joints.axis", i, Rule::NonFinite));
            }
            if (j.axis.norm_squared() - T::one()).abs() > rotation_tolerance::<T>() {
                return Err(ParamError::joint("joints.axis", i, Rule::NotUnitVector));
            }
            // A revolute joint may have no position limits (−∞, +∞: URDF's `continuous`).
            let free = j.kind == JointKind::Revolute && crate::params::unbounded(j.lower, j.upper);
            let checked: &[(&'static str, T)] = if free {
                &[("joints.home", j.home)]
            } else {
                &[("joints.lower", j.lower), ("joints.upper", j.upper), ("joints.home", j.home)]
            };
            for &(name, v) in checked {
                if !v.finite() {
                    return Err(ParamError::joint(name, i, Rule::NonFinite));
                }
                if v.abs() > T::of(Bound::Length.value()) {
                    return Err(ParamError::joint(name, i, Rule::TooLarge(Bound::Length)));
                }
            }
            if j.lower >= j.upper {
                return Err(ParamError::joint("joints.lower", i, Rule::EmptyInterval));
            }
            if j.home <= j.lower || j.home >= j.upper {
                return Err(ParamError::joint("joints.home", i, Rule::HomeOutsideLimits));
            }
            if j.max_velocity.nan() {
                return Err(ParamError::joint("joints.max_velocity", i, Rule::NonFinite));
            }
            if j.max_velocity <= T::zero() {
                return Err(ParamError::joint("joints.max_velocity", i, Rule::NotPositive));
            }
        }
        Ok(())
    }

    /// The joint limits, for the law's [`Params`](crate::Params).
    pub fn limits(&self) -> JointLimits<T, N> {
        JointLimits {
            lower: SVector::from_fn(|i, _| self.joints[i].lower),
            upper: SVector::from_fn(|i, _| self.joints[i].upper),
        }
    }

    /// The home configuration `q*`.
    pub fn home(&self) -> SVector<T, N> {
        SVector::from_fn(|i, _| self.joints[i].home)
    }

    /// The joint velocity limits (rad/s or m/s).
    pub fn max_velocities(&self) -> SVector<T, N> {
        SVector::from_fn(|i, _| self.joints[i].max_velocity)
    }

    /// The end effector seen from the platform, `r_be(q)`, by the product of the module
    /// docs (a plain evaluation for reference and drawing; the laws use faster forms).
    pub fn end_effector(&self, q: &SVector<T, N>) -> Pose3<T> {
        let mut f = self.mount;
        for (i, j) in self.joints.iter().enumerate() {
            f = f.compose(&j.origin).compose(&j.motion(q[i]));
        }
        f.compose(&self.tool)
    }
}

impl<T: Real> Joint<T> {
    /// The joint's motion `Jᵢ(q)`.
    pub fn motion(&self, q: T) -> Pose3<T> {
        match self.kind {
            JointKind::Revolute => Pose3::new(so3::exp(&(self.axis * q)), Vector3::zeros()),
            JointKind::Prismatic => Pose3::new(Matrix3::identity(), self.axis * q),
        }
    }
}

fn check_frame<T: Real>(
    translation: &'static str,
    rotation: &'static str,
    joint: Option<usize>,
    p: &Pose3<T>,
) -> Result<(), ParamError> {
    let err = |name, rule| match joint {
        Some(i) => ParamError::joint(name, i, rule),
        None => ParamError::new(name, rule),
    };
    if !p.translation.iter().all(|x| x.finite()) {
        return Err(err(translation, Rule::NonFinite));
    }
    if p.translation.iter().any(|x| x.abs() > T::of(Bound::Length.value())) {
        return Err(err(translation, Rule::TooLarge(Bound::Length)));
    }
    if !p.rotation.iter().all(|x| x.finite()) {
        return Err(err(rotation, Rule::NonFinite));
    }
    if so3::orthonormality(&p.rotation) > rotation_tolerance::<T>() {
        return Err(err(rotation, Rule::NotOrthonormal));
    }
    Ok(())
}

/// The presets.
impl<T: Real> Chain<T, 3> {
    /// The paper's RPR arm (§4.3): a revolute joint at `(L, 0) = (0.4 m, 0)` on the platform,
    /// a prismatic joint along the first link, a revolute joint, the end effector
    /// `L_e = 0.15 m` further; limits `q₁ ∈ (−π/3, π/3)`, `q₂ ∈ (0, 0.7)`,
    /// `q₃ ∈ (−π/2, π/2)`; home `q_* = (0, 0.45, 0)`. Planar, at height 0: through
    /// [`PlanarArm`](crate::PlanarArm) it is the paper's [`Rpr`](crate::Rpr), bit for bit.
    pub fn rpr() -> Self {
        let (z, o) = (T::zero(), T::one());
        let pi = T::pi();
        let inf = T::of(f64::INFINITY);
        let joint = |kind, axis: Vector3<T>, lower, upper, home| Joint {
            kind,
            origin: Pose3::identity(),
            axis,
            lower,
            upper,
            home,
            max_velocity: inf,
        };
        let vertical = Vector3::new(z, z, o);
        Self {
            mount: Pose3::translation(T::of(0.4), z, z),
            joints: [
                joint(JointKind::Revolute, vertical, -pi / T::of(3.0), pi / T::of(3.0), z),
                joint(JointKind::Prismatic, Vector3::new(o, z, z), z, T::of(0.7), T::of(0.45)),
                joint(JointKind::Revolute, vertical, -pi / T::of(2.0), pi / T::of(2.0), z),
            ],
            tool: Pose3::translation(T::of(0.15), z, z),
        }
    }
}

impl<T: Real> Chain<T, 6> {
    /// Universal Robots' UR5 (CB3), from the standard DH parameters Universal Robots
    /// publish ("DH parameters for calculations of kinematics and dynamics",
    /// universal-robots.com/articles/ur/application-installation/dh-parameters-for-calculations-of-kinematics-and-dynamics/):
    /// `d = (0.089159, 0, 0, 0.10915, 0.09465, 0.0823)` m,
    /// `a = (0, −0.425, −0.39225, 0, 0, 0)` m, `α = (π/2, 0, 0, π/2, −π/2, 0)`; the end
    /// effector is the tool flange. Joint range and speed from the UR5 technical
    /// specifications: ±360° and 180°/s for every joint.
    ///
    /// Two joints get a narrower range for the law, inside the published one: the elbow
    /// (3) `(0.15, π − 0.15)` rad and the second wrist joint (5) `(−π + 0.15, −0.15)` rad.
    /// The published range contains the elbow's (stretched, `q₃ = 0`) and the wrist's
    /// (`q₅ = 0`) singular configurations, where no law can place the end effector; like
    /// the paper's `q₂ > 0` for the RPR arm, these limits keep the arm on one side of them
    /// (elbow up, wrist down).
    ///
    /// Mounted `0.5 m` up and `0.1 m` ahead of the platform's origin, turned by π so that
    /// the arm works in front. Home: `(0, −π/2, π/2, −π/2, −π/2, 0)`: upper arm vertical,
    /// forearm forward, flange pointing down, `0.59 m` in front of the platform, `0.11 m` to
    /// its left and `0.93 m` up.
    pub fn ur5() -> Self {
        let pi = T::pi();
        let two_pi = T::two_pi();
        let z = T::zero();
        let v = pi; // 180°/s
        let margin = T::of(0.15);
        let rev = |a: f64, alpha: T, d: f64, limits: [T; 2], home: T| DhJoint {
            kind: JointKind::Revolute,
            a: T::of(a),
            alpha,
            d: T::of(d),
            theta: z,
            limits,
            home,
            max_velocity: v,
        };
        let full = [-two_pi, two_pi];
        let half_pi = pi / T::of(2.0);
        let rows = [
            rev(0.0, half_pi, 0.089159, full, z),
            rev(-0.425, z, 0.0, full, -half_pi),
            rev(-0.39225, z, 0.0, [margin, pi - margin], half_pi),
            rev(0.0, half_pi, 0.10915, full, -half_pi),
            rev(0.0, -half_pi, 0.09465, [-pi + margin, -margin], -half_pi),
            rev(0.0, z, 0.0823, full, z),
        ];
        let (s, c) = so3::exact_sincos(pi);
        let mount = Pose3::new(so3::about_axis(2, s, c), Vector3::new(T::of(0.1), z, T::of(0.5)));
        Self::dh_unchecked(DhConvention::Standard, mount, &rows, Pose3::identity())
    }
}

impl<T: Real> Chain<T, 7> {
    /// Franka Emika's Panda, from the modified DH parameters and joint limits Franka
    /// publish ("Robot and interface specifications", frankaemika.github.io/docs/control_parameters.html):
    /// `a = (0, 0, 0, 0.0825, −0.0825, 0, 0.088)` m, `d = (0.333, 0, 0.316, 0, 0.384, 0, 0)`
    /// m, `α = (0, −π/2, π/2, π/2, −π/2, π/2, π/2)`, flange `d_F = 0.107` m (the end
    /// effector); `q⁺ = (2.8973, 1.7628, 2.8973, −0.0698, 2.8973, 3.7525, 2.8973)` rad,
    /// `q⁻ = (−2.8973, −1.7628, −2.8973, −3.0718, −2.8973, −0.0175, −2.8973)` rad,
    /// `|q̇| ≤ (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61)` rad/s.
    ///
    /// Mounted `0.5 m` up at the platform's origin. Home: the "ready" pose of Franka's
    /// examples, `(0, −π/4, 0, −3π/4, 0, π/2, π/4)`: flange pointing down, `0.31 m` in front
    /// of the platform and `1.09 m` up.
    pub fn panda() -> Self {
        let pi = T::pi();
        let z = T::zero();
        let h = pi / T::of(2.0);
        let upper = [2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973];
        let lower = [-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973];
        let speed = [2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61];
        let a = [0.0, 0.0, 0.0, 0.0825, -0.0825, 0.0, 0.088];
        let d = [0.333, 0.0, 0.316, 0.0, 0.384, 0.0, 0.0];
        let alpha = [z, -h, h, h, -h, h, h];
        let home = [z, -pi / T::of(4.0), z, -pi * T::of(0.75), z, h, pi / T::of(4.0)];
        let rows = core::array::from_fn(|i| DhJoint {
            kind: JointKind::Revolute,
            a: T::of(a[i]),
            alpha: alpha[i],
            d: T::of(d[i]),
            theta: z,
            limits: [T::of(lower[i]), T::of(upper[i])],
            home: home[i],
            max_velocity: T::of(speed[i]),
        });
        let mount = Pose3::translation(z, z, T::of(0.5));
        let flange = Pose3::translation(z, z, T::of(0.107));
        Self::dh_unchecked(DhConvention::Modified, mount, &rows, flange)
    }
}
