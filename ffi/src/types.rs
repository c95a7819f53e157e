//! The C-visible structs (generic over the scalar, instantiated for `double` and `float`)
//! and their conversion to and from `companion-core`'s types.
//!
//! Enum-valued fields are `uint32_t` holding a value of the named enum, not the enum type:
//! C can store any number in an enum, and Rust must not read an out-of-range enum. A value
//! outside its enum is reported as `COMPANION_STATUS_BAD_ENUM` naming the field.

use companion_core::nalgebra::{SVector, Vector2, Vector3};
use companion_core::{
    AccelerationLimits, CarLike, Command, Discretisation, JointLimits, Measurement, PaperRun, Params,
    PlatformKind, Pose, Precompensation, PrimaryTask, Real, RestFilter, Rpr, SecondaryTask, TargetMotion,
    Unicycle, VelocityLimits, Weight, WeightMargins,
};

/// The number of arm joints (the paper's RPR arm).
pub const COMPANION_JOINTS: usize = 3;

/// The wheeled platform.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompanionPlatform {
    /// Unicycle-like (differential drive), Lemma 1's transverse function.
    Unicycle = 0,
    /// Car-like, Lemma 2's transverse function and the steering law (59).
    Car = 1,
    /// Omnidirectional.
    Omni = 2,
}

/// The paper's four control variants (§4.3).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompanionRun {
    /// Psi = 1, Choice 1 with (51).
    A = 0,
    /// Psi by (52)-(53), Choice 1 with (40).
    B = 1,
    /// As (b) with Choice 2 (no pre-compensation).
    C = 2,
    /// As (b) with Choice 3.
    D = 3,
}

/// How the weight Psi of (29) is formed (`companion-core`'s `Weight`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompanionWeight {
    /// A constant Psi in [0, 1] (`weight_psi`).
    Constant = 0,
    /// Psi~(q) of (52) filtered by (53) (`weight_margins`, `weight_lambda`, `weight_xi`).
    Filtered = 1,
    /// Psi = (1/n) sum sigma_i^2, each sigma~_i filtered as in (54).
    PerJoint = 2,
    /// Psi = (1/n) sum sigma~_i(q^_i)^2 (`weight_margins` only).
    FromFilteredJoints = 3,
}

/// The pre-compensation of the drift in (37) (`companion-core`'s `Precompensation`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompanionPrecompensation {
    /// Choice 1 with decomposition (51); needs the constant weight Psi = 1.
    Full51 = 0,
    /// Choice 1 with decomposition (40), with `precompensation_nu`.
    Full40 = 1,
    /// Choice 2: none.
    Off = 2,
    /// Choice 3.
    Partial = 3,
}

/// How the rest filter (28) is advanced over a step.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompanionRestFilter {
    /// Explicit Euler.
    Explicit = 0,
    /// Linearly implicit Euler (the default).
    LinearlyImplicit = 1,
}

/// How the law becomes a held command.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompanionDiscretisation {
    /// The law at the measured state, held.
    Sampled = 0,
    /// Hold-aware: the law at the state predicted for the middle of the hold (the default).
    Midpoint = 1,
}

/// How the target's motion is extrapolated (midpoint discretisation only).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompanionTargetMotion {
    /// The measured velocity held.
    Held = 0,
    /// Extrapolated to second order from the last three measured velocities (the default).
    Extrapolated = 1,
}

/// A planar pose (m, m, rad).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompanionPose<T> {
    /// x (m).
    pub x: T,
    /// y (m).
    pub y: T,
    /// Heading (rad).
    pub theta: T,
}

/// What the controller measures each cycle.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompanionMeasurement<T> {
    /// Time t (s) at which the measurement was taken.
    pub t: T,
    /// Platform pose r_b in the fixed frame.
    pub base: CompanionPose<T>,
    /// Steering state xi = tan(phi)/l (1/m), car-like platform; ignored otherwise.
    pub steering: T,
    /// Joint positions q (rad, m, rad for the RPR arm).
    pub joints: [T; COMPANION_JOINTS],
    /// Target pose r_d in the fixed frame.
    pub target: CompanionPose<T>,
    /// Target body velocity u_d (m/s, m/s, rad/s).
    pub target_velocity: [T; 3],
}

/// The command for one cycle (the safe command: all zero).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompanionCommand<T> {
    /// Forward speed v (m/s).
    pub v: T,
    /// Lateral speed (m/s), omnidirectional platform only.
    pub v_lat: T,
    /// Angular speed omega (rad/s); car-like: the resulting yaw rate v xi.
    pub omega: T,
    /// Steering rate v_xi (1/(m s)), car-like platform only.
    pub v_xi: T,
    /// Joint velocities u_q (rad/s, m/s, rad/s).
    pub joints: [T; COMPANION_JOINTS],
}

/// Platform velocity limits (+infinity: no limit), met by one common scale factor.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompanionVelocityLimits<T> {
    /// |v| (m/s).
    pub forward: T,
    /// |v_lat| (m/s).
    pub lateral: T,
    /// |omega| (rad/s).
    pub angular: T,
    /// |alpha_dot_i| (rad/s).
    pub alpha_rate: T,
    /// |v_xi| (1/(m s)).
    pub steering_rate: T,
}

/// Acceleration limits of the platform's command and of the joints (+infinity: no limit),
/// met by a second common factor on the change of the command (`companion_core::acceleration`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompanionAccelerationLimits<T> {
    /// |dv/dt| of the forward speed (m/s^2).
    pub forward: T,
    /// |dv_lat/dt| (m/s^2), omnidirectional platform.
    pub lateral: T,
    /// |d omega/dt| (rad/s^2), unicycle and omnidirectional platforms.
    pub angular: T,
    /// |d q_dot_i/dt| of each joint's command (rad/s^2 or m/s^2).
    pub joints: [T; COMPANION_JOINTS],
}

/// The weight margins of eq. (52), per joint.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompanionWeightMargins<T> {
    /// delta_i^-: outer margin at the lower limit.
    pub lower: [T; COMPANION_JOINTS],
    /// delta_i^--: inner margin at the lower limit (< delta_i^-).
    pub lower_inner: [T; COMPANION_JOINTS],
    /// delta_i^+: outer margin at the upper limit.
    pub upper: [T; COMPANION_JOINTS],
    /// delta_i^++: inner margin at the upper limit (< delta_i^+).
    pub upper_inner: [T; COMPANION_JOINTS],
}

/// Every parameter of the planar law, the platform's transverse function and the RPR arm,
/// one field per field of `companion-core` (same names; SI units as documented there).
/// Start from `companion_*_params_paper` and change fields.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompanionParams<T> {
    /// A `CompanionPlatform`.
    pub platform: u32,
    /// Unicycle: epsilon_1 (m) of Lemma 1.
    pub unicycle_epsilon_1: T,
    /// Unicycle: epsilon_2 of Lemma 1.
    pub unicycle_epsilon_2: T,
    /// Car-like: epsilon of Lemma 2.
    pub car_epsilon: T,
    /// Car-like: eta_1, eta_2, eta_3 of Lemma 2 (6 eta2 eta3 > 8 eta3 + eta1 eta2).
    pub car_eta: [T; 3],
    /// Car-like: gain k (1/s) of the steering law (59).
    pub car_k: T,
    /// RPR arm: L (m), the first joint's axis on the platform's axis.
    pub arm_l: T,
    /// RPR arm: L_e (m), the last joint's axis to the end effector.
    pub arm_l_e: T,
    /// alpha(0) (rad): the transverse-function variables the controller starts from.
    pub initial_alpha: [T; 2],
    /// Joint limits q^- (lower).
    pub joint_lower: [T; COMPANION_JOINTS],
    /// Joint limits q^+ (upper).
    pub joint_upper: [T; COMPANION_JOINTS],
    /// r*_ed: the target's desired pose seen from the end effector.
    pub target_in_effector: CompanionPose<T>,
    /// alpha_i > 0 of the joint-limit penalty (20).
    pub penalty_weight: [T; COMPANION_JOINTS],
    /// delta_i > 0 of the joint-limit penalty (21).
    pub penalty_margin: [T; COMPANION_JOINTS],
    /// gamma_0 >= 0 of Gamma(t) in (22).
    pub regularisation_gain: T,
    /// lambda_Gamma >= 0 (1/s).
    pub regularisation_decay: T,
    /// sigma > 0 of the q^ filter (26).
    pub filter_sigma: T,
    /// xi > 0 of the q^ filter (26).
    pub filter_xi: T,
    /// g_i > 0 of G = -diag(g_i) in (30) (1/s).
    pub gain: [T; COMPANION_JOINTS],
    /// k_n >= 0 (1/s), redundant arms only.
    pub null_space_gain: T,
    /// r_*: the platform's preferred pose seen from the target.
    pub preferred_pose: CompanionPose<T>,
    /// gamma > 0 of h_s1 (49) (m^2).
    pub gamma_1: T,
    /// gamma > 0 of h_s2 (27) (m^2).
    pub gamma_2: T,
    /// sigma_i > 0 of the rest filter (28) (1/s).
    pub rest_sigma: [T; 3],
    /// xi > 0 of the rest filter (28) (m).
    pub rest_xi: T,
    /// Bound (m) on the rest filter's lag.
    pub rest_reach: T,
    /// A `CompanionWeight`.
    pub weight: u32,
    /// Psi of `COMPANION_WEIGHT_CONSTANT`.
    pub weight_psi: T,
    /// The margins of (52) (the non-constant weights).
    pub weight_margins: CompanionWeightMargins<T>,
    /// lambda > 0 of (53)/(54) (1/s).
    pub weight_lambda: T,
    /// xi > 0 of (53)/(54).
    pub weight_xi: T,
    /// K_bar of (36), all > 0.
    pub k_bar: [T; 3],
    /// D of (37), all > 0.
    pub d: [T; 3],
    /// mu > 0 of (37).
    pub mu: T,
    /// A `CompanionPrecompensation`.
    pub precompensation: u32,
    /// nu > 0 of `COMPANION_PRECOMPENSATION_FULL40`.
    pub precompensation_nu: T,
    /// A `CompanionRestFilter`.
    pub rest_filter: u32,
    /// 0 or 1: whether dh_s/dt includes Psi_dot (h_s1 - h_s2).
    pub psi_rate_in_drift: u32,
    /// Platform velocity limits.
    pub velocity_limits: CompanionVelocityLimits<T>,
    /// The largest period a step accepts (s).
    pub max_time_step: T,
    /// kappa in (0, 1]: the joint step guard.
    pub joint_step_fraction: T,
    /// |q_dot_i| limits (+infinity: none).
    pub joint_velocity_limits: [T; COMPANION_JOINTS],
    /// Acceleration limits (+infinity: none; the preset has none).
    pub acceleration_limits: CompanionAccelerationLimits<T>,
    /// A `CompanionDiscretisation`.
    pub discretisation: u32,
    /// A `CompanionTargetMotion`.
    pub target_motion: u32,
    /// The largest delay a step accepts (s).
    pub max_delay: T,
    /// The largest turn of alpha or the heading within one period (rad).
    pub max_turn_per_step: T,
}

/// `CompanionPose` in `double`.
pub type CompanionPoseF64 = CompanionPose<f64>;
/// `CompanionPose` in `float`.
pub type CompanionPoseF32 = CompanionPose<f32>;
/// `CompanionMeasurement` in `double`.
pub type CompanionMeasurementF64 = CompanionMeasurement<f64>;
/// `CompanionMeasurement` in `float`.
pub type CompanionMeasurementF32 = CompanionMeasurement<f32>;
/// `CompanionCommand` in `double`.
pub type CompanionCommandF64 = CompanionCommand<f64>;
/// `CompanionCommand` in `float`.
pub type CompanionCommandF32 = CompanionCommand<f32>;
/// `CompanionParams` in `double`.
pub type CompanionParamsF64 = CompanionParams<f64>;
/// `CompanionParams` in `float`.
pub type CompanionParamsF32 = CompanionParams<f32>;

/// The car-like platform of the paper preset: `companion sim`'s default (`CarConfig` in
/// `companion-runtime`, found by `companion tune`): `(ε, η₁, η₂, η₃, k)`.
pub(crate) const CAR_PRESET: [f64; 5] = [0.152, 21.9, 1.9, 15.4, 26.6];
/// The car's `K̄` of the preset (`companion-runtime`'s `CAR_K_BAR`).
pub(crate) const CAR_K_BAR: [f64; 3] = [1.0, 2.07, 254.0];
/// The car's velocity limits of the preset: `companion sim`'s default for the car-like
/// platform (`companion_plant::realistic_limits`: forward, lateral, angular, α̇, steering rate),
/// as the car's `H̄(α)` is nearly singular and its unsaturated gains huge.
pub(crate) const CAR_LIMITS: [f64; 5] = [1.0, 0.8, 2.0, 10.0, 2.0];
/// The omnidirectional platform's `K̄` of the preset (`companion-runtime`'s `OMNI_K_BAR`).
pub(crate) const OMNI_K_BAR: [f64; 3] = [1.0, 1.0, 1.0];

fn arr<T: Copy, const N: usize>(v: &SVector<T, N>) -> [T; N] {
    core::array::from_fn(|i| v[i])
}

fn pose_c<T: Real>(p: &Pose<T>) -> CompanionPose<T> {
    CompanionPose { x: p.x, y: p.y, theta: p.theta }
}

fn pose_core<T: Real>(p: &CompanionPose<T>) -> Pose<T> {
    Pose::new(p.x, p.y, p.theta)
}

/// The platform kind of a C value.
pub fn platform_kind(v: u32) -> Option<PlatformKind> {
    match v {
        0 => Some(PlatformKind::Unicycle),
        1 => Some(PlatformKind::Car),
        2 => Some(PlatformKind::Omni),
        _ => None,
    }
}

/// The paper run of a C value.
pub fn paper_run(v: u32) -> Option<PaperRun> {
    match v {
        0 => Some(PaperRun::A),
        1 => Some(PaperRun::B),
        2 => Some(PaperRun::C),
        3 => Some(PaperRun::D),
        _ => None,
    }
}

impl<T: Real> CompanionParams<T> {
    /// The paper preset of `companion sim --platform P --run R`: `Params::paper(run)` with the
    /// platform's `K̄` (car, omnidirectional), Lemma 1's `(0.2, 0.4)`, the car's tuned
    /// function and its realistic velocity limits, the paper's RPR arm and `α(0) = 0`. Fields the run does not use (the
    /// weight's margins in run (a), `ν` outside run (b)) hold run (b)'s values, so a caller
    /// who switches the variant starts from the paper's numbers.
    pub fn paper(platform: PlatformKind, run: PaperRun) -> Self {
        let p = Params::<T, 3>::paper(run);
        let b = Params::<T, 3>::paper(PaperRun::B);
        let (margins, lambda, xi) = match b.secondary.weight {
            Weight::Filtered { margins, lambda, xi } => (margins, lambda, xi),
            // Run (b) has the filtered weight; the arm is unreachable.
            _ => (WeightMargins::paper(&b.joint_limits, &Params::<T, 3>::paper_q_star()), T::one(), T::one()),
        };
        let (weight, psi) = match p.secondary.weight {
            Weight::Constant(psi) => (CompanionWeight::Constant, psi),
            Weight::Filtered { .. } => (CompanionWeight::Filtered, T::one()),
            Weight::PerJoint { .. } => (CompanionWeight::PerJoint, T::one()),
            Weight::FromFilteredJoints { .. } => (CompanionWeight::FromFilteredJoints, T::one()),
        };
        let (precompensation, nu) = match p.secondary.precompensation {
            Precompensation::Full51 => (CompanionPrecompensation::Full51, T::of(1e-4)),
            Precompensation::Full40 { nu } => (CompanionPrecompensation::Full40, nu),
            Precompensation::Off => (CompanionPrecompensation::Off, T::of(1e-4)),
            Precompensation::Partial => (CompanionPrecompensation::Partial, T::of(1e-4)),
        };
        let k_bar = match platform {
            PlatformKind::Unicycle => arr(&p.secondary.k_bar),
            PlatformKind::Car => CAR_K_BAR.map(T::of),
            PlatformKind::Omni => OMNI_K_BAR.map(T::of),
        };
        let uni = Unicycle::<T>::paper();
        let arm = Rpr::<T>::paper();
        let s = &p.secondary;
        let q = &p.primary;
        let l = match platform {
            PlatformKind::Car => {
                let c = CAR_LIMITS.map(T::of);
                VelocityLimits {
                    forward: c[0],
                    lateral: c[1],
                    angular: c[2],
                    alpha_rate: c[3],
                    steering_rate: c[4],
                }
            }
            PlatformKind::Unicycle | PlatformKind::Omni => p.velocity_limits,
        };
        Self {
            platform: platform as u32,
            unicycle_epsilon_1: uni.epsilon_1,
            unicycle_epsilon_2: uni.epsilon_2,
            car_epsilon: T::of(CAR_PRESET[0]),
            car_eta: [T::of(CAR_PRESET[1]), T::of(CAR_PRESET[2]), T::of(CAR_PRESET[3])],
            car_k: T::of(CAR_PRESET[4]),
            arm_l: arm.l,
            arm_l_e: arm.l_e,
            initial_alpha: [T::zero(); 2],
            joint_lower: arr(&p.joint_limits.lower),
            joint_upper: arr(&p.joint_limits.upper),
            target_in_effector: pose_c(&q.target_in_effector),
            penalty_weight: arr(&q.penalty_weight),
            penalty_margin: arr(&q.penalty_margin),
            regularisation_gain: q.regularisation_gain,
            regularisation_decay: q.regularisation_decay,
            filter_sigma: q.filter_sigma,
            filter_xi: q.filter_xi,
            gain: arr(&q.gain),
            null_space_gain: q.null_space_gain,
            preferred_pose: pose_c(&s.preferred_pose),
            gamma_1: s.gamma_1,
            gamma_2: s.gamma_2,
            rest_sigma: arr(&s.rest_sigma),
            rest_xi: s.rest_xi,
            rest_reach: s.rest_reach,
            weight: weight as u32,
            weight_psi: psi,
            weight_margins: CompanionWeightMargins {
                lower: arr(&margins.lower),
                lower_inner: arr(&margins.lower_inner),
                upper: arr(&margins.upper),
                upper_inner: arr(&margins.upper_inner),
            },
            weight_lambda: lambda,
            weight_xi: xi,
            k_bar,
            d: arr(&s.d),
            mu: s.mu,
            precompensation: precompensation as u32,
            precompensation_nu: nu,
            rest_filter: match s.rest_filter {
                RestFilter::Explicit => CompanionRestFilter::Explicit,
                RestFilter::LinearlyImplicit => CompanionRestFilter::LinearlyImplicit,
            } as u32,
            psi_rate_in_drift: u32::from(s.psi_rate_in_drift),
            velocity_limits: CompanionVelocityLimits {
                forward: l.forward,
                lateral: l.lateral,
                angular: l.angular,
                alpha_rate: l.alpha_rate,
                steering_rate: l.steering_rate,
            },
            max_time_step: p.max_time_step,
            joint_step_fraction: p.joint_step_fraction,
            joint_velocity_limits: arr(&p.joint_velocity_limits),
            acceleration_limits: CompanionAccelerationLimits {
                forward: p.acceleration_limits.forward,
                lateral: p.acceleration_limits.lateral,
                angular: p.acceleration_limits.angular,
                joints: arr(&p.acceleration_limits.joints),
            },
            discretisation: match p.discretisation {
                Discretisation::Sampled => CompanionDiscretisation::Sampled,
                Discretisation::Midpoint => CompanionDiscretisation::Midpoint,
            } as u32,
            target_motion: match p.target_motion {
                TargetMotion::Held => CompanionTargetMotion::Held,
                TargetMotion::Extrapolated => CompanionTargetMotion::Extrapolated,
            } as u32,
            max_delay: p.max_delay,
            max_turn_per_step: p.max_turn_per_step,
        }
    }

    /// The core's parameters, or the name of the enum field that holds a value outside its
    /// enum.
    pub fn to_core(&self) -> Result<Core<T>, &'static str> {
        let margins = WeightMargins {
            lower: SVector::from(self.weight_margins.lower),
            lower_inner: SVector::from(self.weight_margins.lower_inner),
            upper: SVector::from(self.weight_margins.upper),
            upper_inner: SVector::from(self.weight_margins.upper_inner),
        };
        let weight = match self.weight {
            0 => Weight::Constant(self.weight_psi),
            1 => Weight::Filtered { margins, lambda: self.weight_lambda, xi: self.weight_xi },
            2 => Weight::PerJoint { margins, lambda: self.weight_lambda, xi: self.weight_xi },
            3 => Weight::FromFilteredJoints { margins },
            _ => return Err("weight"),
        };
        let precompensation = match self.precompensation {
            0 => Precompensation::Full51,
            1 => Precompensation::Full40 { nu: self.precompensation_nu },
            2 => Precompensation::Off,
            3 => Precompensation::Partial,
            _ => return Err("precompensation"),
        };
        let rest_filter = match self.rest_filter {
            0 => RestFilter::Explicit,
            1 => RestFilter::LinearlyImplicit,
            _ => return Err("rest_filter"),
        };
        let psi_rate_in_drift = match self.psi_rate_in_drift {
            0 => false,
            1 => true,
            _ => return Err("psi_rate_in_drift"),
        };
        let discretisation = match self.discretisation {
            0 => Discretisation::Sampled,
            1 => Discretisation::Midpoint,
            _ => return Err("discretisation"),
        };
        let target_motion = match self.target_motion {
            0 => TargetMotion::Held,
            1 => TargetMotion::Extrapolated,
            _ => return Err("target_motion"),
        };
        let platform = platform_kind(self.platform).ok_or("platform")?;
        let l = &self.velocity_limits;
        let params = Params {
            joint_limits: JointLimits {
                lower: SVector::from(self.joint_lower),
                upper: SVector::from(self.joint_upper),
            },
            primary: PrimaryTask {
                target_in_effector: pose_core(&self.target_in_effector),
                penalty_weight: SVector::from(self.penalty_weight),
                penalty_margin: SVector::from(self.penalty_margin),
                regularisation_gain: self.regularisation_gain,
                regularisation_decay: self.regularisation_decay,
                filter_sigma: self.filter_sigma,
                filter_xi: self.filter_xi,
                gain: SVector::from(self.gain),
                null_space_gain: self.null_space_gain,
            },
            secondary: SecondaryTask {
                preferred_pose: pose_core(&self.preferred_pose),
                gamma_1: self.gamma_1,
                gamma_2: self.gamma_2,
                rest_sigma: Vector3::from(self.rest_sigma),
                rest_xi: self.rest_xi,
                rest_reach: self.rest_reach,
                weight,
                k_bar: Vector3::from(self.k_bar),
                d: Vector3::from(self.d),
                mu: self.mu,
                precompensation,
                rest_filter,
                psi_rate_in_drift,
                heading_filter: None,
            },
            velocity_limits: VelocityLimits {
                forward: l.forward,
                lateral: l.lateral,
                angular: l.angular,
                alpha_rate: l.alpha_rate,
                steering_rate: l.steering_rate,
            },
            max_time_step: self.max_time_step,
            joint_step_fraction: self.joint_step_fraction,
            joint_velocity_limits: SVector::from(self.joint_velocity_limits),
            acceleration_limits: AccelerationLimits {
                forward: self.acceleration_limits.forward,
                lateral: self.acceleration_limits.lateral,
                angular: self.acceleration_limits.angular,
                joints: SVector::from(self.acceleration_limits.joints),
            },
            discretisation,
            target_motion,
            max_delay: self.max_delay,
            max_turn_per_step: self.max_turn_per_step,
        };
        Ok(Core {
            params,
            platform,
            unicycle: Unicycle::new(self.unicycle_epsilon_1, self.unicycle_epsilon_2),
            car: CarLike::new(self.car_epsilon, self.car_eta, self.car_k),
            arm: Rpr { l: self.arm_l, l_e: self.arm_l_e },
            initial_alpha: Vector2::new(self.initial_alpha[0], self.initial_alpha[1]),
        })
    }
}

/// A [`CompanionParams`] in `companion-core`'s types.
#[derive(Clone, Copy, Debug)]
pub struct Core<T: Real> {
    /// The law's parameters.
    pub params: Params<T, 3>,
    /// Which platform.
    pub platform: PlatformKind,
    /// Lemma 1's function (unicycle).
    pub unicycle: Unicycle<T>,
    /// Lemma 2's function (car-like).
    pub car: CarLike<T>,
    /// The RPR arm.
    pub arm: Rpr<T>,
    /// `α(0)`.
    pub initial_alpha: Vector2<T>,
}

impl<T: Real> CompanionMeasurement<T> {
    /// The core's measurement.
    pub fn to_core(&self) -> Measurement<T, 3> {
        Measurement {
            t: self.t,
            base: pose_core(&self.base),
            steering: self.steering,
            joints: SVector::from(self.joints),
            target: pose_core(&self.target),
            target_velocity: Vector3::from(self.target_velocity),
        }
    }
}

impl<T: Real> CompanionCommand<T> {
    /// The C command of a core command.
    pub fn from_core(c: &Command<T, 3>) -> Self {
        let p = &c.platform;
        Self { v: p.v, v_lat: p.v_lat, omega: p.omega, v_xi: p.v_xi, joints: arr(&c.joints) }
    }
}
