//! The run layer: the loops and processes of the command line's verbs.
//!
//! - [`sim`]: `companion sim`, the planar arm in one process;
//! - [`spatial`]: `companion sim --arm ur5|panda|FILE`, the spatial law of §5 on a spatial
//!   plant;
//! - [`hil`]: `companion hil`, `plant` and `control`, the two processes over a transport;
//! - [`latency`]: `companion latency`, the transports' round trips measured.

pub mod hil;
pub mod latency;
pub mod sim;
pub mod spatial;
