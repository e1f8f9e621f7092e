/* answer.h: helpers shared by the answers (probes, panoramas, camera
 * views, outputs). */
#ifndef GI_ANSWER_H
#define GI_ANSWER_H

#include "cascade/cascade_internal.h"
#include "trace/trace.h"

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

/* render.c: a primary hit is shaded this share of its distance nearer the
 * eye. A hit on an edge (a ray square into a room's corner) lay on two
 * planes, and every shadow ray, leaving along one plane's normal, started
 * on the other and met it at t = 0: such pixels had no direct light.
 * 1e-5 of the distance moves the point off any plane the ray is not
 * parallel to and shifts nothing a voxel or a shadow ray can see. */
#define GI_PRIMARY_PULL 1e-5f

/* gather.c: the surface nearest a point in free space (a probe, a
 * panorama's eye), within the reach of the coarsest level's
 * footprint. A cone leaving it (w . n > 0) has its first samples'
 * trilinear footprint on that surface's voxels, whose far side (the back
 * of a wall, lit from the other side) it would read as light in front of
 * it: unless it has a surface already (the ground, for the upper
 * hemisphere), it takes the surface rule of a surface gather, h above
 * that surface, and starts no nearer to it than its first samples'
 * footprint reaches. A cone toward a surface nearer than its first
 * sample reads it where it meets it instead of stepping past it
 * (gather.c's read_surface). Beside a sunlit wall (the closing note's wall scene),
 * probes 0.1-1 of their level's voxel from it read 2.8-3x the path
 * tracer's indirect light, now 0.8-0.9x; a 5 cm sphere's probes 2.1x,
 * now 1.6x. The gathers of a probe near a surface take more samples:
 * 4000 random probes in Munich, 20% more gather time. Panoramas take
 * the same rule at their eye. The upper hemisphere keeps the ground's
 * rule but is lifted as well, and a point on a surface (h 0) takes the
 * side above a level one (gather.c): on a floor, probes read 0.12x the
 * indirect light of one two voxels up. Thread-safe. */
typedef struct gi_near_surface {
  int have;            /* a surface lies within reach */
  float n[3], h;       /* unit direction from it to the point; distance */
} gi_near_surface;
gi_near_surface gi__near_surface(const struct gi_cascade *c, const float p[3]);
/* Applies the rule to n free-space cone jobs from point ns was found for
 * (jobs[0].o, first sample at jobs[0].t0, the voxel of the point's level):
 * changes their starts, or answers cone k itself (done[k] = 1, out[k]). */
void gi__near_surface_rule(const struct gi_cascade *c, const gi_near_surface *ns, gi_cone_job *jobs, int n,
                           uint8_t *done, gi_cone_out *out);

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
