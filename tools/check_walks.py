#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Checks the walk tables of docs/ARCHITECTURE.md (issue 47; the depth frame's, the eye pair's and
the view's stage by stage): every file a row names exists, and
every function, type or member it names in backticks is found, as a whole word, in a file named
in that row or in an earlier row of the same table (a row may say `process_tiles` after an
earlier one named `remote_node/src/pipeline.cpp`). A file named without its folder is the one
of that name in the folders named so far (or, if none, the only one in the tree). Exits 1 and
lists what is not where the table says.

Usage: tools/check_walks.py [ROOT]   (ROOT: the project, default the folder above tools/)
"""
import os
import re
import sys

SOURCE_DIRS = ["common", "proto", "remote_node", "local_node", "tools"]
EXTS = (".h", ".hpp", ".cpp", ".cc")
TICK = re.compile(r"`([^`]+)`")
IDENT = re.compile(r"^~?[A-Za-z_]\w*(::~?[A-Za-z_]\w*)*(\(\))?$")
FILE = re.compile(r"[\w./-]+\.(?:cpp|h|hpp|cc)")
# Backticked words that are not code names: flags, values and the like are skipped by IDENT;
# these pass it but are prose.
NOT_CODE = {"rig", "none", "hardware", "shift", "full", "repair", "on", "off"}


def split_cells(line):
    """A table row's cells; a | inside backticks (`a|b`) does not split."""
    cells, cur, quoted = [], "", False
    for ch in line.strip().strip("|"):
        if ch == "`":
            quoted = not quoted
        if ch == "|" and not quoted:
            cells.append(cur.strip())
            cur = ""
        else:
            cur += ch
    cells.append(cur.strip())
    return cells


def main():
    root = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else
                           os.path.join(os.path.dirname(__file__), ".."))
    os.chdir(root)
    by_name = {}
    for top in SOURCE_DIRS:
        for d, _, names in os.walk(top):
            for n in names:
                if n.endswith(EXTS):
                    by_name.setdefault(n, []).append(os.path.join(d, n))
    text = open("docs/ARCHITECTURE.md", encoding="utf-8").read().splitlines()
    problems, rows, cache = [], 0, {}

    def words_of(path):
        if path not in cache:
            with open(path, encoding="utf-8", errors="replace") as f:
                cache[path] = set(re.findall(r"~?[A-Za-z_]\w*", f.read()))
        return cache[path]

    in_walk, context, dirs = False, [], []
    for lineno, line in enumerate(text, 1):
        if line.startswith("## ") or line.startswith("### "):
            in_walk = line.startswith(
                ("## One depth frame", "## One eye pair", "### The view, stage by stage"))
        if not in_walk:
            continue
        if not line.startswith("|") or line.startswith("|---") or line.startswith("| #"):
            if not line.startswith("|"):
                context, dirs = [], []  # a new table
            continue
        rows += 1
        cells = split_cells(line)
        where = " ".join(cells[2:]) if len(cells) > 2 else line
        row_files, names = [], []
        for tok in TICK.findall(where):
            # "file.cpp: name" in one pair of backticks splits into the file and the name
            for part in re.split(r"[\s,;]+|->", tok):
                part = part.strip().rstrip(":")
                if FILE.fullmatch(part):
                    row_files.append(part)
                elif IDENT.match(part) and part not in NOT_CODE:
                    names.append(part.replace("()", ""))
        for tok in TICK.findall(where):
            d = tok.strip().rstrip("/")
            if "/" in d and os.path.isdir(d):
                for sub, _, names_in in os.walk(d):
                    context += [os.path.join(sub, n) for n in names_in if n.endswith(EXTS)]
        for f in row_files:
            if "/" in f:
                if not os.path.isfile(f):
                    problems.append(f"line {lineno}: no file {f}")
                    continue
                context.append(f)
                dirs.append(os.path.dirname(f))
            else:
                found = [p for p in by_name.get(f, []) if os.path.dirname(p) in dirs]
                found = found or (by_name.get(f, []) if len(by_name.get(f, [])) == 1 else [])
                if not found:
                    problems.append(f"line {lineno}: no file {f} in {sorted(set(dirs)) or 'the tree'}")
                context += found
        for n in names:
            last = n.split("::")[-1]
            if not any(last in words_of(p) for p in context):
                problems.append(f"line {lineno}: `{n}` is in none of the files named so far "
                                f"({', '.join(sorted(set(os.path.basename(p) for p in context))) or 'none'})")
    for p in problems:
        print(p)
    print(f"{rows} walk rows checked, {len(problems)} problem(s)", file=sys.stderr)
    return 1 if problems or rows == 0 else 0


if __name__ == "__main__":
    sys.exit(main())
