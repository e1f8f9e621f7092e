#!/bin/sh
# Installs the Debian 12 packages the build, the tests and the tools need.
# Idempotent: does nothing when every package is already installed.
# Groups for make targets beyond the build:
#   test      Blender, for `make test`'s lightmap round trip through it and
#             its Cycles against our path tracer (both skip loudly only
#             where Blender cannot be had)
# and for the opt-in ones, never needed by `make test`:
#   fuzz      clang and its libFuzzer runtime (make fuzz)
#   valgrind  valgrind (make valgrind)
#   nginx     nginx (make test-scale: tests/scale/nginx.sh)
#   slurm     slurm-wlm and munge (make test-scale: tests/scale/slurm.sh)
set -eu
PKGS="build-essential cmake pkg-config libembree-dev libopenexr-dev openexr
libopenvdb-dev libboost-dev libboost-iostreams-dev libopenvdb-tools python3-openvdb
libassimp-dev libtbb-dev libjansson-dev libcmocka-dev libmicrohttpd-dev
libcurl4-openssl-dev libinih-dev libpng-dev libjpeg62-turbo-dev python3
python3-yaml wrk gnuplot-nox"
for group in "$@"; do
  case "$group" in
    test) PKGS="$PKGS blender" ;;
    fuzz) PKGS="$PKGS clang-14 libclang-rt-14-dev" ;;
    valgrind) PKGS="$PKGS valgrind" ;;
    nginx) PKGS="$PKGS nginx" ;;
    slurm) PKGS="$PKGS slurm-wlm munge" ;;
    *) echo "install-deps: unknown group '$group' (known: test, fuzz, valgrind, nginx, slurm)" >&2; exit 2 ;;
  esac
done
missing=""
for p in $PKGS; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
[ -z "$missing" ] && exit 0
echo "install-deps: installing:$missing"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null 2>&1 || { echo "install-deps: need root or sudo to install:$missing" >&2; exit 1; }
  SUDO="sudo"
fi
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing
