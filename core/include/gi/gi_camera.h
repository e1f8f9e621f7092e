/* gi_camera.h: the pinhole camera of camera views, and the options both
 * renderers (gi_render.h, gi_reference.h) take. Plain values owned by the
 * caller; every function here is thread-safe. */
#ifndef GI_CAMERA_H
#define GI_CAMERA_H

#include <stddef.h>
#include <stdint.h>
#include "gi_error.h"

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

/* Reads the first perspective sensor of a Mitsuba XML scene (0.6 or 3
 * syntax): its to_world transform (matrix, lookat, translate, rotate,
 * scale, in order), its fov and fov_axis (default x) or focal_length
 * (35 mm equivalent, default 50mm), and its film's width and height
 * (Mitsuba's 768 x 576 when absent), with "$name" values from the file's
 * <default> elements. fov_deg is converted to the smaller side. A
 * transform that mirrors the image is refused. Errors name the file, the
 * line and the field. Thread-safe. */
gi_result gi_camera_from_mitsuba(const char *path, gi_camera *cam, gi_error_info *err);

/* Scales width and height so the longer side is `longest` pixels, keeping
 * the aspect (fov_deg stays across the smaller side). */
void gi_camera_fit(gi_camera *cam, int longest);

/* Checks a camera: finite, eye != target, up not along the view, fov in
 * (0, 180), 1..8192 pixels per side. */
gi_result gi_camera_validate(const gi_camera *cam, gi_error_info *err);

/* Options of the _ex renderers; zero means default for every field. The
 * optional specular image makes the glossy part measurable on its own: at
 * each pixel's primary hit, specular times the radiance the glossy lobe
 * gathers (reference: the Phong lobe, sampled; cascade: the one specular
 * cone), 0 where the hit is not glossy or nothing is hit. Its part is
 * already included in rgb. */
typedef struct gi_render_opts {
  int light_samples; /* cascade: shadow rays for sky and area lights per pixel (per anchor where the
                        anchors mix them, see indirect_stride); 0 = 64 (the city's street view: 35% ->
                        26% error against the reference, +34% render time) */
  int spp;           /* reference: paths per pixel, 1..1048576; 0 = 16 */
  uint64_t seed;     /* reference: 0 = 1 */
  int threads;       /* 0 = all cores */
  float *specular;   /* NULL, or width * height * 3 floats, caller-owned, written by the call */
  int indirect_stride; /* cascade: diffuse indirect light, and the direct light of the sampled lights
                          (sky, emitters), gathered at every Nth pixel of every Nth row and mixed
                          between those on the same surface; 1 = at every pixel;
                          0 = GI_RENDER_DEFAULT_STRIDE */
} gi_render_opts;
#define GI_RENDER_DEFAULT_STRIDE 4
#define GI_RENDER_MAX_STRIDE 16

#ifdef __cplusplus
}
#endif
#endif
