//! Everything the runtime knows about `companion-core`'s controller, in one place: how a
//! controller is described and built ([`ControllerSpec`]), one controller of any platform × scalar type
//! behind one concrete type ([`AnyController`]), and the report of one step that both the
//! simulation and the HIL loop record ([`StepReport`]). A change of the law's inputs or
//! parameters is merged here.

mod report;
mod spatial;
mod spec;

pub use report::{StepReport, JOINTS};
pub use spatial::{
    boxed_spatial_controller, command_f64, law_limits, planar_only_keys, spatial_arm, spatial_controller,
    spatial_only_keys, spatial_params, SpatialControllerError, SpatialStep, TARGET_DISTANCE,
};
pub use spec::{
    platform_name, run_name, AccelerationConfig, ArmConfig, CarConfig, ControllerConfig, ControllerSpec,
    DiscretisationConfig, LimitsConfig, RestFilterConfig, Scalar, TargetMotionConfig, UnicycleConfig,
    CAR_K_BAR, OMNI_K_BAR, PAPER_PREFERRED_EXTENSION, PAPER_STROKE,
};

use companion_core::nalgebra::Vector2;
use companion_core::space::Vector as _;
use companion_core::{
    CarLike, Controller, Measurement, Omnidirectional, ParamError, Planar, PlatformKind, Pose, Real, Rpr,
    Rule, Space, Spatial, Unicycle,
};

type Uni<T> = Controller<T, Unicycle<T>, Rpr<T>, JOINTS>;
type Car<T> = Controller<T, CarLike<T>, Rpr<T>, JOINTS>;
type Omni<T> = Controller<T, Omnidirectional, Rpr<T>, JOINTS>;

/// One controller step on an `f64` measurement: the command to hold for `period` seconds,
/// taking effect `delay` seconds after the measurement — the paper's planar law
/// ([`AnyController`]) or a spatial one of `N` joints (a boxed [`SpatialStep`]). The loops
/// step either through it.
pub trait Law<const N: usize = JOINTS, S: Space<f64> = Planar> {
    /// The step.
    fn step(&mut self, meas: &Measurement<f64, N, S>, period: f64, delay: f64) -> StepReport<N>;
}

impl Law for AnyController {
    #[inline]
    fn step(&mut self, meas: &Measurement<f64, JOINTS>, period: f64, delay: f64) -> StepReport {
        AnyController::step(self, meas, period, delay)
    }
}

impl<const N: usize> Law<N, Spatial> for Box<dyn SpatialStep<N> + Send> {
    #[inline]
    fn step(&mut self, meas: &Measurement<f64, N, Spatial>, period: f64, delay: f64) -> StepReport<N> {
        self.as_mut().step(meas, period, delay)
    }
}

/// A controller for one of the three platforms in f64 or f32. (An enum, where a spatial law is
/// boxed behind [`SpatialStep`]: the paper's law is stepped inline, allocation-free, by
/// every caller, the Python package's batch stepping among them.)
#[derive(Clone, Debug)]
pub enum AnyController {
    /// Unicycle, f64.
    UnicycleF64(Box<Uni<f64>>),
    /// Unicycle, f32.
    UnicycleF32(Box<Uni<f32>>),
    /// Car-like, f64.
    CarF64(Box<Car<f64>>),
    /// Car-like, f32.
    CarF32(Box<Car<f32>>),
    /// Omnidirectional, f64.
    OmniF64(Box<Omni<f64>>),
    /// Omnidirectional, f32.
    OmniF32(Box<Omni<f32>>),
}

impl AnyController {
    /// Builds and validates the controller a spec describes, starting from its `α(0)`.
    ///
    /// # Errors
    /// An invalid parameter.
    pub fn new(spec: &ControllerSpec) -> Result<Self, ParamError> {
        spec.arm.validate()?;
        if !spec.initial_alpha.iter().all(|a| a.is_finite()) {
            return Err(ParamError::new("initial_alpha", Rule::NonFinite));
        }
        let mut c = Self::build(spec)?;
        c.set_alpha(spec.initial_alpha);
        Ok(c)
    }

    /// Sets `α` (rad) in the controller's state: the first step starts from it (the law
    /// keeps `α` when it initialises its filters).
    fn set_alpha(&mut self, alpha: [f64; 2]) {
        fn to<T: Real>(a: [f64; 2]) -> Vector2<T> {
            Vector2::new(T::of(a[0]), T::of(a[1]))
        }
        match self {
            Self::UnicycleF64(c) => c.state.alpha = to(alpha),
            Self::UnicycleF32(c) => c.state.alpha = to(alpha),
            Self::CarF64(c) => c.state.alpha = to(alpha),
            Self::CarF32(c) => c.state.alpha = to(alpha),
            Self::OmniF64(c) => c.state.alpha = to(alpha),
            Self::OmniF32(c) => c.state.alpha = to(alpha),
        }
    }

    fn build(spec: &ControllerSpec) -> Result<Self, ParamError> {
        Ok(match (spec.platform, spec.scalar) {
            (PlatformKind::Unicycle, Scalar::F64) => {
                Self::UnicycleF64(Box::new(Controller::new(spec.params(), spec.unicycle(), spec.arm())?))
            }
            (PlatformKind::Unicycle, Scalar::F32) => {
                Self::UnicycleF32(Box::new(Controller::new(spec.params(), spec.unicycle(), spec.arm())?))
            }
            (PlatformKind::Car, Scalar::F64) => {
                Self::CarF64(Box::new(Controller::new(spec.params(), spec.car(), spec.arm())?))
            }
            (PlatformKind::Car, Scalar::F32) => {
                Self::CarF32(Box::new(Controller::new(spec.params(), spec.car(), spec.arm())?))
            }
            (PlatformKind::Omni, Scalar::F64) => {
                Self::OmniF64(Box::new(Controller::new(spec.params(), Omnidirectional, spec.arm())?))
            }
            (PlatformKind::Omni, Scalar::F32) => {
                Self::OmniF32(Box::new(Controller::new(spec.params(), Omnidirectional, spec.arm())?))
            }
        })
    }

    /// One step on an f64 measurement (converted to f32 for the f32 controllers): the command
    /// to hold for `period` seconds, taking effect `delay` seconds after the measurement.
    #[inline]
    pub fn step(&mut self, meas: &Measurement<f64, JOINTS>, period: f64, delay: f64) -> StepReport {
        let (p32, d32) = (period as f32, delay as f32);
        match self {
            Self::UnicycleF64(c) => report(c.step_delayed(meas, period, delay)),
            Self::UnicycleF32(c) => report(c.step_delayed(&measurement_in(meas), p32, d32)),
            Self::CarF64(c) => report(c.step_delayed(meas, period, delay)),
            Self::CarF32(c) => report(c.step_delayed(&measurement_in(meas), p32, d32)),
            Self::OmniF64(c) => report(c.step_delayed(meas, period, delay)),
            Self::OmniF32(c) => report(c.step_delayed(&measurement_in(meas), p32, d32)),
        }
    }

    /// Warnings about accepted parameters (SPEC §3), as text.
    pub fn warnings(&self) -> Vec<String> {
        let w = match self {
            Self::UnicycleF64(c) => c.law.warnings().iter().map(ToString::to_string).collect(),
            Self::UnicycleF32(c) => c.law.warnings().iter().map(ToString::to_string).collect(),
            Self::CarF64(c) => c.law.warnings().iter().map(ToString::to_string).collect(),
            Self::CarF32(c) => c.law.warnings().iter().map(ToString::to_string).collect(),
            Self::OmniF64(c) => c.law.warnings().iter().map(ToString::to_string).collect(),
            Self::OmniF32(c) => c.law.warnings().iter().map(ToString::to_string).collect(),
        };
        w
    }
}

/// The measurement in scalar type `T` (`f32`: rounding to nearest).
pub fn measurement_in<T: Real>(m: &Measurement<f64, JOINTS>) -> Measurement<T, JOINTS> {
    let pose = |p: &Pose<f64>| Pose::new(T::of(p.x), T::of(p.y), T::of(p.theta));
    Measurement {
        t: T::of(m.t),
        base: pose(&m.base),
        steering: T::of(m.steering),
        joints: m.joints.map(T::of),
        target: pose(&m.target),
        target_velocity: m.target_velocity.map(T::of),
    }
}

/// The report of a step of the law in scalar type `T`, of either space: the command in `f64`
/// and the logged diagnostics (`‖e_p‖` of all the components), or the safe command.
pub(crate) fn report<T: Real, const N: usize, S: Space<T>>(
    r: Result<companion_core::Output<T, N, S>, companion_core::Rejected<T, N>>,
) -> StepReport<N> {
    match r {
        Ok(out) => {
            let d = &out.diagnostics;
            // 0 + a² + b² + …: for three components the planar law's (a² + b²) + c², to the bit.
            let e2 = d.e_p.as_slice().iter().fold(0.0, |s, x| s + x.as_f64() * x.as_f64());
            StepReport {
                command: command_f64(&out.command),
                ep_norm: e2.sqrt(),
                h_s: d.h_s.as_f64(),
                psi: d.psi.as_f64(),
                saturation: d.saturation.as_f64(),
                alpha_rate: [d.alpha_rate[0].as_f64(), d.alpha_rate[1].as_f64()],
                joint_scale: d.joint_scale.as_f64(),
                platform_acceleration: d.platform_acceleration > T::one(),
                joint_acceleration: d.joint_acceleration > T::one(),
                error: None,
            }
        }
        Err(rej) => StepReport::rejected(rej.error),
    }
}
