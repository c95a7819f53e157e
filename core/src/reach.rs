//! The arm's reach as coordinates with limits: what the weight `Ψ̃` of (52) sees of a spatial
//! arm beyond its joints' position limits.
//!
//! **Why.** In runs (b)–(d) the platform moves only as far as `Ψ` lets `h_s1` into `h_s`
//! (29), and `Ψ̃` of (52) rises only when a joint nears a position limit. The paper's RPR arm
//! has a prismatic joint whose limits *are* its reach, so for it "out of reach" is "near a
//! limit". A revolute arm runs out of reach at a singular configuration — the elbow
//! straightens far from any limit — or at its inner edge, where the wrist passes over the
//! first joint's axis or behind it; there `Ψ̃` stays 0, the platform never moves and the
//! target drifts away (the PR2's lifted T1 (b)–(d) ended 1.33–1.37 m from the target). So the
//! reach is made coordinates with limits, each treated as (52) treats a joint:
//!
//! ```text
//! x     = p_w(q) + (p_d − p_*(q))                the wrist point the target asks for
//! r     = ‖x − p_s(q)‖                           the extension: shoulder to that point
//! c     = ‖(I − z_a z_aᵀ)(x − o_a(q))‖           the clearance: that point from the first joint's axis
//! b     = q_a + ∠_{z_a}(p_w − o_a, x − o_a)      the bearing: where the first joint must turn to face it
//! σ̃_r = σ̃(r; r⁻, r⁺, δ_r^±, δ_r^±±),  σ̃_c = σ̃(c; c⁻, +∞, δ_c⁻, δ_c⁻⁻),  σ̃_b = σ̃(b; q_a⁻, q_a⁺, δ_b^±, δ_b^±±)
//! ```
//!
//! with `p_s` the origin of the chain's second revolute joint (the shoulder), `p_w` the origin
//! of its wrist joint (the second-to-last revolute joint, or the one before it:
//! [`ReachJoints::of_chain`]; a robot file may name others) and `(z_a, o_a)` the first revolute
//! joint's axis; `p_* = p_e + R_e p*` is where the arm holds the target and `p_d` where the
//! target is, so `x = p_w` while the arm tracks, and when it lags — the target moved where
//! the arm cannot follow, behind it or into its body — `x` is where its wrist would have to
//! be. The limits are read from the chain ([`SpatialArm::reach_of`](crate::SpatialArm::reach_of)):
//! `r⁻`, `r⁺` the folded and stretched extension, the least and largest `r` over the joints
//! between the two points, and `c⁻` the least clearance, by a bounded deterministic search
//! (`search`, below); the bearing has the first joint's own limits. The margins follow the paper's
//! rule from the home (`δ⁺ = 0.2 (r⁺ − r_home)`, `δ⁺⁺ = ⅔ δ⁺`, likewise below). A side with no
//! room at home has no ramp.
//!
//! **Gradients.** The weight's third variant (`Ψ = Ψ̃(q̂)`, a function of the joints alone)
//! takes the arm's own wrist point (`x = p_w`, so `b = q_a`), with its gradient from the
//! arm's axes `z_j` and points `o_j` ([`SpatialKinematics`]):
//!
//! ```text
//! ∂p/∂q_j  = z_j × (p − o_j) (revolute), z_j (prismatic)   for a point p carried past joint j; else 0
//! ∂r/∂q_j  = u · (∂p_w/∂q_j − ∂p_s/∂q_j),                   u = (p_w − p_s)/r
//! ∂c/∂q_j  = n · (∂e − z_a (∂z_a · e) − ∂z_a (z_a · e)),   e = p_w − o_a, ∂e = ∂p_w/∂q_j − ∂o_a/∂q_j,
//!                                                          ∂z_a = z_j × z_a for a revolute j before a,
//!                                                          n = the unit normal from the axis to p_w
//! ∂b/∂q_j  = δ_ja
//! ```
//!
//! Checked by finite differences in the tests.

use nalgebra::{SVector, Vector3};

use crate::chain::{Chain, JointKind};
use crate::error::{ParamError, Rule};
use crate::kinematics::SpatialKinematics;
use crate::scalar::Real;
use crate::secondary::{sigma_tilde_band, TermRule};

/// The joints whose origins and axis define the reach (indices from 0 in the chain).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ReachJoints {
    /// The shoulder: its origin is `p_s`.
    pub shoulder: usize,
    /// The wrist: its origin is `p_w` (`shoulder < wrist`).
    pub wrist: usize,
    /// The joint whose axis the clearance is measured from (`axis < wrist`).
    pub axis: usize,
}

impl ReachJoints {
    /// The default: the axis the chain's first revolute joint, the shoulder its second, and
    /// the wrist its second-to-last — the wrist centre of a spherical wrist — if that joint's
    /// origin lies on the axis of the revolute joint before it (within 1 mm, at home), so
    /// that the wrist's own joints do not move the point; else that joint before it, the
    /// wrist's first (the UR5's `wrist_1`, whose next origin is 9 cm off its axis). `None`
    /// with fewer than four revolute joints.
    pub fn of_chain<T: Real, const N: usize>(chain: &Chain<T, N>) -> Option<Self> {
        let mut revolute = [0usize; N];
        let mut k = 0;
        for (i, j) in chain.joints.iter().enumerate() {
            if j.kind == JointKind::Revolute {
                revolute[k] = i;
                k += 1;
            }
        }
        if k < 4 {
            return None;
        }
        let (shoulder, wrist, before) = (revolute[1], revolute[k - 2], revolute[k - 3]);
        let f = chain.frames(&chain.home());
        let z = f.axes.column(before);
        let off = f.points.column(wrist) - f.points.column(before);
        let on_axis = (off - z * z.dot(&off)).norm_squared() <= T::of(1e-6);
        let wrist = if on_axis || before <= shoulder + 1 { wrist } else { before };
        Some(Self { shoulder, wrist, axis: revolute[0] })
    }

    /// Checks `axis < wrist`, `shoulder < wrist < N`.
    ///
    /// # Errors
    /// `reach_joints` with [`Rule::Geometry`].
    pub fn validate(&self, n: usize) -> Result<(), ParamError> {
        if self.wrist >= n || self.shoulder >= self.wrist || self.axis >= self.wrist {
            return Err(ParamError::new("reach_joints", Rule::Geometry));
        }
        Ok(())
    }
}

/// One coordinate's limits and the margins of its ramp, as a joint's in (52) (m): `σ̃ = 1`
/// within `lower_inner` of `lower` (`upper_inner` of `upper`), 0 farther than `lower_margin`
/// (`upper_margin`), linear between. An infinite limit has no ramp (its margins unused).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReachBand<T> {
    /// The least value (m), or `−∞`.
    pub lower: T,
    /// The largest value (m), or `+∞`.
    pub upper: T,
    /// `δ⁻` (m).
    pub lower_margin: T,
    /// `δ⁻⁻ < δ⁻` (m).
    pub lower_inner: T,
    /// `δ⁺` (m).
    pub upper_margin: T,
    /// `δ⁺⁺ < δ⁺` (m).
    pub upper_inner: T,
}

/// The paper's fraction of the room from home to a limit at which (52)'s ramp starts.
pub const MARGIN_FRACTION: f64 = 0.2;

impl<T: Real> ReachBand<T> {
    /// The band of a coordinate with limits `[lower, upper]` and value `home` at the arm's
    /// home, by the paper's rule: `δ⁻ = f (home − lower)`, `δ⁺ = f (upper − home)` with `f`
    /// `fraction` (the paper's 0.2), `δ⁻⁻ = ⅔ δ⁻`, `δ⁺⁺ = ⅔ δ⁺`. A side with less than 1 mm
    /// of room (or an infinite limit) gets no ramp: its limit becomes infinite.
    pub fn from_home(lower: T, upper: T, home: T, fraction: T) -> Self {
        let two_thirds = T::of(2.0) / T::of(3.0);
        let room = T::of(1e-3);
        let side = |limit: T, r: T, sign: T| {
            if limit.finite() && r > room {
                (limit, r * fraction, r * fraction * two_thirds)
            } else {
                (sign * T::of(f64::INFINITY), T::one(), T::of(0.5))
            }
        };
        let (lo, dm, dmm) = side(lower, home - lower, -T::one());
        let (hi, dp, dpp) = side(upper, upper - home, T::one());
        Self { lower: lo, upper: hi, lower_margin: dm, lower_inner: dmm, upper_margin: dp, upper_inner: dpp }
    }

    /// `σ̃` and `dσ̃/dx` at `x`.
    #[inline]
    pub fn sigma(&self, x: T) -> (T, T) {
        sigma_tilde_band(
            x,
            self.lower,
            self.upper,
            self.lower_margin,
            self.lower_inner,
            self.upper_margin,
            self.upper_inner,
        )
    }

    /// Checks the rules of (52)'s margins: finite and positive, `δ⁻⁻ < δ⁻`, `δ⁺⁺ < δ⁺`, and
    /// the two ramps apart (`lower + δ⁻ < upper − δ⁺`).
    ///
    /// # Errors
    /// `name` with the rule broken.
    pub fn validate(&self, name: &'static str) -> Result<(), ParamError> {
        for m in [self.lower_margin, self.lower_inner, self.upper_margin, self.upper_inner] {
            if !m.finite() {
                return Err(ParamError::new(name, Rule::NonFinite));
            }
            if m <= T::zero() {
                return Err(ParamError::new(name, Rule::NotPositive));
            }
        }
        if self.lower.nan() || self.upper.nan() {
            return Err(ParamError::new(name, Rule::NonFinite));
        }
        if self.lower_inner >= self.lower_margin || self.upper_inner >= self.upper_margin {
            return Err(ParamError::new(name, Rule::WeightMarginOrder));
        }
        if self.lower + self.lower_margin >= self.upper - self.upper_margin {
            return Err(ParamError::new(name, Rule::WeightMarginOrder));
        }
        Ok(())
    }
}

/// The reach terms of the weight: the two coordinates and their bands (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reach<T> {
    /// The joints that define the points and the axis.
    pub joints: ReachJoints,
    /// The band of the extension `r` (m).
    pub extension: ReachBand<T>,
    /// The band of the clearance `c` (m; its upper limit `+∞`).
    pub clearance: ReachBand<T>,
    /// The band of the bearing: the axis joint's position where it must turn to face the
    /// wrist point (rad; the joint's limits and (52)'s margins from its home).
    pub bearing: ReachBand<T>,
    /// How the three terms enter `Ψ̃` with the joints' `σ̃ᵢ`.
    pub rule: TermRule,
}

/// The reach coordinates at one configuration, with their gradients in `q`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReachCoordinates<T, const N: usize> {
    /// The extension `r` (m).
    pub extension: T,
    /// `∂r/∂q`.
    pub extension_gradient: SVector<T, N>,
    /// The clearance `c` (m).
    pub clearance: T,
    /// `∂c/∂q`.
    pub clearance_gradient: SVector<T, N>,
}

/// `∂p/∂q_j` of a point `p` carried by the links after joint `j`.
#[inline(always)]
fn point_rate<T: Real, const N: usize>(
    kin: &SpatialKinematics<T, N>,
    j: usize,
    p: &Vector3<T>,
) -> Vector3<T> {
    let z = kin.axes.column(j).into_owned();
    if kin.revolute[j] {
        z.cross(&(p - kin.points.column(j)))
    } else {
        z
    }
}

/// The task's position error in the platform's frame, `a = p_d − p_*`: where the target is
/// less where the arm holds it (module docs), with the point `p_*` it is measured from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lag<T> {
    /// `p_*`: where the target should be, at the arm's configuration (m).
    pub held: Vector3<T>,
    /// `p_d`: where the target is (m).
    pub target: Vector3<T>,
}

impl ReachJoints {
    /// The wrist point the extension and the clearance measure: the arm's `p_w`, moved by
    /// the task's position error `p_d − p_*` if `lag` is given.
    #[inline(always)]
    fn wrist_point<T: Real, const N: usize>(
        &self,
        kin: &SpatialKinematics<T, N>,
        lag: Option<&Lag<T>>,
    ) -> Vector3<T> {
        let p_w = kin.points.column(self.wrist).into_owned();
        match lag {
            Some(l) => p_w + (l.target - l.held),
            None => p_w,
        }
    }

    /// The extension and the clearance at the frames `kin` (module docs), without gradients,
    /// and the angle (rad) the axis joint must turn through to face the wrist point (0
    /// without `lag`, or where the point is on the axis).
    #[inline]
    pub fn coordinates_value<T: Real, const N: usize>(
        &self,
        kin: &SpatialKinematics<T, N>,
        lag: Option<&Lag<T>>,
    ) -> (T, T, T) {
        let x = self.wrist_point(kin, lag);
        let d = x - kin.points.column(self.shoulder);
        let (z_a, o_a) = (kin.axes.column(self.axis).into_owned(), kin.points.column(self.axis).into_owned());
        let a = x - o_a;
        let c = a - z_a * z_a.dot(&a);
        let turn = match lag {
            Some(_) => {
                let w = kin.points.column(self.wrist) - o_a;
                let u = w - z_a * z_a.dot(&w);
                let (sin, cos) = (z_a.dot(&u.cross(&c)), u.dot(&c));
                if sin == T::zero() && cos == T::zero() {
                    T::zero()
                } else {
                    sin.arctan2(cos)
                }
            }
            None => T::zero(),
        };
        (d.norm_squared().square_root(), c.norm_squared().square_root(), turn)
    }

    /// The extension and the clearance at the frames `kin` (of the arm's own wrist point)
    /// with their gradients in `q`.
    pub fn coordinates<T: Real, const N: usize>(
        &self,
        kin: &SpatialKinematics<T, N>,
    ) -> ReachCoordinates<T, N> {
        let x = self.wrist_point(kin, None);
        let p_s = kin.points.column(self.shoulder).into_owned();
        let d = x - p_s;
        let r = d.norm_squared().square_root();
        let (z_a, o_a) = (kin.axes.column(self.axis).into_owned(), kin.points.column(self.axis).into_owned());
        let e = x - o_a;
        let h = z_a.dot(&e);
        let cv = e - z_a * h;
        let c = cv.norm_squared().square_root();
        let zero = T::zero();
        let u = if r > zero { d / r } else { Vector3::zeros() };
        let n = if c > zero { cv / c } else { Vector3::zeros() };
        let p_w = kin.points.column(self.wrist).into_owned();
        let mut dr = SVector::<T, N>::zeros();
        let mut dc = SVector::<T, N>::zeros();
        for j in 0..N {
            let dx = if j < self.wrist { point_rate(kin, j, &p_w) } else { Vector3::zeros() };
            let dp_s = if j < self.shoulder { point_rate(kin, j, &p_s) } else { Vector3::zeros() };
            dr[j] = u.dot(&(dx - dp_s));
            // c² = |e|² − (z·e)²: ∂c = n·(∂e − z (∂z·e)) with ∂e = ∂x − ∂o_a.
            let (do_a, dz_a) = if j < self.axis {
                let z = kin.axes.column(j).into_owned();
                if kin.revolute[j] {
                    (point_rate(kin, j, &o_a), z.cross(&z_a))
                } else {
                    (z, Vector3::zeros())
                }
            } else {
                (Vector3::zeros(), Vector3::zeros())
            };
            let de = dx - do_a;
            dc[j] = n.dot(&(de - z_a * dz_a.dot(&e) - dz_a * h));
        }
        ReachCoordinates { extension: r, extension_gradient: dr, clearance: c, clearance_gradient: dc }
    }
}

impl<T: Real> Reach<T> {
    /// Checks the joints against an arm of `n` joints and both bands.
    ///
    /// # Errors
    /// `reach_joints`, `reach.extension` or `reach.clearance` with the rule broken.
    pub fn validate(&self, n: usize) -> Result<(), ParamError> {
        self.joints.validate(n)?;
        self.extension.validate("reach.extension")?;
        self.clearance.validate("reach.clearance")?;
        self.bearing.validate("reach.bearing")
    }

    /// `(σ̃_r, σ̃_c, σ̃_b)` at the joints `q` with frames `kin`, of the wrist point moved by
    /// the task's position error if `lag` is given.
    #[inline]
    pub fn sigma<const N: usize>(
        &self,
        kin: &SpatialKinematics<T, N>,
        q: &SVector<T, N>,
        lag: Option<&Lag<T>>,
    ) -> [T; 3] {
        let (r, c, turn) = self.joints.coordinates_value(kin, lag);
        let b = q[self.joints.axis] + turn;
        [self.extension.sigma(r).0, self.clearance.sigma(c).0, self.bearing.sigma(b).0]
    }

    /// `(σ̃_r, σ̃_c, σ̃_b)` of the arm's own wrist point, with their gradients in `q`.
    pub fn sigma_gradient<const N: usize>(
        &self,
        kin: &SpatialKinematics<T, N>,
        q: &SVector<T, N>,
    ) -> ([T; 3], [SVector<T, N>; 3]) {
        let x = self.joints.coordinates(kin);
        let (sr, dsr) = self.extension.sigma(x.extension);
        let (sc, dsc) = self.clearance.sigma(x.clearance);
        let a = self.joints.axis;
        let (sb, dsb) = self.bearing.sigma(q[a]);
        let mut db = SVector::<T, N>::zeros();
        db[a] = dsb;
        ([sr, sc, sb], [x.extension_gradient * dsr, x.clearance_gradient * dsc, db])
    }
}

/// What the construction's search needs of an arm: its frames at `q`.
pub(crate) trait Frames<T, const N: usize> {
    fn frames_at(&self, q: &SVector<T, N>) -> SpatialKinematics<T, N>;
}

/// Samples per joint of a coordinate sweep of the search.
const SAMPLES: usize = 24;
/// Golden-section steps refining a sweep's best sample.
const REFINE: usize = 40;
/// Coordinate sweeps from each start, at most.
const SWEEPS: usize = 12;

/// The least (`sign = 1`) or largest (`sign = −1`) of `f` over the joints `lo..hi` (others at
/// `home`), within their limits (a joint without limits over `[−π, π]`): coordinate sweeps —
/// each joint sampled at [`SAMPLES`] points and the best refined by golden sections — from the
/// home and from the corners and middles of the joints' ranges (`3ᵏ` starts for `k ≤ 3` joints,
/// `1 + 2k` otherwise), until a sweep gains less than `10⁻¹²`. Deterministic and bounded.
pub(crate) fn search<T: Real, const N: usize>(
    chain: &Chain<T, N>,
    f: &impl Fn(&SVector<T, N>) -> T,
    lo: usize,
    hi: usize,
    sign: T,
) -> T {
    let home = chain.home();
    let range = |j: usize| {
        let joint = &chain.joints[j];
        if joint.lower.finite() && joint.upper.finite() {
            (joint.lower, joint.upper)
        } else {
            (-T::pi(), T::pi())
        }
    };
    let g = |q: &SVector<T, N>| sign * f(q);
    let k = hi.saturating_sub(lo);
    let starts = if k <= 3 { 3usize.pow(k as u32) } else { 1 + 2 * k };
    let mut best = g(&home);
    for s in 0..=starts {
        let mut q = home;
        if s > 0 {
            // Start s − 1: each joint at a quarter, the middle or three quarters of its range.
            let mut code = s - 1;
            for j in lo..hi {
                let (a, b) = range(j);
                let level = if k <= 3 {
                    let l = code % 3;
                    code /= 3;
                    l
                } else if code / 2 == j - lo {
                    2 * (code % 2)
                } else {
                    1
                };
                q[j] = a + (b - a) * T::of(0.25 * (level as f64 + 1.0));
            }
        }
        let mut value = g(&q);
        for _ in 0..SWEEPS {
            let before = value;
            for j in lo..hi {
                value = sweep(&g, &mut q, j, range(j), value);
            }
            if before - value <= T::of(1e-12) {
                break;
            }
        }
        if value < best {
            best = value;
        }
    }
    sign * best
}

/// One joint's sweep: `q[j]` moved to where `g` is least over `[a, b]`, if lower than `value`.
fn sweep<T: Real, const N: usize>(
    g: &impl Fn(&SVector<T, N>) -> T,
    q: &mut SVector<T, N>,
    j: usize,
    (a, b): (T, T),
    value: T,
) -> T {
    let at = |x: T, q: &SVector<T, N>| {
        let mut p = *q;
        p[j] = x;
        g(&p)
    };
    let step = (b - a) / T::of((SAMPLES - 1) as f64);
    let (mut best_i, mut best) = (0usize, at(a, q));
    for i in 1..SAMPLES {
        let v = at(a + step * T::of(i as f64), q);
        if v < best {
            (best_i, best) = (i, v);
        }
    }
    // Golden sections within the neighbouring samples.
    let centre = a + step * T::of(best_i as f64);
    let (mut x0, mut x1) = ((centre - step).max(a), (centre + step).min(b));
    let ratio = T::of(0.618_033_988_749_894_8);
    let (mut c, mut d) = (x1 - (x1 - x0) * ratio, x0 + (x1 - x0) * ratio);
    let (mut fc, mut fd) = (at(c, q), at(d, q));
    for _ in 0..REFINE {
        if fc < fd {
            (x1, d, fd) = (d, c, fc);
            c = x1 - (x1 - x0) * ratio;
            fc = at(c, q);
        } else {
            (x0, c, fc) = (c, d, fd);
            d = x0 + (x1 - x0) * ratio;
            fd = at(d, q);
        }
    }
    let (x, v) = if fc < fd { (c, fc) } else { (d, fd) };
    let (x, v) = if v < best { (x, v) } else { (centre, best) };
    if v < value {
        q[j] = x;
        v
    } else {
        value
    }
}

impl<T: Real> Reach<T> {
    /// The reach of an arm (module docs): the bands' limits searched over the chain, their
    /// margins `fraction` (the paper's [`MARGIN_FRACTION`]) of the room from the home to each
    /// limit. `None` if the joints do not suit the chain (see [`ReachJoints::validate`]).
    pub(crate) fn search<A: Frames<T, N>, const N: usize>(
        arm: &A,
        chain: &Chain<T, N>,
        joints: ReachJoints,
        fraction: T,
    ) -> Option<Self> {
        joints.validate(N).ok()?;
        let ext = |q: &SVector<T, N>| joints.coordinates_value(&arm.frames_at(q), None).0;
        let clear = |q: &SVector<T, N>| joints.coordinates_value(&arm.frames_at(q), None).1;
        let (lo, hi) = (joints.shoulder + 1, joints.wrist);
        let (r_min, r_max) = (search(chain, &ext, lo, hi, T::one()), search(chain, &ext, lo, hi, -T::one()));
        let c_min = search(chain, &clear, joints.axis + 1, joints.wrist, T::one());
        let (r_home, c_home, _) = joints.coordinates_value(&arm.frames_at(&chain.home()), None);
        let extension = ReachBand::from_home(r_min.min(r_home), r_max.max(r_home), r_home, fraction);
        let clearance = ReachBand::from_home(c_min.min(c_home), T::of(f64::INFINITY), c_home, fraction);
        let j = &chain.joints[joints.axis];
        let bearing = ReachBand::from_home(j.lower, j.upper, j.home, fraction);
        Some(Self { joints, extension, clearance, bearing, rule: TermRule::Max })
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::SVector;

    use super::*;
    use crate::chain::Joint;
    use crate::se3::Pose3;
    use crate::SpatialArm;

    /// Deterministic joints inside the limits (a linear congruential sequence).
    fn configurations<const N: usize>(
        chain: &Chain<f64, N>,
        count: usize,
    ) -> impl Iterator<Item = SVector<f64, N>> + '_ {
        let mut x: u64 = 0x2545_f491_4f6c_dd1d;
        (0..count).map(move |_| {
            SVector::from_fn(|i, _| {
                x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
                let u = (x >> 11) as f64 / (1u64 << 53) as f64;
                let j = &chain.joints[i];
                let (lo, hi) = if j.lower.is_finite() { (j.lower, j.upper) } else { (-3.0, 3.0) };
                lo + (hi - lo) * (0.02 + 0.96 * u)
            })
        })
    }

    /// The Panda behind a prismatic torso lifting along `z` and turning the arm a little: a
    /// joint before the axis joint and before the shoulder, both kinds.
    fn torso_panda() -> Chain<f64, 8> {
        let p = Chain::<f64, 7>::panda();
        let torso = Joint {
            kind: JointKind::Prismatic,
            origin: Pose3::from_xyz_rpy([0.1, 0.0, 0.3], [0.0, 0.2, 0.3]),
            axis: Vector3::new(0.0, 0.6, 0.8),
            lower: 0.0,
            upper: 0.4,
            home: 0.2,
            max_velocity: 0.1,
        };
        let joints = core::array::from_fn(|i| if i == 0 { torso } else { p.joints[i - 1] });
        Chain::new(p.mount, joints, p.tool).expect("valid")
    }

    /// `∂r/∂q` and `∂c/∂q` against central differences of the values, at 200 configurations
    /// of the UR5, the Panda and the Panda on a tilted prismatic torso.
    fn gradients_match<const N: usize>(chain: &Chain<f64, N>) {
        let arm = SpatialArm::new(chain).expect("valid");
        let joints = ReachJoints::of_chain(chain).expect("revolute joints");
        let h = 1e-6;
        for q in configurations(chain, 200) {
            let x = joints.coordinates(&arm.kinematics(&q));
            let (r, c, turn) = joints.coordinates_value(&arm.kinematics(&q), None);
            assert_eq!((x.extension, x.clearance, turn), (r, c, 0.0));
            for j in 0..N {
                let (mut qp, mut qm) = (q, q);
                qp[j] += h;
                qm[j] -= h;
                let (rp, cp, _) = joints.coordinates_value(&arm.kinematics(&qp), None);
                let (rm, cm, _) = joints.coordinates_value(&arm.kinematics(&qm), None);
                let (dr, dc) = ((rp - rm) / (2.0 * h), (cp - cm) / (2.0 * h));
                assert!(
                    (dr - x.extension_gradient[j]).abs() < 1e-7,
                    "∂r/∂q{j}: {dr} vs {}",
                    x.extension_gradient[j]
                );
                if c > 1e-3 {
                    assert!(
                        (dc - x.clearance_gradient[j]).abs() < 1e-7,
                        "∂c/∂q{j}: {dc} vs {}",
                        x.clearance_gradient[j]
                    );
                }
            }
        }
    }

    #[test]
    fn the_reach_gradients_are_the_values_derivatives() {
        gradients_match(&Chain::<f64, 6>::ur5());
        gradients_match(&Chain::<f64, 7>::panda());
        gradients_match(&torso_panda());
    }

    /// The σ̃ gradients of [`Reach::sigma_gradient`] against central differences of
    /// [`Reach::sigma`] without a target (inside the ramps, away from their corners).
    #[test]
    fn the_weight_terms_gradients_are_their_values_derivatives() {
        let chain = torso_panda();
        let arm = SpatialArm::new(&chain).expect("valid");
        let reach = *arm.reach().expect("a reach");
        let h = 1e-7;
        let mut inside = 0;
        for q in configurations(&chain, 2000) {
            let (s, g) = reach.sigma_gradient(&arm.kinematics(&q), &q);
            assert_eq!(s, reach.sigma(&arm.kinematics(&q), &q, None));
            for (k, sk) in s.iter().enumerate() {
                if *sk <= 0.01 || *sk >= 0.99 {
                    continue;
                }
                inside += 1;
                for j in 0..8 {
                    let (mut qp, mut qm) = (q, q);
                    qp[j] += h;
                    qm[j] -= h;
                    let d = (reach.sigma(&arm.kinematics(&qp), &qp, None)[k]
                        - reach.sigma(&arm.kinematics(&qm), &qm, None)[k])
                        / (2.0 * h);
                    assert!(
                        (d - g[k][j]).abs() < 1e-5 * (1.0 + d.abs()),
                        "term {k}, q{j}: {d} vs {}",
                        g[k][j]
                    );
                }
            }
        }
        assert!(inside > 20, "configurations inside a ramp: {inside}");
    }

    /// The default points: the UR5's shoulder_lift to wrist_1 (wrist_2's origin is 9 cm off
    /// wrist_1's axis), the Panda's joint 2 to joint 6 (its wrist centre); the axis the first
    /// joint's. A chain with fewer than four revolute joints has none.
    #[test]
    fn the_default_points_are_the_shoulder_and_the_wrist_centre() {
        let ur5 = ReachJoints::of_chain(&Chain::<f64, 6>::ur5()).expect("a reach");
        assert_eq!(ur5, ReachJoints { shoulder: 1, wrist: 3, axis: 0 });
        let panda = ReachJoints::of_chain(&Chain::<f64, 7>::panda()).expect("a reach");
        assert_eq!(panda, ReachJoints { shoulder: 1, wrist: 5, axis: 0 });
        let torso = ReachJoints::of_chain(&torso_panda()).expect("a reach");
        assert_eq!(torso, ReachJoints { shoulder: 2, wrist: 6, axis: 1 });
        assert_eq!(ReachJoints::of_chain(&Chain::<f64, 3>::rpr()), None);
        assert!(ReachJoints { shoulder: 3, wrist: 3, axis: 0 }.validate(6).is_err());
        assert!(ReachJoints { shoulder: 1, wrist: 6, axis: 0 }.validate(6).is_err());
        assert!(ReachJoints { shoulder: 1, wrist: 3, axis: 3 }.validate(6).is_err());
    }

    /// The search's folded and stretched extension against a dense grid over the joints
    /// between the points (the Panda's joints 3–5, 61³ points; the UR5's elbow, 100 001): the
    /// search finds at least the grid's extremes, and no more than a local refinement can.
    #[test]
    fn the_search_finds_the_folded_and_stretched_reach() {
        let panda = Chain::<f64, 7>::panda();
        let arm = SpatialArm::new(&panda).expect("valid");
        let r = *arm.reach().expect("a reach");
        let j = r.joints;
        let (mut lo, mut hi) = (f64::INFINITY, 0.0_f64);
        let steps = 60;
        let mut q = panda.home();
        for a in 0..=steps {
            for b in 0..=steps {
                for c in 0..=steps {
                    for (k, i) in [(a, 2), (b, 3), (c, 4)] {
                        let jt = &panda.joints[i];
                        q[i] = jt.lower + (jt.upper - jt.lower) * k as f64 / steps as f64;
                    }
                    let (x, _, _) = j.coordinates_value(&arm.kinematics(&q), None);
                    (lo, hi) = (lo.min(x), hi.max(x));
                }
            }
        }
        assert!(
            r.extension.lower <= lo + 1e-12 && r.extension.lower > lo - 1e-3,
            "{} vs {lo}",
            r.extension.lower
        );
        assert!(
            r.extension.upper >= hi - 1e-12 && r.extension.upper < hi + 1e-3,
            "{} vs {hi}",
            r.extension.upper
        );

        let ur5 = Chain::<f64, 6>::ur5();
        let arm = SpatialArm::new(&ur5).expect("valid");
        let r = *arm.reach().expect("a reach");
        let e = &ur5.joints[2];
        let (mut lo, mut hi) = (f64::INFINITY, 0.0_f64);
        let mut q = ur5.home();
        for k in 0..=100_000 {
            q[2] = e.lower + (e.upper - e.lower) * f64::from(k) / 1e5;
            let (x, _, _) = r.joints.coordinates_value(&arm.kinematics(&q), None);
            (lo, hi) = (lo.min(x), hi.max(x));
        }
        assert!(
            (r.extension.lower - lo).abs() < 1e-9 && (r.extension.upper - hi).abs() < 1e-9,
            "{:?} vs {lo} {hi}",
            r.extension
        );
    }

    /// The margins by the paper's rule from the home, and the ramp of (52) on them.
    #[test]
    fn a_band_has_the_papers_margins_and_ramp() {
        let b = ReachBand::<f64>::from_home(0.2, 0.7, 0.45, 0.2);
        assert!((b.upper_margin - 0.05).abs() < 1e-15 && (b.upper_inner - 0.05 * 2.0 / 3.0).abs() < 1e-15);
        assert!((b.lower_margin - 0.05).abs() < 1e-15);
        assert_eq!(b.sigma(0.45), (0.0, 0.0));
        assert_eq!(b.sigma(0.69).0, 1.0);
        assert_eq!(b.sigma(0.21).0, 1.0);
        let (s, d) = b.sigma(0.7 - 0.05 * 5.0 / 6.0);
        assert!((s - 0.5).abs() < 1e-12 && d > 0.0, "{s} {d}");
        b.validate("b").expect("valid");
        // A side without room has no ramp; an infinite limit neither.
        let one = ReachBand::<f64>::from_home(0.2, 0.45, 0.45, 0.2);
        assert_eq!(one.upper, f64::INFINITY);
        assert_eq!(one.sigma(1e3).0, 0.0);
        let bad = ReachBand { lower_inner: 0.06, ..b };
        assert_eq!(bad.validate("x").unwrap_err().rule, Rule::WeightMarginOrder);
        let bad = ReachBand { upper_margin: f64::NAN, ..b };
        assert_eq!(bad.validate("x").unwrap_err().rule, Rule::NonFinite);
    }

    /// Where the arm holds the target, the wrist point the target asks for is the arm's own
    /// (bit for bit); a target moved away stretches it, one moved behind the first joint
    /// turns its bearing past the joint's limit.
    #[test]
    fn the_wrist_point_follows_the_target() {
        let chain = Chain::<f64, 7>::panda();
        let arm = SpatialArm::new(&chain).expect("valid");
        let reach = *arm.reach().expect("a reach");
        let q = chain.home();
        let kin = arm.kinematics(&q);
        let star = arm.level_target(0.2);
        let held = kin.effector.compose(&star).translation;
        let at = |target: Vector3<f64>| reach.sigma(&kin, &q, Some(&Lag { held, target }));
        assert_eq!(at(held), reach.sigma(&kin, &q, None));
        assert_eq!(at(held), [0.0; 3]);
        let out = held + (held - kin.points.column(1)).normalize() * 0.5;
        assert_eq!(at(out)[0], 1.0, "a target 0.5 m farther is out of reach");
        // Behind the first joint's axis: the first joint (±2.90 rad) would turn by π.
        let o = kin.points.column(0).into_owned();
        let mut behind = o - (held - o);
        behind[2] = held[2];
        let s = at(behind);
        assert_eq!(s[2], 1.0, "{s:?}");
    }
}
