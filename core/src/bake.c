/* bake.c: the pipeline around one viewpoint, the effect plan, and the
 * final gather.
 *
 * gi_cascade_bake resolves the quality (defaults, validation), decides
 * which effects the scene and request call for, then runs the stages in
 * order: place, voxelize, inject, filter, bounce. Each stage's time goes
 * into the report. gi_cascade_gather answers points from the finished
 * texture: direct light by shadow rays from the point itself (exact up to
 * sampling noise), indirect light by cones over the whole sphere, both
 * projected into SH L2 irradiance. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "cascade_internal.h"
#include "internal.h"

#define PI_F 3.14159265358979f

static const char *const fx_names[GI_FX_COUNT] = {"sun", "local_lights", "sky", "emissive",
                                                  "bounce", "specular", "ao"};

const char *gi_effect_name(gi_effect_id id) {
  return (unsigned)id < GI_FX_COUNT ? fx_names[id] : "unknown";
}

int gi_effect_from_name(const char *name) {
  for (int i = 0; name && i < GI_FX_COUNT; i++)
    if (!strcmp(name, fx_names[i])) return i;
  return -1;
}

static void set_fx(gi_bake_report *r, gi_effect_id id, int ran, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void set_fx(gi_bake_report *r, gi_effect_id id, int ran, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  r->effects[id].ran = ran;
  vsnprintf(r->effects[id].why, sizeof r->effects[id].why, fmt, ap);
  va_end(ap);
}

gi_result gi_quality_resolve(const gi_scene *s, const gi_quality *in, gi_quality *q,
                             gi_error_info *err) {
  if (!s || !q) return gi__fail(err, GI_ERR_INVALID_ARG, "quality: scene and output are required");
  gi_quality z = {0};
  *q = in ? *in : z;
  if (q->levels == 0) q->levels = 6;
  if (q->res == 0) q->res = 32;
  if (q->cones == 0) q->cones = 16;
  if (q->step == 0) q->step = 0.5f;
  if (q->bounces == 0) q->bounces = 2; /* auto: the effect plan replaces it */
  else if (q->bounces < 0) q->bounces = 0;
  for (int i = 0; i < GI_FX_COUNT; i++)
    if (q->effects[i] < -1 || q->effects[i] > 1)
      return gi__fail(err, GI_ERR_INVALID_ARG, "quality: effects[%s] must be -1 (off), 0 (auto) or 1 (on), got %d",
                      fx_names[i], q->effects[i]);
  if (q->specular < -1 || q->specular > 1)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: specular must be -1, 0 or 1, got %d", q->specular);
  if (q->light_samples == 0) q->light_samples = 16;
  if (q->probe_samples == 0) q->probe_samples = 256;
  if (q->seed == 0) q->seed = 1;
  if (q->levels < 1 || q->levels > GI_MAX_LEVELS)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: levels must be 1..%d, got %d", GI_MAX_LEVELS, q->levels);
  if (q->res < 8 || q->res > 256 || q->res % 4)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: res must be a multiple of 4 in 8..256, got %d", q->res);
  if (q->cones != 4 && q->cones != 6 && q->cones != 8 && q->cones != 16 && q->cones != 32)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: cones must be 4, 6, 8, 16 or 32, got %d", q->cones);
  if (!isfinite(q->voxel0) || q->voxel0 < 0)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: voxel size must be a positive finite number");
  if (!isfinite(q->aperture_deg) || q->aperture_deg < 0 || q->aperture_deg >= 180)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: aperture must be in (0, 180) degrees");
  if (!isfinite(q->step) || q->step < 0.05f || q->step > 4)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: step must be in 0.05..4, got %g", q->step);
  if (q->bounces > 8)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: bounces must be at most 8, got %d", q->bounces);
  if (q->light_samples < 1 || q->light_samples > 512 || q->probe_samples < 1 || q->probe_samples > 8192)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: light samples must be 1..512 and probe samples 1..8192");
  if (q->voxel0 == 0) {
    /* The coarsest level spans 1.25 times the scene's largest side: a
     * centred viewpoint then keeps every wall a few voxels inside the
     * window, clear of the one-voxel border cones need for filtering. A
     * wide, flat scene (a city) spans at most 16 times its height (but at
     * least an eighth of its width): light from farther away than that
     * barely reaches a street, and a cascade over all of a 5 km city
     * would voxelize every triangle of it for each viewpoint. */
    double lo[3], hi[3], ext = 0;
    gi_scene_bounds(s, lo, hi);
    for (int a = 0; a < 3; a++) ext = fmax(ext, hi[a] - lo[a]);
    int up = gi_scene_up(s) == GI_UP_Z ? 2 : 1;
    double height = hi[up] - lo[up], cap = fmax(16.0 * height, ext / 8.0);
    if (cap < ext) ext = cap;
    if (!(ext > 0)) ext = 1.0;
    q->voxel0 = 1.25 * ext / ((double)q->res * (double)(1ull << (q->levels - 1)));
  }
  if (!isfinite(q->ao_lambda) || q->ao_lambda < 0)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: ao_lambda must be finite and >= 0");
  if (q->ao_lambda == 0) q->ao_lambda = (float)(1.0 / (4.0 * q->voxel0));
  return GI_OK;
}

int gi__fx_forced(const gi_quality *q, gi_effect_id id) {
  int f = q->effects[id];
  if (f == GI_FX_AUTO && id == GI_FX_SPECULAR) f = q->specular;
  if (f == GI_FX_AUTO && id == GI_FX_AO && q->ao) f = GI_FX_ON;
  return f;
}

/* Triangles whose bounds overlap the coarsest level's box grown by `grow`
 * times its side on every face; *n = 0 on an empty scene or allocation
 * failure. Caller frees. */
static uint32_t *tris_in_range(const struct gi_cascade *c, float grow, size_t *n) {
  uint32_t *t = NULL;
  size_t cap = 0;
  *n = 0;
  const gi_level *L = &c->lv[c->n - 1];
  float lo[3], hi[3];
  for (int a = 0; a < 3; a++) {
    float m = grow * (L->hi[a] - L->lo[a]);
    lo[a] = L->lo[a] - m, hi[a] = L->hi[a] + m;
  }
  if (gi__query_box(c->scene, lo, hi, &t, n, &cap) != GI_OK) *n = 0;
  return t;
}

/* Sky visibility: 32 stratified upward rays from the viewpoint and from the
 * centres of the finest level's six faces. One escaping ray is enough; a
 * closed room (or the Cornell box's ceiling side) stops them all. */
static int sky_rays(const struct gi_cascade *c, int *tested) {
  const gi_scene *s = c->scene;
  enum { ORG = 7, PER = 32 };
  float org[3 * ORG * PER], dir[3 * ORG * PER], tn[ORG * PER], tf[ORG * PER];
  uint8_t vis[ORG * PER];
  const float up[3] = {0, s->up == GI_UP_Z ? 0.f : 1.f, s->up == GI_UP_Z ? 1.f : 0.f};
  float t[3], b[3];
  gi__basis(up, t, b);
  float half = (float)(0.5 * c->R * c->lv[0].s);
  int n = 0;
  for (int o = 0; o < ORG; o++) {
    float p[3] = {c->at[0], c->at[1], c->at[2]};
    if (o) p[(o - 1) / 2] += (o & 1) ? half : -half;
    uint64_t rng = gi__mix64(0x5c1ull + (uint64_t)o);
    for (int j = 0; j < PER; j++, n++) {
      float ct = ((float)j + gi__u01(&rng)) / PER, st = sqrtf(fmaxf(0.f, 1 - ct * ct));
      float phi = 2 * PI_F * gi__u01(&rng);
      for (int k = 0; k < 3; k++) {
        org[3 * n + k] = p[k];
        dir[3 * n + k] = st * cosf(phi) * t[k] + st * sinf(phi) * b[k] + ct * up[k];
      }
      tn[n] = 0;
      tf[n] = INFINITY;
    }
  }
  gi__occluded(s, n, org, dir, tn, tf, vis);
  int seen = 0;
  for (int i = 0; i < n; i++) seen += vis[i];
  *tested = n;
  return seen;
}

/* The effect plan: what this scene and request call for, with reasons.
 * Runs after placement (it looks at what lies inside the cascade). May set
 * q->bounces when the request left it to the plan (auto_bounces). Returns 1
 * when the plan capped the bounces while the orders left out still weigh
 * 2% or more: the bounce stage then adds their geometric tail (inject.c). */
static int plan_effects(const struct gi_cascade *c, gi_quality *q, int auto_bounces, gi_bake_report *r) {
  const gi_scene *s = c->scene;
  int sun = 0, local = 0, sky = 0;
  for (uint32_t i = 0; i < s->num_lights; i++) {
    const gi_light *l = &s->lights[i];
    int lit = l->color[0] > 0 || l->color[1] > 0 || l->color[2] > 0;
    if (!lit) continue;
    if (l->type == GI_LIGHT_SUN) sun++;
    else if (l->type == GI_LIGHT_SKY) sky++;
    else local++;
  }
  if (gi__fx_forced(q, GI_FX_SUN) == GI_FX_OFF) set_fx(r, GI_FX_SUN, 0, "turned off by the request");
  else if (sun) set_fx(r, GI_FX_SUN, 1, "%d directional light%s", sun, sun > 1 ? "s" : "");
  else set_fx(r, GI_FX_SUN, 0, "no directional light in the scene");
  if (gi__fx_forced(q, GI_FX_LOCAL) == GI_FX_OFF) set_fx(r, GI_FX_LOCAL, 0, "turned off by the request");
  else if (local) set_fx(r, GI_FX_LOCAL, 1, "%d point/spot light%s", local, local > 1 ? "s" : "");
  else set_fx(r, GI_FX_LOCAL, 0, "no point or spot light in the scene");

  int fs = gi__fx_forced(q, GI_FX_SKY);
  if (fs == GI_FX_OFF) set_fx(r, GI_FX_SKY, 0, "turned off by the request");
  else if (!sky) set_fx(r, GI_FX_SKY, 0, "no sky light in the scene");
  else if (fs == GI_FX_ON) set_fx(r, GI_FX_SKY, 1, "forced on by the request, %d samples per voxel", q->light_samples);
  else {
    int tested = 0, seen = sky_rays(c, &tested);
    if (seen) set_fx(r, GI_FX_SKY, 1, "sky seen by %d of %d test rays, %d samples per voxel", seen, tested,
                     q->light_samples);
    else set_fx(r, GI_FX_SKY, 0, "sky light present, but none of %d upward test rays from the viewpoint and the "
                                 "finest level's faces escapes", tested);
  }

  /* Emitters light the cascade from outside it too: look half a cascade
   * beyond it (an emitter farther away lights it at under a ninth of the
   * irradiance it would give at the border, and the coarsest level
   * already spans the whole scene by default). Albedo and gloss: inside only. */
  size_t ne = 0, nt = 0;
  uint32_t *tris = tris_in_range(c, 0.5f, &ne);
  uint32_t emit_in = 0, glossy = 0;
  for (size_t i = 0; i < ne; i++) {
    const gi_material *m = &s->materials[s->tri_material[tris[i]]];
    emit_in += m->emission[0] > 0 || m->emission[1] > 0 || m->emission[2] > 0;
  }
  free(tris);
  tris = tris_in_range(c, 0.f, &nt);
  double area = 0, a_sum = 0;
  for (size_t i = 0; i < nt; i++) {
    const uint32_t *ix = &s->indices[3 * tris[i]];
    const gi_material *m = &s->materials[s->tri_material[tris[i]]];
    const float *A = &s->vertices[3 * ix[0]], *B = &s->vertices[3 * ix[1]], *C = &s->vertices[3 * ix[2]];
    float e1[3], e2[3], n[3];
    for (int k = 0; k < 3; k++) e1[k] = B[k] - A[k], e2[k] = C[k] - A[k];
    gi__cross(e1, e2, n);
    double ar = 0.5 * gi__len(n);
    area += ar;
    a_sum += ar * fmaxf(m->albedo[0], fmaxf(m->albedo[1], m->albedo[2]));
    glossy += m->roughness < 0.5f && m->specular > 0;
  }
  free(tris);
  int fe = gi__fx_forced(q, GI_FX_EMISSIVE);
  if (fe == GI_FX_OFF) set_fx(r, GI_FX_EMISSIVE, 0, "turned off by the request");
  else if (!s->num_emitters) set_fx(r, GI_FX_EMISSIVE, 0, "no emissive surfaces");
  else if (emit_in || fe == GI_FX_ON)
    set_fx(r, GI_FX_EMISSIVE, 1, "%u emissive triangles (%u within reach of the cascade%s), %d samples per voxel",
           s->num_emitters, emit_in, emit_in ? "" : ", forced on", q->light_samples);
  else set_fx(r, GI_FX_EMISSIVE, 0, "%u emissive triangles, none within half a cascade of it", s->num_emitters);

  /* Bounces from the albedo: the k-th reflection adds about a^k of the
   * direct light (a = area-weighted albedo, brightest channel, of what lies
   * in the cascade). With B voxel bounces the gather holds k = B + 1, so
   * the first one missing weighs a^(B+2). Stop when that is under 2% of
   * the direct light: the probe's own Monte Carlo noise on direct light is
   * about that (measured 1.2% Cornell, 1.6% Munich at 256 probe samples).
   * At most 3: each bounce is a full cone gather at every voxel. When the
   * cap stops short of that (a bright closed room: the Cornell box's mean
   * albedo gives a^5 = 20%), the orders left out are not dropped: the
   * bounce stage extrapolates them as a geometric series from the last two
   * bounces (see gi__bounce), which costs no gather. */
  double abar = area > 0 ? a_sum / area : 0;
  int fb = gi__fx_forced(q, GI_FX_BOUNCE);
  int tail = 0;
  if (auto_bounces) {
    int B = 1;
    while (B < 3 && pow(abar, B + 2) >= 0.02) B++;
    q->bounces = B;
    tail = B >= 2 && pow(abar, B + 2) >= 0.02;
  }
  if (fb == GI_FX_OFF) q->bounces = 0, set_fx(r, GI_FX_BOUNCE, 0, "turned off by the request");
  else if (q->bounces == 0) set_fx(r, GI_FX_BOUNCE, 0, "bounces set to none by the request");
  else if (abar <= 0 && fb != GI_FX_ON) set_fx(r, GI_FX_BOUNCE, 0, "every albedo in range is 0: a bounce would add nothing");
  else if (auto_bounces && tail)
    set_fx(r, GI_FX_BOUNCE, 1, "%d bounces and the geometric tail of the rest: mean albedo %.2f in range, next "
                               "bounce would add %.1f%% of direct (stop under 2%%, at most 3)", q->bounces, abar,
           100 * pow(abar, q->bounces + 2));
  else if (auto_bounces)
    set_fx(r, GI_FX_BOUNCE, 1, "%d bounce%s: mean albedo %.2f in range, next bounce would add %.1f%% of direct "
                               "(stop under 2%%, at most 3)", q->bounces, q->bounces > 1 ? "s" : "", abar,
           100 * pow(abar, q->bounces + 2));
  else set_fx(r, GI_FX_BOUNCE, 1, "%d bounce%s as requested, mean albedo %.2f in range", q->bounces,
              q->bounces > 1 ? "s" : "", abar);

  /* The specular cone needs a view direction; probes have none. Camera
   * views re-decide this entry (gi_cascade_view_plan) from the same count. */
  r->glossy_triangles = glossy;
  int fsp = gi__fx_forced(q, GI_FX_SPECULAR);
  if (fsp == GI_FX_OFF) set_fx(r, GI_FX_SPECULAR, 0, "turned off by the request");
  else if (fsp == GI_FX_ON)
    set_fx(r, GI_FX_SPECULAR, 0, "forced on: camera views trace it at every pixel; probe output has no view direction");
  else if (glossy)
    set_fx(r, GI_FX_SPECULAR, 0, "%u glossy triangle%s in range: camera views trace it; probe output has no view "
                                 "direction", glossy, glossy > 1 ? "s" : "");
  else set_fx(r, GI_FX_SPECULAR, 0, "no glossy material within the cascade");
  if (gi__fx_forced(q, GI_FX_AO) == GI_FX_ON) set_fx(r, GI_FX_AO, 1, "requested, lambda %.3g per unit", q->ao_lambda);
  else set_fx(r, GI_FX_AO, 0, "not requested");
  return tail && r->effects[GI_FX_BOUNCE].ran;
}

gi_result gi_effect_plan(const gi_scene *s, const double at[3], const gi_quality *qin, gi_effect out[GI_FX_COUNT],
                         gi_quality *resolved, gi_error_info *err) {
  if (!s || !at || !out) return gi__fail(err, GI_ERR_INVALID_ARG, "plan: scene, viewpoint and output are required");
  gi_quality q;
  gi_result rc = gi_quality_resolve(s, qin, &q, err);
  if (rc != GI_OK) return rc;
  /* The plan looks at what lies inside the placed cascade: place one
   * without its voxel arrays, as gi_cascade_bake would. */
  struct gi_cascade *c = calloc(1, sizeof *c);
  if (!c) return gi__fail(err, GI_ERR_NOMEM, "plan: out of memory");
  c->scene = (gi_scene *)s;
  c->n = q.levels;
  c->R = q.res;
  c->s0 = q.voxel0;
  for (int a = 0; a < 3; a++) {
    c->at[a] = (float)(at[a] - s->origin[a]);
    if (!isfinite(at[a]) || !isfinite(c->at[a]) || fabs(at[a] - s->origin[a]) > 1e9) {
      free(c);
      return gi__fail(err, GI_ERR_INVALID_ARG, "plan: viewpoint is not finite or more than 1e9 units from the scene");
    }
  }
  gi__cascade_place(c);
  plan_effects(c, &q, !qin || qin->bounces == 0, &c->report);
  memcpy(out, c->report.effects, sizeof c->report.effects);
  if (resolved) *resolved = q;
  free(c);
  return GI_OK;
}

gi_result gi_cascade_anchor(const gi_scene *s, const double at[3], const gi_quality *resolved,
                            int64_t anchor[3], gi_error_info *err) {
  if (!s || !at || !resolved || !(resolved->voxel0 > 0))
    return gi__fail(err, GI_ERR_INVALID_ARG, "anchor: scene, viewpoint and a resolved quality are required");
  for (int a = 0; a < 3; a++) {
    /* The same float rounding and snapping as gi_cascade_bake and
     * gi__cascade_place: level 0's window starts at 2 floor(at / 2 s0) - R/2
     * and every coarser level follows from it, so equal anchors mean equal
     * cascades. */
    float al = (float)(at[a] - s->origin[a]);
    if (!isfinite(at[a]) || !isfinite(al))
      return gi__fail(err, GI_ERR_NONFINITE, "anchor: viewpoint is not finite");
    anchor[a] = (int64_t)floor((double)al / (2.0 * resolved->voxel0));
  }
  return GI_OK;
}

static void free_levels(struct gi_cascade *c) {
  for (int d = 0; d < GI_MAX_LEVELS; d++) {
    free(c->lv[d].geo);
    free(c->lv[d].rad);
    free(c->lv[d].side);
    free(c->lv[d].direct);
    free(c->lv[d].occ);
    free(c->lv[d].busy);
  }
}

void gi_cascade_free(gi_cascade *c) {
  if (!c) return;
  free_levels(c);
  gi_scene_release(c->scene);
  free(c);
}

size_t gi_cascade_bytes(const gi_cascade *c) {
  /* geo, rad, side, direct, occ and busy: every per-voxel array a level holds. */
  size_t per = sizeof(gi_vgeo) + sizeof(gi_vrad) + 2 * sizeof(float[2][3]) + sizeof(uint32_t) + sizeof(uint8_t);
  return (size_t)c->n * (size_t)c->R * c->R * c->R * per;
}

const gi_bake_report *gi_cascade_report(const gi_cascade *c) { return &c->report; }

gi_result gi_cascade_bake(const gi_scene *scene, const double at[3], const gi_quality *qin,
                          gi_cascade **out, gi_bake_report *report, gi_error_info *err) {
  *out = NULL;
  if (!scene || !at) return gi__fail(err, GI_ERR_INVALID_ARG, "bake: scene and viewpoint are required");
  if (!isfinite(at[0]) || !isfinite(at[1]) || !isfinite(at[2]))
    return gi__fail(err, GI_ERR_NONFINITE, "bake: viewpoint (%g, %g, %g) is not finite", at[0], at[1], at[2]);
  gi_quality q;
  gi_result rc = gi_quality_resolve(scene, qin, &q, err);
  if (rc != GI_OK) return rc;
  struct gi_cascade *c = calloc(1, sizeof *c);
  if (!c) return gi__fail(err, GI_ERR_NOMEM, "bake: out of memory");
  c->scene = gi_scene_retain((gi_scene *)scene);
  c->n = q.levels;
  c->R = q.res;
  c->s0 = q.voxel0;
  for (int a = 0; a < 3; a++) {
    c->at_world[a] = at[a];
    c->at[a] = (float)(at[a] - scene->origin[a]);
  }
  /* A viewpoint beyond float range of the scene would lose all precision. */
  if (!isfinite(c->at[0]) || !isfinite(c->at[1]) || !isfinite(c->at[2]) ||
      fabs(at[0] - scene->origin[0]) > 1e9 || fabs(at[1] - scene->origin[1]) > 1e9 ||
      fabs(at[2] - scene->origin[2]) > 1e9) {
    gi_cascade_free(c);
    return gi__fail(err, GI_ERR_INVALID_ARG, "bake: viewpoint is more than 1e9 units from the scene");
  }
  c->report.quality = q;
  c->report.levels = q.levels;
  gi__cone_set(q.cones, q.aperture_deg, c->cone_dir, c->cone_weight, &c->cone_tan);
  c->num_cones = q.cones;
  /* Report every knob resolved, so a JSON answer says exactly what ran. */
  q.aperture_deg = (float)(2.0 * atan((double)c->cone_tan) * 180.0 / 3.14159265358979323846);
  q.threads = gi__num_workers(q.threads);

  if ((rc = gi__cascade_alloc(c, err)) != GI_OK) goto fail;
  gi__cascade_place(c);
  int tail = plan_effects(c, &q, !qin || qin->bounces == 0, &c->report);
  if (c->report.effects[GI_FX_AO].ran) q.ao = 1;
  c->report.quality = q;
  for (int d = 0; d < c->n; d++) {
    c->report.voxel_size[d] = c->lv[d].s;
    for (int a = 0; a < 3; a++)
      c->report.level_origin[d][a] = (double)c->lv[d].cell0[a] * c->lv[d].s + scene->origin[a];
  }
  double t0 = gi__now_ms();
  if ((rc = gi__voxelize(c, q.threads, err)) != GI_OK) goto fail;
  double t1 = gi__now_ms();
  if ((rc = gi__inject(c, &q, err)) != GI_OK) goto fail;
  double t2 = gi__now_ms();
  gi__cascade_filter(c, q.threads);
  gi__cascade_mark_busy(c);
  double t3 = gi__now_ms();
  if (c->report.effects[GI_FX_BOUNCE].ran)
    if ((rc = gi__bounce(c, &q, q.bounces, tail, err)) != GI_OK) goto fail;
  double t4 = gi__now_ms();
  c->report.ms.voxelize = t1 - t0;
  c->report.ms.inject = t2 - t1;
  c->report.ms.filter = t3 - t2;
  c->report.ms.bounce = t4 - t3;
  /* Occupancy per level, including the filtered region. */
  for (int d = 0; d < c->n; d++) {
    uint64_t occ = 0;
    size_t vox = (size_t)c->R * c->R * c->R;
    for (size_t i = 0; i < vox; i++) occ += c->lv[d].geo[i].area > 0;
    c->report.occupied[d] = occ;
  }
  c->report.cascade_bytes = gi_cascade_bytes(c);
  if (report) *report = c->report;
  *out = c;
  return GI_OK;
fail:
  gi_cascade_free(c);
  return rc;
}

typedef struct {
  const struct gi_cascade *c;
  const double *pts;
  gi_probe *out;
} gather_ctx;

static void gather_one(const struct gi_cascade *c, const float p[3], gi_probe *pr, uint64_t seed) {
  const gi_scene *s = c->scene;
  const gi_quality *q = &c->report.quality;
  memset(pr, 0, sizeof *pr);
  const float up[3] = {0, s->up == GI_UP_Z ? 0.f : 1.f, s->up == GI_UP_Z ? 1.f : 0.f};
  /* Direct light: shadow rays from the point itself. */
  gi_light_plan lp = gi__light_plan(&c->report, q->probe_samples);
  int cap = q->probe_samples * 2 + (int)s->num_lights + 8;
  gi_ray_scratch sc = {0};
  if (gi__scratch_alloc(&sc, cap) == 0) {
    gi_lsample *ls = sc.ls;
    float *org = sc.org, *dir = sc.dir, *tn = sc.tn, *tf = sc.tf;
    uint8_t *vis = sc.vis;
    uint64_t rng = gi__mix64(seed);
    int n = gi__light_samples(s, &lp, p, &rng, ls, cap);
    float eps = (float)(1e-4 * c->s0);
    for (int i = 0; i < n; i++) {
      memcpy(&org[3 * i], p, sizeof(float[3]));
      memcpy(&dir[3 * i], ls[i].w, sizeof(float[3]));
      tn[i] = eps;
      tf[i] = isinf(ls[i].dist) ? INFINITY : ls[i].dist * 0.999f;
    }
    gi__occluded(s, n, org, dir, tn, tf, vis);
    int mb = lp.emissive && s->num_emitters ? q->probe_samples : 0;
    float pb = (float)mb / (4 * PI_F);
    for (int i = 0; i < n; i++) {
      if (!vis[i]) continue;
      /* Balance heuristic against the uniform sphere samples below. */
      float f = ls[i].mpl > 0 ? ls[i].mpl / (ls[i].mpl + pb) : 1.f;
      float V[3] = {f * ls[i].V[0], f * ls[i].V[1], f * ls[i].V[2]};
      gi__sh_add(pr->sh_direct, ls[i].w, V, 1.0f);
      float cu = gi__dot(up, ls[i].w);
      if (cu > 0)
        for (int k = 0; k < 3; k++) pr->direct[k] += V[k] * cu;
    }
    /* Uniform sphere rays: near, large emitters (see inject.c). */
    for (int j = 0; j < mb; j++) {
      float z = 1 - 2 * ((float)j + gi__u01(&rng)) / (float)mb;
      float r = sqrtf(fmaxf(0.f, 1 - z * z)), phi = 2 * PI_F * gi__u01(&rng);
      float w[3] = {r * cosf(phi), r * sinf(phi), z};
      float V[3];
      if (!gi__emitter_ray(s, p, w, eps, q->probe_samples, pb, V)) continue;
      gi__sh_add(pr->sh_direct, w, V, 1.0f);
      float cu = gi__dot(up, w);
      if (cu > 0)
        for (int k = 0; k < 3; k++) pr->direct[k] += V[k] * cu;
    }
  }
  gi__scratch_free(&sc);
  gi__sh_radiance_to_irradiance(pr->sh_direct);

  /* Indirect light: the cone set on both hemispheres around up. */
  float sh_ind[9][3] = {{0}};
  int d = gi__finest_level_at(c, p);
  float t0 = (float)(d >= 0 ? c->lv[d].s : c->s0);
  float domega = 2 * PI_F / (float)c->num_cones;
  float occ = 0;
  for (int hemi = 0; hemi < 2; hemi++) {
    float n[3], t[3], b[3];
    for (int k = 0; k < 3; k++) n[k] = hemi ? -up[k] : up[k];
    gi__basis(n, t, b);
    for (int ci = 0; ci < c->num_cones; ci++) {
      const float *cd = c->cone_dir[ci];
      float w[3];
      for (int k = 0; k < 3; k++) w[k] = cd[0] * t[k] + cd[1] * b[k] + cd[2] * n[k];
      gi_cone_out co;
      if (d >= 0) {
        gi__cone_trace(c, p, w, c->cone_tan, t0, q->step, q->ao_lambda, &co);
      } else {
        memset(&co, 0, sizeof co);
      }
      gi__sh_add(sh_ind, w, co.L, domega);
      if (!hemi) {
        for (int k = 0; k < 3; k++) pr->indirect[k] += c->cone_weight[ci] * co.L[k];
        occ += c->cone_weight[ci] * co.occlusion;
      }
    }
  }
  gi__sh_radiance_to_irradiance(sh_ind);
  for (int i = 0; i < 9; i++)
    for (int k = 0; k < 3; k++) pr->sh[i][k] = pr->sh_direct[i][k] + sh_ind[i][k];
  for (int k = 0; k < 3; k++) pr->irradiance[k] = pr->direct[k] + pr->indirect[k];
  pr->ao = c->report.effects[GI_FX_AO].ran ? 1.0f - occ / PI_F : 1.0f;
}

static void gather_range(void *p, size_t b, size_t e, int worker) {
  gather_ctx *g = p;
  const struct gi_cascade *c = g->c;
  for (size_t i = b; i < e; i++) {
    float pl[3];
    for (int k = 0; k < 3; k++) pl[k] = (float)(g->pts[3 * i + k] - c->scene->origin[k]);
    /* Seed by position so a probe's noise does not depend on its index. */
    uint64_t h = c->report.quality.seed;
    for (int k = 0; k < 3; k++) {
      uint32_t bits;
      memcpy(&bits, &pl[k], 4);
      h = gi__mix64(h ^ bits);
    }
    gather_one(c, pl, &g->out[i], h);
  }
}

gi_result gi_cascade_gather(const gi_cascade *c, const double *pts, size_t n, gi_probe *out,
                            double *ms, gi_error_info *err) {
  if (!c || (!pts && n) || (!out && n)) return gi__fail(err, GI_ERR_INVALID_ARG, "gather: missing arguments");
  for (size_t i = 0; i < 3 * n; i++)
    if (!isfinite(pts[i]))
      return gi__fail(err, GI_ERR_NONFINITE, "gather: point %zu has a non-finite coordinate", i / 3);
  double t0 = gi__now_ms();
  gather_ctx g = {c, pts, out};
  gi__parallel_for(n, 1, c->report.quality.threads, gather_range, &g);
  if (ms) *ms = gi__now_ms() - t0;
  return GI_OK;
}
