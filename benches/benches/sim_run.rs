//! A whole simulated run in process, exactly as `companion sim` makes it
//! (`companion_runtime::run::sim::run_one`): plant (RK4), controller and recording
//! (`timeseries.csv` every 10 steps, `summary.json`, the summary over every step), written
//! into a temporary folder.
//!
//! The run: the paper's trajectory 2, 120 s at `dt = 1 ms` (120 001 controller steps),
//! unicycle, f64, variants (a) and (c). Throughput is in controller steps per second;
//! real time is 1 000 steps per second, so "× real time" = steps per second / 1 000.
//!
//! `cargo bench -p companion-benches --bench sim_run`

use std::hint::black_box;
use std::time::Duration;

use companion_benches::{TempDir, CHOICE_CONFIGS};
use companion_plant::PaperTrajectory;
use companion_runtime::domain::observe::Silent;
use companion_runtime::run::sim::run_one;
use criterion::{criterion_group, criterion_main, Criterion, SamplingMode, Throughput};

fn whole_run(c: &mut Criterion) {
    let mut group = c.benchmark_group("sim_run");
    group.sample_size(10).sampling_mode(SamplingMode::Flat);
    for config in [CHOICE_CONFIGS[0], CHOICE_CONFIGS[2]] {
        let s = config.scenario(PaperTrajectory::Two);
        let dir = TempDir::new(&s.name);
        group.throughput(Throughput::Elements(s.steps() + 1));
        group.bench_function(s.name.clone(), |b| {
            b.iter(|| black_box(run_one(&s, dir.path(), &Silent).expect("the paper's run").summary));
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(4));
    targets = whole_run
}
criterion_main!(benches);
