/* vdbmem.c: the cascade's radiance as an OpenVDB grid at the finest voxel
 * size, for the memory table (OpenVDB's own memUsage()).
 *
 * Each level's own occupied voxels (the region a finer level covers is
 * filtered from it, so it is skipped) are resampled to the finest size: a
 * coarse voxel holds one surface (its area-weighted plane through its
 * centroid, along its normal), so the fine voxels kept are those that plane
 * crosses (the plane/box overlap test), not the whole coarse cube; a fine
 * voxel takes its coarse voxel's texel: 6 face radiances and the opacity
 * per axis, 7 Vec3f grids sharing one topology. */
#include <math.h>
#include <stdlib.h>
#include "walk.h"
#include "gi/gi_vdb.h"
#include "cascade/cascade_internal.h"

#define VDB_GRIDS 7

/* Visits the fine voxels of level d's own voxel at `slot` that its surface
 * plane crosses; with m NULL it only counts them. */
static uint64_t resample_voxel(const gi_cascade *c, int d, uint32_t slot, gi_vdb_mem *m, int *fail) {
  const gi_level *L = &c->lv[d];
  const gi_vgeo *g = gi__geo(L, slot);
  int64_t cell[3];
  gi__slot_cell(L, c->R, slot, cell);
  int64_t f = (int64_t)1 << d;
  double s0 = c->s0, reach = 0.5 * s0 * (fabs(g->normal[0]) + fabs(g->normal[1]) + fabs(g->normal[2]));
  float vals[3 * VDB_GRIDS];
  if (m) {
    gi_vrad_f t;
    gi__vrad_unpack(c, &L->rad[slot], &t);
    for (int k = 0; k < 18; k++) vals[k] = t.p[k / 3][k % 3];
    for (int a = 0; a < 3; a++) vals[18 + a] = t.alpha[a];
  }
  uint64_t n = 0;
  gi_error_info err = {0};
  for (int64_t k = cell[2] * f; k < (cell[2] + 1) * f; k++)
    for (int64_t j = cell[1] * f; j < (cell[1] + 1) * f; j++)
      for (int64_t i = cell[0] * f; i < (cell[0] + 1) * f; i++) {
        double p[3] = {((double)i + 0.5) * s0, ((double)j + 0.5) * s0, ((double)k + 0.5) * s0};
        double dist = g->normal[0] * (p[0] - g->centroid[0]) + g->normal[1] * (p[1] - g->centroid[1]) +
                      g->normal[2] * (p[2] - g->centroid[2]);
        if (d > 0 && fabs(dist) > reach) continue;
        n++;
        if (m && gi_vdb_mem_set(m, (int)i, (int)j, (int)k, vals, &err) != GI_OK) *fail = 1;
      }
  return n;
}

static uint64_t resample_level(const gi_cascade *c, int d, gi_vdb_mem *m, int *fail) {
  uint64_t n = 0;
  for (uint32_t o = 0; o < c->lv[d].num_occ && !*fail; o++) n += resample_voxel(c, d, c->lv[d].occ[o], m, fail);
  return n;
}

int vdb_figure_measure(const gi_cascade *c, size_t max_voxels, vdb_figure *out) {
  /* Count first: the levels whose fine voxels fit the budget are built. */
  uint64_t total = 0;
  int fail = 0, levels = 0;
  for (int d = 0; d < c->n; d++) {
    uint64_t nd = resample_level(c, d, NULL, &fail);
    if (total + nd > max_voxels) break;
    total += nd, levels = d + 1;
  }
  gi_vdb_mem *m = NULL;
  gi_error_info err = {0};
  if (gi_vdb_mem_new(VDB_GRIDS, &m, &err) != GI_OK) return fprintf(stderr, "gi-walk: %s\n", err.msg), -1;
  for (int d = 0; d < levels && !fail; d++) resample_level(c, d, m, &fail);
  if (fail) {
    gi_vdb_mem_free(m);
    return fprintf(stderr, "gi-walk: building the OpenVDB grid failed (out of memory?)\n"), -1;
  }
  gi_vdb_mem_usage(m, &out->bytes, &out->active);
  out->levels_covered = levels;
  gi_vdb_mem_free(m);
  return 0;
}
