#!/usr/bin/env python3
"""No function in the project's own C code runs over MAX lines.

A function starts at a line that begins in column 0 with a declaration
ending in '{' (the house style: the brace on the signature's last line)
and ends at the next '}' in column 0. Usage: check-length.py MAX DIR..."""
import os
import re
import sys

START = re.compile(r"^[A-Za-z_][^;{}]*\)\s*\{\s*$")


def functions(path):
    lines = open(path, encoding="utf-8", errors="replace").read().split("\n")
    i = 0
    while i < len(lines):
        line = lines[i]
        j = i
        # A signature may span lines: join until '{' or ';'.
        if re.match(r"^[A-Za-z_]", line) and "(" in line and not line.startswith(("typedef", "struct", "enum", "union")):
            sig = line
            while not sig.rstrip().endswith(("{", ";", "}")) and j + 1 < len(lines) and j - i < 6:
                j += 1
                sig += " " + lines[j].strip()
            if START.match(sig):
                name = re.search(r"([A-Za-z_][A-Za-z0-9_]*)\s*\(", sig).group(1)
                k = j + 1
                while k < len(lines) and not lines[k].startswith("}"):
                    k += 1
                yield name, i + 1, k - i + 1
                i = k
        i += 1


def main():
    limit = int(sys.argv[1])
    long_ones, count = [], 0
    for root in sys.argv[2:]:
        for dirpath, _, files in os.walk(root):
            for f in sorted(files):
                if f.endswith((".c", ".cpp")):
                    p = os.path.join(dirpath, f)
                    for name, line, n in functions(p):
                        count += 1
                        if n > limit:
                            long_ones.append((n, p, line, name))
    for n, p, line, name in sorted(long_ones, reverse=True):
        print(f"FAIL: {p}:{line} {name} is {n} lines (limit {limit})")
    print(f"{count} functions: {count - len(long_ones)} passed, {len(long_ones)} failed")
    return 1 if long_ones or count < 100 else 0


if __name__ == "__main__":
    sys.exit(main())
