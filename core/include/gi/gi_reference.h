/* gi_reference.h: the ground truth the cone tracer is measured against.
 *
 * A Monte Carlo path tracer on the scene's Embree BVH, with the same
 * triangles, materials and lights (sun, point, spot, sky, emissive
 * triangles) as the bake, but sampled by code of its own (light sampling,
 * camera, random streams): a sampling bug in the bake shows up as an error
 * instead of cancelling out of the comparison. The one shared piece is the
 * scene's light tree, which picks emitters by distance: only its
 * probabilities enter, and they are tested on their own. Light reflected
 * once from point and spot lights is also traced from the light (MIS with
 * the paths), so a lamp next to a surface does not make it noisy.
 * Surfaces are two-sided: a Lambertian lobe (albedo) plus, on glossy
 * materials (roughness < 0.5, specular > 0), a normalised Phong lobe of
 * weight `specular` around the mirror direction, with the exponent the
 * renderer's specular cone is sized from (see reference.c). Emitters are
 * one-sided.
 * It answers what gi_cascade_gather answers, at the same points and in the
 * same convention: irradiance on a surface facing the scene's up axis,
 * split into direct light (straight from a light or an emitter) and
 * indirect light (reflected at least once), and SH L2 irradiance over the
 * whole sphere. Each probe also carries the standard error of its mean,
 * from the per-sample variance, so a report can show that the reference's
 * own noise is far below the errors it measures.
 *
 * Determinism: every probe's samples come from a seed mixed from the
 * option seed and the probe's position, in fixed chunks whose sums are
 * added in a fixed order, so the answer is bit-identical for any thread
 * count. Thread-safety: the scene is only read; any number of calls may run
 * at once on one scene. The caller owns pts and out; nothing is retained. */
#ifndef GI_REFERENCE_H
#define GI_REFERENCE_H

#include <stddef.h>
#include <stdint.h>
#include "gi_error.h"
#include "gi_camera.h"
#include "gi_quality.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Changes whenever the reference's answers change (a fix, another random
 * stream): callers that cache its results key them on it.
 * 3: its own light sampling, camera and PCG32 streams.
 * 4: shadow rays from a surface aim at the sampled light point (nearby
 *    emitters were lost in large scenes).
 * 5: emitters picked by power, distance and orientation (the light tree).
 * 6: light tracing from point and spot lights, MIS-weighted against the
 *    path's directions (the light a street lamp's head reflects). */
#define GI_REFERENCE_VERSION 6
/* How next-event estimation picks an emissive triangle. Either way the
 * estimate is unbiased (its MIS weights use the same probabilities); they
 * differ in noise. */
typedef enum gi_ref_pick {
  /* By power over distance squared times how far the emitters can face the
   * shading point, walking the scene's light tree: a point near one window
   * of a city samples that window, not one across town. The default. */
  GI_REF_PICK_TREE = 0,
  /* By power (area times mean emission) alone, wherever the point is:
   * version 3's sampler, kept to compare against. */
  GI_REF_PICK_POWER = 1
} gi_ref_pick;

/* Zero means default for every field. */
typedef struct gi_reference_opts {
  int samples;      /* paths per probe; default 1024 (1..1<<24) */
  int max_depth;    /* reflections per path: 0 = unbounded (Russian roulette),
                       k > 0 = light reflected at most k times (the bake's
                       `bounces` B matches k = B + 1), -1 = direct light only */
  int rr_depth;     /* Russian roulette from this many reflections on; default 3 */
  uint64_t seed;    /* default 1 */
  int threads;      /* 0 = all cores */
  int emitter_pick; /* a gi_ref_pick; default GI_REF_PICK_TREE */
  int no_light_tracing; /* 1: without light tracing from point and spot
                       lights (version 5's estimator), to compare against */
  int lights;       /* the light kinds the paths see: a mask of 1 << GI_FX_SUN,
                       GI_FX_LOCAL, GI_FX_SKY and GI_FX_EMISSIVE (gi_quality.h);
                       0 = every light. Against a bake with only those effects
                       on, it tells which light a cone tracer's error comes from */
} gi_reference_opts;
/* Every light kind gi_reference_opts.lights may name. */
#define GI_REF_LIGHTS_ALL ((1 << GI_FX_SUN) | (1 << GI_FX_LOCAL) | (1 << GI_FX_SKY) | (1 << GI_FX_EMISSIVE))

/* One reference probe. Same convention as gi_probe: irradiance = direct +
 * indirect on a surface facing up; sh is SH L2 irradiance (cosine
 * convolution applied, basis order as in gi_bake.h). std_err_* are the
 * standard errors of the means above (one sigma), per channel. */
typedef struct gi_ref_probe {
  float irradiance[3], direct[3], indirect[3];
  float sh[9][3];
  float std_err[3], std_err_direct[3], std_err_indirect[3];
  uint32_t samples;
} gi_ref_probe;

/* Path-traces n probes at world points pts[3*i..] into out[i]. Non-finite
 * points, and points more than 1e9 units from the scene's origin on any
 * axis (as the panorama's), give GI_ERR_NONFINITE, bad options GI_ERR_INVALID_ARG (the
 * message names the field). ms (may be NULL) receives the wall-clock time. */
gi_result gi_reference_irradiance(const gi_scene *scene, const double *pts, size_t n,
                                  const gi_reference_opts *opts, gi_ref_probe *out, double *ms,
                                  gi_error_info *err);

/* Path-traces the same view with spp paths per pixel (1..1048576; same
 * materials and lights as gi_reference_irradiance: a Lambertian lobe plus,
 * on glossy materials, the Phong lobe the specular cone stands for).
 * Same as gi_reference_render_ex with those fields set. */
gi_result gi_reference_render(const gi_scene *s, const gi_camera *cam, int spp, uint64_t seed, int threads,
                              float *rgb, double *ms, gi_error_info *err);

/* gi_reference_render with options (opts may be NULL); *ms (may be NULL)
 * receives the wall clock. */
gi_result gi_reference_render_ex(const gi_scene *s, const gi_camera *cam, const gi_render_opts *opts, float *rgb,
                                 double *ms, gi_error_info *err);

/* Path-traces the lat-long panorama of the radiance arriving at world
 * point at, pixel for pixel the image gi_cascade_panorama gives as
 * direct + indirect (gi_probe.h: polar angle from the scene's up axis down
 * the rows, azimuth across the columns), each pixel's paths jittered over
 * its cell in angle: what a primary ray sees of emitters and the sky plus
 * the light surfaces reflect. Delta lights (the sun) show only through
 * the surfaces they light, as in the cone-traced panorama. rgb holds
 * 3 * w * h floats; opts (may be NULL) gives spp, seed and threads;
 * w x h within 2..16384 x 1..8192. */
gi_result gi_reference_panorama(const gi_scene *s, const double at[3], int w, int h, const gi_render_opts *opts,
                                float *rgb, double *ms, gi_error_info *err);

#ifdef __cplusplus
}
#endif
#endif
