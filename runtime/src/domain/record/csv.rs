//! `timeseries.csv`, written by the `csv` crate (quoting where a field needs it) with numbers in
//! Rust's shortest round-trip formatting, for either arm: the columns are the task space's
//! ([`Task::columns`]).
//!
//! Rows are not written through `csv`'s serde support: it formats floats with `ryu`
//! (`1.0`, `1e-7`), which would change every file's bytes from Rust's `Display` (`1`,
//! `0.0000001`), and it formats through an allocated `String` per field.

use std::fmt::Write as _;
use std::io::Write;
use std::marker::PhantomData;

use companion_core::{Planar, PlatformKind};

use super::row::{Row, Task};

/// `timeseries.csv` being written: the `csv` writer and a reusable field buffer.
#[derive(Debug)]
pub struct CsvFile<W: Write, S: Task = Planar> {
    out: csv::Writer<W>,
    kind: PlatformKind,
    field: String,
    space: PhantomData<S>,
}

impl<W: Write, S: Task> CsvFile<W, S> {
    /// A CSV of the columns of `kind` with `joints` joints into `w`; writes the header.
    ///
    /// # Errors
    /// Writing the header failed.
    pub fn new(w: W, kind: PlatformKind, joints: usize) -> csv::Result<Self> {
        let mut out = csv::WriterBuilder::new().buffer_capacity(1 << 16).from_writer(w);
        out.write_record(S::columns(kind, joints))?;
        Ok(Self { out, kind, field: String::with_capacity(64), space: PhantomData })
    }

    /// Writes one row.
    ///
    /// # Errors
    /// Writing failed.
    pub fn write_row<const N: usize>(&mut self, row: &Row<S, N>) -> csv::Result<()> {
        let (out, field) = (&mut self.out, &mut self.field);
        let mut failed = Ok(());
        S::numbers(row, self.kind, &mut |v| {
            if failed.is_ok() {
                field.clear();
                let _ = write!(field, "{v}");
                failed = out.write_field(&*field);
            }
        });
        failed?;
        self.field.clear();
        row.write_status(&mut self.field);
        self.out.write_field(&self.field)?;
        self.out.write_record(None::<&[u8]>)
    }

    /// Flushes the buffer to the underlying writer.
    ///
    /// # Errors
    /// Writing failed.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}
