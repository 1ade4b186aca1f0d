#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Lists what keeps the non-test code from reading as a plan (issue 47): modules that include each
other, `../` includes, and folders of sources with more than 25 files.

A module is a header and its source: files of one library (the folder that holds `include/` and
`src/`) with the same name before the extension. Module A includes module B when any file of A
includes a file of B; two modules that include each other are a cycle. Test code (tests/) is not
read. Exits 1 when anything is listed, 0 when the tree is clean.

Usage: tools/include_cycles.py [--under PREFIX]... [ROOT]
  ROOT    the project (default: the folder above tools/)
  --under report only problems whose files are all under PREFIX (repeatable; the whole tree is
          still read). The test suite holds the folders already clean to it.
"""
import os
import re
import sys

SOURCE_DIRS = ["common", "proto", "remote_node", "local_node", "tools"]
EXTS = (".h", ".hpp", ".cpp", ".cc")
MAX_FILES = 25
INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"', re.M)


def library_of(path):
    """The folder whose include/ or src/ holds the file (or the file's own folder)."""
    parts = path.split(os.sep)
    for i in range(len(parts) - 1, 0, -1):
        if parts[i] in ("include", "src"):
            return os.sep.join(parts[:i])
    return os.path.dirname(path)


def module_of(path):
    return (library_of(path), os.path.splitext(os.path.basename(path))[0])


def main():
    args, under = sys.argv[1:], []
    while args and args[0] == "--under":
        if len(args) < 2:
            print("include_cycles.py: --under needs a PREFIX", file=sys.stderr)
            return 2
        under.append(args[1].rstrip("/") + "/")
        args = args[2:]
    if len(args) > 1 or (args and args[0].startswith("-")):
        print(f"include_cycles.py: unexpected arguments {args}; see --help in the file's header",
              file=sys.stderr)
        return 2
    root = os.path.abspath(args[0] if args else os.path.join(os.path.dirname(__file__), ".."))

    def wanted(*paths):
        return not under or all(any(p.startswith(u) for u in under) for p in paths)
    os.chdir(root)
    files = []
    for top in SOURCE_DIRS:
        for d, _, names in os.walk(top):
            files += [os.path.join(d, n) for n in names if n.endswith(EXTS)]
    roots = sorted({os.path.join(library_of(f), "include") for f in files
                    if os.path.isdir(os.path.join(library_of(f), "include"))})
    known = set(files)

    def resolve(src, inc):
        for base in [os.path.dirname(src), library_of(src), os.path.join(library_of(src), "src")] + roots:
            p = os.path.normpath(os.path.join(base, inc))
            if p in known:
                return p
        return None

    problems = []
    edges = {}
    for f in sorted(files):
        with open(f, encoding="utf-8", errors="replace") as fh:
            text = fh.read()
        for inc in INCLUDE.findall(text):
            if (inc.startswith("../") or "/../" in inc) and wanted(f):
                problems.append(f"parent include: {f} includes \"{inc}\"")
            target = resolve(f, inc)
            if target is None:
                continue
            a, b = module_of(f), module_of(target)
            if a != b:
                edges.setdefault(a, {}).setdefault(b, (f, target))
    seen = set()
    for a, outs in sorted(edges.items()):
        for b, (fa, ta) in sorted(outs.items()):
            if a < b and a in edges.get(b, {}):
                fb, tb = edges[b][a]
                if not wanted(fa, ta, fb, tb):
                    continue
                problems.append(f"cycle: {fa} -> {ta} and {fb} -> {tb}")
                seen.add((a, b))
    for d in sorted({os.path.dirname(f) for f in files}):
        n = sum(1 for f in files if os.path.dirname(f) == d)
        if n > MAX_FILES and wanted(d + "/"):
            problems.append(f"crowded folder: {d} holds {n} source files (at most {MAX_FILES})")
    for p in problems:
        print(p)
    print(f"{len(seen)} module cycle(s), {sum(p.startswith('parent') for p in problems)} parent "
          f"include(s), {sum(p.startswith('crowded') for p in problems)} crowded folder(s)",
          file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
