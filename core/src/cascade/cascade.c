/* cascade.c: placing and allocating the cascaded voxel texture.
 *
 * Placement snaps each level's window to twice its voxel size around the
 * viewpoint, so a viewpoint moving by less than a voxel leaves every grid
 * where it was, and level d's window starts on a cell border of level d+1. */
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "cascade/cascade_internal.h"

/* Every array of every level lies in one zeroed block (gi__big_calloc:
 * huge pages, so first touches cost 17 faults instead of 8,000 on a
 * default cascade), each array starting on a cache line. */
#define GI_ARRAY_ALIGN 64

/* Bytes cleared between two checks of the cancel token (~5 ms of first touches here). */
#define GI_CLEAR_SLICE ((size_t)1 << 20)

static size_t align_up(size_t n) { return (n + GI_ARRAY_ALIGN - 1) & ~(size_t)(GI_ARRAY_ALIGN - 1); }

/* Bytes of one level's arrays in the block. */
static size_t level_block_bytes(size_t vox, size_t blocks) {
  return align_up(vox * sizeof(gi_vgeo)) + align_up(vox * sizeof(gi_vrad)) + 2 * align_up(vox * sizeof(gi_faces3)) +
         align_up(vox * sizeof(uint32_t)) + align_up(vox) + align_up(blocks);
}

gi_result gi__cascade_alloc(struct gi_cascade *c, gi_error_info *err) {
  size_t vox = (size_t)c->R * c->R * c->R, nb = (size_t)gi__busy4_side(c->R);
  c->rad_scale = 1.0f;
  if (gi_cancel_check(c->cancel) != GI_CANCEL_NONE) return gi__cancel_fail(c->cancel, err, "allocate");
  c->block_bytes = (size_t)c->n * level_block_bytes(vox, nb * nb * nb);
  int zeroed;
  char *b = c->block = gi__big_malloc(c->block_bytes, &zeroed);
  if (!b) return gi__fail(err, GI_ERR_NOMEM, "cascade: cannot allocate %d levels of %d^3 voxels", c->n, c->R);
  /* Heap memory (small blocks) is cleared in slices a fired token stops. */
  for (size_t at = 0; !zeroed && at < c->block_bytes; at += GI_CLEAR_SLICE) {
    if (gi_cancel_check(c->cancel) != GI_CANCEL_NONE) {
      gi__cascade_free_levels(c);
      return gi__cancel_fail(c->cancel, err, "allocate");
    }
    size_t n = c->block_bytes - at < GI_CLEAR_SLICE ? c->block_bytes - at : GI_CLEAR_SLICE;
    memset(b + at, 0, n);
  }
  for (int d = 0; d < c->n; d++) {
    gi_level *L = &c->lv[d];
    L->geo = (gi_vgeo *)b, b += align_up(vox * sizeof *L->geo);
    L->rad = (gi_vrad *)b, b += align_up(vox * sizeof *L->rad);
    L->side = (gi_faces3 *)b, b += align_up(vox * sizeof *L->side);
    L->direct = (gi_faces3 *)b, b += align_up(vox * sizeof *L->direct);
    L->occ = (uint32_t *)b, b += align_up(vox * sizeof *L->occ);
    L->busy = (uint8_t *)b, b += align_up(vox);
    L->busy4 = (uint8_t *)b, b += align_up(nb * nb * nb);
  }
  return GI_OK;
}

void gi__cascade_free_levels(struct gi_cascade *c) {
  gi__big_free(c->block, c->block_bytes, 1);
  c->block = NULL;
  c->block_bytes = 0;
  for (int d = 0; d < GI_MAX_LEVELS; d++) {
    gi_level *L = &c->lv[d];
    L->geo = NULL, L->rad = NULL, L->side = NULL, L->direct = NULL, L->occ = NULL, L->busy = NULL, L->busy4 = NULL;
  }
}

void gi__cascade_place(struct gi_cascade *c) {
  int R = c->R;
  double at[3] = {(double)c->at[0], (double)c->at[1], (double)c->at[2]};
  for (int d = 0; d < c->n; d++) {
    gi_level *L = &c->lv[d];
    L->s = c->s0 * (double)(1ull << d);
    for (int a = 0; a < 3; a++) {
      int64_t centre = (int64_t)floor(at[a] / L->s);
      L->cell0[a] = gi__floordiv(centre - R / 2, 2) * 2;
      L->slot0[a] = gi__wrap(L->cell0[a], R);
      L->lo[a] = (float)(L->cell0[a] * L->s);
      L->hi[a] = (float)((L->cell0[a] + R) * L->s);
    }
    L->has_inner = 0;
    if (d > 0) {
      const gi_level *F = &c->lv[d - 1];
      L->has_inner = 1;
      for (int a = 0; a < 3; a++) {
        /* cell0 of the finer level is even, so this division is exact. */
        int64_t i0 = F->cell0[a] / 2, i1 = i0 + R / 2;
        if (i0 < L->cell0[a]) i0 = L->cell0[a];
        if (i1 > L->cell0[a] + R) i1 = L->cell0[a] + R;
        L->inner0[a] = i0;
        L->inner1[a] = i1;
      }
    }
  }
}

int gi__level_contains(const gi_level *L, const float p[3], float border) {
  float b = border * (float)L->s;
  for (int a = 0; a < 3; a++)
    if (!(p[a] >= L->lo[a] + b && p[a] <= L->hi[a] - b)) return 0;
  return 1;
}
