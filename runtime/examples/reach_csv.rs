//! The reach along a spatial run: for every STEP-th row of a run's `timeseries.csv`, the
//! weight Ψ the law logged, the reach coordinates of the arm's own wrist point (extension `r`,
//! clearance `c`; companion-core's `reach` module) with their σ̃, and the arm's conditioning
//! ratio ρ against the law's damping onset (`*` where ρ is below it: the damped zone).
//!
//! ```sh
//! R=target/py/lib/python3.11/site-packages/cmeel.prefix/share/example-robot-data/robots \
//!   cargo run --release -p companion-runtime --example reach_csv -- ARM RUN/timeseries.csv STEP
//! ```
//!
//! ARM: `tiago` (examples/arms/tiago-unicycle.toml's home), `pr2` (`tuck_right_arm`, torso
//! 0.1 m), `ur5` or `panda` (the presets); `R` example-robot-data's `robots` folder (the
//! URDF arms only). The reach is the chain's as the URDF gives it (not narrowed by a config's
//! `[controller.joint_limits]`). Used for the book's account of the runs (b)–(d) that miss
//! their aim (docs/book/src/your-robot.md).

use companion_core::nalgebra::SVector;
use companion_core::{Chain, PaperRun, Params, SpatialArm};
use companion_runtime::domain::arm::{ArmDescription, HomeList, UrdfRequest};
use std::path::PathBuf;

fn go<const N: usize>(chain: Chain<f64, N>, csv: &str, step: usize) {
    let arm = SpatialArm::new(&chain).unwrap();
    let p = Params::for_arm(&arm, PaperRun::A, arm.level_target(0.2)).unwrap();
    let onset = arm.onset_from_home(&p.primary, &p.joint_limits);
    let reach = *arm.reach().unwrap();
    println!("ext {:?}\nclear {:?} onset {onset:.2e}", reach.extension, reach.clearance);
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| head.iter().position(|h| *h == n).unwrap();
    let qc: Vec<usize> = (1..=N).map(|i| col(&format!("q{i}"))).collect();
    let (ct, ce, cpsi, cv, cw, cjs) =
        (col("t"), col("ep_norm"), col("psi"), col("v"), col("omega"), col("joint_scale"));
    for (k, l) in lines.enumerate() {
        if k % step != 0 {
            continue;
        }
        let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap_or(f64::NAN)).collect();
        let q = SVector::<f64, N>::from_fn(|i, _| f[qc[i]]);
        let kin = arm.kinematics(&q);
        let (r, c, _) = reach.joints.coordinates_value(&kin, None);
        let s = reach.sigma(&kin, &q, None);
        let rho = arm.ratio_at(&p.primary, &p.joint_limits, &q);
        let m = companion_core::WeightMargins::paper(&p.joint_limits, &chain.home());
        let mut js = String::new();
        for i in 0..N {
            let (sg, _) = companion_core::secondary::sigma_tilde_joint(
                q[i],
                p.joint_limits.lower[i],
                p.joint_limits.upper[i],
                &m,
                i,
            );
            if sg > 0.0 {
                js += &format!(" j{}:{sg:.2}", i + 1);
            }
        }
        // joints' own sigma
        println!("t {:6.2} ep {:.2e} psi {:.3} r {r:.4} c {c:.4} sr {:.2} sc {:.2} rho {rho:.1e}{} v {:+.2} w {:+.2} js {:.2}", f[ct], f[ce], f[cpsi], s[0], s[1], if rho < onset {"*"} else {" "}, f[cv], f[cw], f[cjs]);
        if !js.is_empty() {
            println!("        sigma{js}");
        }
    }
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    if a.len() != 4 {
        eprintln!("usage: reach_csv tiago|pr2|ur5|panda RUN/timeseries.csv STEP");
        std::process::exit(2);
    }
    let step: usize = a[3].parse().expect("STEP: a positive integer");
    let r = std::env::var("R").unwrap_or_default();
    let urdf = |path: &str, tip: &str, srdf: Option<(&str, &str)>, home: HomeList| {
        ArmDescription::from_urdf(&UrdfRequest {
            path: PathBuf::from(format!("{r}/{path}")),
            base_link: Some("base_footprint".into()),
            tip_link: Some(tip.into()),
            srdf: srdf.map(|s| PathBuf::from(format!("{r}/{}", s.0))),
            home_state: srdf.map(|s| s.1.to_string()),
            home: Some(home),
            mount: None,
        })
        .unwrap()
    };
    match a[1].as_str() {
        "tiago" => go::<8>(
            urdf(
                "tiago_description/robots/tiago_no_hand.urdf",
                "arm_tool_link",
                None,
                HomeList::Values(vec![0.175, 1.374, -0.240, -0.982, 1.66, 0.0, 0.5, 0.0]),
            )
            .chain()
            .unwrap(),
            &a[2],
            step,
        ),
        "pr2" => go::<8>(
            urdf(
                "pr2_description/urdf/pr2.urdf",
                "r_gripper_tool_frame",
                Some(("pr2_description/srdf/pr2.srdf", "tuck_right_arm")),
                HomeList::Named(vec![("torso_lift_joint".into(), 0.1)]),
            )
            .chain()
            .unwrap(),
            &a[2],
            step,
        ),
        "ur5" => go::<6>(Chain::ur5(), &a[2], step),
        _ => go::<7>(Chain::panda(), &a[2], step),
    }
}
