# cpu_path.sh: GI_CPU_PATH picks the cone march's build (baseline,
# x86-64-v3, auto; unset or empty is auto), and any other value stops
# gi-bake with exit 2 and a line naming the variable, the value and the
# accepted values, before it writes anything: a typo used to pass silently
# for a forced path. gi-server, gi-walk and gi-accuracy --version name the
# path as gi-bake does.
. "$(dirname "$0")/common.sh"

# version VALUE: gi-bake --version with GI_CPU_PATH=VALUE; rc, out, err.
version() { GI_CPU_PATH=$1 "$BIN" --version > "$T/out" 2> "$T/err"; rc=$?; }

(unset GI_CPU_PATH; "$BIN" --version > "$T/auto" 2> "$T/err") || fail "--version without GI_CPU_PATH failed"
auto=$(sed -n 's/^cpu path: //p' "$T/auto")
case $auto in
  baseline | x86-64-v3) pass "unset: the $auto path" ;;
  *) fail "unset: cpu path '$auto'" ;;
esac
for v in "" auto; do
  version "$v"
  [ $rc -eq 0 ] && grep -qx "cpu path: $auto" "$T/out" && [ ! -s "$T/err" ] && pass "'$v' is auto ($auto)" ||
    fail "'$v': exit $rc, $(cat "$T/out" "$T/err")"
done
version baseline
[ $rc -eq 0 ] && grep -qx "cpu path: baseline" "$T/out" && pass "baseline" || fail "baseline: exit $rc, $(cat "$T/out" "$T/err")"
version x86-64-v3
if [ "$auto" = x86-64-v3 ]; then
  [ $rc -eq 0 ] && grep -qx "cpu path: x86-64-v3" "$T/out" && pass "x86-64-v3" ||
    fail "x86-64-v3: exit $rc, $(cat "$T/out" "$T/err")"
else
  # Auto took baseline: this CPU (or build) has no v3 path to force.
  [ $rc -eq 2 ] && grep -q "^gi-bake: GI_CPU_PATH=x86-64-v3, but this CPU or build cannot run" "$T/err" &&
    pass "x86-64-v3 on a CPU without it -> 2" || fail "x86-64-v3 without it: exit $rc, $(cat "$T/out" "$T/err")"
fi

# Typos, other names and other cases are refused, named, with what is accepted.
for v in baselin avx2 BASELINE x86-64-v4 " baseline"; do
  version "$v"
  want="gi-bake: GI_CPU_PATH='$v' is not recognised: expected baseline, x86-64-v3 or auto (auto, the default when"
  want="$want unset, takes $auto on this CPU)"
  if [ $rc -eq 2 ] && [ ! -s "$T/out" ] && [ "$(cat "$T/err")" = "$want" ]; then
    pass "'$v' -> 2"
  else
    fail "'$v': exit $rc, stdout '$(cat "$T/out")', stderr '$(cat "$T/err")'"
  fi
done

# Every tool that marches says its path the same way: gi-server printed
# its version alone. Its first line names the tool, its second the path.
for tool in gi-server gi-walk gi-accuracy; do
  exe="$(dirname "$BIN")/$tool"
  [ -x "$exe" ] || { fail "$tool not built next to gi-bake"; continue; }
  for v in "" baseline; do
    GI_CPU_PATH=$v "$exe" --version > "$T/out" 2> "$T/err"; rc=$?
    want=$auto
    [ -n "$v" ] && want=$v
    if [ $rc -eq 0 ] && sed -n 1p "$T/out" | grep -q "^$tool [0-9][^ ]* (.*)\$" && [ "$(sed -n 2p "$T/out")" = "cpu path: $want" ] &&
      [ "$(wc -l < "$T/out")" -eq 2 ]; then
      pass "$tool --version with '$v': cpu path: $want"
    else
      fail "$tool --version with '$v': exit $rc, stdout '$(cat "$T/out")', stderr '$(cat "$T/err")'"
    fi
  done
done

# A bake with a bad value writes nothing.
make_box_scene
GI_CPU_PATH=avx2 "$BIN" "$T/box.obj" --at 2,2,2 --levels 2 --res 8 --exr "$T/box.exr" > "$T/out" 2> "$T/err"
rc=$?
[ $rc -eq 2 ] && [ ! -e "$T/box.exr" ] && grep -q "GI_CPU_PATH='avx2'" "$T/err" && pass "bake with avx2 -> 2, no EXR" ||
  fail "bake with avx2: exit $rc, $(ls "$T"), $(cat "$T/err")"
finish
