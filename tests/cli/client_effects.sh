# client_effects.sh: gi-client --set effects=NAME:on|off|auto[,...] against a
# real gi-server (city extent 300, quality low): malformed values exit 2
# naming --set: effects before any request; lighting and probes answers
# say the override in their gi.effects header, and a cascade with sky:off
# is another cascade than the default, while sky:auto is the default's.
. "$(dirname "$0")/common.sh"
SERVER="$(dirname "$BIN")/gi-server"
[ -x "$SERVER" ] || { skip "gi-server not built next to gi-client"; exit 77; }
unset GI_TOKEN GI_SERVER

# bad VALUE MESSAGE: --set effects=VALUE exits 2 with exactly MESSAGE (no server needed).
bad() {
  "$BIN" --server http://127.0.0.1:9 lighting city --at 5,1.7,3 --set "effects=$1" -o "$T/bad.exr" \
    > "$T/out" 2> "$T/err"
  rc=$?
  if [ $rc -eq 2 ] && [ "$(head -n 1 "$T/err")" = "gi-client: --set: effects: $2" ]; then
    pass "effects=$1 -> 2"
  else
    fail "effects=$1: exit $rc, stderr '$(cat "$T/err")'"
  fi
}
bad sky "expected NAME:on|off|auto[,...], got 'sky'"
bad sky:of "expected on, off or auto after 'sky:', got 'of'"
bad fog:off "unknown effect 'fog' (sun, local_lights, sky, emissive, bounce, specular, ao)"
bad sky:off,sky:on "effect 'sky' given twice"
bad sky:off, "empty entry (expected NAME:on|off|auto[,...]), got 'sky:off,'"
bad 'sky:off"' "expected on, off or auto after 'sky:', got 'off\"'"
"$BIN" scene city --set effects=sky:off > "$T/out" 2> "$T/err"; rc=$?
[ $rc -eq 2 ] && grep -q "^gi-client: --set: does not apply to 'scene'" "$T/err" && pass "scene takes no --set" ||
  fail "scene --set effects: exit $rc, $(cat "$T/err")"

start_city_server "$SERVER" 30
URL=http://127.0.0.1:$PORT
C() { "$BIN" --server "$URL" --timeout 60 "$@" --quality low > "$T/out" 2> "$T/err"; }
# effect FILE NAME: "ran (why)" or "skipped (why)" for NAME in an EXR's gi.effects.
effect() { grep -a -o "$2=[a-z]* ([^)]*)" "$1" | head -n 1 | sed "s/^$2=//"; }

C lighting city --at 5,1.7,3 -o "$T/default.exr"; rc=$?
[ $rc -eq 0 ] || fail "lighting: exit $rc, $(cat "$T/err")"
case $(effect "$T/default.exr" sky) in
  "ran ("*) pass "the default plan runs the sky" ;;
  *) fail "default sky: '$(effect "$T/default.exr" sky)'" ;;
esac
C lighting city --at 5,1.7,3 --set effects=sky:off,ao:on -o "$T/off.exr"; rc=$?
[ $rc -eq 0 ] || fail "lighting effects=sky:off,ao:on: exit $rc, $(cat "$T/err")"
[ "$(effect "$T/off.exr" sky)" = "skipped (turned off by the request)" ] && pass "lighting: sky:off reached the server" ||
  fail "lighting sky: '$(effect "$T/off.exr" sky)'"
case $(effect "$T/off.exr" ao) in
  "ran (requested"*) pass "lighting: ao:on reached the server" ;;
  *) fail "lighting ao: '$(effect "$T/off.exr" ao)'" ;;
esac

# probes: the knobs go in the JSON body, effects as a string.
printf '5 1.7 3\n6 1.7 3\n' > "$T/pts.txt"
C probes city --points "$T/pts.txt" --set effects=sky:off --set bounces=1 -o "$T/p.exr"; rc=$?
[ $rc -eq 0 ] || fail "probes: exit $rc, $(cat "$T/err")"
[ "$(effect "$T/p.exr" sky)" = "skipped (turned off by the request)" ] && pass "probes: sky:off reached the server" ||
  fail "probes sky: '$(effect "$T/p.exr" sky)'"

# cascades: a VDB holds no effect header; the cascade itself differs.
C cascades city --at 5,1.7,3 -o "$T/default.vdb"; rc=$?
[ $rc -eq 0 ] || fail "cascades: exit $rc, $(cat "$T/err")"
C cascades city --at 5,1.7,3 --set effects=sky:off -o "$T/off.vdb"; rc=$?
[ $rc -eq 0 ] && grep -q "^X-GI-Cache: miss" "$T/err" || fail "cascades sky:off: exit $rc, $(cat "$T/err")"
[ -s "$T/off.vdb" ] && ! cmp -s "$T/default.vdb" "$T/off.vdb" && pass "cascades: sky:off baked another cascade" ||
  fail "cascades: sky:off gave no VDB or the default's bytes"
C cascades city --at 5,1.7,3 --set effects=sky:auto -o "$T/auto.vdb"; rc=$?
[ $rc -eq 0 ] && cmp -s "$T/default.vdb" "$T/auto.vdb" && pass "cascades: sky:auto is the default" ||
  fail "cascades sky:auto: exit $rc, $(cat "$T/err")"

# walk: the session's knobs in the query, as lighting's.
printf '0,5,1.7,3\n0.1,5.1,1.7,3\n' > "$T/path.csv"
C walk city --path "$T/path.csv" --rate 0 --json --set effects=sky:off; rc=$?
[ $rc -eq 0 ] && grep -q '"errors": *0' "$T/out" && pass "walk with effects=sky:off" ||
  fail "walk effects: exit $rc, $(cat "$T/out" "$T/err")"
finish
