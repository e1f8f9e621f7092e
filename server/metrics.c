/* metrics.c: counters for /metrics in Prometheus text format 0.0.4.
 *
 * Counters are atomics, so recording never takes a lock on the request
 * path; a scrape reads them without stopping anyone (values may be a
 * request apart from each other, which Prometheus tolerates). */
#define _POSIX_C_SOURCE 200809L
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "server.h"
#include "gi_git_rev.h" /* GI_GIT_REV: generated at build time (cmake/git_rev.cmake) */

static const char *const ep_names[GS_EP_COUNT] = {"health", "scenes", "scene",      "lighting", "cascades",
                                                  "probes", "job",    "job_result", "metrics",  "lightmap_uv",
                                                  "sessions", "session", "session_lighting", "other"};
static const int codes[] = {200, 201, 202, 204, 304, 307, 400, 401, 404, 405, 409, 413, 500, 501, 503, 504};
#define NCODES (sizeof codes / sizeof codes[0])
static const double buckets[] = {0.001, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60};
#define NB (sizeof buckets / sizeof buckets[0])

typedef struct {
  atomic_ullong le[NB + 1]; /* last: +Inf */
  atomic_ullong sum_us;
} histogram;

struct gs_metrics {
  atomic_ullong requests[GS_EP_COUNT][NCODES + 1]; /* last: any other code */
  histogram req_seconds, bake_seconds, move_seconds;
  atomic_ullong moves, cycles, session_events[GS_SESSION_EVENT_COUNT];
  atomic_ullong cache[3], evictions, bakes, rejected, timeouts, cancelled, encode[3], encode_evictions;
  atomic_llong in_flight; /* bakes running now */
};

gs_metrics *gs_metrics_new(void) { return calloc(1, sizeof(gs_metrics)); }
void gs_metrics_free(gs_metrics *m) { free(m); }

static void observe(histogram *h, double s) {
  size_t i = 0;
  while (i < NB && s > buckets[i]) i++;
  atomic_fetch_add(&h->le[i], 1);
  atomic_fetch_add(&h->sum_us, (unsigned long long)(s * 1e6));
}

void gs_metrics_request(gs_metrics *m, gs_endpoint ep, int status, double seconds) {
  size_t c = NCODES;
  for (size_t i = 0; i < NCODES; i++)
    if (codes[i] == status) c = i;
  atomic_fetch_add(&m->requests[ep][c], 1);
  observe(&m->req_seconds, seconds);
}

void gs_metrics_bake(gs_metrics *m, double seconds) {
  atomic_fetch_add(&m->bakes, 1);
  observe(&m->bake_seconds, seconds);
}
void gs_metrics_bake_begin(gs_metrics *m) { atomic_fetch_add(&m->in_flight, 1); }
void gs_metrics_bake_end(gs_metrics *m, int cancelled) {
  atomic_fetch_sub(&m->in_flight, 1);
  if (cancelled) atomic_fetch_add(&m->cancelled, 1);
}
void gs_metrics_move_cancelled(gs_metrics *m) { atomic_fetch_add(&m->cancelled, 1); }
void gs_metrics_move(gs_metrics *m, double seconds, int cycle_closed) {
  atomic_fetch_add(&m->moves, 1);
  if (cycle_closed) atomic_fetch_add(&m->cycles, 1);
  observe(&m->move_seconds, seconds);
}
void gs_metrics_session(gs_metrics *m, gs_session_event ev) { atomic_fetch_add(&m->session_events[ev], 1); }
void gs_metrics_cache(gs_metrics *m, gs_cache_how how) { atomic_fetch_add(&m->cache[how], 1); }
void gs_metrics_eviction(gs_metrics *m) { atomic_fetch_add(&m->evictions, 1); }
void gs_metrics_rejected(gs_metrics *m) { atomic_fetch_add(&m->rejected, 1); }
void gs_metrics_timeout(gs_metrics *m) { atomic_fetch_add(&m->timeouts, 1); }
void gs_metrics_encode(gs_metrics *m, gs_cache_how how) { atomic_fetch_add(&m->encode[how], 1); }
void gs_metrics_encode_eviction(gs_metrics *m) { atomic_fetch_add(&m->encode_evictions, 1); }

typedef struct {
  char *buf;
  size_t len, cap;
} sbuf;

static void put(sbuf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void put(sbuf *b, const char *fmt, ...) {
  for (;;) {
    va_list ap;
    va_start(ap, fmt);
    int n = b->buf ? vsnprintf(b->buf + b->len, b->cap - b->len, fmt, ap) : -1;
    va_end(ap);
    if (n >= 0 && (size_t)n < b->cap - b->len) {
      b->len += (size_t)n;
      return;
    }
    size_t cap = b->cap ? 2 * b->cap : 8192;
    char *nb = realloc(b->buf, cap);
    if (!nb) return;
    b->buf = nb;
    b->cap = cap;
  }
}

static void put_hist(sbuf *b, const char *name, const char *help, histogram *h) {
  put(b, "# HELP %s %s\n# TYPE %s histogram\n", name, help, name);
  unsigned long long cum = 0;
  for (size_t i = 0; i < NB; i++) {
    cum += atomic_load(&h->le[i]);
    put(b, "%s_bucket{le=\"%g\"} %llu\n", name, buckets[i], cum);
  }
  cum += atomic_load(&h->le[NB]);
  put(b, "%s_bucket{le=\"+Inf\"} %llu\n%s_sum %.6f\n%s_count %llu\n", name, cum, name,
      (double)atomic_load(&h->sum_us) * 1e-6, name, cum);
}

static void put_counter(sbuf *b, const char *name, const char *help, unsigned long long v) {
  put(b, "# HELP %s %s\n# TYPE %s counter\n%s %llu\n", name, help, name, name, v);
}

static void put_gauge(sbuf *b, const char *name, const char *help, double v) {
  put(b, "# HELP %s %s\n# TYPE %s gauge\n%s %.17g\n", name, help, name, name, v);
}

char *gs_metrics_render(gs_metrics *m, const gs_gauges *g) {
  sbuf b = {0};
  put(&b, "# HELP gi_build_info Build of this server.\n# TYPE gi_build_info gauge\n"
          "gi_build_info{version=\"%s\",git=\"%s\"} 1\n", GI_VERSION, GI_GIT_REV);
  put(&b, "# HELP gi_requests_total HTTP requests answered, by endpoint and status.\n"
          "# TYPE gi_requests_total counter\n");
  for (int e = 0; e < GS_EP_COUNT; e++)
    for (size_t c = 0; c <= NCODES; c++) {
      unsigned long long v = atomic_load(&m->requests[e][c]);
      if (!v) continue;
      if (c < NCODES) put(&b, "gi_requests_total{endpoint=\"%s\",code=\"%d\"} %llu\n", ep_names[e], codes[c], v);
      else put(&b, "gi_requests_total{endpoint=\"%s\",code=\"other\"} %llu\n", ep_names[e], v);
    }
  put_hist(&b, "gi_request_duration_seconds", "Time from request to answer.", &m->req_seconds);
  put_hist(&b, "gi_bake_duration_seconds", "Time to bake one cascade (voxelize to bounce).", &m->bake_seconds);
  put_counter(&b, "gi_bakes_total", "Cascades baked.", atomic_load(&m->bakes));
  put_counter(&b, "gi_bakes_cancelled_total",
              "Bakes stopped because every request waiting for them left (deadline or hang-up), "
              "and session moves stopped at their deadline.",
              atomic_load(&m->cancelled));
  put_gauge(&b, "gi_bakes_in_flight", "Cascades (for requests, sessions and jobs) and lightmaps being baked now.",
            (double)atomic_load(&m->in_flight));
  put_counter(&b, "gi_cache_hits_total", "Requests answered from a cached cascade.", atomic_load(&m->cache[0]));
  put_counter(&b, "gi_cache_misses_total", "Requests that baked their cascade.", atomic_load(&m->cache[1]));
  put_counter(&b, "gi_cache_coalesced_total", "Requests that waited for a bake already running for their key.",
              atomic_load(&m->cache[2]));
  put_counter(&b, "gi_cache_evictions_total", "Cascades evicted to stay within the cache budget.",
              atomic_load(&m->evictions));
  put_counter(&b, "gi_encode_hits_total",
              "Answers the same for everyone (a cell's probe or panorama, a VDB) streamed from kept bytes.",
              atomic_load(&m->encode[GS_CACHE_HIT]));
  put_counter(&b, "gi_encode_misses_total", "Such answers gathered and encoded for the request (and kept).",
              atomic_load(&m->encode[GS_CACHE_MISS]));
  put_counter(&b, "gi_encode_coalesced_total",
              "Such answers that waited for another request's gather and encode of the same bytes.",
              atomic_load(&m->encode[GS_CACHE_COALESCED]));
  put_counter(&b, "gi_encode_evictions_total",
              "Kept answers evicted to stay within the cache budget (alone or with their cascade).",
              atomic_load(&m->encode_evictions));
  put_counter(&b, "gi_rejected_total", "Requests answered 503 (queue full or memory budget taken).",
              atomic_load(&m->rejected));
  put_counter(&b, "gi_timeouts_total", "Requests answered 504 at their deadline.", atomic_load(&m->timeouts));
  put_gauge(&b, "gi_cache_bytes", "Bytes held by cached cascades and kept answers.", (double)g->cache_bytes);
  put_gauge(&b, "gi_encoded_bytes", "Bytes of kept answers (part of gi_cache_bytes).", (double)g->answer_bytes);
  put_gauge(&b, "gi_encoded_answers", "Answers kept (or being encoded) in the cache.", (double)g->answers);
  put_gauge(&b, "gi_cache_budget_bytes", "The configured memory budget: cached, in-flight, held and sending bytes.",
            (double)g->cache_budget);
  put_gauge(&b, "gi_inflight_bytes", "Estimated bytes of the bakes running now (cache misses and jobs).",
            (double)g->inflight_bytes);
  put_gauge(&b, "gi_sending_bytes",
            "Bytes of encoded answers not kept in the cache (or evicted since) held until their clients have read "
            "them.",
            (double)g->sending_bytes);
  put_gauge(&b, "gi_cache_entries", "Cascades in the cache (baking or ready).", (double)g->cache_entries);
  put_gauge(&b, "gi_queue_depth", "Requests waiting for a bake worker.", (double)g->queue_depth);
  put_gauge(&b, "gi_queue_capacity", "Requests that may wait before 503.", (double)g->queue_capacity);
  put_gauge(&b, "gi_workers_busy", "Bake workers running a request.", (double)g->workers_busy);
  put(&b, "# HELP gi_jobs Probe jobs by state.\n# TYPE gi_jobs gauge\n");
  for (int i = 0; i < GI_JOB_STATE_COUNT; i++)
    put(&b, "gi_jobs{state=\"%s\"} %d\n", gi_proto_job_state_name((gi_proto_job_state)i), g->jobs[i]);
  put_hist(&b, "gi_session_move_duration_seconds", "Time of one session move (gi_cascade_move, before the gather).",
           &m->move_seconds);
  put_counter(&b, "gi_session_moves_total", "Session cascades moved.", atomic_load(&m->moves));
  put_counter(&b, "gi_session_cycles_total", "Session moves that closed the refresh cycle (equal to a cold bake).",
              atomic_load(&m->cycles));
  put_counter(&b, "gi_sessions_created_total", "Sessions opened.", atomic_load(&m->session_events[GS_SESSION_CREATED]));
  put_counter(&b, "gi_sessions_expired_total", "Sessions ended after session_ttl_s idle.",
              atomic_load(&m->session_events[GS_SESSION_EXPIRED]));
  put_counter(&b, "gi_sessions_deleted_total", "Sessions ended by DELETE.",
              atomic_load(&m->session_events[GS_SESSION_DELETED]));
  put_counter(&b, "gi_sessions_rejected_total", "Session creations answered 503 (max_sessions or memory budget).",
              atomic_load(&m->session_events[GS_SESSION_REJECTED]));
  put_gauge(&b, "gi_sessions_open", "Sessions open now.", (double)g->sessions_open);
  put_gauge(&b, "gi_session_bytes", "Bytes sessions hold in the memory budget (their cascades and move scratch).",
            (double)g->session_bytes);
  put_gauge(&b, "gi_scenes", "Scenes in the catalog.", (double)g->scenes);
  put_gauge(&b, "gi_uptime_seconds", "Seconds since start.", g->uptime_s);
  return b.buf;
}
