/* canonical.c: cell-addressed, cacheable URLs (issue 14).
 *
 * A cascade depends on the scene, the anchor cell of the viewpoint
 * (gi_cascade_anchor) and the quality, nothing else. So an answer for a
 * cell is a resource that never changes: it gets a URL naming the cell
 * and a hash of everything else (q), is answered as immutable with a
 * strong ETag, and every cache in front (nginx) may keep it. A viewpoint
 * URL redirects to it.
 *
 * q hashes the scene's version (its file's bytes, or the city's
 * parameters), the quality knobs the request set (in canonical form,
 * carried in the URL so any replica can bake from it) and the server's
 * build (its bytes carry it). A scene file that changes gives a new q, so
 * no cache ever serves the old answer under the new URL.
 *
 * Lightmaps (issue 13) hook in here: kind=lightmap is parsed for cell URLs
 * already (501 until it exists). Its answer is a cell answer like the
 * others: gs_canon_url names it by kind, and the parameters that shape it
 * (region, texel, atlas) must be appended in gs_canon_url in one fixed
 * order and hashed into gs_canon_etag's shape, and its EXR must carry no
 * timings (answer_extras in serve.c); the UV glTF gets a sibling cell URL
 * (.../cells/{i},{j},{k}/lightmap-uv.glb) the same way. */
#define _POSIX_C_SOURCE 200809L
#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "server.h"
#include "gi_git_rev.h" /* GI_GIT_REV: generated at build time (cmake/git_rev.cmake) */

#define FNV_OFFSET 0xcbf29ce484222325ull
#define FNV_PRIME 0x100000001b3ull

uint64_t gs_hash_bytes(uint64_t h, const void *data, size_t n) {
  const unsigned char *p = data;
  for (size_t i = 0; i < n; i++) h = (h ^ p[i]) * FNV_PRIME;
  return h;
}

static uint64_t hash_str(uint64_t h, const char *s) { return gs_hash_bytes(h, s, strlen(s) + 1); }

int gs_scene_version(const gs_scene_conf *sc, uint64_t *out, char *err, size_t errsize) {
  char params[256];
  /* How the scene is built from its bytes is part of its version. */
  snprintf(params, sizeof params, "city=%d extent=%.17g seed=%" PRIu64 " detail=%d up=%d", sc->is_city,
           sc->is_city ? sc->extent : 0.0, sc->is_city ? sc->seed : 0, sc->is_city ? sc->detail : 0,
           (int)(sc->up ? sc->up : GI_UP_Y)); /* not given is y */
  uint64_t h = hash_str(FNV_OFFSET, params);
  if (!sc->is_city) {
    FILE *f = fopen(sc->source, "rb");
    if (!f) {
      snprintf(err, errsize, "scene version: cannot read %s", sc->source);
      return -1;
    }
    unsigned char buf[1 << 16];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, f)) > 0) h = gs_hash_bytes(h, buf, n);
    int bad = ferror(f);
    fclose(f);
    if (bad) {
      snprintf(err, errsize, "scene version: read error on %s", sc->source);
      return -1;
    }
  }
  *out = h;
  return 0;
}

/* Appends "&key=value" (no '&' when buf is empty). */
static void knob(char *buf, size_t size, const char *key, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
static void knob(char *buf, size_t size, const char *key, const char *fmt, ...) {
  size_t n = strlen(buf);
  if (n + 1 >= size) return;
  int w = snprintf(buf + n, size - n, "%s%s=", n ? "&" : "", key);
  if (w < 0 || (size_t)w >= size - n) return;
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(buf + n + (size_t)w, size - n - (size_t)w, fmt, ap);
  va_end(ap);
}

/* The request's knobs in one fixed order and a form that parses back to
 * the same gi_quality bit for bit (%.17g doubles, %.9g floats). */
static void canonical_knobs(const gi_quality *q, char *buf, size_t size) {
  buf[0] = 0;
  if (q->levels) knob(buf, size, "levels", "%d", q->levels);
  if (q->res) knob(buf, size, "res", "%d", q->res);
  if (q->voxel0 > 0) knob(buf, size, "voxel", "%.17g", q->voxel0);
  if (q->cones) knob(buf, size, "cones", "%d", q->cones);
  if (q->aperture_deg > 0) knob(buf, size, "aperture", "%.9g", (double)q->aperture_deg);
  if (q->step > 0) knob(buf, size, "step", "%.9g", (double)q->step);
  if (q->bounces) knob(buf, size, "bounces", "%d", q->bounces < 0 ? 0 : q->bounces);
  if (q->light_samples) knob(buf, size, "samples", "%d", q->light_samples);
  if (q->probe_samples) knob(buf, size, "probe_samples", "%d", q->probe_samples);
  if (q->ao) knob(buf, size, "ao", "1");
  if (q->seed) knob(buf, size, "seed", "%" PRIu64, q->seed);
  char fx[256] = "";
  for (int i = 0; i < GI_FX_COUNT; i++) {
    int m = q->effects[i];
    if (m == GI_FX_AUTO) continue;
    size_t n = strlen(fx);
    snprintf(fx + n, sizeof fx - n, "%s%s:%s", n ? "," : "", gi_effect_name((gi_effect_id)i),
             m == GI_FX_ON ? "on" : "off");
  }
  if (fx[0]) knob(buf, size, "effects", "%s", fx);
}

/* Whether two resolved qualities bake the same cascade: every field the
 * bake reads (padding aside, so not memcmp). */
static int same_resolved(const gi_quality *a, const gi_quality *b) {
  return a->levels == b->levels && a->res == b->res && a->voxel0 == b->voxel0 && a->cones == b->cones &&
         a->aperture_deg == b->aperture_deg && a->step == b->step && a->bounces == b->bounces &&
         a->light_samples == b->light_samples && a->probe_samples == b->probe_samples &&
         a->ao_lambda == b->ao_lambda && a->ao == b->ao && a->specular == b->specular && a->threads == b->threads &&
         a->seed == b->seed && !memcmp(a->effects, b->effects, sizeof a->effects);
}

/* Knobs a request set to what the core would choose anyway, cleared in
 * *q: levels=6 or seed=1 alone gave another q, another ETag and another
 * cache entry for the same bytes. A knob is cleared only when the quality
 * without it resolves to the same one, field for field, for this scene
 * (explicit levels=6 is not the default on a scene wide enough to get
 * more levels). Not bounces, whose default is the plan's choice at the
 * viewpoint (bounces=4 is not "auto" though auto may pick 4), nor
 * aperture, which the bake derives from the cone count. */
static void drop_defaults(const gi_scene *scene, const gi_quality *resolved, gi_quality *q) {
  gi_quality t, r;
  for (int k = 0; k < 8; k++) {
    t = *q;
    switch (k) {
    case 0: t.levels = 0; break;
    case 1: t.res = 0; break;
    case 2: t.voxel0 = 0; break;
    case 3: t.cones = 0; break;
    case 4: t.step = 0; break;
    case 5: t.light_samples = 0; break;
    case 6: t.probe_samples = 0; break;
    default: t.seed = 0; break;
    }
    if (!memcmp(&t, q, sizeof t)) continue; /* not set */
    if (gi_quality_resolve(scene, &t, &r, NULL) == GI_OK && same_resolved(&r, resolved)) *q = t;
  }
}

gi_result gs_canon_quality(const gs_service *svc, const gs_scene *s, const gi_quality *in, gs_canon *out,
                           gi_error_info *err) {
  memset(out, 0, sizeof *out);
  out->req = *in;
  out->req.threads = svc->cfg->bake_threads;
  gi_result rc = gi_quality_resolve(s->scene, &out->req, &out->resolved, err);
  if (rc != GI_OK) return rc;
  gi_quality canon = out->req;
  drop_defaults(s->scene, &out->resolved, &canon);
  canonical_knobs(&canon, out->knobs, sizeof out->knobs);
  uint64_t h = gs_hash_bytes(FNV_OFFSET, &s->version, sizeof s->version);
  h = hash_str(h, out->knobs);
  h = hash_str(h, GI_VERSION " " GI_GIT_REV);
  snprintf(out->q, sizeof out->q, "%016" PRIx64, h);
  return GI_OK;
}

void gs_canon_url(const gs_scene *s, const gs_canon *c, const int64_t cell[3], gs_endpoint ep,
                  const gi_proto_bake *b, char *buf, size_t size) {
  static const char *const kinds[] = {"probe", "panorama", "lightmap"};
  int n = snprintf(buf, size, "/v1/scenes/%s/cells/%" PRId64 ",%" PRId64 ",%" PRId64 "/%s?q=%s", s->id, cell[0],
                   cell[1], cell[2], ep == GS_EP_CASCADES ? "cascades.vdb" : "lighting", c->q);
  if (n < 0 || (size_t)n >= size) return;
  char tail[512] = "";
  if (ep != GS_EP_CASCADES) knob(tail, sizeof tail, "kind", "%s", kinds[b->kind]);
  if (c->knobs[0]) snprintf(tail + strlen(tail), sizeof tail - strlen(tail), "%s%s", tail[0] ? "&" : "", c->knobs);
  if (ep == GS_EP_CASCADES && b->faces) knob(tail, sizeof tail, "faces", "1");
  if (ep != GS_EP_CASCADES && b->half) knob(tail, sizeof tail, "half", "1");
  if (ep != GS_EP_CASCADES && b->kind == GI_PROTO_PANORAMA) {
    knob(tail, sizeof tail, "width", "%d", b->width);
    knob(tail, sizeof tail, "height", "%d", b->height);
  }
  if (tail[0]) snprintf(buf + n, size - (size_t)n, "&%s", tail);
}

void gs_canon_etag(const gs_canon *c, const int64_t cell[3], gs_endpoint ep, const gi_proto_bake *b,
                   char *out, size_t size) {
  /* The effect plan is a function of the scene, the cell and the knobs
   * (effects= included), so these fix the bytes. */
  uint64_t h = hash_str(FNV_OFFSET, c->q);
  h = gs_hash_bytes(h, cell, 3 * sizeof cell[0]);
  int shape[6] = {ep == GS_EP_CASCADES, (int)b->kind, b->half, b->faces, b->width, b->height};
  if (ep == GS_EP_CASCADES) shape[1] = shape[2] = shape[4] = shape[5] = 0;
  else shape[3] = 0;
  if (ep != GS_EP_CASCADES && b->kind != GI_PROTO_PANORAMA) shape[4] = shape[5] = 0;
  h = gs_hash_bytes(h, shape, sizeof shape);
  snprintf(out, size, "\"%016" PRIx64 "\"", h);
}

int gs_etag_matches(const char *if_none_match, const char *etag) {
  if (!if_none_match) return 0;
  size_t n = strlen(etag);
  for (const char *p = if_none_match; *p;) {
    p += strspn(p, " \t,");
    if (*p == '*') return 1;
    if (!strncmp(p, "W/", 2)) p += 2; /* weak comparison, as If-None-Match asks */
    if (!strncmp(p, etag, n) && (p[n] == 0 || p[n] == ',' || p[n] == ' ' || p[n] == '\t')) return 1;
    p += strcspn(p, ",");
  }
  return 0;
}

json_t *gs_canon_grid_json(const gs_scene *s, const gs_canon *c) {
  double o[3];
  gi_scene_origin(s->scene, o);
  int64_t cell[3] = {0, 0, 0};
  gi_proto_bake probe = {.kind = GI_PROTO_PROBE}, vdb = {0};
  char lighting[640], cascades[640];
  gs_canon_url(s, c, cell, GS_EP_LIGHTING, &probe, lighting, sizeof lighting);
  gs_canon_url(s, c, cell, GS_EP_CASCADES, &vdb, cascades, sizeof cascades);
  /* Templates: the cell segment becomes {i},{j},{k}. */
  const char *seg = "/cells/0,0,0/";
  char tl[700], tc[700];
  char *p = strstr(lighting, seg), *r = strstr(cascades, seg);
  snprintf(tl, sizeof tl, "%.*s/cells/{i},{j},{k}/%s", p ? (int)(p - lighting) : 0, lighting, p ? p + strlen(seg) : "");
  snprintf(tc, sizeof tc, "%.*s/cells/{i},{j},{k}/%s", r ? (int)(r - cascades) : 0, cascades, r ? r + strlen(seg) : "");
  char ver[17];
  snprintf(ver, sizeof ver, "%016" PRIx64, s->version);
  return json_pack("{s:[f,f,f], s:f, s:f, s:s, s:s, s:s, s:s, s:s, s:s}", "origin", o[0], o[1], o[2], "voxel",
                   c->resolved.voxel0, "cell_size", 2.0 * c->resolved.voxel0, "snap",
                   "cell[a] = floor(float32(at[a] - origin[a]) / cell_size), float32 = IEEE single rounding",
                   "scene_version", ver, "q", c->q, "query", c->knobs, "lighting", tl, "cascades", tc);
}

/* OpenVDB's file header: magic (8 bytes), file version and library
 * version (3 x 4), the grid-offsets flag (1), then a random UUID as 36
 * characters, new at every write. */
#define VDB_UUID_AT 21
#define VDB_UUID_LEN 36

static int uuid_shaped(const unsigned char *u) {
  for (int i = 0; i < VDB_UUID_LEN; i++) {
    int dash = i == 8 || i == 13 || i == 18 || i == 23;
    if (dash ? u[i] != '-' : !((u[i] >= '0' && u[i] <= '9') || (u[i] >= 'a' && u[i] <= 'f'))) return 0;
  }
  return 1;
}

int gs_vdb_stable_uuid(gs_blob *b) {
  static const unsigned char magic[8] = {0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0};
  if (b->size < VDB_UUID_AT + VDB_UUID_LEN || memcmp(b->data, magic, sizeof magic) ||
      !uuid_shaped(b->data + VDB_UUID_AT))
    return -1;
  /* The UUID then names the content: a hash of every other byte. */
  uint64_t h1 = gs_hash_bytes(FNV_OFFSET, b->data, VDB_UUID_AT);
  h1 = gs_hash_bytes(h1, b->data + VDB_UUID_AT + VDB_UUID_LEN, b->size - VDB_UUID_AT - VDB_UUID_LEN);
  uint64_t h2 = gs_hash_bytes(h1, "uuid", 4);
  char u[VDB_UUID_LEN + 1];
  snprintf(u, sizeof u, "%08x-%04x-%04x-%04x-%012" PRIx64, (unsigned)(h1 >> 32), (unsigned)(h1 >> 16) & 0xffff,
           (unsigned)h1 & 0xffff, (unsigned)(h2 >> 48), (uint64_t)(h2 & 0xffffffffffffull));
  memcpy(b->data + VDB_UUID_AT, u, VDB_UUID_LEN);
  return 0;
}
