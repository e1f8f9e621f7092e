# lightmap_files.sh: what a --lightmap run leaves on disk. A lightmap past
# the machine's memory is refused before its atlases are allocated (exit 2
# naming --texel, the bytes needed and allowed: one ran 100 s to 12 GB
# resident on a 24 GiB machine for a 36 GB lightmap); a rerun that needs
# fewer atlases removes the numbered atlases of the earlier run that it
# did not write (they were left, silently), and the bare name beside
# numbered ones, but no file that is not a gi-bake lightmap; numbered
# atlases' temporaries of a process that is gone are removed.
. "$(dirname "$0")/common.sh"
make_box_scene
Q="--levels 3 --res 16 --probe-samples 16 --cones 6 --threads 1"
GONE=99999999 # above any pid_max: no such process

# 200 separate 8 m squares at texel 0.001: 8000^2-texel charts, four to a
# 16384 atlas, 50 atlases: about 1.3e10 texels, over 1 TB on any machine.
python3 - "$T/tiles.obj" <<'PY'
import sys
with open(sys.argv[1], "w") as f:
    for i in range(200):
        x = 10.0 * i
        f.write("v %g 0 0\nv %g 0 8\nv %g 0 8\nv %g 0 0\n" % (x, x, x + 8, x + 8))
        f.write("f %d %d %d %d\n" % (4 * i + 1, 4 * i + 2, 4 * i + 3, 4 * i + 4))
PY
start=$(date +%s)
# shellcheck disable=SC2086
"$BIN" "$T/tiles.obj" $Q --lightmap "$T/huge.exr" --texel 0.001 --atlas 16384 > /dev/null 2> "$T/err"; rc=$?
secs=$(( $(date +%s) - start ))
if [ $rc -eq 2 ] && [ $secs -le 5 ] && [ -z "$(find "$T" -name 'huge*')" ] && python3 - "$T/err" <<'PY'; then
import re, sys
e = open(sys.argv[1]).read()
m = re.search(r"gi-bake: --texel: lightmap: 50 atlases of 16384 texels \((\d+) in all\) need about [0-9.]+ GiB "
              r"\((\d+) bytes\) to bake and write, more than the [0-9.]+ GiB \((\d+) bytes\) allowed: this machine's", e)
assert m, e
texels, need, allowed = map(int, m.groups())
assert texels >= 200 * 8000 * 8000, texels       # the charts alone
assert need == 104 * texels, (need, texels)      # 80 held + 24 while sorted into tiles
assert 0 < allowed < need, (allowed, need)
assert "raise --texel" in e, e
PY
  pass "a 1.3 TB lightmap: exit 2 in ${secs} s naming --texel and the bytes, no file"
else
  fail "huge lightmap: rc $rc after ${secs} s: $(cat "$T/err")"
fi

# shellcheck disable=SC2086
lm() { "$BIN" "$T/box.obj" $Q --lightmap "$T/lm.exr" "$@" > /dev/null 2> "$T/err"; }
atlases() { (cd "$T" && ls lm*.exr 2> /dev/null | tr '\n' ' '); }
lm --texel 0.25 --atlas 32 || fail "first run: $(cat "$T/err")"
many=$(atlases)
[ "$many" = "lm.0001.exr lm.0002.exr lm.0003.exr lm.0004.exr lm.0005.exr lm.0006.exr " ] \
  && pass "--texel 0.25: six atlases" || fail "--texel 0.25 wrote: $many"
echo "not a lightmap" > "$T/lm.0009.exr"
: > "$T/lm.0003.exr.tmp.$GONE"
: > "$T/lm.0004.exr.tmp.$$"
lm --texel 0.5 --atlas 32 || fail "second run: $(cat "$T/err")"
[ "$(atlases)" = "lm.0001.exr lm.0002.exr lm.0009.exr " ] && grep -q "removed '.*lm.0006.exr', an atlas of an earlier" \
  "$T/err" && pass "--texel 0.5: two atlases, the earlier 0003..0006 removed, a file not a lightmap kept" \
  || fail "--texel 0.5 left: $(atlases); $(cat "$T/err")"
[ ! -e "$T/lm.0003.exr.tmp.$GONE" ] && [ -e "$T/lm.0004.exr.tmp.$$" ] \
  && pass "an atlas temporary of a process gone removed, a live one's kept" \
  || fail "temporaries: $(ls "$T" | grep tmp | tr '\n' ' ')"
lm --texel 1 --atlas 64 || fail "third run: $(cat "$T/err")"
[ "$(atlases)" = "lm.0009.exr lm.exr " ] && pass "one atlas: lm.exr alone, the numbered ones removed" \
  || fail "one atlas left: $(atlases)"
lm --texel 0.5 --atlas 32 || fail "fourth run: $(cat "$T/err")"
[ "$(atlases)" = "lm.0001.exr lm.0002.exr lm.0009.exr " ] && pass "numbered again: the bare lm.exr removed" \
  || fail "numbered again left: $(atlases)"
finish
