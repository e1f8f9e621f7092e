#!/bin/sh
# check-install.sh BUILD LIBDIR VERSION SONAME SCENES_DIR CC CMAKE [CFLAGS [LDFLAGS]]
#
# Installs the built tree into a temporary prefix (cmake --install) and
# checks what a downstream user gets: the layout, libgi.so's SONAME and its
# exports (the public gi_* functions, no gi__* internals), then builds
# prog.c against the prefix by pkg-config (shared, and static with
# --static), and by find_package(gi) (gi::gi, and gi::gi_static). Every
# program must print the same probe as the installed gi-bake --json for the
# same scene, point and quality: the embedded city always, the Cornell box
# when the shared scenes are present (exit 77, "Skipped", when not).
# CFLAGS and LDFLAGS are the tree's own (sanitizer builds need them).
set -eu
build=$1 libdir=$2 version=$3 soname=$4 scenes=$5 cc=$6 cmake=$7 cflags=${8:-} ldflags=${9:-}
here=$(cd "$(dirname "$0")" && pwd)
tmp=$(mktemp -d "${TMPDIR:-/tmp}/gi-install.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
prefix=$tmp/prefix
lib=$prefix/$libdir
# The quality prog.c bakes at; gi-bake gets the same on its command line.
quality="--levels 3 --res 8 --bounces 1 --samples 4 --probe-samples 16 --threads 2"
cornell=$scenes/cornell-box/cornell-box.obj
cornell_at="278 273 279.6"

fail() { echo "FAIL: $*" >&2; exit 1; }

"$cmake" --install "$build" --prefix "$prefix" >"$tmp/install.log" 2>&1 \
  || { cat "$tmp/install.log"; fail "cmake --install $build"; }

for f in bin/gi-server bin/gi-bake bin/gi-client bin/gi-accuracy include/gi/gi.h include/gi/gi_bake.h \
         "$libdir/libgi.a" "$libdir/libgi.so" "$libdir/$soname" "$libdir/libgi.so.$version" \
         "$libdir/pkgconfig/gi.pc" "$libdir/cmake/gi/giConfig.cmake" "$libdir/cmake/gi/giConfigVersion.cmake"; do
  test -e "$prefix/$f" || fail "$f not installed"
done
test -L "$lib/libgi.so" && test -L "$lib/$soname" && test ! -L "$lib/libgi.so.$version" \
  || fail "libgi.so -> $soname -> libgi.so.$version symlinks"
got=$(readelf -d "$lib/libgi.so.$version" | sed -n 's/.*Library soname: \[\(.*\)\]/\1/p')
test "$got" = "$soname" || fail "SONAME is '$got', expected $soname"
for h in "$here"/../../core/include/gi/*.h; do
  cmp -s "$h" "$prefix/include/gi/$(basename "$h")" || fail "header $(basename "$h") not installed as is"
done

# Exports: exactly the public API. Every function a public header declares,
# nothing internal (gi__*), nothing from the dependencies or the C++ shim.
nm -D --defined-only "$lib/libgi.so" | awk '{print $3}' | sort -u >"$tmp/exported"
grep -hoE '\bgi_[a-z0-9_]+[[:space:]]*\(' "$prefix"/include/gi/*.h | sed 's/[[:space:](]//g' | sort -u >"$tmp/declared"
test -s "$tmp/declared" || fail "no functions found in the public headers"
missing=$(comm -23 "$tmp/declared" "$tmp/exported")
test -z "$missing" || fail "declared but not exported by libgi.so: $missing"
extra=$(comm -13 "$tmp/declared" "$tmp/exported")
test -z "$extra" || fail "exported by libgi.so but in no public header: $extra"
echo "libgi.so ($soname) exports the $(wc -l <"$tmp/exported") public functions and nothing else"
# libgi.a hides nothing: a static link puts every global symbol of the
# members it pulls beside the program's own, so the C ones carry the gi_
# prefix too (the reference's ref_hash clashed with a program's own).
nm -g --defined-only "$lib/libgi.a" 2>/dev/null | awk 'NF == 3 && $2 ~ /^[TDBR]$/ {print $3}' \
  | grep -v '^gi_' | sort -u >"$tmp/archive_extra" || true
test ! -s "$tmp/archive_extra" || fail "libgi.a defines global symbols without the gi_ prefix: $(tr '\n' ' ' <"$tmp/archive_extra")"

# A program built against libgi.so needs it, and none of its dependencies.
only_libgi() { # PROGRAM
  needed=$(readelf -d "$1" | sed -n 's/.*Shared library: \[\(.*\)\]/\1/p' | tr '\n' ' ')
  case "$needed" in *"$soname"*) ;; *) fail "$1 does not need $soname: $needed";; esac
  case "$needed" in *embree*|*openvdb*|*OpenEXR*|*assimp*|*tbb*|*png*|*jpeg*) fail "$1 links libgi's dependencies: $needed";; esac
}

# (a) pkg-config, shared: the program needs libgi.so alone, not its
# dependencies; gi.pc alone suffices (no other .pc on the search path).
flags=$(PKG_CONFIG_LIBDIR="$lib/pkgconfig" PKG_CONFIG_PATH= pkg-config --cflags --libs gi) \
  || fail "pkg-config gi needs more than gi.pc"
test "$(PKG_CONFIG_LIBDIR="$lib/pkgconfig" pkg-config --modversion gi)" = "$version" || fail "gi.pc version"
# shellcheck disable=SC2086
"$cc" -std=c11 -Wall -Werror $cflags -o "$tmp/prog_pc" "$here/prog.c" $flags $ldflags -Wl,-rpath,"$lib" \
  || fail "build against pkg-config gi"
only_libgi "$tmp/prog_pc"

# (b) pkg-config --static: libgi.a (named explicitly; -lgi would pick the
# .so) plus gi.pc's Libs.private.
export PKG_CONFIG_PATH="$lib/pkgconfig"
# shellcheck disable=SC2046,SC2086
"$cc" -std=c11 -Wall -Werror $cflags -o "$tmp/prog_pc_static" "$here/prog.c" \
  $(pkg-config --static --cflags --libs gi | sed 's/-lgi\b/-l:libgi.a/') $ldflags \
  || fail "static build against pkg-config gi"
if readelf -d "$tmp/prog_pc_static" | grep -q 'libgi\.so'; then fail "prog_pc_static needs libgi.so"; fi

# (c) find_package(gi): gi::gi (prog) and gi::gi_static (prog_static).
"$cmake" -S "$here/consumer" -B "$tmp/cmake" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_C_COMPILER="$cc" \
  -DCMAKE_BUILD_TYPE=Release -DGI_STATIC=ON -DCMAKE_C_FLAGS="$cflags" -DCMAKE_CXX_FLAGS="$cflags" \
  -DCMAKE_EXE_LINKER_FLAGS="$ldflags" >"$tmp/cmake.log" 2>&1 \
  && "$cmake" --build "$tmp/cmake" -j 2 >>"$tmp/cmake.log" 2>&1 \
  || { cat "$tmp/cmake.log"; fail "find_package(gi) project"; }
only_libgi "$tmp/cmake/prog"
if readelf -d "$tmp/cmake/prog_static" | grep -q 'libgi\.so'; then fail "prog_static needs libgi.so"; fi
# A C-only project asking for gi::gi_static learns it must enable C++
# (OpenVDB's package needs a C++ compiler), not a Boost internal error.
mkdir -p "$tmp/conly"
printf 'cmake_minimum_required(VERSION 3.16)\nproject(conly C)\nfind_package(gi REQUIRED COMPONENTS static)\n' \
  >"$tmp/conly/CMakeLists.txt"
if "$cmake" -S "$tmp/conly" -B "$tmp/conly/b" -DCMAKE_PREFIX_PATH="$prefix" >"$tmp/conly.log" 2>&1; then
  fail "find_package(gi COMPONENTS static) passed in a C-only project"
fi
tr -s ' \n' ' ' <"$tmp/conly.log" | grep -q 'needs C++ enabled' \
  || { cat "$tmp/conly.log"; fail "find_package(gi COMPONENTS static) in a C-only project does not say C++ is needed"; }

# Debian's python3 (a pyenv shim on PATH costs seconds per call).
py=python3; test -x /usr/bin/python3 && py=/usr/bin/python3
progs="pkg-config:prog_pc pkg-config--static:prog_pc_static gi::gi:cmake/prog gi::gi_static:cmake/prog_static"

# Each program's probe against the installed gi-bake's --json probe: the
# same floats (each is printed with enough digits to round-trip).
compare() { # LABEL JSON then NAME OUTPUT pairs
  "$py" - "$@" <<'PY'
import json, struct, sys
label, jpath, rest = sys.argv[1], sys.argv[2], sys.argv[3:]
p = json.load(open(jpath))["probe"]
want = p["irradiance"] + p["direct"] + p["indirect"]
if not sum(want[:3]) > 0:
    sys.exit(f"FAIL: {label}: gi-bake's irradiance {want[:3]} is not positive")
f32 = lambda v: struct.unpack("f", struct.pack("f", v))[0]
for name, opath in zip(rest[::2], rest[1::2]):
    got = [float(v) for v in open(opath).read().split()]
    if len(got) != 9 or [f32(v) for v in got] != [f32(v) for v in want]:
        sys.exit(f"FAIL: {name} program on {label}: probe {got} differs from gi-bake's {want}")
PY
}
# The cascade a program wrote: the grids gi-bake wrote (names, types,
# bounds, active voxel counts; vdb_print, package libopenvdb-tools).
same_vdb() { # NAME BAKE.vdb PROG.vdb
  if command -v vdb_print >/dev/null 2>&1; then
    test -f "$2.txt" || vdb_print "$2" | sed "s|$2||" >"$2.txt" || fail "vdb_print $2"
    vdb_print "$3" | sed "s|$3||" >"$3.txt" || fail "$1: vdb_print"
    cmp -s "$2.txt" "$3.txt" || { diff "$2.txt" "$3.txt"; fail "$1: VDB grids differ from gi-bake's"; }
  else
    test -s "$3" || fail "$1: no VDB written"
  fi
}
check_scene() { # LABEL SCENE [X Y Z] (none: gi-bake's default viewpoint)
  label=$1 scene=$2; shift 2
  at=; test $# = 3 && at="--at $1,$2,$3"
  # shellcheck disable=SC2086
  "$prefix/bin/gi-bake" "$scene" $at $quality --vdb "$tmp/$label.vdb" --json >"$tmp/$label.json" 2>"$tmp/$label.err" \
    || { cat "$tmp/$label.err"; fail "installed gi-bake $scene"; }
  # shellcheck disable=SC2046
  set -- $("$py" -c 'import json,sys; print(*map(repr, json.load(open(sys.argv[1]))["viewpoint"]))' "$tmp/$label.json")
  pairs=
  for prog in $progs; do
    name=${prog%:*} exe=$tmp/${prog##*:} out=$tmp/$label.$(echo "${prog%:*}" | tr -c 'a-z\n' _)
    "$exe" "$scene" "$1" "$2" "$3" "$out.vdb" >"$out.txt" || fail "$name program on $label"
    same_vdb "$name program on $label" "$tmp/$label.vdb" "$out.vdb"
    pairs="$pairs $name $out.txt"
  done
  # shellcheck disable=SC2086
  compare "$label" "$tmp/$label.json" $pairs || exit 1
  echo "$label: all four programs print gi-bake's probe at ($1, $2, $3): $(cat "$out.txt")"
}

check_scene city city
if [ -f "$cornell" ]; then
  # shellcheck disable=SC2086
  check_scene cornell "$cornell" $cornell_at
else
  echo "SKIP: shared scene $cornell is absent: only the city was checked"
  exit 77
fi
