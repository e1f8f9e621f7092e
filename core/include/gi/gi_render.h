/* gi_render.h: pictures of a baked cascade from a camera.
 *
 * The paper's final rendering step: primary rays on Embree, direct light by
 * shadow rays, indirect light by diffuse cones from the cascade, and a
 * specular cone for glossy materials. The same view path-traced
 * (gi_reference_render, gi_reference.h) is the picture to compare with.
 * Images are linear RGB floats, row-major from the top-left, 3 per pixel,
 * owned by the caller and written only by the call. Renderers only read the
 * cascade: any number may run at once; each uses up to `threads` workers
 * of the shared pool (0 = all cores). */
#ifndef GI_RENDER_H
#define GI_RENDER_H

#include <stddef.h>
#include <stdint.h>
#include "gi_camera.h"
#include "gi_cascade.h"
#include "gi_error.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The effect plan of a camera view of c: the bake's plan, with the
 * specular pass decided for an output that has a view direction.
 *   auto: runs when glossy materials (roughness < 0.5, specular > 0) lie
 *         in the cascade, and traces one cone at each of their pixels only;
 *   on:   runs, one cone at every pixel weighted by the material's
 *         specular reflectance (a forced pass costs the same in any scene;
 *         on a diffuse scene it adds exactly nothing);
 *   off:  no specular cone at all.
 * Thread-safe (reads the cascade only). */
void gi_cascade_view_plan(const gi_cascade *c, gi_effect out[GI_FX_COUNT]);

/* What one view cost. */
typedef struct gi_render_stats {
  double ms;                         /* wall clock of the whole view */
  uint64_t diffuse_cones;            /* diffuse cones traced: the anchors' and the own gathers' */
  int indirect_stride;               /* the anchors' spacing the view used (1 when it gathered no indirect light) */
  uint64_t specular_cones;           /* specular cones traced: 0 when the pass is skipped */
  uint64_t pixels_outside;           /* pixels whose surface lies outside every level of the cascade:
                                        their direct light alone, no indirect (a view reaching past
                                        what the cascade holds) */
  gi_effect effects[GI_FX_COUNT];    /* gi_cascade_view_plan, as followed */
} gi_render_stats;

/* Renders the view from the cascade into rgb (width * height * 3 floats).
 * light_samples shadow rays per pixel for sky and area lights (0 = 64);
 * *ms (may be NULL) receives the wall clock. Same as gi_cascade_render_ex
 * with those fields set. */
gi_result gi_cascade_render(const gi_cascade *c, const gi_camera *cam, int light_samples, int threads, float *rgb,
                            double *ms, gi_error_info *err);

/* gi_cascade_render with options (opts may be NULL); reports its cost and
 * plan in *st (may be NULL). */
gi_result gi_cascade_render_ex(const gi_cascade *c, const gi_camera *cam, const gi_render_opts *opts, float *rgb,
                               gi_render_stats *st, gi_error_info *err);

#ifdef __cplusplus
}
#endif
#endif
