#!/usr/bin/env python3
"""The cost table of `tests/firmware/measure`: per platform and law, the `f32` step's
instructions (min / mean / max over the paper's 8 runs), the worst step named with its run
and time, the stack of one step, and the flash the law takes; per run; the other cases. It
prints Markdown and writes the same figures as JSON.

Usage:
  report.py worst FIRMWARE_OUT
      prints the gdbcount.py arguments for the worst steps (CASE:STEP ...): per platform
      and law in f32, the worst step and the worst after the first.
  report.py profile-steps FIRMWARE_OUT
      prints the gdbcount.py arguments for the unicycle steps that `measure --profile`
      profiles: the worst, the worst after the first, two typical ones.
  report.py table FIRMWARE_OUT GDB_OUT ELF JSON_PATH SECONDS
      prints the tables and writes JSON_PATH.

FIRMWARE_OUT is the firmware's output (its `C` lines: see src/main.rs), GDB_OUT the `G`
lines of gdbcount.py.
"""

import bisect
import json
import re
import shutil
import subprocess
import sys
from collections import defaultdict

DT = 1e-3  # s, the control period of src/scenario.rs
PLATFORMS = {"uni": "unicycle", "car": "car-like", "omni": "omnidirectional"}
# The aims of issue 20 (unicycle, f32): instructions and stack bytes.
AIMS = {"default mean": 3000, "default worst": 3500, "sampled mean": 1500, "stack": 2048}
# The aims of issue 36 (unicycle, f32, with the robot's limits on): no more than the default
# law cost before the limits were added (tests/firmware/README.md).
AIMS_LIMITS = {"mean": 4181, "worst after the first": 4438}

C_FIELDS = (
    "steps sum min max max_step max_later max_later_step first stack_two_steps stack_case "
    "stack_build stack_step stack_step_at window overflow"
).split()


def parse_case(name):
    """Platform, trajectory, run, scalar, law of a case name (`uni-2c-f32-sampled`,
    `uni-2c-f32-limits`: the default law with a robot's limits on)."""
    parts = name.split("-")
    spatial = parts[0] == "ur5"
    if spatial:
        parts = parts[1:]
    law = {"sampled": "sampled", "limits": "limits"}[parts[3]] if parts[3:] else "default"
    plat = ("ur5 on " if spatial else "") + PLATFORMS[parts[0]]
    return {"platform": plat, "trajectory": int(parts[1][0]), "run": parts[1][1], "scalar": parts[2], "law": law}


def read_cases(path):
    cases = []
    for line in open(path):
        f = line.split()
        if f and f[0] == "C":
            c = {"name": f[1], **parse_case(f[1])}
            c.update({k: int(v) for k, v in zip(C_FIELDS, f[2:])})
            c["mean"] = c["sum"] / c["steps"]
            cases.append(c)
    return cases


def groups(cases):
    """The f32 table's rows: (platform, law) over the 8 runs of trajectories 1 and 2."""
    g = defaultdict(list)
    for c in cases:
        if c["scalar"] == "f32" and not c["platform"].startswith("ur5"):
            g[(c["platform"], c["law"])].append(c)
    return {k: v for k, v in g.items() if len(v) == 8}


def worst(cs, key="max", at="max_step"):
    c = max(cs, key=lambda c: (c[key], -cs.index(c)))
    return {"case": c["name"], "run": f"{c['trajectory']}{c['run']}", "step": c[at], "time_s": round(c[at] * DT, 3),
            "instructions": c[key]}


def summary(g):
    rows = []
    for (plat, law), cs in g.items():
        steps = sum(c["steps"] for c in cs)
        rows.append({
            "platform": plat,
            "law": law,
            "scalar": "f32",
            "runs": len(cs),
            "steps": steps,
            "min": min(c["min"] for c in cs),
            "mean": sum(c["sum"] for c in cs) / steps,
            "max": max(c["max"] for c in cs),
            "worst": worst(cs),
            "worst_after_first": worst(cs, "max_later", "max_later_step"),
            "stack_step": max(c["stack_step"] for c in cs),
            "stack_two_steps": max(c["stack_two_steps"] for c in cs),
        })
    return rows


def n(x):
    """An integer with thin spaces as thousands separators (as in the README)."""
    return f"{round(x):,}".replace(",", " ")


def when(w):
    return f"{w['run']}, step {w['step']} (t = {w['time_s']:.3f} s)"


def symbol_sizes(elf):
    """{name: (address, size)} of the ELF's functions (llvm-nm or nm, demangled)."""
    nm = shutil.which("llvm-nm") or shutil.which("nm")
    if nm is None:
        return {}
    out = subprocess.run([nm, "-S", "-C", elf], capture_output=True, text=True, check=True).stdout
    sizes = {}
    for line in out.splitlines():
        m = re.match(r"^([0-9a-f]+) ([0-9a-f]+) [tTrRdD] (.*)$", line)
        if m:
            sizes[m.group(3)] = (int(m.group(1), 16) & ~1, int(m.group(2), 16))
    return sizes


def reachable_code(elf, sizes, roots):
    """(bytes, functions) of the code reachable by direct calls and branches from the
    functions whose names match `roots`: every `bl`/`b` whose target lies in another
    function, by llvm-objdump's disassembly (indirect calls are not followed; the law makes
    none); None without llvm-objdump."""
    objdump = shutil.which("llvm-objdump")
    if objdump is None or not sizes:
        return None
    text = subprocess.run([objdump, "-d", "--no-show-raw-insn", elf], capture_output=True, text=True).stdout
    funcs = sorted((a, s) for a, s in sizes.values() if s > 0)
    starts = [a for a, _ in funcs]

    def containing(addr):
        i = bisect.bisect_right(starts, addr) - 1
        return funcs[i][0] if i >= 0 and addr < funcs[i][0] + funcs[i][1] else None

    calls = defaultdict(set)
    branch = re.compile(r"^\s*([0-9a-f]+):\s+b[a-z]*(?:\.w)?\s+0x([0-9a-f]+)")
    for line in text.splitlines():
        m = branch.match(line)
        if m:
            src, dst = containing(int(m.group(1), 16)), containing(int(m.group(2), 16))
            if src is not None and dst is not None and src != dst:
                calls[src].add(dst)
    todo = [a for name, (a, _) in sizes.items() if any(re.search(r, name) for r in roots)]
    seen = set()
    while todo:
        a = todo.pop()
        if a not in seen:
            seen.add(a)
            todo.extend(calls[a])
    size_of = dict(funcs)
    return sum(size_of.get(a, 0) for a in seen), len(seen)


def flash(elf, fw_out):
    image = None
    for line in open(fw_out):
        f = line.split()
        if f and f[0] == "M":
            image = int(f[1])
    result = {"image": image}
    sizes = symbol_sizes(elf)
    types = {"unicycle": "Unicycle", "car-like": "CarLike", "omnidirectional": "Omnidirectional"}
    for plat, ty in types.items():
        for scalar in ("f32", "f64"):
            r = reachable_code(elf, sizes, [rf"scenario::controller_step::<{scalar}, [\w:]*\b{ty}\b"])
            if r is not None:
                result[f"step code, {plat}, {scalar}"] = {"bytes": r[0], "functions": r[1]}
    return result


def crosscheck(gdb_out, fw_out):
    s = {}
    for line in open(fw_out):
        f = line.split()
        if f and f[0] == "S":
            s[(f[1], int(f[2]))] = int(f[3])
    rows = []
    for line in open(gdb_out):
        f = line.split()
        if f and f[0] == "G":
            key = (f[1], int(f[2]))
            rows.append({"case": f[1], "step": key[1], "systick": s.get(key), "single_step": int(f[3]),
                         "step_function": int(f[4])})
    return rows


def table(fw_out, gdb_out, elf, json_path, seconds):
    cases = read_cases(fw_out)
    g = groups(cases)
    rows = summary(g)
    horizon = "trajectory 1: 3 s (3 000 steps), trajectory 2: 6 s (6 000 steps: 5 s at rest, 1 s of the first rotation)"
    print(f"Cost of one controller step in f32, over the paper's 8 runs (trajectories 1 and 2 x runs a-d; {horizon}; 1 ms)")
    print("instructions between the two SysTick readings around the call of controller_step, less the probe's own;")
    print("mean over all steps of the 8 runs; stack: the most one step wrote below the caller's stack pointer,")
    print("painted around every step\n")
    print("| platform, law | min | mean | max | worst step: run, step (time) | worst after the first step | stack of one step |")
    print("|---|---:|---:|---:|---|---|---:|")
    for r in rows:
        w, l = r["worst"], r["worst_after_first"]
        print(f"| {r['platform']}, {r['law']} | {n(r['min'])} | {n(r['mean'])} | {n(r['max'])} | {when(w)} "
              f"| {n(l['instructions'])}: {when(l)} | {n(r['stack_step'])} B |")

    print("\nPer run (mean, max in parentheses; f32):\n")
    cols = list(g)
    print("| run | " + " | ".join(f"{p}, {law}" for p, law in cols) + " |")
    print("|---|" + "---:|" * len(cols))
    runs = sorted({(c["trajectory"], c["run"]) for cs in g.values() for c in cs})
    for t, run in runs:
        cells = []
        for k in cols:
            c = next(c for c in g[k] if (c["trajectory"], c["run"]) == (t, run))
            cells.append(f"{n(c['mean'])} ({n(c['max'])})")
        print(f"| {t}{run} | " + " | ".join(cells) + " |")

    others = [c for c in cases if not any(c in cs for cs in g.values())]
    print("\nThe other cases (the f64 figures, the UR5, and the sampled law's run 1a on car and omni):\n")
    print("| case | steps | min | mean | max | worst after the first: step | stack of one step |")
    print("|---|---:|---:|---:|---:|---|---:|")
    for c in others:
        print(f"| {c['name']} | {n(c['steps'])} | {n(c['min'])} | {n(c['mean'])} | {n(c['max'])} "
              f"| {n(c['max_later'])}: {c['max_later_step']} | {n(c['stack_step'])} B |")

    fl = flash(elf, fw_out)
    print(f"\nFlash: the image {n(fl['image'])} B (vector table, code, read-only data: every case of the harness).")
    step_code = {k: v for k, v in fl.items() if k.startswith("step code")}
    if step_code:
        print("Code reachable from one law's step (controller_step::<scalar, platform> and every function it")
        print("calls or branches to directly, by llvm-objdump; the code a firmware that steps this law links,")
        print("without the constructor and the read-only data):\n")
        print("| platform | f32 | f64 |\n|---|---:|---:|")
        for plat in ("unicycle", "car-like", "omnidirectional"):
            a = fl.get(f"step code, {plat}, f32", {}).get("bytes")
            b = fl.get(f"step code, {plat}, f64", {}).get("bytes")
            print(f"| {plat} | {n(a) if a else '-'} B | {n(b) if b else '-'} B |")

    uni = {r["law"]: r for r in rows if r["platform"] == "unicycle"}
    aims = []
    if "default" in uni:
        aims.append(("unicycle f32 default, mean", uni["default"]["mean"], AIMS["default mean"], ""))
        aims.append(("unicycle f32 default, worst step", uni["default"]["max"], AIMS["default worst"], ""))
        aims.append(("unicycle f32 default, worst step after the first", uni["default"]["worst_after_first"]["instructions"],
                     AIMS["default worst"], ""))
        aims.append(("unicycle f32 default, stack of one step", uni["default"]["stack_step"], AIMS["stack"], " B"))
    if "sampled" in uni:
        aims.append(("unicycle f32 sampled, mean", uni["sampled"]["mean"], AIMS["sampled mean"], ""))
    print("\nAims of issue 20:\n")
    print("| figure | measured | aim | |\n|---|---:|---:|---|")
    for what, got, aim, unit in aims:
        print(f"| {what} | {n(got)}{unit} | <= {n(aim)}{unit} | {'met' if got <= aim else 'not met'} |")
    if "limits" in uni:
        lim = uni["limits"]
        limit_aims = [("unicycle f32 with the limits on, mean", lim["mean"], AIMS_LIMITS["mean"], ""),
                      ("unicycle f32 with the limits on, worst step after the first",
                       lim["worst_after_first"]["instructions"], AIMS_LIMITS["worst after the first"], "")]
        print("\nAims of issue 36 (the limits on, at no more than the default law's cost before them):\n")
        print("| figure | measured | aim | |\n|---|---:|---:|---|")
        for what, got, aim, unit in limit_aims:
            print(f"| {what} | {n(got)}{unit} | <= {n(aim)}{unit} | {'met' if got <= aim else 'not met'} |")
        aims += limit_aims

    cc = crosscheck(gdb_out, fw_out)
    doc = {
        "horizon": {"trajectory_1_s": 3.0, "trajectory_2_s": 6.0, "period_s": DT},
        "summary_f32": rows,
        "cases": cases,
        "crosscheck": cc,
        "flash": fl,
        "aims": [{"figure": w, "measured": got, "aim": aim, "met": got <= aim} for w, got, aim, _ in aims],
        "seconds": seconds,
    }
    with open(json_path, "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    print(f"\n(JSON: {json_path})")


def worst_args(fw_out):
    cases = read_cases(fw_out)
    wanted = defaultdict(set)
    for (plat, law), cs in groups(cases).items():
        for w in (worst(cs), worst(cs, "max_later", "max_later_step")):
            wanted[w["case"]].add(w["step"])
    print(" ".join(f"{c}:{','.join(map(str, sorted(s)))}" for c, s in wanted.items()))


def profile_args(fw_out):
    """The unicycle's f32 default steps to profile: its worst, its worst after the first, and
    two typical ones (t = 1 s of runs 1a and 1b, near those runs' means)."""
    cs = groups(read_cases(fw_out)).get(("unicycle", "default"), [])
    wanted = defaultdict(set)
    if cs:
        for w in (worst(cs), worst(cs, "max_later", "max_later_step")):
            wanted[w["case"]].add(w["step"])
    for c in ("uni-1a-f32", "uni-1b-f32"):
        wanted[c].add(1000)
    print(" ".join(f"{c}:{','.join(map(str, sorted(s)))}" for c, s in wanted.items()))


def main(argv):
    if len(argv) == 3 and argv[1] == "worst":
        worst_args(argv[2])
    elif len(argv) == 3 and argv[1] == "profile-steps":
        profile_args(argv[2])
    elif len(argv) == 7 and argv[1] == "table":
        table(argv[2], argv[3], argv[4], argv[5], int(argv[6]))
    else:
        sys.stderr.write(__doc__)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
