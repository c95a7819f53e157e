//! Every spatial arm preset and shipped arm file tracks lifted trajectory 1 (run (a)) on every
//! platform with `companion sim --arm X --platform P` and nothing else but the run's length and
//! `--no-plots`: final ‖e_p‖ ≤ 1e−5, every joint strictly inside its limits, no step refused.
//! Through the binary, so the defaults are exactly the CLI's (the arm's platform settings
//! filled in where no `--config` is given).
//!
//! The Panda carries its own settings for the unicycle and the car: [`panda_unicycle`] and
//! [`panda_car`] show what the paper's and the car's defaults do with it instead.

use std::path::{Path, PathBuf};
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_companion");

fn out(tag: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("presets-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// `--arm` for `arm`: a preset's name, or a shipped arm file's path.
fn arm_arg(arm: &str) -> String {
    if arm.ends_with(".toml") {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/arms").join(arm).display().to_string()
    } else {
        arm.to_string()
    }
}

fn json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).expect("JSON")
}

/// Runs `companion sim --arm ARM --platform P --duration 40 --no-plots extra…`; (exit code,
/// summary.json, scenario.json).
fn sim(
    tag: &str,
    arm: &str,
    platform: &str,
    extra: &[&str],
) -> (Option<i32>, serde_json::Value, serde_json::Value) {
    sim_for(tag, arm, platform, "40", extra)
}

/// [`sim`] for `duration` seconds.
fn sim_for(
    tag: &str,
    arm: &str,
    platform: &str,
    duration: &str,
    extra: &[&str],
) -> (Option<i32>, serde_json::Value, serde_json::Value) {
    let dir = out(tag);
    let o = Command::new(BIN)
        .args(["sim", "--arm", &arm_arg(arm), "--platform", platform, "--duration", duration, "--no-plots"])
        .args(extra)
        .arg("--out")
        .arg(&dir)
        .output()
        .expect("companion runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("panicked"), "{arm} {platform} panicked:\n{err}");
    let (s, c) = (json(&dir.join("summary.json")), json(&dir.join("scenario.json")));
    let _ = std::fs::remove_dir_all(&dir);
    (o.status.code(), s, c)
}

fn f(v: &serde_json::Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("{key} in {v}"))
}

/// The default run of `arm` on `platform` settles and keeps every joint inside its limits.
fn tracks(arm: &str, platform: &str, joints: usize) -> serde_json::Value {
    let (code, s, scenario) =
        sim(&format!("{}-{platform}", arm.replace(".toml", "-file")), arm, platform, &[]);
    assert_eq!(code, Some(0), "{arm} {platform}: {s}");
    assert_eq!(s["joints"], joints, "{arm}");
    assert_eq!(s["steps"], 40_001, "{arm} {platform}");
    let fin = f(&s, "final_ep_norm");
    assert!(fin <= 1e-5, "{arm} {platform}: final ‖e_p‖ {fin:e} > 1e-5\n{s}");
    let margins = s["min_joint_margin"].as_array().expect("margins");
    assert_eq!(margins.len(), joints);
    for (j, m) in margins.iter().enumerate() {
        let m = m.as_f64().expect("a number");
        assert!(m > 0.0, "{arm} {platform}: joint {} reached its limit (margin {m})", j + 1);
    }
    assert!(f(&s, "smallest_joint_margin") > 0.0);
    assert_eq!(s["rejected_steps"], 0, "{arm} {platform}: {s}");
    assert_eq!(s["verdict"], "ok", "{arm} {platform}");
    scenario
}

/// One test per arm × platform.
macro_rules! track {
    ($($name:ident: $arm:literal, $platform:literal, $joints:literal;)*) => {
        $(
            #[test]
            fn $name() {
                tracks($arm, $platform, $joints);
            }
        )*
    };
}

track! {
    ur5_unicycle: "ur5", "unicycle", 6;
    ur5_car: "ur5", "car", 6;
    ur5_omni: "ur5", "omni", 6;
    panda_omni: "panda", "omni", 7;
    ur5_file_unicycle: "ur5.toml", "unicycle", 6;
    ur5_file_car: "ur5.toml", "car", 6;
    ur5_file_omni: "ur5.toml", "omni", 6;
    panda_file_unicycle: "panda.toml", "unicycle", 7;
    panda_file_car: "panda.toml", "car", 7;
    panda_file_omni: "panda.toml", "omni", 7;
}

/// The Panda on the unicycle runs with the settings the preset carries (Lemma 1's ε₂ =
/// 0.8 m, the run's scenario.json says so) and settles; with the paper's ε₂ = 0.4 m given by
/// `--config` (which overrides the arm's) the shoulder's published speed holds it back and
/// it does not settle within the 40 s — why the preset carries its own.
#[test]
fn panda_unicycle() {
    let scenario = tracks("panda", "unicycle", 7);
    assert_eq!(scenario["base"]["controller"]["unicycle"]["epsilon_2"], 0.8, "{scenario}");
    let d = out("paper-epsilon");
    std::fs::create_dir_all(&d).unwrap();
    let paper = d.join("paper.toml");
    std::fs::write(&paper, "[unicycle]\nepsilon_1 = 0.2\nepsilon_2 = 0.4\n").unwrap();
    let (code, s, scenario) = sim("panda-paper", "panda", "unicycle", &["--config", paper.to_str().unwrap()]);
    assert_eq!(code, Some(0));
    assert_eq!(scenario["base"]["controller"]["unicycle"]["epsilon_2"], 0.4, "--config wins");
    assert!(f(&s, "final_ep_norm") > 1e-5, "{s}");
    assert!(f(&s, "max_joint_scale") > 1.0, "the joint guard slowed the arm: {s}");
    let _ = std::fs::remove_dir_all(d);
}

/// Lifted trajectory 2, run (a), 120 s: tracked (‖e_p‖ < 1e−3) at least 90 % of the time after
/// 20 s with the defaults for the Panda on the unicycle (its carried ε₂ = 0.8 m) and on the
/// omnidirectional platform and for the UR5 on the omnidirectional platform; the UR5 on the
/// unicycle with `examples/arms/ur5-trajectory2.toml` (with the paper's (ε₁, ε₂) its published
/// joint speeds hold it to ~70 %: the file says why).
#[test]
fn lifted_trajectory_2_is_tracked() {
    let ur5_t2 = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/arms/ur5-trajectory2.toml");
    let ur5_t2 = ur5_t2.to_str().unwrap();
    for (arm, platform, extra) in [
        ("panda", "unicycle", &[][..]),
        ("panda", "omni", &[]),
        ("ur5", "omni", &[]),
        ("ur5", "unicycle", &["--config", ur5_t2]),
    ] {
        let mut args = vec!["--trajectory", "2"];
        args.extend(extra);
        let (code, s, _) = sim_for(&format!("t2-{arm}-{platform}"), arm, platform, "120", &args);
        assert_eq!(code, Some(0), "{arm} {platform}: {s}");
        let tracked = f(&s, "fraction_ep_below_1e-3_after_20s");
        assert!(tracked >= 0.9, "{arm} {platform} {extra:?}: tracked {tracked} after 20 s\n{s}");
        assert!(f(&s, "smallest_joint_margin") > 0.0, "{arm} {platform}");
        assert_eq!(s["rejected_steps"], 0, "{arm} {platform}");
    }
}

/// The UR5 on the car on lifted trajectory 2: with the core's damping onset the arm comes
/// near its wrist's singular configuration and the law refuses thousands of steps there (exit
/// 6, the run failed); with `examples/arms/ur5-car-trajectory2.toml` (`damping_below = 1e-2`)
/// none is refused and the run settles at its end (the file gives the figures and why the
/// tracked share is modest). The planar arm refuses the key by name.
#[test]
fn ur5_car_trajectory_2_needs_earlier_damping() {
    let (code, s, _) = sim_for("ur5-car-t2-default", "ur5", "car", "120", &["--trajectory", "2"]);
    assert_eq!(code, Some(6), "{s}");
    assert!(s["rejected_steps"].as_u64().is_some_and(|n| n > 1000), "{s}");
    let file = arm_arg("ur5-car-trajectory2.toml");
    let args = ["--trajectory", "2", "--config", &file];
    let (code, s, scenario) = sim_for("ur5-car-t2-damped", "ur5", "car", "120", &args);
    assert_eq!(code, Some(0), "{s}");
    assert_eq!(s["rejected_steps"], 0, "{s}");
    assert!(f(&s, "final_ep_norm") <= 1e-6, "{s}");
    assert!(f(&s, "fraction_ep_below_1e-3_after_20s") > 0.2, "{s}");
    assert_eq!(scenario["base"]["controller"]["overrides"]["damping_below"], 0.01, "{scenario}");
    let dir = out("rpr-damping");
    let o = Command::new(BIN)
        .args(["sim", "--duration", "1", "--no-plots", "--config", &file, "--out"])
        .arg(&dir)
        .output()
        .expect("companion runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("controller.damping_below") && err.contains("planar"), "{err}");
    assert!(!dir.exists(), "refused, yet {} was written", dir.display());
}

/// `companion tune --arm` on the UR5 on the car on lifted T2, searching the damping onset:
/// its preset, read back by `sim --arm`, gives the run the report promised (the same tracked
/// fraction, none refused) — the tune's trial and the simulation agree through the files.
#[test]
fn tune_finds_a_damping_onset_for_the_ur5_on_the_car_that_sim_confirms() {
    let dir = out("tune-ur5-car");
    std::fs::create_dir_all(&dir).unwrap();
    let space = dir.join("space.toml");
    std::fs::write(&space, "[parameters]\ndamping_below = [1e-3, 3e-2]\n").unwrap();
    let tuned = dir.join("tune");
    let o = Command::new(BIN)
        .args(["tune", "--arm", "ur5", "--platform", "car", "--runs", "2a", "--budget", "12", "--quiet"])
        .arg("--space")
        .arg(&space)
        .arg("--out")
        .arg(&tuned)
        .output()
        .expect("companion runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    let report = json(&tuned.join("report.json"));
    assert_eq!(report["arm"], "ur5", "{report}");
    let best = &report["candidates"][report["best"].as_u64().unwrap() as usize];
    let promised = best["runs"][0]["tracked"].as_f64().unwrap();
    assert!(promised > 0.3, "{best}");
    let preset = tuned.join("preset.toml");
    let text = std::fs::read_to_string(&preset).unwrap();
    assert!(text.contains("damping_below") && text.contains("spatial arm `ur5`"), "{text}");
    let args = ["--trajectory", "2", "--config", preset.to_str().unwrap()];
    let (code, s, _) = sim_for("ur5-car-t2-tuned", "ur5", "car", "120", &args);
    assert_eq!(code, Some(0), "{s}");
    assert_eq!(s["rejected_steps"], 0, "{s}");
    assert_eq!(f(&s, "fraction_ep_below_1e-3_after_20s"), promised, "{s}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The Panda on the car runs with the Lemma 2 parameters the preset carries (scenario.json
/// says so) and settles; over 120 s too, with `‖e_p‖` below the aim's 1e−5 all the time from
/// 20 s on (no burst comes back). With the car's defaults given by `--config`
/// (`examples/arms/panda-car-defaults.toml`) it does not settle within the 40 s: the car's
/// manoeuvres ask joints beyond their published speeds and the joint guard slows the arm — why
/// the preset carries its own (docs/book/src/spatial-arms.md).
#[test]
fn panda_car() {
    let scenario = tracks("panda", "car", 7);
    let car = &scenario["base"]["controller"]["car"];
    assert_eq!((car["epsilon"].as_f64(), car["eta_1"].as_f64()), (Some(0.176), Some(12.1)), "{scenario}");
    let (code, s, _) = sim_for("panda-car-120", "panda", "car", "120", &[]);
    assert_eq!(code, Some(0), "{s}");
    assert!(f(&s, "final_ep_norm") <= 1e-5, "{s}");
    assert!(f(&s, "max_ep_norm_after_20s") <= 1e-5, "a burst after 20 s: {s}");
    assert!(f(&s, "smallest_joint_margin") > 0.0, "{s}");
    assert_eq!(s["rejected_steps"], 0, "{s}");
    let defaults = arm_arg("panda-car-defaults.toml");
    let (code, s, scenario) = sim("panda-car-defaults", "panda", "car", &["--config", &defaults]);
    assert_eq!(code, Some(0));
    assert_eq!(scenario["base"]["controller"]["car"]["epsilon"], 0.152, "--config wins");
    assert!(f(&s, "final_ep_norm") > 1e-5, "{s}");
    assert!(f(&s, "max_joint_scale") > 1.0, "the joint guard slowed the arm: {s}");
}

#[path = "common/robots.rs"]
mod robots;

/// `sim --arm` the TIAGo from its URDF with its robot file (`examples/arms/tiago-unicycle.toml`:
/// its base's limits, the heading filter, the elbow kept bent) and `extra`.
fn tiago_file(
    tag: &str,
    duration: &str,
    extra: &[&str],
) -> (Option<i32>, serde_json::Value, serde_json::Value) {
    let urdf = robots::robot("tiago_description/robots/tiago_no_hand.urdf");
    let file = arm_arg("tiago-unicycle.toml");
    let mut args = vec!["--config", &file];
    args.extend_from_slice(extra);
    sim_for(tag, &urdf, "unicycle", duration, &args)
}

/// The TIAGo on its own base's limits (PAL's 1 m/s, 1 m/s², 2.09 rad/s, 2.09 rad/s², from its
/// robot file alone): lifted T1 (a) settles to the discretisation's floor and T2 (a) is
/// tracked most of the time, with the limits acting, the elbow never within its law's limit
/// (0.253 rad) and no step refused. (Deterministic runs; the spread over perturbed homes is
/// the `tiago-limits` report's, law.md.)
#[test]
fn the_tiago_tracks_on_its_own_base_limits() {
    let (code, s, scenario) = tiago_file("tiago-limits-t1", "40", &[]);
    assert_eq!(code, Some(0), "{s}");
    assert!(f(&s, "final_ep_norm") <= 1e-7, "{s}");
    assert!(f(&s, "max_ep_norm_after_20s") <= 1e-6, "{s}");
    assert!(f(&s, "max_abs_v") <= 1.0 + 1e-9 && f(&s, "max_abs_omega") <= 2.09 + 1e-9, "{s}");
    assert!(s["platform_acceleration_steps"].as_u64().is_some_and(|n| n > 0), "the limits never acted: {s}");
    assert_eq!(s["rejected_steps"], 0, "{s}");
    let o = &scenario["base"]["controller"]["overrides"];
    assert_eq!(o["joint_limits"]["arm_4_joint"][0], 0.253, "{scenario}");
    let (code, s, _) = tiago_file("tiago-limits-t2", "120", &["--trajectory", "2"]);
    assert_eq!(code, Some(0), "{s}");
    assert!(f(&s, "fraction_ep_below_1e-3_after_20s") >= 0.9, "{s}");
    // The elbow (the fifth joint) kept off straight: its law limit is 0.253 rad.
    let lower = s["min_joint_margin"][4].as_f64().expect("margins");
    assert!(lower > 0.0, "{s}");
}

/// The same file without its heading filter tracks T2 less of the time: the base swings
/// around the target while it turns in place. (The filter's own equations are tested in
/// companion-core's suite, `heading`.)
#[test]
fn the_heading_filter_is_what_keeps_the_tiago_on_trajectory_2() {
    let d = out("tiago-no-heading");
    std::fs::create_dir_all(&d).unwrap();
    let text = std::fs::read_to_string(arm_arg("tiago-unicycle.toml")).unwrap();
    let without: String =
        text.lines().filter(|l| !l.starts_with("heading_")).map(|l| format!("{l}\n")).collect();
    let file = d.join("no-heading.toml");
    std::fs::write(&file, without).unwrap();
    let urdf = robots::robot("tiago_description/robots/tiago_no_hand.urdf");
    let args = ["--trajectory", "2", "--config", file.to_str().unwrap()];
    let (_, s_without, _) = sim_for("tiago-no-heading-t2", &urdf, "unicycle", "120", &args);
    let (_, s_with, _) = tiago_file("tiago-heading-t2", "120", &["--trajectory", "2"]);
    let (a, b) =
        (f(&s_without, "fraction_ep_below_1e-3_after_20s"), f(&s_with, "fraction_ep_below_1e-3_after_20s"));
    assert!(b > a + 0.02, "with the filter {b}, without {a}");
    assert!(
        f(&s_with, "path_length_after_20s") < f(&s_without, "path_length_after_20s"),
        "{s_with}\n{s_without}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// `[controller.joint_limits]`: refused by name and rule before anything runs — an unknown
/// joint (the message lists the arm's), limits wider than the robot's, limits that leave out
/// the home — and with the planar arm.
#[test]
fn the_laws_joint_limits_are_checked() {
    let d = out("law-limits");
    std::fs::create_dir_all(&d).unwrap();
    let urdf = robots::robot("tiago_description/robots/tiago_no_hand.urdf");
    let base = std::fs::read_to_string(arm_arg("tiago-unicycle.toml")).unwrap();
    let base = &base[..base.find("[controller.joint_limits]").expect("the file has the table")];
    for (table, says) in [
        (
            "elbow_joint = [0.3, 2.0]",
            "names elbow_joint, which is not a joint of the arm (torso_lift_joint, arm_1_joint",
        ),
        (
            "arm_4_joint = [-1.0, 2.0]",
            "arm_4_joint = [-1, 2] is not inside the robot's limits [-0.392699081699, 2.35619449019]",
        ),
        ("arm_4_joint = [1.7, 2.0]", "arm_4_joint = [1.7, 2] does not hold the home (arm_4_joint = 1.66)"),
        ("arm_4_joint = [2.0, 1.0]", "the limits must be finite, lower < upper"),
    ] {
        let file = d.join("c.toml");
        std::fs::write(&file, format!("{base}[controller.joint_limits]\n{table}\n")).unwrap();
        let dir = d.join("out");
        let o = Command::new(BIN)
            .args([
                "sim",
                "--arm",
                &urdf,
                "--platform",
                "unicycle",
                "--duration",
                "1",
                "--no-plots",
                "--config",
            ])
            .arg(&file)
            .arg("--out")
            .arg(&dir)
            .output()
            .expect("companion runs");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{table}: {err}");
        assert!(err.contains(says), "{table}: {err}");
        assert!(!dir.exists(), "{table}: refused, yet written");
    }
    let file = d.join("planar.toml");
    std::fs::write(&file, "[controller.joint_limits]\nq1 = [0.0, 0.5]\n").unwrap();
    let o = Command::new(BIN)
        .args(["sim", "--duration", "1", "--no-plots", "--config"])
        .arg(&file)
        .arg("--out")
        .arg(d.join("out"))
        .output()
        .expect("companion runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("controller.joint_limits"), "{err}");
    let _ = std::fs::remove_dir_all(&d);
}
