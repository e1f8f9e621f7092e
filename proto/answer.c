/* answer.c: the JSON and header values both sides read.
 *
 * Errors and job status are encoded here for the server and decoded here
 * for the client, so the two cannot drift apart. JSON goes through jansson;
 * nothing is formatted by hand that a reader must parse back. */
#define _POSIX_C_SOURCE 200809L
#include <jansson.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include "gi_proto.h"

const char *gi_proto_status_name(int status) {
  switch (status) {
  case 400: return "bad_request";
  case 401: return "unauthorized";
  case 404: return "not_found";
  case 405: return "method_not_allowed";
  case 409: return "not_ready";
  case 413: return "payload_too_large";
  case 501: return "not_implemented";
  case 503: return "overloaded";
  case 504: return "timeout";
  default: return status >= 500 ? "internal" : "bad_request";
  }
}

/* Length of the well-formed UTF-8 sequence at p (1..4; no overlong form,
 * surrogate or code point past U+10FFFF), 0 when it is not one. */
static size_t utf8_len(const unsigned char *p) {
  unsigned c = p[0];
  unsigned n = c < 0x80 ? 1 : c < 0xC2 ? 0 : c < 0xE0 ? 2 : c < 0xF0 ? 3 : c < 0xF5 ? 4 : 0;
  for (unsigned i = 1; i < n; i++)
    if ((p[i] & 0xC0) != 0x80) return 0;
  if ((c == 0xE0 && p[1] < 0xA0) || (c == 0xED && p[1] >= 0xA0) || (c == 0xF0 && p[1] < 0x90) ||
      (c == 0xF4 && p[1] >= 0x90))
    return 0;
  return n;
}

int gi_proto_fail(gi_proto_error *e, int status, const char *fmt, ...) {
  if (!e) return status;
  e->status = status;
  snprintf(e->name, sizeof e->name, "%s", gi_proto_status_name(status));
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(e->message, sizeof e->message, fmt, ap);
  va_end(ap);
  /* A message quotes what the client sent (a path, a %ff in a query) and may
   * be cut mid-character: jansson refuses invalid UTF-8, which left the
   * error's body empty. Each byte that is not part of a character is '?'. */
  for (unsigned char *p = (unsigned char *)e->message; *p;) {
    size_t n = utf8_len(p);
    if (n) p += n;
    else *p++ = '?';
  }
  return status;
}

static json_t *error_obj(const gi_proto_error *e) {
  return json_pack("{s:i, s:s, s:s}", "code", e->status, "name", e->name, "message", e->message);
}

char *gi_proto_error_json(const gi_proto_error *e) {
  json_t *o = error_obj(e);
  char *s = o ? json_dumps(o, JSON_COMPACT) : NULL;
  json_decref(o);
  return s;
}

static int error_from(const json_t *o, gi_proto_error *out) {
  json_int_t code;
  const char *name, *msg;
  if (!o || json_unpack((json_t *)o, "{s:I, s:s, s:s}", "code", &code, "name", &name, "message", &msg)) return -1;
  out->status = (int)code;
  snprintf(out->name, sizeof out->name, "%s", name);
  snprintf(out->message, sizeof out->message, "%s", msg);
  return 0;
}

int gi_proto_error_parse(const char *json, size_t len, gi_proto_error *out) {
  json_t *o = json_loadb(json, len, 0, NULL);
  int rc = error_from(o, out);
  json_decref(o);
  return rc;
}

static const char *const job_states[GI_JOB_STATE_COUNT] = {"queued", "running", "done", "failed", "cancelled"};

const char *gi_proto_job_state_name(gi_proto_job_state s) {
  return (unsigned)s < GI_JOB_STATE_COUNT ? job_states[s] : "unknown";
}

char *gi_proto_job_json(const gi_proto_job *j) {
  double progress = j->probes ? (double)j->probes_done / (double)j->probes : 0.0;
  if (j->state == GI_JOB_DONE) progress = 1.0;
  char href[96];
  snprintf(href, sizeof href, "/v1/jobs/%s", j->id);
  /* "job" repeats "id": the 202 answer of POST .../probes names it so. */
  json_t *o = json_pack("{s:s, s:s, s:s, s:s, s:f, s:I, s:I, s:i, s:i, s:f}", "id", j->id, "job", j->id, "href", href,
                        "state",
                        gi_proto_job_state_name(j->state), "progress", progress, "probes", (json_int_t)j->probes,
                        "probes_done", (json_int_t)j->probes_done, "tiles", j->tiles, "tiles_done",
                        j->tiles_done, "elapsed_s", j->elapsed_s);
  if (!o) return NULL;
  if (j->state == GI_JOB_DONE) {
    char res[112];
    snprintf(res, sizeof res, "/v1/jobs/%s/result", j->id);
    json_object_set_new(o, "result", json_string(res));
  }
  if (j->state == GI_JOB_FAILED) json_object_set_new(o, "error", error_obj(&j->error));
  char *s = json_dumps(o, JSON_COMPACT);
  json_decref(o);
  return s;
}

int gi_proto_job_parse(const char *json, size_t len, gi_proto_job *out) {
  memset(out, 0, sizeof *out);
  json_t *o = json_loadb(json, len, 0, NULL);
  const char *id, *state;
  json_int_t probes, done;
  int tiles, tiles_done;
  double elapsed;
  int rc = -1;
  if (o && !json_unpack(o, "{s:s, s:s, s:I, s:I, s:i, s:i, s:F}", "id", &id, "state", &state, "probes", &probes,
                        "probes_done", &done, "tiles", &tiles, "tiles_done", &tiles_done, "elapsed_s", &elapsed)) {
    snprintf(out->id, sizeof out->id, "%s", id);
    out->state = (gi_proto_job_state)-1;
    for (int i = 0; i < GI_JOB_STATE_COUNT; i++)
      if (!strcmp(state, job_states[i])) out->state = (gi_proto_job_state)i;
    out->probes = (size_t)probes;
    out->probes_done = (size_t)done;
    out->tiles = tiles;
    out->tiles_done = tiles_done;
    out->elapsed_s = elapsed;
    rc = (int)out->state >= 0 ? 0 : -1;
    if (out->state == GI_JOB_FAILED && error_from(json_object_get(o, "error"), &out->error)) rc = -1;
  }
  json_decref(o);
  return rc;
}

char *gi_proto_session_json(const gi_proto_session *s) {
  char self[96], light[112];
  snprintf(self, sizeof self, "/v1/sessions/%s", s->id);
  snprintf(light, sizeof light, "/v1/sessions/%s/lighting", s->id);
  json_t *o = json_pack("{s:s, s:s, s:f, s:[f,f,f], s:I, s:I, s:{s:s, s:s}}", "id", s->id, "scene", s->scene,
                        "ttl_s", s->ttl_s, "at", s->at[0], s->at[1], s->at[2], "moves", (json_int_t)s->moves,
                        "bytes", (json_int_t)s->bytes, "links", "self", self, "lighting", light);
  if (!o) return NULL;
  char *out = json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(17));
  json_decref(o);
  return out;
}

int gi_proto_session_parse(const char *json, size_t len, gi_proto_session *out) {
  memset(out, 0, sizeof *out);
  json_t *o = json_loadb(json, len, 0, NULL);
  const char *id, *scene;
  json_int_t moves, bytes;
  int rc = -1;
  if (o && !json_unpack(o, "{s:s, s:s, s:F, s:[F,F,F], s:I, s:I}", "id", &id, "scene", &scene, "ttl_s", &out->ttl_s,
                        "at", &out->at[0], &out->at[1], &out->at[2], "moves", &moves, "bytes", &bytes) &&
      strlen(id) < sizeof out->id && strlen(scene) < sizeof out->scene) {
    snprintf(out->id, sizeof out->id, "%s", id);
    snprintf(out->scene, sizeof out->scene, "%s", scene);
    out->moves = (unsigned long long)moves;
    out->bytes = (unsigned long long)bytes;
    rc = 0;
  }
  json_decref(o);
  return rc;
}

void gi_proto_server_timing(const gi_timings *t, double total_ms, char *buf, size_t size) {
  snprintf(buf, size,
           "voxelize;dur=%.2f, inject;dur=%.2f, filter;dur=%.2f, bounce;dur=%.2f, gather;dur=%.2f, "
           "encode;dur=%.2f, total;dur=%.2f",
           t->voxelize, t->inject, t->filter, t->bounce, t->gather, t->encode, total_ms);
}

void gi_proto_server_timing_layout(double layout_ms, const gi_timings *t, double total_ms, char *buf, size_t size) {
  int n = snprintf(buf, size, "layout;dur=%.2f, ", layout_ms);
  if (n >= 0 && (size_t)n < size) gi_proto_server_timing(t, total_ms, buf + n, size - (size_t)n);
}

void gi_proto_effects_header(const gi_effect fx[GI_FX_COUNT], char *buf, size_t size) {
  size_t off = 0;
  buf[0] = 0;
  for (int i = 0; i < GI_FX_COUNT && off < size; i++) {
    int w = snprintf(buf + off, size - off, "%s%s=%s", i ? ", " : "", gi_effect_name((gi_effect_id)i),
                     fx[i].ran ? "ran" : "skipped");
    if (w < 0) break;
    off += (size_t)w;
  }
}
