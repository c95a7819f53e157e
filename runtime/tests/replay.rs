//! `--mcap FILE` through the binary, read back by an independent MCAP reader: the `mcap`
//! package from PyPI (Foxglove's Python reader) in `tests/mcap/check_replay.py`, which checks
//! the channels, topics, schema names and encodings, the message counts (one frame per row of
//! timeseries.csv), the time order, and decoded values against timeseries.csv (the end
//! effector as the composition of the transform chain). Also: a run that failed still leaves
//! a readable file.
//!
//! Needs `python3` with `mcap` (`scripts/setup` installs it). Without it each test says so and
//! passes — unless `COMPANION_REQUIRE_MCAP_READER` is set (CI sets it), when its absence
//! fails.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

const BIN: &str = env!("CARGO_BIN_EXE_companion");

fn checker() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/mcap/check_replay.py")
}

/// Whether the Python reader can run here; says why not once.
fn available() -> bool {
    static OK: OnceLock<bool> = OnceLock::new();
    *OK.get_or_init(|| {
        let probe = Command::new("python3").args(["-c", "import mcap.reader"]).output();
        let ok = probe.as_ref().is_ok_and(|o| o.status.success());
        if !ok {
            let why = match probe {
                Err(e) => format!("python3 not found ({e})"),
                Ok(o) => {
                    format!("python3 has no mcap module ({})", String::from_utf8_lossy(&o.stderr).trim())
                }
            };
            assert!(
                std::env::var_os("COMPANION_REQUIRE_MCAP_READER").is_none(),
                "COMPANION_REQUIRE_MCAP_READER is set but the Python MCAP reader cannot run: {why}"
            );
            eprintln!("SKIPPED: the replay tests need python3 with mcap (pip, scripts/setup): {why}");
        }
        ok
    })
}

fn dir(tag: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("replay-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn companion(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().unwrap()
}

/// The checker's verdict on `file` (with `csv` for the values): the counts it printed.
fn check(file: &Path, csv: Option<&Path>, platform: &str) -> serde_json::Value {
    let mut c = Command::new("python3");
    c.arg(checker()).arg(file).args(["--platform", platform]);
    if let Some(csv) = csv {
        c.arg("--csv").arg(csv);
    }
    let out = c.output().unwrap();
    assert!(
        out.status.success(),
        "the independent reader refused {}:\n{}",
        file.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn csv_rows(csv: &Path) -> u64 {
    std::fs::read_to_string(csv).unwrap().lines().count() as u64 - 1
}

#[test]
fn a_simulated_run_reads_back_with_an_independent_reader() {
    if !available() {
        return;
    }
    let d = dir("sim");
    for (platform, trajectory, log_every) in [("unicycle", "1", "10"), ("car", "2", "7"), ("omni", "2", "1")]
    {
        let out = d.join(platform);
        // The file in a folder that does not exist yet.
        let file = d.join("replays").join(format!("{platform}.mcap"));
        let o = companion(&[
            "sim",
            "--duration",
            "3",
            "--no-plots",
            "--platform",
            platform,
            "--trajectory",
            trajectory,
            "--log-every",
            log_every,
            "--out",
            out.to_str().unwrap(),
            "--mcap",
            file.to_str().unwrap(),
        ]);
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{platform}: {}", String::from_utf8_lossy(&o.stderr));
        let csv = out.join("timeseries.csv");
        let rows = csv_rows(&csv);
        assert!(stdout.contains(&format!("({rows} frames")), "{stdout}");
        let got = check(&file, Some(&csv), platform);
        assert_eq!(got["frames"], rows, "{got}");
        assert_eq!(got["csv_rows"], rows, "{got}");
        assert_eq!(got["last_ns"], 3_000_000_000u64, "{got}");
        for topic in ["/tf", "/scene", "/joint_states", "/command", "/tracking_error"] {
            assert_eq!(got["topics"][topic], rows, "{topic}: {got}");
        }
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// `sim --arm ur5|panda --mcap`: the spatial arm's links, its joints and the six components
/// of `e_p` read back by the independent reader and checked against the spatial
/// timeseries.csv (the effector as the composition of the `/tf` chain, in 3D).
#[test]
fn a_spatial_run_reads_back_with_an_independent_reader() {
    if !available() {
        return;
    }
    let d = dir("spatial");
    for (arm, platform, joints) in [("ur5", "unicycle", 6), ("panda", "omni", 7)] {
        let out = d.join(arm);
        let file = d.join(format!("{arm}.mcap"));
        let o = companion(&[
            "sim",
            "--arm",
            arm,
            "--duration",
            "2",
            "--no-plots",
            "--platform",
            platform,
            "--log-every",
            "5",
            "--out",
            out.to_str().unwrap(),
            "--mcap",
            file.to_str().unwrap(),
        ]);
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{arm}: {}", String::from_utf8_lossy(&o.stderr));
        let csv = out.join("timeseries.csv");
        let rows = csv_rows(&csv);
        assert_eq!(rows, 401, "2 s at 1 ms, every 5th step and the last");
        assert!(stdout.contains(&format!("({rows} frames")), "{stdout}");
        let got = check(&file, Some(&csv), platform);
        assert_eq!(got["frames"], rows, "{got}");
        assert_eq!(got["csv_rows"], rows, "{got}");
        let header = std::fs::read_to_string(&csv).unwrap();
        let header = header.lines().next().unwrap();
        assert!(header.contains(&format!("q{joints},")) && !header.contains(&format!("q{},", joints + 1)));
    }
    // A path that cannot be written is refused before the run starts.
    let blocked = d.join("file");
    std::fs::write(&blocked, "").unwrap();
    let o = companion(&[
        "sim",
        "--arm",
        "ur5",
        "--duration",
        "1",
        "--out",
        d.join("never").to_str().unwrap(),
        "--mcap",
        blocked.join("x.mcap").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!d.join("never").join("timeseries.csv").exists(), "the run did not start");
    let _ = std::fs::remove_dir_all(&d);
}

/// A target file whose arm starts at a joint limit: the law rejects every step.
const STUCK_AT_A_LIMIT: &str =
    "[initial]\nq = [0.0, 0.0, 0.0]\n\n[[segment]]\nduration = 1\nvelocity = [0.0, 0.0, 0.0]\n";

#[test]
fn a_failed_run_leaves_a_readable_replay() {
    if !available() {
        return;
    }
    let d = dir("failed");
    // 1. The law rejects every step: exit 6, every row in the replay, status `rejected:…`.
    let target = d.join("t.toml");
    std::fs::write(&target, STUCK_AT_A_LIMIT).unwrap();
    let (out, file) = (d.join("rejected"), d.join("rejected.mcap"));
    let o = companion(&[
        "sim",
        "--duration",
        "0.5",
        "--no-plots",
        "--target-file",
        target.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--mcap",
        file.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(6), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = out.join("timeseries.csv");
    assert!(std::fs::read_to_string(&csv).unwrap().contains("rejected:JointAtLimit"));
    let got = check(&file, Some(&csv), "unicycle");
    assert_eq!(got["frames"], csv_rows(&csv), "{got}");

    // 2. An error part-way: timeseries.csv cannot be written (the disk is full), so the run
    //    stops with exit 2 — and the replay holds the frames up to the error, finished.
    #[cfg(target_os = "linux")]
    {
        let (out, file) = (d.join("full"), d.join("full.mcap"));
        std::fs::create_dir_all(&out).unwrap();
        std::os::unix::fs::symlink("/dev/full", out.join("timeseries.csv")).unwrap();
        let o = companion(&[
            "sim",
            "--duration",
            "60",
            "--log-every",
            "1",
            "--no-plots",
            "--out",
            out.to_str().unwrap(),
            "--mcap",
            file.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains("timeseries.csv"), "{err}");
        let got = check(&file, None, "unicycle");
        let frames = got["frames"].as_u64().unwrap();
        assert!(frames > 0 && frames < 60_001, "{got}");
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn hil_in_lockstep_writes_the_same_replay_as_sim_byte_for_byte() {
    // Needs no Python: the two files are compared byte for byte.
    let d = dir("lockstep");
    let name = format!("rp{}", std::process::id());
    let (sim, hil) = (d.join("sim.mcap"), d.join("hil.mcap"));
    let (sim_out, hil_out) = (d.join("sim"), d.join("hil"));
    let common = ["--duration", "2", "--trajectory", "2", "--no-plots", "--log-every", "3"];
    let mut a = vec!["sim", "--out", sim_out.to_str().unwrap(), "--mcap", sim.to_str().unwrap()];
    a.extend(common);
    let o = companion(&a);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut a = vec![
        "hil",
        "--lockstep",
        "--name",
        &name,
        "--out",
        hil_out.to_str().unwrap(),
        "--mcap",
        hil.to_str().unwrap(),
    ];
    a.extend(common);
    let o = companion(&a);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (x, y) = (std::fs::read(&sim).unwrap(), std::fs::read(&hil).unwrap());
    assert!(x.len() > 10_000, "{}", x.len());
    assert!(x == y, "sim and hil --lockstep replays differ ({} and {} bytes)", x.len(), y.len());
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_plant_whose_controller_is_killed_leaves_a_readable_replay() {
    if !available() {
        return;
    }
    let d = dir("killed");
    let name = format!("rk{}", std::process::id());
    let (out, file) = (d.join("out"), d.join("run.mcap"));
    let run = |role: &str, extra: &[&str]| {
        let mut a = vec![role, "--name", &name, "--duration", "30", "--no-plots", "--quiet"];
        a.extend(extra);
        Command::new(BIN)
            .args(&a)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    let plant = run("plant", &["--out", out.to_str().unwrap(), "--mcap", file.to_str().unwrap()]);
    let mut control = run("control", &[]);
    // Killed once the plant has streamed 50 rows (a counted state, not a sleep that a loaded
    // machine may spend starting up); a watchdog, not a measurement, bounds the wait.
    let csv = out.join("timeseries.csv");
    let end = std::time::Instant::now() + std::time::Duration::from_secs(120);
    while std::fs::read(&csv).map_or(0, |b| b.iter().filter(|&&c| c == b'\n').count()) <= 50 {
        assert!(std::time::Instant::now() < end, "the plant wrote no 50 rows in 120 s");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    control.kill().unwrap();
    let _ = control.wait();
    let o = plant.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{err}");
    let got = check(&file, Some(&csv), "unicycle");
    let frames = got["frames"].as_u64().unwrap();
    assert!(frames > 10 && frames < 3_000, "{got}");
    let _ = std::fs::remove_dir_all(&d);
}
