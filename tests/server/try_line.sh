#!/bin/sh
# try_line.sh: the "try: curl ..." line gi-server prints when it listens
# (what `make run` shows a new user) fetches a probe EXR when run as printed.
# Without -L it saved the viewpoint URL's 307 body (JSON) under *.exr.
# Usage: sh try_line.sh path/to/gi-server
set -u
SERVER=${1:?usage: sh try_line.sh path/to/gi-server}
set -- "$SERVER"
. "$(dirname "$0")/../cli/common.sh"
command -v curl > /dev/null || { skip "curl is not installed"; exit 77; }
start_city_server "$SERVER" 60

line=$(sed -n 's/^try: //p' "$T/server.out")
[ -n "$line" ] || { fail "no 'try:' line in: $(cat "$T/server.out")"; finish; }
(cd "$T" && sh -c "$line -s") || fail "'$line' exited $?"
# An EXR starts with the magic 76 2f 31 01.
magic=$(od -An -tx1 -N4 "$T/city-probe.exr" 2> /dev/null | tr -d ' \n')
[ "$magic" = "762f3101" ] && pass "'$line' wrote an EXR" \
  || fail "'$line' wrote no EXR (first bytes '$magic'): $(head -c 200 "$T/city-probe.exr" 2> /dev/null)"
finish
