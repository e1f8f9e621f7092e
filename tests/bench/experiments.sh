#!/bin/sh
# experiments.sh BUILD: regenerates docs/experiments.md and its chart
# (make experiments). gi-walk tables measures the city at 600, 1500 and
# 5000 m and Munich (skipped loudly when /work/shared/scenes is absent);
# the walk figures and the chart's data come from make bench-walk's output
# in out/ (run here first when out/ has none, or when GI_EXPERIMENTS_WALK=1).
# The hand-written reading stays in docs/experiments-reading.md.
set -eu
[ $# -eq 1 ] || { echo "usage: experiments.sh BUILD" >&2; exit 2; }
BUILD=$1
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
OUT=$ROOT/out
WALK=$BUILD/bin/gi-walk
MUNICH=${GI_MUNICH:-$ROOT/../shared/scenes/munich/munich.obj}
command -v gnuplot > /dev/null || "$ROOT/scripts/install-deps.sh"
mkdir -p "$OUT" "$ROOT/docs"
if [ "${GI_EXPERIMENTS_WALK:-0}" = 1 ] || [ ! -s "$OUT/bench-walk-steps-walk.csv" ] || [ ! -s "$OUT/bench-walk.txt" ]; then
  "$ROOT/tests/bench/walk-bench.sh" "$BUILD"
fi
LOAD0=$(cut -d' ' -f1-3 /proc/loadavg)
TABLES=$OUT/experiments-tables.md
: > "$TABLES"
for e in 600 1500 5000; do
  echo "experiments: city at $e m"
  "$WALK" tables --label "City, $e m" --extent "$e" --md "$TABLES"
done
if [ -r "$MUNICH" ]; then
  echo "experiments: Munich"
  "$WALK" tables --label "Munich (munich.obj, up z)" --scene "$MUNICH" --up z --at 0,0,2 --md "$TABLES"
else
  echo "experiments: ############################################"
  echo "experiments: MUNICH SKIPPED: no $MUNICH"
  echo "experiments: ############################################"
  printf '### Munich\n\nSkipped: %s was not found on the machine that ran this.\n\n' "$MUNICH" >> "$TABLES"
fi
LOAD1=$(cut -d' ' -f1-3 /proc/loadavg)
NOTE="Run of $(date -u '+%Y-%m-%d %H:%M UTC') at $(git -C "$ROOT" rev-parse --short HEAD) on $(nproc) cores \
($(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //')). Load average (1, 5, 15 min) $LOAD0 before the tables \
and $LOAD1 after: the machine was shared, so every time here is a figure of that run, not of the code alone; \
the ratios (same run, same load) are the steadier figures."
python3 "$ROOT/tools/gi-walk/experiments.py" --tables "$TABLES" --bench-txt "$OUT/bench-walk.txt" \
  --steps "$OUT/bench-walk-steps-walk.csv" --steps-drive "$OUT/bench-walk-steps-drive.csv" --reading "$ROOT/docs/experiments-reading.md" \
  --md "$ROOT/docs/experiments.md" --png "$ROOT/docs/experiments-walk.png" --run-note "$NOTE"
echo "experiments: wrote docs/experiments.md and docs/experiments-walk.png"
