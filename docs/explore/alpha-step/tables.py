#!/usr/bin/env python3
"""Tables of the α-step variants from measure.sh's folder (README.md beside this script).

    docs/explore/alpha-step/tables.py OUT [--runs]

Per variant: the pointwise distance at 1 ms (and the smallest ratio 1 ms / 0.5 ms), the
floors, the runs that a single run from the paper's start tracks less than today at 100 Hz
and 1 kHz, the same over 24 nearby starts (mean lower than today's by more than twice the
standard error of the difference), and the peak |v| of T2 (d) with the Ψ̇ term at 1 kHz.
With --runs, every run's mean ± sd over the 24 starts at both periods.
"""
import json
import math
import os
import re
import statistics as st
import sys

out = sys.argv[1]
ORDER = ["today", "reordered", "exact", "exact-car-too", "half", "exact-decaying",
         "exact-growing", "exact-rate-only", "exact-v-omega-only", "blend-0.05", "blend-0.1",
         "blend-0.2"]
names = [n for n in ORDER if os.path.isdir(os.path.join(out, n))]
TRACKED = "fraction_ep_below_1e-3_after_20s"


def load(name, file):
    with open(os.path.join(out, name, file)) as f:
        return json.load(f)


def starts(name, dt):
    d = os.path.join(out, name)
    files = sorted(f for f in os.listdir(d) if re.fullmatch(rf"start-(-?\d+)-{dt}\.json", f))
    return [load(name, f) for f in files]


def pointwise(name):
    rows = {}
    for line in open(os.path.join(out, name, "pointwise.txt")):
        m = re.match(r"PW (\w+) ([\d.e+-]+) .*\| ([\d.e+-]+) ÷([\d.]+)", line)
        if m:
            rows[m[1]] = (float(m[2]), float(m[4]))
    return rows


def short(run):
    return run.replace("traj", "T").replace("-unicycle", "").replace("-psidot", "+Ψ̇")


def worse_single(name, dt):
    base, this = load("today", f"nominal-{dt}.json"), load(name, f"nominal-{dt}.json")
    return [f"{short(r)} {100 * this[r][TRACKED]:.2f} ({100 * base[r][TRACKED]:.2f})"
            for r in sorted(base) if this[r][TRACKED] < base[r][TRACKED]]


def worse_mean(name, dt):
    base, this = starts("today", dt), starts(name, dt)
    res = []
    for r in sorted(base[0]):
        a = [100 * s[r][TRACKED] for s in base]
        b = [100 * s[r][TRACKED] for s in this]
        se = math.sqrt(st.pvariance(a) / len(a) + st.pvariance(b) / len(b))
        if st.mean(b) < st.mean(a) - max(2 * se, 1e-9):
            res.append(f"{short(r)} {st.mean(b):.2f} ({st.mean(a):.2f})")
    return res


def psi(name):
    v = [s["max_abs_v"] for s in load(name, "psi.json").values()]
    return st.median(v), sum(x < 29 for x in v), len(v)


print("| variant | pointwise 1 ms T1a / T2a / T1c (÷ to 0.5 ms, least) | T1a final 1 kHz | "
      "T2a tracked 1 kHz / 100 Hz | single runs tracked less, 100 Hz | same, 1 kHz | "
      "24 starts: mean tracked lower (> 2 SE), 100 Hz | same, 1 kHz | T2d+Ψ̇ 1 kHz peak |v|: "
      "paper's start; median of 24 (< 29 m/s) |")
print("|---|---|---|---|---|---|---|---|---|")
for n in names:
    pw = pointwise(n)
    k1, k100 = load(n, "nominal-0.001.json"), load(n, "nominal-0.01.json")
    t2a = "traj2-a-unicycle"
    steps = lambda s: round((1 - s[t2a][TRACKED]) * s[t2a]["steps_after_20s"])
    med, below, total = psi(n)
    cells = [
        n,
        " / ".join(f"{pw[r][0]:.2e}" for r in ("t1a", "t2a", "t1c"))
        + f" (÷{min(pw[r][1] for r in pw):.2f})",
        f"{k1['traj1-a-unicycle']['final_ep_norm']:.1e}",
        f"{100 * k1[t2a][TRACKED]:.2f} % / {100 * k100[t2a][TRACKED]:.2f} % ({steps(k100)} steps over)",
        ", ".join(worse_single(n, "0.01")) or "none",
        ", ".join(worse_single(n, "0.001")) or "none",
        ", ".join(worse_mean(n, "0.01")) or "none",
        ", ".join(worse_mean(n, "0.001")) or "none",
        f"{k1['traj2-d-unicycle-psidot']['max_abs_v']:.1f}; {med:.1f} ({below}/{total})",
    ]
    print("| " + " | ".join(cells) + " |")
s = [x["max_abs_v"] for x in load("sampled", "psi.json").values()]
print(f"\nsampled law, T2d+Ψ̇ 1 kHz peak |v| over the 24 starts: median {st.median(s):.1f} "
      f"({sum(x < 29 for x in s)}/{len(s)} below 29 m/s)")

if "--runs" in sys.argv:
    for dt in ("0.01", "0.001"):
        print(f"\ntracked after 20 s over the 24 starts, dt = {dt} s: mean ± sd\n")
        print("| run | " + " | ".join(names) + " |")
        print("|---|" + "---|" * len(names))
        runs = sorted(starts("today", dt)[0])
        for r in runs:
            cells = []
            for n in names:
                v = [100 * x[r][TRACKED] for x in starts(n, dt)]
                cells.append(f"{st.mean(v):.1f} ± {st.pstdev(v):.1f}")
            print(f"| {short(r)} | " + " | ".join(cells) + " |")
