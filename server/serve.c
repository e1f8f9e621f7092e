/* serve.c: a parsed request in, an encoded answer out (runs on workers).
 *
 * The core's writers write to a path: each answer is encoded into the
 * private work folder, read back into a reference-counted blob and
 * unlinked at once, so nothing stays on disk and no descriptor stays open
 * whatever the client does; the blob counts in the memory budget until
 * the client has read it. An answer that is the same bytes for everyone
 * (a cascade's VDB, a cell's probe or panorama: no timings in them) is
 * gathered and encoded once and kept in the cache (gs_cache_answer,
 * counted in the budget): identical requests at the same time wait for
 * that one encode, later ones stream the same bytes. A viewpoint's own
 * answer (a probe list, a session's lighting) carries its timings and is
 * encoded per request.
 *
 * Probe lists are split into tiles: the points a single cascade answers
 * from its finest level. Each tile's cascade is anchored at the tile's
 * centre, so neighbouring requests share cascades through the cache. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <stddef.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include "server.h"

double gs_now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

void gs_tmp_path(gs_service *svc, const char *ext, char *buf, size_t size) {
  unsigned long n = atomic_fetch_add(&svc->tmp_counter, 1);
  /* The private folder (jobs.c, mode 0700) once it exists; made again when
   * something removed it (a /tmp cleaner), or every answer written through
   * it would fail until a restart. Normally one mkdir failing with EEXIST. */
  if (svc->work_dir[0] && mkdir(svc->work_dir, 0700) == 0)
    fprintf(stderr, "gi-server: %s had been removed: made again\n", svc->work_dir);
  snprintf(buf, size, "%s/gi-server-%ld-%lu%s", svc->work_dir[0] ? svc->work_dir : svc->cfg->tmp_dir, (long)getpid(),
           n, ext);
}

int gs_status_of(gi_result rc) {
  switch (rc) {
  case GI_ERR_INVALID_ARG:
  case GI_ERR_NONFINITE:
  case GI_ERR_EMPTY: return 400;
  case GI_ERR_LIMIT: return 413;
  case GI_ERR_NOMEM: return 503;
  case GI_ERR_CANCELLED: return 504;
  default: return 500;
  }
}

/* Jobs wait this long for room in the memory budget before they fail. */
#define GS_JOB_ADMIT_WAIT_MS 30000
#define GS_JOB_ADMIT_POLL_MS 100

void gs_blob_retain(gs_blob *b) { atomic_fetch_add(&b->refs, 1); }

void gs_blob_release(gs_blob *b) {
  if (!b || atomic_fetch_sub(&b->refs, 1) != 1) return;
  if (b->sending) gs_cache_unsend(b->sending, b->size);
  free(b);
}

void gs_blob_release_data(void *data) {
  gs_blob_release((gs_blob *)((unsigned char *)data - offsetof(gs_blob, data)));
}

gs_blob *gs_blob_take_file(const char *path, gi_error_info *err) {
  int fd = open(path, O_RDONLY | O_CLOEXEC);
  struct stat st;
  gs_blob *b = NULL;
  if (fd >= 0 && fstat(fd, &st) == 0 && (b = malloc(sizeof *b + (size_t)st.st_size + 1))) {
    atomic_init(&b->refs, 1);
    b->sending = NULL;
    b->size = (size_t)st.st_size;
    size_t got = 0;
    while (got < b->size) {
      ssize_t n = read(fd, b->data + got, b->size - got);
      if (n <= 0 && !(n < 0 && errno == EINTR)) break;
      if (n > 0) got += (size_t)n;
    }
    if (got < b->size) {
      free(b);
      b = NULL;
    }
  }
  int saved = errno;
  if (fd >= 0) close(fd);
  unlink(path);
  if (!b && err) snprintf(err->msg, sizeof err->msg, "encode: cannot read the encoded file back: %s", strerror(saved));
  return b;
}

void gs_answer_error(gs_answer *a, const gi_proto_error *e) {
  free(a->json);
  gs_blob_release(a->blob);
  a->blob = NULL;
  if (a->fd >= 0) close(a->fd);
  a->fd = -1;
  a->status = e->status;
  a->json = gi_proto_error_json(e);
  a->content_type = "application/json";
}

void gs_answer_free(gs_answer *a) {
  free(a->json);
  a->json = NULL;
  gs_blob_release(a->blob);
  a->blob = NULL;
  if (a->fd >= 0) close(a->fd);
  a->fd = -1;
}

const char *gs_client_message(gi_result rc, const gi_error_info *e, char *buf, size_t size) {
  const char *msg = e->msg[0] ? e->msg : gi_strerror(rc);
  if (rc != GI_ERR_IO) return msg;
  /* An answer's file in the private folder (a full disk): its path stays in
   * the log; the client learns the OS reason only, when the message has one. */
  fprintf(stderr, "gi-server: %s\n", msg);
  char reason[128];
  for (int n = 1; n < 256; n++) {
    if (strerror_r(n, reason, sizeof reason) == 0 && strncmp(reason, "Unknown error", 13) && strstr(msg, reason)) {
      snprintf(buf, size, "could not write the answer: %s", reason);
      return buf;
    }
  }
  snprintf(buf, size, "could not write the answer");
  return buf;
}

void gs_answer_core_error(gs_answer *a, gi_result rc, const gi_error_info *e) {
  gi_proto_error pe;
  char msg[256];
  gi_proto_fail(&pe, gs_status_of(rc), "%s", gs_client_message(rc, e, msg, sizeof msg));
  gs_answer_error(a, &pe);
}

gi_result gs_answer_take_file(gs_service *svc, gs_answer *a, const char *path, const char *type, gi_error_info *e) {
  gs_blob *b = gs_blob_take_file(path, e);
  if (!b) return GI_ERR_IO;
  /* Its bytes live until the client has read them (a slow reader: minutes):
   * they count in the budget meanwhile, or thirty slow readers of a 13 MB
   * panorama held 470 MB outside it. */
  gi_result rc = gs_cache_admit_sending(svc->cache, b, e);
  if (rc != GI_OK) {
    gs_blob_release(b);
    return rc;
  }
  a->status = 200;
  a->blob = b;
  a->size = b->size;
  a->content_type = type;
  return GI_OK;
}

/* The cascade's VDB, encoded now (the caller keeps it: gs_cache_answer). */
static gi_result cascade_vdb(gs_service *svc, gs_entry *ent, int faces, gs_answer *a, gi_error_info *e) {
  /* The encode's dense copies count against the memory budget as a
   * bake does (235 MB at 8 levels of 64^3 with faces: past the RSS
   * bound when the cache was full). */
  size_t need = gi_cascade_vdb_bytes_estimate(gs_entry_cascade(ent), faces);
  gi_result rc = gs_cache_reserve(svc->cache, need, "this VDB's encode", e);
  if (rc != GI_OK) return rc;
  char path[1200];
  gs_tmp_path(svc, ".vdb", path, sizeof path);
  rc = gi_cascade_write_vdb(gs_entry_cascade(ent), path, faces, e);
  gs_cache_unreserve(svc->cache, need);
  if (rc != GI_OK) {
    unlink(path);
    return rc;
  }
  gs_blob *b = gs_blob_take_file(path, e);
  if (!b) return GI_ERR_IO;
  if (gs_vdb_stable_uuid(b) != 0) {
    gs_blob_release(b);
    snprintf(e->msg, sizeof e->msg, "encode: the VDB writer's header is not the expected one");
    return GI_ERR_IO;
  }
  a->status = 200;
  a->blob = b;
  a->size = b->size;
  return GI_OK;
}

/* The shape of an answer that is the same bytes for every request naming
 * it, for gs_cache_answer: a cascade's VDB, or a cell's probe or panorama
 * (answer_extras: no timings in it), with every parameter that shapes the
 * bytes beyond its cascade. 0 for any other answer. */
static int answer_shape(gs_endpoint ep, const gi_proto_bake *b, char *buf, size_t size) {
  if (ep == GS_EP_CASCADES) {
    snprintf(buf, size, "vdb faces=%d", b->faces ? 1 : 0);
    return 1;
  }
  if (ep != GS_EP_LIGHTING || !b->cell || (b->kind != GI_PROTO_PROBE && b->kind != GI_PROTO_PANORAMA)) return 0;
  int pano = b->kind == GI_PROTO_PANORAMA;
  /* %a: the point exactly (a cell's centre, so the same for every request). */
  int n = snprintf(buf, size, "%s half=%d %dx%d at=%a,%a,%a", pano ? "panorama" : "probe", b->half ? 1 : 0,
                   pano ? b->width : 1, pano ? b->height : 1, b->at[0], b->at[1], b->at[2]);
  return n > 0 && (size_t)n < size; /* a cut shape could name another answer: not kept */
}

static const char *const cache_names[3] = {"hit", "miss", "coalesced"};

/* The request's quality as the core takes it (zero = auto, the server's
 * thread count) into *req, and its resolution into the return value. */
gi_quality gs_resolve_request(gs_service *svc, const gs_scene *s, const gi_quality *in, gi_quality *req,
                              gi_error_info *e, gi_result *rc) {
  *req = *in;
  req->threads = svc->cfg->bake_threads;
  gi_quality out;
  *rc = gi_quality_resolve(s->scene, req, &out, e);
  return out;
}

/* Timings of this answer: the stages it ran itself (a cache hit baked nothing). */
static void finish_headers(gs_answer *a, const gi_bake_report *rep, const gi_timings *ms, const char *cache,
                           double t_start_ms) {
  gi_proto_server_timing(ms, gs_now_ms() - t_start_ms, a->server_timing, sizeof a->server_timing);
  gi_proto_effects_header(rep->effects, a->effects, sizeof a->effects);
  a->cache = cache;
}

/* A cell's answer is the same bytes whoever asks and whenever (its ETag
 * says so): its EXR carries no timings or cache outcome, which stay in
 * the headers. A viewpoint's own answer (POST probes) keeps them. */
static size_t answer_extras(const gi_proto_bake *b) { return b->cell ? 0 : 2; }

/* The probe or panorama at b->at from cascade c: the lighting answer, for
 * the scene's lighting URLs and for sessions alike. ms holds the stages
 * already run (a bake's or a move's); gather and encode are added. The
 * gather stops on cancel. */
gi_result gs_answer_lighting(gs_service *svc, const gs_scene *s, const gi_cascade *c, const gi_proto_bake *b,
                             const gi_cancel *cancel, const char *cache, gi_timings *ms, double t_start_ms,
                             gs_answer *a, gi_error_info *e) {
  const gi_bake_report *rep = gi_cascade_report(c);
  char path[1200], timing[320];
  double t0;
  gi_result rc;
  if (b->kind == GI_PROTO_PANORAMA) {
    size_t n = 3 * (size_t)b->width * (size_t)b->height;
    float *dir = malloc(n * sizeof(float)), *ind = malloc(n * sizeof(float));
    if (!dir || !ind) {
      rc = GI_ERR_NOMEM;
      snprintf(e->msg, sizeof e->msg, "panorama: out of memory for %dx%d", b->width, b->height);
    } else {
      rc = gi_cascade_panorama_ex(c, b->at, b->width, b->height, cancel, dir, ind, &ms->gather, e);
    }
    if (rc == GI_OK) {
      gi_proto_server_timing(ms, gs_now_ms() - t_start_ms, timing, sizeof timing);
      gi_exr_extra extra[] = {{"gi.timings", timing}, {"gi.cache", cache}};
      gs_tmp_path(svc, ".exr", path, sizeof path);
      t0 = gs_now_ms();
      rc = gi_panorama_write_exr(path, b->width, b->height, dir, ind, s->scene, b->at, rep, b->half, extra,
                                 answer_extras(b), e);
      ms->encode = gs_now_ms() - t0;
      if (rc == GI_OK) rc = gs_answer_take_file(svc, a, path, "image/x-exr", e);
    }
    free(dir);
    free(ind);
  } else {
    gi_probe pr;
    rc = gi_cascade_gather_ex(c, b->at, 1, cancel, &pr, &ms->gather, e);
    if (rc == GI_OK) {
      gi_proto_server_timing(ms, gs_now_ms() - t_start_ms, timing, sizeof timing);
      gi_exr_extra extra[] = {{"gi.timings", timing}, {"gi.cache", cache}};
      gs_tmp_path(svc, ".exr", path, sizeof path);
      t0 = gs_now_ms();
      rc = gi_probes_write_exr_ex(path, &pr, 1, s->scene, b->at, rep, b->half, extra, answer_extras(b), e);
      ms->encode = gs_now_ms() - t0;
      if (rc == GI_OK) rc = gs_answer_take_file(svc, a, path, "image/x-exr", e);
    }
  }
  if (rc == GI_OK) finish_headers(a, rep, ms, cache, t_start_ms);
  return rc;
}

int gs_serve_join_running(gs_service *svc, const gs_scene *s, gs_endpoint ep, const gi_proto_bake *b, gs_waiter *w) {
  if ((ep != GS_EP_LIGHTING && ep != GS_EP_CASCADES) || (ep == GS_EP_LIGHTING && b->kind == GI_PROTO_LIGHTMAP))
    return 0;
  gi_error_info e = {0};
  gi_result rc;
  gi_quality req, q = gs_resolve_request(svc, s, &b->quality, &req, &e, &rc);
  char shape[256];
  int kept = answer_shape(ep, b, shape, sizeof shape);
  return rc == GI_OK && gs_cache_join_running(svc->cache, s, b->at, &req, &q, kept ? shape : NULL, w);
}

void gs_serve_bake(gs_service *svc, const gs_scene *s, gs_endpoint ep, const gi_proto_bake *b, double t_start_ms,
                   gs_waiter *w, const gi_cancel *cancel, gs_answer *a) {
  if (ep == GS_EP_LIGHTMAP_UV || (ep == GS_EP_LIGHTING && b->kind == GI_PROTO_LIGHTMAP))
    return gs_serve_lightmap(svc, s, ep, b, t_start_ms, cancel, a);
  gi_error_info e = {0};
  gi_result rc;
  gi_quality req, q = gs_resolve_request(svc, s, &b->quality, &req, &e, &rc);
  if (rc != GI_OK) return gs_answer_core_error(a, rc, &e);
  gs_entry *ent = NULL;
  gs_cache_how how;
  rc = gs_cache_get(svc->cache, s, b->at, &req, &q, w, &ent, &how, &e);
  if (rc == GS_PENDING) return; /* no answer yet: w is woken when the bake ends */
  if (rc != GI_OK) return gs_answer_core_error(a, rc, &e);
  const gi_cascade *c = gs_entry_cascade(ent);
  const gi_bake_report *rep = gi_cascade_report(c);
  gi_timings ms = {0};
  if (how == GS_CACHE_MISS) ms = rep->ms;
  /* The same bytes for everyone: kept, being encoded by another request
   * (wait for it), or encoded here for all who ask meanwhile. */
  char shape[256];
  gs_blob *kept = NULL;
  gs_entry *job = NULL;
  if (answer_shape(ep, b, shape, sizeof shape)) {
    rc = gs_cache_answer(svc->cache, ent, shape, w, &kept, &job, &e);
    if (rc == GS_PENDING) return; /* w holds ent now, and is woken when the encode ends */
    /* A shared gather stops when every request waiting for it has left, not when this one does. */
    if (job) cancel = gs_entry_cancel(job);
  }
  if (rc == GI_OK && kept) {
    a->status = 200;
    a->blob = kept;
    a->size = kept->size;
  } else if (rc == GI_OK && ep == GS_EP_CASCADES) {
    double t0 = gs_now_ms();
    rc = cascade_vdb(svc, ent, b->faces, a, &e);
    ms.encode = gs_now_ms() - t0;
  } else if (rc == GI_OK) {
    rc = gs_answer_lighting(svc, s, c, b, cancel, cache_names[how], &ms, t_start_ms, a, &e);
  }
  if (job) gs_cache_answer_done(svc->cache, job, w, rc, rc == GI_OK ? a->blob : NULL, &e);
  if (rc == GI_OK) {
    a->content_type = ep == GS_EP_CASCADES ? "application/octet-stream" : "image/x-exr";
    if (ep == GS_EP_CASCADES)
      snprintf(a->disposition, sizeof a->disposition, "attachment; filename=\"%s-cascades.vdb\"", s->id);
    finish_headers(a, rep, &ms, cache_names[how], t_start_ms);
  } else {
    gs_answer_core_error(a, rc, &e);
  }
  gs_cache_release(svc->cache, ent);
}

/* ---- tiles -------------------------------------------------------------- */

typedef struct {
  int64_t t[3];
  size_t i;
} tile_key;

/* Tile indices stay well inside int64_t (2^62). */
#define GS_MAX_TILE_INDEX 4.6e18

static int cmp_tile(const void *a, const void *b) {
  const tile_key *x = a, *y = b;
  for (int k = 0; k < 3; k++)
    if (x->t[k] != y->t[k]) return x->t[k] < y->t[k] ? -1 : 1;
  return x->i < y->i ? -1 : x->i > y->i;
}

int gs_tiles_make(const gs_scene *s, const gi_quality *q, const double *pts, size_t n, gs_tile **out,
                  size_t *num_tiles) {
  /* -1: out of memory; -2: a point too far to index its tile. */
  (void)s;
  *out = NULL;
  *num_tiles = 0;
  /* A tile of side T around its centre stays inside level 0's window (which
   * reaches at least (R/2 - 2) s0 from the snapped centre) with the one-voxel
   * border cones need: T/2 <= (R/2 - 3) s0. */
  double T = (double)(q->res / 2 - 4 > 2 ? q->res / 2 - 4 : 2) * q->voxel0;
  tile_key *k = malloc((n ? n : 1) * sizeof *k);
  if (!k) return -1;
  for (size_t i = 0; i < n; i++) {
    for (int a = 0; a < 3; a++) {
      /* Converting a double beyond int64 is undefined: such a point has no tile. */
      double t = floor(pts[3 * i + a] / T);
      if (!(fabs(t) < GS_MAX_TILE_INDEX)) {
        free(k);
        return -2;
      }
      k[i].t[a] = (int64_t)t;
    }
    k[i].i = i;
  }
  qsort(k, n, sizeof *k, cmp_tile);
  size_t nt = 0;
  for (size_t i = 0; i < n; i++)
    if (i == 0 || memcmp(k[i].t, k[i - 1].t, sizeof k[i].t)) nt++;
  gs_tile *t = calloc(nt ? nt : 1, sizeof *t);
  size_t *idx = malloc((n ? n : 1) * sizeof *idx);
  if (!t || !idx) {
    free(t);
    free(idx);
    free(k);
    return -1;
  }
  size_t j = (size_t)-1;
  for (size_t i = 0; i < n; i++) {
    if (i == 0 || memcmp(k[i].t, k[i - 1].t, sizeof k[i].t)) {
      j++;
      for (int a = 0; a < 3; a++) t[j].at[a] = ((double)k[i].t[a] + 0.5) * T;
      t[j].idx = idx + i;
    }
    idx[i] = k[i].i;
    t[j].n++;
  }
  free(k);
  *out = t;
  *num_tiles = nt;
  return 0;
}

void gs_tiles_free(gs_tile *t, size_t n) {
  (void)n;
  if (t) free(t[0].idx); /* one block for all tiles' indices */
  free(t);
}

int gs_tile_around(const double at[3], size_t n, gs_tile **out, size_t *num_tiles) {
  gs_tile *t = malloc(sizeof *t);
  size_t *idx = malloc((n ? n : 1) * sizeof *idx);
  *out = NULL, *num_tiles = 0;
  if (!t || !idx) {
    free(t), free(idx);
    return -1;
  }
  for (size_t i = 0; i < n; i++) idx[i] = i;
  memcpy(t->at, at, sizeof t->at);
  t->idx = idx, t->n = n;
  *out = t, *num_tiles = 1;
  return 0;
}

/* A job's bakes wait for room in the budget (interactive bakes finish in
 * seconds) rather than fail at the first busy moment; a cancelled job (or
 * one past its deadline) stops waiting at once, not after the whole wait. */
static gi_result reserve_waiting(gs_service *svc, size_t need, const gi_cancel *cancel, gi_error_info *err) {
  double t0 = gs_now_ms();
  gi_result rc;
  while ((rc = gs_cache_reserve(svc->cache, need, "this job's bake", err)) == GI_ERR_NOMEM &&
         gs_now_ms() - t0 < GS_JOB_ADMIT_WAIT_MS) {
    if (gi_cancel_check(cancel) != GI_CANCEL_NONE) {
      snprintf(err->msg, sizeof err->msg, "probes: stopped while waiting for room in the memory budget");
      return GI_ERR_CANCELLED;
    }
    struct timespec ts = {0, GS_JOB_ADMIT_POLL_MS * 1000000L};
    nanosleep(&ts, NULL);
  }
  return rc;
}

gi_result gs_gather_tiles(gs_service *svc, const gs_scene *s, const gi_quality *req, const gi_quality *q,
                          const double *pts, const gs_tile *tiles, size_t num_tiles, int use_cache,
                          gs_waiter *w, const gi_cancel *cancel, gi_probe *out,
                          gi_bake_report *rep, gi_timings *ms, gs_cache_how *how_out,
                          int (*progress)(void *ctx, size_t tile, size_t probes, gi_error_info *err), void *ctx,
                          gi_error_info *err) {
  size_t maxn = 0;
  for (size_t t = 0; t < num_tiles; t++) maxn = tiles[t].n > maxn ? tiles[t].n : maxn;
  double *tp = malloc(3 * (maxn ? maxn : 1) * sizeof *tp);
  gi_probe *tr = malloc((maxn ? maxn : 1) * sizeof *tr);
  if (!tp || !tr) {
    free(tp);
    free(tr);
    snprintf(err->msg, sizeof err->msg, "probes: out of memory");
    return GI_ERR_NOMEM;
  }
  /* Private bakes run one at a time: one reservation covers them all. */
  size_t need = 0;
  gi_result rc = GI_OK;
  if (!use_cache) {
    need = gs_bake_bytes(q);
    if ((rc = reserve_waiting(svc, need, cancel, err)) != GI_OK) need = 0;
  }
  if (how_out) *how_out = GS_CACHE_HIT;
  for (size_t t = 0; t < num_tiles && rc == GI_OK; t++) {
    const gs_tile *tl = &tiles[t];
    gs_entry *ent = NULL;
    gi_cascade *own = NULL;
    const gi_cascade *c;
    gs_cache_how how = GS_CACHE_MISS;
    if (use_cache) {
      if ((rc = gs_cache_get(svc->cache, s, tl->at, req, q, w, &ent, &how, err)) != GI_OK) break;
      c = gs_entry_cascade(ent);
    } else {
      /* A job's bake is a bake like any other in /metrics (it was missing from the gauge). */
      double t0 = gs_now_ms();
      gs_metrics_bake_begin(svc->metrics);
      rc = gi_cascade_bake_ex(s->scene, tl->at, req, cancel, &own, NULL, err);
      gs_metrics_bake_end(svc->metrics, 0);
      if (rc != GI_OK) break;
      gs_metrics_bake(svc->metrics, (gs_now_ms() - t0) * 1e-3);
      c = own;
    }
    const gi_bake_report *r = gi_cascade_report(c);
    if (t == 0 && rep) *rep = *r;
    if (how == GS_CACHE_MISS && ms) {
      ms->voxelize += r->ms.voxelize;
      ms->inject += r->ms.inject;
      ms->filter += r->ms.filter;
      ms->bounce += r->ms.bounce;
    }
    if (how_out && how != GS_CACHE_HIT) *how_out = how;
    for (size_t i = 0; i < tl->n; i++) memcpy(&tp[3 * i], &pts[3 * tl->idx[i]], 3 * sizeof(double));
    double g = 0;
    rc = gi_cascade_gather_ex(c, tp, tl->n, cancel, tr, &g, err);
    if (ms) ms->gather += g;
    if (rc == GI_OK)
      for (size_t i = 0; i < tl->n; i++) out[tl->idx[i]] = tr[i];
    if (ent) gs_cache_release(svc->cache, ent);
    gi_cascade_free(own);
    /* Between tiles: the caller may stop here (job cancelled or past its deadline). */
    if (rc == GI_OK && progress && progress(ctx, t, tl->n, err) && t + 1 < num_tiles) rc = GI_ERR_LIMIT;
  }
  if (need) gs_cache_unreserve(svc->cache, need);
  free(tp);
  free(tr);
  return rc;
}

/* With 'at', every point must lie within the one cascade around it: a
 * point outside got direct light only, its indirect light 0, with a 200
 * (the Cornell box's probes asked from its camera). Asked of the placement
 * the bake will make (gi_cascade_would_cover): the coarse levels lean
 * toward the scene, so a distance from 'at' does not say. 1 and a 400
 * naming the first point beyond it (or a 503/400 when the question
 * itself fails), 0 when all are inside. */
static int beyond_reach(const gs_scene *s, const gi_proto_probes *p, const gi_quality *q, gi_proto_error *pe) {
  size_t n = p->num_points, held = 0;
  uint8_t *in = malloc(n ? n : 1);
  gi_error_info e = {0};
  if (!in) {
    gi_proto_fail(pe, 503, "probes: out of memory for %zu points", n);
    return 1;
  }
  gi_result rc = gi_cascade_would_cover(s->scene, p->bake.at, q, p->points, n, in, &held, &e);
  if (rc != GI_OK) {
    free(in);
    gi_proto_fail(pe, rc == GI_ERR_NOMEM ? 503 : 400, "body: 'at': %s", e.msg);
    return 1;
  }
  for (size_t i = 0; held < n && i < n; i++) {
    if (in[i]) continue;
    const double *x = &p->points[3 * i];
    double d = 0;
    for (int k = 0; k < 3; k++) d = fmax(d, fabs(x[k] - p->bake.at[k]));
    gi_proto_fail(pe, 400,
                  "body: points[%zu] (%g, %g, %g) lies outside the cascade baked around 'at' (%g units from it "
                  "along an axis; %d levels, coarsest voxel %g): its indirect light would be 0; leave 'at' out "
                  "(the server places cascades around the points) or ask for more levels", i, x[0], x[1], x[2], d,
                  q->levels, ldexp(q->voxel0, q->levels - 1));
    break;
  }
  free(in);
  return held < n;
}

void gs_serve_probes(gs_service *svc, const gs_scene *s, gi_proto_probes *p, double t_start_ms, gs_waiter *w,
                     const gi_cancel *cancel, gs_answer *a) {
  gi_error_info e = {0};
  gi_result rc;
  gi_quality req, q = gs_resolve_request(svc, s, &p->bake.quality, &req, &e, &rc);
  if (rc != GI_OK) {
    gi_proto_probes_free(p);
    return gs_answer_core_error(a, rc, &e);
  }
  gs_tile *tiles = NULL;
  size_t nt = 0;
  int far = 0;
  gi_proto_error pe;
  if (p->bake.has_at && beyond_reach(s, p, &q, &pe)) {
    gs_answer_error(a, &pe);
    gi_proto_probes_free(p);
    return;
  }
  if (p->bake.has_at) gs_tile_around(p->bake.at, p->num_points, &tiles, &nt); /* the client chose one cascade */
  else if ((far = gs_tiles_make(s, &q, p->points, p->num_points, &tiles, &nt) == -2) || !tiles) nt = 0;
  if (nt == 0) {
    if (far) gi_proto_fail(&pe, 400, "body: points: a point is too far from the scene for voxels of %g", q.voxel0);
    else gi_proto_fail(&pe, 503, "probes: out of memory for %zu points", p->num_points);
    gs_answer_error(a, &pe);
    gi_proto_probes_free(p);
    return;
  }
  if (p->num_points > svc->cfg->lim.max_probes_inline || nt > (size_t)svc->cfg->max_tiles_inline) {
    /* Too much for one answer: a job, polled at /v1/jobs/{id}. */
    gs_tiles_free(tiles, nt);
    char id[40];
    gi_proto_error pe;
    size_t n = p->num_points, need = gs_bake_bytes(&q), budget = svc->cfg->cache_bytes;
    /* A bake larger than the whole budget never runs: 413 now, as for a short
     * list, not a 202 for a job that can only fail. */
    if (budget && need > budget) {
      gi_proto_fail(&pe, 413, "memory: this bake needs about %zu MiB, more than the whole budget (%zu MiB)",
                    need >> 20, budget >> 20);
      gi_proto_probes_free(p);
      gs_answer_error(a, &pe);
      return;
    }
    if (gs_jobs_submit(svc->jobs, s, p, &req, &q, id, &pe) != 0) {
      gi_proto_probes_free(p);
      gs_answer_error(a, &pe);
      return;
    }
    gi_proto_job j = {.state = GI_JOB_QUEUED, .probes = n};
    snprintf(j.id, sizeof j.id, "%s", id);
    a->status = 202;
    a->json = gi_proto_job_json(&j);
    a->content_type = "application/json";
    snprintf(a->location, sizeof a->location, "/v1/jobs/%s", id);
    return;
  }
  gi_probe *pr = malloc(p->num_points * sizeof *pr);
  gi_bake_report rep;
  gi_timings ms = {0};
  gs_cache_how how = GS_CACHE_HIT;
  if (!pr) {
    rc = GI_ERR_NOMEM;
    snprintf(e.msg, sizeof e.msg, "probes: out of memory");
  } else {
    rc = gs_gather_tiles(svc, s, &req, &q, p->points, tiles, nt, 1, w, cancel, pr, &rep, &ms, &how,
                         NULL, NULL, &e);
  }
  if (rc == GI_OK) {
    char path[1200], timing[320], ntiles[32];
    gi_proto_server_timing(&ms, gs_now_ms() - t_start_ms, timing, sizeof timing);
    snprintf(ntiles, sizeof ntiles, "%zu", nt);
    gi_exr_extra extra[] = {{"gi.timings", timing}, {"gi.cache", cache_names[how]}, {"gi.tiles", ntiles}};
    gs_tmp_path(svc, ".exr", path, sizeof path);
    double t0 = gs_now_ms();
    const double *vp = tiles[0].at; /* 'at' itself when given */
    rc = gi_probes_write_exr_ex(path, pr, p->num_points, s->scene, vp, &rep, p->bake.half, extra, 3, &e);
    ms.encode = gs_now_ms() - t0;
    if (rc == GI_OK && (rc = gs_answer_take_file(svc, a, path, "image/x-exr", &e)) == GI_OK)
      finish_headers(a, &rep, &ms, cache_names[how], t_start_ms);
  }
  if (rc != GI_OK) gs_answer_core_error(a, rc, &e);
  free(pr);
  gs_tiles_free(tiles, nt);
  gi_proto_probes_free(p);
}
