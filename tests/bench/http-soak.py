#!/usr/bin/env python3
"""http-soak.py: mixed traffic against a running gi-server, RSS sampled every second.

    http-soak.py URL PID SCENE X,Y,Z [TOKEN]

For SOAK_SECONDS (default 600) SOAK_CLIENTS threads (default 6) each pick,
per request: a cache hit (lighting at the fixed viewpoint), a miss (lighting
at a random point within +-SOAK_SPREAD on x and z), a VDB (cascades.vdb at
the fixed viewpoint or a random one), or a probe job (POST of more points
than an answer holds, then its status, and half of them cancelled with
DELETE /v1/jobs/{id}). A sampler reads VmRSS of PID every second.

Prints the requests by kind and status, every status the contract does not
expect (GETs: 200, 503, 504; job POST: 202, 503; DELETE: 200, 202, 409),
and max RSS against the server's memory budget (gi_cache_budget_bytes from
/metrics). Like every benchmark here it never fails: exit 0.
"""
import json
import os
import random
import sys
import threading
import time
import urllib.error
import urllib.request

SAMPLE_S = 1.0
# Job points: a row of points 5 m apart, each its own quality=low tile.
JOB_POINTS = 1100
JOB_SPACING = 5.0
# What each kind may answer without it counting as unexpected.
EXPECTED = {
    "hit": {200, 503, 504},
    "miss": {200, 503, 504},
    "vdb": {200, 503, 504},
    "job_post": {202, 503},
    "job_get": {200},
    "job_delete": {200, 202, 409},
}
# Share of each kind in the mix (weights).
MIX = [("hit", 5), ("miss", 2), ("vdb", 2), ("job", 1)]


def request(url, token, method="GET", body=None, timeout=300):
    req = urllib.request.Request(url, data=body, method=method)
    if token:
        req.add_header("Authorization", "Bearer " + token)
    if body is not None:
        req.add_header("Content-Type", "application/json")
    try:
        with urllib.request.urlopen(req, timeout=timeout) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()
    except Exception as e:  # connection reset, timeout: counted as status 0
        return 0, str(e).encode()


def rss_mib(pid):
    try:
        with open("/proc/%s/status" % pid) as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


def metric(base, token, name):
    st, body = request(base + "/metrics", token, timeout=30)
    if st != 200:
        return None
    for line in body.decode("utf-8", "replace").splitlines():
        if line.startswith(name + " "):
            return float(line.split()[1])
    return None


class Soak:
    def __init__(self, base, pid, scene, at, token):
        self.base, self.pid, self.scene, self.at, self.token = base, pid, scene, at, token
        self.spread = float(os.environ.get("SOAK_SPREAD", "50"))
        self.lock = threading.Lock()
        self.counts = {}
        self.unexpected = {}
        self.stop = threading.Event()
        self.rss = []

    def count(self, kind, status, body=b""):
        with self.lock:
            key = (kind, status)
            self.counts[key] = self.counts.get(key, 0) + 1
            if status not in EXPECTED[kind] and key not in self.unexpected:
                self.unexpected[key] = body[:200].decode("utf-8", "replace")

    def point(self, rng, vary):
        x, y, z = self.at
        if vary:
            x += rng.uniform(-self.spread, self.spread)
            z += rng.uniform(-self.spread, self.spread)
        return "%r,%r,%r" % (x, y, z)

    def job(self, rng):
        x, y, z = self.at
        x0 = x + rng.uniform(-self.spread, self.spread)
        pts = [[x0 + JOB_SPACING * i, y, z] for i in range(JOB_POINTS)]
        body = json.dumps({"quality": "low", "points": pts}).encode()
        st, resp = request(self.base + "/v1/scenes/%s/probes" % self.scene, self.token, "POST", body)
        self.count("job_post", st, resp)
        if st != 202:
            return
        jid = json.loads(resp).get("job", "")
        time.sleep(rng.uniform(0.2, 2.0))
        st, resp = request(self.base + "/v1/jobs/" + jid, self.token)
        self.count("job_get", st, resp)
        # Half the jobs are cancelled; the others run to their end (or retention).
        if rng.random() < 0.5:
            st, resp = request(self.base + "/v1/jobs/" + jid, self.token, "DELETE")
            self.count("job_delete", st, resp)

    def client(self, seed):
        rng = random.Random(seed)
        kinds = [k for k, w in MIX for _ in range(w)]
        lpath = self.base + "/v1/scenes/%s/lighting?redirect=0&at=" % self.scene
        vpath = self.base + "/v1/scenes/%s/cascades.vdb?redirect=0&at=" % self.scene
        while not self.stop.is_set():
            kind = rng.choice(kinds)
            if kind == "hit":
                st, body = request(lpath + self.point(rng, False), self.token)
            elif kind == "miss":
                st, body = request(lpath + self.point(rng, True), self.token)
            elif kind == "vdb":
                st, body = request(vpath + self.point(rng, rng.random() < 0.3), self.token)
                kind = "vdb"
            else:
                self.job(rng)
                continue
            self.count(kind, st, body if st != 200 else b"")

    def sampler(self):
        while not self.stop.is_set():
            r = rss_mib(self.pid)
            if r is not None:
                self.rss.append(r)
            self.stop.wait(SAMPLE_S)

    def run(self, seconds, clients):
        budget = metric(self.base, self.token, "gi_cache_budget_bytes")
        threads = [threading.Thread(target=self.sampler)]
        threads += [threading.Thread(target=self.client, args=(i,)) for i in range(clients)]
        t0 = time.monotonic()
        for t in threads:
            t.start()
        try:
            while time.monotonic() - t0 < seconds:
                time.sleep(0.5)
        finally:
            self.stop.set()
            for t in threads:
                t.join()
        self.report(seconds, clients, budget, time.monotonic() - t0)

    def report(self, seconds, clients, budget, took):
        print("== soak: %d s of mixed traffic, %d clients (took %.0f s with the last answers)" % (seconds, clients, took))
        kinds = sorted({k for k, _ in self.counts})
        for kind in kinds:
            by = sorted((st, n) for (k, st), n in self.counts.items() if k == kind)
            print("%-10s %s" % (kind, "  ".join("%s x %d" % (st or "no answer", n) for st, n in by)))
        if self.unexpected:
            print("unexpected statuses:")
            for (kind, st), body in sorted(self.unexpected.items()):
                print("  %s %s: %s" % (kind, st or "no answer", body))
        else:
            print("unexpected statuses: none")
        bud = "%.0f MiB" % (budget / 2**20) if budget else "unknown"
        if self.rss:
            print("RSS: %.0f MiB at start, max %.0f MiB, last %.0f MiB, %d samples; memory budget (cache_mb) %s"
                  % (self.rss[0], max(self.rss), self.rss[-1], len(self.rss), bud))
            if budget:
                print("max RSS - budget: %+.0f MiB" % (max(self.rss) - budget / 2**20))
        else:
            print("RSS: not sampled (no /proc/%s/status); memory budget %s" % (self.pid, bud))
        for name in ("gi_inflight_bytes", "gi_cache_bytes", "gi_encode_hits_total", "gi_encode_misses_total",
                     "gi_cache_evictions_total", "gi_rejected_total"):
            v = metric(self.base, self.token, name)
            print("%-26s %s" % (name, "%.0f" % v if v is not None else "-"))


def main():
    if len(sys.argv) < 5:
        print("usage: http-soak.py URL PID SCENE X,Y,Z [TOKEN]", file=sys.stderr)
        return 0
    base, pid, scene, at = sys.argv[1].rstrip("/"), sys.argv[2], sys.argv[3], sys.argv[4]
    token = sys.argv[5] if len(sys.argv) > 5 else ""
    try:
        seconds = int(os.environ.get("SOAK_SECONDS", "600"))
        clients = int(os.environ.get("SOAK_CLIENTS", "6"))
        at = [float(v) for v in at.split(",")]
    except ValueError as e:
        print("http-soak: %s; nothing measured" % e, file=sys.stderr)
        return 0
    if seconds <= 0:
        print("http-soak: SOAK_SECONDS=%d: no soak" % seconds)
        return 0
    Soak(base, pid, scene, at, token).run(seconds, clients)
    return 0


if __name__ == "__main__":
    sys.exit(main())
