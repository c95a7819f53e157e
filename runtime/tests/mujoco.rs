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
/// end, and the CSV's e_p is recomputed independently. (The aim for this run —
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
}
