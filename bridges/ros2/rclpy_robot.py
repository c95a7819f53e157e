#!/usr/bin/env python3
"""A stand-in for a ROS 2 mobile manipulator written as an rclpy node: ROS 2's own client
library and its default middleware (rmw_fastrtps_cpp, Fast DDS), from the `ros-jazzy-*` wheels
scripts/setup installs into target/py. The robot `companion ros2` drives in the tests, with the
same kinematics as the Cyclone DDS stand-in (standin_kinematics.py):

- publishes `sensor_msgs/msg/JointState` (the arm's joints by name, plus an extra joint the
  node must ignore) and `nav_msgs/msg/Odometry` at `--rate`, stamped with the system clock;
- integrates the commands it receives from the moment they arrive (`geometry_msgs/msg/TwistStamped`
  for the base, `std_msgs/msg/Float64MultiArray` for the joints), in its subscriptions' callbacks;
- reads the target the node generates (`--target node`) and checks it against the closed form
  of lifted trajectory 1, or publishes that target (`--target topics`);
- measures the tracking error with its own kinematics; reads the node's diagnostics and its
  `/rosout` lines;
- `--inject KIND@T` for `--inject-for` s from T s after the first command: `stale`, `nan`,
  `names`, `silent` (as the Cyclone stand-in);
- once the node runs, records the graph as ROS sees it (`--graph-at` s after the first command):
  the nodes, the topics and their types, every endpoint of the node's topics with its node, type,
  type hash and QoS, as rclpy's graph API gives them;
- on SIGINT or SIGTERM writes `--out` (JSON) and exits 0.

rclpy's executor is spun with `spin_once` in this one thread (its EventsExecutor's shutdown
hangs while another thread spins).

    target/py/bin/python bridges/ros2/rclpy_robot.py --arm examples/arms/ur5.toml --rate 100 --out r.json &
    target/release/companion ros2 --arm ur5 --dt 0.01 --duration 15
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

import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy.signals import SignalHandlerOptions  # noqa: E402

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PoseStamped, TwistStamped  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rcl_interfaces.msg import Log  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402

from standin_kinematics import (  # noqa: E402
    epoch,
    final_errors,
    percentiles,
    quaternion_z,
    robot_arguments,
    rotation_of,
    set_up,
)

STOP = False


def _stop(*_):
    global STOP
    STOP = True


def stamp_of(ns):
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def ns_of(t):
    return t.sec * 1_000_000_000 + t.nanosec


def qos_text(q):
    """An endpoint's QoS as rclpy reports it."""
    return {
        "reliability": q.reliability.name.lower(),
        "durability": q.durability.name.lower(),
        "history": q.history.name.lower(),
        "depth": q.depth,
    }


def graph(node, topics):
    """The graph as rclpy sees it: nodes, topics and types, and every endpoint of `topics`."""
    out = {
        "nodes": sorted(f"{ns.rstrip('/')}/{n}" for n, ns in node.get_node_names_and_namespaces()),
        "topics": {t: list(types) for t, types in node.get_topic_names_and_types()},
        "endpoints": {},
    }
    for t in topics:
        eps = []
        for kind, infos in (("publisher", node.get_publishers_info_by_topic(t)),
                            ("subscription", node.get_subscriptions_info_by_topic(t))):  # fmt: skip
            for i in infos:
                eps.append({
                    "kind": kind,
                    "node": f"{i.node_namespace.rstrip('/')}/{i.node_name}",
                    "type": i.topic_type,
                    "type_hash": str(i.topic_type_hash),
                    "gid": ".".join(f"{b:02x}" for b in i.endpoint_gid[:16]),
                    "qos": qos_text(i.qos_profile),
                })  # fmt: skip
        out["endpoints"][t] = eps
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    robot_arguments(p, 100.0)
    p.add_argument("--node-name", default="standin_robot")
    p.add_argument("--graph-at", type=float, default=1.0, help="s after the first command")
    p.add_argument("--commands", action="store_true",
                   help="every command in --out: joints (monotonic s, all zero, largest |velocity|), base (s, largest |v|)")
    args = p.parse_args(argv)

    robot, chain, names, n, traj, inject, inject_at = set_up(args)

    rclpy.init(domain_id=args.domain_id, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGINT, _stop)
    signal.signal(signal.SIGTERM, _stop)
    node = rclpy.create_node(args.node_name)
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                     history=HistoryPolicy.KEEP_LAST)  # fmt: skip
    deep = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
    joints_pub = node.create_publisher(JointState, args.joint_states, qos)
    odom_pub = node.create_publisher(Odometry, args.odom, qos)
    if args.target == "topics":
        tpose_pub = node.create_publisher(PoseStamped, args.target_pose, qos)
        ttwist_pub = node.create_publisher(TwistStamped, args.target_twist, qos)

    period = 1.0 / args.rate
    every = max(1, int(round(args.rate / 100.0)))
    t0_mono = time.monotonic()
    t0_real_ns = time.time_ns()
    res = {
        "published": 0, "late_publishes": 0, "base_commands": 0, "joint_commands": 0,
        "zero_commands": 0, "nonzero_commands": 0, "last_command_zero": None, "commands_in_fault": [0, 0],
        "commands_after_fault": [0, 0], "bad_command_length": 0, "target_messages": 0,
        "target_max_deviation": 0.0, "diagnostics": 0, "diagnostic_levels": {}, "diagnostic_messages": [],
        "rosout": [], "max_joint_command": 0.0, "max_base_command": 0.0,
    }  # fmt: skip
    errs, latencies, joint_latencies, gaps, commands, base_commands = [], [], [], [], [], []
    stamps = []  # the last stamps published
    st = {"first_cmd": None, "s0_ns": None, "last_mono": t0_mono, "graph": None, "base_stamp": None}

    def advance():
        now = time.monotonic()
        robot.advance(now - st["last_mono"])
        st["last_mono"] = now
        return now

    def window(now):
        if st["first_cmd"] is None or inject_at is None:
            return None
        t = now - st["first_cmd"]
        if inject_at <= t < inject_at + args.inject_for:
            return "in"
        if t >= inject_at + args.inject_for + 0.2:
            return "after"
        return None

    def on_base(msg):
        now = advance()
        tw = msg.twist
        robot.v = (tw.linear.x, tw.linear.y, tw.angular.z)
        res["base_commands"] += 1
        res["max_base_command"] = max(res["max_base_command"], abs(tw.linear.x), abs(tw.linear.y), abs(tw.angular.z))
        st["base_stamp"] = ns_of(msg.header.stamp)
        latencies.append((time.time_ns() - st["base_stamp"]) * 1e-6)
        if args.commands:
            base_commands.append((now, max(abs(tw.linear.x), abs(tw.linear.y), abs(tw.angular.z))))

    def on_joints(msg):
        now = advance()
        data = list(msg.data)
        if len(data) != n:
            res["bad_command_length"] += 1
            return
        robot.qdot = data
        res["joint_commands"] += 1
        # The joint command carries no stamp: the node sends it right after the base's of the
        # same period, whose stamp is the period's.
        if st["base_stamp"] is not None:
            joint_latencies.append((time.time_ns() - st["base_stamp"]) * 1e-6)
        is_zero = all(x == 0.0 for x in data) and robot.v == (0.0, 0.0, 0.0)
        biggest = max((abs(x) for x in data), default=0.0)
        res["max_joint_command"] = max(res["max_joint_command"], biggest)
        if args.commands:
            commands.append((now, is_zero, biggest))
        if st["first_cmd"] is None and not is_zero:
            st["first_cmd"] = now
        res["zero_commands" if is_zero else "nonzero_commands"] += 1
        res["last_command_zero"] = is_zero
        w = window(now)
        if w == "in" and now - st["first_cmd"] >= inject_at + 0.05:
            res["commands_in_fault"][0 if is_zero else 1] += 1
        elif w == "after":
            res["commands_after_fault"][0 if is_zero else 1] += 1

    def on_diag(msg):
        if not msg.status:
            return
        res["diagnostics"] += 1
        lv = str(int.from_bytes(msg.status[0].level, "little") if isinstance(msg.status[0].level, bytes)
                 else int(msg.status[0].level))  # fmt: skip
        res["diagnostic_levels"][lv] = res["diagnostic_levels"].get(lv, 0) + 1
        m = msg.status[0].message
        if lv != "0" and m not in res["diagnostic_messages"] and len(res["diagnostic_messages"]) < 50:
            res["diagnostic_messages"].append(m)

    def on_target(msg):
        stamp = ns_of(msg.header.stamp)
        pp = msg.pose.position
        if st["s0_ns"] is None:
            st["s0_ns"] = epoch(traj, stamp, (pp.x, pp.y, pp.z), stamps)
        res["target_messages"] += 1
        if res["target_messages"] % every or chain is None:
            return
        want = traj.pose((stamp - st["s0_ns"]) * 1e-9)[1]
        dev = math.sqrt(sum((a - b) ** 2 for a, b in zip((pp.x, pp.y, pp.z), want)))
        dev = max(dev, max(abs(a - b) for a, b in zip(rotation_of(msg.pose.orientation), (1, 0, 0, 0, 1, 0, 0, 0, 1))))
        res["target_max_deviation"] = max(res["target_max_deviation"], dev)

    def on_rosout(msg):
        if len(res["rosout"]) < 200:
            res["rosout"].append({"name": msg.name, "level": int(msg.level), "msg": msg.msg})

    node.create_subscription(TwistStamped, args.base_command, on_base, deep)
    node.create_subscription(Float64MultiArray, args.joint_command, on_joints, deep)
    node.create_subscription(DiagnosticArray, args.diagnostics, on_diag, deep)
    rosout_qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                            durability=DurabilityPolicy.TRANSIENT_LOCAL)  # fmt: skip
    node.create_subscription(Log, "/rosout", on_rosout, rosout_qos)
    if args.target == "node":
        node.create_subscription(PoseStamped, args.target_pose, on_target, deep)
    executor = SingleThreadedExecutor()
    executor.add_node(node)

    next_pub = t0_mono
    last_pub = None
    while not STOP:
        now = time.monotonic()
        if now < next_pub:
            executor.spin_once(timeout_sec=next_pub - now)
            continue
        if now - next_pub > period:
            res["late_publishes"] += 1
            next_pub = now
        next_pub += period
        now = advance()
        now_ns = time.time_ns()
        stamps.append(now_ns)
        del stamps[:-50]
        fault = window(now) == "in" and inject
        js = JointState()
        js.header.stamp = stamp_of(now_ns - (1_000_000_000 if fault == "stale" else 0))
        js.name = list(args.extra_joint) + names
        js.position = [0.0] * len(args.extra_joint) + list(robot.q)
        if fault == "nan":
            js.position[-1] = float("nan")
        if fault == "names":
            js.name, js.position = js.name[:-1], js.position[:-1]
        if fault != "silent":
            joints_pub.publish(js)
        x, y, th = robot.base
        od = Odometry()
        od.header.stamp = stamp_of(now_ns)
        od.header.frame_id, od.child_frame_id = "odom", "base_link"
        od.pose.pose.position.x, od.pose.pose.position.y = x, y
        qx, qy, qz, qw = quaternion_z(th)
        od.pose.pose.orientation.x, od.pose.pose.orientation.y = qx, qy
        od.pose.pose.orientation.z, od.pose.pose.orientation.w = qz, qw
        od.twist.twist.linear.x, od.twist.twist.angular.z = robot.v[0], robot.v[2]
        odom_pub.publish(od)
        if args.target == "topics":
            rot, pos = traj.pose((now_ns - t0_real_ns) * 1e-9)
            lin, ang = traj.twist((now_ns - t0_real_ns) * 1e-9)
            ps = PoseStamped()
            ps.header.stamp, ps.header.frame_id = stamp_of(now_ns), "odom"
            ps.pose.position.x, ps.pose.position.y, ps.pose.position.z = pos
            ps.pose.orientation.w = 1.0
            tw = TwistStamped()
            tw.header = ps.header
            tw.twist.linear.x, tw.twist.linear.y, tw.twist.linear.z = lin
            tw.twist.angular.x, tw.twist.angular.y, tw.twist.angular.z = ang
            tpose_pub.publish(ps)
            ttwist_pub.publish(tw)
        res["published"] += 1
        if last_pub is not None:
            gaps.append((now - last_pub) * 1e3)
        last_pub = now
        first = st["first_cmd"]
        if first is not None and chain is not None and res["published"] % every == 0:
            if args.target == "topics":
                tgt = traj.pose((now_ns - t0_real_ns) * 1e-9)
            elif st["s0_ns"] is not None:
                tgt = traj.pose((now_ns - st["s0_ns"]) * 1e-9)
            else:
                tgt = None
            if tgt is not None:
                pos, full = robot.errors(tgt)
                errs.append((now - first, pos, full))
        if first is not None and st["graph"] is None and now - first >= args.graph_at:
            st["graph"] = graph(node, [args.joint_states, args.odom, args.base_command, args.joint_command,
                                       args.target_pose, args.diagnostics, "/rosout", "/clock"])  # fmt: skip

    # The last lines of the node (written as it ends) may still be on their way.
    end = time.monotonic() + 0.2
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.02)
    res["publish_gap_ms"] = percentiles(gaps)
    res["command_latency_ms"] = percentiles(latencies)
    res["joint_command_latency_ms"] = percentiles(joint_latencies)
    res["first_command_s"] = None if st["first_cmd"] is None else st["first_cmd"] - t0_mono
    res["first_command_mono"] = st["first_cmd"]
    final_errors(res, errs, args.final_at)
    res["graph"] = st["graph"]
    if args.commands:
        res["commands"] = commands
        res["base_commands"] = base_commands
    with open(args.out, "w") as f:
        json.dump(res, f, indent=1)
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
