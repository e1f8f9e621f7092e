"""check_manifests.py: configs/k8s/ validated offline (issue 14).

Kubernetes cannot run here, so this parses every manifest (PyYAML) and
checks the fields docs/ and configs/k8s/ name, and how the objects refer
to each other:
- every object: apiVersion/kind pairs Kubernetes knows, a DNS-1123 name;
  every container: an image, requests <= limits;
- the server Deployment: selector = pod labels, readinessProbe GET
  /v1/health on the container's port, GI_SERVER_TOKEN from a Secret key
  that token-secret.example.yaml defines, terminationGracePeriodSeconds
  above the server's shutdown_grace_s (10 s); the Service selects those
  pods and targets that port;
- the bake Job: completionMode Indexed, SHARDS = completions, parallelism
  <= completions, gi-bake ... --shard $JOB_COMPLETION_INDEX/$SHARDS
  --resume DIR with DIR on the PersistentVolumeClaim bake-pvc.yaml defines
  (ReadWriteMany); the merge Job runs gi-bake merge on the same claim,
  over the files the shards write, and is not indexed.
Then breaks copies on purpose and expects each break to be noticed.
Usage: check_manifests.py DIR. Exit 0 ok, 1 problems, 77 skip (no PyYAML)."""
import copy
import glob
import os
import re
import sys

try:
    import yaml
except ImportError:
    print("SKIP: python3-yaml is not installed (scripts/install-deps.sh installs it)")
    sys.exit(77)

KINDS = {("apps/v1", "Deployment"), ("v1", "Service"), ("v1", "Secret"), ("v1", "PersistentVolumeClaim"),
         ("batch/v1", "Job")}
DNS1123 = re.compile(r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$")
SHUTDOWN_GRACE_S = 10  # configs/docker.ini [server] shutdown_grace_s
UNITS = {"": 1, "m": 1e-3, "Ki": 2 ** 10, "Mi": 2 ** 20, "Gi": 2 ** 30, "Ti": 2 ** 40, "k": 1e3, "M": 1e6, "G": 1e9}


def quantity(q):
    m = re.fullmatch(r"([0-9.]+)([A-Za-z]*)", str(q))
    if not m or m.group(2) not in UNITS:
        raise ValueError("bad quantity %r" % q)
    return float(m.group(1)) * UNITS[m.group(2)]


def pod_spec(obj):
    return obj.get("spec", {}).get("template", {}).get("spec", {}) or {}


def containers(obj):
    s = pod_spec(obj)
    return (s.get("initContainers") or []) + (s.get("containers") or [])


def command_text(c):
    return " ".join(str(x) for x in (c.get("command") or []) + (c.get("args") or []))


def env(c):
    return {e["name"]: e for e in c.get("env") or []}


def check_common(docs, p):
    for o in docs:
        name = o.get("metadata", {}).get("name", "")
        w = "%s %s" % (o.get("kind"), name)
        if (o.get("apiVersion"), o.get("kind")) not in KINDS:
            p.append("%s: unknown apiVersion/kind %s/%s" % (w, o.get("apiVersion"), o.get("kind")))
        if not DNS1123.match(name) or len(name) > 63:
            p.append("%s: name is not a DNS-1123 label" % w)
        for c in containers(o):
            if not c.get("image"):
                p.append("%s: container %s has no image" % (w, c.get("name")))
            res = c.get("resources") or {}
            for k, v in (res.get("requests") or {}).items():
                lim = (res.get("limits") or {}).get(k)
                try:
                    if lim is not None and quantity(v) > quantity(lim):
                        p.append("%s: %s request %s above limit %s" % (w, k, v, lim))
                except ValueError as e:
                    p.append("%s: %s" % (w, e))


def one(docs, kind, pred, p, what):
    found = [o for o in docs if o.get("kind") == kind and pred(o)]
    if len(found) != 1:
        p.append("expected one %s (%s), found %d" % (kind, what, len(found)))
        return None
    return found[0]


def check_server(docs, p):
    dep = one(docs, "Deployment", lambda o: True, p, "the server")
    svc = one(docs, "Service", lambda o: True, p, "the server")
    secret = one(docs, "Secret", lambda o: True, p, "the token example")
    if not dep:
        return
    labels = dep["spec"]["template"]["metadata"].get("labels") or {}
    sel = (dep["spec"].get("selector") or {}).get("matchLabels") or {}
    if not sel or any(labels.get(k) != v for k, v in sel.items()):
        p.append("Deployment: selector %s does not match pod labels %s" % (sel, labels))
    grace = pod_spec(dep).get("terminationGracePeriodSeconds", 30)
    if grace <= SHUTDOWN_GRACE_S:
        p.append("Deployment: terminationGracePeriodSeconds %s not above shutdown_grace_s %d" % (grace, SHUTDOWN_GRACE_S))
    cs = pod_spec(dep).get("containers") or []
    srv = [c for c in cs if "gi-server" in command_text(c) or c.get("name") == "gi-server"]
    if len(srv) != 1:
        p.append("Deployment: expected one gi-server container")
        return
    c = srv[0]
    ports = {pt.get("name"): pt.get("containerPort") for pt in c.get("ports") or []}
    rp = ((c.get("readinessProbe") or {}).get("httpGet") or {})
    if rp.get("path") != "/v1/health":
        p.append("Deployment: readinessProbe is not GET /v1/health (%s)" % rp.get("path"))
    if rp.get("port") not in ports and rp.get("port") not in ports.values():
        p.append("Deployment: readinessProbe port %s is not a container port %s" % (rp.get("port"), ports))
    tok = env(c).get("GI_SERVER_TOKEN", {}).get("valueFrom", {}).get("secretKeyRef") or {}
    if not tok:
        p.append("Deployment: GI_SERVER_TOKEN does not come from a Secret")
    elif secret and (tok.get("name") != secret["metadata"]["name"] or
                     tok.get("key") not in (secret.get("stringData") or secret.get("data") or {})):
        p.append("Deployment: token Secret %s/%s is not the one token-secret.example.yaml defines" %
                 (tok.get("name"), tok.get("key")))
    if svc:
        # Jobs and sessions live on one replica: spread at random, their polls and moves read 404.
        if svc["spec"].get("sessionAffinity") != "ClientIP":
            p.append("Service: sessionAffinity must be ClientIP (jobs and sessions live on one replica)")
        ssel = svc["spec"].get("selector") or {}
        if not ssel or any(labels.get(k) != v for k, v in ssel.items()):
            p.append("Service: selector %s does not select the server pods %s" % (ssel, labels))
        for sp in svc["spec"].get("ports") or []:
            t = sp.get("targetPort", sp.get("port"))
            if t not in ports and t not in ports.values():
                p.append("Service: targetPort %s is not a container port %s" % (t, ports))


def claim_mounts(obj):
    """Mount path -> claim name, for volumes from PersistentVolumeClaims."""
    vols = {v["name"]: (v.get("persistentVolumeClaim") or {}).get("claimName") for v in pod_spec(obj).get("volumes") or []}
    out = {}
    for c in containers(obj):
        for m in c.get("volumeMounts") or []:
            if vols.get(m["name"]):
                out[m["mountPath"]] = vols[m["name"]]
    return out


def check_bake(docs, p):
    pvc = one(docs, "PersistentVolumeClaim", lambda o: True, p, "the bake folder")
    # The main containers: the merge's init container runs a --shard owning no tile (for the bake hash).
    shard = one(docs, "Job", lambda o: "--shard" in " ".join(command_text(c) for c in pod_spec(o).get("containers") or []),
                p, "the shards")
    merge = one(docs, "Job", lambda o: "gi-bake merge" in " ".join(command_text(c) for c in containers(o)), p, "merge")
    claim = pvc["metadata"]["name"] if pvc else None
    if pvc and "ReadWriteMany" not in (pvc["spec"].get("accessModes") or []):
        p.append("PersistentVolumeClaim: shards on several nodes need ReadWriteMany")
    if pvc and not ((pvc["spec"].get("resources") or {}).get("requests") or {}).get("storage"):
        p.append("PersistentVolumeClaim: no storage request")
    if shard:
        s = shard["spec"]
        if s.get("completionMode") != "Indexed":
            p.append("bake Job: completionMode is %s, not Indexed" % s.get("completionMode"))
        n = s.get("completions")
        if not isinstance(n, int) or n < 1:
            p.append("bake Job: completions %r" % n)
        if s.get("parallelism", 1) > (n or 0):
            p.append("bake Job: parallelism above completions")
        if pod_spec(shard).get("restartPolicy") not in ("OnFailure", "Never"):
            p.append("bake Job: restartPolicy must be OnFailure or Never")
        c = [c for c in containers(shard) if "--shard" in command_text(c)][0]
        cmd = command_text(c)
        if str(env(c).get("SHARDS", {}).get("value")) != str(n):
            p.append("bake Job: SHARDS=%s but completions=%s" % (env(c).get("SHARDS", {}).get("value"), n))
        if not re.search(r'gi-bake\b.*--shard "?\$\{?JOB_COMPLETION_INDEX\}?/\$\{?SHARDS\}?"?', cmd):
            p.append("bake Job: not gi-bake ... --shard $JOB_COMPLETION_INDEX/$SHARDS: %s" % cmd)
        m = re.search(r"--resume\s+\"?([^\s\"]+)", cmd)
        mounts = claim_mounts(shard)
        if not m:
            p.append("bake Job: no --resume DIR")
        elif not any(m.group(1).startswith(mp) and cl == claim for mp, cl in mounts.items()):
            p.append("bake Job: --resume %s is not on the claim %s (mounts %s)" % (m.group(1), claim, mounts))
        outs = re.findall(r"--exr\s+\"?([^\s\"]+)", cmd)
        if not outs or not any(outs[0].startswith(mp) for mp in mounts):
            p.append("bake Job: --exr is not on the claim")
    if merge:
        if merge["spec"].get("completionMode") == "Indexed":
            p.append("merge Job: must not be indexed")
        mounts = claim_mounts(merge)
        if claim not in mounts.values():
            p.append("merge Job: does not mount the claim %s" % claim)
        if shard:
            cmd = " ".join(command_text(c) for c in containers(merge))
            shard_cmd = command_text([c for c in containers(shard) if "--shard" in command_text(c)][0])
            exr = re.findall(r"--exr\s+\"?([^\s\"]+)", shard_cmd)
            # The shards by number, 0 .. SHARDS-1: a glob also took a previous run's higher-numbered ones.
            named = re.search(r'in="\$in (\S+)"', cmd)
            want = exr[0].replace("$JOB_COMPLETION_INDEX", "$i") if exr else None
            mcmd = " ".join(command_text(c) for c in containers(merge) if "gi-bake merge" in command_text(c))
            if "*" in mcmd or not named or named.group(1) != want or "$in" not in mcmd.split("gi-bake merge")[-1]:
                p.append("merge Job: its inputs %s are not the shards' outputs %s by number" %
                         (named.group(1) if named else None, want))
            menv = {k: v for c in containers(merge) for k, v in env(c).items()}
            if str(menv.get("SHARDS", {}).get("value")) != str(shard["spec"].get("completions")):
                p.append("merge Job: SHARDS=%s but the bake's completions=%s" %
                         (menv.get("SHARDS", {}).get("value"), shard["spec"].get("completions")))


def check(docs):
    p = []
    check_common(docs, p)
    check_server(docs, p)
    check_bake(docs, p)
    return p


def main():
    files = sorted(glob.glob(os.path.join(sys.argv[1], "*.yaml")))
    docs = []
    for f in files:
        with open(f) as fh:
            docs += [d for d in yaml.safe_load_all(fh) if d]
    problems = check(docs)
    for x in problems:
        print("FAIL: " + x)

    def job(d, what):
        return [o for o in d if o.get("kind") == "Job" and what in str(o)][0]

    def dep_container(d):
        return [o for o in d if o.get("kind") == "Deployment"][0]["spec"]["template"]["spec"]["containers"][0]

    breakers = [
        ("readinessProbe", lambda d: dep_container(d).pop("readinessProbe")),
        ("token Secret", lambda d: dep_container(d)["env"][0].pop("valueFrom")),
        ("Indexed", lambda d: job(d, "--shard")["spec"].pop("completionMode")),
        ("completions", lambda d: job(d, "--shard")["spec"].__setitem__("completions", 3)),
        ("shard index", lambda d: job(d, "--shard")["spec"]["template"]["spec"]["containers"][0]["args"].__setitem__(
            0, job(d, "--shard")["spec"]["template"]["spec"]["containers"][0]["args"][0].replace(
                "JOB_COMPLETION_INDEX/", "INDEX/"))),
        ("claim", lambda d: job(d, "merge")["spec"]["template"]["spec"]["volumes"][0].__setitem__(
            "persistentVolumeClaim", {"claimName": "other"})),
        ("service port", lambda d: [o for o in d if o.get("kind") == "Service"][0]["spec"]["ports"][0].__setitem__(
            "targetPort", 9999)),
        ("session affinity", lambda d: [o for o in d if o.get("kind") == "Service"][0]["spec"].pop("sessionAffinity")),
    ]
    for what, breaker in breakers:
        broken = copy.deepcopy(docs)
        breaker(broken)
        if not check(broken):
            problems.append("self-test: breaking %s went unnoticed" % what)
            print("FAIL: self-test: breaking %s went unnoticed" % what)
    if problems:
        sys.exit(1)
    print("ok: %d objects in %d files (%s); %d deliberate breaks noticed" %
          (len(docs), len(files), ", ".join(sorted("%s/%s" % (o["kind"], o["metadata"]["name"]) for o in docs)),
           len(breakers)))


main()
