//! The platform law — §3.4.2, §4.2, §5 — as one phase of a step.
//!
//! ```text
//! r̄   = r_*⁻¹ r_d⁻¹ r̄_b,   r̄_b = r_b f(α)⁻¹                                   (11), (49)
//! a    = Ψ a₁ + (1 − Ψ) a₂,  ∂h_s/∂t = Ψ a₁ᵀb₁ + (1 − Ψ) ∂h_s2/∂t               (29), (51)
//! ū_b  = −b̂₁ − (aᵀDa + b̂₂)/(aᵀKa + μ) K a,   K = H̄ K̄ H̄ᵀ                      (36)–(37)
//! w    = H̄(α)⁻¹ ū_b   (unicycle (v, ω, α̇); car (v, α̇₁, α̇₂); omni (v₁, v₂, ω))   (14), (60)
//! v_ξ  = ξ̇_f(α) − k_h (ξ − ξ_f(α)),  k_h = (1 − e^{−k h})/h                    (59)
//! ```
//!
//! **Linearly implicit over the hold.** `ū_e` is (37) at the state predicted with the
//! previous command as a guess (`ū_g`); the law at the point reached after `θh` with the new
//! command is, to first order in the companion frame's displacement `δ` (body coordinates;
//! `θh` becomes the matrix weight below),
//!
//! ```text
//! ū = ū_e + J (θh ū − h/2 ū_g) + (θh − h/2) G_a (D₁ b₁ + D₂ ρ)
//! J  = G_a (D₁ − D₂ Q),   G_a = ∂ū/∂a = −∂b̂₁/∂a − K a (∂coef/∂a)ᵀ − coef K
//! D₁ = Ψ ∂a₁/∂δ = Ψ (diag(1, 1, γ cos θ̃) + [0 0 a₁,y; 0 0 −a₁,x; 0 0 0])
//! D₂ = (1 − Ψ) ∂a₂/∂r̃_b = −2 (1 − Ψ) diag(1, 1, γ cos θ̃_b),   ṙ̃_b = ρ − Q ū     (28)
//! ```
//!
//! (`b₁` of (51) is the drift of `r̄` due to the target, `ρ = R̄(θ̃_b) û` that of `r̃_b`).
//! Solved as one 3×3 system `M ū = ū_e − h/2 J ū_g + (a h − h/2) G_a (D₁ b₁ + D₂ ρ)` with
//!
//! ```text
//! M = I − a hJ + b (hJ)²,    z = h‖J‖∞,    θ(z) = 1/(1 − e^{−z}) − 1/z
//! z ≤ z* ≈ 4.8:  a = ½,      b = (θ(z) − ½)/z          (→ 1/12 as z → 0)
//! z > z*:        a = 1 − s,  b = s²/4,  s = 2 (1 + √(z/(e^z − 1)))/z
//! ```
//!
//! **Why this step, and its local error.** Over one hold a mode `y′ = −μy` of the linearised
//! loop (`x = μh`, `0 ≤ x ≤ z`) is advanced by `R(x) = (1 − (1 − a)x + b x²)/(1 + a x + b x²)`;
//! the continuous law gives `e^{−x}`. With `a = ½` the step is second order, and with
//! `b = 1/12` it is the (2,2) Padé approximant, `R(x) − e^{−x} = x⁵/720 + O(x⁶)` — so the
//! slow modes, which carry the trajectory, are followed to fifth order in `x` whatever the
//! stiffest mode does (a scalar weight `I − θhJ` gives them `(θ − ½) x²` instead, first
//! order in `h` once `θ` moves away from ½). `b(z)` makes the step exact for the mode at
//! `x = z` (the one `‖J‖∞` bounds), and `b ≥ 1/16` keeps `R ≥ 0`: no mode rings at the
//! Nyquist frequency. Where `b` would fall below 1/16 (`z > z*`) the second branch keeps both
//! (exact at `x = z`, numerator `(1 − s x/2)² ≥ 0`) and tends to implicit Euler as `z` grows
//! (`a → 1`, `b → 0`, `R(z) = e^{−z}`), which damps the stiff modes: the rest filter's gain
//! reaches 2·10³/s with `K̄ = diag(1, 1, 100)`, the pre-compensation (40) `1/ν = 10⁴/s` near
//! `a = 0`. Measured against the continuous closed loop (`companion-tests`' `pointwise`:
//! RK4 at 10⁻⁵ s), the largest difference of `x_b, y_b, θ_b, q` over the first 10 s at 1 ms
//! fell from 2.85·10⁻² to 3.8·10⁻³ (T1 a), 3.9·10⁻² to 5.3·10⁻³ (T2 a) and 1.2·10⁻² to
//! 2.4·10⁻³ (T1 c), second order (÷3.9 per halving), the floors unchanged; the scalar weight
//! `θ(z)` alone (exact for the mode at `z` only) reached 8·10⁻³, 1.1·10⁻² and 3.3·10⁻³, the
//! earlier `θ = ½ + ½ z/(1 + z)` the figures above. The unicycle's `α` step with the same
//! weights (`alpha_step_one`) brought them to 3.05·10⁻³, 4.08·10⁻³ and 2.36·10⁻³ (÷4.0).
//! Below `z = ½`, `b` is taken from its series (the closed form cancels; in `f32` completely
//! below `z ≈ 10⁻³`).
//! `a` and `b` are scaled down (towards the explicit step) if `det M < ½`, which happens
//! only when the pre-compensation makes a mode unstable (`∂h_s/∂t < 0` in (40)) — then
//! growth is the continuous law's own.
//! [`Discretisation::Sampled`] keeps the earlier treatment:
//! only the rest filter, `θ = 1`, from the measured state ([`RestFilter`]).
//!
//! **One common saturation factor** (end of §3.4.2) `ρ ∈ (0, 1]` multiplies `w`, `ū_b` and
//! the feed-forward of `v_ξ`: the smallest of `limit/|component|` over the velocity limits,
//! `φ_max/(h |rate|)` over the rates of `α` and of the heading (the turn-per-step bound,
//! [`Params::max_turn_per_step`](crate::Params::max_turn_per_step)), and for the car the
//! factor that keeps `|v_ξ|` within its limit. Computed as a ratio `limit/|x|`, it never
//! overflows: an enormous command is scaled to the limit, not zeroed. The steering's
//! feedback `−k_h (ξ − ξ_f)` is not scaled (it is not a velocity of the companion frame); if
//! it alone exceeds the steering limit the platform waits (`ρ = 0`) while the wheels turn
//! at their limit.

use nalgebra::{Matrix3, Vector2, Vector3};

use crate::params::{Discretisation, Params, Precompensation, RestFilter};
use crate::platform::{CompanionFrame, Platform, PlatformKind};
use crate::scalar::Real;
use crate::se2::{inverse3, PoseSc};
use crate::secondary::{tracking_cost_sc, RestCost};
use crate::space::Space;

/// Where the platform law is evaluated.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PlatformPoint<'a, T> {
    /// The target seen from the base.
    pub r_bd: &'a PoseSc<T>,
    /// The companion frame at `α`.
    pub frame: &'a CompanionFrame<T>,
    /// The target's body velocity.
    pub u_d: &'a Vector3<T>,
    /// The weight `Ψ` and its rate.
    pub psi: T,
    /// `Ψ̇`.
    pub psi_rate: T,
    /// The rest filter's cost at `r̃_b` (when `Ψ ≢ 1`).
    pub rest: Option<&'a RestCost<T>>,
    /// Car-like: the steering error `ξ − ξ_f(α)` when the command starts to act.
    pub xi_error: T,
    /// Car-like: the steering state when the command starts to act (for the heading rate).
    pub xi: T,
}

/// The hold the command is computed for.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Hold<T> {
    /// The period `h` (s).
    pub period: T,
    /// How far into the hold the point is (`h/2` for the midpoint, 0 for `Sampled`).
    pub half: T,
    /// The previous command's `ū_b` (the guess the point was predicted with).
    pub guess_u_bar: Vector3<T>,
    /// The previous command's generalised inputs `w` (its `α̇` is the guess of `α`).
    pub guess_w: Vector3<T>,
}

/// The platform part of a step.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PlatformStep<T> {
    /// Generalised inputs `w` (after saturation).
    pub w: Vector3<T>,
    /// `ū_b = H̄ w` commanded (after saturation).
    pub u_bar: Vector3<T>,
    /// The companion frame's actual velocity: `ū_b` plus, for the car, the part
    /// `[I −S p_f; 0 1] (0, 0, v (ξ − ξ_f))` of (57) (drives the rest filter).
    pub u_bar_actual: Vector3<T>,
    /// The car's steering rate (0 otherwise).
    pub v_xi: T,
    /// `1/ρ ≥ 1`, finite.
    pub saturation: T,
    /// The implicit weight `a` of the step (module docs; 1 for `Sampled`'s rest filter, 0 when
    /// explicit).
    pub theta: T,
    /// `h_s`, `h_s1`, `h_s2`.
    pub h_s: T,
    /// `h_s1`.
    pub h_s1: T,
    /// `h_s2`.
    pub h_s2: T,
    /// `f(α)⁻¹`.
    pub f_inv: PoseSc<T>,
}

/// The platform law of a [`ControlLaw`](crate::ControlLaw): its parameters, its platform and
/// the constant `r_*⁻¹` (borrowed for one step). It reads only the space-independent
/// parameters: the platform works on the target's projection on the plane.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PlatformLaw<'a, T: Real, P, const N: usize, S: Space<T>> {
    pub params: &'a Params<T, N, S>,
    pub platform: &'a P,
    pub r_star_inv: &'a PoseSc<T>,
}

/// The largest saturation factor reported (the platform stopped).
const STOPPED: f64 = 3.0e38;

impl<T: Real, P: Platform<T>, const N: usize, S: Space<T>> PlatformLaw<'_, T, P, N, S> {
    /// (37) at `pt`, corrected over the hold, mapped to the platform's inputs and saturated.
    #[inline(always)]
    pub(crate) fn platform_step(&self, pt: &PlatformPoint<'_, T>, hold: &Hold<T>) -> PlatformStep<T> {
        let sec = &self.params.secondary;
        let frame = pt.frame;
        let (sf, cf) = frame.sin_cos_theta_f;
        let f_inv = PoseSc { pose: frame.f.inverse_sc(sf, cf), sc: (-sf, cf) };
        // m = r_d⁻¹ r̄_b = r_db f(α)⁻¹ (the companion frame seen from the target), r̄ = r_*⁻¹ m.
        let m = pt.r_bd.inverse().compose(&f_inv);
        let r_bar = self.r_star_inv.compose(&m);
        let track = tracking_cost_sc(&r_bar.pose, r_bar.sc, &m.pose, m.sc, pt.u_d, sec.gamma_1);

        // The secondary cost (29): h_s1 always; h_s2 with the rest filter unless Ψ ≡ 1.
        let psi = pt.psi;
        let (h_s, a, dh_dt, h_s2) = match pt.rest {
            Some(rest) => {
                let one_m = T::one() - psi;
                let mut dh = psi * track.dh_dt + one_m * rest.dh_dt;
                if sec.psi_rate_in_drift {
                    dh += pt.psi_rate * (track.h - rest.h);
                }
                (psi * track.h + one_m * rest.h, track.a * psi + rest.a * one_m, dh, rest.h)
            }
            None => (track.h, track.a, track.dh_dt, T::zero()),
        };

        // Pre-compensation (b̂₁, b̂₂).
        let zero3 = Vector3::zeros();
        let (b1, b2) = match sec.precompensation {
            Precompensation::Full51 => (track.b1, T::zero()),
            Precompensation::Full40 { nu } => {
                let n = T::one() / (a.dot(&a) + nu);
                (a * (dh_dt * n), dh_dt * nu * n)
            }
            Precompensation::Off => (zero3, T::zero()),
            Precompensation::Partial => (zero3, dh_dt),
        };

        // (37) with K = H̄ K̄ H̄ᵀ (36): K a = H̄ (K̄ ∘ H̄ᵀa).
        let hbar = &frame.hbar;
        let z = hbar.transpose() * a;
        let kz = z.component_mul(&sec.k_bar);
        let denom = z.dot(&kz) + sec.mu;
        let coef = (a.component_mul(&sec.d).dot(&a) + b2) / denom;
        let k_a = hbar * kz;
        let u_e = -(k_a * coef) - b1;

        let lin =
            Linearisation { a: &a, k_a: &k_a, coef, denom, dh_dt, track_a: &track.a, track_b1: &track.b1 };
        let (u_bar, theta) = self.implicit_correction(pt, hold, &lin, u_e, r_bar.sc.1);
        let mut w = frame.hbar_inv * u_bar;
        if hold.half > T::zero() && P::ALPHA_DIM > 0 {
            w = self.implicit_alpha(frame, w, hold);
        }

        // The car's steering (59), exact over the hold for the feedback part.
        let (fb, ff) = if P::KIND == PlatformKind::Car {
            let k = self.platform.steering_gain();
            let kh = if hold.half > T::zero() && k * hold.period > T::zero() {
                (T::one() - (-k * hold.period).exponential()) / hold.period
            } else {
                k
            };
            (-kh * pt.xi_error, frame.dxi_f.dot(&P::alpha_rate(&w)))
        } else {
            (T::zero(), T::zero())
        };

        // One common factor ρ ∈ [0, 1], as ratios that cannot overflow.
        let prm = &self.params;
        let mut rho = P::saturation_scale(&prm.velocity_limits, &w);
        let turn = P::max_turn_rate(&w, pt.xi) * hold.period;
        if turn > prm.max_turn_per_step {
            rho = rho.min(prm.max_turn_per_step / turn);
        }
        let lim_xi = prm.velocity_limits.steering_rate;
        let mut v_xi = fb + ff;
        if P::KIND == PlatformKind::Car && v_xi.abs() > lim_xi {
            // The smallest scaling of the feed-forward that puts |fb + ρ ff| on the limit:
            // ff along fb leaves L − |fb| for it, against fb L + |fb|.
            let same_sign = fb * ff >= T::zero();
            if same_sign && fb.abs() >= lim_xi {
                rho = T::zero();
            } else {
                let room = if same_sign { lim_xi - fb.abs() } else { lim_xi + fb.abs() };
                rho = rho.min(room / ff.abs());
            }
        }
        w *= rho;
        let u_bar = u_bar * rho;
        if P::KIND == PlatformKind::Car {
            v_xi = fb + ff * rho;
            if v_xi.abs() > lim_xi {
                v_xi = if v_xi > T::zero() { lim_xi } else { -lim_xi };
            }
        }
        let saturation = if rho > T::of(1.0 / STOPPED) { T::one() / rho } else { T::of(STOPPED) };

        // The car's companion frame also moves with v (ξ − ξ_f) (57); mean error over the hold.
        let u_bar_actual = if P::KIND == PlatformKind::Car {
            let e_mid = pt.xi_error + fb * hold.half;
            let c = w[0] * e_mid;
            let (px, py) = (frame.f.x, frame.f.y);
            u_bar + Vector3::new(py * c, -px * c, c)
        } else {
            u_bar
        };
        PlatformStep { w, u_bar, u_bar_actual, v_xi, saturation, theta, h_s, h_s1: track.h, h_s2, f_inv }
    }

    /// `ū` from `ū_e` by the linearly implicit step of the module docs; returns `(ū, θ)`.
    #[inline(always)]
    fn implicit_correction(
        &self,
        pt: &PlatformPoint<'_, T>,
        hold: &Hold<T>,
        lin: &Linearisation<'_, T>,
        u_e: Vector3<T>,
        cos_r_bar: T,
    ) -> (Vector3<T>, T) {
        let sec = &self.params.secondary;
        let midpoint = self.params.discretisation == Discretisation::Midpoint;
        if !midpoint && (pt.rest.is_none() || sec.rest_filter == RestFilter::Explicit) {
            return (u_e, T::zero());
        }
        let two = T::of(2.0);
        let (a, k_a, coef, denom) = (lin.a, lin.k_a, lin.coef, lin.denom);
        let hk = Matrix3::from_fn(|r, c| pt.frame.hbar[(r, c)] * sec.k_bar[c]);
        let k = hk * pt.frame.hbar.transpose();

        // G_a = ∂ū/∂a.
        let mut dcoef = (a.component_mul(&sec.d) - k_a * coef) * (two / denom);
        let mut db1 = Matrix3::zeros();
        if midpoint {
            if let Precompensation::Full40 { nu } = sec.precompensation {
                let mm = T::one() / (a.dot(a) + nu);
                db1 = (Matrix3::identity() - a * a.transpose() * (two * mm)) * (lin.dh_dt * mm);
                dcoef -= a * (two * lin.dh_dt * nu * mm * mm / denom);
            }
        }
        let g_a = -db1 - k_a * dcoef.transpose() - k * coef;

        // D₁ (tracking, midpoint only) and D₂ (rest filter) with Q.
        let psi = pt.psi;
        let mut d1 = Matrix3::zeros();
        if midpoint {
            let ta = lin.track_a;
            d1 = Matrix3::new(
                T::one(),
                T::zero(),
                ta[1],
                T::zero(),
                T::one(),
                -ta[0],
                T::zero(),
                T::zero(),
                sec.gamma_1 * cos_r_bar,
            ) * psi;
        }
        let mut d_disp = d1;
        let mut drift_term = d1 * lin.track_b1;
        if let Some(rest) = pt.rest {
            let s = -two * (T::one() - psi);
            let d2 = Vector3::new(s, s, s * sec.gamma_2 * rest.cos_theta);
            // D₁ − D₂ Q, with D₂ diagonal.
            for r in 0..3 {
                for c in 0..3 {
                    d_disp[(r, c)] -= d2[r] * rest.q[(r, c)];
                }
            }
            drift_term += rest.drift.component_mul(&d2);
        }
        let j = g_a * d_disp;
        let (h, half) = (hold.period, hold.half);
        let (mut theta, mut square) = (T::one(), T::zero());
        if midpoint {
            let mut norm = T::zero();
            for r in 0..3 {
                let row = j[(r, 0)].abs() + j[(r, 1)].abs() + j[(r, 2)].abs();
                if row > norm {
                    norm = row;
                }
            }
            (theta, square) = stiffness_weights(h * norm);
        }
        let base = u_e - j * hold.guess_u_bar * half;
        let jh = j * h;
        let jh2 = if square > T::zero() { jh * jh } else { Matrix3::zeros() };
        for _ in 0..4 {
            let m = Matrix3::identity() - jh * theta + jh2 * square;
            if let Some((inv, det)) = inverse3(&m) {
                // (`Sampled` keeps the earlier rest-filter step as it was: any invertible M.)
                if det >= T::of(0.5) || !midpoint {
                    let rhs = base + g_a * drift_term * (theta * h - half);
                    return (inv * rhs, theta);
                }
            }
            theta *= T::of(0.5);
            square *= T::of(0.25);
        }
        (u_e, T::zero())
    }
}

impl<T: Real, P: Platform<T>, const N: usize, S: Space<T>> PlatformLaw<'_, T, P, N, S> {
    /// `w = H̄(α)⁻¹ ū` with `α` advanced linearly implicitly over the hold: `H̄⁻¹` was taken
    /// at `α_e = α + h/2 α̇_g` (`α̇_g` the previous command's, the guess); at `α + θh α̇`,
    /// to first order,
    ///
    /// ```text
    /// w = w_e + c (θh α̇ − h/2 α̇_g),   c = ∂(H̄⁻¹ū)/∂α = −H̄⁻¹ (∂H̄/∂α) w_e
    /// ```
    ///
    /// solved for `α̇`: one unknown on the unicycle ([`alpha_step_one`], exact weight), two on
    /// the car ([`alpha_step_two`], first-order weight). Without it the loop
    /// `α → H̄(α)⁻¹ → α̇` (gain `~|ū|/det H`) rings at the Nyquist frequency at long periods.
    #[inline(always)]
    fn implicit_alpha(&self, frame: &CompanionFrame<T>, w_e: Vector3<T>, hold: &Hold<T>) -> Vector3<T> {
        let g = P::alpha_rate(&hold.guess_w);
        let c0 = -(frame.hbar_inv * (frame.dhbar[0] * w_e));
        if P::ALPHA_DIM == 1 {
            return alpha_step_one(w_e, c0, g[0], hold);
        }
        let c1 = -(frame.hbar_inv * (frame.dhbar[1] * w_e));
        alpha_step_two(w_e, [c0, c1], g, hold)
    }
}

/// The unicycle's `α` step (`w = (v, ω, α̇)`, `c = ∂w/∂α`, `c_α = c[2] = ∂α̇/∂α`), exact for
/// the linearised equation. Over the hold `α̇ = w_e,α + c_α (α − α_e)` has constant
/// coefficients; with `x = −h c_α` and `r = w_e,α − h/2 c_α α̇_g` (the rate at the measured
/// `α`) it gives
///
/// ```text
/// held α̇, the mean rate:      (α(h) − α(0))/h         = r / m(x)
/// mean α, where v, ω are taken: (1/h)∫(α(t) − α(0)) dt = θ(x) h α̇
/// m(x) = x/(1 − e^{−x}) = 1 + θ(x) x,   θ(x) = 1/(1 − e^{−x}) − 1/x = ½ + x/12 − x³/720 + …
/// w = w_e + c (θ(x) h α̇ − h/2 α̇_g)
/// ```
///
/// `m` and `θ` are the platform step's weights at `z = |x|` ([`stiffness_weights`]):
/// `m = 1 + a x + b x²`, `θ = a + b x`. They are exact where the mode decays (`x = z`) and,
/// where `a = ½` (`z ≤ z* ≈ 4.8`), where it grows (`x = −z`: `m(−z) = m(z) − z`). So the held
/// `α̇` is the linearised equation's mean rate and `v`, `ω` are evaluated at its mean `α`;
/// the local error left is the linearisation's (`c` changing over the hold, the curvature of
/// `H̄⁻¹ū` in `α`): `O(h²)` in the held command, as everywhere in the midpoint step, without
/// a sign of its own. The earlier first-order weight `θ = ½ + ½ z/(1 + z)` was off `θ(x)` by
/// `5x/12` where the mode decays (`7|x|/12` where it grows): an `O(h²)` bias of the mean `α`
/// with one sign, which no feedback removes from `α`'s phase. It was T2 (a)'s largest
/// distance from the continuous law at 1 ms, 5.31·10⁻³ (now 4.08·10⁻³; T1 (a) 3.76·10⁻³ →
/// 3.05·10⁻³: the book's precision chapter, docs/book/src/precision.md).
///
/// Where `m ≤ ½` (`x < −1.26`: a mode that grows more than 3.5-fold over the hold) the step
/// stays explicit: `w_e`.
#[inline(always)]
fn alpha_step_one<T: Real>(w_e: Vector3<T>, c: Vector3<T>, alpha_dot_g: T, hold: &Hold<T>) -> Vector3<T> {
    let (h, half) = (hold.period, hold.half);
    let x = -(h * c[2]);
    let (a, b) = stiffness_weights(x.abs());
    let theta = a + b * x;
    let m = T::one() + theta * x;
    if m.nan() || m <= T::of(0.5) {
        return w_e;
    }
    let alpha_dot = (w_e[2] - half * c[2] * alpha_dot_g) / m;
    w_e + c * (theta * h * alpha_dot - half * alpha_dot_g)
}

/// The car's `α` step (`w = (v, α̇₁, α̇₂)`, `c_j = ∂w/∂α_j`, `C = ∂α̇/∂α`, `C_ij = c_j[i + 1]`):
/// the 2×2 system `(I − θh C) α̇ = w_e,α − h/2 C α̇_g` with the scalar, first-order weight
/// `θ = ½ + ½ z/(1 + z)`, `z = h max(|C₀₀|, |C₁₀| + |C₀₁|, |C₁₁|)`.
///
/// Not the unicycle's exact weight: the car's `C` has complex eigenvalues on 13 % of the
/// steps of T1 (a) and 35 % of T2 (a) at 100 Hz (`|Im| h` up to 2–4), which no scalar weight
/// integrates exactly, and the matrix form `M = I − a hC + b (hC)²` leaves them undamped
/// where `θ > ½` damps them: with it the car tracks T1 (a) at 100 Hz 66.8 % of the time
/// after 20 s over 24 nearby starts, against 79.4 % with this weight
/// (`docs/explore/alpha-step`).
#[inline(always)]
fn alpha_step_two<T: Real>(w_e: Vector3<T>, c: [Vector3<T>; 2], g: Vector2<T>, hold: &Hold<T>) -> Vector3<T> {
    let (h, half) = (hold.period, hold.half);
    let [c0, c1] = c;
    let z = h * c0[1].abs().max(c0[2].abs() + c1[1].abs()).max(c1[2].abs());
    let theta = T::of(0.5) + T::of(0.5) * z / (T::one() + z);
    // M = I − θh C; the right-hand side r = w_e,α − h/2 C α̇_g.
    let m00 = T::one() - theta * h * c0[1];
    let m01 = -theta * h * c1[1];
    let m10 = -theta * h * c0[2];
    let m11 = T::one() - theta * h * c1[2];
    let r0 = w_e[1] - half * c0[1] * g[0] - half * c1[1] * g[1];
    let r1 = w_e[2] - half * (c0[2] * g[0] + c1[2] * g[1]);
    let det = m00 * m11 - m01 * m10;
    if det.nan() || det <= T::of(0.5) {
        return w_e;
    }
    let a0 = (r0 * m11 - m01 * r1) / det;
    let a1 = (m00 * r1 - m10 * r0) / det;
    w_e + c0 * (theta * h * a0 - half * g[0]) + c1 * (theta * h * a1 - half * g[1])
}

/// The weights `(a, b)` of the step's matrix `M = I − a hJ + b (hJ)²` for `z = h‖J‖∞`
/// (module docs; the unicycle's `α` step takes them for its scalar `J = ∂α̇/∂α`,
/// [`alpha_step_one`]). A mode `y′ = −μy` of `J` (`x = μh ≤ z`) is advanced by
/// `R(x) = (1 − (1 − a)x + b x²)/(1 + a x + b x²)`; exact (`R = e^{−x}`) needs
/// `m(x) = 1 + a x + b x² = x/(1 − e^{−x})`.
///
/// - `a = ½`, `b = (θ(z) − ½)/z` with `θ(z) = 1/(1 − e^{−z}) − 1/z` while `b ≥ 1/16`
///   (`z ≤ z* ≈ 4.8`): exact for the mode at `x = z`, and for every mode to `O(x³)` (`b → 1/12`,
///   the (2,2) Padé approximant of `e^{−x}` as `z → 0`). Below `z = ½`, `b` from its series
///   `Σ B₂ₙ z²ⁿ⁻²/(2n)! = 1/12 − z²/720 + z⁴/30240 − …` to `z¹²` (truncation below 10⁻¹⁶;
///   the closed form cancels, in `f32` completely below `z ≈ 10⁻³`).
/// - beyond, `b = s²/4`, `a = 1 − s`, `s = 2 (1 + √(z/(e^z − 1)))/z`: still exact at `x = z`
///   and `1 − (1 − a)x + b x² = (1 − s x/2)² ≥ 0`, so no mode rings (`0 ≤ R < 1`); as
///   `z → ∞`, `a → 1`, `b → 0` (implicit Euler: the stiff modes are damped, `R(z) = e^{−z}`).
///   The two branches meet continuously at `z*` (where `s = ½`).
#[inline(always)]
pub(crate) fn stiffness_weights<T: Real>(z: T) -> (T, T) {
    let half = T::of(0.5);
    if z < half {
        let z2 = z * z;
        // The Bernoulli numbers B₂ₙ/(2n)!, n = 1..7.
        let b = T::of(-691.0 / (2730.0 * 479_001_600.0)) + z2 * T::of(7.0 / (6.0 * 87_178_291_200.0));
        let b = T::of(1.0 / 47_900_160.0) + z2 * b;
        let b = T::of(1.0 / 30_240.0) + z2 * (T::of(-1.0 / 1_209_600.0) + z2 * b);
        return (half, T::of(1.0 / 12.0) + z2 * (T::of(-1.0 / 720.0) + z2 * b));
    }
    let e = (-z).exponential();
    let one_m = T::one() - e;
    let b = (T::one() / one_m - T::one() / z - half) / z;
    if b >= T::of(1.0 / 16.0) || !z.finite() {
        return (half, b);
    }
    let s = T::of(2.0) * (T::one() + (z * e / one_m).square_root()) / z;
    (T::one() - s, s * s * T::of(0.25))
}

/// The quantities of (37) that its linearisation needs.
#[derive(Clone, Copy, Debug)]
struct Linearisation<'a, T> {
    a: &'a Vector3<T>,
    k_a: &'a Vector3<T>,
    coef: T,
    denom: T,
    dh_dt: T,
    track_a: &'a Vector3<T>,
    track_b1: &'a Vector3<T>,
}

#[cfg(test)]
mod tests {
    use super::stiffness_weights;

    /// `R(x)` of the module docs for weights `(a, b)`.
    fn r(x: f64, (a, b): (f64, f64)) -> f64 {
        (1.0 - (1.0 - a) * x + b * x * x) / (1.0 + a * x + b * x * x)
    }

    #[test]
    fn the_step_is_exact_at_the_norm_and_never_rings() {
        let mut last = stiffness_weights(0.0_f64);
        assert_eq!(last, (0.5, 1.0 / 12.0));
        for i in 1..=4000 {
            let z = f64::from(i) * 0.01;
            let w = stiffness_weights(z);
            // Exact for the mode at x = z; continuous in z (both branch switches included).
            assert!((r(z, w) - (-z).exp()).abs() < 1e-12, "z = {z}: R = {} vs {}", r(z, w), (-z).exp());
            assert!(
                (w.0 - last.0).abs() < 0.01 && (w.1 - last.1).abs() < 0.01,
                "z = {z}: {w:?} after {last:?}"
            );
            // No mode below z rings (up to rounding), and every one is damped.
            for k in 1..=50 {
                let x = z * f64::from(k) / 50.0;
                let rx = r(x, w);
                assert!((-1e-15..1.0).contains(&rx), "z = {z}, x = {x}: R = {rx}");
            }
            last = w;
        }
        // The series and the closed form agree where they meet, in f32 too.
        let (below, above) = (stiffness_weights(0.5 - 1e-12_f64), stiffness_weights(0.5_f64));
        assert!((below.1 - above.1).abs() < 1e-14, "{below:?} {above:?}");
        for z in [1e-6_f32, 1e-3, 0.1, 0.49, 0.5, 1.0, 4.0, 10.0, 1e3] {
            let (a32, b32) = stiffness_weights(z);
            let (a64, b64) = stiffness_weights(f64::from(z));
            assert!(
                (f64::from(a32) - a64).abs() < 1e-6 && (f64::from(b32) - b64).abs() < 1e-5 * b64.max(1e-3),
                "z = {z}"
            );
        }
    }
}
