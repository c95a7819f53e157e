//! # companion-runtime
//!
//! Processes and time for the companion controller: everything that is not the law
//! (`companion-core`) or the physics (`companion-plant`).
//!
//! - [`scenario`]: a run's description, from flags and a TOML file;
//! - [`control`]: one controller of any platform × scalar behind one type;
//! - [`sim`]: the in-process simulation (`companion sim`);
//! - [`record`]: `timeseries.csv` and `summary.json`;
//! - [`plots`]: SVG figures and the index page;
//! - [`hil`]: the hardware-in-the-loop demo — plant and controller as two processes over
//!   iceoryx2 shared memory, with deadlines (`companion hil`, `plant`, `control`);
//! - [`latency`]: the worst-case latency benchmark (`companion latency`);
//! - [`wire`]: the two `#[repr(C)]` messages of the HIL loop (the interface a hardware bridge
//!   implements); [`ipc`]: their iceoryx2 services; [`rt`]: real-time setup (the crate's only
//!   `unsafe`); [`clock`]: time behind a trait.

pub mod clock;
pub mod control;
pub mod hil;
pub mod ipc;
pub mod latency;
pub mod plant_setup;
pub mod plots;
pub mod record;
pub mod rt;
pub mod scenario;
pub mod sim;
pub mod wire;
