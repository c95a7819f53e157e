//! The controller: validated parameters ([`ControlLaw`]) + a small [`State`], one hot
//! function [`ControlLaw::step`], and the owning convenience wrapper [`Controller`].
//!
//! Order of one step (the platform first, because the arm law (30) needs the platform
//! velocity actually commanded):
//!
//! 1. reject a bad measurement or time step (typed error + safe command, state untouched);
//! 2. the companion frame `r̄_b = r_b f(α)⁻¹` (11) and `H̄(α)` (15)/(60);
//! 3. `h_s`, `a`, `∂h_s/∂t`, then `ū_b` by (37) and `(platform inputs, α̇) = H̄⁻¹ ū_b`;
//! 4. the car's steering rate (59); one common saturation factor ≥ 1 over all of them;
//! 5. the arm law (30) with the saturated `u_b`;
//! 6. the state (`α`, `q̂`, `Ψ` or `σᵢ`, `r̃_b`) advanced by one explicit Euler step of `dt`
//!    (exact for `α`, whose rate is held over the step).

use nalgebra::{Matrix3, SVector, Vector2, Vector3};

use crate::arm::Arm;
use crate::error::{Field, ParamError, StepError};
use crate::params::{Params, Precompensation, RestFilter, Warning, Weight};
use crate::platform::{Platform, PlatformCommand, PlatformKind};
use crate::primary::{base_to_relative, filter_rate, primary_terms};
use crate::scalar::{wrap_angle, Real};
use crate::se2::{add_sc, inverse3, rbar_sc, Pose};
use crate::secondary::{bounded_filter_rate, psi_tilde, rest_cost, sigma_tilde_joint, tracking_cost_sc};

/// What the controller measures each cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement<T, const N: usize> {
    /// Time `t` (s). The law's own time (in `Γ(t)`) counts from the first step.
    pub t: T,
    /// Platform pose `r_b` in the fixed frame (m, m, rad).
    pub base: Pose<T>,
    /// Steering state `ξ = tan φ / ℓ` (1/m) of a car-like platform; ignored otherwise.
    pub steering: T,
    /// Joint positions `q` (rad or m).
    pub joints: SVector<T, N>,
    /// Target pose `r_d` in the fixed frame (m, m, rad).
    pub target: Pose<T>,
    /// Target body velocity `u_d`, `ṙ_d = R̄(θ_d) u_d` (m/s, m/s, rad/s).
    pub target_velocity: Vector3<T>,
}

/// The command for one cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Command<T, const N: usize> {
    /// Platform velocities.
    pub platform: PlatformCommand<T>,
    /// Joint velocities `u_q = q̇` (rad/s or m/s), eq. (30).
    pub joints: SVector<T, N>,
}

impl<T: Real, const N: usize> Command<T, N> {
    /// The safe command: every velocity zero.
    pub fn zero() -> Self {
        let z = T::zero();
        Self { platform: PlatformCommand { v: z, v_lat: z, omega: z, v_xi: z }, joints: SVector::zeros() }
    }

    /// Whether every component is finite.
    pub fn is_finite(&self) -> bool {
        let p = &self.platform;
        p.v.finite()
            && p.v_lat.finite()
            && p.omega.finite()
            && p.v_xi.finite()
            && self.joints.iter().all(|x| x.finite())
    }
}

/// What a step reports besides the command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diagnostics<T, const N: usize> {
    /// `e_p`, eq. (42): the tracking error (m, m, rad).
    pub e_p: Vector3<T>,
    /// `e_m`, eq. (23).
    pub e_m: SVector<T, N>,
    /// `h_s`, eq. (29).
    pub h_s: T,
    /// `h_s1`, eq. (49).
    pub h_s1: T,
    /// `h_s2`, eq. (27) (0 when `Ψ ≡ 1`, where it is not needed).
    pub h_s2: T,
    /// The weight `Ψ ∈ [0, 1]`.
    pub psi: T,
    /// `h_ℓ(q)`, eq. (20): positive when a joint is within its penalty margin.
    pub joint_penalty: T,
    /// The common saturation factor of the platform velocities and `α̇` (≥ 1; 1 means no
    /// saturation).
    pub saturation: T,
    /// The common factor (≥ 1) the joint velocities were divided by so that no joint covers
    /// more than [`Params::joint_step_fraction`] of its distance to a limit in one step, and
    /// none exceeds its velocity limit; 1 means the arm law (30) was applied as is.
    pub joint_scale: T,
    /// `det H̄(α)` (1 for the omnidirectional platform).
    pub det_h: T,
    /// The 1-norm condition number of `∂e_m/∂q`, eq. (24).
    pub condition: T,
    /// `α` at this step (unused components zero).
    pub alpha: Vector2<T>,
    /// `α̇` commanded (after saturation).
    pub alpha_rate: Vector2<T>,
    /// `ū_b` applied (after saturation), the companion frame's body velocity.
    pub u_bar: Vector3<T>,
    /// The companion frame `r̄_b` (11) in the fixed frame.
    pub companion: Pose<T>,
}

/// The result of a successful step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Output<T, const N: usize> {
    /// The command to apply until the next step.
    pub command: Command<T, N>,
    /// Values for logging and monitoring.
    pub diagnostics: Diagnostics<T, N>,
}

/// A rejected step: why, and the safe command to send instead (every velocity zero).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rejected<T, const N: usize> {
    /// Why the step was rejected.
    pub error: StepError,
    /// The safe command.
    pub command: Command<T, N>,
}

impl<T: Real, const N: usize> core::fmt::Display for Rejected<T, N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "step rejected: {}", self.error)
    }
}

/// The law's evolving quantities: `α`, `q̂` (26), `Ψ` (53) or `σᵢ` (54), `r̃_b` (28).
///
/// [`State::new`] is uninitialised; the first accepted step sets it per SPEC §3:
/// `q̂(0) = q(0)`, `Ψ(0) = Ψ̃(q(0))`, `σᵢ(0) = σ̃ᵢ(qᵢ(0))`, `r̃_b(0) = 0`, and keeps `α`
/// (0 unless set before).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct State<T, const N: usize> {
    /// Transverse-function variables `α` (rad); unused components stay zero.
    pub alpha: Vector2<T>,
    /// Filtered joints `q̂`, eq. (26).
    pub q_hat: SVector<T, N>,
    /// The weight `Ψ` (for [`Weight::Filtered`]).
    pub psi: T,
    /// The filtered `σᵢ` (for [`Weight::PerJoint`]).
    pub sigma: SVector<T, N>,
    /// `r̃_b` of the rest filter (28).
    pub r_tilde: Pose<T>,
    /// The time of the first step (s).
    pub t0: T,
    /// Whether the first step has set the state.
    pub initialized: bool,
}

impl<T: Real, const N: usize> State<T, N> {
    /// An uninitialised state with `α = 0`.
    pub fn new() -> Self {
        Self {
            alpha: Vector2::zeros(),
            q_hat: SVector::zeros(),
            psi: T::zero(),
            sigma: SVector::zeros(),
            r_tilde: Pose::identity(),
            t0: T::zero(),
            initialized: false,
        }
    }
}

impl<T: Real, const N: usize> Default for State<T, N> {
    fn default() -> Self {
        Self::new()
    }
}

/// The validated law for platform `P` and arm `A` with `N` joints.
#[derive(Clone, Copy, Debug)]
pub struct ControlLaw<T: Real, P, A, const N: usize> {
    params: Params<T, N>,
    platform: P,
    arm: A,
    /// `(sin θ*, cos θ*)` of `r*_ed`.
    rot_star: (T, T),
    /// `r_*⁻¹`.
    r_star_inv: Pose<T>,
    /// `(sin, cos)` of `r_*⁻¹`'s angle.
    sc_star_inv: (T, T),
}

#[inline]
fn clamp01<T: Real>(x: T) -> T {
    if x < T::zero() {
        T::zero()
    } else if x > T::one() {
        T::one()
    } else {
        x
    }
}

impl<T: Real, P: Platform<T>, A: Arm<T, N>, const N: usize> ControlLaw<T, P, A, N> {
    /// Validates the parameters, the platform's transverse function and the arm.
    ///
    /// # Errors
    /// The first parameter that breaks a rule (see [`Params::validate`]).
    pub fn new(params: Params<T, N>, platform: P, arm: A) -> Result<Self, ParamError> {
        params.validate()?;
        platform.validate()?;
        arm.validate()?;
        let rot_star = params.primary.target_in_effector.theta.sincos();
        let r_star_inv = params.secondary.preferred_pose.inverse();
        let sc_star_inv = r_star_inv.theta.sincos();
        Ok(Self { params, platform, arm, rot_star, r_star_inv, sc_star_inv })
    }

    /// The parameters.
    pub fn params(&self) -> &Params<T, N> {
        &self.params
    }

    /// The platform (with its transverse function).
    pub fn platform(&self) -> &P {
        &self.platform
    }

    /// The arm.
    pub fn arm(&self) -> &A {
        &self.arm
    }

    /// Conditions the paper asks for that the parameters break but that are accepted.
    pub fn warnings(&self) -> heapless::Vec<Warning, 16> {
        self.params.warnings()
    }

    /// One control step: the command to hold for the next `dt` seconds, and diagnostics.
    /// On success the state has advanced by `dt`.
    ///
    /// # Errors
    /// A bad measurement or time step: a [`Rejected`] with the reason and the safe command;
    /// the state is left as it was.
    #[inline]
    pub fn step(
        &self,
        state: &mut State<T, N>,
        meas: &Measurement<T, N>,
        dt: T,
    ) -> Result<Output<T, N>, Rejected<T, N>> {
        match self.compute(state, meas, dt) {
            Ok(out) => Ok(out),
            Err(error) => Err(Rejected { error, command: Command::zero() }),
        }
    }

    fn check(&self, meas: &Measurement<T, N>, dt: T) -> Result<(), StepError> {
        if !dt.finite() || dt <= T::zero() || dt > self.params.max_time_step {
            return Err(StepError::BadTimeStep);
        }
        // 0·x is ±0 for finite x and NaN otherwise: one test on the common path, the field
        // by field search only when something is not finite.
        let (b, d, u) = (&meas.base, &meas.target, &meas.target_velocity);
        let mut nan = meas.t * T::zero();
        for x in [b.x, b.y, b.theta, d.x, d.y, d.theta, u[0], u[1], u[2]] {
            nan += x * T::zero();
        }
        if P::KIND == PlatformKind::Car {
            nan += meas.steering * T::zero();
        }
        for i in 0..N {
            nan += meas.joints[i] * T::zero();
        }
        if nan != T::zero() {
            return Err(Self::which_non_finite(meas));
        }
        let lim = &self.params.joint_limits;
        for i in 0..N {
            let q = meas.joints[i];
            if q <= lim.lower[i] || q >= lim.upper[i] {
                #[allow(clippy::cast_possible_truncation)]
                return Err(StepError::JointAtLimit(i as u8));
            }
        }
        if self.arm.is_singular(&meas.joints) {
            return Err(StepError::SingularArm);
        }
        Ok(())
    }

    /// The first non-finite field of a measurement that has one.
    #[cold]
    fn which_non_finite(meas: &Measurement<T, N>) -> StepError {
        let field = if !meas.t.finite() {
            Field::Time
        } else if !meas.base.is_finite() {
            Field::BasePose
        } else if !meas.joints.iter().all(|x| x.finite()) {
            Field::Joints
        } else if !meas.target.is_finite() {
            Field::TargetPose
        } else if !meas.target_velocity.iter().all(|x| x.finite()) {
            Field::TargetVelocity
        } else {
            Field::Steering
        };
        StepError::NonFinite(field)
    }

    /// The state the first step starts from (SPEC §3).
    fn initial(&self, state: &State<T, N>, meas: &Measurement<T, N>) -> State<T, N> {
        let q = &meas.joints;
        let lim = &self.params.joint_limits;
        let mut s = State::new();
        s.alpha = state.alpha;
        s.q_hat = *q;
        s.t0 = meas.t;
        s.initialized = true;
        match &self.params.secondary.weight {
            Weight::Constant(psi) => s.psi = *psi,
            Weight::Filtered { margins, .. } | Weight::FromFilteredJoints { margins } => {
                s.psi = psi_tilde(q, &lim.lower, &lim.upper, margins).0;
            }
            Weight::PerJoint { margins, .. } => {
                for i in 0..N {
                    s.sigma[i] = sigma_tilde_joint(q[i], lim.lower[i], lim.upper[i], margins, i).0;
                }
                s.psi = s.sigma.dot(&s.sigma) / T::of(N as f64);
            }
        }
        s
    }

    /// The joint guard: the smallest factor `s ≥ 1` such that `u_q / s` moves no joint by more
    /// than `κ` times its distance to the limit it moves towards within `dt` (a
    /// fraction-to-the-boundary rule), and keeps each `|u_qᵢ|` within its limit.
    ///
    /// In continuous time the penalty (20)–(21) keeps the joints inside their limits; a
    /// sampled command held over `dt` can still step over a limit when `u_q` is very large
    /// (e.g. with the `Ψ̇` drift term). The guard is inactive otherwise.
    #[inline]
    fn joint_guard(&self, q: &SVector<T, N>, u_q: &SVector<T, N>, dt: T) -> T {
        let lim = &self.params.joint_limits;
        let kappa = self.params.joint_step_fraction;
        let mut scale = T::one();
        for i in 0..N {
            let u = u_q[i];
            let room = if u > T::zero() { lim.upper[i] - q[i] } else { lim.lower[i] - q[i] };
            // u and room have the same sign; room ≠ 0 (q is strictly inside its limits).
            let r = (u * dt) / (kappa * room);
            if r > scale {
                scale = r;
            }
            let v = u.abs() / self.params.joint_velocity_limits[i];
            if v > scale {
                scale = v;
            }
        }
        scale
    }

    /// `ū_b` of (37) with the rest filter (28) advanced by one linearly implicit Euler step
    /// instead of an explicit one.
    ///
    /// The loop `r̃_b → h_s2 → ū_b → r̃_b` has a gain of up to `2 (1 − Ψ) coef λ_max(K)`
    /// (the ratio in (37) times the largest eigenvalue of `K = H̄ K̄ H̄ᵀ`), which with the
    /// paper's `K̄ = diag(1, 1, 100)` reaches ~2·10³/s: sampled at 1 kHz with the command held
    /// over the period, an explicit update oscillates at the Nyquist frequency (`α̇` and `ω`
    /// flip sign every step). Evaluating (37) at the end-of-step filter state, linearised,
    /// is stable for any gain and equals the continuous law as `dt → 0`:
    ///
    /// ```text
    /// ū = (I + dt J Q)⁻¹ (ū₀ + dt J R̄(θ̃) û),   J = ∂ū/∂r̃_b = ∂ū/∂a · (1 − Ψ) ∂a₂/∂r̃_b
    /// ∂ū/∂a = −K a (∂coef/∂a)ᵀ − coef K,   ∂coef/∂a = 2 (D a − coef K a)/(aᵀKa + μ)
    /// ∂a₂/∂r̃_b = −2 diag(1, 1, γ cos θ̃_b)
    /// ```
    ///
    /// (the pre-compensation terms are held at their start-of-step values in `J`).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn implicit_rest_step(
        &self,
        hbar: &Matrix3<T>,
        rest: &crate::secondary::RestCost<T>,
        psi: T,
        a: &Vector3<T>,
        k_a: &Vector3<T>,
        coef: T,
        denom: T,
        u_bar: Vector3<T>,
        dt: T,
    ) -> Vector3<T> {
        let sec = &self.params.secondary;
        let two = T::of(2.0);
        let k = hbar * Matrix3::from_diagonal(&sec.k_bar) * hbar.transpose();
        let dcoef = (a.component_mul(&sec.d) - k_a * coef) * (two / denom);
        let du_da = -(k_a * dcoef.transpose()) - k * coef;
        let s = -two * (T::one() - psi);
        let da_dr = Vector3::new(s, s, s * sec.gamma_2 * rest.cos_theta);
        let j = Matrix3::from_fn(|r, c| du_da[(r, c)] * da_dr[c]);
        let m = Matrix3::identity() + j * rest.q * dt;
        match inverse3(&m) {
            Some((inv, _)) => inv * (u_bar + j * rest.drift * dt),
            None => u_bar,
        }
    }

    #[allow(clippy::too_many_lines)]
    #[inline]
    fn compute(
        &self,
        state: &mut State<T, N>,
        meas: &Measurement<T, N>,
        dt: T,
    ) -> Result<Output<T, N>, StepError> {
        self.check(meas, dt)?;
        let init;
        let st: &State<T, N> = if state.initialized {
            state
        } else {
            init = self.initial(state, meas);
            &init
        };
        let prm = &self.params;
        let sec = &prm.secondary;
        let lim = &prm.joint_limits;
        let q = &meas.joints;
        let u_d = &meas.target_velocity;

        // Primary task, with Γ(t) = γ₀ e^{−λ t} and the q̂ filter (26).
        let t_rel = {
            let t = meas.t - st.t0;
            if t > T::zero() {
                t
            } else {
                T::zero()
            }
        };
        let p = &prm.primary;
        let gamma = if p.regularisation_gain > T::zero() {
            p.regularisation_gain * (-p.regularisation_decay * t_rel).exponential()
        } else {
            T::zero()
        };
        let gamma_rate = -p.regularisation_decay * gamma;
        let q_hat_rate = filter_rate(&st.q_hat, q, p.filter_sigma, p.filter_xi);
        // Every sine and cosine is computed once: of θ_b, θ_bd, α (in the companion frame) and
        // the arm's angles; the others follow by angle addition.
        let sc_b = meas.base.theta.sincos();
        let r_bd = meas.base.between_sc(&meas.target, sc_b.0, sc_b.1);
        let sc_bd = r_bd.theta.sincos();
        let prim = primary_terms(
            p,
            lim,
            &self.arm,
            q,
            &r_bd,
            gamma,
            gamma_rate,
            &st.q_hat,
            &q_hat_rate,
            self.rot_star,
        );

        // Companion frame (11): m = r_d⁻¹ r̄_b = r_db f(α)⁻¹, r̄ = r_*⁻¹ m.
        let frame = self.platform.companion(&st.alpha).ok_or(StepError::NumericalFailure)?;
        let sc_f = frame.sin_cos_theta_f;
        let f_inv = frame.f.inverse_sc(sc_f.0, sc_f.1);
        let sc_db = (-sc_bd.0, sc_bd.1);
        let m = r_bd.inverse_sc(sc_bd.0, sc_bd.1).compose_sc(&f_inv, sc_db.0, sc_db.1);
        let sc_m = add_sc(sc_db, (-sc_f.0, sc_f.1));
        let r_bar = self.r_star_inv.compose_sc(&m, self.sc_star_inv.0, self.sc_star_inv.1).wrapped();
        let sc_bar = add_sc(self.sc_star_inv, sc_m);

        // The weight Ψ and its rate.
        let inv_n = T::one() / T::of(N as f64);
        let mut sigma_rate = SVector::<T, N>::zeros();
        let (psi, psi_rate) = match &sec.weight {
            Weight::Constant(psi) => (*psi, T::zero()),
            Weight::Filtered { margins, lambda, xi } => {
                let target = psi_tilde(q, &lim.lower, &lim.upper, margins).0;
                (st.psi, bounded_filter_rate(st.psi, target, *lambda, *xi))
            }
            Weight::PerJoint { margins, lambda, xi } => {
                let mut rate = T::zero();
                for i in 0..N {
                    let target = sigma_tilde_joint(q[i], lim.lower[i], lim.upper[i], margins, i).0;
                    sigma_rate[i] = bounded_filter_rate(st.sigma[i], target, *lambda, *xi);
                    rate += T::of(2.0) * st.sigma[i] * sigma_rate[i] * inv_n;
                }
                (st.sigma.dot(&st.sigma) * inv_n, rate)
            }
            Weight::FromFilteredJoints { margins } => {
                let (psi, grad) = psi_tilde(&st.q_hat, &lim.lower, &lim.upper, margins);
                (psi, grad.dot(&q_hat_rate))
            }
        };

        // Secondary cost (29): h_s1 always; h_s2 and the rest filter unless Ψ ≡ 1.
        let track = tracking_cost_sc(&r_bar, sc_bar, &m, sc_m, u_d, sec.gamma_1);
        let rest_needed = sec.weight != Weight::Constant(T::one());
        let (h_s, a, dh_dt, h_s2, rest) = if rest_needed {
            let rest = rest_cost(&st.r_tilde, &sec.rest_sigma, sec.rest_xi, sec.gamma_2);
            let one_m = T::one() - psi;
            let mut dh = psi * track.dh_dt + one_m * rest.dh_dt;
            if sec.psi_rate_in_drift {
                dh += psi_rate * (track.h - rest.h);
            }
            (psi * track.h + one_m * rest.h, track.a * psi + rest.a * one_m, dh, rest.h, Some(rest))
        } else {
            (track.h, track.a, track.dh_dt, T::zero(), None)
        };

        // Pre-compensation (b̂₁, b̂₂).
        let zero3 = Vector3::zeros();
        let (b1, b2) = match sec.precompensation {
            Precompensation::Full51 => (track.b1, T::zero()),
            Precompensation::Full40 { nu } => {
                let n = T::one() / (a.dot(&a) + nu);
                (a * (dh_dt * n), dh_dt * nu * n)
            }
            Precompensation::None => (zero3, T::zero()),
            Precompensation::Partial => (zero3, dh_dt),
        };

        // Platform law (37) with K = H̄ K̄ H̄ᵀ (36): with z = H̄ᵀ a, K a = H̄ (K̄ z), so
        // H̄⁻¹ ū_b = −H̄⁻¹ b̂₁ − coef K̄ z.
        let z = frame.hbar.transpose() * a;
        let kz = z.component_mul(&sec.k_bar);
        let a_k_a = z.dot(&kz);
        let a_d_a = a.component_mul(&sec.d).dot(&a);
        let denom = a_k_a + sec.mu;
        let coef = (a_d_a + b2) / denom;
        let k_a = frame.hbar * kz;
        let mut u_bar = -(k_a * coef);
        if b1 != zero3 {
            u_bar -= b1;
        }
        let mut w = match (&rest, sec.rest_filter) {
            (Some(rest), RestFilter::LinearlyImplicit) => {
                u_bar = self.implicit_rest_step(&frame.hbar, rest, psi, &a, &k_a, coef, denom, u_bar, dt);
                frame.hbar_inv * u_bar
            }
            _ => {
                let mut w = -(kz * coef);
                if b1 != zero3 {
                    w -= frame.hbar_inv * b1;
                }
                w
            }
        };
        let mut v_xi = self.platform.steering_rate(&frame, meas.steering, &P::alpha_rate(&w));

        // One common saturation factor ≥ 1 (end of §3.4.2).
        let ratio = P::saturation_ratio(&prm.velocity_limits, &w, v_xi);
        let saturation = if ratio > T::one() { ratio } else { T::one() };
        if saturation > T::one() {
            let inv = T::one() / saturation;
            w *= inv;
            u_bar *= inv;
            v_xi *= inv;
        }
        let alpha_rate = P::alpha_rate(&w);
        let u_b = P::body_velocity(&w, meas.steering);

        // Arm law (30): u_q = (∂e_m/∂q)⁻¹ (G e_m − ∂e_m/∂r_b u_b − ∂e_m/∂t)
        //             = (∂e_m/∂q)⁻¹ (G e_m − ∂e_m/∂r_bd ṙ_bd − ∂e_m/∂t|explicit).
        let r_bd_rate = rbar_sc(sc_bd.0, sc_bd.1) * u_d - base_to_relative(&r_bd) * u_b;
        let rhs = -prim.e_m.component_mul(&p.gain) - prim.de_m_dr_bd * r_bd_rate - prim.de_m_dt_explicit;
        let inv = prim.de_m_dq.try_inverse().ok_or(StepError::SingularTaskJacobian)?;
        let mut u_q = inv * rhs;
        let condition = one_norm(&prim.de_m_dq) * one_norm(&inv);
        let joint_scale = self.joint_guard(q, &u_q, dt);
        if joint_scale > T::one() {
            u_q /= joint_scale;
        }

        let command = Command { platform: P::command(&w, v_xi, meas.steering), joints: u_q };

        // The state after dt (written only once everything is known to be finite).
        let mut alpha = st.alpha;
        for i in 0..P::ALPHA_DIM {
            alpha[i] = wrap_angle(alpha[i] + alpha_rate[i] * dt);
        }
        let q_hat = st.q_hat + q_hat_rate * dt;
        let (mut psi_next, mut sigma_next) = (st.psi, st.sigma);
        match &sec.weight {
            Weight::Filtered { .. } => psi_next = clamp01(st.psi + psi_rate * dt),
            Weight::PerJoint { .. } => {
                sigma_next = (st.sigma + sigma_rate * dt).map(clamp01);
                psi_next = sigma_next.dot(&sigma_next) * inv_n;
            }
            Weight::Constant(_) | Weight::FromFilteredJoints { .. } => {}
        }
        let r_tilde = match &rest {
            Some(rest) => {
                let rate = rest.drift - rest.q * u_bar;
                let r = &st.r_tilde;
                Pose::new(r.x + rate[0] * dt, r.y + rate[1] * dt, wrap_angle(r.theta + rate[2] * dt))
            }
            None => st.r_tilde,
        };
        // 0·x is ±0 for finite x and NaN otherwise: one test for everything.
        let mut nan = condition * T::zero();
        let c = &command.platform;
        for x in
            [c.v, c.v_lat, c.omega, c.v_xi, alpha[0], alpha[1], psi_next, r_tilde.x, r_tilde.y, r_tilde.theta]
        {
            nan += x * T::zero();
        }
        for i in 0..N {
            nan += (u_q[i] + q_hat[i]) * T::zero();
        }
        if nan != T::zero() {
            return Err(StepError::NumericalFailure);
        }

        let companion = meas.base.compose_sc(&f_inv, sc_b.0, sc_b.1);
        let prev_alpha = st.alpha;
        if !state.initialized {
            *state = *st;
        }
        state.alpha = alpha;
        state.q_hat = q_hat;
        state.psi = psi_next;
        state.sigma = sigma_next;
        state.r_tilde = r_tilde;
        let diagnostics = Diagnostics {
            e_p: prim.e_p,
            e_m: prim.e_m,
            h_s,
            h_s1: track.h,
            h_s2,
            psi,
            joint_penalty: prim.h_l,
            saturation,
            joint_scale,
            det_h: frame.det_h,
            condition,
            alpha: prev_alpha,
            alpha_rate,
            u_bar,
            companion,
        };
        Ok(Output { command, diagnostics })
    }
}

fn one_norm<T: Real, const N: usize>(m: &nalgebra::SMatrix<T, N, N>) -> T {
    let mut best = T::zero();
    for j in 0..N {
        let mut s = T::zero();
        for i in 0..N {
            s += m[(i, j)].abs();
        }
        if s > best || s.nan() {
            best = s;
        }
    }
    best
}

/// A [`ControlLaw`] with its [`State`]: the convenient way to run one controller.
#[derive(Clone, Copy, Debug)]
pub struct Controller<T: Real, P, A, const N: usize> {
    /// The validated law.
    pub law: ControlLaw<T, P, A, N>,
    /// Its state.
    pub state: State<T, N>,
}

impl<T: Real, P: Platform<T>, A: Arm<T, N>, const N: usize> Controller<T, P, A, N> {
    /// A controller with a fresh state.
    ///
    /// # Errors
    /// An invalid parameter (see [`ControlLaw::new`]).
    pub fn new(params: Params<T, N>, platform: P, arm: A) -> Result<Self, ParamError> {
        Ok(Self { law: ControlLaw::new(params, platform, arm)?, state: State::new() })
    }

    /// One step (see [`ControlLaw::step`]).
    ///
    /// # Errors
    /// A rejected measurement or time step, with the safe command.
    #[inline]
    pub fn step(&mut self, meas: &Measurement<T, N>, dt: T) -> Result<Output<T, N>, Rejected<T, N>> {
        self.law.step(&mut self.state, meas, dt)
    }

    /// Forgets the state; the next step starts afresh.
    pub fn reset(&mut self) {
        self.state = State::new();
    }
}
