/* internal.h: helpers shared by the core's source files (not installed). */
#ifndef GI_INTERNAL_H
#define GI_INTERNAL_H

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include "gi/gi_error.h"

/* Records code and a printf-style message in err (which may be NULL) and
 * returns code, so callers write `return gi__fail(err, GI_ERR_IO, ...)`. */
gi_result gi__fail(gi_error_info *err, gi_result code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Runs fn(ctx, begin, end) over [0, n) in chunks of `grain` on up to
 * `threads` threads (0 = all cores). Blocks until all chunks are done.
 * fn must be safe to run concurrently on disjoint ranges. */
typedef void (*gi__range_fn)(void *ctx, size_t begin, size_t end, int worker);
void gi__parallel_for(size_t n, size_t grain, int threads, gi__range_fn fn, void *ctx);
/* Number of workers gi__parallel_for will use for `threads` (worker ids are 0..N-1). */
int gi__num_workers(int threads);

/* Monotonic clock in milliseconds. */
double gi__now_ms(void);

static inline int gi__finite3(const float v[3]) {
  return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

#endif
