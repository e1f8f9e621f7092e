/* gi_vdb.h: write and read OpenVDB files (C face of the one C++ file).
 *
 * Grids are given as dense blocks; only voxels whose value differs from the
 * background are stored (OpenVDB is sparse). Index (i,j,k) of a dense block
 * is data[i + dims[0]*(j + dims[1]*k)] (x fastest). The grid's transform
 * maps voxel (i,j,k)'s centre to world origin + (i+0.5, j+0.5, k+0.5) *
 * voxel_size, so voxel (0,0,0)'s min corner sits at origin.
 * No C++ exception crosses this interface. Thread-safe for distinct files. */
#ifndef GI_VDB_H
#define GI_VDB_H

#include <stddef.h>
#include <stdint.h>
#include "gi_error.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum gi_vdb_kind { GI_VDB_FLOAT = 0, GI_VDB_VEC3 = 1 } gi_vdb_kind;

typedef struct gi_vdb_meta {
  const char *name;  /* metadata key */
  const char *str;   /* string value, or NULL to store num as a double */
  double num;
} gi_vdb_meta;

typedef struct gi_vdb_grid {
  const char *name;     /* e.g. "L0_density", "density", "Cd" */
  gi_vdb_kind kind;
  int dims[3];
  const float *data;    /* dims product values (x3 for VEC3, interleaved), borrowed */
  double voxel_size;
  double origin[3];     /* world position of voxel (0,0,0)'s min corner */
  int fog_volume;       /* 1: GRID_FOG_VOLUME class (density) */
  size_t num_meta;
  const gi_vdb_meta *meta; /* per-grid metadata */
} gi_vdb_grid;

/* Writes the grids (and file-level metadata) to path via a temporary name
 * and a rename. A write the OS refuses (a full disk) is GI_ERR_IO naming
 * the file and the reason; the temporary file is removed and path is left
 * as it was. */
gi_result gi_vdb_write(const char *path, const gi_vdb_grid *grids, size_t num_grids,
                       const gi_vdb_meta *file_meta, size_t num_file_meta, gi_error_info *err);

/* A grid given voxel by voxel: every listed voxel becomes active, even
 * when its value equals the background (0). */
typedef struct gi_vdb_sparse {
  const char *name;
  gi_vdb_kind kind;
  size_t count;
  const int *ijk;       /* 3 index coordinates per voxel, borrowed */
  const float *data;    /* count values (x3 for VEC3, interleaved), borrowed */
  double voxel_size;
  double origin[3];     /* as gi_vdb_grid: voxel (0,0,0)'s min corner */
  size_t num_meta;
  const gi_vdb_meta *meta;
} gi_vdb_sparse;

/* Writes sparse grids like gi_vdb_write. uuid (may be NULL: OpenVDB's
 * random one) is the file's 36-character id "xxxxxxxx-xxxx-xxxx-xxxx-
 * xxxxxxxxxxxx" (hex digits); with it, equal inputs give equal bytes. */
gi_result gi_vdb_write_sparse(const char *path, const gi_vdb_sparse *grids, size_t num_grids,
                              const gi_vdb_meta *file_meta, size_t num_file_meta, const char *uuid,
                              gi_error_info *err);

/* What a grid in a file holds, for tests and inspection tools. */
typedef struct gi_vdb_grid_info {
  char name[128];
  gi_vdb_kind kind;
  double voxel_size;          /* uniform scale of the transform */
  double index_to_world[3];   /* world position of index (0,0,0)'s centre */
  long active_voxels;
  int is_fog_volume;
} gi_vdb_grid_info;

/* Lists grids: fills up to max infos, returns the count in *num. */
gi_result gi_vdb_read_info(const char *path, gi_vdb_grid_info *infos, size_t max, size_t *num,
                           gi_error_info *err);
/* Samples grid `name` at integer index (i,j,k) (no interpolation). val gets
 * 1 float (FLOAT) or 3 (VEC3); background where inactive. */
gi_result gi_vdb_read_value(const char *path, const char *name, int i, int j, int k, float val[3],
                            gi_error_info *err);
/* Reads a string or numeric metadata value of grid `name` (or of the file
 * when name is NULL) as text into buf. */
gi_result gi_vdb_read_meta(const char *path, const char *name, const char *key, char *buf,
                           size_t bufsize, gi_error_info *err);

/* OpenVDB's own memory figure for sparse grids built in memory (nothing is
 * written): a set of `vec3_grids` Vec3f grids sharing one index space,
 * filled voxel by voxel. Used to size a sparse grid against the cascade
 * (docs/experiments.md). Not thread-safe: one thread per builder. */
typedef struct gi_vdb_mem gi_vdb_mem;
gi_result gi_vdb_mem_new(int vec3_grids, gi_vdb_mem **out, gi_error_info *err);
/* Sets voxel (i,j,k) active in every grid: vals holds 3 * vec3_grids
 * floats, grid g's value at vals[3g..3g+2]. GI_ERR_NOMEM on allocation
 * failure (the builder stays usable for gi_vdb_mem_free). */
gi_result gi_vdb_mem_set(gi_vdb_mem *m, int i, int j, int k, const float *vals, gi_error_info *err);
/* The sum of the grids' memUsage() in bytes and the active voxels of one grid
 * (0 and 0 for a NULL m; a NULL output is skipped). */
void gi_vdb_mem_usage(const gi_vdb_mem *m, size_t *bytes, uint64_t *active);
void gi_vdb_mem_free(gi_vdb_mem *m); /* accepts NULL */

#ifdef __cplusplus
}
#endif
#endif
