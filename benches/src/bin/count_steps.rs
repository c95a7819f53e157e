//! `count_steps CONFIG PASSES`: records the inputs of configuration `CONFIG` (as the
//! `controller_step` bench does: the closed loop of trajectories 1 and 2, up to 2 048
//! samples from each) and then makes `PASSES` passes over them, one controller step per
//! sample, exactly as a bench iteration does.
//!
//! Meant to run under `valgrind --tool=callgrind` (see `benches/callgrind.sh`): the
//! difference of the instruction counts of two runs with `P` and `2P` passes, divided by
//! the number of steps in `P` passes, is the cost of one step averaged over every sample,
//! with everything else — setup, start-up, exit — cancelled, whatever the compiler inlined.
//!
//! `count_steps --list` prints the configuration names.

use std::hint::black_box;
use std::process::ExitCode;

use companion_benches::{all_configs, dispatch, record, step_sample, BenchPlatform, Config};
use companion_core::Real;

/// Must match the `controller_step` bench.
const PER_TRAJECTORY: usize = 2048;

#[inline(never)]
fn run<T: Real, P: BenchPlatform<T>>(config: Config, passes: u64) -> Result<(), String> {
    let rec = record::<T, P>(config, PER_TRAJECTORY);
    let samples = &rec.samples;
    let mut accepted = 0u64;
    for _ in 0..passes {
        for sample in samples {
            let (out, _) = black_box(step_sample(&rec.law, black_box(sample), rec.dt));
            accepted += u64::from(out.is_ok());
        }
    }
    let steps = passes * samples.len() as u64;
    println!(
        "{}: {steps} steps, {accepted} accepted; {} samples ({} closed-loop steps rejected)",
        config.name(),
        samples.len(),
        rec.rejected
    );
    if accepted == steps {
        Ok(())
    } else {
        Err(format!("{}: {} of {steps} steps rejected", config.name(), steps - accepted))
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("--list") {
        for c in all_configs() {
            println!("{}", c.name());
        }
        return ExitCode::SUCCESS;
    }
    let (Some(config), Some(passes), 2) = (
        args.first().and_then(|n| Config::from_name(n)),
        args.get(1).and_then(|s| s.parse().ok()),
        args.len(),
    ) else {
        eprintln!("usage: count_steps CONFIG PASSES   (configs: count_steps --list)");
        return ExitCode::from(2);
    };
    match dispatch!(config, run(config, passes)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("count_steps: {e}");
            ExitCode::FAILURE
        }
    }
}
