# client_http.sh: gi-client against a canned stand-in server
# (fake_gi_server.py): the URL and body it sends, the error line it prints
# for a JSON error, the Server-Timing / X-GI-Cache lines, temp+rename of
# downloads, and polling a probe job to its result. The real server's
# integration tests live elsewhere.
. "$(dirname "$0")/common.sh"
PY=$(command -v python3) || { skip "python3 not found"; exit 77; }
"$PY" "$(dirname "$0")/fake_gi_server.py" "$T/port" & SRV=$!
trap 'kill $SRV 2>/dev/null; rm -rf "$T"' EXIT INT TERM
i=0; while [ ! -s "$T/port" ] && [ $i -lt 100 ]; do sleep 0.1; i=$((i + 1)); done
[ -s "$T/port" ] || { fail "the stand-in server did not start"; finish; }
URL=http://127.0.0.1:$(cat "$T/port")
unset GI_TOKEN GI_SERVER
C() { "$BIN" --server "$URL" --timeout 20 "$@" > "$T/out" 2> "$T/err"; }
# check DESCRIPTION EXPECTED-RC: compares with the last C's exit status.
check() { [ "$rc" -eq "$2" ] && pass "$1 -> $rc" || fail "$1: exit $rc, expected $2; stderr: $(cat "$T/err")"; }
has() { grep -q -F -e "$2" "$1" || fail "$(basename "$1") lacks '$2': $(cat "$1")"; }
no_tmp() { ls "$T" | grep -q '\.tmp\.' && fail "temporary file left: $(ls "$T")"; true; }

C health; rc=$?; check "health" 0
has "$T/out" '"status": "ok"'
[ "$(tail -c 1 "$T/out" | od -An -c | tr -d ' ')" = '\n' ] || fail "health on stdout does not end with a newline"
C -q health -o "$T/h.json"; rc=$?; check "health -o" 0
[ "$(tail -c 1 "$T/h.json")" = "}" ] || fail "health -o must keep the exact bytes: $(cat "$T/h.json")"
C metrics; rc=$?; check "metrics" 0
has "$T/out" "gi_bakes_total 3"

# lighting: the query names every parameter, '+' is escaped, headers printed, file renamed into place.
C lighting city --at 1e+20,-2.5,3 --kind panorama --quality high --set width=512 --set height=256 \
  --set bounces=0 -o "$T/l.exr"; rc=$?; check "lighting" 0
[ "$(cat "$T/l.exr")" = "/v1/scenes/city/lighting?at=1e%2B20,-2.5,3&kind=panorama&quality=high&width=512&height=256&bounces=0" ] \
  || fail "lighting sent $(cat "$T/l.exr")"
has "$T/err" "Server-Timing: voxelize;dur=12.1, inject;dur=3"
has "$T/err" "X-GI-Cache: miss"
[ -s "$T/out" ] && fail "lighting wrote to stdout"
no_tmp
C -q cascades city --at 0,1.5,0 --faces --set levels=4 -o "$T/c.vdb"; rc=$?; check "cascades -q" 0
[ "$(cat "$T/c.vdb")" = "/v1/scenes/city/cascades.vdb?at=0,1.5,0&faces=1&levels=4" ] || fail "cascades sent $(cat "$T/c.vdb")"
[ -s "$T/err" ] && fail "-q still printed: $(cat "$T/err")"

# A server that publishes its grid: the client asks the cell URL itself
# (x: (3 - 0.5) / 2.5 = 1, y: 0, z: (-3 + 0.25) / 2.5 = -1.1 -> -2), in the
# server's parameter order; the scene request carried the quality knobs.
G=/v1/scenes/grid/cells/1,0,-2
C -q lighting grid --at 3,1,-3 --set levels=3 --set res=16 -o "$T/g.exr"; rc=$?; check "lighting by cell" 0
[ "$(cat "$T/g.exr")" = "$G/lighting?q=0123456789abcdef&kind=probe&levels=3&res=16" ] || fail "cell URL $(cat "$T/g.exr")"
C -q lighting grid --at 3,1,-3 --kind panorama --set half=1 --set height=8 -o "$T/g.exr"; rc=$?; check "panorama by cell" 0
[ "$(cat "$T/g.exr")" = "$G/lighting?q=0123456789abcdef&kind=panorama&levels=3&res=16&half=1&width=256&height=8" ] ||
  fail "panorama cell URL $(cat "$T/g.exr")"
C -q cascades grid --at 3,1,-3 --faces -o "$T/g.vdb"; rc=$?; check "cascades by cell" 0
[ "$(cat "$T/g.vdb")" = "$G/cascades.vdb?q=0123456789abcdef&levels=3&res=16&faces=1" ] || fail "vdb cell URL $(cat "$T/g.vdb")"

# Errors: the JSON error line, exit 1, the old output untouched, no temp file.
echo old > "$T/keep.exr"
C lighting nope --at 0,0,0 -o "$T/keep.exr"; rc=$?; check "404" 1
has "$T/err" "gi-client: HTTP 404 not_found: no scene 'nope'"
C lighting busy --at 0,0,0 -o "$T/keep.exr"; rc=$?; check "503" 1
has "$T/err" "gi-client: HTTP 503 overloaded: all workers busy (Retry-After: 3 s)"
C lighting html --at 0,0,0 -o "$T/keep.exr"; rc=$?; check "502 without JSON" 1
has "$T/err" "gi-client: HTTP 502: <html>Bad Gateway</html>"
C lighting trunc --at 0,0,0 -o "$T/keep.exr"; rc=$?; check "truncated download" 1
has "$T/err" "$URL/v1/scenes/trunc/lighting?at=0,0,0"
C lighting secret --at 0,0,0 -o "$T/keep.exr"; rc=$?; check "401 without a token" 1
has "$T/err" "gi-client: HTTP 401 unauthorized: a bearer token is required"
[ "$(cat "$T/keep.exr")" = old ] || fail "a failed request changed the existing output"
no_tmp
printf 'tok3n\n' > "$T/token"
C lighting secret --at 0,0,0 --token-file "$T/token" -o "$T/s.exr"; rc=$?; check "--token-file" 0
GI_TOKEN=tok3n C lighting secret --at 0,0,0 -o "$T/s2.exr"; rc=$?; check "GI_TOKEN" 0

# probes: a small set is answered at once (the fake echoes the JSON body).
printf '# two points\n1 2 3\n\n4.5,-5,0.1 # trailing comment\n' > "$T/two.txt"
C probes city --points "$T/two.txt" --at 0,1,0 --half --ao -o "$T/p.exr"; rc=$?; check "probes (200)" 0
[ "$(cat "$T/p.exr")" = '{"points":[[1,2,3],[4.5,-5,0.1]],"at":[0,1,0],"half":true,"ao":true}' ] \
  || fail "probes sent $(cat "$T/p.exr")"
has "$T/err" "X-GI-Cache: hit"
C probes city --points "$T/two.txt" --set levels=4 --set voxel=0.25 -o "$T/p.exr"; rc=$?; check "probes --set" 0
[ "$(cat "$T/p.exr")" = '{"points":[[1,2,3],[4.5,-5,0.1]],"quality":{"levels":4,"voxel":0.25}}' ] \
  || fail "probes --set sent $(cat "$T/p.exr")"
C probes city --points "$T/two.txt" --quality high --set seed=7 -o "$T/p.exr"; rc=$?; check "probes --quality --set" 0
[ "$(cat "$T/p.exr")" = '{"points":[[1,2,3],[4.5,-5,0.1]],"quality":{"preset":"high","seed":7}}' ] \
  || fail "probes --quality --set sent $(cat "$T/p.exr")"

# A larger set becomes a job: polled (one line per 10% when stderr is no tty), then downloaded.
printf '0 0 0\n1 1 1\n2 2 2\n3 3 3\n' > "$T/four.txt"
C probes city --points "$T/four.txt" -o "$T/job.exr"; rc=$?; check "probes job" 0
[ "$(cat "$T/job.exr")" = "RESULT j4" ] || fail "job result: $(cat "$T/job.exr")"
has "$T/err" "gi-client: job j4: 20% (10/40 probes"
has "$T/err" "gi-client: job j4: 100% (40/40 probes"
[ "$(grep -c '^gi-client: job j4: [0-9]*%' "$T/err")" -eq 4 ] || fail "expected 4 progress lines: $(cat "$T/err")"
no_tmp
C probes city --points "$T/four.txt" --no-wait -o "$T/nw.exr"; rc=$?; check "probes --no-wait" 0
has "$T/out" '"job": "j4"'
[ -e "$T/nw.exr" ] && fail "--no-wait wrote the output"
# --no-wait prints the job: it insisted on -o, then left it unused. A list
# answered at once is an EXR, which needs -o: said, not written to stdout.
C probes city --points "$T/four.txt" --no-wait; rc=$?; check "probes --no-wait without -o" 0
has "$T/out" '"job": "j4"'
C probes city --points "$T/two.txt" --no-wait; rc=$?; check "probes --no-wait answered at once, no -o" 1
has "$T/err" "the server answered at once (HTTP 200, an EXR, not a job): give -o OUT to keep it"
[ -s "$T/out" ] && fail "--no-wait without -o wrote an EXR to stdout: $(cat "$T/out")"
# Ctrl-C while a job is polled cancels it on the server (it ran on for nobody), exit 130.
printf '0 0 0\n1 1 1\n2 2 2\n3 3 3\n4 4 4\n5 5 5\n' > "$T/six.txt"
timeout --preserve-status -s INT 2 "$BIN" --server "$URL" --timeout 20 probes city --points "$T/six.txt" \
  -o "$T/slow.exr" > "$T/out" 2> "$T/err"; rc=$?; check "Ctrl-C while polling" 130
has "$T/err" "gi-client: job jslow: interrupted; cancelled it on the server"
[ -e "$T/slow.exr" ] && fail "an interrupted job wrote the output"
no_tmp
C job jslow; rc=$?; check "the interrupted job" 0
has "$T/out" '"state": "cancelled"'
C job j4; rc=$?; check "job JOBID" 0
has "$T/out" '"state": "queued"'
printf '0 0 0\n1 1 1\n2 2 2\n' > "$T/three.txt"
echo old > "$T/f.exr"
C -q probes city --points "$T/three.txt" -o "$T/f.exr"; rc=$?; check "failed job" 1
has "$T/err" "gi-client: job jfail failed: internal: bake failed: out of memory"
[ "$(cat "$T/f.exr")" = old ] || fail "a failed job changed the existing output"
no_tmp
finish
