/* bench.c: one cascade moved along a path, against cold bakes.
 *
 * Step 0 bakes the cascade cold at the path's first point and makes what
 * moves need (gi_cascade_move_prepare, timed apart: a session does it when
 * it starts, not on a step). Every later step
 * calls gi_cascade_move (also when the eye stays in its cell: each call is
 * one tick of the refresh clock, as a session's request would be) and then
 * gathers the probe at the eye. A step "crosses" when its level-0 anchor
 * differs from the previous step's: only then does the move scroll. Cold
 * bakes are expensive, so they are made at a subsample: every k-th
 * crossing step i (k = crossings / samples), baked at i and at i - 1, which
 * gives drift at both points and a cold pair straddling the grid shift.
 * Popping is measured at a fixed point: the probe at step i's point from the
 * cascade before the move and after it (for cold: the bakes at i - 1 and i,
 * both gathered at i's point): the change between two points also holds
 * the light's real gradient there (a shadow's edge) and flips of emitter
 * samples (the consecutive-step jump is kept too). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "walk.h"

static int cold_bake(const gi_scene *s, const gi_quality *q, const double at[3], gi_cascade **out, double *ms,
                     double *cpu) {
  gi_error_info err = {0};
  double w0 = now_ms(), c0 = cpu_ms();
  gi_result r = gi_cascade_bake(s, at, q, out, NULL, &err);
  *ms = now_ms() - w0, *cpu = cpu_ms() - c0;
  if (r != GI_OK) fprintf(stderr, "gi-walk: cold bake at %.3f %.3f %.3f: %s\n", at[0], at[1], at[2], err.msg);
  return r == GI_OK ? 0 : -1;
}

/* crossed[i] for every step, from the anchors alone (no bake). A point no
 * cascade can be placed at is named (the path's file or name, its number
 * and time) before any move runs: the move reaching it would fail later. */
static int mark_crossings(const gi_scene *s, const gi_quality *resolved, const char *label, const walk_path *p,
                          step_rec *steps) {
  int64_t prev[3] = {0}, cur[3];
  gi_error_info err = {0};
  for (size_t i = 0; i < p->n; i++) {
    if (gi_cascade_anchor(s, p->at[i], resolved, cur, &err) != GI_OK)
      return fprintf(stderr, "gi-walk: %s: point %zu of %zu (t = %g s) at (%g, %g, %g): %s\n", label, i + 1, p->n,
                     p->t[i], p->at[i][0], p->at[i][1], p->at[i][2], err.msg), -1;
    steps[i].crossed = i > 0 && memcmp(cur, prev, sizeof cur) != 0;
    memcpy(prev, cur, sizeof cur);
  }
  return 0;
}

/* Whether step i is a crossing the cold bakes may sample: both its points
 * outside solids (a probe inside one holds only leaked light). */
static int sampled_crossing(const walk_path *p, const step_rec *steps, size_t i) {
  return steps[i].crossed && !walk_point_inside(p, i) && !walk_point_inside(p, i - 1);
}

/* Marks the cold-bake subsample: every k-th such crossing step and the step before it. */
static void mark_cold(const walk_path *p, int samples, step_rec *steps) {
  size_t ncross = 0, seen = 0;
  for (size_t i = 1; i < p->n; i++) ncross += (size_t)sampled_crossing(p, steps, i);
  if (!ncross || samples < 1) return;
  size_t k = ncross / (size_t)samples;
  if (k < 1) k = 1;
  int made = 0;
  for (size_t i = 1; i < p->n && made < samples; i++) {
    if (!sampled_crossing(p, steps, i)) continue;
    /* The middle of each group of k, so the first sample is not the first step. */
    if (seen++ % k == k / 2) steps[i].cold = steps[i - 1].cold = 1, made++;
  }
}

/* A cold bake at `at`, gathered there and at the next step's point `next`. */
static int cold_at(const gi_scene *s, const gi_quality *q, const double at[3], const double next[3], step_rec *st) {
  gi_cascade *c = NULL;
  if (cold_bake(s, q, at, &c, &st->cold_ms, &st->cold_cpu_ms) != 0) return -1;
  int rc = probe_at(c, at, &st->cold_probe, NULL);
  if (!rc && next) rc = probe_at(c, next, &st->cold_next, NULL);
  gi_cascade_free(c);
  return rc;
}

static int move_step(gi_cascade *c, const double at[3], step_rec *st) {
  /* The same point before and after the update: the jump the update causes,
   * apart from how the light changes between points. */
  if (probe_at(c, at, &st->pre, NULL) != 0) return -1;
  gi_bake_report rep;
  gi_move_info info;
  gi_error_info err = {0};
  double w0 = now_ms(), c0 = cpu_ms();
  gi_result r = gi_cascade_move(c, at, &rep, &info, &err);
  st->move_ms = now_ms() - w0, st->move_cpu_ms = cpu_ms() - c0;
  if (r != GI_OK) return fprintf(stderr, "gi-walk: move to %.3f %.3f %.3f: %s\n", at[0], at[1], at[2], err.msg), -1;
  st->closed = info.cycle_closed;
  memset(st->redone, 0, sizeof st->redone);
  for (int d = 0; d < rep.levels; d++) {
    st->redone[0] += rep.level_voxelized[d];
    st->redone[1] += rep.level_injected[d];
    st->redone[2] += rep.level_rebounced[d];
  }
  return probe_at(c, at, &st->moved, &st->gather_ms);
}

/* Cold bakes at both sides of the update that jumped most (p->worst_shift). */
static int worst_shift_cold(const bench_opts *o, const gi_scene *s, walk_path *p, const step_rec *steps) {
  p->worst_shift = 0, p->worst_shift_cold = -1;
  double worst = -1;
  for (size_t i = 1; i < p->n; i++) {
    double j = probe_rel(&steps[i].moved, &steps[i].pre);
    /* The steps the 'any step' figure counts (report.c): neither end
     * inside a solid. Only the step's own end was checked, and a shift
     * from inside read 101% against any step's 36%. */
    if (steps[i].crossed && !walk_point_inside(p, i) && !walk_point_inside(p, i - 1) && j > worst)
      worst = j, p->worst_shift = i;
  }
  if (!p->worst_shift) return 0;
  step_rec before, after;
  memset(&before, 0, sizeof before), memset(&after, 0, sizeof after);
  size_t k = p->worst_shift;
  if (cold_at(s, &o->q, p->at[k - 1], p->at[k], &before) || cold_at(s, &o->q, p->at[k], NULL, &after)) return -1;
  p->worst_shift_cold = probe_rel(&after.cold_probe, &before.cold_next);
  return 0;
}

int bench_path(const bench_opts *o, const gi_scene *s, walk_path *p, step_rec *steps) {
  memset(steps, 0, p->n * sizeof *steps);
  gi_cascade *c = NULL;
  step_rec *s0 = &steps[0];
  if (cold_bake(s, &o->q, p->at[0], &c, &s0->cold_ms, &s0->cold_cpu_ms) != 0) return -1;
  gi_quality resolved = p->resolved = gi_cascade_report(c)->quality;
  /* What moves need, made once as a server session does at its start. */
  gi_error_info err = {0};
  double w0 = now_ms();
  if (gi_cascade_move_prepare(c, &err) != GI_OK) {
    fprintf(stderr, "gi-walk: move setup: %s\n", err.msg);
    gi_cascade_free(c);
    return -1;
  }
  p->setup_ms = now_ms() - w0;
  int rc = probe_at(c, p->at[0], &s0->moved, &s0->gather_ms);
  s0->cold_probe = s0->moved, s0->cold = 1;
  if (!rc && p->n > 1) rc = probe_at(c, p->at[1], &s0->cold_next, NULL);
  if (!rc) rc = mark_crossings(s, &resolved, o->path_file ? o->path_file : p->name, p, steps);
  if (!rc) mark_cold(p, o->samples, steps);
  for (size_t i = 1; i < p->n && !rc; i++) {
    rc = move_step(c, p->at[i], &steps[i]);
    /* The cold bake uses the request's quality, as the moved cascade's first bake did. */
    if (!rc && steps[i].cold) rc = cold_at(s, &o->q, p->at[i], i + 1 < p->n ? p->at[i + 1] : NULL, &steps[i]);
    if (!rc && (i % 100 == 0 || i + 1 == p->n))
      fprintf(stderr, "gi-walk: %s: step %zu of %zu\n", p->name, i, p->n - 1);
  }
  gi_cascade_free(c);
  if (!rc) rc = worst_shift_cold(o, s, p, steps);
  return rc;
}
