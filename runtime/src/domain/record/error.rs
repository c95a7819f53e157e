//! Why a run's records could not be written: `timeseries.csv`, `summary.json` and
//! `scenario.json`, the recording thread, and the replay file ([`ReplayError`]) written with
//! the CSV. Every variant's text is the message the command line prints; no variant
//! allocates on the recording path but for a file's name.

use std::path::PathBuf;

use super::mcap::ReplayError;

/// Why recording a run failed.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// A folder or `timeseries.csv` cannot be created.
    #[error("creating {}", path.display())]
    Create {
        /// The folder or file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The header of `timeseries.csv` cannot be written.
    #[error("writing {}", path.display())]
    Header {
        /// The file.
        path: PathBuf,
        /// The CSV writer's error.
        #[source]
        source: csv::Error,
    },
    /// A row of `timeseries.csv` cannot be written.
    #[error("writing timeseries.csv")]
    Row(#[source] csv::Error),
    /// `timeseries.csv` cannot be flushed to the disk.
    #[error("writing timeseries.csv")]
    Flush(#[source] std::io::Error),
    /// `summary.json` or `scenario.json` cannot be written.
    #[error("writing {}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The summary or the scenario cannot be put as JSON.
    #[error(transparent)]
    Serialize(#[from] serde_json::Error),
    /// The replay file (`--mcap`) failed.
    #[error(transparent)]
    Replay(#[from] ReplayError),
    /// The recording thread cannot be started.
    #[error("starting the CSV writer thread")]
    Spawn(#[source] std::io::Error),
    /// The recording thread was already joined after it failed.
    #[error("writing timeseries.csv failed earlier")]
    FailedEarlier,
    /// The recording thread panicked.
    #[error("the CSV writer thread panicked")]
    Panicked,
    /// The recording thread ended without an error while rows were still coming.
    #[error("the CSV writer thread stopped early")]
    StoppedEarly,
}
