#!/usr/bin/env python3
"""Every internal link and anchor of the repository's Markdown resolves.

    python3 scripts/check_links.py [--root DIR]

Reads every `*.md` under the root (default: the repository; folders named `target` or `out`
and hidden ones left out) and checks each link that is not to another site — inline links
and images, reference definitions, HTML `href`/`src`:

- the file or folder it names exists, inside the root (no absolute paths: on GitHub they
  leave the repository);
- its `#anchor`, in a Markdown file, is a heading's anchor or an explicit `<a id>`, as GitHub
  *and* mdBook compute it (lower case, punctuation dropped, spaces to `-`, `-1`, `-2`, … for
  repeated headings) — a link that works on one but not the other is reported; `#L10` or
  `#L10-L20` in another file is a line range within it;
- `docs/book/src/SUMMARY.md` (if present) lists every chapter of `docs/book/src/` and only
  chapters that exist (mdBook would create a missing one empty, and leave out one unlisted).

Links inside code blocks and code spans are not links. Prints one line per problem
(`file:line: ...`) and exits 1 if there is any, else prints what it checked and exits 0.
Python's standard library only. `tests/tests/docs.rs` runs it on the repository and on small
trees with known faults.
"""

import argparse
import os
import re
import sys
import unicodedata
from urllib.parse import unquote

SKIP_DIRS = {"target", "out", "node_modules", "__pycache__"}
SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")
FENCE = re.compile(r"^( {0,3}|\s*(?:[-*+]|\d+[.)])?\s+)(`{3,}|~{3,})(.*)$")
HEADING = re.compile(r"^ {0,3}(#{1,6})[ \t]+(.*?)(?:[ \t]+#+)?[ \t]*$")
REF_DEF = re.compile(r"^ {0,3}\[([^\]]+)\]:\s*(<[^>]*>|\S+)")
HTML_ATTR = re.compile(r"""<[A-Za-z][^>]*?\b(href|src)\s*=\s*["']([^"']*)["']""")
HTML_ID = re.compile(r"""<[A-Za-z][^>]*?\b(?:id|name)\s*=\s*["']([^"']+)["']""")
LINE_ANCHOR = re.compile(r"^L(\d+)(?:-L(\d+))?$")


def markdown_files(root):
    """Every `*.md` under `root`, sorted, as paths relative to it."""
    found = []
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d not in SKIP_DIRS and not d.startswith("."))
        found += [os.path.relpath(os.path.join(folder, f), root) for f in files if f.endswith(".md")]
    return sorted(found)


def without_code_spans(line):
    """The line with its inline code spans (`...`, ``...``) blanked out."""
    out, i = [], 0
    while i < len(line):
        if line[i] == "`":
            n = len(line[i:]) - len(line[i:].lstrip("`"))
            end = line.find("`" * n, i + n)
            # A run of n backticks closes only on a run of exactly n.
            while end != -1 and line[end + n : end + n + 1] == "`":
                end = line.find("`" * n, end + n + 1)
            if end == -1:
                out.append(line[i : i + n])
                i += n
                continue
            out.append(" " * (end + n - i))
            i = end + n
        else:
            out.append(line[i])
            i += 1
    return "".join(out)


def prose_lines(text):
    """(line number, line) of the lines outside fenced code blocks and HTML comments."""
    fence = None
    in_comment = False
    for n, line in enumerate(text.split("\n"), 1):
        if fence is not None:
            m = FENCE.match(line)
            if m and m.group(2)[0] == fence[0] and len(m.group(2)) >= len(fence) and not m.group(3).strip():
                fence = None
            continue
        m = FENCE.match(line)
        if m and not (m.group(2)[0] == "`" and "`" in m.group(3)):
            fence = m.group(2)
            continue
        # HTML comments (one or several lines) say nothing a reader follows.
        kept = ""
        rest = line
        while rest:
            if in_comment:
                end = rest.find("-->")
                if end == -1:
                    rest = ""
                else:
                    in_comment = False
                    rest = rest[end + 3 :]
            else:
                start = rest.find("<!--")
                if start == -1:
                    kept += rest
                    rest = ""
                else:
                    kept += rest[:start]
                    in_comment = True
                    rest = rest[start + 4 :]
        yield n, kept


def heading_text(raw):
    """A heading's text as a reader sees it: no markup, links by their text."""
    t = re.sub(r"!\[([^\]]*)\]\([^)]*\)", r"\1", raw)
    t = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", t)
    t = re.sub(r"<[^>]+>", "", t)
    t = t.replace("`", "")
    t = re.sub(r"\\(.)", r"\1", t)
    t = re.sub(r"(\*\*|__|\*|~~)", "", t)
    return t.strip()


def github_slug(text):
    """GitHub's anchor: lower case, all but letters, marks, digits, `_`, `-` and spaces
    dropped, each space a `-`."""
    kept = (c for c in text.lower() if c in "-_ " or unicodedata.category(c)[0] in "LMN")
    return "".join(kept).replace(" ", "-")


def mdbook_slug(text):
    """mdBook's (`normalize_id`): alphanumerics (ASCII-lowercased), `_` and `-` kept, each
    white space a `-`, the rest dropped."""
    out = []
    for c in text:
        if c.isspace():
            out.append("-")
        elif c in "_-" or unicodedata.category(c)[0] in "LN":
            out.append(c.lower() if c.isascii() else c)
    return "".join(out)


def unique(slugs):
    """Repeated slugs as both renderers number them: `x`, `x-1`, `x-2`, …"""
    seen, out = {}, []
    for s in slugs:
        k = seen.get(s, 0)
        out.append(s if k == 0 else f"{s}-{k}")
        seen[s] = k + 1
    return out


class Doc:
    """A Markdown file's links and anchors."""

    def __init__(self, path, text):
        self.path = path
        self.links = []  # (line, target)
        headings, explicit = [], set()
        for n, line in prose_lines(text):
            explicit.update(HTML_ID.findall(line))
            m = HEADING.match(line)
            if m:
                headings.append(heading_text(m.group(2)))
            code_free = without_code_spans(line)
            m = REF_DEF.match(code_free)
            if m:
                self.links.append((n, m.group(2).strip("<>")))
                continue
            for target in inline_targets(code_free):
                self.links.append((n, target))
            for _, target in HTML_ATTR.findall(code_free):
                self.links.append((n, target))
        self.github = set(unique([github_slug(h) for h in headings])) | explicit
        self.mdbook = set(unique([mdbook_slug(h) for h in headings])) | explicit


def inline_targets(line):
    """The destinations of the line's inline links and images `[text](dest "title")`."""
    out = []
    i = line.find("](")
    while i != -1:
        j = i + 2
        while j < len(line) and line[j] == " ":
            j += 1
        if j < len(line) and line[j] == "<":
            end = line.find(">", j)
            if end != -1:
                out.append(line[j + 1 : end])
            i = line.find("](", j)
            continue
        depth, k = 0, j
        while k < len(line):
            c = line[k]
            if c == "(":
                depth += 1
            elif c == ")":
                if depth == 0:
                    break
                depth -= 1
            elif c.isspace():
                break
            k += 1
        out.append(line[j:k])
        i = line.find("](", k)
    return out


def check(root):
    """(problems, number of links checked, number of files)."""
    root = os.path.abspath(root)
    files = markdown_files(root)
    docs = {}
    for f in files:
        with open(os.path.join(root, f), encoding="utf-8") as fh:
            docs[f] = Doc(f, fh.read())
    problems, checked = [], 0
    for f, doc in docs.items():
        for n, target in doc.links:
            if not target or SCHEME.match(target):
                continue
            checked += 1
            where = f"{f}:{n}: link {target!r}"
            path, _, anchor = target.partition("#")
            path = unquote(path)
            if path.startswith("/"):
                problems.append(f"{where}: an absolute path (on GitHub it leaves the repository)")
                continue
            if path:
                full = os.path.normpath(os.path.join(root, os.path.dirname(f), path))
                if os.path.relpath(full, root).startswith(".."):
                    problems.append(f"{where}: outside the repository")
                    continue
                if not os.path.exists(full):
                    problems.append(f"{where}: no such file or folder")
                    continue
                rel = os.path.relpath(full, root)
            else:
                rel = f
            if not anchor:
                continue
            anchor = unquote(anchor)
            if rel in docs:
                d = docs[rel]
                on_github, on_mdbook = anchor in d.github, anchor in d.mdbook
                if not on_github and not on_mdbook:
                    problems.append(f"{where}: no heading or id '#{anchor}' in {rel}")
                elif not on_github:
                    problems.append(f"{where}: '#{anchor}' is mdBook's anchor, not GitHub's")
                elif not on_mdbook:
                    problems.append(f"{where}: '#{anchor}' is GitHub's anchor, not mdBook's")
            else:
                m = LINE_ANCHOR.match(anchor)
                if not m or os.path.isdir(os.path.join(root, rel)):
                    problems.append(f"{where}: an anchor into {rel}, which is not Markdown")
                    continue
                with open(os.path.join(root, rel), encoding="utf-8", errors="replace") as fh:
                    lines = fh.read().count("\n") + 1
                last = int(m.group(2) or m.group(1))
                if last > lines:
                    problems.append(f"{where}: {rel} has {lines} lines")
    problems += summary_problems(root, docs)
    return problems, checked, len(files)


def summary_problems(root, docs):
    """SUMMARY.md against the book's chapters."""
    src = os.path.join("docs", "book", "src")
    summary = os.path.join(src, "SUMMARY.md")
    if summary not in docs:
        return []
    listed = set()
    for _, target in docs[summary].links:
        path = unquote(target.partition("#")[0])
        if path and not SCHEME.match(path):
            listed.add(os.path.normpath(os.path.join(src, path)))
    return [
        f"{summary}: does not list the chapter {f}"
        for f in docs
        if f.startswith(src + os.sep) and f != summary and f not in listed
    ]


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--root", default=os.path.dirname(here), help="the tree to check (default: the repository)")
    args = ap.parse_args()
    problems, checked, files = check(args.root)
    for p in problems:
        print(p)
    if problems:
        print(f"{len(problems)} broken of {checked} internal links in {files} Markdown files")
        return 1
    print(f"{checked} internal links and anchors in {files} Markdown files: all resolve")
    return 0


if __name__ == "__main__":
    sys.exit(main())
