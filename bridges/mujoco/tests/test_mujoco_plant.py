"""The MuJoCo plant's robot, without a controller: what it reads from the URDF, what its drives
do, the target it moves, the files it writes. Run by scripts/test (target/py's pytest); the
wire against `companion control` is tested in runtime/tests/mujoco.rs."""

import json
import math
import os
import subprocess
import sys
import zlib

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", "..", ".."))
sys.path.insert(0, os.path.join(REPO, "bridges", "mujoco"))
os.environ["MUJOCO_GL"] = os.environ.get("MUJOCO_GL", "egl")

import companion_mujoco as plant  # noqa: E402
import mujoco_robot  # noqa: E402

TIAGO_URDF = "tiago_description/robots/tiago_no_hand.urdf"
TIAGO_HOME = [0.2, 1.0, -0.5, -1.0, 1.2, 0.0, 0.5, 0.0]
TIAGO = ["--arm", TIAGO_URDF, "--base-link", "base_footprint", "--tip-link", "arm_tool_link",
         "--home", ",".join(map(str, TIAGO_HOME)), "--platform", "unicycle"]
UR5_FILE = os.path.join(REPO, "examples", "arms", "ur5.toml")


def tiago(*sets, dt=0.001):
    return mujoco_robot.Robot(TIAGO_URDF, "base_footprint", "arm_tool_link", "unicycle", TIAGO_HOME, dt,
                              mujoco_robot.load_table(sets=sets))


def open_loop(tmp_path, commands, duration, *extra):
    """The plant with `--open-loop` commands: its summary.json."""
    out = str(tmp_path / "run")
    code = plant.main([*extra, "--open-loop", commands, "--duration", str(duration), "--out", out,
                       "--filmstrip", "0", "--no-plots"])
    assert code == 0
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f), out


def test_the_tiago_base_is_read_from_its_urdf():
    r = tiago()
    # The URDF: wheel collision cylinders of radius 0.0985 m, wheel joints at y = ±0.2022 m,
    # <limit effort="6.0" velocity="10.152284264"/>; four casters (spheres of 0.025 m).
    assert r.wheels["radius"] == 0.0985
    assert r.wheels["track"] == pytest.approx(2 * 0.2022, abs=1e-12)
    assert (r.wheels["left"]["joint"], r.wheels["right"]["joint"]) == ("wheel_left_joint", "wheel_right_joint")
    assert sorted(r.casters) == sorted(f"caster_{p}_2_link" for p in ("front_left", "front_right", "back_left",
                                                                      "back_right"))
    m = r.model
    for side in ("left", "right"):
        assert list(m.actuator_forcerange[m.actuator("wheel/" + side).id]) == [-6.0, 6.0]
    assert r.chain_names == ["torso_lift_joint"] + [f"arm_{i}_joint" for i in range(1, 8)]
    assert list(m.actuator_forcerange[m.actuator("servo/arm_1_joint").id]) == [-39.0, 39.0]
    # The head is held (off the chain), the wheels are not servos of the arm's kind.
    held = [s["joint"] for s in r.servo_joints if not s["chain"]]
    assert held == ["head_1_joint", "head_2_joint"]


def test_a_unicycle_command_becomes_wheel_rates_and_a_too_fast_one_keeps_its_curvature():
    r = tiago()
    radius, track = r.wheels["radius"], r.wheels["track"]
    assert not r.command(0.3, 0.0, 0.5, [0.0] * 8)
    left, right = r.wheel_target * r.wheel_sign
    assert (left, right) == pytest.approx(((0.3 - 0.5 * track / 2) / radius, (0.3 + 0.5 * track / 2) / radius))
    # 5 m/s and 6 rad/s (the HIL demo asks such of its base): scaled down to the wheels' 10.15
    # rad/s by one factor, so the curvature ω/v stays.
    assert r.command(5.0, 0.0, 6.0, [0.0] * 8)
    left, right = r.wheel_target * r.wheel_sign
    assert max(abs(left), abs(right)) == pytest.approx(10.152284264)
    v, w = radius * (left + right) / 2, radius * (right - left) / track
    assert w / v == pytest.approx(6.0 / 5.0)


def test_the_tiago_drives_straight_at_the_commanded_speed_within_its_torque_limits(tmp_path):
    s, out = open_loop(tmp_path, "0.5:0,0;3:0.5,0", 3.5, *TIAGO)
    rows = np.genfromtxt(os.path.join(out, "timeseries.csv"), delimiter=",", names=True, dtype=None,
                         encoding=None)
    # Rolling: 0.5 m/s reached (6 N·m per wheel on 65 kg accelerate it at about 1.9 m/s²).
    assert rows["v_true"][-1] == pytest.approx(0.5, rel=0.01)
    assert abs(rows["omega_true"][-1]) < 0.01
    # No drive ever gave more than its URDF effort (MuJoCo's force limits): the load columns.
    loads = [c for c in rows.dtype.names if c.startswith("load_")]
    assert max(float(rows[c].max()) for c in loads) <= 1.0 + 1e-9
    assert s["saturation_fraction"]["wheel/left"] > 0, "the start asks for more than 6 N·m"
    assert s["wheel_slip"]["fraction_of_time"] < 0.01
    assert s["robot"]["wheels"] == {"left": "wheel_left_joint", "right": "wheel_right_joint",
                                    "radius": 0.0985, "track": pytest.approx(0.4044)}


def test_wheel_odometry_drifts_where_the_wheels_slip_and_the_drift_is_reported(tmp_path):
    gentle, _ = open_loop(tmp_path / "a", "1:0.3,0;2:0.3,0.3", 3, *TIAGO, "--base-from", "odometry")
    # Braking from 1 m/s at full torque: the wheels lose their load to the front casters and slip.
    hard, _ = open_loop(tmp_path / "b", "2:1.0,0;1:0,0", 3, *TIAGO, "--base-from", "odometry")
    assert gentle["odometry_drift"]["max_m"] < 0.01
    assert hard["wheel_slip"]["time_s"] > 0.05
    assert hard["odometry_drift"]["final_m"] > 10 * gentle["odometry_drift"]["final_m"]


def test_the_ur5_urdf_is_the_arm_file_and_another_arm_file_is_refused(tmp_path):
    a = plant.parse(["--arm", UR5_FILE, "--platform", "omni"])
    robot, chain, arm_hash = plant.build_robot(a, mujoco_robot.load_table())
    assert arm_hash == 0x9503B11C37A273FF  # the ur5 preset's (companion control prints it)
    bent = tmp_path / "ur5-longer-forearm.toml"
    bent.write_text(open(UR5_FILE).read().replace("xyz = [-0.39225, 0.0, 0.10915]", "xyz = [-0.4, 0.0, 0.10915]"))
    a = plant.parse(["--arm", str(bent), "--platform", "omni"])
    with pytest.raises(plant.wire.Fatal, match="is not the arm of"):
        plant.build_robot(a, mujoco_robot.load_table())


def test_the_lifted_target_is_the_reference_bridges():
    # The reference bridge integrates trajectory 1 with the platform, its own way.
    chain = plant.wire.Chain(UR5_FILE)
    ref = plant.wire.SpatialRobot(0.001, chain)
    mine = plant.LiftedTarget(1, 0.001, ref.height)
    zero = ref.zero_command()
    for k in range(3000):
        mine.advance(k * 0.001)
        ref.advance(zero, zero, 0.0)
    rot, pos, _, twist = mine.at(3.0)
    _, _, _, (rpos, rrot, _, rtwist) = ref.measure()
    assert np.abs(np.array(pos) - rpos).max() < 1e-14
    assert np.abs(np.array(rot) - rrot).max() < 1e-14
    assert np.abs(np.array(twist) - rtwist).max() < 1e-15


def test_trajectory_2_follows_table_1():
    # Table 1 of the paper, row by row: (start, u_d at the row's start).
    w = math.pi ** 2 / 20
    for t, u in [(0.0, (0, 0, 0)), (5.0, (0, 0, w)), (27.0, (0.2, 0, 0)), (37.0, (0, 0, w)), (59.0, (0, 0.05, 0)),
                 (99.0, (0, 0, 0)), (105.0, (-0.2, 0, 0)), (115.0, (0, 0, 0)), (120.0, (0, 0, 0))]:
        assert plant.table1(t)(t) == pytest.approx(u, abs=1e-15)


def test_the_actuator_table_is_overridden_by_name_and_a_typo_is_refused():
    g0 = tiago().gains
    g1 = tiago("arm.time_constant=0.0025", "joint.arm_7_joint.armature=0.03", "joint.arm_2_joint.kv=123.0").gains
    # kv = I / τ, I the joint's inertia with its drive's armature (the wrist's is nearly all
    # armature: 0.01 kg m² by default, its link 4e-5).
    assert g1["servo/arm_1_joint"] == pytest.approx(2 * g0["servo/arm_1_joint"])
    assert g0["servo/arm_7_joint"] == pytest.approx(0.01 / 0.005, rel=0.01)
    assert g1["servo/arm_7_joint"] == pytest.approx(0.03 / 0.0025, rel=0.01)
    assert g1["servo/arm_2_joint"] == 123.0
    with pytest.raises(mujoco_robot.ModelError, match="unknown key arm.time_constnat"):
        tiago("arm.time_constnat=0.01")


@pytest.mark.parametrize("joint, rate", [("arm_7_joint", 0.5), ("arm_7_joint", 0.02), ("arm_1_joint", 0.5),
                                         ("torso_lift_joint", 0.05)])
def test_a_servo_follows_a_step_of_its_rate_without_chatter(joint, rate):
    # The TIAGo's wrist link alone weighs 4e-5 kg m² against a URDF friction of 1 N m: a stiff
    # servo on it chattered (±4.8 rad/s each physics step, the joint still); with its drive's
    # armature and a PI servo it turns as commanded.
    r = tiago()
    m, d = r.model, r.data
    dof = m.jnt_dofadr[m.joint(joint).id]
    qa = m.jnt_qposadr[m.joint(joint).id]
    u = [0.0] * 8
    u[r.chain_names.index(joint)] = rate
    r.command(0.0, 0.0, 0.0, u)
    q0 = float(d.qpos[qa])
    rates = []
    for _ in range(400):  # 0.2 s
        r.substep()
        rates.append(float(d.qvel[dof]))
    assert min(rates[20:]) > 0.0, "the joint stopped or turned back after 10 ms: chatter"
    assert max(abs(x - rate) for x in rates[200:]) < 0.05 * rate  # after 100 ms
    assert float(d.qpos[qa]) - q0 == pytest.approx(0.2 * rate, rel=0.1)


def test_the_png_writer_makes_what_a_png_reader_reads(tmp_path):
    img = (np.arange(4 * 6 * 3) % 256).astype(np.uint8).reshape(4, 6, 3)
    path = tmp_path / "x.png"
    plant.png(str(path), img)
    from PIL import Image  # (matplotlib's dependency, in target/py)

    back = np.asarray(Image.open(path).convert("RGB"))
    assert (back == img).all()
    data = path.read_bytes()
    assert zlib.crc32(data[12:29]) == int.from_bytes(data[29:33], "big")  # IHDR's CRC


def plant_cli(*args):
    return subprocess.run([sys.executable, os.path.join(REPO, "bridges", "mujoco", "companion_mujoco.py"), *args],
                          capture_output=True, text=True)


def test_a_run_folder_that_is_a_file_is_refused_before_anything_runs(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    r = plant_cli("--open-loop", "1:0,0", "--duration", "1", "--out", str(f))
    assert r.returncode == 2
    assert f"--out {f} is a file" in r.stderr
    assert f.read_text() == "x"


@pytest.mark.parametrize("flags, says", [
    (["--home", "0.2,x"], "--home '0.2,x': comma-separated numbers"),
    (["--home", "0.2,1.0"], "--home gives 2 joints, the chain base_footprint -> arm_tool_link"),
    (["--home", "0.5,1.0,-0.5,-1.0,1.2,0.0,0.5,0.0"], "joint torso_lift_joint at 0.5 is outside its limits"),
    (["--tip-link", "no_such_link"], "no link named 'no_such_link'"),
    (["--set", "wheels.kv=1"], "unknown key wheels.kv"),
    (["--set", "arm.time_constant=-1"], "arm.time_constant must be a positive number"),
    (["--open-loop", "1:0"], "--open-loop '1:0': SECONDS:V,OMEGA[,V_LAT]"),
    (["--base-from", "odometry", "--platform", "omni"], "wheel odometry: a wheeled base"),
])
def test_bad_input_is_named_with_exit_2_and_nothing_written(tmp_path, flags, says):
    out = tmp_path / "run"
    args = dict(zip(TIAGO[::2], TIAGO[1::2]))
    args.update(zip(flags[::2], flags[1::2]))
    args.setdefault("--open-loop", "1:0,0")
    r = plant_cli(*[x for kv in args.items() for x in kv], "--duration", "1", "--out", str(out))
    assert r.returncode == 2, r.stderr
    assert says in r.stderr
    assert "Traceback" not in r.stderr
    assert not out.exists()


@pytest.mark.parametrize("ignore", [True, False])
def test_a_signal_while_python_shuts_down_cannot_kill_a_plant_that_ended(ignore):
    """The plant's last step, `exit_with(code)`: SIGINT and SIGTERM ignored before Python's
    shutdown, which puts SIG_DFL back in place of a Python handler (CPython's _PySignal_Fini;
    not in place of SIG_IGN). CI once saw a signal to the group land there: the plant died after
    writing its files, and `hil` reported a peer that died, exit 3. The shutdown is stood in for
    by an exit hook doing what _PySignal_Fini does, then a thread signalling the process: with
    `exit_with` the code stands; the control case (`sys.exit`) dies of the signal."""
    finish = "wire.exit_with(0)" if ignore else "sys.exit(0)"
    code = f"""
import atexit, os, signal, sys, threading
sys.path.insert(0, {os.path.join(REPO, "bridges", "python")!r})
import companion_bridge as wire
wire.install_signal_handlers()
def shutdown():
    for sig in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(sig) not in (signal.SIG_DFL, signal.SIG_IGN):
            signal.signal(sig, signal.SIG_DFL)
    t = threading.Thread(target=os.kill, args=(os.getpid(), signal.SIGTERM))
    t.start()
    t.join()
atexit.register(shutdown)
{finish}
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == (0 if ignore else -15), r.stderr
