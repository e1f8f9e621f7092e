/* plan.h: the effect plan's internals (plan.c), shared with the bake and
 * the camera view. */
#ifndef GI_PLAN_H
#define GI_PLAN_H

#include "cascade/cascade_internal.h"

/* The request's override for one effect, GI_FX_ON, GI_FX_OFF or
 * GI_FX_AUTO (the legacy `specular` and `ao` fields count when effects[id]
 * is auto). Shared by the bake's plan and the camera view's. */
int gi__fx_forced(const gi_quality *q, gi_effect_id id);
/* Decides the effect plan around the placed cascade c into r (keeping its
 * survey of the coarsest level's range in c->survey), and may set
 * q->bounces when the request left it to the plan (auto_bounces). *tail is
 * 1 when the bounce stage should add the geometric tail of the orders the
 * cap leaves out. Fails (GI_ERR_NOMEM) when the triangle query does. */
gi_result gi__plan_effects(struct gi_cascade *c, gi_quality *q, int auto_bounces, gi_bake_report *r,
                           int *tail, gi_error_info *err);
/* gi_effect_plan with the points the answers will be gathered at (as
 * gi__cascade_bake_at's pts: 6 floats each, local position and normal;
 * NULL, 0: none), which the sky test looks up from too. */
gi_result gi__effect_plan_for(const gi_scene *s, const double at[3], const gi_quality *qin, const float *pts, int npts,
                              gi_effect out[GI_FX_COUNT], gi_quality *resolved, gi_error_info *err);

/* A finite viewpoint a cascade of finest voxel s0 can be placed at:
 * within GI_MAX_VIEW_DISTANCE of the scene's origin on each axis (each
 * local coordinate is a float: farther, positions lose all precision; a
 * limit on the distance would refuse points no less precise than ones it
 * takes) and within 2^52 voxels of it (cells are indexed in int64 and
 * placed in double, gi__cells_ok). Else
 * GI_ERR_INVALID_ARG, the message starting with `who`. Shared by the
 * bake, the effect plan and a move. */
#define GI_MAX_VIEW_DISTANCE 1e9
#define GI_MAX_VIEW_DISTANCE_TEXT "1e9"
gi_result gi__viewpoint_range(const gi_scene *s, const double at[3], double s0, const char *who, gi_error_info *err);

/* A cascade as gi_cascade_bake would place it at `at` with resolved
 * quality q (levels' windows, no voxel arrays), for questions asked before
 * a bake: what the plan surveys, which points the bake will cover. The
 * caller frees *out with gi__free; it borrows s. Errors as the bake's for
 * the viewpoint (messages start with `who`), GI_ERR_NOMEM. */
gi_result gi__cascade_placed(const gi_scene *s, const double at[3], const gi_quality *q, const char *who,
                             struct gi_cascade **out, gi_error_info *err);

#endif
