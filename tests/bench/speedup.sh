#!/bin/sh
# speedup.sh BUILD_DIR: the cold bake of v0.1.0 against this tree, side by side.
#
# Builds v0.1.0 (db8404f) once from a git worktree under out/ (cached), then
# bakes each scene with both gi-bake binaries, alternating, RUNS times each on
# 2 threads, and once more per run on 1 thread with this tree (thread scaling).
# Prints medians and `speed-up: N.Nx` per scene (with the range of the single
# runs' ratios, each v0.1.0 bake over the bake after it), samples per cone, ns per
# marched sample per thread (the replays' time left out) and the millions of
# lit steps the later bounces replayed instead of marching (light/bounce.c),
# and appends one JSON line per scene to out/bench.jsonl.
# Each run also bakes twice at once on 1 thread each: the ceiling column is
# what two cores give this workload when they share a cache and memory.
#
# The bake is the cascade's plan and stages (plan, voxelize, inject, filter,
# bounce), not the scene's load or the probe's gather; v0.1.0 reports no plan
# (its setup was a placement), so its side counts the four stages. A benchmark prints figures and never
# fails the build: this script always exits 0. Numbers are comparable only
# within one run on one machine; a loaded machine slows both sides alike.
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${1:-build}
case $BUILD in /*) ;; *) BUILD="$ROOT/$BUILD" ;; esac
NOW="$BUILD/bin/gi-bake"
BASE_REV=${BENCH_BASE_REV:-db8404f}
RUNS=${BENCH_RUNS:-5}
OUT="$ROOT/out"
SCENES=${GI_SCENES_DIR:-$ROOT/../shared/scenes}
JSONL="$OUT/bench.jsonl"

say() { echo "speedup: $*" >&2; }
[ -x "$NOW" ] || { say "no gi-bake at $NOW (build first: make); nothing measured"; exit 0; }
command -v python3 > /dev/null 2>&1 || { say "python3 is needed to read gi-bake --json"; exit 0; }
mkdir -p "$OUT" || exit 0

# v0.1.0, built once with its own build rules (its CMake default: Release).
. "$ROOT/tests/bench/base-build.sh"
base_gi_bake "$BASE_REV" v0.1.0 || exit 0
OLD=$BASE_BIN

TMP=$(mktemp -d "${TMPDIR:-/tmp}/gi-speedup.XXXXXX") || exit 0
trap 'rm -rf "$TMP"' EXIT INT TERM
REV=$(git -C "$ROOT" rev-parse --short HEAD 2> /dev/null || echo unknown)
git -C "$ROOT" diff --quiet HEAD -- 2> /dev/null || REV="$REV-dirty"
STAMP=$(date -u +%Y-%m-%dT%H:%M:%SZ)

# bake FILE BIN THREADS ARGS...: one line "bake_ms samples cones ns taps" to $TMP/FILE
# (taps: lit steps the later bounces replayed instead of marching; none in v0.1.0).
# (sh functions share variables: these names are bake's own; two bakes at
# once run in subshells, each with its own FILE.)
bake() {
  b_file=$1; b_bin=$2; b_thr=$3; shift 3
  if "$b_bin" "$@" --threads "$b_thr" --json > "$TMP/$b_file.json" 2> "$TMP/$b_file.err"; then
    python3 - "$TMP/$b_file.json" >> "$TMP/$b_file" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
t = d["timings_ms"]
bake = sum(t.get(k, 0) for k in ("plan", "voxelize", "inject", "filter", "bounce"))
print(bake, d.get("cone_samples", 0), d.get("cones_traced", 0), d.get("ns_per_sample", 0), d.get("taps_replayed", 0))
PY
  else
    say "$b_file: $(tail -n 1 "$TMP/$b_file.err")"
  fi
}

echo "cold bake, v0.1.0 ($BASE_REV) against $REV, $RUNS alternating runs, $(nproc) cpus, $STAMP"
echo "ceiling: what two 1-thread bakes run at once give over one alone (2 x alone / together), the"
echo "most 2 threads can give on this machine when the cores slow each other (shared cache, memory)"
printf '%-10s %12s %12s %10s %12s %14s %14s %9s %12s\n' scene "v0.1.0 ms" "now ms" speed-up "samples/cone" \
  "ns/sample/thr" "2 thr vs 1" ceiling "M replayed"

# scene LABEL ARGS...
scene() {
  label=$1; shift
  rm -f "$TMP/$label.old" "$TMP/$label.now" "$TMP/$label.one" "$TMP/$label.pa" "$TMP/$label.pb"
  i=0
  while [ $i -lt "$RUNS" ]; do
    bake "$label.old" "$OLD" 2 "$@"
    bake "$label.now" "$NOW" 2 "$@"
    bake "$label.one" "$NOW" 1 "$@"
    (bake "$label.pa" "$NOW" 1 "$@") & (bake "$label.pb" "$NOW" 1 "$@"); wait
    i=$((i + 1))
  done
  python3 - "$TMP/$label" "$label" "$REV" "$BASE_REV" "$STAMP" "$JSONL" "$*" <<'PY' ||
import json, statistics, sys
pre, label, rev, base, stamp, jsonl, args = sys.argv[1:8]
def rows(p):
    try:
        return [list(map(float, l.split())) for l in open(pre + "." + p) if l.strip()]
    except OSError:
        return []
o, n, s, pair = rows("old"), rows("now"), rows("one"), rows("pa") + rows("pb")
if not o or not n:
    print("%-10s  not measured" % label); sys.exit(0)
mo, mn = statistics.median(r[0] for r in o), statistics.median(r[0] for r in n)
ms1 = statistics.median(r[0] for r in s) if s else float("nan")
mp = statistics.median(r[0] for r in pair) if pair else float("nan")
spc = n[0][1] / n[0][2] if n[0][2] else float("nan")
ns = statistics.median(r[3] for r in n)
taps = n[0][4] if len(n[0]) > 4 else 0.0
print("%-10s %12.1f %12.1f %9.1fx %12.1f %14.1f %13.2fx %8.2fx %12.2f" %
      (label, mo, mn, mo / mn, spc, ns, ms1 / mn, 2 * ms1 / mp, taps / 1e6))
# Each run's own ratio (its v0.1.0 bake over the bake right after it): how far
# this machine's speed moved within the run, which the medians hide.
per = sorted(a[0] / b[0] for a, b in zip(o, n) if b[0] > 0)
print("%-10s speed-up: %.1fx (median; single runs %.1f-%.1fx)" % (label, mo / mn, per[0], per[-1]))
with open(jsonl, "a") as f:
    f.write(json.dumps({"bench": "speedup", "scene": label, "args": args, "rev": rev, "base": base,
                        "stamp": stamp, "runs": len(n), "v010_bake_ms": mo, "bake_ms": mn,
                        "speedup": mo / mn, "one_thread_ms": ms1, "thread_scaling": ms1 / mn,
                        "pair_one_thread_ms": mp, "thread_ceiling": 2 * ms1 / mp,
                        "samples_per_cone": spc, "ns_per_sample": ns,
                        "cone_samples": n[0][1], "v010_cone_samples": o[0][1], "taps_replayed": taps,
                        "speedup_run_min": per[0], "speedup_run_max": per[-1]}) + "\n")
PY
    say "$label: could not read the figures"
}

if [ -f "$SCENES/cornell-box/cornell-box.obj" ]; then
  scene cornell "$SCENES/cornell-box/cornell-box.obj"
else
  say "SKIP cornell: $SCENES/cornell-box/cornell-box.obj not found"
fi
if [ -f "$SCENES/munich/munich.obj" ]; then
  scene munich "$SCENES/munich/munich.obj" --up z --at 0,0,2
else
  say "SKIP munich: $SCENES/munich/munich.obj not found"
fi
scene city city
exit 0
