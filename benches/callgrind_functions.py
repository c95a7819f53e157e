#!/usr/bin/env python3
"""Instructions per controller step, function by function, from two callgrind runs.

usage: callgrind_functions.py ONE.out TWO.out STEPS BINARY

ONE.out and TWO.out are `valgrind --tool=callgrind --dump-instr=yes` outputs of
`count_steps CONFIG 1` and `count_steps CONFIG 2` (benches/callgrind.sh --functions makes
them); STEPS is the number of steps in one pass. The difference of the two runs is exactly
one pass of controller steps.

The core is compiled into a few big functions (everything is inlined into `step`), so
callgrind's own per-function totals say little. Here every instruction address of the
difference is looked up with `addr2line -i`, which gives the chain of inlined frames, and
its cost is charged to the innermost frame whose source is in `core/src/` — so arithmetic
inlined from `core::ops` or nalgebra counts for the law's function that does it — or, for
code outside the core (libm, the benchmark harness), to the innermost frame. Calls per step
of libm functions come from callgrind's call counts.
"""
import collections
import re
import sys

from callgrind_format import inline_chains, parse


def costs(path):
    """Self cost per instruction address in count_steps, and call counts per callee name."""
    prof = parse(path)
    cost = collections.Counter()
    for fn, per_addr in prof.self_cost.items():
        if "count_steps" in (prof.obj.get(fn) or ""):
            cost.update(per_addr)
    calls = collections.Counter()
    for sites in prof.calls.values():
        for _, callee, count, _ in sites:
            calls[callee] += count
    return cost, calls


# libm's helpers, charged to the function that uses them.
LIBM = {
    "k_sin": "sincos",
    "k_cos": "sincos",
    "rem_pio2": "sincos",
    "rem_pio2_large": "sincos",
    "get_high_word": "sincos",
    "get_low_word": "sincos",
    "scalbn": "sincos",
    "sincos": "sincos",
    "exp": "exp",
    "atan": "atan",
    "atan2": "atan2",
    "sqrt": "sqrt",
}


def main():
    one, two, steps, binary = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4]
    cost1, calls1 = costs(one)
    cost2, calls2 = costs(two)
    diff = {a: c - cost1.get(a, 0) for a, c in cost2.items() if c != cost1.get(a, 0)}
    chains = inline_chains(binary, sorted(diff))

    def short(fn):
        fn = re.sub(r"<(\w+) as companion_core::[\w:]+::(\w+)<[^>]*>>", r"<\1 as \2>", fn)
        fn = fn.replace("companion_core::", "")
        fn = re.sub(r"<T,P,A,_>|<T,_>|<T>|<A,_>", "", fn)
        return fn

    per_fn = collections.Counter()
    for a, c in diff.items():
        chain = chains.get(a, [])
        core = [(f, l) for f, l in chain if "/core/src/" in l and "/rustc/" not in l]
        if chain and "libm" in chain[0][1]:
            # libm, inlined or not: charged to the elementary function the core called.
            outer = [f for f, l in chain if "libm" in l][-1]
            key = f"{LIBM.get(outer.split('::')[-1], outer)}  [libm]"
        elif core:
            fn, loc = core[0]
            key = f"{short(fn)}  [{loc.split('/core/src/')[1].split(':')[0]}]"
        elif chain:
            fn, loc = chain[0]
            key = f"{short(fn)}  [{'harness' if 'benches/' in loc else 'other'}]"
        else:
            key = "?"
        per_fn[key] += c
    total = sum(diff.values())
    print(f"{total / steps:8.0f}  instructions per step (100 %)")
    for key, c in per_fn.most_common():
        if c / steps < 1.5:
            break
        print(f"{c / steps:8.0f}  {100 * c / total:4.1f} %  {key}")
    print("calls per step:")
    for f in sorted(calls2):
        n = (calls2[f] - calls1.get(f, 0)) / steps
        if f and f.startswith("libm::") and n >= 0.05:
            print(f"{n:8.2f}  {f}")


if __name__ == "__main__":
    main()
