//! The controller: validated parameters ([`ControlLaw`]) + a small [`State`], one hot
//! function [`ControlLaw::step_delayed`] ([`ControlLaw::step`] is it without delay), and the
//! owning convenience wrapper [`Controller`].
//!
//! One step, in phases (the platform first, because the arm law (30) needs the platform
//! velocity actually commanded):
//!
//! 1. **check** the measurement, the period and the delay: a bad one gives a typed error and
//!    the safe command, and leaves the state as it was;
//! 2. **predict** (`hold`): the robot when the command starts to act (`t_k + τ`, through the
//!    commands in flight) and at the evaluation time — the middle of the hold,
//!    `t_e = t_k + τ + h/2`, with the previous command as a first guess
//!    ([`Discretisation::Midpoint`]), or the measurement itself ([`Discretisation::Sampled`]);
//! 3. the **filters** `q̂`, `Ψ` at `t_e` (half an explicit step from their values at `t_k + τ`);
//! 4. the **platform law** at `t_e` (`platform_law`): companion frame (11), `h_s` (29),
//!    `ū_b` (37) corrected linearly implicitly over the hold, `H̄⁻¹` (14)/(60), the car's
//!    steering (59), one common saturation factor;
//! 5. the **arm law** (30) at `t_e` with the new platform velocity, linearly implicit in `G`,
//!    and the joint guard (`arm_law`);
//! 6. the **state** advanced by the period (midpoint rule; `α` exactly, as its rate is
//!    held), kept bounded, and everything checked finite.
//!
//! **No lock-out.** If a step fails numerically (an overflow from extreme values), it is
//! computed once more from filters re-initialised from the measurement (`q̂ = q`,
//! `Ψ = Ψ̃(q)`, `r̃_b = 0`, no command in flight; `α` kept), and that step is reported with
//! [`Diagnostics::recovered`] and counted in [`State::recoveries`]. So a valid measurement is
//! accepted at once whatever came before it; only a measurement that fails from a fresh
//! state too is rejected (`NumericalFailure`), with the state untouched.

use nalgebra::{SMatrix, SVector, Vector2, Vector3};

use crate::arm_law::{ArmLaw, ArmStep};
use crate::command::{Command, Diagnostics, Output, Rejected};
use crate::error::{Field, ParamError, StepError};
use crate::hold::{self, advance_inside, Start};
use crate::measurement::Measurement;
use crate::params::{Discretisation, Params, TargetMotion, Warning, Weight, WeightMargins};
use crate::platform::{Platform, PlatformKind};
use crate::platform_law::{Hold, PlatformLaw, PlatformPoint, PlatformStep, Previous};
use crate::primary::filter_rate;
use crate::scalar::{wrap_angle, Real};
use crate::se2::{Pose, PoseSc};
use crate::secondary::{
    bounded_filter_rate, heading_filtered, heading_rates, psi_tilde, psi_tilde_value, psi_with_terms,
    rest_cost, sigma_tilde_joint, sigma_tildes, RestCost,
};
use crate::space::{Space, Vector};
use crate::state::{wrap_alpha, Sent, State, HISTORY};
use crate::task::{Manipulator, TaskPoint};

/// The validated law for platform `P` and arm `A` with `N` joints: a planar [`Arm`](crate::Arm)
/// tracking a target in the plane (§4), or a [`SpatialArm`](crate::SpatialArm) tracking one
/// in space (§5).
#[derive(Clone, Copy, Debug)]
pub struct ControlLaw<T: Real, P, A: Manipulator<T, N>, const N: usize> {
    params: Params<T, N, A::Space>,
    platform: P,
    arm: A,
    /// What the arm law precomputes from `r*_ed`.
    star: <A::Space as Space<T>>::Star,
    /// `r_*⁻¹` with its sine and cosine.
    r_star_inv: PoseSc<T>,
    /// Whether `Ψ ≢ 1`, so that `h_s2` and the rest filter are needed.
    rest_needed: bool,
    /// `h/2` is used (the midpoint discretisation).
    midpoint: bool,
    /// The acceleration limits of the platform's generalised inputs `w` (`+∞`: none), and
    /// whether one is finite ([`crate::acceleration`]).
    input_acceleration: Vector3<T>,
    platform_accel: bool,
    /// Whether a joint has a finite acceleration limit.
    joint_accel: bool,
}

#[inline]
fn clamp<T: Real>(x: T, lo: T, hi: T) -> T {
    if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    }
}

/// The target's velocity trend at the measurement: `u̇_d` and `ü_d`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TargetTrend<V> {
    pub rate: V,
    pub curvature: V,
}

impl<V> TargetTrend<V> {
    /// No trend: the velocity held.
    fn held<T>() -> Self
    where
        V: Vector<T>,
    {
        Self { rate: V::zeros(), curvature: V::zeros() }
    }

    /// `u_d(t_k + s)`.
    fn velocity_after<T: Real>(&self, u_d: &V, s: T) -> V
    where
        V: Vector<T>,
    {
        *u_d + self.rate * s + self.curvature * (s * s * T::of(0.5))
    }

    /// The mean velocity over `[t_k, t_k + s]`: `u_d + s/2 u̇_d + s²/6 ü_d`.
    fn mean_velocity<T: Real>(&self, u_d: &V, s: T) -> V
    where
        V: Vector<T>,
    {
        *u_d + self.rate * (s * T::of(0.5)) + self.curvature * (s * s * T::of(1.0 / 6.0))
    }
}

/// `Ψ` or the `σᵢ` with their rates at one point.
#[derive(Clone, Copy, Debug)]
struct WeightAt<T, const N: usize> {
    psi: T,
    psi_rate: T,
    sigma_rate: SVector<T, N>,
}

/// The measurement, state and output of a law with arm `A`.
type Meas<T, A, const N: usize> = Measurement<T, N, <A as Manipulator<T, N>>::Space>;
type St<T, A, const N: usize> = State<T, N, <A as Manipulator<T, N>>::Space>;
type Out<T, A, const N: usize> = Output<T, N, <A as Manipulator<T, N>>::Space>;
type Rel<T, A, const N: usize> = <<A as Manipulator<T, N>>::Space as Space<T>>::Relative;

impl<T: Real, P: Platform<T>, A: Manipulator<T, N>, const N: usize> ControlLaw<T, P, A, N> {
    /// Validates the parameters, the platform's transverse function and the arm.
    ///
    /// # Errors
    /// The first parameter that breaks a rule (see [`Params::validate`]).
    pub fn new(params: Params<T, N, A::Space>, platform: P, arm: A) -> Result<Self, ParamError> {
        params.validate()?;
        platform.validate()?;
        arm.validate_arm()?;
        let star = A::Space::star(&params.primary.target_in_effector);
        let r_star_inv = PoseSc::new(params.secondary.preferred_pose).inverse();
        let rest_needed = params.secondary.weight != Weight::Constant(T::one());
        let midpoint = params.discretisation == Discretisation::Midpoint;
        let input_acceleration = params.acceleration_limits.of_inputs(P::KIND);
        let platform_accel = params.acceleration_limits.limits_platform(P::KIND);
        let joint_accel = params.acceleration_limits.limits_joints();
        Ok(Self {
            params,
            platform,
            arm,
            star,
            r_star_inv,
            rest_needed,
            midpoint,
            input_acceleration,
            platform_accel,
            joint_accel,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &Params<T, N, A::Space> {
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

    /// One control step without delay: the command to hold for the next `period` seconds,
    /// from a measurement taken when the command starts to act. See [`step_delayed`].
    ///
    /// # Errors
    /// A bad measurement or period: a [`Rejected`] with the reason and the safe command; the
    /// state is left as it was.
    ///
    /// [`step_delayed`]: Self::step_delayed
    #[inline]
    pub fn step(
        &self,
        state: &mut St<T, A, N>,
        meas: &Meas<T, A, N>,
        period: T,
    ) -> Result<Out<T, A, N>, Rejected<T, N>> {
        self.step_delayed(state, meas, period, T::zero())
    }

    /// One control step: the command to hold for `period` seconds (s), starting `delay`
    /// seconds after the measurement was taken (compute and transport time; `0 ≤ delay ≤
    /// max_delay` and at most [`HISTORY`] periods). On success the state has advanced by
    /// `period`. With [`Discretisation::Sampled`] the delay is checked and used by the joint
    /// guard only (the joints when the command starts to act).
    ///
    /// The result is returned by value; [`step_delayed_into`](Self::step_delayed_into)
    /// writes it where the caller keeps it (a firmware's loop: no copy of the output).
    ///
    /// # Errors
    /// A bad measurement, period or delay: a [`Rejected`] with the reason and the safe
    /// command; the state is left as it was.
    #[inline]
    pub fn step_delayed(
        &self,
        state: &mut St<T, A, N>,
        meas: &Meas<T, A, N>,
        period: T,
        delay: T,
    ) -> Result<Out<T, A, N>, Rejected<T, N>> {
        by_value(|out| self.step_delayed_into(state, meas, period, delay, out))
    }

    /// [`step_delayed`](Self::step_delayed) with the output written into `out`, in place:
    /// the command and the diagnostics are written there as the law finds them, and no copy
    /// of the output is made on the way (~250 B; on a Cortex-M4F ~200 instructions of a
    /// ~4 000-instruction step, `tests/firmware`). On a rejected step `out.command` is the
    /// safe command and `out.diagnostics` is unspecified.
    ///
    /// # Errors
    /// As [`step_delayed`](Self::step_delayed).
    #[inline(always)]
    pub fn step_delayed_into(
        &self,
        state: &mut St<T, A, N>,
        meas: &Meas<T, A, N>,
        period: T,
        delay: T,
        out: &mut Out<T, A, N>,
    ) -> Result<(), Rejected<T, N>> {
        safe_on_rejection(self.step_inner(state, meas, period, delay, out), out)
    }

    #[inline(always)]
    fn step_inner(
        &self,
        state: &mut St<T, A, N>,
        meas: &Meas<T, A, N>,
        period: T,
        delay: T,
        out: &mut Out<T, A, N>,
    ) -> Result<(), Rejected<T, N>> {
        if let Err(error) = self.check(meas, period, delay) {
            return Err(Rejected::from(error));
        }
        if !state.initialized {
            return self.first_step(state, meas, period, delay, out);
        }
        match self.compute(state, meas, period, delay, None, None, out) {
            Err(Rejected { error: StepError::NumericalFailure, .. }) => {
                self.recover(state, meas, period, delay, out)
            }
            result => result,
        }
    }

    /// The first step of a run, taken now: the state made afresh from `meas` (SPEC §3: the
    /// filters from the measurement, `α` kept, no command in flight, the robot at rest) and
    /// the step computed from it — the step that costs about three steady-state steps (its
    /// hold is predicted in three passes). A firmware calls it before it enables the timer
    /// interrupt that steps the law, and applies its command as the interrupt starts: then
    /// every step inside the interrupt is a steady-state step (all but a
    /// [recovery](Diagnostics::recovered), the cold path of a numerical failure). Also the
    /// way to resume after the robot was stopped: the acceleration limits count from rest.
    ///
    /// # Errors
    /// As [`step_delayed`](Self::step_delayed); on a rejection the state is left as it was.
    #[inline(never)]
    pub fn start_into(
        &self,
        state: &mut St<T, A, N>,
        meas: &Meas<T, A, N>,
        period: T,
        delay: T,
        out: &mut Out<T, A, N>,
    ) -> Result<(), Rejected<T, N>> {
        let result = match self.check(meas, period, delay) {
            Err(error) => Err(Rejected::from(error)),
            Ok(()) => self.first_step(state, meas, period, delay, out),
        };
        safe_on_rejection(result, out)
    }

    /// [`start_into`](Self::start_into) returning the output by value.
    ///
    /// # Errors
    /// As [`step_delayed`](Self::step_delayed); on a rejection the state is left as it was.
    pub fn start(
        &self,
        state: &mut St<T, A, N>,
        meas: &Meas<T, A, N>,
        period: T,
        delay: T,
    ) -> Result<Out<T, A, N>, Rejected<T, N>> {
        by_value(|out| self.start_into(state, meas, period, delay, out))
    }

    /// The first step: from the state SPEC §3 prescribes, written only on success.
    #[cold]
    #[inline(never)]
    fn first_step(
        &self,
        state: &mut St<T, A, N>,
        meas: &Meas<T, A, N>,
        period: T,
        delay: T,
        out: &mut Out<T, A, N>,
    ) -> Result<(), Rejected<T, N>> {
        let keep = Keep::first(state, meas);
        let mut work = *state;
        self.initial_into(&keep, meas, &mut work);
        self.passes(&keep, &mut work, meas, period, delay, out)?;
        *state = work;
        Ok(())
    }

    /// A step from a fresh state (no command before it). With the hold-aware law there is no
    /// previous command to predict the hold with, so the step is computed three times, each
    /// pass with the previous pass's result as the guess (of `ū_b`, `w`, `u_q` and
    /// `∂u_q/∂u_b`), as every later step has its predecessor's — two predictor–corrector
    /// iterations of the midpoint. Predicted with the robot at rest, the first hold's error
    /// is close to the sampled law's (T1 (c): `q₁` 1.3·10⁻² rad off after the first
    /// millisecond, the run's largest distance from the continuous law); after one
    /// iteration it is still the largest of T1 (c) and T2 (a) (3.3·10⁻³, 5.8·10⁻³), after
    /// two it is no longer. The commands in flight stay none: a guess is not a command that
    /// was sent (and the acceleration limits count from the command `keep` names: rest, or
    /// the last one sent before a recovery).
    ///
    /// `work` is the fresh state ([`Self::initial_into`]`(keep, meas, work)`) on entry and
    /// holds the result on success. The passes share `work`, each from the fresh state
    /// written again in place (out of line, cheap, deterministic: no copy of a state) and the
    /// two guesses (a few vectors each): this function's frame is ~300 B in `f32` on a
    /// Cortex-M4F, where a copy of the fresh state per pass made it 936 B and the step's
    /// stack 3 kB. A pass that fails leaves `work` as it was given (a step commits only on
    /// success), so the pass before it is computed again from its guess — the same result,
    /// deterministically. The first step is the one step that costs about three
    /// steady-state steps (`tests/firmware/measure` names it; [`Self::start_into`] takes it
    /// outside a firmware's control interrupt).
    #[inline(never)]
    fn passes(
        &self,
        keep: &Keep<T, N>,
        work: &mut St<T, A, N>,
        meas: &Meas<T, A, N>,
        period: T,
        delay: T,
        out: &mut Out<T, A, N>,
    ) -> Result<(), Rejected<T, N>> {
        let from = Some(&keep.reference);
        let first = self.compute(work, meas, period, delay, None, from, out);
        if !self.midpoint || first.is_err() {
            return first;
        }
        // The second pass, from the first's guess; if it fails, the first again.
        let one = Guess::of(work);
        self.reset(keep, meas, work);
        one.set(work);
        if self.compute(work, meas, period, delay, Some(&one.sent), from, out).is_err() {
            self.reset(keep, meas, work);
            return self.compute(work, meas, period, delay, None, from, out);
        }
        // The third, from the second's; if it fails, the second again.
        let two = Guess::of(work);
        self.reset(keep, meas, work);
        two.set(work);
        let third = self.compute(work, meas, period, delay, Some(&two.sent), from, out);
        if third.is_ok() {
            return third;
        }
        self.reset(keep, meas, work);
        one.set(work);
        self.compute(work, meas, period, delay, Some(&one.sent), from, out)
    }

    /// `work` made fresh again, in place ([`Self::initial_into`]). Out of line, so that the
    /// first step's passes add nothing to the stack but `passes`' few vectors.
    #[inline(never)]
    fn reset(&self, keep: &Keep<T, N>, meas: &Meas<T, A, N>, work: &mut St<T, A, N>) {
        self.initial_into(keep, meas, work);
    }

    /// The step once more from filters re-initialised from the measurement.
    #[cold]
    #[inline(never)]
    fn recover(
        &self,
        state: &mut St<T, A, N>,
        meas: &Meas<T, A, N>,
        period: T,
        delay: T,
        out: &mut Out<T, A, N>,
    ) -> Result<(), Rejected<T, N>> {
        let mut keep = Keep::recovering(state);
        let mut work = *state;
        self.initial_into(&keep, meas, &mut work);
        if let Err(rejected) = self.passes(&keep, &mut work, meas, period, delay, out) {
            // From rest, if the command sent before was itself extreme (crate::acceleration).
            if !(self.platform_accel || self.joint_accel) {
                return Err(rejected);
            }
            keep.reference = Reference::rest();
            self.initial_into(&keep, meas, &mut work);
            self.passes(&keep, &mut work, meas, period, delay, out)?;
        }
        out.diagnostics.recovered = true;
        *state = work;
        Ok(())
    }

    fn check(&self, meas: &Meas<T, A, N>, period: T, delay: T) -> Result<(), StepError> {
        if !period.finite() || period <= T::zero() || period > self.params.max_time_step {
            return Err(StepError::BadTimeStep);
        }
        if !delay.finite()
            || delay < T::zero()
            || delay > self.params.max_delay
            || delay > period * T::of(HISTORY as f64)
        {
            return Err(StepError::BadDelay);
        }
        // 0·x is ±0 for finite x and NaN otherwise: one test on the common path, the field
        // by field search only when something is not finite.
        let b = &meas.base;
        let mut nan = meas.t * T::zero();
        for x in [b.x, b.y, b.theta] {
            nan += x * T::zero();
        }
        for x in meas.target_velocity.as_slice() {
            nan += *x * T::zero();
        }
        if P::KIND == PlatformKind::Car {
            nan += meas.steering * T::zero();
        }
        for i in 0..N {
            nan += meas.joints[i] * T::zero();
        }
        if nan != T::zero() || !A::Space::pose_is_finite(&meas.target) {
            return Err(Self::which_non_finite(meas));
        }
        let lim = &self.params.joint_limits;
        for i in 0..N {
            let q = meas.joints[i];
            if q <= lim.lower[i] || q >= lim.upper[i] {
                return Err(StepError::JointAtLimit(i as u8));
            }
        }
        self.arm.check_joints(&meas.joints)
    }

    /// The first non-finite field of a measurement that has one.
    #[cold]
    fn which_non_finite(meas: &Meas<T, A, N>) -> StepError {
        let field = if !meas.t.finite() {
            Field::Time
        } else if !meas.base.is_finite() {
            Field::BasePose
        } else if !meas.joints.iter().all(|x| x.finite()) {
            Field::Joints
        } else if !A::Space::pose_is_finite(&meas.target) {
            Field::TargetPose
        } else if !meas.target_velocity.as_slice().iter().all(|x| x.finite()) {
            Field::TargetVelocity
        } else {
            Field::Steering
        };
        StepError::NonFinite(field)
    }

    /// The state of a first step (SPEC §3), written into `s` in place: `q̂ = q`, `Ψ = Ψ̃(q)`
    /// (or the `σᵢ`), `r̃_b = 0`, no command in flight, and `α`, the run's start time and the
    /// recovery count from `keep`. Every field the law reads is written (the slots of the
    /// command history past its length are not: they are never read).
    #[inline(always)]
    fn initial_into(&self, keep: &Keep<T, N>, meas: &Meas<T, A, N>, s: &mut St<T, A, N>) {
        let q = &meas.joints;
        let lim = &self.params.joint_limits;
        s.alpha = keep.alpha;
        s.q_hat = *q;
        s.sigma = SVector::zeros();
        s.r_tilde = Pose::identity();
        s.heading_lag = T::zero();
        s.t0 = keep.t0;
        s.initialized = true;
        s.last_t = meas.t;
        s.last_target_velocity = meas.target_velocity;
        s.last_target_rate = Vector::zeros();
        s.recoveries = keep.recoveries;
        match &self.params.secondary.weight {
            Weight::Constant(psi) => s.psi = *psi,
            Weight::Filtered { margins, .. } | Weight::FromFilteredJoints { margins } => {
                s.psi = self.psi_tilde_of(q, &self.target_seen(meas), margins);
            }
            Weight::PerJoint { margins, .. } => {
                for i in 0..N {
                    s.sigma[i] = sigma_tilde_joint(q[i], lim.lower[i], lim.upper[i], margins, i).0;
                }
                s.psi = self.psi_of_sigma(&s.sigma, q);
            }
        }
        s.forget_commands();
    }

    /// The target seen from the measured base, `r_bd`.
    #[inline(always)]
    fn target_seen(&self, meas: &Meas<T, A, N>) -> Rel<T, A, N> {
        A::Space::relative(&meas.base, meas.base.theta.sincos(), &meas.target)
    }

    /// How the target's body velocity is extrapolated from the measurement (`u̇_d`, `ü_d`
    /// at `t_k`), and the raw difference quotient (remembered for the next step).
    ///
    /// The quotients `q_k = (u_k − u_{k−1})/(t_k − t_{k−1}) ≈ u̇_d(t_k − h/2)` of two steps
    /// give `ü_d ≈ (q_k − q_{k−1})/h` and `u̇_d(t_k) ≈ q_k + h/2 ü_d`: extrapolated over `s`,
    /// the velocity is off by `O(s³ u⃛_d)` instead of `O(s (s + h) ü_d)` with `q_k` alone —
    /// which with a delay of a few periods is the largest term of the error floor. The
    /// estimate is used only when the two quotients agree to within half their size: a jump
    /// of `u_d` (the paper's trajectory 2) or noise that dominates the rate is not
    /// extrapolated.
    #[allow(clippy::type_complexity)]
    fn target_rate(
        &self,
        st: &St<T, A, N>,
        meas: &Meas<T, A, N>,
    ) -> (TargetTrend<<A::Space as Space<T>>::Vector>, <A::Space as Space<T>>::Vector) {
        let zero = Vector::zeros();
        let gap = meas.t - st.last_t;
        if self.params.target_motion == TargetMotion::Held || gap <= T::zero() {
            return (TargetTrend::held(), zero);
        }
        let quotient = (meas.target_velocity - st.last_target_velocity) / gap;
        let prev = st.last_target_rate;
        let scale = quotient.amax().max(prev.amax());
        if (quotient - prev).amax() > T::of(0.5) * scale {
            return (TargetTrend::held(), quotient);
        }
        let curvature = (quotient - prev) / gap;
        (TargetTrend { rate: quotient + curvature * (gap * T::of(0.5)), curvature }, quotient)
    }

    /// `Ψ` and its rate (or the `σᵢ` rates) for filter values `psi`/`sigma` at joints `q`,
    /// filtered joints `q̂` moving at `q̂̇`.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn weight_at(
        &self,
        psi: T,
        sigma: &SVector<T, N>,
        q: &SVector<T, N>,
        q_hat: &SVector<T, N>,
        q_hat_rate: &SVector<T, N>,
        r_bd: &Rel<T, A, N>,
    ) -> WeightAt<T, N> {
        let lim = &self.params.joint_limits;
        let mut sigma_rate = SVector::<T, N>::zeros();
        let inv_n = T::one() / T::of(N as f64);
        let (psi, psi_rate) = match &self.params.secondary.weight {
            Weight::Constant(c) => (*c, T::zero()),
            Weight::Filtered { margins, lambda, xi } => {
                let target = self.psi_tilde_of(q, r_bd, margins);
                (psi, bounded_filter_rate(psi, target, *lambda, *xi))
            }
            Weight::PerJoint { margins, lambda, xi } => {
                let mut rate = T::zero();
                for i in 0..N {
                    let target = sigma_tilde_joint(q[i], lim.lower[i], lim.upper[i], margins, i).0;
                    sigma_rate[i] = bounded_filter_rate(sigma[i], target, *lambda, *xi);
                    rate += T::of(2.0) * sigma[i] * sigma_rate[i] * inv_n;
                }
                match self.arm.weight_terms(&self.params.primary, q_hat, None, true) {
                    None => (sigma.dot(sigma) * inv_n, rate),
                    Some(terms) => {
                        // The arm's terms have no filter of their own: at q̂, as in the third
                        // variant.
                        let (psi, d, g) = psi_with_terms(sigma, &terms);
                        (psi, d.dot(&sigma_rate) + g.dot(q_hat_rate))
                    }
                }
            }
            Weight::FromFilteredJoints { margins } => {
                let (p, grad) = self.psi_tilde_gradient_of(q_hat, margins);
                (p, grad.dot(q_hat_rate))
            }
        };
        WeightAt { psi, psi_rate, sigma_rate }
    }

    /// `Ψ̃(q)` of (52) with the arm's own terms ([`Manipulator::weight_terms`], a spatial
    /// arm's reach); exactly the paper's for an arm without any.
    #[inline(always)]
    fn psi_tilde_of(&self, q: &SVector<T, N>, r_bd: &Rel<T, A, N>, margins: &WeightMargins<T, N>) -> T {
        let lim = &self.params.joint_limits;
        match self.arm.weight_terms(&self.params.primary, q, Some(r_bd), false) {
            None => psi_tilde_value(q, &lim.lower, &lim.upper, margins),
            Some(terms) => psi_with_terms(&sigma_tildes(q, &lim.lower, &lim.upper, margins).0, &terms).0,
        }
    }

    /// [`Self::psi_tilde_of`] with its gradient.
    #[inline(always)]
    fn psi_tilde_gradient_of(&self, q: &SVector<T, N>, margins: &WeightMargins<T, N>) -> (T, SVector<T, N>) {
        let lim = &self.params.joint_limits;
        match self.arm.weight_terms(&self.params.primary, q, None, true) {
            None => psi_tilde(q, &lim.lower, &lim.upper, margins),
            Some(terms) => {
                let (sigma, ds) = sigma_tildes(q, &lim.lower, &lim.upper, margins);
                let (psi, d, g) = psi_with_terms(&sigma, &terms);
                (psi, d.component_mul(&ds) + g)
            }
        }
    }

    /// `Ψ = (1/N) Σ σᵢ²` of the filtered `σᵢ` (54), with the arm's terms at the filtered
    /// joints `q̂` (they have no filter of their own).
    #[inline(always)]
    fn psi_of_sigma(&self, sigma: &SVector<T, N>, q_hat: &SVector<T, N>) -> T {
        match self.arm.weight_terms(&self.params.primary, q_hat, None, false) {
            None => sigma.dot(sigma) / T::of(N as f64),
            Some(terms) => psi_with_terms(sigma, &terms).0,
        }
    }

    /// One step from `state`, which is written only at the end, once everything is known to
    /// be finite: the phases 2–6 of the module docs in turn, each a function of its own
    /// (inlined here) that takes what it needs and returns what it found.
    ///
    /// Never inlined: it is the whole law, and the step, the first step and the recovery
    /// share this one copy. Inlined into each (and into every caller of `step`), it was
    /// four copies per law instance in a firmware image (15–35 kB each in `f32` on a
    /// Cortex-M4F), and their merged stack frames made the step's stack 5 kB.
    ///
    /// The phases are `#[inline(always)]`, and the structs they hand on cost nothing once
    /// inlined — as long as no reference into one reaches a function that is not inlined
    /// (`psi_tilde`, `tracking_cost_sc`, the spatial arm's law; in `f64` most of the
    /// arithmetic): the compiler keeps a struct in registers only if no pointer into it
    /// escapes, and otherwise keeps all of it in memory for the whole step. Such a field is
    /// handed on as a copy (`&{ pred.start.q }`): without the copy of `r_bd` alone, an
    /// `f64` step on the Cortex-M4F took ~720 instructions and 270 B of stack more.
    ///
    /// The output is written into `out` (the diagnostics as they are found, the command once
    /// everything is known to be finite): no copy of it is made. `reference` is the command
    /// the acceleration limits count from ([`Reference`]); `None`: the state's last command
    /// (read only when there are acceleration limits).
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    fn compute(
        &self,
        state: &mut St<T, A, N>,
        meas: &Meas<T, A, N>,
        h: T,
        delay: T,
        first_guess: Option<&Sent<T, N>>,
        reference: Option<&Reference<T, N>>,
        out: &mut Out<T, A, N>,
    ) -> Result<(), Rejected<T, N>> {
        let st: &St<T, A, N> = state;
        // The command the acceleration limits count from, when there are any.
        let reference = if self.platform_accel || self.joint_accel {
            Some(reference.copied().unwrap_or_else(|| Reference::sent_by(st)))
        } else {
            None
        };
        let pred = self.predict(st, meas, h, delay, first_guess)?;
        let filters = self.filters_at_te(st, &pred);
        let platform = self.platform_at_te(st, &pred, &filters, reference.as_ref())?;
        let arm = self.arm_at_te(st, &pred, &filters, &platform.step, reference.as_ref())?;
        let found = Phases { pred: &pred, filters: &filters, platform: &platform, arm: &arm };
        let update = self.state_after(st, meas, &found);
        self.diagnostics_into(st, meas, &found, &mut out.diagnostics);
        if !all_finite(&arm.command, &update, &out.diagnostics) {
            return Err(StepError::NumericalFailure.into());
        }
        out.command = arm.command;
        update.commit(state);
        Ok(())
    }

    /// Phase 2, prediction: the robot when the command starts (`t_k + τ`), the target at `t_e`,
    /// and the hold they are predicted over: `t_e = t_k + τ + h/2`, the middle of the hold
    /// ([`Discretisation::Midpoint`]), or the measurement itself and `t_e = t_k`
    /// ([`Discretisation::Sampled`], which uses the delay in the joint guard only).
    ///
    /// # Errors
    /// [`StepError::TargetYawUndefined`] when the target's projection on the plane has none.
    #[inline(always)]
    fn predict(
        &self,
        st: &St<T, A, N>,
        meas: &Meas<T, A, N>,
        h: T,
        delay: T,
        first_guess: Option<&Sent<T, N>>,
    ) -> Result<Prediction<T, N, A::Space>, StepError> {
        let lim = &self.params.joint_limits;
        let measured_delay = delay;
        let (half, delay) = if self.midpoint { (h * T::of(0.5), delay) } else { (T::zero(), T::zero()) };
        let target = self.target_at_te(st, meas, delay + half)?;
        let start = if self.midpoint {
            hold::in_flight::<T, P, A::Space, N>(st, meas, delay, lim)
        } else {
            Start::measured(meas)
        };
        // The joint guard's reference: the joints when the command starts to act, also in the
        // sampled law, which otherwise ignores the delay (with a delay the command in flight
        // keeps moving them towards a limit).
        let q_guard = if !self.midpoint && measured_delay > T::zero() {
            hold::in_flight::<T, P, A::Space, N>(st, meas, measured_delay, lim).q
        } else {
            start.q
        };
        Ok(Prediction {
            hold: Hold { period: h, half, guess_u_bar: st.last_u_bar, guess_w: st.last_w },
            start,
            q_guard,
            guess: first_guess.copied().unwrap_or_else(|| st.last_sent()),
            target,
            t_e: (meas.t - st.t0 + delay + half).max(T::zero()),
        })
    }

    /// Phase 2, prediction of the target: `r_bd` and `u_d` `s` seconds after the measurement (at
    /// `t_e`), extrapolated with the target's trend ([`Self::target_rate`]) by the midpoint
    /// law, as measured by the sampled one, and their projection on the plane (§5).
    ///
    /// ```text
    /// u_d(t_k + s) = u_d + s u̇_d + s²/2 ü_d,    r_bd(t_k + s) = r_bd exp(s ū_d),
    /// ū_d = u_d + s/2 u̇_d + s²/6 ü_d (the mean velocity over [t_k, t_k + s])
    /// ```
    ///
    /// # Errors
    /// [`StepError::TargetYawUndefined`] when the projection has no yaw.
    #[inline(always)]
    fn target_at_te(
        &self,
        st: &St<T, A, N>,
        meas: &Meas<T, A, N>,
        s: T,
    ) -> Result<TargetAtTe<T, A::Space>, StepError> {
        let (trend, quotient) =
            if self.midpoint { self.target_rate(st, meas) } else { (TargetTrend::held(), Vector::zeros()) };
        let sc_b = meas.base.theta.sincos();
        let r_bd = A::Space::relative(&meas.base, sc_b, &meas.target);
        let u_d0 = &meas.target_velocity;
        let r_bd =
            if self.midpoint { A::Space::advance(&r_bd, &trend.mean_velocity(u_d0, s), s) } else { r_bd };
        let u_d = trend.velocity_after(u_d0, s);
        let Some((plane_r_bd, plane_u_d)) = A::Space::project(&r_bd, &u_d) else {
            return Err(StepError::TargetYawUndefined);
        };
        Ok(TargetAtTe { quotient, sc_b, r_bd, u_d, plane_r_bd, plane_u_d })
    }

    /// Phase 3, the filters at `t_e`: half an explicit step from `t_k + τ`, kept in `[0, 1]`.
    ///
    /// ```text
    /// q̂(t_e) = q̂ + h/2 q̂̇(t_k + τ),    Ψ(t_e) = Ψ + h/2 Ψ̇(t_k + τ)  (or the σᵢ likewise)
    /// ```
    #[inline(always)]
    fn filters_at_te(&self, st: &St<T, A, N>, pred: &Prediction<T, N, A::Space>) -> FiltersAtTe<T, N> {
        let p = &self.params.primary;
        let (q, half) = (&{ pred.start.q }, pred.hold.half);
        let q_hat_rate = filter_rate(&st.q_hat, q, p.filter_sigma, p.filter_xi);
        let q_hat = st.q_hat + q_hat_rate * half;
        let r_bd = &{ pred.target.r_bd };
        let w0 = self.weight_at(st.psi, &st.sigma, q, &st.q_hat, &q_hat_rate, r_bd);
        let (psi, sigma) = match &self.params.secondary.weight {
            Weight::FromFilteredJoints { .. } => {
                (self.weight_at(T::zero(), &st.sigma, q, &q_hat, &q_hat_rate, r_bd).psi, st.sigma)
            }
            Weight::PerJoint { .. } => {
                let sigma = (st.sigma + w0.sigma_rate * half).map(|x| clamp(x, T::zero(), T::one()));
                (self.psi_of_sigma(&sigma, &q_hat), sigma)
            }
            _ => (clamp(w0.psi + w0.psi_rate * half, T::zero(), T::one()), st.sigma),
        };
        FiltersAtTe { q_hat, psi, sigma, psi_rate: w0.psi_rate }
    }

    /// Phase 4, the platform law at `t_e`, evaluated where the previous command would take it: the
    /// companion frame at `α_e = α + h/2 α̇_prev`, the target seen from the base moved by the
    /// previous command, the rest cost at `t_e` and, for the car, the steering error when the
    /// command starts.
    ///
    /// # Errors
    /// [`StepError::NumericalFailure`] when the companion frame cannot be computed.
    #[inline(always)]
    fn platform_at_te(
        &self,
        st: &St<T, A, N>,
        pred: &Prediction<T, N, A::Space>,
        filters: &FiltersAtTe<T, N>,
        reference: Option<&Reference<T, N>>,
    ) -> Result<PlatformAtTe<T>, StepError> {
        let (start, half) = (&pred.start, pred.hold.half);
        let alpha_rate_prev = P::alpha_rate(&st.last_w);
        let alpha_e = st.alpha + alpha_rate_prev * half;
        let frame = if self.midpoint {
            self.platform.companion_with_derivative(&alpha_e)
        } else {
            self.platform.companion(&alpha_e)
        };
        let Some(frame) = frame else {
            return Err(StepError::NumericalFailure);
        };
        let r_bd = if half > T::zero() {
            let guess = &pred.guess.platform;
            let base = Self::base_at_te(start, guess.v_xi, half, |xi| P::body_velocity_of(guess, xi));
            base.inverse().compose(&pred.target.plane_r_bd)
        } else {
            pred.target.plane_r_bd
        };
        let rest = self.rest_at_te(st, half);
        // The heading filter at t_e (half an explicit step, as the other filters), and the
        // target its law sees.
        let u_d = pred.target.plane_u_d;
        let (r_bd, u_d, heading) = match &self.params.secondary.heading_filter {
            Some(f) => {
                let lag = st.heading_lag + heading_rates(st.heading_lag, u_d[2], f).1 * half;
                let (turn, lag_rate) = heading_rates(lag, u_d[2], f);
                let (r_bd, u_d) = heading_filtered(&r_bd, &u_d, lag, turn);
                (r_bd, u_d, HeadingAtTe { lag, lag_rate })
            }
            None => (r_bd, u_d, HeadingAtTe { lag: T::zero(), lag_rate: T::zero() }),
        };
        let xi_error = if P::KIND == PlatformKind::Car {
            // ξ_f when the command starts: ξ_f(α_e) less its change over the first half.
            start.xi - (frame.xi_f - frame.dxi_f.dot(&alpha_rate_prev) * half)
        } else {
            T::zero()
        };
        let point = PlatformPoint {
            r_bd: &r_bd,
            frame: &frame,
            u_d: &u_d,
            psi: filters.psi,
            psi_rate: filters.psi_rate,
            rest: rest.as_ref(),
            xi_error,
            xi: start.xi,
        };
        // The acceleration limits count from the previous command sent (crate::acceleration).
        let previous = match reference {
            Some(r) if self.platform_accel => {
                Some(Previous { w: r.w, u_bar: r.u_bar, limits: self.input_acceleration })
            }
            _ => None,
        };
        let law = PlatformLaw {
            params: &self.params,
            platform: &self.platform,
            r_star_inv: &self.r_star_inv,
            previous,
        };
        let step = law.platform_step(&point, &pred.hold);
        Ok(PlatformAtTe { step, alpha_rate: P::alpha_rate(&step.w), rest, det_h: frame.det_h, heading })
    }

    /// The base at `t_e` relative to the measurement, moved from `t_k + τ` over `h/2` by a
    /// command whose body velocity at steering `ξ` is `u_b(ξ)`, taken at the steering's mean
    /// over that half:
    ///
    /// ```text
    /// E_e = E_τ exp(h/2 u_b(ξ + h/4 v_ξ))
    /// ```
    #[inline(always)]
    fn base_at_te(start: &Start<T, N>, v_xi: T, half: T, u_b: impl Fn(T) -> Vector3<T>) -> PoseSc<T> {
        let xi_mean = start.xi + v_xi * half * T::of(0.5);
        start.base.compose(&PoseSc::exp(&u_b(xi_mean), half))
    }

    /// The rest filter's cost at `t_e` (phase 4), when `Ψ ≢ 1`: at `r̃_b` half an explicit
    /// step on, with the previous command's `ū_b` (eq. (28)).
    ///
    /// ```text
    /// r̃_b(t_e) = r̃_b + h/2 (drift − Q ū_b,prev)
    /// ```
    #[inline(always)]
    fn rest_at_te(&self, st: &St<T, A, N>, half: T) -> Option<RestCost<T>> {
        if !self.rest_needed {
            return None;
        }
        let sec = &self.params.secondary;
        let r0 = rest_cost(&st.r_tilde, &sec.rest_sigma, sec.rest_xi, sec.gamma_2);
        if half > T::zero() {
            let rate = r0.drift - r0.q * st.last_u_bar;
            let r = &st.r_tilde;
            let r_e = Pose::new(r.x + rate[0] * half, r.y + rate[1] * half, r.theta + rate[2] * half);
            Some(rest_cost(&r_e, &sec.rest_sigma, sec.rest_xi, sec.gamma_2))
        } else {
            Some(r0)
        }
    }

    /// Phase 5, the arm law at `t_e`, along the new platform command `plat`: the law (30) with the
    /// base and the target where that command takes them, the joints where the guessed joint
    /// command takes them, and the joint guard; and the command the two laws make.
    ///
    /// # Errors
    /// What the arm law rejects (see `arm_law`).
    #[inline(always)]
    fn arm_at_te(
        &self,
        st: &St<T, A, N>,
        pred: &Prediction<T, N, A::Space>,
        filters: &FiltersAtTe<T, N>,
        plat: &PlatformStep<T>,
        reference: Option<&Reference<T, N>>,
    ) -> Result<ArmAtTe<T, N, A::Space>, StepError> {
        let p = &self.params.primary;
        let (start, half) = (&pred.start, pred.hold.half);
        let xi_mid = start.xi + plat.v_xi * half;
        let u_b = P::body_velocity(&plat.w, xi_mid);
        let base = if half > T::zero() {
            Self::base_at_te(start, plat.v_xi, half, |xi| P::body_velocity(&plat.w, xi))
        } else {
            start.base
        };
        let r_bd = if self.midpoint {
            A::Space::seen_from_moved_base(&base, &{ pred.target.r_bd })
        } else {
            pred.target.r_bd
        };
        let previous = match reference {
            Some(r) if self.joint_accel => Some(r.joints),
            _ => None,
        };
        let joints = self.joints_at_te(st, pred, &u_b);
        let gamma = self.regularisation(pred.t_e);
        let (q_hat, u_d) = (filters.q_hat, pred.target.u_d);
        let q_hat_rate = filter_rate(&q_hat, &joints.q, p.filter_sigma, p.filter_xi);
        let law =
            ArmLaw { params: &self.params, arm: &self.arm, star: &self.star, braking: self.joint_accel };
        let mut step = law.arm_step(
            &TaskPoint {
                q: &joints.q,
                r_bd: &r_bd,
                u_d: &u_d,
                u_b: &u_b,
                gamma,
                gamma_rate: -p.regularisation_decay * gamma,
                q_hat: &q_hat,
                q_hat_rate: &q_hat_rate,
                guess: &joints.guess,
            },
            &pred.q_guard,
            pred.hold.period,
            half,
        )?;
        let joint_acceleration = match &previous {
            Some(p) => law.limit_change(&mut step, p, &pred.q_guard, pred.hold.period),
            None => T::one(),
        };
        let command = Command { platform: P::command(&plat.w, plat.v_xi, xi_mid), joints: step.task.u_q };
        Ok(ArmAtTe { step, command, base, q_hat_rate, joint_acceleration })
    }

    /// The joint command's guess and the joints at `t_e` (phase 5), for a platform moving at
    /// `u_b`: the last joint command plus its answer to the change of the platform's
    /// velocity (`∂u_q/∂u_b` of the last step), and the joints it takes over `h/2`, kept
    /// inside their limits. The feed-forward `∂e_m/∂r_bd ṙ_bd` depends on q, so the joints'
    /// midpoint must be accurate when the platform manoeuvres quickly (T2 (a) at 10 ms: 71 %
    /// tracked with the last command alone, 99 % with this).
    ///
    /// ```text
    /// u_q,guess = u_q,prev + ∂u_q/∂u_b (u_b − u_b,prev),    q(t_e) = q(t_k + τ) + h/2 u_q,guess
    /// ```
    ///
    /// (Not limited by the joints' acceleration limits: where they act, the arm law's linear
    /// correction over the hold takes the difference to the command, as it does any guess's.)
    #[inline(always)]
    fn joints_at_te(
        &self,
        st: &St<T, A, N>,
        pred: &Prediction<T, N, A::Space>,
        u_b: &Vector3<T>,
    ) -> JointsAtTe<T, N> {
        let (start, half, guess) = (&pred.start, pred.hold.half, &pred.guess);
        let guess = if half > T::zero() {
            guess.joints + st.last_sensitivity * (u_b - P::body_velocity_of(&guess.platform, start.xi))
        } else {
            guess.joints
        };
        let q = if half > T::zero() {
            advance_inside(&{ start.q }, &(guess * half), &self.params.joint_limits, T::of(0.5))
        } else {
            start.q
        };
        JointsAtTe { guess, q }
    }

    /// `γ(t_e) = γ₀ e^{−λ_Γ t_e}` of `Γ(t) = γ(t) I` in (22), `t_e` seconds after the run's
    /// first step (phase 5).
    #[inline(always)]
    fn regularisation(&self, t_e: T) -> T {
        let p = &self.params.primary;
        if p.regularisation_gain > T::zero() {
            p.regularisation_gain * (-p.regularisation_decay * t_e).exponential()
        } else {
            T::zero()
        }
    }

    /// Phase 6, the state after the period: `α` exactly (its rate is held), the filters by the
    /// midpoint rule (their rates at `t_e`; with `Sampled`, explicit Euler), the commands and
    /// the measurement remembered for the next step.
    #[inline(always)]
    fn state_after(
        &self,
        st: &St<T, A, N>,
        meas: &Meas<T, A, N>,
        found: &Phases<'_, T, N, A::Space>,
    ) -> Update<T, N, A::Space> {
        let Phases { pred, filters, platform, arm } = *found;
        let h = pred.hold.period;
        let after = self.filters_after(st, pred, filters, arm);
        let plat = &platform.step;
        Update {
            alpha: wrap_alpha(st.alpha + platform.alpha_rate * h),
            q_hat: after.q_hat,
            psi: after.psi,
            sigma: after.sigma,
            r_tilde: self.rest_after(st, platform, h),
            // δ⁺ = δ + h δ̇(t_e), the midpoint rule as for the other filters.
            heading_lag: wrap_angle(st.heading_lag + platform.heading.lag_rate * h),
            w: plat.w,
            u_bar: plat.u_bar,
            sensitivity: arm.step.task.sensitivity,
            t: meas.t,
            target_velocity: meas.target_velocity,
            target_rate: pred.target.quotient,
            sent: Sent { platform: arm.command.platform, joints: arm.command.joints, period: h },
        }
    }

    /// The filters after the period (phase 6) by the midpoint rule: their rates at `t_e`,
    /// with the joints `q(t_e) = q(t_k + τ) + h/2 u_q` of the new command; `q̂` kept within
    /// the joint limits, `Ψ` (or the `σᵢ`) in `[0, 1]`.
    ///
    /// ```text
    /// q̂⁺ = q̂ + h q̂̇(t_e),    Ψ⁺ = Ψ + h Ψ̇(t_e)  (or the σᵢ likewise)
    /// ```
    #[inline(always)]
    fn filters_after(
        &self,
        st: &St<T, A, N>,
        pred: &Prediction<T, N, A::Space>,
        filters: &FiltersAtTe<T, N>,
        arm: &ArmAtTe<T, N, A::Space>,
    ) -> FiltersAfter<T, N> {
        let lim = &self.params.joint_limits;
        let (h, half) = (pred.hold.period, pred.hold.half);
        let q_mid = pred.start.q + arm.command.joints * half;
        let q_hat = st.q_hat + arm.q_hat_rate * h;
        let r_bd = &{ pred.target.r_bd };
        let w_mid =
            self.weight_at(filters.psi, &filters.sigma, &q_mid, &{ filters.q_hat }, &arm.q_hat_rate, r_bd);
        let q_hat = SVector::from_fn(|i, _| clamp(q_hat[i], lim.lower[i], lim.upper[i]));
        let (psi, sigma) = match &self.params.secondary.weight {
            Weight::Filtered { .. } => (clamp(st.psi + w_mid.psi_rate * h, T::zero(), T::one()), st.sigma),
            Weight::PerJoint { .. } => {
                let sigma = (st.sigma + w_mid.sigma_rate * h).map(|x| clamp(x, T::zero(), T::one()));
                (self.psi_of_sigma(&sigma, &q_hat), sigma)
            }
            Weight::Constant(_) | Weight::FromFilteredJoints { .. } => (st.psi, st.sigma),
        };
        FiltersAfter { q_hat, psi, sigma }
    }

    /// `r̃_b` after the period (phase 6): an explicit step of (28) with the rates at `t_e`
    /// and the platform's actual `ū_b`, its position kept within `±rest_reach`, its angle
    /// wrapped. Not part of the law when `Ψ ≡ 1`: kept at its initial value.
    ///
    /// ```text
    /// r̃_b⁺ = r̃_b + h (drift − Q ū_b,actual)
    /// ```
    #[inline(always)]
    fn rest_after(&self, st: &St<T, A, N>, platform: &PlatformAtTe<T>, h: T) -> Pose<T> {
        let Some(rest) = &platform.rest else {
            return Pose::identity();
        };
        let rate = rest.drift - rest.q * platform.step.u_bar_actual;
        let r = &st.r_tilde;
        let reach = self.params.secondary.rest_reach;
        Pose::new(
            clamp(r.x + rate[0] * h, -reach, reach),
            clamp(r.y + rate[1] * h, -reach, reach),
            wrap_angle(r.theta + rate[2] * h),
        )
    }

    /// What the step reports, written into `d`: the terms of both laws at `t_e`, the
    /// filter's weight there, `α` and its rate, the companion frame `r_b E_e f(α)⁻¹` in the
    /// world, and the factors of the limits.
    #[inline(always)]
    fn diagnostics_into(
        &self,
        st: &St<T, A, N>,
        meas: &Meas<T, A, N>,
        found: &Phases<'_, T, N, A::Space>,
        d: &mut Diagnostics<T, N, A::Space>,
    ) {
        let Phases { pred, filters, platform, arm } = *found;
        let (plat, prim) = (&platform.step, &arm.step.task);
        let sc_b = pred.target.sc_b;
        d.e_p = prim.e_p;
        d.e_m = prim.e_m;
        d.h_s = plat.h_s;
        d.h_s1 = plat.h_s1;
        d.h_s2 = plat.h_s2;
        d.psi = filters.psi;
        d.joint_penalty = prim.h_l;
        d.saturation = plat.saturation;
        d.joint_scale = arm.step.joint_scale;
        d.platform_acceleration = plat.acceleration;
        d.joint_acceleration = arm.joint_acceleration;
        d.det_h = platform.det_h;
        d.heading_lag = platform.heading.lag;
        d.condition = prim.condition;
        d.alpha = st.alpha;
        d.alpha_rate = platform.alpha_rate;
        d.u_bar = plat.u_bar;
        d.companion = if self.midpoint {
            PoseSc { pose: meas.base, sc: sc_b }.compose(&arm.base).compose(&plat.f_inv).pose
        } else {
            meas.base.compose_sc(&plat.f_inv.pose, sc_b.0, sc_b.1)
        };
        d.implicitness = plat.theta;
        d.recovered = false;
    }
}

/// What phase 2 predicts: the hold, the robot when the command starts to act (`t_k + τ`),
/// the target at `t_e`.
#[derive(Clone, Copy, Debug)]
struct Prediction<T: Real, const N: usize, S: Space<T>> {
    /// The hold: its period `h` (s), the point `h/2` into it (0 with `Sampled`), the previous
    /// command's `ū_b` and `w`.
    hold: Hold<T>,
    /// The robot at `t_k + τ` (the measurement itself with `Sampled`).
    start: Start<T, N>,
    /// The joint guard's reference: the joints when the command starts to act (also with
    /// `Sampled`).
    q_guard: SVector<T, N>,
    /// The previous command (or, on a first step's second pass, the first pass's).
    guess: Sent<T, N>,
    /// The target at `t_e`.
    target: TargetAtTe<T, S>,
    /// `t_e − t₀ ≥ 0` (s): the time since the run's first step, which `Γ` decays with.
    t_e: T,
}

/// The target at `t_e` (phase 2), seen from the base as measured.
#[derive(Clone, Copy, Debug)]
struct TargetAtTe<T: Real, S: Space<T>> {
    /// `(u_d,k − u_d,k−1)/(t_k − t_{k−1})`, remembered for the next step's trend (zero with
    /// `Sampled`).
    quotient: S::Vector,
    /// `(sin θ_b, cos θ_b)` of the measured base.
    sc_b: (T, T),
    /// `r_bd(t_e)`.
    r_bd: S::Relative,
    /// `u_d(t_e)`.
    u_d: S::Vector,
    /// `r_bd(t_e)` projected on the plane (§5).
    plane_r_bd: PoseSc<T>,
    /// `u_d(t_e)` projected on the plane.
    plane_u_d: Vector3<T>,
}

/// What phases 2–5 of a step found, as phase 6 and the diagnostics read it.
#[derive(Clone, Copy, Debug)]
struct Phases<'a, T: Real, const N: usize, S: Space<T>> {
    /// Phase 2: the hold, the robot when the command starts, the target at `t_e`.
    pred: &'a Prediction<T, N, S>,
    /// Phase 3: the filters at `t_e`.
    filters: &'a FiltersAtTe<T, N>,
    /// Phase 4: the platform law at `t_e`.
    platform: &'a PlatformAtTe<T>,
    /// Phase 5: the arm law at `t_e` and the command.
    arm: &'a ArmAtTe<T, N, S>,
}

/// The filters at `t_e` (phase 3).
#[derive(Clone, Copy, Debug)]
struct FiltersAtTe<T, const N: usize> {
    /// `q̂(t_e)`.
    q_hat: SVector<T, N>,
    /// `Ψ(t_e)`.
    psi: T,
    /// The `σᵢ(t_e)` (the state's unless the weight is per joint).
    sigma: SVector<T, N>,
    /// `Ψ̇(t_k + τ)`.
    psi_rate: T,
}

/// The platform law at `t_e` (phase 4).
#[derive(Clone, Copy, Debug)]
struct PlatformAtTe<T> {
    /// The new platform command and the terms of its law.
    step: PlatformStep<T>,
    /// `α̇` of the new command (held over the period).
    alpha_rate: Vector2<T>,
    /// The rest filter's cost at `t_e` (when `Ψ ≢ 1`).
    rest: Option<RestCost<T>>,
    /// `det H(α_e)` of the companion frame.
    det_h: T,
    /// The heading filter at `t_e` (zeros without one).
    heading: HeadingAtTe<T>,
}

/// The heading filter's lag `δ(t_e)` and its rate there (phase 4).
#[derive(Clone, Copy, Debug)]
struct HeadingAtTe<T> {
    lag: T,
    lag_rate: T,
}

/// The arm law at `t_e` (phase 5) and the command of the step.
#[derive(Clone, Copy, Debug)]
struct ArmAtTe<T: Real, const N: usize, S: Space<T>> {
    /// The arm law after the joint guard.
    step: ArmStep<T, N, S>,
    /// The command: the new platform command and `u_q`.
    command: Command<T, N>,
    /// `E_e = r_b⁻¹ r_b(t_e)`: the base at `t_e` along the new platform command, relative to
    /// the measurement.
    base: PoseSc<T>,
    /// `q̂̇(t_e)`: the filter's rate at `q̂(t_e)`, `q(t_e)`.
    q_hat_rate: SVector<T, N>,
    /// The joint acceleration factor `1/β_q ≥ 1` ([`crate::acceleration`]).
    joint_acceleration: T,
}

/// The joints the arm law is evaluated at (phase 5).
#[derive(Clone, Copy, Debug)]
struct JointsAtTe<T, const N: usize> {
    /// The joint command's guess (rad/s or m/s).
    guess: SVector<T, N>,
    /// `q(t_e)`: the joints at `t_k + τ` moved by the guess over `h/2`.
    q: SVector<T, N>,
}

/// The filters after the period (phase 6).
#[derive(Clone, Copy, Debug)]
struct FiltersAfter<T, const N: usize> {
    /// `q̂⁺`, within the joint limits.
    q_hat: SVector<T, N>,
    /// `Ψ⁺`.
    psi: T,
    /// The `σᵢ⁺`.
    sigma: SVector<T, N>,
}

/// What an accepted step changes in the state (small, so that the state is written in
/// place and only once everything is known to be finite).
#[derive(Clone, Copy, Debug)]
struct Update<T: Real, const N: usize, S: Space<T>> {
    alpha: Vector2<T>,
    q_hat: SVector<T, N>,
    psi: T,
    sigma: SVector<T, N>,
    r_tilde: Pose<T>,
    heading_lag: T,
    w: Vector3<T>,
    u_bar: Vector3<T>,
    sensitivity: SMatrix<T, N, 3>,
    t: T,
    target_velocity: S::Vector,
    target_rate: S::Vector,
    sent: Sent<T, N>,
}

impl<T: Real, const N: usize, S: Space<T>> Update<T, N, S> {
    #[inline(always)]
    fn commit(&self, state: &mut State<T, N, S>) {
        state.alpha = self.alpha;
        state.q_hat = self.q_hat;
        state.psi = self.psi;
        state.sigma = self.sigma;
        state.r_tilde = self.r_tilde;
        state.heading_lag = self.heading_lag;
        state.last_w = self.w;
        state.last_u_bar = self.u_bar;
        state.last_sensitivity = self.sensitivity;
        state.last_t = self.t;
        state.last_target_velocity = self.target_velocity;
        state.last_target_rate = self.target_rate;
        state.push_sent(self.sent);
        state.initialized = true;
    }
}

/// What a first step's pass hands the next as its guess (see `ControlLaw::start`): the
/// state's predictions of the hold and the command the pass would have sent.
#[derive(Clone, Copy)]
struct Guess<T: Real, const N: usize> {
    w: Vector3<T>,
    u_bar: Vector3<T>,
    sensitivity: SMatrix<T, N, 3>,
    sent: Sent<T, N>,
}

impl<T: Real, const N: usize> Guess<T, N> {
    #[inline(always)]
    fn of<S: Space<T>>(state: &State<T, N, S>) -> Self {
        Self {
            w: state.last_w,
            u_bar: state.last_u_bar,
            sensitivity: state.last_sensitivity,
            sent: state.last_sent(),
        }
    }

    /// This guess's predictions into a fresh `state`.
    #[inline(always)]
    fn set<S: Space<T>>(&self, state: &mut State<T, N, S>) {
        state.last_w = self.w;
        state.last_u_bar = self.u_bar;
        state.last_sensitivity = self.sensitivity;
    }
}

/// The command the acceleration limits count from ([`crate::acceleration`]): the previous
/// command sent, as the platform law's generalised inputs `w`, the companion frame's
/// velocity `ū_b` and the joint velocities.
#[derive(Clone, Copy, Debug)]
struct Reference<T: Real, const N: usize> {
    w: Vector3<T>,
    u_bar: Vector3<T>,
    joints: SVector<T, N>,
}

impl<T: Real, const N: usize> Reference<T, N> {
    /// The robot at rest (before the first command).
    fn rest() -> Self {
        Self { w: Vector3::zeros(), u_bar: Vector3::zeros(), joints: SVector::zeros() }
    }

    /// The last command `state` sent, or rest if it sent none.
    #[inline(always)]
    fn sent_by<S: Space<T>>(state: &State<T, N, S>) -> Self {
        match state.sent(0) {
            Some(sent) => Self { w: state.last_w, u_bar: state.last_u_bar, joints: sent.joints },
            None => Self::rest(),
        }
    }
}

/// What a first step (or a recovery) keeps of the state it was given (SPEC §3): `α`
/// (wrapped; 0 if not finite), the run's start time, the recovery count, and the command the
/// acceleration limits count from.
#[derive(Clone, Copy, Debug)]
struct Keep<T: Real, const N: usize> {
    alpha: Vector2<T>,
    t0: T,
    recoveries: u32,
    reference: Reference<T, N>,
}

impl<T: Real, const N: usize> Keep<T, N> {
    fn alpha_of<S: Space<T>>(state: &State<T, N, S>) -> Vector2<T> {
        wrap_alpha(state.alpha).map(|a| if a.finite() { a } else { T::zero() })
    }

    /// A run's first step: its time is the run's start, the robot at rest.
    fn first<S: Space<T>>(state: &State<T, N, S>, meas: &Measurement<T, N, S>) -> Self {
        Self {
            alpha: Self::alpha_of(state),
            t0: meas.t,
            recoveries: state.recoveries,
            reference: Reference::rest(),
        }
    }

    /// A recovery: the run's start time kept, one more recovery, the acceleration limits
    /// counting from the last command sent (the robot is moving).
    fn recovering<S: Space<T>>(state: &State<T, N, S>) -> Self {
        Self {
            alpha: Self::alpha_of(state),
            t0: state.t0,
            recoveries: state.recoveries.saturating_add(1),
            reference: Reference::sent_by(state),
        }
    }
}

/// Whether the command, the state's update and the diagnostics are all finite. `0·x` is ±0
/// for finite `x` and NaN otherwise: one comparison for everything.
fn all_finite<T: Real, const N: usize, S: Space<T>>(
    c: &Command<T, N>,
    u: &Update<T, N, S>,
    d: &Diagnostics<T, N, S>,
) -> bool {
    let z = T::zero();
    let p = &c.platform;
    let mut nan = z;
    for x in [
        p.v,
        p.v_lat,
        p.omega,
        p.v_xi,
        u.alpha[0],
        u.alpha[1],
        u.psi,
        u.r_tilde.x,
        u.r_tilde.y,
        u.r_tilde.theta,
        u.heading_lag,
    ] {
        nan += x * z;
    }
    for x in
        [d.h_s, d.h_s1, d.h_s2, d.psi, d.joint_penalty, d.saturation, d.condition, d.det_h, d.heading_lag]
    {
        nan += x * z;
    }
    for x in [d.companion.x, d.companion.y, d.companion.theta, u.u_bar[0], u.u_bar[1], u.u_bar[2]] {
        nan += x * z;
    }
    for i in 0..N {
        nan += (c.joints[i] + u.q_hat[i] + u.sigma[i] + d.e_m[i]) * z;
        for j in 0..3 {
            nan += u.sensitivity[(i, j)] * z;
        }
    }
    for (e, r) in d.e_p.as_slice().iter().zip(u.target_rate.as_slice()) {
        nan += (*e + *r) * z;
    }
    nan == z
}

/// The output of an in-place call, returned by value.
#[inline(always)]
fn by_value<T: Real, const N: usize, S: Space<T>>(
    into: impl FnOnce(&mut Output<T, N, S>) -> Result<(), Rejected<T, N>>,
) -> Result<Output<T, N, S>, Rejected<T, N>> {
    let mut out = Output::zero();
    into(&mut out)?;
    Ok(out)
}

/// `result`, with the safe command written into `out` when it is a rejection.
#[inline(always)]
fn safe_on_rejection<T: Real, const N: usize, S: Space<T>>(
    result: Result<(), Rejected<T, N>>,
    out: &mut Output<T, N, S>,
) -> Result<(), Rejected<T, N>> {
    if let Err(rejected) = &result {
        out.command = rejected.command;
    }
    result
}

/// A [`ControlLaw`] with its [`State`]: the convenient way to run one controller.
#[derive(Clone, Copy, Debug)]
pub struct Controller<T: Real, P, A: Manipulator<T, N>, const N: usize> {
    /// The validated law.
    pub law: ControlLaw<T, P, A, N>,
    /// Its state.
    pub state: St<T, A, N>,
}

impl<T: Real, P: Platform<T>, A: Manipulator<T, N>, const N: usize> Controller<T, P, A, N> {
    /// A controller with a fresh state.
    ///
    /// # Errors
    /// An invalid parameter (see [`ControlLaw::new`]).
    pub fn new(params: Params<T, N, A::Space>, platform: P, arm: A) -> Result<Self, ParamError> {
        Ok(Self { law: ControlLaw::new(params, platform, arm)?, state: State::new() })
    }

    /// One step without delay (see [`ControlLaw::step`]).
    ///
    /// # Errors
    /// A rejected measurement or period, with the safe command.
    #[inline]
    pub fn step(&mut self, meas: &Meas<T, A, N>, period: T) -> Result<Out<T, A, N>, Rejected<T, N>> {
        self.law.step(&mut self.state, meas, period)
    }

    /// One step with the measurement taken `delay` seconds before the command starts to act
    /// (see [`ControlLaw::step_delayed`]).
    ///
    /// # Errors
    /// A rejected measurement, period or delay, with the safe command.
    #[inline]
    pub fn step_delayed(
        &mut self,
        meas: &Meas<T, A, N>,
        period: T,
        delay: T,
    ) -> Result<Out<T, A, N>, Rejected<T, N>> {
        self.law.step_delayed(&mut self.state, meas, period, delay)
    }

    /// One step without delay with the output written into `out`, in place (see
    /// [`ControlLaw::step_delayed_into`]): a firmware's control loop.
    ///
    /// # Errors
    /// A rejected measurement or period, with the safe command (also in `out.command`).
    #[inline]
    pub fn step_into(
        &mut self,
        meas: &Meas<T, A, N>,
        period: T,
        out: &mut Out<T, A, N>,
    ) -> Result<(), Rejected<T, N>> {
        self.law.step_delayed_into(&mut self.state, meas, period, T::zero(), out)
    }

    /// [`step_delayed`](Self::step_delayed) with the output written into `out`, in place.
    ///
    /// # Errors
    /// A rejected measurement, period or delay, with the safe command (also in
    /// `out.command`).
    #[inline]
    pub fn step_delayed_into(
        &mut self,
        meas: &Meas<T, A, N>,
        period: T,
        delay: T,
        out: &mut Out<T, A, N>,
    ) -> Result<(), Rejected<T, N>> {
        self.law.step_delayed_into(&mut self.state, meas, period, delay, out)
    }

    /// The run's first step, taken now, outside the control loop (see
    /// [`ControlLaw::start_into`]): a firmware calls it before it enables its control
    /// interrupt, applies the command when the interrupt starts, and every step inside the
    /// interrupt is then a steady-state one. Restarts a run from rest on a state that already
    /// ran (`α` kept).
    ///
    /// # Errors
    /// A rejected measurement, period or delay, with the safe command; the state is left as
    /// it was.
    pub fn start(
        &mut self,
        meas: &Meas<T, A, N>,
        period: T,
        delay: T,
    ) -> Result<Out<T, A, N>, Rejected<T, N>> {
        self.law.start(&mut self.state, meas, period, delay)
    }

    /// [`start`](Self::start) with the output written into `out`.
    ///
    /// # Errors
    /// As [`start`](Self::start) (the safe command also in `out.command`).
    pub fn start_into(
        &mut self,
        meas: &Meas<T, A, N>,
        period: T,
        delay: T,
        out: &mut Out<T, A, N>,
    ) -> Result<(), Rejected<T, N>> {
        self.law.start_into(&mut self.state, meas, period, delay, out)
    }

    /// Forgets the state; the next step starts afresh.
    pub fn reset(&mut self) {
        self.state = State::new();
    }
}
