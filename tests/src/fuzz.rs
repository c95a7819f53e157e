//! A closed-loop fuzz of the controller: the plant runs, and now and then bursts of garbage
//! replace the measurement, the period or the delay given to the law. The controller must
//! never panic, never command a non-finite value or exceed its velocity limits, and — the
//! point — must come back: once valid measurements return, the first one is accepted.
//!
//! Each *episode* draws a configuration (platform, `f32`/`f64`, paper run a–d, hold-aware or
//! sampled, period, delay, velocity limits or none, trajectory 1 or 2) and runs it for a
//! number of steps with the plant in the loop. A *burst* is 1–20 steps in which every
//! measurement is corrupted by one [`Garbage`] kind; after it the law gets the plant's
//! true measurement again. A valid measurement the law rejects is counted by reason; a
//! *lock-out* is [`LOCK_OUT_STEPS`] valid measurements in a row rejected — the controller
//! stuck while the robot is fine.
//!
//! A valid measurement may legitimately be rejected: after a burst whose accepted commands
//! (a target teleported a kilometre away is a valid, if wrong, measurement) drove the real
//! arm against a joint limit, `JointAtLimit` is the law's correct answer. The report counts
//! those apart; they are not lock-outs as long as they end.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use companion_core::{Measurement, PaperRun, PlatformKind, Pose, StepError};
use companion_plant::{PaperTrajectory, Simulated};
use companion_runtime::domain::controller::{AnyController, DiscretisationConfig, Scalar, JOINTS};
use companion_runtime::domain::plant_setup;
use companion_runtime::domain::scenario::{LimitsChoice, Scenario};
use rayon::prelude::*;

/// Valid measurements rejected in a row that make a lock-out.
pub const LOCK_OUT_STEPS: u64 = 1_000;

/// How long (s) a wrong measurement the law accepted may still steer the robot: its filters
/// (`q̂`, `Ψ`, `r̃_b`) forget it with time constants of a second or two.
pub const SETTLE: f64 = 10.0;

/// The largest distance from the origin (m) of the robot in the law's domain, for the fuzz.
pub const REACH: f64 = 1e6;

/// The largest distance (m) between the robot and the target in the `f32` law's domain. At
/// 100–200 km, `f32` resolves positions to 1–2 cm and the terms of (24) to nothing: a 10⁸-step
/// fuzz found the `f32` law rejecting every step there (`NumericalFailure`) with the arm at
/// its prismatic stop; within 10 km it never did. (docs/book/src/law.md states the domain.)
pub const F32_REACH: f64 = 1e4;

/// The largest car steering `|ξ|` (1/m) in the law's domain, for the fuzz.
pub const STEERING: f64 = 1e3;

/// Whether the true measurement `m` lies in the law's domain: finite, joints strictly inside
/// their limits, the robot within [`REACH`] (and, for the `f32` law, within [`F32_REACH`] of
/// the target), the steering within [`STEERING`].
fn in_domain(
    m: &Measurement<f64, JOINTS>,
    lower: &[f64; JOINTS],
    upper: &[f64; JOINTS],
    f32_law: bool,
) -> Result<(), String> {
    let distance = (m.base.x - m.target.x).hypot(m.base.y - m.target.y);
    if f32_law && (distance.is_nan() || distance >= F32_REACH) {
        return Err(format!("f32 law {distance:.0} m from the target"));
    }
    for i in 0..JOINTS {
        let q = m.joints[i];
        if !(q > lower[i] && q < upper[i]) {
            return Err(format!("joint {} at {q} outside ({}, {})", i + 1, lower[i], upper[i]));
        }
    }
    if !(m.base.x.abs() < REACH && m.base.y.abs() < REACH && m.base.theta.abs() < REACH) {
        return Err(format!("base at {:?}", m.base));
    }
    if m.steering.is_nan() || m.steering.abs() >= STEERING {
        return Err(format!("steering {}", m.steering));
    }
    Ok(())
}

/// How a burst corrupts the measurement (or the period or delay passed with it).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Garbage {
    /// One field NaN.
    Nan,
    /// One field `±∞`.
    Infinite,
    /// One field `±1e300` (finite in f64, `±∞` once rounded to f32).
    Huge,
    /// One field `±1e30` (finite in both, overflows products).
    Large,
    /// One field subnormal or `−0`.
    Tiny,
    /// The target teleported up to 1 000 km away.
    TargetTeleport,
    /// The platform teleported up to 1 km away.
    BaseTeleport,
    /// The time jumps by up to `±1e6` s (or to `±1e300`).
    TimeJump,
    /// A joint beyond its limit, or the arm singular (`q₂ = 0`).
    JointOut,
    /// The target's velocity up to `1e6` (m/s, rad/s).
    TargetVelocity,
    /// The period not finite, `≤ 0`, or far above the maximum.
    BadPeriod,
    /// The delay not finite, negative or far above the maximum.
    BadDelay,
}

impl Garbage {
    /// Every kind.
    pub const ALL: [Self; 12] = [
        Self::Nan,
        Self::Infinite,
        Self::Huge,
        Self::Large,
        Self::Tiny,
        Self::TargetTeleport,
        Self::BaseTeleport,
        Self::TimeJump,
        Self::JointOut,
        Self::TargetVelocity,
        Self::BadPeriod,
        Self::BadDelay,
    ];
}

/// What to fuzz.
#[derive(Clone, Copy, Debug)]
pub struct FuzzConfig {
    /// Closed-loop steps in all (rounded up to whole episodes).
    pub steps: u64,
    /// Steps per episode.
    pub episode_steps: u64,
    /// The seed of everything random.
    pub seed: u64,
    /// Stop starting episodes after this long (the report says so).
    pub time_box: Option<Duration>,
    /// The chance, per valid step, that a burst starts.
    pub burst_rate: f64,
}

impl Default for FuzzConfig {
    fn default() -> Self {
        Self { steps: 1_000_000, episode_steps: 20_000, seed: 1, time_box: None, burst_rate: 0.005 }
    }
}

/// What a fuzz found.
#[derive(Clone, Debug, Default)]
pub struct FuzzReport {
    /// Episodes run.
    pub episodes: u64,
    /// Closed-loop steps run.
    pub steps: u64,
    /// Steps whose input was garbage, by kind.
    pub garbage: BTreeMap<Garbage, u64>,
    /// Of those, steps the law accepted (a wrong but finite measurement is a measurement).
    pub garbage_accepted: u64,
    /// Bursts (each followed by valid measurements).
    pub bursts: u64,
    /// Bursts followed by a valid measurement (not by another burst).
    pub recovery_checks: u64,
    /// Of those, bursts after which the first valid measurement was accepted.
    pub recovered_at_once: u64,
    /// The most valid measurements rejected in a row.
    pub longest_rejection: u64,
    /// Valid measurements rejected, by reason.
    pub valid_rejected: BTreeMap<String, u64>,
    /// The first few of those, described.
    pub rejections: Vec<String>,
    /// Stretches of [`LOCK_OUT_STEPS`] valid measurements rejected in a row, with where.
    pub lock_outs: Vec<String>,
    /// Commands with a non-finite value (must be none).
    pub non_finite_commands: u64,
    /// Commands above the velocity limits (must be none).
    pub limit_violations: u64,
    /// The first few of those, described.
    pub violations: Vec<String>,
    /// Times the robot left the law's domain (a joint at its limit, a position beyond
    /// [`REACH`], a steering beyond [`STEERING`]) within [`SETTLE`] seconds of garbage the
    /// law accepted — a wrong measurement gives a wrong command, and a kinematic plant has
    /// no hard stops. The plant is then put back at its initial conditions (the controller
    /// is not told, and the command in flight stays in flight).
    pub plant_resets: u64,
    /// Times the robot left the domain with no garbage accepted for [`SETTLE`] seconds: the
    /// controller itself drove it out (must be none), described.
    pub left_on_its_own: Vec<String>,
    /// Whether the time box ended the fuzz before `steps`.
    pub timed_out: bool,
    /// Wall time (s).
    pub wall_time_s: f64,
}

impl FuzzReport {
    fn merge(&mut self, o: FuzzReport) {
        self.episodes += o.episodes;
        self.steps += o.steps;
        for (k, v) in o.garbage {
            *self.garbage.entry(k).or_default() += v;
        }
        self.garbage_accepted += o.garbage_accepted;
        self.bursts += o.bursts;
        self.recovery_checks += o.recovery_checks;
        self.recovered_at_once += o.recovered_at_once;
        self.longest_rejection = self.longest_rejection.max(o.longest_rejection);
        for (k, v) in o.valid_rejected {
            *self.valid_rejected.entry(k).or_default() += v;
        }
        self.rejections.extend(o.rejections);
        self.rejections.truncate(5);
        self.lock_outs.extend(o.lock_outs);
        self.non_finite_commands += o.non_finite_commands;
        self.limit_violations += o.limit_violations;
        self.violations.extend(o.violations);
        self.violations.truncate(10);
        self.plant_resets += o.plant_resets;
        self.left_on_its_own.extend(o.left_on_its_own);
        self.timed_out |= o.timed_out;
    }

    /// Steps whose input was garbage.
    pub fn garbage_steps(&self) -> u64 {
        self.garbage.values().sum()
    }

    /// Whether the controller held: no lock-out, no non-finite command, no limit exceeded.
    pub fn passed(&self) -> bool {
        self.lock_outs.is_empty()
            && self.non_finite_commands == 0
            && self.limit_violations == 0
            && self.left_on_its_own.is_empty()
    }
}

impl std::fmt::Display for FuzzReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "{} closed-loop steps in {} episodes ({:.1} s{})",
            self.steps,
            self.episodes,
            self.wall_time_s,
            if self.timed_out { ", stopped by the time box" } else { "" }
        )?;
        writeln!(
            f,
            "garbage: {} steps in {} bursts, {} accepted as (wrong) measurements",
            self.garbage_steps(),
            self.bursts,
            self.garbage_accepted
        )?;
        for (k, v) in &self.garbage {
            writeln!(f, "  {k:?}: {v}")?;
        }
        writeln!(
            f,
            "after a burst the first valid measurement was accepted {} of {} times; longest rejection {} steps",
            self.recovered_at_once, self.recovery_checks, self.longest_rejection
        )?;
        for (k, v) in &self.valid_rejected {
            writeln!(f, "  valid rejected {k}: {v}")?;
        }
        for r in &self.rejections {
            writeln!(f, "  {r}")?;
        }
        writeln!(
            f,
            "lock-outs: {}; non-finite commands: {}; limit violations: {}",
            self.lock_outs.len(),
            self.non_finite_commands,
            self.limit_violations
        )?;
        for l in self.lock_outs.iter().chain(&self.violations) {
            writeln!(f, "  {l}")?;
        }
        writeln!(
            f,
            "plant reset after accepted garbage drove it out of the domain: {}; left the domain on its own: {}",
            self.plant_resets,
            self.left_on_its_own.len()
        )?;
        for l in &self.left_on_its_own {
            writeln!(f, "  {l}")?;
        }
        Ok(())
    }
}

/// SplitMix64: a small, well-mixed, seedable generator (the fuzz needs no more).
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `0..n`.
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// `+1` or `−1`.
    pub fn sign(&mut self) -> f64 {
        if self.next_u64() & 1 == 0 {
            1.0
        } else {
            -1.0
        }
    }

    /// One of `items`.
    pub fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[self.below(items.len())]
    }
}

/// The scenario of one episode of `steps` steps.
fn episode_scenario(rng: &mut Rng, steps: u64) -> Scenario {
    let platform = rng.pick(&[PlatformKind::Unicycle, PlatformKind::Car, PlatformKind::Omni]);
    let run = rng.pick(&[PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D]);
    let trajectory = rng.pick(&[PaperTrajectory::One, PaperTrajectory::Two]);
    let dt = rng.pick(&[2.5e-4, 1e-3, 4e-3, 1e-2]);
    let mut b = Scenario::builder(trajectory, run, platform)
        .dt(dt)
        .scalar(rng.pick(&[Scalar::F64, Scalar::F32]))
        .discretisation(rng.pick(&[DiscretisationConfig::Midpoint, DiscretisationConfig::Sampled]))
        .limits(rng.pick(&[LimitsChoice::Unlimited, LimitsChoice::Realistic]))
        .duration(dt * (steps + 1) as f64);
    if rng.unit() < 0.3 {
        b = b.delay(dt * rng.unit());
    }
    b.build().unwrap_or_else(|e| panic!("a fuzz scenario is valid: {e}"))
}

/// Corrupts one field of `m`.
fn corrupt_field(m: &mut Measurement<f64, JOINTS>, rng: &mut Rng, value: f64) {
    match rng.below(14) {
        0 => m.t = value,
        1 => m.base.x = value,
        2 => m.base.y = value,
        3 => m.base.theta = value,
        4 => m.steering = value,
        i @ 5..=7 => m.joints[i - 5] = value,
        8 => m.target.x = value,
        9 => m.target.y = value,
        10 => m.target.theta = value,
        i => m.target_velocity[i - 11] = value,
    }
}

/// The measurement, period and delay of one garbage step.
fn garbage(
    kind: Garbage,
    m: &Measurement<f64, JOINTS>,
    period: f64,
    delay: f64,
    lower: &[f64; JOINTS],
    upper: &[f64; JOINTS],
    rng: &mut Rng,
) -> (Measurement<f64, JOINTS>, f64, f64) {
    let mut m = *m;
    let (mut period, mut delay) = (period, delay);
    let sign = rng.sign();
    match kind {
        Garbage::Nan => corrupt_field(&mut m, rng, f64::NAN),
        Garbage::Infinite => corrupt_field(&mut m, rng, sign * f64::INFINITY),
        Garbage::Huge => corrupt_field(&mut m, rng, sign * 1e300),
        Garbage::Large => corrupt_field(&mut m, rng, sign * 1e30),
        Garbage::Tiny => {
            let v = rng.pick(&[-0.0, 1e-310, -4.9e-324, 1e-40]);
            corrupt_field(&mut m, rng, v);
        }
        Garbage::TargetTeleport => {
            let r = 1e6 * rng.unit();
            m.target = Pose::new(m.target.x + rng.sign() * r, m.target.y + rng.sign() * r, m.target.theta);
        }
        Garbage::BaseTeleport => {
            let r = 1e3 * rng.unit();
            m.base = Pose::new(m.base.x + rng.sign() * r, m.base.y - rng.sign() * r, m.base.theta + r);
        }
        Garbage::TimeJump => {
            m.t = if rng.unit() < 0.2 { rng.sign() * 1e300 } else { m.t + rng.sign() * 1e6 * rng.unit() };
        }
        Garbage::JointOut => {
            let j = rng.below(JOINTS);
            m.joints[j] = match rng.below(3) {
                0 => lower[j] - rng.unit(),
                1 => upper[j] + rng.unit(),
                _ if j == 1 => 0.0,
                _ => upper[j],
            };
        }
        Garbage::TargetVelocity => {
            let i = rng.below(3);
            m.target_velocity[i] = rng.sign() * 1e6 * rng.unit();
        }
        Garbage::BadPeriod => period = rng.pick(&[0.0, -period, f64::NAN, f64::INFINITY, 1e9, 1e-300]),
        Garbage::BadDelay => delay = rng.pick(&[-1e-3, f64::NAN, f64::INFINITY, 1e9, -0.0]),
    }
    (m, period, delay)
}

/// One episode of `steps` closed-loop steps.
fn episode(index: u64, seed: u64, steps: u64, burst_rate: f64) -> FuzzReport {
    let mut rng = Rng::new(seed ^ index.wrapping_mul(0xd134_2543_de82_ef95));
    let s = episode_scenario(&mut rng, steps);
    let mut report = FuzzReport { episodes: 1, ..FuzzReport::default() };
    let mut controller = AnyController::new(&s.controller).expect("valid parameters");
    let mut plant = plant_setup::build(&s).expect("a valid plant");
    let params = s.controller.params::<f64>();
    let (lo, hi) = (params.joint_limits.lower, params.joint_limits.upper);
    let (lower, upper) = ([lo[0], lo[1], lo[2]], [hi[0], hi[1], hi[2]]);
    let (limits, joint_limits) = (params.velocity_limits, params.joint_velocity_limits);
    let (dt, delay) = (s.dt, s.delay);
    let f32_law = s.controller.scalar == Scalar::F32;
    let mut burst: Option<(Garbage, u64)> = None;
    let mut after_burst = false;
    let mut rejected_run = 0u64;
    let mut previous = companion_core::Command::zero();
    // The time of the last garbage the law accepted.
    let mut garbage_accepted_at = f64::NEG_INFINITY;
    // The time of the plant's start (it restarts from t = 0 when reset).
    let mut t0 = 0.0;
    for n in 0..steps {
        let mut truth = plant.measure();
        truth.t += t0;
        if let Err(why) = in_domain(&truth, &lower, &upper, f32_law) {
            if (n as f64) * dt - garbage_accepted_at < SETTLE {
                report.plant_resets += 1;
            } else {
                report.left_on_its_own.push(format!("episode {index} ({}), step {n}: {why}", describe(&s)));
            }
            // (The command in flight stays in flight: the controller remembers it.)
            plant = plant_setup::build(&s).expect("a valid plant");
            t0 = n as f64 * dt;
            truth = plant.measure();
            truth.t += t0;
        }
        if burst.is_none() && rng.unit() < burst_rate {
            burst = Some((rng.pick(&Garbage::ALL), 1 + rng.next_u64() % 20));
            report.bursts += 1;
        }
        let report_step = if let Some((kind, left)) = burst {
            let (m, p, d) = garbage(kind, &truth, dt, delay, &lower, &upper, &mut rng);
            *report.garbage.entry(kind).or_default() += 1;
            let r = controller.step(&m, p, d);
            if r.error.is_none() {
                report.garbage_accepted += 1;
                garbage_accepted_at = n as f64 * dt;
            }
            burst = if left > 1 { Some((kind, left - 1)) } else { None };
            after_burst = burst.is_none();
            r
        } else {
            let r = controller.step(&truth, dt, delay);
            match r.error {
                None => {
                    if after_burst {
                        report.recovery_checks += 1;
                        report.recovered_at_once += u64::from(rejected_run == 0);
                    }
                    after_burst = false;
                    rejected_run = 0;
                }
                Some(e) => {
                    if after_burst {
                        report.recovery_checks += 1;
                    }
                    after_burst = false;
                    rejected_run += 1;
                    report.longest_rejection = report.longest_rejection.max(rejected_run);
                    *report.valid_rejected.entry(reason(e)).or_default() += 1;
                    if report.rejections.len() < 5 && rejected_run == 1 {
                        report.rejections.push(format!(
                            "episode {index} ({}), step {n}: {e:?} at {truth:?}",
                            describe(&s)
                        ));
                    }
                    if rejected_run == LOCK_OUT_STEPS {
                        report.lock_outs.push(format!(
                            "episode {index} ({}), step {n}: {e:?} at {truth:?}",
                            describe(&s)
                        ));
                    }
                }
            }
            r
        };
        let c = report_step.command;
        if !c.is_finite() {
            report.non_finite_commands += 1;
        }
        let over = |x: f64, m: f64| x.abs() > m * (1.0 + 1e-6);
        let p = &c.platform;
        // (A car's `ω = v ξ` only reports the turn rate of the measured steering.)
        let car = s.controller.platform == PlatformKind::Car;
        if over(p.v, limits.forward)
            || over(p.v_lat, limits.lateral)
            || (!car && over(p.omega, limits.angular))
            || over(p.v_xi, limits.steering_rate)
            || (0..JOINTS).any(|i| over(c.joints[i], joint_limits[i]))
        {
            report.limit_violations += 1;
            if report.violations.len() < 10 {
                report
                    .violations
                    .push(format!("episode {index} ({}), step {n}: {c:?} above {limits:?}", describe(&s)));
            }
        }
        let c = if c.is_finite() { c } else { companion_core::Command::zero() };
        plant
            .try_advance_delayed(&previous, &c, delay, dt)
            .unwrap_or_else(|e| panic!("episode {index} ({}): the plant refused a command: {e}", s.name));
        previous = c;
        report.steps += 1;
    }
    report
}

/// A scenario in a line: its name, period and delay.
fn describe(s: &Scenario) -> String {
    format!("{}, dt {} s, delay {} s", s.name, s.dt, s.delay)
}

/// The variant's name of a step error (without its field), for counting.
fn reason(e: StepError) -> String {
    let s = format!("{e:?}");
    s.split('(').next().unwrap_or_default().to_string()
}

/// Runs the fuzz: episodes in parallel (rayon), `progress` called with the steps done
/// after each episode.
pub fn fuzz(cfg: &FuzzConfig, progress: &(dyn Fn(u64) + Sync)) -> FuzzReport {
    let start = Instant::now();
    let episodes = cfg.steps.div_ceil(cfg.episode_steps.max(1));
    let done = std::sync::atomic::AtomicU64::new(0);
    let mut report = (0..episodes)
        .into_par_iter()
        .map(|i| {
            if cfg.time_box.is_some_and(|b| start.elapsed() > b) {
                return FuzzReport { timed_out: true, ..FuzzReport::default() };
            }
            let r = episode(i, cfg.seed, cfg.episode_steps, cfg.burst_rate);
            let total = done.fetch_add(r.steps, std::sync::atomic::Ordering::Relaxed) + r.steps;
            progress(total);
            r
        })
        .reduce(FuzzReport::default, |mut a, b| {
            a.merge(b);
            a
        });
    report.wall_time_s = start.elapsed().as_secs_f64();
    report
}
