"""Reading callgrind output and inline frames: shared by callgrind_functions.py and
callgrind_run.py.

`parse` reads a `valgrind --tool=callgrind --dump-instr=yes` output (names compressed or
not, positions relative or absolute) into per-function costs by instruction address;
`inline_chains` asks `addr2line -i` for the inlined frames at each address.
"""
import collections
import re
import subprocess


class Profile:
    """One callgrind output.

    self_cost[fn][address]: instructions executed at `address` in `fn` itself;
    calls[fn]: (address, callee, count, inclusive cost) for each call site in `fn`;
    obj[fn]: the object file `fn` belongs to; total: the output's total.
    """

    def __init__(self):
        self.self_cost = collections.defaultdict(collections.Counter)
        self.calls = collections.defaultdict(list)
        self.obj = {}
        self.total = 0


def parse(path):
    """Reads the callgrind output at `path` into a `Profile`."""
    names = {}

    def name(kind, text):
        m = re.match(r"\((\d+)\)(?: (.*))?", text)
        if not m:
            return text
        if m.group(2) is not None:
            names[(kind, m.group(1))] = m.group(2)
        return names.get((kind, m.group(1)), "?")

    prof = Profile()
    obj = fn = callee = None
    count = 0
    last = [0, 0]
    pending = False  # the next cost line is a call's inclusive cost
    for raw in open(path):
        line = raw.rstrip("\n")
        if not line or line.startswith("#"):
            continue
        m = re.match(r"(summary|totals):(.*)", line)
        if m:
            prof.total = int(m.group(2).strip())
            continue
        m = re.match(r"(\w+)=(.*)", line)
        if m:
            key, val = m.groups()
            if key in ("fl", "fi", "fe", "cfl", "cfi"):
                name("fl", val)
            elif key == "ob":
                obj = name("ob", val)
            elif key == "cob":
                name("ob", val)
            elif key == "fn":
                fn = name("fn", val)
                prof.obj.setdefault(fn, obj)
            elif key == "cfn":
                callee = name("fn", val)
            elif key == "calls":
                count = int(val.split()[0])
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
            prof.calls[fn].append((pos[0], callee, count, c))
            pending = False
        else:
            prof.self_cost[fn][pos[0]] += c
    return prof


def inline_chains(binary, addrs):
    """{address: [(function, file:line), ...]}, innermost inlined frame first."""
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
            result[cur].append((out[i], out[i + 1] if i + 1 < len(out) else ""))
            i += 2
    return result
