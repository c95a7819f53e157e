#!/usr/bin/env python3
"""A stand-in for a ROS 2 mobile manipulator, over Eclipse Cyclone DDS (the middleware under
rmw_cyclonedds) with ROS 2's topic names, type names and layouts (ros2_msgs.py) — no ROS
installation. It is the kinematic robot `companion ros2` drives in the tests:

- publishes `sensor_msgs/JointState` (the arm's joints by name, plus `--extra-joint`s the node
  must ignore) and `nav_msgs/Odometry` at `--rate`, stamped with the system clock;
- integrates the commands it receives from the moment they arrive: the base's
  `geometry_msgs/TwistStamped` (exactly, as a body twist held constant) and the joints'
  `std_msgs/Float64MultiArray` (in `--joint-names` order);
- with `--target topics` publishes the target (lifted trajectory 1, in closed form) as a
  `geometry_msgs/PoseStamped` and its body twist as a `geometry_msgs/TwistStamped`; with
  `--target node` reads the target the node generates and checks it against the same closed
  form;
- measures the tracking error with its own kinematics (the reference bridge's reading of the
  arm file or of a URDF chain, `--arm robot.urdf --base-link B --tip-link T --home …`:
  bridges/python/companion_bridge.py), independently of the node;
- `--inject KIND@T` for `--inject-for` seconds from T seconds after the first command: `stale`
  (joint states stamped 1 s old), `nan` (a NaN joint position), `names` (the arm's last joint
  left out), `silent` (no joint states);
- on SIGINT or SIGTERM writes `--out` (JSON) and exits 0.

    python3 bridges/ros2/standin_robot.py --arm examples/arms/ur5.toml --rate 1000 --out r.json &
    companion ros2 --arm ur5 --duration 15
"""

import argparse
import json
import math
import os
import signal
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "python"))

import ros2_msgs as m  # noqa: E402
from standin_kinematics import (  # noqa: E402
    epoch,
    final_errors,
    percentiles,
    quaternion_z,
    robot_arguments,
    rotation_of,
    set_up,
)
from cyclonedds.core import Policy, Qos, ReadCondition, SampleState, ViewState, InstanceState, WaitSet  # noqa: E402
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402
from cyclonedds.util import duration  # noqa: E402

STOP = False


def _stop(*_):
    global STOP
    STOP = True


def dds_topic(name):
    """ROS 2's topic `/a/b` on DDS: `rt/a/b`."""
    return "rt" + (name if name.startswith("/") else "/" + name)


def qos(args, depth=None):
    rel = Policy.Reliability.Reliable(duration(milliseconds=100)) if args.reliable else Policy.Reliability.BestEffort
    return Qos(rel, Policy.History.KeepLast(depth or 10), Policy.Durability.Volatile)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    robot_arguments(p, 1000.0)
    p.add_argument("--best-effort", dest="reliable", action="store_false")
    p.add_argument("--trace", action="store_true", help="every error sample (t, ‖p̃‖, ‖e_p‖) in --out")
    args = p.parse_args(argv)
    signal.signal(signal.SIGINT, _stop)
    signal.signal(signal.SIGTERM, _stop)

    robot, chain, names, n, traj, inject, inject_at = set_up(args)

    dp = DomainParticipant(args.domain_id)
    q = qos(args)

    def writer(name, t):
        return DataWriter(dp, Topic(dp, dds_topic(name), t, qos=q), qos=q)

    def reader(name, t, depth=None):
        qq = qos(args, depth)
        return DataReader(dp, Topic(dp, dds_topic(name), t, qos=q), qos=qq)

    joints_w = writer(args.joint_states, m.JointState)
    odom_w = writer(args.odom, m.Odometry)
    base_r = reader(args.base_command, m.TwistStamped, 100)
    joint_r = reader(args.joint_command, m.Float64MultiArray, 100)
    diag_r = reader(args.diagnostics, m.DiagnosticArray, 100)
    if args.target == "topics":
        tpose_w = writer(args.target_pose, m.PoseStamped)
        ttwist_w = writer(args.target_twist, m.TwistStamped)
        target_r = None
    else:
        target_r = reader(args.target_pose, m.PoseStamped, 1000)
    ws = WaitSet(dp)
    any_state = SampleState.Any | ViewState.Any | InstanceState.Any
    for r in (base_r, joint_r):
        ws.attach(ReadCondition(r, any_state))

    period = 1.0 / args.rate
    every = max(1, int(round(args.rate / 100.0)))
    t0_mono = time.monotonic()
    t0_real_ns = time.time_ns()
    last_mono = t0_mono
    next_pub = t0_mono
    res = {
        "published": 0, "late_publishes": 0, "base_commands": 0, "joint_commands": 0,
        "zero_commands": 0, "nonzero_commands": 0, "last_command_zero": None, "commands_in_fault": [0, 0], "commands_after_fault": [0, 0],
        "bad_command_length": 0, "target_messages": 0, "target_max_deviation": 0.0, "diagnostics": 0,
        "diagnostic_levels": {}, "errors": [], "publish_gaps_ms": [],
    }  # fmt: skip
    first_cmd = None
    latencies = []  # a base command's stamp to its application here (ms)
    s0_ns = None  # the node's run's epoch, from its first target
    stamps = []  # the last stamps published
    last_pub_mono = None

    def target_at_real(ns):
        if args.target == "topics":
            return traj.pose((ns - t0_real_ns) * 1e-9)
        if s0_ns is None:
            return None
        return traj.pose((ns - s0_ns) * 1e-9)

    def window(now):
        if first_cmd is None or inject_at is None:
            return None
        t = now - first_cmd
        if inject_at <= t < inject_at + args.inject_for:
            return "in"
        if t >= inject_at + args.inject_for + 0.2:
            return "after"
        return None

    def note_command(is_zero, now):
        nonlocal first_cmd
        if first_cmd is None and not is_zero:
            first_cmd = now
        res["zero_commands" if is_zero else "nonzero_commands"] += 1
        res["last_command_zero"] = is_zero
        w = window(now)
        # Allow 50 ms of transition after the fault starts (a silent publisher is noticed
        # after --silence-ms).
        if w == "in" and now - first_cmd >= inject_at + 0.05:
            res["commands_in_fault"][0 if is_zero else 1] += 1
        elif w == "after":
            res["commands_after_fault"][0 if is_zero else 1] += 1

    while not STOP:
        now = time.monotonic()
        timeout = max(0.0, next_pub - now)
        ws.wait(duration(microseconds=int(timeout * 1e6)))
        # Both clocks at once: the state is integrated to `now`, stamped and judged at `now_ns`.
        now, now_ns = time.monotonic(), time.time_ns()
        robot.advance(now - last_mono)
        last_mono = now
        for s in base_r.take(N=100):
            if not isinstance(s, m.TwistStamped):
                continue
            tw = s.twist
            robot.v = (tw.linear.x, tw.linear.y, tw.angular.z)
            res["base_commands"] += 1
            latencies.append((now_ns - s.header.stamp.ns()) * 1e-6)
        for s in joint_r.take(N=100):
            if not isinstance(s, m.Float64MultiArray):
                continue
            if len(s.data) != n:
                res["bad_command_length"] += 1
                continue
            robot.qdot = list(s.data)
            res["joint_commands"] += 1
            note_command(all(x == 0.0 for x in s.data) and robot.v == (0.0, 0.0, 0.0), now)
        for s in diag_r.take(N=100):
            if isinstance(s, m.DiagnosticArray) and s.status:
                res["diagnostics"] += 1
                lv = str(int(s.status[0].level))
                res["diagnostic_levels"][lv] = res["diagnostic_levels"].get(lv, 0) + 1
        if target_r is not None:
            for s in target_r.take(N=1000):
                if not isinstance(s, m.PoseStamped):
                    continue
                stamp = s.header.stamp.ns()
                if s0_ns is None:
                    pp = s.pose.position
                    s0_ns = epoch(traj, stamp, (pp.x, pp.y, pp.z), stamps)
                res["target_messages"] += 1
                if res["target_messages"] % every or chain is None:
                    continue
                want = traj.pose((stamp - s0_ns) * 1e-9)[1]
                got = (s.pose.position.x, s.pose.position.y, s.pose.position.z)
                dev = math.sqrt(sum((a - b) ** 2 for a, b in zip(got, want)))
                dev = max(dev, max(abs(a - b) for a, b in zip(rotation_of(s.pose.orientation), (1, 0, 0, 0, 1, 0, 0, 0, 1))))
                res["target_max_deviation"] = max(res["target_max_deviation"], dev)
        if now < next_pub:
            continue
        if now - next_pub > period:
            res["late_publishes"] += 1
            next_pub = now
        next_pub += period
        stamp_ns = now_ns
        stamps.append(stamp_ns)
        del stamps[:-50]
        fault = window(now) == "in" and inject
        js = m.JointState(header=m.Header(stamp=m.Time.of_ns(stamp_ns - (1_000_000_000 if fault == "stale" else 0)), frame_id=""))
        js.name = list(args.extra_joint) + names
        js.position = [0.0] * len(args.extra_joint) + list(robot.q)
        if fault == "nan":
            js.position[-1] = float("nan")
        if fault == "names":
            js.name, js.position = js.name[:-1], js.position[:-1]
        if fault != "silent":
            joints_w.write(js)
        x, y, th = robot.base
        od = m.Odometry(header=m.Header(stamp=m.Time.of_ns(stamp_ns), frame_id="odom"), child_frame_id="base_link")
        od.pose.pose.position = m.Point(x=x, y=y, z=0.0)
        od.pose.pose.orientation = m.Quaternion(*quaternion_z(th))
        od.twist.twist.linear.x, od.twist.twist.angular.z = robot.v[0], robot.v[2]
        odom_w.write(od)
        if args.target == "topics":
            rot, pos = traj.pose((stamp_ns - t0_real_ns) * 1e-9)
            lin, ang = traj.twist((stamp_ns - t0_real_ns) * 1e-9)
            hdr = m.Header(stamp=m.Time.of_ns(stamp_ns), frame_id="odom")
            tpose_w.write(m.PoseStamped(header=hdr, pose=m.Pose(position=m.Point(*pos), orientation=m.Quaternion())))
            ttwist_w.write(m.TwistStamped(header=hdr, twist=m.Twist(linear=m.Vector3(*lin), angular=m.Vector3(*ang))))
        res["published"] += 1
        if last_pub_mono is not None:
            res["publish_gaps_ms"].append((now - last_pub_mono) * 1e3)
        last_pub_mono = now
        # The error (forward kinematics in Python) at most 100 times a second: at 1 kHz every
        # publish would take the CPU the robot's own timing needs.
        tgt = target_at_real(now_ns) if res["published"] % every == 0 else None
        if tgt is not None and first_cmd is not None and chain is not None:
            pos, full = robot.errors(tgt)
            res["errors"].append((now - first_cmd, pos, full))

    errs = res.pop("errors")
    res["publish_gap_ms"] = percentiles(res.pop("publish_gaps_ms"))
    res["command_latency_ms"] = percentiles(latencies)
    res["first_command_s"] = None if first_cmd is None else first_cmd - t0_mono
    final_errors(res, errs, args.final_at)
    if args.trace:
        res["trace"] = errs
    with open(args.out, "w") as f:
        json.dump(res, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
