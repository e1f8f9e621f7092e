/* surface.c: irradiance at a point on a surface (lightmap texels).
 *
 * The probe gather's recipe with a normal: direct light by the shared
 * light sampler and shadow-ray rule, emitter samples balanced against
 * cosine rays exactly as the voxel injection balances them (inject.c), and
 * indirect light by the cascade's diffuse cones around the normal with the
 * gather's surface rule (trace/gather.c), as camera views and the voxel
 * bounces gather, the apex moved off the surfaces beside it as a voxel
 * side's (gi__away_from_beside). Nothing here samples or marches on its own. */
#include <string.h>
#include "answer/answer.h"
#include "base/internal.h"
#include "scene/lights.h"
#include "trace/trace.h"

/* Direct light: light samples in front of the surface, then cosine rays for emitters. */
static void surface_direct(const struct gi_cascade *c, const float x[3], const float n[3], int samples, uint64_t *rng,
                           gi_ray_scratch *sc, float E[3]) {
  const gi_scene *s = c->scene;
  gi_light_plan lp = gi__answer_light_plan(s, &c->report, samples);
  gi_lsample *ls = sc->ls;
  int nl = gi__light_samples(s, &lp, x, rng, ls, sc->cap), m = 0;
  for (int i = 0; i < nl; i++)
    if (gi__dot(n, ls[i].w) > 0) ls[m++] = ls[i];
  float voxel = gi__voxel_at(c, x);
  gi__shadow_rays(s, x, n, voxel, ls, m, sc);
  int mb = lp.emissive && s->num_emitters ? lp.emit_samples : 0;
  for (int i = 0; i < m; i++) {
    if (!sc->vis[i]) continue;
    float cn = gi__dot(n, ls[i].w);
    /* Balance heuristic against the cosine rays below. */
    float f = gi__mis_light(ls[i].mpl, (float)mb * cn / GI_PI_F, 0);
    for (int k = 0; k < 3; k++) E[k] += f * ls[i].V[k] * cn;
  }
  if (!mb) return;
  float o[3];
  float tn = gi__shadow_origin(x, n, voxel, n, o);
  /* Stratified in u1 and, by the radical inverse, in azimuth. */
  float rot = gi__u01(rng);
  gi__emitter_cosine_rays(s, x, o, tn, n, mb, lp.emit_samples, rng, &rot, E);
}

/* The queued points' indirect light, marched together. */
static void flush_gathers(const struct gi_cascade *c, const gi_gather_req *req, const size_t *who, int nq,
                          float (*indirect)[3]) {
  gi_gather_out go[GI_SURFACE_BATCH];
  gi__gather_hemispheres(c, req, (size_t)nq, go);
  for (int q = 0; q < nq; q++) memcpy(indirect[who[q]], go[q].E, sizeof go[q].E);
}

void gi__surface_irradiance(const struct gi_cascade *c, const gi_surface_pt *pt, size_t count, int samples,
                            struct gi_ray_scratch *sc, float (*direct)[3], float (*indirect)[3]) {
  gi_gather_req req[GI_SURFACE_BATCH];
  size_t who[GI_SURFACE_BATCH];
  int nq = 0;
  for (size_t i = 0; i < count; i++) {
    uint64_t rng = gi__mix64(pt[i].seed);
    memset(direct[i], 0, 3 * sizeof(float));
    memset(indirect[i], 0, 3 * sizeof(float));
    surface_direct(c, pt[i].x, pt[i].n, samples, &rng, sc, direct[i]);
    int d = gi__finest_level_at(c, pt[i].x);
    if (d < 0) continue;
    /* Its apex off the surfaces beside it, as a voxel side's in the
     * bounces: a wall's top row of texels started its cones within a
     * voxel of the ceiling, and the cones going down read the ceiling's
     * voxel (0.51-0.69 of the path tracer's indirect light at the
     * Cornell box's wall-to-ceiling edge). Shifting p moves the apex
     * p + s n alike. */
    float o[3], sh[3], p[3];
    for (int k = 0; k < 3; k++) o[k] = pt[i].x[k] + (float)c->lv[d].s * pt[i].n[k];
    gi__away_from_beside(c, d, pt[i].n, o, sh);
    for (int k = 0; k < 3; k++) p[k] = pt[i].x[k] + sh[k];
    req[nq] = gi__gather_req(p, pt[i].n, GI_GATHER_SURFACE, d);
    who[nq++] = i;
    if (nq == GI_SURFACE_BATCH) flush_gathers(c, req, who, nq, indirect), nq = 0;
  }
  if (nq > 0) flush_gathers(c, req, who, nq, indirect);
}
