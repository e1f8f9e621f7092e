/* bake.c: the public cascade calls around one viewpoint: the anchor, what
 * a bake would cover, the bake's entry points (their pipeline is
 * pipeline.c: quality, placement, effect plan, voxelize, inject, filter,
 * bounce), freeing and counting a cascade. Answers come from answer/. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "cascade/cascade_internal.h"
#include "light/light.h"
#include "plan.h"
#include "trace/trace.h"

gi_result gi_cascade_anchor(const gi_scene *s, const double at[3], const gi_quality *resolved,
                            int64_t anchor[3], gi_error_info *err) {
  if (!s || !at || !resolved || !anchor)
    return gi__fail(err, GI_ERR_INVALID_ARG, "anchor: %s is NULL",
                    !s ? "scene" : !at ? "viewpoint" : !resolved ? "resolved" : "anchor");
  if (!(resolved->voxel0 > 0) || !isfinite(resolved->voxel0))
    return gi__fail(err, GI_ERR_INVALID_ARG, "anchor: resolved->voxel0 is %g, not a resolved voxel size",
                    resolved->voxel0);
  if (!isfinite(at[0]) || !isfinite(at[1]) || !isfinite(at[2]))
    return gi__fail(err, GI_ERR_NONFINITE, "anchor: viewpoint (%g, %g, %g) is not finite", at[0], at[1], at[2]);
  /* A viewpoint the bake and a move refuse has no placement. A finite one
   * past float range (1e39) was called "not finite", and one past 1e9 got
   * an anchor that no bake could have: gi-walk replayed a path up to such
   * a point and only its move failed. */
  gi_result rc = gi__viewpoint_range(s, at, resolved->voxel0, "anchor", err);
  if (rc != GI_OK) return rc;
  for (int a = 0; a < 3; a++) {
    /* The same float rounding and snapping as gi_cascade_bake and
     * gi__cascade_place: level 0's window starts at 2 floor(at / 2 s0) - R/2
     * and every coarser level follows from it, so equal anchors mean equal
     * cascades. */
    float al = (float)(at[a] - s->origin[a]);
    anchor[a] = (int64_t)floor((double)al / (2.0 * resolved->voxel0));
  }
  return GI_OK;
}

gi_result gi_cascade_would_cover(const gi_scene *s, const double at[3], const gi_quality *resolved,
                                 const double *pts, size_t n, uint8_t *covered, size_t *num_covered,
                                 gi_error_info *err) {
  if (num_covered) *num_covered = 0;
  if (!s || !at || !resolved || (n && !pts))
    return gi__fail(err, GI_ERR_INVALID_ARG, "cover: %s is NULL",
                    !s ? "scene" : !at ? "viewpoint" : !resolved ? "resolved" : "pts");
  if (resolved->levels < 1 || resolved->levels > GI_MAX_LEVELS || resolved->res < 8 || resolved->res > GI_MAX_RES ||
      resolved->res % 4 || !(resolved->voxel0 > 0) || !isfinite(resolved->voxel0))
    return gi__fail(err, GI_ERR_INVALID_ARG, "cover: levels %d, res %d, voxel0 %g: not a resolved quality",
                    resolved->levels, resolved->res, resolved->voxel0);
  struct gi_cascade *c;
  gi_result rc = gi__cascade_placed(s, at, resolved, "cover", &c, err);
  if (rc != GI_OK) return rc;
  size_t count = 0;
  for (size_t i = 0; i < n; i++) {
    /* The placed levels answer as the baked ones will. */
    int in = gi_cascade_covers(c, pts + 3 * i);
    if (covered) covered[i] = (uint8_t)in;
    count += (size_t)in;
  }
  gi__free(c);
  if (num_covered) *num_covered = count;
  return GI_OK;
}

void gi_cascade_free(gi_cascade *c) {
  if (!c) return;
  gi__move_state_free(c->move_state);
  gi__cascade_discard(c);
}

/* The dense arrays per voxel (rad, vix, occ, busy) and, at most, one entry
 * (geo, side, direct, freed) per voxel. busy4 (one byte per 4^3 cells,
 * 0.01%) is left out: the server's budgets and tests count whole bytes
 * per voxel. */
static size_t level_bytes(int levels, int res, int every_voxel) {
  size_t vox = (size_t)res * (size_t)res * (size_t)res;
  return (size_t)levels * vox * (GI_SLOT_BYTES + (every_voxel ? GI_ENTRY_BYTES : 0));
}

/* A moved cascade also holds its re-bake's buffers. */
size_t gi_cascade_bytes(const gi_cascade *c) { return c ? gi__cascade_held_bytes(c) : 0; }

size_t gi_cascade_bytes_estimate(const gi_quality *resolved) {
  /* Unresolved (zero) or out-of-range levels or res: no estimate rather
   * than a wrong one (res 2^20 wrapped size_t into a few bytes). */
  if (!resolved || resolved->levels <= 0 || resolved->res <= 0 || resolved->levels > GI_MAX_LEVELS ||
      resolved->res > GI_MAX_RES)
    return 0;
  /* The bound: every voxel holding geometry (plus each level's entry 0). */
  return level_bytes(resolved->levels, resolved->res, 1) + (size_t)resolved->levels * GI_ENTRY_BYTES;
}

const gi_bake_report *gi_cascade_report(const gi_cascade *c) { return c ? &c->report : NULL; }

gi_result gi_cascade_bake(const gi_scene *scene, const double at[3], const gi_quality *qin,
                          gi_cascade **out, gi_bake_report *report, gi_error_info *err) {
  return gi_cascade_bake_ex(scene, at, qin, NULL, out, report, err);
}

gi_result gi_cascade_bake_ex(const gi_scene *scene, const double at[3], const gi_quality *qin,
                             const gi_cancel *cancel, gi_cascade **out, gi_bake_report *report,
                             gi_error_info *err) {
  return gi__cascade_bake_at(scene, at, qin, cancel, NULL, 0, out, report, err);
}

/* Up to MAX_PTS of n world points, evenly, as the plan's answer points
 * (local position, no normal); non-finite ones skipped. */
enum { MAX_PTS = 32 };
static int point_hints(const gi_scene *scene, const double *pts, size_t n, float hint[MAX_PTS][6]) {
  int nh = 0;
  size_t want = n < MAX_PTS ? n : MAX_PTS;
  for (size_t i = 0; pts && scene && i < want; i++) {
    const double *p = pts + 3 * (i * n / want);
    if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2])) continue;
    for (int k = 0; k < 3; k++) hint[nh][k] = (float)(p[k] - scene->origin[k]), hint[nh][3 + k] = 0;
    nh++;
  }
  return nh;
}

gi_result gi_cascade_bake_for(const gi_scene *scene, const double at[3], const double *pts, size_t n,
                              const gi_quality *q, const gi_cancel *cancel, gi_cascade **out,
                              gi_bake_report *report, gi_error_info *err) {
  if (n && !pts) {
    if (out) *out = NULL;
    return gi__fail(err, GI_ERR_INVALID_ARG, "bake: pts is NULL with n = %zu points", n);
  }
  float hint[MAX_PTS][6];
  int nh = point_hints(scene, pts, n, hint);
  return gi__cascade_bake_at(scene, at, q, cancel, &hint[0][0], nh, out, report, err);
}

gi_result gi_effect_plan_for(const gi_scene *scene, const double at[3], const double *pts, size_t n,
                             const gi_quality *q, gi_effect out[GI_FX_COUNT], gi_quality *resolved,
                             gi_error_info *err) {
  if (n && !pts) return gi__fail(err, GI_ERR_INVALID_ARG, "effect plan: pts is NULL with n = %zu points", n);
  float hint[MAX_PTS][6];
  int nh = point_hints(scene, pts, n, hint);
  return gi__effect_plan_for(scene, at, q, &hint[0][0], nh, out, resolved, err);
}
