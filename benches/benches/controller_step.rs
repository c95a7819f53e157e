//! One controller step, `ControlLaw::step`, on realistic inputs.
//!
//! Setup (not timed, once per configuration): the closed loop of the paper's trajectories
//! 1 (40 s) and 2 (120 s) at 1 kHz is run with that configuration, and 2 048
//! `(state, measurement)` pairs are kept from each, evenly spaced in time. Each timed
//! iteration restores the next recorded state and steps the law on the next recorded
//! measurement, so the branches taken (penalty band, saturation, Ψ) are those of a real
//! run and the work does not depend on how many iterations criterion chooses. Only steps
//! the law accepted are kept (the car's run (a) on trajectory 2 ends with a joint at its
//! limit, after which every step is an early rejection).
//!
//! Groups: `step/platform` (unicycle, car, omni × f64, f32; variant (a)) and
//! `step/choice` (variants (a)–(d), unicycle, f64).
//!
//! `cargo bench -p companion-benches --bench controller_step`; instruction counts of the
//! same work: `benches/callgrind.sh`.

use std::hint::black_box;
use std::time::Duration;

use companion_benches::{
    dispatch, record, step_sample, BenchPlatform, Config, Recording, CHOICE_CONFIGS, PLATFORM_CONFIGS,
};
use companion_core::Real;
use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BenchmarkGroup, Criterion};

/// Recorded inputs per trajectory.
const PER_TRAJECTORY: usize = 2048;

fn bench_config<T: Real, P: BenchPlatform<T>>(group: &mut BenchmarkGroup<'_, WallTime>, config: Config) {
    // Recorded on first use, so that a filtered `cargo bench -- car` records only what it runs.
    let mut recording: Option<Recording<T, P>> = None;
    group.bench_function(config.name(), |b| {
        let rec = recording.get_or_insert_with(|| record::<T, P>(config, PER_TRAJECTORY));
        assert!(rec.samples.len() >= PER_TRAJECTORY, "{}: too few accepted steps", config.name());
        let samples = &rec.samples;
        let mut i = 0;
        b.iter(|| {
            let sample = &samples[i];
            i = if i + 1 == samples.len() { 0 } else { i + 1 };
            black_box(step_sample(&rec.law, black_box(sample), rec.dt))
        });
    });
}

fn platforms(c: &mut Criterion) {
    let mut group = c.benchmark_group("step/platform");
    for config in PLATFORM_CONFIGS {
        dispatch!(config, bench_config(&mut group, config));
    }
    group.finish();
}

fn choices(c: &mut Criterion) {
    let mut group = c.benchmark_group("step/choice");
    for config in CHOICE_CONFIGS {
        dispatch!(config, bench_config(&mut group, config));
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(4));
    targets = platforms, choices
}
criterion_main!(benches);
