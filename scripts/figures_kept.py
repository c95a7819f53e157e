#!/usr/bin/env python3
"""Every number of the documentation at an earlier commit is still in the documentation now.

    python3 scripts/figures_kept.py [BASE] [--verbose]

Lists the numbers of BASE's README.md and Markdown under docs/ (default BASE: the commit
before the README was cut down to a page and the rest moved into docs/book/) and looks for
each in today's README.md and every Markdown file under docs/. A number is a run of digits
with its decimal part, exponent (`e−7`), superscript exponent (`10⁻⁴`) and thousands
groups (`20 001`), not part of a word or name (`f64`, `T1`, `a52c08f`). Prints the numbers
not found, the numbers found fewer times than before (a repeated figure may have been said
once), and a count; exits 1 if a number is missing. Python's standard library and git.
"""

import argparse
import os
import re
import subprocess
import sys
from collections import Counter

BASE = "d4bbbc0"  # the last commit with the 1 409-line README
SUPERSCRIPTS = "⁰¹²³⁴⁵⁶⁷⁸⁹⁻"
NUMBER = re.compile(
    r"(?<![\w.,/#@$&-])(\d{1,3}(?: \d{3})+|\d+)(\.\d+)?(e-?\d+)?([" + SUPERSCRIPTS + r"]+)?(?![\w])"
)


def normalise(text):
    """One kind of space and minus; lines joined (a number may be wrapped)."""
    for c in "\u2009\u202f\u00a0\n\t":
        text = text.replace(c, " ")
    return text.replace("\u2212", "-")


def numbers(text):
    return Counter("".join(m.groups(default="")) for m in NUMBER.finditer(normalise(text)))


def git(*args):
    return subprocess.run(["git", *args], capture_output=True, text=True, check=True).stdout


def documents_at(rev):
    names = [n for n in git("ls-tree", "-r", "--name-only", rev).split("\n") if n]
    keep = [n for n in names if n == "README.md" or (n.startswith("docs/") and n.endswith(".md"))]
    return {n: git("show", f"{rev}:{n}") for n in keep}


def documents_now(root):
    out = {"README.md": open(os.path.join(root, "README.md"), encoding="utf-8").read()}
    for folder, _, files in os.walk(os.path.join(root, "docs")):
        for f in files:
            if f.endswith(".md"):
                p = os.path.join(folder, f)
                out[os.path.relpath(p, root)] = open(p, encoding="utf-8").read()
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("base", nargs="?", default=BASE)
    ap.add_argument("--verbose", action="store_true", help="also list the numbers said fewer times")
    args = ap.parse_args()
    root = git("rev-parse", "--show-toplevel").strip()
    os.chdir(root)
    before_docs = documents_at(args.base)
    now = Counter()
    for text in documents_now(root).values():
        now += numbers(text)
    status = 0
    for name in ["README.md"] + sorted(n for n in before_docs if n != "README.md"):
        before = numbers(before_docs[name])
        missing = sorted(n for n in before if now[n] == 0)
        fewer = sorted(n for n in before if 0 < now[n] < before[n])
        print(
            f"{name} at {args.base}: {len(before)} distinct numbers ({sum(before.values())} in all); "
            f"found now: {len(before) - len(missing)}; missing: {len(missing)}"
        )
        for n in missing:
            print(f"  missing: {n!r} ({before[n]}× before)")
        if args.verbose:
            for n in fewer:
                print(f"  fewer: {n!r} {before[n]}× before, {now[n]}× now")
        status |= bool(missing)
    return status


if __name__ == "__main__":
    sys.exit(main())
