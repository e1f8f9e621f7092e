/* cancel.c: the cancel token (gi_cancel.h) and the stage-side check.
 *
 * The flag and the deadline are atomics: one thread sets them while the
 * workers of any number of calls read them. The deadline is kept in whole
 * microseconds so it fits an atomic integer. */
#include <limits.h>
#include <stdatomic.h>
#include "base/internal.h"
#include "gi/gi_cancel.h"

#define GI_US_PER_MS 1000.0

struct gi_cancel {
  atomic_int flag;
  atomic_llong deadline_us; /* 0: none */
};

gi_cancel *gi_cancel_new(void) {
  gi_cancel *c = gi__calloc(1, sizeof *c);
  if (!c) return NULL;
  atomic_init(&c->flag, 0);
  atomic_init(&c->deadline_us, 0);
  return c;
}

void gi_cancel_free(gi_cancel *c) { gi__free(c); }

void gi_cancel_set(gi_cancel *c) {
  if (c) atomic_store(&c->flag, 1);
}

void gi_cancel_set_deadline(gi_cancel *c, double deadline_ms) {
  if (!c) return;
  double us = deadline_ms * GI_US_PER_MS;
  long long v;
  if (deadline_ms == 0) v = 0; /* none */
  /* Negative or NaN has passed (the clock is never below 0): stopping is
   * safer than a bake that runs on; 1 keeps it apart from "none". */
  else if (!(us >= 1)) v = 1;
  /* Past what a long long holds the conversion is undefined (1e300 gave
   * LLONG_MIN, "none" by luck); such a deadline is never reached. */
  else if (us >= 0x1p63) v = LLONG_MAX;
  else v = (long long)us;
  atomic_store(&c->deadline_us, v);
}

gi_cancel_reason gi_cancel_check(const gi_cancel *c) {
  if (!c) return GI_CANCEL_NONE;
  gi_cancel *m = (gi_cancel *)c; /* atomic loads need a non-const object in C11 */
  if (atomic_load_explicit(&m->flag, memory_order_relaxed)) return GI_CANCEL_REQUESTED;
  long long us = atomic_load_explicit(&m->deadline_us, memory_order_relaxed);
  if (us > 0 && gi__now_ms() * GI_US_PER_MS >= (double)us) return GI_CANCEL_DEADLINE;
  return GI_CANCEL_NONE;
}

double gi_now_ms(void) { return gi__now_ms(); }

gi_result gi__cancel_fail(const gi_cancel *c, gi_error_info *err, const char *stage) {
  gi_cancel_reason why = gi_cancel_check(c);
  return gi__fail(err, GI_ERR_CANCELLED, "%s: stopped because %s", stage,
                  why == GI_CANCEL_DEADLINE ? "the deadline passed" : "the caller cancelled");
}
