//! Why an exploration, or the merge of its shards, did not run or finish: every variant's
//! text is the message the command line prints, and [`ExploreError::Busy`] is the one with
//! an exit code of its own (9).

use std::path::PathBuf;

use super::lock::Busy;
use super::results::{LineError, ResultsError};
use super::space::SpaceError;
use crate::domain::plots::PlotError;
use crate::domain::scenario::ScenarioError;
use crate::study::shared::Poisoned;

/// `--shard` is not `K/N` with `1 ≤ K ≤ N`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("--shard must be K/N with 1 <= K <= N (e.g. 2/8), got `{0}`")]
pub struct BadShard(pub String);

/// Why an exploration or a merge failed.
#[derive(Debug, thiserror::Error)]
pub enum ExploreError {
    /// Another process is running in the folder (exit code 9).
    #[error(transparent)]
    Busy(#[from] Busy),
    /// `--samples 0`.
    #[error("--samples must be at least 1")]
    NoSamples,
    /// The base scenario is invalid.
    #[error("the scenario")]
    Scenario(#[source] ScenarioError),
    /// The space is invalid.
    #[error(transparent)]
    Space(#[from] SpaceError),
    /// A file or folder cannot be made, opened, locked or read: what was being done, to which.
    #[error("{doing} {}", path.display())]
    File {
        /// `creating`, `opening`, `locking` or `reading`.
        doing: &'static str,
        /// The file or folder.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A file of the output folder cannot be written: what was being done
    /// (`writing explore.json`, `appending to journal.csv`, …).
    #[error("{0}")]
    Output(&'static str, #[source] std::io::Error),
    /// A file of the output folder cannot be read or cut back (the operating system's words).
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// The identity, a shard's file or the summary cannot be put as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// The folder holds another exploration.
    #[error(
        "{} holds another exploration (different scenario, space, samples, seed or shard); choose another \
         --out, or remove that folder to start afresh",
        folder.display()
    )]
    Another {
        /// The folder.
        folder: PathBuf,
    },
    /// `results.csv` of the folder was not written by a finished run.
    #[error("results.csv ends in a cut line: it was not written by a finished run; not used")]
    CutResults,
    /// A results file cannot be used.
    #[error(transparent)]
    Results(#[from] ResultsError),
    /// A line to be written into `results.csv` is corrupt.
    #[error(transparent)]
    Line(#[from] LineError),
    /// A file's sample is not one of this run's.
    #[error("{what}: sample {sample} is not one of this run's (samples {samples}, shard {index}/{count})")]
    NotThisRuns {
        /// The file.
        what: String,
        /// The sample.
        sample: u64,
        /// The exploration's samples.
        samples: u64,
        /// The shard's `K`.
        index: u64,
        /// The shard's `N`.
        count: u64,
    },
    /// A sample appears twice with different lines.
    #[error("{what}: sample {sample} appears twice with different results; not used")]
    Twice {
        /// The file.
        what: String,
        /// The sample.
        sample: u64,
    },
    /// The figures cannot be drawn or written.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// A run panicked while holding the journal or the finished lines.
    #[error(transparent)]
    Poisoned(#[from] Poisoned),
    /// `explore merge` without folders.
    #[error("explore merge needs the shards' folders")]
    NoShards,
    /// A folder has no `explore.json`.
    #[error(
        "{}: no explore.json: not an exploration's folder, or its shard has not started (run its command)",
        dir.display()
    )]
    NotAnExploration {
        /// The folder.
        dir: PathBuf,
    },
    /// A shard is still running.
    #[error(
        "{}: this shard is still running (a process holds the lock on its explore.json); merge once it has ended",
        dir.display()
    )]
    Running {
        /// The shard's folder.
        dir: PathBuf,
    },
    /// A folder's `explore.json` is not an exploration's.
    #[error("{} is not an exploration's explore.json", path.display())]
    Manifest {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        #[source]
        source: serde_json::Error,
    },
    /// A column of the manifest is not a knob.
    #[error("{}: unknown column `{column}`", path.display())]
    UnknownColumn {
        /// The manifest.
        path: PathBuf,
        /// The column.
        column: String,
    },
    /// A shard is of another exploration than the first folder's.
    #[error("{} is a shard of another exploration than {} (explore.json differs)", dir.display(), first.display())]
    OtherExploration {
        /// The shard's folder.
        dir: PathBuf,
        /// The first folder.
        first: PathBuf,
    },
    /// A folder has no `shard.json`.
    #[error("{}: not a shard (no shard.json)", dir.display())]
    NotAShard {
        /// The folder.
        dir: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A `shard.json` cannot be read.
    #[error("reading {}", path.display())]
    ShardFile {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        #[source]
        source: serde_json::Error,
    },
    /// A `shard.json` names no valid shard.
    #[error("{}: shard {index}/{count} is not valid", dir.display())]
    InvalidShard {
        /// The folder.
        dir: PathBuf,
        /// Its `K`.
        index: u64,
        /// Its `N`.
        count: u64,
    },
    /// The shards are of splits into different numbers of parts.
    #[error("{}: shard of a split into {count} parts, the others into {others}", dir.display())]
    Split {
        /// The folder.
        dir: PathBuf,
        /// Its `N`.
        count: u64,
        /// The others'.
        others: u64,
    },
    /// A shard is given twice.
    #[error("shard {index}/{count} given twice: {} and {}", first.display(), second.display())]
    ShardTwice {
        /// Its `K`.
        index: u64,
        /// Its `N`.
        count: u64,
        /// The first folder with it.
        first: PathBuf,
        /// The second.
        second: PathBuf,
    },
    /// A shard ended unfinished and nothing runs it.
    #[error(
        "{}: shard {index}/{count} is unfinished and no process is running it ({in_journal} of its {expected} \
         samples are in its journal.csv): run its command again to resume it, then merge",
        dir.display()
    )]
    Unfinished {
        /// The folder.
        dir: PathBuf,
        /// Its `K`.
        index: u64,
        /// Its `N`.
        count: u64,
        /// The samples its journal holds.
        in_journal: usize,
        /// Its samples.
        expected: usize,
    },
    /// A shard's `results.csv` ends in a cut line.
    #[error("{what}: ends in a cut line; not merged")]
    CutShard {
        /// The file.
        what: String,
    },
    /// A shard's `results.csv` has another number of samples than the shard.
    #[error("{what}: {found} samples, but shard {index}/{count} has {expected}")]
    SampleCount {
        /// The file.
        what: String,
        /// The samples in it.
        found: usize,
        /// Its `K`.
        index: u64,
        /// Its `N`.
        count: u64,
        /// The shard's samples.
        expected: usize,
    },
    /// Shards are missing (`K/N` each).
    #[error("shards missing: {}", .0.join(", "))]
    Missing(Vec<String>),
}
