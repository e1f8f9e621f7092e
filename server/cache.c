/* cache.c: baked cascades keyed by scene, snapped viewpoint and quality.
 *
 * The key uses gi_cascade_anchor: viewpoints in the same snapped cell give
 * bit-identical cascades, so a client moving inside a cell is answered
 * from memory. A key being baked is in the table as BAKING: a second
 * request for it does not bake again (coalescing). A request with a
 * waiter (an HTTP request) returns GS_PENDING and frees its worker; the
 * baking worker wakes it when the bake ends, handing it the entry held
 * (gs_waiter's got), and it runs again on that: an entry nobody else holds
 * is evicted at once under a zero budget, and a waiter finding it gone
 * would bake again. Its answer's encode hands the answer the same way.
 * A request without one (a probe list) waits on the condition variable.
 * Every bake has a cancel token: when the last interested request leaves
 * (deadline, hang-up) the token is set, the entry leaves the table and the
 * bake stops within tens of milliseconds; it is never cached. The table is bounded in bytes; when it is over budget the
 * least recently used READY entries that no request holds are evicted.
 * Entries a request holds may briefly push the total over the budget; they
 * are evicted when released. One mutex guards the table; bakes run
 * outside it.
 *
 * Admission by bytes: before a bake starts, its estimate (gs_bake_bytes:
 * the cascade's exact size plus its transient buffers) is reserved as
 * in-flight bytes. A bake is admitted only while cached bytes + in-flight
 * bytes stay within the budget, after evicting unheld entries; otherwise
 * the caller answers 503 (GI_ERR_NOMEM) with Retry-After. Jobs' private
 * bakes reserve through gs_cache_reserve, so they count too.
 *
 * Kept answers: an answer that is the same bytes for whoever asks (a
 * cell's probe or panorama EXR, a cascade's VDB) is an entry of its own,
 * keyed by its shape and its cascade's generation (a number each bake
 * gets: a cascade baked again is another, so an answer never outlives the
 * cascade it was gathered from). It is coalesced as a bake is: one request
 * gathers and encodes (BAKING is that encode for such an entry), the others
 * wait for it without a worker, and a failed or abandoned encode is never
 * kept. Kept answers count in the cached bytes and are evicted in the same
 * LRU order as cascades, and with their cascade. Bytes a client is still
 * reading stay counted: an answer not kept (or evicted meanwhile) counts
 * as being sent (gs_cache_admit_sending) until its last reference goes;
 * evicting an answer a client still reads would free nothing, so eviction
 * passes it by. The table is a list in LRU order: it holds at most a few
 * hundred cascades and their answers, and the scan compares a hash first,
 * so it costs microseconds next to a gather. */
#define _POSIX_C_SOURCE 200809L
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "server.h"

enum { BAKING, READY, FAILED };

/* Keys: scene id, cell and every knob (make_key). */
#define GS_KEY_SIZE 512

struct gs_entry {
  char key[GS_KEY_SIZE];
  uint64_t hash;          /* of key: compared before it */
  int state;
  int refs;               /* requests holding or waiting for it */
  int answer;             /* a kept answer, not a cascade */
  uint64_t gen;           /* a cascade's bake number; an answer's: its cascade's */
  gi_cascade *cascade;    /* a cascade entry's, once READY */
  gs_blob *blob;          /* an answer entry's encoded bytes, once READY */
  size_t bytes;           /* the cascade's, or the answer's */
  size_t reserved;        /* in-flight bytes admitted for its bake, until the bake ends */
  gi_result rc;
  gi_error_info err;
  int linked;             /* in the table (failed and cancelled entries leave it at once) */
  gi_cancel *cancel;      /* the bake's (or encode's) token: set when nobody is interested any more */
  int interest;           /* requests that want the bake: the baker and its waiters */
  gs_waiter *waiters;     /* requests to wake when the bake ends (the baker's own first, if any) */
  struct gs_entry *prev, *next; /* most recent first */
};

struct gs_cache {
  pthread_mutex_t mu;
  pthread_cond_t done;
  gs_entry *head, *tail;
  size_t bytes, entries, budget; /* bytes: cascades' and kept answers'; entries: cascades */
  size_t answers, answer_bytes;  /* kept (or encoding) answers, and their part of bytes */
  uint64_t gens;          /* bakes started: each cascade's generation */
  size_t inflight;        /* estimates of the bakes admitted and not yet finished */
  size_t held;            /* sessions' cascades (session.c), for their lives */
  size_t sending;         /* answers' encoded bytes until their clients have them (gs_cache_admit_sending) */
  gs_metrics *metrics;
};

gs_cache *gs_cache_new(size_t budget_bytes, gs_metrics *m) {
  gs_cache *c = calloc(1, sizeof *c);
  if (!c) return NULL;
  pthread_mutex_init(&c->mu, NULL);
  pthread_cond_init(&c->done, NULL);
  c->budget = budget_bytes;
  c->metrics = m;
  return c;
}

/* Counts e's bytes in (sign 1) or out of (-1) the table's. Locked. */
static void count_bytes(gs_cache *c, const gs_entry *e, int sign) {
  if (sign > 0) c->bytes += e->bytes;
  else c->bytes -= e->bytes;
  if (!e->answer) return;
  if (sign > 0) c->answer_bytes += e->bytes;
  else c->answer_bytes -= e->bytes;
}

static void unlink_entry(gs_cache *c, gs_entry *e) {
  if (!e->linked) return;
  if (e->prev) e->prev->next = e->next;
  else c->head = e->next;
  if (e->next) e->next->prev = e->prev;
  else c->tail = e->prev;
  e->prev = e->next = NULL;
  e->linked = 0;
  if (e->answer) c->answers--;
  else c->entries--;
  count_bytes(c, e, -1);
}

static void push_front(gs_cache *c, gs_entry *e) {
  e->prev = NULL;
  e->next = c->head;
  if (c->head) c->head->prev = e;
  c->head = e;
  if (!c->tail) c->tail = e;
  e->linked = 1;
  if (e->answer) c->answers++;
  else c->entries++;
  count_bytes(c, e, 1);
}

/* e's bytes become n (counted in the table's while it is linked). Locked. */
static void set_bytes(gs_cache *c, gs_entry *e, size_t n) {
  if (e->linked) count_bytes(c, e, -1);
  e->bytes = n;
  if (e->linked) count_bytes(c, e, 1);
}

/* The cache lets go of a kept answer's bytes (locked). A client still
 * reading them keeps them alive: they stay in the budget, as bytes being
 * sent, until its last reference goes (gs_blob_release, which then takes
 * the lock: hence the last release here is done in place). Only the
 * cache retains a kept blob, under this lock, so its count can only fall
 * meanwhile. */
static void drop_kept(gs_cache *c, gs_blob *b) {
  if (!b) return;
  if (c->budget) {
    b->sending = c;
    c->sending += b->size;
  }
  if (atomic_fetch_sub(&b->refs, 1) != 1) return;
  if (b->sending) c->sending -= b->size;
  free(b);
}

static void free_entry(gs_cache *c, gs_entry *e) {
  gi_cascade_free(e->cascade);
  gi_cancel_free(e->cancel);
  drop_kept(c, e->blob);
  free(e);
}

/* Room left for `extra` more bytes: cached + in-flight + extra within the budget. */
static int fits(const gs_cache *c, size_t extra) {
  return c->bytes + c->inflight + c->held + c->sending + extra <= c->budget;
}

/* Whether evicting e would free its bytes: READY, unheld, and (an answer)
 * not being read by a client, whose bytes would only move to the sending
 * count. Locked. */
static int evictable(const gs_cache *c, const gs_entry *e) {
  if (e->state != READY || e->refs) return 0;
  return !e->answer || !c->budget || atomic_load(&e->blob->refs) == 1;
}

static void evicted(gs_cache *c, gs_entry *e) {
  unlink_entry(c, e);
  if (c->metrics) {
    if (e->answer) gs_metrics_encode_eviction(c->metrics);
    else gs_metrics_eviction(c->metrics);
  }
  free_entry(c, e);
}

/* Evicts unheld READY entries from the LRU end until extra bytes fit; a
 * cascade's kept answers go with it (no request can name its generation
 * any more). Locked. */
static void evict(gs_cache *c, size_t extra) {
  gs_entry *e = c->tail;
  while (e && !fits(c, extra)) {
    gs_entry *prev = e->prev;
    if (evictable(c, e)) {
      if (!e->answer) {
        uint64_t gen = e->gen;
        evicted(c, e);
        for (gs_entry *a = c->head, *n; a; a = n) {
          n = a->next;
          if (a->answer && a->gen == gen && a->state == READY && a->refs == 0) evicted(c, a);
        }
        prev = c->tail; /* the answers may have been anywhere: look again from the end */
      } else {
        evicted(c, e);
      }
    }
    e = prev;
  }
}

void gs_cache_free(gs_cache *c) {
  if (!c) return;
  c->budget = 0; /* nobody reads a blob any more: nothing moves to the sending count */
  for (gs_entry *e = c->head, *n; e; e = n) {
    n = e->next;
    free_entry(c, e);
  }
  pthread_mutex_destroy(&c->mu);
  pthread_cond_destroy(&c->done);
  free(c);
}

static void make_key(const gs_scene *s, const int64_t a[3], const gi_quality *req, const gi_quality *q, char *key,
                     size_t size) {
  /* Every knob that changes the cascade or its report; %a keeps floats exact.
   * Bounces as requested (0 = the plan decides, which differs from an
   * explicit count); threads left out: they change speed, not values. */
  int n = snprintf(key, size, "%s|%lld,%lld,%lld|L%d R%d s%a c%d ap%a st%a b%d ls%d ps%d ao%d sp%d sd%llu lam%a fx",
                   s->id, (long long)a[0], (long long)a[1], (long long)a[2], q->levels, q->res, q->voxel0, q->cones,
                   (double)q->aperture_deg, (double)q->step, req->bounces, q->light_samples, q->probe_samples, q->ao,
                   q->specular, (unsigned long long)q->seed, (double)q->ao_lambda);
  for (int i = 0; i < GI_FX_COUNT && n > 0 && (size_t)n < size; i++)
    n += snprintf(key + n, size - (size_t)n, "%+d", q->effects[i]);
}

size_t gs_bake_bytes(const gi_quality *resolved) {
  size_t cas = gi_cascade_bytes_estimate(resolved);
  return cas + cas / GS_BAKE_TRANSIENT_DIV;
}

/* Reserves need bytes for a bake, an encode or an answer being sent
 * (what: "this bake", "this answer", ... for the messages; locked):
 * evicts what it must, else GI_ERR_NOMEM. */
static gi_result admit(gs_cache *c, size_t need, const char *what, gi_error_info *err) {
  /* A zero budget caches nothing and admits every bake (admission off). */
  if (c->budget == 0) return GI_OK;
  if (need > c->budget) {
    if (err)
      snprintf(err->msg, sizeof err->msg, "memory: %s needs about %zu MiB, more than the whole budget (%zu MiB)", what,
               need >> 20, c->budget >> 20);
    return GI_ERR_LIMIT;
  }
  if (!fits(c, need)) evict(c, need);
  if (!fits(c, need)) {
    if (err)
      snprintf(err->msg, sizeof err->msg,
               "busy: the memory budget is taken (%zu MiB cached, %zu MiB baking, %zu MiB held by sessions, "
               "%zu MiB of answers being sent, this needs %zu MiB); retry later",
               c->bytes >> 20, c->inflight >> 20, c->held >> 20, c->sending >> 20, need >> 20);
    return GI_ERR_NOMEM;
  }
  c->inflight += need;
  return GI_OK;
}

static void unreserve(gs_cache *c, size_t need) {
  if (c->budget == 0) return;
  c->inflight -= need;
}

gi_result gs_cache_reserve(gs_cache *c, size_t need, const char *what, gi_error_info *err) {
  pthread_mutex_lock(&c->mu);
  gi_result rc = admit(c, need, what, err);
  pthread_mutex_unlock(&c->mu);
  return rc;
}

void gs_cache_unreserve(gs_cache *c, size_t need) {
  pthread_mutex_lock(&c->mu);
  unreserve(c, need);
  pthread_cond_broadcast(&c->done);
  pthread_mutex_unlock(&c->mu);
}

gi_result gs_cache_hold(gs_cache *c, size_t need, gi_error_info *err) {
  pthread_mutex_lock(&c->mu);
  gi_result rc = admit(c, need, "this session's cascade", err);
  if (rc == GI_OK && c->budget) {
    /* Admitted as a bake, kept apart: a session holds it until it ends. */
    c->inflight -= need;
    c->held += need;
  }
  pthread_mutex_unlock(&c->mu);
  return rc;
}

void gs_cache_unhold(gs_cache *c, size_t need) {
  pthread_mutex_lock(&c->mu);
  if (c->budget) c->held -= need;
  pthread_cond_broadcast(&c->done);
  pthread_mutex_unlock(&c->mu);
}

size_t gs_cache_inflight(gs_cache *c) {
  pthread_mutex_lock(&c->mu);
  size_t n = c->inflight;
  pthread_mutex_unlock(&c->mu);
  return n;
}

gi_result gs_cache_admit_sending(gs_cache *c, gs_blob *b, gi_error_info *err) {
  if (c->budget == 0) return GI_OK; /* no bound: nothing counted */
  pthread_mutex_lock(&c->mu);
  gi_result rc = admit(c, b->size, "this answer's encoded file (fewer pixels or half=1 make it smaller)", err);
  if (rc == GI_OK) {
    c->inflight -= b->size; /* admitted as a bake, counted apart */
    c->sending += b->size;
    b->sending = c;
  }
  pthread_mutex_unlock(&c->mu);
  return rc;
}

void gs_cache_unsend(gs_cache *c, size_t bytes) {
  pthread_mutex_lock(&c->mu);
  c->sending -= bytes;
  pthread_cond_broadcast(&c->done);
  pthread_mutex_unlock(&c->mu);
}

size_t gs_cache_sending(gs_cache *c) {
  pthread_mutex_lock(&c->mu);
  size_t n = c->sending;
  pthread_mutex_unlock(&c->mu);
  return n;
}

/* Drops a reference to e (NULL is fine). Locked. */
static void release_locked(gs_cache *c, gs_entry *e) {
  if (!e) return;
  e->refs--;
  if (!e->linked && e->refs == 0) free_entry(c, e);
  else if (e->refs == 0) evict(c, 0);
}

/* w is interested in e's bake (or encode). Locked. */
static void join(gs_entry *e, gs_waiter *w) {
  w->entry = e;
  w->next = e->waiters;
  e->waiters = w;
  e->interest++;
}

/* Unlinks w from its entry's list. Locked. */
static void drop_waiter(gs_waiter *w) {
  gs_entry *e = w->entry;
  for (gs_waiter **p = &e->waiters; *p; p = &(*p)->next)
    if (*p == w) {
      *p = w->next;
      break;
    }
  w->entry = NULL;
  w->next = NULL;
  e->interest--;
}

int gs_cache_leave(gs_cache *c, gs_waiter *w) {
  if (!w) return 0;
  pthread_mutex_lock(&c->mu);
  gs_entry *e = w->entry;
  int cancelled = 0;
  w->left = 1; /* it joins no bake after this */
  /* Woken but never to run again: what it was handed goes back. */
  release_locked(c, w->got);
  release_locked(c, w->got_answer);
  w->got = w->got_answer = NULL;
  /* A linked waiter means its bake is still running: the baker's own
   * reference keeps e alive. */
  if (e) {
    drop_waiter(w);
    if (e->interest == 0 && e->state == BAKING) {
      gi_cancel_set(e->cancel);
      /* A request arriving now starts a fresh bake instead of joining this one. */
      unlink_entry(c, e);
      cancelled = e->answer ? 2 : 1;
    }
  }
  pthread_cond_broadcast(&c->done); /* a blocking waiter stops waiting */
  pthread_mutex_unlock(&c->mu);
  return cancelled;
}

/* The table's key of at's cell (its anchor into anchor) at quality (req
 * as asked, q resolved). */
static gi_result key_of(const gs_scene *s, const double at[3], const gi_quality *req, const gi_quality *q,
                        int64_t anchor[3], char key[GS_KEY_SIZE], gi_error_info *err) {
  gi_result rc = gi_cascade_anchor(s->scene, at, q, anchor, err);
  if (rc == GI_OK) make_key(s, anchor, req, q, key, GS_KEY_SIZE);
  return rc;
}

/* FNV-1a 64 of a key (canonical.c's). */
static uint64_t hash_key(const char *key) { return gs_hash_bytes(0xcbf29ce484222325ull, key, strlen(key)); }

/* The entry under key, or NULL. Locked. */
static gs_entry *lookup(gs_cache *c, const char *key) {
  uint64_t h = hash_key(key);
  gs_entry *e = c->head;
  while (e && (e->hash != h || strcmp(e->key, key))) e = e->next;
  return e;
}

/* The key of cascade generation gen's answer of this shape. */
static void answer_key(uint64_t gen, const char *shape, char key[GS_KEY_SIZE]) {
  snprintf(key, GS_KEY_SIZE, "answer|%llu|%s", (unsigned long long)gen, shape);
}

/* A cache outcome in /metrics: the cascade's or the answer's counters. */
static void count_how(gs_cache *c, const gs_entry *e, gs_cache_how how) {
  if (!c->metrics) return;
  if (e->answer) gs_metrics_encode(c->metrics, how);
  else gs_metrics_cache(c->metrics, how);
}

/* Most recently used first. Locked. */
static void touch(gs_cache *c, gs_entry *e) {
  if (!e->linked) return;
  unlink_entry(c, e);
  push_front(c, e);
}

/* What a wake handed w (its cascade, or answer), now the caller's
 * reference, or NULL. */
static gs_entry *take_handed(gs_cache *c, gs_waiter *w, int answer) {
  if (!w) return NULL;
  pthread_mutex_lock(&c->mu);
  gs_entry **p = answer ? &w->got_answer : &w->got, *e = *p;
  *p = NULL;
  if (e) touch(c, e);
  pthread_mutex_unlock(&c->mu);
  return e;
}

/* An entry found in the table: a hit, a pending waiter, or a blocking
 * wait for the bake. held: the caller's reference that passes to w when
 * it waits without a worker (its cascade, while it waits for its answer).
 * Called locked; returns unlocked. */
static gi_result found(gs_cache *c, gs_entry *e, gs_waiter *w, gs_entry *held, gs_entry **out,
                       gs_cache_how *how, gi_error_info *err) {
  touch(c, e);
  *how = e->state == READY ? GS_CACHE_HIT : GS_CACHE_COALESCED;
  if (e->state == BAKING && w && !w->blocking) {
    join(e, w);
    w->got = held;
    pthread_mutex_unlock(&c->mu);
    count_how(c, e, *how);
    return GS_PENDING;
  }
  e->refs++;
  if (e->state == BAKING) {
    /* A blocking waiter's interest is its link, which gs_cache_leave drops. */
    if (w) join(e, w);
    else e->interest++;
    while (e->state == BAKING && !(w && w->left)) pthread_cond_wait(&c->done, &c->mu);
    if (!w) e->interest--;
    else if (w->entry == e) drop_waiter(w);
  }
  int gave_up = w && w->left;
  pthread_mutex_unlock(&c->mu);
  count_how(c, e, *how);
  if (gave_up) {
    if (err)
      snprintf(err->msg, sizeof err->msg, "%s", e->answer ? "encode: the request was given up while it waited for "
               "its answer's encode" : "bake: the request was given up while it waited for the bake");
    gs_cache_release(c, e);
    return GI_ERR_CANCELLED;
  }
  if (e->state == FAILED) {
    if (err) *err = e->err;
    gi_result rc = e->rc;
    gs_cache_release(c, e);
    return rc;
  }
  *out = e;
  return GI_OK;
}

/* e's bake (or encode) failed with rc: it leaves the table, and its
 * waiters get the error. Locked. */
static void fail_entry(gs_cache *c, gs_entry *e, gi_result rc, const gi_error_info *e_err) {
  e->state = FAILED;
  e->rc = rc == GI_OK ? GI_ERR_CANCELLED : rc;
  e->err = *e_err;
  if (rc == GI_OK)
    snprintf(e->err.msg, sizeof e->err.msg, "%s: cancelled as it finished (nobody waited)",
             e->answer ? "encode" : "bake");
  unlink_entry(c, e);
}

/* e's bake (or encode) ended, its state set: wakes the waiters (each held
 * under the lock, woken after it), handing each e held when it is READY.
 * Called locked; returns unlocked. */
static void wake_waiters(gs_cache *c, gs_entry *e) {
  /* Blocking waiters read e themselves once the lock is let go (and may
   * reuse their waiter at once): only the others are kept to be woken. */
  gs_waiter *woken = NULL;
  for (gs_waiter *w = e->waiters, *n; w; w = n) {
    n = w->next;
    w->entry = NULL;
    w->next = NULL;
    e->interest--;
    if (w->blocking) continue;
    w->rc = e->state == FAILED ? e->rc : GI_OK;
    if (e->state == FAILED) {
      w->err = e->err;
    } else if (e->answer) {
      e->refs++;
      w->got_answer = e;
    } else {
      e->refs++;
      w->got = e;
      w->how = GS_CACHE_COALESCED;
    }
    w->hold(w->arg);
    w->next = woken;
    woken = w;
  }
  e->waiters = NULL;
  pthread_cond_broadcast(&c->done);
  pthread_mutex_unlock(&c->mu);
  for (gs_waiter *w = woken, *n; w; w = n) {
    n = w->next; /* wake may run the request at once and reuse w */
    w->next = NULL;
    w->wake(w->arg);
  }
}

/* The bake ended: stores or drops the result and wakes the waiters. */
static void bake_done(gs_cache *c, gs_entry *e, gs_waiter *self, gi_result rc, gi_cascade *cas,
                      const gi_error_info *e_err) {
  pthread_mutex_lock(&c->mu);
  unreserve(c, e->reserved);
  e->reserved = 0;
  if (self && self->entry == e) drop_waiter(self);
  /* Cancelled (nobody waited any more, the entry left the table then) is never cached. */
  if (rc == GI_OK && e->linked) {
    e->cascade = cas;
    set_bytes(c, e, gi_cascade_bytes(cas));
    e->state = READY;
    evict(c, 0);
  } else {
    gi_cascade_free(cas);
    fail_entry(c, e, rc, e_err);
  }
  wake_waiters(c, e);
}

int gs_cache_join_running(gs_cache *c, const gs_scene *s, const double at[3], const gi_quality *req,
                          const gi_quality *q, const char *shape, gs_waiter *w) {
  int64_t anchor[3];
  char key[GS_KEY_SIZE];
  if (!w || w->blocking || key_of(s, at, req, q, anchor, key, NULL) != GI_OK) return 0; /* the worker reports it */
  pthread_mutex_lock(&c->mu);
  gs_entry *e = lookup(c, key), *cas = e;
  if (e && e->state == READY && shape) {
    /* The cascade is there: its answer may be being encoded. */
    answer_key(e->gen, shape, key);
    e = lookup(c, key);
  }
  if (!e || e->state != BAKING || w->left || w->entry) {
    pthread_mutex_unlock(&c->mu);
    return 0;
  }
  touch(c, e);
  join(e, w);
  if (e->answer) {
    /* Its cascade stays for its rerun, as if found there. */
    cas->refs++;
    w->got = cas;
    w->how = GS_CACHE_HIT;
  }
  pthread_mutex_unlock(&c->mu);
  if (e->answer) count_how(c, cas, GS_CACHE_HIT); /* its rerun finds the cascade without counting it */
  count_how(c, e, GS_CACHE_COALESCED);
  return 1;
}

/* A new BAKING entry under key (a cascade of generation gen, or an answer
 * of its cascade's), held once by its baker and in the table; w (may be
 * NULL: the caller stays interested) waits for it. NULL without memory.
 * Locked. */
static gs_entry *start_entry(gs_cache *c, const char *key, int answer, uint64_t gen, gs_waiter *w) {
  gs_entry *e = calloc(1, sizeof *e);
  gi_cancel *token = e ? gi_cancel_new() : NULL;
  if (!token) {
    free(e);
    return NULL;
  }
  snprintf(e->key, sizeof e->key, "%s", key);
  e->hash = hash_key(e->key);
  e->answer = answer;
  e->gen = gen;
  e->state = BAKING;
  e->refs = 1;
  e->cancel = token;
  /* Without a waiter the caller cannot leave: it stays interested. */
  if (w) join(e, w);
  else e->interest = 1;
  push_front(c, e);
  return e;
}

gi_result gs_cache_get(gs_cache *c, const gs_scene *s, const double at[3], const gi_quality *req,
                       const gi_quality *q, gs_waiter *w, gs_entry **out, gs_cache_how *how, gi_error_info *err) {
  *out = NULL;
  gs_entry *handed = take_handed(c, w, 0);
  if (w && w->rc != GI_OK) {
    /* Woken by a bake (or its answer's encode) that failed: its error is this request's answer. */
    gi_result rc = w->rc;
    if (err) *err = w->err;
    w->rc = GI_OK;
    gs_cache_release(c, handed);
    return rc;
  }
  if (handed) {
    /* Woken by the bake it waited for, or by its answer's encode: counted then. */
    *how = w->how;
    *out = handed;
    return GI_OK;
  }
  int64_t anchor[3];
  char key[GS_KEY_SIZE];
  gi_result rc = key_of(s, at, req, q, anchor, key, err);
  if (rc != GI_OK) return rc;
  pthread_mutex_lock(&c->mu);
  if (w && w->left) {
    /* Given up (deadline, hang-up) before it could join a bake. */
    pthread_mutex_unlock(&c->mu);
    if (err) snprintf(err->msg, sizeof err->msg, "bake: the request was given up before its bake started");
    return GI_ERR_CANCELLED;
  }
  gs_entry *e = lookup(c, key);
  if (e) {
    rc = found(c, e, w, NULL, out, how, err);
    if (rc == GI_OK && w) w->how = *how; /* for a rerun after a wait for its answer */
    return rc;
  }
  size_t need = gs_bake_bytes(q);
  if ((rc = admit(c, need, "this bake", err)) != GI_OK) {
    pthread_mutex_unlock(&c->mu);
    return rc;
  }
  if (!(e = start_entry(c, key, 0, ++c->gens, w))) {
    unreserve(c, need);
    pthread_mutex_unlock(&c->mu);
    if (err) snprintf(err->msg, sizeof err->msg, "cache: out of memory for an entry");
    return GI_ERR_NOMEM;
  }
  e->reserved = need;
  gi_cancel *token = e->cancel;
  pthread_mutex_unlock(&c->mu);
  *how = GS_CACHE_MISS;
  if (c->metrics) gs_metrics_cache(c->metrics, GS_CACHE_MISS);

  /* Bake at the anchor cell's centre: any point with the same anchor gives
   * the same cascade, and the centre makes the metadata the cascade keeps
   * (its VDB's viewpoint) the same whichever request baked it first, so a
   * cell's answer is the same bytes on every replica. */
  double centre[3];
  if (gi_cascade_cell_centre(s->scene, anchor, q, centre, NULL) != GI_OK) memcpy(centre, at, sizeof centre);
  double t0 = gs_now_ms();
  gi_cascade *cas = NULL;
  gi_error_info e_err = {0};
  if (c->metrics) gs_metrics_bake_begin(c->metrics);
  rc = gi_cascade_bake_ex(s->scene, centre, req, token, &cas, NULL, &e_err);
  if (c->metrics) gs_metrics_bake_end(c->metrics, rc == GI_ERR_CANCELLED);
  if (c->metrics && rc == GI_OK) gs_metrics_bake(c->metrics, (gs_now_ms() - t0) * 1e-3);
  bake_done(c, e, w, rc, cas, &e_err);
  if (e->state == FAILED) {
    if (err) *err = e->err;
    rc = e->rc;
    gs_cache_release(c, e);
    return rc;
  }
  *out = e;
  if (w) w->how = GS_CACHE_MISS;
  return GI_OK;
}

const gi_cascade *gs_entry_cascade(const gs_entry *e) { return e->cascade; }

void gs_cache_release(gs_cache *c, gs_entry *e) {
  if (!e) return;
  pthread_mutex_lock(&c->mu);
  release_locked(c, e);
  pthread_mutex_unlock(&c->mu);
}

gi_result gs_cache_answer(gs_cache *c, gs_entry *cas, const char *shape, gs_waiter *w, gs_blob **blob,
                          gs_entry **job, gi_error_info *err) {
  *blob = NULL;
  *job = NULL;
  if (w && w->rc != GI_OK) {
    /* Woken by an encode that failed: its error is this request's answer. */
    gi_result rc = w->rc;
    if (err) *err = w->err;
    w->rc = GI_OK;
    return rc;
  }
  gs_entry *handed = take_handed(c, w, 1);
  if (handed) {
    /* Woken by the encode it waited for: counted then. */
    gs_blob_retain(handed->blob);
    *blob = handed->blob;
    gs_cache_release(c, handed);
    return GI_OK;
  }
  char key[GS_KEY_SIZE];
  answer_key(cas->gen, shape, key);
  pthread_mutex_lock(&c->mu);
  if (w && w->left) {
    pthread_mutex_unlock(&c->mu);
    if (err) snprintf(err->msg, sizeof err->msg, "encode: the request was given up before its answer's encode started");
    return GI_ERR_CANCELLED;
  }
  gs_entry *e = lookup(c, key);
  if (e) {
    gs_cache_how how;
    gi_result rc = found(c, e, w, cas, &e, &how, err);
    if (rc != GI_OK) return rc;
    /* Held (refs): the entry, and so its blob, stays until released. */
    gs_blob_retain(e->blob);
    *blob = e->blob;
    gs_cache_release(c, e);
    return GI_OK;
  }
  if (!(e = start_entry(c, key, 1, cas->gen, w))) {
    pthread_mutex_unlock(&c->mu);
    if (err) snprintf(err->msg, sizeof err->msg, "cache: out of memory for an answer's entry");
    return GI_ERR_NOMEM;
  }
  pthread_mutex_unlock(&c->mu);
  count_how(c, e, GS_CACHE_MISS);
  *job = e;
  return GI_OK;
}

const gi_cancel *gs_entry_cancel(const gs_entry *job) { return job->cancel; }

void gs_cache_answer_done(gs_cache *c, gs_entry *job, gs_waiter *self, gi_result rc, gs_blob *b,
                          const gi_error_info *err) {
  pthread_mutex_lock(&c->mu);
  if (self && self->entry == job) drop_waiter(self);
  /* Abandoned (nobody waited any more: it left the table then) or failed: never kept. */
  if (rc == GI_OK && b && job->linked) {
    if (b->sending) {
      /* Admitted as bytes being sent: from now on they count as the entry's. */
      c->sending -= b->size;
      b->sending = NULL;
    }
    gs_blob_retain(b);
    job->blob = b;
    set_bytes(c, job, b->size);
    job->state = READY;
    evict(c, 0);
  } else {
    fail_entry(c, job, rc == GI_OK && !b ? GI_ERR_INTERNAL : rc, err);
  }
  wake_waiters(c, job);
  gs_cache_release(c, job);
}

void gs_cache_stats(gs_cache *c, size_t *bytes, size_t *entries) {
  pthread_mutex_lock(&c->mu);
  *bytes = c->bytes;
  *entries = c->entries;
  pthread_mutex_unlock(&c->mu);
}

void gs_cache_answer_stats(gs_cache *c, size_t *bytes, size_t *answers) {
  pthread_mutex_lock(&c->mu);
  *bytes = c->answer_bytes;
  *answers = c->answers;
  pthread_mutex_unlock(&c->mu);
}
