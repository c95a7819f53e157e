//! The secondary task and the platform law — §3.3, §3.4.2 and §4.2.
//!
//! ```text
//! h_s1 = ½ d_γ(e, r̄)²,   r̄ = r_*⁻¹ r_d⁻¹ r̄_b                                (49)
//!        aᵀ = (x̃, ỹ, γ sin θ̃) R̄(θ̃),  ∂h_s1/∂t = aᵀ b₁,  b₁ = −Ad_{(r_* r̄)⁻¹} u_d  (51)
//! h_s2 = d_γ(e, r̃_b)²,   r̃_b filtered by (28)                             (27)–(28)
//! h_s  = Ψ h_s1 + (1 − Ψ) h_s2                                               (29)
//! ū_b  = −b̂₁ − (aᵀDa + b̂₂)/(aᵀKa + μ) K a,   K(α) = H̄ K̄ H̄ᵀ                (36)–(37)
//! ```
//!
//! Beyond the paper, the target these see may be the target with its heading filtered
//! ([`HeadingFilter`], [`heading_rates`], [`heading_filtered`]).

use nalgebra::{Matrix3, SVector, Vector3};

use crate::params::{HeadingFilter, WeightMargins};
use crate::scalar::Real;
use crate::se2::{Pose, PoseSc};

/// `h_s1` of eq. (49) with its gradient `a₁` and the drift terms of (51).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackingCost<T> {
    /// `h_s1 = ½ d_γ(e, r̄)²`.
    pub h: T,
    /// `a₁ = (∂h_s1/∂r̄_b)ᵀ` (eq. 33), in the sense of (10).
    pub a: Vector3<T>,
    /// `b₁ = −Ad_{(r_* r̄)⁻¹} u_d`, eq. (51).
    pub b1: Vector3<T>,
    /// `∂h_s1/∂t = a₁ᵀ b₁`.
    pub dh_dt: T,
}

/// Evaluates `h_s1` (49) at `r̄ = r_*⁻¹ r_d⁻¹ r̄_b`, given also `m = r_* r̄ = r_d⁻¹ r̄_b` (the
/// companion frame seen from the target), the target's body velocity `u_d` and `γ`.
#[inline]
pub fn tracking_cost<T: Real>(r_bar: &Pose<T>, m: &Pose<T>, u_d: &Vector3<T>, gamma: T) -> TrackingCost<T> {
    tracking_cost_sc(r_bar, r_bar.theta.sincos(), m, m.theta.sincos(), u_d, gamma)
}

/// [`tracking_cost`] with the sines and cosines of `θ̃` (of `r̄`) and `θ_m` already known.
#[inline]
pub(crate) fn tracking_cost_sc<T: Real>(
    r_bar: &Pose<T>,
    sc_bar: (T, T),
    m: &Pose<T>,
    sc_m: (T, T),
    u_d: &Vector3<T>,
    gamma: T,
) -> TrackingCost<T> {
    let (s, c) = sc_bar;
    let (x, y) = (r_bar.x, r_bar.y);
    let half = T::of(0.5);
    let h = half * (x * x + y * y) + gamma * (T::one() - c);
    let a = Vector3::new(c * x + s * y, -s * x + c * y, gamma * s);
    // Ad_{m⁻¹} = [R(−θ_m)  R(−θ_m) S p_m; 0 1], S p_m = (−y_m, x_m).
    let (sm, cm) = sc_m;
    let (u0, u1, w) = (u_d[0], u_d[1], u_d[2]);
    let px = u0 - m.y * w;
    let py = u1 + m.x * w;
    let b1 = Vector3::new(-(cm * px + sm * py), -(-sm * px + cm * py), -w);
    TrackingCost { h, a, b1, dh_dt: a.dot(&b1) }
}

/// `h_s2` of eq. (27) with its gradient `a₂` and drift, and the rest filter (28).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestCost<T> {
    /// `h_s2 = d_γ(e, r̃_b)²` (no ½, as printed).
    pub h: T,
    /// `a₂ = (∂h_s2/∂r̄_b)ᵀ = −2 [I₂ S p̃_b; 0 1]ᵀ (x̃_b, ỹ_b, γ sin θ̃_b)ᵀ`.
    pub a: Vector3<T>,
    /// `∂h_s2/∂t = 2 (x̃_b, ỹ_b, γ sin θ̃_b) R̄(θ̃_b) û`.
    pub dh_dt: T,
    /// `R̄(θ̃_b) û`: the part of `ṙ̃_b` that does not depend on `ū_b`.
    pub drift: Vector3<T>,
    /// `Q = [I₂ S p̃_b; 0 1]`: `ṙ̃_b = drift − Q ū_b`, eq. (28).
    pub q: Matrix3<T>,
    /// `cos θ̃_b`.
    pub cos_theta: T,
}

/// Evaluates `h_s2` (27) and the filter (28) at `r̃_b` with `(σ₁, σ₂, σ₃)`, `ξ`, `γ`.
#[inline]
pub fn rest_cost<T: Real>(r_tilde: &Pose<T>, sigma: &Vector3<T>, xi: T, gamma: T) -> RestCost<T> {
    let (s, c) = r_tilde.theta.sincos();
    let (x, y, th) = (r_tilde.x, r_tilde.y, r_tilde.theta);
    let two = T::of(2.0);
    let d2 = x * x + y * y + two * gamma * (T::one() - c);
    let k = -T::one() / (xi + d2.square_root());
    let u_hat = Vector3::new(sigma[0] * x * k, sigma[1] * y * k, sigma[2] * th * k);
    let drift = Vector3::new(c * u_hat[0] - s * u_hat[1], s * u_hat[0] + c * u_hat[1], u_hat[2]);
    let g = Vector3::new(x, y, gamma * s);
    let a = Vector3::new(g[0], g[1], -y * g[0] + x * g[1] + g[2]) * (-two);
    let (z, o) = (T::zero(), T::one());
    let q = Matrix3::new(o, z, -y, z, o, x, z, z, o);
    RestCost { h: d2, a, dh_dt: two * g.dot(&drift), drift, q, cos_theta: c }
}

/// `σ̃ᵢ(qᵢ)` of eq. (52) for joint `i` (SPEC §3's reading), with its derivative:
/// 1 within `δᵢ⁻⁻` of the lower limit (`δᵢ⁺⁺` of the upper), 0 farther than `δᵢ⁻`
/// (`δᵢ⁺`), linear in between.
#[inline]
pub fn sigma_tilde_joint<T: Real, const N: usize>(
    q: T,
    lower: T,
    upper: T,
    m: &WeightMargins<T, N>,
    i: usize,
) -> (T, T) {
    sigma_tilde_band(q, lower, upper, m.lower[i], m.lower_inner[i], m.upper[i], m.upper_inner[i])
}

/// `σ̃` of (52) for a coordinate `q` with limits `[lo, hi]` and margins `δ⁻` (`dm`), `δ⁻⁻`
/// (`dmm`), `δ⁺` (`dp`), `δ⁺⁺` (`dpp`), with its derivative.
#[inline]
pub(crate) fn sigma_tilde_band<T: Real>(q: T, lo: T, hi: T, dm: T, dmm: T, dp: T, dpp: T) -> (T, T) {
    let (z, o) = (T::zero(), T::one());
    if q <= lo + dmm || q >= hi - dpp {
        (o, z)
    } else if q < lo + dm {
        let w = o / (dm - dmm);
        ((lo + dm - q) * w, -w)
    } else if q > hi - dp {
        let w = o / (dp - dpp);
        ((q - (hi - dp)) * w, w)
    } else {
        (z, z)
    }
}

/// `Ψ̃(q) = (1/n) Σ σ̃ᵢ(qᵢ)²`, eq. (52), with its gradient.
#[inline]
pub fn psi_tilde<T: Real, const N: usize>(
    q: &SVector<T, N>,
    lower: &SVector<T, N>,
    upper: &SVector<T, N>,
    m: &WeightMargins<T, N>,
) -> (T, SVector<T, N>) {
    let inv_n = T::one() / T::of(N as f64);
    let two = T::of(2.0);
    let mut psi = T::zero();
    let mut grad = SVector::<T, N>::zeros();
    for i in 0..N {
        let (s, ds) = sigma_tilde_joint(q[i], lower[i], upper[i], m, i);
        psi += s * s * inv_n;
        grad[i] = two * s * ds * inv_n;
    }
    (psi, grad)
}

/// `Ψ̃(q)` of eq. (52) without its gradient.
#[inline]
pub fn psi_tilde_value<T: Real, const N: usize>(
    q: &SVector<T, N>,
    lower: &SVector<T, N>,
    upper: &SVector<T, N>,
    m: &WeightMargins<T, N>,
) -> T {
    let mut psi = T::zero();
    for i in 0..N {
        let (s, _) = sigma_tilde_joint(q[i], lower[i], upper[i], m, i);
        psi += s * s;
    }
    psi / T::of(N as f64)
}

/// How many terms an arm may add to `Ψ̃` ([`ArmTerms`]).
pub const ARM_TERMS: usize = 3;

/// The terms an arm adds to `Ψ̃` beyond its joints' `σ̃ᵢ` — a spatial arm's reach
/// ([`crate::reach`]): `σ̃ₖ ∈ [0, 1]` with their gradients in `q`, and how they enter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArmTerms<T, const N: usize> {
    /// The `σ̃ₖ`.
    pub sigma: [T; ARM_TERMS],
    /// `∂σ̃ₖ/∂q` (zero where only the values were asked for).
    pub gradient: [SVector<T, N>; ARM_TERMS],
    /// How they enter `Ψ̃`.
    pub rule: TermRule,
}

/// How an arm's terms enter `Ψ̃` with its joints' `σ̃ᵢ` (see [`psi_with_terms`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TermRule {
    /// The largest of all: `Ψ̃ = max(maxᵢ σ̃ᵢ², maxₖ σ̃ₖ²)`. The default.
    Max,
    /// Averaged, as (52) averages the joints: `Ψ̃ = (Σᵢ σ̃ᵢ² + Σₖ σ̃ₖ²)/(N + K)`.
    Mean,
}

/// `Ψ̃` from the joints' `σ̃ᵢ` and an arm's terms, by their rule, with `∂Ψ̃/∂σ̃ᵢ` and the
/// terms' part of its gradient in `q`: `∂Ψ̃/∂qᵢ = ∂Ψ̃/∂σ̃ᵢ ∂σ̃ᵢ/∂qᵢ + (the third)ᵢ`. At a tie
/// the max takes the first (the joints in order, then the terms): its gradient is that
/// term's.
#[inline]
pub fn psi_with_terms<T: Real, const N: usize>(
    sigma: &SVector<T, N>,
    terms: &ArmTerms<T, N>,
) -> (T, SVector<T, N>, SVector<T, N>) {
    let two = T::of(2.0);
    match terms.rule {
        TermRule::Mean => {
            let inv = T::one() / T::of((N + ARM_TERMS) as f64);
            let (mut sum, mut grad) = (sigma.dot(sigma), SVector::<T, N>::zeros());
            for k in 0..ARM_TERMS {
                let s = terms.sigma[k];
                sum += s * s;
                grad += terms.gradient[k] * (two * s);
            }
            (sum * inv, sigma * (two * inv), grad * inv)
        }
        TermRule::Max => {
            let (mut best, mut joint) = (T::zero(), 0usize);
            for i in 0..N {
                if sigma[i] * sigma[i] > best {
                    (best, joint) = (sigma[i] * sigma[i], i);
                }
            }
            let mut term = None;
            for k in 0..ARM_TERMS {
                let s = terms.sigma[k];
                if s * s > best {
                    (best, term) = (s * s, Some(k));
                }
            }
            let mut d = SVector::<T, N>::zeros();
            match term {
                Some(k) => (best, d, terms.gradient[k] * (two * terms.sigma[k])),
                None => {
                    d[joint] = two * sigma[joint];
                    (best, d, SVector::zeros())
                }
            }
        }
    }
}

/// `σ̃ᵢ(qᵢ)` of (52) for every joint, with `dσ̃ᵢ/dqᵢ`.
#[inline]
pub fn sigma_tildes<T: Real, const N: usize>(
    q: &SVector<T, N>,
    lower: &SVector<T, N>,
    upper: &SVector<T, N>,
    m: &WeightMargins<T, N>,
) -> (SVector<T, N>, SVector<T, N>) {
    let mut s = SVector::<T, N>::zeros();
    let mut ds = SVector::<T, N>::zeros();
    for i in 0..N {
        (s[i], ds[i]) = sigma_tilde_joint(q[i], lower[i], upper[i], m, i);
    }
    (s, ds)
}

/// The rate of the bounded filters (26), (53), (54): `−λ (x − x̃)/(ξ + |x − x̃|)`.
#[inline]
pub fn bounded_filter_rate<T: Real>(x: T, target: T, lambda: T, xi: T) -> T {
    let d = x - target;
    -lambda * d / (xi + d.abs())
}

/// The heading filter's rates ([`HeadingFilter`]) at lag `δ`, for a target turning at `ω_d`:
/// the reference heading's `θ̂̇_d = σ δ/(ξ + |δ|)` and the lag's `δ̇ = ω_d − θ̂̇_d`.
#[inline]
pub fn heading_rates<T: Real>(lag: T, omega_d: T, f: &HeadingFilter<T>) -> (T, T) {
    let turn = f.rate * lag / (f.xi + lag.abs());
    (turn, omega_d - turn)
}

/// The target as the platform's law sees it through the heading filter ([`HeadingFilter`]):
/// seen from the base `r̂_bd = r_bd Rot(−δ)`, moving at `û_d = (R(δ) (u_d,x, u_d,y), θ̂̇_d)`.
#[inline]
pub fn heading_filtered<T: Real>(
    r_bd: &PoseSc<T>,
    u_d: &Vector3<T>,
    lag: T,
    turn: T,
) -> (PoseSc<T>, Vector3<T>) {
    let (s, c) = lag.sincos();
    let rot = PoseSc { pose: Pose::new(T::zero(), T::zero(), -lag), sc: (-s, c) };
    (r_bd.compose(&rot), Vector3::new(c * u_d[0] - s * u_d[1], s * u_d[0] + c * u_d[1], turn))
}
