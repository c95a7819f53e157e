#!/usr/bin/env python3
"""Which joints hold a spatial run back: from a run's timeseries.csv (log every step:
`--log-every 1`), from 20 s on (after the start's transient, as the tracked fraction), the
steps where the joint guard slowed the arm (joint_scale > 1) and, per joint, how many of them
it set (its commanded speed at its published limit) and the largest speed the law asked of it
(|u_q| x joint_scale); and the platform's largest curvature |xi| (car: 1/m) and turn rate
|omega| over the same steps. The published speeds are the preset's
(`ur5`, `panda`, from scenario.json's arm) or given: joint_guard.py RUN_DIR [SPEED ...]."""
import csv, json, sys

PRESETS = {"ur5": [3.14159265358979] * 6, "panda": [2.175] * 4 + [2.61] * 3}

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
xi = max((abs(float(r["xi"])) for r in rows), default=0.0)
omega = max((abs(float(r["omega"])) for r in rows), default=0.0)
print(f"{d}: {len(rows)} rows from 20 s, {guarded} with the joint guard acting; "
      f"platform: |xi| up to {xi:.2f}, |omega| up to {omega:.2f} rad/s")
for i in range(n):
    print(f"  joint {i + 1}: set the guard on {setter[i]} rows; asked for up to {peak[i]:.2f} rad/s "
          f"(published {speeds[i]:.3f}, x{peak[i] / speeds[i]:.2f})")
