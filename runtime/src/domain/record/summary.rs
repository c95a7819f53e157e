//! The figures of `summary.json`, accumulated over every step of a run, for either arm: one
//! [`Summary`] and one [`SummaryAccumulator`]; a spatial arm's run adds its [`ArmFigures`].

use companion_core::space::Vector as _;
use serde::Serialize;

use super::digest::TrajectoryDigest;
use super::row::{CommandSource, Row, Task};
use super::verdict::{rejection_failure, Failure, Rejections};
use crate::domain::arm::MAX_JOINTS;

/// How long after a held or stopped period a step is not counted in the maximum "clear of
/// holds" (s): a held command's disturbance decays over the law's time constants.
pub const CLEAR_OF_HOLDS_S: f64 = 0.5;

/// The largest `‖e_p‖` for `t ≥ 20 s` at least [`CLEAR_OF_HOLDS_S`] after the last period
/// whose command was not fresh (held or stopped), accumulated step by step.
#[derive(Clone, Copy, Debug, Default)]
pub struct ClearOfHolds {
    last_not_fresh_t: Option<f64>,
    max: f64,
    steps: u64,
}

impl ClearOfHolds {
    /// Adds the step at `t` whose command came from `source`, with true error `ep`.
    pub fn add(&mut self, t: f64, source: CommandSource, ep: f64) {
        if source != CommandSource::Fresh {
            self.last_not_fresh_t = Some(t);
        }
        if t >= 20.0 && ep.is_finite() && self.last_not_fresh_t.is_none_or(|u| t - u >= CLEAR_OF_HOLDS_S) {
            self.max = self.max.max(ep);
            self.steps += 1;
        }
    }

    /// The maximum (NaN when no step counted) and the steps counted.
    pub fn finish(&self) -> (f64, u64) {
        (if self.steps > 0 { self.max } else { f64::NAN }, self.steps)
    }
}

/// How many steps' commands came from where: the controller's answer to the step, the last
/// one held after a missed deadline, the robot stopped (real-time HIL; in `sim` and lockstep
/// every command is fresh).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct CommandSources {
    /// The answer to the step's own measurement.
    pub fresh: u64,
    /// The previous command, held.
    pub held: u64,
    /// The safe zero command.
    pub stopped: u64,
}

impl CommandSources {
    /// Counts one step's command.
    #[inline]
    pub fn count(&mut self, source: CommandSource) {
        match source {
            CommandSource::Fresh => self.fresh += 1,
            CommandSource::Held => self.held += 1,
            CommandSource::Stopped => self.stopped += 1,
        }
    }
}

/// What a spatial arm's `summary.json` adds (§5): the arm, the six components of `e_p`, the
/// joint nearest its limit and the verdict. (The paper's arm's `summary.json` keeps its own
/// keys, which its figures and the Python package read.)
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ArmFigures {
    /// The arm's name.
    pub arm: String,
    /// Joints.
    pub joints: usize,
    /// `e_p` at the last step.
    pub final_e_p: Vec<f64>,
    /// The largest `|e_p,i|` for `t ≥ 20 s`, per component.
    pub max_abs_e_p_after_20s: Vec<f64>,
    /// The smallest of the joints' margins (rad or m).
    pub smallest_joint_margin: f64,
    /// Which joint it is (from 1).
    pub smallest_margin_joint: usize,
    /// `ok`, or `failed` with the reasons in `failures`.
    pub verdict: String,
}

/// The run's figures (`summary.json`). "After 20 s" means `t ≥ 20 s`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Summary {
    /// The scenario's name.
    pub scenario: String,
    /// `‖e_p‖` at the last step.
    pub final_ep_norm: f64,
    /// The largest `‖e_p‖` for `t ≥ 20 s`; NaN (`null` in JSON) when no step had `t ≥ 20 s`
    /// (a shorter run says nothing about it, which `0` would have claimed it did).
    pub max_ep_norm_after_20s: f64,
    /// The fraction of steps with `t ≥ 20 s` where `‖e_p‖ < 1e−3`; NaN (`null`) as above.
    #[serde(rename = "fraction_ep_below_1e-3_after_20s")]
    pub fraction_ep_below_1e_3_after_20s: f64,
    /// Per joint, the smallest distance to the nearer limit over the run (rad or m).
    pub min_joint_margin: Vec<f64>,
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
    /// The largest factor the joint guard divided the arm's velocities by (1: the arm law
    /// (30) was always applied as is).
    pub max_joint_scale: f64,
    /// Steps where the joint guard acted (factor > 1).
    pub joint_guard_steps: u64,
    /// Steps where the platform's acceleration limits acted: the change of its command was
    /// divided by the acceleration factor (`companion_core::acceleration`; 0 without limits).
    pub platform_acceleration_steps: u64,
    /// Steps where the joints' acceleration limits acted.
    pub joint_acceleration_steps: u64,
    /// How often the limits changed the law's command after 20 s, and whether more often than
    /// [`LIMITS_ACTED_BEYOND`] of the steps.
    pub limits_after_20s: LimitsActed,
    /// `h_s` at the first step.
    pub initial_h_s: f64,
    /// `h_s` at the last step.
    pub final_h_s: f64,
    /// Controller steps.
    pub steps: u64,
    /// Steps the controller rejected (safe command sent).
    pub rejected_steps: u64,
    /// The rejected steps by reason.
    pub rejections: Rejections,
    /// The time of the first rejected step (s).
    pub first_rejection_at_s: Option<f64>,
    /// Steps with `t ≥ 20 s` and a finite `‖e_p‖` (0: the figures "after 20 s" say nothing).
    pub steps_after_20s: u64,
    /// The largest `‖e_p‖` for `t ≥ 20 s` at least [`CLEAR_OF_HOLDS_S`] after the last held or
    /// stopped period (real time; in lockstep and `sim` every command is fresh, so it equals
    /// the maximum above): the law's floor apart from the machine's scheduling. NaN (`null`)
    /// when no such step.
    pub max_ep_norm_after_20s_clear_of_holds: f64,
    /// The steps it is taken over.
    pub steps_after_20s_clear_of_holds: u64,
    /// Wall-clock time of the run (s).
    pub wall_time_s: f64,
    /// The [`TrajectoryDigest`] of every step (16 hex digits): equal for two runs only if
    /// they are bit-identical.
    pub trajectory_digest: String,
    /// Whether the run ended before its last step (SIGINT/SIGTERM, or a lost peer).
    pub ended_early: bool,
    /// Why the run failed (empty: it did what a run must; see `record::verdict`).
    pub failures: Vec<Failure>,
    /// Where the steps' commands came from.
    pub command_sources: CommandSources,
    /// A spatial arm's figures (absent for the paper's arm).
    #[serde(flatten)]
    pub arm: Option<ArmFigures>,
    /// HIL runs: the link between the plant and the controller (absent from `sim`'s).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub link: Option<LinkRecord>,
}

/// The link of a HIL run, as `summary.json` records it.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct LinkRecord {
    /// The transport, its endpoint and security, e.g. `zenoh (listening on tls/0.0.0.0:7447,
    /// mutual TLS, peer certificate ctrl.local)`.
    pub transport: String,
    /// Whether the link let anyone in (`--insecure`: plain TCP, neither authenticated nor
    /// encrypted).
    pub insecure: bool,
}

/// The fraction of the steps after 20 s above which a run is said to have been shaped by the
/// limits the law's analysis does not cover ([`LimitsActed::beyond`]): 5 %. The paper's own
/// saturation (end of §3.4.2) divides the whole platform command by one common factor and keeps
/// its direction, so `h_s` still decreases, only more slowly; the acceleration limits (a second
/// factor on the *change* of the command, `companion_core::acceleration`) and the joint guard
/// (the arm's published joint speeds) do not keep it — the command sent is then not the law's.
/// A transient or a manoeuvre's peak cut now and then leaves the tracking to the law; once
/// they act on more than one step in twenty after the run should have converged, what the run
/// does after 20 s is theirs as much as the law's, and a run that settles so has no guarantee
/// that it would again (from another start, at another target speed). The paper's runs and the
/// presets' runs without limits are at 0–0.4 %, the runs under a real base's limits that do
/// not settle at 20–100 % (the book's chapter "The law", "A robot's own limits").
pub const LIMITS_ACTED_BEYOND: f64 = 0.05;

/// How often the limits changed the law's command on the steps with `t ≥ 20 s`: the
/// velocity limits' common factor (the paper's saturation), the platform's and the joints'
/// acceleration factors and the joint guard (the arm's published joint speeds).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct LimitsActed {
    /// Steps where the velocity limits' common factor was above 1.
    pub velocity_steps: u64,
    /// Steps where the platform's acceleration limits acted.
    pub platform_acceleration_steps: u64,
    /// Steps where the joints' acceleration limits acted.
    pub joint_acceleration_steps: u64,
    /// Steps where the joint guard slowed the arm.
    pub joint_guard_steps: u64,
    /// Steps where any of them acted.
    pub steps: u64,
    /// `steps` over the steps after 20 s (NaN, `null` in JSON, when there are none).
    pub fraction: f64,
    /// Steps where an acceleration limit or the joint guard acted: the limits beyond the
    /// paper's saturation, which change the direction of the law's command.
    pub beyond_saturation_steps: u64,
    /// `beyond_saturation_steps` over the steps after 20 s (NaN when there are none).
    pub beyond_saturation_fraction: f64,
    /// Whether `beyond_saturation_fraction` is above [`LIMITS_ACTED_BEYOND`]: the run after
    /// 20 s is shaped by its limits, not by the law alone (a run that settles so may have
    /// settled by luck).
    pub beyond: bool,
}

impl LimitsActed {
    /// Adds one step after 20 s.
    #[inline]
    fn add(&mut self, velocity: bool, platform_acceleration: bool, joint_acceleration: bool, guard: bool) {
        self.velocity_steps += u64::from(velocity);
        self.platform_acceleration_steps += u64::from(platform_acceleration);
        self.joint_acceleration_steps += u64::from(joint_acceleration);
        self.joint_guard_steps += u64::from(guard);
        let beyond = platform_acceleration || joint_acceleration || guard;
        self.beyond_saturation_steps += u64::from(beyond);
        self.steps += u64::from(velocity || beyond);
    }

    /// The fractions and the verdict over `after` steps after 20 s.
    fn finish(&mut self, after: u64) {
        let of = |n: u64| if after > 0 { n as f64 / after as f64 } else { f64::NAN };
        self.fraction = of(self.steps);
        self.beyond_saturation_fraction = of(self.beyond_saturation_steps);
        self.beyond = self.beyond_saturation_fraction > LIMITS_ACTED_BEYOND;
    }

    /// `velocity 40.6 %, platform acceleration 12.0 %` (the kinds that acted, of `after` steps).
    pub fn describe(&self, after: u64) -> String {
        let pct = |n: u64| 100.0 * n as f64 / after.max(1) as f64;
        let kinds: Vec<String> = [
            ("velocity (saturation)", self.velocity_steps),
            ("platform acceleration", self.platform_acceleration_steps),
            ("joint acceleration", self.joint_acceleration_steps),
            ("joint guard", self.joint_guard_steps),
        ]
        .into_iter()
        .filter(|(_, n)| *n > 0)
        .map(|(k, n)| format!("{k} {:.1} %", pct(n)))
        .collect();
        kinds.join(", ")
    }
}

/// The speed below which `v` has no sign for counting sign changes (m/s).
pub const SIGN_SPEED: f64 = 1e-3;

/// The distance a platform must cover in one direction for a reversal to count as a
/// maneuver (m).
pub const MANEUVER_DISTANCE: f64 = 0.01;

/// Accumulates the summary over every step, of either arm (nothing allocates in
/// [`add`](Self::add)).
#[derive(Clone, Debug)]
pub struct SummaryAccumulator {
    s: Summary,
    /// The arm's name, for a spatial arm's figures.
    arm: Option<String>,
    /// Joints.
    joints: usize,
    /// Per joint, the smallest margin so far.
    margins: [f64; MAX_JOINTS],
    /// `e_p` at the last finite step, and its largest `|e_p,i|` after 20 s.
    final_e_p: [f64; 6],
    max_abs_e_p: [f64; 6],
    /// How many components `e_p` has (3 in the plane, 6 in space).
    error_dim: usize,
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
    lower: [f64; MAX_JOINTS],
    upper: [f64; MAX_JOINTS],
    digest: TrajectoryDigest,
    clear: ClearOfHolds,
}

impl SummaryAccumulator {
    /// A new accumulator for joints with limits `lower`, `upper` (as many as the arm has, at
    /// most [`MAX_JOINTS`]).
    pub fn new(name: &str, lower: &[f64], upper: &[f64]) -> Self {
        let joints = lower.len().min(upper.len()).min(MAX_JOINTS);
        let limits = |from: &[f64]| {
            let mut a = [0.0; MAX_JOINTS];
            a[..joints].copy_from_slice(&from[..joints]);
            a
        };
        let s = Summary {
            scenario: name.to_string(),
            max_saturation: 1.0,
            max_joint_scale: 1.0,
            joint_guard_steps: 0,
            rejections: Rejections::for_joints(joints),
            ..Summary::default()
        };
        Self {
            s,
            arm: None,
            joints,
            margins: [f64::INFINITY; MAX_JOINTS],
            final_e_p: [0.0; 6],
            max_abs_e_p: [0.0; 6],
            error_dim: 0,
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
            lower: limits(lower),
            upper: limits(upper),
            digest: TrajectoryDigest::default(),
            clear: ClearOfHolds::default(),
        }
    }

    /// The same accumulator for a spatial arm named `arm`: its summary adds [`ArmFigures`].
    #[must_use]
    pub fn with_arm(mut self, arm: &str) -> Self {
        self.arm = Some(arm.to_string());
        self
    }

    /// Adds one step.
    ///
    /// Reads only the row's time, platform pose, joints and error and its report: the loop
    /// skips the end effector's pose on steps that are not logged.
    pub fn add<S: Task, const N: usize>(&mut self, row: &Row<S, N>) {
        let s = &mut self.s;
        let p = &row.plant;
        let r = &row.report;
        self.digest.add(row);
        s.steps += 1;
        s.command_sources.count(row.source);
        if let Some(e) = r.error {
            s.rejected_steps += 1;
            s.rejections.count(e);
            s.first_rejection_at_s.get_or_insert(p.t);
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
        // The robot's true tracking error (from the plant's exact state), whether or not
        // the controller accepted the step.
        let ep = p.ep_norm;
        self.clear.add(p.t, row.source, ep);
        let e_p = p.e_p.as_slice();
        self.error_dim = e_p.len().min(6);
        if ep.is_finite() {
            s.final_ep_norm = ep;
            for (f, e) in self.final_e_p.iter_mut().zip(e_p) {
                *f = *e;
            }
            if ep >= 1e-3 {
                s.ep_settling_time_s = p.t;
            }
            if p.t >= 20.0 {
                self.after20 += 1;
                s.max_ep_norm_after_20s = s.max_ep_norm_after_20s.max(ep);
                for (m, e) in self.max_abs_e_p.iter_mut().zip(e_p) {
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
        for i in 0..N.min(self.joints) {
            let m = (p.joints[i] - self.lower[i]).min(self.upper[i] - p.joints[i]);
            self.margins[i] = self.margins[i].min(m);
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
        if r.joint_scale.is_finite() {
            s.max_joint_scale = s.max_joint_scale.max(r.joint_scale);
            if r.joint_scale > 1.0 {
                s.joint_guard_steps += 1;
            }
        }
        s.platform_acceleration_steps += u64::from(r.platform_acceleration);
        s.joint_acceleration_steps += u64::from(r.joint_acceleration);
        if p.t >= 20.0 && ep.is_finite() {
            s.limits_after_20s.add(
                r.saturation > 1.0,
                r.platform_acceleration,
                r.joint_acceleration,
                r.joint_scale > 1.0,
            );
        }
    }

    /// The summary so far, with the wall time (a run that ended: see [`Summary::judge`]).
    pub fn finish(&self, wall_time_s: f64) -> Summary {
        let mut s = self.s.clone();
        let margins = &self.margins[..self.joints];
        s.min_joint_margin = margins.to_vec();
        let dim = self.error_dim;
        s.arm = self.arm.as_ref().map(|arm| {
            let (j, m) = margins.iter().copied().enumerate().fold((0, f64::INFINITY), |a, (i, m)| {
                if m < a.1 {
                    (i, m)
                } else {
                    a
                }
            });
            ArmFigures {
                arm: arm.clone(),
                joints: self.joints,
                final_e_p: self.final_e_p[..dim].to_vec(),
                max_abs_e_p_after_20s: self.max_abs_e_p[..dim].to_vec(),
                smallest_joint_margin: m,
                smallest_margin_joint: j + 1,
                verdict: String::new(),
            }
        });
        if self.after20 > 0 {
            s.fraction_ep_below_1e_3_after_20s = self.below as f64 / self.after20 as f64;
        } else {
            s.max_ep_norm_after_20s = f64::NAN;
            s.fraction_ep_below_1e_3_after_20s = f64::NAN;
        }
        s.steps_after_20s = self.after20;
        s.limits_after_20s.finish(self.after20);
        (s.max_ep_norm_after_20s_clear_of_holds, s.steps_after_20s_clear_of_holds) = self.clear.finish();
        s.wall_time_s = wall_time_s;
        s.trajectory_digest = self.digest.hex();
        if s.steps > 0 {
            s.rms_v = (self.sum_v2 / s.steps as f64).sqrt();
            s.rms_omega = (self.sum_w2 / s.steps as f64).sqrt();
        }
        s.set_verdict();
        s
    }
}

impl Summary {
    /// The verdict of a run that ended (early if `ended_early`: SIGINT/SIGTERM, a lost peer)
    /// held to `max_rejected`: the law's rejections beyond it are a failure.
    pub fn judge(&mut self, ended_early: bool, max_rejected: f64) {
        self.ended_early = ended_early;
        let failed = rejection_failure(&self.rejections, self.steps, self.first_rejection_at_s, max_rejected);
        self.failures.extend(failed);
        self.set_verdict();
    }

    /// Adds a reason the run failed (e.g. the HIL plant's missed deadlines).
    pub fn fail(&mut self, f: Failure) {
        self.failures.push(f);
        self.set_verdict();
    }

    /// A spatial arm's verdict: `ok` for a run that did what a run must, else `failed`.
    fn set_verdict(&mut self) {
        let ok = self.failures.is_empty() && !self.ended_early;
        if let Some(a) = &mut self.arm {
            a.verdict = if ok { "ok" } else { "failed" }.to_string();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_maximum_clear_of_holds_leaves_out_half_a_second_after_each_held_or_stopped_period() {
        let mut c = ClearOfHolds::default();
        let dt = 1e-3;
        // 19.9–21 s fresh with |e_p| 1e-4, a held period at 21 s and a stopped one at 22 s,
        // each followed by a disturbance of 1e-2 for 0.4 s; fresh with 1e-4 again after.
        for k in 19_900..=24_000_u32 {
            let t = f64::from(k) * dt;
            let source = match k {
                21_000 => CommandSource::Held,
                22_000 => CommandSource::Stopped,
                _ => CommandSource::Fresh,
            };
            let disturbed = (21_000..21_400).contains(&k) || (22_000..22_400).contains(&k);
            c.add(t, source, if disturbed { 1e-2 } else { 1e-4 });
        }
        let (max, steps) = c.finish();
        assert_eq!(max, 1e-4);
        // t ≥ 20 s: 4 001 steps, less [21, 21.5) and [22, 22.5) (500 each; float instants).
        assert!((2_999..=3_003).contains(&steps), "{steps}");
        // No step after 20 s: NaN, as the maximum including holds is.
        let mut short = ClearOfHolds::default();
        short.add(3.0, CommandSource::Fresh, 1e-4);
        assert!(short.finish().0.is_nan());
        assert_eq!(short.finish().1, 0);
    }
}
