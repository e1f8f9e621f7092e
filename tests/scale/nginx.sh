#!/usr/bin/env bash
# nginx.sh: three gi-server replicas behind nginx (configs/nginx/gi.conf), for real (issue 14).
#
# Starts 3 replicas and a 4th reference server (not behind nginx) on
# loopback ports, and nginx with configs/nginx/gi.conf (ports, cache folder
# and token rewritten by sed). Then:
#   1. a walk of 300 viewpoint requests through nginx (tests/scale/walk.py):
#      every answer 200 after one 307, byte-identical to the reference
#      server's answer for its cell URL, and each cell baked exactly once
#      across the replicas (gi_bakes_total from their /metrics);
#   2. the same walk again: served from nginx's cache, zero bakes;
#   2b. a probe job and a session walk with gi-client through nginx: every
#      poll and move reaches the replica that owns the job or session;
#   3. a walk at another seed (new cells) with replica 2 killed (SIGKILL)
#      after 100 steps: every request still 200 (nginx retries the dead
#      replica's on the next one: proxy_next_upstream), the retried ones
#      counted from nginx's log.
# Then the surviving servers must exit 0 on SIGTERM (under ASan: no report).
# Prints bakes, nginx cache hits and p50/p99 latency through nginx. Stops
# everything it started, by pid. Exit 0 pass, 1 fail, 77 skip (no nginx).
# Usage: tests/scale/nginx.sh [BUILD_DIR]
set -u
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
BUILD=${1:-$ROOT/build}
SERVER=$BUILD/bin/gi-server
PY=${PYTHON:-/usr/bin/python3}
STEPS=300
QUALITY="res=16&levels=3"
KILL_AFTER=100
TOKEN=scale-test-token-$$

NGINX=$(command -v nginx || true)
[ -z "$NGINX" ] && [ -x /usr/sbin/nginx ] && NGINX=/usr/sbin/nginx
if [ -z "$NGINX" ]; then
  echo "SKIP: nginx is not installed (make test-scale installs it: apt-get install -y nginx)"
  exit 77
fi
[ -x "$SERVER" ] || { echo "FAIL: $SERVER not built (make all)"; exit 1; }

T=$(mktemp -d /tmp/gi-scale-nginx.XXXXXX)
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null; done
  for p in "${PIDS[@]}"; do wait "$p" 2>/dev/null; done
  [ -f "$T/nginx.pid" ] && kill "$(cat "$T/nginx.pid")" 2>/dev/null
  rm -rf "$T"
}
trap cleanup EXIT
fail() { echo "FAIL: $*"; echo "--- logs in $T kept"; trap - EXIT; for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null; done; \
         [ -f "$T/nginx.pid" ] && kill "$(cat "$T/nginx.pid")" 2>/dev/null; exit 1; }

cat > "$T/gi-server.ini" <<EOF
[server]
bind = 127.0.0.1
port = 0
workers = 2
queue = 256
bake_threads = 1
[scene city]
source = city
extent = 300
EOF

# start_server NAME: starts a gi-server on an ephemeral port; sets PORT and SPID.
start_server() {
  GI_SERVER_TOKEN=$TOKEN "$SERVER" --config "$T/gi-server.ini" --port-file "$T/$1.port" > "$T/$1.log" 2>&1 &
  SPID=$!
  PIDS+=("$SPID")
  for _ in $(seq 1 300); do [ -s "$T/$1.port" ] && break; sleep 0.1; done
  [ -s "$T/$1.port" ] || fail "$1 did not start (see $T/$1.log)"
  PORT=$(cat "$T/$1.port")
}
declare -a RPORT RPID
for r in 1 2 3; do start_server "replica$r"; RPORT[$r]=$PORT; RPID[$r]=$SPID; done
start_server reference; REF_PORT=$PORT; REF_PID=$SPID
NGINX_PORT=$($PY -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')

# The shipped config with its "rewritten" lines pointed at this run.
mkdir -p "$T/cache" "$T/tmp"
sed -e "s|/var/cache/nginx/gi|$T/cache|" \
    -e "s|127.0.0.1:8081|127.0.0.1:${RPORT[1]}|" -e "s|127.0.0.1:8082|127.0.0.1:${RPORT[2]}|" \
    -e "s|127.0.0.1:8083|127.0.0.1:${RPORT[3]}|" -e "s|listen 127.0.0.1:8080|listen 127.0.0.1:$NGINX_PORT|" \
    -e "s|REPLACE_WITH_TOKEN|$TOKEN|" "$ROOT/configs/nginx/gi.conf" > "$T/gi.conf"
cat > "$T/nginx.conf" <<EOF
$( [ "$(id -u)" = 0 ] && echo "user root;" )
worker_processes 1;
pid $T/nginx.pid;
error_log $T/nginx-error.log warn;
events { worker_connections 512; }
http {
  log_format gi '\$status \$request_method \$request_uri up=\$upstream_addr upstatus=\$upstream_status cache=\$upstream_cache_status t=\$request_time';
  access_log $T/access.log gi;
  client_body_temp_path $T/tmp/body;
  proxy_temp_path $T/tmp/proxy;
  fastcgi_temp_path $T/tmp/fastcgi;
  uwsgi_temp_path $T/tmp/uwsgi;
  scgi_temp_path $T/tmp/scgi;
  include $T/gi.conf;
}
EOF
"$NGINX" -t -q -p "$T" -c "$T/nginx.conf" 2> "$T/nginx-t.log" || { cat "$T/nginx-t.log"; fail "nginx -t refused the config"; }
"$NGINX" -p "$T" -c "$T/nginx.conf" -g 'daemon off;' 2>> "$T/nginx-error.log" &
PIDS+=($!)
for _ in $(seq 1 100); do curl -s -o /dev/null "http://127.0.0.1:$NGINX_PORT/v1/health" && break; sleep 0.1; done
curl -sf -o /dev/null "http://127.0.0.1:$NGINX_PORT/v1/health" || fail "nginx does not answer on $NGINX_PORT"
echo "replicas on ${RPORT[1]} ${RPORT[2]} ${RPORT[3]}, reference on $REF_PORT, nginx $("$NGINX" -v 2>&1 | sed 's|.*/||') on $NGINX_PORT"
code=$(curl -s -o /dev/null -w '%{http_code}' "http://127.0.0.1:$NGINX_PORT/v1/scenes/city/lighting?at=0,2,0")
[ "$code" = 401 ] || fail "nginx let a request without the token through ($code)"

metric() { # metric PORT NAME: a counter summed over label sets
  curl -s -H "Authorization: Bearer $TOKEN" "http://127.0.0.1:$1/metrics" |
    awk -v n="$2" '$1 == n || index($1, n "{") == 1 { s += $2 } END { printf "%d\n", s }'
}
bakes() { local s=0; for r in "$@"; do s=$((s + $(metric "${RPORT[$r]}" gi_bakes_total))); done; echo $s; }
walk() { # walk NAME [extra walk.py args]
  local name=$1; shift
  local t0=$(date +%s%N)
  $PY "$HERE/walk.py" --port "$NGINX_PORT" --token "$TOKEN" --n $STEPS --quality "$QUALITY" --out "$T/$name.jsonl" "$@" \
    > "$T/$name.out" 2>&1 || { cat "$T/$name.out"; fail "walk $name"; }
  WALK_S=$(( ($(date +%s%N) - t0) / 1000000 ))ms
}
# summary FILE: "n=.. ok=.. cells=.. hits=.. p50=.. p99=.."
summary() {
  $PY - "$1" <<'EOF'
import json, sys
recs = [json.loads(l) for l in open(sys.argv[1])]
ms = sorted(r["ms"] for r in recs)
pct = lambda p: ms[min(len(ms) - 1, int(p * len(ms)))]
cells = {r["location"].split("/")[5] + "?" + r["location"].split("q=")[1].split("&")[0] for r in recs if r.get("location")}
hits = sum(r.get("nginx_cache") == "HIT" for r in recs)
ok = sum(r["status"] == 200 and r.get("redirect") == 307 for r in recs)
print("n=%d ok=%d cells=%d hits=%d p50=%.1f p99=%.1f" % (len(recs), ok, len(cells), hits, pct(0.5), pct(0.99)))
EOF
}
field() { echo "$1" | tr ' ' '\n' | sed -n "s/^$2=//p"; }

# ---- 1. the walk, cold ---------------------------------------------------------
walk first
S1=$(summary "$T/first.jsonl")
B1=$(bakes 1 2 3)
per=""; for r in 1 2 3; do per="$per $(metric "${RPORT[$r]}" gi_bakes_total)"; done
echo "walk 1 (cold): $S1; bakes per replica:$per = $B1; ${WALK_S}"
[ "$(field "$S1" ok)" = $STEPS ] || fail "walk 1: not every step was 307 then 200"
[ "$B1" = "$(field "$S1" cells)" ] || fail "walk 1: $B1 bakes for $(field "$S1" cells) cells (each must be baked once)"
# Every answer equals the reference server's answer for its cell URL.
$PY - "$T/first.jsonl" "$REF_PORT" "$TOKEN" <<'EOF' || fail "walk 1: an answer differs from the reference server's"
import hashlib, http.client, json, sys
recs = [json.loads(l) for l in open(sys.argv[1])]
c = http.client.HTTPConnection("127.0.0.1", int(sys.argv[2]), timeout=300)
ref, bad = {}, 0
for r in recs:
    loc = r["location"]
    if loc not in ref:
        c.request("GET", loc, headers={"Authorization": "Bearer " + sys.argv[3]})
        resp = c.getresponse()
        body = resp.read()
        ref[loc] = (resp.status, hashlib.sha256(body).hexdigest(), resp.getheader("ETag"))
    st, sha, etag = ref[loc]
    if st != 200 or sha != r["sha"] or etag != r["etag"]:
        bad += 1
        print("  differs: %s (reference %d %s %s, nginx %s %s)" % (loc, st, sha[:12], etag, r["sha"][:12], r["etag"]))
print("walk 1: %d answers byte-identical to the reference server's for their %d cell URLs" % (len(recs) - bad, len(ref)))
sys.exit(1 if bad else 0)
EOF
immutable=$(grep -c '"cache_control": "public, max-age=31536000, immutable"' "$T/first.jsonl")
[ "$immutable" = $STEPS ] || fail "walk 1: $immutable of $STEPS answers immutable"

# ---- 2. the same walk: nginx's cache, no bakes ------------------------------------
walk second
S2=$(summary "$T/second.jsonl")
B2=$(bakes 1 2 3)
echo "walk 2 (repeat): $S2; bakes $((B2 - B1)); ${WALK_S}"
[ "$(field "$S2" ok)" = $STEPS ] || fail "walk 2: not every step was 307 then 200"
[ "$B2" = "$B1" ] || fail "walk 2: $((B2 - B1)) bakes (the cache must answer)"
[ "$(field "$S2" hits)" = $STEPS ] || fail "walk 2: $(field "$S2" hits) of $STEPS answers from nginx's cache"
shas() { $PY -c 'import json, sys; [print(json.loads(l)["sha"]) for l in open(sys.argv[1])]' "$1"; }
cmp -s <(shas "$T/first.jsonl") <(shas "$T/second.jsonl") || fail "walk 2: answers differ from walk 1's"

# ---- 2b. a job and a session through nginx ----------------------------------------
# They live on the replica that made them: hashed by URL, a poll or a move
# reached another replica and read 404 (the job unknown, the session
# reopened at every step).
CLIENT=$BUILD/bin/gi-client
NG="--server http://127.0.0.1:$NGINX_PORT --token $TOKEN"
for i in $(seq 1 24); do echo "$i 1.7 $((i % 5))"; done > "$T/pts.txt"   # more than max_probes_inline: a job
"$CLIENT" $NG probes city --points "$T/pts.txt" --quality low -o "$T/job.exr" > "$T/job.out" 2>&1 \
  || fail "a probe job through nginx: $(tail -n 3 "$T/job.out")"
grep -q "job " "$T/job.out" || fail "24 points were answered inline, not as a job: $(cat "$T/job.out")"
printf 't,x,y,z\n' > "$T/walk.csv"; for i in $(seq 0 9); do echo "$i,$((3 * i)),1.7,2" >> "$T/walk.csv"; done
"$CLIENT" $NG walk city --path "$T/walk.csv" --rate 0 --quality low --json > "$T/walk.json" 2> "$T/walk.err" \
  || fail "a session walk through nginx: $(cat "$T/walk.json" "$T/walk.err")"
$PY - "$T/walk.json" <<'EOF' || fail "session walk through nginx: $(cat "$T/walk.json")"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["steps"] == 10 and j["errors"] == 0 and j["reopened"] == 0, j
EOF
echo "a 24-point job and a 10-step session walk through nginx: every poll and move on its own replica"

# ---- 3. new cells, replica 2 killed after KILL_AFTER steps ----------------------------
before=$(wc -l < "$T/access.log")
walk third --quality "$QUALITY&seed=2" --kill-pid "${RPID[2]}" --kill-after $KILL_AFTER
S3=$(summary "$T/third.jsonl")
wait "${RPID[2]}" 2>/dev/null
kill -0 "${RPID[2]}" 2>/dev/null && fail "replica 2 still runs"
retried=$(tail -n +$((before + 1)) "$T/access.log" | grep -c 'up=[^ ]*, ')
failed_up=$(tail -n +$((before + 1)) "$T/access.log" | grep -c 'upstatus=502')
B3=$(bakes 1 3)
echo "walk 3 (seed=2, replica 2 killed after $KILL_AFTER steps): $S3; retried on another replica: $retried" \
     "(attempts refused by the dead replica: $failed_up); replicas 1 and 3 have baked $B3 in all; ${WALK_S}"
[ "$(field "$S3" ok)" = $STEPS ] || fail "walk 3: $(( STEPS - $(field "$S3" ok) )) requests lost"
[ "$retried" -ge 1 ] || fail "walk 3: nginx retried nothing: was replica 2 asked at all?"

echo "nginx: walk 1 p50 $(field "$S1" p50) ms p99 $(field "$S1" p99) ms (cold, $B1 bakes for $(field "$S1" cells) cells);" \
     "walk 2 p50 $(field "$S2" p50) ms p99 $(field "$S2" p99) ms ($(field "$S2" hits) cache hits, 0 bakes);" \
     "walk 3 p50 $(field "$S3" p50) ms p99 $(field "$S3" p99) ms ($retried retried)"
# The surviving servers shut down cleanly on SIGTERM (exit 0; a sanitizer report would not be 0).
for p in "${RPID[1]}" "${RPID[3]}" "$REF_PID"; do
  kill -TERM "$p"; st=0; wait "$p" || st=$?
  [ "$st" = 0 ] || fail "gi-server $p exited $st after SIGTERM"
done
echo "PASS: nginx in front of 3 replicas"
