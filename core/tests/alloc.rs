//! The core never allocates (SPEC §2: no heap): a counting global allocator sees zero
//! allocations across 10 000 controller steps of each platform, in f64 and f32, in closed
//! loop, accepted and rejected steps alike — the planar law and the spatial one (UR5,
//! Panda).
//!
//! This file holds a single test so that nothing else runs in its process; the counter
//! only counts while the flag of the current thread is set, around `step` itself (the
//! test harness and the simulated plant are not the core's business).
#![allow(unsafe_code)] // a GlobalAlloc impl is unsafe by definition; it only forwards to System

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use common::*;
use companion_core::nalgebra::{Vector3, Vector6};
use companion_core::{
    CarLike, Chain, ControlLaw, Manipulator, Measurement, Omnidirectional, PaperRun, Params, Platform, Pose,
    Real, Rpr, Spatial, SpatialArm, State, Unicycle, VelocityLimits, Weight,
};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}

fn note() {
    if COUNTING.try_with(Cell::get).unwrap_or(false) {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    }
}

// SAFETY: every method forwards to `System` with the caller's arguments unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note();
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note();
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

const STEPS: usize = 10_000;
const DT: f64 = 1e-3;

/// Runs `STEPS` steps in closed loop with the plant; every 97th measurement is corrupted
/// (a NaN joint) so that the rejection path runs too. Returns (allocations, accepted).
fn count<T: Real, P: Platform<T>>(law: &ControlLaw<T, P, Rpr<T>, 3>, r_bd: V3, xi: f64) -> (usize, usize) {
    let mut plant = Plant::paper_start(r_bd, Q::new(0.0, 0.35, 0.0), xi);
    let mut state = State::<T, 3>::new();
    let mut accepted = 0;
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    for k in 0..STEPS {
        let mut meas: Measurement<T, 3> = measurement_as(&plant.measurement(&trajectory_1));
        if k % 97 == 96 {
            meas.joints[0] = T::of(f64::NAN);
        }
        let dt = T::of(DT);
        COUNTING.with(|c| c.set(true));
        let result = law.step(&mut state, &meas, dt);
        let warnings = law.warnings();
        COUNTING.with(|c| c.set(false));
        assert!(warnings.len() <= 1);
        let command = match result {
            Ok(out) => {
                accepted += 1;
                command_f64(&out.command)
            }
            Err(rejected) => command_f64(&rejected.command),
        };
        plant.advance(P::KIND, &command, &trajectory_1, DT, 1);
    }
    (ALLOCATIONS.load(Ordering::Relaxed) - before, accepted)
}

fn laws<T: Real>(run: PaperRun) -> Vec<(&'static str, usize, usize)> {
    let p = Params::<T, 3>::paper(run);
    let mut car_p = p;
    car_p.velocity_limits = VelocityLimits {
        forward: T::of(1.0),
        lateral: T::of(1.0),
        angular: T::of(2.0),
        alpha_rate: T::of(20.0),
        steering_rate: T::of(20.0),
    };
    let paper_start = V3::new(2.6, 1.0, 0.0);
    let uni = ControlLaw::new(p, Unicycle::paper(), Rpr::paper()).expect("valid");
    let car = ControlLaw::new(
        car_p,
        CarLike::new(T::of(0.4), [T::one(), T::of(2.0), T::one()], T::of(10.0)),
        Rpr::paper(),
    )
    .expect("valid");
    let omni = ControlLaw::new(p, Omnidirectional, Rpr::paper()).expect("valid");
    let mut filtered = p;
    filtered.secondary.heading_filter =
        Some(companion_core::HeadingFilter { rate: T::of(0.05), xi: T::of(0.2) });
    let heading = ControlLaw::new(filtered, Unicycle::paper(), Rpr::paper()).expect("valid");
    let (a, b) = count(&uni, paper_start, 0.0);
    let (c, d) = count(&car, paper_start, 0.0);
    let (e, f) = count(&omni, paper_start, 0.0);
    let (g, h) = count(&heading, paper_start, 0.0);
    vec![("unicycle", a, b), ("car", c, d), ("omni", e, f), ("unicycle, heading filter", g, h)]
}

/// A spatial arm's law for `STEPS` steps: the target held `0.2 m` below the flange at home
/// and moving on a small circle, the joints and base advanced by the commands (Euler).
fn count_spatial<T: Real, const N: usize>(chain: &Chain<T, N>, run: PaperRun, variant: u8) -> (usize, usize)
where
    SpatialArm<T, N>: Manipulator<T, N, Space = Spatial>,
{
    let arm = SpatialArm::new(chain).expect("valid");
    let mut params = Params::for_arm(&arm, run, arm.level_target(T::of(0.2))).expect("valid");
    // The weight's other variants (54) and Ψ = Ψ̃(q̂), whose rate takes the reach's gradient.
    if let Weight::Filtered { margins, lambda, xi } = params.secondary.weight {
        params.secondary.weight = match variant {
            1 => Weight::PerJoint { margins, lambda, xi },
            2 => Weight::FromFilteredJoints { margins },
            _ => params.secondary.weight,
        };
    }
    let law = ControlLaw::new(params, Unicycle::paper(), arm).expect("valid");
    let home = arm.kinematics(&chain.home()).effector.compose(&params.primary.target_in_effector);
    let mut q = chain.home();
    let mut state = State::<T, N, Spatial>::new();
    let mut base = Pose::<T>::identity();
    let mut accepted = 0;
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    for k in 0..STEPS {
        let t = T::of(k as f64 * DT);
        let (s, c) = (t * T::of(0.5)).sincos();
        let mut target = home;
        target.translation += Vector3::new(c * T::of(0.05), s * T::of(0.05), T::zero());
        let v = Vector3::new(-s * T::of(0.025), c * T::of(0.025), T::zero());
        let rotated = target.rotation.transpose() * v;
        let mut meas = Measurement::<T, N, Spatial> {
            t,
            base,
            steering: T::zero(),
            joints: q,
            target,
            target_velocity: Vector6::new(
                rotated[0],
                rotated[1],
                rotated[2],
                T::zero(),
                T::zero(),
                T::zero(),
            ),
        };
        if k % 97 == 96 {
            meas.joints[0] = T::of(f64::NAN);
        }
        COUNTING.with(|c| c.set(true));
        let result = law.step(&mut state, &meas, T::of(DT));
        COUNTING.with(|c| c.set(false));
        let command = match result {
            Ok(out) => {
                accepted += 1;
                out.command
            }
            Err(rejected) => rejected.command,
        };
        q += command.joints * T::of(DT);
        base = base.compose(&Pose::new(
            command.platform.v * T::of(DT),
            T::zero(),
            command.platform.omega * T::of(DT),
        ));
    }
    (ALLOCATIONS.load(Ordering::Relaxed) - before, accepted)
}

/// (Called from the one test: a second test in parallel would mix its counts into these.)
fn spatial_steps_allocate_nothing() {
    // Runs (b)-(d) weigh the arm's reach (its three weight variants), run (a) does not.
    for (name, (allocations, accepted)) in [
        ("ur5 f64 (a)", count_spatial::<f64, 6>(&Chain::ur5(), PaperRun::A, 0)),
        ("ur5 f32 (a)", count_spatial::<f32, 6>(&Chain::ur5(), PaperRun::A, 0)),
        ("panda f64 (a)", count_spatial::<f64, 7>(&Chain::panda(), PaperRun::A, 0)),
        ("panda f32 (a)", count_spatial::<f32, 7>(&Chain::panda(), PaperRun::A, 0)),
        ("ur5 f64 (b)", count_spatial::<f64, 6>(&Chain::ur5(), PaperRun::B, 0)),
        ("ur5 f32 (c), per joint", count_spatial::<f32, 6>(&Chain::ur5(), PaperRun::C, 1)),
        ("panda f64 (d), of q̂", count_spatial::<f64, 7>(&Chain::panda(), PaperRun::D, 2)),
        ("panda f32 (b)", count_spatial::<f32, 7>(&Chain::panda(), PaperRun::B, 0)),
    ] {
        assert_eq!(allocations, 0, "{name}: {allocations} allocations in {STEPS} steps");
        assert!(accepted >= STEPS - STEPS / 97 - 10, "{name}: only {accepted} steps accepted");
    }
}

#[test]
fn ten_thousand_steps_allocate_nothing() {
    // The counter works: an allocation inside the window is seen.
    COUNTING.with(|c| c.set(true));
    let probe = std::hint::black_box(vec![1u8; 16]);
    COUNTING.with(|c| c.set(false));
    assert!(ALLOCATIONS.load(Ordering::Relaxed) >= 1, "the counting allocator is not in use");
    drop(probe);

    let rejected_per_run = STEPS / 97;
    for (ty, results) in [
        ("f64 (a)", laws::<f64>(PaperRun::A)),
        ("f64 (b)", laws::<f64>(PaperRun::B)),
        ("f32 (a)", laws::<f32>(PaperRun::A)),
        ("f32 (d)", laws::<f32>(PaperRun::D)),
    ] {
        for (platform, allocations, accepted) in results {
            assert_eq!(allocations, 0, "{platform} {ty}: {allocations} allocations in {STEPS} steps");
            // The loop really ran the law (not only its rejection path).
            assert!(
                accepted >= STEPS - rejected_per_run - 10,
                "{platform} {ty}: only {accepted} steps accepted"
            );
        }
    }
    spatial_steps_allocate_nothing();
}
