/* answer.h: helpers shared by the answers (probes, panoramas, camera
 * views, outputs). */
#ifndef GI_ANSWER_H
#define GI_ANSWER_H

#include "cascade/cascade_internal.h"

/* camera.c: a camera set up in the scene's local frame, shared by the
 * cone-traced and the path-traced views. */
struct gi_camera;
typedef struct gi__cam {
  float eye[3], fwd[3], right[3], upv[3];
  float tanx, tany;    /* half-extent of the image plane at distance 1 */
  int w, h;
} gi__cam;
gi_result gi__cam_setup(const gi_scene *s, const struct gi_camera *cam, gi__cam *k, gi_error_info *err);
/* Unit direction through image position (px, py), in pixels from the top-left. */
void gi__cam_ray(const gi__cam *k, float px, float py, float dir[3]);

/* sh.c */
void gi__sh_basis(const float w[3], float y[9]);
void gi__sh_add(float sh[9][3], const float w[3], const float L[3], float weight);
void gi__sh_radiance_to_irradiance(float sh[9][3]);

/* surface.c: irradiance at points x on a surface of unit normal n (the
 * side to gather): direct light by the probes' shadow-ray rule with a
 * normal (light samples balanced against cosine rays that find emitters),
 * indirect light by the cascade's cones with the gather's surface rule,
 * the points' gathers marched together (GI_SURFACE_BATCH at a time).
 * samples: light samples for sky and emitters; seed: each point's
 * stream. sc holds at least gi__light_sample_cap samples. Thread-safe. */
struct gi_ray_scratch;
typedef struct gi_surface_pt {
  float x[3], n[3];
  uint64_t seed;
} gi_surface_pt;
#define GI_SURFACE_BATCH 32
void gi__surface_irradiance(const struct gi_cascade *c, const gi_surface_pt *pt, size_t count, int samples,
                            struct gi_ray_scratch *sc, float (*direct)[3], float (*indirect)[3]);

#endif
