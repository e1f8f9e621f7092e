/* test_sessions.c: server sessions (issue 12 item 2) over HTTP.
 *
 * One gi-server (city extent 300, two sessions at most, a 2 s idle TTL):
 *   - a session walks, then stands still until its refresh cycle closes; its
 *     probe then equals the core's cold bake at that point (half-float
 *     rounding of texels aside), and every answer carries the move's
 *     Server-Timing stages and X-GI-Move;
 *   - bad input: unknown session 404, non-finite and far 'at' 400 naming it,
 *     kind=lightmap 400, quality knobs on a session 400, a panorama taller
 *     than 8192 400, HEAD 405 (Allow: GET) without moving, DELETE then 404;
 *   - a client hanging up during a far move stops it and keeps its session:
 *     the next move re-bakes the cascade there and moves on;
 *   - limits: a third session is a 503 with Retry-After; an idle one
 *     expires after the TTL (404, gi_sessions_expired_total);
 *   - two clients hammering one session: every request answered, move
 *     numbers 1..N each exactly once (serialised), and the cascade after
 *     it is still a cold bake's once the cycle closes (nothing torn).
 * Two more servers: a 13 MiB budget (a session evicts a cached cascade to
 * fit; a second one does not fit: 503) and a 0.3 s deadline (a session
 * whose bake outlives it is a 504, its bake cancelled, no session left).
 * A 0.5 s deadline: a session's far move past it is the deadline's 504,
 * stopped; the session's next moves re-bake it and answer a cold bake. */
#define _POSIX_C_SOURCE 200809L
#include "server_util.h"
#include "test_util.h"
#include <curl/curl.h>
#include <jansson.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>
#include "gi/gi.h"

#define TOKEN SU_TOKEN
#define GET(path) su_http(&S, NULL, path, NULL, TOKEN)
/* Sessions' idle TTL in the test server, seconds. */
#define TTL_S 2
#define STR_(x) #x
#define STR(x) STR_(x)
/* A session at quality=low has 5 levels: standing still, the cycle closes
 * after 2^4 calls at a held anchor (gi_cascade_refresh_period). */
#define CYCLE 16
/* Relative difference allowed against a cold bake: texels stored as half
 * floats at another scale round differently (gi_move.h). */
#define COLD_TOL 1e-3
/* Requests each of the two hammering clients sends. */
#define HAMMER_N 12

static su_server S, S_budget, S_deadline;

static const gi_quality Q_LOW = {.levels = 5, .res = 16, .cones = 6, .bounces = 1, .light_samples = 8,
                                 .probe_samples = 64, .threads = 2};

static int setup(void **state) {
  (void)state;
  curl_global_init(CURL_GLOBAL_DEFAULT);
  return su_start(&S, "sessions",
                  "[server]\nbind = 127.0.0.1\nport = 0\nconnection_threads = 4\nbake_threads = 2\nworkers = 2\n"
                  "queue = 32\ntmp_dir = .\ntoken_file = token.txt\n"
                  "[limits]\nmax_sessions = 2\nsession_ttl_s = " STR(TTL_S) "\n"
                  "[scene city]\nsource = city\nextent = 300\n");
}

static int teardown(void **state) {
  (void)state;
  int st = su_stop(&S);
  if (S_budget.pid) st |= su_stop(&S_budget);
  if (S_deadline.pid) st |= su_stop(&S_deadline);
  curl_global_cleanup();
  return st == 0 ? 0 : -1;
}

/* POST .../sessions; returns the new id (static buffer). */
static const char *open_session(const char *query, const char *body) {
  static char id[64];
  char path[256];
  snprintf(path, sizeof path, "/v1/scenes/city/sessions%s", query);
  su_resp r = su_http(&S, "POST", path, body, TOKEN);
  if (r.status != 201) fprintf(stderr, "create: %ld %.*s\n", r.status, (int)r.len, r.body);
  assert_int_equal(r.status, 201);
  json_t *o = json_loadb(r.body, r.len, 0, NULL);
  assert_non_null(o);
  snprintf(id, sizeof id, "%s", json_string_value(json_object_get(o, "id")));
  assert_int_equal(strlen(id), 32);
  char want[128];
  snprintf(want, sizeof want, "/v1/sessions/%s/lighting", id);
  assert_string_equal(json_string_value(json_object_get(json_object_get(o, "links"), "lighting")), want);
  assert_true(json_number_value(json_object_get(o, "ttl_s")) == TTL_S);
  assert_true(json_integer_value(json_object_get(o, "bytes")) > 0);
  snprintf(want, sizeof want, "/v1/sessions/%s", id);
  assert_string_equal(su_header(&r, "Location"), want);
  json_decref(o);
  free(r.body);
  return id;
}

static su_resp move_to(const char *id, const char *at) {
  char path[256];
  snprintf(path, sizeof path, "/v1/sessions/%s/lighting?at=%s", id, at);
  return GET(path);
}

static void delete_session(const char *id) {
  char path[128];
  snprintf(path, sizeof path, "/v1/sessions/%s", id);
  su_resp r = su_http(&S, "DELETE", path, NULL, TOKEN);
  assert_int_equal(r.status, 204);
  free(r.body);
}

/* A HEAD request's status, and its Allow header into allow (empty: none). */
static long head_status(const char *path, char *allow, size_t size) {
  su_resp r = {0};
  struct curl_slist *hd;
  CURL *c = su_make_req(&S, NULL, path, NULL, TOKEN, &r, &hd);
  curl_easy_setopt(c, CURLOPT_NOBODY, 1L);
  long status = -1;
  if (curl_easy_perform(c) == CURLE_OK) curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &status);
  const char *a = su_header(&r, "Allow");
  snprintf(allow, size, "%s", a ? a : "");
  curl_slist_free_all(hd);
  curl_easy_cleanup(c);
  free(r.body);
  return status;
}

/* The session's JSON: its moves and at[0] (moves -1 when it is not 200). */
static long session_moves(const char *id, double *x) {
  char path[128];
  snprintf(path, sizeof path, "/v1/sessions/%s", id);
  su_resp r = GET(path);
  long moves = -1;
  json_t *o = r.status == 200 ? json_loadb(r.body, r.len, 0, NULL) : NULL;
  if (o) moves = (long)json_integer_value(json_object_get(o, "moves"));
  if (o && x) *x = json_number_value(json_array_get(json_object_get(o, "at"), 0));
  json_decref(o);
  free(r.body);
  return moves;
}

/* A field of X-GI-Move ("n=3 cycle=0 ..."), or -1. */
static long move_field(const su_resp *r, const char *key) {
  const char *h = su_header(r, "X-GI-Move");
  if (!h) return -1;
  char pat[32];
  snprintf(pat, sizeof pat, "%s=", key);
  const char *p = strstr(h, pat);
  return p ? strtol(p + strlen(pat), NULL, 10) : -1;
}

/* The probe's irradiance in an EXR answer of server srv. */
static void exr_rgb_of(const su_server *srv, const su_resp *r, float rgb[3]) {
  gi_exr_file *x = su_read_exr(srv, r, "answer.exr");
  const char *names[3] = {"R", "G", "B"};
  for (int k = 0; k < 3; k++) rgb[k] = gi_exr_file_channel(x, names[k])[0];
  gi_exr_file_free(x);
}

static void exr_rgb(const su_resp *r, float rgb[3]) { exr_rgb_of(&S, r, rgb); }

/* The core's probe at `at` from a cold bake of quality q, in this process. */
static void cold_probe_q(const double at[3], const gi_quality *q, float rgb[3]) {
  gi_city_params p = {.extent = 300};
  gi_scene_options opt = {.up = GI_UP_Y, .threads = 2, .default_lights = 1};
  gi_scene *s = NULL;
  gi_cascade *c = NULL;
  gi_error_info e = {0};
  assert_int_equal(gi_city_build(&p, &opt, &s, &e), GI_OK);
  assert_int_equal(gi_cascade_bake(s, at, q, &c, NULL, &e), GI_OK);
  gi_probe pr;
  assert_int_equal(gi_cascade_gather(c, at, 1, &pr, NULL, &e), GI_OK);
  memcpy(rgb, pr.irradiance, sizeof pr.irradiance);
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* Stands at `at` until the session's refresh cycle closes (CYCLE calls at
 * a held anchor); that answer's probe into rgb. Returns the moves it made. */
static int stand_until_cycle(const char *id, const char *at, float rgb[3]) {
  for (int i = 0; i <= CYCLE; i++) {
    su_resp r = move_to(id, at);
    assert_int_equal(r.status, 200);
    int closed = move_field(&r, "cycle") == 1;
    if (closed) exr_rgb(&r, rgb);
    free(r.body);
    if (closed) return i + 1;
  }
  fail_msg("the refresh cycle did not close within %d moves", CYCLE + 1);
  return -1;
}

static void expect_cold_q(const float got[3], const double at[3], const gi_quality *q) {
  float want[3];
  cold_probe_q(at, q, want);
  for (int k = 0; k < 3; k++) {
    printf("  probe[%d]: session %.7g, cold bake %.7g\n", k, got[k], want[k]);
    assert_true(isfinite(got[k]) && got[k] > 0);
    assert_true(fabsf(got[k] - want[k]) <= COLD_TOL * fabsf(want[k]));
  }
}

static void expect_cold(const float got[3], const double at[3]) { expect_cold_q(got, at, &Q_LOW); }

static void test_walk_matches_cold_bake(void **state) {
  (void)state;
  const char *id = open_session("?quality=low&at=10,2,10", NULL);
  const char *walk[] = {"10.5,2,10", "12,2,10", "20,2,11", "25,2,14"};
  for (size_t i = 0; i < sizeof walk / sizeof walk[0]; i++) {
    su_resp r = move_to(id, walk[i]);
    assert_int_equal(r.status, 200);
    assert_string_equal(su_header(&r, "Content-Type"), "image/x-exr");
    const char *t = su_header(&r, "Server-Timing");
    const char *stages[] = {"voxelize;dur=", "inject;dur=", "filter;dur=", "bounce;dur=", "gather;dur=", "total;dur="};
    for (size_t k = 0; k < 6; k++) assert_non_null(strstr(t, stages[k]));
    assert_int_equal(move_field(&r, "n"), (long)i + 1);
    assert_true(move_field(&r, "cycle") == 0 && move_field(&r, "rebuilt") == 0);
    /* 10 -> 10.5 stays in its 2-voxel cell; 12 and 20 leave it. */
    assert_int_equal(move_field(&r, "crossed"), i == 0 ? 0 : 1);
    float rgb[3];
    exr_rgb(&r, rgb);
    for (int k = 0; k < 3; k++) assert_true(isfinite(rgb[k]) && rgb[k] > 0);
    free(r.body);
  }
  float got[3];
  int stood = stand_until_cycle(id, "25,2,14", got);
  expect_cold(got, (const double[3]){25, 2, 14});
  /* GET names where it stands and how often it moved. */
  char path[128];
  snprintf(path, sizeof path, "/v1/sessions/%s", id);
  su_resp r = GET(path);
  assert_int_equal(r.status, 200);
  json_t *o = json_loadb(r.body, r.len, 0, NULL);
  assert_int_equal(json_integer_value(json_object_get(o, "moves")), (long)(sizeof walk / sizeof walk[0]) + stood);
  assert_true(json_number_value(json_array_get(json_object_get(o, "at"), 2)) == 14);
  json_decref(o);
  free(r.body);
  assert_true(su_metric(&S, "gi_session_cycles_total", NULL) >= 1);
  assert_true(su_metric(&S, "gi_session_move_duration_seconds_count", NULL) >= CYCLE);
  assert_true(su_metric(&S, "gi_sessions_open", NULL) == 1);
  assert_true(su_metric(&S, "gi_session_bytes", NULL) > 0);
  delete_session(id);
  assert_true(su_metric(&S, "gi_session_bytes", NULL) == 0);
}

static void test_bad_input(void **state) {
  (void)state;
  su_resp r = move_to("0123456789abcdef0123456789abcdef", "1,2,3");
  su_expect_error(&r, 404, "not_found", "does not exist or has ended");
  free(r.body);
  const char *id = open_session("", "{\"at\":[5,2,5],\"quality\":\"low\"}");
  char path[256];
  r = move_to(id, "nan,2,3");
  su_expect_error(&r, 400, "bad_request", "parameter 'at'");
  free(r.body);
  r = move_to(id, "1e12,2,3");
  su_expect_error(&r, 400, "bad_request", "parameter 'at': out of range");
  free(r.body);
  snprintf(path, sizeof path, "/v1/sessions/%s/lighting?at=1,2,3&kind=lightmap", id);
  r = GET(path);
  su_expect_error(&r, 400, "bad_request", "parameter 'kind'");
  free(r.body);
  snprintf(path, sizeof path, "/v1/sessions/%s/lighting?at=1,2,3&levels=3", id);
  r = GET(path);
  su_expect_error(&r, 400, "bad_request", "parameter 'levels': a session's quality is set when it is created");
  free(r.body);
  snprintf(path, sizeof path, "/v1/sessions/%s/lighting", id);
  r = GET(path);
  su_expect_error(&r, 400, "bad_request", "parameter 'at' is required");
  free(r.body);
  snprintf(path, sizeof path, "/v1/sessions/%s/lighting?at=1,2,3&kind=panorama&width=2&height=8193", id);
  r = GET(path);
  su_expect_error(&r, 400, "bad_request", "parameter 'height'");
  free(r.body);
  /* HEAD would move the cascade: 405 naming GET, and nothing moved. */
  char allow[64];
  snprintf(path, sizeof path, "/v1/sessions/%s/lighting?at=40,2,40", id);
  assert_int_equal(head_status(path, allow, sizeof allow), 405);
  assert_string_equal(allow, "GET");
  double x = 0;
  assert_int_equal(session_moves(id, &x), 0);
  assert_true(x == 5);
  /* The refused moves left the cascade alone: the next is move 1. */
  r = move_to(id, "5,2,5");
  assert_int_equal(r.status, 200);
  assert_int_equal(move_field(&r, "n"), 1);
  free(r.body);
  r = su_http(&S, "POST", "/v1/scenes/city/sessions?quality=low", "{\"quality\":\"low\"}", TOKEN);
  su_expect_error(&r, 400, "bad_request", "not both");
  free(r.body);
  r = su_http(&S, "POST", "/v1/scenes/city/sessions", "{\"at\":[1,2]}", TOKEN);
  su_expect_error(&r, 400, "bad_request", "body: 'at'");
  free(r.body);
  r = su_http(&S, "POST", "/v1/scenes/nope/sessions", NULL, TOKEN);
  su_expect_error(&r, 404, "not_found", "nope");
  free(r.body);
  snprintf(path, sizeof path, "/v1/sessions/%s", id);
  r = su_http(&S, "PUT", path, NULL, TOKEN);
  su_expect_error(&r, 405, "method_not_allowed", "GET, HEAD, DELETE");
  free(r.body);
  delete_session(id);
  r = move_to(id, "5,2,5");
  su_expect_error(&r, 404, "not_found", id);
  free(r.body);
  r = su_http(&S, "DELETE", path, NULL, TOKEN);
  su_expect_error(&r, 404, "not_found", id);
  free(r.body);
}

/* A client that hangs up while its session moves far (every level
 * rebuilt: a cold bake's work) keeps its session: the move runs to its
 * end, and the next request moves on from there. */
static void test_hangup_keeps_session(void **state) {
  (void)state;
  char id[64], req[512];
  snprintf(id, sizeof id, "%s", open_session("?quality=high&at=0,1.7,0", NULL));
  snprintf(req, sizeof req,
           "GET /v1/sessions/%s/lighting?at=100,1.7,0 HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer " TOKEN "\r\n\r\n",
           id);
  int fd = su_connect(&S, NULL);
  assert_true(fd >= 0);
  assert_int_equal(send(fd, req, strlen(req), MSG_NOSIGNAL), (ssize_t)strlen(req));
  su_sleep_ms(50); /* the move has started */
  close(fd);
  double t0 = su_now_ms(), x = 0;
  long moves;
  while ((moves = session_moves(id, &x)) == 0 && su_now_ms() - t0 < 30000) su_sleep_ms(20);
  printf("  client gone during a far move: session has %ld move(s) at x = %g after %.0f ms\n", moves, x,
         su_now_ms() - t0);
  assert_int_equal(moves, 1);
  assert_true(x == 100);
  su_resp r = move_to(id, "100,1.7,0");
  assert_int_equal(r.status, 200);
  assert_int_equal(move_field(&r, "n"), 2);
  assert_int_equal(move_field(&r, "crossed"), 0);
  float rgb[3];
  exr_rgb(&r, rgb);
  for (int k = 0; k < 3; k++) assert_true(isfinite(rgb[k]) && rgb[k] > 0);
  free(r.body);
  delete_session(id);
}

static void test_limit_and_expiry(void **state) {
  (void)state;
  char a[64], b[64];
  snprintf(a, sizeof a, "%s", open_session("?quality=low", NULL));
  snprintf(b, sizeof b, "%s", open_session("?quality=low", NULL));
  double rejected = su_metric(&S, "gi_sessions_rejected_total", NULL);
  su_resp r = su_http(&S, "POST", "/v1/scenes/city/sessions?quality=low", NULL, TOKEN);
  su_expect_error(&r, 503, "overloaded", "max_sessions");
  const char *ra = su_header(&r, "Retry-After");
  assert_non_null(ra);
  assert_true(atoi(ra) >= 1 && atoi(ra) <= TTL_S);
  free(r.body);
  assert_true(su_metric(&S, "gi_sessions_rejected_total", NULL) == rejected + 1);
  /* A used session stays; an idle one ends after the TTL. */
  double expired = su_metric(&S, "gi_sessions_expired_total", NULL);
  for (int i = 0; i < 3; i++) {
    su_sleep_ms(TTL_S * 1000 / 2);
    r = move_to(b, "0,2,0");
    assert_int_equal(r.status, 200);
    free(r.body);
  }
  r = move_to(a, "0,2,0");
  su_expect_error(&r, 404, "not_found", "after 2 s idle");
  free(r.body);
  assert_true(su_metric(&S, "gi_sessions_expired_total", NULL) == expired + 1);
  assert_true(su_metric(&S, "gi_sessions_open", NULL) == 1);
  /* Its slot is free again. */
  snprintf(a, sizeof a, "%s", open_session("?quality=low", NULL));
  delete_session(a);
  delete_session(b);
}

typedef struct {
  const char *id;
  const char *at[2];
  long status[HAMMER_N], n[HAMMER_N];
} hammer_arg;

/* One client: HAMMER_N moves on the session, back and forth (no cmocka here: another thread). */
static void *hammer(void *p) {
  hammer_arg *h = p;
  for (int i = 0; i < HAMMER_N; i++) {
    char path[256];
    snprintf(path, sizeof path, "/v1/sessions/%s/lighting?at=%s", h->id, h->at[i % 2]);
    su_resp r = {0};
    struct curl_slist *hd;
    CURL *c = su_make_req(&S, NULL, path, NULL, TOKEN, &r, &hd);
    h->status[i] = curl_easy_perform(c) == CURLE_OK ? 0 : -1;
    if (h->status[i] == 0) curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &h->status[i]);
    h->n[i] = move_field(&r, "n");
    curl_slist_free_all(hd);
    curl_easy_cleanup(c);
    free(r.body);
  }
  return NULL;
}

static void test_concurrent_serialised(void **state) {
  (void)state;
  const char *id = open_session("?quality=low&at=0,2,0", NULL);
  hammer_arg h[2] = {{.id = id, .at = {"0,2,0", "9,2,3"}}, {.id = id, .at = {"-7,2,1", "4,2,-8"}}};
  pthread_t th[2];
  for (int i = 0; i < 2; i++) assert_int_equal(pthread_create(&th[i], NULL, hammer, &h[i]), 0);
  for (int i = 0; i < 2; i++) pthread_join(th[i], NULL);
  int seen[2 * HAMMER_N + 1] = {0};
  for (int i = 0; i < 2; i++)
    for (int k = 0; k < HAMMER_N; k++) {
      assert_int_equal(h[i].status[k], 200);
      assert_true(h[i].n[k] >= 1 && h[i].n[k] <= 2 * HAMMER_N);
      seen[h[i].n[k]]++;
    }
  /* One move at a time: every move number once. */
  for (int n = 1; n <= 2 * HAMMER_N; n++) assert_int_equal(seen[n], 1);
  float got[3];
  stand_until_cycle(id, "6,2,6", got);
  expect_cold(got, (const double[3]){6, 2, 6});
  delete_session(id);
}

/* One session at quality=low (res 16, 5 levels) holds its bounds for its
 * life, 15.47 MiB: the bake's 8.59 MiB with transients and the move's 6.88
 * MiB. A cached low cascade holds at least its 1.11 MiB of dense arrays,
 * and a low bake is admitted for 8.59 MiB: in 16 MiB a session fits with
 * room for nothing else. */
#define BUDGET_INI                                                                                     \
  "[server]\nbind = 127.0.0.1\nport = 0\nbake_threads = 2\nworkers = 2\ntmp_dir = .\n"                   \
  "[limits]\ncache_mb = 16\nmax_sessions = 4\n[scene city]\nsource = city\nextent = 300\n"

static void test_budget(void **state) {
  (void)state;
  assert_int_equal(su_start(&S_budget, "budget", BUDGET_INI), 0);
  su_resp r = su_http(&S_budget, NULL, "/v1/scenes/city/lighting?at=40,2,40&quality=low&redirect=0", NULL, NULL);
  assert_int_equal(r.status, 200);
  free(r.body);
  assert_true(su_metric(&S_budget, "gi_cache_entries", NULL) == 1);
  /* The session takes the cached cascade's room. */
  r = su_http(&S_budget, "POST", "/v1/scenes/city/sessions?quality=low", NULL, NULL);
  assert_int_equal(r.status, 201);
  json_t *o = json_loadb(r.body, r.len, 0, NULL);
  double bytes = (double)json_integer_value(json_object_get(o, "bytes"));
  char self[128];
  snprintf(self, sizeof self, "%s", json_string_value(json_object_get(json_object_get(o, "links"), "self")));
  json_decref(o);
  free(r.body);
  assert_true(su_metric(&S_budget, "gi_cache_entries", NULL) == 0);
  assert_true(su_metric(&S_budget, "gi_cache_evictions_total", NULL) == 1);
  assert_true(su_metric(&S_budget, "gi_session_bytes", NULL) == bytes);
  /* A second session does not fit beside the first. */
  r = su_http(&S_budget, "POST", "/v1/scenes/city/sessions?quality=low", NULL, NULL);
  su_expect_error(&r, 503, "overloaded", "held by sessions");
  assert_non_null(su_header(&r, "Retry-After"));
  free(r.body);
  assert_true(su_metric(&S_budget, "gi_sessions_rejected_total", NULL) == 1);
  /* Nor does a cold bake; ending the session gives the room back. */
  r = su_http(&S_budget, NULL, "/v1/scenes/city/lighting?at=-40,2,40&quality=low&redirect=0", NULL, NULL);
  su_expect_error(&r, 503, "overloaded", "held by sessions");
  free(r.body);
  r = su_http(&S_budget, "DELETE", self, NULL, NULL);
  assert_int_equal(r.status, 204);
  free(r.body);
  assert_true(su_metric(&S_budget, "gi_session_bytes", NULL) == 0);
  r = su_http(&S_budget, NULL, "/v1/scenes/city/lighting?at=-40,2,40&quality=low&redirect=0", NULL, NULL);
  assert_int_equal(r.status, 200);
  free(r.body);
  assert_int_equal(su_stop(&S_budget), 0);
  S_budget.pid = 0;
}

/* A session being baked holds its bytes in the budget, and /metrics says
 * so: gi_session_bytes read 0 while a 503 named the MiB it held. */
static void test_creation_bytes(void **state) {
  (void)state;
  assert_int_equal(su_start(&S_deadline, "creating",
                            "[server]\nbind = 127.0.0.1\nport = 0\nbake_threads = 1\nworkers = 2\ntmp_dir = .\n"
                            "[scene city]\nsource = city\nextent = 300\n"),
                   0);
  const char *req = "POST /v1/scenes/city/sessions?quality=high HTTP/1.1\r\nHost: x\r\nContent-Length: 0\r\n"
                    "Connection: close\r\n\r\n";
  int fd = su_connect(&S_deadline, NULL);
  assert_true(fd >= 0);
  assert_int_equal(send(fd, req, strlen(req), MSG_NOSIGNAL), (ssize_t)strlen(req));
  double t0 = su_now_ms();
  while (su_metric(&S_deadline, "gi_bakes_in_flight", NULL) < 1 && su_now_ms() - t0 < 10000) su_sleep_ms(10);
  double during = su_metric(&S_deadline, "gi_session_bytes", NULL), flight = su_metric(&S_deadline, "gi_bakes_in_flight", NULL);
  static char buf[8192];
  su_read(fd, buf, sizeof buf, 60000);
  close(fd);
  assert_non_null(strstr(buf, "HTTP/1.1 201"));
  double after = su_metric(&S_deadline, "gi_session_bytes", NULL);
  printf("  a high-quality session while it bakes: gi_session_bytes %.0f (after: %.0f)\n", during, after);
  assert_true(flight == 1);
  assert_true(during > 0 && during == after);
  assert_int_equal(su_stop(&S_deadline), 0);
  S_deadline.pid = 0;
}

static void test_deadline_cancels_creation(void **state) {
  (void)state;
  assert_int_equal(su_start(&S_deadline, "deadline",
                            "[server]\nbind = 127.0.0.1\nport = 0\nbake_threads = 2\nworkers = 2\ntmp_dir = .\n"
                            "deadline_s = 0.3\n[scene city]\nsource = city\nextent = 300\n"),
                   0);
  /* High quality bakes for seconds on two cores (the default's 0.2-0.3 s
   * bake now and then finished inside the 0.3 s deadline). */
  su_resp r = su_http(&S_deadline, "POST", "/v1/scenes/city/sessions?quality=high", NULL, NULL);
  su_expect_error(&r, 504, "timeout", "deadline");
  assert_non_null(su_header(&r, "Retry-After"));
  free(r.body);
  /* The bake stops within a chunk's time: nothing left running, nothing open. */
  double t0 = su_now_ms();
  while (su_metric(&S_deadline, "gi_bakes_in_flight", NULL) > 0 && su_now_ms() - t0 < 10000) su_sleep_ms(20);
  assert_true(su_metric(&S_deadline, "gi_bakes_in_flight", NULL) == 0);
  assert_true(su_metric(&S_deadline, "gi_bakes_cancelled_total", NULL) == 1);
  assert_true(su_metric(&S_deadline, "gi_sessions_open", NULL) == 0);
  assert_true(su_metric(&S_deadline, "gi_sessions_created_total", NULL) == 0);
  assert_true(su_metric(&S_deadline, "gi_session_bytes", NULL) == 0);
  assert_int_equal(su_stop(&S_deadline), 0);
  S_deadline.pid = 0;
}

/* quality=high (6 levels) with the deadline server's one bake thread. */
static const gi_quality Q_HIGH_1 = {.cones = 32, .light_samples = 64, .probe_samples = 1024, .step = 0.35f,
                                    .threads = 1};
/* The deadline server's, seconds. A session baked 1 km above the city
 * (nothing in range: a 0.05 s bake) and moved into its streets rebuilds
 * every level: a cold bake, 1.7-3.2 s with two bake threads and 3.1-3.6 s
 * with one (measured run to its end, as moves did without a token). */
#define MOVE_DEADLINE_S 0.5
/* The stopped move answered and the session answering again, ms: the
 * deadline plus a chunk and a 0.05 s re-bake; an unstoppable move held
 * the session for seconds (the next request a 504 waiting for it). */
#define MOVE_STOP_BOUND_MS 2500

typedef struct {
  const char *path;
  su_resp r;
} get_arg;

/* One GET on S_deadline (no cmocka here: another thread). */
static void *get_deadline(void *p) {
  get_arg *g = p;
  struct curl_slist *hd;
  CURL *c = su_make_req(&S_deadline, NULL, g->path, NULL, NULL, &g->r, &hd);
  g->r.status = -1;
  if (curl_easy_perform(c) == CURLE_OK) curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &g->r.status);
  curl_slist_free_all(hd);
  curl_easy_cleanup(c);
  return NULL;
}

/* A session's move past the deadline stops as a lighting request's bake
 * does: the deadline's 504 (Retry-After, gi_timeouts_total), counted in
 * gi_bakes_cancelled_total. The session stays: a request that waited for
 * it, and the next one, re-bake the cascade where they are (no request
 * reads the stopped move's partial cascade) and answer a cold bake's
 * probe there. */
static void test_deadline_stops_move(void **state) {
  (void)state;
  assert_int_equal(su_start(&S_deadline, "movedeadline",
                            "[server]\nbind = 127.0.0.1\nport = 0\nbake_threads = 1\nworkers = 2\ntmp_dir = .\n"
                            "deadline_s = " STR(MOVE_DEADLINE_S) "\n[scene city]\nsource = city\nextent = 300\n"),
                   0);
  su_resp r = su_http(&S_deadline, "POST", "/v1/scenes/city/sessions?quality=high&at=0,1000,0", NULL, NULL);
  assert_int_equal(r.status, 201);
  json_t *o = json_loadb(r.body, r.len, 0, NULL);
  char id[64], far[160], near[160];
  snprintf(id, sizeof id, "%s", json_string_value(json_object_get(o, "id")));
  json_decref(o);
  free(r.body);
  snprintf(far, sizeof far, "/v1/sessions/%s/lighting?at=30,1.7,30", id);
  snprintf(near, sizeof near, "/v1/sessions/%s/lighting?at=0,1000,0.5", id);
  get_arg a = {.path = far}, b = {.path = near};
  pthread_t ta, tb;
  double t0 = su_now_ms();
  assert_int_equal(pthread_create(&ta, NULL, get_deadline, &a), 0);
  su_sleep_ms(250); /* b waits for the far move's turn to end */
  assert_int_equal(pthread_create(&tb, NULL, get_deadline, &b), 0);
  pthread_join(ta, NULL);
  double t_a = su_now_ms() - t0;
  pthread_join(tb, NULL);
  su_resp c = su_http(&S_deadline, NULL, near, NULL, NULL);
  double t_c = su_now_ms() - t0;
  char mb[128], mc[128]; /* su_header's buffer is reused */
  snprintf(mb, sizeof mb, "%s", su_header(&b.r, "X-GI-Move") ? su_header(&b.r, "X-GI-Move") : "-");
  snprintf(mc, sizeof mc, "%s", su_header(&c, "X-GI-Move") ? su_header(&c, "X-GI-Move") : "-");
  printf("  far move: %ld after %.0f ms; waiting request: %ld (%s); next: %ld (%s) %.0f ms after the far move began\n",
         a.r.status, t_a, b.r.status, mb, c.status, mc, t_c);
  su_expect_error(&a.r, 504, "timeout", "deadline");
  assert_non_null(su_header(&a.r, "Retry-After"));
  /* Nothing reads the partial cascade: an answer after the stop is a re-bake's. */
  const double at[3] = {0, 1000, 0.5};
  float got[3];
  assert_true(b.r.status == 200 || b.r.status == 504);
  if (b.r.status == 200) {
    assert_int_equal(move_field(&b.r, "cycle"), 1);
    assert_int_equal(move_field(&b.r, "rebuilt"), 6);
    exr_rgb_of(&S_deadline, &b.r, got);
    expect_cold_q(got, at, &Q_HIGH_1);
  }
  assert_int_equal(c.status, 200);
  if (b.r.status != 200) assert_int_equal(move_field(&c, "rebuilt"), 6);
  exr_rgb_of(&S_deadline, &c, got);
  expect_cold_q(got, at, &Q_HIGH_1);
  assert_true(t_c < MOVE_STOP_BOUND_MS);
  double timeouts = su_metric(&S_deadline, "gi_timeouts_total", NULL);
  double cancelled = su_metric(&S_deadline, "gi_bakes_cancelled_total", NULL);
  printf("  gi_timeouts_total %g, gi_bakes_cancelled_total %g\n", timeouts, cancelled);
  assert_true(timeouts == 1 + (b.r.status == 504));
  assert_true(cancelled >= 1 && cancelled <= 1 + (b.r.status == 504));
  assert_true(su_metric(&S_deadline, "gi_sessions_open", NULL) == 1);
  free(a.r.body);
  free(b.r.body);
  free(c.body);
  assert_int_equal(su_stop(&S_deadline), 0);
  S_deadline.pid = 0;
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_walk_matches_cold_bake),
      cmocka_unit_test(test_bad_input),
      cmocka_unit_test(test_hangup_keeps_session),
      cmocka_unit_test(test_limit_and_expiry),
      cmocka_unit_test(test_concurrent_serialised),
      cmocka_unit_test(test_budget),
      cmocka_unit_test(test_creation_bytes),
      cmocka_unit_test(test_deadline_cancels_creation),
      cmocka_unit_test(test_deadline_stops_move),
  };
  return cmocka_run_group_tests(tests, setup, teardown);
}
