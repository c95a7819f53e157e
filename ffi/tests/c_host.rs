//! The C ABI from C on the host: `tests/c/*.c` compiled by the system `cc` against
//! `include/companion.h` and linked with `libcompanion_ffi.a`.
//!
//! `c_reproduces_companion_sim_bit_for_bit` runs `companion sim`'s own loop
//! (`companion_runtime::run::sim::run_loop` with its plant, `build_plant`, on the paper's
//! trajectory 1, 1 ms) with the C program as the controller that closes it, and `companion
//! sim`'s in-process controller (`sim::InProcess`, what `run_one` steps) beside it on the
//! same measurements: the first 1 000 commands (steps 0 to 999) must have the same bits, for
//! the three platforms × runs (a)–(d) × `double` and `float`.
//!
//! `c_commands_are_those_in_companion_sims_timeseries` checks the same against what
//! `companion sim` writes (`sim::run_one`'s `timeseries.csv`, every step logged, unicycle
//! run (a), `double` and `float`): its `v` and `omega` columns are the C commands' bits.
//!
//! `c_bad_input_gives_named_statuses` runs `tests/c/errors.c`: one check per class of status.
//!
//! The staticlib is built by `cargo build -p companion-ffi` in this test's own profile and
//! target directory (`cargo test` builds the crate's staticlib too, but leaves it under a
//! hashed name in `deps/`, with the features of the test build).

mod common;
use common::NoRows;

use std::convert::Infallible;
use std::io::{Read, Write};
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::sync::OnceLock;

use anyhow::{bail, Context, Result};
use companion_core::nalgebra::SVector;
use companion_core::{Command as CoreCommand, Measurement, PaperRun, PlatformCommand, PlatformKind, Real};
use companion_plant::PaperTrajectory;
use companion_runtime::domain::controller::{measurement_in, Scalar, StepReport, JOINTS};
use companion_runtime::domain::observe::Silent;
use companion_runtime::domain::scenario::Scenario;
use companion_runtime::run::sim::{build_plant, run_loop, Exchange, InProcess, LoopEnd, Robot};
use companion_runtime::transport::link::LinkError;

/// Commands compared per case: steps 0..=999.
const COMMANDS: usize = 1000;

/// `target/<profile>` of this test binary (`target/<profile>/deps/c_host-…`).
fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("the test binary's path");
    exe.parent().and_then(Path::parent).expect("target/<profile>/deps/<test>").to_path_buf()
}

/// Builds `libcompanion_ffi.a` for the host in this test's profile; returns its path.
fn staticlib() -> &'static Path {
    static LIB: OnceLock<PathBuf> = OnceLock::new();
    LIB.get_or_init(|| {
        let dir = profile_dir();
        let profile = dir.file_name().and_then(|n| n.to_str()).expect("a profile directory").to_owned();
        let target_dir = dir.parent().expect("the target directory").to_path_buf();
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        // `debug` is the directory of the `dev` profile.
        let profile_arg = if profile == "debug" { "dev".to_owned() } else { profile };
        let out = Command::new(cargo)
            .args(["build", "-p", "companion-ffi", "--lib", "--profile", &profile_arg])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .env("CARGO_TARGET_DIR", &target_dir)
            .env_remove("CARGO_BUILD_TARGET")
            .output()
            .expect("cargo runs");
        assert!(
            out.status.success(),
            "cargo build -p companion-ffi failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let lib = dir.join("libcompanion_ffi.a");
        assert!(lib.is_file(), "{} was not built", lib.display());
        lib
    })
}

/// Compiles `tests/c/<name>.c` with the system C compiler and links the staticlib.
fn compile(name: &str) -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    let exe = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("companion-ffi-{name}"));
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let out = Command::new(&cc)
        .args(["-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic", "-I"])
        .arg(here.join("include"))
        .arg(here.join("tests").join("c").join(format!("{name}.c")))
        .arg(staticlib())
        // What a Rust staticlib for a hosted target needs (`--print native-static-libs`).
        .args(["-lpthread", "-ldl", "-lm", "-o"])
        .arg(&exe)
        .output()
        .unwrap_or_else(|e| panic!("{cc} runs (a C compiler is needed for this test): {e}"));
    assert!(
        out.status.success(),
        "compiling tests/c/{name}.c failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    exe
}

fn host_program() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| compile("host"))
}

/// The C program as a controller: one measurement in, status and command out.
struct CController {
    child: Child,
    stdin: Option<ChildStdin>,
    stdout: ChildStdout,
    single: bool,
}

impl CController {
    fn spawn(platform: PlatformKind, run: PaperRun, scalar: Scalar, dt: f64) -> Result<Self> {
        let platform = match platform {
            PlatformKind::Unicycle => 0,
            PlatformKind::Car => 1,
            PlatformKind::Omni => 2,
        };
        let run = match run {
            PaperRun::A => 0,
            PaperRun::B => 1,
            PaperRun::C => 2,
            PaperRun::D => 3,
        };
        let mut child = Command::new(host_program())
            .args([scalar.name().to_owned(), format!("{platform}"), format!("{run}"), format!("{dt:e}")])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .context("the C program starts")?;
        let stdin = child.stdin.take();
        let stdout = child.stdout.take().context("its stdout")?;
        Ok(Self { child, stdin, stdout, single: scalar == Scalar::F32 })
    }

    /// One step: the status and the command (widened to `f64`, exactly, for `float`).
    fn step(&mut self, m: &Measurement<f64, JOINTS>) -> Result<(i32, CoreCommand<f64, JOINTS>)> {
        let stdin = self.stdin.as_mut().context("stdin open")?;
        let mut bytes = Vec::with_capacity(14 * 8);
        if self.single {
            let m = measurement_in::<f32>(m);
            for x in measurement_fields(&m) {
                bytes.extend_from_slice(&x.to_ne_bytes());
            }
        } else {
            for x in measurement_fields(m) {
                bytes.extend_from_slice(&x.to_ne_bytes());
            }
        }
        stdin.write_all(&bytes)?;
        stdin.flush()?;
        let mut status = [0u8; 4];
        self.stdout.read_exact(&mut status).context("the C program answers")?;
        let mut values = [0f64; 7];
        if self.single {
            let mut buf = [0u8; 7 * 4];
            self.stdout.read_exact(&mut buf)?;
            for (v, b) in values.iter_mut().zip(buf.chunks_exact(4)) {
                *v = f64::from(f32::from_ne_bytes(b.try_into()?));
            }
        } else {
            let mut buf = [0u8; 7 * 8];
            self.stdout.read_exact(&mut buf)?;
            for (v, b) in values.iter_mut().zip(buf.chunks_exact(8)) {
                *v = f64::from_ne_bytes(b.try_into()?);
            }
        }
        let command = CoreCommand {
            platform: PlatformCommand { v: values[0], v_lat: values[1], omega: values[2], v_xi: values[3] },
            joints: SVector::<f64, JOINTS>::new(values[4], values[5], values[6]),
        };
        Ok((i32::from_ne_bytes(status), command))
    }

    /// Closes its input and returns its closing line (`steps N digest HEX`).
    fn finish(mut self) -> Result<String> {
        drop(self.stdin.take());
        let out = self.child.wait_with_output()?;
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        if !out.status.success() {
            bail!("the C program exited with {:?}: {stderr}", out.status.code());
        }
        Ok(stderr.trim().to_owned())
    }
}

/// The fields of a `CompanionMeasurement` in declaration order.
fn measurement_fields<T: Real>(m: &Measurement<T, JOINTS>) -> [T; 14] {
    [
        m.t,
        m.base.x,
        m.base.y,
        m.base.theta,
        m.steering,
        m.joints[0],
        m.joints[1],
        m.joints[2],
        m.target.x,
        m.target.y,
        m.target.theta,
        m.target_velocity[0],
        m.target_velocity[1],
        m.target_velocity[2],
    ]
}

/// One step of both controllers.
#[derive(Debug)]
struct Pair {
    reference: StepReport,
    c_status: i32,
    c_command: CoreCommand<f64, JOINTS>,
}

/// `companion sim`'s controller and the C one on the same measurements; the C command
/// drives the plant.
struct Twin {
    reference: InProcess,
    c: CController,
    steps: Vec<Pair>,
}

impl Exchange for Twin {
    type End = Infallible;

    fn exchange(
        &mut self,
        _n: u64,
        meas: &Measurement<f64, JOINTS>,
    ) -> Result<ControlFlow<Infallible, StepReport>, LinkError> {
        let reference = self.reference.report(meas);
        // The C controller answers over a pipe: its failures are the link's.
        let (c_status, c_command) = self
            .c
            .step(meas)
            .map_err(|e| LinkError::Receive { step: "the C controller's pipe", cause: format!("{e:#}") })?;
        self.steps.push(Pair { reference, c_status, c_command });
        Ok(ControlFlow::Continue(StepReport { command: c_command, ..reference }))
    }
}

fn bits(c: &CoreCommand<f64, JOINTS>) -> [u64; 7] {
    let p = &c.platform;
    [p.v, p.v_lat, p.omega, p.v_xi, c.joints[0], c.joints[1], c.joints[2]].map(f64::to_bits)
}

/// Runs one case; returns the C program's closing line and its commands.
fn run_case(
    platform: PlatformKind,
    run: PaperRun,
    scalar: Scalar,
) -> Result<(String, Vec<CoreCommand<f64, JOINTS>>)> {
    let name = format!("{platform:?} run {run:?} {}", scalar.name());
    // `companion sim --platform P --run R --scalar S --duration 0.999`: steps 0..=999.
    let s = Scenario::builder(PaperTrajectory::One, run, platform).scalar(scalar).duration(0.999).build()?;
    assert_eq!(s.steps() + 1, COMMANDS as u64);
    assert_eq!((s.dt, s.delay), (1e-3, 0.0));
    let mut plant = build_plant(&s)?;
    let reference = InProcess::new(&s)?;
    let c = CController::spawn(platform, run, scalar, s.dt)?;
    let mut twin = Twin { reference, c, steps: Vec::with_capacity(COMMANDS) };
    let end = run_loop(&s, &mut Robot::of(&mut plant, &s), &mut twin, &mut NoRows, &Silent)?;
    assert_eq!(end, LoopEnd::Completed);
    let Twin { c, steps, .. } = twin;
    let closing = c.finish()?;
    assert_eq!(steps.len(), COMMANDS, "{name}: steps run");
    for (n, p) in steps.iter().enumerate() {
        assert_eq!(p.reference.error, None, "{name}, step {n}: companion sim rejected it");
        assert_eq!(p.c_status, 0, "{name}, step {n}: the C program's step returned status {}", p.c_status);
        assert_eq!(
            bits(&p.c_command),
            bits(&p.reference.command),
            "{name}, step {n}: the C command differs from companion sim's\n  C:    {:?}\n  sim:  {:?}",
            p.c_command,
            p.reference.command
        );
    }
    let moving = steps.iter().filter(|p| p.c_command.platform.v != 0.0).count();
    assert!(moving > COMMANDS / 2, "{name}: the platform hardly moved ({moving} steps)");
    assert!(closing.starts_with(&format!("steps {COMMANDS} digest ")), "{name}: closing line {closing:?}");
    Ok((closing, steps.iter().map(|p| p.c_command).collect()))
}

#[test]
fn c_reproduces_companion_sim_bit_for_bit() {
    let mut digests = Vec::new();
    for platform in [PlatformKind::Unicycle, PlatformKind::Car, PlatformKind::Omni] {
        for run in [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D] {
            for scalar in [Scalar::F64, Scalar::F32] {
                let (closing, _) = run_case(platform, run, scalar)
                    .unwrap_or_else(|e| panic!("{platform:?} run {run:?} {}: {e:#}", scalar.name()));
                eprintln!("{platform:?} run {run:?} {}: {closing}", scalar.name());
                digests.push(closing);
            }
        }
    }
    // Different scenarios give different command streams (the comparison is not vacuous).
    let mut unique = digests.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), digests.len(), "two cases gave the same commands");
    eprintln!(
        "c_host: {} cases × {COMMANDS} commands from C equal companion sim's bit for bit",
        digests.len()
    );
}

/// What `companion sim` itself writes, not only its code path: `sim::run_one` (the command's
/// function) with every step logged writes `timeseries.csv`, whose `v` and `omega` columns
/// (shortest round-trip formatting) must parse to the C program's commands' bits.
#[test]
fn c_commands_are_those_in_companion_sims_timeseries() {
    for scalar in [Scalar::F64, Scalar::F32] {
        let (_, c_commands) = run_case(PlatformKind::Unicycle, PaperRun::A, scalar).expect("the C loop runs");
        let s = Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle)
            .scalar(scalar)
            .duration(0.999)
            .log_every(1)
            .build()
            .expect("a valid scenario");
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("companion-ffi-sim-{}", scalar.name()));
        std::fs::create_dir_all(&dir).expect("an output directory");
        companion_runtime::run::sim::run_one(&s, &dir, &Silent).expect("companion sim runs");
        let csv = std::fs::read_to_string(dir.join("timeseries.csv")).expect("timeseries.csv");
        let mut lines = csv.lines();
        let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
        let col = |name: &str| header.iter().position(|h| *h == name).expect("the column exists");
        let (v, omega, status) = (col("v"), col("omega"), col("status"));
        let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
        assert_eq!(rows.len(), COMMANDS, "{}: rows of timeseries.csv", scalar.name());
        for (n, (row, c)) in rows.iter().zip(&c_commands).enumerate() {
            let parse = |i: usize| row[i].parse::<f64>().expect("a number");
            assert_eq!(row[status], "ok", "{}, step {n}", scalar.name());
            assert_eq!(
                (parse(v).to_bits(), parse(omega).to_bits()),
                (c.platform.v.to_bits(), c.platform.omega.to_bits()),
                "{}, step {n}: timeseries.csv's (v, omega) differ from the C command",
                scalar.name()
            );
        }
    }
}

#[test]
fn c_bad_input_gives_named_statuses() {
    let exe = compile("errors");
    let out = Command::new(&exe).output().expect("the C program runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let failures: Vec<&str> = stdout.lines().filter(|l| l.starts_with("FAIL")).collect();
    assert!(failures.is_empty(), "C checks failed:\n{}", failures.join("\n"));
    assert!(out.status.success(), "errors.c exited with {:?}:\n{stdout}", out.status.code());
    let passed = stdout.lines().filter(|l| l.starts_with("ok ")).count();
    // Every check of errors.c ran (update this when adding checks there); the closing line
    // agrees.
    const CHECKS: usize = 85;
    assert_eq!(passed, CHECKS, "not every check ran:\n{stdout}");
    assert!(stdout.contains(&format!("{passed} passed, 0 failed")), "{stdout}");
}
