# grid_resume.sh: a resumed --grid bake's manifest describes the whole
# outputs, and an absurd grid is refused at once.
# The manifest of a bake stopped part way and resumed counted only the last
# run's tiles (effects' tiles_ran 5 of 8, no record of the 3 resumed ones):
# now its totals equal an uninterrupted bake's, and one record per tile
# names the run that baked it and matches the EXR's valid probes. A grid of
# 1.38M tiles was planned silently for 43 s before its first progress line
# (ETA 9.5 days): more tiles than --max-tiles (default 100000) exit 2 naming
# the flag, the count and the limit, before the grid is built.
. "$(dirname "$0")/common.sh"
make_box_scene
BOXQ="--grid 0.5 --voxel 1 --res 8 --levels 2 --bounces 1 --cones 4 --samples 1 --probe-samples 4 --threads 1"
EXR_READ="$(cd "$(dirname "$0")/../blender" && pwd)"

"$BIN" "$T/box.obj" $BOXQ --exr "$T/full.exr" --manifest "$T/full.json" > /dev/null 2> "$T/full.err" \
  || { cat "$T/full.err" >&2; fail "uninterrupted grid bake failed"; finish; }

# Run 1 stops in storing tile 3 (its temporary is a FIFO nobody reads; the
# shell's pid is gi-bake's after exec) and is sent SIGTERM: tiles 0-2 kept.
mkdir "$T/ck"
sh -c 'mkfifo "$1/ck/tile-0000003.bin.tmp.$$" && shift && exec "$@"' sh "$T" "$BIN" "$T/box.obj" $BOXQ \
  --resume "$T/ck" --exr "$T/r.exr" --manifest "$T/r.json" > /dev/null 2>&1 &
pid1=$!
i=0 # until it waits for a reader of the FIFO
while [ $i -lt 400 ] && ! grep -qE 'partner|pipe|fifo' "/proc/$pid1/wchan" 2> /dev/null; do
  sleep 0.05; i=$((i + 1))
done
kill -TERM $pid1; wait $pid1; rc=$?
kept=$(ls "$T/ck" | grep -c '^tile-.*\.bin$')
[ $rc -eq 143 ] && [ "$kept" -eq 3 ] && [ ! -e "$T/r.json" ] && pass "run 1 stopped after 3 of 8 tiles" \
  || fail "run 1: rc $rc, $kept tiles kept"

"$BIN" "$T/box.obj" $BOXQ --resume "$T/ck" --exr "$T/r.exr" --manifest "$T/r.json" > /dev/null 2> "$T/r.err"; rc=$?
[ $rc -eq 0 ] && cmp -s "$T/r.exr" "$T/full.exr" && pass "run 2 resumed: EXR == the uninterrupted bake's" \
  || fail "run 2: rc $rc $(tail -n 1 "$T/r.err")"
PYTHONPATH="$EXR_READ" python3 - "$T/r.json" "$T/full.json" "$T/r.exr" "$pid1" <<'PY' \
  && pass "resumed manifest: totals of the uninterrupted bake, one record per tile matching the EXR" \
  || fail "resumed manifest does not describe the outputs"
import json, sys
import exr_read
r, full = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
rt, ft = r["tiles"], full["tiles"]
# This run's counts keep their meaning: 5 baked now, 3 resumed.
assert (rt["baked"], rt["resumed"], rt["owned"]) == (5, 3, 8), rt
for e in full["effects"]:
    assert r["effects"][e]["tiles_ran"] == full["effects"][e]["tiles_ran"], \
        (e, r["effects"][e]["tiles_ran"], full["effects"][e]["tiles_ran"])
for k in ("count", "owned", "probes_owned", "probes_outside_level0", "probes_done"):
    assert rt[k] == ft[k], (k, rt[k], ft[k])
assert ft["probes_done"] == 729 and ft["probes_baked"] == 729 and ft["probes_resumed"] == 0, ft
assert rt["probes_baked"] + rt["probes_resumed"] == 729 and rt["probes_resumed"] == 512 + 64 + 64, rt
# Runs: 3 tiles by the stopped run (its pid), 5 by this one.
runs = {(x["run"].rsplit("-", 1)[1], x["this_run"]): (x["tiles"], x["probes"]) for x in rt["runs"]}
assert runs == {(sys.argv[4], False): (3, 640), (r["run"].rsplit("-", 1)[1], True): (5, 89)}, rt["runs"]
# One record per tile: its probes are the EXR's valid pixels in its box.
w, h, ch = exr_read.read(sys.argv[3])
cnt, side = r["grid"]["counts"], rt["size"]
valid = {}
for i, v in enumerate(ch["valid.Y"]):
    x, y, z = i % cnt[0], i // cnt[0] % cnt[1], i // (cnt[0] * cnt[1])
    t = x // side[0] + rt["grid"][0] * (y // side[1] + rt["grid"][1] * (z // side[2]))
    valid[t] = valid.get(t, 0) + (v == 1.0)
recs = {x["tile"]: x for x in rt["records"]}
assert sorted(recs) == list(range(8)), sorted(recs)
for t, x in recs.items():
    assert x["probes"] == valid[t], (t, x["probes"], valid[t])
    assert x["source"] == ("resumed" if t < 3 else "baked"), x
    assert x["run"] == (r["run"] if t >= 3 else [y["run"] for y in rt["runs"] if not y["this_run"]][0]), x
    f = [y for y in ft["records"] if y["tile"] == t][0]
    assert (x["effects_ran"], x["outside_level0"]) == (f["effects_ran"], f["outside_level0"]), (x, f)
PY

# An absurd grid (201^3 points in tiles of 2^3: 1030301 tiles): refused at
# once, naming the flag, the count and the limit, with nothing written.
start=$(date +%s)
timeout 20 "$BIN" "$T/box.obj" --grid 0.02 --voxel 0.01 --res 8 --threads 1 --exr "$T/big.exr" \
  > /dev/null 2> "$T/big.err"
rc=$?
took=$(($(date +%s) - start))
[ $rc -eq 2 ] && grep -q -- "--max-tiles: the grid needs 1030301 tiles .* more than the limit 100000" "$T/big.err" \
  && [ $took -le 3 ] && [ ! -e "$T/big.exr" ] && pass "1030301 tiles refused in ${took} s: exit 2 naming --max-tiles" \
  || fail "absurd grid: rc $rc after ${took} s: $(head -c 300 "$T/big.err")"
# The limit is the flag's: 8 tiles bake under --max-tiles 8, not under 7.
"$BIN" "$T/box.obj" $BOXQ --max-tiles 7 --exr "$T/m7.exr" > /dev/null 2> "$T/m7.err"; rc=$?
want="--max-tiles: the grid needs 8 tiles (9 x 9 x 9 points in tiles of 8 x 8 x 8), more than the limit 7"
[ $rc -eq 2 ] && grep -qF -- "$want" "$T/m7.err" && [ ! -e "$T/m7.exr" ] && pass "--max-tiles 7: 8 tiles refused" \
  || fail "--max-tiles 7: rc $rc $(cat "$T/m7.err")"
"$BIN" "$T/box.obj" $BOXQ --max-tiles 8 --exr "$T/m8.exr" > /dev/null 2> "$T/m8.err"; rc=$?
[ $rc -eq 0 ] && cmp -s "$T/m8.exr" "$T/full.exr" && pass "--max-tiles 8: baked" || fail "--max-tiles 8: rc $rc"
finish
