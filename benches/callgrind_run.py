#!/usr/bin/env python3
"""Where the instructions of a simulated run go, per step: the parts of the loop body.

usage: callgrind_run.py STEPS BINARY MAIN.out [OTHER_THREAD.out ...]

MAIN.out is the callgrind output (`--dump-instr=yes --separate-threads=yes`) of the thread
that runs `companion_runtime::sim::run_loop`; the others are the remaining threads (the CSV
writer). Made by benches/profile_run.sh.

Robust to inlining: every instruction of the function that holds the loop (run_loop, or
run_one if run_loop was inlined into it) and every call made from it are looked up with
`addr2line -i`; the cost (self, or the call's inclusive cost) is charged to the frame
inlined directly into run_loop — `AnyController::step`, `Plant::advance`, ... — or, for a
call made by run_loop itself, to the function called.
"""
import collections
import re
import subprocess
import sys

LOOP = "companion_runtime::sim::run_loop"

HANDOFF = "recording: logged rows (CSV, or hand-off)"
# The parts, by the first matching fragment of the charged frame's name.
PARTS = [
    ("controller step", ["AnyController::step", "InProcess", "Exchange>::exchange", "companion_core::"]),
    ("plant step (RK4)", ["Plant<A,_>::advance", "Plant<A, _>::advance", "try_advance", "companion_plant::dynamics"]),
    ("measurement", ["Plant<A,_>::measure", "Plant<A, _>::measure"]),
    ("plant sample (logged end effector)", ["sim::sample", "sim::summary_sample", "end_effector"]),
    (HANDOFF, ["Recorder::record", "Recorder::logs", "Recorder::join_writer"]),
    ("progress bar", ["indicatif"]),
]
SUMMARY = "recording: summary over every step"


def parse(path):
    """Per function: self cost per address, and (address, callee, inclusive) per call."""
    names = {}

    def name(kind, text):
        m = re.match(r"\((\d+)\)(?: (.*))?", text)
        if not m:
            return text
        if m.group(2) is not None:
            names[(kind, m.group(1))] = m.group(2)
        return names.get((kind, m.group(1)), "?")

    self_cost = collections.defaultdict(collections.Counter)
    calls = collections.defaultdict(list)
    total = 0
    fn = callee = None
    last = [0, 0]
    pending = False
    for raw in open(path):
        line = raw.rstrip("\n")
        if not line or line.startswith("#"):
            continue
        m = re.match(r"(summary|totals):(.*)", line)
        if m:
            total = int(m.group(2).strip())
            continue
        m = re.match(r"(\w+)=(.*)", line)
        if m:
            key, val = m.groups()
            if key in ("fl", "fi", "fe", "cfl", "cfi"):
                name("fl", val)
            elif key in ("ob", "cob"):
                name("ob", val)
            elif key == "fn":
                fn = name("fn", val)
            elif key == "cfn":
                callee = name("fn", val)
            elif key == "calls":
                pending = True
            continue
        if line[0] not in "0123456789+-*":
            continue
        parts = line.split()
        pos = []
        for i in range(2):
            p = parts[i]
            v = last[i] if p == "*" else last[i] + int(p, 0) if p[0] in "+-" else int(p, 0)
            pos.append(v)
        last = pos
        c = int(parts[2]) if len(parts) > 2 else 0
        if pending:
            calls[fn].append((pos[0], callee, c))
            pending = False
        else:
            self_cost[fn][pos[0]] += c
    return self_cost, calls, total


def chains(binary, addrs):
    out = subprocess.run(
        ["addr2line", "-a", "-f", "-i", "-C", "-e", binary],
        input="".join(f"{a:#x}\n" for a in addrs),
        capture_output=True,
        text=True,
        check=True,
    ).stdout.splitlines()
    result, cur, i = {}, None, 0
    while i < len(out):
        if out[i].startswith("0x"):
            cur = int(out[i], 16)
            result[cur] = []
            i += 1
        else:
            result[cur].append(out[i])
            i += 2
    return result


def part_of(below, callee):
    """The part for the inline frames below run_loop (outermost first) and the callee."""
    for part, fragments in PARTS:
        if below and any(f in below[0] for f in fragments):
            # The summary is inlined into Recorder::record or called from it.
            if part.startswith("recording") and any("SummaryAccumulator::add" in f for f in below + [callee or ""]):
                return SUMMARY
            return part
    if callee and not below:
        for part, fragments in PARTS:
            if any(f in callee for f in fragments):
                return SUMMARY if "SummaryAccumulator::add" in callee else part
    return "the loop itself (counter, row, Result)"


RECORD = "companion_runtime::record::Recorder::record"


def summary_in(prefix, self_cost, calls, binary):
    """The cost of SummaryAccumulator::add inside the functions named `prefix`, inlined or
    called."""
    items = []
    for f in self_cost:
        if f and f.startswith(prefix):
            items += [(a, None, c) for a, c in self_cost[f].items()]
            items += calls[f]
    ch = chains(binary, sorted({a for a, _, _ in items}))
    return sum(
        c
        for a, callee, c in items
        if any("SummaryAccumulator::add" in fr for fr in ch.get(a, [])) or "SummaryAccumulator::add" in (callee or "")
    )


def main():
    steps, binary, main_out = float(sys.argv[1]), sys.argv[2], sys.argv[3]
    self_cost, calls, main_total = parse(main_out)
    holders = [f for f in self_cost if f and (f.startswith(LOOP) or f.startswith("companion_runtime::sim::run_one"))]
    items = []  # (address, callee or None, cost)
    for f in holders:
        items += [(a, None, c) for a, c in self_cost[f].items()]
        items += calls[f]
    ch = chains(binary, sorted({a for a, _, _ in items}))
    per_part = collections.Counter()
    in_loop = 0
    split_record = False
    for a, callee, c in items:
        chain = ch.get(a, [])
        idx = next((i for i, fr in enumerate(chain) if fr.startswith(LOOP)), None)
        if idx is None:
            continue  # run_one's own work outside the loop (set-up, summary file)
        in_loop += c
        below = list(reversed(chain[:idx]))  # outermost first
        part = part_of(below, callee)
        if part.startswith("recording") and callee and callee.startswith(RECORD):
            split_record = True
        per_part[part] += c
    if split_record:
        # Recorder::record is a function of its own (called only from the loop): split
        # its inclusive cost.
        summary = summary_in(RECORD, self_cost, calls, binary)
        per_part[SUMMARY] += summary
        per_part[HANDOFF] -= summary
    print(f"{'main thread, whole process':<56} {main_total / steps:8.0f}")
    print(f"{'  the loop (run_loop)':<56} {in_loop / steps:8.0f}  100.0 %")
    for part, c in per_part.most_common():
        if c / steps >= 0.5:
            print(f"{'    ' + part:<56} {c / steps:8.0f}  {100 * c / in_loop:5.1f} %")
    for other in sys.argv[4:]:
        _, _, t = parse(other)
        print(f"{'CSV writer thread (formatting, writing)':<56} {t / steps:8.0f}")


if __name__ == "__main__":
    main()
