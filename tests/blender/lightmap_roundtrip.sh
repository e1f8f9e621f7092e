# lightmap_roundtrip.sh GI-BAKE: the lightmap in Blender. gi-bake bakes the
# box scene's lightmap (EXR + glTF) and renders a camera view from the
# cascade; Blender imports the glTF, applies the EXR through the second UV
# set as emission and renders the same camera; the two pictures must agree
# (mean relative error of luminance, the lamp's own pixels left out: the
# lightmap holds reflected light only). Exit 77 (skip, said loudly) when
# Blender is not installed.
. "$(dirname "$0")/../cli/common.sh"
HERE=$(cd "$(dirname "$0")" && pwd)
if ! command -v blender > /dev/null 2>&1; then
  echo "SKIP: blender is not installed: the lightmap's Blender round trip was NOT run (apt-get install blender)"
  exit 77
fi
make_box_scene
Q="--levels 4 --res 16 --probe-samples 64"
EYE=2,2,3.8 TARGET=2,1.2,0 FOV=70 W=64 H=64
# shellcheck disable=SC2086
"$BIN" "$T/box.obj" $Q --lightmap "$T/lm.exr" --uv-out "$T/lm.glb" --texel 0.05 --atlas 1024 > /dev/null 2> "$T/err" \
  || { cat "$T/err" >&2; fail "gi-bake --lightmap"; finish; }
# shellcheck disable=SC2086
"$BIN" "$T/box.obj" $Q --render "$EYE,$TARGET,$FOV,$W,$H" --exr "$T/view.exr" > /dev/null 2> "$T/err" \
  || { cat "$T/err" >&2; fail "gi-bake --render"; finish; }
blender -b --factory-startup --python "$HERE/lightmap_roundtrip.py" -- "$T/lm.glb" "$T/lm.exr" "$T/blender.exr" \
  "$EYE" "$TARGET" "$FOV" "$W" "$H" > "$T/blender.log" 2>&1 \
  || { tail -n 20 "$T/blender.log" >&2; fail "blender"; finish; }
grep "^blender:" "$T/blender.log"
python3 - "$HERE" "$T/view.exr" "$T/blender.exr" <<'PY' && pass "Blender's render matches gi-bake --render" \
  || fail "Blender's render differs from gi-bake --render"
import sys
sys.path.insert(0, sys.argv[1])
from exr_read import read
w, h, view = read(sys.argv[2])
w2, h2, bl = read(sys.argv[3])
assert (w, h) == (w2, h2), ((w, h), (w2, h2))
lum = lambda c, i: 0.2126 * c["R"][i] + 0.7152 * c["G"][i] + 0.0722 * c["B"][i]
# The lamp (radiance 10) is emission the lightmap does not hold; edges of
# the view's pixels that see it are left out with it.
errs = [abs(lum(bl, i) - lum(view, i)) / lum(view, i) for i in range(w * h) if 1e-3 < lum(view, i) < 2.0]
mre = sum(errs) / len(errs)
print("blender vs cone-traced view: %d pixels, mean relative error %.1f%%" % (len(errs), 100 * mre))
assert len(errs) > w * h // 2 and mre < 0.2, mre
PY
finish
