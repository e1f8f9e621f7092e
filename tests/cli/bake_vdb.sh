# bake_vdb.sh: --vdb writes a cascade snapshot that vdb_print lists
# (L0_density, plain density), with no temporary file left behind.
. "$(dirname "$0")/common.sh"
make_box_scene

"$BIN" "$T/box.obj" --at 2,1.5,2 --levels 3 --res 16 --bounces 1 --json \
    --vdb "$T/cascades.vdb" --exr "$T/probe.exr" --half > "$T/out.json" 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && pass "bake with --vdb exits 0" || { cat "$T/err" >&2; fail "bake exited $rc"; finish; }
[ -s "$T/cascades.vdb" ] && pass "VDB exists" || fail "VDB missing"
[ -s "$T/probe.exr" ] && pass "EXR exists" || fail "EXR missing"
leftover=$(find "$T" -name '*.tmp.*')
[ -z "$leftover" ] && pass "no temporary files" || fail "temporary files left: $leftover"
python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); assert d["outputs"]["vdb"].endswith("cascades.vdb")' \
  "$T/out.json" && pass "JSON names the VDB" || fail "JSON outputs.vdb"

# A disk that fills up during the write (no root needed): the file size
# limit (16 blocks: 8 or 16 KiB as the shell counts) refuses bytes past it as a full disk would (EFBIG instead of
# ENOSPC; SIGXFSZ ignored so the write fails instead of killing). The VDB
# writer ignored failed writes: exit 0 and a truncated file in place.
vdb_size=$(wc -c < "$T/cascades.vdb")
[ "$vdb_size" -gt 16384 ] && pass "VDB is $vdb_size bytes (over the limit below)" || fail "VDB only $vdb_size bytes"
(trap '' XFSZ; ulimit -f 16; exec "$BIN" "$T/box.obj" --at 2,1.5,2 --levels 3 --res 16 --bounces 1 \
    --vdb "$T/full.vdb") > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 1 ] && grep -q "VDB file '$T/full.vdb': cannot write '$T/full.vdb.tmp.[0-9]*': File too large" "$T/err" \
  && pass "--vdb on a full disk -> exit 1: $(cat "$T/err")" || fail "--vdb on a full disk (rc $rc): $(cat "$T/err")"
[ ! -e "$T/full.vdb" ] && [ -z "$(find "$T" -name 'full.vdb.tmp.*')" ] && pass "nothing left of the failed VDB" \
  || fail "the failed VDB left files: $(ls "$T")"

if command -v vdb_print > /dev/null 2>&1; then
  vdb_print "$T/cascades.vdb" > "$T/grids" 2>&1
  grep -q 'L0_density' "$T/grids" && pass "vdb_print lists L0_density" || fail "vdb_print: no L0_density: $(cat "$T/grids")"
  grep -q '^density' "$T/grids" && pass "vdb_print lists density" || fail "vdb_print: no plain density"
else
  skip "vdb_print not installed (package libopenvdb-tools): VDB grid check skipped"
fi
if command -v exrheader > /dev/null 2>&1; then
  exrheader "$T/probe.exr" | grep -q 'sh\.L00\.R, 16-bit' && pass "--half stores half floats" \
    || fail "--half: sh.L00.R is not 16-bit"
else
  skip "exrheader not installed: --half check skipped"
fi
# Half floats end at 65504: a brighter probe is stored as 65504, and said
# so (it was silent); the dim bake above clamped nothing and says nothing.
! grep -q "half-float range" "$T/err" && pass "--half within range -> no warning" \
  || fail "--half within range warned: $(cat "$T/err")"
"$BIN" "$T/box.obj" --at 2,1.5,2 --levels 3 --res 16 --bounces 1 --point 2,2,2,1e6,1e6,1e6 \
    --exr "$T/bright.exr" --half > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && grep -q "EXR file '$T/bright.exr': [0-9]* values beyond the half-float range were stored as" "$T/err" \
  && pass "--half past 65504 -> warned: $(cat "$T/err")" || fail "--half past 65504 (rc $rc): $(cat "$T/err")"
finish
