//! Recording on the calling thread: `timeseries.csv`, the logged rows kept for the plots and,
//! with `--mcap`, the replay file ([`Log`]), and with them the summary over every step
//! ([`Recorder`]) — of either arm, the row's type saying which.

use std::fs::File;
use std::path::Path;

use companion_core::{Planar, PlatformKind};

use super::csv::CsvFile;
use super::error::RecordError;
use super::mcap::{ReplayError, ReplaySummary};
use super::replay::Replay;
use super::row::{Row, Task};
use super::summary::SummaryAccumulator;
use crate::domain::controller::JOINTS;
use crate::domain::scenario::Scenario;

/// Where a run loop hands its rows (of an arm of `N` joints, targets in `S`).
pub trait RowSink<S: Task = Planar, const N: usize = JOINTS> {
    /// Every how many steps a row is logged (written to the CSV and kept for the plots).
    fn log_every(&self) -> u64;

    /// Whether the row of step `n` is logged: `n` is a multiple of
    /// [`log_every`](Self::log_every), or the last step. The loop computes the parts of a row
    /// only a logged row needs for these.
    #[inline]
    fn logs(&self, n: u64, last: bool) -> bool {
        n % self.log_every() == 0 || last
    }

    /// Records step `n`.
    ///
    /// # Errors
    /// Writing the file failed.
    fn record(&mut self, n: u64, row: &Row<S, N>, last: bool) -> Result<(), RecordError>;

    /// Writes what is buffered to the file.
    ///
    /// # Errors
    /// Writing the file failed.
    fn flush(&mut self) -> Result<(), RecordError> {
        Ok(())
    }
}

/// `timeseries.csv`, the logged rows (one every `log_every` steps, and the last) and, if
/// asked for, the same rows as an MCAP replay.
#[derive(Debug)]
pub struct Log<S: Task = Planar, const N: usize = JOINTS> {
    csv: CsvFile<File, S>,
    log_every: u64,
    /// The logged rows (for plots).
    pub rows: Vec<Row<S, N>>,
    /// The replay file (`--mcap`). If the log is dropped without
    /// [`finish_replay`](Self::finish_replay) (an error part-way), the MCAP writer finishes
    /// the file as it is dropped: a failed run still leaves a readable file.
    replay: Option<Replay<S, N>>,
}

impl<S: Task, const N: usize> Log<S, N> {
    /// Creates `dir/timeseries.csv` (and `dir` if missing) with the columns of an arm of `N`
    /// joints on a platform of `kind`, and writes the header; room for `expected_rows` rows.
    ///
    /// # Errors
    /// The folder or file cannot be created.
    pub fn create(
        dir: &Path,
        kind: PlatformKind,
        log_every: u64,
        expected_rows: usize,
    ) -> Result<Self, RecordError> {
        std::fs::create_dir_all(dir)
            .map_err(|source| RecordError::Create { path: dir.to_path_buf(), source })?;
        let path = dir.join("timeseries.csv");
        let file = match File::create(&path) {
            Ok(f) => f,
            Err(source) => return Err(RecordError::Create { path, source }),
        };
        let csv = CsvFile::new(file, kind, N).map_err(|source| RecordError::Header { path, source })?;
        Ok(Self { csv, log_every: log_every.max(1), rows: Vec::with_capacity(expected_rows), replay: None })
    }

    /// Writes every logged row to `replay` too.
    #[must_use]
    pub fn with_replay(mut self, replay: Option<Replay<S, N>>) -> Self {
        self.replay = replay;
        self
    }

    /// Finishes the replay file, if there is one.
    ///
    /// # Errors
    /// Writing the file failed.
    pub fn finish_replay(&mut self) -> Result<Option<ReplaySummary>, ReplayError> {
        self.replay.take().map(Replay::finish).transpose()
    }
}

impl Log {
    /// The log of scenario `s` of the paper's arm in `dir` (created if missing).
    ///
    /// # Errors
    /// The folder or file cannot be created.
    pub fn for_scenario(s: &Scenario, dir: &Path) -> Result<Self, RecordError> {
        Self::create(dir, s.controller.platform, s.log_every, expected_rows(s))
    }
}

/// The rows a run of `s` logs, about: one every `log_every` steps, and the last.
pub fn expected_rows(s: &Scenario) -> usize {
    usize::try_from(s.steps() / s.log_every.max(1) + 2).unwrap_or(0)
}

impl<S: Task, const N: usize> RowSink<S, N> for Log<S, N> {
    fn log_every(&self) -> u64 {
        self.log_every
    }

    fn record(&mut self, n: u64, row: &Row<S, N>, last: bool) -> Result<(), RecordError> {
        if self.logs(n, last) {
            self.csv.write_row(row).map_err(RecordError::Row)?;
            self.rows.push(*row);
            if let Some(r) = &mut self.replay {
                r.write(row)?;
            }
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<(), RecordError> {
        self.csv.flush().map_err(RecordError::Flush)
    }
}

/// The summary of scenario `s` of the paper's arm (its name and joint limits), empty.
pub fn summary_for(s: &Scenario) -> SummaryAccumulator {
    let lim = s.controller.params::<f64>().joint_limits;
    SummaryAccumulator::new(&s.name, lim.lower.as_slice(), lim.upper.as_slice())
}

/// The log and the summary over every step.
#[derive(Debug)]
pub struct Recorder<S: Task = Planar, const N: usize = JOINTS> {
    /// `timeseries.csv` and the logged rows.
    pub log: Log<S, N>,
    /// The summary accumulator.
    pub summary: SummaryAccumulator,
}

impl Recorder {
    /// The recorder for scenario `s` of the paper's arm writing into `dir` (created if
    /// missing).
    ///
    /// # Errors
    /// The folder or file cannot be created.
    pub fn for_scenario(s: &Scenario, dir: &Path) -> Result<Self, RecordError> {
        Ok(Self { log: Log::for_scenario(s, dir)?, summary: summary_for(s) })
    }
}

impl<S: Task, const N: usize> RowSink<S, N> for Recorder<S, N> {
    fn log_every(&self) -> u64 {
        self.log.log_every
    }

    fn record(&mut self, n: u64, row: &Row<S, N>, last: bool) -> Result<(), RecordError> {
        self.summary.add(row);
        self.log.record(n, row, last)
    }

    fn flush(&mut self) -> Result<(), RecordError> {
        self.log.flush()
    }
}
