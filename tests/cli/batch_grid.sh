# batch_grid.sh: gi-bake --grid (issue 13): sharded bakes merge into the
# unsharded bake's EXR and VDB byte for byte; a kill -9 run resumes from
# its checkpoints and redoes only the tiles not yet written, giving the
# clean bake's bytes; the manifest and EXR header describe the bake; street
# level drops probes inside the city's buildings; bad input exits 2 or 1
# naming the argument or file, with no output left behind.
. "$(dirname "$0")/common.sh"
make_box_scene
# Low quality: a box of 9^3 probes in 2 x 2 x 2 tiles.
BOXQ="--grid 0.5 --voxel 1 --res 8 --levels 2 --bounces 1 --cones 4 --samples 1 --probe-samples 4 --threads 1"
# Another bake of the same grid: one more bounce (gi-bake takes each value once).
BOXQ2=$(echo "$BOXQ" | sed 's/--bounces 1/--bounces 2/')

"$BIN" "$T/box.obj" $BOXQ --exr "$T/full.exr" --vdb "$T/full.vdb" --manifest "$T/full.json" \
    > "$T/out" 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && pass "grid bake exits 0" || { cat "$T/err" >&2; fail "grid bake exited $rc"; finish; }
grep -q 'progress tile=7 done=8/8 probes=729/729 ' "$T/err" && pass "one progress line per tile" \
  || fail "progress lines: $(grep progress "$T/err" | tail -2)"

# Automatic bounces and the default aperture: the manifest and the EXR's
# gi.quality say what the bake ran (the plan's count, the cones' matched
# aperture), not gi_quality_resolve's placeholders (bounces=2, aperture 0).
AUTOQ=$(echo "$BOXQ" | sed 's/--bounces 1 //')
"$BIN" "$T/box.obj" $AUTOQ --manifest "$T/auto.json" > /dev/null 2> "$T/auto.err" \
  || { cat "$T/auto.err" >&2; fail "grid bake with automatic bounces failed"; }
python3 - "$T/auto.json" <<'PY' && pass "manifest quality: the plan's bounces, the cones' aperture" \
  || fail "manifest quality with automatic bounces: $(cat "$T/auto.json")"
import json, re, sys
m = json.load(open(sys.argv[1]))
why = m["effects"]["bounce"]["why"]
planned = int(re.match(r"(\d+) bounce", why).group(1))
q = m["quality"]
assert q["bounces"] == planned, (q["bounces"], why)
assert "bounces=%d " % planned in q["text"] and "aperture_deg=0 " not in q["text"], q["text"]
PY

# Three shards, merged in a shuffled order.
for i in 0 1 2; do
  "$BIN" "$T/box.obj" $BOXQ --shard $i/3 --exr "$T/s$i.exr" > /dev/null 2> "$T/s$i.err" \
    || { cat "$T/s$i.err" >&2; fail "shard $i/3 failed"; }
done
"$BIN" merge --exr "$T/m.exr" --vdb "$T/m.vdb" "$T/s2.exr" "$T/s0.exr" "$T/s1.exr" 2> "$T/merge.err" \
  && pass "merge exits 0" || { cat "$T/merge.err" >&2; fail "merge failed"; }
cmp "$T/m.exr" "$T/full.exr" && pass "merged EXR == unsharded EXR, byte for byte" || fail "merged EXR differs"
cmp "$T/m.vdb" "$T/full.vdb" && pass "merged VDB == unsharded VDB, byte for byte" || fail "merged VDB differs"
cmp -s "$T/s0.exr" "$T/full.exr" && fail "a shard alone equals the full bake (shards not partial?)" \
  || pass "a single shard differs from the full bake"

# The manifest against the grid the options describe, and the EXR header's hash.
hash=$(python3 - "$T/full.json" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
g, t, q = m["grid"], m["tiles"], m["quality"]
assert g["counts"] == [9, 9, 9] and g["spacing"] == 0.5 and g["origin"] == [0, 0, 0], g
assert g["points"] == 729 and g["valid"] == 729 and g["above_ground"] == 0, g
assert t["size"] == [8, 8, 8] and t["count"] == 8 and t["baked"] == 8 and t["shard"] is None, t
assert t["probes_outside_level0"] == 0, t
assert q["res"] == 8 and q["levels"] == 2 and q["voxel0"] == 1 and q["bounces"] == 1, q
assert m["effects"]["emissive"]["ran"] is True, m["effects"]
for k in ("load", "plan", "bake", "gather", "write", "total"):
    assert m["timings_ms"][k] >= 0, k
assert m["probes_per_s"] > 0 and m["peak_rss_mb"] > 0
assert len(m["bake_hash"]) == 16
print(m["bake_hash"])
PY
) && pass "manifest fields match the grid" || fail "manifest fields"
if command -v exrheader > /dev/null 2>&1; then
  exrheader "$T/full.exr" > "$T/hdr"
  grep -q "gi.bake_hash (type string): \"$hash\"" "$T/hdr" && pass "EXR header carries the manifest's hash" \
    || fail "EXR gi.bake_hash is not $hash"
  grep -q 'gi.version (type string): "gi-bake ' "$T/hdr" && pass "EXR says gi-bake wrote it" \
    || fail "EXR gi.version: $(grep gi.version "$T/hdr")"
  for c in P.X P.Y P.Z valid.Y sh.L22.B irradiance.R; do
    grep -q "^    $c, 32-bit" "$T/hdr" || fail "EXR has no float channel $c"
  done
  grep -q 'dataWindow (type box2i): (0 0) - (8 80)' "$T/hdr" && pass "EXR is 9 x 81, one pixel per probe" \
    || fail "EXR data window: $(grep dataWindow "$T/hdr")"
else
  skip "exrheader not installed: EXR header checks skipped"
fi
if command -v vdb_print > /dev/null 2>&1; then
  vdb_print -l "$T/full.vdb" > "$T/grids" 2>&1
  for g in sh_L00 sh_L1-1 sh_L10 sh_L11 sh_L2-2 sh_L2-1 sh_L20 sh_L21 sh_L22 irradiance P; do
    grep -q "^Name: $g\$" "$T/grids" || fail "VDB has no grid $g"
  done
  [ "$(grep -c 'Number of active voxels: *729$' "$T/grids")" -eq 11 ] && pass "VDB: 11 grids of 729 probes" \
    || fail "VDB voxel counts: $(grep -E 'Name|active voxels' "$T/grids" | head -6)"
else
  skip "vdb_print not installed: VDB grid check skipped"
fi

# Merge refusals: a missing shard, a shard of another bake; nothing written.
"$BIN" merge --exr "$T/bad.exr" "$T/s0.exr" "$T/s2.exr" 2> "$T/e1"; rc=$?
[ $rc -eq 1 ] && grep -q 'shard 1/3 missing' "$T/e1" && [ ! -e "$T/bad.exr" ] \
  && pass "merge with a shard missing: exit 1, names it, no output" || fail "missing shard: rc $rc: $(cat "$T/e1")"
"$BIN" "$T/box.obj" $BOXQ2 --shard 1/3 --exr "$T/other.exr" > /dev/null 2>&1
"$BIN" merge --exr "$T/bad.exr" --vdb "$T/bad.vdb" "$T/s0.exr" "$T/other.exr" "$T/s2.exr" 2> "$T/e2"; rc=$?
[ $rc -eq 1 ] && grep -q "other.exr: belongs to a different bake" "$T/e2" && [ ! -e "$T/bad.exr" ] && [ ! -e "$T/bad.vdb" ] \
  && pass "merge of different bakes: exit 1, names the file, no output" || fail "different bakes: rc $rc: $(cat "$T/e2")"
"$BIN" merge --exr "$T/bad.exr" "$T/s0.exr" "$T/s0.exr" "$T/s1.exr" "$T/s2.exr" 2> "$T/e3"; rc=$?
[ $rc -eq 1 ] && grep -q 'given twice' "$T/e3" && pass "merge with a shard twice: exit 1" || fail "twice: rc $rc"
"$BIN" merge --exr "$T/bad.exr" "$T/box.obj" 2> "$T/e4"; rc=$?
[ $rc -eq 1 ] && grep -q 'box.obj' "$T/e4" && pass "merge of a non-EXR: exit 1 naming it" || fail "non-EXR: rc $rc"
"$BIN" merge "$T/s0.exr" 2> "$T/e5"; rc=$?
[ $rc -eq 2 ] && pass "merge without an output: exit 2" || fail "merge without output: rc $rc"
"$BIN" merge --exr "$T/m1.exr" --exr "$T/m2.exr" "$T/s0.exr" "$T/s1.exr" "$T/s2.exr" 2> "$T/e10"; rc=$?
[ $rc -eq 2 ] && grep -q -- "--exr: given twice" "$T/e10" && [ ! -e "$T/m1.exr" ] && [ ! -e "$T/m2.exr" ] \
  && pass "merge with --exr twice: exit 2, nothing written" || fail "--exr twice: rc $rc: $(cat "$T/e10")"
# A shard whose image is not its gi.grid's size (re-saved or cropped by
# another tool, same header): refused by name, not read past its end. Only
# the first shard's size was checked; the others were read as the grid's.
cat > "$T/reshape.py" <<'PY'
# reshape.py IN OUT W H [CHANNEL]: IN's header around a W x H image of
# zeros, uncompressed, without CHANNEL when given.
import struct, sys
src, dst, w, h = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
drop = sys.argv[5].encode() if len(sys.argv) > 5 else None
b = open(src, "rb").read()
pos, attrs = 8, []
def cstr(p):
    e = b.index(b"\0", p)
    return b[p:e].decode(), e + 1
while b[pos] != 0:  # the header's attributes, kept but for the windows and compression
    name, pos = cstr(pos)
    typ, pos = cstr(pos)
    (size,) = struct.unpack_from("<i", b, pos)
    attrs.append([name, typ, b[pos + 4:pos + 4 + size]])
    pos += 4 + size
chl = [a for a in attrs if a[0] == "channels"][0]
ch, p, nch, kept = chl[2], 0, 0, b""
while ch[p] != 0:
    e = ch.index(b"\0", p) + 17
    if ch[p:e - 17] != drop: kept, nch = kept + ch[p:e], nch + 1
    p = e
chl[2] = kept + b"\0"
for a in attrs:
    if a[0] in ("dataWindow", "displayWindow"): a[2] = struct.pack("<4i", 0, 0, w - 1, h - 1)
    if a[0] == "compression": a[2] = b"\0"
out = bytearray(b[:8])
for n, t, v in attrs: out += n.encode() + b"\0" + t.encode() + b"\0" + struct.pack("<i", len(v)) + v
out += b"\0"
line = 4 * w * nch  # float channels, uncompressed scanlines of zeros
start = len(out) + 8 * h
for y in range(h): out += struct.pack("<Q", start + y * (8 + line))
for y in range(h): out += struct.pack("<ii", y, line) + bytes(line)
open(dst, "wb").write(bytes(out))
PY
python3 "$T/reshape.py" "$T/s1.exr" "$T/crop.exr" 3 3 || fail "could not write the cropped shard"
"$BIN" merge --exr "$T/bad.exr" "$T/s0.exr" "$T/crop.exr" "$T/s2.exr" 2> "$T/e7"; rc=$?
[ $rc -eq 1 ] && grep -q "crop.exr: image is 3 x 3, but its gi.grid needs 9 x 81" "$T/e7" && [ ! -e "$T/bad.exr" ] \
  && pass "merge of a shard of the wrong size: exit 1 naming it" || fail "wrong size: rc $rc: $(cat "$T/e7")"
# A shard without one of the channels: the message names the channel.
python3 "$T/reshape.py" "$T/s1.exr" "$T/nopy.exr" 9 81 P.Y || fail "could not write the shard without P.Y"
"$BIN" merge --exr "$T/bad.exr" "$T/s0.exr" "$T/nopy.exr" "$T/s2.exr" 2> "$T/e9"; rc=$?
[ $rc -eq 1 ] && grep -q "nopy.exr: probe-grid channel P.Y is missing" "$T/e9" && [ ! -e "$T/bad.exr" ] \
  && pass "merge of a shard without P.Y: exit 1 naming the channel" || fail "no P.Y: rc $rc: $(cat "$T/e9")"
# An output that is one of the shards would replace it with the merged file
# (no gi.shard): the merge could never be run again. Refused, shard intact.
cp "$T/s0.exr" "$T/s0copy.exr"
"$BIN" merge --exr "$T/./s0copy.exr" "$T/s0copy.exr" "$T/s1.exr" "$T/s2.exr" 2> "$T/e8"; rc=$?
[ $rc -eq 2 ] && grep -q -- "--exr: .* is also the shard input" "$T/e8" && cmp -s "$T/s0copy.exr" "$T/s0.exr" \
  && pass "merge onto a shard input: exit 2, shard intact" || fail "output = input: rc $rc: $(cat "$T/e8")"

# A merge killed while it writes leaves no temporary file: the EXR waited
# for the VDB as "OUT.part.PID" (and the writers' "...part.PID.tmp.PID"),
# names the signal handler did not know, tens of MB each on a large grid.
"$BIN" "$T/box.obj" $(echo "$BOXQ" | sed 's/--grid 0.5/--grid 0.08/') --shard 0/1 --exr "$T/big.exr" \
    > /dev/null 2>&1 || fail "the 51^3 shard failed"
mkdir "$T/km"
"$BIN" merge --exr "$T/km/m.exr" --vdb "$T/km/m.vdb" "$T/big.exr" 2> /dev/null &
pid=$!
n=0
while [ -z "$(ls "$T/km")" ] && [ $n -lt 3000 ]; do sleep 0.01; n=$((n + 1)); done
kill -TERM $pid 2> /dev/null; wait $pid; rc=$?
left=$(ls "$T/km" | grep -v '^m\.\(exr\|vdb\)$' | tr '\n' ' ')
if [ -n "$left" ]; then fail "killed merge (rc $rc) left: $left"
elif [ $rc -eq 143 ]; then pass "merge killed while writing: no temporary file left"
else skip "the merge finished (rc $rc) before the kill: leftovers not checked"; fi

# A checkpoint folder of another bake is refused, not mixed in.
"$BIN" "$T/box.obj" $BOXQ --resume "$T/ckb" --exr "$T/b1.exr" > /dev/null 2>&1
"$BIN" "$T/box.obj" $BOXQ2 --resume "$T/ckb" --exr "$T/b2.exr" > /dev/null 2> "$T/e6"; rc=$?
[ $rc -eq 1 ] && grep -q -- "--resume: .*tile-0000000.bin' belongs to a different bake" "$T/e6" && [ ! -e "$T/b2.exr" ] \
  && pass "--resume with another bake's tiles: exit 1 naming the file" || fail "resume mismatch: rc $rc: $(cat "$T/e6")"
cmp "$T/b1.exr" "$T/full.exr" && pass "a --resume bake equals the plain bake" || fail "--resume changed the EXR"

# An edited scene is another bake: a wall's colour in the .mtl, or a vertex
# moved in the .obj (same triangle count, same grid points), refuses the old
# tiles. Both kept the hash, and --resume wrote the old scene's answers.
mkdir "$T/ed"
cp "$T/box.obj" "$T/box.mtl" "$T/ed/"
"$BIN" "$T/ed/box.obj" $BOXQ --resume "$T/cke" --exr "$T/e1.exr" > /dev/null 2>&1
sed -i 's/^Kd 0.7 0.7 0.7/Kd 0.2 0.7 0.7/' "$T/ed/box.mtl"
"$BIN" "$T/ed/box.obj" $BOXQ --resume "$T/cke" --exr "$T/e2.exr" > /dev/null 2> "$T/e7"; rc=$?
[ $rc -eq 1 ] && grep -q "belongs to a different bake" "$T/e7" && [ ! -e "$T/e2.exr" ] \
  && pass "--resume after the .mtl changed: the old tiles are refused" || fail "edited .mtl: rc $rc: $(tail -1 "$T/e7")"
cp "$T/box.mtl" "$T/ed/"
sed -i 's/^v 2.5 3.9 2.5/v 2.4 3.9 2.5/' "$T/ed/box.obj"
"$BIN" "$T/ed/box.obj" $BOXQ --resume "$T/cke" --exr "$T/e3.exr" > /dev/null 2> "$T/e8"; rc=$?
[ $rc -eq 1 ] && grep -q "belongs to a different bake" "$T/e8" && [ ! -e "$T/e3.exr" ] \
  && pass "--resume after the .obj changed: the old tiles are refused" || fail "edited .obj: rc $rc: $(tail -1 "$T/e8")"

# Bad arguments: exit 2 naming the option, before any work, no output.
expect_usage() { # OPTION-NAME ARGS...
  name=$1; shift
  "$BIN" "$T/box.obj" "$@" --exr "$T/never.exr" > /dev/null 2> "$T/eu"; rc=$?
  if [ $rc -eq 2 ] && grep -q -- "$name" "$T/eu" && [ ! -e "$T/never.exr" ]; then pass "$* -> exit 2 naming $name"
  else fail "$*: rc $rc: $(cat "$T/eu")"; fi
}
expect_usage --grid --grid 0
expect_usage --grid --grid -1
expect_usage --grid --grid nan
expect_usage --grid --grid inf
expect_usage --grid --grid 1e999
expect_usage --above-ground --grid 1 --above-ground 0
expect_usage --above-ground --grid 1 --above-ground -2
expect_usage --region --grid 1 --region 1,2,3,0,5,6
expect_usage --region --grid 1 --region 100,100,100,200,200,200
expect_usage --shard --grid 1 --shard 3/3
expect_usage --shard --grid 1 --shard 1/0
expect_usage --shard --grid 1 --shard -1/2
expect_usage --shard --grid 1 --shard x/2
expect_usage --grid --grid 1e-4
# A spacing past the largest voxel (the finest voxel defaults to it): the
# message said only "quality: voxel size must be at most 1e+07".
expect_usage "--grid (the finest voxel" --grid 1e8

# Street level on a corner of the city: probes inside buildings dropped.
CITYQ="--grid 15 --above-ground 2 --region -90,-10,-90,90,200,90 --res 8 --levels 4 --bounces 1 --cones 4 --samples 1 --probe-samples 4 --threads 1"
"$BIN" city $CITYQ --exr "$T/city.exr" --vdb "$T/city.vdb" --manifest "$T/city.json" > /dev/null 2> "$T/cerr" \
  || { cat "$T/cerr" >&2; fail "city grid bake failed"; finish; }
python3 - "$T/city.json" <<'PY' && pass "street level: probes inside buildings dropped, counts add up" || fail "city manifest"
import json, sys
g = json.load(open(sys.argv[1]))["grid"]
assert g["counts"] == [13, 1, 13], g
assert g["dropped_inside"] > 0 and g["valid"] > 0, g
assert g["valid"] + g["dropped_inside"] + g["no_ground"] == g["points"], g
PY

# Tiles share one bounce count: a white room with a lamp on a black 40 m
# ground. Each tile's own plan follows the albedo round it (the room's
# tiles more bounces than the ground's), and neighbouring tiles' probes
# stepped where they met; every tile now bakes the most any planned.
cat > "$T/room.mtl" <<'MTL'
newmtl white
Kd 0.7 0.7 0.7
newmtl black
Kd 0 0 0
MTL
cat > "$T/room.obj" <<'OBJ'
mtllib room.mtl
v 0 0 0
v 4 0 0
v 4 0 5
v 0 0 5
v 0 3 0
v 4 3 0
v 4 3 5
v 0 3 5
v -18 -0.01 -18
v 22 -0.01 -18
v 22 -0.01 22
v -18 -0.01 22
usemtl white
f 1 2 3 4
f 5 8 7 6
f 1 5 6 2
f 2 6 7 3
f 3 7 8 4
f 4 8 5 1
usemtl black
f 9 12 11 10
OBJ
ROOMQ="--grid 1 --region -18,0.5,-18,22,2.5,22 --res 8 --levels 4 --cones 4 --samples 1 --probe-samples 4 --threads 1"
"$BIN" "$T/room.obj" $ROOMQ --point 2,2.5,2.5,20,20,20 --no-default-lights --exr "$T/room.exr" --json \
  > "$T/room.json" 2> "$T/rerr" || { cat "$T/rerr" >&2; fail "room grid bake failed"; finish; }
python3 - "$T/room.json" <<'PY' && pass "grid tiles share one bounce count" || fail "grid bounce count"
import json, sys
d = json.load(open(sys.argv[1]))
b = d["effects"]["bounce"]
assert b["ran"] and "in every tile" in b["why"] and b["tiles_ran"] == d["tiles"]["baked"], (b, d["tiles"])
assert d["quality"]["bounces"] >= 2, d["quality"]
PY

# kill -9 in the middle, then --resume: only unfinished tiles are baked again.
"$BIN" city $CITYQ --resume "$T/ck" --exr "$T/r.exr" > /dev/null 2> "$T/r1.err" &
pid=$!
n=0
baked_so_far() { c=$(grep -c 'source=baked' "$T/r1.err" 2> /dev/null); echo "${c:-0}"; }
while [ "$(baked_so_far)" -lt 3 ] && [ $n -lt 600 ]; do sleep 0.1; n=$((n + 1)); done
kill -9 $pid 2> /dev/null; wait $pid 2> /dev/null
done1=$(ls "$T/ck" | grep -c '^tile-.*\.bin$')
[ -e "$T/r.exr" ] && fail "killed run left an output" || pass "killed run left no output"
"$BIN" city $CITYQ --resume "$T/ck" --exr "$T/r.exr" --vdb "$T/r.vdb" > /dev/null 2> "$T/r2.err"; rc=$?
resumed=$(grep -c 'source=resumed' "$T/r2.err")
redone=$(grep -c 'source=\(baked\|empty\)' "$T/r2.err")
[ $rc -eq 0 ] && [ "$done1" -ge 3 ] && [ "$resumed" -eq "$done1" ] && [ "$redone" -eq $((16 - done1)) ] \
  && pass "resume after kill -9: $done1 tiles kept, $redone redone of 16" \
  || fail "resume: rc $rc, checkpoints $done1, resumed $resumed, redone $redone"
cmp "$T/r.exr" "$T/city.exr" && cmp "$T/r.vdb" "$T/city.vdb" && pass "resumed output == clean bake, byte for byte" \
  || fail "resumed output differs from the clean bake"
finish
