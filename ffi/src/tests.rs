//! Unit tests (with `std`): the storage fits, the presets are `companion sim`'s, the status
//! table is complete and matches the header, and the C functions answer bad calls with
//! statuses. The C programs in `tests/c/` check the same through the C ABI.

use core::alloc::{GlobalAlloc, Layout};
use core::cell::Cell;
use core::ffi::CStr;
use std::alloc::System;
use std::string::String;
use std::vec::Vec;

use companion_core::{Bound, Field, PaperRun, ParamError, PlatformKind, Rpr, Rule, StepError};
use companion_plant::PaperTrajectory;
use companion_runtime::domain::controller::Scalar as RuntimeScalar;
use companion_runtime::domain::scenario::Scenario;

use super::*;

const PLATFORMS: [PlatformKind; 3] = [PlatformKind::Unicycle, PlatformKind::Car, PlatformKind::Omni];
const RUNS: [PaperRun; 4] = [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D];

#[test]
fn storage_holds_every_variant_without_much_waste() {
    let slot = size_of::<Slot>();
    std::eprintln!("Slot: {slot} bytes, storage {COMPANION_CONTROLLER_SIZE}");
    assert!(slot <= COMPANION_CONTROLLER_SIZE);
    // The size is one number for every target; keep it within 1 kB of the host's need (a
    // 32-bit target needs no more: the controller holds floats and a few bytes of flags).
    assert!(COMPANION_CONTROLLER_SIZE - slot < 1024, "COMPANION_CONTROLLER_SIZE can shrink");
}

fn presets_match<T: Real + core::fmt::Debug>(scalar: RuntimeScalar) {
    for platform in PLATFORMS {
        for run in RUNS {
            let c =
                CompanionParams::<T>::paper(platform, run).to_core().expect("the preset's enums are valid");
            // What `companion sim --platform P --run R --scalar S` builds.
            let scenario = Scenario::builder(PaperTrajectory::One, run, platform).scalar(scalar).build();
            let spec = scenario.expect("the paper's scenarios are valid").controller;
            assert_eq!(c.platform, platform);
            assert_eq!(c.params, spec.params::<T>(), "{platform:?} {run:?} {scalar:?}: params");
            assert_eq!(c.unicycle, spec.unicycle::<T>(), "{platform:?} {run:?}: Lemma 1's function");
            assert_eq!(c.car, spec.car::<T>(), "{platform:?} {run:?}: Lemma 2's function");
            assert_eq!(c.arm, Rpr::<T>::paper());
            assert_eq!([c.initial_alpha[0].as_f64(), c.initial_alpha[1].as_f64()], spec.initial_alpha);
        }
    }
}

#[test]
fn the_paper_preset_is_companion_sims_controller() {
    presets_match::<f64>(RuntimeScalar::F64);
    presets_match::<f32>(RuntimeScalar::F32);
}

#[test]
fn every_status_has_its_own_number_and_the_headers_name() {
    let header = include_str!("../include/companion.h");
    let mut codes: Vec<i32> = ALL_STATUSES.iter().map(|s| *s as i32).collect();
    codes.sort_unstable();
    codes.dedup();
    assert_eq!(codes.len(), ALL_STATUSES.len(), "two statuses share a number");
    for s in ALL_STATUSES {
        let name = s.name().to_str().expect("ASCII");
        assert!(header.contains(&std::format!("  {name} = {},\n", s as i32)), "{name} not in the header");
        // SAFETY: `companion_status_name` returns a static NUL-terminated string.
        let back = unsafe { CStr::from_ptr(companion_status_name(s as i32)) };
        assert_eq!(back.to_str().expect("ASCII"), name);
        assert_eq!(CompanionStatus::from_code(s as i32), Some(s));
    }
    let enumerators = header.lines().filter(|l| l.trim_start().starts_with("COMPANION_STATUS_")).count();
    assert_eq!(enumerators, ALL_STATUSES.len(), "the table ALL misses a status of the header");
    for unknown in [-1, 6, 99, 120, 199, 223, 1000, i32::MIN] {
        // SAFETY: as above.
        let name = unsafe { CStr::from_ptr(companion_status_name(unknown)) };
        assert_eq!(name.to_str().expect("ASCII"), "COMPANION_STATUS_UNKNOWN");
    }
}

#[test]
fn every_core_error_has_a_distinct_status() {
    let rules = [
        Rule::NonFinite,
        Rule::NotPositive,
        Rule::Negative,
        Rule::NotInUnitInterval,
        Rule::EmptyInterval,
        Rule::PenaltyMarginTooWide,
        Rule::WeightMarginOrder,
        Rule::Transversality,
        Rule::Decomposition51NeedsPsiOne,
        Rule::Geometry,
        Rule::TooLarge(Bound::Length),
        Rule::TooLarge(Bound::TransverseSize),
        Rule::TooLarge(Bound::Magnitude),
        Rule::TooLarge(Bound::Time),
        Rule::NotOrthonormal,
        Rule::NotUnitVector,
        Rule::TooFewJoints,
        Rule::HomeOutsideLimits,
        Rule::NotPlanar,
        Rule::PeriodTooLong,
    ];
    let fields = [
        Field::Time,
        Field::BasePose,
        Field::Steering,
        Field::Joints,
        Field::TargetPose,
        Field::TargetVelocity,
    ];
    let mut steps: Vec<StepError> = fields.into_iter().map(StepError::NonFinite).collect();
    steps.extend([
        StepError::BadTimeStep,
        StepError::BadDelay,
        StepError::JointAtLimit(0),
        StepError::JointAtLimit(1),
        StepError::JointAtLimit(2),
        StepError::SingularArm,
        StepError::SingularTaskJacobian,
        StepError::TargetYawUndefined,
        StepError::NumericalFailure,
    ]);
    let mut codes: Vec<i32> =
        rules.iter().map(|r| CompanionStatus::from_param(&ParamError::new("x", *r)) as i32).collect();
    assert!(codes.iter().all(|c| (100..200).contains(c)));
    let step_codes: Vec<i32> = steps.iter().map(|e| CompanionStatus::from_step(*e) as i32).collect();
    assert!(step_codes.iter().all(|c| (200..300).contains(c)));
    codes.extend(step_codes);
    let n = codes.len();
    codes.sort_unstable();
    codes.dedup();
    assert_eq!(codes.len(), n, "two core errors share a status");
    // With the call errors and OK, that is every status.
    assert_eq!(n + 6, ALL_STATUSES.len());
}

fn measurement() -> CompanionMeasurementF64 {
    CompanionMeasurement {
        t: 0.0,
        base: CompanionPose { x: 0.0, y: 0.0, theta: 0.0 },
        steering: 0.0,
        joints: [0.0, 0.35, 0.0],
        target: CompanionPose { x: 2.6, y: 1.0, theta: 0.0 },
        target_velocity: [0.0, -0.157, 0.0],
    }
}

fn storage() -> std::boxed::Box<CompanionController> {
    std::boxed::Box::new(CompanionController { _opaque: [0; COMPANION_CONTROLLER_WORDS] })
}

fn error_param(e: &CompanionParamError) -> String {
    // SAFETY: `param` is NUL-terminated (at most 47 bytes are copied into 48).
    unsafe { CStr::from_ptr(e.param.as_ptr()) }.to_str().expect("ASCII").into()
}

#[test]
fn the_c_functions_step_like_the_core() {
    let mut ctrl = storage();
    let mut err = CompanionParamError { status: 99, joint: 9, param: [1; 48] };
    let s = companion_f64_init_paper(
        &mut *ctrl,
        CompanionPlatform::Unicycle as u32,
        CompanionRun::A as u32,
        &mut err,
    );
    assert_eq!(s, CompanionStatus::Ok);
    assert_eq!((err.status, err.joint, error_param(&err).as_str()), (0, -1, ""));
    let mut reference = companion_core::Controller::new(
        companion_core::Params::<f64, 3>::paper(PaperRun::A),
        companion_core::Unicycle::paper(),
        Rpr::paper(),
    )
    .expect("the paper's parameters are valid");
    let mut m = measurement();
    for k in 0..50 {
        m.t = f64::from(k) * 1e-3;
        m.joints[0] = 0.001 * f64::from(k);
        let mut out = CompanionCommand::default();
        assert_eq!(companion_f64_step(&mut *ctrl, 1e-3, 0.0, &m, &mut out), CompanionStatus::Ok);
        let expect = reference.step(&m.to_core(), 1e-3).expect("accepted");
        assert_eq!(out, CompanionCommand::from_core(&expect.command));
    }
}

#[test]
fn bad_calls_are_statuses_with_the_safe_command() {
    let mut ctrl = storage();
    let m = measurement();
    let garbage = CompanionCommand { v: 42.0, v_lat: 42.0, omega: 42.0, v_xi: 42.0, joints: [42.0; 3] };
    let zero = CompanionCommand::default();
    // Not initialised.
    let mut out = garbage;
    assert_eq!(companion_f64_step(&mut *ctrl, 1e-3, 0.0, &m, &mut out), CompanionStatus::NotInitialised);
    assert_eq!(out, zero);
    // NULL pointers.
    out = garbage;
    assert_eq!(companion_f64_step(ptr::null_mut(), 1e-3, 0.0, &m, &mut out), CompanionStatus::NullPointer);
    assert_eq!(out, zero);
    assert_eq!(companion_f64_step(&mut *ctrl, 1e-3, 0.0, &m, ptr::null_mut()), CompanionStatus::NullPointer);
    assert_eq!(companion_f64_init(&mut *ctrl, ptr::null(), ptr::null_mut()), CompanionStatus::NullPointer);
    assert_eq!(companion_f64_params_paper(0, 0, ptr::null_mut()), CompanionStatus::NullPointer);
    // Out-of-range enums.
    let mut p = CompanionParamsF64::default();
    assert_eq!(companion_f64_params_paper(3, 0, &mut p), CompanionStatus::BadEnum);
    assert_eq!(companion_f64_params_paper(0, 4, &mut p), CompanionStatus::BadEnum);
    let mut err = CompanionParamError { status: 0, joint: 0, param: [0; 48] };
    assert_eq!(companion_f32_init_paper(&mut *ctrl, 0, 9, &mut err), CompanionStatus::BadEnum);
    assert_eq!(error_param(&err), "run");
    // Misaligned storage.
    let mut words = [0u64; COMPANION_CONTROLLER_WORDS + 1];
    let odd = words.as_mut_ptr().cast::<u8>().wrapping_add(4).cast::<CompanionController>();
    assert_eq!(companion_f64_init_paper(odd, 0, 0, ptr::null_mut()), CompanionStatus::Misaligned);
    // The other scalar type.
    assert_eq!(companion_f64_init_paper(&mut *ctrl, 0, 0, ptr::null_mut()), CompanionStatus::Ok);
    let m32 = CompanionMeasurementF32 {
        t: 0.0,
        base: CompanionPose::default(),
        steering: 0.0,
        joints: [0.0, 0.35, 0.0],
        target: CompanionPose { x: 2.6, y: 1.0, theta: 0.0 },
        target_velocity: [0.0, -0.157, 0.0],
    };
    let mut out32 = CompanionCommand { v: 1.0f32, ..CompanionCommand::default() };
    assert_eq!(companion_f32_step(&mut *ctrl, 1e-3, 0.0, &m32, &mut out32), CompanionStatus::WrongScalar);
    assert_eq!(out32, CompanionCommand::default());
    // A failed init leaves the storage not initialised.
    companion_f64_params_paper(0, 0, &mut p);
    p.gain[2] = 0.0;
    assert_eq!(companion_f64_init(&mut *ctrl, &p, &mut err), CompanionStatus::ParamNotPositive);
    assert_eq!((error_param(&err).as_str(), err.joint, err.status), ("gain", 2, 101));
    assert_eq!(companion_f64_step(&mut *ctrl, 1e-3, 0.0, &m, &mut out), CompanionStatus::NotInitialised);
    p.gain[2] = 3.0;
    p.discretisation = 2;
    assert_eq!(companion_f64_init(&mut *ctrl, &p, &mut err), CompanionStatus::BadEnum);
    assert_eq!(error_param(&err), "discretisation");
    // Rejected steps: the core's reason, the zero command.
    p.discretisation = CompanionDiscretisation::Midpoint as u32;
    assert_eq!(companion_f64_init(&mut *ctrl, &p, ptr::null_mut()), CompanionStatus::Ok);
    /// A change of the measurement, the period, the delay and the status it must give.
    type Case = (fn(&mut CompanionMeasurementF64), f64, f64, CompanionStatus);
    let cases: [Case; 6] = [
        (|m| m.joints[1] = 0.0, 1e-3, 0.0, CompanionStatus::StepJointAtLimitQ2),
        (|m| m.joints[0] = 10.0, 1e-3, 0.0, CompanionStatus::StepJointAtLimitQ1),
        (|m| m.base.x = f64::NAN, 1e-3, 0.0, CompanionStatus::StepNonFiniteBasePose),
        (|m| m.target_velocity[2] = f64::INFINITY, 1e-3, 0.0, CompanionStatus::StepNonFiniteTargetVelocity),
        (|_| {}, f64::NAN, 0.0, CompanionStatus::StepBadTimeStep),
        (|_| {}, 1e-3, -1.0, CompanionStatus::StepBadDelay),
    ];
    for (change, period, delay, status) in cases {
        let mut bad = m;
        change(&mut bad);
        out = garbage;
        assert_eq!(companion_f64_step(&mut *ctrl, period, delay, &bad, &mut out), status);
        assert_eq!(out, zero, "{status:?}");
    }
}

/// Counts the allocations of the current thread (the tests run in parallel threads).
struct Counting;

std::thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

// SAFETY: forwards to the system allocator; the count is a thread-local `Cell` without a
// destructor (`try_with` never panics).
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        // SAFETY: the caller's contract of `GlobalAlloc::alloc`, passed on.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract of `GlobalAlloc::dealloc`, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

#[test]
fn init_and_step_never_allocate() {
    let mut ctrl = storage();
    let mut params = CompanionParamsF32::default();
    let before = ALLOCATIONS.with(Cell::get);
    let mut accepted = 0;
    for platform in 0..3 {
        for run in 0..4 {
            let m = measurement();
            assert_eq!(
                companion_f64_init_paper(&mut *ctrl, platform, run, ptr::null_mut()),
                CompanionStatus::Ok
            );
            for k in 0..200 {
                let mut m = m;
                m.t = f64::from(k) * 1e-3;
                m.target.x -= 1e-4 * f64::from(k);
                let mut out = CompanionCommand::default();
                accepted += usize::from(
                    companion_f64_step(&mut *ctrl, 1e-3, 0.0, &m, &mut out) == CompanionStatus::Ok,
                );
            }
            assert_eq!(companion_f32_params_paper(platform, run, &mut params), CompanionStatus::Ok);
            assert_eq!(companion_f32_init(&mut *ctrl, &params, ptr::null_mut()), CompanionStatus::Ok);
            let m32 = CompanionMeasurementF32 {
                t: 0.0,
                base: CompanionPose::default(),
                steering: 0.0,
                joints: [0.0, 0.35, 0.0],
                target: CompanionPose { x: 2.6, y: 1.0, theta: 0.0 },
                target_velocity: [0.0, -0.157, 0.0],
            };
            for k in 0..200u16 {
                let mut m = m32;
                m.t = f32::from(k) * 1e-3;
                let mut out = CompanionCommand::default();
                accepted += usize::from(
                    companion_f32_step(&mut *ctrl, 1e-3, 0.0, &m, &mut out) == CompanionStatus::Ok,
                );
            }
            // A rejected step does not allocate either.
            let mut bad = m32;
            bad.joints[1] = -1.0;
            let mut out = CompanionCommand::default();
            assert_eq!(
                companion_f32_step(&mut *ctrl, 1e-3, 0.0, &bad, &mut out),
                CompanionStatus::StepJointAtLimitQ2
            );
        }
    }
    assert_eq!(ALLOCATIONS.with(Cell::get) - before, 0, "the C functions allocated");
    assert_eq!(accepted, 12 * 400, "every step was accepted");
}
