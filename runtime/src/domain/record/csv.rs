//! The columns of `timeseries.csv`, written by the `csv` crate (quoting where a field needs
//! it) with numbers in Rust's shortest round-trip formatting.
//!
//! Rows are not written through `csv`'s serde support: it formats floats with `ryu`
//! (`1.0`, `1e-7`), which would change every file's bytes from Rust's `Display` (`1`,
//! `0.0000001`), and it formats through an allocated `String` per field.

use std::fmt::Write as _;
use std::io::Write;

use companion_core::PlatformKind;

use super::row::Row;

/// The CSV header's columns for a platform.
pub fn columns(kind: PlatformKind) -> Vec<&'static str> {
    let mut h = vec![
        "t",
        "x_b",
        "y_b",
        "theta_b",
        "q1",
        "q2",
        "q3",
        "x_e",
        "y_e",
        "theta_e",
        "x_d",
        "y_d",
        "theta_d",
        "ep_norm",
        "h_s",
        "psi",
        "v",
        "omega",
        "alpha_dot",
        "sat",
        "joint_scale",
    ];
    match kind {
        PlatformKind::Car => h.extend(["alpha_dot2", "xi", "v_xi"]),
        PlatformKind::Omni => h.push("v_lat"),
        PlatformKind::Unicycle => {}
    }
    h.push("status");
    h
}

/// `timeseries.csv` being written: the `csv` writer and a reusable field buffer.
#[derive(Debug)]
pub struct CsvFile<W: Write> {
    out: csv::Writer<W>,
    kind: PlatformKind,
    field: String,
}

impl<W: Write> CsvFile<W> {
    /// A CSV of `kind`'s columns into `w`; writes the header.
    ///
    /// # Errors
    /// Writing the header failed.
    pub fn new(w: W, kind: PlatformKind) -> csv::Result<Self> {
        let mut out = csv::WriterBuilder::new().buffer_capacity(1 << 16).from_writer(w);
        out.write_record(columns(kind))?;
        Ok(Self { out, kind, field: String::with_capacity(64) })
    }

    /// Writes one row.
    ///
    /// # Errors
    /// Writing failed.
    pub fn write_row(&mut self, row: &Row) -> csv::Result<()> {
        let p = &row.plant;
        let r = &row.report;
        let c = &r.command.platform;
        let common = [
            p.t,
            p.base.x,
            p.base.y,
            p.base.theta,
            p.joints[0],
            p.joints[1],
            p.joints[2],
            p.end_effector.x,
            p.end_effector.y,
            p.end_effector.theta,
            p.target.x,
            p.target.y,
            p.target.theta,
            p.ep_norm,
            r.h_s,
            r.psi,
            c.v,
            c.omega,
            r.alpha_rate[0],
            r.saturation,
            r.joint_scale,
        ];
        let extra: &[f64] = match self.kind {
            PlatformKind::Car => &[r.alpha_rate[1], p.steering, c.v_xi],
            PlatformKind::Omni => &[c.v_lat],
            PlatformKind::Unicycle => &[],
        };
        for v in common.iter().chain(extra) {
            self.field.clear();
            let _ = write!(self.field, "{v}");
            self.out.write_field(&self.field)?;
        }
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
