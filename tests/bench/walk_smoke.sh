#!/bin/sh
# walk_smoke.sh GI_WALK: a seconds-long run of gi-walk (make test).
# bench on a 200 m city at 4 levels of 16^3 for 3 s: every path point must
# lie on a street band at the eye height, consecutive points one step of
# the path's speed apart (less only at a corner), and both JSON lines must
# hold finite figures (a crossing, a cold bake, drift within reason).
# tables on the same city: the markdown must hold every level and an
# OpenVDB memUsage no smaller than its active voxels' values. Usage errors exit 2.
set -eu
WALK=$1
TMP=$(mktemp -d "${TMPDIR:-/tmp}/gi-walk-smoke.XXXXXX")
trap 'rm -rf "$TMP"' EXIT
fail() { echo "walk_smoke: FAIL: $*" >&2; exit 1; }

"$WALK" bench --extent 200 --levels 4 --res 16 --seconds 3 --rate 10 --samples 2 --out "$TMP" \
  --json "$TMP/b.jsonl" > "$TMP/out.txt" 2> "$TMP/err.txt" || { cat "$TMP/err.txt"; fail "bench exited $?"; }
grep -Eq '^speed-up: [0-9]+\.[0-9]x \(mean\)' "$TMP/out.txt" || fail "no 'speed-up: N.Nx (mean)' line"
python3 - "$TMP" <<'PY'
import json, math, sys
d = sys.argv[1]
BLOCK, HALF_STREET, HALF_EXTENT, RATE = 60.0, 7.0, 100.0, 10.0
for name, speed, eye in (("walk", 1.4, 1.7), ("drive", 14.0, 1.2)):
    rows = [list(map(float, l.split(","))) for l in open(f"{d}/walk-{name}.csv")]
    assert len(rows) == 31, (name, len(rows))
    for i, (t, x, y, z) in enumerate(rows):
        assert abs(t - i / RATE) < 1e-6, (name, i, t)
        assert abs(y - eye) < 1e-6, (name, i, y)
        off = lambda v: abs(v - BLOCK * round(v / BLOCK))
        assert abs(x) <= HALF_EXTENT and abs(z) <= HALF_EXTENT, (name, i, x, z)
        assert off(x) <= HALF_STREET or off(z) <= HALF_STREET, f"{name} point {i} ({x}, {z}) is off the streets"
        if i:
            step = math.dist((x, z), rows[i - 1][1:4:2])
            assert step <= speed / RATE + 1e-3 and step > 0.5 * speed / RATE, (name, i, step)
lines = [json.loads(l) for l in open(f"{d}/b.jsonl")]
assert [l["path"] for l in lines] == ["walk", "drive"], lines
for l in lines:
    for k in ("update_ms_mean", "cold_ms_mean", "speedup_mean", "speedup_p99", "step_ms_mean", "drift_mean",
              "drift_max", "pop_shift", "pop_pairs_cold", "pop_shift_cold"):
        assert l[k] is not None and math.isfinite(l[k]), (l["path"], k, l[k])
    # The largest shift's step is a step of the path, and cold bakes across it were measured.
    assert 1 <= l["pop_shift_step"] <= l["steps"] and 0 <= l["pop_shift_cold"] < 1, l
    assert l["crossings"] >= 1 and l["cold_bakes"] >= 3 and l["pairs"] >= 1, l
    assert l["update_ms_mean"] > 0 and l["cold_ms_mean"] > 0 and 0 <= l["drift_max"] < 0.5, l
print("walk_smoke: paths on the streets, JSON figures finite")
PY

"$WALK" tables --label "smoke" --extent 200 --levels 4 --res 16 --moves 3 --md "$TMP/t.md" 2> "$TMP/err.txt" ||
  { cat "$TMP/err.txt"; fail "tables exited $?"; }
python3 - "$TMP/t.md" <<'PY'
import re, sys
md = open(sys.argv[1]).read()
for d in range(4):
    assert re.search(rf"^\| {d} \| ", md, re.M), f"no row for level {d}"
m = re.search(r"OpenVDB, [0-9.]+ m voxels, 7 Vec3f grids, (\d+) active \(memUsage\) \| (\d+) \|", md)
assert m, "no OpenVDB row"
active, size = int(m.group(1)), int(m.group(2))
# Leaf buffers hold 7 x 12 bytes per active voxel at least.
assert active > 0 and size >= active * 84, (active, size)
assert re.search(r"dynamic update \(mean of 3 one-cell moves\) \| [0-9.]+ \|", md), "no dynamic update row"
print(f"walk_smoke: tables ok ({active} active voxels, {size} bytes)")
PY

rc=0; "$WALK" bench --seconds abc > /dev/null 2>&1 || rc=$?
[ $rc -eq 2 ] || fail "--seconds abc exited $rc, expected 2"
rc=0; "$WALK" frobnicate > /dev/null 2>&1 || rc=$?
[ $rc -eq 2 ] || fail "an unknown command exited $rc, expected 2"
rc=0; "$WALK" tables --label x --md "$TMP/x.md" > /dev/null 2>&1 || rc=$?
[ $rc -eq 2 ] || fail "tables without a scene exited $rc, expected 2"
echo "walk_smoke: ok"
