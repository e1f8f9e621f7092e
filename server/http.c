/* http.c: the HTTP front on libmicrohttpd (the only file that includes it).
 *
 * libmicrohttpd's threads parse, authenticate, route and validate, and
 * answer the cheap endpoints (health, catalog, jobs, metrics) themselves.
 * Anything that bakes or encodes goes to the bounded worker pool: the
 * connection is suspended, the worker fills in the answer and resumes it,
 * so a poll thread never waits for a bake. A full queue is a 503 at once.
 *
 * Deadlines: a reaper thread answers 504 for a request still unanswered at
 * its deadline. The worker and the reaper race to answer; one mutex and
 * the request's `done` flag make exactly one of them win, and resume is
 * only ever called on a suspended connection. A request lives until both
 * libmicrohttpd and its task have let go of it (reference count).
 *
 * Cancelling: a request that waits for another request's bake returns
 * its worker (the cache's GS_PENDING) and stays suspended; the baking
 * worker's completion queues it again. The reaper also watches suspended
 * connections for a hang-up (libmicrohttpd does not poll them). A request
 * past its deadline or whose client left tells the cache it is no longer
 * interested, and a bake nobody waits for is cancelled.
 *
 * Hostile clients: the first call for a request (headers complete) routes,
 * authenticates and checks the framing, and answers a refusal at once, so
 * no body is read and no "100 Continue" sent for it. The same reaper also
 * shuts down connections whose request has been arriving for longer than
 * request_timeout_s (libmicrohttpd's own timeout restarts on every byte). */
#define _POSIX_C_SOURCE 200809L
#include <arpa/inet.h>
#include <errno.h>
#include <jansson.h>
#include <limits.h>
#include <math.h>
#include <microhttpd.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>
#include "server.h"
#include "gi_git_rev.h" /* GI_GIT_REV: generated at build time (cmake/git_rev.cmake) */

/* More query parameters than this is a 400 (the contract's limit). */
#define GS_MAX_PARAMS 64
/* libmicrohttpd's memory per connection: headers, the query's parsed
 * parameters (about 48 bytes each) and the read buffer. Its default, 32 KiB,
 * ran out at ~500 parameters and left the client hanging without a status. */
#define GS_CONNECTION_MEMORY ((size_t)256 << 10)
/* The core refuses viewpoints more than this from the scene's origin on an axis; say so at once. */
#define GS_MAX_DISTANCE 1e9
#define GS_MAX_DISTANCE_TEXT "1e9"
/* Connections at once, from all clients. */
#define GS_MAX_CONNECTIONS 1000u
/* A connection silent this long is closed (libmicrohttpd's timer, which
 * restarts on every byte; request_timeout_s bounds the whole request). */
#define GS_IDLE_TIMEOUT_S 60u
/* What libmicrohttpd's parser takes from the connection's memory per query
 * parameter (its header record, rounded up). */
#define GS_PARAM_COST 64
/* A number macro as a string literal. */
#define GS_STR_(x) #x
#define GS_STR(x) GS_STR_(x)
/* How often the reaper looks at deadlines. */
#define GS_REAPER_PERIOD_MS 50
/* libmicrohttpd messages logged per second at most; the rest are counted. */
#define GS_MHD_LOG_PER_S 20

typedef struct {
  gi_proto_kv kv[GS_MAX_PARAMS];
  size_t n;
  int overflow;
  const char *nul_key;  /* a value with a NUL byte in it */
} query;

typedef struct gs_req {
  gs_http *h;
  struct MHD_Connection *conn;
  gs_endpoint ep;
  const gs_scene *scene;
  char method[8];
  char path[160];
  char id[64];              /* the scene or job id the route named */
  int cell_url;             /* /v1/scenes/{id}/cells/{i},{j},{k}/...: cell names the cascade */
  int64_t cell[3];
  char cell_far[112];       /* a cell URL whose index has too many digits to address: "(i, j, k)" */
  /* A cell answer's headers, sent with a 200 or 304 (canonical.c). */
  char etag[24];
  const char *cache_control;
  char content_location[768];
  double t_start, deadline;
  char *body;
  size_t len, cap;
  int too_large;
  int answered;             /* a response is queued */
  /* Guarded by h->mu. */
  int dispatched, suspended, done;
  int gone;                 /* the client hung up while it waited: close without an answer */
  gs_waiter w;              /* its interest in a bake (cache.c) */
  gi_cancel *cancel;        /* its other work: set when it is given up (deadline, hang-up) */
  gs_answer ans;
  gi_proto_bake bake;
  gi_proto_probes probes;
  atomic_int refs;
  struct gs_req *prev, *next;  /* waiting list (dispatched, not done) */
} gs_req;

/* One TCP connection, for the absolute request deadline: libmicrohttpd's
 * own timeout restarts on every byte, so a client sending one byte a second
 * would hold its connection for ever. */
typedef struct gs_conn {
  int fd;
  double t_phase;     /* when the request now arriving started (or the connection) */
  int receiving;      /* its headers or body are still arriving */
  int cut;            /* shut down for missing the deadline */
  struct gs_conn *prev, *next;
} gs_conn;

struct gs_http {
  gs_service *svc;
  struct MHD_Daemon *d;
  int port;
  pthread_mutex_t mu;
  gs_req *waiting;
  pthread_t reaper;
  int stop;
  pthread_cond_t stop_cv;
  pthread_mutex_t conn_mu;  /* guards conns and cut_logged; never held with mu */
  gs_conn *conns;
  unsigned long cuts, cuts_logged;
  atomic_int closing;       /* shutting down: new connections are closed at accept */
  pthread_mutex_t log_mu;   /* guards the libmicrohttpd log budget below */
  double log_second;        /* when the current second of the budget began */
  unsigned log_lines;       /* lines logged in it */
  unsigned long log_dropped; /* lines not logged since the last note */
};

static void req_release(gs_req *r) {
  if (atomic_fetch_sub(&r->refs, 1) != 1) return;
  gs_answer_free(&r->ans);
  gi_proto_probes_free(&r->probes);
  gi_cancel_free(r->cancel);
  free(r->body);
  free(r);
}

/* ---- answers ------------------------------------------------------------ */

static void answer_json(gs_answer *a, int status, json_t *o) {
  a->status = status;
  a->json = o ? json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(10)) : NULL;
  json_decref(o);
  a->content_type = "application/json";
  if (!a->json) {
    gi_proto_error e;
    gi_proto_fail(&e, 500, "could not encode the answer");
    gs_answer_error(a, &e);
  }
}

static void answer_fail(gs_answer *a, int status, const char *fmt, const char *arg);

static void answer_json_precise(gs_answer *a, int status, json_t *o) {
  a->status = status;
  a->json = o ? json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(17)) : NULL;
  json_decref(o);
  a->content_type = "application/json";
  if (!a->json) answer_fail(a, 500, "%s", "could not encode the answer");
}

static void answer_fail(gs_answer *a, int status, const char *fmt, const char *arg) {
  gi_proto_error e;
  gi_proto_fail(&e, status, fmt, arg);
  gs_answer_error(a, &e);
}

/* The methods an endpoint takes (405's Allow). */
static const char *allowed_methods(gs_endpoint ep) {
  if (ep == GS_EP_PROBES || ep == GS_EP_SESSIONS) return "POST";
  if (ep == GS_EP_JOB || ep == GS_EP_SESSION) return "GET, HEAD, DELETE";
  /* A session's GET moves its cascade: a HEAD must change nothing, so it has none. */
  if (ep == GS_EP_SESSION_LIGHTING) return "GET";
  return "GET, HEAD";
}

static enum MHD_Result send_answer(gs_http *h, gs_req *r) {
  gs_answer *a = &r->ans;
  struct MHD_Response *resp;
  if (a->blob) {
    /* The blob's reference goes to libmicrohttpd, which drops it when done. */
    resp = MHD_create_response_from_buffer_with_free_callback(a->blob->size, a->blob->data, gs_blob_release_data);
    if (resp) a->blob = NULL;
  } else if (a->fd >= 0) {
    resp = MHD_create_response_from_fd(a->size, a->fd);
    if (resp) a->fd = -1; /* libmicrohttpd closes it */
  } else {
    const char *body = a->json ? a->json : "";
    resp = MHD_create_response_from_buffer(strlen(body), (void *)body, MHD_RESPMEM_MUST_COPY);
  }
  if (!resp) return MHD_NO;
  if (a->status != 304)
    MHD_add_response_header(resp, "Content-Type", a->content_type ? a->content_type : "application/json");
  /* Only a cell's answer is cacheable, never an error or a busy 503. */
  int cell_ok = r->etag[0] && (a->status == 200 || a->status == 304);
  const char *cc = cell_ok ? r->cache_control : a->cache_control;
  MHD_add_response_header(resp, "Cache-Control", cc ? cc : "no-store");
  if (cell_ok) MHD_add_response_header(resp, "ETag", r->etag);
  if (cell_ok && r->content_location[0]) MHD_add_response_header(resp, "Content-Location", r->content_location);
  if (!a->server_timing[0])
    snprintf(a->server_timing, sizeof a->server_timing, "total;dur=%.2f", gs_now_ms() - r->t_start);
  MHD_add_response_header(resp, "Server-Timing", a->server_timing);
  if (a->effects[0]) MHD_add_response_header(resp, "X-GI-Effects", a->effects);
  if (a->cache) MHD_add_response_header(resp, "X-GI-Cache", a->cache);
  if (a->move[0]) MHD_add_response_header(resp, "X-GI-Move", a->move);
  if (a->disposition[0]) MHD_add_response_header(resp, "Content-Disposition", a->disposition);
  if (a->location[0]) MHD_add_response_header(resp, "Location", a->location);
  if (a->status == 503 || a->status == 504) {
    char retry[16];
    snprintf(retry, sizeof retry, "%d", a->retry_after_s > 0 ? a->retry_after_s : 1);
    MHD_add_response_header(resp, "Retry-After", retry);
  }
  if (a->status == 401) MHD_add_response_header(resp, "WWW-Authenticate", "Bearer realm=\"gi-server\"");
  if (a->status == 405)
    MHD_add_response_header(resp, "Allow", allowed_methods(r->ep));
  enum MHD_Result ok = MHD_queue_response(r->conn, (unsigned)a->status, resp);
  r->answered = 1;
  MHD_destroy_response(resp);
  double secs = (gs_now_ms() - r->t_start) * 1e-3;
  gs_metrics_request(h->svc->metrics, r->ep, a->status, secs);
  if (a->status == 503) gs_metrics_rejected(h->svc->metrics);
  char method[4 * sizeof r->method], path[4 * sizeof r->path];
  gs_log_escape(r->method, method, sizeof method);
  gs_log_escape(r->path, path, sizeof path);
  fprintf(stderr, "gi-server: %s %s %d %.1f ms%s%s\n", method, path, a->status, secs * 1e3, a->cache ? " " : "",
          a->cache ? a->cache : "");
  return ok;
}

/* ---- worker side -------------------------------------------------------- */

static void waiting_remove(gs_http *h, gs_req *r) {
  if (r->prev) r->prev->next = r->next;
  else if (h->waiting == r) h->waiting = r->next;
  if (r->next) r->next->prev = r->prev;
  r->prev = r->next = NULL;
}

/* The 504 of a request past its deadline, whoever saw it first: the
 * reaper, or the worker whose lightmap, gather or session wait stopped on
 * the request's token (which carries the deadline). The same request would
 * cost as much again: retry after a deadline's time, when the server may be
 * less busy, or ask for less. stopped: what was stopped, or "". */
static void deadline_answer(gs_http *h, gs_answer *a, const char *stopped) {
  const gs_config *cfg = h->svc->cfg;
  int retry = (int)ceil(cfg->deadline_s);
  gi_proto_error e;
  gi_proto_fail(&e, 504, "the request took longer than the server's deadline of %g s%s; a retry costs as much: "
                "retry after %d s, or ask for a cheaper quality", cfg->deadline_s, stopped, retry);
  gs_answer_error(a, &e);
  a->retry_after_s = retry;
  gs_metrics_timeout(h->svc->metrics);
}

/* Hands an answer to the request unless the reaper answered first. */
static void complete(gs_http *h, gs_req *r, gs_answer *a) {
  pthread_mutex_lock(&h->mu);
  if (r->done) {
    pthread_mutex_unlock(&h->mu);
    gs_answer_free(a);
    return;
  }
  /* Stopped by its deadline before the reaper looked: the reaper's answer
   * (it was a 504 with Retry-After 1, not counted in gi_timeouts_total). */
  if (a->status == 504 && gi_cancel_check(r->cancel) == GI_CANCEL_DEADLINE)
    deadline_answer(h, a, " and its work was stopped");
  r->done = 1;
  r->ans = *a;
  waiting_remove(h, r);
  if (r->suspended) {
    r->suspended = 0;
    MHD_resume_connection(r->conn);
  }
  pthread_mutex_unlock(&h->mu);
}

static void task(void *arg) {
  gs_req *r = arg;
  gs_http *h = r->h;
  pthread_mutex_lock(&h->mu);
  int skip = r->done;
  pthread_mutex_unlock(&h->mu);
  if (!skip) {
    gs_answer a = {.fd = -1};
    if (r->ep == GS_EP_PROBES) gs_serve_probes(h->svc, r->scene, &r->probes, r->t_start, &r->w, r->cancel, &a);
    else if (r->ep == GS_EP_SESSIONS) gs_session_create(h->svc, r->scene, &r->bake, r->cancel, r->t_start, &a);
    else if (r->ep == GS_EP_SESSION_LIGHTING)
      gs_session_lighting(h->svc, r->id, &r->bake, r->t_start, r->cancel, &a);
    else gs_serve_bake(h->svc, r->scene, r->ep, &r->bake, r->t_start, &r->w, r->cancel, &a);
    /* Status 0: it waits for another request's bake; wake_request queues it again. */
    if (a.status) complete(h, r, &a);
  }
  req_release(r);
}

/* The cache holds r (under its lock) for the wake that follows. */
static void hold_request(void *arg) {
  gs_req *r = arg;
  atomic_fetch_add(&r->refs, 1);
}

/* The bake r waited for ended: run r again on a worker (a cache hit now). */
static void wake_request(void *arg) {
  gs_req *r = arg;
  gs_http *h = r->h;
  pthread_mutex_lock(&h->mu);
  int done = r->done;
  pthread_mutex_unlock(&h->mu);
  /* Not to run again (answered meanwhile, or no worker takes it): the
   * entry the wake handed it goes back (gs_cache_leave), or it stayed
   * held, and counted, until the server stopped. */
  if (done) {
    gs_cache_leave(h->svc->cache, &r->w);
    req_release(r);
    return;
  }
  /* It waited its turn already: ahead of the queue, not behind other bakes. */
  if (gs_pool_submit_first(h->svc->pool, task, r) == 0) return; /* the task takes the hold */
  gs_cache_leave(h->svc->cache, &r->w);
  gi_proto_error e;
  gi_proto_fail(&e, 503, "%s", "the server is busy: the bake this request waited for is done, but no worker "
                               "could take it; retry after 1 s");
  gs_answer a = {.fd = -1};
  gs_answer_error(&a, &e);
  complete(h, r, &a);
  req_release(r);
}

/* Whether the client of a suspended request has closed its connection
 * (libmicrohttpd does not poll suspended connections). */
static int hung_up(gs_req *r) {
  const union MHD_ConnectionInfo *ci = MHD_get_connection_info(r->conn, MHD_CONNECTION_INFO_CONNECTION_FD);
  if (!ci) return 0;
  struct pollfd p = {.fd = ci->connect_fd, .events = POLLIN};
  if (poll(&p, 1, 0) <= 0) return 0;
  if (p.revents & (POLLHUP | POLLERR)) return 1;
  /* Readable: the end of the stream (0), or a pipelined request (kept). */
  char b;
  ssize_t n = recv(ci->connect_fd, &b, 1, MSG_PEEK | MSG_DONTWAIT);
  return n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR);
}

/* Past its deadline (504) or hung up (closed without an answer): r leaves
 * its bake, which is cancelled when nobody else waits for it. Called
 * unlocked with a reference on r; r is done and out of the waiting list. */
static void give_up(gs_http *h, gs_req *r) {
  int cancelled = gs_cache_leave(h->svc->cache, &r->w);
  if (r->cancel) gi_cancel_set(r->cancel);
  static const char *const stopped[3] = {"", " and its bake was stopped", " and its gather was stopped"};
  if (!r->gone) deadline_answer(h, &r->ans, stopped[cancelled]);
  pthread_mutex_lock(&h->mu);
  if (r->suspended) {
    r->suspended = 0;
    MHD_resume_connection(r->conn);
  }
  pthread_mutex_unlock(&h->mu);
  req_release(r);
}

/* Gives up every waiting request past its deadline or whose client left.
 * Called locked (mu); returns locked, having unlocked in between. */
static void reap_deadlines(gs_http *h) {
  double now = gs_now_ms();
  gs_req *expired = NULL;
  for (gs_req *r = h->waiting, *n; r; r = n) {
    n = r->next;
    if (r->done) continue;
    int gone = r->suspended && hung_up(r);
    if (now < r->deadline && !gone) continue;
    r->done = 1;
    r->gone = gone && now < r->deadline;
    waiting_remove(h, r);
    atomic_fetch_add(&r->refs, 1);
    r->next = expired; /* a private list now: r left the waiting list */
    expired = r;
  }
  pthread_mutex_unlock(&h->mu);
  for (gs_req *r = expired, *n; r; r = n) {
    n = r->next;
    r->next = NULL;
    give_up(h, r);
  }
  pthread_mutex_lock(&h->mu);
}

/* ---- connections: the absolute request deadline -------------------------- */

static void on_connection(void *cls, struct MHD_Connection *conn, void **socket_context,
                          enum MHD_ConnectionNotificationCode code) {
  gs_http *h = cls;
  if (code == MHD_CONNECTION_NOTIFY_STARTED) {
    gs_conn *c = calloc(1, sizeof *c);
    const union MHD_ConnectionInfo *ci = MHD_get_connection_info(conn, MHD_CONNECTION_INFO_CONNECTION_FD);
    if (!c || !ci) {
      free(c); /* without a record only libmicrohttpd's idle timeout applies */
      return;
    }
    c->fd = ci->connect_fd;
    c->t_phase = gs_now_ms();
    c->receiving = 1;
    pthread_mutex_lock(&h->conn_mu);
    c->next = h->conns;
    if (h->conns) h->conns->prev = c;
    h->conns = c;
    pthread_mutex_unlock(&h->conn_mu);
    *socket_context = c;
    return;
  }
  gs_conn *c = *socket_context;
  if (!c) return;
  /* libmicrohttpd closes the socket after this: until then c->fd is ours. */
  pthread_mutex_lock(&h->conn_mu);
  if (c->prev) c->prev->next = c->next;
  else h->conns = c->next;
  if (c->next) c->next->prev = c->prev;
  pthread_mutex_unlock(&h->conn_mu);
  free(c);
  *socket_context = NULL;
}

static gs_conn *conn_of(struct MHD_Connection *conn) {
  const union MHD_ConnectionInfo *ci = MHD_get_connection_info(conn, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
  return ci ? ci->socket_context : NULL;
}

/* The whole request is in: from here the bake deadline (504) applies. */
static void conn_request_arrived(gs_http *h, struct MHD_Connection *conn) {
  gs_conn *c = conn_of(conn);
  if (!c) return;
  pthread_mutex_lock(&h->conn_mu);
  c->receiving = 0;
  pthread_mutex_unlock(&h->conn_mu);
}

/* Answered: the next request on this connection starts its clock now. */
static void conn_request_done(gs_http *h, struct MHD_Connection *conn) {
  gs_conn *c = conn_of(conn);
  if (!c) return;
  pthread_mutex_lock(&h->conn_mu);
  c->receiving = 1;
  c->t_phase = gs_now_ms();
  pthread_mutex_unlock(&h->conn_mu);
}

/* Shuts down every connection whose request has been arriving for longer
 * than request_timeout_s; libmicrohttpd then sees the socket closed and
 * cleans up on its own thread. Logs a count at most once a second. */
static void cut_slow_connections(gs_http *h, double *last_log) {
  double limit = h->svc->cfg->request_timeout_s * 1e3, now = gs_now_ms();
  pthread_mutex_lock(&h->conn_mu);
  for (gs_conn *c = h->conns; c; c = c->next) {
    if (!c->receiving || c->cut || now - c->t_phase <= limit) continue;
    shutdown(c->fd, SHUT_RDWR);
    c->cut = 1;
    h->cuts++;
  }
  unsigned long cuts = h->cuts, fresh = cuts - h->cuts_logged;
  int log = fresh && now - *last_log >= 1000;
  if (log) h->cuts_logged = cuts, *last_log = now;
  pthread_mutex_unlock(&h->conn_mu);
  if (log)
    fprintf(stderr, "gi-server: closed %lu connection(s) that sent no whole request within %g s, or a query too large "
            "to parse (%lu so far)\n", fresh,
            h->svc->cfg->request_timeout_s, cuts);
}

static void mhd_log_note(gs_http *h, double now);

static void *reaper_main(void *p) {
  gs_http *h = p;
  double last_log = 0;
  pthread_mutex_lock(&h->mu);
  while (!h->stop) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    ts.tv_nsec += GS_REAPER_PERIOD_MS * 1000000L;
    if (ts.tv_nsec >= 1000000000L) ts.tv_sec++, ts.tv_nsec -= 1000000000L;
    pthread_cond_timedwait(&h->stop_cv, &h->mu, &ts);
    reap_deadlines(h);
    pthread_mutex_unlock(&h->mu);
    cut_slow_connections(h, &last_log);
    pthread_mutex_lock(&h->log_mu);
    mhd_log_note(h, gs_now_ms()); /* the count, even when the flood has stopped */
    pthread_mutex_unlock(&h->log_mu);
    gs_sessions_sweep(h->svc->sessions);
    pthread_mutex_lock(&h->mu);
  }
  pthread_mutex_unlock(&h->mu);
  return NULL;
}

/* r waits for its answer: on the waiting list (the reaper's deadlines),
 * its connection suspended. Locked. */
static void suspend(gs_http *h, gs_req *r) {
  r->next = h->waiting;
  if (h->waiting) h->waiting->prev = r;
  h->waiting = r;
  r->suspended = 1;
  MHD_suspend_connection(r->conn);
}

/* Queues r's work and suspends the connection; 503 when the queue is full. */
static enum MHD_Result dispatch(gs_http *h, gs_req *r) {
  /* Work that is not a cached bake (sessions, lightmaps, gathers) stops on
   * this token (without one, at its own pace); cached bakes stop through the
   * waiter. A probe list waits for its tiles' bakes on its own worker. */
  r->cancel = gi_cancel_new();
  if (r->cancel) gi_cancel_set_deadline(r->cancel, gi_now_ms() + (r->deadline - gs_now_ms()));
  r->w.blocking = r->ep == GS_EP_PROBES;
  pthread_mutex_lock(&h->mu);
  r->dispatched = 1;
  /* A bake for the same cell already running: wait for it without a
   * worker or a queue slot (it wakes r when it ends; the mutex held keeps
   * that wake from completing r before it is suspended). */
  if (gs_serve_join_running(h->svc, r->scene, r->ep, &r->bake, &r->w)) {
    suspend(h, r);
    pthread_mutex_unlock(&h->mu);
    return MHD_YES;
  }
  atomic_fetch_add(&r->refs, 1);
  if (gs_pool_submit(h->svc->pool, task, r) != 0) {
    atomic_fetch_sub(&r->refs, 1);
    r->done = 1;
    pthread_mutex_unlock(&h->mu);
    int depth, cap, busy;
    gs_pool_stats(h->svc->pool, &depth, &cap, &busy);
    gi_proto_error e;
    gi_proto_fail(&e, 503, "the server is busy: %d requests wait for %d workers; retry after 1 s", depth, busy);
    gs_answer_error(&r->ans, &e);
    return send_answer(h, r);
  }
  if (!r->done) {
    /* The task cannot resume before this: it takes the same mutex. */
    suspend(h, r);
    pthread_mutex_unlock(&h->mu);
    return MHD_YES;
  }
  pthread_mutex_unlock(&h->mu);
  return send_answer(h, r);
}

/* ---- cheap endpoints ---------------------------------------------------- */

static json_t *vec3(const double v[3]) { return json_pack("[f,f,f]", v[0], v[1], v[2]); }
static json_t *vec3f(const float v[3]) { return json_pack("[f,f,f]", (double)v[0], (double)v[1], (double)v[2]); }

static json_t *bounds_json(const gi_scene *s) {
  double lo[3], hi[3];
  gi_scene_bounds(s, lo, hi);
  return json_pack("{s:o, s:o}", "min", vec3(lo), "max", vec3(hi));
}

/* GET /v1/scenes/{id}: the scene, its default plan and the grid for the
 * quality knobs in the query (the default quality without any). */
static void scene_info(gs_service *svc, const gs_scene *s, const query *qy, gs_answer *a) {
  gi_proto_bake b;
  gi_proto_error pe;
  gs_canon canon;
  gi_error_info e = {0};
  if (gi_proto_parse_scene(qy->kv, qy->n, &svc->cfg->lim, &b, &pe)) return gs_answer_error(a, &pe);
  gi_result rc = gs_canon_quality(svc, s, &b.quality, &canon, &e);
  if (rc != GI_OK) {
    gi_proto_fail(&pe, 400, "%s", e.msg);
    return gs_answer_error(a, &pe);
  }
  gi_scene_stats st;
  gi_scene_get_stats(s->scene, &st);
  json_t *lights = json_array();
  for (size_t i = 0; i < gi_scene_num_lights(s->scene); i++) {
    const gi_light *l = gi_scene_light(s->scene, i);
    static const char *const types[] = {"sun", "point", "spot", "sky"};
    json_t *o = json_pack("{s:s, s:o}", "type", types[l->type & 3], "color", vec3f(l->color));
    if (l->type == GI_LIGHT_SUN || l->type == GI_LIGHT_SPOT) json_object_set_new(o, "direction", vec3f(l->direction));
    if (l->type == GI_LIGHT_POINT || l->type == GI_LIGHT_SPOT) json_object_set_new(o, "position", vec3(l->position));
    json_array_append_new(lights, o);
  }
  json_t *fx = json_object();
  for (int i = 0; i < GI_FX_COUNT; i++)
    json_object_set_new(fx, gi_effect_name((gi_effect_id)i),
                        json_pack("{s:b, s:s}", "ran", s->effects[i].ran, "why", s->effects[i].why));
  const gi_quality *q = &s->quality;
  /* The core derives the aperture from the cone count at bake time: a cone
   * whose solid angle is its region's, 2 pi (1 - cos h) = 2 pi / N. */
  double ap = q->aperture_deg > 0 ? q->aperture_deg : 2.0 * acos(1.0 - 1.0 / q->cones) * 180.0 / 3.14159265358979;
  json_t *qj = json_pack("{s:i, s:i, s:f, s:i, s:f, s:f, s:i, s:b, s:i, s:i}", "levels", q->levels, "res", q->res,
                         "voxel", q->voxel0, "cones", q->cones, "aperture_deg", ap, "step",
                         (double)q->step, "bounces", q->bounces, "bounce_tail", q->bounce_tail, "samples",
                         q->light_samples, "probe_samples", q->probe_samples);
  json_t *o = json_pack("{s:s, s:s, s:I, s:{s:I, s:I, s:I}, s:i, s:i, s:o, s:o, s:o, s:o, s:o, s:f}", "id", s->id, "up",
                        gi_scene_up(s->scene) == GI_UP_Z ? "z" : "y", "triangles", (json_int_t)st.triangles,
                        "dropped", "nonfinite", (json_int_t)st.dropped_nonfinite, "degenerate",
                        (json_int_t)st.dropped_degenerate, "see_through", (json_int_t)st.dropped_see_through, "materials", (int)st.materials, "emissive_triangles",
                        (int)st.emissive_triangles, "lights", lights, "bounds", bounds_json(s->scene),
                        "default_viewpoint", vec3(s->default_at), "quality", qj, "effects", fx, "load_ms",
                        s->load_ms);
  json_object_set_new(o, "lights_skipped", json_integer(st.lights_skipped));
  json_object_set_new(o, "far_triangles", json_integer((json_int_t)st.far_triangles));
  json_object_set_new(o, "uv2_missing", json_integer((json_int_t)st.uv2_missing));
  json_object_set_new(o, "grid", gs_canon_grid_json(s, &canon));
  /* Full precision: a client snaps with origin and cell_size bit for bit. */
  answer_json_precise(a, 200, o);
}

static void catalog(gs_service *svc, gs_answer *a) {
  json_t *arr = json_array();
  for (size_t i = 0; i < svc->cat->num; i++) {
    const gs_scene *s = &svc->cat->scenes[i];
    gi_scene_stats st;
    gi_scene_get_stats(s->scene, &st);
    char href[96];
    snprintf(href, sizeof href, "/v1/scenes/%s", s->id);
    json_array_append_new(arr, json_pack("{s:s, s:I, s:s, s:o, s:s}", "id", s->id, "triangles",
                                         (json_int_t)st.triangles, "up",
                                         gi_scene_up(s->scene) == GI_UP_Z ? "z" : "y", "bounds",
                                         bounds_json(s->scene), "href", href));
  }
  answer_json(a, 200, json_pack("{s:o}", "scenes", arr));
}

static void health(gs_service *svc, gs_answer *a) {
  answer_json(a, 200, json_pack("{s:s, s:s, s:s, s:s, s:f, s:i}", "status", "ok", "version", GI_VERSION, "git",
                                GI_GIT_REV, "cpu_path", gi_cpu_path(), "uptime_s",
                                (gs_now_ms() - svc->start_ms) * 1e-3, "scenes", (int)svc->cat->num));
}

static void metrics(gs_service *svc, gs_answer *a) {
  gs_gauges g = {0};
  gs_cache_stats(svc->cache, &g.cache_bytes, &g.cache_entries);
  gs_cache_answer_stats(svc->cache, &g.answer_bytes, &g.answers);
  g.cache_budget = svc->cfg->cache_bytes;
  g.inflight_bytes = gs_cache_inflight(svc->cache);
  g.sending_bytes = gs_cache_sending(svc->cache);
  gs_pool_stats(svc->pool, &g.queue_depth, &g.queue_capacity, &g.workers_busy);
  gs_jobs_count(svc->jobs, g.jobs);
  g.uptime_s = (gs_now_ms() - svc->start_ms) * 1e-3;
  g.scenes = svc->cat->num;
  gs_sessions_stats(svc->sessions, &g.sessions_open, &g.session_bytes);
  a->status = 200;
  a->json = gs_metrics_render(svc->metrics, &g);
  a->content_type = "text/plain; version=0.0.4; charset=utf-8";
}

/* ---- routing ------------------------------------------------------------ */

/* Constant-time comparison: the time taken does not depend on where a guess differs. */
static int token_ok(const char *want, const char *got, size_t m) {
  size_t n = strlen(want);
  unsigned char diff = (unsigned char)(n != m);
  for (size_t i = 0; i < n; i++) diff |= (unsigned char)(want[i] ^ (i < m ? got[i] : 0));
  return diff == 0;
}

static int valid_id(const char *s, size_t n) {
  if (n == 0 || n > 63) return 0;
  for (size_t i = 0; i < n; i++)
    if (!((s[i] >= 'a' && s[i] <= 'z') || (s[i] >= 'A' && s[i] <= 'Z') || (s[i] >= '0' && s[i] <= '9') ||
          s[i] == '-' || s[i] == '_'))
      return 0;
  return 1;
}

/* "(i, j, k)" for a message, each index of more than 24 digits shortened
 * to its first 20 and its digit count (the path may be 256 KiB long). */
static void cell_text(const char *seg, char *out, size_t size) {
  size_t o = (size_t)snprintf(out, size, "(");
  for (int i = 0; i < 3 && o < size; i++) {
    size_t n = strcspn(seg, ","), nd = n - (seg[0] == '-');
    int w = nd > 24 ? snprintf(out + o, size - o, "%.*s...(%zu digits)", (int)(n - nd + 20), seg, nd)
                    : snprintf(out + o, size - o, "%.*s", (int)n, seg);
    o += w > 0 ? (size_t)w : 0;
    if (o < size) o += (size_t)snprintf(out + o, size - o, "%s", i < 2 ? ", " : ")");
    seg += n + (i < 2);
  }
}

/* "/cells/{i},{j},{k}/lighting" or ".../cascades.vdb": 1 when it matches.
 * Indices too long to address still route, so the answer is the 400 that
 * names the cell (lighting()), not a 404 for a path that exists. */
static int route_cell(gs_req *r, const char *tail) {
  if (strncmp(tail, "/cells/", 7)) return 0;
  const char *seg = tail + 7, *end = strchr(seg, '/');
  long long c[3];
  if (!end) return 0;
  char *buf = strndup(seg, (size_t)(end - seg));
  if (!buf) return 0;
  int st = gi_proto_parse_cell(buf, c);
  if (st == -2) cell_text(buf, r->cell_far, sizeof r->cell_far);
  free(buf);
  if (st == -1) return 0;
  if (!strcmp(end, "/lighting")) r->ep = GS_EP_LIGHTING;
  else if (!strcmp(end, "/cascades.vdb")) r->ep = GS_EP_CASCADES;
  else return 0;
  r->cell_url = 1;
  for (int a = 0; a < 3; a++) r->cell[a] = st ? 0 : c[a];
  return 1;
}

/* Splits the path into an endpoint and its id; 0 when no route matches. */
static int route(gs_req *r, const char *url, char *id, size_t idsize) {
  if (!strcmp(url, "/v1/health")) return r->ep = GS_EP_HEALTH, 1;
  if (!strcmp(url, "/v1/scenes")) return r->ep = GS_EP_SCENES, 1;
  if (!strcmp(url, "/metrics")) return r->ep = GS_EP_METRICS, 1;
  const char *rest;
  int scenes = !strncmp(url, "/v1/scenes/", 11), jobs = !strncmp(url, "/v1/jobs/", 9);
  int sessions = !strncmp(url, "/v1/sessions/", 13);
  if (!scenes && !jobs && !sessions) return 0;
  rest = url + (scenes ? 11 : jobs ? 9 : 13);
  const char *slash = strchr(rest, '/');
  size_t n = slash ? (size_t)(slash - rest) : strlen(rest);
  if (!valid_id(rest, n) || n >= idsize) return 0;
  memcpy(id, rest, n);
  id[n] = 0;
  const char *tail = slash ? slash : "";
  if (scenes) {
    if (!*tail) r->ep = GS_EP_SCENE;
    else if (!strcmp(tail, "/lighting")) r->ep = GS_EP_LIGHTING;
    else if (!strcmp(tail, "/cascades.vdb")) r->ep = GS_EP_CASCADES;
    else if (!strcmp(tail, "/probes")) r->ep = GS_EP_PROBES;
    else if (!strcmp(tail, "/lightmap-uv.glb")) r->ep = GS_EP_LIGHTMAP_UV;
    else if (!strcmp(tail, "/sessions")) r->ep = GS_EP_SESSIONS;
    else return route_cell(r, tail);
  } else if (sessions) {
    if (!*tail) r->ep = GS_EP_SESSION;
    else if (!strcmp(tail, "/lighting")) r->ep = GS_EP_SESSION_LIGHTING;
    else return 0;
  } else {
    if (!*tail) r->ep = GS_EP_JOB;
    else if (!strcmp(tail, "/result")) r->ep = GS_EP_JOB_RESULT;
    else return 0;
  }
  return 1;
}

/* The bearer token from Authorization and its length in *len, or NULL. The
 * scheme is case-insensitive (RFC 7235); one or more spaces follow it.
 * Trailing spaces and tabs are not part of a field's value (RFC 9110 5.5),
 * but libmicrohttpd 0.9.75 keeps them: they are not part of the token. */
static const char *bearer_token(const char *auth, size_t *len) {
  *len = 0;
  if (!auth || strncasecmp(auth, "Bearer", 6) || auth[6] != ' ') return NULL;
  auth += 6;
  while (*auth == ' ') auth++;
  size_t n = strlen(auth);
  while (n && (auth[n - 1] == ' ' || auth[n - 1] == '\t')) n--;
  *len = n;
  return auth;
}

typedef struct {
  int count;            /* Content-Length headers */
  int differ;           /* two of them disagree */
  int chunked;          /* Transfer-Encoding present */
  int unknown_coding;   /* a Transfer-Encoding other than "chunked" alone */
  const char *length;   /* the first Content-Length */
} framing;

static enum MHD_Result collect_framing(void *cls, enum MHD_ValueKind kind, const char *key, const char *value) {
  framing *f = cls;
  if (!strcasecmp(key, "Transfer-Encoding")) {
    /* libmicrohttpd decodes "chunked" only; any other coding (gzip, "gzip,
     * chunked", identity) it reads as a body without an end, and the client
     * waited for request_timeout_s and got no answer at all. */
    if (f->chunked++ || !value || strcasecmp(value, "chunked")) f->unknown_coding = 1;
  }
  if (strcasecmp(key, "Content-Length")) return MHD_YES;
  if (f->count++ && strcmp(f->length, value ? value : "")) f->differ = 1;
  if (!f->length) f->length = value ? value : "";
  return MHD_YES;
}

/* A body's framing, from the headers: 0, or an error answer in a. Refuses
 * before a byte of the body is read (so no "100 Continue" either). */
static int check_framing(gs_http *h, gs_req *r, gs_answer *a) {
  framing f = {0};
  MHD_get_connection_values(r->conn, MHD_HEADER_KIND, collect_framing, &f);
  if (f.differ) {
    answer_fail(a, 400, "%s", "Content-Length: the request has two different values");
    return -1;
  }
  if (f.count && f.chunked) {
    answer_fail(a, 400, "%s", "Content-Length and Transfer-Encoding: a request may have only one of them");
    return -1;
  }
  if (f.unknown_coding) {
    answer_fail(a, 501, "%s", "Transfer-Encoding: only 'chunked' is supported (RFC 9112 6.1: 501)");
    return -1;
  }
  if (!f.count) return 0;
  const char *d = f.length;
  size_t n = strspn(d, "0123456789");
  if (!n || d[n]) {
    answer_fail(a, 400, "Content-Length: expected a number of bytes, got '%.32s'", d);
    return -1;
  }
  /* 20 digits up to 2^64 - 1 reach here (libmicrohttpd answers longer
   * ones itself): a length, too large, not a malformed one. */
  size_t lim = h->svc->cfg->lim.max_body_bytes;
  unsigned long long len = n > 19 ? ULLONG_MAX : strtoull(d, NULL, 10);
  if (len > lim) {
    gi_proto_error pe;
    gi_proto_fail(&pe, 413, "body: %.32s bytes exceed the server limit of %zu", d, lim);
    gs_answer_error(a, &pe);
    return -1;
  }
  return 0;
}

/* Everything the headers decide, on the first call, before any body is
 * read: route, token, method and framing. 0 to go on, else the answer is in r. */
static int check_headers(gs_http *h, gs_req *r, const char *url) {
  gs_service *svc = h->svc;
  gs_answer *a = &r->ans;
  if (!route(r, url, r->id, sizeof r->id)) {
    r->ep = GS_EP_OTHER;
    answer_fail(a, 404, "no such endpoint: %.100s (see /v1/health, /v1/scenes, /metrics)", url);
    return -1;
  }
  if (r->ep != GS_EP_HEALTH && svc->cfg->token[0]) {
    const char *auth = MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, "Authorization");
    size_t len;
    const char *got = bearer_token(auth, &len);
    if (!token_ok(svc->cfg->token, got, len)) {
      answer_fail(a, 401, "%s", auth ? "the bearer token is not valid" : "an Authorization: Bearer token is required");
      return -1;
    }
  }
  int post = r->ep == GS_EP_PROBES || r->ep == GS_EP_SESSIONS;
  int del = (r->ep == GS_EP_JOB || r->ep == GS_EP_SESSION) && !strcmp(r->method, "DELETE");
  int get_ok = !strcmp(r->method, "GET") || (!strcmp(r->method, "HEAD") && r->ep != GS_EP_SESSION_LIGHTING);
  if (post ? strcmp(r->method, "POST") : !(get_ok || del)) {
    answer_fail(a, 405, "this endpoint takes %s", allowed_methods(r->ep));
    return -1;
  }
  return check_framing(h, r, a);
}

static enum MHD_Result collect(void *cls, enum MHD_ValueKind kind, const char *key, size_t key_size,
                               const char *value, size_t value_size) {
  query *q = cls;
  if ((key && strlen(key) != key_size) || (value && strlen(value) != value_size)) {
    q->nul_key = key ? key : "";
    return MHD_NO;
  }
  if (q->n == GS_MAX_PARAMS) {
    q->overflow = 1;
    return MHD_NO;
  }
  q->kv[q->n++] = (gi_proto_kv){key, value ? value : ""};
  return MHD_YES;
}

/* The query parameters into q: 0, or an error answer in a. */
static int read_query(gs_req *r, query *q, gs_answer *a) {
  MHD_get_connection_values_n(r->conn, MHD_GET_ARGUMENT_KIND, collect, q);
  if (q->nul_key) {
    char key[4 * 64];
    gs_log_escape(q->nul_key, key, sizeof key);
    answer_fail(a, 400, "parameter '%.64s': a NUL byte (%%00) in a parameter is not allowed", key);
    return -1;
  }
  if (q->overflow) {
    answer_fail(a, 400, "%s", "more than 64 query parameters");
    return -1;
  }
  return 0;
}

static void cheap_endpoint(gs_service *svc, gs_req *r, const query *q, gs_answer *a) {
  gi_proto_error pe;
  if (r->ep == GS_EP_SCENE) scene_info(svc, r->scene, q, a);
  else if (gi_proto_parse_none(q->kv, q->n, &pe)) gs_answer_error(a, &pe);
  else if (r->ep == GS_EP_HEALTH) health(svc, a);
  else if (r->ep == GS_EP_SCENES) catalog(svc, a);
  else if (r->ep == GS_EP_METRICS) metrics(svc, a);
  else if (r->ep == GS_EP_JOB && !strcmp(r->method, "DELETE")) gs_jobs_cancel(svc->jobs, r->id, a);
  else if (r->ep == GS_EP_SESSION && !strcmp(r->method, "DELETE")) gs_session_delete(svc, r->id, a);
  else if (r->ep == GS_EP_SESSION) gs_session_info(svc, r->id, a);
  else if (r->ep == GS_EP_JOB) gs_jobs_status(svc->jobs, r->id, a);
  else gs_jobs_result(svc->jobs, r->id, a);
}

/* Points within GS_MAX_DISTANCE of the scene's origin on each axis (the
 * core's rule: it was the bounds grown by it, and 1e9 + 1 past the origin
 * passed here to be refused by the bake in other words), else a 400
 * naming the first far one. */
static int check_near(const gs_scene *s, const double *pts, size_t n, const char *what, gi_proto_error *e) {
  double o[3];
  gi_scene_origin(s->scene, o);
  for (size_t i = 0; i < n; i++)
    for (int k = 0; k < 3; k++) {
      if (fabs(pts[3 * i + k] - o[k]) <= GS_MAX_DISTANCE) continue;
      if (n == 1)
        return gi_proto_fail(e, 400, "%s: out of range: (%g, %g, %g) is more than " GS_MAX_DISTANCE_TEXT
                             " units from the scene's origin on axis %c", what, pts[0], pts[1], pts[2], "xyz"[k]);
      return gi_proto_fail(e, 400, "%s[%zu]: out of range: (%g, %g, %g) is more than " GS_MAX_DISTANCE_TEXT
                           " units from the scene's origin on axis %c", what, i, pts[3 * i], pts[3 * i + 1],
                           pts[3 * i + 2], "xyz"[k]);
    }
  return 0;
}

/* A core error before any bake (quality, cell): its status and message. */
static enum MHD_Result fail_early(gs_http *h, gs_req *r, gi_result rc, const gi_error_info *e) {
  gi_proto_error pe;
  gi_proto_fail(&pe, gs_status_of(rc) == 500 ? 400 : gs_status_of(rc), "%s", e->msg[0] ? e->msg : gi_strerror(rc));
  gs_answer_error(&r->ans, &pe);
  return send_answer(h, r);
}

/* A 307 to url, with a short JSON body naming it. */
static enum MHD_Result redirect(gs_http *h, gs_req *r, const char *url, const char *cache_control) {
  answer_json(&r->ans, 307, json_pack("{s:s}", "location", url));
  snprintf(r->ans.location, sizeof r->ans.location, "%s", url);
  r->ans.cache_control = cache_control;
  return send_answer(h, r);
}

typedef struct {
  const char *etag;
  int match;
} inm_ctx;

static enum MHD_Result collect_inm(void *cls, enum MHD_ValueKind kind, const char *key, const char *value) {
  inm_ctx *c = cls;
  if (!strcasecmp(key, "If-None-Match") && gs_etag_matches(value, c->etag)) c->match = 1;
  return MHD_YES;
}

/* Whether an If-None-Match names etag. A list may span several field lines
 * (RFC 9110 5.3); libmicrohttpd's lookup gives only the first of them. */
static int if_none_match(struct MHD_Connection *conn, const char *etag) {
  inm_ctx c = {etag, 0};
  MHD_get_connection_values(conn, MHD_HEADER_KIND, collect_inm, &c);
  return c.match;
}

/* Lighting and cascades (canonical.c): a viewpoint URL redirects to its
 * cell's URL (or, with redirect=0, is answered as it); a cell URL with a
 * stale q redirects to the current one; a cell answer is immutable, with
 * a strong ETag, and If-None-Match naming it is a 304 without any work. */
static enum MHD_Result lighting(gs_http *h, gs_req *r, const query *q) {
  gs_service *svc = h->svc;
  const gi_proto_limits *lim = &svc->cfg->lim;
  gi_proto_error pe;
  int light = r->ep == GS_EP_LIGHTING, st;
  if (r->cell_url) st = light ? gi_proto_parse_cell_lighting(q->kv, q->n, lim, &r->bake, &pe)
                              : gi_proto_parse_cell_cascades(q->kv, q->n, lim, &r->bake, &pe);
  else st = light ? gi_proto_parse_lighting(q->kv, q->n, lim, &r->bake, &pe)
                  : gi_proto_parse_cascades(q->kv, q->n, lim, &r->bake, &pe);
  if (!st && r->cell_far[0])
    st = gi_proto_fail(&pe, 400, "cell: %s is too far from the scene to address", r->cell_far);
  if (st || (!r->cell_url && check_near(r->scene, r->bake.at, 1, "parameter 'at'", &pe))) {
    gs_answer_error(&r->ans, &pe);
    return send_answer(h, r);
  }
  /* Lightmaps are answered at the viewpoint, uncached, until they get cell
   * URLs too (the hook: canonical.c's header comment). */
  if (!r->cell_url && r->bake.kind == GI_PROTO_LIGHTMAP) return dispatch(h, r);
  gs_canon c;
  gi_error_info e = {0};
  gi_result rc = gs_canon_quality(svc, r->scene, &r->bake.quality, &c, &e);
  if (rc != GI_OK) return fail_early(h, r, rc, &e);
  char url[sizeof r->content_location];
  if (!r->cell_url && (rc = gi_cascade_anchor(r->scene->scene, r->bake.at, &c.resolved, r->cell, &e)) != GI_OK)
    return fail_early(h, r, rc, &e);
  gs_canon_url(r->scene, &c, r->cell, r->ep, &r->bake, url, sizeof url);
  if (!r->cell_url && r->bake.redirect) return redirect(h, r, url, "public, max-age=" GS_STR(GS_REDIRECT_MAX_AGE_S));
  /* Stale (another scene version or build) or forged: the current URL, never cached. */
  if (r->cell_url && strcmp(r->bake.q, c.q)) return redirect(h, r, url, NULL);
  if ((rc = gi_cascade_cell_centre(r->scene->scene, r->cell, &c.resolved, r->bake.at, &e)) != GI_OK)
    return fail_early(h, r, rc, &e);
  if (check_near(r->scene, r->bake.at, 1, "cell", &pe)) {
    gs_answer_error(&r->ans, &pe);
    return send_answer(h, r);
  }
  r->bake.cell = 1;
  gs_canon_etag(&c, r->cell, r->ep, &r->bake, r->etag, sizeof r->etag);
  /* A viewpoint URL's answer changes with the scene's version: revalidate it. */
  r->cache_control = r->cell_url ? "public, max-age=" GS_STR(GS_CELL_MAX_AGE_S) ", immutable" : "no-cache";
  if (!r->cell_url) snprintf(r->content_location, sizeof r->content_location, "%s", url);
  if (if_none_match(r->conn, r->etag)) {
    r->ans.status = 304;
    return send_answer(h, r);
  }
  return dispatch(h, r);
}

/* POST /v1/scenes/{id}/sessions and GET /v1/sessions/{sid}/lighting: the
 * same checks as lighting ('at' near the scene), then a worker. An unknown
 * session is a 404 here, without a worker. */
static enum MHD_Result sessions(gs_http *h, gs_req *r, const query *q) {
  gs_service *svc = h->svc;
  gi_proto_error pe;
  int st;
  if (r->ep == GS_EP_SESSIONS) {
    st = r->too_large ? gi_proto_fail(&pe, 413, "body: more than the server limit of %zu bytes",
                                      svc->cfg->lim.max_body_bytes)
                      : gi_proto_parse_session(q->kv, q->n, r->body, r->len, &svc->cfg->lim, &r->bake, &pe);
  } else {
    r->scene = gs_session_scene(svc, r->id);
    if (!r->scene) {
      gs_session_info(svc, r->id, &r->ans); /* its 404, worded once (session.c) */
      return send_answer(h, r);
    }
    st = gi_proto_parse_session_lighting(q->kv, q->n, &svc->cfg->lim, &r->bake, &pe);
  }
  const char *what = r->ep == GS_EP_SESSIONS && r->len ? "body: 'at'" : "parameter 'at'";
  if (st || (r->bake.has_at && check_near(r->scene, r->bake.at, 1, what, &pe))) {
    gs_answer_error(&r->ans, &pe);
    return send_answer(h, r);
  }
  return dispatch(h, r);
}

/* The whole request has arrived: validate and answer, or dispatch. */
static enum MHD_Result handle(gs_http *h, gs_req *r) {
  gs_service *svc = h->svc;
  gs_answer *a = &r->ans;
  query q = {0};
  if (read_query(r, &q, a)) return send_answer(h, r);
  gi_proto_error pe;
  if (r->ep == GS_EP_SCENE || r->ep == GS_EP_LIGHTING || r->ep == GS_EP_CASCADES || r->ep == GS_EP_PROBES ||
      r->ep == GS_EP_LIGHTMAP_UV || r->ep == GS_EP_SESSIONS) {
    r->scene = gs_catalog_find(svc->cat, r->id);
    if (!r->scene) {
      answer_fail(a, 404, "scene '%s' is not in the catalog (GET /v1/scenes lists them)", r->id);
      return send_answer(h, r);
    }
  }
  switch (r->ep) {
  case GS_EP_LIGHTING:
  case GS_EP_CASCADES: return lighting(h, r, &q);
  case GS_EP_LIGHTMAP_UV: {
    if (gi_proto_parse_lightmap_uv(q.kv, q.n, &svc->cfg->lim, &r->bake, &pe) ||
        check_near(r->scene, r->bake.at, 1, "parameter 'at'", &pe)) {
      gs_answer_error(a, &pe);
      return send_answer(h, r);
    }
    return dispatch(h, r);
  }
  case GS_EP_SESSIONS:
  case GS_EP_SESSION_LIGHTING: return sessions(h, r, &q);
  case GS_EP_PROBES:
    if (r->too_large) {
      gi_proto_fail(&pe, 413, "body: more than the server limit of %zu bytes", svc->cfg->lim.max_body_bytes);
    } else if (gi_proto_parse_none(q.kv, q.n, &pe) == 0 &&
               gi_proto_parse_probes(r->body, r->len, &svc->cfg->lim, &r->probes, &pe) == 0 &&
               check_near(r->scene, r->probes.points, r->probes.num_points, "body: points", &pe) == 0 &&
               (!r->probes.bake.has_at || check_near(r->scene, r->probes.bake.at, 1, "body: 'at'", &pe) == 0)) {
      return dispatch(h, r);
    }
    gs_answer_error(a, &pe);
    return send_answer(h, r);
  default:
    cheap_endpoint(svc, r, &q, a);
    return send_answer(h, r);
  }
}

/* Body bytes: kept up to the limit; the rest is read and dropped, then 413
 * (only when the length was not announced: an announced one is checked first). */
static enum MHD_Result take_upload(gs_http *h, gs_req *r, const char *upload, size_t *upload_size) {
  size_t lim = h->svc->cfg->lim.max_body_bytes;
  if (r->too_large || r->len + *upload_size > lim) {
    r->too_large = 1;
  } else {
    if (r->len + *upload_size + 1 > r->cap) {
      size_t cap = r->cap ? r->cap : 4096;
      while (cap < r->len + *upload_size + 1) cap *= 2;
      char *nb = realloc(r->body, cap);
      if (!nb) return MHD_NO;
      r->body = nb;
      r->cap = cap;
    }
    memcpy(r->body + r->len, upload, *upload_size);
    r->len += *upload_size;
  }
  *upload_size = 0;
  return MHD_YES;
}

/* on_uri's mark for a path with a NUL byte (%00) in it: libmicrohttpd
 * decodes it and the handler sees the path cut there (/v1/health%00zzz
 * answered as /v1/health, aliasing a cell URL's cached answer). */
static char nul_in_path;

static int path_has_nul(const char *uri) {
  for (const char *p = uri; *p && *p != '?'; p++)
    if (p[0] == '%' && p[1] == '0' && p[2] == '0') return 1;
  return 0;
}

static enum MHD_Result on_request(void *cls, struct MHD_Connection *conn, const char *url, const char *method,
                                  const char *version, const char *upload, size_t *upload_size, void **con_cls) {
  gs_http *h = cls;
  int nul_path = *con_cls == &nul_in_path;
  gs_req *r = nul_path ? NULL : *con_cls;
  if (!r) {
    r = calloc(1, sizeof *r);
    if (!r) return MHD_NO;
    r->h = h;
    r->conn = conn;
    r->ans.fd = -1;
    atomic_init(&r->refs, 1);
    r->w = (gs_waiter){.hold = hold_request, .wake = wake_request, .arg = r};
    r->t_start = gs_now_ms();
    r->deadline = r->t_start + h->svc->cfg->deadline_s * 1e3;
    snprintf(r->method, sizeof r->method, "%s", method);
    snprintf(r->path, sizeof r->path, "%s", url);
    *con_cls = r;
    if (nul_path) {
      r->ep = GS_EP_OTHER;
      answer_fail(&r->ans, 400, "%s", "the path holds a NUL byte (%00), which no path may hold");
      return send_answer(h, r);
    }
    /* Answered now, a refused request's body is never read. */
    if (check_headers(h, r, url)) return send_answer(h, r);
    return MHD_YES;
  }
  if (r->answered && !r->dispatched) {
    *upload_size = 0; /* refused from its headers: nothing more to read */
    return MHD_YES;
  }
  if (*upload_size) return take_upload(h, r, upload, upload_size);
  if (r->dispatched) {
    /* Resumed: the worker or the reaper left the answer. */
    pthread_mutex_lock(&h->mu);
    int done = r->done, gone = r->gone;
    pthread_mutex_unlock(&h->mu);
    if (gone) {
      char path[4 * sizeof r->path];
      gs_log_escape(r->path, path, sizeof path);
      fprintf(stderr, "gi-server: %s %s: the client left after %.1f ms\n", r->method, path, gs_now_ms() - r->t_start);
      return MHD_NO; /* nobody to answer: close */
    }
    return done ? send_answer(h, r) : MHD_YES;
  }
  conn_request_arrived(h, conn);
  return handle(h, r);
}

/* Before libmicrohttpd parses the query. Its parser keeps a record per
 * parameter in the connection's memory; when they do not fit it gives up
 * without answering, and the client would wait for the request deadline.
 * A query that could not fit (far beyond the 64 parameters the contract
 * allows, which always fit) gets the contract's 400 at once instead, and
 * the connection closes. */
static void *on_uri(void *cls, const char *uri, struct MHD_Connection *conn) {
  gs_http *h = cls;
  if (path_has_nul(uri)) return &nul_in_path;
  const char *q = strchr(uri, '?');
  if (!q) return NULL;
  size_t params = 1;
  for (const char *p = q; *p; p++) params += *p == '&';
  size_t len = strlen(uri);
  if (len + params * GS_PARAM_COST <= GS_CONNECTION_MEMORY / 2) return NULL;
  const union MHD_ConnectionInfo *ci = MHD_get_connection_info(conn, MHD_CONNECTION_INFO_CONNECTION_FD);
  if (ci) {
    /* libmicrohttpd cannot answer once its parser gives up: the contract's
     * 400 goes out by hand, then the connection closes. */
    char msg[160], head[160];
    snprintf(msg, sizeof msg, "the query does not fit the server's memory for one request (%zu bytes, %zu parameters; "
                              "at most 64 parameters are read)", len, params);
    gi_proto_error e;
    gi_proto_fail(&e, 400, "%s", msg);
    char *body = gi_proto_error_json(&e);
    size_t n = body ? strlen(body) : 0;
    int hl = snprintf(head, sizeof head, "HTTP/1.1 400 Bad Request\r\nContent-Type: application/json\r\n"
                                         "Content-Length: %zu\r\nConnection: close\r\n\r\n", n);
    if (send(ci->connect_fd, head, (size_t)hl, MSG_NOSIGNAL | MSG_DONTWAIT) == hl && n)
      (void)!send(ci->connect_fd, body, n, MSG_NOSIGNAL | MSG_DONTWAIT);
    free(body);
    shutdown(ci->connect_fd, SHUT_RDWR);
  }
  pthread_mutex_lock(&h->conn_mu);
  h->cuts++;
  pthread_mutex_unlock(&h->conn_mu);
  return NULL;
}

static void on_completed(void *cls, struct MHD_Connection *conn, void **con_cls,
                         enum MHD_RequestTerminationCode code) {
  gs_http *h = cls;
  conn_request_done(h, conn);
  gs_req *r = *con_cls;
  if (r == (void *)&nul_in_path) r = NULL; /* on_request never ran */
  if (!r) return;
  *con_cls = NULL;
  /* Closed before its answer went out: it no longer wants its bake. */
  if (code != MHD_REQUEST_TERMINATED_COMPLETED_OK) {
    gs_cache_leave(h->svc->cache, &r->w);
    if (r->cancel) gi_cancel_set(r->cancel);
  }
  req_release(r);
}

/* Says how many libmicrohttpd lines were not logged, once their second is
 * over. Called with log_mu held. */
static void mhd_log_note(gs_http *h, double now) {
  if (now - h->log_second < 1000) return;
  if (h->log_dropped)
    fprintf(stderr, "gi-server: libmicrohttpd: %lu more message(s) not logged (at most %d a second)\n",
            h->log_dropped, GS_MHD_LOG_PER_S);
  h->log_dropped = 0;
  h->log_lines = 0;
  h->log_second = now;
}

/* libmicrohttpd's messages can quote what a client sent: escaped like ours.
 * A client can make one per connection attempt ("Server reached connection
 * limit" for each one refused at accept): tens of thousands a second filled
 * the log by megabytes a second. At most GS_MHD_LOG_PER_S lines a second. */
static void mhd_log(void *cls, const char *fmt, va_list ap) {
  gs_http *h = cls;
  pthread_mutex_lock(&h->log_mu);
  mhd_log_note(h, gs_now_ms());
  int skip = h->log_lines >= GS_MHD_LOG_PER_S;
  if (skip) h->log_dropped++;
  else h->log_lines++;
  pthread_mutex_unlock(&h->log_mu);
  if (skip) return;
  char raw[512], esc[4 * sizeof raw];
  vsnprintf(raw, sizeof raw, fmt, ap);
  size_t n = strlen(raw);
  while (n && (raw[n - 1] == '\n' || raw[n - 1] == '\r')) raw[--n] = 0;
  gs_log_escape(raw, esc, sizeof esc);
  fprintf(stderr, "gi-server: libmicrohttpd: %s\n", esc);
}

/* libmicrohttpd aborts the process on an internal error it cannot handle;
 * its reason goes to the log first, so the abort is not a mystery. */
static void mhd_panic(void *cls, const char *file, unsigned int line, const char *reason) {
  (void)cls;
  fprintf(stderr, "gi-server: libmicrohttpd gave up at %s:%u: %s\n", file ? file : "?", line,
          reason ? reason : "(no reason)");
  abort();
}

/* At shutdown a new connection is closed as soon as it is accepted (see gs_http_stop). */
static enum MHD_Result on_accept(void *cls, const struct sockaddr *addr, socklen_t len) {
  (void)addr, (void)len;
  return atomic_load(&((gs_http *)cls)->closing) ? MHD_NO : MHD_YES;
}

/* Why the daemon could not listen at sa: libmicrohttpd says only that it
 * failed, so a socket of our own repeats the bind and keeps errno ("in
 * use, or not permitted" was also printed for an address this host does
 * not have). */
static void listen_failure(const gs_config *cfg, const struct sockaddr_in *sa, char *err, size_t errsize) {
  int fd = socket(AF_INET, SOCK_STREAM, 0), e = 0, one = 1;
  if (fd >= 0) {
    (void)setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (bind(fd, (const struct sockaddr *)sa, sizeof *sa) != 0) e = errno;
    else if (listen(fd, 1) != 0) e = errno;
    close(fd);
  } else {
    e = errno;
  }
  const char *why = e == EADDRNOTAVAIL ? "no interface of this host has that address"
                    : e == EADDRINUSE  ? "another process listens there"
                    : e == EACCES      ? "a port below 1024 needs privileges"
                    : e                ? strerror(e)
                                       : "libmicrohttpd refused it";
  snprintf(err, errsize, "cannot listen on %s:%d: %s", cfg->bind, cfg->port, why);
}

gs_http *gs_http_start(gs_service *svc, char *err, size_t errsize) {
  const gs_config *cfg = svc->cfg;
  struct sockaddr_in sa;
  memset(&sa, 0, sizeof sa);
  sa.sin_family = AF_INET;
  sa.sin_port = htons((uint16_t)cfg->port);
  if (inet_pton(AF_INET, cfg->bind, &sa.sin_addr) != 1) {
    snprintf(err, errsize, "%s: [server] bind: '%s' is not an IPv4 address", cfg->path, cfg->bind);
    return NULL;
  }
  gs_http *h = calloc(1, sizeof *h);
  if (!h) {
    snprintf(err, errsize, "out of memory");
    return NULL;
  }
  h->svc = svc;
  pthread_mutex_init(&h->mu, NULL);
  pthread_cond_init(&h->stop_cv, NULL);
  pthread_mutex_init(&h->conn_mu, NULL);
  pthread_mutex_init(&h->log_mu, NULL);
  atomic_init(&h->closing, 0);
  MHD_set_panic_func(mhd_panic, NULL);
  unsigned flags = MHD_USE_AUTO_INTERNAL_THREAD | MHD_ALLOW_SUSPEND_RESUME | MHD_USE_ERROR_LOG;
  h->d = MHD_start_daemon(flags, 0, on_accept, h, on_request, h, MHD_OPTION_EXTERNAL_LOGGER, mhd_log, h,
                          MHD_OPTION_SOCK_ADDR, (struct sockaddr *)&sa, MHD_OPTION_THREAD_POOL_SIZE, (unsigned)cfg->connection_threads,
                          MHD_OPTION_CONNECTION_LIMIT, GS_MAX_CONNECTIONS,
                          MHD_OPTION_PER_IP_CONNECTION_LIMIT, (unsigned)cfg->max_connections_per_ip,
                          MHD_OPTION_CONNECTION_TIMEOUT, GS_IDLE_TIMEOUT_S,
                          MHD_OPTION_CONNECTION_MEMORY_LIMIT, GS_CONNECTION_MEMORY,
                          MHD_OPTION_NOTIFY_COMPLETED, on_completed, h, MHD_OPTION_NOTIFY_CONNECTION, on_connection, h,
                          MHD_OPTION_URI_LOG_CALLBACK, on_uri, h, MHD_OPTION_END);
  if (!h->d) {
    listen_failure(cfg, &sa, err, errsize);
    pthread_mutex_destroy(&h->mu);
    pthread_mutex_destroy(&h->conn_mu);
    pthread_mutex_destroy(&h->log_mu);
    pthread_cond_destroy(&h->stop_cv);
    free(h);
    return NULL;
  }
  const union MHD_DaemonInfo *di = MHD_get_daemon_info(h->d, MHD_DAEMON_INFO_BIND_PORT);
  h->port = di ? di->port : cfg->port;
  if (pthread_create(&h->reaper, NULL, reaper_main, h) != 0) {
    MHD_stop_daemon(h->d);
    free(h);
    snprintf(err, errsize, "cannot start the deadline thread");
    return NULL;
  }
  return h;
}

int gs_http_port(const gs_http *h) { return h->port; }

void gs_http_stop(gs_http *h) {
  if (!h) return;
  /* No new connections; let suspended ones be answered (by their worker or
   * at their deadline), then stop. Not MHD_quiesce_daemon: with epoll and
   * a thread pool (0.9.75) its worker threads race it to take the listen
   * socket out of their epoll sets, and the loser aborts the process (a
   * rare SIGABRT at SIGTERM); and the socket it hands back may only be
   * closed after MHD_stop_daemon, which this once did first. Connections
   * accepted meanwhile are closed at once (on_accept); MHD_stop_daemon
   * closes the listen socket. */
  atomic_store(&h->closing, 1);
  for (;;) {
    pthread_mutex_lock(&h->mu);
    int busy = h->waiting != NULL;
    pthread_mutex_unlock(&h->mu);
    /* Then every answer out to its client: a request is done when its
     * connection waits for the next one (receiving). MHD_stop_daemon cut
     * a 15 MB panorama being sent at SIGTERM, and the client read a 200
     * with a short body while the server exited 0. A client that never
     * reads its answer is cut by the shutdown grace (exit status 3). */
    if (!busy) {
      pthread_mutex_lock(&h->conn_mu);
      for (gs_conn *c = h->conns; c && !busy; c = c->next) busy = !c->receiving && !c->cut;
      pthread_mutex_unlock(&h->conn_mu);
    }
    if (!busy) break;
    struct timespec ts = {0, 20 * 1000000L};
    nanosleep(&ts, NULL);
  }
  pthread_mutex_lock(&h->mu);
  h->stop = 1;
  pthread_cond_signal(&h->stop_cv);
  pthread_mutex_unlock(&h->mu);
  pthread_join(h->reaper, NULL);
  MHD_stop_daemon(h->d);
  pthread_mutex_destroy(&h->mu);
  pthread_mutex_destroy(&h->conn_mu);
  pthread_mutex_destroy(&h->log_mu);
  pthread_cond_destroy(&h->stop_cv);
  free(h);
}
