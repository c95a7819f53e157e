//! What the law needs from an arm: one trait, [`Manipulator`], for the planar arms of §4
//! (every [`Arm`](crate::Arm), through a blanket implementation) and the spatial arms of
//! §5 ([`SpatialArm`](crate::SpatialArm)).
//!
//! The law ([`ControlLaw`](crate::ControlLaw)) is written once: it predicts the robot over
//! the hold, runs the platform law on the planar projection of the target, and asks the arm
//! for its law (30) at the predicted point ([`Manipulator::arm_law`]). Each arm evaluates
//! its own task — `e_m` and its derivatives, planar or spatial — and hands the result to
//! the same discretisation (`arm_law`: the linearly implicit, A-stable step and the
//! sensitivity to the platform's velocity), which solves it with an inverse (as many joints
//! as task rows, or fewer) or with a weighted pseudo-inverse and the joint-limit penalty in
//! the null space (more joints). The joint guard is applied after, by the law.

use nalgebra::{SMatrix, SVector, Vector3};

use crate::error::{ParamError, StepError};
use crate::params::{JointLimits, PrimaryTask};
use crate::scalar::Real;
use crate::secondary::ArmTerms;
use crate::space::Space;

/// Where the arm law is evaluated: the state predicted for the middle of the hold.
#[derive(Clone, Copy, Debug)]
pub struct TaskPoint<'a, T: Real, const N: usize, S: Space<T>> {
    /// Joint positions `q`.
    pub q: &'a SVector<T, N>,
    /// The target seen from the base, `r_bd`.
    pub r_bd: &'a S::Relative,
    /// The target's body velocity `u_d`.
    pub u_d: &'a S::Vector,
    /// The platform's body velocity commanded, `u_b = (v₁, v₂, ω)`.
    pub u_b: &'a Vector3<T>,
    /// `Γ` of (22) (the scalar of `Γ I`).
    pub gamma: T,
    /// `Γ̇`.
    pub gamma_rate: T,
    /// The filtered joints `q̂` of (26).
    pub q_hat: &'a SVector<T, N>,
    /// Their rate `q̂̇`.
    pub q_hat_rate: &'a SVector<T, N>,
    /// The previous joint command, with which the point was predicted (the guess).
    pub guess: &'a SVector<T, N>,
}

/// The arm law at a point, before the joint guard.
#[derive(Clone, Copy, Debug)]
pub struct TaskStep<T: Real, const N: usize, S: Space<T>> {
    /// `u_q` (rad/s or m/s).
    pub u_q: SVector<T, N>,
    /// `∂u_q/∂u_b`: how the joint command answers a change of the platform's body velocity
    /// (the next step's guess uses it); zero with the `Sampled` discretisation.
    pub sensitivity: SMatrix<T, N, 3>,
    /// The 1-norm condition number of the matrix the law inverts.
    pub condition: T,
    /// `e_p`, eq. (42).
    pub e_p: S::Vector,
    /// `e_m`, eq. (23).
    pub e_m: SVector<T, N>,
    /// `h_ℓ(q)`, eq. (20).
    pub h_l: T,
}

/// An arm with `N` joints as the law sees it: its task space, its validation, a cheap
/// check of a measured configuration, and its law (30) at a point.
///
/// Implemented for every planar [`Arm`](crate::Arm) and for
/// [`SpatialArm`](crate::SpatialArm); a new kind of arm implements it with the
/// discretisation of `arm_law` (crate-internal), so it is not meant to be implemented
/// outside the crate.
pub trait Manipulator<T: Real, const N: usize>: Copy + core::fmt::Debug {
    /// The target's space: [`Planar`](crate::Planar) or [`Spatial`](crate::Spatial).
    type Space: Space<T>;

    /// Checks the arm's description.
    ///
    /// # Errors
    /// The first parameter that breaks a rule.
    fn validate_arm(&self) -> Result<(), ParamError>;

    /// A cheap check of a measured configuration before a step (a planar arm's singular
    /// configurations). A spatial arm checks its Jacobian where the law is evaluated.
    ///
    /// # Errors
    /// [`StepError::SingularArm`].
    fn check_joints(&self, q: &SVector<T, N>) -> Result<(), StepError>;

    /// The arm law (30) at `point`, over a hold `half` seconds into which the point lies
    /// (0: evaluated at the measurement, explicit). `star` is [`Space::star`] of
    /// `task.target_in_effector`.
    ///
    /// # Errors
    /// [`StepError::SingularArm`], [`StepError::SingularTaskJacobian`].
    fn arm_law(
        &self,
        task: &PrimaryTask<T, N, Self::Space>,
        limits: &JointLimits<T, N>,
        star: &<Self::Space as Space<T>>::Star,
        point: &TaskPoint<'_, T, N, Self::Space>,
        half: T,
    ) -> Result<TaskStep<T, N, Self::Space>, StepError>;

    /// The terms the arm adds to the weight `Ψ̃` of (52) at `q` beyond its joints' `σ̃ᵢ` — a
    /// spatial arm's reach ([`crate::reach`]): of where the target at `r_bd` asks the arm to
    /// be, if given; else, and with their gradients in `q` when `gradient`, of the arm as it
    /// is (gradients zero otherwise). `None` (the default): the planar arms, whose reach is a joint's
    /// ([`crate::secondary::psi_with_terms`] says how the terms enter).
    #[inline(always)]
    fn weight_terms(
        &self,
        task: &PrimaryTask<T, N, Self::Space>,
        q: &SVector<T, N>,
        r_bd: Option<&<Self::Space as Space<T>>::Relative>,
        gradient: bool,
    ) -> Option<ArmTerms<T, N>> {
        let _ = (task, q, r_bd, gradient);
        None
    }
}
