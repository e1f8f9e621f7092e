#!/bin/sh
# run-bench.sh BUILD_DIR: per-stage milliseconds and cascade bytes of gi-bake
# on the Cornell box, Munich and the procedural city at three sizes, each
# with 1 and 2 threads. Prints a table and appends one JSON line per run to
# out/bench.jsonl (with the git revision and thread count).
#
# A benchmark prints figures; it never decides pass or fail: this script
# always exits 0. Shared scenes (../shared/scenes, or $GI_SCENES_DIR) are
# skipped loudly when absent. Numbers are only comparable within one run on
# one machine.
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${1:-build}
case $BUILD in /*) ;; *) BUILD="$ROOT/$BUILD" ;; esac
BIN="$BUILD/bin/gi-bake"
SCENES=${GI_SCENES_DIR:-$ROOT/../shared/scenes}
OUT="$ROOT/out"
JSONL="$OUT/bench.jsonl"
THREADS=${BENCH_THREADS:-"1 2"}

if [ ! -x "$BIN" ]; then
  echo "run-bench: no gi-bake at $BIN (build first: make); nothing measured" >&2
  exit 0
fi
if ! command -v python3 > /dev/null 2>&1; then
  echo "run-bench: python3 is needed to read gi-bake --json; nothing measured" >&2
  exit 0
fi
mkdir -p "$OUT" || { echo "run-bench: cannot create $OUT" >&2; exit 0; }
TMP=$(mktemp -d "${TMPDIR:-/tmp}/gi-bench.XXXXXX") || exit 0
trap 'rm -rf "$TMP"' EXIT INT TERM
REV=$(git -C "$ROOT" rev-parse --short HEAD 2> /dev/null || echo unknown)
git -C "$ROOT" diff --quiet HEAD -- 2> /dev/null || REV="$REV-dirty"
STAMP=$(date -u +%Y-%m-%dT%H:%M:%SZ)
HOST=$(uname -n)
CPUS=$(nproc 2> /dev/null || echo 1)

echo "gi-bake benchmark  rev $REV  $STAMP  $HOST ($CPUS cpus)"
printf '%-18s %3s %10s %8s %8s %8s %8s %8s %8s %8s %9s %8s\n' scene thr triangles load voxelize inject \
  filter bounce gather encode total "MiB"

# row LABEL THREADS ARGS...: one bake, one table row, one JSON line.
row() {
  label=$1; thr=$2; shift 2
  # Writing both files makes "encode" a real figure; they are thrown away.
  if ! "$BIN" "$@" --threads "$thr" --json --exr "$TMP/probe.exr" --vdb "$TMP/cascades.vdb" \
      > "$TMP/run.json" 2> "$TMP/run.err"; then
    printf '%-18s %3s  FAILED: %s\n' "$label" "$thr" "$(tail -n 1 "$TMP/run.err")"
    return 0
  fi
  python3 - "$TMP/run.json" "$JSONL" "$label" "$thr" "$REV" "$STAMP" "$HOST" "$*" <<'PY' || \
    printf '%-18s %3s  could not read the JSON\n' "$label" "$thr"
import json, sys
path, jsonl, label, thr, rev, stamp, host, args = sys.argv[1:9]
d = json.load(open(path))
t = d["timings_ms"]
keys = ["load", "voxelize", "inject", "filter", "bounce", "gather", "encode", "total"]
print("%-18s %3s %10d " % (label, thr, d["scene"]["triangles"]) +
      " ".join("%8.1f" % t[k] for k in keys[:-1]) + " %9.1f %8.2f" % (t["total"], d["cascade_bytes"] / 2**20))
line = {"bench": "gi-bake", "scene": label, "args": args, "threads": d["threads"], "rev": rev,
        "time": stamp, "host": host, "triangles": d["scene"]["triangles"], "timings_ms": t,
        "cascade_bytes": d["cascade_bytes"], "voxels_occupied": d["voxels_occupied"],
        "levels": d["quality"]["levels"], "res": d["quality"]["res"], "voxel0": d["quality"]["voxel0"],
        "shadow_rays": d["shadow_rays"], "cone_samples": d["cone_samples"],
        "effects_ran": sorted(k for k, v in d["effects"].items() if v["ran"]), "version": d["version"]}
with open(jsonl, "a") as f:
    f.write(json.dumps(line) + "\n")
PY
}

# bench LABEL ARGS...: the same bake at every thread count.
bench() {
  label=$1; shift
  for thr in $THREADS; do row "$label" "$thr" "$@"; done
}

CORNELL="$SCENES/cornell-box/cornell-box.obj"
if [ -f "$CORNELL" ]; then
  bench cornell-box "$CORNELL" --at 278,273,279.6
else
  echo "SKIP cornell-box: $CORNELL not found (set GI_SCENES_DIR)" >&2
fi

# Munich is Z-up, ground at z = 0; its bounds are (-805.6, -688.6, 0) ..
# (669.9, 517.0, 98.6). The bounds' centre at 2 m is on an open square in
# full sun (direct irradiance 3.2 against 0.4 in a street shadow 16 m north).
MUNICH="$SCENES/munich/munich.obj"
if [ -f "$MUNICH" ]; then
  bench munich "$MUNICH" --up z --at -67.85,-85.78,2
else
  echo "SKIP munich: $MUNICH not found (set GI_SCENES_DIR)" >&2
fi

# The city at detail 2 (the default): ~0.14 M triangles at 600 m, ~0.8 M at
# 1500 m and ~8.9 M at 5000 m (3-5 s and 1.5 GB to build). The finest voxel
# is pinned to 0.5 m so all three bake the same cascade (coarsest level
# 512 m across): the default would stretch it over the whole city, and the
# rows would measure different cascades instead of the cost of scene size.
for extent in 600 1500 5000; do
  bench "city-$extent" city --city-extent "$extent" --city-detail 2 --voxel 0.5
done

echo "JSON lines appended to $JSONL"
echo
# What the specular pass costs in a camera view, and what the plan saves.
sh "$ROOT/tests/bench/specular-bench.sh" "$BUILD"
exit 0
