# scene_smoke.sh: gi-accuracy --scene FILE on a tiny generated box (issue
# 16, item 3): a quick knob sweep and a short path-tracer sweep write the
# CSV and the markdown into the output folder; read back, every knob has its
# rows with finite errors, the path tracer's error falls with samples, the
# reference's own error is reported, finite and the same in both files.
# --probes takes the points as given and the default --out is
# out/accuracy-NAME; bad arguments exit 2 (a missing file 1), naming the
# option, with nothing written.
# Usage: sh scene_smoke.sh path/to/gi-accuracy
. "$(dirname "$0")/../cli/common.sh"
make_box_scene
QUICK="--quick --ref-samples 1024 --pt-max 16 --repeat 1 --threads 2 --no-views --no-workloads"

"$BIN" --version > "$T/v" 2>&1; rc=$?
[ $rc -eq 0 ] && grep -q "^gi-accuracy [0-9]" "$T/v" && pass "--version -> 0" || fail "--version: exit $rc: $(cat "$T/v")"
"$BIN" --scene "$T/box.obj" $QUICK --out "$T/acc" > "$T/stdout" 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && pass "--scene run exits 0" || { cat "$T/err" >&2; fail "--scene run exited $rc"; finish; }
[ -s "$T/acc/accuracy.csv" ] && [ -s "$T/acc/accuracy.md" ] && [ -s "$T/acc/accuracy.gp" ] \
  && pass "CSV, markdown and plot script written to --out" || fail "outputs missing: $(ls "$T/acc")"
# The sweep's own top (--pt-max 16), not 4096 whatever was swept.
grep -q "tracer runs at 1..16 samples per probe" "$T/acc/accuracy.md" && grep -q "path tracer, 1..16 samples" \
  "$T/acc/accuracy.gp" && ! grep -q 4096 "$T/acc/accuracy.gp" && pass "the report names the sweep's 16 samples" \
  || fail "sample range in the report: $(grep -o '1\.\.[0-9]* samples' "$T/acc/accuracy.md" "$T/acc/accuracy.gp")"

python3 - "$T/acc/accuracy.csv" "$T/acc/accuracy.md" <<'PY' && pass "CSV and markdown read back" || fail "CSV / markdown"
import csv, math, re, sys
rows = list(csv.DictReader(open(sys.argv[1])))
md = open(sys.argv[2]).read()
assert rows and all(r["scene"] == "box" for r in rows), {r["scene"] for r in rows}
cone = [r for r in rows if r["kind"] == "cone"]
path = [r for r in rows if r["kind"] == "path"]
# --quick: each knob of the sweep, and the default once.
want = {"default": 1, "res": 2, "levels": 3, "voxel0": 2, "cones": 3, "aperture": 2, "step": 2, "bounces": 4,
        "light_samples": 3}
got = {}
for r in cone:
    got[r["knob"]] = got.get(r["knob"], 0) + 1
assert got == want, got
assert [int(float(r["value"])) for r in path] == [1, 4, 16], [r["value"] for r in path]
for r in rows:
    for k in ("ms", "mre_total", "mre_direct", "mre_indirect", "relmse_total", "ref_rel_se_total"):
        v = float(r[k])
        assert math.isfinite(v) and v >= 0, (r["knob"], k, v)
    assert float(r["ms"]) > 0, r
d = [r for r in cone if r["default"] == "1"]
assert len(d) == 1 and d[0]["knob"] == "default", d
# A lit closed box: the default bake is within 50% of the reference
# (a wrong sweep, e.g. probes outside the cascade, reads ~100%).
assert float(d[0]["mre_total"]) < 0.5, d[0]["mre_total"]
# The path tracer converges: 16 paths beat 1 path.
assert float(path[-1]["mre_total"]) < float(path[0]["mre_total"]), [p["mre_total"] for p in path]
# The reference's own error: in the markdown, finite, small at 1024 paths,
# and the CSV's figure for the same reference.
m = re.search(r"## box\n\nViewpoint \(([^)]*)\), (\d+) probes \(a 3x3x3 lattice[^)]*\)\. Reference: 1024 paths per "
              r"probe, [0-9.]+ s; its own mean relative standard error: total ([0-9.naif]+)%", md)
assert m, md[:2000]
se = float(m.group(3)) / 100
assert math.isfinite(se) and 0 < se < 0.05, se
assert int(m.group(2)) == 27, m.group(2)       # every lattice point is inside the lit box
assert [float(x) for x in m.group(1).split(",")] == [2, 2, 2], m.group(1)  # the bounds' centre
assert abs(float(d[0]["ref_rel_se_total"]) - se) < 1e-4, (d[0]["ref_rel_se_total"], se)
assert "| cone | **default** |" in md and "| path | samples | 16 |" in md
# The error by light kind: the box has one kind (its emissive lamp), so that
# kind's reference is the scene's own (the same paths: share 100%) and its
# bake the default one (the same indirect error as the default row).
m = re.search(r"\| box \| (\w+) \| ([0-9.]+)% \| ([0-9.]+)% \| ([0-9.]+) \[", md)
assert m and "## Indirect light by the light it comes from" in md, md[:3000]
assert m.group(1) == "emissive" and float(m.group(2)) == 100.0, m.groups()
assert abs(float(m.group(3)) / 100 - float(d[0]["mre_indirect"])) < 1e-4, (m.group(3), d[0]["mre_indirect"])
assert len(re.findall(r"\| box \| [a-z/]+ \| [0-9.]+% \|", md)) == 1  # no kind the scene lacks
# The hand-built cascade: one level keeps the small source's flux up to
# tau / alpha; across levels the figures are there, finite and ordered.
m = re.search(r"Thin rays read it on one level: \*\*([0-9.]+)\*\* \(the optical-depth model's own excess is "
              r"tau/alpha = ([0-9.]+)\).*read across levels \*\*([0-9.]+) on average, ([0-9.]+) to ([0-9.]+)\*\*", md)
assert m, "hand-over section missing"
one, ta, mean, lo, hi = (float(x) for x in m.groups())
assert 1.0 < one < ta + 0.015, (one, ta)
assert 0 < lo <= mean <= hi < 10, (lo, mean, hi)
PY

# --probes as given, viewpoint their middle, the default --out under the working directory.
printf '# two points\n1 1 1\n3 2 3\n' > "$T/pts.txt"
(cd "$T" && "$BIN" --scene box.obj --probes pts.txt $QUICK > "$T/stdout2" 2> "$T/err2"); rc=$?
[ $rc -eq 0 ] && pass "--probes run exits 0" || { cat "$T/err2" >&2; fail "--probes run exited $rc"; }
grep -q 'Viewpoint (2, 1.5, 2), 2 probes (2 points from pts.txt, as given)' "$T/out/accuracy-box/accuracy.md" \
  && pass "--probes taken as given, default --out out/accuracy-box" \
  || fail "--probes run: $(ls -R "$T/out" 2>&1 | head -5)"
# Points no light reaches (under the closed box): every relative error
# would be 0/0; it wrote NaN figures and exited 0. Now 1, saying why.
printf '2 -3 2\n1 -2 1\n' > "$T/dark.txt"
"$BIN" --scene "$T/box.obj" --probes "$T/dark.txt" $QUICK --out "$T/dark" > /dev/null 2> "$T/err3"; rc=$?
[ $rc -eq 1 ] && grep -q "the reference reads no light at any of the 2 probes" "$T/err3" && [ ! -e "$T/dark/accuracy.csv" ] \
  && pass "--probes no light reaches -> 1, named, no CSV" || fail "dark --probes (rc $rc): $(cat "$T/err3")"

# Street level (the cities' rule) on a ground with one closed block, Z up:
# a 7 x 7 grid 2 m up, the probe inside the block dropped, the viewpoint a
# kept probe 2 m up; only the bounce knob swept, to stay quick.
cat > "$T/street.obj" <<'OBJ'
v -20 -20 0
v 20 -20 0
v 20 20 0
v -20 20 0
v -5 -5 0
v 5 -5 0
v 5 5 0
v -5 5 0
v -5 -5 8
v 5 -5 8
v 5 5 8
v -5 5 8
f 1 2 3 4
f 9 10 11 12
f 5 6 10 9
f 6 7 11 10
f 7 8 12 11
f 8 5 9 12
OBJ
"$BIN" --scene "$T/street.obj" --up z --above-ground 2 --knobs bounces --quick --ref-samples 256 --pt-max 4 --no-workloads \
    --repeat 1 --threads 2 --no-views --out "$T/st" > /dev/null 2> "$T/err3"; rc=$?
[ $rc -eq 0 ] && pass "--above-ground run exits 0" || { cat "$T/err3" >&2; fail "--above-ground run exited $rc"; }
python3 - "$T/st/accuracy.csv" "$T/st/accuracy.md" <<'PY' && pass "street-level probes placed, only bounces swept" \
  || fail "street-level run"
import csv, re, sys
rows = list(csv.DictReader(open(sys.argv[1])))
assert sorted({r["knob"] for r in rows}) == ["bounces", "default", "samples"], {r["knob"] for r in rows}
md = open(sys.argv[2]).read()
m = re.search(r"Viewpoint \(([^)]*)\), (\d+) probes \(a 7x7 street-level grid, 5.33333 apart, 2 above the ground "
              r"\(gi_probe_grid_build\), 1 inside buildings dropped", md)
assert m, md[:1500]
at = [float(x) for x in m.group(1).split(",")]
assert at[2] == 2 and not (abs(at[0]) < 5 and abs(at[1]) < 5), at  # 2 m up, outside the block
assert int(m.group(2)) == 24, m.group(2)
PY

# --spacing sets that grid's pitch (Munich's rule is 12 m): 2 m apart around
# --at, beside the block, so no point falls inside it.
"$BIN" --scene "$T/street.obj" --up z --at 12,0,2 --above-ground 2 --spacing 2 --knobs bounces --quick \
    --ref-samples 256 --pt-max 4 --no-workloads --repeat 1 --threads 2 --no-views --out "$T/sp" > /dev/null 2> "$T/err4"
rc=$?
[ $rc -eq 0 ] && grep -q "a 7x7 street-level grid, 2 apart, 2 above the ground (gi_probe_grid_build), 0 inside" \
    "$T/sp/accuracy.md" && pass "--spacing sets the grid's pitch" || { cat "$T/err4" >&2; fail "--spacing run ($rc)"; }

# A gnuplot that fails: the report says it failed (it said "not installed").
mkdir -p "$T/fakebin"
printf '#!/bin/sh\nexit 1\n' > "$T/fakebin/gnuplot"
chmod +x "$T/fakebin/gnuplot"
PATH="$T/fakebin:$PATH" "$BIN" --scene "$T/street.obj" --up z --at 12,0,2 --above-ground 2 --spacing 2 --knobs bounces \
    --quick --ref-samples 256 --pt-max 4 --no-workloads --repeat 1 --threads 2 --no-views --out "$T/gf" > /dev/null \
    2> "$T/err5"
grep -q "gnuplot failed on its script" "$T/gf/accuracy.md" && grep -q "gnuplot failed on" "$T/err5" \
  && pass "a failing gnuplot is reported as failing" || fail "failing gnuplot: $(grep -i 'plot was not' "$T/gf/accuracy.md")"

# Bad arguments: exit 2 naming the option; a missing file exits 1; nothing written.
expect_rc() {
  want=$1 what=$2; shift 2
  "$BIN" --out "$T/bad" "$@" > /dev/null 2> "$T/e"; rc=$?
  if [ $rc -ne "$want" ]; then fail "$*: exited $rc, expected $want: $(cat "$T/e")"; return; fi
  grep -q -e "$what" "$T/e" || { fail "$*: message does not say '$what': $(cat "$T/e")"; return; }
  [ ! -e "$T/bad" ] || { fail "$*: wrote $T/bad"; rm -rf "$T/bad"; return; }
  pass "$* -> $want ($what)"
}
printf '1 2\n' > "$T/badpts.txt"
expect_rc 2 "cannot be combined with --scenes" --scene "$T/box.obj" --scenes cornell
expect_rc 2 "need --scene FILE" --at 1,2,3
expect_rc 2 "unknown scene 'town'" --scenes cornell,town
expect_rc 2 "'city' named twice" --scenes city,city5k,city
expect_rc 2 "'--at' needs a value" --scene "$T/box.obj" --at
expect_rc 2 "--at: expected" --scene "$T/box.obj" --at 1,2
expect_rc 2 "--up: expected y or z" --scene "$T/box.obj" --up x
expect_rc 2 "--above-ground: expected a finite number > 0" --scene "$T/box.obj" --above-ground -1
expect_rc 2 "cannot be combined with --probes" --scene "$T/box.obj" --above-ground 2 --probes "$T/pts.txt"
expect_rc 2 "--spacing: is the street grid's spacing: it needs --above-ground" --scene "$T/box.obj" --spacing 2
expect_rc 2 "--spacing: expected a finite number > 0" --scene "$T/box.obj" --above-ground 2 --spacing 0
expect_rc 2 "badpts.txt" --scene "$T/box.obj" --probes "$T/badpts.txt"
printf '# no points here\n\n' > "$T/nopts.txt"
expect_rc 2 "--probes: '$T/nopts.txt' holds no points" --scene "$T/box.obj" --probes "$T/nopts.txt"
expect_rc 2 "--view: expected a Mitsuba" --scene "$T/box.obj" --view 1,2,3
expect_rc 2 "--view: .*eye" --scene "$T/box.obj" --view 1,1,1,1,1,1,60,8,8
expect_rc 2 "cannot be combined with --no-views" --scene "$T/box.obj" --view 1,1,1,2,2,2,60,8,8 --no-views
expect_rc 2 "--knobs: unknown knob 'foo'" --scene "$T/box.obj" --knobs res,foo
expect_rc 2 "--knobs: unknown knob ''" --scene "$T/box.obj" --knobs res,
expect_rc 2 "--md: given twice" --scene "$T/box.obj" --md "$T/a.md" --md "$T/b.md"
expect_rc 2 "--at: given twice" --scene "$T/box.obj" --at 1,1,1 --at 2,2,2
expect_rc 1 "cannot read" --scene "$T/missing.obj"
expect_rc 1 "missing.txt" --scene "$T/box.obj" --probes "$T/missing.txt"
# A shared scene --scenes names must be there: it was skipped, exit 0 (with
# every named scene missing: "no scene was available", exit 0).
expect_rc 1 "--scenes: munich: cannot read '$T/noscenes/munich/munich.obj'" --scenes city,munich \
  --scenes-dir "$T/noscenes"

# What the run writes or reads at its end is checked before the sweep: an
# unwritable --md or --png, a missing --notes and an --out that is a file
# only failed (or were left out, exit 0) after the whole run, hours for
# `make accuracy`. Each exits before any reference or CSV is made.
echo "a file" > "$T/plain"
expect_before() {
  want=$1 what=$2; shift 2
  "$BIN" --scene "$T/box.obj" $QUICK "$@" > /dev/null 2> "$T/e"; rc=$?
  if [ $rc -eq "$want" ] && grep -q -e "$what" "$T/e" && [ -z "$(find "$T/eb" -name 'accuracy.csv' -o -name 'ref-*')" ]
  then pass "$* -> $want before the sweep ($what)"
  else fail "$*: exited $rc, expected $want saying '$what' before the sweep: $(tail -n 2 "$T/e")"; fi
}
mkdir -p "$T/eb"
expect_before 1 "--md: cannot write into '$T/nowhere'" --out "$T/eb" --md "$T/nowhere/r.md"
expect_before 2 "--md: '$T' is a folder" --out "$T/eb" --md "$T"
expect_before 1 "--png: cannot write into '$T/nowhere'" --out "$T/eb" --png "$T/nowhere/p.png"
expect_before 1 "--notes: cannot read '$T/nonotes.md'" --out "$T/eb" --notes "$T/nonotes.md"
expect_before 1 "--notes: '$T' is not a file" --out "$T/eb" --notes "$T"
expect_before 1 "--out: '$T/plain' exists and is not a folder" --out "$T/plain"
# A viewpoint or probe the bake cannot place (more than 1e9 from the scene)
# is refused before the reference, not by the bake after it.
printf '1 1 1\n1e12 0 0\n' > "$T/farpts.txt"
expect_before 1 "--at (1e+12, 0, 0) is more than 1e9 units from the scene's origin on axis x" --out "$T/eb" \
  --at 1e12,0,0
expect_before 1 "--probes: $T/farpts.txt: point 2 (1e+12, 0, 0) is more than 1e9" --out "$T/eb" \
  --probes "$T/farpts.txt"

# The reference cache knows the scene it was made from: an unchanged rerun
# reads it, an edited .mtl (a brighter lamp) renders it again. It was keyed
# by the file's base name: the edited scene was measured against the old
# scene's reference.
mkdir "$T/ed"
cp "$T/box.obj" "$T/box.mtl" "$T/ed/"
"$BIN" --scene "$T/ed/box.obj" $QUICK --out "$T/edo" > /dev/null 2> "$T/ed1" || fail "edit run 1: $(tail -n 2 "$T/ed1")"
"$BIN" --scene "$T/ed/box.obj" $QUICK --out "$T/edo" > /dev/null 2> "$T/ed2" || fail "edit run 2: $(tail -n 2 "$T/ed2")"
sed -i 's/^Ke 10 10 10/Ke 40 40 40/' "$T/ed/box.mtl"
"$BIN" --scene "$T/ed/box.obj" $QUICK --out "$T/edo" > /dev/null 2> "$T/ed3" || fail "edit run 3: $(tail -n 2 "$T/ed3")"
if grep -q "box: reference from cache" "$T/ed2" && grep -q "box: reference, 27 probes" "$T/ed3" \
   && ! grep -q "box: reference from cache" "$T/ed3"; then
  pass "reference cache: reused for the same scene, made again after its .mtl changed"
else fail "reference cache: rerun '$(grep 'box: reference' "$T/ed2")', edited '$(grep 'box: reference' "$T/ed3")'"; fi
# ... and after a texture it reads changed: the walls' map_Kd, two pixels
# (dark, light) mirrored, so the .obj and .mtl bytes and the material's
# factors (its mean albedo) stay the same, which was all the key read.
png2() { python3 -c 'import struct, sys, zlib
a, b = int(sys.argv[2]), int(sys.argv[3]); raw = bytes([0, a, a, a, b, b, b])
ck = lambda t, d: struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
open(sys.argv[1], "wb").write(b"\x89PNG\r\n\x1a\n" + ck(b"IHDR", struct.pack(">IIBBBBB", 2, 1, 8, 2, 0, 0, 0))
                              + ck(b"IDAT", zlib.compress(raw)) + ck(b"IEND", b""))' "$1" "$2" "$3"; }
mkdir "$T/tx"
# Every corner at the dark pixel's centre (one vt): the walls read one pixel.
sed -e 's#^mtllib box.mtl#mtllib box.mtl\nvt 0.25 0.5#' -e '/^f /s#\([0-9][0-9]*\)\( \|$\)#\1/1\2#g' \
  "$T/box.obj" > "$T/tx/box.obj"
sed 's/^Kd 0.7 0.7 0.7/Kd 1 1 1\nmap_Kd wall.png/' "$T/box.mtl" > "$T/tx/box.mtl"
png2 "$T/tx/wall.png" 64 230
"$BIN" --scene "$T/tx/box.obj" $QUICK --out "$T/txo" > /dev/null 2> "$T/tx1" || fail "texture run 1: $(tail -n 2 "$T/tx1")"
png2 "$T/tx/wall.png" 230 64
"$BIN" --scene "$T/tx/box.obj" $QUICK --out "$T/txo" > /dev/null 2> "$T/tx2" || fail "texture run 2: $(tail -n 2 "$T/tx2")"
if grep -q "box: reference, 27 probes" "$T/tx2" && ! grep -q "box: reference from cache" "$T/tx2"; then
  pass "reference cache: made again after a texture the scene reads changed"
else fail "reference cache: after the texture changed: '$(grep 'box: reference' "$T/tx2")'"; fi

# Probes are chosen by the luminance of their direct light: a lamp lit in
# red alone kept none by the green channel, and the run exited 1 without a
# word. A lone triangle's indirect light is 0 at every probe: its relative
# error is undefined (nan in the CSV, n/a in the report), not 1e28. A
# sealed box's lattice sees no light at all: an error that says so.
TINY="--quick --ref-samples 256 --pt-max 4 --repeat 1 --threads 2 --no-views --no-workloads --no-cycles \
  --no-by-light --knobs res"
mkdir "$T/red"
cp "$T/box.obj" "$T/red/"
sed 's/^Ke 10 10 10/Ke 30 0 0/' "$T/box.mtl" > "$T/red/box.mtl"
"$BIN" --scene "$T/red/box.obj" $TINY --out "$T/redo" > /dev/null 2> "$T/rederr"; rc=$?
[ $rc -eq 0 ] && grep -q "^box,cone" "$T/redo/accuracy.csv" && pass "a red-only lamp: probes chosen, measured" \
  || fail "red-only lamp: exit $rc: $(tail -n 2 "$T/rederr")"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' > "$T/tri.obj"
"$BIN" --scene "$T/tri.obj" $TINY --out "$T/trio" > /dev/null 2> "$T/trierr"; rc=$?
python3 - "$T/trio/accuracy.csv" "$T/trio/accuracy.md" <<'PY' && [ $rc -eq 0 ] \
  && pass "a lone triangle: indirect error n/a, total finite" || fail "lone triangle: exit $rc: $(tail -n 2 "$T/trierr")"
import csv, math, sys
rows = list(csv.DictReader(open(sys.argv[1])))
assert rows
for r in rows:
    assert math.isnan(float(r["mre_indirect"])), r["mre_indirect"]
    assert math.isfinite(float(r["mre_total"])), r["mre_total"]
md = open(sys.argv[2]).read()
assert "| n/a |" in md and "nan%" not in md
PY
printf 'v 0 0 0\nv 2 0 0\nv 2 2 0\nv 0 2 0\nv 0 0 2\nv 2 0 2\nv 2 2 2\nv 0 2 2\n' > "$T/sealed.obj"
printf 'f 1 2 3 4\nf 5 8 7 6\nf 1 5 6 2\nf 4 3 7 8\nf 1 4 8 5\nf 2 6 7 3\n' >> "$T/sealed.obj"
"$BIN" --scene "$T/sealed.obj" $TINY --out "$T/sealo" > /dev/null 2> "$T/sealerr"; rc=$?
[ $rc -eq 1 ] && grep -q "probe selection: none of the 27 candidate points sees direct light" "$T/sealerr" \
  && grep -q -- "--probes FILE" "$T/sealerr" && pass "a sealed box: no lit probe, said so, exit 1" \
  || fail "sealed box: exit $rc: $(cat "$T/sealerr")"
finish
