# render.sh: --render draws the cascade's view beside the path-traced one:
# a PNG three views wide, an EXR with both images and the error, the JSON
# "render" figures finite; bad cameras exit 2 naming --render.
. "$(dirname "$0")/common.sh"
make_box_scene

"$BIN" "$T/box.obj" --at 2,1.5,2 --levels 3 --res 16 --bounces 1 --json \
    --render 2,2,0.3,2,2,3,70,24,16 --render-samples 4 --png "$T/view.png" --exr "$T/view.exr" \
    > "$T/out.json" 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && pass "render exits 0" || { cat "$T/err" >&2; fail "render exited $rc"; finish; }
python3 - "$T/out.json" "$T/view.png" <<'PY' && pass "PNG 72x16 and JSON figures" || fail "render outputs"
import json, math, struct, sys
d = json.load(open(sys.argv[1]))["render"]
assert d["width"] == 24 and d["height"] == 16 and d["path_samples"] == 4, d
for k in ("cone_ms", "path_ms", "mean_relative_error"): assert math.isfinite(d[k]) and d[k] >= 0, k
png = open(sys.argv[2], "rb").read(32)
assert png[:8] == b"\x89PNG\r\n\x1a\n"
w, h = struct.unpack(">II", png[16:24])
assert (w, h) == (72, 16), (w, h)
PY
if command -v exrheader > /dev/null 2>&1; then
  exrheader "$T/view.exr" > "$T/hdr" 2>&1
  grep -q 'path\.R' "$T/hdr" && grep -q 'error\.Y' "$T/hdr" && pass "EXR has path.R and error.Y" || fail "EXR channels"
fi

expect2() {
  "$BIN" "$@" > /dev/null 2> "$T/err"; rc=$?
  if [ $rc -eq 2 ] && grep -q -e "--render\|--png" "$T/err"; then pass "'$*' -> 2: $(head -n 1 "$T/err")"
  else fail "'$*' exited $rc: $(cat "$T/err")"; fi
}
expect2 "$T/box.obj" --render 2,2,0.3,2,2,0.3,70,24,16 --png "$T/x.png"
expect2 "$T/box.obj" --render 2,2,0.3,2,2,3,0,24,16 --png "$T/x.png"
expect2 "$T/box.obj" --render 2,2,0.3,2,2,3,70,24.5,16 --png "$T/x.png"
expect2 "$T/box.obj" --render "$T/missing.xml" --png "$T/x.png"
expect2 "$T/box.obj" --png "$T/x.png"
expect2 "$T/box.obj" --render 2,2,0.3,2,2,3,70,24,16
finish
