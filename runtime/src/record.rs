//! What a run records: `timeseries.csv` (one row every N steps, first and last always) and
//! the figures of `summary.json`, accumulated over *every* step.
//!
//! The same recorder serves the in-process simulation and the HIL plant process, so the two
//! write byte-identical files for the same scenario in lockstep mode. Numbers are written
//! with Rust's shortest round-trip formatting (deterministic, exact).

use std::fmt::Write as _;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::sync::mpsc::SyncSender;
use std::thread::JoinHandle;

use anyhow::{bail, Context, Result};
use companion_core::nalgebra::SVector;
use companion_core::{PlatformKind, Pose};
use serde::Serialize;

use crate::control::{StepReport, JOINTS};

/// The plant's true state at one step, as recorded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantSample {
    /// Time (s).
    pub t: f64,
    /// Platform pose.
    pub base: Pose<f64>,
    /// Car steering `ξ` (1/m); 0 for other platforms.
    pub steering: f64,
    /// Joints.
    pub joints: SVector<f64, JOINTS>,
    /// End-effector pose (world).
    pub end_effector: Pose<f64>,
    /// Target pose (world).
    pub target: Pose<f64>,
}

/// How the command of a step was obtained (HIL adds hold/stop).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommandSource {
    /// The controller's command for this step.
    Fresh,
    /// The previous command, held because this step's command missed its deadline.
    Held,
    /// The safe zero command: commands missed too many deadlines.
    Stopped,
}

/// One logged row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    /// The plant's state.
    pub plant: PlantSample,
    /// The controller's report.
    pub report: StepReport,
    /// Where the command came from.
    pub source: CommandSource,
}

impl Row {
    /// The status column: `ok`, the rejection reason, `held` or `stopped`.
    pub fn status(&self) -> String {
        match (self.source, self.report.error) {
            (CommandSource::Held, _) => "held".into(),
            (CommandSource::Stopped, _) => "stopped".into(),
            (CommandSource::Fresh, None) => "ok".into(),
            (CommandSource::Fresh, Some(e)) => format!("rejected:{e:?}").replace([' ', ','], ""),
        }
    }
}

/// The run's figures (`summary.json`). "After 20 s" means `t ≥ 20 s`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Summary {
    /// The scenario's name.
    pub scenario: String,
    /// `‖e_p‖` at the last step.
    pub final_ep_norm: f64,
    /// The largest `‖e_p‖` for `t ≥ 20 s`.
    pub max_ep_norm_after_20s: f64,
    /// The fraction of steps with `t ≥ 20 s` where `‖e_p‖ < 1e−3`.
    #[serde(rename = "fraction_ep_below_1e-3_after_20s")]
    pub fraction_ep_below_1e_3_after_20s: f64,
    /// Per joint, the smallest distance to the nearer limit over the run (rad or m).
    pub min_joint_margin: [f64; JOINTS],
    /// The platform's path length (m).
    pub path_length: f64,
    /// The platform's path length for `t ≥ 20 s` (m).
    pub path_length_after_20s: f64,
    /// Sign changes of the commanded forward speed `v` (maneuvers), counting only speeds
    /// above 1 mm/s so that numerical dithering around zero does not count.
    pub v_sign_changes: u64,
    /// Maneuvers: reversals of the platform's driving direction, counted as turning points of
    /// the signed odometer `∫ v dt` with 1 cm of hysteresis (chattering of `v` around zero
    /// does not count).
    pub maneuvers: u64,
    /// The last time `‖e_p‖ ≥ 1e−3` (s): after it, the target is tracked to 1 mm. 0 if never.
    pub ep_settling_time_s: f64,
    /// The largest `|v|` commanded (m/s).
    pub max_abs_v: f64,
    /// The largest `|ω|` commanded (rad/s).
    pub max_abs_omega: f64,
    /// The root mean square of the commanded `v` over the run (m/s): the typical platform
    /// speed, robust where the maximum is one spike.
    pub rms_v: f64,
    /// The root mean square of the commanded `ω` over the run (rad/s).
    pub rms_omega: f64,
    /// The largest `|α̇ᵢ|` commanded (rad/s).
    pub max_abs_alpha_rate: f64,
    /// The largest saturation factor.
    pub max_saturation: f64,
    /// `h_s` at the first step.
    pub initial_h_s: f64,
    /// `h_s` at the last step.
    pub final_h_s: f64,
    /// Controller steps.
    pub steps: u64,
    /// Steps the controller rejected (safe command sent).
    pub rejected_steps: u64,
    /// Wall-clock time of the run (s).
    pub wall_time_s: f64,
}

/// The speed below which `v` has no sign for counting sign changes (m/s).
pub const SIGN_SPEED: f64 = 1e-3;

/// The distance a platform must cover in one direction for a reversal to count as a
/// maneuver (m).
pub const MANEUVER_DISTANCE: f64 = 0.01;

/// Accumulates the summary over every step.
#[derive(Clone, Debug)]
pub struct SummaryAccumulator {
    s: Summary,
    after20: u64,
    below: u64,
    last_sign: i8,
    last_pos: Option<(f64, f64)>,
    /// The signed odometer, the previous command's `v`, the current direction of travel
    /// (0 before the first leg) and the odometer's extremum in that direction.
    odometer: f64,
    sum_v2: f64,
    sum_w2: f64,
    prev_v: f64,
    direction: i8,
    extremum: f64,
    lower: [f64; JOINTS],
    upper: [f64; JOINTS],
}

impl SummaryAccumulator {
    /// A new accumulator for joints with limits `lower`, `upper`.
    pub fn new(name: &str, lower: [f64; JOINTS], upper: [f64; JOINTS]) -> Self {
        let s = Summary {
            scenario: name.to_string(),
            min_joint_margin: [f64::INFINITY; JOINTS],
            max_saturation: 1.0,
            ..Summary::default()
        };
        Self {
            s,
            after20: 0,
            below: 0,
            last_sign: 0,
            last_pos: None,
            odometer: 0.0,
            sum_v2: 0.0,
            sum_w2: 0.0,
            prev_v: 0.0,
            direction: 0,
            extremum: 0.0,
            lower,
            upper,
        }
    }

    /// Adds one step.
    ///
    /// Reads only the row's time, platform pose and joints and its report: the in-process
    /// loop ([`run_loop`](crate::sim::run_loop)) skips the end effector's pose on steps
    /// that are not logged.
    pub fn add(&mut self, row: &Row) {
        let s = &mut self.s;
        let p = &row.plant;
        let r = &row.report;
        s.steps += 1;
        if r.error.is_some() {
            s.rejected_steps += 1;
        }
        let mut moved = 0.0;
        if let Some((x, y)) = self.last_pos {
            moved = (p.base.x - x).hypot(p.base.y - y);
            s.path_length += moved;
            if p.t >= 20.0 {
                s.path_length_after_20s += moved;
            }
        }
        self.last_pos = Some((p.base.x, p.base.y));
        if s.steps == 1 {
            s.initial_h_s = r.h_s;
        }
        if r.ep_norm.is_finite() {
            s.final_ep_norm = r.ep_norm;
            if r.ep_norm >= 1e-3 {
                s.ep_settling_time_s = p.t;
            }
            if p.t >= 20.0 {
                self.after20 += 1;
                s.max_ep_norm_after_20s = s.max_ep_norm_after_20s.max(r.ep_norm);
                if r.ep_norm < 1e-3 {
                    self.below += 1;
                }
            }
        }
        if r.h_s.is_finite() {
            s.final_h_s = r.h_s;
        }
        for i in 0..JOINTS {
            let m = (p.joints[i] - self.lower[i]).min(self.upper[i] - p.joints[i]);
            s.min_joint_margin[i] = s.min_joint_margin[i].min(m);
        }
        let v = r.command.platform.v;
        if v.abs() > SIGN_SPEED {
            let sign = if v > 0.0 { 1 } else { -1 };
            if self.last_sign != 0 && sign != self.last_sign {
                s.v_sign_changes += 1;
            }
            self.last_sign = sign;
        }
        // Maneuvers: turning points of the signed odometer `∫ v dt` (the distance moved
        // since the last step was driven by the previous step's command), with 1 cm of
        // hysteresis.
        self.odometer += moved * self.prev_v.signum();
        self.prev_v = v;
        if self.direction >= 0 && self.odometer < self.extremum - MANEUVER_DISTANCE {
            if self.direction > 0 {
                s.maneuvers += 1;
            }
            self.direction = -1;
            self.extremum = self.odometer;
        } else if self.direction <= 0 && self.odometer > self.extremum + MANEUVER_DISTANCE {
            if self.direction < 0 {
                s.maneuvers += 1;
            }
            self.direction = 1;
            self.extremum = self.odometer;
        } else if (self.direction > 0 && self.odometer > self.extremum)
            || (self.direction < 0 && self.odometer < self.extremum)
        {
            self.extremum = self.odometer;
        }
        s.max_abs_v = s.max_abs_v.max(v.abs());
        s.max_abs_omega = s.max_abs_omega.max(r.command.platform.omega.abs());
        self.sum_v2 += v * v;
        self.sum_w2 += r.command.platform.omega * r.command.platform.omega;
        for a in r.alpha_rate {
            if a.is_finite() {
                s.max_abs_alpha_rate = s.max_abs_alpha_rate.max(a.abs());
            }
        }
        if r.saturation.is_finite() {
            s.max_saturation = s.max_saturation.max(r.saturation);
        }
    }

    /// The summary so far, with the wall time.
    pub fn finish(&self, wall_time_s: f64) -> Summary {
        let mut s = self.s.clone();
        #[allow(clippy::cast_precision_loss)]
        if self.after20 > 0 {
            s.fraction_ep_below_1e_3_after_20s = self.below as f64 / self.after20 as f64;
        }
        s.wall_time_s = wall_time_s;
        #[allow(clippy::cast_precision_loss)]
        if s.steps > 0 {
            s.rms_v = (self.sum_v2 / s.steps as f64).sqrt();
            s.rms_omega = (self.sum_w2 / s.steps as f64).sqrt();
        }
        s
    }
}

/// `timeseries.csv`: the open file and a line buffer.
#[derive(Debug)]
struct CsvFile {
    out: BufWriter<File>,
    kind: PlatformKind,
    line: String,
}

impl CsvFile {
    fn write_row(&mut self, row: &Row) -> std::io::Result<()> {
        self.line.clear();
        format_row(&mut self.line, self.kind, row);
        self.out.write_all(self.line.as_bytes())
    }
}

/// Logged rows per message to the writer thread.
const BATCH_ROWS: usize = 128;
/// Batches in flight before [`Recorder::record`] waits for the writer thread.
const BATCHES_IN_FLIGHT: usize = 16;

/// Where logged rows go.
#[derive(Debug)]
enum Csv {
    /// Formatted and written by [`Recorder::record`] itself.
    Direct(CsvFile),
    /// Collected into batches for a writer thread, which formats and writes them.
    Background { batch: Vec<Row>, tx: SyncSender<Vec<Row>>, thread: JoinHandle<std::io::Result<CsvFile>> },
    /// The writer thread failed; its error was reported.
    Failed,
}

/// Writes `timeseries.csv`, keeps the logged rows for plots, and accumulates the summary.
///
/// Formatting the CSV (shortest round-trip decimals) is the most expensive part of recording;
/// [`in_background`](Self::in_background) moves it to a writer thread. The bytes written are
/// the same either way.
#[derive(Debug)]
pub struct Recorder {
    csv: Csv,
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
        let mut out = BufWriter::with_capacity(1 << 16, file);
        out.write_all(header(kind).as_bytes())?;
        Ok(Self {
            csv: Csv::Direct(CsvFile { out, kind, line: String::with_capacity(512) }),
            log_every,
            rows: Vec::with_capacity(expected_rows),
            summary,
        })
    }

    /// The same recorder with the CSV formatted and written by a thread of its own, until
    /// the next [`flush`](Self::flush) (which waits for it). [`record`](Self::record) then
    /// only copies the logged rows; write errors are reported by a later `record` or by
    /// `flush`.
    ///
    /// # Errors
    /// The thread cannot be started.
    pub fn in_background(mut self) -> Result<Self> {
        let mut file = match std::mem::replace(&mut self.csv, Csv::Failed) {
            Csv::Direct(file) => file,
            other => {
                // Already in the background, or failed: nothing to do.
                self.csv = other;
                return Ok(self);
            }
        };
        let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<Row>>(BATCHES_IN_FLIGHT);
        let thread = std::thread::Builder::new()
            .name("csv-format".into())
            .spawn(move || {
                for batch in rx {
                    for row in &batch {
                        file.write_row(row)?;
                    }
                }
                Ok(file)
            })
            .context("starting the CSV writer thread")?;
        self.csv = Csv::Background { batch: Vec::with_capacity(BATCH_ROWS), tx, thread };
        Ok(self)
    }

    /// Whether [`record`](Self::record) logs step `n` (written to the CSV and kept in
    /// [`rows`](Self::rows)): `n` is a multiple of `log_every`, or the last step.
    #[inline]
    pub fn logs(&self, n: u64, last: bool) -> bool {
        n % self.log_every == 0 || last
    }

    /// Records step `n`; the row is logged when `n` is a multiple of `log_every` or `last`.
    ///
    /// # Errors
    /// Writing the file failed.
    pub fn record(&mut self, n: u64, row: &Row, last: bool) -> Result<()> {
        self.summary.add(row);
        if self.logs(n, last) {
            match &mut self.csv {
                Csv::Direct(file) => file.write_row(row)?,
                Csv::Background { batch, tx, .. } => {
                    batch.push(*row);
                    if batch.len() == BATCH_ROWS {
                        let full = std::mem::replace(batch, Vec::with_capacity(BATCH_ROWS));
                        if tx.send(full).is_err() {
                            // The thread stopped early, so it failed: report why.
                            self.join_writer()?;
                            bail!("the CSV writer thread stopped early");
                        }
                    }
                }
                Csv::Failed => bail!("writing timeseries.csv failed earlier"),
            }
            self.rows.push(*row);
        }
        Ok(())
    }

    /// Flushes the file (after waiting for the writer thread, if there is one; the recorder
    /// then writes directly again).
    ///
    /// # Errors
    /// Writing the file failed.
    pub fn flush(&mut self) -> Result<()> {
        self.join_writer()?;
        match &mut self.csv {
            Csv::Direct(file) => file.out.flush().context("writing timeseries.csv"),
            Csv::Background { .. } | Csv::Failed => bail!("writing timeseries.csv failed earlier"),
        }
    }

    /// Hands the last batch to the writer thread, if any, waits for it and takes the file
    /// back.
    fn join_writer(&mut self) -> Result<()> {
        let (batch, tx, thread) = match std::mem::replace(&mut self.csv, Csv::Failed) {
            Csv::Background { batch, tx, thread } => (batch, tx, thread),
            other => {
                self.csv = other;
                return Ok(());
            }
        };
        // A failed send means the thread has stopped: its result says why.
        if !batch.is_empty() {
            let _ = tx.send(batch);
        }
        drop(tx);
        let file = thread
            .join()
            .map_err(|_| anyhow::anyhow!("the CSV writer thread panicked"))?
            .context("writing timeseries.csv")?;
        self.csv = Csv::Direct(file);
        Ok(())
    }
}

/// The CSV header for a platform.
pub fn header(kind: PlatformKind) -> String {
    let mut h = String::from(
        "t,x_b,y_b,theta_b,q1,q2,q3,x_e,y_e,theta_e,x_d,y_d,theta_d,ep_norm,h_s,psi,v,omega,alpha_dot,sat",
    );
    match kind {
        PlatformKind::Car => h.push_str(",alpha_dot2,xi,v_xi"),
        PlatformKind::Omni => h.push_str(",v_lat"),
        PlatformKind::Unicycle => {}
    }
    h.push_str(",status\n");
    h
}

/// Appends one CSV line for `row`.
pub fn format_row(out: &mut String, kind: PlatformKind, row: &Row) {
    let p = &row.plant;
    let r = &row.report;
    let c = &r.command.platform;
    let vals = [
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
        r.ep_norm,
        r.h_s,
        r.psi,
        c.v,
        c.omega,
        r.alpha_rate[0],
        r.saturation,
    ];
    for (i, v) in vals.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        let _ = write!(out, "{v}");
    }
    match kind {
        PlatformKind::Car => {
            let _ = write!(out, ",{},{},{}", r.alpha_rate[1], p.steering, c.v_xi);
        }
        PlatformKind::Omni => {
            let _ = write!(out, ",{}", c.v_lat);
        }
        PlatformKind::Unicycle => {}
    }
    out.push(',');
    out.push_str(&row.status());
    out.push('\n');
}

#[cfg(test)]
mod tests {
    use super::*;
    use companion_core::{Command, StepError};

    fn row(k: u32) -> Row {
        let x = f64::from(k);
        let mut report = StepReport {
            command: Command::zero(),
            ep_norm: 1.0 / (x + 3.0),
            h_s: x.sqrt(),
            psi: 1.0,
            saturation: 1.0,
            alpha_rate: [x * 0.1, -x / 7.0],
            error: None,
        };
        report.command.platform.v = (x * 0.37).sin();
        report.command.platform.omega = -x * 1e-3;
        if k % 97 == 5 {
            report = StepReport::rejected(StepError::SingularArm);
        }
        let plant = PlantSample {
            t: x * 1e-3,
            base: Pose::new(x.cos(), x.sin(), x / 3.0),
            steering: 0.01 * x,
            joints: SVector::<f64, JOINTS>::new(0.1, 0.35 + 1e-5 * x, -0.2),
            end_effector: Pose::new(1.0 / 3.0, x * 1e-7, -x),
            target: Pose::new(2.5, 1.0, 0.0),
        };
        Row { plant, report, source: CommandSource::Fresh }
    }

    fn dir(tag: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("companion-record-{}-{tag}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("temporary folder");
        d
    }

    fn recorder(d: &Path, kind: PlatformKind) -> Recorder {
        let acc = SummaryAccumulator::new("test", [-1.0, 0.0, -1.5], [1.0, 0.7, 1.5]);
        Recorder::create(d, kind, 3, acc, 0).expect("creating the CSV")
    }

    #[test]
    fn the_writer_thread_writes_the_same_bytes_rows_and_summary() {
        for kind in [PlatformKind::Unicycle, PlatformKind::Car, PlatformKind::Omni] {
            let (d1, d2) = (dir("direct"), dir("background"));
            let mut direct = recorder(&d1, kind);
            // Twice: the second call keeps the running thread.
            let mut background =
                recorder(&d2, kind).in_background().expect("thread").in_background().expect("thread");
            let steps = 3 * BATCH_ROWS as u32 * 5 + 7;
            for k in 0..=steps {
                direct.record(u64::from(k), &row(k), k == steps).expect("direct");
                background.record(u64::from(k), &row(k), k == steps).expect("background");
            }
            direct.flush().expect("direct");
            background.flush().expect("background");
            let a = std::fs::read(d1.join("timeseries.csv")).expect("read");
            let b = std::fs::read(d2.join("timeseries.csv")).expect("read");
            assert!(a.len() > 100_000, "{}", a.len());
            assert_eq!(a, b, "{kind:?}");
            // Debug strings: rejected rows hold NaN.
            assert_eq!(format!("{:?}", direct.rows), format!("{:?}", background.rows));
            assert_eq!(
                format!("{:?}", direct.summary.finish(0.0)),
                format!("{:?}", background.summary.finish(0.0))
            );
            // After a flush the recorder writes directly again, and still the same bytes.
            for k in steps + 1..steps + 10 {
                direct.record(u64::from(k), &row(k), false).expect("direct");
                background.record(u64::from(k), &row(k), false).expect("background");
            }
            direct.flush().expect("direct");
            background.flush().expect("background");
            assert_eq!(
                std::fs::read(d1.join("timeseries.csv")).expect("read"),
                std::fs::read(d2.join("timeseries.csv")).expect("read")
            );
            let _ = std::fs::remove_dir_all(&d1);
            let _ = std::fs::remove_dir_all(&d2);
        }
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_write_error_of_the_writer_thread_is_reported() {
        // `timeseries.csv` -> /dev/full: every write fails with "no space left on device".
        let d = dir("full");
        std::os::unix::fs::symlink("/dev/full", d.join("timeseries.csv")).expect("symlink");
        let mut r = recorder(&d, PlatformKind::Unicycle).in_background().expect("thread");
        let mut result = Ok(());
        for k in 0..200_000 {
            result = r.record(k, &row(k as u32), false);
            if result.is_err() {
                break;
            }
        }
        let err = match result {
            Err(e) => e,
            Ok(()) => r.flush().expect_err("the disk is full"),
        };
        assert!(format!("{err:#}").contains("timeseries.csv"), "{err:#}");
        // Later calls keep failing instead of silently dropping rows.
        assert!(r.record(0, &row(0), false).is_err());
        assert!(r.flush().is_err());
        let _ = std::fs::remove_dir_all(&d);
    }
}
