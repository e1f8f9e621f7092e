/* report.c: the walk benchmark's figures against the goals.
 *
 * Cost: the update is the move at a step that crosses a cell boundary; the
 * cold figure is the full bake at the subsampled points (wall clock, and
 * process CPU time for a loaded machine). Drift: the largest relative
 * difference of the probe figures (probe.c) between the moved cascade and
 * the cold bake at the same point. Popping: the largest relative jump of
 * the probe at a fixed point (step i's) across the update (moved: before
 * and after the move; cold: the bakes at i - 1 and i), over the sampled
 * pairs (each straddles a grid shift) for both, and over every crossing
 * step for the moved cascade. The jump between consecutive steps' points is
 * printed too; it includes the light's real change between the points and
 * flips of emitter samples. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "walk.h"

#define GOAL_SPEEDUP_MEAN 10.0
#define GOAL_SPEEDUP_P99 5.0
#define GOAL_DRIFT_MEAN 0.01
#define GOAL_DRIFT_MAX 0.03
#define GOAL_POP_SHIFT 0.02

typedef struct figures {
  size_t steps, crossings, colds, pairs;
  double upd_mean, upd_p99, cold_mean, cold_p99, upd_cpu_mean, upd_cpu_p99, cold_cpu_mean, cold_cpu_p99;
  double step_mean, step_p99, gather_mean;
  size_t drift_points; /* cold-baked points outside solids */
  double drift_mean, drift_max;
  /* At a fixed point across the update (moved) or across the anchors (cold). */
  double pop_shift, pop_all, pop_pairs_moved, pop_pairs_cold;
  /* Between consecutive steps' points: includes the light's change between them. */
  double jump_pairs_moved, jump_pairs_cold, jump_all;
} figures;

static void cost_figures(const walk_path *p, const step_rec *st, figures *f, double *a, double *b, double *c,
                         double *d) {
  size_t nu = 0, nc = 0;
  for (size_t i = 0; i < p->n; i++) {
    if (i > 0 && st[i].crossed) a[nu] = st[i].move_ms, c[nu] = st[i].move_cpu_ms, nu++;
    if (st[i].cold) b[nc] = st[i].cold_ms, d[nc] = st[i].cold_cpu_ms, nc++;
  }
  f->crossings = nu, f->colds = nc;
  f->upd_mean = stat_mean(a, nu), f->upd_p99 = stat_pct(a, nu, 99);
  f->upd_cpu_mean = stat_mean(c, nu), f->upd_cpu_p99 = stat_pct(c, nu, 99);
  f->cold_mean = stat_mean(b, nc), f->cold_p99 = stat_pct(b, nc, 99);
  f->cold_cpu_mean = stat_mean(d, nc), f->cold_cpu_p99 = stat_pct(d, nc, 99);
  size_t ns = 0;
  for (size_t i = 1; i < p->n; i++) a[ns++] = st[i].move_ms + st[i].gather_ms;
  f->steps = ns, f->step_mean = stat_mean(a, ns), f->step_p99 = stat_pct(a, ns, 99);
  for (size_t i = 1; i < p->n; i++) a[i - 1] = st[i].gather_ms;
  f->gather_mean = stat_mean(a, ns);
}

static void quality_figures(const walk_path *p, const step_rec *st, figures *f, double *a) {
  size_t n = 0;
  for (size_t i = 1; i < p->n; i++)
    if (st[i].cold && !walk_point_inside(p, i)) a[n++] = probe_rel(&st[i].moved, &st[i].cold_probe);
  f->drift_points = n;
  f->drift_mean = stat_mean(a, n), f->drift_max = stat_max(a, n);
  /* The largest jump at a shift: bench_path found its step. */
  if (p->worst_shift) f->pop_shift = probe_rel(&st[p->worst_shift].moved, &st[p->worst_shift].pre);
  for (size_t i = 1; i < p->n; i++) {
    if (walk_point_inside(p, i) || walk_point_inside(p, i - 1)) continue;
    double fixed = probe_rel(&st[i].moved, &st[i].pre), jump = probe_rel(&st[i].moved, &st[i - 1].moved);
    f->pop_all = fmax(f->pop_all, fixed);
    f->jump_all = fmax(f->jump_all, jump);
    if (!(st[i].cold && st[i - 1].cold && st[i].crossed)) continue;
    f->pop_pairs_moved = fmax(f->pop_pairs_moved, fixed);
    f->pop_pairs_cold = fmax(f->pop_pairs_cold, probe_rel(&st[i].cold_probe, &st[i - 1].cold_next));
    f->jump_pairs_moved = fmax(f->jump_pairs_moved, jump);
    f->jump_pairs_cold = fmax(f->jump_pairs_cold, probe_rel(&st[i].cold_probe, &st[i - 1].cold_probe));
    f->pairs++;
  }
}

static const char *met(int ok) { return ok ? "met" : "MISSED"; }
/* A goal whose figure had no samples (a path that crossed no cell, no cold
 * pair) is not measured rather than missed. */
static const char *met_if(int have, int ok) { return have ? met(ok) : "not measured (no samples)"; }

/* "N.N" or "n/a" (no samples), in one of eight rotating buffers (one printf uses up to 6). */
static const char *num(double v, int prec) {
  static char buf[8][32];
  static int k;
  k = (k + 1) % 8;
  if (isfinite(v)) snprintf(buf[k], sizeof buf[k], "%.*f", prec, v);
  else snprintf(buf[k], sizeof buf[k], "n/a");
  return buf[k];
}

/* Goal checks tolerate rounding: figures that print the same (to 0.01%,
 * so within 5e-5) meet a "no worse" goal. A moved cascade equals cold
 * bakes only to float rounding (its sums run in another order): past the
 * Stanford bunny, popping at the sampled shifts read 1.8e-6 moved against
 * exactly 0 cold, printed 0.00% and 0.00%, and was called missed. */
#define NO_WORSE(a, b) ((a) <= (b) * (1 + 1e-9) + 5e-5)

static void print_figures(const walk_path *p, const figures *f) {
  double su_mean = f->cold_mean / f->upd_mean, su_p99 = f->cold_p99 / f->upd_p99;
  printf("== %s: %s m/s, eye %s m, %zu steps at %s Hz, %zu crossing a cell boundary, %zu cold bakes "
         "(%d levels of %d^3, finest voxel %.3f m)\n", p->name, num(p->speed, 1), num(p->eye, 1), f->steps,
         num(p->rate, 0), f->crossings,
         f->colds, p->resolved.levels, p->resolved.res, p->resolved.voxel0);
  printf("update (crossing steps): mean %s ms, p99 %s ms; cold bake: mean %s ms, p99 %s ms\n", num(f->upd_mean, 1),
         num(f->upd_p99, 1), num(f->cold_mean, 1), num(f->cold_p99, 1));
  printf("speed-up: %sx (mean)   goal >= %.0fx: %s\n", num(su_mean, 1), GOAL_SPEEDUP_MEAN,
         met_if(isfinite(su_mean), su_mean >= GOAL_SPEEDUP_MEAN));
  printf("speed-up: %sx (p99)    goal >= %.0fx: %s\n", num(su_p99, 1), GOAL_SPEEDUP_P99,
         met_if(isfinite(su_p99), su_p99 >= GOAL_SPEEDUP_P99));
  printf("  (CPU time: update mean %s ms, p99 %s ms; cold mean %s ms, p99 %s ms: %sx mean, %sx p99)\n",
         num(f->upd_cpu_mean, 1), num(f->upd_cpu_p99, 1), num(f->cold_cpu_mean, 1), num(f->cold_cpu_p99, 1),
         num(f->cold_cpu_mean / f->upd_cpu_mean, 1), num(f->cold_cpu_p99 / f->upd_cpu_p99, 1));
  printf("per step (move + gather, every step): mean %s ms, p99 %s ms (gather alone: mean %s ms); "
         "move setup once at the start (as a session's): %s ms\n",
         num(f->step_mean, 2), num(f->step_p99, 2), num(f->gather_mean, 2), num(p->setup_ms, 1));
  if (p->num_inside)
    printf("(%zu of %zu points lie inside solids: drift and popping leave them out)\n", p->num_inside, p->n);
  printf("drift (probe vs cold bake, %zu points): mean %s%% goal <= %.0f%%: %s; max %s%% goal <= %.0f%%: %s\n",
         f->drift_points, num(100 * f->drift_mean, 2), 100 * GOAL_DRIFT_MEAN,
         met_if(isfinite(f->drift_mean), f->drift_mean <= GOAL_DRIFT_MEAN), num(100 * f->drift_max, 2),
         100 * GOAL_DRIFT_MAX, met_if(isfinite(f->drift_max), f->drift_max <= GOAL_DRIFT_MAX));
  printf("popping at a fixed point, %zu sampled shifts: moved %s%%, cold %s%%  goal no worse than cold: %s\n",
         f->pairs, num(100 * f->pop_pairs_moved, 2), num(100 * f->pop_pairs_cold, 2),
         met_if(f->pairs > 0, NO_WORSE(f->pop_pairs_moved, f->pop_pairs_cold)));
  printf("popping at a fixed point, every grid shift (moved): %s%%  goal <= %.0f%%: %s; any step: %s%%\n",
         num(100 * f->pop_shift, 2), 100 * GOAL_POP_SHIFT, met_if(f->crossings > 0, f->pop_shift <= GOAL_POP_SHIFT),
         num(100 * f->pop_all, 2));
  if (p->worst_shift)
    printf("  (the largest jump at a shift: step %zu, at %.2f %.2f %.2f; cold bakes across that shift: %s%%)\n",
           p->worst_shift, p->at[p->worst_shift][0], p->at[p->worst_shift][1], p->at[p->worst_shift][2],
           p->worst_shift_cold >= 0 ? num(100 * p->worst_shift_cold, 2) : "n/a");
  printf("consecutive steps' probes (incl. the light's change between points): sampled shifts moved %s%%, "
         "cold %s%%; any step moved %s%%\n", num(100 * f->jump_pairs_moved, 2), num(100 * f->jump_pairs_cold, 2),
         num(100 * f->jump_all, 2));
}

/* "key":value with null for a figure that has no samples. */
static void jnum(FILE *json, const char *key, double v) {
  if (isfinite(v)) fprintf(json, ",\"%s\":%.6g", key, v);
  else fprintf(json, ",\"%s\":null", key);
}

static void json_figures(const bench_opts *o, const walk_path *p, const figures *f, FILE *json) {
  fprintf(json, "{\"bench\":\"walk\",\"path\":\"%s\",\"steps\":%zu,\"crossings\":%zu,\"cold_bakes\":%zu,\"pairs\":%zu",
          p->name, f->steps, f->crossings, f->colds, f->pairs);
  const struct { const char *k; double v; } kv[] = {
      {"speed_mps", p->speed}, {"eye_m", p->eye}, {"rate_hz", p->rate},
      {"city_extent_m", o->scene_file ? NAN : o->city.extent},
      {"levels", p->resolved.levels}, {"res", p->resolved.res}, {"voxel0_m", p->resolved.voxel0}, {"update_ms_mean", f->upd_mean}, {"update_ms_p99", f->upd_p99},
      {"cold_ms_mean", f->cold_mean}, {"cold_ms_p99", f->cold_p99}, {"speedup_mean", f->cold_mean / f->upd_mean},
      {"speedup_p99", f->cold_p99 / f->upd_p99}, {"update_cpu_ms_mean", f->upd_cpu_mean},
      {"cold_cpu_ms_mean", f->cold_cpu_mean}, {"step_ms_mean", f->step_mean}, {"step_ms_p99", f->step_p99},
      {"gather_ms_mean", f->gather_mean}, {"setup_ms", p->setup_ms}, {"points_inside", (double)p->num_inside},
      {"drift_points", (double)f->drift_points}, {"drift_mean", f->drift_mean}, {"drift_max", f->drift_max},
      {"pop_shift", f->pop_shift}, {"pop_shift_step", (double)p->worst_shift},
      {"pop_shift_cold", p->worst_shift_cold >= 0 ? p->worst_shift_cold : NAN},
      {"pop_any_step", f->pop_all}, {"pop_pairs_moved", f->pop_pairs_moved},
      {"pop_pairs_cold", f->pop_pairs_cold}, {"jump_pairs_moved", f->jump_pairs_moved},
      {"jump_pairs_cold", f->jump_pairs_cold}, {"jump_any_step", f->jump_all}};
  for (size_t i = 0; i < sizeof kv / sizeof kv[0]; i++) jnum(json, kv[i].k, kv[i].v);
  fprintf(json, "}\n");
  fflush(json);
}

/* Per-step figures for the chart (docs/experiments.md). */
static void steps_csv(const bench_opts *o, const walk_path *p, const step_rec *st) {
  char file[1024];
  snprintf(file, sizeof file, "%s/bench-walk-steps-%s.csv", o->out_dir, p->name);
  FILE *f = fopen(file, "w");
  if (!f) return walk_file_error(file);
  fprintf(f, "step,t,crossed,closed,move_ms,gather_ms,move_cpu_ms,cold_ms,voxelized,injected,regathered,jump,drift,pop,cold_pop");
  for (int k = 0; k < PROBE_FIGS; k++) fprintf(f, ",fig%d", k);
  fprintf(f, "\n");
  for (size_t i = 0; i < p->n; i++) {
    fprintf(f, "%zu,%.3f,%d,%d,%.3f,%.3f,%.3f,%.3f,%llu,%llu,%llu,%.5f,%.5f", i, p->t[i], st[i].crossed, st[i].closed,
            st[i].move_ms, st[i].gather_ms, st[i].move_cpu_ms, st[i].cold ? st[i].cold_ms : -1.0,
            (unsigned long long)st[i].redone[0], (unsigned long long)st[i].redone[1],
            (unsigned long long)st[i].redone[2], i ? probe_rel(&st[i].moved, &st[i - 1].moved) : 0.0,
            st[i].cold ? probe_rel(&st[i].moved, &st[i].cold_probe) : -1.0);
    fprintf(f, ",%.5f", i ? probe_rel(&st[i].moved, &st[i].pre) : 0.0);
    /* A sampled pair's cold figure beside the moved one (quality_figures' pairs). */
    int pair = i > 0 && st[i].crossed && st[i].cold && st[i - 1].cold;
    fprintf(f, ",%.5f", pair ? probe_rel(&st[i].cold_probe, &st[i - 1].cold_next) : -1.0);
    for (int k = 0; k < PROBE_FIGS; k++) fprintf(f, ",%.6g", st[i].moved.v[k]);
    fprintf(f, "\n");
  }
  if (fclose(f) != 0) walk_file_error(file);
}

void report_path(const bench_opts *o, const walk_path *p, const step_rec *steps, FILE *json) {
  double *buf = malloc(4 * p->n * sizeof *buf);
  if (!buf) return;
  figures f;
  memset(&f, 0, sizeof f);
  cost_figures(p, steps, &f, buf, buf + p->n, buf + 2 * p->n, buf + 3 * p->n);
  quality_figures(p, steps, &f, buf);
  print_figures(p, &f);
  if (json) json_figures(o, p, &f, json);
  steps_csv(o, p, steps);
  free(buf);
}
