/* test_levels.h: comparing two cascades' levels slot by slot. The voxels
 * holding geometry keep their data in entries (cascade_internal.h) whose
 * order depends on the path that filled them (a bake, a move), so tests
 * compare what each slot reads, never the arrays themselves. */
#ifndef TEST_LEVELS_H
#define TEST_LEVELS_H

#include <string.h>
#include "cascade/cascade_internal.h"

enum { TL_GEO = 1, TL_SIDE = 2, TL_DIRECT = 4 };

/* 1 when every slot of A and B holds geometry alike and the arrays named in
 * `what` read the same bytes there. */
static inline int tl_same_entries(const gi_level *A, const gi_level *B, int R, int what) {
  size_t vox = (size_t)R * R * R;
  for (uint32_t s = 0; s < vox; s++) {
    if ((A->vix[s] == 0) != (B->vix[s] == 0)) return 0;
    if ((what & TL_GEO) && memcmp(gi__geo(A, s), gi__geo(B, s), sizeof(gi_vgeo)) != 0) return 0;
    if ((what & TL_SIDE) && memcmp(gi__side(A, s), gi__side(B, s), sizeof(gi_faces3)) != 0) return 0;
    if ((what & TL_DIRECT) && memcmp(gi__direct(A, s), gi__direct(B, s), sizeof(gi_faces3)) != 0) return 0;
  }
  return 1;
}

#endif
