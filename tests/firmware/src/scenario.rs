//! The firmware check's scenario: one source file that the firmware binary (`mod scenario`)
//! and the host test `tests/tests/firmware_host.rs` (`#[path] mod scenario`) both compile,
//! so that both run the same operations and their outputs can be compared bit for bit.
//!
//! It closes the loop of the controller around a minimal plant, step 1 ms, platform at the
//! origin, `q(0) = (0, 0.35, 0)`, on the start of the paper's two trajectories (SPEC §4):
//! - trajectory 1, the first 3 s: target velocity `u_d(t) = −(π/20)(sin(πt/2), cos(πt/2),
//!   0)`, target at `(2.6, 1, 0)`;
//! - trajectory 2 (Table 1), the first 6 s: the target at rest at `(2.5, 1, 0)` for 5 s,
//!   then the first second of its first rotation, `ω_d = (π²/20) cos(π(t − 5)/2)` (a jump
//!   of `ω_d` from 0 to 0.49 rad/s at `t = 5 s`).
//!
//! In `f32`, all four of the paper's runs (a)–(d) on both trajectories, unicycle, car-like
//! and omnidirectional (the 8 runs × 3 platforms of the cost table), the `Sampled`
//! discretisation on the unicycle's 8 runs, and the unicycle's 8 with a robot's limits on
//! ([`robot_limits`]: velocity and acceleration limits of the platform and the joints); in `f64` (≈ 50 times slower on the M4F), runs
//! (a) and (c) of trajectory 1; and the spatial law of §5 ([`SpatialArm`]): the UR5 on the
//! unicycle, run (a), on trajectory 1 lifted (the same circle, the target level and `0.2 m`
//! below the flange at home, plus `z = 0.05 sin(2πt/10)` m), from its home configuration.
//! It prints a digest of the commands (FNV-1a of their bits) every [`REPORT_EVERY`] steps
//! and a final line per case.
//!
//! Output lines (space separated, floats as the hex bits of their `f64` value):
//!
//! ```text
//! D <case> <step> <digest> <v> <v_lat> <omega> <v_xi> <u_q1> … <u_qN>
//! F <case> <steps> <rejected> <digest> <|e_p|> <|e_p| decimal>
//! ```
#![allow(dead_code)] // each includer uses a different part

use core::fmt::Write;
use core::hint::black_box;

use companion_core::nalgebra::{SVector, Vector3, Vector6};
use companion_core::{
    AccelerationLimits, CarLike, Chain, Command, Controller, Discretisation, Manipulator, Measurement,
    Omnidirectional, Output, PaperRun, Params, Platform, PlatformKind, Pose, Pose3, Real, Rejected, Rpr,
    Spatial, SpatialArm, Unicycle, VelocityLimits,
};

/// Control period (s).
pub const DT: f64 = 1e-3;
/// Steps of a case on trajectory 1: 3 s.
pub const STEPS_1: u32 = 3000;
/// Steps of a case on trajectory 2: 6 s (the rest, then the first second of the rotation).
pub const STEPS_2: u32 = 6000;
/// A `D` line every this many steps (and after the last).
pub const REPORT_EVERY: u32 = 250;

/// Which platform a case runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plat {
    /// Unicycle, the paper's `(ε₁, ε₂) = (0.2, 0.4)`.
    Uni,
    /// Car-like, `ε = 0.3, η = (1, 2, 1), k = 5`, with velocity limits.
    Car,
    /// Omnidirectional.
    Omni,
    /// The UR5 ([`Chain::ur5`]) on the paper's unicycle: the spatial law.
    Ur5Uni,
}

/// The paper's target trajectory of a case (§4.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Traj {
    /// Trajectory 1, the circle ([`target`]), for [`STEPS_1`] steps.
    One,
    /// Trajectory 2, Table 1 ([`target_2`]), for [`STEPS_2`] steps.
    Two,
}

/// One closed-loop run.
#[derive(Clone, Copy, Debug)]
pub struct Case {
    /// Short name used in the output: platform, trajectory and run (`uni-2c-f32`), scalar,
    /// `-sampled` for the earlier discretisation.
    pub name: &'static str,
    /// The platform.
    pub plat: Plat,
    /// The paper's trajectory.
    pub traj: Traj,
    /// The paper's run (a)–(d).
    pub run: PaperRun,
    /// `f64` (else `f32`).
    pub double: bool,
    /// The earlier discretisation, `Discretisation::Sampled` (else the default, `Midpoint`).
    pub sampled: bool,
    /// A robot's limits on ([`robot_limits`]), `-limits` in the name.
    pub limits: bool,
}

impl Case {
    /// Steps of 1 ms the case runs.
    pub const fn steps(&self) -> u32 {
        match self.traj {
            Traj::One => STEPS_1,
            Traj::Two => STEPS_2,
        }
    }
}

const fn f32c(name: &'static str, plat: Plat, traj: Traj, run: PaperRun) -> Case {
    Case { name, plat, traj, run, double: false, sampled: false, limits: false }
}

const fn f64c(name: &'static str, plat: Plat, run: PaperRun) -> Case {
    Case { name, plat, traj: Traj::One, run, double: true, sampled: false, limits: false }
}

const fn sampled(name: &'static str, plat: Plat, traj: Traj, run: PaperRun, double: bool) -> Case {
    Case { name, plat, traj, run, double, sampled: true, limits: false }
}

const fn limited(name: &'static str, traj: Traj, run: PaperRun) -> Case {
    Case { name, plat: Plat::Uni, traj, run, double: false, sampled: false, limits: true }
}

use PaperRun::{A, B, C, D};
use Plat::{Car, Omni, Uni, Ur5Uni};
use Traj::{One, Two};

/// Every case, in output order: the `f32` cases of the cost table first (the default law,
/// 8 runs × 3 platforms, then the sampled one, then the unicycle with the limits on), so that the single-step count reaches them
/// soon; then the spatial law in `f32`, the `f64` cases, the UR5 in `f64`. The firmware
/// marks the start of each case (`companion_case_start`), where `gdbcount.py` starts
/// numbering the calls of the case's step function. The spatial cases (`ur5-…`) step
/// through their own function, `spatial_step`.
pub const CASES: [Case; 51] = [
    f32c("uni-1a-f32", Uni, One, A),
    f32c("uni-1b-f32", Uni, One, B),
    f32c("uni-1c-f32", Uni, One, C),
    f32c("uni-1d-f32", Uni, One, D),
    f32c("uni-2a-f32", Uni, Two, A),
    f32c("uni-2b-f32", Uni, Two, B),
    f32c("uni-2c-f32", Uni, Two, C),
    f32c("uni-2d-f32", Uni, Two, D),
    f32c("car-1a-f32", Car, One, A),
    f32c("car-1b-f32", Car, One, B),
    f32c("car-1c-f32", Car, One, C),
    f32c("car-1d-f32", Car, One, D),
    f32c("car-2a-f32", Car, Two, A),
    f32c("car-2b-f32", Car, Two, B),
    f32c("car-2c-f32", Car, Two, C),
    f32c("car-2d-f32", Car, Two, D),
    f32c("omni-1a-f32", Omni, One, A),
    f32c("omni-1b-f32", Omni, One, B),
    f32c("omni-1c-f32", Omni, One, C),
    f32c("omni-1d-f32", Omni, One, D),
    f32c("omni-2a-f32", Omni, Two, A),
    f32c("omni-2b-f32", Omni, Two, B),
    f32c("omni-2c-f32", Omni, Two, C),
    f32c("omni-2d-f32", Omni, Two, D),
    sampled("uni-1a-f32-sampled", Uni, One, A, false),
    sampled("uni-1b-f32-sampled", Uni, One, B, false),
    sampled("uni-1c-f32-sampled", Uni, One, C, false),
    sampled("uni-1d-f32-sampled", Uni, One, D, false),
    sampled("uni-2a-f32-sampled", Uni, Two, A, false),
    sampled("uni-2b-f32-sampled", Uni, Two, B, false),
    sampled("uni-2c-f32-sampled", Uni, Two, C, false),
    sampled("uni-2d-f32-sampled", Uni, Two, D, false),
    sampled("car-1a-f32-sampled", Car, One, A, false),
    sampled("omni-1a-f32-sampled", Omni, One, A, false),
    limited("uni-1a-f32-limits", One, A),
    limited("uni-1b-f32-limits", One, B),
    limited("uni-1c-f32-limits", One, C),
    limited("uni-1d-f32-limits", One, D),
    limited("uni-2a-f32-limits", Two, A),
    limited("uni-2b-f32-limits", Two, B),
    limited("uni-2c-f32-limits", Two, C),
    limited("uni-2d-f32-limits", Two, D),
    f32c("ur5-uni-1a-f32", Ur5Uni, One, A),
    f64c("uni-1a-f64", Uni, A),
    f64c("uni-1c-f64", Uni, C),
    f64c("car-1a-f64", Car, A),
    f64c("car-1c-f64", Car, C),
    f64c("omni-1a-f64", Omni, A),
    f64c("omni-1c-f64", Omni, C),
    sampled("uni-1a-f64-sampled", Uni, One, A, true),
    f64c("ur5-uni-1a-f64", Ur5Uni, A),
];

/// Hooks around each controller step (the firmware counts instructions there).
pub trait Probe {
    /// Just before `step`.
    fn enter(&mut self);
    /// Just after `step`.
    fn leave(&mut self);
}

/// No measurement (the host).
#[derive(Debug)]
pub struct NoProbe;

impl Probe for NoProbe {
    #[inline(always)]
    fn enter(&mut self) {}
    #[inline(always)]
    fn leave(&mut self) {}
}

/// What a case ends with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    /// Steps run.
    pub steps: u32,
    /// Steps the controller rejected (the safe command was applied).
    pub rejected: u32,
    /// FNV-1a over the bits of every command.
    pub digest: u64,
    /// `|e_p|` of the last accepted step.
    pub e_p: f64,
}

/// The car-like platform of the scenario: Lemma 2 holds (6·2·1 = 12 > 8·1 + 1·2 = 10).
pub fn car<T: Real>() -> CarLike<T> {
    CarLike::new(T::of(0.3), [T::one(), T::of(2.0), T::one()], T::of(5.0))
}

/// The car's velocity limits: `det H̄` is ~1e−3 for this function, so unsaturated gains
/// are huge (SPEC §3); these keep the run bounded.
pub fn car_limits<T: Real>() -> VelocityLimits<T> {
    let mut l = VelocityLimits::unlimited();
    l.forward = T::of(1.0);
    l.alpha_rate = T::of(20.0);
    l.steering_rate = T::of(20.0);
    l
}

/// A robot's limits, for the cost of the law with them on: the TIAGo's base as PAL's
/// controller configures it (`tiago_controller_configuration/config/mobile_base_controller.yaml`:
/// 1 m/s and 1 m/s², 2.09 rad/s and 2.09 rad/s²) and, so that every part of the limits runs,
/// 10 rad/s² (m/s² for the prismatic joint) on each joint, where PAL publishes none.
pub fn robot_limits<T: Real>() -> (VelocityLimits<T>, AccelerationLimits<T, 3>) {
    let mut v = VelocityLimits::unlimited();
    v.forward = T::one();
    v.angular = T::of(2.09);
    let mut a = AccelerationLimits::unlimited();
    a.forward = T::one();
    a.angular = T::of(2.09);
    a.joints = SVector::repeat(T::of(10.0));
    (v, a)
}

/// The parameters of case `c` on platform kind `kind`.
fn params_of<T: Real>(c: &Case, kind: PlatformKind) -> Params<T, 3> {
    let mut params = Params::<T, 3>::paper(c.run);
    if kind == PlatformKind::Car {
        params.velocity_limits = car_limits();
    }
    if c.sampled {
        params.discretisation = Discretisation::Sampled;
    }
    if c.limits {
        (params.velocity_limits, params.acceleration_limits) = robot_limits();
    }
    params
}

/// Runs one case, writing its `D` and `F` lines to `out`.
pub fn run_case<W: Write, Q: Probe>(c: &Case, out: &mut W, probe: &mut Q) -> Outcome {
    match (c.plat, c.double) {
        (Plat::Uni, false) => run::<f32, _, _, _>(c, Unicycle::paper(), out, probe),
        (Plat::Uni, true) => run::<f64, _, _, _>(c, Unicycle::paper(), out, probe),
        (Plat::Car, false) => run::<f32, _, _, _>(c, car(), out, probe),
        (Plat::Car, true) => run::<f64, _, _, _>(c, car(), out, probe),
        (Plat::Omni, false) => run::<f32, _, _, _>(c, Omnidirectional, out, probe),
        (Plat::Omni, true) => run::<f64, _, _, _>(c, Omnidirectional, out, probe),
        (Plat::Ur5Uni, false) => run_spatial::<f32, _, _, _>(c, Unicycle::paper(), out, probe),
        (Plat::Ur5Uni, true) => run_spatial::<f64, _, _, _>(c, Unicycle::paper(), out, probe),
    }
}

/// The plant: platform pose, steering `ξ`, joints; the target is in closed form.
#[derive(Clone, Copy, Debug)]
struct Plant<T, const N: usize> {
    base: Pose<T>,
    xi: T,
    q: SVector<T, N>,
}

/// `(r_d(t), u_d(t))` of trajectory 1 with `r_d(0) = (2.6, 1, 0)`:
/// `x_d = 2.6 + (cos(πt/2) − 1)/10`, `y_d = 1 − sin(πt/2)/10`, `θ_d = 0`.
pub fn target<T: Real>(t: T) -> (Pose<T>, Vector3<T>) {
    let (s, c) = (T::pi() * T::of(0.5) * t).sincos();
    let tenth = T::of(0.1);
    let speed = T::pi() / T::of(20.0);
    let pose = Pose::new(T::of(2.6) + tenth * (c - T::one()), T::one() - tenth * s, T::zero());
    (pose, Vector3::new(-speed * s, -speed * c, T::zero()))
}

/// `(r_d(t), u_d(t))` of trajectory 2 (Table 1), in closed form, with `r_d(0) = (2.5, 1,
/// 0)`: at rest for 5 s; rotations in place, `ω_d = (π²/20) cos(π(t − t₀)/2)`, on [5, 27)
/// and [37, 59) s, each of which ends where it started (`θ_d = (π/10) sin(π(t − t₀)/2)`,
/// zero at the end); between and after them straight lines at `θ_d = 0`: `v₁ = 0.2` m/s on
/// [27, 37), `v₂ = 0.05` m/s on [59, 99), rest on [99, 105), `v₁ = −0.2` m/s on [105, 115),
/// then rest. (The cases run its first 6 s.)
pub fn target_2<T: Real>(t: T) -> (Pose<T>, Vector3<T>) {
    let at = |x: f64, y: f64| Pose::new(T::of(x), T::of(y), T::zero());
    let rest = T::of(5.0);
    if t < rest {
        return (Pose::new(T::of(2.5), T::one(), T::zero()), Vector3::zeros());
    }
    let rotation = |t0: T, x: f64, y: f64| {
        let pi = T::pi();
        let (s, c) = (pi * T::of(0.5) * (t - t0)).sincos();
        (
            Pose::new(T::of(x), T::of(y), pi / T::of(10.0) * s),
            Vector3::new(T::zero(), T::zero(), pi * pi / T::of(20.0) * c),
        )
    };
    let line = |t0: f64, x: f64, y: f64, vx: f64, vy: f64| {
        let d = t - T::of(t0);
        let pose = Pose::new(T::of(x) + T::of(vx) * d, T::of(y) + T::of(vy) * d, T::zero());
        (pose, Vector3::new(T::of(vx), T::of(vy), T::zero()))
    };
    if t < T::of(27.0) {
        rotation(rest, 2.5, 1.0)
    } else if t < T::of(37.0) {
        line(27.0, 2.5, 1.0, 0.2, 0.0)
    } else if t < T::of(59.0) {
        rotation(T::of(37.0), 4.5, 1.0)
    } else if t < T::of(99.0) {
        line(59.0, 4.5, 1.0, 0.0, 0.05)
    } else if t < T::of(105.0) {
        (at(4.5, 3.0), Vector3::zeros())
    } else if t < T::of(115.0) {
        line(105.0, 4.5, 3.0, -0.2, 0.0)
    } else {
        (at(2.5, 3.0), Vector3::zeros())
    }
}

/// The target of case `c` at `t`.
fn target_of<T: Real>(c: &Case, t: T) -> (Pose<T>, Vector3<T>) {
    match c.traj {
        Traj::One => target(t),
        Traj::Two => target_2(t),
    }
}

/// Trajectory 1 lifted, from `start`: the circle of [`target`], level, plus
/// `z = 0.05 sin(2πt/10)` m; the body twist `(ṗ, 0)` (the frame does not turn).
pub fn lifted<T: Real>(t: T, start: &Vector3<T>) -> (Pose3<T>, Vector6<T>) {
    let (planar, u) = target(t);
    let w = T::two_pi() / T::of(10.0);
    let (s, c) = (w * t).sincos();
    let a = T::of(0.05);
    let p = Vector3::new(planar.x - T::of(2.6) + start[0], planar.y - T::one() + start[1], start[2] + a * s);
    (
        Pose3::translation(p[0], p[1], p[2]),
        Vector6::new(u[0], u[1], a * w * c, T::zero(), T::zero(), T::zero()),
    )
}

/// `d(x, y, θ, ξ)/dt` of the platform under a held command.
fn platform_rate<T: Real, const N: usize>(kind: PlatformKind, s: [T; 4], cmd: &Command<T, N>) -> [T; 4] {
    let p = &cmd.platform;
    let (sn, cs) = s[2].sincos();
    let (v, v_lat, omega, xi_rate) = match kind {
        PlatformKind::Unicycle => (p.v, T::zero(), p.omega, T::zero()),
        PlatformKind::Car => (p.v, T::zero(), p.v * s[3], p.v_xi),
        PlatformKind::Omni => (p.v, p.v_lat, p.omega, T::zero()),
    };
    [v * cs - v_lat * sn, v * sn + v_lat * cs, omega, xi_rate]
}

/// One RK4 step of the platform (zero-order hold), exact Euler for the joints.
fn advance<T: Real, const N: usize>(kind: PlatformKind, plant: &mut Plant<T, N>, cmd: &Command<T, N>, dt: T) {
    let s0 = [plant.base.x, plant.base.y, plant.base.theta, plant.xi];
    let add =
        |a: [T; 4], k: [T; 4], h: T| [a[0] + k[0] * h, a[1] + k[1] * h, a[2] + k[2] * h, a[3] + k[3] * h];
    let half = dt * T::of(0.5);
    let k1 = platform_rate(kind, s0, cmd);
    let k2 = platform_rate(kind, add(s0, k1, half), cmd);
    let k3 = platform_rate(kind, add(s0, k2, half), cmd);
    let k4 = platform_rate(kind, add(s0, k3, dt), cmd);
    let sixth = dt / T::of(6.0);
    let two = T::of(2.0);
    let mut s = s0;
    for i in 0..4 {
        s[i] += sixth * (k1[i] + two * k2[i] + two * k3[i] + k4[i]);
    }
    plant.base = Pose::new(s[0], s[1], s[2]);
    plant.xi = s[3];
    plant.q += cmd.joints * dt;
}

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

fn fnv(mut h: u64, word: u64) -> u64 {
    for b in word.to_le_bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(FNV_PRIME);
    }
    h
}

/// The bits of a command's values: the platform's four, then the joints'.
fn command_words<T: Real, const N: usize>(c: &Command<T, N>) -> impl Iterator<Item = u64> + '_ {
    let p = &c.platform;
    let b = |x: T| x.as_f64().to_bits();
    [b(p.v), b(p.v_lat), b(p.omega), b(p.v_xi)].into_iter().chain(c.joints.iter().map(move |x| b(*x)))
}

/// One controller step, never inlined: the firmware's second instruction count
/// (`tests/firmware/gdbcount.py`) single-steps from this function's entry to its return.
/// One instance per scalar type and platform; in each, the steps of run (a) come first.
/// The output is written into the caller's `out`, in place, as a firmware's loop keeps it.
#[inline(never)]
pub fn controller_step<T: Real, P: Platform<T>>(
    ctrl: &mut Controller<T, P, Rpr<T>, 3>,
    meas: &Measurement<T, 3>,
    dt: T,
    out: &mut Output<T, 3>,
) -> Result<(), Rejected<T, 3>> {
    ctrl.step_into(meas, dt, out)
}

fn run<T: Real, P: Platform<T>, W: Write, Q: Probe>(
    c: &Case,
    platform: P,
    out: &mut W,
    probe: &mut Q,
) -> Outcome {
    let params = params_of::<T>(c, P::KIND);
    let Ok(mut ctrl) = Controller::new(params, platform, Rpr::paper()) else {
        let _ = writeln!(out, "E {} invalid parameters", c.name);
        return Outcome { steps: 0, rejected: 0, digest: 0, e_p: f64::NAN };
    };
    let dt = T::of(DT);
    let mut plant = Plant {
        base: Pose::new(T::zero(), T::zero(), T::zero()),
        xi: T::zero(),
        q: SVector::<T, 3>::new(T::zero(), T::of(0.35), T::zero()),
    };
    let mut digest = FNV_OFFSET;
    let mut rejected = 0;
    let mut e_p = f64::NAN;
    let mut output = Output::zero();
    for n in 0..c.steps() {
        let t = T::of(f64::from(n)) * dt;
        let (target, target_velocity) = target_of(c, t);
        let meas =
            Measurement { t, base: plant.base, steering: plant.xi, joints: plant.q, target, target_velocity };
        // The inputs are complete in memory before the probe's first reading (black_box
        // there), and pass through black_box again after it, so that no part of building
        // them falls inside the bracket and no part of the step before it; the result
        // goes through black_box before the second reading.
        let (ct, me, h, o) = (black_box(&mut ctrl), black_box(&meas), black_box(dt), black_box(&mut output));
        probe.enter();
        let result = controller_step(black_box(ct), black_box(me), black_box(h), black_box(o));
        black_box(&result);
        black_box(&output);
        probe.leave();
        match result {
            Ok(()) => e_p = output.diagnostics.e_p.norm().as_f64(),
            Err(_) => rejected += 1,
        }
        // On a rejection `output.command` is the safe command.
        let cmd = output.command;
        digest = record(c, n, digest, &cmd, out);
        advance(P::KIND, &mut plant, &cmd, dt);
    }
    finish(c, rejected, digest, e_p, out)
}

/// Folds a command into the digest and writes its `D` line when one is due.
fn record<T: Real, const N: usize, W: Write>(
    c: &Case,
    n: u32,
    mut digest: u64,
    cmd: &Command<T, N>,
    out: &mut W,
) -> u64 {
    for w in command_words(cmd) {
        digest = fnv(digest, w);
    }
    if (n + 1) % REPORT_EVERY == 0 || n + 1 == c.steps() {
        let _ = write!(out, "D {} {} {:016x}", c.name, n + 1, digest);
        for w in command_words(cmd) {
            let _ = write!(out, " {w:016x}");
        }
        let _ = writeln!(out);
    }
    digest
}

/// The case's `F` line and outcome.
fn finish<W: Write>(c: &Case, rejected: u32, digest: u64, e_p: f64, out: &mut W) -> Outcome {
    let steps = c.steps();
    let _ = writeln!(out, "F {} {steps} {rejected} {digest:016x} {:016x} {e_p:e}", c.name, e_p.to_bits());
    Outcome { steps, rejected, digest, e_p }
}

/// The spatial law's controller with the UR5.
pub type Ur5Controller<T, P> = Controller<T, P, SpatialArm<T, 6>, 6>;

/// One step of the spatial law, never inlined (as [`controller_step`]; `gdbcount.py` finds
/// `spatial_step::<T, Platform>` for the `ur5-…` cases), its output written in place.
#[inline(never)]
pub fn spatial_step<T: Real, P: Platform<T>>(
    ctrl: &mut Ur5Controller<T, P>,
    meas: &Measurement<T, 6, Spatial>,
    dt: T,
    out: &mut Output<T, 6, Spatial>,
) -> Result<(), Rejected<T, 6>>
where
    SpatialArm<T, 6>: Manipulator<T, 6, Space = Spatial>,
{
    ctrl.step_into(meas, dt, out)
}

/// The UR5's law (`r*_ed`: the target level, `0.2 m` along the flange's axis at home) and
/// the lifted trajectory's start (`(2.6, 1)` in the plane, at the target's height at home).
fn ur5<T: Real, P: Platform<T>>(platform: P) -> Option<(Ur5Controller<T, P>, Vector3<T>)>
where
    SpatialArm<T, 6>: Manipulator<T, 6, Space = Spatial>,
{
    let arm = SpatialArm::new(&Chain::ur5()).ok()?;
    let star = arm.level_target(T::of(0.2));
    let params = Params::for_arm(&arm, PaperRun::A, star).ok()?;
    let z0 = arm.kinematics(&arm.chain().home()).effector.compose(&star).translation[2];
    let ctrl = Controller::new(params, platform, arm).ok()?;
    Some((ctrl, Vector3::new(T::of(2.6), T::one(), z0)))
}

fn run_spatial<T: Real, P: Platform<T>, W: Write, Q: Probe>(
    c: &Case,
    platform: P,
    out: &mut W,
    probe: &mut Q,
) -> Outcome
where
    SpatialArm<T, 6>: Manipulator<T, 6, Space = Spatial>,
{
    let Some((mut ctrl, start)) = ur5::<T, P>(platform) else {
        let _ = writeln!(out, "E {} invalid parameters", c.name);
        return Outcome { steps: 0, rejected: 0, digest: 0, e_p: f64::NAN };
    };
    let dt = T::of(DT);
    let mut plant = Plant {
        base: Pose::new(T::zero(), T::zero(), T::zero()),
        xi: T::zero(),
        q: Chain::<T, 6>::ur5().home(),
    };
    let mut digest = FNV_OFFSET;
    let mut rejected = 0;
    let mut e_p = f64::NAN;
    let mut output = Output::zero();
    for n in 0..c.steps() {
        let t = T::of(f64::from(n)) * dt;
        let (target, target_velocity) = lifted(t, &start);
        let meas =
            Measurement { t, base: plant.base, steering: plant.xi, joints: plant.q, target, target_velocity };
        // As in `run`: the inputs complete before the first reading, the result after.
        let (ct, me, h, o) = (black_box(&mut ctrl), black_box(&meas), black_box(dt), black_box(&mut output));
        probe.enter();
        let result = spatial_step(black_box(ct), black_box(me), black_box(h), black_box(o));
        black_box(&result);
        black_box(&output);
        probe.leave();
        match result {
            Ok(()) => e_p = output.diagnostics.e_p.norm().as_f64(),
            Err(_) => rejected += 1,
        }
        // On a rejection `output.command` is the safe command.
        let cmd = output.command;
        digest = record(c, n, digest, &cmd, out);
        advance(P::KIND, &mut plant, &cmd, dt);
    }
    finish(c, rejected, digest, e_p, out)
}

/// Measures the stack a closure uses (the firmware paints the free stack and finds the
/// lowest word written).
pub trait StackProbe {
    /// Runs `f`; the bytes of stack it used below the caller's frame.
    fn measure(&mut self, f: &mut dyn FnMut()) -> usize;
}

/// Runs the closure, measures nothing (0).
#[derive(Debug)]
pub struct NoStack;

impl StackProbe for NoStack {
    fn measure(&mut self, f: &mut dyn FnMut()) -> usize {
        f();
        0
    }
}

/// Builds the controller of case `c` and takes two steps from the initial state (the first
/// initialises it); the stack of the two steps alone, measured by `stack` once the
/// controller is built (0 if it cannot be).
pub fn first_steps<S: StackProbe>(c: &Case, stack: &mut S) -> usize {
    match (c.plat, c.double) {
        (Plat::Uni, false) => one::<f32, _, _>(c, Unicycle::paper(), stack),
        (Plat::Uni, true) => one::<f64, _, _>(c, Unicycle::paper(), stack),
        (Plat::Car, false) => one::<f32, _, _>(c, car(), stack),
        (Plat::Car, true) => one::<f64, _, _>(c, car(), stack),
        (Plat::Omni, false) => one::<f32, _, _>(c, Omnidirectional, stack),
        (Plat::Omni, true) => one::<f64, _, _>(c, Omnidirectional, stack),
        (Plat::Ur5Uni, false) => one_spatial::<f32, _, _>(Unicycle::paper(), stack),
        (Plat::Ur5Uni, true) => one_spatial::<f64, _, _>(Unicycle::paper(), stack),
    }
}

/// [`one`] for the spatial law.
fn one_spatial<T: Real, P: Platform<T>, S: StackProbe>(platform: P, stack: &mut S) -> usize
where
    SpatialArm<T, 6>: Manipulator<T, 6, Space = Spatial>,
{
    if let Some((mut ctrl, start)) = ur5::<T, P>(platform) {
        let (target, target_velocity) = lifted(T::zero(), &start);
        let meas = Measurement {
            t: T::zero(),
            base: Pose::new(T::zero(), T::zero(), T::zero()),
            steering: T::zero(),
            joints: Chain::<T, 6>::ur5().home(),
            target,
            target_velocity,
        };
        return stack.measure(&mut || two_steps(&mut ctrl, &meas));
    }
    0
}

/// Two steps of `ctrl` with the same measurement (the first initialises the state).
fn two_steps<T: Real, P: Platform<T>, A: Manipulator<T, N>, const N: usize>(
    ctrl: &mut Controller<T, P, A, N>,
    meas: &Measurement<T, N, A::Space>,
) {
    for _ in 0..2 {
        let r = ctrl.step(black_box(meas), T::of(DT));
        black_box(&r);
    }
}

/// Builds the controller and takes two steps (the first initialises the state); the stack
/// of the steps alone.
fn one<T: Real, P: Platform<T>, S: StackProbe>(c: &Case, platform: P, stack: &mut S) -> usize {
    let params = params_of::<T>(c, P::KIND);
    if let Ok(mut ctrl) = Controller::new(params, platform, Rpr::paper()) {
        let (target, target_velocity) = target_of(c, T::zero());
        let meas = Measurement {
            t: T::zero(),
            base: Pose::new(T::zero(), T::zero(), T::zero()),
            steering: T::zero(),
            joints: SVector::<T, 3>::new(T::zero(), T::of(0.35), T::zero()),
            target,
            target_velocity,
        };
        return stack.measure(&mut || two_steps(&mut ctrl, &meas));
    }
    0
}
