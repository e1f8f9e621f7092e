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
#if defined(__linux__)
#include <sys/mman.h>
#endif
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

/* gi__big_calloc: blocks of at least this size are mapped from the kernel
 * on 2 MB boundaries and advised for transparent huge pages. */
#define GI_HUGE_PAGE ((size_t)2 << 20)
/* The mapping's start and length live this far before the block. */
#define GI_BIG_HEADER ((size_t)64)

/* Sanitizer builds map the block too: it is the path the product runs,
 * and ASan's own allocator took 130-210 ms to malloc and 150-240 ms to
 * free a costly request's 350 MB block, with no way to stop it (a
 * cancelled bake returned 400 ms late). The block is one allocation
 * either way, so ASan never saw an overrun from one array into the next;
 * the live count below still catches a block never freed. */
#if defined(__linux__) && defined(MADV_HUGEPAGE)
#define GI_BIG_MAP 1
#else
#define GI_BIG_MAP 0
#endif

void *gi__big_calloc(size_t n, size_t size) {
#if GI_BIG_MAP
  if (size && n > (SIZE_MAX - 2 * GI_HUGE_PAGE) / size) return NULL;
  size_t bytes = n * size;
  if (bytes >= GI_HUGE_PAGE) {
    if (injected_failure()) return NULL;
    /* Room to align the block and keep the header in front of it. */
    size_t len = bytes + 2 * GI_HUGE_PAGE;
    void *map = mmap(NULL, len, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (map == MAP_FAILED) return NULL;
    uintptr_t p = ((uintptr_t)map + GI_BIG_HEADER + GI_HUGE_PAGE - 1) & ~(uintptr_t)(GI_HUGE_PAGE - 1);
    /* Advice only: without huge pages the block is still zeroed memory. */
    (void)madvise((void *)p, (bytes + GI_HUGE_PAGE - 1) & ~(GI_HUGE_PAGE - 1), MADV_HUGEPAGE);
    void **hdr = (void **)(p - GI_BIG_HEADER);
    hdr[0] = map;
    hdr[1] = (void *)len;
    hdr[2] = (void *)p; /* a check that the block came from here */
    atomic_fetch_add_explicit(&live, 1, memory_order_relaxed);
    return (void *)p;
  }
#endif
  return gi__calloc(n, size);
}

void *gi__big_malloc(size_t bytes, int *zeroed) {
  *zeroed = 0;
#if GI_BIG_MAP
  if (bytes >= GI_HUGE_PAGE) {
    void *p = gi__big_calloc(bytes, 1); /* mapped: zero pages, nothing to clear */
    *zeroed = p != NULL;
    return p;
  }
#endif
  return gi__malloc(bytes ? bytes : 1);
}

void gi__big_free(void *p, size_t n, size_t size) {
  if (!p) return;
#if GI_BIG_MAP
  if (n * size >= GI_HUGE_PAGE) {
    void **hdr = (void **)((uintptr_t)p - GI_BIG_HEADER);
    if (hdr[2] == p) {
      atomic_fetch_sub_explicit(&live, 1, memory_order_relaxed);
      munmap(hdr[0], (size_t)hdr[1]);
      return;
    }
  }
#endif
  gi__free(p);
}

void gi__alloc_release(void *p) {
  if (p) atomic_fetch_sub_explicit(&live, 1, memory_order_relaxed);
}

void gi__alloc_fail_after(long n) { atomic_store(&countdown, n < 0 ? -1 : n); }

long gi__alloc_live(void) { return atomic_load(&live); }

long gi__alloc_attempts(void) { return atomic_load(&attempts); }

int gi__alloc_fail_armed(void) { return atomic_load(&countdown) >= 0; }
