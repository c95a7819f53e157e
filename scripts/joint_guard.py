#!/usr/bin/env python3
"""Which joints hold a spatial run back: from a run's timeseries.csv (log every step:
`--log-every 1`), from 20 s on (after the start's transient, as the tracked fraction), the
steps where the joint guard slowed the arm (joint_scale > 1) and, per joint, how many of them
it set (its commanded speed at its published limit) and the largest speed the law asked of it
(|u_q| x joint_scale); the spells in which the guard acts (a guard that chattered would
switch on and off from one step to the next); the platform's largest curvature |xi| (car: 1/m) and turn rate
|omega| over the same steps; and for the presets, how close the target came to joint 1's
(vertical) axis, where joint 1's rate grows as the inverse of that distance. The published
speeds are the preset's (`ur5`, `panda`, from scenario.json's arm) or given:
joint_guard.py RUN_DIR [SPEED ...]."""
import csv, json, math, sys

PRESETS = {"ur5": [3.14159265358979] * 6, "panda": [2.175] * 4 + [2.61] * 3}
# Where joint 1's axis stands on the platform (the presets' [mount] xyz, x and y).
AXIS = {"ur5": (0.1, 0.0), "panda": (0.0, 0.0)}

d = sys.argv[1]
arm = json.load(open(d + "/scenario.json"))["arm"]
speeds = [float(x) for x in sys.argv[2:]] or PRESETS.get(arm)
if speeds is None:
    sys.exit(f"{arm}: give the joints' published speeds after the run's folder")
n = len(speeds)
rows = list(csv.DictReader(open(d + "/timeseries.csv")))
rows = [r for r in rows if float(r["t"]) >= 20.0]
guarded = 0
setter = [0] * n
peak = [0.0] * n
for r in rows:
    s = float(r["joint_scale"])
    u = [float(r[f"u_q{i + 1}"]) for i in range(n)]
    for i in range(n):
        peak[i] = max(peak[i], abs(u[i]) * max(s, 1.0))
    if s > 1.0:
        guarded += 1
        # The joint that set the factor runs at its published speed (to rounding).
        at = [i for i in range(n) if abs(abs(u[i]) - speeds[i]) <= 1e-9 * speeds[i]]
        for i in at:
            setter[i] += 1
spells, run = [], 0
for r in rows:
    if float(r["joint_scale"]) > 1.0:
        run += 1
    elif run:
        spells.append(run)
        run = 0
if run:
    spells.append(run)
xi = max((abs(float(r["xi"])) for r in rows), default=0.0)
omega = max((abs(float(r["omega"])) for r in rows), default=0.0)
print(f"{d}: {len(rows)} rows from 20 s, {guarded} with the joint guard acting; "
      f"platform: |xi| up to {xi:.2f}, |omega| up to {omega:.2f} rad/s")
if spells:
    print(f"  the guard acted in {len(spells)} spells of {min(spells)} to {max(spells)} rows "
          f"({sum(1 for n in spells if n <= 2)} of one or two rows)")
if arm in AXIS and rows:
    mx, my = AXIS[arm]
    def distance(r):
        th = float(r["theta_b"])
        ax = float(r["x_b"]) + mx * math.cos(th) - my * math.sin(th)
        ay = float(r["y_b"]) + mx * math.sin(th) + my * math.cos(th)
        return math.hypot(float(r["x_d"]) - ax, float(r["y_d"]) - ay)
    near = [r for r in rows if float(r["joint_scale"]) > 1.0 and distance(r) < 0.15]
    print(f"  the target's distance from joint 1's axis: at least {min(map(distance, rows)):.3f} m; "
          f"within 0.15 m on {len(near)} of the guarded rows")
for i in range(n):
    print(f"  joint {i + 1}: set the guard on {setter[i]} rows; asked for up to {peak[i]:.2f} rad/s "
          f"(published {speeds[i]:.3f}, x{peak[i] / speeds[i]:.2f})")
