#!/usr/bin/env python3
"""README's row for tests/cli names every client_*.sh with the server it runs against.

Each script's server is read from the script: a real gi-server when it
starts one (gi-server), the stand-in when it runs fake_gi_server.py, else
none. In the row, the first of the markers "no server", "fake_gi_server.py"
and "real `gi-server`" after the script's name must be that one (the row
once said every client test used the stand-in). Usage: check-cli-doc.py REPO"""
import glob
import os
import sys

MARKERS = {"none": "no server", "stand-in": "fake_gi_server.py", "real": "real `gi-server`"}
SAY = {"none": "no server", "stand-in": "the stand-in fake_gi_server.py", "real": "a real gi-server"}


def server_of(path):
    text = open(path, encoding="utf-8").read()
    if "fake_gi_server.py" in text:
        return "stand-in"
    return "real" if "/gi-server" in text else "none"


def main():
    repo = sys.argv[1]
    rows = [l for l in open(os.path.join(repo, "README.md"), encoding="utf-8") if l.startswith("| `tests/cli/` |")]
    if len(rows) != 1:
        print("README.md: expected one table row for tests/cli/, found %d" % len(rows))
        return 1
    row, bad = rows[0], 0
    for path in sorted(glob.glob(os.path.join(repo, "tests", "cli", "client_*.sh"))):
        name, want = os.path.basename(path), server_of(path)
        at = row.find("`%s`" % name)
        if at < 0:
            print("README.md: the tests/cli row does not name %s (it runs against %s)" % (name, SAY[want]))
            bad += 1
            continue
        found = {k: row.find(m, at) for k, m in MARKERS.items() if row.find(m, at) >= 0}
        got = min(found, key=found.get) if found else None
        if got != want:
            print("README.md: the tests/cli row says %s for %s, which runs against %s"
                  % (SAY[got] if got else "no server kind", name, SAY[want]))
            bad += 1
        else:
            print("ok: %s: %s" % (name, MARKERS[want]))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
