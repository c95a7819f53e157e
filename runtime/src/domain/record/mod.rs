//! What a run records: `timeseries.csv` (one row every N steps, first and last always) and
//! the figures of `summary.json`, accumulated over *every* step.
//!
//! The same recorder serves the in-process simulation and the HIL plant process, and either
//! arm, so the two write byte-identical files for the same scenario in lockstep mode. Numbers are written
//! with Rust's shortest round-trip formatting (deterministic, exact).
//!
//! - [`error`]: why a run's records could not be written;
//! - [`row`]: one recorded step, of the paper's planar arm or a spatial one (its [`Task`]
//!   space); [`outcome`]: a run's outcome and its JSON files;
//! - [`output`]: the output folder, taken away again if the run never started;
//! - [`summary`]: the figures of `summary.json`; [`digest`]: the trajectory's fingerprint;
//! - [`csv`]: the columns of `timeseries.csv`;
//! - [`verdict`]: the law's rejections by reason, and whether a run did what a run must;
//! - [`recorder`]: both, on the calling thread;
//! - [`mcap`]: a run as an MCAP file for Foxglove, from arm-agnostic frames; [`replay`]: a
//!   run's rows as such frames, the arm drawn from its chain (`--mcap FILE`, written by the
//!   recording thread with the CSV);
//! - [`writer`]: a recorder on a thread of its own, fed through a lock-free ring (the HIL
//!   plant's real-time loop never waits for the disk; the simulation formats its CSV in
//!   parallel with the run).

pub mod csv;
pub mod digest;
pub mod error;
pub mod mcap;
pub mod outcome;
pub mod output;
pub mod recorder;
pub mod replay;
pub mod row;
pub mod summary;
pub mod verdict;
pub mod writer;

pub use self::digest::TrajectoryDigest;
pub use self::error::RecordError;
pub use self::mcap::{McapRecorder, ReplayError, ReplayFrame, ReplayLayout, ReplaySummary};
pub use self::outcome::{write_summary, RunOutcome};
pub use self::output::{OutputDir, OutputError};
pub use self::recorder::{Recorder, RowSink};
pub use self::replay::Replay;
pub use self::row::{CommandSource, PlantSample, Row, Task};
pub use self::summary::{
    ArmFigures, CommandSources, LimitsActed, Summary, SummaryAccumulator, LIMITS_ACTED_BEYOND,
    MANEUVER_DISTANCE, SIGN_SPEED,
};
pub use self::verdict::{Acceptance, Failure, Rejections};
pub use self::writer::{LogItem, RecordWriter};
