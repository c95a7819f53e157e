//! The study layer: many runs.
//!
//! - [`trial`]: one run without files, for the studies;
//! - [`shared`]: the state parallel runs share, and [`shared::Poisoned`];
//! - [`knobs`]: the parameters that are sampled and searched;
//! - [`starts`]: perturbed starts, and how many of them a setting settles from;
//! - [`explore`]: `companion explore`, Monte Carlo over starts and parameters (sharded);
//! - [`tune`]: `companion tune`, a search for parameters.

pub mod explore;
pub mod knobs;
pub mod shared;
pub mod starts;
pub mod trial;
pub mod tune;
