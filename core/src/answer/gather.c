/* gather.c: probes from a baked cascade.
 *
 * Direct light by shadow rays from the point itself (exact up to sampling
 * noise), indirect light by cones over the whole sphere, both projected
 * into SH L2 irradiance. */
#include <stdlib.h>
#include <string.h>
#include "answer/answer.h"
#include "base/internal.h"
#include "scene/lights.h"
#include "trace/trace.h"
#include "trace/march_internal.h"
#include "scene/scene_internal.h"

/* Keeps the gather's stream apart from the bake's, which share quality.seed. */
#define GI_GATHER_SEED_SALT 0x70726f6265ull /* "probe" */
/* The probes weight their light samples and sphere rays by the power
 * heuristic: 16 seeds x 200 probes, the direct light's spread from seed to
 * seed 0.38 -> 0.24% (Cornell box) and 3.30 -> 3.11% (city) against the
 * balance heuristic. The injection keeps the balance heuristic: there the
 * power heuristic helped the Cornell box (indirect 0.20 -> 0.11%) but not
 * the city's windows (0.60 -> 0.64%). */
#define GI_PROBE_MIS_POWER 1

typedef struct {
  const struct gi_cascade *c;
  const double *pts;
  gi_probe *out;
  int cap;             /* light samples per probe at most (gi__light_sample_cap) */
  atomic_int failed;   /* a worker ran out of memory */
} gather_ctx;

/* How far below p (along -up) the first surface lies, or -1 when none is
 * near enough for a coarse level's footprint to hold it. */
static float ground_height(const struct gi_cascade *c, const float p[3], const float up[3]) {
  const float down[3] = {-up[0], -up[1], -up[2]};
  float reach = GI_TRILINEAR_REACH * (float)c->lv[c->n - 1].s, t, ng[3];
  uint32_t tri;
  if (!gi__intersect1(c->scene, p, down, 0, reach, &t, &tri, ng)) return -1.f;
  return t;
}

/* The probes' nearest-surface rule (answer.h): per gather, its probe's. */
typedef struct {
  const struct gi_cascade *c;
  const gi_near_surface *near; /* per gather */
} near_ctx;

/* Nearer a surface than this share of s0, p - q is float noise (0 on
 * it), and the side is chosen (gi__near_surface). */
#define NEAR_SURFACE_ON 1e-3f
/* A surface whose normal is within ~84 degrees of up is a floor or a
 * ceiling for that choice, steeper ones walls. */
#define NEAR_SURFACE_LEVEL 0.1f
/* The nearest surface is the ground under an upper hemisphere when its
 * direction to the point lies within ~25 degrees of that hemisphere's up. */
#define GROUND_COS 0.9f
/* An axis ray's hit whose normal lies within ~25 degrees of the nearest
 * surface's direction is that surface (or one parallel to it). */
#define NEAR_OTHER_SAME 0.9f

gi_near_surface gi__near_surface(const struct gi_cascade *c, const float p[3]) {
  gi_near_surface ns = {0};
  float reach = GI_TRILINEAR_REACH * (float)c->lv[c->n - 1].s, q[3], h, ng[3];
  if (!gi__closest_point(c->scene, p, reach, q, &h, ng) || !(h >= 0)) return ns;
  if (h > NEAR_SURFACE_ON * (float)c->s0) {
    for (int k = 0; k < 3; k++) ns.n[k] = (p[k] - q[k]) / h;
  } else {
    /* A probe on a floor took no rule at all: its upward cones began
     * inside the floor's voxels and read its underside, 0.03 of the
     * indirect light a probe a voxel higher reads (0.26). On a level
     * surface it is taken above it, as a probe stands on the ground (a
     * room's floor is wound either way); on a wall, on the side p - q
     * says, else the side the wall faces. */
    const float up[3] = {0, c->scene->up == GI_UP_Z ? 0.f : 1.f, c->scene->up == GI_UP_Z ? 1.f : 0.f};
    float e[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]}, cu = gi__dot(ng, up), d = gi__dot(e, ng);
    float sg = fabsf(cu) > NEAR_SURFACE_LEVEL ? (cu < 0 ? -1.f : 1.f) : d < 0 ? -1.f : 1.f;
    for (int k = 0; k < 3; k++) ns.n[k] = sg * ng[k];
    if (!(gi__dot(ns.n, ns.n) > 0)) return ns;
  }
  ns.h = h, ns.have = 1;
  return ns;
}

/* A cone meeting a surface at x (unit normal m, on the cone's side),
 * nearer than its first sample: narrower than a voxel there, it is a
 * ray, and sees the light that surface's voxels send toward it, not what
 * lies behind (marched on from its first sample, past the surface, it
 * read half the surface's voxels and half those behind it, and let a lit
 * room through a thin wall: test_hardcases). One sample in the layer of
 * voxels holding x across m's main axis (the cone's side of x first; for
 * a sheet on a cell border, the cell that owns it), trilinear along the
 * surface, so it moves smoothly with x. Half a voxel in front of x,
 * trilinear in all three axes, read Munich's street probes at 8.5%
 * indirect error against 8.0% (the march from the first sample: 7.7%);
 * one voxel, nearest in all axes, 7.5%, but it jumps as hits cross voxel
 * borders. 0 when nothing there faces the cone. */
static int read_surface(const struct gi_cascade *c, const float x[3], const float m[3], const float w[3], float t,
                        gi_cone_out *o) {
  int d = gi__finest_level_at(c, x);
  if (d < 0) return 0;
  const gi_level *L = &c->lv[d];
  float s = (float)L->s, q[3], prem[3], wal = 0, sig;
  int ax = 0;
  for (int a = 1; a < 3; a++)
    if (fabsf(m[a]) > fabsf(m[ax])) ax = a;
  /* Only the face along that axis: the sample's trilinear reach along the
   * surface holds the neighbouring surfaces' voxels too, and read along w
   * their other faces showed what those send away from the point (a probe
   * 5 cm from a sealed room's corner read the sunlit roof's top through
   * the ceiling's voxels, L00 1.1-1.7 where the truth is 0: test_hardcases). */
  float wa[3] = {0, 0, 0};
  wa[ax] = w[ax] < 0 ? -1.f : 1.f;
  for (int side = 0; side < 2 && !(wal > GI_MIN_SAMPLE_WEIGHT); side++) {
    memcpy(q, x, sizeof q);
    float y = x[ax] + (side ? -1e-2f : 1e-2f) * s * m[ax];
    q[ax] = L->lo[ax] + (floorf((y - L->lo[ax]) / s) + 0.5f) * s;
    gi__sample_level(c, d, q, wa, prem, &wal, &sig);
  }
  if (!(wal > GI_MIN_SAMPLE_WEIGHT)) return 0;
  for (int k = 0; k < 3; k++) o->L[k] = prem[k] / wal;
  float D = gi__maxf(2.f * t * c->probe_tan, (float)c->s0);
  o->alpha = 1.f;
  o->occlusion = 1.f / (1.f + c->report.quality.ao_lambda * 0.5f * D);
  o->samples = 1;
  return 1;
}

void gi__near_surface_rule(const struct gi_cascade *c, const gi_near_surface *ns, gi_cone_job *jobs, int n,
                           uint8_t *done, gi_cone_out *out) {
  if (!ns->have || n < 1) return;
  /* How far the leaving cones may be lifted (below): in a gap narrower
   * than that, no further than half way to the surface across it. */
  float lift = GI_TRILINEAR_REACH * jobs[0].t0, room = lift - ns->h, t_gap, ng_gap[3];
  /* Rays leaving a point on the surface skip that surface (hit at t = 0). */
  float on = NEAR_SURFACE_ON * (float)c->s0;
  uint32_t tri_gap;
  if (room > 0 && gi__intersect1(c->scene, jobs[0].o, ns->n, on, room, &t_gap, &tri_gap, ng_gap)) room = 0.5f * t_gap;
  /* A point near several surfaces (a corner) lifts the cones leaving
   * each of them as the nearest's below: started within a voxel of the
   * ceiling, a cone leaving it read the roof's top through the ceiling's
   * coarse voxels. Free cones only: those under the ground's rule keep
   * its limits (below). */
  float om[6][3], orr[6];
  int no = gi__surfaces_beside(c, jobs[0].o, lift, on, 0x3fu /* all six axes */, ns->n, NEAR_OTHER_SAME, om, orr);
  for (int i = 0; i < n; i++) {
    gi_cone_job *j = &jobs[i];
    for (int q = 0; q < no && j->h0 < 0; q++)
      if (gi__dot(j->w, om[q]) > 0)
        for (int k = 0; k < 3; k++) j->o[k] += orr[q] * om[q][k];
    float t, ng[3], tn = gi__dot(j->w, ns->n) > 0 ? on : 0.f;
    uint32_t tri;
    if (ns->h < j->t0 && gi__intersect1(c->scene, j->o, j->w, tn, j->t0, &t, &tri, ng)) {
      float x[3] = {j->o[0] + t * j->w[0], j->o[1] + t * j->w[1], j->o[2] + t * j->w[2]};
      float len = gi__len(ng), m[3];
      float sg = gi__dot(ng, j->w) > 0 ? -1.f : 1.f; /* facing the cone */
      for (int k = 0; k < 3; k++) m[k] = len > 0 ? sg * ng[k] / len : -j->w[k];
      if (read_surface(c, x, m, j->w, t, &out[i])) {
        done[i] = 1;
        continue;
      }
      j->t0 = t;
    }
    /* A cone under the ground's level rule (h0 >= 0: a probe's upper
     * hemisphere) takes the lift only from the ground it stands on (the
     * nearest surface, below it) and within a finest voxel of it, by at
     * most what is left of that voxel, so the lift fades to none at s0:
     * only that near did its first samples' footprint hold the floor's own
     * voxels (their dark underside). Lifted from farther up or off a
     * facade, Munich's street probes (2 m up, 1.1 s0) read the path
     * tracer's indirect light worse: 8.21 -> 9.90%, and 8.69% with the
     * voxel's limit alone (gi-accuracy, default quality). */
    float r = room;
    if (j->h0 >= 0) r = gi__dot(ns->n, j->n) > GROUND_COS ? gi__minf(room, (float)c->s0 - ns->h) : 0.f;
    if ((j->h0 >= 0 && !(r > 0)) || !(gi__dot(j->w, ns->n) > 0)) continue;
    memcpy(j->n, ns->n, sizeof j->n);
    j->h0 = ns->h;
    /* Nearer than its footprint, even the finest level there reaches
     * back: the cone starts where the first samples' footprint clears the
     * surface, as a surface gather's starts clear of its own (there a
     * voxel up). test_hardcases' thin wall leaked 59% into a probe a
     * quarter voxel from it; 4.8% lifted a voxel, 2.4% lifted 1.5. Reading
     * only the axes across the normal wherever the footprint reached the
     * surface instead (no lift) leaked 3.7% and took Munich's indirect
     * error from 7.7 to 8.5%: at coarse levels it hid the facade across
     * the street too. */
    if (r > 0) {
      for (int k = 0; k < 3; k++) j->o[k] += r * ns->n[k];
      j->h0 = ns->h + r;
    }
  }
}

static void near_adjust(void *ctx, size_t gather, gi_cone_job *jobs, int n, uint8_t *done, gi_cone_out *out) {
  const near_ctx *nc = ctx;
  gi__near_surface_rule(nc->c, &nc->near[gather], jobs, n, done, out);
}

/* The probe's direct light: shadow rays from the point itself (up: the
 * scene's up axis). Clears pr. */
static void gather_direct(const struct gi_cascade *c, const float p[3], const float up[3], const gi_near_surface *ns,
                          gi_probe *pr, uint64_t seed, gi_ray_scratch *scr) {
  const gi_scene *s = c->scene;
  const gi_quality *q = &c->report.quality;
  memset(pr, 0, sizeof *pr);
  gi_light_plan lp = gi__answer_light_plan(s, &c->report, q->probe_samples);
  int cap = scr->cap;
  gi_lsample *ls = scr->ls;
  uint8_t *vis = scr->vis;
  uint64_t rng = gi__mix64(seed);
  int n = gi__light_samples(s, &lp, p, &rng, ls, cap);
  /* A probe is a point in space: the shadow rule without a normal, whose
   * rays ignore hits nearer than the offset. A point nearer a surface than
   * that starts its rays the offset off it, on the side the near-surface
   * rule gives it, and ignores nothing: 1 mm under a sunlit ceiling it
   * read full sun through it (the path tracer's rays ignore 2e-5 of the
   * scene's extent). */
  float voxel = gi__voxel_at(c, p), off = gi__shadow_offset(voxel), o0[3], tn0 = off;
  memcpy(o0, p, sizeof o0);
  if (ns->have && ns->h < off) {
    for (int k = 0; k < 3; k++) o0[k] = p[k] + (off - ns->h) * ns->n[k];
    tn0 = 0.f;
    gi__shadow_rays_from(s, p, o0, tn0, ls, n, scr);
  } else {
    gi__shadow_rays(s, p, NULL, voxel, ls, n, scr);
  }
  int mb = lp.emissive && s->num_emitters ? q->probe_samples : 0;
  float pb = (float)mb / (4 * GI_PI_F);
  for (int i = 0; i < n; i++) {
    if (!vis[i]) continue;
    /* MIS against the uniform sphere samples below. */
    float f = gi__mis_light(ls[i].mpl, pb, GI_PROBE_MIS_POWER);
    float V[3] = {f * ls[i].V[0], f * ls[i].V[1], f * ls[i].V[2]};
    gi__sh_add(pr->sh_direct, ls[i].w, V, 1.0f);
    float cu = gi__dot(up, ls[i].w);
    if (cu > 0)
      for (int k = 0; k < 3; k++) pr->direct[k] += V[k] * cu;
  }
  /* Uniform sphere rays: near, large emitters (see inject.c); stratified
   * in z and, by the radical inverse, in azimuth. */
  float rot = mb ? gi__u01(&rng) : 0.f;
  float w[GI_EMIT_RAYS][3], o[GI_EMIT_RAYS][3], tn[GI_EMIT_RAYS], pbs[GI_EMIT_RAYS], V[GI_EMIT_RAYS][3];
  uint8_t hit[GI_EMIT_RAYS];
  for (int b = 0; b < mb; b += GI_EMIT_RAYS) {
    int nb = mb - b < GI_EMIT_RAYS ? mb - b : GI_EMIT_RAYS;
    for (int i = 0; i < nb; i++) {
      int j = b + i;
      float z = 1 - 2 * ((float)j + gi__u01(&rng)) / (float)mb;
      float r = sqrtf(fmaxf(0.f, 1 - z * z)), phi = 2 * GI_PI_F * gi__radical2_rot((uint32_t)j, rot);
      w[i][0] = r * cosf(phi), w[i][1] = r * sinf(phi), w[i][2] = z;
      memcpy(o[i], o0, sizeof o[i]);
      tn[i] = tn0;
      pbs[i] = pb;
    }
    gi__emitter_rays(s, p, nb, (const float(*)[3])o, (const float(*)[3])w, tn, q->probe_samples, pbs,
                     GI_PROBE_MIS_POWER, V, hit);
    for (int i = 0; i < nb; i++) {
      if (!hit[i]) continue;
      gi__sh_add(pr->sh_direct, w[i], V[i], 1.0f);
      float cu = gi__dot(up, w[i]);
      if (cu > 0)
        for (int k = 0; k < 3; k++) pr->direct[k] += V[i][k] * cu;
    }
  }
  gi__sh_radiance_to_irradiance(pr->sh_direct);
}

/* The probe's two gathers: the probes' cone set on both hemispheres
 * around up, by the gather's free-space rule (the upper one keeps the
 * ground's level limit, h0). */
static void probe_requests(const struct gi_cascade *c, const float p[3], const float up[3], gi_gather_req req[2],
                           float h0[2]) {
  const float down[3] = {-up[0], -up[1], -up[2]};
  req[0] = gi__gather_req(p, up, GI_GATHER_FREE, -1);
  req[1] = gi__gather_req(p, down, GI_GATHER_FREE, -1);
  h0[0] = ground_height(c, p, up), h0[1] = -1.f;
}

/* Indirect light from the two gathers (go, dirs and cones per hemisphere)
 * into SH L2, and the probe's sums. */
static void probe_finish(const struct gi_cascade *c, const gi_gather_out go[2], const float (*dirs)[3],
                         const gi_cone_out *cones, gi_probe *pr) {
  float sh_ind[9][3] = {{0}};
  float domega = 2 * GI_PI_F / (float)c->num_probe_cones;
  int nc = c->num_probe_cones;
  for (int hemi = 0; hemi < 2; hemi++)
    for (int ci = 0; ci < nc; ci++) gi__sh_add(sh_ind, dirs[hemi * nc + ci], cones[hemi * nc + ci].L, domega);
  memcpy(pr->indirect, go[0].E, sizeof go[0].E);
  float occ = go[0].occlusion;
  gi__sh_radiance_to_irradiance(sh_ind);
  for (int i = 0; i < 9; i++)
    for (int k = 0; k < 3; k++) pr->sh[i][k] = pr->sh_direct[i][k] + sh_ind[i][k];
  for (int k = 0; k < 3; k++) pr->irradiance[k] = pr->direct[k] + pr->indirect[k];
  pr->ao = c->report.effects[GI_FX_AO].ran ? 1.0f - occ / GI_PI_F : 1.0f;
}

/* Probes gathered together: their hemispheres' cones march in one batch. */
#define PROBE_BATCH 4

static void gather_range(void *p, size_t b, size_t e, int worker) {
  gather_ctx *g = p;
  const struct gi_cascade *c = g->c;
  gi_ray_scratch sc = {0};
  if (gi__scratch_alloc(&sc, g->cap)) {
    atomic_store(&g->failed, 1);
    return;
  }
  /* One seed for every probe: the same light samples at every point, so
   * a probe's noise does not depend on its index and varies smoothly as
   * the point moves (no popping along a walk; seeding by position made a
   * step of s0/16 change the direct light by up to 40%). */
  const uint64_t seed = gi__mix64(c->report.quality.seed ^ GI_GATHER_SEED_SALT);
  int nc = c->num_probe_cones;
  const float up[3] = {0, c->scene->up == GI_UP_Z ? 0.f : 1.f, c->scene->up == GI_UP_Z ? 1.f : 0.f};
  gi_gather_req req[2 * PROBE_BATCH];
  float h0[2 * PROBE_BATCH];
  gi_near_surface near[2 * PROBE_BATCH];
  gi_gather_out go[2 * PROBE_BATCH];
  float dirs[2 * PROBE_BATCH * GI_MAX_CONES][3];
  gi_cone_out cones[2 * PROBE_BATCH * GI_MAX_CONES];
  for (size_t i0 = b; i0 < e; i0 += PROBE_BATCH) {
    size_t m = e - i0 < PROBE_BATCH ? e - i0 : PROBE_BATCH;
    for (size_t j = 0; j < m; j++) {
      float pl[3];
      for (int k = 0; k < 3; k++) pl[k] = (float)(g->pts[3 * (i0 + j) + k] - c->scene->origin[k]);
      near[2 * j] = near[2 * j + 1] = gi__near_surface(c, pl);
      gather_direct(c, pl, up, &near[2 * j], &g->out[i0 + j], seed, &sc);
      probe_requests(c, pl, up, req + 2 * j, h0 + 2 * j);
    }
    near_ctx nctx = {c, near};
    gi__gather_probe_hemispheres(c, req, h0, 2 * m, near_adjust, &nctx, go, dirs, cones);
    for (size_t j = 0; j < m; j++)
      probe_finish(c, go + 2 * j, (const float(*)[3])(dirs + 2 * j * nc), cones + 2 * j * nc, &g->out[i0 + j]);
  }
  gi__scratch_free(&sc);
}

int gi_cascade_covers(const gi_cascade *c, const double p[3]) {
  /* A partial cascade's levels are placed at a viewpoint their light is not from. */
  if (!c || !p || c->torn) return 0;
  float pl[3];
  for (int k = 0; k < 3; k++) {
    if (!isfinite(p[k])) return 0;
    pl[k] = (float)(p[k] - c->scene->origin[k]);
  }
  return gi__finite3(pl) && gi__finest_level_at(c, pl) >= 0;
}

gi_result gi_cascade_gather(const gi_cascade *c, const double *pts, size_t n, gi_probe *out,
                            double *ms, gi_error_info *err) {
  return gi_cascade_gather_ex(c, pts, n, NULL, out, ms, err);
}

gi_result gi_cascade_gather_ex(const gi_cascade *c, const double *pts, size_t n, const gi_cancel *cancel,
                               gi_probe *out, double *ms, gi_error_info *err) {
  if (!c || (!pts && n) || (!out && n))
    return gi__fail(err, GI_ERR_INVALID_ARG, "gather: %s is NULL", !c ? "cascade" : !pts ? "pts" : "out");
  if (gi__cascade_whole(c, "gather", err) != GI_OK) return GI_ERR_INVALID_ARG;
  /* No caller holds 3n doubles and n probes past this: 3 * n below would
   * wrap, check a few points and gather the rest from unread memory. */
  if (n > SIZE_MAX / sizeof *out)
    return gi__fail(err, GI_ERR_INVALID_ARG, "gather: n = %zu probes cannot fit in memory", n);
  for (size_t i = 0; i < 3 * n; i++)
    if (!isfinite(pts[i]))
      return gi__fail(err, GI_ERR_NONFINITE, "gather: point %zu has a non-finite coordinate", i / 3);
  double t0 = gi__now_ms();
  gi_light_plan lp = gi__answer_light_plan(c->scene, &c->report, c->report.quality.probe_samples);
  gather_ctx g = {.c = c, .pts = pts, .out = out, .cap = gi__light_sample_cap(c->scene, &lp)};
  atomic_init(&g.failed, 0);
  if (gi__parallel_for_cancel(n, 1, c->report.quality.threads, gather_range, &g, &g.failed, cancel))
    return gi__cancel_fail(cancel, err, "gather");
  if (atomic_load(&g.failed))
    return gi__fail(err, GI_ERR_NOMEM, "gather: out of memory for the light-sample buffers (%d samples)", g.cap);
  if (ms) *ms = gi__now_ms() - t0;
  return GI_OK;
}
