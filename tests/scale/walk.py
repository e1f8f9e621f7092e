"""walk.py: a client walking through a city, for tests/scale/nginx.sh.

Each step asks GET /v1/scenes/{scene}/lighting?at=... (a probe; every 7th a
small panorama, every 13th the cascades.vdb), expects the 307 to its cell
URL, follows it and records status, bytes (sha256), nginx's X-Cache-Status
and the latency of both requests together. Steps run on a few threads, so
some are in flight when --kill-pid is killed after --kill-after steps.
Writes one JSON object per step to --out. Standard library only."""
import argparse
import hashlib
import http.client
import json
import math
import os
import signal
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor

PANORAMA_EVERY, PANORAMA_AT = 7, 3
VDB_EVERY, VDB_AT = 13, 5
# The walk: a loop around a block of the test city (extent 300 m), at eye height.
LOOP_HALF_X, LOOP_HALF_Z, EYE_Y = 90.0, 60.0, 2.0


def viewpoint(i, n):
    """Point i of n along the loop's perimeter."""
    per = 4 * (LOOP_HALF_X + LOOP_HALF_Z)
    d = per * i / n
    sides = [(2 * LOOP_HALF_X, lambda t: (-LOOP_HALF_X + t, -LOOP_HALF_Z)),
             (2 * LOOP_HALF_Z, lambda t: (LOOP_HALF_X, -LOOP_HALF_Z + t)),
             (2 * LOOP_HALF_X, lambda t: (LOOP_HALF_X - t, LOOP_HALF_Z)),
             (2 * LOOP_HALF_Z, lambda t: (-LOOP_HALF_X, LOOP_HALF_Z - t))]
    for length, at in sides:
        if d <= length:
            x, z = at(d)
            return x, EYE_Y + 0.5 * math.sin(i), z
        d -= length
    return -LOOP_HALF_X, EYE_Y, -LOOP_HALF_Z


def url_of(i, n, scene, quality):
    x, y, z = viewpoint(i, n)
    at = "at=%.3f,%.3f,%.3f" % (x, y, z)
    if i % VDB_EVERY == VDB_AT:
        return "/v1/scenes/%s/cascades.vdb?%s&%s" % (scene, at, quality)
    if i % PANORAMA_EVERY == PANORAMA_AT:
        return "/v1/scenes/%s/lighting?%s&%s&kind=panorama&width=32&height=16" % (scene, at, quality)
    return "/v1/scenes/%s/lighting?%s&%s" % (scene, at, quality)


local = threading.local()


def conn(host, port):
    c = getattr(local, "c", None)
    if c is None:
        c = local.c = http.client.HTTPConnection(host, port, timeout=300)
    return c


def get(host, port, path, token):
    """One GET on this thread's keep-alive connection (one reconnect on a dropped one)."""
    for attempt in range(2):
        c = conn(host, port)
        try:
            c.request("GET", path, headers={"Authorization": "Bearer " + token})
            r = c.getresponse()
            return r.status, dict(r.getheaders()), r.read()
        except (http.client.HTTPException, OSError):
            c.close()
            local.c = None
            if attempt:
                raise


def step(args, i):
    t0 = time.monotonic()
    rec = {"i": i, "url": url_of(i, args.n, args.scene, args.quality)}
    try:
        st, h, _ = get(args.host, args.port, rec["url"], args.token)
        rec["redirect"] = st
        rec["location"] = h.get("Location", "")
        if st == 307:
            st, h, body = get(args.host, args.port, rec["location"], args.token)
            rec["sha"] = hashlib.sha256(body).hexdigest()
            rec["bytes"] = len(body)
            rec["etag"] = h.get("ETag", "")
            rec["cache_control"] = h.get("Cache-Control", "")
        rec["status"] = st
        rec["nginx_cache"] = h.get("X-Cache-Status", "")
    except Exception as e:  # a lost request: recorded, the test fails on it
        rec["status"] = 0
        rec["error"] = repr(e)
    rec["ms"] = (time.monotonic() - t0) * 1e3
    return rec


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--token", required=True)
    ap.add_argument("--scene", default="city")
    ap.add_argument("--quality", default="res=16&levels=3")
    ap.add_argument("--n", type=int, default=300)
    ap.add_argument("--threads", type=int, default=4)
    ap.add_argument("--kill-pid", type=int, default=0)
    ap.add_argument("--kill-after", type=int, default=0)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    done = [0]
    lock = threading.Lock()

    def run(i):
        rec = step(args, i)
        with lock:
            done[0] += 1
            if args.kill_pid and done[0] == args.kill_after:
                os.kill(args.kill_pid, signal.SIGKILL)
                rec["killed_after"] = True
        return rec

    with ThreadPoolExecutor(args.threads) as ex:
        recs = list(ex.map(run, range(args.n)))
    with open(args.out, "w") as f:
        for r in recs:
            f.write(json.dumps(r) + "\n")
    bad = [r for r in recs if r["status"] != 200]
    print("walk: %d steps, %d not 200" % (len(recs), len(bad)))
    for r in bad[:5]:
        print("  %s" % json.dumps(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
