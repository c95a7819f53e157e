//! A run's replay: each logged [`Row`] as a [`ReplayFrame`], the arm drawn in 3D from its
//! description as data — a spatial arm's chain, or the paper's RPR arm as `Chain::rpr()`
//! (the same geometry as the plant's `Rpr`, at height 0, the platform on the ground).
//!
//! The link frames come from the chain (URDF form, see `companion_core::chain`):
//!
//! ```text
//! base_from_link₁ = M · O₁ · J₁(q₁),   linkᵢ₋₁_from_linkᵢ = Oᵢ · Jᵢ(qᵢ),   link_N_from_effector = E
//! ```
//!
//! and the tracking error is the row's `e_p` (the plant's, whose norm is the row's `ep_norm`).

use std::marker::PhantomData;
use std::path::Path;

use companion_core::nalgebra::SVector;
use companion_core::space::Vector as _;
use companion_core::{Chain, Planar, PlatformCommand, PlatformKind, Pose3};

use super::mcap::{McapRecorder, ReplayError, ReplayFrame, ReplayLayout, ReplaySummary};
use super::row::{Row, Task};
use crate::domain::controller::JOINTS;
use crate::domain::scenario::Scenario;

/// Each link's frame in its parent's frame at `q` (`parent_from_link`; the first link's
/// parent is the platform), and the end effector in the last link's frame: the chain of the
/// module docs, for any arm described as data.
pub fn link_frames<const N: usize>(
    chain: &Chain<f64, N>,
    q: &SVector<f64, N>,
) -> ([Pose3<f64>; N], Pose3<f64>) {
    let links = core::array::from_fn(|i| {
        let j = &chain.joints[i];
        let local = j.origin.compose(&j.motion(q[i]));
        if i == 0 {
            chain.mount.compose(&local)
        } else {
            local
        }
    });
    (links, chain.tool)
}

/// The platform command's components a platform has, in the order of
/// [`platform_command`].
pub fn platform_command_names(kind: PlatformKind) -> &'static [&'static str] {
    match kind {
        PlatformKind::Unicycle => &["v", "omega"],
        PlatformKind::Car => &["v", "omega", "v_xi"],
        PlatformKind::Omni => &["v", "v_lat", "omega"],
    }
}

/// A platform command's components as [`platform_command_names`] orders them, into `out`;
/// returns how many there are.
pub fn platform_command(kind: PlatformKind, c: &PlatformCommand<f64>, out: &mut [f64; 3]) -> usize {
    let v = match kind {
        PlatformKind::Unicycle => [c.v, c.omega, 0.0],
        PlatformKind::Car => [c.v, c.omega, c.v_xi],
        PlatformKind::Omni => [c.v, c.v_lat, c.omega],
    };
    *out = v;
    platform_command_names(kind).len()
}

/// The replay file of a run of either arm: the arm's chain (the paper's RPR arm as
/// `Chain::rpr()`, or a spatial arm's), its layout, and the MCAP writer.
#[derive(Debug)]
pub struct Replay<S: Task = Planar, const N: usize = JOINTS> {
    mcap: McapRecorder,
    chain: Chain<f64, N>,
    kind: PlatformKind,
    status: String,
    space: PhantomData<S>,
}

impl<S: Task, const N: usize> Replay<S, N> {
    /// The replay's layout for an arm of `N` joints on a platform of `kind`.
    pub fn layout(kind: PlatformKind) -> ReplayLayout {
        let names = |prefix: &str| (1..=N).map(|i| format!("{prefix}{i}")).collect();
        ReplayLayout {
            links: names("link"),
            joints: names("q"),
            platform_command: platform_command_names(kind).iter().map(|s| (*s).to_string()).collect(),
            e_p: S::ERROR_NAMES.iter().map(|s| (*s).to_string()).collect(),
        }
    }

    /// Creates `path` for the arm `chain` on a platform of `kind` (see
    /// [`McapRecorder::create`]).
    ///
    /// # Errors
    /// The file cannot be created.
    pub fn create(path: &Path, kind: PlatformKind, chain: Chain<f64, N>) -> Result<Self, ReplayError> {
        let mcap = McapRecorder::create(path, Self::layout(kind))?;
        Ok(Self { mcap, chain, kind, status: String::with_capacity(64), space: PhantomData })
    }

    /// Writes a logged row.
    ///
    /// # Errors
    /// Writing failed.
    pub fn write(&mut self, row: &Row<S, N>) -> Result<(), ReplayError> {
        let p = &row.plant;
        let (links, effector) = link_frames(&self.chain, &p.joints);
        let mut platform = [0.0; 3];
        let n = platform_command(self.kind, &row.report.command.platform, &mut platform);
        self.status.clear();
        row.write_status(&mut self.status);
        let frame = ReplayFrame {
            t: p.t,
            base: Pose3::from_planar(&p.base),
            links: &links,
            effector,
            target: S::lift(&p.target),
            joints: p.joints.as_slice(),
            platform_command: &platform[..n],
            joint_command: row.report.command.joints.as_slice(),
            e_p: p.e_p.as_slice(),
            ep_norm: p.ep_norm,
            h_s: row.report.h_s,
            status: &self.status,
        };
        self.mcap.write(&frame)
    }

    /// Writes every row and finishes the file.
    ///
    /// # Errors
    /// Writing failed.
    pub fn write_all(mut self, rows: &[Row<S, N>]) -> Result<ReplaySummary, ReplayError> {
        for r in rows {
            self.write(r)?;
        }
        self.finish()
    }

    /// The run never started: removes the file (see [`McapRecorder::discard`]).
    pub fn discard(self) {
        self.mcap.discard();
    }

    /// Finishes the file.
    ///
    /// # Errors
    /// Writing failed.
    pub fn finish(self) -> Result<ReplaySummary, ReplayError> {
        self.mcap.finish()
    }
}

impl Replay {
    /// Creates `path` for a run of the paper's arm in scenario `s`.
    ///
    /// # Errors
    /// The file cannot be created.
    pub fn for_scenario(path: &Path, s: &Scenario) -> Result<Self, ReplayError> {
        Self::create(path, s.controller.platform, Chain::rpr())
    }
}

#[cfg(test)]
mod tests {
    use companion_core::{Arm, Pose, Rpr};

    use super::*;

    #[test]
    fn the_drawn_arm_ends_at_the_plants_end_effector() {
        // The chain's frames against the plant's closed form (`Rpr`), over the joint ranges.
        let chain = Chain::<f64, 3>::rpr();
        let arm = Rpr::<f64>::paper();
        let base = Pose::new(1.5, -0.7, 2.1);
        for k in 0..50 {
            let x = f64::from(k) / 49.0;
            let q = SVector::<f64, 3>::new(-1.0 + 2.0 * x, 0.05 + 0.6 * x, 1.5 - 3.0 * x);
            let (links, tool) = link_frames(&chain, &q);
            let mut world = Pose3::from_planar(&base);
            for l in &links {
                world = world.compose(l);
            }
            let effector = world.compose(&tool);
            let expected = base.compose(&arm.end_effector(&q));
            let t = effector.translation;
            assert!((t[0] - expected.x).abs() < 1e-12 && (t[1] - expected.y).abs() < 1e-12, "{q:?}");
            assert!(t[2].abs() < 1e-15, "the planar arm lies at height 0");
            let heading = effector.rotation[(1, 0)].atan2(effector.rotation[(0, 0)]);
            assert!(companion_core::wrap_angle(heading - expected.theta).abs() < 1e-12, "{q:?}");
            // r_eb is what the law uses: its inverse is the same pose.
            let r_be = arm.kinematics(&q).r_eb.inverse();
            assert!((r_be.x - arm.end_effector(&q).x).abs() < 1e-12);
        }
    }
}
