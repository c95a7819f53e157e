//! Golden trajectory digests: reference runs simulated by a fresh `companion sim` process
//! must reproduce, bit for bit, the [`TrajectoryDigest`] stored in
//! `runtime/tests/golden/digests.txt` — the eight runs of the paper's §4.3, a car-like, an
//! omnidirectional and a single-precision run.
//!
//! A digest changes when any number of any step changes: a reordered sum, another libm, a
//! compiler contracting `a·b + c` into a fused multiply-add. When a change is *meant* to
//! move the trajectories, rerun with `COMPANION_BLESS=1` to rewrite the file and say why
//! in the commit; otherwise a mismatch is a regression of determinism.
//!
//! [`TrajectoryDigest`]: companion_runtime::domain::record::TrajectoryDigest

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_companion");

/// The reference runs: a name and the `companion sim` arguments.
const RUNS: &[(&str, &[&str])] = &[
    ("uni-1a", &["--trajectory", "1", "--choice", "a"]),
    ("uni-1b", &["--trajectory", "1", "--choice", "b"]),
    ("uni-1c", &["--trajectory", "1", "--choice", "c"]),
    ("uni-1d", &["--trajectory", "1", "--choice", "d"]),
    ("uni-2a", &["--trajectory", "2", "--choice", "a"]),
    ("uni-2b", &["--trajectory", "2", "--choice", "b"]),
    ("uni-2c", &["--trajectory", "2", "--choice", "c"]),
    ("uni-2d", &["--trajectory", "2", "--choice", "d"]),
    ("car-1c", &["--trajectory", "1", "--choice", "c", "--platform", "car"]),
    ("omni-2a", &["--trajectory", "2", "--choice", "a", "--platform", "omni"]),
    ("uni-1a-f32", &["--trajectory", "1", "--choice", "a", "--scalar", "f32"]),
];

fn golden_file() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/digests.txt")
}

/// The digests stored in the repository, by name.
fn stored() -> Vec<(String, String)> {
    let text = std::fs::read_to_string(golden_file()).unwrap_or_default();
    text.lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .map(|l| {
            let mut f = l.split_whitespace();
            let name = f.next().unwrap_or_default().to_string();
            let digest = f.next().unwrap_or_default().to_string();
            (name, digest)
        })
        .collect()
}

/// Runs `companion sim` in a fresh process and returns `summary.json`'s digest.
fn simulate(name: &str, args: &[&str]) -> String {
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("golden-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let status = Command::new(BIN)
        .arg("sim")
        .args(args)
        .args(["--no-plots", "--log-every", "1000", "--out"])
        .arg(&out)
        .output()
        .expect("companion runs");
    assert!(status.status.success(), "{name}: {}", String::from_utf8_lossy(&status.stderr));
    let text = std::fs::read_to_string(out.join("summary.json")).expect("summary.json");
    let _ = std::fs::remove_dir_all(&out);
    let json: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    let digest = json["trajectory_digest"].as_str().expect("a trajectory_digest").to_string();
    assert_eq!(digest.len(), 16, "{name}: {digest}");
    digest
}

#[test]
fn reference_runs_reproduce_their_stored_digests() {
    // Two runs at a time: the machine has 2 cores and the other tests run too.
    let measured: Vec<(&str, &[&str], String)> = std::thread::scope(|scope| {
        let handles: Vec<_> = RUNS
            .chunks(RUNS.len().div_ceil(2))
            .map(|chunk| {
                scope.spawn(move || chunk.iter().map(|(n, a)| (*n, *a, simulate(n, a))).collect::<Vec<_>>())
            })
            .collect();
        handles.into_iter().flat_map(|h| h.join().expect("a simulation thread")).collect()
    });

    if std::env::var_os("COMPANION_BLESS").is_some() {
        let mut text = String::from(
            "# Trajectory digests of reference runs (runtime/tests/golden.rs): name, digest,\n\
             # `companion sim` arguments. Rewritten by COMPANION_BLESS=1 cargo test --release\n\
             # -p companion-runtime --test golden; say in the commit why trajectories moved.\n",
        );
        for (name, args, digest) in &measured {
            let _ = writeln!(text, "{name:<12} {digest}  {}", args.join(" "));
        }
        std::fs::write(golden_file(), text).expect("writing the golden file");
        return;
    }

    let stored = stored();
    let mut wrong = Vec::new();
    for (name, _, digest) in &measured {
        match stored.iter().find(|(n, _)| n == name) {
            Some((_, d)) if d == digest => {}
            Some((_, d)) => wrong.push(format!("{name}: stored {d}, this build {digest}")),
            None => wrong.push(format!("{name}: no stored digest (this build {digest})")),
        }
    }
    assert!(
        wrong.is_empty(),
        "trajectories drifted from {} (rerun with COMPANION_BLESS=1 if the change is meant):\n{}",
        golden_file().display(),
        wrong.join("\n")
    );
}

/// The same scenario simulated twice in two fresh processes gives the same digest, and a
/// different scenario another one: the digest is a function of the trajectory.
#[test]
fn digest_is_a_function_of_the_trajectory() {
    let args: &[&str] = &["--trajectory", "1", "--choice", "a", "--duration", "2"];
    let a = simulate("twice-1", args);
    let b = simulate("twice-2", args);
    assert_eq!(a, b);
    let c = simulate("other", &["--trajectory", "1", "--choice", "a", "--duration", "2", "--dt", "0.002"]);
    assert_ne!(a, c);
}

/// `--arm rpr` (the default) is today's planar path: the reference run with the flag gives
/// its stored digest, bit for bit.
#[test]
fn arm_rpr_is_the_planar_path() {
    let with = simulate("arm-rpr", &["--trajectory", "1", "--choice", "a", "--arm", "rpr"]);
    let stored = stored();
    let (_, want) = stored.iter().find(|(n, _)| n == "uni-1a").expect("uni-1a is stored");
    assert_eq!(&with, want);
}
