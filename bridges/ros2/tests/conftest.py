"""The node under test: `target/release/companion` built with `--features ros2` (scripts/test
builds it; COMPANION_ROS2_BIN names another)."""

import os
import subprocess

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", ".."))


@pytest.fixture(scope="module")
def node_bin():
    exe = os.environ.get("COMPANION_ROS2_BIN", os.path.join(ROOT, "target", "release", "companion"))
    if not os.path.exists(exe):
        pytest.fail(f"{exe} is missing: cargo build --release -p companion-runtime --features ros2")
    r = subprocess.run([exe, "ros2", "--startup-timeout", "0", "--out", "/tmp/companion-ros2-probe"],
                       capture_output=True, text=True, timeout=60)  # fmt: skip
    if "needs a build with the ROS 2 node" in r.stderr:
        pytest.fail(f"{exe} was built without the ROS 2 node: cargo build --release -p companion-runtime --features ros2")
    return exe
