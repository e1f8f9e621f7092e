# client_walk.sh: gi-client walk against a real gi-server (city extent 300,
# quality low): the printed counts (steps, cells crossed, refresh cycles
# closed, errors) for a path whose answers are known, the JSON summary,
# pacing by the t column, the session deleted at the end, and bad path
# lines named by file:line.
. "$(dirname "$0")/common.sh"
SERVER="$(dirname "$BIN")/gi-server"
[ -x "$SERVER" ] || { skip "gi-server not built next to gi-client"; exit 77; }
start_city_server "$SERVER" 30
URL=http://127.0.0.1:$PORT
unset GI_TOKEN GI_SERVER
W() { "$BIN" --server "$URL" --timeout 60 walk city --quality low "$@" > "$T/out" 2> "$T/err"; }

# 20 steps standing at the start (the session's bake is that anchor's cold
# bake already: no slice runs, nothing crosses), then 4 jumps of 50 m: each
# crosses a cell and moves level 0 by more than its extent (47 m at low),
# which rebuilds it and re-bakes at once, closing a cycle (gi_move.h).
{
  echo "# t,x,y,z"
  for k in $(seq 0 19); do echo "$k,5,1.7,3"; done
  echo "20,55,1.7,3  # 50 m east"
  echo "21,105,1.7,3"
  echo ""
  echo "22,5,1.7,3"
  echo "23,55,1.7,3"
} > "$T/path.csv"
W --path "$T/path.csv" --rate 0; rc=$?
[ $rc -eq 0 ] && pass "walk -> 0" || fail "walk: exit $rc: $(cat "$T/err")"
grep -q "^walk city: 24 steps, 4 crossed a cell, 4 cycles closed, 0 errors, " "$T/out" ||
  fail "walk counts: $(cat "$T/out")"
grep -q "^latency ms: p50 [0-9.]*  p90 [0-9.]*  p99 [0-9.]*  max [0-9.]*  mean [0-9.]*$" "$T/out" ||
  fail "walk latency line: $(cat "$T/out")"
cat "$T/out"

# --json: one object with the same counts; percentiles ordered; paced by t
# (5 steps 0.1 s apart take at least 0.4 s).
printf '0,5,1.7,3\n0.1,5.1,1.7,3\n0.2,5.2,1.7,3\n0.3,5.3,1.7,3\n0.4,5.4,1.7,3\n' > "$T/slow.csv"
W --path "$T/slow.csv" --json; rc=$?
[ $rc -eq 0 ] && pass "walk --json -> 0" || fail "walk --json: exit $rc: $(cat "$T/err")"
/usr/bin/python3 - "$T/out" <<'PY' || fail "walk --json: $(cat "$T/out")"
import json, sys
j = json.load(open(sys.argv[1]))
l = j["latency_ms"]
assert j["steps"] == 5 and j["errors"] == 0 and j["cycles"] == 0 and not j["interrupted"], j
assert 0 < l["p50"] <= l["p90"] <= l["p99"] <= l["max"], l
assert j["elapsed_s"] >= 0.4, j
assert len(j["session"]) == 32, j
PY

# Both sessions were deleted: none open, two deleted.
"$BIN" --server "$URL" metrics > "$T/m" 2> /dev/null
grep -q "^gi_sessions_open 0$" "$T/m" || fail "sessions left open: $(grep session "$T/m")"
grep -q "^gi_sessions_deleted_total 2$" "$T/m" || fail "sessions not deleted: $(grep session "$T/m")"

# Bad lines: file:line and exit 2, before any request.
printf '0,1,2,3\n# fine\n1,2,x,4\n' > "$T/bad.csv"
W --path "$T/bad.csv"; rc=$?
[ $rc -eq 2 ] && pass "bad path line -> 2" || fail "bad path line: exit $rc"
grep -q -F "gi-client: --path: $T/bad.csv:3: expected t,x,y,z (four finite numbers), got '1,2,x,4'" "$T/err" ||
  fail "bad line message: $(cat "$T/err")"
printf '1,1,2,3\n0.5,1,2,3\n' > "$T/back.csv"
W --path "$T/back.csv"; rc=$?
[ $rc -eq 2 ] && grep -q -F "back.csv:2: t = 0.5 goes back in time" "$T/err" && pass "time going back -> 2" ||
  fail "time going back: exit $rc: $(cat "$T/err")"
W; rc=$?
[ $rc -eq 2 ] && grep -q -F "'walk' needs --path FILE" "$T/err" && pass "no --path -> 2" || fail "no --path: exit $rc"
"$BIN" --server "$URL" metrics > "$T/m" 2> /dev/null
grep -q "^gi_sessions_created_total 2$" "$T/m" || fail "a refused walk opened a session: $(grep created "$T/m")"

# A coordinate printed with an exponent (1e+06) arrives whole: a query's '+'
# reads as a space, and the step was a 400 before the walk encoded it.
printf '0,5,1.7,3\n1,1000000,1.7,3\n' > "$T/far.csv"
W --path "$T/far.csv" --rate 0; rc=$?
[ $rc -eq 0 ] && grep -q "^walk city: 2 steps, 1 crossed a cell, 1 cycles closed, 0 errors, " "$T/out" &&
  pass "a step at x = 1e+06 -> answered" || fail "step at 1e+06: exit $rc: $(cat "$T/out" "$T/err")"

# A spreadsheet's CSV: a header line of column names and CRLF line ends.
# The header is skipped on the first line only; later it is a bad line.
printf 't_s, x , y,z\r\n0,5,1.7,3\r\n0.1,5.1,1.7,3\r\n' > "$T/hdr.csv"
W --path "$T/hdr.csv" --rate 0; rc=$?
[ $rc -eq 0 ] && grep -q "^walk city: 2 steps, 0 crossed a cell, 0 cycles closed, 0 errors, " "$T/out" &&
  pass "header line and CRLF -> 2 steps" || fail "header line: exit $rc: $(cat "$T/out" "$T/err")"
printf '0,5,1.7,3\nt,x,y,z\n' > "$T/hdr2.csv"
W --path "$T/hdr2.csv"; rc=$?
[ $rc -eq 2 ] && grep -q -F "hdr2.csv:2: expected t,x,y,z (four finite numbers), got 't,x,y,z'" "$T/err" &&
  pass "header after a step -> 2" || fail "late header: exit $rc: $(cat "$T/err")"
printf 't,x,y\n0,5,1.7,3\n' > "$T/hdr3.csv"
W --path "$T/hdr3.csv"; rc=$?
[ $rc -eq 2 ] && grep -q -F "hdr3.csv:1: expected t,x,y,z (four finite numbers), got 't,x,y'" "$T/err" &&
  pass "three-name header -> 2" || fail "three-name header: exit $rc: $(cat "$T/err")"

# A step due 1e308 s on is waited for (till Ctrl-C here), not taken at
# once: its wait converted to time_t out of range and did not wait at all.
# The walk's clock starts after the client's start-up and first step, which
# took 0.56 s of a 3 s timeout under ASan in CI: 5 s leaves room for them.
printf '0,5,1.7,3\n1e308,5.1,1.7,3\n' > "$T/late.csv"
timeout -s INT 5 "$BIN" --server "$URL" --timeout 60 walk city --quality low --path "$T/late.csv" --json \
  > "$T/out" 2> "$T/err"
/usr/bin/python3 - "$T/out" <<'PY' && pass "a step due at t = 1e308 is waited for" || fail "late step: $(cat "$T/out" "$T/err")"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["steps"] == 1 and j["interrupted"] and j["elapsed_s"] >= 2.5, j
PY
finish
