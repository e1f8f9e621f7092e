#!/usr/bin/env python3
"""The core's files form a pipeline, not a web: no two object files of the
core library call each other, directly or around a longer loop.

Reads the archive's symbol tables with nm: a file that leaves symbol S
undefined and a file that defines S make an edge. Prints the file graph
by stage and fails on any cycle (Tarjan's strongly connected components).
Usage: check-calls.py NM ARCHIVE"""
import subprocess
import sys


def symbols(nm, archive):
    out = subprocess.run([nm, "-A", archive], capture_output=True, text=True, check=True).stdout
    defined, used = {}, {}
    for line in out.splitlines():
        # archive:object.o: [address] TYPE symbol
        parts = line.split(":")
        if len(parts) < 3:
            continue
        obj = parts[1].strip()
        fields = parts[-1].split()
        if len(fields) < 2:
            continue
        kind, sym = fields[-2], fields[-1]
        if kind == "U":
            used.setdefault(obj, set()).add(sym)
        elif kind in "TDBRVWu" and not sym.startswith("."):
            defined.setdefault(sym, obj)
    return defined, used


def cycles(graph):
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def main():
    nm, archive = sys.argv[1], sys.argv[2]
    defined, used = symbols(nm, archive)
    graph = {}
    for obj, syms in used.items():
        for s in syms:
            d = defined.get(s)
            if d and d != obj:
                graph.setdefault(obj, set()).add(d)
    objs = sorted(set(defined.values()) | set(used))
    for o in objs:
        print(f"{o}: -> {', '.join(sorted(graph.get(o, ()))) or '(nothing in the core)'}")
    bad = cycles(graph)
    for comp in bad:
        print("FAIL: these files call each other:", " <-> ".join(comp))
    edges = sum(len(v) for v in graph.values())
    print(f"{len(objs)} files, {edges} call edges: {1 if not bad else 0} passed, {1 if bad else 0} failed")
    if len(objs) < 20:
        print("FAIL: expected the core's 20+ object files in", archive)
        return 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
