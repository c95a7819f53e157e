//! # companion-core
//!
//! The feedback law of *"A Framework for the Control of Nonholonomic Mobile
//! Manipulators"* as a `no_std`, allocation-free library: a manipulator arm on a wheeled
//! platform — omnidirectional, unicycle-like or car-like — tracks a moving target with its
//! end effector while its joints stay inside their limits, and the platform follows
//! through a *companion omnidirectional frame* built from a transverse function.
//!
//! Why a crate of its own: the law must run unchanged on a microcontroller (Cortex-M4F,
//! f32) and on a host (f64), with the same bits from the same inputs. So it has no heap, no
//! `std`, no panics reachable from its API, fixed-size matrices (`nalgebra`), and its
//! elementary functions from code it controls: the pinned `libm` for f64, f32-native
//! functions of its own for f32 (see [`Real`]).
//!
//! ## Map of the paper
//!
//! | paper | here |
//! |---|---|
//! | SE(2), eqs. (1)–(10) | [`se2`] |
//! | transverse functions, companion frame, (11)–(16), (55)–(60) | [`platform`] |
//! | arm kinematics `r_eb(q)`, (45) | [`arm`] |
//! | primary task `e_p`, `h_ℓ`, `h_r`, `e_m`, (20)–(26), (42), (48) | [`primary`] |
//! | secondary cost, weight `Ψ`, (27)–(29), (49)–(54) | [`secondary`] |
//! | platform law (37) with Choices 1–3, arm law (30), saturation | [`ControlLaw::step`] |
//! | (beyond the paper) acceleration limits, a second common factor | [`acceleration`] |
//! | §4.3 parameters | [`Params::paper`] |
//!
//! ## Example
//!
//! ```
//! use companion_core::{Controller, Measurement, PaperRun, Params, Pose, Rpr, Unicycle};
//! use nalgebra::{Vector3, SVector};
//!
//! let mut ctrl = Controller::new(Params::<f64, 3>::paper(PaperRun::A), Unicycle::paper(), Rpr::paper())?;
//! let meas = Measurement {
//!     t: 0.0,
//!     base: Pose::new(0.0, 0.0, 0.0),
//!     steering: 0.0,
//!     joints: SVector::<f64, 3>::new(0.0, 0.35, 0.0),
//!     target: Pose::new(2.6, 1.0, 0.0),
//!     target_velocity: Vector3::new(0.0, -0.157, 0.0),
//! };
//! let out = ctrl.step(&meas, 1e-3).expect("a valid measurement");
//! assert!(out.command.is_finite());
//! // A joint at its limit is rejected with the safe command.
//! let bad = Measurement { joints: SVector::<f64, 3>::new(0.0, 0.0, 0.0), ..meas };
//! let rejected = ctrl.step(&bad, 1e-3).unwrap_err();
//! assert_eq!(rejected.command, companion_core::Command::zero());
//! # Ok::<(), companion_core::ParamError>(())
//! ```
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![warn(clippy::std_instead_of_core, clippy::alloc_instead_of_core)]
#![cfg_attr(not(test), warn(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

#[cfg(test)]
extern crate std;

pub mod acceleration;
pub mod arm;
mod arm_law;
pub mod chain;
pub mod command;
pub mod error;
mod fastmath;
mod hold;
pub mod kinematics;
pub mod law;
pub mod lie;
mod linalg;
pub mod measurement;
pub mod params;
pub mod platform;
mod platform_law;
pub mod primary;
pub mod reach;
pub mod scalar;
pub mod se2;
pub mod se3;
pub mod secondary;
pub mod so3;
pub mod space;
pub mod spatial;
pub mod state;
pub mod task;

pub use acceleration::AccelerationLimits;
pub use arm::{Arm, ArmKinematics, PlanarArm, Rpr};
pub use chain::{Chain, DhConvention, DhJoint, FrameData, Joint, JointData, JointKind};
pub use command::{Command, Diagnostics, Output, Rejected};
pub use error::{Bound, Field, ParamError, Rule, StepError};
pub use kinematics::SpatialKinematics;
pub use law::{ControlLaw, Controller};
pub use lie::LieGroup;
pub use measurement::Measurement;
pub use params::{
    Discretisation, HeadingFilter, JointLimits, PaperRun, Params, Precompensation, PrimaryTask, RestFilter,
    SecondaryTask, TargetMotion, Warning, Weight, WeightMargins,
};
pub use platform::{
    CarLike, CompanionFrame, Omnidirectional, Platform, PlatformCommand, PlatformKind, Unicycle,
    VelocityLimits,
};
pub use reach::{Reach, ReachBand, ReachJoints};
pub use scalar::{wrap_angle, Real};
pub use se2::{Pose, PoseSc};
pub use se3::Pose3;
pub use secondary::{ArmTerms, TermRule};
pub use space::{Planar, Space, Spatial};
pub use spatial::{SpatialArm, SpatialPoint, SpatialTerms, DAMPING_BELOW, DAMPING_DEPTH, SINGULAR_BELOW};
pub use state::{Sent, State, HISTORY};
pub use task::Manipulator;

pub use nalgebra;
