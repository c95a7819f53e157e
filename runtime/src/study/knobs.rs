//! The controller parameters that `companion explore` samples and `companion tune` searches
//! ([`Knob`]), each with the config-file key it sets, and how a set of values becomes a
//! scenario ([`apply`]).
//!
//! A knob's name is the key it sets in a `--config` file: `epsilon`, `eta_1`, `eta_2`, `eta_3`,
//! `k` in `[car]` (Lemma 2 and eq. 59), `epsilon_1`, `epsilon_2` in `[unicycle]` (Lemma 1),
//! `stroke` in `[arm]`, and in `[controller]` one entry of `k_bar` (`k_bar_1..3`, eq. 36), all
//! of `d` (eq. 37) or `gain` (eq. 30), `lambda` (eq. 53), and a spatial arm's damping onset
//! `damping_below`, and in `[velocity_limits]` the cap on the transverse function's phase rate
//! `alpha_rate` (`|α̇ᵢ|`, rad/s; unicycle and car). Two more scale a spatial arm (`--arm`, [`ArmScale`]) rather than set a
//! config key: `joint_speed` (every joint's published speed times it) and `reach` (every
//! length of the arm times it).

use companion_core::PlatformKind;
use serde::{Deserialize, Serialize};

use crate::domain::arm::ArmScale;
use crate::domain::controller::{platform_name, ArmConfig};
use crate::domain::scenario::{Scenario, ScenarioBuilder};

/// A parameter that can be sampled or searched.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Knob {
    /// Lemma 2's `ε` (car), the transverse function's size.
    Epsilon,
    /// Lemma 2's `η₁` (car).
    Eta1,
    /// Lemma 2's `η₂` (car).
    Eta2,
    /// Lemma 2's `η₃` (car).
    Eta3,
    /// The steering gain `k` of (59) (car), 1/s.
    K,
    /// Lemma 1's `ε₁` (unicycle), m.
    Epsilon1,
    /// Lemma 1's `ε₂` (unicycle).
    Epsilon2,
    /// `K̄₁₁` of (36): the weight of `v` (all platforms).
    KBar1,
    /// `K̄₂₂` of (36): of `ω` (unicycle), `α̇₁` (car), `v₂` (omni).
    KBar2,
    /// `K̄₃₃` of (36): of `α̇` (unicycle), `α̇₂` (car), `ω` (omni).
    KBar3,
    /// `D = d I₃` of (37): the rate at which `h_s` is made to decrease.
    D,
    /// The arm gain `g` of `G = −g I₃` (30), 1/s.
    Gain,
    /// `λ` of the weight filter (53), 1/s (runs b–d).
    Lambda,
    /// The prismatic joint's stroke `q₂⁺` (m); `q₂*`, the margins and `r_*` follow
    /// (`ArmConfig`).
    Stroke,
    /// A spatial arm's joint speeds: every joint's published `max_velocity` times this.
    JointSpeed,
    /// A spatial arm's size: every length of the arm times this ([`ArmScale::reach`]).
    Reach,
    /// A spatial arm's damping onset `ρ₀` (`[controller] damping_below`): below it the
    /// arm's inverse is damped.
    DampingBelow,
    /// The cap on the transverse function's phase rate `|α̇ᵢ|` (`[velocity_limits]
    /// alpha_rate`, rad/s; unicycle and car): with the velocity limits' common factor, it
    /// slows the platform's manoeuvres (their frequency goes with `α̇`, the paper's §2).
    AlphaRate,
}

/// Which arm a knob belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArmKind {
    /// The paper's planar RPR arm (`--arm rpr`).
    Planar,
    /// A spatial arm (`--arm ur5|panda|FILE`).
    Spatial,
}

/// Every knob, in the order columns and draws use (new knobs go at the end, so that the
/// draws of the others stay where they were).
pub const ALL: [Knob; 18] = [
    Knob::Epsilon,
    Knob::Eta1,
    Knob::Eta2,
    Knob::Eta3,
    Knob::K,
    Knob::Epsilon1,
    Knob::Epsilon2,
    Knob::KBar1,
    Knob::KBar2,
    Knob::KBar3,
    Knob::D,
    Knob::Gain,
    Knob::Lambda,
    Knob::Stroke,
    Knob::JointSpeed,
    Knob::Reach,
    Knob::DampingBelow,
    Knob::AlphaRate,
];

impl Knob {
    /// The knob's name (its key in a space or config file).
    pub fn name(self) -> &'static str {
        match self {
            Self::Epsilon => "epsilon",
            Self::Eta1 => "eta_1",
            Self::Eta2 => "eta_2",
            Self::Eta3 => "eta_3",
            Self::K => "k",
            Self::Epsilon1 => "epsilon_1",
            Self::Epsilon2 => "epsilon_2",
            Self::KBar1 => "k_bar_1",
            Self::KBar2 => "k_bar_2",
            Self::KBar3 => "k_bar_3",
            Self::D => "d",
            Self::Gain => "gain",
            Self::Lambda => "lambda",
            Self::Stroke => "stroke",
            Self::JointSpeed => "joint_speed",
            Self::Reach => "reach",
            Self::DampingBelow => "damping_below",
            Self::AlphaRate => "alpha_rate",
        }
    }

    /// The knob named `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        ALL.into_iter().find(|k| k.name() == name)
    }

    /// The knob named `name`, checked to apply to `platform` and `arm`.
    ///
    /// # Errors
    /// No knob has that name (the message lists them), or it is another platform's or
    /// another arm's.
    pub fn parse_for(name: &str, platform: PlatformKind, arm: ArmKind) -> Result<Self, String> {
        let k = Self::from_name(name).ok_or_else(|| {
            let known: Vec<&str> = ALL.iter().map(|k| k.name()).collect();
            format!("unknown parameter `{name}` (known: {})", known.join(", "))
        })?;
        k.check_platform(platform)?;
        k.check_arm(arm)?;
        Ok(k)
    }

    /// The arm the knob belongs to (`None`: every arm). `gain`, `stroke` set the planar arm's
    /// task; `lambda` filters the weight Ψ of either arm (a spatial arm's margins of (52) are
    /// its own, its filter the spec's).
    pub fn arm(self) -> Option<ArmKind> {
        match self {
            Self::Gain | Self::Stroke => Some(ArmKind::Planar),
            Self::JointSpeed | Self::Reach | Self::DampingBelow => Some(ArmKind::Spatial),
            _ => None,
        }
    }

    /// Whether the knob applies to `arm`; otherwise the reason, for an error message.
    ///
    /// # Errors
    /// The knob is the other kind of arm's.
    pub fn check_arm(self, arm: ArmKind) -> Result<(), String> {
        match (self.arm(), arm) {
            (Some(ArmKind::Planar), ArmKind::Spatial) => Err(format!(
                "`{}` is a parameter of the paper's planar arm (--arm rpr), not of a spatial arm",
                self.name()
            )),
            (Some(ArmKind::Spatial), ArmKind::Planar) => Err(format!(
                "`{}` is a parameter of a spatial arm (--arm ur5|panda|FILE), not of the paper's planar arm",
                self.name()
            )),
            _ => Ok(()),
        }
    }

    /// The platform the knob belongs to (`None`: every platform).
    pub fn platform(self) -> Option<PlatformKind> {
        match self {
            Self::Epsilon | Self::Eta1 | Self::Eta2 | Self::Eta3 | Self::K => Some(PlatformKind::Car),
            Self::Epsilon1 | Self::Epsilon2 => Some(PlatformKind::Unicycle),
            _ => None,
        }
    }

    /// Whether the knob applies to `platform`; otherwise the reason, for an error message.
    ///
    /// # Errors
    /// The knob is another platform's.
    pub fn check_platform(self, platform: PlatformKind) -> Result<(), String> {
        if self == Self::AlphaRate && platform == PlatformKind::Omni {
            return Err("`alpha_rate` caps the transverse function's phase rate: the omni platform has none"
                .to_string());
        }
        match self.platform() {
            Some(p) if p != platform => Err(format!(
                "`{}` is a parameter of the {} platform, not of the {} platform (--platform)",
                self.name(),
                platform_name(p),
                platform_name(platform)
            )),
            _ => Ok(()),
        }
    }

    /// The knob's value in a built scenario.
    pub fn value(self, s: &Scenario) -> f64 {
        let c = &s.controller;
        let p = c.params::<f64>();
        match self {
            Self::Epsilon => c.car.epsilon,
            Self::Eta1 => c.car.eta_1,
            Self::Eta2 => c.car.eta_2,
            Self::Eta3 => c.car.eta_3,
            Self::K => c.car.k,
            Self::Epsilon1 => c.unicycle.epsilon_1,
            Self::Epsilon2 => c.unicycle.epsilon_2,
            Self::KBar1 => p.secondary.k_bar[0],
            Self::KBar2 => p.secondary.k_bar[1],
            Self::KBar3 => p.secondary.k_bar[2],
            Self::D => p.secondary.d[0],
            Self::Gain => p.primary.gain[0],
            Self::Lambda => match p.secondary.weight {
                companion_core::Weight::Filtered { lambda, .. }
                | companion_core::Weight::PerJoint { lambda, .. } => lambda,
                _ => f64::NAN,
            },
            Self::Stroke => c.arm.stroke_and_extension().0,
            // Factors on the arm as given.
            Self::JointSpeed | Self::Reach => 1.0,
            Self::DampingBelow => c.overrides.damping_below.unwrap_or(companion_core::DAMPING_BELOW),
            Self::AlphaRate => p.velocity_limits.alpha_rate,
        }
    }
}

/// The arm's scale the knobs among `values` set ([`ArmScale::ONE`] for the others).
pub fn arm_scale(values: &[(Knob, f64)]) -> ArmScale {
    let mut scale = ArmScale::ONE;
    for &(k, v) in values {
        match k {
            Knob::JointSpeed => scale.joint_speed = v,
            Knob::Reach => scale.reach = v,
            _ => {}
        }
    }
    scale
}

/// `builder` with the knobs set to `values`; `base` is the scenario `builder` builds (it gives
/// the values of the entries a knob does not set, e.g. the other entries of `k_bar`). The
/// arm's knobs (`joint_speed`, `reach`) set no key: [`arm_scale`] reads them.
pub fn apply(builder: &ScenarioBuilder, base: &Scenario, values: &[(Knob, f64)]) -> ScenarioBuilder {
    let mut file = builder.current_config().clone();
    let c = &base.controller;
    let p = c.params::<f64>();
    for &(knob, v) in values {
        match knob {
            Knob::Epsilon => file.car.get_or_insert(c.car).epsilon = v,
            Knob::Eta1 => file.car.get_or_insert(c.car).eta_1 = v,
            Knob::Eta2 => file.car.get_or_insert(c.car).eta_2 = v,
            Knob::Eta3 => file.car.get_or_insert(c.car).eta_3 = v,
            Knob::K => file.car.get_or_insert(c.car).k = v,
            Knob::Epsilon1 => file.unicycle.get_or_insert(c.unicycle).epsilon_1 = v,
            Knob::Epsilon2 => file.unicycle.get_or_insert(c.unicycle).epsilon_2 = v,
            Knob::KBar1 | Knob::KBar2 | Knob::KBar3 => {
                let i = match knob {
                    Knob::KBar1 => 0,
                    Knob::KBar2 => 1,
                    _ => 2,
                };
                let k = &mut file.controller.k_bar;
                k.get_or_insert([p.secondary.k_bar[0], p.secondary.k_bar[1], p.secondary.k_bar[2]])[i] = v;
            }
            Knob::D => file.controller.d = Some([v; 3]),
            Knob::Gain => file.controller.gain = Some([v; 3]),
            Knob::Lambda => file.controller.lambda = Some(v),
            Knob::Stroke => {
                let arm = file.arm.get_or_insert(ArmConfig::default());
                arm.stroke = Some(v);
            }
            Knob::DampingBelow => file.controller.damping_below = Some(v),
            // Over the limits that ran (the car's default ones too), so that setting the cap
            // keeps the rest; an infinite cap is none.
            Knob::AlphaRate => {
                file.velocity_limits.get_or_insert(c.limits.unwrap_or_default()).alpha_rate =
                    v.is_finite().then_some(v);
            }
            Knob::JointSpeed | Knob::Reach => {}
        }
    }
    builder.clone().config(file)
}

#[cfg(test)]
mod tests {
    use super::*;
    use companion_core::PaperRun;
    use companion_plant::PaperTrajectory;

    #[test]
    fn names_round_trip_and_apply_sets_what_value_reads() {
        for k in ALL {
            assert_eq!(Knob::from_name(k.name()), Some(k));
        }
        let b = Scenario::builder(PaperTrajectory::One, PaperRun::B, PlatformKind::Car);
        let base = b.clone().build().unwrap();
        let values: Vec<(Knob, f64)> = [
            (Knob::Epsilon, 0.2),
            (Knob::Eta1, 1.5),
            (Knob::Eta2, 4.0),
            (Knob::Eta3, 3.0),
            (Knob::K, 7.0),
            (Knob::KBar2, 33.0),
            (Knob::D, 2.0),
            (Knob::Gain, 4.0),
            (Knob::Lambda, 2.5),
            (Knob::Stroke, 0.9),
        ]
        .into();
        let s = apply(&b, &base, &values).build().unwrap();
        for (k, v) in values {
            assert_eq!(k.value(&s), v, "{}", k.name());
        }
        // The other entries of K̄ are the base's.
        assert_eq!(Knob::KBar1.value(&s), Knob::KBar1.value(&base));
        assert_eq!(Knob::KBar3.value(&s), Knob::KBar3.value(&base));
        assert!(Knob::Epsilon1.check_platform(PlatformKind::Car).is_err());
        assert!(Knob::Epsilon.check_platform(PlatformKind::Car).is_ok());
        assert!(Knob::D.check_platform(PlatformKind::Omni).is_ok());
        // The arm's knobs: only with a spatial arm, and they set no key of the config.
        assert!(Knob::JointSpeed.check_arm(ArmKind::Planar).is_err());
        assert!(Knob::Reach.check_arm(ArmKind::Spatial).is_ok());
        assert!(Knob::Gain.check_arm(ArmKind::Spatial).is_err());
        assert!(Knob::Epsilon.check_arm(ArmKind::Spatial).is_ok());
        let scaled = [(Knob::JointSpeed, 1.5), (Knob::Reach, 0.8), (Knob::Epsilon, 0.2)];
        assert_eq!(
            apply(&b, &base, &scaled).current_config(),
            apply(&b, &base, &scaled[2..]).current_config()
        );
        assert_eq!(arm_scale(&scaled), ArmScale { joint_speed: 1.5, reach: 0.8 });
        assert_eq!(arm_scale(&scaled[2..]), ArmScale::ONE);
    }

    /// `alpha_rate` sets `[velocity_limits] alpha_rate` over the limits that ran: the car's
    /// default limits stay, a preset merges with it (the stricter wins), the omni platform
    /// refuses it.
    #[test]
    fn alpha_rate_caps_the_phase_and_keeps_the_other_limits() {
        let car = Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Car);
        let base = car.clone().build().unwrap();
        let s = apply(&car, &base, &[(Knob::AlphaRate, 1.5)]).build().unwrap();
        let (l, d) =
            (s.controller.params::<f64>().velocity_limits, base.controller.params::<f64>().velocity_limits);
        assert_eq!(
            (l.alpha_rate, l.forward, l.angular, l.steering_rate),
            (1.5, d.forward, d.angular, d.steering_rate)
        );
        assert_eq!(Knob::AlphaRate.value(&s), 1.5);
        let uni = Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle)
            .limits(crate::domain::scenario::LimitsChoice::Tiago);
        let base = uni.clone().build().unwrap();
        assert_eq!(Knob::AlphaRate.value(&base), f64::INFINITY);
        let s = apply(&uni, &base, &[(Knob::AlphaRate, 2.5)]).build().unwrap();
        let l = s.controller.params::<f64>().velocity_limits;
        assert_eq!((l.alpha_rate, l.forward, l.angular), (2.5, 1.0, 2.09));
        assert!(Knob::AlphaRate.check_platform(PlatformKind::Omni).is_err());
        assert!(Knob::AlphaRate.check_platform(PlatformKind::Unicycle).is_ok());
        assert!(Knob::AlphaRate.check_arm(ArmKind::Spatial).is_ok());
    }
}
