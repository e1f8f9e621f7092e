"""check_openapi.py: proto/openapi.yaml describes the HTTP contract exactly.

Loads the document (PyYAML, Debian's python3-yaml), resolves every $ref, and
checks it against the contract's table below: every path and method, every
operation's exact set of response codes, error bodies, the headers the
contract promises (WWW-Authenticate, Allow, Retry-After, Location,
Content-Disposition, Server-Timing, X-GI-Cache, X-GI-Effects), content types
and each operation's query parameters. Then breaks a copy on purpose and
expects the check to notice (a check that cannot fail proves nothing).
With proto/request.c as a second argument it also reads the C parser's
parameter table and checks the query parameters against it.
Usage: check_openapi.py openapi.yaml [request.c]. Exit 0 ok, 1 problems, 77 skip."""
import copy
import sys

try:
    import yaml
except ImportError:
    print("SKIP: python3-yaml is not installed (scripts/install-deps.sh installs it)")
    sys.exit(77)

ERR = {400: "bad_request", 401: "unauthorized", 404: "not_found", 405: "method_not_allowed",
       409: "not_ready", 413: "payload_too_large", 500: "internal", 501: "not_implemented",
       503: "overloaded", 504: "timeout"}
# The quality group both bake endpoints take (proto/request.c: P_QUALITY).
BAKE_Q = {"quality", "levels", "res", "voxel", "cones", "aperture", "step", "bounces", "samples", "probe_samples",
          "ao", "seed", "effects"}
# kind=lightmap's own parameters (P_LM), also taken by lightmap-uv.glb.
LIGHTMAP = {"region", "texel", "atlas"}
# path -> method -> (success codes, error codes, query parameters)
CONTRACT = {
    "/v1/health": {"get": ({200}, {405, 500}, set())},
    "/v1/scenes": {"get": ({200}, {401, 405, 500}, set())},
    "/v1/scenes/{id}": {"get": ({200}, {400, 401, 404, 405, 500}, BAKE_Q)},
    "/v1/scenes/{id}/lighting": {"get": ({200, 304, 307}, {400, 401, 404, 405, 413, 500, 503, 504},
                                         {"at", "kind", "half", "width", "height", "redirect"} | BAKE_Q | LIGHTMAP)},
    "/v1/scenes/{id}/lightmap-uv.glb": {"get": ({200}, {400, 401, 404, 405, 413, 500, 503, 504},
                                                {"at"} | BAKE_Q | LIGHTMAP)},
    "/v1/scenes/{id}/cascades.vdb": {"get": ({200, 304, 307}, {400, 401, 404, 405, 500, 503, 504},
                                             {"at", "faces", "redirect"} | BAKE_Q)},
    # Cell-addressed answers (issue 14): immutable, ETag, 304; 307 for a stale q; kind=lightmap 501 there.
    "/v1/scenes/{id}/cells/{cell}/lighting": {"get": ({200, 304, 307}, {400, 401, 404, 405, 500, 501, 503, 504},
                                                      {"q", "kind", "half", "width", "height"} | BAKE_Q)},
    "/v1/scenes/{id}/cells/{cell}/cascades.vdb": {"get": ({200, 304, 307}, {400, 401, 404, 405, 500, 503, 504},
                                                          {"q", "faces"} | BAKE_Q)},
    "/v1/scenes/{id}/probes": {"post": ({200, 202}, {400, 401, 404, 405, 413, 500, 503, 504}, set())},
    "/v1/jobs/{id}": {"get": ({200}, {401, 404, 405, 500}, set()),
                      "delete": ({200, 202}, {401, 404, 405, 409, 500}, set())},
    "/v1/jobs/{id}/result": {"get": ({200}, {401, 404, 405, 409, 500}, set())},
    "/metrics": {"get": ({200}, {401, 405, 500}, set())},
    # Sessions (issue 12): a moving viewer's own cascade.
    "/v1/scenes/{id}/sessions": {"post": ({201}, {400, 401, 404, 405, 413, 500, 503, 504}, {"at"} | BAKE_Q)},
    "/v1/sessions/{sid}": {"get": ({200}, {401, 404, 405, 500}, set()),
                           "delete": ({204}, {401, 404, 405, 500}, set())},
    "/v1/sessions/{sid}/lighting": {"get": ({200}, {400, 401, 404, 405, 500, 503, 504},
                                            {"at", "kind", "half", "width", "height"})},
}
# A session's start 'at' is optional; everywhere else 'at' is required.
AT_OPTIONAL = {"/v1/scenes/{id}/sessions"}
CELL_PATHS = {"/v1/scenes/{id}/cells/{cell}/lighting", "/v1/scenes/{id}/cells/{cell}/cascades.vdb"}
CONTENT_200 = {"/v1/scenes/{id}/lighting": "image/x-exr", "/v1/sessions/{sid}/lighting": "image/x-exr", "/v1/scenes/{id}/lightmap-uv.glb": "model/gltf-binary",
               "/v1/scenes/{id}/cascades.vdb": "application/octet-stream",
               "/v1/scenes/{id}/cells/{cell}/lighting": "image/x-exr",
               "/v1/scenes/{id}/cells/{cell}/cascades.vdb": "application/octet-stream",
               "/v1/scenes/{id}/probes": "image/x-exr", "/v1/jobs/{id}/result": "image/x-exr",
               "/metrics": "text/plain; version=0.0.4"}
ERR_HEADERS = {401: "WWW-Authenticate", 405: "Allow", 503: "Retry-After", 504: "Retry-After"}
BAKE_HEADERS = {"Server-Timing", "X-GI-Cache", "X-GI-Effects"}


def resolve(doc, node, problems, where):
    """Follows a $ref (internal only) and returns the target."""
    seen = 0
    while isinstance(node, dict) and "$ref" in node:
        ref = node["$ref"]
        if not ref.startswith("#/"):
            problems.append("%s: external $ref %s" % (where, ref))
            return {}
        cur = doc
        for part in ref[2:].split("/"):
            if not isinstance(cur, dict) or part not in cur:
                problems.append("%s: $ref %s does not resolve" % (where, ref))
                return {}
            cur = cur[part]
        node = cur
        seen += 1
        if seen > 20:
            problems.append("%s: $ref loop at %s" % (where, ref))
            return {}
    return node


def all_refs(doc, node, problems, where="#"):
    if isinstance(node, dict):
        if "$ref" in node:
            resolve(doc, node, problems, where)
        for k, v in node.items():
            all_refs(doc, v, problems, where + "/" + str(k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            all_refs(doc, v, problems, "%s[%d]" % (where, i))


def check(doc):
    p = []
    if doc.get("openapi") != "3.0.3":
        p.append("openapi is %r, expected '3.0.3'" % doc.get("openapi"))
    all_refs(doc, doc, p)
    err_schema = resolve(doc, {"$ref": "#/components/schemas/Error"}, p, "Error")
    names = set((err_schema.get("properties", {}).get("name", {}) or {}).get("enum", []))
    if names != set(ERR.values()):
        p.append("Error.name enum %s != %s" % (sorted(names), sorted(ERR.values())))
    paths = doc.get("paths", {})
    if set(paths) != set(CONTRACT):
        p.append("paths: extra %s, missing %s" % (sorted(set(paths) - set(CONTRACT)), sorted(set(CONTRACT) - set(paths))))
    for path, methods in CONTRACT.items():
        item = paths.get(path, {})
        ops = {m for m in item if m in ("get", "put", "post", "delete", "patch", "head", "options")}
        if ops != set(methods):
            p.append("%s: methods %s, expected %s" % (path, sorted(ops), sorted(methods)))
        for m, (ok, errs, query) in methods.items():
            op = item.get(m)
            if not op:
                continue
            w = "%s %s" % (m.upper(), path)
            codes = {int(c) for c in op.get("responses", {})}
            if codes != ok | errs:
                p.append("%s: responses %s, expected %s" % (w, sorted(codes), sorted(ok | errs)))
            for c, r in op.get("responses", {}).items():
                c = int(c)
                r = resolve(doc, r, p, "%s %d" % (w, c))
                hdrs = set(r.get("headers", {}) or {})
                if c >= 400:
                    js = (r.get("content", {}) or {}).get("application/json", {})
                    if js.get("schema") != {"$ref": "#/components/schemas/Error"}:
                        p.append("%s %d: body is not the Error schema" % (w, c))
                    ex = js.get("example")
                    if ex and (ex.get("code") != c or ex.get("name") != ERR.get(c)):
                        p.append("%s %d: example %s does not match %s" % (w, c, ex, ERR.get(c)))
                    if c in ERR_HEADERS and ERR_HEADERS[c] not in hdrs:
                        p.append("%s %d: no %s header" % (w, c, ERR_HEADERS[c]))
                elif c == 200:
                    want = CONTENT_200.get(path, "application/json")
                    if set(r.get("content", {})) != {want}:
                        p.append("%s 200: content %s, expected %s" % (w, sorted(r.get("content", {})), want))
                    if (path in ("/v1/scenes/{id}/lighting", "/v1/scenes/{id}/cascades.vdb", "/v1/scenes/{id}/probes")
                            or path in CELL_PATHS) and not BAKE_HEADERS <= hdrs:
                        p.append("%s 200: headers %s lack %s" % (w, sorted(hdrs), sorted(BAKE_HEADERS - hdrs)))
                    if path.endswith("cascades.vdb") and "Content-Disposition" not in hdrs:
                        p.append("%s 200: no Content-Disposition" % w)
                    if path == "/v1/sessions/{sid}/lighting" and not (BAKE_HEADERS | {"X-GI-Move"}) <= hdrs:
                        p.append("%s 200: headers %s lack Server-Timing, X-GI-Cache, X-GI-Effects or X-GI-Move"
                                 % (w, sorted(hdrs)))
                    if (path in CELL_PATHS or (path.startswith("/v1/scenes/") and path.endswith(
                            ("/lighting", "/cascades.vdb")))) and not {"ETag", "Cache-Control"} <= hdrs:
                        p.append("%s 200: no ETag or Cache-Control" % w)
                elif c == 201 and not {"Location", "Server-Timing"} <= hdrs:
                    p.append("%s 201: no Location or Server-Timing header" % w)
                elif c == 307 and "Location" not in hdrs:
                    p.append("%s 307: no Location header" % w)
                elif c == 304 and "ETag" not in hdrs:
                    p.append("%s 304: no ETag header" % w)
                elif c == 202 and m == "post" and "Location" not in hdrs:
                    p.append("%s 202: no Location header" % w)
            params = [resolve(doc, x, p, w) for x in op.get("parameters", [])]
            q = {x.get("name") for x in params if x.get("in") == "query"}
            if q != query:
                p.append("%s: query parameters %s, expected %s" % (w, sorted(q), sorted(query)))
            for x in params:
                s = x.get("schema", {})
                if s.get("type") not in ("string", "integer", "number", "boolean"):
                    p.append("%s: parameter %s has no scalar type" % (w, x.get("name")))
                if x.get("in") == "path" and not x.get("required"):
                    p.append("%s: path parameter %s not required" % (w, x.get("name")))
                if x.get("name") == "at" and not x.get("required") and path not in AT_OPTIONAL:
                    p.append("%s: 'at' must be required" % w)
            if path == "/v1/health" and op.get("security") != []:
                p.append("GET /v1/health must need no token (security: [])")
    req = paths.get("/v1/scenes/{id}/probes", {}).get("post", {}).get("requestBody", {})
    body = resolve(doc, req.get("content", {}).get("application/json", {}).get("schema", {}), p, "probes body")
    if set(body.get("properties", {})) != {"points", "at", "quality", "half", "ao"} or body.get("required") != ["points"]:
        p.append("probes body: properties %s, required %s" % (sorted(body.get("properties", {})), body.get("required")))
    return p


def query_sets_from_c(path):
    """The query keys the C parser accepts per endpoint, read from
    proto/request.c's params[] table and the groups each gi_proto_parse_*
    passes to parse_query: the YAML must not drift from the code."""
    import re
    src = open(path).read()
    table = re.findall(r'\{"(\w+)",\s*(P_\w+)\}', src)
    out = {}
    for fn, path_key in (("lighting", "/v1/scenes/{id}/lighting"), ("cascades", "/v1/scenes/{id}/cascades.vdb"),
                         ("lightmap_uv", "/v1/scenes/{id}/lightmap-uv.glb"),
                         ("cell_lighting", "/v1/scenes/{id}/cells/{cell}/lighting"),
                         ("cell_cascades", "/v1/scenes/{id}/cells/{cell}/cascades.vdb"), ("scene", "/v1/scenes/{id}"),
                         ("session", "/v1/scenes/{id}/sessions"),
                         ("session_lighting", "/v1/sessions/{sid}/lighting")):
        m = re.search(r"gi_proto_parse_%s\([^)]*\)\s*\{.*?parse_query\([^,]+,[^,]+,\s*([A-Z_| ]+)," % fn, src, re.S)
        if not m or not table:
            return None
        groups = {g.strip() for g in m.group(1).split("|")}
        out[path_key] = {k for k, g in table if g in groups}
    return out


def main():
    with open(sys.argv[1]) as f:
        doc = yaml.safe_load(f)
    if len(sys.argv) > 2:
        from_c = query_sets_from_c(sys.argv[2])
        if from_c is None:
            print("FAIL: cannot read the parameter table of %s" % sys.argv[2])
            sys.exit(1)
        for path, keys in from_c.items():
            ok, errs, q = next(iter(CONTRACT[path].values()))
            if q != keys:
                print("FAIL: %s: the contract table says %s, %s accepts %s" % (path, sorted(q), sys.argv[2], sorted(keys)))
                sys.exit(1)
        print("ok: query parameters agree with %s" % sys.argv[2])
    problems = check(doc)
    for x in problems:
        print("FAIL: " + x)
    # The check must notice a dropped error, a dropped header and a dropped parameter.
    for what, breaker in [
        ("lighting 503", lambda d: d["paths"]["/v1/scenes/{id}/lighting"]["get"]["responses"].pop("503")),
        ("Retry-After", lambda d: d["components"]["responses"]["Overloaded"].pop("headers")),
        ("504 Retry-After", lambda d: d["components"]["responses"]["Timeout"].pop("headers")),
        ("probe_samples", lambda d: d["paths"]["/v1/scenes/{id}/lighting"]["get"]["parameters"].remove(
            {"$ref": "#/components/parameters/ProbeSamples"})),
        ("jobs path", lambda d: d["paths"].pop("/v1/jobs/{id}")),
        ("cell ETag", lambda d: d["paths"]["/v1/scenes/{id}/cells/{cell}/lighting"]["get"]["responses"]["200"][
            "headers"].pop("ETag")),
        ("cell 304", lambda d: d["paths"]["/v1/scenes/{id}/cells/{cell}/cascades.vdb"]["get"]["responses"].pop("304")),
        ("job cancel", lambda d: d["paths"]["/v1/jobs/{id}"].pop("delete")),
        ("session delete", lambda d: d["paths"]["/v1/sessions/{sid}"].pop("delete")),
        ("X-GI-Move", lambda d: d["paths"]["/v1/sessions/{sid}/lighting"]["get"]["responses"]["200"][
            "headers"].pop("X-GI-Move")),
    ]:
        broken = copy.deepcopy(doc)
        breaker(broken)
        if not check(broken):
            problems.append("self-test: removing %s went unnoticed" % what)
            print("FAIL: self-test: removing %s went unnoticed" % what)
    if problems:
        sys.exit(1)
    ops = sum(len(m) for m in CONTRACT.values())
    print("ok: %d paths, %d operations, every error response and header of the contract" % (len(CONTRACT), ops))


main()
