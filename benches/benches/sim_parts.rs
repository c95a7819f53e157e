//! The parts of one simulated step besides the controller: the plant's RK4 step, the
//! measurement and recorded sample, one CSV row, one summary update.
//!
//! Inputs come from the closed loop of trajectory 2, variant (a), unicycle, f64 (the
//! `sim_run` bench's run): 2 048 plant snapshots evenly spaced over the 120 s with the
//! command applied there, and the run's logged rows. The plant snapshot is cloned outside
//! the timed part (`iter_batched_ref`).
//!
//! `cargo bench -p companion-benches --bench sim_parts`

use std::hint::black_box;
use std::time::Duration;

use companion_benches::{law, Config, TempDir, CHOICE_CONFIGS};
use companion_core::{Command, PlatformKind, Rpr, State, Unicycle};
use companion_plant::{PaperTrajectory, Plant};
use companion_runtime::domain::controller::{command_f64, measurement_in, JOINTS};
use companion_runtime::domain::observe::Silent;
use companion_runtime::domain::record::csv::CsvFile;
use companion_runtime::domain::record::{Row, SummaryAccumulator};
use companion_runtime::run::sim::{build_plant, run_one, sample};
use criterion::{criterion_group, criterion_main, BatchSize, Criterion};

const SNAPSHOTS: usize = 2048;

type RprPlant = Plant<Rpr<f64>, JOINTS>;

/// Plant snapshots of the closed loop with the command applied at each.
fn snapshots(config: Config) -> Vec<(RprPlant, Command<f64, JOINTS>)> {
    let s = config.scenario(PaperTrajectory::Two);
    let law = law::<f64, Unicycle<f64>>(&s);
    let mut plant = build_plant(&s).expect("the paper's plant");
    let steps = s.steps();
    let stride = steps / SNAPSHOTS as u64;
    let mut state = State::new();
    let mut out = Vec::with_capacity(SNAPSHOTS);
    for n in 0..steps {
        let meas = measurement_in::<f64>(&plant.measure());
        let command = match law.step(&mut state, &meas, s.dt) {
            Ok(o) => command_f64(&o.command),
            Err(r) => command_f64(&r.command),
        };
        if n % stride == 0 && out.len() < SNAPSHOTS {
            out.push((plant.clone(), command));
        }
        plant.advance(&command, s.dt);
    }
    out
}

fn plant(c: &mut Criterion) {
    let config = CHOICE_CONFIGS[0];
    let dt = config.scenario(PaperTrajectory::Two).dt;
    let snaps = snapshots(config);
    let mut group = c.benchmark_group("sim_parts");
    let mut i = 0;
    group.bench_function("plant_advance", |b| {
        b.iter_batched_ref(
            || {
                i = (i + 1) % snaps.len();
                snaps[i].clone()
            },
            |(plant, command)| plant.advance(black_box(command), dt),
            BatchSize::SmallInput,
        );
    });
    let mut i = 0;
    group.bench_function("measure_and_sample", |b| {
        b.iter(|| {
            let p = &snaps[i].0;
            i = (i + 1) % snaps.len();
            black_box((black_box(p).measure(), sample(p, &companion_core::Pose::new(0.5, 0.0, 0.0), true)))
        });
    });

    // The logged rows of a whole run (one every 10 steps).
    let dir = TempDir::new("sim-parts");
    let rows: Vec<Row> =
        run_one(&config.scenario(PaperTrajectory::Two), dir.path(), &Silent).expect("the paper's run").rows;
    // Formatted and written into the void (the csv writer's buffer is flushed as it fills).
    let mut csv = CsvFile::new(std::io::sink(), PlatformKind::Unicycle, 3).expect("a sink takes anything");
    let mut i = 0;
    group.bench_function("csv_row", |b| {
        b.iter(|| {
            let row = &rows[i];
            i = (i + 1) % rows.len();
            csv.write_row(black_box(row)).expect("a sink takes anything");
        });
    });
    let lim = companion_core::Params::<f64, 3>::paper_limits();
    let mut acc = SummaryAccumulator::new("bench", lim.lower.as_slice(), lim.upper.as_slice());
    let mut i = 0;
    group.bench_function("summary_add", |b| {
        b.iter(|| {
            let row = &rows[i];
            i = (i + 1) % rows.len();
            acc.add(black_box(row));
        });
    });
    black_box(acc.finish(0.0));
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    targets = plant
}
criterion_main!(benches);
