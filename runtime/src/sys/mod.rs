//! The system layer: what the operating system gives a real-time process. It knows nothing
//! of the domain.
//!
//! - [`rt`]: real-time setup (scheduling class, memory locking, CPU affinity) and the
//!   monotonic clock's raw reading;
//! - [`signals`]: SIGINT/SIGTERM as a flag the loops poll;
//! - [`clock`]: time behind a trait, so the loops run on a fake clock in tests;
//! - [`machine`]: what the machine is (CPUs, load, kernel) for the reports;
//! - [`process`]: children and signals to them;
//! - [`lock`]: one process per role and demo name;
//! - [`threads`]: what another process's threads are doing (a hung peer's record).
//!
//! `rt`, `process` and `lock` hold the crate's only `unsafe` (plain libc calls).

pub mod clock;
pub mod lock;
pub mod machine;
pub mod process;
pub mod rt;
pub mod signals;
pub mod threads;
