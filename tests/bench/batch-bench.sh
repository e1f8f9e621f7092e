#!/bin/sh
# batch-bench.sh BUILD_DIR: the batch probe-grid figures of issue 13: Munich
# street-level probes at 4 m spacing, 2 m above the ground, on 2 threads:
# probe count, tiles, total time, probes/s and peak RSS. Appends one JSON
# line to out/bench-batch.jsonl.
#
# Figures only: this script always exits 0, and skips loudly when the
# shared scenes are absent. Quality: --levels 5 (the coarsest level still
# spans the city) and --bounces 1, so the whole city bakes in minutes;
# BENCH_BATCH_ARGS adds or overrides options.
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${1:-build}
case $BUILD in /*) ;; *) BUILD="$ROOT/$BUILD" ;; esac
BIN="$BUILD/bin/gi-bake"
SCENES=${GI_SCENES_DIR:-$ROOT/../shared/scenes}
MUNICH="$SCENES/munich/munich.obj"
OUT="$ROOT/out"
ARGS=${BENCH_BATCH_ARGS:-"--levels 5 --bounces 1"}

[ -x "$BIN" ] || { echo "batch-bench: no gi-bake at $BIN (build first: make); nothing measured" >&2; exit 0; }
[ -f "$MUNICH" ] || { echo "batch-bench: SKIP: $MUNICH absent; nothing measured" >&2; exit 0; }
command -v python3 > /dev/null 2>&1 || { echo "batch-bench: python3 needed to read the manifest" >&2; exit 0; }
mkdir -p "$OUT" || exit 0
TMP=$(mktemp -d "${TMPDIR:-/tmp}/gi-bench-batch.XXXXXX") || exit 0
trap 'rm -rf "$TMP"' EXIT INT TERM

echo "batch-bench: Munich, --grid 4 --above-ground 2 --threads 2 $ARGS (minutes)..."
# shellcheck disable=SC2086
if ! "$BIN" "$MUNICH" --up z --grid 4 --above-ground 2 --threads 2 $ARGS \
     --exr "$TMP/munich.exr" --vdb "$TMP/munich.vdb" --manifest "$TMP/munich.json" \
     > "$TMP/out" 2> "$TMP/err"; then
  echo "batch-bench: the bake failed:" >&2
  tail -5 "$TMP/err" >&2
  exit 0
fi
python3 - "$TMP/munich.json" "$OUT/bench-batch.jsonl" "$TMP/munich.exr" "$TMP/munich.vdb" <<'PY' || true
import json, os, sys
m = json.load(open(sys.argv[1]))
g, t, ms = m["grid"], m["tiles"], m["timings_ms"]
row = {"bench": "batch-munich", "version": m["version"], "spacing": g["spacing"],
       "above_ground": g["above_ground"], "columns": g["points"], "probes": g["valid"],
       "dropped_inside": g["dropped_inside"], "no_ground": g["no_ground"], "tiles": t["count"],
       "tiles_baked": t["baked"], "threads": m["threads"], "total_s": ms["total"] / 1e3,
       "bake_s": ms["bake"] / 1e3, "gather_s": ms["gather"] / 1e3, "probes_per_s": m["probes_per_s"],
       "peak_rss_mb": m["peak_rss_mb"], "exr_mb": os.path.getsize(sys.argv[3]) / 2**20,
       "vdb_mb": os.path.getsize(sys.argv[4]) / 2**20, "quality": m["quality"]["text"]}
print("Munich street-level probes, %g m spacing, %g m above ground, %d threads" %
      (row["spacing"], row["above_ground"], row["threads"]))
print("  columns %d, probes %d (dropped inside buildings %d, no ground %d)" %
      (row["columns"], row["probes"], row["dropped_inside"], row["no_ground"]))
print("  tiles %d, total %.1f s (bake %.1f s, gather %.1f s), %.0f probes/s (of bake+gather time)" %
      (row["tiles"], row["total_s"], row["bake_s"], row["gather_s"], row["probes_per_s"]))
print("  peak RSS %.0f MB, EXR %.1f MB, VDB %.1f MB" % (row["peak_rss_mb"], row["exr_mb"], row["vdb_mb"]))
print("  quality: " + row["quality"])
with open(sys.argv[2], "a") as f:
    f.write(json.dumps(row) + "\n")
PY
exit 0
