/* cascade.c: placing and allocating the cascaded voxel texture.
 *
 * Placement snaps each level's window to twice its voxel size around the
 * viewpoint, so a viewpoint moving by less than a voxel leaves every grid
 * where it was, and level d's window starts on a cell border of level d+1. */
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "cascade/cascade_internal.h"

/* calloc may clear recycled memory (tens of MB per array of a large
 * cascade): the token is checked before each array. */
static int fired(const struct gi_cascade *c) { return gi_cancel_check(c->cancel) != GI_CANCEL_NONE; }

gi_result gi__cascade_alloc(struct gi_cascade *c, gi_error_info *err) {
  size_t vox = (size_t)c->R * c->R * c->R;
  c->rad_scale = 1.0f;
  for (int d = 0; d < c->n; d++) {
    gi_level *L = &c->lv[d];
    if (fired(c) || !(L->geo = gi__calloc(vox, sizeof *L->geo)) || fired(c) ||
        !(L->rad = gi__calloc(vox, sizeof *L->rad)) || fired(c) ||
        !(L->side = gi__calloc(vox, sizeof *L->side)) || fired(c) ||
        !(L->direct = gi__calloc(vox, sizeof *L->direct)) || fired(c) ||
        !(L->occ = gi__malloc(vox * sizeof *L->occ)) || fired(c) || !(L->busy = gi__calloc(vox, 1))) {
      if (fired(c)) return gi__cancel_fail(c->cancel, err, "allocate");
      return gi__fail(err, GI_ERR_NOMEM, "cascade: cannot allocate %d levels of %d^3 voxels", c->n, c->R);
    }
  }
  return GI_OK;
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
