# out_paths.sh: outputs named as a symlink, a FIFO, a device or a folder.
# Writers put "<path>.tmp.<pid>" and rename it into place; a rename over a
# symlink or a device replaced it with a plain file (as root, --exr
# /dev/null broke /dev/null). Now a symlink's target gets the file and the
# link stays, a FIFO or device gets the bytes after the run, a folder is
# refused, and a killed run leaves no temporary file behind.
. "$(dirname "$0")/common.sh"
make_box_scene
Q="--at 2,1.5,2 --levels 2 --res 8 --bounces 1"

"$BIN" "$T/box.obj" $Q --exr "$T/plain.exr" > /dev/null 2> "$T/err" || fail "plain --exr: $(cat "$T/err")"
magic() { od -A n -t x1 -N 4 "$1" | tr -d ' \n'; }
[ "$(magic "$T/plain.exr")" = "762f3101" ] && pass "plain EXR written" || fail "plain EXR magic $(magic "$T/plain.exr")"

# A symlink: the file it names is replaced, the link is kept.
echo old > "$T/target.exr"
ln -s target.exr "$T/link.exr"
"$BIN" "$T/box.obj" $Q --exr "$T/link.exr" > /dev/null 2> "$T/err"; rc=$?
if [ $rc -eq 0 ] && [ -L "$T/link.exr" ] && [ "$(readlink "$T/link.exr")" = target.exr ] &&
   cmp -s "$T/target.exr" "$T/plain.exr"; then pass "a symlink keeps pointing at the new file"
else fail "symlink: rc $rc, $(ls -l "$T/link.exr" "$T/target.exr" 2>&1 | tr '\n' ' ')"; fi

# A FIFO: a reader gets the whole file, the FIFO stays a FIFO.
mkfifo "$T/pipe.exr"
cat "$T/pipe.exr" > "$T/from-pipe" &
reader=$!
"$BIN" "$T/box.obj" $Q --exr "$T/pipe.exr" > /dev/null 2> "$T/err"; rc=$?
wait $reader
if [ $rc -eq 0 ] && [ -p "$T/pipe.exr" ] && cmp -s "$T/from-pipe" "$T/plain.exr"; then pass "a FIFO gets the EXR's bytes"
else fail "FIFO: rc $rc, $(cat "$T/err")"; fi

# Standard output through a pipe (--exr /dev/stdout | ...): the stream holds
# the EXR alone, the summary goes to stderr.
"$BIN" "$T/box.obj" $Q --exr /dev/stdout 2> "$T/err" | cat > "$T/stdout.bin"
if cmp -s "$T/stdout.bin" "$T/plain.exr" && grep -q "^probe" "$T/err"; then pass "--exr /dev/stdout | cat: the EXR alone"
else fail "--exr /dev/stdout: $(wc -c < "$T/stdout.bin") bytes, $(head -n 3 "$T/err")"; fi
# "-" is standard output too (it wrote a file named '-').
(cd "$T" && "$BIN" box.obj $Q --exr - 2> "$T/err" | cat > "$T/dash.bin")
if cmp -s "$T/dash.bin" "$T/plain.exr" && [ ! -e "$T/-" ]; then pass "--exr - | cat: the EXR on stdout, no file '-'"
else fail "--exr -: $(wc -c < "$T/dash.bin") bytes, file '-' $( [ -e "$T/-" ] && echo exists)"; fi

# A character device (root only: mknod), as /dev/null is: still a device after the run.
if mknod -m 666 "$T/null" c 1 3 2> /dev/null; then
  "$BIN" "$T/box.obj" $Q --exr "$T/null" --vdb "$T/null" > /dev/null 2> "$T/err"; rc=$?
  [ $rc -eq 0 ] && [ -c "$T/null" ] && pass "a device stays a device" || fail "device: rc $rc, $(ls -l "$T/null")"
else
  skip "not root: no device node to write to (mknod)"
fi

# A folder is a usage error, before any work.
"$BIN" "$T/box.obj" $Q --exr "$T" > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 2 ] && grep -q "is a folder" "$T/err" && pass "a folder: exit 2, $(head -n 1 "$T/err")" ||
  fail "folder: rc $rc, $(cat "$T/err")"

# Two outputs on one plain file: the second rename replaced the first output
# and the run exited 0 having "written" both. A usage error, before any work.
"$BIN" "$T/box.obj" $Q --exr "$T/both.out" --vdb "$T/./both.out" > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 2 ] && grep -q -- "--vdb: .* is also the --exr output" "$T/err" && [ ! -e "$T/both.out" ] &&
  pass "--exr and --vdb on one file: exit 2" || fail "one file twice: rc $rc, $(cat "$T/err")"

# A run killed before its output is in place leaves no temporary file: a
# run whose FIFO has no reader yet waits for one, holding the finished EXR
# in a private folder under TMPDIR; SIGTERM then removes it.
mkdir "$T/tmp"
mkfifo "$T/lonely.exr"
TMPDIR="$T/tmp" "$BIN" "$T/box.obj" $Q --exr "$T/lonely.exr" > /dev/null 2>&1 &
pid=$!
i=0
while [ $i -lt 600 ] && [ -z "$(find "$T/tmp" -name lonely.exr 2> /dev/null)" ]; do sleep 0.05; i=$((i + 1)); done
held=$(find "$T/tmp" -name lonely.exr | head -n 1)
sleep 0.2
kill -TERM $pid; wait $pid; rc=$?
left=$(find "$T/tmp" -mindepth 1 | tr '\n' ' ')
[ -n "$held" ] && [ $rc -eq 143 ] && [ -z "$left" ] && pass "SIGTERM while waiting to deliver: nothing left in TMPDIR" ||
  fail "SIGTERM: held '$held', rc $rc, left '$left'"

# An output naming an input (the scene, the --probes file; directly or by
# a link) is refused before anything runs: the rename into place wrote the
# EXR over the scene it had just read.
cp "$T/box.obj" "$T/keep.obj"
printf '1 1 1\n' > "$T/pts.txt"
ln -s keep.obj "$T/keep-link.obj"
for args in "--exr $T/keep.obj" "--vdb $T/keep.obj" "--exr $T/keep-link.obj" "--exr $T/pts.txt --probes $T/pts.txt"; do
  # shellcheck disable=SC2086
  "$BIN" "$T/keep.obj" $Q $args > /dev/null 2> "$T/err"; rc=$?
  [ $rc -eq 2 ] && grep -q "is also the .*; write the output elsewhere" "$T/err" && cmp -s "$T/box.obj" "$T/keep.obj" \
    && [ "$(cat "$T/pts.txt")" = "1 1 1" ] && pass "$args: refused, input intact: $(head -n 1 "$T/err")" \
    || fail "$args: rc $rc, $(head -n 1 "$T/err")"
  cp "$T/box.obj" "$T/keep.obj"
done
finish
