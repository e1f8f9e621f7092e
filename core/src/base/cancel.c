/* cancel.c: the cancel token (gi_cancel.h) and the stage-side check.
 *
 * The flag and the deadline are atomics: one thread sets them while the
 * workers of any number of calls read them. The deadline is kept in whole
 * microseconds so it fits an atomic integer. */
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
  long long us = deadline_ms > 0 ? (long long)(deadline_ms * GI_US_PER_MS) : 0;
  /* A deadline at time 0 would read as "none": keep it in the past instead. */
  if (deadline_ms > 0 && us == 0) us = 1;
  atomic_store(&c->deadline_us, us);
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

/* The wrapped chunk function: skips the chunk (and stops the loop) once the
 * token fired. One flag load and at most one clock read per chunk. */
typedef struct {
  gi__range_fn fn;
  void *ctx;
  const gi_cancel *cancel;
  atomic_int *stop;
  atomic_int fired;
} cancel_ctx;

static void cancel_range(void *p, size_t b, size_t e, int worker) {
  cancel_ctx *cc = p;
  if (gi_cancel_check(cc->cancel) != GI_CANCEL_NONE) {
    atomic_store(&cc->fired, 1);
    atomic_store(cc->stop, 1);
    return;
  }
  cc->fn(cc->ctx, b, e, worker);
}

int gi__parallel_for_cancel(size_t n, size_t grain, int threads, gi__range_fn fn, void *ctx, atomic_int *stop,
                            const gi_cancel *cancel) {
  atomic_int own;
  atomic_init(&own, 0);
  if (!stop) stop = &own;
  if (!cancel) {
    gi__parallel_for_stop(n, grain, threads, fn, ctx, stop == &own ? NULL : stop);
    return 0;
  }
  if (gi_cancel_check(cancel) != GI_CANCEL_NONE) return 1;
  cancel_ctx cc = {.fn = fn, .ctx = ctx, .cancel = cancel, .stop = stop};
  atomic_init(&cc.fired, 0);
  gi__parallel_for_stop(n, grain, threads, cancel_range, &cc, stop);
  return atomic_load(&cc.fired);
}
