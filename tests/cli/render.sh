# render.sh: --render draws the cascade's view beside the path-traced one:
# a PNG three views wide, an EXR with both images and the error, the JSON
# "render" figures finite; bad cameras exit 2 naming --render.
. "$(dirname "$0")/common.sh"
make_box_scene

"$BIN" "$T/box.obj" --at 2,1.5,2 --levels 3 --res 16 --bounces 1 --json \
    --render 2,2,0.3,2,2,3,70,24,16 --render-samples 4 --png "$T/view.png" --exr "$T/view.exr" \
    > "$T/out.json" 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && pass "render exits 0" || { cat "$T/err" >&2; fail "render exited $rc"; finish; }
grep -q "looks inside a solid" "$T/err" && fail "a camera in the room noted as inside a solid: $(cat "$T/err")"
python3 - "$T/out.json" "$T/view.png" <<'PY' && pass "PNG 72x16 and JSON figures" || fail "render outputs"
import json, math, struct, sys
j = json.load(open(sys.argv[1]))
assert j["outputs"]["png"] == sys.argv[2] and j["outputs"]["exr"].endswith("view.exr"), j["outputs"]
d = j["render"]
assert d["width"] == 24 and d["height"] == 16 and d["path_samples"] == 4, d
for k in ("cone_ms", "path_ms", "mean_relative_error"): assert math.isfinite(d[k]) and d[k] >= 0, k
png = open(sys.argv[2], "rb").read(32)
assert png[:8] == b"\x89PNG\r\n\x1a\n"
w, h = struct.unpack(">II", png[16:24])
assert (w, h) == (72, 16), (w, h)
PY
# --render-stride: 1 gathers at every pixel (16 cones at each one inside the
# cascade), the default 4 at anchors where a pixel's four lie on its surface
# within a voxel (160 x 96 pixels: 4 of them span about a voxel of the back
# wall), so it traces fewer; both report the stride they used.
cones() {
  "$BIN" "$T/box.obj" --at 2,1.5,2 --levels 3 --res 16 --bounces 1 --json \
      --render 2,2,0.3,2,2,3,70,160,96 --render-samples 1 --png "$T/s.png" "$@" > "$T/s.json" 2> "$T/err" &&
    python3 -c 'import json,sys; r=json.load(open(sys.argv[1]))["render"]; print(r["indirect_stride"], r["diffuse_cones"])' "$T/s.json"
}
one=$(cones --render-stride 1) && four=$(cones) &&
  python3 - "$one" "$four" <<'PY' && pass "--render-stride 1: $one; default: $four" || fail "--render-stride: '$one' / '$four'"
import sys
s1, c1 = map(int, sys.argv[1].split()); s4, c4 = map(int, sys.argv[2].split())
assert s1 == 1 and c1 % 16 == 0 and 0 < c1 <= 160 * 96 * 16, (s1, c1)
assert s4 == 4 and 0 < c4 < c1 // 2, (s4, c4)
PY

# A Mitsuba 0.6 sensor as most published scenes write it: a toWorld matrix
# (its x axis the image's left), a fov along y on a 2:1 film given by a
# <default>. It draws the film's aspect at 256 pixels across, the same
# image as the same camera given as numbers.
cat > "$T/cam06.xml" <<'XML'
<?xml version="1.0" encoding="utf-8"?>
<scene version="0.6.0">
  <default name="res" value="512"/>
  <!-- <sensor type="orthographic"/> an old camera -->
  <sensor type="perspective">
    <float name="fov" value="30"/>
    <string name="fovAxis" value="y"/>
    <transform name="toWorld">
      <matrix value="-1 0 0 2  0 1 0 2  0 0 -1 3  0 0 0 1"/>
    </transform>
    <film type="ldrfilm"><integer name="width" value="$res"/><integer name="height" value="256"/></film>
  </sensor>
</scene>
XML
view() {
  out=$1; shift
  "$BIN" "$T/box.obj" --at 2,1.5,2 --levels 3 --res 16 --bounces 1 --json --render-samples 1 --render "$@" \
      --exr "$T/$out.exr" > "$T/$out.json" 2> "$T/err" &&
    python3 -c 'import json,sys; r=json.load(open(sys.argv[1]))["render"]; print(r["width"], r["height"])' "$T/$out.json"
}
m=$(view m "$T/cam06.xml") && n=$(view n 2,2,3,2,2,2,30,256,128) && [ "$m" = "256 128" ] && [ "$n" = "256 128" ] &&
  cmp -s "$T/m.exr" "$T/n.exr" && pass "a Mitsuba 0.6 matrix sensor draws as the same camera in numbers ($m)" ||
  { cat "$T/err" >&2; fail "Mitsuba 0.6 sensor: '$m' against '$n', or the images differ"; }

# An eye inside a closed, unlit solid: the reference is black, so each
# pixel's error is floored at the cone view's mean (20x at most, 2000%);
# with a floor of 1e-30 the figure read 4e29%.
printf 'v -2 0 -2\nv -2 0 2\nv -2 4 -2\nv -2 4 2\nv 2 0 -2\nv 2 0 2\nv 2 4 -2\nv 2 4 2\n' > "$T/closed.obj"
printf 'v -10 0 -10\nv 10 0 -10\nv 10 0 10\nv -10 0 10\n' >> "$T/closed.obj"
printf 'f 1 5 6\nf 1 6 2\nf 3 4 8\nf 3 8 7\nf 1 2 4\nf 1 4 3\nf 5 7 8\nf 5 8 6\nf 1 3 7\nf 1 7 5\nf 2 6 8\nf 2 8 4\n' >> "$T/closed.obj"
printf 'f 9 12 11\nf 9 11 10\n' >> "$T/closed.obj"
"$BIN" "$T/closed.obj" --at 5,1,5 --levels 3 --res 16 --json --render 0,2,0,1,2,0,60,32,32 --render-samples 4 \
    --png "$T/closed.png" > "$T/closed.json" 2> "$T/err" &&
  python3 -c 'import json,sys; e=json.load(open(sys.argv[1]))["render"]["mean_relative_error"]; assert 0 <= e <= 20.0001, e; print(e)' \
    "$T/closed.json" > "$T/mre" && pass "a black reference: mean relative error $(cat "$T/mre") (<= 20)" ||
  fail "black reference: $(cat "$T/err" "$T/mre" 2> /dev/null)"
# That camera stands inside the closed cube: a note says its cone view is leaked light.
grep -q "gi-bake: note: the camera (0, 2, 0) looks inside a solid (" "$T/err" \
  && pass "a camera inside a solid: noted" || fail "inside-solid camera note: $(cat "$T/err")"
# A viewpoint inside a solid with --render: the note says the view reads
# that cascade too (it spoke of the probe alone).
"$BIN" "$T/closed.obj" --at 0,2,0 --levels 3 --res 16 --render 5,1,5,6,1,6,60,16,16 --png "$T/inside.png" \
    > /dev/null 2> "$T/err"
grep -q "the --render view's indirect light comes from a cascade centred there: give --at where the view looks" \
  "$T/err" && pass "a viewpoint inside a solid with --render: the note names the view" ||
  fail "viewpoint-inside note with --render: $(cat "$T/err")"

if command -v exrheader > /dev/null 2>&1; then
  exrheader "$T/view.exr" > "$T/hdr" 2>&1
  grep -q 'path\.R' "$T/hdr" && grep -q 'error\.Y' "$T/hdr" && pass "EXR has path.R and error.Y" || fail "EXR channels"
fi

expect2() {
  "$BIN" "$@" > /dev/null 2> "$T/err"; rc=$?
  if [ $rc -eq 2 ] && grep -q -e "--render\|--png" "$T/err"; then pass "'$*' -> 2: $(head -n 1 "$T/err")"
  else fail "'$*' exited $rc: $(cat "$T/err")"; fi
}
# Straight down (a plan view) has no up in the compact form: north goes to the top.
"$BIN" "$T/box.obj" --at 2,1.5,2 --levels 3 --res 16 --bounces 1 --render 2,3.5,2,2,0,2,90,16,16 --render-samples 1 \
    --png "$T/down.png" > /dev/null 2> "$T/err" && pass "a view straight down renders" ||
  fail "straight down: $(cat "$T/err")"
expect2 "$T/box.obj" --render 2,2,0.3,2,2,0.3,70,24,16 --png "$T/x.png"
expect2 "$T/box.obj" --render 2,2,0.3,2,2,3,0,24,16 --png "$T/x.png"
expect2 "$T/box.obj" --render 2,2,0.3,2,2,3,70,24.5,16 --png "$T/x.png"
expect2 "$T/box.obj" --render "$T/missing.xml" --png "$T/x.png"
expect2 "$T/box.obj" --png "$T/x.png"
expect2 "$T/box.obj" --render 2,2,0.3,2,2,3,70,24,16
expect2s() {
  "$BIN" "$@" > /dev/null 2> "$T/err"; rc=$?
  if [ $rc -eq 2 ] && grep -q -e "--render-stride" "$T/err"; then pass "'$*' -> 2: $(head -n 1 "$T/err")"
  else fail "'$*' exited $rc: $(cat "$T/err")"; fi
}
expect2s "$T/box.obj" --render 2,2,0.3,2,2,3,70,24,16 --png "$T/x.png" --render-stride 0
expect2s "$T/box.obj" --render 2,2,0.3,2,2,3,70,24,16 --png "$T/x.png" --render-stride 17
expect2s "$T/box.obj" --render-stride 2
# --render-samples alone was accepted and ignored, where --render-stride and --png say they need --render.
"$BIN" "$T/box.obj" --render-samples 4 > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 2 ] && grep -q -e "--render-samples: needs --render" "$T/err" && pass "--render-samples alone -> 2" \
  || fail "--render-samples alone exited $rc: $(cat "$T/err")"
finish
