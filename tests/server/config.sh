#!/bin/sh
# config.sh: gi-server refuses bad configs at start, naming file, line and key.
# Usage: sh config.sh path/to/gi-server
set -u
BIN=${1:?usage: sh config.sh path/to/gi-server}
T=$(mktemp -d "${TMPDIR:-/tmp}/gi-config.XXXXXX")
trap 'rm -rf "$T"' EXIT INT TERM
FAILS=0
fail() { echo "FAIL: $*" >&2; FAILS=$((FAILS + 1)); }

# expect NAME STATUS NEEDLE: runs --check-config on $T/NAME.ini.
expect() {
  out=$("$BIN" --config "$T/$1.ini" --check-config 2>&1); st=$?
  if [ "$st" -ne "$2" ]; then fail "$1: exit $st, want $2: $out"; return; fi
  case "$out" in *"$3"*) echo "ok: $1: $(echo "$out" | grep -F -- "$3" | head -1)" ;;
                 *) fail "$1: output lacks '$3': $out" ;; esac
}
scene='[scene city]
source = city
extent = 150'

printf '[server]\nport = 0\n%s\n' "$scene" > "$T/good.ini"
expect good 0 "is valid: 1 scene(s)"
printf '[server]\nport = 0\nworkers = lots\n%s\n' "$scene" > "$T/workers.ini"
expect workers 1 "workers.ini:3: [server] workers: expected an integer in 1..256, got 'lots'"
printf '[server]\nprot = 8080\n%s\n' "$scene" > "$T/typo.ini"
expect typo 1 "typo.ini:2: [server] prot: unknown key"
printf '[limits]\ncache_mb = -5\n%s\n' "$scene" > "$T/neg.ini"
expect neg 1 "neg.ini:2: [limits] cache_mb: expected an integer in 0..1048576, got '-5'"
printf '[limits]\nmax_res = 64.5\n%s\n' "$scene" > "$T/frac.ini"
expect frac 1 "[limits] max_res: expected an integer in 8..256"
printf '[server]\ndeadline_s = nan\n%s\n' "$scene" > "$T/nan.ini"
expect nan 1 "[server] deadline_s: expected a number in 0.1..86400, got 'nan'"
printf '[server]\nmax_connections_per_ip = 0\n%s\n' "$scene" > "$T/perip.ini"
expect perip 1 "perip.ini:2: [server] max_connections_per_ip: expected an integer in 1..1000, got '0'"
printf '[server]\nrequest_timeout_s = 0.1\n%s\n' "$scene" > "$T/reqto.ini"
expect reqto 1 "[server] request_timeout_s: expected a number in 0.5..3600, got '0.1'"
printf '[server]\nshutdown_grace_s = inf\n%s\n' "$scene" > "$T/grace.ini"
expect grace 1 "[server] shutdown_grace_s: expected a number in 0.1..3600, got 'inf'"
printf '[limits]\njob_deadline_s = -1\n%s\n' "$scene" > "$T/jobdl.ini"
expect jobdl 1 "[limits] job_deadline_s: expected a number in 0.1..604800, got '-1'"
printf '[server]\nmax_connections_per_ip = 8\nrequest_timeout_s = 2.5\nshutdown_grace_s = 1\n[limits]\njob_deadline_s = 60\n%s\n' "$scene" > "$T/newkeys.ini"
expect newkeys 0 "is valid: 1 scene(s)"
printf '[limits]\nmax_sessions = 0\n%s\n' "$scene" > "$T/maxsess.ini"
expect maxsess 1 "maxsess.ini:2: [limits] max_sessions: expected an integer in 1..100000, got '0'"
printf '[limits]\ncache_mb = 64\nsession_ttl_s = forever\n%s\n' "$scene" > "$T/ttl.ini"
expect ttl 1 "ttl.ini:3: [limits] session_ttl_s: expected a number in 0.1..604800, got 'forever'"
printf '[limits]\nmax_sessions = 4\nsession_ttl_s = 0.5\n%s\n' "$scene" > "$T/sess.ini"
expect sess 0 "is valid: 1 scene(s)"
printf '[cache]\nsize = 1\n%s\n' "$scene" > "$T/section.ini"
expect section 1 "section.ini:2: [cache] size: unknown section"
printf '[server]\nport = 0\nthis line has no equals sign\n%s\n' "$scene" > "$T/syntax.ini"
expect syntax 1 "syntax.ini:3: syntax error"
printf '[scene a b]\nsource = city\n' > "$T/badid.ini"
expect badid 1 "scene id 'a b' must be"
# The city's seed takes the full unsigned 64-bit range, as gi-bake --city-seed does.
printf '[server]\nport = 0\n[scene city]\nsource = city\nextent = 150\nseed = 18446744073709551615\n' > "$T/seedmax.ini"
expect seedmax 0 "is valid: 1 scene(s)"
printf '[server]\nport = 0\n[scene city]\nsource = city\nextent = 150\nseed = 18446744073709551616\n' > "$T/seedover.ini"
expect seedover 1 "seedover.ini:6: [scene city] seed: expected an integer in 0..18446744073709551615"
printf '[server]\nport = 0\n[scene city]\nsource = city\nextent = 150\nseed = -1\n' > "$T/seedneg.ini"
expect seedneg 1 "[scene city] seed: expected an integer in 0..18446744073709551615, got '-1'"
printf '[scene city]\nup = y\n' > "$T/nosource.ini"
expect nosource 1 "[scene city]: 'source' is required"
# The city is always Y-up: up = z was accepted and silently ignored.
printf '[scene city]\nsource = city\nup = z\n' > "$T/cityz.ini"
expect cityz 1 "cityz.ini:3: [scene city] up: the procedural city is always Y-up"
printf '[scene city]\nup = y\nsource = city\n' > "$T/cityy.ini"
expect cityy 0 "is valid: 1 scene(s)"
# Scene sections are taken at their header: an id of 44..63 characters was
# cut to 43 by inih (the scene served under another id), a section with no
# keys was no scene at all, and a header repeated right after the first
# merged into it.
long_id=$(printf 'a%.0s' $(seq 1 60))
printf '[scene %s]\nsource = city\nextent = 150\n' "$long_id" > "$T/longid.ini"
expect longid 0 "scene '$long_id': "
printf '%s\n[scene empty]\n' "$scene" > "$T/emptyscene.ini"
expect emptyscene 1 "emptyscene.ini:4: [scene empty]: 'source' is required"
printf '%s\n[scene city]\nseed = 2\n' "$scene" > "$T/twice.ini"
expect twice 1 "twice.ini:4: [scene city]: scene 'city' is defined twice (first on line 1)"
printf '[scene x]\nsource = missing.obj\n' > "$T/missing.ini"
expect missing 1 "missing.obj"
# A file that does not load is named at its source line, not the section's.
printf '[server]\nport = 0\n\n[scene x]\nsource = missing.obj\n' > "$T/missing5.ini"
expect missing5 1 "missing5.ini:5: [scene x] source: scene file"

printf '[scene x]\nsource = missing.obj\noptional = yes\n%s\n' "$scene" > "$T/optional.ini"
expect optional 0 "is valid: 1 scene(s)"
printf '[scene x]\nsource = missing.obj\nextent = 300\n' > "$T/cityonly.ini"
expect cityonly 1 "apply to source = city only"
printf '[server]\nport = 0\n' > "$T/empty.ini"
expect empty 1 "no [scene ID] sections"
printf 'short\n' > "$T/tok"
printf '[server]\ntoken_file = tok\n%s\n' "$scene" > "$T/token.ini"
expect token 1 "token_file: '$T/tok' must hold one token of 16..255 characters"
# A token no client can send (a line break or a space inside) made every
# request a 401: refused at start, with the config line; so is the variable.
printf 'abcdefghijklmnop\nqrstuvwxyz012345\n' > "$T/tok2"
printf '[server]\nport = 0\ntoken_file = tok2\n%s\n' "$scene" > "$T/token2.ini"
expect token2 1 "token2.ini:3: [server] token_file: '$T/tok2' must hold one token of visible ASCII"
out=$(GI_SERVER_TOKEN='0123456789abcdef 0123' "$BIN" --config "$T/good.ini" --check-config 2>&1); st=$?
[ "$st" -eq 1 ] && case "$out" in *"GI_SERVER_TOKEN must hold one token of visible ASCII"*) true;; *) false;; esac \
  && echo "ok: GI_SERVER_TOKEN with a space: $out" || fail "GI_SERVER_TOKEN with a space: exit $st: $out"
printf '[server]\ntmp_dir = nowhere\n%s\n' "$scene" > "$T/tmpdir.ini"
expect tmpdir 1 "tmp_dir: '$T/nowhere' is not a writable folder"
expect absent 1 "absent.ini: cannot open config"
printf '[limits]\nmax_probes_inline = 10\nmax_probes_job = 5\n%s\n' "$scene" > "$T/order.ini"
expect order 1 "max_probes_inline (10) exceeds max_probes_job (5)"
# Errors found after the parse name the line too: the later of the two keys,
# and where tmp_dir was set.
expect order 1 "order.ini:3: [limits] max_probes_job: max_probes_inline (10) exceeds"
expect tmpdir 1 "tmpdir.ini:2: [server] tmp_dir: '$T/nowhere' is not a writable folder"
# A key given twice: the last value silently won, also across a repeated
# [limits] and for an indented line (inih makes it a second value of the key
# above: "workers = 2" then "  8" set 8 workers).
printf '[server]\nworkers = 2\nport = 0\nworkers = 8\n%s\n' "$scene" > "$T/dupkey.ini"
expect dupkey 1 "dupkey.ini:4: [server] workers: given twice (first on line 2"
printf '[limits]\nmax_res = 32\n[server]\nport = 0\n[limits]\nmax_res = 16\n%s\n' "$scene" > "$T/dupsec.ini"
expect dupsec 1 "dupsec.ini:6: [limits] max_res: given twice (first on line 2"
printf '[server]\nworkers = 2\n   8\n%s\n' "$scene" > "$T/indent.ini"
expect indent 1 "indent.ini:3: [server] workers: given twice (first on line 2; an indented line"
printf '%s\nup = y\nup = z\n' "$scene" > "$T/dupscene.ini"
expect dupscene 1 "dupscene.ini:5: [scene city] up: given twice (first on line 4"
# bind is an IPv4 address: checked with its line, and by --check-config
# (which said "valid" while the real start then failed without a line).
printf '[server]\nport = 0\nbind = localhost\n%s\n' "$scene" > "$T/bind.ini"
expect bind 1 "bind.ini:3: [server] bind: expected an IPv4 address, got 'localhost'"
# What inih misreads is refused with its line: a line longer than inih's
# buffer (the rest became a "line 3" syntax error, or a second value for
# the key when it began with a space), a NUL byte (the rest of the line
# dropped), and a folder given as the config (read as an empty file).
long=$(printf 'w%.0s' $(seq 1 250))
printf '[scene x]\nsource = %s.obj\n' "$long" > "$T/long.ini"
expect long 1 "long.ini:2: line longer than 199 characters"
printf '[server]\nport = 0 ; %s\n%s\n' "$(printf 'word %.0s' $(seq 1 60))" "$scene" > "$T/longc.ini"
expect longc 1 "longc.ini:2: line longer than 199 characters"
printf '[server]\nport = 0\000 1\n%s\n' "$scene" > "$T/nul.ini"
expect nul 1 "nul.ini:2: a NUL byte"
mkdir "$T/dir.ini"
expect dir 1 "dir.ini: cannot read config: Is a directory"
# A scene file flat along z without 'up' (an OpenStreetMap export): loaded
# with y up and a note naming the fix; none once 'up' is given.
printf 'v 0 0 0\nv 100 0 0\nv 100 80 0\nv 0 80 0\nv 10 10 0\nv 10 10 12\nv 20 10 12\nf 1 2 3 4\nf 5 6 7\n' > "$T/flat.obj"
printf '[scene flat]\nsource = flat.obj\n' > "$T/flat.ini"
expect flat 0 "[scene flat] is flat along z (100 x 80 x 12) and has no 'up': read with y up; if z is up"
printf '[scene flat]\nsource = flat.obj\nup = z\n' > "$T/flatz.ini"
expect flatz 0 "is valid: 1 scene(s)"
case "$("$BIN" --config "$T/flatz.ini" --check-config 2>&1)" in *"flat along z"*) fail "flatz: a note with up = z";; esac

# A --port-file that cannot be written stops the start (exit 1) and takes
# the private folder it had made in tmp_dir with it.
mkdir "$T/tmpd"
printf '[server]\nport = 0\ntmp_dir = tmpd\n%s\n' "$scene" > "$T/pf.ini"
"$BIN" --config "$T/pf.ini" --port-file "$T/nowhere/port" > /dev/null 2> "$T/pf.err"; st=$?
left=$(ls "$T/tmpd")
[ "$st" -eq 1 ] && grep -q -- "--port-file: cannot write" "$T/pf.err" && [ -z "$left" ] \
  && echo "ok: unwritable --port-file: exit 1, nothing left in tmp_dir" || fail "port-file: exit $st, left '$left'"

# Bad command lines exit 2.
"$BIN" --port 70000 >/dev/null 2>&1; [ $? -eq 2 ] || fail "--port 70000 should exit 2"
"$BIN" --frobnicate >/dev/null 2>&1; [ $? -eq 2 ] || fail "--frobnicate should exit 2"
"$BIN" --config >/dev/null 2>&1; [ $? -eq 2 ] || fail "--config without a value should exit 2"
# --bind is checked as an argument (exit 2 naming it), not at listen time
# as the config's [server] bind (exit 1, after loading every scene).
out=$("$BIN" --config "$T/good.ini" --bind localhost --check-config 2>&1); st=$?
[ "$st" -eq 2 ] && case "$out" in *"--bind: expected an IPv4 address, got 'localhost'"*) true;; *) false;; esac \
  && echo "ok: --bind localhost: exit 2" || fail "--bind localhost: exit $st: $out"
out=$("$BIN" --config "$T/good.ini" --config "$T/workers.ini" --check-config 2>&1); st=$?
[ "$st" -eq 2 ] && case "$out" in *"--config given twice"*) true;; *) false;; esac \
  && echo "ok: --config twice: exit 2" || fail "--config twice: exit $st: $out"
"$BIN" --help | grep -q -- "--port-file" || fail "--help lacks --port-file"

# Why it cannot listen: the address is not this host's, or another process
# listens on the port (both were "in use, or not permitted").
out=$(timeout 60 "$BIN" --config "$T/good.ini" --bind 192.0.2.1 --port 0 2>&1); st=$?
[ "$st" -ne 0 ] && case "$out" in *"cannot listen on 192.0.2.1:0: no interface of this host has that address"*) true;;
  *) false;; esac && echo "ok: an address not on this host is named as such" || fail "bind 192.0.2.1: exit $st: $out"
python3 -c 'import socket, sys, time
s = socket.socket(); s.bind(("127.0.0.1", 0)); s.listen(1)
print(s.getsockname()[1], flush=True); time.sleep(60)' > "$T/busy" &
busy=$!
for _ in 1 2 3 4 5 6 7 8 9 10; do [ -s "$T/busy" ] && break; sleep 0.2; done
port=$(cat "$T/busy")
out=$(timeout 60 "$BIN" --config "$T/good.ini" --bind 127.0.0.1 --port "$port" 2>&1); st=$?
kill $busy 2> /dev/null
[ "$st" -ne 0 ] && case "$out" in *"cannot listen on 127.0.0.1:$port: another process listens there"*) true;;
  *) false;; esac && echo "ok: a port in use is named as such" || fail "port $port in use: exit $st: $out"

[ "$FAILS" -eq 0 ] && { echo "all passed"; exit 0; }
echo "$FAILS failure(s)" >&2; exit 1
