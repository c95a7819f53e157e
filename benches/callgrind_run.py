#!/usr/bin/env python3
"""Where the instructions of a simulated run go, per step: the parts of the loop body.

usage: callgrind_run.py STEPS BINARY MAIN.out [OTHER_THREAD.out ...]

MAIN.out is the callgrind output (`--dump-instr=yes --separate-threads=yes`) of the thread
that runs `companion_runtime::run::sim::run_loop`; the others are the remaining threads (the CSV
writer). Made by benches/profile_run.sh.

Robust to inlining: every instruction of the function that holds the loop (run_loop, or
run_one or simulate if run_loop was inlined into it) and every call made from it are looked up with
`addr2line -i`; the cost (self, or the call's inclusive cost) is charged to the frame
inlined directly into run_loop — `AnyController::step`, `Plant::advance`, ... — or, for a
call made by run_loop itself, to the function called.
"""
import collections
import sys

from callgrind_format import inline_chains, parse

LOOP = "companion_runtime::run::sim::run_loop"

HANDOFF = "recording: logged rows (CSV, or hand-off)"
# The parts, by the first matching fragment of the charged frame's name.
PARTS = [
    ("controller step", ["AnyController::step", "InProcess", "Exchange>::exchange", "companion_core::"]),
    ("plant step (RK4)", ["Plant<A,_>::advance", "Plant<A, _>::advance", "try_advance", "companion_plant::dynamics"]),
    ("measurement", ["Plant<A,_>::measure", "Plant<A, _>::measure"]),
    ("plant sample (logged end effector)", ["robot::sample", "Robot<", "end_effector", "tracking_error"]),
    (HANDOFF, ["RecordWriter", "RowSink", "rtrb::", "Recorder::record"]),
    ("progress bar", ["indicatif"]),
]
SUMMARY = "recording: summary over every step"


def load(path):
    """Per function: self cost per address, (address, callee, inclusive) per call; the total."""
    prof = parse(path)
    calls = {fn: [(a, callee, c) for a, callee, _, c in sites] for fn, sites in prof.calls.items()}
    return prof.self_cost, collections.defaultdict(list, calls), prof.total


def chains(binary, addrs):
    """{address: [function, ...]}, innermost inlined frame first."""
    return {a: [f for f, _ in frames] for a, frames in inline_chains(binary, addrs).items()}


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


# The hand-off of a row to the writer thread (the summary is accumulated on that thread since
# the simulation and the HIL plant share one writer; a direct Recorder still splits it here).
RECORD = "<companion_runtime::domain::record::writer::RecordWriter as companion_runtime::domain::record::recorder::RowSink>::record"


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
    self_cost, calls, main_total = load(main_out)
    holders = [
        f
        for f in self_cost
        if f
        and (
            f.startswith(LOOP)
            or f.startswith("companion_runtime::run::sim::run_one")
            or f.startswith("companion_runtime::run::sim::simulate")
        )
    ]
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
        _, _, t = load(other)
        print(f"{'CSV writer thread (summary, formatting, writing)':<56} {t / steps:8.0f}")


if __name__ == "__main__":
    main()
