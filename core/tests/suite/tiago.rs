//! The PAL TIAGo on the unicycle: what run (a) asks of a real arm, and the reach and joint
//! speeds that decide whether it settles ([`companion_core::spatial`]'s module docs, "What run
//! (a) asks of the arm").
//!
//! The chain is PAL's as example-robot-data 6.0.0's `tiago_no_hand.urdf` describes it from
//! `base_footprint` to `arm_tool_link`: a prismatic torso (0–0.35 m at 0.07 m/s) and a
//! seven-joint arm (`arm_1` … `arm_7`, 1.76–4.58 rad/s), its origins, axes, limits and speeds
//! typed here from the file (the suite reads nothing outside the repository; the runtime's
//! URDF reader is held to Pinocchio on the file itself). Every run is the paper's run (a) on
//! lifted trajectory 1 from the paper's start, the target 0.2 m along the tool's `z` as
//! `sim --arm` places it, with the law as `sim --arm` builds it (the damping onset from the
//! home).

use companion_core::nalgebra::{SVector, Vector3};
use companion_core::{
    Chain, ControlLaw, Joint, JointKind, Omnidirectional, PaperRun, Params, Platform, Pose3, Spatial,
    SpatialArm, State, Unicycle,
};

use crate::spatial::{lifted_for, simulate, Run, SpatialPlant};

/// The URDF's right angle (its digits, as the file writes it: not `FRAC_PI_2`).
#[allow(clippy::approx_constant)]
const H: f64 = 1.57079632679;

fn joint(
    kind: JointKind,
    xyz: [f64; 3],
    rpy: [f64; 3],
    limits: [f64; 2],
    home: f64,
    speed: f64,
) -> Joint<f64> {
    Joint {
        kind,
        origin: Pose3::from_xyz_rpy(xyz, rpy),
        axis: Vector3::new(0.0, 0.0, 1.0),
        lower: limits[0],
        upper: limits[1],
        home,
        max_velocity: speed,
    }
}

/// The TIAGo from `base_footprint` to `arm_tool_link` at `home` (torso, `arm_1` … `arm_7`), with
/// the URDF's digits (`arm_4`'s lower limit and the tool's yaw are not `FRAC_PI_8` and `PI`).
#[allow(clippy::approx_constant)]
fn tiago_chain(home: [f64; 8]) -> Chain<f64, 8> {
    use JointKind::{Prismatic as P, Revolute as R};
    let joints = [
        joint(P, [0.0, 0.0, 0.597], [0.0; 3], [0.0, 0.35], home[0], 0.07),
        joint(R, [0.15505, 0.014, -0.151], [0.0, 0.0, -H], [0.0, 2.74889357189], home[1], 2.7),
        joint(R, [0.125, 0.0165, -0.031], [H, 0.0, 0.0], [-H, 1.0908307825], home[2], 3.66),
        joint(R, [0.0895, 0.0, 0.0015], [-H, 0.0, H], [-3.53429173529, H], home[3], 4.58),
        joint(R, [-0.02, -0.027, -0.222], [-H, -H, 0.0], [-0.392699081699, 2.35619449019], home[4], 4.58),
        joint(R, [-0.162, 0.02, 0.027], [0.0, -H, 0.0], [-2.09439510239, 2.09439510239], home[5], 1.95),
        joint(R, [0.0, 0.0, 0.15], [0.0, -H, -H], [-1.41371669412, 1.41371669412], home[6], 1.76),
        joint(R, [0.0; 3], [H, 0.0, H], [-2.09439510239, 2.09439510239], home[7], 1.76),
    ];
    // base_footprint → base_link (0.0985 up) → torso_fixed_link (−0.062, 0.193 up): the mount.
    let mount = Pose3::translation(-0.062, 0.0, 0.2915);
    let tool = Pose3::from_xyz_rpy([0.0, 0.0, 0.046], [H, -H, 3.14159265359]);
    Chain::new(mount, joints, tool).expect("the TIAGo's chain is valid")
}

/// The home the runs used: the tool 0.64 m ahead and 0.54 m up, well conditioned, but
/// with the arm nearly stretched.
const STRETCHED: [f64; 8] = [0.2, 1.0, -0.5, -1.0, 1.2, 0.0, 0.5, 0.0];

/// A home with reach both ways: every joint at the middle of its range but the elbow (`arm_4`),
/// bent to the middle of the reach — the shoulder–wrist distance 0.450 m, halfway between
/// 0.274 m (folded) and 0.625 m (stretched) — and the wrist's pitch (`arm_6`) 0.5 rad off
/// 0, where `arm_5` and `arm_7` would turn about one axis.
const MID_REACH: [f64; 8] = [0.175, 1.374, -0.240, -0.982, 1.66, 0.0, 0.5, 0.0];

/// The unicycle's transverse function the TIAGo needs (module docs of `spatial`): `ε₁` inside
/// the arm's reserve of reach from [`MID_REACH`] (0.175 m), `ε₂` wide enough to slow the
/// platform's forward manoeuvres to what the wrist can hold the tool's orientation through.
const TIAGO_UNICYCLE: (f64, f64) = (0.15, 1.5);

/// The law as `sim --arm` builds it for the TIAGo at `home`.
fn tiago(home: [f64; 8]) -> (SpatialArm<f64, 8>, Params<f64, 8, Spatial>) {
    let arm = SpatialArm::new(&tiago_chain(home)).expect("valid");
    let p = Params::for_arm(&arm, PaperRun::A, arm.level_target(0.2)).expect("valid");
    let (_, depth) = arm.damping();
    let arm = arm.with_damping(arm.onset_from_home(&p.primary, &p.joint_limits), depth).expect("valid");
    (arm, p)
}

/// Run (a) of lifted trajectory 1 from `home` on `platform`, 40 s at 1 ms, the last 10 s
/// summed up.
fn lifted_1a<P: Platform<f64>>(home: [f64; 8], platform: P) -> Run {
    let (arm, p) = tiago(home);
    let target = lifted_for(&arm, &p.primary.target_in_effector);
    simulate(&ControlLaw::new(p, platform, arm).expect("valid"), &target, 0.0, 1e-3, 40.0, 10.0)
}

/// The shoulder–wrist distance (`arm_2`'s axis point to `arm_6`'s) at `q`.
fn shoulder_to_wrist(arm: &SpatialArm<f64, 8>, q: &SVector<f64, 8>) -> f64 {
    let k = arm.kinematics(q);
    (k.points.column(6) - k.points.column(2)).norm()
}

/// From [`MID_REACH`] with [`TIAGO_UNICYCLE`], run (a) of lifted trajectory 1 settles: every
/// component of `e_p` at most 1e−5 over the last 10 s of 40, no step refused, the joints inside
/// their limits and the joint guard idle over those 10 s (the published speeds are met). On the
/// omnidirectional platform the same home settles too.
#[test]
fn tiago_unicycle_tracks_lifted_trajectory_1() {
    let (e1, e2) = TIAGO_UNICYCLE;
    let run = lifted_1a(MID_REACH, Unicycle::new(e1, e2));
    std::println!("TIAGo unicycle ({e1}, {e2}) (a): {run:?}");
    assert_eq!(run.rejected, 0);
    assert!(run.e_p_tail.amax() <= 1e-5, "e_p over the last 10 s: {}", run.e_p_tail);
    assert!(run.margin > 0.0, "joints inside their limits: margin {}", run.margin);
    assert_eq!(run.joint_scale_tail, 1.0, "the published speeds are met");
    let omni = lifted_1a(MID_REACH, Omnidirectional);
    assert_eq!(omni.rejected, 0);
    assert!(omni.e_p_tail.amax() <= 1e-5, "omni: e_p {}", omni.e_p_tail);
    assert!(omni.margin > 0.0);
}

/// Why the paper's transverse function `(0.2, 0.4)` does not do for the TIAGo, from the same
/// home: run (a)'s steady manoeuvres are the platform's, whatever the arm (the platform law
/// does not see it), at up to 0.83 m/s; the TIAGo's wrist (`arm_5` … `arm_7`, 1.76–1.95 rad/s)
/// cannot turn the tool back through them, so the joint guard slows the whole arm over the
/// last 10 s and `e_p` stays above 1e−3. With [`TIAGO_UNICYCLE`] the same manoeuvres take at
/// most 0.5 m/s and the guard is idle (previous test).
#[test]
fn with_the_papers_function_the_tiagos_wrist_cannot_follow() {
    let paper = lifted_1a(MID_REACH, Unicycle::paper());
    let (e1, e2) = TIAGO_UNICYCLE;
    let wide = lifted_1a(MID_REACH, Unicycle::new(e1, e2));
    std::println!("TIAGo unicycle, the paper's function: {paper:?}\n  ({e1}, {e2}): {wide:?}");
    assert!(paper.speed_tail > 0.8, "the paper's manoeuvres: {} m/s", paper.speed_tail);
    assert!(paper.joint_scale_tail > 1.5, "the guard slows the arm: {}", paper.joint_scale_tail);
    assert!(paper.e_p_tail.amax() > 1e-3, "e_p {}", paper.e_p_tail);
    assert!(wide.speed_tail < 0.5, "the wider function's manoeuvres: {} m/s", wide.speed_tail);
}

/// Why the home does not settle, whatever the transverse function: at [`STRETCHED`] the
/// arm has 0.09 m of reach left (shoulder–wrist 0.536 m of 0.625 m), less than the paper's
/// `ε₁ = 0.2 m` the platform's manoeuvres move the target by. In run (a) the elbow straightens
/// — the shoulder–wrist distance within 2 cm of its largest on 71 % of the steps after 12 s —
/// and the redundant solution's `S = A W⁻¹ Aᵀ` is below the damping onset (its Hadamard ratio
/// at the joints reached, [`SpatialArm::ratio_at`]) on 54 %: the law gives up the unreachable
/// part of the task, as it should, and `e_p` stays above 1e−2 (0.18 over the last 10 s).
#[test]
fn from_the_stretched_home_the_target_is_out_of_reach() {
    let (arm, p) = tiago(STRETCHED);
    let home = arm.chain().home();
    // The largest shoulder–wrist distance over the elbow's range (the other joints at home).
    let (lo, hi) = (arm.chain().joints[4].lower, arm.chain().joints[4].upper);
    let longest = (0..=1000)
        .map(|k| {
            let mut q = home;
            q[4] = lo + (hi - lo) * f64::from(k) / 1000.0;
            shoulder_to_wrist(&arm, &q)
        })
        .fold(0.0, f64::max);
    let reserve = longest - shoulder_to_wrist(&arm, &home);
    assert!((0.08..0.1).contains(&reserve), "reach left at home: {reserve} m");
    let mid = tiago(MID_REACH).0;
    let mid_reserve = longest - shoulder_to_wrist(&mid, &mid.chain().home());
    assert!(mid_reserve > TIAGO_UNICYCLE.0, "reach left from the mid-reach home: {mid_reserve} m");

    // Run (a), the paper's function, with the law's own measure at every step.
    let law = ControlLaw::new(p, Unicycle::paper(), arm).expect("valid");
    let target = lifted_for(&arm, &p.primary.target_in_effector);
    let (onset, _) = arm.damping();
    let mut plant = SpatialPlant { t: 0.0, base: Vector3::zeros(), xi: 0.0, q: home };
    let mut st = State::new();
    let (mut steps, mut damped, mut stretched) = (0usize, 0usize, 0usize);
    let mut e_p_tail: f64 = 0.0;
    for _ in 0..40_000 {
        let m = plant.measurement(&target);
        let o = law.step(&mut st, &m, 1e-3).expect("no step refused");
        if plant.t >= 12.0 {
            steps += 1;
            damped += usize::from(arm.ratio_at(&p.primary, &p.joint_limits, &plant.q) < onset);
            stretched += usize::from(shoulder_to_wrist(&arm, &plant.q) > longest - 0.02);
        }
        if plant.t >= 30.0 {
            e_p_tail = e_p_tail.max(o.diagnostics.e_p.norm());
        }
        plant.advance(<Unicycle<f64> as Platform<f64>>::KIND, &o.command, 1e-3);
    }
    let (damped, stretched) = (damped as f64 / steps as f64, stretched as f64 / steps as f64);
    std::println!("TIAGo stretched home: damped {damped:.3}, stretched {stretched:.3}, e_p {e_p_tail:.2e}");
    assert!(damped > 0.4, "damped on {damped} of the steps");
    assert!(stretched > 0.5, "elbow straight on {stretched} of the steps");
    assert!(e_p_tail > 1e-2, "e_p over the last 10 s: {e_p_tail}");
}

/// [`Unicycle::manoeuvres`] (from `H̄(α)⁻¹` alone) against the closed loop: the platform's
/// largest forward speed over the last 10 s of run (a) on lifted trajectory 1 (`π/20 m/s`) is
/// the function's `v_max` within 5 % for the paper's `(0.2, 0.4)`, the Panda's `(0.2, 0.8)` and
/// the TIAGo's `(0.15, 1.5)` (0.83, 0.54, 0.47 m/s measured; 0.86, 0.54, 0.47 computed): the
/// speeds those settings ask the arm to follow, known before a run.
#[test]
fn the_manoeuvres_are_known_from_the_transverse_function() {
    for (e1, e2) in [(0.2, 0.4), (0.2, 0.8), TIAGO_UNICYCLE] {
        let unicycle = Unicycle::new(e1, e2);
        let (v_max, w_max) = unicycle.manoeuvres(core::f64::consts::PI / 20.0, 720);
        let run = lifted_1a(MID_REACH, unicycle);
        std::println!(
            "({e1}, {e2}): v_max {v_max:.3} m/s, w_max {w_max:.3} rad/s; measured {:.3}",
            run.speed_tail
        );
        assert!(
            (run.speed_tail - v_max).abs() <= 0.05 * v_max,
            "({e1}, {e2}): {} against {v_max}",
            run.speed_tail
        );
    }
    // Small ε: 2u/ε₂ and 2u/ε₁.
    let u: f64 = 0.01;
    let (v, w) = Unicycle::<f64>::new(0.02, 0.04).manoeuvres(u, 720);
    assert!((v - 2.0 * u / 0.04).abs() < 0.01 * v && (w - 2.0 * u / 0.02).abs() < 0.01 * w, "{v} {w}");
}
