//! What the two roles agree on at start-up, computed the same way on both sides: the
//! controller's identity (platform, joints, target space, arm, scenario hash, the longest
//! period its law admits), the scenario and arm hashes, and the one parameter of the law that depends on the plant's
//! announcement — the joint guard κ.
//!
//! The joint guard: a real-time plant may hold a command for `hold_periods` periods after the
//! one it was meant for, so the law limits each joint's step to `κ = min(κ₀, 1/(hold + 2))`
//! of its distance to the limit, and a held command never drives a joint onto its limit. A
//! lockstep plant never holds a command: κ = κ₀ there (the run equals `companion sim`). Both
//! `hold_periods` and the lockstep flag are the plant's, on the wire; the controller's own
//! flags play no part.

use companion_core::Chain;

use crate::domain::controller::{ControllerSpec, JOINTS};
use crate::transport::wire::canonical::scenario_hash;
use crate::transport::wire::target::space;
use crate::transport::wire::{canonical, platform, Announcement, ControllerIdentity};

/// κ₀: the core's default joint guard when the scenario does not set one.
const DEFAULT_JOINT_STEP_FRACTION: f64 = 0.5;

/// The scenario hash of a controller specification: [`scenario_hash`] of its JSON form (the
/// `controller` object of `scenario.json`).
pub fn controller_hash(spec: &ControllerSpec) -> u64 {
    serde_json::to_value(spec).map_or(0, |v| scenario_hash(&v))
}

/// The arm hash of the runtime's arm, the paper's RPR arm ([`canonical::arm_hash`]; both
/// roles announce it).
pub fn arm_hash() -> u64 {
    canonical::arm_hash(&Chain::<f64, JOINTS>::rpr())
}

/// The controller's identity for a specification (the paper's arm).
pub fn identity(spec: &ControllerSpec) -> ControllerIdentity {
    ControllerIdentity {
        platform: platform::code(spec.platform),
        joint_count: JOINTS as u32,
        space: space::PLANAR,
        arm_hash: arm_hash(),
        scenario_hash: controller_hash(spec),
        max_dt: spec.params::<f64>().max_time_step,
    }
}

/// The controller's identity for a specification with a spatial arm of `joints` joints whose
/// hash is `arm_hash` (§5; the platform law's `max_time_step` is the spec's, as on planar
/// runs).
pub fn spatial_identity(spec: &ControllerSpec, joints: usize, arm_hash: u64) -> ControllerIdentity {
    ControllerIdentity {
        joint_count: u32::try_from(joints).unwrap_or(u32::MAX),
        space: space::SPATIAL,
        arm_hash,
        ..identity(spec)
    }
}

/// The joint guard κ for a plant that holds commands for `hold_periods` periods (real time)
/// or waits for every one (`lockstep`).
pub fn joint_step_fraction(spec: &ControllerSpec, lockstep: bool, hold_periods: u32) -> f64 {
    let k0 = spec.overrides.joint_step_fraction.unwrap_or(DEFAULT_JOINT_STEP_FRACTION);
    if lockstep {
        k0
    } else {
        k0.min(1.0 / (f64::from(hold_periods) + 2.0))
    }
}

/// The specification the controller runs for a plant with this announcement (κ set from the
/// plant's hold periods in real time; unchanged in lockstep).
pub fn for_plant(spec: &ControllerSpec, a: &Announcement) -> ControllerSpec {
    let mut s = spec.clone();
    if !a.lockstep() {
        s.overrides.joint_step_fraction = Some(joint_step_fraction(spec, false, a.hold_periods));
    }
    s
}

#[cfg(test)]
mod tests {
    use companion_core::{PaperRun, PlatformKind};

    use super::*;
    use crate::domain::controller::{ControllerConfig, Scalar};
    use crate::transport::wire::flags;

    fn spec() -> ControllerSpec {
        ControllerSpec::paper(PlatformKind::Unicycle, PaperRun::A, Scalar::F64)
    }

    fn announcement(lockstep: bool, hold_periods: u32) -> Announcement {
        Announcement {
            flags: if lockstep { flags::LOCKSTEP } else { 0 },
            platform: platform::UNICYCLE,
            joint_count: 3,
            space: crate::transport::wire::target::space::PLANAR,
            hold_periods,
            dt: 1e-3,
            period_ns: if lockstep { 0 } else { 1_000_000 },
            scenario_hash: 0,
            arm_hash: 0,
        }
    }

    #[test]
    fn the_joint_guard_follows_the_plants_announcement_only() {
        // Real time: room for the plant's held periods, whatever the controller's own flags.
        assert_eq!(
            for_plant(&spec(), &announcement(false, 20)).overrides.joint_step_fraction,
            Some(1.0 / 22.0)
        );
        assert_eq!(for_plant(&spec(), &announcement(false, 0)).overrides.joint_step_fraction, Some(0.5));
        // Lockstep: the specification as given (equal to `companion sim`).
        assert_eq!(for_plant(&spec(), &announcement(true, 20)), spec());
        // A scenario's smaller guard is kept.
        let mut s = spec();
        s.overrides = ControllerConfig { joint_step_fraction: Some(0.01), ..ControllerConfig::default() };
        assert_eq!(for_plant(&s, &announcement(false, 20)).overrides.joint_step_fraction, Some(0.01));
    }

    #[test]
    fn the_hash_is_the_canonical_hash_of_the_specification_and_depends_on_it() {
        let a = controller_hash(&spec());
        let v = serde_json::to_value(spec()).unwrap();
        assert_eq!(a, scenario_hash(&v));
        let other = ControllerSpec::paper(PlatformKind::Unicycle, PaperRun::B, Scalar::F64);
        assert_ne!(a, controller_hash(&other));
        let id = identity(&spec());
        assert_eq!((id.platform, id.joint_count, id.scenario_hash), (platform::UNICYCLE, 3, a));
        assert!(id.max_dt > 0.0);
    }
}
