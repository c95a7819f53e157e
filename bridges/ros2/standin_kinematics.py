"""The stand-in robots' kinematics, shared by the Cyclone DDS one (standin_robot.py) and the
rclpy one (rclpy_robot.py): a kinematic mobile manipulator that integrates the commands it
receives (the base's body twist held constant, exactly; the joints' velocities), lifted
trajectory 1 in closed form, and the tracking error by the reference bridge's own kinematics
(bridges/python/companion_bridge.py), independently of the node.
"""

import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))

from companion_bridge import (  # noqa: E402
    urdf_arguments,
    LIFT_AMPLITUDE,
    LIFT_PERIOD,
    TARGET_DISTANCE,
    Chain,
    UrdfChain,
    compose3,
    inverse3,
    planar_pose3,
    so3_log,
    transpose,
)

UR5_JOINTS = "shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint"


def quaternion_z(yaw):
    """(x, y, z, w) of a rotation by `yaw` about z."""
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def yaw_of(q):
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def rotation_of(q):
    x, y, z, w = q.x, q.y, q.z, q.w
    return (
        1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
        2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
        2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y),
    )  # fmt: skip


def se2_step(pose, v, v_lat, omega, dt):
    """The platform moved by the body twist (v, v_lat, ω) held for dt (exactly)."""
    x, y, th = pose
    phi = omega * dt
    if abs(phi) < 1e-9:
        a, b = 1.0 - phi * phi / 6.0, phi / 2.0
    else:
        a, b = math.sin(phi) / phi, (1.0 - math.cos(phi)) / phi
    dx, dy = (a * v - b * v_lat) * dt, (b * v + a * v_lat) * dt
    s, c = math.sin(th), math.cos(th)
    return (x + c * dx - s * dy, y + s * dx + c * dy, th + phi)


class LiftedTrajectory1:
    """The paper's trajectory 1 lifted (docs/protocol.md §8), in closed form: the circle of
    radius 0.1 m and period 4 s from r_bd(0) = (2.6, 1, z0), level, and z0 + A sin(2πt/T)."""

    def __init__(self, height):
        self.height = height

    def pose(self, t):
        a = math.pi * t / 2.0
        p = (2.6 + 0.1 * (math.cos(a) - 1.0), 1.0 - 0.1 * math.sin(a),
             self.height + LIFT_AMPLITUDE * math.sin(2 * math.pi * t / LIFT_PERIOD))  # fmt: skip
        return (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0), p

    def twist(self, t):
        k, a, w = math.pi / 20.0, math.pi * t / 2.0, 2 * math.pi / LIFT_PERIOD
        return (-k * math.sin(a), -k * math.cos(a), LIFT_AMPLITUDE * w * math.cos(w * t)), (0.0, 0.0, 0.0)


class Robot:
    def __init__(self, chain, joints):
        self.chain = chain
        self.q = [j[5] for j in chain.joints]
        self.base = (0.0, 0.0, 0.0)
        self.v = (0.0, 0.0, 0.0)
        self.qdot = [0.0] * joints
        home = chain.end_effector(self.q)
        # r*_ed: TARGET_DISTANCE along the flange's z, level when the arm is at home.
        self.star = (transpose(home[0]), (0.0, 0.0, TARGET_DISTANCE))
        self.height = compose3(home, self.star)[1][2]

    def advance(self, dt):
        if dt <= 0:
            return
        self.base = se2_step(self.base, self.v[0], self.v[1], self.v[2], dt)
        self.q = [q + dt * d for q, d in zip(self.q, self.qdot)]

    def effector_star(self):
        return compose3(compose3(planar_pose3(self.base), self.chain.end_effector(self.q)), self.star)

    def errors(self, target):
        """(‖p̃‖ in metres, ‖e_p‖) against the target pose."""
        e = self.effector_star()
        r = compose3(inverse3(e), target)
        pos = math.sqrt(sum(x * x for x in r[1]))
        rot = math.sqrt(sum(x * x for x in so3_log(r[0])))
        return pos, math.sqrt(pos * pos + rot * rot)


class PlanarRobot(Robot):
    """The unicycle carrying the paper's RPR arm: integrated as the spatial robot, not measured."""

    def __init__(self):
        self.q = [0.0, 0.35, 0.0]
        self.base = (0.0, 0.0, 0.0)
        self.v = (0.0, 0.0, 0.0)
        self.qdot = [0.0] * 3
        self.height = 0.0


def make_robot(args):
    """(robot, chain or None, joint names, joint count) of `--arm` as the stand-ins read it: rpr
    (the paper's planar arm, its joints only, no error measured), a URDF chain, or an arm file."""
    if args.arm == "rpr":
        return PlanarRobot(), None, (args.joint_names or UR5_JOINTS).split(","), 3
    if args.arm.endswith(".urdf"):
        chain = UrdfChain(args.arm, args.base_link, args.tip_link, args.home, args.srdf, args.home_state)
        names = args.joint_names.split(",") if args.joint_names else chain.joint_names
        return Robot(chain, len(chain.joints)), chain, names, len(chain.joints)
    chain = Chain(args.arm)
    return Robot(chain, len(chain.joints)), chain, (args.joint_names or UR5_JOINTS).split(","), len(chain.joints)


def percentiles(xs):
    """p50, p99 and max of a list (None when empty)."""
    xs = sorted(xs)
    return {
        "p50": xs[len(xs) // 2] if xs else None,
        "p99": xs[int(len(xs) * 0.99)] if xs else None,
        "max": xs[-1] if xs else None,
    }


def final_errors(res, errs, final_at):
    """The error figures at the node's end (`--final-at`): the last sample 50 ms before it and
    the largest position error in the 2 s before that."""
    if final_at is not None and errs:
        before = [e for e in errs if e[0] <= final_at - 0.05]
        last2 = [e for e in before if e[0] >= final_at - 2.05]
        res["final_position_error"] = before[-1][1] if before else None
        res["final_ep_norm"] = before[-1][2] if before else None
        res["max_position_error_last_2_s"] = max(e[1] for e in last2) if last2 else None
    res["error_samples"] = len(errs)


def robot_arguments(p, rate):
    """The flags both stand-ins take: the arm, the topics, the faults to inject, the figures."""
    p.add_argument("--arm", required=True, help="arm file (TOML), a URDF, or rpr (the paper's planar arm)")
    urdf_arguments(p)
    p.add_argument("--joint-names", default=None, help="default: a URDF's, else the UR5's")
    p.add_argument("--extra-joint", action="append", default=None,
                   help="listed too, first (default: torso_lift_joint, or head_1_joint if the arm has it)")
    p.add_argument("--rate", type=float, default=rate)
    p.add_argument("--domain-id", type=int, default=0)
    p.add_argument("--target", choices=["topics", "node"], default="node")
    p.add_argument("--joint-states", default="/joint_states")
    p.add_argument("--odom", default="/mobile_base_controller/odom")
    p.add_argument("--base-command", default="/mobile_base_controller/cmd_vel")
    p.add_argument("--joint-command", default="/arm_velocity_controller/commands")
    p.add_argument("--target-pose", default="/companion/target_pose")
    p.add_argument("--target-twist", default="/companion/target_twist")
    p.add_argument("--diagnostics", default="/diagnostics")
    p.add_argument("--inject", default=None, help="stale@T, nan@T, names@T or silent@T (s after the first command)")
    p.add_argument("--inject-for", type=float, default=0.5)
    p.add_argument("--final-at", type=float, default=None,
                   help="the node's --duration: the final error is taken this long after the first command")
    p.add_argument("--out", required=True)


def set_up(args):
    """(robot, chain, names, n, trajectory, injected fault, its start) of the parsed flags."""
    robot, chain, names, n = make_robot(args)
    if args.extra_joint is None:
        args.extra_joint = ["head_1_joint" if "torso_lift_joint" in names else "torso_lift_joint"]
    if len(names) != n:
        raise SystemExit(f"--joint-names has {len(names)} names, the arm {n} joints")
    inject, inject_at = None, None
    if args.inject:
        inject, at = args.inject.split("@")
        inject_at = float(at)
    return robot, chain, names, n, LiftedTrajectory1(robot.height), inject, inject_at


def epoch(traj, stamp_ns, position, stamps):
    """The node's run's epoch (ns) from its first generated target, stamped `stamp_ns` at
    `position`: the node starts its run at the older of its first measurement's two stamps
    (joint state, odometry) and stamps the target with the newer — one of this robot's own
    stamps, `stamps` (those it published, newest last), up to a few of its periods apart when the
    two messages reach the node in different periods. The epoch is the one of them that puts the
    first target on the closed form."""
    candidates = [s for s in stamps if s <= stamp_ns][-4:] or [stamp_ns]

    def off(s0):
        return math.dist(position, traj.pose((stamp_ns - s0) * 1e-9)[1])

    return min(candidates, key=off)
