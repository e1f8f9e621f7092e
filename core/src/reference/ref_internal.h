/* ref_internal.h: the reference path tracer's own sampling, lights and
 * camera (reference/ only).
 *
 * The reference judges the cone tracer, so it shares none of its sampling
 * code: not the light sampler (scene/lights.c), not the camera
 * (answer/camera.c), not the basis or the random numbers of base/internal.h.
 * A bug there then shows up as a disagreement instead of cancelling out.
 * What it shares is the scene's data and the BVH queries (io/bvh_embree.c),
 * the physics being defined by them. */
#ifndef GI_REF_INTERNAL_H
#define GI_REF_INTERNAL_H

#include <stdint.h>
#include "base/internal.h"
#include "gi/gi_reference.h"
#include "gi/gi_render.h"
#include "scene/scene_internal.h"

/* ---- ref_sampling.c: random numbers, frames, directions, SH ---------- */

/* PCG32 (O'Neill 2014, XSH-RR): 64-bit state, odd increment = stream. */
typedef struct ref_rng {
  uint64_t state, inc;
} ref_rng;
static inline uint32_t ref_rng_u32(ref_rng *r) {
  uint64_t old = r->state;
  r->state = old * 6364136223846793005ULL + r->inc;
  uint32_t xs = (uint32_t)(((old >> 18) ^ old) >> 27), rot = (uint32_t)(old >> 59);
  return (xs >> rot) | (xs << ((32 - rot) & 31));
}
/* Uniform in [0, 1): the top 24 bits, exact in a float. */
static inline float ref_u01(ref_rng *r) { return (float)(ref_rng_u32(r) >> 8) * (1.0f / 16777216.0f); }
/* Uniform in [0, 1) with 53 bits (two draws): an emitter pick walks a
 * dozen levels of the light tree, each rescaling u, and 24 bits would run
 * out for emitters of small probability. */
static inline double ref_u01d(ref_rng *r) {
  uint64_t a = ref_rng_u32(r) >> 5, b = ref_rng_u32(r) >> 6;
  return ((double)a * 67108864.0 + (double)b) * (1.0 / 9007199254740992.0);
}
/* A stream from a key: both state and increment are hashed from it. */
void gi__ref_rng_seed(ref_rng *r, uint64_t key);
/* Mixes v into the hash h (MurmurHash3's 64-bit finaliser). */
uint64_t gi__ref_hash(uint64_t h, uint64_t v);

/* Orthonormal t, b with unit n as the third axis: Gram-Schmidt of the
 * world axis least aligned with n. */
void gi__ref_frame(const float n[3], float t[3], float b[3]);
/* Cosine-weighted direction about unit n (pdf cos / pi). */
void gi__ref_cosine(const float n[3], ref_rng *r, float w[3]);
/* Uniform direction on the sphere (pdf 1 / (4 pi)). */
void gi__ref_sphere(ref_rng *r, float w[3]);

/* SH L2 in the gi_bake.h basis order: adds weight * Y(w) * L. */
void gi__ref_sh_add(float sh[9][3], const float w[3], const float L[3], float weight);
/* Radiance coefficients to irradiance ones (the clamped-cosine convolution). */
void gi__ref_sh_to_irradiance(float sh[9][3]);

/* ---- ref_lights.c: next-event estimation ---------------------------- */

/* One emissive triangle of the picking table. */
typedef struct ref_emitter {
  double cdf;       /* power pick: cumulative probability up to and including this one */
  float pick;       /* power pick: this one's probability */
  float area;
  uint32_t tri;     /* triangle index; the table is in ascending order (the scene's emitter slots) */
} ref_emitter;

typedef struct ref_lights {
  const gi_scene *s;
  float up[3];      /* the scene's up axis */
  float sky[3];     /* every sky light's radiance, summed */
  int has_sky;
  float eps;        /* ray offset, scaled to the scene */
  float extent;     /* the scene's largest side */
  int by_tree;      /* GI_REF_PICK_TREE: picks from the scene's light tree, seen from the point */
  int lights;       /* the light kinds paths see (gi_reference_opts.lights, never 0 here) */
  uint32_t num_emitters;
  ref_emitter *em;  /* NULL when there are none */
} ref_lights;

/* Builds the table from the scene's triangles and materials; pick is a
 * gi_ref_pick (by power, distance and orientation from the scene's light
 * tree, or by area times mean emission alone); lights (a mask as
 * gi_reference_opts.lights, 0 = all) leaves out the kinds it does not
 * name: no sky, no emitter table, delta lights that give nothing. GI_ERR_NOMEM when out of
 * memory, GI_ERR_INTERNAL when the scene's emitter slots disagree with the
 * table (the tree's picks would then name other triangles). */
gi_result gi__ref_lights_init(ref_lights *L, const gi_scene *s, int pick, int lights, gi_error_info *err);
/* 1 when the paths see light kind fx (a gi_effect_id). */
static inline int ref_light_on(const ref_lights *L, int fx) { return L->lights >> fx & 1; }
void gi__ref_lights_free(ref_lights *L);
/* The table entry u in [0, 1) picks for shading point x, and its probability. */
uint32_t gi__ref_emitter_pick(const ref_lights *L, const float x[3], double u, double *prob);
/* The probability that a pick for x returns entry q (what MIS must use). */
double gi__ref_emitter_pick_prob(const ref_lights *L, const float x[3], uint32_t q);

/* An eye or a probe further than this from the scene's origin loses its
 * float precision (past 3.4e38 its offset is Inf and a path NaN). */
#define REF_MAX_DIST 1e9

/* A sun, point or spot light seen from x: unit direction w toward it,
 * distance (INFINITY for the sun) and the irradiance E it gives a surface
 * facing it. 0 when it gives x nothing (outside a spot's cone, a sky). */
int gi__ref_delta_light(const ref_lights *L, const gi_light *l, const float x[3], float w[3], float *dist, float E[3]);
/* One area sample of the emitters seen from x: direction, distance, the
 * sample's solid-angle pdf and the emitted radiance. 0 when the point is
 * behind its triangle (one-sided) or there are no emitters. */
int gi__ref_emitter_sample(const ref_lights *L, const float x[3], ref_rng *r, float w[3], float *dist, float *pdf,
                       float Le[3]);
/* Solid-angle pdf with which gi__ref_emitter_sample from x draws the point at
 * distance t on triangle tri, seen at cosine cos_e; 0 for a non-emitter. */
float gi__ref_emitter_pdf(const ref_lights *L, const float x[3], uint32_t tri, float t, float cos_e);
/* A shadow ray stops this fraction short of the light's sample point, so it
 * does not hit the emitter it aims at. */
#define REF_SHADOW_SHORTEN 0.999f
/* Shadow rays of one point, traced REF_BATCH at a time (one BVH call per
 * batch: a city has hundreds of street lights). Lives on the stack. */
#define REF_BATCH 32
typedef struct ref_batch {
  int n;
  float org[3 * REF_BATCH], dir[3 * REF_BATCH], tn[REF_BATCH], tf[REF_BATCH];
  float V[REF_BATCH][3]; /* what each ray brings when nothing blocks it */
  uint8_t vis[REF_BATCH];
} ref_batch;
/* Queues the segment o + t w, t in [tnear, tfar], carrying V; flushes first when full. */
void gi__ref_batch_add(ref_batch *b, const ref_lights *L, const float o[3], const float w[3], float tnear, float tfar,
                   const float V[3], float E[3], float sh[9][3]);
/* Traces the queued rays; each unblocked one adds V to E or, with sh,
 * V along its direction to sh and V times its cosine to the up axis to E. */
void gi__ref_batch_flush(ref_batch *b, const ref_lights *L, float E[3], float sh[9][3]);
/* Light tracing from point and spot lights toward a probe (reference.c):
 * the light reflected once from a point light is a spike on the few
 * surfaces next to it (a street lamp's own head, 10 cm above its light,
 * gets 10^4 times a street's irradiance), which the probe's path direction
 * finds only rarely. A light picked in proportion to lum(I) / d^2 from the
 * probe shoots a uniform direction; the surface it meets reflects toward
 * the probe. The probe path's first vertex weighs the same light's term by
 * the balance heuristic against it. */
typedef struct ref_lt {
  const float *p;   /* the probe */
  float pb;         /* solid-angle pdf of the probe path's direction */
  double total;     /* sum of gi__ref_lt_weight over the scene's lights; 0: no light tracing */
} ref_lt;
/* Light l's pick weight seen from probe p: lum(I) / max(d^2, floor) for a
 * point or spot light, 0 for others. */
double gi__ref_lt_weight(const ref_lights *L, const gi_light *l, const float p[3]);
double gi__ref_lt_total(const ref_lights *L, const float p[3]);
/* Area pdf with which light tracing from lt's probe reaches a point at
 * distance dist from light l, seen from it at cosine c. */
double gi__ref_lt_pdf(const ref_lights *L, const ref_lt *lt, const gi_light *l, float c, float dist);
/* Direct irradiance at x on the side n from sun, point and spot lights and
 * one emitter sample (balance heuristic against a cosine sample, pdf
 * cos / pi). The sky is left to the cosine sample (it has no other). With
 * lt (x is then the first vertex of that probe's path), each point and
 * spot light's term is weighted against light tracing. */
void gi__ref_direct(const ref_lights *L, const float x[3], const float n[3], ref_rng *r, float E[3], const ref_lt *lt);

/* ---- ref_camera.c: the pinhole camera ---------------------------------- */

typedef struct ref_cam {
  float eye[3], fwd[3], right[3], up[3]; /* local frame */
  float half;       /* tan(fov / 2) over half the smaller side, per pixel */
  int w, h;
  int pano;         /* 1: a lat-long panorama about the scene's up axis (gi_probe.h's convention) */
  int up_z;         /* the panorama's up axis is Z (else Y) */
} ref_cam;
/* Validates cam and sets it up in the scene's local frame. */
gi_result gi__ref_cam_init(ref_cam *k, const gi_scene *s, const gi_camera *cam, gi_error_info *err);
/* A lat-long panorama of w x h pixels seen from at (world coordinates). */
gi_result gi__ref_pano_init(ref_cam *k, const gi_scene *s, const double at[3], int w, int h, gi_error_info *err);
/* Unit direction through image point (px, py), pixels from the top-left corner. */
void gi__ref_cam_dir(const ref_cam *k, float px, float py, float w[3]);

#endif
