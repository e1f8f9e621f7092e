/* alloc.c: every heap allocation of the core goes through here.
 *
 * The wrappers are malloc/calloc/realloc/free plus two atomic counters, so
 * memory from gi__malloc may be released by plain free() and vice versa;
 * the counters only stay balanced when the core frees its own memory. A
 * buffer handed to a caller who frees it with free() is passed to
 * gi__alloc_release, which takes it out of the count.
 *
 * The counters serve the tests (base/alloc_test.h): gi__alloc_live() finds
 * leaks in a normal build, gi__alloc_fail_after(n) makes the n-th
 * allocation from now fail so every out-of-memory path can be walked. */
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include "base/alloc_test.h"
#include "base/internal.h"

static atomic_long live;          /* successful allocations minus frees */
static atomic_long attempts;      /* every allocation call, failed or not */
static atomic_long countdown = -1; /* allocations left before the injected failure; < 0: none armed */

/* 1 when this allocation is the one the test asked to fail. */
static int injected_failure(void) {
  atomic_fetch_add_explicit(&attempts, 1, memory_order_relaxed);
  if (atomic_load_explicit(&countdown, memory_order_relaxed) < 0) return 0;
  return atomic_fetch_sub(&countdown, 1) == 0;
}

void *gi__malloc(size_t n) {
  if (injected_failure()) return NULL;
  void *p = malloc(n ? n : 1);
  if (p) atomic_fetch_add_explicit(&live, 1, memory_order_relaxed);
  return p;
}

void *gi__calloc(size_t n, size_t size) {
  if (injected_failure()) return NULL;
  void *p = calloc(n ? n : 1, size ? size : 1);
  if (p) atomic_fetch_add_explicit(&live, 1, memory_order_relaxed);
  return p;
}

void *gi__realloc(void *p, size_t n) {
  if (injected_failure()) return NULL; /* p stays valid, as with realloc */
  void *q = realloc(p, n ? n : 1);
  if (q && !p) atomic_fetch_add_explicit(&live, 1, memory_order_relaxed);
  return q;
}

char *gi__strdup(const char *s) {
  size_t n = strlen(s) + 1;
  char *d = gi__malloc(n);
  if (d) memcpy(d, s, n);
  return d;
}

void gi__free(void *p) {
  if (!p) return;
  atomic_fetch_sub_explicit(&live, 1, memory_order_relaxed);
  free(p);
}

void gi__alloc_release(void *p) {
  if (p) atomic_fetch_sub_explicit(&live, 1, memory_order_relaxed);
}

void gi__alloc_fail_after(long n) { atomic_store(&countdown, n < 0 ? -1 : n); }

long gi__alloc_live(void) { return atomic_load(&live); }

long gi__alloc_attempts(void) { return atomic_load(&attempts); }

int gi__alloc_fail_armed(void) { return atomic_load(&countdown) >= 0; }
