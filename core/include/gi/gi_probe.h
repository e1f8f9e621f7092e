/* gi_probe.h: answers at points from a baked cascade: SH L2 irradiance
 * probes and lat-long panoramas.
 *
 * Every output array is owned by the caller and written only by the call.
 * Gathers only read the cascade: any number may run at once on one
 * cascade, each taking up to the bake's `threads` workers of the shared
 * pool (see gi_quality.threads). */
#ifndef GI_PROBE_H
#define GI_PROBE_H

#include <stddef.h>
#include <stdint.h>
#include "gi_cascade.h"
#include "gi_error.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A gathered probe. sh holds SH L2 irradiance coefficients: the irradiance
 * on a surface with unit normal n is E(n) = sum_i sh[i] * Y_i(n), with the
 * real SH basis Y_0..Y_8 in the order L00, L1-1, L10, L11, L2-2, L2-1, L20,
 * L21, L22 (x, y, z = world axes). irradiance is E(up) for the scene's up
 * axis; direct and indirect split it. ao is 1 when unoccluded. */
typedef struct gi_probe {
  float sh[9][3];
  float sh_direct[9][3];
  float irradiance[3];
  float direct[3];
  float indirect[3];
  float ao;
} gi_probe;

/* Gathers n probes at world points pts[3*i..]. Non-finite points give
 * GI_ERR_NONFINITE. Thread-safe on a baked cascade. ms (may be NULL)
 * receives the gather time. */
gi_result gi_cascade_gather(const gi_cascade *c, const double *pts, size_t n, gi_probe *out,
                            double *ms, gi_error_info *err);
/* As gi_cascade_gather, checking `cancel` (may be NULL) between probes:
 * GI_ERR_CANCELLED once it fires (out is then partly written). */
gi_result gi_cascade_gather_ex(const gi_cascade *c, const double *pts, size_t n, const gi_cancel *cancel,
                               gi_probe *out, double *ms, gi_error_info *err);

/* 1 when world point p lies inside one of c's levels, where a gather
 * reads indirect light from the cascade; 0 outside every level (or p not
 * finite), where a probe's indirect light is 0, its ao 1 (no voxel there
 * to occlude it) and only its direct light, from its own shadow rays, is
 * answered. Thread-safe. */
int gi_cascade_covers(const gi_cascade *c, const double p[3]);

/* Evaluates SH L2 irradiance coefficients at unit normal n. */
void gi_sh_eval_irradiance(const float sh[9][3], const float n[3], float out[3]);

/* A lat-long panorama of the radiance arriving at one point: pixel (x, y)
 * looks along polar angle theta = pi (y + 0.5) / h from the scene's up axis
 * and azimuth phi = 2 pi (x + 0.5) / w (up Y: w = (sin t cos p, cos t,
 * sin t sin p); up Z: w = (sin t cos p, sin t sin p, cos t)). direct is what
 * a primary ray sees of emitters and the sky; indirect is the light that
 * surfaces reflect, gathered by one cone per pixel from the cascade. Each
 * array holds 3 * w * h floats (RGB interleaved, row-major), caller-owned.
 * Thread-safe on a baked cascade. */
gi_result gi_cascade_panorama(const gi_cascade *c, const double at[3], int w, int h, float *direct,
                              float *indirect, double *ms, gi_error_info *err);
/* As gi_cascade_panorama, checking `cancel` (may be NULL; gi_cancel.h)
 * between rows: GI_ERR_CANCELLED once it fires (direct and indirect are
 * then partly written). */
gi_result gi_cascade_panorama_ex(const gi_cascade *c, const double at[3], int w, int h, const gi_cancel *cancel,
                                 float *direct, float *indirect, double *ms, gi_error_info *err);

#ifdef __cplusplus
}
#endif
#endif
