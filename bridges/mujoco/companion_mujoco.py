#!/usr/bin/env python3
"""The MuJoCo plant: `companion plant` with a physical robot.

It speaks the wire exactly as the reference bridge does (it *is* the reference bridge's
session — bridges/python/companion_bridge.py, imported — with another robot): handshake,
scenario and arm hashes, lockstep and real time, END_OF_RUN, liveness, every fault path and
exit code. The robot is a MuJoCo model read from a URDF with what a URDF lacks
(bridges/mujoco/mujoco_robot.py, the table in actuators.toml): a differential-drive base on
its wheels, or an omnidirectional base; arm and torso servos with effort limits and gravity
compensation. It tracks the paper's trajectory 1 or 2 lifted into space (docs/book/src/bridge.md
§8), and writes the run's files: timeseries.csv (the spatial run's columns, then the
physics'), summary.json, latency.json (with the plant's own step time), scenario.json, a
filmstrip rendered off-screen and index.html.

    companion control --name demo --arm examples/arms/ur5.toml --platform omni &
    target/py/bin/python bridges/mujoco/companion_mujoco.py --name demo --arm examples/arms/ur5.toml \\
        --platform omni --out out/mujoco-ur5

`companion hil --plant mujoco …` starts it as the demo's plant. `--open-loop` drives the
robot without a controller (commands from the flag), for trying a base or a table.
"""

import signal
import sys

# SIGINT and SIGTERM are recorded from the first line on (the imports below take most of a
# second): the session acts on them between periods (companion_bridge.serve).
EARLY_SIGNALS = []
for _sig in (signal.SIGINT, signal.SIGTERM):
    signal.signal(_sig, lambda signum, _frame: EARLY_SIGNALS.append(signum))

import argparse  # noqa: E402
import atexit  # noqa: E402
import gc  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import os  # noqa: E402
import platform as host  # noqa: E402
import random  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import zlib  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(REPO, "bridges", "python"))
# Off-screen pictures through EGL unless the user chose another backend (osmesa, glfw). Set
# before mujoco is imported: it reads the variable then, and refuses to load with a value it
# does not know — then the run goes on without pictures, and says why.
GL_WANTED = os.environ.setdefault("MUJOCO_GL", "egl")
NO_GL = None
if GL_WANTED.lower().strip() not in ("egl", "osmesa", "glfw", "glx"):
    NO_GL = "not one of MuJoCo's backends (egl, osmesa, glfw)"
    os.environ["MUJOCO_GL"] = "disabled"

import numpy as np  # noqa: E402

import companion_bridge as wire  # noqa: E402
import mujoco  # noqa: E402
import mujoco_robot  # noqa: E402
from companion_bridge import compose3, inverse3, so3_log, transpose  # noqa: E402

wire.install_signal_handlers()
for _sig in EARLY_SIGNALS:
    wire.on_signal(_sig)

# ----- MuJoCo's own log (MUJOCO_LOG.TXT): in the run's folder, never in the working directory --
# Until the run's folder exists (its first row), MuJoCo logs into a private temporary folder;
# the folder's MUJOCO_LOG.TXT then gets what it holds, and every later message. MuJoCo prints
# each message on stderr too.
_LOG_TMP = tempfile.mkdtemp(prefix="companion-mujoco-log-")
atexit.register(shutil.rmtree, _LOG_TMP, True)


def mujoco_log_to(path):
    c = mujoco.MjLogConfig.get()
    c.logfile = path
    c.set()


mujoco_log_to(os.path.join(_LOG_TMP, "MUJOCO_LOG.TXT"))


def mujoco_log_into(folder):
    """MuJoCo's log into `folder` (the run's), with what it logged before the folder existed."""
    early = os.path.join(_LOG_TMP, "MUJOCO_LOG.TXT")
    target = os.path.join(folder, "MUJOCO_LOG.TXT")
    if os.path.exists(early):
        with open(early, "rb") as src, open(target, "ab") as dst:
            dst.write(src.read())
        os.remove(early)
    mujoco_log_to(target)

# ----- the target: the paper's trajectories lifted (docs/book/src/bridge.md §8) -------------------

TABLE1_OMEGA = math.pi * math.pi / 20.0
# The exit code of a completed run that did not keep real time (companion's, docs/book/src/bridge.md §6).
EXIT_DEADLINES = 7


def table1(t):
    """Trajectory 2, Table 1 of the paper: the smooth piece of u_d at `t` as a function of
    time (sim-plant/src/trajectory.rs, `table1`)."""
    def constant(v1, v2):
        return lambda _t: (v1, v2, 0.0)

    def rotation(t0):
        return lambda s: (0.0, 0.0, TABLE1_OMEGA * math.cos(math.pi / 2.0 * (s - t0)))

    if not 0.0 <= t < 120.0 or t < 5.0:
        return constant(0.0, 0.0)
    if t < 27.0:
        return rotation(5.0)
    if t < 37.0:
        return constant(0.2, 0.0)
    if t < 59.0:
        return rotation(37.0)
    if t < 99.0:
        return constant(0.0, 0.05)
    if t < 105.0:
        return constant(0.0, 0.0)
    if t < 115.0:
        return constant(-0.2, 0.0)
    return constant(0.0, 0.0)


TRAJECTORIES = {1: (2.6, 1.0), 2: (2.5, 1.0)}


class LiftedTarget:
    """The planar target of trajectory 1 or 2 integrated by RK4 per period (its piece of u_d
    picked at the period's midpoint, as the kinematic plant does), at the height `z0` where
    the arm at home holds it, plus the 5 cm vertical sine of period 10 s."""

    def __init__(self, trajectory, dt, z0):
        self.trajectory, self.dt, self.z0 = trajectory, dt, z0
        x, y = TRAJECTORIES[trajectory]
        self.pose = (x, y, 0.0)  # the platform starts at the origin facing x

    def velocity_piece(self, t_mid):
        if self.trajectory == 1:
            return wire.target_velocity
        return table1(t_mid)

    def advance(self, t0):
        """One RK4 step of the planar pose, as the reference bridge's (the same sums, in the
        same order)."""
        h = self.dt
        u = self.velocity_piece(t0 + 0.5 * h)
        x, y, th = self.pose
        half, tm = 0.5 * h, t0 + 0.5 * h
        sin, cos = math.sin, math.cos
        u1, um, u4 = u(t0), u(tm), u(t0 + h)
        s, c = sin(th), cos(th)
        k1 = (c * u1[0] - s * u1[1], s * u1[0] + c * u1[1], u1[2])
        t2 = th + half * k1[2]
        s, c = sin(t2), cos(t2)
        k2 = (c * um[0] - s * um[1], s * um[0] + c * um[1], um[2])
        t3 = th + half * k2[2]
        s, c = sin(t3), cos(t3)
        k3 = (c * um[0] - s * um[1], s * um[0] + c * um[1], um[2])
        t4 = th + h * k3[2]
        s, c = sin(t4), cos(t4)
        k4 = (c * u4[0] - s * u4[1], s * u4[0] + c * u4[1], u4[2])
        w = h / 6.0
        self.pose = (
            x + w * (((k1[0] + 2.0 * k2[0]) + 2.0 * k3[0]) + 1.0 * k4[0]),
            y + w * (((k1[1] + 2.0 * k2[1]) + 2.0 * k3[1]) + 1.0 * k4[1]),
            th + w * (((k1[2] + 2.0 * k2[2]) + 2.0 * k3[2]) + 1.0 * k4[2]),
        )

    def at(self, t):
        """(R 9-tuple, p, yaw, twist) at time t (the pose integrated to t)."""
        x, y, th = self.pose
        w = 2.0 * math.pi / wire.LIFT_PERIOD
        z = self.z0 + wire.LIFT_AMPLITUDE * math.sin(w * t)
        rot = wire.about_axis(2, math.sin(th), math.cos(th))
        u = self.velocity_piece(t)(t) if self.trajectory == 2 else wire.target_velocity(t)
        twist = (u[0], u[1], wire.LIFT_AMPLITUDE * w * math.cos(w * t), 0.0, 0.0, u[2])
        return rot, (x, y, z), math.atan2(rot[3], rot[0]), twist


# ----- what the robot is: an arm file's chain or a URDF's -----------------------------------

UR5_URDF = ("ur_description/urdf/ur5_robot.urdf", "base_link", "tool0")
ARM_PRESETS = {"ur5": os.path.join(REPO, "examples", "arms", "ur5.toml")}


def mount_of(robot, chain, home):
    """Where the URDF's root link sits on the platform so that its tip is the arm file's
    effector: M_urdf = r_be(home) · (tip seen from the root link at home)⁻¹ (both from the
    model, MuJoCo's kinematics and the chain's). Checked against the chain at other
    configurations by the caller."""
    r, p = robot.tool_in_base(home)
    file_pose = chain.end_effector(tuple(home))
    urdf_pose = (tuple(r.flatten().tolist()), tuple(p.tolist()))
    return compose3(file_pose, inverse3(urdf_pose))


def rpy_of(rot):
    """roll, pitch, yaw of a rotation R = R_z(y) R_y(p) R_x(r) (9-tuple)."""
    pitch = math.asin(max(-1.0, min(1.0, -rot[6])))
    return math.atan2(rot[7], rot[8]), pitch, math.atan2(rot[3], rot[0])


def build_robot(a, table):
    """The MuJoCo robot the flags describe, the chain the controller has (for the arm hash and
    a check), and the arm hash. Raises wire.Fatal (exit 2) with the reason."""
    arm = ARM_PRESETS.get(a.arm, a.arm)
    try:
        if arm.endswith(".toml"):
            chain = wire.Chain(arm)
            home = [j[5] for j in chain.joints]
            urdf, base, tip = (a.urdf, a.base_link, a.tip_link) if a.urdf else UR5_URDF
            mount = None
            if a.platform == "omni":
                # First at the root, to find the mount that makes the URDF's tip the file's
                # effector.
                probe = mujoco_robot.Robot(urdf, base, tip, "omni", home, a.dt, table, visuals=False)
                m = mount_of(probe, chain, home)
                mount = (m[1], rpy_of(m[0]))
            elif not a.urdf:
                raise wire.Fatal(f"--arm {a.arm}: the UR5's URDF has no base; the MuJoCo plant carries it on --platform omni")
            robot = mujoco_robot.Robot(urdf, base, tip, a.platform, home, a.dt, table, mount=mount)
            check_chain(robot, chain, arm, urdf)
            return robot, chain, wire.arm_hash(chain.description())
        if arm.endswith(".urdf"):
            # The controller's chain, read by the reference bridge's second implementation of
            # companion's URDF reader (its arm hash and forward kinematics), and MuJoCo's model
            # of the same file: checked against each other below.
            path = mujoco_robot.resolve_robot_file(arm)
            if not a.tip_link or not (a.home or a.home_state):
                raise wire.Fatal(f"--arm {a.arm}: a URDF needs --tip-link and --home (or --srdf and --home-state)")
            # The cut and a list home checked here, each error named (the chain's reader
            # assumes them well formed).
            urdf = mujoco_robot.Urdf(path)
            base = a.base_link or urdf.root_link
            names = [j["name"] for j in urdf.chain(base, a.tip_link)]
            if a.home and "=" not in a.home and len(numbers_of("--home", a.home)) != len(names):
                raise wire.Fatal(
                    f"--home gives {len(numbers_of('--home', a.home))} joints, the chain {base} -> {a.tip_link} of "
                    f"{path} has {len(names)} ({', '.join(names)})"
                )
            try:
                chain = wire.UrdfChain(path, base, a.tip_link, a.home, a.srdf, a.home_state)
            except (ValueError, OSError) as e:
                raise wire.Fatal(f"--home {a.home!r} / --srdf {a.srdf!r}: {e}")
            home = [j[5] for j in chain.joints]
            mount = None
            if a.platform == "omni":
                m = numbers_of("--mount", a.mount, 6)
                mount = (m[:3], m[3:])
                chain.mount = (wire.from_rpy(*m[3:]), tuple(m[:3]))
            robot = mujoco_robot.Robot(path, base, a.tip_link, a.platform, home, a.dt, table, mount=mount)
            check_chain(robot, chain, arm, path)
            return robot, chain, wire.arm_hash(chain.description())
    except mujoco_robot.ModelError as e:
        raise wire.Fatal(str(e))
    except (ValueError, KeyError, TypeError, np.linalg.LinAlgError) as e:
        # What MuJoCo or the file's numbers refused that no check above names: the reason, as
        # one line (exit 2, as every refusal of a robot before the run).
        raise wire.Fatal(f"--arm {a.arm}: the MuJoCo plant cannot build this robot: {mujoco_robot.one_line(e)}")
    raise wire.Fatal(f"--arm {a.arm}: ur5, an arm file (.toml) or a URDF (.urdf)")


def numbers_of(flag, text, count=None):
    """A flag's comma-separated numbers (finite), `count` of them if given; else wire.Fatal."""
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        v = []
    if not v or not all(math.isfinite(x) for x in v) or (count is not None and len(v) != count):
        n = f"{count} " if count else ""
        raise wire.Fatal(f"{flag} {text!r}: {n}comma-separated numbers")
    return v


def check_chain(robot, chain, arm, urdf):
    """The controller's chain (the arm file) and the simulated URDF are one arm: the tip's
    pose from the platform agrees at 20 seeded configurations within the limits."""
    rng = random.Random(7)
    worst = 0.0
    for _ in range(20):
        q = [rng.uniform(max(lo, -math.pi), min(hi, math.pi)) for (_, _, _, lo, hi, _) in chain.joints]
        r, p = robot.tool_in_base(q)
        rc, pc = chain.end_effector(tuple(q))
        worst = max(worst, float(np.abs(np.array(rc).reshape(3, 3) - r).max()), float(np.abs(np.array(pc) - p).max()))
    if worst > 1e-9:
        raise wire.Fatal(f"the URDF {urdf} is not the arm of {arm}: their effector poses differ by up to {worst:.3g}")


# ----- the robot the session drives ---------------------------------------------------------


class Physical:
    """The bridge's robot interface (companion_bridge.Robot) over a MuJoCo model: measure,
    advance one period, the tracking error — and everything the plant records."""

    space = wire.SPATIAL

    def __init__(self, a, robot, chain, arm_hash, steps):
        self.a, self.robot, self.dt = a, robot, a.dt
        self.step, self.steps = 0, steps
        self.arm_hash = arm_hash
        self.home = list(robot.data.qpos[robot.chain_qadr])
        # The joint limits the controller knows (an arm file's may be inside the URDF's, which
        # MuJoCo enforces): the margins are measured to them.
        self.limits = [(j[3], j[4]) for j in chain.joints] if chain is not None else robot.limits
        n = len(self.home)
        # r*_ed: 0.2 m along the flange's z, level at home (docs/book/src/bridge.md §8), from the model.
        r, p = robot.tool_in_base(self.home)
        home_pose = (tuple(r.flatten().tolist()), tuple(p.tolist()))
        self.star = (transpose(home_pose[0]), (0.0, 0.0, wire.TARGET_DISTANCE))
        self._star_t = np.array(self.star[0]).reshape(3, 3).T
        self._star_p = np.array(self.star[1])
        self.z0 = compose3(home_pose, self.star)[1][2]
        self.target = LiftedTarget(a.trajectory, a.dt, self.z0)
        self.rng = np.random.default_rng(a.seed)
        self.noise = a.noise
        self.odometry = a.base_from == "odometry"
        if self.odometry and not robot.wheels:
            raise wire.Fatal("--base-from odometry is wheel odometry: a wheeled base (--platform unicycle) only")
        self.h = self.dt / robot.substeps
        self._yaw_turns, self._last_yaw = 0.0, 0.0
        self._odo = None
        self._cache_step = -1
        self._ep = None
        # Records, one row per period (kept in memory, written at the end).
        self.rows = []
        self.film = []
        self.film_at = set()
        if a.filmstrip > 0:
            for k in range(a.filmstrip):
                self.film_at.add(int(round(k * steps / max(1, a.filmstrip - 1))))
        nu = robot.model.nu
        self.sat_steps = np.zeros(nu, dtype=np.int64)
        self.sat_period = np.zeros(nu)
        self._ratio = np.zeros(nu)
        self._inv_limit = 1.0 / robot.act_limit
        self.substeps_total = 0
        self.slip = np.zeros(2)
        self.traction = np.zeros(2)
        self.plant_ns = []
        self.clipped = False
        self.clipped_periods = 0
        self.last_measured = None
        self.odometry_error = []
        self.joints = n
        # timeseries.csv, written as the run goes (a killed plant leaves its rows on disk).
        self.stream = RowStream(a.out_dir, n, robot.act_names)

    # -- the interface --

    @property
    def t(self):
        return self.step * self.dt

    @property
    def base(self):
        return self.last_measured[1] if self.last_measured else (0.0, 0.0, 0.0)

    @property
    def q(self):
        return self.last_measured[2] if self.last_measured else tuple(self.home)

    def command_of(self, c):
        """(v, ω, joint rates, v_lat, status, the law's ‖e_p‖, joint scale)."""
        n = self.joints
        if c.status != 0:
            return (0.0, 0.0, (0.0,) * n, 0.0, c.status, float("nan"), float("nan"))
        return (c.v, c.omega, tuple(c.joints[i] for i in range(n)), c.v_lat, 0, c.ep_norm, c.joint_scale)

    def zero_command(self):
        return (0.0, 0.0, (0.0,) * self.joints, 0.0, -1, float("nan"), float("nan"))

    def true_base(self):
        x, y, yaw = self.robot.base_pose()
        # Unwrapped: the measured heading is continuous, as the kinematic plant's.
        d = yaw - self._last_yaw
        if d > math.pi:
            self._yaw_turns -= 2.0 * math.pi
        elif d < -math.pi:
            self._yaw_turns += 2.0 * math.pi
        self._last_yaw = yaw
        return x, y, yaw + self._yaw_turns

    def measure(self):
        start = time.perf_counter_ns()
        if self.step == 0 and not self.plant_ns:
            # A second measure of the plant's cost: the process's CPU time over the run.
            self.cpu_start, self.wall_start = time.process_time_ns(), start
        truth = self.true_base()
        base = truth
        if self.odometry:
            base = self._odometry(truth)
        q = self.robot.joints()
        if self.noise:
            e = self.rng.normal(size=3 + len(q))
            base = (base[0] + 1e-3 * e[0], base[1] + 1e-3 * e[1], base[2] + 1e-3 * e[2])
            q = [qi + 5e-4 * ei for qi, ei in zip(q, e[3:])]
        rot, pos, yaw, twist = self.target.at(self.t)
        self.last_measured = (self.t, tuple(base), tuple(q), (pos, rot, yaw, twist), truth)
        self.plant_ns.append(time.perf_counter_ns() - start)
        return self.t, tuple(base), tuple(q), (pos, rot, yaw, twist)

    def _odometry(self, truth):
        angles = self.robot.wheel_angles()
        if self._odo is None:
            self._odo = list(truth)
            self._angles = angles
        r, b = self.robot.wheels["radius"], self.robot.wheels["track"]
        sl, sr = self.robot.wheel_sign
        dl = (angles[0] - self._angles[0]) * sl * r
        dr = (angles[1] - self._angles[1]) * sr * r
        self._angles = angles
        ds, dth = 0.5 * (dl + dr), (dr - dl) / b
        x, y, th = self._odo
        mid = th + 0.5 * dth
        self._odo = [x + ds * math.cos(mid), y + ds * math.sin(mid), th + dth]
        err = math.hypot(self._odo[0] - truth[0], self._odo[1] - truth[1])
        self.odometry_error.append((err, abs(self._odo[2] - truth[2])))
        return tuple(self._odo)

    def _set(self, cmd):
        self.clipped |= self.robot.command(cmd[0], cmd[3], cmd[1], cmd[2])

    def advance(self, previous, command, delay):
        """One period: `previous` until `delay` (to the nearest physics step), then
        `command`."""
        start = time.perf_counter_ns()
        rb = self.robot
        first = int(round(delay / self.h)) if delay > 0.0 else 0
        self.clipped = False
        self.sat_period[:] = 0.0
        force, ratio = rb.data.actuator_force, self._ratio
        for k in range(rb.substeps):
            if k == 0:
                self._set(previous if first > 0 else command)
            elif k == first:
                self._set(command)
            rb.substep()
            np.abs(force, out=ratio)
            ratio *= self._inv_limit
            np.maximum(self.sat_period, ratio, out=self.sat_period)
            self.sat_steps += ratio >= 1.0 - 1e-9
        self.substeps_total += rb.substeps
        self.clipped_periods += self.clipped
        self.target.advance(self.t)
        self.step += 1
        self.plant_ns[-1] += time.perf_counter_ns() - start

    def error(self):
        """e_p of the simulated effector against the target now: (position 3, rotation 3)."""
        if self._cache_step != self.step:
            rot, pos, _, _ = self.target.at(self.t)
            d, tool = self.robot.data, self.robot.tool
            re, pe = d.xmat[tool].reshape(3, 3), d.xpos[tool]
            # r̃ = (r*_ed)⁻¹ r_e⁻¹ r_d, with r*_ed = (S, s): R̃ = Sᵀ R_eᵀ R_d, p̃ = Sᵀ (R_eᵀ (p_d − p_e) − s).
            a = self._star_t @ re.T
            r = a @ np.asarray(rot).reshape(3, 3)
            p = a @ (np.asarray(pos) - pe) - self._star_t @ self._star_p
            self._ep = (tuple(p.tolist()), so3_log(tuple(r.flatten().tolist())),
                        (tuple(re.flatten().tolist()), tuple(pe.tolist())), (rot, pos))
            self._cache_step = self.step
        return self._ep

    def tracking_error(self):
        p, phi, _, _ = self.error()
        return math.sqrt(sum(x * x for x in p) + sum(x * x for x in phi))

    # -- records --

    def record(self, cmd, outcome):
        """The row of this period (the state at its start, the command applied from it)."""
        rb = self.robot
        p, phi, tool, target = self.error()
        t, base, q, _, truth = self.last_measured
        v, vl, w = rb.base_velocity()
        slip = (0.0, 0.0, 0.0, 0.0)
        if rb.wheels:
            rb.wheel_slip(self.slip)
            rb.wheel_traction(self.traction)
            slip = (float(self.slip[0]), float(self.slip[1]), float(self.traction[0]), float(self.traction[1]))
        status = {0: "ok", -1: "stopped" if outcome == "stopped" else "none"}.get(cmd[4], f"rejected:{cmd[4]:#x}")
        if outcome == "held":
            status = "held"
        row = (t, base, q, tool, target, p, phi, cmd, status, truth, (v, vl, w), slip, self.sat_period.copy())
        self.rows.append(row)
        self.stream.write(row)
        if self.step in self.film_at:
            self.film.append((self.step, self.robot.data.qpos.copy(), target))
        self.cpu_end, self.wall_end = time.process_time_ns(), time.perf_counter_ns()


def csv_header(n, names):
    """timeseries.csv's columns: a spatial `companion sim` run's, then the physics'."""
    header = ["t", "x_b", "y_b", "theta_b", "xi"] + [f"q{i}" for i in range(1, n + 1)]
    for p in ("e", "d"):
        header += [f"{c}_{p}" for c in ("x", "y", "z", "qx", "qy", "qz", "qw")]
    header += ["ep_x", "ep_y", "ep_z", "ep_rx", "ep_ry", "ep_rz", "ep_norm", "h_s", "psi", "v", "v_lat", "omega",
               "v_xi"]
    header += [f"u_q{i}" for i in range(1, n + 1)] + ["joint_scale", "status"]
    extra = ["x_true", "y_true", "theta_true", "v_true", "v_lat_true", "omega_true", "ep_position", "ep_rotation",
             "ep_norm_law", "slip_left", "slip_right", "traction_left", "traction_right"] + [f"load_{x}" for x in names]
    return ",".join(header + extra) + "\n"


def csv_line(row):
    """One row of timeseries.csv, and its position, orientation and whole errors."""
    (t, base, q, tool, target, p, phi, cmd, status, truth, vel, slip, sat) = row
    pe = math.sqrt(sum(x * x for x in p))
    re = math.sqrt(sum(x * x for x in phi))
    en = math.sqrt(pe * pe + re * re)
    vals = [t, base[0], base[1], base[2], 0.0, *q]
    for (rot, pos) in (tool, target):
        vals += [*pos, *quat_xyzw(rot)]
    vals += [*p, *phi, en, float("nan"), float("nan"), cmd[0], cmd[3], cmd[1], 0.0, *cmd[2], cmd[6]]
    line = ",".join(repr(float(x)) for x in vals) + "," + status + ","
    tail = [*truth, *vel, pe, re, cmd[5], *slip, *sat.tolist()]
    return line + ",".join(repr(float(x)) for x in tail) + "\n", pe, re, en


class RowStream:
    """timeseries.csv as the run goes, as `companion plant` writes it: the run's folder made at
    the first row (MuJoCo's log moved into it), each row written at once and the file flushed
    every FLUSH_S — a SIGKILLed plant leaves the rows up to its last flush (the controller trims
    a cut last line and counts them in fault.json)."""

    FLUSH_S = 0.05

    def __init__(self, out, joints, names):
        self.out, self.header = out, csv_header(joints, names)
        self.file = None
        self.last_flush = 0.0
        self.pos_err, self.rot_err, self.ep_norm = [], [], []

    def write(self, row):
        if self.file is None:
            os.makedirs(self.out, exist_ok=True)
            mujoco_log_into(self.out)
            self.file = open(os.path.join(self.out, "timeseries.csv"), "w", buffering=1 << 16)
            self.file.write(self.header)
            self.last_flush = time.monotonic()
        line, pe, re, en = csv_line(row)
        self.file.write(line)
        self.pos_err.append(pe)
        self.rot_err.append(re)
        self.ep_norm.append(en)
        now = time.monotonic()
        if now - self.last_flush >= self.FLUSH_S:
            self.file.flush()
            self.last_flush = now

    def close(self):
        if self.file is not None:
            self.file.close()


class PhysicsSummary(wire.Summary):
    """The reference bridge's figures, and each period's row recorded by the robot."""

    def __init__(self, bridge):
        super().__init__()
        self.bridge = bridge
        self.last_counts = dict(bridge.counts)

    def add(self, robot, cmd):
        start = time.perf_counter_ns()
        super().add(robot, cmd)
        c = self.bridge.counts
        outcome = "fresh"
        if c["held"] != self.last_counts["held"]:
            outcome = "held"
        elif c["stopped"] != self.last_counts["stopped"]:
            outcome = "stopped"
        self.last_counts = dict(c)
        robot.record(cmd, outcome)
        # The plant's work per period: measuring, recording and advancing (advance adds its own).
        robot.plant_ns[-1] += time.perf_counter_ns() - start


class MujocoPlant(wire.Bridge):
    """The reference bridge's session with the MuJoCo robot."""

    def __init__(self, a, physical):
        super().__init__(a, physical)
        self.summary = PhysicsSummary(self)
        # Sleep closer to each release than the reference bridge (300 µs of spinning a period
        # is a third of a CPU, which a loaded machine does not give).
        self.spin_ns = a.spin_us * 1000

    def run(self):
        """The session; then the verdict `companion plant` gives a real-time run: exit 7 if
        the robot was stopped or more than --max-miss-fraction of the deadlines were missed."""
        # No garbage collection during the run: its full passes over the growing records
        # stalled the loop for up to 24 ms (the records hold no cycles; collected at the end).
        gc.disable()
        try:
            code = super().run()
        finally:
            gc.enable()
        c, cycles = self.counts, self.robot.step + 1
        failures = []
        behind = self.behind_ns / (self.a.dt * 1e9)  # periods the schedule slipped by
        if behind > self.a.max_miss_fraction * cycles:
            failures.append(
                f"the plant fell behind real time {self.fell_behind} time(s), by {self.behind_ns / 1e9:.2f} s in all "
                f"({100.0 * behind / cycles:.1f} % of the run's {cycles * self.a.dt:.1f} s, more than --max-miss-fraction "
                f"{self.a.max_miss_fraction})"
            )
        if c["stop_events"] > 0:
            failures.append(
                f"the plant stopped the robot {c['stop_events']} time(s) ({c['stopped']} periods stopped): commands "
                "missed their deadlines for longer than --hold-periods"
            )
        if c["deadline_misses"] > self.a.max_miss_fraction * cycles:
            failures.append(
                f"{c['deadline_misses']} of {cycles} periods missed their deadline "
                f"({100.0 * c['deadline_misses'] / cycles:.1f} %, more than --max-miss-fraction {self.a.max_miss_fraction})"
            )
        for f in failures:
            print(f"warning: plant: RUN FAILED: {f}", file=sys.stderr)
        self.failures = failures
        return EXIT_DEADLINES if code == wire.EXIT_OK and failures else code

    def publish(self, seq, flags, delay):
        # The drives' own lag, announced as part of the delay (docs/book/src/bridge.md, "The
        # delay": a bridge adds what it knows of its actuators).
        return super().publish(seq, flags, delay + self.a.actuator_delay)

    def report(self, code, why=None):
        # The session's own JSON (counts, delays) beside the run's files, when there is a run.
        self.a.out = os.path.join(self.a.out_dir, "session.json") if self.robot.rows else None
        if self.a.out:
            os.makedirs(self.a.out_dir, exist_ok=True)
        super().report(code, why)
        write_run(self.a, self.robot, self, code, why)


# ----- open loop: the robot without a controller -------------------------------------------


def parse_open_loop(text, joints):
    """`T:v,omega[,v_lat];…`: segments of T seconds of a constant base command (joints still)."""
    out = []
    for item in filter(None, (x.strip() for x in text.split(";"))):
        dur, _, cmd = item.partition(":")
        try:
            nums = [float(x) for x in cmd.split(",")]
            d = float(dur)
        except ValueError:
            nums, d = [], -1.0
        if not 2 <= len(nums) <= 3 or not d > 0:
            raise wire.Fatal(f"--open-loop {item!r}: SECONDS:V,OMEGA[,V_LAT]")
        v, w = nums[0], nums[1]
        vl = nums[2] if len(nums) == 3 else 0.0
        out.append((d, (v, w, (0.0,) * joints, vl, 0, float("nan"), float("nan"))))
    return out


class OpenLoop:
    """The robot under `--open-loop` commands, period by period, recorded as a session's."""

    def __init__(self, a, physical):
        self.a, self.robot = a, physical
        self.counts = {"fresh": 0, "deadline_misses": 0, "late": 0, "held": 0, "stopped": 0, "stop_events": 0}
        self.summary = PhysicsSummary(self)
        self.segments = parse_open_loop(a.open_loop, physical.joints)

    def run(self):
        steps = self.robot.steps
        ends, acc = [], 0.0
        for d, c in self.segments:
            acc += d
            ends.append((acc, c))
        zero = self.robot.zero_command()
        for n in range(steps + 1):
            if wire.stop_requested():
                raise wire.Interrupted(f"interrupted at period {n}")
            self.robot.measure()
            t = n * self.a.dt
            cmd = next((c for end, c in ends if t < end - 1e-12), zero)
            self.counts["fresh"] += 1
            self.summary.add(self.robot, cmd)
            if n < steps:
                self.robot.advance(cmd, cmd, 0.0)
        return wire.EXIT_OK

    def report(self, code, why=None):
        print(f"mujoco: open loop, {self.robot.steps + 1} periods: {self.summary.line()}", file=sys.stderr)
        write_run(self.a, self.robot, None, code, why)


# ----- the run's files ------------------------------------------------------------------------


def quat_xyzw(rot):
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.asarray(rot, dtype=float))
    if q[0] < 0:
        q = -q
    return (float(q[1]), float(q[2]), float(q[3]), float(q[0]))


def percentiles(values):
    if not values:
        return None
    s = sorted(values)

    def at(p):
        return s[min(len(s) - 1, int(math.ceil(p / 100.0 * len(s))) - 1)]

    return {"p50": at(50), "p90": at(90), "p99": at(99), "p99_9": at(99.9), "max": s[-1], "count": len(s)}


SLIP_SPEED = 0.01  # m/s: a wheel "slips" while its lowest point moves faster over the floor
SLIDING = 0.95  # a wheel "slides" while it uses this much of its friction (tangential / μ normal)


def write_run(a, phys, bridge, code, why):
    """timeseries.csv, summary.json, latency.json, scenario.json, the filmstrip and
    index.html in a.out_dir."""
    out = a.out_dir
    if not phys.rows:
        print(f"mujoco: no period ran: nothing written to {out}", file=sys.stderr)
        return
    phys.stream.close()
    rb = phys.robot
    rows = phys.rows
    names = rb.act_names
    pos_err, rot_err, ep_norm = phys.stream.pos_err, phys.stream.rot_err, phys.stream.ep_norm
    t = np.array([r[0] for r in rows])
    figures = physical_figures(a, phys, t, np.array(pos_err), np.array(rot_err), np.array(ep_norm))
    session = {}
    if bridge is not None:
        s = bridge.summary
        session = {
            "counts": bridge.counts,
            "invalid": bridge.invalid,
            "rejected_steps": bridge.rejected,
            "max_joint_scale": bridge.max_joint_scale,
            "joint_guard_steps": bridge.joint_guard_steps,
            "max_abs_v_commanded": s.max_v,
            "max_abs_omega_commanded": s.max_w,
            "v_sign_changes": s.v_sign_changes,
            "failures": getattr(bridge, "failures", []),
        }
    summary = {
        "plant": "mujoco",
        "exit": code,
        "end": why or "completed",
        "mode": "open loop" if a.open_loop else ("lockstep" if a.lockstep else "real time"),
        "robot": {
            "urdf": rb.urdf.path,
            "base_link": rb.base_link,
            "tip_link": rb.tip_link,
            "platform": rb.platform,
            "chain": rb.chain_names,
            "home": phys.home,
            "arm_hash": f"{phys.arm_hash:#018x}",
            "wheels": None if not rb.wheels else {
                "left": rb.wheels["left"]["joint"], "right": rb.wheels["right"]["joint"],
                "radius": rb.wheels["radius"], "track": rb.wheels["track"],
            },
            "casters": rb.casters,
            # Each drive: its gain kv (from its time constant) and its force or torque limit.
            "drives": {n: {"kv": rb.gains[n], "limit": float(lim)} for n, lim in zip(rb.act_names, rb.act_limit)},
        },
        "trajectory": a.trajectory,
        "dt": a.dt,
        "physics_step": phys.h,
        "base_from": a.base_from,
        "noise": a.noise,
        "seed": a.seed,
        "actuators": rb.table,
        "mujoco": mujoco.__version__,
        # What the plant or MuJoCo changed of the URDF to simulate it, by link (mujoco_robot).
        "physics_fixes": rb.fixes,
        "mesh_fixes": rb.mesh_fixes,
        **figures,
        "session": session,
    }
    with open(os.path.join(out, "summary.json"), "w") as f:
        json.dump(summary, f, indent=2, allow_nan=True)
    with open(os.path.join(out, "scenario.json"), "w") as f:
        json.dump({"target_in_effector": {"xyz": list(phys.star[1]), "rotation": list(phys.star[0])},
                   "trajectory": a.trajectory, "z0": phys.z0, "dt": a.dt}, f, indent=2)
    latency = {
        "mode": summary["mode"],
        # Measuring, recording and advancing one period, by the clock (perf_counter) around them.
        "plant_step_ns": percentiles(phys.plant_ns),
        "plant_step_mean_ns": statistics.fmean(phys.plant_ns),
        # The same cost a second way: the process's CPU time (user + system) and the wall time
        # from the first measurement to the last row, per period. The CPU time also holds the
        # wire's work (publishing, receiving, the wait's polling).
        "process_cpu_per_period_ns": (phys.cpu_end - phys.cpu_start) / len(rows),
        "wall_per_period_ns": (phys.wall_end - phys.wall_start) / len(rows),
        "host": host.node(),
        "cpus": os.cpu_count(),
        "load_average": os.getloadavg(),
        "rt": phys.rt,
    }
    if bridge is not None:
        latency.update({
            "cycles": len(rows),
            "rate_hz": 0 if a.lockstep else 1.0 / a.dt,
            "deadline_ns": 0 if a.lockstep else int(a.deadline_us * 1000),
            "deadline_misses": bridge.counts["deadline_misses"],
            "held_periods": bridge.counts["held"],
            "stopped_periods": bridge.counts["stopped"],
            "late_commands": bridge.counts["late"],
            # Releases more than a period late: the schedule restarted, the run that much longer.
            "fell_behind": bridge.fell_behind,
            "behind_s": bridge.behind_ns / 1e9,
            "real_time_factor": (phys.wall_end - phys.wall_start) / 1e9 / max(a.dt * (len(rows) - 1), 1e-9),
            # The answer's arrival after the measurement's stamp (the delay the plant measured).
            "round_trip_ns": percentiles([int(x * 1e9) for x in bridge.delays]),
        })
    with open(os.path.join(out, "latency.json"), "w") as f:
        json.dump(latency, f, indent=2)
    pictures = film(a, phys, out)
    plots = draw_plots(a, out, t, np.array(pos_err), np.array(rot_err), rows, names)
    write_index(a, out, summary, latency, pictures, plots)
    print_figures(summary, latency)
    print(f"wrote {out}", file=sys.stderr)


def physical_figures(a, phys, t, pos_err, rot_err, ep_norm):
    """The figures of the issue's side-by-side table, from the recorded rows."""
    rb = phys.robot
    rows = phys.rows
    if not rows:
        return {"steps": 0}
    after = t >= 20.0
    q = np.array([r[2] for r in rows])
    lo = np.array([l for l, _ in phys.limits])
    hi = np.array([h for _, h in phys.limits])
    margins = np.minimum(q - lo, hi - q).min(axis=0)
    vel = np.array([r[10] for r in rows])
    acc = np.diff(vel, axis=0) / a.dt if len(rows) > 1 else np.zeros((0, 3))
    cmd = np.array([(r[7][0], r[7][3], r[7][1]) for r in rows])
    fig = {
        "steps": len(rows),
        "final_ep_norm": float(ep_norm[-1]),
        "final_position_error_m": float(pos_err[-1]),
        "final_orientation_error_rad": float(rot_err[-1]),
        "max_position_error_after_20s_m": float(pos_err[after].max()) if after.any() else None,
        "max_orientation_error_after_20s_rad": float(rot_err[after].max()) if after.any() else None,
        "max_ep_norm_after_20s": float(ep_norm[after].max()) if after.any() else None,
        "tracked_after_20s_position_1cm": float((pos_err[after] < 1e-2).mean()) if after.any() else None,
        "tracked_after_20s_ep_norm_1mm": float((ep_norm[after] < 1e-3).mean()) if after.any() else None,
        "joint_margin_min": dict(zip(rb.chain_names, margins.tolist())),
        "smallest_joint_margin": float(margins.min()),
        "joint_limit_reached": bool(margins.min() <= 0.0),
        "max_abs_v_true": float(np.abs(vel[:, 0]).max()),
        "max_abs_v_lat_true": float(np.abs(vel[:, 1]).max()),
        "max_abs_omega_true": float(np.abs(vel[:, 2]).max()),
        "max_abs_v_commanded": float(np.abs(cmd[:, 0]).max()),
        "max_abs_omega_commanded": float(np.abs(cmd[:, 2]).max()),
        "max_abs_acceleration": float(np.abs(acc[:, 0]).max()) if len(acc) else 0.0,
        "p99_abs_acceleration": float(np.percentile(np.abs(acc[:, 0]), 99)) if len(acc) else 0.0,
        "max_abs_angular_acceleration": float(np.abs(acc[:, 2]).max()) if len(acc) else 0.0,
        "p99_abs_angular_acceleration": float(np.percentile(np.abs(acc[:, 2]), 99)) if len(acc) else 0.0,
        "saturation_fraction": dict(zip(rb.act_names, (phys.sat_steps / max(1, phys.substeps_total)).tolist())),
        "drive_limited_fraction": phys.clipped_periods / max(1, len(rows) - 1),
    }
    if rb.wheels:
        slip = np.array([r[11] for r in rows])
        slipping = (slip[:, :2] > SLIP_SPEED).any(axis=1)
        sliding = (slip[:, 2:] >= SLIDING).any(axis=1)
        fig["wheel_slip"] = {
            # A wheel's lowest point moving over the floor faster than this (creep included).
            "threshold_m_per_s": SLIP_SPEED,
            "fraction_of_time": float(slipping.mean()),
            "time_s": float(slipping.sum() * a.dt),
            "distance_m": {"left": float(slip[:, 0].sum() * a.dt), "right": float(slip[:, 1].sum() * a.dt)},
            "max_speed_m_per_s": float(slip[:, :2].max()),
            # A wheel using this much of its friction or more: sliding, not creeping.
            "sliding_traction": SLIDING,
            "sliding_fraction_of_time": float(sliding.mean()),
            "sliding_time_s": float(sliding.sum() * a.dt),
        }
    if phys.odometry_error:
        e = np.array(phys.odometry_error)
        fig["odometry_drift"] = {"final_m": float(e[-1, 0]), "max_m": float(e[:, 0].max()),
                                 "final_rad": float(e[-1, 1]), "max_rad": float(e[:, 1].max())}
    return fig


def print_figures(s, lat):
    f = lambda x, fmt: "—" if x is None else format(x, fmt)  # noqa: E731
    print(
        f"mujoco: final position {f(s.get('final_position_error_m'), '.2e')} m, orientation "
        f"{f(s.get('final_orientation_error_rad'), '.2e')} rad; after 20 s max {f(s.get('max_position_error_after_20s_m'), '.2e')} m "
        f"/ {f(s.get('max_orientation_error_after_20s_rad'), '.2e')} rad, tracked (1 cm) "
        f"{f(s.get('tracked_after_20s_position_1cm'), '.3f')}; smallest joint margin {f(s.get('smallest_joint_margin'), '.4f')}",
        file=sys.stderr,
    )
    if "wheel_slip" in s:
        w = s["wheel_slip"]
        print(f"mujoco: wheels slip over {w['threshold_m_per_s']} m/s {100 * w['fraction_of_time']:.2f} % of the time "
              f"({w['distance_m']} m), slide (traction at their friction's limit) "
              f"{100 * w['sliding_fraction_of_time']:.2f} %", file=sys.stderr)
    sat = {k: round(v, 4) for k, v in s.get("saturation_fraction", {}).items() if v > 0}
    print(f"mujoco: saturated (fraction of physics steps): {sat or 'none'}", file=sys.stderr)
    ps = lat.get("plant_step_ns")
    if ps:
        print(f"mujoco: plant step p50 {ps['p50'] / 1e3:.1f} us, p99 {ps['p99'] / 1e3:.1f} us, max {ps['max'] / 1e3:.1f} us",
              file=sys.stderr)


# ----- pictures ------------------------------------------------------------------------------


def png(path, image):
    """An 8-bit RGB PNG of `image` (H×W×3 uint8)."""
    h, w, _ = image.shape
    raw = b"".join(b"\x00" + image[y].tobytes() for y in range(h))

    def chunk(kind, data):
        c = kind + data
        return len(data).to_bytes(4, "big") + c + zlib.crc32(c).to_bytes(4, "big")

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", w.to_bytes(4, "big") + h.to_bytes(4, "big") + bytes([8, 2, 0, 0, 0])))
        f.write(chunk(b"IDAT", zlib.compress(raw, 6)))
        f.write(chunk(b"IEND", b""))


def film(a, phys, out):
    """The filmstrip: the recorded states rendered off-screen after the run (never during:
    rendering would cost real time). Returns (files, why there are none)."""
    if a.filmstrip <= 0:
        return [], "no filmstrip asked for (--filmstrip 0)"
    if wire.stop_requested():
        return [], "the run was interrupted (SIGINT/SIGTERM): no pictures rendered, the run's files first"
    if not phys.film:
        return [], "the run ended before its first frame"
    rb = phys.robot
    try:
        if NO_GL:
            raise RuntimeError(NO_GL)
        renderer = mujoco.Renderer(rb.model, 360, 480)
    except Exception as e:  # noqa: BLE001 - any failure of the GL stack means: no picture
        why = (f"no off-screen renderer (MUJOCO_GL={GL_WANTED}): {type(e).__name__}: {e}; scripts/setup installs "
               "EGL and Mesa (Debian libegl1 libegl-mesa0 libopengl0 libgl1-mesa-dri)")
        print(f"mujoco: {why}", file=sys.stderr)
        return [], why
    files, images = [], []
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    opt = mujoco.MjvOption()
    for g in range(len(opt.geomgroup)):
        opt.geomgroup[g] = 1
    d = rb.data
    for k, (step, qpos, (rot, pos)) in enumerate(phys.film):
        d.qpos[:] = qpos
        rb.set_target_marker(rot, pos)
        mujoco.mj_forward(rb.model, d)
        b = d.xpos[rb.base]
        cam.lookat[:] = [(b[0] + pos[0]) / 2, (b[1] + pos[1]) / 2, 0.55]
        cam.distance = 2.6 + 0.5 * math.hypot(b[0] - pos[0], b[1] - pos[1])
        cam.azimuth, cam.elevation = 225.0, -22.0
        renderer.update_scene(d, camera=cam, scene_option=opt)
        img = renderer.render()
        name = f"frame-{k:02d}.png"
        png(os.path.join(out, name), img)
        files.append((name, step * a.dt))
        images.append(img)
    renderer.close()
    strip = np.concatenate([im[::2, ::2] for im in images], axis=1)
    png(os.path.join(out, "filmstrip.png"), strip)
    return files, None


def draw_plots(a, out, t, pos_err, rot_err, rows, names):
    """Plots (matplotlib, if installed): the effector's errors, the base's speeds, wheel slip
    and the drives' loads."""
    if a.no_plots or not rows:
        return []
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return []
    made = []
    fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    ax[0].semilogy(t, np.maximum(pos_err, 1e-12))
    ax[0].set_ylabel("position error (m)")
    ax[1].semilogy(t, np.maximum(rot_err, 1e-12))
    ax[1].set_ylabel("orientation error (rad)")
    ax[1].set_xlabel("t (s)")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "errors.png"), dpi=90)
    plt.close(fig)
    made.append("errors.png")
    vel = np.array([r[10] for r in rows])
    cmd = np.array([(r[7][0], r[7][1]) for r in rows])
    fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    ax[0].plot(t, cmd[:, 0], label="v commanded", lw=0.8)
    ax[0].plot(t, vel[:, 0], label="v (simulated)", lw=0.8)
    ax[0].set_ylabel("m/s")
    ax[0].legend(loc="upper right")
    ax[1].plot(t, cmd[:, 1], label="ω commanded", lw=0.8)
    ax[1].plot(t, vel[:, 2], label="ω (simulated)", lw=0.8)
    ax[1].set_ylabel("rad/s")
    ax[1].set_xlabel("t (s)")
    ax[1].legend(loc="upper right")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "base.png"), dpi=90)
    plt.close(fig)
    made.append("base.png")
    sat = np.array([r[12] for r in rows])
    fig, ax = plt.subplots(figsize=(8, 4))
    for i, nm in enumerate(names):
        ax.plot(t, sat[:, i], lw=0.7, label=nm)
    ax.set_ylabel("|force| / limit")
    ax.set_xlabel("t (s)")
    ax.legend(fontsize=6, ncol=3, loc="upper right")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "loads.png"), dpi=90)
    plt.close(fig)
    made.append("loads.png")
    if any(any(x != 0.0 for x in r[11]) for r in rows[:: max(1, len(rows) // 100)]):
        slip = np.array([r[11][:2] for r in rows])
        fig, ax = plt.subplots(figsize=(8, 3))
        ax.plot(t, slip[:, 0], lw=0.7, label="left")
        ax.plot(t, slip[:, 1], lw=0.7, label="right")
        ax.axhline(SLIP_SPEED, color="k", lw=0.5, ls="--")
        ax.set_ylabel("wheel slip (m/s)")
        ax.set_xlabel("t (s)")
        ax.legend()
        fig.tight_layout()
        fig.savefig(os.path.join(out, "slip.png"), dpi=90)
        plt.close(fig)
        made.append("slip.png")
    return made


def write_index(a, out, summary, latency, pictures, plots):
    files, why = pictures
    esc = lambda s: str(s).replace("&", "&amp;").replace("<", "&lt;")  # noqa: E731
    parts = [
        "<!doctype html><meta charset='utf-8'><title>companion: MuJoCo plant</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:1em auto}img{max-width:100%}"
        "td,th{padding:2px 8px;text-align:left}</style>",
        f"<h1>MuJoCo plant: {esc(os.path.basename(summary['robot']['urdf']))} on the "
        f"{esc(summary['robot']['platform'])} base, lifted trajectory {summary['trajectory']}</h1>",
        f"<p>{esc(summary['mode'])}, {summary['steps'] if 'steps' in summary else 0} periods of {a.dt * 1e3:g} ms; "
        f"ended: {esc(summary['end'])} (exit {summary['exit']})</p>",
        "<h2>Filmstrip</h2>",
    ]
    if files:
        parts.append("<p><img src='filmstrip.png' alt='filmstrip'></p><p>")
        parts += [f"<a href='{f}'>t = {t:.1f} s</a> " for f, t in files]
        parts.append("</p>")
    else:
        parts.append(f"<p>No pictures: {esc(why)}</p>")
    parts.append("<h2>Figures</h2><table>")
    for k in ("final_position_error_m", "final_orientation_error_rad", "max_position_error_after_20s_m",
              "max_orientation_error_after_20s_rad", "tracked_after_20s_position_1cm", "smallest_joint_margin",
              "max_abs_v_true", "max_abs_omega_true", "max_abs_acceleration", "drive_limited_fraction"):
        parts.append(f"<tr><th>{k}</th><td>{esc(summary.get(k))}</td></tr>")
    if "wheel_slip" in summary:
        parts.append(f"<tr><th>wheel_slip</th><td>{esc(json.dumps(summary['wheel_slip']))}</td></tr>")
    parts.append(f"<tr><th>saturation_fraction</th><td>{esc(json.dumps(summary.get('saturation_fraction')))}</td></tr>")
    parts.append(f"<tr><th>plant step (ns)</th><td>{esc(json.dumps(latency.get('plant_step_ns')))}</td></tr>")
    parts.append("</table>")
    for p in plots:
        parts.append(f"<p><img src='{p}' alt='{p}'></p>")
    parts.append("<p>Files: <a href='timeseries.csv'>timeseries.csv</a> · <a href='summary.json'>summary.json</a> · "
                 "<a href='latency.json'>latency.json</a> · <a href='scenario.json'>scenario.json</a></p>")
    with open(os.path.join(out, "index.html"), "w") as f:
        f.write("\n".join(parts) + "\n")


# ----- the command line ------------------------------------------------------------------------


class Parser(argparse.ArgumentParser):
    """The plant's flags: a bad one is one line (exit 2), no abbreviations (`companion hil`
    checks the flags it forwards by their names)."""

    def error(self, message):
        self.exit(wire.EXIT_ERROR, f"error: {message} (companion_mujoco.py --help lists the flags)\n")


def parse(argv):
    p = Parser(description=__doc__.split("\n\n")[0], allow_abbrev=False)
    wire.session_arguments(p)
    p.set_defaults(events=True)
    p.add_argument("--no-events", dest="events", action="store_false", help="poll instead of notifying")
    p.add_argument("--arm", default="ur5", help="ur5, an arm file (.toml; the UR5's) or a URDF (.urdf)")
    p.add_argument("--urdf", help="with an arm file: the URDF to simulate (default: the UR5's ur5_robot.urdf)")
    wire.urdf_arguments(p)
    p.add_argument("--mount", default="0,0,0,0,0,0", help="a URDF arm on the omni base: x,y,z,roll,pitch,yaw")
    p.add_argument("--platform", choices=["unicycle", "omni"], default="omni")
    p.add_argument("--trajectory", type=int, choices=[1, 2], default=1, help="the paper's trajectory, lifted")
    p.add_argument("--out", dest="out_dir", default="out/mujoco", help="the run's folder")
    p.add_argument("--actuators", action="append", default=[], help="an actuator table over the default")
    p.add_argument("--set", action="append", default=[], help="one table entry, SECTION.KEY=VALUE")
    p.add_argument("--base-from", choices=["mocap", "odometry"], default="mocap",
                   help="the measured base pose: the simulator's (a motion-capture system) or wheel odometry")
    p.add_argument("--noise", action="store_true", help="measurement noise: σ 1 mm, 1 mrad (base), 0.5 mrad (joints)")
    p.add_argument("--seed", type=int, default=1, help="the noise's seed")
    p.add_argument("--filmstrip", type=int, default=8, help="frames rendered after the run (0: none)")
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--max-miss-fraction", type=float, default=0.05,
                   help="real time: a run missing more of its deadlines fails (exit 7), as does one that stopped the robot")
    p.add_argument("--rt", action="store_true",
                   help="real-time setup: SCHED_FIFO, one CPU, memory locked (a missing privilege is a warning)")
    p.add_argument("--rt-priority", type=int, default=80, help="SCHED_FIFO priority with --rt (1-99)")
    p.add_argument("--cpu", type=int, help="the plant's CPU with --rt (default: the last one)")
    p.add_argument("--spin-us", type=float, default=100.0,
                   help="real time: spin this long before each release, sleep before (µs)")
    p.add_argument("--actuator-delay", type=float, default=0.0,
                   help="s added to the delay announced in every measurement (the drives' lag)")
    p.add_argument("--open-loop", help="no controller: base commands SECONDS:V,OMEGA[,V_LAT];… (joints still)")
    p.add_argument("--check", action="store_true",
                   help="check the flags, the actuator table and the robot (MuJoCo loads it), print CHECKED and exit "
                   "0, or the reason and exit 2; nothing is written (`companion hil --plant mujoco` does this first)")
    a = wire.finish_arguments(p.parse_args(argv))
    a.out = None  # set at the end (MujocoPlant.report)
    a.rows = None
    return a


def real_time_setup(a):
    """--rt: SCHED_FIFO at --rt-priority, pinned to --cpu, memory locked — what `companion
    plant --rt` does; each refusal is a warning. Returns what was granted (latency.json)."""
    got = {"requested": a.rt, "fifo": False, "memory_locked": False, "cpu": None}
    if not a.rt:
        return got
    cpu = a.cpu if a.cpu is not None else (os.cpu_count() or 1) - 1
    try:
        os.sched_setaffinity(0, {cpu})
        got["cpu"] = cpu
    except OSError as e:
        print(f"warning: --rt: CPU {cpu}: {e}", file=sys.stderr)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(a.rt_priority))
        got["fifo"] = True
    except OSError as e:
        print(f"warning: --rt: SCHED_FIFO {a.rt_priority}: {e} (running with the default scheduler)", file=sys.stderr)
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    if libc.mlockall(3) == 0:  # MCL_CURRENT | MCL_FUTURE
        got["memory_locked"] = True
    else:
        print(f"warning: --rt: mlockall: {os.strerror(ctypes.get_errno())}", file=sys.stderr)
    return got


def main(argv=None):
    a = parse(argv)
    for bad, why in ((not (a.dt > 0 and math.isfinite(a.dt)), "--dt must be positive"),
                     (not (a.duration > 0 and math.isfinite(a.duration)), "--duration must be positive"),
                     (a.filmstrip < 0 or a.filmstrip > 100, "--filmstrip: 0 to 100 frames"),
                     (not 1 <= a.rt_priority <= 99, "--rt-priority: 1 to 99"),
                     (a.cpu is not None and not 0 <= a.cpu < (os.cpu_count() or 1), "--cpu: not a CPU of this machine"),
                     (not (math.isfinite(a.actuator_delay) and 0.0 <= a.actuator_delay <= 8 * a.dt),
                      "--actuator-delay: seconds in [0, 8 periods]"),
                     (not (math.isfinite(a.spin_us) and 0.0 <= a.spin_us <= 1e6), "--spin-us: 0 to 1000000 µs"),
                     (not (math.isfinite(a.deadline_us) and a.deadline_us > 0), "--deadline-us must be positive"),
                     (a.hold_periods < 0, "--hold-periods must be 0 or more"),
                     (not (math.isfinite(a.silence_ms) and a.silence_ms > 0), "--silence-ms must be positive"),
                     (not (math.isfinite(a.peer_timeout) and a.peer_timeout > 0), "--peer-timeout must be positive"),
                     (not (math.isfinite(a.startup_timeout) and a.startup_timeout >= 0),
                      "--startup-timeout must be 0 or more"),
                     (not 0.0 <= a.max_miss_fraction <= 1.0, "--max-miss-fraction: a fraction in [0, 1]"),
                     (a.progress < 0, "--progress must be 0 or more")):
        if bad:
            print(f"error: {why}", file=sys.stderr)
            return wire.EXIT_ERROR
    if os.path.exists(a.out_dir) and not os.path.isdir(a.out_dir):
        print(f"error: --out {a.out_dir} is a file, not a folder", file=sys.stderr)
        return wire.EXIT_ERROR
    steps = int(round(a.duration / a.dt))

    def make():
        try:
            table = mujoco_robot.load_table(a.actuators, a.set)
        except mujoco_robot.ModelError as e:
            raise wire.Fatal(str(e))
        robot, _chain, arm_hash = build_robot(a, table)
        phys = Physical(a, robot, _chain, arm_hash, steps)
        if a.open_loop:
            parse_open_loop(a.open_loop, phys.joints)
        if a.check:
            raise Checked()
        if robot.fixes:
            by_link = {}
            for f in robot.fixes:
                by_link.setdefault(f["link"] or "other links", []).append(f["fix"])
            print(f"mujoco: {len(robot.fixes)} physics fixes to simulate the URDF (summary.json physics_fixes):",
                  file=sys.stderr)
            for link, fixes in by_link.items():
                print(f"mujoco:   {link}: {'; '.join(fixes)}", file=sys.stderr)
        if robot.mesh_fixes:
            print(f"mujoco: {len(robot.mesh_fixes)} visual meshes replaced or dropped (pictures only; summary.json "
                  "mesh_fixes)", file=sys.stderr)
        phys.rt = real_time_setup(a)
        if a.open_loop:
            return OpenLoop(a, phys)
        return MujocoPlant(a, phys)

    if a.check:
        try:
            make()
        except Checked:
            print("CHECKED", flush=True)
            return wire.EXIT_OK
        except wire.Fatal as e:
            print(f"error: {e}", file=sys.stderr)
            return wire.EXIT_ERROR
        except Exception:  # noqa: BLE001 - a bug, said as one
            import traceback

            traceback.print_exc()
            print("error: an unexpected exception checking the plant (a bug: please report it)", file=sys.stderr)
            return wire.EXIT_BUG
    return wire.serve(make)


class Checked(Exception):
    """--check: the robot was built; nothing more is done."""


if __name__ == "__main__":
    wire.exit_with(main())
