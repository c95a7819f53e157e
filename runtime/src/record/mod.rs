//! What a run records: `timeseries.csv` (one row every N steps, first and last always) and
//! the figures of `summary.json`, accumulated over *every* step.
//!
//! The same recorder serves the in-process simulation and the HIL plant process, so the two
//! write byte-identical files for the same scenario in lockstep mode. Numbers are written
//! with Rust's shortest round-trip formatting (deterministic, exact).
//!
//! - [`row`]: one recorded step; [`outcome`]: a run's outcome and its JSON files;
//! - [`summary`]: the figures of `summary.json`;
//! - [`csv`]: the columns of `timeseries.csv`;
//! - [`recorder`]: both, on the calling thread;
//! - [`writer`]: a recorder on a thread of its own, fed through a lock-free ring (the HIL
//!   plant's real-time loop never waits for the disk; the simulation formats its CSV in
//!   parallel with the run).

pub mod csv;
pub mod outcome;
pub mod recorder;
pub mod row;
pub mod summary;
pub mod writer;

pub use self::outcome::{write_summary, RunOutcome};
pub use self::recorder::{Recorder, RowSink};
pub use self::row::{CommandSource, PlantSample, Row};
pub use self::summary::{Summary, SummaryAccumulator, MANEUVER_DISTANCE, SIGN_SPEED};
pub use self::writer::{LogItem, RecordWriter};
