/* test_parallel.c: the persistent worker pool behind gi__parallel_for.
 *   every index runs exactly once, for any grain and thread count;
 *   worker ids stay below gi__num_workers(threads) and no two workers of
 *     one call hold the same id at once; threads = 1 runs on the caller;
 *     at most `threads` workers run one call at once;
 *   nested calls, and calls from several application threads at once
 *     (each nesting more calls), finish with the right sums;
 *   a call finishes even while every pool thread is stuck in another call's
 *     chunk: the caller works its own job;
 *   a bake answers the same bits on 1, 2 and 3 threads (a race or a
 *     thread-dependent path shows; a reassociated double sum too small to
 *     reach a float would not). */
#include "test_util.h"
#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi.h"
#include "base/internal.h"

#define MAX_IDS 256
#define SPIN_ROUNDS 2000 /* a little work per index so chunks overlap */

typedef struct {
  atomic_int *hits;          /* per index */
  atomic_int in_use[MAX_IDS];/* per worker id: 1 while a chunk runs with it */
  atomic_int running, max_running;
  atomic_int bad_id, clash;
  int id_bound;
  pthread_t caller;
  atomic_int off_caller;     /* chunks run by a thread other than the caller */
} count_ctx;

static void spin(void) {
  volatile unsigned x = 0;
  for (int i = 0; i < SPIN_ROUNDS; i++) x += (unsigned)i;
}

static void count_range(void *p, size_t b, size_t e, int worker) {
  count_ctx *c = p;
  if (worker < 0 || worker >= c->id_bound) {
    atomic_fetch_add(&c->bad_id, 1);
    return;
  }
  if (atomic_exchange(&c->in_use[worker], 1)) atomic_fetch_add(&c->clash, 1);
  int now = atomic_fetch_add(&c->running, 1) + 1, m = atomic_load(&c->max_running);
  while (now > m && !atomic_compare_exchange_weak(&c->max_running, &m, now)) {}
  if (!pthread_equal(pthread_self(), c->caller)) atomic_fetch_add(&c->off_caller, 1);
  for (size_t i = b; i < e; i++) {
    atomic_fetch_add(&c->hits[i], 1);
    spin();
  }
  atomic_fetch_sub(&c->running, 1);
  atomic_store(&c->in_use[worker], 0);
}

/* Runs one counting call and checks coverage and ids; returns the most
 * workers seen at once. */
static int run_count(size_t n, size_t grain, int threads, int *off_caller) {
  count_ctx *c = calloc(1, sizeof *c);
  assert_non_null(c);
  c->hits = calloc(n ? n : 1, sizeof *c->hits);
  assert_non_null(c->hits);
  c->id_bound = gi__num_workers(threads);
  c->caller = pthread_self();
  gi__parallel_for(n, grain, threads, count_range, c);
  for (size_t i = 0; i < n; i++) assert_int_equal(atomic_load(&c->hits[i]), 1);
  assert_int_equal(atomic_load(&c->bad_id), 0);
  assert_int_equal(atomic_load(&c->clash), 0);
  int m = atomic_load(&c->max_running);
  if (off_caller) *off_caller = atomic_load(&c->off_caller);
  free(c->hits);
  free(c);
  return m;
}

static void test_coverage_and_ids(void **state) {
  const size_t ns[] = {0, 1, 7, 1000, 10007};
  const size_t grains[] = {0, 1, 3, 64, 100000};
  const int threads[] = {0, 1, 2, 3, 8};
  for (size_t i = 0; i < sizeof ns / sizeof *ns; i++)
    for (size_t g = 0; g < sizeof grains / sizeof *grains; g++)
      for (size_t t = 0; t < sizeof threads / sizeof *threads; t++) {
        int most = run_count(ns[i], grains[g], threads[t], NULL);
        int cap = gi__num_workers(threads[t]);
        assert_true(most <= cap);
      }
}

static void test_one_thread_runs_on_caller(void **state) {
  int off = -1;
  assert_int_equal(run_count(5000, 10, 1, &off), 1);
  assert_int_equal(off, 0);
}

/* Nested: each outer index sums 0..INNER-1 with its own parallel call. */
#define OUTER 16
#define INNER 2000
typedef struct {
  atomic_llong sums[OUTER];
} nest_ctx;
typedef struct {
  atomic_llong *sum;
} inner_ctx;

static void inner_range(void *p, size_t b, size_t e, int worker) {
  inner_ctx *ic = p;
  long long s = 0;
  for (size_t i = b; i < e; i++) s += (long long)i;
  atomic_fetch_add(ic->sum, s);
}

static void outer_range(void *p, size_t b, size_t e, int worker) {
  nest_ctx *nc = p;
  for (size_t i = b; i < e; i++) {
    inner_ctx ic = {&nc->sums[i]};
    gi__parallel_for(INNER, 17, 0, inner_range, &ic);
  }
}

static void run_nested(void) {
  nest_ctx nc;
  for (int i = 0; i < OUTER; i++) atomic_init(&nc.sums[i], 0);
  gi__parallel_for(OUTER, 1, 0, outer_range, &nc);
  for (int i = 0; i < OUTER; i++) assert_true(atomic_load(&nc.sums[i]) == (long long)INNER * (INNER - 1) / 2);
}

static void test_nested(void **state) { run_nested(); }

#define APP_THREADS 4
#define CALLS_PER_THREAD 20
static void *app_thread(void *arg) {
  (void)arg;
  for (int k = 0; k < CALLS_PER_THREAD; k++) {
    run_nested();
    run_count(3000, 5, 0, NULL);
  }
  return NULL;
}

static void test_concurrent_callers(void **state) {
  pthread_t t[APP_THREADS];
  for (int i = 0; i < APP_THREADS; i++) assert_int_equal(pthread_create(&t[i], NULL, app_thread, NULL), 0);
  for (int i = 0; i < APP_THREADS; i++) assert_int_equal(pthread_join(t[i], NULL), 0);
}

/* A call whose chunks wait until released: it holds every pool thread that
 * joins it, and its own caller. */
typedef struct {
  atomic_int release, entered;
} hold_ctx;

static void hold_range(void *p, size_t b, size_t e, int worker) {
  hold_ctx *h = p;
  atomic_fetch_add(&h->entered, 1);
  while (!atomic_load(&h->release)) sched_yield();
}

static void *holder(void *arg) {
  gi__parallel_for(1024, 1, 0, hold_range, arg);
  return NULL;
}

static void test_progress_while_pool_busy(void **state) {
  hold_ctx h;
  atomic_init(&h.release, 0);
  atomic_init(&h.entered, 0);
  pthread_t t;
  assert_int_equal(pthread_create(&t, NULL, holder, &h), 0);
  while (atomic_load(&h.entered) < 1) sched_yield();
  /* Whatever the holder took, this call still completes (on this thread if
   * need be), with every index once. */
  int most = run_count(2000, 4, 0, NULL);
  int held = atomic_load(&h.entered);
  atomic_store(&h.release, 1);
  assert_int_equal(pthread_join(t, NULL), 0);
  printf("while %d worker%s held the other call, this one ran on %d at most\n", held, held > 1 ? "s" : "", most);
  assert_true(most >= 1 && held >= 1);
}

/* A closed room under a lamp: bounces, the tail and its energy ratio all
 * run; the probes, the bounces' sums behind them, must not move with the
 * thread count. */
static void test_bake_same_bits_any_threads(void **state) {
  (void)state;
  gi_scene *s = tu_lit_room(0.7f);
  assert_non_null(s);
  enum { NP = 4 };
  const double pts[NP * 3] = {0, 1.2, 0, 1.5, 0.3, 1.5, -1.2, 1.0, -0.2, -1.8, 2.3, 1.8};
  gi_probe first[NP], got[NP];
  for (int t = 1; t <= 3; t++) {
    gi_error_info err = {0};
    gi_quality q = {.levels = 3, .res = 32, .voxel0 = 0.125, .threads = t};
    gi_cascade *c = NULL;
    double at[3] = {0, 1.2, 0};
    assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
    assert_true(gi_cascade_report(c)->bounces_run >= 2);
    assert_int_equal(gi_cascade_gather(c, pts, NP, t == 1 ? first : got, NULL, &err), GI_OK);
    if (t > 1) assert_memory_equal(first, got, sizeof first);
    gi_cascade_free(c);
  }
  printf("probe indirect %.6f on 1, 2 and 3 threads\n", first[0].indirect[0]);
  assert_true(first[0].indirect[0] > 0);
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_coverage_and_ids),
      cmocka_unit_test(test_one_thread_runs_on_caller),
      cmocka_unit_test(test_nested),
      cmocka_unit_test(test_concurrent_callers),
      cmocka_unit_test(test_progress_while_pool_busy),
      cmocka_unit_test(test_bake_same_bits_any_threads),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
