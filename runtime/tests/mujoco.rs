//! The MuJoCo plant (`bridges/mujoco/companion_mujoco.py`: the robot's URDF with wheels,
//! drives, servos and gravity, behind the wire) against `companion control` and in `companion
//! hil --plant mujoco`: lockstep runs byte-identical, a killed plant or controller noticed as
//! with the kinematic plant, robots that differ refused by name on both sides, the demo's
//! files and pictures, what the MuJoCo plant cannot do refused before anything starts.
//!
//! Needs `target/py` with mujoco, example-robot-data and iceoryx2 (`scripts/setup`). Without
//! them each test says so and passes — unless `COMPANION_REQUIRE_MUJOCO` is set (CI sets it),
//! when their absence fails. The tests run one at a time; every process has a time limit.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::Receiver;
use std::sync::{Mutex, MutexGuard, OnceLock};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_companion");

/// A watchdog for a process that should have ended (a loaded machine is slow, never this slow).
const LIMIT: Duration = Duration::from_secs(120);

static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

fn one_at_a_time() -> MutexGuard<'static, ()> {
    ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The Python `companion hil --plant mujoco` runs (as the binary finds it).
fn python() -> PathBuf {
    std::env::var_os("COMPANION_PYTHON")
        .map_or_else(|| workspace().join("target/py/bin/python"), PathBuf::from)
}

/// Whether the MuJoCo plant can run here; says why not once.
fn available() -> bool {
    static OK: OnceLock<bool> = OnceLock::new();
    *OK.get_or_init(|| {
        let probe = Command::new(python())
            .args(["-c", "import mujoco, iceoryx2, os, sys; sys.path.insert(0, 'bridges/mujoco'); import mujoco_robot; assert os.path.isdir(mujoco_robot.robots_dir())"])
            .current_dir(workspace())
            .output();
        let why = match probe {
            Err(e) => Some(format!("{}: {e}", python().display())),
            Ok(o) if !o.status.success() => Some(String::from_utf8_lossy(&o.stderr).trim().to_string()),
            Ok(_) => None,
        };
        if let Some(why) = &why {
            assert!(
                std::env::var_os("COMPANION_REQUIRE_MUJOCO").is_none(),
                "COMPANION_REQUIRE_MUJOCO is set but the MuJoCo plant cannot run: {why}"
            );
            eprintln!("SKIPPED: the MuJoCo plant's tests need target/py with mujoco (scripts/setup): {why}");
        }
        why.is_none()
    })
}

fn out_dir(tag: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("mujoco-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn demo(tag: &str) -> String {
    format!("m{}-{tag}", std::process::id())
}

fn started(mut c: Command) -> Child {
    c.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("a process starts")
}

/// The MuJoCo plant with `args`.
fn mujoco_plant(args: &[&str]) -> Child {
    let mut c = Command::new(python());
    c.arg(workspace().join("bridges/mujoco/companion_mujoco.py")).args(args);
    started(c)
}

/// `companion ARGS`.
fn companion(args: &[&str]) -> Child {
    let mut c = Command::new(BIN);
    c.args(args);
    started(c)
}

/// `child` to its end (killed, and the test failed, after [`LIMIT`]): status and everything
/// it wrote.
fn ended(mut child: Child, what: &str) -> (ExitStatus, String) {
    let end = Instant::now() + LIMIT;
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > end {
            let _ = child.kill();
            let o = child.wait_with_output().unwrap();
            panic!("{what} still running after {LIMIT:?}:\n{}", String::from_utf8_lossy(&o.stderr));
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let o = child.wait_with_output().unwrap();
    (o.status, format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr)))
}

/// The controller with `control` and then the MuJoCo plant with `plant`, each to its end:
/// `((plant), (controller))`.
fn against(control: &[&str], plant: &[&str]) -> ((ExitStatus, String), (ExitStatus, String)) {
    let mut c = vec!["control"];
    c.extend(control);
    let c = companion(&c);
    let p = mujoco_plant(plant);
    (ended(p, "the MuJoCo plant"), ended(c, "the controller"))
}

fn ur5_file() -> String {
    workspace().join("examples/arms/ur5.toml").display().to_string()
}

/// The TIAGo's URDF as example-robot-data installs it in target/py.
fn tiago_urdf() -> String {
    let out = Command::new(python())
        .args(["-c", "import sys; sys.path.insert(0, 'bridges/mujoco'); import mujoco_robot as m; print(m.resolve_robot_file('tiago_description/robots/tiago_no_hand.urdf'))"])
        .current_dir(workspace())
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap().trim().to_string()
}

/// The TIAGo's cut and home (the notes' well-conditioned home), on its wheels: the flags both
/// the MuJoCo plant and `companion control`/`hil` take, after `--arm URDF`.
const TIAGO_CUT: [&str; 8] = [
    "--base-link",
    "base_footprint",
    "--tip-link",
    "arm_tool_link",
    "--home",
    "0.2,1.0,-0.5,-1.0,1.2,0.0,0.5,0.0",
    "--platform",
    "unicycle",
];

fn json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// `companion hil --plant mujoco` with the UR5 (its arm file) on the omni base, lockstep,
/// `extra` flags, into `out`: status and output.
fn hil_ur5(name: &str, out: &Path, extra: &[&str], env: &[(&str, &str)]) -> (ExitStatus, String) {
    let mut c = Command::new(BIN);
    c.args([
        "hil",
        "--plant",
        "mujoco",
        "--name",
        name,
        "--arm",
        &ur5_file(),
        "--platform",
        "omni",
        "--lockstep",
    ])
    .arg("--out")
    .arg(out)
    .args(extra)
    .envs(env.iter().copied());
    ended(started(c), "companion hil --plant mujoco")
}

#[test]
fn two_lockstep_runs_through_the_demo_are_byte_identical_and_their_csv_checks_independently() {
    if !available() {
        return;
    }
    let _g = one_at_a_time();
    let runs: Vec<PathBuf> = ["a", "b"]
        .iter()
        .map(|tag| {
            let out = out_dir(&format!("twice-{tag}"));
            let (st, text) =
                hil_ur5(&demo(tag), &out, &["--duration", "2", "--plant-arg=--filmstrip=0"], &[]);
            assert!(st.success(), "{text}");
            assert!(
                text.contains("answered 2001 measurements (0 skipped as superseded, 0 dropped"),
                "{text}"
            );
            out
        })
        .collect();
    let csv = |d: &Path| std::fs::read(d.join("timeseries.csv")).unwrap();
    let (a, b) = (csv(&runs[0]), csv(&runs[1]));
    assert_eq!(a.iter().filter(|&&c| c == b'\n').count(), 1 + 2001, "a row per period");
    assert!(a == b, "two lockstep runs of the MuJoCo plant differ");
    let s = json(&runs[0].join("summary.json"));
    assert_eq!(
        (s["steps"].as_u64(), s["session"]["counts"]["fresh"].as_u64()),
        (Some(2001), Some(2001)),
        "{s}"
    );
    e_p_checks_independently(&runs[0]);
}

/// The tracking error of every row of `run`'s CSV recomputed from the logged poses (plain
/// Python, not the plant's code) agrees with the plant's `ep_norm` column.
fn e_p_checks_independently(run: &Path) {
    let check = Command::new("python3")
        .arg(workspace().join("scripts/check_spatial_csv.py"))
        .arg(run)
        .output()
        .unwrap();
    assert!(check.status.success(), "{}", String::from_utf8_lossy(&check.stdout));
}

#[test]
fn the_demo_writes_a_filmstrip_or_says_why_it_has_none() {
    if !available() {
        return;
    }
    let _g = one_at_a_time();
    let out = out_dir("film");
    let (st, text) = hil_ur5(&demo("film"), &out, &["--duration", "1", "--plant-arg=--filmstrip=3"], &[]);
    assert!(st.success(), "{text}");
    let index = std::fs::read_to_string(out.join("index.html")).unwrap();
    for f in ["timeseries.csv", "summary.json", "latency.json", "scenario.json"] {
        assert!(out.join(f).is_file(), "{f} missing");
        assert!(index.contains(&format!("href='{f}'")), "index.html does not link {f}");
    }
    if out.join("filmstrip.png").is_file() {
        assert!(index.contains("<img src='filmstrip.png'"), "{index}");
        for k in 0..3 {
            let frame = std::fs::read(out.join(format!("frame-{k:02}.png"))).unwrap();
            assert!(frame.starts_with(b"\x89PNG\r\n\x1a\n") && frame.len() > 1000, "frame {k}");
        }
    } else {
        assert!(
            index.contains("No pictures: no off-screen renderer"),
            "neither a filmstrip nor why: {index}"
        );
    }
    // Without a renderer (a backend MuJoCo does not have) the run still completes and says why.
    let out = out_dir("nofilm");
    let (st, text) = hil_ur5(
        &demo("nofilm"),
        &out,
        &["--duration", "1", "--plant-arg=--filmstrip=3"],
        &[("MUJOCO_GL", "none")],
    );
    assert!(st.success(), "{text}");
    let index = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(index.contains("No pictures: no off-screen renderer (MUJOCO_GL=none)"), "{index}");
    assert!(!out.join("filmstrip.png").exists());
    assert!(text.contains("no off-screen renderer"), "{text}");
}

/// Whether a line containing `pat` comes on `lines` (within [`LIMIT`]) before they end.
fn seen(lines: &Receiver<String>, pat: &str) -> bool {
    let end = Instant::now() + LIMIT;
    while let Ok(l) = lines.recv_timeout(end.saturating_duration_since(Instant::now())) {
        if l.contains(pat) {
            return true;
        }
    }
    false
}

/// Waits for a line containing `pat` on `lines` (at most [`LIMIT`]).
fn wait_for(lines: &Receiver<String>, pat: &str) {
    let end = Instant::now() + LIMIT;
    loop {
        match lines.recv_timeout(end.saturating_duration_since(Instant::now())) {
            Ok(l) if l.contains(pat) => return,
            Ok(_) => {}
            Err(_) => panic!("no line with {pat:?} within {LIMIT:?}"),
        }
    }
}

/// `err`'s lines as they come, and all of them once it ends.
fn line_by_line(err: std::process::ChildStderr) -> (Receiver<String>, std::thread::JoinHandle<String>) {
    let (tx, lines) = std::sync::mpsc::channel();
    let reader = std::thread::spawn(move || {
        use std::io::BufRead;
        let mut seen = String::new();
        for l in std::io::BufReader::new(err).lines().map_while(Result::ok) {
            seen.push_str(&l);
            seen.push('\n');
            let _ = tx.send(l);
        }
        seen
    });
    (lines, reader)
}

/// Real time, UR5 on the omni base; one side SIGKILLed once the plant has run 500 periods (a
/// counted state, never a fixed sleep). `((plant), (controller))`.
fn kill_at_period_500(kill_plant: bool, out: &Path) -> ((ExitStatus, String), (ExitStatus, String)) {
    let n = demo(if kill_plant { "killp" } else { "killc" });
    let ur5 = ur5_file();
    let control =
        companion(&["control", "--name", &n, "--arm", &ur5, "--platform", "omni", "--wait", "hybrid"]);
    let mut plant = mujoco_plant(&[
        "--name",
        &n,
        "--arm",
        &ur5,
        "--platform",
        "omni",
        "--duration",
        "30",
        "--hold-periods",
        "100000",
        "--max-miss-fraction",
        "1",
        "--progress",
        "500",
        "--filmstrip",
        "0",
        "--no-plots",
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = plant.stderr.take().unwrap();
    let (lines, reader) = line_by_line(err);
    wait_for(&lines, "bridge: period 500");
    let victim = if kill_plant { plant.id() } else { control.id() };
    assert!(Command::new("kill").args(["-KILL", &victim.to_string()]).status().unwrap().success());
    let (ps, pt) = ended(plant, "the MuJoCo plant");
    let c = ended(control, "the controller");
    ((ps, pt + &reader.join().unwrap()), c)
}

#[test]
fn a_killed_mujoco_plant_is_noticed_as_a_killed_kinematic_plant_is_and_the_other_way_round() {
    if !available() {
        return;
    }
    let _g = one_at_a_time();
    // The plant killed: the controller finds it dead (exit 3), by the node id of its samples.
    let (_, (cs, ct)) = kill_at_period_500(true, &out_dir("killp"));
    assert_eq!(cs.code(), Some(3), "{ct}");
    assert!(ct.contains("the plant (pid") && ct.contains("died"), "{ct}");
    // The controller killed: the plant stops its robot, says why, exits 3 and writes its files.
    let out = out_dir("killc");
    let ((ps, pt), _) = kill_at_period_500(false, &out);
    assert_eq!(ps.code(), Some(3), "{pt}");
    assert!(pt.contains("the controller died") && pt.contains("robot stopped"), "{pt}");
    let s = json(&out.join("summary.json"));
    assert_eq!(s["exit"], 3, "{s}");
    assert!(s["end"].as_str().unwrap().contains("the controller died"), "{s}");
    assert!(s["steps"].as_u64().unwrap() > 500, "{s}");
}

#[test]
fn a_plant_and_a_controller_with_different_robots_refuse_each_other_by_name() {
    if !available() {
        return;
    }
    let _g = one_at_a_time();
    let ur5 = ur5_file();
    // The UR5 with another elbow limit: the same joints and platform, another arm.
    let dir = out_dir("arms");
    std::fs::create_dir_all(&dir).unwrap();
    let other = dir.join("ur5-other-elbow.toml");
    let text = std::fs::read_to_string(&ur5)
        .unwrap()
        .replace("limits = [0.15, 2.991592653589793]", "limits = [0.2, 2.9]");
    assert_ne!(text, std::fs::read_to_string(&ur5).unwrap(), "the elbow's limits are in the file");
    std::fs::write(&other, text).unwrap();
    let other = other.display().to_string();
    let ur5_plant = ["--arm", ur5.as_str(), "--platform", "omni"];
    let urdf = tiago_urdf();
    let mut tiago = vec!["--arm", urdf.as_str()];
    tiago.extend(TIAGO_CUT);
    // The same URDF cut one link short (arm_7_link, the tool's frame dropped): 8 joints too,
    // another arm.
    let mut short = tiago.clone();
    short[5] = "arm_7_link";
    // (the controller's flags, the plant's, what the controller says, what the plant says)
    let cases: [(&[&str], &[&str], &str, &str); 5] = [
        (
            &["--arm", "panda", "--platform", "omni"],
            &ur5_plant,
            "joint count mismatch: the plant has 6 joints, the controller is built for 7",
            "this bridge has 6 joints, the controller is built for 7",
        ),
        (
            &["--arm", &other, "--platform", "omni"],
            &ur5_plant,
            "arm mismatch: the plant's arm is ur5 (0x",
            "(arm mismatch): this bridge's arm hash is 0x",
        ),
        (
            &["--arm", "ur5", "--platform", "unicycle"],
            &ur5_plant,
            "the plant is omnidirectional, the controller is built for unicycle",
            "this bridge is omnidirectional, the controller is built for unicycle",
        ),
        (
            &["--arm", "ur5", "--platform", "unicycle"],
            &tiago,
            "joint count mismatch: the plant has 8 joints, the controller is built for 6",
            "this bridge has 8 joints, the controller is built for 6",
        ),
        (
            &short,
            &tiago,
            "arm mismatch: the plant's arm is 0x",
            "(arm mismatch): this bridge's arm hash is 0x",
        ),
    ];
    for (control, plant, controller_says, plant_says) in cases {
        let n = demo("refuse");
        let mut c = vec!["--name", n.as_str(), "--startup-timeout", "30"];
        c.extend(control);
        let mut p =
            vec!["--name", n.as_str(), "--lockstep", "--duration", "1", "--filmstrip", "0", "--no-plots"];
        let out = dir.join("run");
        p.extend(["--out", out.to_str().unwrap()]);
        p.extend(plant);
        let ((ps, pt), (cs, ct)) = against(&c, &p);
        println!("{control:?} / {plant:?}\n  controller: {}\n  plant: {}", ct.trim(), pt.trim());
        assert_eq!(
            (cs.code(), ps.code()),
            (Some(2), Some(2)),
            "{control:?}\ncontroller:\n{ct}\nplant:\n{pt}"
        );
        assert!(ct.contains(controller_says), "{control:?}: the controller said\n{ct}");
        assert!(pt.contains(plant_says), "{control:?}: the plant said\n{pt}");
    }
}

/// The TIAGo from its URDF in the demo: the controller reads the same URDF and accepts the
/// plant (their arm hashes, computed each its own way, agree), 10 s in lockstep run to their
/// end, and the CSV's e_p is recomputed independently. (The issue's aim for this run —
/// settled within 2 mm after 20 s — is not met by the law on either plant: docs/book/src/mujoco.md.)
#[test]
fn the_tiago_from_its_urdf_runs_in_the_demo_against_a_controller_reading_the_same_urdf() {
    if !available() {
        return;
    }
    let _g = one_at_a_time();
    let out = out_dir("tiago");
    let urdf = tiago_urdf();
    let mut c = Command::new(BIN);
    c.args(["hil", "--plant", "mujoco", "--name", &demo("tiago"), "--arm", &urdf])
        .args(TIAGO_CUT)
        .args(["--lockstep", "--duration", "10", "--plant-arg=--filmstrip=0", "--no-plots", "--out"])
        .arg(&out);
    let (st, text) = ended(started(c), "companion hil --plant mujoco (TIAGo)");
    assert!(st.success(), "{text}");
    assert!(text.contains("answered 10001 measurements (0 skipped as superseded, 0 dropped"), "{text}");
    let s = json(&out.join("summary.json"));
    assert_eq!(s["robot"]["chain"].as_array().map(Vec::len), Some(8), "{s}");
    assert_eq!(s["robot"]["wheels"]["track"].as_f64().map(|t| (t * 1e4).round()), Some(4044.0), "{s}");
    e_p_checks_independently(&out);
}

/// ‖p̃‖ (the position half of `e_p`) of each row of a run's `timeseries.csv`, with its time.
fn position_errors(run: &Path) -> Vec<(f64, f64)> {
    let text = std::fs::read_to_string(run.join("timeseries.csv")).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let (t, x, y, z) = (col("t"), col("ep_x"), col("ep_y"), col("ep_z"));
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|c| c.parse().unwrap_or(f64::NAN)).collect();
            (v[t], (v[x] * v[x] + v[y] * v[y] + v[z] * v[z]).sqrt())
        })
        .collect()
}

/// The book's TIAGo command (`examples/arms/tiago-unicycle.toml`: the mid-reach home, the
/// base's own limits, the heading filter), 20 s in lockstep: the TIAGo on its wheels converges
/// from 2 m away to within 5 cm over the last 5 s (1.4 cm measured; the 1 mm aim is not met,
/// docs/book/src/mujoco.md says why), its wheels at their friction's limit less than
/// 1 % of the time (0.3 % measured) and no joint at its limit.
#[test]
fn the_tiago_from_a_home_it_settles_from_converges_on_its_wheels_without_sliding() {
    if !available() {
        return;
    }
    let _g = one_at_a_time();
    let out = out_dir("tiago-settles");
    let mut c = Command::new(BIN);
    c.args(["hil", "--plant", "mujoco", "--name", &demo("tiago-settles"), "--platform", "unicycle"])
        .args(["--arm", &tiago_urdf(), "--config"])
        .arg(workspace().join("examples/arms/tiago-unicycle.toml"))
        .args(["--lockstep", "--duration", "20", "--plant-arg=--filmstrip=0", "--no-plots", "--out"])
        .arg(&out);
    let (st, text) = ended(started(c), "companion hil --plant mujoco (TIAGo, mid-reach home)");
    assert!(st.success(), "{text}");
    let e = position_errors(&out);
    assert!(e[0].1 > 1.0, "the target starts {} m away", e[0].1);
    let last = e.iter().filter(|(t, _)| *t >= 15.0).map(|(_, p)| *p).fold(0.0, f64::max);
    assert!(last < 0.05, "max |p~| over 15-20 s: {last} m");
    let s = json(&out.join("summary.json"));
    let sliding = s["wheel_slip"]["sliding_fraction_of_time"].as_f64().unwrap();
    assert!(sliding < 0.01, "the wheels slide {sliding} of the time");
    assert_eq!(s["joint_limit_reached"], serde_json::Value::Bool(false), "{s}");
    e_p_checks_independently(&out);
}

#[test]
fn what_the_mujoco_plant_cannot_do_is_refused_by_name_before_anything_starts() {
    if !available() {
        return;
    }
    let _g = one_at_a_time();
    let ur5 = ur5_file();
    for (flags, says) in [
        (
            &["--arm", ur5.as_str(), "--platform", "omni", "--chaos", "1"][..],
            "--plant mujoco does not take --chaos",
        ),
        (&["--platform", "omni"][..], "give a spatial --arm"),
        (&["--arm", ur5.as_str(), "--platform", "car"][..], "not a car"),
        (
            &["--arm", ur5.as_str(), "--platform", "omni", "--actuator-lag", "0.01"][..],
            "does not take --actuator-lag",
        ),
    ] {
        let out = out_dir("refused");
        let mut a = vec!["hil", "--plant", "mujoco", "--name", "refused"];
        a.extend(flags);
        a.extend(["--out", out.to_str().unwrap()]);
        let (st, text) = ended(companion(&a), "companion hil");
        assert_eq!(st.code(), Some(2), "{flags:?}: {text}");
        assert!(text.contains(says), "{flags:?}: {text}");
        assert!(!out.exists(), "{flags:?}: {} was written", out.display());
    }
    let (st, text) = ended(companion(&["plant", "--plant", "mujoco"]), "companion plant");
    assert_eq!(st.code(), Some(2), "{text}");
    assert!(text.contains("--plant and --plant-arg are for `companion hil`"), "{text}");
    // What the plant itself would refuse, refused before anything starts too (issue 45: each
    // of these started both processes, or ran nothing and exited 0).
    let ur5_omni = ["--arm", ur5.as_str(), "--platform", "omni"];
    let with = |extra: &'static [&'static str]| {
        ur5_omni.iter().copied().chain(extra.iter().copied()).collect::<Vec<&str>>()
    };
    for (flags, says) in [
        (vec!["--arm", "ur5", "--platform", "unicycle"], "on --platform omni only"),
        (vec!["--arm", ur5.as_str(), "--platform", "unicycle"], "on --platform omni only"),
        (vec!["--arm", "panda", "--platform", "omni"], "it has no model of --arm panda"),
        (
            with(&["--plant-arg=--help"]),
            "printed its help (above) instead of checking its flags: no run was started",
        ),
        (with(&["--plant-arg=--set=nonsense=1"]), "SECTION.KEY=VALUE, e.g. arm.time_constant=0.002"),
        (
            with(&["--plant-arg=--set=wheels.kv=40"]),
            "unknown key wheels.kv (wheels has caster_friction, effort, speed, time_constant",
        ),
        (
            with(&["--plant-arg=--name=other"]),
            "--plant-arg=--name=other: `companion hil` gives the plant --name itself",
        ),
        (with(&["--plant-arg=--filmstrip=x"]), "argument --filmstrip: invalid int value: 'x'"),
        (with(&["--plant-arg=--open-loop=1:0,0"]), "without the controller"),
    ] {
        let out = out_dir("refused");
        let mut a = vec!["hil", "--plant", "mujoco", "--name", "refused"];
        a.extend(&flags);
        a.extend(["--out", out.to_str().unwrap()]);
        let (st, text) = ended(companion(&a), "companion hil");
        assert_eq!(st.code(), Some(2), "{flags:?}: {text}");
        assert!(text.contains(says), "{flags:?}: {text}");
        assert!(!text.contains("started the plant") && !text.contains("Traceback"), "{flags:?}: {text}");
        assert!(!out.exists(), "{flags:?}: {} was written", out.display());
        if flags.contains(&"--plant-arg=--help") {
            assert!(text.contains("usage: companion_mujoco.py"), "the help is printed: {text}");
        }
    }
    let mut c = Command::new(BIN);
    c.args(["hil", "--plant", "mujoco", "--name", "refused", "--arm", &ur5, "--platform", "omni"])
        .env("COMPANION_PYTHON", "/nonexistent/python3");
    let (st, text) = ended(started(c), "companion hil");
    assert_eq!(st.code(), Some(2), "{text}");
    assert!(text.contains("COMPANION_PYTHON=/nonexistent/python3: no such file"), "{text}");
}

/// Two threads spinning for as long as the value lives: the machine loaded beside the runs.
struct Load(std::sync::Arc<std::sync::atomic::AtomicBool>, Vec<std::thread::JoinHandle<()>>);

impl Load {
    fn start() -> Self {
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let threads = (0..2)
            .map(|_| {
                let stop = std::sync::Arc::clone(&stop);
                std::thread::spawn(move || {
                    let mut x = 0u64;
                    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                        x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
                    }
                })
            })
            .collect();
        Self(stop, threads)
    }
}

impl Drop for Load {
    fn drop(&mut self) {
        self.0.store(true, std::sync::atomic::Ordering::Relaxed);
        for t in self.1.drain(..) {
            let _ = t.join();
        }
    }
}

/// `companion hil --plant mujoco` (the UR5, real time, 30 s unless `extra` gives a
/// `--duration`) in a process group of its own; its stderr as lines, and everything it wrote
/// once it ends.
fn hil_in_group(
    name: &str,
    out: &Path,
    extra: &[&str],
) -> (Child, Receiver<String>, std::thread::JoinHandle<String>) {
    use std::os::unix::process::CommandExt;
    let mut c = Command::new(BIN);
    c.args(["hil", "--plant", "mujoco", "--name", name, "--arm", &ur5_file(), "--platform", "omni"])
        .args(if extra.contains(&"--duration") { &[][..] } else { &["--duration", "30"][..] })
        .args(["--max-miss-fraction", "1", "--hold-periods", "100000", "--quiet", "--no-plots"])
        // A loaded machine starts Python, MuJoCo and the model slowly (over 20 s was seen with
        // load 18 on two CPUs): the start is waited for as long as the process watchdog.
        .args(["--startup-timeout", "120"])
        .args(["--plant-arg=--progress=300", "--plant-arg=--filmstrip=0", "--out"])
        .arg(out)
        .args(extra)
        .process_group(0);
    let mut child = started(c);
    let err = child.stderr.take().unwrap();
    let (lines, reader) = line_by_line(err);
    (child, lines, reader)
}

fn signal_group(pgid: u32, signal: &str) {
    let st = Command::new("kill").args([&format!("-{signal}"), "--", &format!("-{pgid}")]).status().unwrap();
    assert!(st.success(), "kill -{signal} -- -{pgid}");
}

/// SIGINT and SIGTERM to the demo's process group — a terminal's Ctrl-C, a supervisor's stop:
/// both processes get it, and the controller forwards a SIGTERM to the plant — once or three
/// times, before the plant's run starts, in its middle and while it writes its files, with
/// two threads spinning beside it: the run ends with its files (those of a run that started)
/// and exit 130, never a Python traceback (issue 45: 2 of 5 SIGINT and 4 of 5 SIGTERM died
/// in the plant's report() and exited 3). Each signal goes when the run reaches a counted
/// state — a line the processes print — never after a sleep.
#[test]
fn sigint_and_sigterm_to_the_group_end_the_mujoco_run_with_its_files_and_exit_130() {
    if !available() {
        return;
    }
    let _g = one_at_a_time();
    let _load = Load::start();
    let mut k = 0;
    let mut tally = Vec::new();
    for (moment, at) in [("before the run", "started the plant"), ("mid-run", "bridge: period 300")] {
        for signal in ["INT", "TERM"] {
            for count in [1, 3] {
                k += 1;
                let out = out_dir(&format!("sig{k}"));
                let (child, lines, reader) = hil_in_group(&demo(&format!("sig{k}")), &out, &[]);
                let pgid = child.id();
                wait_for(&lines, at);
                for _ in 0..count {
                    signal_group(pgid, signal);
                }
                let (st, _) = ended(child, "companion hil --plant mujoco");
                let text = reader.join().unwrap();
                let what = format!("SIG{signal} x{count} {moment}");
                assert_eq!(st.code(), Some(130), "{what}:\n{text}");
                assert!(!text.contains("Traceback"), "{what}:\n{text}");
                if moment == "mid-run" {
                    for f in ["timeseries.csv", "summary.json", "latency.json", "session.json"] {
                        assert!(out.join(f).is_file(), "{what}: no {f}:\n{text}");
                    }
                    let rows =
                        std::fs::read_to_string(out.join("timeseries.csv")).unwrap().lines().count() - 1;
                    assert!(rows >= 300, "{what}: {rows} rows");
                    let s = json(&out.join("summary.json"));
                    assert_eq!(s["exit"], 130, "{what}: {s}");
                    assert!(s["end"].as_str().unwrap().contains("interrupted"), "{what}: {s}");
                    assert_eq!(s["steps"].as_u64(), Some(rows as u64), "{what}: every row counted");
                } else {
                    assert!(!out.exists(), "{what}: wrote {} before its run", out.display());
                }
                tally.push(what);
            }
        }
    }
    // While the plant writes the files of a completed run (lockstep, 0.3 s): the files are whole
    // and the run's verdict stands, as `companion plant`'s does.
    for signal in ["INT", "TERM"] {
        k += 1;
        let out = out_dir(&format!("sig{k}"));
        let (child, lines, reader) =
            hil_in_group(&demo(&format!("sig{k}")), &out, &["--lockstep", "--duration", "0.3"]);
        let pgid = child.id();
        if !seen(&lines, "bridge: final|ep|") {
            let (st, _) = ended(child, "companion hil --plant mujoco");
            panic!("the run ended ({st}) before its files:\n{}", reader.join().unwrap());
        }
        for _ in 0..3 {
            signal_group(pgid, signal);
        }
        let (st, _) = ended(child, "companion hil --plant mujoco");
        let text = reader.join().unwrap();
        assert_eq!(st.code(), Some(0), "SIG{signal} in report():\n{text}");
        assert!(!text.contains("Traceback"), "{text}");
        let s = json(&out.join("summary.json"));
        assert_eq!((s["exit"].as_i64(), s["steps"].as_u64()), (Some(0), Some(301)), "{s}");
        assert!(out.join("latency.json").is_file() && out.join("index.html").is_file(), "{text}");
        tally.push(format!("SIG{signal} x3 in report()"));
    }
    println!("{} runs, each as it should: {}", tally.len(), tally.join("; "));
}

/// A SIGKILLed MuJoCo plant leaves the rows it had on disk, as the Rust plant does: the plant
/// streams timeseries.csv (flushed every 50 ms), and the controller trims a cut last line and
/// counts them in fault.json (issue 45: 0 of 10 runs left a timeseries.csv).
#[test]
fn a_sigkilled_mujoco_plant_leaves_its_rows_and_fault_json_counts_them() {
    if !available() {
        return;
    }
    let _g = one_at_a_time();
    let out = out_dir("sigkill");
    let (child, lines, reader) = hil_in_group(&demo("sigkill"), &out, &[]);
    let plant = loop {
        let l = lines.recv_timeout(LIMIT).expect("the plant's pid");
        if let Some(rest) = l.strip_prefix("started the plant (pid ") {
            break rest.split(')').next().unwrap().to_string();
        }
    };
    wait_for(&lines, "bridge: period 600");
    assert!(Command::new("kill").args(["-KILL", &plant]).status().unwrap().success());
    let (st, _) = ended(child, "companion hil --plant mujoco");
    let text = reader.join().unwrap();
    assert_eq!(st.code(), Some(3), "{text}");
    let fault = json(&out.join("fault.json"));
    let rows = std::fs::read_to_string(out.join("timeseries.csv")).unwrap().lines().count() as u64 - 1;
    assert_eq!(fault["rows_on_disk"].as_u64(), Some(rows), "{fault}");
    // Period 600 was printed before its row: at most 50 ms of rows (50 at 1 kHz) were not flushed.
    assert!(rows >= 550, "{rows} rows on disk after period 600: {fault}");
}

/// What the plant changes of a URDF to simulate it is said by link, in the run's output and in
/// summary.json — a mass of -1 kg raised to MuJoCo's 1 g, the meshes it cannot find dropped —
/// and a file MuJoCo cannot load (a negative principal inertia), or would load with NaN (a mass
/// of nan: MuJoCo only warns), is refused with the reason, exit 2, before the controller
/// starts (issue 45: a traceback and exit 1). MuJoCo's own log lands in the run's folder, not
/// in the working directory.
#[test]
fn physics_fixes_are_reported_by_link_and_a_file_mujoco_cannot_load_is_refused_before_the_run() {
    if !available() {
        return;
    }
    let _g = one_at_a_time();
    let dir = out_dir("fixes");
    std::fs::create_dir_all(&dir).unwrap();
    let tiago = std::fs::read_to_string(tiago_urdf()).unwrap();
    let mass = r#"<mass value="2.275860"/>"#;
    let inertia = r#"<inertia ixx="0.018178""#;
    assert!(tiago.contains(mass) && tiago.contains(inertia), "arm_3_link's inertial, as the tests know it");
    let write = |name: &str, text: String| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p.display().to_string()
    };
    let run = |arm: &str, out: &Path| {
        let mut c = Command::new(BIN);
        c.args(["hil", "--plant", "mujoco", "--name", &demo("fixes"), "--arm", arm])
            .args(TIAGO_CUT)
            .args(["--lockstep", "--duration", "0.2", "--plant-arg=--filmstrip=0", "--no-plots", "--out"])
            .arg(out)
            .current_dir(&dir);
        ended(started(c), "companion hil --plant mujoco (a mutated TIAGo)")
    };
    let light = write("light.urdf", tiago.replacen(mass, r#"<mass value="-1"/>"#, 1));
    let out = dir.join("light-run");
    let (st, text) = run(&light, &out);
    assert!(st.success(), "{text}");
    assert!(text.contains("arm_3_link: mass -1 -> 0.001 kg (MuJoCo's boundmass)"), "{text}");
    assert!(text.contains("visual meshes replaced or dropped"), "{text}");
    let s = json(&out.join("summary.json"));
    let fixes = s["physics_fixes"].as_array().unwrap();
    assert!(
        fixes.iter().any(|f| f["link"] == "arm_3_link" && f["fix"].as_str().unwrap().contains("mass -1")),
        "{s}"
    );
    let meshes = s["mesh_fixes"].as_array().unwrap();
    assert!(meshes.iter().any(|f| f["fix"].as_str().unwrap().contains("not found: dropped")), "{s}");
    for (name, text_in, says) in [
        (
            "negative-inertia",
            tiago.replacen(inertia, r#"<inertia ixx="-5""#, 1),
            "inertia must have positive eigenvalues",
        ),
        (
            "nan-mass",
            tiago.replacen(mass, r#"<mass value="nan"/>"#, 1),
            "<mass value>='nan' is not finite numbers",
        ),
    ] {
        let arm = write(&format!("{name}.urdf"), text_in);
        let out = dir.join(format!("{name}-run"));
        let (st, text) = run(&arm, &out);
        assert_eq!(st.code(), Some(2), "{name}:\n{text}");
        assert!(text.contains(says) && text.contains("arm_3_link"), "{name}:\n{text}");
        assert!(!text.contains("Traceback") && !text.contains("started the plant"), "{name}:\n{text}");
        assert!(!out.exists(), "{name}: wrote {}", out.display());
    }
    // A table that makes MuJoCo warn (an unstable base drive): its log in the run's folder,
    // none in the working directory.
    let cwd = dir.join("cwd");
    std::fs::create_dir_all(&cwd).unwrap();
    let out = dir.join("log-run");
    let mut c = Command::new(BIN);
    c.args(["hil", "--plant", "mujoco", "--name", &demo("log"), "--arm", &ur5_file(), "--platform", "omni"])
        .args([
            "--lockstep",
            "--duration",
            "0.2",
            "--max-rejected",
            "1",
            "--no-plots",
            "--plant-arg=--filmstrip=0",
        ])
        .args(["--plant-arg=--set=omni.time_constant=1e-12", "--plant-arg=--set=omni.force=1e30", "--out"])
        .arg(&out)
        .current_dir(&cwd);
    let (st, text) = ended(started(c), "companion hil --plant mujoco (an unstable table)");
    assert!(text.contains("The simulation is unstable"), "no warning from MuJoCo (status {st}):\n{text}");
    let log = std::fs::read_to_string(out.join("MUJOCO_LOG.TXT")).unwrap();
    assert!(log.contains("The simulation is unstable"), "{log}");
    assert_eq!(std::fs::read_dir(&cwd).unwrap().count(), 0, "the working directory got a file");
}
