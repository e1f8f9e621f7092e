/* parallel.c: a blocking parallel-for on one persistent pthread pool.
 *
 * The pool (cores - 1 helper threads; the calling thread is always the
 * cores-th worker) starts on the first call that can use it and is joined
 * at exit. A call publishes a job; idle helpers join jobs that have chunks
 * left and fewer workers than their share, take chunks from the job's
 * atomic counter, and leave when the job runs dry or its share shrinks
 * because more calls became active. The caller works on its own job from
 * start to end, so every call progresses even when no helper is free
 * (nested calls and calls from many application threads cannot deadlock:
 * a caller waits only for helpers that are running one of its chunks).
 * The sharing rule is documented in base/internal.h. */
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <unistd.h>
#include "base/internal.h"

typedef struct job {
  size_t n, grain;
  atomic_size_t next;   /* first index of the next chunk */
  gi__range_fn fn;
  void *ctx;
  atomic_int *stop;     /* optional: no chunk starts once it is set (a worker failed) */
  const gi_cancel *cancel; /* optional: no chunk starts once it fired */
  int cap;              /* workers this call may use (threads, chunks), caller included */
  atomic_int helpers;   /* helpers inside the job; changed under the pool lock */
  int free_ids[GI_MAX_WORKERS]; /* worker ids not in use (1..cap-1); the caller is 0 */
  int num_free;
  int closed;           /* the caller stopped admitting helpers */
  pthread_cond_t done;  /* signalled when the last helper leaves a closed job */
  struct job *prev, *nextj;
} job;

static struct {
  pthread_once_t once;
  pthread_mutex_t lock;
  pthread_cond_t work;  /* a job was published, or shares grew */
  job *head;            /* published jobs, oldest first */
  atomic_int active;    /* calls running on the pool (their callers included) */
  atomic_uint published; /* bumped (under the lock) whenever pool.work is broadcast */
  atomic_int stop;
  int cores;            /* helpers + 1 */
  int num_helpers;
  pthread_t *tid;
} pool = {.once = PTHREAD_ONCE_INIT, .lock = PTHREAD_MUTEX_INITIALIZER, .work = PTHREAD_COND_INITIALIZER};

static int online_cores(void) {
  long c = sysconf(_SC_NPROCESSORS_ONLN);
  if (c < 1) return 1;
  return c > GI_MAX_WORKERS ? GI_MAX_WORKERS : (int)c;
}

/* Workers (caller included) one call may have while `active` calls run:
 * ceil(cores / active), at least 1. */
static int share(int active) {
  if (active < 1) active = 1;
  return (pool.cores + active - 1) / active;
}

static int workers_wanted(const job *j) {
  int s = share(atomic_load_explicit(&pool.active, memory_order_relaxed));
  return s < j->cap ? s : j->cap;
}

/* A job a helper may join: chunks left, an id free and room in its share.
 * Called with the lock held. */
static job *pick_job(void) {
  for (job *j = pool.head; j; j = j->nextj) {
    if (j->closed || j->num_free == 0) continue;
    if (atomic_load_explicit(&j->next, memory_order_relaxed) >= j->n) continue;
    if (atomic_load_explicit(&j->helpers, memory_order_relaxed) + 1 < workers_wanted(j)) return j;
  }
  return NULL;
}

static void leave_job(job *j, int id) {
  j->free_ids[j->num_free++] = id;
  int left = atomic_fetch_sub_explicit(&j->helpers, 1, memory_order_relaxed) - 1;
  if (left == 0 && j->closed) pthread_cond_signal(&j->done);
}

/* No further chunk starts once a worker failed (*stop) or the caller's
 * token fired: one flag load, plus a clock read when it has a deadline. */
static int stopped(atomic_int *stop, const gi_cancel *cancel) {
  return (stop && atomic_load_explicit(stop, memory_order_relaxed)) || gi_cancel_check(cancel) != GI_CANCEL_NONE;
}

/* One chunk at a time until the job runs dry or stops, the pool stops, or
 * the job has more workers than its share (another call became active). */
static void help(job *j, int id) {
  for (;;) {
    if (stopped(j->stop, j->cancel)) return;
    size_t b = atomic_fetch_add(&j->next, j->grain);
    if (b >= j->n) return;
    size_t e = b + j->grain < j->n ? b + j->grain : j->n;
    j->fn(j->ctx, b, e, id);
    if (atomic_load_explicit(&pool.stop, memory_order_relaxed)) return;
    if (atomic_load_explicit(&j->helpers, memory_order_relaxed) + 1 > workers_wanted(j)) return;
  }
}

static inline void cpu_relax(void) {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#endif
}

/* How long an idle helper polls for the next job before it sleeps. A bake
 * runs about fifty parallel loops with a little serial work between them,
 * and a helper woken from its sleep for each started late: the Cornell
 * box's 2-thread bake ran 105.7 -> 98.0 ms with this (1.75x -> 1.88x of
 * one thread); 50 us was too short to help. */
#define SPIN_NS 200000

/* Waits for pool.work with the lock held: polls `published` for up to
 * SPIN_NS first, then sleeps. A broadcast made while it polled is seen by
 * the check under the lock, and one made after it by the wait. */
static void idle_wait(void) {
  unsigned seen = atomic_load_explicit(&pool.published, memory_order_relaxed);
  pthread_mutex_unlock(&pool.lock);
  double end = gi__now_ms() + SPIN_NS * 1e-6;
  while (atomic_load_explicit(&pool.published, memory_order_relaxed) == seen && !atomic_load(&pool.stop) &&
         gi__now_ms() < end)
    for (int i = 0; i < 32; i++) cpu_relax();
  pthread_mutex_lock(&pool.lock);
  if (atomic_load_explicit(&pool.published, memory_order_relaxed) == seen && !atomic_load(&pool.stop))
    pthread_cond_wait(&pool.work, &pool.lock);
}

static void *helper_main(void *unused) {
  (void)unused;
  pthread_mutex_lock(&pool.lock);
  while (!atomic_load(&pool.stop)) {
    job *j = pick_job();
    if (!j) {
      idle_wait();
      continue;
    }
    int id = j->free_ids[--j->num_free];
    atomic_fetch_add_explicit(&j->helpers, 1, memory_order_relaxed);
    pthread_mutex_unlock(&pool.lock);
    help(j, id);
    pthread_mutex_lock(&pool.lock);
    leave_job(j, id);
  }
  pthread_mutex_unlock(&pool.lock);
  return NULL;
}

/* Joins every helper at exit so leak and thread checkers see a clean end.
 * A call still running then finishes on its caller alone. */
static void pool_teardown(void) {
  pthread_mutex_lock(&pool.lock);
  atomic_store(&pool.stop, 1);
  pthread_cond_broadcast(&pool.work);
  pthread_mutex_unlock(&pool.lock);
  for (int i = 0; i < pool.num_helpers; i++)
    if (!pthread_equal(pool.tid[i], pthread_self())) pthread_join(pool.tid[i], NULL);
  free(pool.tid); /* num_helpers stays: late calls read it, and stop sends them to run alone */
  pool.tid = NULL;
}

static void pool_init(void) {
  /* Helpers wait for the lock until the counts below are final. */
  pthread_mutex_lock(&pool.lock);
  int want = online_cores() - 1;
  pool.tid = want > 0 ? malloc((size_t)want * sizeof *pool.tid) : NULL;
  if (!pool.tid) want = 0;
  for (int i = 0; i < want; i++) {
    if (pthread_create(&pool.tid[i], NULL, helper_main, NULL) != 0) break;
    pool.num_helpers++;
  }
  /* Fewer helpers than asked (out of threads): shares count what exists. */
  pool.cores = pool.num_helpers + 1;
  pthread_mutex_unlock(&pool.lock);
  if (pool.num_helpers > 0) atexit(pool_teardown);
}

int gi__num_workers(int threads) {
  if (threads <= 0) threads = online_cores();
  return threads > GI_MAX_WORKERS ? GI_MAX_WORKERS : threads;
}

/* Returns 1 when the token fired with chunks left undone. */
static int run_alone(size_t n, size_t grain, gi__range_fn fn, void *ctx, atomic_int *stop, const gi_cancel *cancel) {
  for (size_t b = 0; b < n; b += grain) {
    if (stopped(stop, cancel)) return gi_cancel_check(cancel) != GI_CANCEL_NONE;
    fn(ctx, b, b + grain < n ? b + grain : n, 0);
  }
  return 0;
}

static void unlink_job(job *j) {
  if (j->prev) j->prev->nextj = j->nextj;
  else pool.head = j->nextj;
  if (j->nextj) j->nextj->prev = j->prev;
}

void gi__parallel_for(size_t n, size_t grain, int threads, gi__range_fn fn, void *ctx) {
  gi__parallel_for_cancel(n, grain, threads, fn, ctx, NULL, NULL);
}

void gi__parallel_for_stop(size_t n, size_t grain, int threads, gi__range_fn fn, void *ctx, atomic_int *stop) {
  gi__parallel_for_cancel(n, grain, threads, fn, ctx, stop, NULL);
}

int gi__parallel_for_cancel(size_t n, size_t grain, int threads, gi__range_fn fn, void *ctx, atomic_int *stop,
                            const gi_cancel *cancel) {
  if (n == 0) return 0;
  if (grain == 0) grain = 1;
  int t = gi__num_workers(threads);
  size_t chunks = (n + grain - 1) / grain;
  if ((size_t)t > chunks) t = (int)chunks;
  if (t > 1) pthread_once(&pool.once, pool_init);
  if (t <= 1 || pool.num_helpers == 0 || atomic_load(&pool.stop)) {
    return run_alone(n, grain, fn, ctx, stop, cancel);
  }
  if (t > pool.cores) t = pool.cores;
  job j = {.n = n, .grain = grain, .fn = fn, .ctx = ctx, .stop = stop, .cancel = cancel, .cap = t};
  atomic_init(&j.next, 0);
  atomic_init(&j.helpers, 0);
  for (int id = t - 1; id >= 1; id--) j.free_ids[j.num_free++] = id;
  pthread_cond_init(&j.done, NULL);

  pthread_mutex_lock(&pool.lock);
  atomic_fetch_add(&pool.active, 1);
  j.nextj = NULL;
  j.prev = NULL;
  if (pool.head) {
    job *last = pool.head;
    while (last->nextj) last = last->nextj;
    last->nextj = &j;
    j.prev = last;
  } else {
    pool.head = &j;
  }
  atomic_fetch_add_explicit(&pool.published, 1, memory_order_relaxed);
  pthread_cond_broadcast(&pool.work);
  pthread_mutex_unlock(&pool.lock);

  /* The caller is worker 0 and stays until no chunk is left. */
  while (!stopped(stop, cancel)) {
    size_t b = atomic_fetch_add(&j.next, grain);
    if (b >= n) break;
    fn(ctx, b, b + grain < n ? b + grain : n, 0);
  }

  pthread_mutex_lock(&pool.lock);
  j.closed = 1;
  unlink_job(&j);
  while (atomic_load_explicit(&j.helpers, memory_order_relaxed) > 0) pthread_cond_wait(&j.done, &pool.lock);
  atomic_fetch_sub(&pool.active, 1);
  /* Shares just grew: idle helpers may join the calls still running. */
  if (pool.head) {
    atomic_fetch_add_explicit(&pool.published, 1, memory_order_relaxed);
    pthread_cond_broadcast(&pool.work);
  }
  pthread_mutex_unlock(&pool.lock);
  pthread_cond_destroy(&j.done);
  /* Chunks nobody took: only a stop or the token can leave any. */
  return atomic_load(&j.next) < n && gi_cancel_check(cancel) != GI_CANCEL_NONE;
}
