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

void gi__hemisphere_jobs(const struct gi_cascade *c, const gi_gather_start *g, const float n[3], gi_cone_job *jobs) {
  float t[3], b[3];
  gi__basis(n, t, b);
  for (int ci = 0; ci < c->num_cones; ci++) {
    const float *cd = c->cone_dir[ci];
    gi_cone_job *j = &jobs[ci];
    memcpy(j->o, g->o, sizeof j->o);
    memcpy(j->n, g->n, sizeof j->n);
    for (int k = 0; k < 3; k++) j->w[k] = cd[0] * t[k] + cd[1] * b[k] + cd[2] * n[k];
    j->t0 = g->t0;
    j->h0 = g->h0;
  }
}

int gi__gather_hemisphere(const struct gi_cascade *c, const float p[3], const float n[3], gi_gather_mode mode,
                          int level, gi_gather_out *out, float (*dirs)[3], gi_cone_out *cones) {
  memset(out, 0, sizeof *out);
  gi_gather_start g;
  if (!gi__gather_start(c, p, n, mode, level, &g)) {
    if (dirs) memset(dirs, 0, (size_t)c->num_cones * sizeof *dirs);
    if (cones) memset(cones, 0, (size_t)c->num_cones * sizeof *cones);
    return 0;
  }
  gi_cone_job jobs[GI_MAX_CONES];
  gi_cone_out co[GI_MAX_CONES];
  gi__hemisphere_jobs(c, &g, n, jobs);
  gi__cone_march_jobs(c, jobs, c->num_cones, c->cone_tan, g.step, g.ao_lambda, co);
  for (int ci = 0; ci < c->num_cones; ci++) {
    float cw = c->cone_weight[ci];
    for (int k = 0; k < 3; k++) out->E[k] += cw * co[ci].L[k];
    out->occlusion += cw * co[ci].occlusion;
    out->samples += co[ci].samples;
    if (dirs) memcpy(dirs[ci], jobs[ci].w, sizeof(float[3]));
    if (cones) cones[ci] = co[ci];
  }
  return 1;
}
