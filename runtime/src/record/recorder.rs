//! Recording on the calling thread: the summary over every step, the logged rows kept for
//! the plots, and `timeseries.csv`.

use std::fs::File;
use std::path::Path;

use anyhow::{Context, Result};
use companion_core::PlatformKind;

use super::csv::CsvFile;
use super::row::Row;
use super::summary::SummaryAccumulator;
use crate::scenario::Scenario;

/// Where a run loop hands its rows.
pub trait RowSink {
    /// Whether the row of step `n` is logged (written to the CSV and kept for the plots), so
    /// that the loop computes the parts of it only a logged row needs.
    fn logs(&self, n: u64, last: bool) -> bool;

    /// Records step `n`.
    ///
    /// # Errors
    /// Writing the file failed.
    fn record(&mut self, n: u64, row: &Row, last: bool) -> Result<()>;
}

/// Writes `timeseries.csv`, keeps the logged rows for plots, and accumulates the summary.
#[derive(Debug)]
pub struct Recorder {
    csv: CsvFile<File>,
    log_every: u64,
    /// The logged rows (for plots).
    pub rows: Vec<Row>,
    /// The summary accumulator.
    pub summary: SummaryAccumulator,
}

impl Recorder {
    /// Creates `dir/timeseries.csv` and writes the header.
    ///
    /// # Errors
    /// The file cannot be created.
    pub fn create(
        dir: &Path,
        kind: PlatformKind,
        log_every: u64,
        summary: SummaryAccumulator,
        expected_rows: usize,
    ) -> Result<Self> {
        let path = dir.join("timeseries.csv");
        let file = File::create(&path).with_context(|| format!("creating {}", path.display()))?;
        let csv = CsvFile::new(file, kind).with_context(|| format!("writing {}", path.display()))?;
        Ok(Self { csv, log_every, rows: Vec::with_capacity(expected_rows), summary })
    }

    /// The recorder for scenario `s` writing into `dir` (created if missing).
    ///
    /// # Errors
    /// The folder or file cannot be created.
    pub fn for_scenario(s: &Scenario, dir: &Path) -> Result<Self> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let lim = s.controller.params::<f64>().joint_limits;
        let acc = SummaryAccumulator::new(
            &s.name,
            [lim.lower[0], lim.lower[1], lim.lower[2]],
            [lim.upper[0], lim.upper[1], lim.upper[2]],
        );
        #[allow(clippy::cast_possible_truncation)]
        let rows = (s.steps() / s.log_every) as usize + 2;
        Self::create(dir, s.controller.platform, s.log_every, acc, rows)
    }

    /// Every how many steps a row is logged.
    pub fn log_every(&self) -> u64 {
        self.log_every
    }

    /// Flushes `timeseries.csv` to the file.
    ///
    /// # Errors
    /// Writing the file failed.
    pub fn flush(&mut self) -> Result<()> {
        self.csv.flush().context("writing timeseries.csv")
    }
}

impl RowSink for Recorder {
    /// `n` is a multiple of `log_every`, or the last step.
    #[inline]
    fn logs(&self, n: u64, last: bool) -> bool {
        n % self.log_every == 0 || last
    }

    fn record(&mut self, n: u64, row: &Row, last: bool) -> Result<()> {
        self.summary.add(row);
        if self.logs(n, last) {
            self.csv.write_row(row).context("writing timeseries.csv")?;
            self.rows.push(*row);
        }
        Ok(())
    }
}
