//! Parameters of the law, validated once when a [`ControlLaw`](crate::ControlLaw) is
//! built, and the paper's §4.3 preset.

use nalgebra::{SVector, Vector3};

use crate::acceleration::AccelerationLimits;
use crate::error::{at_most, check_nonneg, check_positive, positive};
use crate::error::{Bound, ParamError, Rule};
use crate::platform::VelocityLimits;
use crate::scalar::Real;
use crate::se2::Pose;
use crate::space::{Planar, Space};

/// Joint limits `q⁻ < q⁺` (rad for revolute joints, m for prismatic ones).
///
/// A revolute joint without position limits (URDF's `continuous`: a wheel, a wrist that
/// turns forever) has `q⁻ = −∞`, `q⁺ = +∞` ([`is_unbounded`](Self::is_unbounded)). Every
/// term of the law that keeps a joint inside its limits is then zero for it by its own
/// formula, with no special case on the hot path: the penalty (21) (`qᵢ < −∞ + δᵢ` never
/// holds), `σ̃ᵢ` of the weight (52) (so `Ψ` averages zeros for it over the `N` joints) and
/// the joint guard's fraction-to-the-boundary rule (its room is infinite); its velocity limit
/// still applies. Its margins `δᵢ`, `δᵢ±`, `δᵢ±±` must still be finite and positive: they
/// are unused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointLimits<T, const N: usize> {
    /// Lower limits `q⁻` (`−∞` for an unbounded joint).
    pub lower: SVector<T, N>,
    /// Upper limits `q⁺` (`+∞` for an unbounded joint).
    pub upper: SVector<T, N>,
}

impl<T: Real, const N: usize> JointLimits<T, N> {
    /// Whether joint `i` has no position limits (`q⁻ = −∞` and `q⁺ = +∞`).
    pub fn is_unbounded(&self, i: usize) -> bool {
        unbounded(self.lower[i], self.upper[i])
    }
}

/// Whether `[lower, upper]` is the whole line (`−∞`, `+∞`): a joint without position limits.
#[inline]
pub fn unbounded<T: Real>(lower: T, upper: T) -> bool {
    !lower.finite() && !upper.finite() && lower < T::zero() && upper > T::zero()
}

/// A margin of `fraction` of a joint's range for each joint (joint units); `1` for a joint
/// without limits, whose margins are unused ([`JointLimits`]).
pub fn range_fraction<T: Real, const N: usize>(limits: &JointLimits<T, N>, fraction: T) -> SVector<T, N> {
    SVector::from_fn(|i, _| {
        if limits.is_unbounded(i) {
            T::one()
        } else {
            (limits.upper[i] - limits.lower[i]) * fraction
        }
    })
}

/// The primary (manipulation) task: `e_p` (42), the joint-limit penalty `h_ℓ` (20)–(21),
/// the regularisation `h_r` (22) with the filter (26), and the gain `G` of (30), for a
/// target in the plane ([`Planar`], the default) or in space ([`Spatial`](crate::Spatial)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimaryTask<T: Real, const N: usize, S: Space<T> = Planar> {
    /// `r*_ed`: the target's desired pose seen from the end effector (m, rad). The paper
    /// uses `(X*, 0, 0)` with `X* = 0.5 m`.
    pub target_in_effector: S::Pose,
    /// `αᵢ > 0`: weights of the joint-limit penalty (20).
    pub penalty_weight: SVector<T, N>,
    /// `δᵢ > 0`: the penalty (21) is active within `δᵢ` of a limit (joint units).
    pub penalty_margin: SVector<T, N>,
    /// `γ₀ ≥ 0` of `Γ(t) = γ₀ e^{−λ_Γ t} I` in (22). Paper: 0.2.
    pub regularisation_gain: T,
    /// `λ_Γ ≥ 0` (1/s) of `Γ(t) = γ₀ e^{−λ_Γ t} I`. Paper: 1. Time counts from the first step.
    pub regularisation_decay: T,
    /// `σ > 0` of the `q̂` filter (26) (joint units per second). Default 10.
    pub filter_sigma: T,
    /// `ξ > 0` of the `q̂` filter (26) (joint units). Default 1.
    pub filter_xi: T,
    /// Gains `gᵢ > 0` of `G = −diag(gᵢ)` in (30) (1/s). The paper's "G = 3 I₃" is gain 3,
    /// i.e. `G = −3 I₃`, so that `ė_m = G e_m` converges. An arm with more joints than the
    /// task has dimensions (a 7-joint arm in space) drives `e_p` itself: `ė_p = G e_p`, with
    /// the first 6 gains (see [`SpatialArm`](crate::SpatialArm)).
    pub gain: SVector<T, N>,
    /// `k_n ≥ 0` (1/s): for arms with more joints than the task has dimensions, the rate at
    /// which the joint-limit penalty `h_ℓ` is descended in the null space of the task; 0
    /// switches that motion off. Unused otherwise. Default 1.
    pub null_space_gain: T,
}

/// The margins of `σ̃ᵢ` in eq. (52), per joint (joint units). With the SPEC's reading:
/// `σ̃ᵢ = 1` within `δᵢ⁻⁻` of the lower limit (`δᵢ⁺⁺` of the upper), 0 farther than `δᵢ⁻`
/// (`δᵢ⁺`), linear in between.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WeightMargins<T, const N: usize> {
    /// `δᵢ⁻`: outer margin at the lower limit.
    pub lower: SVector<T, N>,
    /// `δᵢ⁻⁻ < δᵢ⁻`: inner margin at the lower limit.
    pub lower_inner: SVector<T, N>,
    /// `δᵢ⁺`: outer margin at the upper limit.
    pub upper: SVector<T, N>,
    /// `δᵢ⁺⁺ < δᵢ⁺`: inner margin at the upper limit.
    pub upper_inner: SVector<T, N>,
}

/// How the weight `Ψ(t)` of `h_s = Ψ h_s1 + (1 − Ψ) h_s2` (29) is formed (§4.2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Weight<T, const N: usize> {
    /// A constant `Ψ ∈ [0, 1]`; run (a) uses `Ψ = 1` (`h_s = h_s1`).
    Constant(T),
    /// `Ψ̃(q)` of (52) filtered by (53) with `(λ, ξ)`.
    Filtered {
        /// The margins of (52).
        margins: WeightMargins<T, N>,
        /// `λ > 0` (1/s) of (53). Paper: 1.66.
        lambda: T,
        /// `ξ > 0` of (53). Paper: 1.
        xi: T,
    },
    /// `Ψ = (1/n) Σ σᵢ²` with each `σ̃ᵢ(qᵢ)` filtered as in (54).
    PerJoint {
        /// The margins of (52).
        margins: WeightMargins<T, N>,
        /// `λ > 0` (1/s).
        lambda: T,
        /// `ξ > 0`.
        xi: T,
    },
    /// The cheaper third variant: `Ψ = (1/n) Σ σ̃ᵢ(q̂ᵢ)²` with `q̂` of (26); no extra state.
    FromFilteredJoints {
        /// The margins of (52).
        margins: WeightMargins<T, N>,
    },
}

/// The pre-compensation `(b̂₁, b̂₂)` of the drift `∂h_s/∂t` in the platform law (37).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Precompensation<T> {
    /// Choice 1 with decomposition (51): `b̂₁ = −Ad_{(r_* r̄)⁻¹} u_d`, `b̂₂ = 0`. Exact only
    /// for `h_s = h_s1` (constant `Ψ = 1`). Run (a).
    Full51,
    /// Choice 1 with decomposition (40): `b̂₁ = (∂h_s/∂t) a / (‖a‖² + ν)`,
    /// `b̂₂ = (∂h_s/∂t) ν / (‖a‖² + ν)`. Run (b).
    Full40 {
        /// `ν > 0`. Paper: 1e−4.
        nu: T,
    },
    /// Choice 2: no pre-compensation, `b̂₁ = b̂₂ = 0`. Run (c).
    Off,
    /// Choice 3: `b̂₁ = 0`, `b̂₂ = ∂h_s/∂t`. Run (d).
    Partial,
}

/// How the rest filter (28) — and with it `ū_b` — is advanced over one sampling period.
///
/// The paper's law is continuous-time. Sampled with the command held over a period, the
/// loop through the filter `r̃_b → h_s2 → ū_b → r̃_b` has a gain up to
/// `2 (1 − Ψ) λ_max(K) aᵀDa/(aᵀKa + μ)`, ~2·10³/s with the paper's `K̄ = diag(1, 1, 100)`:
/// at dt = 1 ms an explicit update makes `α̇` and `ω` flip sign every step during the
/// transients of runs (b)–(d). Both variants equal the paper's law as `dt → 0`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RestFilter {
    /// Explicit Euler: (37) evaluated at the start-of-step filter state. Oscillates at the
    /// Nyquist frequency when `dt · gain > 2`.
    Explicit,
    /// Linearly implicit Euler: (37) evaluated at the end-of-step filter state, linearised
    /// (one 3×3 solve). Stable for any gain. The default.
    LinearlyImplicit,
}

/// How the continuous-time law becomes a command that is held for one period.
///
/// The paper's law is continuous: the command changes with the state. A controller computes
/// it at the measurement time `t_k` and the robot holds it until the next one (zero-order
/// hold), possibly after a delay `τ` (compute, transport). Evaluated at the measurement,
/// the held command leaves an error floor first order in the period (‖e_p‖ ≈ 0.1·dt on
/// trajectory 1, run (a)); evaluated at the state the robot will be in halfway through the
/// hold, second order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Discretisation {
    /// The law evaluated at the measured state and held: a literal sampling of the paper.
    /// The floor of ‖e_p‖ is first order in the period; the measurement delay is ignored.
    /// The rest filter (28) is advanced as [`SecondaryTask::rest_filter`] says.
    Sampled,
    /// Hold-aware (the default): the law evaluated at the state predicted for the middle of
    /// the interval over which the command will act — from the measurement, the commands
    /// still in flight during the delay, the previous command as a first guess, the
    /// platform's and arm's kinematics and the target's measured twist and its rate — with
    /// the difference between the guess and the new command corrected to first order
    /// (linearly implicit). The closed loop is then second-order accurate in the period,
    /// and the stiff loops (the rest filter, the pre-compensation (40), the penalty near a
    /// joint limit) are stable at any admitted period. See [`ControlLaw`](crate::ControlLaw).
    Midpoint,
}

/// How the target's motion is extrapolated over the delay and half the hold
/// ([`Discretisation::Midpoint`] only).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetMotion {
    /// The measured body velocity `u_d` held: the error floor keeps a term first order in
    /// the period when the target accelerates (`≈ |u̇_d| h/(2g)`, 4·10⁻⁵ m at 1 ms on the
    /// paper's trajectory 1).
    Held,
    /// `u_d(t)` extrapolated to second order from the last three measured velocities (their
    /// two difference quotients), used only while the quotients agree — so a jump of `u_d`,
    /// as in the paper's trajectory 2, or noise that dominates the rate is not
    /// extrapolated. The default.
    Extrapolated,
}

/// The secondary task and the platform law: `h_s1` (49), `h_s2` (27)–(28), `Ψ`, and (37).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SecondaryTask<T, const N: usize> {
    /// `r_*`: the preferred pose of the platform seen from the target (m, m, rad). Paper:
    /// `−(X* + L_e + L + 0.45, 0, 0)`.
    pub preferred_pose: Pose<T>,
    /// `γ > 0` of the distance in `h_s1` (49) (m²). Paper: 1.
    pub gamma_1: T,
    /// `γ > 0` of the distance in `h_s2` (27) (m²). Paper: 1.
    pub gamma_2: T,
    /// `σᵢ > 0` of the rest filter (28) (1/s). Paper: 10.
    pub rest_sigma: Vector3<T>,
    /// `ξ > 0` of the rest filter (28) (m). Paper: 1.
    pub rest_xi: T,
    /// How far (m) the rest filter's virtual frame may lag behind the companion frame: the
    /// position of `r̃_b` is kept within `±rest_reach` on each axis. Default 10.
    ///
    /// Not in the paper, and inactive in its runs (`|r̃_b|` stays below a metre). Why: the
    /// filter's own speed saturates at `σᵢ` (10 m/s) once `d(r̃_b) ≫ ξ`, so a platform driven
    /// faster than that — towards a target 100 m away without velocity limits — leaves the
    /// virtual frame arbitrarily far behind, and `h_s2 = d²`, quadratic in that lag, then
    /// outweighs `h_s1` whatever `Ψ`: the platform oscillates between the target and a frame
    /// hundreds of metres back and never arrives (run (b), 100 m, 1 ms, measured). With the
    /// lag bounded the far targets converge.
    pub rest_reach: T,
    /// The weight `Ψ` of (29).
    pub weight: Weight<T, N>,
    /// `K̄ = diag(k̄_b, k̄_b, k̄_α)` of (36), all > 0. Paper: (1, 1, 100).
    pub k_bar: Vector3<T>,
    /// `D = diag(dᵢ)` of (37), all > 0. Paper: `I₃`.
    pub d: Vector3<T>,
    /// `μ > 0` regularising (37). Paper: 1e−4.
    pub mu: T,
    /// The pre-compensation choice.
    pub precompensation: Precompensation<T>,
    /// How the rest filter (28) is advanced over a step (see [`RestFilter`]).
    pub rest_filter: RestFilter,
    /// Whether `∂h_s/∂t` includes `Ψ̇ (h_s1 − h_s2)`. The paper preset leaves it out: with
    /// it, runs (b) and (d) chatter (SPEC §3).
    pub psi_rate_in_drift: bool,
    /// The platform follows the target's heading at a bounded rate (beyond the paper; `None`,
    /// the default: the paper's `h_s1` (49), which follows it at once). See [`HeadingFilter`].
    pub heading_filter: Option<HeadingFilter<T>>,
}

/// The target's heading as the platform's law sees it, filtered (beyond the paper).
///
/// `h_s1` (49) puts the companion frame at `r_d r_*`: when the target turns about its own
/// vertical by `Δθ`, that pose swings `|p_*| Δθ` sideways — lateral motion, which a
/// nonholonomic base can only make by manoeuvres, while the arm could simply turn the tool.
/// With this filter the platform's law sees instead the target `r̂_d = r_d Rot(−δ)`: the same
/// position, its heading `θ̂_d = θ_d − δ` lagging by `δ`, which turns at most `σ` rad/s
/// towards the target's:
///
/// ```text
/// θ̂̇_d = σ δ/(ξ + |δ|),   δ̇ = ω_d − θ̂̇_d,   δ(0) = 0          (the bounded filter of (26), (53))
/// r̂_bd = r_bd Rot(−δ),   û_d = (R(δ) (u_d,x, u_d,y), θ̂̇_d)     (its body velocity, (4))
/// ```
///
/// The target's translation reaches the platform's law unfiltered (with its feed-forward
/// (51)); only its turning is slowed, and the arm holds the tool through the lag `δ`. The
/// arm law (30) is unchanged and tracks the target itself. `δ` is wrapped to `(−π, π]`: a
/// target that keeps turning faster than `σ` is followed the short way round.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadingFilter<T> {
    /// `σ > 0` (rad/s): the fastest the platform's reference heading turns.
    pub rate: T,
    /// `ξ > 0` (rad): the lag below which the filter is linear, with gain `σ/ξ` (1/s).
    pub xi: T,
}

/// All parameters of the law for an arm with `N` joints and a target in the plane
/// ([`Planar`], the default) or in space ([`Spatial`](crate::Spatial)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params<T: Real, const N: usize, S: Space<T> = Planar> {
    /// Joint limits.
    pub joint_limits: JointLimits<T, N>,
    /// The primary task and the arm law (30).
    pub primary: PrimaryTask<T, N, S>,
    /// The secondary task and the platform law (37).
    pub secondary: SecondaryTask<T, N>,
    /// Platform velocity limits, met by one common scale factor.
    pub velocity_limits: VelocityLimits<T>,
    /// The largest period `step` accepts (s), at most [`Params::period_bound`] (validated).
    /// Default: the paper's bound, 0.01.
    pub max_time_step: T,
    /// `κ ∈ (0, 1]`: within one step no joint may cover more than this fraction of its
    /// distance to the limit it moves towards; all joint velocities are divided by one common
    /// factor when one would (a discrete-time guard, see `Diagnostics::joint_scale`). Default
    /// 0.5.
    pub joint_step_fraction: T,
    /// `|q̇ᵢ|` limits (rad/s or m/s), met by the same common factor. Default `+∞` (none).
    pub joint_velocity_limits: SVector<T, N>,
    /// Acceleration limits of the platform's command and of the joints, met by a second
    /// common factor on the change of the command ([`crate::acceleration`]). Default `+∞`
    /// (none: the law is then bit for bit the paper's discretisation).
    pub acceleration_limits: AccelerationLimits<T, N>,
    /// How the law is turned into a held command. Default [`Discretisation::Midpoint`].
    pub discretisation: Discretisation,
    /// How the target's motion is extrapolated. Default [`TargetMotion::Extrapolated`].
    pub target_motion: TargetMotion,
    /// The largest delay `τ` (s) from a measurement to the moment its command takes effect
    /// that `step_delayed` accepts (also at most [`crate::HISTORY`] periods). Default 0.05.
    pub max_delay: T,
    /// The largest angle (rad) that `α` (each component) or the platform's heading may turn
    /// through within one held period: all platform velocities and `α̇` are divided by one
    /// common factor when one would turn more. A sampling bound: `α` is a phase that the
    /// held command advances linearly, and beyond ~½ rad per period the companion frame
    /// `f(α)` and `H̄(α)` change too much over one hold for the law to be meaningful (a far
    /// target at 1 kHz asks for `α̇` of thousands of rad/s). Inactive in the paper's runs
    /// at 1 ms. Default 0.5.
    pub max_turn_per_step: T,
}

/// The paper's four control variants (§4.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PaperRun {
    /// `Ψ = 1`, Choice 1 with (51).
    A,
    /// `Ψ` by (52)–(53), Choice 1 with (40), `ν = 1e−4`.
    B,
    /// As (b) with Choice 2.
    C,
    /// As (b) with Choice 3.
    D,
}

/// A condition the paper's text asks for but that the parameters break, accepted because
/// the paper's own values break it (SPEC §3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Warning {
    /// `δᵢ⁻⁻ ≤ δᵢ` (joint index from 0): `Ψ` saturates inside the penalty band.
    LowerWeightMarginInsidePenalty(u8),
    /// `δᵢ⁺⁺ ≤ δᵢ` (joint index from 0); the paper's q₂ (0.0333 < 0.035).
    UpperWeightMarginInsidePenalty(u8),
}

impl core::fmt::Display for Warning {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Warning::LowerWeightMarginInsidePenalty(j) => {
                write!(f, "joint {}: delta-- <= delta (eq. 52 asks delta < delta--)", j + 1)
            }
            Warning::UpperWeightMarginInsidePenalty(j) => {
                write!(f, "joint {}: delta++ <= delta (eq. 52 asks delta < delta++)", j + 1)
            }
        }
    }
}

impl<T: Real, const N: usize> WeightMargins<T, N> {
    /// The paper's margins: `δ⁻ = 0.2 (q* − q⁻)`, `δ⁺ = 0.2 (q⁺ − q*)`, `δ⁻⁻ = ⅔ δ⁻`,
    /// `δ⁺⁺ = ⅔ δ⁺`; `δ⁻ = δ⁺ = 1` (unused) for a joint without limits.
    pub fn paper(limits: &JointLimits<T, N>, q_star: &SVector<T, N>) -> Self {
        let margin = |i: usize, room: T| if limits.is_unbounded(i) { T::one() } else { room * T::of(0.2) };
        let lower = SVector::from_fn(|i, _| margin(i, q_star[i] - limits.lower[i]));
        let upper = SVector::from_fn(|i, _| margin(i, limits.upper[i] - q_star[i]));
        let two_thirds = T::of(2.0) / T::of(3.0);
        Self { lower, lower_inner: lower * two_thirds, upper, upper_inner: upper * two_thirds }
    }
}

impl<T: Real> Params<T, 3> {
    /// The paper's joint limits for the RPR arm: `q₁ ∈ (−π/3, π/3)`, `q₂ ∈ (0, 0.7)`,
    /// `q₃ ∈ (−π/2, π/2)`.
    pub fn paper_limits() -> JointLimits<T, 3> {
        let pi = T::pi();
        JointLimits {
            lower: SVector::<T, 3>::new(-pi / T::of(3.0), T::zero(), -pi / T::of(2.0)),
            upper: SVector::<T, 3>::new(pi / T::of(3.0), T::of(0.7), pi / T::of(2.0)),
        }
    }

    /// The paper's preferred joint configuration `q_* = (0, 0.45, 0)`.
    pub fn paper_q_star() -> SVector<T, 3> {
        SVector::<T, 3>::new(T::zero(), T::of(0.45), T::zero())
    }

    /// The paper's §4.3 parameters for run (a)–(d), for the RPR arm of
    /// [`Rpr::paper`](crate::Rpr::paper). No velocity limits.
    pub fn paper(run: PaperRun) -> Self {
        let limits = Self::paper_limits();
        let x_star = T::of(0.5);
        let (l, l_e) = (T::of(0.4), T::of(0.15));
        let margins = WeightMargins::paper(&limits, &Self::paper_q_star());
        let filtered = Weight::Filtered { margins, lambda: T::of(1.66), xi: T::one() };
        let (weight, precompensation) = match run {
            PaperRun::A => (Weight::Constant(T::one()), Precompensation::Full51),
            PaperRun::B => (filtered, Precompensation::Full40 { nu: T::of(1e-4) }),
            PaperRun::C => (filtered, Precompensation::Off),
            PaperRun::D => (filtered, Precompensation::Partial),
        };
        let ones = SVector::<T, 3>::repeat(T::one());
        Self {
            joint_limits: limits,
            primary: PrimaryTask {
                target_in_effector: Pose::new(x_star, T::zero(), T::zero()),
                penalty_weight: ones,
                penalty_margin: (limits.upper - limits.lower) * T::of(0.05),
                regularisation_gain: T::of(0.2),
                regularisation_decay: T::one(),
                filter_sigma: T::of(10.0),
                filter_xi: T::one(),
                gain: ones * T::of(3.0),
                null_space_gain: T::one(),
            },
            secondary: SecondaryTask {
                preferred_pose: Pose::new(-(x_star + l_e + l + T::of(0.45)), T::zero(), T::zero()),
                gamma_1: T::one(),
                gamma_2: T::one(),
                rest_sigma: Vector3::repeat(T::of(10.0)),
                rest_xi: T::one(),
                rest_reach: T::of(10.0),
                weight,
                k_bar: Vector3::new(T::one(), T::one(), T::of(100.0)),
                d: Vector3::repeat(T::one()),
                mu: T::of(1e-4),
                precompensation,
                rest_filter: RestFilter::LinearlyImplicit,
                psi_rate_in_drift: false,
                heading_filter: None,
            },
            velocity_limits: VelocityLimits::unlimited(),
            max_time_step: T::of(0.01),
            joint_step_fraction: T::of(0.5),
            joint_velocity_limits: SVector::repeat(T::of(f64::INFINITY)),
            acceleration_limits: AccelerationLimits::unlimited(),
            discretisation: Discretisation::Midpoint,
            target_motion: TargetMotion::Extrapolated,
            max_delay: T::of(0.05),
            max_turn_per_step: T::of(0.5),
        }
    }
}

fn positive_each<T: Real, const N: usize>(
    name: &'static str,
    v: &SVector<T, N>,
    bound: Bound,
) -> Result<(), ParamError> {
    for (i, x) in v.iter().enumerate() {
        check_positive(name, *x, bound).map_err(|e| ParamError::joint(name, i, e.rule))?;
    }
    Ok(())
}

fn finite_pose<T: Real>(name: &'static str, p: &Pose<T>) -> Result<(), ParamError> {
    if !p.is_finite() {
        return Err(ParamError::new(name, Rule::NonFinite));
    }
    for v in [p.x, p.y, p.theta] {
        at_most(name, v, Bound::Length)?;
    }
    Ok(())
}

impl<T: Real, const N: usize> WeightMargins<T, N> {
    fn validate(&self, limits: &JointLimits<T, N>) -> Result<(), ParamError> {
        positive_each("weight.margins.lower", &self.lower, Bound::Length)?;
        positive_each("weight.margins.lower_inner", &self.lower_inner, Bound::Length)?;
        positive_each("weight.margins.upper", &self.upper, Bound::Length)?;
        positive_each("weight.margins.upper_inner", &self.upper_inner, Bound::Length)?;
        for i in 0..N {
            if self.lower_inner[i] >= self.lower[i] {
                return Err(ParamError::joint("weight.margins.lower_inner", i, Rule::WeightMarginOrder));
            }
            if self.upper_inner[i] >= self.upper[i] {
                return Err(ParamError::joint("weight.margins.upper_inner", i, Rule::WeightMarginOrder));
            }
            if self.lower[i] + self.upper[i] >= limits.upper[i] - limits.lower[i] {
                return Err(ParamError::joint("weight.margins.lower", i, Rule::WeightMarginOrder));
            }
        }
        Ok(())
    }
}

impl<T: Real, const N: usize, S: Space<T>> Params<T, N, S> {
    /// Checks every parameter against the rules of the paper (and SPEC §3), and against the
    /// bounds that keep every step computable: lengths and poses within 10³, gains and rates
    /// within 10⁶, times within 1 s, and `max_time_step` within [`period_bound`].
    ///
    /// Parameters are named by their field (`gain`, `filter_sigma`, `weight.lambda`,
    /// `velocity_limits.forward`, ...), as in the runtime's configuration files.
    ///
    /// # Errors
    /// The first parameter that breaks a rule, naming it and the rule.
    ///
    /// [`period_bound`]: Self::period_bound
    pub fn validate(&self) -> Result<(), ParamError> {
        let lim = &self.joint_limits;
        for i in 0..N {
            if lim.is_unbounded(i) {
                continue;
            }
            if !lim.lower[i].finite() {
                return Err(ParamError::joint("joint_limits.lower", i, Rule::NonFinite));
            }
            if !lim.upper[i].finite() {
                return Err(ParamError::joint("joint_limits.upper", i, Rule::NonFinite));
            }
            at_most("joint_limits.lower", lim.lower[i], Bound::Length)
                .and_then(|()| at_most("joint_limits.upper", lim.upper[i], Bound::Length))
                .map_err(|e| ParamError::joint(e.param, i, e.rule))?;
            if lim.lower[i] >= lim.upper[i] {
                return Err(ParamError::joint("joint_limits.lower", i, Rule::EmptyInterval));
            }
        }
        let p = &self.primary;
        S::validate_pose("target_in_effector", &p.target_in_effector)?;
        positive_each("penalty_weight", &p.penalty_weight, Bound::Magnitude)?;
        positive_each("penalty_margin", &p.penalty_margin, Bound::Length)?;
        for i in 0..N {
            if p.penalty_margin[i] * T::of(2.0) >= lim.upper[i] - lim.lower[i] {
                return Err(ParamError::joint("penalty_margin", i, Rule::PenaltyMarginTooWide));
            }
        }
        check_nonneg("regularisation_gain", p.regularisation_gain, Bound::Magnitude)?;
        check_nonneg("regularisation_decay", p.regularisation_decay, Bound::Magnitude)?;
        check_positive("filter_sigma", p.filter_sigma, Bound::Magnitude)?;
        check_positive("filter_xi", p.filter_xi, Bound::Length)?;
        positive_each("gain", &p.gain, Bound::Magnitude)?;
        check_nonneg("null_space_gain", p.null_space_gain, Bound::Magnitude)?;

        let s = &self.secondary;
        finite_pose("preferred_pose", &s.preferred_pose)?;
        check_positive("gamma_1", s.gamma_1, Bound::Magnitude)?;
        check_positive("gamma_2", s.gamma_2, Bound::Magnitude)?;
        positive_each("rest_sigma", &s.rest_sigma, Bound::Magnitude)?;
        check_positive("rest_xi", s.rest_xi, Bound::Length)?;
        check_positive("rest_reach", s.rest_reach, Bound::Length)?;
        match &s.weight {
            Weight::Constant(psi) => {
                if !psi.finite() {
                    return Err(ParamError::new("weight.psi", Rule::NonFinite));
                }
                if *psi < T::zero() || *psi > T::one() {
                    return Err(ParamError::new("weight.psi", Rule::NotInUnitInterval));
                }
            }
            Weight::Filtered { margins, lambda, xi } | Weight::PerJoint { margins, lambda, xi } => {
                margins.validate(lim)?;
                check_positive("weight.lambda", *lambda, Bound::Magnitude)?;
                check_positive("weight.xi", *xi, Bound::Magnitude)?;
            }
            Weight::FromFilteredJoints { margins } => margins.validate(lim)?,
        }
        positive_each("k_bar", &s.k_bar, Bound::Magnitude)?;
        positive_each("d", &s.d, Bound::Magnitude)?;
        check_positive("mu", s.mu, Bound::Magnitude)?;
        match s.precompensation {
            Precompensation::Full40 { nu } => check_positive("precompensation.nu", nu, Bound::Magnitude)?,
            Precompensation::Full51 => {
                if s.weight != Weight::Constant(T::one()) {
                    return Err(ParamError::new("precompensation", Rule::Decomposition51NeedsPsiOne));
                }
            }
            Precompensation::Off | Precompensation::Partial => {}
        }
        if let Some(f) = &s.heading_filter {
            check_positive("heading_rate", f.rate, Bound::Magnitude)?;
            check_positive("heading_xi", f.xi, Bound::Length)?;
        }
        self.velocity_limits.validate()?;
        check_positive("max_time_step", self.max_time_step, Bound::Time)?;
        // (To within rounding: the bound's own f32 rounding must not reject it.)
        if self.max_time_step > self.period_bound() * T::of(1.0 + 1e-6) {
            return Err(ParamError::new("max_time_step", Rule::PeriodTooLong));
        }
        check_nonneg("max_delay", self.max_delay, Bound::Time)?;
        check_positive("max_turn_per_step", self.max_turn_per_step, Bound::Length)?;
        if self.max_turn_per_step > T::pi() {
            return Err(ParamError::new("max_turn_per_step", Rule::TooLarge(Bound::Length)));
        }
        positive("joint_step_fraction", self.joint_step_fraction)?;
        if self.joint_step_fraction > T::one() {
            return Err(ParamError::new("joint_step_fraction", Rule::NotInUnitInterval));
        }
        for i in 0..N {
            let v = self.joint_velocity_limits[i];
            if v.nan() {
                return Err(ParamError::joint("joint_velocity_limits", i, Rule::NonFinite));
            }
            if v <= T::zero() {
                return Err(ParamError::joint("joint_velocity_limits", i, Rule::NotPositive));
            }
        }
        self.acceleration_limits.validate()
    }

    /// The largest admitted control period (s): `0.1 / r_max`, with `r_max` the largest rate
    /// of the law — the arm gains `gᵢ` of (30), the filters' rates `σ/ξ` of (26) and `σᵢ/ξ`
    /// of (28), `λ/ξ` of (53)–(54), and the null-space gain `k_n`. The paper's values give
    /// `r_max = 10/s`: 10 ms.
    ///
    /// Ten periods per fastest time constant is the usual rule for running a continuous
    /// design sampled, and here it is measured rather than assumed. With
    /// [`Discretisation::Midpoint`] no loop is unstable at longer periods — the arm loop, the
    /// stiff platform loops and `α` are advanced linearly implicitly, the car's steering loop
    /// exactly, and the bounded filters by the midpoint rule, stable while `period · rate < 2`
    /// — but the law's discrete closed loop acquires spurious periodic orbits there: from 20
    /// to 40 ms some far targets are never reached (the platform circles with `α` turning at
    /// the turn-per-step bound) and run (b) chatters. Up to 10 ms every paper run on every
    /// platform converges, and so do far targets from 5 to 1 000 m, runs a–d, unicycle and
    /// omnidirectional (`tests/tests/sampled_data.rs`; a Monte Carlo over 480 random far
    /// targets during development, 3 to 1 000 m at any bearing and heading, converged 478).
    pub fn period_bound(&self) -> T {
        let p = &self.primary;
        let s = &self.secondary;
        let mut r = (p.filter_sigma / p.filter_xi).max(p.null_space_gain);
        for i in 0..N {
            r = r.max(p.gain[i]);
        }
        for i in 0..3 {
            r = r.max(s.rest_sigma[i] / s.rest_xi);
        }
        if let Weight::Filtered { lambda, xi, .. } | Weight::PerJoint { lambda, xi, .. } = &s.weight {
            r = r.max(*lambda / *xi);
        }
        if let Some(f) = &s.heading_filter {
            r = r.max(f.rate / f.xi);
        }
        T::of(0.1) / r
    }

    /// Conditions the paper's text asks for that these parameters break but that are
    /// accepted (the paper's own values break one of them, SPEC §3).
    pub fn warnings(&self) -> heapless::Vec<Warning, 16> {
        let mut out = heapless::Vec::new();
        let margins = match &self.secondary.weight {
            Weight::Constant(_) => return out,
            Weight::Filtered { margins, .. }
            | Weight::PerJoint { margins, .. }
            | Weight::FromFilteredJoints { margins } => margins,
        };
        for i in 0..N {
            let d = self.primary.penalty_margin[i];
            let j = i as u8;
            if margins.lower_inner[i] <= d {
                let _ = out.push(Warning::LowerWeightMarginInsidePenalty(j));
            }
            if margins.upper_inner[i] <= d {
                let _ = out.push(Warning::UpperWeightMarginInsidePenalty(j));
            }
        }
        out
    }
}
