//! What the controller process serves: its identity on the wire (platform, joints, target
//! space, arm and scenario hashes) and the law it builds once the plant has announced itself —
//! the paper's planar law ([`PlanarLaw`]) or the spatial law of §5 for an arm of `N` joints
//! ([`SpatialLaw`]). The loop ([`super::serve`]) is the same for both.

use companion_core::{Manipulator, Planar, Spatial, SpatialArm, HISTORY};

use super::handshake;
use crate::domain::arm::SpatialArmSpec;
pub use crate::domain::controller::Law;
use crate::domain::controller::{
    boxed_spatial_controller, AnyController, ControllerSpec, SpatialControllerError, SpatialStep, JOINTS,
};
use crate::domain::scenario::ScenarioError;
use crate::transport::wire::target::WireSpace;
use crate::transport::wire::{Announcement, ControllerIdentity};

/// Why the law for the plant that announced itself cannot be built: a parameter of the
/// planar law, or the spatial law's arm or parameters.
#[derive(Debug, thiserror::Error)]
pub enum LawError {
    /// The planar law.
    #[error(transparent)]
    Planar(#[from] ScenarioError),
    /// The spatial law.
    #[error(transparent)]
    Spatial(#[from] SpatialControllerError),
}

/// What the controller serves: its identity, and the law for a plant's announcement.
pub trait Served<const N: usize> {
    /// Where the target lives.
    type Space: WireSpace;
    /// The law built for the plant.
    type Law: Law<N, Self::Space>;

    /// What the controller announces (and admits plants by).
    fn identity(&self) -> ControllerIdentity;

    /// The law for the plant that announced `a` (the joint guard from its hold periods:
    /// [`handshake::for_plant`]), and the largest delay it admits at the plant's `dt` (s).
    ///
    /// # Errors
    /// An invalid parameter.
    fn build(&self, a: &Announcement) -> Result<(Self::Law, f64), LawError>;
}

/// The largest delay a law of `spec` admits at period `dt`: its `max_delay`, and no more
/// than its history of commands spans.
fn max_delay(spec: &ControllerSpec, dt: f64) -> f64 {
    let span = dt * HISTORY as f64;
    spec.params::<f64>().max_delay.min(span)
}

/// The paper's planar law for the RPR arm.
#[derive(Clone, Copy, Debug)]
pub struct PlanarLaw<'a>(pub &'a ControllerSpec);

impl Served<JOINTS> for PlanarLaw<'_> {
    type Space = Planar;
    type Law = AnyController;

    fn identity(&self) -> ControllerIdentity {
        handshake::identity(self.0)
    }

    fn build(&self, a: &Announcement) -> Result<(AnyController, f64), LawError> {
        let run = handshake::for_plant(self.0, a);
        let ctrl = AnyController::new(&run).map_err(ScenarioError::Param)?;
        Ok((ctrl, max_delay(&run, a.dt)))
    }
}

/// The spatial law of §5 for an arm of `N` joints.
#[derive(Clone, Copy, Debug)]
pub struct SpatialLaw<'a> {
    /// The platform law's settings and the run (a)–(d).
    pub spec: &'a ControllerSpec,
    /// The arm.
    pub arm: &'a SpatialArmSpec,
    /// The arm's hash ([`crate::transport::wire::canonical::arm_hash`]).
    pub arm_hash: u64,
}

impl<const N: usize> Served<N> for SpatialLaw<'_>
where
    SpatialArm<f64, N>: Manipulator<f64, N, Space = Spatial>,
    SpatialArm<f32, N>: Manipulator<f32, N, Space = Spatial>,
{
    type Space = Spatial;
    type Law = Box<dyn SpatialStep<N> + Send>;

    fn identity(&self) -> ControllerIdentity {
        handshake::spatial_identity(self.spec, N, self.arm_hash)
    }

    fn build(&self, a: &Announcement) -> Result<(Self::Law, f64), LawError> {
        let run = handshake::for_plant(self.spec, a);
        let law = boxed_spatial_controller::<N>(&run, self.arm)?;
        Ok((law, max_delay(&run, a.dt)))
    }
}
