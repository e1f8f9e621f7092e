# walk_paths.sh: gi-walk bench --paths-only on cities it was not tuned for
# (extents 200 m and 2500 m): it creates the --out folder with its parents,
# writes both paths as t,x,y,z with 601 points 0.1 s apart at the walk's
# and the drive's speed (1.4 and 14 m/s, eye 1.7 and 1.2 m; a corner's step
# is a shorter chord), and names an --out it cannot create.
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
"$WALK" bench --paths-only --out /proc/gi-walk-test > "$T/out" 2> "$T/err"; rc=$?
[ $rc -eq 1 ] && grep -q -F "gi-walk: --out: cannot create '/proc/gi-walk-test'" "$T/err" &&
  pass "uncreatable --out -> 1, named" || fail "uncreatable --out: exit $rc: $(cat "$T/err")"
finish
