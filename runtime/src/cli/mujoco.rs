//! `companion hil --plant mujoco`: the demo's plant is the MuJoCo plant
//! (`bridges/mujoco/companion_mujoco.py`, a physical robot behind the same wire), started in
//! `target/py`'s Python (`scripts/setup` installs MuJoCo there). This module turns the demo's
//! flags into that program's; what the MuJoCo plant cannot do is refused here by name, before
//! anything starts: the demo's flags it does not take, a `--plant-arg` that repeats a flag the
//! demo gives the plant itself, and — by the plant's own check (`companion_mujoco.py --check`:
//! its flags parsed, its actuator table read, the robot built by MuJoCo, nothing written) —
//! every flag and file the plant would refuse, with its reason. A `--plant-arg=--help` prints
//! the plant's flags and starts no run (exit 2: it is not a run).

use std::path::{Path, PathBuf};
use std::process::{Command as Process, Stdio};

use anyhow::{bail, Result};
use clap::ValueEnum;
use companion_core::PlatformKind;
use companion_runtime::run::hil::{HilConfig, HilScenario};

use super::args::ScenarioArgs;

/// `--plant`: which plant `companion hil` starts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub enum PlantArg {
    /// `companion plant`: the robot's kinematics, integrated exactly.
    #[default]
    Kinematic,
    /// The MuJoCo plant: the robot's URDF with wheels, drives, servos and gravity
    /// (bridges/mujoco; `scripts/setup` installs MuJoCo into target/py).
    Mujoco,
}

/// What of `companion hil`'s flags the MuJoCo plant's command is made of (the demo's own
/// `HilArgs`, seen from here without depending on them).
pub struct DemoFlags<'a> {
    /// `--arm`.
    pub arm: &'a str,
    /// The scenario's flags.
    pub scenario: &'a ScenarioArgs,
    /// `--plant-arg`s.
    pub plant_args: &'a [String],
    /// The flags given that the MuJoCo plant does not take, by name.
    pub unsupported: Vec<&'static str>,
}

/// The workspace this binary was built from (the MuJoCo plant's script lives there).
fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The Python that runs the MuJoCo plant: `$COMPANION_PYTHON`, else the workspace's
/// `target/py` (scripts/setup makes it).
fn python() -> Result<PathBuf> {
    if let Some(p) = std::env::var_os("COMPANION_PYTHON") {
        let p = PathBuf::from(p);
        if !p.is_file() {
            bail!(
                "COMPANION_PYTHON={}: no such file: set it to a Python with mujoco, example-robot-data and iceoryx2, \
                 or unset it to use target/py (scripts/setup makes it)",
                p.display()
            );
        }
        return Ok(p);
    }
    let p = workspace().join("target/py/bin/python");
    if !p.exists() {
        bail!(
            "--plant mujoco runs in {}, which does not exist: run scripts/setup (it installs MuJoCo there), or set \
             COMPANION_PYTHON to a Python with mujoco, example-robot-data and iceoryx2",
            p.display()
        );
    }
    Ok(p)
}

/// A URDF arm's cut, home and mount as the MuJoCo plant takes them: the links (flags over the
/// config file's `[robot]`, the root by default), the home the controller resolved (any of
/// `--home`, `--srdf`/`--home-state`, names), the mount (`[robot] mount`).
fn urdf_flags(a: &DemoFlags<'_>, s: &HilScenario) -> Result<Vec<String>> {
    let robot = a.scenario.config_file()?.robot.unwrap_or_default();
    let flags = &a.scenario.robot;
    let mut out = Vec::new();
    if let Some(b) = flags.base_link.clone().or(robot.base_link) {
        out.extend(["--base-link".to_string(), b]);
    }
    if let Some(t) = flags.tip_link.clone().or(robot.tip_link) {
        out.extend(["--tip-link".to_string(), t]);
    }
    let Some(ss) = s.spatial() else { bail!("--plant mujoco: a URDF arm is spatial") };
    let home: Vec<f64> = match ss.arm.joints() {
        6 => ss.arm.chain::<f64, 6>()?.home().iter().copied().collect(),
        7 => ss.arm.chain::<f64, 7>()?.home().iter().copied().collect(),
        _ => ss.arm.chain::<f64, 8>()?.home().iter().copied().collect(),
    };
    out.extend(["--home".to_string(), home.iter().map(f64::to_string).collect::<Vec<_>>().join(",")]);
    if let Some(m) = robot.mount {
        let xyz = m.xyz.unwrap_or_else(|| vec![0.0; 3]);
        let rpy = m.rpy.unwrap_or_else(|| vec![0.0; 3]);
        let all: Vec<String> = xyz.iter().chain(rpy.iter()).map(f64::to_string).collect();
        out.extend(["--mount".to_string(), all.join(",")]);
    }
    Ok(out)
}

/// The MuJoCo plant's command for the demo `a` describes (`cfg`, `s` its resolved flags).
///
/// # Errors
/// A flag the MuJoCo plant does not take (named), or no Python to run it.
pub fn plant_process(a: &DemoFlags<'_>, cfg: &HilConfig, s: &HilScenario) -> Result<Process> {
    let refuse = [
        (
            a.scenario.actuator_lag.is_some(),
            "--actuator-lag (the kinematic plant's; the MuJoCo plant's drives lag)",
        ),
        (
            a.scenario.wheel_scale_error.is_some(),
            "--wheel-scale-error (the kinematic plant's; MuJoCo's wheels slip)",
        ),
        (a.scenario.target_file.is_some(), "--target-file"),
    ];
    let mut given = a.unsupported.iter().copied().chain(refuse.iter().filter(|(g, _)| *g).map(|(_, f)| *f));
    if let Some(flag) = given.next() {
        bail!("--plant mujoco does not take {flag}");
    }
    if s.spatial().is_none() {
        bail!("--plant mujoco simulates a robot read from a URDF: give a spatial --arm (ur5, an arm file, a URDF)");
    }
    let base = s.base();
    let platform = match base.controller.platform {
        PlatformKind::Unicycle => "unicycle",
        PlatformKind::Omni => "omni",
        PlatformKind::Car => {
            bail!("--plant mujoco drives a differential-drive (unicycle) or omni base, not a car")
        }
    };
    let urdf_arm = companion_runtime::domain::arm::urdf::is_urdf(Path::new(a.arm));
    let own_urdf = a.plant_args.iter().any(|x| x == "--urdf" || x.starts_with("--urdf="));
    if !urdf_arm && a.arm != "ur5" && !a.arm.ends_with(".toml") {
        bail!(
            "--plant mujoco simulates the ur5 preset, an arm file (.toml; the UR5's URDF unless \
             --plant-arg=--urdf=FILE) or a URDF (.urdf): it has no model of --arm {}",
            a.arm
        );
    }
    if !urdf_arm && platform != "omni" && !own_urdf {
        bail!(
            "--plant mujoco carries --arm {} (the UR5's URDF, which has no base) on --platform omni only: give \
             --platform omni, or a URDF with its wheels (--arm robot.urdf, e.g. the TIAGo)",
            a.arm
        );
    }
    let script = workspace().join("bridges/mujoco/companion_mujoco.py");
    let mut p = Process::new(python()?);
    let timing = &cfg.timing;
    let ms = |ns: u64| format!("{}", ns as f64 / 1e6);
    p.arg(script)
        .args(["--name", cfg.name.as_str()])
        .args(["--arm", a.arm, "--platform", platform])
        .args(["--trajectory", &a.scenario.trajectory.to_string()])
        .args(["--duration", &base.duration.to_string(), "--dt", &base.dt.to_string()])
        .args(["--deadline-us", &(timing.deadline_ns / 1000).to_string()])
        .args(["--hold-periods", &timing.hold_periods.to_string()])
        .args(["--silence-ms", &ms(timing.silence_ns)])
        .args(["--peer-timeout", &(timing.peer_timeout_ns as f64 / 1e9).to_string()])
        .args(["--startup-timeout", &cfg.startup_timeout.as_secs_f64().to_string()])
        .args(["--max-miss-fraction", &cfg.acceptance.max_miss_fraction.to_string()])
        .args([
            "--scenario-hash",
            &format!("{:#x}", companion_runtime::run::hil::handshake::controller_hash(&base.controller)),
        ])
        .arg("--out")
        .arg(&cfg.out);
    if timing.lockstep {
        p.arg("--lockstep");
    }
    if cfg.no_plots {
        p.arg("--no-plots");
    }
    if urdf_arm {
        p.args(urdf_flags(a, s)?);
    }
    if let Some(rt) = &cfg.rt {
        // The plant's half of --rt (SCHED_FIFO, its CPU, memory locked); the controller
        // takes its own.
        p.args(["--rt", "--rt-priority", &rt.priority.to_string(), "--cpu", &rt.plant_cpu.to_string()]);
    }
    if a.scenario.noise {
        p.args(["--noise", "--seed", &a.scenario.seed.to_string()]);
    }
    check_plant_args(&p, a.plant_args)?;
    p.args(a.plant_args);
    check(&p)?;
    // Python turns a SIGINT before the plant's handler into a traceback: ignored until then
    // (companion_mujoco.py handles it from its first line; this process forwards a SIGTERM).
    companion_runtime::sys::process::start_with_sigint_ignored(&mut p);
    Ok(p)
}

/// The plant's flags `companion hil` must not be handed again: those it gives the plant itself
/// (from its own flags), and those that make the plant something other than this run's plant.
///
/// # Errors
/// A `--plant-arg` that repeats one of them, named with the flag of `hil` that sets it.
fn check_plant_args(p: &Process, plant_args: &[String]) -> Result<()> {
    let given: Vec<String> =
        p.get_args().filter_map(|x| x.to_str()).filter(|x| x.starts_with("--")).map(str::to_string).collect();
    for arg in plant_args {
        let flag = arg.split_once('=').map_or(arg.as_str(), |(f, _)| f);
        if !flag.starts_with("--") {
            continue;
        }
        if given.iter().any(|g| g == flag) {
            bail!(
                "--plant-arg={}: `companion hil` gives the plant {flag} itself, from its own flags (give it to \
                 hil: its value must be the controller's too)",
                excerpt(arg)
            );
        }
        let why = match flag {
            "--lockstep" | "--noise" | "--seed" => {
                Some("a flag of the run that `companion hil` takes itself and hands to both processes: give it to hil")
            }
            "--open-loop" => Some("the plant would drive the robot without the controller"),
            "--check" => Some("hil checks the plant's flags itself before it starts the run"),
            "--scenario-json" | "--joint-count" | "--arm-hash" | "--space" | "--protocol-version"
            | "--service-version" | "--short-command" => {
                Some("a test flag that makes the plant announce something else than its robot")
            }
            _ => None,
        };
        if let Some(why) = why {
            bail!("--plant-arg={}: {why}", excerpt(arg));
        }
    }
    Ok(())
}

fn excerpt(s: &str) -> String {
    companion_runtime::domain::arm::urdf::excerpt(s)
}

/// The plant's own check of `p`'s flags (`--check`: the flags, the actuator table, the robot
/// built by MuJoCo; nothing written), before anything of the run starts. Its warnings (MuJoCo's
/// among them) are passed on.
///
/// # Errors
/// The plant's reason for refusing (one line), or its help printed instead of a check.
fn check(p: &Process) -> Result<()> {
    let mut c = Process::new(p.get_program());
    c.args(p.get_args()).arg("--check").stdin(Stdio::null());
    companion_runtime::sys::process::start_with_sigint_ignored(&mut c);
    let out = c.output().map_err(|e| {
        anyhow::anyhow!("--plant mujoco: cannot run {}: {e}", p.get_program().to_string_lossy())
    })?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let reason = stderr.lines().rev().find_map(|l| l.strip_prefix("error: ")).map(str::to_string);
    for l in stderr.lines().filter(|l| !l.starts_with("error: ") && !l.trim().is_empty()) {
        eprintln!("{l}");
    }
    if companion_runtime::sys::signals::termination_requested() {
        // The caller sees the signal and ends (exit 130): nothing was started.
        return Ok(());
    }
    match (out.status.code(), reason) {
        (Some(0), _) if stdout.lines().any(|l| l.trim() == "CHECKED") => Ok(()),
        (Some(0), _) => {
            print!("{stdout}");
            bail!(
                "--plant-arg: the MuJoCo plant printed its help (above) instead of checking its flags: no run was \
                 started"
            )
        }
        (_, Some(reason)) => bail!("--plant mujoco: {reason}"),
        (code, None) => bail!(
            "--plant mujoco: the plant's check ended with {} and no reason: {}",
            code.map_or("a signal".to_string(), |c| format!("exit code {c}")),
            excerpt(stderr.trim())
        ),
    }
}
