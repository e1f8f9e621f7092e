# bad_files.sh: hostile scene files (OBJ, PLY, glTF: missing, empty,
# truncated, binary junk, NaN/Inf coordinates, out-of-range indices, huge
# face counts) make gi-bake exit 1 within 60 s with a message naming the
# file, and leave no output (and no temporary) behind; an output file that
# already exists is left exactly as it was.
. "$(dirname "$0")/common.sh"

PLY_HEAD='ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n'
GLTF='{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],"meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],"buffers":[{"byteLength":44,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA="}],"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],"accessors":[{"bufferView":0,"componentType":5126,"count":COUNT,"type":"VEC3"},{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}]}'

mkdir -p "$T/in" "$T/out"
: > "$T/in/empty.obj"; : > "$T/in/empty.ply"; : > "$T/in/empty.gltf"
python3 -c "import random,sys; random.seed(5); sys.stdout.buffer.write(bytes(random.randrange(256) for _ in range(4096)))" > "$T/in/junk.obj"
cp "$T/in/junk.obj" "$T/in/junk.ply"; cp "$T/in/junk.obj" "$T/in/junk.gltf"; cp "$T/in/junk.obj" "$T/in/junk.glb"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2' > "$T/in/truncated.obj"
printf 'v nan 0 0\nv 1 inf 0\nv 0 1 -inf\nf 1 2 3\n' > "$T/in/nan.obj"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n' > "$T/in/index.obj"
printf "${PLY_HEAD}0 0 0\n1 0 0\n" > "$T/in/truncated.ply"
printf "${PLY_HEAD}nan 0 0\n1 inf 0\n0 1 -inf\n3 0 1 2\n" > "$T/in/nan.ply"
printf "${PLY_HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n" > "$T/in/index.ply"
printf 'ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 900000000\nproperty list uchar int vertex_indices\nend_header\n' > "$T/in/huge.ply"
echo "$GLTF" | sed 's/COUNT/3/' | head -c 300 > "$T/in/truncated.gltf"
echo "$GLTF" | sed 's/COUNT/1000000000/' > "$T/in/huge.gltf"
# A sparse accessor claiming 1e9 replaced elements over 4 stored: assimp
# 5.2 copied them before checking (a heap overread under ASan).
SPARSE='{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],"meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":2},{"attributes":{"POSITION":0},"indices":3}]}],"buffers":[{"byteLength":176,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAQAAAAAAAAAAAAACAQAAAAAAAAIBAAAAAAAAAAAAAAIBAAADAPwAAQEAAAMA/AAAgQAAAQEAAAMA/AAAgQAAAQEAAACBAAADAPwAAQEAAACBAAAACAAEAAAADAAIABAAFAAYABAAGAAcABAAFAAYABwAAAMA/AABgQAAAwD8AACBAAABgQAAAwD8AACBAAABgQAAAIEAAAMA/AABgQAAAIEA="}],"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":96},{"buffer":0,"byteOffset":96,"byteLength":24},{"buffer":0,"byteOffset":120,"byteLength":8},{"buffer":0,"byteOffset":128,"byteLength":48}],"accessors":[{"bufferView":0,"componentType":5126,"count":8,"type":"VEC3","min":[0,0,0],"max":[4,3.5,4],"sparse":{"count":SCOUNT,"indices":{"bufferView":2,"componentType":5123},"values":{"bufferView":3}}},{"bufferView":1,"componentType":5123,"count":12,"type":"SCALAR"},{"bufferView":1,"byteOffset":0,"componentType":5123,"count":6,"type":"SCALAR"},{"bufferView":1,"byteOffset":12,"componentType":5123,"count":6,"type":"SCALAR"}]}'
echo "$SPARSE" | sed 's/SCOUNT/1000000000/' > "$T/in/sparse.gltf"

# expect_bad FILE: exit 1, message names FILE, no output or temporary left.
expect_bad() {
  f=$1
  timeout 60 "$BIN" "$f" --at 0,0,0 --levels 2 --res 8 --exr "$T/out/probe.exr" --vdb "$T/out/cascades.vdb" \
    > "$T/stdout" 2> "$T/err"; rc=$?
  if [ $rc -eq 124 ]; then fail "$f: gi-bake hung (killed after 60 s)"; return; fi
  if [ $rc -ne 1 ]; then fail "$f: exited $rc, expected 1: $(cat "$T/err")"; return; fi
  grep -q -F "$f" "$T/err" || { fail "$f: message does not name the file: $(cat "$T/err")"; return; }
  left=$(ls -A "$T/out")
  [ -z "$left" ] || { fail "$f: left output behind: $left"; rm -f "$T"/out/*; return; }
  pass "$(basename "$f") -> 1: $(head -n 1 "$T/err")"
}

expect_bad "$T/in/sparse.gltf"
grep -q -F "glTF accessor 0: sparse count must be 1..8" "$T/err" && pass "sparse count past the accessor's: said so" \
  || fail "sparse.gltf: $(cat "$T/err")"
echo "$SPARSE" | sed 's/SCOUNT/4/' > "$T/sparse-ok.gltf"
timeout 60 "$BIN" "$T/sparse-ok.gltf" --levels 2 --res 8 --bounces 1 > /dev/null 2> "$T/err" && pass "sparse.count 4: baked" \
  || fail "sparse-ok.gltf: $(cat "$T/err")"
# A line loop whose indices pass its vertex count beside a good triangle:
# assimp 5.2 crashed on it (a segfault); points and lines are no surface,
# so they leave the file before assimp reads it and the triangle bakes.
echo "$GLTF" | sed 's/COUNT/3/' | sed 's/"indices":1}\]/"indices":1},{"attributes":{"POSITION":2},"indices":1,"mode":2}]/' \
  | sed 's/"type":"SCALAR"}\]/"type":"SCALAR"},{"bufferView":0,"componentType":5126,"count":1,"type":"VEC3"}]/' \
  > "$T/loop.gltf"
timeout 60 "$BIN" "$T/loop.gltf" --at 0.3,0.3,0.5 --levels 2 --res 8 --bounces 1 > "$T/loop.out" 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && grep -q "1 triangles kept" "$T/loop.out" && pass "line loop past its vertices beside a triangle: baked" \
  || fail "loop.gltf: rc $rc $(cat "$T/err") $(grep kept "$T/loop.out")"
expect_bad "$T/in/missing.obj"
expect_bad "$T/in/missing.ply"
expect_bad "$T/in/missing.gltf"
for f in "$T"/in/*; do expect_bad "$f"; done
# A FIFO: its open waited for a writer forever (gi-bake hung); it is no
# regular file, refused at once like a folder or /dev/null.
mkfifo "$T/fifo.obj" && expect_bad "$T/fifo.obj"

# A failing run must not touch an output that already exists.
printf 'precious' > "$T/out/probe.exr"
printf 'precious' > "$T/out/cascades.vdb"
timeout 60 "$BIN" "$T/in/junk.obj" --exr "$T/out/probe.exr" --vdb "$T/out/cascades.vdb" > /dev/null 2>&1; rc=$?
[ $rc -eq 1 ] || fail "junk.obj over existing outputs exited $rc, expected 1"
[ "$(cat "$T/out/probe.exr")" = precious ] && [ "$(cat "$T/out/cascades.vdb")" = precious ] \
  && pass "existing outputs left intact by a failing run" || fail "a failing run changed existing outputs"
[ -z "$(find "$T/out" -name '*.tmp.*')" ] && pass "no temporary files" || fail "temporary files left in $T/out"

# An unwritable output (its folder does not exist) fails the run, names the
# path, and leaves the other output absent rather than half-written.
make_box_scene
timeout 120 "$BIN" "$T/box.obj" --at 2,2,2 --levels 2 --res 8 --bounces 1 --exr "$T/out2/probe.exr" \
  > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 1 ] && grep -q -F "$T/out2/probe.exr" "$T/err" && pass "unwritable --exr -> 1: $(head -n 1 "$T/err")" \
  || fail "unwritable --exr exited $rc: $(cat "$T/err")"

# An OBJ whose material library is missing, or whose usemtl names a
# material no library defines, still bakes (grey, as assimp reads it) but
# says so, naming the library and the material; a file whose materials are
# all found says nothing.
mkdir -p "$T/mtl"
printf 'mtllib lost.mtl\nv 0 0 0\nv 4 0 0\nv 0 4 1\nusemtl wall\nf 1 2 3\n' > "$T/mtl/lost.obj"
printf 'newmtl wall\nKd 0.5 0.5 0.5\n' > "$T/mtl/here.mtl"
printf 'mtllib here.mtl\nv 0 0 0\nv 4 0 0\nv 0 4 1\nusemtl wal\nf 1 2 3\nusemtl wall\nf 1 3 2\n' > "$T/mtl/typo.obj"
printf 'mtllib here.mtl\nv 0 0 0\nv 4 0 0\nv 0 4 1\nusemtl wall\nf 1 2 3\n' > "$T/mtl/fine.obj"
timeout 60 "$BIN" "$T/mtl/lost.obj" --levels 2 --res 8 --bounces 1 > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && grep -q -F "material library '$T/mtl/lost.mtl' cannot be read (No such file or directory)" "$T/err" \
  && grep -q -F "material 'wall' is used but defined in none of its material libraries" "$T/err" \
  && pass "missing MTL -> baked, both warned" || fail "missing MTL (rc $rc): $(cat "$T/err")"
timeout 60 "$BIN" "$T/mtl/typo.obj" --levels 2 --res 8 --bounces 1 > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && grep -q -F "material 'wal' is used but defined in none" "$T/err" && ! grep -q "'wall'" "$T/err" \
  && pass "usemtl typo -> warned, the defined one not" || fail "usemtl typo (rc $rc): $(cat "$T/err")"
timeout 60 "$BIN" "$T/mtl/fine.obj" --levels 2 --res 8 --bounces 1 > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && ! grep -q "warning" "$T/err" && pass "materials all found -> no warning" \
  || fail "fine.obj (rc $rc): $(cat "$T/err")"

# An MTL colour of one number is grey (the MTL format: g and b equal r;
# assimp read "Kd 0.7" as red and failed the whole OBJ on "Kd 0.7 "); one
# of two numbers is an error naming the library and its line.
make_box_scene
mkdir -p "$T/one"
sed 's/^mtllib box.mtl/mtllib one.mtl/' "$T/box.obj" > "$T/one/one.obj"
for blank in '' ' '; do
  printf "newmtl white\nKd 0.7$blank\nnewmtl lamp\nKd 0$blank\nKe 10$blank\n" > "$T/one/one.mtl"
  timeout 60 "$BIN" "$T/one/one.obj" --at 2,2,2 --levels 2 --res 8 --bounces 1 --json > "$T/one.json" 2> "$T/err"; rc=$?
  one=$(python3 -c "import json,sys; print(*json.load(open(sys.argv[1]))['probe']['irradiance'])" "$T/one.json" 2>&1)
  # shellcheck disable=SC2086
  set -- $one
  [ $rc -eq 0 ] && [ $# -eq 3 ] && [ "$1" = "$2" ] && [ "$1" = "$3" ] && python3 -c "import sys; sys.exit(not float(sys.argv[1]) > 1)" "$1" \
    && pass "MTL colours of one number ('Kd 0.7$blank', 'Ke 10$blank') -> grey: $one" \
    || fail "one-number MTL, blank '$blank' (rc $rc): $one $(cat "$T/err")"
done
printf 'newmtl white\nKd 0.7 0.6\nnewmtl lamp\nKe 10 10 10\n' > "$T/one/one.mtl"
timeout 60 "$BIN" "$T/one/one.obj" --at 2,2,2 --levels 2 --res 8 --bounces 1 > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 1 ] && grep -q -F "material library '$T/one/one.mtl' line 2: 'Kd' needs 1 or 3 numbers" "$T/err" \
  && pass "MTL colour of two numbers -> 1: $(cat "$T/err")" || fail "two-number MTL (rc $rc): $(cat "$T/err")"

# Blender's Collada export writes an emitter's colour without its strength:
# said once, naming the material; the same file from another tool is not.
dae() { # TOOL FILE: a floor and an emissive quad above it, with an ambient light
  cat > "$2" <<DAE
<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
<asset><contributor><authoring_tool>$1</authoring_tool></contributor><up_axis>Y_UP</up_axis></asset>
<library_lights><light id="A"><technique_common><ambient><color>1 1 1</color></ambient></technique_common></light></library_lights>
<library_effects><effect id="e"><profile_COMMON><technique sid="c"><lambert><emission><color>1 0.8 0.6 1</color>
</emission><diffuse><color>0.5 0.5 0.5 1</color></diffuse></lambert></technique></profile_COMMON></effect>
<effect id="f"><profile_COMMON><technique sid="c"><lambert><diffuse><color>0.5 0.5 0.5 1</color></diffuse></lambert>
</technique></profile_COMMON></effect></library_effects>
<library_materials><material id="glow" name="glow"><instance_effect url="#e"/></material>
<material id="floor" name="floor"><instance_effect url="#f"/></material></library_materials>
<library_geometries><geometry id="g"><mesh><source id="p"><float_array id="pa" count="24">0 0 0 4 0 0 4 0 4 0 0 4
1 2 1 3 2 1 3 2 3 1 2 3</float_array><technique_common><accessor source="#pa" count="8" stride="3"><param name="X"
type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
<vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
<triangles material="floor" count="2"><input semantic="VERTEX" source="#v" offset="0"/><p>0 2 1 0 3 2</p></triangles>
<triangles material="glow" count="2"><input semantic="VERTEX" source="#v" offset="0"/><p>4 5 6 4 6 7</p></triangles>
</mesh></geometry></library_geometries>
<library_visual_scenes><visual_scene id="s"><node id="n"><instance_geometry url="#g"><bind_material><technique_common>
<instance_material symbol="floor" target="#floor"/><instance_material symbol="glow" target="#glow"/>
</technique_common></bind_material></instance_geometry></node><node id="la"><instance_light url="#A"/></node>
</visual_scene></library_visual_scenes><scene><instance_visual_scene url="#s"/></scene></COLLADA>
DAE
}
dae "Blender 3.4.1" "$T/mtl/blender.dae"
dae "Maya 2024" "$T/mtl/maya.dae"
timeout 60 "$BIN" "$T/mtl/blender.dae" --at 2,0.5,2 --levels 2 --res 8 --bounces 1 > "$T/dae.out" 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && [ "$(grep -c "Blender's Collada export writes an emitter's colour without its strength" "$T/err")" = 1 ] \
  && grep -q -F "material 'glow'" "$T/err" && grep -q "1 light skipped: area and ambient" "$T/dae.out" \
  && pass "Blender Collada emitter -> warned once; ambient light skipped, said" \
  || fail "blender.dae (rc $rc): $(cat "$T/err") $(grep skipped "$T/dae.out")"
timeout 60 "$BIN" "$T/mtl/maya.dae" --at 2,0.5,2 --levels 2 --res 8 --bounces 1 > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && ! grep -q "warning" "$T/err" && pass "another tool's Collada emitter -> no warning" \
  || fail "maya.dae (rc $rc): $(cat "$T/err")"
finish
