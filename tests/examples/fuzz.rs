//! The closed-loop fuzz at scale (`companion_tests::fuzz`): garbage bursts injected into
//! running loops of every platform, scalar type, run and discretisation; fails (exit 1) on a
//! lock-out, a non-finite command or a limit exceeded.
//!
//! ```text
//! cargo run --release -p companion-tests --example fuzz -- [STEPS] [SECONDS] [SEED]
//! ```
//!
//! `STEPS` closed-loop steps (default 10 000 000) in episodes of 20 000, stopped after
//! `SECONDS` of wall time (default: no limit; CI gives it a box and says so in the report).

use std::io::Write as _;
use std::time::Duration;

use companion_tests::fuzz::{fuzz, FuzzConfig};

fn arg<T: std::str::FromStr>(n: usize, name: &str, default: T) -> T {
    match std::env::args().nth(n) {
        None => default,
        Some(a) => a.parse().unwrap_or_else(|_| {
            eprintln!("fuzz: {name} must be a number, got {a:?}");
            std::process::exit(2)
        }),
    }
}

fn main() {
    let steps = arg::<f64>(1, "STEPS", 1e7) as u64;
    let seconds = arg::<f64>(2, "SECONDS", 0.0);
    let seed = arg::<u64>(3, "SEED", 1);
    let cfg = FuzzConfig {
        steps,
        seed,
        time_box: (seconds > 0.0).then(|| Duration::from_secs_f64(seconds)),
        ..FuzzConfig::default()
    };
    eprintln!(
        "fuzz: {steps} steps, seed {seed}{}",
        if seconds > 0.0 { format!(", {seconds} s box") } else { String::new() }
    );
    let report = fuzz(&cfg, &|done| {
        if done % 1_000_000 < cfg.episode_steps {
            eprint!("\rfuzz: {done} steps");
            let _ = std::io::stderr().flush();
        }
    });
    eprintln!();
    print!("{report}");
    if !report.passed() {
        eprintln!("fuzz: FAILED");
        std::process::exit(1);
    }
}
