/* walk.c: gi-client walk: replays a path against a server session.
 *
 * Opens a session at the path's first point (POST /v1/scenes/ID/sessions
 * with the quality knobs), asks GET /v1/sessions/SID/lighting at every
 * point, paced by the path's t column (or --rate HZ; 0 = as fast as the
 * server answers), and deletes the session at the end, also after Ctrl-C.
 * Per step it measures the client's latency (request sent to answer read)
 * and reads X-GI-Move (a move that crossed a cell, one that closed the
 * refresh cycle). The summary: steps, crossings, cycles, errors and the
 * latency's p50/p90/p99/max, as text or (--json) one JSON object.
 * A session the server ended (404: idle past its session_ttl_s, deleted)
 * is replaced by a new one at the step that found it gone, said on stderr
 * and counted as reopened; that step is then asked again, once. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "client.h"
#include "gi_proto.h"

static volatile sig_atomic_t g_walk_stop;
static void on_walk_signal(int sig) {
  (void)sig;
  g_walk_stop = 1;
}

static double mono_s(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* Sleeps until monotonic time t (seconds); returns early on a signal. In
 * spans of at most a quarter second: a step due 1e308 s on converted to
 * time_t out of range and was not waited for at all, and a Ctrl-C that
 * lands just before a span starts (or on another thread, not interrupting
 * this one) held the walk for the whole span: an hour, once in a CI run. */
#define SLEEP_SPAN_S 0.25
static void sleep_until(double t) {
  for (;;) {
    double d = t - mono_s();
    if (!(d > 0) || g_walk_stop) return;
    if (d > SLEEP_SPAN_S) d = SLEEP_SPAN_S;
    struct timespec ts = {(time_t)d, (long)((d - floor(d)) * 1e9)};
    if (nanosleep(&ts, NULL) != 0) return;
  }
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

/* Nearest-rank percentile of sorted v[0..n). */
static double pct(const double *v, size_t n, double p) {
  if (!n) return 0;
  size_t r = (size_t)ceil(p / 100.0 * (double)n);
  return v[r ? r - 1 : 0];
}

/* A field of X-GI-Move ("n=3 cycle=0 crossed=1 ..."): its value, or 0. */
static long move_field(const char *h, const char *key) {
  char pat[32];
  snprintf(pat, sizeof pat, "%s=", key);
  for (const char *p = h; (p = strstr(p, pat)); p++)
    if (p == h || p[-1] == ' ') return strtol(p + strlen(pat), NULL, 10);
  return 0;
}

/* What the walk counted. */
typedef struct walk_stats {
  size_t steps, ok, crossed, cycles, errors, reopened;
  double *lat_ms; /* per successful step */
  double elapsed_s;
  int interrupted;
} walk_stats;

static void print_summary(const gc_opts *o, const char *sid, walk_stats *w) {
  qsort(w->lat_ms, w->ok, sizeof *w->lat_ms, cmp_double);
  double sum = 0;
  for (size_t i = 0; i < w->ok; i++) sum += w->lat_ms[i];
  double mean = w->ok ? sum / (double)w->ok : 0, p50 = pct(w->lat_ms, w->ok, 50), p90 = pct(w->lat_ms, w->ok, 90),
         p99 = pct(w->lat_ms, w->ok, 99), mx = w->ok ? w->lat_ms[w->ok - 1] : 0;
  if (o->json) {
    json_t *j = json_pack("{s:s, s:s, s:I, s:I, s:I, s:I, s:I, s:b, s:f, s:{s:f, s:f, s:f, s:f, s:f}}", "scene",
                          o->id, "session", sid, "steps", (json_int_t)w->steps, "crossed", (json_int_t)w->crossed,
                          "cycles", (json_int_t)w->cycles, "errors", (json_int_t)w->errors, "reopened",
                          (json_int_t)w->reopened, "interrupted", w->interrupted, "elapsed_s", w->elapsed_s,
                          "latency_ms", "p50", p50, "p90", p90, "p99", p99, "max", mx, "mean", mean);
    char *s = j ? json_dumps(j, JSON_COMPACT | JSON_REAL_PRECISION(6)) : NULL;
    if (s) puts(s);
    free(s);
    json_decref(j);
  } else {
    char reopened[64] = "";
    if (w->reopened) snprintf(reopened, sizeof reopened, ", %zu sessions reopened", w->reopened);
    printf("walk %s: %zu steps, %zu crossed a cell, %zu cycles closed, %zu errors%s%s, %.2f s\n", o->id, w->steps,
           w->crossed, w->cycles, w->errors, reopened, w->interrupted ? " (interrupted)" : "", w->elapsed_s);
    printf("latency ms: p50 %.2f  p90 %.2f  p99 %.2f  max %.2f  mean %.2f\n", p50, p90, p99, mx, mean);
  }
  fflush(stdout);
}

/* POST .../sessions?quality..&at=the step's point: the session id into sid. */
static int open_session(const gc_opts *o, CURL *c, const gc_step *at, char sid[40]) {
  gc_opts here = *o;
  gc_step first = *at;
  here.steps = &first; /* gc_session_url starts the session at steps[0] */
  char *url = gc_session_url(&here, c);
  if (!url) return EXIT_RUN;
  gc_response a;
  int rc = gc_request(o, c, "POST", url, "", 0, GC_MEM_ALL, &a);
  gi_proto_session s;
  if (!rc && gi_proto_session_parse(a.body ? a.body : "", a.body_len, &s)) {
    fprintf(stderr, "gi-client: POST %s: the answer is not a session\n", url);
    rc = EXIT_RUN;
  }
  if (!rc) snprintf(sid, 40, "%s", s.id);
  gc_response_free(&a);
  free(url);
  return rc;
}

/* One step's request, counted into w when it succeeds. Returns 0, the
 * HTTP status of a failed answer, 1 without one (network), -1 out of memory. */
static long ask_step(const gc_opts *o, CURL *c, const char *sid, const gc_step *st, walk_stats *w) {
  gc_opts quiet = *o;
  quiet.quiet = 1; /* one line per step would drown the summary */
  char *url = gc_step_url(o, c, sid, st->at);
  if (!url) return -1;
  double ts = mono_s();
  gc_response a;
  int rc = gc_request(&quiet, c, "GET", url, NULL, 0, GC_MEM_DROP, &a);
  double ms = (mono_s() - ts) * 1e3;
  long status = rc ? (a.status ? a.status : 1) : 0;
  if (!rc) {
    w->lat_ms[w->ok++] = ms;
    w->crossed += move_field(a.move, "crossed") == 1;
    w->cycles += move_field(a.move, "cycle") == 1;
  }
  gc_response_free(&a);
  free(url);
  return status;
}

/* The server ended the session (idle past its TTL, or deleted): a new one
 * at this step, so a path with a long pause goes on. 0, or -1 without one. */
static int reopen(const gc_opts *o, CURL *c, const gc_step *st, char sid[40], walk_stats *w) {
  char x[32], y[32], z[32];
  gc_fmt_double(x, sizeof x, st->at[0]);
  gc_fmt_double(y, sizeof y, st->at[1]);
  gc_fmt_double(z, sizeof z, st->at[2]);
  fprintf(stderr, "gi-client: walk: session %s has ended (HTTP 404); opening a new one at %s,%s,%s\n", sid, x, y, z);
  if (open_session(o, c, st, sid)) return -1;
  w->reopened++;
  return 0;
}

/* Runs the steps, counting into w. A 404 (the session ended) opens a new
 * session and asks the step again; one that cannot be replaced, or a
 * second 404, stops the walk. sid is the session in use. */
static void walk_steps(const gc_opts *o, CURL *c, char sid[40], walk_stats *w) {
  double t0 = mono_s();
  for (size_t i = 0; i < o->num_steps && !g_walk_stop; i++) {
    double due = o->rate > 0 ? t0 + (double)i / o->rate
                 : o->rate == 0 ? 0
                                : t0 + (o->steps[i].t - o->steps[0].t);
    sleep_until(due);
    if (g_walk_stop) break;
    w->steps++;
    long st = ask_step(o, c, sid, &o->steps[i], w);
    int gone = st == 404;
    if (gone && reopen(o, c, &o->steps[i], sid, w) == 0) gone = (st = ask_step(o, c, sid, &o->steps[i], w)) == 404;
    if (st == 0) continue;
    w->errors++;
    if (gone || st == -1) break; /* no session to move, or no memory */
  }
  w->elapsed_s = mono_s() - t0;
  w->interrupted = g_walk_stop != 0;
}

int gc_walk(const gc_opts *o, CURL *c) {
  char sid[40];
  struct sigaction sa = {0}, old_int, old_term;
  sa.sa_handler = on_walk_signal;
  sigaction(SIGINT, &sa, &old_int);
  sigaction(SIGTERM, &sa, &old_term);
  int rc = open_session(o, c, &o->steps[0], sid);
  if (rc) return rc;
  walk_stats w = {0};
  w.lat_ms = malloc((o->num_steps ? o->num_steps : 1) * sizeof *w.lat_ms);
  if (w.lat_ms) walk_steps(o, c, sid, &w);
  else w.errors = 1;
  /* The session holds server memory: end it, also after Ctrl-C. */
  char url[4300];
  snprintf(url, sizeof url, "%s/v1/sessions/%s", o->server, sid);
  gc_response a;
  gc_opts quiet = *o;
  quiet.quiet = 1;
  int del = gc_request(&quiet, c, "DELETE", url, NULL, 0, GC_MEM_ALL, &a);
  gc_response_free(&a);
  print_summary(o, sid, &w);
  free(w.lat_ms);
  sigaction(SIGINT, &old_int, NULL);
  sigaction(SIGTERM, &old_term, NULL);
  if (w.interrupted) return 130;
  return w.errors || del ? EXIT_RUN : 0;
}
