/* gi_move.h: move a baked cascade to a new viewpoint.
 *
 * gi_cascade_move scrolls each level of a baked cascade by whole voxels
 * (toroidal storage: nothing is copied), voxelizes and injects direct light
 * only into the voxels that came into range (or left a finer level's
 * region), refilters the nested regions and refreshes indirect light on a
 * deterministic schedule (the paper's section 1.3: finer levels more often):
 *   - move m (counted from 1) re-gathers level d's own voxels when m is a
 *     multiple of gi_cascade_refresh_period(c, d) = 2^d, plus every voxel
 *     that came into range this move (one gather from the current texture);
 *   - when m is a multiple of the coarsest level's period 2^(n-1) the move
 *     closes the refresh cycle: it re-plans and re-bounces every level from
 *     its direct light exactly as a bake does, so the cascade then equals a
 *     cold bake at the same anchor (up to half-float rounding of texels
 *     stored at a different rad_scale).
 * Every call is one tick of that clock, also a call to the same point (a
 * viewer standing still lets the cycle close). New voxels and kept voxels
 * within 2 cells of them are gathered in the move that brings them in
 * (their cones read the coarser levels), rather than copying the next
 * coarser level's values until their level's turn.
 * A level that moves by its extent or more is rebuilt whole.
 *
 * Ownership and threads: the caller owns the cascade; a move writes it, so
 * no reader may run during a move. On error the cascade is left partial
 * and must be freed. The report (gi_cascade.h) describes the move: its
 * level_voxelized, level_injected and level_rebounced and its stage times
 * count only what the move redid; gi_cascade_report returns it too. */
#ifndef GI_MOVE_H
#define GI_MOVE_H

#include "gi_cascade.h"

#ifdef __cplusplus
extern "C" {
#endif

/* What one move decided, beside the counts in the report. */
typedef struct gi_move_info {
  uint64_t move;               /* this move's number, from 1 */
  int cycle_closed;            /* 1: every level was re-bounced as a bake would (equal to a cold bake) */
  int relit;                   /* 1: the effect plan's lights changed: every voxel was re-injected */
  int rebuilt[GI_MAX_LEVELS];  /* 1: the level moved by its extent or more and was rebuilt whole */
  int refreshed[GI_MAX_LEVELS];/* 1: all of the level's own voxels were re-gathered */
} gi_move_info;

/* Moves cascade c to viewpoint `at` (world). report and info may be NULL.
 * GI_ERR_NONFINITE / GI_ERR_INVALID_ARG for a bad viewpoint (the cascade
 * is then untouched). */
gi_result gi_cascade_move(gi_cascade *c, const double at[3], gi_bake_report *report, gi_move_info *info,
                          gi_error_info *err);
/* Moves between two refreshes of level d (2^d); the refresh cycle is the
 * coarsest level's period. 0 for a level the cascade does not have. */
uint64_t gi_cascade_refresh_period(const gi_cascade *c, int level);

#ifdef __cplusplus
}
#endif
#endif
