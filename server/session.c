/* session.c: a walking client's own cascade, moved instead of rebaked.
 *
 * POST /v1/scenes/{id}/sessions bakes one cascade for the session at
 * creation (on a worker, with the request's deadline and cancel token), so
 * the 201 means the session is ready and every later request is a move.
 * GET /v1/sessions/{sid}/lighting moves that cascade with gi_cascade_move
 * and answers through the lighting endpoint's own code (serve.c).
 *
 * Memory: a session holds gs_bake_bytes of its quality (the cascade plus
 * the transient share a move's scratch needs) in the cache's budget for its
 * whole life (gs_cache_hold): unheld cache entries are evicted to make room,
 * and when that is not enough the creation is a 503 with Retry-After.
 * Sessions are also limited in number (max_sessions: 503 beyond, with
 * Retry-After until the least recently used idle session expires).
 *
 * Threads: one mutex guards the table and every session's refs, busy flag
 * and idle clock. A request holds a reference while it waits and runs, and
 * sets busy while it uses the cascade: requests on one session run one at
 * a time in arrival order of the lock, never interleaved, and the cascade
 * is written by one move at a time with no reader beside it. A session
 * ends (DELETE, idle past session_ttl_s, a failed move, shutdown) by
 * leaving the table; its cascade is freed when the last request lets go.
 *
 * Cancelling: the request's token (deadline, hang-up) stops the wait for
 * its session's lock and the gather after the move. The move itself stops
 * at the request's deadline only (a token of its own): a move that
 * rebuilds a level costs a cold bake's work, which must stay bounded, but a
 * walking client that drops a stale request or times out must find its
 * session moved. A stopped move is a 504 (the deadline's answer, http.c)
 * counted in gi_bakes_cancelled_total; it leaves the cascade partial, which
 * no call reads (gi_move.h), and the session keeps it: the session's next
 * move re-bakes it at its viewpoint (a cold bake's work, as its creation
 * did within the deadline). The busy flag keeps every other request off
 * the cascade in between. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <time.h>
#include <unistd.h>
#include "gi/gi_move.h"
#include "server.h"

/* A request waiting for a busy session looks at its cancel token this often. */
#define GS_SESSION_WAIT_MS 50
/* Random bytes in a session id (two hex digits each). */
#define GS_SESSION_ID_BYTES (GS_SESSION_ID_LEN / 2)

typedef struct gs_session {
  char id[GS_SESSION_ID_LEN + 1];
  const gs_scene *scene;
  gi_quality req, resolved;
  gi_cascade *cascade;
  size_t held;              /* bytes it holds in the cache's budget */
  double at[3];             /* where the cascade was last moved (or baked) */
  int64_t anchor[3];        /* at's anchor cell: a move to another cell crossed one */
  uint64_t moves;
  /* Guarded by the table's mutex. */
  double last_used_ms;
  int refs;                 /* requests holding it */
  int busy;                 /* a request is using its cascade */
  int ended;                /* out of the table: freed when refs drops to 0 */
  struct gs_session *next;
} gs_session;

struct gs_sessions {
  gs_service *svc;
  pthread_mutex_t mu;
  pthread_cond_t idle;      /* some session's busy flag was cleared */
  gs_session *head;
  int open;                 /* in the table */
  int creating;             /* slots taken by creations still baking */
  size_t bytes;             /* held by sessions not yet freed */
};

gs_sessions *gs_sessions_new(gs_service *svc) {
  gs_sessions *t = calloc(1, sizeof *t);
  if (!t) return NULL;
  t->svc = svc;
  pthread_mutex_init(&t->mu, NULL);
  pthread_cond_init(&t->idle, NULL);
  return t;
}

/* Frees s's cascade and gives its bytes back to the budget. Unlocked. */
static void session_free(gs_sessions *t, gs_session *s) {
  gi_cascade_free(s->cascade);
  gs_cache_unhold(t->svc->cache, s->held);
  pthread_mutex_lock(&t->mu);
  t->bytes -= s->held;
  pthread_mutex_unlock(&t->mu);
  free(s);
}

void gs_sessions_free(gs_sessions *t) {
  if (!t) return;
  /* The workers have stopped: nobody holds a session any more. */
  for (gs_session *s = t->head, *n; s; s = n) {
    n = s->next;
    session_free(t, s);
  }
  pthread_mutex_destroy(&t->mu);
  pthread_cond_destroy(&t->idle);
  free(t);
}

/* Takes s out of the table (it ends). Locked. */
static void unlink_session(gs_sessions *t, gs_session *s) {
  for (gs_session **p = &t->head; *p; p = &(*p)->next)
    if (*p == s) {
      *p = s->next;
      s->next = NULL;
      s->ended = 1;
      t->open--;
      return;
    }
}

static gs_session *find(gs_sessions *t, const char *sid) {
  gs_session *s = t->head;
  while (s && strcmp(s->id, sid)) s = s->next;
  return s;
}

void gs_sessions_sweep(gs_sessions *t) {
  if (!t) return;
  double now = gs_now_ms(), ttl = t->svc->cfg->session_ttl_s * 1e3;
  gs_session *gone = NULL;
  pthread_mutex_lock(&t->mu);
  for (gs_session *s = t->head, *n; s; s = n) {
    n = s->next;
    if (s->refs || now - s->last_used_ms <= ttl) continue;
    unlink_session(t, s);
    s->next = gone; /* a private list now */
    gone = s;
  }
  pthread_mutex_unlock(&t->mu);
  for (gs_session *s = gone, *n; s; s = n) {
    n = s->next;
    session_free(t, s);
    gs_metrics_session(t->svc->metrics, GS_SESSION_EXPIRED);
  }
}

void gs_sessions_stats(gs_sessions *t, int *open, size_t *bytes) {
  pthread_mutex_lock(&t->mu);
  *open = t->open;
  *bytes = t->bytes;
  pthread_mutex_unlock(&t->mu);
}

/* Seconds until a slot frees by itself: the least recently used idle
 * session's expiry, else a whole TTL. Locked. */
static int retry_after_locked(const gs_sessions *t) {
  double now = gs_now_ms(), ttl = t->svc->cfg->session_ttl_s * 1e3, wait = ttl;
  for (const gs_session *s = t->head; s; s = s->next)
    if (!s->refs && ttl - (now - s->last_used_ms) < wait) wait = ttl - (now - s->last_used_ms);
  int secs = (int)ceil(wait * 1e-3);
  return secs < 1 ? 1 : secs;
}

/* A reference on the session named sid, or NULL. */
static gs_session *hold(gs_sessions *t, const char *sid) {
  pthread_mutex_lock(&t->mu);
  gs_session *s = find(t, sid);
  if (s) s->refs++;
  pthread_mutex_unlock(&t->mu);
  return s;
}

/* Drops a reference; the last one frees an ended session. */
static void put(gs_sessions *t, gs_session *s) {
  pthread_mutex_lock(&t->mu);
  int last = --s->refs == 0 && s->ended;
  pthread_mutex_unlock(&t->mu);
  if (last) session_free(t, s);
}

enum { ACQ_OK = 0, ACQ_ENDED = 1, ACQ_CANCELLED = 2 };

/* Waits for the session's cascade to be free and takes it. */
static int acquire(gs_sessions *t, gs_session *s, const gi_cancel *cancel) {
  pthread_mutex_lock(&t->mu);
  while (s->busy && !s->ended && !gi_cancel_check(cancel)) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    ts.tv_nsec += GS_SESSION_WAIT_MS * 1000000L;
    if (ts.tv_nsec >= 1000000000L) ts.tv_sec++, ts.tv_nsec -= 1000000000L;
    pthread_cond_timedwait(&t->idle, &t->mu, &ts);
  }
  int rc = s->ended ? ACQ_ENDED : gi_cancel_check(cancel) ? ACQ_CANCELLED : ACQ_OK;
  if (rc == ACQ_OK) s->busy = 1;
  pthread_mutex_unlock(&t->mu);
  return rc;
}

/* Lets the next request in; the idle clock starts again now. */
static void release(gs_sessions *t, gs_session *s) {
  pthread_mutex_lock(&t->mu);
  s->busy = 0;
  s->last_used_ms = gs_now_ms();
  pthread_cond_broadcast(&t->idle);
  pthread_mutex_unlock(&t->mu);
}

static void fail(gs_answer *a, int status, int retry_after_s, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void fail(gs_answer *a, int status, int retry_after_s, const char *fmt, ...) {
  gi_proto_error e;
  char msg[sizeof e.message];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  gi_proto_fail(&e, status, "%s", msg);
  gs_answer_error(a, &e);
  a->retry_after_s = retry_after_s;
}

static void not_found(gs_service *svc, gs_answer *a, const char *sid) {
  fail(a, 404, 0, "session '%.40s' does not exist or has ended (sessions end on DELETE or after %g s idle)", sid,
       svc->cfg->session_ttl_s);
}

/* The session's JSON (200 or 201). */
static void answer_session(gs_service *svc, gs_session *s, int status, gs_answer *a) {
  gi_proto_session ps = {.ttl_s = svc->cfg->session_ttl_s, .moves = s->moves, .bytes = s->held};
  snprintf(ps.id, sizeof ps.id, "%s", s->id);
  snprintf(ps.scene, sizeof ps.scene, "%s", s->scene->id);
  memcpy(ps.at, s->at, sizeof ps.at);
  a->json = gi_proto_session_json(&ps);
  if (!a->json) return fail(a, 500, 0, "could not encode the session");
  a->status = status;
  a->content_type = "application/json";
  snprintf(a->location, sizeof a->location, "/v1/sessions/%s", s->id);
}

static int random_id(char out[GS_SESSION_ID_LEN + 1]) {
  unsigned char b[GS_SESSION_ID_BYTES];
  size_t got = 0;
  while (got < sizeof b) {
    ssize_t n = getrandom(b + got, sizeof b - got, 0);
    if (n < 0 && errno != EINTR) return -1;
    if (n > 0) got += (size_t)n;
  }
  for (size_t i = 0; i < sizeof b; i++) snprintf(out + 2 * i, 3, "%02x", b[i]);
  return 0;
}

/* Takes a creation slot, or answers 503. */
static int take_slot(gs_sessions *t, gs_answer *a) {
  pthread_mutex_lock(&t->mu);
  int max = t->svc->cfg->max_sessions, full = t->open + t->creating >= max;
  int retry = full ? retry_after_locked(t) : 0;
  if (!full) t->creating++;
  pthread_mutex_unlock(&t->mu);
  if (!full) return 0;
  gs_metrics_session(t->svc->metrics, GS_SESSION_REJECTED);
  fail(a, 503, retry, "busy: %d sessions are open, the server's limit (max_sessions); retry after %d s, when an idle "
       "one expires, or DELETE one you hold", max, retry);
  return -1;
}

static void give_slot(gs_sessions *t) {
  pthread_mutex_lock(&t->mu);
  t->creating--;
  pthread_mutex_unlock(&t->mu);
}

/* Bytes sessions hold, up (sign 1) or down (-1). */
static void add_bytes(gs_sessions *t, size_t n, int sign) {
  pthread_mutex_lock(&t->mu);
  if (sign > 0) t->bytes += n;
  else t->bytes -= n;
  pthread_mutex_unlock(&t->mu);
}

/* The new session's cascade, baked at at: 0, or the answer is in a. */
static int bake_session(gs_service *svc, gs_session *s, const double at[3], const gi_cancel *cancel, gs_answer *a) {
  gi_error_info e = {0};
  gi_result rc;
  s->resolved = gs_resolve_request(svc, s->scene, &s->req, &s->req, &e, &rc);
  if (rc != GI_OK) return gs_answer_core_error(a, rc, &e), -1;
  /* The bake, and what its moves add (the re-bake's texture): held for the session's life. */
  size_t need = gs_bake_bytes(&s->resolved) + gi_cascade_move_bytes_estimate(&s->resolved);
  if ((rc = gs_cache_hold(svc->cache, need, &e)) != GI_OK) {
    if (rc == GI_ERR_NOMEM) gs_metrics_session(svc->metrics, GS_SESSION_REJECTED);
    return gs_answer_core_error(a, rc, &e), -1;
  }
  /* Counted from now, as the budget counts it: while the bake ran,
   * /metrics read 0 session bytes beside a 503 naming 501 MiB of them. */
  add_bytes(svc->sessions, need, 1);
  double t0 = gs_now_ms();
  gs_metrics_bake_begin(svc->metrics);
  rc = gi_cascade_bake_ex(s->scene->scene, at, &s->req, cancel, &s->cascade, NULL, &e);
  gs_metrics_bake_end(svc->metrics, rc == GI_ERR_CANCELLED);
  if (rc == GI_OK) {
    gs_metrics_bake(svc->metrics, (gs_now_ms() - t0) * 1e-3);
    rc = gi_cascade_anchor(s->scene->scene, at, &s->resolved, s->anchor, &e);
  }
  /* What moves need, now: the first move does not pay for it. */
  if (rc == GI_OK) rc = gi_cascade_move_prepare(s->cascade, &e);
  if (rc != GI_OK) {
    gi_cascade_free(s->cascade);
    add_bytes(svc->sessions, need, -1);
    gs_cache_unhold(svc->cache, need);
    return gs_answer_core_error(a, rc, &e), -1;
  }
  s->held = need;
  memcpy(s->at, at, sizeof s->at);
  return 0;
}

void gs_session_create(gs_service *svc, const gs_scene *sc, const gi_proto_bake *b, const gi_cancel *cancel,
                       double t_start_ms, gs_answer *a) {
  gs_sessions *t = svc->sessions;
  if (take_slot(t, a)) return;
  gs_session *s = calloc(1, sizeof *s);
  if (!s || random_id(s->id)) {
    free(s);
    give_slot(t);
    return fail(a, 503, 0, "sessions: out of memory or randomness for a new session");
  }
  s->scene = sc;
  s->req = b->quality;
  if (bake_session(svc, s, b->has_at ? b->at : sc->default_at, cancel, a)) {
    free(s);
    give_slot(t);
    return;
  }
  pthread_mutex_lock(&t->mu);
  t->creating--;
  t->open++;
  s->last_used_ms = gs_now_ms();
  s->next = t->head;
  t->head = s;
  /* Answered before the lock is let go: no request can move it yet. */
  answer_session(svc, s, 201, a);
  const gi_bake_report *rep = gi_cascade_report(s->cascade);
  gi_proto_server_timing(&rep->ms, gs_now_ms() - t_start_ms, a->server_timing, sizeof a->server_timing);
  gi_proto_effects_header(rep->effects, a->effects, sizeof a->effects);
  pthread_mutex_unlock(&t->mu);
  gs_metrics_session(svc->metrics, GS_SESSION_CREATED);
}

/* X-GI-Move: the move's number, whether it closed the refresh cycle (the
 * cascade then equals a cold bake), relit, rebuilt levels, crossed a cell. */
static void move_header(gs_answer *a, const gi_bake_report *rep, const gi_move_info *mi, int crossed) {
  int rebuilt = 0;
  unsigned long long vox = 0;
  for (int d = 0; d < rep->levels && d < GI_MAX_LEVELS; d++) {
    rebuilt += mi->rebuilt[d] != 0;
    vox += rep->level_voxelized[d];
  }
  snprintf(a->move, sizeof a->move, "n=%llu cycle=%d rebuilt=%d crossed=%d relit=%d voxelized=%llu",
           (unsigned long long)mi->move, mi->cycle_closed, rebuilt, crossed, mi->relit, vox);
}

/* Moves s (held and acquired) to b->at and answers. */
static void move_and_answer(gs_service *svc, gs_session *s, const gi_proto_bake *b, double t_start_ms,
                            const gi_cancel *cancel, gs_answer *a) {
  gi_error_info e = {0};
  gi_bake_report rep;
  gi_move_info mi;
  double t0 = gs_now_ms();
  /* The move stops at the request's deadline, not when its client hangs up: a walking client
   * drops stale requests and times out by design, and the finished move is what its next request
   * reads, where a stopped one would make every next move a cold bake (a client whose timeout is
   * shorter than that would never be answered again). A stopped move leaves the cascade partial;
   * the next move re-bakes it (gi_move.h). */
  gi_cancel *until = gi_cancel_new();
  if (!until) return fail(a, 503, 1, "out of memory for the move's deadline");
  gi_cancel_set_deadline(until, gi_now_ms() + (t_start_ms + svc->cfg->deadline_s * 1e3 - gs_now_ms()));
  gi_result rc = gi_cascade_move_ex(s->cascade, b->at, until, &rep, &mi, &e);
  gi_cancel_free(until);
  if (rc == GI_ERR_NONFINITE || rc == GI_ERR_INVALID_ARG)
    return fail(a, 400, 0, "parameter 'at': %s", e.msg[0] ? e.msg : gi_strerror(rc)); /* cascade untouched */
  if (rc == GI_ERR_CANCELLED) {
    /* Past the deadline: http.c answers its 504 (Retry-After, gi_timeouts_total). */
    gs_metrics_move_cancelled(svc->metrics);
    return fail(a, 504, (int)ceil(svc->cfg->deadline_s), "the session's move was stopped at the deadline; "
                "the session stays: its next move re-bakes its cascade there");
  }
  if (rc != GI_OK) {
    /* A failed move (out of memory) leaves the cascade partial: the session cannot go on. */
    pthread_mutex_lock(&svc->sessions->mu);
    unlink_session(svc->sessions, s);
    pthread_mutex_unlock(&svc->sessions->mu);
    return fail(a, gs_status_of(rc), 0, "session ended: its move failed: %s", e.msg[0] ? e.msg : gi_strerror(rc));
  }
  gs_metrics_move(svc->metrics, (gs_now_ms() - t0) * 1e-3, mi.cycle_closed);
  int64_t anchor[3];
  int crossed = 0;
  if (gi_cascade_anchor(s->scene->scene, b->at, &s->resolved, anchor, NULL) == GI_OK) {
    crossed = memcmp(anchor, s->anchor, sizeof anchor) != 0;
    memcpy(s->anchor, anchor, sizeof anchor);
  }
  pthread_mutex_lock(&svc->sessions->mu); /* GET /v1/sessions/{sid} reads them */
  memcpy(s->at, b->at, sizeof s->at);
  s->moves++;
  pthread_mutex_unlock(&svc->sessions->mu);
  gi_timings ms = rep.ms;
  ms.gather = ms.encode = 0;
  rc = gs_answer_lighting(svc, s->scene, s->cascade, b, cancel, "session", &ms, t_start_ms, a, &e);
  if (rc != GI_OK) return gs_answer_core_error(a, rc, &e);
  move_header(a, &rep, &mi, crossed);
}

void gs_session_lighting(gs_service *svc, const char *sid, const gi_proto_bake *b, double t_start_ms,
                         const gi_cancel *cancel, gs_answer *a) {
  gs_sessions *t = svc->sessions;
  gs_session *s = hold(t, sid);
  if (!s) return not_found(svc, a, sid);
  int acq = acquire(t, s, cancel);
  if (acq == ACQ_ENDED) not_found(svc, a, sid);
  else if (acq == ACQ_CANCELLED)
    fail(a, 504, (int)ceil(svc->cfg->deadline_s), "the request gave up waiting for its session's previous request");
  else {
    move_and_answer(svc, s, b, t_start_ms, cancel, a);
    release(t, s);
  }
  put(t, s);
}

const gs_scene *gs_session_scene(gs_service *svc, const char *sid) {
  pthread_mutex_lock(&svc->sessions->mu);
  gs_session *s = find(svc->sessions, sid);
  const gs_scene *sc = s ? s->scene : NULL;
  pthread_mutex_unlock(&svc->sessions->mu);
  return sc;
}

void gs_session_info(gs_service *svc, const char *sid, gs_answer *a) {
  gs_sessions *t = svc->sessions;
  pthread_mutex_lock(&t->mu);
  gs_session *s = find(t, sid);
  if (s) answer_session(svc, s, 200, a);
  pthread_mutex_unlock(&t->mu);
  if (!s) not_found(svc, a, sid);
}

void gs_session_delete(gs_service *svc, const char *sid, gs_answer *a) {
  gs_sessions *t = svc->sessions;
  pthread_mutex_lock(&t->mu);
  gs_session *s = find(t, sid);
  int now = 0;
  if (s) {
    unlink_session(t, s);
    now = s->refs == 0; /* else the last request frees it */
  }
  pthread_mutex_unlock(&t->mu);
  if (!s) return not_found(svc, a, sid);
  if (now) session_free(t, s);
  gs_metrics_session(svc->metrics, GS_SESSION_DELETED);
  a->status = 204;
  a->content_type = "application/json";
}
