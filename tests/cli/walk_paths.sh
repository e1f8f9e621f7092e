# walk_paths.sh: gi-walk bench --paths-only on cities it was not tuned for
# (extents 200 m and 2500 m): it creates the --out folder with its parents,
# writes both paths as t,x,y,z with 601 points 0.1 s apart at the walk's
# and the drive's speed (1.4 and 14 m/s, eye 1.7 and 1.2 m; a corner's step
# is a shorter chord), and names an --out it cannot create; --path replays
# a path file through the city (its figures, JSON line and errors).
. "$(dirname "$0")/common.sh"
WALK="$(dirname "$BIN")/gi-walk"
[ -x "$WALK" ] || { skip "gi-walk not built next to gi-bake"; exit 77; }
for e in 200 2500; do
  "$WALK" bench --extent $e --paths-only --out "$T/new/$e" > "$T/out" 2> "$T/err"; rc=$?
  [ $rc -eq 0 ] && pass "extent $e: paths written" || { fail "extent $e: exit $rc: $(cat "$T/err")"; continue; }
  /usr/bin/python3 - "$T/new/$e" <<'PY' || fail "extent $e: path files"
import math, sys
for name, speed, eye in (("walk", 1.4, 1.7), ("drive", 14.0, 1.2)):
    rows = [[float(x) for x in l.split(",")] for l in open(f"{sys.argv[1]}/walk-{name}.csv")]
    assert len(rows) == 601, (name, len(rows))
    assert all(len(r) == 4 and all(math.isfinite(x) for x in r) for r in rows), name
    steps = []
    for a, b in zip(rows, rows[1:]):
        assert abs(b[0] - a[0] - 0.1) < 1e-6, (name, a, b)
        steps.append(math.dist(a[1:], b[1:]))
        # Along the streets: a step is the speed's, a corner's chord a little less.
        assert 0.5 * 0.1 * speed <= steps[-1] <= 1.001 * 0.1 * speed, (name, a, b, steps[-1])
    steps.sort()
    assert abs(steps[len(steps) // 2] - 0.1 * speed) < 1e-3 * speed, (name, steps[len(steps) // 2])
    assert all(abs(r[2] - eye) < 1e-6 for r in rows), name
    print(f"{name}: 601 points, steps {0.1 * speed:g} m, eye {eye} m")
PY
done
# --path: a path file (a spreadsheet's: header, CRLF) replayed through the
# 300 m city: the figures are named after the file, the JSON line has the
# steps, no eye height and the city's extent.
"$WALK" bench --extent 300 --paths-only --out "$T/gen" > /dev/null 2>&1
{ printf 't,x,y,z\r\n'; head -n 30 "$T/gen/walk-drive.csv" | sed 's/$/\r/'; } > "$T/my drive.csv"
"$WALK" bench --extent 300 --path "$T/my drive.csv" --samples 2 --out "$T/pb" --json "$T/pb.jsonl" \
  > "$T/out" 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && grep -q "^== my_drive: 14.0 m/s, eye n/a m, 29 steps at 10 Hz, " "$T/out" \
  && grep -q "^speed-up: [0-9.]*x (mean)" "$T/out" && [ -s "$T/pb/bench-walk-steps-my_drive.csv" ] \
  && pass "--path replayed: $(grep '^speed-up' "$T/out" | head -1)" || fail "--path (rc $rc): $(cat "$T/out" "$T/err")"
/usr/bin/python3 - "$T/pb.jsonl" <<'PY' || fail "--path JSON: $(cat "$T/pb.jsonl")"
import json, sys
j = json.loads(open(sys.argv[1]).read().splitlines()[-1])
assert j["path"] == "my_drive" and j["steps"] == 29 and j["eye_m"] is None and j["city_extent_m"] == 300, j
assert j["cold_bakes"] >= 3 and j["speedup_mean"] > 0 and 0 <= j["drift_max"] < 1, j
PY
# A path through a closed block: its 10 points inside are counted and left
# out of drift and popping (their probes hold only leaked light).
cat > "$T/block.obj" <<'OBJ'
v -40 0 -40
v 40 0 -40
v 40 0 40
v -40 0 40
f 1 4 3 2
v -5 0 -5
v 5 0 -5
v 5 0 5
v -5 0 5
v -5 10 -5
v 5 10 -5
v 5 10 5
v -5 10 5
f 5 6 7 8
f 9 12 11 10
f 5 9 10 6
f 6 10 11 7
f 7 11 12 8
f 8 12 9 5
OBJ
/usr/bin/python3 -c "
for i in range(40): print('%.1f,%.1f,2,0.5' % (i / 10, -19.5 + i))" > "$T/through.csv"
"$WALK" bench --path "$T/through.csv" --scene "$T/block.obj" --samples 4 --out "$T/pt" --json "$T/pt.jsonl" \
  > "$T/out" 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && grep -q "note: 10 of 40 points of $T/through.csv lie inside solids" "$T/err" \
  && grep -q "^(10 of 40 points lie inside solids: drift and popping leave them out)" "$T/out" \
  && pass "--path through a solid: 10 points inside, left out" || fail "--path through a solid (rc $rc): $(cat "$T/out" "$T/err")"
/usr/bin/python3 - "$T/pt.jsonl" <<'PY' || fail "--path through a solid, JSON: $(cat "$T/pt.jsonl")"
import json, sys
j = json.loads(open(sys.argv[1]).read().splitlines()[-1])
assert j["points_inside"] == 10 and 1 <= j["drift_points"] <= 8, j
# The worst grid shift is one of the steps 'any step' counts: never larger
# (a shift from inside the block read more than every step did).
assert j["pop_shift"] <= j["pop_any_step"], (j["pop_shift"], j["pop_any_step"])
PY
# The same block with z up, read without --up: a note names the fix.
awk '$1 == "v" { print "v", $2, $4, $3; next } { print }' "$T/block.obj" > "$T/block-z.obj"
"$WALK" bench --path "$T/through.csv" --scene "$T/block-z.obj" --samples 1 --out "$T/pz" > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && grep -q "note: $T/block-z.obj is flat along z but read with y up (the default): .* pass --up z" "$T/err" \
  && pass "--scene that looks z-up without --up: noted" || fail "z-up note (rc $rc): $(cat "$T/err")"
"$WALK" bench --path "$T/through.csv" --path "$T/bad.csv" --out "$T/pb" > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 2 ] && grep -q -F "gi-walk: --path: given twice (it takes one value)" "$T/err" \
  && pass "--path twice -> 2" || fail "--path twice (rc $rc): $(cat "$T/err")"
printf '0,1,2,3\n0.1,1,2\n' > "$T/bad.csv"
"$WALK" bench --extent 300 --path "$T/bad.csv" --out "$T/pb" > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 2 ] && grep -q -F "gi-walk: --path: $T/bad.csv:2: expected t,x,y,z (four finite numbers), got '0.1,1,2'" "$T/err" \
  && pass "bad path line -> 2, named" || fail "bad path line (rc $rc): $(cat "$T/err")"
# --up without --scene: refused (the city is y up; it was taken and ignored).
"$WALK" bench --extent 200 --path "$T/through.csv" --up z --out "$T/upz" > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 2 ] && grep -q -F "gi-walk: --up: applies to a --scene file (the city is y up)" "$T/err" \
  && pass "--up without --scene -> 2" || fail "--up without --scene (rc $rc): $(cat "$T/err")"
# --res as gi-bake takes it: 18 passed, wrote the paths' CSVs, then failed (1) at the first bake.
"$WALK" bench --extent 200 --res 18 --seconds 1 --out "$T/r18" > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 2 ] && [ ! -e "$T/r18" ] && grep -q -F "gi-walk: --res: expected a multiple of 4 in 8..256, got '18'" "$T/err" \
  && pass "--res 18 -> 2 before any output" || fail "--res 18 (rc $rc): $(cat "$T/err")"
"$WALK" bench --scene "$T/bad.csv" --out "$T/pb" > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 2 ] && grep -q -- "--scene: bench takes a scene file with --path FILE only" "$T/err" \
  && pass "--scene without --path -> 2" || fail "--scene without --path (rc $rc): $(cat "$T/err")"

# A step past Embree's ray range (1e20) aborted the bench; now it is refused, named.
printf '0,0,1.7,0\n0.1,1e20,1.7,0\n' > "$T/far.csv"
"$WALK" bench --extent 300 --path "$T/far.csv" --samples 1 --out "$T/pf" > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 1 ] && grep -q "1e+20" "$T/err" && pass "a step at 1e20 -> 1, named" || fail "step at 1e20: exit $rc: $(cat "$T/err")"
# A point past 1e9 units is refused before any move, named with the reason:
# at 2e9 the path was replayed up to it (only its move failed, naming no
# point), and 1e39 (finite) was "not finite".
for v in 2e9 1e39; do
  printf '0,0,1.7,0\n0.1,1,1.7,0\n0.2,%s,1.7,0\n0.3,2,1.7,0\n' $v > "$T/far.csv"
  "$WALK" bench --extent 300 --path "$T/far.csv" --samples 1 --out "$T/pf" > /dev/null 2> "$T/err"; rc=$?
  [ $rc -eq 1 ] && grep -q -F "gi-walk: $T/far.csv: point 3 of 4 (t = 0.2 s) at (" "$T/err" \
    && grep -q "anchor: viewpoint is more than 1e9 units from the scene" "$T/err" \
    && pass "a point at $v -> 1, named before any move" || fail "point at $v: exit $rc: $(cat "$T/err")"
done

"$WALK" bench --help > "$T/out" 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && grep -q "^usage: gi-walk bench" "$T/out" && pass "bench --help -> usage, 0" ||
  fail "bench --help: exit $rc: $(cat "$T/err")"
"$WALK" --version > "$T/out" 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && grep -q "^gi-walk [0-9]" "$T/out" && grep -q "^cpu path: " "$T/out" && pass "--version -> 0" ||
  fail "--version: exit $rc: $(cat "$T/out" "$T/err")"

"$WALK" bench --paths-only --out /proc/gi-walk-test > "$T/out" 2> "$T/err"; rc=$?
[ $rc -eq 1 ] && grep -q -F "gi-walk: --out: cannot create '/proc/gi-walk-test'" "$T/err" &&
  pass "uncreatable --out -> 1, named" || fail "uncreatable --out: exit $rc: $(cat "$T/err")"
finish
