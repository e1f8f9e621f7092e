# common.sh: helpers sourced by the CLI tests (not a test itself).
# Each test gets the gi-bake binary as $1 and a private temp dir in $T.
set -u
BIN=${1:?usage: sh test.sh path/to/gi-bake}
T=$(mktemp -d "${TMPDIR:-/tmp}/gi-cli.XXXXXX")
trap 'rm -rf "$T"' EXIT INT TERM
FAILS=0

fail() { echo "FAIL: $*" >&2; FAILS=$((FAILS + 1)); }
pass() { echo "ok: $*"; }
skip() { echo "SKIP: $*" >&2; }
finish() { [ "$FAILS" -eq 0 ] && { echo "all passed"; exit 0; }; echo "$FAILS failure(s)" >&2; exit 1; }

# A closed 4 m box (inward-facing walls) with a 1 m emissive quad under the
# ceiling: every probe inside sees light directly and by bounces.
make_box_scene() {
  cat > "$T/box.mtl" <<'MTL'
newmtl white
Kd 0.7 0.7 0.7
newmtl lamp
Kd 0 0 0
Ke 10 10 10
MTL
  cat > "$T/box.obj" <<'OBJ'
mtllib box.mtl
v 0 0 0
v 4 0 0
v 4 0 4
v 0 0 4
v 0 4 0
v 4 4 0
v 4 4 4
v 0 4 4
v 1.5 3.9 1.5
v 2.5 3.9 1.5
v 2.5 3.9 2.5
v 1.5 3.9 2.5
usemtl white
f 1 4 3 2
f 5 6 7 8
f 1 5 8 4
f 2 3 7 6
f 1 2 6 5
f 4 8 7 3
usemtl lamp
f 9 10 11 12
OBJ
}

# start_city_server SERVER TTL: a gi-server on an ephemeral port serving the
# 300 m city, 2 sessions at most, idle sessions ended after TTL seconds;
# PORT is its port; stopped on exit. Fails the test when it does not start.
start_city_server() {
  cat > "$T/s.ini" <<INI
[server]
bind = 127.0.0.1
port = 0
workers = 2
bake_threads = 2
tmp_dir = $T
[limits]
max_sessions = 2
session_ttl_s = $2
[scene city]
source = city
extent = 300
INI
  "$1" --config "$T/s.ini" --port-file "$T/port" > "$T/server.out" 2> "$T/server.log" & SRV=$!
  trap 'kill $SRV 2>/dev/null; wait $SRV 2>/dev/null; rm -rf "$T"' EXIT INT TERM
  i=0; while [ ! -s "$T/port" ] && [ $i -lt 300 ]; do sleep 0.1; i=$((i + 1)); done
  [ -s "$T/port" ] || { fail "gi-server did not start: $(cat "$T/server.log")"; finish; }
  PORT=$(cat "$T/port")
}
