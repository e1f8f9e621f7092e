/* gather.c: the one rule for where gather cones start (see trace.h).
 *
 * Every stage that gathers from the cascade (voxel bounces, probes,
 * panoramas, camera views, specular cones) goes through here, so a camera
 * view sees exactly the light the bounces see: a surface point starts its
 * cones one voxel off the surface and keeps coarse levels whose footprint
 * would reach back through it out of reach (march.c), a free-space point
 * starts at itself. */
#include <string.h>
#include "base/internal.h"
#include "scene/scene_internal.h"
#include "trace/trace.h"

/* Step along a cone, in voxels of the sampled level, when the cascade
 * carries no resolved quality (hand-built textures in tests). */
#define GI_GATHER_DEFAULT_STEP 0.5f

int gi__gather_start(const struct gi_cascade *c, const float p[3], const float *n, gi_gather_mode mode, int level,
                     gi_gather_start *g) {
  int d = level >= 0 && level < c->n ? level : gi__finest_level_at(c, p);
  float s = (float)(d >= 0 ? c->lv[d].s : c->s0);
  const gi_quality *q = &c->report.quality;
  memset(g, 0, sizeof *g);
  g->step = q->step > 0 ? q->step : GI_GATHER_DEFAULT_STEP;
  g->ao_lambda = q->ao_lambda;
  g->t0 = s;
  if (mode == GI_GATHER_SURFACE && n) {
    for (int k = 0; k < 3; k++) g->o[k] = p[k] + s * n[k], g->n[k] = n[k];
    g->h0 = s;
  } else {
    memcpy(g->o, p, sizeof(float[3]));
    g->h0 = -1.f;
  }
  return d >= 0;
}

void gi__gather_cone(const struct gi_cascade *c, const gi_gather_start *g, const float w[3], float tan_half,
                     gi_cone_out *out) {
  gi__cone_march(c, g->o, w, tan_half, g->t0, g->step, g->ao_lambda, g->h0, g->h0 >= 0 ? g->n : NULL, out);
}

/* A cone set around +Z: count directions, their weights, tan(aperture / 2). */
typedef struct {
  int n;
  const float (*dir)[3];
  const float *weight;
  float tan;
} cone_set;

static void set_jobs(const cone_set *cs, const gi_gather_start *g, const float n[3], gi_cone_job *jobs) {
  float t[3], b[3];
  gi__basis(n, t, b);
  for (int ci = 0; ci < cs->n; ci++) {
    const float *cd = cs->dir[ci];
    gi_cone_job *j = &jobs[ci];
    memcpy(j->o, g->o, sizeof j->o);
    memcpy(j->n, g->n, sizeof j->n);
    for (int k = 0; k < 3; k++) j->w[k] = cd[0] * t[k] + cd[1] * b[k] + cd[2] * n[k];
    j->t0 = g->t0;
    j->h0 = g->h0;
  }
}

void gi__hemisphere_jobs(const struct gi_cascade *c, int wide, const gi_gather_start *g, const float n[3],
                         gi_cone_job *jobs) {
  cone_set cs = wide ? (cone_set){c->num_wide_cones, c->wide_dir, c->wide_weight, c->wide_tan}
                     : (cone_set){c->num_cones, c->cone_dir, c->cone_weight, c->cone_tan};
  set_jobs(&cs, g, n, jobs);
}

void gi__cone_march_rest(const struct gi_cascade *c, const gi_cone_job *jobs, const uint8_t *done, int nj,
                         float tan_half, float step, float ao_lambda, gi_cone_out *co) {
  gi_cone_job rest[GI_MARCH_BATCH_JOBS];
  gi_cone_out got[GI_MARCH_BATCH_JOBS];
  int m = 0;
  for (int k = 0; k < nj && k < GI_MARCH_BATCH_JOBS; k++)
    if (!done[k]) rest[m++] = jobs[k];
  if (m) gi__cone_march_jobs(c, rest, m, tan_half, step, ao_lambda, got);
  m = 0;
  for (int k = 0; k < nj && k < GI_MARCH_BATCH_JOBS; k++)
    if (!done[k]) co[k] = got[m++];
}

/* The gathers req[0..count) with cone set cs into out[i] (and, when given,
 * dirs and cones: cs->n per gather, zeroed for a gather outside every
 * level); h0 (may be NULL) as gi__gather_probe_hemispheres', per gather.
 * Several gathers' cones march together, which keeps the SIMD lanes
 * fuller (one surface gather's 16 cones kept them 61% busy in a camera
 * view); each gather's sums are those of a gather alone. */
static void gather_many(const struct gi_cascade *c, const cone_set *cs, const gi_gather_req *req, const float *h0,
                        size_t count, gi_cone_adjust adjust, void *ctx, gi_gather_out *out, float (*dirs)[3],
                        gi_cone_out *cones) {
  gi_cone_job jobs[GI_MARCH_BATCH_JOBS];
  gi_cone_out co[GI_MARCH_BATCH_JOBS];
  uint8_t done[GI_MARCH_BATCH_JOBS];
  size_t per = GI_MARCH_BATCH_JOBS / (size_t)cs->n; /* 32 gathers of the default set, 8 probe hemispheres */
  if (per > 32) per = 32; /* the `in` mask's bits */
  for (size_t b = 0; b < count; b += per) {
    size_t e = count - b < per ? count : b + per;
    int nj = 0, answered = 0;
    uint32_t in = 0; /* bit i - b: gather i lies in the cascade */
    gi_gather_start g;
    for (size_t i = b; i < e; i++) {
      memset(&out[i], 0, sizeof out[i]);
      const float *n = req[i].n;
      if (!gi__gather_start(c, req[i].p, n, req[i].mode, req[i].level, &g)) {
        if (dirs) memset(dirs + i * (size_t)cs->n, 0, (size_t)cs->n * sizeof *dirs);
        if (cones) memset(cones + i * (size_t)cs->n, 0, (size_t)cs->n * sizeof *cones);
        continue;
      }
      if (h0 && req[i].mode == GI_GATHER_FREE && h0[i] >= 0) {
        /* A free point h0 above a surface of normal n: the apex stays at the
         * point, the surface's level-entry rule applies (see gi__gather_probe_hemispheres). */
        memcpy(g.n, n, sizeof g.n);
        g.h0 = h0[i];
      }
      in |= 1u << (i - b);
      set_jobs(cs, &g, n, jobs + nj);
      if (adjust) {
        memset(done + nj, 0, (size_t)cs->n);
        adjust(ctx, i, jobs + nj, cs->n, done + nj, co + nj);
        for (int k = 0; k < cs->n; k++) answered += done[nj + k];
      }
      nj += cs->n;
    }
    if (!nj) continue;
    if (answered) gi__cone_march_rest(c, jobs, done, nj, cs->tan, g.step, g.ao_lambda, co);
    else gi__cone_march_jobs(c, jobs, nj, cs->tan, g.step, g.ao_lambda, co);
    int j = 0;
    for (size_t i = b; i < e; i++) {
      if (!(in >> (i - b) & 1)) continue;
      for (int ci = 0; ci < cs->n; ci++, j++) {
        float cw = cs->weight[ci];
        for (int k = 0; k < 3; k++) out[i].E[k] += cw * co[j].L[k];
        out[i].occlusion += cw * co[j].occlusion;
        out[i].samples += co[j].samples;
        if (dirs) memcpy(dirs[i * (size_t)cs->n + ci], jobs[j].w, sizeof(float[3]));
        if (cones) cones[i * (size_t)cs->n + ci] = co[j];
      }
    }
  }
}

void gi__gather_hemispheres(const struct gi_cascade *c, const gi_gather_req *req, size_t count, gi_gather_out *out) {
  cone_set cs = {c->num_cones, c->cone_dir, c->cone_weight, c->cone_tan};
  gather_many(c, &cs, req, NULL, count, NULL, NULL, out, NULL, NULL);
}

void gi__gather_probe_hemispheres(const struct gi_cascade *c, const gi_gather_req *req, const float *h0, size_t count,
                                  gi_cone_adjust adjust, void *ctx, gi_gather_out *out, float (*dirs)[3],
                                  gi_cone_out *cones) {
  cone_set cs = {c->num_probe_cones, c->probe_dir, c->probe_weight, c->probe_tan};
  gather_many(c, &cs, req, h0, count, adjust, ctx, out, dirs, cones);
}

int gi__surfaces_beside(const struct gi_cascade *c, const float o[3], float reach, float on, unsigned axes,
                        const float *skip_n, float skip_cos, float m[6][3], float r[6]) {
  int k = 0;
  for (int a = 0; a < 6; a++) {
    if (!(axes >> a & 1)) continue;
    float e[3] = {0, 0, 0}, th, ng[3], tb;
    uint32_t tri;
    e[a / 2] = (a & 1) ? -1.f : 1.f;
    if (!gi__intersect1(c->scene, o, e, on, reach, &th, &tri, ng)) continue;
    float len = gi__len(ng), sg = gi__dot(ng, e) > 0 ? -1.f : 1.f;
    if (!(len > 0)) continue;
    for (int i = 0; i < 3; i++) m[k][i] = sg * ng[i] / len;
    if (skip_n && gi__dot(m[k], skip_n) > skip_cos) continue;
    float room = reach - th;
    if (!(room > 0)) continue;
    if (gi__intersect1(c->scene, o, m[k], on, room, &tb, &tri, ng)) room = 0.5f * tb;
    r[k++] = room;
  }
  return k;
}

/* 1 when every cell of level d that o + t e crosses for t in [0, reach]
 * (e an axis) is in the window and holds no surface: the ray along e can
 * meet nothing, and is not cast (Munich's bounce spent 16 ms on them). */
static int cells_empty_along(const struct gi_cascade *c, int d, const float o[3], const float e[3], float reach) {
  const gi_level *L = &c->lv[d];
  /* Every half cell, the last at reach itself: no cell the ray crosses is skipped. */
  int steps = (int)ceilf(2.f * reach / (float)L->s);
  for (int i = 0; i <= steps; i++) {
    float t = gi__minf((float)i * 0.5f * (float)L->s, reach);
    int64_t cell[3];
    for (int a = 0; a < 3; a++) {
      cell[a] = (int64_t)floor(((double)o[a] + (double)t * e[a]) / L->s);
      if (cell[a] < L->cell0[a] || cell[a] >= L->cell0[a] + c->R) return 0;
    }
    if (L->vix[gi__slot(cell[0], cell[1], cell[2], c->R)]) return 0;
  }
  return 1;
}

void gi__away_from_beside(const struct gi_cascade *c, int d, const float n[3], const float o[3], float out[3]) {
  float reach = GI_BESIDE_REACH * (float)c->lv[d].s, m[6][3], r[6];
  unsigned axes = 0;
  for (int a = 0; a < 6; a++) {
    float e[3] = {0, 0, 0};
    e[a / 2] = (a & 1) ? -1.f : 1.f;
    /* Along the normal lie its own surface and what it faces. */
    if (fabsf(gi__dot(e, n)) <= 0.5f && !cells_empty_along(c, d, o, e, reach)) axes |= 1u << a;
  }
  int k = gi__surfaces_beside(c, o, reach, 1e-3f * (float)c->s0, axes, NULL, 0, m, r);
  out[0] = out[1] = out[2] = 0;
  for (int i = 0; i < k; i++)
    for (int a = 0; a < 3; a++) out[a] += r[i] * m[i][a];
}
