//! The weight `Ψ̃` of (52) sees a spatial arm's reach (companion-core's `reach` module, issue
//! 44), end to end through the binary: runs (b)–(d) of the TIAGo and the PR2 on lifted
//! trajectory 1 reach the target where the paper's weight left them metres away; runs (a)
//! never see the weight; the `[controller]` keys are checked before anything runs.

use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "common/robots.rs"]
mod robots;

const BIN: &str = env!("CARGO_BIN_EXE_companion");

fn dir(tag: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("reach-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("test dir");
    d
}

/// Runs `companion sim args… --no-plots --out DIR/run`; its summary.json.
fn sim(d: &Path, args: &[&str]) -> serde_json::Value {
    let out = d.join("run");
    let _ = std::fs::remove_dir_all(&out);
    let o = Command::new(BIN)
        .arg("sim")
        .args(args)
        .arg("--no-plots")
        .arg("--out")
        .arg(&out)
        .output()
        .expect("companion runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{args:?}:\n{err}");
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap_or_else(|e| panic!("{args:?}: {e}"));
    serde_json::from_str(&text).expect("JSON")
}

fn f(v: &serde_json::Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("{key} in {v}"))
}

/// The TIAGo's robot file with `line` added to its `[controller]` table.
fn tiago_config(d: &Path, line: &str) -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("examples/arms/tiago-unicycle.toml")).expect("the file");
    let text = text.replacen("[controller]\n", &format!("[controller]\n{line}\n"), 1);
    let p = d.join(format!("tiago-{}.toml", line.len()));
    std::fs::write(&p, text).expect("write");
    p.display().to_string()
}

/// A `[controller]` table of one line.
fn controller(d: &Path, line: &str) -> String {
    let p = d.join("controller.toml");
    std::fs::write(&p, format!("[controller]\n{line}\n")).expect("write");
    p.display().to_string()
}

/// Every (b)–(d) run of lifted T1 (40 s) ends within 10⁻⁵ m, no step refused, every joint
/// inside its limits; the platform's weight rose from the first step (`h_s` > 0 where the
/// target starts 2.4 m away). Without the reach (the paper's (52)) run (c) ends `far` away.
fn reaches_in_b_to_d(tag: &str, arm: &[&str], without: &[&str], far: f64) {
    let d = dir(tag);
    for choice in ["b", "c", "d"] {
        let s = sim(&d, &[arm, &["--trajectory", "1", "--choice", choice, "--duration", "40"]].concat());
        let name = format!("{tag} ({choice})");
        assert!(f(&s, "final_ep_norm") <= 1e-5, "{name}: final ‖e_p‖ {}", f(&s, "final_ep_norm"));
        assert_eq!(f(&s, "rejected_steps"), 0.0, "{name}");
        assert!(f(&s, "smallest_joint_margin") > 0.0, "{name}: a joint reached its limit");
        assert!(f(&s, "initial_h_s") > 0.1, "{name}: h_s {} at the start", f(&s, "initial_h_s"));
    }
    let s = sim(&d, &[without, &["--trajectory", "1", "--choice", "c", "--duration", "40"]].concat());
    assert!(f(&s, "final_ep_norm") > far, "{tag} (c) without the reach: {}", f(&s, "final_ep_norm"));
    assert_eq!(f(&s, "initial_h_s"), 0.0, "{tag} (c) without the reach: Ψ = 0 at the start");
    let _ = std::fs::remove_dir_all(&d);
}

/// The TIAGo on its own base (`examples/arms/tiago-unicycle.toml`): (b)–(d) settle (measured
/// 1.8e−8 to 3.5e−8); without the reach (c) ends 0.258 m away.
#[test]
fn the_tiago_reaches_the_lifted_circle_in_runs_b_to_d() {
    let d = dir("tiago-files");
    let urdf = robots::robot("tiago_description/robots/tiago_no_hand.urdf");
    let (with, without) = (tiago_config(&d, ""), tiago_config(&d, "reach = false"));
    let arm = |cfg: &str| ["--arm", &urdf, "--config", cfg, "--platform", "unicycle"].map(String::from);
    let (a, b) = (arm(&with), arm(&without));
    let (a, b): (Vec<&str>, Vec<&str>) =
        (a.iter().map(|s| s.as_str()).collect(), b.iter().map(|s| s.as_str()).collect());
    reaches_in_b_to_d("tiago", &a, &b, 0.1);
    let _ = std::fs::remove_dir_all(&d);
}

/// The PR2 on its omnidirectional base (`tuck_right_arm`, torso 0.1 m): (b)–(d) settle
/// (2.1e−8 to 2.2e−8); without the reach (c) ends 1.33 m away.
#[test]
fn the_pr2_reaches_the_lifted_circle_in_runs_b_to_d() {
    let d = dir("pr2-files");
    let off = controller(&d, "reach = false");
    let arm = robots::pr2();
    let arm: Vec<&str> = arm.iter().map(String::as_str).collect();
    let without = [&arm[..], &["--config", &off]].concat();
    reaches_in_b_to_d("pr2", &arm, &without, 1.0);
    let _ = std::fs::remove_dir_all(&d);
}

/// Run (a)'s weight is the constant `Ψ = 1`: the reach changes nothing, bit for bit (the
/// trajectory digest), on the presets and a URDF arm; and a preset gets the reach with no
/// flag (its run (c) moves the platform: `h_s` > 0 at the start, 0 without the reach).
#[test]
fn runs_a_do_not_see_the_reach_and_presets_have_it_by_default() {
    let d = dir("presets");
    let off = controller(&d, "reach = false");
    for (arm, platform) in [("ur5", "unicycle"), ("panda", "omni"), ("panda", "car")] {
        let args = ["--arm", arm, "--platform", platform, "--trajectory", "1", "--duration", "10"];
        let on = sim(&d, &[&args[..], &["--choice", "a"]].concat());
        let no = sim(&d, &[&args[..], &["--choice", "a", "--config", &off]].concat());
        assert_eq!(on["trajectory_digest"], no["trajectory_digest"], "{arm} on {platform} (a)");
        let c = sim(&d, &[&args[..], &["--choice", "c"]].concat());
        assert!(f(&c, "initial_h_s") > 0.1, "{arm} on {platform} (c): {c}");
        let c = sim(&d, &[&args[..], &["--choice", "c", "--config", &off]].concat());
        assert_eq!(f(&c, "initial_h_s"), 0.0, "{arm} on {platform} (c) without the reach");
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// The reach's keys: a bad value refused by name before anything is written (exit 2), a
/// planar run refuses them, and the two settings that only reshape the weight run.
#[test]
fn the_reach_keys_are_checked_before_anything_runs() {
    let d = dir("keys");
    let out = d.join("out");
    for (line, platform, says) in [
        ("reach_margin = 0.0", "--arm=ur5", "reach_margin"),
        ("reach_margin = 1.0", "--arm=ur5", "reach_margin"),
        ("reach_margin = nan", "--arm=panda", "reach_margin"),
        (
            "reach_joints = [\"shoulder_lift_joint\", \"nope\", \"shoulder_pan_joint\"]",
            "--arm=ur5",
            "\"nope\"",
        ),
        (
            "reach_joints = [\"wrist_1_joint\", \"shoulder_lift_joint\", \"shoulder_pan_joint\"]",
            "--arm=ur5",
            "reach_joints",
        ),
        ("reach_rule = \"median\"", "--arm=ur5", "median"),
        ("reach = 3", "--arm=ur5", "reach"),
        ("reach_margin = 0.1", "--platform=unicycle", "controller.reach_margin"),
        ("reach = true", "--platform=omni", "controller.reach"),
    ] {
        let cfg = controller(&d, line);
        let o = Command::new(BIN)
            .args(["sim", platform, "--duration", "0.05", "--no-plots", "--config", &cfg, "--out"])
            .arg(&out)
            .output()
            .expect("companion runs");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{line} ({platform}):\n{err}");
        assert!(err.contains(says), "{line} ({platform}): {err}");
        assert!(!err.contains("panicked"), "{line}: {err}");
        assert!(!out.exists(), "{line}: refused, yet the run's folder was written");
    }
    for line in [
        "reach_rule = \"mean\"",
        "reach_margin = 0.3",
        "reach_joints = [\"shoulder_lift_joint\", \"wrist_1_joint\", \"shoulder_pan_joint\"]",
    ] {
        let cfg = controller(&d, line);
        let s = sim(&d, &["--arm", "ur5", "--duration", "0.05", "--config", &cfg]);
        assert_eq!(f(&s, "rejected_steps"), 0.0, "{line}");
    }
    let _ = std::fs::remove_dir_all(&d);
}
