#!/bin/sh
# walk-server.sh BUILD OUT EXTENT: the server half of make bench-walk.
# Replays OUT/walk-walk.csv and OUT/walk-drive.csv with `gi-client walk
# --json` against a gi-server (ephemeral port, the city at EXTENT m) and
# prints its per-step percentiles. Skips loudly when gi-client has no walk
# command. Figures only: exits 0.
set -u
BUILD=$1 OUT=$2 EXTENT=$3
CLIENT=$BUILD/bin/gi-client SERVER=$BUILD/bin/gi-server
say() { echo "bench-walk (server): $*"; }
skip() {
  echo "bench-walk: ##########################################################"
  echo "bench-walk: SERVER PART SKIPPED: $*"
  echo "bench-walk: ##########################################################"
  exit 0
}
[ -x "$CLIENT" ] && [ -x "$SERVER" ] || skip "no $CLIENT or $SERVER"
"$CLIENT" --help 2>&1 | grep -q '\bwalk\b' || skip "this gi-client has no 'walk' command (gi-client --help does not list it)"
TMP=$(mktemp -d "${TMPDIR:-/tmp}/gi-walk-bench.XXXXXX") || exit 0
SRV_PID=""
cleanup() {
  # Stops only the server this script started, by its pid.
  if [ -n "$SRV_PID" ] && kill -0 "$SRV_PID" 2> /dev/null; then
    kill -TERM "$SRV_PID" 2> /dev/null
    i=0; while kill -0 "$SRV_PID" 2> /dev/null && [ $i -lt 100 ]; do sleep 0.1; i=$((i + 1)); done
    kill -0 "$SRV_PID" 2> /dev/null && kill -KILL "$SRV_PID"
    wait "$SRV_PID" 2> /dev/null
  fi
  rm -rf "$TMP"
}
trap cleanup EXIT
trap 'exit 0' INT TERM
cat > "$TMP/walk.ini" <<INI
[server]
bind = 127.0.0.1
port = 0
workers = 1
[scene city]
source = city
extent = $EXTENT
seed = 1
INI
"$SERVER" --port 0 --port-file "$TMP/port" --config "$TMP/walk.ini" > "$TMP/server.log" 2>&1 &
SRV_PID=$!
i=0
while [ ! -s "$TMP/port" ]; do
  kill -0 "$SRV_PID" 2> /dev/null || { cat "$TMP/server.log"; SRV_PID=""; skip "gi-server exited before binding (log above)"; }
  [ $i -ge 1200 ] && skip "gi-server wrote no port file in 120 s"
  sleep 0.1; i=$((i + 1))
done
URL="http://127.0.0.1:$(cat "$TMP/port")"
say "gi-server (pid $SRV_PID) on $URL serving the city at $EXTENT m"
for p in walk drive; do
  [ -r "$OUT/walk-$p.csv" ] || { say "no $OUT/walk-$p.csv: skipped $p"; continue; }
  say "$p: gi-client walk city --path $OUT/walk-$p.csv --json"
  if "$CLIENT" --server "$URL" walk city --path "$OUT/walk-$p.csv" --json > "$TMP/$p.json" 2> "$TMP/$p.err"; then
    cat "$TMP/$p.json"
    grep '^{' "$TMP/$p.json" | sed "s/^{/{\"bench\":\"walk-server\",\"path\":\"$p\",/" >> "$OUT/bench-walk.jsonl"
  else
    say "WARNING: gi-client walk failed for $p:"; cat "$TMP/$p.err"
  fi
  cat "$TMP/$p.err" >&2
done
exit 0
