# formats.sh GI-BAKE: one Blender scene, four formats, one light. Blender
# (formats.py) writes a scene with a sun, point and spot lamps, a one-sided
# emitter and its mirror image, a linked duplicate, a textured floor and
# Principled materials to glTF, FBX and Collada (and, without the lamps, to
# glTF and OBJ); gi-bake bakes each at the same viewpoint with the same
# eight probes. The same scene must read the same: FBX within 1% of glTF,
# Collada within 3% (Blender writes its materials there as Lambert ones, the
# roughness 0.2 lobe lost), OBJ within 1%; and the mirrored emitter lights
# the probe under it as its twin does (within 2%). Before this stop's import
# fixes the formats' lamps were 12.6x apart, and the mirrored emitter lit
# nothing below it. Exit 77 (skip, said loudly) when Blender is not installed.
. "$(dirname "$0")/../cli/common.sh"
HERE=$(cd "$(dirname "$0")" && pwd)
if ! command -v blender > /dev/null 2>&1; then
  echo "SKIP: blender is not installed: the formats' Blender round trip was NOT run (apt-get install blender)"
  exit 77
fi
blender -b --factory-startup --python-exit-code 1 --python "$HERE/formats.py" -- "$T" > "$T/blender.log" 2>&1 \
  || { tail -n 20 "$T/blender.log" >&2; fail "blender export"; finish; }
# Blender's (x, y, z) is (x, z, -y) in every export (y up).
printf '0 0.3 0\n-3 0.3 -3\n-1.8 0.3 -3\n2 0.5 -0.5\n-3 0.5 3\n3 0.5 3\n-2.5 0.5 -0.9\n5 1 -5\n' > "$T/pts.txt"
for f in scene.glb scene.fbx scene.dae plain.glb plain.obj; do
  timeout 120 "$BIN" "$T/$f" --at 0,1,0 --probes "$T/pts.txt" --json > "$T/$f.json" 2> "$T/$f.err" \
    || { cat "$T/$f.err" >&2; fail "gi-bake $f"; }
done
python3 - "$T" <<'PY' && pass "one Blender scene reads the same from glTF, FBX, Collada and OBJ" \
  || fail "the formats disagree"
import json, sys
t = sys.argv[1]
probes = {f: json.load(open("%s/%s.json" % (t, f)))["probes"] for f in
          ("scene.glb", "scene.fbx", "scene.dae", "plain.glb", "plain.obj")}
ok = True

def rel(a, b):
    big = max(max(p["irradiance"]) for p in b)
    return max(abs(x - y) / max(y, 1e-3 * big) for pa, pb in zip(a, b) for x, y in zip(pa["irradiance"], pb["irradiance"]))

for f, ref, tol in (("scene.fbx", "scene.glb", 0.01), ("scene.dae", "scene.glb", 0.03), ("plain.obj", "plain.glb", 0.01)):
    r = rel(probes[f], probes[ref])
    print("%s against %s: largest relative difference %.2f%% (at most %.0f%%)" % (f, ref, 100 * r, 100 * tol))
    ok &= r <= tol
# Lit by its emitters alone, the probes under the emitter and its mirror image.
a, b = probes["plain.glb"][4]["direct"][1], probes["plain.glb"][5]["direct"][1]
print("under the emitter %.4f, under its mirror image %.4f" % (a, b))
ok &= a > 0.1 and abs(a - b) <= 0.02 * a
assert all(p["in_cascade"] for ps in probes.values() for p in ps)
sys.exit(0 if ok else 1)
PY
finish
