//! # companion-runtime
//!
//! Processes and time for the companion controller: everything that is not the law
//! (`companion-core`) or the physics (`companion-plant`). A library of typed values with a
//! thin command-line edge (the `companion` binary's `cli` module: clap, progress bars,
//! printing, exit codes); nothing in the library parses a flag or prints.
//!
//! Five layers, one folder each. A module uses modules of its own layer or of the layers
//! listed before it, never of one after it:
//!
//! 1. [`domain`]: what a run is and what it leaves behind — the controller, the scenario,
//!    the arms as data, records, plots; no process, clock or transport;
//! 2. [`sys`]: the operating system — real-time setup, signals, clocks, the machine,
//!    children, the one-process-per-role lock; the crate's only `unsafe` (plain libc calls);
//! 3. [`transport`]: the wire (the two `#[repr(C)]` messages a hardware bridge implements),
//!    the link as the loops see it, iceoryx2 and Zenoh, and `--transport`'s endpoint;
//! 4. [`run`]: the loops and processes — `companion sim`, `hil`, `plant`, `control`,
//!    `latency`;
//! 5. [`study`]: many runs — one run without files, the sampled parameters, `explore`,
//!    `tune`.
//!
//! `domain` and `sys` use nothing of each other. Tests in `companion-tests` check that no
//! module depends on another in a cycle (`module_cycles`) and that every dependency between
//! these layers points up the list (`runtime_layers`).

pub mod domain;
pub mod run;
pub mod study;
pub mod sys;
pub mod transport;
