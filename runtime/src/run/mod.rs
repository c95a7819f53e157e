//! The run layer: the loops and processes of the command line's verbs.
//!
//! - [`robot`]: the simulated robot every loop drives, of either arm;
//! - [`sim`]: `companion sim`, one process, its loop (also the HIL plant's in lockstep);
//! - [`spatial`]: `companion sim --arm ur5|panda|FILE`, the spatial law of §5 on a spatial
//!   plant, through the same loop and records;
//! - [`hil`]: `companion hil`, `plant` and `control`, the two processes over a transport;
//! - [`latency`]: `companion latency`, the transports' round trips measured;
//! - `ros2` (cargo feature `ros2`): `companion ros2`, the controller as a ROS 2 node.

pub mod hil;
pub mod latency;
pub mod robot;
#[cfg(feature = "ros2")]
pub mod ros2;
pub mod sim;
pub mod spatial;
