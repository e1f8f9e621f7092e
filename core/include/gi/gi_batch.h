/* gi_batch.h: regular probe grids for batch bakes, and the files they go to.
 *
 * A probe grid is a regular lattice of points over a region of a scene:
 * either a full 3D lattice, or (above_ground > 0) one probe per column of
 * the two horizontal axes, placed above_ground units above the ground found
 * by a downward ray (the first upward-facing surface that is neither a
 * building's roof nor a narrow cover such as a canopy or a bridge deck; see
 * README "Batch probe grids"), with probes inside buildings dropped
 * (valid = 0).
 * Points are numbered x fastest, then y, then z (world axes), always in
 * the same order for the same scene and spec.
 *
 * The volume writers take a grid's probes and write the probe EXR (one
 * pixel per grid point, width = counts[0], height = counts[1] * counts[2])
 * and an OpenVDB probe volume. Both are pure functions of their inputs
 * (the VDB's file id is derived from `id`), so equal inputs give equal
 * bytes: sharded bakes can be merged into the file an unsharded bake
 * writes. Thread-safe for distinct grids and paths. */
#ifndef GI_BATCH_H
#define GI_BATCH_H

#include <stddef.h>
#include <stdint.h>
#include "gi_error.h"
#include "gi_exr.h"
#include "gi_probe.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The most points one grid may hold (the probe EXR's pixel budget). */
#define GI_GRID_MAX_POINTS ((size_t)1 << 24)

typedef struct gi_grid_spec {
  double spacing;        /* world units between neighbours, finite and > 0 */
  int have_region;       /* 0: the scene's bounds */
  double lo[3], hi[3];   /* region, world; must overlap the scene's bounds */
  double above_ground;   /* > 0: street-level mode, this far above the ground */
} gi_grid_spec;

/* Why a point is not a probe. */
enum { GI_GRID_VALID = 1, GI_GRID_NO_GROUND = 2, GI_GRID_INSIDE = 3 };

typedef struct gi_probe_grid {
  int counts[3];         /* points per world axis (the up axis has 1 in street-level mode) */
  double origin[3];      /* world position of point (0,0,0) (its up coordinate: the region's floor) */
  double spacing;
  int up_axis;           /* 1 = y, 2 = z */
  double above_ground;   /* 0: full lattice */
  size_t n;              /* counts[0] * counts[1] * counts[2] */
  double *pos;           /* 3 per point, world, in double: a float position 1e7 from the origin is
                            1 unit coarse, and a 0.25 m grid baked 45 distinct points of 1377 (the
                            files store float) */
  uint8_t *state;        /* GI_GRID_VALID, GI_GRID_NO_GROUND or GI_GRID_INSIDE per point */
  size_t num_valid, num_no_ground, num_inside;
} gi_probe_grid;

/* Builds the grid. Errors: GI_ERR_INVALID_ARG (spacing not finite and > 0,
 * region empty, not finite, or beside the scene's bounds (above or below
 * them is taken: probes over the roofs), a point beyond
 * float range: the message names it), GI_ERR_LIMIT (more than
 * GI_GRID_MAX_POINTS points), GI_ERR_NOMEM. Deterministic; thread-safe. */
gi_result gi_probe_grid_build(const gi_scene *scene, const gi_grid_spec *spec, gi_probe_grid *out,
                              gi_error_info *err);
/* The grid's size without building it: counts, origin, spacing, up_axis,
 * above_ground and n as gi_probe_grid_build gives them (num_valid = n),
 * pos and state NULL; no ray is cast and nothing is allocated, so a caller
 * can refuse a huge grid at once. The same errors but GI_ERR_NOMEM and the
 * float-range check. Deterministic; thread-safe. */
gi_result gi_probe_grid_size(const gi_scene *scene, const gi_grid_spec *spec, gi_probe_grid *out,
                             gi_error_info *err);
void gi_probe_grid_free(gi_probe_grid *g); /* accepts a zeroed grid */

/* A grid's answers, ready to write: probes[i] is used where valid[i] is 1. */
typedef struct gi_probe_volume {
  int counts[3];
  double origin[3];
  double spacing;
  int up_axis;           /* 1 = y, 2 = z: a street-level volume needs one of them */
  int street_level;      /* 1: one probe per column; the VDB places it at its own height (within
                            +-2^31 spacings of origin: VDB's indices are int32) */
  size_t n;
  const double *pos;     /* 3n, world (written as float) */
  const uint8_t *valid;  /* n, 0 or 1 */
  const gi_probe *probes;/* n */
  int ao;                /* 1: the EXR carries ao.Y */
} gi_probe_volume;

/* The probe EXR: R,G,B, irradiance/direct/indirect.R,G,B, [ao.Y],
 * sh.L00.R .. sh.L22.B, P.X,P.Y,P.Z, valid.Y; FLOAT, ZIP; the given header
 * attributes in the given order. Invalid points hold zeros (P still holds
 * the point's place). */
gi_result gi_probe_volume_write_exr(const char *path, const gi_probe_volume *v, const gi_exr_attr *attrs,
                                    size_t num_attrs, gi_error_info *err);

/* The OpenVDB probe volume: Vec3 grids sh_L00 .. sh_L22 (SH coefficients,
 * RGB), irradiance and P (exact position), one active voxel per valid
 * probe. Voxel size = spacing; voxel (i,j,k)'s centre is origin + (i,j,k) *
 * spacing, so a lattice probe sits on its voxel's centre; a street-level
 * probe takes the voxel nearest its height. id (may be NULL) names the bake
 * (file metadata gi.bake_hash, and the file's UUID is derived from it). */
gi_result gi_probe_volume_write_vdb(const char *path, const gi_probe_volume *v, const char *id,
                                    gi_error_info *err);

#ifdef __cplusplus
}
#endif
#endif
