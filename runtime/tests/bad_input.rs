//! Bad input through the binary, as a new user would type it: every bad flag value and
//! config error ends with exit code 2 and a message that names the flag or parameter and its
//! rule, never a panic, and leaves nothing behind (no output folder). Then sweeps: every
//! numeric flag and every numeric config key with non-finite, negative, zero, huge and tiny
//! values — whatever is accepted runs, nothing panics.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_companion");

/// A fresh folder for `tag` (the output folders go below it and must not appear).
fn dir(tag: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("bad-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// How long any one of these runs may take: they are short or refused at once, so a run
/// still going after this is a hang (as a lag of 1e-300 s once was).
const HANG: Duration = Duration::from_secs(60);

/// Runs `companion args…`; (exit code, stderr). Fails the test if the run hangs.
fn run(args: &[&str]) -> (Option<i32>, String) {
    let mut child = Command::new(BIN)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stderr.read_to_string(&mut text);
        text
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > HANG {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{args:?} still running after {HANG:?}");
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    (status.code(), reader.join().unwrap())
}

/// Asserts the run of `args` (with `--out <d>/out` added) fails with code 2, says `says`,
/// does not panic and writes no output folder.
fn refused(d: &Path, args: &[&str], says: &[&str]) {
    let out = d.join("out");
    let mut all: Vec<&str> = args.to_vec();
    let o = out.to_str().unwrap();
    all.extend(["--out", o]);
    let (code, err) = run(&all);
    assert!(!err.contains("panicked"), "{args:?} panicked:\n{err}");
    assert_eq!(code, Some(2), "{args:?}: exit code {code:?}\n{err}");
    for s in says {
        assert!(err.contains(s), "{args:?}: the message does not say {s:?}:\n{err}");
    }
    assert!(!out.exists(), "{args:?} left {} behind", out.display());
}

fn file(d: &Path, name: &str, text: &str) -> String {
    let p = d.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_string()
}

#[test]
fn bad_flag_values_are_refused_by_name_and_rule_before_anything_starts() {
    let d = dir("flags");
    let name = format!("bad{}", std::process::id());
    let n = name.as_str();
    let cases: &[(&[&str], &[&str])] = &[
        (
            &["--startup-timeout", "nan"],
            &["--startup-timeout must be a number of seconds in [0, 86400], got NaN"],
        ),
        (
            &["--startup-timeout", "-1"],
            &["--startup-timeout must be a number of seconds in [0, 86400], got -1"],
        ),
        (&["--startup-timeout", "inf"], &["--startup-timeout", "got inf"]),
        (&["--startup-timeout", "1e300"], &["--startup-timeout", "got 1.000e300"]),
        (&["--peer-timeout", "0"], &["--peer-timeout must be a number of seconds in (0, 3600], got 0"]),
        (&["--peer-timeout", "1e300"], &["--peer-timeout", "got 1.000e300"]),
        (&["--deadline-us", "0"], &["--deadline-us", "0 is not in 1..=1000000"]),
        (&["--deadline-us", "2000"], &["--deadline-us must be in (0, period] = (0, 1000] µs"]),
        (&["--rate", "0"], &["--rate must be between 1 and 100000 Hz, got 0"]),
        (&["--rate", "nan"], &["--rate must be between 1 and 100000 Hz, got NaN"]),
        (&["--silence-ms", "0"], &["--silence-ms", "0 is not in 1..=60000"]),
        (&["--spin-margin-us", "18446744073709551615"], &["--spin-margin-us", "not in 0..=1000000"]),
        (&["--hold-periods", "4294967295"], &["--hold-periods", "not in 0..=100000"]),
        (&["--dt", "0"], &["dt must be a positive number of seconds, got 0"]),
        (&["--dt", "-1"], &["dt must be a positive number of seconds, got -1"]),
        (&["--dt", "nan"], &["dt must be a positive number of seconds, got NaN"]),
        (&["--dt", "-inf"], &["dt must be a positive number of seconds, got -inf"]),
        (&["--seed", "-1"], &["invalid value '-1' for '--seed <SEED>'"]),
        (&["--hold-periods", "-1"], &["invalid value '-1' for '--hold-periods <K>'"]),
        (&["--max-command-age", "9"], &["--max-command-age", "9 is not in 0..=8"]),
        (&["--dt", "0.5"], &["dt = 0.5 s is longer than the law's largest admitted period"]),
        (&["--duration", "0"], &["duration must be a positive number of seconds, got 0"]),
        (&["--duration", "-5"], &["duration must be a positive number of seconds, got -5"]),
        (&["--duration", "1e300"], &["duration / dt", "more than 1e9"]),
        (&["--log-every", "0"], &["log_every must be at least 1"]),
        (&["--max-output-mb", "0"], &["the run would write about", "--log-every"]),
        (&["--actuator-lag", "nan"], &["actuator_lag", "must be finite"]),
        (&["--actuator-lag", "-1"], &["actuator_lag"]),
        (&["--actuator-lag", "1e-300"], &["`actuator_lag` must be >= 1e-4 s (got 1e-300)"]),
        (&["--wheel-scale-error", "-2"], &["wheel_scale_error` must be > -1 (got -2)"]),
        (&["--max-miss-fraction", "2"], &["--max-miss-fraction must be a fraction in [0, 1], got 2"]),
        (&["--max-rejected", "nan"], &["--max-rejected must be a fraction in [0, 1], got NaN"]),
        (&["--name", "a/b"], &["--name must be 1 to 32 characters"]),
        (&["--name", ""], &["--name must be 1 to 32 characters"]),
        (&["--trajectory", "3"], &["--trajectory", "3 is not in 1..=2"]),
        (&["--rt-priority", "0"], &["--rt-priority", "0 is not in 1..=99"]),
        (&["--target-file", "/nonexistent/t.toml"], &["target file /nonexistent/t.toml", "No such file"]),
        (&["--config", "/nonexistent/c.toml"], &["reading /nonexistent/c.toml"]),
        (&["--chaos", "1", "--duration", "3"], &["--chaos needs a run of at least 5 s"]),
        (&["--chaos", "1", "--lockstep"], &["--chaos needs real time"]),
        (&["--inject", "bogus@1"], &["--inject: unknown kind"]),
        (&["--child"], &["--child is for the plant"]),
    ];
    for (args, says) in cases {
        // A name of our own (two runs of the suite never share a lock), unless the case is
        // about the name.
        let mut all = vec!["hil"];
        if !args.contains(&"--name") {
            all.extend(["--name", n]);
        }
        all.extend(*args);
        refused(&d, &all, says);
    }
    // The roles alone check the same flags.
    for role in ["plant", "control"] {
        refused(&d, &[role, "--name", n, "--startup-timeout", "nan"], &["--startup-timeout"]);
        refused(&d, &[role, "--name", n, "--chaos", "1"], &["--chaos is for `companion hil`"]);
    }
    refused(&d, &["sim", "--delay", "-1"], &["delay must be a number of seconds in [0,"]);
    refused(&d, &["sim", "--delay", "1"], &["delay must be a number of seconds in [0,"]);
    refused(&d, &["sim", "--dt", "1e-8", "--duration", "5"], &["about 16.5 GB", "--log-every 166 or more"]);
    refused(
        &d,
        &["sim", "--max-rejected", "-0.1"],
        &["--max-rejected must be a fraction in [0, 1], got -0.1"],
    );
    refused(&d, &["latency", "--cycles", "0"], &["--cycles must be at least 1"]);
    refused(&d, &["latency", "--repeat", "0"], &["--repeat", "1..=1000"]);
    refused(&d, &["latency", "--release-timers", "sleep,never"], &["--release-timers", "never"]);
    refused(&d, &["latency", "--hil-only", "--skip-hil"], &["--hil-only", "--skip-hil"]);
    refused(&d, &["hil", "--release-timer", "soon"], &["--release-timer", "soon"]);
    // --mcap: a path that cannot be written is refused before the run starts; with a bad
    // flag, no replay file is made either.
    let here = d.to_str().unwrap();
    refused(
        &d,
        &["sim", "--mcap", "/proc/companion-replay.mcap"],
        &["--mcap: creating /proc/companion-replay.mcap"],
    );
    refused(&d, &["sim", "--mcap", here], &["--mcap: creating", "Is a directory"]);
    let mcap = d.join("replay.mcap");
    refused(&d, &["sim", "--dt", "0", "--mcap", mcap.to_str().unwrap()], &["dt must be a positive"]);
    assert!(!mcap.exists(), "a refused run left {}", mcap.display());
    refused(&d, &["sim", "--all", "--mcap", mcap.to_str().unwrap()], &["--mcap writes one run"]);
    assert!(!mcap.exists(), "a refused run left {}", mcap.display());
    // The plant records: `hil` (its child plant) and `plant` check the path; `control` has
    // nothing to record.
    for role in ["hil", "plant"] {
        refused(
            &d,
            &[role, "--name", n, "--mcap", "/proc/companion-replay.mcap"],
            &["--mcap: creating /proc/companion-replay.mcap"],
        );
    }
    refused(&d, &["control", "--name", n, "--mcap", mcap.to_str().unwrap()], &["--mcap is for the plant"]);
    assert!(!mcap.exists(), "a refused run left {}", mcap.display());
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn config_and_target_file_errors_are_refused_by_name_and_rule() {
    let d = dir("files");
    let cases: &[(&str, &[&str])] = &[
        ("[controller]\nx_star = 1e308\n", &["unknown field `x_star`"]),
        (
            "[controller]\ngain = [1, 2, 3, 4]\n",
            &["invalid length 4, expected an array of exactly 3 numbers"],
        ),
        ("[controller]\ngain = [1e300, 1, 1]\n", &["parameter `gain` (joint 1): must be <= 1e6"]),
        ("[controller]\nmu = -1\n", &["parameter `mu`"]),
        ("[car]\nepsilon = 0.3\neta = [2, 3, 2, 99]\nk = 5\n", &["unknown field `eta`"]),
        ("[plant.noise]\nposition = -1\nangle = 1\njoints = 1\n", &["noise.position` must be >= 0 (got -1)"]),
        ("[velocity_limits]\nforward = -1\n", &["velocity_limits.forward`: must be > 0"]),
        ("[controller]\nmax_time_step = 1e300\n", &["max_time_step`: must be <= 1e0"]),
        ("junk\n", &["key with no value"]),
    ];
    for (i, (text, says)) in cases.iter().enumerate() {
        let cfg = file(&d, &format!("c{i}.toml"), text);
        refused(&d, &["sim", "--duration", "1", "--config", &cfg], says);
        let name = format!("badcfg{}-{i}", std::process::id());
        refused(&d, &["hil", "--duration", "1", "--name", &name, "--config", &cfg], says);
    }
    let target = file(&d, "t.toml", "junk\n");
    refused(&d, &["sim", "--target-file", &target], &["target file", "key with no value"]);
    let name = format!("badtgt{}", std::process::id());
    refused(&d, &["hil", "--name", &name, "--target-file", &target], &["target file", "key with no value"]);
    let _ = std::fs::remove_dir_all(&d);
}

/// Values a careless or malicious user might give any number.
const VALUES: [&str; 12] =
    ["nan", "inf", "-inf", "-1", "0", "1e300", "-1e300", "1e-300", "18446744073709551616", "-0", "abc", ""];

#[test]
fn no_flag_value_makes_the_program_panic_or_leave_files() {
    let d = dir("sweep");
    let flags = [
        "--dt",
        "--duration",
        "--rate",
        "--deadline-us",
        "--hold-periods",
        "--max-miss-fraction",
        "--max-rejected",
        "--spin-margin-us",
        "--silence-ms",
        "--peer-timeout",
        "--startup-timeout",
        "--actuator-lag",
        "--wheel-scale-error",
        "--seed",
        "--log-every",
        "--max-output-mb",
        "--rt-priority",
        "--plant-cpu",
        "--trajectory",
        "--chaos",
        "--max-command-age",
    ];
    let out = d.join("out");
    let o = out.to_str().unwrap();
    let mut runs = 0;
    let mut accepted_values = 0;
    for flag in flags {
        for v in VALUES {
            // The plant alone, with nobody to join it within 0 s: a run that passes every check
            // still ends at once (exit 2, nothing written).
            let name = format!("sweep{}", std::process::id());
            let mut args = vec!["plant", "--name", &name, "--out", o, flag, v];
            if flag != "--startup-timeout" {
                args.extend(["--startup-timeout", "0"]);
            }
            let (code, err) = run(&args);
            runs += 1;
            assert!(!err.contains("panicked"), "{flag} {v:?} panicked:\n{err}");
            assert_eq!(code, Some(2), "{flag} {v:?}: {code:?}\n{err}");
            assert!(!out.exists(), "{flag} {v:?} left {o} behind");
            // Either refused, naming the flag (as typed, or as the parameter it sets), or
            // accepted and then ended for want of a peer.
            let param = flag.trim_start_matches('-').replace('-', "_");
            let refused =
                err.contains(flag) || err.contains(&param) || err.contains("the run would write about");
            let accepted = err.contains("no control joined");
            assert!(refused != accepted, "{flag} {v:?}: neither refused by name nor run:\n{err}");
            if accepted {
                accepted_values += 1;
            }
        }
    }
    assert_eq!(runs, flags.len() * VALUES.len());
    // Some values are fine (`--seed 0`, `--hold-periods 0`): the sweep ran the plant too.
    assert!(accepted_values > 0 && accepted_values < runs / 2, "{accepted_values} of {runs} accepted");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn no_config_value_makes_the_program_panic() {
    let d = dir("cfg-sweep");
    let keys: &[(&str, &str, bool)] = &[
        ("controller", "gain", true),
        ("controller", "target_in_effector", true),
        ("controller", "preferred_pose", true),
        ("controller", "penalty_weight", true),
        ("controller", "penalty_margin", true),
        ("controller", "k_bar", true),
        ("controller", "d", true),
        ("controller", "rest_sigma", true),
        ("controller", "joint_velocity_limits", true),
        ("controller", "regularisation_gain", false),
        ("controller", "regularisation_decay", false),
        ("controller", "filter_sigma", false),
        ("controller", "filter_xi", false),
        ("controller", "mu", false),
        ("controller", "nu", false),
        ("controller", "lambda", false),
        ("controller", "gamma_1", false),
        ("controller", "gamma_2", false),
        ("controller", "rest_xi", false),
        ("controller", "max_time_step", false),
        ("controller", "joint_step_fraction", false),
        ("controller", "max_delay", false),
        ("controller", "max_turn_per_step", false),
        ("controller", "rest_reach", false),
        ("controller", "heading_rate", false),
        ("controller", "heading_xi", false),
        // A spatial arm's law's: a planar run refuses them by name, whatever the value.
        ("controller", "damping_below", false),
        ("controller", "damping_depth", false),
        ("controller", "singular_below", false),
        ("controller", "reach_margin", false),
        ("velocity_limits", "forward", false),
        ("velocity_limits", "angular", false),
        ("acceleration_limits", "forward", false),
        ("acceleration_limits", "angular", false),
        ("acceleration_limits", "joints", true),
        ("plant", "actuator_lag", false),
        ("plant", "wheel_scale_error", false),
    ];
    let values = ["nan", "inf", "-inf", "-1.0", "0.0", "1e300", "-1e300", "1e-300"];
    let mut outcomes = std::collections::BTreeMap::new();
    for (table, key, array) in keys {
        for v in values {
            let value = if *array { format!("[{v}, {v}, {v}]") } else { v.to_string() };
            let cfg = file(&d, "c.toml", &format!("[{table}]\n{key} = {value}\n"));
            for platform in ["unicycle", "car"] {
                let out = d.join("out");
                let o = out.to_str().unwrap();
                let (code, err) = run(&[
                    "sim",
                    "--duration",
                    "0.05",
                    "--no-plots",
                    "--platform",
                    platform,
                    "--config",
                    &cfg,
                    "--out",
                    o,
                ]);
                assert!(!err.contains("panicked"), "{key} = {value} ({platform}) panicked:\n{err}");
                assert!(matches!(code, Some(0 | 2 | 6)), "{key} = {value} ({platform}): {code:?}\n{err}");
                if code == Some(2) {
                    assert!(!out.exists(), "{key} = {value}: refused, yet {o} was written");
                    assert!(err.contains(key) || err.contains("invalid"), "{key} = {value}: {err}");
                } else {
                    // Ran: the data is on disk, and a run that failed says so.
                    let summary = std::fs::read_to_string(out.join("summary.json")).unwrap_or_else(|e| {
                        panic!("{key} = {value}: ran ({code:?}) but no summary.json: {e}")
                    });
                    assert_eq!(
                        summary.contains("\"failures\": []"),
                        code == Some(0),
                        "{key} = {value}: exit {code:?} with\n{summary}"
                    );
                }
                *outcomes.entry(code.unwrap()).or_insert(0) += 1;
                let _ = std::fs::remove_dir_all(&out);
            }
        }
    }
    // The sweep reached the runs, not only the parser: some values run (the defaults are
    // among them), most are refused.
    eprintln!("exit codes over the sweep: {outcomes:?}");
    assert!(outcomes.get(&0).is_some_and(|&n| n > 0), "{outcomes:?}");
    assert!(outcomes.get(&2).is_some_and(|&n| n > 100), "{outcomes:?}");
    let _ = std::fs::remove_dir_all(&d);
}

/// `[acceleration_limits] joints` with another number of values than the arm has joints:
/// refused by name (exit 2, nothing written), for the planar arm and for a spatial one.
#[test]
fn acceleration_limits_of_another_joint_count_are_refused() {
    let d = dir("acc-joints");
    let cfg = file(&d, "c.toml", "[acceleration_limits]\njoints = [1.0, 2.0]\n");
    for (arm, joints) in [(None, 3), (Some("ur5"), 6)] {
        let out = d.join("out");
        let o = out.to_str().unwrap();
        let mut args = vec!["sim", "--duration", "0.05", "--no-plots", "--config", &cfg, "--out", o];
        if let Some(a) = arm {
            args.extend(["--arm", a]);
        }
        let (code, err) = run(&args);
        assert_eq!(code, Some(2), "{arm:?}: {err}");
        assert!(
            err.contains(&format!("acceleration_limits.joints has 2 values; the arm has {joints} joints")),
            "{arm:?}: {err}"
        );
        assert!(!out.exists(), "{arm:?}: refused, yet {o} was written");
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// A target file whose arm starts at a joint limit: the law rejects every step.
const STUCK_AT_A_LIMIT: &str =
    "[initial]\nq = [0.0, 0.0, 0.0]\n\n[[segment]]\nduration = 1\nvelocity = [0.0, 0.0, 0.0]\n";

#[test]
fn a_run_whose_every_step_is_rejected_fails_with_its_files_written() {
    let d = dir("rejected");
    let target = file(&d, "t.toml", STUCK_AT_A_LIMIT);
    let out = d.join("out");
    let o = out.to_str().unwrap();
    let name = format!("rej{}", std::process::id());
    for args in [
        vec!["sim", "--duration", "0.5", "--no-plots", "--target-file", &target, "--out", o],
        vec![
            "hil",
            "--lockstep",
            "--name",
            &name,
            "--duration",
            "0.5",
            "--no-plots",
            "--target-file",
            &target,
            "--out",
            o,
        ],
    ] {
        let _ = std::fs::remove_dir_all(&out);
        let (code, err) = run(&args);
        assert_eq!(code, Some(6), "{args:?}:\n{err}");
        assert!(err.contains("RUN FAILED: the law rejected 501 of 501 steps"), "{args:?}:\n{err}");
        assert!(err.contains("joint 2 is at or beyond its limit"), "{args:?}:\n{err}");
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        assert_eq!(summary["rejected_steps"], 501, "{summary}");
        assert_eq!(summary["failures"][0]["failure"], "rejected", "{summary}");
        let rows = std::fs::read_to_string(out.join("timeseries.csv")).unwrap().lines().count();
        assert!(rows > 40, "{args:?}: {rows} lines in timeseries.csv");
    }
    // With the limit raised to everything, the same run is a success.
    let _ = std::fs::remove_dir_all(&out);
    let (code, err) = run(&[
        "sim",
        "--duration",
        "0.5",
        "--no-plots",
        "--target-file",
        &target,
        "--max-rejected",
        "1",
        "--out",
        o,
    ]);
    assert_eq!(code, Some(0), "{err}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn every_command_lists_its_exit_codes_in_help() {
    for command in ["sim", "hil", "plant", "control", "latency"] {
        let out = Command::new(BIN).args([command, "--help"]).output().unwrap();
        assert!(out.status.success(), "{command} --help");
        let help = String::from_utf8_lossy(&out.stdout);
        for line in
            ["Exit codes:", "    2    bad flag value", "    6    the run completed", "  130    interrupted"]
        {
            assert!(help.contains(line), "{command} --help lacks {line:?}:\n{help}");
        }
    }
}

/// An arm file (`--arm FILE`) or spatial target that breaks a rule is refused before anything
/// runs, naming the field: too few or too many joints, empty limits, a home outside them, a
/// non-orthonormal mounting rotation, a target the chain cannot reach in height, a start
/// outside the limits; and flags spatial runs do not have.
#[test]
fn bad_arm_files_and_spatial_targets_are_refused_by_field() {
    let d = dir("arm");
    let ur5 =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/arms/ur5.toml"))
            .unwrap();
    let joint = "[[joint]]\ntype = \"revolute\"\naxis = [0.0, 0.0, 1.0]\nlimits = [-1.0, 1.0]\nhome = 0.0\n";
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        ("three", joint.repeat(3), vec!["`joint`", "6 to 8 joints", "has 3"]),
        ("nine", joint.repeat(9), vec!["`joint`", "6 to 8 joints", "has 9"]),
        (
            "empty",
            ur5.replacen("limits = [-6.283185307179586, 6.283185307179586]", "limits = [0.5, 0.5]", 1),
            vec!["joint 1: limits", "lower"],
        ),
        (
            "home",
            ur5.replacen("home = 0.0", "home = 9.0", 1),
            vec!["joint 1: home", "inside the joint limits"],
        ),
        (
            "mount",
            ur5.replacen(
                "rpy = [0.0, 0.0, 3.141592653589793]",
                "rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.2, 1.0]]",
                1,
            ),
            vec!["mount.rotation", "orthonormal"],
        ),
        ("typo", ur5.replacen("max_velocity", "max_speed", 1), vec!["unknown field `max_speed`", "line"]),
    ];
    for (name, text, says) in &cases {
        let arm = file(&d, &format!("{name}.toml"), text);
        refused(&d, &["sim", "--arm", &arm, "--duration", "1"], says);
    }
    refused(
        &d,
        &["sim", "--arm", "/nonexistent/arm.toml"],
        &["cannot read arm file", "/nonexistent/arm.toml"],
    );
    // A target 10 m up: out of the UR5's reach (0.5 m mount, ~1.1 m of links).
    let high = file(&d, "high.toml", "[initial]\nr_bd = [2.5, 1.0, 10.0, 0.0, 0.0, 0.0]\n");
    refused(
        &d,
        &["sim", "--arm", "ur5", "--target-file", &high],
        &["cannot reach the target's height", "10.000"],
    );
    // A target that climbs out of reach during the run.
    let climb = file(&d, "climb.toml", "[[segment]]\nduration = 20\nvelocity = [0, 0, 0.5, 0, 0, 0]\n");
    refused(&d, &["sim", "--arm", "panda", "--target-file", &climb], &["cannot reach the target's height"]);
    let start = file(&d, "start.toml", "[initial]\nq = [0, -1.5, 3.5, -1.5, -1.5, 0]\n");
    refused(&d, &["sim", "--arm", "ur5", "--target-file", &start], &["`q[2]`", "joint 3"]);
    let count = file(&d, "count.toml", "[initial]\nq = [0, 0, 0]\n");
    refused(&d, &["sim", "--arm", "ur5", "--target-file", &count], &["`q` has 3 entries", "6 joints"]);
    let planar = file(&d, "planar.toml", "[[segment]]\nduration = 1\nvelocity = [0, 0, 0]\n");
    refused(
        &d,
        &["sim", "--arm", "ur5", "--target-file", &planar],
        &["segment 1: `velocity` has 3 entries", "6"],
    );
    refused(&d, &["sim", "--arm", "ur5", "--all"], &["--all", "--arm"]);
    refused(&d, &["sim", "--arm", "ur5", "--delay", "1"], &["delay must be a number of seconds in [0,"]);
    refused(&d, &["sim", "--arm", "panda", "--noise"], &["noise", "spatial arm"]);
    let gain = file(&d, "gain.toml", "[controller]\ngain = [1.0, 1.0, 1.0]\n");
    refused(&d, &["sim", "--arm", "ur5", "--config", &gain], &["controller.gain", "planar arm"]);
    // `explore --arm`: a space of parameters is needed, with no planar start in it; the
    // arm's checks are sim --arm's.
    refused(&d, &["explore", "--arm", "ur5", "--samples", "1"], &["spatial --arm needs a --space file"]);
    let start = file(&d, "start-space.toml", "[initial]\ndistance = [1.0, 2.0]\n");
    refused(
        &d,
        &["explore", "--arm", "panda", "--space", &start, "--samples", "1"],
        &["`distance` is not available with a spatial arm"],
    );
    let slow = file(&d, "slow-space.toml", "[parameters]\njoint_speed = [-1.0, 2.0]\n");
    refused(
        &d,
        &["explore", "--arm", "ur5", "--space", &slow, "--samples", "1"],
        &["joint_speed = -1", "must be finite and > 0"],
    );
    let reach = file(&d, "reach-space.toml", "[parameters]\nreach = [0.5, 2.0]\n");
    refused(
        &d,
        &["explore", "--space", &reach, "--samples", "1"],
        &["`reach` is a parameter of a spatial arm"],
    );
    refused(&d, &["explore", "--arm", "ur5", "--space", &reach, "--noise"], &["noise", "spatial arm"]);
}

/// A small URDF (a fixed base, six revolute joints in line, a tool) with `extra` elements
/// before `</robot>`, one element a line.
fn urdf(extra: &str) -> String {
    let mut s = String::from("<?xml version=\"1.0\"?>\n<robot name=\"six\">\n<link name=\"base\"/>\n");
    for i in 1..=6 {
        s.push_str(&format!(
            "<link name=\"l{i}\"/>\n<joint name=\"j{i}\" type=\"revolute\">\n<parent link=\"{}\"/>\n<child link=\"l{i}\"/>\n\
             <origin xyz=\"0 0 0.1\" rpy=\"0 {} 0\"/>\n<axis xyz=\"0 {} 1\"/>\n<limit lower=\"0\" upper=\"2\" effort=\"1\" velocity=\"1\"/>\n</joint>\n",
            if i == 1 { "base".to_string() } else { format!("l{}", i - 1) },
            if i % 2 == 0 { "0.5" } else { "0" },
            if i % 2 == 0 { "1" } else { "0" },
        ));
    }
    s.push_str("<link name=\"tool\"/>\n<joint name=\"tool_joint\" type=\"fixed\">\n<parent link=\"l6\"/>\n<child link=\"tool\"/>\n</joint>\n");
    s.push_str(extra);
    s.push_str("</robot>\n");
    s
}

/// The line of `pat` in `text` (1-based).
fn line_of(text: &str, pat: &str) -> usize {
    text[..text.find(pat).unwrap()].matches('\n').count() + 1
}

/// Issue 45's reproducers through the command line: a URDF whose joints loop (before the
/// fix, `sim` ran until 4 GiB of memory were gone), a joint whose parent is its child, an
/// `origin` of 2 million numbers (quoted whole before), `velocity="inf"` and `effort="-5"`
/// (read before, refused by urdfdom) — each refused at once, exit 2, one line naming the
/// file's line, nothing written; and `--home`: a value 1e-320 above a limit (accepted before,
/// then every step non-finite), an empty value, a joint named twice.
#[test]
fn issue_45s_urdfs_and_homes_are_refused_in_one_line_naming_the_line() {
    let d = dir("urdf");
    let sim = |arm: &str, home: &str| {
        vec![
            "sim",
            "--arm",
            arm,
            "--tip-link",
            "tool",
            "--home",
            home,
            "--platform",
            "omni",
            "--duration",
            "1",
        ]
        .into_iter()
        .map(String::from)
        .collect::<Vec<_>>()
    };
    let home = "1,1,1,1,1,1";
    let ok = file(&d, "ok.urdf", &urdf(""));
    let out = d.join("out");
    let ok_args = sim(&ok, home);
    let (code, err) = run(&ok_args
        .iter()
        .map(String::as_str)
        .chain(["--no-plots", "--out", out.to_str().unwrap()])
        .collect::<Vec<_>>());
    assert_eq!(code, Some(0), "the file itself is valid: {err}");
    let _ = std::fs::remove_dir_all(d.join("out"));
    let loop_text = urdf(
        "<joint name=\"back\" type=\"fixed\">\n<parent link=\"l3\"/>\n<child link=\"base\"/>\n</joint>\n",
    );
    let self_text = urdf("<link name=\"cam\"/>\n<joint name=\"cam_joint\" type=\"fixed\">\n<parent link=\"cam\"/>\n<child link=\"cam\"/>\n</joint>\n");
    let numbers = "0 ".repeat(2_000_000);
    let huge_text = urdf("").replacen("<origin xyz=\"0 0 0.1\"", &format!("<origin xyz=\"{numbers}\""), 1);
    let inf_text = urdf("").replacen("velocity=\"1\"", "velocity=\"inf\"", 1);
    let neg_text = urdf("").replacen("effort=\"1\"", "effort=\"-5\"", 1);
    for (name, text, at, says) in [
        ("loop", &loop_text, "<joint name=\"j1\"", "form a loop"),
        ("self", &self_text, "<joint name=\"cam_joint\"", "has `cam` as both parent and child link"),
        ("huge", &huge_text, "<origin xyz=\"0 0 0 0", "xyz=\"0 0 0 0 0"),
        ("inf", &inf_text, "<limit", "<limit velocity>=\"inf\" is not a finite number"),
        ("neg", &neg_text, "<limit", "<limit effort>=\"-5\" is negative"),
    ] {
        let arm = file(&d, &format!("{name}.urdf"), text);
        let args = sim(&arm, home);
        let (code, err) = run(&args
            .iter()
            .map(String::as_str)
            .chain(["--out", d.join("out").to_str().unwrap()])
            .collect::<Vec<_>>());
        assert_eq!(code, Some(2), "{name}: {err}");
        let line = format!("{arm}:{}:", line_of(text, at));
        assert!(err.contains(&line) && err.contains(says), "{name}: not {line} … {says}:\n{err}");
        assert_eq!(err.trim().lines().count(), 1, "{name}: one line:\n{err}");
        assert!(err.len() < 600, "{name}: {} characters", err.len());
        assert!(!d.join("out").exists(), "{name}: wrote its folder");
    }
    for (h, says) in [
        (
            "1e-320,1,1,1,1,1",
            "home of joint `j1`: 1e-320 lies within 1 % of the range [0, 2] of its lower limit",
        ),
        ("1,,1,1,1,1,1", "--home: \"1,,1,1,1,1,1\": value 2 of 7 is empty"),
        ("j1=1,j2=1,j1=0.5", "joint `j1` is named twice"),
    ] {
        refused(&d, &sim(&ok, h).iter().map(String::as_str).collect::<Vec<_>>(), &[says]);
    }
}

/// `--out` naming an existing file is refused before anything starts or is written, by every
/// command that writes a folder (`hil` started both processes before refusing it).
#[test]
fn an_out_that_is_a_file_is_refused_before_anything_starts() {
    let d = dir("outfile");
    let f = file(&d, "afile", "not a folder\n");
    for args in [
        &["hil", "--duration", "0.1", "--name", "outfile-hil"][..],
        &["plant", "--duration", "0.1", "--name", "outfile-plant"][..],
        &["sim", "--duration", "0.1"][..],
        &["explore", "--samples", "2"][..],
    ] {
        let mut all = args.to_vec();
        all.extend(["--out", f.as_str()]);
        let (code, err) = run(&all);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(err.contains(&f) && !err.contains("started the plant"), "{args:?}:\n{err}");
        assert_eq!(std::fs::read_to_string(&f).unwrap(), "not a folder\n");
    }
}
