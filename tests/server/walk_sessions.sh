#!/bin/sh
# walk_sessions.sh: gi-client walk keeps walking when a request is dropped
# or the server ends its session (city extent 300).
#   - a step that times out on the client (--timeout 0.2) while its move
#     jumps from empty space into the city (a cold bake's work, ~1 s at
#     quality high) does not end the session: the later steps are answered
#     in the same session (1 error, 0 reopened);
#   - a pause longer than the TTL: the step after it finds the session gone
#     (404), a new one is opened there, said on stderr and counted, and the
#     walk goes on (0 errors, 1 reopened, exit 0).
# Usage: sh walk_sessions.sh path/to/gi-server path/to/gi-client
set -u
SERVER=${1:?usage: sh walk_sessions.sh path/to/gi-server path/to/gi-client}
CLIENT=${2:?usage: sh walk_sessions.sh path/to/gi-server path/to/gi-client}
# The CLI tests' helpers (T, fail, pass, finish, start_city_server), with gi-client as their BIN.
set -- "$CLIENT"
. "$(dirname "$0")/../cli/common.sh"
# The first case's server keeps idle sessions 60 s: the steps after the jump
# come 15 s later, long after its move ends even under ASan (5x slower);
# both times stretch by GI_TEST_SLOWDOWN (make tsan: 4, TSan is ~15x slower).
SLOW=${GI_TEST_SLOWDOWN:-1}
start_city_server "$SERVER" $((60 * SLOW))
URL=http://127.0.0.1:$PORT
unset GI_TOKEN GI_SERVER
# check FILE PYTHON-ASSERTION: the --json summary in FILE satisfies it.
check() { /usr/bin/python3 -c "import json, sys; j = json.load(open(sys.argv[1])); assert $2, j" "$1"; }
metric() { "$CLIENT" --server "$URL" metrics 2> /dev/null | sed -n "s/^$1 //p"; }

# Opened in empty space (a bake of nothing), then a jump into the city that
# outlasts the client's 0.2 s timeout, then small steps once it has ended.
GAP=$((15 * SLOW))
printf '0,5000,1.7,0\n0.5,0,1.7,0\n%s,0.1,1.7,0\n%s.1,0.2,1.7,0\n%s.2,0.3,1.7,0\n' $GAP $GAP $GAP > "$T/enter.csv"
"$CLIENT" --server "$URL" --timeout 0.2 walk city --quality high --path "$T/enter.csv" --json > "$T/out" 2> "$T/err"
rc=$?
if [ $rc -eq 1 ] && check "$T/out" 'j["steps"] == 5 and j["errors"] == 1 and j["reopened"] == 0'; then
  pass "a timed-out far move keeps the session: $(cat "$T/out")"
else
  fail "timed-out far move: exit $rc: $(cat "$T/out" "$T/err")"
fi
grep -q "HTTP 404" "$T/err" && fail "a step found the session gone: $(cat "$T/err")"
[ "$(metric gi_sessions_created_total)" = 1 ] || fail "sessions created: $(metric gi_sessions_created_total)"

# A second server whose idle sessions end after 2 s, and a pause of 3.4 s:
# the session expires meanwhile.
kill $SRV 2> /dev/null; wait $SRV 2> /dev/null
rm -f "$T/port"
start_city_server "$SERVER" 2
URL=http://127.0.0.1:$PORT
printf '0,5,1.7,3\n0.1,5.1,1.7,3\n3.5,5.2,1.7,3\n3.6,5.3,1.7,3\n' > "$T/pause.csv"
"$CLIENT" --server "$URL" walk city --quality low --path "$T/pause.csv" --json > "$T/out" 2> "$T/err"
rc=$?
if [ $rc -eq 0 ] && check "$T/out" 'j["steps"] == 4 and j["errors"] == 0 and j["reopened"] == 1'; then
  pass "a pause past the TTL reopens the session: $(cat "$T/out")"
else
  fail "pause past the TTL: exit $rc: $(cat "$T/out" "$T/err")"
fi
grep -q "gi-client: walk: session [0-9a-f]* has ended (HTTP 404); opening a new one at 5.2,1.7,3$" "$T/err" ||
  fail "reopening not said on stderr: $(cat "$T/err")"
[ "$(metric gi_sessions_expired_total)" = 1 ] || fail "sessions expired: $(metric gi_sessions_expired_total)"
[ "$(metric gi_sessions_created_total)" = 2 ] || fail "sessions created: $(metric gi_sessions_created_total)"
[ "$(metric gi_sessions_open)" = 0 ] || fail "sessions left open: $(metric gi_sessions_open)"
# The text summary says it too.
"$CLIENT" --server "$URL" walk city --quality low --path "$T/pause.csv" > "$T/out" 2> "$T/err"
grep -q "^walk city: 4 steps, .*, 0 errors, 1 sessions reopened, " "$T/out" || fail "text summary: $(cat "$T/out")"
finish
