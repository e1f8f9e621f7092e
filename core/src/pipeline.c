/* pipeline.c: one cascade baked around one viewpoint (gi__cascade_bake_at,
 * behind gi_cascade_bake*, bake.c).
 *
 * It resolves the quality (defaults, validation), places the cascade, asks
 * the effect plan (plan.c) which effects the scene and request call for,
 * then runs the stages in order: voxelize (cascade/voxelize.c), inject
 * (light/inject.c), filter (cascade/filter.c), bounce (light/bounce.c).
 * Each stage's time goes into the report. Apart from bake.c because a move
 * re-bakes a partial cascade through it (move/move.c), and bake.c's
 * gi_cascade_free calls the move's file. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "cascade/cascade_internal.h"
#include "light/light.h"
#include "plan.h"
#include "trace/trace.h"

/* The report's work per level: voxels voxelized (the level's own, not its
 * filtered region), injected and bounced. */
static void level_work(struct gi_cascade *c) {
  for (int d = 0; d < c->n; d++) {
    gi_level *L = &c->lv[d];
    uint64_t inner = 1;
    for (int a = 0; a < 3; a++) inner *= L->has_inner ? (uint64_t)(L->inner1[a] - L->inner0[a]) : 0;
    c->report.level_voxelized[d] = (uint64_t)c->R * c->R * c->R - inner;
    c->report.level_injected[d] = L->num_occ;
    c->report.level_rebounced[d] = (uint64_t)L->num_occ * (uint64_t)c->report.bounces_run;
  }
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
  double tp = gi__now_ms();
  gi_quality q;
  gi_result rc = gi_quality_resolve(scene, qin, &q, err);
  if (rc != GI_OK) return rc;
  struct gi_cascade *c = gi__calloc(1, sizeof *c);
  if (!c) return gi__fail(err, GI_ERR_NOMEM, "bake: out of memory");
  c->scene = gi_scene_retain((gi_scene *)scene);
  c->wide_level = GI_MAX_LEVELS;
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
    gi__cascade_discard(c); /* no move state yet */
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
  c->report.ms.plan = t0 - tp;
  c->report.ms.voxelize = t1 - t0;
  c->report.ms.inject = t2 - t1;
  c->report.ms.filter = t3 - t2;
  c->report.ms.bounce = t4 - t3;
  gi__cascade_count_occupied(c);
  level_work(c);
  c->report.cascade_bytes = gi__cascade_level_bytes(c); /* no move state yet */
  c->cancel = NULL; /* the token need not outlive the bake */
  if (report) *report = c->report;
  *out = c;
  return GI_OK;
fail:
  gi__cascade_discard(c);
  return rc;
}
