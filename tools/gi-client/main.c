/* gi-client: a thin command-line client for gi-server's HTTP API.
 *
 * Design: one libcurl easy handle, reused, so polls and the final download
 * share a connection. Each request decides where the body goes once the
 * status line is in: a 2xx answer streams into the output (stdout, or
 * OUT.tmp.<pid> that is renamed onto OUT only after the whole body arrived
 * and was flushed), anything else is kept in memory (capped) so the JSON
 * error {code, name, message} can be printed. A 202 from POST probes is
 * kept in memory too: it is the job to poll. Error bodies and job status are
 * decoded by the contract's own code (proto/answer.c). Nothing here knows
 * the server's limits; its 400 messages name the field. */
#define _POSIX_C_SOURCE 200809L
#include <curl/curl.h>
#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>
#include <unistd.h>
#include "client.h"
#include "gi_proto.h"

#define MAX_MEM_BODY (1 << 20) /* error and job bodies are small; refuse a runaway one */
#define POLL_MS 500

/* 202: a job to poll; ALL: a poll answer; DROP: a walk's step (counted, not kept);
 * JOB_ONLY: a 202 kept, any other 2xx refused (probes --no-wait without -o) */
enum { MEM_NONE = 0, MEM_202 = 1, MEM_ALL = GC_MEM_ALL, MEM_DROP = GC_MEM_DROP, MEM_JOB_ONLY = 4 };

/* --- output file: temp name, renamed on success ------------------------------ */

/* The temp path, for the signal handler: Ctrl-C during a download must not
 * leave OUT.tmp.<pid> behind. */
static char g_tmp_path[4200];
static volatile sig_atomic_t g_tmp_live;
/* While a probe job is polled, Ctrl-C only asks the loop to stop: the job
 * it started is then cancelled on the server (DELETE) before the exit,
 * as walk deletes its session; it kept running for nobody. */
static volatile sig_atomic_t g_polling, g_cancelling, g_stop;

static void on_signal(int sig) {
  if (g_polling || g_cancelling) {
    g_stop = 1;
    return;
  }
  if (g_tmp_live) unlink(g_tmp_path);
  signal(sig, SIG_DFL);
  raise(sig);
}

/* A poll in flight when Ctrl-C came ends at once (the server may hang). */
static int on_progress(void *ud, curl_off_t dt, curl_off_t dn, curl_off_t ut, curl_off_t un) {
  (void)ud, (void)dt, (void)dn, (void)ut, (void)un;
  return g_polling && g_stop;
}

/* --- one request --------------------------------------------------------------- */

typedef struct buf {
  char *p;
  size_t n, cap;
} buf;

static int buf_add(buf *b, const void *d, size_t n) {
  if (b->n + n + 1 > b->cap) {
    size_t nc = b->cap ? b->cap : 4096;
    while (nc < b->n + n + 1) nc *= 2;
    char *np = realloc(b->p, nc);
    if (!np) return -1;
    b->p = np;
    b->cap = nc;
  }
  memcpy(b->p + b->n, d, n);
  b->n += n;
  b->p[b->n] = '\0';
  return 0;
}

typedef struct answer {
  CURL *curl;
  const char *out;      /* file name, or NULL for stdout (text commands) */
  int mem_mode;         /* MEM_*: which 2xx bodies stay in memory instead of the sink */
  int decided;          /* 1 once the first body byte chose a sink */
  FILE *fp;             /* the 2xx sink */
  int fp_is_tmp;
  long status;
  size_t bytes;
  int last_nl;          /* the body so far ends with '\n' */
  buf mem;              /* non-2xx (or 202) body */
  int write_failed;     /* errno of a failed write, or -1 (too big), 0 = fine */
  char timing[1024], cache[64], retry_after[64], location[512], move[160];
} answer;

static void copy_header(char *dst, size_t cap, const char *v, size_t n) {
  while (n && (v[n - 1] == '\r' || v[n - 1] == '\n' || v[n - 1] == ' ')) n--;
  while (n && (*v == ' ' || *v == '\t')) v++, n--;
  if (n >= cap) n = cap - 1;
  memcpy(dst, v, n);
  dst[n] = '\0';
}

static size_t on_header(char *p, size_t size, size_t nmemb, void *ud) {
  answer *a = ud;
  size_t n = size * nmemb;
  /* A new status line (after "100 Continue", say) starts a new header set. */
  if (n >= 5 && !strncmp(p, "HTTP/", 5)) {
    a->timing[0] = a->cache[0] = a->retry_after[0] = a->location[0] = a->move[0] = '\0';
    return n;
  }
  const char *colon = memchr(p, ':', n);
  if (!colon) return n;
  size_t kn = (size_t)(colon - p), vn = n - kn - 1;
#define HDR(name, dst)                                                          \
  if (kn == sizeof(name) - 1 && !strncasecmp(p, name, kn)) copy_header(dst, sizeof dst, colon + 1, vn)
  HDR("Server-Timing", a->timing);
  HDR("X-GI-Cache", a->cache);
  HDR("Retry-After", a->retry_after);
  HDR("Location", a->location);
  HDR("X-GI-Move", a->move);
#undef HDR
  return n;
}

static int open_sink(answer *a) {
  if (!a->out) {
    a->fp = stdout;
    return 0;
  }
  snprintf(g_tmp_path, sizeof g_tmp_path, "%s.tmp.%ld", a->out, (long)getpid());
  g_tmp_live = 1;
  a->fp = fopen(g_tmp_path, "wb");
  if (!a->fp) {
    g_tmp_live = 0;
    a->write_failed = errno ? errno : EIO;
    return -1;
  }
  a->fp_is_tmp = 1;
  return 0;
}

static size_t on_body(char *p, size_t size, size_t nmemb, void *ud) {
  answer *a = ud;
  size_t n = size * nmemb;
  if (!a->decided) {
    curl_easy_getinfo(a->curl, CURLINFO_RESPONSE_CODE, &a->status);
    a->decided = 1;
    int keep202 = a->status == 202 && (a->mem_mode == MEM_202 || a->mem_mode == MEM_JOB_ONLY);
    int ok2xx = a->status >= 200 && a->status < 300 && a->mem_mode != MEM_ALL && a->mem_mode != MEM_DROP &&
                !keep202;
    if (ok2xx && a->mem_mode == MEM_JOB_ONLY) {
      a->write_failed = -2; /* no OUT for this answer: reported below */
      return 0;
    }
    if (ok2xx && open_sink(a)) return 0; /* aborts the transfer: reported below */
  }
  if (a->mem_mode == MEM_DROP && a->status >= 200 && a->status < 300) {
    /* Counted only. */
  } else if (a->fp) {
    if (fwrite(p, 1, n, a->fp) != n) {
      a->write_failed = errno ? errno : EIO;
      return 0;
    }
  } else {
    if (a->mem.n + n > MAX_MEM_BODY || buf_add(&a->mem, p, n)) {
      a->write_failed = -1;
      return 0;
    }
  }
  a->bytes += n;
  if (n) a->last_nl = p[n - 1] == '\n';
  return n;
}

static void drop_tmp(answer *a) {
  if (a->fp && a->fp_is_tmp) {
    fclose(a->fp);
    unlink(g_tmp_path);
    g_tmp_live = 0;
  }
  a->fp = NULL;
}

/* Prints "gi-client: HTTP <status> <name>: <message>" from a JSON error body,
 * or the start of a non-JSON body (a proxy's HTML page, say). */
static void print_http_error(const answer *a) {
  gi_proto_error e;
  if (a->mem.n && !gi_proto_error_parse(a->mem.p, a->mem.n, &e)) {
    fprintf(stderr, "gi-client: HTTP %ld %s: %s", a->status, e.name, e.message);
  } else {
    int n = 0;
    while (n < 200 && n < (int)a->mem.n && a->mem.p[n] != '\n' && a->mem.p[n] != '\r') n++;
    fprintf(stderr, "gi-client: HTTP %ld: %s%.*s", a->status, n ? "" : "(no error body)", n, a->mem.p ? a->mem.p : "");
  }
  if (a->retry_after[0]) fprintf(stderr, " (Retry-After: %s s)", a->retry_after);
  fputc('\n', stderr);
}

/* The whole answer is in OUT.tmp.<pid>: flushed and synced, then renamed,
 * so OUT is either the old file or the whole new one. */
static int commit_out(const gc_opts *o, answer *a, const char *out) {
  int bad = fflush(a->fp) != 0 || fsync(fileno(a->fp)) != 0;
  int e = errno;
  bad |= fclose(a->fp) != 0;
  a->fp = NULL;
  if (bad || rename(g_tmp_path, out) != 0) {
    if (!bad) e = errno;
    fprintf(stderr, "gi-client: cannot write '%s': %s\n", out, strerror(e));
    unlink(g_tmp_path);
    g_tmp_live = 0;
    return EXIT_RUN;
  }
  g_tmp_live = 0;
  if (!o->quiet) fprintf(stderr, "gi-client: wrote %s (%zu bytes)\n", out, a->bytes);
  return 0;
}

/* Runs one request. On success (2xx) returns 0 with the body in the sink
 * (committed to OUT for downloads) or, for a 202 kept in memory, in a->mem.
 * On failure prints why and returns EXIT_RUN. The caller frees a->mem.p. */
static int run_request(const gc_opts *o, CURL *c, const char *method, const char *url, const char *body,
                       size_t body_len, const char *out, int mem_mode, answer *a) {
  memset(a, 0, sizeof *a);
  a->curl = c;
  a->out = out;
  a->mem_mode = mem_mode;
  char err[CURL_ERROR_SIZE] = "";
  struct curl_slist *hdrs = NULL;
  char auth[4200];
  if (o->token) {
    snprintf(auth, sizeof auth, "Authorization: Bearer %s", o->token);
    hdrs = curl_slist_append(hdrs, auth);
  }
  if (body) {
    hdrs = curl_slist_append(hdrs, "Content-Type: application/json");
    hdrs = curl_slist_append(hdrs, "Expect:"); /* no 100-continue round trip */
  }
  curl_easy_reset(c);
  curl_easy_setopt(c, CURLOPT_URL, url);
  curl_easy_setopt(c, CURLOPT_ERRORBUFFER, err);
  curl_easy_setopt(c, CURLOPT_HTTPHEADER, hdrs);
  curl_easy_setopt(c, CURLOPT_HEADERFUNCTION, on_header);
  curl_easy_setopt(c, CURLOPT_HEADERDATA, a);
  curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, on_body);
  curl_easy_setopt(c, CURLOPT_WRITEDATA, a);
  curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(c, CURLOPT_XFERINFOFUNCTION, on_progress);
  curl_easy_setopt(c, CURLOPT_NOPROGRESS, 0L);
  /* A viewpoint URL answers 307 to its cell URL on the same server. */
  if (!body) curl_easy_setopt(c, CURLOPT_FOLLOWLOCATION, 1L);
  curl_easy_setopt(c, CURLOPT_CONNECTTIMEOUT_MS, 10000L);
  curl_easy_setopt(c, CURLOPT_USERAGENT, "gi-client/" GI_VERSION);
  if (o->timeout_ms) curl_easy_setopt(c, CURLOPT_TIMEOUT_MS, o->timeout_ms);
  if (body) {
    curl_easy_setopt(c, CURLOPT_POSTFIELDS, body);
    curl_easy_setopt(c, CURLOPT_POSTFIELDSIZE_LARGE, (curl_off_t)body_len);
  }
  /* GET unless there is a body (POST: curl follows from POSTFIELDS), or DELETE. */
  if (!strcmp(method, "DELETE")) curl_easy_setopt(c, CURLOPT_CUSTOMREQUEST, "DELETE");
  CURLcode cr = curl_easy_perform(c);
  curl_slist_free_all(hdrs);
  curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &a->status);

  if (!o->quiet) {
    if (a->timing[0]) fprintf(stderr, "Server-Timing: %s\n", a->timing);
    if (a->cache[0]) fprintf(stderr, "X-GI-Cache: %s\n", a->cache);
  }
  if (a->write_failed == -2) {
    fprintf(stderr, "gi-client: %s %s: the server answered at once (HTTP %ld, an EXR, not a job): give -o OUT to "
                    "keep it\n", method, url, a->status);
    return EXIT_RUN;
  }
  if (a->write_failed) {
    if (a->write_failed == -1)
      fprintf(stderr, "gi-client: %s %s: answer (HTTP %ld) longer than %d bytes\n", method, url, a->status,
              MAX_MEM_BODY);
    else
      fprintf(stderr, "gi-client: %s: cannot write '%s': %s\n", url, out ? g_tmp_path : "stdout",
              strerror(a->write_failed));
    drop_tmp(a);
    return EXIT_RUN;
  }
  if (cr == CURLE_ABORTED_BY_CALLBACK && g_stop) return EXIT_RUN; /* Ctrl-C: the caller says so */
  if (cr != CURLE_OK) {
    fprintf(stderr, "gi-client: %s %s: %s\n", method, url, err[0] ? err : curl_easy_strerror(cr));
    drop_tmp(a);
    return EXIT_RUN;
  }
  if (a->status < 200 || a->status >= 300) {
    print_http_error(a);
    drop_tmp(a);
    return EXIT_RUN;
  }
  if (mem_mode == MEM_ALL || mem_mode == MEM_DROP || (a->status == 202 && (mem_mode == MEM_202 ||
      mem_mode == MEM_JOB_ONLY)))
    return 0;
  if (!a->decided && open_sink(a)) { /* an empty 2xx body: still an (empty) answer */
    fprintf(stderr, "gi-client: cannot write '%s': %s\n", g_tmp_path, strerror(a->write_failed));
    return EXIT_RUN;
  }
  if (!a->fp_is_tmp) {
    /* The server's JSON has no final newline; a terminal or a pipe reads better with one.
     * Files (-o) keep the exact bytes. */
    if (a->bytes && !a->last_nl) fputc('\n', a->fp);
    if (fflush(a->fp)) {
      fprintf(stderr, "gi-client: cannot write stdout: %s\n", strerror(errno));
      return EXIT_RUN;
    }
    return 0;
  }
  return commit_out(o, a, out);
}

/* --- URLs and bodies --------------------------------------------------------- */

/* Shortest "%.*g" that reads back as the same double (finite input only). */
void gc_fmt_double(char *dst, size_t cap, double v) {
  for (int prec = 6; prec <= 17; prec++) {
    snprintf(dst, cap, "%.*g", prec, v);
    if (strtod(dst, NULL) == v) return;
  }
}

/* Appends s percent-encoded for a query value; commas stay readable. */
static int add_query_value(buf *b, const char *s) {
  for (const unsigned char *p = (const unsigned char *)s; *p; p++) {
    char t[4];
    int keep = (*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') || *p == '-' ||
               *p == '.' || *p == '_' || *p == '~' || *p == ',';
    if (keep) t[0] = (char)*p, t[1] = 0;
    else snprintf(t, sizeof t, "%%%02X", *p);
    if (buf_add(b, t, strlen(t))) return -1;
  }
  return 0;
}

static int add_param(buf *b, int *first, const char *key, const char *value) {
  int rc = buf_add(b, *first ? "?" : "&", 1) || buf_add(b, key, strlen(key)) || buf_add(b, "=", 1) ||
           add_query_value(b, value);
  *first = 0;
  return rc ? -1 : 0;
}

static void fmt_at(char *dst, size_t cap, const double at[3]) {
  char x[32], y[32], z[32];
  gc_fmt_double(x, sizeof x, at[0]);
  gc_fmt_double(y, sizeof y, at[1]);
  gc_fmt_double(z, sizeof z, at[2]);
  snprintf(dst, cap, "%s,%s,%s", x, y, z);
}

/* server + prefix + escaped id + suffix, then the command's query. */
static char *build_url(const gc_opts *o, CURL *c, const char *prefix, const char *id, const char *suffix) {
  buf b = {0};
  int first = 1, fail = buf_add(&b, o->server, strlen(o->server)) || buf_add(&b, prefix, strlen(prefix));
  if (id && !fail) {
    char *e = curl_easy_escape(c, id, 0); /* ids go in a path segment: '/' and '?' must not */
    fail = !e || buf_add(&b, e, strlen(e));
    curl_free(e);
  }
  if (suffix && !fail) fail = buf_add(&b, suffix, strlen(suffix));
  if (!fail && o->cmd == GC_WALK) {
    char at[100];
    fmt_at(at, sizeof at, o->steps[0].at);
    fail |= add_param(&b, &first, "at", at);
    if (o->quality) fail |= add_param(&b, &first, "quality", o->quality);
    for (int i = 0; i < o->num_sets; i++) fail |= add_param(&b, &first, o->sets[i].key, o->sets[i].value);
  }
  if (!fail && (o->cmd == GC_LIGHTING || o->cmd == GC_CASCADES)) {
    char at[100];
    fmt_at(at, sizeof at, o->at);
    fail |= add_param(&b, &first, "at", at);
    if (o->kind) fail |= add_param(&b, &first, "kind", o->kind);
    if (o->quality) fail |= add_param(&b, &first, "quality", o->quality);
    if (o->faces) fail |= add_param(&b, &first, "faces", "1");
    for (int i = 0; i < o->num_sets; i++) fail |= add_param(&b, &first, o->sets[i].key, o->sets[i].value);
  }
  if (fail) {
    free(b.p);
    fputs("gi-client: out of memory\n", stderr);
    return NULL;
  }
  return b.p;
}

int gc_request(const gc_opts *o, CURL *c, const char *method, const char *url, const char *body, size_t len,
               int mem_mode, gc_response *r) {
  answer a;
  int rc = run_request(o, c, method, url, body, len, NULL, mem_mode, &a);
  r->status = a.status;
  r->body = a.mem.p;
  r->body_len = a.mem.n;
  snprintf(r->move, sizeof r->move, "%s", a.move);
  return rc;
}

void gc_response_free(gc_response *r) {
  free(r->body);
  r->body = NULL;
}

char *gc_session_url(const gc_opts *o, CURL *c) { return build_url(o, c, "/v1/scenes/", o->id, "/sessions"); }

char *gc_step_url(const gc_opts *o, CURL *c, const char *sid, const double at[3]) {
  buf b = {0};
  int first = 1;
  char v[100];
  fmt_at(v, sizeof v, at);
  char *e = curl_easy_escape(c, sid, 0); /* a path segment, as build_url's ids */
  int fail = !e || buf_add(&b, o->server, strlen(o->server)) || buf_add(&b, "/v1/sessions/", 13) ||
             buf_add(&b, e, strlen(e)) || buf_add(&b, "/lighting", 9) || add_param(&b, &first, "at", v);
  curl_free(e);
  if (!fail && o->kind) fail = add_param(&b, &first, "kind", o->kind);
  if (fail) {
    free(b.p);
    fputs("gi-client: out of memory\n", stderr);
    return NULL;
  }
  return b.p;
}

/* The POST probes body: {"points":[[x,y,z],..],"at":[..],"quality":..,"half":..,"ao":..}.
 * Written by hand: a million points as jansson objects would cost ~150 MB. */
static char *probes_body(const gc_opts *o, size_t *len) {
  buf b = {0};
  char n[100];
  int fail = buf_add(&b, "{\"points\":[", 11);
  for (size_t i = 0; i < o->num_points && !fail; i++) {
    char x[32], y[32], z[32];
    gc_fmt_double(x, sizeof x, o->points[3 * i]);
    gc_fmt_double(y, sizeof y, o->points[3 * i + 1]);
    gc_fmt_double(z, sizeof z, o->points[3 * i + 2]);
    int k = snprintf(n, sizeof n, "%s[%s,%s,%s]", i ? "," : "", x, y, z);
    fail = buf_add(&b, n, (size_t)k);
  }
  fail |= buf_add(&b, "]", 1);
  if (o->have_at) {
    char at[100];
    fmt_at(at, sizeof at, o->at);
    int k = snprintf(n, sizeof n, ",\"at\":[%s]", at);
    fail |= buf_add(&b, n, (size_t)k);
  }
  if (o->quality && !o->num_sets) {
    int k = snprintf(n, sizeof n, ",\"quality\":\"%s\"", o->quality);
    fail |= buf_add(&b, n, (size_t)k);
  } else if (o->num_sets) {
    /* Knobs as an object; a preset goes in first as "preset" (the knobs override it). */
    fail |= buf_add(&b, ",\"quality\":{", 12);
    if (o->quality) {
      int k = snprintf(n, sizeof n, "\"preset\":\"%s\"%s", o->quality, ",");
      fail |= buf_add(&b, n, (size_t)k);
    }
    for (int i = 0; i < o->num_sets; i++) {
      /* Keys and values were checked by args.c: plain words and numbers. */
      if (o->sets[i].is_text) {
        int k = snprintf(n, sizeof n, "%s\"%s\":\"", i ? "," : "", o->sets[i].key);
        fail |= buf_add(&b, n, (size_t)k) || buf_add(&b, o->sets[i].value, strlen(o->sets[i].value)) ||
                buf_add(&b, "\"", 1);
        continue;
      }
      double v = strtod(o->sets[i].value, NULL);
      char num[32];
      if (o->sets[i].is_int) snprintf(num, sizeof num, "%lld", strtoll(o->sets[i].value, NULL, 10));
      else gc_fmt_double(num, sizeof num, v);
      int k = snprintf(n, sizeof n, "%s\"%s\":%s", i ? "," : "", o->sets[i].key, num);
      fail |= buf_add(&b, n, (size_t)k);
    }
    fail |= buf_add(&b, "}", 1);
  }
  if (o->half) fail |= buf_add(&b, ",\"half\":true", 12);
  if (o->ao) fail |= buf_add(&b, ",\"ao\":true", 10);
  fail |= buf_add(&b, "}", 1);
  if (fail) {
    free(b.p);
    fputs("gi-client: out of memory building the request body\n", stderr);
    return NULL;
  }
  *len = b.n;
  return b.p;
}

/* --- jobs ---------------------------------------------------------------------- */

static double now_s(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void sleep_ms(long ms) {
  struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
  while (nanosleep(&ts, &ts) && errno == EINTR && !g_stop) {}
}

/* Ctrl-C while polling: DELETE the job, then exit 130. More signals (a
 * second Ctrl-C, `timeout -s INT` signalling the process and then its
 * group) do not stop it; at most CANCEL_MS bounds it. */
#define CANCEL_MS 10000L
static int cancel_job(const gc_opts *o, CURL *c, const char *id, const char *url) {
  g_cancelling = 1;
  g_polling = 0; /* this request is not aborted */
  gc_opts q = *o;
  q.quiet = 1;
  if (!q.timeout_ms || q.timeout_ms > CANCEL_MS) q.timeout_ms = CANCEL_MS;
  answer a;
  int rc = run_request(&q, c, "DELETE", url, NULL, 0, NULL, MEM_ALL, &a);
  free(a.mem.p);
  if (rc) fprintf(stderr, "gi-client: job %s: interrupted, and it could not be cancelled (above)\n", id);
  else fprintf(stderr, "gi-client: job %s: interrupted; cancelled it on the server\n", id);
  return 130;
}

/* Progress on stderr: a bar redrawn in place on a terminal, else one line
 * each time another 10% is done (logs stay short). */
typedef struct progress {
  int tty, quiet, last_decile, drawn;
} progress;

static void progress_show(progress *p, const char *id, const char *state, double frac, long long done,
                          long long total, double elapsed) {
  if (p->quiet) return;
  if (!(frac >= 0)) frac = 0; /* NaN too */
  if (frac > 1) frac = 1;
  if (p->tty) {
    char bar[31];
    int fill = (int)(frac * 30 + 0.5);
    for (int i = 0; i < 30; i++) bar[i] = i < fill ? '#' : '-';
    bar[30] = '\0';
    fprintf(stderr, "\rjob %s [%s] %5.1f%%  %lld/%lld probes  %-7s %6.1f s ", id, bar, 100 * frac, (long long)done,
            (long long)total, state, elapsed);
    p->drawn = 1;
  } else {
    int dec = (int)(frac * 10 + 1e-9);
    if (dec > p->last_decile) {
      fprintf(stderr, "gi-client: job %s: %d%% (%lld/%lld probes, %.1f s)\n", id, dec * 10, (long long)done,
              (long long)total, elapsed);
      p->last_decile = dec;
    }
  }
  fflush(stderr);
}

static void progress_end(progress *p) {
  if (p->drawn) fputc('\n', stderr);
  p->drawn = 0;
}

/* Polls GET /v1/jobs/{id} until done or failed, then downloads the result. */
static int wait_job(const gc_opts *o, CURL *c, const char *id) {
  char *url = build_url(o, c, "/v1/jobs/", id, NULL);
  char *result_url = build_url(o, c, "/v1/jobs/", id, "/result");
  int rc = EXIT_RUN;
  progress pg = {isatty(STDERR_FILENO), o->quiet, 0, 0};
  double t0 = now_s();
  if (!url || !result_url) goto done;
  if (!o->quiet) fprintf(stderr, "gi-client: job %s: waiting (%s)\n", id, url);
  g_polling = 1;
  for (;;) {
    answer a;
    gc_opts q = *o;
    q.quiet = 1; /* no header lines for every poll */
    memset(&a, 0, sizeof a);
    int bad = g_stop ? EXIT_RUN : run_request(&q, c, "GET", url, NULL, 0, NULL, MEM_ALL, &a);
    if (g_stop) {
      progress_end(&pg);
      free(a.mem.p);
      rc = cancel_job(o, c, id, url);
      goto done;
    }
    if (bad) {
      progress_end(&pg);
      free(a.mem.p);
      goto done;
    }
    gi_proto_job j;
    bad = gi_proto_job_parse(a.mem.p ? a.mem.p : "", a.mem.n, &j);
    free(a.mem.p);
    if (bad) {
      progress_end(&pg);
      fprintf(stderr, "gi-client: GET %s: expected a job status (id, state, probes, probes_done, ...)\n", url);
      goto done;
    }
    const char *state = gi_proto_job_state_name(j.state);
    double frac = j.probes ? (double)j.probes_done / (double)j.probes : 0;
    if (j.state == GI_JOB_FAILED || j.state == GI_JOB_CANCELLED) {
      progress_end(&pg);
      if (j.state == GI_JOB_CANCELLED) fprintf(stderr, "gi-client: job %s was cancelled\n", id);
      else fprintf(stderr, "gi-client: job %s failed: %s: %s\n", id, j.error.name, j.error.message);
      goto done;
    }
    progress_show(&pg, id, state, frac, (long long)j.probes_done, (long long)j.probes, now_s() - t0);
    if (j.state == GI_JOB_DONE) {
      progress_end(&pg);
      break;
    }
    sleep_ms(POLL_MS);
  }
  g_polling = 0;
  answer a;
  rc = run_request(o, c, "GET", result_url, NULL, 0, o->out, MEM_NONE, &a);
  free(a.mem.p);
done:
  g_polling = 0;
  free(url);
  free(result_url);
  return rc;
}

/* --- commands ------------------------------------------------------------------ */

static int run(const gc_opts *o, CURL *c) {
  answer a;
  char *url = NULL, *body = NULL;
  int rc = EXIT_RUN;
  switch (o->cmd) {
  case GC_HEALTH: url = build_url(o, c, "/v1/health", NULL, NULL); break;
  case GC_SCENES: url = build_url(o, c, "/v1/scenes", NULL, NULL); break;
  case GC_SCENE: url = build_url(o, c, "/v1/scenes/", o->id, NULL); break;
  case GC_METRICS: url = build_url(o, c, "/metrics", NULL, NULL); break;
  case GC_JOB: url = build_url(o, c, "/v1/jobs/", o->id, NULL); break;
  /* The cell URL when the server publishes its grid (cacheable, no 307). */
  case GC_LIGHTING:
    if (!(url = gc_cell_url(o))) url = build_url(o, c, "/v1/scenes/", o->id, "/lighting");
    break;
  case GC_CASCADES:
    if (!(url = gc_cell_url(o))) url = build_url(o, c, "/v1/scenes/", o->id, "/cascades.vdb");
    break;
  case GC_PROBES: url = build_url(o, c, "/v1/scenes/", o->id, "/probes"); break;
  case GC_WALK: return gc_walk(o, c);
  }
  if (!url) return EXIT_RUN;
  if (o->cmd != GC_PROBES) {
    rc = run_request(o, c, "GET", url, NULL, 0, o->out, MEM_NONE, &a);
    free(a.mem.p);
    free(url);
    return rc;
  }
  size_t len = 0;
  if (!(body = probes_body(o, &len))) goto out;
  int mode = o->no_wait && !o->out ? MEM_JOB_ONLY : MEM_202;
  if ((rc = run_request(o, c, "POST", url, body, len, o->out, mode, &a))) goto out_a;
  if (a.status != 202) goto out_a; /* 200: the EXR is already in place */
  rc = EXIT_RUN;
  json_error_t je;
  json_t *j = json_loadb(a.mem.p ? a.mem.p : "", a.mem.n, 0, &je);
  const char *job = j ? json_string_value(json_object_get(j, "job")) : NULL;
  if (!job || !*job) {
    fprintf(stderr, "gi-client: POST %s: a 202 answer without a \"job\" id\n", url);
  } else if (o->no_wait) {
    fwrite(a.mem.p, 1, a.mem.n, stdout);
    if (a.mem.n && a.mem.p[a.mem.n - 1] != '\n') putchar('\n');
    rc = fflush(stdout) ? EXIT_RUN : 0;
  } else {
    json_int_t n = json_integer_value(json_object_get(j, "probes"));
    if (!o->quiet) fprintf(stderr, "gi-client: %lld probes became job %s\n", (long long)n, job);
    rc = wait_job(o, c, job);
  }
  json_decref(j);
out_a:
  free(a.mem.p);
out:
  free(body);
  free(url);
  return rc;
}

int main(int argc, char **argv) {
  gc_opts o;
  int rc = gc_parse(argc, argv, &o);
  static ta_ctx fin = TA_CTX("gi-client");
  if (rc) {
    gc_opts_fini(&o);
    ta_outputs_finish(&fin, 0);
    return rc < 0 ? 0 : rc;
  }
  /* sigaction, not signal(): this signal() resets the handler after one
   * signal, and `timeout -s INT` sends two (to the process, then to its
   * group), so a polled job's Ctrl-C died before its DELETE. */
  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, NULL);
  sigaction(SIGTERM, &sa, NULL);
  signal(SIGPIPE, SIG_IGN); /* a closed stdout is a write error, reported */
  if (curl_global_init(CURL_GLOBAL_DEFAULT)) {
    fputs("gi-client: cannot initialise libcurl\n", stderr);
    gc_opts_fini(&o);
    return EXIT_RUN;
  }
  CURL *c = curl_easy_init();
  if (!c) {
    fputs("gi-client: cannot initialise libcurl\n", stderr);
    rc = EXIT_RUN;
  } else {
    rc = run(&o, c);
    curl_easy_cleanup(c);
  }
  curl_global_cleanup();
  gc_opts_fini(&o);
  int frc = ta_outputs_finish(&fin, rc == 0);
  return rc ? rc : frc;
}
