# batch_hash.sh: gi-bake --grid's bake hash covers what the bake read, not
# only the scene file: a glTF's external .bin and a material's texture
# swapped under --resume refuse the old tiles, and shards of the two merge
# to nothing; a comment added to the scene file keeps the hash (and the
# tiles); shards baked on the two CPU paths (their answers differ by
# float rounding) do not merge. The hash took the scene file's bytes and
# material colours: a moved wall in geo.bin or a mirrored map_Kd image kept
# it, --resume said "0 baked, N resumed" and wrote the old scene's bake.
. "$(dirname "$0")/common.sh"
Q="--grid 1 --res 8 --levels 2 --bounces 1 --cones 4 --samples 1 --probe-samples 4 --threads 1"

# common.sh's closed box (its lamp lights it, no sky: the effect plan's
# text is the same for both) with a low partition at x = 1 (geo_a.bin) or
# x = 3 (geo_b.bin): the same bounds and grid points, other answers.
# Textured scene: a floor and a wall whose map_Kd is black | white
# (tex_a.png) or mirrored.
python3 - "$T" <<'PY'
import json, os, struct, sys, zlib
T = sys.argv[1]
def geo(x):
    # The closed box of common.sh (walls facing in), its lamp, and a low partition at x.
    c = [(0, 0, 0), (4, 0, 0), (4, 0, 4), (0, 0, 4), (0, 4, 0), (4, 4, 0), (4, 4, 4), (0, 4, 4)]
    box = [(1, 4, 3, 2), (5, 6, 7, 8), (1, 5, 8, 4), (2, 3, 7, 6), (1, 2, 6, 5), (4, 8, 7, 3)]
    pos = c + [(1.5, 3.9, 1.5), (2.5, 3.9, 1.5), (2.5, 3.9, 2.5), (1.5, 3.9, 2.5)]
    pos += [(x, 0, 1), (x, 2, 1), (x, 2, 3), (x, 0, 3)]
    quads = [[i - 1 for i in q] for q in box] + [[12, 13, 14, 15], [15, 14, 13, 12]]
    tri = lambda q: [q[0], q[1], q[2], q[0], q[2], q[3]]
    walls = [i for q in quads for i in tri(q)]
    lamp = tri([8, 9, 10, 11])
    idx = walls + lamp
    return (b"".join(struct.pack("<3f", *p) for p in pos) + struct.pack("<%dI" % len(idx), *idx),
            len(pos), len(walls), len(lamp))
for name, x in (("geo_a.bin", 1.0), ("geo_b.bin", 3.0)):
    data, nv, nw, nl = geo(x)
    open(os.path.join(T, name), "wb").write(data)
g = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
     "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0},
                                {"attributes": {"POSITION": 0}, "indices": 2, "material": 1}]}],
     "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.7, 0.7, 1], "metallicFactor": 0}},
                   {"pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0},
                    "emissiveFactor": [1, 1, 1]}],
     "buffers": [{"byteLength": len(data), "uri": "geo.bin"}],
     "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 12 * nv},
                     {"buffer": 0, "byteOffset": 12 * nv, "byteLength": 4 * nw},
                     {"buffer": 0, "byteOffset": 12 * nv + 4 * nw, "byteLength": 4 * nl}],
     "accessors": [{"bufferView": 0, "componentType": 5126, "count": nv, "type": "VEC3",
                    "min": [0, 0, 0], "max": [4, 4, 4]},
                   {"bufferView": 1, "componentType": 5125, "count": nw, "type": "SCALAR"},
                   {"bufferView": 2, "componentType": 5125, "count": nl, "type": "SCALAR"}]}
json.dump(g, open(os.path.join(T, "scene.gltf"), "w"))
def png(path, rgb):  # one row of 8-bit RGB pixels
    raw = b"\0" + bytes(c for p in rgb for c in p)
    chunk = lambda t, d: struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
    ihdr = struct.pack(">IIBBBBB", len(rgb), 1, 8, 2, 0, 0, 0)
    open(path, "wb").write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw)) +
                           chunk(b"IEND", b""))
png(os.path.join(T, "tex_a.png"), [(0, 0, 0), (255, 255, 255)])
png(os.path.join(T, "tex_b.png"), [(255, 255, 255), (0, 0, 0)])
open(os.path.join(T, "room.mtl"), "w").write("newmtl wall\nKd 1 1 1\nmap_Kd tex.png\n")
open(os.path.join(T, "room.obj"), "w").write("""mtllib room.mtl
usemtl wall
v 0 0 0
v 0 0 4
v 4 0 4
v 4 0 0
v 0 4 0
v 4 4 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
f 1/1 2/2 3/3
f 1/1 3/3 4/4
f 1/1 4/2 6/3
f 1/1 6/3 5/4
""")
PY

hash_of() { sed -n 's/.*"bake_hash": "\([0-9a-f]*\)".*/\1/p' "$1"; }

# resume_refused WHAT SCENE FILE A B: a --resume bake with FILE = A, then
# with FILE = B into the same folder: exit 1, the old tile named, no EXR
# (B bakes other answers); a fresh bake with B has another hash; the two's
# shards do not merge.
resume_refused() {
  what=$1 scene=$2 file=$3 a=$4 b=$5 d="$T/ck-$1"
  cp "$T/$a" "$T/$file"
  "$BIN" "$T/$scene" $Q --resume "$d" --shard 0/2 --exr "$T/$what-a.exr" --manifest "$T/$what-a.json" \
    > /dev/null 2> "$T/$what-a.err" || { cat "$T/$what-a.err" >&2; fail "$what: first bake failed"; return; }
  cp "$T/$b" "$T/$file"
  "$BIN" "$T/$scene" $Q --resume "$d" --shard 0/2 --exr "$T/$what-r.exr" > /dev/null 2> "$T/$what-r.err"; rc=$?
  if [ $rc -eq 1 ] && grep -q "tile-.*belongs to a different bake" "$T/$what-r.err" && [ ! -e "$T/$what-r.exr" ]; then
    pass "$what: --resume after $file changed refuses the old tiles"
  else fail "$what: --resume after $file changed: rc $rc: $(tail -2 "$T/$what-r.err")"; fi
  "$BIN" "$T/$scene" $Q --shard 0/2 --exr "$T/$what-b0.exr" > /dev/null 2>&1 || fail "$what: fresh bake failed"
  cmp -s "$T/$what-a.exr" "$T/$what-b0.exr" && fail "$what: the two $file bake the same (the test proves nothing)"
  "$BIN" "$T/$scene" $Q --shard 1/2 --exr "$T/$what-b.exr" --manifest "$T/$what-b.json" > /dev/null 2>&1 \
    || fail "$what: second bake failed"
  ha=$(hash_of "$T/$what-a.json") hb=$(hash_of "$T/$what-b.json")
  [ -n "$ha" ] && [ "$ha" != "$hb" ] && pass "$what: another $file, another hash ($ha, $hb)" \
    || fail "$what: $file changed, hash $ha kept ($hb)"
  "$BIN" merge --exr "$T/$what-m.exr" "$T/$what-a.exr" "$T/$what-b.exr" 2> "$T/$what-m.err"; rc=$?
  [ $rc -eq 1 ] && grep -q "different bake" "$T/$what-m.err" && [ ! -e "$T/$what-m.exr" ] \
    && pass "$what: shards of the two $file merge to nothing" || fail "$what: merge: rc $rc: $(cat "$T/$what-m.err")"
}
resume_refused gltf scene.gltf geo.bin geo_a.bin geo_b.bin
resume_refused texture room.obj tex.png tex_a.png tex_b.png

# A comment in the OBJ loads the same scene: the same hash, every tile resumed.
cp "$T/tex_a.png" "$T/tex.png"
"$BIN" "$T/room.obj" $Q --resume "$T/ck-c" --exr "$T/c1.exr" --manifest "$T/c1.json" > /dev/null 2>&1 \
  || fail "comment: first bake failed"
echo "# a comment changes no answer" >> "$T/room.obj"
"$BIN" "$T/room.obj" $Q --resume "$T/ck-c" --exr "$T/c2.exr" --manifest "$T/c2.json" > /dev/null 2> "$T/c2.err"; rc=$?
[ $rc -eq 0 ] && [ "$(hash_of "$T/c1.json")" = "$(hash_of "$T/c2.json")" ] && ! grep -q 'source=baked' "$T/c2.err" \
  && cmp -s "$T/c1.exr" "$T/c2.exr" && pass "a comment added to the OBJ: same hash, every tile resumed" \
  || fail "comment: rc $rc, hashes $(hash_of "$T/c1.json") $(hash_of "$T/c2.json")"

# The CPU path: shards of the two paths are two bakes, and merge says why.
GI_CPU_PATH=x86-64-v3 "$BIN" "$T/room.obj" $Q --shard 0/2 --exr "$T/v3.exr" > /dev/null 2>&1; rc=$?
if [ $rc -eq 2 ]; then skip "this CPU has no x86-64-v3 path: shards of two paths not compared"
else
  GI_CPU_PATH=baseline "$BIN" "$T/room.obj" $Q --shard 1/2 --exr "$T/bl.exr" > /dev/null 2>&1 \
    || fail "baseline shard failed"
  "$BIN" merge --exr "$T/p.exr" "$T/v3.exr" "$T/bl.exr" 2> "$T/p.err"; rc=$?
  [ $rc -eq 1 ] && grep -q "different bake" "$T/p.err" && grep -q "cpu path baseline" "$T/p.err" && [ ! -e "$T/p.exr" ] \
    && pass "shards of the x86-64-v3 and baseline paths: merge refuses, naming the paths" \
    || fail "two CPU paths: merge rc $rc: $(cat "$T/p.err")"
fi
finish
