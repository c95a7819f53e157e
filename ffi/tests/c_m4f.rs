//! The C ABI from C on an emulated Cortex-M4F: `m4f/main.c` (with its own start-up code and
//! no C library) compiled by `arm-none-eabi-gcc` for the Cortex-M4F (hard float) and linked
//! with the `thumbv7em-none-eabihf` `libcompanion_ffi.a` — what a C firmware does — then run
//! under QEMU's `mps2-an386` board (the board of `tests/firmware`).
//!
//! `c_on_m4f_reproduces_companion_sim_bit_for_bit`: this test runs `companion sim`'s loop
//! (`sim::run_loop`, its plant and in-process controller, trajectory 1, 1 ms) for each case,
//! records the 1 000 measurements and the reference commands, and hands the measurements to
//! the firmware as a data blob (the plant does not run on the board: `companion-plant` is a
//! std crate). The firmware steps the C controller over them and prints an FNV-1a digest of
//! its commands' bits per case — the digest `tests/c/host.c` prints — which must equal the
//! digest of `companion sim`'s commands: the same bits on the M4F as on the host.
//!
//! Needs `qemu-system-arm`, `arm-none-eabi-gcc` (Debian's `gcc-arm-none-eabi`) and the Rust
//! target; `scripts/setup` installs them. Missing tools fail the test: it is not skipped.

mod common;
use common::NoRows;

use std::convert::Infallible;
use std::fmt::Write as _;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::Result;
use companion_core::{Command as CoreCommand, Measurement, PaperRun, PlatformKind, Real};
use companion_plant::PaperTrajectory;
use companion_runtime::domain::controller::{measurement_in, Scalar, StepReport, JOINTS};
use companion_runtime::domain::observe::Silent;
use companion_runtime::domain::scenario::Scenario;
use companion_runtime::run::sim::{build_plant, run_loop, Exchange, InProcess, LoopEnd, Robot};
use companion_runtime::transport::link::LinkError;

const TARGET: &str = "thumbv7em-none-eabihf";
const STEPS: usize = 1000;

/// The cases on the board: the three platforms, run (a) and (c), `double` and `float`.
const CASES: [(PlatformKind, PaperRun, Scalar); 12] = {
    use PaperRun::{A, C};
    use PlatformKind::{Car, Omni, Unicycle};
    use Scalar::{F32, F64};
    [
        (Unicycle, A, F64),
        (Unicycle, A, F32),
        (Unicycle, C, F64),
        (Unicycle, C, F32),
        (Car, A, F64),
        (Car, A, F32),
        (Car, C, F64),
        (Car, C, F32),
        (Omni, A, F64),
        (Omni, A, F32),
        (Omni, C, F64),
        (Omni, C, F32),
    ]
};

/// `companion sim`'s controller on its loop, recording what it measured and answered.
struct Recorder {
    reference: InProcess,
    steps: Vec<(Measurement<f64, JOINTS>, StepReport)>,
}

impl Exchange for Recorder {
    type End = Infallible;

    fn exchange(
        &mut self,
        _n: u64,
        meas: &Measurement<f64, JOINTS>,
    ) -> Result<ControlFlow<Infallible, StepReport>, LinkError> {
        let report = self.reference.report(meas);
        self.steps.push((*meas, report));
        Ok(ControlFlow::Continue(report))
    }
}

/// FNV-1a over the bits of every command component (as `tests/c/host.c` and `m4f/main.c`).
fn digest(commands: &[CoreCommand<f64, JOINTS>]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for c in commands {
        let p = &c.platform;
        for x in [p.v, p.v_lat, p.omega, p.v_xi, c.joints[0], c.joints[1], c.joints[2]] {
            for b in x.to_bits().to_le_bytes() {
                h ^= u64::from(b);
                h = h.wrapping_mul(0x0100_0000_01b3);
            }
        }
    }
    h
}

/// The measurement as the firmware reads it: a `CompanionMeasurement` (14 scalars, native
/// little-endian layout, as on the board).
fn push_measurement<T: Real>(blob: &mut Vec<u8>, m: &Measurement<T, JOINTS>, bytes: impl Fn(T) -> Vec<u8>) {
    let b = &m.base;
    let d = &m.target;
    let v = &m.target_velocity;
    for x in [
        m.t,
        b.x,
        b.y,
        b.theta,
        m.steering,
        m.joints[0],
        m.joints[1],
        m.joints[2],
        d.x,
        d.y,
        d.theta,
        v[0],
        v[1],
        v[2],
    ] {
        blob.extend(bytes(x));
    }
}

/// Runs `companion sim`'s loop for one case: the measurements and the reference digest.
fn reference(platform: PlatformKind, run: PaperRun, scalar: Scalar) -> Result<(Vec<u8>, u64)> {
    let s = Scenario::builder(PaperTrajectory::One, run, platform).scalar(scalar).duration(0.999).build()?;
    let mut plant = build_plant(&s)?;
    let mut rec = Recorder { reference: InProcess::new(&s)?, steps: Vec::with_capacity(STEPS) };
    assert_eq!(
        run_loop(&s, &mut Robot::of(&mut plant, &s), &mut rec, &mut NoRows, &Silent)?,
        LoopEnd::Completed
    );
    assert_eq!(rec.steps.len(), STEPS);
    assert!(rec.steps.iter().all(|(_, r)| r.error.is_none()), "companion sim rejected a step");
    let mut blob = Vec::new();
    for (m, _) in &rec.steps {
        match scalar {
            Scalar::F64 => push_measurement(&mut blob, m, |x: f64| x.to_le_bytes().to_vec()),
            Scalar::F32 => {
                push_measurement(&mut blob, &measurement_in::<f32>(m), |x: f32| x.to_le_bytes().to_vec())
            }
        }
    }
    let commands: Vec<_> = rec.steps.iter().map(|(_, r)| r.command).collect();
    Ok((blob, digest(&commands)))
}

/// Runs a command that must succeed; its standard output and error (QEMU writes the
/// semihosting console, `SYS_WRITE0`, to its standard error).
fn run(cmd: &mut Command, what: &str) -> String {
    let out = cmd.output().unwrap_or_else(|e| panic!("{what}: cannot run it ({e}); run scripts/setup"));
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{what} failed ({:?}):\n{stdout}", out.status.code(),);
    stdout
}

/// `cargo build -p companion-ffi --target thumbv7em-none-eabihf` in this test's profile and
/// target directory; the staticlib's path.
fn firmware_staticlib() -> PathBuf {
    let exe = std::env::current_exe().expect("the test binary's path");
    let profile_dir = exe.parent().and_then(Path::parent).expect("target/<profile>/deps/<test>");
    let profile = profile_dir.file_name().and_then(|n| n.to_str()).expect("a profile directory").to_owned();
    let target_dir = profile_dir.parent().expect("the target directory");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let profile_arg = if profile == "debug" { "dev".to_owned() } else { profile.clone() };
    run(
        Command::new(cargo)
            .args(["build", "-p", "companion-ffi", "--lib", "--target", TARGET, "--profile", &profile_arg])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .env("CARGO_TARGET_DIR", target_dir)
            .env_remove("CARGO_BUILD_TARGET"),
        "cargo build -p companion-ffi --target thumbv7em-none-eabihf (is the target installed?)",
    );
    target_dir.join(TARGET).join(profile).join("libcompanion_ffi.a")
}

#[test]
fn c_on_m4f_reproduces_companion_sim_bit_for_bit() {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    let work = Path::new(env!("CARGO_TARGET_TMPDIR")).join("companion-ffi-m4f");
    std::fs::create_dir_all(&work).expect("a work directory");

    // The measurements of every case in one blob, each case 8-byte aligned.
    let mut blob = Vec::new();
    let mut table = String::from(
        "/* Generated by ffi/tests/c_m4f.rs. */\nstruct m4f_case { int single; uint32_t platform, run, offset, steps; };\nstatic const struct m4f_case M4F_CASES[] = {\n",
    );
    let mut expected = Vec::new();
    for (platform, run, scalar) in CASES {
        let (data, want) = reference(platform, run, scalar).expect("companion sim's loop runs");
        while blob.len() % 8 != 0 {
            blob.push(0);
        }
        let platform_code = match platform {
            PlatformKind::Unicycle => 0,
            PlatformKind::Car => 1,
            PlatformKind::Omni => 2,
        };
        let run_code = match run {
            PaperRun::A => 0,
            PaperRun::B => 1,
            PaperRun::C => 2,
            PaperRun::D => 3,
        };
        writeln!(
            table,
            "    {{{}, {platform_code}, {run_code}, {}, {STEPS}}}, /* {platform:?} {run:?} {} */",
            u8::from(scalar == Scalar::F32),
            blob.len(),
            scalar.name()
        )
        .expect("write to a String");
        blob.extend(data);
        expected.push((format!("{platform:?} run {run:?} {}", scalar.name()), want));
    }
    table.push_str("};\n");
    std::fs::write(work.join("m4f_cases.h"), table).expect("write m4f_cases.h");
    let bin = work.join("m4f_data.bin");
    std::fs::write(&bin, &blob).expect("write m4f_data.bin");
    let asm = format!(
        "    .section .rodata.m4f_data, \"a\"\n    .balign 8\n    .global m4f_data\nm4f_data:\n    .incbin \"{}\"\n",
        bin.display()
    );
    std::fs::write(work.join("data.S"), asm).expect("write data.S");

    let lib = firmware_staticlib();
    let elf = work.join("companion-ffi-m4f.elf");
    let m4f = here.join("m4f");
    run(
        Command::new("arm-none-eabi-gcc")
            .args(["-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16"])
            .args(["-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-ffreestanding", "-nostdlib"])
            .arg("-I")
            .arg(here.join("include"))
            .arg("-I")
            .arg(&m4f)
            .arg("-I")
            .arg(&work)
            .arg("-T")
            .arg(m4f.join("m4f.ld"))
            .args([m4f.join("startup.c"), m4f.join("main.c"), work.join("data.S")])
            .arg(&lib)
            .args(["-lgcc", "-Wl,--gc-sections", "-o"])
            .arg(&elf),
        "arm-none-eabi-gcc (Debian's gcc-arm-none-eabi)",
    );
    let stdout = run(
        Command::new("timeout")
            .arg("300")
            .args(["qemu-system-arm", "-cpu", "cortex-m4", "-machine", "mps2-an386", "-nographic"])
            .args(["-semihosting-config", "enable=on,target=native", "-kernel"])
            .arg(&elf),
        "qemu-system-arm running the C firmware (124: timed out; 1: a step was rejected; 101: a fault)",
    );
    let lines: Vec<&str> = stdout.lines().filter(|l| l.starts_with("case ")).collect();
    assert_eq!(lines.len(), CASES.len(), "the firmware printed:\n{stdout}");
    for (i, ((name, want), line)) in expected.iter().zip(&lines).enumerate() {
        let want_line = format!("case {i} steps {STEPS} rejected 0 digest {want:016x}");
        assert_eq!(
            *line, want_line,
            "{name}: the C commands on the emulated M4F differ from companion sim's"
        );
        eprintln!("{name}: M4F digest {want:016x} = companion sim's");
    }
    eprintln!(
        "c_m4f: {} cases × {STEPS} commands from C on the emulated Cortex-M4F equal companion sim's",
        CASES.len()
    );
}
