"""`companion ros2` against Eclipse Cyclone DDS (PyPI `cyclonedds`, the middleware under
rmw_cyclonedds), with ROS 2's topic names, type names and CDR layouts, and no ROS installation.

- The message layouts: every struct of ros2_msgs.py against ROS 2's `.msg` definitions written
  out below (from the ROS 2 packages' `.msg` files), field by field, and their CDR bytes
  against an encoder driven by those definitions alone.
- The closed loop: bridges/ros2/standin_robot.py (a kinematic UR5 on a unicycle, in Python over
  Cyclone DDS) driven by the node in real time at 100 Hz and 1 kHz on lifted trajectory 1,
  run (a); the robot measures the tracking error itself. The tests hold it to a bound only a
  broken loop misses (1 cm); its precision (~1e-4 m, a real-time figure that load moves) is
  measured with its spread by bridges/ros2/precision.py, not asserted here.
- The safety rules: a stale, a malformed (a joint left out), a non-finite and a silent input
  each give the zero command while they last, counted in summary.json, and the run fails.

The node is `target/release/companion` built with `--features ros2` (scripts/test builds it;
COMPANION_ROS2_BIN names another).
"""

import json
import os
import random
import re
import signal
import struct
import subprocess
import sys
import time

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", "..", ".."))
sys.path.insert(0, os.path.join(HERE, ".."))

import ros2_msgs as m  # noqa: E402

STANDIN = os.path.join(HERE, "..", "standin_robot.py")
UR5 = os.path.join(ROOT, "examples", "arms", "ur5.toml")
TIAGO_CONFIG = os.path.join(ROOT, "examples", "arms", "tiago-unicycle.toml")
# The TIAGo at 1 kHz (its law settles lifted T1 (a) at 200 Hz too, not at 100 Hz: docs/book/src/ros2.md);
# TIAGO_RATE=200 measures the other.
TIAGO_RATE = int(os.environ.get("TIAGO_RATE", "1000"))
# The stand-in's commands arrive about 0.2 ms after the node sends them on this loopback
# (its `command_latency_ms` p50 measured 0.14–0.25 ms here): told to the node, as a user tells
# it their robot's controller cycle.
COMMAND_LATENCY = "0.0002"

# ----- ROS 2's definitions, from the packages' .msg files (comments and constants left out) --

MSG = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id",
    "sensor_msgs/JointState": "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1",
    "geometry_msgs/Pose": "Point position\nQuaternion orientation",
    "geometry_msgs/PoseWithCovariance": "Pose pose\nfloat64[36] covariance",
    "geometry_msgs/Twist": "Vector3 linear\nVector3 angular",
    "geometry_msgs/TwistWithCovariance": "Twist twist\nfloat64[36] covariance",
    "nav_msgs/Odometry": "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist",
    "geometry_msgs/PoseStamped": "std_msgs/Header header\nPose pose",
    "geometry_msgs/TwistStamped": "std_msgs/Header header\nTwist twist",
    "std_msgs/MultiArrayDimension": "string label\nuint32 size\nuint32 stride",
    "std_msgs/MultiArrayLayout": "MultiArrayDimension[] dim\nuint32 data_offset",
    "std_msgs/Float64MultiArray": "MultiArrayLayout layout\nfloat64[] data",
    "diagnostic_msgs/KeyValue": "string key\nstring value",
    "diagnostic_msgs/DiagnosticStatus": "byte level\nstring name\nstring message\nstring hardware_id\nKeyValue[] values",
    "diagnostic_msgs/DiagnosticArray": "std_msgs/Header header\nDiagnosticStatus[] status",
}  # fmt: skip

PRIMITIVE = {  # .msg type: (struct format, size)
    "int32": ("<i", 4), "uint32": ("<I", 4), "float64": ("<d", 8), "byte": ("<B", 1),
}  # fmt: skip


def fields(pkg_type):
    """The .msg's fields: (name, base type with package, array: None, -1 unbounded or n)."""
    pkg = pkg_type.split("/")[0]
    out = []
    for line in MSG[pkg_type].splitlines():
        typ, name = line.split()[:2]
        arr = None
        mm = re.fullmatch(r"(.+)\[(\d*)\]", typ)
        if mm:
            typ, arr = mm.group(1), int(mm.group(2)) if mm.group(2) else -1
        if typ not in PRIMITIVE and typ != "string" and "/" not in typ:
            typ = f"{pkg}/{typ}"
        out.append((name, typ, arr))
    return out


class Cdr:
    """CDR (XCDR1, little-endian) from the .msg definitions alone: each primitive aligned to
    its size from the start of the payload, strings as uint32 length with the NUL, sequences as
    uint32 count, fixed arrays as their elements."""

    def __init__(self):
        self.b = bytearray()

    def align(self, n):
        while len(self.b) % n:
            self.b.append(0)

    def prim(self, typ, v):
        fmt, n = PRIMITIVE[typ]
        self.align(n)
        self.b += struct.pack(fmt, v)

    def string(self, s):
        data = s.encode() + b"\0"
        self.prim("uint32", len(data))
        self.b += data

    def value(self, typ, v):
        if typ in PRIMITIVE:
            self.prim(typ, v)
        elif typ == "string":
            self.string(v)
        else:
            for name, t, arr in fields(typ):
                x = getattr(v, name)
                if arr is None:
                    self.value(t, x)
                else:
                    if arr == -1:
                        self.prim("uint32", len(x))
                    else:
                        assert len(x) == arr, (typ, name)
                    for e in x:
                        self.value(t, e)


def encode(typ, v):
    c = Cdr()
    c.value(typ, v)
    return bytes(c.b)


PY_TYPE = {cls.__idl_typename__: cls for cls in m.ALL}


def idl_class(pkg_type):
    pkg, name = pkg_type.split("/")
    return PY_TYPE[f"{pkg}::msg::dds_::{name}_"]


def test_every_struct_has_the_fields_of_its_msg_in_order():
    import typing

    from cyclonedds.idl import types as t

    assert sorted(PY_TYPE) == sorted(f"{k.split('/')[0]}::msg::dds_::{k.split('/')[1]}_" for k in MSG)
    for pkg_type in MSG:
        cls = idl_class(pkg_type)
        hints = typing.get_type_hints(cls, include_extras=True)
        got = list(hints)
        want = [f[0] for f in fields(pkg_type)]
        assert got == want, pkg_type
        for name, typ, arr in fields(pkg_type):
            h = hints[name]
            meta = getattr(h, "__metadata__", (None,))[0]
            if arr == -1:
                assert isinstance(meta, t.sequence), (pkg_type, name, h)
                inner = meta.subtype
            elif arr is not None:
                assert isinstance(meta, t.array) and meta.length == arr, (pkg_type, name, h)
                inner = meta.subtype
            else:
                inner = h
            if typ == "string":
                assert inner is str, (pkg_type, name, inner)
            elif typ in PRIMITIVE:
                want_t = {"int32": t.int32, "uint32": t.uint32, "float64": t.float64, "byte": t.byte}[typ]
                assert inner == want_t, (pkg_type, name, inner)
            else:
                assert inner is idl_class(typ), (pkg_type, name, inner)


def sample(pkg_type, k=1):
    """A value of every field, different from the defaults."""
    cls = idl_class(pkg_type)
    kw = {}
    for i, (name, typ, arr) in enumerate(fields(pkg_type)):
        def one(j):
            if typ == "string":
                return f"{name}{j}" * (j % 3 + 1)
            if typ in ("int32",):
                return -7 * (i + j + k)
            if typ in ("uint32", "byte"):
                return (3 * (i + j + k)) % 250
            if typ == "float64":
                return 0.5 * (i + 1) + j * 1.25 - k
            return sample(typ, k + i + j)

        kw[name] = one(0) if arr is None else [one(j) for j in range(arr if arr > 0 else 3)]
    return cls(**kw)


@pytest.mark.parametrize("pkg_type", list(MSG))
def test_cyclone_bytes_are_the_msg_definitions_cdr(pkg_type):
    v = sample(pkg_type)
    raw = v.serialize()
    # The 4-byte encapsulation header: CDR little-endian (XCDR1), as rmw_cyclonedds writes.
    assert raw[:4] == b"\x00\x01\x00\x00", raw[:4]
    assert raw[4:] == encode(pkg_type, v)
    assert type(v).deserialize(raw) == v


# ----- the node against the stand-in ----------------------------------------------------------


def next_domain():
    """A ROS_DOMAIN_ID drawn at random (as test_rclpy.py's)."""
    return str(random.SystemRandom().randrange(1, 233))


def closed_loop(node_bin, tmp_path, rate, duration, target="node", inject=None, node_extra=(), rt=True,
                arm=UR5, node_arm="ur5", standin_extra=()):
    """Starts the stand-in, runs the node to its end (`--duration`), then stops the stand-in
    (SIGINT: it writes its figures). Returns (node exit code, node summary, stand-in figures,
    node output)."""
    domain = next_domain()
    out = tmp_path / "standin.json"
    standin = [sys.executable, STANDIN, "--arm", arm, "--rate", str(rate), "--domain-id", domain,
               "--target", target, "--final-at", str(duration), "--out", str(out), *standin_extra]  # fmt: skip
    if inject:
        standin += ["--inject", inject]
    pre = []
    if rt and os.geteuid() == 0:
        pre = ["chrt", "-f", "50"]
    robot = subprocess.Popen(pre + standin, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        cmd = [node_bin, "ros2", "--arm", node_arm, "--dt", str(1.0 / rate), "--duration", str(duration),
               "--domain-id", domain, "--target", "trajectory" if target == "node" else "topics",
               "--command-latency", COMMAND_LATENCY, "--startup-timeout", "30", "--out", str(tmp_path / "node")]  # fmt: skip
        if rt:
            cmd.append("--rt")
        cmd += list(node_extra)
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=duration + 120)
    finally:
        robot.send_signal(signal.SIGINT)
        log, _ = robot.communicate(timeout=60)
    assert robot.returncode == 0, log
    summary = json.loads((tmp_path / "node" / "summary.json").read_text())
    figures = json.loads(out.read_text())
    return r.returncode, summary, figures, r.stdout + r.stderr


@pytest.mark.parametrize("rate", [100, 1000])
def test_the_node_tracks_lifted_trajectory_1_with_the_ur5_on_the_unicycle(node_bin, tmp_path, rate):
    # Late periods are the machine's (a figure, precision.py's): not held against the run here.
    code, s, f, log = closed_loop(node_bin, tmp_path, rate, 15.0, node_extra=("--max-miss-fraction", "1"))
    print(json.dumps({"rate": rate, "node": {k: s[k] for k in ("periods", "steps", "zero_commands", "late",
          "skipped_releases", "final_ep_norm", "measurement_age_ns", "failures")}, "robot": f}, indent=1))  # fmt: skip
    # The node ran its 15 s at the rate, the law stepped on every period but a few, and the
    # robot received every command in ROS 2's layout (its length the arm's).
    assert s["end"] == "completed" and abs(s["duration_s"] - 15.0) < 0.5, log
    assert s["steps"] >= 0.9 * 15.0 * rate and s["rejections"]["singular_arm"] == 0, s
    assert f["joint_commands"] >= s["periods"] and f["bad_command_length"] == 0, f
    # The node's generated target is lifted trajectory 1 from where the robot stood, to 1e-6 m.
    assert f["target_messages"] >= s["steps"] * 0.9 and f["target_max_deviation"] < 1e-6, f
    # Its diagnostics arrived, at their 10 Hz.
    assert f["diagnostics"] >= 100, f
    # Tracking, by the robot's own kinematics: within 1 cm at the end and in the last 2 s, a
    # bound only a broken loop misses (the aim, 1e-4 m, is precision.py's figure).
    assert f["final_position_error"] < 1e-2 and f["max_position_error_last_2_s"] < 1e-2, f
    assert code == 0, log


def test_the_target_read_from_topics_is_tracked(node_bin, tmp_path):
    code, s, f, log = closed_loop(node_bin, tmp_path, 100, 15.0, target="topics",
                                  node_extra=("--max-miss-fraction", "1"))  # fmt: skip
    print(json.dumps({"node": s["final_ep_norm"], "robot": f}, indent=1))
    assert s["topics"]["target_twist"] == "/companion/target_twist"
    assert s["input_faults"]["stale"]["target_pose"] == 0
    assert f["final_position_error"] < 1e-2 and f["max_position_error_last_2_s"] < 1e-2, f
    assert code == 0, log


@pytest.mark.parametrize(
    "kind, cause, input_",
    [
        ("stale", "stale", "joint_states"),
        ("names", "malformed", "joint_states"),
        ("nan", "non_finite", "joint_states"),
        ("silent", "silent", "joint_states"),
    ],
)
def test_a_bad_input_gives_the_zero_command_while_it_lasts(node_bin, tmp_path, kind, cause, input_):
    rate, at, length = 100, 3.0, 0.5
    code, s, f, log = closed_loop(node_bin, tmp_path, rate, 6.0, inject=f"{kind}@{at}")
    print(json.dumps({"faults": s["input_faults"], "robot": f}, indent=1))
    zero_in, nonzero_in = f["commands_in_fault"]
    zero_after, nonzero_after = f["commands_after_fault"]
    # Every command while the fault lasted was zero, and tracking resumed after it (the zeros
    # after it: the node's, sent every period for 0.1 s as it ends).
    assert nonzero_in == 0 and zero_in >= 0.8 * (length - 0.05) * rate, f
    assert nonzero_after >= 1.5 * rate and zero_after <= 0.1 * rate + 2, f
    # Counted by cause and input: about one period each for the fault's length.
    n = s["input_faults"][cause][input_]
    assert 0.8 * length * rate <= n <= 1.3 * length * rate + 3, (n, s["input_faults"])
    assert s["zero_commands"] == sum(sum(v.values()) for k, v in s["input_faults"].items() if k != "undecodable")
    # 50 zero periods of 600 are more than --max-miss-fraction 0.05: the run failed, exit 7.
    assert code == 7 and any("zero commands for an input fault" in x for x in s["failures"]), log


@pytest.mark.parametrize("sig, name", [(signal.SIGINT, "SIGINT"), (signal.SIGTERM, "SIGTERM")])
def test_a_termination_signal_ends_the_run_with_the_zero_command_and_the_summary(node_bin, tmp_path, sig, name):
    domain = next_domain()
    out = tmp_path / "standin.json"
    robot = subprocess.Popen([sys.executable, STANDIN, "--arm", UR5, "--rate", "100", "--domain-id", domain,
                              "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)  # fmt: skip
    node = subprocess.Popen([node_bin, "ros2", "--arm", "ur5", "--dt", "0.01", "--domain-id", domain,
                             "--startup-timeout", "30", "--out", str(tmp_path / "node")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        # The counted state: the node says it runs (every input arrived); then the signal.
        seen = []
        for line in node.stderr:
            seen.append(line)
            if "every input arrived; running until SIGINT or SIGTERM" in line:
                break
        assert seen and "running" in seen[-1], seen
        node.send_signal(sig)
        rest, err = node.communicate(timeout=30)
    finally:
        if node.poll() is None:
            node.kill()
        robot.send_signal(signal.SIGINT)
        log, _ = robot.communicate(timeout=60)
    assert node.returncode == 130, (name, err)
    s = json.loads((tmp_path / "node" / "summary.json").read_text())
    f = json.loads(out.read_text())
    assert s["end"] == "interrupted" and s["periods"] == s["steps"] >= 1, s
    # The robot's last command: the zero the node sent as it ended.
    assert f["nonzero_commands"] >= 1 and f["last_command_zero"] is True, f


NAMES = "j_base,j_shoulder,j_elbow,j_wrist_1,j_wrist_2,j_wrist_3"


@pytest.mark.parametrize(
    "node_arm, arm, joints, names",
    [
        ("rpr", "rpr", 3, "rpr_joint_1,rpr_joint_2,rpr_joint_3"),
        ("panda", os.path.join(ROOT, "examples", "arms", "panda.toml"), 7, ",".join(f"panda_joint{i}" for i in range(1, 8))),
        (UR5, UR5, 6, NAMES),
    ],
    ids=["rpr", "panda", "ur5-file"],
)
def test_the_node_drives_every_arm_the_cli_knows(node_bin, tmp_path, node_arm, arm, joints, names):
    extra = ("--joint-names", names) if node_arm == UR5 else ()
    code, s, f, log = closed_loop(node_bin, tmp_path, 100, 3.0, node_arm=node_arm, arm=arm,
                                  node_extra=extra, standin_extra=("--joint-names", names))  # fmt: skip
    # Every period a step of the law, none rejected; every command of the arm's length, moving it.
    assert s["joint_names"] == names.split(",") and s["end"] == "completed", s
    rejected = sum(sum(v) if isinstance(v, list) else v for v in s["rejections"].values())
    assert s["steps"] == s["periods"] >= 290 and rejected == 0, s
    assert f["joint_commands"] >= s["periods"] and f["bad_command_length"] == 0 and f["nonzero_commands"] > 250, f
    assert code == 0, log


def tiago_urdf():
    """example-robot-data's TIAGo (PyPI, installed into target/py by scripts/setup)."""
    for d in sys.path:
        p = os.path.join(d, "cmeel.prefix", "share", "example-robot-data", "robots", "tiago_description",
                         "robots", "tiago_no_hand.urdf")  # fmt: skip
        if os.path.isfile(p):
            return p
    pytest.fail("example-robot-data's TIAGo URDF is not installed here: run scripts/setup")


def test_the_tiago_from_its_urdf_tracks_lifted_trajectory_1_on_its_own_base(node_bin, tmp_path):
    # The node reads the URDF and examples/arms/tiago-unicycle.toml ([robot]: the links and the
    # home by joint name; the transverse function); the stand-in reads the same URDF with the
    # reference bridge's own reader and the same home, and publishes the TIAGo's head joint too.
    import tomllib

    urdf = tiago_urdf()
    with open(TIAGO_CONFIG, "rb") as fh:
        robot = tomllib.load(fh)["robot"]
    home = ",".join(f"{k}={v}" for k, v in robot["home"].items())
    duration = 20.0
    code, s, f, log = closed_loop(node_bin, tmp_path, TIAGO_RATE, duration, node_arm=urdf, arm=urdf,
                                  node_extra=("--config", TIAGO_CONFIG, "--max-miss-fraction", "1"),
                                  standin_extra=("--base-link", robot["base_link"], "--tip-link", robot["tip_link"],
                                                 "--home", home))  # fmt: skip
    print(json.dumps({"node": {k: s[k] for k in ("periods", "steps", "late", "final_ep_norm")}, "robot": f}, indent=1))
    # The torso and the seven arm joints by the URDF's names; the head ignored.
    assert s["joint_names"] == ["torso_lift_joint"] + [f"arm_{i}_joint" for i in range(1, 8)], s
    assert s["end"] == "completed" and s["steps"] >= 0.9 * duration * TIAGO_RATE, log
    assert f["joint_commands"] >= s["periods"] and f["bad_command_length"] == 0, f
    assert f["target_max_deviation"] < 1e-6, f
    # Tracking within 1 cm at the end, by the robot's own kinematics: a bound only a broken loop
    # misses (its precision, 2e-5 to 1.2e-4 m in runs here, is a real-time figure: ros2.md).
    assert f["final_position_error"] < 1e-2 and f["max_position_error_last_2_s"] < 1e-2, f
    assert code == 0, log
