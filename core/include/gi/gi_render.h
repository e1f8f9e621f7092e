/* gi_render.h: pictures of a baked cascade and of the reference, from a camera.
 *
 * The paper's final rendering step: primary rays on Embree, direct light by
 * shadow rays, indirect light by diffuse cones from the cascade, and a
 * specular cone for glossy materials. The same view path-traced
 * (gi_reference_render) is the picture to compare with. Images are linear
 * RGB floats, row-major from the top-left, 3 per pixel, owned by the caller.
 * Both renderers only read the cascade or scene: any number may run at
 * once; each uses up to `threads` threads of its own (0 = all cores). */
#ifndef GI_RENDER_H
#define GI_RENDER_H

#include <stddef.h>
#include <stdint.h>
#include "gi_bake.h"
#include "gi_error.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A pinhole camera in world coordinates. fov_deg is the full field of view
 * across the smaller image side (Mitsuba's fov_axis "smaller"). */
typedef struct gi_camera {
  double eye[3], target[3], up[3];
  double fov_deg;
  int width, height;
} gi_camera;

/* Reads the first perspective sensor of a Mitsuba XML scene: lookat origin,
 * target and up, and fov. Width and height are left as they are (Mitsuba
 * files often hold "$res"). Errors name the file and the missing field. */
gi_result gi_camera_from_mitsuba(const char *path, gi_camera *cam, gi_error_info *err);

/* Checks a camera: finite, eye != target, up not along the view, fov in
 * (0, 180), 1..8192 pixels per side. */
gi_result gi_camera_validate(const gi_camera *cam, gi_error_info *err);

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
  uint64_t diffuse_cones;            /* diffuse cones traced (all pixels) */
  uint64_t specular_cones;           /* specular cones traced: 0 when the pass is skipped */
  gi_effect effects[GI_FX_COUNT];    /* gi_cascade_view_plan, as followed */
} gi_render_stats;

/* Renders the view from the cascade into rgb (width * height * 3 floats).
 * light_samples shadow rays per pixel for sky and area lights (0 = 64);
 * *ms (may be NULL) receives the wall clock. Same as gi_cascade_render_ex
 * with those fields set. */
gi_result gi_cascade_render(const gi_cascade *c, const gi_camera *cam, int light_samples, int threads, float *rgb,
                            double *ms, gi_error_info *err);

/* Path-traces the same view with spp paths per pixel (1..1048576; same
 * materials and lights as gi_reference_irradiance: a Lambertian lobe plus,
 * on glossy materials, the Phong lobe the specular cone stands for).
 * Same as gi_reference_render_ex with those fields set. */
gi_result gi_reference_render(const gi_scene *s, const gi_camera *cam, int spp, uint64_t seed, int threads,
                              float *rgb, double *ms, gi_error_info *err);

/* Options of the _ex renderers; zero means default for every field. The
 * optional specular image makes the glossy part measurable on its own: at
 * each pixel's primary hit, specular times the radiance the glossy lobe
 * gathers (reference: the Phong lobe, sampled; cascade: the one specular
 * cone), 0 where the hit is not glossy or nothing is hit. Its part is
 * already included in rgb. */
typedef struct gi_render_opts {
  int light_samples; /* cascade: shadow rays per pixel for sky and area lights; 0 = 64 (the city's street
                        view: 35% -> 26% error against the reference, +34% render time) */
  int spp;           /* reference: paths per pixel, 1..1048576; 0 = 16 */
  uint64_t seed;     /* reference: 0 = 1 */
  int threads;       /* 0 = all cores */
  float *specular;   /* NULL, or width * height * 3 floats, caller-owned, written by the call */
} gi_render_opts;

/* gi_cascade_render and gi_reference_render with options (opts may be
 * NULL). The cascade's view reports its cost and plan in *st, the
 * reference its wall clock in *ms (either may be NULL). Thread-safety as
 * above; each call writes only its own images. */
gi_result gi_cascade_render_ex(const gi_cascade *c, const gi_camera *cam, const gi_render_opts *opts, float *rgb,
                               gi_render_stats *st, gi_error_info *err);
gi_result gi_reference_render_ex(const gi_scene *s, const gi_camera *cam, const gi_render_opts *opts, float *rgb,
                                 double *ms, gi_error_info *err);

/* Writes an 8-bit sRGB PNG from linear RGB floats times `exposure`,
 * through a temporary file renamed into place. */
gi_result gi_image_write_png(const char *path, const float *rgb, int width, int height, float exposure,
                             gi_error_info *err);

#ifdef __cplusplus
}
#endif
#endif
