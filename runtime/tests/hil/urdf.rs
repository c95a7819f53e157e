//! Robots read from their vendors' URDFs (example-robot-data, installed into target/py by
//! scripts/setup): the HIL in lockstep byte-identical to `companion sim` with the TIAGo and
//! the PR2 (whose chain has two continuous joints); a plant and a controller cut from the same
//! file at different links refuse each other; and every bad request ends with exit code 2, one
//! sentence naming the file and the joint or link, and nothing written.

use super::*;

#[path = "../common/robots.rs"]
mod robots;
use robots::{pr2, robot, tiago};

#[test]
fn a_urdf_arm_in_lockstep_is_byte_identical_to_sim() {
    let _g = serial();
    let t = tiago();
    let t: Vec<&str> = t.iter().map(String::as_str).collect();
    let pr2 = pr2();
    let pr2: Vec<&str> = pr2.iter().map(String::as_str).collect();
    for extra in [
        [&t[..], &["--platform", "unicycle"]].concat(),
        [&t[..], &["--platform", "omni"]].concat(),
        pr2.to_vec(),
    ] {
        let (hs, _) = lockstep_equals_sim("2", &extra);
        assert_eq!(hs["joints"], 8, "{extra:?}");
    }
}

#[test]
fn chains_cut_at_other_links_refuse_each_other() {
    let _g = serial();
    let d = dir("urdf-refused");
    let n = name("urdf-refused");
    let t = tiago();
    let t: Vec<&str> = t.iter().map(String::as_str).collect();
    let plant = [&lockstep_plant(&n, &d)[..], &t].concat();
    // The same eight joints, another tool (the force sensor's frame past the flange).
    let other: Vec<&str> =
        t.iter().map(|a| if *a == "arm_tool_link" { "wrist_ft_tool_link" } else { a }).collect();
    let control = [&["--name", n.as_str()][..], &other].concat();
    let (plant, control) = two_roles(&plant, &control);
    refused_for(&d, &plant, &control, "arm mismatch");
}

/// `args` (with `--out DIR` added) ends with code 2, says each of `says` in one line, and
/// writes nothing.
fn refused_cli(args: &[&str], says: &[&str]) {
    let d = dir("urdf-bad");
    let out = d.join("out");
    let mut all = args.to_vec();
    all.extend(["--duration", "1", "--out", out.to_str().unwrap()]);
    let (st, _, err) = run(&all);
    assert_eq!(st.code(), Some(2), "{args:?}: {err}");
    for s in says {
        assert!(err.contains(s), "{args:?}: {err:?} does not say {s:?}");
    }
    assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists(), "{args:?} wrote {}", out.display());
}

#[test]
fn bad_urdf_requests_are_refused_before_anything_runs() {
    let urdf = robot("tiago_description/robots/tiago_no_hand.urdf");
    let u = urdf.as_str();
    for cmd in ["sim", "hil"] {
        refused_cli(
            &[cmd, "--arm", u, "--base-link", "base_footprint"],
            &["give --tip-link", "arm_tool_link"],
        );
        refused_cli(
            &[cmd, "--arm", u, "--tip-link", "arm_tool_link"],
            &["need a home", "--home q1,…,q8", "torso_lift_joint"],
        );
        refused_cli(
            &[cmd, "--arm", u, "--tip-link", "arm_tool_link", "--home", "0.4,1,-0.5,-1,1.2,0,0.5,0"],
            &["home of joint `torso_lift_joint`: 0.4 is not strictly inside its limits [0, 0.35]"],
        );
        refused_cli(
            &[cmd, "--arm", u, "--tip-link", "gripper"],
            &["--tip-link gripper:", "has no such link"],
        );
        refused_cli(
            &[
                cmd,
                "--arm",
                u,
                "--base-link",
                "arm_3_link",
                "--tip-link",
                "arm_tool_link",
                "--home",
                "0,0,0,0,0",
            ],
            &[
                "the chain from `arm_3_link` to `arm_tool_link` has 4 moving joint(s) (arm_4_joint",
                "needs 6 to 8",
            ],
        );
        refused_cli(&[cmd, "--arm", "ur5", "--tip-link", "tool0"], &["read a URDF: give --arm FILE.urdf"]);
    }
    refused_cli(
        &["sim", "--arm", "robot.urdf.xacro", "--tip-link", "tool0"],
        &["xacro template", "expand it first"],
    );
    refused_cli(
        &["sim", "--arm", "nonexistent.urdf", "--tip-link", "tool0"],
        &["cannot read nonexistent.urdf"],
    );
}

/// The TIAGo on its own base (the unicycle), from the robot file that carries its home and
/// transverse function (`examples/arms/tiago-unicycle.toml`): lifted T1 (a) settles within
/// 40 s, nothing refused, the joints inside their limits; and the HIL in lockstep writes the
/// same run.
#[test]
fn the_tiago_settles_on_the_unicycle_with_its_robot_file() {
    let _g = serial();
    let urdf = robot("tiago_description/robots/tiago_no_hand.urdf");
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/arms/tiago-unicycle.toml");
    let flags = ["--arm", urdf.as_str(), "--config", file.to_str().unwrap(), "--platform", "unicycle"];
    let d = dir("tiago-unicycle");
    let out = d.join("sim");
    let mut args = vec!["sim", "--duration", "40", "--no-plots", "--out", out.to_str().unwrap()];
    args.extend(flags);
    let (st, _, err) = run(&args);
    assert!(st.success(), "{err}");
    let s = json(&out.join("summary.json"));
    let f = |k: &str| s[k].as_f64().unwrap();
    assert!(f("final_ep_norm") <= 1e-5, "{s}");
    assert!(f("max_ep_norm_after_20s") <= 1e-5, "{s}");
    assert_eq!(s["rejected_steps"], 0, "{s}");
    assert!(f("smallest_joint_margin") > 0.0, "{s}");
    lockstep_equals_sim("2", &flags);
}
