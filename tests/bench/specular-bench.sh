#!/bin/sh
# specular-bench.sh BUILD_DIR: what the specular pass of a camera view
# costs, and what the effect plan saves by skipping it where nothing is
# glossy. For each street view (Munich: diffuse only; the procedural city:
# glass curtain walls) gi-bake renders the same view with the specular
# effect on auto, forced on and off, REPEAT times in turn, and prints the
# median cone-traced render milliseconds, the specular cones traced, and
# the ratio to the run with the pass off, measured in the same run. The
# cone counts are the deterministic part: the timing of auto against off
# (the same work when nothing is glossy) shows the run's own noise.
#
# A benchmark prints figures and always exits 0. Shared scenes are skipped
# loudly when absent. Set SPEC_REPEAT (default 3) and SPEC_SIZE (WxH,
# default 640,360).
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${1:-build}
case $BUILD in /*) ;; *) BUILD="$ROOT/$BUILD" ;; esac
BIN="$BUILD/bin/gi-bake"
SCENES=${GI_SCENES_DIR:-$ROOT/../shared/scenes}
REPEAT=${SPEC_REPEAT:-3}
SIZE=${SPEC_SIZE:-640,360}

if [ ! -x "$BIN" ]; then
  echo "specular-bench: no gi-bake at $BIN (build first: make); nothing measured" >&2
  exit 0
fi
TMP=$(mktemp -d "${TMPDIR:-/tmp}/gi-spec.XXXXXX") || exit 0
trap 'rm -rf "$TMP"' EXIT INT TERM

echo "specular pass of a camera view ($SIZE pixels, median of $REPEAT renders each; 1 path/pixel for the unused path-traced half)"
printf '%-8s %-6s %12s %16s %14s %10s   %s\n' view mode "render ms" "specular cones" "diffuse cones" "vs off" "plan"

# view LABEL ARGS...: REPEAT rounds of auto, on, off; then one row per mode.
view() {
  label=$1; shift
  i=0
  while [ $i -lt "$REPEAT" ]; do
    for mode in auto on off; do
      if ! "$BIN" "$@" --effect "specular=$mode" --render-samples 1 --json --png "$TMP/v.png" \
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
for mode in ("auto", "on", "off"):
    runs = [json.load(open("%s/%s.%d.json" % (tmp, mode, i))) for i in range(n)]
    ms = statistics.median(r["render"]["cone_ms"] for r in runs)
    rows[mode] = (ms, runs[0]["render"]["specular_cones"], runs[0]["render"]["diffuse_cones"],
                  runs[0]["effects"]["specular"])
off = rows["off"][0]
for mode in ("auto", "on", "off"):
    ms, cones, diffuse, fx = rows[mode]
    print("%-8s %-6s %12.1f %16d %14d %9.2fx   %s: %s" % (label, mode, ms, cones, diffuse, ms / off,
          "ran" if fx["ran"] else "skipped", fx["why"]))
PY
}

MUNICH="$SCENES/munich/munich.obj"
if [ -f "$MUNICH" ]; then
  # From the open square at eye height, north up a street canyon.
  view munich "$MUNICH" --up z --at -67.85,-85.78,2 --render "-67.85,-85.78,1.7,-67.85,-45.78,1.7,70,$SIZE"
else
  echo "SKIP munich: $MUNICH not found (set GI_SCENES_DIR)" >&2
fi
# The city's default viewpoint, looking down the street along +x.
view city city --at 2.1,1.7,1.4 --render "2.1,1.7,1.4,42.1,1.7,1.4,70,$SIZE"
exit 0
