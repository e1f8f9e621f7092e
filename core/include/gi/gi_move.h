/* gi_move.h: move a baked cascade to a new viewpoint.
 *
 * Ownership and threads: the caller owns the cascade; a move writes it, so
 * no reader may run during a move. On error (a failure or a cancel) the
 * cascade is left partial: its levels are placed at the new viewpoint,
 * some scrolled and others not, and its plan, light and refresh cycle are
 * left part way. Every call that would read that refuses it with
 * GI_ERR_INVALID_ARG saying so (gather, panorama, render, VDB and
 * gi_cascade_move_prepare); gi_cascade_covers answers 0 and
 * gi_cascade_refresh_period 0, gi_cascade_view_plan every effect off, and
 * gi_cascade_report describes the stopped move's work so far. The next
 * gi_cascade_move bakes it afresh at its viewpoint with the bake's own
 * quality (a cold bake's work, as a move by every level's extent: info
 * says every level rebuilt and refreshed, the cycle closed), after which
 * it equals a cold bake there and moves on as any cascade; a re-bake that
 * fails or is cancelled in turn leaves it partial. Freeing it is fine too.
 * A move refused before it starts (a bad viewpoint, no memory for its
 * state) leaves the cascade as it was. The report (gi_cascade.h)
 * describes the move: its level_voxelized, level_injected and
 * level_rebounced (voxels gathered, the live update's and the re-bake
 * slice's, each once a move) and its stage times count only what the move
 * did; gi_cascade_report returns it too. A moved cascade holds the
 * re-bake's texture, its side light and each voxel's last increment beside
 * its own: gi_cascade_bytes counts them, gi_cascade_move_bytes_estimate
 * bounds them.
 *
 * The scene is static, so the light field does not change as the viewer
 * moves: the cascade is a window on it. gi_cascade_move therefore
 *   - scrolls each level by whole voxels (toroidal storage: nothing is
 *     copied) and voxelizes and injects direct light only into the voxels
 *     that came into range (or left a finer level's region), bit-identical
 *     to a bake's;
 *   - gathers those new voxels and the kept voxels within 3 cells of them
 *     once (near a window's face a voxel's cones read the coarser level at
 *     once) from a copy of the texture that holds the orders the bake's
 *     last bounce read: every voxel's light less what the last bounce
 *     and the bounce tail on it added (its own increment since a re-bake
 *     closed, before that the bounce's share; with a tail and no re-bake
 *     closed yet, the whole texture), the new voxels' from a first gather
 *     of their own, the tail then put back on what they gathered;
 *     other kept voxels keep their light;
 *   - re-bakes in the background: on each call that keeps the anchor
 *     (gi_cascade_anchor), it runs one slice of the bake's own bounce
 *     schedule (k bounces and the tail, from direct light) against a second
 *     texture, each slice 1/P of the bake's voxel gathers, with
 *     P = gi_cascade_refresh_period(c, d): 2^(n-1) (at least 4) for a
 *     viewer at rest; for one that keeps moving, the calls it spent per
 *     anchor lately less one (a running mean), when that is from 8 to
 *     2^(n-1) - 1, so the cycle closes before the next crossing.
 * The refresh cycle: the P-th consecutive call that keeps the anchor (the
 * call that arrived there does not count) completes the re-bake and swaps
 * its texture in; the cascade then equals a cold bake at that anchor (up
 * to half-float rounding of texels stored at a different rad_scale) and
 * info->cycle_closed is 1. Further calls at that anchor do nothing (a
 * freshly baked cascade is already there). A call that changes the anchor
 * restarts the re-bake, so a viewer that crosses cells on almost every
 * call sees the live update alone (measured on the city at default
 * quality, 600 steps at 10 Hz, against cold bakes: a 14 m/s drive reads
 * 0.39% mean / 1.49% max (docs/experiments.md) on the probe's total
 * irradiance, whose direct part a move does not change; its indirect part alone, over a
 * 40-step drive, read 1.65% mean / 4.12% max, and stepped by 3.2% when the
 * cycle closed at rest (2026-12-06); a 1.4 m/s walk, crossing
 * every ~10 calls, read 1.25% / 2.25% with the resting cycle, which never
 * closed, and 0.02% / 0.09% with the moving one).
 * A level that moves by its extent or more is rebuilt whole; such a move,
 * and one that changes the effect plan's lights (every voxel re-injected),
 * runs the whole re-bake at once (a cold bake's work) and closes the cycle.
 * So no call that scrolls by less than a level's extent costs more than
 * the new voxels' work (and a refilter above them), and no call that keeps
 * the anchor more than one slice (1/P of a bake's gathers, plus one
 * reshade and refilter per bounce the slice ends). */
#ifndef GI_MOVE_H
#define GI_MOVE_H

#include "gi_cascade.h"

#ifdef __cplusplus
extern "C" {
#endif

/* What one move decided, beside the counts in the report. */
typedef struct gi_move_info {
  uint64_t move;               /* this move's number, from 1 */
  int cycle_closed;            /* 1: the re-bake completed: the cascade equals a cold bake */
  int relit;                   /* 1: the effect plan's lights changed: every voxel was re-injected */
  int rebuilt[GI_MAX_LEVELS];  /* 1: the level moved by its extent or more and was rebuilt whole */
  int refreshed[GI_MAX_LEVELS];/* 1: the level's light is now the re-bake's (as cycle_closed) */
  int slice;                   /* the re-bake slice this call ran, 1..P (P: the cycle closed); 0: none */
} gi_move_info;

/* Moves cascade c to viewpoint `at` (world). report and info may be NULL.
 * GI_ERR_NONFINITE / GI_ERR_INVALID_ARG for a bad viewpoint (the cascade
 * is then untouched). */
gi_result gi_cascade_move(gi_cascade *c, const double at[3], gi_bake_report *report, gi_move_info *info,
                          gi_error_info *err);
/* As gi_cascade_move, checking `cancel` (may be NULL; gi_cancel.h) between
 * chunks of every stage: once it fires the move stops within a chunk's
 * time and returns GI_ERR_CANCELLED; the cascade is then partial (see
 * above: the next move re-bakes it, or free it; a rebuilt level can cost a
 * cold bake: a server must be able to stop it). A token that never fires
 * moves exactly as gi_cascade_move. */
gi_result gi_cascade_move_ex(gi_cascade *c, const double at[3], const gi_cancel *cancel, gi_bake_report *report,
                             gi_move_info *info, gi_error_info *err);
/* Allocates what moves need (the re-bake's texture, touched so its pages
 * are in memory) as the first move would, so that move does not pay for
 * it: a session calls it once after its bake, at creation. Without it the
 * first move does it (6 levels of 32^3: 12 MB, 15-20 ms on the test VM).
 * GI_ERR_NOMEM leaves the cascade as it was. Calling it again, or after a
 * move, does nothing. On a partial cascade (see above) GI_ERR_INVALID_ARG,
 * saying so. Not thread-safe with other calls on c. */
gi_result gi_cascade_move_prepare(gi_cascade *c, gi_error_info *err);
/* The most bytes gi_cascade_move adds to a cascade baked with this
 * resolved quality (the re-bake's texture, irradiance and gathers, and
 * each voxel's apex shift: up to 352 bytes per voxel), known before the
 * first move, so a holder of a moving cascade can reserve them. 0 when
 * levels or res is unresolved or out of range. Thread-safe. */
size_t gi_cascade_move_bytes_estimate(const gi_quality *resolved);
/* P: the calls at one anchor that complete the re-bake (the refresh cycle)
 * under way, or the next one at rest; the same for every level (the bake's
 * bounces couple them). 0 for a level the cascade does not have. */
uint64_t gi_cascade_refresh_period(const gi_cascade *c, int level);

#ifdef __cplusplus
}
#endif
#endif
