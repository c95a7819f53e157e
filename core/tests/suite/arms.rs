//! Arms described as data ([`Chain`]): the `rpr` preset is the paper's arm bit for bit
//! through [`PlanarArm`] (kinematics and whole closed-loop runs); a general planar chain
//! against the spatial product of its frames and finite differences; the `ur5` and
//! `panda` presets against Denavit–Hartenberg products written here from the published
//! tables and against the Panda's published "ready" pose; validation naming the field.

use companion_core::nalgebra::{Matrix4, SVector, Vector3};
use companion_core::{
    so3, Arm, Chain, ControlLaw, DhConvention, FrameData, Joint, JointData, JointKind, Omnidirectional,
    PaperRun, ParamError, Params, PlanarArm, Platform, Pose, Pose3, Real, Rpr, Rule, State, Unicycle,
};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

use crate::common::{car, central, check_close, trajectory_1, Plant, Q, V3};

fn bits<T: Real, const R: usize, const C: usize>(m: &companion_core::nalgebra::SMatrix<T, R, C>) -> Vec<u64> {
    m.iter().map(|x| x.as_f64().to_bits()).collect()
}

/// The chain's planar kinematics equal `Rpr`'s closed form to the last bit.
fn same_kinematics<T: Real>(q: &SVector<T, 3>) -> Result<(), TestCaseError> {
    let a = PlanarArm::new(&Chain::<T, 3>::rpr()).map_err(|e| TestCaseError::fail(format!("{e}")))?;
    let (k, r) = (a.kinematics(q), Rpr::<T>::paper().kinematics(q));
    let p = |p: &Pose<T>| [p.x.as_f64().to_bits(), p.y.as_f64().to_bits(), p.theta.as_f64().to_bits()];
    prop_assert_eq!(p(&k.r_eb), p(&r.r_eb), "r_eb at {:?}", q);
    prop_assert_eq!(bits(&k.jacobian), bits(&r.jacobian), "∂r_eb/∂q at {:?}", q);
    for h in 0..3 {
        prop_assert_eq!(bits(&k.hessian[h]), bits(&r.hessian[h]), "Hessian {} at {:?}", h, q);
    }
    prop_assert_eq!(
        (k.sin_cos_theta.0.as_f64().to_bits(), k.sin_cos_theta.1.as_f64().to_bits()),
        (r.sin_cos_theta.0.as_f64().to_bits(), r.sin_cos_theta.1.as_f64().to_bits())
    );
    prop_assert_eq!(a.is_singular(q), Rpr::<T>::paper().is_singular(q));
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn rpr_chain_is_the_papers_arm_f64(q in (-3.0..3.0, 1e-3..2.0, -3.0..3.0f64)) {
        same_kinematics::<f64>(&Q::new(q.0, q.1, q.2))?;
    }

    #[test]
    fn rpr_chain_is_the_papers_arm_f32(q in (-3.0..3.0f32, 1e-3..2.0f32, -3.0..3.0f32)) {
        same_kinematics::<f32>(&SVector::<f32, 3>::new(q.0, q.1, q.2))?;
    }
}

#[test]
fn rpr_chain_at_special_points() {
    for q in
        [Q::new(0.0, 0.35, 0.0), Q::new(-0.0, 0.45, -0.0), Q::new(0.0, 0.0, 0.0), Q::new(1.0, -0.2, -1.0)]
    {
        same_kinematics::<f64>(&q).expect("identical");
    }
}

/// Whole closed-loop runs: the laws built on `Rpr` and on the `rpr` chain give the same
/// commands and diagnostics, bit for bit, every platform, runs (a)–(d), with a delay.
#[test]
fn rpr_chain_gives_the_same_commands() {
    fn run<P: Platform<f64>, A: Arm<f64, 3>>(platform: P, arm: A, run: PaperRun, delay: f64) -> Vec<u64> {
        let mut p = Params::<f64, 3>::paper(run);
        p.velocity_limits.forward = 2.0;
        let law = ControlLaw::new(p, platform, arm).expect("valid");
        let mut plant = Plant::paper_start(V3::new(2.6, 1.0, 0.0), Q::new(0.0, 0.35, 0.0), 0.0);
        let mut st = State::new();
        let mut out = Vec::new();
        for _ in 0..400 {
            let m = plant.measurement(&trajectory_1);
            let cmd = match law.step_delayed(&mut st, &m, 1e-3, delay) {
                Ok(o) => {
                    let d = &o.diagnostics;
                    out.extend(d.e_p.iter().chain(d.e_m.iter()).map(|x| x.to_bits()));
                    out.extend([d.h_s, d.condition, d.joint_scale].map(f64::to_bits));
                    o.command
                }
                Err(r) => r.command,
            };
            let p = &cmd.platform;
            out.extend([p.v, p.v_lat, p.omega, p.v_xi].map(f64::to_bits));
            out.extend(cmd.joints.iter().map(|x| x.to_bits()));
            plant.advance(P::KIND, &cmd, &trajectory_1, 1e-3, 1);
        }
        out
    }
    let chain = PlanarArm::new(&Chain::rpr()).expect("planar");
    for r in [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D] {
        for delay in [0.0, 2.5e-3] {
            assert_eq!(
                run(Unicycle::paper(), Rpr::paper(), r, delay),
                run(Unicycle::paper(), chain, r, delay)
            );
            assert_eq!(run(car(), Rpr::paper(), r, delay), run(car(), chain, r, delay));
            assert_eq!(run(Omnidirectional, Rpr::paper(), r, delay), run(Omnidirectional, chain, r, delay));
        }
    }
}

/// A planar chain with every kind of element: offsets in x and y, fixed yaws, a joint about
/// `−z`, prismatic joints along oblique axes.
fn general_chain(yaws: [f64; 3], offsets: [f64; 4], axis: f64) -> Chain<f64, 4> {
    let j = |kind, origin: Pose3<f64>, axis: Vector3<f64>| Joint {
        kind,
        origin,
        axis,
        lower: -10.0,
        upper: 10.0,
        home: 0.3,
        max_velocity: f64::INFINITY,
    };
    let yaw = |x: f64, y: f64, a: f64| Pose3::from_xyz_rpy([x, y, 0.2], [0.0, 0.0, a]);
    Chain::new(
        yaw(offsets[0], offsets[1], yaws[0]),
        [
            j(JointKind::Revolute, Pose3::identity(), Vector3::new(0.0, 0.0, 1.0)),
            j(JointKind::Prismatic, yaw(offsets[2], 0.0, yaws[1]), Vector3::new(axis.cos(), axis.sin(), 0.0)),
            j(JointKind::Revolute, yaw(0.0, offsets[3], 0.0), Vector3::new(0.0, 0.0, -1.0)),
            j(JointKind::Revolute, yaw(0.3, -0.1, yaws[2]), Vector3::new(0.0, 0.0, 1.0)),
        ],
        yaw(0.15, 0.05, 0.4),
    )
    .expect("valid chain")
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// `r_eb` is the inverse of the spatial product of the frames (projected), and its
    /// first and second derivatives are its finite differences.
    #[test]
    fn general_planar_chain(
        yaws in prop::array::uniform3(-2.0..2.0f64),
        offsets in prop::array::uniform4(-0.5..0.5f64),
        axis in -3.0..3.0f64,
        q in prop::array::uniform4(-2.0..2.0f64),
    ) {
        let chain = general_chain(yaws, offsets, axis);
        let arm = PlanarArm::new(&chain).map_err(|e| TestCaseError::fail(format!("{e}")))?;
        let q = SVector::<f64, 4>::from(q);
        let k = arm.kinematics(&q);
        let be = chain.end_effector(&q);
        let eb = be.inverse();
        let want = V3::new(eb.translation[0], eb.translation[1], eb.rotation[(1, 0)].atan2(eb.rotation[(0, 0)]));
        let got = V3::new(k.r_eb.x, k.r_eb.y, crate::common::wrap(k.r_eb.theta));
        check_close("r_eb", &got, &want, 1e-12, 1.0)?;
        prop_assert!((k.sin_cos_theta.0 - k.r_eb.theta.sin()).abs() < 1e-12);
        let h = 1e-5;
        for i in 0..4 {
            let at = |d: f64| {
                let mut qq = q;
                qq[i] += d;
                let r = arm.kinematics(&qq);
                (V3::new(r.r_eb.x, r.r_eb.y, r.r_eb.theta), r.jacobian)
            };
            let fd = central(|d| at(d).0, 0.0, h);
            check_close("∂r_eb/∂q", &k.jacobian.column(i).into_owned(), &fd, 1e-8, 1.0)?;
            let fd2 = central(|d| at(d).1, 0.0, h);
            for (c, hess) in k.hessian.iter().enumerate() {
                let want = fd2.row(c).transpose();
                check_close("∂²r_eb/∂q²", &hess.column(i).into_owned(), &want, 1e-7, 1.0)?;
            }
        }
    }
}

/// A reference DH product, from the published tables: standard `R_z T_z T_x R_x`,
/// modified `R_x T_x R_z T_z`, with `std`'s trigonometry.
fn dh(convention: DhConvention, rows: &[(f64, f64, f64); 7], n: usize, q: &[f64]) -> Matrix4<f64> {
    let rz = |t: f64| {
        let (s, c) = t.sin_cos();
        Matrix4::new(c, -s, 0.0, 0.0, s, c, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    };
    let rx = |t: f64| {
        let (s, c) = t.sin_cos();
        Matrix4::new(1.0, 0.0, 0.0, 0.0, 0.0, c, -s, 0.0, 0.0, s, c, 0.0, 0.0, 0.0, 0.0, 1.0)
    };
    let tr = |x: f64, z: f64| {
        Matrix4::new(1.0, 0.0, 0.0, x, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, z, 0.0, 0.0, 0.0, 1.0)
    };
    let mut t = Matrix4::identity();
    for i in 0..n {
        let (a, d, alpha) = rows[i];
        t *= match convention {
            DhConvention::Standard => rz(q[i]) * tr(0.0, d) * tr(a, 0.0) * rx(alpha),
            DhConvention::Modified => rx(alpha) * tr(a, 0.0) * rz(q[i]) * tr(0.0, d),
        };
    }
    t
}

fn matrix(p: &Pose3<f64>) -> Matrix4<f64> {
    let mut m = Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&p.rotation);
    m.fixed_view_mut::<3, 1>(0, 3).copy_from(&p.translation);
    m
}

const PI: f64 = core::f64::consts::PI;
const UR5: [(f64, f64, f64); 7] = [
    (0.0, 0.089159, PI / 2.0),
    (-0.425, 0.0, 0.0),
    (-0.39225, 0.0, 0.0),
    (0.0, 0.10915, PI / 2.0),
    (0.0, 0.09465, -PI / 2.0),
    (0.0, 0.0823, 0.0),
    (0.0, 0.0, 0.0),
];
const PANDA: [(f64, f64, f64); 7] = [
    (0.0, 0.333, 0.0),
    (0.0, 0.0, -PI / 2.0),
    (0.0, 0.316, PI / 2.0),
    (0.0825, 0.0, PI / 2.0),
    (-0.0825, 0.384, -PI / 2.0),
    (0.0, 0.0, PI / 2.0),
    (0.088, 0.0, PI / 2.0),
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn ur5_is_its_dh_table(q in prop::array::uniform6(-6.0..6.0f64)) {
        let chain = Chain::<f64, 6>::ur5();
        let got = matrix(&chain.mount).try_inverse().unwrap() * matrix(&chain.end_effector(&SVector::from(q)));
        check_close("UR5 flange", &got, &dh(DhConvention::Standard, &UR5, 6, &q), 1e-12, 1.0)?;
    }

    #[test]
    fn panda_is_its_dh_table(q in prop::array::uniform7(-2.8..2.8f64)) {
        let chain = Chain::<f64, 7>::panda();
        let got = matrix(&chain.mount).try_inverse().unwrap() * matrix(&chain.end_effector(&SVector::from(q)));
        let flange = Matrix4::new_translation(&Vector3::new(0.0, 0.0, 0.107));
        check_close("Panda flange", &got, &(dh(DhConvention::Modified, &PANDA, 7, &q) * flange), 1e-12, 1.0)?;
    }
}

/// Published figures: the Panda's "ready" pose puts the end effector of Franka's hand
/// (0.1034 m beyond the flange) at (0.307, 0, 0.487) m with the hand pointing down
/// (franka_ros / libfranka examples); and the presets' homes as documented.
#[test]
fn presets_at_home() {
    let panda = Chain::<f64, 7>::panda();
    assert_eq!(panda.validate(), Ok(()));
    let flange = panda.mount.inverse().compose(&panda.end_effector(&panda.home()));
    let hand = flange.compose(&Pose3::translation(0.0, 0.0, 0.1034));
    assert!((hand.translation - Vector3::new(0.3069, 0.0, 0.4869)).amax() < 1e-4, "{}", hand.translation);
    assert!((hand.rotation.column(2) - Vector3::new(0.0, 0.0, -1.0)).amax() < 1e-12, "pointing down");
    let ur5 = Chain::<f64, 6>::ur5();
    assert_eq!(ur5.validate(), Ok(()));
    let f = ur5.end_effector(&ur5.home());
    assert!((f.translation - Vector3::new(0.5869, 0.10915, 0.9319)).amax() < 1e-4, "{}", f.translation);
    assert!((f.rotation.column(2) - Vector3::new(0.0, 0.0, -1.0)).amax() < 1e-12, "pointing down");
    let rpr = Chain::<f64, 3>::rpr();
    assert_eq!(rpr.validate(), Ok(()));
    assert_eq!(rpr.home(), Params::<f64, 3>::paper_q_star());
    assert_eq!(rpr.limits(), Params::<f64, 3>::paper_limits());
}

/// Every rule of a description, naming its field (and joint).
#[test]
fn validation_names_the_field() {
    let err = |e: Result<Chain<f64, 6>, ParamError>| e.err();
    let base = Chain::<f64, 6>::ur5();
    let mut c = base;
    c.mount.rotation[(0, 1)] += 1e-3;
    assert_eq!(
        err(Chain::new(c.mount, c.joints, c.tool)),
        Some(ParamError::new("mount.rotation", Rule::NotOrthonormal))
    );
    let mut c = base;
    c.mount.rotation = -c.mount.rotation; // a reflection: det = −1
    assert_eq!(c.validate(), Err(ParamError::new("mount.rotation", Rule::NotOrthonormal)));
    let mut c = base;
    c.tool.rotation *= 2.0;
    assert_eq!(c.validate(), Err(ParamError::new("tool.rotation", Rule::NotOrthonormal)));
    let mut c = base;
    c.joints[3].origin.rotation[(2, 2)] = f64::NAN;
    assert_eq!(c.validate(), Err(ParamError::joint("joints.origin.rotation", 3, Rule::NonFinite)));
    let mut c = base;
    c.mount.translation[2] = f64::INFINITY;
    assert_eq!(c.validate(), Err(ParamError::new("mount.translation", Rule::NonFinite)));
    let mut c = base;
    c.joints[1].axis = Vector3::new(0.0, 0.0, 2.0);
    assert_eq!(c.validate(), Err(ParamError::joint("joints.axis", 1, Rule::NotUnitVector)));
    let mut c = base;
    c.joints[2].lower = c.joints[2].upper;
    assert_eq!(c.validate(), Err(ParamError::joint("joints.lower", 2, Rule::EmptyInterval)));
    let mut c = base;
    c.joints[4].home = c.joints[4].upper;
    assert_eq!(c.validate(), Err(ParamError::joint("joints.home", 4, Rule::HomeOutsideLimits)));
    let mut c = base;
    c.joints[0].home = -7.0;
    assert_eq!(c.validate(), Err(ParamError::joint("joints.home", 0, Rule::HomeOutsideLimits)));
    let mut c = base;
    c.joints[5].max_velocity = 0.0;
    assert_eq!(c.validate(), Err(ParamError::joint("joints.max_velocity", 5, Rule::NotPositive)));
    let mut c = base;
    c.joints[5].upper = f64::NAN;
    assert_eq!(c.validate(), Err(ParamError::joint("joints.upper", 5, Rule::NonFinite)));

    // A planar arm needs planar frames and axes, and three joints.
    let rpr = Chain::<f64, 3>::rpr();
    let mut c = rpr;
    c.joints[0].axis = Vector3::new(1.0, 0.0, 0.0);
    assert_eq!(PlanarArm::new(&c).err(), Some(ParamError::joint("joints.axis", 0, Rule::NotPlanar)));
    let mut c = rpr;
    c.joints[1].axis = Vector3::new(0.0, 0.0, 1.0);
    assert_eq!(PlanarArm::new(&c).err(), Some(ParamError::joint("joints.axis", 1, Rule::NotPlanar)));
    let mut c = rpr;
    c.mount.rotation = so3::from_rpy(0.1, 0.0, 0.0);
    assert_eq!(PlanarArm::new(&c).err(), Some(ParamError::new("mount.rotation", Rule::NotPlanar)));
    let two = Chain::new(rpr.mount, [rpr.joints[0], rpr.joints[2]], rpr.tool).expect("a valid chain");
    assert_eq!(PlanarArm::new(&two).err(), Some(ParamError::new("joints", Rule::TooFewJoints)));

    // From plain numbers: the same checks, the same names.
    let frame = |xyz, rotation| FrameData { xyz, rotation };
    let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let joint = |axis, limits: [f64; 2], home| JointData {
        kind: JointKind::Revolute,
        origin: frame([0.0, 0.0, 0.1], id),
        axis,
        limits,
        home,
        max_velocity: 2.0,
    };
    let good = [joint([0.0, 0.0, 1.0], [-1.0, 1.0], 0.0); 3];
    assert!(Chain::from_arrays(&frame([0.0; 3], id), &good, &frame([0.0; 3], id)).is_ok());
    let skew = [[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    assert_eq!(
        Chain::from_arrays(&frame([0.0; 3], skew), &good, &frame([0.0; 3], id)).err(),
        Some(ParamError::new("mount.rotation", Rule::NotOrthonormal))
    );
    let mut bad = good;
    bad[2] = joint([0.0, 0.0, 1.0], [0.5, 1.0], 0.0);
    assert_eq!(
        Chain::from_arrays(&frame([0.0; 3], id), &bad, &frame([0.0; 3], id)).err(),
        Some(ParamError::joint("joints.home", 2, Rule::HomeOutsideLimits))
    );
}
