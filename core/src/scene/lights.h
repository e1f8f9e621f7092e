/* lights.h: the light sampler and the shadow-ray rule (scene/lights.c,
 * scene/shadow.c). Read-only on the scene: thread-safe. */
#ifndef GI_LIGHTS_H
#define GI_LIGHTS_H

#include "base/internal.h"
#include "gi/gi_bake.h"
#include "scene/scene_internal.h"

/* One light sample seen from a point: direction w (unit, local), distance
 * to the light (INFINITY for sun and sky) and V, such that a surface with
 * unit normal m receives irradiance V * max(0, m.w) from it when visible.
 * Solid-angle and pdf weights are folded into V. */
typedef struct gi_lsample {
  float w[3];
  float dist;
  float V[3];
  float mpl;           /* emitters: sample count times solid-angle pdf, for MIS; else 0 */
  uint8_t fx;          /* gi_effect_id of the light kind */
} gi_lsample;
/* Solid-angle pdf (times the light-sample count m) with which point p's
 * light samples reach emissive triangle tri along a ray of length t meeting
 * it at cosine cos_e. */
float gi__emitter_mpl(const gi_scene *s, const float p[3], uint32_t tri, float t, float cos_e, int m);
/* Rays per gi__emitter_rays call: its buffers live on the stack. */
#define GI_EMIT_RAYS 64
/* The shadow ray to an emitter found along a ray stops this share short
 * of it, so the emitter's own triangle (or its neighbour across an edge)
 * does not block it. */
#define GI_EMIT_SHADOW_SHORT 1e-4f
/* 1 when a ray along w meets emissive triangle tri on a side it emits
 * from (its front, either side when two-sided), with *cos_e that side's
 * cosine; 0 for a non-emitter, a degenerate triangle or its back. */
int gi__emitter_hit(const gi_scene *s, uint32_t tri, const float w[3], float *cos_e);
/* MIS companion of emitter light sampling at point p, for n <=
 * GI_EMIT_RAYS rays as two streams (the emitters found, then the shadow
 * rays in front of them). Ray i traces o[i] + t w[i] (t > tnear[i]; o[i]
 * is p's shadow-ray start); when it meets an emitter's front, hit[i] = 1
 * and out[i] = Le w_b / pb[i], with w_b its MIS weight: pb / (mpl + pb) by
 * the balance heuristic (power 0), pb^2 / (mpl^2 + pb^2) by the power
 * heuristic (power 1), mpl being the light strategy's pdf for that point
 * (m_light samples) and pb[i] the caller's own pdf times its sample count.
 * Else hit[i] = 0 and out[i] is untouched. The caller weights its light
 * samples by the same heuristic (gi__mis_light). */
void gi__emitter_rays(const gi_scene *s, const float p[3], int n, const float (*o)[3], const float (*w)[3],
                      const float *tnear, int m_light, const float *pb, int power, float (*out)[3], uint8_t *hit);
/* mb cosine-weighted rays about unit normal n from o (past tnear), for
 * the light of point p (m_light light samples): stratum j's u1 is
 * (j + u) / mb, its u2 drawn (rot NULL) or the radical inverse of j
 * rotated by *rot. Adds what their emitters give a surface facing n,
 * by the balance heuristic, to E. */
void gi__emitter_cosine_rays(const gi_scene *s, const float p[3], const float o[3], float tnear, const float n[3],
                             int mb, int m_light, uint64_t *rng, const float *rot, float E[3]);
/* A light sample's MIS weight against the caller's rays (pdf pb times
 * their count), by the balance (power 0) or power (power 1) heuristic.
 * The power form goes through the ratio pb / mpl, so a tiny far emitter
 * (mpl near float's limit) gives 1, not inf / inf. */
static inline float gi__mis_light(float mpl, float pb, int power) {
  if (!(mpl > 0)) return 1.f;
  if (!power) return mpl / (mpl + pb);
  float r = pb / mpl;
  return 1.f / (1.f + r * r);
}
/* Triangle tri's winding normal, unnormalised (length: twice its area). */
static inline void gi__tri_cross(const gi_scene *s, uint32_t tri, float ng[3]) {
  const uint32_t *ix = &s->indices[3 * tri];
  const float *A = &s->vertices[3 * ix[0]], *B = &s->vertices[3 * ix[1]], *C = &s->vertices[3 * ix[2]];
  float e1[3], e2[3];
  for (int k = 0; k < 3; k++) e1[k] = B[k] - A[k], e2[k] = C[k] - A[k];
  gi__cross(e1, e2, ng);
}
/* --- local_tree.c: point and spot lights --------------------------------- */
/* A point or spot light l seen from p into *o; 0 when it sends nothing there. */
int gi__local_sample(const gi_scene *s, const gi_light *l, const float p[3], gi_lsample *o);
/* A point samples the scene's point and spot lights through a light cut
 * when they are more than GI_LOCAL_EXACT_RATIO times the cut: at most the
 * plan's local_cut samples, every light that may bring more than
 * GI_LOCAL_CUT_SHARE of the cut's total its own, the rest one light per
 * group picked by intensity over distance squared (unbiased). The cut is
 * GI_LOCAL_CUT_PER_SAMPLE times the plan's sky and emitter samples,
 * within [GI_LOCAL_CUT_MIN, GI_LOCAL_CUT_MAX]: a voxel's 16 give 64 (its
 * noise averages out over the bounces' cones), a probe's 256 the most.
 * With fewer lights each takes its own sample: cheaper than the cut (a
 * 64-sample cut made the injection 62 -> 86 ms over 256 lamps, 35 -> 55
 * ms over 100) and without its noise. */
#define GI_LOCAL_EXACT_RATIO 4
#define GI_LOCAL_CUT_MIN 64
#define GI_LOCAL_TREE_MIN (GI_LOCAL_EXACT_RATIO * GI_LOCAL_CUT_MIN + 1)
#define GI_LOCAL_CUT_MAX 1024
#define GI_LOCAL_CUT_PER_SAMPLE 4
#define GI_LOCAL_CUT_SHARE 0.002f
/* Builds s->local_tree when the scene has GI_LOCAL_TREE_MIN point and
 * spot lights or more (needs s->lights and s->origin). */
gi_result gi__local_tree_build(gi_scene *s, gi_error_info *err);
/* The light cut's samples seen from p into out (at most min(max, cut,
 * GI_LOCAL_CUT_MAX)); draws from rng once per group. 0 without a tree. */
int gi__local_cut_samples(const gi_scene *s, const float p[3], int cut, uint64_t *rng, gi_lsample *out, int max);
/* --- light_tree.c: emitters picked by power and distance ---------------- */
/* Builds s->ltree and s->emitter_leaf over the s->num_emitters slots of
 * s->emitter_tri, power[slot] = luminance x area. */
gi_result gi__light_tree_build(gi_scene *s, const float *power, gi_error_info *err);
/* The emitter slot that u in [0, 1) picks for point p, its probability,
 * and u rescaled within the pick (uniform in [0, 1) again: stratified
 * picks that land on one emitter spread it evenly). */
uint32_t gi__light_tree_pick(const gi_scene *s, const float p[3], double u, float *prob, float *u_rest);
/* The probability that a pick from p returns slot. */
float gi__light_tree_prob(const gi_scene *s, const float p[3], uint32_t slot);
/* 0 when no emitter can send light to the side of plane (o, nrm) that nrm
 * points to (none lies ahead of it showing o its front), so a caller can
 * skip the rays that look for one; 1 when one may, or when telling would
 * take more than GI_LT_FACE_BUDGET nodes. Thread-safe (reads the tree). */
#define GI_LT_FACE_BUDGET 16
int gi__light_tree_may_face(const gi_scene *s, const float o[3], const float nrm[3]);
/* Whether some emitter's box lies within distance r of p; conservative
 * (1 when telling would take more than GI_LT_FACE_BUDGET nodes). Thread-safe. */
int gi__light_tree_within(const gi_scene *s, const float p[3], float r);
/* Whether some emitter's box reaches in front of the plane through o with
 * normal nrm: the same answer for every point of that plane (no facing
 * test), conservative, at most GI_LT_FACE_BUDGET nodes. Thread-safe. */
int gi__light_tree_ahead(const gi_scene *s, const float o[3], const float nrm[3]);
/* Which light kinds to sample, and how many rays for sky and emitters. */
typedef struct gi_light_plan {
  int sun, local, sky, emissive;
  int sky_samples, emit_samples;
  int local_cut; /* the most samples of a light cut (local_tree.c) */
} gi_light_plan;
/* The cut a plan of `samples` sky/emitter samples takes (GI_LOCAL_CUT_*). */
static inline int gi__local_cut_size(int samples) {
  long cut = (long)GI_LOCAL_CUT_PER_SAMPLE * samples;
  return (int)(cut < GI_LOCAL_CUT_MIN ? GI_LOCAL_CUT_MIN : cut > GI_LOCAL_CUT_MAX ? GI_LOCAL_CUT_MAX : cut);
}
/* 1 when a cut of `cut` samples is what s's point and spot lights take
 * (local_tree.c, GI_LOCAL_EXACT_RATIO); else each light its own sample. */
static inline int gi__local_cut_on(const gi_scene *s, int cut) {
  return s->local_tree && s->num_local > (uint32_t)(GI_LOCAL_EXACT_RATIO * cut);
}
/* 1 when plan lp samples s's point and spot lights through the light cut. */
static inline int gi__local_by_cut(const gi_scene *s, const gi_light_plan *lp) {
  return lp->local && gi__local_cut_on(s, lp->local_cut);
}
/* The light kinds the effect plan of report r enabled, with `samples` rays
 * for sky and emitters. */
gi_light_plan gi__light_plan(const gi_bake_report *r, int samples);
/* The lights an answer at a point samples (a probe, a camera view's or a
 * lightmap's surface point): report r's plan, and the sky of scene s
 * whenever it has one the request did not turn off. The plan leaves the
 * sky out of the voxels when no test ray from around the viewpoint
 * escapes (a closed room), but an answer's shadow rays start at its own
 * point, which may see the sky all the same: a probe outside the closed
 * object that a viewpoint at a model's centre lies in. Likewise the
 * emitters, which the plan leaves out when none lies within half a
 * cascade of the viewpoint. */
gi_light_plan gi__answer_light_plan(const gi_scene *s, const gi_bake_report *r, int samples);
/* 1 when answers sample the sky by the rule above (a camera's or a
 * panorama's ray that escapes also sees it). */
int gi__answer_sky(const gi_scene *s, const gi_bake_report *r);
/* Per-thread buffers for one batch of light samples and their shadow rays. */
typedef struct gi_ray_scratch {
  int cap;
  gi_lsample *ls;
  float *org, *dir, *tn, *tf;  /* 3, 3, 1, 1 floats per ray */
  uint8_t *vis;
} gi_ray_scratch;
/* Allocates cap of each; 0 on success, -1 (everything freed) when out of memory. */
int gi__scratch_alloc(gi_ray_scratch *sc, int cap);
void gi__scratch_free(gi_ray_scratch *sc);
/* The most samples gi__light_samples can return under plan lp: one per
 * sun, point and spot light, sky_samples per sky light, emit_samples for
 * the emitters. Size sample buffers with it: a smaller one drops lights. */
int gi__light_sample_cap(const gi_scene *s, const gi_light_plan *lp);
/* The shadow-ray rule, one for every stage (the path-traced reference keeps
 * its own). From a surface point with unit normal n a ray starts
 * GI_SHADOW_OFFSET_VOXELS local voxels off the surface, on the side of n
 * that faces the light, so the surface cannot shadow itself; from a point
 * in space (n NULL) it starts at the point and ignores hits closer than
 * that (a probe nearer a surface than that starts off it instead:
 * gi__shadow_rays_from). A ray toward a light at a finite distance aims from its start at
 * the sampled light point and stops GI_SHADOW_SHORTEN of the way short of
 * it, so the light's own surface does not block it. */
#define GI_SHADOW_OFFSET_VOXELS 0.02f
#define GI_SHADOW_SHORTEN 1e-3f
static inline float gi__shadow_offset(float voxel) { return GI_SHADOW_OFFSET_VOXELS * voxel; }
/* Start o of a shadow ray toward unit w from p; returns its tnear. */
float gi__shadow_origin(const float p[3], const float *n, float voxel, const float w[3], float o[3]);
/* Visibility of the count samples ls (count <= sc->cap) from p by the rule
 * above: fills sc's org/dir/tn/tf, traces them, sc->vis[i] = 1 when sample
 * i is unoccluded. voxel: the local voxel size at p. */
void gi__shadow_rays(const gi_scene *s, const float p[3], const float *n, float voxel, const gi_lsample *ls,
                     int count, gi_ray_scratch *sc);
/* gi__shadow_rays for a surface whose two sides start at different
 * points: rays toward lights on n's side leave from pp, the others from
 * pn (a thin solid's two faces in one voxel). */
void gi__shadow_rays_sided(const gi_scene *s, const float pp[3], const float pn[3], const float *n, float voxel,
                           const gi_lsample *ls, int count, gi_ray_scratch *sc);
/* gi__shadow_rays for point p's samples with the rays leaving from o past
 * tnear instead (a point in space moved off a surface it nearly touches:
 * answer/gather.c); finite ones aim at the sampled light point. */
void gi__shadow_rays_from(const gi_scene *s, const float p[3], const float o[3], float tnear, const gi_lsample *ls,
                          int count, gi_ray_scratch *sc);
/* An emitter picked by the light tree: its slot, the probability of the
 * pick and what is left of the pick's u (uniform in [0, 1) again). */
typedef struct gi_emitter_pick {
  uint32_t slot;
  float prob, u_rest;
} gi_emitter_pick;
/* m picks from point c, stratum k of u into out[k], sharing the walk
 * down the tree (in stratum order); 0 when the scene has no emitter. */
int gi__emitter_picks(const gi_scene *s, const float c[3], int m, uint64_t *rng, gi_emitter_pick *out);
/* m picks from p, pick k at u[k] (each as gi__light_tree_pick makes it);
 * with u ascending (stratified) the picks share their walk: the tree is
 * walked a level at a time, each node weighed once, two nodes per vector
 * step, so the nodes of one level overlap instead of waiting on one
 * another. Thread-safe (reads the tree). */
void gi__light_tree_picks(const gi_scene *s, const float p[3], const double *u, int m, gi_emitter_pick *out);
/* The sample of pick pk (made from any point) at point p: the whole
 * estimate in V and mpl for one sample, with pk's probability; u_rest
 * and r2 place it on the triangle. 0 when it sends nothing to p. */
int gi__emitter_sample_at(const gi_scene *s, const gi_emitter_pick *pk, float r2, const float p[3], gi_lsample *q);
/* Fills out (capacity max) with samples for point p; returns the count. */
int gi__light_samples(const gi_scene *s, const gi_light_plan *lp, const float p[3], uint64_t *rng,
                      gi_lsample *out, int max);
/* The sum of the scene's sky radiances: what a ray that escapes sees. */
void gi__sky_radiance(const gi_scene *s, float out[3]);
#endif
