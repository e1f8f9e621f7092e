/* gi_bake.h: bake the light around a viewpoint and gather it at points.
 *
 * A bake has two phases. gi_cascade_bake builds the cascaded voxel texture
 * around a viewpoint (voxelize, inject direct light, bounce); it is the
 * expensive, cacheable part. gi_cascade_gather then answers any number of
 * points from it (final gather into SH L2 irradiance). A baked cascade is
 * read-only: any number of threads may gather from it at once. The
 * cascade retains its scene until it is freed.
 *
 * Units: irradiance in the scene's radiometric unit (W m^-2 for physical
 * inputs); positions in world coordinates (double). */
#ifndef GI_BAKE_H
#define GI_BAKE_H

#include <stddef.h>
#include <stdint.h>
#include "gi_error.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

#define GI_MAX_LEVELS 12

/* The effects a bake can simulate (the effect plan decides which run). */
typedef enum gi_effect_id {
  GI_FX_SUN = 0,       /* directional lights */
  GI_FX_LOCAL,         /* point and spot lights */
  GI_FX_SKY,
  GI_FX_EMISSIVE,      /* emissive surfaces as area lights */
  GI_FX_BOUNCE,        /* voxel-to-voxel indirect bounces */
  GI_FX_SPECULAR,
  GI_FX_AO,
  GI_FX_COUNT
} gi_effect_id;

/* Per-request override of one effect in gi_quality.effects. */
enum { GI_FX_AUTO = 0, GI_FX_ON = 1, GI_FX_OFF = -1 };

/* Quality knobs. Zero means default for every field, so
 * `gi_quality q = {0};` is the default quality. */
typedef struct gi_quality {
  int levels;          /* cascade levels n; default 6 (1..GI_MAX_LEVELS) */
  int res;             /* voxels per side R; default 32 (a multiple of 4, 8..256) */
  double voxel0;       /* finest voxel size s0; default: the coarsest level spans the scene */
  int cones;           /* diffuse cones per hemisphere: 4, 6, 8, 16 or 32; default 16 */
  float aperture_deg;  /* diffuse cone full aperture; default from the cone count */
  float step;          /* march step as a fraction of the cone diameter; default 0.5 */
  int bounces;         /* voxel-to-voxel bounces after injection; 0 = auto from the albedo
                          in range (1..3, see the effect plan), -1 = none */
  int light_samples;   /* shadow rays per voxel for sky and area lights; default 16 */
  int probe_samples;   /* shadow rays per probe for sky and area lights; default 256 */
  float ao_lambda;     /* AO falloff 1/(1 + lambda r), per metre... scene unit; default 1/(4 s0) */
  int ao;              /* 1: compute ambient occlusion at gather points */
  int specular;        /* -1 off, 0 auto (glossy materials in range), 1 force on */
  int threads;         /* 0 = all cores */
  uint64_t seed;       /* sampling seed; default 1 (bakes are deterministic) */
  int effects[GI_FX_COUNT]; /* per effect: GI_FX_AUTO (0, the plan decides), GI_FX_ON, GI_FX_OFF.
                               `specular` and `ao` above still count when their entry is auto. */
} gi_quality;

/* What the plan decided for one effect, and why (for reports and headers). */
typedef struct gi_effect {
  int ran;
  char why[160];
} gi_effect;

const char *gi_effect_name(gi_effect_id id); /* "sun", "local_lights", ... */
/* The id of an effect name, or -1. */
int gi_effect_from_name(const char *name);

/* Per-stage wall-clock milliseconds. */
typedef struct gi_timings {
  double voxelize, inject, bounce, filter, gather, encode;
} gi_timings;

/* What one bake did: counts for reports, tests and benchmarks. */
typedef struct gi_bake_report {
  gi_quality quality;          /* with every default resolved */
  gi_effect effects[GI_FX_COUNT];
  gi_timings ms;
  int levels;
  double voxel_size[GI_MAX_LEVELS];
  double level_origin[GI_MAX_LEVELS][3]; /* world min corner of each level's box */
  uint64_t occupied[GI_MAX_LEVELS];      /* voxels holding geometry, per level */
  uint64_t triangles_visited;            /* triangle/level pairs from the BVH query */
  uint64_t shadow_rays;
  uint64_t cone_samples;
  size_t cascade_bytes;
  int bounces_run;
  uint32_t glossy_triangles;             /* glossy triangles inside the cascade: a camera
                                            view's specular pass runs on auto when > 0 */
} gi_bake_report;

typedef struct gi_cascade gi_cascade;

/* Resolves every default of in (may be NULL) for scene and validates it,
 * exactly as gi_cascade_bake will. Thread-safe. */
gi_result gi_quality_resolve(const gi_scene *scene, const gi_quality *in, gi_quality *out,
                             gi_error_info *err);

/* The effect plan gi_cascade_bake would follow at `at` for request quality
 * q (may be NULL), without baking (for catalogs and previews). resolved
 * (may be NULL) receives the quality with the plan's bounce count.
 * Thread-safe. */
gi_result gi_effect_plan(const gi_scene *scene, const double at[3], const gi_quality *q,
                         gi_effect out[GI_FX_COUNT], gi_quality *resolved, gi_error_info *err);

/* The snapped placement of the cascade baked at `at` with a resolved
 * quality: two viewpoints with equal anchors (same scene and quality) give
 * bit-identical cascades, so the anchor is a cache key. Thread-safe. */
gi_result gi_cascade_anchor(const gi_scene *scene, const double at[3], const gi_quality *resolved,
                            int64_t anchor[3], gi_error_info *err);

/* Builds the cascade around `at` (world) and lights it. q may be NULL
 * (defaults). On success the caller owns *out (gi_cascade_free). */
gi_result gi_cascade_bake(const gi_scene *scene, const double at[3], const gi_quality *q,
                          gi_cascade **out, gi_bake_report *report, gi_error_info *err);
void gi_cascade_free(gi_cascade *c); /* accepts NULL */
size_t gi_cascade_bytes(const gi_cascade *c);
const gi_bake_report *gi_cascade_report(const gi_cascade *c);

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

/* Evaluates SH L2 irradiance coefficients at unit normal n. */
void gi_sh_eval_irradiance(const float sh[9][3], const float n[3], float out[3]);

/* Writes probes as an EXR, one pixel per probe in a row: channels R,G,B
 * (irradiance), direct.R/G/B, indirect.R/G/B, ao.Y (when ao ran) and the 27
 * sh.L00.R ... sh.L22.B; header attributes from the report. */
gi_result gi_probes_write_exr(const char *path, const gi_probe *probes, size_t n,
                              const gi_scene *scene, const double at[3],
                              const gi_bake_report *rep, int use_half, gi_error_info *err);

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

/* Extra string attributes for the EXR writers (name and value borrowed). */
typedef struct gi_exr_extra {
  const char *name;
  const char *value;
} gi_exr_extra;

/* gi_probes_write_exr with extra header attributes (timings, cache state). */
gi_result gi_probes_write_exr_ex(const char *path, const gi_probe *probes, size_t n,
                                 const gi_scene *scene, const double at[3],
                                 const gi_bake_report *rep, int use_half,
                                 const gi_exr_extra *extra, size_t num_extra, gi_error_info *err);

/* Writes a panorama as EXR: R,G,B (direct + indirect radiance), direct.R/G/B,
 * indirect.R/G/B; header gi.kind = "panorama" plus the probe attributes. */
gi_result gi_panorama_write_exr(const char *path, int w, int h, const float *direct,
                                const float *indirect, const gi_scene *scene, const double at[3],
                                const gi_bake_report *rep, int use_half,
                                const gi_exr_extra *extra, size_t num_extra, gi_error_info *err);

/* Writes the cascade snapshot as VDB: per level L<d>_density (fog),
 * L<d>_Cd (radiance), L<d>_albedo, L<d>_normal, and the finest level as
 * plain density and Cd. faces = 1 adds per-face grids L<d>_face_px ... */
gi_result gi_cascade_write_vdb(const gi_cascade *c, const char *path, int faces,
                               gi_error_info *err);

#ifdef __cplusplus
}
#endif
#endif
