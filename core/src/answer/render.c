/* render.c: the final rendering step, a camera view shaded from the cascade.
 *
 * DESIGN. One primary ray per pixel (pixel centre) through Embree. At the
 * hit, surfaces are two-sided: the normal turns toward the camera. Direct
 * light comes from shadow rays with the bake's own light sampler and plan
 * (so a skipped effect stays skipped); indirect light from the bake's
 * diffuse cone set around the normal by the gather's surface rule (one
 * voxel of the finest level containing the point off the surface, coarse
 * levels kept off it: trace/gather.c), exactly as the voxel bounces
 * gather, at every stride-th pixel of every stride-th row (the anchors,
 * gathered first) and mixed between them where they lie on the pixel's
 * surface (see "indirect light at anchors" below), as is the sampled
 * lights' direct light (sky, emitters); the specular pass
 * (gi_cascade_view_plan decides whether it runs and where) adds one
 * specular cone along the mirror direction, weighted by the material's
 * specular reflectance.
 * Rows run in parallel, each pixel seeded by its index; a pixel depends
 * only on the anchors, so a view is the same on any number of threads.
 * */
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "answer/answer.h"
#include "base/internal.h"
#include "gi/gi_render.h"
#include "plan.h"
#include "scene/lights.h"
#include "trace/trace.h"

/* ---- the cone-traced view ------------------------------------------- */

/* Where the specular pass traces its cone. */
enum { SPEC_NONE = 0, SPEC_GLOSSY = 1, SPEC_ALL = 2 };

static int spec_mode(const struct gi_cascade *c) {
  int f = gi__fx_forced(&c->report.quality, GI_FX_SPECULAR);
  if (f == GI_FX_OFF) return SPEC_NONE;
  if (f == GI_FX_ON) return SPEC_ALL;
  return c->report.glossy_triangles ? SPEC_GLOSSY : SPEC_NONE;
}

void gi_cascade_view_plan(const gi_cascade *c, gi_effect out[GI_FX_COUNT]) {
  if (!c || !out) return;
  if (c->torn) { /* a stopped move may have re-planned part way; a view is refused anyway */
    memset(out, 0, GI_FX_COUNT * sizeof *out);
    for (int i = 0; i < GI_FX_COUNT; i++)
      snprintf(out[i].why, sizeof out[i].why, "the cascade is partial (gi_move.h)");
    return;
  }
  memcpy(out, c->report.effects, sizeof c->report.effects);
  gi_effect *e = &out[GI_FX_SPECULAR];
  uint32_t g = c->report.glossy_triangles;
  switch (spec_mode(c)) {
    case SPEC_ALL:
      e->ran = 1;
      snprintf(e->why, sizeof e->why, "forced on: one specular cone at every pixel (%u glossy triangle%s in range)", g,
               g == 1 ? "" : "s");
      break;
    case SPEC_GLOSSY:
      e->ran = 1;
      snprintf(e->why, sizeof e->why, "%u glossy triangle%s in range: one specular cone at each of their pixels", g,
               g == 1 ? "" : "s");
      break;
    default:
      e->ran = 0;
      if (g) snprintf(e->why, sizeof e->why, "turned off by the request");
      else snprintf(e->why, sizeof e->why, "%s", c->report.effects[GI_FX_SPECULAR].why);
  }
}

typedef struct {
  const struct gi_cascade *c;
  const gi__cam *k;
  int samples;
  int spec;            /* SPEC_* */
  float *rgb;
  _Atomic uint64_t diffuse_cones, specular_cones, outside;
  float *spec_img;     /* optional: specular * L_cone per pixel */
  int cap;             /* light samples per pixel at most (gi__light_sample_cap) */
  atomic_int failed;   /* a worker ran out of memory */
  int stride;          /* anchors at every stride-th pixel of every stride-th row (1: none, every pixel its own) */
  int aw, ah;          /* anchors per row and per column */
  int mix_sampled;     /* the plan samples the sky or emitters: anchors hold their direct light */
  struct anchor *anc;  /* aw * ah, or NULL when stride is 1 */
} render_ctx;

/* ---- indirect (and sampled direct) light at anchors, mixed ---------- */

/* Diffuse indirect light varies on the scale of the voxels it is gathered
 * from (one voxel off the surface), not of pixels: it is gathered at the
 * anchors (every stride-th pixel of every stride-th row), and a pixel
 * between four anchors that all lie on its own surface within a voxel of
 * it takes their bilinear mix; any other pixel (an edge, a corner, a thin
 * object, a far surface) gathers its own. The sampled lights (sky,
 * emitters) vary as smoothly over a surface, and their 64 shadow rays per
 * pixel were most of a view's time: they too are sampled at the anchors
 * and mixed (a pixel that gathers its own samples them itself). The sun,
 * point and spot lights (sharp shadows), emission and the specular cone
 * stay per pixel. Indirect light alone, measured at stride 4 against every pixel
 * (default quality, 64 light samples): Munich's street view 921,600 ->
 * 81,456 diffuse cones, render 357 -> 178 ms, pixels 0.04% apart; the
 * Cornell box's view against its path-traced reference 12.66% -> 12.57%
 * error (the mix smooths the gathers' pixel-scale ripple). The default
 * spacing is GI_RENDER_DEFAULT_STRIDE (gi_camera.h). */
/* An anchor lies on the pixel's surface when their normals are within
 * about 18 degrees and the anchor lies within ANCHOR_PLANE voxels of the
 * pixel's tangent plane and ANCHOR_REACH voxels of the pixel (voxels of
 * the finest level at the pixel). */
#define ANCHOR_COS 0.95f
#define ANCHOR_PLANE 0.25f
#define ANCHOR_REACH 1.0f

typedef struct anchor {
  float x[3], n[3];    /* the primary hit and its normal, turned to the camera */
  float E[3];          /* diffuse indirect irradiance (0 when the bake ran no bounce) */
  float Es[3];         /* direct irradiance from the sampled lights (sky, emitters) */
  int ok;              /* hit a surface inside the cascade, E and Es gathered */
} anchor;

/* The primary hit of pixel (px, py): 1 with its point, the normal turned
 * toward the camera, and its triangle, 0 when the ray leaves the scene. */
static int primary_hit(const render_ctx *rc, int px, int py, float w[3], float x[3], float n[3], float ng[3],
                       uint32_t *tri) {
  float t;
  gi__cam_ray(rc->k, (float)px + 0.5f, (float)py + 0.5f, w);
  if (!gi__camera_hit(rc->c->scene, rc->k->eye, w, &t, tri, ng)) return 0;
  float cw = gi__dot(ng, w);
  t *= 1.f - GI_PRIMARY_PULL;
  for (int a = 0; a < 3; a++) n[a] = cw > 0 ? -ng[a] : ng[a], x[a] = rc->k->eye[a] + t * w[a];
  return 1;
}

/* Direct irradiance at surface point x (normal n) of pixel (px, py) from
 * the lights of plan lp, by shadow rays (seeded by the pixel). With a
 * glossy lobe (r: its mirror direction, ns its exponent; r NULL: none),
 * H receives what the lobe reflects of the sun, point and spot lights,
 * sum V p(w) over those seen: no cone or lobe sample can meet a light of
 * no area, and a glossy floor under a lamp showed no highlight. */
static void direct_light(const render_ctx *rc, const gi_light_plan *lp, int px, int py, const float x[3],
                         const float n[3], const float *r, double ns, gi_ray_scratch *sc, float E[3], float H[3]) {
  const struct gi_cascade *c = rc->c;
  const gi_scene *s = c->scene;
  gi_lsample *ls = sc->ls;
  uint64_t rng = gi__mix64(c->report.quality.seed ^ ((uint64_t)py << 32 | (uint32_t)px));
  int nl = gi__light_samples(s, lp, x, &rng, ls, sc->cap), k = 0;
  /* Only lights in front of the surface; compact in place. */
  for (int i = 0; i < nl; i++)
    if (gi__dot(n, ls[i].w) > 0) ls[k++] = ls[i];
  gi__shadow_rays(s, x, n, gi__voxel_at(c, x), ls, k, sc);
  E[0] = E[1] = E[2] = 0;
  H[0] = H[1] = H[2] = 0;
  for (int i = 0; i < k; i++)
    if (sc->vis[i]) {
      float cn = gi__dot(n, ls[i].w);
      for (int a = 0; a < 3; a++) E[a] += ls[i].V[a] * cn;
      if (r && (ls[i].fx == GI_FX_SUN || ls[i].fx == GI_FX_LOCAL)) {
        float p = gi__phong_lobe(ns, gi__dot(r, ls[i].w));
        for (int a = 0; a < 3; a++) H[a] += ls[i].V[a] * p;
      }
    }
}

/* Gathers marched together (gi__gather_hemispheres): anchors per batch,
 * and pixels that need their own gather. */
#define GATHER_BATCH 32

typedef struct {
  gi_gather_req req[GATHER_BATCH];
  gi_gather_out out[GATHER_BATCH];
  int n;
} gather_batch;

static void anchor_flush(const render_ctx *rc, gather_batch *gb, anchor **who, uint64_t *cones) {
  if (rc->c->report.bounces_run > 0) {
    gi__gather_hemispheres(rc->c, gb->req, (size_t)gb->n, gb->out);
    for (int q = 0; q < gb->n; q++) {
      memcpy(who[q]->E, gb->out[q].E, sizeof who[q]->E);
      *cones += (uint64_t)rc->c->num_cones;
    }
  }
  for (int q = 0; q < gb->n; q++) who[q]->ok = 1;
  gb->n = 0;
}

static void anchor_rows(void *p, size_t b, size_t e, int worker) {
  (void)worker;
  render_ctx *rc = p;
  uint64_t cones = 0;
  gather_batch gb = {.n = 0};
  anchor *who[GATHER_BATCH];
  gi_ray_scratch sc = {0};
  if (gi__scratch_alloc(&sc, rc->cap)) {
    atomic_store(&rc->failed, 1);
    return;
  }
  /* Anchors sample the lights that are mixed: the sky and the emitters. */
  gi_light_plan lp = gi__answer_light_plan(rc->c->scene, &rc->c->report, rc->samples);
  lp.sun = lp.local = 0;
  for (size_t j = b; j < e; j++)
    for (int i = 0; i < rc->aw; i++) {
      anchor *an = &rc->anc[j * (size_t)rc->aw + (size_t)i];
      float w[3], ng[3];
      uint32_t tri;
      memset(an, 0, sizeof *an);
      int px = i * rc->stride, py = (int)j * rc->stride;
      if (!primary_hit(rc, px, py, w, an->x, an->n, ng, &tri)) continue;
      int d = gi__finest_level_at(rc->c, an->x);
      if (d < 0) continue;
      float H[3]; /* no lobe: the anchors hold diffuse light only */
      if (rc->mix_sampled) direct_light(rc, &lp, px, py, an->x, an->n, NULL, 0, &sc, an->Es, H);
      gb.req[gb.n] = gi__gather_req(an->x, an->n, GI_GATHER_SURFACE, d);
      who[gb.n++] = an;
      if (gb.n == GATHER_BATCH) anchor_flush(rc, &gb, who, &cones);
    }
  anchor_flush(rc, &gb, who, &cones);
  gi__scratch_free(&sc);
  atomic_fetch_add(&rc->diffuse_cones, cones);
}

/* The pixel's indirect light and sampled lights' direct light from the
 * four anchors around it: 1 when all of them lie on its surface (E and Es
 * their bilinear mix), else 0. */
static int interpolate_anchors(const render_ctx *rc, int px, int py, const float x[3], const float n[3], int d,
                               float E[3], float Es[3]) {
  int S = rc->stride, i0 = px / S, j0 = py / S;
  float fx = (float)(px - i0 * S) / (float)S, fy = (float)(py - j0 * S) / (float)S;
  float s = (float)rc->c->lv[d].s, wsum = 0, acc[3] = {0, 0, 0}, accs[3] = {0, 0, 0};
  for (int dj = 0; dj < 2; dj++)
    for (int di = 0; di < 2; di++) {
      int i = i0 + di, j = j0 + dj;
      float wt = (di ? fx : 1 - fx) * (dj ? fy : 1 - fy);
      if (!(wt > 0)) continue;
      if (i >= rc->aw || j >= rc->ah) return 0;
      const anchor *an = &rc->anc[(size_t)j * rc->aw + (size_t)i];
      if (!an->ok || gi__dot(an->n, n) < ANCHOR_COS) return 0;
      float v[3] = {an->x[0] - x[0], an->x[1] - x[1], an->x[2] - x[2]};
      if (fabsf(gi__dot(v, n)) > ANCHOR_PLANE * s || gi__dot(v, v) > ANCHOR_REACH * ANCHOR_REACH * s * s) return 0;
      for (int a = 0; a < 3; a++) acc[a] += wt * an->E[a], accs[a] += wt * an->Es[a];
      wsum += wt;
    }
  for (int a = 0; a < 3; a++) E[a] = acc[a] / wsum, Es[a] = accs[a] / wsum;
  return 1;
}

/* A pixel waiting for its own gather (render_rows): shade_pixel's state
 * before the indirect light, for finish_pixel after it. */
typedef struct {
  float *out, *spec;
  const gi_material *m;
  float albedo[3];              /* the hit triangle's (gi__tri_albedo) */
  float x[3], n[3], w[3], E[3]; /* E: the direct irradiance */
  float H[3];    /* the glossy lobe's share of the sun, point and spot lights (direct_light) */
  int d;
  uint64_t seed; /* the pixel's own: its specular emitter rays */
} pending_px;

/* Adds the diffuse reflection of irradiance E (direct + indirect) and the
 * specular cone to pixel out. */
static void finish_pixel(const render_ctx *rc, const pending_px *pp, uint64_t cones[2]) {
  const gi_material *m = pp->m;
  float *out = pp->out;
  for (int a = 0; a < 3; a++) out[a] += pp->albedo[a] * (1.f / GI_PI_F) * pp->E[a];
  int glossy = gi__gloss(m) > 0;
  float S[3] = {pp->H[0], pp->H[1], pp->H[2]};
  if (pp->d >= 0 && (rc->spec == SPEC_ALL || (rc->spec == SPEC_GLOSSY && glossy))) {
    gi_cone_out co;
    gi__specular_trace(rc->c, pp->x, pp->n, pp->w, m->roughness, pp->seed, &co);
    cones[1]++;
    for (int a = 0; a < 3; a++) S[a] += co.L[a];
  }
  float sc[3]; /* the lobe per channel; a matte material forced through the pass: its `specular` */
  if (glossy) gi__gloss_rgb(m, sc);
  else sc[0] = sc[1] = sc[2] = m->specular;
  for (int a = 0; a < 3; a++) out[a] += sc[a] * S[a];
  if (pp->spec)
    for (int a = 0; a < 3; a++) pp->spec[a] = sc[a] * S[a];
}

/* Shades pixel (px, py) into out (and spec); returns 1, with *pp filled
 * and the pixel unfinished, when its indirect light needs a gather of its
 * own (no anchors, or they do not lie on its surface). */
static int shade_pixel(render_ctx *rc, int px, int py, gi_ray_scratch *sc, uint64_t cones[2], float out[3],
                       float *spec, pending_px *pp) {
  const struct gi_cascade *c = rc->c;
  const gi_scene *s = c->scene;
  float ng[3];
  uint32_t tri;
  pp->out = out, pp->spec = spec;
  pp->seed = c->report.quality.seed ^ ((uint64_t)py << 32 | (uint32_t)px);
  out[0] = out[1] = out[2] = 0;
  if (!primary_hit(rc, px, py, pp->w, pp->x, pp->n, ng, &tri)) {
    /* The camera sees the sky itself where answers sample it. */
    if (gi__answer_sky(s, &c->report)) gi__sky_radiance(s, out);
    return 0;
  }
  const float *x = pp->x, *n = pp->n;
  const gi_material *m = pp->m = &s->materials[s->tri_material[tri]];
  memcpy(pp->albedo, gi__tri_albedo(s, tri), sizeof pp->albedo);
  if (gi__emitter_cos(s, tri, -gi__dot(ng, pp->w)) > 0) /* an emitter's front (or two-sided) faces the camera */
    for (int a = 0; a < 3; a++) out[a] += m->emission[a];
  float *E = pp->E;
  /* The anchors' mix (an anchor's own pixel is its cell's corner at weight
   * 1: its own light), or the pixel's own light and gather. */
  int d = pp->d = gi__finest_level_at(c, x);
  if (d < 0) atomic_fetch_add_explicit(&rc->outside, 1, memory_order_relaxed);
  float Ei[3] = {0, 0, 0}, Es[3] = {0, 0, 0};
  int mixed = rc->anc && d >= 0 && interpolate_anchors(rc, px, py, x, n, d, Ei, Es);
  gi_light_plan lp = gi__answer_light_plan(c->scene, &c->report, rc->samples);
  /* A mixed pixel samples only the sharp lights (sun, point, spot) itself. */
  if (mixed && rc->mix_sampled) lp.sky = lp.emissive = 0;
  /* The lobe the reference path-traces (gi__gloss > 0), where the specular pass runs. */
  float r[3];
  double ns = 0;
  int lobe = rc->spec != SPEC_NONE && (ns = gi__gloss_exponent(m)) > 0 && isfinite(ns);
  if (lobe) {
    float dn = gi__dot(pp->w, n);
    for (int a = 0; a < 3; a++) r[a] = pp->w[a] - 2 * dn * n[a];
  }
  direct_light(rc, &lp, px, py, x, n, lobe ? r : NULL, ns, sc, E, pp->H);
  for (int a = 0; a < 3; a++) E[a] += Es[a];
  if (d >= 0 && c->report.bounces_run > 0) {
    if (!mixed) return 1;
    for (int a = 0; a < 3; a++) E[a] += Ei[a];
  }
  finish_pixel(rc, pp, cones);
  return 0;
}

/* The pending pixels' gathers, then the rest of their shading. */
static void pixel_flush(const render_ctx *rc, pending_px *pp, gather_batch *gb, uint64_t cones[2]) {
  gi__gather_hemispheres(rc->c, gb->req, (size_t)gb->n, gb->out);
  for (int q = 0; q < gb->n; q++) {
    cones[0] += (uint64_t)rc->c->num_cones;
    for (int a = 0; a < 3; a++) pp[q].E[a] += gb->out[q].E[a];
    finish_pixel(rc, &pp[q], cones);
  }
  gb->n = 0;
}

static void render_rows(void *p, size_t b, size_t e, int worker) {
  render_ctx *rc = p;
  gi_ray_scratch sc = {0};
  uint64_t cones[2] = {0, 0};
  if (gi__scratch_alloc(&sc, rc->cap)) {
    atomic_store(&rc->failed, 1);
    return;
  }
  gather_batch gb = {.n = 0};
  pending_px pp[GATHER_BATCH];
  for (size_t y = b; y < e; y++)
    for (int x = 0; x < rc->k->w; x++) {
      size_t i = 3 * ((size_t)y * rc->k->w + x);
      if (!shade_pixel(rc, x, (int)y, &sc, cones, &rc->rgb[i], rc->spec_img ? &rc->spec_img[i] : NULL, &pp[gb.n]))
        continue;
      gb.req[gb.n] = gi__gather_req(pp[gb.n].x, pp[gb.n].n, GI_GATHER_SURFACE, pp[gb.n].d);
      if (++gb.n == GATHER_BATCH) pixel_flush(rc, pp, &gb, cones);
    }
  pixel_flush(rc, pp, &gb, cones);
  gi__scratch_free(&sc);
  atomic_fetch_add(&rc->diffuse_cones, cones[0]);
  atomic_fetch_add(&rc->specular_cones, cones[1]);
}

gi_result gi_cascade_render_ex(const gi_cascade *c, const gi_camera *cam, const gi_render_opts *opts, float *rgb,
                               gi_render_stats *st, gi_error_info *err) {
  if (!c || !rgb) return gi__fail(err, GI_ERR_INVALID_ARG, "render: %s is NULL", !c ? "cascade" : "rgb");
  if (gi__cascade_whole(c, "render", err) != GI_OK) return GI_ERR_INVALID_ARG;
  gi_render_opts o = {0};
  if (opts) o = *opts;
  if (o.light_samples == 0) o.light_samples = 64;
  if (o.light_samples < 1 || o.light_samples > 4096)
    return gi__fail(err, GI_ERR_INVALID_ARG, "render: light_samples must be 1..4096, got %d", o.light_samples);
  if (o.indirect_stride < 0 || o.indirect_stride > GI_RENDER_MAX_STRIDE)
    return gi__fail(err, GI_ERR_INVALID_ARG, "render: indirect_stride must be 0..%d, got %d", GI_RENDER_MAX_STRIDE,
                    o.indirect_stride);
  gi__cam k;
  gi_result r = gi__cam_setup(c->scene, cam, &k, err);
  if (r != GI_OK) return r;
  double t0 = gi__now_ms();
  size_t np = (size_t)k.w * k.h * 3;
  memset(rgb, 0, np * sizeof(float));
  if (o.specular) memset(o.specular, 0, np * sizeof(float));
  render_ctx rc = {.c = c, .k = &k, .samples = o.light_samples, .spec = spec_mode(c), .rgb = rgb,
                   .spec_img = o.specular};
  gi_light_plan lp = gi__answer_light_plan(c->scene, &c->report, o.light_samples);
  rc.cap = gi__light_sample_cap(c->scene, &lp);
  atomic_init(&rc.failed, 0);
  atomic_init(&rc.diffuse_cones, 0);
  atomic_init(&rc.specular_cones, 0);
  atomic_init(&rc.outside, 0);
  rc.stride = o.indirect_stride ? o.indirect_stride : GI_RENDER_DEFAULT_STRIDE;
  rc.mix_sampled = lp.sky || (lp.emissive && c->scene->num_emitters > 0);
  if (rc.stride > 1 && (c->report.bounces_run > 0 || rc.mix_sampled)) {
    rc.aw = (k.w - 1) / rc.stride + 1, rc.ah = (k.h - 1) / rc.stride + 1;
    rc.anc = gi__malloc((size_t)rc.aw * (size_t)rc.ah * sizeof *rc.anc);
    if (!rc.anc)
      return gi__fail(err, GI_ERR_NOMEM, "render: out of memory for %d x %d indirect anchors", rc.aw, rc.ah);
    gi__parallel_for_stop((size_t)rc.ah, 1, o.threads, anchor_rows, &rc, &rc.failed);
  } else {
    rc.stride = 1;
  }
  gi__parallel_for_stop((size_t)k.h, 1, o.threads, render_rows, &rc, &rc.failed);
  gi__free(rc.anc);
  if (atomic_load(&rc.failed))
    return gi__fail(err, GI_ERR_NOMEM, "render: out of memory for the light-sample buffers (%d samples)", rc.cap);
  if (st) {
    memset(st, 0, sizeof *st);
    st->ms = gi__now_ms() - t0;
    st->diffuse_cones = atomic_load(&rc.diffuse_cones);
    st->specular_cones = atomic_load(&rc.specular_cones);
    st->pixels_outside = atomic_load(&rc.outside);
    st->indirect_stride = rc.stride;
    gi_cascade_view_plan(c, st->effects);
  }
  for (size_t i = 0; i < np; i++)
    if (!isfinite(rgb[i]) || (o.specular && !isfinite(o.specular[i])))
      return gi__fail(err, GI_ERR_NONFINITE, "render: pixel %zu is not finite", i / 3);
  return GI_OK;
}

gi_result gi_cascade_render(const gi_cascade *c, const gi_camera *cam, int light_samples, int threads, float *rgb,
                            double *ms, gi_error_info *err) {
  gi_render_opts o = {.light_samples = light_samples, .threads = threads};
  gi_render_stats st;
  gi_result r = gi_cascade_render_ex(c, cam, &o, rgb, &st, err);
  if (ms) *ms = r == GI_OK ? st.ms : 0;
  return r;
}
