//! The simulated robot: configuration, state, and the [`Plant`] that owns them.

use companion_core::nalgebra::{SVector, Vector3};
use companion_core::{Arm, Command, Measurement, Planar, PlatformKind, Pose, Space};
use rand::distr::{OpenClosed01, StandardUniform};
use rand::rngs::ChaCha12Rng;
use rand::{RngExt, SeedableRng};

use crate::dynamics::{Continuous, Model, Trig};
use crate::error::{AdvanceError, PlantError, Rule};
use crate::imperfections::{Imperfections, Noise};
use crate::initial::InitialConditions;
use crate::trajectory::Trajectory;

/// What the plant simulates: which platform, how imperfect, and the car's end stops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantConfig {
    /// The wheeled platform's kinematics.
    pub platform: PlatformKind,
    /// Lag, noise, scale error (default: none).
    pub imperfections: Imperfections,
    /// Car-like platform only: the largest `|ξ|` (1/m), `ξ = tan φ / ℓ`, where the steered
    /// wheels reach their end stops; `ξ̇` is held at 0 there while `v_ξ` pushes outward.
    /// `None` (default, the paper's model): no limit. See
    /// [`realistic_steering_limit`](crate::realistic_steering_limit).
    pub steering_limit: Option<f64>,
}

impl PlantConfig {
    /// The perfect plant of the paper for `platform`: no imperfections, no steering limit.
    pub fn new(platform: PlatformKind) -> Self {
        Self { platform, imperfections: Imperfections::default(), steering_limit: None }
    }

    /// The same configuration with `imperfections`.
    pub fn with_imperfections(self, imperfections: Imperfections) -> Self {
        Self { imperfections, ..self }
    }

    /// The same configuration with a steering limit (1/m).
    pub fn with_steering_limit(self, limit: f64) -> Self {
        Self { steering_limit: Some(limit), ..self }
    }

    /// The equations of motion of a plant so configured whose target (planar, or a spatial
    /// target's planar part) follows `trajectory`.
    pub(crate) fn model<'a>(&self, trajectory: &'a Trajectory) -> Model<'a> {
        Model {
            kind: self.platform,
            wheel_scale: 1.0 + self.imperfections.wheel_scale_error,
            lag: self.imperfections.actuator_lag,
            steering_limit: self.steering_limit,
            trajectory,
        }
    }

    /// Checks every parameter.
    ///
    /// # Errors
    /// The first parameter that breaks a rule.
    pub fn validate(&self) -> Result<(), PlantError> {
        self.imperfections.validate()?;
        if let Some(l) = self.steering_limit {
            PlantError::check_finite("steering_limit", l)?;
            if l <= 0.0 {
                return Err(PlantError::Invalid {
                    param: "steering_limit",
                    rule: Rule::NotPositive,
                    value: l,
                });
            }
        }
        Ok(())
    }
}

/// The true state of the simulated robot at one step: `N` joints, a target in `S` (the
/// plane of the paper's arm, §4, or space, §5 — [`crate::SpatialPlant`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantState<const N: usize, S: Space<f64> = Planar> {
    /// Time `t = step · dt` (s).
    pub t: f64,
    /// Step index `n` (0 before the first step).
    pub step: u64,
    /// Platform pose `r_b` (m, m, rad); `θ` continuous, never wrapped.
    pub base: Pose<f64>,
    /// Car-like platform: steering state `ξ` (1/m).
    pub steering: f64,
    /// Joint positions `q` (rad or m).
    pub joints: SVector<f64, N>,
    /// Target pose `r_d` in the world: in the plane (m, m, rad; `θ` continuous, never
    /// wrapped) or in space.
    pub target: S::Pose,
    /// Target body velocity `u_d(t)`: `(v₁, v₂, ω)` in the plane, the twist `(v, ω)` in space
    /// (m/s, rad/s). At a jump of `u_d` this is the value after the jump, the one the target
    /// follows over the next step.
    pub target_velocity: S::Vector,
    /// The velocities the robot actually has at `t`, after lag and scale error: the
    /// platform's body velocity `(v, v_lat, ω)` (for the car `ω = v ξ`), the steering rate
    /// `v_ξ` (car) and `u_q`. Fields a platform does not have are zero. Zero before the
    /// first step.
    pub applied: Command<f64, N>,
    /// The command held over the last step (zero before the first step).
    pub command: Command<f64, N>,
}

impl<const N: usize, S: Space<f64>> PlantState<N, S> {
    /// The state at the end of step `n` (at `t`): the platform and joints of the continuous
    /// state `x`, the target at `target` moving at `target_velocity`, `applied` and the
    /// `command` held over the step.
    pub(crate) fn after(
        (n, t): (u64, f64),
        x: &Continuous<N>,
        (target, target_velocity): (S::Pose, S::Vector),
        applied: Command<f64, N>,
        command: &Command<f64, N>,
    ) -> Self {
        Self {
            t,
            step: n + 1,
            base: Pose::from_vector(&x.base),
            steering: x.steering,
            joints: x.joints,
            target,
            target_velocity,
            applied,
            command: *command,
        }
    }

    /// The state as the controller would measure it without noise: time, platform pose,
    /// steering, joints, target pose and target velocity, bit for bit.
    pub fn measurement(&self) -> Measurement<f64, N, S> {
        Measurement {
            t: self.t,
            base: self.base,
            steering: self.steering,
            joints: self.joints,
            target: self.target,
            target_velocity: self.target_velocity,
        }
    }
}

/// The simulated mobile manipulator and its target.
///
/// Fixed-step RK4 under a zero-order-hold command; the time of step `n` is `n·dt` exactly
/// (no accumulated rounding); angles stay continuous. Deterministic: the same
/// configuration, initial conditions and commands give the same bits (elementary
/// functions from the pinned `libm`, noise from a seeded ChaCha generator).
#[derive(Clone, Debug)]
pub struct Plant<A: Arm<f64, N>, const N: usize> {
    config: PlantConfig,
    arm: A,
    trajectory: Trajectory,
    state: PlantState<N>,
    x: Continuous<N>,
    dt: Option<f64>,
    /// sin/cos of recent angles (a pure cache: it never changes a result).
    trig: Trig,
}

impl<A: Arm<f64, N>, const N: usize> Plant<A, N> {
    /// A plant at its initial conditions (`t = 0`, step 0, at rest).
    ///
    /// # Errors
    /// A parameter or initial value that breaks a rule, or an invalid arm geometry.
    pub fn new(
        config: PlantConfig,
        arm: A,
        initial: InitialConditions<N>,
        trajectory: Trajectory,
    ) -> Result<Self, PlantError> {
        config.validate()?;
        arm.validate().map_err(PlantError::Arm)?;
        initial.validate()?;
        if let (PlatformKind::Car, Some(l)) = (config.platform, config.steering_limit) {
            if initial.steering.abs() > l {
                return Err(PlantError::Invalid {
                    param: "initial.steering",
                    rule: Rule::BeyondSteeringLimit,
                    value: initial.steering,
                });
            }
        }
        let x = Continuous {
            base: initial.base.to_vector(),
            steering: initial.steering,
            joints: initial.joints,
            target: initial.target.to_vector(),
            platform_lag: SVector::zeros(),
            joint_lag: SVector::zeros(),
        };
        let state = PlantState {
            t: 0.0,
            step: 0,
            base: initial.base,
            steering: initial.steering,
            joints: initial.joints,
            target: initial.target,
            target_velocity: trajectory.velocity(0.0),
            applied: Command::zero(),
            command: Command::zero(),
        };
        Ok(Self { config, arm, trajectory, state, x, dt: None, trig: Trig::default() })
    }

    /// The configuration.
    pub fn config(&self) -> &PlantConfig {
        &self.config
    }

    /// The arm.
    pub fn arm(&self) -> &A {
        &self.arm
    }

    /// The target's trajectory.
    pub fn trajectory(&self) -> &Trajectory {
        &self.trajectory
    }

    /// The fixed time step (s), known from the first step on.
    pub fn dt(&self) -> Option<f64> {
        self.dt
    }

    /// The step index `n`: how many steps have been taken.
    pub fn step_index(&self) -> u64 {
        self.state.step
    }

    /// The time `t = n·dt` (s).
    pub fn time(&self) -> f64 {
        self.state.t
    }

    /// The exact state (never noisy).
    pub fn truth(&self) -> &PlantState<N> {
        &self.state
    }

    /// What the controller sees at the current step: time, platform pose, steering,
    /// joints, target pose and target velocity `u_d(t)`.
    ///
    /// Without noise this is the true state, bit for bit. With noise, independent Gaussian
    /// samples are added to the platform's and the target's poses, the steering state and
    /// the joints (`t` and `u_d`, which the controller knows, are exact); the samples depend
    /// only on the seed and the step index, so a second call in the same step returns the
    /// same measurement.
    pub fn measure(&self) -> Measurement<f64, N> {
        let s = &self.state;
        let mut m = s.measurement();
        if let Some(noise) = self.config.imperfections.noise {
            // A generator per measurement: the noise of step n is ChaCha stream n of the
            // seed (see the `imperfections` module), whatever was measured before.
            let mut rng = ChaCha12Rng::seed_from_u64(self.config.imperfections.seed);
            rng.set_stream(s.step);
            add_noise(&mut Gaussian { rng, spare: None }, &noise, &mut m);
        }
        m
    }

    /// One RK4 step of `dt` seconds with `command` held (zero-order hold).
    ///
    /// Which command fields act: unicycle `v`, `omega`; car `v`, `v_xi` (`omega` is only a
    /// report of `v ξ` and is ignored); omnidirectional `v`, `v_lat`, `omega`; and `joints`.
    ///
    /// # Panics
    /// On what [`try_advance`](Self::try_advance) refuses: a time step that is not finite
    /// and `> 0` or differs from the first one, or a non-finite command.
    pub fn advance(&mut self, command: &Command<f64, N>, dt: f64) {
        if let Err(e) = self.try_advance(command, dt) {
            panic!("Plant::advance: {e}");
        }
    }

    /// One RK4 step of `dt` seconds with `command` held, as [`advance`](Self::advance).
    ///
    /// # Errors
    /// A time step that is not finite and `> 0`, or differs from the plant's fixed step
    /// (set by the first step), or a non-finite command; the state is left as it was.
    pub fn try_advance(&mut self, command: &Command<f64, N>, dt: f64) -> Result<(), AdvanceError> {
        Simulated::try_advance_delayed(self, command, command, 0.0, dt)
    }
}

/// Adds noise in a fixed order: platform `x, y, θ`, steering, joints, target `x, y, θ`.
fn add_noise<const N: usize>(gaussian: &mut Gaussian, noise: &Noise, m: &mut Measurement<f64, N>) {
    let mut draw = |sigma: f64| sigma * gaussian.sample();
    m.base.x += draw(noise.position);
    m.base.y += draw(noise.position);
    m.base.theta += draw(noise.angle);
    m.steering += draw(noise.steering);
    for q in m.joints.iter_mut() {
        *q += draw(noise.joints);
    }
    m.target.x += draw(noise.position);
    m.target.y += draw(noise.position);
    m.target.theta += draw(noise.angle);
}

/// Standard normal samples by the Box–Muller transform, two per pair of uniforms, with
/// every elementary function from `libm` (see [`Imperfections`]).
struct Gaussian {
    rng: ChaCha12Rng,
    spare: Option<f64>,
}

impl Gaussian {
    fn sample(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        let u1: f64 = self.rng.sample(OpenClosed01); // (0, 1]: ln u1 is finite
        let u2: f64 = self.rng.sample(StandardUniform); // [0, 1)
        let r = libm::sqrt(-2.0 * libm::log(u1));
        let (s, c) = libm::sincos(core::f64::consts::TAU * u2);
        self.spare = Some(r * s);
        r * c
    }
}

/// A simulated robot as its user drives it, whatever its arm: the paper's planar arm
/// ([`Plant`], targets in the plane) or a chain in space ([`crate::SpatialPlant`]) — one
/// interface, so that a loop that measures, records and advances is written once.
pub trait Simulated<const N: usize> {
    /// Where the target lives: [`Planar`] or [`companion_core::Spatial`].
    type Space: Space<f64>;

    /// What the controller sees at the current step.
    fn measure(&self) -> Measurement<f64, N, Self::Space>;

    /// The exact state.
    fn truth(&self) -> &PlantState<N, Self::Space>;

    /// The end effector's pose in the world.
    fn end_effector(&self) -> <Self::Space as Space<f64>>::Pose;

    /// The true tracking error `e_p` for the desired pose `r*_ed` of the target seen from the
    /// end effector (three components in the plane, six in space).
    fn tracking_error(
        &self,
        target_in_effector: &<Self::Space as Space<f64>>::Pose,
    ) -> <Self::Space as Space<f64>>::Vector;

    /// One step of `dt` seconds: `previous` for the first `delay` seconds, `command` for the
    /// rest (`delay = 0`: `command` throughout).
    ///
    /// # Errors
    /// A time step that is not finite and `> 0` or differs from the first, a non-finite
    /// command, a delay outside `[0, dt)`; the state is left as it was.
    fn try_advance_delayed(
        &mut self,
        previous: &Command<f64, N>,
        command: &Command<f64, N>,
        delay: f64,
        dt: f64,
    ) -> Result<(), AdvanceError>;

    /// One step of `dt` seconds with `command` held throughout.
    ///
    /// # Errors
    /// As [`try_advance_delayed`](Self::try_advance_delayed).
    fn try_advance(&mut self, command: &Command<f64, N>, dt: f64) -> Result<(), AdvanceError> {
        self.try_advance_delayed(command, command, 0.0, dt)
    }
}

impl<A: Arm<f64, N>, const N: usize> Simulated<N> for Plant<A, N> {
    type Space = Planar;

    #[inline]
    fn measure(&self) -> Measurement<f64, N> {
        Plant::measure(self)
    }

    #[inline]
    fn truth(&self) -> &PlantState<N> {
        Plant::truth(self)
    }

    /// The true world pose of the end effector, `r_b · r_eb(q)⁻¹` (m, m, rad).
    fn end_effector(&self) -> Pose<f64> {
        let r_eb = self.arm.kinematics(&self.state.joints).r_eb;
        self.state.base.compose(&r_eb.inverse())
    }

    /// The true tracking error `e_p = (r*_ed)⁻¹ r_ed` of the paper's eq. (42) at the current
    /// step, with `r_ed = r_eb(q) r_bd` from the exact state (never noisy) and the desired
    /// pose `r*_ed` of the target seen from the end effector; the angle wrapped to (−π, π].
    fn tracking_error(&self, target_in_effector: &Pose<f64>) -> Vector3<f64> {
        let s = &self.state;
        let r_bd = s.base.between(&s.target);
        let r_ed = self.arm.kinematics(&s.joints).r_eb.compose(&r_bd);
        let e = target_in_effector.between(&r_ed);
        Vector3::new(e.x, e.y, e.theta)
    }

    /// One step of `dt` seconds in which the command changes `delay` seconds in: `previous`
    /// acts over `[t, t + delay)`, `command` over `[t + delay, t + dt)`, each integrated by
    /// RK4 (a command that takes effect late: the robot's transport and compute delay). With
    /// `delay = 0` this is [`Plant::try_advance`], to the bit.
    fn try_advance_delayed(
        &mut self,
        previous: &Command<f64, N>,
        command: &Command<f64, N>,
        delay: f64,
        dt: f64,
    ) -> Result<(), AdvanceError> {
        let model = self.config.model(&self.trajectory);
        let n = self.state.step;
        let trig = &mut self.trig;
        let (x, applied, t1) =
            model.period(&mut self.dt, (n, &self.x), (previous, command, delay), dt, trig)?;
        // u_d(t₁⁺): the piece the target follows over the next step.
        let target_velocity =
            self.trajectory.piece(t1 + 0.5 * dt).velocity_with(t1, |a| trig.phase.sincos(a));
        let target = (Pose::from_vector(&x.target), target_velocity);
        self.state = PlantState::after((n, t1), &x, target, applied, command);
        self.x = x;
        Ok(())
    }
}
