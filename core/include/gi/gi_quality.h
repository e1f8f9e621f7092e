/* gi_quality.h: what a bake may cost, and which effects it simulates.
 *
 * A gi_quality is a plain value owned by the caller; zero means default for
 * every field. gi_quality_resolve and gi_effect_plan only read the scene and
 * write the caller's outputs: they are thread-safe, any number may run at
 * once. Strings returned
 * by gi_effect_name are static. */
#ifndef GI_QUALITY_H
#define GI_QUALITY_H

#include <stddef.h>
#include <stdint.h>
#include "gi_error.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

#define GI_MAX_LEVELS 12
/* Largest voxel size a caller may ask for, world units (the server's limit too). */
#define GI_MAX_VOXEL 1e7
/* Smallest default voxel size (a scene under ~1e-8 units across): below
 * it the voxelizer's squared polygon areas (float, ~s^4) underflow and
 * levels read empty (a 1e-13 voxel held nothing). A given voxel0 is judged
 * against the viewpoint's distance instead (gi_cascade_anchor). */
#define GI_MIN_VOXEL 1e-9

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
  int levels;          /* cascade levels n; default 6, more for a scene wider than its
                          reach (see voxel0), at most GI_MAX_LEVELS (1..GI_MAX_LEVELS) */
  int res;             /* voxels per side R; default 32 (a multiple of 4, 8..256) */
  double voxel0;       /* finest voxel size s0; default: the coarsest level spans 1.25x the
                          scene's reach (its largest side, at most 16 heights, at least an
                          eighth of its width). When levels and voxel0 are both default and
                          the scene is wider than that reach, levels are added, each halving
                          s0, until s0 is no coarser than a piece 4 heights across gets.
                          At most GI_MAX_VOXEL; a scene whose default falls outside
                          GI_MIN_VOXEL..GI_MAX_VOXEL fails, naming the reason. */
  int cones;           /* diffuse cones per hemisphere: 4, 6, 8, 16 or 32; default 16 */
  float aperture_deg;  /* diffuse cone full aperture; default from the cone count */
  float step;          /* march step in voxels of the sampled level; default 1 (near surfaces at most 0.75) */
  int bounces;         /* voxel-to-voxel bounces after injection; 0 = auto from the albedo
                          in range (1..4, see the effect plan), -1 = none */
  int light_samples;   /* shadow rays per voxel for sky and area lights; default 16 */
  int probe_samples;   /* shadow rays per probe for sky and area lights; default 256 */
  float ao_lambda;     /* AO falloff 1/(1 + lambda r), per metre... scene unit; default 1/(4 s0) */
  int ao;              /* 1: compute ambient occlusion at gather points */
  int specular;        /* -1 off, 0 auto (glossy materials in range), 1 force on */
  int threads;         /* 0 = all cores */
  uint64_t seed;       /* sampling seed; default 1 (bakes are deterministic) */
  int effects[GI_FX_COUNT]; /* per effect: GI_FX_AUTO (0, the plan decides), GI_FX_ON, GI_FX_OFF.
                               `specular` and `ao` above still count when their entry is auto. */
  int bounce_tail;     /* 1 when the last bounce adds the geometric tail of the orders left out.
                          Out: set in reports and in gi_effect_plan's `resolved` (the plan's
                          automatic count adds it at its cap), so a resolved quality says which
                          it was, and baking it again (bounces and bounce_tail as reported)
                          runs the same. In: with an explicit bounces >= 2, 1 adds the tail
                          too; ignored with an automatic count (the plan decides). */
} gi_quality;

/* What the plan decided for one effect, and why (for reports and headers). */
typedef struct gi_effect {
  int ran;
  char why[160];
} gi_effect;

const char *gi_effect_name(gi_effect_id id); /* "sun", "local_lights", ... */
/* The id of an effect name, or -1. */
int gi_effect_from_name(const char *name);

/* Resolves every default of in (may be NULL) for scene and validates it,
 * exactly as gi_cascade_bake will, but for three that the bake decides
 * later: bounces 0 (automatic) comes out as 2, a placeholder the effect
 * plan replaces at the viewpoint (gi_effect_plan's `resolved` has the
 * count; baking with out as given would ask for 2 exactly, without the
 * plan's tail); aperture_deg 0 stays 0 (the cone set's matched width,
 * 40.7 degrees for 16 cones) and threads 0 stays 0 (all cores). The bake's
 * report holds all three as run. Thread-safe. */
gi_result gi_quality_resolve(const gi_scene *scene, const gi_quality *in, gi_quality *out,
                             gi_error_info *err);

/* The effect plan gi_cascade_bake would follow at `at` for request quality
 * q (may be NULL), without baking (for catalogs and previews). resolved
 * (may be NULL) receives the quality with the plan's bounce count.
 * Thread-safe. */
gi_result gi_effect_plan(const gi_scene *scene, const double at[3], const gi_quality *q,
                         gi_effect out[GI_FX_COUNT], gi_quality *resolved, gi_error_info *err);
/* The plan gi_cascade_bake_for would follow for answers at pts (n world
 * points; may be NULL when n is 0): its sky test also looks up from them.
 * A tiled bake plans every tile so before baking any, to give them all one
 * bounce count (resolved's bounces and bounce_tail, baked back as given). */
gi_result gi_effect_plan_for(const gi_scene *scene, const double at[3], const double *pts, size_t n,
                             const gi_quality *q, gi_effect out[GI_FX_COUNT], gi_quality *resolved,
                             gi_error_info *err);

#ifdef __cplusplus
}
#endif
#endif
