//! The domain layer: what a run is and what it leaves behind. Nothing here starts a process,
//! reads a clock or touches a transport.
//!
//! - [`controller`]: the one module that touches the core's controller (planar and
//!   spatial), and the names of platforms and runs;
//! - [`platform_config`]: the `[unicycle]` and `[car]` tables (a leaf);
//! - [`arm`]: spatial arms as data (presets and arm files);
//! - [`scenario`]: a run's description, built in one expression or from a TOML file;
//! - [`plant_setup`]: the simulated plant a scenario asks for;
//! - [`record`]: `timeseries.csv`, `summary.json`, MCAP, digests, verdicts, the spatial
//!   records;
//! - [`plots`], [`histogram`] (latency histograms), [`spread`] (a figure over repeated runs),
//!   [`observe`] (progress and messages, for the command line to show).

pub mod arm;
pub mod controller;
pub mod histogram;
pub mod observe;
pub mod plant_setup;
pub mod platform_config;
pub mod plots;
pub mod record;
pub mod scenario;
pub mod spread;
