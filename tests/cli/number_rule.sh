# number_rule.sh: gi-bake and gi-client apply the ONE number rule of
# tools/common/toolargs.h to the same strings: an integer is -?(0|[1-9][0-9]*), a
# number a plain finite decimal, a list exactly three numbers separated by
# commas; no '+', blanks, hex, inf/nan, trailing bytes or overflow. Each
# input goes to an integer, a number and a triple option of both tools, with
# an output in a missing folder: an accepted value gets past the parser and
# fails on the output (exit 1), a refused one exits 2 naming the option.
# Neither tool loads a scene or connects anywhere.
. "$(dirname "$0")/common.sh"
CLIENT=$(dirname "$BIN")/gi-client
[ -x "$CLIENT" ] || { skip "no gi-client beside $BIN"; exit 77; }
export GI_SERVER=http://127.0.0.1:1
unset GI_TOKEN
NOWHERE="$T/no-such-dir/out.exr"

# run NAME EXPECTED-RC OPTION-IN-MESSAGE CMD...: exit code and, for 2, the message.
run() {
  name=$1 want=$2 opt=$3; shift 3
  "$@" > "$T/out" 2> "$T/err"; rc=$?
  if [ $rc -ne "$want" ]; then fail "$name: exited $rc, expected $want: $(head -n 1 "$T/err")"; return; fi
  if [ "$want" -eq 2 ] && ! grep -q -F -e "$opt" "$T/err"; then
    fail "$name: message does not name $opt: $(head -n 1 "$T/err")"; return
  fi
  pass "$name -> $rc"
}

# integer VALUE RC: gi-bake --levels, gi-client --set levels=.
integer() {
  run "gi-bake --levels '$1'" "$2" --levels "$BIN" city --levels "$1" --exr "$NOWHERE"
  run "gi-client --set 'levels=$1'" "$2" --set "$CLIENT" lighting city --at 1,2,3 --set "levels=$1" -o "$NOWHERE"
}
# number VALUE RC: gi-bake --voxel, gi-client --set voxel=.
number() {
  run "gi-bake --voxel '$1'" "$2" --voxel "$BIN" city --voxel "$1" --exr "$NOWHERE"
  run "gi-client --set 'voxel=$1'" "$2" --set "$CLIENT" lighting city --at 1,2,3 --set "voxel=$1" -o "$NOWHERE"
}
# triple VALUE RC: --at of both.
triple() {
  run "gi-bake --at '$1'" "$2" --at "$BIN" city --at "$1" --exr "$NOWHERE"
  run "gi-client --at '$1'" "$2" --at "$CLIENT" lighting city --at "$1" -o "$NOWHERE"
}

for v in 7 1 8; do integer "$v" 1; done
for v in 07 +7 " 7" "7 " 7x 0x7 7.0 1e1 "" -- 99999999999999999999 -99999999999999999999; do integer "$v" 2; done
for v in 0.5 .5 5. 2e-1 1E+1 007.25; do number "$v" 1; done
for v in +0.5 " 0.5" 0.5x 0x1 0x1p-1 nan inf -inf 1e999 "" 1e 0.5,1; do number "$v" 2; done
for v in 1,2,3 -1.5,.5,2e1 0,0,-0; do triple "$v" 1; done
for v in +1,2,3 "1, 2,3" 1,2 1,2,3, 1,,3 0x1,2,3 nan,0,0 1,2,inf 1e999,0,0 "1;2;3"; do triple "$v" 2; done
finish
