//! What the C tests share.

use companion_runtime::domain::record::{RecordError, Row, RowSink};

/// Rows are not needed: the tests keep the controllers' answers themselves.
pub struct NoRows;

impl RowSink for NoRows {
    fn log_every(&self) -> u64 {
        u64::MAX
    }
    fn record(&mut self, _n: u64, _row: &Row, _last: bool) -> Result<(), RecordError> {
        Ok(())
    }
}
