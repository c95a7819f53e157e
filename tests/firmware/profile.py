#!/usr/bin/env python3
"""Where a controller step's instructions go: a profile per function of single-stepped steps.

Reads the traces that `gdbcount.py --trace DIR` writes (one `pc sp lr` line, hex, before
each instruction of a counted step) and attributes every instruction to functions with the
ELF's debug information:
  - the inlined frames of its address (`addr2line -f -i`: the function the compiler wrote
    the instruction for, and each function it was inlined into, up to the real function);
  - the real calls around it, rebuilt from the trace: an instruction at a function's entry
    (an `nm` symbol) opens a frame whose return is the link register and whose caller is
    the previous instruction (with its own inlined frames); reaching that return with the
    stack pointer of the entry closes it (tail calls share their caller's return).
A function's *self* count is the instructions whose innermost frame it is; its *core self*
count gives each instruction to the innermost frame that is a function of companion-core
(so that nalgebra's and core's arithmetic inlined into the law counts for the law's
function that uses it); its *inclusive* count is the instructions during which it is on
the (inlined or real) call stack, each counted once.

Usage: profile.py ELF TRACE [TRACE ...]   (prints one profile per trace, Markdown)
Needs addr2line (binutils) or llvm-addr2line, and nm or llvm-nm.
"""

import re
import shutil
import subprocess
import sys
from collections import Counter
from pathlib import Path

TOP = 25  # rows per table


def tool(*names):
    for n in names:
        if shutil.which(n):
            return n
    sys.exit(f"profile: none of {', '.join(names)} is on the PATH")


def function_starts(elf):
    out = subprocess.run([tool("nm", "llvm-nm"), elf], capture_output=True, text=True, check=True).stdout
    return {int(f[0], 16) & ~1 for f in (line.split() for line in out.splitlines()) if len(f) >= 3 and f[1] in "tTwW"}


def inline_chains(elf, pcs):
    """{pc: [outermost function, ..., innermost]} by addr2line."""
    pcs = sorted(pcs)
    a2l = tool("addr2line", "llvm-addr2line")
    text = "\n".join(f"0x{pc:x}" for pc in pcs) + "\n"
    out = subprocess.run([a2l, "-a", "-f", "-i", "-C", "-e", elf], input=text, capture_output=True, text=True,
                         check=True).stdout
    chains, current, lines = {}, None, []
    for line in out.splitlines() + ["0x0"]:
        if re.fullmatch(r"0x[0-9a-f]+", line):
            if current is not None:
                names = [simplify(lines[i]) for i in range(0, len(lines), 2)]
                chains[current] = list(reversed(names)) or ["??"]
            current, lines = int(line, 16), []
        else:
            lines.append(line)
    return chains


def strip_generics(name):
    """Drops generic argument lists (`Foo<f32, 3>` -> `Foo`), keeps qualified paths."""
    out, depth, i = [], 0, 0
    while i < len(name):
        ch = name[i]
        if ch == "<" and (depth > 0 or (out and (out[-1].isalnum() or out[-1] in "_:"))):
            depth += 1
        elif ch == ">" and depth > 0:
            depth -= 1
        elif depth == 0:
            out.append(ch)
        i += 1
    return "".join(out)


def simplify(name):
    name = strip_generics(name).replace("::::", "::")
    if name.endswith("::"):
        name = name[:-2]
    m = re.fullmatch(r"<(.*) as (.*)>::(\w+)", name)
    if m:
        name = f"<{short(m.group(1))} as {short(m.group(2))}>::{m.group(3)}"
    else:
        m = re.fullmatch(r"<(.*)>::(.*)", name)
        name = f"{short(m.group(1))}::{m.group(2)}" if m else short(name)
    return name


def short(path):
    parts = path.split("::")
    crate = parts[0]
    keep = parts[-2:] if len(parts) > 2 else parts
    prefix = {"companion_core": "core:", "companion_firmware": "fw:", "nalgebra": "na:", "core": "std:",
              "libm": "libm:", "compiler_builtins": "cb:"}.get(crate, "")
    return prefix + "::".join(keep)


def profile(trace, starts, chains_of):
    rows = [tuple(int(x, 16) for x in line.split()) for line in open(trace) if line.strip()]
    selfc, corec, incl = Counter(), Counter(), Counter()
    frames = []  # (return address, stack pointer at entry, the caller's inlined chain)
    prev = None
    for pc, sp, lr in rows:
        while frames and pc == frames[-1][0] and sp == frames[-1][1]:
            frames.pop()
        # A call: at a function's entry with the link register just set by the previous
        # instruction (bl: 4 bytes, blx: 2); a tail call: at an entry with the stack
        # pointer of the current frame's entry (its own frame already popped). A branch
        # to a symbol inside a function (LLVM shares blocks) is neither.
        called = prev is not None and (lr & ~1) in (prev + 2, prev + 4)
        tail = frames and sp == frames[-1][1]
        if prev is not None and pc in starts and (called or tail):
            frames.append((lr & ~1, sp, chains_of[prev]))
        chain = chains_of[pc]
        stack = [f for fr in frames for f in fr[2]] + chain
        selfc[chain[-1]] += 1
        corec[next((f for f in reversed(stack) if f.startswith("core:")), chain[-1])] += 1
        for f in set(stack):
            incl[f] += 1
        prev = pc
    return len(rows), selfc, corec, incl


def main(argv):
    if len(argv) < 3:
        sys.stderr.write(__doc__)
        return 2
    elf, traces = argv[1], argv[2:]
    starts = function_starts(elf)
    pcs = set()
    for t in traces:
        pcs.update(int(line.split()[0], 16) for line in open(t) if line.strip())
    chains_of = inline_chains(elf, pcs)
    results = {}
    for t in traces:
        total, selfc, corec, incl = results[Path(t).stem] = profile(t, starts, chains_of)
        print(f"\nProfile of {Path(t).stem} ({total} instructions between the SysTick readings):\n")
        print("| instructions, self | % | function (innermost inlined frame) |\n|---:|---:|---|")
        for f, c in selfc.most_common(TOP):
            print(f"| {c} | {100 * c / total:.1f} | `{f}` |")
        print("\n| instructions, core self | % | companion-core function (innermost on the stack) |\n|---:|---:|---|")
        for f, c in corec.most_common(TOP):
            print(f"| {c} | {100 * c / total:.1f} | `{f}` |")
        print("\n| instructions, inclusive | % | function (on the inlined or real call stack) |\n|---:|---:|---|")
        for f, c in incl.most_common(TOP + 10):
            print(f"| {c} | {100 * c / total:.1f} | `{f}` |")
    if len(results) > 1:
        # Side by side: companion-core's functions, inclusive (the most in any step first),
        # and the copies (memcpy, memset), in each profiled step.
        names = list(results)
        core = Counter()
        for _, _, _, incl in results.values():
            for f, c in incl.items():
                if f.startswith("core:") or "memcpy" in f or "memset" in f or "memclr" in f:
                    core[f] = max(core[f], c)
        print("\nInclusive instructions per step, side by side (companion-core's functions and the copies):\n")
        print("| function | " + " | ".join(names) + " |\n|---|" + "---:|" * len(names))
        print("| (all) | " + " | ".join(str(results[k][0]) for k in names) + " |")
        for f, _ in core.most_common(TOP + 15):
            print(f"| `{f}` | " + " | ".join(str(results[k][3][f]) for k in names) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
