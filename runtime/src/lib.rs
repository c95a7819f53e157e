//! # companion-runtime
//!
//! Processes and time for the companion controller: everything that is not the law
//! (`companion-core`) or the physics (`companion-plant`). A library of typed values with a
//! thin command-line edge (the `companion` binary's `cli` module: clap, progress bars,
//! printing, exit codes); nothing in the library parses a flag or prints.
//!
//! Layers, each depending only on the ones above it:
//!
//! - domain: [`controller`] (the one module that touches the core's controller),
//!   [`platform_config`] (the `[unicycle]` and `[car]` tables, a leaf),
//!   [`scenario`] (a run's description, built in one expression or from a TOML file),
//!   [`plant_setup`], [`record`] (`timeseries.csv`, `summary.json`), [`plots`],
//!   [`histogram`], [`observe`] (progress and messages, for the CLI to show);
//! - system: [`rt`] (real-time setup), [`signals`], [`clock`] (time behind a trait),
//!   [`machine`], [`process`] (children and signals), [`lock`] (one process per role and demo
//!   name) — `rt`, `process` and `lock` hold the crate's only `unsafe` (plain libc calls);
//! - transport: [`wire`] (the two `#[repr(C)]` messages: the interface a hardware bridge
//!   implements), [`link`] (the transport as the loops see it), [`ipc`] (iceoryx2), `zenoh_link` (Zenoh over
//!   TCP, cargo feature `zenoh`), [`transport`] (`--transport`: the endpoint of either);
//! - loops and processes: [`sim`] (`companion sim`), [`spatial`] (`companion sim --arm
//!   ur5|panda|FILE`: the spatial law of §5 on a spatial plant; arms as data in [`arm`], a
//!   domain module), [`hil`] (`companion hil`, `plant`,
//!   `control`), [`latency`] (`companion latency`);
//! - many runs: [`trial`] (one run without files), [`knobs`] (the parameters that are
//!   sampled and searched), [`explore`] (`companion explore`: Monte Carlo over starts and
//!   parameters), [`tune`] (`companion tune`: a search for parameters).
//!
//! A test in `companion-tests` (`module_cycles`) checks that no module depends on another in
//! a cycle, in every crate of the workspace.

pub mod arm;
#[cfg(feature = "zenoh")]
pub mod certs;
pub mod clock;
pub mod controller;
pub mod explore;
pub mod hil;
pub mod histogram;
pub mod ipc;
pub mod knobs;
pub mod latency;
pub mod link;
pub mod lock;
pub mod machine;
pub mod observe;
pub mod plant_setup;
pub mod platform_config;
pub mod plots;
pub mod process;
pub mod record;
pub mod rt;
pub mod scenario;
pub mod signals;
pub mod sim;
pub mod spatial;
pub mod transport;
pub mod trial;
pub mod tune;
pub mod wire;
#[cfg(feature = "zenoh")]
pub mod zenoh_link;
#[cfg(feature = "zenoh")]
pub mod zenoh_log;
