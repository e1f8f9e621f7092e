#!/bin/sh
# walk-bench.sh BUILD: the moving-viewpoint benchmark (make bench-walk).
#
# In process (gi-walk bench): a street walk at 1.4 m/s and a drive at 14 m/s
# through the city at default quality, 10 Hz for 60 s, along the street
# centre lines (each point checked outside building footprints). One
# cascade follows each path with gi_cascade_move; a subsample of the steps
# that cross a cell boundary is also baked cold (GI_WALK_SAMPLES pairs per
# path, default 12: each pair is the crossing step and the one before it).
# Prints speed-up, drift and popping against the issue's goals, appends JSON
# lines to out/bench-walk.jsonl and writes the paths to out/walk-walk.csv and
# out/walk-drive.csv (t,x,y,z, what gi-client walk replays).
# Through the server: when gi-client has a `walk` command, a gi-server on an
# ephemeral port serves the same city and the same CSVs are replayed with
# `gi-client walk --json`; otherwise it says loudly that this part was skipped.
# Figures only: it exits 0 whatever they are (2 for its own usage errors).
# GI_WALK_QUICK=1: a 3 s walk on a 200 m city at 4 levels of 16^3 (seconds,
# to test this script). GI_WALK_EXTENT overrides the city's side (600 m).
set -u
[ $# -eq 1 ] || { echo "usage: walk-bench.sh BUILD" >&2; exit 2; }
BUILD=$1
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
OUT=${GI_WALK_OUT:-$ROOT/out}
WALK=$BUILD/bin/gi-walk
mkdir -p "$OUT"
EXTENT=${GI_WALK_EXTENT:-600}
ARGS="--seconds 60 --rate 10 --samples ${GI_WALK_SAMPLES:-12}"
if [ "${GI_WALK_QUICK:-0}" = 1 ]; then
  EXTENT=${GI_WALK_EXTENT:-200}
  ARGS="--seconds 3 --rate 10 --samples 2 --levels 4 --res 16"
  echo "bench-walk: QUICK mode (GI_WALK_QUICK=1): small city, low quality; the figures mean nothing"
fi
[ -x "$WALK" ] || { echo "bench-walk: no $WALK (build it first: make); nothing measured"; exit 0; }
echo "bench-walk: $(date -u '+%H:%M:%S UTC'): $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg) at start"
# shellcheck disable=SC2086
if ! "$WALK" bench --extent "$EXTENT" $ARGS --out "$OUT" --json "$OUT/bench-walk.jsonl" | tee "$OUT/bench-walk.txt"; then
  echo "bench-walk: WARNING: gi-walk bench failed (see above); figures incomplete"
fi
echo "bench-walk: $(date -u '+%H:%M:%S UTC'): load $(cut -d' ' -f1-3 /proc/loadavg) at the end of the in-process part"
"$ROOT/tests/bench/walk-server.sh" "$BUILD" "$OUT" "$EXTENT"
exit 0
