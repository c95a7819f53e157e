//! `companion explore`'s unit of work: one sample, a whole closed-loop run without files
//! (`Exploration::run_sample`: a 40 s run of trajectory 1 at `dt = 1 ms`, 40 001 steps, from
//! a random start around the target), on the unicycle (run a) and the car (run c, realistic
//! limits); and a batch of 8 samples on a pool of 1 and of 2 threads, for the scaling.
//!
//! Runs per CPU-hour = 3 600 s / (time of one sample). The aim is ≥ 50 000, i.e. at
//! most 72 ms per sample; the batch's time with 2 threads should be about half its time with
//! 1 (when the machine has 2 free cores: criterion measures wall time).
//!
//! `cargo bench -p companion-benches --bench explore_run`

use std::hint::black_box;
use std::time::Duration;

use companion_core::{PaperRun, PlatformKind};
use companion_plant::PaperTrajectory;
use companion_runtime::domain::scenario::{LimitsChoice, Scenario};
use companion_runtime::study::explore::{Exploration, SpaceFile};
use criterion::{criterion_group, criterion_main, Criterion, SamplingMode, Throughput};

fn exploration(platform: PlatformKind, choice: PaperRun) -> Exploration {
    let mut b = Scenario::builder(PaperTrajectory::One, choice, platform).duration(40.0);
    if platform == PlatformKind::Car {
        b = b.limits(LimitsChoice::Realistic);
    }
    Exploration::new(b, &SpaceFile::around_the_target(), 1000, 1).expect("the default space")
}

fn one_sample(c: &mut Criterion) {
    let mut group = c.benchmark_group("explore_sample");
    group.sample_size(10).sampling_mode(SamplingMode::Flat).throughput(Throughput::Elements(1));
    for (platform, choice, name) in
        [(PlatformKind::Unicycle, PaperRun::A, "unicycle-a"), (PlatformKind::Car, PaperRun::C, "car-c")]
    {
        let e = exploration(platform, choice);
        let mut i = 0;
        group.bench_function(name, |b| {
            b.iter(|| {
                i += 1;
                black_box(e.run_sample(i % 1000))
            });
        });
    }
    group.finish();
}

fn threads(c: &mut Criterion) {
    let mut group = c.benchmark_group("explore_batch_of_8");
    group.sample_size(10).sampling_mode(SamplingMode::Flat).throughput(Throughput::Elements(8));
    let e = exploration(PlatformKind::Unicycle, PaperRun::A);
    for n in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build().expect("a thread pool");
        group.bench_function(format!("{n}-threads"), |b| {
            b.iter(|| {
                use rayon::prelude::*;
                pool.install(|| (0..8u64).into_par_iter().map(|i| e.run_sample(i).1).sum::<u64>())
            });
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(5));
    targets = one_sample, threads
}
criterion_main!(benches);
