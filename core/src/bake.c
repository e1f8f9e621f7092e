/* bake.c: the pipeline around one viewpoint.
 *
 * gi_cascade_bake resolves the quality (defaults, validation), places the
 * cascade, asks the effect plan (plan.c) which effects the scene and
 * request call for, then runs the stages in order: voxelize
 * (cascade/voxelize.c), inject (light/inject.c), filter
 * (cascade/filter.c), bounce (light/bounce.c). Each stage's time goes into
 * the report. Answers come from answer/. */
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
  gi__cascade_free_levels(c);
  gi__move_state_free(c->move_state);
  gi_scene_release(c->scene);
  gi__free(c);
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

gi_result gi__cascade_bake_at(const gi_scene *scene, const double at[3], const gi_quality *qin,
                              const gi_cancel *cancel, const float *pts, int npts, gi_cascade **out,
                              gi_bake_report *report, gi_error_info *err) {
  /* out is checked first: every other failure writes NULL through it. */
  if (!out) return gi__fail(err, GI_ERR_INVALID_ARG, "bake: out is NULL");
  *out = NULL;
  if (!scene || !at) return gi__fail(err, GI_ERR_INVALID_ARG, "bake: %s is NULL", !scene ? "scene" : "viewpoint");
  if (!isfinite(at[0]) || !isfinite(at[1]) || !isfinite(at[2]))
    return gi__fail(err, GI_ERR_NONFINITE, "bake: viewpoint (%g, %g, %g) is not finite", at[0], at[1], at[2]);
  gi_quality q;
  gi_result rc = gi_quality_resolve(scene, qin, &q, err);
  if (rc != GI_OK) return rc;
  struct gi_cascade *c = gi__calloc(1, sizeof *c);
  if (!c) return gi__fail(err, GI_ERR_NOMEM, "bake: out of memory");
  c->scene = gi_scene_retain((gi_scene *)scene);
  c->cancel = cancel;
  c->n = q.levels;
  c->R = q.res;
  c->s0 = q.voxel0;
  /* Only placement reads c->at, through the same float rounding and floor
   * as gi_cascade_anchor; the plan and every stage read the snapped levels,
   * so the cascade depends on the anchor alone. at_world is kept for the
   * VDB's viewpoint metadata. */
  for (int a = 0; a < 3; a++) {
    c->at_world[a] = at[a];
    c->at[a] = (float)(at[a] - scene->origin[a]);
  }
  if ((rc = gi__viewpoint_range(scene, at, q.voxel0, "bake", err)) != GI_OK) {
    gi_cascade_free(c);
    return rc;
  }
  c->report.quality = q;
  c->report.levels = q.levels;
  gi__cone_set(q.cones, q.aperture_deg, c->cone_dir, c->cone_weight, &c->cone_tan);
  c->num_cones = q.cones;
  gi__probe_cone_set(q.cones, q.aperture_deg, c->probe_dir, c->probe_weight, &c->probe_tan);
  c->num_probe_cones = gi__probe_cone_count(q.cones);
  gi__wide_cone_set(q.cones, q.aperture_deg, c->wide_dir, c->wide_weight, &c->wide_tan);
  c->num_wide_cones = gi__wide_cone_count(q.cones);
  /* Report every knob resolved, so a JSON answer says exactly what ran. */
  q.aperture_deg = (float)(2.0 * atan((double)c->cone_tan) * 180.0 / 3.14159265358979323846);
  q.threads = gi__num_workers(q.threads);

  if ((rc = gi__cascade_alloc(c, err)) != GI_OK) goto fail;
  gi__cascade_place(c);
  c->plan_q = q;
  c->auto_bounces = !qin || qin->bounces == 0;
  if (qin) c->req_q = *qin;
  c->req_default = !qin;
  int tail;
  c->answer_pts = pts, c->num_answer_pts = pts ? npts : 0;
  rc = gi__plan_effects(c, &q, !qin || qin->bounces == 0, &c->report, &tail, err);
  c->answer_pts = NULL, c->num_answer_pts = 0; /* the caller's array */
  if (rc != GI_OK) goto fail;
  q.ao = c->report.effects[GI_FX_AO].ran; /* the plan decides: --effect ao=off wins over --ao */
  c->report.quality = q;
  c->tail = tail;
  for (int d = 0; d < c->n; d++) {
    c->report.voxel_size[d] = c->lv[d].s;
    for (int a = 0; a < 3; a++)
      c->report.level_origin[d][a] = (double)c->lv[d].cell0[a] * c->lv[d].s + scene->origin[a];
  }
  double t0 = gi__now_ms();
  if ((rc = gi__voxelize(c, q.threads, err)) != GI_OK) goto fail;
  double t1 = gi__now_ms();
  if ((rc = gi__inject(c, &q, err)) != GI_OK) goto fail;
  double t2 = gi__now_ms();
  if (gi__cascade_filter(c, q.threads)) {
    rc = gi__cancel_fail(cancel, err, "filter");
    goto fail;
  }
  gi__cascade_mark_busy(c);
  double t3 = gi__now_ms();
  if (c->report.effects[GI_FX_BOUNCE].ran)
    if ((rc = gi__bounce(c, &q, q.bounces, tail, err)) != GI_OK) goto fail;
  double t4 = gi__now_ms();
  c->report.ms.voxelize = t1 - t0;
  c->report.ms.inject = t2 - t1;
  c->report.ms.filter = t3 - t2;
  c->report.ms.bounce = t4 - t3;
  gi__cascade_count_occupied(c);
  for (int d = 0; d < c->n; d++) {
    gi_level *L = &c->lv[d];
    uint64_t inner = 1;
    for (int a = 0; a < 3; a++) inner *= L->has_inner ? (uint64_t)(L->inner1[a] - L->inner0[a]) : 0;
    c->report.level_voxelized[d] = (uint64_t)c->R * c->R * c->R - inner;
    c->report.level_injected[d] = L->num_occ;
    c->report.level_rebounced[d] = (uint64_t)L->num_occ * (uint64_t)c->report.bounces_run;
  }
  c->report.cascade_bytes = gi_cascade_bytes(c);
  c->cancel = NULL; /* the token need not outlive the bake */
  if (report) *report = c->report;
  *out = c;
  return GI_OK;
fail:
  gi_cascade_free(c);
  return rc;
}
