# base-build.sh: sourced by the benches that compare this tree with an older
# revision. base_gi_bake REV NAME builds gi-bake at REV once, from a git
# worktree at out/NAME-src into out/NAME-build (its own CMake rules, Release),
# and sets BASE_BIN to it; returns 1 (saying why) when it cannot. Needs ROOT,
# OUT and a say function from the caller.
base_gi_bake() {
  bb_rev=$1; bb_src="$OUT/$2-src"; bb_bld="$OUT/$2-build"
  BASE_BIN="$bb_bld/bin/gi-bake"
  [ -x "$BASE_BIN" ] && return 0
  if [ ! -d "$bb_src" ]; then
    git -C "$ROOT" worktree add --detach "$bb_src" "$bb_rev" > /dev/null 2>&1 ||
      { say "cannot check out $bb_rev into $bb_src (is this a git clone with history?)"; return 1; }
  fi
  say "building $2 ($bb_rev) in $bb_bld, once"
  (cmake -S "$bb_src" -B "$bb_bld" -DCMAKE_BUILD_TYPE=Release > "$OUT/$2-build.log" 2>&1 &&
    cmake --build "$bb_bld" -j "$(nproc)" --target gi-bake >> "$OUT/$2-build.log" 2>&1) ||
    { say "building $2 failed (see $OUT/$2-build.log)"; return 1; }
}
