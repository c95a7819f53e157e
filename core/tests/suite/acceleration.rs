//! The acceleration limits ([`companion_core::acceleration`]): no accepted command changes
//! faster than its limit, per component and per period, from the command accepted before
//! it (rest before the first) — closed loop on the exact plant, every platform, `f32` and
//! `f64`, random limits, periods and starts, joints near their limits; the change keeps the
//! direction of the law's (one common factor, one component on its limit); the joints never
//! reach their limits on the way (the guard's braking bound); a previous command outside the
//! guard is braked at the limit, not beyond; every bad limit is refused by name; the start
//! call is the first step, taken now; the in-place step is the step.
//!
//! Tolerances: `u⁺ = (1 − β) u_p + β u` is a few roundings from the exact value, so a
//! change may exceed `a h` by a few ulp of the commands: `4 ε (a h + |u⁺| + |u_p|)`.

use crate::common::*;
use companion_core::nalgebra::SVector;
use companion_core::{
    AccelerationLimits, Command, ControlLaw, Controller, Field, Measurement, Output, PaperRun, ParamError,
    Params, Platform, PlatformKind, Real, Rpr, Rule, State, StepError, Unicycle, VelocityLimits,
};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

/// The components a platform commands, with their limits: `(previous, new, limit)`.
fn components<T: Real>(
    kind: PlatformKind,
    prev: &Command<T, 3>,
    next: &Command<T, 3>,
    l: &AccelerationLimits<T, 3>,
) -> Vec<(f64, f64, f64)> {
    let (p, n) = (&prev.platform, &next.platform);
    let f = |a: T, b: T, c: T| (a.as_f64(), b.as_f64(), c.as_f64());
    let mut out = vec![f(p.v, n.v, l.forward)];
    match kind {
        PlatformKind::Unicycle => out.push(f(p.omega, n.omega, l.angular)),
        PlatformKind::Omni => {
            out.push(f(p.v_lat, n.v_lat, l.lateral));
            out.push(f(p.omega, n.omega, l.angular));
        }
        PlatformKind::Car => {}
    }
    for i in 0..3 {
        out.push(f(prev.joints[i], next.joints[i], l.joints[i]));
    }
    out
}

fn epsilon<T: Real>() -> f64 {
    if core::mem::size_of::<T>() == 4 {
        f64::from(f32::EPSILON)
    } else {
        f64::EPSILON
    }
}

/// Every component of `next` within its limit of `prev` over a hold of `h`; returns the
/// largest `|Δ| / (a h)` (1: a component on its limit).
fn within<T: Real>(
    kind: PlatformKind,
    prev: &Command<T, 3>,
    next: &Command<T, 3>,
    l: &AccelerationLimits<T, 3>,
    h: f64,
) -> Result<f64, TestCaseError> {
    let eps = epsilon::<T>();
    let mut largest = 0.0f64;
    for (i, (p, n, a)) in components(kind, prev, next, l).into_iter().enumerate() {
        prop_assert!(n.is_finite(), "component {i}: {n}");
        let room = a * h;
        let d = (n - p).abs();
        prop_assert!(
            d <= room + 4.0 * eps * (room + n.abs() + p.abs()),
            "component {i} changed by {d:e} from {p:e} to {n:e}; the limit allows {room:e}"
        );
        if room.is_finite() {
            largest = largest.max(d / room);
        }
    }
    Ok(largest)
}

fn limit() -> impl Strategy<Value = f64> {
    prop_oneof![1 => Just(f64::INFINITY), 4 => 0.2..5.0f64]
}

fn limits() -> impl Strategy<Value = AccelerationLimits<f64, 3>> {
    (limit(), limit(), limit(), (limit(), limit(), limit())).prop_map(|(forward, lateral, angular, j)| {
        AccelerationLimits { forward, lateral, angular, joints: SVector::<f64, 3>::new(j.0, j.1, j.2) }
    })
}

fn cast_limits<T: Real>(l: &AccelerationLimits<f64, 3>) -> AccelerationLimits<T, 3> {
    AccelerationLimits {
        forward: T::of(l.forward),
        lateral: T::of(l.lateral),
        angular: T::of(l.angular),
        joints: l.joints.map(T::of),
    }
}

/// A start: the target seen from the platform, the joints (up to 2 % of their range from a
/// limit), the period, the target's speed, the limits.
#[derive(Clone, Debug)]
struct Start {
    r_bd: V3,
    q: Q,
    dt: f64,
    speed: f64,
    limits: AccelerationLimits<f64, 3>,
}

fn start() -> impl Strategy<Value = Start> {
    ((0.5..4.0f64, -2.0..2.0f64, -PI..PI), joints_inside(0.02), 1e-3..1e-2f64, 0.0..2.0f64, limits())
        .prop_map(|((x, y, th), q, dt, speed, limits)| Start {
            r_bd: V3::new(x, y, th),
            q,
            dt,
            speed,
            limits,
        })
}

/// The case's law in `T` on platform `P` (the car with the scenario's velocity limits).
fn law<T: Real, P: Platform<T>>(platform: P, run: PaperRun, s: &Start) -> ControlLaw<T, P, Rpr<T>, 3> {
    let mut p = Params::<T, 3>::paper(run);
    p.max_time_step = T::of(1e-2);
    p.acceleration_limits = cast_limits(&s.limits);
    if P::KIND == PlatformKind::Car {
        p.velocity_limits = VelocityLimits {
            forward: T::one(),
            lateral: T::of(f64::INFINITY),
            angular: T::of(f64::INFINITY),
            alpha_rate: T::of(20.0),
            steering_rate: T::of(20.0),
        };
    }
    ControlLaw::new(p, platform, Rpr::paper()).expect("valid")
}

/// `steps` steps of the closed loop on the exact plant: every command within its limits of
/// the one before (rest before the first), every step accepted (the joints never reach a
/// limit); returns how many steps the platform's and the joints' factor acted.
fn closed_loop<T: Real, P: Platform<T>>(
    law: &ControlLaw<T, P, Rpr<T>, 3>,
    s: &Start,
    steps: usize,
) -> Result<(u32, u32), TestCaseError> {
    let kind = P::KIND;
    let speed = s.speed;
    let u_d = move |t: f64| trajectory_1(t) * speed;
    let mut plant = Plant::paper_start(s.r_bd, s.q, 0.0);
    let mut state = State::<T, 3>::new();
    let mut prev = Command::<T, 3>::zero();
    let lim = law.params().acceleration_limits;
    let (mut platform_acted, mut joints_acted) = (0, 0);
    let h = T::of(s.dt);
    for k in 0..steps {
        let meas: Measurement<T, 3> = measurement_as(&plant.measurement(&u_d));
        let out = law.step(&mut state, &meas, h).map_err(|r| {
            TestCaseError::fail(format!("step {k} rejected: {:?} (joints {:?})", r.error, plant.q))
        })?;
        let largest = within(kind, &prev, &out.command, &lim, h.as_f64())?;
        let d = &out.diagnostics;
        prop_assert!(d.platform_acceleration >= T::one() && d.joint_acceleration >= T::one());
        if d.platform_acceleration > T::one() {
            platform_acted += 1;
        }
        if d.joint_acceleration > T::one() {
            joints_acted += 1;
            // The factor acted: one component sits on its limit.
            prop_assert!(
                largest > 1.0 - 1e-3,
                "the factor acted but no component is on its limit: {largest}"
            );
        }
        prev = out.command;
        plant.advance(kind, &command_f64(&out.command), &u_d, s.dt, 1);
    }
    Ok((platform_acted, joints_acted))
}

fn all_platforms<T: Real>(s: &Start, run: PaperRun, steps: usize) -> Result<(), TestCaseError>
where
    Unicycle<T>: Platform<T>,
{
    closed_loop(&law::<T, _>(Unicycle::paper(), run, s), s, steps)?;
    closed_loop(
        &law::<T, _>(
            companion_core::CarLike::new(T::of(0.4), [T::one(), T::of(2.0), T::one()], T::of(5.0)),
            run,
            s,
        ),
        s,
        steps,
    )?;
    closed_loop(&law::<T, _>(companion_core::Omnidirectional, run, s), s, steps)?;
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// No command ever changes faster than its limit, from rest, closed loop; every step is
    /// accepted (no joint reaches its limit), every command finite; f64 and f32.
    #[test]
    fn commands_never_change_faster_than_the_limits(s in start(), k in 0..4usize) {
        let run = [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D][k];
        all_platforms::<f64>(&s, run, 400)?;
        all_platforms::<f32>(&s, run, 400)?;
    }
}

/// The paper's trajectory 1 (a) with limits above what its steady state asks for (5 m/s²,
/// 10 rad/s², 30 rad/s² on the joints; the unlimited law's largest after 20 s: 3.4 m/s²,
/// 5.7 rad/s², 20 rad/s²): the limits act in the first seconds, which ask for hundreds, and
/// the loop still converges to the unlimited law's floor.
#[test]
fn the_limits_act_and_the_loop_still_converges() {
    let s = Start {
        r_bd: V3::new(2.6, 1.0, 0.0),
        q: Q::new(0.0, 0.35, 0.0),
        dt: 1e-3,
        speed: 1.0,
        limits: AccelerationLimits {
            forward: 5.0,
            lateral: 5.0,
            angular: 10.0,
            joints: SVector::repeat(30.0),
        },
    };
    let uni = law::<f64, _>(Unicycle::paper(), PaperRun::A, &s);
    let (platform, joints) = closed_loop(&uni, &s, 20_000).expect("within the limits");
    assert!(platform > 1000 && joints > 100, "the factors acted on {platform} and {joints} steps");
    let u_d = |t: f64| trajectory_1(t);
    let mut plant = Plant::paper_start(s.r_bd, s.q, 0.0);
    let mut c = Controller { law: uni, state: State::new() };
    let mut e_p = 0.0f64;
    for k in 0..30_000 {
        let out = c.step(&plant.measurement(&u_d), 1e-3).expect("accepted");
        if k >= 20_000 {
            e_p = e_p.max(out.diagnostics.e_p.norm());
        }
        plant.advance(PlatformKind::Unicycle, &out.command, &u_d, 1e-3, 1);
    }
    assert!(e_p < 1e-5, "‖e_p‖ up to {e_p:e} from 20 to 30 s");
}

/// With the platform's limits only, the platform command moves from the previous one
/// straight towards the unlimited law's: one common factor, one component on its limit.
#[test]
fn the_platform_command_keeps_its_direction() {
    let free = unicycle_law(Params::paper(PaperRun::A));
    let mut p = Params::paper(PaperRun::A);
    p.acceleration_limits.forward = 0.5;
    p.acceleration_limits.angular = 1.0;
    let limited = unicycle_law(p);
    // From a running state: the same step of both laws, after 50 steps of the limited one.
    let u_d = |t: f64| trajectory_1(t);
    let mut plant = Plant::paper_start(V3::new(2.6, 1.0, 0.0), Q::new(0.0, 0.35, 0.0), 0.0);
    let mut st = State::new();
    for _ in 0..50 {
        let out = limited.step(&mut st, &plant.measurement(&u_d), 1e-3).expect("accepted");
        plant.advance(PlatformKind::Unicycle, &out.command, &u_d, 1e-3, 1);
    }
    let prev = st.sent(0).expect("sent").platform;
    let meas = plant.measurement(&u_d);
    let (mut a, mut b) = (st, st);
    let u = free.step(&mut a, &meas, 1e-3).expect("accepted").command.platform;
    let out = limited.step(&mut b, &meas, 1e-3).expect("accepted");
    let (l, d) = (out.command.platform, &out.diagnostics);
    let beta = 1.0 / d.platform_acceleration;
    assert!(beta < 1.0, "the limits act at t = 50 ms");
    for (x_prev, x_free, x) in [(prev.v, u.v, l.v), (prev.omega, u.omega, l.omega)] {
        let want = x_prev + beta * (x_free - x_prev);
        assert!((x - want).abs() <= 1e-12 * (1.0 + want.abs()), "{x} vs {want}");
    }
    let on_limit = ((l.v - prev.v).abs() / 0.5e-3).max((l.omega - prev.omega).abs() / 1e-3);
    assert!((on_limit - 1.0).abs() < 1e-9, "{on_limit}");
}

/// A previous joint command outside the joint guard (the joint measured much closer to its
/// limit than the commands took it: the robot did not follow): no common factor keeps both
/// limits, and the acceleration limits win — that joint brakes by exactly `a h`, no more,
/// every other within its limit too — rather than stop at once.
#[test]
fn a_previous_command_outside_the_guard_is_braked_at_the_limit() {
    let a = 2.0;
    let mut p = Params::paper(PaperRun::A);
    p.acceleration_limits.joints = SVector::repeat(a);
    let law = unicycle_law(p);
    let u_d = |t: f64| trajectory_1(t);
    let mut plant = Plant::paper_start(V3::new(2.6, 1.0, 0.0), Q::new(0.0, 0.35, 0.0), 0.0);
    let mut st = State::new();
    // Run until some joint moves at 0.05 (rad or m)/s or more.
    let (i, u_p) = (0..2000)
        .find_map(|_| {
            let out = law.step(&mut st, &plant.measurement(&u_d), 1e-3).expect("accepted");
            plant.advance(PlatformKind::Unicycle, &out.command, &u_d, 1e-3, 1);
            let j = out.command.joints.iamax();
            (out.command.joints[j].abs() >= 0.05).then_some((j, out.command.joints))
        })
        .expect("a joint moves");
    // That joint is now measured 10 µm from the limit it moves towards.
    let mut meas = plant.measurement(&u_d);
    meas.joints[i] = if u_p[i] > 0.0 { UPPER[i] - 1e-5 } else { LOWER[i] + 1e-5 };
    let out = law.step(&mut st, &meas, 1e-3).expect("accepted");
    let u = out.command.joints;
    let braked = u_p[i] - a * 1e-3 * u_p[i].signum();
    assert!(
        (u[i] - braked).abs() <= 1e-12,
        "joint {i}: {} to {}, braked at the limit to {braked}",
        u_p[i],
        u[i]
    );
    for j in 0..3 {
        assert!((u[j] - u_p[j]).abs() <= a * 1e-3 * (1.0 + 1e-12), "joint {j}: {} to {}", u_p[j], u[j]);
    }
    assert!(out.diagnostics.joint_acceleration > 1.0 && out.command.is_finite());
}

/// The safe command of a rejected step stops the robot at once, outside the limits, and
/// leaves the state as it was; the start call resumes from rest: its command is within
/// `a h` of zero.
#[test]
fn a_safe_stop_and_the_start_call_after_it() {
    let mut p = Params::paper(PaperRun::A);
    p.acceleration_limits =
        AccelerationLimits { forward: 1.0, lateral: 1.0, angular: 2.0, joints: SVector::repeat(2.0) };
    let mut c = Controller::new(p, Unicycle::paper(), Rpr::paper()).expect("valid");
    let u_d = |t: f64| trajectory_1(t);
    let mut plant = Plant::paper_start(V3::new(2.6, 1.0, 0.0), Q::new(0.0, 0.35, 0.0), 0.0);
    let mut last = Command::zero();
    for _ in 0..500 {
        let out = c.step(&plant.measurement(&u_d), 1e-3).expect("accepted");
        last = out.command;
        plant.advance(PlatformKind::Unicycle, &out.command, &u_d, 1e-3, 1);
    }
    assert!(last.platform.v.abs() + last.platform.omega.abs() > 0.1, "moving: {:?}", last.platform);
    let before = c.state;
    let bad = Measurement { t: f64::NAN, ..plant.measurement(&u_d) };
    let r = c.step(&bad, 1e-3).expect_err("rejected");
    assert_eq!((r.error, r.command), (StepError::NonFinite(Field::Time), Command::zero()));
    assert_eq!(c.state, before);
    // The robot was stopped: the start call counts from rest.
    let out = c.start(&plant.measurement(&u_d), 1e-3, 0.0).expect("accepted");
    within::<f64>(PlatformKind::Unicycle, &Command::zero(), &out.command, &p.acceleration_limits, 1e-3)
        .expect("within the limits of rest");
    assert!(out.diagnostics.platform_acceleration > 1.0);
}

/// The start call is the first step, taken now: on a fresh controller the same output and
/// state as the first `step`, bit for bit; on a running one a fresh start (α kept); a bad
/// measurement is rejected with the state as it was and the safe command in `out`.
#[test]
fn the_start_call_is_the_first_step() {
    fn check<P: Platform<f64>>(law: ControlLaw<f64, P, Rpr<f64>, 3>) {
        let u_d = |t: f64| trajectory_1(t);
        let plant = Plant::paper_start(V3::new(2.6, 1.0, 0.0), Q::new(0.0, 0.35, 0.0), 0.0);
        let meas = plant.measurement(&u_d);
        let (mut a, mut b) =
            (Controller { law, state: State::new() }, Controller { law, state: State::new() });
        a.state.alpha[0] = 0.3;
        b.state.alpha[0] = 0.3;
        let stepped = a.step(&meas, 1e-3).expect("accepted");
        let mut started = Output::zero();
        b.start_into(&meas, 1e-3, 0.0, &mut started).expect("accepted");
        assert_eq!(stepped, started);
        assert_eq!(a.state, b.state);
        // Later: a fresh start, α kept.
        let later = Measurement { t: 0.5, ..meas };
        b.step(&Measurement { t: 1e-3, ..meas }, 1e-3).expect("accepted");
        let alpha = b.state.alpha;
        let again = b.start(&later, 1e-3, 0.0).expect("accepted");
        let mut fresh = Controller { law, state: State::new() };
        fresh.state.alpha = alpha;
        assert_eq!(again, fresh.step(&later, 1e-3).expect("accepted"));
        assert_eq!(b.state, fresh.state);
        // A bad measurement: rejected, the state kept, the safe command written.
        let kept = b.state;
        let mut out = again;
        let r = b.start_into(&Measurement { joints: Q::new(0.0, 0.0, 0.0), ..meas }, 1e-3, 0.0, &mut out);
        assert_eq!(r.expect_err("at the limit").error, StepError::JointAtLimit(1));
        assert_eq!(out.command, Command::zero());
        assert_eq!(b.state, kept);
    }
    check(unicycle_law(Params::paper(PaperRun::B)));
    check(car_law(Params::paper(PaperRun::C)));
    check(omni_law(Params::paper(PaperRun::A)));
}

/// The in-place step is the step: the same outputs and states bit for bit over a run, f32
/// and f64; a rejected step writes the safe command into `out`.
#[test]
fn the_in_place_step_is_the_step() {
    fn run<T: Real>() {
        let law = ControlLaw::new(Params::<T, 3>::paper(PaperRun::B), Unicycle::paper(), Rpr::paper())
            .expect("valid");
        let u_d = |t: f64| trajectory_1(t);
        let mut plant = Plant::paper_start(V3::new(2.6, 1.0, 0.0), Q::new(0.0, 0.35, 0.0), 0.0);
        let (mut a, mut b) =
            (Controller { law, state: State::new() }, Controller { law, state: State::new() });
        let mut out = Output::zero();
        for _ in 0..300 {
            let meas: Measurement<T, 3> = measurement_as(&plant.measurement(&u_d));
            let by_value = a.step(&meas, T::of(1e-3)).expect("accepted");
            b.step_into(&meas, T::of(1e-3), &mut out).expect("accepted");
            assert_eq!(by_value, out);
            assert_eq!(a.state, b.state);
            plant.advance(PlatformKind::Unicycle, &command_f64(&out.command), &u_d, 1e-3, 1);
        }
        let bad = Measurement { t: T::of(f64::NAN), ..measurement_as(&plant.measurement(&u_d)) };
        assert!(b.step_delayed_into(&bad, T::of(1e-3), T::zero(), &mut out).is_err());
        assert_eq!(out.command, Command::zero());
    }
    run::<f64>();
    run::<f32>();
}

/// Every bad limit is refused, named with its joint; `+∞` is no limit.
#[test]
fn bad_limits_are_refused_by_name() {
    type L = AccelerationLimits<f64, 3>;
    type Case = (fn(&mut L), ParamError);
    let cases: Vec<Case> = vec![
        (|l| l.forward = f64::NAN, ParamError::new("acceleration_limits.forward", Rule::NonFinite)),
        (|l| l.forward = 0.0, ParamError::new("acceleration_limits.forward", Rule::NotPositive)),
        (|l| l.lateral = -1.0, ParamError::new("acceleration_limits.lateral", Rule::NotPositive)),
        (|l| l.lateral = f64::NAN, ParamError::new("acceleration_limits.lateral", Rule::NonFinite)),
        (|l| l.angular = -0.0, ParamError::new("acceleration_limits.angular", Rule::NotPositive)),
        (
            |l| l.angular = f64::NEG_INFINITY,
            ParamError::new("acceleration_limits.angular", Rule::NotPositive),
        ),
        (|l| l.joints[0] = f64::NAN, ParamError::joint("acceleration_limits.joints", 0, Rule::NonFinite)),
        (|l| l.joints[2] = 0.0, ParamError::joint("acceleration_limits.joints", 2, Rule::NotPositive)),
        (|l| l.joints[1] = -3.0, ParamError::joint("acceleration_limits.joints", 1, Rule::NotPositive)),
    ];
    for (i, (change, want)) in cases.into_iter().enumerate() {
        let mut p = Params::<f64, 3>::paper(PaperRun::A);
        change(&mut p.acceleration_limits);
        assert_eq!(p.validate(), Err(want), "case {i}");
        let got = ControlLaw::new(p, Unicycle::paper(), Rpr::paper()).map(|_| ()).expect_err("refused");
        assert_eq!(got, want, "case {i} through ControlLaw::new");
        let msg = got.to_string();
        assert!(msg.contains(want.param), "{msg}");
        // The same in f32.
        let mut q = Params::<f32, 3>::paper(PaperRun::A);
        q.acceleration_limits = cast_limits(&p.acceleration_limits);
        assert_eq!(q.validate(), Err(want), "case {i} in f32");
    }
    let mut p = Params::<f64, 3>::paper(PaperRun::A);
    p.acceleration_limits = AccelerationLimits {
        forward: 1e-9,
        lateral: f64::INFINITY,
        angular: 1e9,
        joints: SVector::repeat(f64::INFINITY),
    };
    assert_eq!(p.validate(), Ok(()));
}
