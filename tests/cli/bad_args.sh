# bad_args.sh: bad arguments exit 2 naming the option; a missing scene
# file exits 1 naming the path. No scene is loaded for any of these.
. "$(dirname "$0")/common.sh"

# expect_usage OPTION-NAME ARGS...: exit 2 and the message names OPTION-NAME.
expect_usage() {
  name=$1; shift
  "$BIN" "$@" > "$T/out" 2> "$T/err"; rc=$?
  if [ $rc -ne 2 ]; then fail "'$*' exited $rc, expected 2"; return; fi
  grep -q -e "$name" "$T/err" || { fail "'$*': message does not name $name: $(cat "$T/err")"; return; }
  [ -s "$T/out" ] && { fail "'$*' wrote to stdout"; return; }
  pass "'$*' -> 2: $(head -n 1 "$T/err")"
}

expect_usage --at city --at 1,2
expect_usage --at city --at a,b,c
expect_usage --at city --at nan,0,0
expect_usage --at city --at 1,2,inf
expect_usage --at city --at "1,2,3,"
expect_usage --at city --at 1e999,0,0
expect_usage --levels city --levels 0
# The tools' one number rule (tools/common/toolargs.h): a sign may only be
# '-'; blanks, hex, trailing bytes and overflow are refused.
expect_usage --levels city --levels +5
expect_usage --levels city --levels " 5"
expect_usage --levels city --levels 5x
expect_usage --levels city --levels 0x10
expect_usage --levels city --levels ""
expect_usage --threads city --threads 99999999999999999999
expect_usage --at city --at +1,2,3
expect_usage --at city --at 0x1,2,3
expect_usage --voxel city --voxel 1e999
expect_usage --voxel city --voxel nan
expect_usage --city-seed city --city-seed +3
expect_usage --city-seed city --city-seed 18446744073709551616
expect_usage --levels city --levels 13
expect_usage --res city --res 30
expect_usage --res city --res 4
expect_usage --voxel city --voxel -1
expect_usage --cones city --cones 5
expect_usage --bounces city --bounces 9
expect_usage --threads city --threads x
expect_usage --samples city --samples 0
expect_usage --up city --up x
expect_usage --sun city --sun 0,0,0,1,1,1
expect_usage --sky city --sky 1,-1,1
expect_usage --point city --point 1,2,3,1,1
expect_usage --spot city --spot 0,5,0,0,-1,0,20,30,1,1
expect_usage --spot city --spot 0,5,0,0,-1,0,40,30,1,1,1
expect_usage --spot city --spot 0,5,0,0,0,0,20,30,1,1,1
expect_usage --city-extent city --city-extent 0
expect_usage --city-seed city --city-seed -3
expect_usage --city-detail city --city-detail 9
expect_usage --effect city --effect glow=on
expect_usage --effect city --effect sky=maybe
expect_usage --effect city --effect sky
expect_usage --at city --at
expect_usage --voxel city --voxel 1e38
expect_usage --bogus city --bogus
expect_usage SCENE
expect_usage --city-extent "$T/x.obj" --city-extent 100
# A value given twice: the second silently replaced the first (here a bake
# at res 32 where 16 was asked too; --exr wrote one file of two).
expect_usage "--res: given twice" city --res 16 --res 32
expect_usage "--exr: given twice" city --exr "$T/a.exr" --exr "$T/b.exr"
expect_usage "--effect: 'sun' given twice" city --effect sun=off --effect sun=on

printf '1 2 3\n# comment\n4 5 x\n' > "$T/pts.txt"
expect_usage "pts.txt:3" city --probes "$T/pts.txt"
# A list of comments only baked the viewpoint alone, exit 0.
printf '# 1 2 3\n\n' > "$T/nopts.txt"
expect_usage "nopts.txt' holds no points" city --probes "$T/nopts.txt"

# Coordinates past Embree's ray range (about 1.8e18) aborted the process
# (its ray.valid() assertion): a viewpoint there is refused (1, named), a
# probe or a lamp there is answered; no signal either way.
far() {
  want=$1; shift
  "$BIN" city --levels 2 --res 8 --bounces 1 "$@" > /dev/null 2> "$T/err"; rc=$?
  [ $rc -eq "$want" ] && pass "'$*' -> $rc" || fail "'$*' exited $rc (want $want): $(tail -n 2 "$T/err")"
}
far 1 --at 1e20,1.7,0
far 1 --at 1.9e18,1.7,0
printf '1e20 1 1\n0 1.7 0\n' > "$T/far.txt"
far 0 --probes "$T/far.txt"
far 0 --point 1e19,1,1,1,1,1
# Past 1e30 a lamp's position is refused (2, named): at 1e39 it went Inf in
# float and every answer NaN ('internal error: non-finite value').
far 2 --point 1e39,1,1,1,1,1
grep -q "^gi-bake: --point: position X,Y,Z must be within 1e30" "$T/err" && pass "a far lamp is named" \
  || fail "far lamp: $(cat "$T/err")"
far 2 --spot 0,-1e31,0,0,1,0,10,20,1,1,1
# A --render eye past 1e9: refused (2) before the bake, as every other bad
# camera is; it failed (1) after a whole bake.
far 2 --render 1e300,5,10,0,0,0,60,8,8 --exr "$T/far.exr"
grep -q "^gi-bake: --render: the eye (1e+300, 5, 10) is more than 1e9 units from the scene's origin on axis x" \
  "$T/err" && pass "a far --render eye is named" || fail "far --render eye: $(cat "$T/err")"
# The limit holds per axis from the scene's origin (the city's x and z are 0), as the core's camera: the
# message said "from the scene" of a distance it never checked. 1e9 - 1 renders, 1e9 + 1 is refused.
far 0 --render 999999999,5,10,0,0,0,60,4,4 --exr "$T/near.exr"
far 2 --render 5,2,-1000000001,0,0,0,60,4,4 --exr "$T/far.exr"
grep -q "^gi-bake: --render: the eye (5, 2, -1e+09) is more than 1e9 units from the scene's origin on axis z" \
  "$T/err" && pass "an eye 1e9 + 1 along z is named" || fail "eye 1e9 + 1 along z: $(cat "$T/err")"
# The core's message names its stage once ("bake: bake: the voxel size" stuttered).
far 1 --at 1e7,0,0 --voxel 1e-9
grep -q "^gi-bake: bake: the voxel size 1e-09 is too small" "$T/err" && pass "a bake error names 'bake:' once" \
  || fail "bake error: $(cat "$T/err")"

# A missing scene file is a runtime error (1) naming the file.
missing="$T/no-such-dir/missing-scene.obj"
"$BIN" "$missing" > "$T/out" 2> "$T/err"; rc=$?
if [ $rc -ne 1 ]; then fail "missing scene exited $rc, expected 1"
elif ! grep -q -F "$missing" "$T/err"; then fail "missing scene: message lacks the path: $(cat "$T/err")"
else pass "missing scene -> 1: $(head -n 1 "$T/err")"; fi
finish
