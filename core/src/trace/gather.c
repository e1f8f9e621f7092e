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

static int gather_set(const struct gi_cascade *c, const cone_set *cs, const float p[3], const float n[3],
                      gi_gather_mode mode, int level, float h0, gi_gather_out *out, float (*dirs)[3],
                      gi_cone_out *cones) {
  memset(out, 0, sizeof *out);
  gi_gather_start g;
  int in = gi__gather_start(c, p, n, mode, level, &g);
  if (in && mode == GI_GATHER_FREE && h0 >= 0) {
    /* A free point h0 above a surface of normal n: the apex stays at the
     * point, the surface's level-entry rule applies (see gi__gather_hemisphere_probe). */
    memcpy(g.n, n, sizeof g.n);
    g.h0 = h0;
  }
  if (!in) {
    if (dirs) memset(dirs, 0, (size_t)cs->n * sizeof *dirs);
    if (cones) memset(cones, 0, (size_t)cs->n * sizeof *cones);
    return 0;
  }
  gi_cone_job jobs[GI_MAX_CONES];
  gi_cone_out co[GI_MAX_CONES];
  set_jobs(cs, &g, n, jobs);
  gi__cone_march_jobs(c, jobs, cs->n, cs->tan, g.step, g.ao_lambda, co);
  for (int ci = 0; ci < cs->n; ci++) {
    float cw = cs->weight[ci];
    for (int k = 0; k < 3; k++) out->E[k] += cw * co[ci].L[k];
    out->occlusion += cw * co[ci].occlusion;
    out->samples += co[ci].samples;
    if (dirs) memcpy(dirs[ci], jobs[ci].w, sizeof(float[3]));
    if (cones) cones[ci] = co[ci];
  }
  return 1;
}

int gi__gather_hemisphere(const struct gi_cascade *c, const float p[3], const float n[3], gi_gather_mode mode,
                          int level, gi_gather_out *out, float (*dirs)[3], gi_cone_out *cones) {
  cone_set cs = {c->num_cones, c->cone_dir, c->cone_weight, c->cone_tan};
  return gather_set(c, &cs, p, n, mode, level, -1.f, out, dirs, cones);
}

/* Cones of one gi__gather_hemispheres march at most (32 gathers of the
 * default set): enough to keep the lanes busy past a batch's drain. */
#define GATHER_BATCH_JOBS 512

void gi__gather_hemispheres(const struct gi_cascade *c, const gi_gather_req *req, size_t count, gi_gather_out *out) {
  cone_set cs = {c->num_cones, c->cone_dir, c->cone_weight, c->cone_tan};
  gi_cone_job jobs[GATHER_BATCH_JOBS];
  gi_cone_out co[GATHER_BATCH_JOBS];
  size_t per = cs.n > 0 ? GATHER_BATCH_JOBS / (size_t)cs.n : 1; /* GI_MAX_CONES <= GATHER_BATCH_JOBS */
  if (per > 32) per = 32; /* the `in` mask's bits */
  for (size_t b = 0; b < count; b += per) {
    size_t e = count - b < per ? count : b + per;
    int nj = 0;
    unsigned in = 0; /* bit i - b: request i is inside the cascade */
    gi_gather_start g;
    for (size_t i = b; i < e; i++) {
      memset(&out[i], 0, sizeof out[i]);
      if (!gi__gather_start(c, req[i].p, req[i].n, req[i].mode, req[i].level, &g)) continue;
      in |= 1u << (i - b);
      set_jobs(&cs, &g, req[i].n, jobs + nj);
      nj += cs.n;
    }
    if (!nj) continue;
    gi__cone_march_jobs(c, jobs, nj, cs.tan, g.step, g.ao_lambda, co);
    /* As gather_set sums one gather's cones. */
    const gi_cone_out *o = co;
    for (size_t i = b; i < e; i++) {
      if (!(in >> (i - b) & 1)) continue;
      for (int ci = 0; ci < cs.n; ci++) {
        float cw = cs.weight[ci];
        for (int k = 0; k < 3; k++) out[i].E[k] += cw * o[ci].L[k];
        out[i].occlusion += cw * o[ci].occlusion;
        out[i].samples += o[ci].samples;
      }
      o += cs.n;
    }
  }
}

int gi__gather_hemisphere_probe(const struct gi_cascade *c, const float p[3], const float n[3], float h0,
                                gi_gather_out *out, float (*dirs)[3], gi_cone_out *cones) {
  cone_set cs = {c->num_probe_cones, c->probe_dir, c->probe_weight, c->probe_tan};
  return gather_set(c, &cs, p, n, GI_GATHER_FREE, -1, h0, out, dirs, cones);
}
