/* taps.c: the growth of a march's tap record (trace.h: gi_tap_rec). Its
 * own file: both builds of the march call it, and march.c calls them. */
#include "base/internal.h"
#include "trace/trace.h"

int gi__tap_grow(gi_tap_rec *r) {
  if (r->full) return 0;
  size_t cap = r->cap ? 2 * r->cap : 1024;
  if (cap > r->max) cap = r->max;
  gi_tap *t = cap > r->cap ? gi__realloc(r->t, cap * sizeof *t) : NULL;
  if (!t) {
    /* Past max is the caller's budget; a failed realloc is out of memory. */
    r->oom = cap > r->cap;
    r->full = 1;
    return 0;
  }
  r->t = t, r->cap = cap;
  return 1;
}
