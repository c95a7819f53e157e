//! The manipulator arm: its forward kinematics `r_eb(q)` with first and second
//! derivatives, behind a trait with a const-generic joint count `N`.
//!
//! The law needs only `r_eb(q)` — the platform's pose seen from the end effector — and
//! its derivatives (§4.1), so any planar arm can be plugged in without touching the law.
//! The paper's RPR arm (45) is [`Rpr`].

use nalgebra::{SMatrix, SVector};

use crate::chain::{Chain, JointKind};
use crate::error::{Bound, ParamError, Rule};
use crate::scalar::Real;
use crate::se2::Pose;

/// `r_eb(q)` with its derivatives at one joint configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArmKinematics<T, const N: usize> {
    /// `r_eb(q) = (x_eb, y_eb, θ_eb)`: the platform frame seen from the end effector.
    pub r_eb: Pose<T>,
    /// `∂r_eb/∂q` (3×N), ordinary partial derivatives of `(x_eb, y_eb, θ_eb)`.
    pub jacobian: SMatrix<T, 3, N>,
    /// The Hessians `∂²x_eb/∂q²`, `∂²y_eb/∂q²`, `∂²θ_eb/∂q²` (each N×N, symmetric).
    pub hessian: [SMatrix<T, N, N>; 3],
    /// `(sin θ_eb, cos θ_eb)`: arms usually know them from their own trigonometry, which
    /// saves the law a call.
    pub sin_cos_theta: (T, T),
}

/// A planar manipulator arm with `N` joints mounted on the platform.
pub trait Arm<T: Real, const N: usize>: Copy + core::fmt::Debug {
    /// Whether `∂²θ_eb/∂q²` may be non-zero. Planar arms of revolute and prismatic joints
    /// have `θ_eb` linear in `q` (minus a sum of joint angles) and may set this to `false`,
    /// which lets the law skip that term of (24); the default is the safe `true`.
    const THETA_CURVED: bool = true;

    /// Checks the geometry (e.g. positive link lengths).
    ///
    /// # Errors
    /// The first parameter that breaks a rule.
    fn validate(&self) -> Result<(), ParamError>;

    /// `r_eb(q)` with first and second derivatives.
    fn kinematics(&self, q: &SVector<T, N>) -> ArmKinematics<T, N>;

    /// Whether `q` is a singular configuration of the arm, where `∂r_eb/∂q` loses rank.
    fn is_singular(&self, q: &SVector<T, N>) -> bool;
}

/// The paper's RPR arm, eq. (45): a revolute joint at `(L, 0)` on the platform, a
/// prismatic joint of extension `q₂`, a revolute joint, and the end effector `L_e` further.
///
/// ```text
/// r_eb(q) = ( −R(−q₁−q₃)(L, 0)ᵀ − R(−q₃)(q₂, 0)ᵀ − (L_e, 0)ᵀ ,  −q₁ − q₃ )
/// det ∂r_eb/∂q = q₂            (singular at q₂ = 0)
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rpr<T> {
    /// `L` (m): position of the first joint's axis on the platform's axis.
    pub l: T,
    /// `L_e` (m): distance from the last joint's axis to the end effector.
    pub l_e: T,
}

impl<T: Real> Rpr<T> {
    /// The paper's §4.3 geometry `L = 0.4 m`, `L_e = 0.15 m`.
    pub fn paper() -> Self {
        Self { l: T::of(0.4), l_e: T::of(0.15) }
    }

    /// The end effector's pose seen from the platform, `r_be = r_eb⁻¹`.
    pub fn end_effector(&self, q: &SVector<T, 3>) -> Pose<T> {
        let (s1, c1) = q[0].sincos();
        let (s13, c13) = (q[0] + q[2]).sincos();
        Pose::new(self.l + q[1] * c1 + self.l_e * c13, q[1] * s1 + self.l_e * s13, q[0] + q[2])
    }
}

impl<T: Real> Arm<T, 3> for Rpr<T> {
    /// `θ_eb = −(q₁ + q₃)` is linear.
    const THETA_CURVED: bool = false;

    fn validate(&self) -> Result<(), ParamError> {
        for (name, v) in [("l", self.l), ("l_e", self.l_e)] {
            if !v.finite() {
                return Err(ParamError::new(name, Rule::NonFinite));
            }
            if v < T::zero() {
                return Err(ParamError::new(name, Rule::Geometry));
            }
            if v > T::of(Bound::Length.value()) {
                return Err(ParamError::new(name, Rule::TooLarge(Bound::Length)));
            }
        }
        Ok(())
    }

    #[inline]
    fn kinematics(&self, q: &SVector<T, 3>) -> ArmKinematics<T, 3> {
        let (l, le) = (self.l, self.l_e);
        let q2 = q[1];
        let (s13, c13) = (q[0] + q[2]).sincos();
        let (s3, c3) = q[2].sincos();
        let r_eb = Pose::new(-l * c13 - q2 * c3 - le, l * s13 + q2 * s3, -q[0] - q[2]);
        let z = T::zero();
        let one = T::one();
        #[rustfmt::skip]
        let jacobian = SMatrix::<T, 3, 3>::new(
            l * s13, -c3, l * s13 + q2 * s3,
            l * c13,  s3, l * c13 + q2 * c3,
            -one,      z, -one,
        );
        #[rustfmt::skip]
        let hx = SMatrix::<T, 3, 3>::new(
            l * c13, z,  l * c13,
            z,       z,  s3,
            l * c13, s3, l * c13 + q2 * c3,
        );
        #[rustfmt::skip]
        let hy = SMatrix::<T, 3, 3>::new(
            -l * s13, z,  -l * s13,
            z,        z,  c3,
            -l * s13, c3, -l * s13 - q2 * s3,
        );
        // θ_eb = −(q₁ + q₃).
        ArmKinematics { r_eb, jacobian, hessian: [hx, hy, SMatrix::zeros()], sin_cos_theta: (-s13, c13) }
    }

    #[inline]
    fn is_singular(&self, q: &SVector<T, 3>) -> bool {
        // det ∂r_eb/∂q = q₂: the arm is singular at q₂ = 0 and folded beyond it.
        q[1] <= T::zero()
    }
}

/// A planar arm described as data: a [`Chain`] whose joints turn about the vertical or
/// slide in the plane, evaluated in the plane (the law of §4).
///
/// Its kinematics are computed in the form of [`Rpr`]'s closed form, term by term and in
/// the same order — every sine and cosine of a sum of joint angles taken once, sums formed
/// left to right, no product with a structural zero — so that `PlanarArm::new(&Chain::rpr())`
/// gives [`Rpr::paper`]'s values to the last bit (tested), and with them the same commands.
///
/// ```text
/// r_be = T(m) R(ψ_m) ∏ᵢ [T(oᵢ) R(ψᵢ) Jᵢ(qᵢ)] T(e) R(ψ_e)       (T: translation, R: rotation)
/// r_eb:  θ_eb = −Σ angles,   p_eb = −Σ_k R(−Φ_k) ℓ_k
/// ```
///
/// where `ℓ_k` runs over the translations (fixed offsets and prismatic extensions
/// `qⱼ aⱼ`) and `Φ_k` is the sum of the angles after translation `k`. Singular: for three
/// joints, where `det ∂r_eb/∂q` does not have its sign at home (zero or folded over, as the
/// RPR arm at `q₂ ≤ 0`); for other joint counts, where `∂r_eb/∂q` loses rank exactly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanarArm<T, const N: usize> {
    chain: Chain<T, N>,
    /// `(x, y, yaw)` of the mount, each joint's origin and the tool.
    mount: [T; 3],
    origins: [[T; 3]; N],
    tool: [T; 3],
    /// Revolute: `±1` (the axis is `±z`); prismatic: the axis `(a_x, a_y)`.
    motion: [(bool, T, T); N],
    /// The sign of `det ∂r_eb/∂q` at home (three joints).
    home_sign: T,
}

/// An element of the product: a translation or a rotation, with what it depends on.
#[derive(Clone, Copy, Debug)]
enum Item<T> {
    /// Nothing (a zero offset or angle).
    None,
    /// A fixed translation `(x, y)`.
    Offset(T, T),
    /// Prismatic joint `j` along `(a_x, a_y)`.
    Slide(usize, T, T),
    /// A fixed rotation.
    Turn(T),
    /// Revolute joint `j` with sign `σ`.
    Joint(usize, T),
}

impl<T: Real, const N: usize> PlanarArm<T, N> {
    /// The planar arm of a chain.
    ///
    /// # Errors
    /// The chain's own rule (see [`Chain::validate`]); `joints` with [`Rule::TooFewJoints`]
    /// for fewer than three joints; [`Rule::NotPlanar`] naming the frame or axis that leaves
    /// the plane.
    pub fn new(chain: &Chain<T, N>) -> Result<Self, ParamError> {
        chain.validate()?;
        if N < 3 {
            return Err(ParamError::new("joints", Rule::TooFewJoints));
        }
        let planar = |p: &crate::se3::Pose3<T>| {
            let r = &p.rotation;
            let (z, o) = (T::zero(), T::one());
            (r[(0, 2)] == z && r[(1, 2)] == z && r[(2, 0)] == z && r[(2, 1)] == z && r[(2, 2)] == o)
                .then(|| [p.translation[0], p.translation[1], r[(1, 0)].arctan2(r[(0, 0)])])
        };
        let mount = planar(&chain.mount).ok_or(ParamError::new("mount.rotation", Rule::NotPlanar))?;
        let tool = planar(&chain.tool).ok_or(ParamError::new("tool.rotation", Rule::NotPlanar))?;
        let mut origins = [[T::zero(); 3]; N];
        let mut motion = [(true, T::one(), T::zero()); N];
        for (i, j) in chain.joints.iter().enumerate() {
            origins[i] =
                planar(&j.origin).ok_or(ParamError::joint("joints.origin.rotation", i, Rule::NotPlanar))?;
            let a = &j.axis;
            motion[i] = match j.kind {
                JointKind::Revolute if a[0] == T::zero() && a[1] == T::zero() => (true, a[2], T::zero()),
                JointKind::Prismatic if a[2] == T::zero() => (false, a[0], a[1]),
                _ => return Err(ParamError::joint("joints.axis", i, Rule::NotPlanar)),
            };
        }
        let mut arm = Self { chain: *chain, mount, origins, tool, motion, home_sign: T::one() };
        arm.home_sign = if arm.det(&chain.home()) < T::zero() { -T::one() } else { T::one() };
        Ok(arm)
    }

    /// The chain it was built from.
    pub fn chain(&self) -> &Chain<T, N> {
        &self.chain
    }

    /// How many elements the product has: mount (2), each joint (3), tool (2).
    const LEN: usize = 4 + 3 * N;

    /// Element `e` of the product at `q`.
    #[inline(always)]
    fn item(&self, e: usize) -> Item<T> {
        let z = T::zero();
        let frame = |f: &[T; 3], rotation: bool| {
            if rotation {
                if f[2] == z {
                    Item::None
                } else {
                    Item::Turn(f[2])
                }
            } else if f[0] == z && f[1] == z {
                Item::None
            } else {
                Item::Offset(f[0], f[1])
            }
        };
        if e < 2 {
            return frame(&self.mount, e == 1);
        }
        if e >= 2 + 3 * N {
            return frame(&self.tool, e == 3 + 3 * N);
        }
        let (i, k) = ((e - 2) / 3, (e - 2) % 3);
        let Some(o) = self.origins.get(i) else { return Item::None };
        match (k, self.motion.get(i)) {
            (0, _) => frame(o, false),
            (1, _) => frame(o, true),
            (_, Some(&(true, sign, _))) => Item::Joint(i, sign),
            (_, Some(&(false, ax, ay))) => Item::Slide(i, ax, ay),
            _ => Item::None,
        }
    }

    /// The angle of a rotation element at `q` (`None` for other elements).
    #[inline(always)]
    fn angle(item: Item<T>, q: &SVector<T, N>) -> Option<T> {
        match item {
            Item::Turn(a) => Some(a),
            Item::Joint(j, sign) => Some(if sign < T::zero() { -q[j] } else { q[j] }),
            _ => None,
        }
    }

    /// `Φ`: the sum of the angles after element `e`, left to right (`None` if there are none).
    #[inline(always)]
    fn angles_after(&self, e: usize, q: &SVector<T, N>) -> Option<T> {
        let mut sum: Option<T> = None;
        for f in e + 1..Self::LEN {
            if let Some(a) = Self::angle(self.item(f), q) {
                sum = Some(sum.map_or(a, |s| s + a));
            }
        }
        sum
    }

    /// `det ∂r_eb/∂q` for three joints (1 otherwise).
    fn det(&self, q: &SVector<T, N>) -> T {
        if N != 3 {
            return T::one();
        }
        let j = self.kinematics(q).jacobian;
        j[(0, 0)] * (j[(1, 1)] * j[(2, 2)] - j[(1, 2)] * j[(2, 1)])
            - j[(0, 1)] * (j[(1, 0)] * j[(2, 2)] - j[(1, 2)] * j[(2, 0)])
            + j[(0, 2)] * (j[(1, 0)] * j[(2, 1)] - j[(1, 1)] * j[(2, 0)])
    }
}

/// `a x + b y`, leaving out a term whose factor is a structural zero (`x_zero`, `y_zero`):
/// `a x` alone is not `a x + b·0` when `a x = −0`.
#[inline(always)]
fn lin<T: Real>(a: T, b: T, x: T, y: T, x_zero: bool, y_zero: bool) -> T {
    match (x_zero, y_zero) {
        (false, true) => a * x,
        (true, false) => b * y,
        _ => a * x + b * y,
    }
}

/// `acc = v` the first time, `acc += v` after: a sum that starts with its first term (so
/// that `0 + (−0)` never turns a `−0` into `+0`).
#[inline(always)]
fn add<T: Real>(acc: &mut T, seen: &mut bool, v: T) {
    if *seen {
        *acc += v;
    } else {
        *acc = v;
        *seen = true;
    }
}

impl<T: Real, const N: usize> Arm<T, N> for PlanarArm<T, N> {
    /// `θ_eb` is minus a sum of joint angles: linear.
    const THETA_CURVED: bool = false;

    fn validate(&self) -> Result<(), ParamError> {
        Self::new(&self.chain).map(|_| ())
    }

    fn kinematics(&self, q: &SVector<T, N>) -> ArmKinematics<T, N> {
        let z = T::zero();
        let (mut x, mut y, mut th) = (z, z, z);
        let (mut sx, mut sy, mut sth) = (false, false, false);
        let mut jac = SMatrix::<T, 3, N>::zeros();
        let mut sj = [[false; N]; 2];
        let mut hx = SMatrix::<T, N, N>::zeros();
        let mut hy = SMatrix::<T, N, N>::zeros();
        let mut sh = [[[false; N]; N]; 2];
        // (sin Φ, cos Φ) of the current run of translations (None: no angle after them).
        let mut sc: Option<Option<(T, T)>> = None;
        let mut total: Option<(T, T)> = None;
        for e in 0..Self::LEN {
            let item = self.item(e);
            let (lx, ly, slide) = match item {
                Item::Offset(a, b) => (a, b, None),
                Item::Slide(j, ax, ay) => (q[j] * ax, q[j] * ay, Some((j, ax, ay))),
                Item::Joint(j, sign) => {
                    sc = None;
                    jac[(2, j)] = -sign;
                    add(&mut th, &mut sth, if sign < z { q[j] } else { -q[j] });
                    continue;
                }
                Item::Turn(a) => {
                    sc = None;
                    add(&mut th, &mut sth, -a);
                    continue;
                }
                Item::None => continue,
            };
            let run = *sc.get_or_insert_with(|| self.angles_after(e, q).map(|phi| phi.sincos()));
            if total.is_none() && th == z && !sth {
                // No rotation before this translation: its Φ is the total angle.
                total = Some(run.unwrap_or((z, T::one())));
            }
            let Some((s, c)) = run else {
                // No rotation after: p_eb −= ℓ.
                if lx != z {
                    add(&mut x, &mut sx, -lx);
                }
                if ly != z {
                    add(&mut y, &mut sy, -ly);
                }
                continue;
            };
            // Contributions with structural zeros left out: −R(−Φ) ℓ and its derivatives.
            let xz = (lx == z && slide.is_none()) || slide.is_some_and(|(_, ax, _)| ax == z);
            let yz = (ly == z && slide.is_none()) || slide.is_some_and(|(_, _, ay)| ay == z);
            // ∂/∂Φ of −R(−Φ)ℓ = (d0, d1); its second derivative (d1, −d0).
            let d0 = lin(s, -c, lx, ly, xz, yz);
            let d1 = lin(c, s, lx, ly, xz, yz);
            add(&mut x, &mut sx, -d1);
            add(&mut y, &mut sy, d0);
            if let Some((p, ax, ay)) = slide {
                let (axz, ayz) = (ax == z, ay == z);
                let (u, v) = (lin(s, -c, ax, ay, axz, ayz), lin(c, s, ax, ay, axz, ayz));
                jac[(0, p)] = -v;
                jac[(1, p)] = u;
                sj[0][p] = true;
                sj[1][p] = true;
                // With each revolute joint after it.
                for f in e + 1..Self::LEN {
                    if let Item::Joint(j, sign) = self.item(f) {
                        let (u, v) = if sign < z { (-u, -v) } else { (u, v) };
                        hx[(p, j)] = u;
                        hx[(j, p)] = u;
                        hy[(p, j)] = v;
                        hy[(j, p)] = v;
                    }
                }
            }
            // The revolute joints after this translation, and their pairs.
            let d2x = d1;
            let d2y = -d0;
            for f in e + 1..Self::LEN {
                let Item::Joint(j, sj_sign) = self.item(f) else { continue };
                let neg = sj_sign < z;
                add(&mut jac[(0, j)], &mut sj[0][j], if neg { -d0 } else { d0 });
                add(&mut jac[(1, j)], &mut sj[1][j], if neg { -d1 } else { d1 });
                for g in f..Self::LEN {
                    let Item::Joint(i, si_sign) = self.item(g) else { continue };
                    let neg2 = neg != (si_sign < z);
                    let (a, b) = if neg2 { (-d2x, -d2y) } else { (d2x, d2y) };
                    let (r, col) = (j.min(i), j.max(i));
                    add(&mut hx[(r, col)], &mut sh[0][r][col], a);
                    add(&mut hy[(r, col)], &mut sh[1][r][col], b);
                }
            }
        }
        for r in 0..N {
            for col in r + 1..N {
                if sh[0][r][col] {
                    hx[(col, r)] = hx[(r, col)];
                    hy[(col, r)] = hy[(r, col)];
                }
            }
        }
        let (s_t, c_t) = match total {
            Some(t) => t,
            None => (-th).sincos(),
        };
        ArmKinematics {
            r_eb: Pose::new(x, y, th),
            jacobian: jac,
            hessian: [hx, hy, SMatrix::zeros()],
            sin_cos_theta: (-s_t, c_t),
        }
    }

    fn is_singular(&self, q: &SVector<T, N>) -> bool {
        if N == 3 {
            // Zero, folded over, or NaN.
            let d = self.det(q) * self.home_sign;
            d <= T::zero() || d.nan()
        } else {
            let j = self.kinematics(q).jacobian;
            let gram = if N < 3 { None } else { Some(j * j.transpose()) };
            match gram {
                Some(g) => g.try_inverse().is_none(),
                None => (j.transpose() * j).try_inverse().is_none(),
            }
        }
    }
}
