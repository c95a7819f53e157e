#!/usr/bin/env python3
"""A rogue on the robot's domain, as rclpy: a second writer on an input of `companion ros2`.

- `--joints-offset D`: on each joint state of the robot, publishes a copy on the same topic
  with every position `+D` rad, right after it;
- `--odom-hz F`: publishes odometry at `F` Hz, the robot's last pose moved `--odom-offset` m
  along x, stamped now.

It waits for the robot's first joint state, then `--start-after` s, creates its publishers,
publishes for `--for` s, destroys them (its writers leave the graph) and writes `--out`: what it
published, and when it was active and published first (CLOCK_MONOTONIC, the stand-in's clock).
"""

import argparse
import json
import signal
import sys
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from builtin_interfaces.msg import Time
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState

STOP = False


def _stop(*_):
    global STOP
    STOP = True


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--domain-id", type=int, default=0)
    p.add_argument("--node-name", default="rogue")
    p.add_argument("--joint-states", default="/joint_states")
    p.add_argument("--odom", default="/mobile_base_controller/odom")
    p.add_argument("--joints-offset", type=float, default=None)
    p.add_argument("--odom-hz", type=float, default=None)
    p.add_argument("--odom-offset", type=float, default=0.5)
    p.add_argument("--start-after", type=float, default=3.0)
    p.add_argument("--for", dest="length", type=float, default=2.0)
    p.add_argument("--out", required=True)
    args = p.parse_args(argv)
    rclpy.init(domain_id=args.domain_id, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGINT, _stop)
    signal.signal(signal.SIGTERM, _stop)
    node = rclpy.create_node(args.node_name)
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
    st = {"first": None, "odom": None, "pubs": None, "joints": 0, "odometry": 0, "start": None, "end": None,
          "first_publish": None}  # fmt: skip

    def on_joints(msg):
        if msg.header.frame_id == "rogue":
            return
        if st["first"] is None:
            st["first"] = time.monotonic()
        if st["pubs"] and args.joints_offset is not None:
            copy = JointState()
            copy.header.stamp, copy.header.frame_id = msg.header.stamp, "rogue"
            copy.name = list(msg.name)
            copy.position = [x + args.joints_offset for x in msg.position]
            st["pubs"][0].publish(copy)
            st["joints"] += 1
            st["first_publish"] = st["first_publish"] or time.monotonic()

    def on_odom(msg):
        if msg.header.frame_id != "rogue":
            st["odom"] = msg

    node.create_subscription(JointState, args.joint_states, on_joints, qos)
    node.create_subscription(Odometry, args.odom, on_odom, qos)
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    next_odom = None
    while not STOP:
        now = time.monotonic()
        if st["pubs"] is None and st["first"] is not None and st["end"] is None and now >= st["first"] + args.start_after:
            st["pubs"] = (
                node.create_publisher(JointState, args.joint_states, qos) if args.joints_offset is not None else None,
                node.create_publisher(Odometry, args.odom, qos) if args.odom_hz else None,
            )
            st["start"] = now
            next_odom = now
        if st["pubs"] is not None and now >= st["start"] + args.length:
            for pub in st["pubs"]:
                if pub is not None:
                    node.destroy_publisher(pub)
            st["pubs"], st["end"] = None, now
        if st["pubs"] and args.odom_hz and st["odom"] is not None and now >= next_odom:
            od = st["odom"]
            fake = Odometry()
            ns = time.time_ns()
            fake.header.stamp = Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
            fake.header.frame_id, fake.child_frame_id = "rogue", od.child_frame_id
            p, q = od.pose.pose.position, od.pose.pose.orientation
            fake.pose.pose.position.x, fake.pose.pose.position.y = p.x + args.odom_offset, p.y
            fake.pose.pose.orientation.z, fake.pose.pose.orientation.w = q.z, q.w
            st["pubs"][1].publish(fake)
            st["odometry"] += 1
            st["first_publish"] = st["first_publish"] or time.monotonic()
            next_odom += 1.0 / args.odom_hz
        wait = 0.01 if next_odom is None or not st["pubs"] else max(0.0, next_odom - time.monotonic())
        ex.spin_once(timeout_sec=min(wait, 0.01))
    with open(args.out, "w") as f:
        json.dump({"joints": st["joints"], "odometry": st["odometry"], "start_mono": st["start"],
                   "first_publish_mono": st["first_publish"], "end_mono": st["end"]}, f, indent=1)  # fmt: skip
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
