//! A robot's own limits through the binary: `--limits NAME` composes with the config file's
//! (the stricter value per key, `scenario.json` saying where each came from), the TIAGo's
//! robot file carries its base's limits, `summary.json` says when the limits shaped a run, and
//! `companion settle` runs a setting from perturbed homes that `sim --home` replays.

#[path = "common/robots.rs"]
mod robots;

use std::path::{Path, PathBuf};
use std::process::Command;

use robots::robot;

const BIN: &str = env!("CARGO_BIN_EXE_companion");

fn out(tag: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("limits-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).expect("JSON")
}

fn workspace(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel).display().to_string()
}

/// Runs `companion ARGS`; (exit code, stdout, stderr).
fn companion(args: &[&str]) -> (Option<i32>, String, String) {
    let o = Command::new(BIN).args(args).output().expect("companion runs");
    (o.status.code(), String::from_utf8_lossy(&o.stdout).into(), String::from_utf8_lossy(&o.stderr).into())
}

/// `companion sim ARGS --no-plots --out DIR`: (stdout, summary.json, scenario.json).
fn sim(tag: &str, args: &[&str]) -> (String, serde_json::Value, serde_json::Value) {
    let d = out(tag);
    let mut a = vec!["sim", "--no-plots", "--out", d.to_str().expect("UTF-8")];
    a.extend(args);
    let (code, stdout, stderr) = companion(&a);
    assert_eq!(code, Some(0), "{args:?}: {stderr}");
    let r = (stdout, json(&d.join("summary.json")), json(&d.join("scenario.json")));
    let _ = std::fs::remove_dir_all(&d);
    r
}

/// The record of one limit in a planar or spatial `scenario.json`: (value, source).
fn applied(scenario: &serde_json::Value, key: &str) -> Option<(f64, String)> {
    let base = scenario.get("base").unwrap_or(scenario);
    base["limits"]["applied"].as_array()?.iter().find(|s| s["key"] == key).map(|s| {
        (s["value"].as_f64().unwrap_or(f64::NAN), s["from"].as_str().unwrap_or_default().to_string())
    })
}

fn tiago_urdf() -> String {
    robot("tiago_description/robots/tiago_no_hand.urdf")
}

/// A config file's `alpha_rate` survives `--limits tiago` (it used to be dropped): the commanded
/// phase rate stays within it, the base within the TIAGo's 1 m/s and 2.09 rad/s, and
/// `scenario.json` names each limit's source; a file's stricter forward speed wins over the
/// preset's. `--limits none` drops the file's limits and says which.
#[test]
fn the_config_files_limits_compose_with_a_preset() {
    let d = out("cfg");
    std::fs::create_dir_all(&d).expect("folder");
    let cfg = d.join("limits.toml");
    std::fs::write(&cfg, "[velocity_limits]\nalpha_rate = 0.8\nforward = 0.3\n").expect("write");
    let c = cfg.to_str().expect("UTF-8");
    let (_, s, sc) = sim("cfg-tiago", &["--duration", "5", "--config", c, "--limits", "tiago"]);
    let f = |k: &str| s[k].as_f64().unwrap_or(f64::NAN);
    assert!(f("max_abs_alpha_rate") <= 0.8 * (1.0 + 1e-12), "{s}");
    assert!(f("max_abs_alpha_rate") > 0.79, "the cap acted: {s}");
    assert!(f("max_abs_v") <= 0.3 * (1.0 + 1e-12) && f("max_abs_omega") <= 2.09 * (1.0 + 1e-12), "{s}");
    assert_eq!(applied(&sc, "velocity_limits.alpha_rate"), Some((0.8, "config file".into())), "{sc}");
    assert_eq!(applied(&sc, "velocity_limits.forward"), Some((0.3, "config file".into())));
    assert_eq!(applied(&sc, "velocity_limits.angular"), Some((2.09, "limits tiago".into())));
    assert_eq!(applied(&sc, "acceleration_limits.forward"), Some((1.0, "limits tiago".into())));
    let (_, s, sc) = sim("cfg-none", &["--duration", "5", "--config", c, "--limits", "none"]);
    assert!(s["max_abs_alpha_rate"].as_f64().unwrap_or(0.0) > 0.8, "{s}");
    assert_eq!(
        sc["limits"]["dropped"],
        serde_json::json!(["velocity_limits.forward", "velocity_limits.alpha_rate"])
    );
    assert!(sc["limits"].get("applied").is_none_or(|a| a.as_array().is_some_and(Vec::is_empty)), "{sc}");
    let _ = std::fs::remove_dir_all(&d);
}

/// `examples/arms/tiago-unicycle.toml` alone is the TIAGo with its base's limits: the same run,
/// bit for bit, as with `--limits tiago` added (the file's limits are PAL's or stricter), and
/// not the run without limits.
#[test]
fn the_tiago_robot_file_alone_carries_its_bases_limits() {
    let (urdf, file) = (tiago_urdf(), workspace("examples/arms/tiago-unicycle.toml"));
    let run = ["--arm", &urdf, "--config", &file, "--platform", "unicycle", "--duration", "5"];
    let (_, alone, sc) = sim("tiago-alone", &run);
    let (_, with, _) = sim("tiago-with", &[&run[..], &["--limits", "tiago"]].concat());
    let (_, none, _) = sim("tiago-none", &[&run[..], &["--limits", "none"]].concat());
    assert_eq!(alone["trajectory_digest"], with["trajectory_digest"]);
    assert_ne!(alone["trajectory_digest"], none["trajectory_digest"]);
    for (key, pal) in [
        ("velocity_limits.forward", 1.0),
        ("velocity_limits.angular", 2.09),
        ("acceleration_limits.forward", 1.0),
        ("acceleration_limits.angular", 2.09),
    ] {
        let (v, from) = applied(&sc, key).unwrap_or_else(|| panic!("{key}: {sc}"));
        assert!(v <= pal && from == "config file", "{key}: {v} from {from}");
    }
}

/// `companion settle` on the TIAGo: each start's home, replayed with `sim --home`, gives the
/// same run (its final ‖e_p‖ to the bit, and the same verdict), through the URDF reader's own
/// home rather than the study's rehoming; the planar arm is refused with a reason.
#[test]
fn settle_runs_from_homes_that_sim_replays() {
    let (urdf, file) = (tiago_urdf(), workspace("examples/arms/tiago-unicycle.toml"));
    let d = out("settle");
    let run =
        ["--arm", urdf.as_str(), "--config", file.as_str(), "--platform", "unicycle", "--duration", "21"];
    let mut a =
        vec!["settle", "--starts", "2", "--seed", "5", "--quiet", "--out", d.to_str().expect("UTF-8")];
    a.extend(run);
    let (code, stdout, stderr) = companion(&a);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stdout.contains("2 start(s), homes within ±0.1"), "{stdout}");
    let text = std::fs::read_to_string(d.join("settle.json")).expect("settle.json");
    let r: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    let runs = r["runs"].as_array().expect("runs");
    assert_eq!(runs.len(), 2);
    // The homes as written (serde_json's reader may round a number one ulp off; --home reads
    // the digits with Rust's own parser, exactly).
    let homes: Vec<String> = text
        .match_indices("\"home\": [")
        .map(|(i, m)| {
            let rest = &text[i + m.len()..];
            rest[..rest.find(']').expect("a list")].split(',').map(str::trim).collect::<Vec<_>>().join(",")
        })
        .collect();
    assert_eq!(homes.len(), 2, "{text}");
    for (k, (start, h)) in runs.iter().zip(&homes).enumerate() {
        let (_, s, _) = sim(&format!("replay-{k}"), &[&run[..], &["--home", h]].concat());
        assert_eq!(s["final_ep_norm"], start["final_ep_norm"], "start {k}");
        let settled =
            s["max_ep_norm_after_20s"].as_f64().is_some_and(|m| m < 1e-3) && s["rejected_steps"] == 0;
        assert_eq!(serde_json::Value::Bool(settled), start["settled"], "start {k}");
    }
    assert_eq!(r["settled"], runs.iter().filter(|s| s["settled"] == true).count());
    let (code, _, stderr) = companion(&["settle", "--starts", "2"]);
    assert_eq!(code, Some(2), "{stderr}");
    let (code, _, stderr) = companion(&["settle", "--arm", "rpr"]);
    assert_eq!(code, Some(2));
    assert!(stderr.contains("settle perturbs a spatial arm's home"), "{stderr}");
    let (code, _, stderr) =
        companion(&["tune", "--starts", "3", "--budget", "10", "--out", d.to_str().expect("UTF-8")]);
    assert_eq!(code, Some(2));
    assert!(stderr.contains("--starts 3 perturbs a spatial arm's home"), "{stderr}");
    let _ = std::fs::remove_dir_all(&d);
}

/// `summary.json` says how often the limits changed the law's command after 20 s: never on the
/// paper's unlimited run (and `sim` prints nothing about it), on most steps of the paper's
/// tuning under the TIAGo's limits (and `sim` says so).
#[test]
fn the_summary_says_when_the_limits_shaped_the_run() {
    let (stdout, s, _) = sim("paper", &["--duration", "30"]);
    let l = &s["limits_after_20s"];
    assert_eq!((l["steps"].as_u64(), l["beyond"].as_bool()), (Some(0), Some(false)), "{s}");
    assert!(!stdout.contains("the limits acted"), "{stdout}");
    let (stdout, s, _) = sim("paper-tiago", &["--duration", "30", "--limits", "tiago"]);
    let l = &s["limits_after_20s"];
    let after = s["steps_after_20s"].as_f64().unwrap_or(f64::NAN);
    let n = |k: &str| l[k].as_f64().unwrap_or(f64::NAN);
    assert!(n("beyond_saturation_fraction") > 0.05 && l["beyond"] == true, "{s}");
    assert_eq!(n("fraction"), n("steps") / after);
    assert_eq!(n("beyond_saturation_fraction"), n("beyond_saturation_steps") / after);
    assert!(n("platform_acceleration_steps") > 0.0 && n("steps") >= n("beyond_saturation_steps"), "{s}");
    assert!(stdout.contains("the limits acted on") && stdout.contains("more than 5 %"), "{stdout}");
    // The paper's saturation alone (the car's default velocity limits) keeps the law's
    // direction: counted, not flagged.
    let (stdout, s, _) = sim("car", &["--duration", "30", "--platform", "car"]);
    let l = &s["limits_after_20s"];
    assert!(l["velocity_steps"].as_u64().unwrap_or(0) > 0, "{s}");
    assert_eq!((l["beyond_saturation_steps"].as_u64(), l["beyond"].as_bool()), (Some(0), Some(false)), "{s}");
    assert!(!stdout.contains("the limits acted"), "{stdout}");
}
