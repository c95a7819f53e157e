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

use anyhow::{Context, Result};
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
            prev_v: 0.0,
            direction: 0,
            extremum: 0.0,
            lower,
            upper,
        }
    }

    /// Adds one step.
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
        s
    }
}

/// Writes `timeseries.csv`, keeps the logged rows for plots, and accumulates the summary.
#[derive(Debug)]
pub struct Recorder {
    csv: BufWriter<File>,
    kind: PlatformKind,
    log_every: u64,
    line: String,
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
        let mut csv = BufWriter::with_capacity(1 << 16, file);
        csv.write_all(header(kind).as_bytes())?;
        Ok(Self {
            csv,
            kind,
            log_every,
            line: String::with_capacity(512),
            rows: Vec::with_capacity(expected_rows),
            summary,
        })
    }

    /// Records step `n`; the row is logged when `n` is a multiple of `log_every` or `last`.
    ///
    /// # Errors
    /// Writing the file failed.
    pub fn record(&mut self, n: u64, row: &Row, last: bool) -> Result<()> {
        self.summary.add(row);
        if n % self.log_every == 0 || last {
            self.line.clear();
            format_row(&mut self.line, self.kind, row);
            self.csv.write_all(self.line.as_bytes())?;
            self.rows.push(*row);
        }
        Ok(())
    }

    /// Flushes the file.
    ///
    /// # Errors
    /// Writing the file failed.
    pub fn flush(&mut self) -> Result<()> {
        self.csv.flush().context("writing timeseries.csv")
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
