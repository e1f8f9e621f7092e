#!/bin/sh
# Every public header compiles on its own, first in a translation unit, as
# strict C99 and as C++11, with warnings as errors: a header that forgets an
# include, uses a C11-only construct or lacks extern "C" fails here.
# Usage: check-headers.sh INCLUDE_DIR CC CXX
set -u
inc=$1 cc=$2 cxx=$3
tmp=$(mktemp -d) || exit 1
trap 'rm -rf "$tmp"' EXIT
pass=0 fail=0
for h in "$inc"/gi/*.h; do
  name=$(basename "$h")
  printf '#include "gi/%s"\nint main(void) { return 0; }\n' "$name" > "$tmp/t.c"
  printf '#include "gi/%s"\nint main() { return 0; }\n' "$name" > "$tmp/t.cpp"
  if "$cc" -std=c99 -pedantic-errors -Wall -Wextra -Werror -I"$inc" -c "$tmp/t.c" -o "$tmp/t.o" 2> "$tmp/err"; then
    pass=$((pass + 1))
  else
    fail=$((fail + 1)); echo "FAIL C99: $name"; cat "$tmp/err"
  fi
  if "$cxx" -std=c++11 -pedantic-errors -Wall -Wextra -Werror -I"$inc" -c "$tmp/t.cpp" -o "$tmp/t.o" 2> "$tmp/err"; then
    pass=$((pass + 1))
  else
    fail=$((fail + 1)); echo "FAIL C++11: $name"; cat "$tmp/err"
  fi
  # Each header says who owns what and what is thread-safe, in its opening comment.
  if head -40 "$h" | grep -qi 'thread'; then
    pass=$((pass + 1))
  else
    fail=$((fail + 1)); echo "FAIL docs: $name says nothing about threads in its opening comment"
  fi
done
count=$(ls "$inc"/gi/*.h | wc -l)
echo "$count headers: $pass passed, $fail failed"
[ "$count" -ge 10 ] && [ "$fail" -eq 0 ]
