//! The spatial law of §5: an arm of six or more joints tracks a target in SE(3).
//!
//! **The task.** `e_p = (r*_ed)⁻¹ r_ed` with `r_ed = r_eb(q) r_bd ∈ SE(3)`, in the
//! coordinates
//!
//! ```text
//! r̃ = (r*_ed)⁻¹ r_ed = (R̃, p̃),     e_p = (p̃, φ̃),   φ̃ = log R̃ ∈ {|φ| ≤ π}
//! ```
//!
//! — the translation of `r̃` (m) and the rotation vector of its rotation (rad). Why these:
//! (1) for a target and an arm in the plane (`R = R_z`) they are exactly the planar `e_p`
//! of (42), `(x̃, ỹ, θ̃)` with `θ̃` wrapped (and zeros), so the spatial law is the planar
//! law in that case (tested); (2) `e_p = 0` exactly when `r_ed = r*_ed` (`log R = 0` only
//! for `R = I`) and `e_p` is analytic for `|φ̃| < π` — at `π` the rotation vector jumps, as
//! the planar `θ̃` does when wrapped; (3) position and angle keep their units, and `|φ̃|` is
//! the angle between the two orientations. Not the full SE(3) logarithm: that would mix
//! the translation with the rotation (`V(φ)⁻¹ p̃`) and differ from (42) in the plane.
//!
//! **Derivatives** (body perturbations, as in (10)). With the arm's frames in the
//! platform's frame — joint axes `zᵢ` through points `oᵢ`, end effector `(R_e, p_e)` — the
//! target `r_bd = (R_d, p_d)`, and
//!
//! ```text
//! M = R_e R*,   p_* = p_e + R_e p*   (where the target should be),   a = p_d − p_*
//! tᵢ = zᵢ × (p_d − oᵢ), wᵢ = zᵢ × (p_* − oᵢ), ζᵢ = zᵢ  (revolute);  tᵢ = wᵢ = zᵢ, ζᵢ = 0  (prismatic)
//! K = R_d J_r(φ̃)⁻¹ R_dᵀ
//!
//! ∂e_p/∂q   = [−Mᵀ T; −J_r(φ̃)⁻¹ R_dᵀ Z]                       (6×N, T = [tᵢ], Z = [ζᵢ])
//! ∂e_p/∂u_bd = [Mᵀ R_d  0; 0  J_r(φ̃)⁻¹]                      (u_bd: the target's twist seen from the base)
//! e_m       = (∂e_p/∂q)ᵀ e_p + ∂h_ℓ/∂q + Γ (q − q̂)                                   (23)
//! ∂e_m/∂q   = sym(Tᵀ W + Zᵀ K Z) + diag(∂²h_ℓ/∂q² + Γ)        (W = [wᵢ])             (24)
//! ∂e_m/∂u_bd = −[Wᵀ R_d   Zᵀ Kᵀ R_d]
//! u_bd      = u_d − Ad_{r_db} u_b,   Ad_{r_db} u_b = (R_dᵀ (v_b + ω_b × p_d), R_dᵀ ω_b)   (9)
//! ```
//!
//! `sym(X)` is `X`'s upper triangle (`j ≥ i`) mirrored: there `∂zᵢ/∂qⱼ = ∂oᵢ/∂qⱼ = 0`, and
//! `Tᵀ W + Zᵀ K Z` is the whole of (24) including `Σ_k e_p,k ∂²e_p,k/∂q²` — the second
//! derivatives enter through `W` (the desired point `p_*` instead of `p_d`, which differ by
//! `a`, part of `e_p`) and `K` (`J_r⁻¹` in one factor instead of `J_r⁻ᵀ J_r⁻¹`); at `e_p = 0`
//! it is `JᵀJ`. It needs no derivative of `J_r⁻¹` because `J_r(φ)⁻ᵀ φ = φ`, so
//! `(∂φ̃/∂q)ᵀ φ̃ = −Zᵀ R_d φ̃` exactly. Every one of these is checked by finite differences.
//!
//! **The law** is (30), discretised over the hold as for the planar arm (`arm_law`): with
//! six joints `e_m` is driven (`ė_m = G e_m`) and `∂e_m/∂q` inverted; with seven or more,
//! `e_p` itself (`ė_p = G e_p`, the first six gains), solved by the weighted pseudo-inverse
//! with the joint-limit penalty descended in its null space (`arm_law` says how and why),
//! so the task is met exactly while the redundancy keeps the joints away from their limits.
//! Measured on the Panda (lifted trajectory 1, unicycle, run (a)): the weights
//! `wᵢ = 1 + ∂²h_ℓ/∂qᵢ²` gave larger smallest margins than `W = I` with the same descent
//! (0.285 against 0.282 rad, 0.354 against 0.333 with a wider transverse function), and
//! the penalty needs its band wide (`δᵢ = 0.2 (qᵢ⁺ − qᵢ⁻)`, [`Params::for_arm`]) to act at
//! all: with the paper's 5 % no joint enters it and the null-space term changes nothing.
//!
//! **Near singular configurations** the solution is damped, and at them the step refused.
//! The matrix the law inverts — `∂e_m/∂q` (six joints) or `S = A W⁻¹ Aᵀ` (more) — gets
//! `λ² I` added, `λ² = κ (tr/M) (1 − ρ/ρ₀)²` below the onset `ρ₀` (default `10⁻³`, depth
//! `κ = 0.1`, [`SpatialArm::with_damping`]): the singularity-robust inverse of Nakamura and
//! Hanafusa (1986) and Wampler (1986). Above the onset the law is exact; below it, motion
//! along directions the arm can hardly produce is given up rather than demanded at
//! unbounded speed — which is what happens while a target is out of reach (far, or beyond
//! a joint limit: a joint deep in its band weighs `wᵢ ≫ 1`, which takes its column out of
//! `S`). `ρ` is the measure below for six joints, and for more `S`'s own (it
//! sees the joints the weights take out; its Hadamard ratio `det S/∏ Sᵢᵢ`). Without it, a far target drives a seven-joint
//! arm into its limits or a singular configuration within a second (measured: stuck there,
//! every step refused, from the paper's start on the omnidirectional platform).
//!
//! The step is refused ([`StepError::SingularArm`]) when
//!
//! ```text
//! ρ = det(J Jᵀ) / ((|W|²/3)³ (|Z|²/3)³) < ρ_min,     J = [W; Z]
//! ```
//!
//! ([`SpatialArm::singular_below`], default `10⁻¹⁰`): `J` is the arm's own Jacobian at the
//! point where the target should be (`W`'s columns move that point, `Z`'s turn the frame),
//! and the normalisation by the mean squared norms of its position and rotation rows makes
//! `ρ ∈ [0, 1]` (Fischer's and the arithmetic–geometric mean inequalities), 0 only at a
//! singular configuration, and independent of the frame the rows are written in and of the
//! unit of length. Not `∂e_p/∂q` itself: its position rows carry the lever arm of the
//! tracking error (`tᵢ = wᵢ + zᵢ × a`), which makes them nearly dependent on the rotation
//! rows whenever the target is far, whatever the arm's posture. `ρ` falls as the square of
//! the distance to a singular configuration.
//!
//! **The platform** runs the planar law on §5's projection of the target ([`crate::space`]);
//! its preferred pose `r_*` is where the arm at home holds the target at `r*_ed`
//! ([`Params::for_arm`]).
//!
//! **What run (a) asks of the arm on a unicycle.** With `Ψ ≡ 1` and the drift pre-compensated,
//! `h_s → 0`: the companion frame rides with the target, and the platform is where the
//! transverse function puts it (in the plane; the target's height is the lift's),
//!
//! ```text
//! r̄ → 0:   r̄_b = r_d r_*,   r_b = r̄_b f(α) = r_d r_* f(α),   r_bd = f(α)⁻¹ r_*⁻¹          (11), (49)
//! ū = H̄(α) (v, ω, α̇) = the target's velocity seen from the companion frame                  (14)
//! small ε, ū = (0, u, 0):   α̇ = 2u/(ε₁ε₂),   v = (2u/ε₂) cos α,   ω = −(2u/ε₁) sin α          (16)
//! ```
//!
//! (rows 1 and 3 of `H̄ ≈ [1 0 −ε₁cos α; ε₂cos α 0 −ε₁ε₂cos 2α/2; 0 1 ε₂ sin α]` give `v` and `ω`,
//! row 2 `α̇`; for any `ε`, [`Unicycle::manoeuvres`](crate::Unicycle::manoeuvres) takes the largest
//! over `α` and the target's direction from `H̄(α)⁻¹` itself). So the arm holds the target over the
//! orbit `f(α)⁻¹ r_*⁻¹`, `α ∈ S¹` — the target seen from the platform moved by up to `ε₁` along its
//! `x` and turned by up to `arctan ε₂` about its vertical axis — and follows the platform's
//! manoeuvres: it must turn the tool back at `ω` and carry it at `v`. A wider function slows them
//! (`∝ 1/ε`) and asks more reach (`∝ ε`): the paper's condition on `ε̄` (D(ε₁, ε₂) inside the joint
//! limits, Proposition 1) with the joint speeds added. Nothing in the law can lift either bound:
//! beyond the reach the law damps (the target is out of reach), beyond the speeds the joint guard
//! slows the arm, and `e_p` stays. On lifted trajectory 1 (`u = π/20 m/s`) the paper's `(0.2, 0.4)`
//! makes the platform manoeuvre at up to 0.83 m/s and 1.44 rad/s whatever the arm (`H̄⁻¹` says 0.86
//! m/s and at most 1.57 rad/s); the UR5 follows that, the Panda's shoulder needs `ε₂ = 0.8`, and
//! PAL's TIAGo (a torso and seven joints, its wrist at 1.76–1.95 rad/s, 0.27–0.62 m from shoulder
//! to wrist) needs a home with reach both ways — the elbow at mid-reach — and `(ε₁, ε₂) = (0.15,
//! 1.5)`: `ε₁` inside the 0.175 m of reach it keeps, `ε₂` slowing the forward manoeuvres to 0.47
//! m/s, which its wrist follows (core's test suite, `tiago`, has the figures and why a stretched
//! home or the paper's function cannot do).

use nalgebra::{Matrix3, SMatrix, SVector, Vector3, Vector6};

use crate::acceleration::AccelerationLimits;
use crate::arm_law::{implicit_rhs, solve_redundant, solve_square_into, Linearised};
use crate::chain::{Chain, JointKind};
use crate::error::{ParamError, Rule, StepError};
use crate::kinematics::SpatialKinematics;
use crate::linalg;
use crate::params::{
    range_fraction, JointLimits, PaperRun, Params, PrimaryTask, SecondaryTask, Weight, WeightMargins,
};
use crate::primary::{penalty, PrimaryPoint};
use crate::reach::{Frames, Lag, Reach, ReachJoints, MARGIN_FRACTION};
use crate::scalar::Real;
use crate::se2::Pose;
use crate::se3::{Matrix6, Pose3};
use crate::secondary::{ArmTerms, ARM_TERMS};
use crate::so3;
use crate::space::Spatial;
use crate::task::{Manipulator, TaskPoint, TaskStep};

/// The default `ρ_min` of [`SpatialArm::with_singular_below`]: a step below it is refused.
pub const SINGULAR_BELOW: f64 = 1e-10;
/// The default damping onset `ρ₀` of [`SpatialArm::with_damping`].
pub const DAMPING_BELOW: f64 = 1e-3;
/// The default damping depth `κ` of [`SpatialArm::with_damping`].
pub const DAMPING_DEPTH: f64 = 0.1;
/// How much worse than at home an arm's conditioning may get before it is damped
/// ([`SpatialArm::onset_from_home`]).
pub const HOME_RATIO_FACTOR: f64 = 50.0;

/// `cᵢ`: 1 for a revolute joint; `(v̄ / vᵢ)²` for a prismatic one, with `v̄` the fastest
/// finite speed limit of the revolute joints (1 rad/s if none) — a prismatic joint's metres
/// made commensurable with the revolute joints' radians by their speed limits (1 if it has
/// none, or if it is faster than `v̄`).
fn speed_weights<T: Real, const N: usize>(chain: &Chain<T, N>) -> SVector<T, N> {
    let mut fastest = T::zero();
    for j in &chain.joints {
        if j.kind == JointKind::Revolute && j.max_velocity.finite() && j.max_velocity > fastest {
            fastest = j.max_velocity;
        }
    }
    if fastest <= T::zero() {
        fastest = T::one();
    }
    SVector::from_fn(|i, _| {
        let j = &chain.joints[i];
        if j.kind == JointKind::Prismatic && j.max_velocity < fastest {
            let r = fastest / j.max_velocity;
            r * r
        } else {
            T::one()
        }
    })
}

/// A spatial arm: a [`Chain`] of six or more joints, for the law of §5.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpatialArm<T, const N: usize> {
    chain: Chain<T, N>,
    /// Each joint's frame in the previous joint's moving frame, turned so that the joint
    /// moves about or along its `z` axis.
    links: [Pose3<T>; N],
    revolute: [bool; N],
    /// The end effector in the last joint's (turned) moving frame.
    tool: Pose3<T>,
    /// The Hadamard ratio below which a configuration is singular.
    singular_below: T,
    /// `ρ₀`: the ratio below which the solution is damped.
    damping_below: T,
    /// `κ`: the damping's depth at a singular configuration, relative to the mean diagonal.
    damping_depth: T,
    /// `cᵢ` of the redundant solution's weights `wᵢ = cᵢ (1 + ∂²h_ℓ/∂qᵢ²)` (module docs).
    speed_weights: SVector<T, N>,
    /// The reach terms of the weight `Ψ̃` ([`crate::reach`]); `None`: the joints' alone.
    reach: Option<Reach<T>>,
}

/// The task's quantities at one `(q, r_bd, t)` (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpatialTerms<T, const N: usize> {
    /// `e_p = (p̃, φ̃)`.
    pub e_p: Vector6<T>,
    /// `∂e_p/∂q` (6×N).
    pub de_p_dq: SMatrix<T, 6, N>,
    /// `∂e_p/∂u_bd` (6×6): with respect to a body perturbation of `r_bd`.
    pub de_p_du: Matrix6<T>,
    /// `e_m`, eq. (23).
    pub e_m: SVector<T, N>,
    /// `∂e_m/∂q`, eq. (24), with the second-derivative term.
    pub de_m_dq: SMatrix<T, N, N>,
    /// `∂e_m/∂u_bd` (N×6).
    pub de_m_du: SMatrix<T, N, 6>,
    /// `Γ̇ (q − q̂) − Γ q̂̇`.
    pub de_m_dt_explicit: SVector<T, N>,
    /// `∂h_ℓ/∂q`.
    pub grad_l: SVector<T, N>,
    /// The diagonal `∂²h_ℓ/∂qᵢ²`.
    pub hess_l: SVector<T, N>,
    /// `h_ℓ(q)`, eq. (20).
    pub h_l: T,
    /// The arm's measure `ρ ∈ [0, 1]` (module docs; 0: singular); 1 when `N < 6` (not
    /// computed).
    pub singularity: T,
}

/// The arguments of the spatial task at one point: the planar task's, with `r_bd` in space.
pub type SpatialPoint<'a, T, const N: usize> = PrimaryPoint<'a, T, N, Pose3<T>>;

/// `v ∈ [0, 1)`.
fn unit<T: Real>(name: &'static str, v: T) -> Result<T, ParamError> {
    if v >= T::zero() && v < T::one() {
        Ok(v)
    } else {
        Err(ParamError::new(name, Rule::NotInUnitInterval))
    }
}

/// `Q` with `Q e_z = a` (`a` unit): exact for the coordinate axes.
fn axis_to_z<T: Real>(a: &Vector3<T>) -> Matrix3<T> {
    let (z, o) = (T::zero(), T::one());
    let h = if a[0].abs() < T::of(0.9) { Vector3::new(o, z, z) } else { Vector3::new(z, o, z) };
    let x = h - a * h.dot(a);
    let x = x / x.norm_squared().square_root();
    let y = a.cross(&x);
    Matrix3::from_columns(&[x, y, *a])
}

impl<T: Real, const N: usize> Chain<T, N> {
    /// The frames at `q` (every joint's axis and origin, the end effector), from the
    /// description as it is (URDF form): for reference, tests and drawing.
    pub fn frames(&self, q: &SVector<T, N>) -> SpatialKinematics<T, N> {
        let mut f = self.mount;
        let mut axes = SMatrix::<T, 3, N>::zeros();
        let mut points = SMatrix::<T, 3, N>::zeros();
        let mut revolute = [true; N];
        for (i, j) in self.joints.iter().enumerate() {
            f = f.compose(&j.origin);
            axes.set_column(i, &(f.rotation * j.axis));
            points.set_column(i, &f.translation);
            revolute[i] = j.kind == JointKind::Revolute;
            f = f.compose(&j.motion(q[i]));
        }
        SpatialKinematics { axes, points, revolute, effector: f.compose(&self.tool) }
    }
}

impl<T: Real, const N: usize> SpatialArm<T, N> {
    /// The spatial arm of a chain.
    ///
    /// # Errors
    /// The chain's own rule (see [`Chain::validate`]), or `joints` with
    /// [`Rule::TooFewJoints`] for fewer than six joints (the task has six dimensions).
    pub fn new(chain: &Chain<T, N>) -> Result<Self, ParamError> {
        chain.validate()?;
        if N < 6 {
            return Err(ParamError::new("joints", Rule::TooFewJoints));
        }
        let mut links = [Pose3::identity(); N];
        let mut revolute = [true; N];
        // Each axis turned into z: O · exp(q [a]) = (O Q) · exp(q [e_z]) · Qᵀ, and the
        // trailing Qᵀ moves into the next frame.
        let mut prev = Matrix3::identity();
        for (i, j) in chain.joints.iter().enumerate() {
            let q = axis_to_z(&j.axis);
            let turned = Pose3::new(prev.transpose(), Vector3::zeros())
                .compose(&j.origin)
                .compose(&Pose3::new(q, Vector3::zeros()));
            links[i] = turned;
            revolute[i] = j.kind == JointKind::Revolute;
            prev = q;
        }
        let tool = Pose3::new(prev.transpose(), Vector3::zeros()).compose(&chain.tool);
        Ok(Self {
            chain: *chain,
            links,
            revolute,
            tool,
            singular_below: T::of(SINGULAR_BELOW),
            damping_below: T::of(DAMPING_BELOW),
            damping_depth: T::of(DAMPING_DEPTH),
            speed_weights: speed_weights(chain),
            reach: None,
        }
        .with_default_reach())
    }

    /// The same arm with the reach of [`ReachJoints::of_chain`] searched over its chain
    /// ([`Reach::search`], the paper's margins), or none if the chain has fewer than four
    /// revolute joints.
    fn with_default_reach(mut self) -> Self {
        self.reach = ReachJoints::of_chain(&self.chain)
            .and_then(|j| Reach::search(&self, &self.chain, j, T::of(MARGIN_FRACTION)));
        self
    }

    /// The reach terms of the weight ([`crate::reach`]).
    pub fn reach(&self) -> Option<&Reach<T>> {
        self.reach.as_ref()
    }

    /// The reach of `joints` searched over the chain, its margins `fraction` of the room from
    /// the home to each limit (the paper's 0.2: [`MARGIN_FRACTION`]).
    ///
    /// # Errors
    /// `reach_joints` with [`Rule::Geometry`] when the joints do not suit the chain;
    /// `reach_margin` when `fraction` is not in `(0, 1)` (at 1 the ramp would reach the home).
    pub fn reach_of(&self, joints: ReachJoints, fraction: T) -> Result<Reach<T>, ParamError> {
        joints.validate(N)?;
        if !(fraction > T::zero() && fraction < T::one()) {
            return Err(ParamError::new("reach_margin", Rule::NotInUnitInterval));
        }
        Reach::search(self, &self.chain, joints, fraction)
            .ok_or(ParamError::new("reach_joints", Rule::Geometry))
    }

    /// The same arm with other reach terms (`None`: the weight sees the joints alone, as the
    /// paper's (52)).
    ///
    /// # Errors
    /// The reach's rule broken ([`Reach::validate`]).
    pub fn with_reach(mut self, reach: Option<Reach<T>>) -> Result<Self, ParamError> {
        if let Some(r) = &reach {
            r.validate(N)?;
        }
        self.reach = reach;
        Ok(self)
    }

    /// The weights `cᵢ` the redundant solution gives each joint (module docs): by default
    /// a prismatic joint's by its speed limit against the revolute joints'; 1 for every
    /// joint with `by_speed = false` (the least norm in the joints' own units).
    pub fn with_speed_weighting(mut self, by_speed: bool) -> Self {
        self.speed_weights = if by_speed { speed_weights(&self.chain) } else { SVector::repeat(T::one()) };
        self
    }

    /// The weights `cᵢ` (module docs).
    pub fn speed_weights(&self) -> &SVector<T, N> {
        &self.speed_weights
    }

    /// The chain it was built from.
    pub fn chain(&self) -> &Chain<T, N> {
        &self.chain
    }

    /// The Hadamard ratio of `∂e_p/∂q` below which the law refuses a step (module docs).
    pub fn singular_below(&self) -> T {
        self.singular_below
    }

    /// The same arm with another singularity threshold `ρ_min ∈ [0, 1)` (default `10⁻¹⁰`).
    ///
    /// # Errors
    /// `singular_below` with [`Rule::NotInUnitInterval`].
    pub fn with_singular_below(mut self, threshold: T) -> Result<Self, ParamError> {
        self.singular_below = unit("singular_below", threshold)?;
        Ok(self)
    }

    /// The damping's onset `ρ₀` and depth `κ` (module docs).
    pub fn damping(&self) -> (T, T) {
        (self.damping_below, self.damping_depth)
    }

    /// The same arm with another damping: onset `ρ₀ ∈ [0, 1)` (0: never damped; default
    /// `10⁻³`) and depth `κ ∈ [0, 1)` (default 0.1).
    ///
    /// # Errors
    /// `damping_below` or `damping_depth` with [`Rule::NotInUnitInterval`].
    pub fn with_damping(mut self, onset: T, depth: T) -> Result<Self, ParamError> {
        self.damping_below = unit("damping_below", onset)?;
        self.damping_depth = unit("damping_depth", depth)?;
        Ok(self)
    }

    /// The ratio `ρ` the law compares with the damping's onset (module docs) at `q` with the
    /// target where it should be (`e_p = 0`): the arm's own conditioning there, with the
    /// weights of the redundant solution for more than six joints.
    pub fn ratio_at(
        &self,
        task: &PrimaryTask<T, N, Spatial>,
        limits: &JointLimits<T, N>,
        q: &SVector<T, N>,
    ) -> T {
        let kin = self.kinematics(q);
        let r_bd = kin.effector.compose(&task.target_in_effector);
        let zero = SVector::<T, N>::zeros();
        let point = SpatialPoint {
            q,
            r_bd: &r_bd,
            gamma: T::zero(),
            gamma_rate: T::zero(),
            q_hat: q,
            q_hat_rate: &zero,
        };
        let tm = terms(&kin, task, limits, &point);
        if N > 6 {
            let w = tm.hess_l.zip_map(&self.speed_weights, |h, c| c * (T::one() + h));
            let a = &tm.de_p_dq;
            let b = SMatrix::<T, N, 6>::from_fn(|i, j| a[(j, i)] / w[i]);
            hadamard_sym(&(a * b))
        } else {
            tm.singularity
        }
    }

    /// The damping onset this arm gets when none is set: `min(10⁻³, ρ_home / 50)`, with
    /// `ρ_home` the [`ratio_at`](Self::ratio_at) its home — damping starts where the arm is
    /// fifty times worse conditioned than at the posture it prefers, or at the fixed `10⁻³`
    /// if that comes first. The fixed onset alone damps a redundant arm whose home is already
    /// near it (the TIAGo's: `ρ_home ≈ 10⁻³` with its slow torso weighed out), which then
    /// never meets its task.
    pub fn onset_from_home(&self, task: &PrimaryTask<T, N, Spatial>, limits: &JointLimits<T, N>) -> T {
        let r = self.ratio_at(task, limits, &self.chain.home()) / T::of(HOME_RATIO_FACTOR);
        let fixed = T::of(DAMPING_BELOW);
        if r < fixed && r >= T::zero() {
            r
        } else {
            fixed
        }
    }

    /// The frames at `q`: every joint's axis `zᵢ` and point `oᵢ`, and the end effector.
    #[inline(always)]
    pub fn kinematics(&self, q: &SVector<T, N>) -> SpatialKinematics<T, N> {
        let mut r = self.chain.mount.rotation;
        let mut p = self.chain.mount.translation;
        let mut axes = SMatrix::<T, 3, N>::zeros();
        let mut points = SMatrix::<T, 3, N>::zeros();
        for i in 0..N {
            let link = &self.links[i];
            p += r * link.translation;
            r *= link.rotation;
            let zi = r.column(2).into_owned();
            axes.set_column(i, &zi);
            points.set_column(i, &p);
            if self.revolute[i] {
                // R R_z(q): the first two columns turn.
                let (s, c) = q[i].sincos();
                let (c0, c1) = (r.column(0).into_owned(), r.column(1).into_owned());
                r.set_column(0, &(c0 * c + c1 * s));
                r.set_column(1, &(c1 * c - c0 * s));
            } else {
                p += zi * q[i];
            }
        }
        let effector = Pose3::new(r, p).compose(&self.tool);
        SpatialKinematics { axes, points, revolute: self.revolute, effector }
    }

    /// `r*_ed` that puts the target `distance` metres along the end effector's `z` axis (a
    /// flange's approach direction), level — its `z` up and its `x` along the platform's `x`
    /// — when the arm is at home.
    pub fn level_target(&self, distance: T) -> Pose3<T> {
        let home = self.kinematics(&self.chain.home()).effector;
        let z = T::zero();
        Pose3::new(home.rotation.transpose(), Vector3::new(z, z, distance))
    }

    /// The platform's preferred pose `r_*` seen from the projected target: where the arm at
    /// home holds the target at `r*_ed` (the paper's `r_*` for the RPR arm at `q_*`).
    ///
    /// # Errors
    /// `target_in_effector` with [`Rule::Geometry`] when the target at home has no yaw (its
    /// `x` axis vertical).
    pub fn preferred_pose(&self, target_in_effector: &Pose3<T>) -> Result<Pose<T>, ParamError> {
        let home = self.kinematics(&self.chain.home()).effector;
        let r_bd = home.compose(target_in_effector);
        let plane = r_bd.planar().ok_or(ParamError::new("target_in_effector", Rule::Geometry))?;
        Ok(plane.inverse().pose)
    }

    /// The task at a point (module docs).
    ///
    /// Never inlined into the law: with its temporaries in the law's frame, that frame was
    /// larger than the M4F's load/store offsets reach (±1 020 B), so that every access to
    /// the stack took an extra address computation (~1 600 instructions of a step).
    #[inline(never)]
    pub fn terms(
        &self,
        task: &PrimaryTask<T, N, Spatial>,
        limits: &JointLimits<T, N>,
        point: &SpatialPoint<'_, T, N>,
    ) -> SpatialTerms<T, N> {
        terms(&self.kinematics(point.q), task, limits, point)
    }

    /// (30) at a point over the hold (module docs; [`Manipulator::arm_law`]). Never inlined
    /// into the step, for the same reason as [`Self::terms`].
    #[inline(never)]
    fn law(
        &self,
        task: &PrimaryTask<T, N, Spatial>,
        limits: &JointLimits<T, N>,
        pt: &TaskPoint<'_, T, N, Spatial>,
        half: T,
    ) -> Result<TaskStep<T, N, Spatial>, StepError> {
        let point = SpatialPoint {
            q: pt.q,
            r_bd: pt.r_bd,
            gamma: pt.gamma,
            gamma_rate: pt.gamma_rate,
            q_hat: pt.q_hat,
            q_hat_rate: pt.q_hat_rate,
        };
        let tm = self.terms(task, limits, &point);
        if tm.singularity.nan() || tm.singularity < self.singular_below {
            return Err(StepError::SingularArm);
        }
        // u_bd = u_d − B u_b with B = Ad_{r_db} restricted to the platform's (v₁, v₂, ω).
        let b = base_columns(pt.r_bd);
        let u_bd = pt.u_d - b * pt.u_b;
        let mut step = TaskStep {
            u_q: SVector::zeros(),
            sensitivity: SMatrix::zeros(),
            condition: T::zero(),
            e_p: tm.e_p,
            e_m: tm.e_m,
            h_l: tm.h_l,
        };
        if N > 6 {
            // ė_p = G e_p with the first six gains; the penalty in the null space.
            let gain = SVector::<T, 6>::from_fn(|i, _| task.gain[i]);
            let transport = tm.de_p_du * u_bd;
            let zero = Vector6::zeros();
            let lin = Linearised {
                e: &tm.e_p,
                a: &tm.de_p_dq,
                transport: &transport,
                explicit: &zero,
                drhs: tm.de_p_du * b,
            };
            let (rhs, drhs) = implicit_rhs(&lin, &gain, pt.guess, half);
            let w = tm.hess_l.zip_map(&self.speed_weights, |h, c| c * (T::one() + h));
            let z = SVector::<T, N>::from_fn(|i, _| -task.null_space_gain * tm.grad_l[i] / w[i]);
            let (onset, depth) = (self.damping_below, self.damping_depth);
            (step.u_q, step.sensitivity, step.condition) = solve_redundant(
                &tm.de_p_dq,
                &w,
                &z,
                &rhs,
                &drhs,
                |s: &Matrix6<T>| damping(s, hadamard_sym(s), onset, depth),
                half,
            )?;
        } else {
            let transport = linalg::mul(&tm.de_m_du, &u_bd);
            let lin = Linearised {
                e: &tm.e_m,
                a: &tm.de_m_dq,
                transport: &transport,
                explicit: &tm.de_m_dt_explicit,
                drhs: linalg::mul(&tm.de_m_du, &b),
            };
            let (rhs, drhs) = implicit_rhs(&lin, &task.gain, pt.guess, half);
            let lambda2 = damping(&tm.de_m_dq, tm.singularity, self.damping_below, self.damping_depth);
            step.condition = solve_square_into(
                &tm.de_m_dq,
                &rhs,
                &drhs,
                lambda2,
                half,
                &mut step.u_q,
                &mut step.sensitivity,
            )?;
        }
        Ok(step)
    }
}

/// `−∂u_bd/∂u_b = Ad_{r_db}` on the platform's twist `(v₁, v₂, ω)`: the columns
/// `(R_dᵀ e_x, 0)`, `(R_dᵀ e_y, 0)`, `(R_dᵀ (e_z × p_d), R_dᵀ e_z)`.
#[inline(always)]
fn base_columns<T: Real>(r_bd: &Pose3<T>) -> SMatrix<T, 6, 3> {
    let rt = r_bd.rotation.transpose();
    let p = &r_bd.translation;
    let zc = Vector3::new(-p[1], p[0], T::zero());
    let c2 = rt * zc;
    SMatrix::<T, 6, 3>::from_fn(|i, j| match (i, j) {
        (0..=2, 0) => rt[(i, 0)],
        (0..=2, 1) => rt[(i, 1)],
        (0..=2, _) => c2[i],
        (_, 2) => rt[(i - 3, 2)],
        _ => T::zero(),
    })
}

/// The task of the module docs from the arm's frames.
#[inline(always)]
pub fn terms<T: Real, const N: usize>(
    kin: &SpatialKinematics<T, N>,
    task: &PrimaryTask<T, N, Spatial>,
    limits: &JointLimits<T, N>,
    point: &SpatialPoint<'_, T, N>,
) -> SpatialTerms<T, N> {
    let SpatialPoint { q, r_bd, gamma, gamma_rate, q_hat, q_hat_rate } = *point;
    let star = &task.target_in_effector;
    let (r_e, p_e) = (&kin.effector.rotation, &kin.effector.translation);
    let (r_d, p_d) = (&r_bd.rotation, &r_bd.translation);
    let m = r_e * star.rotation;
    let p_star = p_e + r_e * star.translation;
    let a = p_d - p_star;
    let mt = m.transpose();
    let phi = so3::log(&(mt * r_d));
    let jri = so3::right_jacobian_inv(&phi);
    let p_tilde = mt * a;
    let e_p = Vector6::new(p_tilde[0], p_tilde[1], p_tilde[2], phi[0], phi[1], phi[2]);

    // Columns tᵢ, wᵢ, ζᵢ.
    let mut t_cols = SMatrix::<T, 3, N>::zeros();
    let mut w_cols = SMatrix::<T, 3, N>::zeros();
    let mut z_cols = SMatrix::<T, 3, N>::zeros();
    for i in 0..N {
        let zi = kin.axes.column(i).into_owned();
        if kin.revolute[i] {
            let oi = kin.points.column(i).into_owned();
            t_cols.set_column(i, &zi.cross(&(p_d - oi)));
            w_cols.set_column(i, &zi.cross(&(p_star - oi)));
            z_cols.set_column(i, &zi);
        } else {
            t_cols.set_column(i, &zi);
            w_cols.set_column(i, &zi);
        }
    }
    let rdt = r_d.transpose();
    let jp = -(mt * t_cols);
    let jphi = -(jri * (rdt * z_cols));
    let mut de_p_dq = SMatrix::<T, 6, N>::zeros();
    de_p_dq.fixed_rows_mut::<3>(0).copy_from(&jp);
    de_p_dq.fixed_rows_mut::<3>(3).copy_from(&jphi);
    let mut de_p_du = Matrix6::zeros();
    de_p_du.fixed_view_mut::<3, 3>(0, 0).copy_from(&(mt * r_d));
    de_p_du.fixed_view_mut::<3, 3>(3, 3).copy_from(&jri);

    // Joint-limit penalty (20)–(21).
    let mut grad_l = SVector::<T, N>::zeros();
    let mut hess_l = SVector::<T, N>::zeros();
    let mut h_l = T::zero();
    for i in 0..N {
        let w = task.penalty_weight[i];
        let (f, f1, f2) = penalty(q[i], limits.lower[i], limits.upper[i], task.penalty_margin[i]);
        h_l += T::of(0.5) * w * f * f;
        grad_l[i] = w * f * f1;
        hess_l[i] = w * (f1 * f1 + f * f2);
    }
    let dq = q - q_hat;
    let e_m = de_p_dq.transpose() * e_p + grad_l + dq * gamma;

    // (24): sym(Tᵀ W + Zᵀ K Z) + diag(∂²h_ℓ + Γ).
    let k = r_d * jri * rdt;
    let kz = k * z_cols;
    let mut de_m_dq = SMatrix::<T, N, N>::zeros();
    for col in 0..N {
        for row in 0..=col {
            let v = t_cols.column(row).dot(&w_cols.column(col)) + z_cols.column(row).dot(&kz.column(col));
            de_m_dq[(row, col)] = v;
            de_m_dq[(col, row)] = v;
        }
    }
    for i in 0..N {
        de_m_dq[(i, i)] += hess_l[i] + gamma;
    }
    // ∂e_m/∂u_bd = −[Wᵀ R_d, Zᵀ Kᵀ R_d].
    let left = -(w_cols.transpose() * r_d);
    let right = -((kz.transpose()) * r_d);
    let mut de_m_du = SMatrix::<T, N, 6>::zeros();
    de_m_du.fixed_columns_mut::<3>(0).copy_from(&left);
    de_m_du.fixed_columns_mut::<3>(3).copy_from(&right);
    let de_m_dt_explicit = dq * gamma_rate - q_hat_rate * gamma;

    let singularity = if N >= 6 { manipulability(&w_cols, &z_cols) } else { T::one() };
    SpatialTerms {
        e_p,
        de_p_dq,
        de_p_du,
        e_m,
        de_m_dq,
        de_m_du,
        de_m_dt_explicit,
        grad_l,
        hess_l,
        h_l,
        singularity,
    }
}

/// `λ² = κ (tr S / M) (1 − ρ/ρ₀)²` below the onset `ρ₀`, 0 above.
fn damping<T: Real, const M: usize>(s: &SMatrix<T, M, M>, ratio: T, onset: T, depth: T) -> T {
    // (Also for a NaN ratio: the step fails later, as non-finite.)
    if ratio >= onset || ratio.nan() {
        return T::zero();
    }
    let f = T::one() - ratio.max(T::zero()) / onset;
    let mut tr = T::zero();
    for i in 0..M {
        tr += s[(i, i)];
    }
    depth * f * f * tr / T::of(M as f64)
}

/// The Hadamard ratio `det S/∏ Sᵢᵢ` of a symmetric positive semi-definite 6×6 matrix.
fn hadamard_sym<T: Real>(s: &Matrix6<T>) -> T {
    let mut prod = T::one();
    for i in 0..6 {
        prod *= s[(i, i)];
    }
    if prod > T::zero() {
        linalg::determinant(s) / prod
    } else {
        T::zero()
    }
}

/// The arm's measure `ρ = det(J Jᵀ)/((|W|²/3)³ (|Z|²/3)³)` of `J = [W; Z]` (module docs):
/// for six joints `det(J Jᵀ) = det(J)²`.
fn manipulability<T: Real, const N: usize>(w: &SMatrix<T, 3, N>, z: &SMatrix<T, 3, N>) -> T {
    let det = if N == 6 {
        // J itself, built once and eliminated in place.
        let mut j = SMatrix::<T, 6, 6>::from_fn(|r, c| if r < 3 { w[(r, c)] } else { z[(r - 3, c)] });
        let d = linalg::determinant_in_place(&mut j);
        d * d
    } else {
        let mut j = SMatrix::<T, 6, N>::zeros();
        j.fixed_rows_mut::<3>(0).copy_from(w);
        j.fixed_rows_mut::<3>(3).copy_from(z);
        linalg::determinant(&(j * j.transpose()))
    };
    let third = T::one() / T::of(3.0);
    let (v, r) = (w.norm_squared() * third, z.norm_squared() * third);
    let scale = v * v * v * r * r * r;
    if scale > T::zero() {
        det / scale
    } else {
        T::zero()
    }
}

impl<T: Real, const N: usize> Frames<T, N> for SpatialArm<T, N> {
    fn frames_at(&self, q: &SVector<T, N>) -> SpatialKinematics<T, N> {
        self.kinematics(q)
    }
}

macro_rules! spatial_manipulator {
    ($t:ty) => {
        /// A spatial arm is a [`Manipulator`] of space (implemented for `f32` and `f64`:
        /// a generic implementation would overlap, for the coherence rules, with the one
        /// every planar [`Arm`](crate::Arm) gets).
        impl<const N: usize> Manipulator<$t, N> for SpatialArm<$t, N> {
            type Space = Spatial;

            fn validate_arm(&self) -> Result<(), ParamError> {
                self.chain.validate()?;
                if N < 6 {
                    return Err(ParamError::new("joints", Rule::TooFewJoints));
                }
                match &self.reach {
                    Some(r) => r.validate(N),
                    None => Ok(()),
                }
            }

            #[inline]
            fn check_joints(&self, _q: &SVector<$t, N>) -> Result<(), StepError> {
                // Checked where the law is evaluated, with the Jacobian it computes anyway.
                Ok(())
            }

            #[inline(always)]
            fn weight_terms(
                &self,
                task: &PrimaryTask<$t, N, Spatial>,
                q: &SVector<$t, N>,
                r_bd: Option<&Pose3<$t>>,
                gradient: bool,
            ) -> Option<ArmTerms<$t, N>> {
                let reach = self.reach.as_ref()?;
                let kin = self.kinematics(q);
                if gradient {
                    let (sigma, gradient) = reach.sigma_gradient(&kin, q);
                    return Some(ArmTerms { sigma, gradient, rule: reach.rule });
                }
                let lag = match r_bd {
                    Some(r_bd) => {
                        let e = &kin.effector;
                        Some(Lag {
                            held: e.translation + e.rotation * task.target_in_effector.translation,
                            target: r_bd.translation,
                        })
                    }
                    None => None,
                };
                Some(ArmTerms {
                    sigma: reach.sigma(&kin, q, lag.as_ref()),
                    gradient: [SVector::zeros(); ARM_TERMS],
                    rule: reach.rule,
                })
            }

            #[inline(always)]
            fn arm_law(
                &self,
                task: &PrimaryTask<$t, N, Spatial>,
                limits: &JointLimits<$t, N>,
                _star: &Pose3<$t>,
                point: &TaskPoint<'_, $t, N, Spatial>,
                half: $t,
            ) -> Result<TaskStep<$t, N, Spatial>, StepError> {
                self.law(task, limits, point, half)
            }
        }
    };
}

spatial_manipulator!(f32);
spatial_manipulator!(f64);

impl<T: Real, const N: usize> Params<T, N, Spatial> {
    /// The paper's §4.3 law (run (a)–(d)) for a spatial arm: its limits, home (`q*`) and
    /// speeds from the chain; `r*_ed` as given; the platform's preferred pose from the home
    /// ([`SpatialArm::preferred_pose`]); penalty margins `δᵢ = 0.05 (qᵢ⁺ − qᵢ⁻)` (0.2 for
    /// arms with more than six joints, whose penalty acts in the null space of the task
    /// only and is better felt early); the weight margins of (52) from the home; every
    /// other value as the paper's.
    ///
    /// # Errors
    /// As [`SpatialArm::preferred_pose`].
    pub fn for_arm(
        arm: &SpatialArm<T, N>,
        run: PaperRun,
        target_in_effector: Pose3<T>,
    ) -> Result<Self, ParamError> {
        let chain = arm.chain();
        let limits = chain.limits();
        let home = chain.home();
        let preferred = arm.preferred_pose(&target_in_effector)?;
        let margin = if N > 6 { T::of(0.2) } else { T::of(0.05) };
        let paper = Params::<T, 3>::paper(run);
        let weight = match paper.secondary.weight {
            Weight::Constant(c) => Weight::Constant(c),
            Weight::Filtered { lambda, xi, .. } => {
                Weight::Filtered { margins: WeightMargins::paper(&limits, &home), lambda, xi }
            }
            Weight::PerJoint { lambda, xi, .. } => {
                Weight::PerJoint { margins: WeightMargins::paper(&limits, &home), lambda, xi }
            }
            Weight::FromFilteredJoints { .. } => {
                Weight::FromFilteredJoints { margins: WeightMargins::paper(&limits, &home) }
            }
        };
        let p = &paper.primary;
        let s = &paper.secondary;
        Ok(Self {
            joint_limits: limits,
            primary: PrimaryTask {
                target_in_effector,
                penalty_weight: SVector::repeat(p.penalty_weight[0]),
                penalty_margin: range_fraction(&limits, margin),
                regularisation_gain: p.regularisation_gain,
                regularisation_decay: p.regularisation_decay,
                filter_sigma: p.filter_sigma,
                filter_xi: p.filter_xi,
                gain: SVector::repeat(p.gain[0]),
                null_space_gain: p.null_space_gain,
            },
            secondary: SecondaryTask {
                preferred_pose: preferred,
                gamma_1: s.gamma_1,
                gamma_2: s.gamma_2,
                rest_sigma: s.rest_sigma,
                rest_xi: s.rest_xi,
                rest_reach: s.rest_reach,
                weight,
                k_bar: s.k_bar,
                d: s.d,
                mu: s.mu,
                precompensation: s.precompensation,
                rest_filter: s.rest_filter,
                psi_rate_in_drift: s.psi_rate_in_drift,
                heading_filter: s.heading_filter,
            },
            velocity_limits: paper.velocity_limits,
            max_time_step: paper.max_time_step,
            joint_step_fraction: paper.joint_step_fraction,
            joint_velocity_limits: chain.max_velocities(),
            acceleration_limits: AccelerationLimits::unlimited(),
            discretisation: paper.discretisation,
            target_motion: paper.target_motion,
            max_delay: paper.max_delay,
            max_turn_per_step: paper.max_turn_per_step,
        })
    }
}
