#![allow(dead_code)] // each test file that includes this module uses some of its robots
//! example-robot-data's URDFs, which scripts/setup installs into target/py (the tests read
//! them from there: data of another project, never copied into this one).

use std::path::Path;

/// example-robot-data's `robots/REL` in the test environment (target/py).
pub fn robot(rel: &str) -> String {
    let py = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/py/lib");
    let found = std::fs::read_dir(&py).ok().into_iter().flatten().flatten().find_map(|e| {
        let p = e.path().join("site-packages/cmeel.prefix/share/example-robot-data/robots").join(rel);
        p.exists().then_some(p)
    });
    found
        .unwrap_or_else(|| panic!("{rel}: example-robot-data is not in target/py: run scripts/setup"))
        .display()
        .to_string()
}

/// The TIAGo's arm with its torso, from `base_footprint` to `arm_tool_link`, at a
/// well-conditioned home (the tool 0.64 m ahead and 0.54 m up; the smallest singular value of
/// its Jacobian 0.22).
#[allow(dead_code)] // not every test file that includes this module runs the TIAGo
pub fn tiago() -> Vec<String> {
    [
        "--arm",
        &robot("tiago_description/robots/tiago_no_hand.urdf"),
        "--base-link",
        "base_footprint",
        "--tip-link",
        "arm_tool_link",
        "--home",
        "0.2,1.0,-0.5,-1.0,1.2,0.0,0.5,0.0",
    ]
    .map(String::from)
    .to_vec()
}

/// The PR2's right arm and torso on its omnidirectional base, from `base_footprint` to
/// `r_gripper_tool_frame`, at the SRDF's `tuck_right_arm` with the torso at 0.1 m.
pub fn pr2() -> Vec<String> {
    [
        "--arm",
        &robot("pr2_description/urdf/pr2.urdf"),
        "--tip-link",
        "r_gripper_tool_frame",
        "--srdf",
        &robot("pr2_description/srdf/pr2.srdf"),
        "--home-state",
        "tuck_right_arm",
        "--home",
        "torso_lift_joint=0.1",
        "--platform",
        "omni",
    ]
    .map(String::from)
    .to_vec()
}
