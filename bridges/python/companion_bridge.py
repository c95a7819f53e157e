#!/usr/bin/env python3
"""The reference bridge: a replacement for `companion plant`, in Python.

Written from docs/book/src/bridge.md alone (protocol version 4) with the official iceoryx2 binding
(`pip install iceoryx2==0.10.0`). It plays the plant: it simulates the paper's unicycle with
its RPR arm tracking trajectory 1 — or, with `--arm FILE`, an arm file's chain of 6 to 8
joints tracking trajectory 1 lifted into space (docs/book/src/bridge.md §8) — (a bridge to hardware
would read its sensors in `measure()` and drive its motors in `advance()`), publishes one
measurement per period, applies the controller's answer from the moment it arrives, and
reports the measured delay.

    companion control --name demo --duration 5 &
    python3 bridges/python/companion_bridge.py --name demo --duration 5            # real time
    python3 bridges/python/companion_bridge.py --name demo --duration 5 --lockstep

    companion control --name demo --arm ur5 &
    python3 bridges/python/companion_bridge.py --name demo --arm examples/arms/ur5.toml

It also injects faults for the tests (`--help`). Exit codes as `companion plant`: 0 the run
completed, 2 an error or the controller refused this plant, 3 the controller died or left,
4 the controller is alive but silent, 101 a bug (an unexpected exception: its traceback is
printed, the files are written), 130 interrupted. SIGINT and SIGTERM — one or many, at any
moment, also while the files are written — end the run as `companion plant` ends it: the next
period is the last (END_OF_RUN), its answer awaited a second at most, then the files are
written and the bridge exits 130.
"""

import argparse
import ctypes
import json
import math
import random
import signal
import statistics
import struct
import sys
import time
import tomllib

import iceoryx2 as iox

# ----- the wire (docs/book/src/bridge.md §3) ---------------------------------------------------------

PROTOCOL_VERSION = 4
MAX_JOINTS = 8
PREFIX = "companion_"

END_OF_RUN, LOCKSTEP, STOPPED, NOTIFIES = 1, 2, 4, 8
PLATFORMS = {"unicycle": 1, "car": 2, "omni": 3}
PLATFORM_NAMES = {1: "unicycle", 2: "car-like", 3: "omnidirectional"}
PLANAR, SPATIAL = 1, 2
SPACE_NAMES = {PLANAR: "planar (SE(2))", SPATIAL: "spatial (SE(3))"}
REFUSALS = {
    0x8001: "protocol version",
    0x8002: "joint count",
    0x8003: "platform",
    0x8004: "scenario",
    0x8005: "period (dt)",
    0x8006: "target space",
    0x8007: "arm",
}

EXIT_OK, EXIT_ERROR, EXIT_PEER_LOST, EXIT_PEER_HUNG, EXIT_INTERRUPTED = 0, 2, 3, 4, 130
# An unexpected exception: a bug (companion's code for a panic, docs/book/src/hil.md).
EXIT_BUG = 101
# How long an interrupted run waits for the answer to its last measurement (s), as `companion
# control` keeps answering for a second after its own signal.
INTERRUPT_GRACE_S = 1.0

# ----- SIGINT and SIGTERM: recorded, acted on between periods -------------------------------
# The handler only records the signal: the loops look at it once a period and end the run there,
# so a second signal (a terminal's Ctrl-C reaches the plant and the controller, which forwards a
# SIGTERM) never lands in the middle of writing the files.

SIGNALS = {"first": None, "count": 0, "at": None}


def on_signal(signum, _frame=None):
    """Records SIGINT or SIGTERM (the first one's number and time, and how many came)."""
    SIGNALS["count"] += 1
    if SIGNALS["first"] is None:
        SIGNALS["first"] = signum
        SIGNALS["at"] = time.monotonic()


def install_signal_handlers():
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)


def exit_with(code):
    """Exits with `code`, SIGINT and SIGTERM ignored from here on: the run has ended and said
    so. Python's own shutdown puts the default handler back in place of a Python one (not of
    SIG_IGN) before the process ends: a signal in that window killed the plant after its files
    were written, and `hil` saw a peer that died (exit 3, not the run's 0). (Ignored, not
    blocked: a mask is a thread's, and MuJoCo's and numpy's threads would take the signal.)"""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)
    sys.exit(code)


def stop_requested():
    """Whether SIGINT or SIGTERM came."""
    return SIGNALS["first"] is not None


def stop_waited():
    """Seconds since the first signal (0 without one)."""
    return time.monotonic() - SIGNALS["at"] if SIGNALS["at"] is not None else 0.0


class Interrupted(Exception):
    """SIGINT or SIGTERM before the run could end at a period (waiting for the controller to
    join, or for an answer): the bridge exits 130."""


def _type_name(name):
    return staticmethod(lambda: name)


class Measurement(ctypes.Structure):
    """MeasurementMsg, 344 bytes, little-endian, no padding."""

    _fields_ = [
        ("version", ctypes.c_uint32),
        ("flags", ctypes.c_uint32),
        ("seq", ctypes.c_uint64),
        ("session", ctypes.c_uint64),
        ("scenario_hash", ctypes.c_uint64),
        ("arm_hash", ctypes.c_uint64),
        ("plant_time_ns", ctypes.c_uint64),
        ("period_ns", ctypes.c_uint64),
        ("sim_time", ctypes.c_double),
        ("dt", ctypes.c_double),
        ("delay", ctypes.c_double),
        ("platform", ctypes.c_uint32),
        ("hold_periods", ctypes.c_uint32),
        ("joint_count", ctypes.c_uint32),
        ("space", ctypes.c_uint32),
        ("base", ctypes.c_double * 3),
        ("steering", ctypes.c_double),
        ("target_position", ctypes.c_double * 3),
        ("target_rotation", ctypes.c_double * 9),
        ("target_yaw", ctypes.c_double),
        ("target_twist", ctypes.c_double * 6),
        ("joints", ctypes.c_double * MAX_JOINTS),
    ]
    type_name = _type_name("companion::MeasurementV4")


class Command(ctypes.Structure):
    """CommandMsg, 248 bytes."""

    _fields_ = [
        ("version", ctypes.c_uint32),
        ("status", ctypes.c_uint32),
        ("seq", ctypes.c_uint64),
        ("session", ctypes.c_uint64),
        ("plant_time_ns", ctypes.c_uint64),
        ("compute_ns", ctypes.c_uint64),
        ("received_ns", ctypes.c_uint64),
        ("skipped", ctypes.c_uint32),
        ("joint_count", ctypes.c_uint32),
        ("flags", ctypes.c_uint32),
        ("platform", ctypes.c_uint32),
        ("scenario_hash", ctypes.c_uint64),
        ("arm_hash", ctypes.c_uint64),
        ("space", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
        ("delay", ctypes.c_double),
        ("v", ctypes.c_double),
        ("v_lat", ctypes.c_double),
        ("omega", ctypes.c_double),
        ("v_xi", ctypes.c_double),
        ("joints", ctypes.c_double * MAX_JOINTS),
        ("ep_norm", ctypes.c_double),
        ("h_s", ctypes.c_double),
        ("psi", ctypes.c_double),
        ("saturation", ctypes.c_double),
        ("alpha_rate", ctypes.c_double * 2),
        ("joint_scale", ctypes.c_double),
    ]
    type_name = _type_name("companion::CommandV4")


class CommandWithoutJointScale(ctypes.Structure):
    """(tests) CommandMsg as a bridge with a wrong declaration would have it: its last field
    missing (240 bytes) under the type name. iceoryx2 compares name, size and alignment, so
    the two never connect."""

    _fields_ = Command._fields_[:-1]
    type_name = _type_name("companion::CommandV4")


assert ctypes.sizeof(Measurement) == 344 and ctypes.alignment(Measurement) == 8
assert ctypes.sizeof(Command) == 248 and ctypes.alignment(Command) == 8
assert Measurement.target_yaw.offset == 224 and Measurement.joints.offset == 280
assert Command.joints.offset == 128 and Command.joint_scale.offset == 240


def known_status(code):
    """Whether a command status is one the protocol defines (docs/book/src/bridge.md, status codes)."""
    return (
        code in (0, 0x200, 0x400, 0x500, 0x600, 0x700, 0x800)
        or 0x100 <= code <= 0x105
        or 0x300 <= code < 0x300 + MAX_JOINTS
    )


def is_refusal(code):
    return code & 0xFF00 == 0x8000


# ----- the scenario hash (docs/book/src/bridge.md, "The scenario hash") ------------------------------


def canonical_text(value):
    lines = []

    def walk(v, path):
        def join(key):
            return key if path == "" else path + "." + key

        if v is None:
            return
        if isinstance(v, bool):
            lines.append(f"{path}={'true' if v else 'false'}\n")
        elif isinstance(v, (int, float)) and not math.isfinite(v):
            return  # JSON has no infinity: a continuous joint's limits are null, as companion writes them
        elif isinstance(v, (int, float)):
            bits = struct.unpack("<Q", struct.pack("<d", float(v)))[0]
            lines.append(f"{path}={bits:016x}\n")
        elif isinstance(v, str):
            lines.append(f"{path}={v}\n")
        elif isinstance(v, list):
            for i, e in enumerate(v):
                walk(e, join(str(i)))
        elif isinstance(v, dict):
            for k, e in v.items():
                walk(e, join(k))

    walk(value, "")
    return "".join(sorted(lines, key=lambda s: s.encode()))


def fnv1a(data):
    h = 0xCBF29CE484222325
    for b in data:
        h ^= b
        h = (h * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


def scenario_hash(value):
    return fnv1a(canonical_text(value).encode()) or 1


def rpr_arm_description():
    """The paper's RPR arm as docs/book/src/bridge.md ("The arm hash") describes it."""
    identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]

    def frame(x):
        return {"rotation": identity, "translation": [x, 0.0, 0.0]}

    def joint(kind, axis, lower, upper):
        return {"kind": kind, "origin": frame(0.0), "axis": axis, "lower": lower, "upper": upper}

    vertical = [0.0, 0.0, 1.0]
    return {
        "mount": frame(0.4),
        "joints": [
            joint("revolute", vertical, -math.pi / 3.0, math.pi / 3.0),
            joint("prismatic", [1.0, 0.0, 0.0], 0.0, 0.7),
            joint("revolute", vertical, -math.pi / 2.0, math.pi / 2.0),
        ],
        "tool": frame(0.15),
    }


def arm_hash(description):
    """The arm hash: the canonical hash of the description with every negative zero written as
    zero (docs/book/src/bridge.md, "The arm hash")."""

    def positive_zeros(v):
        if isinstance(v, float):
            return v + 0.0
        if isinstance(v, list):
            return [positive_zeros(e) for e in v]
        if isinstance(v, dict):
            return {k: positive_zeros(e) for k, e in v.items()}
        return v

    return scenario_hash(positive_zeros(description))


RPR_ARM_HASH = arm_hash(rpr_arm_description())
RPR_LIMITS = [(-math.pi / 3.0, math.pi / 3.0), (0.0, 0.7), (-math.pi / 2.0, math.pi / 2.0)]


def planar_target(pose, velocity):
    """A planar target on the wire (docs/book/src/bridge.md, the target): position, rotation R_z(θ)
    row by row, the exact yaw, the 6-DOF body twist."""
    x, y, th = pose
    s, c = math.sin(th), math.cos(th)
    return (x, y, 0.0), (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0), th, (velocity[0], velocity[1], 0.0, 0.0, 0.0, velocity[2])


# ----- the robot: the paper's unicycle and RPR arm, trajectory 1 (docs/book/src/bridge.md §8) ------

L, L_E = 0.4, 0.15
TARGET_IN_EFFECTOR = (0.5, 0.0, 0.0)
SIGN_SPEED = 1e-3


def wrap(a):
    if -math.pi < a <= math.pi:
        return a
    w = a - 2 * math.pi * round(a / (2 * math.pi))
    if w <= -math.pi:
        w += 2 * math.pi
    elif w > math.pi:
        w -= 2 * math.pi
    return w


def between(a, b):
    """a⁻¹ · b for poses (x, y, θ)."""
    s, c = math.sin(a[2]), math.cos(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return (c * dx + s * dy, -s * dx + c * dy, wrap(b[2] - a[2]))


def compose(a, b):
    s, c = math.sin(a[2]), math.cos(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


def target_velocity(t):
    """Trajectory 1: u_d(t) = −(π/20) (sin(πt/2), cos(πt/2), 0)."""
    k = math.pi / 20.0
    a = math.pi * t / 2.0
    return (-k * math.sin(a), -k * math.cos(a), 0.0)


class Robot:
    """Unicycle + RPR arm + target, integrated by RK4 under a held command.

    What the session loops ask of a robot (another plant — bridges/mujoco — gives the same):
    `measure()`, `advance(previous, command, delay)`, `tracking_error()`, `t`, `base`, `q`,
    `limits`, `space`, `arm_hash`, and the commands it takes: `command_of(c)` (a checked
    CommandMsg; its first two entries v and ω) and `zero_command()`."""

    space = PLANAR
    limits = RPR_LIMITS

    def __init__(self, dt):
        self.dt = dt
        self.step = 0
        self.base = (0.0, 0.0, 0.0)
        self.q = (0.0, 0.35, 0.0)
        self.target = compose(self.base, (2.6, 1.0, 0.0))
        self.arm_hash = RPR_ARM_HASH

    @property
    def t(self):
        return self.step * self.dt

    def command_of(self, c):
        return command_of(c, len(self.q))

    def zero_command(self):
        return zero_command(len(self.q))

    def measure(self):
        """Time, platform, joints and the target as the wire carries it."""
        return self.t, self.base, self.q, planar_target(self.target, target_velocity(self.t))

    def tracking_error(self):
        q1, q2, q3 = self.q
        s13, c13 = math.sin(q1 + q3), math.cos(q1 + q3)
        s3, c3 = math.sin(q3), math.cos(q3)
        r_eb = (-L * c13 - q2 * c3 - L_E, L * s13 + q2 * s3, -q1 - q3)
        r_ed = compose(r_eb, between(self.base, self.target))
        e = between(TARGET_IN_EFFECTOR, r_ed)
        return math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])

    @staticmethod
    def _derivative(t, base_theta, target_theta, cmd):
        v, omega, uq = cmd
        sb, cb = math.sin(base_theta), math.cos(base_theta)
        ud = target_velocity(t)
        st, ct = math.sin(target_theta), math.cos(target_theta)
        return (
            (cb * v, sb * v, omega),
            (ct * ud[0] - st * ud[1], st * ud[0] + ct * ud[1], ud[2]),
        )

    def _rk4(self, t0, t1, cmd):
        h = t1 - t0
        half = 0.5 * h
        tm = t0 + half
        b, d = self.base, self.target
        kb1, kd1 = self._derivative(t0, b[2], d[2], cmd)
        kb2, kd2 = self._derivative(tm, b[2] + half * kb1[2], d[2] + half * kd1[2], cmd)
        kb3, kd3 = self._derivative(tm, b[2] + half * kb2[2], d[2] + half * kd2[2], cmd)
        kb4, kd4 = self._derivative(t1, b[2] + h * kb3[2], d[2] + h * kd3[2], cmd)
        w = h / 6.0

        def step(x, k1, k2, k3, k4):
            return tuple(x[i] + w * (((k1[i] + 2.0 * k2[i]) + 2.0 * k3[i]) + 1.0 * k4[i]) for i in range(3))

        self.base = step(b, kb1, kb2, kb3, kb4)
        self.target = step(d, kd1, kd2, kd3, kd4)
        self.q = tuple(self.q[i] + h * cmd[2][i] for i in range(len(self.q)))

    def advance(self, previous, command, delay):
        """One period: `previous` for the first `delay` seconds, then `command`."""
        t0 = self.step * self.dt
        t1 = (self.step + 1) * self.dt
        if delay > 0.0:
            ts = t0 + delay
            self._rk4(t0, ts, previous)
            self._rk4(ts, t1, command)
        else:
            self._rk4(t0, t1, command)
        self.step += 1


class SpatialRobot(Robot):
    """The unicycle carrying an arm file's chain, tracking trajectory 1 lifted (§8): the
    planar motion integrated as the planar robot's, at the height where the arm at home holds
    the target at r*_ed, plus a 5 cm vertical sine over 10 s. The joints start at home."""

    space = SPATIAL

    def __init__(self, dt, chain):
        super().__init__(dt)
        self.chain = chain
        self.q = tuple(j[5] for j in chain.joints)
        self.limits = [(j[3], j[4]) for j in chain.joints]
        self.arm_hash = arm_hash(chain.description())
        home = chain.end_effector(self.q)
        # r*_ed: TARGET_DISTANCE along the flange's z, level when the arm is at home.
        self.star = (transpose(home[0]), (0.0, 0.0, TARGET_DISTANCE))
        self.height = compose3(home, self.star)[1][2]

    def z(self, t):
        return self.height + LIFT_AMPLITUDE * math.sin(2.0 * math.pi * t / LIFT_PERIOD)

    def z_rate(self, t):
        w = 2.0 * math.pi / LIFT_PERIOD
        return LIFT_AMPLITUDE * w * math.cos(w * t)

    def target_pose(self):
        x, y, th = self.target
        return about_axis(2, math.sin(th), math.cos(th)), (x, y, self.z(self.t))

    def measure(self):
        t = self.t
        rotation, position = self.target_pose()
        u = target_velocity(t)
        twist = (u[0], u[1], self.z_rate(t), 0.0, 0.0, u[2])
        yaw = math.atan2(rotation[3], rotation[0])
        return t, self.base, self.q, (position, rotation, yaw, twist)

    def tracking_error(self):
        """‖e_p‖ of e_p = (p̃, log R̃), r̃ = (r*_ed)⁻¹ r_ed, r_ed = (r_b r_be(q))⁻¹ r_d."""
        effector = compose3(planar_pose3(self.base), self.chain.end_effector(self.q))
        r = compose3(inverse3(self.star), compose3(inverse3(effector), self.target_pose()))
        phi = so3_log(r[0])
        return math.sqrt(sum(x * x for x in r[1]) + sum(x * x for x in phi))


def zero_command(joints):
    """No motion: the safe command of a robot with `joints` joints."""
    return (0.0, 0.0, (0.0,) * joints)


def command_of(c, joints):
    """The velocities of a checked command: zero when the law rejected the step."""
    if c.status != 0:
        return zero_command(joints)
    return (c.v, c.omega, tuple(c.joints[i] for i in range(joints)))


# ----- a spatial arm (docs/book/src/bridge.md §8): an arm file's chain, trajectory 1 lifted ---------
# Poses in SE(3) are (R, p): R a 3×3 rotation as a 9-tuple row by row, p a 3-tuple.

IDENTITY = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
TARGET_DISTANCE = 0.2
LIFT_AMPLITUDE, LIFT_PERIOD = 0.05, 10.0


def mat_mul(a, b):
    return tuple(
        a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j] for i in range(3) for j in range(3)
    )


def mat_vec(a, v):
    return tuple(a[3 * i] * v[0] + a[3 * i + 1] * v[1] + a[3 * i + 2] * v[2] for i in range(3))


def transpose(a):
    return (a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8])


def compose3(a, b):
    """a · b."""
    t = mat_vec(a[0], b[1])
    return mat_mul(a[0], b[0]), (a[1][0] + t[0], a[1][1] + t[1], a[1][2] + t[2])


def inverse3(a):
    rt = transpose(a[0])
    t = mat_vec(rt, a[1])
    return rt, (-t[0], -t[1], -t[2])


def about_axis(axis, s, c):
    """The rotation by the angle of sine s and cosine c about axis 0 (x), 1 (y) or 2 (z)."""
    if axis == 0:
        return (1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
    if axis == 1:
        return (c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
    return (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)


def exact_sincos(a):
    """sin a, cos a with values within 4 ε of 0 or ±1 rounded to them (right angles exact)."""
    tiny = 4.0 * sys.float_info.epsilon

    def snap(x):
        for v in (0.0, 1.0, -1.0):
            if abs(x - v) <= tiny:
                return v
        return x

    return snap(math.sin(a)), snap(math.cos(a))


def from_rpy(roll, pitch, yaw):
    """R_z(yaw) R_y(pitch) R_x(roll), as an arm file's `rpy`."""
    return mat_mul(
        mat_mul(about_axis(2, *exact_sincos(yaw)), about_axis(1, *exact_sincos(pitch))),
        about_axis(0, *exact_sincos(roll)),
    )


def so3_exp(phi):
    """exp [φ]× (Rodrigues)."""
    th = math.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    if th < 1e-12:
        return IDENTITY
    x, y, z = phi[0] / th, phi[1] / th, phi[2] / th
    s, c = math.sin(th), math.cos(th)
    v = 1.0 - c
    return (
        c + x * x * v, x * y * v - z * s, x * z * v + y * s,
        x * y * v + z * s, c + y * y * v, y * z * v - x * s,
        x * z * v - y * s, y * z * v + x * s, c + z * z * v,
    )  # fmt: skip


def so3_log(r):
    """The rotation vector of R (|φ| ≤ π)."""
    v = ((r[7] - r[5]) * 0.5, (r[2] - r[6]) * 0.5, (r[3] - r[1]) * 0.5)
    c = (r[0] + r[4] + r[8] - 1.0) * 0.5
    s = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    th = math.atan2(s, c)
    if c > -0.9:
        k = th / s if s > 0.0 else 1.0
        return (v[0] * k, v[1] * k, v[2] * k)
    # Near π: the axis from the largest diagonal entry of (sym(R) − cos θ I) / (1 − cos θ).
    d = [(r[4 * i] - c) / (1.0 - c) for i in range(3)]
    k = max(range(3), key=lambda i: d[i])
    n = [0.0, 0.0, 0.0]
    n[k] = math.sqrt(max(d[k], 0.0))
    for j in range(3):
        if j != k:
            n[j] = (r[3 * k + j] + r[3 * j + k]) * 0.5 / (1.0 - c) / n[k]
    if n[0] * v[0] + n[1] * v[1] + n[2] * v[2] < 0.0:
        n = [-x for x in n]
    return (n[0] * th, n[1] * th, n[2] * th)


class Chain:
    """An arm file (docs/book/src/spatial-arms.md, "Arms as data"): the mount on the platform,
    each joint's frame in the previous joint's moving frame, its axis and limits, and the tool."""

    def __init__(self, path):
        try:
            with open(path, "rb") as f:
                d = tomllib.load(f)
            self._read(path, d)
        except (OSError, tomllib.TOMLDecodeError, KeyError, TypeError, ValueError) as e:
            raise Fatal(f"arm file {path}: {e!r}")

    def _read(self, path, d):

        def frame(t):
            t = t or {}
            if "rotation" in t:
                rotation = tuple(float(x) for row in t["rotation"] for x in row)
            else:
                rotation = from_rpy(*[float(x) for x in t.get("rpy", [0.0, 0.0, 0.0])])
            return rotation, tuple(float(x) for x in t.get("xyz", [0.0, 0.0, 0.0]))

        self.name = d.get("name", path)
        self.mount = frame(d.get("mount"))
        self.tool = frame(d.get("tool"))
        self.joints = []
        for j in d["joint"]:
            lower, upper = (float(x) for x in j["limits"])
            axis = tuple(float(x) for x in j["axis"])
            self.joints.append((j["type"], frame(j), axis, lower, upper, float(j["home"])))
        if not 1 <= len(self.joints) <= MAX_JOINTS:
            raise Fatal(f"arm file {path}: {len(self.joints)} joints, the wire carries 1 to {MAX_JOINTS}")

    def description(self):
        """The arm as docs/book/src/bridge.md ("The arm hash") describes it."""

        def frame(f):
            return {"rotation": list(f[0]), "translation": list(f[1])}

        return {
            "mount": frame(self.mount),
            "joints": [
                {"kind": kind, "origin": frame(origin), "axis": list(axis), "lower": lower, "upper": upper}
                for kind, origin, axis, lower, upper, _ in self.joints
            ],
            "tool": frame(self.tool),
        }

    def end_effector(self, q):
        """r_be(q) = M · O₁ J₁(q₁) ⋯ O_N J_N(q_N) · E, the end effector seen from the platform."""
        f = self.mount
        for (kind, origin, axis, _, _, _), qi in zip(self.joints, q):
            if kind == "revolute" and axis == (0.0, 0.0, 1.0):
                motion = (about_axis(2, math.sin(qi), math.cos(qi)), (0.0, 0.0, 0.0))
            elif kind == "revolute":
                motion = (so3_exp((axis[0] * qi, axis[1] * qi, axis[2] * qi)), (0.0, 0.0, 0.0))
            else:
                motion = (IDENTITY, (axis[0] * qi, axis[1] * qi, axis[2] * qi))
            f = compose3(compose3(f, origin), motion)
        return compose3(f, self.tool)


class UrdfChain(Chain):
    """The chain between two links of a URDF (docs/book/src/your-robot.md), read here with the
    standard library alone — a second implementation of companion's reader, so the handshake's
    arm hash checks the two against each other: fixed joints folded into the next moving
    joint's origin (or the tool after the last), continuous joints revolute without limits,
    axes normalised, the home from `home` (every value in order, or name=value over an SRDF
    group state's)."""

    def __init__(self, path, base_link, tip_link, home, srdf=None, home_state=None):
        import xml.etree.ElementTree as ET

        try:
            root = ET.parse(path).getroot()
        except (OSError, ET.ParseError) as e:
            raise Fatal(f"URDF {path}: {e}")
        joints = {}
        for j in root.findall("joint"):
            child, parent = j.find("child"), j.find("parent")
            if child is None or parent is None or child.get("link") is None or parent.get("link") is None:
                raise Fatal(f"URDF {path}: joint {str(j.get('name'))[:80]!r} has no <parent link> or <child link>")
            joints[child.get("link")] = j
        links = [lk.get("name") for lk in root.findall("link")]
        roots = [lk for lk in links if lk not in joints]
        base = base_link or (roots[0] if roots else None)
        if not tip_link or base is None:
            raise Fatal(f"URDF {path}: give --tip-link (and a file with a root link)")
        # The walk up from the tip: at most one step per joint (a loop is refused, not walked).
        path_up, link = [], tip_link
        while link != base:
            if link not in joints or len(path_up) > len(joints):
                raise Fatal(f"URDF {path}: link {str(tip_link)[:80]!r} is not below {str(base)[:80]!r}")
            path_up.append(joints[link])
            link = joints[link].find("parent").get("link")

        def numbers(el, attr, default):
            if el is None or not el.get(attr):
                return default
            v = el.get(attr).split()
            try:
                out = tuple(float(x) for x in v[:4])
            except ValueError:
                out = ()
            if len(out) != 3 or not all(math.isfinite(x) for x in out):
                raise Fatal(f"URDF {path}: {attr}={el.get(attr)[:80]!r} is not three finite numbers")
            return out

        self.name = root.get("name", path)
        self.mount = (IDENTITY, (0.0, 0.0, 0.0))
        self.joints, names = [], []
        pending = (IDENTITY, (0.0, 0.0, 0.0))
        for j in reversed(path_up):
            o = j.find("origin")
            origin = (from_rpy(*numbers(o, "rpy", (0.0, 0.0, 0.0))), numbers(o, "xyz", (0.0, 0.0, 0.0)))
            kind = j.get("type")
            if kind == "fixed":
                pending = compose3(pending, origin)
                continue
            if kind not in ("revolute", "continuous", "prismatic") or j.find("mimic") is not None:
                raise Fatal(f"URDF {path}: joint {j.get('name')!r} ({kind}) cannot be driven")
            a = numbers(j.find("axis"), "xyz", (1.0, 0.0, 0.0))
            n = math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
            lim = j.find("limit")
            if kind == "continuous":
                lower, upper = -math.inf, math.inf
            elif lim is None:
                raise Fatal(f"URDF {path}: joint {str(j.get('name'))[:80]!r} ({kind}) has no <limit>")
            else:
                lower, upper = float(lim.get("lower", 0)), float(lim.get("upper", 0))
            self.joints.append(
                ("prismatic" if kind == "prismatic" else "revolute", compose3(pending, origin),
                 (a[0] / n, a[1] / n, a[2] / n), lower, upper, None)
            )  # fmt: skip
            names.append(j.get("name"))
            pending = (IDENTITY, (0.0, 0.0, 0.0))
        self.tool = pending
        values = {}
        if srdf:
            for gs in ET.parse(srdf).getroot().findall("group_state"):
                if gs.get("name") == home_state:
                    values.update({e.get("name"): float(e.get("value").split()[0]) for e in gs.findall("joint")})
        if home and all("=" in x for x in home.split(",")):
            values.update({k.strip(): float(v) for k, v in (x.split("=") for x in home.split(","))})
        elif home:
            values.update(zip(names, (float(x) for x in home.split(","))))
        missing = [n for n in names if n not in values]
        if missing:
            raise Fatal(f"URDF {path}: no home for {', '.join(missing)} (--home)")
        self.joints = [j[:5] + (values[n],) for j, n in zip(self.joints, names)]
        self.joint_names = names


def planar_pose3(pose):
    """The platform's (x, y, θ) as a pose in space: a rotation about z, height 0."""
    return about_axis(2, math.sin(pose[2]), math.cos(pose[2])), (pose[0], pose[1], 0.0)


# ----- the transport (docs/book/src/bridge.md §2) ----------------------------------------------------


class Link:
    def __init__(self, name, events, default_settings, service_version=PROTOCOL_VERSION, command=Command):
        iox.set_log_level_from_env_or(iox.LogLevel.Fatal)
        self.cfg = iox.config.default()
        self.cfg.global_cfg.prefix = iox.FileName.new(PREFIX)
        # No clean-up of every dead node of the prefix when a node is created or dropped: that
        # would let this process erase another demo's just-killed peer before its partner looks
        # (docs/book/src/bridge.md §2). Only this demo's dead nodes are removed, below and in
        # peer_state.
        self.cfg.global_cfg.node.cleanup_dead_nodes_on_creation = False
        self.cfg.global_cfg.node.cleanup_dead_nodes_on_destruction = False
        self.name = name
        self.version = service_version
        self.remove_dead(self.demo_dead_nodes())
        self.node = iox.NodeBuilder.new().config(self.cfg).create(iox.ServiceType.Ipc)
        base = f"companion/{name}/v{service_version}"
        self.meas_service = self._pubsub(base + "/measurement", Measurement, default_settings)
        self.cmd_service = self._pubsub(base + "/command", command, default_settings)
        self.publisher = (
            self.meas_service.publisher_builder()
            .backpressure_strategy(iox.BackpressureStrategy.DiscardData)
            .create()
        )
        self.subscriber = self.cmd_service.subscriber_builder().create()
        self.notifier = self.listener = None
        if events:
            ready = self._event(base + "/measurement-ready")
            self.notifier = ready.notifier_builder().create()
            self.listener = self._event(base + "/command-ready").listener_builder().create()
        self.peer = None

    def demo_dead_nodes(self):
        """Ids of the dead nodes an earlier run of this demo left: those attached to its
        services, and the project's own nodes NAME/plant and NAME/control."""
        prefix = f"companion/{self.name}/"
        ids = []  # (the binding's UniqueNodeId compares but does not hash)
        for d in iox.Service.list(self.cfg, iox.ServiceType.Ipc):
            if d.name().to_string().startswith(prefix):
                ids.extend(n._0.id for n in d.nodes() or [] if isinstance(n, iox.NodeState.Dead))
        names = {f"{self.name}/plant", f"{self.name}/control"}
        for n in iox.Node.list(iox.ServiceType.Ipc, self.cfg):
            if isinstance(n, iox.NodeState.Dead) and n._0.details is not None:
                if n._0.details.name.as_str() in names:
                    ids.append(n._0.id)
        return ids

    def remove_dead(self, ids):
        """Removes the resources of the dead nodes whose ids are in `ids`, and only those."""
        for n in iox.Node.list(iox.ServiceType.Ipc, self.cfg):
            if isinstance(n, iox.NodeState.Dead) and n._0.id in ids:
                n._0.try_remove_stale_resources()

    def _pubsub(self, name, payload, default_settings):
        sn = iox.ServiceName.new(name)
        if default_settings:
            # Whoever comes first creates; with iceoryx2's defaults when it is us.
            return self.node.service_builder(sn).publish_subscribe(payload).open_or_create()
        deadline = time.monotonic() + 2.0
        while True:
            try:
                return self.node.service_builder(sn).publish_subscribe(payload).open()
            except iox.PublishSubscribeOpenError as e:
                if str(e) == "IncompatibleTypes":
                    raise Fatal(
                        f"{name} exists with another payload type than {payload.type_name()} "
                        f"({ctypes.sizeof(payload)} bytes, alignment {ctypes.alignment(payload)}, no user header)"
                    )
                if str(e) != "DoesNotExist" and time.monotonic() > deadline:
                    raise
            try:
                return (
                    self.node.service_builder(sn)
                    .publish_subscribe(payload)
                    .max_publishers(1)
                    .max_subscribers(1)
                    .history_size(0)
                    .subscriber_max_buffer_size(4)
                    .enable_safe_overflow(True)
                    .create()
                )
            except iox.PublishSubscribeCreateError as e:
                if str(e) != "AlreadyExists" and time.monotonic() > deadline:
                    raise
            time.sleep(0.005)

    def _event(self, name):
        return self.node.service_builder(iox.ServiceName.new(name)).event().open_or_create()

    def connected(self):
        return (
            self.meas_service.dynamic_config.number_of_subscribers >= 1
            and self.cmd_service.dynamic_config.number_of_publishers >= 1
        )

    def other_version(self):
        """A live peer on this demo with another protocol version: (version, service, pid)."""
        prefix = f"companion/{self.name}/"
        for d in iox.Service.list(self.cfg, iox.ServiceType.Ipc):
            sn = d.name().to_string()
            if not sn.startswith(prefix):
                continue
            rest = sn[len(prefix):]
            if rest in ("measurement", "command"):
                version = 1
            elif rest.startswith("v") and rest.split("/", 1)[-1] in ("measurement", "command"):
                try:
                    version = int(rest[1:].split("/", 1)[0])
                except ValueError:
                    continue
            else:
                continue
            if version == self.version:
                continue
            for n in d.nodes() or []:
                if isinstance(n, iox.NodeState.Alive) and n._0.id != self.node.id:
                    return version, sn, n._0.details.process_id
        return None

    def wait_for_peer(self, timeout_s):
        end = time.monotonic() + timeout_s
        next_scan = 0.0
        while not self.connected():
            if stop_requested():
                raise Interrupted(f"interrupted while waiting for a controller to join demo '{self.name}'")
            now = time.monotonic()
            if now >= next_scan:
                other = self.other_version()
                if other:
                    v, sn, pid = other
                    # Stay a moment, so that the peer's own scan finds us and says so too.
                    time.sleep(0.5)
                    raise Fatal(
                        f"protocol version mismatch: process {pid} waits on demo '{self.name}' with protocol "
                        f"version {v} (service {sn}); this bridge speaks version {self.version}"
                    )
                next_scan = now + 0.2
            if now > end:
                raise Fatal(
                    f"no controller joined demo '{self.name}' within {timeout_s:.0f} s (services "
                    f"companion/{self.name}/v{self.version}/measurement and /command, iceoryx2 prefix {PREFIX})"
                )
            time.sleep(0.001)

    def publish(self, m):
        self.publisher.send_copy(m)
        if self.notifier is not None:
            self.notifier.notify()

    def receive(self):
        """The next command (a copy), or None; remembers the node that sent it."""
        s = self.subscriber.receive()
        if s is None:
            return None
        self.peer = s.header.node_id
        c = Command.from_buffer_copy(s.payload().contents)
        s.delete()
        return c

    def wait_event(self, seconds):
        if self.listener is not None:
            try:
                self.listener.timed_wait(iox.Duration.from_micros(max(1, int(seconds * 1e6))))
            except iox.ListenerWaitError as e:
                # A signal woke the wait (its handler recorded it): the loop looks at it next.
                if "InterruptSignal" not in str(e):
                    raise

    def peer_state(self):
        """'alive', 'dead' (with its resources cleaned) or 'absent'."""
        ids = [self.peer] if self.peer is not None else [
            n._0.id for n in self.cmd_service.nodes if n._0.id != self.node.id
        ]
        state = "absent"
        for n in iox.Node.list(iox.ServiceType.Ipc, self.cfg):
            if n._0.id in ids:
                if isinstance(n, iox.NodeState.Alive):
                    return "alive"
                if isinstance(n, iox.NodeState.Dead):
                    state = "dead"
        if state == "dead":
            self.remove_dead(ids)
        return state


# ----- the run ---------------------------------------------------------------------------------


class Refused(Exception):
    pass


class Fatal(Exception):
    """An error that ends the bridge with exit code 2 (a mismatch, no peer)."""


class Lost(Exception):
    def __init__(self, code, why):
        super().__init__(why)
        self.code = code


class Summary:
    """The figures `companion sim` prints, computed the same way (record/summary.rs)."""

    def __init__(self):
        self.final_ep = float("nan")
        self.max_ep_after_20 = 0.0
        self.ep_after_20 = []
        self.after20 = self.below = 0
        self.path = 0.0
        self.last_pos = None
        self.last_sign = 0
        self.v_sign_changes = 0
        self.max_v = self.max_w = 0.0
        self.steps = 0
        self.margins = None

    def add(self, robot, cmd):
        t, (x, y, _), ep = robot.t, robot.base, robot.tracking_error()
        self.steps += 1
        margins = [min(q - lo, hi - q) for q, (lo, hi) in zip(robot.q, robot.limits)]
        self.margins = margins if self.margins is None else [min(a, b) for a, b in zip(self.margins, margins)]
        if self.last_pos is not None:
            self.path += math.hypot(x - self.last_pos[0], y - self.last_pos[1])
        self.last_pos = (x, y)
        if math.isfinite(ep):
            self.final_ep = ep
            if t >= 20.0:
                self.after20 += 1
                self.max_ep_after_20 = max(self.max_ep_after_20, ep)
                self.below += ep < 1e-3
                self.ep_after_20.append(ep)
        v, w = cmd[0], cmd[1]
        if abs(v) > SIGN_SPEED:
            sign = 1 if v > 0 else -1
            if self.last_sign != 0 and sign != self.last_sign:
                self.v_sign_changes += 1
            self.last_sign = sign
        self.max_v = max(self.max_v, abs(v))
        self.max_w = max(self.max_w, abs(w))

    def line(self):
        tracked = 100.0 * self.below / self.after20 if self.after20 else 0.0
        return (
            f"final|ep| {self.final_ep:.2e} max|ep|>20 {self.max_ep_after_20:.2e} tracked {tracked:.1f}% "
            f"path m {self.path:.2f} v sgn {self.v_sign_changes} max|v| {self.max_v:.3f} max|w| {self.max_w:.3f}"
        )


class Bridge:
    def __init__(self, a, robot=None):
        """The session of `a` (the flags) with `robot` (default: the kinematic robot `a.arm`
        names)."""
        self.a = a
        command = CommandWithoutJointScale if a.short_command else Command
        if robot is None and a.arm and a.arm.endswith(".urdf"):
            chain = UrdfChain(a.arm, a.base_link, a.tip_link, a.home, a.srdf, a.home_state)
            robot = SpatialRobot(a.dt, chain)
        elif robot is None:
            robot = SpatialRobot(a.dt, Chain(a.arm)) if a.arm else Robot(a.dt)
        self.robot = robot
        self.joints = len(self.robot.q)
        # What this bridge announces: its robot's, unless a test says otherwise.
        self.joint_count = self.joints if a.joint_count is None else a.joint_count
        self.arm_hash = self.robot.arm_hash if a.arm_hash is None else a.arm_hash
        self.space = self.robot.space if a.space is None else a.space
        self.link = Link(a.name, a.events, a.default_settings, a.service_version, command)
        self.session = random.getrandbits(64) or 1
        self.period_ns = 0 if a.lockstep else int(round(a.dt * 1e9))
        self.flags = (LOCKSTEP if a.lockstep else 0) | (NOTIFIES if a.events else 0)
        self.summary = Summary()
        self.counts = {"fresh": 0, "deadline_misses": 0, "late": 0, "held": 0, "stopped": 0, "stop_events": 0}
        self.rejected = 0
        self.invalid = {}
        # When the last valid answer too late to apply arrived: the controller is alive then.
        self.late_heard = 0
        self.delays = []
        # --rows: one tuple per period (kept in memory, written at the end: no file I/O in
        # the loop).
        self.rows = [] if a.rows else None
        # The controller's logged joint guard factor (CommandMsg.joint_scale) over the fresh
        # commands the law computed (status 0): its largest value, how often it acted, and how
        # many carried no valid factor (not finite or below 1).
        self.max_joint_scale = 1.0
        self.joint_guard_steps = 0
        self.joint_scale_invalid = 0
        self.last_sent = None
        self.poll = not a.events  # sleep on the controller's event only while it notifies
        # Real time: how long before each release the loop stops sleeping and spins; how often
        # it fell more than a period behind its schedule (and restarted it), and by how much
        # in all (the run then took that much longer than its simulated time).
        self.spin_ns = 300_000
        self.fell_behind = 0
        self.behind_ns = 0
        # The period SIGINT/SIGTERM made the last one (None: not interrupted).
        self.interrupted_at = None

    # -- messages --

    def measurement(self, seq, flags, delay):
        t, base, q, (position, rotation, yaw, twist) = self.robot.measure()
        m = Measurement()
        m.version = self.a.protocol_version
        m.flags = self.flags | flags
        m.seq = seq
        m.session = self.session
        m.scenario_hash = self.a.scenario_hash
        m.plant_time_ns = time.monotonic_ns()
        m.period_ns = self.period_ns
        m.sim_time = t
        m.dt = self.a.dt
        m.delay = delay
        m.arm_hash = self.arm_hash
        m.platform = PLATFORMS[self.a.platform]
        m.hold_periods = self.a.hold_periods
        m.joint_count = self.joint_count
        m.space = self.space
        m.base[:] = base
        m.target_position[:] = position
        m.target_rotation[:] = rotation
        m.target_yaw = yaw
        m.target_twist[:] = twist
        for i, qi in enumerate(q):
            m.joints[i] = qi
        return m

    def publish(self, seq, flags, delay):
        m = self.measurement(seq, flags, delay)
        for kind in self.a.inject.get(seq, []):
            self.link.publish(corrupt(m, kind, self.last_sent))
        self.link.publish(m)
        self.last_sent = m
        return m

    def drain(self, seq):
        """Every waiting command, checked (docs/book/src/bridge.md, what the plant checks); returns the
        last fresh one for `seq` with its arrival time."""
        fresh = None
        while True:
            c = self.link.receive()
            if c is None:
                return fresh
            now = time.monotonic_ns()
            why = self.check(c, seq)
            if why is None:
                fresh = (c, now)
                if not (c.flags & NOTIFIES):
                    self.poll = True
            elif why == "refused":
                raise Refused(describe_refusal(c, self.last_sent))
            elif why == "late":
                self.counts["late"] += 1
                self.late_heard = now
            else:
                self.invalid[why] = self.invalid.get(why, 0) + 1

    def check(self, c, seq):
        if c.version != PROTOCOL_VERSION:
            return "version"
        if c.session != self.session:
            return "session"
        if is_refusal(c.status):
            return "refused"
        if c.seq < seq:
            return "late"
        if c.seq > seq:
            return "future_seq"
        if c.joint_count != self.joint_count:
            return "joint_count"
        if not known_status(c.status):
            return "status"
        values = [c.v, c.v_lat, c.omega, c.v_xi] + [c.joints[i] for i in range(self.joint_count)]
        if not all(math.isfinite(x) for x in values):
            return "non_finite"
        return None

    def idle(self, deadline_ns, spun_since):
        """One wait step: the controller's event, or a spin that turns into 50 µs naps."""
        now = time.monotonic_ns()
        if not self.poll:
            self.link.wait_event(min(0.01, max(0.0, (deadline_ns - now) / 1e9)))
        elif now - spun_since > 200_000:
            time.sleep(0.00005)

    def note_diagnostics(self, c):
        if c.status != 0:
            self.rejected += 1
            return
        if not math.isfinite(c.joint_scale) or c.joint_scale < 1.0:
            self.joint_scale_invalid += 1
            return
        self.max_joint_scale = max(self.max_joint_scale, c.joint_scale)
        self.joint_guard_steps += c.joint_scale > 1.0

    def watch(self, silent_since_ns):
        """After a silence: is the controller still there? Raises Lost if not."""
        silent = time.monotonic_ns() - silent_since_ns
        if silent < self.a.silence_ms * 1_000_000:
            return
        state = self.link.peer_state()
        if state == "dead":
            raise Lost(EXIT_PEER_LOST, f"the controller died ({silent / 1e6:.0f} ms after its last command)")
        if state == "absent":
            raise Lost(EXIT_PEER_LOST, "the controller left")
        if silent > self.a.peer_timeout * 1e9:
            raise Lost(EXIT_PEER_HUNG, f"the controller is alive but silent for {silent / 1e6:.0f} ms")

    # -- the loops --

    def run(self):
        a = self.a
        steps = int(round(a.duration / a.dt))
        self.link.wait_for_peer(a.startup_timeout)
        print(
            f"bridge: demo '{a.name}', session {self.session:#x}, {'lockstep' if a.lockstep else 'real time'}, "
            f"{steps + 1} periods",
            file=sys.stderr,
        )
        code = self.lockstep(steps) if a.lockstep else self.real_time(steps)
        if self.interrupted_at is not None:
            raise Interrupted(f"interrupted at period {self.interrupted_at}")
        return code

    def last_period(self, n, last):
        """The run's last period: `last`, or the next one after SIGINT/SIGTERM (the run then
        ends as `companion plant`'s does, with END_OF_RUN on that period's measurement)."""
        if stop_requested() and self.interrupted_at is None and last > n + 1:
            self.interrupted_at = n + 1
            return n + 1
        return last

    def give_up_waiting(self):
        """After SIGINT/SIGTERM, an answer is awaited INTERRUPT_GRACE_S at most."""
        if stop_requested() and stop_waited() > INTERRUPT_GRACE_S:
            raise Interrupted("interrupted while waiting for the controller's answer")

    def lockstep(self, steps):
        delay = 0.0
        n, last = 0, steps
        while n <= last:
            self.maybe_fault(n)
            self.progress(n)
            self.publish(n, END_OF_RUN if n == last else 0, delay)
            heard = spun = time.monotonic_ns()
            while True:
                got = self.drain(n)
                if got:
                    break
                self.give_up_waiting()
                self.watch(heard)
                self.idle(time.monotonic_ns() + 10_000_000, spun)
            c, _ = got
            self.counts["fresh"] += 1
            self.note_diagnostics(c)
            cmd = self.robot.command_of(c)
            self.summary.add(self.robot, cmd)
            if n < last:
                self.robot.advance(cmd, cmd, 0.0)
            last = self.last_period(n, last)
            n += 1
        return EXIT_OK

    def real_time(self, steps):
        a = self.a
        period = self.period_ns
        deadline_ns = int(a.deadline_us * 1000)
        start = time.monotonic_ns()
        acting, last_fresh, delay = self.robot.zero_command(), None, 0.0
        misses = 0
        stopped = False
        heard = start
        n, last = 0, steps
        while n <= last:
            self.maybe_fault(n)
            self.progress(n)
            release = start + n * period
            while (ahead := release - self.spin_ns - time.monotonic_ns()) > 0:
                time.sleep(ahead / 1e9)
            while time.monotonic_ns() < release:
                pass
            late = time.monotonic_ns() - release
            if n > 0 and late > period:
                # Fell behind (a pause, or a starved process): restart the period clock; the
                # robot's time goes on from where it was.
                if late > 50 * period:
                    print(f"bridge: period {n} released {late / 1e6:.0f} ms late", file=sys.stderr)
                # This process was not running: not the controller's silence.
                heard += late - period
                self.fell_behind += 1
                self.behind_ns += late
                start = time.monotonic_ns() - n * period
                release = start + n * period
            m = self.publish(n, (END_OF_RUN if n == last else 0) | (STOPPED if stopped else 0), delay)
            t_pub = m.plant_time_ns
            # The handshake's answer and the last one (the end of the run) are awaited up to
            # the peer timeout (a second after a signal); the others until the deadline.
            patient = n in (0, last)
            limit = t_pub + int(a.peer_timeout * 1e9) if patient else release + deadline_ns
            got, spun = None, time.monotonic_ns()
            while True:
                got = self.drain(n)
                if got or time.monotonic_ns() >= limit:
                    break
                if patient:
                    self.give_up_waiting()
                self.idle(limit, spun)
            if n == 0:
                start = time.monotonic_ns()
            switch_at = 0.0
            if got:
                c, t_rx = got
                heard = t_rx
                self.counts["fresh"] += 1
                self.note_diagnostics(c)
                cmd = last_fresh = self.robot.command_of(c)
                misses, stopped = 0, False
                if n > 0:
                    switch_at = min((t_rx - t_pub) * a.dt / period, a.dt * (1 - 1e-9))
                    delay = switch_at
                    self.delays.append(switch_at)
            else:
                self.counts["deadline_misses"] += 1
                misses += 1
                if last_fresh is not None and misses <= a.hold_periods:
                    cmd = last_fresh
                    self.counts["held"] += 1
                else:
                    cmd = self.robot.zero_command()
                    self.counts["stopped"] += 1
                    if not stopped and last_fresh is not None:
                        self.counts["stop_events"] += 1
                    stopped = True
            self.summary.add(self.robot, cmd)
            if self.rows is not None:
                outcome = "fresh" if got else ("held" if not stopped else "stopped")
                self.rows.append((n, self.robot.t, self.summary.final_ep, outcome, switch_at, late))
            if n == last:
                break
            self.robot.advance(acting, cmd, switch_at)
            acting = cmd
            if not got:
                # Silence is the controller's: any valid answer, also a late one, is news.
                self.watch(max(heard, self.late_heard))
            last = self.last_period(n, last)
            n += 1
        return EXIT_OK

    def progress(self, n):
        """A line every --progress periods: a counted state others can wait for."""
        every = self.a.progress
        if every > 0 and n > 0 and n % every == 0:
            print(f"bridge: period {n}", file=sys.stderr, flush=True)

    def maybe_fault(self, n):
        a = self.a
        if n == a.pause_at:
            time.sleep(a.pause_ms / 1000.0)
        if n == a.stall_at:
            print(f"bridge: stalling at period {n} (alive, silent)", file=sys.stderr)
            while not stop_requested():
                time.sleep(0.01)
            raise Interrupted(f"interrupted while stalled at period {n}")

    def report(self, code, why=None):
        out = {
            "exit": code,
            "end": why or "completed",
            "summary": self.summary.line(),
            "final_ep_norm": self.summary.final_ep,
            "path_length": self.summary.path,
            "v_sign_changes": self.summary.v_sign_changes,
            "max_abs_v": self.summary.max_v,
            "max_abs_omega": self.summary.max_w,
            "max_ep_norm_after_20s": self.summary.max_ep_after_20 if self.summary.ep_after_20 else None,
            "median_ep_norm_after_20s": statistics.median(self.summary.ep_after_20) if self.summary.ep_after_20 else None,
            "steps": self.summary.steps,
            "rejected_steps": self.rejected,
            "joints": self.joints,
            "min_joint_margin": self.summary.margins,
            "smallest_joint_margin": min(self.summary.margins) if self.summary.margins else None,
            "smallest_margin_joint": 1 + min(range(self.joints), key=lambda i: self.summary.margins[i])
            if self.summary.margins
            else None,
            "max_joint_scale": self.max_joint_scale,
            "joint_guard_steps": self.joint_guard_steps,
            "joint_scale_invalid": self.joint_scale_invalid,
            "counts": self.counts,
            "invalid": self.invalid,
            "fell_behind": self.fell_behind,
            "behind_s": self.behind_ns / 1e9,
            "delay_mean_s": sum(self.delays) / len(self.delays) if self.delays else 0.0,
            "delay_max_s": max(self.delays) if self.delays else 0.0,
        }
        print(f"bridge: {self.summary.line()}", file=sys.stderr)
        print(f"bridge: {json.dumps(self.counts)} invalid {json.dumps(self.invalid)}", file=sys.stderr)
        if why:
            print(f"bridge: {why}", file=sys.stderr)
        if self.a.out:
            with open(self.a.out, "w") as f:
                json.dump(out, f, indent=2)
        if self.rows is not None:
            with open(self.a.rows, "w") as f:
                f.write("period,t,ep_norm,outcome,switch_at_s,release_late_ns\n")
                for r in self.rows:
                    f.write(f"{r[0]},{r[1]:.6f},{r[2]:.6e},{r[3]},{r[4]:.6e},{r[5]}\n")


def describe_refusal(c, mine):
    what = REFUSALS.get(c.status, f"status {c.status:#x}")
    if c.status == 0x8001:
        detail = f"this bridge speaks version {mine.version}, the controller version {c.version}"
    elif c.status == 0x8002:
        detail = f"this bridge has {mine.joint_count} joints, the controller is built for {c.joint_count}"
    elif c.status == 0x8003:
        detail = (
            f"this bridge is {PLATFORM_NAMES.get(mine.platform, mine.platform)}, the controller is built for "
            f"{PLATFORM_NAMES.get(c.platform, c.platform)}"
        )
    elif c.status == 0x8004:
        detail = f"this bridge's scenario hash is {mine.scenario_hash:#018x}, the controller's {c.scenario_hash:#018x}"
    elif c.status == 0x8006:
        detail = (
            f"this bridge's target is {SPACE_NAMES.get(mine.space, mine.space)}, the controller tracks a "
            f"{SPACE_NAMES.get(c.space, c.space)} one"
        )
    elif c.status == 0x8007:
        detail = f"this bridge's arm hash is {mine.arm_hash:#018x}, the controller's {c.arm_hash:#018x}"
    else:
        detail = f"dt = {mine.dt} s"
    return f"the controller refused this plant ({what} mismatch): {detail}"


def corrupt(m, kind, previous):
    """A malformed copy of measurement `m` (sent before it), for the tests."""
    c = Measurement.from_buffer_copy(m)
    if kind == "stale" and previous is not None:
        c = Measurement.from_buffer_copy(previous)
    elif kind == "session":
        c.session ^= 0x5A5A
    elif kind == "version":
        c.version = 1
    elif kind == "changed":
        c.hold_periods += 1
    elif kind == "joints":
        c.joint_count = 4
    return c


def parse_inject(text):
    plan = {}
    for item in filter(None, (x.strip() for x in (text or "").split(","))):
        kind, _, seq = item.partition("@")
        if kind not in ("stale", "session", "version", "changed", "joints") or not seq.isdigit():
            raise SystemExit(f"error: --inject {item!r}: KIND@SEQ with KIND stale, session, version, changed, joints")
        plan.setdefault(int(seq), []).append(kind)
    return plan


def session_arguments(p):
    """The flags of a plant session (the wire, time, the handshake's announcement and the
    test faults): the reference bridge's and the MuJoCo plant's (bridges/mujoco)."""
    p.add_argument("--name", default="demo", help="the demo's name (services companion/NAME/v4/…)")
    p.add_argument("--duration", type=float, default=30.0, help="simulated seconds")
    p.add_argument("--dt", type=float, default=0.001, help="control period and hold (s)")
    p.add_argument("--lockstep", action="store_true", help="wait for every command (deterministic)")
    p.add_argument("--deadline-us", type=float, default=500.0, help="deadline after each release (µs)")
    p.add_argument("--hold-periods", type=int, default=20, help="periods to hold a command after a miss")
    p.add_argument("--events", action="store_true", help="notify measurement-ready, sleep on command-ready")
    p.add_argument("--silence-ms", type=float, default=20.0)
    p.add_argument("--peer-timeout", type=float, default=2.0, help="s")
    p.add_argument("--startup-timeout", type=float, default=20.0, help="s")
    p.add_argument("--scenario-json", help="a scenario.json whose controller object gives the scenario hash")
    p.add_argument("--scenario-hash", type=lambda s: int(s, 0), default=0, help="sent as is (0: not checked)")
    p.add_argument("--joint-count", type=int, help="(tests) the joint count sent (default: the arm's)")
    p.add_argument(
        "--arm-hash", type=lambda s: int(s, 0), help="sent as is (default: the arm's own; 0: not checked)"
    )
    p.add_argument("--space", type=int, help="(tests) the target space code sent (default: the arm's)")
    p.add_argument("--protocol-version", type=int, default=PROTOCOL_VERSION, help="(tests) the version field")
    p.add_argument("--service-version", type=int, default=PROTOCOL_VERSION, help="(tests) the version in the names")
    p.add_argument(
        "--short-command", action="store_true", help="(tests) declare CommandMsg without its last field"
    )
    p.add_argument("--default-settings", action="store_true", help="create services with iceoryx2's defaults")
    p.add_argument("--inject", help="(tests) malformed measurements, e.g. stale@10,session@20,version@30")
    p.add_argument("--pause-at", type=int, default=-1, help="(tests) pause before this period")
    p.add_argument("--pause-ms", type=float, default=100.0)
    p.add_argument("--stall-at", type=int, default=-1, help="(tests) stop publishing, stay alive")
    p.add_argument(
        "--progress", type=int, default=0, help="print 'bridge: period N' every N periods (0: never)"
    )


def urdf_arguments(p):
    """The flags that cut a chain from a URDF and give its home, as `companion` takes them (the
    bridge, the MuJoCo plant and the ROS 2 stand-in share them; `UrdfChain` reads them)."""
    p.add_argument("--base-link", help="URDF arm: the chain's first link (default: the root link)")
    p.add_argument("--tip-link", help="URDF arm: the end effector's link")
    p.add_argument("--srdf", help="URDF arm: an SRDF whose <group_state> --home-state gives the home")
    p.add_argument("--home-state", help="URDF arm: the SRDF's <group_state> name")
    p.add_argument("--home", help="URDF arm: q1,…,qN in the chain's order, or name=value,… over --home-state's")


def finish_arguments(a):
    """What session_arguments' flags need after parsing: the injections parsed, the scenario
    hash read from --scenario-json."""
    a.inject = parse_inject(a.inject)
    if a.scenario_json:
        with open(a.scenario_json) as f:
            described = json.load(f)
        # A spatial run's scenario.json holds the planar run's scenario under `base`.
        a.scenario_hash = scenario_hash(described.get("controller") or described["base"]["controller"])
    return a


def serve(make_bridge):
    """Runs the session `make_bridge()` builds to its end and reports it: the exit code
    (0 completed, 2 an error or a refusal, 3 the controller died or left, 4 it is silent,
    101 a bug, 130 interrupted). Every code is one of companion's (docs/book/src/hil.md)."""
    install_signal_handlers()
    try:
        bridge = make_bridge()
    except Fatal as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_INTERRUPTED if stop_requested() else EXIT_ERROR
    except (Interrupted, KeyboardInterrupt):
        print("bridge: interrupted before the run started: nothing written", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception:  # noqa: BLE001 - a bug, said as one
        import traceback

        traceback.print_exc()
        print("error: an unexpected exception in the bridge (a bug: please report it)", file=sys.stderr)
        return EXIT_BUG
    if stop_requested():
        print("bridge: interrupted before the run started: nothing written", file=sys.stderr)
        return EXIT_INTERRUPTED
    try:
        code, why = bridge.run(), None
    except Fatal as e:
        code, why = EXIT_ERROR, f"error: {e}"
    except Refused as e:
        code, why = EXIT_ERROR, f"error: {e}"
    except Lost as e:
        code, why = e.code, f"{e}; robot stopped"
    except (Interrupted, KeyboardInterrupt) as e:
        code, why = EXIT_INTERRUPTED, f"{e or 'interrupted'}; robot stopped"
    except Exception:  # noqa: BLE001 - a bug: said, and the files written as far as they go
        import traceback

        traceback.print_exc()
        code, why = EXIT_BUG, "error: an unexpected exception in the bridge (a bug: please report it); robot stopped"
    # (A signal after the last period leaves a completed run completed, as `companion plant`
    # does: its files are written whole all the same.)
    try:
        bridge.report(code, why)
    except OSError as e:
        print(f"error: writing the run's files: {e}", file=sys.stderr)
        return code if code != EXIT_OK else EXIT_ERROR
    except Exception:  # noqa: BLE001 - a bug, said as one
        import traceback

        traceback.print_exc()
        print("error: an unexpected exception writing the run's files (a bug: please report it)", file=sys.stderr)
        return EXIT_BUG
    if SIGNALS["count"] > 1:
        print(f"bridge: {SIGNALS['count']} signals came; the first ended the run", file=sys.stderr)
    return code


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    session_arguments(p)
    p.add_argument("--platform", choices=sorted(PLATFORMS), default="unicycle")
    p.add_argument(
        "--arm",
        help="an arm file of 6 to 8 joints (examples/arms/ur5.toml) or a URDF (with --tip-link and --home): "
        "its chain tracks trajectory 1 lifted (default: the paper's RPR arm on trajectory 1)",
    )
    urdf_arguments(p)
    p.add_argument("--out", help="write the run's figures as JSON here")
    p.add_argument("--rows", help="(real time) write one CSV row per period here: t, |e_p|, fresh/held/stopped, delay")
    a = finish_arguments(p.parse_args(argv))
    return serve(lambda: Bridge(a))


if __name__ == "__main__":
    exit_with(main())
