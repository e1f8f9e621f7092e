/* cell.c: the inverse of gi_cascade_anchor, for addressing cascades by cell.
 *
 * A server that names a cascade by its anchor cell (a cacheable URL)
 * needs the cell's world-space centre to bake and gather there, and the
 * scene origin to publish the grid so clients can snap viewpoints
 * themselves. The snapping stays in gi_cascade_anchor (bake.c). */
#include "base/internal.h"
#include "scene/scene_internal.h"
#include "gi/gi_cascade.h"

void gi_scene_origin(const gi_scene *s, double out[3]) {
  for (int a = 0; a < 3; a++) out[a] = s ? s->origin[a] : 0.0;
}

gi_result gi_cascade_cell_centre(const gi_scene *s, const int64_t cell[3], const gi_quality *resolved,
                                 double at[3], gi_error_info *err) {
  if (!s || !cell || !resolved || !at || !(resolved->voxel0 > 0) || !isfinite(resolved->voxel0))
    return gi__fail(err, GI_ERR_INVALID_ARG, "cell: scene, cell and a resolved quality are required");
  double side = 2.0 * resolved->voxel0;
  for (int a = 0; a < 3; a++) at[a] = s->origin[a] + ((double)cell[a] + 0.5) * side;
  /* Far cells lose the float precision the snapping works in: the centre
   * must snap back to the same cell or the cell has no cascade (past 1e9
   * units it has no anchor at all). */
  int64_t back[3];
  if (gi_cascade_anchor(s, at, resolved, back, NULL) != GI_OK || back[0] != cell[0] || back[1] != cell[1] ||
      back[2] != cell[2])
    return gi__fail(err, GI_ERR_INVALID_ARG, "cell: (%lld, %lld, %lld) is too far from the scene to address",
                    (long long)cell[0], (long long)cell[1], (long long)cell[2]);
  return GI_OK;
}
