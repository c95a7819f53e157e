//! Bad input (SPEC §6): no measurement, state or time step can make a step panic or emit a
//! non-finite command; a rejected step answers the safe command (all velocities zero) and
//! leaves the state exactly as it was; and each kind of bad input gets its own
//! [`StepError`]. For the three platforms, in f64 and f32, without and with velocity and
//! acceleration limits.
//!
//! The property tests draw every scalar either from a valid point or from any bit pattern
//! (NaN with payloads, ±∞, subnormals, ±0, the largest values), so that both the early
//! checks and the deep arithmetic are reached with garbage.

use crate::common::*;
use companion_core::nalgebra::{SVector, Vector2, Vector3};
use companion_core::{
    AccelerationLimits, CarLike, Command, ControlLaw, Field, Measurement, Omnidirectional, PaperRun, Params,
    Platform, Pose, Real, Rpr, State, StepError, Unicycle, VelocityLimits,
};
use proptest::prelude::*;

/// Any f64: all classes, raw bits, f32 bits (f32 subnormals and NaN payloads), specials.
fn wild() -> BoxedStrategy<f64> {
    prop_oneof![
        proptest::num::f64::ANY,
        any::<u64>().prop_map(f64::from_bits),
        any::<u32>().prop_map(|b| f64::from(f32::from_bits(b))),
        prop::sample::select(vec![
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            5e-324,
            -5e-324,
            1e-310,
            f64::MAX,
            f64::MIN,
            1e300,
            -1e300,
            3.5e38,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            -f64::NAN,
            f64::EPSILON,
        ]),
        -1e3..1e3f64,
    ]
    .boxed()
}

/// A value from a valid point or (one time in eight) anything: with 14 measured scalars,
/// about 15 % of the cases are fully valid and a third have exactly one bad value, so
/// both the checks and the arithmetic past them see garbage.
fn maybe(valid: f64) -> BoxedStrategy<f64> {
    prop_oneof![7 => Just(valid), 1 => wild()].boxed()
}

fn maybe3(v: Vector3<f64>) -> impl Strategy<Value = Vector3<f64>> {
    (maybe(v[0]), maybe(v[1]), maybe(v[2])).prop_map(|(a, b, c)| Vector3::new(a, b, c))
}

fn maybe_pose(p: Pose<f64>) -> impl Strategy<Value = Pose<f64>> {
    (maybe(p.x), maybe(p.y), maybe(p.theta)).prop_map(|(a, b, c)| Pose::new(a, b, c))
}

#[derive(Clone, Copy, Debug)]
struct Case {
    meas: Measurement<f64, 3>,
    state: State<f64, 3>,
    dt: f64,
}

/// Measurements with garbage fields; a valid, fresh or garbage state; any time step.
fn case() -> impl Strategy<Value = Case> {
    point(0.0).prop_flat_map(|pt| {
        let m = pt.meas;
        let s = pt.state;
        let meas = (
            maybe(m.t),
            maybe_pose(m.base),
            maybe(m.steering),
            maybe3(m.joints),
            maybe_pose(m.target),
            maybe3(m.target_velocity),
        )
            .prop_map(|(t, base, steering, joints, target, target_velocity)| Measurement {
                t,
                base,
                steering,
                joints,
                target,
                target_velocity,
            });
        let state = prop_oneof![
            Just(s),
            Just(State::new()),
            (maybe(s.alpha[0]), maybe3(s.q_hat), maybe(s.psi), maybe_pose(s.r_tilde), maybe(s.t0)).prop_map(
                move |(a, q_hat, psi, r_tilde, t0)| {
                    let mut st = s;
                    st.alpha = Vector2::new(a, s.alpha[1]);
                    st.q_hat = q_hat;
                    st.psi = psi;
                    st.sigma = SVector::repeat(psi);
                    st.r_tilde = r_tilde;
                    st.t0 = t0;
                    st.initialized = true;
                    st
                }
            ),
        ];
        let dt = prop_oneof![4 => Just(1e-3), 2 => 0.0..0.12f64, 1 => wild()];
        (meas, state, dt).prop_map(|(meas, state, dt)| Case { meas, state, dt }).boxed()
    })
}

/// The state's scalars as bits (NaN payloads included), to compare "exactly as it was".
fn bits<T: Real>(s: &State<T, 3>) -> Vec<u64> {
    let mut v: Vec<f64> = Vec::new();
    v.extend(s.alpha.iter().map(|x| x.as_f64()));
    v.extend(s.q_hat.iter().map(|x| x.as_f64()));
    v.push(s.psi.as_f64());
    v.extend(s.sigma.iter().map(|x| x.as_f64()));
    v.extend([s.r_tilde.x, s.r_tilde.y, s.r_tilde.theta, s.t0].iter().map(|x| x.as_f64()));
    let mut out: Vec<u64> = v.iter().map(|x| x.to_bits()).collect();
    out.push(u64::from(s.initialized));
    out
}

fn cast_state<T: Real>(s: &State<f64, 3>) -> State<T, 3> {
    s.cast()
}

fn never_panics_never_non_finite<T: Real, P: Platform<T>>(
    law: &ControlLaw<T, P, Rpr<T>, 3>,
    c: &Case,
) -> Result<(), TestCaseError> {
    let meas: Measurement<T, 3> = measurement_as(&c.meas);
    let mut state = cast_state::<T>(&c.state);
    let before = bits(&state);
    let limits = law.params().velocity_limits;
    match law.step(&mut state, &meas, T::of(c.dt)) {
        Ok(out) => {
            prop_assert!(out.command.is_finite(), "non-finite command {:?}", out.command);
            prop_assert!(state.initialized);
            // The evolving quantities the law integrates are finite after an accepted step.
            let finite = state.alpha.iter().chain(state.q_hat.iter()).all(|x| x.finite())
                && state.psi.finite()
                && state.r_tilde.is_finite();
            prop_assert!(finite, "non-finite state after an accepted step: {:?}", state);
            let p = &out.command.platform;
            let within = |x: T, l: T| x.abs() <= l * T::of(1.0 + 1e-6);
            prop_assert!(within(p.v, limits.forward));
            match P::KIND {
                companion_core::PlatformKind::Unicycle => prop_assert!(within(p.omega, limits.angular)),
                companion_core::PlatformKind::Omni => {
                    prop_assert!(within(p.v_lat, limits.lateral) && within(p.omega, limits.angular));
                }
                companion_core::PlatformKind::Car => prop_assert!(within(p.v_xi, limits.steering_rate)),
            }
            for a in out.diagnostics.alpha_rate.iter() {
                prop_assert!(within(*a, limits.alpha_rate));
            }
        }
        Err(rejected) => {
            prop_assert_eq!(rejected.command, Command::zero());
            prop_assert_eq!(bits(&state), before, "state changed by a rejected step ({:?})", rejected.error);
        }
    }
    Ok(())
}

fn run(k: usize) -> PaperRun {
    [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D][k]
}

fn params<T: Real>(k: usize, lim: bool) -> Params<T, 3> {
    let mut p = Params::<T, 3>::paper(run(k));
    if lim {
        // Limits that bind sometimes, so that the saturated path sees garbage too.
        p.velocity_limits = VelocityLimits {
            forward: T::of(0.5),
            lateral: T::of(0.5),
            angular: T::one(),
            alpha_rate: T::of(5.0),
            steering_rate: T::of(5.0),
        };
        // And acceleration limits that bind from rest (the fresh states), on every component.
        p.acceleration_limits = AccelerationLimits {
            forward: T::one(),
            lateral: T::one(),
            angular: T::of(2.0),
            joints: SVector::repeat(T::of(5.0)),
        };
        // And the heading filter, whose lag garbage also reaches.
        p.secondary.heading_filter = Some(companion_core::HeadingFilter { rate: T::of(0.1), xi: T::of(0.2) });
    }
    p
}

fn uni<T: Real>(k: usize, lim: bool) -> ControlLaw<T, Unicycle<T>, Rpr<T>, 3> {
    ControlLaw::new(params(k, lim), Unicycle::paper(), Rpr::paper()).expect("valid")
}

fn carl<T: Real>(k: usize, lim: bool) -> ControlLaw<T, CarLike<T>, Rpr<T>, 3> {
    ControlLaw::new(
        params(k, lim),
        CarLike::new(T::of(0.4), [T::one(), T::of(2.0), T::one()], T::of(10.0)),
        Rpr::paper(),
    )
    .expect("valid")
}

fn omni<T: Real>(k: usize, lim: bool) -> ControlLaw<T, Omnidirectional, Rpr<T>, 3> {
    ControlLaw::new(params(k, lim), Omnidirectional, Rpr::paper()).expect("valid")
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn arbitrary_input_f64(c in case(), k in 0usize..4, lim in any::<bool>()) {
        never_panics_never_non_finite(&uni::<f64>(k, lim), &c)?;
        never_panics_never_non_finite(&carl::<f64>(k, lim), &c)?;
        never_panics_never_non_finite(&omni::<f64>(k, lim), &c)?;
    }

    #[test]
    fn arbitrary_input_f32(c in case(), k in 0usize..4, lim in any::<bool>()) {
        never_panics_never_non_finite(&uni::<f32>(k, lim), &c)?;
        never_panics_never_non_finite(&carl::<f32>(k, lim), &c)?;
        never_panics_never_non_finite(&omni::<f32>(k, lim), &c)?;
    }
}

// ---------------------------------------------------------------------------------------
// Each bad input gets its own error, the safe command, and an untouched state.

fn valid_meas<T: Real>() -> Measurement<T, 3> {
    Measurement {
        t: T::of(1.0),
        base: Pose::new(T::of(0.1), T::of(-0.2), T::of(0.3)),
        steering: T::of(0.2),
        joints: SVector::<T, 3>::new(T::of(0.1), T::of(0.4), T::of(-0.2)),
        target: Pose::new(T::of(1.8), T::of(0.5), T::of(0.1)),
        target_velocity: Vector3::new(T::of(0.1), T::of(-0.1), T::of(0.05)),
    }
}

fn expect_error<T: Real, P: Platform<T>>(
    law: &ControlLaw<T, P, Rpr<T>, 3>,
    meas: &Measurement<T, 3>,
    dt: T,
    want: StepError,
) {
    // On a fresh state and on one that has run.
    let mut warm = State::new();
    law.step(&mut warm, &valid_meas(), T::of(1e-3)).expect("the valid measurement is accepted");
    for mut state in [State::new(), warm] {
        let before = bits(&state);
        let r = law.step(&mut state, meas, dt).expect_err("must be rejected");
        assert_eq!(r.error, want, "{:?} / {meas:?} / dt {dt:?}", P::KIND);
        assert_eq!(r.command, Command::zero());
        assert_eq!(bits(&state), before, "state changed by a rejected step");
        assert!(!format!("{r}").is_empty());
    }
}

fn typed_errors<T: Real, P: Platform<T>>(law: &ControlLaw<T, P, Rpr<T>, 3>) {
    let m = valid_meas::<T>();
    let ok = |meas: &Measurement<T, 3>, dt: T| law.step(&mut State::new(), meas, dt);
    assert!(ok(&m, T::of(1e-3)).is_ok());

    // The time step.
    let max = law.params().max_time_step;
    for dt in [T::zero(), -T::zero(), T::of(-1e-3), T::of(f64::NAN), T::of(f64::INFINITY), max * T::of(1.001)]
    {
        expect_error(law, &m, dt, StepError::BadTimeStep);
    }
    assert!(ok(&m, max).is_ok(), "dt = max_time_step is accepted");

    // Non-finite fields.
    let dt = T::of(1e-3);
    for bad in [T::of(f64::NAN), T::of(f64::INFINITY), T::of(f64::NEG_INFINITY)] {
        expect_error(law, &Measurement { t: bad, ..m }, dt, StepError::NonFinite(Field::Time));
        for k in 0..3 {
            let mut p = m.base;
            let mut v = p.to_vector();
            v[k] = bad;
            p = Pose::from_vector(&v);
            expect_error(law, &Measurement { base: p, ..m }, dt, StepError::NonFinite(Field::BasePose));
            expect_error(law, &Measurement { target: p, ..m }, dt, StepError::NonFinite(Field::TargetPose));
            let mut q = m.joints;
            q[k] = bad;
            expect_error(law, &Measurement { joints: q, ..m }, dt, StepError::NonFinite(Field::Joints));
            let mut u = m.target_velocity;
            u[k] = bad;
            expect_error(
                law,
                &Measurement { target_velocity: u, ..m },
                dt,
                StepError::NonFinite(Field::TargetVelocity),
            );
        }
        let steer = Measurement { steering: bad, ..m };
        if P::KIND == companion_core::PlatformKind::Car {
            expect_error(law, &steer, dt, StepError::NonFinite(Field::Steering));
        } else {
            // Only the car measures a steering angle.
            assert!(ok(&steer, dt).is_ok());
        }
    }

    // A negative or backward time is not an error (StepError::NonFinite's documentation).
    assert!(ok(&Measurement { t: T::of(-5.0), ..m }, dt).is_ok());

    // Joints at and beyond their limits.
    let lim = law.params().joint_limits;
    for i in 0..3 {
        for q_i in
            [lim.lower[i], lim.upper[i], lim.lower[i] - T::of(0.1), lim.upper[i] + T::of(0.1), T::of(1e30)]
        {
            let mut q = m.joints;
            q[i] = q_i;
            expect_error(law, &Measurement { joints: q, ..m }, dt, StepError::JointAtLimit(i as u8));
        }
        // Just inside is accepted.
        let mut q = m.joints;
        q[i] = lim.upper[i] - T::of(1e-3);
        assert!(ok(&Measurement { joints: q, ..m }, dt).is_ok());
    }
}

/// q₂ ≤ 0 is the RPR arm's singularity: with the paper's limits (q₂ ∈ (0, 0.7)) it is a
/// joint at its limit; with limits that allow q₂ ≤ 0 it is `SingularArm`.
fn singular_arm<T: Real, P: Platform<T>>(platform: P) {
    let mut p = Params::<T, 3>::paper(PaperRun::C);
    p.joint_limits.lower[1] = T::of(-0.7);
    p.secondary.weight = companion_core::Weight::Constant(T::of(0.5));
    let law = ControlLaw::new(p, platform, Rpr::paper()).expect("valid");
    let m = valid_meas::<T>();
    for q2 in [T::zero(), -T::zero(), T::of(-0.1), T::of(-1e-30)] {
        let mut q = m.joints;
        q[1] = q2;
        expect_error(&law, &Measurement { joints: q, ..m }, T::of(1e-3), StepError::SingularArm);
    }
    let mut q = m.joints;
    q[1] = T::of(1e-3);
    assert!(law.step(&mut State::new(), &Measurement { joints: q, ..m }, T::of(1e-3)).is_ok());
}

#[test]
fn typed_errors_all_platforms_f64() {
    for k in 0..4 {
        typed_errors(&uni::<f64>(k, false));
        typed_errors(&carl::<f64>(k, true));
        typed_errors(&omni::<f64>(k, false));
    }
    singular_arm::<f64, _>(Unicycle::paper());
    singular_arm::<f64, _>(CarLike::new(0.4, [1.0, 2.0, 1.0], 10.0));
    singular_arm::<f64, _>(Omnidirectional);
}

#[test]
fn typed_errors_all_platforms_f32() {
    for k in 0..4 {
        typed_errors(&uni::<f32>(k, false));
        typed_errors(&carl::<f32>(k, true));
        typed_errors(&omni::<f32>(k, false));
    }
    singular_arm::<f32, _>(Unicycle::paper());
    singular_arm::<f32, _>(CarLike::new(0.4, [1.0, 2.0, 1.0], 10.0));
    singular_arm::<f32, _>(Omnidirectional);
}

/// The owning wrapper: a rejected step keeps the state; `reset` forgets it.
#[test]
fn controller_wrapper_keeps_state_on_rejection() {
    let mut c = companion_core::Controller::new(
        Params::<f64, 3>::paper(PaperRun::B),
        Unicycle::paper(),
        Rpr::paper(),
    )
    .expect("valid");
    let m = valid_meas::<f64>();
    c.step(&m, 1e-3).expect("valid");
    let before = c.state;
    let r = c.step(&Measurement { t: f64::NAN, ..m }, 1e-3).unwrap_err();
    assert_eq!(r.error, StepError::NonFinite(Field::Time));
    assert_eq!(c.state, before);
    c.reset();
    assert!(!c.state.initialized);
}
