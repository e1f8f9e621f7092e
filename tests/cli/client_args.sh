# client_args.sh: gi-client's argument errors exit 2 naming the option, before
# any connection is tried (the server URL points at a closed port, so a
# request that slipped through would exit 1, not 2). Then connection errors:
# exit 1, the message names the URL, an existing output stays untouched.
. "$(dirname "$0")/common.sh"
CLOSED=http://127.0.0.1:1   # tcpmux: nothing listens there
export GI_SERVER=$CLOSED
unset GI_TOKEN

# expect_usage NAME ARGS...: exit 2, stderr names NAME, nothing on stdout.
expect_usage() {
  name=$1; shift
  "$BIN" "$@" > "$T/out" 2> "$T/err"; rc=$?
  if [ $rc -ne 2 ]; then fail "'$*' exited $rc, expected 2: $(head -n 1 "$T/err")"; return; fi
  grep -q -F -e "$name" "$T/err" || { fail "'$*': message does not name $name: $(cat "$T/err")"; return; }
  [ -s "$T/out" ] && { fail "'$*' wrote to stdout"; return; }
  pass "'$*' -> 2: $(head -n 1 "$T/err")"
}

O="$T/o.exr"
expect_usage COMMAND
expect_usage "unknown command 'frobnicate'" frobnicate
expect_usage "unknown option '--bogus'" health --bogus
expect_usage "unknown option '-x'" -x health
expect_usage "'--server' needs a value" health --server
expect_usage "'-o' needs a value" health -o
expect_usage "'--at' needs a value" lighting city -o "$O" --at
expect_usage "unexpected argument 'extra'" health extra
expect_usage "missing scene ID" scene
expect_usage "missing JOBID" job
expect_usage --server --server ftp://x health
expect_usage --server --server "http://" health
expect_usage --server --server "http://a b" health
GI_SERVER=localhost:8080 expect_usage GI_SERVER health
expect_usage --timeout --timeout 0 health
expect_usage --timeout --timeout -3 health
expect_usage --timeout --timeout nan health
expect_usage --timeout --timeout inf health
expect_usage --timeout --timeout 5s health
# The tools' one number rule (tools/common/toolargs.h), as in gi-bake.
expect_usage --timeout --timeout +5 health
expect_usage --timeout --timeout " 5" health
expect_usage --timeout --timeout 1e999 health
expect_usage --timeout --timeout "" health
expect_usage --token --token "a b" health
expect_usage --token-file --token x --token-file "$T/tok" health
printf '\n\n' > "$T/empty-token"
expect_usage --token-file --token-file "$T/empty-token" health
GI_TOKEN="two words" expect_usage GI_TOKEN health
# lighting / cascades
expect_usage --at lighting city -o "$O"
expect_usage --at lighting city --at 1,2 -o "$O"
expect_usage --at lighting city --at a,b,c -o "$O"
expect_usage --at lighting city --at nan,0,0 -o "$O"
expect_usage --at lighting city --at 1,2,inf -o "$O"
expect_usage --at lighting city --at 1e999,0,0 -o "$O"
expect_usage --at lighting city --at "1,2,3," -o "$O"
expect_usage -o lighting city --at 1,2,3
expect_usage --kind lighting city --at 1,2,3 --kind lightmap -o "$O"
expect_usage --quality lighting city --at 1,2,3 --quality best -o "$O"
expect_usage --set lighting city --at 1,2,3 --set levels -o "$O"
expect_usage --set lighting city --at 1,2,3 --set =3 -o "$O"
expect_usage "unknown key 'colour'" lighting city --at 1,2,3 --set colour=1 -o "$O"
expect_usage "levels" lighting city --at 1,2,3 --set levels=x -o "$O"
expect_usage "levels" lighting city --at 1,2,3 --set levels=0 -o "$O"
expect_usage "res" lighting city --at 1,2,3 --set res=3.5 -o "$O"
expect_usage "res" lighting city --at 1,2,3 --set res=0x20 -o "$O"
expect_usage "voxel" lighting city --at 1,2,3 --set voxel=nan -o "$O"
expect_usage "voxel" lighting city --at 1,2,3 --set voxel=-1 -o "$O"
expect_usage "bounces" lighting city --at 1,2,3 --set bounces=-1 -o "$O"
expect_usage "--set: levels" lighting city --at 1,2,3 --set levels=+3 -o "$O"
expect_usage "--set: levels" lighting city --at 1,2,3 --set "levels= 3" -o "$O"
expect_usage "--set: levels" lighting city --at 1,2,3 --set levels=3x -o "$O"
expect_usage "--set: seed" lighting city --at 1,2,3 --set seed=99999999999999999999 -o "$O"
expect_usage "--set: voxel" lighting city --at 1,2,3 --set voxel=+1 -o "$O"
expect_usage "--set: voxel" lighting city --at 1,2,3 --set voxel=0x1 -o "$O"
expect_usage "--set: voxel" lighting city --at 1,2,3 --set voxel=1e999 -o "$O"
expect_usage --at lighting city --at +1,2,3 -o "$O"
expect_usage "ao" lighting city --at 1,2,3 --set ao=yes -o "$O"
# Checked by the contract's own parser (proto/request.c), in the server's words.
expect_usage "parameter 'cones': expected 4, 6, 8, 16 or 32, got 5" lighting city --at 1,2,3 --set cones=5 -o "$O"
expect_usage "parameter 'res': expected a multiple of 4" lighting city --at 1,2,3 --set res=30 -o "$O"
expect_usage "parameter 'bounces': expected 0..8" cascades city --at 1,2,3 --set bounces=9 -o "$O"
expect_usage "parameter 'cones'" probes city --points x --set cones=7 -o "$O"
expect_usage "parameter 'width'" lighting city --at 1,2,3 --kind panorama --set width=1 -o "$O"
expect_usage --at lighting city --at 0x10,2,3 -o "$O"
expect_usage "given twice" lighting city --at 1,2,3 --set res=16 --set res=32 -o "$O"
expect_usage "--at: given twice" lighting city --at 1,2,3 --at 4,5,6 -o "$O"
expect_usage "--output: given twice" lighting city --at 1,2,3 -o "$O" --output "$O.2"
expect_usage "only to --kind panorama" lighting city --at 1,2,3 --set width=64 -o "$O"
expect_usage "'probe_samples' does not apply to 'cascades'" cascades city --at 1,2,3 --set probe_samples=8 -o "$O"
expect_usage "'ao' does not apply to 'probes'" probes city --points x --set ao=1 -o "$O"
expect_usage "seed" lighting city --at 1,2,3 --set seed=0 -o "$O"
expect_usage "aperture" lighting city --at 1,2,3 --set aperture=inf -o "$O"
expect_usage "--kind: does not apply to 'cascades'" cascades city --at 1,2,3 --kind probe -o "$O"
expect_usage "--faces: does not apply to 'lighting'" lighting city --at 1,2,3 --faces -o "$O"
expect_usage "--at: does not apply to 'health'" health --at 1,2,3
expect_usage "--points: does not apply to 'lighting'" lighting city --at 1,2,3 --points x -o "$O"
# probes and the points file (gi-bake --probes format, errors name file:line)
expect_usage --points probes city -o "$O"
printf '1 2 3\n# comment\n\n4,5,6\n7 8 x\n' > "$T/pts.txt"
expect_usage "pts.txt:5" probes city --points "$T/pts.txt" -o "$O"
printf '1 2 3\n4 5 nan\n' > "$T/nan.txt"
expect_usage "nan.txt:2" probes city --points "$T/nan.txt" -o "$O"
printf '1 2 3 4\n' > "$T/four.txt"
expect_usage "four.txt:1" probes city --points "$T/four.txt" -o "$O"
printf '# only a comment\n\n' > "$T/none.txt"
expect_usage "no points" probes city --points "$T/none.txt" -o "$O"

# Unreadable files are I/O errors: exit 1, naming the file.
expect_io() {
  what=$1; shift
  "$BIN" "$@" > "$T/out" 2> "$T/err"; rc=$?
  if [ $rc -ne 1 ]; then fail "'$*' exited $rc, expected 1"; return; fi
  grep -q -F -e "$what" "$T/err" || { fail "'$*': message lacks $what: $(cat "$T/err")"; return; }
  pass "'$*' -> 1: $(head -n 1 "$T/err")"
}
expect_io "$T/missing.txt" probes city --points "$T/missing.txt" -o "$O"
expect_io "$T/no-token" --token-file "$T/no-token" health
expect_io "$T/no-dir" lighting city --at 1,2,3 -o "$T/no-dir/o.exr"

# --help documents every option and command, and exits 0.
"$BIN" --help > "$T/help" 2>&1 || fail "--help exited $?"
for w in --server GI_SERVER --token GI_TOKEN --token-file --timeout -o -q health scenes scene metrics job \
         lighting cascades probes --at --kind panorama --quality --set --faces --points --half --ao --no-wait \
         levels res voxel cones aperture step bounces samples probe_samples seed width height Server-Timing X-GI-Cache "Exit status"; do
  grep -q -F -e "$w" "$T/help" || fail "--help does not mention $w"
done
pass "--help mentions every option"

# Connection refused: exit 1, the message names the URL; the output is untouched.
echo "previous answer" > "$O"
"$BIN" -q lighting city --at 1,2,3 -o "$O" > "$T/out" 2> "$T/err"; rc=$?
if [ $rc -ne 1 ]; then fail "connection refused exited $rc, expected 1"
elif ! grep -q -F "gi-client: GET $CLOSED/v1/scenes/city/lighting?at=1,2,3" "$T/err"; then
  fail "connection refused: message lacks the URL: $(cat "$T/err")"
else pass "connection refused -> 1: $(cat "$T/err")"; fi
[ "$(cat "$O")" = "previous answer" ] || fail "a failed request changed the existing output"
ls "$T" | grep -q '\.tmp\.' && fail "a temporary file was left: $(ls "$T")"
"$BIN" --server "$CLOSED/" health > "$T/out" 2> "$T/err"; rc=$?
[ $rc -eq 1 ] && grep -q -F "$CLOSED/v1/health:" "$T/err" && pass "trailing / on --server: $(cat "$T/err")" \
  || fail "health on a closed port: rc $rc: $(cat "$T/err")"
finish
