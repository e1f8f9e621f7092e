#!/bin/sh
# http-bench.sh: load test of gi-server's lighting endpoint with wrk.
#
#   http-bench.sh URL [PID]              bench a running server (PID: its RSS is reported)
#   http-bench.sh --start SERVER CONFIG  start SERVER --port 0 --port-file F --config CONFIG,
#                                        bench it, stop it (what `make bench-http` runs)
#
# Two runs over the same scene: "cached" asks for one viewpoint again and again
# (after one warm-up request, every answer should be X-GI-Cache: hit);
# "uncached" moves the viewpoint to a pseudo-random point within +-SPREAD on
# x and z for every request (tests/bench/http-lighting.lua), so nearly every
# request bakes. Prints requests/s, p50/p99 latency (wrk --latency), the
# X-GI-Cache counts and the server's RSS, and appends one JSON line per run to
# out/bench-http.jsonl. Like every benchmark here it never decides pass or
# fail: it exits 0 unless its own arguments are wrong (2).
#
# Environment: BENCH_SCENE (default: the first scene of /v1/scenes), BENCH_AT
# (X,Y,Z; default: the scene's default_viewpoint), BENCH_DURATION (10s, the
# cached run), BENCH_UNCACHED_DURATION (30s: a cold bake takes seconds, and
# wrk counts only requests that finish within the run),
# BENCH_CONNECTIONS (4), BENCH_THREADS (2), BENCH_SPREAD (50 world units),
# BENCH_TIMEOUT (60s, wrk's per-request limit), GI_TOKEN (bearer token).
#
# Then the soak (tests/bench/http-soak.py): SOAK_SECONDS (600; 0 skips it) of
# mixed traffic from SOAK_CLIENTS (6) threads: cache hits, misses, VDBs, probe
# jobs and DELETE cancels, with the server's RSS sampled every second; prints
# max RSS against the memory budget and any status the contract does not expect.
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
LUA="$ROOT/tests/bench/http-lighting.lua"
DUR=${BENCH_DURATION:-10s}
UDUR=${BENCH_UNCACHED_DURATION:-30s}
CONN=${BENCH_CONNECTIONS:-4}
THR=${BENCH_THREADS:-2}
SPREAD=${BENCH_SPREAD:-50}
WTIMEOUT=${BENCH_TIMEOUT:-60s}
TOKEN=${GI_TOKEN:-}
usage() { echo "usage: http-bench.sh URL [PID] | http-bench.sh --start SERVER CONFIG" >&2; exit 2; }
say() { echo "http-bench: $*" >&2; }

TMP=$(mktemp -d "${TMPDIR:-/tmp}/gi-http-bench.XXXXXX") || exit 0
SRV_PID=""
cleanup() {
  # Stops only the server this script started, by its pid.
  if [ -n "$SRV_PID" ] && kill -0 "$SRV_PID" 2> /dev/null; then
    kill -TERM "$SRV_PID" 2> /dev/null
    i=0; while kill -0 "$SRV_PID" 2> /dev/null && [ $i -lt 100 ]; do sleep 0.1; i=$((i + 1)); done
    kill -0 "$SRV_PID" 2> /dev/null && { say "server $SRV_PID ignored SIGTERM for 10 s: SIGKILL"; kill -KILL "$SRV_PID"; }
    wait "$SRV_PID" 2> /dev/null
    say "stopped the server (pid $SRV_PID)"
  fi
  rm -rf "$TMP"
}
trap cleanup EXIT
trap 'exit 0' INT TERM

[ $# -ge 1 ] || usage
if [ "$1" = --start ]; then
  [ $# -eq 3 ] || usage
  SERVER=$2 CONFIG=$3
  [ -x "$SERVER" ] || { say "no server binary at $SERVER (build it first: make); nothing measured"; exit 0; }
  [ -r "$CONFIG" ] || { say "cannot read config $CONFIG; nothing measured"; exit 0; }
  "$SERVER" --port 0 --port-file "$TMP/port" --config "$CONFIG" > "$TMP/server.log" 2>&1 &
  SRV_PID=$!
  # The port file appears once the scenes are loaded and the socket is bound.
  i=0
  while [ ! -s "$TMP/port" ]; do
    if ! kill -0 "$SRV_PID" 2> /dev/null; then
      say "the server exited before binding; its log:"; cat "$TMP/server.log" >&2; SRV_PID=""; exit 0
    fi
    [ $i -ge 1200 ] && { say "no port file after 120 s; nothing measured"; exit 0; }
    sleep 0.1; i=$((i + 1))
  done
  URL="http://127.0.0.1:$(cat "$TMP/port")"
  PID=$SRV_PID
  say "started $SERVER (pid $PID) on $URL with $CONFIG"
else
  [ $# -le 2 ] || usage
  URL=${1%/}
  PID=${2:-}
  case $URL in http://*|https://*) ;; *) say "URL must start with http:// or https://, got '$URL'"; exit 2 ;; esac
  case $PID in ''|*[!0-9]*) [ -n "$PID" ] && { say "PID must be a number, got '$PID'"; exit 2; } ;; esac
fi

command -v wrk > /dev/null 2>&1 || { say "wrk is not installed (scripts/install-deps.sh installs it); nothing measured"; exit 0; }
command -v python3 > /dev/null 2>&1 || { say "python3 is needed to read the scene list; nothing measured"; exit 0; }

# GET URL -> "STATUS X-GI-CACHE MS" then the body on stdout (python: no curl binary needed, the token as a header).
get() {
  python3 - "$1" "$TOKEN" << 'PY'
import sys, time, urllib.request
req = urllib.request.Request(sys.argv[1])
if sys.argv[2]:
    req.add_header("Authorization", "Bearer " + sys.argv[2])
t0 = time.monotonic()
try:
    with urllib.request.urlopen(req, timeout=300) as r:
        body = r.read()
        ms = (time.monotonic() - t0) * 1000
        sys.stdout.write("%d %s %.1f\n" % (r.status, r.headers.get("X-GI-Cache", "-"), ms))
        sys.stdout.write(body.decode("utf-8", "replace"))
except Exception as e:
    sys.stdout.write("000 - %s\n" % e)
PY
}

rss() {
  [ -n "$PID" ] && [ -r "/proc/$PID/status" ] || { echo "null null"; return; }
  awk '/^VmRSS:/ {r=$2} /^VmHWM:/ {h=$2} END {printf "%d %d\n", r/1024, h/1024}' "/proc/$PID/status"
}

i=0
until get "$URL/v1/health" > "$TMP/health" && head -n 1 "$TMP/health" | grep -q '^200'; do
  [ $i -ge 100 ] && { say "$URL/v1/health does not answer 200: $(head -n 1 "$TMP/health"); nothing measured"; exit 0; }
  sleep 0.1; i=$((i + 1))
done

SCENE=${BENCH_SCENE:-}
if [ -z "$SCENE" ]; then
  get "$URL/v1/scenes" > "$TMP/scenes"
  SCENE=$(tail -n +2 "$TMP/scenes" | python3 -c 'import json,sys; print(json.load(sys.stdin)["scenes"][0]["id"])' 2> /dev/null)
  [ -n "$SCENE" ] || { say "no scene in $URL/v1/scenes: $(head -c 300 "$TMP/scenes"); nothing measured"; exit 0; }
fi
AT=${BENCH_AT:-}
if [ -z "$AT" ]; then
  get "$URL/v1/scenes/$SCENE" > "$TMP/scene"
  AT=$(tail -n +2 "$TMP/scene" | python3 -c 'import json,sys; print(",".join(repr(float(v)) for v in json.load(sys.stdin)["default_viewpoint"]))' 2> /dev/null)
  [ -n "$AT" ] || { say "no default_viewpoint in $URL/v1/scenes/$SCENE: $(head -c 300 "$TMP/scene"); nothing measured"; exit 0; }
fi
case $AT in *,*,*) ;; *) say "BENCH_AT must be X,Y,Z, got '$AT'"; exit 2 ;; esac
X=${AT%%,*}; YZ=${AT#*,}; Y=${YZ%%,*}; Z=${YZ#*,}
LPATH="/v1/scenes/$SCENE/lighting"

# Warm-up: the first request for the fixed viewpoint bakes; the cached run
# then measures hits only. Its own latency is the cold figure.
get "$URL$LPATH?at=$X,$Y,$Z" > "$TMP/warm"
WARM=$(head -n 1 "$TMP/warm")
COLD_MS=$(echo "$WARM" | awk '{print $3}')
case $WARM in 200*) ;; *) say "warm-up request failed: $WARM $(tail -n +2 "$TMP/warm" | head -c 300); nothing measured"; exit 0 ;; esac

REV=$(git -C "$ROOT" rev-parse --short HEAD 2> /dev/null || echo unknown)
STAMP=$(date -u +%Y-%m-%dT%H:%M:%SZ)
CPUS=$(nproc 2> /dev/null || echo 1)
mkdir -p "$ROOT/out" && JSONL="$ROOT/out/bench-http.jsonl" || JSONL=/dev/null
set -- $(rss); RSS0=$1
echo "gi-server HTTP benchmark  rev $REV  $STAMP  $(uname -n) ($CPUS cpus)"
echo "server $URL  scene $SCENE  at $X,$Y,$Z  wrk: $THR threads, $CONN connections, $DUR cached, $UDUR uncached"
echo "first request (cold bake, X-GI-Cache: $(echo "$WARM" | awk '{print $2}')): $COLD_MS ms;  server RSS ${RSS0} MiB"

for MODE in fixed vary; do
  NAME=cached D=$DUR; [ $MODE = vary ] && NAME=uncached D=$UDUR
  echo
  echo "== $NAME ($MODE viewpoint$( [ $MODE = vary ] && echo ", +-$SPREAD on x and z"))"
  wrk -t"$THR" -c"$CONN" -d"$D" --timeout "$WTIMEOUT" --latency -s "$LUA" "$URL" \
    -- "$MODE" "$LPATH" "$X" "$Y" "$Z" "$SPREAD" "$TOKEN" > "$TMP/wrk.$MODE" 2>&1
  grep -v '^RESULT' "$TMP/wrk.$MODE"
  R=$(grep '^RESULT' "$TMP/wrk.$MODE" | head -n 1)
  if [ -z "$R" ]; then say "wrk printed no result for $NAME"; continue; fi
  set -- $(rss); RSS=$1 HWM=$2
  # RESULT k=v ... -> a summary line and a JSON line.
  echo "$R" | awk -v name="$NAME" -v rss="$RSS" -v hwm="$HWM" '{
    for (i = 2; i <= NF; i++) { split($i, kv, "="); v[kv[1]] = kv[2] }
    printf "%-8s %9.1f req/s   p50 %8.2f ms   p99 %8.2f ms   hit %s miss %s coalesced %s   non-2xx %s   errors %s   RSS %s MiB (peak %s)\n",
      name, v["rps"], v["p50_ms"], v["p99_ms"], v["hit"], v["miss"], v["coalesced"], v["non200"],
      v["socket_errors"] + v["timeouts"], rss, hwm }'
  echo "$R" | awk -v name="$NAME" -v rss="$RSS" -v hwm="$HWM" -v rev="$REV" -v stamp="$STAMP" -v scene="$SCENE" \
    -v at="$X,$Y,$Z" -v conn="$CONN" -v thr="$THR" -v cpus="$CPUS" -v cold="$COLD_MS" '{
    for (i = 2; i <= NF; i++) { split($i, kv, "="); k[i] = kv[1]; v[i] = kv[2] }
    printf "{\"bench\":\"http\",\"run\":\"%s\",\"scene\":\"%s\",\"at\":[%s],\"connections\":%d,\"wrk_threads\":%d,\"cpus\":%d,\"cold_ms\":%s",
      name, scene, at, conn, thr, cpus, cold
    for (i = 2; i <= NF; i++) printf ",\"%s\":%s", k[i], v[i]
    printf ",\"rss_mib\":%s,\"rss_peak_mib\":%s,\"git\":\"%s\",\"time\":\"%s\"}\n", rss, hwm, rev, stamp }' \
    | tee -a "$JSONL" > "$TMP/json"
done
echo
echo "JSON lines appended to $JSONL"

echo
python3 "$ROOT/tests/bench/http-soak.py" "$URL" "${PID:-0}" "$SCENE" "$X,$Y,$Z" "$TOKEN"
exit 0
