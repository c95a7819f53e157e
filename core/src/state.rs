//! The law's evolving quantities, apart from its (immutable) parameters.
//!
//! The filters (`α`, `q̂`, `Ψ` or `σᵢ`, `r̃_b`) run on the robot's *actuation* clock: at the
//! start of step `k` they hold their values for the moment `t_k + τ` at which the command
//! being computed starts to act (with `τ` the measurement delay, 0 by default), and an
//! accepted step advances them by the period it commands. Besides them the state keeps
//! what the hold-aware discretisation predicts from: the commands still in flight, the last
//! command (the first guess of the next one), and the last measured target velocity.

use nalgebra::{SMatrix, SVector, Vector2, Vector3};

use crate::platform::PlatformCommand;
use crate::scalar::{wrap_angle, Real};
use crate::se2::Pose;
use crate::space::{Planar, Space, Vector};

/// How many sent commands the state remembers: a delay may span at most this many periods.
pub const HISTORY: usize = 8;

/// A command the law sent, as the prediction of the robot's motion needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sent<T, const N: usize> {
    /// The platform velocities.
    pub platform: PlatformCommand<T>,
    /// The joint velocities (rad/s or m/s).
    pub joints: SVector<T, N>,
    /// How long it is held (s).
    pub period: T,
}

impl<T: Real, const N: usize> Sent<T, N> {
    fn zero() -> Self {
        let z = T::zero();
        Self {
            platform: PlatformCommand { v: z, v_lat: z, omega: z, v_xi: z },
            joints: SVector::zeros(),
            period: z,
        }
    }
}

/// The law's evolving quantities: `α`, `q̂` (26), `Ψ` (53) or `σᵢ` (54), `r̃_b` (28), the
/// heading filter's lag `δ`, and what the discretisation predicts from.
///
/// [`State::new`] is uninitialised; the first accepted step sets it per SPEC §3:
/// `q̂(0) = q(0)`, `Ψ(0) = Ψ̃(q(0))`, `σᵢ(0) = σ̃ᵢ(qᵢ(0))`, `r̃_b(0) = 0`, `δ(0) = 0`, and keeps `α`
/// (0 unless set before); the robot is taken to be at rest before it.
///
/// Bounded whatever the measurements: `α` and the angles are wrapped, `Ψ, σᵢ ∈ [0, 1]`,
/// `q̂` within the joint limits, and the position of `r̃_b` within
/// [`SecondaryTask::rest_reach`](crate::SecondaryTask::rest_reach).
///
/// Two states are equal when every quantity and the commands the history holds are (the
/// history's slots past its length are not part of the state: a first step writes its fresh
/// state in place over them).
#[derive(Clone, Copy, Debug)]
pub struct State<T: Real, const N: usize, S: Space<T> = Planar> {
    /// Transverse-function variables `α` (rad); unused components stay zero.
    pub alpha: Vector2<T>,
    /// Filtered joints `q̂`, eq. (26).
    pub q_hat: SVector<T, N>,
    /// The weight `Ψ` (for [`Weight::Filtered`](crate::Weight::Filtered)).
    pub psi: T,
    /// The filtered `σᵢ` (for [`Weight::PerJoint`](crate::Weight::PerJoint)).
    pub sigma: SVector<T, N>,
    /// `r̃_b` of the rest filter (28).
    pub r_tilde: Pose<T>,
    /// `δ = θ_d − θ̂_d` of the heading filter (rad; 0 without one,
    /// [`HeadingFilter`](crate::HeadingFilter)).
    pub heading_lag: T,
    /// The time of the first step (s).
    pub t0: T,
    /// Whether the first step has set the state.
    pub initialized: bool,
    /// The generalised platform inputs `w` of the last command (after saturation): the
    /// first guess of the next one.
    pub last_w: Vector3<T>,
    /// The companion frame's velocity `ū_b` of the last command.
    pub last_u_bar: Vector3<T>,
    /// `∂u_q/∂u_b` of the last command: with the change of the platform's velocity, it turns
    /// the last joint command into the guess of the next one.
    pub last_sensitivity: SMatrix<T, N, 3>,
    /// Time of the last accepted measurement (s).
    pub last_t: T,
    /// Target body velocity of the last accepted measurement.
    pub last_target_velocity: S::Vector,
    /// The difference quotient of the target velocity at the last accepted measurement.
    pub last_target_rate: S::Vector,
    /// How many steps re-initialised the filters after a numerical failure.
    pub recoveries: u32,
    sent: [Sent<T, N>; HISTORY],
    sent_next: usize,
    sent_len: usize,
}

impl<T: Real, const N: usize, S: Space<T>> State<T, N, S> {
    /// An uninitialised state with `α = 0`.
    pub fn new() -> Self {
        let z3 = Vector3::zeros();
        Self {
            alpha: Vector2::zeros(),
            q_hat: SVector::zeros(),
            psi: T::zero(),
            sigma: SVector::zeros(),
            r_tilde: Pose::identity(),
            heading_lag: T::zero(),
            t0: T::zero(),
            initialized: false,
            last_w: z3,
            last_u_bar: z3,
            last_sensitivity: SMatrix::zeros(),
            last_t: T::zero(),
            last_target_velocity: S::Vector::zeros(),
            last_target_rate: S::Vector::zeros(),
            recoveries: 0,
            sent: [Sent::zero(); HISTORY],
            sent_next: 0,
            sent_len: 0,
        }
    }

    /// The `i`-th most recent command sent (0: the last one), if remembered.
    pub fn sent(&self, i: usize) -> Option<&Sent<T, N>> {
        if i >= self.sent_len {
            return None;
        }
        self.sent.get((self.sent_next + HISTORY - 1 - i) % HISTORY)
    }

    /// The last command sent, or zero velocities before the first one.
    pub(crate) fn last_sent(&self) -> Sent<T, N> {
        self.sent(0).copied().unwrap_or_else(Sent::zero)
    }

    /// Remembers a command sent.
    pub(crate) fn push_sent(&mut self, s: Sent<T, N>) {
        if let Some(slot) = self.sent.get_mut(self.sent_next % HISTORY) {
            *slot = s;
        }
        self.sent_next = (self.sent_next + 1) % HISTORY;
        if self.sent_len < HISTORY {
            self.sent_len += 1;
        }
    }

    /// Forgets the commands in flight and the guess (after a re-initialisation).
    pub(crate) fn forget_commands(&mut self) {
        self.sent_len = 0;
        self.sent_next = 0;
        self.last_w = Vector3::zeros();
        self.last_u_bar = Vector3::zeros();
        self.last_sensitivity = SMatrix::zeros();
    }

    /// The same state in another scalar type (rounding to nearest for `f32`), e.g. to run
    /// one law in `f32` and `f64` from the same state.
    pub fn cast<U: Real>(&self) -> State<U, N, S>
    where
        S: Space<U>,
    {
        let c = |x: T| U::of(x.as_f64());
        let cp = |p: &PlatformCommand<T>| PlatformCommand {
            v: c(p.v),
            v_lat: c(p.v_lat),
            omega: c(p.omega),
            v_xi: c(p.v_xi),
        };
        let mut sent = [Sent::<U, N>::zero(); HISTORY];
        for (to, from) in sent.iter_mut().zip(self.sent.iter()) {
            *to = Sent { platform: cp(&from.platform), joints: from.joints.map(c), period: c(from.period) };
        }
        State {
            alpha: self.alpha.map(c),
            q_hat: self.q_hat.map(c),
            psi: c(self.psi),
            sigma: self.sigma.map(c),
            r_tilde: Pose::new(c(self.r_tilde.x), c(self.r_tilde.y), c(self.r_tilde.theta)),
            heading_lag: c(self.heading_lag),
            t0: c(self.t0),
            initialized: self.initialized,
            last_w: self.last_w.map(c),
            last_u_bar: self.last_u_bar.map(c),
            last_sensitivity: self.last_sensitivity.map(c),
            last_t: c(self.last_t),
            last_target_velocity: <S as Space<T>>::cast_vector::<U>(&self.last_target_velocity),
            last_target_rate: <S as Space<T>>::cast_vector::<U>(&self.last_target_rate),
            recoveries: self.recoveries,
            sent,
            sent_next: self.sent_next,
            sent_len: self.sent_len,
        }
    }

    /// Whether every value is finite and within its documented bounds.
    pub fn is_bounded(&self, lower: &SVector<T, N>, upper: &SVector<T, N>, reach: T) -> bool {
        let pi = T::pi();
        let angle_ok = |a: T| a > -pi && a <= pi;
        let unit = |x: T| x >= T::zero() && x <= T::one();
        angle_ok(self.alpha[0])
            && angle_ok(self.alpha[1])
            && angle_ok(self.r_tilde.theta)
            && angle_ok(self.heading_lag)
            && unit(self.psi)
            && self.sigma.iter().all(|s| unit(*s))
            && (0..N).all(|i| self.q_hat[i] >= lower[i] && self.q_hat[i] <= upper[i])
            && self.r_tilde.x.abs() <= reach
            && self.r_tilde.y.abs() <= reach
            && self.last_w.iter().chain(self.last_u_bar.iter()).all(|x| x.finite())
    }
}

impl<T: Real, const N: usize, S: Space<T>> PartialEq for State<T, N, S> {
    fn eq(&self, other: &Self) -> bool {
        self.alpha == other.alpha
            && self.q_hat == other.q_hat
            && self.psi == other.psi
            && self.sigma == other.sigma
            && self.r_tilde == other.r_tilde
            && self.heading_lag == other.heading_lag
            && self.t0 == other.t0
            && self.initialized == other.initialized
            && self.last_w == other.last_w
            && self.last_u_bar == other.last_u_bar
            && self.last_sensitivity == other.last_sensitivity
            && self.last_t == other.last_t
            && self.last_target_velocity == other.last_target_velocity
            && self.last_target_rate == other.last_target_rate
            && self.recoveries == other.recoveries
            && self.sent_len == other.sent_len
            && (0..self.sent_len).all(|i| self.sent(i) == other.sent(i))
    }
}

impl<T: Real, const N: usize, S: Space<T>> Default for State<T, N, S> {
    fn default() -> Self {
        Self::new()
    }
}

/// Wraps both components of `α`.
#[inline]
pub(crate) fn wrap_alpha<T: Real>(a: Vector2<T>) -> Vector2<T> {
    Vector2::new(wrap_angle(a[0]), wrap_angle(a[1]))
}
