#!/bin/sh
# valgrind memcheck on a small bake: the CLI tests' closed box with an area
# light, 2 levels of 8^3, one bounce, EXR and VDB written, and a glTF
# triangle (assimp's path). Fails on any
# memcheck error or definite leak. Usage: valgrind-bake.sh path/to/gi-bake
. "$(dirname "$0")/../cli/common.sh"
command -v valgrind >/dev/null 2>&1 || { echo "valgrind-bake: valgrind is not installed (apt-get install valgrind)" >&2; exit 1; }
make_box_scene
valgrind --tool=memcheck --error-exitcode=99 --leak-check=full --errors-for-leak-kinds=definite \
  --show-leak-kinds=definite --track-origins=yes --suppressions="$(dirname "$0")/valgrind.supp" \
  "$BIN" "$T/box.obj" --at 2,2,2 --res 8 --levels 2 --bounces 1 --samples 4 --probe-samples 16 --threads 2 \
  --exr "$T/box.exr" --vdb "$T/box.vdb" > "$T/out.txt" 2> "$T/valgrind.txt"
rc=$?
grep -E "ERROR SUMMARY|definitely lost|indirectly lost|possibly lost" "$T/valgrind.txt"
if [ "$rc" -ne 0 ]; then
  cat "$T/valgrind.txt" >&2
  fail "memcheck on the small bake exited $rc"
fi
[ -s "$T/box.exr" ] && [ -s "$T/box.vdb" ] || fail "the bake under valgrind did not write its EXR and VDB"
# A glTF goes through assimp's meshes (add_meshes), which the OBJ above
# does not: it read an unset texture-coordinate set per material.
valgrind --tool=memcheck --error-exitcode=99 --leak-check=full --errors-for-leak-kinds=definite \
  --show-leak-kinds=definite --track-origins=yes --suppressions="$(dirname "$0")/valgrind.supp" \
  "$BIN" "$(dirname "$0")/../fuzz/corpus/scene/emissive_strength.gltf" --res 8 --levels 2 --bounces 1 --samples 4 \
  --probe-samples 16 --threads 2 > "$T/out.txt" 2> "$T/valgrind.txt"
rc=$?
grep -E "ERROR SUMMARY" "$T/valgrind.txt"
[ "$rc" -eq 0 ] || { cat "$T/valgrind.txt" >&2; fail "memcheck on the glTF bake exited $rc"; }
finish
