#!/usr/bin/env python3
"""The paper's lifted trajectory 1 at SPEED times its speed, as a target file for
`companion sim --arm … --target-file FILE` (piecewise-constant body twists, one per STEP
seconds, for DURATION seconds).

The circle keeps its radius (0.1 m) and its fixed heading; its speed and frequency scale by
SPEED (0.157 m/s and pi/2 rad/s at 1); the vertical sine (5 cm over 10 s) is the lifted
trajectory's, unscaled. Without an [initial] table the target starts 2.5 m ahead and 1 m to
the left at the height the arm's home holds it (the paper's trajectory 1 starts 2.6 m ahead).

    python3 scripts/lifted_circle.py 1.3 > t1x1.3.toml      # 40 s in 10 ms segments
    python3 scripts/lifted_circle.py 1.3 --step 0.005 --duration 60 > t.toml
"""

import argparse
import math
import sys


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("speed", type=float, help="the circle's speed as a multiple of the paper's (> 0)")
    p.add_argument("--step", type=float, default=0.01, help="segment length in s (default 0.01)")
    p.add_argument("--duration", type=float, default=40.0, help="seconds (default 40)")
    a = p.parse_args()
    for name, v in (("speed", a.speed), ("--step", a.step), ("--duration", a.duration)):
        if not (math.isfinite(v) and v > 0):
            p.error(f"{name} must be a positive number, not {v}")
    n = round(a.duration / a.step)
    if n < 1 or n > 1_000_000:
        p.error(f"--duration/--step gives {n} segments: between 1 and 1000000")
    out = [f"# lifted trajectory 1 at {a.speed} x its speed: scripts/lifted_circle.py {a.speed} "
           f"--step {a.step} --duration {a.duration}\n"]
    k, amp, period = a.speed, 0.05, 10.0
    for i in range(n):
        t = (i + 0.5) * a.step  # the segment's midpoint: the mean velocity to second order
        vx = -k * math.pi / 20.0 * math.sin(math.pi * k * t / 2.0)
        vy = -k * math.pi / 20.0 * math.cos(math.pi * k * t / 2.0)
        vz = amp * 2.0 * math.pi / period * math.cos(2.0 * math.pi * t / period)
        out.append(f"[[segment]]\nduration = {a.step!r}\nvelocity = [{vx!r}, {vy!r}, {vz!r}, 0.0, 0.0, 0.0]\n")
    sys.stdout.write("\n".join(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
