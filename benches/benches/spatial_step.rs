//! One step of the spatial law of §5 (the UR5 on the paper's unicycle) against one step of
//! the planar law (the RPR arm on the same unicycle), recorded the same way, so that one run
//! gives their ratio (issue 11: at most 4×).
//!
//! Setup (not timed): each law runs closed loop for 4 s at 1 kHz around a kinematic plant
//! (the unicycle integrated exactly for a held command, the joints by Euler), on the paper's
//! trajectory 1 — for the spatial law lifted as in the firmware check (the same circle plus
//! `z = 0.05 sin(2πt/10)` m; the target level and 0.2 m along the flange at home) — and the
//! `(state, measurement)` of every step is kept. Each timed iteration restores the next
//! recorded state and steps the law on the next recorded measurement.
//!
//! `cargo bench -p companion-benches --bench spatial_step`; groups `step/spatial`
//! (`ur5-uni-a-f64`, `ur5-uni-a-f32`) and `step/planar-same-loop` (`uni-a-f64`,
//! `uni-a-f32`).

use std::hint::black_box;
use std::time::Duration;

use companion_core::nalgebra::{SVector, Vector3};
use companion_core::{
    Chain, ControlLaw, Manipulator, Measurement, PaperRun, Params, Planar, Pose, Real, Rpr, Spatial,
    SpatialArm, State, Unicycle,
};
use criterion::{criterion_group, criterion_main, Criterion};

/// The firmware check's scenario, for its targets (trajectory 1 and its lift).
#[path = "../../tests/firmware/src/scenario.rs"]
mod scenario;

/// Steps recorded per law: 4 s at 1 kHz.
const STEPS: usize = 4000;
const DT: f64 = 1e-3;

/// The unicycle's pose after `dt` at `(v, ω)` held (exact).
fn advance<T: Real>(p: &Pose<T>, v: T, omega: T, dt: T) -> Pose<T> {
    let dtheta = omega * dt;
    let (s0, c0) = p.theta.sincos();
    let (s1, c1) = (p.theta + dtheta).sincos();
    let (dx, dy) = if dtheta.abs() > T::of(1e-9) {
        (v / omega * (s1 - s0), v / omega * (c0 - c1))
    } else {
        (v * dt * c0, v * dt * s0)
    };
    Pose::new(p.x + dx, p.y + dy, p.theta + dtheta)
}

/// A recorded step: the state before it and its measurement.
type Sample<T, A, const N: usize> =
    (State<T, N, <A as Manipulator<T, N>>::Space>, Measurement<T, N, <A as Manipulator<T, N>>::Space>);

/// Runs `law` closed loop from `q0` on the target `target(t)`; every step's state and
/// measurement.
fn record<T: Real, A: Manipulator<T, N>, const N: usize>(
    law: &ControlLaw<T, Unicycle<T>, A, N>,
    q0: SVector<T, N>,
    target: impl Fn(
        T,
    ) -> (
        <A::Space as companion_core::Space<T>>::Pose,
        <A::Space as companion_core::Space<T>>::Vector,
    ),
) -> Vec<Sample<T, A, N>> {
    let dt = T::of(DT);
    let mut state = State::new();
    let (mut base, mut q) = (Pose::new(T::zero(), T::zero(), T::zero()), q0);
    let mut out = Vec::with_capacity(STEPS);
    for n in 0..STEPS {
        let t = T::of(n as f64) * dt;
        let (pose, velocity) = target(t);
        let meas =
            Measurement { t, base, steering: T::zero(), joints: q, target: pose, target_velocity: velocity };
        out.push((state, meas));
        let cmd = law
            .step(&mut state, &meas, dt)
            .unwrap_or_else(|r| panic!("step {n} rejected: {:?}", r.error))
            .command;
        base = advance(&base, cmd.platform.v, cmd.platform.omega, dt);
        q += cmd.joints * dt;
    }
    out
}

fn bench_law<T: Real, A: Manipulator<T, N>, const N: usize>(
    c: &mut Criterion,
    group: &str,
    name: &str,
    law: &ControlLaw<T, Unicycle<T>, A, N>,
    samples: &[Sample<T, A, N>],
) {
    let dt = T::of(DT);
    let mut g = c.benchmark_group(group);
    g.bench_function(name, |b| {
        let mut i = 0;
        b.iter(|| {
            let (state, meas) = &samples[i];
            i = if i + 1 == samples.len() { 0 } else { i + 1 };
            let mut s = *state;
            let out = law.step(&mut s, black_box(meas), dt);
            black_box((out, s))
        });
    });
    g.finish();
}

fn spatial<T: Real>(c: &mut Criterion, name: &str)
where
    SpatialArm<T, 6>: Manipulator<T, 6, Space = Spatial>,
{
    let arm = SpatialArm::new(&Chain::<T, 6>::ur5()).expect("the UR5 preset");
    let star = arm.level_target(T::of(0.2));
    let params = Params::for_arm(&arm, PaperRun::A, star).expect("the UR5's parameters");
    let home = arm.chain().home();
    let z0 = arm.kinematics(&home).effector.compose(&star).translation[2];
    let law = ControlLaw::new(params, Unicycle::paper(), arm).expect("a valid law");
    // The firmware check's lift starts at (2.6, 1) in the plane, at the target's height.
    let start = Vector3::new(T::of(2.6), T::one(), z0);
    let lifted = |t: T| scenario::lifted(t, &start);
    let samples = record(&law, home, lifted);
    bench_law(c, "step/spatial", name, &law, &samples);
}

fn planar<T: Real>(c: &mut Criterion, name: &str)
where
    Rpr<T>: Manipulator<T, 3, Space = Planar>,
{
    let law = ControlLaw::new(Params::<T, 3>::paper(PaperRun::A), Unicycle::paper(), Rpr::paper())
        .expect("the paper's law");
    let q0 = SVector::<T, 3>::new(T::zero(), T::of(0.35), T::zero());
    let samples = record(&law, q0, scenario::target::<T>);
    bench_law(c, "step/planar-same-loop", name, &law, &samples);
}

fn steps(c: &mut Criterion) {
    spatial::<f64>(c, "ur5-uni-a-f64");
    spatial::<f32>(c, "ur5-uni-a-f32");
    planar::<f64>(c, "uni-a-f64");
    planar::<f32>(c, "uni-a-f32");
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    targets = steps
}
criterion_main!(benches);
