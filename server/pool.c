/* pool.c: a fixed set of bake workers behind a bounded queue.
 *
 * Bounded on purpose: when more requests wait than the queue holds, the
 * front answers 503 with Retry-After at once instead of letting latency
 * grow without limit. Each bake parallelises internally (gi__parallel_for),
 * so a few workers keep the cores busy. */
#define _POSIX_C_SOURCE 200809L
#include <pthread.h>
#include <stdlib.h>
#include "server.h"

typedef struct {
  gs_task_fn fn;
  void *arg;
} task;

/* A task of gs_pool_submit_first, in a list of its own. */
typedef struct first_task {
  task t;
  struct first_task *next;
} first_task;

struct gs_pool {
  pthread_mutex_t mu;
  pthread_cond_t cv;
  task *ring;
  int cap, queue, head, count, busy, stop;
  first_task *first, *first_tail; /* taken before the ring's */
  int nthreads;
  pthread_t *threads;
};

static void *worker(void *p) {
  gs_pool *pl = p;
  pthread_mutex_lock(&pl->mu);
  for (;;) {
    while (!pl->count && !pl->first && !pl->stop) pthread_cond_wait(&pl->cv, &pl->mu);
    if (!pl->count && !pl->first && pl->stop) break;
    task t;
    if (pl->first) {
      first_task *f = pl->first;
      t = f->t;
      pl->first = f->next;
      if (!pl->first) pl->first_tail = NULL;
      free(f);
    } else {
      t = pl->ring[pl->head];
      pl->head = (pl->head + 1) % pl->cap;
      pl->count--;
    }
    pl->busy++;
    pthread_mutex_unlock(&pl->mu);
    t.fn(t.arg);
    pthread_mutex_lock(&pl->mu);
    pl->busy--;
  }
  pthread_mutex_unlock(&pl->mu);
  return NULL;
}

gs_pool *gs_pool_new(int workers, int queue_capacity) {
  gs_pool *p = calloc(1, sizeof *p);
  if (!p) return NULL;
  /* The ring holds tasks not yet taken: up to `queue` waiting plus one per
   * idle worker about to take its task. */
  p->queue = queue_capacity;
  p->cap = queue_capacity + workers + 1;
  p->ring = calloc((size_t)p->cap, sizeof *p->ring);
  p->threads = calloc((size_t)workers, sizeof *p->threads);
  if (!p->ring || !p->threads) goto fail;
  pthread_mutex_init(&p->mu, NULL);
  pthread_cond_init(&p->cv, NULL);
  for (int i = 0; i < workers; i++) {
    if (pthread_create(&p->threads[i], NULL, worker, p) != 0) break;
    p->nthreads++;
  }
  if (p->nthreads == 0) goto fail;
  return p;
fail:
  free(p->ring);
  free(p->threads);
  free(p);
  return NULL;
}

int gs_pool_submit(gs_pool *p, gs_task_fn fn, void *arg) {
  pthread_mutex_lock(&p->mu);
  /* A task an idle worker takes at once does not count against the queue. */
  int limit = p->queue + (p->nthreads - p->busy);
  if (p->stop || p->count >= limit || p->count >= p->cap) {
    pthread_mutex_unlock(&p->mu);
    return -1;
  }
  p->ring[(p->head + p->count) % p->cap] = (task){fn, arg};
  p->count++;
  pthread_cond_signal(&p->cv);
  pthread_mutex_unlock(&p->mu);
  return 0;
}

int gs_pool_submit_first(gs_pool *p, gs_task_fn fn, void *arg) {
  first_task *f = malloc(sizeof *f);
  if (!f) return -1;
  *f = (first_task){{fn, arg}, NULL};
  pthread_mutex_lock(&p->mu);
  if (p->stop) {
    pthread_mutex_unlock(&p->mu);
    free(f);
    return -1;
  }
  if (p->first_tail) p->first_tail->next = f;
  else p->first = f;
  p->first_tail = f;
  pthread_cond_signal(&p->cv);
  pthread_mutex_unlock(&p->mu);
  return 0;
}

void gs_pool_stats(gs_pool *p, int *depth, int *capacity, int *busy) {
  pthread_mutex_lock(&p->mu);
  *depth = p->count;
  *capacity = p->queue;
  *busy = p->busy;
  pthread_mutex_unlock(&p->mu);
}

void gs_pool_free(gs_pool *p) {
  if (!p) return;
  pthread_mutex_lock(&p->mu);
  p->stop = 1;
  pthread_cond_broadcast(&p->cv);
  pthread_mutex_unlock(&p->mu);
  for (int i = 0; i < p->nthreads; i++) pthread_join(p->threads[i], NULL);
  pthread_mutex_destroy(&p->mu);
  pthread_cond_destroy(&p->cv);
  free(p->ring);
  free(p->threads);
  free(p);
}
