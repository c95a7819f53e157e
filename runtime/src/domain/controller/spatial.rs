//! The spatial law (§5) as the runtime builds and steps it: the arm's task from the chain
//! (`Params::for_arm`, `r*_ed` level 0.2 m beyond the flange), the platform law's settings
//! from the scenario's [`ControllerSpec`] (so `--config`'s `[unicycle]`, `[car]`,
//! `[velocity_limits]`, `[acceleration_limits]` (its `joints` as many as the arm has) and the
//! platform keys of `[controller]`, `--limits`, `--discretisation` act as on planar runs), and
//! one step on an `f64` measurement for a controller in `f64` or `f32`.

use companion_core::reach::MARGIN_FRACTION;
use companion_core::{
    Chain, Command, Controller, Manipulator, Measurement, Omnidirectional, ParamError, Params, Platform,
    PlatformCommand, PlatformKind, Pose, Pose3, ReachJoints, Real, Rule, Spatial, SpatialArm, Weight,
};

use super::report::StepReport;
use super::spec::{ArmConfig, ControllerSpec, Scalar};
use crate::domain::arm::{ArmError, SpatialArmSpec};

/// Where the spatial law puts the target: `r*_ed` this far along the flange's approach axis
/// (`z`), level at home (m). The same as core's closed-loop tests.
pub const TARGET_DISTANCE: f64 = 0.2;

/// A controller that steps on `f64` spatial measurements.
pub trait SpatialStep<const N: usize> {
    /// One step: the command to hold for `period` seconds, taking effect `delay` seconds
    /// after the measurement (0 in `companion sim`; the plant's announced delay in HIL).
    fn step(&mut self, meas: &Measurement<f64, N, Spatial>, period: f64, delay: f64) -> StepReport<N>;
    /// `r*_ed` in `f64` (exactly the controller's).
    fn target_in_effector(&self) -> Pose3<f64>;
}

impl<T: Real, P: Platform<T>, const N: usize> SpatialStep<N> for Controller<T, P, SpatialArm<T, N>, N>
where
    SpatialArm<T, N>: Manipulator<T, N, Space = Spatial>,
{
    #[inline]
    fn step(&mut self, meas: &Measurement<f64, N, Spatial>, period: f64, delay: f64) -> StepReport<N> {
        let m = Measurement::<T, N, Spatial> {
            t: T::of(meas.t),
            base: Pose::new(T::of(meas.base.x), T::of(meas.base.y), T::of(meas.base.theta)),
            steering: T::of(meas.steering),
            joints: meas.joints.map(T::of),
            target: pose_in(&meas.target),
            target_velocity: meas.target_velocity.map(T::of),
        };
        super::report(self.step_delayed(&m, T::of(period), T::of(delay)))
    }

    fn target_in_effector(&self) -> Pose3<f64> {
        let p = &self.law.params().primary.target_in_effector;
        Pose3::new(p.rotation.map(Real::as_f64), p.translation.map(Real::as_f64))
    }
}

fn pose_in<T: Real>(p: &Pose3<f64>) -> Pose3<T> {
    Pose3::new(p.rotation.map(T::of), p.translation.map(T::of))
}

/// A command in `f64` (exact), for the plant.
pub fn command_f64<T: Real, const N: usize>(c: &Command<T, N>) -> Command<f64, N> {
    let p = &c.platform;
    Command {
        platform: PlatformCommand {
            v: p.v.as_f64(),
            v_lat: p.v_lat.as_f64(),
            omega: p.omega.as_f64(),
            v_xi: p.v_xi.as_f64(),
        },
        joints: c.joints.map(Real::as_f64),
    }
}

/// The `[controller]` keys that set the planar arm's task: refused with a spatial arm
/// (its task comes from the chain).
pub fn planar_only_keys(spec: &ControllerSpec) -> Vec<&'static str> {
    let o = &spec.overrides;
    keys_set([
        (o.target_in_effector.is_some(), "controller.target_in_effector"),
        (o.preferred_pose.is_some(), "controller.preferred_pose"),
        (o.gain.is_some(), "controller.gain"),
        (o.penalty_weight.is_some(), "controller.penalty_weight"),
        (o.penalty_margin.is_some(), "controller.penalty_margin"),
        (o.joint_velocity_limits.is_some(), "controller.joint_velocity_limits"),
        (spec.arm != ArmConfig::default(), "arm"),
    ])
}

/// The keys among `keys` that are set.
fn keys_set<const K: usize>(keys: [(bool, &'static str); K]) -> Vec<&'static str> {
    keys.into_iter().filter_map(|(set, key)| set.then_some(key)).collect()
}

/// The spatial law's parameters: the arm's task from `arm` (`Params::for_arm` for the
/// spec's run (a)–(d), `r*_ed` level [`TARGET_DISTANCE`] beyond the flange), the platform
/// law's from the spec (its platform presets and overrides).
///
/// # Errors
/// As `Params::for_arm`.
pub fn spatial_params<T: Real, const N: usize>(
    spec: &ControllerSpec,
    arm: &SpatialArm<T, N>,
) -> Result<Params<T, N, Spatial>, ParamError> {
    let mut p = Params::for_arm(arm, spec.choice, arm.level_target(T::of(TARGET_DISTANCE)))?;
    let planar = spec.params::<T>();
    let (s, from) = (&mut p.secondary, &planar.secondary);
    s.gamma_1 = from.gamma_1;
    s.gamma_2 = from.gamma_2;
    s.rest_sigma = from.rest_sigma;
    s.rest_xi = from.rest_xi;
    s.rest_reach = from.rest_reach;
    s.k_bar = from.k_bar;
    s.d = from.d;
    s.mu = from.mu;
    s.precompensation = from.precompensation;
    s.weight = with_filter_of(s.weight, &from.weight);
    s.rest_filter = from.rest_filter;
    s.psi_rate_in_drift = from.psi_rate_in_drift;
    s.heading_filter = from.heading_filter;
    p.primary.regularisation_gain = planar.primary.regularisation_gain;
    p.primary.regularisation_decay = planar.primary.regularisation_decay;
    p.primary.filter_sigma = planar.primary.filter_sigma;
    p.primary.filter_xi = planar.primary.filter_xi;
    p.velocity_limits = planar.velocity_limits;
    if let Some(a) = &spec.acceleration {
        p.acceleration_limits = a.to_limits();
    }
    p.max_time_step = planar.max_time_step;
    p.joint_step_fraction = planar.joint_step_fraction;
    p.discretisation = planar.discretisation;
    p.target_motion = planar.target_motion;
    p.max_delay = planar.max_delay;
    p.max_turn_per_step = planar.max_turn_per_step;
    Ok(p)
}

/// `weight` (the arm's margins of (52)) with the filter `(λ, ξ)` of (53) of `from` (the
/// spec's, so `[controller] lambda` acts as on planar runs), where both are filtered.
fn with_filter_of<T: Copy, const N: usize>(weight: Weight<T, N>, from: &Weight<T, 3>) -> Weight<T, N> {
    let (lambda, xi) = match *from {
        Weight::Filtered { lambda, xi, .. } | Weight::PerJoint { lambda, xi, .. } => (lambda, xi),
        Weight::Constant(_) | Weight::FromFilteredJoints { .. } => return weight,
    };
    match weight {
        Weight::Filtered { margins, .. } => Weight::Filtered { margins, lambda, xi },
        Weight::PerJoint { margins, .. } => Weight::PerJoint { margins, lambda, xi },
        w => w,
    }
}

/// The arm of `chain` with the spec's singularity settings (`[controller]` `damping_below`,
/// `damping_depth`, `singular_below`; the core's defaults where unset) and its reach
/// (`reach`, `reach_margin`, `reach_rule`, and `joints`, the `reach_joints` found by
/// `reach_joints` (below); the chain's own by default).
///
/// # Errors
/// An invalid chain, or a setting outside its range.
pub fn spatial_arm<T: Real, const N: usize>(
    spec: &ControllerSpec,
    chain: &Chain<T, N>,
    joints: Option<ReachJoints>,
) -> Result<SpatialArm<T, N>, ParamError>
where
    SpatialArm<T, N>: Manipulator<T, N, Space = Spatial>,
{
    let o = &spec.overrides;
    let mut arm = SpatialArm::new(chain)?;
    if o.damping_below.is_none() {
        // The default onset: the core's, or earlier for an arm already near it at home.
        let p = spatial_params(spec, &arm)?;
        let (_, depth) = arm.damping();
        arm = arm.with_damping(arm.onset_from_home(&p.primary, &p.joint_limits), depth)?;
    }
    if o.damping_below.is_some() || o.damping_depth.is_some() {
        let (onset, depth) = arm.damping();
        arm = arm.with_damping(o.damping_below.map_or(onset, T::of), o.damping_depth.map_or(depth, T::of))?;
    }
    if let Some(x) = o.singular_below {
        arm = arm.with_singular_below(T::of(x))?;
    }
    if o.reach == Some(false) {
        return arm.with_reach(None);
    }
    if joints.is_some() || o.reach_margin.is_some() || o.reach_rule.is_some() {
        let joints = joints
            .or_else(|| arm.reach().map(|r| r.joints))
            .ok_or(ParamError::new("reach_joints", Rule::Geometry))?;
        let mut reach = arm.reach_of(joints, T::of(o.reach_margin.unwrap_or(MARGIN_FRACTION)))?;
        if let Some(rule) = o.reach_rule {
            reach.rule = rule.into();
        }
        arm = arm.with_reach(Some(reach))?;
    }
    Ok(arm)
}

/// `[controller] reach_joints` as indices into the arm's joints `names` (`None` if unset).
///
/// # Errors
/// A name the arm has no joint of.
pub fn reach_joints(
    spec: &ControllerSpec,
    names: &[String],
) -> Result<Option<ReachJoints>, SpatialControllerError> {
    let Some(given) = &spec.overrides.reach_joints else {
        return Ok(None);
    };
    let index = |name: &String| {
        names.iter().position(|n| n == name).ok_or_else(|| SpatialControllerError::ReachJoint {
            name: name.clone(),
            joints: names.join(", "),
        })
    };
    Ok(Some(ReachJoints { shoulder: index(&given[0])?, wrist: index(&given[1])?, axis: index(&given[2])? }))
}

/// The `[controller]` keys of a spatial arm's law (its singularity settings): refused with
/// the planar arm, whose one singular configuration (`q₂ = 0`) is a joint limit.
pub fn spatial_only_keys(spec: &ControllerSpec) -> Vec<&'static str> {
    let o = &spec.overrides;
    keys_set([
        (o.damping_below.is_some(), "controller.damping_below"),
        (o.damping_depth.is_some(), "controller.damping_depth"),
        (o.singular_below.is_some(), "controller.singular_below"),
        (o.reach.is_some(), "controller.reach"),
        (o.reach_joints.is_some(), "controller.reach_joints"),
        (o.reach_margin.is_some(), "controller.reach_margin"),
        (o.reach_rule.is_some(), "controller.reach_rule"),
        (o.joint_limits.is_some(), "controller.joint_limits"),
    ])
}

/// A spatial controller: the law of `chain` on `platform`, starting from the spec's `α(0)`,
/// its reach defined by `joints` (the chain's own if `None`).
///
/// # Errors
/// An invalid chain or parameter.
pub fn spatial_controller<T: Real, P: Platform<T>, const N: usize>(
    spec: &ControllerSpec,
    chain: &Chain<T, N>,
    joints: Option<ReachJoints>,
    platform: P,
) -> Result<Controller<T, P, SpatialArm<T, N>, N>, ParamError>
where
    SpatialArm<T, N>: Manipulator<T, N, Space = Spatial>,
{
    let arm = spatial_arm(spec, chain, joints)?;
    let params = spatial_params(spec, &arm)?;
    let mut c = Controller::new(params, platform, arm)?;
    if !spec.initial_alpha.iter().all(|a| a.is_finite()) {
        return Err(ParamError::new("initial_alpha", Rule::NonFinite));
    }
    c.state.alpha =
        companion_core::nalgebra::Vector2::new(T::of(spec.initial_alpha[0]), T::of(spec.initial_alpha[1]));
    Ok(c)
}

/// Why a spatial controller could not be built.
#[derive(Debug, thiserror::Error)]
pub enum SpatialControllerError {
    /// The arm's chain does not have the joints asked for, or is invalid.
    #[error(transparent)]
    Arm(#[from] ArmError),
    /// A parameter of the spatial law breaks a rule.
    #[error("the spatial law's parameters")]
    Law(#[source] ParamError),
    /// `[controller] reach_joints` names a joint the arm does not have.
    #[error("controller.reach_joints: the arm has no joint named {name:?} (its joints: {joints})")]
    ReachJoint {
        /// The name given.
        name: String,
        /// The arm's joints, in order.
        joints: String,
    },
    /// `[acceleration_limits] joints` has another number of values than the arm has joints.
    #[error("acceleration_limits.joints has {given} values; the arm has {joints} joints")]
    JointCount {
        /// The values given.
        given: usize,
        /// The arm's joints.
        joints: usize,
    },
    /// `[controller.joint_limits]` breaks a rule.
    #[error("[controller.joint_limits] {0}")]
    JointLimits(String),
}

/// `chain` with the law's own limits of `[controller.joint_limits]` (by joint name, `names` in
/// the chain's order): each inside the robot's, and the home strictly inside it.
///
/// # Errors
/// An unknown joint (the message lists the chain's), limits not inside the robot's or empty,
/// or a home outside them.
pub fn law_limits<T: Real, const N: usize>(
    spec: &ControllerSpec,
    chain: &Chain<T, N>,
    names: &[String],
) -> Result<Chain<T, N>, SpatialControllerError> {
    let mut chain = *chain;
    let Some(limits) = &spec.overrides.joint_limits else {
        return Ok(chain);
    };
    let err = |m: String| SpatialControllerError::JointLimits(m);
    for (name, [lo, hi]) in limits {
        let Some(i) = names.iter().position(|n| n == name) else {
            return Err(err(format!("names {name}, which is not a joint of the arm ({})", names.join(", "))));
        };
        let j = &mut chain.joints[i];
        let (rlo, rhi, home) = (j.lower.as_f64(), j.upper.as_f64(), j.home.as_f64());
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(err(format!("{name} = [{lo}, {hi}]: the limits must be finite, lower < upper")));
        }
        if *lo < rlo || *hi > rhi {
            return Err(err(format!(
                "{name} = [{lo}, {hi}] is not inside the robot's limits [{rlo}, {rhi}]"
            )));
        }
        if !(home > *lo && home < *hi) {
            return Err(err(format!("{name} = [{lo}, {hi}] does not hold the home ({name} = {home})")));
        }
        j.lower = T::of(*lo);
        j.upper = T::of(*hi);
    }
    Ok(chain)
}

/// The spatial controller of `spec` for `arm` with `N` joints, in the spec's scalar type on
/// its platform, behind one type (built once, before a run: the box is the only allocation).
///
/// # Errors
/// A chain that does not have `N` joints or is invalid, or an invalid parameter.
pub fn boxed_spatial_controller<const N: usize>(
    spec: &ControllerSpec,
    arm: &SpatialArmSpec,
) -> Result<Box<dyn SpatialStep<N> + Send>, SpatialControllerError>
where
    SpatialArm<f64, N>: Manipulator<f64, N, Space = Spatial>,
    SpatialArm<f32, N>: Manipulator<f32, N, Space = Spatial>,
{
    let law = SpatialControllerError::Law;
    if let Some(given) = spec.acceleration.as_ref().and_then(|a| a.joints.as_ref()).map(Vec::len) {
        if given != N {
            return Err(SpatialControllerError::JointCount { given, joints: N });
        }
    }
    let joints = reach_joints(spec, &arm.joint_names())?;
    let names = arm.joint_names();
    let c64 = || law_limits(spec, &arm.chain::<f64, N>()?, &names);
    let c32 = || law_limits(spec, &arm.chain::<f32, N>()?, &names);
    Ok(match (spec.platform, spec.scalar) {
        (PlatformKind::Unicycle, Scalar::F64) => {
            Box::new(spatial_controller(spec, &c64()?, joints, spec.unicycle::<f64>()).map_err(law)?)
        }
        (PlatformKind::Unicycle, Scalar::F32) => {
            Box::new(spatial_controller(spec, &c32()?, joints, spec.unicycle::<f32>()).map_err(law)?)
        }
        (PlatformKind::Car, Scalar::F64) => {
            Box::new(spatial_controller(spec, &c64()?, joints, spec.car::<f64>()).map_err(law)?)
        }
        (PlatformKind::Car, Scalar::F32) => {
            Box::new(spatial_controller(spec, &c32()?, joints, spec.car::<f32>()).map_err(law)?)
        }
        (PlatformKind::Omni, Scalar::F64) => {
            Box::new(spatial_controller(spec, &c64()?, joints, Omnidirectional).map_err(law)?)
        }
        (PlatformKind::Omni, Scalar::F32) => {
            Box::new(spatial_controller(spec, &c32()?, joints, Omnidirectional).map_err(law)?)
        }
    })
}

#[cfg(test)]
mod tests {
    use companion_core::{Chain, PaperRun};

    use super::*;

    fn weight(run: PaperRun, lambda: Option<f64>) -> Weight<f64, 6> {
        let mut spec = ControllerSpec::paper(PlatformKind::Unicycle, run, Scalar::F64);
        spec.overrides.lambda = lambda;
        let arm = SpatialArm::new(&Chain::<f64, 6>::ur5()).unwrap();
        spatial_params(&spec, &arm).unwrap().secondary.weight
    }

    #[test]
    fn controller_lambda_filters_a_spatial_arms_weight_whose_margins_stay_the_arms() {
        let (paper, set) = (weight(PaperRun::B, None), weight(PaperRun::B, Some(3.0)));
        let (
            Weight::Filtered { margins: m0, lambda: l0, xi: x0 },
            Weight::Filtered { margins: m1, lambda: l1, xi: x1 },
        ) = (paper, set)
        else {
            panic!("run (b) filters its weight: {paper:?}, {set:?}");
        };
        assert_eq!((l0, l1), (1.66, 3.0));
        assert_eq!((x0, x1), (1.0, 1.0));
        assert_eq!(m0, m1);
        // Run (a)'s weight is the constant 1: there is no filter for `lambda` to set.
        assert_eq!(weight(PaperRun::A, Some(3.0)), Weight::Constant(1.0));
    }

    #[test]
    fn the_singularity_settings_reach_the_arm_and_bad_ones_are_named() {
        let mut spec = ControllerSpec::paper(PlatformKind::Car, PaperRun::A, Scalar::F64);
        let chain = Chain::<f64, 6>::ur5();
        let core = SpatialArm::new(&chain).unwrap();
        let arm = spatial_arm(&spec, &chain, None).unwrap();
        // Unset, the onset is the core's rule from the arm's home (the UR5's: ρ_home / 50, under
        // the fixed 10⁻³), the depth and the singular bound the core's.
        let p = spatial_params::<f64, 6>(&spec, &core).unwrap();
        let onset = core.onset_from_home(&p.primary, &p.joint_limits);
        assert!(onset > 0.0 && onset < 1e-3, "{onset}");
        assert_eq!((arm.damping(), arm.singular_below()), ((onset, core.damping().1), core.singular_below()));
        spec.overrides.damping_below = Some(1e-2);
        spec.overrides.singular_below = Some(1e-12);
        let arm = spatial_arm(&spec, &chain, None).unwrap();
        assert_eq!((arm.damping(), arm.singular_below()), ((1e-2, core.damping().1), 1e-12));
        assert_eq!(spatial_only_keys(&spec), ["controller.damping_below", "controller.singular_below"]);
        for (key, bad) in [("damping_below", 1.5), ("damping_depth", f64::NAN), ("singular_below", -1.0)] {
            let mut s = ControllerSpec::paper(PlatformKind::Car, PaperRun::A, Scalar::F64);
            match key {
                "damping_below" => s.overrides.damping_below = Some(bad),
                "damping_depth" => s.overrides.damping_depth = Some(bad),
                _ => s.overrides.singular_below = Some(bad),
            }
            let e = spatial_arm(&s, &chain, None).unwrap_err();
            assert_eq!(e.param, key, "{e:?}");
        }
    }
}
