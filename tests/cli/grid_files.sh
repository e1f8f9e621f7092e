# grid_files.sh: the files and folders a --grid run writes. --resume naming
# an output is refused before any work (it made the folder, baked every
# tile, then failed "cannot write 'c3.json'" with no reason); a write error
# gives its reason; SIGTERM while a tile checkpoint is being written removes
# its temporary (one in three signals left one); the EXR waiting for its
# sibling has one temporary name, not "<out>.tmp.<pid>.tmp.<pid>" (kill -9
# left those, 7-21 MB each); a later run removes such temporaries of its
# outputs and resume folder when their process is gone.
. "$(dirname "$0")/common.sh"
make_box_scene
BOXQ="--grid 0.5 --voxel 1 --res 8 --levels 2 --bounces 1 --cones 4 --samples 1 --probe-samples 4 --threads 1"
GONE=99999999 # above any pid_max: no such process

for args in "--manifest $T/c3.json --resume $T/c3.json" "--exr $T/c.exr --resume $T/./c.exr" \
            "--vdb $T/c.vdb --json --resume $T/c.vdb"; do
  # shellcheck disable=SC2086
  "$BIN" "$T/box.obj" $BOXQ $args > /dev/null 2> "$T/err"; rc=$?
  [ $rc -eq 2 ] && grep -q -- "--resume: .* is also the --[a-z]* output" "$T/err" && [ -z "$(ls "$T" | grep '^c')" ] \
    && pass "$(echo "$args" | sed "s|$T/||g"): exit 2, nothing made" \
    || fail "$args: rc $rc, $(head -n 1 "$T/err"), made: $(ls "$T" | grep '^c' | tr '\n' ' ')"
done
echo x > "$T/afile"
"$BIN" "$T/box.obj" $BOXQ --json --resume "$T/afile" > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 2 ] && grep -q -- "--resume: .*afile' exists and is not a folder" "$T/err" \
  && pass "--resume naming a file: exit 2" || fail "--resume file: rc $rc, $(head -n 1 "$T/err")"

# A manifest whose temporary name is too long for the file system: the reason is said.
long=$(printf 'm%.0s' $(seq 1 250))
"$BIN" "$T/box.obj" $BOXQ --manifest "$T/$long" > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 1 ] && grep -q -- "--manifest: cannot write '.*': File name too long" "$T/err" \
  && pass "a manifest write error gives its reason" || fail "manifest error: rc $rc, $(cat "$T/err")"

# SIGTERM while a checkpoint is written: its temporary, a FIFO here so the
# run waits in opening it, is removed with the outputs' temporaries.
mkdir "$T/ck"
"$BIN" "$T/box.obj" $BOXQ --resume "$T/ck" --exr "$T/t.exr" > /dev/null 2>&1 &
pid=$!
mkfifo "$T/ck/tile-0000000.bin.tmp.$pid"
i=0 # until it waits for a reader of the FIFO
while [ $i -lt 400 ] && ! grep -qE 'partner|pipe|fifo' "/proc/$pid/wchan" 2> /dev/null; do sleep 0.05; i=$((i + 1)); done
sleep 0.2
kill -TERM $pid; wait $pid; rc=$?
left=$(ls "$T/ck" "$T" | grep '\.tmp\.' | tr '\n' ' ')
[ $rc -eq 143 ] && [ -z "$left" ] && pass "SIGTERM while a tile is checkpointed: no temporary left" \
  || fail "SIGTERM in a checkpoint: rc $rc, left: $left"

# Temporaries a killed run left: its process gone, they are removed; a live
# process's and another output's are kept.
mkdir -p "$T/ck2"
for f in ck2/tile-0000001.bin.tmp.$GONE g.exr.tmp.$GONE g.exr.tmp.$GONE.tmp.$GONE g.vdb.tmp.$GONE g.exr.tmp.$$ \
         other.exr.tmp.$GONE; do : > "$T/$f"; done
"$BIN" "$T/box.obj" $BOXQ --resume "$T/ck2" --exr "$T/g.exr" --vdb "$T/g.vdb" > /dev/null 2> "$T/err"; rc=$?
left=$(cd "$T" && ls ck2 . | grep '\.tmp\.' | sort | tr '\n' ' ')
[ $rc -eq 0 ] && [ "$left" = "g.exr.tmp.$$ other.exr.tmp.$GONE " ] && [ "$(grep -c "removed .*process $GONE" "$T/err")" -eq 4 ] \
  && pass "stale temporaries removed (4), a live one's and another file's kept" \
  || fail "stale temporaries: rc $rc, left: $left; $(cat "$T/err")"

# One temporary name per output while the EXR waits for the VDB. (Under
# ASan the leak check cannot run traced, and it aborted the run: off here.)
if command -v strace > /dev/null 2>&1; then
  ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0" \
    strace -f -qq -e trace=openat,rename -o "$T/trace" "$BIN" "$T/box.obj" $BOXQ --exr "$T/s.exr" --vdb "$T/s.vdb" \
    > /dev/null 2>&1; rc=$?
  opened=$(grep -c 's\.exr\.tmp\.[0-9]*"' "$T/trace")
  [ $rc -eq 0 ] && [ "$opened" -ge 1 ] && ! grep -q '\.tmp\.[0-9]*\.tmp\.' "$T/trace" \
    && pass "no '<out>.tmp.<pid>.tmp.<pid>' name" || fail "doubled names: rc $rc: $(grep '\.tmp\.' "$T/trace" | head -n 4)"
else
  skip "no strace: the temporary names are not traced"
fi
finish
