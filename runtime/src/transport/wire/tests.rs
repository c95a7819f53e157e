use core::mem::offset_of;

use companion_core::nalgebra::{SVector, Vector3, Vector6};
use companion_core::{Command, Field, Measurement, Planar, PlatformKind, Pose, Pose3, Spatial, StepError};
use iceoryx2::prelude::ZeroCopySend;

use super::*;

fn meas() -> Measurement<f64, 3> {
    Measurement {
        t: 1.5,
        base: Pose::new(0.1, -0.2, 0.3),
        steering: 0.0,
        joints: SVector::<f64, 3>::new(0.1, 0.35, -0.2),
        target: Pose::new(2.6, 1.0, 0.0),
        target_velocity: Vector3::new(0.0, -0.157, 0.0),
    }
}

fn header() -> MeasurementHeader {
    MeasurementHeader {
        seq: 7,
        flags: flags::LOCKSTEP,
        session: 42,
        scenario_hash: 9,
        arm_hash: 0xa5,
        plant_time_ns: 123_456,
        period_ns: 1_000_000,
        dt: 1e-3,
        delay: 2.5e-4,
        platform: platform::UNICYCLE,
        hold_periods: 20,
    }
}

fn identity() -> ControllerIdentity {
    ControllerIdentity {
        platform: platform::UNICYCLE,
        joint_count: 3,
        space: target::space::PLANAR,
        arm_hash: 0xa5,
        scenario_hash: 9,
        max_dt: 0.01,
    }
}

fn command_header() -> CommandHeader {
    CommandHeader { identity: identity(), flags: 0, received_ns: 200_000, skipped: 0, delay: 2.5e-4 }
}

fn good_command() -> CommandMsg {
    let m = MeasurementMsg::new(header(), &meas());
    let diag = LoggedDiagnostics {
        ep_norm: 0.5,
        h_s: 0.1,
        psi: 1.0,
        saturation: 1.0,
        alpha_rate: [0.2, 0.0],
        joint_scale: 1.25,
    };
    let mut cmd = Command::<f64, 3>::zero();
    cmd.platform.v = 0.3;
    cmd.platform.omega = -0.1;
    cmd.joints[1] = 0.05;
    CommandMsg::answer(&m, &command_header(), &cmd, None, &diag)
}

/// `(field, offset)` of every field, in order.
fn measurement_fields() -> Vec<(&'static str, usize)> {
    vec![
        ("version", offset_of!(MeasurementMsg, version)),
        ("flags", offset_of!(MeasurementMsg, flags)),
        ("seq", offset_of!(MeasurementMsg, seq)),
        ("session", offset_of!(MeasurementMsg, session)),
        ("scenario_hash", offset_of!(MeasurementMsg, scenario_hash)),
        ("arm_hash", offset_of!(MeasurementMsg, arm_hash)),
        ("plant_time_ns", offset_of!(MeasurementMsg, plant_time_ns)),
        ("period_ns", offset_of!(MeasurementMsg, period_ns)),
        ("sim_time", offset_of!(MeasurementMsg, sim_time)),
        ("dt", offset_of!(MeasurementMsg, dt)),
        ("delay", offset_of!(MeasurementMsg, delay)),
        ("platform", offset_of!(MeasurementMsg, platform)),
        ("hold_periods", offset_of!(MeasurementMsg, hold_periods)),
        ("joint_count", offset_of!(MeasurementMsg, joint_count)),
        ("space", offset_of!(MeasurementMsg, space)),
        ("base", offset_of!(MeasurementMsg, base)),
        ("steering", offset_of!(MeasurementMsg, steering)),
        ("target_position", offset_of!(MeasurementMsg, target_position)),
        ("target_rotation", offset_of!(MeasurementMsg, target_rotation)),
        ("target_yaw", offset_of!(MeasurementMsg, target_yaw)),
        ("target_twist", offset_of!(MeasurementMsg, target_twist)),
        ("joints", offset_of!(MeasurementMsg, joints)),
    ]
}

fn command_fields() -> Vec<(&'static str, usize)> {
    vec![
        ("version", offset_of!(CommandMsg, version)),
        ("status", offset_of!(CommandMsg, status)),
        ("seq", offset_of!(CommandMsg, seq)),
        ("session", offset_of!(CommandMsg, session)),
        ("plant_time_ns", offset_of!(CommandMsg, plant_time_ns)),
        ("compute_ns", offset_of!(CommandMsg, compute_ns)),
        ("received_ns", offset_of!(CommandMsg, received_ns)),
        ("skipped", offset_of!(CommandMsg, skipped)),
        ("joint_count", offset_of!(CommandMsg, joint_count)),
        ("flags", offset_of!(CommandMsg, flags)),
        ("platform", offset_of!(CommandMsg, platform)),
        ("scenario_hash", offset_of!(CommandMsg, scenario_hash)),
        ("arm_hash", offset_of!(CommandMsg, arm_hash)),
        ("space", offset_of!(CommandMsg, space)),
        ("reserved", offset_of!(CommandMsg, reserved)),
        ("delay", offset_of!(CommandMsg, delay)),
        ("v", offset_of!(CommandMsg, v)),
        ("v_lat", offset_of!(CommandMsg, v_lat)),
        ("omega", offset_of!(CommandMsg, omega)),
        ("v_xi", offset_of!(CommandMsg, v_xi)),
        ("joints", offset_of!(CommandMsg, joints)),
        ("ep_norm", offset_of!(CommandMsg, ep_norm)),
        ("h_s", offset_of!(CommandMsg, h_s)),
        ("psi", offset_of!(CommandMsg, psi)),
        ("saturation", offset_of!(CommandMsg, saturation)),
        ("alpha_rate", offset_of!(CommandMsg, alpha_rate)),
        ("joint_scale", offset_of!(CommandMsg, joint_scale)),
    ]
}

/// The size in bytes of a documented type (`u32`, `u64`, `f64`, `f64[n]`).
fn type_size(t: &str) -> usize {
    match t {
        "u32" => 4,
        "u64" | "f64" => 8,
        _ => {
            let n = t.strip_prefix("f64[").and_then(|r| r.strip_suffix(']')).expect(t);
            8 * n.parse::<usize>().expect(t)
        }
    }
}

/// Checks a documented layout `(offset, type, field)` against the struct's fields and size.
fn check_layout(what: &str, doc: &[(usize, String, String)], fields: &[(&str, usize)], size: usize) {
    let names: Vec<&str> = doc.iter().map(|r| r.2.as_str()).collect();
    let expected: Vec<&str> = fields.iter().map(|f| f.0).collect();
    assert_eq!(names, expected, "{what}: documented fields");
    for ((off, ty, name), (_, real)) in doc.iter().zip(fields) {
        assert_eq!(off, real, "{what}: offset of {name}");
        let _ = ty;
    }
    // Contiguous, no padding, and the last field ends at the struct's size.
    for w in doc.windows(2) {
        assert_eq!(w[0].0 + type_size(&w[0].1), w[1].0, "{what}: {} is followed by a gap", w[0].2);
    }
    let last = doc.last().unwrap();
    assert_eq!(last.0 + type_size(&last.1), size, "{what}: size");
}

/// The rows `offset type field` of the text block after the line containing `title`, in
/// `text` (the module docs: `//!` lines).
fn module_doc_layout(text: &str, title: &str) -> Vec<(usize, String, String)> {
    let mut rows = Vec::new();
    let mut inside = false;
    for line in text.lines().map(|l| l.trim_start_matches("//!").trim()) {
        if line.contains(title) {
            inside = true;
            continue;
        }
        if inside {
            let f: Vec<&str> = line.split_whitespace().collect();
            if let [off, ty, name, ..] = f[..] {
                if let Ok(o) = off.parse::<usize>() {
                    rows.push((o, ty.to_string(), name.to_string()));
                    continue;
                }
            }
            if !rows.is_empty() && line.starts_with("```") {
                break;
            }
        }
    }
    rows
}

/// The rows `| offset | type | field | …` of the first table after the heading containing
/// `title` in the protocol document.
fn protocol_doc_layout(text: &str, title: &str) -> Vec<(usize, String, String)> {
    let mut rows = Vec::new();
    let mut inside = false;
    for line in text.lines() {
        if line.starts_with('#') {
            if inside && !rows.is_empty() {
                break;
            }
            inside = line.contains(title);
            continue;
        }
        if inside && line.starts_with('|') {
            let cells: Vec<&str> = line.trim_matches('|').split('|').map(str::trim).collect();
            if let [off, ty, name, ..] = cells[..] {
                if let Ok(o) = off.parse::<usize>() {
                    rows.push((o, ty.trim_matches('`').to_string(), name.trim_matches('`').to_string()));
                }
            }
        } else if inside && !rows.is_empty() && !line.starts_with('|') {
            break;
        }
    }
    rows
}

#[test]
fn module_docs_and_protocol_document_give_the_real_layouts() {
    let module = include_str!("mod.rs");
    let protocol = include_str!("../../../../docs/book/src/bridge.md");
    for (what, doc) in [
        ("module docs", module_doc_layout(module, "Layout of [`MeasurementMsg`]")),
        ("docs/book/src/bridge.md", protocol_doc_layout(protocol, "MeasurementMsg")),
    ] {
        check_layout(&format!("{what}, measurement"), &doc, &measurement_fields(), MEASUREMENT_SIZE);
    }
    for (what, doc) in [
        ("module docs", module_doc_layout(module, "Layout of [`CommandMsg`]")),
        ("docs/book/src/bridge.md", protocol_doc_layout(protocol, "CommandMsg")),
    ] {
        check_layout(&format!("{what}, command"), &doc, &command_fields(), COMMAND_SIZE);
    }
    assert!(protocol.contains(MEASUREMENT_TYPE_NAME) && protocol.contains(COMMAND_TYPE_NAME));
}

#[test]
fn bytes_follow_the_in_memory_layout() {
    let m = MeasurementMsg::new(header(), &meas());
    let b = m.to_bytes();
    assert_eq!(MeasurementMsg::from_bytes(&b), m);
    // Offsets written out from docs/book/src/bridge.md, independently of the struct.
    assert_eq!(&b[0..4], &4u32.to_le_bytes());
    assert_eq!(&b[8..16], &7u64.to_le_bytes());
    assert_eq!(&b[32..40], &0xa5u64.to_le_bytes());
    assert_eq!(&b[72..80], &2.5e-4f64.to_le_bytes());
    assert_eq!(&b[80..84], &1u32.to_le_bytes());
    assert_eq!(&b[92..96], &1u32.to_le_bytes());
    assert_eq!(&b[128..136], &2.6f64.to_le_bytes());
    assert_eq!(&b[152..160], &1.0f64.to_le_bytes());
    assert_eq!(&b[232 + 8..232 + 16], &(-0.157f64).to_le_bytes());
    assert_eq!(&b[280 + 8..280 + 16], &0.35f64.to_le_bytes());
    let c = good_command();
    let b = c.to_bytes();
    assert_eq!(CommandMsg::from_bytes(&b), c);
    assert_eq!(&b[72..80], &0xa5u64.to_le_bytes());
    assert_eq!(&b[80..84], &1u32.to_le_bytes());
    assert_eq!(&b[96..104], &0.3f64.to_le_bytes());
    assert_eq!(&b[128 + 8..128 + 16], &0.05f64.to_le_bytes());
    assert_eq!(&b[240..248], &1.25f64.to_le_bytes());
}

#[test]
fn measurement_round_trips() {
    let m = meas();
    let msg = MeasurementMsg::new(header(), &m);
    assert_eq!(msg.joint_count, 3);
    assert_eq!(msg.measurement::<3>(), Some(m));
    assert_eq!(msg.measurement::<2>(), None);
    assert_eq!(msg.read::<2, Planar>(), Err(WireError::JointCount(3)));
    assert!(msg.has(flags::LOCKSTEP) && !msg.has(flags::END_OF_RUN));
    // A planar target on the wire: z = 0, a rotation about z, twist (v₁, v₂, 0, 0, 0, ω).
    assert_eq!(msg.space, target::space::PLANAR);
    assert_eq!(msg.target_position, [2.6, 1.0, 0.0]);
    assert_eq!(msg.target_rotation, [1.0, -0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    assert_eq!(msg.target_twist, [0.0, -0.157, 0.0, 0.0, 0.0, 0.0]);
    // A spatial controller reads it as the lifted target; a planar one refuses a spatial one.
    assert_eq!(msg.read::<3, Spatial>(), Err(WireError::Changed));
    assert_eq!(msg.read::<3, Planar>(), Ok(m));
}

#[test]
fn a_spatial_measurement_of_eight_joints_round_trips() {
    let target = Pose3::exp(&Vector6::new(1.5, 0.2, 0.6, 0.3, -0.4, 1.1));
    let m = Measurement::<f64, 8, Spatial> {
        t: 0.25,
        base: Pose::new(0.1, -0.2, 0.3),
        steering: 0.0,
        joints: SVector::<f64, 8>::from_fn(|i, _| 0.1 * f64::from(u8::try_from(i).unwrap()) - 0.3),
        target,
        target_velocity: Vector6::new(0.01, 0.02, 0.03, 0.04, 0.05, 0.06),
    };
    let msg = MeasurementMsg::new(header(), &m);
    assert_eq!((msg.space, msg.joint_count), (target::space::SPATIAL, 8));
    assert_eq!(msg.target_yaw, target.rotation[(1, 0)].atan2(target.rotation[(0, 0)]));
    let back = MeasurementMsg::from_bytes(&msg.to_bytes());
    assert_eq!(back.read::<8, Spatial>(), Ok(m));
    assert_eq!(back.read::<8, Planar>(), Err(WireError::Changed));
    // A rotation that is not one is malformed.
    let mut bad = back;
    bad.target_rotation[0] = 2.0;
    assert_eq!(bad.read::<8, Spatial>(), Err(WireError::NotARotation));
    // A planar message claiming a target off the plane is malformed.
    let mut off = MeasurementMsg::new(header(), &meas());
    off.target_position[2] = 0.3;
    assert_eq!(off.read::<3, Planar>(), Err(WireError::NotPlanar));
    // Eight joint velocities come back.
    let mut cmd = Command::<f64, 8>::zero();
    cmd.joints[7] = -0.75;
    let id = ControllerIdentity { joint_count: 8, space: target::space::SPATIAL, ..identity() };
    let c = CommandMsg::answer(
        &msg,
        &CommandHeader { identity: id, ..command_header() },
        &cmd,
        None,
        &LoggedDiagnostics::IDLE,
    );
    assert_eq!(check_command::<8>(&c, 42, 7), Ok(()));
    assert_eq!(c.command::<8>().joints[7], -0.75);
    assert_eq!((c.space, c.arm_hash), (target::space::SPATIAL, 0xa5));
}

#[test]
fn every_step_error_round_trips_through_status() {
    let mut all = vec![
        None,
        Some(StepError::BadTimeStep),
        Some(StepError::SingularArm),
        Some(StepError::SingularTaskJacobian),
        Some(StepError::NumericalFailure),
        Some(StepError::BadDelay),
        Some(StepError::TargetYawUndefined),
    ];
    for f in [
        Field::Time,
        Field::BasePose,
        Field::Steering,
        Field::Joints,
        Field::TargetPose,
        Field::TargetVelocity,
    ] {
        all.push(Some(StepError::NonFinite(f)));
    }
    for j in 0..3 {
        all.push(Some(StepError::JointAtLimit(j)));
    }
    for e in all {
        assert_eq!(decode_status(encode_status(e)), Ok(e));
        assert!(!refusal::is_refusal(encode_status(e)));
    }
    assert_eq!(decode_status(0x106), Err(WireError::Status(0x106)));
    assert_eq!(decode_status(0x7), Err(WireError::Status(0x7)));
    assert_eq!(decode_status(0x300 + 8), Err(WireError::Status(0x308)));
}

#[test]
fn a_good_command_passes_and_carries_the_controllers_identity() {
    let c = good_command();
    assert_eq!(check_command::<3>(&c, 42, 7), Ok(()));
    assert_eq!(c.command::<3>().platform.v, 0.3);
    assert_eq!((c.platform, c.scenario_hash, c.delay), (platform::UNICYCLE, 9, 2.5e-4));
}

#[test]
fn malformed_commands_are_rejected_with_their_reason() {
    let c = good_command();
    assert_eq!(check_command::<3>(&CommandMsg { version: 1, ..c }, 42, 7), Err(WireError::Version(1)));
    assert_eq!(check_command::<3>(&c, 43, 7), Err(WireError::Session));
    assert_eq!(check_command::<3>(&c, 42, 8), Err(WireError::Stale(7)));
    assert_eq!(check_command::<3>(&c, 42, 6), Err(WireError::Future(7)));
    assert_eq!(check_command::<3>(&CommandMsg { joint_count: 4, ..c }, 42, 7), Err(WireError::JointCount(4)));
    assert_eq!(check_command::<3>(&CommandMsg { status: 0x999, ..c }, 42, 7), Err(WireError::Status(0x999)));
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        assert_eq!(check_command::<3>(&CommandMsg { v: bad, ..c }, 42, 7), Err(WireError::NonFinite));
        assert_eq!(check_command::<3>(&CommandMsg { omega: bad, ..c }, 42, 7), Err(WireError::NonFinite));
        assert_eq!(check_command::<3>(&CommandMsg { v_lat: bad, ..c }, 42, 7), Err(WireError::NonFinite));
        assert_eq!(check_command::<3>(&CommandMsg { v_xi: bad, ..c }, 42, 7), Err(WireError::NonFinite));
        let mut joints = c.joints;
        joints[2] = bad;
        assert_eq!(check_command::<3>(&CommandMsg { joints, ..c }, 42, 7), Err(WireError::NonFinite));
    }
    // NaN diagnostics (a rejected step) are not velocities: accepted.
    let rejected = CommandMsg { status: 0x400, ep_norm: f64::NAN, h_s: f64::NAN, ..c };
    assert_eq!(check_command::<3>(&rejected, 42, 7), Ok(()));
    // Unused joint slots are not checked.
    let mut joints = c.joints;
    joints[5] = f64::NAN;
    assert_eq!(check_command::<3>(&CommandMsg { joints, ..c }, 42, 7), Ok(()));
}

#[test]
fn a_refusal_ends_the_run_whatever_its_sequence_number_and_names_both_sides() {
    let m = MeasurementMsg { joint_count: 4, ..MeasurementMsg::new(header(), &meas()) };
    let why = identity().admit(&m).unwrap_err();
    assert_eq!(why, Refusal::JointCount { plant: 4, controller: 3 });
    let c = CommandMsg::refusal::<3>(&m, &command_header(), &why);
    assert_eq!(c.command::<3>(), Command::zero());
    assert_eq!(check_command::<3>(&c, 42, 99), Err(WireError::Refused(refusal::JOINT_COUNT)));
    // Another session's refusal is not ours.
    assert_eq!(check_command::<3>(&c, 41, 7), Err(WireError::Session));
    // The plant reads the same refusal from the command and its own measurement.
    assert_eq!(Refusal::from_command(&c, &m), Some(why));
    let text = why.to_string();
    assert!(text.contains("4 joints") && text.contains("built for 3"), "{text}");
}

#[test]
fn the_controller_admits_only_a_plant_it_can_serve() {
    let id = identity();
    let m = MeasurementMsg::new(header(), &meas());
    let a = id.admit(&m).unwrap();
    assert!(a.lockstep() && !a.notifies());
    assert_eq!((a.hold_periods, a.platform), (20, platform::UNICYCLE));
    let cases = [
        (MeasurementMsg { version: 3, ..m }, Refusal::Version { plant: 3 }),
        (MeasurementMsg { space: target::space::SPATIAL, ..m }, Refusal::Space { plant: 2, controller: 1 }),
        (MeasurementMsg { arm_hash: 0xb6, ..m }, Refusal::Arm { plant: 0xb6, controller: 0xa5 }),
        (MeasurementMsg { platform: platform::CAR, ..m }, Refusal::Platform { plant: 2, controller: 1 }),
        (MeasurementMsg { platform: 0, ..m }, Refusal::Platform { plant: 0, controller: 1 }),
        (MeasurementMsg { scenario_hash: 10, ..m }, Refusal::Scenario { plant: 10, controller: 9 }),
        (MeasurementMsg { dt: 0.02, ..m }, Refusal::Period { dt: 0.02 }),
        (MeasurementMsg { dt: 0.0, ..m }, Refusal::Period { dt: 0.0 }),
    ];
    for (msg, why) in cases {
        assert_eq!(id.admit(&msg), Err(why));
        let c = CommandMsg::refusal::<3>(&msg, &command_header(), &why);
        assert_eq!(Refusal::from_command(&c, &msg), Some(why), "{why}");
    }
    // 0 on either side: the scenario (the arm) is not checked.
    assert!(id.admit(&MeasurementMsg { scenario_hash: 0, ..m }).is_ok());
    assert!(id.admit(&MeasurementMsg { arm_hash: 0, ..m }).is_ok());
    assert!(ControllerIdentity { arm_hash: 0, ..id }.admit(&MeasurementMsg { arm_hash: 5, ..m }).is_ok());
    // The refusals name both sides: a v3 plant, a spatial plant, a UR5 against a Panda.
    let v = Refusal::Version { plant: 3 }.to_string();
    assert!(v.contains("plant speaks version 3, the controller version 4"), "{v}");
    let sp = Refusal::Space { plant: 2, controller: 1 }.to_string();
    assert!(sp.contains("target is spatial (SE(3))") && sp.contains("tracks a planar (SE(2)) one"), "{sp}");
    let (ur5, panda) = (
        canonical::arm_hash(&companion_core::Chain::<f64, 6>::ur5()),
        canonical::arm_hash(&companion_core::Chain::<f64, 7>::panda()),
    );
    let a = Refusal::Arm { plant: ur5, controller: panda }.to_string();
    assert!(a.contains("the plant's arm is ur5 (0x") && a.contains("built for panda (0x"), "{a}");
    assert!(ControllerIdentity { scenario_hash: 0, ..id }
        .admit(&MeasurementMsg { scenario_hash: 5, ..m })
        .is_ok());
    let p = Refusal::Platform { plant: 2, controller: 1 }.to_string();
    assert!(p.contains("car-like") && p.contains("unicycle"), "{p}");
    assert_eq!(platform::kind(platform::code(PlatformKind::Omni)), Some(PlatformKind::Omni));
}

#[test]
fn measurements_of_a_session_are_checked_for_order_session_and_announcement() {
    let m = MeasurementMsg::new(header(), &meas());
    let a = Announcement::of(&m);
    assert_eq!(check_measurement(&m, 42, &a, Some(6)), Ok(()));
    assert_eq!(check_measurement(&m, 42, &a, Some(7)), Err(WireError::Stale(7)));
    assert_eq!(check_measurement(&m, 41, &a, None), Err(WireError::Session));
    assert_eq!(
        check_measurement(&MeasurementMsg { version: 1, ..m }, 42, &a, None),
        Err(WireError::Version(1))
    );
    assert_eq!(
        check_measurement(&MeasurementMsg { joint_count: 2, ..m }, 42, &a, None),
        Err(WireError::JointCount(2))
    );
    for changed in [
        MeasurementMsg { hold_periods: 3, ..m },
        MeasurementMsg { flags: 0, ..m },
        MeasurementMsg { dt: 2e-3, ..m },
        MeasurementMsg { period_ns: 2, ..m },
        MeasurementMsg { platform: 3, ..m },
        MeasurementMsg { scenario_hash: 1, ..m },
        MeasurementMsg { arm_hash: 1, ..m },
        MeasurementMsg { space: 2, ..m },
    ] {
        assert_eq!(check_measurement(&changed, 42, &a, None), Err(WireError::Changed));
    }
    // What may change: flags that are not announced, the delay, the values.
    let ok = MeasurementMsg { flags: m.flags | flags::STOPPED | flags::END_OF_RUN, delay: 1.0, seq: 8, ..m };
    assert_eq!(check_measurement(&ok, 42, &a, Some(7)), Ok(()));
}

#[test]
fn fnv1a_matches_reference_values() {
    assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
    assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
}

#[test]
#[allow(unsafe_code)]
fn type_names_are_the_derived_ones() {
    // SAFETY: `type_name` only returns the string given to the derive.
    let (m, c) =
        unsafe { (<MeasurementMsg as ZeroCopySend>::type_name(), <CommandMsg as ZeroCopySend>::type_name()) };
    assert_eq!((m, c), (MeasurementMsg::TYPE_NAME, CommandMsg::TYPE_NAME));
}
