#!/usr/bin/env python3
"""What the physics does to the law: the figures of docs/book/src/mujoco.md's side-by-side table, from
run folders of either plant — `companion sim --arm … --log-every 1` (the kinematic plant) or
the MuJoCo plant (lockstep) — computed the same way from each run's timeseries.csv:

- the effector's position error ‖p̃‖ and orientation error ‖log R̃‖ (the two halves of e_p):
  final, largest after 20 s, and the fraction of rows after 20 s with ‖p̃‖ < 1 cm;
- the smallest joint margin (from summary.json);
- the base's largest speeds and its accelerations (p99 and largest of the change of speed per
  period): the simulated base's own (MuJoCo), or the command's, which the kinematic plant
  follows exactly;
- MuJoCo only: wheel slip (the fraction of time a wheel's lowest point moves over 1 cm/s, creep
  included; the fraction of time a wheel uses 95 % of its friction or more — sliding; the
  distance slipped) and the drives at their limits
  (fraction of physics steps, each actuator over 0.1 %).

Usage: compare.py RUN_DIR [RUN_DIR …] (one markdown row each)."""

import csv
import json
import math
import os
import sys


def figures(d):
    rows = list(csv.DictReader(open(os.path.join(d, "timeseries.csv"))))
    s = json.load(open(os.path.join(d, "summary.json")))
    mujoco = s.get("plant") == "mujoco"
    t = [float(r["t"]) for r in rows]
    dt = t[1] - t[0]
    if dt > 0.0011 or dt < 0.0009:
        sys.exit(f"{d}: rows every {dt} s: log every step (--log-every 1)")
    pos = [math.sqrt(sum(float(r[k]) ** 2 for k in ("ep_x", "ep_y", "ep_z"))) for r in rows]
    rot = [math.sqrt(sum(float(r[k]) ** 2 for k in ("ep_rx", "ep_ry", "ep_rz"))) for r in rows]
    after = [i for i, x in enumerate(t) if x >= 20.0]
    speed = "v_true" if mujoco else "v"
    turn = "omega_true" if mujoco else "omega"
    v = [float(r[speed]) for r in rows]
    w = [float(r[turn]) for r in rows]
    acc = sorted(abs(b - a) / dt for a, b in zip(v, v[1:]))
    alpha = sorted(abs(b - a) / dt for a, b in zip(w, w[1:]))
    p99 = lambda xs: xs[min(len(xs) - 1, int(0.99 * len(xs)))]  # noqa: E731
    f = {
        "plant": "MuJoCo" if mujoco else "kinematic",
        "final_pos": pos[-1],
        "final_rot": rot[-1],
        "max_pos_20": max(pos[i] for i in after) if after else float("nan"),
        "max_rot_20": max(rot[i] for i in after) if after else float("nan"),
        "tracked_1cm": sum(pos[i] < 1e-2 for i in after) / len(after) if after else float("nan"),
        "margin": s["smallest_joint_margin"],
        "max_v": max(abs(x) for x in v),
        "max_w": max(abs(x) for x in w),
        "acc": (p99(acc), acc[-1]),
        "alpha": (p99(alpha), alpha[-1]),
    }
    if mujoco:
        f["slip"] = s.get("wheel_slip")
        f["saturated"] = {k.split("/")[-1]: x for k, x in s["saturation_fraction"].items() if x > 0.001}
        f["saturated"]["joint guard"] = s["session"]["joint_guard_steps"] / s["steps"]
    else:
        f["slip"], f["saturated"] = None, {"joint guard": s["joint_guard_steps"] / s["steps"]}
    return f


def row(d):
    f = figures(d)
    slip = "—" if not f["slip"] else (
        f"{100 * f['slip']['fraction_of_time']:.1f} %, {100 * f['slip']['sliding_fraction_of_time']:.1f} % "
        f"({f['slip']['distance_m']['left']:.2f} / {f['slip']['distance_m']['right']:.2f} m)"
    )
    sat = ", ".join(f"{k} {100 * x:.1f} %" for k, x in sorted(f["saturated"].items(), key=lambda kv: -kv[1])[:4])
    return (
        f"| {f['plant']} | {f['final_pos']:.1e} / {f['final_rot']:.1e} | {f['max_pos_20']:.1e} / {f['max_rot_20']:.1e} "
        f"| {100 * f['tracked_1cm']:.1f} % | {f['margin']:.3f} | {f['max_v']:.2f} / {f['max_w']:.2f} "
        f"| {f['acc'][0]:.1f} / {f['acc'][1]:.0f} | {f['alpha'][0]:.1f} / {f['alpha'][1]:.0f} | {slip} | {sat or '—'} |"
    )


HEADER = (
    "| plant | final ‖p̃‖ m / ‖log R̃‖ rad | max after 20 s | tracked (1 cm) after 20 s | smallest joint margin "
    "| max \\|v\\| m/s / \\|ω\\| rad/s | \\|dv/dt\\| p99 / max m/s² | \\|dω/dt\\| p99 / max rad/s² | wheels: time slipping > 1 cm/s, time "
    "sliding (distance slipped left / right) | at their limits |\n|---|---|---|---|---|---|---|---|---|---|"
)

if __name__ == "__main__":
    print(HEADER)
    for d in sys.argv[1:]:
        print(row(d))
