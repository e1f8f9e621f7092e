#!/bin/sh
# render-bench.sh BUILD_DIR: what gathering a camera view's indirect light
# and its sampled lights' direct light (sky, emitters) at anchors saves.
# For each view (the Cornell box's Mitsuba camera; the street views of
# Munich and the procedural city that gi-accuracy compares) gi-bake renders
# the same view with --render-stride 1 (16 diffuse cones and the sampled
# lights' 64 shadow rays at every pixel) and with the default (every 4th
# pixel of every 4th row, mixed between anchors on a pixel's surface),
# alternating, REPEAT times each, and
# prints the median cone-traced render milliseconds, the diffuse cones
# traced and the ratios, measured in the same run. The cone counts are the
# deterministic part. What the mix does to the error against a path-traced
# reference is in docs/accuracy.md ("Camera views at equal error").
#
# A benchmark prints figures and always exits 0. Shared scenes are skipped
# loudly when absent. Set RENDER_REPEAT (default 3).
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${1:-build}
case $BUILD in /*) ;; *) BUILD="$ROOT/$BUILD" ;; esac
BIN="$BUILD/bin/gi-bake"
SCENES=${GI_SCENES_DIR:-$ROOT/../shared/scenes}
REPEAT=${RENDER_REPEAT:-3}

if [ ! -x "$BIN" ]; then
  echo "render-bench: no gi-bake at $BIN (build first: make); nothing measured" >&2
  exit 0
fi
command -v python3 > /dev/null 2>&1 || { echo "render-bench: python3 is needed to read gi-bake --json" >&2; exit 0; }
TMP=$(mktemp -d "${TMPDIR:-/tmp}/gi-render.XXXXXX") || exit 0
trap 'rm -rf "$TMP"' EXIT INT TERM

echo "camera views: indirect and sampled direct light at every pixel (stride 1) against anchors (default stride 4),"
echo "median of $REPEAT renders each, alternating; default quality, 2 threads, 1 path/pixel for the unused path-traced half"
printf '%-8s %-9s %12s %14s %12s %12s\n' view stride "render ms" "diffuse cones" "ms ratio" "cone ratio"

# view LABEL ARGS...: REPEAT rounds of stride 1 and the default, then a row each.
view() {
  label=$1; shift
  i=0
  while [ $i -lt "$REPEAT" ]; do
    for mode in all anchors; do
      if [ $mode = all ]; then extra="--render-stride 1"; else extra=""; fi
      # shellcheck disable=SC2086 # extra is one option and its value, or nothing
      if ! "$BIN" "$@" $extra --threads 2 --render-samples 1 --json --png "$TMP/v.png" \
          > "$TMP/$mode.$i.json" 2> "$TMP/err"; then
        echo "$label $mode: FAILED: $(tail -n 1 "$TMP/err")"
        return 0
      fi
    done
    i=$((i + 1))
  done
  python3 - "$TMP" "$REPEAT" "$label" <<'PY'
import json, statistics, sys
tmp, n, label = sys.argv[1], int(sys.argv[2]), sys.argv[3]
rows = {}
for mode in ("all", "anchors"):
    runs = [json.load(open("%s/%s.%d.json" % (tmp, mode, i)))["render"] for i in range(n)]
    rows[mode] = (statistics.median(r["cone_ms"] for r in runs), runs[0]["diffuse_cones"], runs[0]["indirect_stride"])
base_ms, base_cones = rows["all"][0], rows["all"][1]
for mode in ("all", "anchors"):
    ms, cones, stride = rows[mode]
    print("%-8s %-9d %12.1f %14d %11.2fx %11.3fx" % (label, stride, ms, cones, ms / base_ms,
          cones / base_cones if base_cones else 0.0))
PY
}

CBOX="$SCENES/cornell-box"
if [ -f "$CBOX/cornell-box.obj" ] && [ -f "$CBOX/cbox-mitsuba.xml" ]; then
  # The Mitsuba sensor at 256 x 256, the cascade at the box's centre.
  view cornell "$CBOX/cornell-box.obj" --at 278,273,279.6 --render "$CBOX/cbox-mitsuba.xml"
else
  echo "SKIP cornell: $CBOX/cornell-box.obj or cbox-mitsuba.xml not found (set GI_SCENES_DIR)" >&2
fi
MUNICH="$SCENES/munich/munich.obj"
if [ -f "$MUNICH" ]; then
  # gi-accuracy's street view: eye 1.7 m up at the viewpoint, 40 m north.
  view munich "$MUNICH" --up z --at 0,0,2 --render "0,0,1.7,0,40,1.7,70,320,180"
else
  echo "SKIP munich: $MUNICH not found (set GI_SCENES_DIR)" >&2
fi
# The city's default viewpoint, looking down the street along +x.
view city city --at 2.1,1.7,1.4 --render "2.1,1.7,1.4,42.1,1.7,1.4,70,320,180"
exit 0
