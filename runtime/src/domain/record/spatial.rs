//! What a spatial run records: one [`SpatialRecord`] per logged step (the CSV's row, the
//! plots' data, and what a 3D replay such as MCAP needs), and the [`SpatialSummary`]
//! accumulated over every step.

use std::io::Write;

use companion_core::nalgebra::Vector6;
use companion_core::{so3, PlatformCommand, Pose3, StepError};
use serde::Serialize;

use crate::domain::arm::MAX_JOINTS;
use crate::domain::record::summary::ClearOfHolds;
use crate::domain::record::verdict::{reasons_in_words, Failure};
use crate::domain::record::{CommandSource, TrajectoryDigest};

/// One step of a spatial run, everything in the world frame (`z` up, the platform's plane at
/// `z = 0`): the seam for a 3D replay. A replay (e.g. MCAP with Foxglove's
/// `FrameTransform`s) publishes `base`, each of `links[..joints]`, `effector` and `target`
/// as transforms from the world, `q[..joints]` as joint states, `command` and `e_p`.
///
/// Arrays hold up to [`MAX_JOINTS`] joints; only the first `joints` entries are meaningful
/// (the rest are zero / identity), so one type serves every arm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpatialRecord {
    /// Time (s).
    pub t: f64,
    /// The number of joints of the arm.
    pub joints: usize,
    /// The platform's pose: the planar `(x, y, θ)` lifted (a rotation about `z`, height 0).
    pub base: Pose3<f64>,
    /// The platform's heading `θ_b` (rad, not wrapped).
    pub heading: f64,
    /// The car's steering `ξ` (1/m).
    pub steering: f64,
    /// Joint positions `q` (rad or m).
    pub q: [f64; MAX_JOINTS],
    /// Every joint's moving frame (after its motion) in the world: link `i`'s pose.
    pub links: [Pose3<f64>; MAX_JOINTS],
    /// The end effector in the world.
    pub effector: Pose3<f64>,
    /// The target in the world, `r_d`.
    pub target: Pose3<f64>,
    /// The target's body twist `u_d` (m/s, rad/s).
    pub target_twist: Vector6<f64>,
    /// The platform command applied over the next period.
    pub command: PlatformCommand<f64>,
    /// The joint velocities applied over the next period (rad/s or m/s).
    pub joint_rates: [f64; MAX_JOINTS],
    /// The true tracking error `e_p = (p̃, φ̃)` (m, rad) from the plant's exact state.
    pub e_p: Vector6<f64>,
    /// `‖e_p‖` of the six components.
    pub ep_norm: f64,
    /// The law's `h_s` (NaN when the step was rejected).
    pub h_s: f64,
    /// The joint guard's factor (NaN when rejected).
    pub joint_scale: f64,
    /// The platform's saturation factor (NaN when rejected; in the summary, not the CSV).
    pub saturation: f64,
    /// Why the law rejected the step, if it did (the command is then zero).
    pub error: Option<StepError>,
    /// Where the applied command came from: the answer to this step (always in `companion
    /// sim`), or (real-time HIL) the last one held, or the robot stopped.
    pub source: CommandSource,
}

impl SpatialRecord {
    /// The step's status as `timeseries.csv` and the replay write it: `ok`, the law's reason
    /// for a rejected step, or (real-time HIL) `held` / `stopped`.
    pub fn write_status(&self, out: &mut String) {
        use std::fmt::Write as _;
        match (self.source, self.error) {
            (CommandSource::Held, _) => out.push_str("held"),
            (CommandSource::Stopped, _) => out.push_str("stopped"),
            (CommandSource::Fresh, None) => out.push_str("ok"),
            (CommandSource::Fresh, Some(e)) => {
                let _ = write!(out, "{e}");
            }
        }
    }
}

/// The rejected steps by reason, for an arm of up to [`MAX_JOINTS`] joints.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SpatialRejections {
    /// A measured value was NaN or infinite.
    pub non_finite_measurement: u64,
    /// The time step was refused.
    pub bad_time_step: u64,
    /// Joint `i` (from 1) at or beyond a limit, one entry per joint.
    pub joint_at_limit: Vec<u64>,
    /// The arm at a singular configuration.
    pub singular_arm: u64,
    /// The task's matrix could not be inverted.
    pub singular_task_jacobian: u64,
    /// The delay was refused.
    pub bad_delay: u64,
    /// The target's `x` axis vertical: no yaw for the platform.
    pub target_yaw_undefined: u64,
    /// The law produced a non-finite value.
    pub numerical_failure: u64,
}

impl SpatialRejections {
    fn count(&mut self, e: StepError) {
        match e {
            StepError::NonFinite(_) => self.non_finite_measurement += 1,
            StepError::BadTimeStep => self.bad_time_step += 1,
            StepError::JointAtLimit(j) => {
                if let Some(c) = self.joint_at_limit.get_mut(usize::from(j)) {
                    *c += 1;
                }
            }
            StepError::SingularArm => self.singular_arm += 1,
            StepError::SingularTaskJacobian => self.singular_task_jacobian += 1,
            StepError::BadDelay => self.bad_delay += 1,
            StepError::TargetYawUndefined => self.target_yaw_undefined += 1,
            StepError::NumericalFailure => self.numerical_failure += 1,
        }
    }

    /// The reasons in words with their counts.
    pub fn describe(&self) -> String {
        let mut parts = vec![
            (self.non_finite_measurement, "a measured value is not finite".to_string()),
            (self.bad_time_step, StepError::BadTimeStep.to_string()),
            (self.singular_arm, StepError::SingularArm.to_string()),
            (self.singular_task_jacobian, StepError::SingularTaskJacobian.to_string()),
            (self.bad_delay, StepError::BadDelay.to_string()),
            (self.target_yaw_undefined, StepError::TargetYawUndefined.to_string()),
            (self.numerical_failure, StepError::NumericalFailure.to_string()),
        ];
        for (j, &n) in self.joint_at_limit.iter().enumerate() {
            parts.push((n, StepError::JointAtLimit(u8::try_from(j).unwrap_or(u8::MAX)).to_string()));
        }
        parts.retain(|p| p.0 > 0);
        reasons_in_words(parts)
    }
}

/// A spatial run's figures (`summary.json`). "After 20 s" means `t ≥ 20 s`; "tracked" has
/// the planar runs' definition: the fraction of steps after 20 s with `‖e_p‖ < 1e−3`
/// (here the norm of all six components, metres and radians).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SpatialSummary {
    /// The run's name.
    pub scenario: String,
    /// The arm's name and its joint count.
    pub arm: String,
    /// Joints.
    pub joints: usize,
    /// `‖e_p‖` at the last step.
    pub final_ep_norm: f64,
    /// `e_p` at the last step.
    pub final_e_p: [f64; 6],
    /// The largest `‖e_p‖` for `t ≥ 20 s`.
    pub max_ep_norm_after_20s: f64,
    /// The largest `|e_p,i|` for `t ≥ 20 s`, per component.
    pub max_abs_e_p_after_20s: [f64; 6],
    /// The fraction of steps with `t ≥ 20 s` where `‖e_p‖ < 1e−3`.
    #[serde(rename = "fraction_ep_below_1e-3_after_20s")]
    pub fraction_ep_below_1e_3_after_20s: f64,
    /// Steps with `t ≥ 20 s` and a finite `‖e_p‖`.
    pub steps_after_20s: u64,
    /// The largest `‖e_p‖` for `t ≥ 20 s` at least
    /// [`CLEAR_OF_HOLDS_S`](super::summary::CLEAR_OF_HOLDS_S) after the last held or stopped
    /// period (as in the planar summary); NaN (`null`) when no such step.
    pub max_ep_norm_after_20s_clear_of_holds: f64,
    /// The steps it is taken over.
    pub steps_after_20s_clear_of_holds: u64,
    /// The last time `‖e_p‖ ≥ 1e−3` (s).
    pub ep_settling_time_s: f64,
    /// Per joint, the smallest distance to the nearer limit over the run (rad or m).
    pub min_joint_margin: Vec<f64>,
    /// The smallest of them.
    pub smallest_joint_margin: f64,
    /// Which joint it is (from 1).
    pub smallest_margin_joint: usize,
    /// The platform's path length (m).
    pub path_length: f64,
    /// The largest `|v|` commanded (m/s).
    pub max_abs_v: f64,
    /// The largest platform saturation factor.
    pub max_saturation: f64,
    /// The largest joint guard factor (1: the arm law applied as is).
    pub max_joint_scale: f64,
    /// `h_s` at the last accepted step.
    pub final_h_s: f64,
    /// Controller steps.
    pub steps: u64,
    /// Steps the law rejected (the safe zero command was applied).
    pub rejected_steps: u64,
    /// The rejections by reason.
    pub rejections: SpatialRejections,
    /// The first rejected step's time (s).
    pub first_rejection_at_s: Option<f64>,
    /// FNV-1a over every step's time, platform, steering, joints and command (as the
    /// planar runs' digest): equal for two runs only if they are bit-identical.
    pub trajectory_digest: String,
    /// Wall-clock time (s).
    pub wall_time_s: f64,
    /// Whether SIGINT/SIGTERM ended the run early.
    pub ended_early: bool,
    /// Why the run failed (empty: it did what a run must).
    pub failures: Vec<Failure>,
    /// `ok`, or `failed` with the reasons in `failures`.
    pub verdict: String,
    /// HIL runs: the link between the plant and the controller (absent from `sim`'s).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub link: Option<crate::domain::record::summary::LinkRecord>,
}

/// Accumulates a [`SpatialSummary`] over every step.
#[derive(Clone, Debug)]
pub struct SpatialAccumulator {
    s: SpatialSummary,
    lower: Vec<f64>,
    upper: Vec<f64>,
    after20: u64,
    below: u64,
    last_pos: Option<(f64, f64)>,
    digest: TrajectoryDigest,
    clear: ClearOfHolds,
}

impl SpatialAccumulator {
    /// An accumulator for the joints' limits.
    pub fn new(name: &str, arm: &str, lower: &[f64], upper: &[f64]) -> Self {
        let n = lower.len();
        Self {
            s: SpatialSummary {
                scenario: name.to_string(),
                arm: arm.to_string(),
                joints: n,
                min_joint_margin: vec![f64::INFINITY; n],
                rejections: SpatialRejections { joint_at_limit: vec![0; n], ..SpatialRejections::default() },
                max_saturation: 1.0,
                max_joint_scale: 1.0,
                ..SpatialSummary::default()
            },
            lower: lower.to_vec(),
            upper: upper.to_vec(),
            after20: 0,
            below: 0,
            last_pos: None,
            digest: TrajectoryDigest::default(),
            clear: ClearOfHolds::default(),
        }
    }

    /// Adds one step. Reads the record's time, base, joints, command, `e_p` and report; not
    /// its frames (which the loop computes for logged steps only).
    pub fn add(&mut self, r: &SpatialRecord) {
        let s = &mut self.s;
        let n = r.joints;
        for x in [r.t, r.base.translation[0], r.base.translation[1], r.heading, r.steering] {
            self.digest.number(x);
        }
        for x in &r.q[..n] {
            self.digest.number(*x);
        }
        let c = &r.command;
        for x in [c.v, c.v_lat, c.omega, c.v_xi] {
            self.digest.number(x);
        }
        for x in &r.joint_rates[..n] {
            self.digest.number(*x);
        }
        s.steps += 1;
        if let Some(e) = r.error {
            s.rejected_steps += 1;
            s.rejections.count(e);
            s.first_rejection_at_s.get_or_insert(r.t);
        }
        let (x, y) = (r.base.translation[0], r.base.translation[1]);
        if let Some((x0, y0)) = self.last_pos {
            s.path_length += (x - x0).hypot(y - y0);
        }
        self.last_pos = Some((x, y));
        let ep = r.ep_norm;
        self.clear.add(r.t, r.source, ep);
        if ep.is_finite() {
            s.final_ep_norm = ep;
            s.final_e_p = r.e_p.into();
            if ep >= 1e-3 {
                s.ep_settling_time_s = r.t;
            }
            if r.t >= 20.0 {
                self.after20 += 1;
                s.max_ep_norm_after_20s = s.max_ep_norm_after_20s.max(ep);
                for (m, e) in s.max_abs_e_p_after_20s.iter_mut().zip(r.e_p.iter()) {
                    *m = m.max(e.abs());
                }
                if ep < 1e-3 {
                    self.below += 1;
                }
            }
        }
        if r.h_s.is_finite() {
            s.final_h_s = r.h_s;
        }
        for i in 0..n {
            let m = (r.q[i] - self.lower[i]).min(self.upper[i] - r.q[i]);
            s.min_joint_margin[i] = s.min_joint_margin[i].min(m);
        }
        s.max_abs_v = s.max_abs_v.max(c.v.abs());
        if r.joint_scale.is_finite() {
            s.max_joint_scale = s.max_joint_scale.max(r.joint_scale);
        }
        if r.saturation.is_finite() {
            s.max_saturation = s.max_saturation.max(r.saturation);
        }
    }

    /// The summary: fractions, the smallest margin, the digest and the wall time; the
    /// rejection failure if more than `max_rejected` of the steps were rejected.
    pub fn finish(&self, wall_time_s: f64, ended_early: bool, max_rejected: f64) -> SpatialSummary {
        let mut s = self.s.clone();
        if self.after20 > 0 {
            s.fraction_ep_below_1e_3_after_20s = self.below as f64 / self.after20 as f64;
        }
        s.steps_after_20s = self.after20;
        (s.max_ep_norm_after_20s_clear_of_holds, s.steps_after_20s_clear_of_holds) = self.clear.finish();
        let (j, m) = s.min_joint_margin.iter().copied().enumerate().fold((0, f64::INFINITY), |a, (i, m)| {
            if m < a.1 {
                (i, m)
            } else {
                a
            }
        });
        s.smallest_joint_margin = m;
        s.smallest_margin_joint = j + 1;
        s.trajectory_digest = self.digest.hex();
        s.wall_time_s = wall_time_s;
        s.ended_early = ended_early;
        let n = s.rejected_steps;
        if n > 0 && (s.steps == 0 || n as f64 > max_rejected * s.steps as f64) {
            s.failures.push(Failure::Rejected {
                rejected_steps: n,
                steps: s.steps,
                limit: max_rejected,
                first_at_s: s.first_rejection_at_s,
                reasons: s.rejections.describe(),
            });
        }
        s.verdict = if s.failures.is_empty() && !ended_early { "ok" } else { "failed" }.to_string();
        s
    }
}

impl SpatialSummary {
    /// Adds a reason the run failed (e.g. the HIL plant's missed deadlines).
    pub fn fail(&mut self, f: Failure) {
        self.failures.push(f);
        self.verdict = "failed".to_string();
    }
}

/// The columns of a spatial `timeseries.csv` for `n` joints.
pub fn columns(n: usize) -> Vec<String> {
    let mut h: Vec<String> = ["t", "x_b", "y_b", "theta_b", "xi"].iter().map(ToString::to_string).collect();
    h.extend((1..=n).map(|i| format!("q{i}")));
    for p in ["e", "d"] {
        h.extend(["x", "y", "z", "qx", "qy", "qz", "qw"].iter().map(|c| format!("{c}_{p}")));
    }
    h.extend(
        ["ep_x", "ep_y", "ep_z", "ep_rx", "ep_ry", "ep_rz", "ep_norm", "h_s", "v", "v_lat", "omega", "v_xi"]
            .map(String::from),
    );
    h.extend((1..=n).map(|i| format!("u_q{i}")));
    h.push("joint_scale".to_string());
    h.push("status".to_string());
    h
}

/// Writes the records as `timeseries.csv` (numbers in Rust's shortest round-trip form; a
/// pose as position and unit quaternion `(x, y, z, w)`, as Foxglove orders it; `status` is `ok` or the rejection).
///
/// # Errors
/// Writing failed.
pub fn write_csv<W: Write>(w: W, records: &[SpatialRecord]) -> csv::Result<()> {
    let mut out = SpatialCsv::new(w, records.first().map_or(0, |r| r.joints))?;
    for r in records {
        out.write(r)?;
    }
    out.flush()?;
    Ok(())
}

/// A spatial `timeseries.csv` written row by row (the HIL plant's writer thread).
#[derive(Debug)]
pub struct SpatialCsv<W: Write> {
    out: csv::Writer<W>,
    joints: usize,
    row: Vec<String>,
}

impl<W: Write> SpatialCsv<W> {
    /// Writes the header of an arm of `joints` joints.
    ///
    /// # Errors
    /// The writer failed.
    pub fn new(w: W, joints: usize) -> csv::Result<Self> {
        let mut out = csv::Writer::from_writer(w);
        out.write_record(columns(joints))?;
        Ok(Self { out, joints, row: Vec::new() })
    }

    /// Writes one row.
    ///
    /// # Errors
    /// The writer failed.
    pub fn write(&mut self, r: &SpatialRecord) -> csv::Result<()> {
        let n = self.joints;
        let row = &mut self.row;
        row.clear();
        let mut num = |x: f64| row.push(x.to_string());
        for x in [r.t, r.base.translation[0], r.base.translation[1], r.heading, r.steering] {
            num(x);
        }
        for x in &r.q[..n] {
            num(*x);
        }
        for p in [&r.effector, &r.target] {
            for x in p.translation.iter() {
                num(*x);
            }
            for x in so3::to_quaternion(&p.rotation) {
                num(x);
            }
        }
        for x in r.e_p.iter() {
            num(*x);
        }
        let c = &r.command;
        for x in [r.ep_norm, r.h_s, c.v, c.v_lat, c.omega, c.v_xi] {
            num(x);
        }
        for x in &r.joint_rates[..n] {
            num(*x);
        }
        num(r.joint_scale);
        let mut status = String::new();
        r.write_status(&mut status);
        row.push(status);
        self.out.write_record(&*row)
    }

    /// Flushes what is written to the underlying writer.
    ///
    /// # Errors
    /// The writer failed.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}
