//! # companion-plant
//!
//! The simulated robot that the companion controller drives: a wheeled platform
//! (unicycle, car-like or omnidirectional) carrying an arm, and the moving target the arm
//! must track.
//!
//! Why a crate of its own: the controller in `companion-core` needs a plant to be tested
//! against, and the reproductions of the paper's simulations, the hardware-in-the-loop
//! demo and the benchmarks all need *the same* plant, exactly known and reproducible bit
//! for bit. So this crate is the physics and nothing else — no processes, no clocks, no
//! IPC, no command line (those are the runtime's) — and it is deterministic: fixed-step
//! integration, elementary functions from the workspace's pinned `libm`, noise from a
//! seeded portable generator.
//!
//! ## What it simulates
//!
//! ```text
//! unicycle   ẋ = v cos θ,  ẏ = v sin θ,  θ̇ = ω
//! car-like   ẋ = v cos θ,  ẏ = v sin θ,  θ̇ = v ξ,  ξ̇ = v_ξ          (eq. 55)
//! omni       ṙ_b = R̄(θ) (v, v_lat, ω)                                (eq. 3)
//! arm        q̇ = u_q                      (N joints, a const generic)
//! target     ṙ_d = R̄(θ_d) u_d(t)
//! ```
//!
//! integrated by classical RK4 with the command held over each step (zero-order hold) and
//! the target velocity `u_d(t)` evaluated at the stage times. The time of step `n` is
//! `n·dt` exactly. Angles are never wrapped.
//!
//! The targets ([`Trajectory`]) are the paper's trajectories 1 and 2 (§4.3, Table 1) and
//! piecewise-constant velocities read from a TOML file (see [`trajectory`]).
//!
//! For spatial arms (§5), [`SpatialPlant`] carries a [`Chain`](companion_core::Chain) of six
//! to eight joints on the same platforms, integrated by the same step, with a target in
//! SE(3): the paper's trajectories lifted with a vertical sine, or 6-DOF body twists from a
//! TOML file of the planar file's form (see [`spatial_target`]). Its start and its state are
//! the planar plant's [`InitialConditions`] and [`PlantState`] with the target in space, and
//! both plants are driven through one interface, [`Simulated`]. (Two plant types, because the planar plant is generic over the
//! paper's closed-form planar arms (`Arm`) and integrates its target with the robot, where
//! the spatial one evaluates a chain and moves its target in SE(3).)
//!
//! On request the plant is imperfect ([`Imperfections`]): first-order actuator lag,
//! Gaussian measurement noise, a wheel-speed scale error. The default is the perfect plant
//! of the paper. [`realistic_limits`] gives velocity limits of a plausible robot for the
//! controller's saturation (not used in the paper's runs).
//!
//! Names follow the paper: `r_b` is the platform's pose, `r_d` the target's, `r_bd` the
//! target seen from the platform, `r_eb(q)` the platform seen from the end effector.
//! Units: metres, radians, seconds.
//!
//! ## Example
//!
//! ```
//! use companion_core::{Command, PlatformKind, Rpr};
//! use companion_plant::{paper_initial, PaperTrajectory, Plant, PlantConfig, Trajectory};
//!
//! let mut plant = Plant::new(
//!     PlantConfig::new(PlatformKind::Unicycle),
//!     Rpr::paper(),
//!     paper_initial(PaperTrajectory::One),
//!     Trajectory::Paper1,
//! )?;
//! let meas = plant.measure(); // what the controller sees
//! assert_eq!(meas.target.x, 2.6);
//! let mut command = Command::zero();
//! command.platform.v = 0.5; // m/s
//! for _ in 0..1000 {
//!     plant.advance(&command, 1e-3);
//! }
//! assert_eq!(plant.step_index(), 1000);
//! assert_eq!(plant.time(), 1.0);
//! assert!((plant.truth().base.x - 0.5).abs() < 1e-12);
//! # Ok::<(), companion_plant::PlantError>(())
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod dynamics;
mod error;
mod imperfections;
mod initial;
mod limits;
mod plant;
mod spatial;
pub mod spatial_target;
pub mod trajectory;

#[cfg(test)]
mod tests;

pub use error::{AdvanceError, PlantError, Rule};
pub use imperfections::{Imperfections, Noise, MIN_ACTUATOR_LAG};
pub use initial::InitialConditions;
pub use limits::{
    realistic_limits, realistic_steering_limit, steering_limit, REALISTIC_MAX_STEERING_ANGLE,
    REALISTIC_WHEELBASE,
};
pub use plant::{Plant, PlantConfig, PlantState, Simulated};
pub use spatial::{vertical_reach, SpatialPlant};
pub use spatial_target::{LiftedTrajectory, SpatialTarget, LIFT_AMPLITUDE, LIFT_PERIOD};
pub use trajectory::{
    paper_initial, FileSpace, Location, PaperTrajectory, PiecewiseTrajectory, Segment, Trajectory,
    TrajectoryError, PAPER_INITIAL_JOINTS,
};
