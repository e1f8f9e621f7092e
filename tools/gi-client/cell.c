/* cell.c: gi-client names a viewpoint's cell URL itself (issue 14).
 *
 * GET /v1/scenes/ID (with the request's quality knobs) publishes the grid a
 * viewpoint snaps to and the cell URL templates. Asking the cell URL
 * directly saves the 307 round trip and lets every cache in front (nginx)
 * answer. The snapping is the server's, bit for bit: the offset from the
 * origin rounded to float, then floor(offset / cell_size). Anything
 * missing (an older server, an error) gives NULL: the caller then asks the
 * viewpoint URL and follows its redirect. */
#define _POSIX_C_SOURCE 200809L
#include <curl/curl.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "client.h"

/* A scene answer is small; more than this is not one. */
#define GC_SCENE_MAX_BYTES (1 << 20)
/* Cell indices stay exactly representable and within long long. */
#define GC_MAX_CELL 9e15
/* The server's panorama size when the request names none (openapi.yaml). */
#define GC_PANORAMA_W "256"
#define GC_PANORAMA_H "128"

typedef struct {
  char *p;
  size_t n;
} mem;

static size_t on_body(char *p, size_t size, size_t nmemb, void *ud) {
  mem *m = ud;
  size_t k = size * nmemb;
  if (m->n + k > GC_SCENE_MAX_BYTES) return 0;
  char *q = realloc(m->p, m->n + k + 1);
  if (!q) return 0;
  memcpy(q + m->n, p, k);
  m->p = q;
  m->n += k;
  m->p[m->n] = 0;
  return k;
}

static const char *set_value(const gc_opts *o, const char *key) {
  for (int i = 0; i < o->num_sets; i++)
    if (!strcmp(o->sets[i].key, key)) return o->sets[i].value;
  return NULL;
}

/* Knobs that shape the answer, not the cascade: never sent to /v1/scenes/ID. */
static int answer_only(const char *key) {
  return !strcmp(key, "half") || !strcmp(key, "width") || !strcmp(key, "height");
}

/* GET /v1/scenes/ID?quality knobs into m; 0 on a 200. */
static int fetch_scene(const gc_opts *o, mem *m) {
  CURL *c = curl_easy_init();
  if (!c) return -1;
  char *id = curl_easy_escape(c, o->id, 0);
  size_t cap = strlen(o->server) + 4096;
  char *url = malloc(cap), auth[4200];
  int rc = -1;
  if (id && url) {
    int n = snprintf(url, cap, "%s/v1/scenes/%s", o->server, id);
    char sep = '?';
    if (o->quality) n += snprintf(url + n, cap - (size_t)n, "%cquality=%s", sep, o->quality), sep = '&';
    for (int i = 0; i < o->num_sets && (size_t)n < cap; i++) {
      if (answer_only(o->sets[i].key)) continue;
      char *v = curl_easy_escape(c, o->sets[i].value, 0);
      if (v) n += snprintf(url + n, cap - (size_t)n, "%c%s=%s", sep, o->sets[i].key, v), sep = '&';
      curl_free(v);
    }
    struct curl_slist *h = NULL;
    if (o->token) {
      snprintf(auth, sizeof auth, "Authorization: Bearer %s", o->token);
      h = curl_slist_append(h, auth);
    }
    curl_easy_setopt(c, CURLOPT_URL, url);
    curl_easy_setopt(c, CURLOPT_HTTPHEADER, h);
    curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, on_body);
    curl_easy_setopt(c, CURLOPT_WRITEDATA, m);
    curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
    curl_easy_setopt(c, CURLOPT_CONNECTTIMEOUT_MS, 10000L);
    curl_easy_setopt(c, CURLOPT_USERAGENT, "gi-client/" GI_VERSION);
    if (o->timeout_ms) curl_easy_setopt(c, CURLOPT_TIMEOUT_MS, o->timeout_ms);
    long status = 0;
    if ((size_t)n < cap && curl_easy_perform(c) == CURLE_OK &&
        curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &status) == CURLE_OK && status == 200)
      rc = 0;
    curl_slist_free_all(h);
  }
  curl_free(id);
  free(url);
  curl_easy_cleanup(c);
  return rc;
}

/* The template with {i},{j},{k} and the kind filled in, plus the answer's
 * own parameters in the server's order (canonical.c): faces; half, width, height. */
static char *fill(const gc_opts *o, const char *tpl, const long long cell[3]) {
  const char *slot = strstr(tpl, "{i},{j},{k}"), *kindp = strstr(tpl, "kind=probe");
  if (!slot) return NULL;
  size_t cap = strlen(o->server) + strlen(tpl) + 256;
  char *u = malloc(cap);
  if (!u) return NULL;
  int n = snprintf(u, cap, "%s%.*s%lld,%lld,%lld", o->server, (int)(slot - tpl), tpl, cell[0], cell[1], cell[2]);
  const char *rest = slot + strlen("{i},{j},{k}");
  const char *kind = o->kind ? o->kind : "probe";
  if (o->cmd == GC_LIGHTING && kindp && kindp > rest) {
    n += snprintf(u + n, cap - (size_t)n, "%.*skind=%s%s", (int)(kindp - rest), rest, kind,
                  kindp + strlen("kind=probe"));
  } else {
    n += snprintf(u + n, cap - (size_t)n, "%s", rest);
  }
  const char *half = set_value(o, "half");
  if (o->cmd == GC_CASCADES && o->faces) n += snprintf(u + n, cap - (size_t)n, "&faces=1");
  if (o->cmd == GC_LIGHTING && half && (!strcmp(half, "1") || !strcmp(half, "true")))
    n += snprintf(u + n, cap - (size_t)n, "&half=1");
  if (o->cmd == GC_LIGHTING && !strcmp(kind, "panorama")) {
    const char *w = set_value(o, "width"), *h = set_value(o, "height");
    snprintf(u + n, cap - (size_t)n, "&width=%s&height=%s", w ? w : GC_PANORAMA_W, h ? h : GC_PANORAMA_H);
  }
  return u;
}

char *gc_cell_url(const gc_opts *o) {
  mem m = {0};
  char *url = NULL;
  if (fetch_scene(o, &m) != 0) {
    free(m.p);
    return NULL;
  }
  json_t *root = json_loadb(m.p ? m.p : "", m.n, 0, NULL);
  json_t *g = json_object_get(root, "grid"), *org = json_object_get(g, "origin");
  const char *tpl = json_string_value(json_object_get(g, o->cmd == GC_CASCADES ? "cascades" : "lighting"));
  double cs = json_number_value(json_object_get(g, "cell_size"));
  long long cell[3];
  int ok = tpl && json_array_size(org) == 3 && cs > 0 && isfinite(cs);
  for (int a = 0; a < 3 && ok; a++) {
    double off = (double)(float)(o->at[a] - json_number_value(json_array_get(org, (size_t)a)));
    double k = floor(off / cs);
    ok = isfinite(k) && fabs(k) < GC_MAX_CELL;
    cell[a] = ok ? (long long)k : 0;
  }
  if (ok) url = fill(o, tpl, cell);
  json_decref(root);
  free(m.p);
  return url;
}
