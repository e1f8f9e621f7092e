"""A stand-in for gi-server that answers canned responses, so gi-client's HTTP
handling (errors, headers, temp+rename, job polling) is tested without the
real server. Usage: fake_gi_server.py PORT_FILE. Binds 127.0.0.1:0, writes
the port to PORT_FILE, serves until killed. Lighting answers echo the request
path and query as the body, POST probes echoes the JSON body: the test checks
what gi-client sent."""
import json
import sys
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

TIMING = "voxelize;dur=12.1, inject;dur=3, filter;dur=1, bounce;dur=9, gather;dur=2, encode;dur=1, total;dur=28.1"
polls = {}
cancelled = set()  # jobs a DELETE cancelled; "jslow" (6 points) runs until then


class H(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"

    def log_message(self, *a):
        pass

    def send(self, code, body, ctype="application/json", headers=()):
        if isinstance(body, (dict, list)):
            body = json.dumps(body)
        if isinstance(body, str):
            body = body.encode()
        self.send_response(code)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        for k, v in headers:
            self.send_header(k, v)
        self.end_headers()
        self.wfile.write(body)

    def error(self, code, name, msg, headers=()):
        self.send(code, {"code": code, "name": name, "message": msg}, headers=headers)

    def do_GET(self):
        p = self.path
        path = p.split("?")[0]
        gi = [("Server-Timing", TIMING), ("X-GI-Cache", "miss")]
        if path.startswith("/v1/scenes/secret") and self.headers.get("Authorization") != "Bearer tok3n":
            return self.error(401, "unauthorized", "a bearer token is required", [("WWW-Authenticate", "Bearer")])
        if path == "/v1/health":
            return self.send(200, {"status": "ok", "version": "0.1.0", "git": "fake", "uptime_s": 1.5, "scenes": 1})
        if path == "/v1/scenes":
            return self.send(200, {"scenes": [{"id": "city", "triangles": 12, "up": "y", "href": "/v1/scenes/city",
                                               "bounds": {"min": [-300, 0, -300], "max": [300, 80, 300]}}]})
        if path == "/v1/scenes/city":
            return self.send(200, {"id": "city", "up": "y", "triangles": 12, "default_viewpoint": [12.5, 1.7, -3]})
        if path == "/v1/scenes/grid":
            # A scene that publishes its cell grid (issue 14); q and query as if for levels=3&res=16.
            q = "0123456789abcdef&kind=probe&levels=3&res=16"
            return self.send(200, {"id": "grid", "grid": {
                "origin": [0.5, 0, -0.25], "voxel": 1.25, "cell_size": 2.5, "q": "0123456789abcdef",
                "query": "levels=3&res=16", "asked": p,
                "lighting": "/v1/scenes/grid/cells/{i},{j},{k}/lighting?q=" + q,
                "cascades": "/v1/scenes/grid/cells/{i},{j},{k}/cascades.vdb?q=0123456789abcdef&levels=3&res=16"}})
        if path.startswith("/v1/scenes/grid/cells/"):
            return self.send(200, p, "image/x-exr", gi)
        if path == "/metrics":
            return self.send(200, "gi_bakes_total 3\n", "text/plain; version=0.0.4")
        if path in ("/v1/scenes/city/lighting", "/v1/scenes/secret/lighting", "/v1/scenes/city/cascades.vdb"):
            return self.send(200, p, "image/x-exr", gi)
        if path == "/v1/scenes/nope/lighting":
            return self.error(404, "not_found", "no scene 'nope'")
        if path == "/v1/scenes/city/bad":
            return self.error(400, "bad_request", "at: expected three finite numbers x,y,z")
        if path == "/v1/scenes/busy/lighting":
            return self.error(503, "overloaded", "all workers busy", [("Retry-After", "3")])
        if path == "/v1/scenes/html/lighting":
            return self.send(502, "<html>Bad Gateway</html>\n", "text/html")
        if path == "/v1/scenes/trunc/lighting":
            # Promise 1000 bytes, send 10, hang up: a truncated download.
            self.send_response(200)
            self.send_header("Content-Type", "image/x-exr")
            self.send_header("Content-Length", "1000")
            self.end_headers()
            self.wfile.write(b"0123456789")
            self.wfile.flush()
            self.close_connection = True
            return
        if path.startswith("/v1/jobs/"):
            parts = path.split("/")
            job = parts[3]
            if len(parts) == 5 and parts[4] == "result":
                return self.send(200, "RESULT " + job, "image/x-exr", gi)
            n = polls[job] = polls.get(job, 0) + 1
            base = {"id": job, "probes": 40, "tiles": 4, "elapsed_s": n * 0.5}
            if job in cancelled:
                return self.send(200, dict(base, state="cancelled", progress=0.25, probes_done=10, tiles_done=1))
            if job == "jslow":
                return self.send(200, dict(base, state="running", progress=0.25, probes_done=10, tiles_done=1))
            if job == "jfail" and n >= 2:
                return self.send(200, dict(base, state="failed", progress=0.25, probes_done=10, tiles_done=1,
                                           error={"code": 500, "name": "internal", "message": "bake failed: out of memory"}))
            if n >= 5:
                return self.send(200, dict(base, state="done", progress=1.0, probes_done=40, tiles_done=4,
                                           result="/v1/jobs/%s/result" % job))
            st = "queued" if n == 1 else "running"
            return self.send(200, dict(base, state=st, progress=(n - 1) * 0.25, probes_done=(n - 1) * 10,
                                       tiles_done=n - 1))
        return self.error(404, "not_found", "no route " + path)

    def do_POST(self):
        path = self.path.split("?")[0]
        n = int(self.headers.get("Content-Length", "0"))
        body = self.rfile.read(n)
        if path == "/v1/scenes/city/probes":
            pts = json.loads(body)["points"]
            if len(pts) <= 2:
                return self.send(200, body, "image/x-exr", [("Server-Timing", TIMING), ("X-GI-Cache", "hit")])
            job = "jfail" if len(pts) == 3 else "jslow" if len(pts) == 6 else "j%d" % len(pts)
            polls.pop(job, None)
            cancelled.discard(job)
            return self.send(202, {"job": job, "href": "/v1/jobs/" + job, "state": "queued", "probes": len(pts)},
                             headers=[("Location", "/v1/jobs/" + job)])
        return self.error(404, "not_found", "no route " + path)


    def do_DELETE(self):
        parts = self.path.split("?")[0].split("/")
        if len(parts) == 4 and parts[1:3] == ["v1", "jobs"]:
            cancelled.add(parts[3])
            return self.send(202, {"id": parts[3], "state": "running", "probes": 40, "probes_done": 10,
                                   "progress": 0.25, "tiles": 4, "tiles_done": 1, "elapsed_s": 1.0})
        return self.error(404, "not_found", "no route " + self.path)


srv = ThreadingHTTPServer(("127.0.0.1", 0), H)
with open(sys.argv[1] + ".tmp", "w") as f:
    f.write(str(srv.server_address[1]))
import os
os.rename(sys.argv[1] + ".tmp", sys.argv[1])
srv.serve_forever()
