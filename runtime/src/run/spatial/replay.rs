//! The spatial path's replay (`companion sim --arm … --mcap FILE`): each logged
//! [`SpatialRecord`] as a [`ReplayFrame`] for the MCAP writer.
//!
//! A record holds every frame in the world; the replay wants each link in its parent's
//! frame (Foxglove's transform tree `world → base → link1 → … → linkN → effector`):
//!
//! ```text
//! base_from_link₁ = (world_from_base)⁻¹ world_from_link₁
//! linkᵢ₋₁_from_linkᵢ = (world_from_linkᵢ₋₁)⁻¹ world_from_linkᵢ
//! linkN_from_effector = (world_from_linkN)⁻¹ world_from_effector
//! ```
//!
//! Composing them back gives the world poses to rounding (tested).

use companion_core::{PlatformKind, Pose3};

use super::SpatialScenario;
use crate::domain::arm::MAX_JOINTS;
use crate::domain::record::mcap::ReplayError;
use crate::domain::record::replay::{platform_command, platform_command_names};
use crate::domain::record::spatial::SpatialRecord;
use crate::domain::record::{McapRecorder, ReplayFrame, ReplayLayout, ReplaySummary};

/// The names of `e_p`'s six components: the translation (m) and the rotation vector (rad) of
/// `(r*_ed)⁻¹ r_ed`.
pub const E_P_NAMES: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];

/// The replay's layout for the arm and platform of `s`.
pub fn layout(s: &SpatialScenario) -> ReplayLayout {
    let n = s.arm.joints();
    let names = |prefix: &str| (1..=n).map(|i| format!("{prefix}{i}")).collect();
    ReplayLayout {
        links: names("link"),
        joints: names("q"),
        platform_command: platform_command_names(s.base.controller.platform)
            .iter()
            .map(|c| (*c).to_string())
            .collect(),
        e_p: E_P_NAMES.iter().map(|c| (*c).to_string()).collect(),
    }
}

/// Each link's frame in its parent's (the first link's parent is the platform) and the end
/// effector in the last link's frame, from the record's world poses (the module's equations).
pub fn parent_frames(r: &SpatialRecord) -> ([Pose3<f64>; MAX_JOINTS], Pose3<f64>) {
    let mut links = [Pose3::identity(); MAX_JOINTS];
    let mut parent = r.base;
    for (local, world) in links.iter_mut().zip(&r.links[..r.joints]) {
        *local = parent.between(world);
        parent = *world;
    }
    (links, parent.between(&r.effector))
}

/// Writes every record into `mcap` and finishes the file.
///
/// # Errors
/// Writing failed.
pub fn write(
    mut mcap: McapRecorder,
    kind: PlatformKind,
    records: &[SpatialRecord],
) -> Result<ReplaySummary, ReplayError> {
    let mut status = String::with_capacity(64);
    for r in records {
        let (links, effector) = parent_frames(r);
        let mut platform = [0.0; 3];
        let k = platform_command(kind, &r.command, &mut platform);
        status.clear();
        // As timeseries.csv's `status` column of a spatial run.
        r.write_status(&mut status);
        let e_p: [f64; 6] = r.e_p.into();
        let frame = ReplayFrame {
            t: r.t,
            base: r.base,
            links: &links[..r.joints],
            effector,
            target: r.target,
            joints: &r.q[..r.joints],
            platform_command: &platform[..k],
            joint_command: &r.joint_rates[..r.joints],
            e_p: &e_p,
            ep_norm: r.ep_norm,
            h_s: r.h_s,
            status: &status,
        };
        mcap.write(&frame)?;
    }
    mcap.finish()
}

#[cfg(test)]
mod tests {
    use companion_core::nalgebra::Vector6;
    use companion_core::Pose3;

    use super::*;

    /// Composing the parent frames back from the base gives every world pose.
    #[test]
    fn parent_frames_compose_back_to_the_world_poses() {
        let pose = |k: f64| Pose3::exp(&Vector6::new(0.3 * k, -0.2, 0.1 * k, 0.2, -0.4 * k, 0.7));
        let mut r = SpatialRecord {
            t: 0.0,
            joints: 7,
            base: pose(0.5),
            heading: 0.0,
            steering: 0.0,
            q: [0.0; MAX_JOINTS],
            links: [Pose3::identity(); MAX_JOINTS],
            effector: pose(9.0),
            target: pose(1.0),
            target_twist: Vector6::zeros(),
            command: companion_core::Command::<f64, 1>::zero().platform,
            joint_rates: [0.0; MAX_JOINTS],
            e_p: Vector6::zeros(),
            ep_norm: 0.0,
            h_s: 0.0,
            joint_scale: 1.0,
            saturation: 1.0,
            error: None,
            source: crate::domain::record::CommandSource::Fresh,
        };
        for (k, l) in (1..=7u8).zip(r.links.iter_mut()) {
            *l = pose(f64::from(k));
        }
        let (local, effector) = parent_frames(&r);
        let mut world = r.base;
        for (i, (l, w)) in local.iter().zip(&r.links).take(7).enumerate() {
            world = world.compose(l);
            let d = (world.translation - w.translation).amax() + (world.rotation - w.rotation).amax();
            assert!(d < 1e-12, "link {i}: {d}");
        }
        let e = world.compose(&effector);
        assert!((e.translation - r.effector.translation).amax() < 1e-12);
        assert!(local[7] == Pose3::identity(), "unused links stay identity");
    }
}
