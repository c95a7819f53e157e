//! Parameters of the law, validated once when a [`ControlLaw`](crate::ControlLaw) is
//! built, and the paper's §4.3 preset.

use nalgebra::{SVector, Vector3};

use crate::error::{ParamError, Rule};
use crate::platform::{positive, VelocityLimits};
use crate::scalar::Real;
use crate::se2::Pose;

/// Joint limits `q⁻ < q⁺` (rad for revolute joints, m for prismatic ones).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointLimits<T, const N: usize> {
    /// Lower limits `q⁻`.
    pub lower: SVector<T, N>,
    /// Upper limits `q⁺`.
    pub upper: SVector<T, N>,
}

/// The primary (manipulation) task: `e_p` (42), the joint-limit penalty `h_ℓ` (20)–(21),
/// the regularisation `h_r` (22) with the filter (26), and the gain `G` of (30).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimaryTask<T, const N: usize> {
    /// `r*_ed`: the target's desired pose seen from the end effector (m, m, rad). The paper
    /// uses `(X*, 0, 0)` with `X* = 0.5 m`.
    pub target_in_effector: Pose<T>,
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
    /// i.e. `G = −3 I₃`, so that `ė_m = G e_m` converges.
    pub gain: SVector<T, N>,
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
    None,
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
}

/// All parameters of the law for an arm with `N` joints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params<T, const N: usize> {
    /// Joint limits.
    pub joint_limits: JointLimits<T, N>,
    /// The primary task and the arm law (30).
    pub primary: PrimaryTask<T, N>,
    /// The secondary task and the platform law (37).
    pub secondary: SecondaryTask<T, N>,
    /// Platform velocity limits, met by one common scale factor.
    pub velocity_limits: VelocityLimits<T>,
    /// The largest time step `step` accepts (s). Default 0.1.
    pub max_time_step: T,
    /// `κ ∈ (0, 1]`: within one step no joint may cover more than this fraction of its
    /// distance to the limit it moves towards; all joint velocities are divided by one common
    /// factor when one would (a discrete-time guard, see `Diagnostics::joint_scale`). Default
    /// 0.5.
    pub joint_step_fraction: T,
    /// `|q̇ᵢ|` limits (rad/s or m/s), met by the same common factor. Default `+∞` (none).
    pub joint_velocity_limits: SVector<T, N>,
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

impl<T: Real> WeightMargins<T, 3> {
    /// The paper's margins: `δ⁻ = 0.2 (q* − q⁻)`, `δ⁺ = 0.2 (q⁺ − q*)`, `δ⁻⁻ = ⅔ δ⁻`,
    /// `δ⁺⁺ = ⅔ δ⁺`.
    pub fn paper(limits: &JointLimits<T, 3>, q_star: &SVector<T, 3>) -> Self {
        let lower = (q_star - limits.lower) * T::of(0.2);
        let upper = (limits.upper - q_star) * T::of(0.2);
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
            PaperRun::C => (filtered, Precompensation::None),
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
            },
            secondary: SecondaryTask {
                preferred_pose: Pose::new(-(x_star + l_e + l + T::of(0.45)), T::zero(), T::zero()),
                gamma_1: T::one(),
                gamma_2: T::one(),
                rest_sigma: Vector3::repeat(T::of(10.0)),
                rest_xi: T::one(),
                weight,
                k_bar: Vector3::new(T::one(), T::one(), T::of(100.0)),
                d: Vector3::repeat(T::one()),
                mu: T::of(1e-4),
                precompensation,
                rest_filter: RestFilter::LinearlyImplicit,
                psi_rate_in_drift: false,
            },
            velocity_limits: VelocityLimits::unlimited(),
            max_time_step: T::of(0.1),
            joint_step_fraction: T::of(0.5),
            joint_velocity_limits: SVector::repeat(T::of(f64::INFINITY)),
        }
    }
}

fn nonneg<T: Real>(name: &'static str, v: T) -> Result<(), ParamError> {
    if !v.finite() {
        Err(ParamError::new(name, Rule::NonFinite))
    } else if v < T::zero() {
        Err(ParamError::new(name, Rule::Negative))
    } else {
        Ok(())
    }
}

fn positive_each<T: Real, const N: usize>(name: &'static str, v: &SVector<T, N>) -> Result<(), ParamError> {
    for (i, x) in v.iter().enumerate() {
        positive(name, *x).map_err(|e| ParamError::joint(name, i, e.rule))?;
    }
    Ok(())
}

fn finite_pose<T: Real>(name: &'static str, p: &Pose<T>) -> Result<(), ParamError> {
    if p.is_finite() {
        Ok(())
    } else {
        Err(ParamError::new(name, Rule::NonFinite))
    }
}

impl<T: Real, const N: usize> WeightMargins<T, N> {
    fn validate(&self, limits: &JointLimits<T, N>) -> Result<(), ParamError> {
        positive_each("delta_minus", &self.lower)?;
        positive_each("delta_minus_minus", &self.lower_inner)?;
        positive_each("delta_plus", &self.upper)?;
        positive_each("delta_plus_plus", &self.upper_inner)?;
        for i in 0..N {
            if self.lower_inner[i] >= self.lower[i] {
                return Err(ParamError::joint("delta_minus_minus", i, Rule::WeightMarginOrder));
            }
            if self.upper_inner[i] >= self.upper[i] {
                return Err(ParamError::joint("delta_plus_plus", i, Rule::WeightMarginOrder));
            }
            if self.lower[i] + self.upper[i] >= limits.upper[i] - limits.lower[i] {
                return Err(ParamError::joint("delta_minus", i, Rule::WeightMarginOrder));
            }
        }
        Ok(())
    }
}

impl<T: Real, const N: usize> Params<T, N> {
    /// Checks every parameter against the rules of the paper (and SPEC §3).
    ///
    /// # Errors
    /// The first parameter that breaks a rule, naming it and the rule.
    pub fn validate(&self) -> Result<(), ParamError> {
        let lim = &self.joint_limits;
        for i in 0..N {
            if !lim.lower[i].finite() {
                return Err(ParamError::joint("q_min", i, Rule::NonFinite));
            }
            if !lim.upper[i].finite() {
                return Err(ParamError::joint("q_max", i, Rule::NonFinite));
            }
            if lim.lower[i] >= lim.upper[i] {
                return Err(ParamError::joint("q_min", i, Rule::EmptyInterval));
            }
        }
        let p = &self.primary;
        finite_pose("r_ed_star", &p.target_in_effector)?;
        positive_each("alpha_i", &p.penalty_weight)?;
        positive_each("delta_i", &p.penalty_margin)?;
        for i in 0..N {
            if p.penalty_margin[i] * T::of(2.0) >= lim.upper[i] - lim.lower[i] {
                return Err(ParamError::joint("delta_i", i, Rule::PenaltyMarginTooWide));
            }
        }
        nonneg("gamma_0", p.regularisation_gain)?;
        nonneg("gamma_decay", p.regularisation_decay)?;
        positive("sigma_qhat", p.filter_sigma)?;
        positive("xi_qhat", p.filter_xi)?;
        positive_each("G_gain", &p.gain)?;

        let s = &self.secondary;
        finite_pose("r_star", &s.preferred_pose)?;
        positive("gamma_1", s.gamma_1)?;
        positive("gamma_2", s.gamma_2)?;
        positive_each("sigma_rest", &s.rest_sigma)?;
        positive("xi_rest", s.rest_xi)?;
        match &s.weight {
            Weight::Constant(psi) => {
                if !psi.finite() {
                    return Err(ParamError::new("psi", Rule::NonFinite));
                }
                if *psi < T::zero() || *psi > T::one() {
                    return Err(ParamError::new("psi", Rule::NotInUnitInterval));
                }
            }
            Weight::Filtered { margins, lambda, xi } | Weight::PerJoint { margins, lambda, xi } => {
                margins.validate(lim)?;
                positive("lambda", *lambda)?;
                positive("xi_psi", *xi)?;
            }
            Weight::FromFilteredJoints { margins } => margins.validate(lim)?,
        }
        positive_each("K_bar", &s.k_bar)?;
        positive_each("D", &s.d)?;
        positive("mu", s.mu)?;
        match s.precompensation {
            Precompensation::Full40 { nu } => positive("nu", nu)?,
            Precompensation::Full51 => {
                if s.weight != Weight::Constant(T::one()) {
                    return Err(ParamError::new("precompensation", Rule::Decomposition51NeedsPsiOne));
                }
            }
            Precompensation::None | Precompensation::Partial => {}
        }
        self.velocity_limits.validate()?;
        positive("max_time_step", self.max_time_step)?;
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
        Ok(())
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
            #[allow(clippy::cast_possible_truncation)]
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
