#!/bin/sh
# lights-bench.sh BUILD_DIR: thousands of point lights, against the tree
# before the light cut (3751939, or $LIGHTS_BASE_REV), side by side.
#
# A street of 100 blocks under N point lamps (N = 256, 4096, 16384; glTF
# KHR_lights_punctual, made here), baked at default quality on 2 threads with
# 1000 probes, alternating the two gi-bake binaries RUNS times. Prints the
# medians of load, injection, the probes' gather and the whole run, the
# ratio as `speed-up: N.Nx`, and how far the probes' direct light moved
# (mean and largest relative difference), and appends one JSON line per N
# to out/bench.jsonl. A benchmark prints figures and never fails the build:
# this script always exits 0.
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${1:-build}
case $BUILD in /*) ;; *) BUILD="$ROOT/$BUILD" ;; esac
NOW="$BUILD/bin/gi-bake"
BASE_REV=${LIGHTS_BASE_REV:-3751939}
RUNS=${BENCH_RUNS:-3}
OUT="$ROOT/out"
JSONL="$OUT/bench.jsonl"

say() { echo "lights-bench: $*" >&2; }
[ -x "$NOW" ] || { say "no gi-bake at $NOW (build first: make); nothing measured"; exit 0; }
command -v python3 > /dev/null 2>&1 || { say "python3 is needed to write the scenes and read --json"; exit 0; }
mkdir -p "$OUT" || exit 0
. "$ROOT/tests/bench/base-build.sh"
base_gi_bake "$BASE_REV" "base-$BASE_REV" || exit 0
OLD=$BASE_BIN
TMP=$(mktemp -d "${TMPDIR:-/tmp}/gi-lights.XXXXXX") || exit 0
trap 'rm -rf "$TMP"' EXIT INT TERM
REV=$(git -C "$ROOT" rev-parse --short HEAD 2> /dev/null || echo unknown)
git -C "$ROOT" diff --quiet HEAD -- 2> /dev/null || REV="$REV-dirty"
STAMP=$(date -u +%Y-%m-%dT%H:%M:%SZ)

# The street (ground 200 m square, 10 x 10 blocks 6 m wide and 12 m tall),
# N lamps 3-6 m up, and the probes; fixed seeds.
python3 - "$TMP" <<'PY' || { say "cannot write the scenes"; exit 0; }
import base64, json, random, struct, sys
d = sys.argv[1]
V, I = [], []
def quad(a, b, c, e):
    k = len(V); V.extend([a, b, c, e]); I.extend([k, k + 1, k + 2, k, k + 2, k + 3])
quad((-100, 0, -100), (-100, 0, 100), (100, 0, 100), (100, 0, -100))
for i in range(10):
    for j in range(10):
        x0, z0, h = -90 + 18 * i, -90 + 18 * j, 12
        x1, z1 = x0 + 6, z0 + 6
        quad((x0, h, z0), (x0, h, z1), (x1, h, z1), (x1, h, z0))
        quad((x0, 0, z0), (x0, h, z0), (x1, h, z0), (x1, 0, z0))
        quad((x1, 0, z1), (x1, h, z1), (x0, h, z1), (x0, 0, z1))
        quad((x0, 0, z1), (x0, h, z1), (x0, h, z0), (x0, 0, z0))
        quad((x1, 0, z0), (x1, h, z0), (x1, h, z1), (x1, 0, z1))
vb = b"".join(struct.pack("<3f", *v) for v in V)
ib = b"".join(struct.pack("<I", k) for k in I)
uri = "data:application/octet-stream;base64," + base64.b64encode(vb + ib).decode()
for n in (256, 4096, 16384):
    rnd = random.Random(1)
    lights, nodes = [], [{"mesh": 0}]
    for k in range(n):
        lights.append({"type": "point", "color": [1, 0.8, 0.6], "intensity": rnd.uniform(50, 200)})
        nodes.append({"translation": [rnd.uniform(-99, 99), rnd.uniform(3, 6), rnd.uniform(-99, 99)],
                      "extensions": {"KHR_lights_punctual": {"light": k}}})
    g = {"asset": {"version": "2.0"}, "extensionsUsed": ["KHR_lights_punctual"],
         "extensions": {"KHR_lights_punctual": {"lights": lights}}, "scene": 0,
         "scenes": [{"nodes": list(range(len(nodes)))}], "nodes": nodes,
         "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
         "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.6, 0.6, 1],
                                                 "metallicFactor": 0, "roughnessFactor": 1}}],
         "buffers": [{"byteLength": len(vb) + len(ib), "uri": uri}],
         "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(vb)},
                         {"buffer": 0, "byteOffset": len(vb), "byteLength": len(ib)}],
         "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(V), "type": "VEC3",
                        "min": [-100, 0, -100], "max": [100, 12, 100]},
                       {"bufferView": 1, "componentType": 5125, "count": len(I), "type": "SCALAR"}]}
    json.dump(g, open("%s/lamps%d.gltf" % (d, n), "w"))
    # This tree reads glTF intensities as candela (683 lm/W), the base as W/sr:
    # the same lamps in those units, so both builds bake the same W/sr.
    for l in lights:
        l["intensity"] *= 683
    json.dump(g, open("%s/lamps%d-cd.gltf" % (d, n), "w"))
rnd = random.Random(2)
with open(d + "/probes.txt", "w") as f:
    for _ in range(1000):
        f.write("%.4f %.4f %.4f\n" % (rnd.uniform(-95, 95), rnd.uniform(0.5, 3), rnd.uniform(-95, 95)))
PY

echo "point lamps, $BASE_REV against $REV, $RUNS alternating runs, 2 threads, 1000 probes, $STAMP"
printf '%-7s %-6s %9s %9s %9s %9s\n' lamps build load inject gather total
for n in 256 4096 16384; do
  i=0
  while [ $i -lt "$RUNS" ]; do
    for side in old now; do
      bin=$OLD scene="$TMP/lamps$n.gltf"
      [ $side = now ] && bin=$NOW scene="$TMP/lamps$n-cd.gltf"
      "$bin" "$scene" --at 0,2,0 --threads 2 --probes "$TMP/probes.txt" --json \
        > "$TMP/$n.$side.$i.json" 2> "$TMP/err" || say "$n lamps ($side): $(tail -n 1 "$TMP/err")"
    done
    i=$((i + 1))
  done
  python3 - "$TMP" "$n" "$RUNS" "$REV" "$BASE_REV" "$STAMP" "$JSONL" <<'PY' || say "$n lamps: could not read the figures"
import json, statistics, sys
d, n, runs, rev, base, stamp, jsonl = sys.argv[1:8]
def load(side):
    out = []
    for i in range(int(runs)):
        try:
            out.append(json.load(open("%s/%s.%s.%d.json" % (d, n, side, i))))
        except (OSError, ValueError):
            pass
    return out
old, now = load("old"), load("now")
if not old or not now:
    print("%-7s not measured" % n); sys.exit(0)
keys = ("load", "inject", "gather", "total")
med = lambda runs, k: statistics.median(r["timings_ms"][k] for r in runs)
rel = []
for a, b in zip(old[0]["probes"], now[0]["probes"]):
    u, v = sum(a["direct"]), sum(b["direct"])
    if u > 1e-6:
        rel.append(abs(v - u) / u)
for side, runs in (("before", old), ("now", now)):
    print("%-7s %-6s %9.1f %9.1f %9.1f %9.1f" % (n, side, *(med(runs, k) for k in keys)))
print("%-7s speed-up: %.1fx (whole run), direct light moved %.2f%% on average, %.2f%% at most" %
      (n, med(old, "total") / med(now, "total"), 100 * statistics.mean(rel), 100 * max(rel)))
with open(jsonl, "a") as f:
    f.write(json.dumps({"bench": "lights", "lamps": int(n), "rev": rev, "base": base, "stamp": stamp,
                        "runs": len(now), **{"before_%s_ms" % k: med(old, k) for k in keys},
                        **{"%s_ms" % k: med(now, k) for k in keys},
                        "speedup": med(old, "total") / med(now, "total"),
                        "direct_mean_rel": statistics.mean(rel), "direct_max_rel": max(rel)}) + "\n")
PY
done
exit 0
