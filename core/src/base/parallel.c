/* parallel.c: a blocking parallel-for on pthreads.
 *
 * Each call starts its workers and joins them: a stage runs for
 * milliseconds, thread start-up costs microseconds, and there is no pool
 * state to share between concurrent requests. Chunks are handed out by an
 * atomic counter, so uneven chunks balance themselves. */
#include <pthread.h>
#include <stdatomic.h>
#include <time.h>
#include <unistd.h>
#include "base/internal.h"

#define GI_MAX_WORKERS 256

typedef struct {
  size_t n, grain;
  atomic_size_t next;
  gi__range_fn fn;
  void *ctx;
  atomic_int *stop;    /* optional: no chunk starts once it is set */
} job;

typedef struct {
  job *j;
  int id;
} worker_arg;

static void run(job *j, int id) {
  for (;;) {
    size_t b = atomic_fetch_add(&j->next, j->grain);
    if (b >= j->n || (j->stop && atomic_load_explicit(j->stop, memory_order_relaxed))) break;
    size_t e = b + j->grain < j->n ? b + j->grain : j->n;
    j->fn(j->ctx, b, e, id);
  }
}

static void *worker_main(void *p) {
  worker_arg *a = p;
  run(a->j, a->id);
  return NULL;
}

int gi__num_workers(int threads) {
  if (threads <= 0) {
    long c = sysconf(_SC_NPROCESSORS_ONLN);
    threads = c > 0 ? (int)c : 1;
  }
  return threads > GI_MAX_WORKERS ? GI_MAX_WORKERS : threads;
}

void gi__parallel_for(size_t n, size_t grain, int threads, gi__range_fn fn, void *ctx) {
  gi__parallel_for_stop(n, grain, threads, fn, ctx, NULL);
}

void gi__parallel_for_stop(size_t n, size_t grain, int threads, gi__range_fn fn, void *ctx, atomic_int *stop) {
  if (n == 0) return;
  if (grain == 0) grain = 1;
  int t = gi__num_workers(threads);
  size_t chunks = (n + grain - 1) / grain;
  if ((size_t)t > chunks) t = (int)chunks;
  job j = {.n = n, .grain = grain, .fn = fn, .ctx = ctx, .stop = stop};
  atomic_init(&j.next, 0);
  if (t <= 1) {
    run(&j, 0);
    return;
  }
  pthread_t tid[GI_MAX_WORKERS];
  worker_arg args[GI_MAX_WORKERS];
  int started = 0;
  for (int i = 1; i < t; i++) {
    args[i].j = &j;
    args[i].id = i;
    if (pthread_create(&tid[i], NULL, worker_main, &args[i]) != 0) break;
    started = i;
  }
  run(&j, 0); /* the caller works too; it also finishes if a create failed */
  for (int i = 1; i <= started; i++) pthread_join(tid[i], NULL);
}

double gi__now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}
