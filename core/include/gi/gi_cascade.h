/* gi_cascade.h: bake the light around a viewpoint.
 *
 * gi_cascade_bake builds the cascaded voxel texture around a viewpoint
 * (voxelize, inject direct light, bounce): the expensive, cacheable part.
 * Answers come from it (gi_probe.h, gi_render.h, gi_output.h).
 *
 * Ownership: the caller owns a baked cascade until gi_cascade_free. The
 * cascade retains its scene (gi_scene_retain) until it is freed, so the
 * caller may release the scene right after the bake. A baked cascade is
 * read-only: any number of threads may read it at once; it must not be
 * freed while a reader runs. gi_cascade_move (gi_move.h) is the one writer:
 * no reader may run during a move. gi_cascade_report's pointer lives as long as
 * the cascade.
 *
 * Units: irradiance in the scene's radiometric unit (W m^-2 for physical
 * inputs); positions in world coordinates (double). */
#ifndef GI_CASCADE_H
#define GI_CASCADE_H

#include <stddef.h>
#include <stdint.h>
#include "gi_cancel.h"
#include "gi_error.h"
#include "gi_quality.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Per-stage wall-clock milliseconds. plan: a cold bake's setup before
 * voxelizing (quality, placement, the effect plan's surveys and test
 * rays); a move counts its plan in inject. */
typedef struct gi_timings {
  double voxelize, inject, bounce, filter, gather, encode, plan;
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
  uint64_t cone_samples;                 /* texture samples the bounces' cones took */
  uint64_t cones_traced;                 /* cones the bounces marched */
  uint64_t taps_replayed;                /* lit samples the bounces read again from an earlier
                                            bounce's march instead of marching (bounce.c) */
  double replay_thread_ms;               /* time the replays took, summed over threads (part of
                                            ms.bounce x threads) */
  size_t tape_bytes;                     /* most bytes the replays' tapes held at once */
  size_t cascade_bytes;
  int bounces_run;
  int wide_from_level;                   /* levels from this one up gather with the bounces' wide
                                            set from the first bounce (levels: none; bounce.c) */
  uint32_t glossy_triangles;             /* glossy triangles inside the cascade: a camera
                                            view's specular pass runs on auto when > 0 */
  /* Work per level: voxels voxelized (own voxels, not the filtered region),
   * voxels whose direct light was injected, and voxel gathers the bounces
   * ran (one per voxel per bounce). A bake counts everything; a move
   * (gi_move.h) only what it redid. */
  uint64_t level_voxelized[GI_MAX_LEVELS];
  uint64_t level_injected[GI_MAX_LEVELS];
  uint64_t level_rebounced[GI_MAX_LEVELS];
} gi_bake_report;

typedef struct gi_cascade gi_cascade;

/* The snapped placement of the cascade baked at `at` with a resolved
 * quality: two viewpoints with equal anchors (same scene and quality) give
 * bit-identical cascades, so the anchor is a cache key. A viewpoint the
 * bake refuses has none: GI_ERR_NONFINITE, or GI_ERR_INVALID_ARG past 1e9
 * units (or 2^52 voxels) from the scene's origin on any axis (the limit
 * holds per axis, as for a move's, a view's eye and a panorama's
 * viewpoint). Thread-safe. */
gi_result gi_cascade_anchor(const gi_scene *scene, const double at[3], const gi_quality *resolved,
                            int64_t anchor[3], gi_error_info *err);
/* The world-space centre of anchor cell `cell` (side 2 voxel0, from the
 * scene origin): gi_cascade_anchor of it gives `cell` back, so baking or
 * gathering there answers for the whole cell. GI_ERR_INVALID_ARG for a
 * cell too far away to round-trip. Thread-safe. */
gi_result gi_cascade_cell_centre(const gi_scene *scene, const int64_t cell[3], const gi_quality *resolved,
                                 double at[3], gi_error_info *err);

/* Which of the n world points pts (3 doubles each) a cascade baked at `at`
 * with this resolved quality would cover, by gi_cascade_covers' rule,
 * known before the bake from its placement alone: only the finest level is
 * centred on the viewpoint, each coarser one holds as much of the scene as
 * it can, so a distance from `at` does not say. covered[i] (may be NULL)
 * gets 1 or 0, *num_covered (may be NULL) the count; a non-finite point is
 * not covered. Fails as the bake would for the viewpoint or the quality
 * (GI_ERR_NONFINITE, GI_ERR_INVALID_ARG), or GI_ERR_NOMEM. Thread-safe. */
gi_result gi_cascade_would_cover(const gi_scene *scene, const double at[3], const gi_quality *resolved,
                                 const double *pts, size_t n, uint8_t *covered, size_t *num_covered,
                                 gi_error_info *err);

/* Builds the cascade around `at` (world) and lights it. q may be NULL
 * (defaults). On success the caller owns *out (gi_cascade_free). */
gi_result gi_cascade_bake(const gi_scene *scene, const double at[3], const gi_quality *q,
                          gi_cascade **out, gi_bake_report *report, gi_error_info *err);
/* As gi_cascade_bake, checking `cancel` (may be NULL; gi_cancel.h) between
 * chunks of every stage: once it fires the bake stops within a chunk's
 * time and returns GI_ERR_CANCELLED, *out NULL. A token that never fires
 * gives the same cascade as NULL, bit for bit. */
gi_result gi_cascade_bake_ex(const gi_scene *scene, const double at[3], const gi_quality *q,
                             const gi_cancel *cancel, gi_cascade **out, gi_bake_report *report,
                             gi_error_info *err);
/* As gi_cascade_bake_ex, for answers to be gathered at pts (n world
 * points, x y z each; may be NULL when n is 0) as well as at `at`: the
 * effect plan also tests the sky from up to 32 of them (a viewpoint inside
 * a solid box saw no sky and skipped it, and probes beside the box lost
 * the sky-lit ground's bounce). Non-finite points are ignored. The
 * cascade is otherwise the one gi_cascade_bake_ex makes. */
gi_result gi_cascade_bake_for(const gi_scene *scene, const double at[3], const double *pts, size_t n,
                              const gi_quality *q, const gi_cancel *cancel, gi_cascade **out,
                              gi_bake_report *report, gi_error_info *err);
void gi_cascade_free(gi_cascade *c); /* accepts NULL */
size_t gi_cascade_bytes(const gi_cascade *c); /* 0 for NULL */
/* The most gi_cascade_bytes can report for a cascade baked with this
 * resolved quality (gi_quality_resolve), known before the bake: levels x
 * res^3 x the dense per-voxel arrays and the per-voxel record of geometry
 * and light, as if every voxel held a surface (a bake keeps that record
 * only for the voxels that do, a few percent). A bake's transient buffers
 * come on top. 0 when levels or res is unresolved or out of range. */
size_t gi_cascade_bytes_estimate(const gi_quality *resolved);
const gi_bake_report *gi_cascade_report(const gi_cascade *c); /* NULL for NULL */

#ifdef __cplusplus
}
#endif
#endif
