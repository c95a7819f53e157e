//! The outcome of a run and its `summary.json` and `scenario.json`.

use std::path::Path;

use super::error::RecordError;
use super::row::Row;
use super::summary::Summary;
use crate::domain::scenario::Scenario;

/// The outcome of one run of the paper's arm: its scenario, summary and logged rows (a
/// spatial arm's: `run::spatial::SpatialOutcome`, whose scenario adds the arm and target).
#[derive(Debug)]
pub struct RunOutcome {
    /// The scenario.
    pub scenario: Scenario,
    /// Its summary.
    pub summary: Summary,
    /// The logged rows.
    pub rows: Vec<Row>,
}

/// Writes `summary.json` and `scenario.json` into `dir`.
///
/// # Errors
/// Writing failed.
pub fn write_summary(dir: &Path, s: &Scenario, summary: &Summary) -> Result<(), RecordError> {
    let path = dir.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(summary)? + "\n")
        .map_err(|source| RecordError::Json { path, source })?;
    let path = dir.join("scenario.json");
    std::fs::write(&path, serde_json::to_string_pretty(s)? + "\n")
        .map_err(|source| RecordError::Json { path, source })?;
    Ok(())
}
