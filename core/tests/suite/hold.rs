//! The hold-aware discretisation ([`Discretisation::Midpoint`], the default) by its own
//! properties, with the robot moved between steps by the exact kinematics of a held command
//! (the SE(2) exponential of `common`, written independently of the core):
//!
//! - over one hold `e_m` follows `e_{k+1} = (1 − gh/2)/(1 + gh/2) e_k` to third order in `h`
//!   (the residual, its `h⁴` term removed by Richardson extrapolation, shrinks ~8× when `h`
//!   halves): the discretisation is second order;
//! - a delayed step is the step the robot would get from a measurement taken when the
//!   command starts to act (the commands in flight are predicted exactly);
//! - no lock-out: from any state, however extreme, a valid measurement is accepted at once,
//!   and the state stays bounded;
//! - the turn-per-step bound, the saturation of enormous commands, and bad delays.

use crate::common::*;
use companion_core::nalgebra::{SMatrix, Vector2};
use companion_core::{
    wrap_angle, CarLike, Command, ControlLaw, Discretisation, Measurement, Omnidirectional, PaperRun, Params,
    Platform, PlatformKind, Real, Rpr, State, StepError, Unicycle, VelocityLimits,
};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

/// The paper's parameters with the hold-aware default and without the regularisation
/// `Γ(t)` (so that `e_m` depends on `q` and `r_bd` only and can be evaluated anywhere).
fn midpoint(run: PaperRun) -> Params<f64, 3> {
    let mut p = Params::paper(run);
    assert_eq!(p.discretisation, Discretisation::Midpoint, "the default");
    p.primary.regularisation_gain = 0.0;
    p
}

/// `e_m` at a measurement, by the law's sampled twin (which evaluates at the measurement).
fn e_m_at<P: Platform<f64>>(
    law: &ControlLaw<f64, P, Rpr<f64>, 3>,
    state: &State<f64, 3>,
    m: &Measurement<f64, 3>,
) -> Q {
    let mut p = *law.params();
    p.discretisation = Discretisation::Sampled;
    let sampled = ControlLaw::new(p, *law.platform(), *law.arm()).expect("valid");
    let mut st = *state;
    sampled.step(&mut st, m, 1e-3).map(|o| o.diagnostics.e_m).unwrap_or(Q::repeat(f64::NAN))
}

/// The measurement after holding `c` for `h` seconds: joints linear, base along the
/// exponential of its body twist, target along the exponential of `u_d` (constant).
fn advance(kind: PlatformKind, m: &Measurement<f64, 3>, c: &Command<f64, 3>, h: f64) -> Measurement<f64, 3> {
    let u_b = base_velocity(kind, c, m.steering);
    Measurement {
        t: m.t + h,
        base: pose(&flow(&v3(&m.base), &u_b, h)),
        joints: m.joints + c.joints * h,
        target: pose(&flow(&v3(&m.target), &m.target_velocity, h)),
        ..*m
    }
}

/// A state ready for a constant target twist: the last measured target velocity equal to
/// the current one one period ago (so the extrapolation sees no acceleration).
fn steady(pt: &Point, h: f64) -> State<f64, 3> {
    let mut st = pt.state;
    st.last_t = pt.meas.t - h;
    st.last_target_velocity = pt.meas.target_velocity;
    st.last_target_rate = V3::zeros();
    st
}

/// The residual `e_m(t_{k+1}) − P e_m(t_k)` of the step that starts 20 ms after `pt` (steps
/// of `h`), with `P = (1 − gh/2)/(1 + gh/2)`, and the scale of `e_m`. The steps before give
/// it a guess (the previous command) that is one period old, as in a running loop, and the
/// same time of the transient for every `h`.
fn residual<P: Platform<f64>>(
    law: &ControlLaw<f64, P, Rpr<f64>, 3>,
    pt: &Point,
    h: f64,
) -> Result<(Q, f64), TestCaseError> {
    let warm = (0.02 / h).round() as usize;
    let kind = kind_of::<P>();
    let mut st = steady(pt, h);
    let mut m = pt.meas;
    let mut e1 = Q::zeros();
    for k in 0..=warm {
        if k == warm {
            e1 = e_m_at(law, &st, &m);
        }
        let o = law.step(&mut st, &m, h).map_err(|r| TestCaseError::reject(format!("{:?}", r.error)))?;
        let d = &o.diagnostics;
        // The sampling bounds (turn per step, joint guard) are not the law; skip where they act.
        prop_assume!(d.saturation == 1.0 && d.joint_scale == 1.0 && d.condition < 1e3);
        m = advance(kind, &m, &o.command, h);
    }
    let e2 = e_m_at(law, &st, &m);
    let g = law.params().primary.gain[0];
    let pade = (1.0 - g * h / 2.0) / (1.0 + g * h / 2.0);
    Ok((e2 - e1 * pade, e1.amax().max(1.0)))
}

/// Third order: the residual is `R(h) = a h³ + b h⁴ + O(h⁵)`.
///
/// The raw ratio `R(h)/R(h/2) = 8 (1 + ρ)/(1 + ρ/2)`, `ρ = b h/a`, is 8 only where the
/// third-order term dominates at 1 ms; at the points where `a` happens to be small it is
/// not (a run (b) point with Ψ = 0.134 gave 5.7 in CI). Measured over 5 462 points of this
/// strategy: the raw ratio down to 6.59, moving to 7.36 and 7.69 at 0.5 and 0.25 ms — its
/// distance from 8 halving with `h`, the signature of the `h⁴` term; rounding would make it
/// worse as `h` shrinks (the residuals there, ~10⁻¹¹, are far above it). So the `h⁴` term is
/// removed first, with a third period (Richardson): `16 R(h/2) − R(h) = a h³ + O(h⁵)`, and
/// the ratio of that for `h` and `h/2` must be ~8 — measured 7.98 to 8.14 at those points;
/// larger elsewhere (to ~500 where `a` nearly vanishes: the residual then falls faster than
/// third order, which the claim allows). Asserted > 6.
///
/// The periods are 0.5, 0.25 and 0.125 ms, not 1, 0.5, 0.25 ms: the claim is asymptotic,
/// and at 1 ms some points are not yet in its range — the series in `h` has not converged,
/// so no fixed number of its terms describes `R(1 ms)`. Seed `0d117ede…` (omnidirectional,
/// run (d), Ψ = 0.080, `r_bd = (1.495, 0.095, 0.012)`, `u_d = (−0.035, 0.174, −0.115)`):
/// `R = 3.2e−9, 2.4e−10, 3.0e−11, 3.7e−12, 4.7e−13` at 1 ms … 62.5 µs, raw ratios 13.4,
/// then 7.99, 8.00, 8.00; without the `h⁴` term 5.59 at 1 ms, then 7.999 and 8.004 on every
/// component — third order, with `R(1 ms)` off its asymptote. Over 20 000 cases (59 324
/// evaluations of this function, both platforms) the 1 ms ratio fell to ≤ 6 five times
/// (2.82 to 4.90, all omnidirectional, all ~8.00 one halving lower); from 0.5 ms its minimum
/// is 7.82. The rounding floor moves with the periods (the residual is 8× smaller).
fn order<P: Platform<f64>>(law: &ControlLaw<f64, P, Rpr<f64>, 3>, pt: &Point) -> Result<(), TestCaseError> {
    let (r0, scale) = residual(law, pt, 5e-4)?;
    let (r1, _) = residual(law, pt, 2.5e-4)?;
    let (r2, _) = residual(law, pt, 1.25e-4)?;
    // Below ~1e-9 of the scale at 1 ms (1.25e-10 at 0.5 ms) rounding (amplified by ∂e_m/∂q)
    // disturbs the ratio.
    prop_assume!(r0.amax() > 1.25e-10 * scale);
    let (a0, a1) = (r1 * 16.0 - r0, r2 * 16.0 - r1);
    let ratio = a0.amax() / a1.amax();
    prop_assert!(
        ratio > 6.0,
        "residual {:e}, {:e}, {:e} at 0.5, 0.25, 0.125 ms: without its h⁴ term, ratio {ratio} (third order: 8)",
        r0.amax(),
        r1.amax(),
        r2.amax()
    );
    Ok(())
}

/// A point near the tracking regime: the target about where the preferred pose `r_*` puts it
/// (1.5 m ahead), joints near `q_* = (0, 0.45, 0)`, a target moving at up to 0.2 m/s. Far
/// from it the platform manoeuvres differently at different periods within the 20 ms, and
/// the residuals are not comparable.
fn near_tracking() -> impl Strategy<Value = Point> {
    (pose_in(3.0, PI), vec3(-0.1, 0.1), vec3(-0.1, 0.1), vec3(-0.2, 0.2), (-PI..PI, -PI..PI), 0.0..1.0f64)
        .prop_map(|(base, d, dq, u_d, (a1, a2), psi)| {
            let r_bd = V3::new(1.5 + d[0], d[1], d[2]);
            let q = Q::new(0.0, 0.45, 0.0) + dq;
            let meas = Measurement {
                t: 0.5,
                base: pose(&base),
                steering: 0.0,
                joints: q,
                target: pose(&mul(&base, &r_bd)),
                target_velocity: u_d,
            };
            let mut state = State::new();
            state.alpha = Vector2::new(a1, a2);
            state.q_hat = q;
            state.psi = psi;
            state.sigma = Q::repeat(psi.sqrt());
            state.initialized = true;
            Point { meas, state }
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Over one hold, the arm's task function follows the A-stable second-order
    /// discretisation of `ė_m = G e_m` to third order: halving the period divides the
    /// residual's third-order part by ~8 (asserted > 6; see `order`).
    #[test]
    fn e_m_follows_its_discretisation_to_third_order(pt in near_tracking(), k in 0usize..4) {
        let run = [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D][k];
        order(&ControlLaw::new(midpoint(run), Unicycle::paper(), Rpr::paper()).expect("valid"), &pt)?;
        order(&ControlLaw::new(midpoint(run), Omnidirectional, Rpr::paper()).expect("valid"), &pt)?;
    }

    /// A delayed step equals the step from the measurement the robot would give when the
    /// command starts to act: the commands still in flight (the last `⌈τ/h⌉`, the oldest
    /// for the part of its hold that falls in the delay) are predicted exactly.
    #[test]
    fn delayed_step_is_the_step_at_the_actuation_time(pt in point(0.1), k in 0usize..4, frac in 0.1..3.9f64) {
        let run = [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D][k];
        for kind in [PlatformKind::Unicycle, PlatformKind::Omni] {
            let h = 1e-3;
            let mut p = midpoint(run);
            p.primary.regularisation_gain = 0.2;
            let (mut st, mut m) = (steady(&pt, h), pt.meas);
            // Three commands in flight.
            let step = |st: &mut State<f64, 3>, m: &Measurement<f64, 3>, d: f64| match kind {
                PlatformKind::Unicycle => ControlLaw::new(p, Unicycle::paper(), Rpr::paper()).expect("valid").step_delayed(st, m, h, d),
                _ => ControlLaw::new(p, Omnidirectional, Rpr::paper()).expect("valid").step_delayed(st, m, h, d),
            };
            for _ in 0..4 {
                let o = step(&mut st, &m, 0.0).map_err(|r| TestCaseError::reject(format!("{:?}", r.error)))?;
                m = advance(kind, &m, &o.command, h);
            }
            let tau = frac * h;
            // The robot at t + τ: the oldest command in flight for its last part, then the newer ones.
            let mut spans = Vec::new();
            let mut left = tau;
            for i in 0.. {
                if left <= 0.0 { break; }
                let s = st.sent(i).expect("remembered");
                let d = s.period.min(left);
                spans.push((Command { platform: s.platform, joints: s.joints }, d));
                left -= d;
            }
            let mut at_tau = m;
            for (c, d) in spans.iter().rev() {
                let moved = advance(kind, &at_tau, c, *d);
                at_tau = Measurement { target: at_tau.target, ..moved };
            }
            // The target moves with u_d for τ; time advances by τ.
            at_tau.target = pose(&flow(&v3(&m.target), &m.target_velocity, tau));
            at_tau.t = m.t + tau;
            // The law's prediction stops a joint at 90 % of its way to a limit (a delayed
            // measurement never predicts the arm through one): no such point either.
            let lim = p.joint_limits;
            for i in 0..3 {
                let moved = at_tau.joints[i] - m.joints[i];
                let room = if moved > 0.0 { lim.upper[i] - m.joints[i] } else { m.joints[i] - lim.lower[i] };
                prop_assume!(moved.abs() < 0.9 * room, "joint {} would pass 90 % of its way to a limit", i + 1);
            }
            let (mut sa, mut sb) = (st, st);
            let a = step(&mut sa, &m, tau).map_err(|r| TestCaseError::fail(format!("delayed: {:?}", r.error)))?;
            // (The commands in flight may take a joint to its limit: no such point.)
            let b = step(&mut sb, &at_tau, 0.0).map_err(|r| TestCaseError::reject(format!("at τ: {:?}", r.error)))?;
            let ca = command_vec(&a.command);
            let cb = command_vec(&b.command);
            check_close("command", &ca, &cb, 1e-7, 1.0)?;
            check_close("e_m", &a.diagnostics.e_m, &b.diagnostics.e_m, 1e-7, 1.0)?;
        }
    }
}

fn command_vec(c: &Command<f64, 3>) -> SMatrix<f64, 7, 1> {
    let p = &c.platform;
    SMatrix::<f64, 7, 1>::from_column_slice(&[
        p.v,
        p.v_lat,
        p.omega,
        p.v_xi,
        c.joints[0],
        c.joints[1],
        c.joints[2],
    ])
}

/// A state with every value at an extreme: the lock-out of the earlier law (a state that
/// made every later step fail numerically, rejected with the state left as it was).
fn extreme_state<T: Real>(big: f64) -> State<T, 3> {
    let b = T::of(big);
    let mut st = State::new();
    st.initialized = true;
    st.alpha = Vector2::new(b, -b);
    st.q_hat = SVector3::repeat(b);
    st.psi = T::of(0.5);
    st.sigma = SVector3::repeat(T::of(0.5));
    st.r_tilde = companion_core::Pose::new(b, -b, b);
    st.last_w = companion_core::nalgebra::Vector3::repeat(b);
    st.last_u_bar = companion_core::nalgebra::Vector3::repeat(-b);
    st.last_sensitivity = SMatrix::repeat(b);
    st.last_target_velocity = companion_core::nalgebra::Vector3::repeat(b);
    st.last_target_rate = companion_core::nalgebra::Vector3::repeat(b);
    st.last_t = T::of(-big);
    st
}

type SVector3<T> = companion_core::nalgebra::SVector<T, 3>;

fn paper_measurement<T: Real>(t: f64) -> Measurement<T, 3> {
    measurement_as(&Measurement {
        t,
        base: pose(&V3::zeros()),
        steering: 0.0,
        joints: Q::new(0.0, 0.35, 0.0),
        target: pose(&V3::new(2.6, 1.0, 0.0)),
        target_velocity: V3::new(0.0, -0.157, 0.0),
    })
}

fn no_lock_out<T: Real, P: Platform<T>>(platform: P) {
    for run in [PaperRun::A, PaperRun::B] {
        for disc in [Discretisation::Midpoint, Discretisation::Sampled] {
            let mut p = Params::<T, 3>::paper(run);
            p.discretisation = disc;
            let law = ControlLaw::new(p, platform, Rpr::paper()).expect("valid");
            let lim = p.joint_limits;
            // f32's r̃_b ~1e19 and f64's ~1e154 locked the earlier law out; up to the
            // type's largest finite values here.
            // Up to the type's largest finite value, and beyond: infinities and NaN too.
            let max = if core::mem::size_of::<T>() == 4 { f64::from(f32::MAX) } else { f64::MAX };
            for big in [1e19f64, 1e38, 1e154, 1e300, f64::INFINITY, f64::NAN] {
                let big = if big.is_finite() { big.min(max) } else { big };
                let mut st = extreme_state::<T>(big);
                let out = law.step(&mut st, &paper_measurement(0.0), T::of(1e-3)).unwrap_or_else(|r| {
                    panic!(
                        "{} {disc:?} {run:?} {big:e}: a valid measurement rejected: {:?}",
                        core::any::type_name::<P>(),
                        r.error
                    )
                });
                assert!(out.command.is_finite());
                assert!(
                    st.is_bounded(&lim.lower, &lim.upper, p.secondary.rest_reach),
                    "{disc:?} {big:e}: {st:?}"
                );
                // The next valid step is accepted without another recovery.
                let again = law.step(&mut st, &paper_measurement(1e-3), T::of(1e-3)).expect("accepted");
                assert!(!again.diagnostics.recovered);
            }
        }
    }
}

/// From any state, however extreme, a valid measurement is accepted at once (re-initialising
/// the filters, counted), and the state is bounded afterwards — f32 and f64, every platform,
/// both discretisations.
#[test]
fn no_state_locks_the_controller_out() {
    no_lock_out::<f32, _>(Unicycle::paper());
    no_lock_out::<f64, _>(Unicycle::paper());
    no_lock_out::<f32, _>(CarLike::new(0.3f32, [2.0, 3.0, 2.0], 5.0));
    no_lock_out::<f64, _>(car());
    no_lock_out::<f32, _>(Omnidirectional);
    no_lock_out::<f64, _>(Omnidirectional);
}

/// A recovery is reported and counted; a measurement that fails even from fresh filters
/// is rejected with the state untouched.
#[test]
fn recovery_is_reported_and_counted() {
    let law = unicycle_law(Params::paper(PaperRun::B));
    let mut st = extreme_state::<f64>(1e300);
    let out = law.step(&mut st, &paper_measurement(0.0), 1e-3).expect("accepted");
    assert!(out.diagnostics.recovered);
    assert_eq!(st.recoveries, 1);
    // A target so far away that h_s1 overflows fails from any state.
    let mut far = paper_measurement::<f64>(2e-3);
    far.target = pose(&V3::new(1e200, 1e200, 0.0));
    let before = st;
    let r = law.step(&mut st, &far, 1e-3).expect_err("overflows");
    assert_eq!(r.error, StepError::NumericalFailure);
    assert_eq!(r.command, Command::zero());
    assert_eq!(st, before);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Whatever valid-but-wild measurements come (far targets, fast targets, large steps in
    /// time), every accepted step leaves the state bounded, and the last step of a run of
    /// paper measurements is accepted.
    #[test]
    fn the_state_stays_bounded(
        seq in prop::collection::vec((pose_in(1e4, 50.0), pose_in(1e6, 1e3), vec3(-1e3, 1e3), joints_inside(0.001), 0.0..10.0f64), 1..40),
        k in 0usize..4,
    ) {
        let run = [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D][k];
        let law = unicycle_law(Params::paper(run));
        let lim = law.params().joint_limits;
        let reach = law.params().secondary.rest_reach;
        let mut st = State::new();
        let mut t = 0.0;
        for (base, target, u_d, q, dt) in seq {
            t += dt;
            let m = Measurement { t, base: pose(&base), steering: 0.0, joints: q, target: pose(&target), target_velocity: u_d };
            if law.step(&mut st, &m, 1e-3).is_ok() {
                prop_assert!(st.is_bounded(&lim.lower, &lim.upper, reach), "{st:?}");
            }
        }
        prop_assert!(law.step(&mut st, &paper_measurement(t + 1.0), 1e-3).is_ok());
    }

    /// The turn-per-step bound: within one period neither α nor the heading turns by more
    /// than `max_turn_per_step`, by one common factor with the rest of the platform command.
    #[test]
    fn alpha_and_heading_turn_at_most_the_bound(pt in point(0.02), h in 1e-4..0.01f64, phi in 0.01..1.0f64) {
        let mut p = Params::paper(PaperRun::B);
        p.max_turn_per_step = phi;
        for (o, kind) in [
            (unicycle_law(p).step(&mut pt.state.clone(), &pt.meas, h), PlatformKind::Unicycle),
            (car_law(p).step(&mut pt.state.clone(), &pt.meas, h), PlatformKind::Car),
            (omni_law(p).step(&mut pt.state.clone(), &pt.meas, h), PlatformKind::Omni),
        ] {
            let Ok(o) = o else { continue };
            let c = &o.command.platform;
            let omega = if kind == PlatformKind::Car { c.v * pt.meas.steering } else { c.omega };
            let turn = o.diagnostics.alpha_rate.amax().max(omega.abs()) * h;
            prop_assert!(turn <= phi * (1.0 + 1e-12), "{kind:?}: turns {turn} > {phi}");
        }
    }
}

/// An enormous command is scaled to the limits by the common factor, not zeroed, and the
/// reported factor is finite (f32: a target 10¹⁵ m away gives `|w| ≈ 10¹⁶`).
#[test]
fn enormous_commands_are_scaled_not_zeroed() {
    let mut p = Params::<f32, 3>::paper(PaperRun::A);
    p.velocity_limits =
        VelocityLimits { forward: 1.0, lateral: 0.8, angular: 2.0, alpha_rate: 10.0, steering_rate: 2.0 };
    let law = ControlLaw::new(p, Unicycle::paper(), Rpr::paper()).expect("valid");
    let mut m = paper_measurement::<f32>(0.0);
    m.target = companion_core::Pose::new(1e15, 1e15, 0.0);
    let out = law.step(&mut State::new(), &m, 1e-3).expect("accepted");
    let c = &out.command.platform;
    let d = &out.diagnostics;
    assert!(d.saturation.is_finite() && d.saturation > 1e6, "{}", d.saturation);
    let on_limit = [c.v.abs() / 1.0, c.omega.abs() / 2.0, d.alpha_rate[0].abs() / 10.0];
    let worst = on_limit.iter().fold(0.0f32, |a, b| a.max(*b));
    assert!((worst - 1.0).abs() < 1e-5, "a component sits on its limit: {on_limit:?}");
}

/// A delay outside `[0, min(max_delay, HISTORY periods)]` or not finite is a typed error
/// with the safe command, and the state is untouched.
#[test]
fn bad_delays_are_rejected() {
    let law = unicycle_law(Params::paper(PaperRun::A));
    let mut st = State::new();
    law.step(&mut st, &paper_measurement(0.0), 1e-3).expect("first step");
    let before = st;
    for delay in [-1e-6, f64::NAN, f64::INFINITY, 9e-3] {
        let r = law.step_delayed(&mut st, &paper_measurement(1e-3), 1e-3, delay);
        let r = r.expect_err("rejected");
        assert_eq!(r.error, StepError::BadDelay, "delay {delay}");
        assert_eq!(r.command, Command::zero());
        assert_eq!(st, before);
    }
    // Eight periods is the history's reach: accepted.
    assert!(law.step_delayed(&mut st, &paper_measurement(1e-3), 1e-3, 8e-3).is_ok());
    // At 10 ms the history reaches 80 ms, but max_delay is 50 ms.
    let before = st;
    let r = law.step_delayed(&mut st, &paper_measurement(2e-3), 1e-2, 0.051).expect_err("rejected");
    assert_eq!((r.error, st), (StepError::BadDelay, before));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// `wrap_angle` gives a value in (−π, π] for every finite angle, in f32 and f64, equal
    /// to the angle modulo 2π (of the type) where that is representable.
    #[test]
    fn wrap_angle_at_any_magnitude(bits in any::<u64>(), bits32 in any::<u32>()) {
        let x = f64::from_bits(bits);
        if x.is_finite() {
            let w = wrap_angle(x);
            prop_assert!(w > -core::f64::consts::PI && w <= core::f64::consts::PI, "wrap_angle({x:e}) = {w}");
            if x.abs() < 1e12 {
                prop_assert!((w.sin() - x.sin()).abs() < 1e-3 && (w.cos() - x.cos()).abs() < 1e-3);
            }
        }
        let y = f32::from_bits(bits32);
        if y.is_finite() {
            let w = wrap_angle(y);
            prop_assert!(w > -core::f32::consts::PI && w <= core::f32::consts::PI, "wrap_angle({y:e}) = {w}");
        }
    }
}

/// The magnitudes the earlier reduction got wrong.
#[test]
fn wrap_angle_of_huge_values() {
    for x in [1.1705790686594374e17, 1e300, -1e300, f64::MAX, -f64::MAX, 2.1e8, 7.0e15] {
        let w = wrap_angle(x);
        assert!(w > -core::f64::consts::PI && w <= core::f64::consts::PI, "wrap_angle({x:e}) = {w}");
    }
    for x in [2.1e8f32, 1e20, f32::MAX, -f32::MAX, 3.0e38] {
        let w = wrap_angle(x);
        assert!(w > -core::f32::consts::PI && w <= core::f32::consts::PI, "wrap_angle({x:e}) = {w}");
    }
}
