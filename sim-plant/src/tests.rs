//! Behaviour of the whole plant: integration against closed forms, convergence order,
//! targets, imperfections, determinism.

use core::f64::consts::{FRAC_PI_2, PI};

use companion_core::nalgebra::{SMatrix, SVector, Vector3};
use companion_core::{Arm, ArmKinematics, Command, ParamError, PlatformCommand, PlatformKind, Pose, Rpr};
use proptest::prelude::*;

use crate::*;

type Plant3 = Plant<Rpr<f64>, 3>;

const KINDS: [PlatformKind; 3] = [PlatformKind::Unicycle, PlatformKind::Car, PlatformKind::Omni];

fn initial(base: Pose<f64>) -> InitialConditions<3> {
    InitialConditions::with_relative_target(
        base,
        Pose::new(2.5, 1.0, 0.0),
        SVector::<f64, 3>::new(0.0, 0.35, 0.0),
    )
}

fn plant_with(config: PlantConfig, init: InitialConditions<3>, trajectory: Trajectory) -> Plant3 {
    Plant::new(config, Rpr::paper(), init, trajectory).expect("valid plant")
}

fn plant(kind: PlatformKind, base: Pose<f64>) -> Plant3 {
    plant_with(PlantConfig::new(kind), initial(base), Trajectory::Paper2)
}

fn command(v: f64, v_lat: f64, omega: f64, v_xi: f64, joints: [f64; 3]) -> Command<f64, 3> {
    Command { platform: PlatformCommand { v, v_lat, omega, v_xi }, joints: SVector::<f64, 3>::from(joints) }
}

fn run(p: &mut Plant3, c: &Command<f64, 3>, dt: f64, steps: usize) {
    for _ in 0..steps {
        p.advance(c, dt);
    }
}

/// Closed form for a constant body velocity `u = (v₁, v₂, ω)`, ω ≠ 0, from `r0`:
/// `p(t) = p₀ + (R(θ(t)) − R(θ₀)) (v₂, −v₁)/ω` (since `d/dt R(θ) = ω R(θ) S`).
fn constant_velocity_pose(r0: Pose<f64>, u: Vector3<f64>, t: f64) -> Pose<f64> {
    let theta = r0.theta + u[2] * t;
    let (a, b) = (u[1] / u[2], -u[0] / u[2]);
    let (s, c) = libm::sincos(theta);
    let (s0, c0) = libm::sincos(r0.theta);
    Pose::new(r0.x + (c - c0) * a - (s - s0) * b, r0.y + (s - s0) * a + (c - c0) * b, theta)
}

fn pose_error(a: &Pose<f64>, b: &Pose<f64>) -> f64 {
    (a.x - b.x).abs().max((a.y - b.y).abs()).max((a.theta - b.theta).abs())
}

// ---------------------------------------------------------------- closed forms

#[test]
fn unicycle_at_constant_v_and_omega_traces_the_exact_arc() {
    let r0 = Pose::new(0.3, -0.2, 0.4);
    let mut p = plant(PlatformKind::Unicycle, r0);
    let (v, w) = (0.7, 0.9);
    let c = command(v, 0.0, w, 0.0, [0.0; 3]);
    for k in 1..=1000 {
        p.advance(&c, 1e-2);
        let exact = constant_velocity_pose(r0, Vector3::new(v, 0.0, w), k as f64 * 1e-2);
        assert!(pose_error(&p.truth().base, &exact) < 1e-10, "step {k}");
    }
    // The radius of the arc is v/ω about a fixed centre.
    let centre = (r0.x - v / w * libm::sin(r0.theta), r0.y + v / w * libm::cos(r0.theta));
    let b = p.truth().base;
    assert!((libm::hypot(b.x - centre.0, b.y - centre.1) - v / w).abs() < 1e-10);
}

#[test]
fn omni_at_constant_body_velocity_matches_the_closed_form() {
    let r0 = Pose::new(-1.0, 2.0, -2.0);
    let mut p = plant(PlatformKind::Omni, r0);
    let u = Vector3::new(0.4, -0.3, -0.6);
    let c = command(u[0], u[1], u[2], 0.0, [0.0; 3]);
    run(&mut p, &c, 1e-2, 2000);
    let exact = constant_velocity_pose(r0, u, 20.0);
    assert!(pose_error(&p.truth().base, &exact) < 1e-10);
    // Pure translation: exact to rounding.
    let mut p = plant(PlatformKind::Omni, Pose::new(0.0, 0.0, FRAC_PI_2));
    run(&mut p, &command(0.5, 0.25, 0.0, 0.0, [0.0; 3]), 1e-3, 1000);
    let b = p.truth().base;
    assert!((b.x + 0.25).abs() < 1e-12 && (b.y - 0.5).abs() < 1e-12 && b.theta == FRAC_PI_2);
}

#[test]
fn car_at_constant_steering_is_a_unicycle_with_omega_v_xi() {
    let r0 = Pose::new(0.1, 0.2, 0.3);
    let (v, xi) = (0.6, 0.8);
    let mut init = initial(r0);
    init.steering = xi;
    let mut car = plant_with(PlantConfig::new(PlatformKind::Car), init, Trajectory::Paper2);
    let mut uni = plant(PlatformKind::Unicycle, r0);
    // The car ignores `omega`; the unicycle ignores `v_xi`.
    let c_car = command(v, 0.0, 123.0, 0.0, [0.0; 3]);
    let c_uni = command(v, 0.0, v * xi, 0.0, [0.0; 3]);
    for _ in 0..1500 {
        car.advance(&c_car, 1e-2);
        uni.advance(&c_uni, 1e-2);
    }
    assert_eq!(car.truth().base, uni.truth().base);
    assert_eq!(car.truth().steering, xi);
    let exact = constant_velocity_pose(r0, Vector3::new(v, 0.0, v * xi), 15.0);
    assert!(pose_error(&car.truth().base, &exact) < 1e-10);
    // The applied velocities report the yaw rate v ξ.
    let applied = car.truth().applied.platform;
    assert_eq!((applied.v, applied.omega, applied.v_xi), (v, v * xi, 0.0));
}

#[test]
fn car_steering_integrates_v_xi_and_the_heading_follows() {
    // ξ(t) = ξ₀ + v_ξ t, θ(t) = θ₀ + v (ξ₀ t + v_ξ t²/2): RK4 is exact for both.
    let mut p = plant(PlatformKind::Car, Pose::identity());
    let (v, v_xi) = (0.5, 0.2);
    run(&mut p, &command(v, 0.0, 0.0, v_xi, [0.0; 3]), 1e-2, 300);
    let s = p.truth();
    assert!((s.steering - 0.6).abs() < 1e-13);
    assert!((s.base.theta - v * v_xi * 9.0 / 2.0).abs() < 1e-13);
}

#[test]
fn joints_integrate_their_velocities_for_any_joint_count() {
    let mut p = plant(PlatformKind::Unicycle, Pose::identity());
    run(&mut p, &command(0.0, 0.0, 0.0, 0.0, [0.1, -0.05, 0.2]), 1e-3, 2000);
    let q = p.truth().joints;
    assert!((q - SVector::<f64, 3>::new(0.2, 0.25, 0.4)).amax() < 1e-12);

    let init = InitialConditions::with_relative_target(
        Pose::identity(),
        Pose::new(1.0, 0.0, 0.0),
        SVector::<f64, 2>::new(0.0, 0.5),
    );
    let mut p2 =
        Plant::new(PlantConfig::new(PlatformKind::Omni), Rp, init, Trajectory::Paper1).expect("valid");
    let c = Command { platform: PlatformCommand::default(), joints: SVector::<f64, 2>::new(FRAC_PI_2, 0.1) };
    for _ in 0..1000 {
        p2.advance(&c, 1e-3);
    }
    let q = p2.truth().joints;
    assert!((q[0] - FRAC_PI_2).abs() < 1e-12 && (q[1] - 0.6).abs() < 1e-12);
    // End effector of the RP arm at q = (π/2, 0.6): (L, q₂) = (0.3, 0.6), heading π/2.
    let e = p2.end_effector();
    assert!((e.x - 0.3).abs() < 1e-12 && (e.y - 0.6).abs() < 1e-12 && (e.theta - FRAC_PI_2).abs() < 1e-12);
}

/// A two-joint test arm (revolute at `(L, 0)` then prismatic): `r_be = (L + q₂ cos q₁,
/// q₂ sin q₁, q₁)`, `L = 0.3 m`. Only `r_eb` is used by the plant, so the derivatives
/// are left at zero.
#[derive(Clone, Copy, Debug)]
struct Rp;

impl Arm<f64, 2> for Rp {
    fn validate(&self) -> Result<(), ParamError> {
        Ok(())
    }
    fn kinematics(&self, q: &SVector<f64, 2>) -> ArmKinematics<f64, 2> {
        let (s, c) = libm::sincos(q[0]);
        let r_be = Pose::new(0.3 + q[1] * c, q[1] * s, q[0]);
        ArmKinematics {
            r_eb: r_be.inverse(),
            jacobian: SMatrix::zeros(),
            hessian: [SMatrix::zeros(); 3],
            sin_cos_theta: (0.0, 1.0),
        }
    }
    fn is_singular(&self, q: &SVector<f64, 2>) -> bool {
        q[1] <= 0.0
    }
}

#[test]
fn end_effector_is_the_base_times_the_arm_pose() {
    let q = SVector::<f64, 3>::new(0.3, 0.4, -0.2);
    let arm = Rpr::paper();
    let at_origin = Plant::new(
        PlantConfig::new(PlatformKind::Omni),
        arm,
        InitialConditions { base: Pose::identity(), steering: 0.0, joints: q, target: Pose::identity() },
        Trajectory::Paper1,
    )
    .expect("valid");
    assert!(pose_error(&at_origin.end_effector(), &arm.end_effector(&q)) < 1e-15);
    let base = Pose::new(1.0, -2.0, 2.5);
    let moved = Plant::new(
        PlantConfig::new(PlatformKind::Omni),
        arm,
        InitialConditions { base, steering: 0.0, joints: q, target: Pose::identity() },
        Trajectory::Paper1,
    )
    .expect("valid");
    assert!(pose_error(&moved.end_effector(), &base.compose(&arm.end_effector(&q))) < 1e-15);
}

// ---------------------------------------------------------------- convergence order

/// Final-pose error of the unicycle arc after 8 s with step `dt`.
fn arc_error(dt: f64) -> f64 {
    let r0 = Pose::new(0.0, 0.0, 0.3);
    let mut p = plant(PlatformKind::Unicycle, r0);
    let steps = (8.0 / dt).round() as usize;
    run(&mut p, &command(1.0, 0.0, 1.5, 0.0, [0.0; 3]), dt, steps);
    let exact = constant_velocity_pose(r0, Vector3::new(1.0, 0.0, 1.5), steps as f64 * dt);
    pose_error(&p.truth().base, &exact)
}

#[test]
fn rk4_is_fourth_order_on_the_unicycle_arc() {
    let e = [arc_error(0.2), arc_error(0.1), arc_error(0.05)];
    for w in e.windows(2) {
        let ratio = w[0] / w[1];
        assert!((14.0..18.5).contains(&ratio), "errors {e:?}, ratio {ratio}");
    }
}

#[test]
fn rk4_is_fourth_order_on_the_steering_car_and_the_circling_target() {
    let final_state = |dt: f64| {
        let mut p =
            plant_with(PlantConfig::new(PlatformKind::Car), initial(Pose::identity()), Trajectory::Paper1);
        let steps = (6.4 / dt).round() as usize;
        run(&mut p, &command(1.0, 0.0, 0.0, 0.3, [0.0; 3]), dt, steps);
        *p.truth()
    };
    let reference = final_state(1e-3);
    let err = |dt: f64| {
        let s = final_state(dt);
        (pose_error(&s.base, &reference.base), pose_error(&s.target, &reference.target))
    };
    let (e1, e2, e3) = (err(0.4), err(0.2), err(0.1));
    for (a, b) in [(e1.0, e2.0), (e2.0, e3.0), (e1.1, e2.1), (e2.1, e3.1)] {
        let ratio = a / b;
        assert!((13.0..19.0).contains(&ratio), "{e1:?} {e2:?} {e3:?}: ratio {ratio}");
    }
}

// ---------------------------------------------------------------- targets

#[test]
fn trajectory_1_is_a_circle_of_radius_0_1_m_and_period_4_s() {
    let mut p = plant_with(
        PlantConfig::new(PlatformKind::Unicycle),
        paper_initial(PaperTrajectory::One),
        Trajectory::Paper1,
    );
    let start = p.truth().target;
    assert_eq!(start, Pose::new(2.6, 1.0, 0.0));
    let centre = (start.x - 0.1, start.y);
    let zero = Command::zero();
    for k in 1..=8000 {
        p.advance(&zero, 1e-3);
        let d = p.truth().target;
        assert!((libm::hypot(d.x - centre.0, d.y - centre.1) - 0.1).abs() < 1e-12, "step {k}");
        assert_eq!(d.theta, 0.0);
        match k {
            2000 => assert!(pose_error(&d, &Pose::new(2.4, 1.0, 0.0)) < 1e-12),
            1000 => assert!(pose_error(&d, &Pose::new(2.5, 0.9, 0.0)) < 1e-12),
            4000 | 8000 => assert!(pose_error(&d, &start) < 1e-12, "back at the start after {k} ms"),
            _ => {}
        }
    }
}

#[test]
fn trajectory_2_draws_three_straight_lines_and_ends_where_table_1_says() {
    let mut p = plant(PlatformKind::Unicycle, Pose::identity());
    let zero = Command::zero();
    let mut max_theta: f64 = 0.0;
    for k in 1..=12_000 {
        p.advance(&zero, 1e-2);
        max_theta = max_theta.max(p.truth().target.theta.abs());
        let d = p.truth().target;
        // Checkpoints (37 s, 99 s) where the rotations have returned to θ = 0.
        let u_d = p.measure().target_velocity;
        match k {
            // At a jump the measured u_d is the value after it, whatever the rounding of n·dt.
            500 => assert!((u_d - Vector3::new(0.0, 0.0, PI * PI / 20.0)).amax() < 1e-12, "{u_d:?}"),
            2700 => assert_eq!(u_d, Vector3::new(0.2, 0.0, 0.0)),
            5900 => assert_eq!(u_d, Vector3::new(0.0, 0.05, 0.0)),
            3700 => assert!(pose_error(&d, &Pose::new(4.5, 1.0, 0.0)) < 1e-10, "{d:?}"),
            9900 => assert!(pose_error(&d, &Pose::new(4.5, 3.0, 0.0)) < 1e-10, "{d:?}"),
            _ => {}
        }
    }
    assert_eq!(p.time(), 120.0);
    assert!(pose_error(&p.truth().target, &Pose::new(2.5, 3.0, 0.0)) < 1e-10, "{:?}", p.truth().target);
    // The rotations reach ±(π²/20)(2/π) = ±π/10.
    assert!((max_theta - PI / 10.0).abs() < 1e-10, "{max_theta}");
}

#[test]
fn angles_stay_continuous_over_many_turns() {
    let piecewise =
        Trajectory::from_toml_str("[[segment]]\nduration = 60\nvelocity = [0.1, 0, 2.0]").expect("ok");
    let mut p = plant_with(PlantConfig::new(PlatformKind::Unicycle), initial(Pose::identity()), piecewise);
    let c = command(0.5, 0.0, -3.0, 0.0, [0.0; 3]);
    let mut previous = p.truth().base.theta;
    for _ in 0..10_000 {
        p.advance(&c, 1e-2);
        let theta = p.truth().base.theta;
        assert!((theta - previous + 0.03).abs() < 1e-12, "a jump: {previous} → {theta}");
        previous = theta;
    }
    assert!((p.truth().base.theta + 300.0).abs() < 1e-9);
    // 47 turns and more, not wrapped.
    assert!((p.truth().target.theta - 120.0).abs() < 1e-9);
    let m = p.measure();
    assert_eq!(m.base.theta, p.truth().base.theta);
}

// ---------------------------------------------------------------- time

#[test]
fn time_is_the_step_index_times_dt_without_accumulation() {
    let mut p = plant(PlatformKind::Omni, Pose::identity());
    assert_eq!((p.step_index(), p.time(), p.dt()), (0, 0.0, None));
    let dt = 1e-3;
    let mut summed = 0.0;
    let mut differs = false;
    for n in 1..=10_000u64 {
        p.advance(&Command::zero(), dt);
        summed += dt;
        assert_eq!(p.step_index(), n);
        assert_eq!(p.time().to_bits(), (n as f64 * dt).to_bits());
        assert_eq!(p.measure().t, p.time());
        differs |= summed != p.time();
    }
    assert!(differs, "the test should catch an accumulating clock");
    assert_eq!(p.time(), 10.0);
    assert_eq!(p.dt(), Some(dt));
}

// ---------------------------------------------------------------- errors

#[test]
fn bad_steps_are_refused_and_leave_the_state_alone() {
    let mut p = plant(PlatformKind::Unicycle, Pose::identity());
    let c = command(0.1, 0.0, 0.1, 0.0, [0.0; 3]);
    for dt in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        assert!(matches!(p.try_advance(&c, dt), Err(AdvanceError::BadTimeStep { .. })));
    }
    p.advance(&c, 1e-3);
    let before = *p.truth();
    assert_eq!(p.try_advance(&c, 2e-3), Err(AdvanceError::TimeStepChanged { fixed: 1e-3, dt: 2e-3 }));
    let mut bad = c;
    bad.joints[1] = f64::NAN;
    assert_eq!(p.try_advance(&bad, 1e-3), Err(AdvanceError::NonFiniteCommand));
    bad = c;
    bad.platform.v_xi = f64::INFINITY; // even a field this platform ignores
    assert_eq!(p.try_advance(&bad, 1e-3), Err(AdvanceError::NonFiniteCommand));
    assert_eq!(*p.truth(), before);
    assert!(AdvanceError::TimeStepChanged { fixed: 1e-3, dt: 2e-3 }.to_string().contains("0.001"));
}

#[test]
#[should_panic(expected = "time step")]
fn advance_panics_on_a_bad_step() {
    plant(PlatformKind::Unicycle, Pose::identity()).advance(&Command::zero(), 0.0);
}

#[test]
fn invalid_configurations_are_rejected_naming_the_parameter() {
    let base = PlantConfig::new(PlatformKind::Car);
    let build = |config: PlantConfig, init: InitialConditions<3>| {
        Plant::new(config, Rpr::paper(), init, Trajectory::Paper1).map(|_| ()).expect_err("invalid")
    };
    let init = initial(Pose::identity());
    let lag = |tau| base.with_imperfections(Imperfections { actuator_lag: Some(tau), ..Default::default() });
    for (config, param, rule) in [
        (lag(0.0), "actuator_lag", Rule::NotPositive),
        (lag(-0.1), "actuator_lag", Rule::NotPositive),
        (lag(f64::NAN), "actuator_lag", Rule::NonFinite),
        (
            base.with_imperfections(Imperfections {
                noise: Some(Noise { angle: -1e-3, ..Noise::default() }),
                ..Default::default()
            }),
            "noise.angle",
            Rule::Negative,
        ),
        (
            base.with_imperfections(Imperfections {
                noise: Some(Noise { joints: f64::INFINITY, ..Noise::default() }),
                ..Default::default()
            }),
            "noise.joints",
            Rule::NonFinite,
        ),
        (
            base.with_imperfections(Imperfections { wheel_scale_error: -1.0, ..Default::default() }),
            "wheel_scale_error",
            Rule::NotAboveMinusOne,
        ),
        (base.with_steering_limit(0.0), "steering_limit", Rule::NotPositive),
        (base.with_steering_limit(f64::INFINITY), "steering_limit", Rule::NonFinite),
    ] {
        let e = build(config, init);
        assert!(
            matches!(e, PlantError::Invalid { param: p, rule: r, .. } if p == param && r == rule),
            "{e:?}"
        );
        assert!(e.to_string().contains(param), "{e}");
    }
    let mut steered = init;
    steered.steering = 2.0;
    let e = build(base.with_steering_limit(1.4), steered);
    assert!(matches!(
        e,
        PlantError::Invalid { param: "initial.steering", rule: Rule::BeyondSteeringLimit, .. }
    ));
    let mut nan = init;
    nan.target.theta = f64::NAN;
    assert!(matches!(build(base, nan), PlantError::Invalid { param: "initial.target", .. }));
    let e =
        Plant::new(base, Rpr { l: -0.4, l_e: 0.15 }, init, Trajectory::Paper1).map(|_| ()).expect_err("bad");
    assert!(matches!(e, PlantError::Arm(_)));
    assert!(e.to_string().contains("`l`"), "{e}");
}

// ---------------------------------------------------------------- steering limit

#[test]
fn the_steering_stops_at_its_limit_and_leaves_it_at_once() {
    let limit = realistic_steering_limit();
    let config = PlantConfig::new(PlatformKind::Car).with_steering_limit(limit);
    let mut p = plant_with(config, initial(Pose::identity()), Trajectory::Paper1);
    run(&mut p, &command(0.2, 0.0, 0.0, 1.0, [0.0; 3]), 1e-2, 300);
    assert_eq!(p.truth().steering, limit);
    assert_eq!(p.truth().applied.platform.v_xi, 0.0);
    p.advance(&command(0.2, 0.0, 0.0, -1.0, [0.0; 3]), 1e-2);
    assert!((p.truth().steering - (limit - 1e-2)).abs() < 1e-12);
    // The limit is a car thing: the unicycle ignores it.
    let config = PlantConfig::new(PlatformKind::Unicycle).with_steering_limit(limit);
    let mut u = plant_with(config, initial(Pose::identity()), Trajectory::Paper1);
    run(&mut u, &command(0.2, 0.0, 0.0, 1.0, [0.0; 3]), 1e-2, 300);
    assert_eq!(u.truth().steering, 0.0);
}

// ---------------------------------------------------------------- imperfections

#[test]
fn without_imperfections_the_measurement_is_the_truth_bit_for_bit() {
    for kind in KINDS {
        let mut p = plant(kind, Pose::new(0.5, -0.5, 1.0));
        for k in 0..500 {
            let m = p.measure();
            let s = p.truth();
            assert_eq!(m.t.to_bits(), s.t.to_bits());
            assert_eq!(m.base, s.base);
            assert_eq!(m.steering, s.steering);
            assert_eq!(m.joints, s.joints);
            assert_eq!(m.target, s.target);
            assert_eq!(m.target_velocity, s.target_velocity);
            let x = k as f64 * 0.01;
            p.advance(&command(libm::sin(x), 0.3, libm::cos(x), 0.1, [0.1, 0.01, -0.1]), 1e-2);
        }
    }
}

fn noisy(seed: u64) -> Plant3 {
    let imperfections = Imperfections { noise: Some(Noise::typical()), seed, ..Default::default() };
    plant_with(
        PlantConfig::new(PlatformKind::Car).with_imperfections(imperfections),
        initial(Pose::identity()),
        Trajectory::Paper2,
    )
}

#[test]
fn noise_is_reproducible_for_a_seed_different_for_another_and_never_touches_the_truth() {
    let (mut a, mut b, mut c) = (noisy(7), noisy(7), noisy(8));
    let mut perfect = plant(PlatformKind::Car, Pose::identity());
    let cmd = command(0.3, 0.0, 0.0, 0.1, [0.05, 0.01, 0.0]);
    for _ in 0..200 {
        let (ma, mb, mc) = (a.measure(), b.measure(), c.measure());
        assert_eq!(ma, mb);
        assert_eq!(ma, a.measure(), "a second measurement in the same step is the same");
        assert_ne!(ma.base, mc.base);
        assert_ne!(ma.joints, mc.joints);
        assert_ne!(ma.base, a.truth().base);
        // t and u_d are known to the controller, exactly.
        assert_eq!((ma.t, ma.target_velocity), (a.truth().t, a.truth().target_velocity));
        for p in [&mut a, &mut b, &mut c, &mut perfect] {
            p.advance(&cmd, 1e-2);
        }
        assert_eq!(a.truth(), perfect.truth());
    }
}

#[test]
fn noise_has_the_requested_standard_deviations() {
    let noise = Noise { position: 0.01, angle: 0.02, joints: 0.003, steering: 0.05 };
    let imperfections = Imperfections { noise: Some(noise), seed: 42, ..Default::default() };
    let mut p = plant_with(
        PlantConfig::new(PlatformKind::Car).with_imperfections(imperfections),
        initial(Pose::identity()),
        Trajectory::Paper1,
    );
    let n = 4000;
    let mut sums = [0.0f64; 8];
    let mut squares = [0.0f64; 8];
    for _ in 0..n {
        let m = p.measure();
        let s = *p.truth();
        let e = [
            m.base.x - s.base.x,
            m.base.y - s.base.y,
            m.base.theta - s.base.theta,
            m.steering - s.steering,
            m.joints[0] - s.joints[0],
            m.joints[2] - s.joints[2],
            m.target.x - s.target.x,
            m.target.theta - s.target.theta,
        ];
        for i in 0..8 {
            sums[i] += e[i];
            squares[i] += e[i] * e[i];
        }
        p.advance(&Command::zero(), 1e-3);
    }
    let sigma = [0.01, 0.01, 0.02, 0.05, 0.003, 0.003, 0.01, 0.02];
    for i in 0..8 {
        let mean = sums[i] / n as f64;
        let std = libm::sqrt(squares[i] / n as f64 - mean * mean);
        // 4000 samples: the standard error of the std is σ/√8000 ≈ 1.1 %.
        assert!((std / sigma[i] - 1.0).abs() < 0.06, "component {i}: std {std} vs {}", sigma[i]);
        assert!(mean.abs() < 5.0 * sigma[i] / libm::sqrt(n as f64), "component {i}: mean {mean}");
    }
}

#[test]
fn actuator_lag_follows_one_minus_exp_for_a_step_command() {
    let tau = 0.1;
    let imperfections = Imperfections { actuator_lag: Some(tau), ..Default::default() };
    let mut p = plant_with(
        PlantConfig::new(PlatformKind::Unicycle).with_imperfections(imperfections),
        initial(Pose::identity()),
        Trajectory::Paper1,
    );
    let u_q = [0.2, -0.1, 0.3];
    let c = command(1.0, 0.0, 0.0, 0.0, u_q);
    for _ in 0..1000 {
        p.advance(&c, 1e-3);
        let t = p.time();
        let rise = 1.0 - libm::exp(-t / tau);
        let s = p.truth();
        assert!((s.applied.platform.v - rise).abs() < 1e-10, "t = {t}");
        for (applied, commanded) in s.applied.joints.iter().zip(u_q) {
            assert!((applied - commanded * rise).abs() < 1e-10);
        }
        // x(t) = t − τ (1 − e^{−t/τ}).
        assert!((s.base.x - (t - tau * rise)).abs() < 1e-10, "t = {t}");
        assert!((s.joints[1] - (0.35 + u_q[1] * (t - tau * rise))).abs() < 1e-10);
        assert_eq!(s.command, c);
    }
}

#[test]
fn wheel_scale_error_scales_the_linear_speeds_only() {
    let imperfections = Imperfections { wheel_scale_error: 0.1, ..Default::default() };
    let config = |kind| PlantConfig::new(kind).with_imperfections(imperfections);
    let mut omni = plant_with(config(PlatformKind::Omni), initial(Pose::identity()), Trajectory::Paper1);
    run(&mut omni, &command(1.0, 0.5, 0.0, 0.0, [0.0; 3]), 1e-3, 1000);
    let b = omni.truth().base;
    assert!((b.x - 1.1).abs() < 1e-12 && (b.y - 0.55).abs() < 1e-12);
    let mut uni = plant_with(config(PlatformKind::Unicycle), initial(Pose::identity()), Trajectory::Paper1);
    run(&mut uni, &command(1.0, 0.0, 0.5, 0.0, [0.0; 3]), 1e-3, 1000);
    assert!((uni.truth().base.theta - 0.5).abs() < 1e-12);
    assert!((uni.truth().applied.platform.v - 1.1).abs() < 1e-15);
    // The car's yaw rate v ξ is scaled with v.
    let mut init = initial(Pose::identity());
    init.steering = 0.5;
    let mut car = plant_with(config(PlatformKind::Car), init, Trajectory::Paper1);
    run(&mut car, &command(1.0, 0.0, 0.0, 0.0, [0.0; 3]), 1e-3, 1000);
    assert!((car.truth().base.theta - 0.55).abs() < 1e-12);
}

// ---------------------------------------------------------------- determinism

/// A closed-loop-like run: the command depends on the (noisy) measurement.
fn record(kind: PlatformKind) -> Vec<u64> {
    let config = PlantConfig::new(kind).with_imperfections(Imperfections::typical(2024));
    let mut p = plant_with(config, initial(Pose::new(0.1, 0.2, 0.3)), Trajectory::Paper2);
    let mut bits = Vec::new();
    for _ in 0..3000 {
        let m = p.measure();
        let e = m.target.x - m.base.x;
        let c = command(
            0.5 * e,
            0.1 * (m.target.y - m.base.y),
            libm::sin(m.base.theta + m.t),
            -m.steering,
            [0.01 * m.joints[0], libm::cos(m.t) * 0.01, -0.02],
        );
        p.advance(&c, 1e-3);
        let s = p.truth();
        bits.extend(
            [m.base.x, m.base.theta, m.steering, m.joints[1], m.target.y, s.base.x, s.base.y, s.base.theta]
                .iter()
                .chain([s.steering, s.joints[2], s.target.theta, s.applied.platform.v].iter())
                .map(|x| x.to_bits()),
        );
    }
    bits
}

#[test]
fn two_runs_give_identical_bits() {
    for kind in KINDS {
        assert_eq!(record(kind), record(kind), "{kind:?}");
    }
}

// ---------------------------------------------------------------- properties

fn any_kind() -> impl Strategy<Value = PlatformKind> {
    prop_oneof![Just(PlatformKind::Unicycle), Just(PlatformKind::Car), Just(PlatformKind::Omni)]
}

proptest! {
    /// Finite commands and steps keep every state finite, and the perfect plant measures
    /// the truth.
    #[test]
    fn finite_inputs_keep_the_state_finite(
        kind in any_kind(),
        platform in prop::array::uniform4(-5.0..5.0f64),
        joints in prop::array::uniform3(-2.0..2.0f64),
        dt in 1e-4..0.1f64,
        lag in prop::option::of(1e-3..1.0f64),
        steps in 1usize..60,
    ) {
        let imperfections = Imperfections { actuator_lag: lag, ..Default::default() };
        let mut p = plant_with(
            PlantConfig::new(kind).with_imperfections(imperfections),
            initial(Pose::identity()),
            Trajectory::Paper2,
        );
        let c = command(platform[0], platform[1], platform[2], platform[3], joints);
        for _ in 0..steps {
            p.advance(&c, dt);
        }
        let s = *p.truth();
        prop_assert!(s.base.is_finite() && s.target.is_finite() && s.steering.is_finite());
        prop_assert!(s.joints.iter().all(|q| q.is_finite()) && s.applied.is_finite());
        let m = p.measure();
        prop_assert_eq!((m.base, m.joints, m.target), (s.base, s.joints, s.target));
    }

    /// With the zero command and no lag, the robot does not move at all (bit for bit).
    #[test]
    fn the_zero_command_holds_the_robot_still(
        kind in any_kind(),
        x in -10.0..10.0f64, y in -10.0..10.0f64, theta in -20.0..20.0f64,
        xi in -1.0..1.0f64,
        dt in 1e-4..0.1f64,
    ) {
        let mut init = initial(Pose::new(x, y, theta));
        init.steering = xi;
        let mut p = plant_with(PlantConfig::new(kind), init, Trajectory::Paper1);
        for _ in 0..20 {
            p.advance(&Command::zero(), dt);
        }
        prop_assert_eq!(p.truth().base, init.base);
        prop_assert_eq!(p.truth().steering, xi);
        prop_assert_eq!(p.truth().joints, init.joints);
    }

    /// The omnidirectional platform at any constant body velocity matches the closed form.
    #[test]
    fn omni_matches_the_closed_form_for_any_constant_velocity(
        v1 in -2.0..2.0f64, v2 in -2.0..2.0f64,
        w in prop_oneof![-3.0..-0.1f64, 0.1..3.0f64],
        theta0 in -PI..PI,
    ) {
        let r0 = Pose::new(0.5, -0.5, theta0);
        let mut p = plant(PlatformKind::Omni, r0);
        run(&mut p, &command(v1, v2, w, 0.0, [0.0; 3]), 1e-2, 300);
        let exact = constant_velocity_pose(r0, Vector3::new(v1, v2, w), 3.0);
        prop_assert!(pose_error(&p.truth().base, &exact) < 1e-8);
    }
}

/// The noise for a seed is pinned: a change of generator, seeding or sampling (which would
/// silently change every recorded noisy run) fails here.
#[test]
fn the_noise_of_a_seed_is_pinned() {
    let p = noisy(1);
    let m = p.measure();
    assert_eq!(p.truth().base.x, 0.0);
    assert_eq!(m.base.x.to_bits(), (0.002 * -0.08244339228844336f64).to_bits());
    assert_eq!((m.joints[0] - p.truth().joints[0]).to_bits(), (0.001 * 1.6087799680993273f64).to_bits());
    assert_eq!(m.target.theta.to_bits(), 4570830322211944173);
}

#[test]
fn the_noise_of_a_step_does_not_depend_on_earlier_measurements() {
    let (mut every, mut once) = (noisy(3), noisy(3));
    let c = command(0.1, 0.0, 0.0, 0.05, [0.0; 3]);
    for _ in 0..100 {
        let _ = every.measure();
        every.advance(&c, 1e-2);
        once.advance(&c, 1e-2);
    }
    assert_eq!(every.measure(), once.measure());
}
